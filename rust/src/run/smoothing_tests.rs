//! Tests of the smoother over a simulated run (`super`): kept closes against rebuilt
//! ones, and the metrics' reduced solution against the whole smoothed one.

use super::{smooth_into, Cancel, Covariances, Formulation, Forward, Reduced};
use crate::ekf::calibration::CalibrationConfig;
use crate::ekf::FilterConfig;
use crate::montecarlo::tests::{short_scenario, tuned_filter, TRUE_Q};
use crate::noise::StrategySpec;
use crate::run::Run;
use crate::smoother::smooth;

/// The closes of the covariance step that a run keeps are the ones the backward
/// pass would rebuild: the smoothed record from either is the same, bit for bit
/// (15 and 19 states, σ recorded every 7 epochs: some inside the step before a DVL
/// update, whose σ reads the velocity before it, and some after the last close),
/// and σ is finite at every recorded epoch, those after the run's last close too
/// (the kept closes once lost the one that brings the last step up to date).
#[test]
fn kept_closes_smooth_as_the_rebuilt_ones() {
    let sc = short_scenario(30.0);
    let spec = StrategySpec::Constant { q: TRUE_Q };
    for calibration in [None, Some(CalibrationConfig::default())] {
        let cfg = FilterConfig {
            covariance_step: 0.1,
            dvl_calibration: calibration,
            ..tuned_filter()
        };
        let record = |kept: bool| {
            let mut run = Run::new(&sc, &cfg, &spec, 3, 1, 7, None).unwrap();
            run.keep_for_smoother(&sc);
            if !kept {
                // Rebuilt: the bias estimates at every epoch, the first's too.
                let log = run.smoother.as_mut().unwrap();
                log.forward.closes = None;
                log.bias.push(run.pass.ekf.bias());
            }
            // Stop off the step's grid (the last step is closed at the end), at a
            // recorded epoch after the last close on it: 2996 = 7 · 428.
            for _ in 0..sc.truth.len() - 4 {
                run.step(&sc);
            }
            run.finish(&sc).smoothed.unwrap()
        };
        let (kept, rebuilt) = (record(true), record(false));
        assert!(kept.srmse.is_finite() && !kept.nees.is_empty());
        let sigma = &kept.history.as_ref().unwrap().sigma;
        assert!(sigma.len() > 400, "{} recorded epochs", sigma.len());
        assert!(sigma.iter().flatten().all(|s| s.is_finite()));
        assert_eq!(format!("{kept:?}"), format!("{rebuilt:?}"));
    }
}

/// What a run's metrics keep of the smoothed solution is the whole smoothed
/// solution's, bit for bit: the velocity and position at every epoch (corrected
/// alone there) and, where the whole solution is read, the solution and bias, with
/// σ at the recorded epochs (both formulations, 15 and 19 states, every sample and a
/// 0.1 s covariance step, where most recorded epochs lie inside a step: σ there
/// between the closes on either side).
#[test]
fn the_reduced_solution_is_the_smoothed_one() {
    let sc = short_scenario(30.0);
    let spec = StrategySpec::Constant { q: TRUE_Q };
    let cases = [Formulation::Classic, Formulation::Invariant]
        .into_iter()
        .flat_map(|f| [None, Some(CalibrationConfig::default())].map(|c| (f, c)))
        .flat_map(|(f, c)| [0.0, 0.1].map(|step| (f, c, step)));
    for (formulation, calibration, step) in cases {
        let cfg = FilterConfig {
            covariance_step: step,
            formulation,
            dvl_calibration: calibration,
            ..tuned_filter()
        };
        let mut run = Run::new(&sc, &cfg, &spec, 3, 1, 25, None).unwrap();
        run.keep_for_smoother(&sc);
        if step > 0.0 {
            // The whole smoother reads the bias estimates at every epoch: log them
            // (the closes rebuilt, as kept_closes_smooth_as_the_rebuilt_ones has
            // them equal to the kept ones), the first's too.
            let log = run.smoother.as_mut().unwrap();
            log.forward.closes = None;
            log.bias.push(run.pass.ekf.bias());
        }
        for _ in 0..sc.truth.len() - 7 {
            run.step(&sc);
        }
        let log = run.finished_log().unwrap();
        let forward = log.forward(&sc.truth);
        let (nodes, cancel) = (&log.forward.nodes.0, &Cancel::default());
        let recorded = |k: usize| k.is_multiple_of(25);
        let covariances = Covariances::Where(&recorded);
        // The forward σ the run's history kept (every 25th epoch), NaN elsewhere.
        let history = &run.history.as_ref().unwrap().sigma;
        let sigma: Vec<_> = (0..log.nav.len())
            .map(|k| match recorded(k) {
                true => history[k / 25],
                false => [f64::NAN; 15],
            })
            .collect();
        let with_sigma = Forward {
            sigma: &sigma,
            ..log.forward(&sc.truth)
        };
        let whole = smooth(&with_sigma, &cfg, nodes, covariances, cancel).unwrap();
        let mut reduced = Reduced::new(&log, &sc.truth, (history, 25));
        smooth_into(
            &forward,
            &cfg,
            nodes,
            None,
            covariances,
            &mut reduced,
            cancel,
        )
        .unwrap();
        assert!(!log.whole.is_empty() && reduced.solutions.len() == log.whole.len());
        for k in 1..log.nav.len() {
            let nav = &whole.nav[k];
            let terms = reduced.terms[k].unwrap_or_else(|| {
                // The last epoch, left as the forward pass gave it.
                assert!(k == log.nav.len() - 1 && *nav == log.nav[k]);
                reduced.terms_of(k, &nav.lla, &nav.vel)
            });
            assert_eq!(terms, reduced.terms_of(k, &nav.lla, &nav.vel), "epoch {k}");
        }
        for (k, nav, bias) in &reduced.solutions {
            assert_eq!((nav, bias), (&whole.nav[*k], &whole.bias[*k]), "epoch {k}");
        }
        let sigma: Vec<_> = (0..log.nav.len()).filter(|k| recorded(*k)).collect();
        assert!(sigma
            .iter()
            .all(|k| reduced.sigma.contains(&(*k, whole.sigma[*k]))));
    }
}

