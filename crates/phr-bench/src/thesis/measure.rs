//! The measurements of `phr bench`, one scene at a time.

use super::Plan;
use crate::frame::median_frame as measure_frame;
use crate::Progress;
use anyhow::Result;
use phr_bvh::phr::PhrOptions;
use phr_bvh::{sah_cost, Builder, Bvh, SahConstants};
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use phr_render::output::write_heatmap;
use phr_render::scene::load_scene;
use phr_render::scene::RenderSettings;
use phr_render::Scene;
use phr_tune::bayes::BoOptions;
use phr_tune::grid::{THESIS_ALPHAS, THESIS_DELTAS};
use phr_tune::objective::{OMEGA_P, OMEGA_R};
use phr_tune::tune::{tune, Method, ObjectiveKind, TuneOptions};
use phr_tune::{PhrEvaluator, SearchBox};
use std::path::Path;
use std::time::Instant;

use crate::Stat;

/// One builder on one scene at one resolution.
#[derive(Clone, Debug)]
pub struct Row {
    pub scene: String,
    pub triangles: usize,
    pub res: u32,
    pub builder: String,
    /// (α, δ) of PHR builders.
    pub params: Option<(f64, f64)>,
    pub aux_ms: Stat,
    pub build_ms: Stat,
    pub total_ms: Stat,
    pub sah_21: f64,
    pub sah_11: f64,
    pub build_cost: Option<u64>,
    /// Render time of one 1-spp frame, mean over the views.
    pub render_ms: f64,
    pub mrays: f64,
    /// Collapsing the tree to the renderer's wide BVH and packing its triangles (median).
    pub collapse_ms: f64,
    /// Build (auxiliary LBVH included) + collapse + render.
    pub frame_ms: f64,
    /// Tuning time (PHR-Grid, PHR-BO), in ms and in frames of the tuned configuration.
    pub tune_ms: Option<f64>,
    pub tune_frames: Option<f64>,
}

/// PHR-HQ with a branching factor.
#[derive(Clone, Debug)]
pub struct BranchRow {
    pub scene: String,
    pub k: u32,
    pub build_ms: f64,
    pub sah_21: f64,
    pub render_ms: f64,
}

/// One point of the build cost vs build time study.
#[derive(Clone, Debug)]
pub struct CutPoint {
    pub scene: String,
    pub build_cost: f64,
    pub build_ms: f64,
}

#[derive(Default)]
pub struct Results {
    pub rows: Vec<Row>,
    pub branching: Vec<BranchRow>,
    pub cut: Vec<CutPoint>,
    /// Scenes with their heatmap image (file name in the output folder).
    pub heatmaps: Vec<(String, String)>,
    pub peers: Vec<super::peers::PeerRow>,
}

struct SceneCtx<'a> {
    scene: &'a Scene,
    name: String,
    geometry: Geometry,
    views: Vec<phr_render::camera::CameraDesc>,
    repeats: usize,
}

