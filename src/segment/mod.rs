//! Segmentation, the encoder's core: K connected regions of faces, each with the proxy
//! (ellipsoid, or plane for comparison) that fits it best.
//!
//! Simari & Singh 2005, section 4, extending the Lloyd iteration of Variational Shape
//! Approximation (Cohen-Steiner, Alliez & Desbrun, SIGGRAPH 2004): fit every region's proxy,
//! then regrow all regions by priority-queue flooding (from each region's well-fitting core
//! rather than VSA's single best face, see `lloyd.rs`) so that regions stay connected and
//! every face is assigned; regions are added one at a time where the fit is worst (seeding),
//! and teleported when the error stops improving. The best segmentation seen is kept.
//!
//! The loop ([`segment_with`]) is independent of the primitive: a [`ProxyMetric`] fits a proxy
//! to a set of faces and measures one face against a proxy. [`EllipsoidMetric`] is the
//! paper's metric; [`PlaneMetric`] is VSA's L²,¹ metric, so that planes and ellipsoids can be
//! compared with one tool.

mod lloyd;
pub mod plane;
pub mod proxy;

pub use plane::{Plane, PlaneMetric};
pub use proxy::{EllipsoidMetric, ProxyMetric};

use crate::ellipsoid::Ellipsoid;
use crate::mesh::Mesh;
use serde::Serialize;

/// How many regions to make.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum RegionCount {
    /// Exactly this many (at least one per connected component).
    Fixed(usize),
    /// As few as reach this RMS radial error, as a fraction of the bounding-box diagonal
    /// (at most [`SegmentOptions::max_regions`]).
    Tolerance(f64),
}

/// What the ellipsoids approximate (sections 2 and 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// The surface: the composite α·E_euc + β·E_ang + γ·E_cur metric.
    Surface,
    /// The volume: α·E_euc + δ·(V(R) − 4/3·πabc)², with V(R) the region's convex hull.
    Volume,
}

/// Replacements for the paper's default weights; `None` keeps the default (see
/// [`crate::ellipsoid::metric::Weights::paper`]: α = 1/ā², β = 1.2, γ = 5·10⁻⁴ in canonical
/// units, δ = 10⁵/V²). Overrides are in canonical units (the model scaled to a box diagonal
/// of 1), so the same numbers mean the same whatever the model's units.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct WeightOverrides {
    /// α, the Euclidean weight.
    pub alpha: Option<f64>,
    /// β, the normal weight.
    pub beta: Option<f64>,
    /// γ, the curvature weight (canonical units).
    pub gamma: Option<f64>,
    /// δ, the volume weight (volume mode).
    pub delta: Option<f64>,
}

/// Options of [`segment`]. Every field has a documented default ([`Default`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SegmentOptions {
    /// Number of regions, or an error tolerance that chooses it (default `Fixed(12)`).
    pub regions: RegionCount,
    /// Most Lloyd iterations after seeding (default 50).
    pub max_iterations: usize,
    /// Weight overrides (default: the paper's weights).
    pub weights: WeightOverrides,
    /// Surface or volume (default surface).
    pub mode: Mode,
    /// Allow negative ellipsoids (inner surfaces, for concavities; default true).
    pub allow_negative: bool,
    /// Weight each face's error by its area (default false: the paper's plain sum).
    pub area_weighting: bool,
    /// Worker threads; `None` uses all cores (default). The encoder runs its decoder check
    /// (and `--report`'s measurement) on as many ([`crate::encode::encode_mesh`]). The
    /// result does not depend on it.
    pub threads: Option<usize>,
    /// Most regions a tolerance may ask for (default 256).
    pub max_regions: usize,
}

/// Regions of [`SegmentOptions::default`].
pub const DEFAULT_REGIONS: usize = 12;

/// The region count to use when none is asked for: [`DEFAULT_REGIONS`] for a mesh in one
/// piece, and one more for each further connected component, which needs a region of its
/// own (scans come with loose fragments: Stanford's dragon has hundreds); at most one a
/// face. A fixed count below the component count is refused
/// ([`SegmentError::TooFewRegions`]).
pub fn default_region_count(mesh: &Mesh) -> usize {
    // At most one region a face (every component has a face).
    (DEFAULT_REGIONS + mesh.topology().component_count().saturating_sub(1))
        .min(mesh.face_count())
        .max(1)
}

impl Default for SegmentOptions {
    fn default() -> Self {
        SegmentOptions {
            regions: RegionCount::Fixed(DEFAULT_REGIONS),
            max_iterations: 50,
            weights: WeightOverrides::default(),
            mode: Mode::Surface,
            allow_negative: true,
            area_weighting: false,
            threads: None,
            max_regions: 256,
        }
    }
}

/// The result: a region label for every face and a proxy for every region.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation<P> {
    /// Region of each face, in `0..proxies.len()`. Every region is edge-connected.
    pub labels: Vec<u32>,
    /// The proxy of each region.
    pub proxies: Vec<P>,
    /// The error of each region against its proxy.
    pub region_errors: Vec<f64>,
    /// Sum of the region errors.
    pub total_error: f64,
    /// Total error after each iteration (seeding included), for plots and tests. With a fixed
    /// region count, the last [`Segmentation::iterations`] entries are the Lloyd iterations.
    pub history: Vec<f64>,
    /// Lloyd iterations run (after seeding; teleportation rounds included).
    pub iterations: usize,
}

impl<P> Segmentation<P> {
    /// Number of regions.
    pub fn region_count(&self) -> usize {
        self.proxies.len()
    }

