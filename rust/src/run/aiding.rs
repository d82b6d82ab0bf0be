//! What the aiding sensors' updates did in a simulated run ([`AidingTally`]); their
//! readings are simulated by [`crate::sensors::aiding`].

use crate::ekf::Applied;
use crate::measurement::Reading;

/// What a run's aiding updates did, for its summary.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct AidingTally {
    pub(super) depth_updates: usize,
    pub(super) fix_updates: usize,
    pub(super) nis_sum: f64,
    pub(super) dof: usize,
}

impl AidingTally {
    /// An aiding reading applied.
    pub(super) fn add(&mut self, reading: &Reading, applied: &Applied) {
        // The velocity readings have their own tally; every other reading's NIS is
        // summed here, the depths and fixes counted too.
        if let Reading::Velocity(_) = reading {
            return;
        }
        self.depth_updates += usize::from(matches!(reading, Reading::Depth(_)));
        self.fix_updates += usize::from(matches!(reading, Reading::Fix(_)));
        self.nis_sum += applied.nis;
        self.dof += applied.dof;
    }
}

#[cfg(test)]
mod tests {
    use crate::montecarlo::tests::{short_scenario, tuned_filter, TRUE_Q};
    use crate::montecarlo::{run_monte_carlo, McOptions};
    use crate::noise::StrategySpec;
    use crate::sensors::{DepthModel, FixModel};
    use std::sync::Arc;

    fn final_errors(sc: &crate::scenario::Scenario) -> Vec<(f64, usize, usize, usize)> {
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
            lever_arm: nalgebra::Vector3::zeros(),
        });
        aided.sensors.fixes = vec![FixModel {
            sigma: [2.0, 2.0, f64::NAN],
            period: 10.0,
            times: vec![],
            max_depth: None,
            lever_arm: nalgebra::Vector3::zeros(),
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
