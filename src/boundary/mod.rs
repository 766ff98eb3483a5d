//! Boundaries between regions: the graph of arcs and junctions where regions meet, each
//! region's oriented boundary cycles, and their smoothing (Simari & Singh 2005, section 4.1;
//! the cycles are what the decoder of section 5.1 projects stereographically).
//!
//! Terms: a *boundary vertex* lies on an edge whose two faces are in different regions, or on
//! a mesh border edge. A *junction* is a boundary vertex where three or more regions meet, or
//! where a region boundary meets the mesh border (more generally: where the set of "sides"
//! around it is not exactly two). An *arc* is a chain of boundary edges between two junctions
//! (or a closed loop with no junction), bordering exactly two regions, or one region and the
//! mesh border. A region's *cycles* are closed sequences of arcs, each walked with the region
//! on its left.
//!
//! # How the mesh's irregularities are read
//!
//! - Faces are neighbours only across manifold edges that both run consistently (opposite
//!   directions). Every other face edge — a mesh border, a non-manifold edge, an edge whose two
//!   faces run it the same way (an orientation flip) — is a *border side* of its face: an
//!   edge shared by three faces is the end of three border arcs, one per face.
//! - So a boundary *edge unit* is either a manifold edge between two regions (one unit, used by
//!   one arc and by the cycles of both regions) or a border side of one face (one unit, one
//!   arc, one region's cycles).
//! - A vertex is a *continuation* vertex when exactly one edge unit enters it and one leaves it
//!   (in its left region's direction) and both have the same two sides; every other boundary
//!   vertex is a junction. So a region that touches itself at a vertex (a pinch: four edge
//!   units, sides {A, B}) makes a junction there, as does a non-manifold vertex where border
//!   loops cross.
//! - Cycles are traced by turning around each vertex through the region's own faces: at a
//!   pinch the region's boundary leaves along the edge of the same fan it arrived by, so cycles
//!   never cross and each is the boundary of the region with its pinches cut apart.
//! - Two regions that touch only at a vertex (across a non-manifold vertex, with no boundary
//!   edge there) share no arc.
//!
//! # Which cycle is outer
//!
//! A *piece* of a region is a set of its faces connected across manifold edges (the
//! segmentation keeps regions connected, so normally a region is one piece). Each piece that
//! has cycles has exactly one outer cycle; the others are holes. Removing the piece splits the
//! rest of the surface into parts, where the surface is completed across each mesh border
//! loop by the missing surface it stands for (counted as the flat patch spanning the loop:
//! the length of its vector area). Each cycle borders some of those parts, through the
//! regions or border loops on the other side of its arcs. **The outer cycle is the one whose
//! bordering parts have the largest total area** — the cycle that bounds the largest part of
//! the (completed) surface not in the piece. That is where the decoder (section 5.1) wants
//! the pole of its stereographic projection: the piece then lies inside the outer cycle's
//! image and outside every hole's, as compact as it can be. So a region with a small hole
//! has the big side as outer, a region of an open mesh with a small scan hole keeps its other
//! boundary as outer, and a region spanning a flat open sheet around a few small regions has
//! the sheet's border as outer. Ties (e.g. the two cycles of a band around a torus, which
//! border the same part) go to the longer cycle (sum of edge lengths), then to the one found
//! first. Computed for all pieces at once in time linear in the number of pieces and arcs,
//! from the articulation structure (Hopcroft & Tarjan 1973) of the graph whose nodes are
//! pieces and border loops and whose edges are arcs.

mod smooth;

pub use smooth::{
    smooth_boundaries, smooth_boundaries_holding, SmoothOptions, DEFAULT_EPSILON,
    DEFAULT_ITERATIONS,
};

use crate::mesh::{find_root, join_sets, Mesh};
use glam::DVec3;
use serde::Serialize;

/// Marks "none" in the per-half-edge and per-piece tables.
const NONE: u32 = u32::MAX;

