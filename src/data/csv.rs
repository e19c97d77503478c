//! CSV parsing with line numbers in every error, tolerant of what labs write (comments, `;` or
//! tab separators, decimal commas, a trailing separator, units in the header), and saying so.

use super::DataError;
use std::path::{Path, PathBuf};

/// A table of named numeric columns, as read from a CSV file with a header row.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// Where the record came from (used in error messages).
    pub path: PathBuf,
    /// Column names, in file order.
    pub names: Vec<String>,
    /// Column data, one `Vec` per name.
    pub columns: Vec<Vec<f64>>,
    /// How the file was written (separator, decimal commas, comments, units).
    pub format: CsvFormat,
}

/// Read a CSV file with a header row and numeric cells, line by line (the file's text is never
/// held whole: a long record needs its columns' memory, not its text's as well).
pub fn read_csv(path: &Path) -> Result<Record, DataError> {
    use std::io::BufRead;
    super::memory::check_file(path)?;
    let read_error = |source| DataError::Read {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(read_error)?;
    let size = file.metadata().map_or(0, |m| m.len() as usize);
    let lines = std::io::BufReader::with_capacity(1 << 16, file).lines();
    parse_lines(path, lines, size)
}

/// Parse CSV text (see [`read_csv`]); `path` only labels the errors. Beyond a plain
/// comma-separated table it reads what labs write, and says so in [`Record::format`]: comment
/// lines starting with `#` (anywhere), a byte-order mark, a `;` or tab separator (from the
/// header), decimal commas with them, a trailing separator on every line, and units in the
/// header (`displacement [um]`, `u (V)`). Line numbers in errors are the file's.
pub fn parse_csv(path: &Path, text: &str) -> Result<Record, DataError> {
    parse_lines(path, text.lines().map(Ok), text.len())
}

/// [`parse_csv`] over the lines of a text of about `size` bytes, in one pass.
fn parse_lines<L: AsRef<str>>(
    path: &Path,
    lines: impl Iterator<Item = std::io::Result<L>>,
    size: usize,
) -> Result<Record, DataError> {
    let p = || path.to_path_buf();
    let comment = |l: &str| {
        l.trim_start()
            .trim_start_matches('\u{feff}')
            .starts_with('#')
    };
    // blank and comment lines are counted (comments) and, after the first data row, listed
    let mut comment_lines = 0;
    let mut skipped = Vec::new();
    // the line of the first data row (set by the loop below, read by the filter)
    let first_line = std::cell::Cell::new(0);
    let mut lines = lines.enumerate().filter_map(|(idx, l)| match l {
        Err(source) => Some(Err(DataError::Read { path: p(), source })),
        Ok(l) => {
            let line = l.as_ref();
            let is_comment = comment(line);
            comment_lines += usize::from(is_comment);
            if line.trim().is_empty() || is_comment {
                if first_line.get() != 0 {
                    skipped.push(idx + 1);
                }
                None
            } else {
                Some(Ok((idx, l)))
            }
        }
    });
    let (header_at, header) = lines.next().ok_or(DataError::Empty { path: p() })??;
    let header = header.as_ref().trim_start_matches('\u{feff}');
    let sep = separator_of(header);
    let mut raw: Vec<&str> = header.split(sep).collect();
    let trailing_separator = raw.len() > 1 && raw.last().is_some_and(|n| n.trim().is_empty());
    if trailing_separator {
        raw.pop();
    }
    let (names, units): (Vec<String>, Vec<Option<String>>) =
        raw.iter().map(|n| name_and_unit(n)).unzip();
    for (i, n) in names.iter().enumerate() {
        if n.is_empty() {
            return Err(DataError::EmptyHeaderName {
                path: p(),
                line: header_at + 1,
                position: i + 1,
            });
        }
        if names[..i].contains(n) {
            return Err(DataError::DuplicateColumn {
                path: p(),
                line: header_at + 1,
                name: n.clone(),
            });
        }
    }
    let mut decimal_comma = false;
    // (each column its own reservation: a cloned Vec keeps none)
    let rows = size / (8 * names.len()) + 1;
    let mut columns: Vec<Vec<f64>> = (0..names.len()).map(|_| Vec::with_capacity(rows)).collect();
    for next in lines.by_ref() {
        let (idx, line) = next?;
        let line = line.as_ref();
        let line_no = idx + 1;
        if first_line.get() == 0 {
            first_line.set(line_no);
        }
        let mut found = 0;
        for (j, cell) in line.split(sep).enumerate() {
            if j >= names.len() {
                // the trailing separator's empty cell is not a column
                if !(trailing_separator && j == names.len() && cell.trim().is_empty()) {
                    found += 1;
                }
                continue;
            }
            found += 1;
            let cell = cell.trim().trim_matches('"').trim();
            if cell.is_empty() {
                return Err(DataError::MissingCell {
                    path: p(),
                    line: line_no,
                    column: names[j].clone(),
                });
            }
            let parsed = if sep != ',' && cell.contains(',') {
                decimal_comma = true;
                cell.replace(',', ".").parse::<f64>()
            } else {
                cell.parse::<f64>()
            };
            let v: f64 = parsed.map_err(|_| DataError::NotANumber {
                path: p(),
                line: line_no,
                column: names[j].clone(),
                cell: cell.to_string(),
            })?;
            if !v.is_finite() {
                return Err(DataError::NotFinite {
                    path: p(),
                    line: line_no,
                    column: names[j].clone(),
                    cell: cell.to_string(),
                });
            }
            columns[j].push(v);
        }
        if found != names.len() {
            return Err(DataError::RaggedRow {
                path: p(),
                line: line_no,
                expected: names.len(),
                found,
            });
        }
    }
    if columns[0].is_empty() {
        return Err(DataError::Empty { path: p() });
    }
    drop(lines);
    let first_line = first_line.get();
    Ok(Record {
        path: path.to_path_buf(),
        names,
        columns,
        format: CsvFormat {
            separator: sep,
            decimal_comma,
            comment_lines,
            trailing_separator,
            units,
            first_line,
            skipped,
        },
    })
}

/// How a CSV file was written, as read from it: what [`parse_csv`] accepted beyond a plain
/// comma-separated table (said to the user, never guessed silently).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CsvFormat {
    /// The separator, detected from the header: `,`, `;` or a tab.
    pub separator: char,
    /// Decimal commas (`1,5`): read when the separator is `;` or a tab.
    pub decimal_comma: bool,
    /// Comment lines (starting with `#`) skipped.
    pub comment_lines: usize,
    /// Every line ends with a separator (an empty last column, dropped).
    pub trailing_separator: bool,
    /// Per column, the unit written in its header (`displacement [um]`, `u (V)`), taken off the
    /// name.
    pub units: Vec<Option<String>>,
    /// The file's line of the first data row (1-based; 0: not read from a file).
    pub first_line: usize,
    /// Lines after the first data row that hold no row (blank or comment), in order.
    pub skipped: Vec<usize>,
}

