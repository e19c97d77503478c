//! Atomic writes: a temporary file beside the target, then a rename, so a failure never leaves a
//! partial file; an existing file is kept unless the caller forces.

use super::DataError;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Fail early if `path` exists (without `force`) or its folder does not.
pub fn check_writable(path: &Path, force: bool) -> Result<(), DataError> {
    if path.exists() && !force {
        return Err(DataError::Exists {
            path: path.to_path_buf(),
        });
    }
    let dir = parent(path);
    if !dir.is_dir() {
        return Err(DataError::Write {
            path: path.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!("folder {} does not exist", dir.display()),
            ),
        });
    }
    Ok(())
}

fn parent(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    parent(path).join(format!(".{name}.tmp-{}", std::process::id()))
}

/// Files staged in temporaries and renamed into place together by [`OutputGuard::commit`];
/// dropped uncommitted, the temporaries are removed.
#[derive(Debug, Default)]
pub struct OutputGuard {
    staged: Vec<(PathBuf, PathBuf)>,
    force: bool,
}

impl OutputGuard {
    /// A new guard; `force` allows replacing existing files.
    pub fn new(force: bool) -> Self {
        OutputGuard {
            staged: Vec::new(),
            force,
        }
    }

    /// Stage `bytes` for `path`.
    pub fn stage(&mut self, path: &Path, bytes: &[u8]) -> Result<(), DataError> {
        self.stage_with(path, |w| w.write_all(bytes))
    }

    /// Stage the CSV of `columns` (headed by `names`) for `path`, written row by row: the text
    /// is never held whole (a long record's is about 20 bytes a value). Non-finite values are
    /// refused before anything is written, as [`format_csv`] refuses them.
    pub fn stage_csv(
        &mut self,
        path: &Path,
        names: &[String],
        columns: &[Vec<f64>],
    ) -> Result<(), DataError> {
        check_finite(path, names, columns)?;
        self.stage_with(path, |w| write_rows(w, names, columns))
    }

    /// Stage what `write` writes for `path` (buffered, into a temporary beside it, which the
    /// guard removes when it is dropped uncommitted, a failed write included).
    fn stage_with(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<(), DataError> {
        check_writable(path, self.force)?;
        let tmp = temp_path(path);
        let werr = |source| DataError::Write {
            path: path.to_path_buf(),
            source,
        };
        let f = std::fs::File::create(&tmp).map_err(werr)?;
        self.staged.push((tmp, path.to_path_buf()));
        let mut w = std::io::BufWriter::with_capacity(1 << 20, f);
        write(&mut w).map_err(werr)?;
        let f = w.into_inner().map_err(|e| werr(e.into_error()))?;
        f.sync_all().map_err(werr)
    }

    /// Rename every staged file into place.
    pub fn commit(mut self) -> Result<(), DataError> {
        for (tmp, path) in std::mem::take(&mut self.staged) {
            std::fs::rename(&tmp, &path).map_err(|source| DataError::Write {
                path: path.clone(),
                source,
            })?;
        }
        Ok(())
    }
}

impl Drop for OutputGuard {
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Write `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8], force: bool) -> Result<(), DataError> {
    let mut g = OutputGuard::new(force);
    g.stage(path, bytes)?;
    g.commit()
}

/// Format columns as CSV text, refusing non-finite values (the text of
/// [`OutputGuard::stage_csv`]).
pub fn format_csv(
    path: &Path,
    names: &[String],
    columns: &[Vec<f64>],
) -> Result<String, DataError> {
    check_finite(path, names, columns)?;
    let n = columns.first().map_or(0, Vec::len);
    let mut s = Vec::with_capacity(n * names.len() * 20);
    write_rows(&mut s, names, columns).expect("writing to memory");
    Ok(String::from_utf8(s).expect("numbers and the caller's names are UTF-8"))
}

/// The first non-finite value of `columns` in row order (the row the file would have it on);
/// columns of unequal lengths are refused first.
fn check_finite(path: &Path, names: &[String], columns: &[Vec<f64>]) -> Result<(), DataError> {
    let n = columns.first().map_or(0, Vec::len);
    if let Some(j) = (0..columns.len()).find(|&j| columns[j].len() != n) {
        return Err(DataError::ArrayLength {
            path: path.to_path_buf(),
            column: names.get(j).cloned().unwrap_or_default(),
            found: columns[j].len(),
            expected: n,
        });
    }
    let first = columns
        .iter()
        .enumerate()
        .filter_map(|(j, c)| c.iter().position(|v| !v.is_finite()).map(|k| (k, j)))
        .min();
    match first {
        Some((k, j)) if k < n => Err(DataError::NonFiniteOutput {
            path: path.to_path_buf(),
            column: names[j].clone(),
            row: k + 1,
            value: columns[j][k],
        }),
        _ => Ok(()),
    }
}

/// The header and one line per sample: values in Rust's shortest round-trip form.
fn write_rows(w: &mut dyn Write, names: &[String], columns: &[Vec<f64>]) -> std::io::Result<()> {
    let n = columns.first().map_or(0, Vec::len);
    writeln!(w, "{}", names.join(","))?;
    for k in 0..n {
        for (j, c) in columns.iter().enumerate() {
            if j > 0 {
                w.write_all(b",")?;
            }
            write!(w, "{}", c[k])?;
        }
        w.write_all(b"\n")?;
    }
    Ok(())
}

/// Write columns as CSV atomically.
pub fn write_csv_atomic(
    path: &Path,
    names: &[String],
    columns: &[Vec<f64>],
    force: bool,
) -> Result<(), DataError> {
    let mut g = OutputGuard::new(force);
    g.stage_csv(path, names, columns)?;
    g.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_to_overwrite_without_force_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        write_atomic(&p, b"one", false).unwrap();
        assert!(matches!(
            write_atomic(&p, b"two", false),
            Err(DataError::Exists { .. })
        ));
        assert_eq!(std::fs::read(&p).unwrap(), b"one");
        write_atomic(&p, b"two", true).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_streamed_csv_is_the_formatted_text() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        let names = vec!["t".to_string(), "y".to_string()];
        let cols = vec![vec![0.0, 0.001, 0.002], vec![1.5, -2.25e-7, 1e3]];
        write_csv_atomic(&p, &names, &cols, false).unwrap();
        let text = format_csv(&p, &names, &cols).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), text);
        assert_eq!(text, "t,y\n0,1.5\n0.001,-0.000000225\n0.002,1000\n");
    }

    #[test]
    fn non_finite_values_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        let e = write_csv_atomic(&p, &["y".into()], &[vec![1.0, f64::NAN]], false).unwrap_err();
        assert!(e.to_string().contains("row 2"), "{e}");
        assert!(!p.exists());
        // the first in row order, whatever the column
        let cols = [vec![1.0, 2.0, f64::INFINITY], vec![1.0, f64::NAN, 3.0]];
        let e = format_csv(&p, &["a".into(), "b".into()], &cols).unwrap_err();
        assert!(
            e.to_string().contains("row 2") && e.to_string().contains("`b`"),
            "{e}"
        );
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
