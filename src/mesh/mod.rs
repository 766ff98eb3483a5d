//! The indexed triangle mesh and what can be measured on it.
//!
//! A [`Mesh`] holds vertex positions and triangles and, computed once at construction, its
//! [`Topology`]: vertex–face incidence, face adjacency across manifold edges, border and
//! non-manifold edges, boundary loops and edge-connected components. Geometric quantities
//! (normals, areas, volume) are computed on demand; mean curvature lives in [`curvature`].
//!
//! Invariants kept by [`Mesh::new`]: every index is in range, no triangle repeats a vertex,
//! every coordinate is finite, and there are fewer than 2³² vertices and faces.

pub mod crease;
pub mod curvature;
mod topology;

pub(crate) use topology::orientation_flips;
pub use topology::Topology;
pub(crate) use topology::{find_root, join_sets};

use glam::DVec3;
use serde::Serialize;

/// Why a set of positions and triangles is not a valid [`Mesh`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// A coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFiniteCoordinate {
        /// Index of the offending vertex.
        vertex: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {index}, but there are only {vertex_count} vertices")]
    IndexOutOfRange {
        /// Index of the offending face.
        face: usize,
        /// The index it holds.
        index: u32,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// A triangle uses the same vertex twice.
    #[error("face {face} repeats a vertex")]
    RepeatedVertex {
        /// Index of the offending face.
        face: usize,
    },
    /// More vertices or faces than 32-bit indices can address.
    #[error("{what}: {count} is more than the {max} a mesh can index")]
    TooLarge {
        /// "vertices" or "faces".
        what: &'static str,
        /// How many were given.
        count: usize,
        /// The most allowed.
        max: usize,
    },
}

/// An axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Aabb {
    /// Smallest coordinates.
    pub min: DVec3,
    /// Largest coordinates.
    pub max: DVec3,
}

impl Aabb {
    /// The box around `points`; `None` when there are none.
    pub fn from_points(points: &[DVec3]) -> Option<Aabb> {
        let first = *points.first()?;
        let (min, max) = points
            .iter()
            .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)));
        Some(Aabb { min, max })
    }

    /// The box around both boxes.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Length of the diagonal: the unit in which ellip reports distances.
    pub fn diagonal(&self) -> f64 {
        (self.max - self.min).length()
    }

    /// Centre of the box.
    pub fn center(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }

    /// Edge lengths along x, y and z.
    pub fn size(&self) -> DVec3 {
        self.max - self.min
    }
}

/// An indexed triangle mesh with its topology.
#[derive(Debug, Clone)]
pub struct Mesh {
    positions: Vec<DVec3>,
    faces: Vec<[u32; 3]>,
    topology: Topology,
}

/// Largest number of vertices or faces: indices are `u32`, and `u32::MAX` is reserved.
pub const MAX_ELEMENTS: usize = u32::MAX as usize - 1;

