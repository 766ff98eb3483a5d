//! Smooth unions of known ellipsoids, meshed by iso-surface extraction.
//!
//! A *blob* is the zero set of
//!
//! ```text
//! F(p) = smin_k( d_1(p), d_2(p), …, d_n(p) )
//! ```
//!
//! where `d_i` is the first-order distance estimate to ellipsoid `i` in its own frame,
//! `d = k0 (k0 − 1) / k1` with `k0 = |q / r|` and `k1 = |q / r²|` (I. Quilez, *Ellipsoid SDF*,
//! iquilezles.org, 2008–2019). Its zero set is *exactly* the ellipsoid (`k0 = 1`) and its
//! gradient there is the surface normal scaled by about 1. `smin_k` is Quilez's cubic
//! polynomial smooth minimum (C², *Smooth minimum*, iquilezles.org, 2013): it equals the plain
//! minimum wherever the two arguments differ by at least `k`, so away from a thin seam where
//! two ellipsoids meet the blob's surface lies *on* the true ellipsoids.
//!
//! The zero set is extracted by marching tetrahedra (Doi & Koide 1991) on a regular grid whose
//! cubes are each split into the six tetrahedra of the Kuhn (Freudenthal) triangulation. That
//! triangulation is a simplicial complex of the whole grid — neighbouring cubes split their
//! shared face along the same diagonal — and a tetrahedron has no ambiguous sign patterns, so
//! the output is a closed 2-manifold without the case tables and ambiguity resolution of
//! marching cubes. Surface vertices are keyed by the grid edge they sit on (lower grid point,
//! edge direction), never by float hashing, so neighbouring tetrahedra share them exactly.
//! Grid values within 1% of a cell of zero are pushed to ±1% of a cell before extraction, so
//! no surface vertex starts next to a grid point: that is what keeps the corner-cutting
//! triangles from degenerating. Every vertex is then projected onto the exact zero set of `F`
//! by damped Newton steps along `∇F` (analytic gradient), which puts it on its ellipsoid to
//! rounding error wherever the blending is inactive. Where a groove between two ellipsoids is
//! narrower than a cell the piecewise-linear surface can fold; a few rounds of local
//! relaxation of the folded faces' corners, each followed by re-projection, remove the folds
//! (see `unfold`).

use super::EllipsoidSpec;
use crate::mesh::{Mesh, MeshError};
use crate::rng::SplitMix64;
use glam::{DMat3, DQuat, DVec3};
use rayon::prelude::*;
use std::collections::HashMap;

/// Default smooth-union width, as a fraction of the smallest radius of all ellipsoids.
///
/// Small enough that the blending seam holds only a few percent of a blob's vertices (the rest
/// lie on the true ellipsoids), large enough that the seam is a smooth fillet a few cells wide
/// rather than a crease at the default resolutions.
pub const DEFAULT_BLEND: f64 = 0.05;

/// Default approximate face count.
pub const DEFAULT_TARGET_FACES: usize = 8_000;

/// Smallest accepted [`BlobOptions::target_faces`].
pub const MIN_TARGET_FACES: usize = 100;

/// Largest accepted [`BlobOptions::target_faces`].
pub const MAX_TARGET_FACES: usize = 4_000_000;

/// Largest number of grid points the extraction may sample.
pub const MAX_GRID_POINTS: usize = 64_000_000;

/// How a blob is meshed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlobOptions {
    /// Approximate number of triangles wanted, in
    /// [`MIN_TARGET_FACES`]..=[`MAX_TARGET_FACES`]. The grid cell is calibrated on a coarse
    /// pilot extraction; results land within a few percent of the target. A cell is never
    /// coarser than the smallest radius, so a tiny ellipsoid can raise the count.
    pub target_faces: usize,
    /// Smooth-union width as a fraction of the smallest radius over all ellipsoids, in
    /// `[0, 1]`; 0 is the plain (creased) union. Default [`DEFAULT_BLEND`].
    pub blend: f64,
}

impl Default for BlobOptions {
    fn default() -> Self {
        BlobOptions {
            target_faces: DEFAULT_TARGET_FACES,
            blend: DEFAULT_BLEND,
        }
    }
}

