//! Raw bytes → `format::decode` with small limits → `remesh` with a small vertex budget, then
//! one level of `remesh::subdivide`: every file the decoder accepts must remesh to a mesh or
//! to a typed error, never panic or hang (issue 6, item 9).
//!
//! As in the `decode` target, the bytes are tried as given and with their CRC-32 fields
//! recomputed, so that mutations reach the geometry instead of stopping at a checksum.
#![no_main]

use ellip::format::{self, Limits};
use ellip::remesh::{RemeshOptions, Scheme};
use libfuzzer_sys::fuzz_target;

#[path = "remeshed.rs"]
mod remeshed;

/// Recomputes the header CRC and the CRC of every section whose framing fits in `bytes`.
fn fix_checksums(bytes: &[u8]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    if b.len() < 28 {
        return b;
    }
    let crc = crc32fast::hash(&b[..24]);
    b[24..28].copy_from_slice(&crc.to_le_bytes());
    let mut at = 28usize;
    while at + 16 <= b.len() {
        let stored = u32::from_le_bytes([b[at + 8], b[at + 9], b[at + 10], b[at + 11]]) as usize;
        let Some(end) = (at + 16).checked_add(stored) else {
            break;
        };
        if end + 4 > b.len() {
            break;
        }
        let crc = crc32fast::hash(&b[at..end]);
        b[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        at = end + 4;
    }
    b
}

fn check(data: &[u8]) {
    let Ok(rep) = format::decode(data, &Limits::small()) else {
        return;
    };
    // The last byte chooses the scheme, so both are reached.
    let scheme = if data.last().is_some_and(|b| b & 1 == 1) {
        Scheme::Parametric
    } else {
        Scheme::Adaptive
    };
    let options = RemeshOptions {
        vertices: Some(2_000),
        tolerance: None,
        scheme,
        max_vertices: 100_000,
        subdivision: true,
        leave_out: true,
    };
    remeshed::check_remesh(&rep, &options);
}

fuzz_target!(|data: &[u8]| {
    check(data);
    check(&fix_checksums(data));
});
