//! Placements and the curves that bound faces: frames, lines, circles,
//! ellipses and B-spline curves as exact rational B-splines, and circular
//! arcs as rational quadratics.

use super::*;

/// A right-handed orthonormal frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Frame {
    pub o: DVec3,
    pub x: DVec3,
    pub y: DVec3,
    pub z: DVec3,
}

impl Frame {
    pub(crate) const IDENTITY: Frame = Frame { o: DVec3::ZERO, x: DVec3::X, y: DVec3::Y, z: DVec3::Z };

    /// From an axis and a reference direction (made orthogonal to the axis).
    pub(crate) fn new(o: DVec3, z: DVec3, x_hint: DVec3) -> Frame {
        let z = z.normalize();
        let mut x = x_hint - z * x_hint.dot(z);
        if x.length() < 1e-12 {
            x = z.any_orthonormal_vector();
        }
        let x = x.normalize();
        Frame { o, x, y: z.cross(x), z }
    }

    /// The matrix taking frame coordinates to the parent's.
    pub(crate) fn matrix(&self) -> DMat4 {
        DMat4::from_cols(self.x.extend(0.0), self.y.extend(0.0), self.z.extend(0.0), self.o.extend(1.0))
    }

    /// `q` in frame coordinates.
    pub(crate) fn local(&self, q: DVec3) -> DVec3 {
        let d = q - self.o;
        DVec3::new(d.dot(self.x), d.dot(self.y), d.dot(self.z))
    }
}

/// A curve as a rational B-spline: degree, knots, Cartesian control points
/// with weights, and the arc mapping an ellipse's angle to its parameter.
pub(crate) type CurveNurbs = (usize, Vec<f64>, Vec<(DVec3, f64)>, Option<Arc>);

/// A curve bounding a face.
#[derive(Debug, Clone)]
pub(crate) enum Curve {
    /// `o + t·d`
    Line { o: DVec3, d: DVec3 },
    /// `o + a·cos t·x + b·sin t·y` (a circle when a = b); t in radians.
    Ellipse { f: Frame, a: f64, b: f64 },
    /// Homogeneous control points `(wx, wy, wz, w)`.
    Spline { degree: usize, knots: Vec<f64>, pw: Vec<[f64; 4]> },
    /// Vertex i at t = i.
    Polyline(Vec<DVec3>),
}

impl Curve {
    /// The period, for closed curves of a periodic parameter.
    pub(crate) fn period(&self) -> Option<f64> {
        matches!(self, Curve::Ellipse { .. }).then_some(TAU)
    }

    /// The curve's own parameter range (periodic: one turn from 0).
    pub(crate) fn range(&self) -> (f64, f64) {
        match self {
            Curve::Line { .. } => (0.0, 1.0),
            Curve::Ellipse { .. } => (0.0, TAU),
            Curve::Spline { degree, knots, .. } => (knots[*degree], knots[knots.len() - degree - 1]),
            Curve::Polyline(p) => (0.0, (p.len() - 1) as f64),
        }
    }

    pub(crate) fn point(&self, t: f64) -> DVec3 {
        match self {
            Curve::Line { o, d } => *o + *d * t,
            Curve::Ellipse { f, a, b } => f.o + f.x * (a * t.cos()) + f.y * (b * t.sin()),
            Curve::Spline { degree, knots, pw } => {
                let n = pw.len() - 1;
                let t = t.clamp(knots[*degree], knots[n + 1]);
                let span = hitex_core::nurbs::find_span(n, *degree, t, knots);
                let mut b = [0.0; MAX_DEGREE + 1];
                hitex_core::nurbs::basis_funs(span, t, *degree, knots, &mut b);
                let mut c = [0.0; 4];
                for r in 0..=*degree {
                    let q = pw[span - degree + r];
                    for k in 0..4 {
                        c[k] += b[r] * q[k];
                    }
                }
                DVec3::new(c[0], c[1], c[2]) / c[3]
            }
            Curve::Polyline(p) => {
                let t = t.clamp(0.0, (p.len() - 1) as f64);
                let i = (t.floor() as usize).min(p.len() - 2);
                p[i].lerp(p[i + 1], t - i as f64)
            }
        }
    }

