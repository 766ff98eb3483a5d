//! Connectivity of a triangle mesh, computed once when the mesh is built.
//!
//! Terms, used the same way across ellip:
//! - the *edge* `i` of face `f` runs from corner `i` to corner `i + 1 (mod 3)`;
//! - a *manifold* edge has exactly two faces, a *border* edge one, a *non-manifold* edge
//!   three or more. Faces are adjacent only across manifold edges: a non-manifold edge is kept
//!   as a border between all its faces;
//! - a *component* is a maximal set of faces connected through manifold edges;
//! - a vertex is *non-manifold* when its faces form more than one fan.

use std::collections::VecDeque;

/// Marks "no face" in the adjacency table.
const NONE: u32 = u32::MAX;

/// Bits of the per-face edge flags: bit `i` (0..3) set when this half-edge is the one that
/// represents its edge (each edge is counted once); bit `3 + i` set when edge `i` is a border.
const CANONICAL: u8 = 0b000_111;
const BORDER_SHIFT: u8 = 3;

/// Connectivity of a mesh. Built by [`Mesh::new`](super::Mesh::new).
#[derive(Debug, Clone)]
pub struct Topology {
    vertex_face_offsets: Vec<u32>,
    vertex_faces: Vec<u32>,
    neighbors: Vec<[u32; 3]>,
    /// Per face, two bits per edge: the neighbour's edge that is the same edge.
    neighbor_edges: Vec<u8>,
    edge_flags: Vec<u8>,
    edge_count: usize,
    border_edge_count: usize,
    nonmanifold_edge_count: usize,
    inconsistent_edge_count: usize,
    nonmanifold_vertex_count: usize,
    referenced_vertex_count: usize,
    face_component: Vec<u32>,
    component_count: usize,
    orientable: bool,
    boundary_loops: Vec<Vec<u32>>,
}

impl Topology {
    pub(crate) fn build(vertex_count: usize, faces: &[[u32; 3]]) -> Topology {
        let (vertex_face_offsets, vertex_faces) = build_vertex_faces(vertex_count, faces);
        let mut t = Topology {
            vertex_face_offsets,
            vertex_faces,
            neighbors: vec![[NONE; 3]; faces.len()],
            neighbor_edges: vec![0; faces.len()],
            edge_flags: vec![0; faces.len()],
            edge_count: 0,
            border_edge_count: 0,
            nonmanifold_edge_count: 0,
            inconsistent_edge_count: 0,
            nonmanifold_vertex_count: 0,
            referenced_vertex_count: 0,
            face_component: Vec::new(),
            component_count: 0,
            orientable: true,
            boundary_loops: Vec::new(),
        };
        t.link_edges(faces);
        t.count_vertices(faces);
        t.label_components(faces);
        t.boundary_loops = t.trace_boundary_loops(faces);
        t
    }

    /// Classifies every edge and links faces across manifold edges.
    ///
    /// Each edge is found at its lower endpoint: the half-edges of the faces around a vertex
    /// that lead to a higher vertex, sorted by that vertex, come in groups of one per edge
    /// (each face around the vertex is read once, not once per edge).
    fn link_edges(&mut self, faces: &[[u32; 3]]) {
        // (other end, face, edge of the face).
        let mut ends: Vec<(u32, u32, u8)> = Vec::new();
        for a in 0..self.vertex_face_offsets.len().saturating_sub(1) {
            let a = a as u32;
            ends.clear();
            for &g in self.faces_around(a) {
                let face = &faces[g as usize];
                let c = corner_of(face, a);
                // Edge c runs a → face[c + 1]; edge c + 2 runs face[c + 2] → a.
                for e in [c, (c + 2) % 3] {
                    let b = if e == c { face[(c + 1) % 3] } else { face[e] };
                    if b > a {
                        ends.push((b, g, e as u8));
                    }
                }
            }
            ends.sort_unstable();
            for group in ends.chunk_by(|x, y| x.0 == y.0) {
                // Sorted by face: the first is the lowest, which represents the edge.
                let (_, lowest, e) = group[0];
                self.edge_flags[lowest as usize] |= 1 << e;
                self.edge_count += 1;
                match *group {
                    [(_, f, i)] => {
                        self.border_edge_count += 1;
                        self.edge_flags[f as usize] |= 1 << (BORDER_SHIFT + i);
                    }
                    [(_, f, i), (_, g, j)] => {
                        let (f, g, i, j) = (f as usize, g as usize, i as usize, j as usize);
                        self.neighbors[f][i] = g as u32;
                        self.neighbors[g][j] = f as u32;
                        self.neighbor_edges[f] |= (j as u8) << (2 * i);
                        self.neighbor_edges[g] |= (i as u8) << (2 * j);
                        self.inconsistent_edge_count += usize::from(faces[f][i] == faces[g][j]);
                    }
                    _ => self.nonmanifold_edge_count += 1,
                }
            }
        }
    }

