//! `ellip segment` as users and scripts see it: the coloured output files, the statistics
//! (text and JSON), `--planes`, and one-line errors for bad options.
//!
//! The glTF outputs also go through the Khronos glTF Validator when it is installed (see
//! `tests/common/mod.rs`).

use ellip::import::{read_mesh, ImportOptions};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

/// Faces of fixtures/meshes/blob2.obj.
const BLOB2_FACES: usize = 8044;

fn ellip(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ellip"))
        .args(args)
        .output()
        .expect("the ellip binary runs")
}

fn blob2() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/meshes/blob2.obj")
        .to_string_lossy()
        .into_owned()
}

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("ellip-segment-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("temporary paths are UTF-8")
}

fn assert_success(out: &Output, context: &str) {
    assert!(
        out.status.success(),
        "{context}: exit {:?}, stderr {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// An error is exit 1 (ours) or 2 (clap's usage errors) and exactly one line on stderr.
fn assert_clean_failure(out: &Output, context: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        matches!(out.status.code(), Some(1 | 2)),
        "{context}: exit {:?}, stderr {stderr}",
        out.status.code()
    );
    assert_eq!(
        stderr.lines().count(),
        1,
        "{context}: one line, got {stderr:?}"
    );
    assert!(stderr.starts_with("ellip: error: "), "{context}: {stderr}");
    assert!(out.stdout.is_empty(), "{context}: nothing on stdout");
}

/// The JSON statistics, checked for what every run must satisfy: `k` regions whose faces add
/// up to the mesh's, finite non-negative errors, and the total RMS within the regions' range.
fn check_stats(stdout: &[u8], k: usize, proxy: &str) -> serde_json::Value {
    let v: serde_json::Value = serde_json::from_slice(stdout).expect("stdout is only JSON");
    assert_eq!(v["proxy"], proxy);
    assert_eq!(v["faces"].as_u64(), Some(BLOB2_FACES as u64));
    let regions = v["regions"].as_array().expect("regions");
    assert_eq!(regions.len(), k);
    let mut faces = 0;
    let mut rms = Vec::new();
    for (i, r) in regions.iter().enumerate() {
        assert_eq!(r["region"].as_u64(), Some(i as u64));
        let n = r["faces"].as_u64().expect("faces");
        assert!(n > 0, "region {i} is empty");
        faces += n;
        let e = r["rms_error_percent"].as_f64().expect("rms");
        assert!(e.is_finite() && e >= 0.0, "region {i}: rms {e}");
        rms.push(e);
        assert!(r["error"]
            .as_f64()
            .is_some_and(|e| e.is_finite() && e >= 0.0));
        assert_eq!(r["color"].as_array().map(Vec::len), Some(3));
    }
    assert_eq!(
        faces, BLOB2_FACES as u64,
        "every face in exactly one region"
    );
    let total = v["rms_error_percent"].as_f64().expect("total rms");
    let (lo, hi) = rms.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| {
        (lo.min(x), hi.max(x))
    });
    assert!(
        total >= lo * (1.0 - 1e-12) && total <= hi * (1.0 + 1e-12),
        "total RMS {total} outside the regions' [{lo}, {hi}]"
    );
    let colors: std::collections::HashSet<String> =
        regions.iter().map(|r| r["color"].to_string()).collect();
    assert_eq!(colors.len(), k, "every region has its own colour");
    v
}

/// The colour of each face of a PLY written by ellip (binary, float x y z, float normals,
/// uchar RGBA), checking that its three corners agree.
fn ply_face_colors(bytes: &[u8]) -> Vec<[u8; 4]> {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("PLY header")
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(header.contains("property uchar red"), "{header}");
    assert!(header.contains("property float nx"), "{header}");
    let count = |element: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {element} ")))
            .expect("element count")
            .parse()
            .unwrap()
    };
    let (vertices, faces) = (count("vertex"), count("face"));
    let record = 28;
    let colors: Vec<[u8; 4]> = (0..vertices)
        .map(|v| {
            let at = end + v * record + 24;
            bytes[at..at + 4].try_into().unwrap()
        })
        .collect();
    let mut at = end + vertices * record;
    let mut out = Vec::with_capacity(faces);
    for f in 0..faces {
        assert_eq!(bytes[at], 3);
        let corner = |k: usize| {
            let i = i32::from_le_bytes(bytes[at + 1 + 4 * k..at + 5 + 4 * k].try_into().unwrap());
            colors[usize::try_from(i).unwrap()]
        };
        let c = corner(0);
        assert!(
            corner(1) == c && corner(2) == c,
            "face {f}: corners differ in colour"
        );
        out.push(c);
        at += 13;
    }
    assert_eq!(at, bytes.len());
    out
}