impl CsvFormat {
    /// The file's line of data row `row` (0-based), for messages; `row + 2` (after a header
    /// line) for a record not read from a file.
    pub fn line_of(&self, row: usize) -> usize {
        if self.first_line == 0 {
            return row + 2;
        }
        let mut line = self.first_line + row;
        for &s in &self.skipped {
            if s <= line {
                line += 1;
            } else {
                break;
            }
        }
        line
    }
}

impl CsvFormat {
    /// What differs from a plain CSV, in words (empty: a plain CSV).
    pub fn notes(&self, names: &[String]) -> Vec<String> {
        let mut out = Vec::new();
        match self.separator {
            ',' => {}
            '\t' => out.push("tab-separated (from the header)".to_string()),
            c => out.push(format!("`{c}`-separated (from the header)")),
        }
        if self.decimal_comma {
            out.push("decimal commas".into());
        }
        if self.comment_lines > 0 {
            out.push(format!("{} comment line(s) skipped", self.comment_lines));
        }
        if self.trailing_separator {
            out.push("a trailing separator on every line".into());
        }
        let units: Vec<String> = names
            .iter()
            .zip(&self.units)
            .filter_map(|(n, u)| u.as_ref().map(|u| format!("{n} [{u}]")))
            .collect();
        if !units.is_empty() {
            out.push(format!("units taken off the names: {}", units.join(", ")));
        }
        out
    }
}

