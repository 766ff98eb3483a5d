//! The codec's errors: one enum per direction, matched on by variant and section, never by
//! message.

use crate::representation::InvalidRepresentation;
use std::fmt;

/// A four-byte section tag (spec §4).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Tag(pub [u8; 4]);

impl fmt::Display for Tag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for &b in &self.0 {
            if (0x20..0x7f).contains(&b) {
                write!(f, "{}", b as char)?;
            } else {
                write!(f, "\\x{b:02x}")?;
            }
        }
        Ok(())
    }
}

impl fmt::Debug for Tag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Tag(\"{self}\")")
    }
}

/// "header" or "section `TAG`", for messages.
struct Place(Option<Tag>);

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            None => write!(f, "file header"),
            Some(t) => write!(f, "section `{t}`"),
        }
    }
}

/// Why bytes could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum DecodeError {
    /// The bytes break a rule of the specification; `what` starts with the rule's label
    /// (e.g. "H1", "A3") from `spec/ELLIP.md`.
    #[error("malformed .ellip ({}): {what}", Place(*.section))]
    Format {
        /// The section, or `None` for the file header and framing.
        section: Option<Tag>,
        /// The broken rule.
        what: &'static str,
    },
    /// A major version this reader does not know (spec §10).
    #[error("unsupported .ellip version {major}.{minor} (this reader knows major 1)")]
    UnsupportedVersion {
        /// Major version in the file.
        major: u16,
        /// Minor version in the file.
        minor: u16,
    },
    /// Valid for some version of the format, but uses a feature this reader does not know: a
    /// header flag, a section flag, or an unknown required section.
    #[error("unsupported feature ({}): {what}", Place(*.section))]
    UnsupportedFeature {
        /// The section, or `None` for the file header.
        section: Option<Tag>,
        /// Which feature.
        what: &'static str,
    },
    /// The file asks for more than the reader's [`Limits`](super::Limits) allow.
    #[error("limit exceeded: {what} needs {requested}, the limit is {max}")]
    LimitsExceeded {
        /// Which limit.
        what: &'static str,
        /// What the file asks for.
        requested: u64,
        /// The limit.
        max: u64,
    },
    /// A CRC-32 does not match: the bytes were corrupted.
    #[error("checksum mismatch in {}: stored {stored:#010x}, computed {computed:#010x}", Place(*.section))]
    ChecksumMismatch {
        /// The section, or `None` for the header.
        section: Option<Tag>,
        /// CRC-32 stored in the file.
        stored: u32,
        /// CRC-32 of the bytes.
        computed: u32,
    },
}

/// Why a representation could not be encoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum EncodeError {
    /// The representation breaks an invariant of `spec/ELLIP.md` section 6.
    #[error(transparent)]
    Invalid(#[from] InvalidRepresentation),
    /// An option is out of range.
    #[error("bad encode option: {what}")]
    Options {
        /// Which option and its range.
        what: &'static str,
    },
    /// A count or a section exceeds what the format can hold (spec §9).
    #[error("too large for the format: {what} is {size}, the maximum is {max}")]
    TooLarge {
        /// What.
        what: &'static str,
        /// Its size.
        size: u64,
        /// The format's maximum.
        max: u64,
    },
    /// Serialising or compressing a section failed (not expected with in-memory buffers).
    #[error("could not write section `{section}`: {what}")]
    Write {
        /// The section.
        section: Tag,
        /// What failed.
        what: String,
    },
}
