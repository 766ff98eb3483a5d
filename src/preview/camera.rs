//! The preview's camera: an orthographic view of a bounding box from a fixed direction,
//! scaled to fit a frame. One camera serves every panel, so that they line up.

use crate::mesh::Aabb;
use glam::DVec3;

/// Where the camera looks from, in degrees, with +Y up: the azimuth turns from +Z toward
/// +X, the elevation raises the eye above the XZ plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Degrees from +Z toward +X.
    pub azimuth: f64,
    /// Degrees above the XZ plane.
    pub elevation: f64,
}

impl Default for View {
    /// A three-quarter view from the front right, a little from above: azimuth 30°,
    /// elevation 20°.
    fn default() -> Self {
        View {
            azimuth: 30.0,
            elevation: 20.0,
        }
    }
}

/// A rectangle of pixels to fit the object into.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: f64,
    /// Height in pixels.
    pub height: f64,
    /// Pixels kept free at the top (for a caption).
    pub top: f64,
    /// Pixels kept free on every side, as a fraction of the smaller of width and height.
    pub margin: f64,
}

/// An orthographic camera: screen x to the right, y down (pixels), depth 0 at the near side
/// of the box's bounding sphere and 1 at its far side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    right: DVec3,
    up: DVec3,
    /// Unit vector from the scene toward the eye.
    back: DVec3,
    center: DVec3,
    /// Pixels per model unit.
    scale: f64,
    /// Screen position of `center`.
    origin: [f64; 2],
    /// Radius of the box's bounding sphere (at least a tiny positive number).
    radius: f64,
}

impl Camera {
    /// A camera looking at the centre of `aabb` from `view`, the box's projection centred in
    /// `frame` below its top band and as large as the margins allow. A box that is flat or a
    /// single point still gives a usable camera.
    pub fn fit(aabb: &Aabb, view: View, frame: Frame) -> Camera {
        let corners = (0..8).map(|i| {
            DVec3::new(
                if i & 1 == 0 { aabb.min.x } else { aabb.max.x },
                if i & 2 == 0 { aabb.min.y } else { aabb.max.y },
                if i & 4 == 0 { aabb.min.z } else { aabb.max.z },
            )
        });
        Camera::fit_points(corners, view, frame)
    }

