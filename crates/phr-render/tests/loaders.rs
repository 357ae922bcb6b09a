//! `load_mesh` end to end: dispatch by extension, `.gz`, files next to the mesh, bad inputs,
//! and the real benchmark scenes of `/work/shared/scenes` (skipped when absent).

use flate2::write::GzEncoder;
use glam::Vec3;
use phr_render::load::{load_mesh, MeshData, SourceMaterial};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

const QUAD_OBJ: &str = "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl light\nf -4 -3 -2 -1\n";
const QUAD_MTL: &str = "newmtl light\nKd 0 0 0\nKe 17 12 4\n";

/// A fresh, empty directory for one test; removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("phr-loaders-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

fn check_quad(mesh: &MeshData) {
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(mesh.groups, vec!["light"]);
    let SourceMaterial::Mtl(entry) = &mesh.group_materials[0] else { panic!("no MTL entry") };
    assert_eq!(entry.ke, Some([17.0, 12.0, 4.0]));
}

#[test]
fn obj_plain_uppercase_and_gzipped() {
    let dir = TempDir::new("obj");
    dir.write("quad.mtl", QUAD_MTL);
    check_quad(&load_mesh(&dir.write("quad.obj", QUAD_OBJ)).unwrap());
    check_quad(&load_mesh(&dir.write("QUAD2.OBJ", QUAD_OBJ)).unwrap());
    // The MTL of a gzipped OBJ is still looked up next to it.
    check_quad(&load_mesh(&dir.write("quad3.obj.gz", gzip(QUAD_OBJ.as_bytes()))).unwrap());
}

#[test]
fn ply_gzipped() {
    let dir = TempDir::new("ply");
    let mut ply = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n\
        property double z\nelement face 1\nproperty list uchar ushort vertex_indices\nend_header\n"
        .to_vec();
    for v in [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        ply.extend_from_slice(&v.to_be_bytes());
    }
    ply.extend_from_slice(&[3, 0, 0, 0, 1, 0, 2]);
    let mesh = load_mesh(&dir.write("tri.PLY.GZ", gzip(&ply))).unwrap();
    assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    assert_eq!(mesh.positions[1].x, 1.0);
}

/// One triangle (36 bytes of positions) plus its three `u16` indices, padded to 44 bytes.
fn triangle_buffer() -> Vec<u8> {
    let mut buffer = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        buffer.extend_from_slice(&v.to_le_bytes());
    }
    buffer.extend_from_slice(&[0, 0, 1, 0, 2, 0, 0, 0]);
    buffer
}

/// A glTF document with one triangle translated by (0, 0, 10); `buffer` is the buffer object.
fn triangle_json(buffer: &str) -> String {
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"translation": [0, 0, 10], "mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "buffers": [{buffer}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 6}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}}]}}"#
    )
}

fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    json.resize(json.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    for word in [2, total as u32, json.len() as u32, 0x4E4F_534A] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(&json);
    for word in [bin.len() as u32, 0x004E_4942] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(bin);
    out
}

