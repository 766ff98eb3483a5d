//! Raw bytes, header included, into the decoder with small limits: it must return, never
//! panic, and whatever it accepts must be a valid representation that encodes again.
//!
//! The bytes are decoded twice: as given, and with their CRC-32 fields recomputed so that
//! mutations reach the section parsers instead of stopping at a checksum. Nothing else is
//! repaired: magic, versions, flags, lengths and payloads stay the fuzzer's.
#![no_main]

use ellip::format::{self, EncodeOptions, Limits};
use libfuzzer_sys::fuzz_target;

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
    let limits = Limits::small();
    let decoded = format::decode(data, &limits);
    let summary = format::inspect(data, &limits);
    assert_eq!(decoded.is_ok(), summary.is_ok());
    if let (Ok(rep), Ok(summary)) = (decoded, summary) {
        assert!(rep.validate().is_ok());
        let options = EncodeOptions {
            bits: summary.grid.bits,
        };
        let bytes = format::encode(&rep, &options).expect("a decoded representation encodes");
        let again = format::decode(&bytes, &Limits::default()).expect("and decodes");
        assert_eq!(again.arcs, rep.arcs);
        assert_eq!(again.cycles, rep.cycles);
    }
}

fuzz_target!(|data: &[u8]| {
    check(data);
    check(&fix_checksums(data));
});
