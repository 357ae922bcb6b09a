//! Wavefront OBJ and MTL reader, written by hand so every error carries its line number.
//!
//! Reads `v` (the first three coordinates), `vt` (texture coordinates), `f` (the `v`, `v/vt`,
//! `v//vn` and `v/vt/vn` forms, positive and negative indices, polygons fan-triangulated),
//! `usemtl` (one group per material name, in first-use order; faces before any `usemtl` go to
//! group `default`) and `mtllib` (paths relative to the OBJ's folder). `g`, `o`, `s`, `vn`,
//! lines and points are ignored: the renderer flat-shades and groups by material only.
//!
//! Limits: no line continuation (`\`), no free-form geometry, file names without spaces in
//! `mtllib`. From MTL files only `Kd Ks Ke Tf Ns Ni d Tr illum map_Kd map_d` are read (see
//! [`MtlEntry`]); map options (`-s`, `-o`, ...) are skipped, the file is the last word.

use super::{check_finite, finish, Location, MeshData, MtlEntry, MtlLibrary, SourceMaterial};
use crate::error::LoadError;
use glam::Vec3;
use std::collections::HashMap;
use std::path::Path;
use std::str::SplitAsciiWhitespace;

/// Parses an OBJ file held in memory; `base_dir` is where `mtllib` paths are resolved.
pub(super) fn parse(path: &Path, base_dir: &Path, bytes: &[u8]) -> Result<MeshData, LoadError> {
    let text = String::from_utf8_lossy(super::input::strip_bom(bytes));
    let mut parser = Parser::new(path, base_dir);
    for (i, line) in text.lines().enumerate() {
        parser.line(line, i + 1)?;
    }
    parser.finish()
}

/// The parser's state between lines.
struct Parser<'a> {
    path: &'a Path,
    base_dir: &'a Path,
    mesh: MeshData,
    library: MtlLibrary,
    /// The material libraries read so far.
    libraries_read: std::collections::HashSet<std::path::PathBuf>,
    /// Group index by name.
    group_index: HashMap<String, u32>,
    /// The name given by the last `usemtl`, if any.
    material: Option<String>,
    /// The group faces currently go to; resolved at the first face after a `usemtl`.
    group: Option<u32>,
    /// The largest positive (1-based) face index seen, and its line (0 and 0 before any):
    /// positive indices may refer to vertices defined later, so they are checked at the end.
    max_index: (u64, usize),
    /// `vt` coordinates so far.
    texcoords: Vec<[f32; 2]>,
    /// Each triangle's corners' `vt` indices (0-based; [`NO_VT`] where a corner has none).
    triangle_vt: Vec<[u32; 3]>,
    /// Like `max_index`, for `vt` indices.
    max_vt: (u64, usize),
}

/// A face corner without a texture coordinate.
const NO_VT: u32 = u32::MAX;

impl<'a> Parser<'a> {
    fn new(path: &'a Path, base_dir: &'a Path) -> Self {
        Self {
            path,
            base_dir,
            mesh: MeshData::default(),
            library: MtlLibrary::new(),
            libraries_read: Default::default(),
            group_index: HashMap::new(),
            material: None,
            group: None,
            max_index: (0, 0),
            texcoords: Vec::new(),
            triangle_vt: Vec::new(),
            max_vt: (0, 0),
        }
    }

    fn line(&mut self, line: &str, line_no: usize) -> Result<(), LoadError> {
        let line = strip_comment(line);
        let mut tokens = line.split_ascii_whitespace();
        match tokens.next() {
            Some("v") => self.vertex(tokens, line_no),
            Some("vt") => self.texcoord(tokens, line_no),
            Some("f") => self.face(tokens, line_no),
            Some("usemtl") => self.use_material(rest_after_keyword(line, "usemtl"), line_no),
            Some("mtllib") => self.material_library(tokens, line_no),
            _ => Ok(()),
        }
    }

    fn error(&self, line_no: usize, message: impl Into<String>) -> LoadError {
        LoadError::at_line(self.path, line_no, message)
    }

    fn vertex(&mut self, mut tokens: SplitAsciiWhitespace, line_no: usize) -> Result<(), LoadError> {
        let mut xyz = [0.0f32; 3];
        for value in &mut xyz {
            let token = tokens.next().ok_or_else(|| self.error(line_no, "vertex needs 3 coordinates"))?;
            *value = token.parse().map_err(|_| self.error(line_no, format!("bad number `{token}`")))?;
        }
        let p = Vec3::from(xyz);
        check_finite(self.path, p, Location::Line(line_no))?;
        if self.mesh.positions.len() >= u32::MAX as usize {
            return Err(self.error(line_no, "too many vertices"));
        }
        self.mesh.positions.push(p);
        Ok(())
    }

