//! Tests of the thinned output ([`Epochs::Step`]) and of the node-only smoother over
//! it: the kept epochs are the nearest to each multiple of the period, the forward
//! solution re-integrated between nodes is the forward pass's bit for bit, and the
//! thinned forward and smoothed solutions equal the every-epoch ones at the kept
//! epochs bit for bit.

use super::data::RecordedData;
use super::epochs::Epochs;
use super::filter::{filter_recorded_until, smooth_recorded_until, thinned_source, Recording};
use super::output::FilterOutput;
use super::stream::Stream;
use super::tests::per_sample;
use crate::cancel::Cancel;
use crate::ekf::calibration::CalibrationConfig;
use crate::ekf::tests::moving_state;
use crate::ekf::{FilterConfig, Formulation};
use crate::error::Error;
use crate::noise::StrategySpec;
use crate::smoother::thinned::{self, NodeStates, Stretch};
use crate::smoother::{closes, Forward, ForwardLog};

/// A recording's arrays: IMU rows, their times, DVL rows, their times.
type Arrays = (Vec<[f64; 6]>, Vec<f64>, Vec<[f64; 3]>, Vec<f64>);

/// 6 s of a moving, turning vehicle at 100 Hz with a DVL row every 0.2 s.
fn pass() -> Arrays {
    let n = 600;
    let imu = (0..n)
        .map(|k| {
            let wobble = (k as f64 * 0.07).sin();
            [0.02 * wobble, -0.01, -9.79, 1e-4, 2e-4 * wobble, 2e-3]
        })
        .collect();
    let imu_time = (1..=n).map(|k| k as f64 * 0.01).collect();
    let dvl_time: Vec<f64> = (1..=n / 20).map(|k| k as f64 * 0.2 + 0.003).collect();
    let dvl = dvl_time
        .iter()
        .map(|t| [1.1 + 0.01 * t, 0.01, -0.002 * t])
        .collect();
    (imu, imu_time, dvl, dvl_time)
}

/// The configurations the smoother distinguishes: both formulations, 15 and 19 states,
/// every sample and a covariance step.
fn configs() -> Vec<FilterConfig> {
    let mut out = Vec::new();
    for formulation in [Formulation::Classic, Formulation::Invariant] {
        for calibration in [None, Some(CalibrationConfig::default())] {
            for covariance_step in [0.0, 0.07] {
                out.push(FilterConfig {
                    formulation,
                    covariance_step,
                    dvl_calibration: calibration,
                    ..per_sample()
                });
            }
        }
    }
    out
}

#[test]
fn an_output_step_keeps_the_epoch_nearest_each_multiple() {
    let (imu, imu_time, _, _) = pass();
    let data = RecordedData {
        imu: &imu,
        imu_time: &imu_time,
        t0: 0.0,
        ..RecordedData::default()
    };
    let spec = StrategySpec::Constant { q: [1e-4; 6] };
    let run = |epochs: Epochs| {
        let cfg = per_sample();
        let mut strategy = spec.build(cfg.bias_psd());
        let cancel = Cancel::default();
        filter_recorded_until(
            &data,
            moving_state(),
            [0.0; 6],
            &cfg,
            strategy.as_mut(),
            epochs,
            &cancel,
        )
    };
    // 0.3337 s: multiples at 0.3337, 0.6674, 1.0011 ... nearest epochs 33 (0.33 s), 67,
    // 100 ..., 17 of them before the last epoch's half step.
    let out = run(Epochs::Step(0.3337)).unwrap();
    let expected: Vec<usize> = std::iter::once(0)
        .chain((1..=17).map(|m| (m as f64 * 33.37f64).round() as usize))
        .chain(std::iter::once(600))
        .collect();
    assert_eq!(out.epoch, expected);
    assert_eq!(out.time.len(), expected.len());
    // A step below the IMU's keeps every epoch, once.
    let dense = run(Epochs::Step(0.004)).unwrap();
    assert_eq!(dense.epoch, (0..=600).collect::<Vec<_>>());
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let err = run(Epochs::Step(bad)).unwrap_err().to_string();
        assert!(err.contains("output_step"), "{err}");
    }
}