/// Why a blob could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BlobError {
    /// No ellipsoids were given.
    #[error("a blob needs at least one ellipsoid")]
    NoEllipsoids,
    /// An ellipsoid has a non-finite value, a non-positive radius or a zero rotation.
    #[error("ellipsoid {index} is invalid: {reason}")]
    InvalidEllipsoid {
        /// Index of the offending ellipsoid.
        index: usize,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// `target_faces` is outside the accepted range.
    #[error("target_faces is {target}, expected {min}..={max}")]
    InvalidTargetFaces {
        /// The value given.
        target: usize,
        /// Smallest accepted.
        min: usize,
        /// Largest accepted.
        max: usize,
    },
    /// `blend` is not in `[0, 1]`.
    #[error("blend is {blend}, expected a value in [0, 1]")]
    InvalidBlend {
        /// The value given.
        blend: f64,
    },
    /// The grid needed is larger than [`MAX_GRID_POINTS`] (e.g. radii of very different sizes).
    #[error("the extraction grid would have {points} points, more than the {max} allowed")]
    GridTooLarge {
        /// Grid points needed.
        points: u128,
        /// The most allowed.
        max: usize,
    },
    /// The extracted triangles do not form a valid mesh (not expected; reported, not hidden).
    #[error("the extracted surface is not a valid mesh: {0}")]
    Mesh(#[from] MeshError),
}

/// Meshes the smooth union of `ellipsoids` (see the [module docs](self) for the method).
///
/// The result is closed, manifold and oriented outward; every vertex lies on the zero set of
/// the blob's implicit function, hence exactly (to rounding) on one of the ellipsoids except
/// in the blending seams. Deterministic: the same input gives bit-identical output.
pub fn blob(ellipsoids: &[EllipsoidSpec], options: &BlobOptions) -> Result<Mesh, BlobError> {
    let field = Field::new(ellipsoids, options)?;
    let min_radius = field.min_radius;
    // Pilot: extract (counting triangles only) at a cell a little coarser than a rough
    // estimate, then rescale the cell by the square root of the count ratio.
    let rough_area: f64 = ellipsoids.iter().map(|e| approximate_area(e.radii)).sum();
    let target = options.target_faces as f64;
    let max_cell = min_radius;
    let pilot_cell = (2.0 * (FACES_PER_AREA_CELL2 * rough_area / target).sqrt()).min(max_cell);
    let pilot_grid = Grid::sample(&field, pilot_cell)?;
    let pilot_faces = pilot_grid.count_triangles();
    let cell = if pilot_faces == 0 {
        pilot_cell / 2.0
    } else {
        (pilot_cell * (pilot_faces as f64 / target).sqrt()).min(max_cell)
    };
    let grid = Grid::sample(&field, cell)?;
    let (mut positions, faces) = grid.extract();
    let tolerance = 1e-13 * field.scale;
    positions
        .par_iter_mut()
        .for_each(|p| *p = field.project(*p, tolerance, cell));
    unfold(&field, &mut positions, &faces, tolerance, cell);
    Ok(Mesh::new(positions, faces)?)
}

/// `count` random ellipsoids forming one connected blob of genus 0, reproducibly from `seed`.
///
/// Radii are drawn in `[0.5, 1.5]` (axis ratios up to 1:3), orientations uniformly
/// (Shoemake 1992). The first ellipsoid sits at the origin; each next one is attached to a
/// randomly chosen earlier one (its *parent*): it contains a random point of the parent's
/// surface at 30–70% of its own depth, so the union stays one connected piece. A candidate is
/// kept only if it stays at least a tenth of the smallest radius away from every ellipsoid but
/// its parent (so the union is a tree of overlapping convex pieces: no rings, no cavities,
/// genus 0), if the two surfaces cross at an angle that leaves a groove at least 60° wide,
/// and if every ellipsoid keeps at least 60% of its surface samples outside all the
/// others (so each one remains recognisable). After 1000 rejected candidates for one slot
/// the last one is kept regardless (not seen in practice for counts up to 8).
pub fn random_ellipsoids(seed: u64, count: usize) -> Vec<EllipsoidSpec> {
    const ATTEMPTS: usize = 1000;
    let mut rng = SplitMix64::new(seed);
    let mut out: Vec<EllipsoidSpec> = Vec::with_capacity(count);
    let samples = fibonacci_sphere(SURFACE_SAMPLES);
    while out.len() < count {
        let mut chosen = None;
        for _ in 0..ATTEMPTS {
            let radii = DVec3::new(
                rng.range_f64(0.5, 1.5),
                rng.range_f64(0.5, 1.5),
                rng.range_f64(0.5, 1.5),
            );
            let rotation = random_rotation(&mut rng);
            if out.is_empty() {
                chosen = Some(EllipsoidSpec {
                    center: DVec3::ZERO,
                    rotation,
                    radii,
                });
                break;
            }
            let parent_index = rng.below(out.len() as u64) as usize;
            let Some(parent) = out.get(parent_index) else {
                continue;
            };
            let direction = rng.unit_vector();
            let (surface_point, normal) = surface_point_and_normal(parent, direction);
            let depth = rng.range_f64(0.3, 0.7);
            let candidate = EllipsoidSpec {
                center: DVec3::ZERO,
                rotation,
                radii,
            };
            // Distance from the centre to the surface along −normal.
            let reach = ray_length(&candidate, -normal);
            let candidate = EllipsoidSpec {
                center: surface_point + normal * (reach * depth),
                ..candidate
            };
            chosen = Some(candidate);
            if accepts(&out, &candidate, parent_index, &samples) {
                break;
            }
        }
        match chosen {
            Some(e) => out.push(e),
            None => break, // not reachable: the loop runs at least once
        }
    }
    out
}

/// Signed Euclidean distance from `p` to the surface of `ellipsoid`: negative inside.
///
/// Exact up to rounding, by bisection on the Lagrange parameter (D. Eberly, *Distance from a
/// point to an ellipse, an ellipsoid, or a hyperellipsoid*, Geometric Tools, 2013), including
/// the degenerate cases of points on the principal planes.
pub fn distance_to_ellipsoid(ellipsoid: &EllipsoidSpec, p: DVec3) -> f64 {
    let q = ellipsoid.rotation.normalize().inverse() * (p - ellipsoid.center);
    let r = ellipsoid.radii;
    let inside = (q / r).length_squared() < 1.0;
    // Sort axes by decreasing radius; work in the first octant.
    let mut axes = [(r.x, q.x.abs()), (r.y, q.y.abs()), (r.z, q.z.abs())];
    axes.sort_by(|a, b| b.0.total_cmp(&a.0));
    let e = [axes[0].0, axes[1].0, axes[2].0];
    let y = [axes[0].1, axes[1].1, axes[2].1];
    let d = distance_sorted(&e, &y);
    if inside {
        -d
    } else {
        d
    }
}

/// Unsigned distance from `y` (first octant) to the axis-aligned ellipsoid with radii `e`
/// sorted in decreasing order, in any dimension 1..=3.
fn distance_sorted(e: &[f64], y: &[f64]) -> f64 {
    let n = e.len().min(y.len());
    let (Some(&e_last), Some(&y_last)) = (e.get(n - 1), y.get(n - 1)) else {
        return 0.0;
    };
    if n == 1 {
        return (y_last - e_last).abs();
    }
    if y_last > 0.0 {
        // g(t) = Σ (e_i y_i / (t + e_i²))² − 1 decreases from +∞ to −1 on (−e_last², ∞).
        let g = |t: f64| -> f64 {
            e.iter()
                .zip(y)
                .map(|(&ei, &yi)| {
                    let s = ei * yi / (t + ei * ei);
                    s * s
                })
                .sum::<f64>()
                - 1.0
        };
        let norm = e
            .iter()
            .zip(y)
            .map(|(&ei, &yi)| (ei * yi) * (ei * yi))
            .sum::<f64>()
            .sqrt();
        let mut lo = -e_last * e_last + e_last * y_last;
        let mut hi = -e_last * e_last + norm;
        for _ in 0..256 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if g(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let t = 0.5 * (lo + hi);
        return e
            .iter()
            .zip(y)
            .map(|(&ei, &yi)| {
                let xi = ei * ei * yi / (t + ei * ei);
                (xi - yi) * (xi - yi)
            })
            .sum::<f64>()
            .sqrt();
    }
    // y_last = 0: the closest point leaves the plane when the point projects inside the
    // "evolute ellipse"; otherwise the problem drops one dimension.
    let mut x = [0.0; 3];
    let mut sum = 0.0;
    let mut leaves_plane = true;
    for i in 0..n - 1 {
        let (Some(&ei), Some(&yi)) = (e.get(i), y.get(i)) else {
            return 0.0;
        };
        if yi == 0.0 {
            continue;
        }
        let denom = ei * ei - e_last * e_last;
        if denom <= 0.0 {
            leaves_plane = false;
            break;
        }
        let xi = ei * ei * yi / denom;
        if let Some(slot) = x.get_mut(i) {
            *slot = xi;
        }
        sum += (xi / ei) * (xi / ei);
    }
    if leaves_plane && sum < 1.0 {
        let x_last = e_last * (1.0 - sum).sqrt();
        let mut d2 = x_last * x_last;
        for i in 0..n - 1 {
            let (Some(&xi), Some(&yi)) = (x.get(i), y.get(i)) else {
                return 0.0;
            };
            d2 += (xi - yi) * (xi - yi);
        }
        return d2.sqrt();
    }
    distance_sorted(&e[..n - 1], &y[..n - 1])
}

/// Triangles per (area / cell²) that marching tetrahedra on the Kuhn grid produces on smooth
/// surfaces; only seeds the pilot, which measures the real value.
const FACES_PER_AREA_CELL2: f64 = 3.0;

/// Samples of a candidate's surface nearest its parent's surface whose normals are checked.
const SEAM_SAMPLES: usize = 24;

/// Smallest cosine between the two outward normals where a candidate meets its parent.
const MIN_SEAM_COSINE: f64 = -0.5;

/// Surface samples per ellipsoid for the acceptance tests of [`random_ellipsoids`].
const SURFACE_SAMPLES: usize = 1024;

/// One ellipsoid, prepared for evaluation.
struct Prepared {
    center: DVec3,
    to_local: DMat3,
    to_world: DMat3,
    inv_r: DVec3,
    inv_r2: DVec3,
    min_radius: f64,
}

impl Prepared {
    /// Quilez's first-order distance estimate and its gradient (world frame).
    fn value_gradient(&self, p: DVec3) -> (f64, DVec3) {
        let q = self.to_local * (p - self.center);
        let a = q * self.inv_r; // q / r
        let b = q * self.inv_r2; // q / r²
        let k0 = a.length();
        let k1 = b.length();
        if k1 < 1e-300 || k0 < 1e-300 {
            // At the centre: the estimate's limit depends on direction; any inside value works.
            return (-self.min_radius, DVec3::ZERO);
        }
        let value = k0 * (k0 - 1.0) / k1;
        // ∇k0 = (q / r²) / k0, ∇k1 = (q / r⁴) / k1.
        let grad_k0 = b / k0;
        let grad_k1 = (b * self.inv_r2) / k1;
        let grad_local = ((2.0 * k0 - 1.0) * grad_k0 - value * grad_k1) / k1;
        (value, self.to_world * grad_local)
    }

    fn value(&self, p: DVec3) -> f64 {
        let q = self.to_local * (p - self.center);
        let k0 = (q * self.inv_r).length();
        let k1 = (q * self.inv_r2).length();
        if k1 < 1e-300 || k0 < 1e-300 {
            return -self.min_radius;
        }
        k0 * (k0 - 1.0) / k1
    }
}

/// The blob's implicit function.
struct Field {
    parts: Vec<Prepared>,
    /// Smooth-min width.
    k: f64,
    min_radius: f64,
    /// Size of the scene (largest extent), the unit of the projection tolerance.
    scale: f64,
    lo: DVec3,
    hi: DVec3,
}

impl Field {
    fn new(ellipsoids: &[EllipsoidSpec], options: &BlobOptions) -> Result<Field, BlobError> {
        if ellipsoids.is_empty() {
            return Err(BlobError::NoEllipsoids);
        }
        if !(MIN_TARGET_FACES..=MAX_TARGET_FACES).contains(&options.target_faces) {
            return Err(BlobError::InvalidTargetFaces {
                target: options.target_faces,
                min: MIN_TARGET_FACES,
                max: MAX_TARGET_FACES,
            });
        }
        if !(0.0..=1.0).contains(&options.blend) {
            return Err(BlobError::InvalidBlend {
                blend: options.blend,
            });
        }
        let mut parts = Vec::with_capacity(ellipsoids.len());
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for (index, e) in ellipsoids.iter().enumerate() {
            let invalid = |reason| BlobError::InvalidEllipsoid { index, reason };
            if !e.center.is_finite() || !e.radii.is_finite() || !e.rotation.is_finite() {
                return Err(invalid("non-finite value"));
            }
            if e.radii.min_element() <= 0.0 {
                return Err(invalid("radius not positive"));
            }
            if e.rotation.length() < 1e-12 {
                return Err(invalid("zero rotation quaternion"));
            }
            let rotation = DMat3::from_quat(e.rotation.normalize());
            // Half-extents of the rotated box: |R| · r.
            let abs = DMat3::from_cols(
                rotation.x_axis.abs(),
                rotation.y_axis.abs(),
                rotation.z_axis.abs(),
            );
            let half = abs * e.radii;
            lo = lo.min(e.center - half);
            hi = hi.max(e.center + half);
            parts.push(Prepared {
                center: e.center,
                to_local: rotation.transpose(),
                to_world: rotation,
                inv_r: e.radii.recip(),
                inv_r2: (e.radii * e.radii).recip(),
                min_radius: e.radii.min_element(),
            });
        }
        let min_radius = parts
            .iter()
            .map(|p| p.min_radius)
            .fold(f64::INFINITY, f64::min);
        let k = options.blend * min_radius;
        let scale = (hi - lo).max_element();
        if !scale.is_finite() {
            return Err(BlobError::InvalidEllipsoid {
                index: 0,
                reason: "coordinates too large",
            });
        }
        Ok(Field {
            parts,
            k,
            min_radius,
            scale,
            lo,
            hi,
        })
    }

    fn value(&self, p: DVec3) -> f64 {
        let mut iter = self.parts.iter();
        let Some(first) = iter.next() else {
            return f64::INFINITY;
        };
        let mut acc = first.value(p);
        for part in iter {
            acc = smooth_min(acc, part.value(p), self.k).0;
        }
        acc
    }

    fn value_gradient(&self, p: DVec3) -> (f64, DVec3) {
        let mut iter = self.parts.iter();
        let Some(first) = iter.next() else {
            return (f64::INFINITY, DVec3::ZERO);
        };
        let (mut acc, mut grad) = first.value_gradient(p);
        for part in iter {
            let (v, g) = part.value_gradient(p);
            let (m, w) = smooth_min(acc, v, self.k);
            acc = m;
            grad = grad * (1.0 - w) + g * w;
        }
        (acc, grad)
    }

    /// Moves `p` onto the zero set by damped Newton steps along the gradient, each step at
    /// most `max_step` long and accepted only if it reduces |F|.
    fn project(&self, start: DVec3, tolerance: f64, max_step: f64) -> DVec3 {
        let mut p = start;
        let (mut f, mut g) = self.value_gradient(p);
        for _ in 0..64 {
            if f.abs() <= tolerance {
                break;
            }
            let g2 = g.length_squared();
            if g2 < 1e-300 {
                break;
            }
            let mut step = -g * (f / g2);
            let len = step.length();
            if len > max_step {
                step *= max_step / len;
            }
            let mut improved = false;
            for _ in 0..40 {
                let candidate = p + step;
                let (fc, gc) = self.value_gradient(candidate);
                if fc.abs() < f.abs() {
                    p = candidate;
                    f = fc;
                    g = gc;
                    improved = true;
                    break;
                }
                step *= 0.5;
            }
            if !improved {
                break;
            }
        }
        p
    }
}

/// Rounds of [`unfold`] before giving up (never reached on the fixtures).
const UNFOLD_ROUNDS: usize = 50;

/// Removes the folds the extraction leaves in narrow seams.
///
/// Where two ellipsoids meet in a groove narrower than a cell, the piecewise-linear surface
/// can fold, and projection puts the folded triangles onto a groove wall facing inward. A
/// face is *folded* when its normal points against the sum of the surface normals at its
/// corners. Each round moves every corner of a folded face to the mean of its neighbours and
/// projects it back onto the zero set (Jacobi style, so the result does not depend on the
/// order); from the fifth round on, the neighbours of those vertices move too, to give a
/// stubborn fold more room. Vertices away from folds are untouched and stay exactly where
/// projection put them.
fn unfold(field: &Field, positions: &mut [DVec3], faces: &[[u32; 3]], tolerance: f64, cell: f64) {
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); positions.len()];
    for face in faces {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            if let Some(list) = neighbours.get_mut(a as usize) {
                list.push(b);
            }
            if let Some(list) = neighbours.get_mut(b as usize) {
                list.push(a);
            }
        }
    }
    for list in &mut neighbours {
        list.sort_unstable();
        list.dedup();
    }
    for round in 0..UNFOLD_ROUNDS {
        let folded = folded_faces(field, positions, faces);
        let mut moving = vec![false; positions.len()];
        let mut any = false;
        for (face, _) in faces.iter().zip(&folded).filter(|(_, &f)| f) {
            any = true;
            for &i in face {
                if let Some(m) = moving.get_mut(i as usize) {
                    *m = true;
                }
            }
        }
        if !any {
            return;
        }
        if round >= 4 {
            let core = moving.clone();
            for (v, _) in core.iter().enumerate().filter(|(_, &m)| m) {
                for &n in neighbours.get(v).map_or(&[][..], |l| &l[..]) {
                    if let Some(m) = moving.get_mut(n as usize) {
                        *m = true;
                    }
                }
            }
        }
        let updates: Vec<(usize, DVec3)> = moving
            .iter()
            .enumerate()
            .filter(|(_, &m)| m)
            .filter_map(|(v, _)| {
                let list = neighbours.get(v)?;
                if list.is_empty() {
                    return None;
                }
                let mean = list
                    .iter()
                    .filter_map(|&n| positions.get(n as usize))
                    .sum::<DVec3>()
                    / list.len() as f64;
                Some((v, field.project(mean, tolerance, cell)))
            })
            .collect();
        for (v, p) in updates {
            if let Some(slot) = positions.get_mut(v) {
                *slot = p;
            }
        }
    }
}

