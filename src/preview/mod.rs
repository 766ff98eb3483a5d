//! Preview: meshes drawn side by side into a PNG, in software.
//!
//! Each [`Panel`] is a triangle mesh with per-face or per-vertex colours and, optionally,
//! dark lines over it (the boundaries between regions: [`region_boundaries`]). [`render`]
//! draws the panels with one [`Camera`] fitted to all their vertices (an orthographic three-quarter
//! [`View`]), so that they line up:
//!
//! - rasterised with an f32 z-buffer at 2×2 supersampling (antialiasing), then averaged in
//!   linear light;
//! - per-pixel shading of interpolated vertex normals (a corner whose normal is more than
//!   40° from its face's takes the face's, so creases stay sharp), lit by a headlight and a
//!   key light from the upper left; both sides of a face are lit, so open meshes read well;
//! - region boundaries drawn a few pixels thick in a dark colour, depth-tested against the
//!   surface with a small bias (1% of the scene's depth);
//! - a caption in a 5×7 bitmap font at the top of each panel.
//!
//! Everything runs on one thread in a fixed order: the same panels give the same bytes.
//! Region colours come from [`palette`], the palette `ellip segment` uses.

pub mod camera;
mod font;
pub mod palette;
mod raster;

pub use camera::{Camera, Frame, View};

use crate::mesh::Mesh;
use glam::DVec3;
use raster::{Corner, Lighting, Target, Vec3};
use std::collections::HashMap;
use std::path::Path;

/// The background of every panel (sRGB).
pub const BACKGROUND: [u8; 3] = [244, 244, 246];
/// The colour of a mesh drawn without region colours (sRGB).
pub const SOURCE_GREY: [u8; 3] = [196, 196, 196];
/// The colour of boundary lines (sRGB).
pub const LINE_COLOR: [u8; 3] = [28, 28, 34];
/// The colour of captions (sRGB).
pub const CAPTION_COLOR: [u8; 3] = [60, 60, 66];
/// Largest panel width or height accepted, in pixels.
pub const MAX_PANEL_SIDE: u32 = 4096;
/// Most panels in one image.
pub const MAX_PANELS: usize = 16;
/// Most samples (pixels × supersampling²) of one panel: 16 bytes each while drawing.
pub const MAX_PANEL_SAMPLES: u64 = 4096 * 4096;
/// Most palette colours computed for one panel.
const MAX_PALETTE: usize = 4096;
/// A vertex normal farther than this from its face's normal is not used for that face.
const CREASE_DEGREES: f64 = 40.0;
/// Depth bias of boundary lines, in units of the scene's depth (its bounding sphere's
/// diameter).
const LINE_BIAS: f32 = 0.01;

/// How surfaces are coloured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Shading {
    /// A headlight and a key light (the default).
    #[default]
    Lit,
    /// Every surface pixel in its colour as given: for tests that count colours.
    Unlit,
}

/// Everything [`render`] can be told. Every field has a default ([`Default`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Width of each panel in pixels (default 480).
    pub width: u32,
    /// Height of each panel in pixels (default 480).
    pub height: u32,
    /// Supersampling factor per axis, 1 to 4 (default 2: 2×2 samples a pixel).
    pub supersample: u32,
    /// Lit or not (default [`Shading::Lit`]).
    pub shading: Shading,
    /// Where the camera looks from (default [`View::default`]: azimuth 30°, elevation 20°).
    pub view: View,
    /// Whether to write each panel's title at its top (default true; too small a panel
    /// gets none).
    pub captions: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 480,
            height: 480,
            supersample: 2,
            shading: Shading::Lit,
            view: View::default(),
            captions: true,
        }
    }
}

/// Colours of a panel's surface, sRGB.
#[derive(Debug, Clone, PartialEq)]
pub enum Colors {
    /// One colour for the whole mesh.
    Uniform([u8; 3]),
    /// One per face (missing ones: [`SOURCE_GREY`]).
    PerFace(Vec<[u8; 3]>),
    /// One per vertex, interpolated across faces (missing ones: [`SOURCE_GREY`]).
    PerVertex(Vec<[u8; 3]>),
}

