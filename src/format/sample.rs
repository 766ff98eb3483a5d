//! Small hand-made representations: the golden files of `fixtures/ellip/v1/`, and a builder
//! that turns any [`Recipe`] into a valid representation (for property tests and fuzzing).

use crate::ellipsoid::{Ellipsoid, Sign};
use crate::representation::{Arc, ArcRef, Cycle, Metadata, Representation, Side};
use glam::{DQuat, DVec3};

/// A point on the unit sphere at latitude `lat` and longitude `lon` (radians).
fn on_sphere(lat: f64, lon: f64) -> DVec3 {
    DVec3::new(lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin())
}

/// One region covering a whole sphere: no points, no arcs, no cycles.
pub fn sphere() -> Representation {
    Representation {
        ellipsoids: vec![Ellipsoid::sphere(DVec3::new(0.5, -0.25, 2.0), 1.5)],
        points: Vec::new(),
        arcs: Vec::new(),
        cycles: vec![Vec::new()],
        metadata: Metadata {
            source_vertices: 642,
            source_faces: 1280,
            simplify_tolerance: None,
            measured_error: None,
            measured_hausdorff: None,
            suggested_vertices: Some(642),
            remesh_hint: None,
        },
    }
}

/// Two hemispheres of an ellipsoid sharing one closed arc of 12 points (the equator).
pub fn two_hemispheres() -> Representation {
    let e = Ellipsoid {
        center: DVec3::ZERO,
        rotation: DQuat::from_rotation_z(0.3),
        radii: DVec3::new(2.0, 1.5, 1.0),
        sign: Sign::Positive,
    };
    let points = (0..12)
        .map(|i| e.from_unit_sphere(on_sphere(0.0, std::f64::consts::TAU * i as f64 / 12.0)))
        .collect();
    Representation {
        ellipsoids: vec![e, e],
        points,
        arcs: vec![Arc {
            points: (0..12).collect(),
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
        metadata: Metadata {
            source_vertices: 1000,
            source_faces: 1996,
            simplify_tolerance: Some(0.01),
            measured_error: Some(0.002),
            measured_hausdorff: Some(0.006),
            suggested_vertices: None,
            remesh_hint: None,
        },
    }
}

/// [`two_hemispheres`] with a remesh hint (format 1.1): the stored arcs, no pruning,
/// closest points but along the rays where untangling would drop points
/// ([`crate::remesh::assemble::Treatment::code`] 37).
pub fn two_hemispheres_hinted() -> Representation {
    let mut rep = two_hemispheres();
    rep.metadata.remesh_hint = Some(37);
    rep
}

/// `regions` lunes of a sphere meeting at two junctions (the poles): arc `j` runs from the
/// north to the south pole along longitude 2πj/regions with `interior` points, region `j`
/// lies between arcs `j` and `j + 1`. With `jitter` > 0 the interior points wobble
/// deterministically (like a mesh's edge path) by up to `jitter`.
pub fn lunes(regions: u32, interior: u32, jitter: f64) -> Representation {
    let k = regions.max(2);
    let mut points = vec![DVec3::Z, -DVec3::Z];
    let mut arcs = Vec::new();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut wobble = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * jitter
    };
    for j in 0..k {
        let lon = std::f64::consts::TAU * f64::from(j) / f64::from(k);
        let mut chain = vec![0u32];
        for i in 1..=interior {
            let lat = std::f64::consts::FRAC_PI_2
                - std::f64::consts::PI * f64::from(i) / f64::from(interior + 1);
            chain.push(points.len() as u32);
            points.push(on_sphere(lat + wobble(), lon + wobble()));
        }
        chain.push(1);
        arcs.push(Arc {
            points: chain,
            closed: false,
            left: j,
            right: Side::Region((j + k - 1) % k),
        });
    }
    let cycles = (0..k)
        .map(|j| {
            vec![Cycle {
                arcs: vec![
                    ArcRef {
                        arc: j,
                        reversed: false,
                    },
                    ArcRef {
                        arc: (j + 1) % k,
                        reversed: true,
                    },
                ],
                outer: true,
            }]
        })
        .collect();
    let ellipsoids = (0..k)
        .map(|j| Ellipsoid {
            center: DVec3::new(0.01 * f64::from(j), 0.0, 0.0),
            rotation: DQuat::from_rotation_z(0.1 * f64::from(j)),
            radii: DVec3::new(1.0, 1.0 + 0.05 * f64::from(j), 0.9),
            sign: if j % 2 == 0 {
                Sign::Positive
            } else {
                Sign::Negative
            },
        })
        .collect();
    Representation {
        ellipsoids,
        points,
        arcs,
        cycles,
        metadata: Metadata {
            source_vertices: 5000,
            source_faces: 9996,
            ..Metadata::default()
        },
    }
}

/// Three lunes meeting at two junctions, three interior points per arc.
pub fn three_regions_two_junctions() -> Representation {
    lunes(3, 3, 0.0)
}

/// One negative (bowl) region whose boundary is a closed loop on the mesh border, and a
/// far-away flat region (radius 10⁴, stored in binary64) without boundary.
pub fn bowl_with_border() -> Representation {
    let bowl = Ellipsoid {
        center: DVec3::new(0.0, 0.0, 1.0),
        rotation: DQuat::IDENTITY,
        radii: DVec3::new(1.0, 1.0, 1.0),
        sign: Sign::Negative,
    };
    let flat = Ellipsoid {
        center: DVec3::new(0.0, 0.0, -1e4),
        rotation: DQuat::from_rotation_x(1e-3),
        radii: DVec3::new(1e4, 1e4, 1e4),
        sign: Sign::Positive,
    };
    let points = (0..8)
        .map(|i| {
            let a = std::f64::consts::TAU * f64::from(i) / 8.0;
            DVec3::new(a.cos(), a.sin(), 1.0)
        })
        .collect();
    Representation {
        ellipsoids: vec![bowl, flat],
        points,
        arcs: vec![Arc {
            points: (0..8).collect(),
            closed: true,
            left: 0,
            right: Side::Border,
        }],
        cycles: vec![
            vec![Cycle {
                arcs: vec![ArcRef {
                    arc: 0,
                    reversed: false,
                }],
                outer: true,
            }],
            Vec::new(),
        ],
        metadata: Metadata::default(),
    }
}

/// The golden representations, by file name (without `.ellip`).
pub fn golden() -> Vec<(&'static str, Representation)> {
    vec![
        ("sphere", sphere()),
        ("two-hemispheres", two_hemispheres()),
        ("three-regions-two-junctions", three_regions_two_junctions()),
        ("bowl-with-border", bowl_with_border()),
        ("two-hemispheres-hinted", two_hemispheres_hinted()),
    ]
}

/// Ellipsoid parameters as a fuzzer or a property test produces them; sanitised by
/// [`build`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawEllipsoid {
    /// Centre.
    pub center: [f64; 3],
    /// Rotation (x, y, z, w); normalised, or the identity if it cannot be.
    pub rotation: [f64; 4],
    /// Radii; absolute values, at least 10⁻³.
    pub radii: [f64; 3],
    /// Negative sign.
    pub negative: bool,
}