/// At every sample, where no σ is wanted inside an interval, the backward pass takes
/// the mean through the Bryson–Frazier form (no covariance re-predicted inside the
/// interval) from the covariance before each update that the run kept: that kept
/// covariance is the one the re-predicting pass rebuilds, bit for bit, at every node;
/// the smoothed solution is the re-predicting pass's up to rounding (within 1e-11 of
/// the correction the smoother makes, per block: a noise taken one sample late is
/// ~6e-9 off), the same bits at the nodes, and not the same bits inside (the other
/// path did run); with σ wanted at some epochs (those intervals re-predict, the
/// others do not) the σ there is the re-predicting pass's, bit for bit.
fn assert_bryson_frazier_is_re_predicted(
    sc: &crate::scenario::Scenario,
    formulation: Formulation,
    spec: StrategySpec,
) {
    use crate::mechanization::NavState;
    use crate::smoother::closes;
    let cfg = FilterConfig {
        formulation,
        covariance_step: 0.0,
        ..tuned_filter()
    };
    let mut run = Run::new(sc, &cfg, &spec, 3, 1, 0, None).unwrap();
    run.keep_for_smoother(sc);
    for _ in 0..sc.truth.len() - 7 {
        run.step(sc);
    }
    assert!(run.failure.is_none(), "{:?}", run.failure);
    let log = run.finished_log().unwrap();
    let forward = log.forward(&sc.truth);
    let nodes = &log.forward.nodes.0;
    let cancel = &Cancel::default();
    assert!(nodes.len() > 20, "{} nodes", nodes.len());
    for pair in nodes.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let prior = b
            .p_prior
            .as_ref()
            .unwrap_or_else(|| panic!("no prior at {}", b.epoch));
        let vel_b = cfg.coordinates().at(&log.nav[b.epoch]);
        let (mut rebuilt, every) = (Vec::new(), |_| true);
        let at = (a, b.epoch);
        closes::samples::<15>(&forward, &cfg, at, (0, vel_b), &every, &mut rebuilt, cancel)
            .unwrap();
        let p_end = rebuilt.last().and_then(|c| c.p_prior).unwrap();
        assert_eq!(p_end, **prior, "the prior kept at epoch {}", b.epoch);
    }
    let nowhere = |_: usize| false;
    let bf = smooth(&forward, &cfg, nodes, Covariances::Where(&nowhere), cancel).unwrap();
    let mut plain = nodes.clone();
    for n in plain.iter_mut() {
        n.p_prior = None;
    }
    let re = smooth(&forward, &cfg, &plain, Covariances::Where(&nowhere), cancel).unwrap();
    // Per block: the largest gap between the two, and the largest correction.
    let blocks = |x: &NavState, y: &NavState| {
        let lla = x.lla - y.lla;
        [
            lla.xy().norm() * 6.4e6 + lla.z.abs(),
            (x.vel - y.vel).norm(),
            (x.dcm - y.dcm).norm(),
        ]
    };
    let bias = |a: &[f64; 6], b: &[f64; 6], i: usize| {
        (0..3)
            .map(|j| (a[i + j] - b[i + j]).abs())
            .fold(0.0, f64::max)
    };
    let (mut gap, mut moved, mut differ) = ([0.0f64; 5], [0.0f64; 5], 0);
    for k in 0..log.nav.len() {
        let (x, y) = (&bf.nav[k], &re.nav[k]);
        if nodes.iter().any(|n| n.epoch == k) {
            assert_eq!((x, bf.bias[k]), (y, re.bias[k]), "node epoch {k}");
            continue;
        }
        differ += usize::from(x != y);
        let (g, m) = (blocks(x, y), blocks(y, &log.nav[k]));
        for i in 0..3 {
            gap[i] = gap[i].max(g[i]);
            moved[i] = moved[i].max(m[i]);
        }
        for (i, at) in [(3, 0), (4, 3)] {
            gap[i] = gap[i].max(bias(&bf.bias[k], &re.bias[k], at));
            moved[i] = moved[i].max(bias(&re.bias[k], &forward.bias[k], at));
        }
    }
    assert!(differ > 0, "the Bryson–Frazier path did not run");
    for i in 0..5 {
        assert!(
            moved[i] > 0.0 && gap[i] <= 1e-11 * moved[i],
            "{formulation:?} {spec:?} block {i}: {gap:?} {moved:?}"
        );
    }
    let some = |k: usize| k % 997 == 5;
    let mixed = smooth(&forward, &cfg, nodes, Covariances::Where(&some), cancel).unwrap();
    let old = smooth(&forward, &cfg, &plain, Covariances::Where(&some), cancel).unwrap();
    for k in (0..log.nav.len()).filter(|&k| some(k) || nodes.iter().any(|n| n.epoch == k)) {
        let bits = |s: &[f64; 15]| s.map(f64::to_bits);
        assert_eq!(bits(&mixed.sigma[k]), bits(&old.sigma[k]), "σ at epoch {k}");
    }
}