/// What lies on the other side of an arc.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum Side {
    /// Another region.
    Region(u32),
    /// The mesh border (or a non-manifold edge, which is a border between its faces).
    Border,
}

impl Side {
    /// The region on this side, if any.
    pub fn region(self) -> Option<u32> {
        match self {
            Side::Region(r) => Some(r),
            Side::Border => None,
        }
    }
}

/// A chain of boundary edges between two junctions, or a closed loop.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Arc {
    /// Mesh vertex indices in order. For an arc between junctions the first and last are
    /// junctions (the same one when the arc leaves and returns to it); for a closed loop the
    /// first vertex is not repeated at the end.
    pub vertices: Vec<u32>,
    /// Whether the arc is a closed loop without junctions.
    pub closed: bool,
    /// The region on the arc's left when walked from first to last vertex (outward normals
    /// up). Between two regions it is the lower-numbered one.
    pub left: u32,
    /// What is on its right.
    pub right: Side,
}

/// An arc used forward or backward in a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ArcRef {
    /// Index into [`BoundaryGraph::arcs`].
    pub arc: u32,
    /// Walked from last vertex to first.
    pub reversed: bool,
}

/// One closed boundary of a region, with the region on its left.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Cycle {
    /// The arcs in order: each ends where the next begins, the last where the first begins.
    pub arcs: Vec<ArcRef>,
    /// Whether this is the outer boundary of its piece of the region (exactly one per piece
    /// that has cycles — so one per region, for a connected region; the others are holes).
    /// See the [module docs](self) for the rule.
    pub outer: bool,
}

/// The boundary graph of a segmentation.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct BoundaryGraph {
    /// Every boundary vertex (mesh vertex indices, increasing).
    pub vertices: Vec<u32>,
    /// The junctions (mesh vertex indices, increasing).
    pub junctions: Vec<u32>,
    /// The arcs.
    pub arcs: Vec<Arc>,
    /// For each region, its boundary cycles (empty for a region without boundary, e.g. a
    /// closed component covered by one region). Within a region, the outer cycle of each
    /// piece comes before that piece's holes.
    pub cycles: Vec<Vec<Cycle>>,
}

impl BoundaryGraph {
    /// The mesh vertices of `cycle` in walking order (region on the left), each once: every
    /// arc's vertices in its direction of use, without repeating the vertex where consecutive
    /// arcs meet.
    pub fn cycle_vertices(&self, cycle: &Cycle) -> Vec<u32> {
        let mut out = Vec::new();
        for r in &cycle.arcs {
            let Some(arc) = self.arcs.get(r.arc as usize) else {
                continue;
            };
            if arc.closed {
                if r.reversed {
                    out.extend(arc.vertices.iter().rev());
                } else {
                    out.extend(&arc.vertices);
                }
            } else if r.reversed {
                out.extend(arc.vertices.iter().rev().skip(1));
            } else {
                out.extend(arc.vertices.iter().skip(1));
            }
        }
        out
    }
}

/// Why the boundary graph could not be built, or the boundaries not smoothed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum BoundaryError {
    /// `labels` has the wrong length or a label out of range.
    #[error("labels do not match the mesh: {what}")]
    BadLabels {
        /// What is wrong.
        what: String,
    },
    /// The mesh has more face sides (3 per face) than `u32` indices can name.
    #[error("the mesh has {faces} faces; boundaries handle at most {max}")]
    TooLarge {
        /// Faces in the mesh.
        faces: usize,
        /// The most accepted.
        max: usize,
    },
    /// Smoothing options out of range.
    #[error("bad smoothing options: {what}")]
    BadOptions {
        /// What is wrong.
        what: String,
    },
}

/// Most faces [`extract_boundaries`] accepts: three sides per face must fit in a `u32`.
pub const MAX_FACES: usize = (u32::MAX as usize - 1) / 3;

