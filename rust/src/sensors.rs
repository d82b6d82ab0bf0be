//! Sensor error models and their simulation: IMU white noise (per channel, with a
//! variance that may follow a schedule), constant bias and bias random walk; DVL
//! body-frame velocity with white noise and a lever arm, and random bottom-lock loss
//! ([`DvlDropout`]).
//!
//! Random numbers: every run draws from its own ChaCha8 streams, keyed by the
//! Monte Carlo seed and `4 · run_index + k` (k = 0 IMU, 1 DVL, 2 initial error, 3 DVL
//! dropout), so a run's noise never depends on the thread count, on other runs, or on
//! the filter strategy (common random numbers across strategies). The dropout stream
//! is drawn only when a dropout model is set, and a missed reading still draws its DVL
//! noise: the other streams are the same with and without dropout.
//!
//! The aiding sensors (a depth sensor, a heading sensor, position fixes) are in
//! [`aiding`]. The DVL is
//! optional: a period of 0 means none (a GNSS/INS or depth-only simulation).

use crate::ekf::{check_lever_arm, DvlMounting};
use crate::error::{check, Error, Result};
use crate::mechanization::NavState;
use nalgebra::Vector3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// The largest simulated IMU error per channel, accelerometers \[m/s²\] then gyros
/// \[rad/s\]: a noise 1σ per sample, a bias, or the 1σ a bias walk reaches in a second.
/// 1000 m/s² (100 g) and 100 rad/s (5,700°/s) are beyond any IMU's full scale (±16 g and
/// ±2000°/s for a MEMS part), so a value past them is a unit slip (a variance typed
/// where its σ², or a PSD per hour where per second, was meant), not a sensor.
pub const MAX_IMU_ERROR: [f64; 2] = [1e3, 1e2];

/// `values` (6: accelerometers, then gyros) within [`MAX_IMU_ERROR`], squared where
/// `squared` (variances and PSDs), as the error naming `arg` and the element.
fn within_imu_range(arg: &str, values: &[f64], squared: bool) -> Result<()> {
    for (i, v) in values.iter().enumerate() {
        let (limit, unit) = if i < 3 {
            (MAX_IMU_ERROR[0], "m/s²")
        } else {
            (MAX_IMU_ERROR[1], "rad/s")
        };
        let bound = if squared { limit * limit } else { limit };
        if v.abs() > bound {
            let number = |x: f64| {
                if x.abs() >= 1e6 {
                    format!("{x:e}")
                } else {
                    format!("{x:.4}")
                        .trim_end_matches('0')
                        .trim_end_matches('.')
                        .to_string()
                }
            };
            // A variance or a PSD (its σ over a second) is compared by its square root.
            let what = if squared {
                format!("{} (σ {} {unit})", number(*v), number(v.sqrt()))
            } else {
                format!("{} {unit}", number(*v))
            };
            return Err(Error::invalid(
                arg,
                format!(
                    "element {i} is {what}, beyond {limit} {unit}, past any IMU's full \
                     scale (a unit slip?)"
                ),
            ));
        }
    }
    Ok(())
}

pub mod aiding;
mod dvl;
mod rng;
pub use aiding::{AidingModels, AidingSim, DepthModel, FixModel, HeadingModel};
pub use dvl::{DvlDropout, DvlModel};
pub use rng::{normal, stream_rng, Stream};

/// Per-channel IMU noise variance, piecewise constant in time: `values[i]` holds from
/// `times[i]` until `times[i+1]`. The sample covering `(t, t+dt]` uses the value at `t`.
/// Variances are per sample, in (m/s²)² for the accelerometers and (rad/s)² for the
/// gyros, channel order `[f_x, f_y, f_z, ω_x, ω_y, ω_z]`.
#[derive(Clone, Debug, PartialEq)]
pub struct VarianceSchedule {
    times: Vec<f64>,
    values: Vec<[f64; 6]>,
}

