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

/// Entity 144 fields after the type: PTS, N1, N2, PTO, PTI(1..N2).
/// Returns the base surface's index and the loops in its parameter space.
fn trimmed_surface(
    f: &[&str],
    parsed: &Parsed,
    transforms: &[i64],
    surface_of: &std::collections::HashMap<usize, usize>,
    surfaces: &[IgesSurface],
) -> Result<(usize, Loops), String> {
    let get = |i: usize| f.get(i).copied().ok_or_else(|| format!("record ends before field {}", i + 2));
    let pts = entity_at(get(0)?, parsed.len())?;
    let base =
        *surface_of.get(&pts).ok_or_else(|| format!("the base surface (entry {}) is not an entity 128", pts + 1))?;
    let n1 = num(get(1)?).ok_or("N1 is not a number")?;
    let n2 = num(get(2)?).ok_or("N2 is not a number")? as usize;
    if n2 > parsed.len() {
        return Err(format!("N2 = {n2} inner loops exceeds the entities of the file"));
    }
    let mut loops = Vec::new();
    if n1 == 0.0 {
        // outer boundary = the domain boundary
        let ((u0, u1), (v0, v1)) = surfaces[base].range;
        loops.push(vec![[u0, v0], [u1, v0], [u1, v1], [u0, v1], [u0, v0]]);
    } else {
        loops.push(curve_on_surface(entity_at(get(3)?, parsed.len())?, parsed, transforms)?);
    }
    for i in 0..n2 {
        loops.push(curve_on_surface(entity_at(get(4 + i)?, parsed.len())?, parsed, transforms)?);
    }
    Ok((base, loops))
}

/// A 124 transformation: rows `[R11 R12 R13 T1]`, `[R21 …]`, `[R31 …]`.
type Matrix34 = [[f64; 4]; 3];

/// The matrix that places entity `k` (the composition of its 124 and the
/// 124s that one refers to in turn), or `None` without one.
fn transform_of(k: usize, transforms: &[i64], parsed: &Parsed) -> Result<Option<Matrix34>, String> {
    let mut out: Option<Matrix34> = None;
    let mut ptr = transforms.get(k).copied().unwrap_or(0);
    for _ in 0..16 {
        if ptr == 0 {
            return Ok(out);
        }
        let j = entity_at(&ptr.to_string(), parsed.len())?;
        let (ty, fields, _) = &parsed[j];
        if *ty != 124 {
            return Err(format!("its transformation pointer {ptr} names entity {ty}, not a matrix (124)"));
        }
        let mut m = [[0.0; 4]; 3];
        for (r, row) in m.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x = fields.get(1 + 4 * r + c).and_then(|f| num(f)).filter(|x| x.is_finite()).ok_or_else(|| {
                    format!("matrix (124) at entry {}: field {} is not a number", j + 1, 2 + 4 * r + c)
                })?;
            }
        }
        // an outer matrix applies after the inner one
        out = Some(match out {
            None => m,
            Some(inner) => compose(&m, &inner),
        });
        ptr = transforms.get(j).copied().unwrap_or(0);
    }
    Err("transformation matrices refer to each other in a cycle".into())
}

/// `a ∘ b` of two affine 3×4 matrices.
fn compose(a: &Matrix34, b: &Matrix34) -> Matrix34 {
    let mut out = [[0.0; 4]; 3];
    for (r, row) in out.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| a[r][k] * b[k][c]).sum::<f64>() + if c == 3 { a[r][3] } else { 0.0 };
        }
    }
    out
}

/// Applies a 124 matrix to a surface's Cartesian control points (exact for
/// rational B-splines; weights unchanged).
fn apply_124(s: &mut NurbsSurface, m: &Matrix34) {
    for p in &mut s.points {
        let q = [p[0], p[1], p[2]];
        for (r, row) in m.iter().enumerate() {
            p[r] = row[0] * q[0] + row[1] * q[1] + row[2] * q[2] + row[3];
        }
    }
}

/// Entity 142: CRTN, SPTR, BPTR (curve in parameter space), CPTR, PREF.
fn curve_on_surface(k: usize, parsed: &Parsed, transforms: &[i64]) -> Result<Vec<[f64; 2]>, String> {
    let (ty, fields, _) = &parsed[k];
    if *ty != 142 {
        return Err(format!("entry {} is entity {ty}, expected a curve on a surface (142)", k + 1));
    }
    let bptr = fields.get(3).ok_or("entity 142 ends before BPTR")?;
    if num(bptr) == Some(0.0) {
        return Err("entity 142 has no parameter-space curve (BPTR = 0)".into());
    }
    let mut pts = Vec::new();
    sample_curve(entity_at(bptr, parsed.len())?, parsed, transforms, &mut pts, 0)?;
    if pts.len() < 3 {
        return Err("trimming loop has fewer than three points".into());
    }
    if pts.first() != pts.last() {
        let first = pts[0];
        pts.push(first);
    }
    Ok(pts)
}

/// Relative chord tolerance of sampled trim curves: no point of an arc or
/// conic lies farther than this fraction of the curve's size from the
/// polyline that stands for it.
pub const TRIM_CHORD_TOLERANCE: f64 = 1e-4;

/// Appends samples of a parameter-space curve (126, 110, 100, 104, 106 or
/// 102 of those), placed by its transformation matrix (124) if it has one.
fn sample_curve(
    k: usize,
    parsed: &Parsed,
    transforms: &[i64],
    out: &mut Vec<[f64; 2]>,
    depth: usize,
) -> Result<(), String> {
    if depth > 8 {
        return Err("composite curves nest too deeply".into());
    }
    let mut own = Vec::new();
    let z = sample_curve_here(k, parsed, transforms, &mut own, depth)?;
    let m = transform_of(k, transforms, parsed).map_err(|e| format!("entry {}: {e}", k + 1))?;
    for p in own {
        let p = match &m {
            Some(m) => [
                m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * z + m[0][3],
                m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * z + m[1][3],
            ],
            None => p,
        };
        if out.last() != Some(&p) {
            out.push(p);
        }
    }
    Ok(())
}

/// [`sample_curve`] before the curve's matrix: its points in its own
/// definition space, and the plane's z (ZT) that the matrix sees.
fn sample_curve_here(
    k: usize,
    parsed: &Parsed,
    transforms: &[i64],
    out: &mut Vec<[f64; 2]>,
    depth: usize,
) -> Result<f64, String> {
    let (ty, fields, _) = &parsed[k];
    let val =
        |i: usize, what: &str| -> Result<f64, String> {
            fields.get(i).and_then(|s| num(s)).filter(|x| x.is_finite()).ok_or_else(|| {
                format!("entity {ty} (entry {}): {what} (field {}) missing or not a number", k + 1, i + 1)
            })
        };
    let mut push = |p: [f64; 2]| {
        if out.last() != Some(&p) {
            out.push(p);
        }
    };
    let mut z = 0.0;
    match *ty {
        110 => {
            push([val(1, "X1")?, val(2, "Y1")?]);
            push([val(4, "X2")?, val(5, "Y2")?]);
        }
        102 => {
            let n = val(1, "N")? as usize;
            if n > parsed.len() {
                return Err(format!("composite curve of {n} members exceeds the file"));
            }
            for i in 0..n {
                let member = entity_at(fields.get(2 + i).ok_or("composite curve ends early")?, parsed.len())?;
                let mut part = Vec::new();
                sample_curve(member, parsed, transforms, &mut part, depth + 1)?;
                for p in part {
                    push(p);
                }
            }
        }
        126 => {
            let kk = val(1, "K")? as usize;
            let m = val(2, "M")? as usize;
            if kk >= fields.len() {
                return Err(format!("entity 126 declares {kk} + 1 control points in {} fields", fields.len()));
            }
            if m == 0 || m > hitex_core::nurbs::MAX_DEGREE || kk < m {
                return Err(format!("entity 126: degree {m} with K = {kk}"));
            }
            let need = 7 + (kk + m + 2) + (kk + 1) * 4 + 2;
            if fields.len() < need {
                return Err(format!("entity 126 declares {} control points but has {} fields", kk + 1, fields.len()));
            }
            let mut at = 7;
            let knots: Vec<f64> = (0..kk + m + 2).map(|i| val(at + i, "knot")).collect::<Result<_, _>>()?;
            at += kk + m + 2;
            let w: Vec<f64> = (0..=kk).map(|i| val(at + i, "weight")).collect::<Result<_, _>>()?;
            at += kk + 1;
            let mut pw = Vec::with_capacity(kk + 1);
            for (i, wi) in w.iter().enumerate() {
                if *wi <= 0.0 {
                    return Err(format!("entity 126: weight {i} is not positive"));
                }
                pw.push([val(at + 3 * i, "x")? * wi, val(at + 3 * i + 1, "y")? * wi, *wi]);
            }
            at += 3 * (kk + 1);
            hitex_core::nurbs::validate_knots("curve", &knots, kk + 1, m).map_err(|e| e.to_string())?;
            let (t0, t1) = (val(at, "V0").unwrap_or(knots[m]), val(at + 1, "V1").unwrap_or(knots[kk + 1]));
            let samples = (8 * (kk + 1 - m + 1)).clamp(16, 256);
            for p in sample_curve_2d(m, &knots, &pw, t0, t1, samples) {
                push(p);
            }
        }
        100 => {
            // circular arc: ZT, centre, start, end; counterclockwise, a full
            // circle where start and end coincide
            z = val(1, "ZT")?;
            let c = [val(2, "X1")?, val(3, "Y1")?];
            let a = [val(4, "X2")?, val(5, "Y2")?];
            let b = [val(6, "X3")?, val(7, "Y3")?];
            let r = (a[0] - c[0]).hypot(a[1] - c[1]);
            if r <= 0.0 {
                return Err(format!("entity 100 (entry {}): the arc's start is its centre", k + 1));
            }
            let t0 = (a[1] - c[1]).atan2(a[0] - c[0]);
            let mut t1 = (b[1] - c[1]).atan2(b[0] - c[0]);
            while t1 <= t0 {
                t1 += std::f64::consts::TAU;
            }
            let f = |t: f64| [c[0] + r * t.cos(), c[1] + r * t.sin()];
            for p in sample_adaptive(&f, t0, t1, TRIM_CHORD_TOLERANCE * r) {
                push(p);
            }
            // the end point as written (the radius to it may differ by rounding)
            if a != b {
                push(b);
            }
        }
        104 => {
            // conic arc in standard position: A x² + B xy + C y² + D x + E y + F = 0
            let q: Vec<f64> = (1..=6).map(|i| val(i, "coefficient")).collect::<Result<_, _>>()?;
            z = val(7, "ZT")?;
            let a = [val(8, "X1")?, val(9, "Y1")?];
            let b = [val(10, "X2")?, val(11, "Y2")?];
            let f = conic(&q).map_err(|m| format!("entity 104 (entry {}): {m}", k + 1))?.on_branch_of(a);
            let (t0, t1) = (f.param(a), f.param(b));
            let t1 = match f {
                // counterclockwise; a full ellipse where start and end coincide
                Conic::Ellipse { .. } => {
                    let mut t1 = t1;
                    while t1 <= t0 {
                        t1 += std::f64::consts::TAU;
                    }
                    t1
                }
                _ => t1,
            };
            let size = f.size().max((b[0] - a[0]).hypot(b[1] - a[1]));
            push(a);
            for p in sample_adaptive(&|t| f.point(t), t0, t1, TRIM_CHORD_TOLERANCE * size) {
                push(p);
            }
            if a != b {
                push(b);
            }
        }
        106 => {
            // copious data: IP = 1 (x, y pairs at ZT), 2 (x, y, z), 3 (x, y, z, i, j, k)
            let ip = val(1, "IP")?;
            let n = val(2, "N")?;
            let stride = match ip as i64 {
                1 => 2,
                2 => 3,
                3 => 6,
                _ => return Err(format!("entity 106 (entry {}): IP = {ip} (1, 2 or 3 expected)", k + 1)),
            };
            let first = if stride == 2 { 4 } else { 3 };
            let end = (n as usize).checked_mul(stride).and_then(|x| x.checked_add(first));
            if n < 0.0 || n.fract() != 0.0 || end.is_none_or(|e| e > fields.len()) {
                return Err(format!(
                    "entity 106 (entry {}): declares {} points but has {} fields",
                    k + 1,
                    fields[2],
                    fields.len()
                ));
            }
            if stride == 2 {
                z = val(3, "ZT")?;
            }
            for i in 0..n as usize {
                push([val(first + stride * i, "x")?, val(first + stride * i + 1, "y")?]);
            }
        }
        other => {
            return Err(format!(
                "entry {} is entity {other}, not a curve hitex can trim with (126, 110, 100, 104, 106, 102)",
                k + 1
            ));
        }
    }
    Ok(z)
}

