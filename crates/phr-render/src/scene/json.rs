//! The scene file: JSON, the format of `shared/reference/README.md` (so the reference scenes
//! load as they are), extended with named views, glTF objects and a choice of MTL mapping.
//!
//! Top level: `width`, `height` (or `resolution`), `spp`, `max_depth`, `camera`, `views`
//! (`{"name": camera, ...}`, in file order, after `camera` which is called `default`),
//! `background` (a colour, `{"type": "constant", "color"}`, `{"type": "gradient", "bottom",
//! "top"}` or `{"type": "environment", "file", "scale", "rotate"}`, an HDR image all around,
//! see [`crate::environment`]), `materials` (`{"name": material}`), `objects` (a list). Object types: `sphere`,
//! `quad`, `triangle`, `triangles`, `mesh` (one material for a whole OBJ/PLY/glTF file),
//! `obj_mtl` (an OBJ with its MTL, optional per-name overrides and `"mtl_mapping": "reference"
//! | "full"`, see [`super::materials`]), `gltf` (a glTF file with its own materials and
//! cameras). Objects made of triangles may carry `instances`, a list of transforms: the object
//! is then placed once per transform and its triangles are stored once. File paths may start with `{scenes}`, the shared scenes folder (see
//! [`scenes_dir`]); other relative paths are relative to the scene file. `docs/scene-format.md`
//! documents every key.

use super::materials::MtlMapping;
use super::{Background, InstancedMesh, Mesh, RenderSettings, Scene, SphereObject};
use crate::camera::CameraDesc;
use crate::environment::EnvironmentMap;
use crate::error::LoadError;
use crate::load::{load_mesh_keeping_shared, MeshData};
use crate::material::Material;
use crate::motion::{Animation, AnimationTarget, Motion, ObjectAnimation};
use glam::{Affine3A, Mat4, Quat, Vec2, Vec3};
use indexmap::IndexMap;
use phr_bvh::instance::Instance;
use phr_bvh::sphere::Sphere;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A number meaning the same value three times, or three numbers.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
enum Color {
    Scalar(f32),
    Rgb([f32; 3]),
}

impl From<Color> for Vec3 {
    fn from(c: Color) -> Vec3 {
        match c {
            Color::Scalar(s) => Vec3::splat(s),
            Color::Rgb(v) => Vec3::from(v),
        }
    }
}

#[derive(Deserialize)]
struct SceneFile {
    width: Option<u32>,
    height: Option<u32>,
    resolution: Option<[u32; 2]>,
    spp: Option<u32>,
    max_depth: Option<u32>,
    camera: Option<CameraFile>,
    #[serde(default)]
    views: IndexMap<String, CameraFile>,
    background: Option<BackgroundFile>,
    #[serde(default)]
    materials: IndexMap<String, MaterialFile>,
    objects: Vec<ObjectEntry>,
}