/// Extracts the boundary graph of a labelling of `mesh`'s faces into `region_count` regions
/// (at most one per face; regions without faces are allowed and get no cycles).
///
/// Runs in time and memory linear in the mesh size: a few tables over the faces' sides, one
/// over the vertices, and one walk of every boundary side. See the [module docs](self) for
/// how non-manifold edges, pinches and the outer cycle are handled.
pub fn extract_boundaries(
    mesh: &Mesh,
    labels: &[u32],
    region_count: usize,
) -> Result<BoundaryGraph, BoundaryError> {
    let faces = mesh.faces();
    if labels.len() != faces.len() {
        return Err(BoundaryError::BadLabels {
            what: format!("{} labels for {} faces", labels.len(), faces.len()),
        });
    }
    if region_count > faces.len().max(1) {
        return Err(BoundaryError::BadLabels {
            what: format!(
                "{region_count} regions for {} faces (regions beyond one per face are empty)",
                faces.len()
            ),
        });
    }
    if let Some((f, &l)) = labels
        .iter()
        .enumerate()
        .find(|&(_, &l)| l as usize >= region_count)
    {
        return Err(BoundaryError::BadLabels {
            what: format!("face {f} has label {l}, expected below {region_count}"),
        });
    }
    if faces.len() > MAX_FACES {
        return Err(BoundaryError::TooLarge {
            faces: faces.len(),
            max: MAX_FACES,
        });
    }
    let sides = Sides::build(mesh, labels);
    let vertex_info = VertexInfo::build(mesh.vertex_count(), faces, &sides, labels);
    let (mut arcs, arc_of) = trace_arcs(faces, &sides, labels, &vertex_info);
    let pieces = label_pieces(mesh, &sides, labels);
    measure_arcs(mesh, &sides, &pieces, &mut arcs);
    let cycles = trace_cycles(&sides, labels, &arcs, &arc_of, &pieces, region_count);
    let vertices = (0..vertex_info.state.len() as u32)
        .filter(|&v| vertex_info.state[v as usize] != 0)
        .collect();
    let junctions = (0..vertex_info.state.len() as u32)
        .filter(|&v| vertex_info.is_junction(v))
        .collect();
    Ok(BoundaryGraph {
        vertices,
        junctions,
        arcs: arcs.into_iter().map(|a| a.arc).collect(),
        cycles,
    })
}

/// Per face side `h = 3f + i` (edge `i` of face `f`): its twin across a consistent manifold
/// edge, whether it is a boundary side, and (for boundary sides) the next boundary side of the
/// same region around its end vertex.
struct Sides {
    twin: Vec<u32>,
    next: Vec<u32>,
}

impl Sides {
    fn build(mesh: &Mesh, labels: &[u32]) -> Sides {
        let faces = mesh.faces();
        let topology = mesh.topology();
        let mut twin = vec![NONE; faces.len() * 3];
        for (f, face) in faces.iter().enumerate() {
            for i in 0..3 {
                let Some(g) = topology.neighbor(f, i) else {
                    continue;
                };
                let (a, b) = (face[i], face[(i + 1) % 3]);
                let Some(other) = faces.get(g as usize) else {
                    continue;
                };
                // Consistent: g runs the edge b→a.
                if let Some(j) = (0..3).find(|&j| other[j] == b && other[(j + 1) % 3] == a) {
                    twin[3 * f + i] = 3 * g + j as u32;
                }
            }
        }
        let mut sides = Sides {
            twin,
            next: vec![NONE; faces.len() * 3],
        };
        for h in 0..faces.len() * 3 {
            if sides.is_boundary(h as u32, labels) {
                let end = faces[h / 3][(h % 3 + 1) % 3];
                let guard = topology.faces_around(end).len() + 1;
                sides.next[h] = sides.turn(h as u32, labels, guard);
            }
        }
        sides
    }

    /// Whether side `h` borders another region or nothing.
    fn is_boundary(&self, h: u32, labels: &[u32]) -> bool {
        let t = self.twin[h as usize];
        t == NONE || labels[(t / 3) as usize] != labels[(h / 3) as usize]
    }

