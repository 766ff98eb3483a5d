//! The regions joined into one mesh: shared boundary vertices, outward orientation, analytic
//! normals (issue 6, items 2, 6 and 7).
//!
//! 1. **Budget and spacing.** The total vertex budget N ([`RemeshOptions::budget`]) and an
//!    estimate A of the total surface area give the target edge length
//!    h = √(2A / (√3·N)) of an equilateral mesh with N vertices, used both for the boundary
//!    ([`super::refine`]) and as the interiors' scale.
//! 2. **One vertex pool.** The refined boundary points, each once (pool points at exactly
//!    the same position are merged); every region's loops refer to it, so neighbouring
//!    regions share their boundary vertices and the mesh is watertight.
//! 3. **Regions.** A region with cycles is triangulated in its chart (section 5.1). A region
//!    without cycles is a whole ellipsoid: it is cut along its local equator (shared points,
//!    like an arc) and each half is triangulated in its own chart.
//! 4. **Budget shared by error.** Adaptive (section 5.3, the default): a max-heap of the
//!    regions keyed by their worst face error; the worst region gets the next vertex, until
//!    the budget is spent or every region is within the tolerance. Parametric (section 5.2):
//!    the interior budget shared by area.
//! 5. **Join.** Boundary corners map to the pool, interior corners to new vertices; vertex
//!    normals are the analytic signed normals ([`Ellipsoid::normal`]) averaged over the
//!    regions a vertex touches; then [`check_mesh`] counts degenerate and flipped triangles
//!    and reads closedness off the topology.
//!
//! The tolerance's bounding box is that of the boundary points and of the whole-ellipsoid
//! regions (the part of the output the file pins down before any interior is meshed).

use super::chart::{is_degenerate_loop, ChartMemo, PoleWalk, Projection, RegionChart};
use super::refine::{refine_arcs, Prune, RefineSettings};
use super::subdivide::subdivide;
use super::surface::{Lift, RegionSurface};
use super::triangulate::{
    boundary_crossing, triangulate_parametric, AdaptiveTriangulation, Corner, Crossing,
    RegionInput, RegionMesh,
};
use super::{RemeshError, RemeshOptions, Remeshed, Scheme};
use crate::ellipsoid::{Ellipsoid, NormalSide};
use crate::mesh::{find_root, join_sets, Mesh};
use crate::representation::{Representation, Side};
use glam::DVec3;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap, VecDeque};

/// Fewest points on the equator of a whole-ellipsoid region.
const MIN_EQUATOR_POINTS: usize = 8;

/// A triangle whose area is below this fraction of the squared bounding-box diagonal counts
/// as degenerate (f32 output cannot tell it from a zero-area one).
pub const DEGENERATE_AREA: f64 = 1e-14;

/// What [`check_mesh`] measured on an assembled mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct MeshCheck {
    /// Triangles with (near) zero area ([`DEGENERATE_AREA`]).
    pub degenerate: usize,
    /// Triangles whose normal disagrees with their ellipsoid's signed normal at their
    /// centroid.
    pub flipped: usize,
    /// Every edge has exactly two faces.
    pub closed: bool,
    /// No edge with more than two faces, every vertex a single fan.
    pub manifold: bool,
    /// No edge run the same way by its two faces.
    pub consistently_oriented: bool,
    /// Loops of border edges.
    pub border_loops: usize,
    /// Whether the representation has arcs on the mesh border (when it has none, the mesh
    /// should be closed).
    pub has_border_arcs: bool,
    /// Regions left out of the mesh because they could not be charted or triangulated in
    /// the attempt kept (their place is a hole); 0 unless every attempt at meshing them all
    /// failed (see [`assemble`]).
    pub omitted_regions: usize,
}

impl MeshCheck {
    /// Whether the mesh has every property it should: no region left out, no degenerate or
    /// flipped triangle, manifold and consistently oriented, and closed unless the
    /// representation has border arcs.
    pub fn is_clean(&self) -> bool {
        self.is_clean_from(true)
    }

    /// Whether the mesh's topology is as it should be, whatever its triangles' shapes: no
    /// region left out, manifold, consistently oriented, and closed unless the
    /// representation has border arcs.
    pub fn is_sound(&self) -> bool {
        self.is_sound_from(true)
    }

    /// [`Self::is_clean`] for a mesh decoded from a source that is manifold or not
    /// (`source_manifold`): where the source is not (a scan's fins and fragments meeting at
    /// an edge or a vertex, a teapot's spout), its regions meet where its parts do, and the
    /// decoded mesh is not manifold either; the rest is asked all the same.
    pub fn is_clean_from(&self, source_manifold: bool) -> bool {
        self.degenerate == 0 && self.flipped == 0 && self.is_sound_from(source_manifold)
    }

    /// [`Self::is_sound`] for a source that is manifold or not (see [`Self::is_clean_from`]).
    pub fn is_sound_from(&self, source_manifold: bool) -> bool {
        self.omitted_regions == 0
            && (self.manifold || !source_manifold)
            && self.consistently_oriented
            && (self.closed || self.has_border_arcs)
    }

    /// What keeps the mesh from being clean, in words: "2 flipped and 0 degenerate
    /// triangles", then each of ", 1 region left out", ", not manifold", ", not
    /// consistently oriented" and ", not closed" that applies.
    pub fn faults(&self) -> String {
        format!(
            "{} flipped and {} degenerate triangles{}{}{}{}",
            self.flipped,
            self.degenerate,
            match self.omitted_regions {
                0 => String::new(),
                1 => ", 1 region left out".to_string(),
                n => format!(", {n} regions left out"),
            },
            if self.manifold { "" } else { ", not manifold" },
            if self.consistently_oriented {
                ""
            } else {
                ", not consistently oriented"
            },
            if self.closed || self.has_border_arcs {
                ""
            } else {
                ", not closed"
            },
        )
    }
}

/// What every attempt of [`assemble`] starts from: the budget, the spacing, the tolerance
/// in model units, the regions' estimated areas and the first attempt's refinement.
struct Prepared {
    budget: usize,
    spacing: f64,
    tolerance: Option<f64>,
    areas: Vec<f64>,
    settings: RefineSettings,
}

impl Prepared {
    /// The first attempt's plan ([`Treatment::FIRST`]), its charts made in `charts`.
    fn plan<'a>(
        &'a self,
        rep: &'a Representation,
        options: &'a RemeshOptions,
        charts: &'a ChartMemo,
    ) -> Plan<'a> {
        Plan {
            rep,
            options,
            budget: self.budget,
            spacing: self.spacing,
            tolerance: self.tolerance,
            areas: &self.areas,
            settings: self.settings,
            treatment: Treatment::FIRST,
            leave_out: false,
            charts,
        }
    }
}

fn prepare(rep: &Representation, options: &RemeshOptions) -> Result<Prepared, RemeshError> {
    rep.validate()?;
    options.validate()?;
    let budget = options.budget(rep);
    let areas = estimate_areas(rep)?;
    let total_area: f64 = areas.iter().sum();
    let spacing = (2.0 * total_area / (3f64.sqrt() * budget as f64)).sqrt();
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(RemeshError::Geometry {
            what: "surface area or vertex spacing not finite",
        });
    }
    let diagonal = reference_diagonal(rep);
    if !diagonal.is_finite() {
        return Err(RemeshError::Geometry {
            what: "bounding box not finite",
        });
    }
    let tolerance = options.tolerance.map(|t| t * diagonal);

    // Each whole ellipsoid: its equator and its two poles (`split_whole`).
    let minimum = rep.points.len() + (MIN_EQUATOR_POINTS + 2) * whole_regions(rep).count();
    if minimum > options.max_vertices {
        return Err(RemeshError::TooManyVertices {
            needed: minimum,
            max: options.max_vertices,
        });
    }
    let settings = RefineSettings {
        spacing,
        tolerance: tolerance.unwrap_or(spacing / 16.0),
        // Refined arcs never take the total past the budget: a cube's twelve triangles,
        // decoded at its 8 vertices, got 2 points on the sphere their regions are fitted
        // with (21 % of the diagonal off the cube) where its 8 corners were all it asked for.
        max_new_points: (budget / 4)
            .min(budget.saturating_sub(minimum))
            .min(options.max_vertices - minimum),
        prune: Prune::Narrow,
    };
    Ok(Prepared {
        budget,
        spacing,
        tolerance,
        areas,
        settings,
    })
}

/// A region whose chart or boundary triangulation fails ([`region_faults`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionFault {
    /// The region.
    pub region: u32,
    /// When its loops cross in its chart: two loop edges that cross (their end points in
    /// space), where the boundary folds over itself.
    pub crossing: Option<Crossing>,
    /// Whether every boundary edge of the region is a seam: it lies on both sides of all its
    /// boundary and closes on itself (a ring of faces made one region), which no chart and
    /// no boundary stored more faithfully mends, only cutting the region.
    pub seam: bool,
}

/// The regions whose chart or boundary triangulation fails in the decoder's first attempt
/// (refined, untangled arcs reaching the ellipsoids at their closest points), all of them
/// rather than the first: what [`assemble`] would have to fall back from. In increasing
/// order of region, one fault per region. Its charts are made in `charts` ([`ChartMemo`]).
pub fn region_faults(
    rep: &Representation,
    options: &RemeshOptions,
    charts: &ChartMemo,
) -> Result<Vec<RegionFault>, RemeshError> {
    let prepared = prepare(rep, options)?;
    let (faults, _) = prepared.plan(rep, options, charts).faults()?;
    Ok(faults)
}

/// Remeshes every region and joins them (see [`super::remesh`] and the module doc). A large
/// budget ([`RemeshOptions::subdivision_levels`]) is met by meshing at a fraction of it and
/// subdividing ([`super::subdivide`]), which keeps a clean coarse mesh clean. When the
/// coarse mesh is not clean (the meshing of some regions depends on the budget), with one
/// level fewer, and so on, then by meshing at the full budget; but meshes of more than
/// [`FALLBACK_MAX_VERTICES`] are not made for that: the best mesh made so far (a coarse one,
/// subdivided) is returned instead. Each step costs four times the one before, for as many
/// meshing attempts as the file needs, and such faults come from the boundary and rarely go
/// away with the budget. When some region fails in every attempt, with
/// [`RemeshOptions::leave_out`] the attempts are made again leaving out each region that
/// fails ([`MeshCheck::omitted_regions`]), untangling regions whose loops include one that
/// encloses nothing; if that fails too, the first error stands.
/// [`Remeshed::attempts`] counts the meshings made. Every attempt's charts are made in
/// `charts` ([`ChartMemo`]), once for each distinct input.
pub fn assemble(
    rep: &Representation,
    options: &RemeshOptions,
    charts: &ChartMemo,
) -> Result<Remeshed, RemeshError> {
    let mut attempts = 0;
    let mut out = assemble_counted(rep, options, charts, &mut attempts)?;
    out.attempts = attempts;
    Ok(out)
}

/// [`assemble`], counting the meshings made in `attempts`.
fn assemble_counted(
    rep: &Representation,
    options: &RemeshOptions,
    charts: &ChartMemo,
    attempts: &mut usize,
) -> Result<Remeshed, RemeshError> {
    rep.validate()?;
    options.validate()?;
    let budget = options.budget(rep);
    // The best subdivided mesh that is not clean, if any.
    let mut best: Option<Remeshed> = None;
    for levels in (1..=options.subdivision_levels(budget, rep.region_count())).rev() {
        let coarse_budget = budget.div_ceil(4usize.pow(levels));
        if coarse_budget > FALLBACK_MAX_VERTICES {
            if let Some(kept) = best.take() {
                return Ok(kept);
            }
        }
        let coarse_options = RemeshOptions {
            vertices: Some(coarse_budget),
            ..options.clone()
        };
        let Ok(coarse) = assemble_unsubdivided(rep, &coarse_options, false, charts, attempts)
        else {
            break;
        };
        match subdivide(rep, coarse, levels, options.max_vertices) {
            Ok(fine) if fine.check.is_clean() => return Ok(fine),
            Ok(fine) => keep_better(&mut best, fine, None),
            Err(_) => {}
        }
    }
    if let Some(kept) = best.take() {
        if budget > FALLBACK_MAX_VERTICES {
            return Ok(kept);
        }
        return match assemble_unsubdivided(rep, options, false, charts, attempts) {
            Ok(out) if rank(&out, None) < rank(&kept, None) => Ok(out),
            _ => Ok(kept),
        };
    }
    match assemble_unsubdivided(rep, options, false, charts, attempts) {
        // Some region fails in every attempt (a scan's fragment a few quantisation steps
        // across whose loops enclose nothing on its needle of an ellipsoid, loops that
        // cross however they are untangled): rather than no mesh at all, the others, with a
        // hole where it would be, counted in MeshCheck::omitted_regions.
        Err(e @ RemeshError::Region { .. }) if options.leave_out => {
            assemble_unsubdivided(rep, options, true, charts, attempts).map_err(|_| e)
        }
        other => other,
    }
}

/// Largest mesh [`assemble`] makes only because a coarser one was not clean (50 000
/// vertices, about 100 000 triangles): beyond it a search over every meshing attempt costs
/// seconds (23–28 s for horse K = 20 at 500 000 vertices, none of whose meshes was
/// clean).
pub const FALLBACK_MAX_VERTICES: usize = 50_000;

/// How a mesh that is not clean, or falls short of `wanted` vertices ([`shortfall`]), ranks
/// among others, lowest best: the fewest regions left out, then sound topology, then the
/// fewest degenerate and flipped triangles, then the fewest vertices short.
fn rank(out: &Remeshed, wanted: Option<usize>) -> (usize, bool, usize, usize) {
    let c = &out.check;
    (
        c.omitted_regions,
        !c.is_sound(),
        c.degenerate + c.flipped,
        shortfall(out, wanted),
    )
}

