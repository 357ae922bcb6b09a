//! Mesh file loaders: OBJ (+ MTL), PLY (ASCII and binary), glTF 2.0, and `.gz` of any of them.
//!
//! Every loader produces a [`MeshData`]: positions, triangles (polygons are fan-triangulated),
//! and for each triangle the index of its group (the OBJ `usemtl` name, the glTF material).
//! Mapping groups to the renderer's four materials is the scene's job (`scene` module), not
//! the loader's, so the same file can be rendered with its own materials or with overrides.

use glam::Vec3;
use std::collections::HashMap;

/// The raw material parameters of an MTL entry (only the keys we map; see `scene::mtl_to_material`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MtlEntry {
    pub kd: Option<[f32; 3]>,
    pub ks: Option<[f32; 3]>,
    pub ke: Option<[f32; 3]>,
    pub tf: Option<[f32; 3]>,
    pub ns: Option<f32>,
    pub ni: Option<f32>,
    /// Dissolve (`d`), or `1 - Tr`.
    pub d: Option<f32>,
    pub illum: Option<u32>,
    /// The diffuse colour texture (`map_Kd`), resolved against the MTL file's folder.
    pub map_kd: Option<std::path::PathBuf>,
    /// The alpha mask (`map_d`: the surface is where the image's value is at least one half),
    /// resolved against the MTL file's folder.
    pub map_d: Option<std::path::PathBuf>,
}

/// Where a texture's image is.
#[derive(Clone, Debug, PartialEq)]
pub enum ImageSource {
    /// A file: an MTL `map_Kd`, a glTF image URI (inside the asset's folder).
    File(std::path::PathBuf),
    /// Bytes inside the asset (a GLB buffer view, a `data:` URI), with a name that identifies
    /// them in messages and for sharing (`asset.glb#image 3`).
    Embedded { name: String, bytes: std::sync::Arc<Vec<u8>> },
}

impl ImageSource {
    /// The file, or the embedded image's name.
    pub fn name(&self) -> String {
        match self {
            ImageSource::File(path) => path.display().to_string(),
            ImageSource::Embedded { name, .. } => name.clone(),
        }
    }
}

/// A material as glTF describes it (metallic-roughness, emissive, transmission).
#[derive(Clone, Debug, PartialEq)]
pub struct GltfMaterial {
    pub base_color: [f32; 3],
    /// `baseColorTexture` (texture coordinate set 0), which the base colour multiplies.
    pub base_color_texture: Option<ImageSource>,
    pub metallic: f32,
    pub roughness: f32,
    /// Emissive factor times `KHR_materials_emissive_strength`.
    pub emissive: [f32; 3],
    /// `KHR_materials_transmission` factor (0 if absent).
    pub transmission: f32,
    /// `KHR_materials_ior` (1.5 if absent).
    pub ior: f32,
    /// `alphaMode` `MASK`: the surface is there where the base-colour texture's alpha reaches
    /// this value (the alpha cutoff over the base colour factor's alpha).
    pub alpha_threshold: Option<f32>,
}

/// What a group's material looks like in the source file.
#[derive(Clone, Debug, PartialEq)]
pub enum SourceMaterial {
    /// No material information (PLY, OBJ without MTL entry for this name).
    None,
    Mtl(MtlEntry),
    Gltf(GltfMaterial),
}

/// A named camera found in a file (glTF perspective cameras with their node transform).
#[derive(Clone, Debug, PartialEq)]
pub struct SourceCamera {
    pub name: String,
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Full vertical field of view in degrees.
    pub vfov_degrees: f32,
}

/// One triangle mesh as loaded from a file, world transforms already applied.
#[derive(Clone, Debug, Default)]
pub struct MeshData {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// For each triangle, an index into `groups`.
    pub triangle_group: Vec<u32>,
    /// Group names (OBJ `usemtl` name, glTF material name or `material_N`; `default` otherwise).
    pub groups: Vec<String>,
    /// For each group, what the file says about its material.
    pub group_materials: Vec<SourceMaterial>,
    /// Cameras the file defines (glTF only).
    pub cameras: Vec<SourceCamera>,
    /// Texture coordinates of each triangle's corners (OBJ `vt`), or empty when the file
    /// has none.
    pub uvs: Vec<[[f32; 2]; 3]>,
    /// Keyframed node animations (glTF only), posing ranges of `positions`.
    pub animation: Option<Box<crate::motion::NodeAnimation>>,
    /// Meshes that several glTF nodes place (files without animations): kept apart, once
    /// each, by [`load_mesh_keeping_shared`]; [`load_mesh`] writes them out into the arrays
    /// above ([`MeshData::flatten_shared`]).
    pub shared: Vec<SharedMesh>,
}

