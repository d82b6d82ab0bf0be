//! The random streams of a simulated run: one ChaCha8 stream per run and purpose, and
//! the standard normal draws taken from them.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Which random stream of a run.
#[derive(Clone, Copy, Debug)]
pub enum Stream {
    Imu = 0,
    Dvl = 1,
    InitialError = 2,
    DvlDropout = 3,
}

/// The RNG of one stream of one run.
pub fn stream_rng(seed: u64, run_index: u64, stream: Stream) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(run_index * 4 + stream as u64);
    rng
}

/// Standard normal draw.
#[inline]
pub fn normal(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}
