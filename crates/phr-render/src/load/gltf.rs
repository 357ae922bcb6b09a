//! glTF 2.0 reader (`.gltf` with embedded or external buffers, and `.glb`), via the `gltf` crate.
//!
//! Walks the node hierarchy of the default scene (or the first scene), applies each node's
//! world transform to the positions of its mesh's `TRIANGLES` primitives, and groups triangles
//! by material (one group per glTF material, named after it or `material_N`; primitives without
//! a material go to `default`). Perspective cameras are returned with their world placement.
//!
//! Animations: keyframed node translation, rotation and scale (step, linear, cubic spline)
//! are read into a [`NodeAnimation`] that poses the vertices of the nodes they move; all of
//! a file's animations play together.
//!
//! Textures: `TEXCOORD_0` and each material's `baseColorTexture` (an image file inside the
//! asset's folder, a GLB buffer view or a `data:` URI; under `alphaMode` `MASK` its alpha
//! channel is an alpha mask too), with its `KHR_texture_transform`
//! (offset, rotation, scale) applied to the coordinates of the primitives that use it; glTF's
//! `v` runs down the image, so it is stored as `1 − v` ([`MeshData::uvs`] follows OBJ: `v = 0`
//! is the image's bottom).
//!
//! Limits: other primitive modes (points, lines, strips, fans) and orthographic cameras are
//! skipped; sparse accessors, morph targets and skins are not supported; samplers' wrap modes
//! other than repeat, and other texture coordinate sets are ignored.

use super::{
    check_finite, finish, GltfMaterial, ImageSource, Location, MeshData, SharedMesh, SourceCamera, SourceMaterial,
};
use crate::error::LoadError;
use crate::motion::{AnimatedNode, AnimatedPart, Interpolation, NodeAnimation, Track};
use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::animation::util::ReadOutputs;
use ::gltf::animation::Property;
use ::gltf::camera::Projection;
use ::gltf::mesh::Mode;
use ::gltf::{Accessor, Document, Node, Primitive};
use glam::{Mat4, Quat, Vec3};
use std::collections::HashMap;
use std::path::Path;

/// Deeper node hierarchies are taken for cycles (which glTF forbids).
const MAX_DEPTH: usize = 256;
/// The most vertices a file's node hierarchy may instance. Nodes may share children, so a
/// small file can instance its meshes exponentially often (40 levels of two children sharing
/// one node: 2⁴⁰ instances); 2²⁷ vertices (1.5 GiB of positions) is far above any real asset.
const MAX_INSTANCED_VERTICES: u64 = 1 << 27;

/// The vertices `node` and its descendants instance (triangle primitives' POSITION counts,
/// once per path through the hierarchy), memoised per node so that shared children cost
/// nothing; saturating. `None` past [`MAX_DEPTH`] (a cycle).
fn instanced_vertices(node: &Node, memo: &mut HashMap<usize, u64>, depth: usize) -> Option<u64> {
    if depth > MAX_DEPTH {
        return None;
    }
    if let Some(&n) = memo.get(&node.index()) {
        return Some(n);
    }
    let own = node.mesh().map_or(0, |m| {
        (m.primitives().filter(|p| p.mode() == Mode::Triangles))
            .filter_map(|p| p.get(&::gltf::Semantic::Positions))
            .fold(0u64, |sum, a| sum.saturating_add(a.count() as u64))
    });
    let total =
        node.children().try_fold(own, |sum, c| Some(sum.saturating_add(instanced_vertices(&c, memo, depth + 1)?)))?;
    memo.insert(node.index(), total);
    Some(total)
}

/// Parses a glTF or GLB file held in memory; external buffers are read from `base_dir`.
pub(super) fn parse(path: &Path, base_dir: &Path, bytes: &[u8]) -> Result<MeshData, LoadError> {
    let invalid = |message: String| LoadError::new(path, format!("invalid glTF: {message}"));
    let (document, blob) = read_document(bytes).map_err(invalid)?;
    let buffers = load_buffers(path, base_dir, &document, blob)?;
    let buffers: Vec<&[u8]> = buffers.iter().map(|data| &data[..]).collect();
    let scene = (document.default_scene().or_else(|| document.scenes().next()))
        .ok_or_else(|| LoadError::new(path, "glTF file has no scene"))?;
    let mut memo = HashMap::new();
    let instanced =
        scene.nodes().try_fold(0u64, |sum, n| Some(sum.saturating_add(instanced_vertices(&n, &mut memo, 0)?)));
    match instanced {
        None => return Err(LoadError::new(path, "node hierarchy too deep (or cyclic)")),
        Some(n) if n > MAX_INSTANCED_VERTICES => {
            let message = format!(
                "the node hierarchy instances {n} vertices, more than {MAX_INSTANCED_VERTICES} (nodes sharing children multiply)"
            );
            return Err(LoadError::new(path, message));
        }
        Some(_) => {}
    }
    let animated = document.animations().next().is_some();
    let mut builder = Builder {
        path,
        base_dir,
        buffers: &buffers,
        mesh: MeshData::default(),
        groups: HashMap::new(),
        parts: animated.then(Vec::new),
        placements: Vec::new(),
    };
    for node in scene.nodes() {
        builder.node(&node, Mat4::IDENTITY, 0)?;
    }
    builder.place_meshes(&document)?;
    if let Some(parts) = builder.parts.take() {
        builder.mesh.animation = builder.animation(&document, parts)?.map(Box::new);
    }
    finish(path, builder.mesh)
}

