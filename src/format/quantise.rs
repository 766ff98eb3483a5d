//! The point grid (spec §6.4): each axis of the points' bounding box divided into
//! N = 2^B − 1 equal steps.
//!
//! Decoding is exact and normative: with t = q / N, a coordinate is min·(1 − t) + max·t in
//! IEEE-754 binary64, so q = 0 gives min and q = N gives max bit for bit, and re-encoding a
//! decoded file finds the same box and the same grid indices.

use glam::DVec3;

/// A quantisation grid over a box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Bits per axis, B.
    pub bits: u8,
    /// Smallest coordinates (q = 0).
    pub min: DVec3,
    /// Largest coordinates (q = N).
    pub max: DVec3,
}

impl Grid {
    /// The grid with `bits` per axis over the bounding box of `points` (the zero box when
    /// there are none).
    pub fn around(points: &[DVec3], bits: u8) -> Grid {
        let (min, max) = match points.first() {
            None => (DVec3::ZERO, DVec3::ZERO),
            Some(&p) => points
                .iter()
                .fold((p, p), |(lo, hi), &q| (lo.min(q), hi.max(q))),
        };
        Grid { bits, min, max }
    }

    /// N = 2^B − 1, the largest grid index.
    pub fn levels(&self) -> u32 {
        let b = u32::from(self.bits.min(31));
        (1u32 << b) - 1
    }

    /// Grid step per axis, (max − min) / N.
    pub fn step(&self) -> DVec3 {
        (self.max - self.min) / f64::from(self.levels().max(1))
    }

    /// Worst-case distance between a point and its decoded grid position: half a step per
    /// axis, ½·|step| in 3D (√3/2 of a step on a cube).
    pub fn error_bound(&self) -> f64 {
        0.5 * self.step().length()
    }

    /// Grid indices of `p` (nearest level, clamped to [0, N]).
    pub fn quantise(&self, p: DVec3) -> [u32; 3] {
        let n = self.levels();
        let axis = |x: f64, lo: f64, hi: f64| -> u32 {
            if hi <= lo || hi.is_nan() || lo.is_nan() {
                return 0;
            }
            let t = ((x - lo) / (hi - lo) * f64::from(n)).round();
            // Clamped in f64 first, so the cast cannot overflow; NaN maps to 0.
            if t >= 0.0 {
                t.min(f64::from(n)) as u32
            } else {
                0
            }
        };
        [
            axis(p.x, self.min.x, self.max.x),
            axis(p.y, self.min.y, self.max.y),
            axis(p.z, self.min.z, self.max.z),
        ]
    }

    /// The point at grid indices `q` (spec §6.4, normative).
    pub fn dequantise(&self, q: [u32; 3]) -> DVec3 {
        let n = f64::from(self.levels().max(1));
        let axis = |q: u32, lo: f64, hi: f64| {
            let t = f64::from(q) / n;
            lo * (1.0 - t) + hi * t
        };
        DVec3::new(
            axis(q[0], self.min.x, self.max.x),
            axis(q[1], self.min.y, self.max.y),
            axis(q[2], self.min.z, self.max.z),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_ends_are_exact_and_indices_round_trip() {
        let pts = [DVec3::new(-1.3, 0.2, 5.0), DVec3::new(2.7, 0.2, 11.5)];
        for bits in [1u8, 8, 12, 16, 24] {
            let g = Grid::around(&pts, bits);
            assert_eq!(g.dequantise(g.quantise(pts[0])), pts[0]);
            assert_eq!(g.dequantise(g.quantise(pts[1])), pts[1]);
            let n = g.levels();
            for q in [0, 1, n / 3, n / 2, n.saturating_sub(1), n] {
                let p = g.dequantise([q, 0, q]);
                assert_eq!(g.quantise(p), [q, 0, q]);
                assert_eq!(g, Grid::around(&[g.min, g.max, p], bits));
            }
        }
    }

    #[test]
    fn quantisation_error_is_within_half_a_step() {
        let g = Grid {
            bits: 10,
            min: DVec3::new(-1.0, -2.0, 0.0),
            max: DVec3::new(1.0, 3.0, 0.5),
        };
        let half = g.step() * 0.5;
        for i in 0..1000 {
            let t = i as f64 / 999.0;
            let p = g.min + (g.max - g.min) * DVec3::new(t, (t * 7.3).fract(), (t * 3.1).fract());
            let d = (g.dequantise(g.quantise(p)) - p).abs();
            assert!(d.cmple(half * (1.0 + 1e-9)).all(), "{d} > {half}");
            assert!(d.length() <= g.error_bound() * (1.0 + 1e-9));
        }
    }
}