/// A structure that [`build`] turns into regions and arcs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Piece {
    /// `lunes` regions (2..=8) around two junctions, `interior` points per arc.
    Lunes {
        /// Regions.
        lunes: u8,
        /// Interior points per arc.
        interior: u8,
    },
    /// A closed loop of `points` (3..) between two regions, or between a region and the
    /// border.
    Loop {
        /// Points on the loop.
        points: u8,
        /// Whether the loop is on the mesh border (one region) or between two regions.
        border: bool,
    },
    /// A region without boundary.
    Whole,
}

/// Ingredients of a representation; every recipe builds a valid one.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recipe {
    /// Ellipsoids, used in turn by the regions (a unit sphere if empty).
    pub ellipsoids: Vec<RawEllipsoid>,
    /// Coordinates, used in turn by new points (clamped to ±10⁶; non-finite → 0); if empty,
    /// points are spread on a helix.
    pub coordinates: Vec<[f64; 3]>,
    /// Structures, in order.
    pub pieces: Vec<Piece>,
    /// Metadata (non-finite or negative values are dropped).
    pub metadata: Metadata,
}

fn sanitise(v: f64) -> f64 {
    if v.is_finite() {
        v.clamp(-1e6, 1e6)
    } else {
        0.0
    }
}

fn ellipsoid_from(raw: &RawEllipsoid) -> Ellipsoid {
    let q = DQuat::from_array(raw.rotation.map(sanitise));
    let rotation = if q.length_squared() > 1e-6 {
        q.normalize()
    } else {
        DQuat::IDENTITY
    };
    Ellipsoid {
        center: DVec3::from_array(raw.center.map(sanitise)),
        rotation,
        radii: DVec3::from_array(raw.radii.map(|r| sanitise(r).abs().max(1e-3))),
        sign: if raw.negative {
            Sign::Negative
        } else {
            Sign::Positive
        },
    }
}