/// The document's buffers: the GLB's binary chunk, `data:` URIs, and files relative to the
/// asset's folder. Files are read through [`super::input::read_file`] (regular files only,
/// bounded), and may not leave the asset's folder (no absolute paths, no `..`), so a
/// downloaded asset cannot make us read elsewhere; every error names the buffer and its URI.
/// (The `gltf` crate's own `import_buffers` names neither, panics on percent-escapes that are
/// not UTF-8, and follows any path.)
fn load_buffers(
    path: &Path,
    base_dir: &Path,
    document: &Document,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<Vec<u8>>, LoadError> {
    use ::gltf::buffer::Source;
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let i = buffer.index();
        let fail = |message: String| LoadError::new(path, format!("buffer {i}: {message}"));
        let mut data = match buffer.source() {
            Source::Bin => blob.take().ok_or_else(|| fail("the GLB has no binary chunk".into()))?,
            Source::Uri(uri) if uri.starts_with("data:") => {
                ::gltf::buffer::Data::from_source(Source::Uri(uri), None)
                    .map_err(|e| fail(format!("invalid data URI: {e}")))?
                    .0
            }
            Source::Uri(uri) => {
                let relative = confined_path(uri).map_err(|e| fail(format!("`{uri}` {e}")))?;
                let file = base_dir.join(relative);
                super::input::read_file(&file, &format!("buffer {i} of {}", path.display()))?
            }
        };
        if data.len() < buffer.length() {
            return Err(fail(format!("holds {} bytes, its byteLength says {}", data.len(), buffer.length())));
        }
        data.resize(data.len().next_multiple_of(4), 0);
        buffers.push(data);
    }
    Ok(buffers)
}

/// A relative URI as a path inside the asset's folder: percent-escapes decoded, and refused if
/// it has a scheme, is absolute, or climbs out with `..`.
fn confined_path(uri: &str) -> Result<std::path::PathBuf, &'static str> {
    if uri.contains(':') {
        return Err("has a URI scheme other than data: (only relative file names are read)");
    }
    let mut bytes = Vec::with_capacity(uri.len());
    let mut rest = uri.as_bytes();
    while let Some((&b, tail)) = rest.split_first() {
        if b == b'%' {
            let hex = tail.get(..2).and_then(|h| std::str::from_utf8(h).ok());
            let value = hex.and_then(|h| u8::from_str_radix(h, 16).ok()).ok_or("has a bad percent-escape")?;
            bytes.push(value);
            rest = &tail[2..];
        } else {
            bytes.push(b);
            rest = tail;
        }
    }
    let decoded = String::from_utf8(bytes).map_err(|_| "is not UTF-8 once decoded")?;
    let relative = std::path::PathBuf::from(decoded);
    let inside =
        relative.components().all(|c| matches!(c, std::path::Component::Normal(_) | std::path::Component::CurDir));
    if relative.as_os_str().is_empty() || !inside {
        return Err("leaves the asset's folder (absolute, or with `..`)");
    }
    Ok(relative)
}

/// Parses and validates the JSON (and the GLB chunks), refusing first what would make the
/// `gltf` crate panic. Returns the document and the GLB's binary chunk.
fn read_document(bytes: &[u8]) -> Result<(Document, Option<Vec<u8>>), String> {
    check_glb_length(bytes)?;
    let ::gltf::Gltf { document, blob } =
        ::gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| e.to_string())?;
    let json = document.into_json();
    check_position_accessors(&json)?;
    check_animation_targets(&json)?;
    check_image_sources(&json)?;
    let document = Document::from_json(json).map_err(|e| e.to_string())?;
    Ok((document, blob))
}

