//! Any scene phr loads, written in the reference renderer's JSON (the format of
//! `shared/reference/tools/render_reference.py`, which phr reads too): its triangles as PLY
//! files, one per mesh and material, its spheres, materials, view, background and settings.
//! So Mitsuba 3 renders what phr renders — the built-in scene, a glTF, a PLY — and a converged
//! reference or an equal-time peer image can be made of it (`phr export-reference`,
//! `phr bench-quality`).
//!
//! What the reference renderer has no equivalent for is refused, naming it: textures and
//! alpha masks (`tools/render_textured.py` renders an OBJ's `map_Kd` from the OBJ itself),
//! environment maps, two-sided lights.

use anyhow::{bail, Context, Result};
use phr_render::camera::CameraDesc;
use phr_render::material::Material;
use phr_render::output::write_atomically;
use phr_render::scene::{Background, Mesh, Scene};
use serde_json::{json, Value};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes `scene` seen from `view` as `dir/NAME.json` and its meshes as `dir/NAME_*.ply`;
/// returns the JSON's path. The scene's settings are written as they are (set the size and
/// samples on `scene.settings` first).
pub fn export_reference_scene(scene: &Scene, view: &CameraDesc, name: &str, dir: &Path) -> Result<PathBuf> {
    check_exportable(scene)?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let names = material_names(scene);
    let mut objects = Vec::new();
    let copies = scene.instanced.iter().flat_map(|i| i.written_out());
    let meshes = scene.meshes.iter().map(std::borrow::Cow::Borrowed).chain(copies.map(std::borrow::Cow::Owned));
    for (m, mesh) in meshes.enumerate() {
        for (material, triangles) in by_material(&mesh) {
            let file = format!("{name}_{m}_{material}.ply");
            write_ply(&dir.join(&file), &mesh, &triangles)?;
            objects.push(json!({"type": "mesh", "file": file, "material": names[material as usize]}));
        }
    }
    for s in &scene.spheres {
        objects.push(json!({"type": "sphere", "center": v3(s.sphere.center), "radius": num(s.sphere.radius),
                            "material": names[s.material as usize]}));
    }
    let materials: serde_json::Map<String, Value> =
        scene.materials.iter().zip(&names).map(|(m, n)| (n.clone(), material(m))).collect();
    let background = match &scene.background {
        Background::Constant(c) => v3(*c),
        Background::Gradient { bottom, top } => json!({"type": "gradient", "bottom": v3(*bottom), "top": v3(*top)}),
        Background::Environment(_) => unreachable!("refused above"),
    };
    let s = scene.settings;
    let file = json!({
        "description": format!("{name}, written by phr export-reference"),
        "width": s.width,
        "height": s.height,
        "spp": s.spp,
        "max_depth": s.max_depth,
        "background": background,
        "camera": {"position": v3(view.position), "look_at": v3(view.look_at), "up": v3(view.up),
                   "vfov": num(view.vfov_degrees)},
        "materials": materials,
        "objects": objects,
    });
    let path = dir.join(format!("{name}.json"));
    write_atomically(&path, |tmp| std::fs::write(tmp, serde_json::to_string_pretty(&file)? + "\n"))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// Refuses what the reference renderer cannot draw as phr does.
fn check_exportable(scene: &Scene) -> Result<()> {
    let named = |k: usize| scene.material_names.get(k).map_or("?", String::as_str).to_string();
    if let Some(k) = scene.material_texture.iter().position(Option::is_some) {
        bail!("material {} has a texture, which the reference renderer's scenes cannot name", named(k));
    }
    if let Some(k) = scene.material_mask.iter().position(Option::is_some) {
        bail!("material {} has an alpha mask, which the reference renderer's scenes cannot name", named(k));
    }
    if let Some(k) = scene.materials.iter().position(|m| matches!(m, Material::Emissive { two_sided: true, .. })) {
        bail!("material {} is a two-sided light, which Mitsuba's path tracer has no equivalent of", named(k));
    }
    if matches!(scene.background, Background::Environment(_)) {
        bail!("the scene's background is an environment map, which the reference renderer's scenes cannot name");
    }
    Ok(())
}

/// The materials' names, made unique (a suffix on repeats).
fn material_names(scene: &Scene) -> Vec<String> {
    let mut seen = std::collections::HashSet::new();
    (0..scene.materials.len())
        .map(|k| {
            let base = scene.material_names.get(k).cloned().unwrap_or_else(|| format!("material{k}"));
            let name = if seen.contains(&base) { format!("{base}#{k}") } else { base };
            seen.insert(name.clone());
            name
        })
        .collect()
}

/// `x` in the fewest digits that read back as `x` (0.9, not 0.8999999761581421).
fn num(x: f32) -> Value {
    json!(x.to_string().parse::<f64>().expect("a finite f32 prints as a number"))
}

fn v3(v: glam::Vec3) -> Value {
    json!([num(v.x), num(v.y), num(v.z)])
}

fn material(m: &Material) -> Value {
    match *m {
        Material::Lambertian { albedo } => json!({"type": "lambertian", "albedo": v3(albedo)}),
        Material::Metal { albedo, fuzz, fuzz_in_sphere } => {
            json!({"type": "metal", "albedo": v3(albedo), "fuzz": num(fuzz), "fuzz_in_sphere": fuzz_in_sphere})
        }
        Material::Dielectric { ior } => json!({"type": "dielectric", "ior": num(ior)}),
        Material::Emissive { emit, two_sided } => json!({"type": "emissive", "emit": v3(emit), "two_sided": two_sided}),
    }
}

/// The mesh's triangles grouped by material, in their order.
fn by_material(mesh: &Mesh) -> Vec<(u32, Vec<[u32; 3]>)> {
    let mut groups: std::collections::BTreeMap<u32, Vec<[u32; 3]>> = Default::default();
    for (t, &m) in mesh.triangles.iter().zip(&mesh.triangle_material) {
        groups.entry(m).or_default().push(*t);
    }
    groups.into_iter().collect()
}

/// `triangles` of `mesh` as a binary little-endian PLY (float positions, the vertices they
/// use, in their order of first use; int indices).
fn write_ply(path: &Path, mesh: &Mesh, triangles: &[[u32; 3]]) -> Result<()> {
    let mut index = std::collections::HashMap::new();
    let mut vertices = Vec::new();
    let faces: Vec<[u32; 3]> = triangles
        .iter()
        .map(|t| {
            t.map(|v| {
                *index.entry(v).or_insert_with(|| {
                    vertices.push(mesh.positions[v as usize]);
                    vertices.len() as u32 - 1
                })
            })
        })
        .collect();
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        write!(
            f,
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
             property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            vertices.len(),
            faces.len()
        )?;
        for v in &vertices {
            for c in v.to_array() {
                f.write_all(&c.to_le_bytes())?;
            }
        }
        for face in &faces {
            f.write_all(&[3])?;
            for i in face {
                f.write_all(&(*i as i32).to_le_bytes())?;
            }
        }
        f.flush()
    })
    .with_context(|| format!("writing {}", path.display()))
}
