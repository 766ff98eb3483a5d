//! Encode: a mesh to its ellipsoidal representation and to `.ellip` bytes.
//!
//! The pipeline, one stage per module: [`segment`](crate::segment) the faces into regions
//! with their ellipsoids → [`extract_boundaries`] →
//! [`smooth_boundaries`](crate::boundary::smooth_boundaries) toward the ellipsoids (Simari &
//! Singh 2005, section 4.1) → [`Representation::from_boundary`] →
//! [`Representation::simplify_arcs`] (Douglas–Peucker, the paper's future-work note) →
//! [`format::encode`] (quantised, compressed, checksummed; `spec/ELLIP.md`) → the decoder
//! check: the file is remeshed as a reader would (but without leaving out the regions it
//! cannot mesh, [`crate::remesh::RemeshOptions::leave_out`]), and each region that does not mesh
//! cleanly is mended and the file written again ([`EncodeSettings::verify`]): a region the
//! decoder cannot chart gets its boundaries stored at the mesh's own points, then unsimplified;
//! a small region is dissolved into its neighbours ([`dissolve_regions`]); any other is
//! split ([`split_regions`]), and so is a region decoded clean but far from the source
//! where its ellipsoid is not ([`MAX_DEPARTURE`], [`MAX_RMS_DEPARTURE`]), or missing from
//! the decoded mesh ([`MAX_LOST`]).

use crate::boundary::{
    extract_boundaries, smooth_boundaries_holding, BoundaryError, SmoothOptions,
};
use crate::compare::Bvh;
use crate::ellipsoid::Ellipsoid;
use crate::format::{self, simplify::DEFAULT_RELATIVE_TOLERANCE, EncodeError, EncodeOptions};
use crate::mesh::{Aabb, Mesh};
use crate::remesh::assemble::Treatment;
use crate::remesh::refine::Prune;
use crate::remesh::{ChartMemo, Remeshed};
use crate::representation::{InvalidRepresentation, Metadata, Representation};
use crate::segment::proxy::speck_faces;
use crate::segment::{
    dissolve_regions, segment_with, split_regions, Cut, EllipsoidMetric, Exec, Progress,
    RegionCount, SegmentError, SegmentOptions, Segmentation, Split,
};
use glam::DVec3;
use rayon::prelude::*;
use std::cmp::Ordering;

/// Everything the encoder can be told. Every field has a default ([`Default`]).
#[derive(Debug, Clone, PartialEq)]
pub struct EncodeSettings {
    /// The segmentation (default: [`SegmentOptions::default`], 12 regions).
    pub segment: SegmentOptions,
    /// Boundary smoothing (default: [`SmoothOptions::default`]).
    pub smooth: SmoothOptions,
    /// Boundary tolerance as a fraction of the bounding-box diagonal (default
    /// [`DEFAULT_RELATIVE_TOLERANCE`], 10⁻³): no stored boundary point is farther than this
    /// from the boundary it stands for, simplification and quantisation together. 0 keeps
    /// every boundary point (then only the grid moves them).
    pub simplify_tolerance: f64,
    /// Bits per axis of the boundary-point grid; `None` (the default): the one of
    /// [`AUTO_BITS`] that gives the smallest file within the boundary tolerance
    /// ([`format::DEFAULT_BITS`] when the tolerance is 0).
    pub bits: Option<u8>,
    /// Decode the file as a reader would (default budget and limits, but no region left
    /// out: a file that decodes only with holes counts as one that does not decode) and,
    /// where a region
    /// does not mesh cleanly, mend it and write again, up to [`MAX_SPLIT_ROUNDS`] rounds
    /// (default true). A region whose boundary the decoder cannot chart (it folds, or two of
    /// its loops touch) first has its boundaries stored at the mesh's own points rather than
    /// smoothed, then every one of those points kept; a region of at most
    /// [`SMALL_REGION_SHARE`] of the mean region's faces is dissolved into its neighbours;
    /// any other is split (at most [`MAX_SPLIT_REGIONS`] more regions), and so is a region
    /// that meshes cleanly but departs from the source by more than [`MAX_DEPARTURE`] of
    /// the diagonal beyond what its ellipsoid misses (or by more than
    /// [`MAX_RMS_DEPARTURE`] in RMS), or is missing from the decoded mesh
    /// while its faces lie more than [`MAX_LOST`] from it; a mesh in more pieces than the source
    /// counts as unsound, its extra pieces' regions to blame. Each segmentation is checked
    /// once. A file that decodes clean only with a later boundary treatment than the
    /// decoder's first names it ([`Metadata::remesh_hint`], format 1.1), so that decoders
    /// mesh it once; so does a file that a later treatment meshes clean and closer to the
    /// source (the arcs as stored, where the source has creases that the fitted ellipsoids
    /// meet off).
    /// Failing that, the best file seen is kept (see [`encode_mesh`]). The file may then
    /// hold more or fewer regions than asked for ([`Encoded::verification`] says how many
    /// rounds it took and what, if anything, is still wrong).
    pub verify: bool,
}

impl Default for EncodeSettings {
    fn default() -> Self {
        EncodeSettings {
            segment: SegmentOptions::default(),
            smooth: SmoothOptions::default(),
            simplify_tolerance: DEFAULT_RELATIVE_TOLERANCE,
            bits: None,
            verify: true,
        }
    }
}

/// The result of encoding.
#[derive(Debug, Clone)]
pub struct Encoded {
    /// The `.ellip` file.
    pub bytes: Vec<u8>,
    /// The representation the file holds (before quantisation).
    pub representation: Representation,
    /// The segmentation it came from.
    pub segmentation: Segmentation<Ellipsoid>,
    /// Boundary points before simplification.
    pub boundary_points: usize,
    /// Boundary points simplification removed.
    pub removed_points: usize,
    /// Bits per axis of the point grid used.
    pub bits: u8,
    /// How the file was checked against the decoder ([`EncodeSettings::verify`]).
    pub verification: Verification,
}

