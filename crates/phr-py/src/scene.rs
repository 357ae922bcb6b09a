//! `phr.Scene` and `phr.render`: the path tracer on a scene, as `phr render` runs it (same
//! defaults, same seed, same image), returning the linear mean as an `(h, w, 3)` float32
//! array.

use crate::pool::Pool;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use phr_bvh::Builder;
use phr_render::denoise::{oidn, Filter};
use phr_render::film::Film;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::render::Renderer;
use phr_render::scene::RenderSettings;
use pyo3::exceptions::{PyFileNotFoundError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Mutex;

/// A scene that failed to open, as a Python exception with the whole message:
/// `FileNotFoundError` when the named file does not exist, `ValueError` otherwise.
fn open_error(scene: &str, e: anyhow::Error) -> PyErr {
    let message = format!("{e:#}");
    let named_file = scene != phr_bench::suite::BUILTIN && std::path::Path::new(scene).extension().is_some();
    if named_file && !std::path::Path::new(scene).exists() {
        PyFileNotFoundError::new_err(message)
    } else {
        PyValueError::new_err(message)
    }
}

/// A scene loaded once, to render several views or settings.
///
/// `Scene(scene)`: a scene file (.json), a mesh (.obj, .ply, .gltf, .glb, optionally .gz),
/// `"builtin"`, or a scene of `scenes/suite` by name, as `phr render` opens it.
#[pyclass(module = "phr")]
pub struct Scene {
    scene: phr_render::Scene,
    /// What the scene argument named.
    source: String,
    /// The last geometry built, by builder: renders with the same builder reuse it.
    geometry: Mutex<Option<(Builder, Geometry)>>,
}

#[pymethods]
impl Scene {
    /// Opens a scene file (.json), a mesh (.obj, .ply, .gltf, .glb, optionally .gz),
    /// `"builtin"`, or a scene of `scenes/suite` by name, as `phr render` does.
    #[new]
    fn new(py: Python<'_>, scene: &str) -> PyResult<Self> {
        let loaded = py.detach(|| phr_bench::suite::open_scene(scene)).map_err(|e| open_error(scene, e))?;
        Ok(Self { scene: loaded, source: scene.to_string(), geometry: Mutex::new(None) })
    }

    /// The named views; the first is the default.
    #[getter]
    fn views(&self) -> Vec<String> {
        self.scene.views.iter().map(|(name, _)| name.clone()).collect()
    }

    #[getter]
    fn triangle_count(&self) -> usize {
        self.scene.triangle_count() + self.scene.instanced_triangle_count().0 as usize
    }

    #[getter]
    fn sphere_count(&self) -> usize {
        self.scene.spheres.len()
    }

    /// The render settings the file carries: `width`, `height`, `spp`, `max_depth`.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.scene.settings;
        let d = PyDict::new(py);
        d.set_item("width", s.width)?;
        d.set_item("height", s.height)?;
        d.set_item("spp", s.spp)?;
        d.set_item("max_depth", s.max_depth)?;
        Ok(d)
    }

    /// Every triangle of the scene's meshes as `(vertices, indices)`: float32 of shape
    /// (n, 3) and uint32 of shape (m, 3), ready for `phr.Bvh` (meshes in file order, their
    /// vertices concatenated; then each copy of a mesh placed many times, in the world).
    #[allow(clippy::type_complexity)]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<u32>>)> {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let copies = self.scene.instanced.iter().flat_map(|i| i.written_out());
        for mesh in self.scene.meshes.iter().map(std::borrow::Cow::Borrowed).chain(copies.map(std::borrow::Cow::Owned))
        {
            let base = (vertices.len() / 3) as u32;
            vertices.extend(mesh.positions.iter().flat_map(|p| p.to_array()));
            indices.extend(mesh.triangles.iter().flat_map(|t| t.map(|i| base + i)));
        }
        let (n, m) = (vertices.len() / 3, indices.len() / 3);
        Ok((PyArray1::from_vec(py, vertices).reshape([n, 3])?, PyArray1::from_vec(py, indices).reshape([m, 3])?))
    }

    fn __repr__(&self) -> String {
        format!(
            "<phr.Scene {:?}: {} triangles, {} spheres, views {:?}>",
            self.source,
            self.scene.triangle_count(),
            self.scene.spheres.len(),
            self.views()
        )
    }

    /// Path traces a view: `spp` frames of one sample per pixel, accumulated, as
    /// `phr render` (same arguments, same defaults: the file's settings, builder `sbvh`,
    /// seed 0, integrator `path`: light sampling with MIS; `implicit`: the thesis's). Returns
    /// linear radiance, float32 of shape (height, width, 3), top row first: the raw mean, as
    /// `phr render --linear` writes it, or with `denoiser="atrous"` what `phr render --out`
    /// writes (`"oidn"`, Intel Open Image Denoise, is an error: this module is built without it).
    #[pyo3(signature = (width = None, height = None, spp = None, view = None, seed = 0, max_depth = None, builder = "sbvh", integrator = "path", denoiser = "none", threads = None))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: Option<u32>,
        height: Option<u32>,
        spp: Option<u32>,
        view: Option<&str>,
        seed: u64,
        max_depth: Option<u32>,
        builder: &str,
        integrator: &str,
        denoiser: &str,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, numpy::PyArray3<f32>>> {
        let s = self.scene.settings;
        let settings = RenderSettings {
            width: width.unwrap_or(s.width),
            height: height.unwrap_or(s.height),
            spp: spp.unwrap_or(s.spp),
            max_depth: max_depth.unwrap_or(s.max_depth),
        };
        settings.check().map_err(PyValueError::new_err)?;
        let camera = self.scene.view(view).ok_or_else(|| {
            PyValueError::new_err(format!(
                "no view {:?} in {} (views: {:?})",
                view.unwrap_or(""),
                self.source,
                self.views()
            ))
        })?;
        let builder: Builder = builder.parse().map_err(PyValueError::new_err)?;
        let sample_lights = match integrator {
            "path" => true,
            "implicit" => false,
            other => return Err(PyValueError::new_err(format!("integrator {other:?}: use \"path\" or \"implicit\""))),
        };
        let filter = match denoiser {
            "none" => None,
            "atrous" => Some(Filter::Atrous),
            "oidn" if oidn::AVAILABLE => Some(Filter::Oidn),
            "oidn" => return Err(PyValueError::new_err(format!("denoiser \"oidn\": {}", oidn::MISSING))),
            other => {
                return Err(PyValueError::new_err(format!("denoiser {other:?}: use \"none\", \"atrous\" or \"oidn\"")))
            }
        };
        let pool = Pool::new(threads)?;
        let pixels = py
            .detach(|| {
                pool.install(|| {
                    let mut cached = self.geometry.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
                    if cached.as_ref().is_none_or(|(b, _)| *b != builder) {
                        let mut geometry = Geometry::new(&self.scene);
                        geometry.build(&builder);
                        *cached = Some((builder, geometry));
                    }
                    let (_, geometry) = cached.as_ref().expect("built above");
                    let lights =
                        sample_lights.then(|| LightSet::new(geometry, &self.scene.materials, &self.scene.background));
                    let renderer =
                        Renderer::new(&self.scene, geometry, &camera, &settings, lights.as_ref()).with_seed(seed);
                    let mut film = Film::new(settings.width, settings.height);
                    for frame in 0..settings.spp {
                        film.add_frame(&renderer.render_frame(frame).0);
                    }
                    let image = match filter {
                        Some(filter) => filter.finish(&renderer, &film)?.image,
                        None => film.mean(),
                    };
                    Ok::<_, String>(image.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>())
                })
            })?
            .map_err(PyRuntimeError::new_err)?;
        let (w, h) = (settings.width as usize, settings.height as usize);
        PyArray1::from_vec(py, pixels).reshape([h, w, 3])
    }
}
