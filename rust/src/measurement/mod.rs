//! The measurements of the aiding sensors, each a [`crate::ekf::Measurement`]: for one
//! reading at the filter's estimate, its innovation, Jacobian rows, noise, lever arm
//! and gate; the update itself is the filter's ([`crate::ekf::Ekf::apply`]).
//!
//! - [`Velocity`] (`velocity`): a DVL's body-frame velocity (with the calibration
//!   states) or a NED velocity, at a lever arm;
//! - [`Depth`] (`depth`): a pressure sensor at a lever arm;
//! - [`Fix`] (`fix`): a position fix of an antenna or transponder at a lever arm;
//! - [`Heading`] (`heading`): the yaw from a compass, an AHRS or a gyrocompass;
//! - [`Reading`] (`reading`): one reading of any of them, as a pass applies it.

mod depth;
mod fix;
mod heading;
mod reading;
mod velocity;

pub use depth::{check_depth_sigma, Depth};
pub use fix::Fix;
pub use heading::Heading;
pub use reading::Reading;
pub use velocity::Velocity;
