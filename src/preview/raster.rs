//! A small software rasteriser: triangles with a z-buffer (f32 depth), per-pixel shading of
//! interpolated normals and colours, depth-tested thick lines, and a box-filter downsample
//! for supersampling. Single-threaded and in a fixed order, so the output is the same bytes
//! on every run.

use super::palette::{encode_srgb, to_byte};

/// A vector of three f32: a colour (linear RGB) or a direction.
pub(crate) type Vec3 = [f32; 3];

/// How fragments are lit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Lighting {
    /// Unit vector toward the eye (the headlight shines from there).
    pub eye: Vec3,
    /// Unit vector toward the key light.
    pub key: Vec3,
    /// Whether to light at all; unlit fragments take their colour as it is.
    pub lit: bool,
}

/// Ambient, headlight and key-light weights: they sum to 1, so a surface facing both lights
/// takes its full colour.
const AMBIENT: f32 = 0.16;
const HEADLIGHT: f32 = 0.52;
const KEY: f32 = 0.32;
/// A faint white highlight from the headlight (Blinn–Phong; the half vector is the eye).
const SPECULAR: f32 = 0.05;
const SHININESS: i32 = 24;

impl Lighting {
    /// The linear colour of a fragment of albedo `albedo` with unit normal `n` (facing the eye).
    fn shade(&self, albedo: Vec3, n: Vec3) -> Vec3 {
        if !self.lit {
            return albedo;
        }
        let head = dot(n, self.eye).max(0.0);
        let key = dot(n, self.key).max(0.0);
        let diffuse = AMBIENT + HEADLIGHT * head + KEY * key;
        let specular = SPECULAR * head.powi(SHININESS);
        albedo.map(|c| c * diffuse + specular)
    }
}

/// One corner of a triangle on screen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Corner {
    /// Pixels (x right, y down) and depth (smaller is nearer).
    pub position: Vec3,
    /// Unit normal, already turned toward the eye for the triangle's side.
    pub normal: Vec3,
    /// Linear RGB.
    pub color: Vec3,
}

/// A colour buffer (linear RGB) and a depth buffer of the same size.
#[derive(Debug, Clone)]
pub(crate) struct Target {
    width: usize,
    height: usize,
    color: Vec<Vec3>,
    depth: Vec<f32>,
}

impl Target {
    /// A target cleared to `background`, every depth at infinity (nothing drawn).
    pub fn new(width: usize, height: usize, background: Vec3) -> Target {
        Target {
            width,
            height,
            color: vec![background; width * height],
            depth: vec![f32::INFINITY; width * height],
        }
    }

    /// Draws a triangle: every pixel whose centre is inside (edges included) and nearer than
    /// what is there gets the shaded, interpolated colour. Triangles with a non-finite
    /// coordinate or no area on screen are skipped.
    pub fn triangle(&mut self, corners: &[Corner; 3], lighting: &Lighting) {
        let [a, b, c] = corners.map(|k| k.position);
        if !corners
            .iter()
            .all(|k| k.position.iter().all(|x| x.is_finite()))
        {
            return;
        }
        let area = edge(a, b, c);
        if area.abs() <= f32::EPSILON || !area.is_finite() {
            return;
        }
        let Some((x0, x1, y0, y1)) = self.clip(
            a[0].min(b[0]).min(c[0]),
            a[0].max(b[0]).max(c[0]),
            a[1].min(b[1]).min(c[1]),
            a[1].max(b[1]).max(c[1]),
        ) else {
            return;
        };
        let inverse = 1.0 / area;
        // A face of one colour keeps it exactly (no rounding of the weights).
        let flat = corners[0].color == corners[1].color && corners[1].color == corners[2].color;
        for y in y0..y1 {
            let py = y as f32 + 0.5;
            for x in x0..x1 {
                let p = [x as f32 + 0.5, py, 0.0];
                // Barycentric weights, all >= 0 inside whatever the winding.
                let w = [
                    edge(b, c, p) * inverse,
                    edge(c, a, p) * inverse,
                    edge(a, b, p) * inverse,
                ];
                if w.iter().any(|&w| w < 0.0) {
                    continue;
                }
                let z = w[0] * a[2] + w[1] * b[2] + w[2] * c[2];
                let i = y * self.width + x;
                let Some(depth) = self.depth.get_mut(i) else {
                    continue;
                };
                if z >= *depth {
                    continue;
                }
                *depth = z;
                let mix = |f: fn(&Corner) -> Vec3| -> Vec3 {
                    let [u, v, t] = [f(&corners[0]), f(&corners[1]), f(&corners[2])];
                    [0, 1, 2].map(|k| w[0] * u[k] + w[1] * v[k] + w[2] * t[k])
                };
                let normal = normalize(mix(|k| k.normal)).unwrap_or(lighting.eye);
                let color = if flat {
                    corners[0].color
                } else {
                    mix(|k| k.color)
                };
                let shaded = lighting.shade(color, normal);
                if let Some(pixel) = self.color.get_mut(i) {
                    *pixel = shaded;
                }
            }
        }
    }

