//! Unit tests of the EKF: Jacobians against finite differences, the gate, the
//! divergence watch, covariance health, and the DVL calibration states.

use super::calibration::SCALE;
use super::dynamics::ErrorDynamics;
use super::*;
use crate::attitude::{dcm_from_euler, exp_so3};
use crate::earth;
use crate::error::Result;
use crate::measurement::Velocity;
use crate::mechanization::{step_with_rates, FrameRates, ImuSample, NavState};
use crate::noise::{NoiseStrategy, StrategySpec};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

pub(crate) fn moving_state() -> NavState {
    NavState {
        lla: Vector3::new(0.55, 0.6, -10.0),
        vel: Vector3::new(1.0, 0.5, 0.1),
        dcm: dcm_from_euler(0.05, -0.1, 0.8),
    }
}

/// A DVL reading `z` as the filter's configuration describes the DVL.
pub(crate) fn dvl(ekf: &Ekf, z: Vector3<f64>) -> Velocity {
    let cfg = ekf.config();
    Velocity {
        z,
        variance: cfg.dvl_variance,
        lever_arm: cfg.lever_arm,
        frame: cfg.aiding,
        gate: cfg.innovation_gate,
    }
}

/// The predicted DVL reading and its Jacobian over the 15 states (before the
/// calibration states).
fn measurement_model(ekf: &Ekf) -> (Vector3<f64>, Rows3) {
    dvl(ekf, Vector3::zeros()).model(ekf)
}

/// A DVL reading of exactly what the filter predicts (the calibration states' too): a
/// zero innovation.
pub(crate) fn dvl_at_estimate(ekf: &Ekf) -> Velocity {
    let (predicted, _) = measurement_model(ekf);
    let z = match &ekf.calibration {
        Some(c) => c.estimate.reading(&predicted),
        None => predicted,
    };
    dvl(ekf, z)
}

/// The DVL update with `z`, its report.
fn update(ekf: &mut Ekf, z: &Vector3<f64>) -> Result<UpdateInfo> {
    let m = dvl(ekf, *z);
    let applied = ekf.apply(&m)?;
    Ok(applied
        .report
        .unwrap_or_else(|| unreachable!("a velocity reports")))
}

/// One IMU sample and an optional DVL reading at its end; the strategy sees the update
/// when it is accepted.
fn step(
    ekf: &mut Ekf,
    raw: &ImuSample,
    dt: f64,
    strategy: &mut dyn NoiseStrategy,
    z: Option<&Vector3<f64>>,
    steps_since_update: usize,
) -> Result<Option<UpdateInfo>> {
    ekf.propagate(raw, dt, strategy.process_noise())?;
    let Some(z) = z else {
        return Ok(None);
    };
    let info = update(ekf, z)?;
    if info.accepted {
        strategy.after_update(&info, steps_since_update);
    }
    Ok(Some(info))
}

/// Column `j` of `h` equals the finite difference `numeric` to 1e-5.
fn assert_column<const N: usize>(numeric: &Vector3<f64>, h: &SMatrix<f64, 3, N>, j: usize) {
    for i in 0..3 {
        assert!(
            (numeric[i] - h[(i, j)]).abs() < 1e-5,
            "H[{i},{j}] = {} vs numeric {}",
            h[(i, j)],
            numeric[i]
        );
    }
}

/// Numerical Jacobian of the measurement (body and NED aiding, both formulations)
/// with respect to the error state agrees with H: feedback and H speak of the same
/// coordinates.
#[test]
fn measurement_jacobian_matches_finite_differences() {
    for formulation in [
        Formulation::Classic,
        Formulation::Invariant,
        Formulation::Se23,
    ] {
        for aiding in [Aiding::Body, Aiding::Nav] {
            measurement_jacobian_case(formulation, aiding);
        }
    }
}

