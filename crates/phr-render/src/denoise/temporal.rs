//! Temporal accumulation in front of the à-trous filter: spatiotemporal variance-guided
//! filtering (SVGF, Schied et al. 2017), for one sample per pixel per frame while the view or
//! the scene moves.
//!
//! Each frame's illumination is blended into a history that follows the surfaces: a pixel
//! finds its previous value by projecting its first hit into the previous frame's camera and
//! reading the 2×2 previous pixels around that point, each kept only if it saw the same surface
//! (a normal within [`MIN_NORMAL_COS`] and a position within [`MAX_PLANE_FOOTPRINTS`] of the
//! tangent plane). Where none is kept (a disocclusion, or the first frame) the history starts
//! again. The first and second moments of the luminance are blended the same way; their
//! difference is the sample variance, estimated over the 7×7 neighbours of the same surface
//! while a pixel has fewer than [`SPATIAL_VARIANCE_UNTIL`] frames. The à-trous passes then
//! filter the blended illumination with that variance (all of them where the history is
//! short, fewer where it is long: [`Temporal::converged_passes`]), and the first pass's output
//! becomes the history (SVGF's choice: the history is smoother, so the image is steadier).

use super::atrous::{luminance, Atrous, FilterMemory, GuidePlanes, Signal, MIN_ALBEDO};
use super::Guide;
use crate::camera::Camera;
use glam::Vec3;
use rayon::prelude::*;

/// A previous pixel is the same surface only if the normals' cosine is at least this.
pub const MIN_NORMAL_COS: f32 = 0.9;

/// …and its position lies within this many of the pixel's footprints of the tangent plane.
pub const MAX_PLANE_FOOTPRINTS: f32 = 2.0;

/// Below this many frames of history, a pixel's variance comes from its neighbours.
pub const SPATIAL_VARIANCE_UNTIL: f32 = 4.0;

/// Whether a pixel at `other_position` with `other_normal` lies on the surface of a pixel
/// at `position` (unit `normal`, `footprint`), `offset` pixels away: normals within
/// [`MIN_NORMAL_COS`], and within [`MAX_PLANE_FOOTPRINTS`] footprints per pixel of offset of
/// the tangent plane.
fn same_surface(
    normal: Vec3,
    position: Vec3,
    footprint: f32,
    other_normal: Vec3,
    other_position: Vec3,
    offset: f32,
) -> bool {
    normal.dot(other_normal) >= MIN_NORMAL_COS
        && normal.dot(other_position - position).abs() <= MAX_PLANE_FOOTPRINTS * footprint * offset
}

/// A short history's variance comes from the (2·this + 1)² neighbours around it.
const VARIANCE_RADIUS: usize = 3;

/// The distances of [`VARIANCE_RADIUS`]'s neighbours by |dy| and |dx|.
type Distances = [[f32; VARIANCE_RADIUS + 1]; VARIANCE_RADIUS + 1];

/// A pixel with fewer frames of history than this gets all of the spatial filter's passes;
/// one with more, only [`Temporal::converged_passes`].
pub const ALL_PASSES_UNTIL: f32 = 4.0;

/// History lengths stop growing here (only the blend weight's floor matters beyond).
const MAX_HISTORY: f32 = 256.0;

/// SVGF with [`Atrous`] as its spatial filter. Holds the previous frame, and the memory of
/// the one before (the next frame's history is written into it).
#[derive(Debug)]
pub struct Temporal {
    pub atrous: Atrous,
    /// The spatial filter's passes over pixels with a history of [`ALL_PASSES_UNTIL`] frames
    /// or more (at most `atrous.passes`): their blended samples are already smooth, and the
    /// later passes would only blur them further. Pixels with a shorter history (a
    /// disocclusion, the first frames) get all the passes.
    pub converged_passes: u32,
    /// Smallest weight of a new frame in the blend (`1/length` before that: a plain mean). SVGF
    /// uses 0.2; lower is smoother and lags more behind moving light.
    pub min_alpha: f32,
    history: Option<History>,
    /// The history before that, whose memory the next frame's history reuses.
    spare: Option<History>,
    /// The spatial filter's planes, which the next frame reuses.
    memory: Memory,
}