/// An object and, for dynamic scenes, how it moves.
#[derive(Deserialize)]
struct ObjectEntry {
    #[serde(flatten)]
    object: ObjectFile,
    animate: Option<MotionsFile>,
    /// Placements of the object (after its own `transform`), one copy each.
    instances: Option<Vec<TransformFile>>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum MotionsFile {
    One(MotionFile),
    Many(Vec<MotionFile>),
}

/// A procedural motion (see [`crate::motion::Motion`]).
#[derive(Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
enum MotionFile {
    Rotate {
        #[serde(default = "default_up")]
        axis: [f32; 3],
        /// Defaults to the centre of the object's bounds.
        pivot: Option<[f32; 3]>,
        degrees_per_second: f32,
    },
    Oscillate {
        amplitude: [f32; 3],
        period: f32,
    },
    Wave {
        amplitude: f32,
        wavelength: f32,
        period: f32,
        #[serde(default = "default_wave_direction")]
        direction: [f32; 3],
        #[serde(default = "default_up")]
        displacement: [f32; 3],
    },
}

fn default_wave_direction() -> [f32; 3] {
    [1.0, 0.0, 0.0]
}

#[derive(Deserialize)]
struct CameraFile {
    #[serde(alias = "lookfrom")]
    position: [f32; 3],
    #[serde(alias = "lookat")]
    look_at: [f32; 3],
    #[serde(alias = "vup", default = "default_up")]
    up: [f32; 3],
    #[serde(default = "default_vfov")]
    vfov: f32,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

fn default_vfov() -> f32 {
    90.0
}

#[derive(Deserialize)]
#[serde(untagged)]
enum BackgroundFile {
    Color(Color),
    Typed(TypedBackground),
}

#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
enum TypedBackground {
    Constant {
        color: Color,
    },
    Gradient {
        bottom: Color,
        top: Color,
    },
    Environment {
        file: String,
        #[serde(default = "unit_scale")]
        scale: f32,
        /// Degrees about +y.
        #[serde(default)]
        rotate: f32,
    },
}

fn unit_scale() -> f32 {
    1.0
}

#[derive(Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
enum MaterialFile {
    #[serde(alias = "diffuse")]
    Lambertian {
        albedo: Color,
        /// An image (PNG or JPEG, relative to the scene file) that the albedo multiplies,
        /// through the mesh's texture coordinates.
        #[serde(default)]
        texture: Option<String>,
    },
    Metal {
        albedo: Color,
        #[serde(default)]
        fuzz: f32,
        #[serde(default)]
        fuzz_in_sphere: bool,
    },
    Dielectric {
        #[serde(alias = "refraction_index", alias = "ir")]
        ior: f32,
    },
    #[serde(alias = "diffuse_light", alias = "light")]
    Emissive {
        emit: Color,
        #[serde(default)]
        two_sided: bool,
    },
}

impl MaterialFile {
    /// Refuses what no material can be: colours that are negative or not finite, an index of
    /// refraction that is not positive.
    fn check(&self) -> Result<(), String> {
        let colour = |c: Color, what: &str| {
            let v = Vec3::from(c);
            if v.is_finite() && v.min_element() >= 0.0 {
                Ok(())
            } else {
                Err(format!("{what} [{}, {}, {}] must be finite and not negative", v.x, v.y, v.z))
            }
        };
        match *self {
            MaterialFile::Lambertian { albedo, .. } | MaterialFile::Metal { albedo, .. } => colour(albedo, "albedo"),
            MaterialFile::Emissive { emit, .. } => colour(emit, "emit"),
            MaterialFile::Dielectric { ior } if ior.is_finite() && ior > 0.0 => Ok(()),
            MaterialFile::Dielectric { ior } => Err(format!("ior {ior} must be finite and positive")),
        }
    }
}

impl From<&MaterialFile> for Material {
    fn from(m: &MaterialFile) -> Material {
        match *m {
            MaterialFile::Lambertian { albedo, .. } => Material::Lambertian { albedo: albedo.into() },
            MaterialFile::Metal { albedo, fuzz, fuzz_in_sphere } => {
                Material::Metal { albedo: albedo.into(), fuzz: fuzz.clamp(0.0, 1.0), fuzz_in_sphere }
            }
            MaterialFile::Dielectric { ior } => Material::Dielectric { ior },
            MaterialFile::Emissive { emit, two_sided } => Material::Emissive { emit: emit.into(), two_sided },
        }
    }
}

#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
enum ObjectFile {
    Sphere {
        center: [f32; 3],
        radius: f32,
        material: String,
    },
    Quad {
        #[serde(rename = "Q")]
        q: [f32; 3],
        u: [f32; 3],
        v: [f32; 3],
        material: String,
        transform: Option<TransformFile>,
    },
    Triangle {
        v0: [f32; 3],
        v1: [f32; 3],
        v2: [f32; 3],
        material: String,
        transform: Option<TransformFile>,
    },
    Triangles {
        vertices: Vec<[f32; 3]>,
        faces: Vec<[u32; 3]>,
        material: String,
        transform: Option<TransformFile>,
    },
    Mesh {
        file: String,
        material: String,
        transform: Option<TransformFile>,
        #[serde(default)]
        #[allow(dead_code)]
        smooth_normals: bool,
    },
    ObjMtl {
        file: String,
        #[serde(default)]
        materials: IndexMap<String, MaterialFile>,
        material: Option<String>,
        transform: Option<TransformFile>,
        #[serde(default)]
        mtl_mapping: MtlMappingFile,
    },
    Gltf {
        file: String,
        transform: Option<TransformFile>,
    },
}

#[derive(Clone, Copy, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
enum MtlMappingFile {
    #[default]
    Reference,
    Full,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum TransformFile {
    Matrix { matrix: [[f32; 4]; 4] },
    Srt(SrtFile),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SrtFile {
    scale: Option<Color>,
    rotate: Option<Rotations>,
    translate: Option<[f32; 3]>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum Rotations {
    One([f32; 4]),
    Many(Vec<[f32; 4]>),
}

impl TransformFile {
    /// Scale first, then the rotations in list order, then the translation.
    fn matrix(&self) -> Mat4 {
        match self {
            TransformFile::Matrix { matrix } => Mat4::from_cols_array_2d(matrix).transpose(),
            TransformFile::Srt(srt) => {
                let mut m = Mat4::from_scale(srt.scale.map_or(Vec3::ONE, Vec3::from));
                let rotations = match &srt.rotate {
                    None => Vec::new(),
                    Some(Rotations::One(r)) => vec![*r],
                    Some(Rotations::Many(rs)) => rs.clone(),
                };
                for [x, y, z, degrees] in rotations {
                    let axis = Vec3::new(x, y, z).normalize_or(Vec3::Y);
                    m = Mat4::from_quat(Quat::from_axis_angle(axis, degrees.to_radians())) * m;
                }
                Mat4::from_translation(Vec3::from(srt.translate.unwrap_or([0.0; 3]))) * m
            }
        }
    }
}

/// Reads a scene file (through [`super::load_scene`], the one way to open a scene).
pub(crate) fn load_scene_file(path: &Path) -> Result<Scene, LoadError> {
    let bytes = crate::load::input::read_file(path, "the scene file")?;
    let text = std::str::from_utf8(crate::load::input::strip_bom(&bytes))
        .map_err(|e| LoadError::new(path, format!("not UTF-8 text: {e}")))?;
    parse_scene(text, path)
}

/// Parses scene JSON; `path` names the file in errors and anchors relative paths.
pub fn parse_scene(text: &str, path: &Path) -> Result<Scene, LoadError> {
    let syntax = |e: serde_json::Error| {
        let message = e.to_string();
        let message = message.split(" at line ").next().unwrap_or(&message).to_string();
        LoadError::at_line(path, e.line(), message)
    };
    let value: serde_json::Value = serde_json::from_str(text).map_err(syntax)?;
    check_keys(&value).map_err(|message| LoadError::new(path, message))?;
    let file: SceneFile = serde_json::from_str(text).map_err(syntax)?;
    SceneBuilder { path, scene: Scene::default(), keep_shared: true }.build(file)
}

/// The keys each part of a scene file may have. An unknown key is an error, not ignored: a
/// misspelt `fov` used to leave the camera at 90° without a word, a `transform` on a sphere
/// was dropped. (Materials, motions and transforms are checked by their types.)
const TOP_LEVEL_KEYS: &[&str] = &[
    "description",
    "width",
    "height",
    "resolution",
    "spp",
    "max_depth",
    "camera",
    "views",
    "background",
    "materials",
    "objects",
];
const CAMERA_KEYS: &[&str] = &["position", "lookfrom", "look_at", "lookat", "up", "vup", "vfov"];

fn object_keys(kind: &str) -> Option<&'static [&'static str]> {
    Some(match kind {
        "sphere" => &["type", "center", "radius", "material", "animate"],
        "quad" => &["type", "Q", "u", "v", "material", "transform", "animate", "instances"],
        "triangle" => &["type", "v0", "v1", "v2", "material", "transform", "animate", "instances"],
        "triangles" => &["type", "vertices", "faces", "material", "transform", "animate", "instances"],
        "mesh" => &["type", "file", "material", "transform", "smooth_normals", "animate", "instances"],
        "obj_mtl" => &["type", "file", "materials", "material", "transform", "mtl_mapping", "animate", "instances"],
        "gltf" => &["type", "file", "transform", "animate", "instances"],
        _ => return None,
    })
}

/// Fails on the first key that [`TOP_LEVEL_KEYS`], [`CAMERA_KEYS`] or [`object_keys`] do not
/// list, naming where it is and what is allowed there.
fn check_keys(scene: &serde_json::Value) -> Result<(), String> {
    fn check(value: &serde_json::Value, allowed: &[&str], place: &str) -> Result<(), String> {
        let Some(map) = value.as_object() else { return Ok(()) };
        match map.keys().find(|k| !allowed.contains(&k.as_str())) {
            Some(key) => Err(format!("{place}: unknown key \"{key}\" (allowed: {})", allowed.join(", "))),
            None => Ok(()),
        }
    }
    check(scene, TOP_LEVEL_KEYS, "top level")?;
    if let Some(camera) = scene.get("camera") {
        check(camera, CAMERA_KEYS, "camera")?;
    }
    for (name, view) in scene.get("views").and_then(|v| v.as_object()).into_iter().flatten() {
        check(view, CAMERA_KEYS, &format!("view \"{name}\""))?;
    }
    if let Some(background) = scene.get("background") {
        let allowed: Option<&[&str]> = match background.get("type").and_then(|t| t.as_str()) {
            Some("constant") => Some(&["type", "color"]),
            Some("gradient") => Some(&["type", "bottom", "top"]),
            Some("environment") => Some(&["type", "file", "scale", "rotate"]),
            // No type (a colour), or an unknown one, which the parser names.
            _ => None,
        };
        if let Some(allowed) = allowed {
            check(background, allowed, "background")?;
        }
    }
    for (i, object) in scene.get("objects").and_then(|v| v.as_array()).into_iter().flatten().enumerate() {
        let kind = object.get("type").and_then(|t| t.as_str()).unwrap_or("");
        if let Some(allowed) = object_keys(kind) {
            check(object, allowed, &format!("object {i} ({kind})"))?;
        }
    }
    Ok(())
}

/// The shortest period or wavelength a motion may have (see `SceneBuilder::animate`).
const MIN_PERIOD: f32 = 1e-6;

struct SceneBuilder<'a> {
    path: &'a Path,
    scene: Scene,
    /// The object being added may keep a glTF's shared meshes instanced.
    keep_shared: bool,
}

impl SceneBuilder<'_> {
    fn err(&self, message: impl Into<String>) -> LoadError {
        LoadError::new(self.path, message)
    }

