//! `phr.Bvh`: a triangle mesh's BVH built by any of our builders, traced as the renderer
//! traces it (the 8-wide tree with triangles packed in 4-lane blocks), refitted and rebuilt
//! when the vertices move.

use crate::arrays::{check_vertices, floats};
use crate::pool::Pool;
use glam::Vec3;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use phr_bvh::dynamic::DynamicBvh;
use phr_bvh::metrics::{sah_cost, tree_stats, SahConstants};
use phr_bvh::phr::{build_phr, PhrOptions};
use phr_bvh::triangle::triangle_bounds;
use phr_bvh::{Aabb, Builder, PackedTriangles, Ray, WideBvh};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::time::Instant;

/// The width of the traced tree: the renderer's.
const WIDTH: usize = 8;

/// Rays per parallel task.
const RAY_CHUNK: usize = 256;

/// A BVH over a triangle mesh, traced as phr's renderer traces it.
///
/// `Bvh(vertices, indices, builder="phr-fast", alpha=None, delta=None, branching=2,
/// threads=None)`: `vertices` a float array of shape (n, 3), `indices` an integer array of
/// shape (m, 3) (float32 and uint32, C-contiguous, are read without a copy; others are
/// converted once). `builder`: one of `phr.BUILDERS` or `"phr:ALPHA,DELTA"`; `alpha` and
/// `delta` override a PHR builder's; `branching` 2 to 16 (PHR only). `threads`: None for all
/// cores; 1 to trace on the calling thread (several Python threads then trace at once; builds
/// run on one thread); n for a pool of n threads.
///
/// Calls release the GIL and read their input arrays in place: do not write to them from
/// another thread during a call. Any number of threads may trace one `Bvh` at once; `refit`
/// or `rebuild` while another thread traces it raises `RuntimeError` ("Already borrowed").
#[pyclass(module = "phr")]
pub struct Bvh {
    builder: Builder,
    pool: Pool,
    triangle_indices: Vec<[u32; 3]>,
    vertex_count: usize,
    triangles: Vec<[Vec3; 3]>,
    boxes: Vec<Aabb>,
    /// PHR's auxiliary tree, kept for `rebuild` (refitted, then PHR from it, as the thesis's
    /// dynamic pipeline does).
    dynamic: Option<DynamicBvh>,
    bvh: phr_bvh::Bvh,
    wide: WideBvh<WIDTH>,
    packed: PackedTriangles,
    build_cost: Option<u64>,
    aux_ms: f64,
    build_ms: f64,
    wide_ms: f64,
}

fn ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// The builder a name and optional α, δ and branching factor describe.
fn parse_builder(name: &str, alpha: Option<f32>, delta: Option<f32>, branching: u32) -> PyResult<Builder> {
    let mut builder: Builder = name.parse().map_err(PyValueError::new_err)?;
    if alpha.is_some() || delta.is_some() {
        let Builder::Phr(o) = builder else {
            return Err(PyValueError::new_err(format!(
                "alpha and delta are PHR's parameters; builder {name} has none"
            )));
        };
        let alpha = alpha.unwrap_or(o.alpha);
        let delta = delta.unwrap_or(o.delta);
        if !(alpha.is_finite() && alpha >= 0.0 && delta.is_finite() && delta >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "alpha and delta must be finite and >= 0, got {alpha}, {delta}"
            )));
        }
        builder = Builder::Phr(PhrOptions { alpha, delta, ..o });
    }
    builder.with_branching(branching).map_err(PyValueError::new_err)
}

impl Bvh {
    /// Triangles and their boxes from `vertices` and the kept indices.
    fn set_vertices(&mut self, vertices: &[Vec3]) {
        let Self { triangle_indices, triangles, boxes, .. } = self;
        triangles.clear();
        triangles.par_extend(triangle_indices.par_iter().map(|t| t.map(|i| vertices[i as usize])));
        boxes.clear();
        boxes.par_extend(triangles.par_iter().map(|&[a, b, c]| triangle_bounds(a, b, c)));
    }

