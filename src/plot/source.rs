//! What a figure is drawn from: a record's inputs and outputs, plus the model's prediction of each
//! output when the CSV has a `<output>_hat` column (as `hystbench predict` writes: `t`, inputs,
//! measured outputs, `<output>_hat`).

use super::decimate::turning_points;
use super::style::{unit_display, Quantity};
use super::PlotError;
use crate::data::{read_csv, DataError, IoRecord, Record, Signal};
use crate::metrics::ptp;
use std::path::Path;

/// A record to plot: inputs, measured outputs and, per output, the model's prediction if any.
#[derive(Debug, Clone)]
pub struct PlotRecord {
    /// Name in legends (the file stem when loaded from a file).
    pub label: String,
    pub io: IoRecord,
    /// One entry per output of `io`: the predicted signal, if the record has one.
    pub predicted: Vec<Option<Vec<f64>>>,
    /// One entry per output: the half-width of the prediction band at each sample, if the
    /// record has one (`<output>_lo` and `<output>_hi` columns, as `hystbench predict` writes).
    pub band: Vec<Option<Vec<f64>>>,
    /// The record's column names, listed in errors.
    pub columns: Vec<String>,
    /// Units given by the caller (column, unit), for columns whose names carry none
    /// (a simulated plant's `u`, `y` with its spec's units).
    pub units: Vec<(String, String)>,
}

impl PlotRecord {
    /// A record without predictions.
    pub fn from_io(label: impl Into<String>, io: IoRecord) -> PlotRecord {
        let mut columns = vec![io.time_name.clone()];
        columns.extend(io.input_names());
        columns.extend(io.output_names());
        PlotRecord {
            label: label.into(),
            predicted: vec![None; io.outputs.len()],
            band: vec![None; io.outputs.len()],
            io,
            columns,
            units: Vec::new(),
        }
    }

    /// Add the model's prediction of output `j` (same length as the record).
    pub fn with_prediction(mut self, j: usize, values: Vec<f64>) -> Result<PlotRecord, PlotError> {
        if j >= self.io.outputs.len() || values.len() != self.io.len() {
            return Err(PlotError::Invalid {
                what: format!("prediction for output {j} of {}", self.label),
                problem: format!(
                    "the record has {} outputs and {} samples; the prediction has {} samples",
                    self.io.outputs.len(),
                    self.io.len(),
                    values.len()
                ),
            });
        }
        self.columns
            .push(format!("{}_hat", self.io.outputs[j].name));
        self.predicted[j] = Some(values);
        Ok(self)
    }

    /// Adds the band of output `j`'s prediction (half-widths, one per sample).
    pub fn with_band(mut self, j: usize, half_width: Vec<f64>) -> Result<PlotRecord, PlotError> {
        if j >= self.io.outputs.len() || half_width.len() != self.io.len() {
            return Err(PlotError::Invalid {
                what: format!("prediction band for output {j} of {}", self.label),
                problem: format!(
                    "the record has {} outputs and {} samples; the band has {} samples",
                    self.io.outputs.len(),
                    self.io.len(),
                    half_width.len()
                ),
            });
        }
        self.band[j] = Some(half_width);
        Ok(self)
    }

