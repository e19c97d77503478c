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
//! The estimate is an upper bound on the bench's records, not a prediction to the megabyte: a
//! record refused by a few percent can be cut a little. The grey-box fit's and the diagnosis's
//! per-sample costs follow their peaks from 2,000,000 to 20,000,000 samples (165 and 171 bytes
//! a sample more, 2026-11-29); the estimate is 1.1x to 1.9x the peaks measured at 200,000,
//! 2,000,000 and 20,000,000 samples (it was 2.6x and 3.5x at 20,000,000, set from the shorter
//! records alone). `simulate`, which writes streaming, 2.7x to 6.9x: its cost is kept for
//! plants with more states than the bench's.
//! `HYSTBENCH_MEMORY_AVAILABLE` (bytes) replaces the machine's figure: to check what a
//! smaller machine would say, or to go ahead where the estimate is too cautious.

use super::DataError;
use std::path::Path;

/// The environment variable that replaces the machine's available memory (bytes).
pub const AVAILABLE_VARIABLE: &str = "HYSTBENCH_MEMORY_AVAILABLE";

/// Bytes a command holds per sample beyond the record itself, per input path of an output
/// fitted at a time (grey-box basis columns grow with the paths), measured on the bench's
/// 1-input record with margin (`benches/scale.sh`, 200,000 to 20,000,000 samples); a grey-box
/// fit holds more per sample on a short record, up to a cap ([`Work::held_cap`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Work {
    /// `fit`: the grey-box fit. A long record's basis is streamed in pieces
    /// (`graybox`: the pieces and the columns kept whole up to 128 MB are the fixed part);
    /// what grows with the samples is the record, the residual and the derivatives of the
    /// parameters that are not computed a block at a time.
    GreyBoxFit,
    /// `diagnose`, `improve`: a fit's memory plus the banks and the refit test's candidate
    /// fits (run one at a time on long records).
    Diagnosis,
    /// `identify`: the network's regressors and the grey-box base (fitted on at most 20,000
    /// samples to choose, then on the fitting part).
    Identification,
    /// `predict`, `compare`, `compensate`, `track`: a prediction and its output (`plot` and
    /// `inspect` hold little beyond the record: the reading's check covers them).
    Prediction,
    /// `simulate`: the plant's states and the record written.
    Simulation,
}

impl Work {
    /// Working bytes per sample and input path (see [`Work`]).
    pub const fn bytes_per_sample(self) -> u64 {
        match self {
            Work::GreyBoxFit => 250,
            Work::Diagnosis => 300,
            Work::Identification => 400,
            Work::Prediction | Work::Simulation => 250,
        }
    }

    /// Working bytes per sample and input path held only up to [`Work::held_cap`]: what a
    /// grey-box fit holds whole on a record short enough (its basis, the columns it keeps,
    /// and its starts' runs side by side: 1.5 kB per sample measured at 200,000 and 300,000
    /// samples), and streams in pieces of a fixed size beyond.
    pub const fn held_bytes_per_sample(self) -> u64 {
        match self {
            Work::GreyBoxFit => 2_000,
            Work::Diagnosis => 2_000,
            _ => 0,
        }
    }

    /// The most that [`Work::held_bytes_per_sample`] comes to per input path, whatever the
    /// record's length.
    pub const fn held_cap(self) -> u64 {
        match self {
            // the basis and kept columns (400 MB) and the starts side by side (256 MB)
            Work::GreyBoxFit => 700_000_000,
            Work::Diagnosis => 500_000_000,
            _ => 0,
        }
    }

    /// What to do about a record too large for this work.
    pub const fn advice(self) -> &'static str {
        match self {
            Work::Simulation => "ask for fewer `samples` in the scenario (or simulate it in parts)",
            Work::GreyBoxFit => "fit a part of the record (`--train-fraction F` fits the first F of it), use a part (`hystbench split` at its gaps, or cut its lines) or fewer samples (decimate it)",
            _ => "use a part of the record (`hystbench split` at its gaps, or cut its lines) or fewer samples (decimate it)",
        }
    }

    /// What the command does, for the error.
    pub const fn what(self) -> &'static str {
        match self {
            Work::GreyBoxFit => "a grey-box fit",
            Work::Diagnosis => "a diagnosis",
            Work::Identification => "an identification",
            Work::Prediction => "a prediction",
            Work::Simulation => "a simulation",
        }
    }

    /// The estimated working memory for `samples` samples of `inputs` input paths per output
    /// and `columns` signals in all (the record's own columns, held twice: read and selected).
    pub fn bytes(self, samples: usize, inputs: usize, columns: usize) -> u64 {
        let per_sample = self.bytes_per_sample() * inputs.max(1) as u64 + 16 * columns as u64;
        let held = (self.held_bytes_per_sample() * inputs.max(1) as u64)
            .saturating_mul(samples as u64)
            .min(self.held_cap() * inputs.max(1) as u64);
        per_sample
            .saturating_mul(samples as u64)
            .saturating_add(held)
    }
}

