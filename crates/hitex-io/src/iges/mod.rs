//! IGES 5.3 files: rational B-spline surfaces (entity 128), read leniently.
//!
//! Real exports are sloppy: sequence numbers that repeat, directory pointers
//! that miss, a Terminate section that miscounts, a Global section cut short.
//! The reader relies on what carries meaning — the section letter in column
//! 73, the order of directory entries and of parameter records, the record
//! delimiter — and reports every repair it made. Entities other than 128 are
//! skipped with a warning. All sizes declared in a record are checked against
//! the record's length before anything is allocated.

use crate::step::geometry::{Arc, Curve, Frame, Kind, Surface};
use glam::{DVec2, DVec3};
use hitex_core::nurbs::{MAX_DEGREE, NurbsSurface};
use std::path::Path;
use thiserror::Error;

/// Largest IGES file accepted, in bytes.
pub const MAX_IGES_FILE_BYTES: u64 = 1 << 30;

/// An IGES file that cannot be read.
#[derive(Debug, Error)]
#[error("{file}: {}{message}", if location.is_empty() { String::new() } else { format!("{location}: ") })]
pub struct IgesError {
    /// The file.
    pub file: String,
    /// Line, directory entry or parameter record (empty for the file as a whole).
    pub location: String,
    /// What is wrong.
    pub message: String,
}

/// One entity-128 surface of the file.
#[derive(Debug, Clone)]
pub struct IgesSurface {
    /// The surface.
    pub surface: NurbsSurface,
    /// Parameter range of the record (U0, U1, V0, V1), within the knot domain.
    pub range: ((f64, f64), (f64, f64)),
    /// 1-based index of the directory entry.
    pub directory_entry: usize,
    /// Trimming loops in parameter space (closed polylines; the surface is
    /// kept where a point is inside an odd number of loops). Empty: untrimmed.
    pub trim: Vec<Vec<[f64; 2]>>,
}

/// What a file held, and what the reader had to do.
#[derive(Debug, Clone, Default)]
pub struct IgesModel {
    /// The entity-128 surfaces, in file order.
    pub surfaces: Vec<IgesSurface>,
    /// Entities skipped (type, count, why).
    pub warnings: Vec<String>,
    /// Inconsistencies found and repaired.
    pub repairs: Vec<String>,
    /// The length unit of the global section (parameters 14 and 15: "mm",
    /// "inch", …), where it names one.
    pub units: Option<String>,
    /// Each surface's colour (linear RGB), parallel to `surfaces`, where its
    /// directory entry gives one: a standard colour number (1–8) or a
    /// pointer to a colour definition (314); a trimmed surface without one
    /// takes its base surface's. Empty when no surface has a colour.
    pub colors: Vec<Option<[f32; 3]>>,
}

struct DirEntry {
    entity: i64,
    param_ptr: i64,
    param_lines: i64,
    /// Directory pointer of the entity's transformation matrix (124), 0: none.
    transform: i64,
    /// Colour number (field 13): 0 none, 1–8 a standard colour, negative
    /// the directory pointer of a colour definition (314).
    color: i64,
    line: usize,
}

/// The IGES 5.3 name of an entity type, for messages.
fn entity_name(ty: i64) -> &'static str {
    match ty {
        100 => "circular arc",
        102 => "composite curve",
        104 => "conic arc",
        106 => "copious data",
        108 => "plane",
        110 => "line",
        112 => "parametric spline curve",
        114 => "parametric spline surface",
        116 => "point",
        118 => "ruled surface",
        120 => "surface of revolution",
        122 => "tabulated cylinder",
        123 => "direction",
        124 => "transformation matrix",
        126 => "rational B-spline curve",
        128 => "rational B-spline surface",
        140 => "offset surface",
        141 => "boundary",
        142 => "curve on a parametric surface",
        143 => "bounded surface",
        144 => "trimmed surface",
        186 => "manifold solid B-rep",
        190 => "plane surface",
        192 => "right circular cylindrical surface",
        194 => "right circular conical surface",
        196 => "spherical surface",
        198 => "toroidal surface",
        212 => "general note",
        308 => "subfigure definition",
        314 => "colour definition",
        402 => "associativity instance",
        406 => "property",
        408 => "singular subfigure instance",
        502 => "vertex list",
        504 => "edge list",
        508 => "loop",
        510 => "face",
        514 => "shell",
        _ => "entity",
    }
}

