//! Quantisation: the point grid (spec §6.4) and the error-bounded ellipsoid (spec §6.2,
//! variant 2).
//!
//! The grid divides each axis of the points' bounding box into N = 2^B − 1 equal steps.
//! Decoding is exact and normative: with t = q / N, a coordinate is min·(1 − t) + max·t in
//! IEEE-754 binary64, so q = 0 gives min and q = N gives max bit for bit, and re-encoding a
//! decoded file finds the same box and the same grid indices.
//!
//! A quantised ellipsoid stores its centre and radii as integer multiples of h = 2^e and its
//! rotation as three quaternion components in multiples of 2^−s (the fourth, the largest, is
//! implied). Decoding is exact too (integers times powers of two), so a decoded ellipsoid
//! quantises to the same integers again.

use super::bits::{bit_length, BitReader, BitWriter};
use crate::ellipsoid::{Ellipsoid, Sign};
use glam::{DQuat, DVec3};

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

/// 2^e exactly, for e in the binary64 normal range.
fn power_of_two(e: i32) -> f64 {
    f64::from_bits(((e + 1023).clamp(1, 2046) as u64) << 52)
}

/// Smallest rotation shift s the encoder uses: steps of 2^−8 at the coarsest.
const MIN_ROTATION_SHIFT: i32 = 8;

/// Bits of a field width in the stream.
const WIDTH_BITS: u32 = 5;

/// An ellipsoid in integers (spec §6.2, variant 2): centre = C·2^e, radii = R·2^e, and the
/// rotation's three smaller quaternion components Q·2^−s; the component at `largest` is
/// √(1 − Σ(Q·2^−s)²) ≥ 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct QuantisedEllipsoid {
    pub(crate) negative: bool,
    pub(crate) exponent: i8,
    pub(crate) center: [i32; 3],
    pub(crate) radii: [u32; 3],
    pub(crate) largest: u8,
    pub(crate) shift: u8,
    pub(crate) rotation: [i32; 3],
}

/// The index of the largest |component| of (x, y, z, w), the lowest on ties.
fn largest_component(q: [f64; 4]) -> usize {
    (1..4).fold(0, |m, i| if q[i].abs() > q[m].abs() { i } else { m })
}

impl QuantisedEllipsoid {
    /// The coarsest quantisation whose surface displacement bound
    /// ([`QuantisedEllipsoid::error_bound`]) is at most `tolerance`; `None` when no field
    /// width up to 31 bits reaches it (the caller then stores binary32 or binary64).
    ///
    /// The budget is split in two halves: position (centre and radii, (√3/2 + 1/2)·h ≤ ε/2)
    /// and rotation (4·2^−s·r_max ≤ ε/2).
    pub(crate) fn from_ellipsoid(e: &Ellipsoid, tolerance: f64) -> Option<QuantisedEllipsoid> {
        if !(tolerance > 0.0 && tolerance.is_finite() && e.is_valid()) {
            return None;
        }
        let exponent = (tolerance / 2.74).log2().floor();
        if !(-126.0..=127.0).contains(&exponent) {
            return None;
        }
        let exponent = exponent as i32;
        let h = power_of_two(exponent);
        let to_int = |x: f64| -> Option<i64> {
            let v = (x / h).round();
            (v.abs() < f64::from(1u32 << 30)).then_some(v as i64)
        };
        let mut center = [0i32; 3];
        for (c, &x) in center.iter_mut().zip(&e.center.to_array()) {
            *c = i32::try_from(to_int(x)?).ok()?;
        }
        let mut radii = [0u32; 3];
        for (r, &x) in radii.iter_mut().zip(&e.radii.to_array()) {
            *r = u32::try_from(to_int(x)?.max(1)).ok()?;
        }
        let r_max = f64::from(radii.iter().copied().max().unwrap_or(1)) * h;
        let shift = ((8.0 * r_max / tolerance).log2().ceil() as i32).max(MIN_ROTATION_SHIFT);
        if shift > 31 {
            return None;
        }
        let q = if (e.rotation.length_squared() - 1.0).abs() > 1e-6 {
            e.rotation.normalize()
        } else {
            e.rotation
        }
        .to_array();
        // Try the components from the largest down: the first whose decoded quaternion has
        // it as its largest component again (so that re-encoding picks it too).
        let mut order = [0usize, 1, 2, 3];
        order.sort_by(|&a, &b| q[b].abs().total_cmp(&q[a].abs()).then(a.cmp(&b)));
        let scale = power_of_two(shift);
        for m in order {
            let sign = if q[m] < 0.0 { -1.0 } else { 1.0 };
            let mut rotation = [0i32; 3];
            let mut ok = true;
            for (slot, i) in (0..4).filter(|&i| i != m).enumerate() {
                let v = (sign * q[i] * scale).round();
                if v.abs() >= f64::from(1u32 << 30) {
                    ok = false;
                    break;
                }
                rotation[slot] = v as i32;
            }
            let candidate = QuantisedEllipsoid {
                negative: e.sign == Sign::Negative,
                exponent: exponent as i8,
                center,
                radii,
                largest: m as u8,
                shift: shift as u8,
                rotation,
            };
            if !ok {
                continue;
            }
            let Some(decoded) = candidate.to_ellipsoid() else {
                continue;
            };
            if largest_component(decoded.rotation.to_array()) == m
                && candidate.error_bound() <= tolerance
            {
                return Some(candidate);
            }
        }
        None
    }