    /// A camera looking at the centre of the points' bounding box from `view`, the points'
    /// projection centred in `frame` below its top band and as large as the margins allow
    /// (a tighter fit than the box's corners). Depth spans the box's bounding sphere. No
    /// points, or points all in one place, still give a usable camera; non-finite points are
    /// left out.
    pub fn fit_points(
        points: impl Iterator<Item = DVec3> + Clone,
        view: View,
        frame: Frame,
    ) -> Camera {
        let finite = points.filter(|p| p.is_finite());
        let aabb = finite
            .clone()
            .fold(None, |b: Option<(DVec3, DVec3)>, p| {
                Some(b.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))))
            })
            .unwrap_or((DVec3::ZERO, DVec3::ZERO));
        let (az, el) = (view.azimuth.to_radians(), view.elevation.to_radians());
        let back = DVec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
        let back = back.try_normalize().unwrap_or(DVec3::Z);
        // Looking straight down or up: take +Z as the screen's up instead of +Y.
        let right = DVec3::Y
            .cross(back)
            .try_normalize()
            .or_else(|| back.cross(DVec3::Z).try_normalize())
            .unwrap_or(DVec3::X);
        let up = back.cross(right);
        let center = 0.5 * (aabb.0 + aabb.1);
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in finite {
            let d = p - center;
            let p = [d.dot(right), d.dot(up)];
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let margin = frame.margin * frame.width.min(frame.height);
        let room_x = (frame.width - 2.0 * margin).max(1.0);
        let room_y = (frame.height - frame.top - 2.0 * margin).max(1.0);
        let fit = |room: f64, extent: f64| {
            if extent > 0.0 {
                room / extent
            } else {
                f64::INFINITY
            }
        };
        let scale = fit(room_x, hi[0] - lo[0]).min(fit(room_y, hi[1] - lo[1]));
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            1.0
        };
        let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        let mid = mid.map(|m| if m.is_finite() { m } else { 0.0 });
        let origin = [
            0.5 * frame.width - scale * mid[0],
            frame.top + 0.5 * (frame.height - frame.top) + scale * mid[1],
        ];
        let radius = 0.5 * (aabb.1 - aabb.0).length();
        let radius = if radius.is_finite() && radius > 0.0 {
            radius
        } else {
            1.0
        };
        Camera {
            right,
            up,
            back,
            center,
            scale,
            origin,
            radius,
        }
    }

    /// Screen x, y (pixels, y down) and depth (0 near, 1 far for points of the box's
    /// bounding sphere; smaller is nearer) of a point.
    pub fn project(&self, p: DVec3) -> [f64; 3] {
        let d = p - self.center;
        [
            self.origin[0] + self.scale * d.dot(self.right),
            self.origin[1] - self.scale * d.dot(self.up),
            0.5 - 0.5 * d.dot(self.back) / self.radius,
        ]
    }

    /// Unit vector from the scene toward the eye.
    pub fn toward_eye(&self) -> DVec3 {
        self.back
    }

    /// The screen's right and up directions in the scene (unit vectors).
    pub fn screen_axes(&self) -> (DVec3, DVec3) {
        (self.right, self.up)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> Frame {
        Frame {
            width: 200.0,
            height: 100.0,
            top: 20.0,
            margin: 0.05,
        }
    }

    #[test]
    fn the_box_fits_the_frame_and_is_centred_below_the_band() {
        let aabb = Aabb {
            min: DVec3::new(-1.0, 2.0, 0.0),
            max: DVec3::new(3.0, 4.0, 1.0),
        };
        let camera = Camera::fit(&aabb, View::default(), frame());
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for i in 0..8 {
            let corner = DVec3::new(
                if i & 1 == 0 { aabb.min.x } else { aabb.max.x },
                if i & 2 == 0 { aabb.min.y } else { aabb.max.y },
                if i & 4 == 0 { aabb.min.z } else { aabb.max.z },
            );
            let p = camera.project(corner);
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        // Margin 5 px; the limiting axis touches the margins (to 1e-9 px).
        assert!(
            lo[0] >= 5.0 - 1e-9 && hi[0] <= 195.0 + 1e-9,
            "{lo:?} {hi:?}"
        );
        assert!(
            lo[1] >= 25.0 - 1e-9 && hi[1] <= 95.0 + 1e-9,
            "{lo:?} {hi:?}"
        );
        let touches_x = (lo[0] - 5.0).abs() < 1e-9 && (hi[0] - 195.0).abs() < 1e-9;
        let touches_y = (lo[1] - 25.0).abs() < 1e-9 && (hi[1] - 95.0).abs() < 1e-9;
        assert!(touches_x || touches_y, "{lo:?} {hi:?}");
        // Depth of the box's corners within the bounding sphere's [0, 1].
        assert!(lo[2] >= -1e-12 && hi[2] <= 1.0 + 1e-12, "{lo:?} {hi:?}");
        // The eye is at +Z rotated 30° toward +X, 20° up: the nearest corner is max x, y, z.
        let near = camera.project(aabb.max)[2];
        assert!((near - lo[2]).abs() < 1e-12);
    }

    #[test]
    fn fitting_points_is_tighter_than_their_box_and_skips_non_finite_ones() {
        let points = [
            DVec3::new(-1.0, -1.0, -1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(f64::NAN, 0.0, 0.0),
            DVec3::new(f64::INFINITY, 0.0, 0.0),
        ];
        let f = frame();
        let camera = Camera::fit_points(points.iter().copied(), View::default(), f);
        let box_camera = Camera::fit(
            &Aabb {
                min: points[0],
                max: points[1],
            },
            View::default(),
            f,
        );
        assert!(camera.scale > box_camera.scale, "{camera:?} {box_camera:?}");
        for p in &points[..2] {
            let [x, y, z] = camera.project(*p);
            assert!((5.0 - 1e-9..=195.0 + 1e-9).contains(&x), "{x}");
            assert!((25.0 - 1e-9..=95.0 + 1e-9).contains(&y), "{y}");
            assert!((0.0..=1.0).contains(&z), "{z}");
        }
        let empty = Camera::fit_points(std::iter::empty(), View::default(), f);
        assert!(empty.project(DVec3::ONE).iter().all(|x| x.is_finite()));
    }

    #[test]
    fn flat_and_point_boxes_give_finite_cameras() {
        for aabb in [
            Aabb {
                min: DVec3::ZERO,
                max: DVec3::ZERO,
            },
            Aabb {
                min: DVec3::ZERO,
                max: DVec3::new(1.0, 1.0, 0.0),
            },
        ] {
            for view in [
                View::default(),
                View {
                    azimuth: 0.0,
                    elevation: 90.0,
                },
            ] {
                let camera = Camera::fit(&aabb, view, frame());
                let p = camera.project(aabb.max);
                assert!(p.iter().all(|x| x.is_finite()), "{aabb:?} {view:?} {p:?}");
                let (right, up) = camera.screen_axes();
                assert!((right.length() - 1.0).abs() < 1e-12);
                assert!((up.length() - 1.0).abs() < 1e-12);
                assert!(right.dot(camera.toward_eye()).abs() < 1e-12);
            }
        }
    }
}
