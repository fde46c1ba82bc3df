//! hitex-io: the file formats of hitex.
//!
//! * images ([`image_io`]): PNG and JPEG in, PNG out (atomic writes), through
//!   the `image` crate; meshes: Wavefront OBJ through `tobj` ([`obj`]), STL
//!   ([`stl`]), PLY ([`ply`]); scenes: TOML files whose relative paths
//!   resolve against the file's folder ([`scene_file`]);
//! * NURBS models ([`models`]): STEP parts and assemblies ([`step`]), IGES
//!   ([`iges`]), OBJ free-form ([`obj_freeform`]), hitex JSON ([`nurbs_json`]);
//!   point sets to measure against them ([`points`]);
//! * BTFs: the native `.hbtf` ([`btf_file`]), the same compressed by local
//!   PCA ([`btf_pca_file`]) and measured image sets, PNG and OpenEXR
//!   ([`btf_images`]);
//! * terrain: elevation models ([`dem`], several tiles as one: [`mosaic`]),
//!   GeoTIFF rasters and their georeferencing, whole, by windows or by COG
//!   overview ([`geotiff`]), coordinate
//!   systems ([`crs`]) and reprojection ([`reproject`]), tile stores: TMS
//!   folders ([`gst`]) and MBTiles ([`mbtiles`]);
//! * [`limits`]: the memory cap every reader checks a file's claimed sizes
//!   against; [`fuzz`]: one entry point per reader for the fuzz targets.
//!
//! Every error names the file, and the record or key where known.
// a library prints nothing: it returns errors and warnings, or hands notices to a callback
#![cfg_attr(not(test), deny(clippy::print_stdout, clippy::print_stderr))]
#![warn(missing_docs, unreachable_pub)]

pub mod btf_file;
pub mod btf_images;
pub mod btf_pca_file;
pub mod crs;
pub mod dem;
pub mod fuzz;
pub mod geotiff;
pub mod gst;
pub mod iges;
pub mod image_io;
pub mod limits;
pub mod mbtiles;
pub mod models;
pub mod mosaic;
pub mod nurbs_json;
pub mod obj;
pub mod obj_freeform;
pub mod ply;
pub mod points;
pub mod reproject;
pub mod scene_file;
pub mod step;
pub mod stl;
#[cfg(test)]
mod test_dir;

pub use iges::{IgesModel, IgesSurface, load_iges, parse_iges};
pub use image_io::{create_output_dir, decode_image, load_image, output_error, save_png, write_atomic};
pub use obj::load_obj;
pub use scene_file::{FileLoader, load_scene};
pub use step::{StepError, StepModel, StepOptions, load_step, parse_step};

use std::path::PathBuf;
use thiserror::Error;

/// What a file of binary content is, from its first bytes (`a PNG image`,
/// `a TIFF image`, …; `binary data` for content with NUL bytes and no known
/// signature), or `None` for text: so that a reader of text can say what
/// it was given instead of quoting the bytes.
pub fn binary_kind(head: &[u8]) -> Option<&'static str> {
    const SIGNATURES: &[(&[u8], &str)] = &[
        (b"\x89PNG", "a PNG image"),
        (b"II*\0", "a TIFF image"),
        (b"MM\0*", "a TIFF image"),
        (b"II+\0", "a BigTIFF image"),
        (b"\xff\xd8\xff", "a JPEG image"),
        (b"PK\x03\x04", "a zip archive"),
        (b"\x1f\x8b", "a gzip archive"),
        (b"v/1\x01", "an OpenEXR image"),
        (b"HBTF", "an .hbtf BTF"),
        (b"HPCA", "an .hbtf BTF compressed by local PCA"),
        (b"%PDF", "a PDF document"),
        (b"\x93NUMPY", "a NumPy array"),
    ];
    for (sig, kind) in SIGNATURES {
        if head.starts_with(sig) {
            return Some(kind);
        }
    }
    head.iter().take(4096).any(|&b| b == 0).then_some("binary data")
}

/// Data that cannot be read or used, with no file to name: bytes or text
/// handed to a reader (`parse_*`; the `load_*` functions name the file as
/// well, [`IoError::Format`] through [`DataError::in_file`]), or a raster
/// that cannot be reprojected, tiled or encoded as asked.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{message}")]
pub struct DataError {
    /// What is wrong, with record, field or line where known.
    pub message: String,
}

impl From<String> for DataError {
    fn from(message: String) -> Self {
        Self { message }
    }
}

impl DataError {
    /// The error as one in `path`.
    pub fn in_file(self, path: &std::path::Path) -> IoError {
        IoError::Format { path: path.to_path_buf(), message: self.message }
    }
}

/// A file that could not be read, parsed or written.
#[derive(Debug, Error)]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The file was read but its content is not valid.
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong, with record or line where known.
        message: String,
    },
    /// An output file could not be written.
    #[error("cannot write {path}: {message}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// The output location cannot hold a file: a path through a file, a
    /// missing device, a name the file system refuses (the user's path is
    /// wrong, as opposed to a write that failed).
    #[error("cannot write {path}: {message}")]
    Destination {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// A validation error from the core, without a file yet.
    #[error("{0}")]
    Core(#[from] hitex_core::CoreError),
}

impl IoError {
    /// Attaches a file to a core error (other errors already carry one).
    pub fn in_file(self, path: &std::path::Path) -> Self {
        match self {
            IoError::Core(e) => IoError::Format { path: path.to_path_buf(), message: e.to_string() },
            other => other,
        }
    }
}
