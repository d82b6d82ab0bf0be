//! A filter pass over recorded (or user-simulated) sensor arrays: the IMU and the
//! aiding sensors' streams in, the solution at the kept epochs and each stream's rows
//! out, optionally smoothed.
//!
//! - `data`, `stream`: [`RecordedData`] and its [`Stream`]s, checked;
//! - `filter`: [`filter_recorded`] and [`smooth_recorded_until`], the driver of the
//!   one epoch loop ([`crate::pass`]) over them;
//! - `output`, `recorder`, `stale`, `epochs`: what the pass reports ([`FilterOutput`]),
//!   the observer that writes it, its σ inside a covariance step, and which epochs it
//!   keeps ([`Epochs`]);
//! - `memory`: what a pass would hold at its peak ([`estimate_memory`]), checked before
//!   it allocates.

mod data;
mod epochs;
mod filter;
mod memory;
mod output;
mod recorder;
mod stale;
mod stream;

pub use data::RecordedData;
pub use epochs::Epochs;
pub use filter::{filter_recorded, filter_recorded_until, smooth_recorded_until, start_filter};
pub use memory::{estimate as estimate_memory, PassMemory};
#[cfg(test)]
pub(crate) use output::solution_of;
pub use output::{FilterOutput, StreamRecord};
pub use stream::{velocity_variance, PerRow, Stream, Values};

#[cfg(test)]
mod tests;

#[cfg(test)]
mod smoother_tests;

#[cfg(test)]
mod stream_tests;

#[cfg(test)]
mod thinned_tests;