/// Every strategy's nodes, with depth readings and position fixes, in every
/// configuration: a thinned pass (forward and smoothed) equals the every-epoch one at
/// its kept epochs, bit for bit, and the re-integration between nodes gives the forward
/// solution at every epoch, bit for bit.
#[test]
fn thinned_passes_equal_the_every_epoch_pass_at_the_kept_epochs() {
    let (imu, imu_time, dvl, dvl_time) = pass();
    let q = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
    let lla = moving_state().lla;
    let depth_time: Vec<f64> = (1..12).map(|k| k as f64 * 0.5 + 0.01).collect();
    let depth: Vec<f64> = depth_time.iter().map(|t| 10.0 + 0.1 * t).collect();
    let fix = [
        [lla[0] + 1e-7, lla[1] - 2e-7, f64::NAN],
        [lla[0], lla[1], 9.0],
    ];
    let (fix_time, fix_sigma) = ([2.456, 4.5], [[2.0, 2.0, 3.0], [1.0, 1.5, 0.5]]);
    let cases = [
        (StrategySpec::Constant { q }, vec![], vec![]),
        (
            StrategySpec::External { prior_q: q },
            vec![1.504, 3.0, 4.257],
            vec![[4e-4; 6], q, [2e-4; 6]],
        ),
    ];
    for cfg in configs() {
        for (spec, q_time, q_values) in &cases {
            let data = RecordedData {
                imu: &imu,
                imu_time: &imu_time,
                streams: vec![
                    Stream::dvl(&dvl, &dvl_time, &FilterConfig::default()),
                    Stream::depth(&depth, &depth_time, 0.1),
                    Stream::fix(&fix, &fix_time, &fix_sigma),
                ],
                q_time,
                q_values,
                ..RecordedData::default()
            };
            let cancel = Cancel::default();
            let run = |epochs: Epochs| {
                let mut strategy = spec.build(cfg.bias_psd());
                let s = strategy.as_mut();
                smooth_recorded_until(&data, moving_state(), [0.0; 6], &cfg, s, epochs, &cancel)
                    .unwrap()
            };
            let all = run(Epochs::All);
            let full = all.smoothed.as_ref().unwrap();
            same_solution_kept_as_states_or_rows(&data, &cfg, spec, Epochs::All, &all);
            for step in [0.25, 0.013] {
                let thin = run(Epochs::Step(step));
                same_solution_kept_as_states_or_rows(&data, &cfg, spec, Epochs::Step(step), &thin);
                let s = thin.smoothed.as_ref().unwrap();
                let what = format!("{spec:?} {cfg:?} step {step}");
                assert!(thin.epoch.len() < 601 && thin.epoch.len() > 20, "{what}");
                for (row, &e) in thin.epoch.iter().enumerate() {
                    assert_eq!(thin.time[row], all.time[e], "{what}");
                    assert_eq!(thin.nav[row], all.nav[e], "{what} epoch {e}");
                    assert_eq!(thin.bias[row], all.bias[e], "{what} epoch {e}");
                    assert_eq!(thin.sigma[row], all.sigma[e], "{what} epoch {e}");
                    assert_eq!(s.nav[row], full.nav[e], "{what} epoch {e}");
                    assert_eq!(s.bias[row], full.bias[e], "{what} epoch {e}");
                    assert_eq!(s.sigma[row], full.sigma[e], "{what} epoch {e}");
                    if cfg.dvl_calibration.is_some() {
                        assert_eq!(thin.calibration[row], all.calibration[e]);
                        assert_eq!(thin.calibration_sigma[row], all.calibration_sigma[e]);
                        assert_eq!(s.calibration[row], full.calibration[e], "{what} {e}");
                        assert_eq!(s.calibration_sigma[row], full.calibration_sigma[e]);
                    }
                }
                for (a, b) in thin.streams.iter().zip(&all.streams) {
                    assert_eq!((&a.epoch, &a.nis), (&b.epoch, &b.nis));
                }
                assert_eq!(thin.final_covariance, all.final_covariance);
            }
            // The smoothing moved the solution (the comparison above is not vacuous).
            assert_ne!(full.nav[300], all.nav[300]);
            reintegration_is_exact(&data, &cfg, spec, &all);
        }
    }
}

