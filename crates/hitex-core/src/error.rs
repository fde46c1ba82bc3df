//! Errors of the core crate.

use thiserror::Error;

/// Invalid data handed to the core: always the caller's (or the file's) fault,
/// never an internal failure. Messages name the offending key or record.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CoreError {
    /// A value that must be finite is NaN or infinite.
    #[error("{key}: value is not finite ({value})")]
    NotFinite {
        /// The key or record.
        key: String,
        /// The value found.
        value: f64,
    },
    /// A value outside its allowed range.
    #[error("{key}: {message}")]
    OutOfRange {
        /// The key or record.
        key: String,
        /// The allowed range, and what was found.
        message: String,
    },
    /// The camera cannot form a view (target at the eye, zero or flat field of view, ...).
    #[error("degenerate camera: {0}")]
    DegenerateCamera(String),
    /// A mesh that cannot be drawn (no triangles, indices out of range, ...).
    #[error("invalid mesh '{name}': {message}")]
    InvalidMesh {
        /// The mesh.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// An image with impossible dimensions or data size.
    #[error("invalid image: {0}")]
    InvalidImage(String),
    /// A scene file that parses but refers to something that does not exist.
    #[error("{key}: {message}")]
    InvalidScene {
        /// The key.
        key: String,
        /// What it refers to, and why that fails.
        message: String,
    },
    /// A TOML syntax or type error (line and column are in the message).
    #[error("{0}")]
    Toml(String),
    /// A resident-map cache that cannot start: its level-0 map does not
    /// load (the loader's message), or its loader thread cannot be made.
    #[error("{0}")]
    Residency(String),
    /// A flight path whose keys cannot be flown (the key's index and what
    /// is wrong are in the message).
    #[error("{0}")]
    FlightPath(String),
}

/// Checks that `v` is finite, naming `key` in the error.
pub fn finite(key: &str, v: f64) -> Result<f64, CoreError> {
    if v.is_finite() { Ok(v) } else { Err(CoreError::NotFinite { key: key.to_string(), value: v }) }
}

/// Checks every component of a 3-vector, naming `key[i]` in the error.
pub fn finite3(key: &str, v: [f32; 3]) -> Result<glam::Vec3, CoreError> {
    for (i, c) in v.iter().enumerate() {
        finite(&format!("{key}[{i}]"), *c as f64)?;
    }
    Ok(glam::Vec3::from_array(v))
}
