//! The update rows of a recorded pass at one epoch: the DVL rows, depth readings and
//! position fixes whose nearest epoch it is, applied in that order, and the covariances
//! asked for there; [`Cursor`] tracks the next row of each stream.

use super::position::PositionUpdate;
use super::recorded::FilterOutput;
use super::recorded_data::RecordedData;
use super::{Ekf, Matrix15, Vector15};
use crate::error::{Error, Result};
use crate::noise::NoiseStrategy;
use nalgebra::Vector3;

/// Where a pass stands: the next DVL and q rows, and the IMU steps since the last
/// accepted update.
#[derive(Default)]
pub(super) struct Cursor {
    pub(super) next_dvl: usize,
    pub(super) next_q: usize,
    pub(super) next_covariance: usize,
    pub(super) next_depth: usize,
    pub(super) next_fix: usize,
    pub(super) steps_since_update: usize,
}

/// The error estimates fed back at an epoch: the 15 states' and the DVL calibration's.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Fed {
    pub(super) nav: Vector15,
    pub(super) calibration: [f64; 4],
}

impl Fed {
    pub(super) fn add(&mut self, nav: &Vector15, calibration: &[f64; 4]) {
        self.nav += nav;
        for (sum, v) in self.calibration.iter_mut().zip(calibration) {
            *sum += v;
        }
    }

    pub(super) fn plus(mut self, other: &Fed) -> Fed {
        self.add(&other.nav, &other.calibration);
        self
    }
}

/// Apply every depth reading, then every position fix, whose nearest epoch is `epoch`
/// (time `t` \[s\], step `dt` \[s\]), as DVL rows are placed; rows before the run's first
/// half step are outside it. The sum of the error estimates fed back, or None if no row
/// was there.
pub(super) fn apply_position_rows(
    data: &RecordedData<'_>,
    ekf: &mut Ekf,
    out: &mut FilterOutput,
    at: &mut Cursor,
    epoch: usize,
    t: f64,
    dt: f64,
) -> Result<Option<Fed>> {
    let first = data.t0 - 0.5 * (data.imu_time[0] - data.t0);
    let mut correction: Option<Fed> = None;
    // One stream: each row due from `next` on gets its epoch and NIS (None and NaN
    // where it falls before the run), and its estimate fed back is summed.
    let mut drain = |what: &str,
                     times: &[f64],
                     next: &mut usize,
                     (epochs, nis): (&mut Vec<Option<usize>>, &mut Vec<f64>),
                     update: &dyn Fn(&mut Ekf, usize) -> Result<PositionUpdate>|
     -> Result<()> {
        while *next < times.len() && times[*next] <= t + 0.5 * dt {
            let row = *next;
            *next += 1;
            epochs.push(None);
            nis.push(f64::NAN);
            if times[row] < first {
                continue;
            }
            let done = update(ekf, row).map_err(|e| match e {
                Error::Numerical(m) => {
                    Error::Numerical(format!("{m} ({what} row {row}, t = {t} s)"))
                }
                other => other,
            })?;
            (epochs[row], nis[row]) = (Some(epoch), done.nis);
            correction
                .get_or_insert_with(Fed::default)
                .add(&done.correction, &done.calibration_correction);
        }
        Ok(())
    };
    drain(
        "depth",
        data.depth_time,
        &mut at.next_depth,
        (&mut out.depth_epoch, &mut out.depth_nis),
        &|ekf, row| ekf.update_depth(data.depth[row], data.depth_sigma),
    )?;
    drain(
        "fix",
        data.fix_time,
        &mut at.next_fix,
        (&mut out.fix_epoch, &mut out.fix_nis),
        &|ekf, row| ekf.update_fix(&data.fix[row], &data.fix_sigma[row]),
    )?;
    Ok(correction)
}

/// Keep the covariance (classic coordinates) for every asked-for time whose nearest
/// epoch is `epoch` (time `t` \[s\]; `next_dt` \[s\] the step after it): the times before
/// or at `t + next_dt/2` not yet taken. Times before the run's first half step are outside
/// it (None), as DVL rows are.
pub(super) fn keep_covariances(
    data: &RecordedData<'_>,
    ekf: &Ekf,
    out: &mut FilterOutput,
    at: &mut Cursor,
    epoch: usize,
    t: f64,
    next_dt: f64,
) {
    let times = data.covariance_time;
    let first_dt = data.imu_time[0] - data.t0;
    let mut kept: Option<Matrix15> = None;
    while at.next_covariance < times.len() && times[at.next_covariance] <= t + 0.5 * next_dt {
        if times[at.next_covariance] < data.t0 - 0.5 * first_dt {
            out.covariance_epoch.push(None);
            out.covariances.push(None);
        } else {
            let p = *kept.get_or_insert_with(|| ekf.covariance_up_to_date());
            out.covariance_epoch.push(Some(epoch));
            out.covariances.push(Some(p));
        }
        at.next_covariance += 1;
    }
}

/// Apply every DVL row whose nearest epoch is `epoch` (time `t` \[s\], step `dt` \[s\]);
/// the sum of the error estimates fed back, or None if no row was there.
#[allow(clippy::too_many_arguments)]
pub(super) fn apply_dvl_rows(
    data: &RecordedData<'_>,
    ekf: &mut Ekf,
    strategy: &mut dyn NoiseStrategy,
    out: &mut FilterOutput,
    at: &mut Cursor,
    epoch: usize,
    t: f64,
    dt: f64,
) -> Result<Option<Fed>> {
    let mut correction: Option<Fed> = None;
    while at.next_dvl < data.dvl.len() && data.dvl_time[at.next_dvl] <= t + 0.5 * dt {
        let row = at.next_dvl;
        let z = Vector3::from_column_slice(&data.dvl[row]);
        let info = ekf.update(&z).map_err(|e| match e {
            Error::Numerical(m) => Error::Numerical(format!("{m} (DVL row {row}, t = {t} s)")),
            other => other,
        })?;
        out.nis_monitor.push(info.nis, t);
        let sum = correction.get_or_insert_with(Fed::default);
        if let Some(dx) = &info.correction {
            sum.add(dx, &info.calibration_correction.unwrap_or_default());
        }
        if info.accepted {
            strategy.after_update(&info, at.steps_since_update);
            at.steps_since_update = 0;
        }
        // Mehra's Q̂ is built from the reported (classic) gain: classic already.
        out.adaptive_q[row] = strategy.discrete_q().map(|q| Box::new(*q));
        out.dvl_epoch[row] = Some(epoch);
        out.updates[row] = Some(info);
        at.next_dvl += 1;
    }
    Ok(correction)
}
