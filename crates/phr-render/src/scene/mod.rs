//! The scene model: what gets rendered, independent of the file it came from.
//!
//! A scene is triangle meshes and spheres, each triangle and sphere with one of the scene's
//! materials, a background (the sky), named camera views, and the render settings its file
//! asks for. Loaders (`crate::load`) and the scene file (`json`) fill it in; the built-in
//! default scene (`builtin`) makes one in code.

pub mod builtin;
pub mod json;
pub mod materials;

use crate::camera::CameraDesc;
use crate::material::Material;
use crate::motion::{Animation, AnimationTarget, Motion, ObjectAnimation};
use crate::texture::{AlphaMask, Texture};
use glam::{Vec2, Vec3};
use phr_bvh::instance::Instance;
use phr_bvh::sphere::Sphere;

/// Radiance of rays that leave the scene.
#[derive(Clone, Debug)]
pub enum Background {
    Constant(Vec3),
    /// RTIOW's sky: `(1 - a)·bottom + a·top` with `a = 0.5 (d.y + 1)` for the unit direction `d`.
    Gradient {
        bottom: Vec3,
        top: Vec3,
    },
    /// An HDR image all around ([`crate::environment`]).
    Environment(std::sync::Arc<crate::environment::EnvironmentMap>),
}

impl Background {
    #[inline]
    pub fn radiance(&self, unit_dir: Vec3) -> Vec3 {
        match self {
            Background::Constant(c) => *c,
            Background::Gradient { bottom, top } => {
                let a = 0.5 * (unit_dir.y + 1.0);
                (1.0 - a) * *bottom + a * *top
            }
            Background::Environment(map) => map.radiance(unit_dir),
        }
    }

    /// The brightest channel anywhere in the sky (0: black, it lights nothing).
    pub fn max_radiance(&self) -> f32 {
        match self {
            Background::Constant(c) => c.max_element(),
            Background::Gradient { bottom, top } => bottom.max_element().max(top.max_element()),
            Background::Environment(map) => map.max_radiance(),
        }
    }
}

/// A triangle mesh with one material index per triangle.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub triangle_material: Vec<u32>,
    /// Texture coordinates of each triangle's corners, or empty (no texture coordinates).
    pub uvs: Vec<[Vec2; 3]>,
}

impl Mesh {
    /// Its vertices' bounds.
    pub fn bounds(&self) -> phr_bvh::Aabb {
        self.positions.iter().fold(phr_bvh::Aabb::EMPTY, |b, &p| b.grown(p))
    }
}

/// A mesh placed many times (a scene file's `instances`): its triangles once, in its object
/// space, and one placement per copy. The renderer builds one tree for it and traces every copy
/// through that tree (`crate::geometry`), so a thousand copies cost about one copy's memory.
#[derive(Clone, Debug)]
pub struct InstancedMesh {
    pub mesh: Mesh,
    /// Object space to world space, one per copy; each is invertible and finite.
    pub copies: Vec<Instance>,
    /// Rigid motions (rotations, oscillations; empty: the copies stand still) that every copy
    /// makes in the world after its placement, turning about its own place of the pivot
    /// ([`Motion::placed_by`]).
    pub motions: Vec<Motion>,
}

impl InstancedMesh {
    /// Each copy as a mesh of its own, in the world (named `NAME #k`).
    pub fn written_out(&self) -> impl Iterator<Item = Mesh> + '_ {
        self.copies.iter().enumerate().map(|(k, copy)| Mesh {
            name: format!("{} #{k}", self.mesh.name),
            positions: self.mesh.positions.iter().map(|&p| copy.world_point(p)).collect(),
            ..self.mesh.clone()
        })
    }

    /// World bounds of all its copies.
    pub fn bounds(&self) -> phr_bvh::Aabb {
        let object = self.mesh.bounds();
        self.copies.iter().fold(phr_bvh::Aabb::EMPTY, |b, c| b.union(c.world_box(object)))
    }
}

/// A sphere and its material.
#[derive(Clone, Debug)]
pub struct SphereObject {
    pub sphere: Sphere,
    pub material: u32,
}

/// Render settings a scene file may carry; the command line overrides them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Maximum number of ray segments per path, camera ray included (RTIOW's `max_depth`).
    pub max_depth: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self { width: 512, height: 512, spp: 64, max_depth: 8 }
    }
}

