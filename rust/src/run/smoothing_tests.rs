//! Tests of the smoother over a simulated run (`super`): kept closes against rebuilt
//! ones, and the metrics' reduced solution against the whole smoothed one.

use super::{smooth_into, Cancel, Covariances, Formulation, Forward, Reduced, Sink};
use crate::ekf::calibration::CalibrationConfig;
use crate::ekf::smoother::smooth;
use crate::ekf::smoother::Smoothed;
use crate::ekf::FilterConfig;
use crate::ekf::Matrix15;
use crate::montecarlo::tests::{short_scenario, tuned_filter, TRUE_Q};
use crate::noise::StrategySpec;
use crate::run::Run;
use nalgebra::SMatrix;

/// The closes of the covariance step that a run keeps are the ones the backward
/// pass would rebuild: the smoothed record from either is the same, bit for bit
/// (15 and 19 states, σ recorded every 25 epochs).
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
            let mut run = Run::new(&sc, &cfg, &spec, 3, 1, 25, None).unwrap();
            run.keep_for_smoother(&sc);
            if !kept {
                // Rebuilt: the bias estimates at every epoch, the first's too.
                let log = run.smoother.as_mut().unwrap();
                log.closes = None;
                log.bias.push(super::bias_array(&run.ekf));
            }
            // Stop off the step's grid: the last step is closed at the end.
            for _ in 0..sc.truth.len() - 7 {
                run.step(&sc);
            }
            run.finish(&sc).smoothed.unwrap()
        };
        let (kept, rebuilt) = (record(true), record(false));
        assert!(kept.srmse.is_finite() && !kept.nees.is_empty());
        assert_eq!(format!("{kept:?}"), format!("{rebuilt:?}"));
    }
}

/// σ a fraction of the way between the covariances `from` and `to` at a few
/// epochs: the same from the whole smoothed solution and from a run's metrics.
fn between_alike<const N: usize>(
    whole: &mut Smoothed,
    reduced: &mut Reduced<'_>,
    (from, to): (&SMatrix<f64, N, N>, &SMatrix<f64, N, N>),
    cfg: &FilterConfig,
    forward: &Forward<'_>,
) {
    for (k, w) in [(13, 0.3), (101, 0.7)] {
        let (before, pr) = (whole.sigma[k], reduced.sigma.len());
        whole.set_sigma_between(k, (from, to, w), cfg, forward);
        reduced.set_sigma_between(k, (from, to, w), cfg, forward);
        assert_ne!(whole.sigma[k], before, "epoch {k}");
        assert_eq!(reduced.sigma[pr..], [(k, whole.sigma[k])], "epoch {k}");
    }
}

/// What a run's metrics keep of the smoothed solution is the whole smoothed
/// solution's, bit for bit: the velocity and position at every epoch (corrected
/// alone there) and, where the whole solution is read, the solution and bias, with
/// σ at the recorded epochs (both formulations, 15 and 19 states, every sample).
#[test]
fn the_reduced_solution_is_the_smoothed_one() {
    let sc = short_scenario(30.0);
    let spec = StrategySpec::Constant { q: TRUE_Q };
    for formulation in [Formulation::Classic, Formulation::Invariant] {
        for calibration in [None, Some(CalibrationConfig::default())] {
            let cfg = FilterConfig {
                covariance_step: 0.0,
                formulation,
                dvl_calibration: calibration,
                ..tuned_filter()
            };
            let mut run = Run::new(&sc, &cfg, &spec, 3, 1, 25, None).unwrap();
            run.keep_for_smoother(&sc);
            for _ in 0..sc.truth.len() - 7 {
                run.step(&sc);
            }
            let log = run.finished_log().unwrap();
            let forward = log.forward(&sc.truth);
            let (nodes, cancel) = (&log.nodes.0, &Cancel::default());
            let recorded = |k: usize| k.is_multiple_of(25);
            let covariances = Covariances::Where(&recorded);
            let whole = smooth(&forward, &cfg, nodes, covariances, cancel).unwrap();
            let mut reduced = Reduced::new(&log, &sc.truth);
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
            // σ inside a covariance step (a fraction of the way between the
            // covariances at two closes) is taken alike by both sinks.
            let (from, to) = (&whole.node_covariance[1].1, &whole.node_covariance[2].1);
            let mut whole = whole.clone();
            if calibration.is_some() {
                let pad = |p: &Matrix15| {
                    let mut q = SMatrix::<f64, 19, 19>::identity() * 1e-4;
                    q.fixed_view_mut::<15, 15>(0, 0).copy_from(p);
                    q
                };
                let (from, to) = (pad(from), pad(to));
                between_alike(&mut whole, &mut reduced, (&from, &to), &cfg, &forward);
            } else {
                between_alike(&mut whole, &mut reduced, (from, to), &cfg, &forward);
            }
        }
    }
}