    /// The faces of each region, in increasing order.
    pub fn faces_by_region(&self) -> Vec<Vec<u32>> {
        let mut out = vec![Vec::new(); self.proxies.len()];
        for (f, &r) in self.labels.iter().enumerate() {
            out[r as usize].push(f as u32);
        }
        out
    }
}

/// What the loop reports while it runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Iteration number (0 while seeding).
    pub iteration: usize,
    /// Most iterations.
    pub max_iterations: usize,
    /// Regions so far.
    pub regions: usize,
    /// Total error of the current segmentation.
    pub error: f64,
    /// Lowest total error seen.
    pub best_error: f64,
}

/// Why a mesh could not be segmented.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SegmentError {
    /// The mesh has no faces.
    #[error("the mesh has no faces")]
    EmptyMesh,
    /// Fewer regions asked for than the mesh has connected components.
    #[error("{requested} regions asked for, but the mesh has {components} separate components and each needs at least one")]
    TooFewRegions {
        /// Regions asked for.
        requested: usize,
        /// Connected components.
        components: usize,
    },
    /// More regions asked for than there are faces.
    #[error("{requested} regions asked for, but the mesh has only {faces} faces")]
    TooManyRegions {
        /// Regions asked for.
        requested: usize,
        /// Faces.
        faces: usize,
    },
    /// An option is out of its range.
    #[error("invalid option {what}: {value}")]
    InvalidOption {
        /// The option.
        what: &'static str,
        /// Its value, as text.
        value: String,
    },
}

/// Segments a mesh into ellipsoidal regions with the paper's metric.
pub fn segment(
    mesh: &Mesh,
    options: &SegmentOptions,
) -> Result<Segmentation<Ellipsoid>, SegmentError> {
    let metric = EllipsoidMetric::new(mesh, options)?;
    segment_with(mesh, &metric, options, &mut |_| {})
}

/// Segments a mesh into planar regions with VSA's L²,¹ metric, for comparison.
pub fn segment_planes(
    mesh: &Mesh,
    options: &SegmentOptions,
) -> Result<Segmentation<Plane>, SegmentError> {
    let metric = PlaneMetric::new(mesh);
    segment_with(mesh, &metric, options, &mut |_| {})
}

/// The Lloyd loop with any metric, reporting progress after every iteration.
pub fn segment_with<M: ProxyMetric>(
    mesh: &Mesh,
    metric: &M,
    options: &SegmentOptions,
    progress: &mut dyn FnMut(Progress),
) -> Result<Segmentation<M::Proxy>, SegmentError> {
    lloyd::run(mesh, metric, options, progress)
}

/// Where to cut a region in two: the plane through `point` with unit `normal`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cut {
    /// A point of the plane.
    pub point: glam::DVec3,
    /// Its unit normal.
    pub normal: glam::DVec3,
}

/// Where parallel steps run: rayon's global pool (all cores), or a pool of its own of
/// [`SegmentOptions::threads`] workers, for the segmentation and for the encoder's check of
/// what it writes alike.
pub(crate) enum Exec {
    Global,
    Local(rayon::ThreadPool),
}

impl Exec {
    /// The global pool for `None`, else a pool of `threads` workers.
    pub(crate) fn new(threads: Option<usize>) -> Result<Exec, SegmentError> {
        Ok(match threads {
            None => Exec::Global,
            Some(n) => Exec::Local(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| SegmentError::InvalidOption {
                        what: "threads",
                        value: format!("{n} ({e})"),
                    })?,
            ),
        })
    }

    /// Runs `op` with its parallel iterators in this pool.
    pub(crate) fn install<R: Send>(&self, op: impl FnOnce() -> R + Send) -> R {
        match self {
            Exec::Global => op(),
            Exec::Local(pool) => pool.install(op),
        }
    }
}

/// A region to split ([`split_regions`]), and where, if known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Split {
    /// The region.
    pub region: u32,
    /// The plane to cut it along; `None`: across the longest axis of its faces, at the median.
    pub cut: Option<Cut>,
}

/// Splits regions of a segmentation: each host is cut in two (along its [`Split::cut`], or
/// across the longest axis of its faces), then three Lloyd rounds, warm-started from
/// `segmentation`, settle the cuts; only the hosts' faces change region, so the other regions
/// keep their faces and ellipsoids. The encoder uses it for regions whose boundary
/// its decoder cannot map to a chart (see [`crate::encode::encode_mesh`]). New regions are
/// numbered after the existing ones.
pub fn split_regions<M: ProxyMetric>(
    mesh: &Mesh,
    metric: &M,
    options: &SegmentOptions,
    segmentation: &Segmentation<M::Proxy>,
    hosts: &[Split],
    progress: &mut dyn FnMut(Progress),
) -> Result<Segmentation<M::Proxy>, SegmentError> {
    lloyd::split(mesh, metric, options, segmentation, hosts, progress)
}

/// Removes regions of a segmentation: the faces of each region in `removed` go to the regions
/// around them, the others are renumbered in order (their relative order kept), and three
/// Lloyd rounds, warm-started from `segmentation`, settle the new borders; only the removed
/// regions' faces change region. The encoder uses it for small regions its decoder cannot
/// mesh cleanly, where a split would only make smaller ones (see
/// [`crate::encode::encode_mesh`]). Refused: an index out of range or repeated, or the only
/// region of a connected component.
pub fn dissolve_regions<M: ProxyMetric>(
    mesh: &Mesh,
    metric: &M,
    options: &SegmentOptions,
    segmentation: &Segmentation<M::Proxy>,
    removed: &[u32],
    progress: &mut dyn FnMut(Progress),
) -> Result<Segmentation<M::Proxy>, SegmentError> {
    lloyd::dissolve(mesh, metric, options, segmentation, removed, progress)
}
