//! The ellipsoid primitive: geometry, error metrics and robust fitting.
//!
//! After P. D. Simari and K. Singh, *Extraction and remeshing of ellipsoidal representations
//! from mesh data*, Graphics Interface 2005: section 2 (radial projection, the Euclidean,
//! angular and curvature distances, negative ellipsoids), section 3 (the volume metric) and
//! section 4 "Ellipsoid fitting" (nine parameters plus a sign, principal-axes start, one
//! minimisation per sign keeping the lower error).
//!
//! - [`Ellipsoid`] (this module): centre, rotation, radii and [`Sign`]; the maps to and from
//!   the unit sphere, radial projection Π, normals, closed-form mean and Gaussian curvature,
//!   ray intersection, inside test, volume.
//! - [`metric`]: the paper's per-vertex, per-face and per-region errors, its default weights,
//!   and the canonical scale that makes those defaults unit-free.
//! - [`fit`]: robust Levenberg–Marquardt fitting from several starts, both signs.
//! - [`hull`]: the convex-hull volume V(R) of the volume metric.
//!
//! Sign convention shared with [`crate::mesh::curvature`]: mean curvature is +1/r on a sphere
//! of radius r whose normals point outward, and negative on concave surfaces. A
//! [`Sign::Negative`] ellipsoid stands for the inner surface: its normals point inward and
//! its mean curvature is negated (the Gaussian curvature does not change).

pub mod fit;
pub mod hull;
pub mod metric;

pub use fit::{fit_ellipsoid, Fit, FitInput, FitOptions};
pub use metric::{vertex_error, MeshScale, Weights};

use crate::synth::EllipsoidSpec;
use glam::{DMat3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// Which side of the ellipsoid's surface represents the mesh (paper, section 2, "Negative
/// ellipsoids").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Sign {
    /// The outer surface: normals point away from the centre, mean curvature positive.
    Positive,
    /// The inner surface (bowls, concavities): normals point towards the centre, mean
    /// curvature negative.
    Negative,
}

impl Sign {
    /// +1 for [`Sign::Positive`], −1 for [`Sign::Negative`].
    pub fn factor(self) -> f64 {
        match self {
            Sign::Positive => 1.0,
            Sign::Negative => -1.0,
        }
    }

    /// The other sign.
    pub fn flipped(self) -> Sign {
        match self {
            Sign::Positive => Sign::Negative,
            Sign::Negative => Sign::Positive,
        }
    }
}

/// An ellipsoid: the unit sphere scaled by `radii` along its local x, y, z axes, rotated by
/// `rotation`, moved to `center`; `sign` says which of its two surfaces is meant.
///
/// The paper's nine parameters (section 4): three for the centre, three radii, three for the
/// alignment (here a unit quaternion), plus the sign.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ellipsoid {
    /// Centre.
    pub center: DVec3,
    /// Orientation: maps local axes to world axes (unit quaternion).
    pub rotation: DQuat,
    /// Semi-axis lengths along the local x, y, z axes; positive.
    pub radii: DVec3,
    /// Outer or inner surface.
    pub sign: Sign,
}

/// Which way vectors point against an ellipsoid's signed normal ([`Ellipsoid::normal`]),
/// without normalising it: the implicit function's gradient, taken in the ellipsoid's own
/// frame (a matrix, not a quaternion, per point). For sign tests many times over, such as
/// whether each face of a mesh is turned against the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalSide {
    center: DVec3,
    to_local: DMat3,
    /// The sign over the squared radii.
    weights: DVec3,
}

impl NormalSide {
    /// `v` · [`Ellipsoid::normal`]`(p)` times a positive factor (the gradient's length at
    /// `p`); zero at the centre.
    pub fn along(&self, p: DVec3, v: DVec3) -> f64 {
        let x = self.to_local * (p - self.center);
        (self.to_local * v).dot(x * self.weights)
    }

    /// [`NormalSide::along`] for a triangle: its area vector (corners counter-clockwise seen
    /// from the side it faces) at its centroid. Negative when the triangle is turned against
    /// the surface, the test [`crate::remesh::assemble::check_mesh`] makes of every triangle.
    #[inline]
    pub fn facing(&self, [a, b, c]: [DVec3; 3]) -> f64 {
        self.along((a + b + c) / 3.0, (b - a).cross(c - a))
    }
}

