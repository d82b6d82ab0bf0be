//! The one error type of the core. Every fallible public function returns it; the
//! Python bindings map [`Error::InvalidArgument`] to `ValueError`.

use std::fmt;

/// What went wrong, with the name of the offending argument where there is one.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// A caller-supplied value is unusable: `arg` names it, `reason` says why.
    InvalidArgument { arg: String, reason: String },
    /// The numerics failed (for example a singular innovation covariance).
    Numerical(String),
    /// The caller cancelled the call ([`crate::cancel::Cancel`]).
    Cancelled,
}

impl Error {
    pub fn invalid(arg: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::InvalidArgument {
            arg: arg.into(),
            reason: reason.into(),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidArgument { arg, reason } => write!(f, "{arg}: {reason}"),
            Error::Numerical(msg) => write!(f, "numerical failure: {msg}"),
            Error::Cancelled => write!(f, "cancelled"),
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;

/// Checks shared by every entry point.
pub mod check {
    use super::{Error, Result};

    pub fn finite(arg: &str, values: &[f64]) -> Result<()> {
        match values.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(i) => Err(Error::invalid(
                arg,
                format!("must be finite, element {i} is {}", values[i]),
            )),
        }
    }

    pub fn positive(arg: &str, value: f64) -> Result<()> {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(Error::invalid(
                arg,
                format!("must be finite and > 0, got {value}"),
            ))
        }
    }

    pub fn non_negative(arg: &str, values: &[f64]) -> Result<()> {
        finite(arg, values)?;
        match values.iter().position(|v| *v < 0.0) {
            None => Ok(()),
            Some(i) => Err(Error::invalid(
                arg,
                format!("must be >= 0 (a variance), element {i} is {}", values[i]),
            )),
        }
    }

    /// Strictly increasing, finite sequence.
    pub fn increasing(arg: &str, values: &[f64]) -> Result<()> {
        finite(arg, values)?;
        match values.windows(2).position(|w| w[1] <= w[0]) {
            None => Ok(()),
            Some(i) => Err(Error::invalid(
                arg,
                format!(
                    "must increase strictly, but element {} ({}) <= element {} ({})",
                    i + 1,
                    values[i + 1],
                    i,
                    values[i]
                ),
            )),
        }
    }
}