    /// The ellipsoid (spec §6.2, normative): exact products of integers and powers of two;
    /// the implied component √(1 − ((a² + b²) + c²)) in binary64. `None` when a radius is 0
    /// (rule E2) or the three components' squares sum above 1 (rule E4).
    pub(crate) fn to_ellipsoid(self) -> Option<Ellipsoid> {
        let h = power_of_two(i32::from(self.exponent));
        let step = power_of_two(-i32::from(self.shift));
        if self.radii.contains(&0) {
            return None;
        }
        let v = self.rotation.map(|x| f64::from(x) * step);
        let sum = (v[0] * v[0] + v[1] * v[1]) + v[2] * v[2];
        if sum > 1.0 {
            return None;
        }
        let implied = (1.0 - sum).sqrt();
        let m = usize::from(self.largest.min(3));
        let mut q = [0.0; 4];
        let mut others = v.iter();
        for (i, slot) in q.iter_mut().enumerate() {
            *slot = if i == m {
                implied
            } else {
                *others.next().unwrap_or(&0.0)
            };
        }
        Some(Ellipsoid {
            center: DVec3::from_array(self.center.map(|c| f64::from(c) * h)),
            rotation: DQuat::from_array(q),
            radii: DVec3::from_array(self.radii.map(|r| f64::from(r) * h)),
            sign: if self.negative {
                Sign::Negative
            } else {
                Sign::Positive
            },
        })
    }

    /// Worst-case surface displacement against any ellipsoid that quantises to this one
    /// (spec §6.2): (√3/2 + 1/2)·2^e for centre and radii, 4·2^−s·r_max for the rotation.
    pub(crate) fn error_bound(&self) -> f64 {
        let h = power_of_two(i32::from(self.exponent));
        let r_max = f64::from(self.radii.iter().copied().max().unwrap_or(0)) * h;
        (0.75f64.sqrt() + 0.5) * h + 4.0 * power_of_two(-i32::from(self.shift)) * r_max
    }

    /// Appends the stream of spec §6.2: negative (1 bit), e (8 bits, two's complement),
    /// then centre, radii and rotation each as a 5-bit width W and three W-bit fields (centre
    /// and rotation zig-zag mapped), with the 2-bit `largest` and the 5-bit s before the
    /// rotation's width.
    pub(crate) fn write(&self, w: &mut BitWriter) {
        w.put(u32::from(self.negative), 1);
        w.put(u32::from(self.exponent as u8), 8);
        let zig = self.center.map(super::bits::zigzag);
        put_fields(w, &zig);
        put_fields(w, &self.radii);
        w.put(u32::from(self.largest), 2);
        w.put(u32::from(self.shift), WIDTH_BITS);
        put_fields(w, &self.rotation.map(super::bits::zigzag));
    }

    /// Reads what [`QuantisedEllipsoid::write`] wrote; `None` past the end.
    pub(crate) fn read(r: &mut BitReader<'_>) -> Option<QuantisedEllipsoid> {
        let negative = r.get(1)? == 1;
        let exponent = r.get(8)? as u8 as i8;
        let center = get_fields(r)?.map(super::bits::unzigzag);
        let radii = get_fields(r)?;
        let largest = r.get(2)? as u8;
        let shift = r.get(WIDTH_BITS)? as u8;
        let rotation = get_fields(r)?.map(super::bits::unzigzag);
        Some(QuantisedEllipsoid {
            negative,
            exponent,
            center,
            radii,
            largest,
            shift,
            rotation,
        })
    }
}

