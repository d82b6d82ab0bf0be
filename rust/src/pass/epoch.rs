//! The epoch loop: one IMU sample and the readings due at its end.

use crate::ekf::calibration::{DvlErrors, N_DVL};
use crate::ekf::{Applied, Ekf, Matrix15, ProcessNoise, Transition, Vector15};
use crate::error::Error;
use crate::measurement::Reading;
use crate::mechanization::ImuSample;
use crate::noise::NoiseStrategy;

/// One step of a pass: the raw IMU sample `raw` of `dt` seconds that ends at the epoch
/// `index` (1 for the first sample; epoch 0 is the initial state) at time `t` \[s\].
pub struct Epoch<'a> {
    pub index: usize,
    pub raw: &'a ImuSample,
    pub dt: f64,
    pub t: f64,
    /// The pass's last epoch: its covariance is brought up to date before its
    /// updates, whatever the covariance step.
    pub last: bool,
}

/// The error estimates fed back at an epoch: the 15 states' (in the filter's
/// coordinates) and the DVL calibration states' `[δk̂, δμ̂]` (zero without them).
pub type Fed = (Vector15, DvlErrors);

/// What an epoch's updates left, for an [`Observer`]: the sum fed back and, where an
/// observer asked for it ([`Observer::wants_prior`]), the covariance before them (the
/// first observer that takes it has it).
pub struct Updated {
    pub fed: Fed,
    pub prior: Option<Box<Matrix15>>,
}

/// What a driver keeps of a pass, told each thing as it happens. Every method has a
/// default that keeps nothing; a pair `(A, B)` tells both, in order.
pub trait Observer {
    /// Before the IMU step that leaves the epoch `at.index − 1`, with the noise the
    /// step is propagated with.
    fn before_step(&mut self, _at: &Epoch<'_>, _ekf: &Ekf, _noise: ProcessNoise<'_>) {}

    /// A covariance step closed at the epoch `epoch`, before any update there: `ekf.p`
    /// is the covariance it left, `phi` its transition.
    fn on_close(&mut self, _epoch: usize, _ekf: &Ekf, _phi: &Transition) {}

    /// Whether [`Updated::prior`] is wanted (a copy of P at each epoch with updates).
    fn wants_prior(&self) -> bool {
        false
    }

    /// The `i`-th reading of the epoch was applied (or rejected by its gate): what it
    /// did (an observer may take its report), the filter after it and the noise
    /// strategy after it saw it.
    fn on_reading(
        &mut self,
        _at: &Epoch<'_>,
        _i: usize,
        _reading: &Reading,
        _applied: &mut Applied,
        _ekf: &Ekf,
        _strategy: &dyn NoiseStrategy,
    ) {
    }

    /// After the epoch's updates (`updated`: None where no reading was applied), with
    /// the noise in force for the next step.
    fn after_epoch(
        &mut self,
        _at: &Epoch<'_>,
        _ekf: &Ekf,
        _updated: Option<&mut Updated>,
        _noise: ProcessNoise<'_>,
    ) {
    }
}

/// Keeps nothing.
impl Observer for () {}

impl<A: Observer, B: Observer> Observer for (A, B) {
    fn before_step(&mut self, at: &Epoch<'_>, ekf: &Ekf, noise: ProcessNoise<'_>) {
        self.0.before_step(at, ekf, noise);
        self.1.before_step(at, ekf, noise);
    }

    fn on_close(&mut self, epoch: usize, ekf: &Ekf, phi: &Transition) {
        self.0.on_close(epoch, ekf, phi);
        self.1.on_close(epoch, ekf, phi);
    }

    fn wants_prior(&self) -> bool {
        self.0.wants_prior() || self.1.wants_prior()
    }

    fn on_reading(
        &mut self,
        at: &Epoch<'_>,
        i: usize,
        reading: &Reading,
        applied: &mut Applied,
        ekf: &Ekf,
        strategy: &dyn NoiseStrategy,
    ) {
        self.0.on_reading(at, i, reading, applied, ekf, strategy);
        self.1.on_reading(at, i, reading, applied, ekf, strategy);
    }

    fn after_epoch(
        &mut self,
        at: &Epoch<'_>,
        ekf: &Ekf,
        mut updated: Option<&mut Updated>,
        noise: ProcessNoise<'_>,
    ) {
        self.0.after_epoch(at, ekf, updated.as_deref_mut(), noise);
        self.1.after_epoch(at, ekf, updated, noise);
    }
}

impl<O: Observer> Observer for Option<O> {
    fn before_step(&mut self, at: &Epoch<'_>, ekf: &Ekf, noise: ProcessNoise<'_>) {
        if let Some(o) = self {
            o.before_step(at, ekf, noise);
        }
    }

    fn on_close(&mut self, epoch: usize, ekf: &Ekf, phi: &Transition) {
        if let Some(o) = self {
            o.on_close(epoch, ekf, phi);
        }
    }

    fn wants_prior(&self) -> bool {
        self.as_ref().is_some_and(O::wants_prior)
    }