    /// The boundary side leaving the end vertex of boundary side `h`, found by turning around
    /// that vertex through the faces of `h`'s region (across consistent manifold edges only).
    fn turn(&self, h: u32, labels: &[u32], guard: usize) -> u32 {
        let mut e = next_in_face(h);
        for _ in 0..guard {
            if self.is_boundary(e, labels) {
                return e;
            }
            e = next_in_face(self.twin[e as usize]);
        }
        NONE
    }

    /// The region-side of an edge unit: side `h` itself when its face is the unit's left
    /// region, else its twin. Only for boundary sides.
    fn is_canonical(&self, h: u32, labels: &[u32]) -> bool {
        let t = self.twin[h as usize];
        t == NONE || labels[(h / 3) as usize] < labels[(t / 3) as usize]
    }
}

/// The side after `h` in its face.
fn next_in_face(h: u32) -> u32 {
    h - h % 3 + (h % 3 + 1) % 3
}

/// Endpoints of side `h`.
fn side_ends(faces: &[[u32; 3]], h: u32) -> (u32, u32) {
    let face = faces[(h / 3) as usize];
    let i = (h % 3) as usize;
    (face[i], face[(i + 1) % 3])
}

/// The two sides of an edge unit: left region and right region (or [`NONE`] for border).
fn unit_key(sides: &Sides, labels: &[u32], h: u32) -> (u32, u32) {
    let t = sides.twin[h as usize];
    let right = if t == NONE {
        NONE
    } else {
        labels[(t / 3) as usize]
    };
    (labels[(h / 3) as usize], right)
}

/// Per vertex: how many edge units enter and leave it, and whether they all have one key.
struct VertexInfo {
    /// 0: no boundary; else bits: 1 seen, 2 keys differ.
    state: Vec<u8>,
    incoming: Vec<u8>,
    outgoing: Vec<u8>,
    key: Vec<(u32, u32)>,
}

impl VertexInfo {
    fn build(vertex_count: usize, faces: &[[u32; 3]], sides: &Sides, labels: &[u32]) -> Self {
        let mut info = VertexInfo {
            state: vec![0; vertex_count],
            incoming: vec![0; vertex_count],
            outgoing: vec![0; vertex_count],
            key: vec![(NONE, NONE); vertex_count],
        };
        for h in 0..faces.len() as u32 * 3 {
            if !sides.is_boundary(h, labels) || !sides.is_canonical(h, labels) {
                continue;
            }
            let key = unit_key(sides, labels, h);
            let (a, b) = side_ends(faces, h);
            info.outgoing[a as usize] = info.outgoing[a as usize].saturating_add(1);
            info.incoming[b as usize] = info.incoming[b as usize].saturating_add(1);
            for v in [a as usize, b as usize] {
                if info.state[v] == 0 {
                    info.state[v] = 1;
                    info.key[v] = key;
                } else if info.key[v] != key {
                    info.state[v] |= 2;
                }
            }
        }
        info
    }

    fn is_junction(&self, v: u32) -> bool {
        let v = v as usize;
        self.state[v] != 0
            && (self.state[v] & 2 != 0 || self.incoming[v] != 1 || self.outgoing[v] != 1)
    }
}

/// An arc under construction, with the sides it was traced from.
struct ArcBuild {
    arc: Arc,
    /// First and last canonical side (the left region's).
    first: u32,
    last: u32,
    /// Sum of edge lengths.
    length: f64,
    /// Piece on the left; piece on the right, or for a border arc its border node (see
    /// [`Pieces`]).
    left_piece: u32,
    right_node: u32,
}