fn measurement_jacobian_case(formulation: Formulation, aiding: Aiding) {
    let cfg = FilterConfig {
        lever_arm: Vector3::new(0.5, -0.3, 1.2),
        aiding,
        formulation,
        ..FilterConfig::default()
    };
    let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
    ekf.last_gyro = Vector3::new(0.01, -0.02, 0.05);
    let (h0, h) = measurement_model(&ekf);
    let eps = 1e-6;
    for j in 0..15 {
        let mut e = ekf.clone();
        let mut dx = Vector15::zeros();
        dx[j] = eps;
        // feedback applies −δx: the state moves to "truth" = estimate − δx, so
        // h(estimate) − h(estimate − δx) ≈ H δx.
        e.feedback(&dx);
        e.last_gyro = ekf.last_gyro
            + if j >= GYRO_BIAS {
                Vector3::from_fn(|i, _| if i == j - GYRO_BIAS { eps } else { 0.0 })
            } else {
                Vector3::zeros()
            };
        let (h1, _) = measurement_model(&e);
        assert_column(&((h0 - h1) / eps), &h, j);
    }
}

/// The error of `est` against `truth` in the coordinates `at` (biases given): in
/// SE₂(3) the exact `δP = p̂ − Ĉ Cᵀ p` about the anchor.
fn error_in(at: &Coordinates, est: &NavState, truth: &NavState, bias_error: &[f64; 6]) -> Vector15 {
    let formulation = at.formulation;
    let psi = -crate::attitude::log_so3(&(est.dcm * truth.dcm.transpose()));
    let dv = est.vel - truth.vel;
    let dv = match formulation {
        Formulation::Classic => dv,
        _ => dv - est.vel.cross(&psi),
    };
    let dp = match formulation {
        Formulation::Se23 => {
            let rotation = est.dcm * truth.dcm.transpose();
            at.displacement(&est.lla) - rotation * at.displacement(&truth.lla)
        }
        _ => earth::position_error_ned(&est.lla, &truth.lla),
    };
    let mut x = Vector15::zeros();
    x.fixed_rows_mut::<3>(POS).copy_from(&dp);
    x.fixed_rows_mut::<3>(VEL).copy_from(&dv);
    x.fixed_rows_mut::<3>(ATT).copy_from(&psi);
    for i in 0..6 {
        x[ACC_BIAS + i] = bias_error[i];
    }
    x
}

/// Each column of F, in every formulation, against the strapdown step itself: an
/// estimate one small error away from the truth, both stepped with the same raw IMU
/// sample (the estimate correcting it by its biases), moves its error by `F δx Δt`.
/// SE₂(3)'s anchor lies about 4 km away, so that its `[p̂×]` terms are large.
#[test]
fn error_dynamics_match_the_mechanization() {
    for formulation in [
        Formulation::Classic,
        Formulation::Invariant,
        Formulation::Se23,
    ] {
        let truth = NavState {
            vel: Vector3::new(1.5, -0.8, 0.2),
            ..moving_state()
        };
        let raw = ImuSample {
            accel: Vector3::new(0.3, -0.2, -9.7),
            gyro: Vector3::new(0.02, -0.01, 0.05),
        };
        let dt = 1e-4;
        let scale = [1e-1, 1e-3, 1e-3, 1e-4, 1e-6];
        let rates = FrameRates::at(&truth);
        let cfg = FilterConfig {
            formulation,
            anchor: Some(truth.lla + Vector3::new(-5e-4, 4e-4, 30.0)),
            ..FilterConfig::default()
        };
        let at = cfg.coordinates();
        for j in 0..15 {
            let mut dx = Vector15::zeros();
            dx[j] = scale[j / 3];
            // The estimate is the truth plus δx (feedback of −δx).
            let mut ekf = Ekf::new(&cfg, truth, Vector3::zeros(), Vector3::zeros()).unwrap();
            ekf.feedback(&(-dx));
            let bias_error: [f64; 6] = std::array::from_fn(|i| dx[ACC_BIAS + i]);
            let start = error_in(&at, &ekf.nav, &truth, &bias_error);
            // δx up to its second order (the feedback rotates by exp, the velocity
            // map is taken at the estimate before and after it).
            let close = 1e-3 * scale[j / 3] + 5.0 * scale[j / 3].powi(2);
            assert!((start - dx).abs().max() < close, "{formulation:?} {j}");
            let imu = ImuSample {
                accel: raw.accel - ekf.accel_bias,
                gyro: raw.gyro - ekf.gyro_bias,
            };
            let dynamics = ErrorDynamics::new(
                &ekf.nav,
                &FrameRates::at(&ekf.nav),
                &imu.accel,
                &ekf.point(),
            );
            let est1 = step_with_rates(&ekf.nav, &imu, dt, &FrameRates::at(&ekf.nav));
            let truth1 = step_with_rates(&truth, &raw, dt, &rates);
            let end = error_in(&at, &est1, &truth1, &bias_error);
            let rate = (end - start) / dt;
            let f = dynamics.apply(start.as_slice());
            for i in 0..9 {
                // F is the rate at the start of the step: the step's own drift is
                // O(g Δt) times the error.
                // Positions are read from latitude and longitude, whose last bit is
                // ~1e-9 m: ~1e-5 m/s over one step.
                let resolution = if i < VEL { 2e-5 } else { 0.0 };
                // And the linearization's own error: second order, g δx².
                let (e, second) = (scale[j / 3], 20.0 * scale[j / 3].powi(2));
                let tol = 1e-2 * f[i].abs() + 20.0 * dt * e + second + resolution;
                assert!(
                    (rate[i] - f[i]).abs() <= tol,
                    "{formulation:?}: d(error {i})/dt from a step of error {j}: {} vs F {}",
                    rate[i],
                    f[i]
                );
            }
        }
    }
}

