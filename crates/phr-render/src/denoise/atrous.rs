//! The edge-avoiding à-trous wavelet filter (Dammertz, Sewtz, Hanika & Lensch 2010), with the
//! variance-guided luminance weight of SVGF (Schied et al. 2017).
//!
//! Each pass is a 5×5 B3-spline kernel whose taps lie `2^i` pixels apart (pass `i`), so five
//! passes cover 61×61 pixels at 25 taps per pixel each. A tap's weight is cut down where it
//! leaves the surface of the centre pixel:
//! - **normals** that differ: `max(0, n_p · n_q)^σn`;
//! - **positions** off the centre's tangent plane, measured in pixel footprints at the
//!   centre's distance (the plane distance of a neighbour on the same flat surface is 0, a
//!   step in depth is many footprints);
//! - **illumination** that differs by more than its noise: `|l_p − l_q| / (σl · σ(l_p))`, with
//!   σ(l_p) the standard deviation of the pixel's estimate (carried through the passes as a
//!   filtered variance shrinks, and smoothed over 3×3 before each pass, as in SVGF).
//!
//! The buffers are planes of `f32` (structure of arrays), each row padded on both sides with
//! pixels off every surface. A pass takes a row 16 pixels at a time (AVX-512; 8 with AVX2, 1
//! elsewhere, [`Lanes`]) and adds all 25 taps to those pixels' sums in registers (a chunk
//! with no surface pixel, all sky or light, skips them: a third of the carousel's pixels); the
//! padding lets a chunk's taps read past the row's ends without a test, and `exp` is a
//! polynomial ([`exp_neg`]) that runs on the lanes (the library's is a call per lane).

use super::lanes::{exp_neg, Lanes, Scalar};
#[cfg(target_arch = "x86_64")]
use super::lanes::{Avx2, Avx512};
use super::Guide;
use glam::Vec3;
use phr_bvh::SimdLevel;
use rayon::prelude::*;

/// The filter's settings; the defaults are SVGF's (σl = 4, and the normal exponent 128) and
/// one footprint for the plane distance.
#[derive(Clone, Copy, Debug)]
pub struct Atrous {
    /// Passes (`2^passes − 1` pixels reach, times 2, on each side).
    pub passes: u32,
    pub sigma_luminance: f32,
    pub sigma_plane: f32,
}

impl Default for Atrous {
    fn default() -> Self {
        Self { passes: 5, sigma_luminance: 4.0, sigma_plane: 1.0 }
    }
}

/// The normal weight is `max(0, n_p · n_q)^(2^NORMAL_POWER)`: SVGF's exponent 128, by squaring.
const NORMAL_POWER: u32 = 7;

/// The B3-spline kernel's weights at offsets −2..=2.
const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// Beyond `e^-MAX_EXPONENT` a tap counts for nothing.
const MAX_EXPONENT: f32 = 20.0;

/// `e^-MAX_EXPONENT`: a tap whose normal and exponential weights together fall below it
/// counts for nothing. This also keeps the arithmetic away from subnormal floats (the
/// normal weight of a tap across an edge would underflow), each of which costs the CPU a
/// slow microcode assist: 20 % of the tap loop's time on a moving frame before.
const MIN_FALLOFF: f32 = 2.061_153_6e-9;

/// The normal weight's cosine is raised from at least this (`0.85^128 < MIN_FALLOFF`, so
/// such taps do not count either).
const MIN_NORMAL_COS: f32 = 0.85;

pub(crate) use crate::film::luminance;

/// Pixels of padding on each side of a row of `width` pixels in the planes the taps read: the
/// farthest tap of `passes` passes (2 steps of `2^(passes − 1)`, but taps a whole row or more
/// away are skipped) plus a chunk of the widest lanes, so that a chunk's taps never leave
/// their row's memory. The padding is off every surface (an infinite luminance), so the taps
/// there count for nothing.
fn padding(passes: u32, width: usize) -> usize {
    let widest = 1usize.checked_shl(passes.saturating_sub(1)).unwrap_or(usize::MAX);
    widest.saturating_mul(2).min(width) + MAX_LANES
}

/// The widest [`Lanes`] type's lanes.
const MAX_LANES: usize = 16;

/// A pixel off every surface in a [`Signal`]'s planes (colour, variance, luminance): no
/// colour, and an infinite luminance, so that a tap there counts for nothing.
const OFF_SURFACE: [f32; 5] = [0.0, 0.0, 0.0, 0.0, f32::INFINITY];

/// `K` planes of `width` values a row with `pad` values of `fill` on each side of every row,
/// pixel `i`'s values from `value(i)`: one pass over the rows, in parallel. `memory`'s
/// planes are written over if they have the length of this layout, else new ones are made:
/// the caller promises that planes of that length were made for this layout and `fill` (a
/// padding keeps its values: a pass writes there only the values it holds).
fn padded_planes<const K: usize>(
    memory: Option<[Vec<f32>; K]>,
    rows: usize,
    width: usize,
    pad: usize,
    fill: [f32; K],
    value: impl Fn(usize) -> [f32; K] + Sync,
) -> [Vec<f32>; K] {
    let stride = width + 2 * pad;
    let mut planes = memory
        .filter(|planes| planes.iter().all(|p| p.len() == stride * rows))
        .unwrap_or_else(|| fill.map(|f| vec![f; stride * rows]));
    if stride == 0 {
        return planes;
    }
    let mut chunks: Vec<_> = planes.iter_mut().map(|p| p.chunks_mut(stride)).collect();
    let row_sets: Vec<[&mut [f32]; K]> =
        (0..rows).map(|_| std::array::from_fn(|k| chunks[k].next().expect("rows × stride values"))).collect();
    row_sets.into_par_iter().enumerate().for_each(|(y, mut row)| {
        for x in 0..width {
            for (plane, v) in row.iter_mut().zip(value(y * width + x)) {
                plane[pad + x] = v;
            }
        }
    });
    planes
}

/// Per-pixel planes of a frame's first surfaces: what every pass reads unchanged. The
/// normals and positions are [`padded_planes`] rows of `stride` values.
pub(crate) struct GuidePlanes {
    pub width: usize,
    pub height: usize,
    pad: usize,
    stride: usize,
    normal: [Vec<f32>; 3],
    position: [Vec<f32>; 3],
    /// 0: not a surface to filter ([`Guide::footprint`]); not padded.
    footprint: Vec<f32>,
    /// The same, padded (with 0).
    footprint_padded: Vec<f32>,
    /// The surface mask (1 on surfaces) under [`blur_3x3_into`]: the weights that normalise each
    /// pass's blurred variance, the same for every pass.
    surface_blurred: Vec<f32>,
}

