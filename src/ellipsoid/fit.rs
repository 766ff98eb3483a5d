//! Fitting one ellipsoid to one region (Simari & Singh 2005, section 4, "Ellipsoid fitting").
//!
//! The paper minimises E(R, P) over the nine parameters once per sign, starting from the
//! region's centroid and principal axes, and keeps the sign with the lower error. ellip does
//! the same, made robust for the thousands of awkward regions a segmentation produces:
//!
//! - **Canonical units.** Samples are moved to their weighted centroid and divided by the
//!   mesh scale D (the box diagonal, [`FitOptions::scale`]); curvatures are multiplied by D
//!   and the weights converted so that the objective is unchanged. Every tolerance and cap
//!   below is in these units.
//! - **Parametrisation.** Centre c, radii r = exp(ℓ) (log-parametrised, so always positive),
//!   rotation R updated multiplicatively by small axis-angle steps R ← R·exp(\[ω\]×); centre
//!   steps are taken in the ellipsoid's own frame (c ← c + R·δc).
//! - **Residuals.** Per sample with weight w: √(wα)·d (signed radial distance),
//!   √(wβ)·(ν − s·m) (normal in the ellipsoid's frame, 3 components), √(wγ)·(H − s·H_P);
//!   optionally √δ·(V(R) − 4/3·πabc) once. Jacobians are analytic (derived in the local
//!   frame and chained to c, ℓ, ω), checked against finite differences in the tests.
//! - **Solver.** Levenberg–Marquardt on the 9×9 normal equations with Marquardt's diagonal
//!   scaling (plus a floor, so flat directions stay solvable), Cholesky solves, no allocation
//!   per iteration.
//! - **Starts.** For each sign: the warm start if given; the paper's principal axes (radii
//!   √3·σ along the covariance eigenvectors, floored at 5% of the largest so patches are not
//!   degenerate); the oriented-point sphere (least squares p ≈ c + s·ρ·n, linear in c, ρ — it
//!   sees which side of the patch is outside); the algebraic point sphere (|p|² = 2c·p + k,
//!   Kåsa 1976); and the algebraic quadric through the oriented points (in the spirit of Li &
//!   Griffiths 2004: f(p) = 0 and ∇f(p) × n = 0, linear in the ten coefficients; kept only
//!   when it is an ellipsoid). Each start gets [`FitOptions::probe_iterations`] iterations on
//!   at most [`FitOptions::probe_points`] samples; the cheapest then continues to
//!   convergence on all the solver's samples. Measured on exact 10–30% caps
//!   (`tests/fit.rs`, `better_starts_help_on_partial_caps`): the probe can be misled by
//!   the sphere starts into a wrong basin (3 of 36 caps), the quadric start, exact on exact
//!   data, removes every miss.
//! - **Caps.** Radii are kept in [10⁻⁶, 10³] canonical units, i.e. between 10⁻⁶ and 10³ box
//!   diagonals ([`FitOptions::max_radius`], [`FitOptions::min_radius`]); a flat patch ends at
//!   the upper cap, which at 10³ diagonals deviates from a plane by at most D²/(8·10³·D)
//!   = 1.25·10⁻⁴·D across a whole-model patch. The centre stays within 4× the cap of the
//!   region.
//! - **Specks and facets.** A piece of the mesh with fewer vertices than the nine
//!   parameters (a scan's fins and loose triangles), or a flat region that few between
//!   creases (a cube's triangle), leaves an ellipsoid free between its samples; the
//!   segmentation fits it with a sphere or a plane-like spheroid tangent to it instead
//!   ([`fit_tangent_sphere`]); the encoder's mending does so for any other region this
//!   small that its check blames and whose ellipsoid is turned against one of its faces
//!   ([`crate::segment::EllipsoidMetric::tangent_in_place_of_needle`]).
//! - **Small solids.** A closed piece with that few vertices, one region whole, is decoded
//!   as its whole ellipsoid: the segmentation gives it the ellipsoid of its solid, with the
//!   solid's principal axes, proportions and volume ([`fit_solid`]).
//! - **Large regions.** The iterations use at most [`FitOptions::max_solver_points`] samples,
//!   picked with a fixed stride and reweighted so the total weight is unchanged; the
//!   returned error is then evaluated on every sample at full resolution.
//! - **Never NaN.** Non-finite samples or weights are ignored, every candidate is checked,
//!   and an input without usable samples yields a finite sphere (a tenth of the scale, at
//!   the centroid of the finite points) with its finite error.
//!
//! Deterministic: no randomness, no threads, a fixed order of operations — the same input
//! gives bit-identical output.

#![allow(clippy::needless_range_loop)] // Small fixed-size linear algebra reads best indexed.

use super::metric::{measure_vertex_terms, RegionSamples, VolumeTerm, Weights};
use super::{Ellipsoid, Sign};
use glam::{DMat3, DQuat, DVec3};

/// Why a [`FitInput`] cannot be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// A per-sample array does not have one entry per point.
    #[error("{what} has {actual} entries, expected one per point ({expected})")]
    LengthMismatch {
        /// Which array.
        what: &'static str,
        /// Number of points.
        expected: usize,
        /// Its length.
        actual: usize,
    },
}

/// The samples of one region: positions, unit normals, mean curvatures (outward-positive
/// convention), optional per-sample weights (e.g. from
/// [`gather_region`](super::metric::gather_region)), and an optional warm start.
#[derive(Debug, Clone, Copy)]
pub struct FitInput<'a> {
    points: &'a [DVec3],
    normals: &'a [DVec3],
    curvatures: &'a [f64],
    weights: Option<&'a [f64]>,
    start: Option<Ellipsoid>,
}

impl<'a> FitInput<'a> {
    /// Samples with unit weights; the arrays must have equal lengths.
    pub fn new(
        points: &'a [DVec3],
        normals: &'a [DVec3],
        curvatures: &'a [f64],
    ) -> Result<FitInput<'a>, FitError> {
        let expected = points.len();
        for (what, actual) in [("normals", normals.len()), ("curvatures", curvatures.len())] {
            if actual != expected {
                return Err(FitError::LengthMismatch {
                    what,
                    expected,
                    actual,
                });
            }
        }
        Ok(FitInput {
            points,
            normals,
            curvatures,
            weights: None,
            start: None,
        })
    }

    /// A region's gathered samples ([`crate::ellipsoid::metric::gather_region`]), weighted.
    /// The arrays come from one gather and have equal lengths; should the weights' ever
    /// differ, the unweighted samples are still a sound (if slightly different) input.
    /// Errors as [`FitInput::new`].
    pub fn of_samples(samples: &'a RegionSamples) -> Result<FitInput<'a>, FitError> {
        let input = FitInput::new(&samples.points, &samples.normals, &samples.curvatures)?;
        Ok(input.with_weights(&samples.weights).unwrap_or(input))
    }

    /// Per-sample weights (non-finite or negative ones count as 0).
    pub fn with_weights(self, weights: &'a [f64]) -> Result<FitInput<'a>, FitError> {
        if weights.len() != self.points.len() {
            return Err(FitError::LengthMismatch {
                what: "weights",
                expected: self.points.len(),
                actual: weights.len(),
            });
        }
        Ok(FitInput {
            weights: Some(weights),
            ..self
        })
    }

    /// Start from a previous fit (the segmentation's previous iteration); ignored if invalid.
    pub fn with_start(self, start: Ellipsoid) -> FitInput<'a> {
        FitInput {
            start: start.is_valid().then_some(start),
            ..self
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Sample `i` as (weight, point, normal, curvature) when it counts: a positive weight and
    /// finite values. The one rule for which samples the fit and its error use.
    fn usable_sample(&self, i: usize) -> Option<(f64, DVec3, DVec3, f64)> {
        let w = self.weight(i);
        let (&p, &n, &h) = (
            self.points.get(i)?,
            self.normals.get(i)?,
            self.curvatures.get(i)?,
        );
        (w > 0.0 && p.is_finite() && n.is_finite() && h.is_finite()).then_some((w, p, n, h))
    }

    fn weight(&self, i: usize) -> f64 {
        match self.weights {
            None => 1.0,
            Some(w) => w
                .get(i)
                .copied()
                .filter(|w| w.is_finite() && *w > 0.0)
                .unwrap_or(0.0),
        }
    }
}

/// Which signs to try (section 4: both, keeping the lower error).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignChoice {
    /// Fit both and keep the lower error (ties go to positive).
    Both,
    /// Fit only this sign.
    Only(Sign),
}

impl SignChoice {
    /// The signs to fit, positive first.
    fn signs(self) -> &'static [Sign] {
        match self {
            SignChoice::Both => &[Sign::Positive, Sign::Negative],
            SignChoice::Only(Sign::Positive) => &[Sign::Positive],
            SignChoice::Only(Sign::Negative) => &[Sign::Negative],
        }
    }
}