/// Why a mesh could not be encoded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EncodeMeshError {
    /// The segmentation refused the mesh or the options.
    #[error(transparent)]
    Segment(#[from] SegmentError),
    /// The boundary stage refused the segmentation or the smoothing options.
    #[error(transparent)]
    Boundary(#[from] BoundaryError),
    /// The representation broke a rule of the format (a bug: reported, never written).
    #[error("internal error, the representation is invalid: {0}")]
    Representation(#[from] InvalidRepresentation),
    /// The format refused the representation or the options.
    #[error(transparent)]
    Format(#[from] EncodeError),
    /// Decoding the encoding to measure it failed (a bug: the encoder wrote it).
    #[error("internal error, the encoding does not decode: {0}")]
    Decode(#[from] format::DecodeError),
    /// Remeshing the encoding to measure it failed.
    #[error("the encoding could not be remeshed to measure it: {0}")]
    Remesh(#[from] crate::remesh::RemeshError),
    /// Comparing the decoded mesh with its source failed.
    #[error(transparent)]
    Compare(#[from] crate::compare::CompareError),
    /// No setting the rate control tried meets the target.
    #[error("{0}")]
    Unreachable(String),
    /// An option is out of range.
    #[error("invalid option {what}: {value}")]
    InvalidOption {
        /// The option.
        what: &'static str,
        /// Its value, as text.
        value: String,
    },
}

/// Encodes a mesh: segments it, extracts and smooths the boundaries, simplifies the arcs and
/// writes `.ellip` bytes. `progress` hears from the segmentation loop, its long part.
pub fn encode_mesh(
    mesh: &Mesh,
    settings: &EncodeSettings,
    progress: &mut dyn FnMut(Progress),
) -> Result<Encoded, EncodeMeshError> {
    let first = encode_checked(
        mesh,
        settings,
        MAX_SPLIT_ROUNDS,
        Fidelity::Smoothed,
        progress,
    )?;
    Ok(search_for_clean(mesh, settings, first, None, true, progress)?.encoded)
}

/// What [`encode_mesh`] does when `first`, the file at the settings asked for (checked and
/// mended), does not decode clean: the searches below, the count raised only with
/// `raise` (rate control chooses the count itself, [`encode_to_target`]); `first` itself
/// when it is clean or was not checked. `weighted` is the area-weighted search's file when
/// the caller made it already (rate control's probes), else it is made here.
fn search_for_clean(
    mesh: &Mesh,
    settings: &EncodeSettings,
    first: Checked,
    weighted: Option<Checked>,
    raise: bool,
    progress: &mut dyn FnMut(Progress),
) -> Result<Checked, EncodeMeshError> {
    if !settings.verify || first.score.0 == CLEAN {
        return Ok(first);
    }
    let RegionCount::Fixed(requested) = settings.segment.regions else {
        return store_blamed_faithfully(mesh, settings, vec![first]);
    };
    // No file at the requested count decodes clean, however mended. First the segmentation
    // is done again with each face's error weighted by its area (the metric as an integral
    // over the surface, where the paper's plain sum over vertices lets densely tessellated
    // parts pull the fits: CGAL's camel and mannequin, whose fingers and faces hold tiny
    // triangles with mean curvatures in the thousands, were fitted with needles a
    // ten-thousandth of the diagonal thick; the npm bunny at K = 12, whose ears' loops fold
    // in their charts, 2 flipped triangles, decodes clean so at 13 regions). Then the count
    // is raised by half (beyond one region per further component), a few times, with the
    // weighting asked for (raised with area weighting, armadillo needed 27 regions instead
    // of 22): armadillo at K = 12, whose regions fold over their ellipsoids however they are
    // split, did not decode whole and decoded clean at 18 (since the decoder's first attempt
    // prunes only narrow double ears, its weighted segmentation mended is clean first). The
    // best file is kept, the first clean one ending the search; when none is clean, each
    // search's best is stored again as a last resort (store_blamed_faithfully), and failing
    // that, every search is made again with the junctions held where the mesh has them, and
    // last the count raised once with area weighting, junctions held.
    let mut searches: Vec<(EncodeSettings, usize)> = Vec::new();
    if let Some(weighted) = area_weighted(settings) {
        searches.push((weighted, MAX_REWEIGHTED_ROUNDS));
    }
    let mut k = requested;
    // Each further connected component holds a region of its own: the count raised is that
    // of the regions beyond those (dragon's 875 fragments stay one region each).
    let pieces = mesh.topology().component_count().saturating_sub(1);
    let raises = if raise { MAX_REGION_RAISES } else { 0 };
    for _ in 0..raises {
        let raised = (k + k.saturating_sub(pieces).div_ceil(2)).min(mesh.face_count());
        if raised <= k {
            break;
        }
        k = raised;
        let settings = EncodeSettings {
            segment: SegmentOptions {
                regions: RegionCount::Fixed(k),
                ..settings.segment.clone()
            },
            ..settings.clone()
        };
        searches.push((settings, MAX_SPLIT_ROUNDS));
    }
    let mut tried = vec![first];
    let mut weighted = weighted;
    for (search, rounds) in &searches {
        // The weighted search's file, when the caller made it.
        let made = if search.segment.area_weighting != settings.segment.area_weighting {
            weighted.take()
        } else {
            None
        };
        let Some(checked) = made.or_else(|| {
            search_again(
                mesh,
                settings,
                search,
                *rounds,
                Fidelity::Smoothed,
                progress,
            )
        }) else {
            continue;
        };
        if checked.score.0 == CLEAN {
            return Ok(checked);
        }
        tried.push(checked);
    }
    let mut best = store_blamed_faithfully(mesh, settings, tried)?;
    if best.score.0 == CLEAN || best.score.0 == DOES_NOT_DECODE {
        return Ok(best);
    }
    // Every search again, the requested one first, with the junctions held where the mesh
    // has them while the arcs relax (Fidelity::Junctions). Where three ellipsoids meet far
    // from the mesh, the relaxation drags a junction toward that point and across a narrow
    // region, whose loop then runs the other way round (assimp's low-poly spider: 27
    // flipped triangles at K = 35, clean with the junctions held). Only for a file that
    // decodes: a turned loop gives turned faces, not a chart that fails, and Stanford's
    // dragon at `res3` (886 pieces, no file of which decodes) took 201 s instead of 109 to
    // come to the same file.
    // Last, the one pairing the searches leave out: the count raised once and area
    // weighting together (a raise keeps the weighting asked for). assimp's low-poly spider
    // at K = 29 kept 1 flipped triangle through every search before it; raised to 35, its
    // weighted segmentation with the junctions held is clean after 5 rounds.
    let weighted_raise = searches
        .iter()
        .find(|(search, _)| search.segment.regions != settings.segment.regions)
        .and_then(|(search, _)| area_weighted(search))
        .map(|search| (search, MAX_REWEIGHTED_ROUNDS));
    let again = std::iter::once((settings.clone(), MAX_SPLIT_ROUNDS))
        .chain(searches)
        .chain(weighted_raise);
    for (search, rounds) in again {
        let Some(checked) = search_again(
            mesh,
            settings,
            &search,
            rounds,
            Fidelity::Junctions,
            progress,
        ) else {
            continue;
        };
        if checked.score.0 == CLEAN {
            return Ok(checked);
        }
        if checked.score < best.score {
            best = checked;
        }
    }
    Ok(best)
}

/// `settings` with each face's error weighted by its area ([`SegmentOptions::area_weighting`],
/// the first of the searches [`encode_mesh`] makes for a file that does not decode clean),
/// unless it already is.
fn area_weighted(settings: &EncodeSettings) -> Option<EncodeSettings> {
    (!settings.segment.area_weighting).then(|| EncodeSettings {
        segment: SegmentOptions {
            area_weighting: true,
            ..settings.segment.clone()
        },
        ..settings.clone()
    })
}

/// One of [`encode_mesh`]'s searches after the first: `search` (`asked` with the weighting
/// or the count changed) checked and mended from `floor`, its file saying what changed;
/// `None` if it failed.
fn search_again(
    mesh: &Mesh,
    asked: &EncodeSettings,
    search: &EncodeSettings,
    rounds: usize,
    floor: Fidelity,
    progress: &mut dyn FnMut(Progress),
) -> Option<Checked> {
    let mut checked = encode_checked(mesh, search, rounds, floor, progress).ok()?;
    let verification = &mut checked.encoded.verification;
    verification.area_weighted = search.segment.area_weighting && !asked.segment.area_weighting;
    if let (RegionCount::Fixed(k), RegionCount::Fixed(requested)) =
        (search.segment.regions, asked.segment.regions)
    {
        if k != requested {
            verification.requested_regions = requested;
            verification.raised_regions = Some(k);
        }
    }
    Some(checked)
}

/// What [`encode_checked`] keeps: the file, how it decodes, and the regions its decoder
/// check blamed (none when clean or not checked).
#[derive(Clone)]
struct Checked {
    score: Score,
    encoded: Encoded,
    blamed: Vec<u32>,
}

/// Most rounds of mending for [`encode_mesh`]'s segmentation weighted by area, tried when
/// no file at the requested count decodes clean: as many as [`MAX_SPLIT_ROUNDS`]. The search
/// ends at the first clean file, so a mesh clean within fewer rounds gets the same file
/// whatever this limit (CGAL's camel and couplings are clean after 3 and 9 rounds); CGAL's
/// `man` at K = 12, whose curvature is noisy enough to leave one region over its torso and
/// both legs, is clean only after 20. Half as many (12) left it with 45 flipped triangles.
/// On a mesh clean in no round (the npm dragon and head scans) encoding costs about a
/// seventh more than with 12.
pub const MAX_REWEIGHTED_ROUNDS: usize = MAX_SPLIT_ROUNDS;

/// How many times [`encode_mesh`] raises the region count by half when no file at the
/// requested count decodes clean: 12 becomes 18, then 27.
pub const MAX_REGION_RAISES: usize = 2;

/// The rank of a [`Score`] whose file decodes clean.
const CLEAN: u8 = 0;

/// The rank of a [`Score`] whose file decodes with faults (flipped or degenerate
/// triangles, or unsound), every region near the source.
const DIRTY: u8 = 1;

/// The rank of a [`Score`] whose file decodes clean, but with a region far from the source
/// ([`MAX_DEPARTURE`]). A region meshed a tenth of the diagonal or more from its piece is
/// worse than a few turned triangles: ranked before them, assimp's spider at K = 35 kept a
/// file 59 % of the diagonal RMS off its source.
const FAR: u8 = 2;

/// The rank of a [`Score`] whose file decodes with faults and with a region far from the
/// source.
const DIRTY_AND_FAR: u8 = 3;

/// The rank of a [`Score`] whose file does not decode whole (with every region).
const DOES_NOT_DECODE: u8 = 4;

/// [`encode_mesh`] at the requested region count: the file, mended when checked (at most
/// `max_rounds` rounds; every region's boundaries stored at `floor`, the mending raising
/// them from there), how it decodes ([`Verdict::score`]; clean when not checked) and the
/// regions its check blamed.
fn encode_checked(
    mesh: &Mesh,
    settings: &EncodeSettings,
    max_rounds: usize,
    floor: Fidelity,
    progress: &mut dyn FnMut(Progress),
) -> Result<Checked, EncodeMeshError> {
    let tolerance = settings.simplify_tolerance;
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(EncodeMeshError::InvalidOption {
            what: "simplify tolerance",
            value: tolerance.to_string(),
        });
    }
    let metric = EllipsoidMetric::new(mesh, &settings.segment)?;
    let mut segmentation = segment_with(mesh, &metric, &settings.segment, progress)?;
    let requested = segmentation.region_count();
    let mut verification = Verification {
        requested_regions: requested,
        rounds: 0,
        tried: 0,
        raised_regions: None,
        area_weighted: false,
        problem: None,
    };
    if !settings.verify {
        let fidelity = vec![floor; segmentation.region_count()];
        let (stored, boundary_points) = represent(mesh, &segmentation, settings, &fidelity)?;
        return Ok(Checked {
            score: Verdict::Clean.score(),
            encoded: Encoded::new(stored, segmentation, boundary_points, verification),
            blamed: Vec::new(),
        });
    }
    // Decode what was written; mend the regions the decoder could not mesh cleanly (or
    // meshed far off the source) and write again, until it decodes clean or the rounds are
    // spent. Kept: the first clean encoding, else the best: one clean but off the source
    // (the nearest), then one that decodes (with faults) over one that does not, then a
    // sound mesh (closed where the source is, manifold, consistently oriented, in no more
    // pieces) over one that is not, then the fewest flipped and degenerate triangles, then
    // the fewest regions to blame, then the earliest.
    // A source that is not manifold gives a decoded mesh that is not either (see
    // MeshCheck::is_clean_from): no round could mend that.
    let source = Source::with_threads(mesh, settings.segment.threads)?;
    let max_added = MAX_SPLIT_REGIONS.max(requested);
    let mut best: Option<(Score, Encoded)> = None;
    // The regions the best file's check blamed.
    let mut best_blamed: Vec<u32> = Vec::new();
    // How faithfully each region's boundaries are stored, for the present segmentation.
    let mut fidelity = vec![floor; segmentation.region_count()];
    // The segmentations checked so far: mending must not go round in circles (dissolving
    // the small region a split made gives back the segmentation before the split).
    let mut checked: Vec<Vec<u32>> = vec![segmentation.labels.clone()];
    // Files written and checked: the first, then one a round of mending that got that far.
    let mut verified = 0usize;
    loop {
        let (mut stored, boundary_points) =
            match represent(mesh, &segmentation, settings, &fidelity) {
                Ok(r) => r,
                // A split whose boundaries the representation cannot hold (a bug of the boundary
                // stage, seen once on a real mesh): the encodings before it stand.
                Err(EncodeMeshError::Representation(_)) if best.is_some() => break,
                Err(e) => return Err(e),
            };
        let (verdict, treatment) = verify(&stored.bytes, &source, &segmentation.labels)?;
        verified += 1;
        // A file that decodes clean only with a later treatment than the decoder's first
        // names it, so that decoders mesh it once instead of trying each before it.
        if let Some(t) = treatment.filter(|&t| t != Treatment::FIRST) {
            stored.hint(t)?;
        }
        let score = verdict.score();
        let rank = score.0;
        let seams = verdict.closed_on_themselves();
        let (mut blamed, problem) = verdict.blamed_and_problem();
        verification.problem = problem;
        let done = verification.problem.is_none();
        let candidate = Encoded::new(
            stored,
            segmentation.clone(),
            boundary_points,
            verification.clone(),
        );
        if best.as_ref().is_none_or(|(s, _)| score < *s) {
            best = Some((score, candidate));
            best_blamed = blamed.iter().map(|s| s.region).collect();
        }
        if done || blamed.is_empty() || verification.rounds >= max_rounds {
            break;
        }
        verification.rounds += 1;
        // A region whose boundary the decoder cannot chart (the file does not decode):
        // smoothing toward the ellipsoids' intersections, or simplification, can move a
        // boundary far enough from the mesh's to fold it, or to close the gap between two of
        // its loops. Its boundaries are first stored at the mesh's points (simplified), then
        // as the mesh has them.
        if rank == DOES_NOT_DECODE
            && raise_fidelity(
                &mut fidelity,
                blamed
                    .iter()
                    .map(|s| s.region)
                    .filter(|r| !seams.contains(r)),
            )
        {
            continue;
        }
        // A blamed region too small for an ellipsoid whose fit is turned against its own
        // faces gets the sphere tangent to it instead, and is not mended otherwise this
        // round: a region of one or two faces is decoded as it is, flipped on such a needle,
        // and neither dissolving nor splitting it mended Stanford's dragon at `res4`.
        let faces = segmentation.faces_by_region();
        let mut refitted = false;
        blamed.retain(|split| {
            let r = split.region as usize;
            let (Some(own), Some(proxy)) = (faces.get(r), segmentation.proxies.get(r)) else {
                return true;
            };
            let Some((sphere, error)) = metric.tangent_in_place_of_needle(own, proxy) else {
                return true;
            };
            segmentation.proxies[r] = sphere;
            if let Some(e) = segmentation.region_errors.get_mut(r) {
                segmentation.total_error += error - *e;
                *e = error;
            }
            refitted = true;
            false
        });
        if refitted && blamed.is_empty() {
            continue;
        }
        // Small regions are dissolved into their neighbours (splitting them would only make
        // smaller ones, whose fits go wilder still); the others are split, within the budget
        // (hosts need at least two faces).
        let small = |r: u32| {
            faces.get(r as usize).map_or(0, Vec::len) as f64
                <= SMALL_REGION_SHARE * mesh.face_count() as f64 / requested.max(1) as f64
        };
        let tiny: Vec<u32> = blamed
            .iter()
            .map(|s| s.region)
            .filter(|&r| small(r))
            .collect();
        let dissolved = if tiny.is_empty() {
            None
        } else {
            dissolve_regions(
                mesh,
                &metric,
                &settings.segment,
                &segmentation,
                &tiny,
                progress,
            )
            .ok()
            .filter(|s| !checked.contains(&s.labels))
        };
        segmentation = match dissolved {
            Some(s) => s,
            // Nothing to dissolve, or dissolving gives a segmentation already checked: split
            // every blamed region, small ones included.
            None => {
                let room = (requested + max_added).saturating_sub(segmentation.region_count());
                let hosts: Vec<Split> = blamed
                    .into_iter()
                    .filter(|s| faces.get(s.region as usize).is_some_and(|f| f.len() >= 2))
                    .take(room)
                    .collect();
                if hosts.is_empty() {
                    if refitted {
                        continue;
                    }
                    break;
                }
                split_regions(
                    mesh,
                    &metric,
                    &settings.segment,
                    &segmentation,
                    &hosts,
                    progress,
                )?
            }
        };
        if checked.contains(&segmentation.labels) {
            break;
        }
        checked.push(segmentation.labels.clone());
        fidelity = vec![floor; segmentation.region_count()];
    }
    // The loop keeps an encoding before it can break.
    best.map(|(score, mut encoded)| {
        encoded.verification.tried = verified.saturating_sub(1);
        Checked {
            score,
            encoded,
            blamed: best_blamed,
        }
    })
    .ok_or_else(|| EncodeMeshError::Unreachable("internal error: no encoding was kept".into()))
}

/// What [`encode_mesh`] does first when no search gave a file that decodes clean (before
/// making every search again with the junctions held, [`Fidelity::Junctions`]): each
/// search's best file (`tried`: the requested segmentation's, then the one weighted by
/// area, then the raised ones, each mended as far as it went), in that order, is stored
/// again with the boundaries of the regions its decoder check blamed at the mesh's own
/// points, simplified, then with every one of them kept (the steps a region whose boundary
/// cannot be charted takes first, [`Fidelity`]; the regions blamed at the first step join
/// those of the second). The first clean file ends it; otherwise the best file of all is
/// kept (ties: the earliest). Boundaries smoothed toward the ellipsoids' intersections
/// (section 4.1) can leave the junction of thin regions off them: a low-polygon spider's
/// legs decoded with faces of boundary points only, turned over; at the mesh's points they
/// follow the surface the ellipsoids were fitted to.
///
/// It comes last so that every file a search makes clean stays as it was:
/// - as the first step of mending for every file that decodes with faults, it mended 9 of
///   the 60 small-mesh files of `cargo bench --bench clean` with more regions and bytes
///   (14 962 → 16 238 bytes, 150 → 169 regions);
/// - at the end of each search, it ended armadillo's at K = 12 with 28 regions in 3 661
///   bytes, before the weighted search's 20 regions in 2 359.
///
/// Each search's best gets it, not only the best of all: on that alone, assimp's concave
/// polygon at K = 13 kept a flipped triangle. It takes [`FAITHFUL_STEPS`] steps at most:
/// for as many steps as new regions were blamed, Stanford's dragon at `res3` (892 pieces)
/// encoded in 439 s instead of 127, to the same file.
fn store_blamed_faithfully(
    mesh: &Mesh,
    settings: &EncodeSettings,
    tried: Vec<Checked>,
) -> Result<Checked, EncodeMeshError> {
    let source = Source::with_threads(mesh, settings.segment.threads)?;
    let mut best: Option<Checked> = None;
    for checked in tried {
        let checked = store_faithfully(mesh, settings, &source, checked)?;
        if checked.score.0 == CLEAN {
            return Ok(checked);
        }
        if best.as_ref().is_none_or(|b| checked.score < b.score) {
            best = Some(checked);
        }
    }
    best.ok_or_else(|| EncodeMeshError::Unreachable("internal error: no encoding was kept".into()))
}

/// One file of [`store_blamed_faithfully`]: `kept` and, stored again as it says, the better.
fn store_faithfully(
    mesh: &Mesh,
    settings: &EncodeSettings,
    source: &Source,
    kept: Checked,
) -> Result<Checked, EncodeMeshError> {
    if kept.score.0 == CLEAN {
        return Ok(kept);
    }
    let segmentation = kept.encoded.segmentation.clone();
    let mut blamed = kept.blamed;
    let mut best = (kept.score, kept.encoded);
    let mut fidelity = vec![Fidelity::Smoothed; segmentation.region_count()];
    let mut tried = best.1.verification.tried;
    for _ in 0..FAITHFUL_STEPS {
        if !raise_fidelity(&mut fidelity, blamed.iter().copied()) {
            break;
        }
        let Ok((mut stored, boundary_points)) = represent(mesh, &segmentation, settings, &fidelity)
        else {
            break;
        };
        let (verdict, treatment) = verify(&stored.bytes, source, &segmentation.labels)?;
        tried += 1;
        if let Some(t) = treatment.filter(|&t| t != Treatment::FIRST) {
            stored.hint(t)?;
        }
        let score = verdict.score();
        let (now_blamed, problem) = verdict.blamed_and_problem();
        for r in now_blamed {
            if !blamed.contains(&r.region) {
                blamed.push(r.region);
            }
        }
        if score < best.0 {
            let verification = Verification {
                rounds: tried,
                problem,
                ..best.1.verification.clone()
            };
            best = (
                score,
                Encoded::new(stored, segmentation.clone(), boundary_points, verification),
            );
        }
        if best.0 .0 == CLEAN {
            break;
        }
    }
    best.1.verification.tried = tried;
    Ok(Checked {
        score: best.0,
        encoded: best.1,
        blamed,
    })
}

/// Steps of [`store_blamed_faithfully`]: the blamed regions' boundaries at the mesh's
/// points, simplified, then every one kept.
const FAITHFUL_STEPS: usize = 2;

/// Most rounds of mending (boundaries stored more faithfully, regions dissolved or split)
/// [`encode_mesh`] runs to make its file decode clean.
pub const MAX_SPLIT_ROUNDS: usize = 24;

/// Most regions the splitting may add: this many, or the requested count if larger.
pub const MAX_SPLIT_REGIONS: usize = 16;

/// A region the decoder cannot mesh cleanly is dissolved into its neighbours, not split,
/// when it has at most this share of the mean region's faces (the mesh's faces over the
/// regions asked for). Such regions are fitted with ellipsoids far smaller or flatter than
/// the region is wide (creases, tips), and splitting them makes that worse.
pub const SMALL_REGION_SHARE: f64 = 0.25;

/// How the encoder checked its own file (see [`EncodeSettings::verify`]).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Verification {
    /// Regions the segmentation was asked for (or chose, for a tolerance).
    pub requested_regions: usize,
    /// Rounds of mending that were needed (a region's boundaries stored more faithfully,
    /// small regions dissolved, or regions split): the round the kept file comes from.
    pub rounds: usize,
    /// Rounds of mending tried in all: more than `rounds` when no round made the file
    /// clean and an earlier one was kept.
    pub tried: usize,
    /// The region count the segmentation was raised to, when no file at the requested
    /// count decoded clean (see [`encode_mesh`]).
    pub raised_regions: Option<usize>,
    /// Whether the segmentation was done again with each face's error weighted by its area
    /// ([`SegmentOptions::area_weighting`]), not asked for, because no file with the plain
    /// weighting decoded clean (see [`encode_mesh`]).
    pub area_weighted: bool,
    /// What is still wrong with the decoded file, when mending could not make it clean
    /// (`None`: it decodes clean, or it was not checked). Clean as far as the source
    /// allows: a source that is not manifold gives a mesh that is not either
    /// ([`crate::remesh::assemble::MeshCheck::is_clean_from`]).
    pub problem: Option<String>,
}

/// What decoding an encoding at its suggested density gave: clean; clean but with regions
/// far from the source (how far, in ten-thousandths of the diagonal); a mesh with faults;
/// or an error. With the regions to blame (possibly none), each with where to cut it when
/// that is known, and what went wrong.
enum Verdict {
    Clean,
    Far(u32, Vec<Split>, String),
    Dirty(Faults, Vec<Split>, String),
    /// With the regions that close on themselves
    /// ([`crate::remesh::assemble::RegionFault::seam`]), which only a cut mends.
    Fails(Vec<Split>, String, Vec<u32>),
}

/// How a verdict ranks, lower better: clean, then decodes with faults, then clean with a
/// region far from the source, then both, then fails; then the faults; then the regions to
/// blame.
type Score = (u8, Faults, usize);

impl Verdict {
    /// The regions to blame and what went wrong (none for a clean file).
    fn blamed_and_problem(self) -> (Vec<Split>, Option<String>) {
        match self {
            Verdict::Clean => (Vec::new(), None),
            Verdict::Far(_, regions, problem)
            | Verdict::Dirty(_, regions, problem)
            | Verdict::Fails(regions, problem, _) => (regions, Some(problem)),
        }
    }

    /// The regions that close on themselves, which storing their boundaries more faithfully
    /// cannot mend ([`crate::remesh::assemble::RegionFault::seam`]).
    fn closed_on_themselves(&self) -> Vec<u32> {
        match self {
            Verdict::Fails(_, _, seams) => seams.clone(),
            _ => Vec::new(),
        }
    }

    /// Which encoding [`encode_mesh`] keeps when none decodes clean: the lowest score.
    fn score(&self) -> Score {
        match self {
            Verdict::Clean => (CLEAN, Faults::default(), 0),
            Verdict::Far(distance, blamed, _) => (
                FAR,
                Faults {
                    off: true,
                    distance: *distance,
                    ..Faults::default()
                },
                blamed.len(),
            ),
            Verdict::Dirty(faults, blamed, _) => {
                let rank = if faults.off { DIRTY_AND_FAR } else { DIRTY };
                (rank, *faults, blamed.len())
            }
            Verdict::Fails(blamed, _, _) => (DOES_NOT_DECODE, Faults::default(), blamed.len()),
        }
    }
}

/// How bad a mesh that is not clean is, worst first in the order of comparison: a region
/// off the source, then unsound (not closed where its source is, not manifold, not
/// consistently oriented, or in more pieces than the source), then its flipped and
/// degenerate triangles, then its departure from the source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
struct Faults {
    /// Some region departs from the source by more than [`MAX_DEPARTURE`] beyond what its
    /// ellipsoid misses (or [`MAX_RMS_DEPARTURE`] in RMS), or is missing ([`MAX_LOST`];
    /// `Source::far_regions`).
    off: bool,
    unsound: bool,
    bad_triangles: usize,
    /// For a mesh that decodes clean, how far its farthest region departs from the source,
    /// in ten-thousandths of the diagonal.
    distance: u32,
}

/// The source mesh as the decoder check sees it.
struct Source<'a> {
    mesh: &'a Mesh,
    manifold: bool,
    /// Connected components.
    pieces: usize,
    diagonal: f64,
    /// The source's faces, for the distance from a decoded point to the source.
    faces: Bvh,
    /// Each face's centroid, for the distance from the source to the decoded mesh.
    centroids: Vec<DVec3>,
    /// Each face's axis-aligned bounding box.
    face_boxes: Vec<Aabb>,
    /// The charts of every decode of this source's files ([`ChartMemo`]): a round of
    /// mending changes a few regions, and the check meets the others' charts again.
    charts: ChartMemo,
    /// Where the check's parallel steps run ([`Source::with_threads`]).
    exec: Exec,
}

impl Source<'_> {
    fn new(mesh: &Mesh) -> Source<'_> {
        Source {
            mesh,
            manifold: mesh.topology().is_manifold(),
            pieces: mesh.topology().component_count(),
            diagonal: mesh.bounding_box().map_or(0.0, |b| b.diagonal()),
            faces: face_bvh(mesh),
            centroids: (0..mesh.face_count())
                .map(|f| mesh.face_centroid(f))
                .collect(),
            face_boxes: (0..mesh.face_count())
                .map(|f| {
                    let [a, b, c] = mesh.corners(f);
                    Aabb {
                        min: a.min(b).min(c),
                        max: a.max(b).max(c),
                    }
                })
                .collect(),
            charts: ChartMemo::default(),
            exec: Exec::Global,
        }
    }

    /// [`Source::new`], its parallel steps run by `threads` workers (`None`: all cores), as
    /// [`SegmentOptions::threads`] asks of the whole encoder.
    fn with_threads(mesh: &Mesh, threads: Option<usize>) -> Result<Source<'_>, EncodeMeshError> {
        Ok(Source {
            exec: Exec::new(threads)?,
            ..Source::new(mesh)
        })
    }

    /// The regions without a boundary (a closed piece of the mesh covered by one region,
    /// which the decoder meshes as its whole ellipsoid) whose ellipsoid reaches more than
    /// [`MAX_DEPARTURE`] of the diagonal beyond the box of the region's faces, farthest
    /// first, each with how far. Found before decoding, so also in a file that does not
    /// decode: assimp's `regr01.obj`, 58 pieces, fitted a flat closed piece with radii of a
    /// thousand diagonals; the file failed on another region in every round of mending,
    /// this one was never blamed, and decoders (leaving out what fails) meshed the whole
    /// ellipsoid, 500 diagonals RMS off the source.
    fn far_whole_regions(&self, rep: &Representation, labels: &[u32]) -> Vec<(u32, f64)> {
        let mut boxes: Vec<Option<Aabb>> = vec![None; rep.ellipsoids.len()];
        for (face, &r) in self.face_boxes.iter().zip(labels) {
            if let Some(b) = boxes.get_mut(r as usize) {
                *b = Some(b.map_or(*face, |b| b.union(face)));
            }
        }
        let limit = MAX_DEPARTURE * self.diagonal;
        let mut far: Vec<(u32, f64)> = (0u32..)
            .zip(rep.ellipsoids.iter().zip(&rep.cycles).zip(boxes))
            .filter_map(|(r, ((e, cycles), faces))| {
                let faces = faces.filter(|_| cycles.is_empty())?;
                let half = e.half_extent();
                let beyond = (faces.min - (e.center - half))
                    .max(e.center + half - faces.max)
                    .max_element();
                // Not finite: a hostile or broken fit, as far as it gets.
                (beyond > limit || beyond.is_nan()).then_some((r, beyond))
            })
            .collect();
        far.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        far
    }

    /// When a mesh decoded clean is in more pieces than the source, the regions of the
    /// extra pieces (all but as many of the largest, by faces, as the source has) and the
    /// count. Two small regions, each meshed as one triangle on the same three boundary
    /// points, make a closed, manifold, consistently oriented piece of no volume: horse's
    /// file at K = 18, mended for surface decoded off the source (a region split in two),
    /// had two such pieces, and subdividing one makes every inner edge an edge of four
    /// triangles.
    fn extra_pieces(&self, decoded: &Remeshed) -> Option<(Vec<u32>, usize)> {
        let topology = decoded.mesh.topology();
        let pieces = topology.component_count();
        if pieces <= self.pieces {
            return None;
        }
        let mut faces = vec![0usize; pieces];
        for &c in topology.face_components() {
            faces[c as usize] += 1;
        }
        let mut order: Vec<usize> = (0..pieces).collect();
        order.sort_by(|&a, &b| faces[b].cmp(&faces[a]).then(a.cmp(&b)));
        let mut extra = vec![false; pieces];
        for &c in &order[self.pieces..] {
            extra[c] = true;
        }
        let blamed: std::collections::BTreeSet<u32> = topology
            .face_components()
            .iter()
            .zip(&decoded.face_regions)
            .filter(|(&c, _)| extra[c as usize])
            .map(|(_, &r)| r)
            .collect();
        Some((blamed.into_iter().collect(), pieces))
    }

    /// Whether a decoded mesh keeps to the source as [`verify`] asks of a clean one: no
    /// region far from it ([`Source::far_regions`]) and no more pieces than it has
    /// ([`Source::extra_pieces`]).
    fn keeps_to(&self, decoded: &Remeshed, ellipsoids: &[Ellipsoid], labels: &[u32]) -> bool {
        self.extra_pieces(decoded).is_none()
            && self
                .far_regions(&decoded.mesh, &decoded.face_regions, ellipsoids, labels)
                .is_empty()
    }

    /// The regions of a mesh decoded clean whose surface departs from the source by more
    /// than [`MAX_DEPARTURE`] of the diagonal beyond what their ellipsoids miss, farthest
    /// first, each with that departure. Two ways, one for each direction:
    /// - surface the decoder left out: a source face whose centroid lies that much farther
    ///   from the decoded mesh than from its region's ellipsoid (a region meshed on the
    ///   wrong part of its ellipsoid: dino's tail at K = 12, mended once);
    /// - surface the decoder made up: a decoded face whose centroid lies that much farther
    ///   from the source than any of its region's faces from the region's ellipsoid (the
    ///   part of a long ellipsoid beyond the end of the limb it was fitted to, on the
    ///   region's side of its only boundary loop: dino's front leg at K = 12, a spike 30 %
    ///   of the diagonal long);
    /// - surface made up in bulk: a region whose decoded faces lie farther from the source,
    ///   in RMS over their area, than its source faces from its ellipsoid by more than
    ///   [`MAX_RMS_DEPARTURE`] of the diagonal, with that excess (Wuson at K = 71, mended:
    ///   a band round a thin neck meshed as half its ellipsoid, 9.6 % of the diagonal off
    ///   at most, 4.9 % in RMS).
    ///
    /// What the ellipsoids miss is the segmentation's error, which the region count asked
    /// for trades against the file's size; the rest is lost in decoding, at any count.
    ///
    /// A third way, with a lower bar: a region the decoder left without a face (every
    /// boundary loop of it enclosed nothing once its points were quantised and the arcs
    /// between them cleaned, as a decoder must read them, `remesh::assemble::Plan`), of at
    /// least [`MIN_LOST_AREA`] of the source's area, whose source faces lie more than
    /// [`MAX_LOST`] of the diagonal from the decoded mesh, with the farthest of those
    /// distances. A region a few grid steps across whose loop quantisation merged is
    /// rightly empty (the regions around it close over the spot); a limb whose rings taper
    /// to a point is not.
    fn far_regions(
        &self,
        decoded: &Mesh,
        face_regions: &[u32],
        ellipsoids: &[Ellipsoid],
        labels: &[u32],
    ) -> Vec<(u32, f64)> {
        // Per region, its largest departure.
        let mut farthest = vec![0.0f64; ellipsoids.len()];
        let limit = MAX_DEPARTURE * self.diagonal;
        let mut note = |region: u32, departure: f64| {
            if let Some(d) = farthest.get_mut(region as usize) {
                *d = d.max(departure);
            }
        };
        let decoded_faces = face_bvh(decoded);
        // Each source face's distance to its region's ellipsoid, and to the decoded mesh
        // where that is more than the limit farther (measured exactly only there: most
        // faces are found within it at the first leaf); then each decoded face's to the
        // source likewise. In parallel, reduced in order.
        let fits: Vec<Option<(f64, Option<f64>)>> = self.exec.install(|| {
            self.centroids
                .par_iter()
                .zip(labels)
                .map(|(&c, &region)| {
                    let fit = c.distance(ellipsoids.get(region as usize)?.closest_point(c));
                    let off = (!decoded_faces.is_within(c, fit + limit))
                        .then(|| decoded_faces.find_closest(c))
                        .flatten()
                        .map(|hit| hit.distance_squared.sqrt());
                    Some((fit, off))
                })
                .collect()
        });
        // Per region, the farthest of its faces from its ellipsoid, and their RMS distance
        // from it over their area.
        let mut missed = vec![0.0f64; ellipsoids.len()];
        let mut missed_squares = vec![0.0f64; ellipsoids.len()];
        let mut source_areas = vec![0.0f64; ellipsoids.len()];
        for (f, (&region, fit)) in labels.iter().zip(fits).enumerate() {
            if let Some((fit, off)) = fit {
                let r = region as usize;
                let area = self.mesh.face_area(f);
                missed[r] = missed[r].max(fit);
                missed_squares[r] += fit * fit * area;
                source_areas[r] += area;
                if let Some(d) = off {
                    note(region, d - fit);
                }
            }
        }
        let missed_rms: Vec<f64> = missed_squares
            .iter()
            .zip(&source_areas)
            .map(|(&sq, &area)| if area > 0.0 { (sq / area).sqrt() } else { 0.0 })
            .collect();
        let rms_limit = MAX_RMS_DEPARTURE * self.diagonal;
        // Each decoded face's distance from the source: exact beyond its region's RMS miss
        // and half the RMS limit, else that much at most (most faces are found within it at
        // the first leaf).
        let bound =
            |region: u32| missed_rms.get(region as usize).copied().unwrap_or(0.0) + 0.5 * rms_limit;
        let distance_to_source = |f: usize| {
            self.faces
                .find_closest(decoded.face_centroid(f))
                .map_or(f64::INFINITY, |hit| hit.distance_squared.sqrt())
        };
        // (distance or its bound, whether exact) per decoded face.
        let made_up: Vec<(f64, bool)> = self.exec.install(|| {
            face_regions
                .par_iter()
                .enumerate()
                .map(|(f, &region)| {
                    let near = bound(region);
                    if self.faces.is_within(decoded.face_centroid(f), near) {
                        (near, false)
                    } else {
                        (distance_to_source(f), true)
                    }
                })
                .collect()
        });
        // Per region, its decoded area and (at most) the squares of its faces' distances.
        let mut decoded_areas = vec![0.0f64; ellipsoids.len()];
        let mut decoded_squares = vec![0.0f64; ellipsoids.len()];
        for (f, (&region, &(d, exact))) in face_regions.iter().zip(&made_up).enumerate() {
            let r = region as usize;
            let fit = missed.get(r).copied().unwrap_or(0.0);
            if exact && d > fit + limit {
                note(region, d - fit);
            }
            if let (Some(area), Some(squares)) =
                (decoded_areas.get_mut(r), decoded_squares.get_mut(r))
            {
                let a = decoded.face_area(f);
                *area += a;
                *squares += d * d * a;
            }
        }
        // The regions whose bound passes the RMS limit, measured exactly (few, if any): the
        // faces only bounded so far.
        let rms_excess = |r: usize, squares: f64| {
            let area = decoded_areas[r];
            if area > 0.0 {
                (squares / area).sqrt() - missed_rms[r]
            } else {
                0.0
            }
        };
        let mut in_bulk = vec![0.0f64; ellipsoids.len()];
        for r in 0..ellipsoids.len() {
            if rms_excess(r, decoded_squares[r]) <= rms_limit {
                continue;
            }
            let squares: f64 = self.exec.install(|| {
                face_regions
                    .par_iter()
                    .enumerate()
                    .filter(|&(_, &region)| region as usize == r)
                    .map(|(f, _)| {
                        let d = match made_up[f] {
                            (d, true) => d,
                            (_, false) => distance_to_source(f),
                        };
                        d * d * decoded.face_area(f)
                    })
                    .sum()
            });
            let excess = rms_excess(r, squares);
            if excess > rms_limit {
                in_bulk[r] = excess;
            }
        }
        // Per lost region (no decoded face, at least MIN_LOST_AREA of the source's area),
        // its farthest face from the decoded mesh past MAX_LOST (0: none). Most meshes
        // leave no region without a face, and skip the rest.
        let mut lost = vec![true; ellipsoids.len()];
        for &region in face_regions {
            if let Some(l) = lost.get_mut(region as usize) {
                *l = false;
            }
        }
        let mut gone = vec![0.0f64; ellipsoids.len()];
        if lost.contains(&true) {
            let mut areas = vec![0.0f64; ellipsoids.len()];
            for (f, &region) in labels.iter().enumerate() {
                if let Some(a) = areas.get_mut(region as usize) {
                    *a += self.mesh.face_area(f);
                }
            }
            let least = MIN_LOST_AREA * areas.iter().sum::<f64>();
            for (l, &a) in lost.iter_mut().zip(&areas) {
                *l &= a >= least;
            }
            let lost_limit = MAX_LOST * self.diagonal;
            let missing: Vec<Option<f64>> = self.exec.install(|| {
                self.centroids
                    .par_iter()
                    .zip(labels)
                    .map(|(&c, &region)| {
                        if !lost.get(region as usize).copied().unwrap_or(false)
                            || decoded_faces.is_within(c, lost_limit)
                        {
                            return None;
                        }
                        Some(
                            decoded_faces
                                .find_closest(c)
                                .map_or(f64::INFINITY, |hit| hit.distance_squared.sqrt()),
                        )
                    })
                    .collect()
            });
            for (&region, distance) in labels.iter().zip(missing) {
                if let (Some(d), Some(g)) = (distance, gone.get_mut(region as usize)) {
                    *g = g.max(d);
                }
            }
        }
        let mut far: Vec<(u32, f64)> = (0u32..)
            .zip(farthest.into_iter().zip(gone).zip(in_bulk))
            .filter_map(|(r, ((d, g), b))| {
                let worst = if d > limit { d.max(g) } else { g }.max(b);
                (worst > 0.0).then_some((r, worst))
            })
            .collect();
        far.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        far
    }
}