/// Keeps `out` in `best` if it ranks better ([`rank`]; ties keep the earlier).
fn keep_better(best: &mut Option<Remeshed>, out: Remeshed, wanted: Option<usize>) {
    if best
        .as_ref()
        .is_none_or(|b| rank(&out, wanted) < rank(b, wanted))
    {
        *best = Some(out);
    }
}

/// The share of its vertex budget below which a mesh falls far short of it, so that another
/// treatment is tried ([`shortfall`]): half. Not the 1 % the budget is met within as a rule
/// ([`BUDGET_MET`]): a mesh a little short has lost interior vertices mending turned faces,
/// whatever its treatment, and [`triangulate_adaptive`] makes up for those (before it did,
/// CGAL's cow decoded 19 649 vertices at 20 000, and at best 19 688 after all 14
/// treatments, in 9 times the time). Nor 90 %: assimp's `concave_polygon`, nearly flat,
/// takes 57 vertices at most, every treatment short; at its own 64 the file took 9
/// meshings to decode, and its encoder named another treatment.
const MIN_BUDGET_SHARE: f64 = 0.5;

/// How many vertices `out` lacks of `wanted` when it has fewer than [`MIN_BUDGET_SHARE`] of
/// them, else (or with no budget wanted) 0. A treatment can mesh clean and still stop far short:
/// an octahedron less one face, encoded as one region, names the stored arcs as its first
/// treatment (chosen at its 6 vertices), and their three long loop edges keep every face
/// after the first split from being split again (the boundary clearance), so it decoded 4
/// vertices at a budget of 1 000 or 20 000; the refined arcs give it all of them.
fn shortfall(out: &Remeshed, wanted: Option<usize>) -> usize {
    let Some(budget) = wanted else {
        return 0;
    };
    let have = out.mesh.vertex_count();
    if have as f64 >= MIN_BUDGET_SHARE * budget as f64 {
        0
    } else {
        budget - have
    }
}

/// [`assemble`] without subdivision: every vertex placed by the scheme, with each
/// [`Treatment`] in turn (the file's hint first; counted in `made`) until one is clean and,
/// by vertex addition with no tolerance, meets the budget ([`shortfall`]); otherwise the
/// best mesh is kept ([`rank`]: the fewest regions left out, then sound topology, then the
/// fewest degenerate and flipped triangles, then the fewest vertices short, then the
/// earliest), else the last error.
/// With `leave_out`, a region that fails is left out of the attempt instead of ending it.
fn assemble_unsubdivided(
    rep: &Representation,
    options: &RemeshOptions,
    leave_out: bool,
    charts: &ChartMemo,
    made: &mut usize,
) -> Result<Remeshed, RemeshError> {
    let prepared = prepare(rep, options)?;
    // Vertex addition spends the whole budget unless a tolerance stops it first or a
    // treatment blocks it; the parametric grid's count follows its regions' shapes (torus
    // K = 12 at 5 000: 3 784, 4 103 at best in 9 meshings).
    let wanted = (options.scheme == Scheme::Adaptive && prepared.tolerance.is_none())
        .then_some(prepared.budget);
    let mut plan = prepared.plan(rep, options, charts);
    plan.leave_out = leave_out;
    let mut attempts = Treatment::sequence(&prepared.settings);
    // The file's hint first: the treatment that meshed it clean when it was written (at
    // another budget, as a rule the same one does).
    let hint = rep.metadata.remesh_hint.and_then(Treatment::from_code);
    if let Some(i) = hint.and_then(|h| attempts.iter().position(|&t| t == h)) {
        let hinted = attempts.remove(i);
        attempts.insert(0, hinted);
    }
    let mut best: Option<Remeshed> = None;
    let mut last_error = None;
    if leave_out {
        // Meshing every attempt with regions left out would cost a whole mesh each: only
        // those whose charts fail for the fewest regions are meshed.
        let mut counts: Vec<(usize, Treatment)> = Vec::new();
        for &treatment in &attempts {
            plan.treatment = treatment;
            if let Ok((faults, true)) = plan.faults() {
                counts.push((faults.len(), treatment));
            }
        }
        let fewest = counts.iter().map(|&(n, _)| n).min();
        attempts = counts
            .iter()
            .filter(|&&(n, _)| Some(n) == fewest)
            .map(|&(_, t)| t)
            .collect();
    }
    for treatment in attempts {
        plan.treatment = treatment;
        let meshed = plan.mesh();
        *made += usize::from(!matches!(meshed, Ok(None)));
        match meshed {
            Ok(None) => {}
            Ok(Some(mut out)) => {
                out.treatment = Some(treatment);
                if out.check.is_clean() && shortfall(&out, wanted) == 0 {
                    return Ok(out);
                }
                keep_better(&mut best, out, wanted);
            }
            Err(e @ RemeshError::Region { .. }) => last_error = Some(e),
            Err(e) => return Err(e),
        }
    }
    match (best, last_error) {
        (Some(out), _) => Ok(out),
        (None, Some(e)) => Err(e),
        (None, None) => Err(RemeshError::Geometry {
            what: "no meshing attempt was made",
        }),
    }
}

/// How one meshing attempt treats the boundary: which points the arcs keep, how the
/// regions' loops reach their charts, where each chart's pole may go. [`assemble`] tries
/// them in the order of [`Treatment::sequence`] until one meshes clean; the file can name
/// the one that did when it was written ([`Treatment::code`], stored as
/// [`crate::representation::Metadata::remesh_hint`], spec §6.1), and that one is tried
/// first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Treatment {
    /// The arcs refined on the intersection curves of their ellipsoids ([`refine_arcs`]);
    /// else as stored.
    pub refined: bool,
    /// Which double ears are pruned.
    pub prune: Prune,
    /// Whether loops that cross in their charts are untangled by dropping points.
    pub untangle: bool,
    /// How boundary points reach their region's ellipsoid in its chart:
    /// [`Projection::Closest`] or [`Projection::Radial`].
    pub projection: Projection,
    /// With untangling and closest points, a region whose loops cross in its chart and do
    /// not along the rays from its ellipsoid's centre is charted along the rays instead.
    pub radial_where_untangled: bool,
    /// How each chart's pole is placed.
    pub pole_walk: PoleWalk,
}

impl Treatment {
    /// The first attempt: refined arcs pruned where the chord is narrow, untangled,
    /// reaching the ellipsoids at their closest points, poles free. Code 0.
    pub const FIRST: Treatment = Treatment {
        refined: true,
        prune: Prune::Narrow,
        untangle: true,
        projection: Projection::Closest,
        radial_where_untangled: false,
        pole_walk: PoleWalk::Free,
    };

    /// The treatments [`assemble`] tries, in order. Refined arcs, pruned where the chord
    /// is narrow (a chord across a thin part can turn a face over); the stored arcs, pruned
    /// the same way (refined points off the stored polyline can make loops cross where
    /// arcs meet at sharp angles or where the fitted ellipsoids meet far from the stored
    /// boundary); both pruned everywhere (a kept ear can leave a triangle in both regions;
    /// not made when that prunes nothing more); the stored arcs as they
    /// are (pruning can shortcut a corner across a neighbouring arc); and the same without
    /// untangling. A treatment whose arcs are another's (the stored arcs are the refined
    /// ones when `settings` refines nothing) is left out. Each with the boundary reaching
    /// the ellipsoids at their closest points; then so, except for the regions whose loops
    /// cross that way and not along the rays from their ellipsoids' centres; then along the
    /// rays for every region (section 5.1's radial map, which suits regions whose boundary
    /// lies deep inside a thin ellipsoid better). Mixed projections only differ where
    /// untangling runs; every ear is pruned with the first projection only (of 190 decodes
    /// of 38 files, none came clean from it with the others, and each is a meshing more for
    /// a file that no attempt makes clean). Last, the first with each chart's pole kept from
    /// crossing the boundary ([`PoleWalk::Uncrossed`]): it mends charts the free walk turns
    /// into their holes, but changes some that were sound.
    pub fn sequence(settings: &RefineSettings) -> Vec<Treatment> {
        let mut arcs: Vec<Treatment> = Vec::new();
        for (refined, prune, untangle) in [
            (true, Prune::Narrow, true),
            (false, Prune::Narrow, true),
            (true, Prune::All, true),
            (false, Prune::All, true),
            (false, Prune::Off, true),
            (false, Prune::Off, false),
        ] {
            let t = Treatment {
                refined,
                prune,
                untangle,
                ..Treatment::FIRST
            };
            let same = |u: &Treatment| {
                u.untangle == t.untangle && u.settings(settings) == t.settings(settings)
            };
            if !arcs.iter().any(same) {
                arcs.push(t);
            }
        }
        let mut sequence: Vec<Treatment> = [
            (Projection::Closest, false),
            (Projection::Closest, true),
            (Projection::Radial, false),
        ]
        .into_iter()
        .flat_map(|(projection, radial_where_untangled)| {
            arcs.iter().map(move |&t| Treatment {
                projection,
                radial_where_untangled,
                ..t
            })
        })
        .filter(|t| {
            (!t.radial_where_untangled || t.untangle)
                && (t.prune != Prune::All
                    || (t.projection == Projection::Closest && !t.radial_where_untangled))
        })
        .collect();
        if let Some(&first) = arcs.first() {
            sequence.push(Treatment {
                pole_walk: PoleWalk::Uncrossed,
                ..first
            });
        }
        sequence
    }

    /// The refinement this treatment asks of `settings` (the first attempt's).
    fn settings(&self, settings: &RefineSettings) -> RefineSettings {
        RefineSettings {
            max_new_points: if self.refined {
                settings.max_new_points
            } else {
                0
            },
            prune: self.prune,
            ..*settings
        }
    }

    /// The treatment as a number (spec §12): bit 0 set for the stored arcs (not refined);
    /// bits 1–2 the pruning (0 narrow ears, 1 every ear, 2 none); bit 3 set without
    /// untangling; bit 4 set for the rays from the centres (else closest points); bit 5 set
    /// for the rays only where untangling would drop points; bit 6 set for poles kept from
    /// crossing the boundary. [`Treatment::FIRST`] is 0.
    pub fn code(&self) -> u64 {
        let prune = match self.prune {
            Prune::Narrow => 0,
            Prune::All => 1,
            Prune::Off => 2,
        };
        u64::from(!self.refined)
            | prune << 1
            | u64::from(!self.untangle) << 3
            | u64::from(self.projection == Projection::Radial) << 4
            | u64::from(self.radial_where_untangled) << 5
            | u64::from(self.pole_walk == PoleWalk::Uncrossed) << 6
    }

    /// The treatment a [`Treatment::code`] names; `None` for a number that names none
    /// (a hint this decoder does not know is ignored).
    pub fn from_code(code: u64) -> Option<Treatment> {
        if code >= 1 << 7 {
            return None;
        }
        let bit = |i: u32| code >> i & 1 == 1;
        let prune = match code >> 1 & 3 {
            0 => Prune::Narrow,
            1 => Prune::All,
            2 => Prune::Off,
            _ => return None,
        };
        Some(Treatment {
            refined: !bit(0),
            prune,
            untangle: !bit(3),
            projection: if bit(4) {
                Projection::Radial
            } else {
                Projection::Closest
            },
            radial_where_untangled: bit(5),
            pole_walk: if bit(6) {
                PoleWalk::Uncrossed
            } else {
                PoleWalk::Free
            },
        })
    }
}

impl std::fmt::Display for Treatment {
    /// In words, e.g. "stored arcs, no ears pruned, untangled, closest points (rays where
    /// untangling would drop points)".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let arcs = if self.refined { "refined" } else { "stored" };
        let prune = match self.prune {
            Prune::Narrow => "narrow ears pruned",
            Prune::All => "every ear pruned",
            Prune::Off => "no ears pruned",
        };
        let untangled = if self.untangle {
            "untangled"
        } else {
            "not untangled"
        };
        let projection = match (self.projection, self.radial_where_untangled) {
            (Projection::Radial, _) => "rays from the centres",
            (_, true) => "closest points (rays where untangling would drop points)",
            _ => "closest points",
        };
        write!(f, "{arcs} arcs, {prune}, {untangled}, {projection}")?;
        if self.pole_walk == PoleWalk::Uncrossed {
            write!(f, ", poles kept from crossing the boundary")?;
        }
        Ok(())
    }
}

/// What every attempt at meshing shares.
struct Plan<'a> {
    rep: &'a Representation,
    options: &'a RemeshOptions,
    budget: usize,
    spacing: f64,
    tolerance: Option<f64>,
    areas: &'a [f64],
    /// The first attempt's refinement, which [`Plan::treatment`] adapts.
    settings: RefineSettings,
    /// How this attempt treats the boundary.
    treatment: Treatment,
    /// A region whose chart or triangulation fails is left out (a hole, counted in
    /// [`MeshCheck::omitted_regions`]) instead of ending the attempt; and untangling drops
    /// the loops that enclose nothing, which would keep a region from being untangled
    /// ([`region_crossings`]). Only in this last resort, so that files that mesh whole
    /// mesh as before: untangling such regions in every attempt made Stanford's dragon
    /// at `res3` mesh whole, but changed the encoder's check enough that horse's file at
    /// K = 20 (volume) came out with a region 10 % of the diagonal off its source.
    leave_out: bool,
    /// The charts made so far, in this attempt and the ones before.
    charts: &'a ChartMemo,
}

