//! Knot insertion (A5.1) and exact degree elevation.
//!
//! Degree elevation works the classical way: clamp the knot vector at the
//! ends of the domain (unclamped and periodic knots: see [`clamp_curve`]),
//! split the surface into Bézier
//! strips by knot insertion, raise each Bézier segment's degree by the
//! closed-form rule `Q_i = (i/(p+1)) P_{i−1} + (1 − i/(p+1)) P_i` in
//! homogeneous space, and join the segments again. The result is the same
//! surface (to rounding), with every interior knot of multiplicity p + 1 —
//! a valid, if not minimal, B-spline of degree p + 1.

use super::surface::NurbsSurface;

/// Inserts `u` once into a curve of homogeneous points (A5.1 for r = 1).
/// Returns the new knots and points.
pub fn insert_knot_curve(p: usize, knots: &[f64], pw: &[[f64; 4]], u: f64) -> (Vec<f64>, Vec<[f64; 4]>) {
    let n = pw.len() - 1;
    let k = super::knots::find_span(n, p, u, knots);
    let mut nk = Vec::with_capacity(knots.len() + 1);
    nk.extend_from_slice(&knots[..=k]);
    nk.push(u);
    nk.extend_from_slice(&knots[k + 1..]);
    let mut q = Vec::with_capacity(pw.len() + 1);
    for i in 0..=n + 1 {
        if i + p <= k {
            q.push(pw[i]);
        } else if i > k {
            q.push(pw[i - 1]);
        } else {
            let a = (u - knots[i]) / (knots[i + p] - knots[i]);
            let (p0, p1) = (pw[i - 1], pw[i]);
            q.push([0, 1, 2, 3].map(|t| a * p1[t] + (1.0 - a) * p0[t]));
        }
    }
    (nk, q)
}

/// The same curve over its domain `[U[p], U[n+1]]` with a clamped knot
/// vector (each end p + 1 times): each end knot is inserted until it has
/// multiplicity p, where the curve passes through one control point; the
/// points and knots beyond it, which only shape the curve outside the
/// domain, are dropped. Clamped curves come back unchanged.
pub fn clamp_curve(p: usize, knots: &[f64], pw: &[[f64; 4]]) -> (Vec<f64>, Vec<[f64; 4]>) {
    let (mut k, mut q) = (knots.to_vec(), pw.to_vec());
    let (a, b) = (knots[p], knots[pw.len()]);
    let count = |k: &[f64], x: f64| k.iter().filter(|&&t| t == x).count();
    // the start: a to multiplicity p, then from its first occurrence j keep
    // P[j−1]… (the curve's point at a) under a clamped start
    if k[..p].iter().any(|&t| t != a) {
        while count(&k, a) < p {
            (k, q) = insert_knot_curve(p, &k, &q, a);
        }
        let j = k.iter().position(|&t| t == a).unwrap_or(0);
        if j > 0 {
            q.drain(..j - 1);
            let mut nk = vec![a; p + 1];
            nk.extend_from_slice(&k[j + p..]);
            k = nk;
        }
    }
    // the end: b to multiplicity p, then keep …P[l−p] (l: b's last
    // occurrence) under a clamped end
    let n = q.len() - 1;
    if k[n + 2..].iter().any(|&t| t != b) {
        while count(&k, b) < p {
            (k, q) = insert_knot_curve(p, &k, &q, b);
        }
        if let Some(l) = k.iter().rposition(|&t| t == b)
            && l >= p
        {
            q.truncate(l - p + 1);
            k.truncate(l + 1);
            k.push(b);
        }
    }
    (k, q)
}