/// For each face, whether its normal points against the sum of the surface normals (∇F) at
/// its corners.
fn folded_faces(field: &Field, positions: &[DVec3], faces: &[[u32; 3]]) -> Vec<bool> {
    let normals: Vec<DVec3> = positions
        .par_iter()
        .map(|&p| field.value_gradient(p).1.normalize_or_zero())
        .collect();
    faces
        .iter()
        .map(|face| {
            let [a, b, c] = face.map(|i| i as usize);
            let (Some(&pa), Some(&pb), Some(&pc)) =
                (positions.get(a), positions.get(b), positions.get(c))
            else {
                return false;
            };
            let expected = face
                .iter()
                .filter_map(|&i| normals.get(i as usize))
                .sum::<DVec3>();
            (pb - pa).cross(pc - pa).dot(expected) <= 0.0
        })
        .collect()
}

/// Quilez's cubic polynomial smooth minimum of `a` and `b` with width `k`, and the weight of
/// `b` in its gradient (∇ = (1 − w)∇a + w∇b). Equals `min(a, b)` when `|a − b| ≥ k`.
fn smooth_min(a: f64, b: f64, k: f64) -> (f64, f64) {
    let diff = (a - b).abs();
    if k <= 0.0 || diff >= k {
        return if a <= b { (a, 0.0) } else { (b, 1.0) };
    }
    let h = (k - diff) / k;
    let dip = k * h * h * h / 6.0;
    let shared = 0.5 * h * h;
    if a <= b {
        (a - dip, shared)
    } else {
        (b - dip, 1.0 - shared)
    }
}

