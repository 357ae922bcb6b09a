//! PLY reader (`ascii`, `binary_little_endian`, `binary_big_endian`), written by hand.
//!
//! Reads `element vertex` (properties `x`, `y`, `z` of any scalar type, and texture
//! coordinates when a pair of them is there: the first of `u`/`v`, `s`/`t`,
//! `texture_u`/`texture_v` and `texture_s`/`texture_t` the element has, with `v = 0` at the
//! image's bottom as in OBJ files; other properties, lists included, are skipped; texture
//! coordinates given per face corner, MeshLab's `texcoord` lists, are not read) and `element face` (the list property
//! `vertex_indices` or `vertex_index`; polygons are fan-triangulated). Other elements are
//! skipped: by line in ASCII files, by size in binary ones. All triangles go to one group,
//! `default`.
//!
//! Limits: ASCII files must hold one element per line (as every writer does); no normals or
//! colours are returned.

use super::{capped_capacity, check_finite, finish, Location, MeshData, SourceMaterial};
use crate::error::LoadError;
use glam::Vec3;
use std::path::Path;
use std::str::SplitAsciiWhitespace;

/// Parses a PLY file held in memory; `path` is only used in error messages.
pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<MeshData, LoadError> {
    let bytes = super::input::strip_bom(bytes);
    let header = parse_header(path, bytes)?;
    let layout = Layout::of(path, &header)?;
    let body = bytes.get(header.body_start..).unwrap_or_default();
    let mut mesh = MeshData {
        groups: vec!["default".to_owned()],
        group_materials: vec![SourceMaterial::None],
        ..MeshData::default()
    };
    let mut vertices = Vertices { mesh: &mut mesh, uvs: Vec::new() };
    match header.encoding {
        Encoding::Ascii => read_ascii(path, &header, &layout, body, &mut vertices)?,
        Encoding::Binary { big_endian } => {
            let mut reader = BinaryReader { data: body, pos: 0, big_endian };
            read_binary(path, &header, &layout, &mut reader, &mut vertices)?;
        }
    }
    let uvs = vertices.uvs;
    if layout.has_uv {
        // Face indices were checked against the header's vertex count, which the vertex
        // element's reading met in full.
        mesh.uvs = mesh.triangles.iter().map(|t| t.map(|v| uvs[v as usize])).collect();
    }
    mesh.triangle_group = vec![0; mesh.triangles.len()];
    finish(path, mesh)
}

// ---------------------------------------------------------------------------------------
// Header

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PropertyType {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    ty: PropertyType,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
    /// Header line of the `element` statement.
    line: usize,
}

impl Element {
    /// Bytes per instance if the element has no list property.
    fn fixed_size(&self) -> Option<usize> {
        self.properties.iter().try_fold(0usize, |sum, p| match p.ty {
            PropertyType::Scalar(s) => sum.checked_add(s.size()),
            PropertyType::List { .. } => None,
        })
    }

    /// The element's name in the plural, for messages.
    fn plural(&self) -> String {
        match self.name.as_str() {
            "vertex" => "vertices".to_owned(),
            name => format!("{name}s"),
        }
    }

