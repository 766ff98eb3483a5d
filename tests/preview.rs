//! `ellip preview`: the PNG's size, background, coverage and region colours, determinism,
//! and meshes that are hard to look at.

use ellip::encode::{encode_mesh, EncodeSettings};
use ellip::format::{decode, Limits};
use ellip::import::{read_mesh, ImportOptions};
use ellip::preview::palette::palette;
use ellip::preview::{render, Image, Panel, RenderOptions, Shading, View, BACKGROUND};
use ellip::remesh::{remesh, RemeshOptions};
use ellip::segment::{RegionCount, SegmentOptions};
use ellip::Mesh;
use glam::DVec3;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn read(name: &str) -> Mesh {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/meshes")
        .join(name);
    read_mesh(&path, &ImportOptions::default()).unwrap().mesh
}

/// Segment labels and the decoded mesh of `mesh` encoded at `k` regions.
fn encode(mesh: &Mesh, k: usize) -> (Vec<u32>, ellip::remesh::Remeshed) {
    let settings = EncodeSettings {
        segment: SegmentOptions {
            regions: RegionCount::Fixed(k),
            ..SegmentOptions::default()
        },
        ..EncodeSettings::default()
    };
    let encoded = encode_mesh(mesh, &settings, &mut |_| {}).unwrap();
    let rep = decode(&encoded.bytes, &Limits::default()).unwrap();
    let decoded = remesh(&rep, &RemeshOptions::default()).unwrap();
    (encoded.segmentation.labels, decoded)
}

/// The image a PNG file holds, checked to be 8-bit RGB.
fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buffer.truncate(info.buffer_size());
    (info.width, info.height, buffer)
}

/// Fraction of the pixels of panel `i` (of width `w`), below row `top`, that are not the
/// background.
fn coverage(rgb: &[u8], width: u32, height: u32, panel: u32, w: u32, top: u32) -> f64 {
    let mut covered = 0usize;
    let mut total = 0usize;
    for y in top..height {
        for x in panel * w..(panel + 1) * w {
            let at = 3 * (y * width + x) as usize;
            total += 1;
            if rgb[at..at + 3] != BACKGROUND {
                covered += 1;
            }
        }
    }
    covered as f64 / total as f64
}

/// Pixels of each exact palette colour among the first `k`, for an unlit render.
fn count_region_colours(image: &Image, k: usize) -> BTreeMap<usize, usize> {
    let colours: Vec<[u8; 3]> = palette(k).iter().map(|c| c.srgb()).collect();
    let mut counts = BTreeMap::new();
    for p in image.as_rgb().chunks_exact(3) {
        if let Some(i) = colours.iter().position(|c| c[..] == *p) {
            *counts.entry(i).or_insert(0) += 1;
        }
    }
    counts
}