/// One update from the same prior in either formulation: the same NIS, the same
/// corrected state and, mapped to the classic coordinates at the prior's velocity, the
/// same posterior covariance (an exact change of coordinates).
#[test]
fn one_update_is_the_same_in_either_formulation() {
    let cfg = |formulation| FilterConfig {
        lever_arm: Vector3::new(0.5, -0.3, 1.2),
        formulation,
        ..FilterConfig::default()
    };
    let mut classic = Ekf::new(
        &cfg(Formulation::Classic),
        moving_state(),
        Vector3::zeros(),
        Vector3::zeros(),
    )
    .unwrap();
    classic.last_gyro = Vector3::new(0.01, -0.02, 0.05);
    let a = Matrix15::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 1e-3);
    classic.p += a * a.transpose();
    let mut invariant = classic.clone();
    invariant.cfg.formulation = Formulation::Invariant;
    Point::velocity(Formulation::Invariant, &classic.nav.vel).from_classic(&mut invariant.p);
    let (prior_vel, prior_dcm) = (classic.nav.vel, classic.nav.dcm);
    let z = Vector3::new(1.2, 0.3, 0.05);
    let (c, i) = (
        update(&mut classic, &z).unwrap(),
        update(&mut invariant, &z).unwrap(),
    );
    assert!(
        (c.nis - i.nis).abs() < 1e-10 * c.nis,
        "{} vs {}",
        c.nis,
        i.nis
    );
    assert!(
        (c.gain - i.gain).abs().max() < 1e-12,
        "the reported gain is classic"
    );
    // The same correction (ψ̂, δv̂ = δV̂ + [v̂×]ψ̂); the invariant velocity takes it
    // exactly, v̂ ← Exp(ψ̂)(v̂ − δV̂), the classic one to first order.
    let psi = crate::attitude::log_so3(&(classic.nav.dcm * prior_dcm.transpose()));
    let dv = prior_vel - classic.nav.vel;
    let exact = exp_so3(&psi) * (prior_vel - (dv - prior_vel.cross(&psi)));
    assert!((exact - invariant.nav.vel).abs().max() < 1e-13);
    let second_order = psi.norm() * (dv.norm() + psi.norm() * prior_vel.norm());
    assert!((classic.nav.vel - invariant.nav.vel).norm() <= second_order);
    assert!(psi.norm() > 1e-4, "the update corrects the attitude: {psi}");
    assert!((classic.nav.dcm - invariant.nav.dcm).abs().max() < 1e-13);
    assert!((classic.nav.lla - invariant.nav.lla).abs().max() < 1e-13);
    let mut back = invariant.p;
    Point::velocity(Formulation::Invariant, &prior_vel).to_classic(&mut back);
    assert!((back - classic.p).abs().max() < 1e-12 * classic.p.abs().max());
}

fn calibrated() -> FilterConfig {
    FilterConfig {
        lever_arm: Vector3::new(0.5, -0.3, 1.2),
        dvl_calibration: Some(calibration::CalibrationConfig::default()),
        ..FilterConfig::default()
    }
}

