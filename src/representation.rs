//! The analytic representation of a mesh: one ellipsoid per region, the boundary curves
//! between regions, and each region's boundary cycles (Simari & Singh 2005, sections 4–5).
//!
//! This is the one type the `.ellip` codec ([`crate::format`]) writes and reads, and the one
//! the remesher reads. It mirrors [`crate::boundary::BoundaryGraph`] so that the conversion is
//! direct ([`Representation::from_boundary`]), with mesh vertex indices replaced by indices
//! into a pool of boundary points:
//!
//! - [`Representation::points`]: the boundary-vertex pool (junctions and arc interiors);
//! - [`Arc`]: a chain of pool indices, stored once and shared by the two regions it separates
//!   (which is what makes a decoded mesh watertight);
//! - [`Cycle`]: a closed sequence of signed arc references with its region on the left.
//!
//! [`Representation::validate`] checks every invariant the specification (`spec/ELLIP.md`,
//! section 6) lists; the decoder calls it on everything it reads.

use crate::boundary::{self, BoundaryGraph};
use crate::ellipsoid::Ellipsoid;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// Largest tolerated |‖q‖² − 1| of a stored rotation quaternion (spec, section 6.2).
pub const ROTATION_NORM_TOLERANCE: f64 = 1e-5;

/// A mesh as ellipsoidal regions and their boundaries.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Representation {
    /// One ellipsoid per region; the region count is `ellipsoids.len()`.
    pub ellipsoids: Vec<Ellipsoid>,
    /// The boundary-vertex pool.
    pub points: Vec<DVec3>,
    /// The boundary arcs.
    pub arcs: Vec<Arc>,
    /// For each region, its boundary cycles (empty for a region without boundary).
    pub cycles: Vec<Vec<Cycle>>,
    /// Where the representation came from and how it was made.
    pub metadata: Metadata,
}

/// What lies on the right of an arc.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Side {
    /// Another region.
    Region(u32),
    /// The mesh border.
    Border,
}

impl Side {
    /// The region on this side, if any.
    pub fn region(self) -> Option<u32> {
        match self {
            Side::Region(r) => Some(r),
            Side::Border => None,
        }
    }
}

/// A boundary curve: a chain of pool points between two junctions, or a closed loop.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Arc {
    /// Indices into [`Representation::points`], in order. For an open arc the first and last
    /// are its junctions; a closed loop does not repeat its first point at the end.
    pub points: Vec<u32>,
    /// Whether the arc is a closed loop without junctions.
    pub closed: bool,
    /// The region on the arc's left when walked from first to last point (outward normals up).
    pub left: u32,
    /// What is on its right.
    pub right: Side,
}

/// An arc used forward or backward in a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ArcRef {
    /// Index into [`Representation::arcs`].
    pub arc: u32,
    /// Walked from last point to first.
    pub reversed: bool,
}

/// One closed boundary of a region, with the region on its left.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Cycle {
    /// The arcs in order; each ends where the next starts, the last where the first starts.
    pub arcs: Vec<ArcRef>,
    /// Whether this is the region's outer boundary (exactly one per region that has cycles).
    pub outer: bool,
}

/// Facts about the source and the encoding; none is needed to decode the geometry.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Metadata {
    /// Vertex count of the source mesh.
    pub source_vertices: u64,
    /// Face count of the source mesh.
    pub source_faces: u64,
    /// Tolerance the arcs were simplified with ([`Representation::simplify_arcs`]), in model
    /// units, if they were.
    pub simplify_tolerance: Option<f64>,
    /// Measured symmetric RMS distance between the decoded mesh and its source, in model
    /// units, if measured ([`crate::encode::measure_encoding`]).
    pub measured_error: Option<f64>,
    /// Measured symmetric Hausdorff distance between the decoded mesh and its source, in
    /// model units, if measured ([`crate::encode::measure_encoding`]).
    pub measured_hausdorff: Option<f64>,
    /// Suggested total vertex count for remeshing.
    pub suggested_vertices: Option<u64>,
    /// Which of the reference remesher's boundary treatments meshed the file clean when it
    /// was written ([`crate::remesh::assemble::Treatment::code`]); a remesher tries it
    /// first. A hint: a value that names no treatment is ignored. Format 1.1 (spec §6.1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub remesh_hint: Option<u64>,
}

/// Which part of a representation an invariant concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Part {
    /// [`Representation::ellipsoids`].
    Ellipsoids,
    /// [`Representation::points`].
    Points,
    /// [`Representation::arcs`].
    Arcs,
    /// [`Representation::cycles`].
    Cycles,
    /// [`Representation::metadata`].
    Metadata,
}

