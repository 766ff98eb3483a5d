//! An arbitrary representation → encode → decode: equal up to the stated quantisation
//! bounds, topology and metadata exact, encoding deterministic.
#![no_main]

use arbitrary::Arbitrary;
use ellip::format::sample;
use ellip::format::{self, EncodeOptions, Limits};
use libfuzzer_sys::fuzz_target;

#[path = "recipe.rs"]
mod recipe;

#[derive(Arbitrary, Debug)]
struct Input {
    recipe: recipe::ArbRecipe,
    bits: u8,
}

fuzz_target!(|input: Input| {
    let recipe = input.recipe.recipe();
    let rep = sample::build(&recipe);
    let options = EncodeOptions {
        bits: 1 + input.bits % 24,
    };
    let bytes = format::encode(&rep, &options).expect("a valid representation encodes");
    assert_eq!(
        format::encode(&rep, &options).unwrap(),
        bytes,
        "deterministic"
    );
    let decoded = format::decode(&bytes, &Limits::default()).expect("its encoding decodes");
    let summary = format::inspect(&bytes, &Limits::default()).unwrap();
    let bound = summary.error_bound;
    // Re-encoding is byte-identical when no axis of the grid is narrower than the rounding
    // of its coordinates (spec §11).
    let grid = summary.grid;
    let well_conditioned = (0..3).all(|a| {
        let extent = grid.max[a] - grid.min[a];
        let magnitude = grid.min[a].abs().max(grid.max[a].abs());
        extent == 0.0 || extent > 2f64.powi(i32::from(grid.bits) + 4) * f64::EPSILON * magnitude
    });
    if well_conditioned {
        let again = format::encode(&decoded, &options).expect("a decoded representation encodes");
        assert!(again == bytes, "re-encoding changed the bytes");
    }

    assert_eq!(decoded.cycles, rep.cycles);
    assert_eq!(decoded.metadata, rep.metadata);
    assert_eq!(decoded.arcs.len(), rep.arcs.len());
    for i in 0..rep.arcs.len() {
        let (a, b) = (&rep.arcs[i], &decoded.arcs[i]);
        assert_eq!((a.closed, a.left, a.right), (b.closed, b.left, b.right));
        let pa = rep.arc_positions(i).unwrap();
        let pb = decoded.arc_positions(i).unwrap();
        assert_eq!(pa.len(), pb.len());
        for (p, q) in pa.iter().zip(&pb) {
            // The bound, plus the rounding of the decoder's binary64 arithmetic.
            let slack = 4.0 * f64::EPSILON * p.abs().max_element().max(1.0);
            assert!(
                (*p - *q).length() <= bound * (1.0 + 1e-9) + slack,
                "{p} {q} {bound}"
            );
        }
    }
    for (a, b) in rep.ellipsoids.iter().zip(&decoded.ellipsoids) {
        assert_eq!(a.sign, b.sign);
        // Every stored form moves the surface by at most the grid's bound (spec §6.2), plus
        // the rounding of binary64 arithmetic.
        let magnitude = a.center.length() + a.radii.max_element();
        let tolerance = bound * (1.0 + 1e-9) + 16.0 * f64::EPSILON * magnitude;
        for u in [glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z] {
            let d = (a.from_unit_sphere(u) - b.from_unit_sphere(u)).length();
            assert!(d <= tolerance, "{d} > {tolerance}");
        }
    }
});
