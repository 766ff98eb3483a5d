//! Error metrics between mesh data and an ellipsoid (Simari & Singh 2005, sections 2 and 3).
//!
//! Per vertex v with normal n_v and mean curvature H_v, against ellipsoid P:
//!
//! - Euclidean (radial) E_euc = ‖v − Π(v)‖²,
//! - angular E_ang = ‖n_v ∓ n_P(v)‖²,
//! - curvature E_cur = (H_v ∓ H_P(v))²,
//!
//! where n_P and H_P are the outward normal and mean curvature at the radial projection Π(v),
//! and the lower sign applies to negative ellipsoids ([`Ellipsoid::normal`] and
//! [`Ellipsoid::mean_curvature`] already carry it). The composite is
//! E = α·E_euc + β·E_ang + γ·E_cur; a face's error is the sum over its three vertices
//! (optionally times its area), a region's the sum over its faces. The volume metric is
//! E_vol = α·E_euc(R) + δ·(V(R) − 4/3·πabc)².
//!
//! # Canonical scale
//!
//! The paper's default weights (α = 1/ā², β = 1.2, γ = 5·10⁻⁴, δ = 10⁵/V²) are meant to work
//! whatever the model's units, but γ multiplies a squared curvature (units 1/length²), so on
//! its own it does not. ellip defines every error as the error of the **canonical copy** of
//! the mesh: translated so that its bounding box is centred at the origin and scaled so that
//! the box diagonal D is 1. Then ā is measured in diagonals, curvatures in 1/diagonals, and the
//! paper's numbers apply. [`Weights::paper`] expresses the same thing in the model's own
//! units, so that callers never transform their data: α = 1/ā² (ā in model units — E_euc/ā² is
//! already unit-free), β = 1.2, γ = 5·10⁻⁴·D² (so that γ·(ΔH)² = 5·10⁻⁴·(ΔH·D)²), and
//! δ = 10⁵/V² (unit-free as it stands). The fitting works internally in canonical units for
//! numerical conditioning; see [`crate::ellipsoid::fit`].

use super::Ellipsoid;
use crate::ellipsoid::hull::convex_hull_volume;
use crate::mesh::Mesh;
use glam::DVec3;

/// The paper's β (section 2).
pub const PAPER_BETA: f64 = 1.2;
/// The paper's γ (section 2), for curvatures in canonical units (1 / box diagonal).
pub const PAPER_GAMMA: f64 = 5e-4;
/// The numerator of the paper's δ = 10⁵/V² (section 3).
pub const PAPER_DELTA_NUMERATOR: f64 = 1e5;

/// The lengths that make the paper's weights unit-free.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshScale {
    /// Bounding-box diagonal D: the canonical unit of length.
    pub diagonal: f64,
    /// Average edge length ā.
    pub average_edge_length: f64,
    /// Volume V of the whole model (enclosed volume when closed, else its convex hull's).
    pub volume: f64,
}

impl MeshScale {
    /// A scale from explicit values; non-finite or non-positive ones are replaced by
    /// defaults derived from the others (ā = D/100, V = D³/100, D = 1).
    pub fn new(diagonal: f64, average_edge_length: f64, volume: f64) -> MeshScale {
        let good = |x: f64| x.is_finite() && x > 0.0;
        let diagonal = if good(diagonal) { diagonal } else { 1.0 };
        MeshScale {
            diagonal,
            average_edge_length: if good(average_edge_length) {
                average_edge_length
            } else {
                diagonal / 100.0
            },
            volume: if good(volume) {
                volume
            } else {
                diagonal.powi(3) / 100.0
            },
        }
    }

    /// The scale of a mesh: box diagonal, average edge length, and enclosed volume (the
    /// vertices' convex-hull volume when the mesh is open).
    pub fn of_mesh(mesh: &Mesh) -> MeshScale {
        let diagonal = mesh.bounding_box().map_or(0.0, |b| b.diagonal());
        let volume = mesh
            .volume()
            .map(f64::abs)
            .filter(|v| *v > 0.0)
            .unwrap_or_else(|| convex_hull_volume(mesh.positions()));
        MeshScale::new(diagonal, mesh.average_edge_length(), volume)
    }

    /// Map a point of the model into canonical units around `origin`: (p − origin) / D.
    pub fn to_canonical(&self, p: DVec3, origin: DVec3) -> DVec3 {
        (p - origin) / self.diagonal
    }
}

