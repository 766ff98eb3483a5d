//! The metric interface of the Lloyd loop, and the paper's ellipsoid metric behind it.

use super::{Mode, SegmentError, SegmentOptions};
use crate::ellipsoid::fit::{
    eigen_symmetric, evaluate_error, fit_ellipsoid, fit_solid, fit_tangent_sphere, scatter,
    FitInput, FitOptions, SignChoice, MIN_ELLIPSOID_SAMPLES,
};
use crate::ellipsoid::hull::convex_hull_volume;
use crate::ellipsoid::metric::{
    measure_vertex_terms, vertex_error, FaceWeighting, MeshScale, RegionSamples, SurfaceAttributes,
    VolumeTerm, Weights,
};
use crate::ellipsoid::{Ellipsoid, Sign};
use crate::mesh::crease::CreaseCorners;
use crate::mesh::curvature::mean_curvature_with_normals;
use crate::mesh::Mesh;
use glam::DVec3;

/// A proxy shape and how faces are measured against it: the only thing the Lloyd loop knows
/// about the primitive (as CGAL's VSA: `fit_proxy` and `compute_error`).
pub trait ProxyMetric: Sync {
    /// The fitted shape.
    type Proxy: Clone + Send + Sync + std::fmt::Debug;

    /// Fits the best proxy to a set of faces, starting from `previous` (the region's proxy in
    /// the last iteration) when given. Returns the proxy and the region's error against it.
    /// The loop passes `None` for new regions and when it wants a fresh fit.
    fn fit(&self, faces: &[u32], previous: Option<&Self::Proxy>) -> (Self::Proxy, f64);

    /// The error of one face against a proxy: what the flooding compares.
    fn face_error(&self, face: u32, proxy: &Self::Proxy) -> f64;

    /// The mean squared geometric distance from the face's vertices to the proxy's surface,
    /// in squared model units: what [`RegionCount::Tolerance`](super::RegionCount::Tolerance)
    /// measures. `None` (the default) when the metric has no such distance; the tolerance
    /// mode then refuses the metric.
    fn face_distance_squared(&self, face: u32, proxy: &Self::Proxy) -> Option<f64> {
        let _ = (face, proxy);
        None
    }

    /// The error of one vertex against a proxy, when the metric's face error is a weighted
    /// sum over the face's corners: `face_error(f, P) = face_weight(f) · Σ vertex_error(v, P)`
    /// (summed in corner order). The loop then measures each vertex once per nearby region
    /// instead of once per face. `None` (the default) when the metric is not of that form.
    fn vertex_error(&self, vertex: u32, proxy: &Self::Proxy) -> Option<f64> {
        let _ = (vertex, proxy);
        None
    }

    /// The weight of a face in the per-vertex form (see [`ProxyMetric::vertex_error`]);
    /// 1 by default.
    fn face_weight(&self, face: u32) -> f64 {
        let _ = face;
        1.0
    }
}

/// Most solver iterations of a warm-started fit. The loop refits every region in every
/// iteration from its last proxy, so the fits converge across iterations; measured on the
/// blob fixtures and koala (100K faces, K = 32), 8 iterations on 256 samples reach
/// segmentations as good as 100 on 2048 at a third of the time. (Fresh fits are not cut
/// down the same way: with 30 iterations instead of 100, blob3's seeding went wrong.)
pub const WARM_MAX_ITERATIONS: u32 = 8;
/// Most samples a warm-started fit iterates on (the error is still measured on all).
pub const WARM_SOLVER_POINTS: usize = 256;
/// Probe iterations of a warm-started fit (its two starts: the warm one, and the sphere of
/// the other sign when the region bends that way).
pub const WARM_PROBE_ITERATIONS: u32 = 3;

/// Most solver iterations of a fit from scratch (new and re-seeded regions); the
/// iterations that follow refine it.
pub const FRESH_MAX_ITERATIONS: u32 = 100;
/// Most samples a fit from scratch iterates on.
pub const FRESH_SOLVER_POINTS: usize = 1024;