/// The planes a frame's filtering writes, and the passes each pixel needs, kept for the next
/// frame's: at 256² (three passes) they are 6 MB, which would otherwise be allocated and
/// cleared again every frame.
#[derive(Default)]
struct Memory {
    planes: Option<GuidePlanes>,
    signal: Option<Signal>,
    filter: FilterMemory,
    /// The passes each pixel needs.
    needs: Vec<u8>,
}

impl std::fmt::Debug for Memory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Memory").finish_non_exhaustive()
    }
}

impl Clone for Temporal {
    /// The filter and its history (not the spare memory).
    fn clone(&self) -> Self {
        Self {
            atrous: self.atrous,
            converged_passes: self.converged_passes,
            min_alpha: self.min_alpha,
            history: self.history.clone(),
            spare: None,
            memory: Memory::default(),
        }
    }
}

impl Default for Temporal {
    /// Three passes (14 pixels each way) rather than SVGF's five: with the history's samples
    /// the later passes only blurred (`tests/pipeline.rs`, the moving Cornell box, RMSE of the
    /// last frame: 0.00730 with five, 0.00696 with four, 0.00688 with three; the same frame
    /// with no history 0.0472 with four, 0.0473 with three, 0.0481 with two), and each costs
    /// a quarter of the filter's time. Pixels with a history then get two passes: the moving
    /// views of the four reference scenes (16 frames) came out as close to the references as
    /// with three (RMSE within −2 % … +4 %), and one pass was 13 % worse on the glass and
    /// mirror scene (`docs/dynamic/history.md`).
    fn default() -> Self {
        Self {
            atrous: Atrous { passes: 3, ..Atrous::default() },
            converged_passes: 2,
            min_alpha: 0.1,
            history: None,
            spare: None,
            memory: Memory::default(),
        }
    }
}

/// The previous frame as the next one reads it.
#[derive(Clone, Debug)]
struct History {
    camera: Camera,
    width: usize,
    height: usize,
    normal: Vec<Vec3>,
    position: Vec<Vec3>,
    illumination: Vec<Vec3>,
    /// The luminance's first and second moments.
    moments: Vec<[f32; 2]>,
    /// Frames blended so far (0: not a surface).
    length: Vec<f32>,
}

/// A pixel's history, read from the previous frame.
#[derive(Clone, Copy, Default)]
struct Reprojected {
    illumination: Vec3,
    moments: [f32; 2],
    length: f32,
}

impl Temporal {
    /// Forgets the previous frames (the next frame starts a new history).
    pub fn reset(&mut self) {
        // Its memory serves the next history.
        if let Some(history) = self.history.take() {
            self.spare = Some(history);
        }
    }

    /// Frames blended into `pixel`'s history by the last [`Temporal::denoise`] (0 off surfaces).
    pub fn history_length(&self, pixel: usize) -> f32 {
        self.history.as_ref().map_or(0.0, |h| h.length[pixel])
    }

