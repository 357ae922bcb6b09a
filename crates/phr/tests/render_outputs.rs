//! `phr render`'s extra outputs and estimators on the built-in Cornell-box scene, at tiny
//! sizes: the `--heatmap` PNG has the image's size, spans its colour scale and is not
//! constant; the `--variance` PFM has the image's size, is finite and ≥ 0 everywhere and
//! shrinks as 1/spp (it is the variance of the mean); the default estimator (light sampling
//! with MIS) gives the same expected image as `--integrator implicit`, within the noise its
//! variance files predict, with less variance.

mod common;

use common::{phr_ok, Image, TempDir};
use std::time::Duration;

const SIZE: (u32, u32) = (32, 24);

/// Renders the built-in scene at `SIZE` in `dir`, with the linear mean and the variance of the
/// mean as PFM (`NAME.pfm`, `NAME.var.pfm`); returns them.
fn render(dir: &TempDir, name: &str, spp: u32, extra: &[&str]) -> (Image, Image) {
    let (mean, variance) = (format!("{name}.pfm"), format!("{name}.var.pfm"));
    let (w, h, spp) = (SIZE.0.to_string(), SIZE.1.to_string(), spp.to_string());
    let mut args = vec!["--threads", "2", "render", "builtin", "--quiet", "--out", "out.png", "--width", &w];
    args.extend(["--height", &h, "--spp", &spp, "--linear", &mean, "--variance", &variance]);
    args.extend_from_slice(extra);
    phr_ok(&dir.0, &args, Duration::from_secs(120));
    let images = (Image::pfm(&dir.join(&mean)), Image::pfm(&dir.join(&variance)));
    for (image, file) in [(&images.0, &mean), (&images.1, &variance)] {
        assert_eq!((image.width, image.height), SIZE, "{file}: size");
        assert!(image.rgb.iter().all(|v| v.is_finite() && *v >= 0.0), "{file}: a value negative or not finite");
    }
    images
}

/// Pixel means (over the channels) of an image, and an upper bound of their variances from the
/// per-channel variances (channels of one path are correlated: the bound assumes fully).
fn pixel_means(mean: &Image, variance: &Image) -> Vec<(f64, f64)> {
    mean.rgb
        .chunks_exact(3)
        .zip(variance.rgb.chunks_exact(3))
        .map(|(m, v)| {
            let avg = m.iter().map(|&x| f64::from(x)).sum::<f64>() / 3.0;
            let sd = v.iter().map(|&x| f64::from(x).sqrt()).sum::<f64>() / 3.0;
            (avg, sd * sd)
        })
        .collect()
}

