//! Surface entities: 128 rational B-splines, 114 parametric splines, 120
//! revolved and 122 tabulated surfaces, 144 trimmed surfaces and the 124
//! matrices that place them.

use super::*;

pub(super) type Range = ((f64, f64), (f64, f64));

/// Entity 144 fields after the type: PTS, N1, N2, PTO, PTI(1..N2).
/// Returns the base surface's index and the loops in its parameter space.
pub(super) fn trimmed_surface(
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
pub(super) type Matrix34 = [[f64; 4]; 3];

/// The matrix that places entity `k` (the composition of its 124 and the
/// 124s that one refers to in turn), or `None` without one.
pub(super) fn transform_of(k: usize, transforms: &[i64], parsed: &Parsed) -> Result<Option<Matrix34>, String> {
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
pub(super) fn compose(a: &Matrix34, b: &Matrix34) -> Matrix34 {
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
pub(super) fn apply_124(s: &mut NurbsSurface, m: &Matrix34) {
    for p in &mut s.points {
        let q = [p[0], p[1], p[2]];
        for (r, row) in m.iter().enumerate() {
            p[r] = row[0] * q[0] + row[1] * q[1] + row[2] * q[2] + row[3];
        }
    }
}

/// Entity 120 fields after the type: L (the axis, a line 110), C (the
/// generatrix), SA, TA (start and terminate angles, radians). The
/// generatrix turned about the axis (counterclockwise looking down it from
/// its end), exactly: u the angle (rational quadratic arcs), v the curve's
/// parameter.
pub(super) fn revolution(f: &[&str], parsed: &Parsed, transforms: &[i64]) -> Result<(NurbsSurface, Range), String> {
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
pub(super) fn tabulated(f: &[&str], parsed: &Parsed, transforms: &[i64]) -> Result<(NurbsSurface, Range), String> {
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
pub(super) fn parse_114(f: &[&str]) -> Result<Vec<(NurbsSurface, Range)>, String> {
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

/// Entity 128 fields after the type: K1, K2, M1, M2, PROP1–5, knots S, knots
/// T, weights, control points, U0, U1, V0, V1.
pub(super) fn parse_128(f: &[&str]) -> Result<(NurbsSurface, Range), String> {
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
