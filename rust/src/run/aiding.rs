//! The aiding sensors of a simulated run: the depth readings and position fixes due at
//! an epoch, simulated from the truth ([`crate::sensors::aiding`]) and applied by the
//! filter's position updates ([`crate::ekf::position`]) after the DVL's, as a
//! recording's are.

use super::Run;
use crate::ekf::Vector15;
use crate::mechanization::NavState;
use crate::montecarlo::Scenario;
use crate::sensors::Reading;

/// What a run's aiding updates did, for its summary.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct AidingTally {
    pub(super) depth_updates: usize,
    pub(super) fix_updates: usize,
    pub(super) nis_sum: f64,
    pub(super) dof: usize,
}

/// The error estimates fed back at an epoch: the 15 states' and the DVL calibration's.
pub(super) type Fed = (Vector15, [f64; 4]);

impl Run {
    /// Apply the depth readings and fixes due at this epoch (true state `truth`): the
    /// sums of the error estimates fed back (the 15 states', the DVL calibration's),
    /// None when nothing was due. A numerical
    /// failure ends the run's filtering, as the DVL's does.
    pub(super) fn apply_aiding(
        &mut self,
        scenario: &Scenario,
        truth: &NavState,
        t: f64,
    ) -> Option<Fed> {
        let sim = self.aiding.as_mut()?;
        let sensors = &scenario.sensors;
        sim.readings(
            sensors.depth.as_ref(),
            &sensors.fixes,
            self.k,
            truth,
            &mut self.readings,
        );
        let mut correction: Option<Fed> = None;
        for reading in &self.readings {
            let done = match reading {
                Reading::Depth(z, sigma) => self.ekf.update_depth(*z, *sigma),
                Reading::Fix(fix, sigma) => self.ekf.update_fix(fix, sigma),
            };
            match done {
                Ok(done) => {
                    match reading {
                        Reading::Depth(..) => self.tally.depth_updates += 1,
                        Reading::Fix(..) => self.tally.fix_updates += 1,
                    }
                    self.tally.nis_sum += done.nis;
                    self.tally.dof += done.dof;
                    let (nav, cal) = correction.get_or_insert((Vector15::zeros(), [0.0; 4]));
                    *nav += done.correction;
                    for (c, d) in cal.iter_mut().zip(done.calibration_correction) {
                        *c += d;
                    }
                }
                Err(e) => {
                    self.failure = Some(format!("t = {t} s: {e}"));
                    break;
                }
            }
        }
        correction
    }
}

#[cfg(test)]
mod tests {
    use crate::montecarlo::tests::{short_scenario, tuned_filter, TRUE_Q};
    use crate::montecarlo::{run_monte_carlo, McOptions};
    use crate::noise::StrategySpec;
    use crate::sensors::{DepthModel, FixModel};
    use std::sync::Arc;

    fn final_errors(sc: &crate::montecarlo::Scenario) -> Vec<(f64, usize, usize, usize)> {
        let opts = McOptions {
            n_runs: 4,
            seed: 3,
            ..McOptions::default()
        };
        let spec = StrategySpec::Constant { q: TRUE_Q };
        let res = run_monte_carlo(&Arc::new(sc.clone()), &tuned_filter(), &spec, &opts).unwrap();
        res.runs
            .iter()
            .map(|r| {
                assert!(r.summary.failure.is_none(), "{:?}", r.summary.failure);
                let s = &r.summary;
                (
                    s.final_horizontal_error,
                    s.depth_updates,
                    s.fix_updates,
                    r.nis.len(),
                )
            })
            .collect()
    }

    /// Without a DVL, the free-running INS drifts over 120 s; fixes every 10 s (σ 2 m)
    /// and a depth sensor keep it within metres, with the updates counted as scheduled
    /// and no DVL epoch; the same fixes leave the IMU's and DVL's draws alone.
    #[test]
    fn fixes_without_a_dvl_bound_the_drift() {
        let mut free = (*short_scenario(120.0)).clone();
        free.sensors.dvl.period = 0.0;
        let mut aided = free.clone();
        aided.sensors.depth = Some(DepthModel {
            sigma: 0.1,
            period: 1.0,
        });
        aided.sensors.fixes = vec![FixModel {
            sigma: [2.0, 2.0, f64::NAN],
            period: 10.0,
            times: vec![],
            max_depth: None,
        }];
        let drift = final_errors(&free);
        let bounded = final_errors(&aided);
        for ((d, ..), (b, depth, fixes, dvl)) in drift.iter().zip(&bounded) {
            assert!(*d > 50.0, "free INS after 120 s: {d} m");
            assert!(*b < 10.0, "with fixes: {b} m");
            assert_eq!((*depth, *fixes, *dvl), (120, 12, 0));
        }
    }
}
