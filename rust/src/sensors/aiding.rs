//! The aiding sensors of a simulation: a pressure depth sensor and position fixes (GNSS
//! at the surface, USBL or LBL acoustic fixes), each at its lever arm from the IMU,
//! simulated from the truth with white noise as the filter reads them
//! ([`crate::measurement`]): the same readings a recording's depth and fixes are.
//!
//! Random numbers: each aiding sensor draws from its own part of the run's
//! initial-error stream, `2^66` words in for the depth sensor and `2^67 + j·2^60` for
//! fix source `j` (the initial error itself takes 15 draws at its start), so the IMU,
//! DVL, initial-error and dropout draws are the same with and without aiding sensors,
//! and a run's aiding draws depend only on the seed and the run index.

use crate::earth;
use crate::ekf::check_lever_arm;
use crate::error::{check, Error, Result};
use crate::measurement::{Depth, Fix, Reading};
use crate::mechanization::NavState;
use crate::sensors::{normal, stream_rng, Stream};
use crate::trajectory::Truth;
use nalgebra::Vector3;
use rand_chacha::ChaCha8Rng;

/// A pressure depth sensor at `lever_arm` from the IMU: its depth \[m, positive down\]
/// with white noise, every `period` seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthModel {
    /// 1σ \[m\]; the filter is told the same.
    pub sigma: f64,
    /// Reading period \[s\] (a whole number of IMU periods).
    pub period: f64,
    /// The sensor's position from the IMU \[m, body FRD\]; the filter is told the same.
    pub lever_arm: Vector3<f64>,
}

/// A source of position fixes of an antenna or transponder at `lever_arm` from the IMU:
/// white noise of 1σ `sigma` \[m\] north,
/// east, down (a NaN down σ: horizontal fixes, no height), on a schedule: every
/// `period` seconds (0: not periodic) and at the listed `times` \[s\] (each taken at the
/// IMU epoch nearest it, as a recording's rows are), and with `max_depth` only while the
/// vehicle's true depth is at most that \[m\] (at the surface: GNSS).
#[derive(Clone, Debug, PartialEq)]
pub struct FixModel {
    /// 1σ \[m\] north, east, down; the filter is told the same.
    pub sigma: [f64; 3],
    /// Period \[s\] (0: only the listed times).
    pub period: f64,
    /// Times \[s\] of single fixes, strictly increasing.
    pub times: Vec<f64>,
    /// Fixes only while the true depth is at most this \[m, positive down\] (None: at
    /// any depth).
    pub max_depth: Option<f64>,
    /// The antenna's position from the IMU \[m, body FRD\]; the filter is told the same.
    pub lever_arm: Vector3<f64>,
}

impl DepthModel {
    /// `Err` naming `depth_sigma` or `depth_period` unless both are finite and > 0.
    pub fn validate(&self) -> Result<()> {
        check::positive("depth_sigma", self.sigma)?;
        check::positive("depth_period", self.period)?;
        check_lever_arm("depth_lever_arm", self.lever_arm.as_slice())
    }
}

impl FixModel {
    /// Whether the fixes carry a height (a down σ is given).
    pub fn has_height(&self) -> bool {
        !self.sigma[2].is_nan()
    }

    /// `Err` naming `fixes[i].<key>` unless the σ are finite and > 0 (the down one may
    /// be NaN), the period finite and ≥ 0, the times finite, ≥ 0 and increasing, the
    /// depth limit finite, and some fix is scheduled (a period or times).
    pub fn validate(&self, i: usize) -> Result<()> {
        let name = |key: &str| format!("fixes[{i}].{key}");
        let ok = |s: f64| s.is_finite() && s > 0.0;
        if !(ok(self.sigma[0]) && ok(self.sigma[1]) && (!self.has_height() || ok(self.sigma[2]))) {
            return Err(Error::invalid(
                name("sigma"),
                format!(
                    "needs 1σ [m] north, east (and down, for fixes with a height), each \
                     finite and > 0; got {:?}",
                    self.sigma
                ),
            ));
        }
        if !(self.period.is_finite() && self.period >= 0.0) {
            return Err(Error::invalid(
                name("period"),
                format!(
                    "must be finite and >= 0 s (0: only the listed times), got {}",
                    self.period
                ),
            ));
        }
        check::increasing(&name("times"), &self.times)?;
        if let Some(t) = self.times.iter().find(|t| **t < 0.0) {
            return Err(Error::invalid(
                name("times"),
                format!("must be >= 0 s (the run starts at 0), got {t}"),
            ));
        }
        if let Some(d) = self.max_depth {
            check::finite(&name("max_depth"), &[d])?;
        }
        check_lever_arm(&name("lever_arm"), self.lever_arm.as_slice())?;
        if self.period == 0.0 && self.times.is_empty() {
            return Err(Error::invalid(
                name("period"),
                "no fix is scheduled: give a period > 0 s or a list of times",
            ));
        }
        Ok(())
    }
}

