//! An arbitrary [`Recipe`]: how the `roundtrip` and `remesh` targets make representations.
//! Every recipe builds a valid one ([`ellip::format::sample::build`]), so what the fuzzer
//! varies reaches past the format's checks: ellipsoids of any shape, orientation and sign,
//! loops through any points, junctions, border arcs, whole regions, any metadata (the
//! remesh hint and suggested vertex count among it).

use arbitrary::Arbitrary;
use ellip::format::sample::{Piece, RawEllipsoid, Recipe};
use ellip::representation::Metadata;

#[derive(Arbitrary, Debug)]
enum ArbPiece {
    Lunes(u8, u8),
    Loop(u8, bool),
    Whole,
}

/// A [`RawEllipsoid`]'s fields (which `build` sanitises).
#[derive(Arbitrary, Debug)]
struct ArbEllipsoid {
    center: [f64; 3],
    rotation: [f64; 4],
    radii: [f64; 3],
    negative: bool,
}

/// The fuzzer's side of a [`Recipe`].
#[derive(Arbitrary, Debug)]
pub struct ArbRecipe {
    ellipsoids: Vec<ArbEllipsoid>,
    coordinates: Vec<[f64; 3]>,
    pieces: Vec<ArbPiece>,
    metadata: (u64, u64, Option<f64>, Option<f64>, Option<u64>, Option<u64>),
}

impl ArbRecipe {
    /// The recipe, with at most 8 pieces and 32 interior points per lune arc.
    pub fn recipe(&self) -> Recipe {
        Recipe {
            ellipsoids: self
                .ellipsoids
                .iter()
                .map(|e| RawEllipsoid {
                    center: e.center,
                    rotation: e.rotation,
                    radii: e.radii,
                    negative: e.negative,
                })
                .collect(),
            coordinates: self.coordinates.clone(),
            pieces: self
                .pieces
                .iter()
                .take(8)
                .map(|p| match *p {
                    ArbPiece::Lunes(lunes, interior) => Piece::Lunes {
                        lunes,
                        interior: interior % 32,
                    },
                    ArbPiece::Loop(points, border) => Piece::Loop { points, border },
                    ArbPiece::Whole => Piece::Whole,
                })
                .collect(),
            metadata: Metadata {
                source_vertices: self.metadata.0,
                source_faces: self.metadata.1,
                simplify_tolerance: self.metadata.2,
                measured_error: self.metadata.3,
                measured_hausdorff: self.metadata.3.map(|e| 2.0 * e),
                suggested_vertices: self.metadata.4,
                remesh_hint: self.metadata.5,
            },
        }
    }
}