/// Reads an IGES file.
pub fn load_iges(path: &Path) -> Result<IgesModel, IgesError> {
    let file = path.display().to_string();
    let err = |loc: &str, m: String| IgesError { file: file.clone(), location: loc.to_string(), message: m };
    let meta = std::fs::metadata(path).map_err(|e| err("", e.to_string()))?;
    if meta.len() > MAX_IGES_FILE_BYTES {
        return Err(err("", format!("{} bytes exceeds the {MAX_IGES_FILE_BYTES}-byte limit", meta.len())));
    }
    crate::limits::check_text_file(crate::limits::TextKind::Iges, meta.len()).map_err(|e| err("", e.to_string()))?;
    let bytes = std::fs::read(path).map_err(|e| err("", e.to_string()))?;
    // IGES is ASCII in fixed columns: a stray byte beyond ASCII stands as
    // one '?' so that every later column stays where the file put it
    let text: String = bytes.iter().map(|&b| if b.is_ascii() { b as char } else { '?' }).collect();
    parse_iges(&text, &file)
}

/// Parses IGES text; `name` is used in messages.
pub fn parse_iges(text: &str, name: &str) -> Result<IgesModel, IgesError> {
    let err = |loc: String, m: String| IgesError { file: name.to_string(), location: loc, message: m };
    let mut model = IgesModel::default();
    let mut global = String::new();
    let mut dir_lines: Vec<(usize, &str)> = Vec::new();
    let mut par_lines: Vec<(usize, &str)> = Vec::new();
    let mut terminate: Option<&str> = None;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim_end_matches('\r');
        if line.trim().is_empty() {
            continue;
        }
        let Some(section) = line.get(72..73) else {
            return Err(err(
                format!("line {}", i + 1),
                format!("{} characters; IGES lines have 80 with the section letter in column 73", line.len()),
            ));
        };
        match section {
            "S" => {}
            "G" => global.push_str(line.get(..72).unwrap_or("")),
            "D" => dir_lines.push((i + 1, line)),
            "P" => par_lines.push((i + 1, line)),
            "T" => terminate = Some(line),
            other => {
                return Err(err(format!("line {}", i + 1), format!("unknown section letter '{other}' in column 73")));
            }
        }
    }
    if dir_lines.is_empty() {
        return Err(err("directory".into(), "the file has no directory entries (section D)".into()));
    }
    // global: parameter and record delimiters
    let (pdelim, rdelim) = delimiters(&global, &mut model.repairs);
    model.units = global_units(&global_params(&global, pdelim, rdelim));

    // directory entries: pairs of lines
    if !dir_lines.len().is_multiple_of(2) {
        model.repairs.push(format!("odd number of directory lines ({}): the last one is ignored", dir_lines.len()));
    }
    let field = |l: &str, k: usize| -> Option<i64> { l.get(8 * k..8 * k + 8).and_then(|s| s.trim().parse().ok()) };
    let mut dirs = Vec::new();
    for (k, pair) in dir_lines.chunks_exact(2).enumerate() {
        let (ln, a) = pair[0];
        let b = pair[1].1;
        let entity = field(a, 0).ok_or_else(|| {
            err(format!("directory entry {} (line {ln})", k + 1), "entity type is not a number".into())
        })?;
        if field(b, 0).is_some_and(|t| t != entity) {
            model.repairs.push(format!(
                "directory entry {}: second line names entity {} instead of {entity}",
                k + 1,
                field(b, 0).unwrap_or(0)
            ));
        }
        dirs.push(DirEntry {
            entity,
            param_ptr: field(a, 1).unwrap_or(0),
            param_lines: field(b, 3).unwrap_or(0),
            transform: field(a, 6).unwrap_or(0),
            color: field(b, 2).unwrap_or(0),
            line: ln,
        });
        let seq_a: Option<i64> = a.get(73..80).and_then(|s| s.trim().parse().ok());
        if seq_a != Some(2 * k as i64 + 1) && !model.repairs.iter().any(|r| r.starts_with("directory sequence")) {
            model.repairs.push(format!(
                "directory sequence numbers are not 1, 3, 5, … (line {ln} has {}): entries are taken in file order",
                seq_a.map_or("none".to_string(), |s| s.to_string())
            ));
        }
    }

    // parameter records: columns 1–64 of the P lines, split at the record delimiter
    let mut records: Vec<(usize, String)> = Vec::new();
    let mut current = String::new();
    let mut start_line = 0usize;
    let mut seq_ok = true;
    for (k, (ln, l)) in par_lines.iter().enumerate() {
        if current.is_empty() {
            start_line = *ln;
        }
        let seq: Option<usize> = l.get(73..80).and_then(|s| s.trim().parse().ok());
        if seq != Some(k + 1) {
            seq_ok = false;
        }
        let data = l.get(..64).unwrap_or(l);
        let mut rest = data;
        while let Some(pos) = rest.find(rdelim) {
            current.push_str(&rest[..pos]);
            records.push((start_line, std::mem::take(&mut current)));
            start_line = *ln;
            rest = &rest[pos + 1..];
            // whatever follows a record delimiter on the same line is padding
            rest = if rest.trim().is_empty() { "" } else { rest };
            if !rest.is_empty() {
                break;
            }
        }
        current.push_str(rest.trim_end());
    }
    if !current.trim().is_empty() {
        model.repairs.push(format!("the last parameter record (line {start_line}) has no '{rdelim}': taken as ended"));
        records.push((start_line, current));
    }
    if !seq_ok {
        model.repairs.push(
            "parameter sequence numbers are not 1, 2, 3, …: records are matched to directory entries in file order"
                .into(),
        );
    }
    if records.len() != dirs.len() {
        model.repairs.push(format!(
            "{} directory entries but {} parameter records: the first {} are paired",
            dirs.len(),
            records.len(),
            dirs.len().min(records.len())
        ));
        if records.len() < dirs.len() {
            // entities lost: said wherever the model is used, not only by `info`
            model.warnings.push(format!(
                "the file looks truncated: {} of its {} directory entries have no parameter record and are lost",
                dirs.len() - records.len(),
                dirs.len()
            ));
        }
    }
    if let Some(t) = terminate {
        let count = |tag: char| -> Option<usize> {
            let i = t.find(tag)?;
            t.get(i + 1..i + 8)?.trim().parse().ok()
        };
        if count('D') != Some(dir_lines.len()) || count('P') != Some(par_lines.len()) {
            model.repairs.push(format!(
                "terminate section counts (D {}, P {}) disagree with the file (D {}, P {})",
                count('D').map_or("?".into(), |c| c.to_string()),
                count('P').map_or("?".into(), |c| c.to_string()),
                dir_lines.len(),
                par_lines.len()
            ));
        }
    }
    // directory pointers: P line where each record starts (1-based), and its length in lines
    let line_index: std::collections::HashMap<usize, usize> =
        par_lines.iter().enumerate().map(|(k, (ln, _))| (*ln, k + 1)).collect();
    let mut wrong = Vec::new();
    for (k, (d, (start, _))) in dirs.iter().zip(&records).enumerate() {
        let actual = line_index.get(start).copied().unwrap_or(0) as i64;
        if d.param_ptr != actual || d.param_lines <= 0 {
            wrong.push((k + 1, d.param_ptr, actual));
        }
    }
    if let Some((k, ptr, actual)) = wrong.first() {
        model.repairs.push(format!(
            "{} directory entries point at the wrong parameter lines (first: entry {k} → P {ptr}, its record starts at P {actual}): records taken in file order",
            wrong.len()
        ));
    }

    // entities: the records first, then surfaces, then trimmed surfaces that use them
    let mut skipped: std::collections::BTreeMap<i64, usize> = std::collections::BTreeMap::new();
    let mut parsed: Vec<(i64, Vec<String>, String)> = Vec::with_capacity(dirs.len());
    for (k, (d, (pline, rec))) in dirs.iter().zip(&records).enumerate() {
        let loc = format!("directory entry {} (line {}), parameter record at line {pline}", k + 1, d.line);
        let fields: Vec<String> = rec.split(pdelim).map(|f| f.trim().to_string()).collect();
        let ty: Option<i64> = fields.first().and_then(|f| f.parse().ok());
        if ty != Some(d.entity) {
            return Err(err(
                loc,
                format!(
                    "parameter record starts with {:?}, the directory says entity {}",
                    fields.first().map(String::as_str).unwrap_or(""),
                    d.entity
                ),
            ));
        }
        parsed.push((d.entity, fields, loc));
    }
    let transforms: Vec<i64> = dirs.iter().map(|d| d.transform).collect();
    let matrix_of = |k: usize| transform_of(k, &transforms, &parsed);
    let mut surface_of: std::collections::HashMap<usize, usize> = std::collections::HashMap::new();
    // each surface's colour by its directory entry (1-based)
    let mut colour_of_entry: std::collections::HashMap<usize, Option<[f32; 3]>> = std::collections::HashMap::new();
    let colours = colour_table(&dirs, &parsed);
    // colours that cannot be read: the surfaces keep the default, and one
    // warning names the first
    let mut bad_colours: Vec<usize> = Vec::new();
    let colour = |k: usize, bad: &mut Vec<usize>| -> Option<[f32; 3]> {
        colours[k].as_ref().map_err(|_| bad.push(k)).ok().copied().flatten()
    };
    for (k, (entity, fields, loc)) in parsed.iter().enumerate() {
        if *entity == 128 {
            let f: Vec<&str> = fields[1..].iter().map(String::as_str).collect();
            let mut s = parse_128(&f).map_err(|m| err(loc.clone(), format!("entity 128: {m}")))?;
            // its transformation matrix (124), applied to the control points (exact)
            match matrix_of(k) {
                Ok(Some(m)) => apply_124(&mut s.0, &m),
                Ok(None) => {}
                Err(m) => return Err(err(loc.clone(), format!("entity 128: {m}"))),
            }
            surface_of.insert(k, model.surfaces.len());
            colour_of_entry.insert(k + 1, colour(k, &mut bad_colours));
            model.surfaces.push(IgesSurface { surface: s.0, range: s.1, directory_entry: k + 1, trim: Vec::new() });
        } else if *entity == 120 || *entity == 122 {
            // swept surfaces: a curve turned about a line, or moved along one
            let f: Vec<&str> = fields[1..].iter().map(String::as_str).collect();
            let swept =
                if *entity == 120 { revolution(&f, &parsed, &transforms) } else { tabulated(&f, &parsed, &transforms) };
            let placed = swept.and_then(|(mut s, range)| {
                if let Some(m) = matrix_of(k)? {
                    apply_124(&mut s, &m);
                }
                Ok((s, range))
            });
            match placed {
                Ok((s, range)) => {
                    colour_of_entry.insert(k + 1, colour(k, &mut bad_colours));
                    model.surfaces.push(IgesSurface { surface: s, range, directory_entry: k + 1, trim: Vec::new() });
                }
                Err(m) => {
                    model.warnings.push(format!("{loc}: entity {entity} ({}) skipped: {m}", entity_name(*entity)))
                }
            }
        } else if *entity == 114 {
            // a grid of bicubic polynomial patches: one Bézier patch each, exactly
            let f: Vec<&str> = fields[1..].iter().map(String::as_str).collect();
            let patches = parse_114(&f).map_err(|m| err(loc.clone(), format!("entity 114: {m}")))?;
            let m = matrix_of(k).map_err(|m| err(loc.clone(), format!("entity 114: {m}")))?;
            colour_of_entry.insert(k + 1, colour(k, &mut bad_colours));
            for (mut s, range) in patches {
                if let Some(m) = &m {
                    apply_124(&mut s, m);
                }
                model.surfaces.push(IgesSurface { surface: s, range, directory_entry: k + 1, trim: Vec::new() });
            }
        }
    }
    // trimmed surfaces (144): the base surface is replaced by its trimmed form
    let mut trimmed = Vec::new();
    let mut consumed = std::collections::HashSet::new();
    for (k, (entity, fields, loc)) in parsed.iter().enumerate() {
        match *entity {
            128 | 114 | 120 | 122 => {}
            144 => {
                let f: Vec<&str> = fields[1..].iter().map(String::as_str).collect();
                match trimmed_surface(&f, &parsed, &transforms, &surface_of, &model.surfaces) {
                    Ok((base, loops)) => {
                        consumed.insert(base);
                        let mut s = model.surfaces[base].clone();
                        // the trimmed surface's own matrix applies after its base surface's
                        match matrix_of(k) {
                            Ok(Some(m)) => apply_124(&mut s.surface, &m),
                            Ok(None) => {}
                            Err(m) => return Err(err(loc.clone(), format!("entity 144: {m}"))),
                        }
                        s.trim = loops;
                        // the trimmed surface's colour, else its base surface's
                        let own = colour(k, &mut bad_colours);
                        let base_colour = colour_of_entry.get(&s.directory_entry).copied().flatten();
                        colour_of_entry.insert(k + 1, own.or(base_colour));
                        s.directory_entry = k + 1;
                        trimmed.push(s);
                    }
                    Err(m) => model.warnings.push(format!("{loc}: entity 144 not trimmed: {m}")),
                }
            }
            142 | 126 | 102 | 110 | 100 | 104 | 106 | 124 | 314 => {}
            other => *skipped.entry(other).or_default() += 1,
        }
    }
    if !trimmed.is_empty() {
        let mut kept: Vec<IgesSurface> =
            model.surfaces.iter().enumerate().filter(|(i, _)| !consumed.contains(i)).map(|(_, s)| s.clone()).collect();
        kept.extend(trimmed);
        kept.sort_by_key(|s| s.directory_entry);
        model.surfaces = kept;
    }
    let colors: Vec<Option<[f32; 3]>> =
        model.surfaces.iter().map(|s| colour_of_entry.get(&s.directory_entry).copied().flatten()).collect();
    if colors.iter().any(Option::is_some) {
        model.colors = colors;
    }
    bad_colours.sort_unstable();
    bad_colours.dedup();
    if let Some(&k) = bad_colours.first()
        && let Err(m) = &colours[k]
    {
        let more = if bad_colours.len() > 1 {
            format!(" (and {} more surfaces)", bad_colours.len() - 1)
        } else {
            String::new()
        };
        model.warnings.push(format!("{}: colour ignored, the default grey is used{more}: {m}", parsed[k].2));
    }
    for (&ty, n) in &skipped {
        let what = match ty {
            314 => "colour definition",
            _ => "unsupported entity",
        };
        model.warnings.push(format!("skipped {n} × entity {ty} ({what})"));
    }
    if model.surfaces.is_empty() {
        // say what the file holds instead, the commonest first
        let mut count: std::collections::BTreeMap<i64, usize> = std::collections::BTreeMap::new();
        for (entity, _, _) in &parsed {
            *count.entry(*entity).or_default() += 1;
        }
        let mut held: Vec<(i64, usize)> = count.into_iter().collect();
        held.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let list: Vec<String> =
            held.iter().take(6).map(|&(ty, n)| format!("{n} × {ty} ({})", entity_name(ty))).collect();
        let holds = if list.is_empty() {
            "it holds no entities besides".to_string()
        } else {
            format!("it holds {}{}", list.join(", "), if held.len() > 6 { ", …" } else { "" })
        };
        return Err(err(
            String::new(),
            format!(
                "no surface found: {holds}; hitex reads rational B-spline (128), parametric spline (114), revolved (120) and tabulated (122) surfaces, trimmed by 144/142"
            ),
        ));
    }
    Ok(model)
}

