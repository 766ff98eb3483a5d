//! How far apart two meshes are: sampled Hausdorff, RMS and mean distance, and normal
//! deviation, the way a lossy codec's error is reported (after Cignoni, Rocchini & Scopigno,
//! *Metro: measuring error on simplified surfaces*, 1998).
//!
//! [`compare_meshes`] draws [`CompareOptions::samples`] points uniformly by area on each
//! mesh ([`sample_surface`], seeded, so the same meshes always give the same figures), finds
//! each point's exact closest point on the other mesh through a [`Bvh`] of its triangles, and
//! reduces the per-sample distances in sample order, so the result does not depend on the
//! number of threads. The Hausdorff distance is a maximum and sampling can only miss it, so
//! every vertex of the source mesh is also measured for it (a mesh's vertices are where two
//! piecewise-linear surfaces usually part most); RMS and mean use the area samples only,
//! so they estimate the area-weighted integrals.
//!
//! Both meshes are first scaled by the power of two that brings their largest coordinate
//! into [0.5, 1): exact in floating point (the figures are those of the unscaled meshes, bit
//! for bit, wherever those do not overflow or underflow), and it keeps squared distances and
//! cross products in range for meshes of any size. Faces without a unit normal at that
//! scale (zero area, or a sliver so thin that its normal underflows) hold no surface: they
//! are neither sampled nor searched.

mod bvh;
mod sample;
mod triangle;

pub use bvh::{Bvh, Hit};
pub use sample::{sample_surface, SurfaceSample};
pub use triangle::{closest_point_on_segment, closest_point_on_triangle, distance_to_segment};

use crate::Mesh;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// Default number of area samples drawn on each mesh.
pub const DEFAULT_SAMPLES: usize = 100_000;

/// Most area samples per mesh (about 100 bytes of memory each).
pub const MAX_SAMPLES: usize = 10_000_000;

/// How to compare.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareOptions {
    /// Area samples drawn on each mesh, 1 ..= [`MAX_SAMPLES`]; default [`DEFAULT_SAMPLES`].
    /// The RMS estimate's relative standard error is about `σ/(RMS·√samples)`: well under 1%
    /// at the default for any error spread one would meet.
    pub samples: usize,
    /// Seed of the sampling (mesh B uses `seed + 1`).
    pub seed: u64,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            samples: DEFAULT_SAMPLES,
            seed: 0x5EED_0E11_1B5E,
        }
    }
}

/// Distances from one surface to another, in model units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Distances {
    /// The largest distance found (over area samples and vertices): the one-sided Hausdorff
    /// distance, from below.
    pub hausdorff: f64,
    /// Root mean square of the area samples' distances.
    pub rms: f64,
    /// Mean of the area samples' distances.
    pub mean: f64,
}

impl Distances {
    /// Every distance divided by `length` (e.g. a bounding-box diagonal).
    pub fn divided_by(&self, length: f64) -> Distances {
        Distances {
            hausdorff: self.hausdorff / length,
            rms: self.rms / length,
            mean: self.mean / length,
        }
    }
}

/// The deviation of one surface from another (or the worse of both directions).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Deviation {
    /// Distances to the other surface.
    pub distances: Distances,
    /// Mean angle, in degrees (0..=180), between the unit normal of the face a sample lies on
    /// and the unit normal of the other mesh's face at its closest point (the face of smallest
    /// index when the closest point is on an edge or vertex), as oriented: a decoded mesh
    /// must keep the source's orientation, so a flipped face counts as 180°.
    pub normal_deviation: f64,
    /// The same with each angle folded to 0..=90 (`min(θ, 180° − θ)`): the deviation of the
    /// tangent planes, blind to orientation.
    pub unsigned_normal_deviation: f64,
    /// A point where the largest distance was found.
    pub farthest: DVec3,
    /// Number of area samples.
    pub samples: usize,
    /// Number of vertices measured for the Hausdorff distance.
    pub vertices: usize,
}

