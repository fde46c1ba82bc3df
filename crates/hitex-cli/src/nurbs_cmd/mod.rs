//! `hitex nurbs …`: exact per-pixel NURBS surfaces.

use crate::{Backend, CliError, open_renderer, parse_size, render_frame, save};
use clap::{Args, Subcommand};
use glam::Vec3;
use hitex_io::models::{NurbsModel, load_model};
use hitex_render::nurbs::{Density, MeshCut, ModelView, NurbsMode, PreparedNurbs, UpAxis};
use hitex_render::{Job, Renderer};
use std::path::PathBuf;
use std::time::Instant;

mod check;
mod deviation;
pub use check::*;
pub use deviation::*;

/// `hitex nurbs` subcommands (parsed once a run: the size of the largest
/// costs nothing worth a box).
#[derive(Subcommand)]
#[allow(clippy::large_enum_variant)]
pub enum NurbsCommand {
    /// Render a model (`surface`, `teapot`) or an IGES file.
    Render(RenderArgs),
    /// Patches, degrees, counts, bounds, and what the reader repaired.
    Info {
        /// Model name or file (.stp/.step, .igs/.iges, .obj, .json).
        model: String,
        /// STEP: largest distance between a trim as drawn and the true edge,
        /// model units (default: 1/10 000 of the model's size).
        #[arg(long, allow_negative_numbers = true)]
        chord: Option<f64>,
        /// Print a JSON summary: faces, census by surface kind, bounding box
        /// and area of what the trims keep, units, skipped faces.
        #[arg(long)]
        json: bool,
    },
    /// Write a model as IGES (entity 128), OBJ free-form, or hitex's native JSON.
    Export {
        /// Model name or file.
        model: String,
        /// Output file: `.igs`/`.iges`, `.obj` or `.json`.
        #[arg(short, long)]
        output: PathBuf,
        /// STEP: largest distance between a trim as drawn and the true edge,
        /// model units (default: 1/10 000 of the model's size).
        #[arg(long, allow_negative_numbers = true)]
        chord: Option<f64>,
    },
    /// Continuity across the edges that faces share, from the exact surfaces:
    /// largest gap (G0), normal angle (G1) and relative curvature jump (G2)
    /// per edge, and naked edges. Exits 1 when a tolerance is exceeded.
    Check(CheckArgs),
    /// Distance from each point of a set (a scan, a probe) to the nearest
    /// trimmed face: point inversion, then the trim test; max, mean and RMS.
    Deviation(DeviationArgs),
    /// Point, partials, normal and curvatures at a parameter.
    Eval {
        /// Model name (`surface`, `teapot`, `spray`) or file (STEP, IGES, OBJ, JSON).
        model: String,
        /// Patch index (0-based, file order).
        #[arg(long, default_value_t = 0)]
        patch: usize,
        /// Parameters U,V.
        #[arg(long, value_parser = parse_uv, allow_hyphen_values = true)]
        uv: (f64, f64),
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
}

/// Arguments of `hitex nurbs render`.
#[derive(Args)]
pub struct RenderArgs {
    /// Model name (`surface`, `teapot`, `spray`) or file (STEP, IGES, OBJ, JSON).
    pub model: String,
    /// STEP: largest distance between a trim as drawn and the true edge,
    /// model units (default: 1/10 000 of the model's size).
    #[arg(long, allow_negative_numbers = true)]
    pub chord: Option<f64>,
    /// Display mode.
    #[arg(long, value_enum, default_value_t = NurbsMode::Shaded)]
    pub mode: NurbsMode,
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Output size, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_size, default_value = "512x512")]
    pub size: (u32, u32),
    /// Which renderer to use.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub backend: Backend,
    /// Tessellation of the mesh that places fragments (the surface itself
    /// is evaluated exactly per pixel): `auto` fits each patch's grid to the
    /// surface within `--mesh-chord` (at least 8 cells a side and one a knot
    /// span, up to 256), so that curved silhouettes are not cut to the mesh's
    /// polygons; N: an N×N grid on every patch.
    #[arg(long, value_name = "auto|N", default_value = "auto")]
    pub density: String,
    /// With `--density auto`: the largest distance between the mesh and the
    /// surface along its grid lines, model units (default: 1/4000 of the
    /// model's size, a quarter pixel at 1000 pixels across).
    #[arg(long, value_name = "UNITS")]
    pub mesh_chord: Option<f64>,
    /// Isophote bands over 180° (`--bands` is the older name; image commands
    /// use `--bands` for colour channels).
    #[arg(long = "isophotes", visible_alias = "bands", default_value_t = 12)]
    pub bands: u32,
    /// Zebra stripes over 180°.
    #[arg(long, default_value_t = 10)]
    pub stripes: u32,
    /// Pull (demoulding) direction of `--mode draft`: X,Y,Z or an axis
    /// (x, -z, …); default: the model's up axis.
    #[arg(long, value_parser = parse_pull, allow_hyphen_values = true)]
    pub pull: Option<Vec3>,
    /// Draft angles within ± this many degrees count as "no draft" (`--mode draft`).
    #[arg(long, default_value_t = hitex_render::nurbs::DEFAULT_DRAFT_TOLERANCE_DEG, allow_negative_numbers = true)]
    pub draft_tolerance: f32,
    /// Tool radius of `--mode radius`, model units (default: 1/50 of the model's
    /// bounding diameter).
    #[arg(long, allow_negative_numbers = true)]
    pub min_radius: Option<f32>,
    /// Curvature mapped to full colour, or with `--mode deviation` the
    /// deviation (model units) where the colour saturates (default: from the
    /// model; deviation: the 99th percentile of |deviation|, rounded up).
    #[arg(long, allow_negative_numbers = true)]
    pub range: Option<f32>,
    /// The reference of `--mode deviation`: a mesh (.stl, .obj, .ply with
    /// faces) or a point cloud (.xyz text, x y z a line; .json {"points": …};
    /// .ply without faces).
    #[arg(long, value_name = "FILE")]
    pub reference: Option<PathBuf>,
    /// `--mode deviation`: deviations within ± this many model units are in
    /// tolerance (green; default: a fifth of the range).
    #[arg(long, allow_negative_numbers = true)]
    pub tolerance: Option<f32>,
    /// `--mode deviation`: a surface point with no reference within this
    /// distance has no data (grey; default: 1/20 of the model's bounding
    /// diagonal).
    #[arg(long, allow_negative_numbers = true)]
    pub max_distance: Option<f64>,
    /// Draw the edges `nurbs check` finds, coloured by the continuity each
    /// reaches: green G2, yellow G1 (a curvature jump), orange G0 (a crease),
    /// red a gap beyond --g0, magenta naked (no neighbour).
    #[arg(long)]
    pub continuity: bool,
    /// `--continuity`: largest gap of a shared edge, model units (default:
    /// 1e-4 of the model's bounding diagonal).
    #[arg(long, allow_negative_numbers = true)]
    pub g0: Option<f64>,
    /// `--continuity`: normals within this many degrees are tangent (default 1).
    #[arg(long, allow_negative_numbers = true)]
    pub g1: Option<f64>,
    /// `--continuity`: a relative jump of the normal curvature within this
    /// is curvature-continuous (default 0.1).
    #[arg(long, allow_negative_numbers = true)]
    pub g2: Option<f64>,
    /// `--mode deviation`: the deviation is measured exactly at G×G
    /// parameter points per face and interpolated between them (2…90).
    #[arg(long, value_name = "G", default_value_t = 48)]
    pub deviation_grid: usize,
    /// Draw patch boundaries over the display mode.
    #[arg(long)]
    pub boundaries: bool,
    /// Draw N isoparametric lines per patch and direction (equal steps of
    /// each patch's parameter range, its edges included) over the display mode.
    #[arg(long, value_name = "N")]
    pub isolines: Option<u32>,
    /// Draw the section curves of a family of parallel planes: AXIS,SPACING
    /// (`z,0.5`: the planes z = k·0.5) or X,Y,Z,SPACING for any normal;
    /// spacing in model units.
    #[arg(long, value_name = "AXIS,SPACING", value_parser = parse_sections, allow_hyphen_values = true)]
    pub sections: Option<(Vec3, f32)>,
    /// Raise patches to the nearest prepared degree above them (3 or 5) by
    /// exact degree elevation (the paper's design: one kernel per prepared degree).
    #[arg(long)]
    pub elevate: bool,
    /// Turn the camera about the model's up axis, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub turn: f32,
    /// Elevation of the eye above the model's horizontal plane, degrees in −89…89.
    #[arg(long, default_value_t = ModelView::ELEVATION_DEG, allow_negative_numbers = true)]
    pub elevation: f32,
    /// The model's up axis: auto (a flat model's thinnest extent, else z), x, y, z, -x, -y or -z.
    #[arg(long, default_value = "auto", value_parser = UpAxis::parse, allow_hyphen_values = true)]
    pub up: UpAxis,
}