/// Below this fraction of the smallest radius a point counts as the centre itself, where the
/// radial projection is undefined.
const CENTRE_EPSILON: f64 = 1e-14;

/// Most iterations of [`Ellipsoid::closest_point`]'s root finder (Newton converges in a
/// handful; bisection steps, which halve the bracket, bound the rest).
const MAX_FOOT_ITERATIONS: usize = 100;

impl Ellipsoid {
    /// A positive sphere.
    pub fn sphere(center: DVec3, radius: f64) -> Ellipsoid {
        Ellipsoid {
            center,
            rotation: DQuat::IDENTITY,
            radii: DVec3::splat(radius),
            sign: Sign::Positive,
        }
    }

    /// Half the size of the ellipsoid's axis-aligned bounding box.
    pub fn half_extent(&self) -> DVec3 {
        let m = DMat3::from_quat(self.rotation);
        let scaled = [
            m.x_axis * self.radii.x,
            m.y_axis * self.radii.y,
            m.z_axis * self.radii.z,
        ];
        DVec3::new(
            scaled.iter().map(|a| a.x * a.x).sum::<f64>().sqrt(),
            scaled.iter().map(|a| a.y * a.y).sum::<f64>().sqrt(),
            scaled.iter().map(|a| a.z * a.z).sum::<f64>().sqrt(),
        )
    }

    /// The same ellipsoid with the other sign.
    pub fn flipped(&self) -> Ellipsoid {
        Ellipsoid {
            sign: self.sign.flipped(),
            ..*self
        }
    }

    /// Whether every parameter is finite and every radius positive.
    pub fn is_valid(&self) -> bool {
        self.center.is_finite()
            && self.rotation.is_finite()
            && self.radii.is_finite()
            && self.radii.min_element() > 0.0
    }

    /// Volume 4/3·π·abc.
    pub fn volume(&self) -> f64 {
        4.0 / 3.0 * std::f64::consts::PI * self.radii.x * self.radii.y * self.radii.z
    }