/// The composite metric's weights α, β, γ, in the model's units (section 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights {
    /// Weight of the Euclidean (radial) distance E_euc.
    pub alpha: f64,
    /// Weight of the angular distance E_ang.
    pub beta: f64,
    /// Weight of the curvature distance E_cur.
    pub gamma: f64,
}

impl Weights {
    /// The paper's defaults expressed in the model's units: α = 1/ā², β = 1.2,
    /// γ = 5·10⁻⁴·D² (see the module's "Canonical scale").
    pub fn paper(scale: &MeshScale) -> Weights {
        Weights {
            alpha: 1.0 / (scale.average_edge_length * scale.average_edge_length),
            beta: PAPER_BETA,
            gamma: PAPER_GAMMA * scale.diagonal * scale.diagonal,
        }
    }

    /// Only the Euclidean term, α = 1/ā² (the surface part of the volume metric).
    pub fn euclidean(scale: &MeshScale) -> Weights {
        Weights {
            beta: 0.0,
            gamma: 0.0,
            ..Weights::paper(scale)
        }
    }
}

/// The three distances of one vertex, unweighted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorTerms {
    /// E_euc = ‖v − Π(v)‖².
    pub euclidean: f64,
    /// E_ang = ‖n_v ∓ n_P‖².
    pub angular: f64,
    /// E_cur = (H_v ∓ H_P)².
    pub curvature: f64,
}

impl ErrorTerms {
    /// α·E_euc + β·E_ang + γ·E_cur.
    pub fn weighted(&self, w: &Weights) -> f64 {
        w.alpha * self.euclidean + w.beta * self.angular + w.gamma * self.curvature
    }
}

/// The three distances between a vertex (position, unit normal, mean curvature) and an
/// ellipsoid, with the sign rule for negative ellipsoids.
pub fn measure_vertex_terms(
    e: &Ellipsoid,
    point: DVec3,
    normal: DVec3,
    curvature: f64,
) -> ErrorTerms {
    // One local transform serves all three terms.
    let q = e.to_local(point);
    let r2 = e.radii * e.radii;
    let u = q / e.radii;
    let rho = u.length();
    let s = e.sign.factor();
    let (euclidean, x) = if rho > 1e-300 && rho.is_finite() {
        let d = q.length() * (1.0 - 1.0 / rho);
        (d * d, q / rho)
    } else {
        let x = DVec3::new(e.radii.x, 0.0, 0.0);
        ((x - q).length_squared(), x)
    };
    let g = x / r2;
    let g_len = g.length();
    let local_normal = g / g_len;
    let n_local = e.rotation.inverse() * normal;
    let angular = (n_local - s * local_normal).length_squared();
    let h = (r2.x + r2.y + r2.z - x.length_squared()) / (2.0 * r2.x * r2.y * r2.z * g_len.powi(3));
    let dh = curvature - s * h;
    ErrorTerms {
        euclidean,
        angular,
        curvature: dh * dh,
    }
}

/// The composite error E(v, P) = α·E_euc + β·E_ang + γ·E_cur of one vertex (section 2).
/// Cheap and allocation-free: the segmentation calls it for every vertex of every face it
/// classifies.
pub fn vertex_error(
    e: &Ellipsoid,
    point: DVec3,
    normal: DVec3,
    curvature: f64,
    w: &Weights,
) -> f64 {
    measure_vertex_terms(e, point, normal, curvature).weighted(w)
}

/// Mesh-level per-vertex data the metrics read: positions, unit normals, mean curvatures
/// (all indexed by vertex).
#[derive(Debug, Clone, Copy)]
pub struct SurfaceAttributes<'a> {
    positions: &'a [DVec3],
    normals: &'a [DVec3],
    curvatures: &'a [f64],
}