#[test]
fn gltf_with_external_buffer_and_glb() {
    let dir = TempDir::new("gltf");
    let buffer = triangle_buffer();
    dir.write("tri.bin", &buffer);
    let json = triangle_json(r#"{"byteLength": 44, "uri": "tri.bin"}"#);
    for path in [dir.write("tri.gltf", &json), dir.write("tri.gltf.gz", gzip(json.as_bytes()))] {
        let mesh = load_mesh(&path).unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
        assert_eq!(mesh.positions[2].to_array(), [0.0, 1.0, 10.0]);
        assert_eq!(mesh.groups, vec!["default"]);
        assert_eq!(mesh.group_materials, vec![SourceMaterial::None]);
    }
    let binary = glb(&triangle_json(r#"{"byteLength": 44}"#), &buffer);
    let mesh = load_mesh(&dir.write("tri.glb", binary)).unwrap();
    assert_eq!(mesh.positions[1].to_array(), [1.0, 0.0, 10.0]);
}

fn error_of(path: &Path) -> String {
    load_mesh(path).unwrap_err().to_string()
}

#[test]
fn bad_inputs_give_clear_errors() {
    let dir = TempDir::new("bad");
    let missing = dir.0.join("missing.obj");
    assert!(error_of(&missing).contains("missing.obj: cannot open the mesh file: "), "{}", error_of(&missing));
    let unknown = dir.write("mesh.stl", "solid");
    assert!(error_of(&unknown).contains("unknown mesh format"));
    assert!(error_of(&dir.write("mesh.gz", gzip(b"x"))).contains("unknown mesh format"));
    let not_gzip = dir.write("mesh.obj.gz", QUAD_OBJ);
    assert!(error_of(&not_gzip).contains("cannot decompress"), "{}", error_of(&not_gzip));

    let no_mtl = dir.write("no_mtl.obj", QUAD_OBJ);
    let message = error_of(&no_mtl);
    assert!(
        message.contains("no_mtl.obj:1: cannot open material library") && message.contains("quad.mtl"),
        "{message}"
    );

    let out_of_range = dir.write("range.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\n\nf 1 2 3\nf 1 2 7\n");
    assert!(error_of(&out_of_range).contains("range.obj:6: face index 7 out of range"), "{}", error_of(&out_of_range));
    let nan = dir.write("nan.obj", "v 0 0 0\nv 1 NaN 0\nv 1 1 0\nf 1 2 3\n");
    assert!(error_of(&nan).contains("nan.obj:2: coordinate is not finite"), "{}", error_of(&nan));
    let empty = dir.write("empty.obj", "# nothing\nv 0 0 0\n");
    assert!(error_of(&empty).ends_with("empty.obj: no triangles"), "{}", error_of(&empty));

    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                  property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";
    let mut ply = header.as_bytes().to_vec();
    ply.extend_from_slice(&[0; 36]);
    ply.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 3, 0]);
    let truncated = dir.write("cut.ply", ply);
    assert!(error_of(&truncated).ends_with("cut.ply: file ends after 1 of 2 faces"), "{}", error_of(&truncated));

    // Devices and folders are not read (a device such as /dev/zero never ends).
    let folder = dir.0.join("folder.obj");
    std::fs::create_dir_all(&folder).unwrap();
    assert!(error_of(&folder).contains("folder.obj: the mesh file is not a regular file"), "{}", error_of(&folder));
    let device_mtl = dir.write("device.obj", "mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n");
    let message = error_of(&device_mtl);
    assert!(message.contains("device.obj:1: material library /dev/zero is not a regular file"), "{message}");
}

/// A UTF-8 byte-order mark before an OBJ used to swallow the first vertex and shift every
/// index; it is skipped now, as in every editor.
#[test]
fn byte_order_mark_is_skipped() {
    let dir = TempDir::new("bom");
    let plain = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n";
    let with_bom = dir.write("bom.obj", [b"\xEF\xBB\xBF".as_slice(), plain.as_bytes()].concat());
    let mesh = load_mesh(&with_bom).unwrap();
    assert_eq!(mesh.positions, [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)]);
    assert_eq!(mesh.triangles, [[0, 1, 2]]);
}

/// A material library named many times on one `mtllib` line is read once and works.
#[test]
fn a_repeated_material_library_is_read_once() {
    let dir = TempDir::new("mtl-repeat");
    dir.write("m.mtl", "newmtl red\nKd 1 0 0\n");
    let names = vec!["m.mtl"; 10_000].join(" ");
    let obj = dir.write("r.obj", format!("mtllib {names}\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl red\nf 1 2 3\n"));
    let mesh = load_mesh(&obj).unwrap();
    assert_eq!(mesh.groups, ["red"]);
    assert!(matches!(&mesh.group_materials[0], SourceMaterial::Mtl(m) if m.kd == Some([1.0, 0.0, 0.0])));
}