/// Elevates a curve of homogeneous points from degree p to p + 1 over its
/// domain (an unclamped knot vector is clamped first, [`clamp_curve`]).
pub fn elevate_curve(p: usize, knots: &[f64], pw: &[[f64; 4]]) -> (Vec<f64>, Vec<[f64; 4]>) {
    let (knots, pw) = clamp_curve(p, knots, pw);
    let (knots, pw) = (&knots[..], &pw[..]);
    // decompose into Bézier segments: every interior knot to multiplicity p
    let (mut k, mut q) = (knots.to_vec(), pw.to_vec());
    let interior: Vec<f64> = {
        let mut v: Vec<f64> = knots[p + 1..knots.len() - p - 1].to_vec();
        v.dedup();
        v
    };
    for &x in &interior {
        while k.iter().filter(|&&t| t == x).count() < p {
            let (nk, nq) = insert_knot_curve(p, &k, &q, x);
            k = nk;
            q = nq;
        }
    }
    // q now holds segments of p + 1 points sharing end points
    let segments = (q.len() - 1) / p;
    let mut out: Vec<[f64; 4]> = Vec::new();
    for s in 0..segments {
        let seg = &q[s * p..=s * p + p];
        let mut e = Vec::with_capacity(p + 2);
        for i in 0..=p + 1 {
            let a = i as f64 / (p + 1) as f64;
            let lo = if i == 0 { seg[0] } else { seg[i - 1] };
            let hi = if i == p + 1 { seg[p] } else { seg[i] };
            e.push([0, 1, 2, 3].map(|t| a * lo[t] + (1.0 - a) * hi[t]));
        }
        if s == 0 { out.extend_from_slice(&e) } else { out.extend_from_slice(&e[1..]) }
    }
    // knots: ends p + 2 times, interior knots p + 1 times
    let (a, b) = (knots[p], knots[knots.len() - p - 1]);
    let mut nk = vec![a; p + 2];
    for &x in &interior {
        nk.extend(std::iter::repeat_n(x, p + 1));
    }
    nk.extend(std::iter::repeat_n(b, p + 2));
    (nk, out)
}