/// IMU steps per `period` \[s\] of a trajectory of step `dt` \[s\]: `Err` naming `arg`
/// unless the period is a whole number (≥ 1) of steps.
pub(crate) fn steps_per(period: f64, dt: f64, arg: &str) -> Result<usize> {
    let ratio = period / dt;
    let steps = ratio.round();
    if steps < 1.0 || (ratio - steps).abs() > 1e-6 * ratio {
        return Err(Error::invalid(
            arg,
            format!("must be a whole multiple of the IMU period {dt} s, got {period} s"),
        ));
    }
    Ok(steps as usize)
}

/// The epoch (1 ..= n) a reading at time `t` \[s\] is applied at: the first whose time
/// plus half a step reaches it (the rule of a recording's rows); None past the end.
fn epoch_of(t: f64, truth: &Truth) -> Option<usize> {
    let k = ((t - truth.time[0]) / truth.dt - 0.5).ceil().max(1.0) as usize;
    (k <= truth.len()).then_some(k)
}

/// One fix source's schedule on a truth, stepped along its epochs.
struct Schedule {
    every: Option<usize>,
    /// Epochs of the listed times, increasing, deduplicated.
    epochs: Vec<usize>,
    next: usize,
}

impl Schedule {
    /// Source `j`'s schedule on `truth`: `Err` naming its period unless that is a whole
    /// number of IMU steps.
    fn new(model: &FixModel, j: usize, truth: &Truth) -> Result<Self> {
        let every = match model.period {
            0.0 => None,
            p => Some(steps_per(p, truth.dt, &format!("fixes[{j}].period"))?),
        };
        let mut epochs: Vec<usize> = model
            .times
            .iter()
            .filter_map(|&t| epoch_of(t, truth))
            .collect();
        epochs.dedup();
        Ok(Self {
            every,
            epochs,
            next: 0,
        })
    }

    /// Whether a fix is scheduled at epoch `k` (called with increasing `k`).
    fn scheduled(&mut self, k: usize) -> bool {
        let mut listed = false;
        while self.next < self.epochs.len() && self.epochs[self.next] <= k {
            listed |= self.epochs[self.next] == k;
            self.next += 1;
        }
        listed || self.every.is_some_and(|e| k.is_multiple_of(e))
    }
}

/// One fix source's schedule and random stream in a run.
struct FixSim {
    schedule: Schedule,
    rng: ChaCha8Rng,
}

impl FixModel {
    /// `Err` naming `fixes[j]` unless this source, as source `j`, takes a fix on
    /// `truth`: at a scheduled epoch inside it, at a true depth of at most `max_depth`
    /// where one is set. A source that never fires would leave every run silently
    /// without the fixes it was configured for.
    pub fn check_fires(&self, j: usize, truth: &Truth) -> Result<()> {
        let mut schedule = Schedule::new(self, j, truth)?;
        // the shallowest true depth [m] at a scheduled epoch (None: none scheduled)
        let mut shallowest: Option<f64> = None;
        for k in 1..=truth.len() {
            if schedule.scheduled(k) {
                let depth = -truth.states[k].lla[2];
                if self.max_depth.is_none_or(|d| depth <= d) {
                    return Ok(());
                }
                shallowest = Some(shallowest.map_or(depth, |s| s.min(depth)));
            }
        }
        let duration = truth.duration();
        Err(match (shallowest, self.max_depth) {
            (Some(shallowest), Some(d)) => Error::invalid(
                format!("fixes[{j}].max_depth"),
                format!(
                    "no scheduled fix comes at a true depth of at most {d} m (at the \
                     scheduled epochs the trajectory is never shallower than \
                     {shallowest:.3} m): the source would take no fix"
                ),
            ),
            _ => Error::invalid(
                format!("fixes[{j}]"),
                format!(
                    "schedules no fix inside the trajectory's {duration} s (period {} s, \
                     times {:?}): the source would take no fix",
                    self.period, self.times
                ),
            ),
        })
    }
}