    /// Pieces the curve has (a lower bound on the samples an edge needs).
    pub(crate) fn pieces(&self, t0: f64, t1: f64) -> usize {
        match self {
            Curve::Line { .. } => 1,
            // eight samples a turn before refinement
            Curve::Ellipse { .. } => (((t1 - t0).abs() / (TAU / 8.0)).ceil() as usize).max(2),
            Curve::Spline { degree, knots, .. } => {
                let (lo, hi) = (t0.min(t1), t0.max(t1));
                let spans = knots.windows(2).filter(|w| w[1] > w[0] && w[1] > lo && w[0] < hi).count();
                (spans * (*degree).max(2)).clamp(2, 4096)
            }
            Curve::Polyline(p) => p.len(),
        }
    }

    /// A parameter window covering the curve, `reach` either side of the
    /// point nearest `centre` where it is unbounded (a line).
    pub(crate) fn window(&self, centre: DVec3, reach: f64) -> (f64, f64) {
        match self {
            Curve::Line { o, d } => {
                let t = (centre - *o).dot(*d) / d.length_squared();
                let r = reach / d.length();
                (t - r, t + r)
            }
            other => other.range(),
        }
    }

    /// The curve as a rational B-spline over `(t0, t1)` of its parameter:
    /// degree, knots, Cartesian control points with weights, and for an
    /// ellipse the arc that maps its angle to the B-spline's parameter.
    /// B-spline curves and polylines keep their whole parameter range.
    pub(crate) fn to_nurbs(&self, (t0, t1): (f64, f64)) -> GeomResult<CurveNurbs> {
        Ok(match self {
            Curve::Line { .. } => (1, vec![t0, t0, t1, t1], vec![(self.point(t0), 1.0), (self.point(t1), 1.0)], None),
            Curve::Ellipse { f, a, b } => {
                let arc = Arc::new(t0, t1)?;
                let (knots, ctrl) = arc.control();
                let pts = ctrl.iter().map(|c| (f.o + f.x * (a * c.0) + f.y * (b * c.1), c.2)).collect();
                (2, knots, pts, Some(arc))
            }
            Curve::Spline { degree, knots, pw } => {
                let pts = pw.iter().map(|q| (DVec3::new(q[0], q[1], q[2]) / q[3], q[3])).collect();
                (*degree, knots.clone(), pts, None)
            }
            Curve::Polyline(p) => {
                let n = p.len();
                let mut knots = vec![0.0];
                knots.extend((0..n).map(|i| i as f64));
                knots.push((n - 1) as f64);
                (1, knots, p.iter().map(|q| (*q, 1.0)).collect(), None)
            }
        })
    }

    /// Whether the curve is exactly the straight chord between any two of
    /// its points (a line, or a polyline sampled at its vertices).
    pub(crate) fn is_straight(&self) -> bool {
        matches!(self, Curve::Line { .. })
    }

