//! The process noise of one IMU step, as the filter consumes it.

use super::state::Matrix15;
use nalgebra::Vector3;

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

impl ProcessNoise<'_> {
    /// The variance of one gyro sample's white noise per body axis \[(rad/s)²\] over
    /// a step of `dt` \[s\]: `q_g·Δt_imu/Δt` (the `Q^c = q·Δt_imu` of
    /// [`ProcessNoise::Continuous`], whose attitude noise over the step is
    /// `q_g·Δt_imu·Δt = σ²Δt²`); zero for a discrete Q, which names no channel.
    #[inline]
    pub fn gyro_sample_variance(&self, imu_dt: f64, dt: f64) -> Vector3<f64> {
        match self {
            ProcessNoise::Continuous {
                imu_variance: q, ..
            } => Vector3::new(q[3], q[4], q[5]) * (imu_dt / dt),
            ProcessNoise::Discrete(_) => Vector3::zeros(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gyro_sample_variance_is_the_channel_variance_at_the_step_and_none_for_a_discrete_q() {
        let q = [1.0, 2.0, 3.0, 4e-6, 5e-6, 6e-6];
        let noise = ProcessNoise::Continuous {
            imu_variance: &q,
            bias_psd: &[0.0; 6],
        };
        // A 200 Hz step under imu_dt = 0.01 s: twice the per-sample variance.
        assert_eq!(
            noise.gyro_sample_variance(0.01, 0.005),
            Vector3::new(8e-6, 1e-5, 1.2e-5)
        );
        let discrete = Matrix15::identity();
        assert_eq!(
            ProcessNoise::Discrete(&discrete).gyro_sample_variance(0.01, 0.005),
            Vector3::zeros()
        );
    }
}
