//! Repair: from a parser's [`Soup`] to a valid [`Mesh`], saying what changed.
//!
//! In order: weld vertices with equal (or, on request, nearby) positions, so that split
//! vertices from STL or glTF seams become shared and connectivity exists; drop faces that
//! collapse (a repeated vertex after welding, or zero area) and faces that repeat another
//! face's vertices; drop vertices no face uses; then make each component's faces agree in
//! orientation and turn inside-out closed components outward. Non-manifold edges are kept,
//! and act as borders between their faces (see [`Topology`](crate::mesh::Topology)).

use super::{ImportOptions, Soup};
use crate::mesh::{orientation_flips, Mesh};
use glam::DVec3;
use serde::Serialize;
use std::collections::{HashMap, HashSet};

/// How vertices are welded on import.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Weld {
    /// Join vertices whose coordinates are bit-for-bit equal (−0 equals +0).
    #[default]
    Exact,
    /// Join each vertex to the first earlier vertex within this distance (in model units).
    Within(f64),
}

/// What [`repair`] changed. All counts are of elements of the file as read.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct RepairReport {
    /// Polygons of more than three vertices fanned into triangles.
    pub triangulated_polygons: u64,
    /// Vertices joined into an earlier vertex at the same position.
    pub welded_vertices: u64,
    /// Faces dropped because they repeat a vertex or have zero area.
    pub degenerate_faces: u64,
    /// Faces dropped because an earlier face has the same three vertices.
    pub duplicate_faces: u64,
    /// Vertices dropped because no face uses them.
    pub unreferenced_vertices: u64,
    /// Faces flipped so that each component is consistently oriented.
    pub flipped_faces: u64,
    /// Closed components turned right side out (they enclosed negative volume).
    pub reoriented_components: u64,
    /// Edges with three or more faces, kept as borders between those faces.
    pub nonmanifold_edges: u64,
    /// Vertices whose faces form more than one fan, kept.
    pub nonmanifold_vertices: u64,
}

impl RepairReport {
    /// Whether the file needed no change at all (triangulation aside).
    pub fn is_clean(&self) -> bool {
        self.welded_vertices == 0
            && self.degenerate_faces == 0
            && self.duplicate_faces == 0
            && self.unreferenced_vertices == 0
            && self.flipped_faces == 0
            && self.reoriented_components == 0
            && self.nonmanifold_edges == 0
            && self.nonmanifold_vertices == 0
    }

    /// One short phrase per thing done, for people (e.g. "welded 12 vertices").
    pub fn describe(&self) -> Vec<String> {
        let items = [
            (self.triangulated_polygons, "triangulated", "polygons"),
            (self.welded_vertices, "welded", "vertices"),
            (self.degenerate_faces, "dropped", "degenerate faces"),
            (self.duplicate_faces, "dropped", "duplicate faces"),
            (self.unreferenced_vertices, "dropped", "unreferenced vertices"),
            (self.flipped_faces, "flipped", "faces to a consistent orientation"),
            (self.reoriented_components, "turned outward", "inside-out components"),
            (self.nonmanifold_edges, "kept", "non-manifold edges as borders"),
            (self.nonmanifold_vertices, "kept", "non-manifold vertices"),
        ];
        items
            .iter()
            .filter(|(n, _, _)| *n > 0)
            .map(|(n, verb, what)| format!("{verb} {n} {what}"))
            .collect()
    }
}

/// Why repair could not produce a mesh.
#[derive(Debug, Clone, PartialEq)]
pub enum RepairFailure {
    /// Every face was degenerate or a duplicate (or there were none).
    NoTriangles {
        /// Faces removed on the way.
        removed: u64,
    },
}

/// Turns a soup into a valid mesh (see the [module docs](self)).
pub fn repair(soup: Soup, options: &ImportOptions) -> Result<(Mesh, RepairReport), RepairFailure> {
    let mut report = RepairReport {
        triangulated_polygons: soup.triangulated_polygons,
        ..RepairReport::default()
    };
    let Soup {
        positions,
        triangles,
        ..
    } = soup;

    let (positions, remap) = weld(&positions, options.weld);
    report.welded_vertices = (remap.len() - positions.len()) as u64;

    let mut faces = Vec::with_capacity(triangles.len());
    let mut seen = HashSet::with_capacity(triangles.len());
    for t in &triangles {
        let Some(f) = remap_face(t, &remap) else {
            report.degenerate_faces += 1;
            continue;
        };
        if is_degenerate(&positions, f) {
            report.degenerate_faces += 1;
            continue;
        }
        let mut key = f;
        key.sort_unstable();
        if !seen.insert(key) {
            report.duplicate_faces += 1;
            continue;
        }
        faces.push(f);
    }
    drop(seen);
    if faces.is_empty() {
        return Err(RepairFailure::NoTriangles {
            removed: report.degenerate_faces + report.duplicate_faces,
        });
    }

    let (positions, faces, dropped) = drop_unreferenced(positions, faces);
    report.unreferenced_vertices = dropped;

    let mut mesh = Mesh::new(positions, faces).expect("repair keeps indices in range");
    if !options.keep_orientation {
        let (oriented, flipped, reoriented) = orient_outward(mesh);
        mesh = oriented;
        report.flipped_faces = flipped;
        report.reoriented_components = reoriented;
    }
    report.nonmanifold_edges = mesh.topology().nonmanifold_edge_count() as u64;
    report.nonmanifold_vertices = mesh.topology().nonmanifold_vertex_count() as u64;
    Ok((mesh, report))
}

