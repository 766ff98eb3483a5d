//! OBJ and glTF/GLB import through the public API: geometry, transforms, buffers, warnings,
//! and rejection of malformed files with the right problem and place.

use ellip::import::{
    read_mesh, read_mesh_bytes, ImportError, ImportOptions, Imported, Location, Problem,
};
use ellip::rng::SplitMix64;
use glam::DVec3;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------
// Helpers

fn import(bytes: &[u8], name: &str) -> Result<Imported, ImportError> {
    read_mesh_bytes(bytes, Path::new(name), &ImportOptions::default())
}

/// The place and problem of a rejected file; fails the test if it was accepted.
fn rejection(bytes: &[u8], name: &str) -> (Option<Location>, Problem) {
    match import(bytes, name) {
        Err(ImportError::Malformed { at, problem, .. }) => (at, problem),
        Err(other) => panic!("{name}: expected a malformed-file error, got {other}"),
        Ok(_) => panic!("{name}: expected rejection, but it was imported"),
    }
}

/// Unit cube [0, 1]³; vertex x + 2y + 4z is at (x, y, z).
fn cube_positions() -> Vec<[f32; 3]> {
    (0..8u8)
        .map(|i| {
            [
                f32::from(i & 1),
                f32::from((i >> 1) & 1),
                f32::from((i >> 2) & 1),
            ]
        })
        .collect()
}

/// The cube's twelve triangles, counter-clockwise seen from outside.
const CUBE_TRIANGLES: [u16; 36] = [
    0, 2, 3, 0, 3, 1, // z = 0
    4, 5, 7, 4, 7, 6, // z = 1
    0, 1, 5, 0, 5, 4, // y = 0
    2, 6, 7, 2, 7, 3, // y = 1
    0, 4, 6, 0, 6, 2, // x = 0
    1, 3, 7, 1, 7, 5, // x = 1
];

/// A glTF document with one mesh of one primitive, one node showing it, one scene, and one
/// buffer (without a `uri`) holding the positions then the indices.
fn document(positions: &[[f32; 3]], indices: Option<&[u16]>, mode: u32) -> (Value, Vec<u8>) {
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let position_bytes = bin.len();
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for p in positions {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    let mut views = vec![json!({"buffer": 0, "byteOffset": 0, "byteLength": position_bytes})];
    let mut accessors = vec![json!({
        "bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3",
        "min": min, "max": max
    })];
    let mut primitive = json!({"attributes": {"POSITION": 0}, "mode": mode});
    if let Some(indices) = indices {
        bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
        views.push(json!({
            "buffer": 0, "byteOffset": position_bytes, "byteLength": indices.len() * 2
        }));
        accessors.push(json!({
            "bufferView": 1, "componentType": 5123, "count": indices.len(), "type": "SCALAR"
        }));
        primitive["indices"] = json!(1);
    }
    let json = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": views,
        "accessors": accessors,
        "meshes": [{"primitives": [primitive]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0
    });
    (json, bin)
}

fn cube_document() -> (Value, Vec<u8>) {
    document(&cube_positions(), Some(&CUBE_TRIANGLES), 4)
}

/// Writes a GLB container: header, JSON chunk (space-padded), BIN chunk (zero-padded).
fn glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(json).unwrap();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    out
}

