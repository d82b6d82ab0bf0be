//! Memory a call may take: what this process can still be given ([`available`]), and
//! the one check ([`Estimate::check`]) that every call allocating in proportion to an
//! argument runs once, before it allocates, so that a size beyond the machine is an
//! error naming that argument, never an abort ("memory allocation of … failed").
//!
//! A call sums what it would hold at its peak in [`Part`]s, one per argument that
//! bounds a share of it (the epochs a pass keeps: `output_step`; the covariances
//! asked for: `covariance_time`; ...), from the sizes of the values it keeps. Below
//! [`CHECKED_FROM`] nothing is read; above it the sum is compared with [`available`],
//! and a call that would not fit is refused naming its largest part's argument, with
//! the estimate, what is available and what to change (`docs/results/performance.md`,
//! "Memory").

use crate::error::{Error, Result};

/// Estimates below this \[bytes\] (64 MiB) are not checked: the call reads nothing of
/// the machine. Reading it takes a few `/proc` files, 0.1–0.3 ms: more than a short
/// call, and under 2 % of one that writes 64 MiB.
pub const CHECKED_FROM: f64 = (64u64 << 20) as f64;

/// What this process can still allocate \[bytes\], and which limit sets it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Available {
    pub bytes: f64,
    /// The limit that sets it: `"free memory"` (`MemAvailable` and `SwapFree` of
    /// `/proc/meminfo`), `"RLIMIT_AS"` (the address-space limit less the process's
    /// `VmSize`), `"RLIMIT_DATA"` (the data limit less its `VmData`) or `"cgroup"` (a
    /// memory cgroup's limit less its usage).
    pub source: &'static str,
}

/// What this process can still allocate: the least of the free memory, the room its
/// address-space and data limits leave, and its memory cgroup's. None where none of
/// them can be read (not Linux).
pub fn available() -> Option<Available> {
    let mut least: Option<Available> = None;
    let mut take = |bytes: Option<f64>, source| {
        if let Some(bytes) = bytes {
            if least.is_none_or(|l| bytes < l.bytes) {
                least = Some(Available {
                    bytes: bytes.max(0.0),
                    source,
                });
            }
        }
    };
    let meminfo = read("/proc/meminfo");
    let free =
        kib(&meminfo, "MemAvailable:").map(|m| m + kib(&meminfo, "SwapFree:").unwrap_or(0.0));
    take(free, "free memory");
    let limits = read("/proc/self/limits");
    let status = read("/proc/self/status");
    let room = |limit: &str, used: &str| Some(soft_limit(&limits, limit)? - kib(&status, used)?);
    take(room("Max address space", "VmSize:"), "RLIMIT_AS");
    take(room("Max data size", "VmData:"), "RLIMIT_DATA");
    take(cgroup_room(), "cgroup");
    least
}

/// The text of a file, empty where it cannot be read.
fn read(path: &str) -> String {
    std::fs::read_to_string(path).unwrap_or_default()
}

/// The value \[bytes\] of the line `key` of a `/proc` file in kB (`VmSize:   1234 kB`).
fn kib(text: &str, key: &str) -> Option<f64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let value: f64 = line[key.len()..].split_whitespace().next()?.parse().ok()?;
    Some(value * 1024.0)
}

/// The soft limit \[bytes\] of the row `name` of `/proc/self/limits`; None where it is
/// unlimited or missing.
fn soft_limit(limits: &str, name: &str) -> Option<f64> {
    let line = limits.lines().find(|l| l.starts_with(name))?;
    line[name.len()..].split_whitespace().next()?.parse().ok()
}

