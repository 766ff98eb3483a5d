//! The `.ellip` file format: a versioned encoder and a hardened decoder of
//! [`Representation`]s. The specification is `spec/ELLIP.md`; rule labels in error messages
//! (H1, S2, P8, …) refer to it.
//!
//! - [`encode`]: validate, number the pool in order of use, quantise the points on a grid of
//!   [`EncodeOptions::bits`] per axis, write META, ELPS, ARCS, PNTS, CYCL, each DEFLATE-compressed
//!   when that is smaller. Deterministic: equal inputs give equal bytes.
//! - [`decode`]: check header, checksums and [`Limits`] before any allocation, inflate with a
//!   cap, parse, then [`Representation::validate`]; every failure is a typed
//!   [`DecodeError`], never a panic.
//! - [`inspect`]: decode and summarise, with stored and raw bytes per section (for
//!   `ellip info`).
//! - [`Representation::simplify_arcs`] (Douglas–Peucker, [`simplify`]) is the step before
//!   encoding that makes files small.
//!
//! Layering: [`container`] (header, framing, CRC, DEFLATE) → `sections` (payload schemas) →
//! `wire` (the only user of bincode) and [`quantise`] (the point grid).

mod bits;
pub mod consts;
pub mod container;
mod error;
mod limits;
pub mod quantise;
pub mod sample;
mod sections;
pub mod simplify;
mod wire;

pub use error::{DecodeError, EncodeError, Tag};
pub use limits::Limits;
pub use quantise::Grid;

use crate::representation::{Metadata, Representation};
use consts::*;
use container::{inflate, read_container, write_container, RawSection, SectionView};
use std::collections::BTreeMap;
use wire::Reader;

/// Default bits per axis of the point grid, chosen by measurement (spec appendix B): its
/// worst-case error is 1/(2·(2¹² − 1)) ≈ 1.2·10⁻⁴ of the points' bounding-box diagonal, an
/// eighth of the 10⁻³·diagonal simplification tolerance it is meant to go with; two more bits
/// cost about 25 % more point bytes.
pub const DEFAULT_BITS: u8 = 12;

/// How to encode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncodeOptions {
    /// Bits per axis of the point grid, 1..=24 (default [`DEFAULT_BITS`]). The worst-case
    /// position error of a point is ½·|step| with step = bbox size / (2^bits − 1).
    pub bits: u8,
}

impl Default for EncodeOptions {
    fn default() -> EncodeOptions {
        EncodeOptions { bits: DEFAULT_BITS }
    }
}

/// Stored and raw size of one section.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SectionSummary {
    /// Tag.
    pub tag: Tag,
    /// Flags.
    pub flags: u32,
    /// Payload bytes as stored (compressed or not), without the 20 bytes of framing.
    pub stored_bytes: u64,
    /// Payload bytes once inflated.
    pub raw_bytes: u64,
    /// Whether this reader knows the tag (unknown sections are skipped).
    pub known: bool,
}

/// What [`inspect`] reports about a file.
#[derive(Debug, Clone, PartialEq)]
pub struct FileSummary {
    /// Major version.
    pub major: u16,
    /// Minor version.
    pub minor: u16,
    /// File size in bytes.
    pub total_bytes: u64,
    /// Sections in file order.
    pub sections: Vec<SectionSummary>,
    /// Regions (ellipsoids).
    pub regions: usize,
    /// Ellipsoids stored quantised (spec §6.2 variant 2), moved by at most
    /// [`FileSummary::error_bound`].
    pub quantised_ellipsoids: usize,
    /// Ellipsoids stored in binary32 (the rest are binary64).
    pub f32_ellipsoids: usize,
    /// Arcs.
    pub arcs: usize,
    /// Pool points.
    pub points: usize,
    /// Arc points, summed over the arcs (junctions count once per arc).
    pub arc_points: usize,
    /// Cycles, summed over the regions.
    pub cycles: usize,
    /// The point grid.
    pub grid: Grid,
    /// Worst-case distance between a decoded point and the point that was encoded.
    pub error_bound: f64,
    /// Metadata.
    pub metadata: Metadata,
}

