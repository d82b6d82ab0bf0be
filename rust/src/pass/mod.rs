//! One filter pass, one epoch at a time: the loop every driver runs (a recorded
//! mission, a simulated run, a Monte Carlo's runs and an ensemble's).
//!
//! - `epoch`: [`Pass`] steps the filter over one IMU sample, brings the covariance up
//!   to date where readings are due, applies them in order, lets the noise strategy see
//!   the velocity updates, and tells an [`Observer`] each thing as it happens (the
//!   output a driver keeps, the smoother's log, a run's metrics);
//! - `divergence`: [`NisMonitor`], the divergence watch over the velocity updates' NIS.

mod divergence;
mod epoch;

pub use divergence::{NisMonitor, DIVERGENCE_MEAN_NIS};
pub use epoch::{Epoch, Failure, Fed, Observer, Pass, Updated};