/// A broken invariant, naming the rule of `spec/ELLIP.md` section 6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("invalid representation ({part:?}): {what}")]
pub struct InvalidRepresentation {
    /// Where.
    pub part: Part,
    /// Which rule, e.g. "E2: radius not positive".
    pub what: &'static str,
}

fn invalid(part: Part, what: &'static str) -> InvalidRepresentation {
    InvalidRepresentation { part, what }
}

impl Arc {
    /// The pool index the arc starts at.
    pub fn first(&self) -> Option<u32> {
        self.points.first().copied()
    }

    /// The pool index the arc ends at (for a closed loop: its first point).
    pub fn last(&self) -> Option<u32> {
        if self.closed {
            self.first()
        } else {
            self.points.last().copied()
        }
    }

    /// Start and end of the arc as `r` walks it.
    fn ends(&self, reversed: bool) -> (Option<u32>, Option<u32>) {
        if reversed {
            (self.last(), self.first())
        } else {
            (self.first(), self.last())
        }
    }
}

impl Representation {
    /// The number of regions.
    pub fn region_count(&self) -> usize {
        self.ellipsoids.len()
    }

    /// Builds a representation from a segmentation's ellipsoids and boundary graph: the pool
    /// is the graph's boundary vertices (in its order), each arc's mesh indices become pool
    /// indices. The result is validated.
    pub fn from_boundary(
        ellipsoids: Vec<Ellipsoid>,
        positions: &[DVec3],
        graph: &BoundaryGraph,
        metadata: Metadata,
    ) -> Result<Representation, InvalidRepresentation> {
        let mut pool_index = HashMap::with_capacity(graph.vertices.len());
        let mut points = Vec::with_capacity(graph.vertices.len());
        for &v in &graph.vertices {
            let p = positions
                .get(v as usize)
                .ok_or(invalid(Part::Points, "P2: boundary vertex not in the mesh"))?;
            let next = u32::try_from(points.len())
                .map_err(|_| invalid(Part::Points, "P3: too many points"))?;
            pool_index.entry(v).or_insert_with(|| {
                points.push(*p);
                next
            });
        }
        let mut arcs = Vec::with_capacity(graph.arcs.len());
        for a in &graph.arcs {
            let chain = a
                .vertices
                .iter()
                .map(|v| pool_index.get(v).copied())
                .collect::<Option<Vec<u32>>>()
                .ok_or(invalid(Part::Arcs, "A3: arc vertex not a boundary vertex"))?;
            arcs.push(Arc {
                points: chain,
                closed: a.closed,
                left: a.left,
                right: match a.right {
                    boundary::Side::Region(r) => Side::Region(r),
                    boundary::Side::Border => Side::Border,
                },
            });
        }
        let cycles = graph
            .cycles
            .iter()
            .map(|cs| {
                cs.iter()
                    .map(|c| Cycle {
                        arcs: c
                            .arcs
                            .iter()
                            .map(|r| ArcRef {
                                arc: r.arc,
                                reversed: r.reversed,
                            })
                            .collect(),
                        outer: c.outer,
                    })
                    .collect()
            })
            .collect();
        let rep = Representation {
            ellipsoids,
            points,
            arcs,
            cycles,
            metadata,
        };
        rep.validate()?;
        Ok(rep)
    }

    /// Checks every invariant of `spec/ELLIP.md` section 6 (rules E1–E4, P1, P3, A1–A5,
    /// C1–C6, M1).
    pub fn validate(&self) -> Result<(), InvalidRepresentation> {
        self.validate_ellipsoids()?;
        self.validate_points()?;
        self.validate_arcs()?;
        self.validate_cycles()?;
        self.validate_metadata()
    }

    fn validate_ellipsoids(&self) -> Result<(), InvalidRepresentation> {
        if u32::try_from(self.ellipsoids.len()).is_err() {
            return Err(invalid(Part::Ellipsoids, "E4: too many regions"));
        }
        for e in &self.ellipsoids {
            if !(e.center.is_finite() && e.rotation.is_finite() && e.radii.is_finite()) {
                return Err(invalid(Part::Ellipsoids, "E1: parameter not finite"));
            }
            if e.radii.min_element() <= 0.0 {
                return Err(invalid(Part::Ellipsoids, "E2: radius not positive"));
            }
            if (e.rotation.length_squared() - 1.0).abs() > ROTATION_NORM_TOLERANCE {
                return Err(invalid(Part::Ellipsoids, "E3: rotation not normalised"));
            }
        }
        Ok(())
    }