/// Which fresh starts to try; all by default. Exposed so that tests and benchmarks can
/// measure what each contributes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Starts {
    /// The paper's centroid and principal axes.
    pub principal_axes: bool,
    /// The sphere through oriented points, p ≈ c + s·ρ·n.
    pub oriented_sphere: bool,
    /// The algebraic sphere through the points alone.
    pub algebraic_sphere: bool,
    /// The algebraic quadric through the oriented points, when it is an ellipsoid.
    pub quadric: bool,
}

impl Default for Starts {
    fn default() -> Starts {
        Starts {
            principal_axes: true,
            oriented_sphere: true,
            algebraic_sphere: true,
            quadric: true,
        }
    }
}

/// Everything the fit needs besides the samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Weights α, β, γ in the model's units (e.g. [`Weights::paper`]).
    pub weights: Weights,
    /// The volume term of the volume metric (section 3), if fitting volume.
    pub volume: Option<VolumeTerm>,
    /// The canonical unit of length D (the model's box diagonal, [`super::MeshScale`]).
    pub scale: f64,
    /// Signs to try.
    pub signs: SignChoice,
    /// Fresh starts to try.
    pub starts: Starts,
    /// With a warm start, also try every fresh start (and keep the best). `false` is the
    /// segmentation's fast path: the warm start alone for its own sign, and for the other
    /// sign only the oriented-point sphere — with both signs asked for, that sign is not
    /// fitted at all when the patch does not bend its way (the sphere's radius comes out
    /// non-positive).
    pub fresh_starts_with_warm: bool,
    /// Largest radius, in units of `scale` (default 10³).
    pub max_radius: f64,
    /// Smallest radius, in units of `scale` (default 10⁻⁶).
    pub min_radius: f64,
    /// Most samples the iterations use (default 2048); more are subsampled by stride.
    pub max_solver_points: usize,
    /// Iterations from each start before the best one continues (default 6).
    pub probe_iterations: u32,
    /// Most samples the probe iterations use (default 256), picked by stride from the
    /// solver's samples.
    pub probe_points: usize,
    /// Most iterations in all for the best start (default 100).
    pub max_iterations: u32,
}

impl FitOptions {
    /// [`FitOptions::scale`] when it is a positive finite length, else 1.
    fn unit(&self) -> f64 {
        if self.scale.is_finite() && self.scale > 0.0 {
            self.scale
        } else {
            1.0
        }
    }

    /// Surface fitting with the paper's default weights (section 2) for a model of the given
    /// scale.
    pub fn surface(scale: &super::MeshScale) -> FitOptions {
        FitOptions {
            weights: Weights::paper(scale),
            volume: None,
            scale: scale.diagonal,
            signs: SignChoice::Both,
            starts: Starts::default(),
            fresh_starts_with_warm: true,
            max_radius: 1e3,
            min_radius: 1e-6,
            max_solver_points: 2048,
            probe_iterations: 6,
            probe_points: 256,
            max_iterations: 100,
        }
    }

    /// Volume fitting (section 3): α·E_euc + δ·(V(R) − 4/3·πabc)², positive sign only, with
    /// the paper's δ = 10⁵/V² and `hull_volume` = V(R).
    pub fn volume(scale: &super::MeshScale, hull_volume: f64) -> FitOptions {
        FitOptions {
            weights: Weights::euclidean(scale),
            volume: Some(VolumeTerm::paper(scale, hull_volume)),
            signs: SignChoice::Only(Sign::Positive),
            ..FitOptions::surface(scale)
        }
    }
}

/// A fitted ellipsoid and its error on the whole input (the objective: Σ w·E(v, P), plus the
/// volume term when fitting volume), in the model's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fit {
    /// The ellipsoid.
    pub ellipsoid: Ellipsoid,
    /// Its error.
    pub error: f64,
}

/// Fit one ellipsoid to one region's samples: the minimiser of E(R, P) over both signs
/// (section 4), robustly; see the module documentation. Never returns non-finite values.
pub fn fit_ellipsoid(input: &FitInput<'_>, options: &FitOptions) -> Fit {
    let Some(problem) = Canonical::new(input, options) else {
        return degenerate_fit(input, options);
    };
    let signs = options.signs.signs();
    let mut best: Option<Fit> = None;
    for &sign in signs {
        let Some(params) = problem.solve(sign) else {
            continue;
        };
        let ellipsoid = problem.to_world(&params, sign);
        let error = evaluate_error(input, options, &ellipsoid);
        if best.is_none_or(|b| error < b.error) {
            best = Some(Fit { ellipsoid, error });
        }
    }
    best.unwrap_or_else(|| degenerate_fit(input, options))
}

/// Fewer samples than the nine parameters: too few for an ellipsoid
/// ([`fit_tangent_sphere`]).
pub const MIN_ELLIPSOID_SAMPLES: usize = 9;

/// For an input with fewer usable samples than [`MIN_ELLIPSOID_SAMPLES`]: the sphere
/// tangent to the samples' plane (least squares) at their weighted centroid, on the side
/// their normals face, whose radius gives the lowest objective among the samples' spread
/// times 2^k up to [`FitOptions::max_radius`] and the cap itself, or the caps' limit, a
/// plane: the spheroid as wide as the cap and one unit (the scale) thick, tangent there,
/// whose top is flat to within spread²·unit/(2·cap²) where the widest sphere bulges by
/// spread²/(2·cap). For the signs [`FitOptions::signs`] allows. `None` for other inputs, or
/// when the normals cancel.
///
/// For the specks of a scan, pieces of one or two triangles (see
/// [`crate::segment::proxy::speck_faces`]), the facets of a low-poly part (a cube's
/// triangle), and any other region this small whose ellipsoid turned against one of its
/// faces made the decoder's check blame it
/// ([`crate::segment::EllipsoidMetric::tangent_in_place_of_needle`]): so few samples leave an
/// ellipsoid free between them. Matched to a single
/// triangle's corners and normals, [`fit_ellipsoid`] returns needles a hundredth of the
/// diagonal thick with the triangle inside, whose normal at the triangle's centre points
/// anywhere; a tangent sphere's normal there is the patch's own. A facet's corners lie on
/// the plane-like spheroid to rounding (within 10⁻⁹ of the cap, so boundary smoothing
/// leaves a cube's corners where they are: [`crate::boundary::smooth_boundaries`]).
pub fn fit_tangent_sphere(input: &FitInput<'_>, options: &FitOptions) -> Option<Fit> {
    let samples: Vec<(f64, DVec3, DVec3)> = (0..input.len())
        .filter_map(|i| input.usable_sample(i).map(|(w, p, n, _)| (w, p, n)))
        .take(MIN_ELLIPSOID_SAMPLES)
        .collect();
    if samples.is_empty() || samples.len() >= MIN_ELLIPSOID_SAMPLES {
        return None;
    }
    let total: f64 = samples.iter().map(|s| s.0).sum();
    let centroid = samples.iter().map(|s| s.0 * s.1).sum::<DVec3>() / total;
    let mean_normal = samples
        .iter()
        .map(|s| s.0 * s.2)
        .sum::<DVec3>()
        .try_normalize()?;
    // The samples' plane (through three or more points not on a line), facing the way
    // their normals do; else their mean normal.
    let cov = scatter(samples.iter().map(|&(w, p, _)| (w, p)), centroid);
    let (values, axes) = eigen_symmetric(cov);
    let normal = if values[1] > 1e-6 * values[0] && values[0] > 0.0 {
        let n = axes.z_axis;
        if n.dot(mean_normal) < 0.0 {
            -n
        } else {
            n
        }
    } else {
        mean_normal
    };
    let scale = options.unit();
    let (min_radius, max_radius) = (options.min_radius * scale, options.max_radius * scale);
    let spread = samples
        .iter()
        .map(|s| s.1.distance(centroid))
        .fold(0.0, f64::max)
        .max(min_radius);
    if !(centroid.is_finite() && spread.is_finite() && spread < max_radius) {
        return None;
    }
    let signs = options.signs.signs();
    let mut radii = Vec::new();
    let mut r = spread;
    while r < max_radius {
        radii.push(r);
        r *= 2.0;
    }
    radii.push(max_radius);
    let mut best: Option<Fit> = None;
    for &sign in signs {
        for &radius in &radii {
            // A negative ellipsoid's surface faces its centre.
            let ellipsoid = Ellipsoid {
                sign,
                ..Ellipsoid::sphere(centroid - sign.factor() * radius * normal, radius)
            };
            let error = evaluate_error(input, options, &ellipsoid);
            if best.is_none_or(|b| error < b.error) {
                best = Some(Fit { ellipsoid, error });
            }
        }
        // The caps' limit, a plane: the spheroid as wide as the cap allows and one unit
        // thick, tangent at the centroid (see the function's documentation).
        let ellipsoid = Ellipsoid {
            center: centroid - sign.factor() * scale * normal,
            rotation: DQuat::from_rotation_arc(DVec3::Z, normal),
            radii: DVec3::new(max_radius, max_radius, scale),
            sign,
        };
        let error = evaluate_error(input, options, &ellipsoid);
        if best.is_none_or(|b| error < b.error) {
            best = Some(Fit { ellipsoid, error });
        }
    }
    best
}