/// With the DVL error states (the correlated error too), the 22 columns of H agree
/// with finite differences of the predicted reading, away from the ideal mounting.
#[test]
fn calibrated_measurement_jacobian_matches_finite_differences() {
    let mut cfg = calibrated();
    if let Some(c) = cfg.dvl_calibration.as_mut() {
        c.bias_sigma = [0.01, 0.02, 0.005];
    }
    let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
    ekf.last_gyro = Vector3::new(0.01, -0.02, 0.05);
    ekf.calibration.as_mut().unwrap().estimate =
        DvlMounting::from_angles(0.004, [0.01, -0.02, 0.03]);
    let predict = |e: &Ekf| {
        let (v_b, h_body) = measurement_model(e);
        e.calibration.as_ref().unwrap().measurement(&v_b, &h_body)
    };
    let (z0, h) = predict(&ekf);
    let eps = 1e-6;
    for j in 0..calibration::N_CALIBRATED {
        let mut e = ekf.clone();
        let mut dx = SVector::<f64, { calibration::N_CALIBRATED }>::zeros();
        dx[j] = eps;
        e.feedback(&dx.fixed_rows::<15>(0).into_owned());
        let c = e.calibration.as_mut().unwrap();
        c.feedback(&std::array::from_fn(|k| dx[SCALE + k]));
        if (GYRO_BIAS..GYRO_BIAS + 3).contains(&j) {
            e.last_gyro[j - GYRO_BIAS] += eps;
        }
        let (z1, _) = predict(&e);
        assert_column(&((z0 - z1) / eps), &h, j);
    }
}

/// Calibration states with a zero prior and no walk change nothing: the 19-state
/// filter follows the 15-state one, and its cross-covariance stays zero.
#[test]
fn calibration_states_with_a_zero_prior_leave_the_filter_unchanged() {
    let mut cfg = calibrated();
    cfg.dvl_calibration = Some(calibration::CalibrationConfig {
        scale_sigma: 0.0,
        misalignment_sigma: [0.0; 3],
        ..calibration::CalibrationConfig::default()
    });
    let plain_cfg = FilterConfig {
        dvl_calibration: None,
        ..cfg.clone()
    };
    let mut a = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
    let mut b = Ekf::new(
        &plain_cfg,
        moving_state(),
        Vector3::zeros(),
        Vector3::zeros(),
    )
    .unwrap();
    let q = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
    let mut sa = StrategySpec::Constant { q }.build(cfg.bias_psd());
    let mut sb = StrategySpec::Constant { q }.build(cfg.bias_psd());
    let sample = ImuSample::from_array(&[0.1, 0.02, -9.79, 0.001, -0.002, 0.01]);
    for k in 1..=500 {
        let z = (k % 100 == 0).then(|| Vector3::new(1.0, 0.1, 0.05));
        let ia = step(&mut a, &sample, 0.01, sa.as_mut(), z.as_ref(), 100).unwrap();
        let ib = step(&mut b, &sample, 0.01, sb.as_mut(), z.as_ref(), 100).unwrap();
        if let (Some(ia), Some(ib)) = (ia, ib) {
            assert!((ia.nis - ib.nis).abs() <= 1e-12 * ib.nis.abs().max(1.0));
        }
    }
    assert!((a.p - b.p).abs().max() <= 1e-12 * b.p.abs().max());
    assert!((a.nav.vel - b.nav.vel).abs().max() <= 1e-12);
    let c = a.calibration.as_ref().unwrap();
    assert_eq!((c.cross.abs().max(), c.estimate.scale), (0.0, 0.0));
}

