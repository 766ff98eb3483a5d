//! Section payloads (spec §6): what each section holds and how its items follow each other.
//! Every item goes through [`super::wire`], so the byte layout is bincode's, as the spec says.

use super::bits::{zigzag, BitReader, BitWriter, RiceContext};
use super::consts::*;
use super::error::{DecodeError, EncodeError};
use super::limits::Limits;
use super::quantise::{Grid, QuantisedEllipsoid};
use super::wire::{Reader, Writer};
use crate::ellipsoid::{Ellipsoid, Sign};
use crate::representation::{Arc, ArcRef, Cycle, Metadata, Part, Representation, Side};
use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// The section that holds a part of a representation.
pub(crate) fn tag_of(part: Part) -> super::error::Tag {
    match part {
        Part::Ellipsoids => TAG_ELPS,
        Part::Points => TAG_PNTS,
        Part::Arcs => TAG_ARCS,
        Part::Cycles => TAG_CYCL,
        Part::Metadata => TAG_META,
    }
}

// ---------------------------------------------------------------------------------------
// META (spec §6.1)

/// The META payload, one bincode struct.
#[derive(Serialize, Deserialize)]
struct MetaWire {
    source_vertices: u64,
    source_faces: u64,
    simplify_tolerance: Option<f64>,
    measured_error: Option<f64>,
    suggested_vertices: Option<u64>,
    measured_hausdorff: Option<f64>,
}

/// The lowest minor version that holds `m` (spec §10): 1 with a remesh hint, else 0.
pub(crate) fn meta_minor(m: &Metadata) -> u16 {
    u16::from(m.remesh_hint.is_some())
}

/// The META payload of a file of minor version [`meta_minor`]`(m)`: from 1.1 on, the remesh
/// hint follows the 1.0 fields.
pub(crate) fn write_meta(m: &Metadata) -> Result<Vec<u8>, EncodeError> {
    let mut w = Writer::new(TAG_META);
    w.put(&MetaWire {
        source_vertices: m.source_vertices,
        source_faces: m.source_faces,
        simplify_tolerance: m.simplify_tolerance,
        measured_error: m.measured_error,
        suggested_vertices: m.suggested_vertices,
        measured_hausdorff: m.measured_hausdorff,
    })?;
    if meta_minor(m) >= 1 {
        w.put(&m.remesh_hint)?;
    }
    Ok(w.into_bytes())
}

/// Reads the META payload of a file of minor version `minor` (the hint from 1.1 on).
pub(crate) fn read_meta(r: &mut Reader<'_>, minor: u16) -> Result<Metadata, DecodeError> {
    let m: MetaWire = r.get("M0: malformed metadata")?;
    let remesh_hint = if minor >= 1 {
        r.get::<Option<u64>>("M0: malformed metadata")?
    } else {
        None
    };
    Ok(Metadata {
        source_vertices: m.source_vertices,
        source_faces: m.source_faces,
        simplify_tolerance: m.simplify_tolerance,
        measured_error: m.measured_error,
        suggested_vertices: m.suggested_vertices,
        measured_hausdorff: m.measured_hausdorff,
        remesh_hint,
    })
}

// ---------------------------------------------------------------------------------------
// ELPS (spec §6.2)

/// One ellipsoid: variant 0 in binary32, variant 1 in binary64, variant 2 quantised (a bit
/// stream, [`QuantisedEllipsoid`]). Rotation is (x, y, z, w).
#[derive(Serialize, Deserialize)]
enum WireEllipsoid {
    F32 {
        center: [f32; 3],
        rotation: [f32; 4],
        radii: [f32; 3],
        negative: bool,
    },
    F64 {
        center: [f64; 3],
        rotation: [f64; 4],
        radii: [f64; 3],
        negative: bool,
    },
    Quantised(Vec<u8>),
}

/// Smallest encoded ellipsoid: variant 2, a length and the 5 bytes of the shortest stream
/// (1 + 8 + 3·5 + 3 + 2 + 5 + 5 bits).
const MIN_ELLIPSOID_BYTES: u64 = 7;

/// How many ellipsoids a section stored in each form.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct Precision {
    pub(crate) quantised: usize,
    pub(crate) binary32: usize,
    pub(crate) binary64: usize,
}

/// The encoder normalises a rotation whose |‖q‖² − 1| exceeds this (spec §11).
const ENCODER_RENORMALISE: f64 = 1e-6;

