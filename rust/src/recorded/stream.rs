//! One recorded sensor stream: its rows' times and values, their noise (one for all
//! rows, or one per row), the sensor's lever arm, and the reading each row is.

use crate::earth;
use crate::ekf::{check_lever_arm, Aiding, FilterConfig};
use crate::error::{check, Error, Result};
use crate::measurement::{check_depth_sigma, Depth, Fix, Heading, Reading, Velocity};
use nalgebra::Vector3;

/// A value that is the same for every row of a stream, or given per row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PerRow<'a, T> {
    One(T),
    Each(&'a [T]),
}

impl<T: Copy> PerRow<'_, T> {
    /// The value of row `row`.
    #[inline]
    pub fn at(&self, row: usize) -> T {
        match self {
            PerRow::One(v) => *v,
            PerRow::Each(rows) => rows[row],
        }
    }
}

/// The rows of a stream, by kind of sensor, with their noise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Values<'a> {
    /// Velocities \[m/s\] in `frame`, each axis of variance `variance` \[(m/s)²\]; a NIS
    /// above `gate` (χ², 3 dof) rejects a row.
    Velocity {
        rows: &'a [[f64; 3]],
        variance: PerRow<'a, [f64; 3]>,
        frame: Aiding,
        gate: Option<f64>,
    },
    /// Depths \[m, positive down\] of 1σ `sigma` \[m\].
    Depth {
        rows: &'a [f64],
        sigma: PerRow<'a, f64>,
    },
    /// Fixes `[φ (rad), λ (rad), h (m, up; NaN: horizontal only)]` of 1σ `sigma` \[m,
    /// north, east, down\].
    Fix {
        rows: &'a [[f64; 3]],
        sigma: PerRow<'a, [f64; 3]>,
    },
    /// Headings \[rad, from true north, within ±2π\] of 1σ `sigma` \[rad\]; no lever
    /// arm (a heading is the body's, wherever its sensor sits).
    Heading {
        rows: &'a [f64],
        sigma: PerRow<'a, f64>,
    },
}

/// One sensor's recorded readings: `time` \[s\] (strictly increasing), the values, and
/// the sensor's lever arm \[m, body FRD\] from the IMU. `name` names its arrays in
/// errors (`{name}`, `{name}_time`, `{name}_sigma`).
#[derive(Clone, Debug, PartialEq)]
pub struct Stream<'a> {
    pub name: String,
    pub time: &'a [f64],
    pub values: Values<'a>,
    pub lever_arm: Vector3<f64>,
}

impl<'a> Stream<'a> {
    /// A DVL (or NED velocity, per `cfg.aiding`) stream named `dvl` with the noise,
    /// lever arm and gate of `cfg`.
    pub fn dvl(rows: &'a [[f64; 3]], time: &'a [f64], cfg: &FilterConfig) -> Self {
        Self {
            name: "dvl".into(),
            time,
            values: Values::Velocity {
                rows,
                variance: PerRow::One(cfg.dvl_variance),
                frame: cfg.aiding,
                gate: cfg.innovation_gate,
            },
            lever_arm: cfg.lever_arm,
        }
    }

    /// A depth stream named `depth`, one 1σ for every row, at the IMU.
    pub fn depth(rows: &'a [f64], time: &'a [f64], sigma: f64) -> Self {
        Self {
            name: "depth".into(),
            time,
            values: Values::Depth {
                rows,
                sigma: PerRow::One(sigma),
            },
            lever_arm: Vector3::zeros(),
        }
    }

    /// A stream of fixes named `fix`, a 1σ per row, at the IMU.
    pub fn fix(rows: &'a [[f64; 3]], time: &'a [f64], sigma: &'a [[f64; 3]]) -> Self {
        Self {
            name: "fix".into(),
            time,
            values: Values::Fix {
                rows,
                sigma: PerRow::Each(sigma),
            },
            lever_arm: Vector3::zeros(),
        }
    }

