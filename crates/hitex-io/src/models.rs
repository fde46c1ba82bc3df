//! NURBS models available by name (the paper's Table 1), and model loading
//! from files.

use crate::IoError;
use crate::iges::{IgesModel, IgesSurface, parse_iges};
use hitex_core::nurbs::NurbsSurface;
use std::path::Path;

/// The Utah teapot as 32 bicubic IGES entity-128 surfaces (embedded).
pub const TEAPOT_IGES: &str = include_str!("../data/teapot.igs");

/// Names accepted by [`load_model`] besides file paths.
pub const MODEL_NAMES: [&str; 3] = ["surface", "teapot", "spray"];

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
    /// What the reader found, for a summary (STEP: schema, units, surface
    /// types, instances, the chord tolerance of the trims).
    pub notes: Vec<String>,
    /// Faces by kind of surface in the file (STEP: plane, cylinder, …, skipped
    /// faces included); empty for formats of B-spline patches only.
    pub census: std::collections::BTreeMap<&'static str, usize>,
    /// The length unit where the file states one (STEP: "mm", "inch", …).
    pub units: Option<String>,
    /// Each patch's colour (linear RGB) where the file gives one (STEP
    /// styles); empty: none.
    pub colors: Vec<Option<[f32; 3]>>,
}

impl NurbsModel {
    /// The surfaces alone.
    pub fn nurbs(&self) -> Vec<NurbsSurface> {
        self.surfaces.iter().map(|s| s.surface.clone()).collect()
    }
    /// Each patch's trim loops in its parameter space (empty: untrimmed).
    pub fn trims(&self) -> Vec<Vec<Vec<[f64; 2]>>> {
        self.surfaces.iter().map(|s| s.trim.clone()).collect()
    }

    /// The parameter ranges.
    pub fn ranges(&self) -> Vec<((f64, f64), (f64, f64))> {
        self.surfaces.iter().map(|s| s.range).collect()
    }
}