    /// The smallest number of bytes one instance can take in a binary file.
    fn min_binary_size(&self) -> usize {
        self.properties
            .iter()
            .map(|p| match p.ty {
                PropertyType::Scalar(s) | PropertyType::List { count: s, .. } => s.size(),
            })
            .sum()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary { big_endian: bool },
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the data after `end_header`.
    body_start: usize,
    /// Number of lines up to and including `end_header`.
    lines: usize,
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header, LoadError> {
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0;
    let mut line_no = 0;
    loop {
        line_no += 1;
        let error = |message: &str| LoadError::at_line(path, line_no, message);
        let rest = bytes.get(pos..).unwrap_or_default();
        let Some(len) = rest.iter().position(|&b| b == b'\n') else {
            return Err(error("header has no `end_header` line"));
        };
        pos += len + 1;
        let raw = rest.get(..len).unwrap_or_default();
        let line = std::str::from_utf8(raw).map_err(|_| error("header line is not text"))?;
        let line = line.trim_end_matches('\r');
        if line_no == 1 {
            if line.trim() != "ply" {
                return Err(error("not a PLY file (first line is not `ply`)"));
            }
            continue;
        }
        let mut tokens = line.split_ascii_whitespace();
        match tokens.next() {
            Some("format") => encoding = Some(parse_format(tokens).ok_or_else(|| error("bad format line"))?),
            Some("element") => elements.push(parse_element(tokens, line_no).ok_or_else(|| error("bad element line"))?),
            Some("property") => {
                let element = elements.last_mut().ok_or_else(|| error("property before any element"))?;
                let property = parse_property(tokens).ok_or_else(|| error("bad property line"))?;
                element.properties.push(property);
            }
            Some("end_header") => break,
            Some("comment" | "obj_info") | None => {}
            Some(other) => return Err(error(&format!("unexpected header keyword `{other}`"))),
        }
    }
    let encoding = encoding.ok_or_else(|| LoadError::at_line(path, line_no, "header has no `format` line"))?;
    Ok(Header { encoding, elements, body_start: pos, lines: line_no })
}

fn parse_format(mut tokens: SplitAsciiWhitespace) -> Option<Encoding> {
    let encoding = match tokens.next()? {
        "ascii" => Encoding::Ascii,
        "binary_little_endian" => Encoding::Binary { big_endian: false },
        "binary_big_endian" => Encoding::Binary { big_endian: true },
        _ => return None,
    };
    (tokens.next()? == "1.0").then_some(encoding)
}

fn parse_element(mut tokens: SplitAsciiWhitespace, line: usize) -> Option<Element> {
    let name = tokens.next()?.to_owned();
    let count = tokens.next()?.parse().ok()?;
    Some(Element { name, count, properties: Vec::new(), line })
}

fn parse_property(mut tokens: SplitAsciiWhitespace) -> Option<Property> {
    let ty = match tokens.next()? {
        "list" => {
            let count = Scalar::parse(tokens.next()?).filter(|s| s.is_integer())?;
            let item = Scalar::parse(tokens.next()?)?;
            PropertyType::List { count, item }
        }
        scalar => PropertyType::Scalar(Scalar::parse(scalar)?),
    };
    let name = tokens.next()?.to_owned();
    Some(Property { name, ty })
}

// ---------------------------------------------------------------------------------------
// What to read from which element

/// What a vertex's reading fills: the mesh's positions and the vertices' texture
/// coordinates (empty when the file has none).
struct Vertices<'m> {
    mesh: &'m mut MeshData,
    uvs: Vec<[f32; 2]>,
}

/// Which value of a vertex a property holds: [`U`] and [`V`] after the coordinates 0..3.
const U: usize = 3;
const V: usize = 4;

/// The role of each property of the vertex and face elements.
struct Layout {
    /// Index of the `vertex` element in `Header::elements`.
    vertex: usize,
    /// For each vertex property, which value it is, if any: a coordinate (0..3), [`U`] or
    /// [`V`].
    vertex_axes: Vec<Option<usize>>,
    /// Whether the vertices have texture coordinates (both of a pair).
    has_uv: bool,
    /// Index of the `face` element and of its index list property.
    face: Option<(usize, usize)>,
    vertex_count: usize,
}

impl Layout {
    fn of(path: &Path, header: &Header) -> Result<Self, LoadError> {
        let header_error = |line, message: &str| LoadError::at_line(path, line, message);
        let vertex = (header.elements.iter().position(|e| e.name == "vertex"))
            .ok_or_else(|| header_error(header.lines, "header has no `element vertex`"))?;
        let element = &header.elements[vertex];
        let scalar = |name: &str| {
            element.properties.iter().position(|p| p.name == name && matches!(p.ty, PropertyType::Scalar(_)))
        };
        let axis = |p: &Property| match (p.name.as_str(), p.ty) {
            ("x", PropertyType::Scalar(_)) => Some(0),
            ("y", PropertyType::Scalar(_)) => Some(1),
            ("z", PropertyType::Scalar(_)) => Some(2),
            _ => None,
        };
        let mut vertex_axes: Vec<_> = element.properties.iter().map(axis).collect();
        if (0..3).any(|a| !vertex_axes.contains(&Some(a))) {
            return Err(header_error(element.line, "vertex element needs scalar properties x, y and z"));
        }
        // The first pair of texture coordinates the element has; other such names are
        // skipped like any unknown property.
        let pair = [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")]
            .into_iter()
            .find_map(|(u, v)| Some((scalar(u)?, scalar(v)?)));
        if let Some((u, v)) = pair {
            (vertex_axes[u], vertex_axes[v]) = (Some(U), Some(V));
        }
        let has_uv = pair.is_some();
        if element.count > u32::MAX as usize {
            return Err(header_error(element.line, "too many vertices"));
        }
        let face = match header.elements.iter().position(|e| e.name == "face") {
            None => None,
            Some(f) => Some((f, Self::index_list(path, &header.elements[f])?)),
        };
        Ok(Self { vertex, vertex_axes, has_uv, face, vertex_count: element.count })
    }

    /// The `vertex_indices` (or `vertex_index`) list property of the face element.
    fn index_list(path: &Path, face: &Element) -> Result<usize, LoadError> {
        let is_index_list = |p: &Property| {
            matches!(p.name.as_str(), "vertex_indices" | "vertex_index")
                && matches!(p.ty, PropertyType::List { item, .. } if item.is_integer())
        };
        (face.properties.iter().position(is_index_list)).ok_or_else(|| {
            LoadError::at_line(path, face.line, "face element needs an integer list property vertex_indices")
        })
    }

    fn role(&self, element: usize) -> Role {
        match self.face {
            _ if element == self.vertex => Role::Vertex,
            Some((face, list)) if face == element => Role::Face { list },
            _ => Role::Skip,
        }
    }
}

enum Role {
    Vertex,
    Face { list: usize },
    Skip,
}

/// Appends the fan triangulation of a polygon, given its corners one by one.
struct Fan<'m> {
    triangles: &'m mut Vec<[u32; 3]>,
    first: u32,
    previous: u32,
    corners: usize,
}

impl<'m> Fan<'m> {
    fn new(triangles: &'m mut Vec<[u32; 3]>) -> Self {
        Self { triangles, first: 0, previous: 0, corners: 0 }
    }