    /// The number of rows.
    pub fn len(&self) -> usize {
        self.time.len()
    }

    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }

    /// Whether its readings are velocities (what the noise strategies see).
    pub fn is_velocity(&self) -> bool {
        matches!(self.values, Values::Velocity { .. })
    }

    /// The reading of row `row`.
    pub fn reading(&self, row: usize) -> Reading {
        let lever_arm = self.lever_arm;
        match self.values {
            Values::Velocity {
                rows,
                variance,
                frame,
                gate,
            } => Reading::Velocity(Velocity {
                z: Vector3::from(rows[row]),
                variance: variance.at(row),
                lever_arm,
                frame,
                gate,
            }),
            Values::Depth { rows, sigma } => Reading::Depth(Depth {
                z: rows[row],
                sigma: sigma.at(row),
                lever_arm,
            }),
            Values::Fix { rows, sigma } => Reading::Fix(Fix {
                lla: rows[row],
                sigma: sigma.at(row),
                lever_arm,
            }),
            Values::Heading { rows, sigma } => Reading::Heading(Heading {
                y: rows[row],
                sigma: sigma.at(row),
            }),
        }
    }

    /// Whether the stream can feed a filter of configuration `cfg`: the DVL
    /// calibration states read body-frame velocities, so a NED velocity stream is
    /// refused beside them (named by the stream's `name`).
    pub fn check_config(&self, cfg: &FilterConfig) -> Result<()> {
        if let Values::Velocity {
            frame: Aiding::Nav, ..
        } = self.values
        {
            if cfg.dvl_calibration.is_some() {
                return Err(Error::invalid(
                    &self.name,
                    "a NED velocity stream beside the DVL calibration states \
                     (FilterConfig(dvl_calibration=True)), which need body-frame DVL \
                     readings: give body-frame velocities, or a filter without the states",
                ));
            }
        }
        Ok(())
    }

    /// Lengths, times, values, noise, gate and lever arm (finite), each error naming
    /// the array (`lever_arm`, `{name}_gate`).
    pub fn validate(&self) -> Result<()> {
        let name = &self.name;
        // Each array as long as the times, the σ rows as the values.
        let same = |time: usize, values: usize| {
            if time == values {
                return Ok(());
            }
            Err(Error::invalid(
                format!("{name}_time"),
                format!("has {time} rows but {name} has {values}"),
            ))
        };
        let sigma_rows = |rows: usize, sigma: usize| {
            if rows == sigma {
                return Ok(());
            }
            Err(Error::invalid(
                format!("{name}_sigma"),
                format!("has {sigma} rows but {name} has {rows}"),
            ))
        };
        check_lever_arm(&format!("{name}_lever_arm"), self.lever_arm.as_slice())?;
        match self.values {
            Values::Velocity {
                rows,
                variance,
                gate,
                ..
            } => {
                if let Some(gate) = gate {
                    check::positive(&format!("{name}_gate"), gate)?;
                }
                same(self.len(), rows.len())?;
                for (i, row) in rows.iter().enumerate() {
                    check::finite(name, row).map_err(|_| {
                        Error::invalid(name, format!("row {i} is not finite: {row:?}"))
                    })?;
                }
                if let PerRow::Each(v) = variance {
                    sigma_rows(rows.len(), v.len())?;
                }
                let bad = |v: &[f64; 3]| !v.iter().all(|x| *x > 0.0 && x.is_finite());
                let all: &[[f64; 3]] = match &variance {
                    PerRow::One(v) => std::slice::from_ref(v),
                    PerRow::Each(v) => v,
                };
                if let Some(i) = all.iter().position(bad) {
                    return Err(Error::invalid(
                        format!("{name}_sigma"),
                        format!(
                            "row {i} must hold 3 finite variances > 0 [(m/s)²], got {:?}",
                            all[i]
                        ),
                    ));
                }
            }
            Values::Depth { rows, sigma } => {
                same(self.len(), rows.len())?;
                check::finite(name, rows)?;
                match sigma {
                    PerRow::One(s) => check_depth_sigma(s)?,
                    PerRow::Each(s) => {
                        sigma_rows(rows.len(), s.len())?;
                        for (i, s) in s.iter().enumerate() {
                            check_depth_sigma(*s).map_err(|e| row_error(e, i))?;
                        }
                    }
                }
            }
            Values::Fix { rows, sigma } => {
                same(self.len(), rows.len())?;
                if let PerRow::Each(s) = sigma {
                    sigma_rows(rows.len(), s.len())?;
                }
                for (i, fix) in rows.iter().enumerate() {
                    check_fix(name, i, fix, &sigma.at(i))?;
                }
            }
            Values::Heading { rows, sigma } => {
                same(self.len(), rows.len())?;
                if let PerRow::Each(s) = sigma {
                    sigma_rows(rows.len(), s.len())?;
                }
                check_heading(self, rows, sigma)?;
            }
        }
        check::increasing(&format!("{name}_time"), self.time)
    }
}