/// The memory available to this process, in bytes: [`AVAILABLE_VARIABLE`] when set to a whole
/// number of bytes, else the smaller of the kernel's `MemAvailable` and the room its control
/// groups leave (cgroup v2, the process's group and every parent; else v1); `None` where
/// neither can be read (not Linux): no check.
pub fn available_bytes() -> Option<u64> {
    if let Some(v) = std::env::var(AVAILABLE_VARIABLE)
        .ok()
        .and_then(|v| v.trim().parse().ok())
    {
        return Some(v);
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
    Some(kb.saturating_mul(1024))
}

/// The least room the control groups leave: limit less usage, where the usage does not count
/// the page cache the kernel can reclaim (`inactive_file`, the working set that container
/// runtimes report). Cgroup v2: the process's group (`/proc/self/cgroup`) and each parent up
/// to the root; else v1's hierarchical limit. `None`: no limit, or not in a group.
fn cgroup_room() -> Option<u64> {
    let read = |p: &Path| std::fs::read_to_string(p).ok();
    let stat = |p: &Path, key: &str| -> u64 {
        read(p)
            .and_then(|t| {
                t.lines()
                    .find_map(|l| l.strip_prefix(key)?.strip_prefix(' ')?.trim().parse().ok())
            })
            .unwrap_or(0)
    };
    let room = |limit: u64, usage: u64, reclaimable: u64| {
        limit.saturating_sub(usage.saturating_sub(reclaimable))
    };
    // v2: every group from the process's own up to the root
    let own = read(Path::new("/proc/self/cgroup")).and_then(|t| {
        t.lines()
            .find_map(|l| l.strip_prefix("0::").map(|p| p.trim().to_string()))
    });
    let root = Path::new("/sys/fs/cgroup");
    let mut v2: Option<u64> = None;
    if let Some(own) = own {
        let mut dir = root.join(own.trim_start_matches('/'));
        loop {
            let limit = read(&dir.join("memory.max")).and_then(|t| t.trim().parse::<u64>().ok());
            let usage =
                read(&dir.join("memory.current")).and_then(|t| t.trim().parse::<u64>().ok());
            if let (Some(limit), Some(usage)) = (limit, usage) {
                let r = room(
                    limit,
                    usage,
                    stat(&dir.join("memory.stat"), "inactive_file"),
                );
                v2 = Some(v2.map_or(r, |v| v.min(r)));
            }
            if dir == root || !dir.pop() || !dir.starts_with(root) {
                break;
            }
        }
    }
    if v2.is_some() {
        return v2;
    }
    // v1: the hierarchical limit (v1 reports "no limit" as a page-rounded i64::MAX)
    let v1 = Path::new("/sys/fs/cgroup/memory");
    let limit = stat(&v1.join("memory.stat"), "hierarchical_memory_limit");
    let usage = read(&v1.join("memory.usage_in_bytes")).and_then(|t| t.trim().parse().ok())?;
    (limit > 0 && limit < 1 << 60).then(|| {
        room(
            limit,
            usage,
            stat(&v1.join("memory.stat"), "total_inactive_file"),
        )
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
    check_need(path, work.what(), work.advice(), samples, needed)
}

/// [`check`] for the selected record `io` read from `path`, of which `samples` are worked on
/// (`io.len()`, or a fit's training part): its inputs are the paths, its columns the time,
/// the inputs and the outputs.
pub fn check_record(
    path: &Path,
    work: Work,
    io: &super::IoRecord,
    samples: usize,
) -> Result<(), DataError> {
    let columns = 1 + io.inputs.len() + io.outputs.len();
    check(path, work, samples, io.inputs.len(), columns)
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

/// Bytes as a person reads them, to three significant digits: "3.21 GB", "850 MB", "12.0 kB".
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    let (v, unit) = if b >= 1e9 {
        (b / 1e9, "GB")
    } else if b >= 1e6 {
        (b / 1e6, "MB")
    } else if b >= 1e3 {
        (b / 1e3, "kB")
    } else {
        return format!("{bytes} bytes");
    };
    let decimals = if v >= 100.0 {
        0
    } else if v >= 10.0 {
        1
    } else {
        2
    };
    format!("{v:.decimals$} {unit}")
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
        let fixed = Work::GreyBoxFit.held_cap();
        assert_eq!(
            Work::GreyBoxFit.bytes(10_000_000, 1, 3) - fixed,
            10 * (one - fixed)
        );
        assert!(Work::GreyBoxFit.bytes(1_000_000, 2, 3) > one);
        assert!(Work::Prediction.bytes(1_000_000, 1, 3) < one);
        assert_eq!(human(3_214_000_000), "3.21 GB");
        assert_eq!(human(1_040_000_000), "1.04 GB");
        assert_eq!(human(960_000_000), "960 MB");
        assert_eq!(human(12_000), "12.0 kB");
        assert_eq!(human(0), "0 bytes");
    }
}