/// A figure with its sign: `+0.0123`, `-1.500`.
fn signed(x: f64) -> String {
    if x >= 0.0 { format!("+{}", fmt(x)) } else { fmt(x) }
}

/// `(x, y, z)` in 4 significant digits.
fn xyz(p: [f64; 3]) -> String {
    format!("({}, {}, {})", fmt(p[0]), fmt(p[1]), fmt(p[2]))
}

/// A length or figure in 4 significant digits.
fn fmt(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&x.abs()) {
        let digits = (3 - x.abs().log10().floor() as i32).clamp(0, 6) as usize;
        format!("{x:.digits$}")
    } else {
        format!("{x:.3e}")
    }
}

/// Draws the legend of `p`'s display mode, if it has one: the curvature ramp
/// with its name, units and how its range was chosen.
pub fn mode_legend(f: &mut hitex_render::Frame, p: &PreparedNurbs, user_range: bool) {
    let (name, units, rule, range) = match p.mode {
        NurbsMode::Gauss => ("GAUSS K", "1/LENGTH²", "±2×P75|K|", p.curvature_range[0]),
        NurbsMode::Mean => ("MEAN H", "1/LENGTH", "±2×P75|H|", p.curvature_range[1]),
        NurbsMode::K1 => ("MAX K1", "1/LENGTH", "±2×P75|K|", p.curvature_range[2]),
        NurbsMode::K2 => ("MIN K2", "1/LENGTH", "±2×P75|K|", p.curvature_range[2]),
        NurbsMode::Radius => {
            let q = |c: [f32; 3]| c.map(|x| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
            let k = hitex_render::cpu::nurbs::RADIUS_COLORS;
            let r = format!("= {}", hitex_render::legend::format_value(p.effective_tool_radius()));
            hitex_render::legend::swatch_legend(
                f,
                &["TOOL R", &r],
                &[(q(k[0]), "TIGHT".into()), (q(k[1]), "CONCAVE".into()), (q(k[2]), "CONVEX".into())],
            );
            return;
        }
        NurbsMode::Deviation => {
            let (tol, range) = p.deviation_range;
            hitex_render::legend::deviation_legend(f, tol, range, &["DEVIATION", "+ OUTSIDE"]);
            return;
        }
        NurbsMode::Draft => {
            let t = compact(p.draft_tolerance_deg);
            let q = |c: [f32; 3]| c.map(|x| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
            let k = hitex_render::cpu::nurbs::DRAFT_COLORS;
            let d = p.pull.normalize_or(Vec3::Z);
            let pull = match (0..3).find(|&i| d[i].abs() == 1.0) {
                Some(i) => format!("{}{}", if d[i] < 0.0 { '-' } else { '+' }, ["X", "Y", "Z"][i]),
                None => format!("{},{},{}", compact(d.x), compact(d.y), compact(d.z)),
            };
            hitex_render::legend::swatch_legend(
                f,
                &["DRAFT PULL", &pull],
                &[(q(k[0]), format!(">+{t}°")), (q(k[1]), format!("±{t}°")), (q(k[2]), format!("<-{t}°"))],
            );
            return;
        }
        _ => return,
    };
    if user_range {
        hitex_render::legend::diverging_legend(f, range, &[name, units, "±RANGE"]);
    } else if p.curvature_over_curved_part[p.curvature_slot()] {
        hitex_render::legend::diverging_legend(f, range, &[name, units, rule, "CURVED PART"]);
    } else {
        hitex_render::legend::diverging_legend(f, range, &[name, units, rule]);
    }
}

/// Whether `mode` draws a legend (and so a view keeps its strip clear).
pub fn has_legend(mode: NurbsMode) -> bool {
    matches!(
        mode,
        NurbsMode::Gauss
            | NurbsMode::Mean
            | NurbsMode::K1
            | NurbsMode::K2
            | NurbsMode::Draft
            | NurbsMode::Radius
            | NurbsMode::Deviation
    )
}

/// A number in at most two decimals without trailing zeros: `1`, `0.71`, `-2.5`.
fn compact(x: f32) -> String {
    let s = format!("{x:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// `0.00, 0.00, 1.00`
fn vec3_text(v: Vec3) -> String {
    format!("{:.2}, {:.2}, {:.2}", v.x, v.y, v.z)
}

/// Section planes: `AXIS,SPACING` or `X,Y,Z,SPACING` (a finite normal, not
/// zero; a finite positive spacing).
fn parse_sections(s: &str) -> Result<(Vec3, f32), String> {
    let Some((axis, spacing)) = s.rsplit_once(',') else {
        return Err(format!("'{s}' is not AXIS,SPACING (e.g. z,0.5) or X,Y,Z,SPACING"));
    };
    let normal = parse_pull(axis)?;
    let spacing: f32 = spacing.trim().parse().map_err(|_| format!("spacing '{spacing}' is not a number"))?;
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(format!("spacing {spacing} must be finite and positive"));
    }
    Ok((normal, spacing))
}

/// A pull direction: `X,Y,Z` (not zero, finite) or an axis name.
fn parse_pull(s: &str) -> Result<Vec3, String> {
    if !s.contains(',') {
        return match UpAxis::parse(s).map_err(|e| e.to_string())? {
            UpAxis::Auto => Err("give X,Y,Z or an axis (x, y, z, -x, -y, -z)".into()),
            a => Ok(a.direction()),
        };
    }
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("'{s}' is not X,Y,Z"));
    }
    let mut v = [0.0f32; 3];
    for (o, t) in v.iter_mut().zip(&parts) {
        *o = t.trim().parse().map_err(|_| format!("'{t}' is not a number"))?;
    }
    let v = Vec3::from_array(v);
    if !v.is_finite() || v.length() == 0.0 {
        return Err(format!("'{s}' is no direction: give finite X,Y,Z, not all zero"));
    }
    Ok(v.normalize())
}

/// The window of normalised device coordinates a model is framed into: a
/// margin all round, and clear of the legend strip when there is one.
pub fn view_window(width: u32, height: u32, legend: bool) -> [f32; 4] {
    let strip = if legend { hitex_render::legend::legend_width(width, height) } else { 0 };
    let right = 1.0 - 2.0 * strip as f32 / width.max(1) as f32;
    [-0.94, right - 0.06, -0.94, 0.94]
}

fn parse_uv(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or_else(|| format!("'{s}' is not U,V"))?;
    if b.contains(',') {
        return Err(format!("'{s}' has more than two values: give U,V"));
    }
    let u: f64 = a.trim().parse().map_err(|_| format!("'{a}' is not a number"))?;
    let v: f64 = b.trim().parse().map_err(|_| format!("'{b}' is not a number"))?;
    if !(u.is_finite() && v.is_finite()) {
        return Err("U and V must be finite".into());
    }
    Ok((u, v))
}

/// The census keys of `nurbs info --json`, in order.
const CENSUS_KEYS: [&str; 10] =
    ["plane", "cylinder", "cone", "sphere", "torus", "bspline", "revolution", "extrusion", "offset", "other"];

/// `nurbs info --json`: faces, census, the bounding box and area of the
/// trimmed faces (adaptive quadrature over each trim region), units, skipped.
fn info_json(m: &NurbsModel) -> serde_json::Value {
    use rayon::prelude::*;
    let measures: Vec<hitex_core::nurbs::measure::TrimmedMeasure> = m
        .surfaces
        .par_iter()
        .map(|s| hitex_core::nurbs::measure::trimmed_measure(&s.surface, s.range, &s.trim))
        .collect();
    let area: f64 = measures.iter().map(|x| x.area).sum();
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for x in &measures {
        for k in 0..3 {
            lo[k] = lo[k].min(x.min[k]);
            hi[k] = hi[k].max(x.max[k]);
        }
    }
    let mut census = serde_json::Map::new();
    for k in CENSUS_KEYS {
        let n = if m.census.is_empty() {
            if k == "bspline" { m.surfaces.len() } else { 0 }
        } else {
            m.census.get(k).copied().unwrap_or(0)
        };
        census.insert(k.into(), n.into());
    }
    serde_json::json!({
        "model": m.name,
        "faces": m.surfaces.len(),
        "trimmed": m.surfaces.iter().filter(|s| !s.trim.is_empty()).count(),
        "census": census,
        "bbox": [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]],
        "area": area,
        "units": m.units.clone().unwrap_or_else(|| "unitless".into()),
        "skipped": m.warnings,
        "repairs": m.repairs,
        "notes": m.notes,
    })
}

