//! Textured OBJ and glTF files end to end: `vt` coordinates and an MTL `map_Kd` PNG, or
//! `TEXCOORD_0` and a `baseColorTexture` (times its base colour), become the albedo of a
//! Lambertian quad. Lit by a constant white sky with nothing else around, every path that
//! hits the quad leaves to the sky after one bounce, so a pixel's radiance is exactly the
//! texture's linear colour where its ray hits: the image shows the texture, texel for texel,
//! whatever the noise. Also: a missing texture file is an error naming it and its material,
//! and two materials naming one file share one texture.

use glam::Vec3;
use phr_bvh::Builder;
use phr_render::geometry::Geometry;
use phr_render::render::Renderer;
use phr_render::scene::load_scene;
use std::path::{Path, PathBuf};

/// A fresh folder under the target directory.
fn folder(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("textures-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// 2 × 2 texels, top row red and green, bottom row blue and mid grey (sRGB 128).
const TEXELS: [[u8; 3]; 4] = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [128, 128, 128]];

/// A unit quad in the z = 0 plane facing +z with `vt` corners (0,0)…(1,1), its MTL naming
/// `texture` for material `a` (and for `b`, used by a second quad, when `twice`), and a
/// scene file that looks at it head-on under a white sky.
fn write_scene(dir: &Path, texture: &str, twice: bool) -> PathBuf {
    let image = image::RgbImage::from_fn(2, 2, |x, y| image::Rgb(TEXELS[(y * 2 + x) as usize]));
    image.save(dir.join("checker.png")).unwrap();
    let mut obj = String::from("mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n");
    obj += "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl a\nf 1/1 2/2 3/3 4/4\n";
    let mut mtl = format!("newmtl a\nKd 0.5 0.5 0.5\nmap_Kd {texture}\n");
    if twice {
        obj += "v -1 -1 -5\nv 1 -1 -5\nv 1 1 -5\nusemtl b\nf 5/1 6/2 7/3\n";
        mtl += &format!("newmtl b\nKd 0.5 0.5 0.5\nmap_Kd -s 1 1 1 {texture}\n");
    }
    std::fs::write(dir.join("quad.obj"), obj).unwrap();
    std::fs::write(dir.join("quad.mtl"), mtl).unwrap();
    let scene = r#"{
      "width": 64, "height": 64, "spp": 1, "max_depth": 4, "background": [1, 1, 1],
      "camera": { "position": [0, 0, 2], "look_at": [0, 0, 0], "vfov": 40 },
      "objects": [ { "type": "obj_mtl", "file": "quad.obj" } ]
    }"#;
    std::fs::write(dir.join("scene.json"), scene).unwrap();
    dir.join("scene.json")
}

fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Renders `scene_file` (a quad filling the view, textured with [`TEXELS`]) and checks the
/// pixels at the texel centres against the texels' linear colours times `tint`.
fn check_texels(scene_file: &Path, tint: f32) {
    check_texels_shown(scene_file, tint, [0, 1, 2, 3]);
}

/// [`check_texels`] where the view's top left, top right, bottom left and bottom right
/// quarters show the texels `shown` (a texture transform moved them).
fn check_texels_shown(scene_file: &Path, tint: f32, shown: [usize; 4]) {
    let scene = load_scene(scene_file).unwrap();
    assert_eq!(scene.textures.len(), 1);
    let mut geometry = Geometry::new(&scene);
    geometry.build(&Builder::default());
    for lights in [false, true] {
        let light_set =
            lights.then(|| phr_render::lights::LightSet::new(&geometry, &scene.materials, &scene.background));
        let renderer =
            Renderer::new(&scene, &geometry, &scene.view(None).unwrap(), &scene.settings, light_set.as_ref());
        let (image, _) = renderer.render_frame(0);
        // The quad fills the view (which spans ±2 tan 20° = ±0.728 at its distance): its
        // texel centres, at ±0.5, fall at pixels 32 ± 0.5 / 0.728 · 32 = 32 ± 22.
        for (k, texel) in shown.map(|t| TEXELS[t]).iter().enumerate() {
            let (x, y) = (32 + if k % 2 == 0 { -22 } else { 22 }, 32 + if k < 2 { -22 } else { 22 });
            let pixel = image[(y * 64 + x) as usize];
            let expected = tint * Vec3::from(texel.map(srgb_to_linear));
            // Up to the pixel's jitter across the bilinear blend: a texel is 44 pixels wide.
            assert!(
                (pixel - expected).abs().max_element() < 0.08,
                "{}, light sampling {lights}: texel {k} at pixel ({x}, {y}): {pixel}, expected {expected}",
                scene_file.display()
            );
        }
    }
}

#[test]
fn a_textured_obj_quad_shows_its_texels() {
    let dir = folder("quad");
    check_texels(&write_scene(&dir, "checker.png", false), 1.0);
}

/// The same quad as glTF: `TEXCOORD_0` (v down the image) and a `baseColorTexture` file,
/// times a base colour of 0.5.
#[test]
fn a_textured_gltf_quad_shows_its_texels_times_the_base_colour() {
    let dir = folder("gltf");
    check_texels(&write_gltf_scene(&dir, "", ""), 0.5);
}

