//! Reading the JSON files (plants, scenarios, grey-box and NARX models): one way to read the
//! text and to say where a parse failed.

use std::path::Path;

/// Where and why a JSON text failed to parse (line and column from 1).
#[derive(Debug, Clone, PartialEq)]
pub struct JsonPosition {
    pub line: usize,
    pub column: usize,
    /// serde's message without its own " at line .. column .." suffix.
    pub message: String,
}

impl From<serde_json::Error> for JsonPosition {
    fn from(e: serde_json::Error) -> Self {
        JsonPosition {
            line: e.line(),
            column: e.column(),
            message: e
                .to_string()
                .split(" at line")
                .next()
                .unwrap_or_default()
                .to_string(),
        }
    }
}

/// Parse a JSON text into `T`; the error says where.
pub fn parse_json<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, JsonPosition> {
    serde_json::from_str(text).map_err(JsonPosition::from)
}

/// Read a file's text.
pub fn read_text(path: &Path) -> Result<String, std::io::Error> {
    std::fs::read_to_string(path)
}
