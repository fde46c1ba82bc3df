//! Wavefront OBJ free-form surfaces: `cstype [rat] bspline`, `deg`, `surf`,
//! `parm`, `trim`/`hole` with `curv2d` curves in parameter space, `end`.
//! (`tobj` reads only the polygonal part of OBJ.)
//!
//! Control vertices come from `v x y z [w]` (u varies fastest in `surf`),
//! trimming curves from `vp u v [w]`. Errors name the file and line; sizes
//! are checked against the vertices present before anything is built.

use crate::iges::{IgesSurface, sample_curve_2d};
use crate::{DataError, IoError};
use hitex_core::nurbs::NurbsSurface;
use std::path::Path;

/// Largest OBJ file accepted, in bytes.
pub const MAX_FREEFORM_FILE_BYTES: u64 = 1 << 30;

/// A `trim`/`hole` statement: whether it is a hole, and its (t0, t1, curve) parts.
type TrimRef = (bool, Vec<(f64, f64, i64)>);

#[derive(Default)]
struct Block {
    kind: Kind,
    line: usize,
    deg: (usize, usize),
    rational: bool,
    range: Option<((f64, f64), (f64, f64))>,
    cps: Vec<usize>,
    parm_u: Vec<f64>,
    parm_v: Vec<f64>,
    /// (is a hole, [(t0, t1, curve index)])
    trims: Vec<TrimRef>,
}

#[derive(Default, PartialEq, Eq, Clone, Copy)]
enum Kind {
    #[default]
    None,
    Surface,
    Curve2d,
}

/// Reads the free-form surfaces of an OBJ file.
pub fn load_obj_freeform(path: &Path) -> Result<Vec<IgesSurface>, IoError> {
    load_obj_freeform_warned(path).map(|(s, _)| s)
}