    /// The parameter of the curve point nearest `q` (the edge's vertices lie
    /// on it, up to the file's tolerance).
    pub(crate) fn param_of(&self, q: DVec3) -> f64 {
        match self {
            Curve::Line { o, d } => (q - *o).dot(*d) / d.length_squared(),
            Curve::Ellipse { f, a, b } => {
                let l = f.local(q);
                (l.y / b).atan2(l.x / a).rem_euclid(TAU)
            }
            Curve::Polyline(p) => {
                let mut best = (f64::INFINITY, 0.0);
                for i in 0..p.len() - 1 {
                    let (a, b) = (p[i], p[i + 1]);
                    let ab = b - a;
                    let s = if ab.length_squared() > 0.0 {
                        ((q - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    let d = (a + ab * s).distance_squared(q);
                    if d < best.0 {
                        best = (d, i as f64 + s);
                    }
                }
                best.1
            }
            Curve::Spline { .. } => {
                let (t0, t1) = self.range();
                let n = 64 * self.pieces(t0, t1).min(64);
                let mut best = (f64::INFINITY, t0);
                for k in 0..=n {
                    let t = t0 + (t1 - t0) * k as f64 / n as f64;
                    let d = self.point(t).distance_squared(q);
                    if d < best.0 {
                        best = (d, t);
                    }
                }
                // golden-section refinement on the bracket around the best sample
                let h = (t1 - t0) / n as f64;
                let (mut lo, mut hi) = ((best.1 - h).max(t0), (best.1 + h).min(t1));
                let g = 0.618_033_988_749_894_9;
                for _ in 0..80 {
                    let (m1, m2) = (hi - g * (hi - lo), lo + g * (hi - lo));
                    if self.point(m1).distance_squared(q) < self.point(m2).distance_squared(q) {
                        hi = m2;
                    } else {
                        lo = m1;
                    }
                }
                0.5 * (lo + hi)
            }
        }
    }
}

/// A circular arc from angle `a0` to `a1` (radians, a1 > a0, at most a turn)
/// as rational quadratic pieces of at most a quarter turn, with the knots at
/// the pieces' end angles.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Arc {
    pub a0: f64,
    pub a1: f64,
    pub pieces: usize,
}

impl Arc {
    /// An arc of at most one turn (anything else is no face's window).
    pub(crate) fn new(a0: f64, a1: f64) -> GeomResult<Arc> {
        if !(a0.is_finite() && a1.is_finite() && a1 > a0 && a1 - a0 <= TAU + 1e-9) {
            return Err(format!("an angular range from {a0} to {a1} rad is not within one turn"));
        }
        let pieces = (((a1 - a0) / FRAC_PI_2) - 1e-9).ceil().clamp(1.0, 4.0) as usize;
        Ok(Arc { a0, a1, pieces })
    }

    fn step(&self) -> f64 {
        (self.a1 - self.a0) / self.pieces as f64
    }

    /// Knots and the unit circle's control points `(x, y, w)` (Cartesian).
    pub(crate) fn control(&self) -> (Vec<f64>, Vec<(f64, f64, f64)>) {
        let d = self.step();
        let w = (0.5 * d).cos();
        let mut knots = vec![self.a0; 3];
        let mut pts = vec![(self.a0.cos(), self.a0.sin(), 1.0)];
        for k in 0..self.pieces {
            let (a, b) =
                (self.a0 + d * k as f64, if k + 1 == self.pieces { self.a1 } else { self.a0 + d * (k + 1) as f64 });
            let m = 0.5 * (a + b);
            pts.push((m.cos() / w, m.sin() / w, w));
            pts.push((b.cos(), b.sin(), 1.0));
            if k + 1 < self.pieces {
                knots.extend([b, b]);
            }
        }
        knots.extend([self.a1; 3]);
        (knots, pts)
    }

    /// The B-spline parameter of the arc point at angle `phi`. In a symmetric
    /// rational quadratic piece of sweep Δ, tan(ψ/2) of the angle ψ from the
    /// piece's middle is linear in the piece's parameter τ ∈ [0, 1]:
    /// tan(ψ/2) = (2τ − 1)·tan(Δ/4).
    pub(crate) fn param(&self, phi: f64) -> f64 {
        let d = self.step();
        let k = (((phi - self.a0) / d).floor().max(0.0) as usize).min(self.pieces - 1);
        let a = self.a0 + d * k as f64;
        let psi = (phi - (a + 0.5 * d)).clamp(-0.5 * d, 0.5 * d);
        let tau = 0.5 + (0.5 * psi).tan() / (2.0 * (0.25 * d).tan());
        a + d * tau.clamp(0.0, 1.0)
    }

    /// The angle at B-spline parameter `u` (the inverse of [`Arc::param`]).
    pub(crate) fn angle(&self, u: f64) -> f64 {
        let d = self.step();
        let k = (((u - self.a0) / d).floor().max(0.0) as usize).min(self.pieces - 1);
        let a = self.a0 + d * k as f64;
        let tau = ((u - a) / d).clamp(0.0, 1.0);
        a + 0.5 * d + 2.0 * ((2.0 * tau - 1.0) * (0.25 * d).tan()).atan()
    }
}