    /// Pick inputs and outputs from a parsed record (named columns, else the `u`/`y` convention,
    /// else, for a record with a time column and exactly two other columns besides `*_hat`, those
    /// two as input and output), and the `<output>_hat` columns as predictions.
    pub fn from_record(
        rec: &Record,
        inputs: Option<&[String]>,
        outputs: Option<&[String]>,
    ) -> Result<PlotRecord, PlotError> {
        let io = match IoRecord::from_record(rec, inputs, outputs, true) {
            Ok(io) => io,
            Err(e @ DataError::NoDefaultColumns { .. }) => {
                let time = rec.time_column();
                let rest: Vec<String> = rec
                    .names
                    .iter()
                    .filter(|n| Some(n.as_str()) != time && !n.ends_with("_hat"))
                    .cloned()
                    .collect();
                let unnamed = inputs.is_none_or(<[String]>::is_empty)
                    && outputs.is_none_or(<[String]>::is_empty);
                if time.is_some() && rest.len() == 2 && unnamed {
                    IoRecord::from_record(rec, Some(&rest[..1]), Some(&rest[1..]), true)?
                } else {
                    return Err(e.into());
                }
            }
            Err(e) => return Err(e.into()),
        };
        let column = |name: String| {
            rec.names
                .iter()
                .position(|n| *n == name)
                .map(|i| &rec.columns[i])
        };
        let predicted = io
            .outputs
            .iter()
            .map(|s| column(format!("{}_hat", s.name)).cloned())
            .collect();
        let band = io
            .outputs
            .iter()
            .map(|s| {
                let lo = column(format!("{}_lo", s.name))?;
                let hi = column(format!("{}_hi", s.name))?;
                Some(lo.iter().zip(hi).map(|(l, h)| 0.5 * (h - l)).collect())
            })
            .collect();
        let label = rec
            .path
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| "record".to_string());
        Ok(PlotRecord {
            label,
            io,
            predicted,
            band,
            columns: rec.names.clone(),
            units: Vec::new(),
        })
    }

    /// Read a CSV file and pick its columns (see [`PlotRecord::from_record`]).
    pub fn load(
        path: &Path,
        inputs: Option<&[String]>,
        outputs: Option<&[String]>,
    ) -> Result<PlotRecord, PlotError> {
        let rec = read_csv(path)?;
        let r = PlotRecord::from_record(&rec, inputs, outputs)?;
        Ok(match sidecar_units(path) {
            Some((i, o)) => r.with_units(&i, &o),
            None => r,
        })
    }

    /// Give every input the unit `input` and every output the unit `output` (empty: none),
    /// e.g. from a plant spec's units; used in axis labels.
    pub fn with_units(mut self, input: &str, output: &str) -> PlotRecord {
        for s in &self.io.inputs {
            if !input.is_empty() {
                self.units.push((s.name.clone(), unit_display(input)));
            }
        }
        for s in &self.io.outputs {
            if !output.is_empty() {
                self.units.push((s.name.clone(), unit_display(output)));
            }
        }
        self
    }

    /// The quantity and unit of a column: a unit given with [`PlotRecord::with_units`], else
    /// the one its name carries (`voltage_V`).
    pub fn quantity(&self, column: &str) -> Quantity {
        let base = column.strip_suffix("_hat").unwrap_or(column);
        match self.units.iter().find(|(c, _)| c == base) {
            Some((_, u)) => Quantity {
                name: base.to_string(),
                unit: Some(u.clone()),
            },
            None => Quantity::from_column(column),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.io.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.io.is_empty()
    }

    /// Fail unless the record has at least `needed` samples.
    pub fn require_len(&self, needed: usize, what: &str) -> Result<(), PlotError> {
        if self.len() < needed {
            return Err(PlotError::TooFewSamples {
                path: self.io.path.clone(),
                what: what.to_string(),
                samples: self.len(),
                needed,
            });
        }
        Ok(())
    }

    /// Fail unless every output has a prediction.
    pub fn require_predictions(&self) -> Result<(), PlotError> {
        for (s, p) in self.io.outputs.iter().zip(&self.predicted) {
            if p.is_none() {
                return Err(PlotError::NoPrediction {
                    path: self.io.path.clone(),
                    output: s.name.clone(),
                    available: self.columns.join(", "),
                });
            }
        }
        Ok(())
    }

    /// True when any output has a prediction.
    pub fn has_predictions(&self) -> bool {
        self.predicted.iter().any(Option::is_some)
    }

    /// Residual `y - y_hat` of output `j`, if predicted.
    pub fn residual(&self, j: usize) -> Option<Vec<f64>> {
        let p = self.predicted.get(j)?.as_ref()?;
        Some(
            self.io.outputs[j]
                .values
                .iter()
                .zip(p)
                .map(|(y, h)| y - h)
                .collect(),
        )
    }

    /// Time of sample `k` in seconds.
    pub fn time(&self, k: usize) -> f64 {
        self.io.t0 + k as f64 * self.io.ts
    }

    /// The samples with `from <= t <= to` (either bound may be open).
    pub fn window(&self, from: Option<f64>, to: Option<f64>) -> Result<PlotRecord, PlotError> {
        if from.is_none() && to.is_none() {
            return Ok(self.clone());
        }
        let n = self.len();
        let (start, end) = (self.time(0), self.time(n.saturating_sub(1)));
        let a = from.unwrap_or(f64::NEG_INFINITY);
        let b = to.unwrap_or(f64::INFINITY);
        let first = (0..n).find(|&k| self.time(k) >= a - 1e-9 * self.io.ts);
        let last = (0..n)
            .rev()
            .find(|&k| self.time(k) <= b + 1e-9 * self.io.ts);
        match (first, last) {
            (Some(i), Some(j)) if j > i => {
                let io = self.io.slice(i..j + 1);
                Ok(PlotRecord {
                    label: self.label.clone(),
                    io,
                    predicted: self
                        .predicted
                        .iter()
                        .map(|p| p.as_ref().map(|p| p[i..j + 1].to_vec()))
                        .collect(),
                    band: self
                        .band
                        .iter()
                        .map(|p| p.as_ref().map(|p| p[i..j + 1].to_vec()))
                        .collect(),
                    columns: self.columns.clone(),
                    units: self.units.clone(),
                })
            }
            _ => Err(PlotError::EmptyWindow {
                path: self.io.path.clone(),
                from: a,
                to: b,
                start,
                end,
            }),
        }
    }
}

