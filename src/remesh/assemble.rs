//! The regions joined into one mesh: shared boundary vertices, outward orientation, analytic
//! normals.

use super::{RemeshError, RemeshOptions, Remeshed};
use crate::representation::Representation;

/// Remeshes every region and joins them (see [`super::remesh`]).
pub fn assemble(rep: &Representation, options: &RemeshOptions) -> Result<Remeshed, RemeshError> {
    let _ = (rep, options);
    Err(RemeshError::InvalidOption {
        what: "remesh",
        value: "not implemented yet".into(),
    })
}