#[test]
fn calibrated_covariance_stays_symmetric_positive_definite() {
    let mut cfg = calibrated();
    if let Some(c) = cfg.dvl_calibration.as_mut() {
        c.bias_sigma = [0.01, 0.02, 0.005]; // every DVL error state uncertain
    }
    let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
    let mut strat = StrategySpec::Constant {
        q: [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6],
    }
    .build(cfg.bias_psd());
    let sample = ImuSample::from_array(&[0.0, 0.0, -9.79, 0.0, 0.0, 0.01]);
    let prior = ekf.calibration.as_ref().unwrap().sigma();
    for k in 1..=3000 {
        let z = (k % 100 == 0).then(|| Vector3::new(1.0, 0.0, 0.0));
        step(&mut ekf, &sample, 0.01, strat.as_mut(), z.as_ref(), 100).unwrap();
    }
    let c = ekf.calibration.as_ref().unwrap();
    let full = c.assemble(&ekf.p);
    assert_eq!(full, full.transpose());
    let eig = full.symmetric_eigenvalues();
    assert!(eig.min() > 0.0, "min eigenvalue {}", eig.min());
    // Constants without a walk: the updates never make them less certain.
    assert!((0..4).all(|i| c.sigma()[i] <= prior[i]), "{:?}", c.sigma());
    let nav = FilterConfig {
        aiding: Aiding::Nav,
        ..calibrated()
    };
    assert!(nav
        .validate()
        .unwrap_err()
        .to_string()
        .contains("body-frame aiding"));
}

/// Covariance stays symmetric and positive definite through propagation and updates.
/// A body-frame DVL reading of the filter's own prediction plus `sigmas` standard
/// deviations of its innovation on the first axis.
fn reading(ekf: &Ekf, sigmas: f64) -> Vector3<f64> {
    let (predicted, h) = measurement_model(ekf);
    let s = h * ekf.p * h.transpose()
        + Matrix3::from_diagonal(&Vector3::from_column_slice(&ekf.cfg.dvl_variance));
    predicted + Vector3::new(sigmas * s[(0, 0)].sqrt(), 0.0, 0.0)
}

#[test]
fn innovation_gate_rejects_a_ten_sigma_reading_and_leaves_the_state_alone() {
    let cfg = FilterConfig {
        innovation_gate: Some(16.27),
        ..FilterConfig::default()
    };
    let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
    let before = ekf.clone();
    let z = reading(&ekf, 10.0);
    let info = update(&mut ekf, &z).unwrap();
    assert!(!info.accepted);
    // (S⁻¹)₀₀ ≥ 1/S₀₀ for an SPD S, so the NIS of a 10σ first-axis innovation is ≥ 100.
    assert!(
        info.nis >= 100.0 - 1e-9,
        "NIS of a 10σ innovation: {}",
        info.nis
    );
    assert_eq!((ekf.nav, ekf.p), (before.nav, before.p));
    // 3σ is inside the gate (NIS 9 < 16.27): applied.
    let z = reading(&ekf, 3.0);
    let info = update(&mut ekf, &z).unwrap();
    assert!(info.accepted);
    assert_ne!(ekf.p, before.p);
    // Without a gate the 10σ reading is applied.
    let mut ungated = before.clone();
    ungated.cfg.innovation_gate = None;
    let z = reading(&ungated, 10.0);
    assert!(update(&mut ungated, &z).unwrap().accepted);
    assert_ne!(ungated.nav.vel, before.nav.vel);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let cfg = FilterConfig {
            innovation_gate: Some(bad),
            ..FilterConfig::default()
        };
        assert!(cfg.validate().is_err(), "gate {bad} accepted");
    }
}

#[test]
fn covariance_stays_symmetric_positive_definite() {
    let cfg = FilterConfig::default();
    let mut ekf = Ekf::new(&cfg, moving_state(), Vector3::zeros(), Vector3::zeros()).unwrap();
    let mut strat = StrategySpec::Constant {
        q: [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6],
    }
    .build(cfg.bias_psd());
    let sample = ImuSample::from_array(&[0.0, 0.0, -9.79, 0.0, 0.0, 0.0]);
    for k in 1..=2000 {
        let z = (k % 100 == 0).then(|| Vector3::new(1.0, 0.0, 0.0));
        step(&mut ekf, &sample, 0.01, strat.as_mut(), z.as_ref(), 100).unwrap();
        assert_eq!(ekf.p, ekf.p.transpose());
    }
    let eig = ekf.p.symmetric_eigenvalues();
    assert!(eig.min() > 0.0, "min eigenvalue {}", eig.min());
}