    /// `vt u [v [w]]`: the first two (v is 0 when missing).
    fn texcoord(&mut self, mut tokens: SplitAsciiWhitespace, line_no: usize) -> Result<(), LoadError> {
        let mut uv = [0.0f32; 2];
        for (k, value) in uv.iter_mut().enumerate() {
            let Some(token) = tokens.next() else {
                if k == 0 {
                    return Err(self.error(line_no, "texture coordinate needs at least u"));
                }
                break;
            };
            *value = token.parse().map_err(|_| self.error(line_no, format!("bad number `{token}`")))?;
            if !value.is_finite() {
                return Err(self.error(line_no, format!("texture coordinate `{token}` is not finite")));
            }
        }
        if self.texcoords.len() >= u32::MAX as usize - 1 {
            return Err(self.error(line_no, "too many texture coordinates"));
        }
        self.texcoords.push(uv);
        Ok(())
    }

    /// A polygon, fan-triangulated as (v0, vk, vk+1).
    fn face(&mut self, tokens: SplitAsciiWhitespace, line_no: usize) -> Result<(), LoadError> {
        let group = self.current_group();
        let mut first = None;
        let mut previous = None;
        let mut count = 0usize;
        for token in tokens {
            let v = (self.vertex_index(token, line_no)?, self.texcoord_index(token, line_no)?);
            if let (Some(a), Some(b)) = (first, previous) {
                let ((a, ta), (b, tb), (c, tc)): ((u32, u32), (u32, u32), (u32, u32)) = (a, b, v);
                self.mesh.triangles.push([a, b, c]);
                self.mesh.triangle_group.push(group);
                self.triangle_vt.push([ta, tb, tc]);
            }
            if first.is_none() {
                first = Some(v);
            } else {
                previous = Some(v);
            }
            count += 1;
        }
        if count < 3 {
            return Err(self.error(line_no, format!("face has {count} vertices, needs at least 3")));
        }
        Ok(())
    }

    /// The 0-based vertex index of one face corner (`v`, `v/vt`, `v//vn` or `v/vt/vn`).
    fn vertex_index(&mut self, token: &str, line_no: usize) -> Result<u32, LoadError> {
        let text = token.split('/').next().unwrap_or(token);
        let index: i64 = text.parse().map_err(|_| self.error(line_no, format!("bad vertex index `{token}`")))?;
        let defined = self.mesh.positions.len();
        let resolved = resolve_index(index, defined, line_no, &mut self.max_index);
        resolved
            .map_err(|problem| self.error(line_no, format!("face index {index} {problem} ({defined} vertices so far)")))
    }

    /// The 0-based `vt` index of one face corner ([`NO_VT`] without one).
    fn texcoord_index(&mut self, token: &str, line_no: usize) -> Result<u32, LoadError> {
        let Some(text) = token.split('/').nth(1).filter(|t| !t.is_empty()) else { return Ok(NO_VT) };
        let index: i64 = text.parse().map_err(|_| self.error(line_no, format!("bad texture index `{token}`")))?;
        let defined = self.texcoords.len();
        let resolved = resolve_index(index, defined, line_no, &mut self.max_vt).and_then(|i| {
            if i == NO_VT {
                Err("out of range")
            } else {
                Ok(i)
            }
        });
        resolved.map_err(|problem| {
            self.error(line_no, format!("texture coordinate index {index} {problem} ({defined} so far)"))
        })
    }

    /// The group of the current `usemtl` name, created at its first face.
    fn current_group(&mut self) -> u32 {
        if let Some(group) = self.group {
            return group;
        }
        let name = self.material.as_deref().unwrap_or("default");
        let group = match self.group_index.get(name) {
            Some(&group) => group,
            None => {
                let group = self.mesh.groups.len() as u32;
                self.mesh.groups.push(name.to_owned());
                self.group_index.insert(name.to_owned(), group);
                group
            }
        };
        self.group = Some(group);
        group
    }

    fn use_material(&mut self, name: &str, line_no: usize) -> Result<(), LoadError> {
        if name.is_empty() {
            return Err(self.error(line_no, "usemtl without a material name"));
        }
        if self.material.as_deref() != Some(name) {
            self.material = Some(name.to_owned());
            self.group = None;
        }
        Ok(())
    }

