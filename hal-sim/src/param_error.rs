//! Why a parameter set was rejected: one error type for every parameter struct of the
//! simulator (the gyro's, the resonator's, the pick-off's, the board's), in a module of its own
//! so that they all use it without importing each other.

/// Why a parameter set was rejected.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamError {
    /// A field is not finite or out of its range; the text says which and why.
    OutOfRange(&'static str),
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ParamError::OutOfRange(what) => write!(f, "parameter out of range: {what}"),
        }
    }
}

impl std::error::Error for ParamError {}