    /// Builds from the current triangles: PHR from its auxiliary tree (made on the first
    /// build, refitted on the next ones), the others from scratch; then the traced wide tree
    /// and packed triangles.
    fn build(&mut self) {
        let start = Instant::now();
        let (bvh, aux_ms, build_cost) = match (self.builder, &mut self.dynamic) {
            (Builder::Phr(_), Some(dynamic)) => {
                let (bvh, t) = dynamic.update(&self.boxes);
                (bvh, t.refit.as_secs_f64() * 1e3, Some(t.build_cost))
            }
            (Builder::Phr(o), None) => {
                let dynamic = self.dynamic.insert(DynamicBvh::new(&self.boxes, o));
                let aux_ms = ms(start);
                let (bvh, stats) = build_phr(dynamic.aux(), &o);
                (bvh, aux_ms, Some(stats.build_cost))
            }
            (builder, _) => (builder.build_with_triangles(&self.boxes, &self.triangles), 0.0, None),
        };
        (self.build_ms, self.aux_ms, self.build_cost, self.bvh) = (ms(start), aux_ms, build_cost, bvh);
        let start = Instant::now();
        self.wide = WideBvh::from_bvh(&self.bvh);
        self.packed.repack(&self.wide.prim_indices, &self.triangles);
        self.wide_ms = ms(start);
    }
}