impl Plan<'_> {
    /// Refines the arcs (and untangles them) as the treatment says, triangulates every
    /// piece and joins them. `None` when the attempt would repeat another
    /// ([`Plan::pieces`]).
    fn mesh(&self) -> Result<Option<Remeshed>, RemeshError> {
        let mut faults = Vec::new();
        let Some((positions, pieces)) = self.pieces(self.leave_out.then_some(&mut faults))? else {
            return Ok(None);
        };
        let mut omitted: Vec<u32> = faults.iter().map(|f| f.region).collect();
        // A region left out loses all its pieces (both halves of a whole ellipsoid).
        let mut pieces: Vec<Piece> = pieces
            .into_iter()
            .filter(|p| !omitted.contains(&p.region))
            .collect();
        loop {
            if pieces.is_empty() && !omitted.is_empty() {
                return Err(RemeshError::Region {
                    region: omitted[0],
                    what: "no region could be meshed",
                });
            }
            match self.triangulate_and_join(positions.clone(), &mut pieces) {
                Err(RemeshError::Region { region, .. })
                    if self.leave_out && pieces.iter().any(|p| p.region == region) =>
                {
                    pieces.retain(|p| p.region != region);
                    omitted.push(region);
                }
                Err(e) => return Err(e),
                Ok(mut out) => {
                    omitted.sort_unstable();
                    omitted.dedup();
                    out.check.omitted_regions = omitted.len();
                    out.omitted = omitted;
                    return Ok(Some(out));
                }
            }
        }
    }

    /// Triangulates every piece, sharing the budget among them, and joins them.
    fn triangulate_and_join(
        &self,
        positions: Vec<DVec3>,
        pieces: &mut [Piece],
    ) -> Result<Remeshed, RemeshError> {
        let Plan {
            rep,
            options,
            budget,
            spacing,
            tolerance,
            ..
        } = *self;
        // The pool's points that no piece uses (pruned ears, loops that enclose nothing, the
        // loops of regions left out) are not in the mesh, and not counted against the budget.
        let boundary = boundary_in_use(pieces, positions.len());
        let meshes = match options.scheme {
            Scheme::Adaptive => triangulate_adaptive(
                pieces,
                boundary,
                budget,
                options.max_vertices,
                tolerance,
                spacing,
            )?,
            Scheme::Parametric => {
                triangulate_by_area(pieces, boundary, budget, min_spacing(spacing))?
            }
        };
        join(rep, options.max_vertices, positions, pieces, meshes)
    }

    /// The regions whose chart or boundary triangulation fails in this attempt, in
    /// increasing order, one fault per region; and whether the attempt has anything to mesh
    /// (some piece, and not a repeat: see [`Plan::mesh`]).
    fn faults(&self) -> Result<(Vec<RegionFault>, bool), RemeshError> {
        let mut faults = Vec::new();
        let Some((_, pieces)) = self.pieces(Some(&mut faults))? else {
            return Ok((Vec::new(), false));
        };
        // Stable: a whole ellipsoid's two halves keep their order.
        faults.sort_by_key(|f| f.region);
        faults.dedup_by_key(|f| f.region);
        Ok((faults, !pieces.is_empty()))
    }

    /// The boundary vertex pool and every piece in its chart, settled
    /// ([`settle_charts`]). With `faults`, a region whose chart or boundary triangulation
    /// fails is noted there and left out instead of ending the attempt.
    ///
    /// `None` when the attempt would repeat another, made in its place: with [`Prune::All`],
    /// no point was pruned that [`Prune::Narrow`] keeps; with
    /// [`Treatment::radial_where_untangled`], untangling charted no region radially.
    fn pieces(
        &self,
        mut faults: Option<&mut Vec<RegionFault>>,
    ) -> Result<Option<Pieces>, RemeshError> {
        let Plan {
            rep,
            options,
            spacing,
            areas,
            treatment,
            ..
        } = *self;
        let settings = treatment.settings(&self.settings);
        let mut refined = refine_arcs(rep, &settings);
        if settings.prune == Prune::All && refined.wide_ears == 0 {
            return Ok(None);
        }
        let mut projections = vec![treatment.projection; rep.region_count()];
        if treatment.untangle {
            projections = untangle(
                rep,
                &mut refined.arcs,
                &refined.points,
                treatment.radial_where_untangled,
                Charting {
                    projection: treatment.projection,
                    walk: treatment.pole_walk,
                    skip_degenerate: self.leave_out,
                    charts: self.charts,
                },
            );
        }
        if treatment.radial_where_untangled
            && projections.iter().all(|&p| p == treatment.projection)
        {
            return Ok(None);
        }
        let mut pool = Pool::new(&refined.points);
        let surface_piece = surface_pieces(rep);
        let mut pieces = Vec::with_capacity(rep.region_count());
        for (r, cycles) in rep.cycles.iter().enumerate() {
            let region = r as u32;
            let on = surface_piece.get(r).copied().unwrap_or(region);
            let Some(ellipsoid) = rep.ellipsoids.get(r) else {
                continue;
            };
            let area = areas.get(r).copied().unwrap_or(0.0);
            if cycles.is_empty() {
                let equator_budget = options.max_vertices.saturating_sub(pool.positions.len());
                let halves = split_whole(region, ellipsoid, spacing, equator_budget, &mut pool);
                let Some(halves) = noted(halves, faults.as_deref_mut())? else {
                    continue;
                };
                pieces.extend(halves.map(|mut p| {
                    p.area = area / 2.0;
                    p.with_offsets(spacing)
                }));
                continue;
            }
            let mut loops = Vec::with_capacity(cycles.len());
            for cycle in cycles {
                let mut lp = Vec::new();
                for r in &cycle.arcs {
                    let Some(chain) = refined.arcs.get(r.arc as usize) else {
                        continue;
                    };
                    let closed = rep.arcs.get(r.arc as usize).is_some_and(|a| a.closed);
                    let ids: Vec<u32> = if r.reversed {
                        chain.iter().rev().map(|&i| pool.id(i, on)).collect()
                    } else {
                        chain.iter().map(|&i| pool.id(i, on)).collect()
                    };
                    // Consecutive open arcs share their junction: skip each one's first point.
                    lp.extend(ids.into_iter().skip(usize::from(!closed)));
                }
                let lp = without_spikes(without_repeats(lp));
                // A loop that encloses nothing (two arcs that are the same segment between
                // two junctions, or a tiny region's boundary whose points quantisation
                // merged) is dropped, and the regions on its other sides, which see the same
                // points the other way, are glued directly. The region keeps its other
                // loops, even when the dropped one is its outer one: on a closed surface
                // which loop is outer is a choice (the encoder takes the one around the
                // most area), and without them the regions across them would face a hole.
                // With no loop left the region is empty.
                if lp.len() >= 3 {
                    loops.push(lp);
                }
            }
            // A region whose every boundary edge is a seam lies on both sides of all its
            // boundary and closes on itself: it is left out, and said so, as it was when its
            // loops crossed (meshing it as its whole ellipsoid is for a later change: such an
            // ellipsoid was fitted to a patch, and may reach far beyond it).
            let had_loops = !loops.is_empty();
            let loops: Vec<Vec<u32>> = without_seams(loops)
                .into_iter()
                .filter(|l| l.len() >= 3)
                .collect();
            if had_loops && loops.is_empty() {
                match faults.as_deref_mut() {
                    Some(f) => f.push(RegionFault {
                        region,
                        crossing: None,
                        seam: true,
                    }),
                    None => {
                        return Err(RemeshError::Region {
                            region,
                            what: "every boundary edge is a seam (the region closes on itself)",
                        })
                    }
                }
                continue;
            }
            if loops.is_empty() {
                continue;
            }
            let loop_points: Vec<Vec<DVec3>> = loops
                .iter()
                .map(|l| l.iter().map(|&v| pool.position(v)).collect())
                .collect();
            let stand_in = chart_surface(ellipsoid, &loop_points);
            let projection = projections.get(r).copied().unwrap_or(treatment.projection);
            // Where untangling left the loops as they are, the chart it made ([`ChartMemo`]).
            let chart = self.charts.chart(
                region,
                &stand_in,
                &loop_points,
                projection_onto(&stand_in, ellipsoid, projection),
                treatment.pole_walk,
            );
            let Some(chart) = noted(chart, faults.as_deref_mut())? else {
                continue;
            };
            // Meshed on a stand-in, the points go back onto the region's ellipsoid the way
            // the boundary came to the stand-in.
            let lift = match chart.projection() {
                _ if stand_in == *ellipsoid => Lift::None,
                Projection::NormalOnto(e) => Lift::Closest(e),
                _ => Lift::Radial(*ellipsoid),
            };
            let surface = RegionSurface::lifted(chart, lift);
            pieces.push(
                Piece::new(region, surface, &loops, &pool.positions, area).with_offsets(spacing),
            );
        }
        for piece in &mut pieces {
            piece.expected_vertices = expected_vertices(piece.area, spacing);
        }
        if pool.positions.len() > options.max_vertices {
            return Err(RemeshError::TooManyVertices {
                needed: pool.positions.len(),
                max: options.max_vertices,
            });
        }

        settle_charts(rep, &mut pieces, spacing, faults)?;
        Ok(Some((pool.positions, pieces)))
    }
}

/// The boundary vertex pool and the pieces meshed on it.
type Pieces = (Vec<DVec3>, Vec<Piece>);

/// How many of a pool of `pool` boundary vertices the pieces' loops use.
fn boundary_in_use(pieces: &[Piece], pool: usize) -> usize {
    let mut used = vec![false; pool];
    for &v in pieces.iter().flat_map(|p| &p.global) {
        if let Some(u) = used.get_mut(v as usize) {
            *u = true;
        }
    }
    used.iter().filter(|&&u| u).count()
}

/// `result`'s value; with `faults`, a region error is noted there instead (`None`: the
/// region is left out) rather than returned.
fn noted<T>(
    result: Result<T, RemeshError>,
    faults: Option<&mut Vec<RegionFault>>,
) -> Result<Option<T>, RemeshError> {
    match (result, faults) {
        (Ok(value), _) => Ok(Some(value)),
        (Err(RemeshError::Region { region, .. }), Some(f)) => {
            f.push(RegionFault {
                region,
                crossing: None,
                seam: false,
            });
            Ok(None)
        }
        (Err(e), _) => Err(e),
    }
}

/// Most rounds of [`untangle`].
const UNTANGLE_ROUNDS: usize = 8;

/// Loops longer than this (in total, per region) are not untangled: the sweep could be
/// quadratic on a hostile file.
const UNTANGLE_MAX_POINTS: usize = 200_000;

/// Removes arc points until no region's loops cross in its chart, where that can be done by
/// dropping points inside arcs (junctions stay).
///
/// The chart sees the boundary along rays from the ellipsoid's centre; where the real
/// surface is not star-shaped from there (common on real meshes, which the ellipsoid only
/// approximates), the projected boundary can fold over itself. Each crossing drops an
/// endpoint of one of the crossing segments from the arc it belongs to, for both regions
/// the arc separates; a few rounds settle it. Deterministic. `first` says how the regions
/// are charted (and with which projection first); returns the projection each region's
/// loops came out uncrossed in (their charts stay in `first`'s [`ChartMemo`]).
fn untangle(
    rep: &Representation,
    chains: &mut [Vec<u32>],
    points: &[DVec3],
    radial_where_crossing: bool,
    first: Charting,
) -> Vec<Projection> {
    let projection = first.projection;
    let charting = |projection| Charting {
        projection,
        ..first
    };
    // Regions whose loops changed since they were last looked at: the others would find
    // the same crossings, whose drops were refused.
    let mut changed = vec![true; rep.cycles.len()];
    let mut projections = vec![projection; rep.cycles.len()];
    for round in 0..UNTANGLE_ROUNDS {
        // (arc, position in its chain) of the points to drop.
        let mut drop: Vec<(u32, usize)> = Vec::new();
        for (r, cycles) in rep.cycles.iter().enumerate() {
            if cycles.is_empty() || !changed[r] {
                continue;
            }
            let before = drop.len();
            let (_, crossings) = region_crossings(
                r as u32,
                rep,
                chains,
                points,
                charting(projections[r]),
                &mut drop,
            );
            // Untangling drops boundary points until the loops stop crossing, down to a
            // triangle when a whole loop folds (the closest points of a boundary deep
            // inside a thin ellipsoid jump between its sides: a bunny's ear became one
            // triangle, turned over). Where the rays from the centre see the loops
            // uncrossed, they chart the region instead.
            if radial_where_crossing && round == 0 && crossings > 0 {
                let mut radial_drop = Vec::new();
                let (radial, radial_crossings) = region_crossings(
                    r as u32,
                    rep,
                    chains,
                    points,
                    charting(Projection::Radial),
                    &mut radial_drop,
                );
                if radial.is_some() && radial_crossings == 0 {
                    drop.truncate(before);
                    projections[r] = Projection::Radial;
                }
            }
        }
        if drop.is_empty() {
            return projections;
        }
        changed.fill(false);
        drop.sort_unstable();
        drop.dedup();
        // Remove from the back of each chain so that positions stay valid.
        for &(arc, at) in drop.iter().rev() {
            let Some(a) = rep.arcs.get(arc as usize) else {
                continue;
            };
            if let Some(chain) = chains.get_mut(arc as usize) {
                let min_len = if a.closed { 3 } else { 2 };
                if chain.len() > min_len && at < chain.len() {
                    chain.remove(at);
                    for side in [Some(a.left), a.right.region()] {
                        if let Some(flag) = side.and_then(|r| changed.get_mut(r as usize)) {
                            *flag = true;
                        }
                    }
                }
            }
        }
    }
    projections
}

/// Where a loop point sits in the refined arcs, if it may be dropped: (arc, position).
type Droppable = Option<(u32, usize)>;

/// How [`region_crossings`] charts a region's loops.
#[derive(Debug, Clone, Copy)]
struct Charting<'a> {
    projection: Projection,
    walk: PoleWalk,
    /// Loops that enclose nothing are left out (the decoder's last resort:
    /// [`Plan::leave_out`]).
    skip_degenerate: bool,
    /// Where the charts are made ([`Plan::charts`]).
    charts: &'a ChartMemo,
}

