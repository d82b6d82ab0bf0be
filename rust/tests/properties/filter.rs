//! Filter configurations and noise strategies.

use super::*;

/// A filter configuration with up to two wild fields.
pub(super) fn filter_config() -> impl Strategy<Value = FilterConfig> {
    (
        prop::collection::vec(-6.0..1.0f64, 15),
        prop_oneof![Just(0.0), -14.0..-2.0f64],
        prop_oneof![Just(0.0), -16.0..-4.0f64],
        prop::collection::vec(-6.0..0.0f64, 3),
        prop::collection::vec(-2.0..2.0f64, 3),
        any::<bool>(),
        prop_oneof![4 => Just(0.05), 1 => -3.0..0.0f64],
        // The DVL error states: off, or with 1σ and a scale walk of 10^e (and, with
        // a walk below 1e-3, the correlated error at 1σ 10^(e - 1)).
        prop_oneof![3 => Just(None), 1 => prop::collection::vec(-5.0..-1.0f64, 5).prop_map(Some)],
        // Corruptions: 0..15 p0_sigma, 15 accel psd, 16 gyro psd, 17..20 dvl variance,
        // 20..23 lever arm, 23 imu_dt, 24 innovation gate, 25..30 the calibration's
        // scale σ, misalignment σ (3) and scale walk (where the states are on), 30 the
        // covariance step.
        rarely((0..31usize, wild()), 2),
        // The formulation: all three are held to every property.
        0..3u8,
        // The covariance step: every sample, or intervals of 0.1 s.
        prop_oneof![2 => Just(0.0), 1 => Just(0.1)],
        // The second-order heading term, wherever it applies, in half the cases.
        any::<bool>(),
    )
        .prop_map(
            |(p0, psd_a, psd_g, r, arm, body, dt, cal, bad, formulation, step, term)| {
                let pow = |e: f64| if e == 0.0 { 0.0 } else { 10f64.powf(e) };
                let second_order = term && formulation != 2 && cal.is_none();
                let mut c = FilterConfig {
                    p0_sigma: std::array::from_fn(|i| 10f64.powf(p0[i])),
                    accel_bias_psd: pow(psd_a),
                    gyro_bias_psd: pow(psd_g),
                    dvl_variance: std::array::from_fn(|i| 10f64.powf(r[i])),
                    lever_arm: Vector3::new(arm[0], arm[1], arm[2]),
                    aiding: if body { Aiding::Body } else { Aiding::Nav },
                    imu_dt: if dt == 0.05 { dt } else { 10f64.powf(dt) },
                    innovation_gate: None,
                    dvl_calibration: cal.map(|e| CalibrationConfig {
                        scale_sigma: 10f64.powf(e[0]),
                        misalignment_sigma: [10f64.powf(e[1]), 10f64.powf(e[2]), 10f64.powf(e[3])],
                        scale_psd: 10f64.powf(e[4]),
                        misalignment_psd: 0.0,
                        calibrated: true,
                        // the DVL's correlated error too, in half the cases
                        bias_sigma: [if e[4] < -3.0 {
                            10f64.powf(e[0] - 1.0)
                        } else {
                            0.0
                        }; 3],
                        bias_time_constant: 30.0,
                    }),
                    formulation: match formulation {
                        0 => Formulation::Classic,
                        1 => Formulation::Invariant,
                        _ => Formulation::Se23,
                    },
                    covariance_step: step,
                    anchor: None,
                    heading_second_order: second_order,
                };
                for (field, v) in bad {
                    match (field, c.dvl_calibration.as_mut()) {
                        (0..=14, _) => c.p0_sigma[field] = v,
                        (15, _) => c.accel_bias_psd = v,
                        (16, _) => c.gyro_bias_psd = v,
                        (17..=19, _) => c.dvl_variance[field - 17] = v,
                        (20..=22, _) => c.lever_arm[field - 20] = v,
                        (23, _) => c.imu_dt = v,
                        (24, _) => c.innovation_gate = Some(v),
                        (25, Some(k)) => k.scale_sigma = v,
                        (26..=28, Some(k)) => k.misalignment_sigma[field - 26] = v,
                        (29, Some(k)) => k.scale_psd = v,
                        (30, _) => c.covariance_step = v,
                        _ => {}
                    }
                }
                c
            },
        )
}