impl GuidePlanes {
    /// The planes for up to `passes` passes.
    pub fn new(guide: &Guide, passes: u32) -> Self {
        Self::reusing(None, guide, passes)
    }

    /// [`GuidePlanes::new`], in `memory`'s planes if it has the same layout (a filter
    /// that runs every frame need not allocate and clear them again).
    pub fn reusing(memory: Option<Self>, guide: &Guide, passes: u32) -> Self {
        let (width, height) = (guide.width as usize, guide.height as usize);
        let pad = padding(passes, width);
        let memory = memory.filter(|m| (m.width, m.height, m.pad) == (width, height, pad));
        let (old_planes, mut footprint, mut surface_blurred) = match memory {
            Some(m) => {
                let [nx, ny, nz] = m.normal;
                let [px, py, pz] = m.position;
                (Some([nx, ny, nz, px, py, pz, m.footprint_padded]), m.footprint, m.surface_blurred)
            }
            None => (None, Vec::new(), Vec::new()),
        };
        let [nx, ny, nz, px, py, pz, footprint_padded] = padded_planes(old_planes, height, width, pad, [0.0; 7], |i| {
            let (n, p) = (guide.normal[i], guide.position[i]);
            [n.x, n.y, n.z, p.x, p.y, p.z, guide.footprint[i]]
        });
        footprint.clone_from(&guide.footprint);
        let surface: Vec<f32> = guide.footprint.par_iter().map(|f| if *f > 0.0 { 1.0 } else { 0.0 }).collect();
        surface_blurred.resize(width * height, 0.0);
        blur_3x3_into(&surface, width, height, 0, &mut surface_blurred, |_| true, |_, sum| sum);
        Self {
            width,
            height,
            pad,
            stride: width + 2 * pad,
            normal: [nx, ny, nz],
            position: [px, py, pz],
            footprint,
            footprint_padded,
            surface_blurred,
        }
    }
}

/// What a pass filters: the illumination (three planes), the variance of its luminance (0
/// off surfaces), and the luminance itself (infinite off surfaces: a tap there gets an
/// infinite exponent, so the tap loop needs no test of its own for it). Laid out as the
/// guide's planes ([`padded_planes`], the padding off every surface: [`OFF_SURFACE`]), so
/// that a pass's output is the next pass's input as it is.
pub(crate) struct Signal {
    colour: [Vec<f32>; 3],
    var: Vec<f32>,
    lum: Vec<f32>,
    width: usize,
    pad: usize,
}

impl Signal {
    /// The signal of pixels `illumination` with luminance variances `var`, laid out for
    /// `guide`.
    pub fn new(guide: &GuidePlanes, illumination: &[Vec3], var: &[f32]) -> Self {
        Self::from_fn(guide, |i| (illumination[i], var[i]))
    }

    /// The signal whose pixel `i` has the illumination and luminance variance `pixel(i)`,
    /// laid out for `guide`.
    pub fn from_fn(guide: &GuidePlanes, pixel: impl Fn(usize) -> (Vec3, f32) + Sync) -> Self {
        Self::from_fn_reusing(None, guide, pixel)
    }

    /// [`Signal::from_fn`], in `memory`'s planes if it was laid out for `guide`.
    pub fn from_fn_reusing(
        memory: Option<Self>,
        guide: &GuidePlanes,
        pixel: impl Fn(usize) -> (Vec3, f32) + Sync,
    ) -> Self {
        let (w, h, pad) = (guide.width, guide.height, guide.pad);
        let memory = memory.filter(|m| m.fits(guide)).map(|m| {
            let [r, g, b] = m.colour;
            [r, g, b, m.var, m.lum]
        });
        // Taps are surface pixels with a finite estimate; the others hold 0 (a NaN or an
        // infinity times a tap's weight of 0 would still spread) and an infinite luminance.
        let [r, g, b, var, lum] = padded_planes(memory, h, w, pad, OFF_SURFACE, |i| {
            if guide.footprint[i] > 0.0 {
                let (c, v) = pixel(i);
                // (`max` also makes NaN 0.)
                if c.is_finite() {
                    return [c.x, c.y, c.z, v.max(0.0), luminance(c)];
                }
            }
            OFF_SURFACE
        });
        Self { colour: [r, g, b], var, lum, width: w, pad }
    }

    /// The pixels, row-major, without the padding, into `out`.
    pub fn pixels_into(&self, out: &mut [Vec3]) {
        self.pixels_into_with(out, |_, p| p);
    }

    /// Pixel `i`'s value `p` as `finish(i, p)`, row-major, into `out`.
    pub fn pixels_into_with(&self, out: &mut [Vec3], finish: impl Fn(usize, Vec3) -> Vec3 + Sync) {
        let (w, stride) = (self.width, self.width + 2 * self.pad);
        assert_eq!(out.len(), self.pixel_count(), "one value per pixel");
        out.par_chunks_mut(w.max(1)).enumerate().for_each(|(y, row)| {
            let j = y * stride + self.pad;
            let [r, g, b] = &self.colour;
            for (x, p) in row.iter_mut().enumerate() {
                *p = finish(y * w + x, Vec3::new(r[j + x], g[j + x], b[j + x]));
            }
        });
    }

    /// The pixels, row-major, without the padding.
    pub fn pixels(&self) -> Vec<Vec3> {
        let mut out = vec![Vec3::ZERO; self.pixel_count()];
        self.pixels_into(&mut out);
        out
    }

    fn pixel_count(&self) -> usize {
        self.colour[0].len() / (self.width + 2 * self.pad) * self.width
    }
}

/// Memory an [`Atrous::filter_reusing`] keeps for the next: the planes a pass writes into, the
/// blurred variance's, and the passes of the groups of pixels.
#[derive(Default)]
pub(crate) struct FilterMemory {
    spare: Option<Signal>,
    blurred: Vec<f32>,
    /// Per row, the most passes a pixel of each group of [`MAX_LANES`] needs (at least 1).
    groups: Vec<u8>,
    /// The width, height and padding `blurred` was made for.
    blurred_layout: (usize, usize, usize),
}

/// What [`Atrous::row`] reads: the guide, the pass's signal and blurred variance, the row, the
/// step, and where given the passes each group of [`MAX_LANES`] pixels of the row needs with
/// the pass's number.
type RowArgs<'a> = (&'a GuidePlanes, &'a Signal, &'a [f32], usize, usize, Option<(&'a [u8], u8)>);

/// Where [`Atrous::row`] writes row `y` of the pass's output: its padded rows (`stride`
/// values) of the three colour planes, the variance and the luminance.
type OutRow<'a> = [&'a mut [f32]; 5];