/// The `gltf` crate subtracts the header size from a GLB's declared length unchecked (an
/// overflow panic in debug builds), so a too-small length is refused here first.
fn check_glb_length(bytes: &[u8]) -> Result<(), String> {
    let length = bytes.get(8..12).filter(|_| bytes.starts_with(b"glTF")).and_then(|b| b.try_into().ok());
    match length.map(u32::from_le_bytes) {
        Some(length) if length < 12 => Err(format!("GLB length {length} is shorter than its header")),
        _ => Ok(()),
    }
}

/// The `gltf` crate's own validation indexes the accessor list with each primitive's
/// `POSITION` accessor unchecked (gltf-json 1.4), so out-of-range ones are caught here first.
fn check_position_accessors(json: &::gltf::json::Root) -> Result<(), String> {
    let semantic = ::gltf::json::validation::Checked::Valid(::gltf::Semantic::Positions);
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let index = primitive.attributes.get(&semantic).map(|index| index.value());
            if index.is_some_and(|index| index >= json.accessors.len()) {
                return Err(format!("mesh {m}, primitive {p}: POSITION accessor out of range"));
            }
        }
    }
    Ok(())
}

/// The `gltf` crate's validation skips animation channel targets (gltf-json 1.4), and reading
/// an unknown `path` or an out-of-range `node` then panics; found by the loader fuzz test.
fn check_animation_targets(json: &::gltf::json::Root) -> Result<(), String> {
    for (a, animation) in json.animations.iter().enumerate() {
        for (c, channel) in animation.channels.iter().enumerate() {
            let target = &channel.target;
            if !matches!(target.path, ::gltf::json::validation::Checked::Valid(_)) {
                return Err(format!("animation {a}, channel {c}: unknown target path"));
            }
            if target.node.value() >= json.nodes.len() {
                return Err(format!("animation {a}, channel {c}: target node out of range"));
            }
        }
    }
    Ok(())
}

/// The `gltf` crate reads an image's source by unwrapping its `uri`, or its `bufferView` and
/// `mimeType` (gltf 1.4), which its validation does not require; found by the loader fuzz
/// test. The specification wants exactly one of `uri` and `bufferView`, and a `mimeType` with
/// the latter.
fn check_image_sources(json: &::gltf::json::Root) -> Result<(), String> {
    for (i, image) in json.images.iter().enumerate() {
        match (&image.uri, &image.buffer_view, &image.mime_type) {
            (Some(_), None, _) | (None, Some(_), Some(_)) => {}
            (None, Some(_), None) => return Err(format!("image {i}: a bufferView without a mimeType")),
            _ => return Err(format!("image {i}: needs exactly one of uri and bufferView")),
        }
    }
    Ok(())
}

/// Collects the triangles and cameras of a scene.
struct Builder<'a> {
    path: &'a Path,
    /// Where image files are looked up.
    base_dir: &'a Path,
    buffers: &'a [&'a [u8]],
    mesh: MeshData,
    /// Group index by glTF material index (`None`: no material).
    groups: HashMap<Option<usize>, u32>,
    /// For files with animations: the vertices each node placed, in the node's own space.
    parts: Option<Vec<AnimatedPart>>,
    /// Without animations: `(mesh, node, world)` for each placement of a mesh, in the
    /// hierarchy's order, until [`Builder::place_meshes`].
    placements: Vec<(usize, usize, Mat4)>,
}