/// The documented validity of a filter configuration (see `docs/reference/filter.md` and
/// `FilterConfig::validate`), computed independently.
pub(super) fn config_is_valid(c: &FilterConfig) -> bool {
    let nonneg = |v: f64| v.is_finite() && v >= 0.0;
    c.p0_sigma.iter().all(|v| nonneg(*v))
        && nonneg(c.accel_bias_psd)
        && nonneg(c.gyro_bias_psd)
        && c.dvl_variance.iter().all(|v| v.is_finite() && *v > 0.0)
        && all_finite(c.lever_arm.iter())
        && c.lever_arm
            .iter()
            .all(|v| v.abs() <= pronet::ekf::MAX_LEVER_ARM)
        && c.imu_dt.is_finite()
        && c.imu_dt > 0.0
        && c.innovation_gate.is_none_or(|g| g.is_finite() && g > 0.0)
        && nonneg(c.covariance_step)
        && c.dvl_calibration.is_none_or(|k| {
            c.aiding == Aiding::Body
                && nonneg(k.scale_sigma)
                && k.misalignment_sigma.iter().all(|v| nonneg(*v))
                && nonneg(k.scale_psd)
                && nonneg(k.misalignment_psd)
        })
}

/// The scalar metrics of a run summary: SRMSE, SMAE, final and max horizontal error,
/// mean NIS.
pub(super) fn summary_metrics(s: &RunSummary) -> [f64; 5] {
    [
        s.srmse,
        s.smae,
        s.final_horizontal_error,
        s.max_horizontal_error,
        s.mean_nis,
    ]
}

fn q_row() -> impl Strategy<Value = [f64; 6]> {
    (
        prop::collection::vec(-12.0..3.0f64, 6),
        rarely((0..6usize, wild()), 1),
    )
        .prop_map(|(e, bad)| {
            let mut q: [f64; 6] = std::array::from_fn(|i| 10f64.powf(e[i]));
            for (i, v) in bad {
                q[i] = v;
            }
            q
        })
}

pub(super) fn strategy_spec() -> impl Strategy<Value = StrategySpec> {
    prop_oneof![
        q_row().prop_map(|q| StrategySpec::Constant { q }),
        (0..5usize, q_row()).prop_map(|(window, prior_q)| StrategySpec::Mehra { window, prior_q }),
        q_row().prop_map(|prior_q| StrategySpec::External { prior_q }),
        (0..5usize, q_row())
            .prop_map(|(window, prior_q)| StrategySpec::Adaptive { window, prior_q }),
    ]
}

pub(super) fn strategy_is_valid(s: &StrategySpec) -> bool {
    let ok = |q: &[f64; 6]| q.iter().all(|v| v.is_finite() && *v >= 0.0);
    match s {
        StrategySpec::Constant { q } => ok(q),
        StrategySpec::Mehra { window, prior_q } | StrategySpec::Adaptive { window, prior_q } => {
            *window > 0 && ok(prior_q)
        }
        StrategySpec::External { prior_q } => ok(prior_q),
        StrategySpec::Oracle => true,
    }
}

/// Recorded arrays of a short simulated run (20 s at 20 Hz, DVL at 1 Hz): the paper's
/// sensors along a straight leg, a turn and a speed-up.
pub(super) struct Recording {
    pub(super) truth: Truth,
    pub(super) imu: Vec<[f64; 6]>,
    pub(super) imu_time: Vec<f64>,
    pub(super) dvl: Vec<[f64; 3]>,
    pub(super) dvl_time: Vec<f64>,
}

pub(super) fn recording() -> &'static Recording {
    static CELL: OnceLock<Recording> = OnceLock::new();
    CELL.get_or_init(|| {
        let spec = TrajectorySpec {
            name: "recording".into(),
            lla0: paper_origin(),
            speed0: 1.0,
            rpy0: Vector3::zeros(),
            segments: vec![
                Segment::new(8.0, 0.0, 0.0, 0.0),
                Segment::new(6.0, 0.0, 10f64.to_radians(), 0.0),
                Segment::new(6.0, 0.05, 0.0, 0.0),
            ],
            dt: 0.05,
        };
        let truth = spec.generate().unwrap();
        let sensors = SensorConfig::paper();
        let mut sim = SensorSim::new(&sensors, 11, 0);
        let mut imu = Vec::new();
        let mut dvl = Vec::new();
        let mut dvl_time = Vec::new();
        for k in 0..truth.len() {
            imu.push(sim.imu(&sensors.imu, &truth.imu[k], truth.time[k], truth.dt));
            if (k + 1) % 20 == 0 {
                let g = &truth.imu[k];
                let z = sim.dvl(
                    &sensors.dvl,
                    &truth.states[k + 1],
                    &Vector3::new(g[3], g[4], g[5]),
                );
                dvl.push([z[0], z[1], z[2]]);
                dvl_time.push(truth.time[k + 1]);
            }
        }
        let imu_time = truth.time[1..].to_vec();
        Recording {
            truth,
            imu,
            imu_time,
            dvl,
            dvl_time,
        }
    })
}

