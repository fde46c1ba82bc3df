//! STEP (ISO 10303-21; AP203, AP214, AP242) B-rep parts and assemblies as
//! trimmed rational B-spline patches.
//!
//! * [`part21`]: the exchange structure, read in one pass with every record's
//!   line kept for messages;
//! * `geometry`: placements, curves and surfaces; analytic surfaces become
//!   exact rational B-splines (circles are rational quadratics);
//! * `faces`: faces to patches with parameter-space trims sampled to a chord
//!   tolerance in model units.
//!
//! Assemblies are walked from their root shape representations through
//! `REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION` (an
//! `ITEM_DEFINED_TRANSFORMATION` from the child's placement to the parent's)
//! and `MAPPED_ITEM`s, so that a part used twice is drawn twice, each in its
//! place. Faces that cannot be read yet are skipped with a warning naming
//! the face and the reason; the rest of the model is kept.

mod colors;
mod faces;
pub(crate) mod geometry;
pub mod part21;

use crate::iges::IgesSurface;
use geometry::{Frame, Model};
use glam::DMat4;
use part21::{Param, Record};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::f64::consts::PI;
use std::path::Path;
use thiserror::Error;

/// Largest STEP file accepted, in bytes.
pub const MAX_STEP_FILE_BYTES: u64 = 1 << 30;

/// Deepest assembly nesting followed (deeper links are cycles or damage).
pub const MAX_ASSEMBLY_DEPTH: usize = 32;

/// Most face instances produced (a part placed many times multiplies).
pub const MAX_FACE_INSTANCES: usize = 1 << 20;

/// A STEP file that cannot be read.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("{file}: {}{}{message}", line.map(|l| format!("line {l}: ")).unwrap_or_default(),
    entity.map(|e| format!("#{e}: ")).unwrap_or_default())]
pub struct StepError {
    /// The file.
    pub file: String,
    /// 1-based line, where known.
    pub line: Option<usize>,
    /// The instance, where known.
    pub entity: Option<u64>,
    /// What is wrong.
    pub message: String,
}

/// How faces become patches.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepOptions {
    /// Largest distance, in model units, between a trim edge as drawn and the
    /// true edge. `None`: 1/10 000 of the diagonal of the model's vertices.
    pub chord_tolerance: Option<f64>,
}

/// What a STEP file held.
#[derive(Debug, Clone, Default)]
pub struct StepModel {
    /// One patch per face instance, in the order of the shells and faces;
    /// `directory_entry` holds the face's `#` number.
    pub surfaces: Vec<IgesSurface>,
    /// Faces skipped and entities not read, each naming the entity.
    pub warnings: Vec<String>,
    /// Inconsistencies found and repaired.
    pub repairs: Vec<String>,
    /// The schema of `FILE_SCHEMA` (e.g. `AUTOMOTIVE_DESIGN`).
    pub schema: String,
    /// The length unit (e.g. "mm").
    pub length_unit: String,
    /// The chord tolerance used, in model units.
    pub chord_tolerance: f64,
    /// Faces by surface type (`PLANE`, `CYLINDRICAL_SURFACE`, …), as read.
    pub surface_types: BTreeMap<String, usize>,
    /// Placed faces by kind of surface (`plane`, `cylinder`, `cone`, `sphere`,
    /// `torus`, `bspline`, `revolution`, `extrusion`, `offset`, `other`),
    /// skipped faces included.
    pub census: BTreeMap<&'static str, usize>,
    /// Part instances placed (1 for a single part).
    pub instances: usize,
    /// Each surface's colour (linear RGB) from the file's styles
    /// (`STYLED_ITEM` on the face, its shell or its solid), where it has one.
    pub colors: Vec<Option<[f32; 3]>>,
}

/// Reads a STEP file.
pub fn load_step(path: &Path, opts: &StepOptions) -> Result<StepModel, StepError> {
    let file = path.display().to_string();
    let err = |m: String| StepError { file: file.clone(), line: None, entity: None, message: m };
    let meta = std::fs::metadata(path).map_err(|e| err(e.to_string()))?;
    if meta.len() > MAX_STEP_FILE_BYTES {
        return Err(err(format!("{} bytes exceeds the {MAX_STEP_FILE_BYTES}-byte limit", meta.len())));
    }
    crate::limits::check_text_file(crate::limits::TextKind::Step, meta.len()).map_err(|e| err(e.to_string()))?;
    let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
    parse_step(&bytes, &file, opts)
}