impl<'a> SurfaceAttributes<'a> {
    /// Bundle the three arrays; `None` unless they have the same length.
    pub fn new(
        positions: &'a [DVec3],
        normals: &'a [DVec3],
        curvatures: &'a [f64],
    ) -> Option<SurfaceAttributes<'a>> {
        (positions.len() == normals.len() && positions.len() == curvatures.len()).then_some(
            SurfaceAttributes {
                positions,
                normals,
                curvatures,
            },
        )
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no vertices.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Positions.
    pub fn positions(&self) -> &'a [DVec3] {
        self.positions
    }

    /// Unit normals.
    pub fn normals(&self) -> &'a [DVec3] {
        self.normals
    }

    /// Mean curvatures.
    pub fn curvatures(&self) -> &'a [f64] {
        self.curvatures
    }

    /// Position, normal and curvature of vertex `v`, if it exists.
    pub fn vertex(&self, v: u32) -> Option<(DVec3, DVec3, f64)> {
        let i = usize::try_from(v).ok()?;
        Some((
            *self.positions.get(i)?,
            *self.normals.get(i)?,
            *self.curvatures.get(i)?,
        ))
    }

    /// Area of triangle `face` (0 when an index is out of range).
    pub fn face_area(&self, face: [u32; 3]) -> f64 {
        let p = |v: u32| usize::try_from(v).ok().and_then(|i| self.positions.get(i));
        match (p(face[0]), p(face[1]), p(face[2])) {
            (Some(&a), Some(&b), Some(&c)) => 0.5 * (b - a).cross(c - a).length(),
            _ => 0.0,
        }
    }
}

/// How a face's vertex errors are combined into the face's error (section 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaceWeighting {
    /// E(f) = Σ over the face's vertices (the paper's definition).
    Uniform,
    /// E(f) = (area(f) / reference_area) · Σ over its vertices, the paper's suggested
    /// variation; [`FaceWeighting::area`] picks a reference that keeps errors unit-free.
    Area {
        /// Area counted as weight 1.
        reference_area: f64,
    },
}

impl FaceWeighting {
    /// Area weighting relative to an equilateral triangle of the average edge length
    /// (√3/4·ā²), so that weights are about 1 on an even mesh, whatever its units.
    pub fn area(scale: &MeshScale) -> FaceWeighting {
        let a = scale.average_edge_length;
        FaceWeighting::Area {
            reference_area: 3f64.sqrt() / 4.0 * a * a,
        }
    }

    /// The multiplier of a face's vertex-error sum.
    pub fn face_weight(&self, attributes: &SurfaceAttributes<'_>, face: [u32; 3]) -> f64 {
        match *self {
            FaceWeighting::Uniform => 1.0,
            FaceWeighting::Area { reference_area } => {
                let w = attributes.face_area(face) / reference_area;
                if w.is_finite() {
                    w
                } else {
                    0.0
                }
            }
        }
    }
}

/// E(f, P): the face weight times the sum of its three vertices' errors. A vertex index out
/// of range contributes nothing.
pub fn face_error(
    e: &Ellipsoid,
    attributes: &SurfaceAttributes<'_>,
    face: [u32; 3],
    weighting: FaceWeighting,
    w: &Weights,
) -> f64 {
    let sum: f64 = face
        .iter()
        .filter_map(|&v| attributes.vertex(v))
        .map(|(p, n, h)| vertex_error(e, p, n, h, w))
        .sum();
    weighting.face_weight(attributes, face) * sum
}

/// E(R, P): the sum of the errors of the region's faces.
pub fn region_error(
    e: &Ellipsoid,
    attributes: &SurfaceAttributes<'_>,
    faces: &[[u32; 3]],
    weighting: FaceWeighting,
    w: &Weights,
) -> f64 {
    faces
        .iter()
        .map(|&f| face_error(e, attributes, f, weighting, w))
        .sum()
}

/// The volume part of the volume metric (section 3): hull volume V(R) and its weight δ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VolumeTerm {
    /// δ.
    pub delta: f64,
    /// V(R), the volume of the convex hull of the region's vertices.
    pub hull_volume: f64,
}

impl VolumeTerm {
    /// The paper's default δ = 10⁵/V² with V the whole model's volume.
    pub fn paper(scale: &MeshScale, hull_volume: f64) -> VolumeTerm {
        VolumeTerm {
            delta: PAPER_DELTA_NUMERATOR / (scale.volume * scale.volume),
            hull_volume,
        }
    }

    /// δ·(V(R) − 4/3·πabc)².
    pub fn error(&self, e: &Ellipsoid) -> f64 {
        let d = self.hull_volume - e.volume();
        self.delta * d * d
    }
}

