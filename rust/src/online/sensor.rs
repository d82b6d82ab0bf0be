//! A sensor a navigator is fed readings of: its kind, noise, lever arm and gate, as a
//! recorded [`Stream`] holds them, without rows. Each reading fed is checked as a
//! stream's row is ([`Stream::validate`]) and becomes the same [`Reading`].

use crate::error::{Error, Result};
use crate::measurement::Reading;
use crate::recorded::{velocity_variance, PerRow, Stream, Values};

/// One sensor of a navigator: a stream's settings (its σ one for every reading).
#[derive(Clone, Debug)]
pub struct Sensor {
    template: Stream<'static>,
}

impl Sensor {
    /// The sensor `stream` describes; its rows, if any, are not read. A σ given per row
    /// has no meaning for readings still to come: an error naming `{name}_sigma`.
    pub fn of(stream: &Stream<'_>) -> Result<Self> {
        let name = &stream.name;
        let per_row = Error::invalid(
            format!("{name}_sigma"),
            "a navigator's sensor has one σ for its readings (each reading may give its own)",
        );
        let values = match stream.values {
            Values::Velocity {
                variance,
                frame,
                gate,
                ..
            } => Values::Velocity {
                rows: &[],
                variance: PerRow::One(one(variance).ok_or(per_row)?),
                frame,
                gate,
            },
            Values::Depth { sigma, .. } => Values::Depth {
                rows: &[],
                sigma: PerRow::One(one(sigma).ok_or(per_row)?),
            },
            Values::Fix { sigma, .. } => Values::Fix {
                rows: &[],
                sigma: PerRow::One(one(sigma).ok_or(per_row)?),
            },
            Values::Heading { sigma, .. } => Values::Heading {
                rows: &[],
                sigma: PerRow::One(one(sigma).ok_or(per_row)?),
            },
        };
        let template = Stream {
            name: name.clone(),
            time: &[],
            values,
            lever_arm: stream.lever_arm,
        };
        template.validate()?;
        Ok(Self { template })
    }

    /// Whether the sensor can feed a filter of configuration `cfg`
    /// ([`Stream::check_config`]).
    pub fn check_config(&self, cfg: &crate::ekf::FilterConfig) -> Result<()> {
        self.template.check_config(cfg)
    }

    /// The sensor's name in messages.
    pub fn name(&self) -> &str {
        &self.template.name
    }

    /// The kind of its readings: `"velocity"`, `"depth"`, `"fix"` or `"heading"`.
    pub fn kind(&self) -> &'static str {
        match self.template.values {
            Values::Velocity { .. } => "velocity",
            Values::Depth { .. } => "depth",
            Values::Fix { .. } => "fix",
            Values::Heading { .. } => "heading",
        }
    }

    /// Whether its readings are velocities.
    pub fn is_velocity(&self) -> bool {
        self.template.is_velocity()
    }

    /// The number of values one reading holds: 3 for a velocity \[m/s\] or a fix
    /// `[φ (rad), λ (rad), h (m, NaN: horizontal only)]`, 1 for a depth \[m\] or a
    /// heading \[rad\]; its σ as many (a velocity's and a fix's per axis).
    pub fn width(&self) -> usize {
        match self.template.values {
            Values::Velocity { .. } | Values::Fix { .. } => 3,
            Values::Depth { .. } | Values::Heading { .. } => 1,
        }
    }

    /// The stream as the batch pass takes it, with `time` and `values` as its rows
    /// (the sensor's σ for each): what [`crate::recorded::filter_recorded`] would be
    /// given. `values` holds [`Sensor::width`] numbers per row.
    pub fn with_rows<'a>(&self, time: &'a [f64], values: &'a [f64]) -> Result<Stream<'a>> {
        self.shape(values, time.len())?;
        // A stream of rows of 3 is read from the flat values in place.
        let values = match self.template.values {
            Values::Velocity {
                variance,
                frame,
                gate,
                ..
            } => Values::Velocity {
                rows: as_rows3(values),
                variance,
                frame,
                gate,
            },
            Values::Depth { sigma, .. } => Values::Depth {
                rows: values,
                sigma,
            },
            Values::Fix { sigma, .. } => Values::Fix {
                rows: as_rows3(values),
                sigma,
            },
            Values::Heading { sigma, .. } => Values::Heading {
                rows: values,
                sigma,
            },
        };
        Ok(Stream {
            name: self.template.name.clone(),
            time,
            values,
            lever_arm: self.template.lever_arm,
        })
    }

    /// The reading of `value` ([`Sensor::width`] numbers) at `time` \[s\], with its own
    /// 1σ `sigma` (as many numbers; None: the sensor's), checked as a stream's row.
    pub fn reading(&self, time: f64, value: &[f64], sigma: Option<&[f64]>) -> Result<Reading> {
        let width = self.width();
        self.shape(value, 1)?;
        if let Some(s) = sigma {
            if s.len() != width {
                return Err(Error::invalid(
                    format!("{}_sigma", self.name()),
                    format!("a reading's σ holds {width} numbers, got {}", s.len()),
                ));
            }
        }
        let times = [time];
        let mut stream = self.with_rows(&times, value)?;
        let name = self.name();
        stream.values = match (stream.values, sigma) {
            (values, None) => values,
            (
                Values::Velocity {
                    rows, frame, gate, ..
                },
                Some(s),
            ) => Values::Velocity {
                rows,
                variance: PerRow::One(velocity_variance(name, &[[s[0], s[1], s[2]]])?[0]),
                frame,
                gate,
            },
            (Values::Depth { rows, .. }, Some(s)) => Values::Depth {
                rows,
                sigma: PerRow::One(s[0]),
            },
            (Values::Fix { rows, .. }, Some(s)) => Values::Fix {
                rows,
                sigma: PerRow::One([s[0], s[1], s[2]]),
            },
            (Values::Heading { rows, .. }, Some(s)) => Values::Heading {
                rows,
                sigma: PerRow::One(s[0]),
            },
        };
        if !time.is_finite() {
            return Err(Error::invalid(
                format!("{name}_time"),
                format!("must be finite, got {time}"),
            ));
        }
        stream.validate()?;
        Ok(stream.reading(0))
    }

    /// `values` holds `rows` readings of [`Sensor::width`] numbers.
    fn shape(&self, values: &[f64], rows: usize) -> Result<()> {
        let width = self.width();
        if values.len() == width * rows {
            return Ok(());
        }
        Err(Error::invalid(
            self.name(),
            format!(
                "{rows} reading(s) of {width} number(s) each hold {} numbers, got {}",
                width * rows,
                values.len()
            ),
        ))
    }
}

/// The one value of a [`PerRow`], None when given per row.
fn one<T: Copy>(v: PerRow<'_, T>) -> Option<T> {
    match v {
        PerRow::One(v) => Some(v),
        PerRow::Each(_) => None,
    }
}

/// Flat values as rows of 3 (its length a multiple of 3, checked by the caller).
fn as_rows3(values: &[f64]) -> &[[f64; 3]] {
    let (rows, rest) = values.as_chunks::<3>();
    debug_assert!(rest.is_empty());
    rows
}