    fn build(mut self, file: SceneFile) -> Result<Scene, LoadError> {
        let [width, height] = file.resolution.unwrap_or([file.width.unwrap_or(256), file.height.unwrap_or(256)]);
        self.scene.settings =
            RenderSettings { width, height, spp: file.spp.unwrap_or(64), max_depth: file.max_depth.unwrap_or(50) };
        self.scene.settings.check().map_err(|e| self.err(e))?;
        self.scene.background = match file.background {
            None => Background::Constant(Vec3::ZERO),
            Some(BackgroundFile::Color(c)) => Background::Constant(c.into()),
            Some(BackgroundFile::Typed(TypedBackground::Constant { color })) => Background::Constant(color.into()),
            Some(BackgroundFile::Typed(TypedBackground::Gradient { bottom, top })) => {
                Background::Gradient { bottom: bottom.into(), top: top.into() }
            }
            Some(BackgroundFile::Typed(TypedBackground::Environment { ref file, scale, rotate })) => {
                let path = resolve_path(file, self.path)?;
                Background::Environment(std::sync::Arc::new(EnvironmentMap::load(&path, scale, rotate)?))
            }
        };
        for (name, m) in &file.materials {
            m.check().map_err(|e| self.err(format!("material \"{name}\": {e}")))?;
            self.add_material(name, m)?;
        }
        if let Some(c) = &file.camera {
            self.scene.views.push(("default".into(), camera_desc(c).map_err(|e| self.err(format!("camera: {e}")))?));
        }
        for (name, c) in &file.views {
            let view = camera_desc(c).map_err(|e| self.err(format!("view \"{name}\": {e}")))?;
            self.scene.views.push((name.clone(), view));
        }
        for (i, entry) in file.objects.iter().enumerate() {
            let (meshes, spheres) = (self.scene.meshes.len(), self.scene.spheres.len());
            // An object placed by `instances` is one mesh: a glTF's shared meshes are written out.
            // So is a moving object: its motion moves its one mesh.
            self.keep_shared = entry.instances.is_none() && entry.animate.is_none();
            self.add_object(i, &entry.object)?;
            if let Some(animate) = &entry.animate {
                self.animate(i, animate, meshes, spheres)?;
            }
            if let Some(instances) = &entry.instances {
                self.instance(i, instances, meshes)?;
            }
        }
        if self.scene.meshes.is_empty() && self.scene.instanced.is_empty() && self.scene.spheres.is_empty() {
            return Err(self.err("the scene has no objects"));
        }
        if self.scene.views.is_empty() {
            let auto = self.scene.framing_camera();
            self.scene.views.push(("auto".into(), auto));
        }
        self.scene.check_range(self.path)?;
        Ok(self.scene)
    }