    /// Denoises one frame: `colour` (its samples, typically one per pixel) seen through
    /// `camera`, whose first hits are `guide`; the history moves on to this frame.
    pub fn denoise(&mut self, colour: &[Vec3], guide: &Guide, camera: &Camera) -> Vec<Vec3> {
        let (w, h) = (guide.width as usize, guide.height as usize);
        assert_eq!(colour.len(), w * h, "image and guide sizes differ");
        let albedo = |i: usize| guide.albedo[i].max(Vec3::splat(MIN_ALBEDO));
        let history = self.history.take().filter(|old| old.width == w && old.height == h);
        let mut next = self.spare.take().filter(|old| old.width == w && old.height == h).unwrap_or_else(|| History {
            camera: camera.clone(),
            width: w,
            height: h,
            normal: vec![Vec3::ZERO; w * h],
            position: vec![Vec3::ZERO; w * h],
            illumination: vec![Vec3::ZERO; w * h],
            moments: vec![[0.0; 2]; w * h],
            length: vec![0.0; w * h],
        });
        // The blend, row by row: this frame's illumination into the reprojected history.
        // `next.illumination` holds the blended illumination until the first pass replaces it.
        // The surfaces the next frame reprojects onto are copied in the same pass, while the
        // blend has them in the cache.
        let mut memory = std::mem::take(&mut self.memory);
        memory.needs.resize(w * h, 0);
        let (all_passes, converged_passes) = (self.atrous.passes.min(255) as u8, self.converged_passes.min(255) as u8);
        let rows = (
            memory.needs.par_chunks_mut(w.max(1)),
            next.illumination.par_chunks_mut(w.max(1)),
            next.moments.par_chunks_mut(w.max(1)),
            next.length.par_chunks_mut(w.max(1)),
            next.normal.par_chunks_mut(w.max(1)),
            next.position.par_chunks_mut(w.max(1)),
        );
        rows.into_par_iter().enumerate().for_each(
            |(y, (needs_row, illumination_row, moments_row, length_row, normal_row, position_row))| {
                let row = y * w..(y + 1) * w;
                normal_row.copy_from_slice(&guide.normal[row.clone()]);
                position_row.copy_from_slice(&guide.position[row]);
                for (x, (((blended_illumination, moments), length), needs)) in
                    illumination_row.iter_mut().zip(moments_row).zip(length_row).zip(needs_row).enumerate()
                {
                    let i = y * w + x;
                    let blended = self.blend(colour[i] / albedo(i), guide, history.as_ref(), i);
                    (*blended_illumination, *moments, *length) =
                        (blended.illumination, blended.moments, blended.length);
                    // (Pixels off the surfaces come out of every pass as they went in.)
                    *needs = if guide.footprint[i] <= 0.0 {
                        0
                    } else if blended.length < ALL_PASSES_UNTIL {
                        all_passes
                    } else {
                        converged_passes
                    };
                }
            },
        );
        let planes = GuidePlanes::reusing(memory.planes.take(), guide, self.atrous.passes);
        // The distances of the neighbours of a short history's variance, in pixels (at least
        // 1), by |dy| and |dx|.
        let distances: Distances =
            std::array::from_fn(|dy| std::array::from_fn(|dx| (((dx * dx + dy * dy) as f32).sqrt()).max(1.0)));
        let signal = Signal::from_fn_reusing(memory.signal.take(), &planes, |i| {
            (next.illumination[i], self.variance(guide, &next, &distances, i))
        });
        let filtered = self.atrous.filter_reusing(&planes, signal, &mut memory.filter, Some(&memory.needs), |first| {
            first.pixels_into(&mut next.illumination)
        });
        let mut out = vec![Vec3::ZERO; w * h];
        filtered.pixels_into_with(&mut out, |i, p| if guide.footprint[i] > 0.0 { p * albedo(i) } else { colour[i] });
        (memory.planes, memory.signal) = (Some(planes), Some(filtered));
        self.memory = memory;
        next.camera.clone_from(camera);
        self.spare = history;
        self.history = Some(next);
        out
    }

    /// Pixel `i`'s illumination (this frame's sample over its albedo) blended into its
    /// reprojected history.
    fn blend(&self, illumination: Vec3, guide: &Guide, history: Option<&History>, i: usize) -> Reprojected {
        if guide.footprint[i] <= 0.0 {
            return Reprojected::default();
        }
        let l = luminance(illumination);
        let old = history.and_then(|old| old.reproject(guide, i));
        if !illumination.is_finite() {
            // A non-finite sample is left out: the history goes on as it was (or, with
            // none, the pixel has no estimate, which the spatial filter leaves out).
            return old.unwrap_or(Reprojected { illumination: Vec3::NAN, ..Reprojected::default() });
        }
        let length = (old.map_or(0.0, |o| o.length) + 1.0).min(MAX_HISTORY);
        let alpha = (1.0 / length).max(self.min_alpha);
        let old = old.unwrap_or(Reprojected { illumination, moments: [l, l * l], length: 0.0 });
        Reprojected {
            illumination: old.illumination.lerp(illumination, alpha),
            moments: [old.moments[0] + alpha * (l - old.moments[0]), old.moments[1] + alpha * (l * l - old.moments[1])],
            length,
        }
    }