/// Walks every edge unit into arcs: first those starting at junctions, then the closed loops.
fn trace_arcs(
    faces: &[[u32; 3]],
    sides: &Sides,
    labels: &[u32],
    info: &VertexInfo,
) -> (Vec<ArcBuild>, Vec<u32>) {
    let mut arc_of = vec![NONE; faces.len() * 3];
    let mut arcs: Vec<ArcBuild> = Vec::new();
    let canonical = |h: u32| sides.is_boundary(h, labels) && sides.is_canonical(h, labels);
    for from_junction in [true, false] {
        for start in 0..faces.len() as u32 * 3 {
            if !canonical(start) || arc_of[start as usize] != NONE {
                continue;
            }
            let (origin, _) = side_ends(faces, start);
            if info.is_junction(origin) != from_junction {
                continue;
            }
            let id = arcs.len() as u32;
            let key = unit_key(sides, labels, start);
            let mut vertices = vec![origin];
            let mut h = start;
            let mut closed = false;
            loop {
                arc_of[h as usize] = id;
                let (_, b) = side_ends(faces, h);
                if info.is_junction(b) {
                    break;
                }
                let n = sides.next[h as usize];
                if n == start {
                    closed = true;
                    break;
                }
                // At a continuation vertex the left region's next side is the other unit,
                // with the same key; anything else would be a bug, so stop rather than loop.
                if n == NONE
                    || !canonical(n)
                    || arc_of[n as usize] != NONE
                    || unit_key(sides, labels, n) != key
                {
                    break;
                }
                vertices.push(b);
                h = n;
            }
            if !closed {
                let (_, b) = side_ends(faces, h);
                vertices.push(b);
            }
            arcs.push(ArcBuild {
                arc: Arc {
                    vertices,
                    closed,
                    left: key.0,
                    right: if key.1 == NONE {
                        Side::Border
                    } else {
                        Side::Region(key.1)
                    },
                },
                first: start,
                last: h,
                length: 0.0,
                left_piece: NONE,
                right_node: NONE,
            });
        }
    }
    (arcs, arc_of)
}

/// Labels the pieces: faces of one region connected across consistent manifold edges.
fn label_pieces(mesh: &Mesh, sides: &Sides, labels: &[u32]) -> Pieces {
    let n = mesh.face_count();
    let mut piece = vec![NONE; n];
    let mut area: Vec<f64> = Vec::new();
    let mut stack = Vec::new();
    for seed in 0..n {
        if piece[seed] != NONE {
            continue;
        }
        let id = area.len() as u32;
        let mut total = 0.0;
        piece[seed] = id;
        stack.push(seed as u32);
        while let Some(f) = stack.pop() {
            total += mesh.face_area(f as usize);
            for i in 0..3 {
                let t = sides.twin[3 * f as usize + i];
                if t == NONE {
                    continue;
                }
                let g = (t / 3) as usize;
                if piece[g] == NONE && labels[g] == labels[f as usize] {
                    piece[g] = id;
                    stack.push(g as u32);
                }
            }
        }
        area.push(total);
    }
    let piece_count = area.len() as u32;
    // Border nodes: border sides grouped by shared vertices (union–find on the vertices).
    let faces = mesh.faces();
    let positions = mesh.positions();
    let mut root: Vec<u32> = (0..mesh.vertex_count() as u32).collect();
    let border_sides = || (0..faces.len() as u32 * 3).filter(|&h| sides.twin[h as usize] == NONE);
    for h in border_sides() {
        let (a, b) = side_ends(faces, h);
        join_sets(&mut root, a, b);
    }
    let mut node_of_root = vec![NONE; mesh.vertex_count()];
    let mut vector_area: Vec<DVec3> = Vec::new();
    let mut border_node = vec![NONE; faces.len() * 3];
    for h in border_sides() {
        let (a, b) = side_ends(faces, h);
        let r = find_root(&mut root, a) as usize;
        if node_of_root[r] == NONE {
            node_of_root[r] = piece_count + vector_area.len() as u32;
            vector_area.push(DVec3::ZERO);
        }
        let node = node_of_root[r];
        border_node[h as usize] = node;
        vector_area[(node - piece_count) as usize] +=
            positions[a as usize].cross(positions[b as usize]) / 2.0;
    }
    area.extend(vector_area.iter().map(|v| v.length()));
    Pieces {
        of_face: piece,
        border_node,
        area,
    }
}