    /// Counts referenced and non-manifold vertices (more than one fan of faces).
    ///
    /// The faces around a vertex are linked across its edges that are manifold, each face
    /// to at most two others (across its two edges at the vertex): they form paths and
    /// cycles, one per fan. So the vertex has one fan when the walk from its first face,
    /// one way round and then the other, reaches all of them.
    fn count_vertices(&mut self, faces: &[[u32; 3]]) {
        let (mut referenced, mut nonmanifold) = (0, 0);
        for v in 0..self.vertex_face_offsets.len() - 1 {
            let around = self.faces_around(v as u32);
            let Some(&first) = around.first() else {
                continue;
            };
            referenced += 1;
            let mut reached = 1;
            'ways: for way in 0..2 {
                let (mut previous, mut f) = (NONE, first);
                while reached < around.len() {
                    let c = corner_of(&faces[f as usize], v as u32);
                    // The two edges of f that touch v: c→c+1 and c+2→c.
                    let across = [c, (c + 2) % 3].map(|edge| self.neighbors[f as usize][edge]);
                    let next = if previous == NONE {
                        across[way]
                    } else if across[0] == previous {
                        across[1]
                    } else {
                        across[0]
                    };
                    if next == NONE {
                        break;
                    }
                    if next == first {
                        // Round the whole fan: the other way finds nothing new.
                        break 'ways;
                    }
                    reached += 1;
                    (previous, f) = (f, next);
                }
            }
            if reached < around.len() {
                nonmanifold += 1;
            }
        }
        self.referenced_vertex_count = referenced;
        self.nonmanifold_vertex_count = nonmanifold;
    }

    /// Labels edge-connected components and checks whether each can be oriented consistently.
    fn label_components(&mut self, faces: &[[u32; 3]]) {
        let mut component = vec![NONE; faces.len()];
        // Whether a face would have to be flipped to agree with its component's first face.
        let mut flipped = vec![false; faces.len()];
        let mut queue = VecDeque::new();
        let mut count = 0u32;
        for seed in 0..faces.len() {
            if component[seed] != NONE {
                continue;
            }
            component[seed] = count;
            queue.push_back(seed);
            while let Some(f) = queue.pop_front() {
                for i in 0..3 {
                    let g = self.neighbors[f][i];
                    if g == NONE {
                        continue;
                    }
                    let g = g as usize;
                    let j = self.neighbor_edge(f, i);
                    let agrees = faces[g][j] == faces[f][(i + 1) % 3]; // g runs the edge b→a
                    let want = flipped[f] ^ !agrees;
                    if component[g] == NONE {
                        component[g] = count;
                        flipped[g] = want;
                        queue.push_back(g);
                    } else if flipped[g] != want {
                        self.orientable = false;
                    }
                }
            }
            count += 1;
        }
        self.face_component = component;
        self.component_count = count as usize;
    }

    /// Walks the border edges into closed loops of vertices. Each loop follows the direction of
    /// its faces' edges where they agree, so the region's faces lie on its left.
    fn trace_boundary_loops(&self, faces: &[[u32; 3]]) -> Vec<Vec<u32>> {
        let n = self.vertex_face_offsets.len() - 1;
        // Border half-edges, and for each vertex the ones that touch it.
        let mut edges: Vec<[u32; 2]> = Vec::with_capacity(self.border_edge_count);
        for (f, face) in faces.iter().enumerate() {
            for i in 0..3 {
                if self.is_border_edge(f, i) {
                    edges.push([face[i], face[(i + 1) % 3]]);
                }
            }
        }
        let mut offsets = vec![0u32; n + 1];
        for e in &edges {
            offsets[e[0] as usize + 1] += 1;
            offsets[e[1] as usize + 1] += 1;
        }
        for v in 0..n {
            offsets[v + 1] += offsets[v];
        }
        let mut cursor = offsets.clone();
        let mut touching = vec![0u32; edges.len() * 2];
        for (k, e) in edges.iter().enumerate() {
            for &v in e {
                touching[cursor[v as usize] as usize] = k as u32;
                cursor[v as usize] += 1;
            }
        }
        let mut used = vec![false; edges.len()];
        let mut loops = Vec::new();
        for start in 0..edges.len() {
            if used[start] {
                continue;
            }
            used[start] = true;
            let origin = edges[start][0];
            let mut current = edges[start][1];
            let mut chain = vec![origin];
            while current != origin {
                chain.push(current);
                let around = &touching
                    [offsets[current as usize] as usize..offsets[current as usize + 1] as usize];
                // Prefer an edge leaving `current` in its faces' direction.
                let next = around
                    .iter()
                    .copied()
                    .filter(|&k| !used[k as usize])
                    .min_by_key(|&k| edges[k as usize][0] != current);
                let Some(k) = next else { break };
                used[k as usize] = true;
                let [a, b] = edges[k as usize];
                current = if a == current { b } else { a };
            }
            loops.push(chain);
        }
        loops
    }

    /// Faces incident to vertex `v`, in increasing order.
    pub fn faces_around(&self, v: u32) -> &[u32] {
        let lo = self.vertex_face_offsets[v as usize] as usize;
        let hi = self.vertex_face_offsets[v as usize + 1] as usize;
        &self.vertex_faces[lo..hi]
    }

    /// The face across edge `i` of face `f`, if that edge is manifold.
    pub fn neighbor(&self, f: usize, i: usize) -> Option<u32> {
        let g = self.neighbors[f][i];
        (g != NONE).then_some(g)
    }

    /// The face across edge `i` of face `f` and that face's edge that is the same edge, if
    /// the edge is manifold.
    pub fn across(&self, f: usize, i: usize) -> Option<(u32, usize)> {
        self.neighbor(f, i).map(|g| (g, self.neighbor_edge(f, i)))
    }

    /// Which edge of the face across edge `i` of face `f` is that edge (0 when there is
    /// none).
    fn neighbor_edge(&self, f: usize, i: usize) -> usize {
        usize::from((self.neighbor_edges[f] >> (2 * i)) & 0b11)
    }

    /// The faces across the three edges of face `f` (manifold edges only).
    pub fn neighbors(&self, f: usize) -> impl Iterator<Item = u32> + '_ {
        self.neighbors[f].iter().copied().filter(|&g| g != NONE)
    }

    /// Whether edge `i` of face `f` has no other face.
    pub fn is_border_edge(&self, f: usize, i: usize) -> bool {
        self.edge_flags[f] & (1 << (BORDER_SHIFT + i as u8)) != 0
    }

    /// Whether vertex `v` touches an edge that is not manifold (a border or a non-manifold
    /// edge): there its one-ring is not a closed disc, and curvature estimates do not hold.
    pub fn is_open_vertex(&self, faces: &[[u32; 3]], v: u32) -> bool {
        self.faces_around(v).iter().any(|&f| {
            let f = f as usize;
            let c = corner_of(&faces[f], v);
            self.neighbors[f][c] == NONE || self.neighbors[f][(c + 2) % 3] == NONE
        })
    }

    /// Calls `visit(a, b)` once for every edge of the mesh.
    pub fn for_each_edge(&self, faces: &[[u32; 3]], mut visit: impl FnMut(u32, u32)) {
        for (f, face) in faces.iter().enumerate() {
            let flags = self.edge_flags[f] & CANONICAL;
            for i in 0..3 {
                if flags & (1 << i) != 0 {
                    visit(face[i], face[(i + 1) % 3]);
                }
            }
        }
    }

    /// Number of distinct edges.
    pub fn edge_count(&self) -> usize {
        self.edge_count
    }

    /// Edges with exactly one face.
    pub fn border_edge_count(&self) -> usize {
        self.border_edge_count
    }

    /// Edges with three or more faces.
    pub fn nonmanifold_edge_count(&self) -> usize {
        self.nonmanifold_edge_count
    }

    /// Manifold edges whose two faces run them the same way (an orientation flip).
    pub fn inconsistent_edge_count(&self) -> usize {
        self.inconsistent_edge_count
    }

    /// Vertices whose faces form more than one fan.
    pub fn nonmanifold_vertex_count(&self) -> usize {
        self.nonmanifold_vertex_count
    }

    /// Vertices used by at least one face.
    pub fn referenced_vertex_count(&self) -> usize {
        self.referenced_vertex_count
    }

    /// Component label of face `f`, in `0..component_count()`.
    pub fn component_of(&self, f: usize) -> u32 {
        self.face_component[f]
    }

    /// Component label of every face.
    pub fn face_components(&self) -> &[u32] {
        &self.face_component
    }

    /// Number of edge-connected components.
    pub fn component_count(&self) -> usize {
        self.component_count
    }

    /// Loops of border edges, as vertex cycles (the last vertex connects to the first).
    pub fn boundary_loops(&self) -> &[Vec<u32>] {
        &self.boundary_loops
    }

    /// Every edge has exactly two faces (and there is at least one face).
    pub fn is_closed(&self) -> bool {
        !self.face_component.is_empty()
            && self.border_edge_count == 0
            && self.nonmanifold_edge_count == 0
    }

    /// No edge has more than two faces and every vertex has a single fan.
    pub fn is_manifold(&self) -> bool {
        self.nonmanifold_edge_count == 0 && self.nonmanifold_vertex_count == 0
    }

    /// Every component can be oriented consistently (no Möbius-like flip).
    pub fn is_orientable(&self) -> bool {
        self.orientable
    }

    /// Consistently oriented: orientable and no manifold edge is run the same way twice.
    pub fn is_consistently_oriented(&self) -> bool {
        self.orientable && self.inconsistent_edge_count == 0
    }
}

