//! Every wire constant of the `.ellip` container, with its place in `spec/ELLIP.md`.

use super::error::Tag;

/// File signature (spec §3): `\x89` catches 7-bit transports, `ELLIP` names the format,
/// `\r\n` catches line-ending conversion.
pub const MAGIC: [u8; 8] = *b"\x89ELLIP\r\n";

/// Major version this crate writes and the only one it reads (spec §10).
pub const MAJOR: u16 = 1;

/// Highest minor version this crate writes (1.1 adds `META`'s remesh hint); files with a
/// higher minor are read, ignoring what they add (spec §10). A file is written with the
/// lowest minor that holds its content.
pub const MINOR: u16 = 1;

/// Header size in bytes: magic 8, major 2, minor 2, flags 4, total length 8, CRC-32 4.
pub const HEADER_LEN: usize = 28;

/// Bytes of the header covered by its CRC-32 (all before the CRC field).
pub const HEADER_CRC_COVERS: usize = 24;

/// Header flag bits known to this version: none (spec §3).
pub const KNOWN_HEADER_FLAGS: u32 = 0;

/// Section framing before the payload: tag 4, flags 4, stored length 4, raw length 4.
pub const SECTION_HEADER_LEN: usize = 16;

/// The CRC-32 after each section's payload.
pub const SECTION_CRC_LEN: usize = 4;

/// Section flag bit 0: the payload is a raw DEFLATE stream (RFC 1951).
pub const SECTION_DEFLATE: u32 = 1;

/// Section flag bit 1: a reader that does not know the tag must refuse the file.
pub const SECTION_REQUIRED: u32 = 2;

/// Section flag bits known to this version.
pub const KNOWN_SECTION_FLAGS: u32 = SECTION_DEFLATE | SECTION_REQUIRED;

/// Metadata section (optional, spec §6.1).
pub const TAG_META: Tag = Tag(*b"META");
/// Ellipsoid section (required, spec §6.2).
pub const TAG_ELPS: Tag = Tag(*b"ELPS");
/// Arc section (required, spec §6.3).
pub const TAG_ARCS: Tag = Tag(*b"ARCS");
/// Point section (required, spec §6.4).
pub const TAG_PNTS: Tag = Tag(*b"PNTS");
/// Cycle section (required, spec §6.5).
pub const TAG_CYCL: Tag = Tag(*b"CYCL");

/// Smallest and largest bits per axis of the point grid (spec §6.4).
pub const MIN_BITS: u8 = 1;
/// See [`MIN_BITS`].
pub const MAX_BITS: u8 = 24;

/// Normative maxima (spec §9): a file exceeding them is invalid whatever the reader's limits.
pub const MAX_REGIONS: u64 = 1 << 24;
/// See [`MAX_REGIONS`].
pub const MAX_POINTS: u64 = 1 << 28;
/// See [`MAX_REGIONS`].
pub const MAX_ARCS: u64 = 1 << 28;
/// See [`MAX_REGIONS`].
pub const MAX_ARC_POINTS: u64 = 1 << 30;
/// See [`MAX_REGIONS`].
pub const MAX_CYCLES: u64 = 1 << 30;
/// See [`MAX_REGIONS`].
pub const MAX_CYCLE_REFS: u64 = 1 << 30;
