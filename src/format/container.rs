//! The container (spec §3–4): the 28-byte header, then self-delimiting sections, each framed
//! by tag, flags, stored and raw length, and followed by a CRC-32.
//!
//! Public so that tools and tests can build files section by section (including invalid
//! ones); [`super::encode`] and [`super::decode`] are the normal entry points.

use super::consts::*;
use super::error::{DecodeError, EncodeError, Tag};
use super::limits::{check, Limits};
use flate2::read::DeflateDecoder;
use flate2::write::DeflateEncoder;
use flate2::Compression;
use std::io::{Read, Write};

/// A section as written: its tag, flags and stored (possibly compressed) payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawSection {
    /// Four-byte tag.
    pub tag: Tag,
    /// Flag bits ([`SECTION_DEFLATE`], [`SECTION_REQUIRED`]).
    pub flags: u32,
    /// Raw (inflated) payload length.
    pub raw_length: u32,
    /// The payload as stored.
    pub stored: Vec<u8>,
}

impl RawSection {
    /// A section holding `raw`, DEFLATE-compressed if that makes it smaller (spec §7).
    pub fn compressed(tag: Tag, required: bool, raw: &[u8]) -> Result<RawSection, EncodeError> {
        let too_large = |size: usize| EncodeError::TooLarge {
            what: "section payload",
            size: size as u64,
            max: u64::from(u32::MAX),
        };
        let raw_length = u32::try_from(raw.len()).map_err(|_| too_large(raw.len()))?;
        let write_error = |e: std::io::Error| EncodeError::Write {
            section: tag,
            what: e.to_string(),
        };
        let mut encoder = DeflateEncoder::new(Vec::new(), Compression::best());
        encoder.write_all(raw).map_err(write_error)?;
        let deflated = encoder.finish().map_err(write_error)?;
        let required = if required { SECTION_REQUIRED } else { 0 };
        Ok(if deflated.len() < raw.len() {
            RawSection {
                tag,
                flags: required | SECTION_DEFLATE,
                raw_length,
                stored: deflated,
            }
        } else {
            RawSection {
                tag,
                flags: required,
                raw_length,
                stored: raw.to_vec(),
            }
        })
    }
}

/// Writes a container: header with `major`, `minor` and `flags`, then `sections` in order,
/// with lengths and CRC-32s filled in. Writes whatever it is given (tools use it to build
/// invalid files); only the sizes are checked.
pub fn write_container(
    major: u16,
    minor: u16,
    flags: u32,
    sections: &[RawSection],
) -> Result<Vec<u8>, EncodeError> {
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&major.to_le_bytes());
    out.extend_from_slice(&minor.to_le_bytes());
    out.extend_from_slice(&flags.to_le_bytes());
    out.extend_from_slice(&[0; 8]); // total length, filled in below
    out.extend_from_slice(&[0; 4]); // header CRC, filled in below
    for s in sections {
        let stored_length = u32::try_from(s.stored.len()).map_err(|_| EncodeError::TooLarge {
            what: "stored section",
            size: s.stored.len() as u64,
            max: u64::from(u32::MAX),
        })?;
        let start = out.len();
        out.extend_from_slice(&s.tag.0);
        out.extend_from_slice(&s.flags.to_le_bytes());
        out.extend_from_slice(&stored_length.to_le_bytes());
        out.extend_from_slice(&s.raw_length.to_le_bytes());
        out.extend_from_slice(&s.stored);
        let crc = crc32fast::hash(&out[start..]);
        out.extend_from_slice(&crc.to_le_bytes());
    }
    let total = out.len() as u64;
    out[16..24].copy_from_slice(&total.to_le_bytes());
    let crc = crc32fast::hash(&out[..HEADER_CRC_COVERS]);
    out[24..28].copy_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// A section as found in a file, its payload still stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SectionView<'a> {
    /// Tag.
    pub tag: Tag,
    /// Flags.
    pub flags: u32,
    /// Raw (inflated) length.
    pub raw_length: u32,
    /// Stored payload.
    pub stored: &'a [u8],
    /// Offset of the section's tag in the file.
    pub offset: usize,
}

/// A parsed container: header fields and the sections, checksums verified.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ContainerView<'a> {
    /// Major version.
    pub major: u16,
    /// Minor version.
    pub minor: u16,
    /// Header flags.
    pub flags: u32,
    /// Sections in file order.
    pub sections: Vec<SectionView<'a>>,
}

fn format(section: Option<Tag>, what: &'static str) -> DecodeError {
    DecodeError::Format { section, what }
}

