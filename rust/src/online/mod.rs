//! Online navigation: the filter pass fed as the data arrives, one IMU sample (or a
//! block) and one reading at a time, equal to the batch pass fed in time order, with
//! late readings applied at their own epoch within a lag window.
//!
//! - `navigator`: [`Navigator`], the pass, its sensors' queues and tallies;
//! - `history`: what it keeps to run a stretch again for a late reading (the lag
//!   window's IMU steps and readings, checkpoints of the filter);
//! - `sensor`: [`Sensor`], a stream's settings, turning one reading fed into the
//!   [`crate::measurement::Reading`] a stream's row would be;
//! - `stamps`: [`Stamps`], the IMU's steps fed and the gaps among them;
//! - `tally`: [`Tally`], what it did with each sensor's readings;
//! - `tuning`: the learned loop's instants and window of raw samples.

mod history;
mod navigator;
mod sensor;
mod stamps;
mod tally;
mod tuning;

#[cfg(test)]
mod tests;

pub use history::Outcome;
pub use navigator::{Estimate, Fate, Lag, Navigator, Start};
pub use sensor::Sensor;
pub use stamps::{Stamps, MAX_IMU_GAP};
pub use tally::Tally;
pub use tuning::{Tuning, Window};