    fn material_library(&mut self, files: SplitAsciiWhitespace, line_no: usize) -> Result<(), LoadError> {
        let mut any = false;
        for file in files {
            any = true;
            let mtl_path = self.base_dir.join(file);
            // Each library is read once per load, however often it is named.
            if !self.libraries_read.insert(mtl_path.clone()) {
                continue;
            }
            let what = format!("material library {}", mtl_path.display());
            let bytes = super::input::read_file(&mtl_path, &what).map_err(|e| self.error(line_no, e.message))?;
            // Later definitions of the same name win, as in most readers.
            self.library.extend(parse_mtl(&mtl_path, &bytes)?);
        }
        if !any {
            return Err(self.error(line_no, "mtllib without a file name"));
        }
        Ok(())
    }

    fn finish(mut self) -> Result<MeshData, LoadError> {
        let vertex_count = self.mesh.positions.len() as u64;
        let (index, line_no) = self.max_index;
        if index > vertex_count {
            let message = format!("face index {index} out of range ({vertex_count} vertices)");
            return Err(self.error(line_no, message));
        }
        let (index, line_no) = self.max_vt;
        if index > self.texcoords.len() as u64 {
            let message = format!("texture coordinate index {index} out of range ({} of them)", self.texcoords.len());
            return Err(self.error(line_no, message));
        }
        if self.triangle_vt.iter().flatten().any(|&t| t != NO_VT) {
            let texcoords = &self.texcoords;
            let uv = |t: u32| if t == NO_VT { [0.0; 2] } else { texcoords[t as usize] };
            self.mesh.uvs = self.triangle_vt.iter().map(|t| t.map(uv)).collect();
        }
        let library = &self.library;
        self.mesh.group_materials = (self.mesh.groups.iter())
            .map(|name| library.get(name).cloned().map_or(SourceMaterial::None, SourceMaterial::Mtl))
            .collect();
        finish(self.path, self.mesh)
    }
}

/// A 1-based OBJ index (negative: counted back from the `defined` items so far) made 0-based.
/// Positive ones may name items defined later: the largest, with its line, goes to `max` to
/// be checked at the end. The error is what is wrong with it.
fn resolve_index(index: i64, defined: usize, line_no: usize, max: &mut (u64, usize)) -> Result<u32, &'static str> {
    match index {
        0 => Err("is invalid: OBJ indices start at 1"),
        1.. => {
            let zero_based = u32::try_from(index - 1).map_err(|_| "out of range")?;
            if index as u64 > max.0 {
                *max = (index as u64, line_no);
            }
            Ok(zero_based)
        }
        _ => {
            let resolved = (defined as i64).checked_add(index).filter(|&i| i >= 0);
            resolved.and_then(|i| u32::try_from(i).ok()).ok_or("out of range")
        }
    }
}

/// The line up to its first `#`.
fn strip_comment(line: &str) -> &str {
    line.split_once('#').map_or(line, |(before, _)| before)
}

/// What follows the first token `keyword` of `line`, trimmed (names may contain spaces).
fn rest_after_keyword<'l>(line: &'l str, keyword: &str) -> &'l str {
    let line = line.trim_start_matches(|c: char| c.is_ascii_whitespace());
    line.strip_prefix(keyword).unwrap_or("").trim_matches(|c: char| c.is_ascii_whitespace())
}

/// Parses an MTL file held in memory; `path` is only used in error messages.
pub(super) fn parse_mtl(path: &Path, bytes: &[u8]) -> Result<MtlLibrary, LoadError> {
    let text = String::from_utf8_lossy(super::input::strip_bom(bytes));
    let mut library = MtlLibrary::new();
    let mut current: Option<MtlBuilder> = None;
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = strip_comment(line);
        let mut tokens = line.split_ascii_whitespace();
        let Some(key) = tokens.next() else { continue };
        if key == "newmtl" {
            let name = rest_after_keyword(line, "newmtl");
            if name.is_empty() {
                return Err(LoadError::at_line(path, line_no, "newmtl without a name"));
            }
            if let Some(done) = current.replace(MtlBuilder::new(name)) {
                done.insert_into(&mut library);
            }
        } else if let Some(material) = &mut current {
            let mut values = Values { tokens, path, line_no };
            material.set(key, &mut values)?;
        }
        // Keys before the first `newmtl` belong to no material: ignored.
    }
    if let Some(done) = current {
        done.insert_into(&mut library);
    }
    Ok(library)
}

/// One MTL entry being read.
struct MtlBuilder {
    name: String,
    entry: MtlEntry,
    /// `Tr` (transparency), used as `d = 1 - Tr` when the entry has no `d`.
    tr: Option<f32>,
}

impl MtlBuilder {
    fn new(name: &str) -> Self {
        Self { name: name.to_owned(), entry: MtlEntry::default(), tr: None }
    }

