//! One filter pass, one epoch at a time: the loop every driver runs (a recorded
//! mission, a simulated run, a Monte Carlo's runs and an ensemble's).
//!
//! - `epoch`: [`Pass`] steps the filter over one IMU sample, brings the covariance up
//!   to date where readings are due, applies them in order, lets the noise strategy see
//!   the velocity updates, and tells an [`Observer`] each thing as it happens (the
//!   output a driver keeps, the smoother's log, a run's metrics);
//! - `divergence`: [`NisMonitor`], the divergence watch over the velocity updates' NIS;
//! - `watch`: [`Watch`], what a pass watches at every epoch for its health ([`Extent`]:
//!   the first epoch whose solution left a physical bound, the heading σ).

mod divergence;
mod epoch;
mod watch;

pub use divergence::{NisMonitor, DIVERGENCE_MEAN_NIS};
pub use epoch::{Epoch, Failure, Fed, Observer, Pass, Updated};
pub use watch::{
    Bound, Extent, Watch, MAX_ABS_HEIGHT, MAX_LINEAR_HEADING_SIGMA_DEG, MAX_POSITION_SIGMA,
    MAX_SPEED,
};