impl Signal {
    /// A signal laid out for `guide` with every pixel off the surfaces (0, and an infinite
    /// luminance): what a pass writes into, row by row.
    fn empty(guide: &GuidePlanes) -> Self {
        let [r, g, b, var, lum] = OFF_SURFACE.map(|fill| vec![fill; guide.stride * guide.height]);
        Self { colour: [r, g, b], var, lum, width: guide.width, pad: guide.pad }
    }

    /// Whether it is laid out for `guide` (what a pass reads and writes).
    fn fits(&self, guide: &GuidePlanes) -> bool {
        let len = guide.stride * guide.height;
        self.width == guide.width
            && self.pad == guide.pad
            && self.colour.iter().chain([&self.var, &self.lum]).all(|p| p.len() == len)
    }
}

impl Atrous {
    /// Runs the passes over `signal`; `after_first(&signal)` sees the result of the first pass
    /// (SVGF keeps it as the temporal history). `guide` must have been made for at least
    /// this filter's passes, and `signal` laid out for it (its memory takes a later pass's
    /// output).
    pub(crate) fn filter(&self, guide: &GuidePlanes, signal: Signal, after_first: impl FnMut(&Signal)) -> Signal {
        self.filter_reusing(guide, signal, &mut FilterMemory::default(), None, after_first)
    }

    /// [`Atrous::filter`], taking the planes its passes write into from `memory` (when they
    /// fit the guide) and leaving them there for the next call. With `needs` (a pass count
    /// per pixel, row-major), a pass leaves alone each group of [`MAX_LANES`] pixels of a row
    /// (from its start) whose pixels all need fewer passes than it: their values go on as the
    /// pass before left them. The first pass runs everywhere.
    pub(crate) fn filter_reusing(
        &self,
        guide: &GuidePlanes,
        mut signal: Signal,
        memory: &mut FilterMemory,
        needs: Option<&[u8]>,
        mut after_first: impl FnMut(&Signal),
    ) -> Signal {
        assert!(needs.is_none_or(|n| n.len() == guide.width * guide.height), "a pass count per pixel");
        // Each pass writes into the planes the pass before it read: one signal's memory more
        // for the whole filter, not one per pass.
        assert!(signal.fits(guide), "the signal was laid out for another guide");
        let mut spare = memory.spare.take().filter(|s| s.fits(guide));
        let layout = (guide.width, guide.height, guide.pad);
        if memory.blurred_layout != layout {
            // Its padding must be 0 (what `blurred_variance` leaves there).
            (memory.blurred, memory.blurred_layout) = (vec![0.0; guide.stride * guide.height], layout);
        }
        let (blurred, groups) = (&mut memory.blurred, &mut memory.groups);
        // The passes each group needs, decided once: the same groups for every lane width, so
        // that every compiled loop gives the same image.
        let row_groups = guide.width.div_ceil(MAX_LANES);
        let needs = needs.map(|needs| {
            groups.clear();
            groups.extend(
                needs
                    .chunks(guide.width.max(1))
                    .flat_map(|row| row.chunks(MAX_LANES).map(|group| group.iter().fold(1, |most, &n| most.max(n)))),
            );
            &groups[..]
        });
        for pass in 0..self.passes {
            // Steps this wide are wider than any image: the passes left would keep only their
            // centre taps.
            let Some(step) = 1usize.checked_shl(pass).filter(|s| *s <= isize::MAX as usize / 4) else { break };
            let mut out = spare.take().unwrap_or_else(|| Signal::empty(guide));
            let needs = needs.filter(|_| pass > 0).map(|n| (n, pass.min(u8::MAX as u32) as u8));
            // Only the rows the pass filters read their blurred variance.
            let filtered = |y: usize| {
                needs.is_none_or(|(n, pass)| n[y * row_groups..(y + 1) * row_groups].iter().any(|&k| k > pass))
            };
            blurred_variance(guide, &signal, blurred, filtered);
            self.pass(guide, &signal, blurred, step, needs, &mut out);
            spare = Some(std::mem::replace(&mut signal, out));
            if pass == 0 {
                after_first(&signal);
            }
        }
        memory.spare = spare;
        signal
    }

    /// One pass with taps `step` pixels apart, from `signal` (whose variance is `blurred`
    /// after [`blurred_variance`]) into `out` (laid out for `guide` as `signal` is). Every
    /// pixel is written, but those of the groups that `groups` says are done (see
    /// [`Atrous::filter_reusing`]); the padding keeps its values (the lanes of a row's last
    /// chunk that fall in it write the same values again).
    fn pass(
        &self,
        guide: &GuidePlanes,
        signal: &Signal,
        blurred: &[f32],
        step: usize,
        groups: Option<(&[u8], u8)>,
        out: &mut Signal,
    ) {
        // Each row of `out` is one row of the image (the rows below take it so).
        assert!(out.fits(guide), "the output was laid out for another guide");
        let stride = guide.stride;
        let wide = SimdLevel::detect() == SimdLevel::Avx2;
        #[cfg(target_arch = "x86_64")]
        let widest = wide && std::arch::is_x86_feature_detected!("avx512f");
        #[cfg(not(target_arch = "x86_64"))]
        let widest = false;
        let [out_r, out_g, out_b] = &mut out.colour;
        let rows = (
            out_r.par_chunks_mut(stride),
            out_g.par_chunks_mut(stride),
            out_b.par_chunks_mut(stride),
            out.var.par_chunks_mut(stride),
            out.lum.par_chunks_mut(stride),
        );
        rows.into_par_iter().enumerate().for_each(|(y, (r, g, b, var, lum))| {
            let row_groups = guide.width.div_ceil(MAX_LANES);
            let row_needs = groups.map(|(n, pass)| (&n[y * row_groups..(y + 1) * row_groups], pass));
            let args = (guide, signal, blurred, y, step, row_needs);
            let row = [r, g, b, var, lum];
            if widest {
                // SAFETY: the CPU has AVX-512 F (checked above).
                unsafe { self.row_avx512(args, row) }
            } else if wide {
                // SAFETY: the CPU has AVX2 (checked above).
                unsafe { self.row_avx2(args, row) }
            } else {
                self.row_portable(args, row)
            }
        });
    }

    /// [`Atrous::row`] one pixel at a time.
    fn row_portable(&self, args: RowArgs, out: OutRow) {
        // SAFETY: `Scalar` needs no CPU feature.
        unsafe { self.row::<Scalar>(args, out) }
    }