/// The six tetrahedra of the Kuhn triangulation of the unit cube, as cube-corner indices
/// (bit 0 = x, bit 1 = y, bit 2 = z); each is a monotone path from corner 0 to corner 7.
const KUHN_TETS: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// The field sampled on a regular grid.
struct Grid {
    origin: DVec3,
    cell: f64,
    dims: [usize; 3],
    values: Vec<f64>,
}

impl Grid {
    fn sample(field: &Field, cell: f64) -> Result<Grid, BlobError> {
        // Margin: the smooth union bulges by at most k/6; two cells more keep the border
        // strictly outside, so the surface is closed.
        let margin = field.k + 2.0 * cell;
        let origin = field.lo - DVec3::splat(margin);
        let extent = (field.hi + DVec3::splat(margin)) - origin;
        let counts = (extent / cell).ceil() + DVec3::ONE;
        let too_large = |points: u128| BlobError::GridTooLarge {
            points,
            max: MAX_GRID_POINTS,
        };
        if !counts.is_finite() || counts.max_element() > MAX_GRID_POINTS as f64 {
            return Err(too_large(u128::MAX));
        }
        // In range: each count is finite, positive and at most MAX_GRID_POINTS.
        let dims = [counts.x as usize, counts.y as usize, counts.z as usize];
        let points = dims.iter().map(|&d| d as u128).product::<u128>();
        if points > MAX_GRID_POINTS as u128 {
            return Err(too_large(points));
        }
        let [nx, ny, _] = dims;
        let slab = nx * ny;
        let mut values = vec![0.0; points as usize];
        // Values within 1% of a cell of zero are pushed away from it (keeping their sign), so
        // no surface vertex starts next to a grid point; see the module docs.
        let push = 0.01 * cell;
        values
            .par_chunks_mut(slab.max(1))
            .enumerate()
            .for_each(|(z, chunk)| {
                for (i, v) in chunk.iter_mut().enumerate() {
                    let (x, y) = (i % nx, i / nx);
                    let p = origin + DVec3::new(x as f64, y as f64, z as f64) * cell;
                    let f = field.value(p);
                    *v = if f >= 0.0 { f.max(push) } else { f.min(-push) };
                }
            });
        Ok(Grid {
            origin,
            cell,
            dims,
            values,
        })
    }

    fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    fn point(&self, index: usize) -> DVec3 {
        let [nx, ny, _] = self.dims;
        let x = index % nx;
        let y = (index / nx) % ny;
        let z = index / (nx * ny);
        self.origin + DVec3::new(x as f64, y as f64, z as f64) * self.cell
    }

    /// Calls `visit` with the grid indices and values of the corners of every cube that the
    /// surface crosses.
    fn for_each_crossed_cube(&self, mut visit: impl FnMut([usize; 8], [f64; 8])) {
        let [nx, ny, nz] = self.dims;
        for z in 0..nz.saturating_sub(1) {
            for y in 0..ny.saturating_sub(1) {
                for x in 0..nx.saturating_sub(1) {
                    let base = self.index(x, y, z);
                    let corners: [usize; 8] = std::array::from_fn(|c| {
                        base + (c & 1) + ((c >> 1) & 1) * nx + ((c >> 2) & 1) * nx * ny
                    });
                    let values = corners.map(|i| self.values.get(i).copied().unwrap_or(1.0));
                    let inside = values.iter().filter(|v| **v < 0.0).count();
                    if inside != 0 && inside != 8 {
                        visit(corners, values);
                    }
                }
            }
        }
    }

    /// Number of triangles marching tetrahedra would produce.
    fn count_triangles(&self) -> usize {
        let mut count = 0;
        self.for_each_crossed_cube(|_, values| {
            for tet in KUHN_TETS {
                match tet.iter().filter(|&&c| values[c] < 0.0).count() {
                    1 | 3 => count += 1,
                    2 => count += 2,
                    _ => {}
                }
            }
        });
        count
    }

