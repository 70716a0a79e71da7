//! Integration tests of `motif_core::io`: every file of the bad-input corpus fails cleanly with
//! its file and position, every format round-trips what it can hold, and PLY round-trips exactly
//! (property test).

use std::path::{Path, PathBuf};

use motif_core::error::Position;
use motif_core::io::{self, Format, Model, PlyEncoding, StlEncoding, WriteOptions};
use motif_core::{AttributeData, Error, PointCloud, TriMesh};
use proptest::prelude::*;

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/bad")
}

use Position::{Byte, Line, Whole};

/// Every corpus file, the position its error must give and a fragment of the message.
/// `Whole` is used for empty files and for problems of a `.gltf` document that have no place in
/// the file (its buffers are base64 text or other files).
const EXPECT: &[(&str, Position, &str)] = &[
    ("empty.glb", Whole, "empty"),
    ("empty.gltf", Whole, "empty"),
    ("empty.obj", Whole, "empty"),
    ("empty.off", Whole, "empty"),
    ("empty.ply", Whole, "empty"),
    ("empty.stl", Whole, "empty"),
    ("glb_accessor_count_huge.glb", Byte(552), "needs 48000000000 bytes"),
    ("glb_accessor_out_of_bounds.glb", Byte(544), "accessor 0"),
    ("glb_bad_json.glb", Byte(20), "invalid JSON"),
    ("glb_index_out_of_range.glb", Byte(584), "is 9, but there are 3 vertices"),
    ("glb_nan.glb", Byte(556), "NaN"),
    ("glb_truncated.glb", Byte(8), "truncated"),
    ("glb_version_1.glb", Byte(4), "version 1"),
    ("glb_wrong_magic.glb", Byte(0), "magic"),
    ("gltf_bad_json.gltf", Line(3), "invalid glTF JSON"),
    ("gltf_escaping_uri.gltf", Whole, "leaves the directory"),
    ("gltf_index_out_of_range.gltf", Whole, "is 5, but there are 3 vertices"),
    ("gltf_missing_buffer_file.gltf", Whole, "cannot read"),
    ("gltf_position_accessor_missing.gltf", Whole, "POSITION\"]: Index out of bounds"),
    ("gltf_version_3.gltf", Whole, "version \"3.0\" is not supported"),
    ("obj_all_degenerate.obj", Line(4), "all 2 faces are degenerate"),
    ("obj_bad_corner.obj", Line(4), "bad face corner"),
    ("obj_index_out_of_range.obj", Line(5), "vertex 4, but the file has only 3"),
    ("obj_index_zero.obj", Line(4), "index 0"),
    ("obj_inf.obj", Line(3), "NaN or infinite"),
    ("obj_nan.obj", Line(2), "NaN or infinite"),
    ("obj_no_vertices.obj", Whole, "no vertices"),
    ("obj_non_utf8.obj", Line(4), "UTF-8"),
    ("obj_non_utf8_number.obj", Line(3), "UTF-8"),
    ("obj_relative_before_start.obj", Line(3), "relative vertex index -3"),
    ("obj_short_vertex.obj", Line(2), "found 2 values"),
    ("off_4off.off", Line(1), "not supported"),
    ("off_binary.off", Line(1), "binary OFF"),
    ("off_counts_larger_than_file.off", Line(2), "1000 vertices and 2000 faces"),
    ("off_face_short.off", Line(6), "announces 4 vertices"),
    ("off_index_out_of_range.off", Line(6), "vertex 7"),
    ("off_nan.off", Line(4), "NaN or infinite"),
    ("off_truncated_faces.off", Line(7), "2 of 3 faces"),
    ("off_wrong_header.off", Line(1), "looks like PLY"),
    ("ply_all_degenerate.ply", Line(13), "all 2 faces are degenerate"),
    ("ply_binary_inf.ply", Byte(124), "NaN or infinite"),
    ("ply_face_count_huge.ply", Line(7), "3000000000 records"),
    ("ply_index_out_of_range.ply", Line(13), "vertex 3"),
    ("ply_list_count_past_end.ply", Byte(205), "material"),
    ("ply_nan.ply", Line(9), "NaN or infinite"),
    ("ply_no_end_header.ply", Whole, "end_header"),
    ("ply_non_utf8_header.ply", Line(3), "UTF-8"),
    ("ply_truncated_binary.ply", Byte(210), "truncated"),
    ("ply_unknown_type.ply", Line(4), "float128"),
    ("ply_vertex_count_4e9.ply", Line(3), "4000000000 records"),
    ("ply_wrong_magic.ply", Line(1), "not a PLY file"),
    ("stl_ascii_all_degenerate.stl", Line(2), "degenerate"),
    ("stl_ascii_bad_keyword.stl", Line(5), "vortex"),
    ("stl_ascii_truncated.stl", Line(5), "inside a facet"),
    ("stl_binary_count_huge.stl", Byte(184), "4000000000 triangles"),
    ("stl_binary_nan.stl", Byte(108), "NaN"),
    ("stl_binary_truncated.stl", Byte(134), "truncated"),
    ("stl_binary_truncated_solid_header.stl", Byte(134), "truncated"),
    ("stl_too_short.stl", Byte(14), "too short"),
];