/// A pass without the smoother keeps its solution as rows, a smoothed one (`smoothed`)
/// as whole states, one form only, at every kept epoch; both forms give the same rows,
/// bit for bit.
fn same_solution_kept_as_states_or_rows(
    data: &RecordedData<'_>,
    cfg: &FilterConfig,
    spec: &StrategySpec,
    epochs: Epochs,
    smoothed: &FilterOutput,
) {
    let mut strategy = spec.build(cfg.bias_psd());
    let (x, c) = (moving_state(), Cancel::default());
    let plain =
        filter_recorded_until(data, x, [0.0; 6], cfg, strategy.as_mut(), epochs, &c).unwrap();
    let rows = plain.time.len();
    assert_eq!(plain.time, smoothed.time);
    assert!(plain.nav.is_empty() && smoothed.lla.is_empty() && smoothed.vel.is_empty());
    assert_eq!((smoothed.nav.len(), smoothed.rpy.len()), (rows, 0));
    assert_eq!(
        [plain.lla.len(), plain.vel.len(), plain.rpy.len()],
        [rows; 3]
    );
    for k in 0..rows {
        assert_eq!(
            plain.solution(k),
            smoothed.solution(k),
            "{epochs:?} epoch {k}"
        );
    }
}

/// The forward solution integrated again from each node equals the pass's at every
/// epoch up to the next node.
fn reintegration_is_exact(
    data: &RecordedData<'_>,
    cfg: &FilterConfig,
    spec: &StrategySpec,
    all: &FilterOutput,
) {
    let mut log = ForwardLog {
        states: Some(NodeStates::default()),
        ..ForwardLog::default()
    };
    let mut strategy = spec.build(cfg.bias_psd());
    let keep = Some(&mut log);
    let (x, b, c) = (moving_state(), [0.0; 6], Cancel::default());
    let out = Recording {
        data,
        initial: x,
        initial_bias: b,
        cfg,
    }
    .forward(strategy.as_mut(), Epochs::All, keep, &c)
    .unwrap();
    assert_eq!(out.nav, all.nav);
    let epochs: Vec<usize> = (0..out.nav.len()).collect();
    let (nodes, states) = (&log.nodes, log.states.as_ref().unwrap());
    let src = thinned_source(data, states, &out, &epochs);
    let mut stretch = Stretch::default();
    assert!(nodes.0.len() > 30);
    let every = Forward {
        imu: data.imu,
        imu_time: data.imu_time,
        t0: data.t0,
        nav: &out.nav,
        bias: &out.bias,
        calibration: &out.calibration,
        sigma: &out.sigma,
        calibration_sigma: &out.calibration_sigma,
        dt: None,
    };
    let mut closes = Vec::new();
    let (mut inside_a_step, mut compared) = (0, 0);
    for (j, pair) in nodes.0.windows(2).enumerate() {
        let (a, b) = (&pair[0], &pair[1]);
        let (forward, start) = stretch.rebuild(&src, j, a, b.epoch, &c).unwrap();
        assert_eq!(start.epoch, 0);
        assert_eq!(forward.nav, &out.nav[a.epoch..b.epoch]);
        assert_eq!(forward.bias[0], out.bias[a.epoch]);
        if cfg.covariance_every_sample() {
            continue;
        }
        // Under a covariance step, the closes rebuilt in the same sweep as the
        // re-integration are those rebuilt from the kept solution, bit for bit.
        inside_a_step += usize::from(a.step.is_some());
        let mut want = Vec::new();
        closes::steps::<19>(&every, cfg, (a, b), &mut want, &c).unwrap();
        thinned::rebuild_closes::<19>(&src, cfg, j, (a, b), &mut closes, &c).unwrap();
        compared += want.len();
        assert_eq!(closes.len(), want.len(), "closes from epoch {}", a.epoch);
        for (got, want) in closes.iter().zip(&want) {
            assert_eq!(got.epoch, want.epoch);
            assert_eq!(got.phi, want.phi, "Φ at epoch {}", want.epoch);
            assert_eq!(got.p_prior, want.p_prior, "P at epoch {}", want.epoch);
            let velocities = |c: &closes::Close<19, _>| (c.point_prior, c.point);
            assert_eq!(
                velocities(got),
                velocities(want),
                "v at epoch {}",
                want.epoch
            );
        }
    }
    let q_rows = data.q_time.len();
    assert!(cfg.covariance_every_sample() || q_rows == 0 || inside_a_step > 0);
    assert!(
        cfg.covariance_every_sample() || compared > 50,
        "{compared} closes"
    );
}