/// Finds the crossings of one region's loops in its chart and, for each, a point to drop
/// (where one of the two segments has a point that may be dropped); returns how many loops
/// were charted (`None`: the region has no chart) and the number of crossings, droppable
/// or not. The chart stays in `charting`'s [`ChartMemo`], for meshing to find.
fn region_crossings(
    region: u32,
    rep: &Representation,
    chains: &[Vec<u32>],
    points: &[DVec3],
    charting: Charting,
    drop: &mut Vec<(u32, usize)>,
) -> (Option<usize>, usize) {
    let Charting {
        projection,
        walk,
        skip_degenerate,
        charts,
    } = charting;
    let (Some(e), Some(cycles)) = (
        rep.ellipsoids.get(region as usize),
        rep.cycles.get(region as usize),
    ) else {
        return (None, 0);
    };
    // Each loop vertex with the (arc, position) it can be dropped as, if any.
    let mut loops: Vec<Vec<(DVec3, Droppable)>> = Vec::new();
    for cycle in cycles {
        let mut lp = Vec::new();
        for r in &cycle.arcs {
            let Some(chain) = chains.get(r.arc as usize) else {
                continue;
            };
            let closed = rep.arcs.get(r.arc as usize).is_some_and(|a| a.closed);
            let n = chain.len();
            let order: Vec<usize> = if r.reversed {
                (0..n).rev().collect()
            } else {
                (0..n).collect()
            };
            for &k in order.iter().skip(usize::from(!closed)) {
                let removable = closed || (k > 0 && k + 1 < n);
                let p = chain.get(k).and_then(|&i| points.get(i as usize)).copied();
                if let Some(p) = p {
                    lp.push((p, removable.then_some((r.arc, k))));
                }
            }
        }
        // With `skip_degenerate`, a loop that encloses nothing (fewer than 3 distinct
        // directions: a scan's slit, or a hole whose duplicated vertices quantisation put
        // at one position), which the meshing drops too, is left out here: it fails the
        // chart, and the whole region would go untangled.
        let degenerate = || {
            let positions: Vec<DVec3> = lp.iter().map(|v| v.0).collect();
            is_degenerate_loop(e, &positions)
        };
        if lp.len() >= 3 && !(skip_degenerate && degenerate()) {
            loops.push(lp);
        }
    }
    let total: usize = loops.iter().map(Vec::len).sum();
    if loops.is_empty() || total > UNTANGLE_MAX_POINTS {
        return (None, 0);
    }
    let loop_points: Vec<Vec<DVec3>> = loops
        .iter()
        .map(|l| l.iter().map(|v| v.0).collect())
        .collect();
    let surface = chart_surface(e, &loop_points);
    let Ok(chart) = charts.chart(
        region,
        &surface,
        &loop_points,
        projection_onto(&surface, e, projection),
        walk,
    ) else {
        return (None, 0);
    };
    // Segments in the plane: (a, b, which point to drop if it crosses). Each point is
    // charted once (its closest point is iterative), not once per segment.
    let mut segments: Vec<(glam::DVec2, glam::DVec2, Droppable)> = Vec::new();
    for (lp, points) in loops.iter().zip(&loop_points) {
        let planes: Vec<glam::DVec2> = points.iter().map(|&p| chart.to_plane(p)).collect();
        for (k, (&a, &(_, tag))) in planes.iter().zip(lp).enumerate() {
            let next = (k + 1) % lp.len();
            let (b, next_tag) = (planes[next], lp[next].1);
            if a.is_finite() && b.is_finite() {
                segments.push((a, b, tag.or(next_tag)));
            }
        }
    }
    segments.sort_by(|s, t| s.0.x.min(s.1.x).total_cmp(&t.0.x.min(t.1.x)));
    let mut crossings = 0;
    for (i, s) in segments.iter().enumerate() {
        let max_x = s.0.x.max(s.1.x);
        for t in segments.iter().skip(i + 1) {
            if t.0.x.min(t.1.x) > max_x {
                break;
            }
            if segments_cross(s.0, s.1, t.0, t.1) {
                crossings += 1;
                if let Some(tag) = s.2.or(t.2) {
                    drop.push(tag);
                }
            }
        }
    }
    (Some(loop_points.len()), crossings)
}

/// Whether two segments cross at a point inside both (shared endpoints do not count).
fn segments_cross(p1: glam::DVec2, p2: glam::DVec2, q1: glam::DVec2, q2: glam::DVec2) -> bool {
    let cross = |a: glam::DVec2, b: glam::DVec2| a.x * b.y - a.y * b.x;
    let d1 = cross(p2 - p1, q1 - p1);
    let d2 = cross(p2 - p1, q2 - p1);
    let d3 = cross(q2 - q1, p1 - q1);
    let d4 = cross(q2 - q1, p2 - q1);
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

/// Regions without cycles: whole ellipsoids.
fn whole_regions(rep: &Representation) -> impl Iterator<Item = usize> + '_ {
    rep.cycles
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_empty())
        .map(|(r, _)| r)
}

/// The global vertex pool: refined boundary points, each position once per piece of the
/// surface.
///
/// Points at one position are one vertex, so that the regions around a loop quantisation
/// collapsed are glued directly (see [`Plan::pieces`]); but only within one piece of the
/// surface ([`surface_pieces`]). Separate pieces whose borders quantisation brought
/// together stay apart, as they were in the source: glued, two such borders became one edge
/// run the same way by both its faces (Wuson, a toy from assimp's test models whose
/// whiskers are crossed cards, decoded not consistently oriented). So do points the pieces
/// share: each piece has its own vertex at one ([`Pool::id`]).
struct Pool<'a> {
    refined: &'a [DVec3],
    /// Refined point index → the vertex id it was first given and its piece of the surface
    /// (u32::MAX: not yet used).
    id_of: Vec<(u32, u32)>,
    /// (piece of the surface, position) → vertex id.
    by_position: HashMap<(u32, [u64; 3]), u32>,
    positions: Vec<DVec3>,
}