#[test]
fn every_bad_file_is_a_parse_error_with_file_and_position() {
    let dir = corpus();
    let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
        .expect("the corpus directory exists")
        .map(|e| e.expect("readable entry").file_name().to_string_lossy().into_owned())
        .collect();
    on_disk.sort();
    let listed: Vec<String> = EXPECT.iter().map(|(n, _, _)| n.to_string()).collect();
    assert_eq!(on_disk, listed, "tests/corpus/bad and EXPECT must list the same files");

    let mut wrong = Vec::new();
    for &(name, want_pos, fragment) in EXPECT {
        let file = dir.join(name);
        match io::read(&file) {
            Ok(m) => wrong.push(format!("{name}: read without error ({} vertices)", m.vertices.len())),
            Err(e @ Error::Parse { .. }) => {
                let text = e.to_string();
                let Error::Parse { path, position, message } = e else { unreachable!() };
                if path != file || !text.contains(name) {
                    wrong.push(format!("{name}: the error does not name the file: {text}"));
                }
                if position != want_pos
                    || !text.contains(&format!("{}: {}", file.display(), position.prefix()))
                {
                    wrong.push(format!("{name}: position {position:?}, expected {want_pos:?}: {text}"));
                }
                if !message.contains(fragment) {
                    wrong.push(format!("{name}: message lacks {fragment:?}: {text}"));
                }
            }
            Err(e) => wrong.push(format!("{name}: expected Error::Parse, got {e:?}")),
        }
        // The same bytes from memory fail the same way (except external buffers, which cannot be
        // read from memory at all).
        let bytes = std::fs::read(&file).expect("corpus file is readable");
        let format = Format::from_path(&file).expect("corpus files have known extensions");
        assert!(io::read_from_bytes(&bytes, format, &file).is_err(), "{name} read from memory");
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// A 4×4 grid mesh with every kind of per-vertex data. Positions are multiples of 1/8 (exact in
/// f32) plus one awkward f64 in `z` unless `f32_exact`.
fn sample(f32_exact: bool) -> Model {
    let mut positions = Vec::new();
    for j in 0..4 {
        for i in 0..4 {
            let z = if f32_exact { 0.125 * ((i * j) as f64) } else { 0.1 * (i * j) as f64 + 1e-9 / 3.0 };
            positions.push([i as f64 * 0.5 - 1.0, j as f64 * 0.25, z]);
        }
    }
    let mut triangles = Vec::new();
    for j in 0..3u32 {
        for i in 0..3u32 {
            let v = j * 4 + i;
            triangles.push([v, v + 1, v + 5]);
            triangles.push([v, v + 5, v + 4]);
        }
    }
    let n = positions.len();
    let normals = (0..n).map(|k| {
        let a = k as f64 * 0.37;
        [a.cos() * 0.6, a.sin() * 0.6, 0.8]
    });
    let mut cloud = PointCloud {
        positions,
        normals: Some(normals.collect()),
        colors: Some((0..n).map(|k| [(k * 17) as u8, 255 - (k * 13) as u8, (k * 71 % 256) as u8]).collect()),
        attributes: Vec::new(),
    };
    cloud.set_attribute("label", AttributeData::Int((0..n as i64).map(|k| k * 1_000_003 - 7).collect()));
    cloud.set_attribute("k1", AttributeData::Float((0..n).map(|k| (k as f64).sqrt() / 7.0).collect()));
    Model { source_faces: triangles.len(), vertices: cloud, triangles, format: Format::Ply, warnings: vec![] }
}

fn write_read(model: &Model, file: &str, options: &WriteOptions) -> Model {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join(file);
    io::write(&path, model, options).unwrap_or_else(|e| panic!("writing {file}: {e}"));
    let back = io::read(&path).unwrap_or_else(|e| panic!("reading {file} back: {e}"));
    assert!(back.warnings.is_empty(), "{file}: {:?}", back.warnings);
    back
}

fn assert_normals_close(a: &[[f64; 3]], b: &[[f64; 3]], tol: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (x, y) in a.iter().zip(b) {
        assert!((0..3).all(|k| (x[k] - y[k]).abs() <= tol), "{what}: {x:?} vs {y:?}");
    }
}

#[test]
fn ply_round_trips_everything_in_every_encoding() {
    let m = sample(false);
    for enc in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian, PlyEncoding::BinaryBigEndian] {
        let back = write_read(&m, "m.ply", &WriteOptions { ply: enc, ..Default::default() });
        let what = format!("{enc:?}");
        assert_eq!(back.vertices.positions, m.vertices.positions, "{what}");
        assert_eq!(back.triangles, m.triangles, "{what}");
        assert_eq!(back.source_faces, m.triangles.len(), "{what}");
        assert_eq!(back.vertices.colors, m.vertices.colors, "{what}");
        assert_eq!(back.vertices.attributes, m.vertices.attributes, "{what}");
        // Normals are stored as float.
        let (a, b) = (back.vertices.normals.unwrap(), m.vertices.normals.clone().unwrap());
        assert_normals_close(&a, &b, 1e-7, &what);
        assert_eq!(back.format, Format::Ply);
    }
}

#[test]
fn obj_and_off_round_trip_positions_normals_colours_exactly() {
    let m = sample(false);
    for file in ["m.obj", "m.off"] {
        let back = write_read(&m, file, &WriteOptions::default());
        assert_eq!(back.vertices.positions, m.vertices.positions, "{file}");
        assert_eq!(back.vertices.normals, m.vertices.normals, "{file}");
        assert_eq!(back.vertices.colors, m.vertices.colors, "{file}");
        assert_eq!(back.triangles, m.triangles, "{file}");
        assert!(back.vertices.attributes.is_empty(), "{file} has no named attributes");
    }
}

#[test]
fn stl_round_trips_triangles_in_both_encodings() {
    let m = sample(true);
    for stl in [StlEncoding::Binary, StlEncoding::Ascii] {
        let back = write_read(&m, "m.stl", &WriteOptions { stl, ..Default::default() });
        // Every grid vertex is used, positions are distinct: welding restores the 16 vertices.
        assert_eq!(back.vertices.len(), m.vertices.len(), "{stl:?}");
        assert_eq!(back.triangles.len(), m.triangles.len(), "{stl:?}");
        for (t, u) in back.triangles.iter().zip(&m.triangles) {
            for k in 0..3 {
                assert_eq!(
                    back.vertices.positions[t[k] as usize], m.vertices.positions[u[k] as usize],
                    "{stl:?}"
                );
            }
        }
    }
}

#[test]
fn gltf_and_glb_round_trip() {
    let m = sample(true);
    for file in ["m.glb", "m.gltf"] {
        let back = write_read(&m, file, &WriteOptions::default());
        assert_eq!(back.vertices.positions, m.vertices.positions, "{file}");
        assert_eq!(back.vertices.colors, m.vertices.colors, "{file}");
        assert_eq!(back.triangles, m.triangles, "{file}");
        let (a, b) = (back.vertices.normals.unwrap(), m.vertices.normals.clone().unwrap());
        assert_normals_close(&a, &b, 1e-7, file);
    }
}

#[test]
fn point_clouds_round_trip_and_stl_refuses_them() {
    let cloud = sample(true).vertices;
    let dir = tempfile::tempdir().expect("temp dir");
    for file in ["p.ply", "p.obj", "p.off", "p.glb"] {
        let path = dir.path().join(file);
        io::write_point_cloud(&path, &cloud).unwrap();
        let model = io::read(&path).unwrap();
        assert!(!model.is_mesh(), "{file}");
        assert_eq!(model.vertices.positions, cloud.positions, "{file}");
        assert_eq!(model.vertices.colors, cloud.colors, "{file}");
        let e = io::read_mesh(&path).unwrap_err();
        assert!(e.to_string().contains(file) && e.to_string().contains("no faces"), "{e}");
        assert_eq!(io::read_point_cloud(&path).unwrap().positions, cloud.positions);
    }
    let path = dir.path().join("p.stl");
    assert!(matches!(io::write_point_cloud(&path, &cloud), Err(Error::InvalidInput(_))));
    assert!(!path.exists(), "a refused write leaves no file");
}

#[test]
fn meshes_write_and_read_through_the_convenience_functions() {
    let mesh = sample(true).into_mesh();
    let dir = tempfile::tempdir().expect("temp dir");
    for ext in ["obj", "ply", "off", "stl", "gltf", "glb"] {
        let path = dir.path().join(format!("m.{ext}"));
        io::write_mesh(&path, &mesh).unwrap();
        let back: TriMesh = io::read_mesh(&path).unwrap();
        assert_eq!(back.triangles.len(), mesh.triangles.len(), "{ext}");
        assert_eq!(Model::from_mesh(&back).mesh(), back, "{ext}");
    }
    // Nothing but the six files: the temporary files are gone.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 6);
}

#[test]
fn formats_come_from_extensions_and_are_checked_by_content() {
    assert_eq!(Format::from_path(Path::new("a/B.PLY")).unwrap(), Format::Ply);
    assert_eq!(Format::from_path(Path::new("x.glb")).unwrap(), Format::Glb);
    let e = Format::from_path(Path::new("x.fbx")).unwrap_err();
    assert!(matches!(&e, Error::UnsupportedFormat { extension, .. } if extension == "fbx"), "{e:?}");
    assert!(matches!(io::read(Path::new("noext")), Err(Error::UnsupportedFormat { .. })));
    assert!(matches!(io::read(Path::new("/no/such/file.ply")), Err(Error::Io { .. })));

    // An OBJ saved as .ply is refused, with a hint.
    let e = io::read_from_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", Format::Ply, Path::new("x.ply"))
        .unwrap_err();
    assert!(e.to_string().contains("looks like OBJ"), "{e}");
}

#[test]
fn a_utf8_byte_order_mark_before_text_is_skipped() {
    // Read as text, the mark would hide the first vertex and shift every index after it.
    let obj = b"\xEF\xBB\xBFv 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let m = io::read_from_bytes(obj, Format::Obj, Path::new("bom.obj")).unwrap();
    assert_eq!(m.vertices.positions.len(), 4);
    assert_eq!(m.vertices.positions[0], [9.0, 9.0, 9.0]);
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    let stl = b"\xEF\xBB\xBFsolid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    let m = io::read_from_bytes(stl, Format::Stl, Path::new("bom.stl")).unwrap();
    assert_eq!((m.vertices.positions.len(), m.triangles.len()), (3, 1));
}

#[test]
fn ascii_stl_keywords_are_read_in_any_case() {
    // Some exporters write upper-case keywords; read as binary, the header announced 1.3e9
    // triangles and the file was called truncated.
    let stl = b"SOLID A\nFACET NORMAL 0 0 1\n OUTER LOOP\n  VERTEX 0 0 0\n  Vertex 1 0 0\n  VERTEX 0 1 0\n ENDLOOP\nENDFACET\nEndSolid A\n";
    let m = io::read_from_bytes(stl, Format::Stl, Path::new("upper.stl")).unwrap();
    assert_eq!((m.vertices.positions.len(), m.triangles.len()), (3, 1));
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
}

#[test]
fn ply_triangle_strips_are_read_and_face_one_way() {
    // Four vertices of a unit square; one strip, then the same square as two strips split by −1
    // with a degenerate join (2, 2) that adds nothing.
    let head = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
                element tristrips 1\nproperty list int int vertex_indices\nend_header\n\
                0 0 0\n1 0 0\n0 1 0\n1 1 0\n2 0 0\n";
    let m = io::read_from_bytes(format!("{head}4 0 1 2 3\n").as_bytes(), Format::Ply, Path::new("s.ply"))
        .unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [2, 1, 3]]);
    let area_z = |t: [u32; 3]| {
        let p = |i: u32| m.vertices.positions[i as usize];
        let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    assert!(m.triangles.iter().all(|&t| area_z(t) > 0.0), "both face +z");
    let m = io::read_from_bytes(
        format!("{head}9 0 1 2 2 2 -1 1 4 3\n").as_bytes(),
        Format::Ply,
        Path::new("s.ply"),
    )
    .unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [1, 4, 3]]);
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
}