/// A conic of entity 104 in standard position, by kind.
#[derive(Clone, Copy, Debug)]
enum Conic {
    /// x²/a² + y²/b² = 1: (a cos t, b sin t)
    Ellipse { a: f64, b: f64 },
    /// x²/a² − y²/b² = ±1 (`along_x`: opening along x): (±a cosh t, b sinh t)
    /// on the branch `sign`, or (a sinh t, ±b cosh t)
    Hyperbola { a: f64, b: f64, along_x: bool, sign: f64 },
    /// y = k x² (`along_x` false: x = k y²), parameter x (or y)
    Parabola { k: f64, along_x: bool },
}

impl Conic {
    fn point(&self, t: f64) -> [f64; 2] {
        match *self {
            Conic::Ellipse { a, b } => [a * t.cos(), b * t.sin()],
            Conic::Hyperbola { a, b, along_x: true, sign } => [sign * a * t.cosh(), b * t.sinh()],
            Conic::Hyperbola { a, b, along_x: false, sign } => [a * t.sinh(), sign * b * t.cosh()],
            Conic::Parabola { k, along_x: true } => [t, k * t * t],
            Conic::Parabola { k, along_x: false } => [k * t * t, t],
        }
    }

    /// A hyperbola's branch through `p` (other conics are unchanged).
    fn on_branch_of(self, p: [f64; 2]) -> Conic {
        match self {
            Conic::Hyperbola { a, b, along_x, .. } => {
                let s = if along_x { p[0] } else { p[1] };
                Conic::Hyperbola { a, b, along_x, sign: if s < 0.0 { -1.0 } else { 1.0 } }
            }
            other => other,
        }
    }

    /// The parameter of a point on the conic.
    fn param(&self, p: [f64; 2]) -> f64 {
        match *self {
            Conic::Ellipse { a, b } => (p[1] / b).atan2(p[0] / a),
            Conic::Hyperbola { b, along_x: true, .. } => (p[1] / b).asinh(),
            Conic::Hyperbola { a, along_x: false, .. } => (p[0] / a).asinh(),
            Conic::Parabola { along_x: true, .. } => p[0],
            Conic::Parabola { along_x: false, .. } => p[1],
        }
    }

    /// A length of the curve's scale, for the chord tolerance.
    fn size(&self) -> f64 {
        match *self {
            Conic::Ellipse { a, b } | Conic::Hyperbola { a, b, .. } => a.max(b),
            Conic::Parabola { k, .. } => 1.0 / k.abs(),
        }
    }
}

/// The conic of 104's coefficients (A, B, C, D, E, F), which the standard
/// puts in standard position: centre (or vertex) at the origin, axes along
/// x and y; anything else is refused with what it is.
fn conic(q: &[f64]) -> Result<Conic, String> {
    let (a, b, c, d, e, f) = (q[0], q[1], q[2], q[3], q[4], q[5]);
    let scale = q.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let zero = |x: f64| x.abs() <= 1e-12 * scale;
    if scale == 0.0 {
        return Err("every coefficient is zero".into());
    }
    if !zero(b) {
        return Err(format!("the conic is rotated (B = {b}); the standard asks for standard position"));
    }
    if zero(a) || zero(c) {
        // parabola: A x² + E y = 0 or C y² + D x = 0
        return if !zero(a) && zero(c) && zero(d) && zero(f) && !zero(e) {
            Ok(Conic::Parabola { k: -a / e, along_x: true })
        } else if zero(a) && !zero(c) && zero(e) && zero(f) && !zero(d) {
            Ok(Conic::Parabola { k: -c / d, along_x: false })
        } else {
            Err("a degenerate conic or a parabola off standard position".into())
        };
    }
    if !zero(d) || !zero(e) {
        return Err(format!(
            "the conic's centre is off the origin (D = {d}, E = {e}); the standard asks for standard position"
        ));
    }
    if zero(f) {
        return Err("a degenerate conic (F = 0: a point or two lines)".into());
    }
    let (ra, rc) = (-f / a, -f / c);
    match (ra > 0.0, rc > 0.0) {
        (true, true) => Ok(Conic::Ellipse { a: ra.sqrt(), b: rc.sqrt() }),
        (true, false) => Ok(Conic::Hyperbola { a: ra.sqrt(), b: (-rc).sqrt(), along_x: true, sign: 1.0 }),
        (false, true) => Ok(Conic::Hyperbola { a: (-ra).sqrt(), b: rc.sqrt(), along_x: false, sign: 1.0 }),
        (false, false) => Err("an imaginary ellipse (no real points)".into()),
    }
}

/// Samples of `f` over [t0, t1] (both ends included) such that no
/// midpoint between two samples lies farther than `tol` from their chord:
/// eight even steps, each halved while it misses (at most 2¹² pieces a step).
fn sample_adaptive(f: &dyn Fn(f64) -> [f64; 2], t0: f64, t1: f64, tol: f64) -> Vec<[f64; 2]> {
    fn split(
        f: &dyn Fn(f64) -> [f64; 2],
        a: (f64, [f64; 2]),
        b: (f64, [f64; 2]),
        tol: f64,
        depth: u32,
        out: &mut Vec<[f64; 2]>,
    ) {
        let tm = 0.5 * (a.0 + b.0);
        let m = f(tm);
        let (dx, dy) = (b.1[0] - a.1[0], b.1[1] - a.1[1]);
        let len = dx.hypot(dy);
        let dev = if len > 0.0 {
            ((m[0] - a.1[0]) * dy - (m[1] - a.1[1]) * dx).abs() / len
        } else {
            (m[0] - a.1[0]).hypot(m[1] - a.1[1])
        };
        if dev > tol && depth < 12 {
            split(f, a, (tm, m), tol, depth + 1, out);
            split(f, (tm, m), b, tol, depth + 1, out);
        } else {
            out.push(b.1);
        }
    }
    let mut out = vec![f(t0)];
    let mut prev = (t0, out[0]);
    for i in 1..=8 {
        let t = t0 + (t1 - t0) * i as f64 / 8.0;
        let next = (t, f(t));
        split(f, prev, next, tol, 0, &mut out);
        prev = next;
    }
    out
}

