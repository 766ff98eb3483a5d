//! The face corners at sharp creases, and the normal and mean curvature of each one's side.
//!
//! A vertex normal averages every face around the vertex ([`Mesh::vertex_normals`]) and the
//! cotangent mean curvature ([`super::curvature`]) sums the dihedral angles of every edge
//! around it. Where the surface has a crease (a CAD part's edge, a cube's corner) both
//! belong to neither side: every corner of a cube's faces gets the cube's diagonal for a
//! normal, which the sphere through the corners matches exactly, so the paper's metric
//! (which measures vertices' normals and curvatures against an ellipsoid's) fitted each face
//! of a cube with that sphere, and the cube decoded as a ball at any density but its own.
//!
//! At a vertex where the normals of two faces around it are more than [`CREASE_ANGLE`] apart,
//! each corner gets instead the values of its own side, as renderers split normals by a
//! crease angle:
//! - its normal: the angle-weighted normal of the faces around the vertex within
//!   [`CREASE_ANGLE`] of its own face;
//! - its mean curvature: the mean of the vertex's estimates at the other corners of those
//!   faces that are not on a crease themselves (the side's curvature next to the crease),
//!   else 0 (a side that is all crease, such as a cube's face, is flat).
//!
//! Every other corner keeps its vertex's values; a mesh without creases has no crease
//! corners at all (nothing is stored).
//!
//! The segmentation measures a *facet* (a flat region of a few triangles, every corner on a
//! crease: a cube's triangle) with its sides' values and fits it with its plane
//! ([`crate::segment::proxy::EllipsoidMetric`], [`crate::ellipsoid::fit::fit_tangent_sphere`]).
//! Everywhere else it keeps the vertices' values: measured with their sides' values
//! throughout, a region that spans a crease (fandisk at K = 12 has to round some of its
//! edges) asked one ellipsoid for both sides' normals at the same points, and fandisk's
//! files decoded 0.06–0.3 % of the diagonal further from their source (RMS at K = 8 to 32),
//! and every file of the small shared meshes changed.

use super::Mesh;
use glam::DVec3;

/// How far apart, in radians, the normals of two faces around a vertex may turn before the
/// vertex counts as on a sharp crease (45°).
pub const CREASE_ANGLE: f64 = std::f64::consts::FRAC_PI_4;

/// Most faces around a vertex that is looked at for a crease: a fan of more is taken as
/// smooth (the test compares every pair of faces around the vertex).
pub const MAX_CREASE_FAN: usize = 64;

/// Marks a corner that keeps its vertex's values.
const NONE: u32 = u32::MAX;

/// One crease corner's side (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CreaseSide {
    /// Unit normal of the corner's side.
    pub normal: DVec3,
    /// Mean curvature of the corner's side, in the sign convention of
    /// [`super::curvature`].
    pub curvature: f64,
}

/// The crease corners of a mesh (see the module documentation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CreaseCorners {
    /// Per face, per corner: the index of its side in `sides`, or [`NONE`]. Empty when the
    /// mesh has no crease.
    of_face: Vec<[u32; 3]>,
    sides: Vec<CreaseSide>,
}

impl CreaseCorners {
    /// The crease corners of `mesh`, whose vertices have the mean curvatures `curvatures`.
    pub fn of_mesh(mesh: &Mesh, curvatures: &[f64]) -> CreaseCorners {
        let faces = mesh.faces();
        let topology = mesh.topology();
        let face_normals = mesh.face_normals();
        let normal_of = |f: u32| face_normals.get(f as usize).copied().unwrap_or(DVec3::ZERO);
        let cos = CREASE_ANGLE.cos();
        // Whether two faces, both with a normal (degenerate faces have none), are on one
        // side (`true`: within the crease angle) or on both sides of a crease (`false`).
        let sides = |f: u32, g: u32| -> Option<bool> {
            let (a, b) = (normal_of(f), normal_of(g));
            (a != DVec3::ZERO && b != DVec3::ZERO).then(|| a.dot(b) >= cos)
        };
        let same_side = |f: u32, g: u32| sides(f, g) == Some(true);
        let on_crease: Vec<bool> = (0..mesh.vertex_count() as u32)
            .map(|v| {
                let around = topology.faces_around(v);
                around.len() <= MAX_CREASE_FAN
                    && around.iter().enumerate().any(|(i, &f)| {
                        around
                            .iter()
                            .skip(i + 1)
                            .any(|&g| sides(f, g) == Some(false))
                    })
            })
            .collect();
        if !on_crease.contains(&true) {
            return CreaseCorners::default();
        }
        let mut out = CreaseCorners {
            of_face: vec![[NONE; 3]; faces.len()],
            sides: Vec::new(),
        };
        for (v, _) in on_crease.iter().enumerate().filter(|(_, &c)| c) {
            let v = v as u32;
            let around = topology.faces_around(v);
            for &f in around {
                let Some(k) = faces
                    .get(f as usize)
                    .and_then(|t| t.iter().position(|&u| u == v))
                else {
                    continue;
                };
                let mut normal = DVec3::ZERO;
                let (mut curvature, mut count) = (0.0, 0usize);
                for &g in around {
                    let other = normal_of(g);
                    let Some(tri) = faces.get(g as usize) else {
                        continue;
                    };
                    let Some(j) = tri.iter().position(|&u| u == v) else {
                        continue;
                    };
                    if !same_side(f, g) {
                        continue;
                    }
                    // The face's angle at the vertex (faces index the mesh: `Mesh::new`).
                    let p = mesh.corners(g as usize);
                    let angle = (p[(j + 1) % 3] - p[j]).angle_between(p[(j + 2) % 3] - p[j]);
                    if angle.is_finite() {
                        normal += angle * other;
                    }
                    for &u in tri.iter().filter(|&&u| u != v) {
                        let smooth = !on_crease.get(u as usize).copied().unwrap_or(true);
                        match curvatures.get(u as usize) {
                            Some(&h) if smooth && h.is_finite() => {
                                curvature += h;
                                count += 1;
                            }
                            _ => {}
                        }
                    }
                }
                let curvature = if count > 0 {
                    curvature / count as f64
                } else {
                    0.0
                };
                if let (Some(normal), Some(slot)) = (
                    normal.try_normalize(),
                    out.of_face.get_mut(f as usize).and_then(|c| c.get_mut(k)),
                ) {
                    *slot = out.sides.len() as u32;
                    out.sides.push(CreaseSide { normal, curvature });
                }
            }
        }
        out
    }