/// A mesh placed several times: its triangles once, in its own space (groups and texture
/// coordinates as in [`MeshData`], whose groups they index), and where each copy goes.
#[derive(Clone, Debug, Default)]
pub struct SharedMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub triangle_group: Vec<u32>,
    pub uvs: Vec<[[f32; 2]; 3]>,
    /// Mesh space to the file's space, one per copy.
    pub placements: Vec<glam::Mat4>,
}

impl MeshData {
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Writes every copy of `shared[i]` out into the main arrays, and removes it.
    pub fn flatten_shared_mesh(&mut self, path: &Path, i: usize) -> Result<(), LoadError> {
        let shared = self.shared.remove(i);
        for placement in &shared.placements {
            let base = self.positions.len() as u32;
            for &p in &shared.positions {
                let p = placement.transform_point3(p);
                check_finite(path, p, Location::Vertex(self.positions.len()))?;
                self.positions.push(p);
            }
            let first_triangle = self.triangles.len();
            self.triangles.extend(shared.triangles.iter().map(|t| t.map(|v| v + base)));
            self.triangle_group.extend_from_slice(&shared.triangle_group);
            if !(self.uvs.is_empty() && shared.uvs.is_empty()) {
                self.uvs.resize(first_triangle, [[0.0; 2]; 3]);
                match shared.uvs.len() {
                    0 => self.uvs.resize(self.triangles.len(), [[0.0; 2]; 3]),
                    _ => self.uvs.extend_from_slice(&shared.uvs),
                }
            }
        }
        Ok(())
    }

    /// Writes every shared mesh out ([`MeshData::flatten_shared_mesh`]).
    pub fn flatten_shared(&mut self, path: &Path) -> Result<(), LoadError> {
        while !self.shared.is_empty() {
            self.flatten_shared_mesh(path, 0)?;
        }
        Ok(())
    }
}

pub type MtlLibrary = HashMap<String, MtlEntry>;

mod gltf;
pub mod input;
mod obj;
mod ply;

use crate::error::LoadError;
use std::path::Path;

/// The file formats [`load_mesh`] understands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Obj,
    Ply,
    /// `.gltf` (JSON) and `.glb` (binary); the parser tells them apart by content.
    Gltf,
}

impl Format {
    fn from_extension(extension: &str) -> Option<Self> {
        match extension {
            "obj" => Some(Self::Obj),
            "ply" => Some(Self::Ply),
            "gltf" | "glb" => Some(Self::Gltf),
            _ => None,
        }
    }
}

/// Loads a triangle mesh, choosing the parser by extension (case-insensitive): `.obj` (with
/// its `mtllib` files), `.ply`, `.gltf`, `.glb`, or any of them gzipped (`.obj.gz`, ...).
///
/// Every error names the file, and the line for text formats.
pub fn load_mesh(path: &Path) -> Result<MeshData, LoadError> {
    let mut mesh = load_mesh_keeping_shared(path)?;
    mesh.flatten_shared(path)?;
    Ok(mesh)
}

/// [`load_mesh`], with the meshes several glTF nodes place kept apart, once each
/// ([`MeshData::shared`]): what a scene instances instead of copying.
pub fn load_mesh_keeping_shared(path: &Path) -> Result<MeshData, LoadError> {
    detect_format(path)?;
    parse_mesh_keeping_shared(path, &input::read_file(path, "the mesh file")?)
}

/// [`load_mesh`] on the file's content, already read: `path` names the format (by its
/// extension), the file in errors, and the folder its MTL and buffer files are looked up in.
/// What the loaders' fuzz tests call.
pub fn parse_mesh(path: &Path, bytes: &[u8]) -> Result<MeshData, LoadError> {
    let mut mesh = parse_mesh_keeping_shared(path, bytes)?;
    mesh.flatten_shared(path)?;
    Ok(mesh)
}