fn le_u16(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn le_u32(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn le_u64(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

/// Parses the header and the section framing of `bytes` (spec §3–4, rules H1–H5, S1–S3),
/// verifying every CRC-32. Payloads are not inflated.
pub fn read_container<'a>(
    bytes: &'a [u8],
    limits: &Limits,
) -> Result<ContainerView<'a>, DecodeError> {
    let header = bytes
        .get(..HEADER_LEN)
        .ok_or(format(None, "H1: shorter than the header"))?;
    if header.get(..8) != Some(&MAGIC[..]) {
        return Err(format(None, "H1: not an .ellip file (bad magic)"));
    }
    // `header` is HEADER_LEN bytes long: the reads below cannot fail.
    let stored_crc = le_u32(header, 24).unwrap_or(0);
    let computed = crc32fast::hash(header.get(..HEADER_CRC_COVERS).unwrap_or(&[]));
    if stored_crc != computed {
        return Err(DecodeError::ChecksumMismatch {
            section: None,
            stored: stored_crc,
            computed,
        });
    }
    let major = le_u16(header, 8).unwrap_or(0);
    let minor = le_u16(header, 10).unwrap_or(0);
    if major != MAJOR {
        return Err(DecodeError::UnsupportedVersion { major, minor });
    }
    let flags = le_u32(header, 12).unwrap_or(0);
    if flags & !KNOWN_HEADER_FLAGS != 0 {
        return Err(DecodeError::UnsupportedFeature {
            section: None,
            what: "H4: unknown header flag",
        });
    }
    let total = le_u64(header, 16).unwrap_or(0);
    check("file bytes", total, limits.max_file_bytes)?;
    if total != bytes.len() as u64 {
        return Err(format(
            None,
            if total > bytes.len() as u64 {
                "H5: file truncated (shorter than its total length)"
            } else {
                "H5: bytes after the total length"
            },
        ));
    }
    let mut sections = Vec::new();
    let mut at = HEADER_LEN;
    while at < bytes.len() {
        check(
            "sections",
            sections.len() as u64 + 1,
            u64::from(limits.max_sections),
        )?;
        let frame = bytes
            .get(at..at + SECTION_HEADER_LEN)
            .ok_or(format(None, "S1: truncated section header"))?;
        let tag = Tag(frame[..4].try_into().unwrap_or([0; 4]));
        let flags = le_u32(frame, 4).unwrap_or(0);
        let stored_length = le_u32(frame, 8).unwrap_or(0) as usize;
        let raw_length = le_u32(frame, 12).unwrap_or(0);
        let payload_at = at + SECTION_HEADER_LEN;
        let end = payload_at
            .checked_add(stored_length)
            .and_then(|e| e.checked_add(SECTION_CRC_LEN))
            .filter(|&e| e <= bytes.len())
            .ok_or(format(
                Some(tag),
                "S2: section runs past the end of the file",
            ))?;
        let stored = &bytes[payload_at..end - SECTION_CRC_LEN];
        let stored_crc = le_u32(bytes, end - SECTION_CRC_LEN).unwrap_or(0);
        let computed = crc32fast::hash(&bytes[at..end - SECTION_CRC_LEN]);
        if stored_crc != computed {
            return Err(DecodeError::ChecksumMismatch {
                section: Some(tag),
                stored: stored_crc,
                computed,
            });
        }
        if !tag.0.iter().all(|b| (0x20..0x7f).contains(b)) {
            return Err(format(Some(tag), "S3: tag is not printable ASCII"));
        }
        sections.push(SectionView {
            tag,
            flags,
            raw_length,
            stored,
            offset: at,
        });
        at = end;
    }
    Ok(ContainerView {
        major,
        minor,
        flags,
        sections,
    })
}

/// The raw payload of `section` (spec §7): inflated if [`SECTION_DEFLATE`] is set, output
/// capped at its raw length, which must fit in `budget` bytes.
pub fn inflate(section: &SectionView<'_>, budget: u64) -> Result<Vec<u8>, DecodeError> {
    let raw_length = u64::from(section.raw_length);
    check("inflated bytes", raw_length, budget)?;
    let tag = Some(section.tag);
    if section.flags & SECTION_DEFLATE == 0 {
        if section.stored.len() as u64 != raw_length {
            return Err(format(tag, "S2: stored and raw lengths differ"));
        }
        return Ok(section.stored.to_vec());
    }
    // Reserve what the stored bytes can plausibly inflate to, not what the file claims: a
    // few hostile bytes must not buy a large allocation. The output grows as it is produced,
    // and `take` stops it one byte past the raw length.
    let plausible = (section.stored.len() as u64)
        .saturating_mul(8)
        .saturating_add(4096);
    let capacity =
        usize::try_from(raw_length.min(plausible)).map_err(|_| format(tag, "S2: too long"))?;
    let mut out = Vec::with_capacity(capacity);
    let mut decoder = DeflateDecoder::new(section.stored);
    (&mut decoder)
        .take(raw_length + 1)
        .read_to_end(&mut out)
        .map_err(|_| format(tag, "S8: invalid DEFLATE stream"))?;
    if out.len() as u64 != raw_length {
        return Err(format(
            tag,
            "S8: inflated length differs from the raw length",
        ));
    }
    if decoder.total_in() != section.stored.len() as u64 {
        return Err(format(tag, "S8: bytes after the DEFLATE stream"));
    }
    Ok(out)
}
