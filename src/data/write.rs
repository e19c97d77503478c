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
        check_writable(path, self.force)?;
        let tmp = temp_path(path);
        let werr = |source| DataError::Write {
            path: path.to_path_buf(),
            source,
        };
        let mut f = std::fs::File::create(&tmp).map_err(werr)?;
        f.write_all(bytes).map_err(werr)?;
        f.sync_all().map_err(werr)?;
        self.staged.push((tmp, path.to_path_buf()));
        Ok(())
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

/// Format columns as CSV text, refusing non-finite values.
pub fn format_csv(path: &Path, names: &[String], columns: &[Vec<f64>]) -> Result<String, DataError> {
    let n = columns.first().map_or(0, Vec::len);
    let mut s = String::with_capacity(n * names.len() * 20);
    s.push_str(&names.join(","));
    s.push('\n');
    for k in 0..n {
        for (j, c) in columns.iter().enumerate() {
            let v = c[k];
            if !v.is_finite() {
                return Err(DataError::NonFiniteOutput {
                    path: path.to_path_buf(),
                    column: names[j].clone(),
                    row: k + 1,
                    value: v,
                });
            }
            if j > 0 {
                s.push(',');
            }
            use std::fmt::Write as _;
            let _ = write!(s, "{v}");
        }
        s.push('\n');
    }
    Ok(s)
}

/// Write columns as CSV atomically.
pub fn write_csv_atomic(
    path: &Path,
    names: &[String],
    columns: &[Vec<f64>],
    force: bool,
) -> Result<(), DataError> {
    let text = format_csv(path, names, columns)?;
    write_atomic(path, text.as_bytes(), force)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_to_overwrite_without_force_and_leaves_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        write_atomic(&p, b"one", false).unwrap();
        assert!(matches!(write_atomic(&p, b"two", false), Err(DataError::Exists { .. })));
        assert_eq!(std::fs::read(&p).unwrap(), b"one");
        write_atomic(&p, b"two", true).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn non_finite_values_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        let e = write_csv_atomic(&p, &["y".into()], &[vec![1.0, f64::NAN]], false).unwrap_err();
        assert!(e.to_string().contains("row 2"), "{e}");
        assert!(!p.exists());
    }
}