/// A mesh's faces in a [`Bvh`], each with its index.
fn face_bvh(mesh: &Mesh) -> Bvh {
    Bvh::build(
        (0..mesh.face_count())
            .map(|f| (mesh.corners(f), f as u32))
            .collect(),
    )
}

/// A region whose decoded surface departs from the source by more than this share of the
/// source's bounding-box diagonal beyond what its ellipsoid misses (surface made up: the
/// rest of a long ellipsoid past the end of a limb; or left out: a region meshed on the
/// wrong part of its ellipsoid) is split like one that does not mesh cleanly; a file that
/// decodes clean with such a region ranks after one without and before one with faults.
/// A gross failure, not a tolerance: a tenth of the diagonal is a spike or a missing limb
/// anyone sees. The 72 files of the 12 small shared meshes at K = 4, 8, 12, 18, 24 and 32,
/// as segmented, depart by at most 7.4 % but for 15, which depart by 10.6 to 29.7 % (dino
/// at K = 4 to 18, horse at 4 to 24, fandisk at 4 and 8, bunny, hand, spot and teddy at
/// one count each); mended, those are under a tenth, and their symmetric Hausdorff
/// distance to the source falls from 12.6–30.7 % to 3.3–10.9 %.
pub const MAX_DEPARTURE: f64 = 0.1;