/// Chooses the quantised form when its bound is within `tolerance`; else binary32 when it is
/// exact, or when the worst-case surface displacement its rounding causes,
/// 2⁻²⁴·(‖c‖ + 6·r_max), is within `tolerance`; else binary64 (spec §11, item 4).
fn to_wire(e: &Ellipsoid, tolerance: f64) -> WireEllipsoid {
    if let Some(q) = QuantisedEllipsoid::from_ellipsoid(e, tolerance) {
        let mut w = BitWriter::new();
        q.write(&mut w);
        return WireEllipsoid::Quantised(w.finish());
    }
    let q = if (e.rotation.length_squared() - 1.0).abs() > ENCODER_RENORMALISE {
        e.rotation.normalize()
    } else {
        e.rotation
    };
    let negative = e.sign == Sign::Negative;
    let c = e.center.to_array();
    let r = e.radii.to_array();
    let rot = q.to_array();
    let c32 = c.map(|v| v as f32);
    let r32 = r.map(|v| v as f32);
    let rot32 = rot.map(|v| v as f32);
    let all_finite = c32.iter().chain(&r32).chain(&rot32).all(|v| v.is_finite());
    let radii_positive = r32.iter().all(|&v| v > 0.0);
    let exact = c32.iter().zip(&c).all(|(&a, &b)| f64::from(a) == b)
        && r32.iter().zip(&r).all(|(&a, &b)| f64::from(a) == b)
        && rot32.iter().zip(&rot).all(|(&a, &b)| f64::from(a) == b);
    let displacement = (e.center.length() + 6.0 * e.radii.max_element()) * 2f64.powi(-24);
    if all_finite && radii_positive && (exact || displacement <= tolerance) {
        WireEllipsoid::F32 {
            center: c32,
            rotation: rot32,
            radii: r32,
            negative,
        }
    } else {
        WireEllipsoid::F64 {
            center: c,
            rotation: rot,
            radii: r,
            negative,
        }
    }
}

/// The ELPS payload, ellipsoids moved by at most `tolerance` (0: exact).
pub(crate) fn write_ellipsoids(
    ellipsoids: &[Ellipsoid],
    tolerance: f64,
) -> Result<Vec<u8>, EncodeError> {
    let mut w = Writer::new(TAG_ELPS);
    w.put_count(ellipsoids.len())?;
    for e in ellipsoids {
        w.put(&to_wire(e, tolerance))?;
    }
    Ok(w.into_bytes())
}

/// The ellipsoids, and how many were stored in each form.
pub(crate) fn read_ellipsoids(
    r: &mut Reader<'_>,
    limits: &Limits,
) -> Result<(Vec<Ellipsoid>, Precision), DecodeError> {
    let max = limits.max_regions.min(MAX_REGIONS);
    let n = r.count("regions", max, MIN_ELLIPSOID_BYTES)?;
    let mut out = Vec::with_capacity(n);
    let mut precision = Precision::default();
    for _ in 0..n {
        let (center, rotation, radii, negative) = match r.get("E0: malformed ellipsoid")? {
            WireEllipsoid::Quantised(stream) => {
                precision.quantised += 1;
                let mut bits = BitReader::new(&stream);
                let q = QuantisedEllipsoid::read(&mut bits)
                    .ok_or_else(|| r.error("E0: malformed ellipsoid"))?;
                if !bits.is_at_padded_end() {
                    return Err(r.error("E5: bits after the quantised ellipsoid"));
                }
                if q.radii.contains(&0) {
                    return Err(r.error("E2: radius not positive"));
                }
                let e = q
                    .to_ellipsoid()
                    .ok_or_else(|| r.error("E4: quantised rotation components exceed 1"))?;
                out.push(e);
                continue;
            }
            WireEllipsoid::F32 {
                center,
                rotation,
                radii,
                negative,
            } => {
                precision.binary32 += 1;
                (
                    center.map(f64::from),
                    rotation.map(f64::from),
                    radii.map(f64::from),
                    negative,
                )
            }
            WireEllipsoid::F64 {
                center,
                rotation,
                radii,
                negative,
            } => {
                precision.binary64 += 1;
                (center, rotation, radii, negative)
            }
        };
        out.push(Ellipsoid {
            center: DVec3::from_array(center),
            rotation: DQuat::from_array(rotation),
            radii: DVec3::from_array(radii),
            sign: if negative {
                Sign::Negative
            } else {
                Sign::Positive
            },
        });
    }
    Ok((out, precision))
}