    /// The variance of pixel `i`'s blended estimate (its moments and history length in
    /// `next`, the history being made): the sample variance from its moments (or its
    /// neighbours' on a short history, `distances[|dy|][|dx|]` pixels away) times the
    /// blend's share of one sample.
    fn variance(&self, guide: &Guide, next: &History, distances: &Distances, i: usize) -> f32 {
        let (w, h) = (guide.width as i64, guide.height as i64);
        let length = next.length[i];
        if length <= 0.0 {
            return 0.0;
        }
        let [m1, m2] = if length >= SPATIAL_VARIANCE_UNTIL {
            next.moments[i]
        } else {
            // A 7×7 neighbourhood of the same surface (weights as the filter's, without
            // the luminance).
            let (x, y) = (i as i64 % w, i as i64 / w);
            let (n, p, f) = (guide.normal[i], guide.position[i], guide.footprint[i]);
            let (mut sum, mut total) = ([0.0f32; 2], 0.0f32);
            let r = VARIANCE_RADIUS as i64;
            for qy in (y - r).max(0)..(y + r + 1).min(h) {
                for qx in (x - r).max(0)..(x + r + 1).min(w) {
                    let j = (qy * w + qx) as usize;
                    let offset = distances[(qy - y).unsigned_abs() as usize][(qx - x).unsigned_abs() as usize];
                    if next.length[j] <= 0.0 || !same_surface(n, p, f, guide.normal[j], guide.position[j], offset) {
                        continue;
                    }
                    sum[0] += next.moments[j][0];
                    sum[1] += next.moments[j][1];
                    total += 1.0;
                }
            }
            [sum[0] / total, sum[1] / total]
        };
        let sample_variance = (m2 - m1 * m1).max(0.0);
        // A mean of `length` samples, or at steady state the exponential blend's
        // α / (2 − α).
        let alpha = self.min_alpha;
        sample_variance * (1.0 / length).max(alpha / (2.0 - alpha))
    }
}