/// The paper's metric (sections 2 and 3), with the mesh's normals and curvatures computed once.
///
/// Surface mode: E(f, P) = w_f · Σ over the face's vertices of α·E_euc + β·E_ang + γ·E_cur,
/// both signs fitted unless negative ellipsoids are disallowed. Volume mode: a region's error
/// is α·E_euc(R, P) + δ·(V(R) − 4/3·πabc)² with V(R) the convex hull volume of its vertices
/// (positive ellipsoids only), and a face's error — what the flooding compares — is the
/// Euclidean part α·E_euc alone.
///
/// Weight overrides are read in canonical units (box diagonal 1, see
/// [`crate::ellipsoid::metric`]), so that they mean the same whatever the model's units.
#[derive(Debug, Clone)]
pub struct EllipsoidMetric {
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    curvatures: Vec<f64>,
    faces: Vec<[u32; 3]>,
    /// The weight w_f of each face (1, or its relative area).
    face_weights: Vec<f64>,
    scale: MeshScale,
    /// Weights of the face error (Euclidean only in volume mode).
    weights: Weights,
    /// δ in the model's units, in volume mode.
    delta: Option<f64>,
    /// Options of the fits with a warm start (the fast path).
    warm: FitOptions,
    /// Options of the fits without one.
    fresh: FitOptions,
    /// Per face, whether it belongs to a speck ([`speck_faces`]).
    specks: Vec<bool>,
    /// The small closed pieces and their solids' ellipsoids ([`SmallSolids`]).
    solids: SmallSolids,
    /// The corners on sharp creases, with their sides' normals and curvatures: a facet's
    /// samples ([`EllipsoidMetric::take_crease_sides`]).
    creases: CreaseCorners,
}

/// Per face, whether it lies in a speck: a piece of the mesh (an edge-connected component)
/// with fewer vertices than an ellipsoid has parameters ([`MIN_ELLIPSOID_SAMPLES`]) that is
/// flat (no thicker than [`SPECK_THICKNESS`] of its extent) or has every vertex on its
/// border (a strip or fan with no inner vertex): the fins, loose triangles and folded pairs
/// of triangles of a scan (a face on a non-manifold edge is cut off on import). A speck is a
/// region of its own, fitted with a tangent sphere ([`fit_tangent_sphere`]), and its
/// boundary is stored as the mesh has it. Small closed pieces with depth (the head scan from
/// npm's `snowden` has boxes of seven triangles) bound a solid, whose ellipsoid they get
/// (`SmallSolids`), and open ones with an inner vertex (an octahedron less a face) are
/// fitted like any region: neither is a speck. A piece with depth and no inner vertex, two
/// triangles folded along their shared edge, leaves an ellipsoid through its four corners
/// free: Stanford's dragon at `res3` has six, fitted with needles 265 long in a model 0.2
/// across, two of which decoded turned over.
pub fn speck_faces(mesh: &Mesh) -> Vec<bool> {
    let topology = mesh.topology();
    let labels = topology.face_components();
    let vertices = few_vertices_per_piece(mesh);
    let positions = mesh.positions();
    let flat = |list: &Vec<u32>| {
        let points: Vec<DVec3> = list
            .iter()
            .filter_map(|&v| positions.get(v as usize).copied())
            .collect();
        is_flat(&points)
    };
    // Vertices on a border edge: a piece all of whose vertices are is a strip or fan of
    // triangles with no inner vertex, decoded as its own boundary loop.
    let mut on_border = vec![false; positions.len()];
    for (f, face) in mesh.faces().iter().enumerate() {
        for k in 0..3 {
            if topology.is_border_edge(f, k) {
                for v in [face[k], face[(k + 1) % 3]] {
                    if let Some(b) = on_border.get_mut(v as usize) {
                        *b = true;
                    }
                }
            }
        }
    }
    let bordered = |list: &Vec<u32>| {
        list.iter()
            .all(|&v| on_border.get(v as usize).copied().unwrap_or(false))
    };
    let specks: Vec<bool> = vertices
        .iter()
        .map(|l| l.len() < MIN_ELLIPSOID_SAMPLES && (flat(l) || bordered(l)))
        .collect();
    labels
        .iter()
        .map(|&c| specks.get(c as usize).copied().unwrap_or(false))
        .collect()
}