impl NurbsSurface {
    /// The same surface with degree raised by one in u (`in_u`) or in v.
    pub fn elevate(&self, in_u: bool) -> NurbsSurface {
        let pw = self.homogeneous();
        let (nu, nv) = (self.count_u, self.count_v);
        let cart = |c: [f64; 4]| [c[0] / c[3], c[1] / c[3], c[2] / c[3], c[3]];
        if in_u {
            let mut rows = Vec::new();
            let mut knots = Vec::new();
            for j in 0..nv {
                let (k, q) = elevate_curve(self.degree_u, &self.knots_u, &pw[j * nu..(j + 1) * nu]);
                knots = k;
                rows.push(q);
            }
            let cu = rows[0].len();
            let points = rows.into_iter().flatten().map(cart).collect();
            NurbsSurface { degree_u: self.degree_u + 1, count_u: cu, knots_u: knots, points, ..self.clone() }
        } else {
            let mut cols = Vec::new();
            let mut knots = Vec::new();
            for i in 0..nu {
                let col: Vec<[f64; 4]> = (0..nv).map(|j| pw[j * nu + i]).collect();
                let (k, q) = elevate_curve(self.degree_v, &self.knots_v, &col);
                knots = k;
                cols.push(q);
            }
            let cv = cols[0].len();
            let mut points = Vec::with_capacity(cv * nu);
            for j in 0..cv {
                for col in &cols {
                    points.push(cart(col[j]));
                }
            }
            NurbsSurface { degree_v: self.degree_v + 1, count_v: cv, knots_v: knots, points, ..self.clone() }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nurbs::surface::tests::wavy;
    use proptest::prelude::*;

    /// A bicubic surface on unclamped knot vectors: uniform in u (as a
    /// periodic B-spline's), unclamped at one end only in v.
    fn unclamped() -> NurbsSurface {
        let (nu, nv) = (7, 6);
        let mut pts = Vec::new();
        for j in 0..nv {
            for i in 0..nu {
                let (x, y) = (i as f64, j as f64);
                pts.push([x, y, (0.9 * x).sin() * (0.7 * y).cos() + 0.1 * x * y, 1.0 + 0.3 * ((i + 2 * j) % 3) as f64]);
            }
        }
        let ku: Vec<f64> = (0..nu + 4).map(|i| i as f64 / 2.0).collect();
        let kv = vec![0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 3.5, 4.0, 4.5];
        NurbsSurface::new(3, 3, nu, nv, ku, kv, pts).unwrap()
    }

    #[test]
    fn unclamped_knots_are_clamped_before_elevation() {
        let s = unclamped();
        let ((u0, u1), (v0, v1)) = s.domain();
        assert_eq!((u0, u1, v0, v1), (1.5, 3.5, 0.0, 3.0));
        for e in [s.elevate(true), s.elevate(false), s.elevate(true).elevate(false)] {
            assert_eq!(e.domain(), s.domain());
            // the elevated direction is clamped: p + 1 equal knots at each end
            if e.degree_u > s.degree_u {
                let (p, k) = (e.degree_u, &e.knots_u);
                assert!(k[..=p].iter().all(|&x| x == u0) && k[k.len() - p - 1..].iter().all(|&x| x == u1), "{k:?}");
            }
            for a in 0..=20 {
                for b in 0..=20 {
                    let (u, v) = (u0 + (u1 - u0) * a as f64 / 20.0, v0 + (v1 - v0) * b as f64 / 20.0);
                    let (p, q) = (s.point(u, v), e.point(u, v));
                    for t in 0..3 {
                        assert!((p[t] - q[t]).abs() < 1e-10, "({u}, {v}): {p:?} vs {q:?}");
                    }
                }
            }
        }
        // clamping alone keeps the curve, and a clamped curve is left as it is
        let pw = s.homogeneous();
        let row = &pw[..7];
        let (k, q) = clamp_curve(3, &s.knots_u, row);
        assert_eq!(k.len(), q.len() + 4);
        let (k2, q2) = clamp_curve(3, &k, &q);
        assert_eq!((k2, q2), (k.clone(), q.clone()));
        // knot insertion on the unclamped vector keeps the surface as well
        let (ki, qi) = insert_knot_curve(3, &s.knots_u, row, 2.2);
        let curve = |knots: &[f64], pts: &[[f64; 4]], u: f64| {
            let c = NurbsSurface::new(
                3,
                1,
                pts.len(),
                2,
                knots.to_vec(),
                vec![0.0, 0.0, 1.0, 1.0],
                pts.iter().chain(pts).map(|c| [c[0] / c[3], c[1] / c[3], c[2] / c[3], c[3]]).collect(),
            )
            .unwrap();
            c.point(u, 0.0)
        };
        for a in 0..=20 {
            let u = u0 + (u1 - u0) * a as f64 / 20.0;
            let (p, q, r) = (curve(&s.knots_u, row, u), curve(&ki, &qi, u), curve(&k, &q, u));
            for t in 0..3 {
                assert!((p[t] - q[t]).abs() < 1e-10 && (p[t] - r[t]).abs() < 1e-10, "{u}: {p:?} {q:?} {r:?}");
            }
        }
    }

    proptest! {
        #[test]
        fn elevation_and_insertion_keep_the_surface(u in 0.0f64..=1.0, v in 0.0f64..=1.0, x in 0.01f64..0.99) {
            let s = wavy();
            let p = s.point(u, v);
            for e in [s.elevate(true), s.elevate(false), s.elevate(true).elevate(false).elevate(false)] {
                let q = e.point(u, v);
                for t in 0..3 {
                    prop_assert!((p[t] - q[t]).abs() < 1e-12, "{p:?} vs {q:?}");
                }
            }
            // knot insertion along u on every row
            let pw = s.homogeneous();
            let mut rows = Vec::new();
            let mut knots = Vec::new();
            for j in 0..s.count_v {
                let (k, q) = insert_knot_curve(3, &s.knots_u, &pw[j * 6..(j + 1) * 6], x);
                knots = k;
                rows.push(q);
            }
            let pts = rows.into_iter().flatten().map(|c| [c[0] / c[3], c[1] / c[3], c[2] / c[3], c[3]]).collect();
            let ins = NurbsSurface::new(3, 2, 7, s.count_v, knots, s.knots_v.clone(), pts).unwrap();
            let q = ins.point(u, v);
            for t in 0..3 {
                prop_assert!((p[t] - q[t]).abs() < 1e-12);
            }
        }
    }
}