/// The eight standard colour numbers of IGES 5.3 (field 13 of a directory
/// entry), 1 = black … 8 = white, as sRGB.
const STANDARD_COLOURS: [[f32; 3]; 8] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 1.0, 0.0],
    [1.0, 0.0, 1.0],
    [0.0, 1.0, 1.0],
    [1.0, 1.0, 1.0],
];

/// Each directory entry's colour in linear RGB (`None`: the entry gives
/// none), or why its colour cannot be read.
fn colour_table(dirs: &[DirEntry], parsed: &Parsed) -> Vec<Result<Option<[f32; 3]>, String>> {
    let linear = |c: [f32; 3]| Some(c.map(hitex_core::texture::srgb_to_linear));
    dirs.iter()
        .take(parsed.len())
        .map(|d| match d.color {
            0 => Ok(None),
            n @ 1..=8 => Ok(linear(STANDARD_COLOURS[n as usize - 1])),
            n if n > 8 => Err(format!("colour number {n} is neither a standard colour (1–8) nor a pointer (negative)")),
            n => {
                let j = entity_at(&n.unsigned_abs().to_string(), parsed.len())
                    .map_err(|m| format!("colour pointer {n}: {m}"))?;
                let (ty, fields, _) = &parsed[j];
                if *ty != 314 {
                    return Err(format!("colour pointer {n} names entity {ty}, not a colour definition (314)"));
                }
                // CC1–CC3: red, green and blue in percent of full intensity
                let mut c = [0.0f32; 3];
                for (i, v) in c.iter_mut().enumerate() {
                    let x = fields.get(1 + i).and_then(|f| num(f)).filter(|x| x.is_finite()).ok_or_else(|| {
                        format!("colour definition (314) at entry {}: field {} is not a number", j + 1, 2 + i)
                    })?;
                    *v = (x / 100.0).clamp(0.0, 1.0) as f32;
                }
                Ok(linear(c))
            }
        })
        .collect()
}

/// Index of the entity a directory pointer (odd sequence number) names.
fn entity_at(ptr: &str, count: usize) -> Result<usize, String> {
    let p = num(ptr).ok_or_else(|| format!("pointer '{ptr}' is not a number"))?;
    if p < 1.0 || p.fract() != 0.0 || (p as usize - 1) / 2 >= count || (p as usize).is_multiple_of(2) {
        return Err(format!("pointer {p} names no directory entry"));
    }
    Ok((p as usize - 1) / 2)
}

type Parsed = Vec<(i64, Vec<String>, String)>;
type Loops = Vec<Vec<[f64; 2]>>;

mod curves;
mod global;
mod surfaces;

pub use curves::TRIM_CHORD_TOLERANCE;
pub(crate) use curves::sample_curve_2d;
use curves::*;
pub use global::iges_unit;
#[cfg(test)]
pub(crate) use global::tests_global_params;
use global::*;
use surfaces::*;
#[cfg(test)]
mod tests;