/// Reads STEP text; `name` is used in messages.
pub fn parse_step(bytes: &[u8], name: &str, opts: &StepOptions) -> Result<StepModel, StepError> {
    let ex = part21::parse(bytes).map_err(|e| StepError {
        file: name.to_string(),
        line: Some(e.line),
        entity: e.entity,
        message: e.message,
    })?;
    let fail = |m: String| StepError { file: name.to_string(), line: None, entity: None, message: m };
    let records = &ex.records;
    let mut out = StepModel { schema: ex.schemas().join(", "), ..Default::default() };
    for d in &ex.duplicates {
        out.repairs.push(format!("#{d} is defined twice; the later record is used"));
    }
    let (angle_unit, length_unit) = units(records);
    out.length_unit = length_unit;
    let instances = placed_faces(records);
    if instances.is_empty() {
        return Err(fail(no_faces_message(records)));
    }
    let (centre, size) = faces::vertex_extent(records);
    let model = Model { records, angle_unit, centre, size };
    let tol = match opts.chord_tolerance {
        Some(t) if t > 0.0 && t.is_finite() => t,
        Some(t) => return Err(fail(format!("chord tolerance {t} must be positive"))),
        None if size > 0.0 => size * 1e-4,
        None => 1e-6,
    };
    out.chord_tolerance = tol;
    // a part instance: one representation in one placement
    let placed: HashSet<(u64, [u64; 16])> =
        instances.iter().map(|(_, rep, m)| (*rep, m.to_cols_array().map(f64::to_bits))).collect();
    out.instances = placed.len().max(1);

    let face_colors = colors::face_colors(records);
    // each face once, then placed per instance
    let mut built: HashMap<u64, Option<IgesSurface>> = HashMap::new();
    let mut skipped: BTreeMap<String, Vec<u64>> = BTreeMap::new();
    for (face, _, m) in &instances {
        *out.census.entry(census_key(&surface_type(records, *face))).or_default() += 1;
        let patch = built.entry(*face).or_insert_with(|| match faces::build_face(&model, *face, tol) {
            Ok(p) => {
                let kind = surface_type(records, *face);
                *out.surface_types.entry(kind).or_default() += 1;
                Some(p)
            }
            Err(e) => {
                let line = records.get(face).map_or(0, |r| r.line);
                skipped.entry(e.clone()).or_default().push(*face);
                let _ = line;
                None
            }
        });
        if let Some(p) = patch {
            let mut p = p.clone();
            if *m != DMat4::IDENTITY {
                geometry::transform_surface(&mut p.surface, m);
                // a placement of huge or broken coordinates makes no drawable surface
                if !p.surface.points.iter().all(|q| q.iter().all(|x| x.is_finite() && x.abs() <= 1e150)) {
                    skipped.entry("its placement moves it beyond finite coordinates".into()).or_default().push(*face);
                    continue;
                }
            }
            out.surfaces.push(p);
            out.colors.push(face_colors.get(face).copied());
        }
    }
    for (why, faces) in skipped {
        let list: Vec<String> = faces.iter().take(8).map(|f| format!("#{f}")).collect();
        let more = if faces.len() > 8 { format!(" and {} more", faces.len() - 8) } else { String::new() };
        let n = faces.len();
        out.warnings.push(format!(
            "{n} face{} skipped ({}{more}): {why}",
            if n == 1 { "" } else { "s" },
            list.join(", ")
        ));
    }
    if out.surfaces.is_empty() {
        return Err(fail(format!(
            "no face could be read: {}",
            out.warnings.first().cloned().unwrap_or_else(|| "no faces".into())
        )));
    }
    Ok(out)
}