    fn validate_points(&self) -> Result<(), InvalidRepresentation> {
        if u32::try_from(self.points.len()).is_err() {
            return Err(invalid(Part::Points, "P3: too many points"));
        }
        if self.points.iter().any(|p| !p.is_finite()) {
            return Err(invalid(Part::Points, "P1: point not finite"));
        }
        Ok(())
    }

    fn validate_arcs(&self) -> Result<(), InvalidRepresentation> {
        let regions = self.ellipsoids.len();
        let points = self.points.len();
        for a in &self.arcs {
            if a.left as usize >= regions {
                return Err(invalid(Part::Arcs, "A1: left region out of range"));
            }
            if let Side::Region(r) = a.right {
                if r as usize >= regions {
                    return Err(invalid(Part::Arcs, "A2: right region out of range"));
                }
                if r == a.left {
                    return Err(invalid(Part::Arcs, "A2: arc between a region and itself"));
                }
            }
            if a.points.iter().any(|&i| i as usize >= points) {
                return Err(invalid(Part::Arcs, "A3: point index out of range"));
            }
            let n = a.points.len();
            let min_len = match (a.closed, a.first() == a.points.last().copied()) {
                (true, _) => 3,
                (false, false) => 2,
                (false, true) => 4,
            };
            if n < min_len {
                return Err(invalid(Part::Arcs, "A4: arc too short"));
            }
            let repeats = a.points.windows(2).any(|w| w[0] == w[1])
                || (a.closed && a.points.first() == a.points.last());
            if repeats {
                return Err(invalid(Part::Arcs, "A5: point repeated consecutively"));
            }
        }
        Ok(())
    }

    fn validate_cycles(&self) -> Result<(), InvalidRepresentation> {
        if self.cycles.len() != self.ellipsoids.len() {
            return Err(invalid(
                Part::Cycles,
                "C1: cycle lists do not match regions",
            ));
        }
        // Uses of each arc: bit 0 forward, bit 1 reversed.
        let mut used = vec![0u8; self.arcs.len()];
        for (region, cycles) in self.cycles.iter().enumerate() {
            if !cycles.is_empty() && cycles.iter().filter(|c| c.outer).count() != 1 {
                return Err(invalid(Part::Cycles, "C6: not exactly one outer cycle"));
            }
            for cycle in cycles {
                self.validate_cycle(region, cycle, &mut used)?;
            }
        }
        for (a, u) in self.arcs.iter().zip(&used) {
            let expected = match a.right {
                Side::Region(_) => 3,
                Side::Border => 1,
            };
            if *u != expected {
                return Err(invalid(Part::Cycles, "C5: arc not used once per side"));
            }
        }
        Ok(())
    }

    fn validate_cycle(
        &self,
        region: usize,
        cycle: &Cycle,
        used: &mut [u8],
    ) -> Result<(), InvalidRepresentation> {
        if cycle.arcs.is_empty() {
            return Err(invalid(Part::Cycles, "C2: empty cycle"));
        }
        let mut ends = Vec::with_capacity(cycle.arcs.len());
        for r in &cycle.arcs {
            let (Some(arc), Some(use_slot)) =
                (self.arcs.get(r.arc as usize), used.get_mut(r.arc as usize))
            else {
                return Err(invalid(Part::Cycles, "C2: arc reference out of range"));
            };
            let on_left = if r.reversed {
                arc.right == Side::Region(region as u32)
            } else {
                arc.left as usize == region
            };
            if !on_left {
                return Err(invalid(Part::Cycles, "C3: region not on the arc's side"));
            }
            let bit = if r.reversed { 2 } else { 1 };
            if *use_slot & bit != 0 {
                return Err(invalid(Part::Cycles, "C5: arc used twice on one side"));
            }
            *use_slot |= bit;
            if arc.closed && cycle.arcs.len() != 1 {
                return Err(invalid(Part::Cycles, "C4: closed arc shares a cycle"));
            }
            ends.push(arc.ends(r.reversed));
        }
        for (i, &(_, end)) in ends.iter().enumerate() {
            let next = ends.get(i + 1).or(ends.first()).map(|e| e.0);
            if end.is_none() || next != Some(end) {
                return Err(invalid(Part::Cycles, "C4: cycle not closed"));
            }
        }
        Ok(())
    }