fn from_iges(name: &str, m: IgesModel) -> NurbsModel {
    NurbsModel {
        name: name.to_string(),
        surfaces: m.surfaces,
        warnings: m.warnings,
        repairs: m.repairs,
        notes: vec![],
        census: Default::default(),
        units: m.units,
        colors: m.colors,
    }
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

/// One patch of a swept part: control points sampled on `f(a, t)` over
/// `a ∈ [a0, a1]`, `t ∈ [t0, t1]`, bicubic, with interior knots spaced
/// unevenly so that the knot vectors are non-uniform.
fn swept_patch(
    f: &dyn Fn(f64, f64) -> [f64; 3],
    (a0, a1): (f64, f64),
    (t0, t1): (f64, f64),
    nu: usize,
    nv: usize,
) -> NurbsSurface {
    let knots = |n: usize| -> Vec<f64> {
        let inner = n - 4;
        let mut k = vec![0.0; 4];
        for i in 1..=inner {
            let x = i as f64 / (inner + 1) as f64;
            k.push(x + 0.25 * x * (1.0 - x) * (if i % 2 == 0 { 1.0 } else { -1.0 }) / (inner + 1) as f64);
        }
        k.extend([1.0; 4]);
        k
    };
    let (ku, kv) = (knots(nu), knots(nv));
    // Greville abscissae place each control point where it pulls hardest
    let greville = |k: &[f64], i: usize| (k[i + 1] + k[i + 2] + k[i + 3]) / 3.0;
    let mut pts = Vec::with_capacity(nu * nv);
    for j in 0..nv {
        for i in 0..nu {
            let a = a0 + (a1 - a0) * greville(&ku, i);
            let t = t0 + (t1 - t0) * greville(&kv, j);
            let p = f(a, t);
            pts.push([p[0], p[1], p[2], 1.0]);
        }
    }
    match NurbsSurface::new(3, 3, nu, nv, ku, kv, pts) {
        Ok(s) => s,
        Err(e) => unreachable!("swept patches are valid: {e}"),
    }
}

/// The `spray` model of Table 1: a spray bottle of 266 bicubic patches with
/// 6×6 to 18×18 control points (10 to 22 knots per direction), built from
/// five swept parts, each split into sectors around its axis and bands along it:
///
/// | part | sweep | patches | control points |
/// |---|---|---|---|
/// | body | revolution about z, slight waist | 8 × 12 = 96 | 6×6 |
/// | shoulder | revolution, radius 1.3 → 0.55 | 8 × 4 = 32 | 8×8 |
/// | cap | revolution, rounded top | 8 × 6 = 48 | 10×10 |
/// | nozzle | tube along x | 6 × 9 = 54 | 12×12 |
/// | trigger | bent tube under the nozzle | 6 × 6 = 36 | 18×18 |
///
/// Neighbouring patches share their boundary control points, so the parts
/// are watertight along patch seams.
pub fn spray() -> Vec<NurbsSurface> {
    use std::f64::consts::{PI, TAU};
    type Part = Box<dyn Fn(f64, f64) -> [f64; 3]>;
    let revolve = |r: Box<dyn Fn(f64) -> f64>, z: Box<dyn Fn(f64) -> f64>| -> Part {
        Box::new(move |a: f64, t: f64| [r(t) * a.cos(), r(t) * a.sin(), z(t)])
    };
    let body = revolve(Box::new(|t| 1.3 - 0.12 * (PI * t).sin() + 0.05 * (3.0 * PI * t).sin()), Box::new(|t| 6.0 * t));
    let shoulder = revolve(Box::new(|t| 0.55 + 0.75 * (0.5 * PI * t).cos().powi(2)), Box::new(|t| 6.0 + 1.0 * t));
    let cap = revolve(
        Box::new(|t| if t < 0.8 { 0.55 } else { 0.55 * (1.0 - ((t - 0.8) / 0.2).powi(2)).max(0.0).sqrt().max(0.02) }),
        Box::new(|t| 7.0 + 1.2 * t),
    );
    // nozzle: a tube along +x at height 7.9
    let nozzle: Part = Box::new(|a: f64, t: f64| {
        let r = 0.22 + 0.05 * (PI * t).sin();
        [0.3 + 1.6 * t, r * a.cos(), 7.9 + r * a.sin()]
    });
    // trigger: a tube bent down and forward under the nozzle
    let trigger: Part = Box::new(|a: f64, t: f64| {
        let phi = 0.15 * PI + 0.6 * PI * t;
        let (cx, cz) = (0.9 + 0.9 * phi.sin(), 7.6 - 0.9 * (1.0 - phi.cos()));
        let r = 0.12 + 0.04 * (PI * t).sin();
        // tube cross-section in the plane spanned by the path normal and y
        let (nx, nz) = (phi.sin(), phi.cos());
        [cx + r * a.cos() * nx, r * a.sin(), cz + r * a.cos() * nz]
    });
    let parts: [(Part, usize, usize, usize); 5] =
        [(body, 8, 12, 6), (shoulder, 8, 4, 8), (cap, 8, 6, 10), (nozzle, 6, 9, 12), (trigger, 6, 6, 18)];
    let mut out = Vec::with_capacity(266);
    for (f, sectors, bands, n) in parts.iter() {
        for b in 0..*bands {
            for s in 0..*sectors {
                let a = (TAU * s as f64 / *sectors as f64, TAU * (s + 1) as f64 / *sectors as f64);
                let t = (b as f64 / *bands as f64, (b + 1) as f64 / *bands as f64);
                out.push(swept_patch(f.as_ref(), a, t, *n, *n));
            }
        }
    }
    out
}

/// How files become models.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LoadOptions {
    /// STEP: the chord tolerance of the trims, in model units (see
    /// [`crate::step::StepOptions`]); `None`: 1/10 000 of the model's size.
    pub chord_tolerance: Option<f64>,
}

/// Loads a model by name (`surface`, `teapot`, `spray`), from a STEP or IGES
/// file, a Wavefront OBJ free-form file, or hitex's native JSON.
pub fn load_model(spec: &str) -> Result<NurbsModel, IoError> {
    load_model_with(spec, &LoadOptions::default())
}

