//! The error state's layout: its size, the offsets of its 3-blocks and the matrix types
//! the filter is written in.

use nalgebra::{SMatrix, SVector};

/// The error covariance (15 × 15) and a 15-vector of errors.
pub type Matrix15 = SMatrix<f64, 15, 15>;
pub type Vector15 = SVector<f64, 15>;
/// Kalman gain of a 3-vector measurement.
pub type Gain = SMatrix<f64, 15, 3>;
/// The Jacobian rows of a 3-vector measurement over the 15 states.
pub type Rows3 = SMatrix<f64, 3, 15>;
/// The Jacobian row of a scalar measurement over the 15 states.
pub type Row15 = SMatrix<f64, 1, 15>;

/// Offsets of the 3-blocks of the error state: position \[m, NED\], velocity \[m/s\],
/// attitude \[rad\], accelerometer bias \[m/s²\], gyro bias \[rad/s\].
pub const POS: usize = 0;
pub const VEL: usize = 3;
pub const ATT: usize = 6;
pub const ACC_BIAS: usize = 9;
pub const GYRO_BIAS: usize = 12;

/// The navigation rows and columns of the error state (position, velocity, attitude).
pub const NAV: usize = 9;
