//! Export tests: every format read back and compared with what was written, byte
//! determinism, rejected data, atomic writes, and the Khronos glTF Validator on every glTF and
//! GLB variant we write.
//!
//! The validator runs when `node` and `.ci/node_modules/gltf-validator` exist (install it with
//! `npm ci --prefix .ci`); otherwise its test prints "skipped: …" and passes, unless
//! `ELLIP_REQUIRE_GLTF_VALIDATOR=1` is set (CI sets it), in which case it fails.

use ellip::export::{encode_mesh, write_mesh, ExportError, MeshData};
use ellip::import::MeshFormat;
use ellip::Mesh;
use glam::{DVec3, Vec3};
use std::fs;
use std::path::{Path, PathBuf};

mod common;

/// A fresh, empty folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ellip-export-{name}-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// File names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A regular tetrahedron with outward faces, off the origin and with coordinates that are
/// not exact in binary.
fn tetrahedron() -> Mesh {
    let p = vec![
        DVec3::new(1.1, 1.0, 1.0),
        DVec3::new(1.1, -1.0, -1.0),
        DVec3::new(-0.9, 1.0, -1.0),
        DVec3::new(-0.9, -1.0, 1.0),
    ];
    let f = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
    Mesh::new(p, f).unwrap()
}

/// A wavy height field of `side × side` vertices (side 260 gives 67 600 > 65 535).
fn wavy_grid(side: u32) -> Mesh {
    let mut positions = Vec::new();
    for j in 0..side {
        for i in 0..side {
            let (x, y) = (f64::from(i) * 0.01, f64::from(j) * 0.01);
            positions.push(DVec3::new(x, y, 0.1 * (7.0 * x).sin() * (5.0 * y).cos()));
        }
    }
    let mut faces = Vec::new();
    for j in 0..side - 1 {
        for i in 0..side - 1 {
            let v = j * side + i;
            faces.push([v, v + 1, v + side + 1]);
            faces.push([v, v + side + 1, v + side]);
        }
    }
    Mesh::new(positions, faces).unwrap()
}

/// One colour per vertex, varied in every channel.
fn colors_for(n: usize) -> Vec<[u8; 4]> {
    (0..n)
        .map(|i| {
            let i = i as u32;
            [
                (i * 37 % 256) as u8,
                (i * 91 % 256) as u8,
                (i * 13 % 256) as u8,
                (255 - i % 128) as u8,
            ]
        })
        .collect()
}

// ---------------------------------------------------------------------------------------
// glTF and GLB

/// What a glTF reader recovers from one primitive.
struct Read {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    colors: Option<Vec<[u8; 4]>>,
    indices: Vec<u32>,
    index_type: gltf::accessor::DataType,
    generator: Option<String>,
}

/// Reads a GLB, or a `.gltf` with its buffer bytes, with the `gltf` crate (which also checks
/// the JSON against the schema).
fn read_gltf(json_or_glb: &[u8], external_bin: Option<&[u8]>) -> Read {
    let file = gltf::Gltf::from_slice(json_or_glb).expect("the gltf crate accepts our output");
    let bin: Vec<u8> = match external_bin {
        Some(b) => b.to_vec(),
        None => file.blob.clone().expect("a GLB has a BIN chunk"),
    };
    assert_eq!(file.meshes().count(), 1);
    assert_eq!(file.nodes().count(), 1);
    assert_eq!(file.scenes().count(), 1);
    assert_eq!(file.buffers().count(), 1);
    let mesh = file.meshes().next().unwrap();
    assert_eq!(mesh.primitives().count(), 1);
    let primitive = mesh.primitives().next().unwrap();
    assert_eq!(primitive.mode(), gltf::mesh::Mode::Triangles);
    let reader = primitive.reader(|_| Some(&bin[..]));
    Read {
        positions: reader
            .read_positions()
            .unwrap()
            .map(Vec3::from_array)
            .collect(),
        normals: reader
            .read_normals()
            .unwrap()
            .map(Vec3::from_array)
            .collect(),
        colors: reader.read_colors(0).map(|c| c.into_rgba_u8().collect()),
        indices: reader.read_indices().unwrap().into_u32().collect(),
        index_type: primitive.indices().unwrap().data_type(),
        generator: file.document.as_json().asset.generator.clone(),
    }
}

