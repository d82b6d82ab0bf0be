//! Tests of [`super`]: the navigator against the batch pass over the same data, in time
//! order, with late readings and beyond its lag window.

use super::{Fate, Lag, Navigator, Sensor, Start, Tuning};
use crate::ekf::calibration::CalibrationConfig;
use crate::ekf::tests::moving_state;
use crate::ekf::{Aiding, FilterConfig};
use crate::error::Error;
use crate::noise::StrategySpec;
use crate::pass::{Bound, Extent};
use crate::recorded::solution_of;
use crate::recorded::{filter_recorded, FilterOutput, PerRow, RecordedData, Stream, Values};

/// A deterministic uniform draw in [−1, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// A 30 s recording at 100 Hz: the IMU, then each sensor's times and flat values.
struct Mission {
    imu: Vec<[f64; 6]>,
    imu_time: Vec<f64>,
    streams: Vec<(Vec<f64>, Vec<f64>)>,
}

fn mission() -> Mission {
    let mut r = Lcg(7);
    let n = 3000;
    let imu_time: Vec<f64> = (1..=n).map(|k| k as f64 * 0.01).collect();
    let imu = (0..n)
        .map(|_| {
            [
                0.01 + 0.02 * r.next(),
                0.02 * r.next(),
                -9.79 + 0.02 * r.next(),
                1e-4 * r.next(),
                1e-4 + 1e-4 * r.next(),
                1e-4 * r.next(),
            ]
        })
        .collect();
    let start = moving_state();
    // Readings at their own rates, stamped off the IMU's grid.
    let times = |period: f64, offset: f64| -> Vec<f64> {
        (0..)
            .map(|i| offset + i as f64 * period)
            .take_while(|t| *t < 30.0)
            .collect()
    };
    let dvl_t = times(0.2, 0.013);
    let dvl = dvl_t
        .iter()
        .flat_map(|_| {
            let v = start.dcm.transpose() * start.vel;
            [v[0] + 0.02 * r.next(), v[1] + 0.02 * r.next(), v[2]]
        })
        .collect();
    let depth_t = times(0.5, 0.2567);
    let depth = depth_t.iter().map(|_| 10.0 + 0.05 * r.next()).collect();
    let fix_t = times(1.0, 0.5);
    let fix = fix_t
        .iter()
        .flat_map(|_| [start.lla[0] + 1e-7 * r.next(), start.lla[1], f64::NAN])
        .collect();
    let heading_t = times(1.0, 0.0049);
    let heading = heading_t.iter().map(|_| 0.8 + 0.01 * r.next()).collect();
    Mission {
        imu,
        imu_time,
        streams: vec![
            (dvl_t, dvl),
            (depth_t, depth),
            (fix_t, fix),
            (heading_t, heading),
        ],
    }
}

/// The sensors of [`mission`], in order: a DVL as `cfg` has it, a depth, fixes, a heading.
fn sensors(cfg: &FilterConfig) -> Vec<Sensor> {
    let templates = [
        Stream::dvl(&[], &[], cfg),
        Stream::depth(&[], &[], 0.05),
        Stream {
            name: "fix".into(),
            time: &[],
            values: Values::Fix {
                rows: &[],
                sigma: PerRow::One([2.0, 2.0, 2.0]),
            },
            lever_arm: nalgebra::Vector3::new(0.5, 0.0, -1.0),
        },
        Stream {
            name: "heading".into(),
            time: &[],
            values: Values::Heading {
                rows: &[],
                sigma: PerRow::One(0.02),
            },
            lever_arm: nalgebra::Vector3::zeros(),
        },
    ];
    templates.iter().map(|s| Sensor::of(s).unwrap()).collect()
}

fn start() -> Start {
    Start {
        t0: 0.0,
        nav: moving_state(),
        bias: [0.0; 6],
    }
}

/// The batch pass over `m`, with the q schedule `q` (time, values).
fn batch(
    m: &Mission,
    cfg: &FilterConfig,
    spec: &StrategySpec,
    q: &[(f64, [f64; 6])],
) -> FilterOutput {
    let sensors = sensors(cfg);
    let streams = (sensors.iter().zip(&m.streams))
        .map(|(s, (t, v))| s.with_rows(t, v).unwrap())
        .collect();
    let (q_time, q_values): (Vec<f64>, Vec<[f64; 6]>) = q.iter().copied().unzip();
    let data = RecordedData {
        imu: &m.imu,
        imu_time: &m.imu_time,
        streams,
        q_time: &q_time,
        q_values: &q_values,
        ..RecordedData::default()
    };
    let mut strategy = spec.build(cfg.bias_psd());
    filter_recorded(&data, start().nav, [0.0; 6], cfg, strategy.as_mut()).unwrap()
}