/// The closed pieces of a mesh with fewer vertices than an ellipsoid has parameters
/// ([`MIN_ELLIPSOID_SAMPLES`]): a CAD assembly's boxes, pegs and wedges. A region that is
/// such a piece whole has no boundary and is decoded as its whole ellipsoid, which is fitted
/// to the solid ([`fit_solid`]) rather than to its few vertices, which leave it free: in
/// assimp's `regr01`, a house of 58 pieces, 35 of them closed with eight vertices or fewer,
/// a plate 5 thick and 157 across was decoded as a ball 157 across. Closed pieces this small
/// are also the scans' debris (Stanford's dragon at `res3` has 24, npm's head scan 53).
/// Closed means no border edge: every edge has another face, which may lie on another piece
/// across a non-manifold edge (where import cuts pieces apart). 20 of `regr01`'s boxes touch
/// others along an edge and bound a solid on their own; 26 of the head's small pieces are
/// eight triangles but one, whose edges lie on other pieces, and [`fit_solid`] closes them
/// with that triangle; the single triangles and the pairs of the head and the dragon are no
/// solid's surface and keep their ordinary fit.
#[derive(Debug, Clone, Default)]
struct SmallSolids {
    /// Per face, its piece (edge-connected component).
    piece_of_face: Vec<u32>,
    /// Per piece, when it is a small closed one with a solid: its face count and its
    /// solid's ellipsoid.
    solids: Vec<Option<(usize, Ellipsoid)>>,
}

impl SmallSolids {
    fn of_mesh(mesh: &Mesh) -> SmallSolids {
        let topology = mesh.topology();
        let labels = topology.face_components();
        let n = topology.component_count();
        // The faces of the small pieces.
        let vertices = few_vertices_per_piece(mesh);
        let mut faces: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (f, &c) in labels.iter().enumerate() {
            let small = vertices
                .get(c as usize)
                .is_some_and(|seen| seen.len() < MIN_ELLIPSOID_SAMPLES);
            if let (true, Some(list)) = (small, faces.get_mut(c as usize)) {
                list.push(f);
            }
        }
        let open = open_pieces(mesh);
        let solid = |((list, seen), &open): ((&Vec<usize>, &Vec<u32>), &bool)| {
            if seen.len() >= MIN_ELLIPSOID_SAMPLES || open {
                return None;
            }
            let triangles: Vec<[DVec3; 3]> = list.iter().map(|&f| mesh.corners(f)).collect();
            fit_solid(&triangles).map(|e| (list.len(), e))
        };
        SmallSolids {
            piece_of_face: labels.to_vec(),
            solids: faces.iter().zip(&vertices).zip(&open).map(solid).collect(),
        }
    }

    /// The solid's ellipsoid when `faces` (distinct faces) are the whole of a small closed
    /// piece.
    fn whole(&self, faces: &[u32]) -> Option<Ellipsoid> {
        let piece = *self.piece_of_face.get(*faces.first()? as usize)?;
        let &(count, ellipsoid) = self.solids.get(piece as usize)?.as_ref()?;
        (faces.len() == count
            && faces
                .iter()
                .all(|&f| self.piece_of_face.get(f as usize) == Some(&piece)))
        .then_some(ellipsoid)
    }
}

/// Per piece (edge-connected component) of `mesh`, whether it is open: some face of it has
/// a border edge (an edge with no other face, where import may have cut a non-manifold
/// edge).
fn open_pieces(mesh: &Mesh) -> Vec<bool> {
    let topology = mesh.topology();
    let mut open = vec![false; topology.component_count()];
    for (f, &c) in topology.face_components().iter().enumerate() {
        if (0..3).any(|k| topology.is_border_edge(f, k)) {
            if let Some(o) = open.get_mut(c as usize) {
                *o = true;
            }
        }
    }
    open
}

/// Per piece (edge-connected component) of `mesh`, its vertices in order of first use, up
/// to [`MIN_ELLIPSOID_SAMPLES`]: all of them for a piece with fewer (a speck or a small
/// solid), one too many otherwise.
fn few_vertices_per_piece(mesh: &Mesh) -> Vec<Vec<u32>> {
    let topology = mesh.topology();
    let mut vertices: Vec<Vec<u32>> = vec![Vec::new(); topology.component_count()];
    for (face, &c) in mesh.faces().iter().zip(topology.face_components()) {
        let Some(list) = vertices.get_mut(c as usize) else {
            continue;
        };
        for &v in face {
            if list.len() < MIN_ELLIPSOID_SAMPLES && !list.contains(&v) {
                list.push(v);
            }
        }
    }
    vertices
}