/// The comparison of mesh A with mesh B.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Comparison {
    /// Deviation of A from B: samples on A, closest points on B.
    pub a_to_b: Deviation,
    /// Deviation of B from A.
    pub b_to_a: Deviation,
    /// The symmetric figures: each the larger of the two directions (for the Hausdorff
    /// distance this is its definition; for the others it is the conservative choice).
    pub symmetric: Deviation,
    /// Length of A's bounding-box diagonal, the scale of the relative figures.
    pub diagonal: f64,
}

impl Comparison {
    /// `deviation`'s distances as fractions of A's bounding-box diagonal.
    pub fn relative(&self, deviation: &Deviation) -> Distances {
        deviation.distances.divided_by(self.diagonal)
    }
}

/// Why two meshes could not be compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CompareError {
    /// A mesh has no face with an area (no faces, or only degenerate ones).
    #[error("mesh {mesh} has no surface: {faces} faces, none with an area")]
    NoSurface {
        /// "A" or "B".
        mesh: &'static str,
        /// Its number of faces.
        faces: usize,
    },
    /// The meshes are so far apart, or so large, that a distance exceeds the largest float.
    #[error("the distance between the meshes ({what}) overflows a 64-bit float")]
    Overflow {
        /// Which figure.
        what: &'static str,
    },
    /// An option is out of range.
    #[error("invalid option {what}: {value}")]
    InvalidOption {
        /// The option.
        what: &'static str,
        /// Its value, as text.
        value: String,
    },
}

/// A mesh prepared as a target: its faces with area in a [`Bvh`], and their normals.
struct Target {
    bvh: Bvh,
    normals: Vec<DVec3>,
}

/// Compares mesh `a` with mesh `b` (see the [module docs](self)).
pub fn compare_meshes(
    a: &Mesh,
    b: &Mesh,
    options: &CompareOptions,
) -> Result<Comparison, CompareError> {
    if !(1..=MAX_SAMPLES).contains(&options.samples) {
        return Err(CompareError::InvalidOption {
            what: "samples",
            value: format!("{} (allowed: 1 ..= {MAX_SAMPLES})", options.samples),
        });
    }
    let exponent = scale_exponent(a, b);
    let (scaled_a, scaled_b) = match exponent {
        0 => (a.clone(), b.clone()),
        e => {
            let down = |p: DVec3| p * 2f64.powi(-e);
            // Scaling finite coordinates down (or tiny ones up to at most 1) stays finite.
            let map = |m: &Mesh| m.map_positions(down).unwrap_or_else(|_| m.clone());
            (map(a), map(b))
        }
    };
    let target_a = index_target(&scaled_a, "A")?;
    let target_b = index_target(&scaled_b, "B")?;
    let diagonal = a.bounding_box().map_or(0.0, |bbox| bbox.diagonal());
    let up = 2f64.powi(exponent);
    let a_to_b = measure_deviation(&scaled_a, &target_b, options.samples, options.seed);
    let b_to_a = measure_deviation(
        &scaled_b,
        &target_a,
        options.samples,
        options.seed.wrapping_add(1),
    );
    let (a_to_b, b_to_a) = (scale_deviation(&a_to_b, up)?, scale_deviation(&b_to_a, up)?);
    Ok(Comparison {
        a_to_b,
        b_to_a,
        symmetric: combine_worse(&a_to_b, &b_to_a),
        diagonal,
    })
}

/// The `e` for which `2^-e` brings the largest absolute coordinate of both meshes into
/// [0.5, 1) (0 when every coordinate is 0), within ±1000 so that `2^±e` is a normal float.
fn scale_exponent(a: &Mesh, b: &Mesh) -> i32 {
    let largest = a
        .positions()
        .iter()
        .chain(b.positions())
        .map(|p| p.abs().max_element())
        .fold(0.0f64, f64::max);
    if largest > 0.0 && largest.is_finite() {
        (largest.log2().floor() as i32 + 1).clamp(-1000, 1000)
    } else {
        0
    }
}