/// Checks a read-back glTF primitive against the mesh it was written from.
fn assert_matches(read: &Read, mesh: &Mesh, colors: Option<&[[u8; 4]]>) {
    let expected: Vec<Vec3> = mesh.positions().iter().map(|p| p.as_vec3()).collect();
    assert_eq!(
        read.positions, expected,
        "positions are the exact f32 values"
    );
    let flat: Vec<u32> = mesh.faces().iter().flatten().copied().collect();
    assert_eq!(read.indices, flat);
    let short = mesh.vertex_count() < 65536;
    let expected_type = if short {
        gltf::accessor::DataType::U16
    } else {
        gltf::accessor::DataType::U32
    };
    assert_eq!(read.index_type, expected_type);
    // Default normals are the mesh's angle-weighted normals, unit length in f32.
    for (got, want) in read.normals.iter().zip(mesh.vertex_normals()) {
        assert!((got.length() - 1.0).abs() < 1e-6, "unit normal: {got}");
        assert!((got.as_dvec3() - want).length() < 1e-6, "{got} vs {want}");
    }
    assert_eq!(read.normals.len(), mesh.vertex_count());
    assert_eq!(read.colors.as_deref(), colors);
    assert_eq!(
        read.generator.as_deref(),
        Some(concat!("ellip ", env!("CARGO_PKG_VERSION")))
    );
}

#[test]
fn glb_reads_back_with_the_gltf_crate() {
    let mesh = tetrahedron();
    let colors = colors_for(4);
    let plain = encode_mesh(MeshFormat::Glb, &MeshData::from_mesh(&mesh)).unwrap();
    assert_matches(&read_gltf(&plain, None), &mesh, None);
    let colored = MeshData::from_mesh(&mesh).with_colors(&colors);
    let glb = encode_mesh(MeshFormat::Glb, &colored).unwrap();
    assert_matches(&read_gltf(&glb, None), &mesh, Some(&colors));

    // GLB layout: header length = file length; chunks 4-byte aligned.
    assert_eq!(&glb[0..4], b"glTF");
    let word = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(word(4), 2);
    assert_eq!(word(8), glb.len());
    let json_len = word(12);
    assert_eq!(&glb[16..20], b"JSON");
    assert_eq!(json_len % 4, 0);
    let bin_at = 20 + json_len;
    assert_eq!(word(bin_at) % 4, 0);
    assert_eq!(&glb[bin_at + 4..bin_at + 8], b"BIN\0");
    assert_eq!(bin_at + 8 + word(bin_at), glb.len());
}

#[test]
fn large_glb_uses_32_bit_indices() {
    let mesh = wavy_grid(260);
    assert!(mesh.vertex_count() > 65535);
    let glb = encode_mesh(MeshFormat::Glb, &MeshData::from_mesh(&mesh)).unwrap();
    assert_matches(&read_gltf(&glb, None), &mesh, None);
}

#[test]
fn given_normals_are_renormalised() {
    let mesh = tetrahedron();
    let normals: Vec<DVec3> = mesh.vertex_normals().iter().map(|n| *n * 3.7).collect();
    let data = MeshData::from_mesh(&mesh).with_normals(&normals);
    let read = read_gltf(&encode_mesh(MeshFormat::Glb, &data).unwrap(), None);
    for (got, want) in read.normals.iter().zip(mesh.vertex_normals()) {
        assert!((got.length() - 1.0).abs() < 1e-6);
        assert!((got.as_dvec3() - want).length() < 1e-6);
    }
}