/// [`load_model`] with options.
pub fn load_model_with(spec: &str, opts: &LoadOptions) -> Result<NurbsModel, IoError> {
    match spec {
        "teapot" => {
            let m = parse_iges(TEAPOT_IGES, "teapot (embedded teapot.igs)")
                .map_err(|e| IoError::Format { path: "teapot".into(), message: e.to_string() })?;
            Ok(from_iges("teapot", m))
        }
        "spray" => {
            let surfaces = spray()
                .into_iter()
                .map(|s| {
                    let range = s.domain();
                    IgesSurface { surface: s, range, directory_entry: 0, trim: Vec::new() }
                })
                .collect();
            Ok(NurbsModel {
                name: "spray".into(),
                surfaces,
                warnings: vec![],
                repairs: vec![],
                notes: vec![],
                census: Default::default(),
                units: None,
                colors: vec![],
            })
        }
        "surface" => {
            let s = single_surface();
            let range = s.domain();
            Ok(NurbsModel {
                name: "surface".into(),
                surfaces: vec![IgesSurface { surface: s, range, directory_entry: 0, trim: Vec::new() }],
                warnings: vec![],
                repairs: vec![],
                notes: vec![],
                census: Default::default(),
                units: None,
                colors: vec![],
            })
        }
        path => {
            let p = Path::new(path);
            let ext = p.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
            match ext.as_deref() {
                Some("obj") => {
                    let (surfaces, warnings) = crate::obj_freeform::load_obj_freeform_warned(p)?;
                    Ok(NurbsModel {
                        name: path.to_string(),
                        surfaces,
                        warnings,
                        repairs: vec![],
                        notes: vec![],
                        census: Default::default(),
                        units: None,
                        colors: vec![],
                    })
                }
                Some("json") => {
                    let m = crate::nurbs_json::load_nurbs_json(p)?;
                    Ok(NurbsModel {
                        name: path.to_string(),
                        surfaces: m.surfaces,
                        warnings: vec![],
                        repairs: vec![],
                        notes: vec![],
                        census: Default::default(),
                        units: m.units,
                        colors: m.colors,
                    })
                }
                Some("stp") | Some("step") | Some("p21") => {
                    let m =
                        crate::step::load_step(p, &crate::step::StepOptions { chord_tolerance: opts.chord_tolerance })
                            .map_err(|e| IoError::Format {
                                path: p.to_path_buf(),
                                message: e.to_string().replacen(&format!("{path}: "), "", 1),
                            })?;
                    let types: Vec<String> = m.surface_types.iter().map(|(t, n)| format!("{n} {t}")).collect();
                    let notes = vec![
                        format!(
                            "STEP {}, lengths in {}",
                            if m.schema.is_empty() { "(no schema)" } else { &m.schema },
                            m.length_unit
                        ),
                        format!(
                            "faces: {}; {} placed in {}",
                            types.join(", "),
                            m.surfaces.len(),
                            if m.instances == 1 {
                                "1 part instance".to_string()
                            } else {
                                format!("{} part instances", m.instances)
                            }
                        ),
                        format!(
                            "trims sampled to a chord of {:.3e} {} ({})",
                            m.chord_tolerance,
                            m.length_unit,
                            if opts.chord_tolerance.is_some() {
                                "--chord"
                            } else {
                                "1/10 000 of the model's size; --chord to set"
                            }
                        ),
                    ];
                    Ok(NurbsModel {
                        name: path.to_string(),
                        surfaces: m.surfaces,
                        warnings: m.warnings,
                        repairs: m.repairs,
                        notes,
                        census: m.census,
                        units: Some(m.length_unit),
                        colors: m.colors,
                    })
                }
                Some("igs") | Some("iges") => {
                    let m = crate::iges::load_iges(p).map_err(|e| IoError::Format {
                        path: p.to_path_buf(),
                        message: if e.location.is_empty() {
                            e.message
                        } else {
                            format!("{}: {}", e.location, e.message)
                        },
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
                    let message =
                        "unsupported NURBS format (expected .stp, .step, .igs, .iges, free-form .obj or hitex's .json)"
                            .to_string();
                    Err(IoError::Format { path: p.to_path_buf(), message })
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_1_models_have_their_sizes() {
        let s = load_model("surface").unwrap();
        assert_eq!(s.surfaces.len(), 1);
        assert_eq!((s.surfaces[0].surface.count_u, s.surfaces[0].surface.count_v), (6, 14));
        let t = load_model("teapot").unwrap();
        assert_eq!(t.surfaces.len(), 32);
        let sp = load_model("spray").unwrap();
        assert_eq!(sp.surfaces.len(), 266);
        let max_cp = sp.surfaces.iter().map(|p| p.surface.count_u.max(p.surface.count_v)).max().unwrap();
        assert_eq!(max_cp, 18);
        // patches of one part meet without gaps along their shared edges
        let a = &sp.surfaces[0].surface;
        let b = &sp.surfaces[1].surface;
        for k in 0..=10 {
            let v = k as f64 / 10.0;
            let (p, q) = (a.point(1.0, v), b.point(0.0, v));
            assert!((0..3).all(|i| (p[i] - q[i]).abs() < 1e-12), "{p:?} vs {q:?}");
        }
    }

    #[test]
    fn unknown_models_and_formats_are_clear_errors() {
        let e = load_model("kettle").unwrap_err().to_string();
        assert!(e.contains("kettle") && e.contains("teapot"), "{e}");
        let e = load_model("/no/such/model.igs").unwrap_err().to_string();
        assert!(e.contains("model.igs"), "{e}");
    }
}