impl VarianceSchedule {
    pub fn constant(q: [f64; 6]) -> Self {
        Self {
            times: vec![0.0],
            values: vec![q],
        }
    }

    /// A schedule starting at `times[0] = 0` \[s\], strictly increasing.
    pub fn new(times: Vec<f64>, values: Vec<[f64; 6]>) -> Result<Self> {
        if times.is_empty() || times.len() != values.len() {
            return Err(Error::invalid(
                "imu_variance",
                format!(
                    "needs as many times as rows of variances (got {} and {}), at least one",
                    times.len(),
                    values.len()
                ),
            ));
        }
        check::increasing("imu_variance_times", &times)?;
        if times[0] != 0.0 {
            return Err(Error::invalid(
                "imu_variance_times",
                format!("the first time must be 0 s, got {}", times[0]),
            ));
        }
        for v in &values {
            check::non_negative("imu_variance", v)?;
        }
        Ok(Self { times, values })
    }

    /// The variances in force at time `t`, starting the search at `*cursor` (the index
    /// last returned), so a forward sweep costs O(1) per call.
    #[inline]
    pub fn at(&self, t: f64, cursor: &mut usize) -> &[f64; 6] {
        while *cursor + 1 < self.times.len() && t >= self.times[*cursor + 1] {
            *cursor += 1;
        }
        &self.values[*cursor]
    }

    pub fn times(&self) -> &[f64] {
        &self.times
    }

    pub fn values(&self) -> &[[f64; 6]] {
        &self.values
    }
}

/// IMU error model: white noise, constant bias, bias random walk.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuErrorModel {
    pub variance: VarianceSchedule,
    /// Constant bias `[b_a (m/s²), b_g (rad/s)]`.
    pub bias: [f64; 6],
    /// Bias random-walk PSD per channel \[(m/s²)²/s, (rad/s)²/s\].
    pub bias_rw_psd: [f64; 6],
}

/// All simulated sensors of a scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorConfig {
    pub imu: ImuErrorModel,
    /// The DVL (a period of 0: none).
    pub dvl: DvlModel,
    /// A pressure depth sensor (None: none).
    pub depth: Option<DepthModel>,
    /// A heading sensor (None: none).
    pub heading: Option<HeadingModel>,
    /// Sources of position fixes (none: empty).
    pub fixes: Vec<FixModel>,
}

impl SensorConfig {
    /// The paper's sensors: accelerometer variance 0.01², gyro 0.001², no bias, DVL
    /// variance 0.01 (m/s)² at 1 Hz, no lever arm.
    pub fn paper() -> Self {
        Self {
            imu: ImuErrorModel {
                variance: VarianceSchedule::constant([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]),
                bias: [0.0; 6],
                bias_rw_psd: [0.0; 6],
            },
            dvl: DvlModel {
                variance: [0.01; 3],
                period: 1.0,
                lever_arm: Vector3::zeros(),
                outages: Vec::new(),
                mounting: DvlMounting::default(),
                dropout: None,
            },
            depth: None,
            heading: None,
            fixes: Vec::new(),
        }
    }