impl RenderSettings {
    /// The largest image side, and the most pixels: the film keeps two f64 triples a pixel
    /// (48 bytes), so 2²⁶ pixels (8192², or 16384 × 4096) take 3 GiB, which is where a render
    /// stops being a mistake worth a warning and starts exhausting memory.
    pub const MAX_SIDE: u32 = 16384;
    pub const MAX_PIXELS: u64 = 1 << 26;
    /// The most ray segments a path may have: far beyond any useful estimate, but finite, so
    /// that a camera inside a mirror cannot loop for ever.
    pub const MAX_DEPTH: u32 = 1024;

    /// Says what is wrong with these settings, if anything: every size, sample count and depth
    /// is at least 1 and within the limits above.
    pub fn check(&self) -> Result<(), String> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return Err(format!("image size {w}x{h} is empty"));
        }
        if w > Self::MAX_SIDE || h > Self::MAX_SIDE || u64::from(w) * u64::from(h) > Self::MAX_PIXELS {
            return Err(format!(
                "image size {w}x{h} is too large (at most {} pixels a side and {} pixels in all)",
                Self::MAX_SIDE,
                Self::MAX_PIXELS
            ));
        }
        if self.spp == 0 {
            return Err("spp must be at least 1".into());
        }
        if !(1..=Self::MAX_DEPTH).contains(&self.max_depth) {
            return Err(format!("max_depth {} is outside 1..={}", self.max_depth, Self::MAX_DEPTH));
        }
        Ok(())
    }
}

#[derive(Clone, Debug)]
pub struct Scene {
    pub materials: Vec<Material>,
    pub material_names: Vec<String>,
    pub meshes: Vec<Mesh>,
    /// Meshes placed many times, apart from `meshes` (which are each placed once).
    pub instanced: Vec<InstancedMesh>,
    pub spheres: Vec<SphereObject>,
    pub background: Background,
    /// Named views; the first is the default.
    pub views: Vec<(String, CameraDesc)>,
    pub settings: RenderSettings,
    /// What moves (empty for a static scene); see [`crate::motion`].
    pub animations: Vec<ObjectAnimation>,
    /// Colour textures, each loaded once however many materials use it.
    pub textures: Vec<Texture>,
    /// The image each texture came from ([`crate::load::ImageSource::name`], to share them).
    pub texture_files: Vec<String>,
    /// For each material, its colour texture: a Lambertian surface's albedo is its `albedo`
    /// times the texture's colour at the hit's texture coordinates.
    pub material_texture: Vec<Option<u32>>,
    /// Alpha masks (MTL `map_d`, glTF `alphaMode` `MASK`), each loaded once however many
    /// materials use it.
    pub masks: Vec<AlphaMask>,
    /// The image each mask came from, with its threshold.
    pub mask_files: Vec<String>,
    /// For each material, its alpha mask: rays pass through its surfaces where the mask does
    /// not cover them ([`crate::geometry::Geometry`] tests it).
    pub material_mask: Vec<Option<u32>>,
}

impl Default for Scene {
    fn default() -> Self {
        Self {
            materials: Vec::new(),
            material_names: Vec::new(),
            meshes: Vec::new(),
            instanced: Vec::new(),
            spheres: Vec::new(),
            background: Background::Constant(Vec3::ZERO),
            views: Vec::new(),
            settings: RenderSettings::default(),
            animations: Vec::new(),
            textures: Vec::new(),
            texture_files: Vec::new(),
            material_texture: Vec::new(),
            masks: Vec::new(),
            mask_files: Vec::new(),
            material_mask: Vec::new(),
        }
    }
}

impl Scene {
    /// Adds a material and returns its index.
    pub fn add_material(&mut self, name: impl Into<String>, m: Material) -> u32 {
        self.materials.push(m);
        self.material_names.push(name.into());
        self.material_texture.push(None);
        self.material_mask.push(None);
        (self.materials.len() - 1) as u32
    }

    /// Whether the copies of a mesh placed many times cannot keep `material` and must be
    /// written out triangle by triangle: emitters (light sampling picks each one) and alpha
    /// masks (the copies' leaf test does not look at them).
    pub fn written_out_for(&self, material: u32) -> bool {
        self.materials[material as usize].is_emissive() || self.material_mask[material as usize].is_some()
    }