    /// [`Atrous::row`] 8 pixels at a time.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn row_avx2(&self, args: RowArgs, out: OutRow) {
        // SAFETY: compiled for AVX2, which `Avx2` needs.
        unsafe { self.row::<Avx2>(args, out) }
    }

    /// [`Atrous::row`] 16 pixels at a time.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn row_avx512(&self, args: RowArgs, out: OutRow) {
        // SAFETY: compiled for AVX-512 F, which `Avx512` needs.
        unsafe { self.row::<Avx512>(args, out) }
    }

    /// Never called: there is no AVX-512 off x86-64.
    #[cfg(not(target_arch = "x86_64"))]
    unsafe fn row_avx512(&self, args: RowArgs, out: OutRow) {
        self.row_portable(args, out)
    }

    /// Never called: [`SimdLevel::detect`] finds no AVX2 off x86-64.
    #[cfg(not(target_arch = "x86_64"))]
    unsafe fn row_avx2(&self, args: RowArgs, out: OutRow) {
        self.row_portable(args, out)
    }

    /// Row `y` of the pass, `V::N` centre pixels at a time: their data and their sums stay in
    /// registers while the 25 taps are added in turn, and the normalised result goes
    /// straight to the output rows (colour, variance and luminance; [`OFF_SURFACE`]'s values
    /// off surfaces, where every tap dropped out, and where the result is not finite).
    ///
    /// # Safety
    /// The CPU must have what `V`'s operations use (see [`Lanes`]).
    #[inline(always)]
    unsafe fn row<V: Lanes>(&self, (guide, taps, blurred, y, step, needs): RowArgs, out: OutRow) {
        let (w, h, stride, pad) = (guide.width, guide.height, guide.stride, guide.pad);
        // Every plane the taps read holds `h` padded rows, and the farthest tap of a chunk
        // stays within its row's padding (the loads below rely on both).
        let len = stride * h;
        assert!(y < h, "row {y} of {h}");
        assert!(step.saturating_mul(2).min(w) + MAX_LANES <= pad, "the guide was made for fewer passes");
        assert!(taps.lum.len() == len && taps.var.len() == len && taps.colour.iter().all(|p| p.len() == len));
        assert!(guide.normal.iter().chain(&guide.position).all(|p| p.len() == len));
        assert!(blurred.len() == len && guide.footprint_padded.len() == len);
        assert!(out.iter().all(|row| row.len() == stride));
        assert!(needs.is_none_or(|(n, _)| n.len() == w.div_ceil(MAX_LANES)));
        // The taps whose row lies in the image: kernel weight, 1 / offset length in steps
        // (the plane distance is per step of offset), offset in the padded planes.
        let mut tap_list = [(0.0f32, 0.0f32, 0isize); 25];
        let mut tap_count = 0;
        for (dy, ky) in (-2..=2isize).zip(KERNEL) {
            if !(0..h as isize).contains(&(y as isize + dy * step as isize)) {
                continue;
            }
            for (dx, kx) in (-2..=2isize).zip(KERNEL) {
                if dx != 0 && dx.unsigned_abs() * step >= w {
                    // A row or more across: no centre pixel's tap lies in the image.
                    continue;
                }
                let inv_distance = 1.0 / ((dx * dx + dy * dy) as f32).sqrt().max(1.0);
                tap_list[tap_count] = (kx * ky, inv_distance, (dy * stride as isize + dx) * step as isize);
                tap_count += 1;
            }
        }
        let [out_r, out_g, out_b, out_var, out_lum] = out;
        // SAFETY: a chunk reads `V::N ≤ MAX_LANES` values from padded index `c + offset` of
        // planes of `len` values (asserted above): `c = y·stride + pad + x0` with `x0 < w`,
        // and the offset (0 for the centre's own planes) moves it to a row in the image
        // (checked above) and at most `min(2·step, w − 1)` pixels across (taps a row or more
        // across are skipped), so the chunk's last value lies at most `w − 1 + that + V::N − 1`
        // past the row's start, within `pad` more than the row (asserted above). It writes
        // `V::N` values from `pad + x0` of output rows of `stride = w + 2·pad` values
        // (asserted), which ends within the right padding; lanes there lie off every surface
        // and write the padding's own values. The CPU has `V`'s features (the caller's
        // promise).
        unsafe {
            let at = |plane: &[f32], i: usize| V::load(plane.as_ptr().add(i));
            let [nx, ny, nz] = &guide.normal;
            let [px, py, pz] = &guide.position;
            let [r, g, b] = &taps.colour;
            let zero = V::splat(0.0);
            let infinity = V::splat(f32::INFINITY);
            for x0 in (0..w).step_by(V::N) {
                let c = y * stride + pad + x0;
                let o = pad + x0;
                if let Some((needs, pass)) = needs {
                    // The most passes a pixel of the chunk's group needs (decided first, so that
                    // every lane width treats a group alike).
                    let most = needs[x0 / MAX_LANES];
                    if most < pass {
                        // Done two passes ago or more: the output's memory, which held the
                        // output of the pass before last, holds the chunk's values since.
                        continue;
                    }
                    if most == pass {
                        // Done: the chunk's values (its lanes in the padding included, which
                        // hold the padding's own) go on as they are.
                        for (plane, out) in [r, g, b, &taps.var, &taps.lum].into_iter().zip([
                            &mut *out_r,
                            &mut *out_g,
                            &mut *out_b,
                            &mut *out_var,
                            &mut *out_lum,
                        ]) {
                            at(plane, c).store(out.as_mut_ptr().add(o));
                        }
                        continue;
                    }
                }
                let f = at(&guide.footprint_padded, c);
                if !V::any(f.gt(zero)) {
                    // No surface in the chunk (the sky, a light): the values off surfaces, as
                    // the taps would give them, without the taps.
                    for plane in [&mut *out_r, &mut *out_g, &mut *out_b, &mut *out_var] {
                        zero.store(plane.as_mut_ptr().add(o));
                    }
                    infinity.store(out_lum.as_mut_ptr().add(o));
                    continue;
                }
                let (pnx, pny, pnz) = (at(nx, c), at(ny, c), at(nz, c));
                let (ppx, ppy, ppz) = (at(px, c), at(py, c), at(pz, c));
                let plum = at(&taps.lum, c);
                // 1 / (σl σ(l)), and 1 / (σp footprint step) (0 off surfaces, whose result is
                // not used, and in the padding).
                let one = V::splat(1.0);
                let lscale = one.div(V::splat(self.sigma_luminance).mul(at(blurred, c).sqrt()).add(V::splat(1e-6)));
                let pscale = one.div(V::splat(self.sigma_plane).mul(f).mul(V::splat(step as f32))).keep(f.gt(zero));
                let (mut sr, mut sg, mut sb, mut sv, mut sw) = (zero, zero, zero, zero, zero);
                for &(kernel, inv_distance, offset) in &tap_list[..tap_count] {
                    let q = c.wrapping_add_signed(offset);
                    let cos = pnx.mul(at(nx, q)).add(pny.mul(at(ny, q))).add(pnz.mul(at(nz, q)));
                    // From at least MIN_NORMAL_COS, so that the powers stay normal floats.
                    let mut normal = cos.max(V::splat(MIN_NORMAL_COS));
                    for _ in 0..NORMAL_POWER {
                        normal = normal.mul(normal);
                    }
                    let along_normal =
                        pnx.mul(at(px, q).sub(ppx)).add(pny.mul(at(py, q).sub(ppy))).add(pnz.mul(at(pz, q).sub(ppz)));
                    let plane = along_normal.abs().mul(pscale).mul(V::splat(inv_distance));
                    let light = at(&taps.lum, q).sub(plum).abs().mul(lscale);
                    let exponent = plane.add(light);
                    let falloff = normal.mul(exp_neg(exponent.min(V::splat(MAX_EXPONENT))));
                    // Taps beyond e^-20 (or NaN), off-surface ones among them, count for nothing.
                    let counts = V::and(exponent.lt(V::splat(MAX_EXPONENT)), falloff.gt(V::splat(MIN_FALLOFF)));
                    let weight = V::splat(kernel).mul(falloff).keep(counts);
                    sr = sr.add(at(r, q).mul(weight));
                    sg = sg.add(at(g, q).mul(weight));
                    sb = sb.add(at(b, q).mul(weight));
                    sv = sv.add(at(&taps.var, q).mul(weight).mul(weight));
                    sw = sw.add(weight);
                }
                // The weighted means, and the variance of the weighted sum; kept on surfaces
                // whose taps did not all drop and whose result is finite (a non-finite
                // sample's pixel takes the values of the pixels off surfaces, as in
                // `Signal::from_fn`).
                let (cr, cg, cb) = (sr.div(sw), sg.div(sw), sb.div(sw));
                let var = sv.div(sw.mul(sw)).max(zero);
                let finite = V::and(V::and(cr.abs().lt(infinity), cg.abs().lt(infinity)), cb.abs().lt(infinity));
                let kept = V::and(V::and(f.gt(zero), sw.gt(zero)), finite);
                cr.keep(kept).store(out_r.as_mut_ptr().add(o));
                cg.keep(kept).store(out_g.as_mut_ptr().add(o));
                cb.keep(kept).store(out_b.as_mut_ptr().add(o));
                var.keep(kept).store(out_var.as_mut_ptr().add(o));
                luminance_lanes(cr, cg, cb).or_else(kept, infinity).store(out_lum.as_mut_ptr().add(o));
            }
        }
    }
}