/// Whether `points` are no thicker than [`SPECK_THICKNESS`] of their extent (the square root
/// of the ratio of their smallest to their largest principal variance).
fn is_flat(points: &[DVec3]) -> bool {
    let centroid = points.iter().sum::<DVec3>() / points.len().max(1) as f64;
    let (values, _) = eigen_symmetric(scatter(points.iter().map(|&p| (1.0, p)), centroid));
    values[2] <= SPECK_THICKNESS * SPECK_THICKNESS * values[0]
}

/// Largest thickness of a speck ([`speck_faces`]) as a fraction of its extent (the square
/// root of the ratio of the smallest to the largest principal variance of its vertices).
pub const SPECK_THICKNESS: f64 = 0.1;

impl EllipsoidMetric {
    /// Prepares the metric for a mesh: normals, curvatures, scale and weights.
    ///
    /// # Errors
    /// [`SegmentError::InvalidOption`] when a weight override is negative or not finite.
    pub fn new(mesh: &Mesh, options: &SegmentOptions) -> Result<Self, SegmentError> {
        let o = &options.weights;
        for (what, value) in [
            ("alpha", o.alpha),
            ("beta", o.beta),
            ("gamma", o.gamma),
            ("delta", o.delta),
        ] {
            if let Some(v) = value {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(SegmentError::InvalidOption {
                        what,
                        value: v.to_string(),
                    });
                }
            }
        }
        let scale = MeshScale::of_mesh(mesh);
        let d2 = scale.diagonal * scale.diagonal;
        let paper = Weights::paper(&scale);
        let surface_weights = Weights {
            // Canonical α is per squared diagonal; in model units it is α / D².
            alpha: o.alpha.map_or(paper.alpha, |a| a / d2),
            beta: o.beta.unwrap_or(paper.beta),
            gamma: o.gamma.map_or(paper.gamma, |g| g * d2),
        };
        let normals = mesh.vertex_normals();
        let curvatures = mean_curvature_with_normals(mesh, &normals);
        let creases = CreaseCorners::of_mesh(mesh, &curvatures);
        let weighting = if options.area_weighting {
            FaceWeighting::area(&scale)
        } else {
            FaceWeighting::Uniform
        };
        let positions = mesh.positions().to_vec();
        let faces = mesh.faces().to_vec();
        let face_weights = {
            let attributes = SurfaceAttributes::new(&positions, &normals, &curvatures);
            faces
                .iter()
                .map(|&f| attributes.map_or(0.0, |a| weighting.face_weight(&a, f)))
                .collect()
        };
        let (weights, delta) = match options.mode {
            Mode::Surface => (surface_weights, None),
            Mode::Volume => {
                let paper_delta = VolumeTerm::paper(&scale, 0.0).delta;
                // Canonical δ multiplies canonical volumes (model volume / D³) squared.
                let delta = o.delta.map_or(paper_delta, |d| d / (d2 * d2 * d2));
                let euclidean = Weights {
                    alpha: surface_weights.alpha,
                    beta: 0.0,
                    gamma: 0.0,
                };
                (euclidean, Some(delta))
            }
        };
        let mut fresh = FitOptions::surface(&scale);
        fresh.weights = weights;
        fresh.max_iterations = FRESH_MAX_ITERATIONS;
        fresh.max_solver_points = FRESH_SOLVER_POINTS;
        fresh.signs = if options.allow_negative && delta.is_none() {
            SignChoice::Both
        } else {
            SignChoice::Only(Sign::Positive)
        };
        let warm = FitOptions {
            fresh_starts_with_warm: false,
            max_iterations: WARM_MAX_ITERATIONS,
            max_solver_points: WARM_SOLVER_POINTS,
            probe_iterations: WARM_PROBE_ITERATIONS,
            ..fresh
        };
        Ok(EllipsoidMetric {
            positions,
            normals,
            curvatures,
            faces,
            face_weights,
            scale,
            weights,
            delta,
            warm,
            fresh,
            specks: speck_faces(mesh),
            solids: SmallSolids::of_mesh(mesh),
            creases,
        })
    }

    /// The mesh scale the weights were derived from.
    pub fn scale(&self) -> &MeshScale {
        &self.scale
    }

    /// The weights of the face error, in the model's units.
    pub fn weights(&self) -> &Weights {
        &self.weights
    }

    /// The region's vertices in order of first appearance, each weighted by the summed
    /// weights of its region faces: [`gather_region`](crate::ellipsoid::metric::gather_region)'s
    /// samples, with a reusable per-thread vertex → sample table instead of a hash map (the
    /// segmentation gathers every region in every iteration).
    fn gather(&self, faces: &[u32]) -> RegionSamples {
        thread_local! {
            static SLOTS: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        SLOTS.with(|slots| {
            let mut slots = slots.borrow_mut();
            if slots.len() < self.positions.len() {
                slots.resize(self.positions.len(), u32::MAX);
            }
            let mut out = RegionSamples::default();
            for &f in faces {
                let Some(tri) = self.face(f) else { continue };
                let w = self.face_weights.get(f as usize).copied().unwrap_or(0.0);
                for v in tri {
                    let i = v as usize;
                    let Some(slot) = slots.get_mut(i) else {
                        continue;
                    };
                    if let Some(sw) = out.weights.get_mut(*slot as usize) {
                        *sw += w;
                        continue;
                    }
                    let (Some(&p), Some(&n), Some(&h)) = (
                        self.positions.get(i),
                        self.normals.get(i),
                        self.curvatures.get(i),
                    ) else {
                        continue;
                    };
                    *slot = out.vertices.len() as u32;
                    out.vertices.push(v);
                    out.points.push(p);
                    out.normals.push(n);
                    out.curvatures.push(h);
                    out.weights.push(w);
                }
            }
            // Leave the table clean for the next region.
            for &v in &out.vertices {
                if let Some(slot) = slots.get_mut(v as usize) {
                    *slot = u32::MAX;
                }
            }
            out
        })
    }

    /// For a region of `faces` with fewer samples than an ellipsoid has parameters whose
    /// `proxy` is turned against one of its faces: the sphere tangent to it
    /// ([`fit_tangent_sphere`]), when that turns none of them; else `None`.
    ///
    /// Such a proxy is the needle [`fit_tangent_sphere`]'s documentation describes, whose
    /// normal at a face's centre points anywhere. The decoder's check turns on that normal,
    /// and a region of one or two faces is decoded as it is: Stanford's dragon at `res4`
    /// decoded with a flipped triangle, a region of one face between two others fitted with
    /// radii 0.024 × 0.0019 × 261 of a model 0.26 across, and dissolving or splitting it
    /// (the encoder's mending) could not mend it. Not part of [`ProxyMetric::fit`], which
    /// the segmentation's iterations call: there it changed 10 of 87 files (47 meshes, the
    /// paper-scale, CGAL and assimp ones, at the default K and 18), five nearer their
    /// source and four farther, and assimp's `3ds_max_export` decoded with 2 flipped
    /// triangles where it was clean.
    pub fn tangent_in_place_of_needle(
        &self,
        faces: &[u32],
        proxy: &Ellipsoid,
    ) -> Option<(Ellipsoid, f64)> {
        let mut samples = self.gather(faces);
        if samples.vertices.len() >= MIN_ELLIPSOID_SAMPLES || !self.turns_a_face(faces, proxy) {
            return None;
        }
        if self.is_speck(faces) {
            self.orient_by_own_faces(faces, &mut samples);
        }
        let options = self.with_volume(self.fresh, &samples);
        let input = FitInput::of_samples(&samples).ok()?;
        fit_tangent_sphere(&input, &options)
            .filter(|sphere| !self.turns_a_face(faces, &sphere.ellipsoid))
            .map(|sphere| (sphere.ellipsoid, sphere.error))
    }

    /// For a region that is a small closed piece whole ([`SmallSolids`]): its solid's
    /// ellipsoid and the region's error against it, when the options allow its sign.
    fn fit_whole_solid(&self, faces: &[u32], samples: &RegionSamples) -> Option<(Ellipsoid, f64)> {
        let ellipsoid = self.solids.whole(faces)?;
        if self.fresh.signs == SignChoice::Only(ellipsoid.sign.flipped()) {
            return None;
        }
        let options = self.with_volume(self.fresh, samples);
        let input = FitInput::of_samples(samples).ok()?;
        Some((ellipsoid, evaluate_error(&input, &options, &ellipsoid)))
    }

    /// Whether the region of `faces` is a speck ([`speck_faces`]).
    fn is_speck(&self, faces: &[u32]) -> bool {
        !faces.is_empty()
            && faces
                .iter()
                .all(|&f| self.specks.get(f as usize).copied().unwrap_or(false))
    }

    /// `options` with the volume term of the region sampled as `samples`, in volume mode.
    fn with_volume(&self, mut options: FitOptions, samples: &RegionSamples) -> FitOptions {
        if let Some(delta) = self.delta {
            options.volume = Some(VolumeTerm {
                delta,
                hull_volume: convex_hull_volume(&samples.points),
            });
        }
        options
    }

    /// Whether some face of `faces` is turned against `e` at its centroid (the test the
    /// decoder's check makes of every triangle it outputs).
    fn turns_a_face(&self, faces: &[u32], e: &Ellipsoid) -> bool {
        let side = e.normal_side();
        faces.iter().any(|&f| {
            let corners = self
                .face(f)
                .map(|tri| tri.map(|v| self.positions.get(v as usize).copied()));
            let Some([Some(a), Some(b), Some(c)]) = corners else {
                return false;
            };
            side.facing([a, b, c]) < 0.0
        })
    }

    /// Gives a speck ([`speck_faces`]: fitted with a tangent sphere, see
    /// [`fit_tangent_sphere`]) the normals of its own faces at its vertices. A vertex normal
    /// averages every face around the vertex, and a fin of a scan (one or two triangles on a
    /// non-manifold edge, a piece of its own) stands on a surface whose faces outweigh its
    /// own: on Stanford's dragon at `res4`, 130 of the 351 one-triangle pieces have vertex
    /// normals summing against their face's.
    fn orient_by_own_faces(&self, faces: &[u32], samples: &mut RegionSamples) {
        let mut own = vec![DVec3::ZERO; samples.vertices.len()];
        for &f in faces {
            let Some(tri) = self.face(f) else { continue };
            let corners = tri.map(|v| self.positions.get(v as usize).copied());
            let [Some(a), Some(b), Some(c)] = corners else {
                continue;
            };
            let area_normal = (b - a).cross(c - a);
            for v in tri {
                if let Some(k) = samples.vertices.iter().position(|&s| s == v) {
                    own[k] += area_normal;
                }
            }
        }
        for (n, o) in samples.normals.iter_mut().zip(own) {
            if let Some(o) = o.try_normalize() {
                *n = o;
            }
        }
    }

    /// Whether the region of `faces`, gathered as `samples`, is a facet: fewer samples than
    /// an ellipsoid has parameters, flat ([`SPECK_THICKNESS`]), every corner on a sharp
    /// crease ([`CreaseCorners`]) — a face of a low-poly CAD part (a cube's triangle)
    /// between its edges. (With a corner off the creases the region is left to
    /// [`fit_ellipsoid`]: allowing one changed 14 of the 60 small shared meshes' files, 8
    /// of them further from their source; this rule changes 6, 3 of them further.)
    fn is_facet(&self, faces: &[u32], samples: &RegionSamples) -> bool {
        !self.creases.is_empty()
            && samples.vertices.len() < MIN_ELLIPSOID_SAMPLES
            && faces
                .iter()
                .all(|&f| (0..3).all(|k| self.creases.side(f, k).is_some()))
            && is_flat(&samples.points)
    }

    /// Gives a facet's samples ([`EllipsoidMetric::is_facet`]) the facet's side of the
    /// creases they are on ([`CreaseCorners`]): the mean normal and curvature of the sides of
    /// its corners there. Their vertex normals and curvatures average both sides (a cube's
    /// corners get its diagonal, which the sphere through them matches exactly, and every
    /// triangle of a cube was fitted with that sphere); measured with its own side, a facet
    /// is fitted with its plane ([`fit_tangent_sphere`]).
    fn take_crease_sides(&self, faces: &[u32], samples: &mut RegionSamples) {
        let mut sides = vec![(DVec3::ZERO, 0.0, 0usize); samples.vertices.len()];
        for &f in faces {
            let Some(tri) = self.face(f) else { continue };
            for (k, v) in tri.into_iter().enumerate() {
                let (Some(side), Some(at)) = (
                    self.creases.side(f, k),
                    samples.vertices.iter().position(|&s| s == v),
                ) else {
                    continue;
                };
                if let Some((normal, curvature, count)) = sides.get_mut(at) {
                    *normal += side.normal;
                    *curvature += side.curvature;
                    *count += 1;
                }
            }
        }
        let samples_of = samples.normals.iter_mut().zip(&mut samples.curvatures);
        for ((n, h), (normal, curvature, count)) in samples_of.zip(sides) {
            if let (Some(normal), true) = (normal.try_normalize(), count > 0) {
                *n = normal;
                *h = curvature / count as f64;
            }
        }
    }

    fn face(&self, face: u32) -> Option<[u32; 3]> {
        self.faces.get(usize::try_from(face).ok()?).copied()
    }
}