/// One picture of the row: a mesh (or nothing, e.g. when decoding failed), its colours,
/// lines to draw over it and a title.
#[derive(Debug, Clone)]
pub struct Panel<'a> {
    /// The caption.
    pub title: String,
    /// The mesh; `None` draws an empty panel with its caption.
    pub mesh: Option<&'a Mesh>,
    /// Per-vertex normals; `None` (or a wrong length): the mesh's own vertex normals.
    pub normals: Option<&'a [DVec3]>,
    /// The surface colours.
    pub colors: Colors,
    /// Segments drawn over the surface in [`LINE_COLOR`].
    pub lines: Vec<[DVec3; 2]>,
}

impl<'a> Panel<'a> {
    /// The mesh in [`SOURCE_GREY`], no lines.
    pub fn plain(title: impl Into<String>, mesh: &'a Mesh, normals: Option<&'a [DVec3]>) -> Self {
        Panel {
            title: title.into(),
            mesh: Some(mesh),
            normals,
            colors: Colors::Uniform(SOURCE_GREY),
            lines: Vec::new(),
        }
    }

    /// Each face in its region's [`palette`] colour (`face_regions[f]` is face `f`'s
    /// region), with the boundaries between regions drawn over it.
    pub fn regions(
        title: impl Into<String>,
        mesh: &'a Mesh,
        normals: Option<&'a [DVec3]>,
        face_regions: &[u32],
    ) -> Self {
        // Region numbers past MAX_PALETTE (hostile input) reuse the palette's colours.
        let count = face_regions.iter().max().map_or(0, |&r| r as usize + 1);
        let colors = palette::palette(count.min(MAX_PALETTE));
        let per_face = (0..mesh.face_count())
            .map(|f| {
                face_regions
                    .get(f)
                    .and_then(|&r| colors.get(r as usize % colors.len().max(1)))
                    .map_or(SOURCE_GREY, |c| c.srgb())
            })
            .collect();
        Panel {
            title: title.into(),
            mesh: Some(mesh),
            normals,
            colors: Colors::PerFace(per_face),
            lines: region_boundaries(mesh, face_regions),
        }
    }

    /// A panel with only its caption (e.g. "decoded: failed").
    pub fn empty(title: impl Into<String>) -> Self {
        Panel {
            title: title.into(),
            mesh: None,
            normals: None,
            colors: Colors::Uniform(SOURCE_GREY),
            lines: Vec::new(),
        }
    }
}

/// The edges between faces of different regions, as segments: each edge shared by two faces
/// whose `face_regions` differ, once. Faces without a region (past the slice's end) count as
/// a region of their own.
pub fn region_boundaries(mesh: &Mesh, face_regions: &[u32]) -> Vec<[DVec3; 2]> {
    let region = |f: usize| face_regions.get(f).copied().unwrap_or(u32::MAX);
    // The region of the first face seen on each undirected edge.
    let mut first: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.face_count() * 2);
    let mut lines = Vec::new();
    for (f, face) in mesh.faces().iter().enumerate() {
        let r = region(f);
        for i in 0..3 {
            let (a, b) = (face[i], face[(i + 1) % 3]);
            let key = (a.min(b), a.max(b));
            match first.get(&key) {
                None => {
                    first.insert(key, r);
                }
                Some(&other) if other != r => {
                    if let (Some(&p), Some(&q)) = (
                        mesh.positions().get(a as usize),
                        mesh.positions().get(b as usize),
                    ) {
                        lines.push([p, q]);
                    }
                }
                Some(_) => {}
            }
        }
    }
    lines
}

/// An RGB image, 8 bits a channel, sRGB, rows top to bottom.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    width: u32,
    height: u32,
    pixels: Vec<u8>,
}