    /// Marching tetrahedra: vertices (linearly interpolated, not yet projected) and
    /// outward-oriented triangles.
    fn extract(&self) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mut positions: Vec<DVec3> = Vec::new();
        let mut faces: Vec<[u32; 3]> = Vec::new();
        let mut edge_vertex: HashMap<u64, u32> = HashMap::new();
        self.for_each_crossed_cube(|corners, values| {
            for tet in KUHN_TETS {
                let mut inside = [0usize; 4];
                let mut outside = [0usize; 4];
                let (mut ni, mut no) = (0, 0);
                for &c in &tet {
                    if values[c] < 0.0 {
                        inside[ni] = c;
                        ni += 1;
                    } else {
                        outside[no] = c;
                        no += 1;
                    }
                }
                if ni == 0 || no == 0 {
                    continue;
                }
                let mut vertex = |a: usize, b: usize| -> (u32, DVec3) {
                    // Kuhn edges join corners whose bit sets nest; key by the lower one.
                    let (lo, hi) = if a & b == a { (a, b) } else { (b, a) };
                    let key = ((corners[lo] as u64) << 3) | (lo ^ hi) as u64;
                    let (pa, pb) = (self.point(corners[a]), self.point(corners[b]));
                    let (va, vb) = (values[a], values[b]);
                    let p = pa + (pb - pa) * (va / (va - vb));
                    let id = *edge_vertex.entry(key).or_insert_with(|| {
                        positions.push(p);
                        (positions.len() - 1) as u32
                    });
                    (id, p)
                };
                let centroid = |set: &[usize]| {
                    set.iter().map(|&c| self.point(corners[c])).sum::<DVec3>() / set.len() as f64
                };
                let outward = centroid(&outside[..no]) - centroid(&inside[..ni]);
                let mut emit = |t: [(u32, DVec3); 3]| {
                    let n = (t[1].1 - t[0].1).cross(t[2].1 - t[0].1);
                    faces.push(if n.dot(outward) >= 0.0 {
                        [t[0].0, t[1].0, t[2].0]
                    } else {
                        [t[0].0, t[2].0, t[1].0]
                    });
                };
                match (ni, no) {
                    (1, 3) => {
                        let i = inside[0];
                        emit([
                            vertex(i, outside[0]),
                            vertex(i, outside[1]),
                            vertex(i, outside[2]),
                        ]);
                    }
                    (3, 1) => {
                        let o = outside[0];
                        emit([
                            vertex(inside[0], o),
                            vertex(inside[1], o),
                            vertex(inside[2], o),
                        ]);
                    }
                    _ => {
                        // A quad around the tetrahedron; split along its shorter diagonal.
                        let q = [
                            vertex(inside[0], outside[0]),
                            vertex(inside[0], outside[1]),
                            vertex(inside[1], outside[1]),
                            vertex(inside[1], outside[0]),
                        ];
                        if (q[0].1 - q[2].1).length_squared() <= (q[1].1 - q[3].1).length_squared()
                        {
                            emit([q[0], q[1], q[2]]);
                            emit([q[0], q[2], q[3]]);
                        } else {
                            emit([q[0], q[1], q[3]]);
                            emit([q[1], q[2], q[3]]);
                        }
                    }
                }
            }
        });
        (positions, faces)
    }
}

/// Ramanujan-like approximation of an ellipsoid's area (Knud Thomsen's formula, p = 1.6075,
/// error under 1.1%); only seeds the pilot.
fn approximate_area(r: DVec3) -> f64 {
    let p = 1.6075;
    let (a, b, c) = (r.x.powf(p), r.y.powf(p), r.z.powf(p));
    4.0 * std::f64::consts::PI * ((a * b + a * c + b * c) / 3.0).powf(1.0 / p)
}

/// A uniformly random rotation (Shoemake, *Uniform random rotations*, Graphics Gems III, 1992).
fn random_rotation(rng: &mut SplitMix64) -> DQuat {
    let u1 = rng.next_f64();
    let u2 = rng.range_f64(0.0, std::f64::consts::TAU);
    let u3 = rng.range_f64(0.0, std::f64::consts::TAU);
    let (s, t) = ((1.0 - u1).sqrt(), u1.sqrt());
    DQuat::from_xyzw(s * u2.sin(), s * u2.cos(), t * u3.sin(), t * u3.cos()).normalize()
}

/// The point of `e`'s surface in local direction `u` from its centre (after scaling), and the
/// outward unit normal there, both in world coordinates.
fn surface_point_and_normal(e: &EllipsoidSpec, u: DVec3) -> (DVec3, DVec3) {
    let rotation = e.rotation.normalize();
    let local = u * e.radii;
    let normal_local = (u / e.radii).normalize_or(DVec3::Z);
    (e.center + rotation * local, rotation * normal_local)
}

/// Distance from `e`'s centre to its surface along world direction `d` (unit).
fn ray_length(e: &EllipsoidSpec, d: DVec3) -> f64 {
    let local = e.rotation.normalize().inverse() * d;
    let s = (local / e.radii).length();
    if s > 0.0 {
        1.0 / s
    } else {
        e.radii.min_element()
    }
}

/// `n` nearly evenly spread unit vectors (Fibonacci lattice).
fn fibonacci_sphere(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f64 / n as f64;
            let s = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            DVec3::new(s * phi.cos(), s * phi.sin(), z)
        })
        .collect()
}