/// Samples a rational B-spline curve in the plane (homogeneous `(wx, wy, w)`
/// control points, validated knots) at `samples + 1` even parameter steps.
pub(crate) fn sample_curve_2d(
    m: usize,
    knots: &[f64],
    pw: &[[f64; 3]],
    t0: f64,
    t1: f64,
    samples: usize,
) -> Vec<[f64; 2]> {
    let n = pw.len() - 1;
    // a degree-1 curve is exactly the polyline of its vertices: read it back
    // vertex for vertex (t0, the knots strictly between, t1) instead of
    // resampling, so that polygonal trims round-trip exactly
    let ts: Vec<f64> = if m == 1 {
        let (lo, hi) = (t0.min(t1), t0.max(t1));
        let mut inner: Vec<f64> = knots.iter().copied().filter(|&t| lo < t && t < hi).collect();
        inner.dedup();
        if t1 < t0 {
            inner.reverse();
        }
        std::iter::once(t0).chain(inner).chain(std::iter::once(t1)).collect()
    } else {
        (0..=samples).map(|s| t0 + (t1 - t0) * s as f64 / samples as f64).collect()
    };
    ts.into_iter()
        .map(|t| {
            let span = hitex_core::nurbs::find_span(n, m, t, knots);
            let mut b = [0.0; hitex_core::nurbs::MAX_DEGREE + 1];
            hitex_core::nurbs::basis_funs(span, t, m, knots, &mut b);
            let mut c = [0.0; 3];
            for r in 0..=m {
                let q = pw[span - m + r];
                for (ci, qi) in c.iter_mut().zip(q) {
                    *ci += b[r] * qi;
                }
            }
            [c[0] / c[2], c[1] / c[2]]
        })
        .collect()
}

fn delimiters(global: &str, repairs: &mut Vec<String>) -> (char, char) {
    let g = global.trim_start();
    let hollerith = |s: &str| -> Option<(char, usize)> {
        let rest = s.strip_prefix("1H")?;
        let c = rest.chars().next()?;
        Some((c, 2 + c.len_utf8()))
    };
    let (pd, used) = hollerith(g).unwrap_or((',', 0));
    let after = &g[used..];
    let after = after.strip_prefix(pd).unwrap_or(after);
    let rd = match hollerith(after) {
        Some((c, _)) => c,
        None => {
            if after.trim().is_empty() {
                repairs.push("global section ends after the parameter delimiter: record delimiter ';' assumed".into());
            }
            ';'
        }
    };
    (pd, rd)
}

/// The global section's parameters in order (Hollerith strings as their
/// text), up to the record delimiter.
fn global_params(global: &str, pd: char, rd: char) -> Vec<String> {
    let chars: Vec<char> = global.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i <= chars.len() {
        // skip blanks before a parameter
        while i < chars.len() && chars[i] == ' ' {
            i += 1;
        }
        let digits = chars[i..].iter().take_while(|c| c.is_ascii_digit()).count();
        let value = if digits > 0 && chars.get(i + digits).is_some_and(|c| *c == 'H' || *c == 'h') {
            // nHtext: n characters taken as they are, delimiters included
            let n: usize = chars[i..i + digits].iter().collect::<String>().parse().unwrap_or(0);
            let start = i + digits + 1;
            let end = (start + n).min(chars.len());
            i = end;
            chars[start..end].iter().collect::<String>()
        } else {
            let start = i;
            while i < chars.len() && chars[i] != pd && chars[i] != rd {
                i += 1;
            }
            chars[start..i].iter().collect::<String>().trim().to_string()
        };
        out.push(value);
        while i < chars.len() && chars[i] == ' ' {
            i += 1;
        }
        match chars.get(i) {
            Some(c) if *c == pd => i += 1,
            _ => break,
        }
    }
    out
}

/// [`global_params`] with the default delimiters, for tests elsewhere in the crate.
#[cfg(test)]
pub(crate) fn tests_global_params(global: &str) -> Vec<String> {
    global_params(global, ',', ';')
}

/// The length unit of the global parameters 14 (unit flag) and 15 (unit
/// name), as the other readers name units ("mm", "inch", …).
fn global_units(params: &[String]) -> Option<String> {
    let flag = params.get(13).and_then(|f| f.trim().parse::<i64>().ok());
    let name = params.get(14).map(|n| n.trim().to_ascii_uppercase()).unwrap_or_default();
    let by_flag = match flag {
        Some(1) => Some("inch"),
        Some(2) => Some("mm"),
        Some(4) => Some("ft"),
        Some(5) => Some("mile"),
        Some(6) => Some("m"),
        Some(7) => Some("km"),
        Some(8) => Some("mil"),
        Some(9) => Some("µm"),
        Some(10) => Some("cm"),
        Some(11) => Some("microinch"),
        _ => None,
    };
    by_flag.map(str::to_string).or_else(|| {
        // flag 3: the unit is the name (e.g. 4HINCH, 2HMM)
        let from_name = match name.as_str() {
            "IN" | "INCH" => "inch",
            "MM" => "mm",
            "FT" => "ft",
            "MI" => "mile",
            "M" => "m",
            "KM" => "km",
            "MIL" => "mil",
            "UM" => "µm",
            "CM" => "cm",
            "UIN" => "microinch",
            _ => return (!name.is_empty()).then(|| name.to_ascii_lowercase()),
        };
        Some(from_name.to_string())
    })
}

/// The IGES unit flag and name of a length unit named as `global_units`
/// names them; `None` for a unit IGES has no flag for.
pub fn iges_unit(units: &str) -> Option<(u32, &'static str)> {
    Some(match units {
        "inch" => (1, "INCH"),
        "mm" => (2, "MM"),
        "ft" => (4, "FT"),
        "mile" => (5, "MI"),
        "m" => (6, "M"),
        "km" => (7, "KM"),
        "mil" => (8, "MIL"),
        "µm" => (9, "UM"),
        "cm" => (10, "CM"),
        "microinch" => (11, "UIN"),
        _ => return None,
    })
}

fn num(s: &str) -> Option<f64> {
    let t = s.trim().replace(['D', 'd'], "E");
    t.parse::<f64>().ok().filter(|v| v.is_finite())
}

type Range = ((f64, f64), (f64, f64));

/// Entity 128 fields after the type: K1, K2, M1, M2, PROP1–5, knots S, knots
/// T, weights, control points, U0, U1, V0, V1.
/// The 3-D curve of entry `k` (110 line, 100 circular arc, 126 rational
/// B-spline curve) as an exact rational B-spline, its own matrix (124)
/// applied, with the parameter range the record gives it (126: V0..V1,
/// within its knots; 100: its angles; 110: 0..1).
fn space_curve(k: usize, parsed: &Parsed, transforms: &[i64]) -> Result<(Curve, (f64, f64)), String> {
    let (ty, fields, _) = &parsed[k];
    let f: Vec<&str> = fields.iter().skip(1).map(String::as_str).collect();
    let at = format!("entity {ty} (entry {})", k + 1);
    let real = |i: usize| -> Result<f64, String> {
        f.get(i)
            .and_then(|s| num(s))
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{at}: field {} is not a number", i + 2))
    };
    let p3 = |i: usize| -> Result<DVec3, String> { Ok(DVec3::new(real(i)?, real(i + 1)?, real(i + 2)?)) };
    // degree, knots, Cartesian control points with weights, parameter range
    type Parts = (usize, Vec<f64>, Vec<(DVec3, f64)>, (f64, f64));
    let (degree, knots, mut pts, range): Parts = match ty {
        110 => (1, vec![0.0, 0.0, 1.0, 1.0], vec![(p3(0)?, 1.0), (p3(3)?, 1.0)], (0.0, 1.0)),
        100 => {
            let (zt, c) = (real(0)?, DVec2::new(real(1)?, real(2)?));
            let (a, b) = (DVec2::new(real(3)?, real(4)?) - c, DVec2::new(real(5)?, real(6)?) - c);
            let r = a.length();
            if r.is_nan() || r <= 0.0 {
                return Err(format!("{at}: the arc's start is its centre"));
            }
            // counterclockwise from start to end; the same point: the whole circle
            let a0 = a.y.atan2(a.x);
            let mut a1 = b.y.atan2(b.x);
            while a1 <= a0 + 1e-12 {
                a1 += std::f64::consts::TAU;
            }
            let arc = Arc::new(a0, a1).map_err(|m| format!("{at}: {m}"))?;
            let (knots, unit) = arc.control();
            let pts = unit.iter().map(|&(x, y, w)| (DVec3::new(c.x + r * x, c.y + r * y, zt), w)).collect();
            (2, knots, pts, (a0, a1))
        }
        126 => {
            let int = |i: usize, what: &str| -> Result<usize, String> {
                let v = real(i)?;
                if v.fract() != 0.0 || !(0.0..=f.len() as f64).contains(&v) {
                    return Err(format!("{at}: {what} = {v} is not a count the record can hold"));
                }
                Ok(v as usize)
            };
            let (upper, degree) = (int(0, "K")?, int(1, "M")?);
            if !(1..=MAX_DEGREE).contains(&degree) || upper < degree {
                return Err(format!("{at}: degree M = {degree} with K = {upper} (needs 1 ≤ M ≤ {MAX_DEGREE}, M ≤ K)"));
            }
            let n = upper + 1;
            let nk = n + degree + 1;
            // declared sizes against the record before allocating
            if 6 + nk + 4 * n + 2 > f.len() {
                return Err(format!(
                    "{at}: {n} control points of degree {degree} need more fields than the record's {}",
                    f.len()
                ));
            }
            let knots: Vec<f64> = (0..nk).map(|i| real(6 + i)).collect::<Result<_, _>>()?;
            if knots.windows(2).any(|w| w[1] < w[0]) {
                return Err(format!("{at}: the knots decrease"));
            }
            let mut pts = Vec::with_capacity(n);
            for i in 0..n {
                let w = real(6 + nk + i)?;
                if w <= 0.0 {
                    return Err(format!("{at}: weight {i} is {w}, not positive"));
                }
                pts.push((p3(6 + nk + n + 3 * i)?, w));
            }
            let (d0, d1) = (knots[degree], knots[n]);
            if d1 <= d0 {
                return Err(format!("{at}: the knots span no parameter range"));
            }
            let (v0, v1) =
                (real(6 + nk + 4 * n).unwrap_or(d0).clamp(d0, d1), real(7 + nk + 4 * n).unwrap_or(d1).clamp(d0, d1));
            (degree, knots, pts, if v1 > v0 { (v0, v1) } else { (d0, d1) })
        }
        other => {
            return Err(format!(
                "the curve is entity {other} ({}, entry {}); hitex sweeps lines (110), circular arcs (100) and B-spline curves (126)",
                entity_name(*other),
                k + 1
            ));
        }
    };
    if let Some(m) = transform_of(k, transforms, parsed)? {
        for (p, _) in &mut pts {
            let q = *p;
            *p = DVec3::new(
                m[0][0] * q.x + m[0][1] * q.y + m[0][2] * q.z + m[0][3],
                m[1][0] * q.x + m[1][1] * q.y + m[1][2] * q.z + m[1][3],
                m[2][0] * q.x + m[2][1] * q.y + m[2][2] * q.z + m[2][3],
            );
        }
    }
    let pw = pts.iter().map(|(p, w)| [p.x * w, p.y * w, p.z * w, *w]).collect();
    Ok((Curve::Spline { degree, knots, pw }, range))
}