fn parse_mesh_keeping_shared(path: &Path, bytes: &[u8]) -> Result<MeshData, LoadError> {
    let (format, gzipped) = detect_format(path)?;
    let inflated;
    let bytes = if gzipped {
        inflated = input::gunzip(path, bytes)?;
        &inflated[..]
    } else {
        bytes
    };
    // Files an OBJ or glTF refers to (MTL, .bin buffers) are looked up next to the file.
    let base_dir = path.parent().unwrap_or_else(|| Path::new(""));
    match format {
        Format::Obj => obj::parse(path, base_dir, bytes),
        Format::Ply => ply::parse(path, bytes),
        Format::Gltf => gltf::parse(path, base_dir, bytes),
    }
}

/// The format of `path` by its extension, and whether it is gzipped (`X.gz`).
fn detect_format(path: &Path) -> Result<(Format, bool), LoadError> {
    let lower_extension = |p: &Path| p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let unknown = || LoadError::new(path, "unknown mesh format (expected .obj, .ply, .gltf, .glb, or one of them .gz)");
    let extension = lower_extension(path).ok_or_else(unknown)?;
    if extension != "gz" {
        return Format::from_extension(&extension).map(|f| (f, false)).ok_or_else(unknown);
    }
    let inner = path.file_stem().map(Path::new).and_then(lower_extension).ok_or_else(unknown)?;
    Format::from_extension(&inner).map(|f| (f, true)).ok_or_else(unknown)
}

/// Where a value came from in its file, for error messages.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Location {
    /// 1-based line of a text file.
    Line(usize),
    /// 0-based vertex index (binary formats).
    Vertex(usize),
}

impl Location {
    pub(crate) fn error(self, path: &Path, message: impl Into<String>) -> LoadError {
        match self {
            Self::Line(line) => LoadError::at_line(path, line, message),
            Self::Vertex(i) => LoadError::new(path, format!("vertex {i}: {}", message.into())),
        }
    }
}

/// Fails unless every coordinate of `p` is finite.
pub(crate) fn check_finite(path: &Path, p: Vec3, at: Location) -> Result<(), LoadError> {
    if p.is_finite() {
        Ok(())
    } else {
        Err(at.error(path, format!("coordinate is not finite ({}, {}, {})", p.x, p.y, p.z)))
    }
}

/// Final checks shared by all loaders: at least one triangle, every index in range, every
/// position finite, one group per triangle. Parsers report problems with line numbers as they
/// go; this catches whatever they could not (and guards the invariants the renderer relies on).
pub(crate) fn finish(path: &Path, mesh: MeshData) -> Result<MeshData, LoadError> {
    if mesh.triangles.is_empty() && mesh.shared.is_empty() {
        return Err(LoadError::new(path, "no triangles"));
    }
    for shared in &mesh.shared {
        let n = shared.positions.len();
        let ok = shared.triangles.iter().flatten().all(|&v| (v as usize) < n)
            && shared.triangle_group.len() == shared.triangles.len()
            && (shared.uvs.is_empty() || shared.uvs.len() == shared.triangles.len())
            && shared.triangle_group.iter().all(|&g| (g as usize) < mesh.groups.len());
        if !ok {
            return Err(LoadError::new(path, "internal error: inconsistent shared mesh"));
        }
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return check_finite(path, mesh.positions[i], Location::Vertex(i)).map(|_| mesh);
    }
    let n = mesh.positions.len();
    if let Some((t, tri)) = mesh.triangles.iter().enumerate().find(|(_, tri)| tri.iter().any(|&v| v as usize >= n)) {
        let message = format!("triangle {t}: vertex index out of range {tri:?} ({n} vertices)");
        return Err(LoadError::new(path, message));
    }
    let groups_ok = mesh.triangle_group.len() == mesh.triangles.len()
        && (mesh.uvs.is_empty() || mesh.uvs.len() == mesh.triangles.len())
        && mesh.group_materials.len() == mesh.groups.len()
        && mesh.triangle_group.iter().all(|&g| (g as usize) < mesh.groups.len());
    if !groups_ok {
        return Err(LoadError::new(path, "internal error: inconsistent triangle groups"));
    }
    Ok(mesh)
}

/// `count` items announced by a header, capped by what `available` bytes can hold at
/// `min_bytes` each, so a lying header cannot make us preallocate gigabytes.
pub(crate) fn capped_capacity(count: usize, available: usize, min_bytes: usize) -> usize {
    count.min(available / min_bytes.max(1))
}
