//! A small CSV reader for the result tables (`results.csv`, `ladder.csv`) whose cells may be
//! text or empty, which the record reader ([`crate::data::read_csv`]) rightly refuses.

use super::PlotError;
use std::path::{Path, PathBuf};

/// A header and its rows of trimmed text cells, with line numbers.
pub struct Table {
    pub path: PathBuf,
    pub header: Vec<String>,
    /// (line number, cells)
    pub rows: Vec<(usize, Vec<String>)>,
}

impl Table {
    /// Read `path`; every row must have as many cells as the header, and `required` columns
    /// must be present.
    pub fn read(path: &Path, required: &[&str]) -> Result<Table, PlotError> {
        let text =
            std::fs::read_to_string(path).map_err(|source| crate::data::DataError::Read {
                path: path.to_path_buf(),
                source,
            })?;
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let Some((_, header)) = lines.next() else {
            return Err(PlotError::NoRows {
                path: path.to_path_buf(),
            });
        };
        let header: Vec<String> = header
            .trim_start_matches('\u{feff}')
            .split(',')
            .map(|s| s.trim().trim_matches('"').to_string())
            .collect();
        for name in required {
            if !header.iter().any(|h| h == name) {
                return Err(PlotError::MissingHeader {
                    path: path.to_path_buf(),
                    name: name.to_string(),
                    expected: required.join(","),
                    available: header.join(","),
                });
            }
        }
        let mut rows = Vec::new();
        for (i, line) in lines {
            let cells: Vec<String> = line
                .split(',')
                .map(|s| s.trim().trim_matches('"').to_string())
                .collect();
            if cells.len() != header.len() {
                return Err(PlotError::BadCell {
                    path: path.to_path_buf(),
                    line: i + 1,
                    column: header.last().cloned().unwrap_or_default(),
                    problem: format!(
                        "{} cells, but the header has {} columns",
                        cells.len(),
                        header.len()
                    ),
                });
            }
            rows.push((i + 1, cells));
        }
        if rows.is_empty() {
            return Err(PlotError::NoRows {
                path: path.to_path_buf(),
            });
        }
        Ok(Table {
            path: path.to_path_buf(),
            header,
            rows,
        })
    }

    fn col(&self, name: &str) -> usize {
        self.header
            .iter()
            .position(|h| h == name)
            .unwrap_or(usize::MAX)
    }

    /// The text of column `name` in row `r` (empty if the column is absent).
    pub fn text(&self, r: usize, name: &str) -> &str {
        let c = self.col(name);
        self.rows[r].1.get(c).map_or("", String::as_str)
    }

    fn bad(&self, r: usize, name: &str, problem: String) -> PlotError {
        PlotError::BadCell {
            path: self.path.clone(),
            line: self.rows[r].0,
            column: name.to_string(),
            problem,
        }
    }

    /// A finite number, or `None` for an empty cell.
    pub fn number_or_empty(&self, r: usize, name: &str) -> Result<Option<f64>, PlotError> {
        let s = self.text(r, name);
        if s.is_empty() {
            return Ok(None);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => Err(self.bad(r, name, format!("`{s}` is not a finite number"))),
        }
    }

    /// A finite number (an empty cell is an error).
    pub fn number(&self, r: usize, name: &str) -> Result<f64, PlotError> {
        self.number_or_empty(r, name)?
            .ok_or_else(|| self.bad(r, name, "missing value (empty cell)".into()))
    }

    /// A whole number >= 0.
    pub fn whole(&self, r: usize, name: &str) -> Result<u64, PlotError> {
        let s = self.text(r, name);
        s.parse::<u64>()
            .map_err(|_| self.bad(r, name, format!("`{s}` is not a whole number")))
    }

    /// A 0/1 flag (`true`/`false` accepted too).
    pub fn flag(&self, r: usize, name: &str) -> Result<bool, PlotError> {
        match self.text(r, name) {
            "0" | "false" | "" => Ok(false),
            "1" | "true" => Ok(true),
            s => Err(self.bad(r, name, format!("`{s}` is not 0 or 1"))),
        }
    }

    /// Error for row `r`, column `name`.
    pub fn error(&self, r: usize, name: &str, problem: impl Into<String>) -> PlotError {
        self.bad(r, name, problem.into())
    }
}
