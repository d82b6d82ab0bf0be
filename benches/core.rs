//! Micro-benchmarks of the navigation core's inner steps: one strapdown mechanization
//! step, one EKF covariance-and-state prediction in each formulation, ten predictions at
//! a 0.1 s covariance step and one DVL update.
//!
//! Run: `cargo bench --features bench --bench core` (criterion; HTML under target/criterion). The
//! performance target for mechanization is ≥ 10 M steps/s per core, i.e. ≤ 100 ns.

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Vector3;
use pronet::attitude::dcm_from_euler;
use pronet::ekf::{Ekf, FilterConfig, Formulation, ProcessNoise};
use pronet::measurement::Velocity;
use pronet::mechanization::{step, ImuSample, NavState};
use std::hint::black_box;

const DT: f64 = 0.01;

fn moving_state() -> NavState {
    NavState {
        lla: Vector3::new(0.55, 0.6, -10.0),
        vel: Vector3::new(1.5, 0.3, 0.05),
        dcm: dcm_from_euler(0.02, -0.05, 0.8),
    }
}

fn imu() -> ImuSample {
    ImuSample {
        accel: Vector3::new(0.05, 0.01, -9.79),
        gyro: Vector3::new(1e-4, -2e-4, 0.01),
    }
}

fn ekf_in(formulation: Formulation) -> Ekf {
    let config = FilterConfig {
        formulation,
        ..FilterConfig::default()
    };
    Ekf::new(&config, moving_state(), Vector3::zeros(), Vector3::zeros())
        .expect("the default filter config is valid")
}

fn ekf() -> Ekf {
    ekf_in(Formulation::default())
}

fn benches(c: &mut Criterion) {
    let (state, sample) = (moving_state(), imu());
    c.bench_function("mechanization step", |b| {
        b.iter(|| step(black_box(&state), black_box(&sample), DT))
    });

    let q = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6];
    let bias_psd = FilterConfig::default().bias_psd();
    let noise = ProcessNoise::Continuous {
        imu_variance: &q,
        bias_psd: &bias_psd,
    };
    // One predict step in each formulation, side by side (the invariant one
    // may cost at most 1.2× the classic one; benches/run.py reports the ratio).
    for formulation in [Formulation::Classic, Formulation::Invariant] {
        let start = ekf_in(formulation);
        let name = format!(
            "ekf predict {} (covariance + strapdown)",
            formulation.name()
        );
        c.bench_function(&name, |b| {
            b.iter_batched_ref(
                || start.clone(),
                |f| f.propagate(black_box(&sample), DT, noise),
                criterion::BatchSize::SmallInput,
            )
        });
    }

    // Ten samples at a 0.1 s covariance step: nine accumulate, the tenth
    // closes the interval (Φ P Φᵀ once); against ten samples of the predict above.
    let stepped = Ekf::new(
        &FilterConfig {
            covariance_step: 0.1,
            ..FilterConfig::default()
        },
        moving_state(),
        Vector3::zeros(),
        Vector3::zeros(),
    )
    .expect("a valid config");
    c.bench_function("ekf predict x10 at a 0.1 s covariance step", |b| {
        b.iter_batched_ref(
            || stepped.clone(),
            |f| {
                for _ in 0..10 {
                    f.propagate(black_box(&sample), DT, noise)
                        .expect("a finite prediction");
                }
            },
            criterion::BatchSize::SmallInput,
        )
    });

    let mut predicted = ekf();
    for _ in 0..100 {
        predicted
            .propagate(&sample, DT, noise)
            .expect("a finite prediction");
    }
    let cfg = predicted.config();
    let dvl = Velocity {
        z: Vector3::new(1.4, 0.3, 0.1),
        variance: cfg.dvl_variance,
        lever_arm: cfg.lever_arm,
        frame: cfg.aiding,
        gate: cfg.innovation_gate,
    };
    c.bench_function("ekf dvl update (Joseph form + feedback)", |b| {
        b.iter_batched_ref(
            || predicted.clone(),
            |f| f.apply(black_box(&dvl)).expect("a consistent update"),
            criterion::BatchSize::SmallInput,
        )
    });
}

criterion_group!(core, benches);
criterion_main!(core);