    fn validate_metadata(&self) -> Result<(), InvalidRepresentation> {
        let m = &self.metadata;
        let bad = |v: Option<f64>| v.is_some_and(|x| !(x.is_finite() && x >= 0.0));
        if bad(m.simplify_tolerance) || bad(m.measured_error) || bad(m.measured_hausdorff) {
            return Err(invalid(
                Part::Metadata,
                "M1: value not finite and non-negative",
            ));
        }
        Ok(())
    }

    /// Simplifies every arc by Douglas–Peucker in 3D (D. Douglas and T. Peucker, 1973) with
    /// `tolerance` in model units — the paper's future-work note (Simari & Singh 2005,
    /// section 7). Junctions (open arcs' endpoints), any point used more than once, and the
    /// first point of each closed loop and the point farthest from it are kept; a closed loop
    /// keeps at least three points. Points no longer used are removed from the pool.
    ///
    /// Returns how many pool points were removed.
    pub fn simplify_arcs(&mut self, tolerance: f64) -> usize {
        self.simplify_arcs_except(tolerance, &[])
    }

    /// [`Representation::simplify_arcs`], leaving whole the arcs whose index is marked in
    /// `exact` (indices beyond its length are simplified).
    pub fn simplify_arcs_except(&mut self, tolerance: f64, exact: &[bool]) -> usize {
        let mut uses = vec![0u32; self.points.len()];
        for a in &self.arcs {
            for &i in &a.points {
                if let Some(u) = uses.get_mut(i as usize) {
                    *u = u.saturating_add(1);
                }
            }
        }
        let points = &self.points;
        for (index, a) in self.arcs.iter_mut().enumerate() {
            if exact.get(index).copied().unwrap_or(false) {
                continue;
            }
            let Some(chain) = a
                .points
                .iter()
                .map(|&i| points.get(i as usize).copied())
                .collect::<Option<Vec<DVec3>>>()
            else {
                continue;
            };
            let pinned: Vec<bool> = a
                .points
                .iter()
                .map(|&i| uses.get(i as usize).is_some_and(|&u| u > 1))
                .collect();
            // An open arc that leaves a junction and comes back to it is a ring through that
            // junction: simplify it as a closed loop (at least three distinct points) and close
            // it again, so that it keeps the four points rule A4 asks of it.
            let n = chain.len();
            let ring = !a.closed && n >= 2 && a.first() == a.last();
            let keep = if ring {
                let mut keep = crate::format::simplify::simplify_polyline(
                    &chain[..n - 1],
                    &pinned[..n - 1],
                    true,
                    tolerance,
                );
                keep.push(n - 1);
                keep
            } else {
                crate::format::simplify::simplify_polyline(&chain, &pinned, a.closed, tolerance)
            };
            a.points = keep
                .iter()
                .filter_map(|&k| a.points.get(k).copied())
                .collect();
        }
        self.metadata.simplify_tolerance = Some(tolerance);
        self.remove_unused_points()
    }

    /// Removes pool points no arc uses and renumbers the rest (keeping their order). Returns
    /// how many were removed.
    pub fn remove_unused_points(&mut self) -> usize {
        let mut new_index = vec![u32::MAX; self.points.len()];
        for a in &self.arcs {
            for &i in &a.points {
                if let Some(slot) = new_index.get_mut(i as usize) {
                    *slot = 0;
                }
            }
        }
        let mut kept = Vec::with_capacity(self.points.len());
        for (i, p) in self.points.iter().enumerate() {
            if let Some(slot) = new_index.get_mut(i) {
                if *slot == 0 {
                    *slot = kept.len() as u32;
                    kept.push(*p);
                }
            }
        }
        for a in &mut self.arcs {
            for i in &mut a.points {
                if let Some(&n) = new_index.get(*i as usize) {
                    *i = n;
                }
            }
        }
        let removed = self.points.len() - kept.len();
        self.points = kept;
        removed
    }

    /// The points of arc `arc` in order, or `None` if it does not exist or refers outside the
    /// pool.
    pub fn arc_positions(&self, arc: usize) -> Option<Vec<DVec3>> {
        self.arcs
            .get(arc)?
            .points
            .iter()
            .map(|&i| self.points.get(i as usize).copied())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::sample;

    fn rule(rep: &Representation) -> &'static str {
        rep.validate().unwrap_err().what.split(':').next().unwrap()
    }