/// A region whose decoded surface lies farther from the source in RMS (over its decoded
/// area) than its source faces lie from its ellipsoid (over theirs), by more than this
/// share of the source's bounding-box diagonal, is far from the source as one past
/// [`MAX_DEPARTURE`] is (`Source::far_regions`): surface made up in bulk, short of a
/// spike. Wuson at K = 71, mended, kept a band round a thin neck meshed as half its
/// ellipsoid (5.5 times its source area; 9.6 % of the diagonal off at most, 4.9 % in RMS)
/// and armadillo at K = 12 a region 3.0 % off in RMS (the file's RMS 2.1 and 1.2 %). The
/// regions of the clean files of hand, horse, dino, teddy, spot and duck (K = 8 to 24) lie
/// at most 0.8 % farther in RMS than their ellipsoids (dino's and horse's legs).
pub const MAX_RMS_DEPARTURE: f64 = 0.02;

/// A region the decoder leaves without a face is lost when its source faces lie farther
/// than this share of the source's bounding-box diagonal from the decoded mesh and it holds
/// at least [`MIN_LOST_AREA`] of the source's area (`Source::far_regions`); it is mended
/// like a region far from the source, and a file with one ranks as such. Measured on
/// assimp's models at their default K, with the release before this check (every file
/// clean by the decoder's own check): 9 regions of 4 files had no face; 7 are lost, a shin
/// of `3ds_max_export` whose rings taper to a point (20 faces, 2.1 % of the area, up to
/// 6.7 % of the diagonal from the mesh) and two regions beside it (0.4 and 1.2 %), two
/// pieces of a spider's leg (1.9 and 0.13 % of the area, 5.4 and 1.3 % of the diagonal
/// off), and Wuson's tail in two regions (1.6 and 0.7 %, 1.9 and 2.0 % off: a tube cut
/// open along a seam of duplicated vertices, its rings simplified to three points of
/// which two coincide).
pub const MAX_LOST: f64 = 0.01;

/// The least share of the source's area a region left without a face must hold to count
/// as lost ([`MAX_LOST`]): a thousandth. Below it lie the specks a scan leaves, for which
/// the search for a clean file is not worth making: Stanford's dragon at `res4`, whose
/// file leaves 10 regions of 4 to 10 faces (0.017–0.067 % of its area; one a strand 8 % of
/// the diagonal long) without a face, was searched for them when they counted, and ended
/// with a file of 7 flipped triangles, 19 959 bytes instead of 18 259, in 93 s instead of
/// 6.
pub const MIN_LOST_AREA: f64 = 0.001;

/// Decodes `bytes` as any reader would ([`format::Limits::default`],
/// [`crate::remesh::RemeshOptions::default`], but with no region left out: a file that
/// decodes only with holes counts as one that does not decode) and says whether the mesh
/// is clean as far as the source allows
/// ([`crate::remesh::assemble::MeshCheck::is_clean_from`]) and keeps to the source
/// (`Source::far_regions`, with the source's faces in regions by `labels`) and, if not,
/// which regions to blame; with the treatment a mesh clean by the decoder's own check
/// ([`crate::remesh::assemble::MeshCheck::is_clean`]) was made with (clean and far alike),
/// or for a clean file the treatment that meshes it closest to the source
/// ([`closest_treatment`]).
fn verify(
    bytes: &[u8],
    source: &Source,
    labels: &[u32],
) -> Result<(Verdict, Option<Treatment>), EncodeMeshError> {
    use crate::remesh::assemble::{problem_regions, region_faults, triangle_faults_note};
    use crate::remesh::{remesh_with_charts, RemeshError, RemeshOptions};
    let source_manifold = source.manifold;
    let representation = format::decode(bytes, &format::Limits::default())?;
    // A file that decodes only with regions left out ranks as one that does not decode:
    // the mesh without them is not needed (it would cost a whole meshing per round).
    let options = RemeshOptions {
        leave_out: false,
        ..RemeshOptions::default()
    };
    let out = match remesh_with_charts(&representation, &options, &source.charts) {
        Ok(out) => out,
        // The decoder reports the region its last attempt stopped at, which is often not
        // where its first (and best) attempt failed. Blamed instead: the first region that
        // fails in the first attempt, cut between the two sheets of its fold when the chart
        // shows one. One region a round: splitting every failing region at once was measured
        // worse (dino at K = 12 took 26 regions instead of 15).
        // Blamed too: every whole region far beyond its piece (`Source::far_whole_regions`),
        // which decoders leaving out the failing region would mesh. But where some regions
        // close on themselves (`RegionFault::seam`), those are blamed instead of the first:
        // only a cut mends them, and each needs one. assimp's `regr01` fails on such a
        // region (a closed frame) in its first 16 rounds, blamed first in its 13th: chart
        // faults of lower regions came first and were mended in between.
        Err(RemeshError::Region { region, what }) => {
            let faults = region_faults(&representation, &options, &source.charts)?;
            let seams: Vec<u32> = faults.iter().filter(|f| f.seam).map(|f| f.region).collect();
            let splits: Vec<Split> = if seams.is_empty() {
                let split = faults
                    .first()
                    .map(|f| Split {
                        region: f.region,
                        cut: f.crossing.and_then(cut_between),
                    })
                    .unwrap_or(Split { region, cut: None });
                vec![split]
            } else {
                seams
                    .iter()
                    .map(|&region| Split { region, cut: None })
                    .collect()
            };
            let mut blamed: Vec<Split> = source
                .far_whole_regions(&representation, labels)
                .into_iter()
                .filter(|&(r, _)| splits.iter().all(|s| s.region != r))
                .map(|(region, _)| Split { region, cut: None })
                .collect();
            blamed.extend(splits);
            return Ok((
                Verdict::Fails(
                    blamed,
                    format!("does not decode: region {region}: {what}"),
                    seams,
                ),
                None,
            ));
        }
        Err(e) => return Err(e.into()),
    };
    // How far the mesh departs from the source, whatever else is wrong with it: a mesh
    // with a flipped triangle and a region meshed a thousand diagonals away (horse at
    // K = 48, mended) must not rank with one that has only the flipped triangle.
    let far = source.far_regions(
        &out.mesh,
        &out.face_regions,
        &representation.ellipsoids,
        labels,
    );
    let departure = far.first().map_or(0, |&(_, d)| {
        (d / source.diagonal * 1e4).round().min(f64::from(u32::MAX)) as u32
    });
    let blame = |regions: Vec<u32>| -> Vec<Split> {
        regions
            .into_iter()
            .map(|region| Split { region, cut: None })
            .collect()
    };
    let c = out.check;
    let extra = source.extra_pieces(&out);
    if !c.is_clean_from(source_manifold) || extra.is_some() {
        let faults = Faults {
            off: !far.is_empty(),
            unsound: !c.is_sound_from(source_manifold) || extra.is_some(),
            bad_triangles: c.flipped + c.degenerate,
            distance: departure,
        };
        let verdict = match extra {
            Some((regions, pieces)) if c.is_clean_from(source_manifold) => Verdict::Dirty(
                faults,
                blame(regions),
                format!(
                    "decodes in {pieces} pieces where the source has {}",
                    source.pieces
                ),
            ),
            _ => {
                // The regions far from the source are to blame too: mended only for its
                // faulty triangles, assimp's spider at K = 35 (raised from 29) kept a region
                // meshed 1.5 diagonals off in every round.
                // Where the flipped and degenerate triangles are: blamed, and told in the
                // problem as `ellip decode` tells them.
                let faulty = out.faulty_regions(&representation);
                let mut regions = problem_regions(&out, &faulty, source_manifold);
                for &(region, _) in &far {
                    if !regions.contains(&region) {
                        regions.push(region);
                    }
                }
                Verdict::Dirty(
                    faults,
                    blame(regions),
                    format!(
                        "decodes with {}{}",
                        c.faults(),
                        triangle_faults_note(&faulty)
                    ),
                )
            }
        };
        return Ok((verdict, None));
    }
    let verdict = match far.first() {
        None => Verdict::Clean,
        Some(&(region, distance)) => Verdict::Far(
            departure,
            blame(far.iter().map(|&(r, _)| r).collect()),
            if out.face_regions.contains(&region) {
                format!(
                    "decodes clean, but region {region} departs from the source by {:.1} % of \
                     the diagonal more than its ellipsoid does",
                    100.0 * distance / source.diagonal
                )
            } else {
                format!(
                    "decodes clean, but without region {region}, whose faces lie up to {:.1} % \
                     of the diagonal from the mesh",
                    100.0 * distance / source.diagonal
                )
            },
        ),
    };
    // A mesh clean only as far as a non-manifold source allows is not clean to a decoder,
    // which goes on searching whatever the file names: no hint then.
    let treatment = match out.treatment.filter(|_| c.is_clean()) {
        Some(used) if matches!(verdict, Verdict::Clean) => {
            let named =
                closest_treatment(&representation, &options, source, labels, (used, &out.mesh))?;
            Some(treatment_clean_when_denser(
                &representation,
                &options,
                source,
                labels,
                named,
            ))
        }
        other => other,
    };
    Ok((verdict, treatment))
}

/// How many times the check's budget [`treatment_clean_when_denser`] decodes at.
const DENSER_BUDGET: usize = 2;

/// `named`, the treatment that meshes the file clean at the check's budget (the source's
/// vertex count), unless it does not at [`DENSER_BUDGET`] times that and the treatment
/// the decoder's search ends with there meshes clean at both (keeping to the source at the
/// check's, as [`verify`] asks): a decoder at another budget
/// than the check's would otherwise mesh the file once with the one named and then search
/// the others from the first. Horse at K = 20 in volume mode (the decode bench's file)
/// named the refined arcs with every ear pruned, clean at its 2 502 vertices, not at 5 000
/// or 50 000, which took 4 meshings each (2.9 and 2.1 times as long) to end at the stored
/// arcs, clean at all three.
fn treatment_clean_when_denser(
    representation: &Representation,
    options: &crate::remesh::RemeshOptions,
    source: &Source,
    labels: &[u32],
    named: Treatment,
) -> Treatment {
    use crate::remesh::{remesh_with_charts, RemeshOptions};
    if named == Treatment::FIRST {
        return named;
    }
    let denser = RemeshOptions {
        vertices: Some(DENSER_BUDGET.saturating_mul(options.budget(representation))),
        ..options.clone()
    };
    let mut hinted = representation.clone();
    hinted.metadata.remesh_hint = Some(named.code());
    let Ok(there) = remesh_with_charts(&hinted, &denser, &source.charts) else {
        return named;
    };
    if there.attempts == 1 && there.check.is_clean() {
        return named;
    }
    let Some(other) = there.treatment.filter(|_| there.check.is_clean()) else {
        return named;
    };
    hinted.metadata.remesh_hint = Some(other.code());
    match remesh_with_charts(&hinted, options, &source.charts) {
        Ok(here)
            if here.attempts == 1
                && here.check.is_clean()
                && source.keeps_to(&here, &representation.ellipsoids, labels) =>
        {
            other
        }
        _ => named,
    }
}