impl Mesh {
    /// Builds a mesh, checking the invariants listed in the [module docs](self), and computes
    /// its topology. Zero-area triangles are accepted (the importer removes them; analysis
    /// copes with them).
    pub fn new(positions: Vec<DVec3>, faces: Vec<[u32; 3]>) -> Result<Mesh, MeshError> {
        if positions.len() > MAX_ELEMENTS {
            return Err(MeshError::TooLarge {
                what: "vertices",
                count: positions.len(),
                max: MAX_ELEMENTS,
            });
        }
        if faces.len() > MAX_ELEMENTS {
            return Err(MeshError::TooLarge {
                what: "faces",
                count: faces.len(),
                max: MAX_ELEMENTS,
            });
        }
        if let Some(vertex) = positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFiniteCoordinate { vertex });
        }
        let n = positions.len();
        for (face, f) in faces.iter().enumerate() {
            if let Some(&index) = f.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::IndexOutOfRange {
                    face,
                    index,
                    vertex_count: n,
                });
            }
            if f[0] == f[1] || f[1] == f[2] || f[2] == f[0] {
                return Err(MeshError::RepeatedVertex { face });
            }
        }
        let topology = Topology::build(n, &faces);
        Ok(Mesh {
            positions,
            faces,
            topology,
        })
    }

    /// Vertex positions.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub fn faces(&self) -> &[[u32; 3]] {
        &self.faces
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn face_count(&self) -> usize {
        self.faces.len()
    }

    /// Connectivity: incidence, adjacency, borders, components.
    pub fn topology(&self) -> &Topology {
        &self.topology
    }

    /// Takes the mesh apart into positions and faces.
    pub fn into_parts(self) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        (self.positions, self.faces)
    }

    /// The three corner positions of face `f`.
    pub fn corners(&self, f: usize) -> [DVec3; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Twice the area times the unit normal of face `f` (right-hand rule on its corners).
    pub fn face_area_vector(&self, f: usize) -> DVec3 {
        let [a, b, c] = self.corners(f);
        (b - a).cross(c - a)
    }

    /// Area of face `f`.
    pub fn face_area(&self, f: usize) -> f64 {
        0.5 * self.face_area_vector(f).length()
    }

    /// Unit normal of face `f`; zero for a degenerate face.
    pub fn face_normal(&self, f: usize) -> DVec3 {
        self.face_area_vector(f).normalize_or_zero()
    }

    /// Areas of all faces.
    pub fn face_areas(&self) -> Vec<f64> {
        (0..self.faces.len()).map(|f| self.face_area(f)).collect()
    }

    /// Unit normals of all faces (zero for degenerate faces).
    pub fn face_normals(&self) -> Vec<DVec3> {
        (0..self.faces.len()).map(|f| self.face_normal(f)).collect()
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.faces.len()).map(|f| self.face_area(f)).sum()
    }

    /// Centroid of face `f`.
    pub fn face_centroid(&self, f: usize) -> DVec3 {
        let [a, b, c] = self.corners(f);
        (a + b + c) / 3.0
    }

    /// Angle-weighted vertex normals; see [`angle_weighted_normals`].
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        angle_weighted_normals(&self.positions, &self.faces)
    }

    /// Bounding box; `None` for a mesh without vertices.
    pub fn bounding_box(&self) -> Option<Aabb> {
        Aabb::from_points(&self.positions)
    }

    /// Mean length of the mesh's edges, each edge counted once (0 for an empty mesh). This is
    /// the paper's ā, used in the default weight α = 1/ā² (section 2).
    pub fn average_edge_length(&self) -> f64 {
        let mut sum = 0.0;
        let mut count = 0usize;
        self.topology.for_each_edge(&self.faces, |a, b| {
            sum += (self.positions[a as usize] - self.positions[b as usize]).length();
            count += 1;
        });
        if count == 0 {
            0.0
        } else {
            sum / count as f64
        }
    }

    /// Signed enclosed volume by the divergence theorem, positive when the faces point
    /// outward. Only meaningful for a closed mesh; see [`Mesh::volume`].
    pub fn signed_volume(&self) -> f64 {
        // Measured from the box centre to keep the sum well conditioned far from the origin.
        let origin = self.bounding_box().map_or(DVec3::ZERO, |b| b.center());
        self.faces
            .iter()
            .map(|&[a, b, c]| {
                let pa = self.positions[a as usize] - origin;
                let pb = self.positions[b as usize] - origin;
                let pc = self.positions[c as usize] - origin;
                pa.dot(pb.cross(pc))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Enclosed volume of a closed mesh (every edge shared by exactly two faces); `None` for
    /// an open or non-manifold one.
    pub fn volume(&self) -> Option<f64> {
        self.topology.is_closed().then(|| self.signed_volume())
    }

    /// Genus of a manifold mesh, summed over its components: from the Euler characteristic
    /// χ = V − E + F = 2C − 2g − B with C components and B boundary loops. `None` when the
    /// mesh is not manifold or not orientable, where the formula does not apply.
    pub fn genus(&self) -> Option<u64> {
        let t = &self.topology;
        if !t.is_manifold() || !t.is_orientable() {
            return None;
        }
        let v = t.referenced_vertex_count() as i64;
        let e = t.edge_count() as i64;
        let f = self.faces.len() as i64;
        let chi = v - e + f;
        let twice_genus = 2 * t.component_count() as i64 - chi - t.boundary_loops().len() as i64;
        (twice_genus >= 0 && twice_genus % 2 == 0).then_some(twice_genus as u64 / 2)
    }

    /// A copy with every position mapped through `map`; topology is reused.
    pub fn map_positions(&self, map: impl Fn(DVec3) -> DVec3) -> Result<Mesh, MeshError> {
        let positions: Vec<DVec3> = self.positions.iter().map(|&p| map(p)).collect();
        if let Some(vertex) = positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFiniteCoordinate { vertex });
        }
        Ok(Mesh {
            positions,
            faces: self.faces.clone(),
            topology: self.topology.clone(),
        })
    }
}