/// A stretch without updates (here 25,000 IMU samples, no aiding at all: one interval
/// from the first epoch to the last) is re-integrated with the cancel checked as it
/// goes: a cancelled token stops it within [`STEPS_PER_CHECK`] steps with
/// [`Error::Cancelled`] (no panic, the rest of the stretch not integrated), a live one
/// lets it run to the end.
#[test]
fn the_reintegration_of_a_long_stretch_stops_when_cancelled() {
    use crate::cancel::STEPS_PER_CHECK;
    let n = 25_000;
    let imu: Vec<[f64; 6]> = (0..n)
        .map(|_| [0.01, -0.01, -9.79, 1e-4, 0.0, 2e-3])
        .collect();
    let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
    let data = RecordedData {
        imu: &imu,
        imu_time: &imu_time,
        t0: 0.0,
        ..RecordedData::default()
    };
    let cfg = per_sample();
    let mut log = ForwardLog {
        states: Some(NodeStates::default()),
        ..ForwardLog::default()
    };
    let mut strategy = StrategySpec::Constant { q: [1e-4; 6] }.build(cfg.bias_psd());
    let live = Cancel::default();
    let out = Recording::of(&data, &cfg)
        .forward(strategy.as_mut(), Epochs::Step(1.0), Some(&mut log), &live)
        .unwrap();
    let (nodes, states) = (&log.nodes, log.states.as_ref().unwrap());
    assert_eq!(nodes.0.len(), 2, "one stretch: the first epoch to the last");
    let src = thinned_source(&data, states, &out, &out.epoch);
    let (a, end) = (&nodes.0[0], nodes.0[1].epoch);
    assert!(end - a.epoch > 5 * STEPS_PER_CHECK);
    let mut stretch = Stretch::default();
    let cancelled = Cancel::default();
    cancelled.cancel();
    let err = stretch.rebuild(&src, 0, a, end, &cancelled).err();
    assert_eq!(err, Some(Error::Cancelled));
    assert!(stretch.nav.len() < STEPS_PER_CHECK, "{}", stretch.nav.len());
    // The same buffer, not cancelled: the whole stretch, ending at the kept solution.
    let (forward, _) = stretch.rebuild(&src, 0, a, end, &live).unwrap();
    assert_eq!(forward.nav.len(), end - a.epoch);
    let last_kept = out.epoch.len() - 2; // the kept epoch before the last
    let e = out.epoch[last_kept];
    assert_eq!(forward.nav[e - a.epoch], out.nav[last_kept]);
    // Through the node-only smoother: a cancelled token ends it with the error.
    let err = thinned::smooth(&src, &cfg, &nodes.0, &cancelled).err();
    assert_eq!(err, Some(Error::Cancelled));
}

