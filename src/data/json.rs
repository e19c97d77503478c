//! Reading the JSON files (plants, scenarios, grey-box and NARX models): one way to read the
//! text, to say where a parse failed, and to read a model file's `format` and `version` before
//! the rest.

use serde::de::DeserializeOwned;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A JSON file that cannot be read, or whose text does not parse into what it should hold.
#[derive(Debug, thiserror::Error)]
pub enum JsonFileError {
    #[error("{path}: cannot read: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Line and column from 1, where the parser stopped.
    #[error("{path}: line {line}, column {column}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
}

/// Whether a field holds its type's default (`serde(skip_serializing_if)`): a file leaves out
/// an optional field at its default, so that files written before the field read the same.
pub fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

/// Reads a JSON file's text; the error names the file.
pub fn read_json_text(path: &Path) -> Result<String, JsonFileError> {
    std::fs::read_to_string(path).map_err(|source| JsonFileError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// Parses a JSON file's text into `T` (a key given twice in a struct is refused); `path` labels
/// the error, which says the line and column.
pub fn parse_json_file<T: DeserializeOwned>(path: &Path, text: &str) -> Result<T, JsonFileError> {
    serde_json::from_str(text).map_err(|e| JsonFileError::Parse {
        path: path.to_path_buf(),
        line: e.line(),
        column: e.column(),
        // serde's message without its own " at line .. column .." suffix
        message: e
            .to_string()
            .split(" at line")
            .next()
            .unwrap_or_default()
            .to_string(),
    })
}

/// Reads and parses a JSON file.
pub fn read_json_file<T: DeserializeOwned>(path: &Path) -> Result<T, JsonFileError> {
    parse_json_file(path, &read_json_text(path)?)
}

/// A model file's `format` and `version`, read before the rest so that another kind of file or
/// another version is said as such (other fields are passed over).
#[derive(Debug, Clone, Deserialize)]
pub struct FileHeader {
    pub format: Option<serde_json::Value>,
    pub version: Option<serde_json::Value>,
}

impl FileHeader {
    pub fn read(path: &Path, text: &str) -> Result<FileHeader, JsonFileError> {
        parse_json_file(path, text)
    }

    /// `format` when it is a string.
    pub fn format_str(&self) -> Option<&str> {
        self.format.as_ref().and_then(|f| f.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    #[allow(dead_code)]
    struct Two {
        a: f64,
        b: f64,
    }

    #[test]
    fn errors_name_the_file_line_and_column() {
        let p = Path::new("x.json");
        let e = parse_json_file::<Two>(p, "{\n  \"a\": 1,\n  \"a\": 2\n}").unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.json: line 3, column 5: duplicate field `a`"
        );
        let e = parse_json_file::<Two>(p, "{\"a\": 1,").unwrap_err();
        assert!(
            e.to_string().starts_with("x.json: line 1, column 8: EOF"),
            "{e}"
        );
        let e = read_json_file::<Two>(Path::new("/no/such/file.json")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("/no/such/file.json: cannot read: "),
            "{e}"
        );
        let h = FileHeader::read(p, "{\"format\": \"f\", \"x\": [1], \"version\": 2}").unwrap();
        assert_eq!(h.format_str(), Some("f"));
        assert_eq!(h.version, Some(2.into()));
    }
}