impl Builder<'_> {
    fn error(&self, message: impl Into<String>) -> LoadError {
        LoadError::new(self.path, message)
    }

    fn node(&mut self, node: &Node, parent: Mat4, depth: usize) -> Result<(), LoadError> {
        if depth > MAX_DEPTH {
            return Err(self.error("node hierarchy too deep (or cyclic)"));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let (Some(mesh), None) = (node.mesh(), &self.parts) {
            self.placements.push((mesh.index(), node.index(), world));
        } else if let Some(mesh) = node.mesh() {
            self.mesh_primitives(&mesh, node.index(), world)?;
        }
        if let Some(camera) = node.camera() {
            self.camera(&camera, world)?;
        }
        for child in node.children() {
            self.node(&child, world, depth + 1)?;
        }
        Ok(())
    }

    /// Writes out the meshes of a file without animations: a mesh placed once at its place,
    /// in the hierarchy's order; a mesh that several nodes place once in its own space, as a
    /// [`SharedMesh`] with every placement.
    fn place_meshes(&mut self, document: &Document) -> Result<(), LoadError> {
        let mut uses = vec![0usize; document.meshes().len()];
        self.placements.iter().for_each(|&(m, _, _)| uses[m] += 1);
        let placements = std::mem::take(&mut self.placements);
        let meshes: Vec<::gltf::Mesh> = document.meshes().collect();
        for &(m, node, world) in placements.iter().filter(|(m, _, _)| uses[*m] == 1) {
            self.mesh_primitives(&meshes[m], node, world)?;
        }
        for (m, mesh) in meshes.iter().enumerate().filter(|(m, _)| uses[*m] > 1) {
            let mine: Vec<&(usize, usize, Mat4)> = placements.iter().filter(|p| p.0 == m).collect();
            // Its triangles alone, in the mesh's space (the groups stay shared), then the
            // main triangles back.
            let main = self.take_triangles();
            let result = self.mesh_primitives(mesh, mine[0].1, Mat4::IDENTITY);
            let mut piece = self.take_triangles();
            (self.mesh.positions, self.mesh.triangles, self.mesh.triangle_group, self.mesh.uvs) =
                (main.positions, main.triangles, main.triangle_group, main.uvs);
            result?;
            if !piece.triangles.is_empty() {
                piece.placements = mine.iter().map(|p| p.2).collect();
                self.mesh.shared.push(piece);
            }
        }
        Ok(())
    }

    /// Moves the triangles read so far (positions, triangles, groups, texture coordinates)
    /// out of the mesh being built.
    fn take_triangles(&mut self) -> SharedMesh {
        let mesh = &mut self.mesh;
        SharedMesh {
            positions: std::mem::take(&mut mesh.positions),
            triangles: std::mem::take(&mut mesh.triangles),
            triangle_group: std::mem::take(&mut mesh.triangle_group),
            uvs: std::mem::take(&mut mesh.uvs),
            placements: Vec::new(),
        }
    }

    /// The triangle primitives of `mesh`, placed by `world`.
    fn mesh_primitives(&mut self, mesh: &::gltf::Mesh, node: usize, world: Mat4) -> Result<(), LoadError> {
        let mesh_name = mesh.name().map_or_else(|| format!("mesh {}", mesh.index()), |n| format!("mesh `{n}`"));
        for primitive in mesh.primitives().filter(|p| p.mode() == Mode::Triangles) {
            let context = format!("{mesh_name}, primitive {}", primitive.index());
            self.primitive(&primitive, node, world, &context)?;
        }
        Ok(())
    }

    fn primitive(&mut self, primitive: &Primitive, node: usize, world: Mat4, context: &str) -> Result<(), LoadError> {
        let positions = (primitive.get(&::gltf::Semantic::Positions))
            .ok_or_else(|| self.error(format!("{context}: no POSITION attribute")))?;
        self.check_accessor(&positions, context, &[DataType::F32], Dimensions::Vec3)?;
        if let Some(indices) = primitive.indices() {
            self.check_accessor(&indices, context, &[DataType::U8, DataType::U16, DataType::U32], Dimensions::Scalar)?;
        }
        let buffers = self.buffers;
        let reader = primitive.reader(|buffer| buffers.get(buffer.index()).copied());
        let base = self.mesh.positions.len();
        let Some(points) = reader.read_positions() else {
            return Err(self.error(format!("{context}: cannot read positions")));
        };
        let local: Vec<Vec3> = points.map(Vec3::from).collect();
        for &point in &local {
            let p = world.transform_point3(point);
            check_finite(self.path, p, Location::Vertex(self.mesh.positions.len()))?;
            self.mesh.positions.push(p);
        }
        if let Some(parts) = &mut self.parts {
            parts.push(AnimatedPart { node, first_vertex: base, local });
        }
        let count = self.mesh.positions.len() - base;
        let indices: Vec<u32> = match reader.read_indices() {
            Some(indices) => indices.into_u32().collect(),
            None => (0..count as u32).collect(),
        };
        let first_triangle = self.mesh.triangles.len();
        self.triangles(&indices, base, count, context)?;
        self.texture_coordinates(primitive, &indices, first_triangle, count, context)?;
        let map = base_color_transform(&primitive.material()).map_err(|e| self.error(format!("{context}: {e}")))?;
        if let (Some(map), Some(uvs)) = (map, self.mesh.uvs.get_mut(first_triangle..)) {
            // Stored as (u, 1 − v); the transform works on glTF's (u, v).
            let apply = |[u, w]: [f32; 2]| {
                let t = map.transform_point2(glam::Vec2::new(u, 1.0 - w));
                [t.x, 1.0 - t.y]
            };
            uvs.iter_mut().for_each(|corners| *corners = corners.map(apply));
        }
        let group = self.group(primitive.material())?;
        let triangles = self.mesh.triangles.len();
        self.mesh.triangle_group.resize(triangles, group);
        Ok(())
    }

    /// The corners' `TEXCOORD_0` of the triangles from `first_triangle` on (made of `indices`
    /// into the primitive's `count` vertices), as `(u, 1 − v)`; zeros without them. Meshes
    /// read before the first primitive with texture coordinates get zeros too.
    fn texture_coordinates(
        &mut self,
        primitive: &Primitive,
        indices: &[u32],
        first_triangle: usize,
        count: usize,
        context: &str,
    ) -> Result<(), LoadError> {
        let accessor = primitive.get(&::gltf::Semantic::TexCoords(0));
        if accessor.is_none() && self.mesh.uvs.is_empty() {
            return Ok(());
        }
        self.mesh.uvs.resize(first_triangle, [[0.0; 2]; 3]);
        let Some(accessor) = accessor else {
            self.mesh.uvs.resize(self.mesh.triangles.len(), [[0.0; 2]; 3]);
            return Ok(());
        };
        self.check_accessor(&accessor, context, &[DataType::F32, DataType::U8, DataType::U16], Dimensions::Vec2)?;
        if accessor.count() != count {
            return Err(self.error(format!("{context}: {} texture coordinates for {count} vertices", accessor.count())));
        }
        let buffers = self.buffers;
        let reader = primitive.reader(|buffer| buffers.get(buffer.index()).copied());
        let uv: Vec<[f32; 2]> = match reader.read_tex_coords(0) {
            Some(coords) => coords.into_f32().map(|[u, v]| [u, 1.0 - v]).collect(),
            None => return Err(self.error(format!("{context}: cannot read texture coordinates"))),
        };
        if let Some(bad) = uv.iter().flatten().find(|x| !x.is_finite()) {
            return Err(self.error(format!("{context}: texture coordinate {bad} is not finite")));
        }
        let corners = indices.chunks_exact(3).map(|c| [uv[c[0] as usize], uv[c[1] as usize], uv[c[2] as usize]]);
        self.mesh.uvs.extend(corners);
        Ok(())
    }

    /// The keyframed node animations of the file, all played together; `None` if none of them
    /// moves a mesh. Morph-target weights are not supported and skipped.
    fn animation(&self, document: &Document, parts: Vec<AnimatedPart>) -> Result<Option<NodeAnimation>, LoadError> {
        let mut nodes: Vec<AnimatedNode> = document
            .nodes()
            .map(|n| {
                let (translation, rotation, scale) = n.transform().decomposed();
                AnimatedNode {
                    parent: None,
                    translation: translation.into(),
                    rotation: Quat::from_array(rotation).normalize(),
                    scale: scale.into(),
                    translation_track: None,
                    rotation_track: None,
                    scale_track: None,
                }
            })
            .collect();
        for n in document.nodes() {
            for child in n.children() {
                nodes[child.index()].parent = Some(n.index());
            }
        }
        let buffers = self.buffers;
        let mut duration = 0.0f32;
        for animation in document.animations() {
            for channel in animation.channels() {
                let context = format!("animation {}, channel {}", animation.index(), channel.index());
                let sampler = channel.sampler();
                self.check_accessor(&sampler.input(), &context, &[DataType::F32], Dimensions::Scalar)?;
                let output_types = [DataType::F32, DataType::I8, DataType::U8, DataType::I16, DataType::U16];
                let (types, dims) = match channel.target().property() {
                    Property::Rotation => (&output_types[..], Dimensions::Vec4),
                    Property::MorphTargetWeights => continue,
                    _ => (&output_types[..1], Dimensions::Vec3),
                };
                self.check_accessor(&sampler.output(), &context, types, dims)?;
                let reader = channel.reader(|buffer| buffers.get(buffer.index()).copied());
                let times: Vec<f32> = reader.read_inputs().map(|i| i.collect()).unwrap_or_default();
                if times.is_empty() || times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] < w[0]) {
                    return Err(self.error(format!("{context}: keyframe times must be finite and increasing")));
                }
                let interpolation = match sampler.interpolation() {
                    ::gltf::animation::Interpolation::Step => Interpolation::Step,
                    ::gltf::animation::Interpolation::Linear => Interpolation::Linear,
                    ::gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
                };
                let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
                let node = &mut nodes[channel.target().node().index()];
                let count_error = |n: usize| format!("{context}: {n} values for {} keyframes", times.len());
                match reader.read_outputs() {
                    Some(ReadOutputs::Translations(v)) | Some(ReadOutputs::Scales(v)) => {
                        let values: Vec<Vec3> = v.map(Vec3::from).collect();
                        if values.len() != per_key * times.len() || values.iter().any(|v| !v.is_finite()) {
                            return Err(self.error(count_error(values.len())));
                        }
                        let track = Some(Track { times: times.clone(), values, interpolation });
                        if channel.target().property() == Property::Translation {
                            node.translation_track = track;
                        } else {
                            node.scale_track = track;
                        }
                    }
                    Some(ReadOutputs::Rotations(r)) => {
                        let values: Vec<Quat> = r.into_f32().map(Quat::from_array).collect();
                        if values.len() != per_key * times.len() || values.iter().any(|q| !q.is_finite()) {
                            return Err(self.error(count_error(values.len())));
                        }
                        node.rotation_track = Some(Track { times: times.clone(), values, interpolation });
                    }
                    _ => continue,
                }
                duration = duration.max(*times.last().unwrap_or(&0.0));
            }
        }
        let mut animation = NodeAnimation { nodes, parts: Vec::new(), duration, outer: Mat4::IDENTITY };
        animation.parts = parts.into_iter().filter(|p| animation.moves(p.node)).collect();
        Ok((!animation.parts.is_empty()).then_some(animation))
    }

    /// Appends the triangles of one primitive, whose `count` vertices start at `base`.
    fn triangles(&mut self, indices: &[u32], base: usize, count: usize, context: &str) -> Result<(), LoadError> {
        let corners = indices.chunks_exact(3);
        if !corners.remainder().is_empty() {
            return Err(self.error(format!("{context}: {} indices, not a multiple of 3", indices.len())));
        }
        if base + count > u32::MAX as usize {
            return Err(self.error("too many vertices"));
        }
        if let Some(bad) = indices.iter().find(|&&i| i as usize >= count) {
            return Err(self.error(format!("{context}: index {bad} out of range ({count} vertices)")));
        }
        let base = base as u32;
        self.mesh.triangles.extend(corners.map(|c| [base + c[0], base + c[1], base + c[2]]));
        Ok(())
    }

    /// Checks what the `gltf` crate's reader assumes, so that reading cannot panic: element
    /// type, a buffer view inside its buffer, and every element inside the view.
    fn check_accessor(
        &self,
        accessor: &Accessor,
        context: &str,
        types: &[DataType],
        dimensions: Dimensions,
    ) -> Result<(), LoadError> {
        let fail = |what: &str| self.error(format!("{context}: accessor {} {what}", accessor.index()));
        if accessor.sparse().is_some() {
            return Err(fail("is sparse (not supported)"));
        }
        if !types.contains(&accessor.data_type()) || accessor.dimensions() != dimensions {
            return Err(fail("has the wrong element type"));
        }
        let view = accessor.view().ok_or_else(|| fail("has no buffer view"))?;
        let buffer_len = self.buffers.get(view.buffer().index()).map_or(0, |b| b.len());
        if !matches!(view.offset().checked_add(view.length()), Some(end) if end <= buffer_len) {
            return Err(fail("has a buffer view outside its buffer"));
        }
        let size = accessor.size();
        let stride = view.stride().unwrap_or(size);
        let end = (accessor.count().checked_sub(1))
            .and_then(|last| stride.checked_mul(last))
            .and_then(|last| last.checked_add(accessor.offset()))
            .and_then(|last| last.checked_add(size));
        if stride < size || !matches!(end, Some(end) if end <= view.length()) {
            return Err(fail("is empty or reads outside its buffer view"));
        }
        Ok(())
    }

    /// The group of a material, created at first use.
    fn group(&mut self, material: ::gltf::Material) -> Result<u32, LoadError> {
        let next = self.mesh.groups.len() as u32;
        let group = *self.groups.entry(material.index()).or_insert(next);
        if group == next {
            let (name, source) = match material.index() {
                None => ("default".to_owned(), SourceMaterial::None),
                Some(i) => {
                    let name = material.name().map_or_else(|| format!("material_{i}"), str::to_owned);
                    let mut converted = convert_material(&material);
                    converted.base_color_texture = self.base_color_image(&material, &name)?;
                    (name, SourceMaterial::Gltf(converted))
                }
            };
            self.mesh.groups.push(name);
            self.mesh.group_materials.push(source);
        }
        Ok(group)
    }

    /// Where a material's `baseColorTexture` image is (`None` without one, or for a texture
    /// coordinate set other than 0).
    fn base_color_image(&self, material: &::gltf::Material, name: &str) -> Result<Option<ImageSource>, LoadError> {
        use ::gltf::image::Source;
        let Some(info) = material.pbr_metallic_roughness().base_color_texture() else { return Ok(None) };
        if texture_set(&info) != 0 {
            return Ok(None);
        }
        let image = info.texture().source();
        let index = image.index();
        let fail = |message: String| self.error(format!("material `{name}`, image {index}: {message}"));
        let embedded = |bytes: Vec<u8>| ImageSource::Embedded {
            name: format!("{}#image {index}", self.path.display()),
            bytes: std::sync::Arc::new(bytes),
        };
        Ok(Some(match image.source() {
            Source::View { view, .. } => {
                let buffer = self.buffers.get(view.buffer().index()).copied().unwrap_or(&[]);
                let bytes = view.offset().checked_add(view.length()).and_then(|end| buffer.get(view.offset()..end));
                embedded(bytes.ok_or_else(|| fail("its buffer view lies outside its buffer".into()))?.to_vec())
            }
            Source::Uri { uri, .. } if uri.starts_with("data:") => {
                let data = ::gltf::buffer::Data::from_source(::gltf::buffer::Source::Uri(uri), None)
                    .map_err(|e| fail(format!("invalid data URI: {e}")))?;
                embedded(data.0)
            }
            Source::Uri { uri, .. } => {
                let relative = confined_path(uri).map_err(|e| fail(format!("`{uri}` {e}")))?;
                ImageSource::File(self.base_dir.join(relative))
            }
        }))
    }

    fn camera(&mut self, camera: &::gltf::Camera, world: Mat4) -> Result<(), LoadError> {
        let Projection::Perspective(perspective) = camera.projection() else {
            return Ok(());
        };
        let name = camera.name().map_or_else(|| format!("camera_{}", camera.index()), str::to_owned);
        let position = world.transform_point3(Vec3::ZERO);
        let forward = world.transform_vector3(Vec3::NEG_Z).try_normalize();
        let up = world.transform_vector3(Vec3::Y).try_normalize();
        let (Some(forward), Some(up)) = (forward, up) else {
            return Err(self.error(format!("camera `{name}` has a degenerate transform")));
        };
        self.mesh.cameras.push(SourceCamera {
            name,
            position,
            look_at: position + forward,
            up,
            vfov_degrees: perspective.yfov().to_degrees(),
        });
        Ok(())
    }
}