/// The ellipsoid of a closed piece of a mesh, its triangles' corners given: the one with the
/// solid's centroid, principal axes and proportions (radii proportional to the square roots
/// of the second moments of its volume, as a solid ellipsoid's are: a²/5 along each axis)
/// and the solid's volume. Positive for a piece whose triangles face outward (positive
/// signed volume), negative for one that faces inward (a void). `None` when the volume is
/// not finite or too small for its extent to give three radii (a flat piece).
///
/// A piece may miss a few faces that lie on other pieces (across non-manifold edges, where
/// import cuts pieces apart): its border ([`open_edges`]) is closed by a fan from the
/// border's centroid, as the piece's solid, unless that fan's area is more than
/// [`MAX_CLOSING_SHARE`] of the piece's own (`None`: a single triangle or two, a
/// tetrahedron's three sides, are no solid's surface).
///
/// For the small closed pieces of a CAD assembly (boxes, pegs, wedges of eight vertices or
/// fewer), which a segmentation leaves one region each: a region with no boundary is decoded
/// as its whole ellipsoid, and the vertex samples alone, fewer than the nine parameters, let
/// [`fit_ellipsoid`] end anywhere (a plate of 60 × 5 × 145 of assimp's `regr01` was
/// decoded as a ball as wide as the plate's diagonal). The solid's ellipsoid sees the faces
/// between the vertices: a box of half-extents a, b, c gets radii 1.24·a, 1.24·b, 1.24·c.
pub fn fit_solid(triangles: &[[DVec3; 3]]) -> Option<Ellipsoid> {
    let open = open_edges(triangles);
    let origin = if open.is_empty() {
        triangles.iter().flatten().sum::<DVec3>() / (3 * triangles.len()).max(1) as f64
    } else {
        // The closing fan's apex. Measured from it, the fan's tetrahedra are flat: they add
        // nothing to the volume and its moments, which are the closed solid's.
        let apex = open.iter().flatten().sum::<DVec3>() / (2 * open.len()) as f64;
        let area = |[a, b, c]: [DVec3; 3]| (b - a).cross(c - a).length() / 2.0;
        let closing: f64 = open.iter().map(|&[u, v]| area([apex, u, v])).sum();
        let own: f64 = triangles.iter().map(|&t| area(t)).sum();
        // Also false for a non-finite area.
        let small = closing <= MAX_CLOSING_SHARE * own;
        if !small {
            return None;
        }
        apex
    };
    // Tetrahedra from the origin to each triangle: signed volume, first and second moments
    // (∫x xᵀ over a tetrahedron with corners 0, a, b, c is v/20·(Σ aaᵀ + (Σa)(Σa)ᵀ)).
    let (mut volume, mut first) = (0.0, DVec3::ZERO);
    let mut second = [[0.0; 3]; 3];
    for t in triangles {
        let [a, b, c] = t.map(|p| p - origin);
        let v = a.dot(b.cross(c)) / 6.0;
        let sum = a + b + c;
        volume += v;
        first += v / 4.0 * sum;
        for (i, row) in second.iter_mut().enumerate() {
            for (j, m) in row.iter_mut().enumerate() {
                *m += v / 20.0 * (a[i] * a[j] + b[i] * b[j] + c[i] * c[j] + sum[i] * sum[j]);
            }
        }
    }
    let extent = triangles
        .iter()
        .flatten()
        .map(|p| p.distance(origin))
        .fold(0.0, f64::max);
    if !(volume.is_finite() && volume.abs() > 1e-9 * extent.powi(3)) {
        return None;
    }
    let centroid = first / volume;
    let mut covariance = second;
    for (i, row) in covariance.iter_mut().enumerate() {
        for (j, m) in row.iter_mut().enumerate() {
            *m = *m / volume - centroid[i] * centroid[j];
        }
    }
    let (variances, axes) = eigen_symmetric(covariance);
    if variances[2].is_nan() || variances[2] <= 0.0 {
        return None;
    }
    let shape = DVec3::from(variances.map(|v| (5.0 * v).sqrt()));
    let shape_volume = 4.0 / 3.0 * std::f64::consts::PI * shape.x * shape.y * shape.z;
    let radii = shape * (volume.abs() / shape_volume).cbrt();
    let ellipsoid = Ellipsoid {
        center: origin + centroid,
        rotation: DQuat::from_mat3(&axes).normalize(),
        radii,
        sign: if volume > 0.0 {
            Sign::Positive
        } else {
            Sign::Negative
        },
    };
    ellipsoid.is_valid().then_some(ellipsoid)
}

/// Largest area of the fan that closes a piece's border for [`fit_solid`], as a share of
/// the piece's own area. npm's head scan has 26 pieces of eight triangles less one whose
/// edges lie on other pieces (a share of 1/7); a tetrahedron's three sides (1/3), two
/// triangles on four points and single triangles (about 1), which Stanford's dragon has
/// at `res3` and `res4`, are not solids: fitted as such (their volume measured from their
/// vertices' centroid), two were among the regions the decoder could not mesh cleanly in
/// the dragon at `res4` at 290 regions, where the encoder then found no clean file in 24
/// rounds and took five times as long.
pub const MAX_CLOSING_SHARE: f64 = 0.25;

/// The edges of `triangles` that no other runs the other way (a closed surface has none),
/// as they are run, in a deterministic order: an edge run twice one way and once the other
/// is there once. Corners are matched by position.
pub fn open_edges(triangles: &[[DVec3; 3]]) -> Vec<[DVec3; 2]> {
    let key = |p: DVec3| p.to_array().map(f64::to_bits);
    // Each edge once, its ends in key order, +1 when run that way and −1 the other.
    let mut edges: Vec<([[u64; 3]; 2], i64, [DVec3; 2])> = triangles
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[u, v]| {
            if key(u) <= key(v) {
                ([key(u), key(v)], 1, [u, v])
            } else {
                ([key(v), key(u)], -1, [v, u])
            }
        })
        .collect();
    edges.sort_unstable_by_key(|e| e.0);
    let mut open = Vec::new();
    for run in edges.chunk_by(|a, b| a.0 == b.0) {
        let count: i64 = run.iter().map(|e| e.1).sum();
        let [u, v] = run[0].2;
        let edge = if count > 0 { [u, v] } else { [v, u] };
        open.extend(std::iter::repeat_n(edge, count.unsigned_abs() as usize));
    }
    open
}

/// The objective at full resolution, in world units; capped to a finite value.
pub fn evaluate_error(input: &FitInput<'_>, options: &FitOptions, e: &Ellipsoid) -> f64 {
    let mut sum = 0.0;
    for i in 0..input.len() {
        let Some((w, p, n, h)) = input.usable_sample(i) else {
            continue;
        };
        let t = measure_vertex_terms(e, p, n, h);
        sum += w * t.weighted(&options.weights);
    }
    if let Some(v) = &options.volume {
        sum += v.error(e);
    }
    if sum.is_finite() {
        sum
    } else {
        f64::MAX
    }
}