/// A 5-bit width W (the bit length of the largest value, at most 31 here), then the values
/// in W bits each.
fn put_fields(w: &mut BitWriter, values: &[u32; 3]) {
    let width = values
        .iter()
        .map(|&v| bit_length(u64::from(v)))
        .max()
        .unwrap_or(0)
        .min(31);
    w.put(width, WIDTH_BITS);
    for &v in values {
        w.put(v, width);
    }
}

fn get_fields(r: &mut BitReader<'_>) -> Option<[u32; 3]> {
    let width = r.get(WIDTH_BITS)?;
    Some([r.get(width)?, r.get(width)?, r.get(width)?])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    fn random_ellipsoid(rng: &mut SplitMix64) -> Ellipsoid {
        let axis = rng.unit_vector();
        Ellipsoid {
            center: DVec3::new(
                rng.range_f64(-2.0, 2.0),
                rng.range_f64(-2.0, 2.0),
                rng.range_f64(-2.0, 2.0),
            ),
            rotation: DQuat::from_axis_angle(axis, rng.range_f64(-3.2, 3.2)),
            radii: DVec3::new(
                rng.range_f64(0.01, 1.0),
                rng.range_f64(0.01, 3.0),
                rng.range_f64(0.01, 1.0) * if rng.below(4) == 0 { 1e3 } else { 1.0 },
            ),
            sign: if rng.below(2) == 0 {
                Sign::Positive
            } else {
                Sign::Negative
            },
        }
    }

    #[test]
    fn quantised_ellipsoids_move_the_surface_within_the_bound_and_requantise_exactly() {
        let mut rng = SplitMix64::new(11);
        let mut stored = 0;
        for i in 0..400 {
            let e = random_ellipsoid(&mut rng);
            let tolerance = 10f64.powf(rng.range_f64(-7.0, -2.0));
            let Some(q) = QuantisedEllipsoid::from_ellipsoid(&e, tolerance) else {
                // Only radii of 10³ with tight tolerances overflow 31-bit fields.
                assert!(
                    e.radii.max_element() / tolerance > 1e8,
                    "{i}: {e:?} {tolerance}"
                );
                continue;
            };
            stored += 1;
            assert!(q.error_bound() <= tolerance);
            let d = q.to_ellipsoid().unwrap();
            assert_eq!(d.sign, e.sign);
            assert!((d.rotation.length_squared() - 1.0).abs() < 1e-12);
            // The displacement of corresponding surface points, sampled.
            let mut worst = 0.0f64;
            for _ in 0..200 {
                let u = rng.unit_vector();
                worst = worst.max((e.from_unit_sphere(u) - d.from_unit_sphere(u)).length());
            }
            assert!(
                worst <= q.error_bound(),
                "{i}: {worst} > {}",
                q.error_bound()
            );
            // Decoded values quantise to the same integers.
            assert_eq!(QuantisedEllipsoid::from_ellipsoid(&d, tolerance), Some(q));
            // And the stream round-trips.
            let mut w = BitWriter::new();
            q.write(&mut w);
            let bytes = w.finish();
            let mut r = BitReader::new(&bytes);
            assert_eq!(QuantisedEllipsoid::read(&mut r), Some(q));
            assert!(r.is_at_padded_end());
        }
        assert!(stored > 300, "{stored}");
    }

    #[test]
    fn a_typical_region_costs_about_twenty_bytes() {
        let e = Ellipsoid {
            center: DVec3::new(0.1, -0.2, 0.3),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.4, -1.0, 2.0),
            radii: DVec3::new(0.2, 0.35, 0.1),
            sign: Sign::Positive,
        };
        // A 12-bit grid's error bound on a unit diagonal.
        let q = QuantisedEllipsoid::from_ellipsoid(&e, 1.0 / 8190.0).unwrap();
        let mut w = BitWriter::new();
        q.write(&mut w);
        let bytes = w.finish().len();
        assert!((14..=22).contains(&bytes), "{bytes} bytes");
    }

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
