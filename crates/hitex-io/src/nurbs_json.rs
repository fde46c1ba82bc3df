//! hitex's native NURBS format (JSON) and an IGES writer, so that models can
//! be saved, exchanged and read back exactly.
//!
//! ```json
//! {"format": "hitex-nurbs", "version": 2, "units": "mm", "patches": [
//!   {"degree": [3, 3], "count": [4, 4], "knots_u": [...], "knots_v": [...],
//!    "points": [[x, y, z, w], ...], "range": [[u0, u1], [v0, v1]],
//!    "trim": [[[u, v], ...], ...], "color": [r, g, b]}]}
//! ```
//! Points are Cartesian with their weight, `j * count_u + i` (i along u).
//! Version 2 adds the optional length unit and each patch's optional colour
//! (linear RGB, 0 to 1, as a STEP style gives it); a model with neither is
//! written as version 1, which both versions' readers read.

use crate::iges::IgesSurface;
use crate::{DataError, IoError};
use hitex_core::nurbs::NurbsSurface;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Largest native file accepted, in bytes.
pub const MAX_JSON_FILE_BYTES: u64 = 1 << 30;

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileJson {
    format: String,
    version: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    units: Option<String>,
    patches: Vec<PatchJson>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PatchJson {
    degree: [usize; 2],
    count: [usize; 2],
    knots_u: Vec<f64>,
    knots_v: Vec<f64>,
    points: Vec<[f64; 4]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    range: Option<[[f64; 2]; 2]>,
    /// Trimming loops in parameter space (even–odd rule).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    trim: Vec<Vec<[f64; 2]>>,
    /// Linear RGB (version 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    color: Option<[f32; 3]>,
}

/// A native model: its patches, and what version 2 adds.
#[derive(Debug, Clone)]
pub struct JsonModel {
    /// The patches (`directory_entry`: the patch's place, from 1).
    pub surfaces: Vec<IgesSurface>,
    /// Each patch's colour (linear RGB) where the file gives one; empty: none.
    pub colors: Vec<Option<[f32; 3]>>,
    /// The length unit where the file states one ("mm", "inch", …).
    pub units: Option<String>,
}

/// Reads a native JSON model.
pub fn load_nurbs_json(path: &Path) -> Result<JsonModel, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let meta = std::fs::metadata(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    if meta.len() > MAX_JSON_FILE_BYTES {
        return Err(fmt(format!("file of {} bytes exceeds the {MAX_JSON_FILE_BYTES}-byte limit", meta.len())));
    }
    crate::limits::check_text_file(crate::limits::TextKind::Json, meta.len()).map_err(|e| fmt(e.to_string()))?;
    let text = std::fs::read_to_string(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    nurbs_json(&text).map_err(fmt)
}

/// Parses native JSON text; errors name the patch and field.
pub fn parse_nurbs_json(text: &str) -> Result<JsonModel, DataError> {
    nurbs_json(text).map_err(DataError::from)
}

fn nurbs_json(text: &str) -> Result<JsonModel, String> {
    let f: FileJson = serde_json::from_str(text).map_err(|e| {
        // serde_json's message ends with the position; state it once, first
        let full = e.to_string();
        let msg = full.rsplit_once(" at line ").map_or(full.as_str(), |(m, _)| m);
        format!("line {}, column {}: {msg}", e.line(), e.column())
    })?;
    if f.format != "hitex-nurbs" {
        return Err(format!("format is '{}', expected 'hitex-nurbs'", f.format));
    }
    if f.version != 1 && f.version != 2 {
        return Err(format!("version {} is not supported (this reader knows versions 1 and 2)", f.version));
    }
    if f.version == 1 && (f.units.is_some() || f.patches.iter().any(|p| p.color.is_some())) {
        return Err("units and colours need version 2 (the file says version 1)".into());
    }
    if let Some(u) = &f.units
        && (u.trim().is_empty() || u.len() > 64 || u.chars().any(char::is_control))
    {
        return Err(format!("units {u:?} is not a unit name such as \"mm\" or \"inch\""));
    }
    if f.patches.is_empty() {
        return Err("the file has no patches".into());
    }
    let mut out = Vec::with_capacity(f.patches.len());
    let mut colors = Vec::with_capacity(f.patches.len());
    for (k, p) in f.patches.into_iter().enumerate() {
        if let Some(c) = p.color
            && !c.iter().all(|x| (0.0..=1.0).contains(x))
        {
            return Err(format!("patch {k}: color {c:?} must be three numbers from 0 to 1 (linear RGB)"));
        }
        colors.push(p.color);
        let s = NurbsSurface::new(p.degree[0], p.degree[1], p.count[0], p.count[1], p.knots_u, p.knots_v, p.points)
            .map_err(|e| format!("patch {k}: {e}"))?;
        let dom = s.domain();
        let range = match p.range {
            None => dom,
            Some([[u0, u1], [v0, v1]]) => {
                let ok = [u0, u1, v0, v1].iter().all(|x| x.is_finite())
                    && dom.0.0 <= u0
                    && u0 < u1
                    && u1 <= dom.0.1
                    && dom.1.0 <= v0
                    && v0 < v1
                    && v1 <= dom.1.1;
                if !ok {
                    return Err(format!(
                        "patch {k}: range [[{u0}, {u1}], [{v0}, {v1}]] is not inside the knot domain {dom:?}"
                    ));
                }
                ((u0, u1), (v0, v1))
            }
        };
        for (i, l) in p.trim.iter().enumerate() {
            if l.len() < 3 || l.iter().flatten().any(|x| !x.is_finite()) {
                return Err(format!("patch {k}: trim loop {i} needs at least three finite points"));
            }
        }
        out.push(IgesSurface { surface: s, range, directory_entry: k + 1, trim: p.trim });
    }
    if colors.iter().all(Option::is_none) {
        colors.clear();
    }
    Ok(JsonModel { surfaces: out, colors, units: f.units })
}

/// Native JSON text of a model's patches (version 1).
pub fn to_nurbs_json(surfaces: &[IgesSurface]) -> String {
    to_nurbs_json_with(surfaces, &[], None)
}

/// Native JSON text of a model with its patches' colours (linear RGB; empty
/// or shorter than the patches: the rest have none) and length unit, which
/// read back as given (version 2; version 1 when there is neither).
pub fn to_nurbs_json_with(surfaces: &[IgesSurface], colors: &[Option<[f32; 3]>], units: Option<&str>) -> String {
    let color = |k: usize| colors.get(k).copied().flatten();
    let v2 = units.is_some() || (0..surfaces.len()).any(|k| color(k).is_some());
    let f = FileJson {
        format: "hitex-nurbs".into(),
        version: if v2 { 2 } else { 1 },
        units: units.map(str::to_string),
        patches: surfaces
            .iter()
            .enumerate()
            .map(|(k, p)| PatchJson {
                degree: [p.surface.degree_u, p.surface.degree_v],
                count: [p.surface.count_u, p.surface.count_v],
                knots_u: p.surface.knots_u.clone(),
                knots_v: p.surface.knots_v.clone(),
                points: p.surface.points.clone(),
                range: Some([[p.range.0.0, p.range.0.1], [p.range.1.0, p.range.1.1]]),
                trim: p.trim.clone(),
                color: color(k),
            })
            .collect(),
    };
    serde_json::to_string(&f).unwrap_or_default()
}

/// IGES 5.3 text holding one entity 128 per surface (full-precision reals)
/// and, for trimmed surfaces, its loops as degree-1 parameter-space curves
/// (126) on the surface (142) bounding it (144), which read back exactly.
pub fn to_iges(surfaces: &[IgesSurface], description: &str) -> String {
    to_iges_in(surfaces, description, None)
}

/// [`to_iges`] with the model's length unit in the global section
/// (`units` as the readers name them: "mm", "inch", …; `None` or a unit
/// IGES has no flag for: millimetres, IGES's own default).
pub fn to_iges_in(surfaces: &[IgesSurface], description: &str, units: Option<&str>) -> String {
    to_iges_with(surfaces, &[], description, units)
}

/// The sRGB value that the IGES reader turns back nearest to linear `x`
/// (of a few steps of f32 about the encoding's value: exactly `x` where
/// one does, as 0 and 1 do; the decoding is steeper than one f32 step in
/// places, so not every linear value has an exact preimage).
fn srgb_of(x: f32) -> f32 {
    use hitex_core::texture::{linear_to_srgb, srgb_to_linear};
    let s = linear_to_srgb(x);
    let step = |v: f32, k: i32| f32::from_bits((v.to_bits() as i32 + k).max(0) as u32);
    let miss = |c: f32| (f64::from(srgb_to_linear(c)) - f64::from(x)).abs();
    // a short decimal first: of equally near values the first is kept
    let short = (s * 1e4).round() / 1e4;
    std::iter::once(short)
        .chain((-4..=4).map(|k| step(s, k)))
        .filter(|c| (0.0..=1.0).contains(c))
        .min_by(|a, b| miss(*a).total_cmp(&miss(*b)))
        .unwrap_or(s)
}

/// [`to_iges_in`] with each surface's colour (linear RGB, parallel to
/// `surfaces`; missing or `None`: no colour): one colour definition (314)
/// per distinct colour, in percent of sRGB intensity, named by the colour
/// number of the surfaces (and trimmed surfaces) that have it.
pub fn to_iges_with(
    surfaces: &[IgesSurface],
    colors: &[Option<[f32; 3]>],
    description: &str,
    units: Option<&str>,
) -> String {
    fn lines_of(data: &str, width: usize) -> Vec<String> {
        // break at delimiters so that no number is split
        let mut out = Vec::new();
        let mut cur = String::new();
        for tok in data.split_inclusive([',', ';']) {
            if cur.len() + tok.len() > width && !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
            cur.push_str(tok);
        }
        if !cur.is_empty() {
            out.push(cur);
        }
        out
    }
    let mut s = format!("{:<72}S{:>7}\n", description.chars().take(72).collect::<String>(), 1);
    let (flag, name) = units.and_then(crate::iges::iges_unit).unwrap_or((2, "MM"));
    let global = format!(
        "1H,,1H;,5Hhitex,9Hmodel.igs,5Hhitex,5Hhitex,32,38,6,308,15,5Hhitex,1.0,{flag},{}H{name},1,1.0,\
         15H20260101.000000,1e-09,1000.0,5Hhitex,5Hhitex,11,0;",
        name.len()
    );
    let glines = lines_of(&global, 72);
    for (i, l) in glines.iter().enumerate() {
        s += &format!("{l:<72}G{:>7}\n", i + 1);
    }
    // entities in file order: (type, record, status, colour number); entity
    // i has directory sequence number 2i + 1
    let mut ents: Vec<(u32, String, &str, i64)> = Vec::new();
    let de = |i: usize| 2 * i + 1;
    // the colour definitions first, one per distinct colour (bits compared)
    let mut defined: Vec<([u32; 3], usize)> = Vec::new();
    for c in colors.iter().take(surfaces.len()).flatten() {
        let key = c.map(f32::to_bits);
        if !defined.iter().any(|(k, _)| *k == key) {
            let pct = c.map(|x| format!("{:?}", f64::from(srgb_of(x)) * 100.0));
            defined.push((key, ents.len()));
            ents.push((314, format!("314,{},{},{};", pct[0], pct[1], pct[2]), "00000200", 0));
        }
    }
    let colour_number = |k: usize| -> i64 {
        let Some(Some(c)) = colors.get(k) else { return 0 };
        let key = c.map(f32::to_bits);
        defined.iter().find(|(d, _)| *d == key).map_or(0, |&(_, e)| -(de(e) as i64))
    };
    for (k, p) in surfaces.iter().enumerate() {
        let colour = colour_number(k);
        let n = &p.surface;
        let mut fields = vec![
            "128".to_string(),
            (n.count_u - 1).to_string(),
            (n.count_v - 1).to_string(),
            n.degree_u.to_string(),
            n.degree_v.to_string(),
            "0".into(),
            "0".into(),
            (if n.is_polynomial() { "1" } else { "0" }).into(),
            "0".into(),
            "0".into(),
        ];
        fields.extend(n.knots_u.iter().map(|x| format!("{x:?}")));
        fields.extend(n.knots_v.iter().map(|x| format!("{x:?}")));
        fields.extend(n.points.iter().map(|c| format!("{:?}", c[3])));
        for c in &n.points {
            fields.extend([0, 1, 2].map(|t| format!("{:?}", c[t])));
        }
        fields.extend([p.range.0.0, p.range.0.1, p.range.1.0, p.range.1.1].map(|x| format!("{x:?}")));
        let surface = ents.len();
        let trimmed = p.trim.iter().any(|l| l.len() >= 2);
        ents.push((128, fields.join(",") + ";", if trimmed { "00010000" } else { "00000000" }, colour));
        if !trimmed {
            continue;
        }
        // each loop: a degree-1 B-spline (126) through its vertices at
        // t = 0, 1, …, K in parameter space, on the surface (142)
        let mut curves = Vec::new();
        for l in p.trim.iter().filter(|l| l.len() >= 2) {
            let k = l.len() - 1;
            let closed = l.first() == l.last();
            let mut f = vec![
                "126".to_string(),
                k.to_string(),
                "1".into(),
                "1".into(),
                (if closed { "1" } else { "0" }).into(),
                "1".into(),
                "0".into(),
            ];
            f.push("0.0".into());
            f.extend((0..=k).map(|t| format!("{:?}", t as f64)));
            f.push(format!("{:?}", k as f64));
            f.extend((0..=k).map(|_| "1.0".to_string()));
            for q in l {
                f.extend([format!("{:?}", q[0]), format!("{:?}", q[1]), "0.0".into()]);
            }
            f.extend(["0.0".to_string(), format!("{:?}", k as f64), "0.0".into(), "0.0".into(), "1.0".into()]);
            let c126 = ents.len();
            ents.push((126, f.join(",") + ";", "00010500", 0));
            let c142 = ents.len();
            ents.push((142, format!("142,1,{},{},0,1;", de(surface), de(c126)), "00010000", 0));
            curves.push(c142);
        }
        let inner: Vec<String> = curves[1..].iter().map(|&c| de(c).to_string()).collect();
        let mut rec = format!("144,{},1,{},{}", de(surface), curves.len() - 1, de(curves[0]));
        for i in inner {
            rec += &format!(",{i}");
        }
        ents.push((144, rec + ";", "00000000", colour));
    }
    let mut dir = String::new();
    let mut par = String::new();
    let mut pline = 1usize;
    for (i, (ty, record, status, colour)) in ents.iter().enumerate() {
        let lines = lines_of(record, 64);
        let d = de(i);
        dir +=
            &format!("{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}D{:>7}\n", ty, pline, 0, 1, 0, 0, 0, 0, status, d);
        dir += &format!(
            "{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}D{:>7}\n",
            ty,
            0,
            colour,
            lines.len(),
            0,
            "",
            "",
            "",
            0,
            d + 1
        );
        for l in lines {
            par += &format!("{l:<64}{d:>8}P{pline:>7}\n");
            pline += 1;
        }
    }
    s += &dir;
    s += &par;
    s += &format!("{:<72}T{:>7}\n", format!("S{:>7}G{:>7}D{:>7}P{:>7}", 1, glines.len(), 2 * ents.len(), pline - 1), 1);
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iges::parse_iges;

    fn teapot() -> Vec<IgesSurface> {
        parse_iges(crate::models::TEAPOT_IGES, "teapot").unwrap().surfaces
    }

    #[test]
    fn json_round_trip_is_exact() {
        let mut a = teapot();
        let holed =
            crate::iges::load_iges(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/holed-square.igs")).unwrap();
        a.extend(holed.surfaces);
        let b = parse_nurbs_json(&to_nurbs_json(&a)).unwrap();
        assert_eq!(a.len(), b.surfaces.len());
        for (x, y) in a.iter().zip(&b.surfaces) {
            assert_eq!(x.surface, y.surface);
            assert_eq!(x.range, y.range);
            assert_eq!(x.trim, y.trim);
        }
        assert!(b.colors.is_empty() && b.units.is_none());
        assert!(to_nurbs_json(&a).contains(r#""version":1"#));
    }

    #[test]
    fn colours_and_units_read_back_as_written() {
        let a = teapot();
        // every other patch coloured, with values that need all of f32's digits
        let colors: Vec<Option<[f32; 3]>> =
            (0..a.len()).map(|k| (k % 2 == 0).then(|| [0.1 + k as f32 / 97.0, 1.0 / 3.0, 0.0])).collect();
        let text = to_nurbs_json_with(&a, &colors, Some("inch"));
        assert!(text.contains(r#""version":2"#) && text.contains(r#""units":"inch""#));
        let b = parse_nurbs_json(&text).unwrap();
        assert_eq!(b.colors, colors);
        assert_eq!(b.units.as_deref(), Some("inch"));
        // a unit alone is version 2 too; no colour at all reads back as none
        let b = parse_nurbs_json(&to_nurbs_json_with(&a, &[], Some("mm"))).unwrap();
        assert!(b.colors.is_empty());
        assert_eq!(b.units.as_deref(), Some("mm"));
    }

    #[test]
    fn iges_round_trip_is_exact_and_needs_no_repair() {
        let mut a = teapot();
        a.extend(crate::models::spray().into_iter().take(3).map(|s| {
            let range = s.domain();
            IgesSurface { surface: s, range, directory_entry: 0, trim: Vec::new() }
        }));
        let text = to_iges(&a, "round trip");
        let m = parse_iges(&text, "rt.igs").unwrap();
        assert!(m.repairs.is_empty(), "{:?}", m.repairs);
        assert_eq!(m.surfaces.len(), a.len());
        for (x, y) in a.iter().zip(&m.surfaces) {
            assert_eq!(x.surface, y.surface);
        }
    }

    #[test]
    fn iges_keeps_the_length_unit() {
        let a = teapot();
        for (units, back) in [(Some("inch"), "inch"), (Some("m"), "m"), (Some("mm"), "mm"), (None, "mm")] {
            let m = parse_iges(&to_iges_in(&a, "units", units), "u.igs").unwrap();
            assert_eq!(m.units.as_deref(), Some(back), "{units:?}");
        }
        // flag 3: the unit by name; a Hollerith string may hold delimiters
        let g = "1H,,1H;,7Ha,b;c.d,9Hmodel.igs,5Hhitex,5Hhitex,32,38,6,308,15,5Hhitex,1.0,3,4HINCH,1;";
        let p = crate::iges::tests_global_params(g);
        assert_eq!(p[2], "a,b;c.d");
        assert_eq!(p[13], "3");
        assert_eq!(p[14], "INCH");
    }

    #[test]
    fn iges_round_trip_keeps_colours() {
        // untrimmed teapot patches and the trimmed holed square, some coloured,
        // two sharing a colour, one without
        let mut a = teapot();
        a.truncate(4);
        a.extend(
            crate::iges::load_iges(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/holed-square.igs"))
                .unwrap()
                .surfaces,
        );
        let c =
            vec![Some([0.8, 0.1, 0.05]), None, Some([0.0, 0.5, 1.0]), Some([0.8, 0.1, 0.05]), Some([0.2, 0.3, 1.0])];
        let text = to_iges_with(&a, &c, "colours", None);
        assert_eq!(text.lines().filter(|l| l.starts_with("314,")).count(), 3, "one definition per distinct colour");
        let m = parse_iges(&text, "c.igs").unwrap();
        assert!(m.warnings.is_empty() && m.repairs.is_empty(), "{:?} {:?}", m.warnings, m.repairs);
        assert_eq!(m.colors.len(), a.len());
        for (k, (x, y)) in c.iter().zip(&m.colors).enumerate() {
            match (x, y) {
                (None, None) => {}
                (Some(x), Some(y)) => {
                    // through sRGB percent and back: within an f32 step or two
                    assert!(
                        (0..3).all(|t| (x[t] - y[t]).abs() <= 2.0 * f32::EPSILON * x[t]),
                        "surface {k}: {x:?} → {y:?}"
                    );
                }
                _ => panic!("surface {k}: {x:?} read back as {y:?}"),
            }
        }
        assert!(!m.surfaces[4].trim.is_empty(), "the trimmed surface stays trimmed");
        // black and full intensity come back exactly
        let back = m.colors[2].unwrap_or_default();
        assert_eq!((back[0], back[2]), (0.0, 1.0));
        // no colours: the file is the one written without them
        assert_eq!(to_iges_with(&a, &[], "colours", None), to_iges(&a, "colours"));
    }

    #[test]
    fn iges_round_trip_keeps_trims_exactly() {
        // outer loops and holes, and a loop with hundreds of vertices
        let mut a = crate::iges::load_iges(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/holed-square.igs"))
            .unwrap()
            .surfaces;
        assert!(a.iter().any(|s| s.trim.len() >= 2), "the fixture has holes");
        let mut fine = a[0].clone();
        let ((u0, u1), (v0, v1)) = fine.range;
        let ring: Vec<[f64; 2]> = (0..=457)
            .map(|i| {
                let t = i as f64 / 457.0 * std::f64::consts::TAU;
                let (c, s) = if i == 457 { (1.0, 0.0) } else { (t.cos(), t.sin()) };
                [u0 + (u1 - u0) * (0.5 + 0.4 * c), v0 + (v1 - v0) * (0.5 + 0.4 * s)]
            })
            .collect();
        fine.trim = vec![ring];
        a.push(fine);
        a.extend(teapot().into_iter().take(2));
        let m = parse_iges(&to_iges(&a, "trims"), "rt.igs").unwrap();
        assert!(m.repairs.is_empty(), "{:?}", m.repairs);
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);
        assert_eq!(m.surfaces.len(), a.len());
        for (x, y) in a.iter().zip(&m.surfaces) {
            assert_eq!(x.surface, y.surface);
            assert_eq!(x.range, y.range);
            assert_eq!(x.trim, y.trim);
        }
    }

    #[test]
    fn malformed_json_names_patch_and_field() {
        let cases = [
            ("{", "line 1"),
            (r#"{"format":"other","version":1,"patches":[]}"#, "expected 'hitex-nurbs'"),
            (r#"{"format":"hitex-nurbs","version":9,"patches":[]}"#, "version 9"),
            (r#"{"format":"hitex-nurbs","version":1,"patches":[]}"#, "no patches"),
            (
                r#"{"format":"hitex-nurbs","version":1,"patches":[{"degree":[1,1],"count":[2,2],"knots_u":[0,0,1,1],"knots_v":[0,0,1,1],"points":[[0,0,0,1],[1,0,0,1],[0,1,0,1],[1,1,0,0]]}]}"#,
                "patch 0: control point (1, 1)",
            ),
            (
                r#"{"format":"hitex-nurbs","version":1,"patches":[{"degree":[1,1],"count":[2,2],"knots_u":[0,1,0,1],"knots_v":[0,0,1,1],"points":[[0,0,0,1],[1,0,0,1],[0,1,0,1],[1,1,0,1]]}]}"#,
                "patch 0: u knots",
            ),
            (
                r#"{"format":"hitex-nurbs","version":1,"patches":[{"degree":[1,1],"count":[2,2],"knots_u":[0,0,1,1],"knots_v":[0,0,1,1],"points":[[0,0,0,1]]}]}"#,
                "patch 0",
            ),
            (
                r#"{"format":"hitex-nurbs","version":1,"patches":[{"degree":[1,1],"count":[2,2],"knots_u":[0,0,1,1],"knots_v":[0,0,1,1],"points":[[0,0,0,1],[1,0,0,1],[0,1,0,1],[1,1,0,1]],"range":[[0,2],[0,1]]}]}"#,
                "range",
            ),
            (r#"{"format":"hitex-nurbs","version":1,"patches":[],"extra":1}"#, "extra"),
            (r#"{"format":"hitex-nurbs","version":1,"units":"mm","patches":[]}"#, "need version 2"),
            (r#"{"format":"hitex-nurbs","version":2,"units":" ","patches":[]}"#, "not a unit name"),
            (
                r#"{"format":"hitex-nurbs","version":2,"patches":[{"degree":[1,1],"count":[2,2],"knots_u":[0,0,1,1],"knots_v":[0,0,1,1],"points":[[0,0,0,1],[1,0,0,1],[0,1,0,1],[1,1,0,1]],"color":[0.5,2,0]}]}"#,
                "patch 0: color [0.5, 2.0, 0.0] must be three numbers from 0 to 1",
            ),
        ];
        for (text, needle) in cases {
            let e = parse_nurbs_json(text).unwrap_err();
            assert!(e.message.contains(needle), "{text}: {e}");
        }
    }
}
