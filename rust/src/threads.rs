//! Worker threads: how many a call may have, from an argument or `RAYON_NUM_THREADS`,
//! and the rayon pools the core's parallel calls run on.

use crate::error::{Error, Result};
use std::sync::{Arc, OnceLock};

/// The most worker threads a pool may have, whatever the machine: far above any core
/// count this runs on, and low enough that a mistyped count fails at once instead of
/// spawning for minutes.
pub const MAX_THREADS: usize = 1024;

/// The most worker threads per core this process may use: the core's calls are
/// CPU-bound, so threads beyond one per core only queue (1,024 threads on 2 cores added
/// 3 s to a 1 s Monte Carlo); a few per core leave room for a deliberate oversubscription.
pub const THREADS_PER_CORE: usize = 8;

/// The environment variable that sets the thread count of calls given none (rayon's).
pub const THREADS_ENV: &str = "RAYON_NUM_THREADS";

/// The cores this process may use (its CPU affinity and quota, as the standard library
/// counts them), at least 1.
pub fn usable_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The most threads a pool may have on this machine: [`THREADS_PER_CORE`] per usable
/// core, and never more than [`MAX_THREADS`].
pub fn max_threads() -> usize {
    MAX_THREADS.min(THREADS_PER_CORE * usable_cores())
}

/// `threads` if it is 1 to [`max_threads`], else an error naming `arg`.
pub fn check_threads(arg: &str, threads: usize) -> Result<usize> {
    let most = max_threads();
    if (1..=most).contains(&threads) {
        return Ok(threads);
    }
    Err(Error::invalid(
        arg,
        format!(
            "must be 1 to {most} ({THREADS_PER_CORE} per core this process may use, {} here; \
             never more than {MAX_THREADS}), got {threads}",
            usable_cores()
        ),
    ))
}

/// The thread count of a call given none: [`THREADS_ENV`] if it is set (checked as an
/// explicit count is, the error naming the variable), else one per usable core.
pub fn default_threads() -> Result<usize> {
    threads_from_env(std::env::var_os(THREADS_ENV).map(|v| v.to_string_lossy().into_owned()))
}

/// [`default_threads`] for the value `text` of [`THREADS_ENV`] (None: unset).
fn threads_from_env(text: Option<String>) -> Result<usize> {
    let Some(text) = text else {
        return Ok(usable_cores());
    };
    match text.trim().parse::<usize>() {
        Ok(n) => check_threads(THREADS_ENV, n),
        Err(_) => Err(Error::invalid(
            THREADS_ENV,
            format!(
                "expected a whole number 1 to {} (or unset it: one thread per core), got {text:?}",
                max_threads()
            ),
        )),
    }
}

/// A rayon pool of `threads` worker threads (1 to [`max_threads`]), or an error
/// naming `threads`.
pub fn thread_pool(threads: usize) -> Result<rayon::ThreadPool> {
    check_threads("threads", threads)?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::invalid("threads", format!("cannot start {threads} threads: {e}")))
}

/// Run `f` on a rayon pool of `threads` threads, or on the default pool for `None`.
pub fn with_threads<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> Result<T> {
    Ok(Workers::new(threads)?.run(f))
}

/// The pool of calls given no thread count, [`default_threads`] large, made at the
/// first such call. rayon's own global pool is never used: it would take any
/// `RAYON_NUM_THREADS` unchecked (100,000 built 16,000 threads before failing).
static DEFAULT_POOL: OnceLock<Arc<rayon::ThreadPool>> = OnceLock::new();

fn default_pool() -> Result<Arc<rayon::ThreadPool>> {
    if let Some(pool) = DEFAULT_POOL.get() {
        return Ok(Arc::clone(pool));
    }
    let threads = default_threads()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::invalid(THREADS_ENV, format!("cannot start {threads} threads: {e}")))?;
    Ok(Arc::clone(DEFAULT_POOL.get_or_init(|| Arc::new(pool))))
}

/// The threads a long-lived object's calls run on (a frozen regressor, an ensemble): a
/// pool of its own when it was built with a thread count, else the default pool
/// ([`default_threads`] threads, shared by every call given none). Clones share the pool.
#[derive(Clone, Debug)]
pub struct Workers(Arc<rayon::ThreadPool>);

impl Workers {
    /// A pool of `threads` threads (1 to [`max_threads`], else an error naming
    /// `threads`), or the default pool for `None` (an error naming
    /// [`THREADS_ENV`] if that is set to an unusable count).
    pub fn new(threads: Option<usize>) -> Result<Self> {
        match threads {
            Some(n) => Ok(Self(Arc::new(thread_pool(n)?))),
            None => Ok(Self(default_pool()?)),
        }
    }

    /// Run `f` on these threads: rayon's parallel iterators inside it use them.
    pub fn run<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        self.0.install(f)
    }

    /// How many threads these are.
    pub fn threads(&self) -> usize {
        self.0.current_num_threads()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn workers_run_on_their_own_pool_or_the_default_one() {
        let own = Workers::new(Some(3)).unwrap();
        assert_eq!(own.run(rayon::current_num_threads), 3);
        assert_eq!(own.clone().run(rayon::current_num_threads), 3);
        let default = Workers::new(None).unwrap();
        assert_eq!(default.run(rayon::current_num_threads), default.threads());
        assert_eq!(default.threads(), default_threads().unwrap());
        for bad in [0, max_threads() + 1, MAX_THREADS + 1] {
            let err = Workers::new(Some(bad)).unwrap_err().to_string();
            assert!(err.starts_with("threads: must be 1 to "), "{err}");
        }
    }

    #[test]
    fn the_thread_variable_is_checked_as_an_explicit_count() {
        assert_eq!(threads_from_env(None), Ok(usable_cores()));
        assert_eq!(threads_from_env(Some(" 1 ".into())), Ok(1));
        assert!(max_threads() <= MAX_THREADS);
        assert!(max_threads() >= THREADS_PER_CORE.min(MAX_THREADS));
        for bad in [
            "0",
            "100000",
            "-3",
            "2.5",
            "",
            "all",
            "18446744073709551616",
        ] {
            let err = threads_from_env(Some(bad.into())).unwrap_err().to_string();
            assert!(err.starts_with("RAYON_NUM_THREADS: "), "{bad}: {err}");
        }
    }
}