    #[test]
    fn validation_names_the_broken_rule() {
        let good = sample::three_regions_two_junctions();
        assert_eq!(good.validate(), Ok(()));
        let mut r = good.clone();
        r.ellipsoids[0].rotation *= 1.01;
        assert_eq!(rule(&r), "E3");
        let mut r = good.clone();
        r.points[3].x = f64::INFINITY;
        assert_eq!(rule(&r), "P1");
        let mut r = good.clone();
        r.arcs[0].points.truncate(1);
        assert_eq!(rule(&r), "A4");
        let mut r = good.clone();
        r.arcs[1].points[2] = r.arcs[1].points[1];
        assert_eq!(rule(&r), "A5");
        let mut r = good.clone();
        r.arcs[2].right = Side::Border;
        assert_eq!(rule(&r), "C3");
        let mut r = good.clone();
        r.cycles[1][0].outer = false;
        assert_eq!(rule(&r), "C6");
        let mut r = good.clone();
        let (a, b) = (r.cycles[0][0].arcs[0], r.cycles[0][0].arcs[1]);
        r.cycles[0] = vec![
            Cycle {
                arcs: vec![a],
                outer: true,
            },
            Cycle {
                arcs: vec![b],
                outer: false,
            },
        ];
        assert_eq!(rule(&r), "C4");
        let mut r = good.clone();
        r.cycles.pop();
        assert_eq!(rule(&r), "C1");
        let mut r = good;
        r.metadata.measured_error = Some(-1.0);
        assert_eq!(rule(&r), "M1");
    }

    #[test]
    fn boundary_graphs_convert_directly() {
        let lunes = sample::three_regions_two_junctions();
        // The same topology as a boundary graph over a "mesh" whose vertex 2i holds pool
        // point i (odd vertices are not on any boundary).
        let positions: Vec<DVec3> = lunes
            .points
            .iter()
            .flat_map(|&p| [p, DVec3::splat(9.0)])
            .collect();
        let graph = BoundaryGraph {
            vertices: (0..lunes.points.len() as u32).map(|i| 2 * i).collect(),
            junctions: vec![0, 2],
            arcs: lunes
                .arcs
                .iter()
                .map(|a| boundary::Arc {
                    vertices: a.points.iter().map(|&i| 2 * i).collect(),
                    closed: a.closed,
                    left: a.left,
                    right: match a.right {
                        Side::Region(r) => boundary::Side::Region(r),
                        Side::Border => boundary::Side::Border,
                    },
                })
                .collect(),
            cycles: lunes
                .cycles
                .iter()
                .map(|cs| {
                    cs.iter()
                        .map(|c| boundary::Cycle {
                            arcs: c
                                .arcs
                                .iter()
                                .map(|r| boundary::ArcRef {
                                    arc: r.arc,
                                    reversed: r.reversed,
                                })
                                .collect(),
                            outer: c.outer,
                        })
                        .collect()
                })
                .collect(),
        };
        let rep = Representation::from_boundary(
            lunes.ellipsoids.clone(),
            &positions,
            &graph,
            lunes.metadata.clone(),
        )
        .unwrap();
        assert_eq!(rep, lunes);
        let mut broken = graph;
        broken.arcs[0].vertices[1] = 1; // not a boundary vertex
        assert!(Representation::from_boundary(
            lunes.ellipsoids.clone(),
            &positions,
            &broken,
            Metadata::default()
        )
        .is_err());
    }

    /// An open arc that leaves a junction and returns to it (found encoding teddy at K = 32)
    /// keeps the four points rule A4 asks for, however coarse the tolerance.
    #[test]
    fn a_ring_through_a_junction_stays_a_ring() {
        let circle: Vec<DVec3> = (0..24)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / 24.0;
                DVec3::new(t.cos(), t.sin(), 0.0)
            })
            .collect();
        let mut chain: Vec<u32> = (0..24).collect();
        chain.push(0);
        let mut rep = Representation {
            ellipsoids: vec![Ellipsoid::sphere(DVec3::ZERO, 1.0); 2],
            points: circle,
            arcs: vec![Arc {
                points: chain,
                closed: false,
                left: 0,
                right: Side::Region(1),
            }],
            cycles: vec![Vec::new(), Vec::new()],
            metadata: Metadata::default(),
        };
        for tolerance in [1e-3, 0.1, 10.0] {
            let mut r = rep.clone();
            r.simplify_arcs(tolerance);
            let a = &r.arcs[0];
            assert!(a.points.len() >= 4, "{tolerance}: {:?}", a.points);
            assert_eq!(a.first(), a.last());
            assert!(a.points.windows(2).all(|w| w[0] != w[1]));
        }
        rep.simplify_arcs(10.0);
        assert_eq!(rep.arcs[0].points.len(), 4);
    }
}