    /// Adds the material a mesh file describes, mapped by `mapping`, with its colour texture
    /// when it maps to a Lambertian surface: an MTL `map_Kd` replaces `Kd` (as Blender's and
    /// most OBJ importers do), a glTF `baseColorTexture` is multiplied by the base colour (as
    /// the specification says). With its alpha mask, whatever it maps to: an MTL `map_d`, or
    /// a glTF `alphaMode` `MASK` on the base-colour texture's alpha. Each image is read once
    /// per scene. A texture that cannot be read is an error naming the material and the image.
    pub fn add_source_material(
        &mut self,
        name: &str,
        source: &crate::load::SourceMaterial,
        mapping: materials::MtlMapping,
    ) -> Result<u32, crate::error::LoadError> {
        use crate::load::{ImageSource, SourceMaterial};
        let mut material = materials::map_source_material(source, mapping);
        let image = match (source, &mut material) {
            (SourceMaterial::Mtl(m), Material::Lambertian { albedo }) => m.map_kd.as_ref().map(|file| {
                *albedo = Vec3::ONE;
                ImageSource::File(file.clone())
            }),
            (SourceMaterial::Gltf(g), Material::Lambertian { .. }) => g.base_color_texture.clone(),
            _ => None,
        };
        let index = self.add_textured_material(name, material, image)?;
        // MTL `map_d` (cut at one half), or glTF `alphaMode` `MASK` on the base colour's alpha.
        let mask = match source {
            SourceMaterial::Mtl(m) => m.map_d.as_ref().map(|file| (Some(ImageSource::File(file.clone())), 0.5)),
            SourceMaterial::Gltf(g) => g.alpha_threshold.map(|threshold| (g.base_color_texture.clone(), threshold)),
            SourceMaterial::None => None,
        };
        if let Some((image, threshold)) = mask {
            self.material_mask[index as usize] = self.alpha_mask(name, image, threshold)?;
        }
        Ok(index)
    }

    /// The mask of material `name` (loaded once per image and threshold): `image`'s coverage
    /// cut at `threshold`; without an image, a coverage of one everywhere, so that the whole
    /// surface is there (no mask: `None`) or, for a threshold above one, gone.
    fn alpha_mask(
        &mut self,
        name: &str,
        image: Option<crate::load::ImageSource>,
        threshold: f32,
    ) -> Result<Option<u32>, crate::error::LoadError> {
        let (masks, files) = (&mut self.masks, &mut self.mask_files);
        match image {
            Some(image) => {
                let key = format!("{} (cut at {threshold})", image.name());
                let load = || Ok(AlphaMask::load(&image)?.with_threshold(threshold));
                let mask = intern(files, masks, key, load)
                    .map_err(|e| named(&image, &format!("alpha mask of material \"{name}\""), e))?;
                Ok(Some(mask))
            }
            None if threshold > 1.0 => {
                let gone = AlphaMask::new(1, 1, vec![255]).with_threshold(threshold);
                intern(files, masks, format!("{name}: no coverage reaches {threshold}"), || Ok(gone)).map(Some)
            }
            None => Ok(None),
        }
    }

    /// Adds a material with its colour texture, if it has one: `image` is read once per scene
    /// ([`Scene::texture`]); one that cannot be read is an error naming it and the material.
    pub fn add_textured_material(
        &mut self,
        name: &str,
        material: Material,
        image: Option<crate::load::ImageSource>,
    ) -> Result<u32, crate::error::LoadError> {
        let texture = image
            .map(|image| self.texture(&image).map_err(|e| named(&image, &format!("texture of material \"{name}\""), e)))
            .transpose()?;
        let index = self.add_material(name, material);
        self.material_texture[index as usize] = texture;
        Ok(index)
    }

    /// The texture of `image` (read once: later calls share it).
    pub fn texture(&mut self, image: &crate::load::ImageSource) -> Result<u32, crate::error::LoadError> {
        intern(&mut self.texture_files, &mut self.textures, image.name(), || Texture::load(image))
    }

    /// Writes every copy of [`Scene::instanced`] out as a mesh of its own, in the world: for
    /// what needs each triangle where it is (moving every vertex, exporting triangles).
    pub fn flatten_instanced(&mut self) {
        for copied in std::mem::take(&mut self.instanced) {
            self.write_out(copied);
        }
    }

    /// Adds every copy of `copied` as a mesh of its own, in the world, each with the
    /// copies' motions as its animation.
    pub fn write_out(&mut self, copied: InstancedMesh) {
        for (mesh, copy) in copied.written_out().zip(&copied.copies) {
            if !copied.motions.is_empty() {
                let animation = Animation::Procedural(Motion::placed_by(&copied.motions, copy.to_world));
                self.animations.push(ObjectAnimation { target: AnimationTarget::Mesh(self.meshes.len()), animation });
            }
            self.meshes.push(mesh);
        }
    }

