//! Raw bytes, header included, into the decoder with small limits: it must return, never
//! panic, and whatever it accepts must be a valid representation that encodes again.
#![no_main]

use ellip::format::{self, EncodeOptions, Limits};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
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
});