    /// Draws a segment `half_width` pixels to each side (round caps) in `color`, over drawn
    /// surface only, where the segment is no farther than the surface plus `bias` (depth
    /// units). Lines do not write depth, so their order does not matter.
    pub fn line(&mut self, a: Vec3, b: Vec3, half_width: f32, bias: f32, color: Vec3) {
        if !(a.iter().chain(&b).all(|x| x.is_finite()) && half_width > 0.0) {
            return;
        }
        let Some((x0, x1, y0, y1)) = self.clip(
            a[0].min(b[0]) - half_width,
            a[0].max(b[0]) + half_width,
            a[1].min(b[1]) - half_width,
            a[1].max(b[1]) + half_width,
        ) else {
            return;
        };
        let d = [b[0] - a[0], b[1] - a[1]];
        let length2 = d[0] * d[0] + d[1] * d[1];
        let r2 = half_width * half_width;
        for y in y0..y1 {
            let py = y as f32 + 0.5;
            for x in x0..x1 {
                let px = x as f32 + 0.5;
                let t = if length2 > 0.0 {
                    (((px - a[0]) * d[0] + (py - a[1]) * d[1]) / length2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (qx, qy) = (a[0] + t * d[0] - px, a[1] + t * d[1] - py);
                if qx * qx + qy * qy > r2 {
                    continue;
                }
                let z = a[2] + t * (b[2] - a[2]);
                let i = y * self.width + x;
                let Some(&depth) = self.depth.get(i) else {
                    continue;
                };
                if depth.is_finite() && z - bias <= depth {
                    if let Some(pixel) = self.color.get_mut(i) {
                        *pixel = color;
                    }
                }
            }
        }
    }

    /// The pixel range (x0..x1, y0..y1) that a box of pixel centres can touch, or `None`
    /// when it misses the target.
    fn clip(
        &self,
        x_lo: f32,
        x_hi: f32,
        y_lo: f32,
        y_hi: f32,
    ) -> Option<(usize, usize, usize, usize)> {
        let range = |lo: f32, hi: f32, size: usize| -> Option<(usize, usize)> {
            // Pixel x has its centre at x + 0.5.
            let first = (lo - 0.5).ceil().max(0.0);
            let last = (hi - 0.5).floor().min(size as f32 - 1.0);
            // In range and finite: the casts below are exact.
            (first <= last).then(|| (first as usize, last as usize + 1))
        };
        let (x0, x1) = range(x_lo, x_hi, self.width)?;
        let (y0, y1) = range(y_lo, y_hi, self.height)?;
        Some((x0, x1, y0, y1))
    }

    /// The image `factor` times smaller, each pixel the mean of a `factor`×`factor` block in
    /// linear light, as sRGB bytes (RGB, rows top to bottom).
    pub fn downsample(&self, factor: usize) -> (usize, usize, Vec<u8>) {
        let factor = factor.max(1);
        let (w, h) = (self.width / factor, self.height / factor);
        let mut out = Vec::with_capacity(w * h * 3);
        let weight = 1.0 / (factor * factor) as f32;
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0.0f32; 3];
                for dy in 0..factor {
                    let row = (y * factor + dy) * self.width;
                    for dx in 0..factor {
                        if let Some(c) = self.color.get(row + x * factor + dx) {
                            for k in 0..3 {
                                sum[k] += c[k];
                            }
                        }
                    }
                }
                out.extend(sum.map(|s| to_byte(encode_srgb(f64::from(s * weight)))));
            }
        }
        (w, h, out)
    }
}

/// Twice the signed area of triangle (a, b, p) on screen.
fn edge(a: Vec3, b: Vec3, p: Vec3) -> f32 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