    /// Places the meshes `data` keeps apart because several glTF nodes place them
    /// ([`crate::load::MeshData::shared`]) as [`InstancedMesh`]es, their groups given
    /// materials by `group_material`. Those that emit light or have an alpha mask are written out
    /// into `data` instead ([`Scene::written_out_for`]). Placements that
    /// cannot be inverted (a node scaled to zero, which hides the mesh) are left out.
    pub fn add_shared_meshes(
        &mut self,
        path: &std::path::Path,
        name: &str,
        data: &mut crate::load::MeshData,
        group_material: &[u32],
    ) -> Result<(), crate::error::LoadError> {
        let mut i = 0;
        while i < data.shared.len() {
            let written_out =
                data.shared[i].triangle_group.iter().any(|&g| self.written_out_for(group_material[g as usize]));
            if written_out {
                data.flatten_shared_mesh(path, i)?;
            } else {
                i += 1;
            }
        }
        for shared in std::mem::take(&mut data.shared) {
            let copies: Vec<Instance> =
                shared.placements.iter().filter_map(|&m| Instance::new(glam::Affine3A::from_mat4(m))).collect();
            if copies.is_empty() {
                continue;
            }
            let mesh = Mesh {
                name: format!("{name} (shared mesh)"),
                positions: shared.positions,
                triangles: shared.triangles,
                triangle_material: shared.triangle_group.iter().map(|&g| group_material[g as usize]).collect(),
                uvs: shared.uvs.iter().map(|t| t.map(Vec2::from)).collect(),
            };
            self.instanced.push(InstancedMesh { mesh, copies, motions: Vec::new() });
        }
        Ok(())
    }

    pub fn material_index(&self, name: &str) -> Option<u32> {
        self.material_names.iter().position(|n| n == name).map(|i| i as u32)
    }

    /// Triangles of the meshes placed once (the renderer's primitive array).
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.triangles.len()).sum()
    }

    /// Triangles the copies of [`Scene::instanced`] place in the world (each counted once per
    /// copy), and the triangles they store.
    pub fn instanced_triangle_count(&self) -> (u64, usize) {
        let placed = self.instanced.iter().map(|i| i.mesh.triangles.len() as u64 * i.copies.len() as u64).sum();
        (placed, self.instanced.iter().map(|i| i.mesh.triangles.len()).sum())
    }

    /// The view called `name`, or the first one (a default camera if the scene has none).
    pub fn view(&self, name: Option<&str>) -> Option<CameraDesc> {
        match name {
            Some(n) => self.views.iter().find(|(v, _)| v == n).map(|(_, c)| c.clone()),
            None => Some(self.views.first().map(|(_, c)| c.clone()).unwrap_or_else(|| self.framing_camera())),
        }
    }

    pub fn view_names(&self) -> Vec<&str> {
        self.views.iter().map(|(n, _)| n.as_str()).collect()
    }

    /// World bounds of all geometry.
    pub fn bounds(&self) -> phr_bvh::Aabb {
        let mut b = phr_bvh::Aabb::EMPTY;
        for m in &self.meshes {
            b = b.union(m.bounds());
        }
        for i in &self.instanced {
            b = b.union(i.bounds());
        }
        for s in &self.spheres {
            b = b.union(s.sphere.bounds());
        }
        b
    }

    /// A camera that frames the whole scene from the front-right, slightly above: what a user
    /// wants when they open a bare mesh file.
    pub fn framing_camera(&self) -> CameraDesc {
        let b = self.bounds();
        if b.is_empty() {
            return CameraDesc::default();
        }
        let centre = b.center();
        // |extent| without squaring coordinates, which overflows f32 beyond about 1e19.
        let extent = b.extent();
        let scale = extent.max_element().max(1e-6);
        let radius = 0.5 * scale * (extent / scale).length();
        let vfov: f32 = 40.0;
        let distance = radius / (vfov.to_radians() * 0.5).sin() * 1.05;
        let dir = Vec3::new(0.35, 0.3, 1.0).normalize();
        CameraDesc { position: centre + dir * distance, look_at: centre, up: Vec3::Y, vfov_degrees: vfov }
    }
}

/// The largest coordinate magnitude a scene may have, for geometry and cameras alike.
///
/// The renderer works in f32: hit distances, squared lengths (sphere tests, normalising a
/// direction) and the offsets of secondary rays must stay finite. With coordinates up to
/// 1e18, squared distances stay below 1e37, short of f32's 3.4e38; beyond it, rays turn
/// into infinities and NaNs, and a scene that far out is a units mistake anyway.
pub const MAX_COORDINATE: f32 = 1.0e18;