    /// World point → local coordinates (centred, unrotated, not scaled).
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.rotation.inverse() * (p - self.center)
    }

    /// Map to the unit sphere's space: the point u with `from_unit_sphere(u) == p`. Surface
    /// points map to |u| = 1, inside points to |u| < 1.
    pub fn to_unit_sphere(&self, p: DVec3) -> DVec3 {
        self.to_local(p) / self.radii
    }

    /// Map from the unit sphere's space: centre + rotation · (radii ∘ u).
    pub fn from_unit_sphere(&self, u: DVec3) -> DVec3 {
        self.center + self.rotation * (self.radii * u)
    }

    /// The implicit function |u|² − 1: negative inside, zero on the surface, positive outside.
    pub fn implicit(&self, p: DVec3) -> f64 {
        self.to_unit_sphere(p).length_squared() - 1.0
    }

    /// Whether `p` lies inside or on the ellipsoid (the solid, whatever the sign).
    pub fn contains(&self, p: DVec3) -> bool {
        self.implicit(p) <= 0.0
    }

    /// Radial projection Π(p): where the ray from the centre through `p` meets the surface
    /// (paper, section 2). The centre itself, where that ray is undefined, projects to the end
    /// of the local +x semi-axis.
    pub fn project_radially(&self, p: DVec3) -> DVec3 {
        let u = self.to_unit_sphere(p);
        let rho = u.length();
        if rho > CENTRE_EPSILON && rho.is_finite() {
            self.center + (p - self.center) / rho
        } else {
            self.from_unit_sphere(DVec3::X)
        }
    }

    /// The point of the surface closest to `p` (the foot of the normal through `p`).
    ///
    /// In local coordinates the foot is x = r²∘q / (r² + t) for the root t > −min r² of
    /// Σ (rᵢ qᵢ / (rᵢ² + t))² = 1, which decreases and is convex on that interval; the root
    /// is bracketed as in Eberly, *Distance from a point to an ellipse, an ellipsoid, or a
    /// hyperellipsoid* (2013), and found by Newton's method, falling back to bisection
    /// whenever a step leaves the bracket (a few iterations instead of bisection's ~60). Unlike
    /// Π it moves a point near the surface along the normal only, so points close together
    /// stay in order on the surface however oblique the radial direction is. Where the foot
    /// is not unique (on the inner medial sheet, where the root leaves the interval) it falls
    /// back to Π(p).
    pub fn closest_point(&self, p: DVec3) -> DVec3 {
        let q = self.to_local(p);
        let r2 = self.radii * self.radii;
        let scaled = self.radii * q;
        let s2 = scaled * scaled;
        // f(t) and f'(t).
        let eval = |t: f64| {
            let w = DVec3::ONE / (r2 + DVec3::splat(t));
            let terms = s2 * w * w;
            (terms.element_sum() - 1.0, -2.0 * (terms * w).element_sum())
        };
        let lo0 = -r2.min_element();
        let mut lo = lo0;
        let mut hi = self.radii.max_element() * q.length();
        if !(hi.is_finite() && q.is_finite()) {
            return self.project_radially(p);
        }
        // f(hi) ≤ 0 by construction; f → +∞ at lo unless the point lies in the plane of the
        // shortest axis, where the root may not be in the interval.
        let near_lo = lo + (hi - lo).max(1.0) * 1e-15;
        if eval(near_lo).0 <= 0.0 {
            return self.project_radially(p);
        }
        // Newton from t = 0, the root for a point on the surface: the points this is asked
        // for lie on or near it (boundary points, a mesh's vertices), where a few steps
        // converge. Newton from either side of the root of a convex decreasing function
        // approaches it monotonically.
        let mut t = if lo < 0.0 && hi > 0.0 { 0.0 } else { hi };
        for _ in 0..MAX_FOOT_ITERATIONS {
            let (f, df) = eval(t);
            if f == 0.0 {
                break;
            }
            if f > 0.0 {
                lo = t;
            } else {
                hi = t;
            }
            let newton = t - f / df;
            let next = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            // Converged once the step is down to rounding (of rᵢ² + t, which sets the foot).
            let done = (next - t).abs() <= 4.0 * f64::EPSILON * (t.abs() + r2.min_element());
            t = next;
            if done {
                break;
            }
        }
        let local = r2 * q / (r2 + DVec3::splat(t));
        let foot = self.center + self.rotation * local;
        if foot.is_finite() && t > lo0 {
            foot
        } else {
            self.project_radially(p)
        }
    }

    /// Radial distance ‖p − Π(p)‖; its square is the paper's Euclidean distance E_euc.
    pub fn radial_distance(&self, p: DVec3) -> f64 {
        (p - self.project_radially(p)).length()
    }

    /// Outward unit normal at Π(p), whatever the sign. Normals are constant along rays from
    /// the centre, so `p` need not be on the surface.
    pub fn outward_normal(&self, p: DVec3) -> DVec3 {
        let g = self.to_local(p) / (self.radii * self.radii);
        let local = g.try_normalize().unwrap_or(DVec3::X);
        self.rotation * local
    }

    /// The surface normal at Π(p) as the sign orients it: outward for a positive ellipsoid,
    /// inward for a negative one (paper, section 2).
    pub fn normal(&self, p: DVec3) -> DVec3 {
        self.sign.factor() * self.outward_normal(p)
    }

    /// The signed normal's direction as a linear map, for tests that ask only which side of
    /// the surface a vector points to: see [`NormalSide`].
    pub fn normal_side(&self) -> NormalSide {
        NormalSide {
            center: self.center,
            to_local: DMat3::from_quat(self.rotation.inverse()),
            weights: self.sign.factor() / (self.radii * self.radii),
        }
    }

    /// Mean curvature of the outer surface at Π(p), in closed form; positive (+1/r on a
    /// sphere of radius r).
    ///
    /// With x the local surface point, H = (a² + b² + c² − |x|²) / (2 a²b²c² |g|³) where
    /// g = (x/a², y/b², z/c²) is half the implicit gradient.
    pub fn outward_mean_curvature(&self, p: DVec3) -> f64 {
        let (x, r2) = self.local_surface_point(p);
        let g = x / r2;
        let g_len = g.length();
        let product = r2.x * r2.y * r2.z;
        (r2.x + r2.y + r2.z - x.length_squared()) / (2.0 * product * g_len * g_len * g_len)
    }

    /// Mean curvature at Π(p) with the sign's convention: the outward value for a positive
    /// ellipsoid, its negation for a negative one (paper, section 2).
    pub fn mean_curvature(&self, p: DVec3) -> f64 {
        self.sign.factor() * self.outward_mean_curvature(p)
    }

    /// Gaussian curvature at Π(p), in closed form K = 1 / (a²b²c² |g|⁴); the same for both
    /// signs.
    pub fn gaussian_curvature(&self, p: DVec3) -> f64 {
        let (x, r2) = self.local_surface_point(p);
        let g2 = (x / r2).length_squared();
        1.0 / (r2.x * r2.y * r2.z * g2 * g2)
    }

    /// Local coordinates of Π(p) and the squared radii.
    fn local_surface_point(&self, p: DVec3) -> (DVec3, DVec3) {
        let q = self.to_local(p);
        let rho = (q / self.radii).length();
        let x = if rho > CENTRE_EPSILON && rho.is_finite() {
            q / rho
        } else {
            DVec3::new(self.radii.x, 0.0, 0.0)
        };
        (x, self.radii * self.radii)
    }

    /// Where the line `origin + t·direction` meets the surface: both parameters `t`, in
    /// increasing order (negative values lie behind `origin`; a tangent line gives two equal
    /// values); `None` when it misses, or when `direction` is zero.
    pub fn intersect_ray(&self, origin: DVec3, direction: DVec3) -> Option<[f64; 2]> {
        let o = self.to_unit_sphere(origin);
        let d = (self.rotation.inverse() * direction) / self.radii;
        let a = d.length_squared();
        if a <= 0.0 || !a.is_finite() {
            return None;
        }
        // |o + t d|² = 1  ⇔  a t² + 2 b t + c = 0.
        let b = o.dot(d);
        let c = o.length_squared() - 1.0;
        let disc = b * b - a * c;
        if disc < 0.0 || !disc.is_finite() {
            return None;
        }
        // The numerically stable pair of roots.
        let s = disc.sqrt();
        let q = if b >= 0.0 { -(b + s) } else { -(b - s) };
        let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
        Some(if t0 <= t1 { [t0, t1] } else { [t1, t0] })
    }

    /// The same ellipsoid as a [`EllipsoidSpec`] (the sign is dropped).
    pub fn to_spec(&self) -> EllipsoidSpec {
        EllipsoidSpec {
            center: self.center,
            rotation: self.rotation,
            radii: self.radii,
        }
    }

    /// A positive ellipsoid from a [`EllipsoidSpec`].
    pub fn from_spec(spec: &EllipsoidSpec) -> Ellipsoid {
        Ellipsoid {
            center: spec.center,
            rotation: spec.rotation.normalize(),
            radii: spec.radii,
            sign: Sign::Positive,
        }
    }
}

