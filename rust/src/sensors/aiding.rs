//! The aiding sensors of a simulation: a pressure depth sensor, a heading sensor (a
//! compass or an AHRS) and position fixes (GNSS at the surface, USBL or LBL acoustic
//! fixes), each at its lever arm from the IMU (a heading has none), simulated from the
//! truth with white noise as the filter reads them ([`crate::measurement`]): the same
//! readings a recording's streams are.
//!
//! Random numbers: each aiding sensor draws from its own part of the run's
//! initial-error stream, `2^66` words in for the depth sensor, `3·2^65` for the heading
//! sensor and `2^67 + j·2^60` for fix source `j` (the initial error itself takes 15
//! draws at its start), so the IMU, DVL, initial-error and dropout draws are the same
//! with and without aiding sensors, and a run's aiding draws depend only on the seed
//! and the run index.

use crate::attitude::wrap_angle;
use crate::earth;
use crate::ekf::check_lever_arm;
use crate::error::{check, Error, Result};
use crate::measurement::{Depth, Fix, Heading, Reading};
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

/// A heading sensor (a compass corrected for declination, an AHRS, a gyrocompass): the
/// body's true yaw \[rad, from true north\] with white noise, every `period` seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingModel {
    /// 1σ \[rad\], at most π; the filter is told the same.
    pub sigma: f64,
    /// Reading period \[s\] (a whole number of IMU periods).
    pub period: f64,
}

impl HeadingModel {
    /// `Err` naming `heading_sigma` or `heading_period` unless both are finite and > 0,
    /// the σ at most π (a σ in degrees is refused).
    pub fn validate(&self) -> Result<()> {
        check::positive("heading_sigma", self.sigma)?;
        if self.sigma > std::f64::consts::PI {
            return Err(Error::invalid(
                "heading_sigma",
                format!("must be at most π [rad], got {} (degrees?)", self.sigma),
            ));
        }
        check::positive("heading_period", self.period)
    }
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

/// The aiding sensors of a scenario (borrowed from its `SensorConfig`): what an
/// [`AidingSim`] simulates.
#[derive(Clone, Copy, Debug)]
pub struct AidingModels<'a> {
    pub depth: Option<&'a DepthModel>,
    pub heading: Option<&'a HeadingModel>,
    pub fixes: &'a [FixModel],
}

impl AidingModels<'_> {
    /// Whether there is any.
    pub fn any(&self) -> bool {
        self.depth.is_some() || self.heading.is_some() || !self.fixes.is_empty()
    }
}

/// The aiding sensors of one run, stepping along the truth.
pub struct AidingSim {
    depth: Option<(usize, ChaCha8Rng)>,
    heading: Option<(usize, ChaCha8Rng)>,
    fixes: Vec<FixSim>,
}

/// The run's initial-error stream moved `offset` words in.
fn offset_rng(seed: u64, run_index: u64, offset: u128) -> ChaCha8Rng {
    let mut rng = stream_rng(seed, run_index, Stream::InitialError);
    rng.set_word_pos(offset);
    rng
}

impl AidingSim {
    /// The aiding sensors `sensors` on `truth` for run `run_index` of `seed`; None when
    /// there are none. `Err` naming a period that is not a whole number of IMU steps.
    pub fn new(
        sensors: AidingModels<'_>,
        truth: &Truth,
        seed: u64,
        run_index: u64,
    ) -> Result<Option<Self>> {
        if !sensors.any() {
            return Ok(None);
        }
        let depth = match sensors.depth {
            Some(d) => Some((
                steps_per(d.period, truth.dt, "depth_period")?,
                offset_rng(seed, run_index, 1 << 66),
            )),
            None => None,
        };
        let heading = match sensors.heading {
            Some(h) => Some((
                steps_per(h.period, truth.dt, "heading_period")?,
                offset_rng(seed, run_index, 3 << 65),
            )),
            None => None,
        };
        let fixes = sensors
            .fixes
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
        Ok(Some(Self {
            depth,
            heading,
            fixes,
        }))
    }

    /// The readings due at epoch `k` (called once per epoch, `k` increasing) of the
    /// true state `truth` by the aiding sensors `sensors` (the ones [`Self::new`] was
    /// given), appended to `out`: the depth first, then each fix source's in order,
    /// each read at its sensor's lever arm, then the heading.
    pub fn readings(
        &mut self,
        sensors: AidingModels<'_>,
        k: usize,
        truth: &NavState,
        out: &mut Vec<Reading>,
    ) {
        let (depth, fixes) = (sensors.depth, sensors.fixes);
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
        if let (Some((every, rng)), Some(model)) = (self.heading.as_mut(), sensors.heading) {
            if k.is_multiple_of(*every) {
                let yaw = truth.dcm[(1, 0)].atan2(truth.dcm[(0, 0)]);
                out.push(Reading::Heading(Heading {
                    y: wrap_angle(yaw + model.sigma * normal(rng)),
                    sigma: model.sigma,
                }));
            }
        }
    }
}

#[cfg(test)]
#[path = "aiding_tests.rs"]
mod tests;
