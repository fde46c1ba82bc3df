//! Curve entities: 142 curves on surfaces and the parameter-space curves
//! they refer to (sampled to the trim tolerance), and the 3-D curves of
//! revolved and tabulated surfaces as exact rational B-splines.

use super::*;

/// Entity 142: CRTN, SPTR, BPTR (curve in parameter space), CPTR, PREF.
pub(super) fn curve_on_surface(k: usize, parsed: &Parsed, transforms: &[i64]) -> Result<Vec<[f64; 2]>, String> {
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
pub(super) fn sample_curve(
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
pub(super) fn sample_curve_here(
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
pub(super) enum Conic {
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
pub(super) fn conic(q: &[f64]) -> Result<Conic, String> {
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
pub(super) fn sample_adaptive(f: &dyn Fn(f64) -> [f64; 2], t0: f64, t1: f64, tol: f64) -> Vec<[f64; 2]> {
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

/// The 3-D curve of entry `k` (110 line, 100 circular arc, 126 rational
/// B-spline curve) as an exact rational B-spline, its own matrix (124)
/// applied, with the parameter range the record gives it (126: V0..V1,
/// within its knots; 100: its angles; 110: 0..1).
pub(super) fn space_curve(k: usize, parsed: &Parsed, transforms: &[i64]) -> Result<(Curve, (f64, f64)), String> {
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