impl History {
    /// Pixel `i`'s history: the previous pixels around where its first hit was seen, those of
    /// the same surface, bilinearly weighted (`None`: none is).
    fn reproject(&self, guide: &Guide, i: usize) -> Option<Reprojected> {
        let (n, p, f) = (guide.normal[i], guide.position[i], guide.footprint[i]);
        let (u, v) = self.camera.project(p)?;
        // Pixel centres lie at half-integer coordinates; points far off the image are clamped
        // to just outside it (they find nothing either way, and the integer casts stay small).
        let (u, v) = ((u - 0.5).clamp(-2.0, self.width as f32 + 1.0), (v - 0.5).clamp(-2.0, self.height as f32 + 1.0));
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (mut sum, mut total) = (Reprojected::default(), 0.0f32);
        for (dx, dy, weight) in
            [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
        {
            let (x, y) = (x0 as i64 + dx, y0 as i64 + dy);
            if !(0..self.width as i64).contains(&x) || !(0..self.height as i64).contains(&y) {
                continue;
            }
            let j = y as usize * self.width + x as usize;
            if self.length[j] > 0.0 && weight > 0.0 && same_surface(n, p, f, self.normal[j], self.position[j], 1.0) {
                sum.illumination += self.illumination[j] * weight;
                sum.moments[0] += self.moments[j][0] * weight;
                sum.moments[1] += self.moments[j][1] * weight;
                sum.length += self.length[j] * weight;
                total += weight;
            }
        }
        let inv_total = 1.0 / total;
        (total > 1e-3).then(|| Reprojected {
            illumination: sum.illumination * inv_total,
            moments: [sum.moments[0] * inv_total, sum.moments[1] * inv_total],
            length: sum.length * inv_total,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraDesc;
    use crate::sampler::Pcg32;

    const W: u32 = 48;
    const H: u32 = 32;

    /// A camera at z = 10 looking down −z at the wall z = 0, and the wall's guide as the
    /// camera sees it.
    fn view(x_offset: f32) -> (Camera, Guide) {
        let desc = CameraDesc {
            position: Vec3::new(x_offset, 0.0, 10.0),
            look_at: Vec3::new(x_offset, 0.0, 0.0),
            up: Vec3::Y,
            vfov_degrees: 60.0,
        };
        let camera = Camera::new(&desc, W, H);
        let n = (W * H) as usize;
        let position: Vec<Vec3> = (0..n)
            .map(|i| {
                let ray = camera.ray((i as u32 % W) as f32 + 0.5, (i as u32 / W) as f32 + 0.5);
                ray.origin + ray.dir * (10.0 / -ray.dir.z)
            })
            .collect();
        let footprint = 2.0 * 10.0 * (30.0f32).to_radians().tan() / H as f32;
        let guide = Guide {
            width: W,
            height: H,
            albedo: vec![Vec3::splat(0.5); n],
            normal: vec![Vec3::Z; n],
            position,
            footprint: vec![footprint; n],
        };
        (camera, guide)
    }

    /// One noisy frame: `level(world x)` plus noise of standard deviation `sd`.
    fn frame(guide: &Guide, level: impl Fn(f32) -> f32, sd: f32, rng: &mut Pcg32) -> Vec<Vec3> {
        guide
            .position
            .iter()
            .map(|p| {
                let u: f32 = (0..4).map(|_| rng.next_f32() - 0.5).sum::<f32>() * (3.0f32).sqrt();
                Vec3::splat((level(p.x) + sd * u) * 0.5)
            })
            .collect()
    }

    fn rmse(image: &[Vec3], level: impl Fn(usize) -> f32) -> f32 {
        (image.iter().enumerate().map(|(i, c)| (c.x - level(i)).powi(2)).sum::<f32>() / image.len() as f32).sqrt()
    }

    /// The camera pans across a wall lit by a ramp; each frame's output is close to the truth
    /// (far closer than the à-trous filter of that frame alone), and the history follows the
    /// wall (it grows, however the pixels move).
    #[test]
    fn a_panning_view_accumulates_and_stays_right() {
        let ramp = |x: f32| 0.5 + 0.03 * x;
        let mut rng = Pcg32::new(7, 1);
        let mut temporal = Temporal::default();
        for step in 0..20 {
            let (camera, guide) = view(step as f32 * 0.13);
            let colour = frame(&guide, ramp, 0.3, &mut rng);
            let out = temporal.denoise(&colour, &guide, &camera);
            let truth = |i: usize| ramp(guide.position[i].x) * 0.5;
            let alone = Atrous::default().denoise(&colour, &vec![Vec3::splat(0.0225); colour.len()], &guide);
            if step >= 10 {
                let (ours, spatial) = (rmse(&out, truth), rmse(&alone, truth));
                assert!(ours < 0.6 * spatial, "frame {step}: rmse {ours} against the frame alone's {spatial}");
                let centre = (H / 2 * W + W / 2) as usize;
                assert!(temporal.history_length(centre) > 10.0, "history {}", temporal.history_length(centre));
            }
        }
    }

    /// The planes kept from the last frame (and from a frame of another size before it) give
    /// the same image, to the bit, as planes made afresh (by a clone, which keeps the history
    /// but not the memory), while the surfaces change from frame to frame.
    #[test]
    fn reused_memory_changes_nothing() {
        let mut rng = Pcg32::new(11, 1);
        let mut temporal = Temporal::default();
        let small = Guide { width: W / 2, height: H / 2, ..view(0.0).1 };
        let small = Guide {
            albedo: small.albedo[..(W * H / 4) as usize].to_vec(),
            normal: small.normal[..(W * H / 4) as usize].to_vec(),
            position: small.position[..(W * H / 4) as usize].to_vec(),
            footprint: small.footprint[..(W * H / 4) as usize].to_vec(),
            ..small
        };
        temporal.denoise(&frame(&small, |_| 0.4, 0.2, &mut rng), &small, &view(0.0).0);
        for step in 0..4 {
            let (camera, mut guide) = view(step as f32 * 0.2);
            // A band of sky as wide as the widest lanes' chunk (so that the filter skips its
            // taps), which moves from frame to frame (so that the reused planes held a
            // surface there before), and a narrower one.
            let sky = |x: usize| (16 * (step % 3)..16 * (step % 3) + 16).contains(&x) || x.abs_diff(5 + 9 * step) < 2;
            for i in (0..(W * H) as usize).filter(|i| sky(i % W as usize)) {
                (guide.normal[i], guide.position[i], guide.footprint[i]) = (Vec3::ZERO, Vec3::ZERO, 0.0);
            }
            let colour = frame(&guide, |x| 0.3 + 0.02 * x, 0.3, &mut rng);
            let mut fresh = temporal.clone();
            let reused = temporal.denoise(&colour, &guide, &camera);
            let made = fresh.denoise(&colour, &guide, &camera);
            let bits = |image: &[Vec3]| image.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
            assert_eq!(bits(&reused), bits(&made), "frame {step}");
        }
    }

    /// A pixel without a history yet gets all of the spatial filter's passes, whatever
    /// `converged_passes` says; once its history is long enough, it gets `converged_passes`.
    #[test]
    fn short_histories_get_all_passes() {
        let (camera, guide) = view(0.0);
        let mut rng = Pcg32::new(5, 1);
        let frames: Vec<Vec<Vec3>> = (0..6).map(|_| frame(&guide, |x| 0.4 + 0.02 * x, 0.3, &mut rng)).collect();
        let bits = |image: &[Vec3]| image.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
        let (mut one, mut all) = (Temporal { converged_passes: 1, ..Temporal::default() }, Temporal::default());
        all.converged_passes = all.atrous.passes;
        for (k, colour) in frames.iter().enumerate() {
            let (a, b) = (one.denoise(colour, &guide, &camera), all.denoise(colour, &guide, &camera));
            let short = (k as f32 + 1.0) < ALL_PASSES_UNTIL;
            assert_eq!(bits(&a) == bits(&b), short, "frame {k}");
        }
    }

    /// A surface appears where another was: no trace of the old one's light (its history is
    /// dropped), only the new one's.
    #[test]
    fn a_disocclusion_starts_a_new_history() {
        let mut rng = Pcg32::new(9, 1);
        let mut temporal = Temporal::default();
        let (camera, guide) = view(0.0);
        for _ in 0..10 {
            let colour = frame(&guide, |_| 0.2, 0.05, &mut rng);
            temporal.denoise(&colour, &guide, &camera);
        }
        // The right half is now a wall 3 units nearer, facing the camera, much brighter.
        let mut near = guide.clone();
        let right = |i: usize| (i as u32 % W) >= W / 2;
        for i in 0..(W * H) as usize {
            if right(i) {
                near.position[i].z = 3.0;
            }
        }
        let colour: Vec<Vec3> = frame(&near, |_| 0.2, 0.05, &mut rng)
            .iter()
            .enumerate()
            .map(|(i, c)| if right(i) { *c + Vec3::splat(0.3) } else { *c })
            .collect();
        let out = temporal.denoise(&colour, &near, &camera);
        for (i, pixel) in out.iter().enumerate() {
            let expected = if right(i) { 0.4 } else { 0.1 };
            assert!((pixel.x - expected).abs() < 0.04, "pixel {i}: {} for {expected}", pixel.x);
            let length = temporal.history_length(i);
            assert!((length - if right(i) { 1.0 } else { 11.0 }).abs() < 1e-3, "pixel {i}: history {length}");
        }
    }
}