impl<'a> Pool<'a> {
    fn new(refined: &'a [DVec3]) -> Pool<'a> {
        Pool {
            refined,
            id_of: vec![(u32::MAX, u32::MAX); refined.len()],
            by_position: HashMap::new(),
            positions: Vec::new(),
        }
    }

    /// The vertex of refined point `i` (indices come from [`refine_arcs`], so in range) on
    /// piece `piece` of the surface. A point that two pieces share (two fins of a scan on
    /// one non-manifold edge, each a piece of its own) is a vertex on each: joined, the fins
    /// of Stanford's dragon at `res4` made an edge run the same way by both its faces.
    fn id(&mut self, i: u32, piece: u32) -> u32 {
        match self.id_of.get(i as usize) {
            Some(&(id, on)) if id != u32::MAX && on == piece => id,
            Some(&(id, _)) => {
                let p = self.refined.get(i as usize).copied().unwrap_or_default();
                let new = self.add(p, piece);
                if id == u32::MAX {
                    if let Some(slot) = self.id_of.get_mut(i as usize) {
                        *slot = (new, piece);
                    }
                }
                new
            }
            None => 0,
        }
    }

    /// A vertex at `p` on piece `piece` of the surface: the existing one at exactly this
    /// position on that piece, or a new one.
    fn add(&mut self, p: DVec3, piece: u32) -> u32 {
        // +0.0 and −0.0 are the same position.
        let key = (piece, (p + DVec3::ZERO).to_array().map(f64::to_bits));
        let next = self.positions.len() as u32;
        *self.by_position.entry(key).or_insert_with(|| {
            self.positions.push(p);
            next
        })
    }

    fn position(&self, v: u32) -> DVec3 {
        self.positions.get(v as usize).copied().unwrap_or_default()
    }
}

/// Per region, the piece of the surface it lies on: the smallest region reached from it
/// across arcs between two regions. Two pieces of the source that touch only at a vertex
/// or along border edges count as two, each with a vertex of its own there ([`Pool`]).
fn surface_pieces(rep: &Representation) -> Vec<u32> {
    let n = rep.region_count();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for arc in &rep.arcs {
        let (a, Some(b)) = (arc.left, arc.right.region()) else {
            continue;
        };
        if (a as usize) < n && (b as usize) < n {
            join_sets(&mut parent, a, b);
        }
    }
    (0..n as u32).map(|r| find_root(&mut parent, r)).collect()
}

/// `ids` as a closed loop without consecutive repeats (the last compared with the first).
fn without_repeats(ids: Vec<u32>) -> Vec<u32> {
    let mut out: Vec<u32> = Vec::with_capacity(ids.len());
    for v in ids {
        if out.last() != Some(&v) {
            out.push(v);
        }
    }
    while out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    out
}

/// `ids`, a closed loop without consecutive repeats, without its spikes: wherever it runs
/// to a point and straight back (u → v → u), v and the return are dropped, until none is
/// left. A spike encloses nothing, and its edge, used twice, cannot be a constraint of the
/// region's triangulation twice; it comes from a non-manifold edge (a border to each of its
/// faces) that a region touches from two sides, or two arcs between the same junctions
/// simplified to the same segment.
fn without_spikes(ids: Vec<u32>) -> Vec<u32> {
    // One pass in order: a point that returns to the one before the last kept drops the last
    // (the tip) and is not kept itself (the return). Linear: each point is kept and dropped
    // at most once.
    let mut kept: VecDeque<u32> = VecDeque::with_capacity(ids.len());
    for id in ids {
        if kept.len() >= 2 && kept[kept.len() - 2] == id {
            kept.pop_back();
        } else {
            kept.push_back(id);
        }
    }
    // Then across the seam, where the loop closes: a tip at the end (…, u, v | u, …) or at
    // the start (…, u | v, u, …). Each removal leaves only the seam to look at again.
    while kept.len() >= 3 {
        let n = kept.len();
        if kept[n - 2] == kept[0] {
            kept.pop_back();
            kept.pop_front();
        } else if kept[n - 1] == kept[1] {
            kept.pop_front();
            kept.pop_front();
        } else {
            break;
        }
    }
    kept.into()
}

/// A region's loops (pool vertices, the region on their left, no spikes:
/// [`without_spikes`]) without their seams: wherever one loop runs u → v and the same or
/// another loop v → u, both edges are dropped and the loops re-joined around them.
///
/// Such a pair is an edge the region lies on both sides of, a border to each of its faces:
/// a non-manifold edge that import cut (a CAD model's plates meeting a third face along
/// an edge, assimp's `regr01`), or two border arcs a scan's region closes on itself along.
/// Kept, it is a slit of zero width, the same segment constrained twice, which no chart can
/// triangulate (the region's loops "cross" and it was left out). Dropped, the region is
/// meshed across the edge, as the source's faces on its two sides were one surface; no other
/// region shares the edge (both its arcs are border arcs of this region).
///
/// Re-joining is the half-edge rule: a kept edge is followed by the next edge of its loop,
/// or, where that one was dropped, by whatever follows its partner (and so on). One pair
/// within one loop splits it in two (u … u and v … v); a pair across two loops joins them.
/// Loops without such a pair are returned as they are.
fn without_seams(loops: Vec<Vec<u32>>) -> Vec<Vec<u32>> {
    // Both ends of a pair come twice in the loops, unless the pair is a loop of two points:
    // most regions have neither, and are told so without hashing their edges.
    let mut points: Vec<u32> = loops.concat();
    points.sort_unstable();
    if loops.iter().all(|l| l.len() > 2) && !points.windows(2).any(|w| w[0] == w[1]) {
        return loops;
    }
    // Edge e runs from `from[e]` to the start of `next[e]`, the edge after it in its loop.
    let mut from = Vec::new();
    let mut next = Vec::new();
    for lp in &loops {
        let base = from.len();
        from.extend_from_slice(lp);
        next.extend((0..lp.len()).map(|k| base + (k + 1) % lp.len()));
    }
    // The edges u → v by (u, v), in order; the k-th of u → v is paired with the k-th of v → u.
    let mut by_ends: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for e in 0..from.len() {
        by_ends.entry((from[e], from[next[e]])).or_default().push(e);
    }
    let mut partner = vec![usize::MAX; from.len()];
    let mut paired = false;
    for (&(u, v), forward) in &by_ends {
        if u >= v {
            continue;
        }
        for (&a, &b) in forward
            .iter()
            .zip(by_ends.get(&(v, u)).into_iter().flatten())
        {
            partner[a] = b;
            partner[b] = a;
            paired = true;
        }
    }
    if !paired {
        return loops;
    }
    // The kept edge after kept edge `e` (None if the dropped ones around it lead nowhere).
    let follow = |e: usize| {
        let mut f = next[e];
        for _ in 0..from.len() {
            match partner[f] {
                usize::MAX => return Some(f),
                p => f = next[p],
            }
        }
        None
    };
    let mut seen = vec![false; from.len()];
    let mut out = Vec::new();
    for start in 0..from.len() {
        if partner[start] != usize::MAX || seen[start] {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = start;
        while !seen[e] {
            seen[e] = true;
            lp.push(from[e]);
            match follow(e) {
                Some(f) => e = f,
                None => break,
            }
        }
        out.push(lp);
    }
    out
}

/// One piece to triangulate: a region, or half of a whole-ellipsoid region.
struct Piece {
    region: u32,
    /// The surface it is meshed on: its chart, how the chart's points reach the region's
    /// ellipsoid, and (once [`Piece::with_offsets`] ran) the boundary's offsets.
    surface: RegionSurface,
    /// Positions of the piece's boundary vertices, local numbering.
    boundary: Vec<DVec3>,
    /// Loops in local numbering.
    loops: Vec<Vec<u32>>,
    /// Local boundary vertex → pool vertex.
    global: Vec<u32>,
    /// Estimated area (model units²).
    area: f64,
    /// About how many vertices it ends with ([`RegionInput::expected_vertices`]).
    expected_vertices: usize,
    /// Its boundary-only adaptive triangulation, once [`settle_charts`] built it (taken by
    /// [`triangulate_adaptive`], which would otherwise build the same again).
    start: Option<AdaptiveTriangulation>,
    /// For a whole ellipsoid's half ([`split_whole`]): its pole, its first interior vertex
    /// ([`RegionInput::seeds`]).
    pole: Option<DVec3>,
}

impl Piece {
    fn new(
        region: u32,
        surface: RegionSurface,
        loops: &[Vec<u32>],
        positions: &[DVec3],
        area: f64,
    ) -> Piece {
        let mut local: HashMap<u32, u32> = HashMap::new();
        let mut global = Vec::new();
        let mut boundary = Vec::new();
        let loops = loops
            .iter()
            .map(|l| {
                l.iter()
                    .map(|&v| {
                        *local.entry(v).or_insert_with(|| {
                            global.push(v);
                            boundary.push(positions.get(v as usize).copied().unwrap_or_default());
                            (global.len() - 1) as u32
                        })
                    })
                    .collect()
            })
            .collect();
        Piece {
            region,
            surface,
            boundary,
            loops,
            global,
            area,
            expected_vertices: 0,
            start: None,
            pole: None,
        }
    }

    /// The piece with its boundary's offsets blended into its surface
    /// ([`RegionSurface::with_offsets`]) over bands at least `min_band` wide.
    fn with_offsets(self, min_band: f64) -> Piece {
        let surface = self
            .surface
            .with_offsets(&self.boundary, &self.loops, min_band);
        Piece { surface, ..self }
    }

    /// The chart seen from beneath the region, for a region whose boundary, projected from
    /// its ellipsoid's centre, crosses itself (a region that is not star-shaped from there:
    /// common on real meshes, where the ellipsoid only approximates the surface). The point
    /// of view lies below the boundary's centroid, against the mean outward normal, twice
    /// the region's reach deep; the chart surface is the sphere around it through the
    /// centroid (positive: the mesh's outward side faces away from the point of view).
    fn view_from_beneath(&self, e: &Ellipsoid) -> Option<Piece> {
        let n = self.boundary.len();
        if n == 0 {
            return None;
        }
        let centroid = self.boundary.iter().copied().sum::<DVec3>() / n as f64;
        let normal = self
            .boundary
            .iter()
            .map(|&p| e.normal(p))
            .sum::<DVec3>()
            .try_normalize()?;
        let reach = self
            .boundary
            .iter()
            .map(|&p| (p - centroid).length())
            .fold(0.0, f64::max);
        let origin = centroid - 2.0 * reach * normal;
        let sphere = Ellipsoid::sphere(origin, 2.0 * reach);
        if !(sphere.is_valid() && origin.is_finite()) {
            return None;
        }
        let loops: Vec<Vec<DVec3>> = self
            .loops
            .iter()
            .map(|l| {
                l.iter()
                    .map(|&i| self.boundary.get(i as usize).copied().unwrap_or_default())
                    .collect()
            })
            .collect();
        let chart = RegionChart::with_projection(
            self.region,
            &sphere,
            &loops,
            Projection::Closest,
            PoleWalk::Free,
        )
        .ok()?;
        // Interior points go along the rays from the point of view onto the ellipsoid.
        let lift = Lift::FromPoint {
            origin,
            ellipsoid: *e,
        };
        Some(Piece {
            surface: RegionSurface::lifted(chart, lift),
            boundary: self.boundary.clone(),
            loops: self.loops.clone(),
            global: self.global.clone(),
            start: None,
            ..*self
        })
    }

    fn input(&self) -> RegionInput<'_> {
        RegionInput {
            region: self.region,
            surface: &self.surface,
            boundary: &self.boundary,
            loops: &self.loops,
            seeds: self.pole.as_slice(),
            expected_vertices: self.expected_vertices,
        }
    }
}

/// About how many vertices a piece of `area` meshed at the target edge length `spacing`
/// ends with: its share of the budget by area, as the spacing was found from the budget
/// ([`prepare`]), half as much again for regions curved more than the mean (vertex
/// addition shares the budget by error, not area). A capacity hint, at most
/// [`MAX_EXPECTED_VERTICES`].
fn expected_vertices(area: f64, spacing: f64) -> usize {
    let share = 1.5 * 2.0 * area / (3f64.sqrt() * spacing * spacing);
    if share.is_finite() && share > 0.0 {
        (share as usize).min(MAX_EXPECTED_VERTICES)
    } else {
        0
    }
}

/// The most vertices [`expected_vertices`] reserves room for: the budgets vertex addition
/// meets by itself (larger ones are met by subdivision).
const MAX_EXPECTED_VERTICES: usize = 1 << 16;

/// Builds every piece's boundary-only adaptive triangulation (kept in [`Piece::start`]),
/// replacing the chart of a piece whose triangulation fails by the view from beneath it, if
/// that one triangulates; otherwise returns the first failure. With `faults`, every piece
/// that fails is noted there instead. `spacing` is the target edge length (the offsets'
/// band; a quarter of it the minimum spacing of vertex addition).
fn settle_charts(
    rep: &Representation,
    pieces: &mut [Piece],
    spacing: f64,
    mut faults: Option<&mut Vec<RegionFault>>,
) -> Result<(), RemeshError> {
    let min_spacing = min_spacing(spacing);
    for piece in pieces.iter_mut() {
        let error = match AdaptiveTriangulation::new(&piece.input(), min_spacing) {
            Ok(start) => {
                piece.start = Some(start);
                continue;
            }
            Err(error) => error,
        };
        let other = rep
            .ellipsoids
            .get(piece.region as usize)
            .and_then(|e| piece.view_from_beneath(e))
            .map(|p| p.with_offsets(spacing));
        let started = other.and_then(|mut other| {
            let start = AdaptiveTriangulation::new(&other.input(), min_spacing).ok()?;
            other.start = Some(start);
            Some(other)
        });
        match started {
            Some(other) => {
                *piece = other;
            }
            _ => match faults.as_deref_mut() {
                Some(f) => f.push(RegionFault {
                    region: piece.region,
                    crossing: boundary_crossing(&piece.input()),
                    seam: false,
                }),
                None => return Err(error),
            },
        }
    }
    Ok(())
}

/// How much longer than the region's reach (its boundary's largest distance from the
/// centre) a radius may be before the chart uses a stand-in ellipsoid.
const MAX_RADIUS_TO_REACH: f64 = 4.0;

/// The ellipsoid a region's chart and triangulation use: the region's own, unless a radius
/// is far longer than the region's reach (fits to nearly flat or cylindrical parts give radii
/// of thousands); the unit-sphere map then squeezes the region into a sliver where quantised
/// boundary points cross. The stand-in has the same centre, rotation and sign and its radii
/// capped at [`MAX_RADIUS_TO_REACH`] times the reach, so the region's shape in the chart is
/// sound; interior points go back onto the real ellipsoid the way boundary points came to
/// the stand-in ([`projection_onto`]): to their closest points, or along the rays from the
/// centre.
fn chart_surface(e: &Ellipsoid, loops: &[Vec<DVec3>]) -> Ellipsoid {
    let reach = loops
        .iter()
        .flatten()
        .map(|&p| (p - e.center).length())
        .fold(0.0, f64::max);
    let cap = MAX_RADIUS_TO_REACH * reach;
    if !(cap.is_finite() && cap > 0.0) || e.radii.max_element() <= cap {
        return *e;
    }
    Ellipsoid {
        radii: e.radii.min(DVec3::splat(cap)),
        ..*e
    }
}

/// How boundary points reach a chart's surface: as `preferred` on the region's own
/// ellipsoid. On a stand-in ([`chart_surface`]) with the closest points preferred, the
/// closest point is taken on the real ellipsoid and carried along its inward normal to the
/// stand-in, and interior points go back to their closest points on the real ellipsoid
/// ([`Lift::Closest`]): the stand-in's cross-sections are the real one's where the region
/// is, so that map barely stretches (along the rays from the centre, a region far out
/// along a nearly cylindrical ellipsoid was stretched into triangles a fifth of the
/// diagonal long, folded round the cylinder). With radial projections preferred, both go
/// along the rays.
fn projection_onto(
    surface: &Ellipsoid,
    ellipsoid: &Ellipsoid,
    preferred: Projection,
) -> Projection {
    match preferred {
        Projection::Closest if surface != ellipsoid => Projection::NormalOnto(*ellipsoid),
        other => other,
    }
}

/// A whole ellipsoid cut along its local equator into two halves sharing the equator's
/// points, each in its own chart (whose pole is then the other half's pole) and with its
/// own pole as its first interior vertex ([`RegionInput::seeds`]), whichever scheme
/// meshes it.
fn split_whole(
    region: u32,
    e: &Ellipsoid,
    spacing: f64,
    max_points: usize,
    pool: &mut Pool<'_>,
) -> Result<[Piece; 2], RemeshError> {
    let on_equator = |t: f64| e.from_unit_sphere(DVec3::new(t.cos(), t.sin(), 0.0));
    let samples = 256;
    let circumference: f64 = (0..samples)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / samples as f64;
            let t1 = std::f64::consts::TAU * (k + 1) as f64 / samples as f64;
            (on_equator(t1) - on_equator(t)).length()
        })
        .sum();
    let wanted = (circumference / spacing).ceil();
    let count = if wanted.is_finite() {
        (wanted as usize).clamp(MIN_EQUATOR_POINTS, max_points.max(MIN_EQUATOR_POINTS))
    } else {
        MIN_EQUATOR_POINTS
    };
    let ring: Vec<u32> = (0..count)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / count as f64;
            pool.add(on_equator(t), region)
        })
        .collect();
    let ring = without_repeats(ring);
    if ring.len() < 3 {
        return Err(RemeshError::Region {
            region,
            what: "ellipsoid too small to mesh",
        });
    }
    // Increasing angle is counter-clockwise seen from local +z: the northern half is on its
    // left when the normal points outward (positive sign), the southern half when it points
    // inward (negative sign).
    let reversed: Vec<u32> = ring.iter().rev().copied().collect();
    let (north_loop, south_loop) = match e.sign {
        crate::ellipsoid::Sign::Positive => (ring, reversed),
        crate::ellipsoid::Sign::Negative => (reversed, ring),
    };
    let half = |lp: Vec<u32>, pole: DVec3| -> Result<Piece, RemeshError> {
        let points: Vec<DVec3> = lp.iter().map(|&v| pool.position(v)).collect();
        let chart = RegionChart::new(region, e, &[points])?;
        Ok(Piece {
            pole: Some(e.from_unit_sphere(pole)),
            ..Piece::new(
                region,
                RegionSurface::new(chart),
                &[lp],
                &pool.positions,
                0.0,
            )
        })
    };
    Ok([half(north_loop, DVec3::Z)?, half(south_loop, DVec3::NEG_Z)?])
}

/// The minimum spacing of vertex addition for a target edge length `spacing`: a quarter of
/// it. [`settle_charts`] and [`triangulate_adaptive`] must agree on it, since the latter
/// takes over the triangulations the former built.
fn min_spacing(spacing: f64) -> f64 {
    spacing / 4.0
}

/// Adaptive scheme: the budget shared by error through a max-heap of the pieces' worst
/// errors (section 5.3). Mending faces turned against their ellipsoid can remove interior
/// vertices ([`AdaptiveTriangulation::finish`]); when that leaves the mesh short of the
/// budget by more than the 1 % it is honoured within ([`BUDGET_MET`]), vertex addition is
/// made again from the boundary-only triangulations with the shortfall added to the
/// budget (up to [`MAX_BUDGET_RETRIES`] times), and kept if it comes closer with no more
/// turned faces and within `max_vertices` (it can overshoot the budget, by less than it fell
/// short). CGAL's cow (its encoder's file) at 20 000 vertices lost 351 in six regions (155
/// of 779 in one) and decoded 19 649; 19 994 with this.
fn triangulate_adaptive(
    pieces: &mut [Piece],
    boundary_vertices: usize,
    budget: usize,
    max_vertices: usize,
    tolerance: Option<f64>,
    spacing: f64,
) -> Result<Vec<RegionMesh>, RemeshError> {
    let made = |meshes: &[RegionMesh]| {
        boundary_vertices + meshes.iter().map(|m| m.interior.len()).sum::<usize>()
    };
    let turned = |meshes: &[RegionMesh]| meshes.iter().map(|m| m.turned).sum::<usize>();
    let short = |made: usize| (made as f64) < BUDGET_MET * budget as f64;
    let (mut meshes, spent) = add_vertices(pieces, boundary_vertices, budget, tolerance, spacing)?;
    let mut asked = budget;
    for _ in 0..MAX_BUDGET_RETRIES {
        let kept = made(&meshes);
        if !spent || !short(kept) {
            break;
        }
        asked += budget - kept;
        let (again, _) = add_vertices(pieces, boundary_vertices, asked, tolerance, spacing)?;
        let remade = made(&again);
        if remade.abs_diff(budget) < kept.abs_diff(budget)
            && remade <= max_vertices
            && turned(&again) <= turned(&meshes)
        {
            meshes = again;
        }
    }
    Ok(meshes)
}

/// Most times [`triangulate_adaptive`] makes vertex addition again to make up for the
/// vertices mending removed. Two hemispheres whose boundary points are pulled to 0.6 of
/// their distance from the centre decode 4 681 vertices at 5 000 after one, 4 989 with
/// up to three (4 331 with none).
const MAX_BUDGET_RETRIES: usize = 3;

/// The share of its vertex budget the adaptive scheme's mesh has at least, as a rule: the
/// budget is honoured within 1 % (vertex addition is made again when mending removed more,
/// [`assemble`]). `ellip decode` notes a mesh below it.
pub const BUDGET_MET: f64 = 0.99;

