//! Knot insertion (A5.1) and exact degree elevation.
//!
//! Degree elevation works the classical way: split the surface into Bézier
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

/// Elevates a clamped curve of homogeneous points from degree p to p + 1.
pub fn elevate_curve(p: usize, knots: &[f64], pw: &[[f64; 4]]) -> (Vec<f64>, Vec<[f64; 4]>) {
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