    /// Attaches `animate` to the mesh or sphere object `i` just added (the first new mesh is
    /// number `meshes`, the first new sphere `spheres`).
    fn animate(&mut self, i: usize, animate: &MotionsFile, meshes: usize, spheres: usize) -> Result<(), LoadError> {
        let (target, pivot) = if self.scene.spheres.len() > spheres {
            (AnimationTarget::Sphere(spheres), self.scene.spheres[spheres].sphere.center)
        } else if self.scene.meshes.len() > meshes {
            let mut b = phr_bvh::Aabb::EMPTY;
            self.scene.meshes[meshes].positions.iter().for_each(|&p| b = b.grown(p));
            (AnimationTarget::Mesh(meshes), b.center())
        } else {
            return Err(self.err(format!("object {i}: nothing to animate")));
        };
        if self.scene.animations.iter().any(|a| a.target == target) {
            return Err(
                self.err(format!("object {i}: the glTF file animates itself; \"animate\" cannot be combined with it"))
            );
        }
        let list = match animate {
            MotionsFile::One(m) => vec![m.clone()],
            MotionsFile::Many(ms) => ms.clone(),
        };
        let bad = |what: &str| self.err(format!("object {i}: animate: {what}"));
        let unit = |v: [f32; 3], what: &str| {
            let v = Vec3::from(v);
            if v.is_finite() && v.length() > 0.0 {
                Ok(v.normalize())
            } else {
                Err(bad(&format!("{what} must be a non-zero vector")))
            }
        };
        // Periods and wavelengths below a millionth (of a second, of a unit) make `t / period`
        // overflow to infinity and the pose NaN; amounts must be finite and within the range
        // the renderer accepts.
        let positive = |x: f32, what: &str| {
            if x.is_finite() && x >= MIN_PERIOD {
                Ok(x)
            } else {
                Err(bad(&format!("{what} {x:e} must be at least {MIN_PERIOD:e}")))
            }
        };
        let amount = |x: f32, what: &str| {
            if x.is_finite() && x.abs() <= super::MAX_COORDINATE {
                Ok(x)
            } else {
                Err(bad(&format!("{what} {x:e} must be finite and at most {:e}", super::MAX_COORDINATE)))
            }
        };
        let amounts = |v: [f32; 3], what: &str| -> Result<Vec3, LoadError> {
            for x in v {
                amount(x, what)?;
            }
            Ok(v.into())
        };
        let mut motions = Vec::with_capacity(list.len());
        for m in list {
            motions.push(match m {
                MotionFile::Rotate { axis, pivot: p, degrees_per_second } => {
                    let pivot = p.map_or(Ok(pivot), |p| amounts(p, "pivot"))?;
                    let degrees_per_second = amount(degrees_per_second, "degrees_per_second")?;
                    Motion::Rotate { axis: unit(axis, "axis")?, pivot, degrees_per_second }
                }
                MotionFile::Oscillate { amplitude, period } => Motion::Oscillate {
                    amplitude: amounts(amplitude, "amplitude")?,
                    period: positive(period, "period")?,
                },
                MotionFile::Wave { amplitude, wavelength, period, direction, displacement } => Motion::Wave {
                    amplitude: amount(amplitude, "amplitude")?,
                    wavelength: positive(wavelength, "wavelength")?,
                    period: positive(period, "period")?,
                    direction: unit(direction, "direction")?,
                    displacement: unit(displacement, "displacement")?,
                },
            });
        }
        self.scene.animations.push(ObjectAnimation { target, animation: Animation::Procedural(motions) });
        Ok(())
    }