/// A header name and its unit: `displacement [um]` and `u (V)` are `displacement` in um and
/// `u` in V; a name without a bracketed ending has none.
fn name_and_unit(raw: &str) -> (String, Option<String>) {
    let s = raw.trim().trim_matches('"').trim();
    for (open, close) in [('[', ']'), ('(', ')')] {
        if let Some(body) = s.strip_suffix(close) {
            if let Some(at) = body.rfind(open) {
                let (name, unit) = (body[..at].trim(), body[at + 1..].trim());
                if !name.is_empty() && !unit.is_empty() {
                    return (name.to_string(), Some(unit.to_string()));
                }
            }
        }
    }
    (s.to_string(), None)
}

/// The separator of a header line: a tab or `;` when the line has one and no comma, else `,`.
fn separator_of(header: &str) -> char {
    if header.contains(',') {
        ','
    } else if header.contains('\t') {
        '\t'
    } else if header.contains(';') {
        ';'
    } else {
        ','
    }
}

impl Record {
    /// A record made of arrays (a notebook's): the time stamps `t` (in seconds) and the named
    /// columns, checked as a file's cells are (equal lengths, finite values, distinct names);
    /// `label` stands for the file in errors, whose line numbers are those of the record
    /// written as CSV (header line 1, sample k on line k + 2).
    pub fn from_arrays(
        label: &str,
        t: Vec<f64>,
        columns: Vec<(String, Vec<f64>)>,
    ) -> Result<Record, DataError> {
        let path = PathBuf::from(label);
        let mut names = vec!["t".to_string()];
        let mut data = vec![t];
        for (name, values) in columns {
            if names.contains(&name) {
                return Err(DataError::DuplicateColumn {
                    path,
                    line: 1,
                    name,
                });
            }
            names.push(name);
            data.push(values);
        }
        for (name, col) in names.iter().zip(&data) {
            if col.len() != data[0].len() {
                return Err(DataError::ArrayLength {
                    path,
                    column: name.clone(),
                    found: col.len(),
                    expected: data[0].len(),
                });
            }
            if let Some(k) = col.iter().position(|v| !v.is_finite()) {
                return Err(DataError::NotFinite {
                    path,
                    line: k + 2,
                    column: name.clone(),
                    cell: col[k].to_string(),
                });
            }
        }
        if data[0].is_empty() {
            return Err(DataError::Empty { path });
        }
        Ok(Record {
            path,
            names,
            columns: data,
            format: CsvFormat::default(),
        })
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }

    /// True when the record has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index of a column, or an error that lists the columns there are.
    pub fn index(&self, name: &str) -> Result<usize, DataError> {
        self.names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| DataError::MissingColumn {
                path: self.path.clone(),
                name: name.to_string(),
                available: self.names.join(", "),
            })
    }

    /// A column by name.
    pub fn column(&self, name: &str) -> Result<&[f64], DataError> {
        Ok(&self.columns[self.index(name)?])
    }

    /// The time column: `t` or `time`, else the first column whose name starts with `t_` or
    /// `time_` (as `t_s`, `time_s`).
    pub fn time_column(&self) -> Option<&str> {
        self.names
            .iter()
            .find(|n| n.as_str() == "t" || n.as_str() == "time")
            .or_else(|| {
                self.names
                    .iter()
                    .find(|n| n.starts_with("t_") || n.starts_with("time_"))
            })
            .map(String::as_str)
    }

    /// Every time stamp after the one before (the error names the first line that is not).
    pub fn check_increasing(&self, name: &str, t: &[f64]) -> Result<(), DataError> {
        for k in 1..t.len() {
            if t[k] <= t[k - 1] {
                return Err(DataError::TimeNotIncreasing {
                    path: self.path.clone(),
                    line: k + 2,
                    column: name.to_string(),
                    time: t[k],
                    previous: t[k - 1],
                });
            }
        }
        Ok(())
    }

    /// The sampling period from the time column, checked to be uniform (1 % of a period).
    pub fn sampling_period(&self) -> Result<Option<f64>, DataError> {
        let Some(name) = self.time_column() else {
            return Ok(None);
        };
        let t = self.column(name)?;
        if t.len() < 2 {
            return Ok(None);
        }
        self.check_increasing(name, t)?;
        let n = t.len();
        // the median step is robust against a single gap
        let steps = TimeSteps::of(t);
        let period = steps.median;
        // the first sample off the grid of a period by more than 1 % of a step
        let off_grid = |period: f64| {
            let tol = 0.01 * period;
            t.iter().enumerate().find_map(|(k, &tk)| {
                let deviation = tk - (t[0] + k as f64 * period);
                (deviation.abs() > tol + 1e-9 * tk.abs() * (n as f64).sqrt())
                    .then_some((k, tk, deviation))
            })
        };
        // The median step of times printed with few digits (1/1024 s as 0.000977 once t >= 1 s)
        // is off by the rounding, which adds up over the record; the span's mean step is not.
        // A record uniform on either grid is uniform.
        let span = (t[n - 1] - t[0]) / (n - 1) as f64;
        if let Some((k, tk, deviation)) = off_grid(period) {
            if off_grid(span).is_none() {
                return Ok(Some(span));
            }
            let advice = if steps.gaps.is_empty() {
                "resample it onto a uniform grid (`hystbench split` does, by linear interpolation)"
                    .to_string()
            } else {
                format!(
                        "split it at the gaps into separate records (`hystbench split --data {} --out DIR` writes one uniformly resampled file per part)",
                        self.path.display()
                    )
            };
            return Err(DataError::NonUniformTime {
                path: self.path.clone(),
                line: k + 2,
                column: name.to_string(),
                time: tk,
                period,
                deviation,
                detail: format!(
                    "{}. A record must be uniformly sampled: {advice}",
                    steps.describe()
                ),
            });
        }
        // refine with the whole span: more exact than one step
        Ok(Some(span))
    }
}

/// The time steps of a record: the typical step, the gaps and the jitter.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeSteps {
    /// Median step (s).
    pub median: f64,
    /// Steps longer than [`TimeSteps::GAP`] x the median: (index of the sample after the gap,
    /// step in s).
    pub gaps: Vec<(usize, f64)>,
    /// Largest |step - median| among the other steps (s), and the index where it occurs.
    pub jitter: (f64, usize),
    /// The gap threshold in median steps.
    pub gap: f64,
}

impl TimeSteps {
    /// A step longer than this many median steps is a gap.
    pub const GAP: f64 = 5.0;

    /// Steps of an increasing time column (at least two samples), gaps by [`TimeSteps::GAP`].
    pub fn of(t: &[f64]) -> TimeSteps {
        Self::with_gap(t, Self::GAP)
    }