impl From<EllipsoidSpec> for Ellipsoid {
    fn from(spec: EllipsoidSpec) -> Ellipsoid {
        Ellipsoid::from_spec(&spec)
    }
}

impl From<Ellipsoid> for EllipsoidSpec {
    fn from(e: Ellipsoid) -> EllipsoidSpec {
        e.to_spec()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;
    use glam::DMat3;

    fn random_ellipsoid(rng: &mut SplitMix64) -> Ellipsoid {
        let axis = rng.unit_vector();
        Ellipsoid {
            center: DVec3::new(
                rng.range_f64(-3.0, 3.0),
                rng.range_f64(-3.0, 3.0),
                rng.range_f64(-3.0, 3.0),
            ),
            rotation: DQuat::from_axis_angle(axis, rng.range_f64(0.0, 6.0)),
            radii: DVec3::new(
                rng.range_f64(0.5, 3.0),
                rng.range_f64(0.5, 3.0),
                rng.range_f64(0.5, 3.0),
            ),
            sign: Sign::Positive,
        }
    }

    /// The quadric matrix A with (x − c)ᵀ A (x − c) = 1 on the surface, built from a rotation
    /// matrix rather than the quaternion code path.
    fn quadric(e: &Ellipsoid) -> DMat3 {
        let r = DMat3::from_quat(e.rotation);
        let d = DMat3::from_diagonal(DVec3::ONE / (e.radii * e.radii));
        r * d * r.transpose()
    }

    #[test]
    fn unit_sphere_maps_invert_and_land_on_the_quadric() {
        let mut rng = SplitMix64::new(1);
        for _ in 0..50 {
            let e = random_ellipsoid(&mut rng);
            let a = quadric(&e);
            for _ in 0..20 {
                let u = rng.unit_vector();
                let p = e.from_unit_sphere(u);
                let d = p - e.center;
                assert!((d.dot(a * d) - 1.0).abs() < 1e-12);
                assert!((e.to_unit_sphere(p) - u).length() < 1e-12);
                // Points inside and outside.
                let s = rng.range_f64(0.1, 3.0);
                let q = e.from_unit_sphere(u * s);
                assert_eq!(e.contains(q), s <= 1.0);
            }
        }
    }

    #[test]
    fn radial_projection_lands_on_the_surface_along_the_ray() {
        let mut rng = SplitMix64::new(2);
        for _ in 0..50 {
            let e = random_ellipsoid(&mut rng);
            let a = quadric(&e);
            for _ in 0..20 {
                let p = e.center + rng.unit_vector() * rng.range_f64(0.01, 10.0);
                let pi = e.project_radially(p);
                let d = pi - e.center;
                assert!((d.dot(a * d) - 1.0).abs() < 1e-12);
                // Collinear with the centre and p, same side.
                let dp = p - e.center;
                assert!(d.cross(dp).length() < 1e-12 * dp.length() * d.length().max(1.0));
                assert!(d.dot(dp) > 0.0);
                // Distance: |p − c| · |1 − 1/ρ| with ρ² = (p − c)ᵀ A (p − c).
                let rho = dp.dot(a * dp).sqrt();
                let expected = dp.length() * (1.0 - 1.0 / rho).abs();
                assert!((e.radial_distance(p) - expected).abs() < 1e-12 * (1.0 + expected));
            }
        }
        let e = Ellipsoid::sphere(DVec3::ONE, 2.0);
        assert!(e.project_radially(e.center).is_finite());
    }

    #[test]
    fn normals_match_the_quadric_gradient() {
        let mut rng = SplitMix64::new(3);
        for _ in 0..50 {
            let mut e = random_ellipsoid(&mut rng);
            let a = quadric(&e);
            for _ in 0..20 {
                let p = e.from_unit_sphere(rng.unit_vector());
                let grad = (a * (p - e.center)).normalize();
                assert!((e.outward_normal(p) - grad).length() < 1e-12);
                assert!((e.normal(p) - grad).length() < 1e-12);
                e.sign = Sign::Negative;
                assert!((e.normal(p) + grad).length() < 1e-12);
                e.sign = Sign::Positive;
            }
        }
    }

    /// The side test is the signed normal's dot product times the gradient's length, for
    /// both signs, also on needles (radii 1e-4 against 1e3) and for vectors nearly
    /// tangent to the surface.
    #[test]
    fn normal_side_is_the_normal_times_a_positive_factor() {
        let mut rng = SplitMix64::new(9);
        for round in 0..60 {
            let mut e = random_ellipsoid(&mut rng);
            if round % 3 == 0 {
                e.radii = DVec3::new(1e3, 1e-4, rng.range_f64(1e-4, 1.0));
            }
            if round % 2 == 0 {
                e.sign = Sign::Negative;
            }
            let side = e.normal_side();
            for _ in 0..50 {
                let p = e.from_unit_sphere(rng.unit_vector() * rng.range_f64(0.5, 2.0));
                let n = e.normal(p);
                let v = rng.unit_vector();
                let gradient = e.to_local(p) / (e.radii * e.radii);
                let expected = v.dot(n) * gradient.length();
                let got = side.along(p, v);
                // Both map p into the ellipsoid's frame, to within rounding of |p − c|,
                // which the weights 1 / r² magnify.
                let rounding = 1e-13 * (p - e.center).length() / e.radii.min_element().powi(2);
                assert!(
                    (got - expected).abs() <= 1e-9 * gradient.length() + rounding,
                    "{got} vs {expected}"
                );
                // Nearly tangent vectors keep their side.
                let t = (v - v.dot(n) * n).normalize();
                for lean in [1e-4, -1e-4] {
                    assert_eq!(side.along(p, t + lean * n) > 0.0, lean > 0.0);
                }
            }
        }
    }

    /// Mean and Gaussian curvature from the fundamental forms of the parametrisation
    /// (θ, φ) ↦ (a cos θ cos φ, b cos θ sin φ, c sin θ), by central differences.
    fn curvatures_by_fundamental_forms(e: &Ellipsoid, theta: f64, phi: f64) -> (f64, f64) {
        let x = |t: f64, f: f64| {
            e.from_unit_sphere(DVec3::new(t.cos() * f.cos(), t.cos() * f.sin(), t.sin()))
        };
        let h = 1e-4;
        let xu = (x(theta + h, phi) - x(theta - h, phi)) / (2.0 * h);
        let xv = (x(theta, phi + h) - x(theta, phi - h)) / (2.0 * h);
        let x0 = x(theta, phi);
        let xuu = (x(theta + h, phi) - 2.0 * x0 + x(theta - h, phi)) / (h * h);
        let xvv = (x(theta, phi + h) - 2.0 * x0 + x(theta, phi - h)) / (h * h);
        let xuv = (x(theta + h, phi + h) - x(theta + h, phi - h) - x(theta - h, phi + h)
            + x(theta - h, phi - h))
            / (4.0 * h * h);
        let mut n = xu.cross(xv).normalize();
        if n.dot(x0 - e.center) < 0.0 {
            n = -n;
        }
        let (ee, ff, gg) = (xu.dot(xu), xu.dot(xv), xv.dot(xv));
        let (l, m, nn) = (xuu.dot(n), xuv.dot(n), xvv.dot(n));
        let det = ee * gg - ff * ff;
        // With outward n, a sphere has L = −r: negate so that H = +1/r.
        let mean = -(ee * nn - 2.0 * ff * m + gg * l) / (2.0 * det);
        let gauss = (l * nn - m * m) / det;
        (mean, gauss)
    }

    #[test]
    fn curvature_closed_forms_match_fundamental_forms() {
        let mut rng = SplitMix64::new(4);
        for _ in 0..30 {
            let mut e = random_ellipsoid(&mut rng);
            for _ in 0..10 {
                let theta = rng.range_f64(-1.3, 1.3);
                let phi = rng.range_f64(0.0, std::f64::consts::TAU);
                let (h, k) = curvatures_by_fundamental_forms(&e, theta, phi);
                let p = e.from_unit_sphere(DVec3::new(
                    theta.cos() * phi.cos(),
                    theta.cos() * phi.sin(),
                    theta.sin(),
                ));
                // Off-surface query points use Π(p): scale along the ray.
                let q = e.center + (p - e.center) * rng.range_f64(0.5, 2.0);
                assert!(
                    (e.mean_curvature(q) - h).abs() < 1e-5 * h.abs().max(1.0),
                    "H"
                );
                assert!((e.gaussian_curvature(q) - k).abs() < 1e-5 * k.abs().max(1.0));
                e.sign = Sign::Negative;
                assert!((e.mean_curvature(q) + h).abs() < 1e-5 * h.abs().max(1.0));
                assert!((e.gaussian_curvature(q) - k).abs() < 1e-5 * k.abs().max(1.0));
                e.sign = Sign::Positive;
            }
        }
        let sphere = Ellipsoid::sphere(DVec3::ZERO, 2.0);
        assert!((sphere.mean_curvature(DVec3::new(0.0, 5.0, 0.0)) - 0.5).abs() < 1e-15);
        assert!((sphere.gaussian_curvature(DVec3::new(0.0, 5.0, 0.0)) - 0.25).abs() < 1e-15);
        assert!((sphere.flipped().mean_curvature(DVec3::X) + 0.5).abs() < 1e-15);
    }

    /// Sign changes of the implicit function along the line, by marching and bisection.
    fn march(e: &Ellipsoid, o: DVec3, d: DVec3, span: f64) -> Vec<f64> {
        let steps = 20_000;
        let f = |t: f64| e.implicit(o + d * t);
        let mut hits = Vec::new();
        let mut t_prev = -span;
        for i in 1..=steps {
            let t = -span + 2.0 * span * i as f64 / steps as f64;
            if (f(t_prev) > 0.0) != (f(t) > 0.0) {
                let (mut lo, mut hi) = (t_prev, t);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if (f(mid) > 0.0) == (f(lo) > 0.0) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                hits.push(0.5 * (lo + hi));
            }
            t_prev = t;
        }
        hits
    }

    #[test]
    fn ray_hits_match_brute_force_marching() {
        let mut rng = SplitMix64::new(5);
        let mut hits_seen = 0;
        for _ in 0..100 {
            let e = random_ellipsoid(&mut rng);
            let o = e.center + rng.unit_vector() * rng.range_f64(0.0, 6.0);
            let d = rng.unit_vector() * rng.range_f64(0.5, 2.0);
            let marched = march(&e, o, d, 20.0);
            match e.intersect_ray(o, d) {
                Some([t0, t1]) => {
                    assert!(t0 <= t1);
                    if marched.len() == 2 {
                        hits_seen += 1;
                        assert!((t0 - marched[0]).abs() < 1e-9, "{t0} vs {marched:?}");
                        assert!((t1 - marched[1]).abs() < 1e-9);
                    } else {
                        // Only a grazing line can hit between marching steps.
                        assert!((t1 - t0).abs() < 1e-2, "{t0} {t1} vs {marched:?}");
                    }
                    assert!(e.implicit(o + d * t0).abs() < 1e-9);
                    assert!(e.implicit(o + d * t1).abs() < 1e-9);
                }
                None => assert!(marched.is_empty(), "missed {marched:?}"),
            }
        }
        assert!(hits_seen > 30);
        let e = Ellipsoid::sphere(DVec3::ZERO, 1.0);
        assert_eq!(e.intersect_ray(DVec3::ZERO, DVec3::ZERO), None);
    }

    #[test]
    fn volume_and_spec_round_trip() {
        let e = Ellipsoid {
            center: DVec3::new(1.0, 2.0, 3.0),
            rotation: DQuat::from_rotation_y(0.3),
            radii: DVec3::new(1.0, 2.0, 3.0),
            sign: Sign::Positive,
        };
        assert!((e.volume() - 8.0 * std::f64::consts::PI).abs() < 1e-12);
        let spec = e.to_spec();
        let back = Ellipsoid::from(spec);
        assert_eq!(
            (back.center, back.radii, back.sign),
            (e.center, e.radii, e.sign)
        );
        assert!(back.rotation.abs_diff_eq(e.rotation, 1e-15));
        assert_eq!(EllipsoidSpec::from(e), spec);
        assert!(e.is_valid());
        assert!(!Ellipsoid::sphere(DVec3::ZERO, 0.0).is_valid());
    }

    #[test]
    fn closest_point_is_the_foot_of_the_normal_and_beats_brute_force() {
        let e = Ellipsoid {
            center: DVec3::new(0.5, -1.0, 2.0),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.2),
            radii: DVec3::new(3.0, 1.0, 0.4),
            sign: Sign::Positive,
        };
        let mut rng = crate::rng::SplitMix64::new(5);
        for i in 0..300 {
            let u = rng.unit_vector();
            let s = e.from_unit_sphere(u);
            // Points along the normal from 0.03 inside (less than the smallest radius of
            // curvature, 0.4²/3 ≈ 0.053, so the foot is unique) to 0.3 outside, and a few far
            // ones.
            let offset = if i % 10 == 0 {
                5.0
            } else {
                rng.range_f64(-0.03, 0.3)
            };
            let p = s + offset * e.outward_normal(s);
            let c = e.closest_point(p);
            assert!(e.implicit(c).abs() < 1e-9, "{i}: not on the surface");
            // The foot of the normal: p − c is parallel to the normal at c.
            let n = e.outward_normal(c);
            let d = p - c;
            assert!(
                d.cross(n).length() <= 1e-7 * (1.0 + d.length()),
                "{i}: not normal"
            );
            // No sampled surface point is closer.
            let best = d.length();
            for _ in 0..2000 {
                let v = e.from_unit_sphere(rng.unit_vector());
                assert!(
                    (p - v).length() >= best - 1e-9,
                    "{i}: a closer point exists"
                );
            }
            // Points near the surface keep their own foot.
            if (0.0..0.3).contains(&offset) {
                assert!((c - s).length() < 1e-7, "{i}: {c} vs {s}");
            }
        }
        // The centre (a medial point) falls back to Π and stays finite.
        assert!(e.closest_point(e.center).is_finite());
    }
}
