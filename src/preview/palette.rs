//! Region colours: the palette `ellip segment`, `ellip decode --colors` and `ellip preview`
//! share, so that region `i` has the same colour everywhere.

/// A palette colour: its sRGB bytes (and its OKLab coordinates, for distances).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Color {
    srgb: [u8; 3],
    /// The colour in OKLab, for distances.
    lab: [f64; 3],
}

impl Color {
    /// The colour's sRGB bytes.
    pub fn srgb(&self) -> [u8; 3] {
        self.srgb
    }

    /// The colour's sRGB bytes, opaque.
    pub fn srgb_rgba(&self) -> [u8; 4] {
        let [r, g, b] = self.srgb;
        [r, g, b, 255]
    }

    /// glTF's `COLOR_0` is linear (glTF 2.0, section 3.7.2.1): the sRGB colour decoded.
    pub fn linear_rgba(&self) -> [u8; 4] {
        let [r, g, b] = self.srgb.map(|c| to_byte(decode_srgb(c)));
        [r, g, b, 255]
    }
}

/// `count` well-separated colours, the same first ones whatever the count.
///
/// Farthest-point sampling in OKLab (Ottosson 2020, a perceptually uniform space): from a
/// fixed set of in-gamut candidates of moderate lightness (light enough to shade, dark
/// enough to see on white), start with a coral and repeatedly take the candidate farthest
/// from every colour taken so far (first on ties). Past the candidates, colours repeat.
pub fn palette(count: usize) -> Vec<Color> {
    let (candidates, start) = palette_candidates();
    let mut chosen: Vec<usize> = Vec::new();
    // Distance from each candidate to the nearest chosen colour.
    let mut nearest = vec![f64::INFINITY; candidates.len()];
    let mut next = Some(start);
    while chosen.len() < count.min(candidates.len()) {
        let Some(pick) = next else { break };
        chosen.push(pick);
        let Some(picked) = candidates.get(pick) else {
            break;
        };
        for (d, c) in nearest.iter_mut().zip(&candidates) {
            *d = d.min(lab_distance(&c.lab, &picked.lab));
        }
        next = nearest
            .iter()
            .enumerate()
            .fold(None, |best: Option<(usize, f64)>, (i, &d)| match best {
                Some((_, bd)) if bd >= d => best,
                _ => Some((i, d)),
            })
            .map(|(i, _)| i);
    }
    (0..count)
        .filter_map(|i| {
            let k = chosen.get(i % chosen.len().max(1))?;
            candidates.get(*k).copied()
        })
        .collect()
}

/// In-gamut sRGB colours on an OKLCH lattice: lightness 0.5–0.9, chroma 0.05–0.17, hue every
/// 10°; and the index of the coral the palette starts from (L 0.7, C 0.13, h 30°).
fn palette_candidates() -> (Vec<Color>, usize) {
    let mut out = Vec::new();
    let mut start = 0;
    for li in 0..5 {
        let l = 0.5 + 0.1 * f64::from(li);
        for ci in 0..4 {
            let c = 0.05 + 0.04 * f64::from(ci);
            for hi in 0..36 {
                let h = (10.0 * f64::from(hi)).to_radians();
                let linear = oklab_to_linear_srgb([l, c * h.cos(), c * h.sin()]);
                if linear.iter().all(|x| (0.0..=1.0).contains(x)) {
                    if (li, ci, hi) == (2, 2, 3) {
                        start = out.len();
                    }
                    out.push(from_srgb(linear.map(|x| to_byte(encode_srgb(x)))));
                }
            }
        }
    }
    (out, start)
}