/// Loads a model, with `--chord` checked and passed to the STEP reader.
fn load(model: &str, chord: Option<f64>) -> Result<NurbsModel, CliError> {
    if let Some(c) = chord
        && !(c.is_finite() && c > 0.0)
    {
        return Err(CliError::Input(format!("--chord {c} must be finite and positive (model units)")));
    }
    Ok(hitex_io::models::load_model_with(model, &hitex_io::models::LoadOptions { chord_tolerance: chord })?)
}

/// `--density`: `auto` or a whole number of cells a side in 1…256.
fn parse_density(s: &str) -> Result<Density, CliError> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(Density::Auto);
    }
    match s.parse::<u32>() {
        Ok(n) if (1..=256).contains(&n) => Ok(Density::Fixed(n)),
        _ => Err(CliError::Input(format!(
            "--density {s} must be auto or a whole number in 1 to 256 (cells per patch side)"
        ))),
    }
}

/// A loaded model prepared for rendering with all its parts (trims and
/// colours included): [`PreparedNurbs::from_parts`].
pub fn prepare(model: &NurbsModel, density: Density, mesh_chord: Option<f64>) -> (PreparedNurbs, MeshCut) {
    PreparedNurbs::from_parts(model.nurbs(), &model.ranges(), &model.trims(), &model.colors, density, mesh_chord)
}

