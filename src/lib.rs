//! # ellip — meshes as a few dozen ellipsoidal regions
//!
//! `ellip` turns a dense triangle mesh into a small analytic representation: a set of
//! ellipsoidal surface regions and the boundary curves where they meet, after
//! P. D. Simari and K. Singh, *Extraction and remeshing of ellipsoidal representations from
//! mesh data*, Graphics Interface 2005.
//!
//! ```
//! use ellip::encode::{encode_mesh, EncodeSettings};
//! use ellip::format::{decode, Limits};
//! use ellip::import::{read_mesh, ImportOptions};
//! use ellip::segment::{RegionCount, SegmentOptions};
//!
//! // A mesh made of three known ellipsoids, stored as three ellipsoidal regions.
//! let path = std::path::Path::new("fixtures/meshes/blob1.obj");
//! let mesh = read_mesh(path, &ImportOptions::default())?.mesh;
//! let settings = EncodeSettings {
//!     segment: SegmentOptions { regions: RegionCount::Fixed(3), ..SegmentOptions::default() },
//!     ..EncodeSettings::default()
//! };
//! let encoded = encode_mesh(&mesh, &settings, &mut |_progress| {})?;
//! assert!(encoded.bytes.len() < 2_000, "{} bytes", encoded.bytes.len());
//!
//! // Decoding checks every byte: checksums, limits, and the rules of spec/ELLIP.md.
//! let representation = decode(&encoded.bytes, &Limits::default())?;
//! assert_eq!(representation.ellipsoids.len(), 3);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The crate is organised by pipeline stage; see `spec/architecture.md` for the module
//! graph and the invariants each stage keeps.
//!
//! | stage | module | what it does |
//! |---|---|---|
//! | import | [`import`] | reads OBJ, glTF/GLB, PLY, STL, OFF into a repaired [`Mesh`] |
//! | analyse | [`mesh`] | topology, normals, areas, volume, genus, [`mesh::curvature`] |
//! | export | [`export`] | writes OBJ, glTF/GLB, PLY atomically |
//! | fixtures | [`synth`] | known shapes and blobs of known ellipsoids, for tests |
//! | fit | [`ellipsoid`] | the ellipsoid primitive, the paper's error metrics, robust fitting |
//! | segment | [`segment`] | Lloyd iteration into connected regions, each with its ellipsoid |
//! | boundaries | [`boundary`] | arcs, junctions and cycles between regions; their smoothing |
//! | encode | [`encode`] | the whole encoder: mesh → representation → `.ellip` bytes |
//! | represent | [`representation`] | ellipsoids, boundary-point pool, shared arcs, cycles; arc simplification |
//! | store | [`format`](mod@format) | the `.ellip` file: versioned encoder, hardened decoder (`spec/ELLIP.md`) |
//! | remesh | [`remesh`] | regions back to a watertight triangle mesh: charts, spade CDT, ray query |
//! | measure | [`compare`] | distances between two meshes: Hausdorff, RMS, mean, normal deviation |
//! | show | [`preview`] | meshes side by side in a PNG: software rasteriser, region colours and boundaries |
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod boundary;
pub mod compare;
pub mod ellipsoid;
pub mod encode;
pub mod export;
pub mod format;
pub mod import;
pub mod mesh;
pub mod preview;
pub mod remesh;
pub mod representation;
pub mod rng;
pub mod segment;
pub mod synth;

mod atomic;

/// The README's Rust examples, compiled and run as doc tests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

pub use mesh::{Aabb, Mesh, MeshError};