fn navigator(
    cfg: &FilterConfig,
    spec: &StrategySpec,
    lag: Lag,
    tuning: Option<Tuning>,
) -> Navigator {
    Navigator::new(
        start(),
        cfg,
        spec.build(cfg.bias_psd()),
        sensors(cfg),
        lag,
        tuning,
    )
    .unwrap()
}

/// Every reading of `m` as `(arrival, sensor, time, values)`, arriving `delay(i)` \[s\]
/// after its stamp, in order of arrival.
fn arrivals(m: &Mission, mut delay: impl FnMut() -> f64) -> Vec<(f64, usize, f64, Vec<f64>)> {
    let mut all = Vec::new();
    for (s, (times, values)) in m.streams.iter().enumerate() {
        let width = values.len() / times.len();
        for (i, t) in times.iter().enumerate() {
            all.push((
                t + delay(),
                s,
                *t,
                values[i * width..(i + 1) * width].to_vec(),
            ));
        }
    }
    all.sort_by(|a, b| a.0.total_cmp(&b.0));
    all
}

/// Feed `m` to `nav`, each reading once the IMU has passed its arrival, those arriving
/// after the last sample at the end; `each` sees the navigator at epoch k once every
/// reading stamped up to the next sample's time has been fed (all of epoch k's, in time
/// order).
fn feed(
    nav: &mut Navigator,
    m: &Mission,
    arrivals: &[(f64, usize, f64, Vec<f64>)],
    mut each: impl FnMut(&mut Navigator, usize),
) -> Vec<Fate> {
    let mut fates = Vec::new();
    let mut next = 0;
    let mut give = |nav: &mut Navigator, until: f64, fates: &mut Vec<Fate>| {
        while next < arrivals.len() && arrivals[next].0 <= until {
            let (_, s, time, v) = &arrivals[next];
            fates.push(nav.feed_reading(*s, *time, v, None).unwrap());
            next += 1;
        }
    };
    for (k, (raw, t)) in m.imu.iter().zip(&m.imu_time).enumerate() {
        give(nav, *t, &mut fates);
        if k > 0 {
            each(nav, k);
        }
        nav.feed_imu(*t, raw).unwrap();
    }
    give(nav, f64::INFINITY, &mut fates);
    each(nav, m.imu.len());
    fates
}

fn strategies() -> Vec<StrategySpec> {
    let q = [1e-4, 1e-4, 1e-4, 1e-8, 1e-8, 1e-8];
    vec![
        StrategySpec::Constant { q },
        StrategySpec::Mehra {
            window: 10,
            prior_q: q,
        },
        StrategySpec::Adaptive {
            window: 10,
            prior_q: q,
        },
    ]
}

/// An extent as its bits (NaN equal to NaN).
fn watched(e: Extent) -> (Option<(f64, Bound)>, u64, u64) {
    (e.diverged, e.heading2.to_bits(), e.heading_over.to_bits())
}

#[test]
fn fed_in_time_order_every_epoch_is_the_batch_pass_s() {
    let m = mission();
    let every_sample = FilterConfig {
        covariance_step: 0.0,
        ..FilterConfig::default()
    };
    let calibrated = FilterConfig {
        dvl_calibration: Some(CalibrationConfig::default()),
        ..FilterConfig::default()
    };
    let ned = FilterConfig {
        aiding: Aiding::Nav,
        ..FilterConfig::default()
    };
    for cfg in [FilterConfig::default(), every_sample, calibrated, ned] {
        for spec in strategies() {
            let out = batch(&m, &cfg, &spec, &[]);
            let mut nav = navigator(&cfg, &spec, Lag::default(), None);
            let fates = feed(&mut nav, &m, &arrivals(&m, || 0.0), |nav, k| {
                let e = nav.estimate();
                assert_eq!(solution_of(&e.nav), out.solution(k), "{spec:?} epoch {k}");
                assert_eq!(e.bias, out.bias[k], "{spec:?} epoch {k}");
            });
            let e = nav.estimate();
            assert_eq!(e.sigma, *out.sigma.last().unwrap(), "{spec:?}");
            if let Some((c, c_sigma)) = e.calibration {
                assert_eq!(c, *out.calibration.last().unwrap());
                assert_eq!(c_sigma, *out.calibration_sigma.last().unwrap());
            }
            assert_eq!(e.calibration.is_some(), cfg.dvl_calibration.is_some());
            let tally = nav.tally();
            for (s, record) in out.streams.iter().enumerate() {
                let applied = record.epoch.iter().flatten().count();
                assert_eq!(
                    tally[s].accepted + tally[s].rejected,
                    applied,
                    "{spec:?} {s}"
                );
                let nis: f64 = record.nis.iter().filter(|x| x.is_finite()).sum();
                assert!((tally[s].nis_sum - nis).abs() <= 1e-9 * nis.abs(), "{s}");
            }
            // What it watched for its health: the batch pass's.
            assert_eq!(watched(nav.extent()), watched(out.extent), "{spec:?}");
            assert!(nav.extent().heading2 > 0.0);
            // Stamped after an epoch but within its half step: applied there at once.
            assert!(fates.contains(&Fate::Current) && fates.contains(&Fate::Queued));
            assert!(!fates.contains(&Fate::Late));
            assert!(tally.iter().all(|t| t.late == 0));
        }
    }
}