    /// Steps of an increasing time column; a step longer than `gap` median steps is a gap.
    pub fn with_gap(t: &[f64], gap: f64) -> TimeSteps {
        let steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        let mut sorted = steps.clone();
        let median = if sorted.is_empty() {
            0.0
        } else {
            let mid = sorted.len() / 2;
            *sorted.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        let mut gaps = Vec::new();
        let mut jitter = (0.0, 0);
        for (k, &dt) in steps.iter().enumerate() {
            if dt > gap * median {
                gaps.push((k + 1, dt));
            } else if (dt - median).abs() > jitter.0 {
                jitter = ((dt - median).abs(), k + 1);
            }
        }
        TimeSteps {
            median,
            gaps,
            jitter,
            gap,
        }
    }

    /// The steps in words; lines are CSV lines (header = line 1).
    pub fn describe(&self) -> String {
        let mut s = format!("Median time step {:.6} s", self.median);
        if let Some(&(k, dt)) = self.gaps.iter().max_by(|a, b| a.1.total_cmp(&b.1)) {
            s += &format!(
                "; {} gap(s) longer than {} steps (the largest {:.4} s, before line {})",
                self.gaps.len(),
                self.gap,
                dt,
                k + 2
            );
        }
        if self.jitter.0 > 0.0 {
            s += &format!(
                "; elsewhere steps vary by up to {:.3e} s ({:.1} % of a step, at line {})",
                self.jitter.0,
                100.0 * self.jitter.0 / self.median,
                self.jitter.1 + 2
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Record, DataError> {
        parse_csv(Path::new("x.csv"), s)
    }

    #[test]
    fn reads_header_and_columns() {
        let r = parse("t,u,y\n0,1,2\n0.5,3,4\n").unwrap();
        assert_eq!(r.names, ["t", "u", "y"]);
        assert_eq!(r.column("y").unwrap(), &[2.0, 4.0]);
        assert_eq!(r.sampling_period().unwrap(), Some(0.5));
    }

    /// Times printed with 7 significant digits (a logger's 1/1024 s: 0.0009765625, ...,
    /// 1.000977, 1.001953): the median step (0.000977) is off by the rounding and its grid
    /// drifts off the samples; the record is uniform, and its period is the span's.
    #[test]
    fn times_printed_with_few_digits_are_uniform() {
        let record = |gap: f64| {
            let mut csv = String::from("t,u\n");
            for k in 0..30_000 {
                let t = k as f64 / 1024.0 + if k >= 20_000 { gap } else { 0.0 };
                let digits = if t >= 1.0 {
                    6 - t.log10().floor() as usize
                } else {
                    8
                };
                csv += &format!("{t:.digits$},{k}\n");
            }
            parse(&csv).unwrap()
        };
        let ts = record(0.0).sampling_period().unwrap().unwrap();
        assert!((ts - 1.0 / 1024.0).abs() < 1e-9, "{ts}");
        // a real gap is still refused
        let e = record(0.1).sampling_period().unwrap_err().to_string();
        assert!(e.contains("breaks uniform sampling"), "{e}");
    }

    #[test]
    fn errors_name_line_and_column() {
        let e = parse("t,u\n0,1\n1,abc\n").unwrap_err().to_string();
        assert!(
            e.contains("line 3") && e.contains("`u`") && e.contains("abc"),
            "{e}"
        );
        let e = parse("t,u\n0,1\n1,\n").unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("missing"), "{e}");
        let e = parse("t,u\n0,1\n1,NaN\n").unwrap_err().to_string();
        assert!(e.contains("not finite"), "{e}");
        let e = parse("t,u\n0,1\n1\n").unwrap_err().to_string();
        assert!(e.contains("1 cells"), "{e}");
        let e = parse("t,u\n").unwrap_err().to_string();
        assert!(e.contains("empty"), "{e}");
    }

    #[test]
    fn missing_column_lists_available() {
        let r = parse("t,u\n0,1\n").unwrap();
        let e = r.column("y").unwrap_err().to_string();
        assert!(e.contains("no column `y`") && e.contains("t, u"), "{e}");
    }

    #[test]
    fn gap_in_time_is_reported() {
        let r = parse("t,u\n0,1\n1,1\n2,1\n5,1\n6,1\n").unwrap();
        let e = r.sampling_period().unwrap_err().to_string();
        assert!(e.contains("line 5") && e.contains("split"), "{e}");
    }
}