impl ProxyMetric for EllipsoidMetric {
    type Proxy = Ellipsoid;

    fn fit(&self, faces: &[u32], previous: Option<&Ellipsoid>) -> (Ellipsoid, f64) {
        let mut samples = self.gather(faces);
        if let Some(fit) = self.fit_whole_solid(faces, &samples) {
            return fit;
        }
        let speck = self.is_speck(faces);
        if speck {
            self.orient_by_own_faces(faces, &mut samples);
        }
        let facet = !speck && self.is_facet(faces, &samples);
        if facet {
            self.take_crease_sides(faces, &mut samples);
        }
        let options = self.with_volume(
            if previous.is_some() {
                self.warm
            } else {
                self.fresh
            },
            &samples,
        );
        let fitted = match FitInput::of_samples(&samples) {
            Ok(input) => {
                let input = match previous {
                    Some(&p) => input.with_start(p),
                    None => input,
                };
                let sphere = (speck || facet)
                    .then(|| fit_tangent_sphere(&input, &options))
                    .flatten();
                sphere.unwrap_or_else(|| fit_ellipsoid(&input, &options))
            }
            Err(_) => {
                return (
                    Ellipsoid::sphere(DVec3::ZERO, self.scale.diagonal),
                    f64::MAX,
                );
            }
        };
        let error = if fitted.error.is_finite() {
            fitted.error
        } else {
            f64::MAX
        };
        (fitted.ellipsoid, error)
    }

