//! Bit streams (spec §5.1): fixed-width fields and adaptive Golomb–Rice codes, packed least
//! significant bit first.
//!
//! Byte-granular varints spend 8 or 24 bits on values that need 6 to 16; the two payloads
//! that hold many such values — quantised ellipsoids (`ELPS` variant 2) and the point
//! residuals (`PNTS`) — are bit streams instead. The Rice parameter adapts per context as in
//! LOCO-I / JPEG-LS (Weinberger, Seroussi & Sapiro 2000): k is the smallest integer with
//! N·2^k ≥ A, A the sum and N the count of the values seen, both halved every 32 values.

/// Zero bits that announce an escaped value (spec §5.1): the quotient would be ≥ this.
pub(crate) const RICE_ESCAPE: u32 = 20;
/// Largest Rice parameter.
const RICE_MAX_K: u32 = 24;
/// Count at which a context's sum and count are halved.
const RICE_RESET: u64 = 32;

/// Writes bits least significant first; the last byte is padded with zeros.
#[derive(Debug, Default)]
pub(crate) struct BitWriter {
    bytes: Vec<u8>,
    acc: u64,
    filled: u32,
}

impl BitWriter {
    /// An empty stream.
    pub(crate) fn new() -> BitWriter {
        BitWriter::default()
    }

    /// Appends the `count` (≤ 32) low bits of `value`, least significant first.
    pub(crate) fn put(&mut self, value: u32, count: u32) {
        debug_assert!(count <= 32);
        let mask = if count == 32 {
            u64::from(u32::MAX)
        } else {
            (1u64 << count) - 1
        };
        self.acc |= (u64::from(value) & mask) << self.filled;
        self.filled += count;
        while self.filled >= 8 {
            self.bytes.push(self.acc as u8);
            self.acc >>= 8;
            self.filled -= 8;
        }
    }

    /// The stream, padded to whole bytes.
    pub(crate) fn finish(mut self) -> Vec<u8> {
        if self.filled > 0 {
            self.bytes.push(self.acc as u8);
        }
        self.bytes
    }
}

/// Reads what [`BitWriter`] wrote; every read is checked against the bytes there are.
#[derive(Debug)]
pub(crate) struct BitReader<'a> {
    bytes: &'a [u8],
    /// Bits consumed.
    position: u64,
}

impl<'a> BitReader<'a> {
    /// A reader at the first bit of `bytes`.
    pub(crate) fn new(bytes: &'a [u8]) -> BitReader<'a> {
        BitReader { bytes, position: 0 }
    }

    /// Bits not read yet.
    pub(crate) fn remaining(&self) -> u64 {
        (self.bytes.len() as u64 * 8).saturating_sub(self.position)
    }

    /// The next `count` (≤ 32) bits as an unsigned value; `None` past the end.
    pub(crate) fn get(&mut self, count: u32) -> Option<u32> {
        if count > 32 || u64::from(count) > self.remaining() {
            return None;
        }
        let mut value = 0u64;
        let mut got = 0u32;
        while got < count {
            let byte = *self.bytes.get((self.position / 8) as usize)?;
            let offset = (self.position % 8) as u32;
            let take = (8 - offset).min(count - got);
            let bits = (u64::from(byte) >> offset) & ((1u64 << take) - 1);
            value |= bits << got;
            got += take;
            self.position += u64::from(take);
        }
        u32::try_from(value).ok()
    }

    /// Whether the stream ends here: fewer than 8 bits are left and they are all zero
    /// (spec §5.1: no trailing bytes, zero padding).
    pub(crate) fn is_at_padded_end(&self) -> bool {
        if self.remaining() >= 8 {
            return false;
        }
        let offset = (self.position % 8) as u32;
        if offset == 0 {
            return true;
        }
        self.bytes
            .last()
            .is_some_and(|&b| u32::from(b) >> offset == 0)
    }
}

/// Zig-zag map of a signed value.
pub(crate) fn zigzag(v: i32) -> u32 {
    ((v << 1) ^ (v >> 31)) as u32
}

/// Inverse of [`zigzag`].
pub(crate) fn unzigzag(v: u32) -> i32 {
    ((v >> 1) as i32) ^ -((v & 1) as i32)
}

/// Bits needed to write `v`: 0 for 0, else ⌊log2 v⌋ + 1.
pub(crate) fn bit_length(v: u64) -> u32 {
    64 - v.leading_zeros()
}

/// The adaptive state of one Rice context (spec §5.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct RiceContext {
    sum: u64,
    count: u64,
}

impl Default for RiceContext {
    fn default() -> RiceContext {
        RiceContext { sum: 8, count: 1 }
    }
}

impl RiceContext {
    /// The current parameter: the smallest k ≤ 24 with count·2^k ≥ sum.
    fn k(&self) -> u32 {
        let mut k = 0;
        while k < RICE_MAX_K && (self.count << k) < self.sum {
            k += 1;
        }
        k
    }

