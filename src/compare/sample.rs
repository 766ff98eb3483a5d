//! Area-uniform random points on a mesh's surface, reproducible from a seed.

use crate::rng::SplitMix64;
use crate::Mesh;
use glam::DVec3;

/// A point on a mesh's surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceSample {
    /// The point.
    pub point: DVec3,
    /// The face it lies on.
    pub face: u32,
    /// That face's unit normal.
    pub normal: DVec3,
}

/// `count` points drawn uniformly by area from the faces of `mesh` that have a unit normal
/// (faces of zero area, or so small that their normal underflows, hold no surface), the same
/// points for the same `seed` on every machine. Empty when no face has an area.
///
/// Each point picks a face with probability proportional to its area (a binary search in the
/// running sum of areas), then a uniform point of it: `(1 − √u)·a + √u(1 − v)·b + √u·v·c` for
/// uniform `u, v` (Osada et al., *Shape distributions*, 2002, section 4.2).
pub fn sample_surface(mesh: &Mesh, count: usize, seed: u64) -> Vec<SurfaceSample> {
    let mut running = Vec::with_capacity(mesh.face_count());
    let mut faces = Vec::with_capacity(mesh.face_count());
    let mut total = 0.0;
    for f in 0..mesh.face_count() {
        let normal = mesh.face_normal(f);
        if normal != DVec3::ZERO {
            total += mesh.face_area(f);
            running.push(total);
            faces.push((f as u32, normal));
        }
    }
    if !(total > 0.0 && total.is_finite()) {
        return Vec::new();
    }
    let mut rng = SplitMix64::new(seed);
    (0..count)
        .filter_map(|_| {
            let x = rng.next_f64() * total;
            let i = running.partition_point(|&r| r <= x).min(faces.len() - 1);
            let &(face, normal) = faces.get(i)?;
            let [a, b, c] = mesh.corners(face as usize);
            let r = rng.next_f64().sqrt();
            let v = rng.next_f64();
            Some(SurfaceSample {
                point: a * (1.0 - r) + b * (r * (1.0 - v)) + c * (r * v),
                face,
                normal,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles in the plane z = 0, of areas 1 and 3, and a degenerate one.
    fn two_triangles() -> Mesh {
        let positions = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(13.0, 0.0, 0.0),
            DVec3::new(10.0, 2.0, 0.0),
            DVec3::new(20.0, 0.0, 0.0),
        ];
        // Face 1 is degenerate: collinear corners on the x axis.
        Mesh::new(positions, vec![[0, 1, 2], [0, 1, 6], [3, 4, 5]]).unwrap()
    }

    #[test]
    fn faces_are_drawn_in_proportion_to_their_area() {
        let samples = sample_surface(&two_triangles(), 40_000, 1);
        assert_eq!(samples.len(), 40_000);
        assert!(samples.iter().all(|s| s.face != 1), "degenerate face drawn");
        let on_big = samples.iter().filter(|s| s.face == 2).count() as f64 / 40_000.0;
        // Expected 3/4; binomial σ = √(3/16/40000) ≈ 0.0022, so 5σ ≈ 0.011.
        assert!((on_big - 0.75).abs() < 0.011, "{on_big}");
    }

    #[test]
    fn points_are_uniform_on_their_triangle() {
        let mesh = two_triangles();
        let samples = sample_surface(&mesh, 40_000, 2);
        let on_big: Vec<DVec3> = samples
            .iter()
            .filter(|s| s.face == 2)
            .map(|s| s.point)
            .collect();
        // Every point inside triangle (10,0)-(13,0)-(10,2): x ≥ 10, y ≥ 0, (x−10)/3 + y/2 ≤ 1.
        for p in &on_big {
            assert!(p.x >= 10.0 && p.y >= 0.0 && (p.x - 10.0) / 3.0 + p.y / 2.0 <= 1.0 + 1e-12);
            assert_eq!(p.z, 0.0);
        }
        // The mean of a uniform density is the centroid (11, 2/3); σ of the mean < 0.006.
        let mean = on_big.iter().sum::<DVec3>() / on_big.len() as f64;
        assert!(
            mean.distance(DVec3::new(11.0, 2.0 / 3.0, 0.0)) < 0.03,
            "{mean}"
        );
        // Uniform, not biased to the centroid: a quarter of the area lies within the
        // triangle similar to it at scale 1/2 around the corner (10, 0).
        let near = on_big
            .iter()
            .filter(|p| (p.x - 10.0) / 3.0 + p.y / 2.0 <= 0.5)
            .count() as f64
            / on_big.len() as f64;
        assert!((near - 0.25).abs() < 0.02, "{near}");
        assert!(samples.iter().all(|s| s.normal == DVec3::Z));
    }

    #[test]
    fn the_seed_fixes_the_points() {
        let mesh = two_triangles();
        assert_eq!(sample_surface(&mesh, 100, 7), sample_surface(&mesh, 100, 7));
        assert_ne!(sample_surface(&mesh, 100, 7), sample_surface(&mesh, 100, 8));
    }

    #[test]
    fn a_surface_without_area_gives_no_points() {
        let line = Mesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0], vec![[0, 1, 2]]).unwrap();
        assert!(sample_surface(&line, 10, 1).is_empty());
        let empty = Mesh::new(Vec::new(), Vec::new()).unwrap();
        assert!(sample_surface(&empty, 10, 1).is_empty());
    }
}
