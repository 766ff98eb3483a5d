//! The `ellip` binary as users and scripts see it: exit codes, one-line errors, JSON.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn ellip(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ellip"))
        .args(args)
        .output()
        .expect("the ellip binary runs")
}

fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/meshes")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ellip-cli-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An error is exit code 1 and exactly one line on stderr, never a panic message.
fn assert_clean_failure(out: &Output, context: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{context}: stderr {stderr}");
    assert_eq!(
        stderr.lines().count(),
        1,
        "{context}: one line, got {stderr:?}"
    );
    assert!(stderr.starts_with("ellip: error: "), "{context}: {stderr}");
    assert!(!stderr.contains("panicked"), "{context}: {stderr}");
}

#[test]
fn info_reports_a_closed_sphere_as_json() {
    let out = ellip(&["info", &fixture("icosphere.obj"), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    assert_eq!(v["closed"], true);
    assert_eq!(v["manifold"], true);
    assert_eq!(v["genus"], 0);
    assert_eq!(v["components"], 1);
    assert_eq!(v["boundary_loops"], 0);
    // A unit icosphere: volume a little under 4/3 π.
    let volume = v["volume"].as_f64().unwrap();
    assert!(
        (volume - 4.0 / 3.0 * std::f64::consts::PI).abs() < 0.05,
        "{volume}"
    );
    // Mean curvature of a unit sphere is 1.
    let median = v["curvature"]["median"].as_f64().unwrap();
    assert!((median - 1.0).abs() < 0.02, "{median}");
}

#[test]
fn info_text_names_the_topology() {
    let out = ellip(&["info", &fixture("torus.obj")]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("genus 1"), "{text}");
}

#[test]
fn convert_round_trips_through_every_written_format() {
    let dir = temp_dir("convert");
    for ext in ["obj", "ply", "glb", "gltf"] {
        let out_path = dir.join(format!("torus.{ext}"));
        let out = ellip(&[
            "convert",
            &fixture("torus.obj"),
            out_path.to_str().unwrap(),
            "-q",
        ]);
        assert!(
            out.status.success(),
            "{ext}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let back = ellip(&["info", out_path.to_str().unwrap(), "--json"]);
        assert!(
            back.status.success(),
            "{ext}: {}",
            String::from_utf8_lossy(&back.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&back.stdout).unwrap();
        assert_eq!(v["genus"], 1, "{ext}");
        assert_eq!(v["closed"], true, "{ext}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn convert_refuses_to_overwrite_its_input() {
    let dir = temp_dir("overwrite");
    let path = dir.join("cube.obj");
    std::fs::copy(fixture("cube.obj"), &path).unwrap();
    let before = std::fs::read(&path).unwrap();
    let p = path.to_str().unwrap();
    let out = ellip(&["convert", p, p]);
    assert_clean_failure(&out, "convert onto itself");
    assert_eq!(std::fs::read(&path).unwrap(), before);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_usage_exits_2() {
    assert_eq!(ellip(&["info"]).status.code(), Some(2));
    assert_eq!(ellip(&["frobnicate"]).status.code(), Some(2));
    assert_eq!(ellip(&["convert", "a.obj"]).status.code(), Some(2));
}

#[test]
fn help_shows_examples() {
    let out = ellip(&["--help"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Examples:") && text.contains("ellip convert"));
}

#[test]
fn malformed_files_fail_cleanly() {
    let dir = temp_dir("malformed");
    let cases: &[(&str, &[u8])] = &[
        ("empty.obj", b""),
        ("empty.ply", b""),
        ("empty.stl", b""),
        ("empty.off", b""),
        ("empty.glb", b""),
        ("empty.gltf", b""),
        ("garbage.obj", b"\x00\x01\x02\xff\xfe garbage"),
        ("garbage.ply", b"\x00\x01\x02\xff\xfe garbage"),
        ("garbage.stl", b"\x00\x01\x02\xff\xfe garbage"),
        ("garbage.off", b"\x00\x01\x02\xff\xfe garbage"),
        ("garbage.glb", b"\x00\x01\x02\xff\xfe garbage"),
        ("garbage.gltf", b"{ not json"),
        ("nan.obj", b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
        ("range.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
        ("short.obj", b"v 0 0 0\nv 1 0 0\nf 1 2\n"),
        (
            "forged.ply",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n",
        ),
        ("forged.stl", b"binary stl header padded to eighty bytes.......................................\xff\xff\xff\xff"),
        ("truncated.off", b"OFF\n4 4 0\n0 0 0\n1 0 0\n"),
        ("unknown.xyz", b"1 2 3"),
        ("missing-file.obj", b""),
    ];
    for (name, bytes) in cases {
        let path = dir.join(name);
        if *name != "missing-file.obj" {
            std::fs::write(&path, bytes).unwrap();
        }
        let out = ellip(&["info", path.to_str().unwrap()]);
        assert_clean_failure(&out, name);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains(name),
            "{name}: the message names the file: {stderr}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `info` shows a file's remesh hint in words, and `--json` as its code; a file without one
/// has none (the golden 1.1 file names the stored arcs, no ears pruned, rays where
/// untangling would drop points).
#[test]
fn info_shows_the_remesh_hint() {
    let golden = |name: &str| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures/ellip/v1")
            .join(name)
            .to_string_lossy()
            .into_owned()
    };
    let hinted = golden("two-hemispheres-hinted.ellip");
    let text = ellip(&["info", &hinted]);
    assert!(text.status.success());
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains(".ellip 1.1"), "{text}");
    assert!(
        text.contains("remesh hint     37: stored arcs, no ears pruned, untangled, closest points (rays where untangling would drop points)"),
        "{text}"
    );
    let v: serde_json::Value =
        serde_json::from_slice(&ellip(&["info", &hinted, "--json"]).stdout).unwrap();
    assert_eq!(v["remesh_hint"], 37);
    assert_eq!(v["version"], "1.1");
    let plain = golden("two-hemispheres.ellip");
    let text = String::from_utf8_lossy(&ellip(&["info", &plain]).stdout).into_owned();
    assert!(!text.contains("remesh hint"), "{text}");
    let v: serde_json::Value =
        serde_json::from_slice(&ellip(&["info", &plain, "--json"]).stdout).unwrap();
    assert!(v["remesh_hint"].is_null());
    assert_eq!(v["version"], "1.0");
}

#[test]
fn encode_writes_an_ellip_file_that_info_reads() {
    let dir = temp_dir("encode");
    let out = dir.join("blob2.ellip");
    let run = ellip(&[
        "encode",
        &fixture("blob2.obj"),
        "-k",
        "4",
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(report["bytes"].as_u64(), Some(bytes.len() as u64));
    assert_eq!(report["regions"], 4);
    assert!(report["ratio_to_raw"].as_f64().unwrap() > 10.0);
    // The encoder decoded its file: clean, no region split.
    assert_eq!(report["requested_regions"], 4);
    assert_eq!(report["split_rounds"], 0);
    assert_eq!(report["decode_check"], "clean");

    let info = ellip(&["info", out.to_str().unwrap(), "--json"]);
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(v["version"], "1.0");
    assert_eq!(v["regions"].as_array().unwrap().len(), 4);
    assert_eq!(v["source_faces"], report["faces"]);
    assert_eq!(v["bytes"].as_u64(), Some(bytes.len() as u64));

    // The same input and options give the same bytes; `-o -` writes them to stdout.
    let piped = ellip(&["encode", &fixture("blob2.obj"), "-k", "4", "-o", "-", "-q"]);
    assert!(piped.status.success());
    assert_eq!(piped.stdout, bytes);
    // Without the check: the same file here, and the report says it was not checked.
    let unchecked = dir.join("unchecked.ellip");
    let run = ellip(&[
        "encode",
        &fixture("blob2.obj"),
        "-k",
        "4",
        "-o",
        unchecked.to_str().unwrap(),
        "--no-verify",
        "--json",
    ]);
    assert!(run.status.success());
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["decode_check"], "not checked");
    assert_eq!(std::fs::read(&unchecked).unwrap(), bytes);

    // A damaged file is one clean error line.
    let mut damaged = bytes.clone();
    let middle = damaged.len() / 2;
    damaged[middle] ^= 0x40;
    let bad = dir.join("damaged.ellip");
    std::fs::write(&bad, &damaged).unwrap();
    assert_clean_failure(&ellip(&["info", bad.to_str().unwrap()]), "damaged .ellip");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `count` unit icospheres (80 faces each) in a row, as OBJ text: a mesh of `count`
/// separate components.
fn separate_spheres_obj(count: usize) -> String {
    let sphere = ellip::synth::shapes::icosphere(1.0, 1);
    let n = sphere.vertex_count();
    let mut obj = String::new();
    for c in 0..count {
        for p in sphere.positions() {
            obj += &format!("v {} {} {}\n", p.x + 3.0 * c as f64, p.y, p.z);
        }
    }
    for c in 0..count {
        for f in sphere.faces() {
            let [a, b, d] = f.map(|i| i as usize + c * n + 1);
            obj += &format!("f {a} {b} {d}\n");
        }
    }
    obj
}

#[test]
fn a_mesh_of_fewer_faces_than_the_default_regions_encodes_with_one_region_a_face() {
    let dir = temp_dir("tetrahedron");
    let input = dir.join("tetrahedron.obj");
    std::fs::write(
        &input,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let input = input.to_string_lossy().into_owned();
    let output = dir.join("tetrahedron.ellip").to_string_lossy().into_owned();
    let out = ellip(&["encode", &input, "-o", &output, "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("only 4 faces: 4 regions, one a face"),
        "{stderr}"
    );
    assert!(!stderr.contains("separate components"), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    assert_eq!(v["requested_regions"], 4);
    assert_eq!(v["decode_check"], "clean");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_mesh_of_more_pieces_than_the_default_regions_encodes_with_one_more_region_each() {
    let dir = temp_dir("pieces");
    let input = dir.join("spheres.obj");
    std::fs::write(&input, separate_spheres_obj(14)).unwrap();
    let input = input.to_string_lossy().into_owned();
    let output = dir.join("spheres.ellip").to_string_lossy().into_owned();
    // Without -k: 12 regions and one for each of the 13 further pieces, said on stderr.
    let out = ellip(&["encode", &input, "-o", &output, "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("14 separate components: 25 regions"),
        "{stderr}"
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    assert_eq!(v["requested_regions"], 25);
    assert_eq!(v["decode_check"], "clean");
    // Quiet: no note.
    std::fs::remove_file(&output).unwrap();
    let out = ellip(&["encode", &input, "-o", &output, "--quiet"]);
    assert!(out.status.success());
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // An explicit -k below the piece count is refused, in one line.
    std::fs::remove_file(&output).unwrap();
    let out = ellip(&["encode", &input, "-o", &output, "-k", "12"]);
    assert_clean_failure(&out, "-k 12 for 14 pieces");
    assert!(String::from_utf8_lossy(&out.stderr).contains("14 separate components"));
    // Rate control searches from one region per piece: a budget a byte under the default
    // file's makes it bisect between 14 regions and the default 25.
    let out = ellip(&["encode", &input, "-o", &output, "--json", "--quiet"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    let budget = v["bytes"].as_u64().unwrap() - 1;
    std::fs::remove_file(&output).unwrap();
    let out = ellip(&[
        "encode",
        &input,
        "-o",
        &output,
        "--max-bytes",
        &budget.to_string(),
        "--json",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    let regions = v["regions"].as_u64().unwrap();
    assert!((14..25).contains(&regions), "{v}");
    assert!(v["bytes"].as_u64().unwrap() <= budget, "{v}");
    assert!(v["rate_control_probes"].as_u64().unwrap() >= 2, "{v}");
    // Each probe, in order; the file kept is one that fits.
    let probes = v["rate_control"].as_array().unwrap();
    assert_eq!(
        probes.len() as u64,
        v["rate_control_probes"].as_u64().unwrap()
    );
    assert!(
        probes.iter().any(|p| p["bytes"] == v["bytes"]
            && p["regions"].as_u64().is_some()
            && p["rms_fraction"].as_f64() == Some(v["error"]["rms_fraction"].as_f64().unwrap())
            && p["clean"].as_bool().is_some()),
        "{v}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