    /// Turns the meshes object `i` has just added (from number `meshes` on) into one mesh
    /// placed by each of `instances`. Copies of a mesh that emits or has an alpha mask
    /// become ordinary triangles instead ([`Scene::written_out_for`]), at most
    /// [`MAX_COPIED_TRIANGLES`] of them.
    fn instance(&mut self, i: usize, instances: &[TransformFile], meshes: usize) -> Result<(), LoadError> {
        let path = self.path;
        let bad = |what: String| LoadError::new(path, format!("object {i}: instances: {what}"));
        // Its `animate` moves every copy, rigidly: a wave or a glTF animation would deform the
        // one mesh they share.
        let mut motions = Vec::new();
        while let Some(k) =
            self.scene.animations.iter().position(|a| matches!(a.target, AnimationTarget::Mesh(m) if m >= meshes))
        {
            match self.scene.animations.remove(k).animation {
                Animation::Procedural(list) if motions.is_empty() && Motion::affine_all(&list, 0.0).is_some() => {
                    motions = list
                }
                _ => {
                    return Err(bad("copies can only move rigidly, all alike (animate: rotate, oscillate); \
                         a wave or a glTF animation would deform the mesh they share"
                        .into()))
                }
            }
        }
        if instances.is_empty() {
            return Err(bad("the list is empty: nothing would be placed".into()));
        }
        let copies = instances
            .iter()
            .enumerate()
            .map(|(k, t)| {
                Instance::new(Affine3A::from_mat4(t.matrix()))
                    .ok_or_else(|| bad(format!("transform {k} is not finite or cannot be inverted")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let instanced = InstancedMesh { mesh: merge_meshes(self.scene.meshes.drain(meshes..)), copies, motions };
        if !instanced.mesh.triangle_material.iter().any(|&m| self.scene.written_out_for(m)) {
            self.scene.instanced.push(instanced);
            return Ok(());
        }
        let (copies, triangles) = (instanced.copies.len(), instanced.mesh.triangles.len());
        if triangles.saturating_mul(copies) > MAX_COPIED_TRIANGLES {
            return Err(bad(format!(
                "{copies} copies of {triangles} emitting or alpha-masked triangles exceed {MAX_COPIED_TRIANGLES} \
                 (emitters and masks are copied, not instanced)"
            )));
        }
        self.scene.write_out(instanced);
        Ok(())
    }

    /// Adds a material of the file, with its texture if it names one (an image that cannot
    /// be read is an error naming it and the material).
    fn add_material(&mut self, name: &str, m: &MaterialFile) -> Result<u32, LoadError> {
        let image = match m {
            MaterialFile::Lambertian { texture: Some(file), .. } => {
                Some(crate::load::ImageSource::File(resolve_path(file, self.path)?))
            }
            _ => None,
        };
        self.scene.add_textured_material(name, m.into(), image)
    }

    /// [`SceneBuilder::material`] for an object without texture coordinates: a textured
    /// material is refused rather than drawn in one texel's colour.
    fn untextured_material(&self, object: usize, name: &str, what: &str) -> Result<u32, LoadError> {
        let index = self.material(object, name)?;
        if self.scene.material_texture[index as usize].is_some() {
            return Err(self.err(format!(
                "object {object}: material \"{name}\" has a texture, and {what} has no texture coordinates \
                 (mesh files have them: OBJ `vt`, PLY `u v`, glTF TEXCOORD_0)"
            )));
        }
        Ok(index)
    }

    fn no_texture_coordinates(&self, object: usize, material: &str, file: &str) -> LoadError {
        self.err(format!(
            "object {object}: material \"{material}\" has a texture, and {file} has no texture coordinates"
        ))
    }

    fn material(&self, object: usize, name: &str) -> Result<u32, LoadError> {
        self.scene.material_index(name).ok_or_else(|| {
            let known = self.scene.material_names.join(", ");
            self.err(format!("object {object}: unknown material \"{name}\" (known: {known})"))
        })
    }

    fn add_object(&mut self, i: usize, object: &ObjectFile) -> Result<(), LoadError> {
        match object {
            ObjectFile::Sphere { center, radius, material } => {
                let material = self.untextured_material(i, material, "a sphere")?;
                if !radius.is_finite() || *radius == 0.0 || !Vec3::from(*center).is_finite() {
                    return Err(self.err(format!("object {i}: sphere needs a finite centre and non-zero radius")));
                }
                self.scene
                    .spheres
                    .push(SphereObject { sphere: Sphere { center: (*center).into(), radius: *radius }, material });
            }
            ObjectFile::Quad { q, u, v, material, transform } => {
                let (q, u, v) = (Vec3::from(*q), Vec3::from(*u), Vec3::from(*v));
                let positions = vec![q, q + u, q + v, q + u + v];
                let triangles = vec![[0, 1, 2], [1, 3, 2]];
                self.add_inline(i, "quad", positions, triangles, material, transform)?;
            }
            ObjectFile::Triangle { v0, v1, v2, material, transform } => {
                let positions = vec![(*v0).into(), (*v1).into(), (*v2).into()];
                self.add_inline(i, "triangle", positions, vec![[0, 1, 2]], material, transform)?;
            }
            ObjectFile::Triangles { vertices, faces, material, transform } => {
                let positions = vertices.iter().map(|&v| v.into()).collect();
                self.add_inline(i, "triangles", positions, faces.clone(), material, transform)?;
            }
            ObjectFile::Mesh { file, material: name, transform, .. } => {
                let material = self.material(i, name)?;
                let mut data = self.load(file, transform)?;
                if self.scene.material_texture[material as usize].is_none() {
                    // One untextured material: no texture coordinates needed.
                    data.uvs.clear();
                    data.shared.iter_mut().for_each(|s| s.uvs.clear());
                } else if data.uvs.is_empty() && data.shared.iter().all(|s| s.uvs.is_empty()) {
                    return Err(self.no_texture_coordinates(i, name, file));
                }
                let group_material = vec![material; data.groups.len()];
                self.push_grouped(file, data, &group_material)?;
            }
            ObjectFile::ObjMtl { file, materials, material, transform, mtl_mapping } => {
                let fallback = material.as_deref().map(|m| self.material(i, m)).transpose()?;
                let mapping = match mtl_mapping {
                    MtlMappingFile::Reference => MtlMapping::Reference,
                    MtlMappingFile::Full => MtlMapping::Full,
                };
                for (name, m) in materials {
                    m.check().map_err(|e| self.err(format!("object {i}: material \"{name}\": {e}")))?;
                }
                let data = self.load(file, transform)?;
                let group_material = (0..data.groups.len())
                    .map(|g| {
                        let name = &data.groups[g];
                        if let Some(m) = materials.get(name) {
                            self.add_material(name, m)
                        } else if let Some(f) = fallback {
                            Ok(f)
                        } else {
                            self.scene.add_source_material(name, &data.group_materials[g], mapping)
                        }
                    })
                    .collect::<Result<Vec<u32>, LoadError>>()?;
                if data.uvs.is_empty() && data.shared.iter().all(|s| s.uvs.is_empty()) {
                    // The scene's own textured materials need the file's `vt`. (An MTL's
                    // `map_Kd` without them is left as the MTL mapping makes it.)
                    let scene_textured = |m: u32| {
                        self.scene.material_texture[m as usize].is_some()
                            && (Some(m) == fallback || materials.contains_key(&self.scene.material_names[m as usize]))
                    };
                    if let Some(&m) = group_material.iter().find(|&&m| scene_textured(m)) {
                        return Err(self.no_texture_coordinates(i, &self.scene.material_names[m as usize], file));
                    }
                }
                self.push_grouped(file, data, &group_material)?;
            }
            ObjectFile::Gltf { file, transform } => {
                let mut data = self.load(file, transform)?;
                if let Some(mut nodes) = data.animation.take() {
                    nodes.outer = transform.as_ref().map_or(Mat4::IDENTITY, TransformFile::matrix);
                    let target = AnimationTarget::Mesh(self.scene.meshes.len());
                    self.scene.animations.push(ObjectAnimation { target, animation: Animation::Nodes(nodes) });
                }
                let group_material = (0..data.groups.len())
                    .map(|g| {
                        self.scene.add_source_material(&data.groups[g], &data.group_materials[g], MtlMapping::Full)
                    })
                    .collect::<Result<Vec<u32>, LoadError>>()?;
                for c in &data.cameras {
                    let desc =
                        CameraDesc { position: c.position, look_at: c.look_at, up: c.up, vfov_degrees: c.vfov_degrees };
                    self.scene.views.push((c.name.clone(), desc));
                }
                self.push_grouped(file, data, &group_material)?;
            }
        }
        Ok(())
    }

    fn add_inline(
        &mut self,
        i: usize,
        kind: &str,
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        material: &str,
        transform: &Option<TransformFile>,
    ) -> Result<(), LoadError> {
        let material = self.untextured_material(i, material, &format!("a {kind}"))?;
        if let Some(bad) = triangles.iter().flatten().find(|&&k| k as usize >= positions.len()) {
            return Err(self.err(format!("object {i} ({kind}): vertex index {bad} out of range")));
        }
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(self.err(format!("object {i} ({kind}): coordinate is not finite")));
        }
        let m = transform.as_ref().map_or(Mat4::IDENTITY, TransformFile::matrix);
        let positions = positions.into_iter().map(|p| m.transform_point3(p)).collect();
        let n = triangles.len();
        self.push_mesh(kind, positions, triangles, vec![material; n]);
        Ok(())
    }

    fn load(&self, file: &str, transform: &Option<TransformFile>) -> Result<MeshData, LoadError> {
        let path = resolve_path(file, self.path)?;
        let mut data = load_mesh_keeping_shared(&path)?;
        if !self.keep_shared {
            data.flatten_shared(&path)?;
        }
        if let Some(t) = transform {
            let m = t.matrix();
            data.positions.iter_mut().for_each(|p| *p = m.transform_point3(*p));
            data.shared.iter_mut().flat_map(|s| &mut s.placements).for_each(|p| *p = m * *p);
        }
        Ok(data)
    }

    /// Adds `data`'s triangles as a mesh, and its shared meshes instanced
    /// ([`Scene::add_shared_meshes`]).
    fn push_grouped(&mut self, name: &str, mut data: MeshData, group_material: &[u32]) -> Result<(), LoadError> {
        self.scene.add_shared_meshes(self.path, name, &mut data, group_material)?;
        let materials = data.triangle_group.iter().map(|&g| group_material[g as usize]).collect();
        let uvs = data.uvs.iter().map(|t| t.map(Vec2::from)).collect();
        self.push_mesh(name, data.positions, data.triangles, materials);
        self.scene.meshes.last_mut().expect("pushed").uvs = uvs;
        Ok(())
    }

    fn push_mesh(&mut self, name: &str, positions: Vec<Vec3>, triangles: Vec<[u32; 3]>, triangle_material: Vec<u32>) {
        let name = name.to_string();
        self.scene.meshes.push(Mesh { name, positions, triangles, triangle_material, uvs: Vec::new() });
    }
}

/// The most triangles the copies of an emitting object may add (see
/// `SceneBuilder::instance`): 2²⁶, about 3 GiB of vertices and boxes.
const MAX_COPIED_TRIANGLES: usize = 1 << 26;

/// One mesh of `meshes`' triangles, materials and texture coordinates (zeros for meshes
/// without any, when another has them), named after the first.
fn merge_meshes(meshes: impl Iterator<Item = Mesh>) -> Mesh {
    let meshes: Vec<Mesh> = meshes.collect();
    let with_uvs = meshes.iter().any(|m| !m.uvs.is_empty());
    let mut merged = Mesh { name: meshes.first().map(|m| m.name.clone()).unwrap_or_default(), ..Mesh::default() };
    for m in meshes {
        let base = merged.positions.len() as u32;
        merged.triangles.extend(m.triangles.iter().map(|t| t.map(|v| v + base)));
        merged.positions.extend(m.positions);
        if with_uvs {
            match m.uvs.len() {
                0 => merged.uvs.extend(std::iter::repeat_n([Vec2::ZERO; 3], m.triangles.len())),
                _ => merged.uvs.extend(m.uvs),
            }
        }
        merged.triangle_material.extend(m.triangle_material);
    }
    merged
}

/// A camera from the file, refused if it cannot form an image: a field of view outside
/// (0°, 180°), a look-at point equal to the position, an up vector along the view direction.
fn camera_desc(c: &CameraFile) -> Result<CameraDesc, String> {
    let desc =
        CameraDesc { position: c.position.into(), look_at: c.look_at.into(), up: c.up.into(), vfov_degrees: c.vfov };
    if !(desc.vfov_degrees > 0.0 && desc.vfov_degrees < 180.0) {
        return Err(format!("vfov {} must lie strictly between 0 and 180 degrees", desc.vfov_degrees));
    }
    let forward = desc.look_at - desc.position;
    if !(forward.is_finite() && desc.up.is_finite()) {
        return Err("position, look_at and up must be finite".into());
    }
    if forward.length_squared() == 0.0 {
        return Err("look_at equals position: no view direction".into());
    }
    // Scaled before normalising, so that far-out cameras (refused later, by range) do not
    // overflow here.
    let unit = |v: Vec3| (v / v.abs().max_element()).normalize_or_zero();
    let cross = unit(forward).cross(unit(desc.up));
    if cross.length() < 1e-6 {
        return Err("up is zero or parallel to the view direction".into());
    }
    Ok(desc)
}

/// Resolves a `file` entry: `{scenes}/...` against [`scenes_dir`], relative paths against the
/// scene file's folder.
pub fn resolve_path(file: &str, scene_file: &Path) -> Result<PathBuf, LoadError> {
    if let Some(rest) = file.strip_prefix("{scenes}") {
        let dir = scenes_dir(scene_file).ok_or_else(|| {
            LoadError::new(scene_file, format!("cannot resolve {{scenes}} in \"{file}\": set PHR_SCENES_DIR"))
        })?;
        return Ok(dir.join(rest.trim_start_matches(['/', '\\'])));
    }
    let p = Path::new(file);
    Ok(if p.is_absolute() { p.to_path_buf() } else { scene_file.parent().unwrap_or(Path::new(".")).join(p) })
}

/// The shared scenes folder that `{scenes}` stands for: `$PHR_SCENES_DIR`, else
/// `$REFERENCE_SCENES_DIR`, else the `scenes/` next to a `reference/` folder above the scene
/// file (the layout of `shared/`), else a `shared/scenes` above the scene file, the current
/// directory or the running executable (the project's checkout sits next to `shared/`).
pub fn scenes_dir(scene_file: &Path) -> Option<PathBuf> {
    for var in ["PHR_SCENES_DIR", "REFERENCE_SCENES_DIR"] {
        if let Some(dir) = std::env::var_os(var) {
            return Some(PathBuf::from(dir));
        }
    }
    let absolute = std::path::absolute(scene_file).ok()?;
    let cwd = std::env::current_dir().ok();
    let exe = std::env::current_exe().ok();
    let starts = absolute.parent().into_iter().chain(cwd.as_deref()).chain(exe.as_deref());
    for start in starts {
        for dir in start.ancestors() {
            if dir.join("reference").is_dir() && dir.join("scenes").is_dir() {
                return Some(dir.join("scenes"));
            }
            if dir.join("shared/scenes").is_dir() {
                return Some(dir.join("shared/scenes"));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Scene, LoadError> {
        parse_scene(text, Path::new("/nonexistent/test.json"))
    }

    #[test]
    fn reference_style_scene() {
        let s = parse(
            r#"{"width": 64, "height": 32, "spp": 8, "max_depth": 5,
                "background": {"type": "gradient", "bottom": [1, 1, 1], "top": [0.5, 0.7, 1.0]},
                "camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "vfov": 40},
                "views": {"side": {"lookfrom": [3, 0, 0], "lookat": [0, 0, 0]}},
                "materials": {"w": {"type": "diffuse", "albedo": 0.5}, "l": {"type": "light", "emit": [4, 4, 4]}},
                "objects": [
                  {"type": "sphere", "center": [0, 0, 0], "radius": -1, "material": "w"},
                  {"type": "quad", "Q": [0, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "material": "l",
                   "transform": {"scale": 2, "rotate": [0, 1, 0, 90], "translate": [0, 0, 1]}}]}"#,
        )
        .unwrap();
        assert_eq!(s.settings, RenderSettings { width: 64, height: 32, spp: 8, max_depth: 5 });
        assert_eq!(s.view_names(), vec!["default", "side"]);
        assert_eq!(s.spheres.len(), 1);
        assert_eq!(s.triangle_count(), 2);
        assert_eq!(s.materials[0], Material::Lambertian { albedo: Vec3::splat(0.5) });
        // Scale 2, then 90° about y maps +x to -z, then translate z by 1.
        let p = s.meshes[0].positions[1];
        assert!((p - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-5, "{p}");
        let n = (s.meshes[0].positions[1] - s.meshes[0].positions[0])
            .cross(s.meshes[0].positions[2] - s.meshes[0].positions[0]);
        assert!(n.x > 0.0, "the quad's normal u × v turned from +z to +x: {n}");
    }

    #[test]
    fn errors_name_the_problem() {
        let e = parse(r#"{"objects": [{"type": "sphere", "center": [0,0,0], "radius": 1, "material": "nope"}]}"#)
            .unwrap_err();
        assert!(e.to_string().contains("unknown material \"nope\""), "{e}");
        let e = parse("{\n\"materials\": {\"a\": {\"type\": \"plastic\"}},\n\"objects\": []}").unwrap_err();
        assert_eq!(e.line, Some(2), "{e}");
        assert!(e.to_string().contains("plastic"), "{e}");
        let e = parse(r#"{"objects": []}"#).unwrap_err();
        assert!(e.to_string().contains("no objects"));
        let e = parse(r#"{"materials": {"w": {"type": "diffuse", "albedo": 0.5}}, "objects": [{"type": "triangles", "vertices": [[0,0,0]], "faces": [[0,1,2]], "material": "w"}]}"#).unwrap_err();
        assert!(e.to_string().contains("out of range"), "{e}");
        let e = parse(r#"{"materials": {"w": {"type": "diffuse", "albedo": 0.5}}, "objects": [{"type": "mesh", "file": "missing.ply", "material": "w"}]}"#).unwrap_err();
        assert!(e.to_string().contains("missing.ply"), "{e}");
    }

    /// An environment background names its file when it cannot be read, and takes only its
    /// own keys.
    #[test]
    fn environment_background_errors() {
        let scene = |background: &str| {
            format!(
                r#"{{"background": {background}, "materials": {{"w": {{"type": "diffuse", "albedo": 0.5}}}},
                    "objects": [{{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "w"}}]}}"#
            )
        };
        let e = parse(&scene(r#"{"type": "environment", "file": "sky.hdr"}"#)).unwrap_err().to_string();
        assert!(e.contains("/nonexistent/sky.hdr"), "{e}");
        let e = parse(&scene(r#"{"type": "environment", "file": "sky.hdr", "rotation": 3}"#)).unwrap_err().to_string();
        assert!(e.contains("background: unknown key \"rotation\""), "{e}");
        let e = parse(&scene(r#"{"type": "gradient", "bottom": 1, "top": 1, "file": "x"}"#)).unwrap_err().to_string();
        assert!(e.contains("unknown key \"file\""), "{e}");
    }
}