/// The census name of a STEP surface type.
fn census_key(t: &str) -> &'static str {
    match t {
        "PLANE" => "plane",
        "CYLINDRICAL_SURFACE" => "cylinder",
        "CONICAL_SURFACE" => "cone",
        "SPHERICAL_SURFACE" => "sphere",
        "TOROIDAL_SURFACE" | "DEGENERATE_TOROIDAL_SURFACE" => "torus",
        "B_SPLINE_SURFACE" | "RATIONAL_B_SPLINE_SURFACE" => "bspline",
        "SURFACE_OF_REVOLUTION" => "revolution",
        "SURFACE_OF_LINEAR_EXTRUSION" => "extrusion",
        "OFFSET_SURFACE" => "offset",
        _ => "other",
    }
}

/// The surface type of a face, for the summary (a rectangular trim counts as
/// its basis surface).
fn surface_type(records: &HashMap<u64, Record>, face: u64) -> String {
    let mut surf = records
        .get(&face)
        .and_then(|r| r.parts.first())
        .and_then(|(_, p)| p.get(2))
        .and_then(Param::reference)
        .and_then(|s| records.get(&s));
    for _ in 0..8 {
        match surf.and_then(|r| r.part("RECTANGULAR_TRIMMED_SURFACE")) {
            Some(p) => surf = p.get(1).and_then(Param::reference).and_then(|b| records.get(&b)),
            None => break,
        }
    }
    match surf {
        Some(r) if geometry::is_spline_surface(r) => {
            if r.is("RATIONAL_B_SPLINE_SURFACE") {
                "RATIONAL_B_SPLINE_SURFACE".into()
            } else {
                "B_SPLINE_SURFACE".into()
            }
        }
        Some(r) => r.parts[0].0.clone(),
        None => "?".into(),
    }
}

/// Plane-angle unit (radians per unit) and the length unit's name.
fn units(records: &HashMap<u64, Record>) -> (f64, String) {
    let mut angle = 1.0;
    let mut length = String::from("unitless");
    for r in records.values() {
        if r.is("PLANE_ANGLE_UNIT") && r.is("CONVERSION_BASED_UNIT") {
            // CONVERSION_BASED_UNIT(name, PLANE_ANGLE_MEASURE_WITH_UNIT(value, radian))
            let factor = r
                .part("CONVERSION_BASED_UNIT")
                .and_then(|p| p.get(1))
                .and_then(Param::reference)
                .and_then(|m| records.get(&m))
                .and_then(|m| m.parts.first())
                .and_then(|(_, p)| p.first())
                .and_then(Param::number);
            let name = r.part("CONVERSION_BASED_UNIT").and_then(|p| p.first()).and_then(Param::text).unwrap_or("");
            angle = match factor {
                Some(f) if f > 0.0 && f.is_finite() => f,
                _ if name.eq_ignore_ascii_case("degree") => PI / 180.0,
                _ => 1.0,
            };
        }
        if r.is("LENGTH_UNIT") {
            if let Some(si) = r.part("SI_UNIT") {
                let prefix = match si.first() {
                    Some(Param::Enum(p)) => p.as_str(),
                    _ => "",
                };
                length = match prefix {
                    "MILLI" => "mm",
                    "CENTI" => "cm",
                    "KILO" => "km",
                    "MICRO" => "µm",
                    _ => "m",
                }
                .into();
            } else if let Some(c) = r.part("CONVERSION_BASED_UNIT") {
                length = c.first().and_then(Param::text).unwrap_or("unit").to_ascii_lowercase();
            }
        }
    }
    (angle, length)
}

