//! VSA's planar proxies with the L²,¹ metric (Cohen-Steiner, Alliez & Desbrun, *Variational
//! Shape Approximation*, SIGGRAPH 2004, section 3).
//!
//! A region's proxy is the plane through its area-weighted centroid with its area-weighted
//! average normal; a face's error is `|T| · ‖n_T − n_P‖²`. The L²,¹ fit is in closed form
//! (VSA, section 3.3: the average normal minimises the summed squared normal deviation), so
//! planes are cheap: they are here so that ellipsoids and planes can be compared with one
//! Lloyd loop ([`crate::segment::segment_planes`]).

use super::ProxyMetric;
use crate::mesh::Mesh;
use glam::DVec3;
use serde::Serialize;

/// A plane through `point` with unit `normal`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Plane {
    /// A point of the plane (the region's area centroid).
    pub point: DVec3,
    /// Unit normal.
    pub normal: DVec3,
}

impl Plane {
    /// Signed distance from `p` to the plane, positive on the side the normal points to.
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        (p - self.point).dot(self.normal)
    }

    /// Distance from `p` to the plane.
    pub fn distance(&self, p: DVec3) -> f64 {
        self.signed_distance(p).abs()
    }
}

/// The L²,¹ metric: a face's error is its area times the squared distance between its
/// normal and the proxy's.
///
/// Face normals, areas and centroids are computed once by [`PlaneMetric::new`].
#[derive(Debug, Clone)]
pub struct PlaneMetric {
    /// Unit normal of each face (zero for a degenerate face).
    normals: Vec<DVec3>,
    /// Area of each face.
    areas: Vec<f64>,
    /// Centroid of each face.
    centroids: Vec<DVec3>,
    /// Corner positions of each face, for the geometric distance of the tolerance mode.
    corners: Vec<[DVec3; 3]>,
}

impl PlaneMetric {
    /// Prepares the metric for a mesh (face normals, areas and centroids).
    pub fn new(mesh: &Mesh) -> Self {
        let count = mesh.face_count();
        let mut normals = Vec::with_capacity(count);
        let mut areas = Vec::with_capacity(count);
        let mut centroids = Vec::with_capacity(count);
        let mut corners = Vec::with_capacity(count);
        for f in 0..count {
            corners.push(mesh.corners(f));
            let area_vector = mesh.face_area_vector(f);
            normals.push(area_vector.normalize_or_zero());
            areas.push(0.5 * area_vector.length());
            centroids.push(mesh.face_centroid(f));
        }
        PlaneMetric {
            normals,
            areas,
            centroids,
            corners,
        }
    }

    /// Normal, area and centroid of a face; a face outside the mesh has zero area.
    fn face(&self, face: u32) -> (DVec3, f64, DVec3) {
        let i = face as usize;
        match (
            self.normals.get(i),
            self.areas.get(i),
            self.centroids.get(i),
        ) {
            (Some(&n), Some(&a), Some(&c)) => (n, a, c),
            _ => (DVec3::ZERO, 0.0, DVec3::ZERO),
        }
    }

    /// The L²,¹ proxy of a set of faces (VSA, section 3.3).
    ///
    /// Degenerate cases fall back deterministically: when the area-weighted normals cancel
    /// (a closed region, or only zero-area faces), the normal is the previous proxy's, else
    /// the normal of the region's largest face, else +z; when the region has no area, the
    /// point is the plain average of the face centroids (the previous point, or the origin,
    /// for no faces).
    pub fn fit_plane(&self, faces: &[u32], previous: Option<&Plane>) -> Plane {
        let mut weighted_normal = DVec3::ZERO;
        let mut weighted_centroid = DVec3::ZERO;
        let mut centroid_sum = DVec3::ZERO;
        let mut area = 0.0;
        // The largest face (first one on ties), for the fallback normal.
        let mut largest: Option<(f64, DVec3)> = None;
        for &f in faces {
            let (n, a, c) = self.face(f);
            weighted_normal += a * n;
            weighted_centroid += a * c;
            centroid_sum += c;
            area += a;
            if n != DVec3::ZERO && largest.is_none_or(|(best, _)| a > best) {
                largest = Some((a, n));
            }
        }
        // Relative to the area, so that a closed region's rounding noise does not count as
        // a direction.
        let normal = if weighted_normal.length() > 1e-12 * area {
            weighted_normal.try_normalize()
        } else {
            None
        };
        let normal = normal
            .or_else(|| previous.and_then(|p| p.normal.try_normalize()))
            .or_else(|| largest.map(|(_, n)| n))
            .unwrap_or(DVec3::Z);
        let point = if area > 0.0 && (weighted_centroid / area).is_finite() {
            weighted_centroid / area
        } else if !faces.is_empty() {
            centroid_sum / faces.len() as f64
        } else {
            previous.map_or(DVec3::ZERO, |p| p.point)
        };
        Plane { point, normal }
    }

