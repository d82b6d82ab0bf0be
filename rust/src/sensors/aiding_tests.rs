//! Tests of [`super`]: the aiding sensors' schedules, noise, lever arms and streams.

use super::*;
use crate::sensors::SensorConfig;
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

/// The paper's sensors with the aiding sensors `depth` and `fixes`.
fn aiding(depth: Option<&DepthModel>, fixes: &[FixModel]) -> SensorConfig {
    SensorConfig {
        depth: depth.copied(),
        fixes: fixes.to_vec(),
        ..SensorConfig::paper()
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
    draw_all(&aiding(depth, fix), truth, at_depth, run)
}

/// Every reading of the aiding sensors of `sensors` along `truth`'s epochs, its
/// states at a depth of `at_depth` \[m\].
fn draw_all(
    sensors: &SensorConfig,
    truth: &Truth,
    at_depth: f64,
    run: u64,
) -> Vec<(usize, Reading)> {
    let mut sim = AidingSim::new(sensors.aiding(), truth, 11, run)
        .unwrap()
        .unwrap();
    let mut state = truth.states[0];
    state.lla[2] = -at_depth;
    let mut out = Vec::new();
    let mut all = Vec::new();
    for k in 1..=truth.len() {
        out.clear();
        sim.readings(sensors.aiding(), k, &state, &mut out);
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
            Reading::Fix(m) => f.push(earth::position_error_ned(&Vector3::from(m.lla), &state.lla)),
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
    let err = AidingSim::new(aiding(None, &[periodic, odd]).aiding(), &truth, 0, 0)
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
        assert!(err(late).starts_with("fixes[1]: schedules no fix inside the trajectory's 330 s"),);
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
    assert!(AidingSim::new(aiding(None, &[]).aiding(), &truth, 0, 0)
        .unwrap()
        .is_none());
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

#[test]
fn a_heading_sensor_reads_the_yaw_with_its_noise_and_leaves_the_other_draws() {
    let truth = builtin("paper", 0.01).unwrap().generate().unwrap();
    let depth = DepthModel {
        sigma: 0.2,
        period: 0.01,
        lever_arm: Vector3::zeros(),
    };
    let plain = aiding(Some(&depth), &[]);
    let compass = HeadingModel {
        sigma: 0.01,
        period: 0.05,
    };
    let with = SensorConfig {
        heading: Some(compass),
        ..plain.clone()
    };
    let (a, b) = (
        draw_all(&plain, &truth, 10.0, 3),
        draw_all(&with, &truth, 10.0, 3),
    );
    let is_depth = |r: &&(usize, Reading)| matches!(r.1, Reading::Depth(..));
    assert_eq!(a, b.iter().filter(is_depth).copied().collect::<Vec<_>>());
    // Every 5th epoch, after the depth; the yaw of the (stationary) state plus σ noise,
    // wrapped into (−π, π].
    let c = truth.states[0].dcm;
    let yaw = c[(1, 0)].atan2(c[(0, 0)]);
    let mut e = Vec::new();
    for (i, (k, r)) in b.iter().enumerate() {
        if let Reading::Heading(h) = r {
            assert!(k % 5 == 0 && matches!(b[i - 1], (j, Reading::Depth(..)) if j == *k));
            assert!(h.sigma == 0.01 && h.y.abs() <= std::f64::consts::PI);
            e.push(wrap_angle(h.y - yaw));
        }
    }
    assert_eq!(e.len(), truth.len() / 5);
    let n = e.len() as f64;
    let sd = (e.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    assert!((sd / 0.01 - 1.0).abs() < 0.03, "{sd}");
    assert!((e.iter().sum::<f64>() / n).abs() < 4.0 * 0.01 / n.sqrt());
    for (bad, arg) in [
        (
            HeadingModel {
                sigma: 5.0,
                ..compass
            },
            "heading_sigma",
        ),
        (
            HeadingModel {
                sigma: 0.0,
                ..compass
            },
            "heading_sigma",
        ),
        (
            HeadingModel {
                period: f64::NAN,
                ..compass
            },
            "heading_period",
        ),
    ] {
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.starts_with(&format!("{arg}: ")), "{e}");
    }
    let odd = SensorConfig {
        heading: Some(HeadingModel {
            period: 0.015,
            ..compass
        }),
        ..plain
    };
    let e = AidingSim::new(odd.aiding(), &truth, 0, 0)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.starts_with("heading_period: must be a whole multiple"),
        "{e}"
    );
}