/// Angle-weighted vertex normals (Thürmer & Wüthrich 1998) of any positions and triangles:
/// each incident face's unit normal weighted by the corner angle at the vertex, falling back
/// to the area-weighted normal and then to +z, so always unit length. Triangles with an index
/// out of range are ignored. [`Mesh::vertex_normals`] is this on a mesh.
pub fn angle_weighted_normals(positions: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let mut angle_weighted = vec![DVec3::ZERO; positions.len()];
    let mut area_weighted = vec![DVec3::ZERO; positions.len()];
    for triangle in triangles {
        let corner = |k: usize| positions.get(triangle[k] as usize).copied();
        let (Some(a), Some(b), Some(c)) = (corner(0), corner(1), corner(2)) else {
            continue;
        };
        let p = [a, b, c];
        let area_vector = (b - a).cross(c - a);
        let normal = area_vector.normalize_or_zero();
        for (k, &v) in triangle.iter().enumerate() {
            let angle = (p[(k + 1) % 3] - p[k]).angle_between(p[(k + 2) % 3] - p[k]);
            if let (Some(aw), Some(arw)) = (
                angle_weighted.get_mut(v as usize),
                area_weighted.get_mut(v as usize),
            ) {
                if angle.is_finite() {
                    *aw += angle * normal;
                }
                *arw += area_vector;
            }
        }
    }
    angle_weighted
        .iter()
        .zip(&area_weighted)
        .map(|(a, b)| {
            a.try_normalize()
                .or_else(|| b.try_normalize())
                .unwrap_or(DVec3::Z)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regular tetrahedron with outward faces.
    pub(crate) fn tetrahedron() -> Mesh {
        let p = vec![
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ];
        let f = vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
        Mesh::new(p, f).unwrap()
    }

    #[test]
    fn tetrahedron_measures() {
        let m = tetrahedron();
        // Edge length 2√2; volume a³/(6√2) = 8/3.
        assert!((m.average_edge_length() - 8f64.sqrt()).abs() < 1e-12);
        assert!((m.volume().unwrap() - 8.0 / 3.0).abs() < 1e-12);
        assert_eq!(m.genus(), Some(0));
        for n in m.vertex_normals() {
            assert!((n.length() - 1.0).abs() < 1e-12);
        }
        // Vertex 0 sits on the (1,1,1) diagonal: its normal points along it.
        let n0 = m.vertex_normals()[0];
        assert!((n0 - DVec3::ONE.normalize()).length() < 1e-12);
    }

    #[test]
    fn rejects_invalid_input() {
        let p = vec![DVec3::ZERO, DVec3::X, DVec3::Y];
        assert!(matches!(
            Mesh::new(p.clone(), vec![[0, 1, 3]]),
            Err(MeshError::IndexOutOfRange { index: 3, .. })
        ));
        assert!(matches!(
            Mesh::new(p.clone(), vec![[0, 1, 1]]),
            Err(MeshError::RepeatedVertex { face: 0 })
        ));
        let mut bad = p;
        bad[1].x = f64::NAN;
        assert!(matches!(
            Mesh::new(bad, vec![[0, 1, 2]]),
            Err(MeshError::NonFiniteCoordinate { vertex: 1 })
        ));
    }

    #[test]
    fn open_triangle_has_no_volume() {
        let m = Mesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]]).unwrap();
        assert_eq!(m.volume(), None);
        assert_eq!(m.genus(), Some(0));
        assert!((m.area() - 0.5).abs() < 1e-15);
        assert_eq!(m.face_normal(0), DVec3::Z);
    }

    #[test]
    fn scaling_scales_measures() {
        let m = tetrahedron();
        let s = m.map_positions(|p| p * 10.0).unwrap();
        assert!((s.volume().unwrap() / m.volume().unwrap() - 1000.0).abs() < 1e-9);
        assert!((s.average_edge_length() / m.average_edge_length() - 10.0).abs() < 1e-12);
    }
}