/// glTF buffers: a missing one is named, one outside the asset's folder or behind another
/// URI scheme is refused, a percent-escaped name is decoded.
#[test]
fn gltf_buffers_are_named_and_confined() {
    let dir = TempDir::new("gltf-buffers");
    let tri: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.].iter().flat_map(|f| f.to_le_bytes()).collect();
    let gltf = |uri: &str| {
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
  "buffers": [{{"byteLength": 36, "uri": "{uri}"}}]}}"#
        )
    };
    dir.write("my tri.bin", &tri);
    let ok = dir.write("ok.gltf", gltf("my%20tri.bin"));
    assert_eq!(load_mesh(&ok).unwrap().triangles.len(), 1);
    let missing = dir.write("missing.gltf", gltf("gone.bin"));
    let message = error_of(&missing);
    assert!(message.contains("gone.bin: cannot open buffer 0 of") && message.contains("missing.gltf"), "{message}");
    // 48 levels of two nodes, each with both nodes of the next level as children: 2⁴⁸ paths
    // to the one triangle at the bottom. Refused before anything is instanced.
    let mut nodes: Vec<String> =
        (0..47).flat_map(|l| [0, 1].map(|_| format!(r#"{{"children": [{}, {}]}}"#, 2 * l + 2, 2 * l + 3))).collect();
    nodes.extend([r#"{"mesh": 0}"#.to_string(), r#"{"mesh": 0}"#.to_string()]);
    let bomb =
        gltf("my%20tri.bin").replace(r#""nodes": [{"mesh": 0}]"#, &format!(r#""nodes": [{}]"#, nodes.join(", ")));
    let bomb =
        dir.write("bomb.gltf", bomb.replace(r#""scenes": [{"nodes": [0]}]"#, r#""scenes": [{"nodes": [0, 1]}]"#));
    let message = error_of(&bomb);
    assert!(message.contains("bomb.gltf: the node hierarchy instances") && message.contains("more than"), "{message}");
    for (name, uri, needle) in [
        ("up.gltf", "../secret.bin", "leaves the asset's folder"),
        ("abs.gltf", "/etc/passwd", "leaves the asset's folder"),
        ("scheme.gltf", "http://example.com/x.bin", "URI scheme"),
        ("escape.gltf", "%FF%FE.bin", "not UTF-8"),
    ] {
        let file = dir.write(name, gltf(uri));
        let message = error_of(&file);
        assert!(message.contains(&format!("{name}: buffer 0: `{uri}`")) && message.contains(needle), "{message}");
    }
}

/// The benchmark scenes; prints load times (run with `--nocapture` to see them).
#[test]
fn real_scenes() {
    let scenes = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/scenes"));
    assert!(scenes.is_dir(), "missing {} (shared/ must sit next to the repository)", scenes.display());
    let cases = [
        ("bunny/bun_zipper.ply", 69_451, Some(35_947)),
        ("sponza/sponza.obj", 66_445, Some(66_350)),
        ("sibenik/sibenik.obj", 73_564, Some(40_259)),
        ("sibenik/sibenik_75284_geometry.ply", 75_284, Some(40_981)),
        // 72 `v` lines: the README's 24 misses the ones written `v<TAB>`.
        ("cornell_box/CornellBox-Original.obj", 36, Some(72)),
        ("dragon/dragon_vrip.ply", 871_414, Some(437_645)),
        ("conference/conference_geometry.ply", 331_179, Some(194_399)),
    ];
    for (file, triangles, vertices) in cases {
        let start = Instant::now();
        let mesh = load_mesh(&scenes.join(file)).unwrap();
        eprintln!("{file}: {} triangles in {:.1} ms", mesh.triangle_count(), start.elapsed().as_secs_f64() * 1e3);
        assert_eq!(mesh.triangle_count(), triangles, "{file}");
        if let Some(vertices) = vertices {
            assert_eq!(mesh.positions.len(), vertices, "{file}");
        }
    }
    let cornell = load_mesh(&scenes.join("cornell_box/CornellBox-Original.obj")).unwrap();
    let light = cornell.groups.iter().position(|g| g == "light").expect("group `light`");
    let SourceMaterial::Mtl(entry) = &cornell.group_materials[light] else { panic!("light has no MTL entry") };
    assert_eq!(entry.ke, Some([17.0, 12.0, 4.0]));
}