    fn set(&mut self, key: &str, values: &mut Values) -> Result<(), LoadError> {
        let entry = &mut self.entry;
        match key {
            "Kd" => entry.kd = Some(values.rgb()?),
            "Ks" => entry.ks = Some(values.rgb()?),
            "Ke" => entry.ke = Some(values.rgb()?),
            "Tf" => entry.tf = Some(values.rgb()?),
            "Ns" => entry.ns = Some(values.number()?),
            "Ni" => entry.ni = Some(values.number()?),
            "d" => entry.d = Some(values.skip_halo().number()?),
            "Tr" => self.tr = Some(values.number()?),
            "illum" => entry.illum = Some(values.integer()?),
            "map_Kd" => entry.map_kd = Some(values.file()?),
            "map_d" => entry.map_d = Some(values.file()?),
            _ => {} // Ka, other map_*, bump, ...: not used by the renderer.
        }
        Ok(())
    }

    fn insert_into(mut self, library: &mut MtlLibrary) {
        if self.entry.d.is_none() {
            self.entry.d = self.tr.map(|tr| 1.0 - tr);
        }
        library.insert(self.name, self.entry);
    }
}

/// The values after an MTL key, with what is needed for error messages.
struct Values<'a> {
    tokens: SplitAsciiWhitespace<'a>,
    path: &'a Path,
    line_no: usize,
}