/// Welds vertices; returns the kept positions and, for every input vertex, its new index.
fn weld(positions: &[DVec3], weld: Weld) -> (Vec<DVec3>, Vec<u32>) {
    let mut kept = Vec::with_capacity(positions.len());
    let mut remap = Vec::with_capacity(positions.len());
    match weld {
        Weld::Exact => {
            let mut index: HashMap<[u64; 3], u32> = HashMap::with_capacity(positions.len());
            for &p in positions {
                // +0.0 and −0.0 are the same position.
                let key = (p + DVec3::ZERO).to_array().map(f64::to_bits);
                let next = kept.len() as u32;
                let id = *index.entry(key).or_insert(next);
                if id == next {
                    kept.push(p);
                }
                remap.push(id);
            }
        }
        Weld::Within(tolerance) => {
            let tolerance = tolerance.max(f64::MIN_POSITIVE);
            let cell_of = |p: DVec3| (p / tolerance).floor().to_array().map(|c| c as i64);
            let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
            for &p in positions {
                let c = cell_of(p);
                let mut found = None;
                'search: for dx in -1..=1i64 {
                    for dy in -1..=1i64 {
                        for dz in -1..=1i64 {
                            let key = [
                                c[0].saturating_add(dx),
                                c[1].saturating_add(dy),
                                c[2].saturating_add(dz),
                            ];
                            let Some(ids) = grid.get(&key) else { continue };
                            for &id in ids {
                                if kept[id as usize].distance(p) <= tolerance
                                    && found.is_none_or(|f| id < f)
                                {
                                    found = Some(id);
                                }
                            }
                            if found.is_some() && dx == 1 && dy == 1 && dz == 1 {
                                break 'search;
                            }
                        }
                    }
                }
                let id = found.unwrap_or_else(|| {
                    let id = kept.len() as u32;
                    kept.push(p);
                    grid.entry(c).or_default().push(id);
                    id
                });
                remap.push(id);
            }
        }
    }
    (kept, remap)
}

/// The face with welded indices; `None` if it now repeats a vertex (or, defensively, if an
/// index is out of range).
fn remap_face(t: &[u32; 3], remap: &[u32]) -> Option<[u32; 3]> {
    let f = [
        *remap.get(t[0] as usize)?,
        *remap.get(t[1] as usize)?,
        *remap.get(t[2] as usize)?,
    ];
    (f[0] != f[1] && f[1] != f[2] && f[2] != f[0]).then_some(f)
}

/// Zero area up to rounding: the cross product is negligible against the longest edge.
fn is_degenerate(positions: &[DVec3], f: [u32; 3]) -> bool {
    let [a, b, c] = f.map(|i| positions[i as usize]);
    let longest = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    (b - a).cross(c - a).length() <= 1e-12 * longest
}

/// Drops vertices no face uses and renumbers the rest in order.
fn drop_unreferenced(
    positions: Vec<DVec3>,
    mut faces: Vec<[u32; 3]>,
) -> (Vec<DVec3>, Vec<[u32; 3]>, u64) {
    let mut used = vec![false; positions.len()];
    for f in &faces {
        for &v in f {
            used[v as usize] = true;
        }
    }
    let mut new_index = vec![u32::MAX; positions.len()];
    let mut kept = Vec::with_capacity(positions.len());
    for (v, &p) in positions.iter().enumerate() {
        if used[v] {
            new_index[v] = kept.len() as u32;
            kept.push(p);
        }
    }
    let dropped = (positions.len() - kept.len()) as u64;
    if dropped > 0 {
        for f in &mut faces {
            *f = f.map(|v| new_index[v as usize]);
        }
    }
    (kept, faces, dropped)
}

