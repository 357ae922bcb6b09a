//! `phr.tune`: choosing PHR's α and δ for a mesh, as `phr tune` does for a scene (thesis
//! chapter 6): grid search or Bayesian optimisation of the thesis's objective or of a frame
//! time model calibrated by rendering the mesh.

use crate::arrays;
use crate::pool::Pool;
use phr_bench::suite::apply_thesis_setting;
use phr_bench::tune_bench::calibrate;
use phr_bvh::phr::PhrOptions;
use phr_render::geometry::Geometry;
use phr_render::material::Material;
use phr_render::scene::{Mesh, RenderSettings};
use phr_tune::bayes::BoOptions;
use phr_tune::grid::{THESIS_ALPHAS, THESIS_DELTAS};
use phr_tune::objective::{OMEGA_P, OMEGA_R};
use phr_tune::tune::{tune as run_tune, Method, ObjectiveKind, TuneOptions};
use phr_tune::{PhrEvaluator, SearchBox};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::time::Duration;

/// The mesh as a scene in the thesis's setting (every surface diffuse 0.7, white sky, six
/// path segments), seen by the camera that frames it: what the frame-time objective renders.
fn thesis_scene(vertices: &[glam::Vec3], triangles: &[[u32; 3]]) -> phr_render::Scene {
    let mut scene = phr_render::Scene::default();
    // (Its albedo is the thesis's once `apply_thesis_setting` has run.)
    let material = scene.add_material("diffuse", Material::Lambertian { albedo: glam::Vec3::ONE });
    scene.meshes.push(Mesh {
        name: "mesh".into(),
        positions: vertices.to_vec(),
        triangles: triangles.to_vec(),
        triangle_material: vec![material; triangles.len()],
        uvs: Vec::new(),
    });
    apply_thesis_setting(&mut scene);
    let camera = scene.framing_camera();
    scene.views.push(("framing".into(), camera));
    scene
}

/// Chooses PHR's α and δ for the mesh `vertices`, `indices` and an image of `width × height`.
///
/// `method`: `"bo"` (Bayesian optimisation, `budget` builds) or `"grid"` (every pair of
/// `alphas × deltas`). `objective`: `"thesis"` (`e(α, δ) = b / max b + ω² c / max c`, with
/// `omega_p`, `omega_r`) or `"frame-time"` (a model of the frame time calibrated by rendering
/// the mesh from a camera that frames it). The search box spans `alphas` and `deltas` (the
/// thesis's grid by default). Returns a dict: `alpha`, `delta`, `value` (the objective's),
/// `objective`, `elapsed_ms`, `builds`, and `evaluations`, a list of dicts (`alpha`,
/// `delta`, `build_cost` Σ|cut|, `sah_cost` with constants 2 and 1, `build_ms`, `value`).
#[pyfunction]
#[pyo3(signature = (vertices, indices, width = 256, height = 256, method = "bo", objective = "thesis", budget = 20, seed = 0, alphas = None, deltas = None, omega_p = OMEGA_P, omega_r = OMEGA_R, time_budget_ms = None, threads = None))]
#[allow(clippy::too_many_arguments)]
pub fn tune<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    indices: &Bound<'py, PyAny>,
    width: u32,
    height: u32,
    method: &str,
    objective: &str,
    budget: usize,
    seed: u64,
    alphas: Option<Vec<f64>>,
    deltas: Option<Vec<f64>>,
    omega_p: f64,
    omega_r: f64,
    time_budget_ms: Option<u64>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let alphas = alphas.unwrap_or(THESIS_ALPHAS.to_vec());
    let deltas = deltas.unwrap_or(THESIS_DELTAS.to_vec());
    let finite = |v: &[f64]| !v.is_empty() && v.iter().all(|x| x.is_finite() && *x >= 0.0);
    if !finite(&alphas) || !finite(&deltas) {
        return Err(PyValueError::new_err("alphas and deltas must be non-empty lists of finite numbers >= 0"));
    }
    let size = RenderSettings { width, height, spp: 1, max_depth: phr_bench::suite::THESIS_MAX_DEPTH };
    size.check().map_err(PyValueError::new_err)?;
    let method = match method {
        "grid" => Method::Grid { alphas: alphas.clone(), deltas: deltas.clone() },
        "bo" if budget >= 3 => Method::Bayes(BoOptions {
            budget,
            seed,
            time_budget: time_budget_ms.map(Duration::from_millis),
            ..Default::default()
        }),
        "bo" => return Err(PyValueError::new_err(format!("budget must be at least 3, got {budget}"))),
        other => return Err(PyValueError::new_err(format!("unknown method {other:?} (use \"bo\" or \"grid\")"))),
    };
    let frame_time = match objective {
        "thesis" => false,
        "frame-time" => true,
        other => {
            return Err(PyValueError::new_err(format!(
                "unknown objective {other:?} (use \"thesis\" or \"frame-time\")"
            )))
        }
    };
    let pool = Pool::new(threads)?;
    let v = arrays::floats("vertices", vertices)?;
    let points = v.as_vec3s();
    let tris = arrays::indices(indices, points.len())?;
    let triangles = tris.as_triples();
    if triangles.is_empty() {
        return Err(PyValueError::new_err("the mesh has no triangles"));
    }
    let search = SearchBox::spanning(&alphas, &deltas);
    let (result, builds) = py.detach(|| {
        arrays::check_vertices(points)?;
        pool.install(|| {
            let scene = thesis_scene(points, triangles);
            let mut geometry = Geometry::new(&scene);
            let evaluator = PhrEvaluator::new(&geometry.boxes, PhrOptions::FAST);
            let objective = if frame_time {
                let view = scene.views[0].1.clone();
                ObjectiveKind::FrameTime(calibrate(&evaluator, &scene, &mut geometry, &view, &size, &search))
            } else {
                ObjectiveKind::Thesis { width, height, omega_p, omega_r }
            };
            let result = run_tune(&evaluator, &TuneOptions { method, objective, search, cache: None });
            (result, evaluator.builds())
        })
    })?;
    let out = PyDict::new(py);
    out.set_item("alpha", result.best.alpha)?;
    out.set_item("delta", result.best.delta)?;
    out.set_item("value", result.best_value)?;
    out.set_item("objective", objective)?;
    out.set_item("elapsed_ms", result.elapsed.as_secs_f64() * 1e3)?;
    out.set_item("builds", builds)?;
    let evaluations = PyList::empty(py);
    for (e, value) in &result.evaluations {
        let d = PyDict::new(py);
        d.set_item("alpha", e.alpha)?;
        d.set_item("delta", e.delta)?;
        d.set_item("build_cost", e.build_cost)?;
        d.set_item("sah_cost", e.sah_cost)?;
        d.set_item("build_ms", e.build_ms)?;
        d.set_item("value", value)?;
        evaluations.append(d)?;
    }
    out.set_item("evaluations", evaluations)?;
    Ok(out)
}