/// The texture coordinate set a texture reads: its own, unless its `KHR_texture_transform`
/// names another.
fn texture_set(info: &::gltf::texture::Info) -> u32 {
    info.texture_transform().and_then(|t| t.tex_coord()).unwrap_or(info.tex_coord())
}

/// The `KHR_texture_transform` of a material's base-colour texture, as the map of glTF texture
/// coordinates (`v` down) it makes: scale, then rotate, then offset. The rotation follows the
/// extension's sample model and Khronos's sample viewer (glTF issue #1563): a positive angle
/// turns the coordinates from `+u` towards `-v`. `None` without a transform (or without a
/// texture of set 0, whose coordinates are then not used); an error for non-finite values.
fn base_color_transform(material: &::gltf::Material) -> Result<Option<glam::Affine2>, String> {
    let Some(info) = material.pbr_metallic_roughness().base_color_texture() else { return Ok(None) };
    let Some(transform) = info.texture_transform().filter(|_| texture_set(&info) == 0) else { return Ok(None) };
    let ([ox, oy], rotation, [sx, sy]) = (transform.offset(), transform.rotation(), transform.scale());
    if ![ox, oy, rotation, sx, sy].iter().all(|x| x.is_finite()) {
        let name = material.name().map_or_else(|| format!("material_{}", material.index().unwrap_or(0)), str::to_owned);
        return Err(format!("material `{name}`: KHR_texture_transform has a value that is not finite"));
    }
    let (sin, cos) = rotation.sin_cos();
    let rotate = glam::Mat2::from_cols(glam::Vec2::new(cos, -sin), glam::Vec2::new(sin, cos));
    Ok(Some(glam::Affine2::from_mat2_translation(
        rotate * glam::Mat2::from_diagonal(glam::Vec2::new(sx, sy)),
        glam::Vec2::new(ox, oy),
    )))
}