impl SceneCtx<'_> {
    /// Builds `repeats` times; returns the timings and the last tree.
    fn build(&self, builder: &Builder) -> (Stat, Stat, Stat, Option<u64>, Bvh) {
        let (mut aux, mut build, mut total) = (Vec::new(), Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..self.repeats {
            let r = self.geometry.build_report(builder);
            aux.push(r.aux_time.as_secs_f64() * 1e3);
            build.push(r.build_time.as_secs_f64() * 1e3);
            total.push(r.total_time().as_secs_f64() * 1e3);
            last = Some(r);
        }
        let last = last.expect("at least one repeat");
        (Stat::of(aux), Stat::of(build), Stat::of(total), last.phr.map(|s| s.build_cost), last.bvh)
    }

    /// Median time of what [`Geometry::set_bvh`] does before a frame can be rendered: the
    /// collapse to the wide BVH and the packing of the triangles (into the memory of the
    /// previous tree, as in the frame pipeline).
    fn collapse(&mut self, bvh: &Bvh) -> f64 {
        let mut times: Vec<f64> =
            (0..self.repeats).map(|_| self.geometry.set_bvh(bvh.clone()).as_secs_f64() * 1e3).collect();
        times.sort_by(f64::total_cmp);
        times[times.len() / 2]
    }

    /// Mean over the views of the median 1-spp frame; and Mrays/s.
    fn render(&mut self, bvh: Bvh, res: u32) -> (f64, f64, Bvh) {
        let mut bvh = bvh;
        let (mut ms_sum, mut rays_sum) = (0.0, 0.0);
        let size = RenderSettings { width: res, height: res, spp: 1, max_depth: self.scene.settings.max_depth };
        for view in &self.views {
            let mut frames: Vec<(f64, f64)> = Vec::new();
            for _ in 0..self.repeats {
                frames.push(measure_frame(self.scene, &mut self.geometry, bvh, view, &size));
                bvh = self.geometry.take_bvh();
            }
            frames.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (ms, rays) = frames[frames.len() / 2];
            ms_sum += ms;
            rays_sum += rays;
        }
        let n = self.views.len() as f64;
        (ms_sum / n, rays_sum / ms_sum / 1e3, bvh)
    }
}

pub fn measure_scene(
    path: &Path,
    plan: &Plan,
    out: &Path,
    progress: &dyn Progress,
    results: &mut Results,
) -> Result<()> {
    let mut scene = load_scene(path)?;
    if plan.materials == super::Materials::Thesis {
        crate::suite::apply_thesis_setting(&mut scene);
    }
    let name = crate::suite::scene_name(path);
    let views: Vec<_> = scene.views.iter().take(plan.max_views).map(|(_, c)| c.clone()).collect();
    let mut ctx =
        SceneCtx { scene: &scene, name: name.clone(), geometry: Geometry::new(&scene), views, repeats: plan.repeats };
    let triangles = ctx.geometry.triangle_count();
    let mut evaluator = PhrEvaluator::new(&ctx.geometry.boxes, PhrOptions::FAST);
    for (i, &res) in plan.resolutions.iter().enumerate() {
        if i > 0 {
            // A fresh evaluator: each resolution's tuning time counts all of its builds.
            evaluator = PhrEvaluator::new(&ctx.geometry.boxes, PhrOptions::FAST);
        }
        for builder_name in &plan.builders {
            progress.status(format!("{name} {res}² {builder_name}"));
            if builder_name == "sweep-sah" && triangles > plan.sweep_limit {
                progress.advance();
                continue;
            }
            let (builder, tune_ms) = resolve_builder(builder_name, &evaluator, res)?;
            let (aux_ms, build_ms, total_ms, build_cost, bvh) = ctx.build(&builder);
            let sah_21 = sah_cost(&bvh, SahConstants::THESIS);
            let sah_11 = sah_cost(&bvh, SahConstants::UNIT);
            let collapse_ms = ctx.collapse(&bvh);
            let (render_ms, mrays, _) = ctx.render(bvh, res);
            let frame_ms = total_ms.median + collapse_ms + render_ms;
            let params = match builder {
                Builder::Phr(o) => Some((o.alpha as f64, o.delta as f64)),
                _ => None,
            };
            results.rows.push(Row {
                scene: ctx.name.clone(),
                triangles,
                res,
                builder: builder_name.clone(),
                params,
                aux_ms,
                build_ms,
                total_ms,
                sah_21,
                sah_11,
                build_cost,
                render_ms,
                mrays,
                collapse_ms,
                frame_ms,
                tune_ms,
                tune_frames: tune_ms.map(|t| t / frame_ms),
            });
            progress.advance();
        }
    }
    let res = plan.resolutions[0];
    for &k in &plan.branching {
        progress.status(format!("{name} branching {k}"));
        let builder = Builder::PHR_HQ.with_branching(k).map_err(anyhow::Error::msg)?;
        let (_, _, total, _, bvh) = ctx.build(&builder);
        let sah_21 = sah_cost(&bvh, SahConstants::THESIS);
        let (render_ms, _, _) = ctx.render(bvh, res);
        results.branching.push(BranchRow { scene: name.clone(), k, build_ms: total.median, sah_21, render_ms });
        progress.advance();
    }
    progress.status(format!("{name} Σ|cut| study and heatmaps"));
    for &a in &plan.cut_grid.0 {
        for &d in &plan.cut_grid.1 {
            // Sequential, fresh builds: the tuners' cached timings come from parallel grids.
            let mut runs: Vec<_> = (0..plan.repeats).map(|_| evaluator.measure(a, d)).collect();
            runs.sort_by(|x, y| x.build_ms.total_cmp(&y.build_ms));
            let e = runs[runs.len() / 2];
            results.cut.push(CutPoint { scene: name.clone(), build_cost: e.build_cost, build_ms: e.build_ms });
        }
    }
    results.heatmaps.push((name.clone(), heatmap_pair(&mut ctx, res, out)?));
    if plan.peers {
        let view = &ctx.views[0];
        if let Some(row) = super::peers::run(&name, path, &scene, &mut ctx.geometry, view, res, out, progress)? {
            results.peers.push(row);
        }
    }
    progress.advance();
    Ok(())
}