/// [`load_obj_freeform`], with what looks wrong though it parses (see
/// [`obj_freeform_warnings`]).
pub fn load_obj_freeform_warned(path: &Path) -> Result<(Vec<IgesSurface>, Vec<String>), IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let meta = std::fs::metadata(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    if meta.len() > MAX_FREEFORM_FILE_BYTES {
        return Err(fmt(format!("file of {} bytes exceeds the {MAX_FREEFORM_FILE_BYTES}-byte limit", meta.len())));
    }
    crate::limits::check_text_file(crate::limits::TextKind::ObjFreeform, meta.len()).map_err(|e| fmt(e.to_string()))?;
    let bytes = std::fs::read(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    let text = String::from_utf8_lossy(&bytes);
    let surfaces = obj_freeform(&text).map_err(fmt)?;
    Ok((surfaces, obj_freeform_warnings(&text)))
}

/// Signs of a truncated file in OBJ text that parses: a `surf` or `curv2d`
/// block still open at the end (it is dropped), or a last line without a
/// line end. One line each, naming the line.
pub fn obj_freeform_warnings(text: &str) -> Vec<String> {
    let mut w = Vec::new();
    let mut open: Option<(usize, &str)> = None;
    let mut lines = 0;
    for (i, raw) in text.lines().enumerate() {
        lines = i + 1;
        let line = raw.split('#').next().unwrap_or("");
        match line.split_whitespace().next() {
            Some(tag @ ("surf" | "curv2d")) => open = Some((i + 1, tag)),
            Some("end") => open = None,
            _ => {}
        }
    }
    if let Some((at, tag)) = open {
        w.push(format!(
            "the file ends inside the {tag} block of line {at} (no 'end'): that block is dropped; the file may be truncated"
        ));
    }
    if !text.is_empty() && !text.ends_with('\n') {
        w.push(format!("line {lines} has no line end: the file may be truncated"));
    }
    w
}

/// Parses OBJ text; errors carry the line number.
pub fn parse_obj_freeform(text: &str) -> Result<Vec<IgesSurface>, DataError> {
    obj_freeform(text).map_err(DataError::from)
}

fn obj_freeform(text: &str) -> Result<Vec<IgesSurface>, String> {
    let mut v: Vec<[f64; 4]> = Vec::new();
    let mut vp: Vec<[f64; 3]> = Vec::new();
    let mut rational = false;
    let mut deg = (0usize, 0usize);
    let mut block = Block::default();
    let mut surfaces: Vec<(Block, usize)> = Vec::new();
    let mut curves: Vec<Block> = Vec::new();
    let mut joined = String::new();
    let mut start_line = 0;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim_end();
        // continuation lines end with a backslash
        if joined.is_empty() {
            start_line = i + 1;
        }
        if let Some(head) = line.strip_suffix('\\') {
            joined.push_str(head);
            joined.push(' ');
            continue;
        }
        joined.push_str(line);
        let stmt = std::mem::take(&mut joined);
        let ln = start_line;
        let e = |m: String| format!("line {ln}: {m}");
        let mut it = stmt.split_whitespace();
        let Some(tag) = it.next() else { continue };
        let args: Vec<&str> = it.collect();
        let f = |s: &str| -> Result<f64, String> {
            s.parse::<f64>().ok().filter(|x| x.is_finite()).ok_or_else(|| e(format!("'{s}' is not a finite number")))
        };
        let index = |s: &str, n: usize| -> Result<usize, String> {
            let first = s.split('/').next().unwrap_or("");
            let k: i64 = first.parse().map_err(|_| e(format!("'{s}' is not a vertex index")))?;
            let idx = if k > 0 { k - 1 } else { n as i64 + k };
            if idx < 0 || idx as usize >= n {
                return Err(e(format!("vertex index {k} is out of range ({n} vertices so far)")));
            }
            Ok(idx as usize)
        };
        match tag {
            "v" => {
                if args.len() < 3 {
                    return Err(e("a vertex needs x y z".into()));
                }
                let w = if args.len() > 3 { f(args[3])? } else { 1.0 };
                v.push([f(args[0])?, f(args[1])?, f(args[2])?, w]);
            }
            "vp" => {
                if args.is_empty() {
                    return Err(e("a parameter vertex needs u [v [w]]".into()));
                }
                let g = |k: usize, d: f64| args.get(k).map(|s| f(s)).unwrap_or(Ok(d));
                vp.push([g(0, 0.0)?, g(1, 0.0)?, g(2, 1.0)?]);
            }
            "cstype" => {
                let (rat, ty) = match args.as_slice() {
                    ["rat", t] => (true, *t),
                    [t] => (false, *t),
                    _ => return Err(e("cstype needs [rat] TYPE".into())),
                };
                if ty != "bspline" {
                    return Err(e(format!("cstype '{ty}' is not supported (only bspline and rat bspline)")));
                }
                rational = rat;
            }
            "deg" => {
                let du: usize =
                    args.first().and_then(|s| s.parse().ok()).ok_or_else(|| e("deg needs a degree".into()))?;
                let dv: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(0);
                deg = (du, dv);
            }
            "surf" => {
                if args.len() < 5 {
                    return Err(e("surf needs s0 s1 t0 t1 and control vertices".into()));
                }
                let range = ((f(args[0])?, f(args[1])?), (f(args[2])?, f(args[3])?));
                let cps = args[4..].iter().map(|s| index(s, v.len())).collect::<Result<Vec<_>, _>>()?;
                block = Block {
                    kind: Kind::Surface,
                    line: ln,
                    deg,
                    rational,
                    range: Some(range),
                    cps,
                    ..Default::default()
                };
            }
            "curv2d" => {
                let cps = args.iter().map(|s| index(s, vp.len())).collect::<Result<Vec<_>, _>>()?;
                block = Block { kind: Kind::Curve2d, line: ln, deg, rational, cps, ..Default::default() };
            }
            "parm" => {
                let (dir, vals) = args.split_first().ok_or_else(|| e("parm needs u|v and knots".into()))?;
                let vals = vals.iter().map(|s| f(s)).collect::<Result<Vec<_>, _>>()?;
                match *dir {
                    "u" => block.parm_u = vals,
                    "v" => block.parm_v = vals,
                    d => return Err(e(format!("parm direction '{d}' is not u or v"))),
                }
            }
            "trim" | "hole" => {
                if !args.len().is_multiple_of(3) || args.is_empty() {
                    return Err(e(format!("{tag} needs triples u0 u1 curve")));
                }
                let mut parts = Vec::new();
                for c in args.chunks(3) {
                    let k: i64 = c[2].parse().map_err(|_| e(format!("'{}' is not a curve index", c[2])))?;
                    parts.push((f(c[0])?, f(c[1])?, k));
                }
                block.trims.push((tag == "hole", parts));
            }
            "end" => match block.kind {
                Kind::Surface => surfaces.push((std::mem::take(&mut block), curves.len())),
                Kind::Curve2d => curves.push(std::mem::take(&mut block)),
                Kind::None => return Err(e("'end' without a surf or curv2d".into())),
            },
            "curv" | "bmat" | "step" | "sp" | "scrv" | "con" => {
                return Err(e(format!("'{tag}' is not supported by this reader")));
            }
            _ => {} // polygonal statements, groups, materials: not ours
        }
    }
    if surfaces.is_empty() {
        return Err("no free-form surface (cstype bspline … surf … end) found".into());
    }
    // curves in parameter space, sampled
    let sample = |b: &Block, t0: f64, t1: f64| -> Result<Vec<[f64; 2]>, String> {
        let m = b.deg.0;
        let n = b.cps.len();
        if m == 0 || n < m + 1 || b.parm_u.len() != n + m + 1 {
            return Err(format!(
                "curv2d at line {}: {n} points of degree {m} need {} knots, got {}",
                b.line,
                n + m + 1,
                b.parm_u.len()
            ));
        }
        hitex_core::nurbs::validate_knots("curve", &b.parm_u, n, m)
            .map_err(|x| format!("curv2d at line {}: {x}", b.line))?;
        let pw: Vec<[f64; 3]> = b
            .cps
            .iter()
            .map(|&i| {
                let w = if b.rational { vp[i][2] } else { 1.0 };
                [vp[i][0] * w, vp[i][1] * w, w]
            })
            .collect();
        if pw.iter().any(|p| p[2] <= 0.0) {
            return Err(format!("curv2d at line {}: weights must be positive", b.line));
        }
        Ok(sample_curve_2d(m, &b.parm_u, &pw, t0, t1, (8 * n).clamp(16, 256)))
    };
    let mut out = Vec::with_capacity(surfaces.len());
    for (k, (b, ncurves)) in surfaces.iter().enumerate() {
        let at = format!("surf at line {}", b.line);
        let (p, q) = b.deg;
        let (ku, kv) = (&b.parm_u, &b.parm_v);
        if p == 0 || q == 0 {
            return Err(format!("{at}: 'deg' must give two degrees ≥ 1 before surf"));
        }
        if ku.len() < p + 2 || kv.len() < q + 2 {
            return Err(format!("{at}: parm u and parm v need at least degree + 2 knots"));
        }
        let (nu, nv) = (ku.len() - p - 1, kv.len() - q - 1);
        if nu * nv != b.cps.len() {
            return Err(format!("{at}: {} control vertices, but the knots make a {nu}×{nv} net", b.cps.len()));
        }
        let points = b.cps.iter().map(|&i| if b.rational { v[i] } else { [v[i][0], v[i][1], v[i][2], 1.0] }).collect();
        let s = NurbsSurface::new(p, q, nu, nv, ku.clone(), kv.clone(), points).map_err(|x| format!("{at}: {x}"))?;
        let dom = s.domain();
        let range = b
            .range
            .filter(|r| {
                dom.0.0 <= r.0.0
                    && r.0.0 < r.0.1
                    && r.0.1 <= dom.0.1
                    && dom.1.0 <= r.1.0
                    && r.1.0 < r.1.1
                    && r.1.1 <= dom.1.1
            })
            .unwrap_or(dom);
        let mut trim = Vec::new();
        let has_outer = b.trims.iter().any(|(hole, _)| !hole);
        if !b.trims.is_empty() && !has_outer {
            let ((u0, u1), (v0, v1)) = range;
            trim.push(vec![[u0, v0], [u1, v0], [u1, v1], [u0, v1], [u0, v0]]);
        }
        for (_, parts) in &b.trims {
            let mut lp: Vec<[f64; 2]> = Vec::new();
            for &(t0, t1, c) in parts {
                let idx = if c > 0 { c - 1 } else { *ncurves as i64 + c };
                let cb = usize::try_from(idx)
                    .ok()
                    .and_then(|i| curves.get(i))
                    .ok_or_else(|| format!("{at}: trim curve {c} does not exist ({} curv2d defined)", curves.len()))?;
                for pt in sample(cb, t0, t1)? {
                    if lp.last() != Some(&pt) {
                        lp.push(pt);
                    }
                }
            }
            if lp.len() >= 3 {
                if lp.first() != lp.last() {
                    lp.push(lp[0]);
                }
                trim.push(lp);
            }
        }
        out.push(IgesSurface { surface: s, range, directory_entry: k + 1, trim });
    }
    Ok(out)
}