/// The aiding sensors of one run, stepping along the truth.
pub struct AidingSim {
    depth: Option<(usize, ChaCha8Rng)>,
    fixes: Vec<FixSim>,
}

/// The run's initial-error stream moved `offset` words in.
fn offset_rng(seed: u64, run_index: u64, offset: u128) -> ChaCha8Rng {
    let mut rng = stream_rng(seed, run_index, Stream::InitialError);
    rng.set_word_pos(offset);
    rng
}

impl AidingSim {
    /// The aiding sensors of `depth` and `fixes` on `truth` for run `run_index` of
    /// `seed`; None when there are none. `Err` naming a period that is not a whole
    /// number of IMU steps.
    pub fn new(
        depth: Option<&DepthModel>,
        fixes: &[FixModel],
        truth: &Truth,
        seed: u64,
        run_index: u64,
    ) -> Result<Option<Self>> {
        if depth.is_none() && fixes.is_empty() {
            return Ok(None);
        }
        let depth = match depth {
            Some(d) => Some((
                steps_per(d.period, truth.dt, "depth_period")?,
                offset_rng(seed, run_index, 1 << 66),
            )),
            None => None,
        };
        let fixes = fixes
            .iter()
            .enumerate()
            .map(|(j, f)| {
                let offset = (1u128 << 67) + ((j as u128) << 60);
                Ok(FixSim {
                    schedule: Schedule::new(f, j, truth)?,
                    rng: offset_rng(seed, run_index, offset),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Some(Self { depth, fixes }))
    }

    /// The readings due at epoch `k` (called once per epoch, `k` increasing) of the
    /// true state `truth`, appended to `out`: the depth first, then each fix source's in
    /// order, each read at its sensor's lever arm.
    pub fn readings(
        &mut self,
        depth: Option<&DepthModel>,
        fixes: &[FixModel],
        k: usize,
        truth: &NavState,
        out: &mut Vec<Reading>,
    ) {
        let true_depth = -truth.lla[2];
        // The NED offset of a sensor at `arm` (none at the IMU: the IMU's point exactly).
        let offset = |arm: &Vector3<f64>| (*arm != Vector3::zeros()).then(|| truth.dcm * arm);
        if let (Some((every, rng)), Some(model)) = (self.depth.as_mut(), depth) {
            if k.is_multiple_of(*every) {
                let z = match offset(&model.lever_arm) {
                    Some(arm) => true_depth + arm[2],
                    None => true_depth,
                };
                out.push(Reading::Depth(Depth {
                    z: z + model.sigma * normal(rng),
                    sigma: model.sigma,
                    lever_arm: model.lever_arm,
                }));
            }
        }
        for (sim, model) in self.fixes.iter_mut().zip(fixes) {
            let scheduled = sim.schedule.scheduled(k);
            if !scheduled || model.max_depth.is_some_and(|d| true_depth > d) {
                continue;
            }
            let s = model.sigma;
            let mut noise = Vector3::new(
                s[0] * normal(&mut sim.rng),
                s[1] * normal(&mut sim.rng),
                0.0,
            );
            if model.has_height() {
                noise[2] = s[2] * normal(&mut sim.rng);
            }
            if let Some(arm) = offset(&model.lever_arm) {
                noise += arm;
            }
            let lla = truth.lla + earth::ned_delta_to_lla_delta(&truth.lla, &noise);
            let height = if model.has_height() { lla[2] } else { f64::NAN };
            out.push(Reading::Fix(Fix {
                lla: [lla[0], lla[1], height],
                sigma: s,
                lever_arm: model.lever_arm,
            }));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::builtin;

    fn fixes(period: f64, times: Vec<f64>, max_depth: Option<f64>) -> FixModel {
        FixModel {
            sigma: [2.0, 3.0, f64::NAN],
            period,
            times,
            max_depth,
            lever_arm: Vector3::zeros(),
        }
    }

    /// Every reading of `n` epochs of a stationary truth at `depth` \[m\].
    fn draw(
        depth: Option<&DepthModel>,
        fix: &[FixModel],
        truth: &Truth,
        at_depth: f64,
        run: u64,
    ) -> Vec<(usize, Reading)> {
        let mut sim = AidingSim::new(depth, fix, truth, 11, run).unwrap().unwrap();
        let mut state = truth.states[0];
        state.lla[2] = -at_depth;
        let mut out = Vec::new();
        let mut all = Vec::new();
        for k in 1..=truth.len() {
            out.clear();
            sim.readings(depth, fix, k, &state, &mut out);
            all.extend(out.iter().map(|r| (k, *r)));
        }
        all
    }

    #[test]
    fn readings_have_the_configured_noise() {
        let truth = builtin("paper", 0.01).unwrap().generate().unwrap();
        let depth = DepthModel {
            sigma: 0.2,
            period: 0.01,
            lever_arm: Vector3::zeros(),
        };
        let mut fix = fixes(0.01, vec![], None);
        fix.sigma[2] = 4.0;
        let state = {
            let mut s = truth.states[0];
            s.lla[2] = -30.0;
            s
        };
        let (mut d, mut f) = (Vec::new(), Vec::new());
        for r in draw(Some(&depth), std::slice::from_ref(&fix), &truth, 30.0, 2) {
            match r.1 {
                Reading::Depth(m) => {
                    assert_eq!(m.sigma, 0.2);
                    d.push(m.z - 30.0);
                }
                Reading::Fix(m) => {
                    f.push(earth::position_error_ned(&Vector3::from(m.lla), &state.lla))
                }
                other => panic!("not an aiding reading: {other:?}"),
            }
        }
        // 33,000 draws each: the sample σ within 2 % (its standard error is 0.4 %), the
        // mean within 4 standard errors of 0.
        let n = d.len() as f64;
        assert_eq!(d.len(), truth.len());
        let sd = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        assert!((sd(&d) / 0.2 - 1.0).abs() < 0.02, "{}", sd(&d));
        assert!((d.iter().sum::<f64>() / n).abs() < 4.0 * 0.2 / n.sqrt());
        for (axis, sigma) in [2.0, 3.0, 4.0].iter().enumerate() {
            let e: Vec<f64> = f.iter().map(|v| v[axis]).collect();
            assert!((sd(&e) / sigma - 1.0).abs() < 0.02, "{axis}: {}", sd(&e));
        }
        // depth and fix draws are independent of each other
        let c = d.iter().zip(&f).map(|(a, b)| a * b[0]).sum::<f64>() / n / (0.2 * 2.0);
        assert!(c.abs() < 4.0 / n.sqrt(), "{c}");
    }

    #[test]
    fn fixes_follow_their_schedule() {
        let truth = builtin("paper", 0.01).unwrap().generate().unwrap();
        let epochs = |f: &FixModel, depth: f64| -> Vec<usize> {
            draw(None, std::slice::from_ref(f), &truth, depth, 0)
                .into_iter()
                .map(|(k, _)| k)
                .collect()
        };
        // every 60 s: epochs 6000, 12000, ...; no height without a down σ
        let periodic = fixes(60.0, vec![], None);
        assert_eq!(
            epochs(&periodic, 5.0),
            vec![6000, 12000, 18000, 24000, 30000]
        );
        let one = draw(None, std::slice::from_ref(&periodic), &truth, 5.0, 0)[0].1;
        assert!(matches!(one, Reading::Fix(m) if m.lla[2].is_nan()));
        // listed times at the nearest epoch (the start's at the first), merged with the
        // period without doubles; times past the end are dropped
        let listed = fixes(100.0, vec![0.0, 12.344, 100.0, 329.99, 400.0], None);
        assert_eq!(
            epochs(&listed, 5.0),
            vec![1, 1234, 10000, 20000, 30000, 32999]
        );
        // at the surface only
        let surface = fixes(1.0, vec![], Some(0.5));
        assert_eq!(epochs(&surface, 5.0), Vec::<usize>::new());
        assert_eq!(epochs(&surface, 0.3).len(), 330);
        // a period that is no whole number of steps is refused by name
        let odd = fixes(0.015, vec![], None);
        let err = AidingSim::new(None, &[periodic, odd], &truth, 0, 0)
            .err()
            .unwrap();
        assert!(
            err.to_string()
                .starts_with("fixes[1].period: must be a whole"),
            "{err}"
        );
    }

    #[test]
    fn a_source_that_takes_no_fix_is_refused_by_name() {
        // the paper's 330 s trajectory, never shallower than its 5 m
        let truth = builtin("paper", 0.01).unwrap().generate().unwrap();
        let err = |f: FixModel| f.check_fires(1, &truth).unwrap_err().to_string();
        for fires in [
            fixes(60.0, vec![], None),
            fixes(0.0, vec![329.99], None),
            fixes(400.0, vec![100.0], None),
            fixes(1.0, vec![], Some(5.5)),
        ] {
            assert!(fires.check_fires(1, &truth).is_ok(), "{fires:?}");
        }
        for late in [
            fixes(400.0, vec![], None),
            fixes(0.0, vec![330.5, 500.0], None),
        ] {
            assert!(
                err(late).starts_with("fixes[1]: schedules no fix inside the trajectory's 330 s"),
            );
        }
        let surface = err(fixes(1.0, vec![], Some(0.5)));
        assert!(
            surface.starts_with("fixes[1].max_depth: no scheduled fix comes at a true depth")
                && surface.contains("never shallower than 5.000 m"),
            "{surface}"
        );
        // the depth it names is the shallowest at the scheduled epochs, not anywhere
        let deepest = truth
            .states
            .iter()
            .map(|s| -s.lla[2])
            .fold(f64::NEG_INFINITY, f64::max);
        let at = (0..=truth.len())
            .find(|&k| -truth.states[k].lla[2] == deepest)
            .unwrap();
        let once = err(fixes(0.0, vec![truth.time[at]], Some(deepest - 1.0)));
        assert!(
            once.contains(&format!("never shallower than {deepest:.3} m")),
            "{once}"
        );
        assert!(err(fixes(0.015, vec![], None)).starts_with("fixes[1].period: must be a whole"));
    }

    #[test]
    fn draws_depend_on_seed_and_run_only() {
        let truth = builtin("paper", 0.01).unwrap().generate().unwrap();
        let depth = DepthModel {
            sigma: 0.1,
            period: 1.0,
            lever_arm: Vector3::zeros(),
        };
        let a = draw(Some(&depth), &[], &truth, 10.0, 4);
        let b = draw(Some(&depth), &[fixes(1.0, vec![], None)], &truth, 10.0, 4);
        let b: Vec<_> = b
            .into_iter()
            .filter(|r| matches!(r.1, Reading::Depth(..)))
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, draw(Some(&depth), &[], &truth, 10.0, 5));
        // none configured: nothing to simulate
        assert!(AidingSim::new(None, &[], &truth, 0, 0).unwrap().is_none());
    }

    #[test]
    fn bad_models_are_named() {
        let bad = |f: FixModel| f.validate(2).unwrap_err().to_string();
        let mut f = fixes(1.0, vec![], None);
        f.sigma[1] = 0.0;
        assert!(bad(f).starts_with("fixes[2].sigma: needs"));
        assert!(bad(fixes(-1.0, vec![], None)).starts_with("fixes[2].period: must be"));
        assert!(bad(fixes(0.0, vec![], None)).starts_with("fixes[2].period: no fix"));
        assert!(bad(fixes(0.0, vec![2.0, 1.0], None)).starts_with("fixes[2].times: must inc"));
        assert!(bad(fixes(0.0, vec![-1.0], None)).starts_with("fixes[2].times: must be >= 0"));
        assert!(bad(fixes(1.0, vec![], Some(f64::NAN))).starts_with("fixes[2].max_depth"));
        let d = DepthModel {
            sigma: 0.0,
            period: 1.0,
            lever_arm: Vector3::zeros(),
        };
        assert!(d
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("depth_sigma"));
    }
}