/// The boundary treatments the encoder weighs by their mesh's distance to the source once
/// its file decodes clean, in the order of [`Treatment::sequence`]: the decoder's first (arcs
/// refined onto the intersection curves of their ellipsoids, narrow double ears pruned),
/// the stored arcs pruned the same way, and the stored arcs with no ear pruned. Refined
/// arcs are smooth where regions meet along smooth curves, but where a source has creases
/// (CAD parts) the fitted ellipsoids meet off the crease, and the arcs as stored follow it:
/// fandisk at K = 24 and 3 000 vertices, 0.327 % of the diagonal RMS with the first and
/// 0.133 % with the stored arcs, no ear pruned; a cube of 8 × 8 squares a side at K = 6,
/// 2.09 % and 1.64 %. The treatments that prune every ear were never closer by more than
/// 0.3 % on the shared meshes' K = 24 files, and up to 28 % farther (they cut corners).
const WEIGHED_TREATMENTS: [Treatment; 3] = [
    Treatment::FIRST,
    Treatment {
        refined: false,
        ..Treatment::FIRST
    },
    Treatment {
        refined: false,
        prune: Prune::Off,
        ..Treatment::FIRST
    },
];

/// Area samples per mesh when [`closest_treatment`] weighs treatments (a fifth of
/// `compare`'s default): the RMS estimate's relative standard error stays under 1 %, and
/// the source's samples are the same for every treatment.
const WEIGHING_SAMPLES: usize = 20_000;

/// How much closer to the source (a share of the symmetric RMS distance) a later treatment's
/// mesh must be for the encoder to name it instead of the first that meshed clean: less
/// is within the sampling's noise, and a named treatment that is not clean at another
/// budget costs that decode a meshing more.
const WEIGHING_MARGIN: f64 = 0.02;

/// Of the treatments in [`WEIGHED_TREATMENTS`] from `used` on (the first that meshed the
/// file clean, `decoded` its mesh; those before it did not), the one whose mesh, clean and
/// keeping to the source as [`verify`] asks, is closest to the source by the symmetric RMS
/// distance of [`crate::compare`]; `used` unless another is closer by
/// [`WEIGHING_MARGIN`]. Each later treatment is meshed once, as a decoder does when the
/// file names it (`used` is not one of them: `used`).
fn closest_treatment(
    representation: &Representation,
    options: &crate::remesh::RemeshOptions,
    source: &Source,
    labels: &[u32],
    (used, decoded): (Treatment, &Mesh),
) -> Result<Treatment, EncodeMeshError> {
    use crate::compare::{compare_meshes, CompareOptions};
    let Some(at) = WEIGHED_TREATMENTS.iter().position(|&t| t == used) else {
        return Ok(used);
    };
    let later = &WEIGHED_TREATMENTS[at + 1..];
    if later.is_empty() {
        return Ok(used);
    }
    let compare = CompareOptions {
        samples: WEIGHING_SAMPLES,
        ..CompareOptions::default()
    };
    let rms = |m: &Mesh| -> Result<f64, EncodeMeshError> {
        let compared = source
            .exec
            .install(|| compare_meshes(source.mesh, m, &compare))?;
        Ok(compared.symmetric.distances.rms)
    };
    let first = rms(decoded)?;
    let mut best = (first, used);
    let mut hinted = representation.clone();
    for &t in later {
        hinted.metadata.remesh_hint = Some(t.code());
        // The file decoded clean with `used`: an error here is no reason to fail.
        let Ok(out) = crate::remesh::remesh_with_charts(&hinted, options, &source.charts) else {
            continue;
        };
        if out.treatment != Some(t)
            || !out.check.is_clean()
            || !source.keeps_to(&out, &representation.ellipsoids, labels)
        {
            continue;
        }
        let d = rms(&out.mesh)?;
        if d < best.0 {
            best = (d, t);
        }
    }
    Ok(if best.0 < first * (1.0 - WEIGHING_MARGIN) {
        best.1
    } else {
        used
    })
}

/// The plane halfway between two crossing loop edges, facing from one to the other: the
/// two edges lie on different sheets of a fold (close in the chart, apart in space), and a
/// region cut there no longer overlaps itself. `None` when the edges are not apart.
fn cut_between(crossing: [[DVec3; 2]; 2]) -> Option<Cut> {
    let [[a, b], [c, d]] = crossing;
    let (p, q) = ((a + b) / 2.0, (c + d) / 2.0);
    let scale = (a - b).length().max((c - d).length());
    let normal = (p - q).try_normalize()?;
    ((p - q).length() > scale && normal.is_finite()).then_some(Cut {
        point: (p + q) / 2.0,
        normal,
    })
}

impl Encoded {
    fn new(
        stored: Stored,
        segmentation: Segmentation<Ellipsoid>,
        boundary_points: usize,
        verification: Verification,
    ) -> Encoded {
        Encoded {
            bytes: stored.bytes,
            representation: stored.representation,
            segmentation,
            boundary_points,
            removed_points: stored.removed_points,
            bits: stored.bits,
            verification,
        }
    }
}

/// Everything after the segmentation: boundaries extracted and smoothed, the
/// representation built, simplified and written. Returns the file and the boundary point
/// count before simplification.
fn represent(
    mesh: &Mesh,
    segmentation: &Segmentation<Ellipsoid>,
    settings: &EncodeSettings,
    fidelity: &[Fidelity],
) -> Result<(Stored, usize), EncodeMeshError> {
    let tolerance = settings.simplify_tolerance;
    let graph = extract_boundaries(mesh, &segmentation.labels, segmentation.region_count())?;
    // An arc is stored as faithfully as the more faithful of its two regions asks; arcs at
    // the mesh's points keep them, junctions included. A speck (a piece of a scan too small
    // for an ellipsoid, `speck_faces`) is stored exactly from the start: smoothing moves
    // its three or four points toward the ellipsoids around it, which can turn it over (30
    // single-triangle regions of Stanford's dragon at `res4` decoded flipped so).
    let mut specks = vec![true; segmentation.region_count()];
    for (&speck, &r) in speck_faces(mesh).iter().zip(&segmentation.labels) {
        if let Some(s) = specks.get_mut(r as usize) {
            *s &= speck;
        }
    }
    let of = |r: u32| {
        if specks.get(r as usize).copied().unwrap_or(false) {
            return Fidelity::Exact;
        }
        fidelity
            .get(r as usize)
            .copied()
            .unwrap_or(Fidelity::Smoothed)
    };
    let arc_fidelity =
        |left: u32, right: Option<u32>| of(left).max(right.map_or(Fidelity::Smoothed, of));
    // The junctions of arcs stored as Fidelity::Junctions stay where the mesh has them
    // while the others relax.
    let held: Vec<u32> = graph
        .arcs
        .iter()
        .filter(|a| !a.closed && arc_fidelity(a.left, a.right.region()) == Fidelity::Junctions)
        .flat_map(|a| [a.vertices.first(), a.vertices.last()])
        .flatten()
        .copied()
        .collect();
    let smoothed =
        smooth_boundaries_holding(mesh, &graph, &segmentation.proxies, &settings.smooth, &held)?;
    let mut positions = mesh.positions().to_vec();
    let mut keep = vec![false; mesh.vertex_count()];
    let unsmoothed = graph
        .arcs
        .iter()
        .filter(|a| arc_fidelity(a.left, a.right.region()) >= Fidelity::MeshPoints);
    for a in unsmoothed {
        for &v in &a.vertices {
            keep[v as usize] = true;
        }
    }
    for (&v, &p) in graph.vertices.iter().zip(&smoothed) {
        if !keep[v as usize] {
            positions[v as usize] = p;
        }
    }
    let diagonal = mesh.bounding_box().map_or(0.0, |b| b.diagonal());
    let metadata = Metadata {
        source_vertices: mesh.vertex_count() as u64,
        source_faces: mesh.face_count() as u64,
        simplify_tolerance: None,
        measured_error: None,
        measured_hausdorff: None,
        // Decoders default to the source's vertex count: no need to store it twice.
        suggested_vertices: None,
        remesh_hint: None,
    };
    let representation =
        Representation::from_boundary(segmentation.proxies.clone(), &positions, &graph, metadata)?;
    let boundary_points = representation.points.len();
    let absolute_tolerance = tolerance * diagonal;
    let exact_arcs: Vec<bool> = representation
        .arcs
        .iter()
        .map(|a| arc_fidelity(a.left, a.right.region()) == Fidelity::Exact)
        .collect();
    let store = |representation: &Representation, absolute_tolerance: f64, bits: u8| {
        store(
            representation,
            absolute_tolerance,
            bits,
            &exact_arcs,
            &specks,
        )
    };
    let stored = match settings.bits {
        Some(bits) => store(&representation, absolute_tolerance, bits)?,
        None if absolute_tolerance == 0.0 => {
            store(&representation, absolute_tolerance, format::DEFAULT_BITS)?
        }
        // The grid and the simplification share the boundary tolerance: try each split and
        // keep the smallest file (ties: the finer grid).
        None => {
            let mut best: Option<Stored> = None;
            for bits in AUTO_BITS {
                let grid_error = format::Grid::around(&representation.points, bits).error_bound();
                if grid_error >= absolute_tolerance {
                    continue;
                }
                let candidate = store(&representation, absolute_tolerance, bits)?;
                if best
                    .as_ref()
                    .is_none_or(|b| candidate.bytes.len() <= b.bytes.len())
                {
                    best = Some(candidate);
                }
            }
            match best {
                Some(b) => b,
                None => store(&representation, absolute_tolerance, *AUTO_BITS.end())?,
            }
        }
    };
    Ok((stored, boundary_points))
}

/// How faithfully a region's boundaries are stored. The encoder's decoder check raises it
/// for regions the decoder cannot chart, one step a round; its last search starts every
/// region at [`Fidelity::Junctions`] (see [`encode_mesh`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Fidelity {
    /// Smoothed toward the ellipsoids (section 4.1) and simplified: the default.
    Smoothed,
    /// Smoothed and simplified, but the junctions kept where the mesh has them
    /// ([`smooth_boundaries_holding`]).
    Junctions,
    /// At the mesh's own points, simplified.
    MeshPoints,
    /// At the mesh's own points, every one kept (only the grid moves them).
    Exact,
}

impl Fidelity {
    /// The next, more faithful step, if any: a boundary the decoder cannot chart, or one
    /// whose faces turn, is stored at the mesh's points (a fold or two loops touching is the
    /// arcs', not only the junctions').
    fn next(self) -> Option<Fidelity> {
        match self {
            Fidelity::Smoothed | Fidelity::Junctions => Some(Fidelity::MeshPoints),
            Fidelity::MeshPoints => Some(Fidelity::Exact),
            Fidelity::Exact => None,
        }
    }
}

/// Raises each of `regions`' fidelity one step ([`Fidelity::next`]); whether any was raised.
fn raise_fidelity(fidelity: &mut [Fidelity], regions: impl IntoIterator<Item = u32>) -> bool {
    let mut raised = false;
    for r in regions {
        if let Some(f) = fidelity.get_mut(r as usize) {
            if let Some(next) = f.next() {
                *f = next;
                raised = true;
            }
        }
    }
    raised
}

/// Grid resolutions the automatic choice tries. Coarser grids give smaller files still (9
/// bits: hand at K = 18 in 1 982 bytes instead of 2 047) but their rounding noise, up to
/// half the default tolerance, folds decoded boundaries: the torus fixture decoded with 58
/// flipped triangles at 9 bits and none at 10, and 4 of 13 real meshes failed to decode
/// instead of 3 (spec/ELLIP.md, appendix B).
pub const AUTO_BITS: std::ops::RangeInclusive<u8> = 10..=16;

/// One way of storing a representation.
struct Stored {
    bytes: Vec<u8>,
    representation: Representation,
    removed_points: usize,
    bits: u8,
}

impl Stored {
    /// Names the treatment the file meshes clean with in its metadata (a remesh hint,
    /// spec §6.1) and writes it again: only `META` changes.
    fn hint(&mut self, treatment: Treatment) -> Result<(), EncodeMeshError> {
        self.representation.metadata.remesh_hint = Some(treatment.code());
        self.bytes = format::encode(&self.representation, &EncodeOptions { bits: self.bits })?;
        Ok(())
    }
}

/// Simplifies the arcs (but those marked in `exact`) with what the grid of `bits` leaves of
/// the boundary tolerance (`absolute_tolerance`, model units; 0: no simplification) and
/// writes the file.
fn store(
    representation: &Representation,
    absolute_tolerance: f64,
    bits: u8,
    exact: &[bool],
    specks: &[bool],
) -> Result<Stored, EncodeMeshError> {
    let mut representation = representation.clone();
    // The boundary tolerance bounds a stored point's whole error: Douglas–Peucker gets what
    // the grid's rounding leaves (the grid over all points is at least as coarse as the one
    // over the points simplification keeps).
    let grid_error = format::Grid::around(&representation.points, bits).error_bound();
    let simplify_tolerance = absolute_tolerance - grid_error;
    if absolute_tolerance > 0.0 && simplify_tolerance <= 0.0 {
        return Err(EncodeMeshError::InvalidOption {
            what: "bits",
            value: format!(
                "{bits}: the grid alone moves points by up to {grid_error:.3e}, more than the \
                 boundary tolerance {absolute_tolerance:.3e}; use more bits or a larger tolerance"
            ),
        });
    }
    let removed_points = if absolute_tolerance > 0.0 {
        representation.metadata.simplify_tolerance = Some(simplify_tolerance);
        representation.simplify_arcs_except(simplify_tolerance, exact)
    } else {
        0
    };
    let options = EncodeOptions { bits };
    let mut bytes = format::encode(&representation, &options)?;
    let turned = if specks.contains(&true) {
        turned_specks(&format::decode(&bytes, &format::Limits::default())?, specks)
    } else {
        Vec::new()
    };
    if !turned.is_empty() {
        for r in turned {
            if let Some(e) = representation.ellipsoids.get_mut(r) {
                *e = e.flipped();
            }
        }
        bytes = format::encode(&representation, &options)?;
    }
    Ok(Stored {
        bytes,
        representation,
        removed_points,
        bits,
    })
}