    fn update(&mut self, v: u32) {
        self.sum += u64::from(v);
        self.count += 1;
        if self.count == RICE_RESET {
            self.sum >>= 1;
            self.count >>= 1;
        }
    }

    /// Writes `v`: the quotient v >> k in unary (that many 0 bits, then a 1 bit) and the k low
    /// bits; a quotient ≥ [`RICE_ESCAPE`] as that many 0 bits and then v in 32 bits.
    pub(crate) fn put(&mut self, w: &mut BitWriter, v: u32) {
        let k = self.k();
        let q = v >> k;
        if q < RICE_ESCAPE {
            w.put(0, q);
            w.put(1, 1);
            w.put(v, k);
        } else {
            w.put(0, RICE_ESCAPE);
            w.put(v, 32);
        }
        self.update(v);
    }

    /// Reads a value written by [`RiceContext::put`]; `None` past the end.
    pub(crate) fn get(&mut self, r: &mut BitReader<'_>) -> Option<u32> {
        let k = self.k();
        let mut q = 0;
        while q < RICE_ESCAPE {
            if r.get(1)? == 1 {
                break;
            }
            q += 1;
        }
        let v = if q == RICE_ESCAPE {
            r.get(32)?
        } else {
            // q < 20 and k ≤ 24: q·2^k + low < 2^29.
            (q << k) | r.get(k)?
        };
        self.update(v);
        Some(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    #[test]
    fn fixed_width_fields_round_trip_least_significant_bit_first() {
        let mut w = BitWriter::new();
        w.put(0b101, 3);
        w.put(0xdead_beef, 32);
        w.put(zigzag(-5), 7);
        w.put(1, 1);
        let bytes = w.finish();
        // 3 + 32 + 7 + 1 = 43 bits: 6 bytes, the first holding 0b101 in its low bits.
        assert_eq!(bytes.len(), 6);
        assert_eq!(bytes[0] & 0b111, 0b101);
        let mut r = BitReader::new(&bytes);
        assert_eq!(r.get(3), Some(0b101));
        assert_eq!(r.get(32), Some(0xdead_beef));
        assert_eq!(r.get(7).map(unzigzag), Some(-5));
        assert_eq!(r.get(1), Some(1));
        assert!(r.is_at_padded_end());
        assert_eq!(r.get(8), None);
    }

    #[test]
    fn zigzag_is_a_bijection_on_i32() {
        for v in [0, 1, -1, 2, -2, i32::MAX, i32::MIN, 12345, -12345] {
            assert_eq!(unzigzag(zigzag(v)), v);
        }
        assert_eq!(zigzag(-1), 1);
        assert_eq!(zigzag(1), 2);
    }

    #[test]
    fn rice_codes_round_trip_and_adapt() {
        let mut rng = SplitMix64::new(3);
        // Small values, then large ones, then escapes and extremes.
        let mut values: Vec<u32> = (0..500).map(|_| (rng.next_u64() % 16) as u32).collect();
        values.extend((0..500).map(|_| (rng.next_u64() % 5000) as u32));
        values.extend([u32::MAX, 0, 1 << 31, 7, 1 << 25, 0, 0]);
        let mut w = BitWriter::new();
        let mut ctx = RiceContext::default();
        for &v in &values {
            ctx.put(&mut w, v);
        }
        let bytes = w.finish();
        let mut r = BitReader::new(&bytes);
        let mut ctx = RiceContext::default();
        for &v in &values {
            assert_eq!(ctx.get(&mut r), Some(v));
        }
        assert!(r.is_at_padded_end());
        // Adaptive: the small values cost about log2(16) + 1 bits each, well under a byte.
        let mut w = BitWriter::new();
        let mut ctx = RiceContext::default();
        for &v in &values[..500] {
            ctx.put(&mut w, v);
        }
        let bits = w.finish().len() * 8;
        assert!(bits < 500 * 6, "{bits} bits for 500 values below 16");
    }

    #[test]
    fn truncated_and_garbage_streams_end_in_none_never_a_panic() {
        let mut rng = SplitMix64::new(9);
        for len in 0..64 {
            let bytes: Vec<u8> = (0..len).map(|_| rng.next_u64() as u8).collect();
            let mut r = BitReader::new(&bytes);
            let mut ctx = RiceContext::default();
            let mut n = 0;
            while ctx.get(&mut r).is_some() {
                n += 1;
                assert!(n <= 8 * len, "every value consumes at least one bit");
            }
        }
        let mut r = BitReader::new(&[]);
        assert_eq!(r.get(0), Some(0));
        assert_eq!(r.get(1), None);
        assert_eq!(r.get(33), None);
        assert!(r.is_at_padded_end());
        // Padding must be zero.
        let mut r = BitReader::new(&[0b1000_0001]);
        assert_eq!(r.get(1), Some(1));
        assert!(!r.is_at_padded_end());
    }
}