    /// The aiding sensors besides the DVL.
    pub fn aiding(&self) -> AidingModels<'_> {
        AidingModels {
            depth: self.depth.as_ref(),
            heading: self.heading.as_ref(),
            fixes: &self.fixes,
        }
    }

    pub fn validate(&self) -> Result<()> {
        // `VarianceSchedule::constant` builds without checks; `new` checks the same way.
        for v in &self.imu.variance.values {
            check::non_negative("imu_variance", v)?;
            within_imu_range("imu_variance", v, true)?;
        }
        check::finite("imu_bias", &self.imu.bias)?;
        within_imu_range("imu_bias", &self.imu.bias, false)?;
        check::non_negative("imu_bias_psd", &self.imu.bias_rw_psd)?;
        within_imu_range("imu_bias_psd", &self.imu.bias_rw_psd, true)?;
        check::non_negative("dvl_variance", &self.dvl.variance)?;
        if !(self.dvl.period.is_finite() && self.dvl.period >= 0.0) {
            return Err(Error::invalid(
                "dvl_period",
                format!(
                    "must be finite and >= 0 s (0: no DVL), got {}",
                    self.dvl.period
                ),
            ));
        }
        if let Some(d) = &self.depth {
            d.validate()?;
        }
        if let Some(h) = &self.heading {
            h.validate()?;
        }
        for (i, f) in self.fixes.iter().enumerate() {
            f.validate(i)?;
        }
        check_lever_arm("lever_arm", self.dvl.lever_arm.as_slice())?;
        self.dvl.mounting.validate()?;
        if let Some(d) = &self.dvl.dropout {
            d.validate()?;
        }
        let mut previous_end = f64::NEG_INFINITY;
        for o in &self.dvl.outages {
            check::finite("dvl_outages", o)?;
            if !(o[0] < o[1] && o[0] >= previous_end) {
                let after = if previous_end.is_finite() {
                    format!(" after an outage ending at {previous_end} s")
                } else {
                    String::new()
                };
                return Err(Error::invalid(
                    "dvl_outages",
                    format!(
                        "need [start, end] rows with start < end [s], sorted and not \
                         overlapping; got [{}, {}]{after}",
                        o[0], o[1]
                    ),
                ));
            }
            previous_end = o[1];
        }
        Ok(())
    }
}

/// Per-run simulator of the noisy sensors, stepping along a truth.
pub struct SensorSim {
    imu_rng: ChaCha8Rng,
    dvl_rng: ChaCha8Rng,
    dropout_rng: ChaCha8Rng,
    locked: bool,
    bias: [f64; 6],
    cursor: usize,
}

impl SensorSim {
    pub fn new(cfg: &SensorConfig, seed: u64, run_index: u64) -> Self {
        Self {
            imu_rng: stream_rng(seed, run_index, Stream::Imu),
            dvl_rng: stream_rng(seed, run_index, Stream::Dvl),
            dropout_rng: stream_rng(seed, run_index, Stream::DvlDropout),
            locked: true,
            bias: cfg.imu.bias,
            cursor: 0,
        }
    }

    /// Start the bias at `bias` `[b_a, b_g]` instead of the configured one (a turn-on
    /// bias drawn for this run).
    pub fn with_turn_on_bias(mut self, bias: [f64; 6]) -> Self {
        self.bias = bias;
        self
    }

    /// The true IMU variances of the sample covering `(t_start, t_start + dt]`.
    pub fn variance(&mut self, cfg: &ImuErrorModel, t_start: f64) -> [f64; 6] {
        *cfg.variance.at(t_start, &mut self.cursor)
    }

    /// The bias that the next IMU sample carries `[b_a, b_g]`.
    pub fn bias(&self) -> &[f64; 6] {
        &self.bias
    }

    /// Noisy IMU sample for the interval starting at `t_start` \[s\] of length `dt`,
    /// given the ideal sample. The bias then takes one random-walk step.
    pub fn imu(
        &mut self,
        cfg: &ImuErrorModel,
        ideal: &[f64; 6],
        t_start: f64,
        dt: f64,
    ) -> [f64; 6] {
        let q = cfg.variance.at(t_start, &mut self.cursor);
        let mut out = [0.0; 6];
        for i in 0..6 {
            out[i] = ideal[i] + self.bias[i] + q[i].sqrt() * normal(&mut self.imu_rng);
        }
        for i in 0..6 {
            if cfg.bias_rw_psd[i] > 0.0 {
                self.bias[i] += (cfg.bias_rw_psd[i] * dt).sqrt() * normal(&mut self.imu_rng);
            }
        }
        out
    }