/// [`luminance`] over lanes: the same products summed in the same order, so the same bits.
///
/// # Safety
/// As [`Lanes`].
#[inline(always)]
unsafe fn luminance_lanes<V: Lanes>(r: V, g: V, b: V) -> V {
    let [kr, kg, kb] = crate::film::LUMINANCE_WEIGHTS;
    // SAFETY: the caller's.
    unsafe { r.mul(V::splat(kr)).add(g.mul(V::splat(kg))).add(b.mul(V::splat(kb))) }
}

/// The variance smoothed by a 3×3 Gaussian over surface pixels, as SVGF does before each pass:
/// one pixel's variance estimate from few samples is itself noisy. Into `out`, laid out as
/// the signal's planes (its padding is left as it is, 0 in every caller's), in the rows `y`
/// for which `rows(y)` holds (the others are left as they are).
fn blurred_variance(guide: &GuidePlanes, signal: &Signal, out: &mut [f32], rows: impl Fn(usize) -> bool + Sync) {
    let surface = &guide.surface_blurred;
    blur_3x3_into(&signal.var, guide.width, guide.height, guide.pad, out, rows, |i, sum| {
        let weight = surface[i];
        // (Both sides computed, so that the loop vectorises; the division's result off
        // surfaces is not used.)
        let normalised = sum / weight;
        if weight > 0.0 {
            normalised
        } else {
            0.0
        }
    });
}

/// `plane` (`w × h`, rows of `w` values with `pad` more on each side) under the separable 3×3
/// kernel (¼, ½, ¼)², zero outside the image, each pixel's sum through `finish(pixel, sum)`,
/// into `out` laid out as `plane` (the padding left as it is), in the rows `y` for which
/// `rows(y)` holds (the others left as they are); one pass over the rows, in parallel (each
/// row computes the horizontal sums of its three rows itself, from copies with a zero at each
/// end: a loop without a test per pixel, which the compiler vectorises).
fn blur_3x3_into(
    plane: &[f32],
    w: usize,
    h: usize,
    pad: usize,
    out: &mut [f32],
    rows: impl Fn(usize) -> bool + Sync,
    finish: impl Fn(usize, f32) -> f32 + Sync,
) {
    const GAUSS: [f32; 3] = [0.25, 0.5, 0.25];
    let stride = w + 2 * pad;
    assert!(plane.len() == stride * h && out.len() == stride * h);
    let row = |y: usize| &plane[y * stride + pad..y * stride + pad + w];
    // Row `y`'s horizontal sums into `sums` (zeros for rows outside the image), by way of
    // `edged`, the row with a zero at each end.
    let across = |y: Option<usize>, edged: &mut Vec<f32>, sums: &mut [f32]| {
        let Some(y) = y.filter(|y| *y < h) else {
            sums.fill(0.0);
            return;
        };
        edged.clear();
        edged.push(0.0);
        edged.extend_from_slice(row(y));
        edged.push(0.0);
        for (x, sum) in sums.iter_mut().enumerate() {
            *sum = GAUSS[0] * edged[x] + GAUSS[1] * edged[x + 1] + GAUSS[2] * edged[x + 2];
        }
    };
    out.par_chunks_mut(stride.max(1)).enumerate().for_each_init(
        || (Vec::with_capacity(w + 2), vec![0.0; 3 * w]),
        |(edged, sums), (y, row_out)| {
            if !rows(y) {
                return;
            }
            let (up, rest) = sums.split_at_mut(w);
            let (this, down) = rest.split_at_mut(w);
            across(y.checked_sub(1), edged, up);
            across(Some(y), edged, this);
            across(Some(y + 1), edged, down);
            for (x, value) in row_out[pad..pad + w].iter_mut().enumerate() {
                *value = finish(y * w + x, GAUSS[0] * up[x] + GAUSS[1] * this[x] + GAUSS[2] * down[x]);
            }
        },
    );
}