/// The nodes of the graph that decides outer cycles: the pieces of regions, then one *border
/// node* per set of mesh border sides connected through their vertices (a border loop, or
/// loops that touch), standing for the surface missing beyond it.
struct Pieces {
    /// Piece of each face.
    of_face: Vec<u32>,
    /// Border node of each border side ([`NONE`] elsewhere).
    border_node: Vec<u32>,
    /// Area of each node: a piece's faces; for a border node, the length of its sides'
    /// vector area (the area of the flat patch that would close the loop, a lower bound on
    /// the missing surface's).
    area: Vec<f64>,
}

/// Fills in each arc's length and the pieces on its two sides.
fn measure_arcs(mesh: &Mesh, sides: &Sides, pieces: &Pieces, arcs: &mut [ArcBuild]) {
    let positions = mesh.positions();
    for a in arcs.iter_mut() {
        a.left_piece = pieces.of_face[(a.first / 3) as usize];
        let t = sides.twin[a.first as usize];
        a.right_node = if t == NONE {
            pieces.border_node[a.first as usize]
        } else {
            pieces.of_face[(t / 3) as usize]
        };
        let v = &a.arc.vertices;
        let distance = |x: u32, y: u32| positions[x as usize].distance(positions[y as usize]);
        a.length = v.windows(2).map(|w| distance(w[0], w[1])).sum();
        if a.arc.closed {
            if let (Some(&x), Some(&y)) = (v.first(), v.last()) {
                a.length += distance(x, y);
            }
        }
    }
}

/// A cycle found, with its region, piece and length.
struct FoundCycle {
    region: u32,
    piece: u32,
    length: f64,
    cycle: Cycle,
}

/// Chains arc uses into each region's cycles and marks each piece's outer cycle. A *use* is
/// `2·arc` (forward, by its left region) or `2·arc + 1` (backward, by its right region).
fn trace_cycles(
    sides: &Sides,
    labels: &[u32],
    arcs: &[ArcBuild],
    arc_of: &[u32],
    pieces: &Pieces,
    region_count: usize,
) -> Vec<Vec<Cycle>> {
    let use_count = arcs.len() * 2;
    let mut visited = vec![false; use_count];
    let mut found: Vec<FoundCycle> = Vec::new();
    for u0 in 0..use_count as u32 {
        let a0 = &arcs[(u0 / 2) as usize];
        let (region, piece) = match (u0 % 2, a0.arc.right) {
            (0, _) => (a0.arc.left, a0.left_piece),
            (_, Side::Region(r)) => (r, a0.right_node),
            (_, Side::Border) => continue,
        };
        if visited[u0 as usize] {
            continue;
        }
        let mut refs = Vec::new();
        let mut length = 0.0;
        let mut u = u0;
        loop {
            visited[u as usize] = true;
            let a = &arcs[(u / 2) as usize];
            refs.push(ArcRef {
                arc: u / 2,
                reversed: u % 2 == 1,
            });
            length += a.length;
            // The region's last side along this use, then the region's next side, which
            // starts the next use (its start vertex is a junction, or the arc is closed).
            let end = if u % 2 == 0 {
                a.last
            } else {
                sides.twin[a.first as usize]
            };
            let n = sides.next[end as usize];
            if n == NONE {
                break;
            }
            let next = if sides.is_canonical(n, labels) {
                arc_of[n as usize].wrapping_mul(2)
            } else {
                arc_of[sides.twin[n as usize] as usize]
                    .wrapping_mul(2)
                    .wrapping_add(1)
            };
            if next == u0 || next as usize >= use_count || visited[next as usize] {
                break;
            }
            u = next;
        }
        found.push(FoundCycle {
            region,
            piece,
            length,
            cycle: Cycle {
                arcs: refs,
                outer: false,
            },
        });
    }
    mark_outer(arcs, pieces, &mut found);
    let mut cycles: Vec<Vec<Cycle>> = vec![Vec::new(); region_count];
    // Within a region: pieces in order, each piece's outer cycle first.
    found.sort_by_key(|c| (c.region, c.piece, !c.cycle.outer));
    for c in found {
        if let Some(list) = cycles.get_mut(c.region as usize) {
            list.push(c.cycle);
        }
    }
    cycles
}