/// The specks (`specks[r]`: region r is one, see [`speck_faces`]) whose boundary, as
/// `stored` holds it, winds against their ellipsoid: its area vector (Newell's, over all
/// its loops) points against the ellipsoid's signed normal at the loops' centroid.
///
/// A speck is stored as the mesh has it and fitted with a sphere tangent to it on the side
/// its faces face, so it decodes as its own triangles; but a sliver no higher than a step of
/// the point grid can come out of the grid wound the other way, and then it decodes turned
/// against its sphere. Such a speck's sphere is stored with the other sign ([`store`]): the
/// same surface, its normal the other way. Stanford's dragon from npm at `res3`, whose pairs
/// of triangles on the same three points wound either way are such slivers, decoded with
/// 5 flipped triangles instead of 11 (the encoder's file at its default K).
fn turned_specks(stored: &Representation, specks: &[bool]) -> Vec<usize> {
    let mut turned = Vec::new();
    for (r, cycles) in stored.cycles.iter().enumerate() {
        let (Some(true), Some(e)) = (specks.get(r).copied(), stored.ellipsoids.get(r)) else {
            continue;
        };
        let mut area = DVec3::ZERO;
        let mut sum = DVec3::ZERO;
        let mut count = 0usize;
        for cycle in cycles {
            let mut points: Vec<DVec3> = Vec::new();
            for a in &cycle.arcs {
                let Some(mut arc) = stored.arc_positions(a.arc as usize) else {
                    continue;
                };
                if a.reversed {
                    arc.reverse();
                }
                // Consecutive arcs share their junctions (a closed arc repeats none).
                let closed = stored.arcs.get(a.arc as usize).is_some_and(|a| a.closed);
                points.extend(arc.into_iter().skip(usize::from(!closed)));
            }
            for (k, &p) in points.iter().enumerate() {
                area += p.cross(points[(k + 1) % points.len()]);
            }
            sum += points.iter().sum::<DVec3>();
            count += points.len();
        }
        if count > 0 && e.normal_side().along(sum / count as f64, area) < 0.0 {
            turned.push(r);
        }
    }
    turned
}

// ---------------------------------------------------------------------------------------
// What an encoding loses, and rate control (issue "measure and show").

/// What decoding a `.ellip` file loses against its source mesh: symmetric figures from
/// [`crate::compare::compare_meshes`] (area-uniform samples on both meshes, exact closest
/// points), the decoded mesh remeshed at the file's suggested density (the source's vertex
/// count).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// Symmetric RMS distance, model units.
    pub rms: f64,
    /// Symmetric Hausdorff distance, model units.
    pub hausdorff: f64,
    /// Mean normal deviation, degrees.
    pub normal_deviation: f64,
    /// The source's bounding-box diagonal, the scale of relative figures.
    pub diagonal: f64,
}

/// Decodes `bytes`, remeshes them and compares the result with `mesh`, the comparison's
/// parallel steps run by `threads` workers (`None`: all cores; [`SegmentOptions::threads`]).
pub fn measure_encoding(
    mesh: &Mesh,
    bytes: &[u8],
    threads: Option<usize>,
) -> Result<Measured, EncodeMeshError> {
    let representation = format::decode(bytes, &format::Limits::default())?;
    let decoded = crate::remesh::remesh(&representation, &crate::remesh::RemeshOptions::default())?;
    let c = Exec::new(threads)?.install(|| {
        crate::compare::compare_meshes(
            mesh,
            &decoded.mesh,
            &crate::compare::CompareOptions::default(),
        )
    })?;
    Ok(Measured {
        rms: c.symmetric.distances.rms,
        hausdorff: c.symmetric.distances.hausdorff,
        normal_deviation: c.symmetric.normal_deviation,
        diagonal: c.diagonal,
    })
}

/// The file of `encoded` with `measured` stored in its metadata (`META` measured_error and
/// measured_hausdorff), which `ellip info` shows.
pub fn store_measurement(
    encoded: &Encoded,
    measured: &Measured,
) -> Result<Vec<u8>, EncodeMeshError> {
    let mut representation = encoded.representation.clone();
    representation.metadata.measured_error = Some(measured.rms);
    representation.metadata.measured_hausdorff = Some(measured.hausdorff);
    Ok(format::encode(
        &representation,
        &EncodeOptions { bits: encoded.bits },
    )?)
}

/// What rate control aims at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// The smallest file whose measured RMS error is at most this fraction of the
    /// bounding-box diagonal.
    Rms(f64),
    /// The lowest measured RMS error in at most this many bytes (measurement included).
    MaxBytes(usize),
}

impl Target {
    /// Whether `probe` meets the target.
    fn is_met_by(&self, probe: &Probe) -> bool {
        match *self {
            Target::Rms(t) => probe.rms <= t,
            Target::MaxBytes(n) => probe.bytes <= n,
        }
    }

    /// How `a` compares with `b` for the target, lesser better: the smaller file (then the
    /// lower error) for an RMS target, the lower error (then the smaller file) for a budget.
    fn rank(&self, a: &Probe, b: &Probe) -> Ordering {
        match self {
            Target::Rms(_) => a.bytes.cmp(&b.bytes).then(a.rms.total_cmp(&b.rms)),
            Target::MaxBytes(_) => a.rms.total_cmp(&b.rms).then(a.bytes.cmp(&b.bytes)),
        }
    }
}

/// The probe [`encode_to_target`] keeps, if any meets the target: one that decodes clean
/// before one that does not (a mesh with turned triangles or an open seam is no smaller or
/// closer in any way that matters), then the best for the target ([`Target::rank`]), then
/// the earliest.
fn chosen_probe(probes: &[Probe], target: Target) -> Option<usize> {
    (0..probes.len())
        .filter(|&i| target.is_met_by(&probes[i]))
        .min_by(|&i, &j| {
            let (a, b) = (&probes[i], &probes[j]);
            b.clean.cmp(&a.clean).then(target.rank(a, b))
        })
}

/// The probe whose setting [`encode_to_target`] searches again ([`encode_mesh`]'s searches
/// for a file that does not decode clean): the best that meets the
/// target, cleanliness aside, when it does not decode clean. Before the probes were
/// searched with area weighting too, it mended the horse in 1 500 bytes: K = 6, 1.50 % and
/// not manifold, became a clean file at 1.16 % in 1 219 bytes. For an RMS target the count
/// is raised too: the duck within 0.5 % (K = 48 at 4× the boundary tolerance, 3 flipped
/// triangles in 2 511 bytes, which the searches at K = 48 do not mend) is clean raised to
/// K = 108, 103 regions in 5 150 bytes.
fn probe_to_search_again(probes: &[Probe], target: Target) -> Option<usize> {
    (0..probes.len())
        .filter(|&i| target.is_met_by(&probes[i]))
        .min_by(|&i, &j| target.rank(&probes[i], &probes[j]))
        .filter(|&i| !probes[i].clean)
}

/// What [`encode_to_target`] made at one setting: the file at it and, when that did not
/// decode clean, the area-weighted search's; the better of them measured.
#[derive(Clone)]
struct Probed {
    probe: Probe,
    plain: Checked,
    weighted: Option<Checked>,
    kept: RateControlled,
}

/// One setting rate control tried.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// Regions.
    pub regions: usize,
    /// Boundary tolerance, as a fraction of the diagonal.
    pub boundary_tolerance: f64,
    /// File size with the measurement stored.
    pub bytes: usize,
    /// Measured RMS error as a fraction of the diagonal.
    pub rms: f64,
    /// Whether the file decodes clean (or was not checked: `EncodeSettings::verify` off).
    pub clean: bool,
    /// Whether this is the file [`encode_mesh`]'s further searches made at the setting of
    /// an earlier probe that did not decode clean (see [`encode_to_target`]).
    pub searched_again: bool,
}

/// The result of rate control.
#[derive(Debug, Clone)]
pub struct RateControlled {
    /// The chosen encoding (its `bytes` without the measurement).
    pub encoded: Encoded,
    /// Its measurement.
    pub measured: Measured,
    /// The file, with the measurement stored.
    pub bytes: Vec<u8>,
    /// Every setting tried, in order.
    pub probes: Vec<Probe>,
}

/// Most regions rate control tries (beyond one for each further connected component).
pub const MAX_RATE_REGIONS: usize = 256;

