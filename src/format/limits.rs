//! What a decoder is willing to allocate (spec §9, "recommended decoder defaults").

use super::error::DecodeError;

/// Caps on what [`decode`](super::decode) reads, each checked before the allocation it
/// guards. The defaults are the recommendations of `spec/ELLIP.md` §9; a decoder's memory
/// stays within a small multiple of `max_inflated_bytes` plus 24 bytes per point and 4 bytes
/// per arc point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest file, in bytes. Default 64 MiB.
    pub max_file_bytes: u64,
    /// Most sections. Default 64.
    pub max_sections: u32,
    /// Largest sum of the raw (inflated) lengths of the sections read. Default 128 MiB.
    pub max_inflated_bytes: u64,
    /// Most regions (ellipsoids). Default 65 536.
    pub max_regions: u64,
    /// Most pool points. Default 4 194 304 (2²²).
    pub max_points: u64,
    /// Most arcs. Default 1 048 576 (2²⁰).
    pub max_arcs: u64,
    /// Most arc points, summed over all arcs. Default 8 388 608 (2²³).
    pub max_arc_points: u64,
    /// Most cycles, summed over all regions. Default 2 097 152 (2²¹).
    pub max_cycles: u64,
    /// Most arc references, summed over all cycles. Default 4 194 304 (2²²).
    pub max_cycle_refs: u64,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_file_bytes: 64 << 20,
            max_sections: 64,
            max_inflated_bytes: 128 << 20,
            max_regions: 1 << 16,
            max_points: 1 << 22,
            max_arcs: 1 << 20,
            max_arc_points: 1 << 23,
            max_cycles: 1 << 21,
            max_cycle_refs: 1 << 22,
        }
    }
}

impl Limits {
    /// Small limits for fuzzing and for untrusted input in constrained places: 1 MiB files,
    /// 4 MiB inflated, 65 536 points.
    pub fn small() -> Limits {
        Limits {
            max_file_bytes: 1 << 20,
            max_sections: 16,
            max_inflated_bytes: 4 << 20,
            max_regions: 1 << 10,
            max_points: 1 << 16,
            max_arcs: 1 << 14,
            max_arc_points: 1 << 17,
            max_cycles: 1 << 15,
            max_cycle_refs: 1 << 16,
        }
    }
}

/// `Err(LimitsExceeded)` unless `requested <= max`.
pub(crate) fn check(what: &'static str, requested: u64, max: u64) -> Result<(), DecodeError> {
    if requested <= max {
        Ok(())
    } else {
        Err(DecodeError::LimitsExceeded {
            what,
            requested,
            max,
        })
    }
}