#[test]
fn warnings_report_dropped_faces_and_polygons_count_once() {
    let obj = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 1 1 2\nf 2 3 3\nf 1 2 3\n";
    let m = io::read_from_bytes(obj, Format::Obj, Path::new("q.obj")).unwrap();
    assert_eq!(m.source_faces, 4);
    assert_eq!(m.triangles.len(), 3);
    assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
    assert!(m.warnings[0].contains("dropped 2 degenerate faces") && m.warnings[0].contains("line 6"));
}

#[test]
fn gltf_external_buffers_resolve_next_to_the_file_only() {
    let dir = tempfile::tempdir().expect("temp dir");
    let glb_path = dir.path().join("m.gltf");
    io::write(&glb_path, &sample(true), &WriteOptions::default()).unwrap();
    // Move the embedded buffer out into m.bin.
    let mut doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&glb_path).unwrap()).unwrap();
    let uri = doc["buffers"][0]["uri"].as_str().unwrap().to_string();
    let b64 = uri.split(',').nth(1).unwrap();
    use base64::Engine;
    let bin = base64::engine::general_purpose::STANDARD.decode(b64).unwrap();
    std::fs::write(dir.path().join("m data.bin"), &bin).unwrap();
    doc["buffers"][0]["uri"] = "m%20data.bin".into();
    std::fs::write(&glb_path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let m = io::read(&glb_path).unwrap();
    assert_eq!(m.triangles, sample(true).triangles);

    // From memory there is no directory to look in.
    let bytes = std::fs::read(&glb_path).unwrap();
    let e = io::read_from_bytes(&bytes, Format::Gltf, Path::new("upload.gltf")).unwrap_err();
    assert!(e.to_string().contains("cannot be read here"), "{e}");

    // A reference that climbs out of the directory is refused even when the file exists.
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    doc["buffers"][0]["uri"] = "../m%20data.bin".into();
    std::fs::write(sub.join("n.gltf"), serde_json::to_vec(&doc).unwrap()).unwrap();
    let e = io::read(&sub.join("n.gltf")).unwrap_err();
    assert!(e.to_string().contains("leaves the directory"), "{e}");
}

