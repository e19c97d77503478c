//! # Memory: what a record needs, what the machine has
//!
//! An hour at 10 kHz is 36 million samples. A command whose working memory outgrows the
//! machine's is killed by the kernel without a word (no swap) or thrashes for hours; it should
//! rather say at the start what it would need. Each command checks, once its record is read:
//! its working memory is estimated from the record's size ([`Work::bytes`]; the per-sample
//! costs are those `benches/scale.sh` measures, `docs/benchmarks.md`), and met with the memory
//! the machine has available ([`available_bytes`]: the kernel's estimate of what can be
//! allocated without swapping, under the process's control-group limit when it runs in one).
//! Reading a file checks its text and parsed columns first ([`check_file`]).
//!
//! The estimate is an upper bound on the bench's records (1.1x to 2.6x the peaks measured on
//! 200,000 to 2,000,000 samples, 2026-11-27), not a prediction to the megabyte: a record
//! refused by a few percent can be cut a little.
//! `HYSTBENCH_MEMORY_AVAILABLE` (bytes) replaces the machine's figure: to check what a
//! smaller machine would say, or to go ahead where the estimate is too cautious.

use super::DataError;
use std::path::Path;

/// The environment variable that replaces the machine's available memory (bytes).
pub const AVAILABLE_VARIABLE: &str = "HYSTBENCH_MEMORY_AVAILABLE";

/// Bytes a command holds per sample beyond the record itself, per input path of an output
/// fitted at a time (grey-box basis columns grow with the paths), measured on the bench's
/// 1-input record with margin (`benches/scale.sh`, 200,000 to 2,000,000 samples).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Work {
    /// `fit`, `improve`: the grey-box fit (basis columns, derivatives, one evaluation's
    /// filtered basis): about 1.5 kB a sample measured at 2,000,000.
    GreyBoxFit,
    /// `diagnose`: a fit's memory plus the banks and the refit test's candidate fits (run
    /// one at a time on long records).
    Diagnosis,
    /// `identify`: the network's regressors and the grey-box base (fitted on at most 20,000
    /// samples to choose, then on the fitting part).
    Identification,
    /// `predict`, `compare`, `simulate`, `plot`: a prediction or a simulation and its output.
    Prediction,
}

impl Work {
    /// Working bytes per sample and input path (see [`Work`]).
    pub const fn bytes_per_sample(self) -> u64 {
        match self {
            Work::GreyBoxFit => 1_800,
            Work::Diagnosis => 2_400,
            Work::Identification => 400,
            Work::Prediction => 250,
        }
    }

    /// What the command does, for the error.
    pub const fn what(self) -> &'static str {
        match self {
            Work::GreyBoxFit => "a grey-box fit",
            Work::Diagnosis => "a diagnosis",
            Work::Identification => "an identification",
            Work::Prediction => "a prediction",
        }
    }

    /// The estimated working memory for `samples` samples of `inputs` input paths per output
    /// and `columns` signals in all (the record's own columns, held twice: read and selected).
    pub fn bytes(self, samples: usize, inputs: usize, columns: usize) -> u64 {
        let per_sample = self.bytes_per_sample() * inputs.max(1) as u64 + 16 * columns as u64;
        per_sample.saturating_mul(samples as u64)
    }
}

/// The memory available to this process, in bytes: [`AVAILABLE_VARIABLE`] when set, else the
/// smaller of the kernel's `MemAvailable` and the control group's limit less its usage
/// (cgroup v2, then v1); `None` where neither can be read (not Linux): no check.
pub fn available_bytes() -> Option<u64> {
    if let Ok(v) = std::env::var(AVAILABLE_VARIABLE) {
        return v.trim().parse().ok();
    }
    let meminfo = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| mem_available(&t));
    let cgroup = cgroup_room();
    match (meminfo, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// `MemAvailable` of a `/proc/meminfo` text, in bytes.
fn mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The control group's limit less its usage (`None`: no limit, or not in one).
fn cgroup_room() -> Option<u64> {
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let pair = |limit: &str, usage: &str| -> Option<u64> {
        let limit: u64 = read(limit)?.trim().parse().ok()?; // "max": no limit
        let usage: u64 = read(usage)?.trim().parse().ok()?;
        Some(limit.saturating_sub(usage))
    };
    pair("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current").or_else(|| {
        pair(
            "/sys/fs/cgroup/memory/memory.limit_in_bytes",
            "/sys/fs/cgroup/memory/memory.usage_in_bytes",
        )
        // v1 reports "no limit" as a page-rounded i64::MAX
        .filter(|&room| room < 1 << 60)
    })
}

/// Whether `work` on a record of `samples` samples fits in the available memory; the error
/// names the file, the size, both figures and what to do.
pub fn check(
    path: &Path,
    work: Work,
    samples: usize,
    inputs: usize,
    columns: usize,
) -> Result<(), DataError> {
    let needed = work.bytes(samples, inputs, columns);
    let advice = "use a part of the record (`hystbench split` at its gaps, `--train-fraction` for a fit) or fewer samples (decimate it)";
    check_need(path, work.what(), advice, samples, needed)
}

/// Whether reading the file at `path` fits in the available memory. It is read line by line
/// (`read_csv`), so what it needs is its parsed columns: eight bytes a cell, reserved at one
/// cell per eight bytes of text, about the file's size for cells of eight characters or more.
pub fn check_file(path: &Path) -> Result<(), DataError> {
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(()); // the read reports it
    };
    let text = meta.len();
    let advice = "cut the file into parts (its lines are samples: any text tool does it)";
    check_need(path, "reading the file", advice, 0, text)
}

fn check_need(
    path: &Path,
    what: &str,
    advice: &'static str,
    samples: usize,
    needed: u64,
) -> Result<(), DataError> {
    match available_bytes() {
        Some(available) if needed > available => Err(DataError::TooLarge {
            path: path.to_path_buf(),
            what: what.to_string(),
            advice,
            samples,
            needed,
            available,
        }),
        _ => Ok(()),
    }
}

/// Bytes as a person reads them: "3.2 GB", "850 MB", "12 kB".
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.0} MB", b / 1e6)
    } else {
        format!("{:.0} kB", (b / 1e3).max(1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_available_is_read_in_bytes() {
        let t = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   22000000 kB\n";
        assert_eq!(mem_available(t), Some(22_000_000 * 1024));
        assert_eq!(mem_available("MemTotal: 1 kB\n"), None);
    }

    #[test]
    fn the_estimate_grows_with_samples_and_paths() {
        let one = Work::GreyBoxFit.bytes(1_000_000, 1, 3);
        assert_eq!(Work::GreyBoxFit.bytes(10_000_000, 1, 3), 10 * one);
        assert!(Work::GreyBoxFit.bytes(1_000_000, 2, 3) > one);
        assert!(Work::Prediction.bytes(1_000_000, 1, 3) < one);
        assert_eq!(human(3_200_000_000), "3.2 GB");
        assert_eq!(human(850_000_000), "850 MB");
    }
}