/// The room \[bytes\] the memory cgroups of this process leave: cgroup v2's
/// `memory.max` less `memory.current`, over its cgroup and those above it, or v1's
/// `memory.limit_in_bytes` less `memory.usage_in_bytes` where it is mounted; None
/// without a limit.
fn cgroup_room() -> Option<f64> {
    let number = |path: String| read(&path).trim().parse::<f64>().ok();
    let mut least: Option<f64> = None;
    let mut keep = |room: Option<f64>| {
        if let Some(room) = room {
            least = Some(least.map_or(room, |l: f64| l.min(room)));
        }
    };
    let groups = read("/proc/self/cgroup");
    if let Some(path) = groups.lines().find_map(|l| l.strip_prefix("0::")) {
        let mut dir = format!("/sys/fs/cgroup{}", path.trim_end_matches('/'));
        loop {
            // "max" (no limit) does not parse.
            let max = number(format!("{dir}/memory.max"));
            keep(
                max.zip(number(format!("{dir}/memory.current")))
                    .map(|(m, c)| m - c),
            );
            match dir.rfind('/') {
                Some(cut) if dir[..cut].len() >= "/sys/fs/cgroup".len() => dir.truncate(cut),
                _ => break,
            }
        }
    }
    let v1 = "/sys/fs/cgroup/memory";
    let limit = number(format!("{v1}/memory.limit_in_bytes")).filter(|&l| l < 2f64.powi(60));
    keep(
        limit
            .zip(number(format!("{v1}/memory.usage_in_bytes")))
            .map(|(l, u)| l - u),
    );
    least
}

/// The values a vector grown one push at a time has room for once it holds `count`
/// (it doubles when full, from 4): the room it takes.
pub fn grown(count: f64) -> f64 {
    if count <= 4.0 {
        return count.max(0.0).ceil().min(4.0);
    }
    2f64.powi(count.log2().ceil() as i32)
}

/// One share of a call's memory: `count` values of `each` bytes, bounded by the
/// argument `arg`.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// The argument that bounds it (the one the refusal names).
    pub arg: &'static str,
    /// What the values are, in the plural (`"kept epochs"`).
    pub what: &'static str,
    pub count: f64,
    /// Bytes per value.
    pub each: f64,
    /// What to change to hold less (`"keep fewer epochs: output_step"`).
    pub remedy: &'static str,
}

impl Part {
    pub fn bytes(&self) -> f64 {
        self.count * self.each
    }
}

/// What a call would hold at its peak, in [`Part`]s (inputs the caller already holds
/// are not counted).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    pub parts: Vec<Part>,
    /// What the call holds whatever its arguments \[bytes\] (its state, small buffers).
    pub fixed: f64,
}

impl Estimate {
    /// Add `count` values of `each` bytes bounded by `arg` (nothing for none).
    pub fn add(
        &mut self,
        arg: &'static str,
        what: &'static str,
        (count, each): (f64, f64),
        remedy: &'static str,
    ) -> &mut Self {
        if count > 0.0 && each > 0.0 {
            self.parts.push(Part {
                arg,
                what,
                count,
                each,
                remedy,
            });
        }
        self
    }

    /// The whole estimate \[bytes\].
    pub fn bytes(&self) -> f64 {
        self.fixed + self.parts.iter().map(Part::bytes).sum::<f64>()
    }

    /// The argument that bounds the most of it, with its bytes, and its largest part
    /// (None for an empty estimate).
    pub fn largest(&self) -> Option<(&'static str, f64, &Part)> {
        let of = |arg: &str| -> f64 {
            self.parts
                .iter()
                .filter(|p| p.arg == arg)
                .map(Part::bytes)
                .sum()
        };
        let arg = self
            .parts
            .iter()
            .map(|p| (p.arg, of(p.arg)))
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        let part = self
            .parts
            .iter()
            .filter(|p| p.arg == arg.0)
            .max_by(|a, b| a.bytes().total_cmp(&b.bytes()))?;
        Some((arg.0, arg.1, part))
    }