/// Entity 120 fields after the type: L (the axis, a line 110), C (the
/// generatrix), SA, TA (start and terminate angles, radians). The
/// generatrix turned about the axis (counterclockwise looking down it from
/// its end), exactly: u the angle (rational quadratic arcs), v the curve's
/// parameter.
fn revolution(f: &[&str], parsed: &Parsed, transforms: &[i64]) -> Result<(NurbsSurface, Range), String> {
    let get = |i: usize| f.get(i).copied().ok_or_else(|| format!("record ends before field {}", i + 2));
    let axis = entity_at(get(0)?, parsed.len())?;
    if parsed[axis].0 != 110 {
        return Err(format!("its axis (entry {}) is entity {}, not a line (110)", axis + 1, parsed[axis].0));
    }
    let (line, _) = space_curve(axis, parsed, transforms)?;
    let (p1, p2) = (line.point(0.0), line.point(1.0));
    if (p2 - p1).length() <= 0.0 {
        return Err("its axis has zero length".into());
    }
    let (curve, range) = space_curve(entity_at(get(1)?, parsed.len())?, parsed, transforms)?;
    let angle = |i: usize, what: &str| -> Result<f64, String> {
        get(i).ok().and_then(num).filter(|x| x.is_finite()).ok_or_else(|| format!("{what} is not a number"))
    };
    let (sa, ta) = (angle(2, "the start angle SA")?, angle(3, "the terminate angle TA")?);
    let domain = curve.range();
    let surface = Surface::new(Frame::new(p1, p2 - p1, DVec3::X), Kind::Revolution { curve });
    let (s, _) = surface.to_nurbs([(sa, ta), domain])?;
    Ok((s, ((sa, ta), range)))
}

/// Entity 122 fields after the type: DE (the directrix curve), LX, LY, LZ
/// (the end of the generatrix, which starts at the directrix's start): the
/// directrix moved along the generatrix, exactly: u the curve's
/// parameter, v from 0 to 1.
fn tabulated(f: &[&str], parsed: &Parsed, transforms: &[i64]) -> Result<(NurbsSurface, Range), String> {
    let get = |i: usize| f.get(i).copied().ok_or_else(|| format!("record ends before field {}", i + 2));
    let (curve, range) = space_curve(entity_at(get(0)?, parsed.len())?, parsed, transforms)?;
    let coord = |i: usize| -> Result<f64, String> {
        get(i).ok().and_then(num).filter(|x| x.is_finite()).ok_or_else(|| format!("field {} is not a number", i + 2))
    };
    let end = DVec3::new(coord(1)?, coord(2)?, coord(3)?);
    let axis = end - curve.point(range.0);
    if axis.length() <= 0.0 {
        return Err("its generatrix has zero length".into());
    }
    let domain = curve.range();
    let surface = Surface::new(Frame::IDENTITY, Kind::Extrusion { curve, axis });
    let (s, _) = surface.to_nurbs([domain, (0.0, 1.0)])?;
    Ok((s, (range, (0.0, 1.0))))
}

/// Entity 114 fields after the type: CTYPE, PTYPE, M, N, the breakpoints
/// TU(1..M+1) and TV(1..N+1), then 48 coefficients for each of the
/// (M+1)×(N+1) patches, u index outer: per coordinate x, y, z the 16
/// coefficients A B C D E F G H K L M N P Q R S of `Σ c[4b+a]·s^a·t^b`,
/// s = u − TU(i), t = v − TV(j) (the last row and column of patches only
/// complete the grid). Each of the M×N patches becomes a polynomial bicubic
/// Bézier patch over [TU(i), TU(i+1)] × [TV(j), TV(j+1)], exactly: the
/// power basis scaled to the patch's width and height, then converted to
/// Bernstein form.
fn parse_114(f: &[&str]) -> Result<Vec<(NurbsSurface, Range)>, String> {
    let int = |i: usize, what: &str| -> Result<u64, String> {
        let s = f.get(i).ok_or_else(|| format!("record ends before {what} (field {})", i + 2))?;
        let v = num(s).ok_or_else(|| format!("{what} '{s}' is not a number"))?;
        if v.fract() != 0.0 || !(1.0..=f.len() as f64).contains(&v) {
            return Err(format!("{what} = {v} is not a segment count the record can hold"));
        }
        Ok(v as u64)
    };
    let (m, n) = (int(2, "M (u segments)")?, int(3, "N (v segments)")?);
    // declared sizes against the record before allocating
    let need = (48u64.saturating_mul(m + 1).saturating_mul(n + 1)).saturating_add(6 + m + n);
    if need > f.len() as u64 {
        return Err(format!("declares {m}×{n} patches, which needs {need} fields, but the record has {}", f.len()));
    }
    let (m, n) = (m as usize, n as usize);
    let real = |i: usize, what: &dyn Fn() -> String| -> Result<f64, String> {
        let s = f.get(i).ok_or_else(|| format!("record ends before {}", what()))?;
        num(s).filter(|x| x.is_finite()).ok_or_else(|| format!("{} '{s}' is not a finite number", what()))
    };
    let breaks = |at: usize, count: usize, dir: &str| -> Result<Vec<f64>, String> {
        let t: Vec<f64> =
            (0..count).map(|i| real(at + i, &|| format!("breakpoint T{dir}({})", i + 1))).collect::<Result<_, _>>()?;
        if let Some(i) = t.windows(2).position(|w| w[1] <= w[0]) {
            return Err(format!(
                "breakpoints T{dir} do not rise: T{dir}({}) = {} ≥ T{dir}({}) = {}",
                i + 1,
                t[i],
                i + 2,
                t[i + 1]
            ));
        }
        Ok(t)
    };
    let tu = breaks(4, m + 1, "U")?;
    let tv = breaks(5 + m, n + 1, "V")?;
    let base = 6 + m + n;
    // Bernstein from power coefficients of degree 3: P_i = Σ_{a ≤ i} C(i,a)/C(3,a) c_a
    const TO_BERNSTEIN: [[f64; 4]; 4] =
        [[1.0, 0.0, 0.0, 0.0], [1.0, 1.0 / 3.0, 0.0, 0.0], [1.0, 2.0 / 3.0, 1.0 / 3.0, 0.0], [1.0, 1.0, 1.0, 1.0]];
    let mut out = Vec::with_capacity(m * n);
    for i in 0..m {
        for j in 0..n {
            let (h, g) = (tu[i + 1] - tu[i], tv[j + 1] - tv[j]);
            let at = base + 48 * (i * (n + 1) + j);
            let mut points = vec![[0.0, 0.0, 0.0, 1.0]; 16];
            for q in 0..3 {
                // c[a][b] scaled to the patch: s = h·σ, t = g·τ
                let mut c = [[0.0f64; 4]; 4];
                for (b, gb) in [1.0, g, g * g, g * g * g].into_iter().enumerate() {
                    for (a, ha) in [1.0, h, h * h, h * h * h].into_iter().enumerate() {
                        let k = 16 * q + 4 * b + a;
                        let v = real(at + k, &|| {
                            format!(
                                "patch ({}, {}) coefficient {} of {}",
                                i + 1,
                                j + 1,
                                "ABCDEFGHKLMNPQRS".as_bytes()[k % 16] as char,
                                ["x", "y", "z"][q]
                            )
                        })?;
                        c[a][b] = v * ha * gb;
                    }
                }
                for (pi, ri) in TO_BERNSTEIN.iter().enumerate() {
                    for (pj, rj) in TO_BERNSTEIN.iter().enumerate() {
                        let mut v = 0.0;
                        for a in 0..4 {
                            for b in 0..4 {
                                v += ri[a] * rj[b] * c[a][b];
                            }
                        }
                        points[4 * pj + pi][q] = v;
                    }
                }
            }
            let knots = |a: f64, b: f64| vec![a, a, a, a, b, b, b, b];
            let s = NurbsSurface::new(3, 3, 4, 4, knots(tu[i], tu[i + 1]), knots(tv[j], tv[j + 1]), points)
                .map_err(|e| e.to_string())?;
            out.push((s, ((tu[i], tu[i + 1]), (tv[j], tv[j + 1]))));
        }
    }
    Ok(out)
}