/// The colour of each face of a GLB written by ellip, checking that its corners agree.
fn glb_face_colors(path: &Path) -> Vec<[u8; 4]> {
    let glb = gltf::Gltf::open(path).expect("GLB parses");
    let blob = glb.blob.clone().expect("GLB has a binary chunk");
    let primitive = glb
        .meshes()
        .next()
        .and_then(|m| m.primitives().next())
        .expect("one primitive");
    let reader = primitive.reader(|_| Some(&blob));
    let colors: Vec<[u8; 4]> = reader
        .read_colors(0)
        .expect("COLOR_0")
        .into_rgba_u8()
        .collect();
    let indices: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
    indices
        .chunks_exact(3)
        .enumerate()
        .map(|(f, t)| {
            let c = colors[t[0] as usize];
            assert!(
                colors[t[1] as usize] == c && colors[t[2] as usize] == c,
                "face {f}: corners differ in colour"
            );
            c
        })
        .collect()
}

/// How many faces have each colour, largest first.
fn color_histogram(colors: &[[u8; 4]]) -> Vec<usize> {
    let mut counts: HashMap<[u8; 4], usize> = HashMap::new();
    for c in colors {
        *counts.entry(*c).or_default() += 1;
    }
    let mut out: Vec<usize> = counts.into_values().collect();
    out.sort_unstable_by(|a, b| b.cmp(a));
    out
}

