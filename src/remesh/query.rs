//! The analytic ray query on a whole representation: the first region surface a ray meets
//! (the use Simari & Singh 2005 motivate for the representation; regions tested by their
//! charts, section 5.1).
//!
//! Also the helpers that turn a region's cycles into boundary loops ([`region_loops`],
//! [`region_loop_points`]) and a region into its chart ([`chart_region`]), shared with the
//! remesher.

use super::chart::{is_degenerate_loop, RegionChart};
use super::RemeshError;
use crate::representation::Representation;
use glam::DVec3;

/// A region's boundary loops as pool indices: one loop per cycle, in the order of
/// `rep.cycles[region]`, each with the region on its left (outward normals up), the first
/// point not repeated at the end.
///
/// A cycle's arcs are walked in order, a reversed reference from the arc's last point to its
/// first; consecutive arcs share their junction point, which is kept once. A closed arc (a
/// cycle of its own) does not repeat its first point.
///
/// Meant for validated representations ([`Representation::validate`]): references out of
/// range are skipped, never a panic. A region out of range has no loops.
pub fn region_loops(rep: &Representation, region: u32) -> Vec<Vec<u32>> {
    let Some(cycles) = rep.cycles.get(region as usize) else {
        return Vec::new();
    };
    cycles
        .iter()
        .map(|cycle| {
            let mut points: Vec<u32> = Vec::new();
            for r in &cycle.arcs {
                let Some(arc) = rep.arcs.get(r.arc as usize) else {
                    continue;
                };
                let mut push = |p: u32| {
                    if points.last() != Some(&p) {
                        points.push(p);
                    }
                };
                if r.reversed {
                    arc.points.iter().rev().for_each(|&p| push(p));
                } else {
                    arc.points.iter().for_each(|&p| push(p));
                }
            }
            if points.len() > 1 && points.first() == points.last() {
                points.pop();
            }
            points
        })
        .collect()
}

/// A region's boundary loops as points ([`region_loops`] looked up in the pool; indices out
/// of range are skipped).
pub fn region_loop_points(rep: &Representation, region: u32) -> Vec<Vec<DVec3>> {
    region_loops(rep, region)
        .iter()
        .map(|l| {
            l.iter()
                .filter_map(|&i| rep.points.get(i as usize).copied())
                .collect()
        })
        .collect()
}

/// The chart of one region of a representation: its ellipsoid, bounded by its cycles
/// ([`RegionChart::new`]).
///
/// Loops that enclose nothing ([`is_degenerate_loop`]: fewer than three distinct directions,
/// which real encodings produce when quantisation collapses a region of a few faces to a
/// point) are handled here rather than refused: they are dropped, the region bounded by its
/// other loops, as the remesher does (even when the dropped loop is the outer one: on a
/// closed surface which loop is outer is a choice); a region whose loops are all degenerate
/// is empty ([`RegionChart::empty`]).
///
/// Errors: the region does not exist, or its boundary is unusable.
pub fn chart_region(rep: &Representation, region: u32) -> Result<RegionChart, RemeshError> {
    let ellipsoid = rep
        .ellipsoids
        .get(region as usize)
        .ok_or(RemeshError::Region {
            region,
            what: "region out of range",
        })?;
    let cycles = rep.cycles.get(region as usize).map_or(&[][..], |c| c);
    let mut loops = Vec::new();
    for points in region_loop_points(rep, region) {
        if !is_degenerate_loop(ellipsoid, &points) {
            loops.push(points);
        }
    }
    if loops.is_empty() && !cycles.is_empty() {
        // Every loop was degenerate: nothing is enclosed.
        return Ok(RegionChart::empty(ellipsoid));
    }
    RegionChart::new(region, ellipsoid, &loops)
}

/// Where a ray first meets the represented surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter: the hit is at `origin + t · direction`.
    pub t: f64,
    /// The hit point, on the region's ellipsoid.
    pub point: DVec3,
    /// The surface's unit normal there as the ellipsoid's sign orients it (outward for a
    /// positive ellipsoid, inward for a negative one: the mesh's outward side); the
    /// normalised [`crate::ellipsoid::Ellipsoid::normal`].
    pub normal: DVec3,
    /// The region hit.
    pub region: u32,
}

/// The analytic ray query: every region's chart, built once.
#[derive(Debug, Clone)]
pub struct RayQuery {
    /// One chart per region, in region order.
    charts: Vec<RegionChart>,
}

impl RayQuery {
    /// Builds every region's chart. Errors: the representation breaks a rule of the format
    /// ([`RemeshError::Invalid`]), or a region's boundary cannot be charted
    /// ([`RemeshError::Region`]).
    pub fn new(rep: &Representation) -> Result<RayQuery, RemeshError> {
        rep.validate()?;
        let charts = (0..rep.region_count())
            .map(|r| chart_region(rep, r as u32))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(RayQuery { charts })
    }

    /// The charts, one per region.
    pub fn charts(&self) -> &[RegionChart] {
        &self.charts
    }