/// The builder for a name; PHR-Grid and PHR-BO are tuned here (thesis objective), and their
/// tuning time returned.
fn resolve_builder(name: &str, evaluator: &PhrEvaluator, res: u32) -> Result<(Builder, Option<f64>)> {
    let thesis = ObjectiveKind::Thesis { width: res, height: res, omega_p: OMEGA_P, omega_r: OMEGA_R };
    let box_options = |method| TuneOptions { method, objective: thesis, search: SearchBox::THESIS, cache: None };
    let tuned = |method| {
        let start = Instant::now();
        let r = tune(evaluator, &box_options(method));
        let ms = start.elapsed().as_secs_f64() * 1e3;
        (Builder::Phr(PhrOptions::with(r.best.alpha as f32, r.best.delta as f32)), Some(ms))
    };
    Ok(match name {
        "phr-grid" => tuned(Method::Grid { alphas: THESIS_ALPHAS.to_vec(), deltas: THESIS_DELTAS.to_vec() }),
        "phr-bo" => tuned(Method::Bayes(BoOptions::default())),
        other => (other.parse().map_err(anyhow::Error::msg)?, None),
    })
}

/// Traversal steps per primary ray of the first view, LBVH left and PHR-HQ right, on one
/// colour scale (thesis Figure 5.3). Returns the file name.
fn heatmap_pair(ctx: &mut SceneCtx, res: u32, out: &Path) -> Result<String> {
    let camera = Camera::new(&ctx.views[0], res, res);
    let mut counts = Vec::new();
    for builder in [Builder::default(), Builder::PHR_HQ] {
        ctx.geometry.set_bvh(builder.build(&ctx.geometry.boxes));
        let steps: Vec<u32> = (0..res * res)
            .map(|i| {
                let ray = camera.ray((i % res) as f32 + 0.5, (i / res) as f32 + 0.5);
                let mut s = phr_bvh::TraversalStats::default();
                ctx.geometry.intersect_counted(&ray, &mut s);
                s.nodes
            })
            .collect();
        counts.push(steps);
    }
    // Side by side: one image twice as wide.
    let side: Vec<u32> = (0..res)
        .flat_map(|y| {
            let row = |c: &Vec<u32>| c[(y * res) as usize..((y + 1) * res) as usize].to_vec();
            let mut r = row(&counts[0]);
            r.extend(row(&counts[1]));
            r
        })
        .collect();
    let file = format!("heatmap_{}.png", ctx.name);
    write_heatmap(&out.join(&file), 2 * res, res, &side, None)?;
    Ok(file)
}