    /// The side of corner `k` (0..3) of face `f`, where that corner is on a crease.
    pub fn side(&self, f: u32, k: usize) -> Option<CreaseSide> {
        let i = *self.of_face.get(f as usize)?.get(k)?;
        self.sides.get(i as usize).copied()
    }

    /// How many corners are on a crease.
    pub fn len(&self) -> usize {
        self.sides.len()
    }

    /// Whether no corner is on a crease.
    pub fn is_empty(&self) -> bool {
        self.sides.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::curvature::mean_curvature;
    use crate::synth::shapes::{capsule, cube, cylinder, icosphere, torus};

    #[test]
    fn a_cubes_corners_on_its_edges_take_their_own_faces_side() {
        for subdivisions in [1, 3] {
            let mesh = cube(2.0, subdivisions);
            let creases = CreaseCorners::of_mesh(&mesh, &mean_curvature(&mesh));
            let on_edge = |p: DVec3| p.abs().to_array().iter().filter(|&&c| c > 0.999).count() >= 2;
            for (f, tri) in mesh.faces().iter().enumerate() {
                for (k, &v) in tri.iter().enumerate() {
                    let side = creases.side(f as u32, k);
                    if !on_edge(mesh.positions()[v as usize]) {
                        assert_eq!(side, None, "face {f} corner {k}");
                        continue;
                    }
                    let side = side.expect("a corner on the cube's edge is on a crease");
                    assert!(side.normal.dot(mesh.face_normal(f)) > 1.0 - 1e-12);
                    // Its side is flat: every vertex next to it on its face is either on
                    // an edge too or flat.
                    assert!(side.curvature.abs() < 1e-9, "{}", side.curvature);
                }
            }
        }
    }

    #[test]
    fn smooth_surfaces_have_no_crease_corners() {
        for mesh in [
            icosphere(1.0, 3),
            torus(1.0, 0.3, 48, 24),
            capsule(0.5, 1.0, 20),
            cylinder(1.0, 2.0, 24, 4),
        ] {
            let creases = CreaseCorners::of_mesh(&mesh, &mean_curvature(&mesh));
            assert!(creases.is_empty(), "{} crease corners", creases.len());
        }
    }

    /// A tube closed by two flat caps: at the rims the tube's corners take the tube's normal
    /// and curvature (1/2r, read off the next ring), the caps' corners the caps'.
    #[test]
    fn a_side_takes_the_normal_and_curvature_next_to_the_crease() {
        let (n, m, radius) = (32usize, 4usize, 1.0);
        let tube = cylinder(radius, 2.0, n as u32, m as u32);
        let mut positions = tube.positions().to_vec();
        let mut faces = tube.faces().to_vec();
        let (bottom, top) = (positions.len() as u32, positions.len() as u32 + 1);
        positions.push(DVec3::new(0.0, 0.0, -1.0));
        positions.push(DVec3::new(0.0, 0.0, 1.0));
        for i in 0..n {
            let j = (i + 1) % n;
            faces.push([bottom, j as u32, i as u32]);
            faces.push([top, (m * n + i) as u32, (m * n + j) as u32]);
        }
        let mesh = Mesh::new(positions, faces).unwrap();
        assert!(mesh.topology().is_closed() && mesh.topology().is_consistently_oriented());
        let creases = CreaseCorners::of_mesh(&mesh, &mean_curvature(&mesh));
        let rim = |v: u32| (v as usize) < n || (m * n..(m + 1) * n).contains(&(v as usize));
        let mut counted = [0, 0];
        for (f, tri) in mesh.faces().iter().enumerate() {
            let own = mesh.face_normal(f);
            for (k, &v) in tri.iter().enumerate() {
                let side = creases.side(f as u32, k);
                if !rim(v) {
                    assert_eq!(side, None);
                    continue;
                }
                let side = side.expect("a rim corner is on a crease");
                let p = mesh.positions()[v as usize];
                if own.z.abs() > 0.99 {
                    // A cap's corner.
                    assert!(side.normal.dot(own) > 1.0 - 1e-12);
                    assert!(side.curvature.abs() < 1e-9, "{}", side.curvature);
                    counted[0] += 1;
                } else {
                    let radial = DVec3::new(p.x, p.y, 0.0).normalize();
                    assert!(side.normal.dot(radial) > 2f64.to_radians().cos());
                    let expected = 0.5 / radius;
                    assert!(
                        (side.curvature - expected).abs() < 0.05 * expected,
                        "{}",
                        side.curvature
                    );
                    counted[1] += 1;
                }
            }
        }
        assert_eq!(counted, [4 * n, 6 * n]);
    }
}