/// Which DVL rows a case uses.
#[derive(Clone, Copy, Debug)]
enum DvlRows {
    All,
    None,
    FirstFive,
}

/// One corruption of the recorded data: 0 an IMU value, 1 a DVL value, 2 a DVL time,
/// 3 t0, 4 the initial bias, 5 the initial velocity.
type DataCorruption = (usize, Index, usize, f64);

fn check_output(out: &FilterOutput, n_imu: usize, n_dvl: usize) -> Result<(), TestCaseError> {
    prop_assert_eq!(out.time.len(), n_imu + 1);
    prop_assert_eq!(solution_epochs(out), n_imu + 1);
    prop_assert_eq!(out.sigma.len(), n_imu + 1);
    let dvl = &out.streams[0];
    prop_assert_eq!(dvl.updates.len(), n_dvl);
    prop_assert!(all_finite(&out.time));
    for k in 0..solution_epochs(out) {
        prop_assert!(
            solution_finite(out, k),
            "non-finite solution at epoch {}",
            k
        );
    }
    for (k, b) in out.bias.iter().enumerate() {
        prop_assert!(all_finite(b), "non-finite bias at epoch {}: {:?}", k, b);
    }
    for (k, s) in out.sigma.iter().enumerate() {
        prop_assert!(all_finite(s), "non-finite sigma at epoch {}: {:?}", k, s);
    }
    prop_assert!(
        all_finite(out.final_covariance.iter()),
        "non-finite final covariance: diag {:?}",
        out.final_covariance.diagonal().as_slice()
    );
    // σ is √diag P: a NaN variance must not come out as σ = 0.
    let last = out.sigma.last().unwrap();
    for (i, s) in last.iter().enumerate() {
        let var = out.final_covariance[(i, i)];
        prop_assert!(
            (s * s - var.max(0.0)).abs() <= 1e-9 * var.abs().max(1e-300),
            "sigma[{}] = {} but P[{},{}] = {}",
            i,
            s,
            i,
            i,
            var
        );
    }
    for (j, u) in dvl.updates.iter().enumerate() {
        prop_assert_eq!(u.is_some(), dvl.epoch[j].is_some());
        if let Some(u) = u {
            prop_assert!(
                u.nis.is_finite()
                    && all_finite(u.innovation.iter())
                    && all_finite(u.s.iter())
                    && all_finite(u.gain.iter()),
                "non-finite update {}: {:?}",
                j,
                u
            );
        }
    }
    for (j, q) in dvl.adaptive_q.iter().enumerate() {
        if let Some(q) = q {
            prop_assert!(all_finite(q.iter()), "non-finite adaptive Q at row {}", j);
        }
    }
    Ok(())
}

/// Finite tuning values so large that P overflows (σ² or q·Δt sums beyond f64): the
/// library accepts them (they are finite and ≥ 0) and does not notice the overflow. See
/// the pinned tests at the end of this file; the main properties leave them out.
pub(super) const HUGE: f64 = 1e100;

/// Data values (IMU samples, DVL rows and times, t0, initial velocity and bias) of this
/// size are physically absurd; with no DVL update after them they overflow the state
/// unnoticed, like [`HUGE`] tuning values. Left out of the main property.
pub(super) const ABSURD_DATA: f64 = 1e6;

pub(super) fn huge_tuning(cfg: &FilterConfig, spec: &StrategySpec) -> bool {
    let q = match spec {
        StrategySpec::Constant { q } => q,
        StrategySpec::Mehra { prior_q, .. }
        | StrategySpec::Adaptive { prior_q, .. }
        | StrategySpec::External { prior_q } => prior_q,
        StrategySpec::Oracle => &[0.0; 6],
    };
    let calibration: Vec<f64> = cfg
        .dvl_calibration
        .iter()
        .flat_map(|k| {
            [k.scale_sigma, k.scale_psd, k.misalignment_psd]
                .into_iter()
                .chain(k.misalignment_sigma)
        })
        .collect();
    let huge = cfg
        .p0_sigma
        .iter()
        .chain(q)
        .chain([&cfg.accel_bias_psd, &cfg.gyro_bias_psd, &cfg.imu_dt])
        .chain(&calibration)
        .any(|v| v.is_finite() && v.abs() >= HUGE);
    huge
}

