//! The only place that touches bincode: how one item of a section payload becomes bytes.
//!
//! Configuration (spec §5): `bincode::config::standard().with_limit::<65536>()` of bincode
//! 2.0.1 — little endian; integers as variable-length "varints" (a value below 251 is one
//! byte; 251, 252, 253 announce a following u16, u32, u64 in little endian); signed integers
//! zig-zag mapped first; `f32`/`f64` as their IEEE-754 bytes, little endian; `bool` one byte
//! 0 or 1; `Option` one byte 0 (None) or 1 then the value; enums a varint variant index then
//! the fields; structs, tuples and arrays their fields in order with no framing. The limit
//! caps the bytes one item may claim; it does not change the layout.
//!
//! Sequences are not left to bincode: [`Reader::count`] reads a length as a varint (the same
//! bytes bincode would write), checks it against its [`Limits`](super::Limits) entry and
//! against the bytes left, and only then does the caller allocate.

use super::error::{DecodeError, EncodeError, Tag};
use super::limits::check;
use bincode::config::{Configuration, Limit, LittleEndian, Varint};
use serde::{de::DeserializeOwned, Serialize};

/// Bytes one item may claim while decoding.
const ITEM_LIMIT: usize = 1 << 16;

type Config = Configuration<LittleEndian, Varint, Limit<ITEM_LIMIT>>;

fn config() -> Config {
    bincode::config::standard().with_limit::<ITEM_LIMIT>()
}

/// Serialises items one after another into a section payload.
pub(crate) struct Writer {
    tag: Tag,
    bytes: Vec<u8>,
}

impl Writer {
    /// An empty payload for section `tag`.
    pub(crate) fn new(tag: Tag) -> Writer {
        Writer {
            tag,
            bytes: Vec::new(),
        }
    }

    /// Appends one item.
    pub(crate) fn put<T: Serialize>(&mut self, value: &T) -> Result<(), EncodeError> {
        bincode::serde::encode_into_std_write(value, &mut self.bytes, config())
            .map(|_| ())
            .map_err(|e| EncodeError::Write {
                section: self.tag,
                what: e.to_string(),
            })
    }

    /// Appends a count as a varint.
    pub(crate) fn put_count(&mut self, n: usize) -> Result<(), EncodeError> {
        self.put(&(n as u64))
    }

    /// Appends a byte string: its length as a varint, then the bytes (bincode's layout of a
    /// `Vec<u8>`).
    pub(crate) fn put_bytes(&mut self, bytes: &[u8]) -> Result<(), EncodeError> {
        self.put_count(bytes.len())?;
        self.bytes.extend_from_slice(bytes);
        Ok(())
    }

    /// The payload.
    pub(crate) fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }
}

/// Reads items one after another from a section payload.
pub(crate) struct Reader<'a> {
    tag: Tag,
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    /// A reader over the raw payload of section `tag`.
    pub(crate) fn new(tag: Tag, bytes: &'a [u8]) -> Reader<'a> {
        Reader { tag, bytes }
    }

    /// A format error in this section.
    pub(crate) fn error(&self, what: &'static str) -> DecodeError {
        DecodeError::Format {
            section: Some(self.tag),
            what,
        }
    }

    /// Reads one item; `what` names the rule a malformed item breaks.
    pub(crate) fn get<T: DeserializeOwned>(
        &mut self,
        what: &'static str,
    ) -> Result<T, DecodeError> {
        let (value, used) = bincode::serde::decode_from_slice::<T, _>(self.bytes, config())
            .map_err(|_| self.error(what))?;
        self.bytes = self.bytes.get(used..).ok_or_else(|| self.error(what))?;
        Ok(value)
    }

    /// Reads a count, checks it against `max` (the reader's limit, `limit_name`) and against
    /// the bytes left at `min_item_bytes` per item, and returns it.
    pub(crate) fn count(
        &mut self,
        limit_name: &'static str,
        max: u64,
        min_item_bytes: u64,
    ) -> Result<usize, DecodeError> {
        self.count_more(limit_name, 0, max, min_item_bytes)
    }

    /// Like [`Reader::count`] for a total kept across several counts: `used` items were
    /// counted before, and `used + count` must not exceed `max`.
    pub(crate) fn count_more(
        &mut self,
        limit_name: &'static str,
        used: u64,
        max: u64,
        min_item_bytes: u64,
    ) -> Result<usize, DecodeError> {
        let n: u64 = self.get("X1: count is not a varint")?;
        check(limit_name, used.saturating_add(n), max)?;
        if n.saturating_mul(min_item_bytes) > self.bytes.len() as u64 {
            return Err(self.error("X2: count exceeds the bytes left"));
        }
        usize::try_from(n).map_err(|_| self.error("X2: count exceeds the address space"))
    }

    /// Reads a byte string written by [`Writer::put_bytes`], checking its length against the
    /// bytes left; borrows it without copying.
    pub(crate) fn bytes(&mut self, what: &'static str) -> Result<&'a [u8], DecodeError> {
        let n: u64 = self.get(what)?;
        let n = usize::try_from(n)
            .ok()
            .filter(|&n| n <= self.bytes.len())
            .ok_or_else(|| self.error("X2: count exceeds the bytes left"))?;
        let (head, tail) = self.bytes.split_at(n);
        self.bytes = tail;
        Ok(head)
    }

    /// Bytes not read yet.
    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len()
    }
}