/// The region sizes of the JSON statistics, largest first.
fn region_sizes(v: &serde_json::Value) -> Vec<usize> {
    let mut out: Vec<usize> = v["regions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["faces"].as_u64().unwrap() as usize)
        .collect();
    out.sort_unstable_by(|a, b| b.cmp(a));
    out
}

#[test]
fn segments_into_coloured_glb_and_ply_with_json_statistics() {
    let dir = temp_dir("formats");
    let glb = dir.join("seg.glb");
    let ply = dir.join("seg.ply");
    let out = ellip(&[
        "segment",
        &blob2(),
        "-k",
        "4",
        "-o",
        path_str(&glb),
        "--json",
    ]);
    assert_success(&out, "glb");
    let stats = check_stats(&out.stdout, 4, "ellipsoid");
    for r in stats["regions"].as_array().unwrap() {
        let radii: Vec<f64> = r["radii"]
            .as_array()
            .expect("radii")
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(radii.len(), 3);
        assert!(radii.iter().all(|x| x.is_finite() && *x > 0.0), "{radii:?}");
        assert!(matches!(r["sign"].as_str(), Some("positive" | "negative")));
    }
    assert_eq!(stats["colored"], true);
    // Without a terminal there is no progress bar: stderr only says what was written.
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.starts_with("wrote "), "{stderr}");

    // The GLB reads back with the same faces; each face has one colour, and the colours
    // split the faces exactly as the regions do.
    let back = read_mesh(&glb, &ImportOptions::default()).expect("the GLB reads back");
    assert_eq!(back.mesh.face_count(), BLOB2_FACES);
    assert!(
        back.mesh.topology().is_closed(),
        "welding the copies closes it"
    );
    let glb_colors = glb_face_colors(&glb);
    assert_eq!(glb_colors.len(), BLOB2_FACES);
    assert_eq!(color_histogram(&glb_colors), region_sizes(&stats));

    // The same segmentation (same seed) as PLY: sRGB colours, which the JSON lists.
    let out = ellip(&[
        "segment",
        &blob2(),
        "-k",
        "4",
        "-o",
        path_str(&ply),
        "--json",
        "-q",
    ]);
    assert_success(&out, "ply");
    assert!(out.stderr.is_empty(), "--quiet: {:?}", out.stderr);
    let stats_ply = check_stats(&out.stdout, 4, "ellipsoid");
    assert_eq!(stats_ply["regions"], stats["regions"], "deterministic");
    let ply_colors = ply_face_colors(&std::fs::read(&ply).unwrap());
    assert_eq!(ply_colors.len(), BLOB2_FACES);
    for (r, faces) in stats["regions"].as_array().unwrap().iter().zip(0..) {
        let rgb: Vec<u8> = r["color"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap() as u8)
            .collect();
        let n = ply_colors.iter().filter(|c| c[..3] == rgb[..]).count();
        assert_eq!(n as u64, r["faces"].as_u64().unwrap(), "region {faces}");
    }
    let back = read_mesh(&ply, &ImportOptions::default()).expect("the PLY reads back");
    assert_eq!(back.mesh.face_count(), BLOB2_FACES);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn text_statistics_list_every_region_and_the_total() {
    let out = ellip(&["segment", &blob2(), "-k", "4", "--iterations", "5"]);
    assert_success(&out, "text");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let rows = stdout
        .lines()
        .filter(|l| {
            l.split_whitespace()
                .next()
                .is_some_and(|w| w.parse::<u32>().is_ok())
        })
        .count();
    assert_eq!(rows, 4, "{stdout}");
    assert!(
        stdout.lines().any(|l| l.starts_with("total")
            && l.contains(&BLOB2_FACES.to_string())
            && l.ends_with('%')),
        "{stdout}"
    );
    assert!(stdout.contains("RMS radial error"), "{stdout}");
    assert!(
        out.stderr.is_empty(),
        "no -o, no terminal: {:?}",
        out.stderr
    );
}

#[test]
fn planes_segment_with_the_l21_metric() {
    let dir = temp_dir("planes");
    let glb = dir.join("planes.glb");
    let out = ellip(&[
        "segment",
        &blob2(),
        "-k",
        "4",
        "--planes",
        "--json",
        "-o",
        path_str(&glb),
    ]);
    assert_success(&out, "planes");
    let stats = check_stats(&out.stdout, 4, "plane");
    assert!(stats.get("mode").is_none(), "no mode for planes");
    for r in stats["regions"].as_array().unwrap() {
        let n: Vec<f64> = r["normal"]
            .as_array()
            .expect("normal")
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let length = n.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((length - 1.0).abs() < 1e-12, "unit normal: {n:?}");
        assert!(r.get("radii").is_none());
    }
    let glb_colors = glb_face_colors(&glb);
    assert_eq!(color_histogram(&glb_colors), region_sizes(&stats));
    std::fs::remove_dir_all(&dir).ok();
}

/// `--area-weighting` weights each face's error by its area: the same regions' count, a
/// different metric (blob2's faces differ in area, so the regions differ); it chooses
/// ellipsoids and is refused with `--planes`.
#[test]
fn area_weighting_is_an_option_of_the_ellipsoid_metric() {
    let blob = blob2();
    let run = |extra: &[&str]| {
        let mut args = vec!["segment", blob.as_str(), "-k", "4", "--json"];
        args.extend_from_slice(extra);
        ellip(&args)
    };
    let plain = run(&[]);
    let weighted = run(&["--area-weighting"]);
    assert_success(&plain, "plain");
    assert_success(&weighted, "area weighting");
    // The regions' face counts, not only their fits, differ.
    let sizes = |stdout: &[u8]| -> Vec<u64> {
        check_stats(stdout, 4, "ellipsoid")["regions"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["faces"].as_u64().unwrap())
            .collect()
    };
    assert_ne!(sizes(&plain.stdout), sizes(&weighted.stdout));
    let refused = run(&["--planes", "--area-weighting"]);
    assert!(!refused.status.success());
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(stderr.contains("--area-weighting"), "{stderr}");
}

#[test]
fn obj_output_has_no_colours_and_says_so() {
    let dir = temp_dir("obj");
    let obj = dir.join("seg.obj");
    let out = ellip(&[
        "segment",
        &blob2(),
        "-k",
        "3",
        "--iterations",
        "3",
        "-o",
        path_str(&obj),
        "--json",
    ]);
    assert_success(&out, "obj");
    let stats: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(stats["colored"], false);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("no vertex colours"), "{stderr}");
    let back = read_mesh(&obj, &ImportOptions::default()).unwrap();
    assert_eq!(back.mesh.face_count(), BLOB2_FACES);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_options_fail_in_one_line() {
    let dir = temp_dir("bad");
    let copy = dir.join("blob2.obj");
    std::fs::copy(blob2(), &copy).unwrap();
    let input = path_str(&copy);
    let cases: &[&[&str]] = &[
        &["-k", "0"],
        &["-k", "-3"],
        &["--tolerance", "-1"],
        &["--tolerance", "0"],
        &["--tolerance", "nan"],
        &["-k", "3", "--tolerance", "0.01"],
        &["--threads", "0"],
        &["--alpha", "-1"],
        &["--beta", "inf"],
        &["--planes", "--mode", "volume"],
        &["--planes", "--gamma", "1"],
        &["-o", "out.stl"],
        &["-o", input],
        &["-k", "100000"],
    ];
    for args in cases {
        let mut all = vec!["segment", input];
        all.extend_from_slice(args);
        assert_clean_failure(&ellip(&all), &format!("{args:?}"));
    }
    assert_clean_failure(
        &ellip(&["segment", path_str(&dir.join("missing.obj"))]),
        "missing input",
    );
    // The refused output is the input, untouched.
    assert_eq!(
        std::fs::read(&copy).unwrap(),
        std::fs::read(blob2()).unwrap()
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn khronos_validator_accepts_segmented_gltf_and_glb() {
    if !common::validator_ready() {
        return;
    }
    let dir = temp_dir("validator");
    let glb = dir.join("seg.glb");
    let gltf = dir.join("seg.gltf");
    for (path, extra) in [(&glb, None), (&gltf, Some("--planes"))] {
        let mut args = vec![
            "segment",
            blob2_static(),
            "-k",
            "4",
            "--iterations",
            "5",
            "-q",
            "-o",
            path_str(path),
        ];
        args.extend(extra);
        assert_success(&ellip(&args), &path.display().to_string());
    }
    let files = vec![glb, gltf];
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
    std::fs::remove_dir_all(&dir).ok();
}

/// [`blob2`] as a `&'static str`, for argument lists.
fn blob2_static() -> &'static str {
    concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/meshes/blob2.obj")
}