// ---------------------------------------------------------------------------------------
// The canonical pool (spec §6.3): points numbered in order of first use along the arcs.

/// The pool in canonical order, each arc's chain codes and each point's predictor.
pub(crate) struct Canonical {
    /// Original pool index of each canonical point.
    pub(crate) order: Vec<u32>,
    /// Per arc, per point: 0 for "the next new point", k + 1 for canonical point k.
    pub(crate) codes: Vec<Vec<u32>>,
    /// Per canonical point, the canonical point before its first use in its arc, if any.
    pub(crate) predecessor: Vec<Option<u32>>,
}

/// Numbers the used points of `rep` in order of first use (validated input: every index is
/// in range).
pub(crate) fn canonicalise(rep: &Representation) -> Canonical {
    let mut new_index = vec![u32::MAX; rep.points.len()];
    let mut order = Vec::new();
    let mut predecessor = Vec::new();
    let mut codes = Vec::with_capacity(rep.arcs.len());
    for arc in &rep.arcs {
        let mut prev = None;
        let mut chain = Vec::with_capacity(arc.points.len());
        for &old in &arc.points {
            let Some(slot) = new_index.get_mut(old as usize) else {
                continue;
            };
            if *slot == u32::MAX {
                *slot = order.len() as u32;
                order.push(old);
                predecessor.push(prev);
                chain.push(0);
            } else {
                chain.push(*slot + 1);
            }
            prev = Some(*slot);
        }
        codes.push(chain);
    }
    Canonical {
        order,
        codes,
        predecessor,
    }
}

/// Predicted grid indices of canonical point `i` (spec §6.4) and the kind of prediction,
/// which selects the Rice contexts: with k its predecessor and j k's predecessor,
/// 2·q[k] − q[j] (the chain continued straight on, kind 0); with no j, q[k] (kind 1); with
/// no k, the previous point's q[i − 1]; for the first point, zero (kind 2). In i64: a
/// prediction may leave the grid, the predicted point may not.
fn prediction(i: usize, predecessor: &[Option<u32>], q: &[[u32; 3]]) -> ([i64; 3], usize) {
    let at = |k: usize| q.get(k).map(|v| v.map(i64::from));
    let k = predecessor.get(i).copied().flatten().map(|k| k as usize);
    let j = k.and_then(|k| predecessor.get(k).copied().flatten().map(|j| j as usize));
    let kind = match (k, j) {
        (Some(_), Some(_)) => 0,
        (Some(_), None) => 1,
        (None, _) => 2,
    };
    let predicted = match (k, j) {
        (Some(k), Some(j)) => at(k)
            .zip(at(j))
            .map(|(a, b)| std::array::from_fn(|x| 2 * a[x] - b[x])),
        (Some(k), None) => at(k),
        (None, _) => i.checked_sub(1).and_then(at),
    };
    (predicted.unwrap_or([0; 3]), kind)
}

// ---------------------------------------------------------------------------------------
// ARCS (spec §6.3)

pub(crate) fn write_arcs(rep: &Representation, canon: &Canonical) -> Result<Vec<u8>, EncodeError> {
    let mut w = Writer::new(TAG_ARCS);
    w.put_count(rep.arcs.len())?;
    // The regions on either side are not stored: the cycles name them (§6.5).
    for (arc, codes) in rep.arcs.iter().zip(&canon.codes) {
        w.put(&arc.closed)?;
        w.put_count(codes.len())?;
        for c in codes {
            w.put(c)?;
        }
    }
    Ok(w.into_bytes())
}

/// Arcs read from ARCS, with the number of points they introduce and each point's
/// predecessor (`None` when it opens its arc).
pub(crate) struct ArcsRead {
    pub(crate) arcs: Vec<Arc>,
    pub(crate) predecessor: Vec<Option<u32>>,
}

/// Smallest encoded arc: closed, length, and two one-byte codes.
const MIN_ARC_BYTES: u64 = 4;