/// Whether `candidate`, attached to `parent`, keeps the blob a tree of overlapping pieces in
/// which every ellipsoid stays mostly exposed (see [`random_ellipsoids`]).
fn accepts(
    placed: &[EllipsoidSpec],
    candidate: &EllipsoidSpec,
    parent: usize,
    samples: &[DVec3],
) -> bool {
    let min_radius = placed
        .iter()
        .chain(std::iter::once(candidate))
        .map(|e| e.radii.min_element())
        .fold(f64::INFINITY, f64::min);
    let gap = 0.1 * min_radius;
    let surface = |e: &EllipsoidSpec| -> Vec<DVec3> {
        samples
            .iter()
            .map(|&u| surface_point_and_normal(e, u).0)
            .collect()
    };
    let candidate_surface = surface(candidate);
    for (i, other) in placed.iter().enumerate() {
        if i == parent {
            continue;
        }
        // Disjoint with a gap: neither surface comes near the other, and neither contains
        // the other's centre.
        if distance_to_ellipsoid(other, candidate.center) < gap
            || distance_to_ellipsoid(candidate, other.center) < gap
        {
            return false;
        }
        if candidate_surface
            .iter()
            .any(|&p| distance_to_ellipsoid(other, p) < gap)
        {
            return false;
        }
        if surface(other)
            .iter()
            .any(|&p| distance_to_ellipsoid(candidate, p) < gap)
        {
            return false;
        }
    }
    // The seam with the parent is no sharp groove: where the two surfaces cross, their
    // outward normals are at most 120° apart (a groove opening of at least 60°), so a grid
    // of the sizes used resolves it without folds.
    let Some(parent_spec) = placed.get(parent) else {
        return false;
    };
    let mut near_seam: Vec<(f64, DVec3)> = candidate_surface
        .iter()
        .map(|&p| (distance_to_ellipsoid(parent_spec, p).abs(), p))
        .collect();
    near_seam.sort_by(|a, b| a.0.total_cmp(&b.0));
    for &(_, p) in near_seam.iter().take(SEAM_SAMPLES) {
        if outward_normal(candidate, p).dot(outward_normal(parent_spec, p)) < MIN_SEAM_COSINE {
            return false;
        }
    }
    // Every ellipsoid keeps at least 60% of its surface samples outside all the others.
    let all: Vec<&EllipsoidSpec> = placed.iter().chain(std::iter::once(candidate)).collect();
    for (i, e) in all.iter().enumerate() {
        let points = surface(e);
        let exposed = points
            .iter()
            .filter(|&&p| {
                all.iter()
                    .enumerate()
                    .all(|(j, o)| j == i || !contains(o, p))
            })
            .count();
        if exposed * 10 < points.len() * 6 {
            return false;
        }
    }
    true
}

/// Unit outward normal of the level set of `e`'s quadric through `p`.
fn outward_normal(e: &EllipsoidSpec, p: DVec3) -> DVec3 {
    let rotation = e.rotation.normalize();
    let q = rotation.inverse() * (p - e.center);
    (rotation * (q / (e.radii * e.radii))).normalize_or_zero()
}