/// A deviation measured on scaled meshes, brought back to model units.
fn scale_deviation(d: &Deviation, up: f64) -> Result<Deviation, CompareError> {
    let x = d.distances;
    let distances = Distances {
        hausdorff: x.hausdorff * up,
        rms: x.rms * up,
        mean: x.mean * up,
    };
    if !distances.hausdorff.is_finite() {
        return Err(CompareError::Overflow { what: "Hausdorff" });
    }
    Ok(Deviation {
        distances,
        farthest: d.farthest * up,
        ..*d
    })
}

fn index_target(mesh: &Mesh, name: &'static str) -> Result<Target, CompareError> {
    let normals = mesh.face_normals();
    let triangles: Vec<([DVec3; 3], u32)> = (0..mesh.face_count())
        .filter(|&f| normals[f] != DVec3::ZERO)
        .map(|f| (mesh.corners(f), f as u32))
        .collect();
    if triangles.is_empty() {
        return Err(CompareError::NoSurface {
            mesh: name,
            faces: mesh.face_count(),
        });
    }
    Ok(Target {
        bvh: Bvh::build(triangles),
        normals,
    })
}

/// What one area sample measured.
struct Measured {
    distance_squared: f64,
    /// Angle between the normals, degrees, oriented.
    angle: f64,
}

/// Deviation of `source` from `target`. Per-sample work runs in parallel into a vector in
/// sample order; the sums are then taken sequentially in that order.
fn measure_deviation(source: &Mesh, target: &Target, samples: usize, seed: u64) -> Deviation {
    let points = sample_surface(source, samples, seed);
    let measured: Vec<Measured> = points
        .par_iter()
        .with_min_len(256)
        .map(|s| match target.bvh.find_closest(s.point) {
            Some(hit) => {
                let other = target
                    .normals
                    .get(hit.id as usize)
                    .copied()
                    .unwrap_or(DVec3::ZERO);
                Measured {
                    distance_squared: hit.distance_squared,
                    angle: angle_degrees(s.normal, other),
                }
            }
            // Unreachable: a target has at least one triangle.
            None => Measured {
                distance_squared: 0.0,
                angle: 0.0,
            },
        })
        .collect();
    let vertices = surface_vertices(source);
    let vertex_d2: Vec<f64> = vertices
        .par_iter()
        .with_min_len(256)
        .map(|&p| {
            target
                .bvh
                .find_closest(p)
                .map_or(0.0, |hit| hit.distance_squared)
        })
        .collect();

    let mut max_d2 = f64::NEG_INFINITY;
    let mut farthest = DVec3::ZERO;
    let (mut sum_d2, mut sum_d, mut sum_angle, mut sum_unsigned) = (0.0, 0.0, 0.0, 0.0);
    for (s, m) in points.iter().zip(&measured) {
        if m.distance_squared > max_d2 {
            max_d2 = m.distance_squared;
            farthest = s.point;
        }
        sum_d2 += m.distance_squared;
        sum_d += m.distance_squared.sqrt();
        sum_angle += m.angle;
        sum_unsigned += m.angle.min(180.0 - m.angle);
    }
    for (&p, &d2) in vertices.iter().zip(&vertex_d2) {
        if d2 > max_d2 {
            max_d2 = d2;
            farthest = p;
        }
    }
    let n = measured.len().max(1) as f64;
    Deviation {
        distances: Distances {
            hausdorff: max_d2.max(0.0).sqrt(),
            rms: (sum_d2 / n).sqrt(),
            mean: sum_d / n,
        },
        normal_deviation: sum_angle / n,
        unsigned_normal_deviation: sum_unsigned / n,
        farthest,
        samples: measured.len(),
        vertices: vertices.len(),
    }
}

/// The vertices of faces that have a normal, each once, in index order.
fn surface_vertices(mesh: &Mesh) -> Vec<DVec3> {
    let mut used = vec![false; mesh.vertex_count()];
    for (f, face) in mesh.faces().iter().enumerate() {
        if mesh.face_normal(f) != DVec3::ZERO {
            for &v in face {
                if let Some(u) = used.get_mut(v as usize) {
                    *u = true;
                }
            }
        }
    }
    mesh.positions()
        .iter()
        .zip(&used)
        .filter(|(_, &u)| u)
        .map(|(&p, _)| p)
        .collect()
}