fn parse_128(f: &[&str]) -> Result<(NurbsSurface, Range), String> {
    let int = |i: usize, what: &str| -> Result<i64, String> {
        let s = f.get(i).ok_or_else(|| format!("record ends before {what} (field {})", i + 2))?;
        let v = num(s).ok_or_else(|| format!("{what} '{s}' is not a number"))?;
        if v.fract() != 0.0 {
            return Err(format!("{what} {v} is not an integer"));
        }
        if v.abs() > 1e15 {
            return Err(format!("{what} {v:e} is out of range"));
        }
        Ok(v as i64)
    };
    let (k1, k2, m1, m2) = (int(0, "K1")?, int(1, "K2")?, int(2, "M1")?, int(3, "M2")?);
    for (what, deg) in [("M1 (degree in u)", m1), ("M2 (degree in v)", m2)] {
        if deg < 1 || deg > MAX_DEGREE as i64 {
            return Err(format!("{what} = {deg} is outside 1..={MAX_DEGREE}"));
        }
    }
    if k1 < m1 || k2 < m2 {
        return Err(format!("K1 = {k1}, K2 = {k2} give fewer control points than degree + 1 ({m1}, {m2})"));
    }
    if k1 >= f.len() as i64 || k2 >= f.len() as i64 {
        return Err(format!("K1 = {k1}, K2 = {k2} declare more control points than the record's {} fields", f.len()));
    }
    // declared sizes against the record before allocating
    let (nu, nv) = ((k1 + 1) as u64, (k2 + 1) as u64);
    let (na, nb) = (nu + m1 as u64 + 1, nv + m2 as u64 + 1);
    let need = 9u64 + na + nb + nu * nv * 4 + 4;
    if need > f.len() as u64 {
        return Err(format!(
            "declares {nu}×{nv} control points of degree {m1}×{m2}, which needs {need} fields, but the record has {}",
            f.len()
        ));
    }
    let (nu, nv, na, nb) = (nu as usize, nv as usize, na as usize, nb as usize);
    let real = |i: usize, what: &str| -> Result<f64, String> {
        let s = f.get(i).ok_or_else(|| format!("record ends before {what}"))?;
        num(s).ok_or_else(|| format!("{what} '{s}' is not a finite number"))
    };
    let mut at = 9;
    let mut knots_u = Vec::with_capacity(na);
    for i in 0..na {
        knots_u.push(real(at + i, &format!("u knot {i}"))?);
    }
    at += na;
    let mut knots_v = Vec::with_capacity(nb);
    for i in 0..nb {
        knots_v.push(real(at + i, &format!("v knot {i}"))?);
    }
    at += nb;
    let mut weights = Vec::with_capacity(nu * nv);
    for i in 0..nu * nv {
        weights.push(real(at + i, &format!("weight {i}"))?);
    }
    at += nu * nv;
    let mut points = Vec::with_capacity(nu * nv);
    for (i, w) in weights.iter().enumerate() {
        let c = [real(at + 3 * i, "x")?, real(at + 3 * i + 1, "y")?, real(at + 3 * i + 2, "z")?];
        points.push([c[0], c[1], c[2], *w]);
    }
    at += 3 * nu * nv;
    let surface =
        NurbsSurface::new(m1 as usize, m2 as usize, nu, nv, knots_u, knots_v, points).map_err(|e| e.to_string())?;
    let ((a0, a1), (b0, b1)) = surface.domain();
    let u0 = real(at, "U0").unwrap_or(a0).clamp(a0, a1);
    let u1 = real(at + 1, "U1").unwrap_or(a1).clamp(a0, a1);
    let v0 = real(at + 2, "V0").unwrap_or(b0).clamp(b0, b1);
    let v1 = real(at + 3, "V1").unwrap_or(b1).clamp(b0, b1);
    let range = if u1 > u0 && v1 > v0 { ((u0, u1), (v0, v1)) } else { ((a0, a1), (b0, b1)) };
    Ok((surface, range))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(data: &str, section: char, seq: usize) -> String {
        format!("{data:<72}{section}{seq:>7}\n")
    }

    /// A minimal, well-formed file with one bilinear patch.
    fn tiny(record: &str) -> String {
        let mut s = line("tiny test", 'S', 1);
        s += &line("1H,,1H;;", 'G', 1);
        s += &line(&format!("{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}", 128, 1, 0, 1, 0, 0, 0, 0, 0), 'D', 1);
        s += &line(&format!("{:>8}{:>8}{:>8}{:>8}{:>8}", 128, 0, 0, 1, 0), 'D', 2);
        let mut k = 1;
        for chunk in record.as_bytes().chunks(64) {
            let txt = std::str::from_utf8(chunk).unwrap();
            s += &format!("{txt:<64}{:>8}P{k:>7}\n", 1);
            k += 1;
        }
        s += &line(&format!("S{:>7}G{:>7}D{:>7}P{:>7}", 1, 1, 2, k - 1), 'T', 1);
        s
    }

    /// A well-formed file of several entities with consistent pointers.
    pub(crate) fn iges_file(entities: &[(i64, &str)]) -> String {
        let with: Vec<(i64, &str, usize)> = entities.iter().map(|(t, r)| (*t, *r, 0)).collect();
        iges_file_placed(&with)
    }

    /// Like [`iges_file`], each entity with the directory pointer of its
    /// transformation matrix (0: none).
    pub(crate) fn iges_file_placed(entities: &[(i64, &str, usize)]) -> String {
        let with: Vec<(i64, &str, usize, i64)> = entities.iter().map(|&(t, r, m)| (t, r, m, 0)).collect();
        iges_file_coloured(&with)
    }

    /// Like [`iges_file_placed`], each entity with its colour number too
    /// (directory field 13: 0 none, 1–8 standard, −pointer to a 314).
    pub(crate) fn iges_file_coloured(entities: &[(i64, &str, usize, i64)]) -> String {
        let mut s = line("generated", 'S', 1);
        s += &line("1H,,1H;;", 'G', 1);
        let mut dir = String::new();
        let mut par = String::new();
        let mut pl = 1;
        for (k, (ty, rec, tr, colour)) in entities.iter().enumerate() {
            let lines: Vec<String> =
                rec.as_bytes().chunks(64).map(|c| String::from_utf8_lossy(c).to_string()).collect();
            let de = 2 * k + 1;
            dir +=
                &line(&format!("{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}", ty, pl, 0, 1, 0, 0, tr, 0, 0), 'D', de);
            dir += &line(&format!("{:>8}{:>8}{:>8}{:>8}{:>8}", ty, 0, colour, lines.len(), 0), 'D', de + 1);
            for l in lines {
                par += &format!("{l:<64}{de:>8}P{pl:>7}\n");
                pl += 1;
            }
        }
        s += &dir;
        s += &par;
        s += &line(&format!("S{:>7}G{:>7}D{:>7}P{:>7}", 1, 1, 2 * entities.len(), pl - 1), 'T', 1);
        s
    }

    #[test]
    fn a_file_without_surfaces_says_what_it_holds() {
        let text = iges_file(&[
            (110, "110,0.,0.,0.,1.,0.,0.;"),
            (110, "110,1.,0.,0.,1.,1.,0.;"),
            (116, "116,0.,0.,0.,0;"),
            (186, "186,0,1,0;"),
        ]);
        let e = parse_iges(&text, "part.igs").unwrap_err().to_string();
        assert_eq!(
            e,
            "part.igs: no surface found: it holds 2 × 110 (line), \
             1 × 116 (point), 1 × 186 (manifold solid B-rep); hitex reads rational B-spline (128), parametric \
             spline (114), revolved (120) and tabulated (122) surfaces, trimmed by 144/142"
        );
    }

    /// A unit square trimmed by a circular hole of radius 0.3 at its centre.
    pub(crate) fn holed_square() -> String {
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let pts = [
            (1.0, 0.0),
            (1.0, 1.0),
            (0.0, 1.0),
            (-1.0, 1.0),
            (-1.0, 0.0),
            (-1.0, -1.0),
            (0.0, -1.0),
            (1.0, -1.0),
            (1.0, 0.0),
        ];
        let mut circle = "126,8,2,0,0,0,0,0.,0.,0.,0.25,0.25,0.5,0.5,0.75,0.75,1.,1.,1.,".to_string();
        for i in 0..9 {
            circle += &format!("{},", if i % 2 == 1 { w } else { 1.0 });
        }
        for (x, y) in pts {
            circle += &format!("{},{},0.,", 0.5 + 0.3 * x, 0.5 + 0.3 * y);
        }
        circle += "0.,1.,0.,0.,1.;";
        iges_file(&[(128, BILINEAR), (126, &circle), (142, "142,0,1,3,0,1;"), (144, "144,1,0,1,0,5;")])
    }

    /// A unit square with two holes: a circle (entity 100) of radius 0.15
    /// about (0.3, 0.5), and an ellipse (entity 104) of semi-axes 0.12 and
    /// 0.25 placed about (0.7, 0.5) by a matrix (124).
    pub(crate) fn arc_holes() -> String {
        iges_file_placed(&[
            (128, BILINEAR, 0),
            (100, "100,0.,0.3,0.5,0.45,0.5,0.45,0.5;", 0),
            (124, "124,1.,0.,0.,0.7,0.,1.,0.,0.5,0.,0.,1.,0.;", 0),
            (104, "104,0.0625,0.,0.0144,0.,0.,-0.0009,0.,0.12,0.,0.12,0.;", 5),
            (142, "142,0,1,3,0,1;", 0),
            (142, "142,0,1,7,0,1;", 0),
            (144, "144,1,0,2,0,9,11;", 0),
        ])
    }

    #[test]
    fn arc_holes_fixture_is_current() {
        fixture_is_current("arc-holes.igs", &arc_holes());
        let m = parse_iges(&arc_holes(), "arc-holes.igs").unwrap();
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);
        let t = &m.surfaces[0].trim;
        assert_eq!(t.len(), 3);
        let pi = std::f64::consts::PI;
        assert!((area(&t[1]) / (pi * 0.0225) - 1.0).abs() < 2.0 * TRIM_CHORD_TOLERANCE);
        assert!((area(&t[2]) / (pi * 0.03) - 1.0).abs() < 4.0 * TRIM_CHORD_TOLERANCE);
    }

    #[test]
    fn holed_square_fixture_is_current() {
        fixture_is_current("holed-square.igs", &holed_square());
    }

    /// `data/NAME`, a trimmed surface for tests and users, holds `text`
    /// (`HITEX_BLESS=1` rewrites it).
    fn fixture_is_current(name: &str, text: &str) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data").join(name);
        if std::env::var("HITEX_BLESS").is_ok_and(|v| v == "1") {
            std::fs::write(&path, text).unwrap();
        }
        assert_eq!(std::fs::read_to_string(&path).unwrap(), text, "{name}");
    }

    #[test]
    fn transformation_matrices_place_surfaces() {
        // a quarter turn about z, then (10, 0, 0); a second matrix above it moves by (0, 0, 5)
        let turn = "124,0.,-1.,0.,10.,1.,0.,0.,0.,0.,0.,1.,0.;";
        let lift = "124,1.,0.,0.,0.,0.,1.,0.,0.,0.,0.,1.,5.;";
        let f = iges_file_placed(&[(124, lift, 0), (124, turn, 1), (128, BILINEAR, 3)]);
        let m = parse_iges(&f, "placed.igs").unwrap();
        assert_eq!(m.surfaces.len(), 1, "{:?}", m.warnings);
        let s = &m.surfaces[0].surface;
        // the bilinear patch's corner (1, 0, 0) → turned to (0, 1, 0) → (10, 1, 0) → lifted (10, 1, 5)
        let p = s.point(1.0, 0.0);
        assert!((p[0] - 10.0).abs() < 1e-12 && (p[1] - 1.0).abs() < 1e-12 && (p[2] - 5.0).abs() < 1e-12, "{p:?}");
        assert!(!m.warnings.iter().any(|w| w.contains("124")), "{:?}", m.warnings);
        // a pointer to something other than a matrix is an error naming it
        let f = iges_file_placed(&[(110, "110,0.,0.,0.,1.,0.,0.;", 0), (128, BILINEAR, 1)]);
        let e = parse_iges(&f, "bad.igs").unwrap_err().to_string();
        assert!(e.contains("not a matrix (124)"), "{e}");
        // matrices pointing at each other
        let f = iges_file_placed(&[(124, lift, 3), (124, turn, 1), (128, BILINEAR, 3)]);
        let e = parse_iges(&f, "cycle.igs").unwrap_err().to_string();
        assert!(e.contains("cycle"), "{e}");
    }

    #[test]
    fn trimmed_surface_gets_its_loops() {
        let m = parse_iges(&holed_square(), "holed.igs").unwrap();
        assert!(m.repairs.is_empty(), "{:?}", m.repairs);
        assert_eq!(m.surfaces.len(), 1, "the base surface is replaced by its trimmed form");
        let t = &m.surfaces[0].trim;
        assert_eq!(t.len(), 2);
        assert_eq!(t[0].len(), 5);
        // the hole: every sample on the circle of radius 0.3
        for p in &t[1] {
            let r = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2)).sqrt();
            assert!((r - 0.3).abs() < 1e-12, "{p:?}");
        }
        // a 144 that points at nothing is a warning, and its surface stays untrimmed
        let bad = iges_file(&[(128, BILINEAR), (144, "144,1,1,0,77;")]);
        let m = parse_iges(&bad, "bad.igs").unwrap();
        assert!(m.surfaces[0].trim.is_empty());
        assert!(m.warnings.iter().any(|w| w.contains("entity 144")), "{:?}", m.warnings);
    }

    /// The unit bilinear patch with one hole bounded by `curves` (entries
    /// 2 …, the last one the 142's parameter-space curve; each with its
    /// matrix pointer): the hole's loop, or the file's warnings.
    fn hole(curves: &[(i64, &str, usize)]) -> Result<Vec<[f64; 2]>, Vec<String>> {
        let last = 2 * curves.len() + 1;
        let c142 = format!("142,0,1,{last},0,1;");
        let c144 = format!("144,1,0,1,0,{};", last + 2);
        let mut all = vec![(128, BILINEAR, 0)];
        all.extend_from_slice(curves);
        all.push((142, &c142, 0));
        all.push((144, &c144, 0));
        let m = parse_iges(&iges_file_placed(&all), "hole.igs").unwrap();
        match m.surfaces[0].trim.get(1) {
            Some(l) => Ok(l.clone()),
            None => Err(m.warnings),
        }
    }

    fn area(l: &[[f64; 2]]) -> f64 {
        0.5 * l.windows(2).map(|w| w[0][0] * w[1][1] - w[1][0] * w[0][1]).sum::<f64>()
    }

    /// Largest distance of a chord's midpoint from the circle (c, r).
    fn worst_sagitta(l: &[[f64; 2]], c: [f64; 2], r: f64) -> f64 {
        l.windows(2)
            .map(|w| r - (0.5 * (w[0][0] + w[1][0]) - c[0]).hypot(0.5 * (w[0][1] + w[1][1]) - c[1]))
            .fold(0.0, f64::max)
    }

    #[test]
    fn circular_arcs_trim_to_the_chord_tolerance() {
        // a full circle (start = end), radius 0.3 about (0.5, 0.5)
        let l = hole(&[(100, "100,0.,0.5,0.5,0.8,0.5,0.8,0.5;", 0)]).unwrap();
        for p in &l {
            assert!(((p[0] - 0.5).hypot(p[1] - 0.5) - 0.3).abs() < 1e-12, "{p:?}");
        }
        let sag = worst_sagitta(&l, [0.5, 0.5], 0.3);
        assert!(sag <= TRIM_CHORD_TOLERANCE * 0.3 * 1.0001 && sag > 0.0, "{sag}");
        // counterclockwise, the circle's area to the chord tolerance, not thousands of points
        let a = area(&l);
        assert!((a / (std::f64::consts::PI * 0.09) - 1.0).abs() < 2.0 * TRIM_CHORD_TOLERANCE, "{a}");
        assert!(l.len() < 600, "{}", l.len());
        // a half circle of radius 1 closed by its diameter, as a composite
        // curve that a matrix scales by 1/4 and moves to (0.5, 0.5)
        let quarter = "124,0.25,0.,0.,0.5,0.,0.25,0.,0.5,0.,0.,1.,0.;";
        let l = hole(&[
            (124, quarter, 0),
            (100, "100,0.,0.,0.,1.,0.,-1.,0.;", 0),
            (110, "110,-1.,0.,0.,1.,0.,0.;", 0),
            (102, "102,2,5,7;", 3),
        ])
        .unwrap();
        assert!(l.iter().all(|p| p[1] >= 0.5 - 1e-12 && (p[0] - 0.5).hypot(p[1] - 0.5) <= 0.25 + 1e-12), "{l:?}");
        let half = std::f64::consts::PI * 0.0625 / 2.0;
        assert!((area(&l) / half - 1.0).abs() < 2.0 * TRIM_CHORD_TOLERANCE, "{}", area(&l));
        // a degenerate arc is a warning naming the entity; the surface stays
        let w = hole(&[(100, "100,0.,0.5,0.5,0.5,0.5,0.5,0.5;", 0)]).unwrap_err();
        assert!(w.iter().any(|w| w.contains("entity 100 (entry 2)") && w.contains("centre")), "{w:?}");
    }

    #[test]
    fn conic_arcs_trim_on_their_curves() {
        // the ellipse x²/0.2² + y²/0.1² = 1, whole, moved to (0.5, 0.5)
        let shift = "124,1.,0.,0.,0.5,0.,1.,0.,0.5,0.,0.,1.,0.;";
        let l = hole(&[(124, shift, 0), (104, "104,25.,0.,100.,0.,0.,-1.,0.,0.2,0.,0.2,0.;", 3)]).unwrap();
        for p in &l {
            let (x, y) = (p[0] - 0.5, p[1] - 0.5);
            assert!((x * x / 0.04 + y * y / 0.01 - 1.0).abs() < 1e-12, "{p:?}");
        }
        let e = std::f64::consts::PI * 0.2 * 0.1;
        assert!((area(&l) / e - 1.0).abs() < 4.0 * TRIM_CHORD_TOLERANCE, "{}", area(&l));
        // the parabola y = 2x² from x = −0.5 to 0.5, closed by the line y = 0.5: area 1/3
        let l = hole(&[
            (104, "104,2.,0.,0.,0.,-1.,0.,0.,-0.5,0.5,0.5,0.5;", 0),
            (110, "110,0.5,0.5,0.,-0.5,0.5,0.;", 0),
            (102, "102,2,3,5;", 0),
        ])
        .unwrap();
        assert!(l.iter().all(|p| (p[1] - 2.0 * p[0] * p[0]).abs() < 1e-12 || (p[1] - 0.5).abs() < 1e-12), "{l:?}");
        assert!(l.len() > 10, "sampled, not a chord: {l:?}");
        assert!((area(&l).abs() - 1.0 / 3.0).abs() < 1e-4, "{}", area(&l));
        // the hyperbola x² − y² = 1: its left branch from (−cosh 1, sinh 1) to (−cosh 1, −sinh 1)
        let (c, s) = (1f64.cosh(), 1f64.sinh());
        let rec = format!("104,1.,0.,-1.,0.,0.,-1.,0.,{},{s},{},{};", -c, -c, -s);
        let l = hole(&[(104, &rec, 0)]).unwrap();
        for p in &l {
            assert!(p[0] < 0.0 && (p[0] * p[0] - p[1] * p[1] - 1.0).abs() < 1e-9, "{p:?}");
        }
        assert!(l.len() > 10);
        // off standard position: a warning naming the entity and why
        let w = hole(&[(104, "104,1.,0.5,1.,0.,0.,-1.,0.,1.,0.,1.,0.;", 0)]).unwrap_err();
        assert!(w.iter().any(|w| w.contains("entity 104 (entry 2)") && w.contains("standard position")), "{w:?}");
        let w = hole(&[(104, "104,1.,0.,1.,0.,0.,1.,0.,1.,0.,1.,0.;", 0)]).unwrap_err();
        assert!(w.iter().any(|w| w.contains("imaginary")), "{w:?}");
    }

    #[test]
    fn copious_data_trims_as_its_points() {
        let l = hole(&[(106, "106,1,4,0.,0.1,0.1,0.9,0.1,0.9,0.9,0.1,0.9;", 0)]).unwrap();
        assert_eq!(l, vec![[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9], [0.1, 0.1]]);
        let l = hole(&[(106, "106,2,3,0.2,0.2,0.,0.8,0.2,0.,0.5,0.8,0.;", 0)]).unwrap();
        assert_eq!(l.len(), 4);
        // more points claimed than written, and an unknown IP: warnings naming the entity
        let w = hole(&[(106, "106,1,40,0.,0.1,0.1;", 0)]).unwrap_err();
        assert!(w.iter().any(|w| w.contains("entity 106 (entry 2)") && w.contains("40")), "{w:?}");
        let w = hole(&[(106, "106,1,1e30,0.,0.1,0.1;", 0)]).unwrap_err();
        assert!(w.iter().any(|w| w.contains("entity 106 (entry 2)") && w.contains("1e30")), "{w:?}");
        let w = hole(&[(106, "106,7,1,0.,0.1,0.1;", 0)]).unwrap_err();
        assert!(w.iter().any(|w| w.contains("IP = 7")), "{w:?}");
    }

    const BILINEAR: &str =
        "128,1,1,1,1,0,0,1,0,0,0.,0.,1.,1.,0.,0.,1.,1.,1.,1.,1.,1.,0.,0.,0.,1.,0.,0.,0.,1.,0.,1.,1.,1.,0.,1.,0.,1.;";

    #[test]
    fn surfaces_take_their_colours_from_definitions_and_standard_numbers() {
        let lin = |c: f32| hitex_core::texture::srgb_to_linear(c);
        let text = iges_file_coloured(&[
            (314, "314,100.,50.,0.,6Horange;", 0, 0),
            (128, BILINEAR, 0, -1),
            (128, BILINEAR, 0, 3),
            (128, BILINEAR, 0, 0),
        ]);
        let m = parse_iges(&text, "c.igs").unwrap();
        assert_eq!(m.surfaces.len(), 3);
        assert!(m.warnings.is_empty(), "a colour definition that is used is not 'skipped': {:?}", m.warnings);
        assert_eq!(m.colors, vec![Some([1.0, lin(0.5), 0.0]), Some([0.0, 1.0, 0.0]), None]);
        // no colours anywhere: none listed
        let m = parse_iges(&iges_file(&[(128, BILINEAR)]), "n.igs").unwrap();
        assert!(m.colors.is_empty());
    }

    #[test]
    fn a_trimmed_surface_without_a_colour_takes_its_base_surfaces() {
        let text = holed_square();
        // the base surface (entry 1) coloured blue through its standard number
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        let second = lines.iter().position(|l| l.ends_with("D      2")).unwrap();
        lines[second].replace_range(16..24, &format!("{:>8}", 4));
        let m = parse_iges(&(lines.join("\n") + "\n"), "h.igs").unwrap();
        assert_eq!(m.surfaces.len(), 1);
        assert!(!m.surfaces[0].trim.is_empty());
        assert_eq!(m.colors, vec![Some([0.0, 0.0, 1.0])]);
    }

    #[test]
    fn unreadable_colours_leave_the_default_with_one_warning_naming_the_entry() {
        type Entities<'a> = &'a [(i64, &'a str, usize, i64)];
        let cases: [(Entities, &str); 4] = [
            (
                &[(128, BILINEAR, 0, -7), (128, BILINEAR, 0, -7)],
                "colour pointer -7: pointer 7 names no directory entry",
            ),
            (
                &[(110, "110,0.,0.,0.,1.,0.,0.;", 0, 0), (128, BILINEAR, 0, -1)],
                "names entity 110, not a colour definition",
            ),
            (&[(314, "314,100.,zz,0.;", 0, 0), (128, BILINEAR, 0, -1)], "field 3 is not a number"),
            (&[(128, BILINEAR, 0, 12)], "colour number 12 is neither"),
        ];
        for (entities, needle) in cases {
            let m = parse_iges(&iges_file_coloured(entities), "w.igs").unwrap();
            assert!(m.colors.is_empty(), "{needle}");
            let w: Vec<&String> = m.warnings.iter().filter(|w| w.contains("colour ignored")).collect();
            assert_eq!(w.len(), 1, "{:?}", m.warnings);
            assert!(w[0].contains(needle) && w[0].contains("directory entry"), "{}", w[0]);
        }
        // the same bad pointer on two surfaces: one warning that counts the other
        let m = parse_iges(&iges_file_coloured(cases[0].0), "w.igs").unwrap();
        assert!(m.warnings.iter().any(|w| w.contains("and 1 more surfaces")), "{:?}", m.warnings);
    }

    /// The coefficients of entity 114 records, read independently of the
    /// reader: (TU, TV, 48 coefficients of each of the (M+1)×(N+1) patches).
    fn records_114(text: &str) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        let mut recs: std::collections::BTreeMap<usize, String> = Default::default();
        for l in text.lines().filter(|l| l.len() > 72 && &l[72..73] == "P") {
            recs.entry(l[64..72].trim().parse().unwrap()).or_default().push_str(&l[..64]);
        }
        recs.values()
            .filter(|r| r.starts_with("114,"))
            .map(|r| {
                let f: Vec<f64> =
                    r.split(';').next().unwrap().split(',').skip(1).map(|x| x.trim().parse().unwrap()).collect();
                let (m, n) = (f[2] as usize, f[3] as usize);
                (f[4..5 + m].to_vec(), f[5 + m..6 + m + n].to_vec(), f[6 + m + n..].to_vec())
            })
            .collect()
    }

    #[test]
    fn parametric_spline_surfaces_become_exact_bezier_patches() {
        // a real file of four 114 entities (8×3, 6×3, 8×3 and 8×6 bicubic patches)
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cad/surf114.igs");
        let text = std::fs::read_to_string(&path).unwrap();
        let m = parse_iges(&text, "surf114.igs").unwrap();
        assert_eq!(m.surfaces.len(), 114);
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);
        assert_eq!(m.units.as_deref(), Some("inch"));
        let recs = records_114(&text);
        assert_eq!(recs.len(), 4);
        let mut k = 0;
        let mut worst: f64 = 0.0;
        for (tu, tv, c) in &recs {
            let n = tv.len() - 1;
            for i in 0..tu.len() - 1 {
                for j in 0..n {
                    let s = &m.surfaces[k];
                    assert_eq!(s.range, ((tu[i], tu[i + 1]), (tv[j], tv[j + 1])));
                    let at = 48 * (i * (n + 1) + j);
                    for step in 0..25 {
                        let (fu, fv) = ((step % 5) as f64 / 4.0, (step / 5) as f64 / 4.0);
                        let (u, v) = (tu[i] + fu * (tu[i + 1] - tu[i]), tv[j] + fv * (tv[j + 1] - tv[j]));
                        let (ds, dt) = (u - tu[i], v - tv[j]);
                        let p = s.surface.point(u, v);
                        for q in 0..3 {
                            let mut want = 0.0;
                            for b in 0..4 {
                                for a in 0..4 {
                                    want += c[at + 16 * q + 4 * b + a] * ds.powi(a as i32) * dt.powi(b as i32);
                                }
                            }
                            worst = worst.max((p[q] - want).abs());
                        }
                    }
                    k += 1;
                }
            }
        }
        // the polynomials themselves, to rounding (the model is about 4 inches across)
        assert!(worst < 1e-11, "{worst}");
        // neighbouring patches meet to the file's six digits
        let (a, b) = (&m.surfaces[0], &m.surfaces[1]);
        let v = a.range.1.1;
        for f in [0.0, 0.3, 1.0] {
            let u = a.range.0.0 + f * (a.range.0.1 - a.range.0.0);
            let (p, q) = (a.surface.point(u, v), b.surface.point(u, v));
            assert!((0..3).all(|t| (p[t] - q[t]).abs() < 1e-5), "{p:?} {q:?}");
        }
    }

    #[test]
    fn malformed_parametric_spline_surfaces_name_the_entry() {
        let patch = |m: &str, n: &str, tu: &str, coef: &str| -> String {
            let mut r = format!("114,3,1,{m},{n},{tu},0.,1.");
            for k in 0..4 * 48 {
                r += &format!(",{}", if k == 5 { coef } else { "0." });
            }
            r + ";"
        };
        for (rec, needle) in [
            (patch("1", "1", "0.,1.", "1."), ""),
            (patch("0", "1", "0.,1.", "1."), "M (u segments) = 0"),
            (patch("40", "1", "0.,1.", "1."), "needs"),
            (patch("1", "1", "1.,1.", "1."), "breakpoints TU do not rise"),
            (patch("1", "1", "0.,1.", "zz"), "coefficient F of x 'zz'"),
        ] {
            let r = parse_iges(&iges_file(&[(114, &rec)]), "s.igs");
            if needle.is_empty() {
                assert_eq!(r.unwrap().surfaces.len(), 1);
                continue;
            }
            let e = r.unwrap_err().to_string();
            assert!(
                e.contains("s.igs")
                    && e.contains("directory entry 1")
                    && e.contains("entity 114")
                    && e.contains(needle),
                "{e}"
            );
        }
    }

    /// Points of patch `s` on a 9×9 grid of its parameter range.
    fn grid(s: &IgesSurface) -> Vec<[f64; 3]> {
        let ((u0, u1), (v0, v1)) = s.range;
        (0..81)
            .map(|k| s.surface.point(u0 + (u1 - u0) * (k % 9) as f64 / 8.0, v0 + (v1 - v0) * (k / 9) as f64 / 8.0))
            .collect()
    }

    #[test]
    fn surfaces_of_revolution_are_exact() {
        // a line parallel to the z axis, turned a whole turn: a cylinder of radius 2
        let m = parse_iges(
            &iges_file(&[
                (110, "110,0.,0.,0.,0.,0.,1.;"),
                (110, "110,2.,0.,0.,2.,0.,3.;"),
                (120, "120,1,3,0.,6.283185307179586;"),
            ]),
            "cyl.igs",
        )
        .unwrap();
        assert_eq!(m.surfaces.len(), 1);
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);
        let pts = grid(&m.surfaces[0]);
        assert!(pts.iter().all(|p| ((p[0].hypot(p[1])) - 2.0).abs() < 1e-12 && (-1e-12..=3.0 + 1e-12).contains(&p[2])));
        assert!(pts.iter().any(|p| p[0] < -1.9) && pts.iter().any(|p| p[1] < -1.9), "a whole turn");
        // a half circle (100) about the y axis: a unit sphere
        let m = parse_iges(
            &iges_file(&[
                (110, "110,0.,-1.,0.,0.,1.,0.;"),
                (100, "100,0.,0.,0.,0.,-1.,0.,1.;"),
                (120, "120,1,3,0.,6.283185307179586;"),
            ]),
            "sphere.igs",
        )
        .unwrap();
        let pts = grid(&m.surfaces[0]);
        assert!(pts.iter().all(|p| (p[0].hypot(p[1]).hypot(p[2]) - 1.0).abs() < 1e-12), "{pts:?}");
        // a quarter turn of a line crossing the axis' plane: a cone band between the angles
        let m = parse_iges(
            &iges_file(&[
                (110, "110,0.,0.,0.,0.,0.,1.;"),
                (110, "110,1.,0.,0.,2.,0.,1.;"),
                (120, "120,1,3,0.,1.5707963267948966;"),
            ]),
            "cone.igs",
        )
        .unwrap();
        for p in grid(&m.surfaces[0]) {
            assert!((p[0].hypot(p[1]) - (1.0 + p[2])).abs() < 1e-12 && p[0] > -1e-12 && p[1] > -1e-12, "{p:?}");
        }
    }

    #[test]
    fn tabulated_cylinders_move_their_curve_along_the_generatrix() {
        // a quadratic Bézier (126) moved to 5 above its start, then placed by a matrix (124)
        let bezier = "126,2,2,1,0,1,0,0.,0.,0.,1.,1.,1.,1.,1.,1.,0.,0.,0.,1.,2.,0.,2.,0.,0.,0.,0.,1.,0.,0.,1.;";
        let m = parse_iges(
            &iges_file_placed(&[
                (126, bezier, 0),
                (124, "124,1.,0.,0.,10.,0.,1.,0.,0.,0.,0.,1.,0.;", 0),
                (122, "122,1,0.,0.,5.;", 3),
            ]),
            "tab.igs",
        )
        .unwrap();
        assert_eq!(m.surfaces.len(), 1);
        let s = &m.surfaces[0];
        assert_eq!(s.range, ((0.0, 1.0), (0.0, 1.0)));
        for k in 0..25 {
            let (t, v) = ((k % 5) as f64 / 4.0, (k / 5) as f64 / 4.0);
            let c = [2.0 * t * (1.0 - t) + 2.0 * t * t, 4.0 * t * (1.0 - t)];
            let p = s.surface.point(t, v);
            let want = [10.0 + c[0], c[1], 5.0 * v];
            assert!((0..3).all(|i| (p[i] - want[i]).abs() < 1e-12), "({t}, {v}): {p:?} {want:?}");
        }
    }

    #[test]
    fn swept_surfaces_that_cannot_be_read_are_skipped_with_a_warning() {
        for (entities, needle) in [
            (
                vec![
                    (126, "126,1,1,1,0,1,0,0.,0.,1.,1.,1.,1.,0.,0.,0.,1.,0.,0.,0.,1.;"),
                    (110, "110,1.,0.,0.,1.,0.,1.;"),
                    (120, "120,1,3,0.,1.;"),
                ],
                "not a line (110)",
            ),
            (
                vec![
                    (110, "110,0.,0.,0.,0.,0.,1.;"),
                    (104, "104,1.,0.,1.,0.,0.,-1.,0.,1.,0.,-1.,0.;"),
                    (120, "120,1,3,0.,1.;"),
                ],
                "hitex sweeps lines (110)",
            ),
            (
                vec![(110, "110,0.,0.,0.,0.,0.,1.;"), (110, "110,1.,0.,0.,1.,0.,1.;"), (120, "120,1,3,1.,0.5;")],
                "not within one turn",
            ),
            (vec![(110, "110,1.,0.,0.,1.,0.,1.;"), (122, "122,1,1.,0.,0.;")], "zero length"),
            (vec![(110, "110,1.,0.,0.,1.,0.,1.;"), (122, "122,7,1.,0.,0.;")], "names no directory entry"),
            (
                vec![(110, "110,1.,0.,0.,1.,zz,1.;"), (122, "122,1,1.,0.,5.;")],
                "entity 110 (entry 1): field 6 is not a number",
            ),
        ] {
            let mut all = entities.clone();
            all.push((128, BILINEAR));
            let m = parse_iges(&iges_file(&all), "w.igs").unwrap();
            assert_eq!(m.surfaces.len(), 1, "the rest of the file loads: {needle}");
            let w: Vec<&String> = m.warnings.iter().filter(|w| w.contains("skipped:")).collect();
            assert!(
                w.len() == 1 && w[0].contains("directory entry") && w[0].contains(needle),
                "{needle}: {:?}",
                m.warnings
            );
        }
    }

    #[test]
    fn a_file_of_curves_only_says_so() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/cad/curve_geom_plate.igs");
        let e = load_iges(&path).unwrap_err().to_string();
        assert!(
            e.contains("curve_geom_plate.igs") && e.contains("126 (rational B-spline curve)") && e.contains("114"),
            "{e}"
        );
    }

    #[test]
    fn tiny_file_reads_without_repairs() {
        let m = parse_iges(&tiny(BILINEAR), "tiny.igs").unwrap();
        assert_eq!(m.surfaces.len(), 1);
        assert!(m.repairs.is_empty(), "{:?}", m.repairs);
        let s = &m.surfaces[0].surface;
        assert_eq!((s.degree_u, s.degree_v, s.count_u, s.count_v), (1, 1, 2, 2));
        let p = s.point(0.5, 0.5);
        assert!((p[0] - 0.5).abs() < 1e-12 && (p[1] - 0.5).abs() < 1e-12 && (p[2] - 0.25).abs() < 1e-12, "{p:?}");
    }

    #[test]
    fn malformed_records_name_entity_and_record() {
        let cases = [
            ("128,1,1,1,1,0,0,1,0,0,0.,0.,1.,1.;", "needs"),
            ("128,1,1,0,1,0,0,1,0,0,0.,1.,0.,0.,1.,1.;", "M1"),
            (
                "128,1,1,1,1,0,0,1,0,0,0.,0.,1.,1.,0.,0.,1.,1.,1.,-1.,1.,1.,0.,0.,0.,1.,0.,0.,0.,1.,0.,1.,1.,1.,0.,1.,0.,1.;",
                "weight",
            ),
            (
                "128,1,1,1,1,0,0,1,0,0,0.,1.,0.5,1.,0.,0.,1.,1.,1.,1.,1.,1.,0.,0.,0.,1.,0.,0.,0.,1.,0.,1.,1.,1.,0.,1.,0.,1.;",
                "knot",
            ),
            (
                "128,1,1,1,1,0,0,1,0,0,0.,0.,1.,1.,0.,0.,1.,1.,1.,1.,1.,1.,0.,zz,0.,1.,0.,0.,0.,1.,0.,1.,1.,1.,0.,1.,0.,1.;",
                "'zz'",
            ),
            ("128,999999,999999,3,3,0,0,1,0,0,0.;", "declare more control points"),
            ("128,1e300,1,3,3,0,0,1,0,0,0.;", "K1 1e300 is out of range"),
            ("126,1,1;", "directory says entity 128"),
        ];
        for (rec, needle) in cases {
            let e = parse_iges(&tiny(rec), "bad.igs").unwrap_err().to_string();
            assert!(e.contains("bad.igs") && e.contains("directory entry 1") && e.contains(needle), "{rec}: {e}");
        }
        // truncated lines and garbage
        let e = parse_iges("short line\n", "t.igs").unwrap_err().to_string();
        assert!(e.contains("line 1"), "{e}");
        let e = parse_iges("", "empty.igs").unwrap_err().to_string();
        assert!(e.contains("no directory"), "{e}");
    }

    #[test]
    fn teapot_reads_with_repairs_and_matches_reference_samples() {
        // kept in the repository (the same files as ../shared/data/nurbs): the
        // samples were evaluated by an independent library
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/teapot.igs");
        let refs = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/teapot_reference_samples.jsonl");
        let m = load_iges(&path).unwrap();
        assert_eq!(m.surfaces.len(), 32);
        assert!(!m.repairs.is_empty(), "the teapot file is known to be inconsistent");
        let text = std::fs::read_to_string(&refs).unwrap();
        let mut n = 0;
        for l in text.lines() {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            let patch = v["patch"].as_u64().unwrap() as usize;
            let (u, w) = (v["u"].as_f64().unwrap(), v["v"].as_f64().unwrap());
            let s = &m.surfaces[patch].surface;
            let p = s.point(u, w);
            let nrm = s.normal(u, w);
            for t in 0..3 {
                assert!((p[t] - v["point"][t].as_f64().unwrap()).abs() < 1e-9, "patch {patch} ({u}, {w}): {p:?}");
                assert!((nrm[t] - v["normal"][t].as_f64().unwrap()).abs() < 1e-7, "patch {patch} ({u}, {w}): {nrm:?}");
            }
            n += 1;
        }
        assert_eq!(n, 200);
    }
}