#[pymethods]
impl Bvh {
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (vertices, indices, builder = "phr-fast", alpha = None, delta = None, branching = 2, threads = None))]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        indices: &Bound<'_, PyAny>,
        builder: &str,
        alpha: Option<f32>,
        delta: Option<f32>,
        branching: u32,
        threads: Option<usize>,
    ) -> PyResult<Self> {
        let builder = parse_builder(builder, alpha, delta, branching)?;
        let pool = Pool::new(threads)?;
        let vertices = floats("vertices", vertices)?;
        let points = vertices.as_vec3s();
        let tris = crate::arrays::indices(indices, points.len())?;
        let mut bvh = Bvh {
            builder,
            pool,
            triangle_indices: tris.as_triples().to_vec(),
            vertex_count: points.len(),
            triangles: Vec::new(),
            boxes: Vec::new(),
            dynamic: None,
            bvh: phr_bvh::Bvh::default(),
            wide: WideBvh::default(),
            packed: PackedTriangles::default(),
            build_cost: None,
            aux_ms: 0.0,
            build_ms: 0.0,
            wide_ms: 0.0,
        };
        let pool = bvh.pool.clone();
        py.detach(|| {
            check_vertices(points)?;
            pool.install(|| {
                bvh.set_vertices(points);
                bvh.build();
            })
        })?;
        Ok(bvh)
    }

    /// Moves the vertices (same count, same triangles) and refits the tree to them: the
    /// topology is kept, every box recomputed. Returns the time taken in ms.
    fn refit(&mut self, py: Python<'_>, vertices: &Bound<'_, PyAny>) -> PyResult<f64> {
        let vertices = floats("vertices", vertices)?;
        let points = vertices.as_vec3s();
        if points.len() != self.vertex_count {
            return Err(PyValueError::new_err(format!(
                "refit needs the same {} vertices, got {}",
                self.vertex_count,
                points.len()
            )));
        }
        let pool = self.pool.clone();
        py.detach(|| {
            check_vertices(points)?;
            pool.install(|| {
                let start = Instant::now();
                self.set_vertices(points);
                phr_bvh::refit(&mut self.bvh, &self.boxes);
                self.wide.refit(&self.boxes);
                self.packed.repack(&self.wide.prim_indices, &self.triangles);
                ms(start)
            })
        })
    }

    /// Builds the tree again over the current vertices (PHR: from its auxiliary tree,
    /// refitted, as the thesis's dynamic scenes do). Returns the build time in ms.
    fn rebuild(&mut self, py: Python<'_>) -> PyResult<f64> {
        let pool = self.pool.clone();
        py.detach(|| pool.install(|| self.build()))?;
        Ok(self.build_ms)
    }

    /// The builder's time of the last build, ms (PHR: its auxiliary tree included).
    #[getter]
    fn build_ms(&self) -> f64 {
        self.build_ms
    }

    /// The auxiliary tree's part of `build_ms` (PHR only; 0 for the others).
    #[getter]
    fn aux_ms(&self) -> f64 {
        self.aux_ms
    }

    /// Time to turn the last build into the traced 8-wide tree and pack its triangles, ms.
    #[getter]
    fn wide_ms(&self) -> f64 {
        self.wide_ms
    }

    /// The builder's name (`phr-fast`, `sbvh`, `phr:0.45,7`, ...), as `Bvh(builder=...)`
    /// takes it.
    #[getter]
    fn builder(&self) -> String {
        match self.builder {
            Builder::Phr(o) => Builder::Phr(PhrOptions { branching: 2, ..o }).to_string(),
            b => b.to_string(),
        }
    }

    /// Children per node of the built tree (2 unless a PHR builder was given another).
    #[getter]
    fn branching(&self) -> u32 {
        match self.builder {
            Builder::Phr(o) => o.branching,
            _ => 2,
        }
    }

    fn __len__(&self) -> usize {
        self.triangles.len()
    }

    fn __repr__(&self) -> String {
        format!("<phr.Bvh {} triangles, {}, {} nodes>", self.triangles.len(), self.builder, self.bvh.nodes.len())
    }

    /// The tree's figures as a dict: `sah_cost` (with the given constants, normalised by the
    /// root's area), `build_cost` (PHR's Σ|cut|, None for other builders), `nodes`, `leaves`,
    /// `depth`, `mean_leaf_depth`, `max_leaf_size`, `mean_leaf_size` (of the built tree),
    /// `wide_nodes` (of the traced 8-wide tree), and the timings.
    #[pyo3(signature = (traversal = 1.0, intersection = 1.0))]
    fn stats<'py>(&self, py: Python<'py>, traversal: f32, intersection: f32) -> PyResult<Bound<'py, PyDict>> {
        let s = tree_stats(&self.bvh);
        let d = PyDict::new(py);
        d.set_item("builder", self.builder())?;
        d.set_item("branching", self.branching())?;
        d.set_item("triangles", self.triangles.len())?;
        d.set_item("sah_cost", sah_cost(&self.bvh, SahConstants { traversal, intersection }))?;
        d.set_item("build_cost", self.build_cost)?;
        d.set_item("nodes", s.nodes)?;
        d.set_item("leaves", s.leaves)?;
        d.set_item("depth", s.max_depth)?;
        d.set_item("mean_leaf_depth", s.mean_leaf_depth)?;
        d.set_item("max_leaf_size", s.max_leaf_size)?;
        d.set_item("mean_leaf_size", s.mean_leaf_size)?;
        d.set_item("wide_nodes", self.wide.nodes.len())?;
        d.set_item("build_ms", self.build_ms)?;
        d.set_item("aux_ms", self.aux_ms)?;
        d.set_item("wide_ms", self.wide_ms)?;
        Ok(d)
    }

    /// Closest hits of the rays `origins[i] + t directions[i]`, `tmin < t <= tmax` (t in units
    /// of the direction's length). Returns `(t, prim, uv)`: float32 distances (inf on a miss),
    /// int64 triangle indices (-1 on a miss) and float32 barycentrics of shape (n, 2) (the hit
    /// is `(1 - u - v) p0 + u p1 + v p2`). Rays with a non-finite origin or direction miss, and
    /// so may rays from beyond ±1e18, where f32 distances overflow.
    #[pyo3(signature = (origins, directions, tmin = 0.0, tmax = f32::INFINITY))]
    #[allow(clippy::type_complexity)]
    fn intersect<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f32,
        tmax: f32,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, Bound<'py, PyArray1<i64>>, Bound<'py, PyArray2<f32>>)> {
        let (o, d) = (floats("origins", origins)?, floats("directions", directions)?);
        let rays = Rays::new(o.as_vec3s(), d.as_vec3s(), tmin, tmax)?;
        let n = rays.len();
        let t = PyArray1::<f32>::zeros(py, n, false);
        let prim = PyArray1::<i64>::zeros(py, n, false);
        let uv = PyArray2::<f32>::zeros(py, [n, 2], false);
        {
            let (mut t, mut prim, mut uv) = (t.readwrite(), prim.readwrite(), uv.readwrite());
            let (t, prim, uv) = (t.as_slice_mut()?, prim.as_slice_mut()?, uv.as_slice_mut()?);
            // The outputs in chunks of RAY_CHUNK rays, with the index of each chunk's first ray.
            let chunks: Vec<_> = t
                .chunks_mut(RAY_CHUNK)
                .zip(prim.chunks_mut(RAY_CHUNK))
                .zip(uv.chunks_mut(2 * RAY_CHUNK))
                .enumerate()
                .map(|(c, ((t, prim), uv))| (c * RAY_CHUNK, t, prim, uv))
                .collect();
            py.detach(|| {
                self.pool.for_each(chunks, |(first, t, prim, uv)| {
                    // The chunk's rays traced together, several at once (interleaved).
                    let chunk = rays.chunk(first, t.len());
                    let mut hits = vec![None; chunk.len()];
                    self.wide.closest_triangles_batch(&self.packed, &chunk, &mut hits);
                    for (hit, ((t, prim), uv)) in hits.iter().zip(t.iter_mut().zip(prim).zip(uv.chunks_exact_mut(2))) {
                        match hit {
                            Some(h) => {
                                (*t, *prim) = (h.hit.t, h.prim.into());
                                uv.copy_from_slice(&[h.hit.u, h.hit.v]);
                            }
                            None => (*t, *prim) = (f32::INFINITY, -1),
                        }
                    }
                })
            });
        }
        Ok((t, prim, uv))
    }

    /// Whether anything is hit within `tmin < t <= tmax` along each ray (any-hit queries, as
    /// for shadow rays): a bool array of shape (n,). Rays with a non-finite origin or
    /// direction are not occluded.
    #[pyo3(signature = (origins, directions, tmin = 0.0, tmax = f32::INFINITY))]
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f32,
        tmax: f32,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let (o, d) = (floats("origins", origins)?, floats("directions", directions)?);
        let rays = Rays::new(o.as_vec3s(), d.as_vec3s(), tmin, tmax)?;
        let mut hit = vec![false; rays.len()];
        let chunks: Vec<_> = hit.chunks_mut(RAY_CHUNK).enumerate().map(|(c, hit)| (c * RAY_CHUNK, hit)).collect();
        py.detach(|| {
            self.pool.for_each(chunks, |(first, hit)| {
                let chunk = rays.chunk(first, hit.len());
                self.wide.any_triangles_batch(&self.packed, &chunk, hit);
            })
        });
        Ok(PyArray1::from_vec(py, hit))
    }
}

