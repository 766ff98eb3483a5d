//! PLY, STL and OFF import through the public API: valid files become the expected meshes,
//! and malformed ones (every truncation, random bit flips, forged counts) are rejected
//! without panicking and without large allocations.
//!
//! The largest single allocation is measured by a counting global allocator, per thread so
//! that tests running in parallel do not see each other's allocations.

use ellip::import::{read_mesh_bytes, ImportError, ImportLimits, ImportOptions, Imported};
use ellip::rng::SplitMix64;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;

/// The system allocator, noting the largest request made on each thread.
struct LargestAllocation;

thread_local! {
    // Const-initialised and without a destructor: safe to touch from inside the allocator.
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn note(size: usize) {
    let _ = LARGEST.try_with(|largest| largest.set(largest.get().max(size)));
}

// SAFETY: every call is forwarded unchanged to the system allocator; `note` only records a
// number in a thread-local `Cell` and neither allocates nor unwinds.
unsafe impl GlobalAlloc for LargestAllocation {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: LargestAllocation = LargestAllocation;

/// The largest allocation any of these small inputs may cause: a parse and a repair of a
/// few kilobytes need a few hundred kilobytes at most; a forged count would ask for
/// gigabytes.
const ALLOCATION_CAP: usize = 1 << 20;

/// Imports `bytes` as if from the file `name`, returning the result and the largest single
/// allocation made meanwhile.
fn import_measured(
    bytes: &[u8],
    name: &str,
    options: &ImportOptions,
) -> (Result<Imported, ImportError>, usize) {
    LARGEST.with(|l| l.set(0));
    let result = read_mesh_bytes(bytes, Path::new(name), options);
    (result, LARGEST.with(Cell::get))
}

/// Imports a file that must be rejected; checks the allocation and the message.
fn reject(bytes: &[u8], name: &str, options: &ImportOptions) -> ImportError {
    let (result, largest) = import_measured(bytes, name, options);
    assert!(
        largest <= ALLOCATION_CAP,
        "{name}: allocated {largest} bytes"
    );
    let error = match result {
        Ok(imported) => panic!(
            "{name}: {} bytes were accepted as {} faces",
            bytes.len(),
            imported.mesh.face_count()
        ),
        Err(e) => e,
    };
    assert_one_line(&error, name);
    error
}

fn assert_one_line(error: &ImportError, name: &str) {
    let message = error.to_string();
    assert!(!message.contains('\n'), "{message:?}");
    assert!(message.starts_with(&format!("{name}: ")), "{message:?}");
}

fn import(bytes: &[u8], name: &str) -> Imported {
    read_mesh_bytes(bytes, Path::new(name), &ImportOptions::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

// ---------------------------------------------------------------------------------------
// Fixtures

/// Unit cube corners; corner `i` is at (i & 1, i >> 1 & 1, i >> 2 & 1).
fn cube_corners() -> Vec<[f64; 3]> {
    (0..8)
        .map(|i| [(i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2 & 1) as f64])
        .collect()
}

/// The cube's faces as outward quads.
const CUBE_QUADS: [[u32; 4]; 6] = [
    [0, 2, 3, 1],
    [4, 5, 7, 6],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 4, 6, 2],
    [1, 3, 7, 5],
];

fn cube_ply_ascii() -> Vec<u8> {
    let mut out = String::from(
        "ply\nformat ascii 1.0\ncomment unit cube\nelement vertex 8\nproperty float x\n\
         property float y\nproperty float z\nelement face 6\n\
         property list uchar int vertex_indices\nend_header\n",
    );
    for [x, y, z] in cube_corners() {
        out += &format!("{x} {y} {z}\n");
    }
    for q in CUBE_QUADS {
        out += &format!("4 {} {} {} {}\n", q[0], q[1], q[2], q[3]);
    }
    out.into_bytes()
}

/// The cube as binary PLY with double coordinates, a normal per vertex, and uint8/uint16
/// list types.
fn cube_ply_binary(big_endian: bool) -> Vec<u8> {
    let order = if big_endian { "big" } else { "little" };
    let mut out = format!(
        "ply\nformat binary_{order}_endian 1.0\nelement vertex 8\nproperty double x\n\
         property double y\nproperty double z\nproperty float nx\nelement face 6\n\
         property list uint8 uint16 vertex_indices\nend_header\n"
    )
    .into_bytes();
    for [x, y, z] in cube_corners() {
        for c in [x, y, z] {
            out.extend(if big_endian {
                c.to_be_bytes()
            } else {
                c.to_le_bytes()
            });
        }
        out.extend(if big_endian {
            1f32.to_be_bytes()
        } else {
            1f32.to_le_bytes()
        });
    }
    for q in CUBE_QUADS {
        out.push(4);
        for i in q {
            let i = i as u16;
            out.extend(if big_endian {
                i.to_be_bytes()
            } else {
                i.to_le_bytes()
            });
        }
    }
    out
}

fn cube_off() -> Vec<u8> {
    let mut out = String::from("OFF\n# unit cube\n8 6 12\n");
    for [x, y, z] in cube_corners() {
        out += &format!("{x} {y} {z}\n");
    }
    for q in CUBE_QUADS {
        out += &format!("4 {} {} {} {}\n", q[0], q[1], q[2], q[3]);
    }
    out.into_bytes()
}

/// The cube's triangles, as corner positions.
fn cube_triangles() -> Vec<[[f64; 3]; 3]> {
    let c = cube_corners();
    CUBE_QUADS
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .map(|t| t.map(|i| c[i as usize]))
        .collect()
}

fn tetra_triangles() -> Vec<[[f64; 3]; 3]> {
    let (o, x, y, z) = ([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    vec![[o, y, x], [o, x, z], [o, z, y], [x, y, z]]
}

fn stl_binary(header: &[u8], triangles: &[[[f64; 3]; 3]]) -> Vec<u8> {
    let mut out = vec![b' '; 80];
    out[..header.len()].copy_from_slice(header);
    out.extend((triangles.len() as u32).to_le_bytes());
    for t in triangles {
        out.extend([0u8; 12]);
        for c in t.iter().flatten() {
            out.extend((*c as f32).to_le_bytes());
        }
        out.extend([0u8; 2]);
    }
    out
}

fn stl_ascii(triangles: &[[[f64; 3]; 3]]) -> Vec<u8> {
    let mut out = String::from("solid shape\n");
    for t in triangles {
        out += " facet normal 0 0 0\n  outer loop\n";
        for [x, y, z] in t {
            out += &format!("   vertex {x} {y} {z}\n");
        }
        out += "  endloop\n endfacet\n";
    }
    (out + "endsolid shape\n").into_bytes()
}

/// Every file of the malformation corpus, with the name it is read under.
fn corpus() -> Vec<(Vec<u8>, &'static str)> {
    vec![
        (cube_ply_ascii(), "x.ply"),
        (cube_ply_binary(false), "x.ply"),
        (cube_ply_binary(true), "x.ply"),
        (cube_off(), "x.off"),
        (stl_binary(b"solid but binary", &tetra_triangles()), "x.stl"),
        (stl_binary(b"binary", &cube_triangles()), "x.stl"),
        (stl_ascii(&tetra_triangles()), "x.stl"),
    ]
}

// ---------------------------------------------------------------------------------------
// Valid files

fn assert_unit_cube(imported: &Imported, what: &str) {
    let mesh = &imported.mesh;
    assert_eq!(mesh.vertex_count(), 8, "{what}");
    assert_eq!(mesh.face_count(), 12, "{what}");
    assert!(mesh.topology().is_closed(), "{what}");
    let volume = mesh.volume().expect("closed");
    assert!((volume - 1.0).abs() < 1e-12, "{what}: volume {volume}");
    assert!((mesh.area() - 6.0).abs() < 1e-12, "{what}");
}

#[test]
fn quad_cubes_become_closed_twelve_triangle_meshes() {
    for (bytes, name) in [
        (cube_ply_ascii(), "ascii.ply"),
        (cube_ply_binary(false), "le.ply"),
        (cube_ply_binary(true), "be.ply"),
        (cube_off(), "cube.off"),
    ] {
        let imported = import(&bytes, name);
        assert_unit_cube(&imported, name);
        assert_eq!(imported.repairs.triangulated_polygons, 6, "{name}");
        assert_eq!(imported.repairs.welded_vertices, 0, "{name}");
    }
}

#[test]
fn stl_facets_are_welded_into_shared_vertices() {
    for (bytes, what) in [
        (stl_binary(b"solid tetra", &tetra_triangles()), "binary"),
        (stl_ascii(&tetra_triangles()), "ascii"),
    ] {
        let imported = import(&bytes, "tetra.stl");
        let mesh = &imported.mesh;
        assert_eq!(mesh.vertex_count(), 4, "{what}");
        assert_eq!(mesh.face_count(), 4, "{what}");
        assert_eq!(imported.repairs.welded_vertices, 8, "{what}");
        assert!(mesh.topology().is_closed(), "{what}");
        let volume = mesh.volume().expect("closed");
        assert!(
            (volume - 1.0 / 6.0).abs() < 1e-12,
            "{what}: volume {volume}"
        );
    }
    let imported = import(&stl_binary(b"", &cube_triangles()), "cube.stl");
    assert_unit_cube(&imported, "binary STL cube");
    assert_eq!(imported.repairs.welded_vertices, 36 - 8);
}

#[test]
fn the_format_is_sniffed_when_the_extension_says_nothing() {
    assert_unit_cube(&import(&cube_ply_binary(true), "cube.bin"), "sniffed PLY");
    assert_unit_cube(&import(&cube_off(), "cube"), "sniffed OFF");
    let tetra = import(&stl_ascii(&tetra_triangles()), "tetra.txt");
    assert_eq!(tetra.mesh.face_count(), 4);
}

// ---------------------------------------------------------------------------------------
// Malformed files

#[test]
fn every_truncation_is_rejected() {
    let options = ImportOptions::default();
    for (bytes, name) in corpus() {
        let shortest_valid = if bytes.contains(&0) {
            bytes.len()
        } else if let Some(end) = bytes.windows(8).position(|w| w == b"endsolid") {
            // The solid's name after endsolid is optional.
            end + 8
        } else {
            // Text files end with one newline after a one-digit index, so any cut but that
            // of the newline loses something the file needs.
            bytes.len() - 1
        };
        for len in 0..shortest_valid {
            reject(&bytes[..len], name, &options);
        }
    }
}

#[test]
fn random_bit_flips_never_panic_or_allocate_much() {
    let options = ImportOptions::default();
    let mut rng = SplitMix64::new(0x5EED_F11F);
    let mut rejected = 0;
    let mut total = 0;
    for (bytes, name) in corpus() {
        for _ in 0..400 {
            let mut mutant = bytes.clone();
            for _ in 0..1 + rng.below(4) {
                let bit = rng.below(8 * mutant.len() as u64);
                mutant[(bit / 8) as usize] ^= 1 << (bit % 8);
            }
            let (result, largest) = import_measured(&mutant, name, &options);
            assert!(
                largest <= ALLOCATION_CAP,
                "{name}: allocated {largest} bytes"
            );
            total += 1;
            match result {
                Err(e) => {
                    assert_one_line(&e, name);
                    rejected += 1;
                }
                Ok(imported) => assert!(imported.mesh.face_count() > 0),
            }
        }
    }
    // Most single-bit changes land in coordinates and stay valid, but not all.
    assert!(rejected > 0 && rejected < total, "{rejected} of {total}");
}

/// Replaces the first occurrence of `from` in `bytes` by `to`.
fn replace(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    let at = bytes
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .expect("the text to replace is present");
    [&bytes[..at], to.as_bytes(), &bytes[at + from.len()..]].concat()
}

#[test]
fn forged_counts_are_rejected_before_allocating() {
    let default = ImportOptions::default();
    // Limits so generous that only the bytes-present check stands between a forged count
    // and the allocation.
    let generous = ImportOptions {
        limits: ImportLimits {
            max_vertices: 1 << 40,
            max_faces: 1 << 40,
            ..ImportLimits::default()
        },
        ..ImportOptions::default()
    };
    let tiny_ply = |count_line: &str, format: &str| {
        let mut bytes = format!(
            "ply\nformat {format} 1.0\n{count_line}\nproperty float x\nproperty float y\n\
             property float z\nend_header\n"
        )
        .into_bytes();
        bytes.resize(100, b'0');
        bytes
    };
    let stl_count = |count: u32| {
        let mut bytes = stl_binary(b"", &tetra_triangles()[..1]);
        bytes[80..84].copy_from_slice(&count.to_le_bytes());
        bytes.resize(100, 0);
        bytes
    };
    let mut cases = vec![];
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        for count in ["4000000000", "100000000", "18446744073709551615"] {
            cases.push((
                tiny_ply(&format!("element vertex {count}"), format),
                "x.ply",
            ));
            let other = format!(
                "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
                 element junk {count}"
            );
            cases.push((tiny_ply(&other, format), "x.ply"));
        }
    }
    for count in [4_000_000_000, 100_000_000, 1_431_655_765, u32::MAX] {
        cases.push((stl_count(count), "x.stl"));
    }
    for counts in [
        "4000000000 1 0",
        "100000000 0 0",
        "8 100000000 0",
        "8 4000000000 0",
    ] {
        cases.push((replace(&cube_off(), "8 6 12", counts), "x.off"));
    }
    // Forged list lengths.
    cases.push((
        replace(&cube_ply_ascii(), "4 4 5 7 6", "4000000000 4 5 7 6"),
        "x.ply",
    ));
    let mut binary = cube_ply_binary(false);
    let face_start = binary.len() - 6 * 9;
    binary[face_start] = 255;
    cases.push((binary, "x.ply"));
    let binary = replace(
        &cube_ply_binary(false),
        "list uint8 uint16",
        "list uint32 uint16",
    );
    cases.push((binary, "x.ply"));

    for (bytes, name) in &cases {
        assert!(bytes.len() <= 1000);
        for options in [&default, &generous] {
            reject(bytes, name, options);
        }
    }
}

#[test]
fn errors_name_the_problem_and_where_it_is() {
    let options = ImportOptions::default();
    let message = |bytes: &[u8], name: &str| reject(bytes, name, &options).to_string();
    assert_eq!(
        message(&replace(&cube_off(), "4 0 2 3 1", "4 0 2 3 8"), "x.off"),
        "x.off: off, line 12: face index 8 is out of range (there are 8 vertices)"
    );
    assert_eq!(
        message(&replace(&cube_ply_ascii(), "1 1 1", "1 nan 1"), "x.ply"),
        "x.ply: ply, line 18: vertex 7 has a non-finite coordinate"
    );
    let tetra = stl_binary(b"", &tetra_triangles());
    assert_eq!(
        message(&tetra[..tetra.len() - 10], "x.stl"),
        "x.stl: stl, byte 84: truncated: 200 bytes needed, 190 present"
    );
    assert_eq!(message(b"", "x.ply"), "x.ply: ply: the file is empty");
}

#[test]
fn the_allocation_meter_sees_large_requests() {
    LARGEST.with(|l| l.set(0));
    let big = std::hint::black_box(Vec::<u8>::with_capacity(2 * ALLOCATION_CAP));
    assert!(LARGEST.with(Cell::get) >= 2 * ALLOCATION_CAP);
    drop(big);
}