/// Smallest albedo channel divided by (dark surfaces would blow their noise up).
pub(crate) const MIN_ALBEDO: f32 = 0.01;

impl Atrous {
    /// The denoised image of `colour` (a film's mean), whose per-pixel variance of the mean is
    /// `variance`, guided by `guide` (same size).
    pub fn denoise(&self, colour: &[Vec3], variance: &[Vec3], guide: &Guide) -> Vec<Vec3> {
        let n = (guide.width * guide.height) as usize;
        assert!(colour.len() == n && variance.len() == n, "image and guide sizes differ");
        let albedo: Vec<Vec3> = guide.albedo.iter().map(|a| a.max(Vec3::splat(MIN_ALBEDO))).collect();
        let illumination: Vec<Vec3> = colour.iter().zip(&albedo).map(|(c, a)| *c / *a).collect();
        let var = variance
            .iter()
            .zip(&albedo)
            .map(|(v, a)| {
                // The luminance's standard deviation, channels taken as fully correlated (one
                // path makes all three), then squared.
                let sd = luminance(Vec3::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt()) / *a);
                sd * sd
            })
            .collect::<Vec<f32>>();
        let planes = GuidePlanes::new(guide, self.passes);
        let out = self.filter(&planes, Signal::new(&planes, &illumination, &var), |_| {}).pixels();
        (0..n).map(|i| if guide.footprint[i] > 0.0 { out[i] * albedo[i] } else { colour[i] }).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::Pcg32;

    const W: u32 = 48;
    const H: u32 = 32;

    /// A flat wall facing the camera (normal +z at z = 0) seen head-on, one unit per pixel.
    fn wall() -> Guide {
        wall_of(W, H)
    }

    fn wall_of(width: u32, height: u32) -> Guide {
        let n = (width * height) as usize;
        Guide {
            width,
            height,
            albedo: vec![Vec3::splat(0.5); n],
            normal: vec![Vec3::Z; n],
            position: (0..n).map(|i| Vec3::new((i as u32 % width) as f32, (i as u32 / width) as f32, 0.0)).collect(),
            footprint: vec![1.0; n],
        }
    }

    /// Noise of standard deviation `sd` around `base`, the same in all three channels.
    fn noisy(base: impl Fn(usize) -> f32, sd: f32, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
        let mut rng = Pcg32::new(seed, 1);
        let colour = (0..(W * H) as usize)
            .map(|i| {
                // A sum of 4 uniforms, scaled to the standard deviation: near Gaussian.
                let u: f32 = (0..4).map(|_| rng.next_f32() - 0.5).sum::<f32>() * (3.0f32).sqrt();
                Vec3::splat(base(i) + sd * u)
            })
            .collect();
        (colour, vec![Vec3::splat(sd * sd); (W * H) as usize])
    }

    fn variance(v: impl Iterator<Item = f32>) -> f32 {
        let v: Vec<f32> = v.collect();
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        v.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / v.len() as f32
    }

