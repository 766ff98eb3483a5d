//! A region's chart (Simari & Singh 2005, section 5.1): ellipsoid → unit sphere → rotation
//! that takes a pole far from the region to the north pole → stereographic projection to the
//! plane, and back.

use crate::ellipsoid::Ellipsoid;
use glam::{DQuat, DVec2, DVec3};

/// A map between one ellipsoid's surface and the plane.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionChart {
    /// The region's ellipsoid.
    pub ellipsoid: Ellipsoid,
    /// Rotates unit-sphere points so that the chosen pole becomes the north pole (0, 0, 1).
    pub rotation: DQuat,
}

impl RegionChart {
    /// The chart of region `region` on `ellipsoid`, bounded by `loops`: closed polylines of
    /// boundary points (the first point not repeated at the end), each with the region on its
    /// left when seen with the mesh's outward normal up (spec §6.5). No loops: the whole
    /// ellipsoid.
    ///
    /// The pole is chosen away from the region (section 5.1). This first version takes the
    /// antipode of the loops' mean direction.
    pub fn new(
        region: u32,
        ellipsoid: &Ellipsoid,
        loops: &[Vec<DVec3>],
    ) -> Result<RegionChart, super::RemeshError> {
        let _ = region;
        let probe = RegionChart::with_pole(ellipsoid, DVec3::Z);
        let sum: DVec3 = loops.iter().flatten().map(|&p| probe.to_sphere(p)).sum();
        let pole = (-sum).try_normalize().unwrap_or(DVec3::Z);
        Ok(RegionChart::with_pole(ellipsoid, pole))
    }

    /// The chart whose projection centre (the point mapped to infinity) is `pole`, a
    /// direction on the unit sphere of `ellipsoid`.
    pub fn with_pole(ellipsoid: &Ellipsoid, pole: DVec3) -> RegionChart {
        let pole = pole.try_normalize().unwrap_or(DVec3::Z);
        RegionChart {
            ellipsoid: *ellipsoid,
            rotation: DQuat::from_rotation_arc(pole, DVec3::Z),
        }
    }

    /// A point (on or near the ellipsoid) → its radial projection's unit-sphere direction.
    pub fn to_sphere(&self, p: DVec3) -> DVec3 {
        self.ellipsoid
            .to_unit_sphere(p)
            .try_normalize()
            .unwrap_or(DVec3::X)
    }

    /// Unit-sphere direction → plane, stereographically from the north pole after rotation.
    pub fn sphere_to_plane(&self, u: DVec3) -> DVec2 {
        let v = self.rotation * u;
        // The pole itself goes to a far but finite point.
        let d = (1.0 - v.z).max(1e-300);
        DVec2::new(v.x / d, v.y / d)
    }

    /// Plane → unit-sphere direction (inverse of [`RegionChart::sphere_to_plane`]).
    pub fn plane_to_sphere(&self, q: DVec2) -> DVec3 {
        let s = q.length_squared();
        let d = 1.0 + s;
        let v = DVec3::new(2.0 * q.x / d, 2.0 * q.y / d, (s - 1.0) / d);
        self.rotation.inverse() * v
    }

    /// A point (on or near the ellipsoid) → the plane, through its radial projection.
    pub fn to_plane(&self, p: DVec3) -> DVec2 {
        self.sphere_to_plane(self.to_sphere(p))
    }

    /// Plane → the point on the ellipsoid.
    pub fn from_plane(&self, q: DVec2) -> DVec3 {
        self.ellipsoid.from_unit_sphere(self.plane_to_sphere(q))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_round_trip_is_exact_to_rounding() {
        let e = Ellipsoid {
            center: DVec3::new(0.3, -1.0, 2.0),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.4),
            radii: DVec3::new(2.0, 0.5, 1.0),
            sign: crate::ellipsoid::Sign::Positive,
        };
        let chart = RegionChart::with_pole(&e, DVec3::new(1.0, 2.0, -0.5));
        let mut rng = crate::rng::SplitMix64::new(7);
        for _ in 0..1000 {
            let u = rng.unit_vector();
            let p = e.from_unit_sphere(u);
            let back = chart.from_plane(chart.to_plane(p));
            assert!((back - p).length() < 1e-9, "{p} → {back}");
        }
    }
}