/// Vertex addition for [`triangulate_adaptive`] to `budget` vertices in all, each piece
/// finished ([`mend_curved_splits`]); and whether the budget was spent (else the spacing or
/// the tolerance stopped it first).
fn add_vertices(
    pieces: &mut [Piece],
    boundary_vertices: usize,
    budget: usize,
    tolerance: Option<f64>,
    spacing: f64,
) -> Result<(Vec<RegionMesh>, bool), RemeshError> {
    // The triangulations settle_charts built (the same as built here: same input, same
    // spacing), else built again (a retry after a region was left out, or to make up for
    // vertices mending removed).
    let mut tris = pieces
        .iter_mut()
        .map(|piece| match piece.start.take() {
            Some(start) => Ok(start),
            None => AdaptiveTriangulation::new(&piece.input(), min_spacing(spacing)),
        })
        .collect::<Result<Vec<_>, _>>()?;
    let worst_of = |tris: &[AdaptiveTriangulation]| -> BinaryHeap<Worst> {
        tris.iter()
            .enumerate()
            .filter_map(|(i, t)| t.worst_error().map(|error| Worst { error, piece: i }))
            .collect()
    };
    let mut heap = worst_of(&tris);
    // Interior vertices the boundary-only triangulations already hold (sliver ears split).
    let mut total =
        boundary_vertices + tris.iter().map(AdaptiveTriangulation::added).sum::<usize>();
    let mut min_spacing = min_spacing(spacing);
    let mut relaxations = 0;
    while total < budget {
        let Some(worst) = heap.pop() else {
            // Every piece is as fine as the spacing allows but the budget is not spent: the
            // area estimate (hence the spacing) was too large, as for nearly flat regions
            // whose radii run into the thousands. Refinement goes on at a quarter of the
            // spacing, a few times.
            if relaxations >= MAX_SPACING_RELAXATIONS || tolerance.is_some() {
                break;
            }
            relaxations += 1;
            min_spacing /= 4.0;
            for t in &mut tris {
                t.set_min_spacing(min_spacing);
            }
            heap = worst_of(&tris);
            continue;
        };
        if tolerance.is_some_and(|t| worst.error <= t) {
            break;
        }
        let Some(t) = tris.get_mut(worst.piece) else {
            continue;
        };
        if t.insert_worst() {
            total += 1;
        }
        if let Some(error) = t.worst_error() {
            heap.push(Worst {
                error,
                piece: worst.piece,
            });
        }
    }
    let meshes = pieces
        .iter()
        .zip(tris)
        .map(|(piece, t)| mend_curved_splits(piece, t, min_spacing))
        .collect::<Result<_, _>>()?;
    Ok((meshes, total >= budget))
}

/// The piece's mesh; but where splitting faces far from the surface left a face turned
/// against the ellipsoid ([`AdaptiveTriangulation::made_curved_splits`]), the piece meshed
/// again with as many interior vertices and every face judged by its length alone
/// ([`AdaptiveTriangulation::judge_by_length`]), if that leaves fewer turned faces: a part
/// curved more sharply than the spacing then ends in a flat cut, but nothing is turned over.
/// dino at K = 8 (the encoder's file) decoded with 1 flipped triangle in each of 12 meshings
/// without this (a dino's leg, radii 0.46 × 0.030 × 0.034) and clean in one with it.
fn mend_curved_splits(
    piece: &Piece,
    t: AdaptiveTriangulation,
    min_spacing: f64,
) -> Result<RegionMesh, RemeshError> {
    let (curved, added) = (t.made_curved_splits(), t.added());
    let mesh = t.finish();
    if !curved || mesh.turned == 0 {
        return Ok(mesh);
    }
    let mut by_length = AdaptiveTriangulation::new(&piece.input(), min_spacing)?;
    by_length.judge_by_length();
    while by_length.added() < added && by_length.insert_worst() {}
    let again = by_length.finish();
    Ok(if again.turned < mesh.turned {
        again
    } else {
        mesh
    })
}

/// Most times [`triangulate_adaptive`] lowers the minimum spacing to spend its budget.
const MAX_SPACING_RELAXATIONS: usize = 3;

/// A heap entry: the worst error of a piece; ties go to the lower piece index.
#[derive(Debug, Clone, Copy)]
struct Worst {
    error: f64,
    piece: usize,
}

impl PartialEq for Worst {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Worst {}

impl PartialOrd for Worst {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Worst {
    fn cmp(&self, other: &Self) -> Ordering {
        self.error
            .total_cmp(&other.error)
            .then_with(|| other.piece.cmp(&self.piece))
    }
}

/// Parametric scheme: the interior budget shared by estimated area (largest remainders),
/// each piece gridded on its own (section 5.2).
fn triangulate_by_area(
    pieces: &[Piece],
    boundary_vertices: usize,
    budget: usize,
    min_spacing: f64,
) -> Result<Vec<RegionMesh>, RemeshError> {
    let interior = budget.saturating_sub(boundary_vertices);
    let total: f64 = pieces.iter().map(|p| p.area).sum();
    let mut shares: Vec<f64> = pieces
        .iter()
        .map(|p| {
            if total > 0.0 {
                interior as f64 * p.area / total
            } else {
                interior as f64 / pieces.len().max(1) as f64
            }
        })
        .collect();
    let mut counts: Vec<usize> = shares.iter().map(|s| s.floor() as usize).collect();
    let mut left = interior.saturating_sub(counts.iter().sum());
    let mut order: Vec<usize> = (0..pieces.len()).collect();
    order.sort_by(|&a, &b| {
        let ra = shares[a] - shares[a].floor();
        let rb = shares[b] - shares[b].floor();
        rb.total_cmp(&ra).then(a.cmp(&b))
    });
    for i in order {
        if left == 0 {
            break;
        }
        if let Some(c) = counts.get_mut(i) {
            *c += 1;
            left -= 1;
        }
    }
    // The grid gives about, not exactly, the asked count: each piece's request is scaled by
    // its own miss and the pieces gridded again, a few times. A thin band gets no grid point
    // until a row fits in it and then a whole row or more, so no round need come close:
    // each piece's mesh is chosen among its rounds' for the closest total
    // ([`closest_total`]).
    let mut rounds: Vec<Vec<RegionMesh>> = vec![Vec::new(); pieces.len()];
    let mut requests = counts;
    // The closest choice so far (a round per piece) and its miss.
    let mut closest: Option<(Vec<usize>, usize)> = None;
    for _ in 0..PARAMETRIC_ROUNDS {
        for ((p, &n), options) in pieces.iter().zip(&requests).zip(&mut rounds) {
            options.push(triangulate_parametric(&p.input(), n, min_spacing)?);
        }
        let got: Vec<usize> = rounds
            .iter()
            .map(|o| o.last().map_or(0, |m| m.interior.len()))
            .collect();
        pass_on_lost_shares(&mut shares, &requests, &got);
        for ((request, &made), share) in requests.iter_mut().zip(&got).zip(&shares) {
            // A piece the grid nearly misses must not ask for an unbounded count.
            let cap = 4.0 * share + 16.0;
            *request = (*request as f64 * share / made.max(1) as f64)
                .min(cap)
                .round() as usize;
        }
        let before = closest.as_ref().map_or(usize::MAX, |(_, miss)| *miss);
        let mut found = closest_total(&rounds, interior, None);
        if let Some((chosen, _)) = &closest {
            let from_closest = closest_total(&rounds, interior, Some(chosen));
            if from_closest.1 < found.1 {
                found = from_closest;
            }
        }
        let miss = found.1;
        if miss < before {
            closest = Some(found);
        }
        // Close enough, or no closer than without this round's meshes.
        if miss * 400 <= interior.max(1) || miss >= before {
            break;
        }
    }
    let chosen = closest.map(|(chosen, _)| chosen).unwrap_or_default();
    Ok(rounds
        .into_iter()
        .zip(chosen)
        .map(|(mut options, round)| options.swap_remove(round))
        .collect())
}

/// A piece whose grid had no point inside it for a positive request (`requests[i] > 0`,
/// `got[i] == 0`: a sliver of a chart on a flat part's ellipsoid, thousands of radii across,
/// which gets none at any request) passes its share on to the others, in proportion to
/// theirs: the total stays the same. assimp's binary spider decoded 4 070 vertices at 5 000
/// without this, `regr01` 658 at 20 000.
fn pass_on_lost_shares(shares: &mut [f64], requests: &[usize], got: &[usize]) {
    let mut lost = 0.0;
    for ((share, &asked), &made) in shares.iter_mut().zip(requests).zip(got) {
        if asked > 0 && made == 0 {
            lost += *share;
            *share = 0.0;
        }
    }
    let kept: f64 = shares.iter().sum();
    if lost > 0.0 && kept > 0.0 {
        for share in shares.iter_mut() {
            *share *= 1.0 + lost / kept;
        }
    }
}

/// Which of its rounds' meshes each piece takes (`rounds[piece][round]`, every piece gridded
/// in every round) for interior vertices totalling closest to `interior`, and the miss:
/// from `start` (else the best whole round), one piece's mesh swapped for another round's
/// while that brings the total closer (the largest gain first, the first piece and round
/// on a tie), at most [`MAX_ROUND_SWAPS`] times.
fn closest_total(
    rounds: &[Vec<RegionMesh>],
    interior: usize,
    start: Option<&[usize]>,
) -> (Vec<usize>, usize) {
    let count = |piece: usize, round: usize| rounds[piece][round].interior.len();
    let round_count = rounds.iter().map(Vec::len).min().unwrap_or(0);
    let total_of = |round: usize| (0..rounds.len()).map(|p| count(p, round)).sum::<usize>();
    let mut chosen = match start {
        Some(start) if start.len() == rounds.len() && start.iter().all(|&r| r < round_count) => {
            start.to_vec()
        }
        _ => match (0..round_count).min_by_key(|&r| total_of(r).abs_diff(interior)) {
            Some(first) => vec![first; rounds.len()],
            None => return (vec![0; rounds.len()], interior),
        },
    };
    let mut total: usize = chosen.iter().enumerate().map(|(p, &r)| count(p, r)).sum();
    for _ in 0..MAX_ROUND_SWAPS {
        let mut best: Option<(usize, usize, usize)> = None;
        for (piece, &now) in chosen.iter().enumerate() {
            for round in 0..round_count {
                let miss = (total - count(piece, now) + count(piece, round)).abs_diff(interior);
                if miss < best.map_or(total.abs_diff(interior), |(m, _, _)| m) {
                    best = Some((miss, piece, round));
                }
            }
        }
        let Some((_, piece, round)) = best else {
            break;
        };
        total = total - count(piece, chosen[piece]) + count(piece, round);
        chosen[piece] = round;
    }
    (chosen, total.abs_diff(interior))
}

/// Most swaps [`closest_total`] makes: each looks at every piece's every round, so a file
/// of many pieces costs a bounded number of passes over them.
const MAX_ROUND_SWAPS: usize = 64;

/// Most gridding rounds of the parametric scheme.
const PARAMETRIC_ROUNDS: usize = 4;

/// Joins the pieces' triangles into one mesh with analytic normals, then checks it.
fn join(
    rep: &Representation,
    max_vertices: usize,
    boundary: Vec<DVec3>,
    pieces: &[Piece],
    meshes: Vec<RegionMesh>,
) -> Result<Remeshed, RemeshError> {
    let mut positions = boundary;
    let mut faces = Vec::new();
    let mut face_regions = Vec::new();
    for (piece, m) in pieces.iter().zip(&meshes) {
        let first_interior = positions.len();
        positions.extend_from_slice(&m.interior);
        for tri in &m.triangles {
            let mut face = [0u32; 3];
            let mut ok = true;
            for (slot, corner) in face.iter_mut().zip(tri) {
                let v = match *corner {
                    Corner::Boundary(i) => piece.global.get(i as usize).copied(),
                    Corner::Interior(i) => u32::try_from(first_interior + i as usize).ok(),
                };
                match v {
                    Some(v) => *slot = v,
                    None => ok = false,
                }
            }
            if !ok || face[0] == face[1] || face[1] == face[2] || face[0] == face[2] {
                return Err(RemeshError::Region {
                    region: piece.region,
                    what: "the triangulation returned an invalid triangle",
                });
            }
            faces.push(face);
            face_regions.push(piece.region);
        }
    }
    let (positions, faces) = drop_unused(positions, faces);
    if positions.len() > max_vertices {
        return Err(RemeshError::TooManyVertices {
            needed: positions.len(),
            max: max_vertices,
        });
    }
    Ok(measured(rep, Mesh::new(positions, faces)?, face_regions))
}

/// A remeshed representation from its mesh and face regions: the analytic vertex normals
/// ([`vertex_normals`]) and the check ([`check_mesh`]) added.
pub(super) fn measured(rep: &Representation, mesh: Mesh, face_regions: Vec<u32>) -> Remeshed {
    let normals = vertex_normals(rep, mesh.positions(), mesh.faces(), &face_regions);
    let check = check_mesh(rep, &mesh, &face_regions);
    Remeshed {
        mesh,
        normals,
        face_regions,
        check,
        omitted: Vec::new(),
        attempts: 0,
        treatment: None,
    }
}

/// Removes vertices no face uses, renumbering the rest in order.
fn drop_unused(positions: Vec<DVec3>, mut faces: Vec<[u32; 3]>) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let mut new_index = vec![u32::MAX; positions.len()];
    for f in &faces {
        for &v in f {
            if let Some(slot) = new_index.get_mut(v as usize) {
                *slot = 0;
            }
        }
    }
    let mut kept = Vec::with_capacity(positions.len());
    for (slot, p) in new_index.iter_mut().zip(&positions) {
        if *slot == 0 {
            *slot = kept.len() as u32;
            kept.push(*p);
        }
    }
    for f in &mut faces {
        for v in f {
            *v = new_index.get(*v as usize).copied().unwrap_or(0);
        }
    }
    (kept, faces)
}

/// Per vertex, the signed ellipsoid normals of the regions it touches, averaged and
/// normalised (faces are grouped by region, so each region counts once per vertex).
fn vertex_normals(
    rep: &Representation,
    positions: &[DVec3],
    faces: &[[u32; 3]],
    face_regions: &[u32],
) -> Vec<DVec3> {
    let mut sum = vec![DVec3::ZERO; positions.len()];
    let mut last = vec![u32::MAX; positions.len()];
    let mut first = vec![DVec3::ZERO; positions.len()];
    for (f, &r) in faces.iter().zip(face_regions) {
        let Some(e) = rep.ellipsoids.get(r as usize) else {
            continue;
        };
        for &v in f {
            let v = v as usize;
            let (Some(s), Some(l), Some(p)) = (sum.get_mut(v), last.get_mut(v), positions.get(v))
            else {
                continue;
            };
            if *l != r {
                let n = e.normal(*p);
                if *l == u32::MAX {
                    if let Some(fst) = first.get_mut(v) {
                        *fst = n;
                    }
                }
                *l = r;
                *s += n;
            }
        }
    }
    sum.iter()
        .zip(&first)
        .map(|(s, f)| s.try_normalize().or(f.try_normalize()).unwrap_or(DVec3::Z))
        .collect()
}

/// Counts degenerate and flipped triangles and reads closedness and orientation off the
/// topology.
pub fn check_mesh(rep: &Representation, mesh: &Mesh, face_regions: &[u32]) -> MeshCheck {
    let mut degenerate = 0;
    let mut flipped = 0;
    for fault in face_faults(rep, mesh, face_regions).map(|(_, fault)| fault) {
        match fault {
            FaceFault::Degenerate => degenerate += 1,
            FaceFault::Flipped => flipped += 1,
        }
    }
    let t = mesh.topology();
    MeshCheck {
        degenerate,
        flipped,
        closed: t.is_closed(),
        manifold: t.is_manifold(),
        consistently_oriented: t.is_consistently_oriented(),
        border_loops: t.boundary_loops().len(),
        has_border_arcs: rep.arcs.iter().any(|a| a.right == Side::Border),
        omitted_regions: 0,
    }
}

/// One region's faulty triangles in an assembled mesh ([`triangle_faults_by_region`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RegionTriangleFaults {
    /// The region.
    pub region: u32,
    /// Its triangles whose normal disagrees with its ellipsoid's at their centroid.
    pub flipped: usize,
    /// Its triangles of (near) zero area.
    pub degenerate: usize,
}