    /// The compiled variants of the tap loop (plain, AVX2, AVX-512, as far as this CPU has
    /// them) give the same output rows, bit for bit, on a rough scene: random normals, depths,
    /// colours and variances, and pixels off surfaces, alone and in blocks; and the rows' luminance is
    /// [`luminance`] of their colour.
    #[test]
    fn every_compiled_tap_loop_gives_the_same_rows() {
        let mut rng = Pcg32::new(7, 3);
        let (w, h) = (37u32, 21u32);
        let mut guide = wall_of(w, h);
        for (i, (n, p)) in guide.normal.iter_mut().zip(guide.position.iter_mut()).enumerate() {
            *n = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 1.0).normalize();
            p.z = 3.0 * rng.next_f32();
            // Scattered pixels off surfaces, and a block of them as wide as a chunk of each
            // variant's lanes (which skip such chunks' taps).
            let (x, y) = (i % w as usize, i / w as usize);
            let off = i % 11 == 0 || ((16..32).contains(&x) && y < 5);
            guide.footprint[i] = if off { 0.0 } else { 0.5 + rng.next_f32() };
        }
        let colour: Vec<Vec3> = (0..w * h).map(|_| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())).collect();
        let var: Vec<f32> = (0..w * h).map(|_| 0.1 * rng.next_f32()).collect();
        let planes = GuidePlanes::new(&guide, 5);
        let signal = Signal::new(&planes, &colour, &var);
        let mut blurred = vec![0.0; planes.stride * planes.height];
        blurred_variance(&planes, &signal, &mut blurred, |_| true);
        let atrous = Atrous::default();
        // The output rows a variant writes: the padding holds the values of pixels off
        // surfaces (as the planes' padding does), the image a NaN that every pixel must
        // overwrite.
        let rows = |variant: &dyn Fn(OutRow)| {
            let mut rows = OFF_SURFACE.map(|fill| vec![fill; planes.stride]);
            for row in &mut rows {
                row[planes.pad..planes.pad + w as usize].fill(f32::NAN);
            }
            let [r, g, b, v, l] = &mut rows;
            variant([r, g, b, v, l]);
            rows
        };
        let bits = |rows: &[Vec<f32>; 5]| rows.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        // The AVX2 and AVX-512 loops' rows against the portable loop's, as far as the CPU has
        // them; how many were compared.
        let same_from_every_loop = |args: RowArgs, plain: &[Vec<f32>; 5], what: String| {
            let mut compared = 0;
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2 (checked).
                    let avx2 = rows(&|out| unsafe { atrous.row_avx2(args, out) });
                    assert_eq!(bits(&avx2), bits(plain), "AVX2, {what}");
                    compared += 1;
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has AVX-512 F (checked).
                    let avx512 = rows(&|out| unsafe { atrous.row_avx512(args, out) });
                    assert_eq!(bits(&avx512), bits(plain), "AVX-512, {what}");
                    compared += 1;
                }
            }
            let _ = (args, plain, what);
            compared
        };
        let mut compared = 0;
        for step in [1, 2, 4, 16] {
            for y in 0..h as usize {
                let args = (&planes, &signal, &blurred[..], y, step, None);
                let plain = rows(&|out| atrous.row_portable(args, out));
                let pad = planes.pad;
                let on_surface = (0..w as usize).filter(|&x| plain[4][pad + x].is_finite()).collect::<Vec<_>>();
                assert!(on_surface.len() > w as usize / 3, "row {y}, step {step}: too few pixels filtered");
                for x in on_surface {
                    let c = Vec3::new(plain[0][pad + x], plain[1][pad + x], plain[2][pad + x]);
                    assert_eq!(plain[4][pad + x].to_bits(), luminance(c).to_bits(), "row {y}, step {step}, x {x}");
                }
                for x in (0..w as usize).filter(|x| guide.footprint[y * w as usize + x] <= 0.0) {
                    let values = plain.each_ref().map(|plane| plane[pad + x].to_bits());
                    assert_eq!(values, OFF_SURFACE.map(f32::to_bits), "row {y}, step {step}, x {x}: off surfaces");
                }
                compared += same_from_every_loop(args, &plain, format!("row {y}, step {step}"));
            }
        }
        // With pass counts per group: groups that are done are skipped alike, whatever the
        // lanes (the rows' NaN stays where a variant writes nothing).
        let row_groups = (w as usize).div_ceil(MAX_LANES);
        let needs: Vec<u8> = (0..row_groups * h as usize).map(|_| 1 + (rng.next_u32() % 3) as u8).collect();
        for pass in [1u8, 2] {
            for y in 0..h as usize {
                let row_needs = Some((&needs[y * row_groups..(y + 1) * row_groups], pass));
                let args = (&planes, &signal, &blurred[..], y, 2, row_needs);
                let plain = rows(&|out| atrous.row_portable(args, out));
                compared += same_from_every_loop(args, &plain, format!("row {y}, pass {pass}"));
            }
        }
        #[cfg(target_arch = "x86_64")]
        assert!(compared > 0 || !std::arch::is_x86_feature_detected!("avx2"));
        let _ = compared;
    }

    /// With a pass count per pixel, a chunk all of whose pixels need `k` passes ends with the
    /// values of `k` passes (the first always runs), through the chunk's copy in the first
    /// pass it skips and the memory two passes back after that; the other pixels are
    /// filtered on. The filter's memory holds a previous image's planes, as the temporal
    /// filter's does.
    #[test]
    fn each_pixel_gets_the_passes_it_needs() {
        let guide = wall();
        let planes = GuidePlanes::new(&guide, 4);
        let (colour, var) = noisy(|i| if (i as u32 % W) < W / 2 { 0.3 } else { 0.6 }, 0.1, 7);
        let var: Vec<f32> = var.iter().map(|v| v.x).collect();
        let signal = || Signal::new(&planes, &colour, &var);
        let bits = |s: &Signal| s.pixels().iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
        let mut memory = FilterMemory::default();
        let mut filtered = |passes: u32, needs: Option<&[u8]>| {
            // A first image fills the memory that the second's passes write into.
            let (other, _) = noisy(|_| 0.9, 0.2, 8);
            let atrous = Atrous { passes, ..Atrous::default() };
            let used = atrous.filter_reusing(&planes, Signal::new(&planes, &other, &var), &mut memory, needs, |_| {});
            let out = atrous.filter_reusing(&planes, signal(), &mut memory, needs, |_| {});
            memory.spare = Some(used);
            out
        };
        let n = (W * H) as usize;
        let plain: Vec<Signal> = (0..=4).map(|passes| filtered(passes, None)).collect();
        for k in 0..=4u8 {
            let got = filtered(4, Some(&vec![k; n]));
            assert_eq!(bits(&got), bits(&plain[k.max(1) as usize]), "every pixel needs {k} passes");
        }
        // The left 16 columns (whole chunks of every lane width) need one pass, the rest four.
        let needs: Vec<u8> = (0..n).map(|i| if (i as u32 % W) < 16 { 1 } else { 4 }).collect();
        let (got, one) = (filtered(4, Some(&needs)).pixels(), plain[1].pixels());
        for i in 0..n {
            let left = (i as u32 % W) < 16;
            assert_eq!(got[i] == one[i], left, "pixel {i}: {} against one pass's {}", got[i], one[i]);
        }
    }

    /// Pass counts that vary from pixel to pixel, on an image whose rows end in a partial
    /// group: the same bits as passes run in full, after each of which the groups of
    /// [`MAX_LANES`] pixels that are done get their values from before the pass back.
    #[test]
    fn groups_that_are_done_keep_their_values() {
        let (w, h) = (45usize, 20usize);
        let mut guide = wall_of(w as u32, h as u32);
        // A strip of sky, so that some groups hold pixels off the surfaces.
        for y in 0..h {
            guide.footprint[y * w + 40] = 0.0;
        }
        let planes = GuidePlanes::new(&guide, 4);
        let mut rng = Pcg32::new(3, 1);
        let colour: Vec<Vec3> = (0..w * h).map(|_| Vec3::splat(0.3 + 0.4 * rng.next_f32())).collect();
        let var: Vec<f32> = (0..w * h).map(|_| 0.05 * rng.next_f32()).collect();
        // Mostly one or two passes, now and then four, 0 (taken as one) too.
        let needs: Vec<u8> = (0..w * h).map(|_| [0, 1, 1, 2, 2, 2, 4][(rng.next_u32() % 7) as usize]).collect();
        let atrous = Atrous { passes: 4, ..Atrous::default() };
        let mut memory = FilterMemory::default();
        let (other, _) = noisy(|_| 0.9, 0.2, 8);
        let other: Vec<Vec3> = other[..w * h].to_vec();
        let _ = atrous.filter_reusing(&planes, Signal::new(&planes, &other, &var), &mut memory, Some(&needs), |_| {});
        let got =
            atrous.filter_reusing(&planes, Signal::new(&planes, &colour, &var), &mut memory, Some(&needs), |_| {});
        let mut signal = Signal::new(&planes, &colour, &var);
        let mut blurred = vec![0.0; planes.stride * h];
        for pass in 0..4u8 {
            let mut out = Signal::empty(&planes);
            blurred_variance(&planes, &signal, &mut blurred, |_| true);
            atrous.pass(&planes, &signal, &blurred, 1 << pass, None, &mut out);
            for y in 0..h {
                for group in (0..w).step_by(MAX_LANES) {
                    let pixels = group..(group + MAX_LANES).min(w);
                    let most = needs[y * w..][pixels.clone()].iter().fold(1, |m, &n| m.max(n));
                    if pass > 0 && most <= pass {
                        for x in pixels {
                            let i = y * planes.stride + planes.pad + x;
                            for (to, from) in out
                                .colour
                                .iter_mut()
                                .chain([&mut out.var, &mut out.lum])
                                .zip(signal.colour.iter().chain([&signal.var, &signal.lum]))
                            {
                                to[i] = from[i];
                            }
                        }
                    }
                }
            }
            signal = out;
        }
        let bits = |s: &Signal| s.pixels().iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&got), bits(&signal));
        assert_ne!(bits(&got), bits(&atrous.filter(&planes, Signal::new(&planes, &colour, &var), |_| {})));
    }

    #[test]
    fn a_constant_image_stays_constant() {
        let mut guide = wall();
        // Albedo edges too: the illumination is what is filtered, the albedo comes back.
        guide
            .albedo
            .iter_mut()
            .enumerate()
            .for_each(|(i, a)| *a = if (i / 3) % 2 == 0 { Vec3::splat(0.2) } else { Vec3::ONE });
        let colour: Vec<Vec3> = guide.albedo.iter().map(|a| *a * Vec3::new(0.3, 0.6, 0.9)).collect();
        let variance = vec![Vec3::splat(0.01); colour.len()];
        let out = Atrous::default().denoise(&colour, &variance, &guide);
        for (i, (a, b)) in out.iter().zip(&colour).enumerate() {
            assert!((*a - *b).abs().max_element() < 1e-5, "pixel {i}: {a} from {b}");
        }
    }

    #[test]
    fn noise_on_a_flat_surface_is_removed() {
        let guide = wall();
        let (colour, var) = noisy(|_| 0.4, 0.1, 1);
        let out = Atrous::default().denoise(&colour, &var, &guide);
        let (before, after) = (variance(colour.iter().map(|c| c.x)), variance(out.iter().map(|c| c.x)));
        assert!(after < 0.02 * before, "pixel variance {before} → {after}");
        let mean = out.iter().map(|c| c.x).sum::<f32>() / out.len() as f32;
        assert!((mean - 0.4).abs() < 0.01, "mean {mean}");
    }

    /// Left and right halves at different levels, split by a normal edge or a depth edge: the
    /// filter keeps each side's level right up to the edge.
    #[test]
    fn no_blur_across_a_normal_or_depth_edge() {
        let left = |i: usize| (i as u32 % W) < W / 2;
        let level = |i: usize| if left(i) { 0.4 } else { 0.55 };
        for edge in ["normal", "depth"] {
            let mut guide = wall();
            for i in 0..(W * H) as usize {
                if !left(i) {
                    match edge {
                        "normal" => guide.normal[i] = Vec3::X,
                        _ => guide.position[i].z = 20.0,
                    }
                }
            }
            let (colour, var) = noisy(level, 0.05, 2);
            let out = Atrous::default().denoise(&colour, &var, &guide);
            for (i, c) in out.iter().enumerate() {
                // Columns next to the edge: averages of a side's noise, nothing of the other.
                let column = i as u32 % W;
                if column + 1 == W / 2 || column == W / 2 {
                    assert!((c.x - level(i)).abs() < 0.03, "{edge} edge, pixel {i} (column {column}): {}", c.x);
                }
            }
        }
    }

    /// Columns of two normals 60° apart (cosine ½, so `½^128`, a subnormal float, was the
    /// normal weight between them): no trace of one side reaches the other, even where the
    /// luminance and plane weights would let it.
    #[test]
    fn a_sharp_normal_edge_lets_nothing_through() {
        let mut guide = wall();
        let tilted = Vec3::new(0.75f32.sqrt(), 0.0, 0.5);
        let on_tilted = |i: usize| i % 2 == 1;
        for (i, n) in guide.normal.iter_mut().enumerate() {
            if on_tilted(i) {
                *n = tilted;
            }
        }
        guide.albedo = vec![Vec3::ONE; guide.albedo.len()];
        let colour: Vec<Vec3> =
            (0..(W * H) as usize).map(|i| Vec3::splat(if on_tilted(i) { 1.0 } else { 0.0 })).collect();
        // Noise so large that the luminance weight lets everything through.
        let out = Atrous::default().denoise(&colour, &vec![Vec3::splat(1e6); colour.len()], &guide);
        for (i, c) in out.iter().enumerate().filter(|(i, _)| !on_tilted(*i)) {
            assert_eq!(*c, Vec3::ZERO, "pixel {i}");
        }
    }

    /// More passes than any image needs (their steps grow past its size, and past what
    /// `usize` holds): bounded padding, the constant image kept.
    #[test]
    fn many_passes_on_a_small_image() {
        let (w, h) = (5, 3);
        let (n, guide) = ((w * h) as usize, wall_of(w, h));
        let atrous = Atrous { passes: 80, ..Atrous::default() };
        let out = atrous.denoise(&vec![Vec3::splat(0.25); n], &vec![Vec3::splat(0.01); n], &guide);
        assert!(out.iter().all(|c| (*c - Vec3::splat(0.25)).abs().max_element() < 1e-5), "{out:?}");
        assert!(GuidePlanes::new(&guide, 80).pad <= w as usize + MAX_LANES);
    }

    /// A pixel whose sample is not finite is left out: it comes out black, its neighbours
    /// as if it were not there (before, NaN times a weight of 0 spread it over the image).
    #[test]
    fn a_non_finite_sample_does_not_spread() {
        let guide = wall();
        let (mut colour, var) = noisy(|_| 0.4, 0.05, 4);
        let bad = (H / 2 * W + W / 2) as usize;
        colour[bad] = Vec3::splat(f32::NAN);
        let out = Atrous::default().denoise(&colour, &var, &guide);
        let broken: Vec<usize> = (0..out.len()).filter(|&i| !out[i].is_finite()).collect();
        assert!(broken.is_empty(), "non-finite pixels ({bad} was the NaN sample): {broken:?}");
        assert_eq!(out[bad], Vec3::ZERO);
    }

    /// Images narrower and shorter than the widest step (16 pixels × 2) are filtered too.
    #[test]
    fn tiny_images() {
        for (w, h) in [(1, 1), (3, 40), (40, 2)] {
            let (n, guide) = ((w * h) as usize, wall_of(w, h));
            let out = Atrous::default().denoise(&vec![Vec3::splat(0.25); n], &vec![Vec3::splat(0.01); n], &guide);
            assert!(out.iter().all(|c| (*c - Vec3::splat(0.25)).abs().max_element() < 1e-5), "{w}×{h}");
        }
    }

    #[test]
    fn the_sky_and_lights_are_left_alone() {
        let mut guide = wall();
        let (colour, var) = noisy(|_| 0.5, 0.2, 3);
        for i in 0..W as usize {
            guide.footprint[i] = 0.0;
        }
        let out = Atrous::default().denoise(&colour, &var, &guide);
        assert_eq!(out[..W as usize], colour[..W as usize]);
        assert_ne!(out[W as usize..], colour[W as usize..]);
    }
}