/// The answer for inputs without usable samples: the warm start, else a sphere of a tenth of
/// the scale at their centroid (or the origin), with its (finite) error.
fn degenerate_fit(input: &FitInput<'_>, options: &FitOptions) -> Fit {
    let finite: Vec<DVec3> = input
        .points
        .iter()
        .copied()
        .filter(|p| p.is_finite())
        .collect();
    let center = if finite.is_empty() {
        DVec3::ZERO
    } else {
        finite.iter().sum::<DVec3>() / finite.len() as f64
    };
    let scale = options.unit();
    let mut ellipsoid = input
        .start
        .unwrap_or_else(|| Ellipsoid::sphere(center, 0.1 * scale));
    if let SignChoice::Only(sign) = options.signs {
        ellipsoid.sign = sign;
    }
    Fit {
        ellipsoid,
        error: evaluate_error(input, options, &ellipsoid),
    }
}

/// One sample in canonical units, with its weight.
#[derive(Debug, Clone, Copy)]
struct Sample {
    p: DVec3,
    n: DVec3,
    h: f64,
    w: f64,
}

/// The nine parameters in canonical units (log radii).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Params {
    c: DVec3,
    rot: DQuat,
    l: DVec3,
}

/// The problem in canonical units.
struct Canonical {
    origin: DVec3,
    scale: f64,
    samples: Vec<Sample>,
    /// A stride subset of `samples` for the probe iterations from every start.
    probe_samples: Vec<Sample>,
    alpha: f64,
    beta: f64,
    gamma: f64,
    volume: Option<(f64, f64)>, // (√δ, V(R)) in canonical units
    start: Option<Params>,
    start_sign: Option<Sign>,
    options: FitOptions,
    l_min: f64,
    l_max: f64,
    c_max: f64,
}

type Mat9 = [[f64; 9]; 9];