/// Whether `p` is inside `e`.
fn contains(e: &EllipsoidSpec, p: DVec3) -> bool {
    let q = e.rotation.normalize().inverse() * (p - e.center);
    (q / e.radii).length_squared() < 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(center: DVec3, r: f64) -> EllipsoidSpec {
        EllipsoidSpec {
            center,
            rotation: DQuat::IDENTITY,
            radii: DVec3::splat(r),
        }
    }

    #[test]
    fn smooth_min_is_min_outside_the_band() {
        assert_eq!(smooth_min(1.0, 2.0, 0.5), (1.0, 0.0));
        assert_eq!(smooth_min(3.0, 2.0, 0.5), (2.0, 1.0));
        let (v, w) = smooth_min(1.0, 1.0, 0.6);
        assert!((v - (1.0 - 0.1)).abs() < 1e-15);
        assert!((w - 0.5).abs() < 1e-15);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let e = EllipsoidSpec {
            center: DVec3::new(0.3, -0.2, 0.1),
            rotation: DQuat::from_rotation_y(0.7) * DQuat::from_rotation_x(0.3),
            radii: DVec3::new(1.5, 0.8, 0.5),
        };
        let f = Field::new(
            &[e, sphere(DVec3::new(1.2, 0.0, 0.0), 0.7)],
            &BlobOptions {
                blend: 0.3,
                ..BlobOptions::default()
            },
        )
        .unwrap();
        let h = 1e-6;
        for p in [
            DVec3::new(0.9, 0.3, 0.2),
            DVec3::new(1.4, 0.1, -0.3),
            DVec3::new(-1.0, 0.5, 0.7),
        ] {
            let (v, g) = f.value_gradient(p);
            assert_eq!(v, f.value(p));
            let fd = DVec3::new(
                f.value(p + DVec3::X * h) - f.value(p - DVec3::X * h),
                f.value(p + DVec3::Y * h) - f.value(p - DVec3::Y * h),
                f.value(p + DVec3::Z * h) - f.value(p - DVec3::Z * h),
            ) / (2.0 * h);
            assert!((g - fd).length() < 1e-6, "{g} vs {fd}");
        }
    }

    #[test]
    fn zero_set_is_the_ellipsoid() {
        let e = EllipsoidSpec {
            center: DVec3::new(1.0, 2.0, 3.0),
            rotation: DQuat::from_rotation_z(0.4),
            radii: DVec3::new(2.0, 1.0, 0.5),
        };
        for u in fibonacci_sphere(50) {
            let (p, n) = surface_point_and_normal(&e, u);
            let f = Field::new(&[e], &BlobOptions::default()).unwrap();
            assert!(f.value(p).abs() < 1e-14);
            assert!(distance_to_ellipsoid(&e, p).abs() < 1e-12);
            // The gradient is the outward normal, scaled by about one.
            let (_, g) = f.value_gradient(p);
            assert!(g.normalize().dot(n) > 1.0 - 1e-12);
        }
    }

    #[test]
    fn distance_to_ellipsoid_matches_known_cases() {
        let s = sphere(DVec3::new(1.0, 1.0, 1.0), 2.0);
        assert!((distance_to_ellipsoid(&s, DVec3::new(1.0, 1.0, 5.0)) - 2.0).abs() < 1e-12);
        assert!((distance_to_ellipsoid(&s, DVec3::new(1.0, 1.0, 1.0)) + 2.0).abs() < 1e-12);
        let e = EllipsoidSpec {
            center: DVec3::ZERO,
            rotation: DQuat::IDENTITY,
            radii: DVec3::new(3.0, 2.0, 1.0),
        };
        // On the axes, outside and inside.
        assert!((distance_to_ellipsoid(&e, DVec3::new(5.0, 0.0, 0.0)) - 2.0).abs() < 1e-12);
        assert!((distance_to_ellipsoid(&e, DVec3::new(0.0, 0.0, 0.2)) + 0.8).abs() < 1e-12);
        // The centre: nearest is the end of the smallest axis.
        assert!((distance_to_ellipsoid(&e, DVec3::ZERO) + 1.0).abs() < 1e-12);
        // Against brute force over a dense parametrisation, for points in general position.
        let mut rng = SplitMix64::new(5);
        let dense: Vec<DVec3> = fibonacci_sphere(200_000)
            .into_iter()
            .map(|u| u * e.radii)
            .collect();
        for _ in 0..20 {
            let p = DVec3::new(
                rng.range_f64(-4.0, 4.0),
                rng.range_f64(-3.0, 3.0),
                rng.range_f64(-2.0, 2.0),
            );
            let brute = dense
                .iter()
                .map(|&x| (x - p).length())
                .fold(f64::INFINITY, f64::min);
            let d = distance_to_ellipsoid(&e, p).abs();
            assert!(d <= brute + 1e-12, "{d} > {brute}");
            assert!(brute - d < 0.02, "{d} vs {brute}");
        }
    }

    #[test]
    fn single_sphere_is_closed_and_on_the_surface() {
        let s = sphere(DVec3::new(0.5, 0.0, 0.0), 1.0);
        let mesh = blob(
            &[s],
            &BlobOptions {
                target_faces: 2000,
                blend: 0.05,
            },
        )
        .unwrap();
        assert!(mesh.topology().is_closed() && mesh.topology().is_manifold());
        assert_eq!(mesh.genus(), Some(0));
        for &p in mesh.positions() {
            assert!(distance_to_ellipsoid(&s, p).abs() < 1e-12);
        }
        let v = mesh.volume().unwrap();
        let exact = 4.0 / 3.0 * std::f64::consts::PI;
        assert!(v < exact && v > 0.97 * exact, "{v}");
    }

    #[test]
    fn rejects_bad_input() {
        let s = sphere(DVec3::ZERO, 1.0);
        let o = BlobOptions::default();
        assert_eq!(blob(&[], &o).unwrap_err(), BlobError::NoEllipsoids);
        let bad = EllipsoidSpec {
            radii: DVec3::new(1.0, 0.0, 1.0),
            ..s
        };
        assert!(matches!(
            blob(&[s, bad], &o),
            Err(BlobError::InvalidEllipsoid { index: 1, .. })
        ));
        let nan = EllipsoidSpec {
            center: DVec3::new(f64::NAN, 0.0, 0.0),
            ..s
        };
        assert!(matches!(
            blob(&[nan], &o),
            Err(BlobError::InvalidEllipsoid { index: 0, .. })
        ));
        let small = BlobOptions {
            target_faces: 3,
            ..o
        };
        assert!(matches!(
            blob(&[s], &small),
            Err(BlobError::InvalidTargetFaces { .. })
        ));
        let blend = BlobOptions { blend: -0.1, ..o };
        assert!(matches!(
            blob(&[s], &blend),
            Err(BlobError::InvalidBlend { .. })
        ));
        // A needle next to a huge ellipsoid needs an enormous grid: refused, not attempted.
        let needle = EllipsoidSpec {
            radii: DVec3::new(1e-4, 1e-4, 1e-4),
            ..s
        };
        let huge = EllipsoidSpec {
            radii: DVec3::splat(100.0),
            ..s
        };
        assert!(matches!(
            blob(&[needle, huge], &o),
            Err(BlobError::GridTooLarge { .. })
        ));
    }

    #[test]
    fn random_ellipsoids_are_deterministic_and_bounded() {
        let a = random_ellipsoids(9, 5);
        assert_eq!(a, random_ellipsoids(9, 5));
        assert_ne!(a, random_ellipsoids(10, 5));
        assert_eq!(a.len(), 5);
        assert!(random_ellipsoids(1, 0).is_empty());
        for e in &a {
            assert!(e.radii.min_element() >= 0.5 && e.radii.max_element() <= 1.5);
            assert!((e.rotation.length() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn projected_fixtures_have_no_folds_and_every_vertex_on_the_zero_set() {
        for seed in 1..=3 {
            let es = random_ellipsoids(seed, 5);
            let options = BlobOptions {
                target_faces: 6000,
                ..BlobOptions::default()
            };
            let mesh = blob(&es, &options).unwrap();
            let field = Field::new(&es, &options).unwrap();
            let folded = folded_faces(&field, mesh.positions(), mesh.faces());
            assert_eq!(folded.iter().filter(|&&f| f).count(), 0, "seed {seed}");
            for &p in mesh.positions() {
                assert!(
                    field.value(p).abs() <= 1e-12 * field.scale,
                    "seed {seed}: {p}"
                );
            }
        }
    }
}