/// Every face to draw, with the instance it belongs to and its placement.
fn placed_faces(records: &HashMap<u64, Record>) -> Vec<(u64, u64, DMat4)> {
    let model = Model { records, angle_unit: 1.0, centre: glam::DVec3::ZERO, size: 1.0 };
    // representation links: child → parent with a transform, and same-frame pairs
    let mut children: HashMap<u64, Vec<(u64, DMat4)>> = HashMap::new();
    let mut same: HashMap<u64, Vec<u64>> = HashMap::new();
    let mut is_child: HashSet<u64> = HashSet::new();
    let mut reps: Vec<u64> = Vec::new();
    let mut ids: Vec<&u64> = records.keys().collect();
    ids.sort();
    for &id in &ids {
        let r = &records[id];
        let Some(rel) = r.part("REPRESENTATION_RELATIONSHIP").or_else(|| r.part("SHAPE_REPRESENTATION_RELATIONSHIP"))
        else {
            if r.parts.iter().any(|(n, _)| n.ends_with("REPRESENTATION") && !n.starts_with("DEFINITIONAL"))
                && r.parts[0].1.get(1).and_then(Param::list).is_some()
            {
                reps.push(*id);
            }
            continue;
        };
        let (Some(a), Some(b)) = (rel.get(2).and_then(Param::reference), rel.get(3).and_then(Param::reference)) else {
            continue;
        };
        let t = r
            .part("REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION")
            .and_then(|p| p.first())
            .and_then(Param::reference)
            .and_then(|t| item_transform(&model, t));
        match t {
            Some(m) => {
                children.entry(b).or_default().push((a, m));
                is_child.insert(a);
            }
            None => {
                same.entry(a).or_default().push(b);
                same.entry(b).or_default().push(a);
            }
        }
    }
    // same-frame groups whose members are never placed as a child are roots
    let group = |start: u64| -> Vec<u64> {
        let mut seen = vec![start];
        let mut set: HashSet<u64> = HashSet::from([start]);
        let mut k = 0;
        while k < seen.len() {
            for n in same.get(&seen[k]).into_iter().flatten() {
                if set.insert(*n) {
                    seen.push(*n);
                }
            }
            k += 1;
        }
        seen
    };
    let mut out = Vec::new();
    let mut visited_roots: HashSet<u64> = HashSet::new();
    for &r in &reps {
        if visited_roots.contains(&r) {
            continue;
        }
        let g = group(r);
        visited_roots.extend(g.iter().copied());
        if g.iter().any(|x| is_child.contains(x)) {
            continue;
        }
        let mut walker = Walker { m: &model, children: &children, group_of: &group, path: Vec::new(), calls: 0 };
        walker.walk(&g, DMat4::IDENTITY, &mut out);
    }
    if out.is_empty() {
        // no representation structure: every face once, as placed
        for &id in &ids {
            if records[id].is("ADVANCED_FACE") || records[id].is("FACE_SURFACE") {
                out.push((*id, 0, DMat4::IDENTITY));
            }
        }
    }
    out
}

/// Most representations visited in one assembly walk (a file whose links
/// fan out into the same parts again and again stops here).
const MAX_WALK_CALLS: usize = 1 << 20;

struct Walker<'a, 'b> {
    m: &'a Model<'a>,
    children: &'b HashMap<u64, Vec<(u64, DMat4)>>,
    group_of: &'b dyn Fn(u64) -> Vec<u64>,
    /// Representations on the way down (a link back to one is a cycle).
    path: Vec<u64>,
    calls: usize,
}

impl Walker<'_, '_> {
    fn walk(&mut self, group: &[u64], at: DMat4, out: &mut Vec<(u64, u64, DMat4)>) {
        self.calls += 1;
        if self.path.len() > MAX_ASSEMBLY_DEPTH
            || self.calls > MAX_WALK_CALLS
            || out.len() >= MAX_FACE_INSTANCES
            || group.iter().any(|g| self.path.contains(g))
        {
            return;
        }
        let depth = self.path.len();
        self.path.extend_from_slice(group);
        for &rep in group {
            let Some(items) = self.m.records.get(&rep).and_then(|r| r.parts[0].1.get(1)).and_then(Param::list) else {
                continue;
            };
            for item in items.iter().filter_map(Param::reference) {
                self.items_faces(item, rep, at, out);
            }
            for (child, t) in self.children.get(&rep).into_iter().flatten() {
                let g = (self.group_of)(*child);
                self.walk(&g, at * *t, out);
            }
        }
        self.path.truncate(depth);
    }

