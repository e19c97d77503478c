//! A record seen as a system's inputs and outputs.

use super::{DataError, Record};
use std::path::PathBuf;

/// One named signal.
#[derive(Debug, Clone, PartialEq)]
pub struct Signal {
    pub name: String,
    pub values: Vec<f64>,
}

/// Inputs and outputs of one uniformly sampled experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct IoRecord {
    /// Where it came from (for error messages).
    pub path: PathBuf,
    /// Sampling period in seconds.
    pub ts: f64,
    /// Time of the first sample in seconds.
    pub t0: f64,
    /// Time column name as read (`t` when made here).
    pub time_name: String,
    pub inputs: Vec<Signal>,
    pub outputs: Vec<Signal>,
}

/// Default names for `n` signals with prefix `p`: `p` alone for one signal, else `p1`, `p2`, …
pub fn default_names(prefix: &str, n: usize) -> Vec<String> {
    if n == 1 {
        vec![prefix.to_string()]
    } else {
        (1..=n).map(|i| format!("{prefix}{i}")).collect()
    }
}

fn convention(rec: &Record, prefix: &str) -> Vec<String> {
    if rec.names.iter().any(|n| n == prefix) {
        return vec![prefix.to_string()];
    }
    let mut out = Vec::new();
    for i in 1.. {
        let n = format!("{prefix}{i}");
        if rec.names.contains(&n) {
            out.push(n);
        } else {
            break;
        }
    }
    out
}

impl IoRecord {
    /// Select inputs and outputs from a record: the named columns, or by convention
    /// `u`/`u1,u2…` and `y`/`y1,y2…`. An empty `outputs` selection is allowed when
    /// `outputs_required` is false (a record used only to drive a plant).
    pub fn from_record(
        rec: &Record,
        inputs: Option<&[String]>,
        outputs: Option<&[String]>,
        outputs_required: bool,
    ) -> Result<IoRecord, DataError> {
        let pick = |names: Option<&[String]>, prefix: &str, what: &str, required: bool| {
            let names = match names {
                Some(n) if !n.is_empty() => n.to_vec(),
                _ => convention(rec, prefix),
            };
            if names.is_empty() && required {
                return Err(DataError::NoDefaultColumns {
                    path: rec.path.clone(),
                    what: format!("no {what} column named `{prefix}` or `{prefix}1`, `{prefix}2`…; name the columns with --{what}s"),
                    available: rec.names.join(", "),
                });
            }
            names
                .into_iter()
                .map(|n| {
                    Ok(Signal {
                        values: rec.column(&n)?.to_vec(),
                        name: n,
                    })
                })
                .collect::<Result<Vec<_>, DataError>>()
        };
        let inputs = pick(inputs, "u", "input", true)?;
        let outputs = pick(outputs, "y", "output", outputs_required)?;
        let time_name = rec
            .time_column()
            .ok_or_else(|| DataError::NoDefaultColumns {
                path: rec.path.clone(),
                what: "no time column (`t`, `time`, `t_s`, `time_s`…); add the time in seconds"
                    .into(),
                available: rec.names.join(", "),
            })?;
        let ts = rec.sampling_period()?.ok_or_else(|| DataError::TooShort {
            path: rec.path.clone(),
            rows: rec.len(),
            needed: 2,
            why: "a sampling period needs two time stamps".into(),
        })?;
        let t0 = rec.column(time_name)?[0];
        let time_name = time_name.to_string();
        Ok(IoRecord {
            path: rec.path.clone(),
            ts,
            t0,
            time_name,
            inputs,
            outputs,
        })
    }

    /// A record of one input `u` and one output `y` sampled every `ts` from t = 0 (unit tests).
    #[cfg(test)]
    pub(crate) fn siso(path: &str, ts: f64, u: Vec<f64>, y: Vec<f64>) -> IoRecord {
        IoRecord {
            path: path.into(),
            ts,
            t0: 0.0,
            time_name: "t".into(),
            inputs: vec![Signal {
                name: "u".into(),
                values: u,
            }],
            outputs: vec![Signal {
                name: "y".into(),
                values: y,
            }],
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.inputs
            .first()
            .or(self.outputs.first())
            .map_or(0, |s| s.values.len())
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Input names.
    pub fn input_names(&self) -> Vec<String> {
        self.inputs.iter().map(|s| s.name.clone()).collect()
    }

    /// Output names.
    pub fn output_names(&self) -> Vec<String> {
        self.outputs.iter().map(|s| s.name.clone()).collect()
    }

    /// Samples `range` as a record of their own (time origin moves with it).
    pub fn slice(&self, range: std::ops::Range<usize>) -> IoRecord {
        let cut = |s: &Signal| Signal {
            name: s.name.clone(),
            values: s.values[range.clone()].to_vec(),
        };
        IoRecord {
            path: self.path.clone(),
            ts: self.ts,
            t0: self.t0 + range.start as f64 * self.ts,
            time_name: self.time_name.clone(),
            inputs: self.inputs.iter().map(cut).collect(),
            outputs: self.outputs.iter().map(cut).collect(),
        }
    }

    /// Phase `p` of a decimation by `s`: samples p, p + s, p + 2s, ... (sampling period s ts).
    pub fn phase(&self, s: usize, p: usize) -> IoRecord {
        let cut = |x: &Signal| Signal {
            name: x.name.clone(),
            values: x.values.iter().skip(p).step_by(s.max(1)).copied().collect(),
        };
        IoRecord {
            path: self.path.clone(),
            ts: self.ts * s as f64,
            t0: self.t0 + p as f64 * self.ts,
            time_name: self.time_name.clone(),
            inputs: self.inputs.iter().map(cut).collect(),
            outputs: self.outputs.iter().map(cut).collect(),
        }
    }

    /// First half for training, second half for testing, as in the source study.
    pub fn split_halves(&self) -> (IoRecord, IoRecord) {
        let h = self.len() / 2;
        (self.slice(0..h), self.slice(h..self.len()))
    }

    /// Time stamps.
    pub fn time(&self) -> Vec<f64> {
        (0..self.len())
            .map(|k| self.t0 + k as f64 * self.ts)
            .collect()
    }

    /// Column names and data in file order: time, inputs, outputs.
    pub fn to_columns(&self) -> (Vec<String>, Vec<Vec<f64>>) {
        let mut names = vec![self.time_name.clone()];
        let mut cols = vec![self.time()];
        for s in self.inputs.iter().chain(&self.outputs) {
            names.push(s.name.clone());
            cols.push(s.values.clone());
        }
        (names, cols)
    }
}