    /// `Err` naming the largest part's argument when the estimate is more than this
    /// process can still allocate ([`available`]; estimates below [`CHECKED_FROM`]
    /// are not checked). `call` names the call in the message (`"this pass"`).
    pub fn check(&self, call: &str) -> Result<()> {
        let bytes = self.bytes();
        if bytes < CHECKED_FROM {
            return Ok(());
        }
        match available() {
            Some(room) => self.check_against(call, room),
            None => Ok(()),
        }
    }

    /// [`Estimate::check`] against `room` (read nothing).
    pub fn check_against(&self, call: &str, room: Available) -> Result<()> {
        let bytes = self.bytes();
        let Some((arg, share, part)) = self.largest().filter(|_| bytes > room.bytes) else {
            return Ok(());
        };
        Err(Error::invalid(
            arg,
            format!(
                "{call} would hold about {} of memory, {} of it for {arg} (the most: {} {}, \
                 {} bytes each), and this process can take {} more ({}): {}",
                size(bytes),
                size(share),
                thousands(part.count),
                part.what,
                thousands(part.each),
                size(room.bytes),
                room.source,
                part.remedy
            ),
        ))
    }
}

/// `bytes` as MiB or GiB, one decimal.
pub fn size(bytes: f64) -> String {
    let mib = bytes / f64::from(1u32 << 20);
    if mib < 1024.0 {
        format!("{mib:.1} MiB")
    } else {
        format!("{:.1} GiB", mib / 1024.0)
    }
}

/// A count with its thousands separated (`3,600,001`), rounded to a whole number.
fn thousands(value: f64) -> String {
    let digits = format!("{:.0}", value.clamp(0.0, 1e30));
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pass(epochs: f64) -> Estimate {
        let mut e = Estimate::default();
        e.add("output_step", "kept epochs", (epochs, 800.0), "keep fewer")
            .add(
                "covariance_time",
                "covariances",
                (10.0, 1808.0),
                "ask for fewer",
            )
            .add("smooth", "nodes", (0.0, 2000.0), "no smoother");
        e
    }

    #[test]
    fn an_estimate_sums_its_parts_and_names_the_largest() {
        let e = pass(3_600_001.0);
        assert_eq!(e.parts.len(), 2, "a part of no values is left out");
        assert_eq!(e.bytes(), 3_600_001.0 * 800.0 + 18_080.0);
        let room = Available {
            bytes: 1e9,
            source: "RLIMIT_AS",
        };
        let err = e.check_against("this pass", room).unwrap_err().to_string();
        assert_eq!(
            err,
            "output_step: this pass would hold about 2.7 GiB of memory, 2.7 GiB of it for \
             output_step (the most: 3,600,001 kept epochs, 800 bytes each), and this \
             process can take 953.7 MiB more (RLIMIT_AS): keep fewer"
        );
        assert!(pass(1000.0).check_against("this pass", room).is_ok());
    }

    #[test]
    fn a_small_estimate_is_not_checked() {
        assert!(pass(1000.0).bytes() < CHECKED_FROM);
        assert!(pass(1000.0).check("this pass").is_ok());
        assert_eq!(grown(3.0), 3.0);
        assert_eq!(grown(5.0), 8.0);
        assert_eq!(grown(1024.0), 1024.0);
        assert_eq!(grown(1025.0), 2048.0);
    }

    #[test]
    fn what_is_available_is_read_on_linux() {
        if cfg!(target_os = "linux") {
            let room = available().expect("/proc/meminfo is readable on Linux");
            assert!(room.bytes > 0.0, "{room:?}");
        }
        assert_eq!(
            kib("VmSize:\t  143556 kB\n", "VmSize:"),
            Some(143556.0 * 1024.0)
        );
        let limits = "Max data size             unlimited            unlimited            bytes\n\
                      Max address space         1073741824           unlimited            bytes\n";
        assert_eq!(soft_limit(limits, "Max address space"), Some(1073741824.0));
        assert_eq!(soft_limit(limits, "Max data size"), None);
        assert_eq!(thousands(1234567.0), "1,234,567");
        assert_eq!(thousands(12.0), "12");
    }
}