/// Vertex → incident faces, as compressed rows (offsets, then face indices in order).
fn build_vertex_faces(vertex_count: usize, faces: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
    let mut offsets = vec![0u32; vertex_count + 1];
    for face in faces {
        for &v in face {
            offsets[v as usize + 1] += 1;
        }
    }
    for v in 0..vertex_count {
        offsets[v + 1] += offsets[v];
    }
    let mut cursor = offsets.clone();
    let mut incident = vec![0u32; faces.len() * 3];
    for (f, face) in faces.iter().enumerate() {
        for &v in face {
            incident[cursor[v as usize] as usize] = f as u32;
            cursor[v as usize] += 1;
        }
    }
    (offsets, incident)
}

/// The representative of `v`'s set in a union–find forest over `0..parent.len()` (a root is
/// its own parent), halving the path on the way.
pub(crate) fn find_root(parent: &mut [u32], mut v: u32) -> u32 {
    while parent[v as usize] != v {
        let up = parent[parent[v as usize] as usize];
        parent[v as usize] = up;
        v = up;
    }
    v
}

/// Joins the sets of `a` and `b` under the lower of their two roots, so that each set's
/// root is its smallest member.
pub(crate) fn join_sets(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find_root(parent, a), find_root(parent, b));
    parent[ra.max(rb) as usize] = ra.min(rb);
}