impl Image {
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixel at column `x`, row `y` (from the top), if inside.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let at = 3 * (y as usize * self.width as usize + x as usize);
        let p = self.pixels.get(at..at + 3)?;
        Some([p[0], p[1], p[2]])
    }

    /// The pixels: RGB bytes, rows top to bottom.
    pub fn as_rgb(&self) -> &[u8] {
        &self.pixels
    }

    /// The image as a PNG file (RGB, 8 bits, no metadata): the same image gives the same
    /// bytes.
    pub fn encode_png(&self) -> Result<Vec<u8>, PreviewError> {
        let mut bytes = Vec::new();
        let mut encoder = png::Encoder::new(&mut bytes, self.width, self.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Balanced);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&self.pixels)?;
        writer.finish()?;
        Ok(bytes)
    }

    /// Writes the image as a PNG file, atomically (a temporary file renamed over `path`).
    pub fn write_png(&self, path: &Path) -> Result<(), PreviewError> {
        let bytes = self.encode_png()?;
        crate::atomic::write_atomic(path, |w| w.write_all(&bytes))?;
        Ok(())
    }
}

/// Why a preview could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PreviewError {
    /// An option is out of range.
    #[error("invalid option {what}: {value}")]
    InvalidOption {
        /// The option.
        what: &'static str,
        /// Its value, as text.
        value: String,
    },
    /// Encoding the PNG failed.
    #[error("PNG encoding failed: {0}")]
    Png(#[from] png::EncodingError),
    /// Writing the file failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

impl RenderOptions {
    /// Checks every option against its range.
    pub fn validate(&self, panels: usize) -> Result<(), PreviewError> {
        let invalid = |what, value: String| Err(PreviewError::InvalidOption { what, value });
        if !(1..=MAX_PANEL_SIDE).contains(&self.width) {
            return invalid("width", self.width.to_string());
        }
        if !(1..=MAX_PANEL_SIDE).contains(&self.height) {
            return invalid("height", self.height.to_string());
        }
        if !(1..=4).contains(&self.supersample) {
            return invalid("supersample", self.supersample.to_string());
        }
        let samples =
            u64::from(self.width) * u64::from(self.height) * u64::from(self.supersample).pow(2);
        if samples > MAX_PANEL_SAMPLES {
            return invalid(
                "size",
                format!(
                    "{}x{} at {}x{} supersampling is over {MAX_PANEL_SAMPLES} samples a panel",
                    self.width, self.height, self.supersample, self.supersample
                ),
            );
        }
        if !(1..=MAX_PANELS).contains(&panels) {
            return invalid("panels", panels.to_string());
        }
        if !(self.view.azimuth.is_finite() && self.view.elevation.is_finite()) {
            return invalid("view", format!("{:?}", self.view));
        }
        Ok(())
    }
}

/// Draws the panels side by side: an image `panels × width` wide and `height` high, every
/// panel seen by the same camera, fitted to every mesh's vertices.
pub fn render(panels: &[Panel], options: &RenderOptions) -> Result<Image, PreviewError> {
    options.validate(panels.len())?;
    let (w, h) = (options.width as usize, options.height as usize);
    let s = options.supersample as usize;
    let caption_scale = caption_scale(options);
    // A band for the caption: the glyph height and a margin of half a glyph above and below.
    let band = caption_scale.map_or(0, |k| k * (font::GLYPH.1 + font::GLYPH.1));
    let points = panels
        .iter()
        .filter_map(|p| p.mesh)
        .flat_map(|m| m.positions().iter().copied());
    let camera = Camera::fit_points(
        points,
        options.view,
        Frame {
            width: (w * s) as f64,
            height: (h * s) as f64,
            top: (band * s) as f64,
            margin: 0.06,
        },
    );
    let mut pixels = vec![0u8; panels.len() * w * h * 3];
    let row = panels.len() * w * 3;
    for (i, panel) in panels.iter().enumerate() {
        let mut tile = draw_panel(panel, &camera, options, w * s, h * s)
            .downsample(s)
            .2;
        if let Some(scale) = caption_scale {
            let text = fit_caption(&panel.title, w, scale);
            let margin = scale * font::GLYPH.1 / 2;
            font::draw_text(&mut tile, w, (margin, margin), &text, scale, CAPTION_COLOR);
        }
        for (y, line) in tile.chunks_exact(w * 3).enumerate() {
            let at = y * row + i * w * 3;
            if let Some(dst) = pixels.get_mut(at..at + w * 3) {
                dst.copy_from_slice(line);
            }
        }
    }
    Ok(Image {
        width: options.width * panels.len() as u32,
        height: options.height,
        pixels,
    })
}

/// The font scale of captions, or `None` for no captions (not asked, or a panel too small
/// to hold a few characters).
fn caption_scale(options: &RenderOptions) -> Option<usize> {
    if !options.captions || options.width < 64 || options.height < 64 {
        return None;
    }
    Some(if options.width.min(options.height) >= 320 {
        2
    } else {
        1
    })
}

/// The caption cut to the panel's width (with "..." when cut).
fn fit_caption(title: &str, width: usize, scale: usize) -> String {
    let room = width.saturating_sub(scale * font::GLYPH.1);
    if font::text_width(title, scale) <= room {
        return title.to_string();
    }
    let mut text: String = title.chars().collect();
    while !text.is_empty() && font::text_width(&format!("{text}..."), scale) > room {
        text.pop();
    }
    format!("{text}...")
}

/// One panel at the supersampled size.
fn draw_panel(
    panel: &Panel,
    camera: &Camera,
    options: &RenderOptions,
    width: usize,
    height: usize,
) -> Target {
    let mut target = Target::new(width, height, linear(BACKGROUND));
    let Some(mesh) = panel.mesh else {
        return target;
    };
    let eye = camera.toward_eye();
    let (right, up) = camera.screen_axes();
    let key = (-0.55 * right + 0.75 * up + 0.45 * eye).normalize_or(eye);
    let lighting = Lighting {
        eye: to_f32(eye),
        key: to_f32(key),
        lit: options.shading == Shading::Lit,
    };
    let computed;
    let normals = match panel.normals {
        Some(n) if n.len() == mesh.vertex_count() => n,
        _ => {
            computed = mesh.vertex_normals();
            &computed
        }
    };
    let vertex_colors: Vec<Vec3> = match &panel.colors {
        Colors::PerVertex(c) => (0..mesh.vertex_count())
            .map(|v| linear(c.get(v).copied().unwrap_or(SOURCE_GREY)))
            .collect(),
        _ => Vec::new(),
    };
    let uniform = match &panel.colors {
        Colors::Uniform(c) => linear(*c),
        _ => linear(SOURCE_GREY),
    };
    let crease = CREASE_DEGREES.to_radians().cos();
    let projected: Vec<[f64; 3]> = mesh
        .positions()
        .iter()
        .map(|&p| camera.project(p))
        .collect();
    for (f, face) in mesh.faces().iter().enumerate() {
        let face_normal = mesh.face_normal(f);
        // Seen from behind: light the other side.
        let side = if face_normal.dot(eye) < 0.0 {
            -1.0
        } else {
            1.0
        };
        let face_color = match &panel.colors {
            Colors::PerFace(c) => linear(c.get(f).copied().unwrap_or(SOURCE_GREY)),
            _ => uniform,
        };
        let corner = |v: u32| -> Corner {
            let position = projected.get(v as usize).copied().unwrap_or([f64::NAN; 3]);
            let n = normals.get(v as usize).copied().unwrap_or(face_normal);
            let n = if n.dot(face_normal) >= crease || face_normal == DVec3::ZERO {
                n
            } else {
                face_normal
            };
            Corner {
                position: position.map(|x| x as f32),
                normal: to_f32(side * n),
                color: vertex_colors.get(v as usize).copied().unwrap_or(face_color),
            }
        };
        target.triangle(&face.map(corner), &lighting);
    }
    // Lines: a few pixels thick, scaled with the panel (2 px at 480).
    let thickness = (width.min(height) as f32 / 240.0).max(1.5 * options.supersample as f32);
    let color = linear(LINE_COLOR);
    for [a, b] in &panel.lines {
        let (a, b) = (camera.project(*a), camera.project(*b));
        target.line(
            a.map(|x| x as f32),
            b.map(|x| x as f32),
            0.5 * thickness,
            LINE_BIAS,
            color,
        );
    }
    target
}

fn linear(c: [u8; 3]) -> Vec3 {
    c.map(|x| palette::decode_srgb(x) as f32)
}

fn to_f32(v: DVec3) -> Vec3 {
    [v.x as f32, v.y as f32, v.z as f32]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn region_boundaries_are_the_edges_between_different_regions_once() {
        // Two triangles of a square, then a third beside them.
        let positions = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
        ];
        let mesh = Mesh::new(positions, vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]]).unwrap();
        assert_eq!(region_boundaries(&mesh, &[0, 0, 0]).len(), 0);
        let lines = region_boundaries(&mesh, &[0, 1, 1]);
        assert_eq!(lines.len(), 2, "{lines:?}");
        // A missing label is a region of its own.
        assert_eq!(region_boundaries(&mesh, &[0, 0]).len(), 1);
        // Huge region numbers neither allocate a huge palette nor fail.
        let panel = Panel::regions("r", &mesh, None, &[u32::MAX, 0, 7]);
        let Colors::PerFace(colors) = &panel.colors else {
            panic!("per-face colours")
        };
        assert_eq!(colors.len(), 3);
        assert_eq!(colors[1], palette::palette(1)[0].srgb());
        assert_eq!(panel.lines.len(), 2);
    }

    #[test]
    fn per_vertex_colours_are_interpolated_and_per_face_colours_are_exact() {
        let mesh = Mesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]]).unwrap();
        let options = RenderOptions {
            width: 100,
            height: 100,
            shading: Shading::Unlit,
            captions: false,
            view: View {
                azimuth: 0.0,
                elevation: 0.0,
            },
            ..RenderOptions::default()
        };
        let (red, green, blue) = ([255, 0, 0], [0, 255, 0], [0, 0, 255]);
        let mut panel = Panel::plain("t", &mesh, None);
        panel.colors = Colors::PerVertex(vec![red, green, blue]);
        let image = render(&[panel.clone()], &options).unwrap();
        // Seen from +Z: vertex 0 at the bottom left, 1 at the bottom right, 2 at the top left
        // of the fitted square (6 px margins).
        let near = |x, y| image.pixel(x, y).unwrap();
        let (a, b, c) = (near(8, 91), near(85, 91), near(8, 14));
        // Within 8% of a corner (weights mixed in linear light: 7% is sRGB 74).
        assert!(a[0] > 200 && a[1] < 100 && a[2] < 100, "{a:?}");
        assert!(b[1] > 200 && b[0] < 100 && b[2] < 100, "{b:?}");
        assert!(c[2] > 200 && c[0] < 100 && c[1] < 100, "{c:?}");
        // The middle mixes all three.
        let m = near(30, 65);
        assert!(m.iter().all(|&x| x > 60), "{m:?}");
        panel.colors = Colors::PerFace(vec![green]);
        let image = render(&[panel], &options).unwrap();
        assert_eq!(image.pixel(30, 65), Some(green));
    }

    #[test]
    fn captions_are_cut_to_the_panel() {
        assert_eq!(fit_caption("source", 480, 2), "source");
        let cut = fit_caption("a very long caption that cannot fit here", 100, 1);
        assert!(
            cut.ends_with("...") && font::text_width(&cut, 1) <= 100 - 7,
            "{cut}"
        );
        assert_eq!(fit_caption("xyz", 10, 1), "...");
    }

    #[test]
    fn options_out_of_range_are_refused() {
        let ok = RenderOptions::default();
        assert!(ok.validate(3).is_ok());
        for bad in [
            RenderOptions { width: 0, ..ok },
            RenderOptions {
                height: MAX_PANEL_SIDE + 1,
                ..ok
            },
            RenderOptions {
                supersample: 0,
                ..ok
            },
            RenderOptions {
                supersample: 5,
                ..ok
            },
            RenderOptions {
                view: View {
                    azimuth: f64::NAN,
                    elevation: 0.0,
                },
                ..ok
            },
        ] {
            assert!(bad.validate(3).is_err(), "{bad:?}");
        }
        assert!(ok.validate(0).is_err());
        assert!(ok.validate(MAX_PANELS + 1).is_err());
    }
}