/// An sRGB byte as a linear intensity in [0, 1] (IEC 61966-2-1).
pub fn decode_srgb(c: u8) -> f64 {
    let x = f64::from(c) / 255.0;
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

fn from_srgb(srgb: [u8; 3]) -> Color {
    let linear = srgb.map(decode_srgb);
    Color {
        srgb,
        lab: linear_srgb_to_oklab(linear),
    }
}

/// A linear intensity in [0, 1] as an sRGB value in [0, 1] (IEC 61966-2-1).
pub fn encode_srgb(x: f64) -> f64 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// A value in [0, 1] as a byte, rounded (clamped first).
pub fn to_byte(x: f64) -> u8 {
    let scaled = (x.clamp(0.0, 1.0) * 255.0).round();
    // In 0..=255 after the clamp.
    scaled as u8
}

fn lab_distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// OKLab → linear sRGB (Ottosson 2020).
fn oklab_to_linear_srgb([l, a, b]: [f64; 3]) -> [f64; 3] {
    let l_ = l + 0.396_337_777_4 * a + 0.215_803_757_3 * b;
    let m_ = l - 0.105_561_345_8 * a - 0.063_854_172_8 * b;
    let s_ = l - 0.089_484_177_5 * a - 1.291_485_548_0 * b;
    let (l3, m3, s3) = (l_.powi(3), m_.powi(3), s_.powi(3));
    [
        4.076_741_662_1 * l3 - 3.307_711_591_3 * m3 + 0.230_969_929_2 * s3,
        -1.268_438_004_6 * l3 + 2.609_757_401_1 * m3 - 0.341_319_396_5 * s3,
        -0.004_196_086_3 * l3 - 0.703_418_614_7 * m3 + 1.707_614_701_0 * s3,
    ]
}

/// Linear sRGB → OKLab (Ottosson 2020).
fn linear_srgb_to_oklab([r, g, b]: [f64; 3]) -> [f64; 3] {
    let l = 0.412_221_470_8 * r + 0.536_332_536_3 * g + 0.051_445_992_9 * b;
    let m = 0.211_903_498_2 * r + 0.680_699_545_1 * g + 0.107_396_956_6 * b;
    let s = 0.088_302_461_9 * r + 0.281_718_837_6 * g + 0.629_978_700_5 * b;
    let (l_, m_, s_) = (l.cbrt(), m.cbrt(), s.cbrt());
    [
        0.210_454_255_3 * l_ + 0.793_617_785_0 * m_ - 0.004_072_046_8 * s_,
        1.977_998_495_1 * l_ - 2.428_592_205_0 * m_ + 0.450_593_709_9 * s_,
        0.025_904_037_1 * l_ + 0.782_771_766_2 * m_ - 0.808_675_766_0 * s_,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_palette_is_deterministic_well_separated_and_prefix_stable() {
        let p64 = palette(64);
        assert_eq!(p64.len(), 64);
        assert_eq!(p64, palette(64));
        let (candidates, start) = palette_candidates();
        assert_eq!(p64.first(), candidates.get(start));
        let first = p64[0].srgb;
        assert!(first[0] > first[1] && first[1] > 80, "a coral: {first:?}");
        assert_eq!(palette(12)[..], p64[..12]);
        let min_distance = |colors: &[Color]| {
            let mut min = f64::INFINITY;
            for (i, a) in colors.iter().enumerate() {
                for b in &colors[i + 1..] {
                    min = min.min(lab_distance(&a.lab, &b.lab));
                }
            }
            min
        };
        // OKLab's just-noticeable difference is about 0.02.
        let (d12, d64) = (min_distance(&p64[..12]), min_distance(&p64));
        println!("min OKLab distance: 12 colours {d12:.3}, 64 colours {d64:.3}");
        assert!(d12 > 0.12, "{d12}");
        assert!(d64 > 0.05, "{d64}");
        // Past the candidates, colours repeat rather than fail.
        assert_eq!(palette(2000).len(), 2000);
    }

    #[test]
    fn oklab_round_trips_and_gltf_colours_are_linear() {
        for rgb in [[0.2, 0.5, 0.9], [1.0, 1.0, 1.0], [0.0, 0.3, 0.0]] {
            let back = oklab_to_linear_srgb(linear_srgb_to_oklab(rgb));
            for (x, y) in rgb.iter().zip(back) {
                assert!((x - y).abs() < 1e-6, "{rgb:?} -> {back:?}");
            }
        }
        // White has L = 1 in OKLab.
        assert!((linear_srgb_to_oklab([1.0, 1.0, 1.0])[0] - 1.0).abs() < 1e-6);
        // sRGB 188 is linear 0.5.
        let c = from_srgb([188, 188, 188]);
        assert_eq!(c.linear_rgba(), [128, 128, 128, 255]);
        assert_eq!(c.srgb_rgba(), [188, 188, 188, 255]);
    }
}
