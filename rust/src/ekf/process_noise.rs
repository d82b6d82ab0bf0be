//! The process noise of one IMU step, as the filter consumes it.

use super::state::Matrix15;

/// Process noise for one IMU step.
#[derive(Clone, Copy, Debug)]
pub enum ProcessNoise<'a> {
    /// `Q^c = diag(q·Δt_imu, bias_psd)`, discretized by the filter as `Γ Q^c Γᵀ Δt`:
    /// `q` the per-sample variance of each IMU channel `[f_x, f_y, f_z, ω_x, ω_y, ω_z]`
    /// \[(m/s²)², (rad/s)²\], `bias_psd` the bias random walks' PSDs.
    Continuous {
        imu_variance: &'a [f64; 6],
        bias_psd: &'a [f64; 6],
    },
    /// A discrete 15×15 matrix in the classic error coordinates, added at each IMU step
    /// (mapped into the filter's formulation first).
    Discrete(&'a Matrix15),
}
