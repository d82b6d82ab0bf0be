//! The Rauch–Tung–Striebel smoother over the closed-loop error-state filter.
//!
//! The forward pass (a [`crate::pass::Pass`] told to a [`ForwardLog`]) keeps a
//! [`Node`] at every epoch where the covariance was updated or the process noise
//! changed: the covariance before and after the update, the error estimate fed back,
//! and the noise in force until the next node. Between nodes the filter only
//! predicts, so the backward pass rebuilds each interval's covariances and transitions
//! from the forward solution (kept at every epoch) and the node it starts from, and
//! never stores them for the whole pass: memory grows with the nodes (DVL epochs), not
//! with the IMU samples.
//!
//! After every update the forward filter resets its error estimate to zero, so every
//! error below is relative to the forward solution at its epoch. With `δs` the smoothed
//! error of the solution after an epoch's update (the prior's is `δs⁻ = δs + δx̂`, the
//! feedback being `x̂⁺ = x̂⁻ ⊖ δx̂`), an interval from node `a` to node `b` gives, at
//! each epoch `i` in it (`P_i` the forward covariance there, `Φ_{i→b}` the product of
//! the step transitions from `i` to `b`, `P⁻_b` the covariance before `b`'s update):
//!
//! ```text
//! A_i  = P_i Φ_{i→b}ᵀ (P⁻_b)⁻¹
//! δs_i = A_i δs⁻_b
//! Ps_i = P_i + A_i (Ps_b − P⁻_b) A_iᵀ
//! ```
//!
//! the fixed-interval RTS recursion `C_i = P⁺_i Φ_{i+1}ᵀ (P⁻_{i+1})⁻¹` chained over the
//! closes without an update, where `P⁺ = P⁻` and `δx̂ = 0`: every IMU sample at every
//! sample, the steps' closes under a covariance step. One backward pass (`backward`)
//! runs it, whatever the closes are and wherever it writes. With the DVL calibration
//! states the recursion runs on all 19 (`N` below): their rows of F are zero and the
//! navigation rows do not read them, so every product with `Φ` goes through the
//! navigation rows of the first 15. `docs/reference/smoother.md` ("The RTS smoother") writes it out
//! with its sources.
//!
//! - `node`: the [`Node`]s and how the prediction restarts from one;
//! - `log`: [`ForwardLog`], the forward pass's observer that keeps them (and, under a
//!   covariance step, the closes: `kept`);
//! - `closes`, `transition`: where the backward pass's transitions come from (each
//!   sample's, a step's, rebuilt or kept) and how it goes back through one;
//! - `backward`, `solve`: the one backward pass and the solves at an update;
//! - `thinned`: the closes of a pass that kept some epochs only, re-integrated;
//! - `forward`, `smoothed`, `sink`: what the backward pass reads, the smoothed
//!   solution, and where it writes;
//! - `memory`: what each of these holds, for the estimate a call checks before it
//!   allocates.

mod backward;
pub(crate) mod closes;
mod forward;
mod kept;
mod log;
pub mod memory;
mod node;
mod sink;
mod smoothed;
mod solve;
pub mod thinned;
mod transition;

pub use backward::{smooth, smooth_into};
pub use forward::{Covariances, Forward};
pub use kept::{KeptClose, KeptCloses};
pub use log::ForwardLog;
pub use node::{Node, NodeCalibration, Nodes, Noise};
pub(crate) use sink::changed_sigma;
pub use sink::Sink;
pub use smoothed::Smoothed;