/// Encodes `rep` (spec §6): validates it, drops pool points no arc uses, renumbers the pool
/// in order of first use along the arcs, quantises it, and writes a version 1.0 file (1.1
/// when the metadata holds a remesh hint, spec §6.1).
///
/// Ellipsoids are stored in binary32 when that is exact or moves their surface by at most
/// L·2^−(bits+3), L the pool's bounding-box diagonal — a quarter of the grid's own worst
/// case on a cube — else in binary64 (spec §11). Deterministic: equal inputs give equal bytes,
/// and re-encoding a decoded file gives the same bytes (spec §11 states the condition).
///
/// Errors: [`EncodeError::Options`] for bits outside 1..=24, [`EncodeError::Invalid`] for a
/// representation that breaks a rule of spec §6, [`EncodeError::TooLarge`] beyond the
/// normative maxima of spec §9.
pub fn encode(rep: &Representation, options: &EncodeOptions) -> Result<Vec<u8>, EncodeError> {
    if !(MIN_BITS..=MAX_BITS).contains(&options.bits) {
        return Err(EncodeError::Options {
            what: "bits must be in 1..=24",
        });
    }
    rep.validate()?;
    let too_large = |what, size: usize, max: u64| {
        if size as u64 > max {
            Err(EncodeError::TooLarge {
                what,
                size: size as u64,
                max,
            })
        } else {
            Ok(())
        }
    };
    too_large("regions", rep.ellipsoids.len(), MAX_REGIONS)?;
    too_large("arcs", rep.arcs.len(), MAX_ARCS)?;
    too_large("points", rep.points.len(), MAX_POINTS)?;
    let arc_points: usize = rep.arcs.iter().map(|a| a.points.len()).sum();
    too_large("arc points", arc_points, MAX_ARC_POINTS)?;
    let cycles: usize = rep.cycles.iter().map(Vec::len).sum();
    too_large("cycles", cycles, MAX_CYCLES)?;
    let refs: usize = rep.cycles.iter().flatten().map(|c| c.arcs.len()).sum();
    too_large("cycle arc references", refs, MAX_CYCLE_REFS)?;

    let canon = sections::canonicalise(rep);
    let arcs = sections::write_arcs(rep, &canon)?;
    let (points, grid) = sections::write_points(rep, &canon, options.bits)?;
    let ellipsoids = sections::write_ellipsoids(&rep.ellipsoids, grid.error_bound())?;
    let sections = [
        RawSection::compressed(TAG_META, false, &sections::write_meta(&rep.metadata)?)?,
        RawSection::compressed(TAG_ELPS, true, &ellipsoids)?,
        RawSection::compressed(TAG_ARCS, true, &arcs)?,
        RawSection::compressed(TAG_PNTS, true, &points)?,
        RawSection::compressed(TAG_CYCL, true, &sections::write_cycles(rep)?)?,
    ];
    write_container(MAJOR, sections::meta_minor(&rep.metadata), 0, &sections)
}

/// Decodes a file (spec §3–8) within `limits`.
pub fn decode(bytes: &[u8], limits: &Limits) -> Result<Representation, DecodeError> {
    decode_with_details(bytes, limits).map(|(rep, _)| rep)
}

/// Decodes a file and summarises it, with stored and raw bytes per section.
pub fn inspect(bytes: &[u8], limits: &Limits) -> Result<FileSummary, DecodeError> {
    let (rep, details) = decode_with_details(bytes, limits)?;
    Ok(FileSummary {
        major: details.major,
        minor: details.minor,
        total_bytes: bytes.len() as u64,
        sections: details.sections,
        regions: rep.ellipsoids.len(),
        quantised_ellipsoids: details.precision.quantised,
        f32_ellipsoids: details.precision.binary32,
        arcs: rep.arcs.len(),
        points: rep.points.len(),
        arc_points: rep.arcs.iter().map(|a| a.points.len()).sum(),
        cycles: rep.cycles.iter().map(Vec::len).sum(),
        grid: details.grid,
        error_bound: details.grid.error_bound(),
        metadata: rep.metadata,
    })
}

/// What decoding learns besides the representation.
struct Details {
    major: u16,
    minor: u16,
    sections: Vec<SectionSummary>,
    grid: Grid,
    precision: sections::Precision,
}

const KNOWN_TAGS: [Tag; 5] = [TAG_META, TAG_ELPS, TAG_ARCS, TAG_PNTS, TAG_CYCL];