/// A kept epoch inside a covariance step reads σ interpolated between the σ at the
/// last up-to-date epoch, kept or not (after its updates), and the σ at the close that
/// ends its step (before the updates there). [`StaleSigma`] computes them only where
/// they are read (the close's while a kept epoch is pending, the up-to-date epoch's
/// from a copy of its P and velocity); here both are computed at every such epoch, and
/// the rows must match bit for bit, the calibration σ too (its states walk, so it
/// grows over a step). The ends a wrong choice would take (the close before the kept
/// epoch, the up-to-date epoch before the last) give other values of σ (not of the
/// calibration σ: a random walk's variance grows linearly between updates, and any two
/// points of it interpolate alike); some steps hold two kept epochs.
#[test]
fn a_kept_epoch_inside_a_step_reads_the_sigma_at_its_steps_ends() {
    use super::stale::StaleSigma;
    use crate::ekf::tests::dvl as dvl_reading;
    use crate::ekf::{calibration::Calibration, ClosedSigma, Ekf, ProcessNoise};
    use crate::mechanization::ImuSample;
    use nalgebra::Vector3;
    let (imu, _, dvl, _) = pass();
    let (q, sigmas) = ([1e-4; 6], |ekf: &Ekf| -> ClosedSigma {
        (
            ekf.sigma(),
            ekf.calibration.as_ref().map(Calibration::sigma),
        )
    });
    let between = |t: f64, (t_a, a): (f64, ClosedSigma), (t_b, b): (f64, ClosedSigma)| {
        let w = (t - t_a) / (t_b - t_a);
        let f = |from: f64, to: f64| (from * from + w * (to * to - from * from)).sqrt();
        let c = std::array::from_fn(|i| f(a.1.unwrap()[i], b.1.unwrap()[i]));
        (std::array::from_fn(|i| f(a.0[i], b.0[i])), Some(c))
    };
    for formulation in [Formulation::Classic, Formulation::Invariant] {
        let cfg = FilterConfig {
            formulation,
            covariance_step: 0.07,
            dvl_calibration: Some(CalibrationConfig {
                scale_psd: 1e-6,
                misalignment_psd: 1e-8,
                ..CalibrationConfig::default()
            }),
            ..per_sample()
        };
        let bias = cfg.bias_psd();
        let noise = ProcessNoise::Continuous {
            imu_variance: &q,
            bias_psd: &bias,
        };
        let zero = Vector3::zeros();
        let mut ekf = Ekf::new(&cfg, moving_state(), zero, zero).unwrap();
        let (mut stale, mut out) = (StaleSigma::default(), FilterOutput::default());
        let record = |out: &mut FilterOutput, ekf: &Ekf, t: f64| {
            let (sigma, calibration) = sigmas(ekf);
            out.time.push(t);
            out.sigma.push(sigma);
            out.calibration_sigma.push(calibration.unwrap());
        };
        record(&mut out, &ekf, 0.0);
        stale.after_epoch(&ekf, &mut out, 0.0, true);
        // Every up-to-date epoch and every close, as an eager pass takes them; the kept
        // epochs inside a step: (row, its start in `current`, its end in `closes`).
        let (mut current, mut closes) = (vec![(0.0, sigmas(&ekf), true)], Vec::new());
        let mut inside = Vec::new();
        for (k, sample) in imu.iter().enumerate().map(|(k, s)| (k + 1, s)) {
            let t = k as f64 * 0.01;
            let mut closed = false;
            ekf.propagate_observed(&ImuSample::from_array(sample), 0.01, noise, |_, _| {
                closed = true
            })
            .unwrap();
            if closed {
                stale.on_close(&ekf);
            }
            let aided = k % 20 == 0;
            if aided && ekf.bring_up_to_date().is_some() {
                stale.on_close(&ekf);
            }
            let up_to_date = ekf.is_up_to_date(); // a close at this epoch
            if up_to_date {
                closes.push((t, sigmas(&ekf)));
            }
            if aided {
                let z = Vector3::from(dvl[k / 20 - 1]);
                ekf.apply(&dvl_reading(&ekf, z)).unwrap();
            }
            let kept = k % 9 == 4 || k % 9 == 6;
            if kept {
                record(&mut out, &ekf, t);
            }
            stale.after_epoch(&ekf, &mut out, t, kept);
            if up_to_date {
                current.push((t, sigmas(&ekf), kept));
            } else if kept {
                inside.push((out.time.len() - 1, current.len() - 1, closes.len()));
            }
        }
        let (mut unkept_start, mut updated_start) = (0, 0);
        for &(row, a, b) in inside.iter().filter(|&&(_, _, b)| b < closes.len()) {
            let (t, start) = (out.time[row], (current[a].0, current[a].1));
            let want = between(t, start, closes[b]);
            let what = format!("{formulation:?} row {row} at {t} s");
            assert_eq!(out.sigma[row], want.0, "{what}");
            assert_eq!(Some(out.calibration_sigma[row]), want.1, "{what}");
            // The wrong ends give other values: the comparison tells them apart.
            if a > 0 && b > 0 {
                let stale_start = (current[a - 1].0, current[a - 1].1);
                let (early, late) = (
                    between(t, stale_start, closes[b]),
                    between(t, start, closes[b - 1]),
                );
                assert_ne!(early.0, want.0, "{what}");
                assert_ne!(late.0, want.0, "{what}");
            }
            unkept_start += usize::from(!current[a].2);
            updated_start +=
                usize::from(!current[a].2 && (current[a].0 * 100.0).round() % 20.0 == 0.0);
        }
        // Two kept epochs inside one step: the same start and the same close.
        let pairs = inside
            .windows(2)
            .filter(|w| (w[0].1, w[0].2) == (w[1].1, w[1].2))
            .count();
        assert!(
            unkept_start > 30 && updated_start > 5 && pairs > 10,
            "{unkept_start} {updated_start} {pairs}"
        );
    }
}