/// Both formulations; a constant q and Mehra's discrete Q̂.
#[test]
fn the_bryson_frazier_mean_is_the_re_predicted_one() {
    let sc = short_scenario(30.0);
    let mehra = StrategySpec::Mehra {
        window: 5,
        prior_q: TRUE_Q,
    };
    assert_bryson_frazier_is_re_predicted(
        &sc,
        Formulation::Classic,
        StrategySpec::Constant { q: TRUE_Q },
    );
    assert_bryson_frazier_is_re_predicted(
        &sc,
        Formulation::Invariant,
        StrategySpec::Constant { q: TRUE_Q },
    );
    assert_bryson_frazier_is_re_predicted(&sc, Formulation::Invariant, mehra);
}

/// With the nodes a schedule's noise changes make (the oracle over a three-row q
/// schedule), depth readings and fixes (their own updates, kept priors and all), DVL
/// dropouts and a 7 s outage (intervals of hundreds of samples).
#[test]
fn the_bryson_frazier_mean_is_the_re_predicted_one_with_aiding_and_a_schedule() {
    use crate::sensors::{DepthModel, DvlDropout, FixModel, VarianceSchedule};
    let mut sc = (*short_scenario(60.0)).clone();
    sc.sensors.depth = Some(DepthModel {
        sigma: 0.1,
        period: 9.1,
        lever_arm: nalgebra::Vector3::zeros(),
    });
    sc.sensors.fixes = vec![FixModel {
        sigma: [2.0, 2.0, f64::NAN],
        period: 7.0,
        times: vec![],
        max_depth: None,
        lever_arm: nalgebra::Vector3::zeros(),
    }];
    sc.sensors.dvl.dropout = Some(DvlDropout {
        mean_interval: 5.0,
        mean_length: 3.0,
    });
    sc.sensors.dvl.outages = vec![[20.0, 27.0]];
    let q0 = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
    let q1 = [3e-4, 2e-4, 1e-4, 2e-6, 1e-6, 3e-6];
    sc.sensors.imu.variance =
        VarianceSchedule::new(vec![0.0, 13.333, 41.05], vec![q0, q1, q0]).unwrap();
    let mehra = StrategySpec::Mehra {
        window: 5,
        prior_q: TRUE_Q,
    };
    assert_bryson_frazier_is_re_predicted(&sc, Formulation::Classic, StrategySpec::Oracle);
    assert_bryson_frazier_is_re_predicted(&sc, Formulation::Invariant, StrategySpec::Oracle);
    assert_bryson_frazier_is_re_predicted(&sc, Formulation::Invariant, mehra);
}