fn convert_material(material: &::gltf::Material) -> GltfMaterial {
    let pbr = material.pbr_metallic_roughness();
    let [r, g, b, a] = pbr.base_color_factor();
    let strength = material.emissive_strength().unwrap_or(1.0);
    let masked = material.alpha_mode() == ::gltf::material::AlphaMode::Mask;
    GltfMaterial {
        base_color: [r, g, b],
        base_color_texture: None,
        metallic: pbr.metallic_factor(),
        roughness: pbr.roughness_factor(),
        emissive: material.emissive_factor().map(|e| e * strength),
        transmission: material.transmission().map_or(0.0, |t| t.transmission_factor()),
        ior: material.ior().unwrap_or(1.5),
        alpha_threshold: masked.then(|| material.alpha_cutoff().unwrap_or(0.5) / a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One triangle under two nested translated nodes, a material, a rotated camera.
    pub(crate) fn triangle_gltf(index: u32) -> String {
        let mut buffer = Vec::new();
        for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
            buffer.extend_from_slice(&v.to_le_bytes());
        }
        for i in [0u16, 1, index as u16, 0] {
            buffer.extend_from_slice(&i.to_le_bytes());
        }
        let uri = format!("data:application/octet-stream;base64,{}", base64::encode(&buffer));
        let half = std::f32::consts::FRAC_1_SQRT_2;
        format!(
            r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_transmission", "KHR_materials_ior"],
  "scene": 0,
  "scenes": [{{"nodes": [0, 2]}}],
  "nodes": [
    {{"translation": [1, 0, 0], "children": [1]}},
    {{"translation": [0, 2, 3], "mesh": 0}},
    {{"translation": [0, 0, 5], "rotation": [0, {half}, 0, {half}], "camera": 0}}
  ],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "materials": [{{
    "name": "glow",
    "pbrMetallicRoughness": {{"baseColorFactor": [0.5, 0.25, 0.125, 1], "metallicFactor": 0.75, "roughnessFactor": 0.5}},
    "emissiveFactor": [1, 0.5, 0.25],
    "extensions": {{
      "KHR_materials_emissive_strength": {{"emissiveStrength": 4}},
      "KHR_materials_transmission": {{"transmissionFactor": 0.5}},
      "KHR_materials_ior": {{"ior": 1.33}}
    }}
  }}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.5, "znear": 0.1}}}}],
  "buffers": [{{"byteLength": {len}, "uri": "{uri}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": 6}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}}
  ]
}}"#,
            len = buffer.len()
        )
    }

    fn parse_str(text: &str) -> Result<MeshData, LoadError> {
        parse(Path::new("test.gltf"), Path::new("/nonexistent"), text.as_bytes())
    }

    #[test]
    fn triangle_transform_material_and_camera() {
        let mesh = parse_str(&triangle_gltf(2)).unwrap();
        let expected: Vec<Vec3> = [[1., 2., 3.], [2., 2., 3.], [1., 3., 3.]].map(Vec3::from).into();
        assert_eq!(mesh.positions, expected);
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
        assert_eq!(mesh.triangle_group, vec![0]);
        assert_eq!(mesh.groups, vec!["glow"]);
        let SourceMaterial::Gltf(material) = &mesh.group_materials[0] else { panic!("not a glTF material") };
        assert_eq!(material.base_color, [0.5, 0.25, 0.125]);
        assert_eq!((material.metallic, material.roughness), (0.75, 0.5));
        assert_eq!(material.emissive, [4.0, 2.0, 1.0]);
        assert_eq!((material.transmission, material.ior), (0.5, 1.33));
        let [camera] = &mesh.cameras[..] else { panic!("expected one camera") };
        assert_eq!(camera.name, "camera_0");
        assert!(camera.position.abs_diff_eq(Vec3::new(0.0, 0.0, 5.0), 1e-6));
        assert!(camera.look_at.abs_diff_eq(Vec3::new(-1.0, 0.0, 5.0), 1e-6), "{}", camera.look_at);
        assert!(camera.up.abs_diff_eq(Vec3::Y, 1e-6));
        assert!((camera.vfov_degrees - 0.5f32.to_degrees()).abs() < 1e-4);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let out_of_range = parse_str(&triangle_gltf(3)).unwrap_err().to_string();
        assert!(out_of_range.contains("index 3 out of range (3 vertices)"), "{out_of_range}");
        let bad_view =
            triangle_gltf(2).replace(r#""byteOffset": 36, "byteLength": 6"#, r#""byteOffset": 40, "byteLength": 6"#);
        let message = parse_str(&bad_view).unwrap_err().to_string();
        assert!(message.contains("outside its buffer"), "{message}");
        let huge_count =
            triangle_gltf(2).replace(r#""count": 3, "type": "SCALAR""#, r#""count": 4000000000, "type": "SCALAR""#);
        assert!(parse_str(&huge_count).is_err());
        assert!(parse_str("{").unwrap_err().to_string().starts_with("test.gltf: invalid glTF"));
        assert!(parse_str("").is_err());
        let bad_position = triangle_gltf(2).replace(r#""POSITION": 0"#, r#""POSITION": 9"#);
        let message = parse_str(&bad_position).unwrap_err().to_string();
        assert!(message.contains("POSITION accessor out of range"), "{message}");
        let short_glb = [b"glTF".as_slice(), &2u32.to_le_bytes(), &4u32.to_le_bytes()].concat();
        let message = parse(Path::new("t.glb"), Path::new(""), &short_glb).unwrap_err().to_string();
        assert!(message.contains("shorter than its header"), "{message}");
        let no_mesh = triangle_gltf(2).replace(r#""nodes": [0, 2]"#, r#""nodes": [2]"#);
        assert_eq!(parse_str(&no_mesh).unwrap_err().to_string(), "test.gltf: no triangles");
    }
}