#[test]
fn late_readings_within_the_window_give_the_in_order_result() {
    let m = mission();
    let cfg = FilterConfig::default();
    for spec in strategies() {
        let out = batch(&m, &cfg, &spec, &[]);
        let mut r = Lcg(3);
        let late = arrivals(&m, || 0.25 + 0.25 * r.next());
        let mut nav = navigator(&cfg, &spec, Lag::default(), None);
        let fates = feed(&mut nav, &m, &late, |_, _| {});
        assert!(fates.iter().filter(|f| **f == Fate::Late).count() > 100);
        assert!(!fates.contains(&Fate::Refused));
        let e = nav.estimate();
        assert_eq!(solution_of(&e.nav), out.last_solution(), "{spec:?}");
        assert_eq!(e.bias, *out.bias.last().unwrap());
        assert_eq!(e.sigma, *out.sigma.last().unwrap());
        // The epochs run again watched from their checkpoint: what the first runs
        // without the late readings saw (a larger heading σ) is not kept.
        assert_eq!(watched(nav.extent()), watched(out.extent), "{spec:?}");
    }
}

#[test]
fn readings_beyond_the_window_are_refused_and_counted() {
    let m = mission();
    let cfg = FilterConfig::default();
    let spec = &strategies()[0];
    let mut r = Lcg(5);
    let late = arrivals(&m, || 0.25 + 0.25 * r.next());
    let lag = Lag {
        window: 0.3,
        every: 7,
    };
    let mut nav = navigator(&cfg, spec, lag, None);
    let fates = feed(&mut nav, &m, &late, |_, _| {});
    let refused = fates.iter().filter(|f| **f == Fate::Refused).count();
    assert!(refused > 10, "{refused}");
    let tally = nav.tally();
    let sum = |f: fn(&super::Tally) -> usize| tally.iter().map(f).sum::<usize>();
    assert_eq!(sum(|t| t.refused), refused);
    assert_eq!(sum(|t| t.received), late.len());
    assert_eq!(
        sum(|t| t.accepted + t.rejected + t.refused + t.skipped + t.queued),
        late.len()
    );
    // The history holds the window, not the mission.
    assert!(nav.kept_steps() <= 30 + 7 + 1, "{}", nav.kept_steps());
}

#[test]
fn q_set_at_the_tuning_instants_is_the_batch_q_schedule() {
    let m = mission();
    let cfg = FilterConfig::default();
    let prior = [1e-4, 1e-4, 1e-4, 1e-8, 1e-8, 1e-8];
    let spec = StrategySpec::External { prior_q: prior };
    let tuning = Tuning::new(0.01, 50, 0.3).unwrap();
    // A q from the window: its mean square per channel.
    let q_of = |w: &[[f64; 6]]| -> [f64; 6] {
        std::array::from_fn(|c| 1e-6 + w.iter().map(|s| s[c] * s[c]).sum::<f64>() * 1e-9)
    };
    let schedule: Vec<(f64, [f64; 6])> = (1..=m.imu.len())
        .filter(|k| tuning.due_after(*k) && *k < m.imu.len())
        .map(|k| (m.imu_time[k - 1], q_of(&m.imu[k - 50..k])))
        .collect();
    let out = batch(&m, &cfg, &spec, &schedule);
    let mut r = Lcg(9);
    let late = arrivals(&m, || 0.2 + 0.2 * r.next());
    let mut nav = navigator(&cfg, &spec, Lag::default(), Some(tuning));
    let mut set = 0;
    feed(&mut nav, &m, &late, |nav, _| {
        if nav.tuning_due() {
            let w = nav.window().unwrap();
            nav.set_q(q_of(&w)).unwrap();
            set += 1;
        }
    });
    assert_eq!(set, schedule.len() + 1); // and one after the last sample
    assert_eq!(solution_of(&nav.estimate().nav), out.last_solution());
    assert_eq!(nav.estimate().sigma, *out.sigma.last().unwrap());
}