/// Corner of `face` holding vertex `v` (which it must contain).
fn corner_of(face: &[u32; 3], v: u32) -> usize {
    face.iter()
        .position(|&x| x == v)
        .expect("face contains vertex")
}

/// Per-face flags saying which faces to flip so that each component is consistently
/// oriented, keeping the orientation of each component's lowest-numbered face. Faces in a
/// non-orientable component are left as the breadth-first walk first reaches them.
pub(crate) fn orientation_flips(topology: &Topology, faces: &[[u32; 3]]) -> Vec<bool> {
    let mut visited = vec![false; faces.len()];
    let mut flip = vec![false; faces.len()];
    let mut queue = VecDeque::new();
    for seed in 0..faces.len() {
        if visited[seed] {
            continue;
        }
        visited[seed] = true;
        queue.push_back(seed);
        while let Some(f) = queue.pop_front() {
            for i in 0..3 {
                let Some((g, j)) = topology.across(f, i) else {
                    continue;
                };
                let g = g as usize;
                if visited[g] {
                    continue;
                }
                let agrees = faces[g][j] == faces[f][(i + 1) % 3];
                visited[g] = true;
                flip[g] = flip[f] ^ !agrees;
                queue.push_back(g);
            }
        }
    }
    flip
}

#[cfg(test)]
mod tests {
    use super::*;