pub(crate) fn read_arcs(r: &mut Reader<'_>, limits: &Limits) -> Result<ArcsRead, DecodeError> {
    let n = r.count("arcs", limits.max_arcs.min(MAX_ARCS), MIN_ARC_BYTES)?;
    let max_points = limits.max_points.min(MAX_POINTS);
    let max_arc_points = limits.max_arc_points.min(MAX_ARC_POINTS);
    let mut arcs = Vec::with_capacity(n);
    let mut predecessor: Vec<Option<u32>> = Vec::new();
    let mut arc_points = 0u64;
    for _ in 0..n {
        let closed: bool = r.get("A0: closed flag is not a bool")?;
        let len = r.count_more("arc points", arc_points, max_arc_points, 1)?;
        arc_points += len as u64;
        let mut points = Vec::with_capacity(len);
        let mut prev = None;
        for _ in 0..len {
            let code: u32 = r.get("A3: point code is not a u32 varint")?;
            let index = match code.checked_sub(1) {
                None => {
                    let next = predecessor.len() as u64;
                    super::limits::check("points", next + 1, max_points)?;
                    predecessor.push(prev);
                    u32::try_from(next).map_err(|_| r.error("A3: too many points"))?
                }
                Some(k) if (k as usize) < predecessor.len() => k,
                Some(_) => return Err(r.error("A3: point reference before its first use")),
            };
            points.push(index);
            prev = Some(index);
        }
        // Sides are filled in from the cycles ([`assign_sides`]).
        arcs.push(Arc {
            points,
            closed,
            left: u32::MAX,
            right: Side::Border,
        });
    }
    Ok(ArcsRead { arcs, predecessor })
}

// ---------------------------------------------------------------------------------------
// PNTS (spec §6.4)

pub(crate) fn write_points(
    rep: &Representation,
    canon: &Canonical,
    bits: u8,
) -> Result<(Vec<u8>, Grid), EncodeError> {
    let points: Vec<DVec3> = canon
        .order
        .iter()
        .filter_map(|&i| rep.points.get(i as usize).copied())
        .collect();
    let grid = Grid::around(&points, bits);
    let q: Vec<[u32; 3]> = points.iter().map(|&p| grid.quantise(p)).collect();
    let mut w = Writer::new(TAG_PNTS);
    w.put_count(q.len())?;
    w.put(&bits)?;
    w.put(&grid.min.to_array())?;
    w.put(&grid.max.to_array())?;
    let mut stream = BitWriter::new();
    let mut contexts = [RiceContext::default(); 9];
    for (i, qi) in q.iter().enumerate() {
        let (p, kind) = prediction(i, &canon.predecessor, &q);
        for a in 0..3 {
            // Grid indices are below 2^24 and predictions within (−2^24, 2^25): the
            // residuals fit an i32.
            let d = (i64::from(qi[a]) - p[a]) as i32;
            contexts[3 * kind + a].put(&mut stream, zigzag(d));
        }
    }
    w.put_bytes(&stream.finish())?;
    Ok((w.into_bytes(), grid))
}

pub(crate) fn read_points(
    r: &mut Reader<'_>,
    limits: &Limits,
    predecessor: &[Option<u32>],
) -> Result<(Vec<DVec3>, Grid), DecodeError> {
    // A point costs at least three bits.
    let n = r.count("points", limits.max_points.min(MAX_POINTS), 0)?;
    if n as u64 > (r.remaining() as u64).saturating_mul(8) / 3 {
        return Err(r.error("X2: count exceeds the bytes left"));
    }
    if n != predecessor.len() {
        return Err(r.error("P4: point count differs from the points the arcs use"));
    }
    let bits: u8 = r.get("P5: bits is not a byte")?;
    if !(MIN_BITS..=MAX_BITS).contains(&bits) {
        return Err(r.error("P5: bits out of range 1..=24"));
    }
    let min: [f64; 3] = r.get("P6: malformed bounding box")?;
    let max: [f64; 3] = r.get("P6: malformed bounding box")?;
    let (min, max) = (DVec3::from_array(min), DVec3::from_array(max));
    if !(min.is_finite() && max.is_finite() && min.cmple(max).all()) {
        return Err(r.error("P6: bounding box not finite or min > max"));
    }
    let grid = Grid { bits, min, max };
    let levels = i64::from(grid.levels());
    let stream = r.bytes("P7: malformed residual stream")?;
    if (n as u64).saturating_mul(3) > (stream.len() as u64).saturating_mul(8) {
        return Err(r.error("P7: residual stream shorter than its points"));
    }
    let mut bits = BitReader::new(stream);
    let mut contexts = [RiceContext::default(); 9];
    let mut q: Vec<[u32; 3]> = Vec::with_capacity(n);
    for i in 0..n {
        let (p, kind) = prediction(i, predecessor, &q);
        let mut qi = [0u32; 3];
        for a in 0..3 {
            let d = contexts[3 * kind + a]
                .get(&mut bits)
                .map(super::bits::unzigzag)
                .ok_or_else(|| r.error("P7: residual stream ends early"))?;
            let v = p[a] + i64::from(d);
            if !(0..=levels).contains(&v) {
                return Err(r.error("P8: grid index out of range"));
            }
            qi[a] = v as u32;
        }
        q.push(qi);
    }
    if !bits.is_at_padded_end() {
        return Err(r.error("P9: bits after the last residual"));
    }
    Ok((q.iter().map(|&qi| grid.dequantise(qi)).collect(), grid))
}