    fn on_reading(
        &mut self,
        at: &Epoch<'_>,
        i: usize,
        reading: &Reading,
        applied: &mut Applied,
        ekf: &Ekf,
        strategy: &dyn NoiseStrategy,
    ) {
        if let Some(o) = self {
            o.on_reading(at, i, reading, applied, ekf, strategy);
        }
    }

    fn after_epoch(
        &mut self,
        at: &Epoch<'_>,
        ekf: &Ekf,
        updated: Option<&mut Updated>,
        noise: ProcessNoise<'_>,
    ) {
        if let Some(o) = self {
            o.after_epoch(at, ekf, updated, noise);
        }
    }
}

impl<O: Observer + ?Sized> Observer for &mut O {
    fn before_step(&mut self, at: &Epoch<'_>, ekf: &Ekf, noise: ProcessNoise<'_>) {
        (**self).before_step(at, ekf, noise);
    }

    fn on_close(&mut self, epoch: usize, ekf: &Ekf, phi: &Transition) {
        (**self).on_close(epoch, ekf, phi);
    }

    fn wants_prior(&self) -> bool {
        (**self).wants_prior()
    }

    fn on_reading(
        &mut self,
        at: &Epoch<'_>,
        i: usize,
        reading: &Reading,
        applied: &mut Applied,
        ekf: &Ekf,
        strategy: &dyn NoiseStrategy,
    ) {
        (**self).on_reading(at, i, reading, applied, ekf, strategy);
    }

    fn after_epoch(
        &mut self,
        at: &Epoch<'_>,
        ekf: &Ekf,
        updated: Option<&mut Updated>,
        noise: ProcessNoise<'_>,
    ) {
        (**self).after_epoch(at, ekf, updated, noise);
    }
}

/// Where an epoch failed: in its prediction (`reading` None) or in the update of its
/// `reading`-th reading.
#[derive(Debug)]
pub struct Failure {
    pub reading: Option<usize>,
    pub error: Error,
}

/// A filter pass under way: the filter, and the IMU steps since its last accepted
/// velocity update (what Mehra's Q̂ is spread over).
#[derive(Clone, Debug)]
pub struct Pass {
    pub ekf: Ekf,
    steps_since_update: usize,
}

impl Pass {
    pub fn new(ekf: Ekf) -> Self {
        Self {
            ekf,
            steps_since_update: 0,
        }
    }

    /// One epoch: the IMU step `at` propagated with the strategy's noise, the
    /// covariance brought up to date where a reading is due (or at the last epoch),
    /// then each of `readings` applied in order. The strategy sees every accepted
    /// velocity update, with the IMU steps since the last. `observer` is told each
    /// thing as it happens. An error leaves the epoch where it stopped.
    pub fn epoch(
        &mut self,
        strategy: &mut dyn NoiseStrategy,
        at: &Epoch<'_>,
        readings: &[Reading],
        observer: &mut impl Observer,
    ) -> Result<(), Failure> {
        let failed = |reading: Option<usize>| move |error| Failure { reading, error };
        observer.before_step(at, &self.ekf, strategy.process_noise());
        let noise = strategy.process_noise();
        self.ekf
            .propagate_observed(at.raw, at.dt, noise, |ekf, phi| {
                observer.on_close(at.index, ekf, phi)
            })
            .map_err(failed(None))?;
        self.steps_since_update += 1;
        if at.last || !readings.is_empty() {
            self.close(at.index, observer);
        }
        let prior = (!readings.is_empty() && observer.wants_prior()).then(|| Box::new(self.ekf.p));
        // The velocity readings' estimates and the others' are summed apart, then
        // added.
        let (mut velocity, mut other): (Option<Fed>, Option<Fed>) = (None, None);
        for (i, reading) in readings.iter().enumerate() {
            let mut applied = reading.apply(&mut self.ekf).map_err(failed(Some(i)))?;
            if let Some(info) = applied.report.as_ref().filter(|info| info.accepted) {
                strategy.after_update(info, self.steps_since_update);
                self.steps_since_update = 0;
            }
            let sum = match reading {
                Reading::Velocity(_) => &mut velocity,
                _ => &mut other,
            };
            let (nav, cal) = sum.get_or_insert((Vector15::zeros(), [0.0; N_DVL]));
            if let Some((dx, dc)) = &applied.correction {
                *nav += dx;
                for (c, d) in cal.iter_mut().zip(dc) {
                    *c += d;
                }
            }
            observer.on_reading(at, i, reading, &mut applied, &self.ekf, strategy);
        }
        let fed = match (velocity, other) {
            (Some((a, ca)), Some((b, cb))) => Some((a + b, std::array::from_fn(|i| ca[i] + cb[i]))),
            (a, b) => a.or(b),
        };
        let mut updated = fed.map(|fed| Updated { fed, prior });
        observer.after_epoch(at, &self.ekf, updated.as_mut(), strategy.process_noise());
        Ok(())
    }

    /// Bring the covariance up to date at the epoch `epoch` (the end of a pass), telling
    /// `observer` of the close.
    pub fn close(&mut self, epoch: usize, observer: &mut impl Observer) {
        if let Some(phi) = self.ekf.bring_up_to_date() {
            observer.on_close(epoch, &self.ekf, &phi);
        }
    }
}