/// Builds the representation a recipe describes.
pub fn build(recipe: &Recipe) -> Representation {
    let mut rep = Representation::default();
    let mut next_ellipsoid = 0usize;
    let mut add_region = |rep: &mut Representation| -> u32 {
        let e = match recipe
            .ellipsoids
            .get(next_ellipsoid % recipe.ellipsoids.len().max(1))
        {
            Some(raw) => ellipsoid_from(raw),
            None => Ellipsoid::sphere(DVec3::ZERO, 1.0),
        };
        next_ellipsoid += 1;
        rep.ellipsoids.push(e);
        rep.cycles.push(Vec::new());
        (rep.ellipsoids.len() - 1) as u32
    };
    let mut next_point = 0usize;
    let mut add_point = |rep: &mut Representation| -> u32 {
        let p = match recipe
            .coordinates
            .get(next_point % recipe.coordinates.len().max(1))
        {
            Some(c) => DVec3::from_array(c.map(sanitise)),
            None => {
                let t = next_point as f64 * 0.37;
                DVec3::new(t.cos(), t.sin(), 0.01 * t)
            }
        };
        next_point += 1;
        rep.points.push(p);
        (rep.points.len() - 1) as u32
    };
    let cycle = |refs: Vec<(u32, bool)>| Cycle {
        arcs: refs
            .into_iter()
            .map(|(arc, reversed)| ArcRef { arc, reversed })
            .collect(),
        outer: true,
    };
    for piece in &recipe.pieces {
        match *piece {
            Piece::Whole => {
                add_region(&mut rep);
            }
            Piece::Loop { points, border } => {
                let left = add_region(&mut rep);
                let right = if border {
                    Side::Border
                } else {
                    Side::Region(add_region(&mut rep))
                };
                let chain = (0..points.max(3)).map(|_| add_point(&mut rep)).collect();
                let arc = rep.arcs.len() as u32;
                rep.arcs.push(Arc {
                    points: chain,
                    closed: true,
                    left,
                    right,
                });
                let has_outer = |cs: &Vec<Cycle>| cs.iter().any(|c| c.outer);
                for (region, reversed) in [(Some(left), false), (right.region(), true)] {
                    if let Some(cs) = region.and_then(|r| rep.cycles.get_mut(r as usize)) {
                        let mut c = cycle(vec![(arc, reversed)]);
                        c.outer = !has_outer(cs);
                        cs.push(c);
                    }
                }
            }
            Piece::Lunes { lunes, interior } => {
                let k = u32::from(lunes.clamp(2, 8));
                let regions: Vec<u32> = (0..k).map(|_| add_region(&mut rep)).collect();
                let (north, south) = (add_point(&mut rep), add_point(&mut rep));
                let first_arc = rep.arcs.len() as u32;
                for j in 0..k {
                    let mut chain = vec![north];
                    chain.extend((0..interior).map(|_| add_point(&mut rep)));
                    chain.push(south);
                    rep.arcs.push(Arc {
                        points: chain,
                        closed: false,
                        left: regions[j as usize],
                        right: Side::Region(regions[((j + k - 1) % k) as usize]),
                    });
                }
                for j in 0..k {
                    let c = cycle(vec![
                        (first_arc + j, false),
                        (first_arc + (j + 1) % k, true),
                    ]);
                    rep.cycles[regions[j as usize] as usize].push(c);
                }
            }
        }
    }
    let keep = |v: Option<f64>| v.filter(|x| x.is_finite() && *x >= 0.0);
    rep.metadata = Metadata {
        simplify_tolerance: keep(recipe.metadata.simplify_tolerance),
        measured_error: keep(recipe.metadata.measured_error),
        measured_hausdorff: keep(recipe.metadata.measured_hausdorff),
        ..recipe.metadata.clone()
    };
    rep
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_valid() {
        for (name, rep) in golden() {
            assert_eq!(rep.validate(), Ok(()), "{name}");
        }
        assert_eq!(lunes(7, 40, 0.01).validate(), Ok(()));
        let recipe = Recipe {
            pieces: vec![
                Piece::Whole,
                Piece::Loop {
                    points: 0,
                    border: false,
                },
                Piece::Lunes {
                    lunes: 200,
                    interior: 0,
                },
                Piece::Loop {
                    points: 5,
                    border: true,
                },
            ],
            ..Recipe::default()
        };
        let rep = build(&recipe);
        assert_eq!(rep.validate(), Ok(()));
        assert_eq!(rep.region_count(), 1 + 2 + 8 + 1);
    }
}