// ---------------------------------------------------------------------------------------
// CYCL (spec §6.5)

pub(crate) fn write_cycles(rep: &Representation) -> Result<Vec<u8>, EncodeError> {
    let mut w = Writer::new(TAG_CYCL);
    w.put_count(rep.cycles.len())?;
    for cycles in &rep.cycles {
        w.put_count(cycles.len())?;
        for c in cycles {
            w.put(&c.outer)?;
            w.put_count(c.arcs.len())?;
            for a in &c.arcs {
                let code = (u64::from(a.arc) << 1) | u64::from(a.reversed);
                w.put(&code)?;
            }
        }
    }
    Ok(w.into_bytes())
}

pub(crate) fn read_cycles(
    r: &mut Reader<'_>,
    limits: &Limits,
    regions: usize,
) -> Result<Vec<Vec<Cycle>>, DecodeError> {
    let n = r.count("regions", limits.max_regions.min(MAX_REGIONS), 1)?;
    if n != regions {
        return Err(r.error("C1: region count differs from ELPS"));
    }
    let max_cycles = limits.max_cycles.min(MAX_CYCLES);
    let max_refs = limits.max_cycle_refs.min(MAX_CYCLE_REFS);
    let (mut cycles_seen, mut refs_seen) = (0u64, 0u64);
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let k = r.count_more("cycles", cycles_seen, max_cycles, 2)?;
        cycles_seen += k as u64;
        let mut cycles = Vec::with_capacity(k);
        for _ in 0..k {
            let outer: bool = r.get("C0: outer flag is not a bool")?;
            let m = r.count_more("cycle arc references", refs_seen, max_refs, 1)?;
            refs_seen += m as u64;
            let mut arcs = Vec::with_capacity(m);
            for _ in 0..m {
                let code: u64 = r.get("C2: arc reference is not a varint")?;
                let arc = u32::try_from(code >> 1)
                    .map_err(|_| r.error("C2: arc reference out of range"))?;
                arcs.push(ArcRef {
                    arc,
                    reversed: code & 1 == 1,
                });
            }
            cycles.push(Cycle { arcs, outer });
        }
        out.push(cycles);
    }
    Ok(out)
}

/// Each arc's regions from the cycles that use it (spec §6.5): the region whose cycle walks
/// it forward is on its left, the one whose cycle walks it backward on its right; an arc no
/// cycle walks backward lies on the border. An arc walked forward twice, backward twice, or
/// never forward breaks C5.
pub(crate) fn assign_sides(arcs: &mut [Arc], cycles: &[Vec<Cycle>]) -> Result<(), DecodeError> {
    let c5 = |what| DecodeError::Format {
        section: Some(TAG_CYCL),
        what,
    };
    let mut right_seen = vec![false; arcs.len()];
    for (region, list) in cycles.iter().enumerate() {
        let region = u32::try_from(region).map_err(|_| c5("C1: too many regions"))?;
        for cycle in list {
            for a in &cycle.arcs {
                let i = a.arc as usize;
                let Some(arc) = arcs.get_mut(i) else {
                    return Err(c5("C2: arc index out of range"));
                };
                if a.reversed {
                    if right_seen[i] {
                        return Err(c5("C5: an arc walked backward twice"));
                    }
                    right_seen[i] = true;
                    arc.right = Side::Region(region);
                } else {
                    if arc.left != u32::MAX {
                        return Err(c5("C5: an arc walked forward twice"));
                    }
                    arc.left = region;
                }
            }
        }
    }
    if arcs.iter().any(|a| a.left == u32::MAX) {
        return Err(c5("C5: an arc no cycle walks forward"));
    }
    Ok(())
}