/// Encodes `mesh` to meet `target`, searching the region count K (the setting that moves
/// size and error most) and then the boundary tolerance.
///
/// Strategy: K = 4, 8, 16, … (from the mesh's component count when it has more pieces)
/// doubling until the target's side flips (the error drops under
/// the RMS target, or the file no longer fits the byte budget), then bisection between the
/// last two K; every probe is a full encode, decode and measurement, so the cost is about
/// 2·log₂ K probes. The K where the side flips is then tried with boundary tolerances 2×
/// and 4× the one in `settings` (4× and 16× when even the fewest regions miss a budget):
/// for an RMS target the smallest file still within it is kept, for a budget the lowest
/// error that fits, which is often that K with coarser boundaries rather than fewer
/// regions (the decoder check's mending makes bytes jump between neighbouring K: CGAL's
/// elephant at 1 500 bytes had K = 3, 6 regions, 758 bytes). Error falls and
/// size grows with K only roughly: the search returns the best probe that meets the target
/// (smallest file, or lowest error within the budget), never one that misses it, and one
/// that decodes clean before one that does not. When the best probe that meets the target
/// does not decode clean, its setting gets the further searches [`encode_mesh`] makes for
/// such a file (the count raised only for an RMS target: more regions make a larger
/// file), and their file is one more probe ([`Probe::searched_again`]).
/// `settings.segment.regions` is ignored; `report` hears of each probe.
pub fn encode_to_target(
    mesh: &Mesh,
    settings: &EncodeSettings,
    target: Target,
    report: &mut dyn FnMut(&Probe),
) -> Result<RateControlled, EncodeMeshError> {
    match target {
        Target::Rms(t) if !(t.is_finite() && t > 0.0) => {
            return Err(EncodeMeshError::InvalidOption {
                what: "RMS target",
                value: t.to_string(),
            })
        }
        Target::MaxBytes(0) => {
            return Err(EncodeMeshError::InvalidOption {
                what: "byte budget",
                value: "0".into(),
            })
        }
        _ => {}
    }
    // Every connected component needs a region of its own; the search spends up to
    // MAX_RATE_REGIONS beyond one for each further component.
    let min_k = mesh.topology().component_count().max(1);
    let max_k = (min_k - 1 + MAX_RATE_REGIONS).min(mesh.face_count().max(1));
    let mut tried: Vec<Probed> = Vec::new();
    let settings_at = |k: usize, tolerance: f64| EncodeSettings {
        segment: SegmentOptions {
            regions: RegionCount::Fixed(k),
            ..settings.segment.clone()
        },
        simplify_tolerance: tolerance,
        ..settings.clone()
    };
    // A probe of the better of `plain` and `weighted`, the files made at (k, tolerance):
    // measured and reported.
    let mut measure = |k: usize,
                       tolerance: f64,
                       plain: Checked,
                       weighted: Option<Checked>,
                       searched_again: bool,
                       tried: &mut Vec<Probed>| {
        let kept = match &weighted {
            Some(w) if w.score < plain.score => w,
            _ => &plain,
        };
        let measured = measure_encoding(mesh, &kept.encoded.bytes, settings.segment.threads)?;
        let bytes = store_measurement(&kept.encoded, &measured)?;
        let p = Probe {
            regions: k,
            boundary_tolerance: tolerance,
            bytes: bytes.len(),
            rms: measured.rms / measured.diagonal.max(f64::MIN_POSITIVE),
            clean: kept.score.0 == CLEAN,
            searched_again,
        };
        report(&p);
        let kept = RateControlled {
            encoded: kept.encoded.clone(),
            measured,
            bytes,
            probes: Vec::new(),
        };
        tried.push(Probed {
            probe: p,
            plain,
            weighted,
            kept,
        });
        Ok::<Probe, EncodeMeshError>(p)
    };
    // Each probe is a file at (k, tolerance) and, when it does not decode clean, the first
    // of encode_mesh's searches, with each face's error weighted by its area: without it
    // the search saw the duck at K = 64 decode 338 % of the diagonal off its source
    // (regions far off; weighted, 0.22 %), and the horse within 0.5 % ended at K = 176
    // with 9 799 bytes that did not decode clean (now 3 357 bytes, clean).
    let mut probe = |k: usize, tolerance: f64, tried: &mut Vec<Probed>| {
        if let Some(known) = tried
            .iter()
            .find(|t| t.probe.regions == k && t.probe.boundary_tolerance == tolerance)
        {
            return Ok::<Probe, EncodeMeshError>(known.probe);
        }
        // The search chooses the region count itself: no raising.
        let at = settings_at(k, tolerance);
        let plain = encode_checked(mesh, &at, MAX_SPLIT_ROUNDS, Fidelity::Smoothed, &mut |_| {})?;
        let weighted = match area_weighted(&at) {
            Some(weighted) if at.verify && plain.score.0 != CLEAN => search_again(
                mesh,
                &at,
                &weighted,
                MAX_REWEIGHTED_ROUNDS,
                Fidelity::Smoothed,
                &mut |_| {},
            ),
            _ => None,
        };
        measure(k, tolerance, plain, weighted, false, tried)
    };
    let meets = |p: &Probe| target.is_met_by(p);
    // For an RMS target, "on the far side" is meeting it; for a budget, missing it.
    let beyond = |p: &Probe| match target {
        Target::Rms(_) => meets(p),
        Target::MaxBytes(_) => !meets(p),
    };
    let tolerance = settings.simplify_tolerance;
    let mut below = 0usize; // the largest K known to be on the near side (0: none)
    let mut above = None; // the smallest K known to be beyond
    let mut k = 4.max(min_k).min(max_k);
    loop {
        let p = probe(k, tolerance, &mut tried)?;
        if beyond(&p) {
            above = Some(k);
            break;
        }
        below = k;
        if k == max_k {
            break;
        }
        k = (2 * k).min(max_k);
    }
    if let Some(mut hi) = above {
        let mut lo = (below + 1).max(min_k);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if beyond(&probe(mid, tolerance, &mut tried)?) {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        // The K at the flip with coarser boundaries: for an RMS target a smaller file that
        // may still meet it; for a budget, more regions that may fit (or, when even the
        // fewest regions do not, the only way to fit).
        let factors = match target {
            Target::MaxBytes(_) if hi == min_k => [4.0, 16.0],
            _ => [2.0, 4.0],
        };
        for factor in factors {
            probe(hi, tolerance * factor, &mut tried)?;
        }
    }
    // When the best probe that meets the target does not decode clean, its setting gets
    // the searches encode_mesh makes for such a file, and that file is measured like a
    // probe.
    let probes: Vec<Probe> = tried.iter().map(|t| t.probe).collect();
    if let Some(i) = probe_to_search_again(&probes, target) {
        let Probed {
            probe: p,
            plain,
            weighted,
            ..
        } = tried[i].clone();
        let at = settings_at(p.regions, p.boundary_tolerance);
        // For an error target the count is raised too: more regions lower the error, and
        // the file is measured like any probe.
        let raise = matches!(target, Target::Rms(_));
        let searched = search_for_clean(mesh, &at, plain, weighted, raise, &mut |_| {})?;
        measure(
            p.regions,
            p.boundary_tolerance,
            searched,
            None,
            true,
            &mut tried,
        )?;
    }
    let probes: Vec<Probe> = tried.iter().map(|t| t.probe).collect();
    let best = chosen_probe(&probes, target).map(|i| {
        let t = tried.swap_remove(i);
        (t.probe, t.kept)
    });
    match best {
        Some((_, mut chosen)) => {
            chosen.probes = probes;
            Ok(chosen)
        }
        None => {
            let closest = probes
                .iter()
                .map(|p| {
                    format!(
                        "K={} {} bytes RMS {:.4}%",
                        p.regions,
                        p.bytes,
                        100.0 * p.rms
                    )
                })
                .collect::<Vec<_>>()
                .join("; ");
            Err(EncodeMeshError::Unreachable(match target {
                Target::Rms(t) => format!(
                    "no setting tried reaches an RMS error of {:.4}% of the diagonal (tried: {closest})",
                    100.0 * t
                ),
                Target::MaxBytes(n) => {
                    format!("no setting tried fits in {n} bytes (tried: {closest})")
                }
            }))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `threads` bounds the decoder check's parallel steps as it bounds the segmentation's:
    /// they run in a pool of that many workers, not in rayon's global pool of every core.
    #[test]
    fn the_check_runs_on_as_many_threads_as_asked() {
        let mesh = crate::synth::shapes::icosphere(1.0, 1);
        for threads in [1, 3] {
            let source = Source::with_threads(&mesh, Some(threads)).unwrap();
            assert_eq!(source.exec.install(rayon::current_num_threads), threads);
        }
        let all = Source::with_threads(&mesh, None).unwrap();
        assert_eq!(
            all.exec.install(rayon::current_num_threads),
            rayon::current_num_threads()
        );
    }

    /// A region that closes on itself (every boundary edge a seam: a torus cut along a
    /// meridian by fins on its edges, one region for the tube, as in `tests/remesh.rs`) is
    /// blamed when the file does not decode, as one that storing its boundary more
    /// faithfully (mending's first step for such a file) cannot mend: mending cuts it in its
    /// first round. The cut torus took 13 rounds to a clean file before, 11 now.
    #[test]
    fn a_region_that_closes_on_itself_is_blamed_to_be_cut() {
        let (major, meridian) = (2.0, 12u32);
        let torus = crate::synth::shapes::torus(major, 0.6, 24, meridian);
        let mut positions = torus.positions().to_vec();
        let mut faces = torus.faces().to_vec();
        for j in 0..meridian {
            let (a, b) = (j, (j + 1) % meridian);
            let middle = 0.5 * (positions[a as usize] + positions[b as usize]);
            let out = (middle - DVec3::new(major, 0.0, 0.0)).normalize();
            positions.push(middle + 0.3 * out);
            faces.push([a, b, positions.len() as u32 - 1]);
        }
        let mesh = Mesh::new(positions, faces).unwrap();
        let pieces = mesh.topology().component_count();
        let settings = EncodeSettings {
            segment: SegmentOptions {
                regions: RegionCount::Fixed(pieces),
                ..SegmentOptions::default()
            },
            ..EncodeSettings::default()
        };
        let round_0 = encode_checked(&mesh, &settings, 0, Fidelity::Smoothed, &mut |_| {}).unwrap();
        let labels = &round_0.encoded.segmentation.labels;
        let (verdict, _) = verify(&round_0.encoded.bytes, &Source::new(&mesh), labels).unwrap();
        // The tube: the region with the most faces.
        let mut counts = vec![0usize; pieces];
        for &r in labels {
            counts[r as usize] += 1;
        }
        let tube = (0..pieces as u32)
            .max_by_key(|&r| counts[r as usize])
            .unwrap();
        assert_eq!(verdict.closed_on_themselves(), [tube]);
        let (blamed, problem) = verdict.blamed_and_problem();
        assert!(blamed.iter().any(|s| s.region == tube), "{blamed:?}");
        assert!(problem.is_some_and(|p| p.contains("seam")));
    }

    /// The last resort of the decoder check ([`store_blamed_faithfully`]): teddy at K = 12,
    /// with no round of mending allowed, is written with its boundaries smoothed, and that
    /// file decodes with a flipped triangle; with the blamed region's boundaries at the
    /// mesh's points, the same segmentation decodes clean, and that file is kept. Skipped
    /// without `../shared/meshes`.
    #[test]
    fn a_file_no_round_mends_is_stored_again_with_its_blamed_boundaries_faithful() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes/teddy.obj");
        if !path.is_file() {
            println!("skipped: {} is absent", path.display());
            return;
        }
        let mesh = crate::import::read_mesh(&path, &Default::default())
            .unwrap()
            .mesh;
        let settings = EncodeSettings {
            segment: SegmentOptions {
                regions: RegionCount::Fixed(12),
                ..SegmentOptions::default()
            },
            ..EncodeSettings::default()
        };
        // Round 0's file, smoothed boundaries, no mending: it decodes with faults.
        let round_0 = encode_checked(&mesh, &settings, 0, Fidelity::Smoothed, &mut |_| {}).unwrap();
        assert_eq!(round_0.score.0, DIRTY, "round 0: {:?}", round_0.score);
        assert!(round_0.score.1.bad_triangles > 0);
        assert!(!round_0.blamed.is_empty());
        // Its problem says where the faulty triangles are, as `ellip decode` does.
        let problem = round_0
            .encoded
            .verification
            .problem
            .clone()
            .unwrap_or_default();
        let rep = format::decode(&round_0.encoded.bytes, &format::Limits::default()).unwrap();
        let options = crate::remesh::RemeshOptions {
            leave_out: false,
            ..Default::default()
        };
        let out = crate::remesh::remesh(&rep, &options).unwrap();
        let note = crate::remesh::assemble::triangle_faults_note(
            &crate::remesh::assemble::triangle_faults_by_region(&rep, &out.mesh, &out.face_regions),
        );
        assert!(note.starts_with("; by region: "), "{note}");
        assert_eq!(
            problem,
            format!("decodes with {}{note}", out.check.faults())
        );
        let round_0_bytes = round_0.encoded.bytes.clone();
        let labels = round_0.encoded.segmentation.labels.clone();
        let kept = store_blamed_faithfully(&mesh, &settings, vec![round_0])
            .unwrap()
            .encoded;
        assert_eq!(kept.segmentation.labels, labels);
        assert_eq!(kept.verification.problem, None);
        assert_eq!(kept.verification.rounds, 1, "clean at the first step");
        assert_ne!(kept.bytes, round_0_bytes);
        let (verdict, _) = verify(&kept.bytes, &Source::new(&mesh), &labels).unwrap();
        assert_eq!(verdict.score().0, CLEAN);
    }

    /// The decoder check's test for surface made up or left out in decoding, on a unit
    /// sphere fitted exactly: a decoded region meshed on the whole sphere where the source
    /// is a hemisphere, or on a hemisphere where the source is the whole sphere, departs
    /// from the source by about √2 (the pole to the equator, less the faces' size: the
    /// centroid nearest the pole is not at it), far beyond a tenth of the diagonal; the
    /// same decoded mesh as the source departs by nothing; and a region whose ellipsoid is
    /// far from its faces is not blamed for what the fit missed.
    #[test]
    fn regions_decoded_off_the_source_are_found() {
        use crate::synth::shapes::{hemisphere, icosphere};
        let sphere = icosphere(1.0, 3);
        let cap = hemisphere(1.0, 3);
        let unit = [Ellipsoid::sphere(DVec3::ZERO, 1.0)];
        let all = |m: &Mesh| vec![0u32; m.face_count()];
        // Made up: the whole sphere decoded for a hemisphere.
        let far = Source::new(&cap).far_regions(&sphere, &all(&sphere), &unit, &all(&cap));
        assert_eq!(far.len(), 1);
        assert!((1.3..1.42).contains(&far[0].1), "{far:?}");
        // Left out: a hemisphere decoded for the whole sphere.
        let far = Source::new(&sphere).far_regions(&cap, &all(&cap), &unit, &all(&sphere));
        assert_eq!(far.len(), 1);
        assert!((1.3..1.42).contains(&far[0].1), "{far:?}");
        // Faithful.
        let far = Source::new(&sphere).far_regions(&sphere, &all(&sphere), &unit, &all(&sphere));
        assert!(far.is_empty(), "{far:?}");
        // The fit's own error: a sphere of radius 0.2 for the unit sphere's faces, decoded
        // as itself, lies 0.8 from them, as far as its ellipsoid does: not blamed.
        let small = icosphere(0.2, 3);
        let fit = [Ellipsoid::sphere(DVec3::ZERO, 0.2)];
        let source = Source::new(&sphere);
        let far = source.far_regions(&small, &all(&small), &fit, &all(&sphere));
        assert!(far.is_empty(), "{far:?}");
        // The same decoded mesh for the unit sphere fitted exactly lies 0.8 off it: blamed
        // both ways (0.8 > 0.1 × the diagonal, 3.46).
        let far = source.far_regions(&small, &all(&small), &unit, &all(&sphere));
        assert_eq!(far.len(), 1, "{far:?}");
        assert!((far[0].1 - 0.8).abs() < 0.02, "{far:?}");
    }

    /// Surface made up in bulk: a region decoded a little off its source everywhere,
    /// nowhere past [`MAX_DEPARTURE`], is found when its RMS distance from the source passes
    /// its ellipsoid's by [`MAX_RMS_DEPARTURE`] of the diagonal, with that excess; not when
    /// it stays within half of it, nor for what the fit itself missed.
    #[test]
    fn regions_decoded_off_the_source_in_bulk_are_found() {
        use crate::synth::shapes::icosphere;
        let sphere = icosphere(1.0, 3);
        let source = Source::new(&sphere);
        let all = |m: &Mesh| vec![0u32; m.face_count()];
        let unit = [Ellipsoid::sphere(DVec3::ZERO, 1.0)];
        let limit = MAX_RMS_DEPARTURE * source.diagonal;
        for (off, found) in [(1.5 * limit, true), (0.5 * limit, false)] {
            assert!(off < MAX_DEPARTURE * source.diagonal);
            let decoded = icosphere(1.0 + off, 3);
            let far = source.far_regions(&decoded, &all(&decoded), &unit, &all(&sphere));
            if found {
                assert_eq!(far.len(), 1, "{far:?}");
                // The faces' centroids lie a little inside both spheres.
                assert!((far[0].1 - off).abs() < 0.1 * off, "{far:?} {off}");
            } else {
                assert!(far.is_empty(), "{far:?}");
            }
        }
        // Fitted with the larger sphere and decoded as it, the region lies as far from its
        // faces as its ellipsoid does.
        let radius = 1.0 + 1.5 * limit;
        let decoded = icosphere(radius, 3);
        let fit = [Ellipsoid::sphere(DVec3::ZERO, radius)];
        let far = source.far_regions(&decoded, &all(&decoded), &fit, &all(&sphere));
        assert!(far.is_empty(), "{far:?}");
    }

    /// A region the decoder left without a face is lost when its faces lie more than
    /// [`MAX_LOST`] of the diagonal from the decoded mesh and it holds at least
    /// [`MIN_LOST_AREA`] of the source's area, fitted exactly or not: a small sphere beside
    /// the unit sphere (a limb whose rings tapered to a point), missing from a decoded mesh
    /// that is the unit sphere alone, is found with its farthest face's distance; not when
    /// it is decoded; not a cap of the unit sphere's own faces, which the rest closes over
    /// (a region a few grid steps across whose loop quantisation merged); not a speck of a
    /// ten-thousandth of the area, however far.
    #[test]
    fn regions_missing_from_the_decoded_mesh_are_found() {
        use crate::synth::shapes::icosphere;
        let unit = icosphere(1.0, 3);
        let on_unit = vec![0u32; unit.face_count()];
        let sphere_at = |c: DVec3, r: f64| Ellipsoid::sphere(c, r);
        // The unit sphere (region 0) and a sphere of radius `r` centred at `c` (region 1).
        let with_small = |c: DVec3, r: f64| {
            let (mut positions, mut faces) = unit.clone().into_parts();
            let (small_positions, small_faces) = icosphere(r, 2).into_parts();
            let n = positions.len() as u32;
            positions.extend(small_positions.iter().map(|&p| p + c));
            faces.extend(small_faces.iter().map(|f| f.map(|v| v + n)));
            let labels: Vec<u32> = (0..faces.len())
                .map(|f| u32::from(f >= unit.face_count()))
                .collect();
            (Mesh::new(positions, faces).unwrap(), labels)
        };
        // A sphere of radius 0.05 whose nearest point is 0.05 from the unit sphere (0.25 %
        // of the area): its faces lie up to 0.15 from it, over a hundredth of the diagonal
        // (3.53) and under a tenth (what a region meshed off the source must depart by).
        let centre = DVec3::new(1.1, 0.0, 0.0);
        let (source, labels) = with_small(centre, 0.05);
        let fits = [sphere_at(DVec3::ZERO, 1.0), sphere_at(centre, 0.05)];
        let far = Source::new(&source).far_regions(&unit, &on_unit, &fits, &labels);
        assert_eq!(far.len(), 1, "{far:?}");
        assert_eq!(far[0].0, 1);
        assert!((0.13..0.151).contains(&far[0].1), "{far:?}");
        // Its fit is no excuse: the region is missing, not meshed where its ellipsoid is.
        let loose = [fits[0], sphere_at(centre, 0.6)];
        let far = Source::new(&source).far_regions(&unit, &on_unit, &loose, &labels);
        assert_eq!(far.iter().map(|f| f.0).collect::<Vec<_>>(), [1], "{far:?}");
        // Decoded (the source itself), it is not missing.
        let far = Source::new(&source).far_regions(&source, &labels, &fits, &labels);
        assert!(far.is_empty(), "{far:?}");
        // A cap of the unit sphere's faces as region 1 (a tenth of the area), decoded as
        // part of region 0: on the decoded mesh, not lost.
        let cap: Vec<u32> = (0..unit.face_count())
            .map(|f| u32::from(unit.face_centroid(f).x > 0.8))
            .collect();
        assert!(cap.iter().filter(|&&r| r == 1).count() * 20 > unit.face_count());
        let far = Source::new(&unit).far_regions(&unit, &on_unit, &fits, &cap);
        assert!(far.is_empty(), "{far:?}");
        // A sphere of radius 0.01 (a ten-thousandth of the area) as far off: a speck.
        let speck = DVec3::new(1.06, 0.0, 0.0);
        let (source, labels) = with_small(speck, 0.01);
        let fits = [fits[0], sphere_at(speck, 0.01)];
        let far = Source::new(&source).far_regions(&unit, &on_unit, &fits, &labels);
        assert!(far.is_empty(), "{far:?}");
    }

    /// A closed piece covered by one region is decoded as its whole ellipsoid: one that
    /// reaches far beyond the piece is found before decoding; one that fits, or one with a
    /// boundary (decoded only inside it), is not.
    #[test]
    fn whole_regions_far_beyond_their_piece_are_found() {
        use crate::representation::Cycle;
        use crate::synth::shapes::icosphere;
        let sphere = icosphere(1.0, 3);
        let source = Source::new(&sphere);
        let labels = vec![0u32; sphere.face_count()];
        let whole = |e: Ellipsoid, cycles: Vec<Vec<Cycle>>| Representation {
            ellipsoids: vec![e],
            points: Vec::new(),
            arcs: Vec::new(),
            cycles,
            metadata: Metadata::default(),
        };
        let fitted = whole(Ellipsoid::sphere(DVec3::ZERO, 1.0), vec![Vec::new()]);
        assert!(source.far_whole_regions(&fitted, &labels).is_empty());
        // A flat fit of a thousand diagonals (as a flat piece gets).
        let flat = Ellipsoid {
            radii: DVec3::new(3464.0, 3464.0, 1.0),
            ..Ellipsoid::sphere(DVec3::ZERO, 1.0)
        };
        let far = source.far_whole_regions(&whole(flat, vec![Vec::new()]), &labels);
        assert_eq!(far.len(), 1, "{far:?}");
        assert!((far[0].1 - 3463.0).abs() < 1.0, "{far:?}");
        // The same ellipsoid with a boundary is meshed only inside it: not this check's.
        let bounded = whole(
            flat,
            vec![vec![Cycle {
                arcs: Vec::new(),
                outer: true,
            }]],
        );
        assert!(source.far_whole_regions(&bounded, &labels).is_empty());
        // A sphere 1.5 times the piece: 0.5 beyond it, over 0.1 of the diagonal (3.46).
        let larger = whole(Ellipsoid::sphere(DVec3::ZERO, 1.5), vec![Vec::new()]);
        let far = source.far_whole_regions(&larger, &labels);
        assert_eq!(far.len(), 1, "{far:?}");
        assert!((far[0].1 - 0.5).abs() < 1e-3, "{far:?}");
    }

    /// A decoded mesh in more pieces than its source: the regions of the smallest pieces
    /// beyond the source's count are blamed, whichever order the pieces come in.
    #[test]
    fn pieces_beyond_the_source_s_are_found() {
        use crate::remesh::assemble::MeshCheck;
        use crate::synth::shapes::icosphere;
        let sphere = icosphere(1.0, 2);
        let decoded = |pillow_first: bool| {
            let (mut positions, mut faces) = sphere.clone().into_parts();
            let mut regions = vec![0u32; faces.len()];
            // Two triangles back to back on three new points, in regions 3 and 5.
            let n = positions.len() as u32;
            positions.extend([
                DVec3::splat(3.0),
                DVec3::new(3.1, 3.0, 3.0),
                DVec3::new(3.0, 3.1, 3.0),
            ]);
            let pillow = [[n, n + 1, n + 2], [n, n + 2, n + 1]];
            if pillow_first {
                faces.splice(0..0, pillow);
                regions.splice(0..0, [3, 5]);
            } else {
                faces.extend(pillow);
                regions.extend([3, 5]);
            }
            Remeshed {
                mesh: Mesh::new(positions, faces).unwrap(),
                normals: Vec::new(),
                face_regions: regions,
                check: MeshCheck::default(),
                omitted: Vec::new(),
                attempts: 1,
                treatment: None,
            }
        };
        let source = Source::new(&sphere);
        for pillow_first in [false, true] {
            let out = decoded(pillow_first);
            assert_eq!(out.mesh.topology().component_count(), 2);
            assert_eq!(source.extra_pieces(&out), Some((vec![3, 5], 2)));
        }
        // A source in two pieces allows two.
        let two = decoded(false).mesh;
        assert_eq!(Source::new(&two).extra_pieces(&decoded(true)), None);
    }

    /// The decoder check's fallbacks for a region it cannot chart: its arcs at the mesh's
    /// own points (simplified), then every one of them; the other arcs stay smoothed.
    #[test]
    fn boundaries_are_stored_as_faithfully_as_their_regions_ask() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/meshes/blob3.obj");
        let mesh = crate::import::read_mesh(&path, &crate::import::ImportOptions::default())
            .unwrap()
            .mesh;
        let settings = EncodeSettings {
            segment: crate::segment::SegmentOptions {
                regions: crate::segment::RegionCount::Fixed(8),
                max_iterations: 10,
                ..Default::default()
            },
            verify: false,
            ..EncodeSettings::default()
        };
        let metric = EllipsoidMetric::new(&mesh, &settings.segment).unwrap();
        let seg = segment_with(&mesh, &metric, &settings.segment, &mut |_| {}).unwrap();
        let graph = extract_boundaries(&mesh, &seg.labels, seg.region_count()).unwrap();
        // A region with junctions.
        let chosen = graph
            .arcs
            .iter()
            .find(|a| !a.closed)
            .map(|a| a.left)
            .unwrap();
        let touches = |left: u32, right: Option<u32>| left == chosen || right == Some(chosen);
        // Stored points on arcs of the chosen region, and on the others, by how far they lie
        // from the nearest mesh vertex of those arcs.
        let mesh_points: Vec<DVec3> = graph
            .arcs
            .iter()
            .filter(|a| touches(a.left, a.right.region()))
            .flat_map(|a| a.vertices.iter().map(|&v| mesh.positions()[v as usize]))
            .collect();
        let stored = |f: Fidelity| {
            let mut fidelity = vec![Fidelity::Smoothed; seg.region_count()];
            fidelity[chosen as usize] = f;
            represent(&mesh, &seg, &settings, &fidelity)
                .unwrap()
                .0
                .representation
        };
        let grid = |rep: &Representation| format::Grid::around(&rep.points, 16).error_bound();
        let arcs_of = |rep: &Representation| -> (Vec<u32>, usize) {
            let mut points = Vec::new();
            let mut count = 0;
            for a in &rep.arcs {
                if touches(a.left, a.right.region()) {
                    points.extend(a.points.iter().copied());
                    count += a.points.len();
                }
            }
            (points, count)
        };
        let nearest = |p: DVec3| {
            mesh_points
                .iter()
                .map(|q| q.distance(p))
                .fold(f64::INFINITY, f64::min)
        };
        let diagonal = mesh.bounding_box().unwrap().diagonal();
        // Smoothed: some points move off the mesh.
        let smoothed = stored(Fidelity::Smoothed);
        let (points, _) = arcs_of(&smoothed);
        assert!(points
            .iter()
            .any(|&i| nearest(smoothed.points[i as usize]) > 1e-3 * diagonal));
        // Junctions held: the chosen region's junctions are exactly where the mesh has
        // them, which smoothing moved; its arcs' other points are still smoothed.
        let junctions: Vec<DVec3> = graph
            .arcs
            .iter()
            .filter(|a| !a.closed && touches(a.left, a.right.region()))
            .flat_map(|a| [a.vertices[0], a.vertices[a.vertices.len() - 1]])
            .map(|v| mesh.positions()[v as usize])
            .collect();
        assert!(!junctions.is_empty());
        let ends = |rep: &Representation| -> Vec<DVec3> {
            rep.arcs
                .iter()
                .filter(|a| !a.closed && touches(a.left, a.right.region()))
                .flat_map(|a| [a.points[0], a.points[a.points.len() - 1]])
                .map(|i| rep.points[i as usize])
                .collect()
        };
        let at_junction = |p: &DVec3| junctions.contains(p);
        assert!(!ends(&smoothed).iter().all(at_junction));
        let held = stored(Fidelity::Junctions);
        assert!(ends(&held).iter().all(at_junction));
        let (points, _) = arcs_of(&held);
        assert!(points
            .iter()
            .any(|&i| nearest(held.points[i as usize]) > 1e-3 * diagonal));
        // At the mesh's points: every stored point is one (up to the grid's rounding, which
        // `represent` leaves to the file: the representation is before quantisation).
        let at_mesh = stored(Fidelity::MeshPoints);
        let (points, simplified) = arcs_of(&at_mesh);
        for &i in &points {
            let p = at_mesh.points[i as usize];
            assert!(nearest(p) <= grid(&at_mesh) + 1e-12, "{p}");
        }
        // Exact: and none is dropped (arcs are stored with all their mesh vertices).
        let exact = stored(Fidelity::Exact);
        let (points, kept) = arcs_of(&exact);
        for &i in &points {
            assert!(nearest(exact.points[i as usize]) <= grid(&exact) + 1e-12);
        }
        let all: usize = graph
            .arcs
            .iter()
            .filter(|a| touches(a.left, a.right.region()))
            .map(|a| a.vertices.len())
            .sum();
        assert_eq!(kept, all);
        assert!(simplified < kept, "{simplified} of {kept}");
    }
    /// Rate control keeps a probe that decodes clean before one that does not, whatever
    /// their sizes and errors, and among either the best for the target; it searches again
    /// at the best probe that meets the target only when that one is not clean; a probe
    /// that misses the target is never kept nor searched again.
    #[test]
    fn rate_control_keeps_a_clean_file_first_and_searches_again_at_a_better_dirty_one() {
        let probe = |regions, bytes, rms, clean| Probe {
            regions,
            boundary_tolerance: 1e-3,
            bytes,
            rms,
            clean,
            searched_again: false,
        };
        // K = 6 is the best for both targets (the smallest file, the lowest error) but not
        // clean; K = 9 is too large and too far.
        let probes = [
            probe(4, 1258, 0.0276, true),
            probe(6, 1230, 0.0150, false),
            probe(5, 1240, 0.0351, true),
            probe(9, 1900, 0.0600, true),
        ];
        let budget = Target::MaxBytes(1500);
        let error = Target::Rms(0.04);
        // Within 1.6 %, only the dirty K = 6 meets the target: kept, having been searched
        // again.
        let tight = Target::Rms(0.016);
        for (target, chosen, why) in [
            (budget, 0, "the lower error, clean"),
            (error, 2, "the smaller file, clean"),
            (tight, 1, "the only one that meets the target"),
        ] {
            assert_eq!(
                probe_to_search_again(&probes, target),
                Some(1),
                "{target:?}"
            );
            assert_eq!(chosen_probe(&probes, target), Some(chosen), "{why}");
        }
        // The search again made K = 6 clean: it is kept over every other.
        let mut searched = probes.to_vec();
        searched.push(Probe {
            searched_again: true,
            ..probe(6, 1219, 0.0116, true)
        });
        for target in [budget, error, tight] {
            assert_eq!(chosen_probe(&searched, target), Some(4), "{target:?}");
        }
        // When the best probe is clean nothing is searched again, even with a dirty one
        // beside it; and nothing meets a budget below every file.
        let clean_best = [probe(4, 1258, 0.0276, false), probe(8, 1400, 0.0082, true)];
        assert_eq!(probe_to_search_again(&clean_best, budget), None);
        assert_eq!(chosen_probe(&clean_best, budget), Some(1));
        assert_eq!(
            probe_to_search_again(&clean_best, Target::MaxBytes(1000)),
            None
        );
        assert_eq!(chosen_probe(&clean_best, Target::MaxBytes(1000)), None);
        // Ties keep the earliest.
        let twins = [probe(6, 1264, 0.0150, true), probe(6, 1264, 0.0150, true)];
        assert_eq!(chosen_probe(&twins, budget), Some(0));
    }

    /// Which encoding is kept when none decodes clean: one that decodes over one that does
    /// not; of those that decode, a sound mesh over one with a hole however few flipped
    /// triangles it has (horse at K = 32, mended for 12 rounds, kept a file with a hole and
    /// 1 flipped triangle over closed ones with 13), then the fewest faulty triangles, then
    /// the fewest regions to blame. A clean mesh with a region decoded off the source ranks
    /// after every mesh with faults but none off the source (assimp's spider at K = 35
    /// kept a clean file 59 % of the diagonal RMS off over ones with a few flipped
    /// triangles), the nearer first; of meshes with faults, one with a region off the
    /// source ranks last (horse at K = 48, mended, kept a file with 1 flipped triangle and
    /// a region meshed a thousand diagonals away over one in an extra piece).
    #[test]
    fn a_sound_mesh_ranks_before_one_with_a_hole() {
        let blamed = |n: u32| (0..n).map(|region| Split { region, cut: None }).collect();
        let faulty = |off, unsound, bad_triangles, n| {
            Verdict::Dirty(
                Faults {
                    off,
                    unsound,
                    bad_triangles,
                    distance: if off { 99_000 } else { 0 },
                },
                blamed(n),
                String::new(),
            )
            .score()
        };
        let dirty = |unsound, bad_triangles, n| faulty(false, unsound, bad_triangles, n);
        let ranked = [
            Verdict::Clean.score(),
            dirty(false, 2, 5),
            dirty(false, 13, 1),
            dirty(false, 13, 2),
            dirty(true, 1, 1),
            dirty(true, 40, 1),
            Verdict::Far(1200, blamed(2), String::new()).score(),
            Verdict::Far(3000, blamed(1), String::new()).score(),
            faulty(true, false, 1, 1),
            faulty(true, true, 0, 1),
            Verdict::Fails(blamed(1), String::new(), Vec::new()).score(),
            Verdict::Fails(blamed(2), String::new(), Vec::new()).score(),
        ];
        assert!(ranked.windows(2).all(|w| w[0] < w[1]), "{ranked:?}");
    }

    #[test]
    fn the_cut_between_a_fold_s_sheets_lies_halfway_and_faces_across() {
        // Two short edges 2 apart along z (a fold's two sheets, crossing in the chart).
        let crossing = [
            [DVec3::new(-0.1, 0.0, 1.0), DVec3::new(0.1, 0.0, 1.0)],
            [DVec3::new(0.0, -0.1, -1.0), DVec3::new(0.0, 0.1, -1.0)],
        ];
        let cut = cut_between(crossing).unwrap();
        assert!(cut.point.length() < 1e-12);
        assert!((cut.normal - DVec3::Z).length() < 1e-12);
        // Edges no farther apart than they are long: a local kink, no cut.
        let kink = [
            [DVec3::new(-1.0, 0.0, 0.1), DVec3::new(1.0, 0.0, 0.1)],
            [DVec3::new(0.0, -1.0, -0.1), DVec3::new(0.0, 1.0, -0.1)],
        ];
        assert_eq!(cut_between(kink), None);
    }
}