fn dot(a: Vec3, b: Vec3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(v: Vec3) -> Option<Vec3> {
    let length = dot(v, v).sqrt();
    (length > 1e-12 && length.is_finite()).then(|| v.map(|x| x / length))
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLACK: Vec3 = [0.0; 3];
    const UNLIT: Lighting = Lighting {
        eye: [0.0, 0.0, 1.0],
        key: [0.0, 0.0, 1.0],
        lit: false,
    };

    fn corner(x: f32, y: f32, z: f32, color: Vec3) -> Corner {
        Corner {
            position: [x, y, z],
            normal: [0.0, 0.0, 1.0],
            color,
        }
    }

    fn covered(t: &Target) -> usize {
        t.depth.iter().filter(|d| d.is_finite()).count()
    }

    #[test]
    fn a_triangle_covers_its_area_in_either_winding_and_the_nearer_one_wins() {
        let mut t = Target::new(100, 100, BLACK);
        let red = [1.0, 0.0, 0.0];
        let far = [
            corner(10.0, 10.0, 0.5, red),
            corner(90.0, 10.0, 0.5, red),
            corner(10.0, 90.0, 0.5, red),
        ];
        t.triangle(&far, &UNLIT);
        // Area 3200 px²; pixel centres on the diagonal count once: within 2% of it.
        let n = covered(&t) as f64;
        assert!((n - 3200.0).abs() < 64.0, "{n}");
        // The same triangle nearer, wound the other way, in green: it replaces the red.
        let green = [0.0, 1.0, 0.0];
        let near = [
            corner(10.0, 10.0, 0.2, green),
            corner(10.0, 90.0, 0.2, green),
            corner(90.0, 10.0, 0.2, green),
        ];
        t.triangle(&near, &UNLIT);
        assert_eq!(covered(&t) as f64, n);
        assert!(t.color.iter().all(|&c| c == BLACK || c == green));
        // A farther one changes nothing.
        let before = t.color.clone();
        t.triangle(&far, &UNLIT);
        assert_eq!(t.color, before);
    }

    #[test]
    fn degenerate_and_offscreen_triangles_draw_nothing() {
        let mut t = Target::new(20, 20, BLACK);
        let white = [1.0; 3];
        for tri in [
            [[1.0, 1.0], [10.0, 10.0], [19.0, 19.0]],
            [[-50.0, -50.0], [-40.0, -50.0], [-50.0, -40.0]],
            [[f32::NAN, 1.0], [10.0, 10.0], [1.0, 19.0]],
            [[f32::INFINITY, 1.0], [10.0, 10.0], [1.0, 19.0]],
        ] {
            t.triangle(&tri.map(|[x, y]| corner(x, y, 0.0, white)), &UNLIT);
        }
        assert_eq!(covered(&t), 0);
    }

    #[test]
    fn lines_draw_over_surface_only_and_are_hidden_behind_it() {
        let mut t = Target::new(40, 40, BLACK);
        let grey = [0.5; 3];
        // A square of surface at depth 0.5 over x, y in 10..30.
        let quad = [[10.0, 10.0], [30.0, 10.0], [30.0, 30.0], [10.0, 30.0]];
        for tri in [[0, 1, 2], [0, 2, 3]] {
            t.triangle(
                &tri.map(|i| corner(quad[i][0], quad[i][1], 0.5, grey)),
                &UNLIT,
            );
        }
        let dark = [0.01; 3];
        // In front (within the bias), across the whole target: drawn over the square only.
        t.line([0.0, 20.0, 0.51], [40.0, 20.0, 0.51], 1.0, 0.02, dark);
        let row =
            |t: &Target, y: usize| -> Vec<Vec3> { (0..40).map(|x| t.color[y * 40 + x]).collect() };
        let drawn = row(&t, 20).iter().filter(|&&c| c == dark).count();
        assert_eq!(drawn, 20, "pixels 10..30 of the row");
        assert_eq!(t.color[20 * 40 + 5], BLACK, "not over the background");
        // Behind the surface by more than the bias: hidden.
        t.line([0.0, 15.0, 0.6], [40.0, 15.0, 0.6], 1.0, 0.02, dark);
        assert!(row(&t, 15).iter().all(|&c| c != dark));
    }

    #[test]
    fn downsampling_averages_in_linear_light() {
        let mut t = Target::new(4, 2, [0.0; 3]);
        t.color[0] = [1.0; 3];
        t.color[1] = [1.0; 3];
        let (w, h, bytes) = t.downsample(2);
        assert_eq!((w, h), (2, 1));
        // Half of the block white: linear 0.5 is sRGB 188.
        assert_eq!(bytes, vec![188, 188, 188, 0, 0, 0]);
    }

    #[test]
    fn lighting_is_full_colour_facing_both_lights_and_ambient_facing_away() {
        let lit = Lighting {
            eye: [0.0, 0.0, 1.0],
            key: [0.0, 0.0, 1.0],
            lit: true,
        };
        let c = lit.shade([0.5; 3], [0.0, 0.0, 1.0]);
        assert!((c[0] - 0.5 - SPECULAR).abs() < 1e-6, "{c:?}");
        let c = lit.shade([0.5; 3], [1.0, 0.0, 0.0]);
        assert!((c[0] - 0.5 * AMBIENT).abs() < 1e-6, "{c:?}");
    }
}