/// The variances \[(m/s)²\] of a velocity stream's 1σ rows `sigma` \[m/s\] (one row for
/// all, or one per row): each σ finite and > 0 with a square finite and > 0, or an
/// error naming `{name}_sigma` and the row.
pub fn velocity_variance(name: &str, sigma: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
    let square = |s: &[f64; 3]| s.map(|x| x * x);
    let good = |s: &[f64; 3]| {
        let v = square(s);
        (0..3).all(|j| s[j] > 0.0 && s[j].is_finite() && v[j] > 0.0 && v[j].is_finite())
    };
    if let Some(i) = sigma.iter().position(|s| !good(s)) {
        return Err(Error::invalid(
            format!("{name}_sigma"),
            format!(
                "row {i} must hold 3 finite 1σ > 0 [m/s] whose squares (the variances) \
                 are finite and > 0, got {:?}",
                sigma[i]
            ),
        ));
    }
    Ok(sigma.iter().map(square).collect())
}

/// An error about row `i` of an array: the row named after the array's name.
fn row_error(e: Error, i: usize) -> Error {
    match e {
        Error::InvalidArgument { arg, reason } => Error::invalid(arg, format!("row {i}: {reason}")),
        other => other,
    }
}

/// A heading stream's rows (finite, within ±2π: degrees are refused), 1σ (finite,
/// > 0 and at most π \[rad\]) and lever arm (none).
fn check_heading(stream: &Stream<'_>, rows: &[f64], sigma: PerRow<'_, f64>) -> Result<()> {
    let name = &stream.name;
    let turn = 2.0 * std::f64::consts::PI;
    if let Some(i) = rows.iter().position(|y| y.is_nan() || y.abs() > turn) {
        let hint = if rows[i].is_nan() { "" } else { " (degrees?)" };
        return Err(Error::invalid(
            name,
            format!(
                "row {i} must be a heading in radians within ±2π, got {}{hint}",
                rows[i]
            ),
        ));
    }
    let bad = |s: &f64| s.is_nan() || *s <= 0.0 || *s > std::f64::consts::PI;
    let (which, value) = match sigma {
        PerRow::One(s) => (bad(&s).then_some(String::new()), s),
        PerRow::Each(s) => match s.iter().position(bad) {
            Some(i) => (Some(format!("row {i} ")), s[i]),
            None => (None, 0.0),
        },
    };
    if let Some(which) = which {
        return Err(Error::invalid(
            format!("{name}_sigma"),
            format!(
                "{which}must be a 1σ > 0 and at most π [rad], got {value}{}",
                if value > std::f64::consts::PI {
                    " (degrees?)"
                } else {
                    ""
                }
            ),
        ));
    }
    if stream.lever_arm != Vector3::zeros() {
        return Err(Error::invalid(
            format!("{name}_lever_arm"),
            "a heading is the body's own, wherever its sensor sits: give no lever arm",
        ));
    }
    Ok(())
}

/// Fix row `i` of the stream `name`: a finite latitude within the filter's range, a
/// longitude within [−π, 2π], a finite or NaN height, and its 1σ.
fn check_fix(name: &str, i: usize, fix: &[f64; 3], sigma: &[f64; 3]) -> Result<()> {
    let vertical = !fix[2].is_nan();
    if !fix[0].is_finite() || !fix[1].is_finite() || fix[2].is_infinite() {
        return Err(Error::invalid(
            name,
            format!(
                "row {i} must hold a finite latitude and longitude [rad] and a finite \
                 or NaN height [m], got {fix:?}"
            ),
        ));
    }
    earth::check_latitude(name, fix[0]).map_err(|e| row_error(e, i))?;
    earth::check_longitude(name, fix[1]).map_err(|e| row_error(e, i))?;
    let wanted = if vertical { 3 } else { 2 };
    if !sigma[..wanted].iter().all(|s| *s > 0.0 && s.is_finite()) {
        let axes = if vertical {
            "north, east, down"
        } else {
            "north, east"
        };
        return Err(Error::invalid(
            format!("{name}_sigma"),
            format!("row {i} must hold {wanted} finite 1σ > 0 [m] ({axes}), got {sigma:?}"),
        ));
    }
    Ok(())
}