    fn push(&mut self, v: u32) {
        match self.corners {
            0 => self.first = v,
            1 => {}
            _ => self.triangles.push([self.first, self.previous, v]),
        }
        self.previous = v;
        self.corners += 1;
    }
}

/// Checks a face index against the vertex count; the error text is completed by the caller.
fn vertex_index(value: i64, vertex_count: usize) -> Result<u32, String> {
    u32::try_from(value)
        .ok()
        .filter(|&v| (v as usize) < vertex_count)
        .ok_or_else(|| format!("vertex index {value} out of range ({vertex_count} vertices)"))
}

fn too_few_corners(corners: usize) -> String {
    format!("face has {corners} vertices, needs at least 3")
}

// ---------------------------------------------------------------------------------------
// ASCII body

fn read_ascii(
    path: &Path,
    header: &Header,
    layout: &Layout,
    body: &[u8],
    vertices: &mut Vertices,
) -> Result<(), LoadError> {
    let text = String::from_utf8_lossy(body);
    let mut lines = AsciiLines { path, lines: text.lines(), line_no: header.lines, bytes_left: body.len() };
    for (index, element) in header.elements.iter().enumerate() {
        match layout.role(index) {
            Role::Vertex => ascii_vertices(&mut lines, element, layout, vertices)?,
            Role::Face { list } => ascii_faces(&mut lines, element, list, layout.vertex_count, vertices.mesh)?,
            Role::Skip => {
                for i in 0..element.count {
                    lines.next(i, element)?;
                }
            }
        }
    }
    Ok(())
}

/// The non-blank lines of an ASCII body, with their 1-based line numbers.
struct AsciiLines<'t> {
    path: &'t Path,
    lines: std::str::Lines<'t>,
    line_no: usize,
    bytes_left: usize,
}

