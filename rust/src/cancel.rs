//! Cooperative cancellation of long core calls. Whoever drives the core (the Python
//! binding, when Ctrl-C or SIGTERM arrives) sets a [`Cancel`]; the long loops check it
//! between chunks of work and stop with [`Error::Cancelled`], so an interrupt ends a
//! call within milliseconds instead of when the call would have returned.

use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, Ordering};

/// IMU steps between two checks inside one run: ~4096 steps take a few milliseconds,
/// and one relaxed atomic load per chunk costs nothing measurable.
pub const STEPS_PER_CHECK: usize = 4096;

/// A flag a long call polls; set it to make the call stop.
#[derive(Debug, Default)]
pub struct Cancel(AtomicBool);

impl Cancel {
    /// Ask the call polling this flag to stop.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// `Err(Error::Cancelled)` once [`Cancel::cancel`] was called.
    #[inline]
    pub fn check(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_fails_only_after_cancel() {
        let c = Cancel::default();
        assert_eq!(c.check(), Ok(()));
        c.cancel();
        assert_eq!(c.check(), Err(Error::Cancelled));
    }
}