fn base64(bytes: &[u8]) -> String {
    use base64::Engine as _;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// A fresh, empty folder for one test.
fn scratch_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ellip-import-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Whether `points` contains `p` within `tol`.
fn contains_point(points: &[DVec3], p: DVec3, tol: f64) -> bool {
    points.iter().any(|q| q.distance(p) <= tol)
}

const TOL: f64 = 1e-12;

/// Whether a rejection is the expected kind of problem.
type IsExpected = fn(&Problem) -> bool;

// ---------------------------------------------------------------------------------------
// OBJ

const CUBE_OBJ: &str = "\
# unit cube, quads
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
v 0 0 1
v 1 0 1
v 0 1 1
v 1 1 1
f 1 3 4 2
f 5 6 8 7
f 1 2 6 5
f 3 7 8 4
f 1 5 7 3
f 2 4 8 6
";

#[test]
fn obj_cube_of_quads_becomes_a_closed_mesh_of_twelve_triangles() {
    let imported = import(CUBE_OBJ.as_bytes(), "cube.obj").unwrap();
    let mesh = &imported.mesh;
    assert_eq!(mesh.face_count(), 12);
    assert_eq!(mesh.vertex_count(), 8);
    assert!(mesh.topology().is_closed());
    assert_eq!(mesh.topology().component_count(), 1);
    assert_eq!(imported.repairs.triangulated_polygons, 6);
    assert!((mesh.signed_volume() - 1.0).abs() < TOL);
    assert!((mesh.area() - 6.0).abs() < TOL);
}

#[test]
fn obj_groups_with_repeated_vertices_are_welded_into_one_component() {
    // Two groups, each with its own copies of the vertices it uses.
    let text = "\
o first
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
v 0 0 1
v 1 0 1
v 0 1 1
v 1 1 1
f 1 3 4 2
f 5 6 8 7
f 1 2 6 5
g second
v 0 1 0
v 1 1 0
v 0 0 1
v 0 1 1
v 1 1 1
v 0 0 0
v 1 0 0
v 1 0 1
f 3 7 8 4
f 14 11 12 9
f 15 10 13 16
";
    let imported = import(text.as_bytes(), "groups.obj").unwrap();
    let mesh = &imported.mesh;
    assert_eq!(mesh.face_count(), 12);
    assert_eq!(mesh.vertex_count(), 8);
    assert!(imported.repairs.welded_vertices > 0);
    assert_eq!(mesh.topology().component_count(), 1);
    assert!(mesh.topology().is_closed());
}

#[test]
fn obj_negative_indices_are_relative_to_the_vertices_so_far() {
    // Each face is written right after its last vertex, with relative indices.
    let text = "\
v 0 0 0
v 1 0 0
v 0 1 0
f -3 -2 -1
v 0 0 1
f -4 -1 -3
f -4 -2 -1
f -3 -2 -1
";
    let imported = import(text.as_bytes(), "tetra.obj").unwrap();
    let mesh = &imported.mesh;
    assert_eq!(mesh.face_count(), 4);
    assert_eq!(mesh.vertex_count(), 4);
    assert!(mesh.topology().is_closed());
    assert!((mesh.volume().unwrap() - 1.0 / 6.0).abs() < TOL);
}

#[test]
fn obj_malformed_files_are_rejected_at_the_right_line() {
    let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases: Vec<(String, u64, IsExpected)> = vec![
        (format!("{v}f 0 1 2\n"), 4, |p| {
            matches!(p, Problem::IndexOutOfRange { index: 0, .. })
        }),
        (format!("{v}f -4 1 2\n"), 4, |p| {
            matches!(
                p,
                Problem::IndexOutOfRange {
                    index: -4,
                    vertex_count: 3
                }
            )
        }),
        (format!("{v}# c\nf 1 2 4\n"), 5, |p| {
            matches!(
                p,
                Problem::IndexOutOfRange {
                    index: 4,
                    vertex_count: 3
                }
            )
        }),
        (format!("{v}f 1 2\n"), 4, |p| {
            matches!(p, Problem::FaceTooSmall { vertices: 2 })
        }),
        (format!("v nan 0 0\n{v}f 1 2 3\n"), 1, |p| {
            matches!(p, Problem::NonFiniteCoordinate { vertex: 0 })
        }),
        (format!("{v}v 1e999 0 0\nf 1 2 4\n"), 4, |p| {
            matches!(p, Problem::NonFiniteCoordinate { vertex: 3 })
        }),
        (format!("{v}v 1 \u{fffd}x 0\nf 1 2 3\n"), 4, |p| {
            matches!(p, Problem::Syntax { .. })
        }),
        (format!("{v}f 1 2 3x\n"), 4, |p| {
            matches!(p, Problem::Syntax { .. })
        }),
    ];
    for (text, line, expected) in cases {
        let (at, problem) = rejection(text.as_bytes(), "bad.obj");
        assert_eq!(at, Some(Location::Line(line)), "{text:?}: {problem}");
        assert!(expected(&problem), "{text:?}: {problem:?}");
    }
    let mut non_utf8 = v.as_bytes().to_vec();
    non_utf8.extend_from_slice(b"v 0 0 \xff\xfe\nf 1 2 3\n");
    assert!(matches!(
        rejection(&non_utf8, "bad.obj"),
        (Some(Location::Line(4)), Problem::Syntax { .. })
    ));
}

#[test]
fn obj_without_faces_is_rejected_as_empty_or_unsupported() {
    assert_eq!(rejection(b"", "e.obj"), (None, Problem::Empty));
    assert_eq!(rejection(b"# nothing\n\n", "e.obj"), (None, Problem::Empty));
    assert!(matches!(
        rejection(b"v 0 0 0\nv 1 0 0\nl 1 2\n", "e.obj").1,
        Problem::Unsupported { .. }
    ));
    let mut garbage = vec![0u8; 4096];
    let mut rng = SplitMix64::new(99);
    garbage.iter_mut().for_each(|b| *b = rng.next_u64() as u8);
    assert!(import(&garbage, "garbage.obj").is_err());
}

// ---------------------------------------------------------------------------------------
// glTF and GLB: geometry

#[test]
fn glb_cube_is_read_closed_and_outward() {
    let (json, bin) = cube_document();
    let imported = import(&glb(&json, &bin), "cube.glb").unwrap();
    assert_eq!(imported.mesh.face_count(), 12);
    assert!(imported.mesh.topology().is_closed());
    assert!((imported.mesh.signed_volume() - 1.0).abs() < TOL);
    assert!(imported.repairs.is_clean(), "{:?}", imported.repairs);
    assert!(imported.warnings.is_empty());
}

#[test]
fn glb_instances_are_transformed_through_the_hierarchy() {
    let (mut json, bin) = cube_document();
    // Node 0 moves the cube by (10, 0, 0); node 1 scales it by 2 inside a parent (node 2)
    // that moves it by (0, 0, -5). Node 3 is not in the scene.
    json["nodes"] = json!([
        {"mesh": 0, "translation": [10.0, 0.0, 0.0]},
        {"mesh": 0, "scale": [2.0, 2.0, 2.0]},
        {"children": [1], "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,-5,1]},
        {"mesh": 0, "translation": [100.0, 0.0, 0.0]}
    ]);
    json["scenes"] = json!([{"nodes": [0, 2]}]);
    let imported = import(&glb(&json, &bin), "two.glb").unwrap();
    let mesh = &imported.mesh;
    assert_eq!(mesh.face_count(), 24);
    assert_eq!(mesh.topology().component_count(), 2);
    let points = mesh.positions();
    assert!(contains_point(points, DVec3::new(10.0, 0.0, 0.0), TOL));
    assert!(contains_point(points, DVec3::new(11.0, 1.0, 1.0), TOL));
    assert!(contains_point(points, DVec3::new(0.0, 0.0, -5.0), TOL));
    assert!(contains_point(points, DVec3::new(2.0, 2.0, -3.0), TOL));
    assert!(
        !points.iter().any(|p| p.x > 50.0),
        "node 3 is outside the scene"
    );
    // Volumes 1 and 8, both outward.
    assert!((mesh.signed_volume() - 9.0).abs() < 1e-9);
}

#[test]
fn mirroring_transforms_reverse_the_winding() {
    let (mut json, bin) = cube_document();
    json["nodes"] = json!([{"mesh": 0, "scale": [-1.0, 1.0, 1.0]}]);
    let options = ImportOptions {
        keep_orientation: true,
        ..ImportOptions::default()
    };
    let imported = read_mesh_bytes(&glb(&json, &bin), Path::new("m.glb"), &options).unwrap();
    let bbox = imported.mesh.bounding_box().unwrap();
    assert!((bbox.min.x + 1.0).abs() < TOL && bbox.max.x.abs() < TOL);
    // Without the reversal the mirrored cube would enclose volume -1.
    assert!((imported.mesh.signed_volume() - 1.0).abs() < TOL);
}

#[test]
fn files_without_scenes_show_every_mesh_once() {
    let (mut json, bin) = cube_document();
    let object = json.as_object_mut().unwrap();
    object.remove("scenes");
    object.remove("scene");
    object["nodes"] = json!([{"mesh": 0, "translation": [5.0, 0.0, 0.0]}]);
    let imported = import(&glb(&json, &bin), "noscene.glb").unwrap();
    assert_eq!(imported.mesh.face_count(), 12);
    let bbox = imported.mesh.bounding_box().unwrap();
    assert!(bbox.max.x <= 1.0, "untransformed");
}

#[test]
fn gltf_with_a_data_uri_buffer() {
    let (mut json, bin) = cube_document();
    json["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64(&bin)
    ));
    let text = serde_json::to_vec_pretty(&json).unwrap();
    let imported = import(&text, "cube.gltf").unwrap();
    assert_eq!(imported.mesh.face_count(), 12);
    assert!(imported.mesh.topology().is_closed());
}

#[test]
fn gltf_with_a_byte_order_mark_is_read() {
    let (mut json, bin) = cube_document();
    json["buffers"][0]["uri"] = json!(format!(
        "data:application/gltf-buffer;base64,{}",
        base64(&bin)
    ));
    let mut text = b"\xEF\xBB\xBF".to_vec();
    text.extend(serde_json::to_vec(&json).unwrap());
    assert_eq!(import(&text, "bom.gltf").unwrap().mesh.face_count(), 12);
}

#[test]
fn gltf_with_an_external_buffer_file() {
    let dir = scratch_dir("external");
    let (mut json, bin) = cube_document();
    std::fs::create_dir_all(dir.join("sub dir")).unwrap();
    std::fs::write(dir.join("sub dir").join("cube data.bin"), &bin).unwrap();
    json["buffers"][0]["uri"] = json!("sub%20dir/cube%20data.bin");
    let path = dir.join("cube.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let imported = read_mesh(&path, &ImportOptions::default()).unwrap();
    assert_eq!(imported.mesh.face_count(), 12);
    assert!(imported.mesh.topology().is_closed());

    // A buffer file shorter than declared.
    std::fs::write(dir.join("sub dir").join("cube data.bin"), &bin[..100]).unwrap();
    match read_mesh(&path, &ImportOptions::default()) {
        Err(ImportError::Malformed { problem, .. }) => assert_eq!(
            problem,
            Problem::Truncated {
                needed: bin.len() as u64,
                available: 100
            }
        ),
        other => panic!("expected truncation, got {other:?}"),
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn line_primitives_are_skipped_with_a_warning() {
    let (mut json, bin) = cube_document();
    json["meshes"][0]["primitives"]
        .as_array_mut()
        .unwrap()
        .push(json!({"attributes": {"POSITION": 0}, "mode": 1}));
    let imported = import(&glb(&json, &bin), "lines.glb").unwrap();
    assert_eq!(imported.mesh.face_count(), 12);
    assert_eq!(
        imported.warnings,
        vec!["skipped 1 line primitives".to_owned()]
    );
}

#[test]
fn strips_and_fans_become_triangles() {
    // A square as a strip (0 1 2 3 zig-zag) and as a fan (around corner 0).
    let strip = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let fan = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    for (positions, mode) in [(strip, 5), (fan, 6)] {
        let (json, bin) = document(&positions, None, mode);
        let options = ImportOptions {
            keep_orientation: true,
            ..ImportOptions::default()
        };
        let imported = read_mesh_bytes(&glb(&json, &bin), Path::new("s.glb"), &options).unwrap();
        let mesh = &imported.mesh;
        assert_eq!(mesh.face_count(), 2, "mode {mode}");
        assert!((mesh.area() - 1.0).abs() < TOL, "mode {mode}");
        for f in 0..2 {
            assert!(
                mesh.face_normal(f).z > 0.99,
                "mode {mode}: face {f} faces +z"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// glTF and GLB: malformed and unsupported files

/// A cube GLB after `edit` changes its JSON.
fn edited(edit: impl FnOnce(&mut Value)) -> Vec<u8> {
    let (mut json, bin) = cube_document();
    edit(&mut json);
    glb(&json, &bin)
}

#[test]
fn accessors_and_views_outside_their_data_are_rejected() {
    let gltf_error = |p: &Problem| matches!(p, Problem::Gltf { .. });
    let cases: Vec<(&str, Vec<u8>, IsExpected)> = vec![
        (
            "view past buffer",
            edited(|j| j["bufferViews"][1]["byteLength"] = json!(1000)),
            gltf_error,
        ),
        (
            "view offset huge",
            edited(|j| j["bufferViews"][1]["byteOffset"] = json!(u64::MAX / 2)),
            gltf_error,
        ),
        (
            "accessor past view",
            edited(|j| j["accessors"][0]["count"] = json!(9)),
            gltf_error,
        ),
        (
            "accessor offset",
            edited(|j| j["accessors"][1]["byteOffset"] = json!(2)),
            gltf_error,
        ),
        (
            "huge count",
            edited(|j| j["accessors"][1]["count"] = json!(u32::MAX)),
            |p| matches!(p, Problem::Gltf { .. } | Problem::LimitsExceeded { .. }),
        ),
        (
            "stride",
            edited(|j| j["bufferViews"][0]["byteStride"] = json!(16)),
            gltf_error,
        ),
        (
            "buffer longer than BIN",
            edited(|j| j["buffers"][0]["byteLength"] = json!(1000)),
            |p| matches!(p, Problem::Truncated { needed: 1000, .. }),
        ),
        (
            "index out of range",
            edited(|j| j["accessors"][0]["count"] = json!(7)),
            |p| {
                matches!(
                    p,
                    Problem::IndexOutOfRange {
                        index: 7,
                        vertex_count: 7
                    }
                )
            },
        ),
        (
            "positions as VEC2",
            edited(|j| j["accessors"][0]["type"] = json!("VEC2")),
            |p| matches!(p, Problem::Unsupported { .. }),
        ),
        (
            "float indices",
            edited(|j| j["accessors"][1]["componentType"] = json!(5126)),
            gltf_error,
        ),
        (
            "sparse",
            edited(|j| {
                j["accessors"][0]["sparse"] = json!({
                    "count": 1,
                    "indices": {"bufferView": 1, "componentType": 5123},
                    "values": {"bufferView": 0}
                })
            }),
            |p| matches!(p, Problem::Unsupported { .. }),
        ),
        (
            "no buffer view",
            edited(|j| {
                j["accessors"][0]
                    .as_object_mut()
                    .unwrap()
                    .remove("bufferView");
            }),
            |p| matches!(p, Problem::Unsupported { .. } | Problem::Gltf { .. }),
        ),
        (
            "dangling position",
            edited(|j| j["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(7)),
            gltf_error,
        ),
        (
            "dangling index",
            edited(|j| j["nodes"][0]["mesh"] = json!(3)),
            gltf_error,
        ),
        (
            "bad mode",
            edited(|j| j["meshes"][0]["primitives"][0]["mode"] = json!(9)),
            gltf_error,
        ),
        (
            "cycle",
            edited(|j| {
                j["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
            }),
            gltf_error,
        ),
        (
            "shared child",
            edited(|j| {
                j["nodes"] = json!([{"children": [2]}, {"children": [2]}, {"mesh": 0}]);
                j["scenes"] = json!([{"nodes": [0, 1]}]);
            }),
            gltf_error,
        ),
        (
            "zero rotation",
            edited(|j| j["nodes"][0]["rotation"] = json!([0.0, 0.0, 0.0, 0.0])),
            gltf_error,
        ),
        (
            "not a multiple of 3",
            edited(|j| j["accessors"][1]["count"] = json!(35)),
            gltf_error,
        ),
        (
            // A valid file this reader does not take: named as such.
            "required extension",
            edited(|j| {
                j["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
                j["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
            }),
            |p| {
                matches!(p, Problem::Unsupported { what }
                    if what.contains("KHR_draco_mesh_compression"))
            },
        ),
        (
            "required extension not for geometry",
            edited(|j| {
                j["extensionsRequired"] = json!(["KHR_technique_webgl"]);
                j["extensionsUsed"] = json!(["KHR_technique_webgl"]);
            }),
            gltf_error,
        ),
        (
            "http buffer",
            edited(|j| j["buffers"][0]["uri"] = json!("http://example.com/a.bin")),
            |p| matches!(p, Problem::Unsupported { .. }),
        ),
        (
            "absolute buffer",
            edited(|j| j["buffers"][0]["uri"] = json!("/etc/passwd")),
            |p| matches!(p, Problem::Unsupported { .. }),
        ),
        (
            "escaping buffer",
            edited(|j| j["buffers"][0]["uri"] = json!("../../etc/passwd")),
            |p| matches!(p, Problem::Unsupported { .. }),
        ),
        (
            "file: buffer",
            edited(|j| j["buffers"][0]["uri"] = json!("file:///etc/passwd")),
            |p| matches!(p, Problem::Unsupported { .. }),
        ),
        (
            "text data: URI",
            edited(|j| j["buffers"][0]["uri"] = json!("data:text/plain,hello")),
            |p| matches!(p, Problem::Unsupported { .. }),
        ),
        (
            "bad base64",
            edited(|j| j["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@@")),
            gltf_error,
        ),
    ];
    for (name, bytes, expected) in cases {
        let (_, problem) = rejection(&bytes, "bad.glb");
        assert!(expected(&problem), "{name}: {problem:?}");
    }
}

#[test]
fn non_finite_positions_are_rejected() {
    let mut positions = cube_positions();
    positions[5][1] = f32::NAN;
    let (json, bin) = document(&positions, Some(&CUBE_TRIANGLES), 4);
    // serde_json writes the NaN bound as null, which the glTF validator rejects; drop it.
    let mut json = json;
    json["accessors"][0].as_object_mut().unwrap().remove("min");
    json["accessors"][0].as_object_mut().unwrap().remove("max");
    let (_, problem) = rejection(&glb(&json, &bin), "nan.glb");
    assert!(
        matches!(
            problem,
            Problem::NonFiniteCoordinate { vertex: 5 } | Problem::Gltf { .. }
        ),
        "{problem:?}"
    );
}

#[test]
fn glb_container_problems_are_located_by_byte() {
    let (json, bin) = cube_document();
    let good = glb(&json, &bin);
    let mut version = good.clone();
    version[4] = 1;
    assert!(matches!(
        rejection(&version, "v.glb"),
        (Some(Location::Byte(4)), Problem::Unsupported { .. })
    ));
    let mut length = good.clone();
    length[8..12].copy_from_slice(&4u32.to_le_bytes());
    assert!(matches!(
        rejection(&length, "l.glb"),
        (Some(Location::Byte(8)), Problem::BadHeader { .. })
    ));
    assert_eq!(
        rejection(&good[..good.len() - 1], "t.glb"),
        (
            Some(Location::Byte(0)),
            Problem::Truncated {
                needed: good.len() as u64,
                available: good.len() as u64 - 1
            }
        )
    );
    let mut chunk = good.clone();
    chunk[16..20].copy_from_slice(b"BIN\0");
    assert!(matches!(
        rejection(&chunk, "c.glb"),
        (Some(Location::Byte(16)), Problem::BadHeader { .. })
    ));
    assert!(matches!(
        rejection(b"glTF\x02\x00", "short.glb"),
        (
            Some(Location::Byte(0)),
            Problem::Truncated {
                needed: 12,
                available: 6
            }
        )
    ));
    assert_eq!(rejection(b"  \n", "e.gltf"), (None, Problem::Empty));
    assert!(matches!(
        rejection(b"{\n \"asset\": \n", "j.gltf"),
        (Some(Location::Line(_)), Problem::Gltf { .. })
    ));
}

#[test]
fn limits_are_checked_before_reading() {
    let (json, bin) = cube_document();
    let bytes = glb(&json, &bin);
    let mut options = ImportOptions::default();
    options.limits.max_faces = 11;
    let e = read_mesh_bytes(&bytes, Path::new("c.glb"), &options).unwrap_err();
    assert!(matches!(
        e,
        ImportError::Malformed {
            problem: Problem::LimitsExceeded {
                requested: 12,
                max: 11,
                ..
            },
            ..
        }
    ));
    let mut options = ImportOptions::default();
    options.limits.max_vertices = 7;
    let e = read_mesh_bytes(&bytes, Path::new("c.glb"), &options).unwrap_err();
    assert!(matches!(
        e,
        ImportError::Malformed {
            problem: Problem::LimitsExceeded {
                requested: 8,
                max: 7,
                ..
            },
            ..
        }
    ));
}

// ---------------------------------------------------------------------------------------
// Corpus: damaged files never panic

#[test]
fn truncated_and_bit_flipped_glbs_never_panic() {
    let (mut json, bin) = cube_document();
    json["nodes"] = json!([
        {"mesh": 0, "translation": [1.0, 2.0, 3.0]},
        {"mesh": 0, "scale": [-1.0, 2.0, 2.0], "children": [2]},
        {"mesh": 0, "rotation": [0.0, 0.0, 0.70710677, 0.70710677]}
    ]);
    json["scenes"] = json!([{"nodes": [0, 1]}]);
    let good = glb(&json, &bin);
    assert!(import(&good, "x.glb").is_ok());
    let mut accepted = 0;
    for len in 0..good.len() {
        if import(&good[..len], "x.glb").is_ok() {
            accepted += 1;
        }
    }
    assert_eq!(accepted, 0, "every truncation loses the BIN chunk's end");
    let mut rng = SplitMix64::new(0x5eed);
    for _ in 0..3000 {
        let mut bytes = good.clone();
        for _ in 0..1 + rng.below(3) {
            let bit = rng.below(bytes.len() as u64 * 8);
            bytes[(bit / 8) as usize] ^= 1 << (bit % 8);
        }
        // Either outcome is fine; a panic fails the test.
        if let Ok(imported) = import(&bytes, "x.glb") {
            assert!(imported.mesh.positions().iter().all(|p| p.is_finite()));
        }
    }
}

#[test]
fn truncated_and_bit_flipped_objs_never_panic() {
    let good = CUBE_OBJ.as_bytes();
    for len in 0..good.len() {
        let _ = import(&good[..len], "x.obj");
    }
    let mut rng = SplitMix64::new(0xdead);
    for _ in 0..3000 {
        let mut bytes = good.to_vec();
        for _ in 0..1 + rng.below(3) {
            let bit = rng.below(bytes.len() as u64 * 8);
            bytes[(bit / 8) as usize] ^= 1 << (bit % 8);
        }
        if let Ok(imported) = import(&bytes, "x.obj") {
            assert!(imported.mesh.positions().iter().all(|p| p.is_finite()));
        }
    }
}

/// Every value in a JSON tree below the root, as a path of keys and indices.
fn value_paths(value: &Value, path: &mut Vec<Value>, out: &mut Vec<Vec<Value>>) {
    if !path.is_empty() {
        out.push(path.clone());
    }
    match value {
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                path.push(json!(i));
                value_paths(item, path, out);
                path.pop();
            }
        }
        Value::Object(map) => {
            for (key, item) in map {
                path.push(json!(key));
                value_paths(item, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

/// The value at `path`, if it still exists.
fn value_at<'v>(mut value: &'v mut Value, path: &[Value]) -> Option<&'v mut Value> {
    for key in path {
        value = match key {
            Value::String(k) => value.as_object_mut()?.get_mut(k.as_str())?,
            Value::Number(i) => value.as_array_mut()?.get_mut(i.as_u64()? as usize)?,
            _ => return None,
        };
    }
    Some(value)
}

#[test]
fn glbs_with_mutated_json_never_panic() {
    let (mut json, bin) = cube_document();
    json["nodes"] = json!([
        {"mesh": 0, "translation": [1.0, 2.0, 3.0], "children": [1]},
        {"mesh": 0, "scale": [-1.0, 2.0, 2.0]}
    ]);
    json["meshes"][0]["primitives"]
        .as_array_mut()
        .unwrap()
        .push(json!({"attributes": {"POSITION": 0}, "mode": 5}));
    json["scenes"] = json!([{"nodes": [0]}]);
    let mut paths = Vec::new();
    value_paths(&json, &mut Vec::new(), &mut paths);
    let values = [
        json!(0),
        json!(1),
        json!(2),
        json!(3),
        json!(4),
        json!(7),
        json!(8),
        json!(35),
        json!(36),
        json!(95),
        json!(96),
        json!(167),
        json!(168),
        json!(5121),
        json!(5125),
        json!(5126),
        json!(65535),
        json!(2147483647u64),
        json!(4294967295u64),
        json!(18446744073709551615u64),
        json!(-1),
        json!(0.5),
        json!(1e30),
        json!(-1e30),
        json!("SCALAR"),
        json!("VEC2"),
        json!("MAT4"),
        json!([]),
        json!({}),
        json!(null),
    ];
    let iterations: u64 = std::env::var("ELLIP_FUZZ_ITERATIONS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3000);
    let mut rng = SplitMix64::new(0x6c7f);
    let mut accepted = 0;
    for _ in 0..iterations {
        let mut mutated = json.clone();
        for _ in 0..1 + rng.below(3) {
            // Earlier mutations may have removed the path; then this one does nothing.
            let path = &paths[rng.below(paths.len() as u64) as usize];
            let (last, parent) = path.split_last().unwrap();
            let Some(parent) = value_at(&mut mutated, parent) else {
                continue;
            };
            match (parent, last) {
                (Value::Object(map), Value::String(key)) if rng.below(4) == 0 => {
                    map.remove(key.as_str());
                }
                (Value::Object(map), Value::String(key)) => {
                    map.insert(
                        key.clone(),
                        values[rng.below(values.len() as u64) as usize].clone(),
                    );
                }
                (Value::Array(items), Value::Number(i)) => {
                    if let Some(item) = items.get_mut(i.as_u64().unwrap() as usize) {
                        *item = values[rng.below(values.len() as u64) as usize].clone();
                    }
                }
                _ => {}
            }
        }
        if let Ok(imported) = import(&glb(&mutated, &bin), "x.glb") {
            accepted += 1;
            assert!(imported.mesh.positions().iter().all(|p| p.is_finite()));
        }
    }
    eprintln!("mutated glTF: {accepted} of {iterations} accepted");
    // The mutations are mild enough that some files stay valid, and harsh enough that not all do.
    assert!(
        accepted > 0 && accepted < iterations,
        "{accepted} of {iterations} accepted"
    );
}