    fn face_error(&self, face: u32, proxy: &Ellipsoid) -> f64 {
        let Some(tri) = self.face(face) else {
            return 0.0;
        };
        let weight = self.face_weights.get(face as usize).copied().unwrap_or(0.0);
        let mut sum = 0.0;
        for v in tri {
            let i = v as usize;
            if let (Some(&p), Some(&n), Some(&h)) = (
                self.positions.get(i),
                self.normals.get(i),
                self.curvatures.get(i),
            ) {
                sum += vertex_error(proxy, p, n, h, &self.weights);
            }
        }
        let e = weight * sum;
        if e.is_nan() {
            f64::MAX
        } else {
            e.min(f64::MAX)
        }
    }

    fn vertex_error(&self, vertex: u32, proxy: &Ellipsoid) -> Option<f64> {
        let i = usize::try_from(vertex).ok()?;
        let (&p, &n, &h) = (
            self.positions.get(i)?,
            self.normals.get(i)?,
            self.curvatures.get(i)?,
        );
        Some(vertex_error(proxy, p, n, h, &self.weights))
    }

    fn face_weight(&self, face: u32) -> f64 {
        self.face_weights.get(face as usize).copied().unwrap_or(0.0)
    }

    fn face_distance_squared(&self, face: u32, proxy: &Ellipsoid) -> Option<f64> {
        let tri = self.face(face)?;
        let mut sum = 0.0;
        for v in tri {
            let i = v as usize;
            let (&p, &n, &h) = (
                self.positions.get(i)?,
                self.normals.get(i)?,
                self.curvatures.get(i)?,
            );
            sum += measure_vertex_terms(proxy, p, n, h).euclidean;
        }
        let d = sum / 3.0;
        Some(if d.is_nan() {
            f64::MAX
        } else {
            d.min(f64::MAX)
        })
    }
}