impl Canonical {
    fn new(input: &FitInput<'_>, options: &FitOptions) -> Option<Canonical> {
        let mut valid = Vec::with_capacity(input.len());
        let mut total_w = 0.0;
        let mut centroid = DVec3::ZERO;
        for i in 0..input.len() {
            if let Some((w, p, _, _)) = input.usable_sample(i) {
                valid.push(i);
                total_w += w;
                centroid += w * p;
            }
        }
        if valid.is_empty() || !total_w.is_finite() || total_w <= 0.0 {
            return None;
        }
        let origin = centroid / total_w;
        if !origin.is_finite() {
            return None;
        }
        let scale = if options.scale.is_finite() && options.scale > 0.0 {
            options.scale
        } else {
            let (lo, hi) = valid.iter().fold(
                (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
                |(lo, hi), &i| (lo.min(input.points[i]), hi.max(input.points[i])),
            );
            let d = (hi - lo).length();
            if d.is_finite() && d > 0.0 {
                d
            } else {
                1.0
            }
        };
        // Deterministic stride subsample, reweighted to keep the total weight.
        let m = options.max_solver_points.max(16);
        let chosen: Vec<usize> = if valid.len() > m {
            (0..m)
                .filter_map(|k| valid.get(k * valid.len() / m).copied())
                .collect()
        } else {
            valid
        };
        let chosen_w: f64 = chosen.iter().map(|&i| input.weight(i)).sum();
        let reweight = total_w / chosen_w;
        let samples: Vec<Sample> = chosen
            .iter()
            .map(|&i| Sample {
                p: (input.points[i] - origin) / scale,
                n: input.normals[i],
                h: input.curvatures[i] * scale,
                w: input.weight(i) * reweight,
            })
            .collect();
        let w = &options.weights;
        let good = |x: f64| if x.is_finite() && x > 0.0 { x } else { 0.0 };
        let alpha = good(w.alpha * scale * scale);
        let beta = good(w.beta);
        let gamma = good(w.gamma / (scale * scale));
        let volume = options.volume.and_then(|v| {
            let s3 = scale * scale * scale;
            let sqrt_delta = (v.delta * s3 * s3).sqrt();
            let hull = v.hull_volume / s3;
            (sqrt_delta.is_finite() && hull.is_finite() && sqrt_delta > 0.0)
                .then_some((sqrt_delta, hull))
        });
        let max_r = if options.max_radius.is_finite() && options.max_radius > 0.0 {
            options.max_radius
        } else {
            1e3
        };
        let min_r = if options.min_radius.is_finite() && options.min_radius > 0.0 {
            options.min_radius.min(max_r)
        } else {
            1e-6
        };
        let probe_samples = stride_subsample(&samples, options.probe_points.max(16));
        let mut problem = Canonical {
            origin,
            scale,
            samples,
            probe_samples,
            alpha,
            beta,
            gamma,
            volume,
            start: None,
            start_sign: input.start.map(|e| e.sign),
            options: *options,
            l_min: min_r.ln(),
            l_max: max_r.ln(),
            c_max: 4.0 * max_r,
        };
        problem.start = input.start.map(|e| {
            problem.clamp(Params {
                c: (e.center - origin) / scale,
                rot: e.rotation.normalize(),
                l: (e.radii / scale).map(f64::ln),
            })
        });
        Some(problem)
    }

    fn to_world(&self, x: &Params, sign: Sign) -> Ellipsoid {
        Ellipsoid {
            center: self.origin + self.scale * x.c,
            rotation: x.rot,
            radii: self.scale * x.l.map(f64::exp),
            sign,
        }
    }

    fn clamp(&self, x: Params) -> Params {
        let fix = |v: f64, lo: f64, hi: f64| if v.is_finite() { v.clamp(lo, hi) } else { lo };
        let c = if x.c.is_finite() {
            x.c.clamp_length_max(self.c_max)
        } else {
            DVec3::ZERO
        };
        let rot = if x.rot.is_finite() && x.rot.length_squared() > 0.0 {
            x.rot.normalize()
        } else {
            DQuat::IDENTITY
        };
        Params {
            c,
            rot,
            l: DVec3::new(
                fix(x.l.x, self.l_min, self.l_max),
                fix(x.l.y, self.l_min, self.l_max),
                fix(x.l.z, self.l_min, self.l_max),
            ),
        }
    }

    /// Minimise for one sign from every start; the best start continues to convergence.
    fn solve(&self, sign: Sign) -> Option<Params> {
        let s = sign.factor();
        let mut starts: [Option<Params>; 5] = [None; 5];
        starts[0] = self.start;
        match self.start {
            // The fast path: the warm start alone for its own sign; for the other sign the
            // oriented sphere, which only exists when the patch bends that way — when it
            // does not, that sign is skipped.
            Some(warm) if !self.options.fresh_starts_with_warm => {
                if self.start_sign != Some(sign) {
                    match self.oriented_sphere(s, warm.rot) {
                        Some(sphere) => {
                            starts[0] = None;
                            starts[2] = Some(sphere);
                        }
                        None if self.options.signs == SignChoice::Both => return None,
                        // Asked for this sign alone: from the warm geometry.
                        None => {}
                    }
                }
            }
            _ => {
                let st = self.options.starts;
                let axes = self.principal_axes();
                if st.principal_axes {
                    starts[1] = Some(axes);
                }
                if st.oriented_sphere {
                    starts[2] = self.oriented_sphere(s, axes.rot);
                }
                if st.algebraic_sphere {
                    starts[3] = self.algebraic_sphere(axes.rot);
                }
                if st.quadric {
                    starts[4] = self.quadric();
                }
                if starts.iter().all(Option::is_none) {
                    starts[1] = Some(axes);
                }
            }
        }
        let mut best: Option<(Params, f64, f64, bool)> = None;
        for x in starts.into_iter().flatten() {
            let x = self.clamp(x);
            let (x, cost, lambda, done, _) = self.levenberg_marquardt(
                &self.probe_samples,
                x,
                s,
                1e-3,
                self.options.probe_iterations,
            );
            if best.is_none_or(|b| cost < b.1) {
                best = Some((x, cost, lambda, done));
            }
        }
        let (x, _, lambda, done) = best?;
        // Converged on the probe samples is converged only if they are all the samples.
        if done && self.probe_samples.len() == self.samples.len() {
            return Some(x);
        }
        let rest = self
            .options
            .max_iterations
            .saturating_sub(self.options.probe_iterations);
        Some(
            self.levenberg_marquardt(&self.samples, x, s, lambda, rest)
                .0,
        )
    }

    /// The weighted centroid (the canonical origin) and principal axes (section 4), radii
    /// √3·σ (exact for the uniform sphere), floored at 5% of the largest.
    fn principal_axes(&self) -> Params {
        let mut total = 0.0;
        let mut mean = DVec3::ZERO;
        for s in &self.samples {
            mean += s.w * s.p;
            total += s.w;
        }
        mean /= total;
        let mut cov = scatter(self.samples.iter().map(|s| (s.w, s.p)), mean);
        for row in cov.iter_mut() {
            for v in row.iter_mut() {
                *v /= total;
            }
        }
        let (values, axes) = eigen_symmetric(cov);
        let largest = (3.0 * values[0].max(0.0)).sqrt().max(1e-3);
        let radii = values.map(|v| (3.0 * v.max(0.0)).sqrt().max(0.05 * largest));
        Params {
            c: mean,
            rot: DQuat::from_mat3(&axes),
            l: DVec3::from_array(radii).map(f64::ln),
        }
    }

    /// The sphere through the oriented points: least squares p ≈ c + s·ρ·n (linear in c, ρ).
    /// `None` when ρ comes out non-positive (the patch bends the other way for this sign).
    fn oriented_sphere(&self, s: f64, rot: DQuat) -> Option<Params> {
        let mut a = [[0.0; 4]; 4];
        let mut b = [0.0; 4];
        for smp in &self.samples {
            let w = smp.w;
            let n = s * smp.n;
            let rows = [
                [1.0, 0.0, 0.0, n.x],
                [0.0, 1.0, 0.0, n.y],
                [0.0, 0.0, 1.0, n.z],
            ];
            for (k, row) in rows.iter().enumerate() {
                let y = smp.p[k];
                for i in 0..4 {
                    b[i] += w * row[i] * y;
                    for j in 0..4 {
                        a[i][j] += w * row[i] * row[j];
                    }
                }
            }
        }
        let x = solve_spd(a, b)?;
        let rho = x[3];
        let max_r = self.l_max.exp();
        if !(rho.is_finite() && rho > 0.0) {
            return None;
        }
        let rho = rho.min(max_r);
        // Re-centre consistently with the (possibly capped) radius: c = mean(p − s·ρ·n).
        let mut c = DVec3::ZERO;
        let mut total = 0.0;
        for smp in &self.samples {
            c += smp.w * (smp.p - s * rho * smp.n);
            total += smp.w;
        }
        Some(Params {
            c: c / total,
            rot,
            l: DVec3::splat(rho.ln()),
        })
    }

    /// The algebraic sphere |p|² = 2c·p + k through the points (Kåsa), radius √(k + |c|²).
    fn algebraic_sphere(&self, rot: DQuat) -> Option<Params> {
        let mut a = [[0.0; 4]; 4];
        let mut b = [0.0; 4];
        for smp in &self.samples {
            let row = [2.0 * smp.p.x, 2.0 * smp.p.y, 2.0 * smp.p.z, 1.0];
            let y = smp.p.length_squared();
            for i in 0..4 {
                b[i] += smp.w * row[i] * y;
                for j in 0..4 {
                    a[i][j] += smp.w * row[i] * row[j];
                }
            }
        }
        let x = solve_spd(a, b)?;
        let c = DVec3::new(x[0], x[1], x[2]);
        let r2 = x[3] + c.length_squared();
        (r2.is_finite() && r2 > 0.0 && c.is_finite()).then(|| Params {
            c,
            rot,
            l: DVec3::splat(0.5 * r2.ln()),
        })
    }

    /// An algebraic quadric f(x) = xᵀAx + b·x + c through the oriented points, in the spirit
    /// of Li & Griffiths (2004) but using the normals: least squares on f(p) = 0 and
    /// ∇f(p) × n = 0 (both linear in the ten coefficients), i.e. the eigenvector of the
    /// smallest eigenvalue of the 10×10 scatter matrix. Exact on exact samples of any patch
    /// that determines the ellipsoid; `None` unless the quadric is an ellipsoid.
    fn quadric(&self) -> Option<Params> {
        let mut m = [[0.0; 10]; 10];
        let mut add = |w: f64, row: &[f64; 10]| {
            for i in 0..10 {
                for j in i..10 {
                    m[i][j] += w * row[i] * row[j];
                }
            }
        };
        for smp in &self.samples {
            let p = smp.p;
            let n = smp.n;
            add(
                smp.w,
                &[
                    p.x * p.x,
                    p.y * p.y,
                    p.z * p.z,
                    2.0 * p.x * p.y,
                    2.0 * p.x * p.z,
                    2.0 * p.y * p.z,
                    p.x,
                    p.y,
                    p.z,
                    1.0,
                ],
            );
            // Rows of the gradient 2Ap + b as linear forms of the coefficients.
            let gx = [
                2.0 * p.x,
                0.0,
                0.0,
                2.0 * p.y,
                2.0 * p.z,
                0.0,
                1.0,
                0.0,
                0.0,
                0.0,
            ];
            let gy = [
                0.0,
                2.0 * p.y,
                0.0,
                2.0 * p.x,
                0.0,
                2.0 * p.z,
                0.0,
                1.0,
                0.0,
                0.0,
            ];
            let gz = [
                0.0,
                0.0,
                2.0 * p.z,
                0.0,
                2.0 * p.x,
                2.0 * p.y,
                0.0,
                0.0,
                1.0,
                0.0,
            ];
            let combine = |a: &[f64; 10], ka: f64, b: &[f64; 10], kb: f64| {
                let mut r = [0.0; 10];
                for i in 0..10 {
                    r[i] = ka * a[i] - kb * b[i];
                }
                r
            };
            add(smp.w, &combine(&gy, n.z, &gz, n.y));
            add(smp.w, &combine(&gz, n.x, &gx, n.z));
            add(smp.w, &combine(&gx, n.y, &gy, n.x));
        }
        for i in 0..10 {
            for j in 0..i {
                m[i][j] = m[j][i];
            }
        }
        let (values, vectors) = jacobi_eigen(m);
        let smallest = (0..10).min_by(|&i, &j| values[i].total_cmp(&values[j]))?;
        let v: [f64; 10] = std::array::from_fn(|k| vectors[k][smallest]);
        let a = [[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]];
        let b = DVec3::new(v[6], v[7], v[8]);
        let (mut lambdas, axes) = eigen_symmetric(a);
        // Make A positive definite (the quadric's overall sign is arbitrary).
        let flip = if lambdas[0] < 0.0 { -1.0 } else { 1.0 };
        lambdas = lambdas.map(|l| flip * l);
        let (b, c) = (flip * b, flip * v[9]);
        if lambdas
            .iter()
            .any(|&l| l.is_nan() || l <= 1e-12 * lambdas[0].abs().max(1e-300))
        {
            return None;
        }
        // Centre −½A⁻¹b, through the eigenbasis.
        let bl = axes.transpose() * b;
        let cl = DVec3::new(
            -0.5 * bl.x / lambdas[0],
            -0.5 * bl.y / lambdas[1],
            -0.5 * bl.z / lambdas[2],
        );
        let level = -(c + 0.5 * bl.dot(cl));
        if level.is_nan() || level <= 0.0 {
            return None;
        }
        let radii = DVec3::from_array(lambdas.map(|l| (level / l).sqrt()));
        let centre = axes * cl;
        (radii.is_finite() && centre.is_finite()).then(|| Params {
            c: centre,
            rot: DQuat::from_mat3(&axes),
            l: radii.map(f64::ln),
        })
    }

    /// Levenberg–Marquardt from `x` for at most `iterations`; returns the parameters, their
    /// cost, the damping reached and whether it converged.
    fn levenberg_marquardt(
        &self,
        samples: &[Sample],
        mut x: Params,
        s: f64,
        mut lambda: f64,
        iterations: u32,
    ) -> (Params, f64, f64, bool, u32) {
        let mut a: Mat9 = [[0.0; 9]; 9];
        let mut g = [0.0; 9];
        let mut cost = self.build_normal_equations(samples, &x, s, &mut a, &mut g);
        if !cost.is_finite() {
            return (x, f64::MAX, lambda, true, 0);
        }
        for it in 0..iterations {
            let max_diag = (0..9).map(|i| a[i][i]).fold(0.0, f64::max);
            let floor = 1e-12 * max_diag.max(1e-300);
            let mut accepted = false;
            while lambda < 1e16 {
                let mut m = a;
                for (i, row) in m.iter_mut().enumerate() {
                    row[i] += lambda * (a[i][i].max(floor));
                }
                let rhs = g.map(|v| -v);
                let Some(step) = solve_spd(m, rhs) else {
                    lambda *= 10.0;
                    continue;
                };
                let candidate = self.apply_step(&x, &step);
                let new_cost = self.cost(samples, &candidate, s);
                if new_cost.is_finite() && new_cost < cost {
                    let decrease = cost - new_cost;
                    let step_len = step.iter().map(|v| v * v).sum::<f64>().sqrt();
                    x = candidate;
                    cost = self.build_normal_equations(samples, &x, s, &mut a, &mut g);
                    lambda = (lambda / 3.0).max(1e-15);
                    accepted = true;
                    if decrease <= 1e-10 * cost || step_len < 1e-11 {
                        return (x, cost, lambda, true, it);
                    }
                    break;
                }
                lambda *= 4.0;
            }
            if !accepted {
                return (x, cost, lambda, true, it);
            }
        }
        (x, cost, lambda, false, iterations)
    }

    fn apply_step(&self, x: &Params, step: &[f64; 9]) -> Params {
        let dc = DVec3::new(step[0], step[1], step[2]);
        let dw = DVec3::new(step[3], step[4], step[5]);
        let dl = DVec3::new(step[6], step[7], step[8]);
        self.clamp(Params {
            c: x.c + x.rot * dc,
            rot: (x.rot * DQuat::from_scaled_axis(dw)).normalize(),
            l: x.l + dl,
        })
    }

    /// The objective in canonical units.
    fn cost(&self, samples: &[Sample], x: &Params, s: f64) -> f64 {
        let e = Ellipsoid {
            center: x.c,
            rotation: x.rot,
            radii: x.l.map(f64::exp),
            sign: if s > 0.0 {
                Sign::Positive
            } else {
                Sign::Negative
            },
        };
        let w = Weights {
            alpha: self.alpha,
            beta: self.beta,
            gamma: self.gamma,
        };
        let mut sum = 0.0;
        for smp in samples {
            sum += smp.w * measure_vertex_terms(&e, smp.p, smp.n, smp.h).weighted(&w);
        }
        if let Some((sqrt_delta, hull)) = self.volume {
            let r = x.l.map(f64::exp);
            let v = sqrt_delta * (hull - 4.0 / 3.0 * std::f64::consts::PI * r.x * r.y * r.z);
            sum += v * v;
        }
        sum
    }

    /// Jᵀ J and Jᵀ r at `x` (upper and lower triangles both filled); returns the cost.
    fn build_normal_equations(
        &self,
        samples: &[Sample],
        x: &Params,
        s: f64,
        a: &mut Mat9,
        g: &mut [f64; 9],
    ) -> f64 {
        *a = [[0.0; 9]; 9];
        *g = [0.0; 9];
        let rot_t = DMat3::from_quat(x.rot.conjugate());
        let r = x.l.map(f64::exp);
        let mut cost = 0.0;
        // Centre steps are taken in the ellipsoid's frame (c ← c + R·δc), so ∂/∂δc = −g_q;
        // ∂/∂ω = g_q × q (+ direct terms); ∂/∂ℓ = g_l.
        let row = |gq: DVec3, gl: DVec3, gw_extra: DVec3, q: DVec3| {
            let jw = gq.cross(q) + gw_extra;
            [-gq.x, -gq.y, -gq.z, jw.x, jw.y, jw.z, gl.x, gl.y, gl.z]
        };
        // Up to five rows per sample, added to A in one pass.
        let mut rows = [[0.0; 9]; 5];
        let mut res = [0.0; 5];
        for smp in samples {
            let q = rot_t * (smp.p - x.c);
            let nu = rot_t * smp.n;
            let terms = residual_gradients(q, r);
            let sa = (smp.w * self.alpha).sqrt();
            let sb = (smp.w * self.beta).sqrt();
            let sg = (smp.w * self.gamma).sqrt();
            let mut count = 0;
            if sa > 0.0 {
                rows[count] = row(sa * terms.d_q, sa * terms.d_l, DVec3::ZERO, q);
                res[count] = sa * terms.d;
                count += 1;
            }
            if sb > 0.0 {
                for k in 0..3 {
                    // a_k = ν_k − s·m_k; ∂ν_k/∂ω = e_k × ν.
                    let e = DVec3::AXES[k];
                    rows[count] = row(
                        -s * sb * terms.m_q[k],
                        -s * sb * terms.m_l[k],
                        sb * e.cross(nu),
                        q,
                    );
                    res[count] = sb * (nu[k] - s * terms.m[k]);
                    count += 1;
                }
            }
            if sg > 0.0 {
                rows[count] = row(-s * sg * terms.h_q, -s * sg * terms.h_l, DVec3::ZERO, q);
                res[count] = sg * (smp.h - s * terms.h);
                count += 1;
            }
            accumulate(a, g, &rows[..count], &res[..count]);
            cost += res[..count].iter().map(|r| r * r).sum::<f64>();
        }
        if let Some((sqrt_delta, hull)) = self.volume {
            let vol = 4.0 / 3.0 * std::f64::consts::PI * r.x * r.y * r.z;
            let rv = sqrt_delta * (hull - vol);
            let gl = DVec3::splat(-sqrt_delta * vol);
            accumulate(
                a,
                g,
                &[row(DVec3::ZERO, gl, DVec3::ZERO, DVec3::ZERO)],
                &[rv],
            );
            cost += rv * rv;
        }
        for i in 0..9 {
            for k in 0..i {
                a[i][k] = a[k][i];
            }
        }
        cost
    }
}

/// At most `m` samples picked with a fixed stride, reweighted to keep the total weight.
fn stride_subsample(samples: &[Sample], m: usize) -> Vec<Sample> {
    if samples.len() <= m {
        return samples.to_vec();
    }
    let mut out: Vec<Sample> = (0..m)
        .filter_map(|k| samples.get(k * samples.len() / m).copied())
        .collect();
    let total: f64 = samples.iter().map(|s| s.w).sum();
    let kept: f64 = out.iter().map(|s| s.w).sum();
    let factor = total / kept;
    if factor.is_finite() {
        out.iter_mut().for_each(|s| s.w *= factor);
    }
    out
}

/// A ← A + Σ jⱼ·jⱼᵀ (upper triangle), g ← g + Σ jⱼ·rⱼ, each entry loaded and stored once.
#[inline(always)]
fn accumulate(a: &mut Mat9, g: &mut [f64; 9], rows: &[[f64; 9]], res: &[f64]) {
    for i in 0..9 {
        let mut gi = g[i];
        for (j, r) in rows.iter().zip(res) {
            gi += j[i] * r;
        }
        g[i] = gi;
        for k in i..9 {
            let mut v = a[i][k];
            for j in rows {
                v += j[i] * j[k];
            }
            a[i][k] = v;
        }
    }
}

/// Values and local gradients of the per-sample quantities, as functions of the local
/// point q and the log radii ℓ.
#[derive(Debug, Clone, Copy)]
struct LocalTerms {
    /// Signed radial distance |q|·(1 − 1/ρ).
    d: f64,
    d_q: DVec3,
    d_l: DVec3,
    /// Outward unit normal in the local frame, and the gradients of each component.
    m: DVec3,
    m_q: [DVec3; 3],
    m_l: [DVec3; 3],
    /// Outward mean curvature at Π(q).
    h: f64,
    h_q: DVec3,
    h_l: DVec3,
}

/// The analytic derivatives behind the Jacobian. With u = q/r, ρ = |u|, û = u/ρ:
/// d = |q|(1 − 1/ρ); m = g/|g| with g = u/r; and, on the surface point x = r∘û,
/// H = N / (2 P G^{3/2}), N = Σ r_k²(1 − û_k²), G = Σ û_k²/r_k², P = Π r_k².
fn residual_gradients(q: DVec3, r: DVec3) -> LocalTerms {
    let tiny = 1e-150;
    let u = q / r;
    let rho = u.length().max(tiny);
    let q_len = q.length().max(tiny);
    // Euclidean.
    let rho_q = u / (rho * r);
    let rho_l = -(u * u) / rho;
    let d = q_len * (1.0 - 1.0 / rho);
    let d_q = (q / q_len) * (1.0 - 1.0 / rho) + (q_len / (rho * rho)) * rho_q;
    let d_l = (q_len / (rho * rho)) * rho_l;
    // Normal.
    let gvec = u / r;
    let g_len = gvec.length().max(tiny);
    let m = gvec / g_len;
    let r2 = r * r;
    let inv_gr2 = DVec3::ONE / (g_len * r2);
    let mut m_q = [DVec3::ZERO; 3];
    let mut m_l = [DVec3::ZERO; 3];
    for j in 0..3 {
        for k in 0..3 {
            let proj = if j == k { 1.0 } else { 0.0 } - m[j] * m[k];
            m_q[j][k] = proj * inv_gr2[k];
            m_l[j][k] = -2.0 * m[k] * proj;
        }
    }
    // Mean curvature through ln H.
    let uh = u / rho;
    let uh2 = uh * uh;
    let n_term = (r2 * (DVec3::ONE - uh2)).element_sum().max(tiny);
    let g_term = (uh2 / r2).element_sum().max(tiny);
    let p_term = r2.x * r2.y * r2.z;
    let h = n_term / (2.0 * p_term * g_term * g_term.sqrt());
    let h_uh = -2.0 * r2 * uh / n_term - 3.0 * uh / (r2 * g_term);
    let h_u = (h_uh - uh * uh.dot(h_uh)) / rho;
    let lnh_q = h_u / r;
    let lnh_l = 2.0 * r2 * (DVec3::ONE - uh2) / n_term - DVec3::splat(2.0)
        + 3.0 * uh2 / (r2 * g_term)
        - h_u * u;
    LocalTerms {
        d,
        d_q,
        d_l,
        m,
        m_q,
        m_l,
        h,
        h_q: h * lnh_q,
        h_l: h * lnh_l,
    }
}

/// The scatter matrix Σ w·(p − centre)(p − centre)ᵀ of weighted points.
pub(crate) fn scatter(
    points: impl IntoIterator<Item = (f64, DVec3)>,
    centre: DVec3,
) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (w, p) in points {
        let d = p - centre;
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += w * d[i] * d[j];
            }
        }
    }
    m
}