/// A batch of rays with one interval.
struct Rays<'a> {
    origins: &'a [Vec3],
    directions: &'a [Vec3],
    tmin: f32,
    tmax: f32,
}

impl<'a> Rays<'a> {
    fn new(origins: &'a [Vec3], directions: &'a [Vec3], tmin: f32, tmax: f32) -> PyResult<Self> {
        if origins.len() != directions.len() {
            return Err(PyValueError::new_err(format!(
                "origins and directions must have the same shape, got {} and {} rows",
                origins.len(),
                directions.len()
            )));
        }
        if tmin.is_nan() || tmax.is_nan() || tmin < 0.0 {
            return Err(PyValueError::new_err(format!(
                "need 0 <= tmin and tmax not NaN, got tmin {tmin}, tmax {tmax}"
            )));
        }
        Ok(Self { origins, directions, tmin, tmax })
    }

    fn len(&self) -> usize {
        self.origins.len()
    }

    /// Rays `first..first + count`, those that cannot hit anything as a ray the traversal
    /// refuses at once (a NaN origin).
    fn chunk(&self, first: usize, count: usize) -> Vec<Ray> {
        (first..first + count).map(|i| self.get(i).unwrap_or_else(|| Ray::new(Vec3::NAN, Vec3::X))).collect()
    }

    /// Ray `i`, or `None` if it cannot hit anything (non-finite, or a zero direction).
    #[inline]
    fn get(&self, i: usize) -> Option<Ray> {
        let (o, d) = (*self.origins.get(i)?, self.directions[i]);
        (o.is_finite() && d.is_finite() && d != Vec3::ZERO).then(|| Ray::with_interval(o, d, self.tmin, self.tmax))
    }
}