/// glTF `alphaMode` `MASK`: where the base-colour texture's alpha falls below the cutoff the
/// quad is not there, and the sky behind it shows; elsewhere its texels, as before. The
/// cutoff is compared with the texture's alpha times the base colour factor's.
#[test]
fn a_gltf_alpha_mask_cuts_the_quad() {
    let dir = folder("gltf-mask");
    // Texel 1 (top right) at alpha 0.4, the others opaque; factor alpha 0.8, cutoff 0.3: texel
    // 1 gives 0.32, still there; with cutoff 0.4, 0.32 is a hole.
    for (cutoff, hole) in [(0.3, false), (0.4, true)] {
        let material = format!(r#", "alphaMode": "MASK", "alphaCutoff": {cutoff}"#);
        let scene_file = write_gltf_scene(&dir, "", &material);
        let json = std::fs::read_to_string(dir.join("quad.gltf"))
            .unwrap()
            .replace("[0.5, 0.5, 0.5, 1]", "[0.5, 0.5, 0.5, 0.8]");
        std::fs::write(dir.join("quad.gltf"), json).unwrap();
        let alpha = [255, 102, 255, 255];
        let image = image::RgbaImage::from_fn(2, 2, |x, y| {
            let k = (y * 2 + x) as usize;
            let [r, g, b] = TEXELS[k];
            image::Rgba([r, g, b, alpha[k]])
        });
        image.save(dir.join("checker.png")).unwrap();
        let scene = load_scene(&scene_file).unwrap();
        let mut geometry = Geometry::new(&scene);
        geometry.build(&Builder::default());
        let renderer = Renderer::new(&scene, &geometry, &scene.view(None).unwrap(), &scene.settings, None);
        let (image, _) = renderer.render_frame(0);
        let pixel = |x: i32, y: i32| image[(y * 64 + x) as usize];
        let expected = if hole { Vec3::ONE } else { 0.5 * Vec3::from(TEXELS[1].map(srgb_to_linear)) };
        assert!((pixel(54, 10) - expected).abs().max_element() < 0.08, "cutoff {cutoff}: {}", pixel(54, 10));
        let opaque = 0.5 * Vec3::from(TEXELS[0].map(srgb_to_linear));
        assert!((pixel(10, 10) - opaque).abs().max_element() < 0.08, "cutoff {cutoff}: {}", pixel(10, 10));
    }
}

/// `KHR_texture_transform` on the base-colour texture: scale `(-1, 1)`, then a quarter turn,
/// then an offset of `(0.5, 0)` map the quad's `(u, v)` to `(v + 0.5, u)` (with the rotation
/// of the extension's sample model: `+u` turns towards `-v`), so the top left quarter shows
/// texel 1, the top right texel 3, the bottom left texel 0 and the bottom right texel 2.
/// The other rotation, or another order of the three, shows grey or blue at the top left.
/// A value that is not finite is an error.
#[test]
fn a_gltf_texture_transform_moves_the_texels() {
    let dir = folder("gltf-transform");
    let transform =
        r#", "extensions": {"KHR_texture_transform": {"offset": [0.5, 0], "rotation": 1.5707964, "scale": [-1, 1]}}"#;
    check_texels_shown(&write_gltf_scene(&dir, transform, ""), 0.5, [1, 3, 0, 2]);
    let broken = folder("gltf-transform-inf");
    let infinite = r#", "extensions": {"KHR_texture_transform": {"rotation": 1e39}}"#;
    let Err(error) = load_scene(&write_gltf_scene(&broken, infinite, "")) else {
        panic!("an infinite rotation loaded")
    };
    let error = error.to_string();
    assert!(error.contains("quad.gltf") && error.contains("KHR_texture_transform"), "{error}");
}

/// glTF `alphaMode` `MASK` without a texture: the base colour factor's alpha alone decides,
/// so below the cutoff the whole quad is gone and the sky shows; above it, the quad.
#[test]
fn a_gltf_mask_without_texture_keeps_or_drops_the_whole_surface() {
    let dir = folder("gltf-mask-factor");
    for (alpha, gone) in [(0.8, false), (0.2, true)] {
        let scene_file = write_gltf_scene(&dir, "", r#", "alphaMode": "MASK""#);
        let json = std::fs::read_to_string(dir.join("quad.gltf"))
            .unwrap()
            .replace(r#""baseColorTexture": {"index": 0}"#, r#""roughnessFactor": 1"#)
            .replace("[0.5, 0.5, 0.5, 1]", &format!("[0.5, 0.5, 0.5, {alpha}]"));
        std::fs::write(dir.join("quad.gltf"), json).unwrap();
        let scene = load_scene(&scene_file).unwrap();
        let mut geometry = Geometry::new(&scene);
        geometry.build(&Builder::default());
        let renderer = Renderer::new(&scene, &geometry, &scene.view(None).unwrap(), &scene.settings, None);
        let (image, _) = renderer.render_frame(0);
        let expected = if gone { Vec3::ONE } else { Vec3::splat(0.5) };
        for pixel in [image[10 * 64 + 10], image[32 * 64 + 32], image[54 * 64 + 54]] {
            assert!((pixel - expected).abs().max_element() < 0.02, "factor alpha {alpha}: {pixel}");
        }
    }
}

/// Writes the textured quad of [`write_scene`] as `quad.gltf`, with `info` added to its
/// `baseColorTexture` object and `material` to its material, and a scene file `gltf.json`
/// showing it; returns the scene file.
fn write_gltf_scene(dir: &Path, info: &str, material: &str) -> PathBuf {
    write_scene(dir, "checker.png", false);
    let mut buffer = Vec::new();
    let floats = [-1.0f32, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0];
    let uvs = [0.0f32, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
    for v in floats.iter().chain(&uvs) {
        buffer.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        buffer.extend_from_slice(&i.to_le_bytes());
    }
    let uri = format!("data:application/octet-stream;base64,{}", base64::encode(&buffer));
    let gltf = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": 0}}]}}],
  "materials": [{{"name": "checker", "pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0,
    "baseColorTexture": {{"index": 0{info}}}}}{material}}}],
  "textures": [{{"source": 0}}],
  "images": [{{"uri": "checker.png"}}],
  "buffers": [{{"byteLength": {len}, "uri": "{uri}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
    {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
    {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]
}}"#,
        len = buffer.len()
    );
    std::fs::write(dir.join("quad.gltf"), gltf).unwrap();
    let scene = std::fs::read_to_string(dir.join("scene.json")).unwrap();
    let scene =
        scene.replace(r#"{ "type": "obj_mtl", "file": "quad.obj" }"#, r#"{ "type": "gltf", "file": "quad.gltf" }"#);
    std::fs::write(dir.join("gltf.json"), scene).unwrap();
    dir.join("gltf.json")
}

#[test]
fn one_file_is_one_texture_and_a_missing_one_is_named() {
    let dir = folder("shared");
    let scene = load_scene(&write_scene(&dir, "checker.png", true)).unwrap();
    assert_eq!(scene.textures.len(), 1, "two materials, one file");
    assert_eq!(scene.material_texture.iter().flatten().count(), 2);
    let dir = folder("missing");
    let error = load_scene(&write_scene(&dir, "no_such.png", false)).unwrap_err().to_string();
    assert!(error.contains("no_such.png") && error.contains("material \"a\""), "{error}");
}

/// The same quad as an ASCII PLY with `s t` per vertex, drawn by a `mesh` object whose scene
/// material names the texture (times an albedo of 0.5).
fn write_ply_scene(dir: &Path, object: &str) -> PathBuf {
    write_scene(dir, "checker.png", false);
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
               property float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\n\
               end_header\n-1 -1 0 0 0\n1 -1 0 1 0\n1 1 0 1 1\n-1 1 0 0 1\n4 0 1 2 3\n";
    std::fs::write(dir.join("quad.ply"), ply).unwrap();
    let scene = format!(
        r#"{{
      "width": 64, "height": 64, "spp": 1, "max_depth": 4, "background": [1, 1, 1],
      "camera": {{ "position": [0, 0, 2], "look_at": [0, 0, 0], "vfov": 40 }},
      "materials": {{ "checker": {{ "type": "lambertian", "albedo": [0.5, 0.5, 0.5], "texture": "checker.png" }} }},
      "objects": [ {object} ]
    }}"#
    );
    std::fs::write(dir.join("ply_scene.json"), scene).unwrap();
    dir.join("ply_scene.json")
}

#[test]
fn a_ply_quad_with_texture_coordinates_shows_a_scene_materials_texels() {
    let dir = folder("ply");
    check_texels(&write_ply_scene(&dir, r#"{ "type": "mesh", "file": "quad.ply", "material": "checker" }"#), 0.5);
}

/// A textured scene material on something without texture coordinates is refused, naming
/// the material; so is a texture that is not there.
#[test]
fn a_textured_material_needs_texture_coordinates_and_its_image() {
    let dir = folder("no-uv");
    let cases = [
        (r#"{ "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "checker" }"#, "a sphere"),
        (r#"{ "type": "quad", "Q": [0, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "material": "checker" }"#, "a quad"),
        (r#"{ "type": "mesh", "file": "plain.obj", "material": "checker" }"#, "plain.obj has no texture coordinates"),
        (
            r#"{ "type": "obj_mtl", "file": "plain.obj", "material": "checker" }"#,
            "plain.obj has no texture coordinates",
        ),
    ];
    for (object, expected) in cases {
        let scene = write_ply_scene(&dir, object);
        std::fs::write(dir.join("plain.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let error = load_scene(&scene).unwrap_err().to_string();
        assert!(error.contains("material \"checker\" has a texture") && error.contains(expected), "{error}");
    }
    let scene = write_ply_scene(&dir, r#"{ "type": "mesh", "file": "quad.ply", "material": "checker" }"#);
    std::fs::remove_file(dir.join("checker.png")).unwrap();
    let error = load_scene(&scene).unwrap_err().to_string();
    assert!(error.contains("checker.png") && error.contains("material \"checker\""), "{error}");
}