    fn topo(vertex_count: usize, faces: &[[u32; 3]]) -> Topology {
        Topology::build(vertex_count, faces)
    }

    const TETRA: [[u32; 3]; 4] = [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];

    #[test]
    fn closed_tetrahedron() {
        let t = topo(4, &TETRA);
        assert_eq!(t.edge_count(), 6);
        assert!(t.is_closed() && t.is_manifold() && t.is_consistently_oriented());
        assert_eq!(t.component_count(), 1);
        assert!(t.boundary_loops().is_empty());
        for f in 0..4 {
            assert_eq!(t.neighbors(f).count(), 3);
        }
    }

    #[test]
    fn across_names_the_same_edge_in_the_neighbour() {
        // The tetrahedron, and the same with one face flipped (edges run the same way).
        let mut flipped = TETRA;
        flipped[3] = [1, 2, 3];
        for faces in [TETRA, flipped] {
            let t = topo(4, &faces);
            for (f, face) in faces.iter().enumerate() {
                for i in 0..3 {
                    let (g, j) = t.across(f, i).unwrap();
                    let g = g as usize;
                    assert_ne!(g, f);
                    let mine = [face[i], face[(i + 1) % 3]];
                    let theirs = [faces[g][j], faces[g][(j + 1) % 3]];
                    assert!(
                        theirs == mine || theirs == [mine[1], mine[0]],
                        "{f}.{i}: {mine:?} vs {g}.{j}: {theirs:?}"
                    );
                    assert_eq!(t.across(g, j), Some((f as u32, i)));
                }
            }
        }
        // No neighbour across a border.
        let t = topo(4, &[[0, 1, 2], [0, 2, 3]]);
        assert_eq!(t.across(0, 0), None);
        assert_eq!(t.across(0, 2).map(|(g, _)| g), Some(1));
    }

    #[test]
    fn open_square_has_one_loop_in_face_direction() {
        // Two triangles of a unit square, counter-clockwise.
        let faces = [[0, 1, 2], [0, 2, 3]];
        let t = topo(4, &faces);
        assert_eq!(t.edge_count(), 5);
        assert_eq!(t.border_edge_count(), 4);
        assert!(!t.is_closed() && t.is_manifold());
        assert_eq!(t.boundary_loops().len(), 1);
        let l = &t.boundary_loops()[0];
        assert_eq!(l.len(), 4);
        // The loop runs 0→1→2→3 (face direction), starting anywhere.
        let k = l.iter().position(|&v| v == 0).unwrap();
        let rotated: Vec<u32> = (0..4).map(|i| l[(k + i) % 4]).collect();
        assert_eq!(rotated, vec![0, 1, 2, 3]);
    }

    #[test]
    fn three_faces_on_one_edge_are_not_neighbours() {
        // Edge 0–1 shared by three triangles.
        let faces = [[0, 1, 2], [1, 0, 3], [0, 1, 4]];
        let t = topo(5, &faces);
        assert_eq!(t.nonmanifold_edge_count(), 1);
        assert!(!t.is_manifold() && !t.is_closed());
        assert_eq!(t.component_count(), 3);
        assert_eq!(t.neighbor(0, 0), None);
    }

