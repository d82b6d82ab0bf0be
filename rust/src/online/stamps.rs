//! [`Stamps`]: the IMU's steps as a navigator is fed them, and the gaps among them.
//!
//! A sample is integrated over its whole stamped step, so a step far longer than the
//! IMU's usual one (a dropout, a logger's stall, a clock that jumped) integrates the
//! sample after it as if the vehicle had turned and accelerated evenly across the gap.
//! The batch pass warns of such a step from the median of all of them
//! (`pronet._util.plausibility.imu_gap`); a navigator has only the steps so far, so its
//! usual step is the mean of those within half a step of it (the shorter of the first
//! two starting it), which a gap or a dropped sample leaves as a median would.

/// No IMU step longer than this many usual steps: a longer one is a gap (the readers'
/// and `run_filter`'s rule too, against the median step).
pub const MAX_IMU_GAP: f64 = 5.0;

/// Steps within this share of the usual one count into it: a dropped sample (a step of
/// two) moves a mean where it leaves a median, the batch pass's, as it is.
const USUAL_BAND: f64 = 0.5;

/// The IMU's steps between samples so far (the first sample's, from the start time, is
/// not one of them), and the gaps among them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stamps {
    /// The usual step \[s\]: the mean of the steps so far within half a step of it,
    /// the shorter of the first two setting it (0 before the third sample).
    pub usual: f64,
    /// The steps counted into [`Self::usual`].
    steps: usize,
    /// The first step, held until the second tells whether it is a gap.
    held: Option<(f64, f64)>,
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
        if self.steps > 0 {
            self.take(t, dt);
            return;
        }
        let Some((t1, dt1)) = self.held.take() else {
            self.held = Some((t, dt));
            return;
        };
        // The shorter of the first two sets the usual step; the other is taken against
        // it, in time order.
        self.usual = dt1.min(dt);
        self.steps = 1;
        if dt1 > dt {
            self.take(t1, dt1);
        } else {
            self.take(t, dt);
        }
    }

    fn take(&mut self, t: f64, dt: f64) {
        if dt > MAX_IMU_GAP * self.usual {
            self.gaps += 1;
            self.first.get_or_insert((t, dt));
            if self.longest.is_none_or(|(_, longest)| dt > longest) {
                self.longest = Some((t, dt));
            }
        } else if (dt - self.usual).abs() <= USUAL_BAND * self.usual {
            self.steps += 1;
            self.usual += (dt - self.usual) / self.steps as f64;
        }
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
        // A logger's stamps about 20 ms: ±10 %, their mean; ±40 %, no gap either.
        let stamps_of = |spread: f64| -> Vec<f64> {
            (0..1000)
                .map(|k| 0.02 * (1.0 + spread * ((k % 7) as f64 - 3.0) / 3.0))
                .collect()
        };
        let jitter = stamps_of(0.1);
        let stamps = fed(&jitter);
        assert_eq!((stamps.gaps, stamps.first), (0, None));
        let mean = jitter.iter().sum::<f64>() / jitter.len() as f64;
        assert!((stamps.usual - mean).abs() < 1e-12);
        let wide = fed(&stamps_of(0.4));
        assert_eq!((wide.gaps, wide.first), (0, None));
        assert!((wide.usual - 0.02).abs() < 0.005);
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
        assert!((stamps.usual - 0.01).abs() < 1e-15);
    }

    #[test]
    fn a_gap_among_the_first_two_steps_is_one_and_the_shorter_sets_the_usual_step() {
        // The clock jumps between the first two samples: a gap, not the usual step.
        let stamps = fed(&[1e6, 0.01, 0.01, 0.01]);
        assert_eq!(stamps.gaps, 1);
        assert_eq!(stamps.first, Some((1e6, 1e6)));
        assert!((stamps.usual - 0.01).abs() < 1e-15);
        let stamps = fed(&[0.01, 1e6, 0.01]);
        assert_eq!(stamps.first, Some((1e6 + 0.01, 1e6)));
        assert!((stamps.usual - 0.01).abs() < 1e-15);
        // One step alone tells nothing yet.
        assert_eq!(
            fed(&[1e6]),
            Stamps {
                held: Some((1e6, 1e6)),
                ..Stamps::default()
            }
        );
    }

    #[test]
    fn dropped_samples_leave_the_usual_step_as_a_median_would() {
        // Every fifth sample dropped: steps of two, 20 % of them, within 5 (no gap).
        let steps: Vec<f64> = (0..1000)
            .map(|k| if k % 5 == 4 { 0.02 } else { 0.01 })
            .collect();
        let stamps = fed(&steps);
        assert_eq!(stamps.gaps, 0);
        assert!((stamps.usual - 0.01).abs() < 1e-15);
    }
}