/// One case of the filter-pass property (known overflow cases are left out).
fn filter_case(
    cfg: &FilterConfig,
    spec: &StrategySpec,
    rows: DvlRows,
    bad: &[DataCorruption],
) -> Result<(), TestCaseError> {
    let rec = recording();
    let valid_cfg = config_is_valid(cfg);
    prop_assert_eq!(
        cfg.validate().is_ok(),
        valid_cfg,
        "validate() disagrees: {:?}",
        cfg
    );
    let truth0 = rec.truth.states[0];
    prop_assert_eq!(
        Ekf::new(cfg, truth0, Vector3::zeros(), Vector3::zeros()).is_ok(),
        valid_cfg
    );
    // Strategies come validated, as every public entry point does (Python, Monte Carlo).
    if !strategy_is_valid(spec) {
        prop_assert!(
            spec.validate().is_err(),
            "invalid strategy accepted: {:?}",
            spec
        );
        return Ok(());
    }
    prop_assert!(
        spec.validate().is_ok(),
        "valid strategy refused: {:?}",
        spec
    );
    let huge_data = bad
        .iter()
        .any(|c| c.3.is_finite() && c.3.abs() >= ABSURD_DATA);
    if valid_cfg && (huge_tuning(cfg, spec) || huge_data) {
        return Ok(());
    }

    let mut imu = rec.imu.clone();
    let (mut dvl, mut dvl_time) = match rows {
        DvlRows::All => (rec.dvl.clone(), rec.dvl_time.clone()),
        DvlRows::None => (Vec::new(), Vec::new()),
        DvlRows::FirstFive => (rec.dvl[..5].to_vec(), rec.dvl_time[..5].to_vec()),
    };
    let mut t0 = 0.0;
    let mut bias0 = [0.0; 6];
    let mut init = truth0;
    let mut bad_data = false;
    for &(what, row, col, v) in bad {
        match what {
            0 => {
                let i = row.index(imu.len());
                imu[i][col] = v;
            }
            1 if !dvl.is_empty() => {
                let i = row.index(dvl.len());
                dvl[i][col % 3] = v;
            }
            2 if !dvl.is_empty() => {
                let i = row.index(dvl.len());
                dvl_time[i] = v;
            }
            3 => t0 = v,
            4 => bias0[col] = v,
            5 => init.vel[col % 3] = v,
            _ => continue,
        }
        bad_data |= !v.is_finite();
    }
    let data = RecordedData {
        imu: &imu,
        imu_time: &rec.imu_time,
        t0,
        streams: vec![Stream::dvl(&dvl, &dvl_time, cfg)],
        ..RecordedData::default()
    };
    let mut strategy = spec.build(cfg.bias_psd());
    let result = filter_recorded(&data, init, bias0, cfg, strategy.as_mut());
    if valid_cfg && bad.is_empty() {
        // Valid inputs: the pass may only fail numerically.
        prop_assert!(
            !matches!(result, Err(pronet::Error::InvalidArgument { .. })),
            "valid inputs refused: {:?}",
            result.as_ref().err()
        );
    }
    if !valid_cfg || bad_data {
        prop_assert!(
            matches!(result, Err(pronet::Error::InvalidArgument { .. })),
            "invalid config or non-finite data not refused as an invalid argument: {:?}, {:?}",
            cfg,
            bad
        );
    }
    if let Ok(out) = &result {
        check_output(out, imu.len(), dvl.len())?;
    }
    Ok(())
}

fn dvl_rows() -> impl Strategy<Value = DvlRows> {
    prop_oneof![
        4 => Just(DvlRows::All),
        1 => Just(DvlRows::None),
        1 => Just(DvlRows::FirstFive),
    ]
}

fn data_corruptions() -> BoxedStrategy<Vec<DataCorruption>> {
    rarely((0..6usize, any::<Index>(), 0..6usize, wild()), 1)
}

proptest! {
    #![proptest_config(config())]

    /// Random filter configs (P0 σ, bias PSDs, DVL variances, lever arm, imu_dt),
    /// strategies and recorded-data corruptions through `filter_recorded`.
    #[test]
    fn filter_pass_is_finite_or_err(
        cfg in filter_config(),
        spec in strategy_spec(),
        rows in dvl_rows(),
        bad in data_corruptions(),
    ) {
        filter_case(&cfg, &spec, rows, &bad)?;
    }
}