/// A named signal's values.
pub fn values(s: &Signal) -> &[f64] {
    &s.values
}

/// The plant's units from the JSON sidecar `hystbench simulate` writes beside a record
/// (`<stem>.json` with `plant.units.input/output`); `None` when there is none or it does not say.
pub fn sidecar_units(csv: &Path) -> Option<(String, String)> {
    let text = std::fs::read_to_string(csv.with_extension("json")).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    let u = v.get("plant")?.get("units")?;
    let get = |k: &str| u.get(k).and_then(|x| x.as_str()).unwrap_or("").to_string();
    Some((get("input"), get("output")))
}

/// Cycle number of every sample: the count of input reversals so far (reversals swinging more
/// than 2 % of the input's range) divided by two. Minor loops get their own numbers.
pub fn cycle_index(x: &[f64]) -> Vec<u32> {
    let tp = turning_points(x, 0.02 * ptp(x));
    let mut out = Vec::with_capacity(x.len());
    let mut next = tp.iter().peekable();
    let mut reversals = 0u32;
    for k in 0..x.len() {
        while next.peek().is_some_and(|&&i| i < k) {
            next.next();
            reversals += 1;
        }
        out.push(reversals / 2);
    }
    out
}

/// Loop area of (x, y) per cycle of x (shoelace formula, closed from the last point back to the
/// first), normalised by the bounding box `ptp(x) * ptp(y)`:
/// 0 for a single-valued curve, about 0.785 for a circle traced once per cycle.
/// Returns (normalised area, cycles used).
pub fn normalised_loop_area(x: &[f64], y: &[f64]) -> (f64, u32) {
    // a loop per two reversals, the record's ends counting as half a reversal each
    let reversals = turning_points(x, 0.02 * ptp(x)).len() as u32;
    let cycles = reversals.div_ceil(2).max(1);
    // the whole-record area of `metrics` (what `compare` reports), per cycle
    (
        crate::metrics::normalised_loop_area(x, y).abs() / cycles as f64,
        cycles,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_of_a_circle_and_of_a_line() {
        let n = 4000;
        let th: Vec<f64> = (0..n)
            .map(|k| 2.0 * std::f64::consts::PI * 3.0 * k as f64 / n as f64)
            .collect();
        let x: Vec<f64> = th.iter().map(|t| t.cos()).collect();
        let y: Vec<f64> = th.iter().map(|t| t.sin()).collect();
        let (a, c) = normalised_loop_area(&x, &y);
        assert_eq!(c, 3);
        assert!((a - std::f64::consts::PI / 4.0).abs() < 0.01, "{a}");
        let (a, _) = normalised_loop_area(&x, &x);
        assert!(a.abs() < 1e-9);
    }

    #[test]
    fn cycles_count_reversals() {
        let x: Vec<f64> = (0..100).map(|k| ((k % 20) as f64 - 10.0).abs()).collect();
        let c = cycle_index(&x);
        assert_eq!(c[0], 0);
        assert_eq!(c[99], 4); // 9 reversals
        assert!(c.windows(2).all(|w| w[1] >= w[0]));
    }
}