/// Makes every component consistently oriented, then flips closed components that enclose
/// negative volume. Returns the mesh, the faces flipped for consistency, and the number of
/// components turned outward.
fn orient_outward(mesh: Mesh) -> (Mesh, u64, u64) {
    let t = mesh.topology();
    let mut flip = if t.is_consistently_oriented() {
        vec![false; mesh.face_count()]
    } else {
        orientation_flips(t, mesh.faces())
    };
    let flipped = flip.iter().filter(|&&f| f).count() as u64;

    let components = t.component_count();
    let mut closed = vec![true; components];
    let mut volume = vec![0.0f64; components];
    let origin = mesh.bounding_box().map_or(DVec3::ZERO, |b| b.center());
    for (f, face) in mesh.faces().iter().enumerate() {
        let c = t.component_of(f) as usize;
        if (0..3).any(|i| t.neighbor(f, i).is_none()) {
            closed[c] = false;
        }
        let [a, b, d] = face.map(|v| mesh.positions()[v as usize] - origin);
        let v = a.dot(b.cross(d));
        volume[c] += if flip[f] { -v } else { v };
    }
    let inside_out: Vec<bool> = (0..components)
        .map(|c| closed[c] && t.is_orientable() && volume[c] < 0.0)
        .collect();
    let reoriented = inside_out.iter().filter(|&&x| x).count() as u64;
    if flipped == 0 && reoriented == 0 {
        return (mesh, 0, 0);
    }
    for (f, fl) in flip.iter_mut().enumerate() {
        *fl ^= inside_out[t.component_of(f) as usize];
    }
    let (positions, mut faces) = mesh.into_parts();
    for (face, &fl) in faces.iter_mut().zip(&flip) {
        if fl {
            face.swap(1, 2);
        }
    }
    let mesh = Mesh::new(positions, faces).expect("flipping keeps the mesh valid");
    (mesh, flipped, reoriented)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn soup(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Soup {
        Soup {
            positions: positions.iter().map(|&p| DVec3::from_array(p)).collect(),
            triangles: triangles.to_vec(),
            ..Soup::default()
        }
    }

    /// A tetrahedron given as four separate triangles (12 vertices), as STL stores it.
    fn split_tetrahedron(inside_out: bool) -> Soup {
        let v = [[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0]];
        let faces = [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for f in faces {
            let base = positions.len() as u32;
            let f = if inside_out { [f[0], f[2], f[1]] } else { f };
            positions.extend(f.map(|i| v[i]));
            triangles.push([base, base + 1, base + 2]);
        }
        soup(&positions, &triangles)
    }

    #[test]
    fn welds_split_vertices_into_a_closed_mesh() {
        let (mesh, report) = repair(split_tetrahedron(false), &ImportOptions::default()).unwrap();
        assert_eq!(mesh.vertex_count(), 4);
        assert_eq!(report.welded_vertices, 8);
        assert!(mesh.topology().is_closed());
        assert!(mesh.volume().unwrap() > 0.0);
        assert_eq!(report.reoriented_components, 0);
    }

    #[test]
    fn turns_inside_out_meshes_outward_unless_asked_not_to() {
        let (mesh, report) = repair(split_tetrahedron(true), &ImportOptions::default()).unwrap();
        assert_eq!(report.reoriented_components, 1);
        assert!((mesh.volume().unwrap() - 8.0 / 3.0).abs() < 1e-12);
        let keep = ImportOptions {
            keep_orientation: true,
            ..ImportOptions::default()
        };
        let (mesh, report) = repair(split_tetrahedron(true), &keep).unwrap();
        assert_eq!(report.reoriented_components, 0);
        assert!(mesh.volume().unwrap() < 0.0);
    }

    #[test]
    fn drops_degenerate_duplicate_and_unreferenced() {
        let s = soup(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [2.0, 0.0, 0.0], // collinear with 0 and 1
                [9.0, 9.0, 9.0], // unused
            ],
            &[[0, 1, 2], [2, 1, 0], [0, 1, 3], [0, 0, 2], [1, 2, 0]],
        );
        let (mesh, report) = repair(s, &ImportOptions::default()).unwrap();
        assert_eq!(mesh.face_count(), 1);
        assert_eq!(report.duplicate_faces, 2);
        assert_eq!(report.degenerate_faces, 2);
        assert_eq!(report.unreferenced_vertices, 2);
        assert!(!report.is_clean());
        assert_eq!(report.describe().len(), 3);
    }

    #[test]
    fn nothing_left_is_a_failure() {
        let s = soup(&[[0.0; 3], [1.0, 0.0, 0.0]], &[[0, 1, 1]]);
        assert_eq!(
            repair(s, &ImportOptions::default()).unwrap_err(),
            RepairFailure::NoTriangles { removed: 1 }
        );
    }

    #[test]
    fn tolerance_weld_joins_nearby_vertices() {
        let mut s = split_tetrahedron(false);
        for (i, p) in s.positions.iter_mut().enumerate() {
            *p += DVec3::splat(1e-7 * (i % 3) as f64);
        }
        let (exact, _) = repair(s.clone(), &ImportOptions::default()).unwrap();
        assert!(exact.vertex_count() > 4);
        let near = ImportOptions {
            weld: Weld::Within(1e-5),
            ..ImportOptions::default()
        };
        let (mesh, report) = repair(s, &near).unwrap();
        assert_eq!(mesh.vertex_count(), 4);
        assert_eq!(report.welded_vertices, 8);
        assert!(mesh.topology().is_closed());
    }

    #[test]
    fn inconsistent_faces_are_flipped() {
        let mut s = split_tetrahedron(false);
        s.triangles[3].swap(1, 2);
        let (mesh, report) = repair(s, &ImportOptions::default()).unwrap();
        assert_eq!(report.flipped_faces, 1);
        assert!(mesh.topology().is_consistently_oriented());
        assert!(mesh.volume().unwrap() > 0.0);
    }
}