/// Marks the outer cycle of every piece: the one bordering the most area outside the piece,
/// then the longest, then the first found (see the [module docs](self)).
fn mark_outer(arcs: &[ArcBuild], pieces: &Pieces, found: &mut [FoundCycle]) {
    let piece_count = pieces.area.len();
    let mut count = vec![0u32; piece_count];
    for c in found.iter() {
        count[c.piece as usize] += 1;
    }
    let scores: Vec<f64> = if count.iter().any(|&n| n > 1) {
        let graph = PieceGraph::build(arcs, pieces);
        let mut keys = Vec::new();
        found
            .iter()
            .map(|c| {
                if count[c.piece as usize] < 2 {
                    return 0.0;
                }
                keys.clear();
                for r in &c.cycle.arcs {
                    let a = &arcs[r.arc as usize];
                    let other = if r.reversed {
                        a.left_piece
                    } else {
                        a.right_node
                    };
                    if other != NONE {
                        keys.push(graph.part_beyond(c.piece, other));
                    }
                }
                keys.sort_unstable();
                keys.dedup();
                keys.iter().map(|&k| graph.part_area(c.piece, k)).sum()
            })
            .collect()
    } else {
        vec![0.0; found.len()]
    };
    let mut best: Vec<Option<usize>> = vec![None; piece_count];
    for (k, c) in found.iter().enumerate() {
        let slot = &mut best[c.piece as usize];
        let better = match *slot {
            None => true,
            Some(b) => scores[k]
                .total_cmp(&scores[b])
                .then(c.length.total_cmp(&found[b].length))
                .is_gt(),
        };
        if better {
            *slot = Some(k);
        }
    }
    for k in best.into_iter().flatten() {
        found[k].cycle.outer = true;
    }
}

/// The graph whose nodes are pieces and whose edges are arcs between two regions, with a
/// depth-first search's articulation data (Hopcroft & Tarjan 1973): removing piece `p` splits
/// its connected component into one part per child `c` with `low[c] >= disc[p]` (that child's
/// subtree; every child when `p` is a root) plus the rest.
struct PieceGraph {
    disc: Vec<u32>,
    low: Vec<u32>,
    parent: Vec<u32>,
    size: Vec<u32>,
    subtree_area: Vec<f64>,
    root: Vec<u32>,
    child_offsets: Vec<u32>,
    children: Vec<u32>,
    area: Vec<f64>,
}

