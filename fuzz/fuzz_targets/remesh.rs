//! An arbitrary representation (a [`recipe::ArbRecipe`]), stored and read back with small
//! limits, remeshed by either scheme at an arbitrary budget (or the file's own), then
//! subdivided once: a mesh or a typed error, never a panic or a hang (issue 6, item 9).
//!
//! `decode_remesh` mutates bytes, and the decoder rejects most of what that makes (a
//! mutated DEFLATE stream rarely inflates); here every input is a valid file, so every
//! input reaches the remesher, with geometry no encoder would write: ellipsoids of any
//! shape, loops through any points, hints naming any treatment.
#![no_main]

use arbitrary::Arbitrary;
use ellip::format::{self, sample, EncodeOptions, Limits};
use ellip::remesh::{RemeshOptions, Scheme};
use libfuzzer_sys::fuzz_target;

#[path = "recipe.rs"]
mod recipe;
#[path = "remeshed.rs"]
mod remeshed;

#[derive(Arbitrary, Debug)]
struct Input {
    recipe: recipe::ArbRecipe,
    bits: u8,
    parametric: bool,
    /// The budget, 1 to 3 000 vertices; `None`: the file's suggested count (or the
    /// default), capped at 3 000 too (larger budgets are meshed the same way, only slower).
    vertices: Option<u16>,
}

fuzz_target!(|input: Input| {
    let rep = sample::build(&input.recipe.recipe());
    let options = EncodeOptions {
        bits: 1 + input.bits % 24,
    };
    let bytes = format::encode(&rep, &options).expect("a valid representation encodes");
    let Ok(rep) = format::decode(&bytes, &Limits::small()) else {
        return;
    };
    let options = RemeshOptions {
        vertices: input.vertices.map(|v| 1 + usize::from(v) % 3_000),
        tolerance: None,
        scheme: if input.parametric {
            Scheme::Parametric
        } else {
            Scheme::Adaptive
        },
        max_vertices: 3_000,
        subdivision: true,
        leave_out: true,
    };
    remeshed::check_remesh(&rep, &options);
});