/// Where [`check_mesh`]'s flipped and degenerate triangles are: each region that has any,
/// with its counts, in increasing order of region. The counts add up to the check's. For
/// a user, or a test, to see which regions keep a decoded mesh from being clean (the
/// encoder's check blames them the same way, [`problem_regions`]).
pub fn triangle_faults_by_region(
    rep: &Representation,
    mesh: &Mesh,
    face_regions: &[u32],
) -> Vec<RegionTriangleFaults> {
    let mut by_region: std::collections::BTreeMap<u32, RegionTriangleFaults> =
        std::collections::BTreeMap::new();
    for (region, fault) in face_faults(rep, mesh, face_regions) {
        let counts = by_region.entry(region).or_insert(RegionTriangleFaults {
            region,
            flipped: 0,
            degenerate: 0,
        });
        match fault {
            FaceFault::Degenerate => counts.degenerate += 1,
            FaceFault::Flipped => counts.flipped += 1,
        }
    }
    by_region.into_values().collect()
}

/// `faults` ([`triangle_faults_by_region`]) in words, the first `most` regions and how many
/// more: "10 (1 flipped), 24 (2 flipped and 1 degenerate) and 3 more".
pub fn describe_triangle_faults(faults: &[RegionTriangleFaults], most: usize) -> String {
    let listed: Vec<String> = faults
        .iter()
        .take(most)
        .map(|f| {
            let counts: Vec<String> = [(f.flipped, "flipped"), (f.degenerate, "degenerate")]
                .iter()
                .filter(|(n, _)| *n > 0)
                .map(|(n, what)| format!("{n} {what}"))
                .collect();
            format!("{} ({})", f.region, counts.join(" and "))
        })
        .collect();
    match faults.len().saturating_sub(most) {
        0 => listed.join(", "),
        more => format!("{} and {more} more", listed.join(", ")),
    }
}

/// Most regions [`triangle_faults_note`] names.
pub const LISTED_FAULTY_REGIONS: usize = 10;

/// Where a mesh's flipped and degenerate triangles are, to follow its check's faults in a
/// warning: "; by region: 10 (1 flipped), 24 (2 flipped and 1 degenerate)", the first
/// [`LISTED_FAULTY_REGIONS`] regions ([`describe_triangle_faults`]); empty when there are
/// none. `ellip decode`'s warning and the encoder's check (its file's problem) say it so.
pub fn triangle_faults_note(faults: &[RegionTriangleFaults]) -> String {
    if faults.is_empty() {
        return String::new();
    }
    format!(
        "; by region: {}",
        describe_triangle_faults(faults, LISTED_FAULTY_REGIONS)
    )
}

/// The bounding-box diagonal the tolerance is a fraction of: the box of the boundary points
/// and of the whole-ellipsoid regions.
fn reference_diagonal(rep: &Representation) -> f64 {
    let mut corners: Vec<DVec3> = rep.points.clone();
    for r in whole_regions(rep) {
        if let Some(e) = rep.ellipsoids.get(r) {
            let half = e.half_extent();
            corners.push(e.center - half);
            corners.push(e.center + half);
        }
    }
    crate::mesh::Aabb::from_points(&corners).map_or(0.0, |b| b.diagonal())
}

/// Per region, an estimate of its area: the solid angle its loops enclose on the unit sphere
/// (seen from the centre of the region's ellipsoid) times the mean area scale of the map to
/// the ellipsoid at its boundary points; a whole ellipsoid's area by Thomsen's formula.
fn estimate_areas(rep: &Representation) -> Result<Vec<f64>, RemeshError> {
    let mut areas = Vec::with_capacity(rep.region_count());
    for (r, e) in rep.ellipsoids.iter().enumerate() {
        let cycles = rep.cycles.get(r).map_or(&[][..], Vec::as_slice);
        let area = if cycles.is_empty() {
            ellipsoid_area(e)
        } else {
            let mut loops: Vec<Vec<DVec3>> = Vec::with_capacity(cycles.len());
            for c in cycles {
                let mut lp = Vec::new();
                for a in &c.arcs {
                    let Some(mut pts) = rep.arc_positions(a.arc as usize) else {
                        continue;
                    };
                    if a.reversed {
                        pts.reverse();
                    }
                    lp.extend(pts);
                }
                loops.push(lp);
            }
            region_area(e, &loops)
        };
        if !area.is_finite() {
            return Err(RemeshError::Geometry {
                what: "region area not finite",
            });
        }
        areas.push(area);
    }
    Ok(areas)
}

/// Knud Thomsen's approximation of an ellipsoid's surface area (relative error < 1.1 %).
pub fn ellipsoid_area(e: &Ellipsoid) -> f64 {
    const P: f64 = 1.6075;
    let (a, b, c) = (e.radii.x.powf(P), e.radii.y.powf(P), e.radii.z.powf(P));
    4.0 * std::f64::consts::PI * ((a * b + a * c + b * c) / 3.0).powf(1.0 / P)
}

/// The estimated area of the part of `e` that `loops` (region on the left) bound.
fn region_area(e: &Ellipsoid, loops: &[Vec<DVec3>]) -> f64 {
    let dirs: Vec<Vec<DVec3>> = loops
        .iter()
        .map(|l| {
            l.iter()
                .filter_map(|&p| e.to_unit_sphere(p).try_normalize())
                .collect()
        })
        .collect();
    let count: usize = dirs.iter().map(Vec::len).sum();
    if count == 0 {
        return 0.0;
    }
    // Apex of the fan: away from the boundary.
    let mean: DVec3 = dirs.iter().flatten().copied().sum();
    let apex = (-mean).try_normalize().unwrap_or(DVec3::Z);
    let mut solid = 0.0;
    for l in &dirs {
        for (i, &u) in l.iter().enumerate() {
            let Some(&w) = l.get(i + 1).or(l.first()) else {
                continue;
            };
            // Van Oosterom & Strackee: the signed solid angle of the triangle (apex, u, w).
            let num = apex.dot(u.cross(w));
            let den = 1.0 + apex.dot(u) + apex.dot(w) + u.dot(w);
            solid += 2.0 * num.atan2(den);
        }
    }
    // The fan covers the apex's side of the loops: positively if the region (on the
    // loops' left seen from outside) is that side, else negatively its complement.
    let four_pi = 4.0 * std::f64::consts::PI;
    let mut sphere_area = e.sign.factor() * solid;
    if sphere_area < 0.0 {
        sphere_area += four_pi;
    }
    let sphere_area = sphere_area.clamp(0.0, four_pi);
    let abc = e.radii.x * e.radii.y * e.radii.z;
    let scale: f64 = dirs
        .iter()
        .flatten()
        .map(|u| abc * (*u / e.radii).length())
        .sum::<f64>()
        / count as f64;
    sphere_area * scale
}

/// What is wrong with a triangle of an assembled mesh ([`face_faults`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FaceFault {
    /// Area (near) zero ([`DEGENERATE_AREA`]).
    Degenerate,
    /// Its normal disagrees with its ellipsoid's signed normal at its centroid.
    Flipped,
}

/// The faulty triangles of an assembled mesh, with their regions: what [`check_mesh`]
/// counts, [`triangle_faults_by_region`] counts by region and [`problem_regions`] blames.
fn face_faults<'a>(
    rep: &'a Representation,
    mesh: &'a Mesh,
    face_regions: &'a [u32],
) -> impl Iterator<Item = (u32, FaceFault)> + 'a {
    let diagonal = mesh.bounding_box().map_or(0.0, |b| b.diagonal());
    let min_area = DEGENERATE_AREA * diagonal * diagonal;
    let sides: Vec<NormalSide> = rep.ellipsoids.iter().map(Ellipsoid::normal_side).collect();
    face_regions
        .iter()
        .enumerate()
        .take(mesh.face_count())
        .filter_map(move |(f, &r)| {
            let doubled = mesh.face_area_vector(f);
            let area = 0.5 * doubled.length();
            if area.is_nan() || area <= min_area {
                return Some((r, FaceFault::Degenerate));
            }
            let side = sides.get(r as usize)?;
            (side.along(mesh.face_centroid(f), doubled) < 0.0).then_some((r, FaceFault::Flipped))
        })
}

