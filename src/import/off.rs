//! OFF reader. (Being written.)

use super::{ImportLimits, ParseError, Problem, Soup};

/// Parses a OFF file.
pub(crate) fn parse(_bytes: &[u8], _limits: &ImportLimits) -> Result<Soup, ParseError> {
    Err(ParseError::whole(Problem::Unsupported {
        what: "OFF reading is not implemented yet".into(),
    }))
}