    /// The L²,¹ error of a set of faces against a plane: Σ |T|·‖n_T − n_P‖².
    pub fn region_error(&self, faces: &[u32], plane: &Plane) -> f64 {
        faces.iter().map(|&f| self.face_error(f, plane)).sum()
    }
}

impl ProxyMetric for PlaneMetric {
    type Proxy = Plane;

    fn fit(&self, faces: &[u32], previous: Option<&Plane>) -> (Plane, f64) {
        let plane = self.fit_plane(faces, previous);
        let error = self.region_error(faces, &plane);
        (plane, error)
    }

    fn face_error(&self, face: u32, proxy: &Plane) -> f64 {
        let (n, a, _) = self.face(face);
        a * (n - proxy.normal).length_squared()
    }

    /// Mean squared distance of the face's corners to the plane.
    fn face_distance_squared(&self, face: u32, proxy: &Plane) -> Option<f64> {
        let corners = self.corners.get(face as usize)?;
        let sum: f64 = corners
            .iter()
            .map(|&p| (p - proxy.point).dot(proxy.normal).powi(2))
            .sum();
        Some(sum / 3.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::shapes;

    fn all_faces(mesh: &Mesh) -> Vec<u32> {
        (0..mesh.face_count() as u32).collect()
    }

    #[test]
    fn a_flat_grid_has_zero_error_and_its_own_plane() {
        let mesh = shapes::grid(2.0, 8).map_positions(|p| p + DVec3::new(0.5, -1.0, 3.0));
        let mesh = mesh.unwrap();
        let metric = PlaneMetric::new(&mesh);
        let (plane, error) = metric.fit(&all_faces(&mesh), None);
        assert!(error.abs() < 1e-24, "error {error}");
        assert!(
            (plane.normal - DVec3::Z).length() < 1e-15,
            "{}",
            plane.normal
        );
        assert!(
            (plane.point - DVec3::new(0.5, -1.0, 3.0)).length() < 1e-14,
            "{}",
            plane.point
        );
        for &p in mesh.positions() {
            assert!(plane.distance(p) < 1e-14);
        }
    }

    /// Group a cube's faces by their normal: each group's plane is exactly the cube's side.
    #[test]
    fn a_cubes_sides_give_six_exact_planes() {
        let size = 2.0;
        let mesh = shapes::cube(size, 4);
        let metric = PlaneMetric::new(&mesh);
        let axes = [
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ];
        let mut covered = 0;
        for axis in axes {
            let side: Vec<u32> = (0..mesh.face_count())
                .filter(|&f| mesh.face_normal(f).dot(axis) > 0.99)
                .map(|f| f as u32)
                .collect();
            assert_eq!(side.len(), 2 * 4 * 4, "side {axis}");
            covered += side.len();
            let (plane, error) = metric.fit(&side, None);
            assert!(error.abs() < 1e-24, "side {axis}: error {error}");
            assert!((plane.normal - axis).length() < 1e-15, "{}", plane.normal);
            assert!(
                (plane.point - axis * size / 2.0).length() < 1e-14,
                "{}",
                plane.point
            );
            // Every other side's faces are at 90° (error 2·area) or 180° (4·area).
            for f in 0..mesh.face_count() {
                let expected = mesh.face_area(f) * (mesh.face_normal(f) - axis).length_squared();
                let got = metric.face_error(f as u32, &plane);
                assert!((got - expected).abs() < 1e-15);
            }
        }
        assert_eq!(covered, mesh.face_count());
    }

    /// The Lloyd loop with the L²,¹ metric finds a cube's six sides: six planes, zero error.
    #[test]
    fn segmenting_a_cube_into_six_planes_finds_its_sides() {
        let mesh = shapes::cube(2.0, 4);
        let options = crate::segment::SegmentOptions {
            regions: crate::segment::RegionCount::Fixed(6),
            ..Default::default()
        };
        let s = crate::segment::segment_planes(&mesh, &options).unwrap();
        assert_eq!(s.region_count(), 6);
        assert!(s.total_error.abs() < 1e-20, "error {}", s.total_error);
        let mut normals: Vec<[i64; 3]> = s
            .proxies
            .iter()
            .map(|p| p.normal.to_array().map(|x| x.round() as i64))
            .collect();
        normals.sort_unstable();
        assert_eq!(
            normals,
            vec![
                [-1, 0, 0],
                [0, -1, 0],
                [0, 0, -1],
                [0, 0, 1],
                [0, 1, 0],
                [1, 0, 0]
            ]
        );
        for (plane, faces) in s.proxies.iter().zip(s.faces_by_region()) {
            assert_eq!(faces.len(), 32);
            assert!((plane.point - plane.normal).length() < 1e-14, "{plane:?}");
            for f in faces {
                for p in mesh.corners(f as usize) {
                    assert!(plane.distance(p) < 1e-14);
                }
            }
        }
    }

    #[test]
    fn the_error_is_the_area_weighted_normal_deviation() {
        // Two faces folded at a right angle: the average normal bisects them, and each face
        // deviates by 45°: ‖n_f − n_P‖² = 2 − 2·cos 45°.
        let positions = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
        ];
        let mesh = Mesh::new(positions, vec![[0, 1, 2], [0, 3, 1]]).unwrap();
        let metric = PlaneMetric::new(&mesh);
        let (plane, error) = metric.fit(&[0, 1], None);
        let bisector = DVec3::new(0.0, 1.0, 1.0).normalize();
        assert!(
            (plane.normal - bisector).length() < 1e-15,
            "{}",
            plane.normal
        );
        let expected = 2.0 * 0.5 * (2.0 - 2.0 * std::f64::consts::FRAC_1_SQRT_2);
        assert!((error - expected).abs() < 1e-15, "{error} vs {expected}");
    }

    #[test]
    fn degenerate_regions_fall_back_deterministically() {
        // A whole closed cube: the area-weighted normals cancel.
        let mesh = shapes::cube(1.0, 2);
        let metric = PlaneMetric::new(&mesh);
        let faces = all_faces(&mesh);
        let previous = Plane {
            point: DVec3::ONE,
            normal: DVec3::new(0.0, 3.0, 4.0),
        };
        let with_previous = metric.fit_plane(&faces, Some(&previous));
        assert!((with_previous.normal - DVec3::new(0.0, 0.6, 0.8)).length() < 1e-15);
        assert!(with_previous.point.length() < 1e-15, "centroid of the cube");
        let alone = metric.fit_plane(&faces, None);
        assert_eq!(alone, metric.fit_plane(&faces, None));
        assert!((alone.normal.length() - 1.0).abs() < 1e-15);
        // No faces at all: the previous plane, or +z through the origin.
        assert_eq!(metric.fit_plane(&[], Some(&previous)).point, DVec3::ONE);
        let empty = metric.fit(&[], None);
        assert_eq!(
            empty,
            (
                Plane {
                    point: DVec3::ZERO,
                    normal: DVec3::Z
                },
                0.0
            )
        );
        // Faces outside the mesh weigh nothing instead of panicking.
        assert_eq!(metric.face_error(u32::MAX, &alone), 0.0);
    }

    #[test]
    fn tolerance_distance_is_the_mean_squared_height_of_the_corners() {
        let mesh = shapes::grid(2.0, 4);
        let metric = PlaneMetric::new(&mesh);
        let lifted = Plane {
            point: DVec3::new(0.0, 0.0, 0.5),
            normal: DVec3::Z,
        };
        for f in 0..mesh.face_count() as u32 {
            let d = metric.face_distance_squared(f, &lifted).unwrap();
            assert!((d - 0.25).abs() < 1e-15, "{d}");
        }
        assert_eq!(metric.face_distance_squared(u32::MAX, &lifted), None);
    }
}
