//! What a simulated run reports against its truth: the per-run metrics
//! ([`RunSummary`]), the NIS and block NEES at the DVL epochs, the histories, and the
//! observer that gathers them as the run's pass goes ([`Tally`]).

use super::aiding::AidingTally;
use crate::attitude::log_so3;
use crate::earth;
use crate::ekf::DvlMounting;
use crate::ekf::{Applied, Coordinates, Ekf, Formulation, Matrix15};
use crate::ekf::{ACC_BIAS, ATT, GYRO_BIAS, POS, VEL};
use crate::measurement::Reading;
use crate::mechanization::NavState;
use crate::noise::NoiseStrategy;
use crate::pass::{Epoch, NisMonitor, Observer};
use nalgebra::{Matrix4, Vector3, Vector4};

/// Per-run scalar metrics. Velocity errors are taken at every IMU epoch.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    /// `sqrt(mean_k Σ_{N,E,D} δv²)` \[m/s\].
    pub srmse: f64,
    /// `mean_k Σ_{N,E,D} |δv|` \[m/s\].
    pub smae: f64,
    /// Horizontal position error at the end \[m\].
    pub final_horizontal_error: f64,
    /// Largest horizontal position error over the run \[m\].
    pub max_horizontal_error: f64,
    /// Mean NIS over the applied DVL updates.
    pub mean_nis: f64,
    /// DVL updates the innovation gate rejected.
    pub rejected_updates: usize,
    /// DVL readings due but missing (bottom lock lost: [`crate::sensors::DvlDropout`]).
    pub missed_updates: usize,
    /// Depth readings and position fixes applied (the aiding sensors').
    pub depth_updates: usize,
    pub fix_updates: usize,
    /// The sum of the aiding updates' NIS (depth, fix, heading), and of their degrees of
    /// freedom (its mean per degree of freedom is 1 when the filter is consistent).
    pub aiding_nis: f64,
    pub aiding_dof: usize,
    /// Time \[s\] at which the NIS showed divergence (see [`NisMonitor`]), if it did.
    pub diverged_at: Option<f64>,
    /// Set when the filter failed numerically; the run's metrics are then NaN.
    pub failure: Option<String>,
    /// With the DVL calibration states: the final `[δk, δμ]` error (estimate minus
    /// the simulated DVL's truth) and its 1σ.
    pub calibration: Option<CalibrationSummary>,
}

/// The DVL calibration states at the end of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationSummary {
    /// `[δk, δμ_x, δμ_y, δμ_z]`, estimate minus truth (scale; rad, body axes).
    pub error: [f64; 4],
    /// The filter's 1σ of the same.
    pub sigma: [f64; 4],
}

/// Recorded histories of one run, at `record_time` epochs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct History {
    /// True estimation error `[δp, δv, ψ, δb_a, δb_g]` (estimate minus truth).
    pub error: Vec<[f64; 15]>,
    /// Filter 1σ of the same states.
    pub sigma: Vec<[f64; 15]>,
    /// IMU variances q the strategy used (NaN where it has none, e.g. Mehra).
    pub imu_variance: Vec<[f64; 6]>,
}

/// Estimate-minus-truth error of the full state.
pub(super) fn state_error(ekf: &Ekf, truth: &NavState, true_bias: &[f64; 6]) -> [f64; 15] {
    solution_error(&ekf.nav, &ekf.bias(), truth, true_bias)
}

/// Estimate-minus-truth error of a solution `nav` with bias estimates `bias`.
pub(super) fn solution_error(
    nav: &NavState,
    bias: &[f64; 6],
    truth: &NavState,
    true_bias: &[f64; 6],
) -> [f64; 15] {
    let dp = earth::position_error_ned(&nav.lla, &truth.lla);
    let dv = nav.vel - truth.vel;
    // Ĉ = (I − [ψ×]) C ≈ Exp(−ψ) C.
    let psi = -log_so3(&(nav.dcm * truth.dcm.transpose()));
    let ba = Vector3::new(bias[0], bias[1], bias[2])
        - Vector3::new(true_bias[0], true_bias[1], true_bias[2]);
    let bg = Vector3::new(bias[3], bias[4], bias[5])
        - Vector3::new(true_bias[3], true_bias[4], true_bias[5]);
    let mut e = [0.0; 15];
    for (offset, v) in [
        (POS, dp),
        (VEL, dv),
        (ATT, psi),
        (ACC_BIAS, ba),
        (GYRO_BIAS, bg),
    ] {
        e[offset..offset + 3].copy_from_slice(v.as_slice());
    }
    e
}

/// `[δk, δμ]` of the filter's DVL calibration against the simulated DVL's, with its
/// NEES `eᵀ P_cc⁻¹ e` (NaN where P_cc is singular); None without the states, or where
/// only the DVL's correlated error is estimated (the scale and mounting held).
pub(super) fn calibration_error(
    ekf: &Ekf,
    truth: &DvlMounting,
) -> Option<([f64; 4], [f64; 4], f64)> {
    let c = ekf.calibration.as_ref().filter(|c| c.calibrates())?;
    let e = c.estimate.error_from(truth);
    let v = Vector4::from(e);
    let cov: Matrix4<f64> = c.cov.fixed_view::<4, 4>(0, 0).into_owned();
    let nees = cov.cholesky().map_or(f64::NAN, |ch| v.dot(&ch.solve(&v)));
    let s = c.sigma();
    Some((e, [s[0], s[1], s[2], s[3]], nees))
}

