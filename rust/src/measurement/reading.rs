//! One reading of any sensor, as a pass applies it at an epoch.

use super::depth::Depth;
use super::fix::Fix;
use super::heading::Heading;
use super::velocity::Velocity;
use crate::ekf::{Applied, Ekf};
use crate::error::Result;

/// One reading due at an epoch: its sensor's [`crate::ekf::Measurement`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reading {
    Velocity(Velocity),
    Depth(Depth),
    Fix(Fix),
    Heading(Heading),
}

impl Reading {
    /// Update `ekf` with the reading ([`Ekf::apply`]).
    pub fn apply(&self, ekf: &mut Ekf) -> Result<Applied> {
        match self {
            Reading::Velocity(m) => ekf.apply(m),
            Reading::Depth(m) => ekf.apply(m),
            Reading::Fix(m) => ekf.apply(m),
            Reading::Heading(m) => ekf.apply(m),
        }
    }

    /// The sensor's name in messages.
    pub fn name(&self) -> &'static str {
        use crate::ekf::Measurement;
        match self {
            Reading::Velocity(m) => m.name(),
            Reading::Depth(m) => m.name(),
            Reading::Fix(m) => m.name(),
            Reading::Heading(m) => m.name(),
        }
    }
}