/// One line on the patches whose trims were simplified to fit the trim
/// texture (`None` when none were).
pub fn simplified_trims_warning(list: &[hitex_render::nurbs::TrimSimplified]) -> Option<String> {
    let first = list.first()?;
    let worst = list.iter().max_by(|a, b| a.tolerance.total_cmp(&b.tolerance)).unwrap_or(first);
    let mut line = format!(
        "the trimming loops of {} have more than the {} edges a patch holds and were simplified to fit \
         (patch {}: {} edges to {}, within {:.1e} of its loops' box",
        crate::count(list.len(), "patch", "patches"),
        hitex_render::nurbs::MAX_TRIM_EDGES,
        first.patch,
        first.edges,
        first.kept,
        first.tolerance
    );
    if worst.patch != first.patch {
        line += &format!("; the most on patch {}: {:.1e}", worst.patch, worst.tolerance);
    }
    line += ")";
    Some(line)
}

/// Runs a `hitex nurbs` subcommand.
pub fn run(cmd: NurbsCommand) -> Result<(), CliError> {
    match cmd {
        NurbsCommand::Render(a) => {
            for (flag, v) in [("--isophotes", a.bands), ("--stripes", a.stripes)] {
                if !(1..=1000).contains(&v) {
                    return Err(CliError::Input(format!("{flag} {v} must be in 1 to 1000")));
                }
            }
            let density = parse_density(&a.density)?;
            if let Some(c) = a.mesh_chord
                && !(c.is_finite() && c > 0.0)
            {
                return Err(CliError::Input(format!("--mesh-chord {c} must be finite and positive (model units)")));
            }
            crate::image_out(&a.output)?;
            if !a.turn.is_finite() {
                return Err(CliError::Input(format!("--turn {} must be finite (degrees)", a.turn)));
            }
            if !(a.elevation.is_finite() && a.elevation.abs() <= 89.0) {
                return Err(CliError::Input(format!("--elevation {} must be in −89…89 degrees", a.elevation)));
            }
            if !(a.draft_tolerance.is_finite() && (0.0..=89.0).contains(&a.draft_tolerance)) {
                return Err(CliError::Input(format!(
                    "--draft-tolerance {} must be in 0…89 degrees",
                    a.draft_tolerance
                )));
            }
            if let Some(r) = a.min_radius
                && !(r.is_finite() && r > 0.0)
            {
                return Err(CliError::Input(format!("--min-radius {r} must be finite and positive")));
            }
            if let Some(r) = a.range
                && !(r.is_finite() && r > 0.0)
            {
                return Err(CliError::Input(format!("--range {r} must be finite and positive")));
            }
            let model = load(&a.model, a.chord)?;
            for w in &model.warnings {
                eprintln!("hitex: warning: {}: {w}", model.name);
            }
            let (mut p, mesh) = prepare(&model, density, a.mesh_chord);
            if let Some(w) = simplified_trims_warning(&p.packed.trims_simplified) {
                eprintln!("hitex: warning: {}: {w}", model.name);
            }
            p.mode = a.mode;
            p.bands = a.bands;
            p.stripes = a.stripes;
            p.boundaries = a.boundaries;
            if let Some(n) = a.isolines {
                if !(1..=1000).contains(&n) {
                    return Err(CliError::Input(format!("--isolines {n} must be in 1…1000 lines per patch")));
                }
                p.isolines = n;
            }
            p.sections = a.sections;
            if let Some(r) = a.range {
                let slot = p.curvature_slot();
                p.curvature_range[slot] = r;
            }
            if a.elevate {
                let n = p.elevate_to_prepared();
                say!("elevated {n} patches to the nearest prepared degree (3 or 5)");
            }
            let up = if a.up == UpAxis::Auto { p.detect_up() } else { a.up };
            p.pull = a.pull.unwrap_or_else(|| up.direction());
            p.draft_tolerance_deg = a.draft_tolerance;
            p.tool_radius = a.min_radius.unwrap_or(0.0);
            let deviation_report = match (&a.reference, p.mode) {
                (Some(path), NurbsMode::Deviation) => {
                    let opts = DeviationOptions {
                        grid: a.deviation_grid,
                        tolerance: a.tolerance,
                        range: a.range,
                        max_distance: a.max_distance,
                    };
                    opts.check()?;
                    let data = hitex_io::stl::load_reference(path)?;
                    Some(set_up_deviation(&mut p, &model, data, &path.display().to_string(), &opts)?)
                }
                (None, NurbsMode::Deviation) => {
                    return Err(CliError::Input(
                        "--mode deviation needs --reference FILE: a mesh (.stl, .obj, .ply) or points (.xyz, .json, .ply)".into(),
                    ));
                }
                (Some(_), _) => {
                    return Err(CliError::Input("--reference is read by --mode deviation only".into()));
                }
                (None, _) => None,
            };
            let continuity_report = if a.continuity {
                Some(set_up_continuity(&mut p, &model, a.g0, a.g1, a.g2)?)
            } else {
                for (name, v) in [("--g0", a.g0), ("--g1", a.g1), ("--g2", a.g2)] {
                    if v.is_some() {
                        return Err(CliError::Input(format!("{name} is read with --continuity only")));
                    }
                }
                None
            };
            let view = ModelView { up, turn_deg: a.turn, elevation_deg: a.elevation };
            let window = view_window(a.size.0, a.size.1, has_legend(p.mode) || a.continuity);
            let cam = p.view_camera(&view, a.size.0 as f32 / a.size.1 as f32, window);
            let mut r = open_renderer(a.backend)?;
            let t = Instant::now();
            let mut f = render_frame(&mut r, &Job::Nurbs { model: &p, camera: cam }, a.size)?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            mode_legend(&mut f, &p, a.range.is_some());
            if a.continuity && !has_legend(p.mode) {
                let entries: Vec<([u8; 3], String)> =
                    CONTINUITY_CLASSES.iter().map(|(_, rgb, label)| (*rgb, label.to_string())).collect();
                hitex_render::legend::swatch_legend(&mut f, &["CONTINUITY"], &entries);
            }
            save(&f, &a.output)?;
            say!(
                "wrote {} ({}x{}, {}, mode {}, {}) in {ms:.1} ms",
                a.output.display(),
                a.size.0,
                a.size.1,
                crate::count(p.patch_count(), "patch", "patches"),
                p.mode.name(),
                r.name()
            );
            say!(
                "view: up {}{}, turn {}°, elevation {}°, fitted to the frame",
                up.name(),
                if a.up == UpAxis::Auto {
                    " (auto: a flat model's thinnest extent, else Z; --up to change)"
                } else {
                    ""
                },
                a.turn,
                a.elevation
            );
            say!(
                "mesh placing the fragments: {} ({}; --density N for a fixed grid)",
                crate::count(p.indices.len() / 3, "triangle", "triangles"),
                mesh
            );
            if p.mode == NurbsMode::Radius {
                say!(
                    "tool radius {}{}: red (tight) where the surface is concave with a radius of curvature \
                     below it (a ball tool that size cannot reach), blue concave with a radius from R to 100 R, \
                     grey convex or flatter (concave towards each face's parametric normal Su × Sv)",
                    hitex_render::legend::format_value(p.effective_tool_radius()),
                    if a.min_radius.is_none() { " (1/50 of the model's diameter; --min-radius to set)" } else { "" }
                );
            }
            if p.mode == NurbsMode::Draft {
                say!(
                    "draft against pull ({}){}: green beyond +{t}°, yellow within ±{t}°, red beyond −{t}° \
                     (sign from each face's parametric normal Su × Sv)",
                    vec3_text(p.pull.normalize_or(Vec3::Z)),
                    if a.pull.is_none() { " (the up axis; --pull to set)" } else { "" },
                    t = a.draft_tolerance
                );
            }
            if matches!(p.mode, NurbsMode::Gauss | NurbsMode::Mean | NurbsMode::K1 | NurbsMode::K2) {
                let range = p.curvature_range[p.curvature_slot()];
                let v = hitex_render::legend::format_value(range);
                say!(
                    "colour ramp: blue −{v} … white 0 … red +{v} (1/length{}; {}){}",
                    if p.mode == NurbsMode::Gauss { "²" } else { "" },
                    if a.range.is_some() {
                        "as --range gave"
                    } else if matches!(p.mode, NurbsMode::K1 | NurbsMode::K2) {
                        "± twice the area-weighted 75th percentile of max(|κ1|, |κ2|) over the curved part; --range to set"
                    } else if p.curvature_over_curved_part[p.curvature_slot()] {
                        "± twice the area-weighted 75th percentile over the curved part (flat faces hold over a quarter \
                         of the area); --range to set"
                    } else {
                        "± twice the area-weighted 75th percentile over the surface; --range to set"
                    },
                    if p.mode == NurbsMode::Gauss {
                        ""
                    } else {
                        "; positive where the surface bends towards the viewer (concave as seen)"
                    }
                );
            }
            for line in deviation_report.iter().flatten().chain(continuity_report.iter()) {
                say!("{line}");
            }
            if p.isolines > 0 {
                say!(
                    "isoparametric lines: {} per patch and direction (grey), at equal steps of each patch's parameter range",
                    p.isolines
                );
            }
            if let Some((n, spacing)) = p.sections {
                say!(
                    "sections (magenta): the planes ({}) · P = k × {}, exact per pixel",
                    vec3_text(n),
                    hitex_render::legend::format_value(spacing)
                );
            }
            Ok(())
        }
        NurbsCommand::Info { model, chord, json: true } => {
            let m = load(&model, chord)?;
            say!("{}", serde_json::to_string_pretty(&info_json(&m)).unwrap_or_default());
            Ok(())
        }
        NurbsCommand::Info { model, chord, json: false } => {
            let m = load(&model, chord)?;
            // the summary first, then one line per patch
            let mut degrees = std::collections::BTreeMap::new();
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for s in &m.surfaces {
                let n = &s.surface;
                *degrees.entry((n.degree_u, n.degree_v)).or_insert(0) += 1;
                let (a, b) = n.bounds();
                for t in 0..3 {
                    lo[t] = lo[t].min(a[t]);
                    hi[t] = hi[t].max(b[t]);
                }
            }
            let trimmed = m.surfaces.iter().filter(|s| !s.trim.is_empty()).count();
            say!("{}: {}, {trimmed} trimmed", m.name, crate::count(m.surfaces.len(), "patch", "patches"));
            let d: Vec<String> = degrees.iter().map(|((p, q), c)| format!("{p}×{q}: {c}")).collect();
            say!("degrees: {}", d.join(", "));
            say!("bounds of the control nets: min {lo:?} max {hi:?}");
            let coloured: Vec<[u32; 3]> = m.colors.iter().flatten().map(|c| c.map(f32::to_bits)).collect();
            if !coloured.is_empty() {
                let mut distinct = coloured.clone();
                distinct.sort_unstable();
                distinct.dedup();
                let grey = m.surfaces.len().saturating_sub(coloured.len());
                say!(
                    "colours: {} of {} coloured, {} distinct, the shaded mode's albedo{}",
                    coloured.len(),
                    crate::count(m.surfaces.len(), "patch", "patches"),
                    distinct.len(),
                    if grey > 0 { format!("; the other {grey} grey") } else { String::new() }
                );
            }
            for n in &m.notes {
                say!("{n}");
            }
            for w in &m.warnings {
                say!("warning: {w}");
            }
            for r in &m.repairs {
                say!("repaired: {r}");
            }
            for (k, s) in m.surfaces.iter().enumerate() {
                let n = &s.surface;
                say!(
                    "  patch {k:>3}: degree {}×{}, {}×{} control points, {}×{} knots, {}, u {:?} v {:?}",
                    n.degree_u,
                    n.degree_v,
                    n.count_u,
                    n.count_v,
                    n.knots_u.len(),
                    n.knots_v.len(),
                    if n.is_polynomial() { "polynomial" } else { "rational" },
                    s.range.0,
                    s.range.1
                );
                if !s.trim.is_empty() {
                    let sizes: Vec<String> = s.trim.iter().map(|l| l.len().to_string()).collect();
                    let loops = if s.trim.len() == 1 { "loop" } else { "loops" };
                    say!(
                        "             trimmed by {} {loops} of {} points in parameter space",
                        s.trim.len(),
                        sizes.join(" / ")
                    );
                }
            }
            Ok(())
        }
        NurbsCommand::Export { model, output, chord } => {
            let m = load(&model, chord)?;
            for w in &m.warnings {
                eprintln!("hitex: warning: {}: {w}", m.name);
            }
            let ext = output.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
            let text = match ext.as_deref() {
                Some("json") => hitex_io::nurbs_json::to_nurbs_json_with(&m.surfaces, &m.colors, m.units.as_deref()),
                Some("obj") => hitex_io::obj_freeform::to_obj_freeform(&m.surfaces),
                Some("igs") | Some("iges") => {
                    // IGES states a unit: the model's, else its default (millimetres)
                    let known = m.units.as_deref().and_then(hitex_io::iges::iges_unit);
                    if known.is_none() {
                        eprintln!(
                            "hitex: note: {}: {}; the IGES file says millimetres, IGES's default",
                            m.name,
                            match &m.units {
                                Some(u) => format!("IGES has no unit flag for '{u}'"),
                                None => "the model states no length unit".into(),
                            }
                        );
                    }
                    hitex_io::nurbs_json::to_iges_with(
                        &m.surfaces,
                        &m.colors,
                        &format!("{} exported by hitex", m.name),
                        m.units.as_deref(),
                    )
                }
                _ => {
                    return Err(CliError::Input(format!(
                        "{}: the extension must be .igs, .iges, .obj or .json",
                        output.display()
                    )));
                }
            };
            // what the formats cannot carry is said, not dropped in silence
            let coloured = m.colors.iter().filter(|c| c.is_some()).count();
            if coloured > 0 && ext.as_deref() == Some("obj") {
                eprintln!(
                    "hitex: warning: {}: the colours of {} are not exported (the .obj export carries \
                     surfaces and trims only; .igs and .json keep colours)",
                    m.name,
                    crate::count(coloured, "face", "faces")
                );
            }
            hitex_io::write_atomic(&output, text.as_bytes())?;
            say!("wrote {} ({})", output.display(), crate::count(m.surfaces.len(), "patch", "patches"));
            Ok(())
        }
        NurbsCommand::Check(a) => check(a),
        NurbsCommand::Deviation(a) => deviation(a),
        NurbsCommand::Eval { model, patch, uv, json } => {
            let m = load_model(&model)?;
            let s = m.surfaces.get(patch).ok_or_else(|| {
                CliError::Input(format!(
                    "{}: patch {patch} does not exist ({})",
                    m.name,
                    crate::count(m.surfaces.len(), "patch", "patches")
                ))
            })?;
            let ((u0, u1), (v0, v1)) = s.surface.domain();
            if uv.0 < u0 || uv.0 > u1 || uv.1 < v0 || uv.1 > v1 {
                return Err(CliError::Input(format!(
                    "--uv {},{} is outside the patch domain u [{u0}, {u1}] v [{v0}, {v1}]",
                    uv.0, uv.1
                )));
            }
            let d = s.surface.derivatives(uv.0, uv.1, 2);
            let n = s.surface.normal(uv.0, uv.1);
            let c = s.surface.curvature(uv.0, uv.1);
            if json {
                let v = serde_json::json!({
                    "model": m.name, "patch": patch, "u": uv.0, "v": uv.1,
                    "point": d.d[0][0], "du": d.d[1][0], "dv": d.d[0][1],
                    "duu": d.d[2][0], "duv": d.d[1][1], "dvv": d.d[0][2],
                    "normal": n, "gaussian": c.gaussian, "mean": c.mean, "principal": c.principal,
                });
                say!("{}", serde_json::to_string_pretty(&v).map_err(|e| CliError::Internal(e.to_string()))?);
            } else {
                say!("{} patch {patch} at (u, v) = ({}, {})", m.name, uv.0, uv.1);
                say!("  point     {:?}", d.d[0][0]);
                say!("  dS/du     {:?}", d.d[1][0]);
                say!("  dS/dv     {:?}", d.d[0][1]);
                say!("  d2S/du2   {:?}", d.d[2][0]);
                say!("  d2S/dudv  {:?}", d.d[1][1]);
                say!("  d2S/dv2   {:?}", d.d[0][2]);
                say!("  normal    {n:?}");
                // a signed zero prints as 0
                let g = |x: f64| if x == 0.0 { "0".to_string() } else { format!("{x:e}") };
                say!("  gaussian  {}", g(c.gaussian));
                say!("  mean      {}", g(c.mean));
                say!("  principal {}, {}", g(c.principal[0]), g(c.principal[1]));
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simplified_trims_are_named_in_one_line() {
        use hitex_render::nurbs::TrimSimplified;
        assert_eq!(simplified_trims_warning(&[]), None);
        let a = TrimSimplified { patch: 3, edges: 20_004, kept: 8_000, tolerance: 2e-5 };
        let b = TrimSimplified { patch: 9, edges: 9_000, kept: 8_100, tolerance: 4e-5 };
        let one = simplified_trims_warning(&[a]).unwrap_or_default();
        assert!(one.contains("of 1 patch have more than the 8191 edges"), "{one}");
        assert!(one.contains("patch 3: 20004 edges to 8000, within 2.0e-5") && !one.contains("the most"), "{one}");
        let two = simplified_trims_warning(&[a, b]).unwrap_or_default();
        assert!(two.contains("2 patches") && two.contains("the most on patch 9: 4.0e-5"), "{two}");
    }

    #[test]
    fn pull_directions_parse_and_bad_ones_are_refused() {
        assert_eq!(parse_pull("z"), Ok(Vec3::Z));
        assert_eq!(parse_pull("-x"), Ok(Vec3::NEG_X));
        assert_eq!(parse_pull("0,0,2"), Ok(Vec3::Z));
        let d = parse_pull("1, 0, 1").unwrap();
        assert!((d - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-6);
        for bad in ["0,0,0", "1,2", "1,2,3,4", "a,b,c", "nan,0,1", "inf,0,0", "auto", "w"] {
            assert!(parse_pull(bad).is_err(), "{bad} accepted");
        }
        assert_eq!(compact(1.0), "1");
        assert_eq!(compact(0.7149), "0.71");
        assert_eq!(compact(-0.001), "0");
        assert_eq!(compact(2.5), "2.5");
    }
}