/// Eigen-decomposition of a symmetric 3×3 matrix by cyclic Jacobi rotations: eigenvalues in
/// decreasing order and a right-handed rotation whose columns are the eigenvectors.
pub(crate) fn eigen_symmetric(m: [[f64; 3]; 3]) -> ([f64; 3], DMat3) {
    let (diagonal, v) = jacobi_eigen(m);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| diagonal[j].total_cmp(&diagonal[i]).then(i.cmp(&j)));
    let values = order.map(|i| diagonal[i]);
    let col = |i: usize| DVec3::new(v[0][i], v[1][i], v[2][i]);
    let (x, y) = (col(order[0]).normalize(), col(order[1]).normalize());
    let z = x.cross(y).normalize();
    let y = z.cross(x);
    let basis = DMat3::from_cols(x, y, z);
    if basis.is_finite() {
        (values, basis)
    } else {
        (values, DMat3::IDENTITY)
    }
}

/// Eigen-decomposition of a symmetric N×N matrix by cyclic Jacobi rotations: eigenvalues
/// (unordered) and eigenvectors as the columns of the returned matrix.
fn jacobi_eigen<const N: usize>(mut a: [[f64; N]; N]) -> ([f64; N], [[f64; N]; N]) {
    let mut v = [[0.0; N]; N];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..60 {
        let mut off = 0.0;
        let mut diag = 0.0;
        for i in 0..N {
            diag += a[i][i] * a[i][i];
            for j in i + 1..N {
                off += a[i][j] * a[i][j];
            }
        }
        if off <= 1e-34 * diag || off == 0.0 {
            break;
        }
        for p in 0..N {
            for q in p + 1..N {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = if theta == 0.0 {
                    1.0
                } else {
                    theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
                };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..N {
                    let (akp, akq) = (a[k][p], a[k][q]);
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for k in 0..N {
                    let (apk, aqk) = (a[p][k], a[q][k]);
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for row in v.iter_mut() {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
    }
    (std::array::from_fn(|i| a[i][i]), v)
}

/// Solve a symmetric positive definite system by Cholesky; `None` if not positive definite.
fn solve_spd<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for j in 0..N {
        let mut d = a[j][j];
        for k in 0..j {
            d -= a[j][k] * a[j][k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in j + 1..N {
            let mut v = a[i][j];
            for k in 0..j {
                v -= a[i][k] * a[j][k];
            }
            a[i][j] = v / d;
        }
    }
    for i in 0..N {
        let mut v = b[i];
        for k in 0..i {
            v -= a[i][k] * b[k];
        }
        b[i] = v / a[i][i];
    }
    for i in (0..N).rev() {
        let mut v = b[i];
        for k in i + 1..N {
            v -= a[k][i] * b[k];
        }
        b[i] = v / a[i][i];
    }
    b.iter().all(|v| v.is_finite()).then_some(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    #[test]
    fn a_single_triangle_gets_a_sphere_tangent_to_it() {
        // A fin: a triangle whose vertex normals lean toward the surface it stands on (but
        // still sum to its own side), as on a scan.
        let (a, b, c) = (
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.02, 0.0, 0.0),
            DVec3::new(0.0, 0.02, 0.01),
        );
        let face = (b - a).cross(c - a).normalize();
        let lean = DVec3::new(0.3, -0.2, 0.9).normalize();
        let points = [a, b, c];
        let normals = [
            face,
            (face + lean).normalize(),
            (face + 0.5 * lean).normalize(),
        ];
        let curvatures = [0.0; 3];
        let input = FitInput::new(&points, &normals, &curvatures).unwrap();
        let scale = super::super::MeshScale::new(1.0, 0.01, 0.1);
        let centroid = (a + b + c) / 3.0;
        for sign in [Sign::Positive, Sign::Negative] {
            let options = FitOptions {
                signs: SignChoice::Only(sign),
                ..FitOptions::surface(&scale)
            };
            let fit = fit_tangent_sphere(&input, &options).expect("three samples: a sphere");
            let e = fit.ellipsoid;
            assert_eq!(e.sign, sign);
            // A sphere, or the caps' limit (as wide as the widest, flat on top).
            assert_eq!(e.radii.x, e.radii.y);
            let cap = options.max_radius * options.scale;
            assert!(e.radii.y == e.radii.z || e.radii.x == cap, "{}", e.radii);
            // Tangent to the triangle at its centroid, on the side its normals face: the
            // normal there is the face's, and a corner at distance s from the centroid lies
            // s²/2ρ off it, ρ the radius of curvature there (R²/c for radii R, R, c).
            assert!(e.normal(centroid).dot(face) > 1.0 - 1e-9);
            let rho = e.radii.x * e.radii.x / e.radii.z;
            for p in points {
                let (d, s) = (e.radial_distance(p), p.distance(centroid));
                assert!(d.abs() <= 0.51 * s * s / rho, "{p}: {d}, radii {}", e.radii);
            }
        }
        // Nine samples or more are not a speck's.
        let many: Vec<DVec3> = (0..MIN_ELLIPSOID_SAMPLES)
            .map(|i| DVec3::new(i as f64, (i * i) as f64, 1.0) * 0.01)
            .collect();
        let up = vec![DVec3::Z; many.len()];
        let flat = vec![0.0; many.len()];
        let input = FitInput::new(&many, &up, &flat).unwrap();
        assert!(fit_tangent_sphere(&input, &FitOptions::surface(&scale)).is_none());
    }

    /// A facet of a low-poly part (a cube's triangle), measured with its own face's normal
    /// at every corner: the plane-like spheroid, on which its corners lie to rounding, beats
    /// every sphere tangent to it (the widest bulges by spread²/2R).
    #[test]
    fn a_flat_facet_gets_the_plane_like_spheroid() {
        let points = [
            DVec3::new(0.5, -0.5, 0.5),
            DVec3::new(0.5, 0.5, 0.5),
            DVec3::new(0.5, 0.5, -0.5),
        ];
        let face = DVec3::X;
        let normals = [face; 3];
        let curvatures = [0.0; 3];
        let input = FitInput::new(&points, &normals, &curvatures).unwrap();
        let scale = super::super::MeshScale::new(3f64.sqrt(), 1.2, 1.0);
        let options = FitOptions::surface(&scale);
        let e = fit_tangent_sphere(&input, &options)
            .expect("three samples")
            .ellipsoid;
        let (cap, unit) = (options.max_radius * scale.diagonal, scale.diagonal);
        assert!((e.radii - DVec3::new(cap, cap, unit)).abs().max_element() < 1e-9 * cap);
        for p in points {
            // Within 10⁻⁹ of the cap: what boundary smoothing counts as on the ellipsoid.
            let d = e.radial_distance(p).abs();
            assert!(d < 1e-9 * cap, "{p}: {d}");
            assert!(e.normal(p).dot(face) > 1.0 - 1e-9);
        }
    }

    #[test]
    fn local_gradients_match_finite_differences() {
        let mut rng = SplitMix64::new(9);
        for _ in 0..50 {
            let q = DVec3::new(
                rng.range_f64(-2.0, 2.0),
                rng.range_f64(-2.0, 2.0),
                rng.range_f64(-2.0, 2.0),
            );
            let l = DVec3::new(
                rng.range_f64(-1.0, 1.0),
                rng.range_f64(-1.0, 1.0),
                rng.range_f64(-1.0, 1.0),
            );
            let t = residual_gradients(q, l.map(f64::exp));
            let h = 1e-6;
            for k in 0..3 {
                let e = DVec3::AXES[k] * h;
                let tq = |dq: DVec3| residual_gradients(q + dq, l.map(f64::exp));
                let tl = |dl: DVec3| residual_gradients(q, (l + dl).map(f64::exp));
                let (qp, qm, lp, lm) = (tq(e), tq(-e), tl(e), tl(-e));
                let check = |analytic: f64, numeric: f64, what: &str| {
                    assert!(
                        (analytic - numeric).abs() < 1e-5 * (1.0 + numeric.abs()),
                        "{what}: {analytic} vs {numeric}"
                    );
                };
                check(t.d_q[k], (qp.d - qm.d) / (2.0 * h), "d_q");
                check(t.d_l[k], (lp.d - lm.d) / (2.0 * h), "d_l");
                check(t.h_q[k], (qp.h - qm.h) / (2.0 * h), "h_q");
                check(t.h_l[k], (lp.h - lm.h) / (2.0 * h), "h_l");
                for j in 0..3 {
                    check(t.m_q[j][k], (qp.m[j] - qm.m[j]) / (2.0 * h), "m_q");
                    check(t.m_l[j][k], (lp.m[j] - lm.m[j]) / (2.0 * h), "m_l");
                }
            }
            // Values agree with the ellipsoid's own closed forms.
            let e = Ellipsoid {
                center: DVec3::ZERO,
                rotation: DQuat::IDENTITY,
                radii: l.map(f64::exp),
                sign: Sign::Positive,
            };
            assert!((t.h - e.outward_mean_curvature(q)).abs() < 1e-10 * t.h);
            assert!((t.m - e.outward_normal(q)).length() < 1e-12);
            assert!((t.d.abs() - e.radial_distance(q)).abs() < 1e-12);
        }
    }

    /// The assembled gradient Jᵀr equals half the numerical gradient of the cost, including
    /// the rotation and centre chain rules.
    #[test]
    fn normal_equations_gradient_matches_the_cost() {
        let mut rng = SplitMix64::new(10);
        let points: Vec<DVec3> = (0..40)
            .map(|_| DVec3::new(rng.normal(), rng.normal() * 2.0, rng.normal() * 0.5))
            .collect();
        let normals: Vec<DVec3> = points
            .iter()
            .map(|p| (*p + DVec3::X * 0.1).normalize())
            .collect();
        let curv: Vec<f64> = (0..40).map(|i| 0.1 * i as f64 - 1.0).collect();
        let input = FitInput::new(&points, &normals, &curv).unwrap();
        let mut opts = FitOptions::surface(&super::super::MeshScale::new(4.0, 0.3, 5.0));
        opts.volume = Some(VolumeTerm {
            delta: 0.01,
            hull_volume: 3.0,
        });
        let problem = Canonical::new(&input, &opts).unwrap();
        for s in [1.0, -1.0] {
            let x = Params {
                c: DVec3::new(0.05, -0.02, 0.01),
                rot: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 0.2, -0.5),
                l: DVec3::new(-1.0, -0.5, -1.5),
            };
            let mut a = [[0.0; 9]; 9];
            let mut g = [0.0; 9];
            let cost = problem.build_normal_equations(&problem.samples, &x, s, &mut a, &mut g);
            assert!((cost - problem.cost(&problem.samples, &x, s)).abs() < 1e-9 * cost);
            let h = 1e-6;
            for i in 0..9 {
                let mut step = [0.0; 9];
                step[i] = h;
                let plus = problem.cost(&problem.samples, &problem.apply_step(&x, &step), s);
                step[i] = -h;
                let minus = problem.cost(&problem.samples, &problem.apply_step(&x, &step), s);
                let numeric = (plus - minus) / (4.0 * h);
                assert!(
                    (g[i] - numeric).abs() < 1e-5 * (1.0 + numeric.abs()),
                    "param {i}: {} vs {numeric}",
                    g[i]
                );
            }
        }
    }

    #[test]
    fn eigen_decomposition_reconstructs() {
        let mut rng = SplitMix64::new(12);
        for _ in 0..100 {
            let r = DMat3::from_quat(DQuat::from_scaled_axis(DVec3::new(
                rng.normal(),
                rng.normal(),
                rng.normal(),
            )));
            let d = DVec3::new(
                rng.range_f64(0.0, 3.0),
                rng.range_f64(0.0, 3.0),
                rng.range_f64(0.0, 3.0),
            );
            let m = r * DMat3::from_diagonal(d) * r.transpose();
            let arr = [
                [m.x_axis.x, m.y_axis.x, m.z_axis.x],
                [m.x_axis.y, m.y_axis.y, m.z_axis.y],
                [m.x_axis.z, m.y_axis.z, m.z_axis.z],
            ];
            let (values, basis) = eigen_symmetric(arr);
            assert!(values[0] >= values[1] && values[1] >= values[2]);
            assert!((basis.determinant() - 1.0).abs() < 1e-12);
            let back = basis * DMat3::from_diagonal(DVec3::from_array(values)) * basis.transpose();
            assert!((back - m).to_cols_array().iter().all(|v| v.abs() < 1e-12));
        }
    }

    #[test]
    fn jacobi_handles_larger_matrices() {
        let mut rng = SplitMix64::new(13);
        let mut b = [[0.0; 10]; 10];
        for row in b.iter_mut() {
            for v in row.iter_mut() {
                *v = rng.normal();
            }
        }
        // m = bᵀb is symmetric positive semi-definite.
        let m: [[f64; 10]; 10] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..10).map(|k| b[k][i] * b[k][j]).sum())
        });
        let (values, vectors) = jacobi_eigen(m);
        for e in 0..10 {
            for i in 0..10 {
                let mv: f64 = (0..10).map(|j| m[i][j] * vectors[j][e]).sum();
                assert!((mv - values[e] * vectors[i][e]).abs() < 1e-10);
            }
        }
    }

    #[test]
    fn quadric_start_is_exact_on_exact_samples() {
        let truth = Ellipsoid {
            center: DVec3::new(0.3, -0.2, 0.1),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.4, 1.0, -0.3),
            radii: DVec3::new(2.0, 0.7, 1.2),
            sign: Sign::Positive,
        };
        // A 15% cap: the quadric still pins down the whole ellipsoid.
        let mut rng = SplitMix64::new(14);
        let (mut points, mut normals, mut curv) = (Vec::new(), Vec::new(), Vec::new());
        while points.len() < 200 {
            let u = DVec3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
            if u.z > 0.7 {
                let p = truth.from_unit_sphere(u);
                points.push(p);
                normals.push(truth.normal(p));
                curv.push(truth.mean_curvature(p));
            }
        }
        let input = FitInput::new(&points, &normals, &curv).unwrap();
        let opts = FitOptions::surface(&super::super::MeshScale::new(1.0, 0.05, 1.0));
        let problem = Canonical::new(&input, &opts).unwrap();
        let x = problem.quadric().unwrap();
        let e = problem.to_world(&x, Sign::Positive);
        for &p in &points {
            assert!(e.radial_distance(p) < 1e-6, "{}", e.radial_distance(p));
        }
        assert!((e.volume() - truth.volume()).abs() < 1e-5 * truth.volume());
    }

    #[test]
    fn cholesky_solves_and_rejects_indefinite() {
        let a = [[4.0, 1.0], [1.0, 3.0]];
        let x = solve_spd(a, [1.0, 2.0]).unwrap();
        assert!((4.0 * x[0] + x[1] - 1.0).abs() < 1e-15);
        assert!((x[0] + 3.0 * x[1] - 2.0).abs() < 1e-15);
        assert!(solve_spd([[1.0, 2.0], [2.0, 1.0]], [0.0, 0.0]).is_none());
    }
}