/// `eᵀ P⁻¹ e` of one 3-block (NaN where the block is singular).
pub(super) fn nees3(e: &Vector3<f64>, p: &Matrix15, block: usize) -> f64 {
    match p.fixed_view::<3, 3>(block, block).into_owned().cholesky() {
        Some(ch) => e.dot(&ch.solve(e)),
        None => f64::NAN,
    }
}

/// NEES of each 3-block, each in the coordinates where its error is linear in the
/// state (see `docs/reference/filter.md`, "Metrics"): position, attitude and biases in the
/// classic ones, velocity as the body-frame velocity error rotated to NED,
/// `δV = v̂ − Ĉ Cᵀ v` (the invariant velocity error, exact), against the invariant
/// covariance. The classic `δv` carries `[v̂×]ψ`, which is second-order wrong once
/// heading errors reach degrees; `δV` is what the DVL reads in either formulation.
///
/// In SE₂(3) the position too is taken in the filter's own coordinates,
/// `δP = p̂ − Ĉ Cᵀ p` about the anchor ([`se23_position_nees`]).
fn block_nees(ekf: &Ekf, truth: &NavState, error: &[f64; 15]) -> [f64; 5] {
    let p = ekf.covariance();
    let mut nees = [POS, VEL, ATT, ACC_BIAS, GYRO_BIAS]
        .map(|b| nees3(&Vector3::new(error[b], error[b + 1], error[b + 2]), &p, b));
    let dv = ekf.nav.vel - ekf.nav.dcm * (truth.dcm.transpose() * truth.vel);
    nees[1] = nees3(&dv, &ekf.covariance_in(Formulation::Invariant), VEL);
    let coordinates = ekf.config().coordinates();
    if coordinates.formulation.position_invariant() {
        nees[0] = se23_position_nees(&coordinates, &ekf.nav, truth, &ekf.p);
    }
    nees
}

/// The NEES of SE₂(3)'s position error `δP = p̂ − Ĉ Cᵀ p` (exact; `≈ δp − [p̂×]ψ`), the
/// displacements from the anchor of `coordinates`, against the covariance `p` in its
/// coordinates: linear in the state however large the heading error.
pub(super) fn se23_position_nees(
    coordinates: &Coordinates,
    nav: &NavState,
    truth: &NavState,
    p: &Matrix15,
) -> f64 {
    let truth_disp = coordinates.displacement(&truth.lla);
    let dp = coordinates.displacement(&nav.lla) - nav.dcm * (truth.dcm.transpose() * truth_disp);
    nees3(&dp, p, POS)
}

/// The run's statistics of its updates, gathered as its pass goes.
#[derive(Clone, Debug, Default)]
pub(super) struct Updates {
    /// NIS at each DVL epoch (gate-rejected updates included; NaN where the reading
    /// was lost).
    pub(super) nis: Vec<f64>,
    pub(super) nees: Vec<[f64; 5]>,
    pub(super) calibration_nees: Vec<f64>,
    pub(super) rejected: usize,
    pub(super) missed: usize,
    pub(super) accepted_nis_sum: f64,
    pub(super) nis_monitor: NisMonitor,
    pub(super) aiding: AidingTally,
}

impl Updates {
    /// A due DVL epoch whose reading is missing: NaN NIS and NEES.
    pub(super) fn missed(&mut self, calibrated: bool) {
        self.missed += 1;
        self.nis.push(f64::NAN);
        self.nees.push([f64::NAN; 5]);
        if calibrated {
            self.calibration_nees.push(f64::NAN);
        }
    }

    /// The mean NIS of the applied DVL updates (NaN without one: 0 would look
    /// healthy).
    pub(super) fn mean_nis(&self) -> f64 {
        let accepted = self.nis.len() - self.rejected - self.missed;
        if accepted == 0 {
            f64::NAN
        } else {
            self.accepted_nis_sum / accepted.max(1) as f64
        }
    }
}

/// The observer that judges a run's updates against its truth at the epoch under way:
/// the true state, the IMU's true bias and the DVL's true mounting there.
pub(super) struct Tally<'a> {
    pub(super) updates: &'a mut Updates,
    pub(super) truth: &'a NavState,
    pub(super) true_bias: &'a [f64; 6],
    pub(super) mounting: &'a DvlMounting,
}

impl Observer for Tally<'_> {
    fn on_reading(
        &mut self,
        at: &Epoch<'_>,
        _i: usize,
        reading: &Reading,
        applied: &mut Applied,
        ekf: &Ekf,
        _strategy: &dyn NoiseStrategy,
    ) {
        let u = &mut *self.updates;
        match reading {
            Reading::Velocity(_) => {
                u.nis_monitor.push(applied.nis, at.t);
                if applied.accepted {
                    u.accepted_nis_sum += applied.nis;
                } else {
                    u.rejected += 1;
                }
                // Every epoch is recorded, applied or not, so that the histories stay
                // aligned.
                u.nis.push(applied.nis);
                let e = state_error(ekf, self.truth, self.true_bias);
                u.nees.push(block_nees(ekf, self.truth, &e));
                if let Some((_, _, nees)) = calibration_error(ekf, self.mounting) {
                    u.calibration_nees.push(nees);
                }
            }
            other => u.aiding.add(other, applied),
        }
    }
}