impl<'t> AsciiLines<'t> {
    /// The line of instance `i` of `element`.
    fn next(&mut self, i: usize, element: &Element) -> Result<AsciiLine<'t>, LoadError> {
        loop {
            self.line_no += 1;
            let Some(line) = self.lines.next() else {
                return Err(truncated(self.path, element, Some(i)));
            };
            self.bytes_left = self.bytes_left.saturating_sub(line.len() + 1);
            if !line.trim_ascii().is_empty() {
                return Ok(AsciiLine { tokens: line.split_ascii_whitespace(), line_no: self.line_no });
            }
        }
    }
}

/// The values of one line of an ASCII body.
struct AsciiLine<'t> {
    tokens: SplitAsciiWhitespace<'t>,
    line_no: usize,
}

impl<'t> AsciiLine<'t> {
    fn token(&mut self, path: &Path) -> Result<&'t str, LoadError> {
        self.tokens.next().ok_or_else(|| LoadError::at_line(path, self.line_no, "too few values"))
    }

    fn number(&mut self, path: &Path) -> Result<f64, LoadError> {
        let token = self.token(path)?;
        token.parse().map_err(|_| LoadError::at_line(path, self.line_no, format!("bad number `{token}`")))
    }

    fn integer(&mut self, path: &Path) -> Result<i64, LoadError> {
        let token = self.token(path)?;
        token.parse().map_err(|_| LoadError::at_line(path, self.line_no, format!("bad integer `{token}`")))
    }

    /// Skips a list property's values.
    fn skip_list(&mut self, path: &Path) -> Result<(), LoadError> {
        let n = self.integer(path)?;
        for _ in 0..n {
            self.token(path)?;
        }
        Ok(())
    }
}

fn ascii_vertices(
    lines: &mut AsciiLines,
    element: &Element,
    layout: &Layout,
    vertices: &mut Vertices,
) -> Result<(), LoadError> {
    let path = lines.path;
    // An ASCII vertex takes at least two bytes per property ("0 ").
    let capacity = capped_capacity(element.count, lines.bytes_left, 2 * element.properties.len());
    vertices.reserve(capacity, layout);
    for i in 0..element.count {
        let mut line = lines.next(i, element)?;
        let mut values = [0.0f64; 5];
        for (property, axis) in element.properties.iter().zip(&layout.vertex_axes) {
            match (property.ty, axis) {
                (PropertyType::Scalar(_), Some(axis)) => values[*axis] = line.number(path)?,
                (PropertyType::Scalar(_), None) => {
                    line.token(path)?;
                }
                (PropertyType::List { .. }, _) => line.skip_list(path)?,
            }
        }
        vertices.push(path, values, layout, Location::Line(line.line_no))?;
    }
    Ok(())
}

impl Vertices<'_> {
    fn reserve(&mut self, capacity: usize, layout: &Layout) {
        self.mesh.positions.reserve(capacity);
        if layout.has_uv {
            self.uvs.reserve(capacity);
        }
    }

    /// Adds a vertex: `x, y, z, u, v`.
    fn push(&mut self, path: &Path, values: [f64; 5], layout: &Layout, at: Location) -> Result<(), LoadError> {
        let p = Vec3::new(values[0] as f32, values[1] as f32, values[2] as f32);
        check_finite(path, p, at)?;
        self.mesh.positions.push(p);
        if layout.has_uv {
            let uv = [values[U] as f32, values[V] as f32];
            if !uv.iter().all(|x| x.is_finite()) {
                return Err(at.error(path, format!("texture coordinate is not finite ({}, {})", uv[0], uv[1])));
            }
            self.uvs.push(uv);
        }
        Ok(())
    }
}