    /// The faces of a representation item (solid, shell, surface model, mapped item).
    fn items_faces(&mut self, item: u64, rep: u64, at: DMat4, out: &mut Vec<(u64, u64, DMat4)>) {
        let m = self.m;
        let Some(r) = m.records.get(&item) else { return };
        let name = r.parts[0].0.as_str();
        let p = &r.parts[0].1;
        let refs = |k: usize| -> Vec<u64> {
            match p.get(k) {
                Some(Param::Ref(x)) => vec![*x],
                Some(Param::List(l)) => l.iter().filter_map(Param::reference).collect(),
                _ => vec![],
            }
        };
        match name {
            "MANIFOLD_SOLID_BREP" | "FACETED_BREP" => shells(m, &refs(1), rep, at, out),
            "BREP_WITH_VOIDS" => {
                shells(m, &refs(1), rep, at, out);
                shells(m, &refs(2), rep, at, out);
            }
            "SHELL_BASED_SURFACE_MODEL" | "FACE_BASED_SURFACE_MODEL" => shells(m, &refs(1), rep, at, out),
            "OPEN_SHELL" | "CLOSED_SHELL" | "CONNECTED_FACE_SET" => shells(m, &[item], rep, at, out),
            "ADVANCED_FACE" | "FACE_SURFACE" => out.push((item, rep, at)),
            "MAPPED_ITEM" => {
                // MAPPED_ITEM(name, REPRESENTATION_MAP(origin, representation), target)
                let Some(map) = p.get(1).and_then(Param::reference).and_then(|x| m.records.get(&x)) else { return };
                let Some(mp) = map.part("REPRESENTATION_MAP") else { return };
                let (Some(origin), Some(mapped), Some(target)) = (
                    mp.first().and_then(Param::reference),
                    mp.get(1).and_then(Param::reference),
                    p.get(2).and_then(Param::reference),
                ) else {
                    return;
                };
                if let (Ok(a), Ok(b)) = (m.frame(origin), m.frame(target)) {
                    let t = b.matrix() * a.matrix().inverse();
                    let g = (self.group_of)(mapped);
                    self.walk(&g, at * t, out);
                }
            }
            _ => {}
        }
    }
}

fn shells(m: &Model, ids: &[u64], rep: u64, at: DMat4, out: &mut Vec<(u64, u64, DMat4)>) {
    for s in ids {
        let Some(r) = m.records.get(s) else { continue };
        let Some(faces) = r.parts[0].1.get(1).and_then(Param::list) else { continue };
        for f in faces.iter().filter_map(Param::reference) {
            if out.len() < MAX_FACE_INSTANCES {
                out.push((f, rep, at));
            }
        }
    }
}

/// `ITEM_DEFINED_TRANSFORMATION(name, description, item_1, item_2)`: the
/// child's coordinates, where `item_1` is, to the parent's, where `item_2` is.
fn item_transform(m: &Model, id: u64) -> Option<DMat4> {
    let p = m.records.get(&id)?.part("ITEM_DEFINED_TRANSFORMATION")?;
    let a: Frame = m.frame(p.get(2)?.reference()?).ok()?;
    let b: Frame = m.frame(p.get(3)?.reference()?).ok()?;
    Some(b.matrix() * a.matrix().inverse())
}

/// Says what a file without faces holds.
fn no_faces_message(records: &HashMap<u64, Record>) -> String {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for r in records.values() {
        for (n, _) in &r.parts {
            if n.ends_with("SURFACE") || n.ends_with("CURVE") || n.ends_with("BREP") || n.ends_with("MESH") {
                *counts.entry(n.as_str()).or_default() += 1;
            }
        }
    }
    let mut held: Vec<(usize, &str)> = counts.into_iter().map(|(n, c)| (c, n)).collect();
    held.sort_by(|a, b| b.cmp(a));
    let held: Vec<String> = held.iter().take(6).map(|(c, n)| format!("{c} × {n}")).collect();
    format!(
        "no B-rep faces (ADVANCED_FACE) in {} record{}{}; hitex reads faces of solids and surface models",
        records.len(),
        if records.len() == 1 { "" } else { "s" },
        if held.is_empty() { String::new() } else { format!(" (it holds {})", held.join(", ")) }
    )
}

#[cfg(test)]
mod tests;