#[test]
fn bad_input_is_refused_in_one_line() {
    let cfg = FilterConfig::default();
    let spec = &strategies()[0];
    let mut nav = navigator(&cfg, spec, Lag::default(), None);
    let arg = |e: Error| match e {
        Error::InvalidArgument { arg, .. } => arg,
        other => panic!("{other}"),
    };
    nav.feed_imu(0.01, &[0.0, 0.0, -9.8, 0.0, 0.0, 0.0])
        .unwrap();
    let e = nav.feed_imu(0.01, &[0.0; 6]).unwrap_err();
    assert_eq!(arg(e), "imu_time");
    assert_eq!(arg(nav.feed_imu(0.02, &[f64::NAN; 6]).unwrap_err()), "imu");
    let huge = [1e300, 0.0, -9.8, 0.0, 0.0, 0.0];
    assert_eq!(arg(nav.feed_imu(0.02, &huge).unwrap_err()), "imu");
    // A block with a bad row (or time) feeds none of it; the block mended feeds all.
    let times = [0.02, 0.03, 0.04];
    let mut rows = [[0.0, 0.0, -9.8, 0.0, 0.0, 0.0]; 3];
    rows[2][4] = f64::NAN;
    assert_eq!(arg(nav.feed_imu_block(&times, &rows).unwrap_err()), "imu");
    let e = nav.feed_imu_block(&[0.02, 0.02, 0.04], &rows).unwrap_err();
    assert_eq!(arg(e), "imu_time");
    assert_eq!(nav.epoch(), 1);
    rows[2][4] = 0.0;
    assert_eq!(nav.feed_imu_block(&times, &rows).unwrap(), 3);
    assert_eq!(nav.epoch(), 4);
    assert_eq!(
        arg(nav.feed_reading(0, 0.1, &[1.0], None).unwrap_err()),
        "dvl"
    );
    assert_eq!(
        arg(nav.feed_reading(9, 0.1, &[1.0], None).unwrap_err()),
        "stream"
    );
    let e = nav.feed_reading(1, 0.1, &[1.0], Some(&[-1.0])).unwrap_err();
    assert_eq!(arg(e), "depth_sigma");
    let e = nav.feed_reading(3, 0.1, &[100.0], None).unwrap_err();
    assert_eq!(arg(e), "heading");
    assert_eq!(arg(nav.set_q([1e-4; 6]).unwrap_err()), "strategy");
    // Before the first sample's half step: outside the pass, as a row would be.
    assert_eq!(
        nav.feed_reading(1, -1.0, &[1.0], None).unwrap(),
        Fate::Skipped
    );
    // A per-row σ cannot describe readings still to come.
    let sigma = [0.1, 0.2];
    let per_row = Stream {
        values: Values::Depth {
            rows: &[],
            sigma: PerRow::Each(&sigma),
        },
        ..Stream::depth(&[], &[], 0.1)
    };
    assert_eq!(arg(Sensor::of(&per_row).unwrap_err()), "depth_sigma");
    // A NED velocity stream beside the DVL calibration states, as a batch pass refuses.
    let calibrated = FilterConfig {
        dvl_calibration: Some(CalibrationConfig::default()),
        ..FilterConfig::default()
    };
    let ned = FilterConfig {
        aiding: Aiding::Nav,
        ..FilterConfig::default()
    };
    let e = Navigator::new(
        start(),
        &calibrated,
        spec.build(cfg.bias_psd()),
        sensors(&ned),
        Lag::default(),
        None,
    )
    .err()
    .unwrap();
    assert_eq!(arg(e), "dvl");
    assert_eq!(
        arg(Lag {
            window: f64::NAN,
            every: 1
        }
        .validate()
        .unwrap_err()),
        "lag"
    );
}