/// A position reading at a lever arm from the same prior in the invariant formulation
/// and in SE₂(3) (anchor ~2 km away): a fix's north component has the same innovation
/// and variance; one depth reading gives the same NIS and the same posterior covariance
/// mapped to the classic coordinates at the prior, and states that differ at second
/// order. (A fix's east component is linearized after the north one's feedback, where
/// the two differ at first order in `|Δp̂| σ_ψ`: each keeps P about its own point.)
#[test]
fn one_position_reading_is_the_same_in_se23() {
    use crate::measurement::{Depth, Fix};
    let cfg = |formulation| FilterConfig {
        formulation,
        anchor: Some(moving_state().lla + Vector3::new(3e-4, -2e-4, 5.0)),
        ..FilterConfig::default()
    };
    let prior = moving_state();
    let mut invariant = Ekf::new(
        &cfg(Formulation::Invariant),
        prior,
        Vector3::zeros(),
        Vector3::zeros(),
    )
    .unwrap();
    let a = Matrix15::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 1e-3);
    invariant.p += a * a.transpose();
    invariant.p[(ATT + 2, ATT + 2)] += 0.01; // an uncertain heading
    let mut se23 = invariant.clone();
    se23.cfg = cfg(Formulation::Se23);
    let (at_inv, at_se23) = (invariant.point(), se23.point());
    assert!(at_se23.disp.norm() > 1000.0, "{}", at_se23.disp);
    let mut classic = invariant.p;
    at_inv.to_classic(&mut classic);
    se23.p = classic;
    at_se23.from_classic(&mut se23.p);
    let fix = Fix {
        lla: [prior.lla[0] + 2e-7, prior.lla[1] - 1e-7, f64::NAN],
        sigma: [1.0, 1.0, 1.0],
        lever_arm: Vector3::new(0.4, 0.0, -1.5),
    };
    let variance = |e: &Ekf| {
        let Linearized::Scalar { innovation, row, r } = fix.linearize(0, e) else {
            unreachable!("a fix is read component by component")
        };
        let mut h = Row15::zeros();
        match row {
            ScalarRow::Row(row) => h = row,
            ScalarRow::Unit(k) => h[k] = 1.0,
        }
        (innovation, (h * e.p * h.transpose())[(0, 0)] + r)
    };
    // In SE₂(3) the reading is in the anchor's metres (k of them per metre here, the
    // anchor over a km away): the innovation k times; its variance k² times to the
    // order |p̂|/R of the map from the classic covariance (which takes the estimate's
    // metres for the anchor's), and so the NIS.
    let ((nu_i, s_i), (nu_s, s_s)) = (variance(&invariant), variance(&se23));
    let k = nu_s / nu_i;
    let order = at_se23.disp.norm() / 6.4e6;
    assert!(
        (k - 1.0).abs() > 1e-6 && (k - 1.0).abs() < 10.0 * order,
        "{k}"
    );
    assert!(
        (s_s - k * k * s_i).abs() < 10.0 * order * s_s,
        "{s_i} vs {s_s}"
    );
    let (nis_i, nis_s) = (nu_i * nu_i / s_i, nu_s * nu_s / s_s);
    assert!(
        (nis_s - nis_i).abs() < 10.0 * order * nis_i,
        "{nis_i} vs {nis_s}"
    );
    let depth = Depth {
        z: -prior.lla[2] + 0.3,
        sigma: 0.1,
        lever_arm: Vector3::new(0.4, 0.2, -1.5),
    };
    let (i, s) = (
        invariant.apply(&depth).unwrap(),
        se23.apply(&depth).unwrap(),
    );
    assert!(
        (i.nis - s.nis).abs() < 1e-9 * i.nis,
        "{} vs {}",
        i.nis,
        s.nis
    );
    let (mut pi, mut ps) = (invariant.p, se23.p);
    at_inv.to_classic(&mut pi);
    at_se23.to_classic(&mut ps);
    let gap = (pi - ps).abs().max() / pi.abs().max();
    assert!(gap < 1e-9, "{gap}");
    let psi = crate::attitude::log_so3(&(se23.nav.dcm * prior.dcm.transpose()));
    assert!(psi.norm() > 1e-6, "the depth corrects the attitude: {psi}");
    assert!((invariant.nav.dcm - se23.nav.dcm).abs().max() < 1e-12);
    let moved = earth::position_error_ned(&se23.nav.lla, &invariant.nav.lla).norm();
    assert!(
        moved <= 2.0 * psi.norm().powi(2) * at_se23.disp.norm() + 1e-9,
        "{moved}"
    );
}