/// E_vol(R, P) = α·E_euc(R, P) + δ·(V(R) − 4/3·πabc)² (section 3); E_euc(R, P) sums over
/// faces like [`region_error`].
pub fn region_volume_error(
    e: &Ellipsoid,
    attributes: &SurfaceAttributes<'_>,
    faces: &[[u32; 3]],
    weighting: FaceWeighting,
    alpha: f64,
    volume: &VolumeTerm,
) -> f64 {
    let w = Weights {
        alpha,
        beta: 0.0,
        gamma: 0.0,
    };
    region_error(e, attributes, faces, weighting, &w) + volume.error(e)
}

/// A region flattened into per-vertex samples whose weighted vertex-error sum equals the
/// region's face-error sum: each vertex appears once, weighted by the summed weights of its
/// region faces (1 per face when uniform). The fitting's input.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RegionSamples {
    /// Mesh vertex index of each sample.
    pub vertices: Vec<u32>,
    /// Positions.
    pub points: Vec<DVec3>,
    /// Unit normals.
    pub normals: Vec<DVec3>,
    /// Mean curvatures.
    pub curvatures: Vec<f64>,
    /// Per-sample weights.
    pub weights: Vec<f64>,
}

/// Gather the vertices of `faces` (in order of first appearance) with their weights; vertex
/// indices out of range are skipped.
pub fn gather_region(
    attributes: &SurfaceAttributes<'_>,
    faces: &[[u32; 3]],
    weighting: FaceWeighting,
) -> RegionSamples {
    let mut slot = std::collections::HashMap::with_capacity(faces.len());
    let mut out = RegionSamples::default();
    for &face in faces {
        let fw = weighting.face_weight(attributes, face);
        for &v in &face {
            let Some((p, n, h)) = attributes.vertex(v) else {
                continue;
            };
            let k = *slot.entry(v).or_insert_with(|| {
                out.vertices.push(v);
                out.points.push(p);
                out.normals.push(n);
                out.curvatures.push(h);
                out.weights.push(0.0);
                out.weights.len() - 1
            });
            if let Some(w) = out.weights.get_mut(k) {
                *w += fw;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ellipsoid::Sign;
    use glam::DQuat;

    fn sample_ellipsoid() -> Ellipsoid {
        Ellipsoid {
            center: DVec3::new(0.5, -1.0, 2.0),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1),
            radii: DVec3::new(1.0, 2.0, 0.5),
            sign: Sign::Positive,
        }
    }

    #[test]
    fn terms_match_the_ellipsoid_methods() {
        let e = sample_ellipsoid();
        for (i, p) in [
            DVec3::new(1.0, 0.0, 2.0),
            DVec3::new(-3.0, 2.0, 1.0),
            DVec3::new(0.5, -1.1, 2.05),
        ]
        .into_iter()
        .enumerate()
        {
            let n = DVec3::new(0.2, 0.9, -0.1 * i as f64).normalize();
            let h = 0.3 * i as f64 - 0.4;
            for e in [e, e.flipped()] {
                let t = measure_vertex_terms(&e, p, n, h);
                let d = e.radial_distance(p);
                assert!((t.euclidean - d * d).abs() < 1e-12 * (1.0 + d * d));
                let s = e.sign.factor();
                let outward = e.outward_normal(p);
                assert!((t.angular - (n - s * outward).length_squared()).abs() < 1e-12);
                let hp = e.outward_mean_curvature(p);
                assert!((t.curvature - (h - s * hp).powi(2)).abs() < 1e-12);
                let w = Weights {
                    alpha: 2.0,
                    beta: 3.0,
                    gamma: 5.0,
                };
                let expected = 2.0 * t.euclidean + 3.0 * t.angular + 5.0 * t.curvature;
                assert!((vertex_error(&e, p, n, h, &w) - expected).abs() < 1e-12 * expected);
            }
        }
    }

    #[test]
    fn exact_samples_have_zero_error_only_with_the_right_sign() {
        let e = sample_ellipsoid();
        let w = Weights {
            alpha: 1.0,
            beta: 1.2,
            gamma: 5e-4,
        };
        let p = e.from_unit_sphere(DVec3::new(0.6, 0.0, 0.8));
        let (n, h) = (e.normal(p), e.mean_curvature(p));
        assert!(vertex_error(&e, p, n, h, &w) < 1e-20);
        // The negative ellipsoid sees the same vertex with inverted normal and curvature.
        let neg = e.flipped();
        assert!(vertex_error(&neg, p, -n, -h, &w) < 1e-20);
        // The wrong sign costs 4β from the normal plus γ·(2H)².
        let wrong = vertex_error(&neg, p, n, h, &w);
        assert!((wrong - (4.0 * 1.2 + 5e-4 * 4.0 * h * h)).abs() < 1e-9);
    }

    #[test]
    fn face_and_region_errors_sum_and_gather_consistently() {
        let e = sample_ellipsoid();
        let positions = vec![
            DVec3::new(1.0, 0.0, 2.0),
            DVec3::new(0.0, 1.0, 2.0),
            DVec3::new(0.0, 0.0, 3.0),
            DVec3::new(1.0, 1.0, 3.0),
        ];
        let normals = vec![DVec3::Z, DVec3::X, DVec3::Y, DVec3::ONE.normalize()];
        let curvatures = vec![0.1, 0.2, -0.3, 1.0];
        let attrs = SurfaceAttributes::new(&positions, &normals, &curvatures).unwrap();
        let w = Weights {
            alpha: 1.5,
            beta: 1.2,
            gamma: 0.1,
        };
        let faces = [[0, 1, 2], [1, 3, 2]];
        let ve = |v: usize| vertex_error(&e, positions[v], normals[v], curvatures[v], &w);
        let f0 = face_error(&e, &attrs, faces[0], FaceWeighting::Uniform, &w);
        assert!((f0 - (ve(0) + ve(1) + ve(2))).abs() < 1e-12 * f0);
        let region = region_error(&e, &attrs, &faces, FaceWeighting::Uniform, &w);
        let expected = ve(0) + 2.0 * ve(1) + 2.0 * ve(2) + ve(3);
        assert!((region - expected).abs() < 1e-12 * region);
        // Area weighting multiplies each face by its area over the reference.
        let weighting = FaceWeighting::Area {
            reference_area: 0.25,
        };
        let a0 = 0.5
            * (positions[1] - positions[0])
                .cross(positions[2] - positions[0])
                .length();
        let fa = face_error(&e, &attrs, faces[0], weighting, &w);
        assert!((fa - a0 / 0.25 * f0).abs() < 1e-12 * fa);
        // Gathered samples reproduce the region error.
        for weighting in [FaceWeighting::Uniform, weighting] {
            let samples = gather_region(&attrs, &faces, weighting);
            assert_eq!(samples.vertices, vec![0, 1, 2, 3]);
            let total: f64 = (0..4)
                .map(|k| {
                    samples.weights[k]
                        * vertex_error(
                            &e,
                            samples.points[k],
                            samples.normals[k],
                            samples.curvatures[k],
                            &w,
                        )
                })
                .sum();
            let direct = region_error(&e, &attrs, &faces, weighting, &w);
            assert!((total - direct).abs() < 1e-12 * direct);
        }
        // Out-of-range indices contribute nothing rather than panicking.
        assert_eq!(
            face_error(&e, &attrs, [7, 8, 9], FaceWeighting::Uniform, &w),
            0.0
        );
        assert!(SurfaceAttributes::new(&positions, &normals, &curvatures[..2]).is_none());
    }

    #[test]
    fn paper_weights_are_unit_free() {
        // The same shape in metres and millimetres: identical weighted errors.
        let e = sample_ellipsoid();
        let scale = MeshScale::new(3.0, 0.05, 10.0);
        let k = 1000.0;
        let big = MeshScale::new(3.0 * k, 0.05 * k, 10.0 * k * k * k);
        let e_big = Ellipsoid {
            center: e.center * k,
            radii: e.radii * k,
            ..e
        };
        let p = DVec3::new(1.2, 0.3, 1.0);
        let n = DVec3::new(0.3, 0.4, 0.5).normalize();
        let h = 0.7;
        let a = vertex_error(&e, p, n, h, &Weights::paper(&scale));
        let b = vertex_error(&e_big, p * k, n, h / k, &Weights::paper(&big));
        assert!((a - b).abs() < 1e-10 * a);
        let hull = 2.0;
        let va = VolumeTerm::paper(&scale, hull).error(&e);
        let vb = VolumeTerm::paper(&big, hull * k * k * k).error(&e_big);
        assert!((va - vb).abs() < 1e-10 * va);
    }
}