fn ascii_faces(
    lines: &mut AsciiLines,
    element: &Element,
    list: usize,
    vertex_count: usize,
    mesh: &mut MeshData,
) -> Result<(), LoadError> {
    let path = lines.path;
    let capacity = capped_capacity(element.count, lines.bytes_left, 2 * element.properties.len());
    mesh.triangles.reserve(capacity);
    for i in 0..element.count {
        let mut line = lines.next(i, element)?;
        let line_no = line.line_no;
        let line_error = |message: String| LoadError::at_line(path, line_no, message);
        for (p, property) in element.properties.iter().enumerate() {
            match property.ty {
                PropertyType::List { .. } if p == list => {
                    let corners = line.integer(path)?;
                    let mut fan = Fan::new(&mut mesh.triangles);
                    for _ in 0..corners {
                        let value = line.integer(path)?;
                        fan.push(vertex_index(value, vertex_count).map_err(line_error)?);
                    }
                    if corners < 3 {
                        return Err(line_error(too_few_corners(corners.max(0) as usize)));
                    }
                }
                PropertyType::List { .. } => line.skip_list(path)?,
                PropertyType::Scalar(_) => {
                    line.token(path)?;
                }
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Binary body

/// A cursor over binary data; every read is bounds-checked.
struct BinaryReader<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl BinaryReader<'_> {
    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    fn skip(&mut self, n: usize) -> Option<()> {
        let end = self.pos.checked_add(n).filter(|&end| end <= self.data.len())?;
        self.pos = end;
        Some(())
    }

    fn bytes<const N: usize>(&mut self) -> Option<[u8; N]> {
        let end = self.pos.checked_add(N)?;
        let bytes = self.data.get(self.pos..end)?.try_into().ok()?;
        self.pos = end;
        Some(bytes)
    }

    /// One scalar, as `f64` (exact for every integer type).
    fn read(&mut self, ty: Scalar) -> Option<f64> {
        macro_rules! value {
            ($t:ty) => {{
                let bytes = self.bytes()?;
                if self.big_endian {
                    <$t>::from_be_bytes(bytes)
                } else {
                    <$t>::from_le_bytes(bytes)
                }
            }};
        }
        Some(match ty {
            Scalar::I8 => f64::from(value!(i8)),
            Scalar::U8 => f64::from(value!(u8)),
            Scalar::I16 => f64::from(value!(i16)),
            Scalar::U16 => f64::from(value!(u16)),
            Scalar::I32 => f64::from(value!(i32)),
            Scalar::U32 => f64::from(value!(u32)),
            Scalar::F32 => f64::from(value!(f32)),
            Scalar::F64 => value!(f64),
        })
    }

    /// One value of an integer type (checked by the header parser).
    fn integer(&mut self, ty: Scalar) -> Option<i64> {
        self.read(ty).map(|v| v as i64)
    }

    /// Skips one list property's values.
    fn skip_list(&mut self, count: Scalar, item: Scalar) -> Option<()> {
        let n = usize::try_from(self.integer(count)?).ok()?;
        self.skip(n.checked_mul(item.size())?)
    }
}

fn read_binary(
    path: &Path,
    header: &Header,
    layout: &Layout,
    reader: &mut BinaryReader,
    vertices: &mut Vertices,
) -> Result<(), LoadError> {
    for (index, element) in header.elements.iter().enumerate() {
        match layout.role(index) {
            Role::Vertex => binary_vertices(path, reader, element, layout, vertices)?,
            Role::Face { list } => binary_faces(path, reader, element, list, layout.vertex_count, vertices.mesh)?,
            Role::Skip => skip_binary(reader, element).ok_or_else(|| truncated(path, element, None))?,
        }
    }
    Ok(())
}

/// "file ends after 3 of 10 faces" (or "inside the 7 edges" when skipping a whole element).
fn truncated(path: &Path, element: &Element, done: Option<usize>) -> LoadError {
    let message = match done {
        Some(i) => format!("file ends after {i} of {} {}", element.count, element.plural()),
        None => format!("file ends inside the {} {}", element.count, element.plural()),
    };
    LoadError::new(path, message)
}

fn skip_binary(reader: &mut BinaryReader, element: &Element) -> Option<()> {
    if let Some(size) = element.fixed_size() {
        return reader.skip(size.checked_mul(element.count)?);
    }
    for _ in 0..element.count {
        for property in &element.properties {
            match property.ty {
                PropertyType::Scalar(s) => reader.skip(s.size())?,
                PropertyType::List { count, item } => reader.skip_list(count, item)?,
            }
        }
    }
    Some(())
}

fn binary_vertices(
    path: &Path,
    reader: &mut BinaryReader,
    element: &Element,
    layout: &Layout,
    vertices: &mut Vertices,
) -> Result<(), LoadError> {
    let capacity = capped_capacity(element.count, reader.remaining(), element.min_binary_size());
    vertices.reserve(capacity, layout);
    for i in 0..element.count {
        let mut values = [0.0f64; 5];
        for (property, axis) in element.properties.iter().zip(&layout.vertex_axes) {
            let read = match (property.ty, axis) {
                (PropertyType::Scalar(s), Some(axis)) => reader.read(s).map(|v| values[*axis] = v),
                (PropertyType::Scalar(s), None) => reader.skip(s.size()),
                (PropertyType::List { count, item }, _) => reader.skip_list(count, item),
            };
            read.ok_or_else(|| truncated(path, element, Some(i)))?;
        }
        vertices.push(path, values, layout, Location::Vertex(i))?;
    }
    Ok(())
}

fn binary_faces(
    path: &Path,
    reader: &mut BinaryReader,
    element: &Element,
    list: usize,
    vertex_count: usize,
    mesh: &mut MeshData,
) -> Result<(), LoadError> {
    let capacity = capped_capacity(element.count, reader.remaining(), element.min_binary_size());
    mesh.triangles.reserve(capacity);
    for i in 0..element.count {
        let face_error = |message: String| LoadError::new(path, format!("face {i}: {message}"));
        for (p, property) in element.properties.iter().enumerate() {
            match property.ty {
                PropertyType::List { count, item } if p == list => {
                    let corners = reader.integer(count).ok_or_else(|| truncated(path, element, Some(i)))?;
                    let mut fan = Fan::new(&mut mesh.triangles);
                    for _ in 0..corners {
                        let value = reader.integer(item).ok_or_else(|| truncated(path, element, Some(i)))?;
                        fan.push(vertex_index(value, vertex_count).map_err(face_error)?);
                    }
                    if corners < 3 {
                        return Err(face_error(too_few_corners(corners.max(0) as usize)));
                    }
                    Some(())
                }
                PropertyType::List { count, item } => reader.skip_list(count, item),
                PropertyType::Scalar(s) => reader.skip(s.size()),
            }
            .ok_or_else(|| truncated(path, element, Some(i)))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_bytes(bytes: &[u8]) -> Result<MeshData, LoadError> {
        parse(Path::new("test.ply"), bytes)
    }

    const QUAD_HEADER: &str = "element vertex 4\nproperty float x\nproperty uchar red\nproperty double y\n\
        property list uchar int extra\nproperty int16 z\nelement face 1\nproperty uchar flags\n\
        property list uint8 uint vertex_indices\nelement edge 2\nproperty list ushort char stuff\nproperty int v\n";

    /// A quad whose vertices carry extra properties, followed by an element to skip.
    fn binary_quad(big_endian: bool) -> Vec<u8> {
        let format = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
        let mut data = format!("ply\nformat {format} 1.0\ncomment test\n{QUAD_HEADER}end_header\n").into_bytes();
        let mut put = |bytes: &[u8]| {
            if big_endian {
                data.extend(bytes.iter().rev());
            } else {
                data.extend_from_slice(bytes);
            }
        };
        for (x, y, z) in [(0.0f32, 0.0f64, 0i16), (1.0, 0.0, 0), (1.0, 1.0, 2), (0.0, 1.0, 2)] {
            put(&x.to_le_bytes());
            put(&[7]);
            put(&y.to_le_bytes());
            put(&[2]);
            put(&1i32.to_le_bytes());
            put(&2i32.to_le_bytes());
            put(&z.to_le_bytes());
        }
        put(&[9]);
        put(&[4]);
        for i in 0u32..4 {
            put(&i.to_le_bytes());
        }
        for _ in 0..2 {
            put(&1u16.to_le_bytes());
            put(&[5]);
            put(&3i32.to_le_bytes());
        }
        data
    }

    fn check_quad(mesh: &MeshData) {
        let expected: Vec<Vec3> = [[0., 0., 0.], [1., 0., 0.], [1., 1., 2.], [0., 1., 2.]].map(Vec3::from).into();
        assert_eq!(mesh.positions, expected);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(mesh.groups, vec!["default"]);
        assert_eq!(mesh.triangle_group, vec![0, 0]);
    }

    #[test]
    fn binary_little_and_big_endian() {
        check_quad(&parse_bytes(&binary_quad(false)).unwrap());
        check_quad(&parse_bytes(&binary_quad(true)).unwrap());
    }

    #[test]
    fn ascii_with_extra_properties_and_elements() {
        let text = format!(
            "ply\r\nformat ascii 1.0\r\n{}end_header\r\n\
             0 7 0 2 1 2 0\n1 7 0 0 0\n\n1 7 1 1 5 2\n0 7 1 0 2\n9 4 0 1 2 3\n1 5 3\n0 4\n",
            QUAD_HEADER.replace('\n', "\r\n")
        );
        check_quad(&parse_bytes(text.as_bytes()).unwrap());
    }

    /// Texture coordinates, under each of their names, become each triangle's corners'; one
    /// of a pair alone is skipped.
    #[test]
    fn texture_coordinates() {
        let header = |u: &str, v: &str| {
            format!(
                "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float {u}\n\
                 property float y\nproperty float z\nproperty float {v}\nelement face 1\n\
                 property list uchar int vertex_indices\nend_header\n"
            )
        };
        let body = "0 0.0 0 0 0.5\n1 1.0 0 0 0.5\n1 1.0 1 0 1.0\n0 0.25 1 0 1.0\n4 0 1 2 3\n";
        for (u, v) in [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")] {
            let mesh = parse_bytes(format!("{}{body}", header(u, v)).as_bytes()).unwrap();
            assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]], "{u}/{v}");
            assert_eq!(
                mesh.uvs,
                vec![[[0.0, 0.5], [1.0, 0.5], [1.0, 1.0]], [[0.0, 0.5], [1.0, 1.0], [0.25, 1.0]]],
                "{u}/{v}"
            );
        }
        // `u` without `v`: read as an unknown property, no texture coordinates.
        let mesh = parse_bytes(format!("{}{body}", header("u", "w")).as_bytes()).unwrap();
        assert!(mesh.uvs.is_empty());
        assert_eq!(mesh.positions[2], Vec3::new(1.0, 1.0, 0.0));
        // A non-finite one is an error at its line (binary files: at its vertex).
        let bad = format!("{}{}", header("u", "v"), body.replace("1 1.0 1 0 1.0", "1 inf 1 0 1.0"));
        let message = parse_bytes(bad.as_bytes()).unwrap_err().to_string();
        assert!(message.contains("test.ply:14:") && message.contains("texture coordinate is not finite"), "{message}");
        // Two pairs: the first of the list (u, v) wins over (s, t). Properties x s y z u v t:
        // u takes the values that were t's above, v is 0.
        let twice =
            header("s", "t").replace("property float z", "property float z\nproperty float u\nproperty float v");
        let body = body.replace(" 0.5\n", " 0.5 0 9\n").replace(" 1.0\n", " 1.0 0 9\n");
        let mesh = parse_bytes(format!("{twice}{body}").as_bytes()).unwrap();
        assert_eq!(mesh.uvs, vec![[[0.5, 0.0], [0.5, 0.0], [1.0, 0.0]], [[0.5, 0.0], [1.0, 0.0], [1.0, 0.0]]]);
    }

    /// Binary files: both endiannesses, doubles among floats.
    #[test]
    fn binary_texture_coordinates() {
        for big_endian in [false, true] {
            let format = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
            let mut data = format!(
                "ply\nformat {format} 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nproperty double s\nproperty float t\nelement face 1\n\
                 property list uchar int vertex_indices\nend_header\n"
            )
            .into_bytes();
            let mut put = |bytes: &[u8]| {
                if big_endian {
                    data.extend(bytes.iter().rev());
                } else {
                    data.extend_from_slice(bytes);
                }
            };
            for (i, (s, t)) in [(0.5f64, 0.0f32), (0.75, 0.25), (1.0, 1.0)].into_iter().enumerate() {
                for c in [i as f32, 0.0, 0.0] {
                    put(&c.to_le_bytes());
                }
                put(&s.to_le_bytes());
                put(&t.to_le_bytes());
            }
            put(&[3]);
            for i in [2i32, 0, 1] {
                put(&i.to_le_bytes());
            }
            let mesh = parse_bytes(&data).unwrap();
            assert_eq!(mesh.uvs, vec![[[1.0, 1.0], [0.5, 0.0], [0.75, 0.25]]], "{format}");
        }
    }

    #[test]
    fn truncated_binary_reports_counts() {
        let data = binary_quad(false);
        let cut = data.len() - 12 - 4;
        let message = parse_bytes(&data[..cut]).unwrap_err().to_string();
        assert!(message.contains("file ends after 0 of 1 faces"), "{message}");
        let message = parse_bytes(&data[..data.len() - 80]).unwrap_err().to_string();
        assert!(message.contains("file ends after 2 of 4 vertices"), "{message}");
        let message = parse_bytes(&data[..data.len() - 1]).unwrap_err().to_string();
        assert!(message.contains("file ends inside the 2 edges"), "{message}");
    }

    #[test]
    fn errors_name_file_and_line() {
        let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                      element face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let cases = [
            (format!("{header}0 0 0\n1 0 0\n1 1 0\n3 0 1 3\n"), "test.ply:13:", "out of range"),
            (format!("{header}0 0 0\n1 0 0\n1 1 0\n3 0 1 -1\n"), "test.ply:13:", "out of range"),
            (format!("{header}0 0 0\n1 nan 0\n1 1 0\n3 0 1 2\n"), "test.ply:11:", "not finite"),
            (format!("{header}0 0 0\n1 0 0\n1 1\n3 0 1 2\n"), "test.ply:12:", "too few values"),
            (format!("{header}0 0 0\n1 0 0\n1 1 0\n2 0 1\n"), "test.ply:13:", "at least 3"),
            (format!("{header}0 0 0\n1 0 0\n"), "test.ply:", "file ends after 2 of 3 vertices"),
            (header.replace("face 1", "face 0") + "0 0 0\n1 0 0\n1 1 0\n", "test.ply:", "no triangles"),
            (header.replace("ascii", "utf8"), "test.ply:2:", "bad format"),
            (header.replace("float y", "float"), "test.ply:5:", "bad property"),
            (header.replace("float y", "float w"), "test.ply:3:", "x, y and z"),
            (header.replace("uchar int", "float int"), "test.ply:8:", "bad property"),
            (header.replace("element vertex 3", "element vertex -3"), "test.ply:3:", "bad element"),
            (header.replace("end_header\n", ""), "test.ply:9:", "end_header"),
            (header.replace("ply\n", "plx\n"), "test.ply:1:", "not a PLY"),
            ("ply\nformat ascii 1.0\nend_header\n".to_owned(), "test.ply:3:", "no `element vertex`"),
        ];
        for (text, location, what) in cases {
            let message = parse_bytes(text.as_bytes()).unwrap_err().to_string();
            assert!(message.starts_with(location) && message.contains(what), "{text:?}: {message}");
        }
    }

    #[test]
    fn binary_index_out_of_range_and_nan() {
        let mut data = binary_quad(false);
        let last_index = data.len() - 2 * 7 - 4;
        data[last_index..last_index + 4].copy_from_slice(&4u32.to_le_bytes());
        let message = parse_bytes(&data).unwrap_err().to_string();
        assert!(message.contains("face 0: vertex index 4 out of range (4 vertices)"), "{message}");
        let mut data = binary_quad(false);
        let header_len = data.len() - 4 * 24 - 18 - 14;
        data[header_len..header_len + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
        let message = parse_bytes(&data).unwrap_err().to_string();
        assert!(message.contains("vertex 0: coordinate is not finite"), "{message}");
    }

    #[test]
    fn lying_headers_do_not_panic_or_overallocate() {
        let huge = format!("ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uint uint vertex_indices\nend_header\n", u32::MAX);
        assert!(parse_bytes(huge.as_bytes()).is_err());
        let mut data = binary_quad(false);
        let flags_at = data.len() - 14 - 16 - 2;
        data[flags_at + 1] = 255; // 255 corners announced, only 4 present
        assert!(parse_bytes(&data).is_err());
        for cut in 0..data.len() {
            assert!(parse_bytes(&data[..cut]).is_err());
        }
    }
}
