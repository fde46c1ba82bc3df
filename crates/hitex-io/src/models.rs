//! NURBS models available by name (the paper's Table 1), and model loading
//! from files.

use crate::IoError;
use crate::iges::{IgesModel, IgesSurface, parse_iges};
use hitex_core::nurbs::NurbsSurface;
use std::path::Path;

/// The Utah teapot as 32 bicubic IGES entity-128 surfaces (embedded).
pub const TEAPOT_IGES: &str = include_str!("../data/teapot.igs");

/// Names accepted by [`load_model`] besides file paths.
pub const MODEL_NAMES: [&str; 2] = ["surface", "teapot"];

/// A loaded model: surfaces with their parameter ranges, and the reader's notes.
#[derive(Debug, Clone)]
pub struct NurbsModel {
    /// Where it came from.
    pub name: String,
    /// The patches.
    pub surfaces: Vec<IgesSurface>,
    /// Skipped entities.
    pub warnings: Vec<String>,
    /// Repairs made while reading.
    pub repairs: Vec<String>,
}

impl NurbsModel {
    /// The surfaces alone.
    pub fn nurbs(&self) -> Vec<NurbsSurface> {
        self.surfaces.iter().map(|s| s.surface.clone()).collect()
    }
    /// The parameter ranges.
    pub fn ranges(&self) -> Vec<((f64, f64), (f64, f64))> {
        self.surfaces.iter().map(|s| s.range).collect()
    }
}

fn from_iges(name: &str, m: IgesModel) -> NurbsModel {
    NurbsModel { name: name.to_string(), surfaces: m.surfaces, warnings: m.warnings, repairs: m.repairs }
}

/// The `surface` model of Table 1: one rational bicubic patch of 6×14 control
/// points with non-uniform knots — a wavy, saddle-shaped panel whose weights
/// vary, so that curvature and reflection lines have something to show.
pub fn single_surface() -> NurbsSurface {
    let (nu, nv) = (6usize, 14usize);
    let mut pts = Vec::with_capacity(nu * nv);
    for j in 0..nv {
        for i in 0..nu {
            let x = i as f64 / (nu - 1) as f64 * 4.0 - 2.0;
            let y = j as f64 / (nv - 1) as f64 * 9.0 - 4.5;
            let z = 0.35 * x * x - 0.12 * y * y + 0.45 * (0.9 * y).sin() + 0.2 * (1.7 * x).cos();
            let w = 1.0 + 0.35 * (((i * 7 + j * 3) % 5) as f64 / 4.0);
            pts.push([x, y, z, w]);
        }
    }
    let ku = vec![0.0, 0.0, 0.0, 0.0, 0.3, 0.62, 1.0, 1.0, 1.0, 1.0];
    let kv = vec![0.0, 0.0, 0.0, 0.0, 0.06, 0.15, 0.21, 0.33, 0.42, 0.5, 0.61, 0.7, 0.77, 0.9, 1.0, 1.0, 1.0, 1.0];
    match NurbsSurface::new(3, 3, nu, nv, ku, kv, pts) {
        Ok(s) => s,
        Err(e) => unreachable!("the built-in surface is valid: {e}"),
    }
}

/// Loads a model by name (`surface`, `teapot`) or from an IGES file.
pub fn load_model(spec: &str) -> Result<NurbsModel, IoError> {
    match spec {
        "teapot" => {
            let m = parse_iges(TEAPOT_IGES, "teapot (embedded teapot.igs)")
                .map_err(|e| IoError::Format { path: "teapot".into(), message: e.to_string() })?;
            Ok(from_iges("teapot", m))
        }
        "surface" => {
            let s = single_surface();
            let range = s.domain();
            Ok(NurbsModel {
                name: "surface".into(),
                surfaces: vec![IgesSurface { surface: s, range, directory_entry: 0 }],
                warnings: vec![],
                repairs: vec![],
            })
        }
        path => {
            let p = Path::new(path);
            let ext = p.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
            match ext.as_deref() {
                Some("igs") | Some("iges") => {
                    let m = crate::iges::load_iges(p).map_err(|e| IoError::Format {
                        path: p.to_path_buf(),
                        message: format!("{}: {}", e.location, e.message),
                    })?;
                    Ok(from_iges(path, m))
                }
                _ => {
                    if !p.exists() {
                        return Err(IoError::Format {
                            path: p.to_path_buf(),
                            message: format!("no such file, and not a model name ({})", MODEL_NAMES.join(", ")),
                        });
                    }
                    Err(IoError::Format {
                        path: p.to_path_buf(),
                        message: "unsupported NURBS format (expected .igs or .iges)".into(),
                    })
                }
            }
        }
    }
}