impl PieceGraph {
    fn build(arcs: &[ArcBuild], pieces: &Pieces) -> PieceGraph {
        let n = pieces.area.len();
        let edges = || {
            arcs.iter()
                .filter(|a| a.right_node != NONE && a.left_piece != NONE)
                .map(|a| (a.left_piece, a.right_node))
        };
        let mut offsets = vec![0u32; n + 1];
        for (x, y) in edges() {
            offsets[x as usize + 1] += 1;
            offsets[y as usize + 1] += 1;
        }
        for v in 0..n {
            offsets[v + 1] += offsets[v];
        }
        let mut cursor = offsets.clone();
        let mut adjacent = vec![0u32; offsets[n] as usize];
        for (x, y) in edges() {
            adjacent[cursor[x as usize] as usize] = y;
            cursor[x as usize] += 1;
            adjacent[cursor[y as usize] as usize] = x;
            cursor[y as usize] += 1;
        }
        let mut g = PieceGraph {
            disc: vec![NONE; n],
            low: vec![NONE; n],
            parent: vec![NONE; n],
            size: vec![1; n],
            subtree_area: pieces.area.clone(),
            root: vec![NONE; n],
            child_offsets: Vec::new(),
            children: Vec::new(),
            area: pieces.area.clone(),
        };
        let mut order = Vec::with_capacity(n);
        let mut stack: Vec<(u32, u32)> = Vec::new();
        for r in 0..n as u32 {
            if g.disc[r as usize] != NONE {
                continue;
            }
            g.discover(r, NONE, r, &mut order);
            stack.push((r, offsets[r as usize]));
            while let Some(top) = stack.last_mut() {
                let v = top.0 as usize;
                if top.1 < offsets[v + 1] {
                    let w = adjacent[top.1 as usize];
                    top.1 += 1;
                    if g.disc[w as usize] == NONE {
                        g.discover(w, v as u32, r, &mut order);
                        stack.push((w, offsets[w as usize]));
                    } else {
                        g.low[v] = g.low[v].min(g.disc[w as usize]);
                    }
                } else {
                    stack.pop();
                    let p = g.parent[v];
                    if p != NONE {
                        let p = p as usize;
                        g.low[p] = g.low[p].min(g.low[v]);
                        g.size[p] += g.size[v];
                        g.subtree_area[p] += g.subtree_area[v];
                    }
                }
            }
        }
        // Children of each node, in discovery order.
        let mut child_offsets = vec![0u32; n + 1];
        for &v in &order {
            let p = g.parent[v as usize];
            if p != NONE {
                child_offsets[p as usize + 1] += 1;
            }
        }
        for v in 0..n {
            child_offsets[v + 1] += child_offsets[v];
        }
        let mut cursor = child_offsets.clone();
        let mut children = vec![0u32; child_offsets[n] as usize];
        for &v in &order {
            let p = g.parent[v as usize];
            if p != NONE {
                children[cursor[p as usize] as usize] = v;
                cursor[p as usize] += 1;
            }
        }
        g.child_offsets = child_offsets;
        g.children = children;
        g
    }

    fn discover(&mut self, v: u32, parent: u32, root: u32, order: &mut Vec<u32>) {
        let time = order.len() as u32;
        self.disc[v as usize] = time;
        self.low[v as usize] = time;
        self.parent[v as usize] = parent;
        self.root[v as usize] = root;
        order.push(v);
    }

    fn children_of(&self, p: u32) -> &[u32] {
        let lo = self.child_offsets[p as usize] as usize;
        let hi = self.child_offsets[p as usize + 1] as usize;
        &self.children[lo..hi]
    }

    /// Whether child `c` of `p` is cut off from the rest when `p` is removed.
    fn separates(&self, p: u32, c: u32) -> bool {
        self.parent[p as usize] == NONE || self.low[c as usize] >= self.disc[p as usize]
    }

    /// The part of `p`'s component without `p` that neighbour `q` lies in: a child of `p`
    /// that `p` separates, or [`NONE`] for the rest.
    fn part_beyond(&self, p: u32, q: u32) -> u32 {
        let (dp, dq) = (self.disc[p as usize], self.disc[q as usize]);
        if dq <= dp || dq >= dp + self.size[p as usize] {
            return NONE;
        }
        let children = self.children_of(p);
        let k = children.partition_point(|&c| self.disc[c as usize] <= dq);
        match k.checked_sub(1).map(|k| children[k]) {
            Some(c) if self.separates(p, c) => c,
            _ => NONE,
        }
    }

    /// Area of part `key` (from [`Self::part_beyond`]) of `p`'s component without `p`.
    fn part_area(&self, p: u32, key: u32) -> f64 {
        if key != NONE {
            return self.subtree_area[key as usize];
        }
        let root = self.root[p as usize] as usize;
        let separated: f64 = self
            .children_of(p)
            .iter()
            .filter(|&&c| self.separates(p, c))
            .map(|&c| self.subtree_area[c as usize])
            .sum();
        (self.subtree_area[root] - self.area[p as usize] - separated).max(0.0)
    }
}