#[test]
fn gltf_writes_bin_beside_it_with_an_encoded_uri() {
    let dir = scratch("gltf-uri");
    let mesh = tetrahedron();
    let path = dir.join("my mesh é.gltf");
    write_mesh(&path, &MeshData::from_mesh(&mesh)).unwrap();
    assert_eq!(listing(&dir), ["my mesh é.bin", "my mesh é.gltf"]);
    let json = fs::read(&path).unwrap();
    let value: serde_json::Value = serde_json::from_slice(&json).unwrap();
    assert_eq!(value["buffers"][0]["uri"], "my%20mesh%20%C3%A9.bin");
    let bin = fs::read(dir.join("my mesh é.bin")).unwrap();
    assert_eq!(value["buffers"][0]["byteLength"], bin.len());
    assert_matches(&read_gltf(&json, Some(&bin)), &mesh, None);
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn embedded_gltf_carries_its_buffer() {
    let mesh = tetrahedron();
    let json = encode_mesh(MeshFormat::Gltf, &MeshData::from_mesh(&mesh)).unwrap();
    let value: serde_json::Value = serde_json::from_slice(&json).unwrap();
    let uri = value["buffers"][0]["uri"].as_str().unwrap();
    let payload = uri
        .strip_prefix("data:application/octet-stream;base64,")
        .unwrap();
    use base64::Engine;
    let bin = base64::engine::general_purpose::STANDARD
        .decode(payload)
        .unwrap();
    assert_matches(&read_gltf(&json, Some(&bin)), &mesh, None);
}

#[test]
fn khronos_validator_accepts_everything_we_write() {
    if !common::validator_ready() {
        return;
    }

    let dir = scratch("validator");
    let tet = tetrahedron();
    let grid = wavy_grid(260);
    let tet_colors = colors_for(tet.vertex_count());
    let grid_colors = colors_for(grid.vertex_count());
    let odd_normals: Vec<DVec3> = tet.vertex_normals().iter().map(|n| *n * 0.3).collect();
    // An open strip with a very thin triangle and a vertex no triangle uses.
    let strip_positions = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(1.0, 1.0, 1e-3),
        DVec3::new(2.0, 1e-6, 0.0),
        DVec3::new(5.0, 5.0, 5.0),
    ];
    let strip_faces = [[0, 1, 2], [1, 3, 2], [1, 4, 3]];
    let strip = MeshData {
        positions: &strip_positions,
        triangles: &strip_faces,
        normals: None,
        colors: None,
    };

    let cases: Vec<(&str, MeshData<'_>)> = vec![
        ("tetrahedron.glb", MeshData::from_mesh(&tet)),
        ("tetrahedron.gltf", MeshData::from_mesh(&tet)),
        (
            "tetrahedron-colors.glb",
            MeshData::from_mesh(&tet).with_colors(&tet_colors),
        ),
        (
            "tetrahedron-colors.gltf",
            MeshData::from_mesh(&tet).with_colors(&tet_colors),
        ),
        (
            "tetrahedron-normals.glb",
            MeshData::from_mesh(&tet).with_normals(&odd_normals),
        ),
        ("grid.glb", MeshData::from_mesh(&grid)),
        ("grid.gltf", MeshData::from_mesh(&grid)),
        (
            "grid-colors.glb",
            MeshData::from_mesh(&grid).with_colors(&grid_colors),
        ),
        (
            "grid-colors.gltf",
            MeshData::from_mesh(&grid).with_colors(&grid_colors),
        ),
        ("strip.glb", strip),
        ("name with spaces é.gltf", MeshData::from_mesh(&tet)),
    ];
    let mut files = Vec::new();
    for (name, data) in &cases {
        let path = dir.join(name);
        write_mesh(&path, data).unwrap();
        files.push(path);
    }
    let embedded = dir.join("embedded.gltf");
    fs::write(
        &embedded,
        encode_mesh(MeshFormat::Gltf, &MeshData::from_mesh(&tet)).unwrap(),
    )
    .unwrap();
    files.push(embedded);

    let (ok, stdout) = common::run_validator(&files);
    assert!(ok, "the validator reports problems");
    for file in &files {
        let line = format!("{}: 0 errors, 0 warnings,", file.display());
        assert!(
            stdout.contains(&line),
            "no clean report for {}",
            file.display()
        );
    }

    // A negative control: the harness must notice a broken file. Our own .gltf with a wrong
    // POSITION max, sharing tetrahedron.bin.
    let mut broken: serde_json::Value =
        serde_json::from_slice(&fs::read(dir.join("tetrahedron.gltf")).unwrap()).unwrap();
    broken["accessors"][0]["max"] = serde_json::json!([0.0, 0.0, 0.0]);
    let broken_path = dir.join("broken.gltf");
    fs::write(&broken_path, serde_json::to_vec(&broken).unwrap()).unwrap();
    let (ok, stdout) = common::run_validator(&[broken_path]);
    assert!(!ok, "the validator run fails on a broken file");
    assert!(stdout.contains("ACCESSOR_MAX_MISMATCH"), "{stdout}");
    fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------------------------------
// OBJ

#[test]
fn obj_text_is_exact() {
    let positions = [
        DVec3::new(0.1, -2.5, 1e-3),
        DVec3::new(1.0, 0.0, -0.0),
        DVec3::new(1.0 / 3.0, 123456.789, 0.5),
    ];
    let triangles = [[0, 1, 2]];
    let data = MeshData {
        positions: &positions,
        triangles: &triangles,
        normals: None,
        colors: None,
    };
    let text = String::from_utf8(encode_mesh(MeshFormat::Obj, &data).unwrap()).unwrap();
    assert_eq!(
        text,
        "# ellip\nv 0.1 -2.5 0.001\nv 1 0 -0\nv 0.33333334 123456.79 0.5\nf 1 2 3\n"
    );
    let normals = [DVec3::Z, DVec3::Z, DVec3::new(0.0, 0.6, 0.8)];
    let text = encode_mesh(MeshFormat::Obj, &data.with_normals(&normals)).unwrap();
    let text = String::from_utf8(text).unwrap();
    assert!(text.ends_with("vn 0 0 1\nvn 0 0 1\nvn 0 0.6 0.8\nf 1//1 2//2 3//3\n"));
}

#[test]
fn obj_reads_back_with_tobj() {
    let dir = scratch("obj");
    let mesh = wavy_grid(40);
    let normals = mesh.vertex_normals();
    let colors = colors_for(mesh.vertex_count());
    for with_normals in [false, true] {
        let mut data = MeshData::from_mesh(&mesh).with_colors(&colors);
        if with_normals {
            data = data.with_normals(&normals);
        }
        let path = dir.join("grid.obj");
        write_mesh(&path, &data).unwrap();
        let (models, _) = tobj::load_obj(&path, &tobj::LoadOptions::default()).unwrap();
        assert_eq!(models.len(), 1);
        let m = &models[0].mesh;
        // tobj renumbers vertices in order of first use, so compare corner by corner.
        assert_eq!(m.positions.len(), 3 * mesh.vertex_count());
        let flat: Vec<u32> = mesh.faces().iter().flatten().copied().collect();
        assert_eq!(m.indices.len(), flat.len());
        // tobj reads in f64 here (the `use_f64` feature); each value is a written f32.
        let read_vec3 = |values: &[f64], i: u32| {
            let i = 3 * i as usize;
            Vec3::new(values[i] as f32, values[i + 1] as f32, values[i + 2] as f32)
        };
        let mismatched = (0..flat.len())
            .filter(|&k| {
                read_vec3(&m.positions, m.indices[k])
                    != mesh.positions()[flat[k] as usize].as_vec3()
            })
            .count();
        assert_eq!(
            mismatched, 0,
            "corners whose position is not the exact f32 value"
        );
        assert!(m.vertex_color.is_empty(), "colours are not written to OBJ");
        if with_normals {
            assert_eq!(m.normal_indices.len(), flat.len());
            let mismatched = (0..flat.len())
                .filter(|&k| {
                    read_vec3(&m.normals, m.normal_indices[k])
                        != normals[flat[k] as usize].as_vec3()
                })
                .count();
            assert_eq!(
                mismatched, 0,
                "corners whose normal is not the exact f32 value"
            );
        } else {
            assert!(m.normals.is_empty());
        }
    }
    fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------------------------------
// PLY

/// A binary little-endian PLY in the exact layout we write, split into its parts.
struct Ply {
    header: String,
    vertex_records: Vec<Vec<u8>>,
    faces: Vec<[i32; 3]>,
}

/// Reads our PLY layout back: header up to `end_header`, then fixed-size vertex records of
/// `vertex_size` bytes and faces as a count byte of 3 and three `int`s. The body must be
/// used up exactly.
fn read_ply(bytes: &[u8], vertex_size: usize) -> Ply {
    let end = b"end_header\n";
    let at = bytes
        .windows(end.len())
        .position(|w| w == end)
        .expect("header ends");
    let header = String::from_utf8(bytes[..at + end.len()].to_vec()).unwrap();
    let count = |element: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (nv, nf) = (count("vertex"), count("face"));
    let mut body = &bytes[at + end.len()..];
    let mut vertex_records = Vec::new();
    for _ in 0..nv {
        let (record, rest) = body.split_at(vertex_size);
        vertex_records.push(record.to_vec());
        body = rest;
    }
    let mut faces = Vec::new();
    for _ in 0..nf {
        assert_eq!(body[0], 3, "every face has three vertices");
        let int = |k: usize| i32::from_le_bytes(body[1 + 4 * k..5 + 4 * k].try_into().unwrap());
        faces.push([int(0), int(1), int(2)]);
        body = &body[13..];
    }
    assert!(body.is_empty(), "{} bytes after the last face", body.len());
    Ply {
        header,
        vertex_records,
        faces,
    }
}

/// The `k`-th little-endian f32 of a record.
fn f32_at(record: &[u8], k: usize) -> f32 {
    f32::from_le_bytes(record[4 * k..4 * k + 4].try_into().unwrap())
}

#[test]
fn ply_reads_back() {
    let mesh = tetrahedron();
    let normals = mesh.vertex_normals();
    let colors = colors_for(4);
    let plain = encode_mesh(MeshFormat::Ply, &MeshData::from_mesh(&mesh)).unwrap();
    let ply = read_ply(&plain, 12);
    assert_eq!(
        ply.header,
        "ply\nformat binary_little_endian 1.0\ncomment ellip\nelement vertex 4\n\
         property float x\nproperty float y\nproperty float z\nelement face 4\n\
         property list uchar int vertex_indices\nend_header\n"
    );
    for (record, p) in ply.vertex_records.iter().zip(mesh.positions()) {
        let got = Vec3::new(f32_at(record, 0), f32_at(record, 1), f32_at(record, 2));
        assert_eq!(got, p.as_vec3());
    }
    let faces: Vec<[i32; 3]> = mesh.faces().iter().map(|f| f.map(|i| i as i32)).collect();
    assert_eq!(ply.faces, faces);

    let full = MeshData::from_mesh(&mesh)
        .with_normals(&normals)
        .with_colors(&colors);
    let bytes = encode_mesh(MeshFormat::Ply, &full).unwrap();
    let ply = read_ply(&bytes, 28);
    assert!(ply.header.contains(
        "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n\
         element face 4\n"
    ));
    for (v, record) in ply.vertex_records.iter().enumerate() {
        let p = Vec3::new(f32_at(record, 0), f32_at(record, 1), f32_at(record, 2));
        let n = Vec3::new(f32_at(record, 3), f32_at(record, 4), f32_at(record, 5));
        assert_eq!(p, mesh.positions()[v].as_vec3());
        assert_eq!(n, normals[v].as_vec3());
        assert_eq!(record[24..28], colors[v]);
    }
    assert_eq!(ply.faces, faces);
}

// ---------------------------------------------------------------------------------------
// Every format

const WRITTEN: [(&str, MeshFormat); 4] = [
    ("obj", MeshFormat::Obj),
    ("ply", MeshFormat::Ply),
    ("glb", MeshFormat::Glb),
    ("gltf", MeshFormat::Gltf),
];

#[test]
fn output_is_byte_deterministic_and_write_matches_encode() {
    let dir = scratch("determinism");
    let mesh = wavy_grid(30);
    let colors = colors_for(mesh.vertex_count());
    let data = MeshData::from_mesh(&mesh).with_colors(&colors);
    for (ext, format) in WRITTEN {
        let a = encode_mesh(format, &data).unwrap();
        let b = encode_mesh(format, &data).unwrap();
        assert_eq!(a, b, "{ext}: encoding twice gives the same bytes");
        let path = dir.join(format!("mesh.{ext}"));
        write_mesh(&path, &data).unwrap();
        let first = fs::read(&path).unwrap();
        write_mesh(&path, &data).unwrap();
        assert_eq!(first, fs::read(&path).unwrap(), "{ext}: writing twice");
        if format != MeshFormat::Gltf {
            assert_eq!(first, a, "{ext}: the file holds what encode_mesh returns");
        }
    }
    assert_eq!(
        listing(&dir),
        ["mesh.bin", "mesh.glb", "mesh.gltf", "mesh.obj", "mesh.ply"],
        "no temporary files are left behind"
    );
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn invalid_data_is_rejected_before_anything_is_written() {
    let dir = scratch("invalid");
    let p = [DVec3::ZERO, DVec3::X, DVec3::Y];
    let t = [[0u32, 1, 2]];
    let good = MeshData {
        positions: &p,
        triangles: &t,
        normals: None,
        colors: None,
    };
    let two_normals = [DVec3::Z; 2];
    let zero_normals = [DVec3::Z, DVec3::ZERO, DVec3::Z];
    let nan_normals = [DVec3::Z, DVec3::new(0.0, f64::NAN, 1.0), DVec3::Z];
    // Non-zero in f64 but zero in f32.
    let vanishing_normals = [DVec3::Z, DVec3::new(1e-50, 0.0, 0.0), DVec3::Z];
    let four_colors = [[0u8; 4]; 4];
    let out_of_range = [[0u32, 1, 3]];
    let nan_position = [DVec3::ZERO, DVec3::new(f64::NAN, 0.0, 0.0), DVec3::Y];
    let infinite_position = [DVec3::ZERO, DVec3::X, DVec3::new(0.0, f64::INFINITY, 0.0)];
    let beyond_f32 = [DVec3::ZERO, DVec3::new(1e39, 0.0, 0.0), DVec3::Y];
    let no_triangles: [[u32; 3]; 0] = [];
    let cases: Vec<(&str, MeshData<'_>)> = vec![
        ("normals", good.with_normals(&two_normals)),
        ("normal", good.with_normals(&zero_normals)),
        ("normal", good.with_normals(&nan_normals)),
        ("normal", good.with_normals(&vanishing_normals)),
        ("colors", good.with_colors(&four_colors)),
        (
            "triangle index",
            MeshData {
                triangles: &out_of_range,
                ..good
            },
        ),
        (
            "position",
            MeshData {
                positions: &nan_position,
                ..good
            },
        ),
        (
            "position",
            MeshData {
                positions: &infinite_position,
                ..good
            },
        ),
        (
            "position",
            MeshData {
                positions: &beyond_f32,
                ..good
            },
        ),
        (
            "triangles",
            MeshData {
                triangles: &no_triangles,
                ..good
            },
        ),
    ];
    for (expected, data) in &cases {
        for (ext, format) in WRITTEN {
            let written = write_mesh(&dir.join(format!("bad.{ext}")), data);
            let encoded = encode_mesh(format, data);
            for result in [written.map(|_| Vec::new()), encoded] {
                match result {
                    Err(ExportError::InvalidData { what, detail }) => {
                        assert_eq!(what, *expected, "{ext}: {detail}");
                        assert!(!detail.is_empty());
                    }
                    other => panic!("{ext}: expected InvalidData({expected}), got {other:?}"),
                }
            }
        }
    }
    assert!(listing(&dir).is_empty(), "nothing was written");
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn formats_we_do_not_write_are_unsupported() {
    let dir = scratch("unsupported");
    let mesh = tetrahedron();
    let data = MeshData::from_mesh(&mesh);
    for name in ["mesh.stl", "mesh.off", "mesh.xyz", "mesh"] {
        let path = dir.join(name);
        match write_mesh(&path, &data) {
            Err(ExportError::UnsupportedFormat { path: Some(p), .. }) => assert_eq!(p, path),
            other => panic!("{name}: expected UnsupportedFormat, got {other:?}"),
        }
    }
    for format in [MeshFormat::Stl, MeshFormat::Off] {
        assert!(matches!(
            encode_mesh(format, &data),
            Err(ExportError::UnsupportedFormat { path: None, .. })
        ));
    }
    assert!(listing(&dir).is_empty());
    let message = write_mesh(&dir.join("mesh.stl"), &data)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("mesh.stl") && message.contains("stl"),
        "{message}"
    );
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn io_failure_is_reported_and_leaves_no_file() {
    let dir = scratch("io");
    let mesh = tetrahedron();
    let data = MeshData::from_mesh(&mesh);
    for (ext, _) in WRITTEN {
        let path = dir.join("missing-folder").join(format!("mesh.{ext}"));
        match write_mesh(&path, &data) {
            Err(ExportError::Io { path: p, .. }) => {
                assert!(p.starts_with(dir.join("missing-folder")), "{}", p.display())
            }
            other => panic!("{ext}: expected Io, got {other:?}"),
        }
    }
    assert!(listing(&dir).is_empty());
    fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn existing_files_are_replaced() {
    let dir = scratch("replace");
    let mesh = tetrahedron();
    let data = MeshData::from_mesh(&mesh);
    for (ext, format) in WRITTEN {
        let path = dir.join(format!("mesh.{ext}"));
        fs::write(&path, b"old contents that are longer than nothing").unwrap();
        write_mesh(&path, &data).unwrap();
        if format != MeshFormat::Gltf {
            assert_eq!(
                fs::read(&path).unwrap(),
                encode_mesh(format, &data).unwrap()
            );
        } else {
            assert!(fs::read(&path).unwrap().starts_with(b"{"));
        }
    }
    assert_eq!(
        listing(&dir),
        ["mesh.bin", "mesh.glb", "mesh.gltf", "mesh.obj", "mesh.ply"]
    );
    fs::remove_dir_all(&dir).unwrap();
}