impl Scene {
    /// Fails, naming `path`, if any geometry or view lies outside [`MAX_COORDINATE`] (or is
    /// not finite): what every scene passes before it reaches the renderer.
    pub fn check_range(&self, path: &std::path::Path) -> Result<(), crate::error::LoadError> {
        let within = |p: Vec3| p.abs().max_element() <= MAX_COORDINATE;
        let show = |p: Vec3| format!("({:.3e}, {:.3e}, {:.3e})", p.x, p.y, p.z);
        // Bounds skip NaN coordinates (min and max ignore them), so look at every vertex.
        for mesh in self.meshes.iter().chain(self.instanced.iter().map(|i| &i.mesh)) {
            if let Some(p) = mesh.positions.iter().find(|p| !p.is_finite()) {
                let message = format!("mesh {}: a vertex is not finite {} after its transform", mesh.name, show(*p));
                return Err(crate::error::LoadError::new(path, message));
            }
        }
        let b = self.bounds();
        if !(b.is_empty() || within(b.min) && within(b.max)) {
            let message = format!(
                "the geometry spans {} to {}: coordinates beyond ±{MAX_COORDINATE:e} (or not finite) cannot be rendered in 32-bit floats; scale the scene down",
                show(b.min),
                show(b.max)
            );
            return Err(crate::error::LoadError::new(path, message));
        }
        for (name, v) in &self.views {
            if !(within(v.position) && within(v.look_at) && v.up.is_finite()) {
                let message = format!(
                    "view '{name}': camera position {} / look_at {} / up {} beyond ±{MAX_COORDINATE:e} or not finite",
                    show(v.position),
                    show(v.look_at),
                    show(v.up)
                );
                return Err(crate::error::LoadError::new(path, message));
            }
        }
        Ok(())
    }
}

/// The index of the item called `name` in `items`, made by `load` at its first use (`files`
/// names the items made so far).
fn intern<T>(
    files: &mut Vec<String>,
    items: &mut Vec<T>,
    name: String,
    load: impl FnOnce() -> Result<T, crate::error::LoadError>,
) -> Result<u32, crate::error::LoadError> {
    if let Some(i) = files.iter().position(|f| *f == name) {
        return Ok(i as u32);
    }
    items.push(load()?);
    files.push(name);
    Ok((items.len() - 1) as u32)
}

/// A load error of `image`, said to be the `role` it plays (`texture of material "m"`).
fn named(image: &crate::load::ImageSource, role: &str, e: crate::error::LoadError) -> crate::error::LoadError {
    crate::error::LoadError::new(image.name(), format!("{role}: {}", e.message))
}

/// Opens what the user named: a scene file (`.json`) or a mesh file (`.obj`, `.ply`,
/// `.gltf`, `.glb`, optionally `.gz`), which becomes a scene with the file's own materials
/// (full MTL mapping), the RTIOW gradient sky and a camera framing the mesh. Either way the
/// scene passes [`Scene::check_range`].
pub fn load_scene(path: &std::path::Path) -> Result<Scene, crate::error::LoadError> {
    let name = path.to_string_lossy().to_ascii_lowercase();
    if name.ends_with(".json") {
        return json::load_scene_file(path);
    }
    let mut data = crate::load::load_mesh_keeping_shared(path)?;
    let mut scene = Scene {
        background: Background::Gradient { bottom: Vec3::ONE, top: Vec3::new(0.5, 0.7, 1.0) },
        ..Scene::default()
    };
    let group_material = data
        .groups
        .iter()
        .zip(&data.group_materials)
        .map(|(name, m)| scene.add_source_material(name, m, materials::MtlMapping::Full))
        .collect::<Result<Vec<u32>, _>>()?;
    for c in &data.cameras {
        scene.views.push((c.name.clone(), c.into()));
    }
    let file_name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    scene.add_shared_meshes(path, &file_name, &mut data, &group_material)?;
    let triangle_material = data.triangle_group.iter().map(|&g| group_material[g as usize]).collect();
    scene.meshes.push(Mesh {
        name: file_name,
        positions: data.positions,
        triangles: data.triangles,
        triangle_material,
        uvs: data.uvs.iter().map(|t| t.map(Vec2::from)).collect(),
    });
    let auto = scene.framing_camera();
    scene.views.insert(0, ("auto".into(), auto));
    scene.check_range(path)?;
    Ok(scene)
}