impl Values<'_> {
    fn error(&self, message: impl Into<String>) -> LoadError {
        LoadError::at_line(self.path, self.line_no, message)
    }

    /// A texture file: the last word (options such as `-s 1 1 1` come first), relative to
    /// the MTL file's folder.
    fn file(&mut self) -> Result<std::path::PathBuf, LoadError> {
        let name = self.tokens.clone().last().ok_or_else(|| self.error("texture map without a file name"))?;
        Ok(self.path.parent().unwrap_or(Path::new("")).join(name))
    }

    /// A finite number.
    fn number(&mut self) -> Result<f32, LoadError> {
        let token = self.tokens.next().ok_or_else(|| self.error("missing value"))?;
        match token.parse::<f32>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.error(format!("bad number `{token}`"))),
        }
    }

    /// `r g b`, or a single `r` meaning grey.
    fn rgb(&mut self) -> Result<[f32; 3], LoadError> {
        let r = self.number()?;
        if self.tokens.clone().next().is_none() {
            return Ok([r; 3]);
        }
        Ok([r, self.number()?, self.number()?])
    }

    fn integer(&mut self) -> Result<u32, LoadError> {
        let token = self.tokens.next().ok_or_else(|| self.error("missing value"))?;
        token.parse().map_err(|_| self.error(format!("bad integer `{token}`")))
    }

    /// Skips the `-halo` option of `d`.
    fn skip_halo(&mut self) -> &mut Self {
        if self.tokens.clone().next() == Some("-halo") {
            self.tokens.next();
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn parse_str(text: &str) -> Result<MeshData, LoadError> {
        parse(Path::new("test.obj"), Path::new("/nonexistent"), text.as_bytes())
    }

    #[test]
    fn triangle_and_quad_with_all_index_forms() {
        let mesh = parse_str(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
             f 1 2 3\nf 1/1 2/1 3/1 4/1\nf 1//1 2//1 3//1\nf 1/1/1 2/1/1 3/1/1 # comment\n",
        )
        .unwrap();
        assert_eq!(mesh.positions.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 1, 2]]);
        assert_eq!(mesh.groups, vec!["default"]);
        assert_eq!(mesh.group_materials, vec![SourceMaterial::None]);
        assert_eq!(mesh.triangle_group, vec![0; 5]);
        // Texture coordinates where corners name them, zeros elsewhere.
        assert_eq!(mesh.uvs.len(), 5);
        assert_eq!(mesh.uvs[0], [[0.0; 2]; 3]);
    }

    #[test]
    fn texture_coordinates_follow_the_corners() {
        let mesh = parse_str(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0 0\nvt 1 1\nvt 0.5\n\
             f 1/1 2/2 3/3 4/-1\n",
        )
        .unwrap();
        assert_eq!(mesh.uvs, vec![[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], [[0.0, 0.0], [1.0, 1.0], [0.5, 0.0]]]);
        assert!(parse_str("v 0 0 0\nf 1 1 1\n").unwrap().uvs.is_empty(), "no vt: no uvs");
    }

    #[test]
    fn negative_indices_and_ngon_fan() {
        let mesh = parse_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 1 0\nf -5 -4 -3 -2 -1\n").unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    }

    #[test]
    fn groups_follow_usemtl_first_use_order() {
        let mesh = parse_str(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\ng box\no thing\nusemtl red\nf 1 2 3\n\
             usemtl blue\nf 1 2 3\nusemtl red\nf 1 2 3\nusemtl unused\n",
        )
        .unwrap();
        assert_eq!(mesh.groups, vec!["default", "red", "blue"]);
        assert_eq!(mesh.triangle_group, vec![0, 1, 2, 1]);
    }

    #[test]
    fn errors_carry_file_and_line() {
        let cases = [
            ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n", "test.obj:4:", "out of range"),
            ("v 0 0 0\nv 1 0 0\nf 1 2 -3\n", "test.obj:3:", "out of range"),
            ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 0\n", "test.obj:4:", "index 0"),
            ("v 0 0 0\nv 1 nan 0\n", "test.obj:2:", "not finite"),
            ("v 0 0 inf\n", "test.obj:1:", "not finite"),
            ("v 0 0\n", "test.obj:1:", "3 coordinates"),
            ("v 0 x 0\n", "test.obj:1:", "bad number"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", "test.obj:3:", "at least 3"),
            ("v 0 0 0\nf 1 a 1\n", "test.obj:2:", "bad vertex index"),
            ("v 0 0 0\n", "test.obj:", "no triangles"),
            ("", "test.obj:", "no triangles"),
            ("mtllib missing.mtl\n", "test.obj:1:", "missing.mtl"),
            ("v 0 0 0\nvt 0 0\nf 1/1 1/2 1/1\n", "test.obj:3:", "texture coordinate index 2 out of range"),
            ("v 0 0 0\nvt 0 0\nf 1/-2 1/1 1/1\n", "test.obj:3:", "out of range"),
            ("v 0 0 0\nvt 0 0\nf 1/0 1/1 1/1\n", "test.obj:3:", "index 0"),
            ("v 0 0 0\nvt 0 nan\n", "test.obj:2:", "not finite"),
            ("vt\n", "test.obj:1:", "needs at least u"),
        ];
        for (text, location, what) in cases {
            let message = parse_str(text).unwrap_err().to_string();
            assert!(message.starts_with(location) && message.contains(what), "{text:?}: {message}");
        }
    }

    #[test]
    fn forward_positive_index_is_allowed() {
        let mesh = parse_str("v 0 0 0\nf 1 2 3\nv 1 0 0\nv 1 1 0\n").unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn mtl_keys() {
        let library = parse_mtl(
            Path::new("test.mtl"),
            b"Kd 9 9 9\nnewmtl glass\n  Kd 0.1 0.2 0.3 # note\n Ks 0.5\n Ke 1 2 3\n Tf 0.9 0.9 0.9\n\
              Ns 100\n Ni 1.5\n Tr 0.25\n illum 4\n Ka 1 1 1\n map_Kd tex.png\n map_d -imfchan m leaf.png\n\
              newmtl two words\n d -halo 0.5\n Tr 0.9\n",
        )
        .unwrap();
        let glass = &library["glass"];
        assert_eq!(glass.kd, Some([0.1, 0.2, 0.3]));
        assert_eq!(glass.ks, Some([0.5; 3]));
        assert_eq!(glass.ke, Some([1.0, 2.0, 3.0]));
        assert_eq!(glass.tf, Some([0.9; 3]));
        assert_eq!((glass.ns, glass.ni, glass.d, glass.illum), (Some(100.0), Some(1.5), Some(0.75), Some(4)));
        assert_eq!(library["two words"].d, Some(0.5));
        assert_eq!(glass.map_kd, Some(PathBuf::from("tex.png")), "relative to the MTL's folder");
        assert_eq!(glass.map_d, Some(PathBuf::from("leaf.png")), "its options skipped");
        let error = parse_mtl(Path::new("test.mtl"), b"newmtl a\nKd 1 x 1\n").unwrap_err();
        assert_eq!(error.to_string(), "test.mtl:2: bad number `x`");
    }

    #[test]
    fn mtllib_is_read_relative_to_the_obj() {
        let dir = std::env::temp_dir().join(format!("phr-obj-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("m.mtl"), "newmtl light\nKe 17 12 4\n").unwrap();
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl light\nf 1 2 3\nusemtl other\nf 3 2 1\n";
        let mesh = parse(&PathBuf::from("x.obj"), &dir, obj.as_bytes()).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        let light = MtlEntry { ke: Some([17.0, 12.0, 4.0]), ..MtlEntry::default() };
        assert_eq!(mesh.group_materials, vec![SourceMaterial::Mtl(light), SourceMaterial::None]);
    }
}