fn decode_with_details(
    bytes: &[u8],
    limits: &Limits,
) -> Result<(Representation, Details), DecodeError> {
    let container = read_container(bytes, limits)?;
    // Rules S4–S7: known sections once each, with known flags; unknown ones skipped unless
    // required.
    let mut known: BTreeMap<Tag, SectionView<'_>> = BTreeMap::new();
    let mut summaries = Vec::with_capacity(container.sections.len());
    for s in &container.sections {
        let is_known = KNOWN_TAGS.contains(&s.tag);
        summaries.push(SectionSummary {
            tag: s.tag,
            flags: s.flags,
            stored_bytes: s.stored.len() as u64,
            raw_bytes: u64::from(s.raw_length),
            known: is_known,
        });
        if !is_known {
            if s.flags & SECTION_REQUIRED != 0 {
                return Err(DecodeError::UnsupportedFeature {
                    section: Some(s.tag),
                    what: "S6: unknown required section",
                });
            }
            continue;
        }
        if s.flags & !KNOWN_SECTION_FLAGS != 0 {
            return Err(DecodeError::UnsupportedFeature {
                section: Some(s.tag),
                what: "S4: unknown section flag",
            });
        }
        if known.insert(s.tag, *s).is_some() {
            return Err(DecodeError::Format {
                section: Some(s.tag),
                what: "S5: section appears twice",
            });
        }
    }
    let allow_trailing = container.minor > MINOR;
    let mut budget = limits.max_inflated_bytes;
    let mut payload = |tag: Tag| -> Result<Option<Vec<u8>>, DecodeError> {
        let Some(s) = known.get(&tag) else {
            return Ok(None);
        };
        let raw = inflate(s, budget)?;
        budget -= raw.len() as u64;
        Ok(Some(raw))
    };
    let required = |raw: Option<Vec<u8>>, tag: Tag| {
        raw.ok_or(DecodeError::Format {
            section: Some(tag),
            what: "S7: required section missing",
        })
    };
    let finish = |r: Reader<'_>| {
        if r.remaining() > 0 && !allow_trailing {
            Err(r.error("S9: bytes after the section's fields"))
        } else {
            Ok(())
        }
    };

    let metadata = match payload(TAG_META)? {
        None => Metadata::default(),
        Some(raw) => {
            let mut r = Reader::new(TAG_META, &raw);
            let m = sections::read_meta(&mut r, container.minor)?;
            finish(r)?;
            m
        }
    };
    let raw = required(payload(TAG_ELPS)?, TAG_ELPS)?;
    let mut r = Reader::new(TAG_ELPS, &raw);
    let (ellipsoids, precision) = sections::read_ellipsoids(&mut r, limits)?;
    finish(r)?;
    drop(raw);

    let raw = required(payload(TAG_ARCS)?, TAG_ARCS)?;
    let mut r = Reader::new(TAG_ARCS, &raw);
    let mut arcs = sections::read_arcs(&mut r, limits)?;
    finish(r)?;
    drop(raw);

    let raw = required(payload(TAG_PNTS)?, TAG_PNTS)?;
    let mut r = Reader::new(TAG_PNTS, &raw);
    let (points, grid) = sections::read_points(&mut r, limits, &arcs.predecessor)?;
    finish(r)?;
    drop(raw);

    let raw = required(payload(TAG_CYCL)?, TAG_CYCL)?;
    let mut r = Reader::new(TAG_CYCL, &raw);
    let cycles = sections::read_cycles(&mut r, limits, ellipsoids.len())?;
    finish(r)?;
    drop(raw);
    sections::assign_sides(&mut arcs.arcs, &cycles)?;

    let rep = Representation {
        ellipsoids,
        points,
        arcs: arcs.arcs,
        cycles,
        metadata,
    };
    rep.validate().map_err(|e| DecodeError::Format {
        section: Some(sections::tag_of(e.part)),
        what: e.what,
    })?;
    Ok((
        rep,
        Details {
            major: container.major,
            minor: container.minor,
            sections: summaries,
            grid,
            precision,
        },
    ))
}

/// Writes `.ellip` bytes to `path` atomically (a temporary file in the same folder, then a
/// rename), so that a failed write never leaves a partial file.
pub fn write_file(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    crate::atomic::write_atomic(path, |w| w.write_all(bytes))
}