/// Angle between two unit vectors in degrees, accurate near 0° and 180° (atan2 of the sine
/// and cosine rather than acos of the cosine).
fn angle_degrees(u: DVec3, v: DVec3) -> f64 {
    u.cross(v).length().atan2(u.dot(v)).to_degrees()
}

/// Each figure the larger of the two directions; the farthest point of the direction with
/// the larger Hausdorff distance (A's on a tie); counts summed.
fn combine_worse(ab: &Deviation, ba: &Deviation) -> Deviation {
    let (x, y) = (&ab.distances, &ba.distances);
    Deviation {
        distances: Distances {
            hausdorff: x.hausdorff.max(y.hausdorff),
            rms: x.rms.max(y.rms),
            mean: x.mean.max(y.mean),
        },
        normal_deviation: ab.normal_deviation.max(ba.normal_deviation),
        unsigned_normal_deviation: ab
            .unsigned_normal_deviation
            .max(ba.unsigned_normal_deviation),
        farthest: if y.hausdorff > x.hausdorff {
            ba.farthest
        } else {
            ab.farthest
        },
        samples: ab.samples + ba.samples,
        vertices: ab.vertices + ba.vertices,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::shapes::icosphere;

    #[test]
    fn identical_meshes_are_zero_apart() {
        let mesh = icosphere(1.0, 2);
        let c = compare_meshes(&mesh, &mesh, &CompareOptions::default()).unwrap();
        for d in [c.a_to_b, c.b_to_a, c.symmetric] {
            // A sample is a rounded point of a face: its projection back is ~1e-16 away.
            assert!(d.distances.hausdorff < 1e-12, "{:?}", d.distances);
            assert!(d.distances.rms < 1e-12, "{:?}", d.distances);
            assert!(d.normal_deviation < 1e-6, "{}", d.normal_deviation);
        }
        assert_eq!(c.a_to_b.samples, DEFAULT_SAMPLES);
        assert_eq!(c.a_to_b.vertices, mesh.vertex_count());
    }

    #[test]
    fn a_flipped_copy_deviates_by_180_degrees_oriented_and_0_unsigned() {
        let mesh = icosphere(1.0, 1);
        let (positions, faces) = mesh.clone().into_parts();
        let flipped = Mesh::new(
            positions,
            faces.iter().map(|&[a, b, c]| [a, c, b]).collect(),
        )
        .unwrap();
        let options = CompareOptions {
            samples: 2_000,
            ..CompareOptions::default()
        };
        let c = compare_meshes(&mesh, &flipped, &options).unwrap();
        assert!(c.symmetric.distances.hausdorff < 1e-12);
        assert!((c.a_to_b.normal_deviation - 180.0).abs() < 1e-6);
        assert!(c.a_to_b.unsigned_normal_deviation < 1e-6);
    }

    #[test]
    fn angles_are_accurate_at_both_ends() {
        assert_eq!(angle_degrees(DVec3::X, DVec3::X), 0.0);
        assert!((angle_degrees(DVec3::X, -DVec3::X) - 180.0).abs() < 1e-12);
        assert!((angle_degrees(DVec3::X, DVec3::Y) - 90.0).abs() < 1e-12);
        let tiny = DVec3::new(1.0, 1e-9, 0.0).normalize();
        assert!((angle_degrees(DVec3::X, tiny) - 1e-9f64.to_degrees()).abs() < 1e-15);
    }

    #[test]
    fn sample_count_out_of_range_is_an_error() {
        let mesh = icosphere(1.0, 0);
        for samples in [0, MAX_SAMPLES + 1] {
            let options = CompareOptions {
                samples,
                ..CompareOptions::default()
            };
            assert!(matches!(
                compare_meshes(&mesh, &mesh, &options),
                Err(CompareError::InvalidOption {
                    what: "samples",
                    ..
                })
            ));
        }
    }
}