/// The regions to blame for what [`check_mesh`] found wrong with a remeshed representation,
/// in increasing order: the regions of degenerate and flipped triangles (`faulty`,
/// [`Remeshed::faulty_regions`]), and of the
/// triangles on edges that are not manifold (unless the source is not either:
/// `source_manifold`, see [`MeshCheck::is_clean_from`]), on the border (when the
/// representation has no border arcs), or run the same way by their two triangles. Empty
/// when the mesh is clean, or when its faults (a vertex with two fans of triangles) name no
/// edge.
pub fn problem_regions(
    out: &Remeshed,
    faulty: &[RegionTriangleFaults],
    source_manifold: bool,
) -> Vec<u32> {
    let mesh = &out.mesh;
    let mut blamed: std::collections::BTreeSet<u32> = faulty.iter().map(|f| f.region).collect();
    let c = out.check;
    if !c.is_sound_from(source_manifold) {
        let t = mesh.topology();
        let faces = mesh.faces();
        for (f, (tri, &r)) in faces.iter().zip(&out.face_regions).enumerate() {
            let bad = (0..3).any(|i| match t.neighbor(f, i) {
                // A manifold edge a→b is run b→a by a consistently oriented neighbour.
                Some(g) => faces.get(g as usize).is_some_and(|other| {
                    let (a, b) = (tri[i], tri[(i + 1) % 3]);
                    (0..3).any(|k| other[k] == a && other[(k + 1) % 3] == b)
                }),
                // A border edge, or an edge of three or more triangles.
                None if t.is_border_edge(f, i) => !c.has_border_arcs,
                None => source_manifold,
            });
            if bad {
                blamed.insert(r);
            }
        }
    }
    blamed.into_iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_cap_has_the_area_of_a_cap() {
        // A circle of angular radius 0.3 around +x on a sphere of radius 2, counter-clockwise
        // seen from outside: the cap 2π(1 − cos θ)·r².
        let e = Ellipsoid::sphere(DVec3::ZERO, 2.0);
        let theta: f64 = 0.3;
        let lp: Vec<DVec3> = (0..400)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / 400.0;
                2.0 * DVec3::new(theta.cos(), theta.sin() * t.cos(), theta.sin() * t.sin())
            })
            .collect();
        let cap = std::f64::consts::TAU * (1.0 - theta.cos()) * 4.0;
        let a = region_area(&e, std::slice::from_ref(&lp));
        assert!((a - cap).abs() < 1e-3 * cap, "{a} vs {cap}");
        // Walked the other way, the region is the rest of the sphere.
        let rev: Vec<DVec3> = lp.iter().rev().copied().collect();
        let rest = 16.0 * std::f64::consts::PI - cap;
        let a = region_area(&e, &[rev]);
        assert!((a - rest).abs() < 1e-3 * rest, "{a} vs {rest}");
    }

    #[test]
    fn thomsen_is_exact_on_spheres() {
        let e = Ellipsoid::sphere(DVec3::ONE, 3.0);
        let exact = 4.0 * std::f64::consts::PI * 9.0;
        assert!((ellipsoid_area(&e) - exact).abs() < 1e-9 * exact);
    }

    #[test]
    fn loops_lose_consecutive_repeats() {
        assert_eq!(without_repeats(vec![1, 1, 2, 3, 3, 1]), vec![1, 2, 3]);
        assert_eq!(without_repeats(vec![4, 4]), vec![4]);
    }

    #[test]
    fn a_check_says_what_keeps_a_mesh_from_being_clean() {
        let clean = MeshCheck {
            degenerate: 0,
            flipped: 0,
            closed: true,
            manifold: true,
            consistently_oriented: true,
            border_loops: 0,
            has_border_arcs: false,
            omitted_regions: 0,
        };
        assert!(clean.is_clean() && clean.is_sound());
        // Open where the representation has border arcs: still sound.
        let open = MeshCheck {
            closed: false,
            border_loops: 1,
            has_border_arcs: true,
            ..clean
        };
        assert!(open.is_clean());
        let flipped = MeshCheck {
            flipped: 2,
            ..clean
        };
        assert!(flipped.is_sound() && !flipped.is_clean());
        assert_eq!(flipped.faults(), "2 flipped and 0 degenerate triangles");
        let holed = MeshCheck {
            closed: false,
            border_loops: 1,
            consistently_oriented: false,
            ..clean
        };
        assert!(!holed.is_sound());
        assert_eq!(
            holed.faults(),
            "0 flipped and 0 degenerate triangles, not consistently oriented, not closed"
        );
        // Not manifold: clean only when its source is not either, and nothing else wrong.
        let pinched = MeshCheck {
            manifold: false,
            ..clean
        };
        assert!(!pinched.is_clean() && pinched.is_clean_from(false));
        assert!(!pinched.is_sound() && pinched.is_sound_from(false));
        assert!(!MeshCheck {
            flipped: 1,
            ..pinched
        }
        .is_clean_from(false));
        assert!(!MeshCheck {
            closed: false,
            ..pinched
        }
        .is_sound_from(false));
        assert!(clean.is_clean_from(false) && !holed.is_sound_from(false));
        // Regions left out: never sound, whatever the source.
        let omitted = MeshCheck {
            closed: false,
            border_loops: 2,
            omitted_regions: 2,
            ..clean
        };
        assert!(!omitted.is_sound() && !omitted.is_sound_from(false));
        assert_eq!(
            omitted.faults(),
            "0 flipped and 0 degenerate triangles, 2 regions left out, not closed"
        );
    }

    #[test]
    fn triangle_faults_are_counted_by_region() {
        // Two unit spheres far apart, whole regions.
        let shift = DVec3::new(10.0, 0.0, 0.0);
        let rep = Representation {
            ellipsoids: vec![
                Ellipsoid::sphere(DVec3::ZERO, 1.0),
                Ellipsoid::sphere(shift, 1.0),
            ],
            cycles: vec![Vec::new(), Vec::new()],
            ..Representation::default()
        };
        // Near each sphere's top: a triangle counter-clockwise seen from above (outward) on
        // the first, the same turned over on the second, and one of zero area there.
        let cap = [
            DVec3::new(0.1, 0.0, 0.99),
            DVec3::new(-0.05, 0.087, 0.99),
            DVec3::new(-0.05, -0.087, 0.99),
        ];
        let mut positions = cap.to_vec();
        positions.extend(cap.iter().map(|&p| p + shift));
        positions.extend([0.0, 0.1, 0.2].map(|x| shift + DVec3::new(x, 0.0, 1.0)));
        let faces = vec![[0, 1, 2], [3, 5, 4], [6, 7, 8]];
        let regions = [0, 1, 1];
        let mesh = Mesh::new(positions.clone(), faces.clone()).unwrap();
        let faults = triangle_faults_by_region(&rep, &mesh, &regions);
        assert_eq!(
            faults,
            [RegionTriangleFaults {
                region: 1,
                flipped: 1,
                degenerate: 1
            }]
        );
        let check = check_mesh(&rep, &mesh, &regions);
        assert_eq!((check.flipped, check.degenerate), (1, 1));
        // Turned over, the first region's triangle is counted too, first.
        let turned = Mesh::new(positions, vec![[0, 2, 1], faces[1], faces[2]]).unwrap();
        let faults = triangle_faults_by_region(&rep, &turned, &regions);
        assert_eq!(
            faults
                .iter()
                .map(|f| (f.region, f.flipped, f.degenerate))
                .collect::<Vec<_>>(),
            [(0, 1, 0), (1, 1, 1)]
        );
        assert_eq!(
            describe_triangle_faults(&faults, 10),
            "0 (1 flipped), 1 (1 flipped and 1 degenerate)"
        );
        assert_eq!(
            describe_triangle_faults(&faults, 1),
            "0 (1 flipped) and 1 more"
        );
        // A clean mesh has none.
        let clean = Mesh::new(cap.to_vec(), vec![[0, 1, 2]]).unwrap();
        assert!(triangle_faults_by_region(&rep, &clean, &[0]).is_empty());
        assert_eq!(describe_triangle_faults(&[], 10), "");
    }

    #[test]
    fn loops_lose_their_seams() {
        // One loop running 1 → 2 and later 2 → 1: split into the loops on either side.
        assert_eq!(
            without_seams(vec![vec![0, 1, 2, 3, 4, 2, 1, 5]]),
            vec![vec![0, 1, 5], vec![2, 3, 4]]
        );
        // Two loops, one running 0 → 1, the other 1 → 0: joined into one.
        assert_eq!(
            without_seams(vec![vec![0, 1, 2], vec![1, 0, 3]]),
            vec![vec![1, 2, 0, 3]]
        );
        // A seam of two edges (1 → 2 → 3 and back) between two rims, as on a tube cut
        // along a meridian: the rims are left.
        assert_eq!(
            without_seams(vec![vec![10, 11, 1, 2, 3, 20, 21, 3, 2, 1]]),
            vec![vec![10, 11, 1], vec![3, 20, 21]]
        );
        // Every edge in a pair: nothing is left; also when the loop is two points.
        assert!(without_seams(vec![vec![0, 1, 2], vec![2, 1, 0]]).is_empty());
        assert!(without_seams(vec![vec![4, 5]]).is_empty());
        // No pair: unchanged, however the loops touch.
        let touching = vec![vec![0, 1, 2], vec![0, 3, 4]];
        assert_eq!(without_seams(touching.clone()), touching);
    }

    #[test]
    fn loops_lose_their_spikes() {
        // 1 → 2 → 1 runs out to 2 and back.
        assert_eq!(without_spikes(vec![0, 1, 2, 1, 3]), vec![0, 1, 3]);
        // Two spikes; one across the seam (0 → 1 → 0 from the end round to the start); one
        // inside another.
        assert_eq!(without_spikes(vec![2, 0, 1, 0, 3, 4, 3]), vec![2, 0, 3]);
        assert_eq!(without_spikes(vec![1, 0, 2, 3, 0]), vec![2, 3, 0]);
        assert_eq!(without_spikes(vec![5, 6, 7, 8, 7, 6, 9]), vec![5, 6, 9]);
        // Three traversals of one edge leave one; a bare slit leaves a point.
        assert_eq!(without_spikes(vec![0, 1, 0, 1, 2, 3]), vec![0, 1, 2, 3]);
        assert_eq!(without_spikes(vec![0, 1]), vec![0, 1]);
        assert!(without_spikes(vec![0, 1, 0, 1]).len() < 3);
        // A long way out and back, in one pass.
        let mut long = vec![5000];
        long.extend((0..1000).chain((0..999).rev()));
        long.push(5001);
        assert_eq!(without_spikes(long), vec![5000, 0, 5001]);
        // No spike: unchanged.
        assert_eq!(without_spikes(vec![0, 1, 2, 3]), vec![0, 1, 2, 3]);
    }

    /// A region whose outer loop folds (two points swapped, so two of its edges cross) and
    /// which has a hole that encloses nothing: four arcs whose points all lie at one
    /// position (a scan's vertices, duplicated where it was cut, meeting again). That loop
    /// fails the chart, so the region is not untangled; in the decoder's last resort
    /// (`skip_degenerate`) it is dropped, as the meshing drops it, and the fold is found.
    #[test]
    fn a_loop_that_encloses_nothing_is_dropped_for_untangling_in_the_last_resort() {
        use crate::representation::{Arc, ArcRef, Cycle, Metadata};
        let ring = |k: usize| {
            let t = std::f64::consts::TAU * k as f64 / 12.0;
            DVec3::new(0.5 * t.cos(), 0.5 * t.sin(), 0.75f64.sqrt())
        };
        let mut points: Vec<DVec3> = (0..12).map(ring).collect();
        points.swap(3, 4);
        points.extend([DVec3::Z; 4]);
        let arc = |points: Vec<u32>, closed: bool| Arc {
            points,
            closed,
            left: 0,
            right: Side::Border,
        };
        let forward = |arc: u32| ArcRef {
            arc,
            reversed: false,
        };
        let rep = Representation {
            ellipsoids: vec![Ellipsoid::sphere(DVec3::ZERO, 1.0)],
            points,
            arcs: vec![
                arc((0..12).collect(), true),
                arc(vec![12, 13], false),
                arc(vec![13, 14], false),
                arc(vec![14, 15], false),
                arc(vec![15, 12], false),
            ],
            cycles: vec![vec![
                Cycle {
                    arcs: vec![forward(0)],
                    outer: true,
                },
                Cycle {
                    arcs: (1..5).map(forward).collect(),
                    outer: false,
                },
            ]],
            metadata: Metadata::default(),
        };
        rep.validate().unwrap();
        let chains: Vec<Vec<u32>> = rep.arcs.iter().map(|a| a.points.clone()).collect();
        let crossings = |skip_degenerate: bool| {
            let mut drop = Vec::new();
            let (charted, crossings) = region_crossings(
                0,
                &rep,
                &chains,
                &rep.points,
                Charting {
                    projection: Projection::Closest,
                    walk: PoleWalk::Free,
                    skip_degenerate,
                    charts: &ChartMemo::default(),
                },
                &mut drop,
            );
            (charted, crossings, drop)
        };
        assert_eq!(crossings(false), (None, 0, vec![]));
        let (loops, found, drop) = crossings(true);
        assert_eq!((loops, found, drop.len()), (Some(1), 1, 1));
        assert!(matches!(drop[0], (0, 2..=5)), "{drop:?}");
    }

    #[test]
    fn a_piece_the_grid_misses_passes_its_share_on() {
        // Piece 1 got nothing for its request: its 30 go to pieces 0 and 2 by their shares;
        // piece 3 asked for nothing, so it lost nothing.
        let mut shares = [50.0, 30.0, 20.0, 0.5];
        pass_on_lost_shares(&mut shares, &[50, 30, 20, 0], &[48, 0, 21, 0]);
        assert_eq!(shares[1], 0.0);
        let total: f64 = shares.iter().sum();
        assert!((total - 100.5).abs() < 1e-9, "{shares:?}");
        assert!((shares[0] / shares[2] - 2.5).abs() < 1e-12, "{shares:?}");
        assert!((shares[3] - 0.5 * 100.5 / 70.5).abs() < 1e-12, "{shares:?}");
        // Every piece missed: there is no piece to pass them on to, and none asks again.
        let mut all = [1.0, 2.0];
        pass_on_lost_shares(&mut all, &[1, 2], &[0, 0]);
        assert_eq!(all, [0.0, 0.0]);
    }

    #[test]
    fn treatments_are_named_by_distinct_codes() {
        let settings = RefineSettings {
            spacing: 0.1,
            tolerance: 0.01,
            max_new_points: 100,
            prune: Prune::Narrow,
        };
        let sequence = Treatment::sequence(&settings);
        assert_eq!(sequence.first(), Some(&Treatment::FIRST));
        assert_eq!(Treatment::FIRST.code(), 0);
        let mut codes: Vec<u64> = sequence.iter().map(Treatment::code).collect();
        for (t, &code) in sequence.iter().zip(&codes) {
            assert!(code < 128, "{t}");
            assert_eq!(Treatment::from_code(code), Some(*t), "{code}");
        }
        codes.sort_unstable();
        codes.dedup();
        assert_eq!(codes.len(), sequence.len());
        // Every 7-bit code but the fourth pruning value names a treatment; nothing else does.
        for code in 0..512u64 {
            let named = Treatment::from_code(code);
            assert_eq!(named.is_some(), code < 128 && code >> 1 & 3 != 3, "{code}");
            assert!(named.is_none_or(|t| t.code() == code), "{code}");
        }
        assert_eq!(Treatment::from_code(u64::MAX), None);
        // Without refinement the stored arcs are the refined ones: not tried twice.
        let unrefined = Treatment::sequence(&RefineSettings {
            max_new_points: 0,
            ..settings
        });
        assert!(unrefined.len() < sequence.len());
        assert!(unrefined.iter().all(|t| t.refined || t.prune == Prune::Off));
    }

    #[test]
    fn options_are_validated() {
        let rep = crate::format::sample::three_regions_two_junctions();
        for bad in [
            RemeshOptions {
                vertices: Some(0),
                ..RemeshOptions::default()
            },
            RemeshOptions {
                tolerance: Some(-1.0),
                ..RemeshOptions::default()
            },
            RemeshOptions {
                tolerance: Some(f64::NAN),
                ..RemeshOptions::default()
            },
            RemeshOptions {
                vertices: Some(100),
                max_vertices: 10,
                ..RemeshOptions::default()
            },
        ] {
            assert!(
                matches!(
                    assemble(&rep, &bad, &ChartMemo::default()),
                    Err(RemeshError::InvalidOption { .. })
                ),
                "{bad:?}"
            );
        }
    }
}