    /// Whether the DVL has bottom lock at a reading that is due: always without a
    /// dropout model (and no draw); else one step of its chain ([`DvlDropout`]).
    pub fn dvl_locked(&mut self, cfg: &DvlModel) -> bool {
        if let Some(d) = &cfg.dropout {
            let (lose, regain) = d.probabilities(cfg.period);
            let u: f64 = self.dropout_rng.random();
            self.locked = if self.locked { u >= lose } else { u < regain };
        }
        self.locked
    }

    /// Noisy DVL reading `(1 + k) M (C_n^b v^n + ω × r) + n` \[m/s, the DVL's axes\] for
    /// the true state and the true body rate `gyro` \[rad/s\]; with the ideal mounting
    /// (the default) `C_n^b v^n + ω × r + n`, in the body axes.
    pub fn dvl(&mut self, cfg: &DvlModel, truth: &NavState, gyro: &Vector3<f64>) -> Vector3<f64> {
        let mut v_b = truth.dcm.transpose() * truth.vel + gyro.cross(&cfg.lever_arm);
        if !cfg.mounting.is_ideal() {
            v_b = cfg.mounting.reading(&v_b);
        }
        Vector3::from_fn(|i, _| v_b[i] + cfg.variance[i].sqrt() * normal(&mut self.dvl_rng))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mounting_angles_round_trip_and_the_reading_rotates_into_the_dvl() {
        let m = DvlMounting::from_angles(0.005, [0.01, -0.02, 0.5f64.to_radians()]);
        let a = m.angles();
        assert!((a[0] - 0.01).abs() < 1e-12 && (a[1] + 0.02).abs() < 1e-12);
        assert!((a[2] - 0.5f64.to_radians()).abs() < 1e-12);
        // Yaw only: a forward body velocity has a negative DVL y in the DVL's axes
        // (its x axis is turned right, towards the body's +y).
        let yaw = DvlMounting::from_angles(0.0, [0.0, 0.0, 0.1]);
        let z = yaw.reading(&Vector3::new(1.0, 0.0, 0.0));
        assert!((z[0] - 0.1f64.cos()).abs() < 1e-15 && (z[1] + 0.1f64.sin()).abs() < 1e-15);
        let scaled = DvlMounting::from_angles(0.01, [0.0; 3]);
        assert_eq!(scaled.reading(&Vector3::new(2.0, 0.0, 0.0))[0], 2.02);
        assert!(DvlMounting::default().is_ideal() && !scaled.is_ideal());
    }

    use crate::attitude::dcm_from_euler;

    #[test]
    fn schedule_lookup_is_piecewise_constant() {
        let s = VarianceSchedule::new(vec![0.0, 10.0, 20.0], vec![[1.0; 6], [2.0; 6], [3.0; 6]])
            .unwrap();
        let mut c = 0;
        assert_eq!(s.at(0.0, &mut c)[0], 1.0);
        assert_eq!(s.at(9.99, &mut c)[0], 1.0);
        assert_eq!(s.at(10.0, &mut c)[0], 2.0);
        assert_eq!(s.at(25.0, &mut c)[0], 3.0);
        assert!(VarianceSchedule::new(vec![1.0], vec![[1.0; 6]]).is_err());
        assert!(VarianceSchedule::new(vec![0.0, 0.0], vec![[1.0; 6]; 2]).is_err());
        assert!(VarianceSchedule::new(vec![0.0], vec![[-1.0; 6]]).is_err());
    }

    #[test]
    fn imu_noise_has_the_scheduled_variance() {
        let mut cfg = SensorConfig::paper();
        cfg.imu.variance =
            VarianceSchedule::new(vec![0.0, 50.0], vec![[0.01; 6], [0.04; 6]]).unwrap();
        let mut sim = SensorSim::new(&cfg, 7, 3);
        let n = 20_000;
        let (mut s1, mut s2) = (0.0, 0.0);
        for k in 0..n {
            s1 += sim.imu(&cfg.imu, &[0.0; 6], k as f64 * 0.001, 0.001)[2].powi(2);
        }
        for k in 0..n {
            s2 += sim.imu(&cfg.imu, &[0.0; 6], 50.0 + k as f64 * 0.001, 0.001)[4].powi(2);
        }
        let (v1, v2) = (s1 / n as f64, s2 / n as f64);
        // Sample variance of 20k draws: relative standard error 1 %.
        assert!((v1 / 0.01 - 1.0).abs() < 0.05, "{v1}");
        assert!((v2 / 0.04 - 1.0).abs() < 0.05, "{v2}");
    }

    #[test]
    fn dvl_outages_are_half_open_and_checked() {
        let mut cfg = SensorConfig::paper();
        cfg.dvl.outages = vec![[10.0, 20.0], [30.0, 40.0]];
        cfg.validate().unwrap();
        assert!(cfg.dvl.available(9.99) && !cfg.dvl.available(10.0));
        assert!(!cfg.dvl.available(19.99) && cfg.dvl.available(20.0));
        assert!(!cfg.dvl.available(35.0) && cfg.dvl.available(40.0));
        for bad in [
            vec![[20.0, 10.0]],
            vec![[10.0, 20.0], [15.0, 25.0]],
            vec![[f64::NAN, 1.0]],
        ] {
            cfg.dvl.outages = bad;
            let err = cfg.validate().unwrap_err().to_string();
            assert!(err.starts_with("dvl_outages"), "{err}");
        }
    }

    #[test]
    fn dropout_losses_have_their_mean_length_and_share_and_are_checked() {
        let mut cfg = SensorConfig::paper();
        cfg.dvl.dropout = Some(DvlDropout {
            mean_interval: 60.0,
            mean_length: 20.0,
        });
        cfg.validate().unwrap();
        let mut sim = SensorSim::new(&cfg, 3, 1);
        let locked: Vec<bool> = (0..400_000).map(|_| sim.dvl_locked(&cfg.dvl)).collect();
        let lost = locked.iter().filter(|l| !**l).count() as f64 / locked.len() as f64;
        // stationary share lost: p_lose / (p_lose + p_regain), about 20 / 80
        let (p, r) = cfg.dvl.dropout.unwrap().probabilities(1.0);
        assert!((lost / (p / (p + r)) - 1.0).abs() < 0.05, "{lost}");
        let starts = locked.windows(2).filter(|w| w[0] && !w[1]).count() as f64;
        let mean_length = locked.iter().filter(|l| !**l).count() as f64 / starts;
        assert!(
            (mean_length / (1.0 / r) - 1.0).abs() < 0.05,
            "{mean_length}"
        );
        // the same draws for the same seed and run; none without the model
        let mut again = SensorSim::new(&cfg, 3, 1);
        assert!(locked[..1000]
            .iter()
            .all(|&l| l == again.dvl_locked(&cfg.dvl)));
        let paper = SensorConfig::paper();
        let mut plain = SensorSim::new(&paper, 3, 1);
        assert!((0..1000).all(|_| plain.dvl_locked(&paper.dvl)));
        for bad in [[0.0, 1.0], [1.0, f64::NAN], [-1.0, 1.0]] {
            cfg.dvl.dropout = Some(DvlDropout {
                mean_interval: bad[0],
                mean_length: bad[1],
            });
            let err = cfg.validate().unwrap_err().to_string();
            assert!(err.starts_with("dvl_dropout: needs"), "{err}");
        }
    }

    #[test]
    fn bias_random_walk_grows_with_the_psd() {
        let mut cfg = SensorConfig::paper();
        cfg.imu.variance = VarianceSchedule::constant([0.0; 6]);
        cfg.imu.bias_rw_psd = [1e-4; 6];
        // Over 100 s the bias variance is psd·T = 1e-2; average over 400 runs.
        let mut acc = 0.0;
        for run in 0..400 {
            let mut sim = SensorSim::new(&cfg, 1, run);
            for k in 0..1000 {
                sim.imu(&cfg.imu, &[0.0; 6], k as f64 * 0.1, 0.1);
            }
            acc += sim.bias()[0].powi(2);
        }
        let var = acc / 400.0;
        assert!((var / 1e-2 - 1.0).abs() < 0.25, "{var}");
    }

    #[test]
    fn streams_are_fixed_by_seed_and_run() {
        let cfg = SensorConfig::paper();
        let draw = |seed, run| SensorSim::new(&cfg, seed, run).imu(&cfg.imu, &[0.0; 6], 0.0, 0.01);
        assert_eq!(draw(5, 2), draw(5, 2));
        assert_ne!(draw(5, 2), draw(5, 3));
        assert_ne!(draw(5, 2), draw(6, 2));
    }

    #[test]
    fn dvl_sees_body_velocity_and_lever_arm() {
        let mut cfg = SensorConfig::paper();
        cfg.dvl.variance = [0.0; 3];
        cfg.dvl.lever_arm = Vector3::new(0.0, 0.0, 1.0);
        let truth = NavState {
            lla: Vector3::zeros(),
            vel: Vector3::new(0.0, 2.0, 0.0),
            dcm: dcm_from_euler(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        };
        let mut sim = SensorSim::new(&cfg, 0, 0);
        // Heading east at 2 m/s, rolling at 0.1 rad/s with the DVL 1 m below: ω × r = [0, −0.1, 0].
        let z = sim.dvl(&cfg.dvl, &truth, &Vector3::new(0.1, 0.0, 0.0));
        assert!((z - Vector3::new(2.0, -0.1, 0.0)).norm() < 1e-12, "{z:?}");
    }

    #[test]
    fn a_lever_arm_beyond_any_vehicle_is_refused_by_name() {
        let mut cfg = SensorConfig::paper();
        cfg.dvl.lever_arm = Vector3::new(0.0, -crate::ekf::MAX_LEVER_ARM, 2.0);
        assert!(cfg.validate().is_ok());
        cfg.dvl.lever_arm = Vector3::new(1e9, 0.0, 0.0);
        let err = cfg.validate().unwrap_err().to_string();
        assert!(
            err.starts_with("lever_arm: must be within ±1000 m"),
            "{err}"
        );
        assert!(err.ends_with("element 0 is 1000000000 m"), "{err}");
    }

    #[test]
    fn an_imu_error_past_any_full_scale_is_refused_by_name() {
        let mut cfg = SensorConfig::paper();
        // At the bounds: accepted (a 100 g noise is absurd, but not a unit slip).
        cfg.imu.bias = [1e3, -1e3, 0.0, 1e2, 0.0, -1e2];
        cfg.imu.bias_rw_psd = [1e6, 0.0, 0.0, 1e4, 0.0, 0.0];
        assert!(cfg.validate().is_ok());
        cfg.imu.bias[4] = 101.0;
        let err = cfg.validate().unwrap_err().to_string();
        assert!(
            err.starts_with("imu_bias: element 4 is 101 rad/s, beyond 100 rad/s"),
            "{err}"
        );
        cfg.imu.bias[4] = 0.0;
        cfg.imu.bias_rw_psd[1] = 1.1e6;
        let err = cfg.validate().unwrap_err().to_string();
        let said = "imu_bias_psd: element 1 is 1.1e6 (σ 1048.8088 m/s²), beyond 1000 m/s²";
        assert!(err.starts_with(said), "{err}");
        cfg.imu.bias_rw_psd[1] = 0.0;
        cfg.imu.variance = VarianceSchedule::constant([1e30; 6]);
        let err = cfg.validate().unwrap_err().to_string();
        assert!(
            err.starts_with("imu_variance: element 0 is 1e30 (σ 1e15 m/s²), beyond"),
            "{err}"
        );
    }
}