/// Mean over pixels of the pixel means, and its variance.
fn image_mean(pixels: &[(f64, f64)]) -> (f64, f64) {
    let n = pixels.len() as f64;
    (pixels.iter().map(|p| p.0).sum::<f64>() / n, pixels.iter().map(|p| p.1).sum::<f64>() / (n * n))
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

#[test]
fn heatmap_has_the_image_size_and_spans_its_scale() {
    let dir = TempDir::new("render-heatmap");
    let (w, h) = (SIZE.0.to_string(), SIZE.1.to_string());
    let args = ["render", "builtin", "--quiet", "--spp", "1", "--width", &w, "--height", &h, "--heatmap", "heat.png"];
    let out = phr_ok(&dir.0, &args, Duration::from_secs(60));
    let heat = Image::png(&dir.join("heat.png"));
    assert_eq!((heat.width, heat.height), SIZE, "heatmap size");
    let colours: std::collections::BTreeSet<[u8; 3]> =
        heat.rgb.chunks_exact(3).map(|p| [p[0] as u8, p[1] as u8, p[2] as u8]).collect();
    assert!(colours.len() >= 8, "a heatmap of a Cornell box with a knot has many step counts: {colours:?}");
    // The scale's top is the largest count: some pixel has the colour of the red end.
    let top = phr_render::output::turbo(1.0);
    assert!(colours.contains(&top), "no pixel at the top of the scale {top:?}: {colours:?}");
    let line = out.stdout.lines().find(|l| l.starts_with("heatmap: ")).unwrap_or_else(|| panic!("{}", out.stdout));
    let mean: f64 = line.split("(mean ").nth(1).and_then(|s| s.split(' ').next()).unwrap().parse().unwrap();
    assert!(mean >= 1.0, "{line}");
}

#[test]
fn variance_is_of_the_mean_and_light_sampling_agrees_with_less_of_it() {
    let dir = TempDir::new("render-variance");
    let implicit_args = ["--integrator", "implicit"];
    let (_, var16) = render(&dir, "implicit16", 16, &implicit_args);
    let (implicit, var64) = render(&dir, "implicit64", 64, &implicit_args);
    let (nee, nee_var) = render(&dir, "path64", 64, &[]);

    // The variance of the mean: 4 times the samples, a quarter of the variance (summed over
    // the image: each pixel's estimate is unbiased, if skewed).
    let ratio = var16.mean() / var64.mean();
    assert!((2.5..6.0).contains(&ratio), "variance at 16 spp / at 64 spp = {ratio}, expected about 4");

    // Same expected image: the image means, and those of 4×4 blocks, agree within the noise.
    let (a, b) = (pixel_means(&implicit, &var64), pixel_means(&nee, &nee_var));
    let z = |a: &[(f64, f64)], b: &[(f64, f64)]| {
        let ((ma, va), (mb, vb)) = (image_mean(a), image_mean(b));
        ((ma - mb) / (va + vb).sqrt(), ma, mb)
    };
    let (z_all, m_implicit, m_nee) = z(&a, &b);
    assert!(
        z_all.abs() < 4.0,
        "image means: implicit {m_implicit}, light sampling {m_nee}: {z_all} standard deviations apart"
    );
    // 4×4 blocks of pixels, row by row.
    let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
    let blocks = |p: &[(f64, f64)]| {
        let mut blocks = vec![Vec::new(); 16];
        for (i, &pixel) in p.iter().enumerate() {
            blocks[(i / w) * 4 / h * 4 + (i % w) * 4 / w].push(pixel);
        }
        blocks
    };
    for (k, (ba, bb)) in blocks(&a).iter().zip(&blocks(&b)).enumerate() {
        let (zb, ma, mb) = z(ba, bb);
        assert!(zb.abs() < 5.0, "block {k}: implicit {ma}, light sampling {mb}: {zb} standard deviations apart");
    }

    // Less noise: on average and in the typical pixel.
    let (nee_mean, implicit_mean) = (nee_var.mean(), var64.mean());
    assert!(
        nee_mean < 0.8 * implicit_mean,
        "mean pixel variance: light sampling {nee_mean} vs implicit {implicit_mean}"
    );
    let (mn, mi) = (median(nee_var.rgb.clone()), median(var64.rgb.clone()));
    assert!(mn < 0.8 * mi, "median pixel variance: light sampling {mn} vs implicit {mi}");
}

/// The denoiser's guides are written on request: the albedo in [0, 1] and unit normals (zero
/// where a pixel sees no surface to filter); the denoised image is smoother than the raw mean.
#[test]
fn albedo_and_normal_guides_are_written_and_the_denoiser_smooths() {
    let dir = TempDir::new("render-guides");
    // Larger than SIZE: at 32 × 24 the whole image is within the filter's reach of a border
    // and the median below moved by ±20 % between seeds (0.43–0.59 of the raw one); at 64 ×
    // 48 it stays at 0.25–0.33.
    const GUIDES_SIZE: (u32, u32) = (64, 48);
    let (w, h) = (GUIDES_SIZE.0.to_string(), GUIDES_SIZE.1.to_string());
    let args = ["render", "builtin", "--quiet", "--spp", "4", "--width", &w, "--height", &h];
    let mut with_guides = args.to_vec();
    with_guides.extend(["--out", "denoised.pfm", "--linear", "raw.pfm", "--albedo", "albedo.pfm"]);
    phr_ok(&dir.0, &with_guides, Duration::from_secs(120));
    let (albedo, normal) = (Image::pfm(&dir.join("albedo.pfm")), Image::pfm(&dir.join("albedo_normal.pfm")));
    for image in [&albedo, &normal] {
        assert_eq!((image.width, image.height), GUIDES_SIZE);
    }
    assert!(albedo.rgb.iter().all(|v| (0.0..=1.0).contains(v)), "albedo outside [0, 1]");
    let lengths: Vec<f32> =
        normal.rgb.chunks_exact(3).map(|n| (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()).collect();
    assert!(lengths.iter().all(|l| *l == 0.0 || (l - 1.0).abs() < 1e-4), "normals neither unit nor zero");
    assert!(lengths.iter().filter(|l| **l > 0.0).count() > lengths.len() / 2, "most pixels see a surface");
    // Smoother: the median difference between horizontal neighbours drops (the median: the
    // lights and their edges, left alone, would dominate a sum).
    let roughness = |image: &Image| {
        let pixels: Vec<&[f32]> = image.rgb.chunks_exact(3).collect();
        median(pixels.windows(2).map(|p| (p[0][1] - p[1][1]).abs()).collect())
    };
    let (raw, denoised) = (Image::pfm(&dir.join("raw.pfm")), Image::pfm(&dir.join("denoised.pfm")));
    assert!(roughness(&denoised) < 0.5 * roughness(&raw), "{} vs raw {}", roughness(&denoised), roughness(&raw));
}