/// A test's own scratch directory, removed when the test passes (kept to look at when it
/// fails).
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Scratch {
        let dir = std::env::temp_dir().join(format!("ellip-preview-{test}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

fn ellip(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_ellip"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn a_mesh_gives_three_panels_of_the_asked_size_with_the_object_in_each() {
    let scratch = Scratch::new("panels");
    let blob = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/meshes/blob3.obj");
    let out = scratch.path("blob3.png");
    let args = [
        "preview",
        blob.to_str().unwrap(),
        "-k",
        "5",
        "--size",
        "240x200",
        "-o",
        out.to_str().unwrap(),
    ];
    let run = ellip(&args);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let bytes = std::fs::read(&out).unwrap();
    let (width, height, rgb) = decode_png(&bytes);
    assert_eq!((width, height), (3 * 240, 200));
    // The corners of every panel are background.
    for panel in 0..3 {
        for (x, y) in [(0, height - 1), (239, height - 1), (239, 0)] {
            let at = 3 * (y * width + panel * 240 + x) as usize;
            assert_eq!(rgb[at..at + 3], BACKGROUND, "panel {panel} at ({x}, {y})");
        }
        // Below the caption band (2 × 7 rows at this size), the blob covers 15% to 60% of
        // the panel (measured: 25.8%, the blob being tall in a wide panel); the three panels
        // within 5 points of each other.
        let c = coverage(&rgb, width, height, panel, 240, 14);
        println!("panel {panel}: coverage {c:.3}");
        assert!((0.15..0.6).contains(&c), "panel {panel}: {c}");
        let first = coverage(&rgb, width, height, 0, 240, 14);
        assert!((c - first).abs() < 0.05, "panel {panel}: {c} vs {first}");
    }
    // The same input, the same bytes (another process).
    let again = scratch.path("blob3-again.png");
    let mut args2 = args;
    args2[7] = again.to_str().unwrap();
    assert!(ellip(&args2).status.success());
    assert_eq!(std::fs::read(&again).unwrap(), bytes);
}

#[test]
fn an_ellip_file_gives_two_panels() {
    let scratch = Scratch::new("ellip");
    let blob = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/meshes/blob2.obj");
    let file = scratch.path("blob2.ellip");
    let out = scratch.path("blob2.png");
    let encoded = ellip(&[
        "encode",
        blob.to_str().unwrap(),
        "-k",
        "4",
        "-q",
        "-o",
        file.to_str().unwrap(),
    ]);
    assert!(encoded.status.success());
    let run = ellip(&[
        "preview",
        file.to_str().unwrap(),
        "--size",
        "160x120",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let (width, height, rgb) = decode_png(&std::fs::read(&out).unwrap());
    assert_eq!((width, height), (2 * 160, 120));
    for panel in 0..2 {
        let c = coverage(&rgb, width, height, panel, 160, 7);
        assert!((0.15..0.8).contains(&c), "panel {panel}: {c}");
    }
}

#[test]
fn bad_outputs_and_sizes_are_refused_before_any_work() {
    let scratch = Scratch::new("refused");
    let blob = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/meshes/blob1.obj");
    let blob = blob.to_str().unwrap();
    let png = scratch.path("refused.png");
    let png = png.to_str().unwrap();
    for (args, says) in [
        (vec!["preview", blob, "-o", blob], "PNG"),
        (vec!["preview", blob, "-o", png, "--size", "0x10"], "--size"),
        (vec!["preview", blob, "-o", png, "--size", "640"], "--size"),
        (
            vec!["preview", blob, "-o", png, "--size", "9000x10"],
            "--size",
        ),
        (
            vec!["preview", blob, "-o", png, "--vertices", "0"],
            "--vertices",
        ),
        (vec!["preview", blob, "-o", png, "-k", "0"], "-k"),
    ] {
        let run = ellip(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
    assert!(!Path::new(png).exists());
    // Named .png, the input itself is still refused.
    let copy = scratch.path("input.png");
    std::fs::copy(blob, &copy).unwrap();
    let c = copy.to_str().unwrap();
    let run = ellip(&["preview", c, "-o", c]);
    assert_eq!(run.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&run.stderr).contains("overwrite the input"));
    assert_eq!(std::fs::read(&copy).unwrap(), std::fs::read(blob).unwrap());
}

#[test]
fn the_region_panels_show_every_region_colour() {
    let k = 5;
    let mesh = read("blob3.obj");
    let (labels, decoded) = encode(&mesh, k);
    let options = RenderOptions {
        width: 240,
        height: 240,
        shading: Shading::Unlit,
        captions: false,
        ..RenderOptions::default()
    };
    let panels = |mesh_labels: bool| {
        if mesh_labels {
            Panel::regions("regions", &mesh, None, &labels)
        } else {
            Panel::regions(
                "decoded",
                &decoded.mesh,
                Some(&decoded.normals),
                &decoded.face_regions,
            )
        }
    };
    for source in [true, false] {
        // The default three-quarter view, and the opposite one, for regions at the back.
        let front = render(&[panels(source)], &options).unwrap();
        let back = render(
            &[panels(source)],
            &RenderOptions {
                view: View {
                    azimuth: 210.0,
                    elevation: -20.0,
                },
                ..options
            },
        )
        .unwrap();
        let (f, b) = (
            count_region_colours(&front, k),
            count_region_colours(&back, k),
        );
        println!("source {source}: front {f:?}, back {b:?}");
        // A region counts as shown with at least 50 pixels (0.1% of the panel) of its
        // exact colour; unlit pixels inside a region keep it exactly.
        let shown = |c: &BTreeMap<usize, usize>| c.iter().filter(|(_, &n)| n >= 50).count();
        assert!(shown(&f) >= k - 1, "front view: {f:?}");
        let all: std::collections::BTreeSet<usize> = f
            .iter()
            .chain(&b)
            .filter(|(_, &n)| n >= 50)
            .map(|(&i, _)| i)
            .collect();
        assert_eq!(all.len(), k, "source {source}: {f:?} {b:?}");
    }
}

#[test]
fn rendering_is_deterministic_and_lit_colours_keep_their_hue() {
    let mesh = read("blob2.obj");
    let (labels, _) = encode(&mesh, 4);
    let panels = [
        Panel::plain("source", &mesh, None),
        Panel::regions("regions", &mesh, None, &labels),
    ];
    let options = RenderOptions {
        width: 200,
        height: 150,
        captions: false,
        ..RenderOptions::default()
    };
    let a = render(&panels, &options).unwrap().encode_png().unwrap();
    let b = render(&panels, &options).unwrap().encode_png().unwrap();
    assert_eq!(a, b);
    let (width, height, rgb) = decode_png(&a);
    assert_eq!((width, height), (400, 150));
    // The grey panel is grey (no channel more than 2 apart), the regions panel is not.
    let saturated = |panel: u32| {
        let mut n = 0;
        for y in 0..height {
            for x in panel * 200..(panel + 1) * 200 {
                let at = 3 * (y * width + x) as usize;
                let p = &rgb[at..at + 3];
                let (lo, hi) = (p.iter().min().unwrap(), p.iter().max().unwrap());
                if hi - lo > 2 {
                    n += 1;
                }
            }
        }
        n
    };
    assert_eq!(saturated(0), 0);
    assert!(saturated(1) > 2000, "{}", saturated(1));
}

#[test]
fn degenerate_meshes_render_without_panicking() {
    let triangle = Mesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]]).unwrap();
    // A flat grid in the XZ plane: edge-on from elevation 0.
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for i in 0..5u32 {
        for j in 0..5u32 {
            positions.push(DVec3::new(f64::from(i), 0.0, f64::from(j)));
        }
    }
    for i in 0..4u32 {
        for j in 0..4u32 {
            let v = i * 5 + j;
            faces.push([v, v + 1, v + 6]);
            faces.push([v, v + 6, v + 5]);
        }
    }
    let flat = Mesh::new(positions, faces).unwrap();
    // Every vertex in one place; and coordinates near the largest f64.
    let point = Mesh::new(vec![DVec3::ONE; 3], vec![[0, 1, 2]]).unwrap();
    let huge = Mesh::new(
        vec![
            DVec3::splat(-1e307),
            DVec3::new(1e307, -1e307, 0.0),
            DVec3::splat(1e307),
        ],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let views = [
        View::default(),
        View {
            azimuth: 0.0,
            elevation: 0.0,
        },
        View {
            azimuth: 0.0,
            elevation: 90.0,
        },
    ];
    for mesh in [&triangle, &flat, &point, &huge] {
        for view in views {
            let options = RenderOptions {
                width: 64,
                height: 48,
                view,
                ..RenderOptions::default()
            };
            let panels = [
                Panel::plain("a", mesh, None),
                Panel::regions("b", mesh, None, &[1]),
                Panel::empty("c"),
            ];
            let image = render(&panels, &options).unwrap();
            assert_eq!((image.width(), image.height()), (192, 48));
            let (w, h, _) = decode_png(&image.encode_png().unwrap());
            assert_eq!((w, h), (192, 48));
        }
    }
    // The single triangle face-on (from +Z) fills about half its panel's fitted square.
    let options = RenderOptions {
        width: 100,
        height: 100,
        captions: false,
        view: View {
            azimuth: 0.0,
            elevation: 0.0,
        },
        ..RenderOptions::default()
    };
    let image = render(&[Panel::plain("t", &triangle, None)], &options).unwrap();
    let c = coverage(image.as_rgb(), 100, 100, 0, 100, 0);
    // The fitted square is 88 px (6% margins): half of it is 0.39 of the panel.
    assert!((c - 0.387).abs() < 0.02, "{c}");
}