/// OBJ free-form text of a model: control vertices with weights, one
/// `cstype rat bspline` surface per patch, and its trimming loops as
/// degree-1 `curv2d` curves (`trim` for the first loop, `hole` for the others).
pub fn to_obj_freeform(surfaces: &[IgesSurface]) -> String {
    use std::fmt::Write;
    let mut s = String::from("# written by hitex: rational B-spline surfaces\n");
    let mut vbase = 0usize;
    let mut vpbase = 0usize;
    let mut curves = 0usize;
    for p in surfaces {
        let n = &p.surface;
        // trimming loops first: a surface refers to curves defined before it
        let mut refs = Vec::new();
        for l in &p.trim {
            for q in l {
                let _ = writeln!(s, "vp {:?} {:?}", q[0], q[1]);
            }
            let m = l.len();
            let idx: Vec<String> = (1..=m).map(|k| (vpbase + k).to_string()).collect();
            let knots: Vec<String> = std::iter::once(0.0)
                .chain((0..m).map(|k| k as f64))
                .chain(std::iter::once((m - 1) as f64))
                .map(|k| format!("{k:?}"))
                .collect();
            let _ = writeln!(s, "cstype bspline\ndeg 1\ncurv2d {}\nparm u {}\nend", idx.join(" "), knots.join(" "));
            vpbase += m;
            curves += 1;
            refs.push((curves, (m - 1) as f64));
        }
        for c in &n.points {
            let _ = writeln!(s, "v {:?} {:?} {:?} {:?}", c[0], c[1], c[2], c[3]);
        }
        let idx: Vec<String> = (1..=n.points.len()).map(|k| (vbase + k).to_string()).collect();
        vbase += n.points.len();
        let ((u0, u1), (v0, v1)) = p.range;
        let fmt = |k: &[f64]| k.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(" ");
        let _ = writeln!(s, "cstype rat bspline\ndeg {} {}", n.degree_u, n.degree_v);
        let _ = writeln!(s, "surf {u0:?} {u1:?} {v0:?} {v1:?} {}", idx.join(" "));
        let _ = writeln!(s, "parm u {}\nparm v {}", fmt(&n.knots_u), fmt(&n.knots_v));
        for (k, (c, t1)) in refs.iter().enumerate() {
            let _ = writeln!(s, "{} 0.0 {t1:?} {c}", if k == 0 { "trim" } else { "hole" });
        }
        s.push_str("end\n");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncation_is_reported() {
        assert!(obj_freeform_warnings(QUAD).is_empty(), "{:?}", obj_freeform_warnings(QUAD));
        let cut = &QUAD[..QUAD.rfind("end").unwrap()];
        let w = obj_freeform_warnings(cut.trim_end());
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w[0].contains("ends inside the surf block") && w[1].contains("no line end"), "{w:?}");
    }

    #[test]
    fn round_trip_keeps_surfaces_exactly_and_trims_on_their_polylines() {
        let mut model = crate::iges::parse_iges(crate::models::TEAPOT_IGES, "teapot").unwrap().surfaces;
        let holed =
            crate::iges::load_iges(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/holed-square.igs")).unwrap();
        model.extend(holed.surfaces);
        let back = parse_obj_freeform(&to_obj_freeform(&model)).unwrap();
        assert_eq!(back.len(), model.len());
        for (a, b) in model.iter().zip(&back) {
            assert_eq!(a.surface, b.surface);
            assert_eq!(a.range, b.range);
            assert_eq!(a.trim.len(), b.trim.len());
            // polygonal trims come back vertex for vertex
            assert_eq!(a.trim, b.trim);
        }
    }

    const QUAD: &str = "# a rational bicubic\nv 0 0 0\nv 1 0 0\nv 2 0 0.5\nv 3 0 0\nv 0 1 0\nv 1 1 1 2\nv 2 1 1\nv 3 1 0\n\
v 0 2 0\nv 1 2 0.5\nv 2 2 0.3\nv 3 2 0\nv 0 3 0\nv 1 3 0\nv 2 3 0\nv 3 3 0.2\n\
cstype rat bspline\ndeg 3 3\nsurf 0 1 0 1 1 2 3 4 5 6 7 8 9 10 11 12 13 14 \\\n 15 16\nparm u 0 0 0 0 1 1 1 1\nparm v 0 0 0 0 1 1 1 1\nend\n";

    #[test]
    fn rational_patch_reads_with_weights_and_continuations() {
        let s = parse_obj_freeform(QUAD).unwrap();
        assert_eq!(s.len(), 1);
        let n = &s[0].surface;
        assert_eq!((n.degree_u, n.degree_v, n.count_u, n.count_v), (3, 3, 4, 4));
        assert_eq!(n.points[5], [1.0, 1.0, 1.0, 2.0]);
        assert!(s[0].trim.is_empty());
    }

    #[test]
    fn holes_trim_the_patch() {
        let text = format!(
            "{QUAD}vp 0.3 0.3\nvp 0.7 0.3\nvp 0.7 0.7\nvp 0.3 0.7\nvp 0.3 0.3\ncstype bspline\ndeg 1\ncurv2d 1 2 3 4 5\nparm u 0 0 1 2 3 4 4\nend\n\
             cstype rat bspline\ndeg 3 3\nsurf 0 1 0 1 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16\nparm u 0 0 0 0 1 1 1 1\nparm v 0 0 0 0 1 1 1 1\nhole 0 4 1\nend\n"
        );
        let s = parse_obj_freeform(&text).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[1].trim.len(), 2, "outer = domain boundary, plus the hole");
        assert!(s[1].trim[1].iter().all(|p| (0.3..=0.7).contains(&p[0]) && (0.3..=0.7).contains(&p[1])));
    }

    #[test]
    fn malformed_files_name_the_line() {
        let cases = [
            ("v 0 0\n", "line 1"),
            ("v 0 0 0\ncstype taylor\n", "line 2"),
            ("v 0 0 0\ndeg 3 3\nsurf 0 1 0 1 1 2\n", "line 3"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ncstype bspline\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nparm u 0 0 1 1\nparm v 0 0 1\nend\n",
                "surf at line 7",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ncstype bspline\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nparm u 0 1 0 1\nparm v 0 0 1 1\nend\n",
                "u knots",
            ),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0 0\ncstype rat bspline\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nparm u 0 0 1 1\nparm v 0 0 1 1\nend\n",
                "weight",
            ),
            ("v nan 0 0\n", "finite"),
            ("end\n", "without"),
            ("v 0 0 0\n", "no free-form surface"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ncstype bspline\ndeg 1 1\nsurf 0 1 0 1 1 2 3 4\nparm u 0 0 1 1\nparm v 0 0 1 1\nhole 0 1 9\nend\n",
                "trim curve 9",
            ),
        ];
        for (text, needle) in cases {
            let e = parse_obj_freeform(text).unwrap_err();
            assert!(e.message.contains(needle), "{text:?}: {e}");
        }
    }
}