    #[test]
    fn bowtie_vertex_is_nonmanifold() {
        // Two triangles meeting only at vertex 0.
        let faces = [[0, 1, 2], [0, 3, 4]];
        let t = topo(5, &faces);
        assert_eq!(t.nonmanifold_vertex_count(), 1);
        assert_eq!(t.nonmanifold_edge_count(), 0);
        assert!(!t.is_manifold());
        assert_eq!(t.component_count(), 2);
    }

    /// Non-manifold vertices by brute force: per vertex, the faces around it joined
    /// (union–find) across its edges that have exactly two faces; more than one group is
    /// more than one fan.
    fn nonmanifold_vertices_by_brute_force(vertex_count: usize, faces: &[[u32; 3]]) -> usize {
        let edge_faces = |a: u32, b: u32| {
            faces
                .iter()
                .filter(|f| f.contains(&a) && f.contains(&b))
                .count()
        };
        (0..vertex_count as u32)
            .filter(|&v| {
                let around: Vec<usize> = (0..faces.len())
                    .filter(|&f| faces[f].contains(&v))
                    .collect();
                let mut group: Vec<usize> = (0..around.len()).collect();
                fn root(group: &mut [usize], mut i: usize) -> usize {
                    while group[i] != i {
                        i = group[i];
                    }
                    i
                }
                for i in 0..around.len() {
                    for j in 0..i {
                        let shared: Vec<u32> = faces[around[i]]
                            .iter()
                            .copied()
                            .filter(|&w| w != v && faces[around[j]].contains(&w))
                            .collect();
                        if shared.iter().any(|&w| edge_faces(v, w) == 2) {
                            let (a, b) = (root(&mut group, i), root(&mut group, j));
                            group[a] = b;
                        }
                    }
                }
                let roots: std::collections::BTreeSet<usize> =
                    (0..around.len()).map(|i| root(&mut group, i)).collect();
                roots.len() > 1
            })
            .count()
    }

    /// Non-manifold vertices agree with brute force on a closed torus grid with faces taken
    /// away (fans broken into several) and fins added (edges with three faces).
    #[test]
    fn nonmanifold_vertices_agree_with_brute_force() {
        let mut rng = crate::rng::SplitMix64::new(17);
        let n = 6u32;
        let index = |i: u32, j: u32| (i % n) * n + (j % n);
        for round in 0..40 {
            let mut faces = Vec::new();
            for i in 0..n {
                for j in 0..n {
                    let (a, b, c, d) = (
                        index(i, j),
                        index(i + 1, j),
                        index(i + 1, j + 1),
                        index(i, j + 1),
                    );
                    faces.push([a, b, c]);
                    faces.push([a, c, d]);
                }
            }
            let keep = 0.3 + 0.7 * (round as f64 / 40.0);
            faces.retain(|_| rng.next_f64() < keep);
            let mut vertex_count = n * n;
            for _ in 0..round % 4 {
                if let Some(&[a, b, _]) = faces.get(rng.next_u64() as usize % faces.len().max(1)) {
                    faces.push([b, a, vertex_count]);
                    faces.push([a, b, vertex_count + 1]);
                    vertex_count += 2;
                }
            }
            let t = topo(vertex_count as usize, &faces);
            assert_eq!(
                t.nonmanifold_vertex_count(),
                nonmanifold_vertices_by_brute_force(vertex_count as usize, &faces),
                "round {round}"
            );
        }
    }

    #[test]
    fn flipped_face_is_found_and_fixed() {
        let mut faces = TETRA;
        faces[3] = [1, 2, 3];
        let t = topo(4, &faces);
        assert_eq!(t.inconsistent_edge_count(), 3);
        assert!(t.is_orientable() && !t.is_consistently_oriented());
        let flips = orientation_flips(&t, &faces);
        assert_eq!(flips, vec![false, false, false, true]);
    }

    #[test]
    fn unreferenced_vertices_are_not_counted() {
        let t = topo(10, &TETRA);
        assert_eq!(t.referenced_vertex_count(), 4);
    }
}
