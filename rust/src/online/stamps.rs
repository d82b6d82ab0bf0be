//! [`Stamps`]: the IMU's steps as a navigator is fed them, and the gaps among them.
//!
//! A sample is integrated over its whole stamped step, so a step far longer than the
//! IMU's usual one (a dropout, a logger's stall, a clock that jumped) integrates the
//! sample after it as if the vehicle had turned and accelerated evenly across the gap.
//! The batch pass warns of such a step from the median of all of them
//! (`pronet._util.plausibility.imu_gap`); a navigator has only the steps so far, so its
//! usual step is their mean, gaps left out.

/// No IMU step longer than this many usual steps: a longer one is a gap (the readers'
/// and `run_filter`'s rule too, against the median step).
pub const MAX_IMU_GAP: f64 = 5.0;

/// The IMU's steps between samples so far (the first sample's, from the start time, is
/// not one of them), and the gaps among them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stamps {
    /// The usual step \[s\]: the mean of the steps so far, gaps left out (0 before the
    /// second sample).
    pub usual: f64,
    /// The steps counted into [`Self::usual`].
    steps: usize,
    /// Steps longer than [`MAX_IMU_GAP`] usual steps.
    pub gaps: usize,
    /// The first and the longest gap: the time \[s\] of the sample after it and its
    /// length \[s\].
    pub first: Option<(f64, f64)>,
    pub longest: Option<(f64, f64)>,
}

impl Stamps {
    /// Take the step `dt` \[s\] (> 0) between two samples, ending at the sample time `t`
    /// \[s\].
    pub fn push(&mut self, t: f64, dt: f64) {
        if self.steps > 0 && dt > MAX_IMU_GAP * self.usual {
            self.gaps += 1;
            self.first.get_or_insert((t, dt));
            if self.longest.is_none_or(|(_, longest)| dt > longest) {
                self.longest = Some((t, dt));
            }
            return;
        }
        self.steps += 1;
        self.usual += (dt - self.usual) / self.steps as f64;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fed(steps: &[f64]) -> Stamps {
        let mut stamps = Stamps::default();
        let mut t = 0.0;
        for &dt in steps {
            t += dt;
            stamps.push(t, dt);
        }
        stamps
    }

    #[test]
    fn steady_and_jittering_steps_have_no_gap_and_their_mean_is_the_usual_step() {
        let steady = fed(&[0.01; 1000]);
        assert_eq!(steady.gaps, 0);
        assert!((steady.usual - 0.01).abs() < 1e-15);
        // A logger's stamps, ±40 % about 20 ms: no gap.
        let jitter: Vec<f64> = (0..1000)
            .map(|k| 0.02 * (1.0 + 0.4 * ((k % 7) as f64 - 3.0) / 3.0))
            .collect();
        let stamps = fed(&jitter);
        assert_eq!((stamps.gaps, stamps.first), (0, None));
        let mean = jitter.iter().sum::<f64>() / jitter.len() as f64;
        assert!((stamps.usual - mean).abs() < 1e-12);
    }

    #[test]
    fn a_step_beyond_five_usual_ones_is_a_gap_named_by_the_sample_after_it() {
        let mut steps = vec![0.01; 100];
        steps.push(0.0501); // just beyond 5 steps
        steps.extend([0.01; 10]);
        steps.push(2.0);
        steps.push(0.049); // under 5 steps: not a gap
        let stamps = fed(&steps);
        assert_eq!(stamps.gaps, 2);
        let (t, dt) = stamps.first.unwrap();
        assert!((t - (1.0 + 0.0501)).abs() < 1e-12 && dt == 0.0501);
        let (t, dt) = stamps.longest.unwrap();
        assert!((t - (1.0 + 0.0501 + 0.1 + 2.0)).abs() < 1e-12 && dt == 2.0);
        // The gaps do not count into the usual step.
        assert!((stamps.usual - (0.01 * 110.0 + 0.049) / 111.0).abs() < 1e-15);
    }

    #[test]
    fn the_first_step_sets_the_usual_one() {
        let stamps = fed(&[1.0, 4.0, 30.0]);
        assert_eq!(stamps.gaps, 1);
        assert_eq!(stamps.first, Some((35.0, 30.0)));
        assert!((stamps.usual - 2.5).abs() < 1e-15);
    }
}
