//! The 15-state INS/DVL error-state EKF, closed loop: the filter's state and its
//! prediction, the measurement update every sensor shares, and their parts.
//!
//! Error state `δx = [δp (NED m), δv (m/s), ψ (rad), δb_a (m/s²), δb_g (rad/s)]`, each
//! estimate minus truth; `Ĉ = (I − [ψ×]) C`; the velocity error in the coordinates of
//! the configured [`Formulation`] (`δv`, or `δV = δv − [v̂×]ψ`). Propagation
//! `Φ = I + FΔt`, `Q_d = Γ Q^c Γᵀ Δt` at every IMU sample, or over a covariance step
//! ([`FilterConfig::covariance_step`], `step`); updates in Joseph form with feedback
//! and reset ([`Ekf::apply`]). Every formula is in `docs/reference/filter.md`.
//!
//! - `state`: the error state's layout and matrix types;
//! - `filter`: [`Ekf`], its state and prediction;
//! - `step`: the covariance step;
//! - `update`: the [`Measurement`] a sensor gives and the update it runs;
//! - `joseph`: the update's Joseph form on the support of H;
//! - `dynamics`, `transition`, `formulation`, `process_noise`, `calibration`,
//!   `second_order`, `config`: the error dynamics and Φ, the two velocity-error
//!   coordinates, the noise of a step, the DVL calibration states, the second-order
//!   heading term of the position error, the tuning.

pub mod calibration;
mod config;
pub(crate) mod dynamics;
mod filter;
pub mod formulation;
mod joseph;
mod mounting;
mod process_noise;
pub mod second_order;
mod state;
mod step;
pub(crate) mod transition;
mod update;

pub use config::{
    check_lever_arm, Aiding, FilterConfig, DEFAULT_COVARIANCE_STEP, DEFAULT_P0_SIGMA,
    MAX_COVARIANCE_STEP, MAX_LEVER_ARM,
};
pub use filter::{classic_sigma, correct, corrected_position_velocity, ClosedSigma, Ekf};
pub use formulation::{Coordinates, Formulation, Point};
pub use mounting::DvlMounting;
pub use process_noise::ProcessNoise;
pub use state::{Gain, Matrix15, Row15, Rows3, Vector15, ACC_BIAS, ATT, GYRO_BIAS, NAV, POS, VEL};
pub use step::{variance_between, CovarianceStep};
pub use transition::Transition;
pub use update::{
    Applied, Linearized, Measurement, ScalarRow, UpdateInfo, VectorNoise, VectorRows,
};

#[cfg(test)]
pub(crate) mod tests;