    /// The regions whose chart contains the radial projection of `p` onto their ellipsoid.
    pub fn regions_containing(&self, p: DVec3) -> Vec<u32> {
        (0..self.charts.len() as u32)
            .filter(|&r| self.charts.get(r as usize).is_some_and(|c| c.contains(p)))
            .collect()
    }

    /// The first hit with `t > 0` of the ray `origin + t · direction` (`direction` need not
    /// be unit): over all regions, the smallest root of the ray/ellipsoid intersection that
    /// lands inside the region. `None` when it misses everything, or for a zero or
    /// non-finite ray.
    pub fn first_hit(&self, origin: DVec3, direction: DVec3) -> Option<Hit> {
        self.first_hit_beyond(origin, direction, 0.0)
    }

    /// Like [`RayQuery::first_hit`], counting only hits with `t > t_min` (e.g. a small
    /// positive value for rays leaving the surface).
    pub fn first_hit_beyond(&self, origin: DVec3, direction: DVec3, t_min: f64) -> Option<Hit> {
        if !(origin.is_finite() && direction.is_finite()) || t_min.is_nan() {
            return None;
        }
        let mut best: Option<Hit> = None;
        for (region, chart) in self.charts.iter().enumerate() {
            let Some(roots) = chart.ellipsoid.intersect_ray(origin, direction) else {
                continue;
            };
            let bound = best.map_or(f64::INFINITY, |h| h.t);
            for t in roots {
                if !(t > t_min && t < bound) {
                    continue;
                }
                let point = origin + t * direction;
                if chart.contains(point) {
                    best = Some(Hit {
                        t,
                        point,
                        // Normalised: a decoded rotation is unit only to ~10⁻⁶.
                        normal: chart
                            .ellipsoid
                            .normal(point)
                            .try_normalize()
                            .unwrap_or(DVec3::Z),
                        region: region as u32,
                    });
                    // The roots are increasing: the second cannot be nearer.
                    break;
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ellipsoid::{Ellipsoid, Sign};
    use crate::representation::{Arc, ArcRef, Cycle, Side};
    use crate::rng::SplitMix64;
    use glam::DQuat;

    fn ellipsoid(sign: Sign) -> Ellipsoid {
        Ellipsoid {
            center: DVec3::new(1.0, 0.5, -0.3),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.7, -0.2, 1.3),
            radii: DVec3::new(1.5, 0.8, 1.1),
            sign,
        }
    }

    /// One region, no cycles: the whole ellipsoid. The hit is exactly the first positive root
    /// of `intersect_ray`, with the signed normal.
    #[test]
    fn a_whole_ellipsoid_hits_at_the_first_positive_root() {
        for sign in [Sign::Positive, Sign::Negative] {
            let e = ellipsoid(sign);
            let rep = Representation {
                ellipsoids: vec![e],
                cycles: vec![vec![]],
                ..Representation::default()
            };
            let query = RayQuery::new(&rep).unwrap();
            let mut rng = SplitMix64::new(21);
            let mut hits = 0;
            for _ in 0..2000 {
                let origin = e.center + rng.unit_vector() * rng.range_f64(0.0, 4.0);
                let direction = rng.unit_vector() * rng.range_f64(0.1, 3.0);
                let expected = e
                    .intersect_ray(origin, direction)
                    .and_then(|[t0, t1]| [t0, t1].into_iter().find(|&t| t > 0.0));
                let hit = query.first_hit(origin, direction);
                assert_eq!(hit.map(|h| h.t), expected);
                if let Some(h) = hit {
                    hits += 1;
                    assert_eq!(h.region, 0);
                    assert_eq!(h.point, origin + h.t * direction);
                    assert!((h.normal - e.normal(h.point)).length() < 1e-12);
                }
            }
            assert!(hits > 500, "{hits}");
        }
        let rep = Representation {
            ellipsoids: vec![ellipsoid(Sign::Positive)],
            cycles: vec![vec![]],
            ..Representation::default()
        };
        let query = RayQuery::new(&rep).unwrap();
        assert_eq!(query.first_hit(DVec3::ZERO, DVec3::ZERO), None);
        assert_eq!(query.first_hit(DVec3::NAN, DVec3::X), None);
    }

    /// Two regions of one sphere split by the equator, stored as one closed arc: above the
    /// equator region 0, below region 1; the loops come out of the cycles in the stated
    /// orientation and the query finds the right half.
    #[test]
    fn two_hemispheres_split_by_a_closed_arc() {
        let e = Ellipsoid::sphere(DVec3::ZERO, 2.0);
        let n = 64;
        let points: Vec<DVec3> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                DVec3::new(2.0 * a.cos(), 2.0 * a.sin(), 0.0)
            })
            .collect();
        let rep = Representation {
            ellipsoids: vec![e, e],
            points,
            arcs: vec![Arc {
                points: (0..n as u32).collect(),
                closed: true,
                left: 0,
                right: Side::Region(1),
            }],
            cycles: vec![
                vec![Cycle {
                    arcs: vec![ArcRef {
                        arc: 0,
                        reversed: false,
                    }],
                    outer: true,
                }],
                vec![Cycle {
                    arcs: vec![ArcRef {
                        arc: 0,
                        reversed: true,
                    }],
                    outer: true,
                }],
            ],
            ..Representation::default()
        };
        let loops = region_loops(&rep, 1);
        assert_eq!(loops.len(), 1);
        assert_eq!(loops[0].len(), n);
        assert_eq!(loops[0][0], n as u32 - 1);
        let query = RayQuery::new(&rep).unwrap();
        let mut rng = SplitMix64::new(22);
        for _ in 0..1000 {
            let u = rng.unit_vector();
            if u.z.abs() < 0.02 {
                continue;
            }
            let hit = query.first_hit(u * 5.0, -u).unwrap();
            assert!((hit.t - 3.0).abs() < 1e-12);
            assert_eq!(hit.region, u32::from(u.z < 0.0));
            assert!((hit.normal - u).length() < 1e-12);
            assert_eq!(query.regions_containing(u), vec![u32::from(u.z < 0.0)]);
        }
    }

    /// Open arcs: a cycle of three arcs meeting at junctions gives each junction once.
    #[test]
    fn open_arcs_share_their_junctions_once() {
        let e = Ellipsoid::sphere(DVec3::ZERO, 1.0);
        let points: Vec<DVec3> = (0..6)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 6.0;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let arc = |p: Vec<u32>| Arc {
            points: p,
            closed: false,
            left: 0,
            right: Side::Region(1),
        };
        let rep = Representation {
            ellipsoids: vec![e, e],
            points,
            arcs: vec![arc(vec![0, 1, 2]), arc(vec![2, 3, 4]), arc(vec![4, 5, 0])],
            cycles: vec![
                vec![Cycle {
                    arcs: (0..3)
                        .map(|a| ArcRef {
                            arc: a,
                            reversed: false,
                        })
                        .collect(),
                    outer: true,
                }],
                vec![Cycle {
                    arcs: (0..3)
                        .rev()
                        .map(|a| ArcRef {
                            arc: a,
                            reversed: true,
                        })
                        .collect(),
                    outer: true,
                }],
            ],
            ..Representation::default()
        };
        rep.validate().unwrap();
        assert_eq!(region_loops(&rep, 0), vec![vec![0, 1, 2, 3, 4, 5]]);
        assert_eq!(region_loops(&rep, 1), vec![vec![0, 5, 4, 3, 2, 1]]);
        assert!(region_loops(&rep, 7).is_empty());
        assert!(matches!(
            chart_region(&rep, 7),
            Err(RemeshError::Region { region: 7, .. })
        ));
    }

    /// A sphere: region 0 above the equator; region 1 below it, with a hole around region 2,
    /// whose closed boundary arc quantised to three copies of one point (as real encodings
    /// produce for regions of a few faces). Region 2 is empty, region 1's degenerate hole is
    /// dropped, and the query still answers.
    #[test]
    fn degenerate_loops_give_empty_regions_and_dropped_holes() {
        let e = Ellipsoid::sphere(DVec3::ZERO, 1.0);
        let n = 32u32;
        let mut points: Vec<DVec3> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        points.extend([DVec3::new(0.0, 0.0, -1.0); 3]);
        let single = |arc: u32, reversed: bool, outer: bool| Cycle {
            arcs: vec![ArcRef { arc, reversed }],
            outer,
        };
        let rep = Representation {
            ellipsoids: vec![e, e, e],
            points,
            arcs: vec![
                Arc {
                    points: (0..n).collect(),
                    closed: true,
                    left: 0,
                    right: Side::Region(1),
                },
                Arc {
                    points: vec![n, n + 1, n + 2],
                    closed: true,
                    left: 2,
                    right: Side::Region(1),
                },
            ],
            cycles: vec![
                vec![single(0, false, true)],
                vec![single(0, true, true), single(1, true, false)],
                vec![single(1, false, true)],
            ],
            ..Representation::default()
        };
        rep.validate().unwrap();
        // RegionChart::new itself refuses the degenerate loop.
        assert!(matches!(
            RegionChart::new(2, &e, &region_loop_points(&rep, 2)),
            Err(RemeshError::Region { region: 2, .. })
        ));
        let query = RayQuery::new(&rep).unwrap();
        let charts = query.charts();
        assert!(charts[2].is_empty() && !charts[2].is_whole());
        assert_eq!(charts[1].plane_loops().len(), 1);
        assert_eq!(
            query.regions_containing(DVec3::new(0.0, 0.0, -1.0)),
            vec![1]
        );
        assert_eq!(query.regions_containing(DVec3::new(0.1, 0.2, 0.9)), vec![0]);
        let hit = query
            .first_hit(DVec3::new(0.0, 0.0, -3.0), DVec3::Z)
            .unwrap();
        assert_eq!((hit.region, hit.t), (1, 2.0));
    }
}