#[test]
fn writers_reject_models_they_cannot_store() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut m = sample(true);
    m.triangles.push([0, 1, 99]);
    assert!(matches!(
        io::write(&dir.path().join("a.ply"), &m, &WriteOptions::default()),
        Err(Error::InvalidInput(_))
    ));
    let mut m = sample(true);
    m.vertices.set_attribute("big", AttributeData::Int(vec![1 << 40; 16]));
    let e = io::write(&dir.path().join("b.ply"), &m, &WriteOptions::default()).unwrap_err();
    assert!(e.to_string().contains("32 bits"), "{e}");
    let mut m = sample(true);
    m.vertices.set_attribute("has space", AttributeData::Float(vec![0.0; 16]));
    assert!(io::write(&dir.path().join("c.ply"), &m, &WriteOptions::default()).is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "refused writes leave no files");
}

/// A random point cloud or mesh with every kind of PLY data. Coordinates span the range reading
/// accepts (`io::MAX_COORDINATE`), down to the smallest normal numbers; the first two points are
/// 1 apart, so that the model is never too small to be read (`io::MIN_EXTENT`).
fn arb_model() -> impl Strategy<Value = Model> {
    let normal =
        proptest::num::f64::NORMAL.prop_filter("inside the range read", |x| x.abs() <= io::MAX_COORDINATE);
    let coord = prop_oneof![Just(0.0), Just(-0.0), -1e40f64..1e40, -1.0f64..1.0, normal];
    (3usize..40)
        .prop_flat_map(move |n| {
            (
                proptest::collection::vec([coord.clone(), coord.clone(), coord.clone()], n),
                proptest::option::of(proptest::collection::vec(
                    [-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0],
                    n,
                )),
                proptest::option::of(proptest::collection::vec(any::<[u8; 3]>(), n)),
                proptest::collection::vec(any::<i32>(), n),
                proptest::collection::vec(proptest::num::f64::NORMAL | proptest::num::f64::ZERO, n),
                proptest::collection::vec([0..n as u32, 0..n as u32, 0..n as u32], 0..60),
            )
        })
        .prop_map(|(mut positions, normals, colors, ints, floats, tris)| {
            positions[0] = [1.0, 0.0, 0.0];
            positions[1] = [0.0, 0.0, 0.0];
            let mut cloud = PointCloud { positions, normals, colors, attributes: vec![] };
            cloud.set_attribute("segment", AttributeData::Int(ints.into_iter().map(i64::from).collect()));
            cloud.set_attribute("weight", AttributeData::Float(floats));
            let triangles: Vec<[u32; 3]> =
                tris.into_iter().filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]).collect();
            Model {
                source_faces: triangles.len(),
                vertices: cloud,
                triangles,
                format: Format::Ply,
                warnings: vec![],
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn ply_round_trips_exactly(model in arb_model(), enc in prop_oneof![
        Just(PlyEncoding::Ascii), Just(PlyEncoding::BinaryLittleEndian), Just(PlyEncoding::BinaryBigEndian)
    ]) {
        let back = write_read(&model, "p.ply", &WriteOptions { ply: enc, ..Default::default() });
        prop_assert_eq!(&back.vertices.positions, &model.vertices.positions);
        prop_assert_eq!(&back.triangles, &model.triangles);
        prop_assert_eq!(&back.vertices.colors, &model.vertices.colors);
        prop_assert_eq!(&back.vertices.attributes, &model.vertices.attributes);
        let as_f32 = model.vertices.normals.as_ref().map(|n| {
            n.iter().map(|v| v.map(|c| c as f32 as f64)).collect::<Vec<_>>()
        });
        prop_assert_eq!(&back.vertices.normals, &as_f32);
    }
}

#[test]
fn coordinates_outside_the_range_motif_computes_in_are_refused_on_reading() {
    // A shelf at 10²⁰⁰ used to be resized with vertices welded that should not be (distances
    // squared overflow); such files are now refused with the vertex and a remedy.
    let big = b"v 0 0 0\nv 2e200 0 0\nv 0 1 0\nf 1 2 3\n";
    let e = io::read_from_bytes(big, Format::Obj, Path::new("big.obj")).unwrap_err().to_string();
    assert!(
        e.contains("big.obj") && e.contains("vertex 1") && e.contains("2e200") && e.contains("rescale"),
        "{e}"
    );
    let tiny = b"v 0 0 0\nv 1e-60 0 0\nv 0 1e-60 0\nf 1 2 3\n";
    let e = io::read_from_bytes(tiny, Format::Obj, Path::new("tiny.obj")).unwrap_err().to_string();
    assert!(e.contains("tiny.obj") && e.contains("1e-60 across") && e.contains("rescale"), "{e}");
    // Inside the range, and a single point (no extent), are read.
    for ok in
        [&b"v 0 0 0\nv 1e30 0 0\nv 0 1e30 0\nf 1 2 3\n"[..], b"v 1e-30 0 0\nv 1e-30 0 0\n", b"v 0 0 0\n"]
    {
        assert!(io::read_from_bytes(ok, Format::Obj, Path::new("ok.obj")).is_ok());
    }
}
