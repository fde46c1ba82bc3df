//! STEP geometry as exact rational B-splines: placements, the curves that
//! bound faces, and the surfaces faces lie on.
//!
//! Analytic surfaces (plane, cylinder, cone, sphere, torus) keep their own
//! parametrisation (ISO 10303-42: angles in radians, lengths along the axis)
//! for point inversion and trimming, and become rational B-splines over the
//! parameter window a face needs: circles and arcs are rational quadratics of
//! at most a quarter turn each, never polylines. The map from an angle to the
//! B-spline's parameter is exact (see [`Arc::param`]), so trims drawn in the
//! surface's own parameters land where they belong.

use super::part21::{Param, Record};
use glam::{DMat4, DVec2, DVec3};
use hitex_core::nurbs::{MAX_DEGREE, NurbsSurface};
use std::collections::HashMap;
#[cfg(test)]
use std::f64::consts::PI;
use std::f64::consts::{FRAC_PI_2, TAU};

mod curves;
#[cfg(test)]
mod tests;

pub(crate) use curves::*;

/// The entity names a B-spline surface record may carry.
const SPLINE_SURFACES: [&str; 5] =
    ["B_SPLINE_SURFACE", "B_SPLINE_SURFACE_WITH_KNOTS", "BEZIER_SURFACE", "UNIFORM_SURFACE", "QUASI_UNIFORM_SURFACE"];

/// Whether the record is a B-spline surface (simple or complex).
pub(crate) fn is_spline_surface(r: &Record) -> bool {
    SPLINE_SURFACES.iter().any(|n| r.is(n))
}

/// Entity lookups with messages that name the entity.
pub(crate) struct Model<'a> {
    pub records: &'a HashMap<u64, Record>,
    /// Radians per unit of plane angle in this file (1, or π/180 for degrees).
    pub angle_unit: f64,
    /// Centre and size of the model's vertices: where unbounded surfaces
    /// (extrusions of lines) are cut for point inversion.
    pub centre: DVec3,
    pub size: f64,
}

/// A message about entity `id`.
pub(crate) type GeomResult<T> = Result<T, String>;

impl<'a> Model<'a> {
    pub(crate) fn record(&self, id: u64) -> GeomResult<&'a Record> {
        self.records.get(&id).ok_or_else(|| format!("#{id} is referenced but not defined"))
    }

    /// Parameters of `id` as entity `name` (a simple record or that part of a
    /// complex one).
    pub(crate) fn params(&self, id: u64, name: &str) -> GeomResult<&'a [Param]> {
        let r = self.record(id)?;
        r.part(name).ok_or_else(|| format!("#{id} is {}, expected {name}", r.type_name()))
    }

    pub(crate) fn point(&self, id: u64) -> GeomResult<DVec3> {
        let p = self.params(id, "CARTESIAN_POINT")?;
        let c = coords(p.get(1), id, "coordinates")?;
        Ok(DVec3::new(c[0], c.get(1).copied().unwrap_or(0.0), c.get(2).copied().unwrap_or(0.0)))
    }

    pub(crate) fn direction(&self, id: u64) -> GeomResult<DVec3> {
        let p = self.params(id, "DIRECTION")?;
        let c = coords(p.get(1), id, "direction ratios")?;
        let d = DVec3::new(c[0], c.get(1).copied().unwrap_or(0.0), c.get(2).copied().unwrap_or(0.0));
        // scaled first, so that huge ratios normalise instead of overflowing
        let m = d.abs().max_element();
        (d / m).try_normalize().filter(|_| m > 0.0).ok_or_else(|| format!("#{id}: DIRECTION of zero length"))
    }

    /// `VECTOR(name, orientation, magnitude)` as a vector.
    pub(crate) fn vector(&self, id: u64) -> GeomResult<DVec3> {
        let p = self.params(id, "VECTOR")?;
        let d = self.direction(reference(p.get(1), id, "orientation")?)?;
        let m = number(p.get(2), id, "magnitude")?;
        Ok(d * m)
    }

    /// `AXIS2_PLACEMENT_3D` (or `_2D`) as a right-handed frame.
    pub(crate) fn frame(&self, id: u64) -> GeomResult<Frame> {
        let r = self.record(id)?;
        if let Some(p) = r.part("AXIS2_PLACEMENT_2D") {
            let o = self.point(reference(p.get(1), id, "location")?)?;
            let x = match p.get(2).and_then(Param::reference) {
                Some(d) => self.direction(d)?,
                None => DVec3::X,
            };
            return Ok(Frame::new(o, DVec3::Z, x));
        }
        let p = self.params(id, "AXIS2_PLACEMENT_3D")?;
        let o = self.point(reference(p.get(1), id, "location")?)?;
        let z = match p.get(2).and_then(Param::reference) {
            Some(d) => self.direction(d)?,
            None => DVec3::Z,
        };
        let x = match p.get(3).and_then(Param::reference) {
            Some(d) => self.direction(d)?,
            None => z.any_orthonormal_vector(),
        };
        Ok(Frame::new(o, z, x))
    }

    /// A curve (3-D or in a surface's parameter plane, then z = 0).
    pub(crate) fn curve(&self, id: u64, depth: usize) -> GeomResult<Curve> {
        if depth > 16 {
            return Err(format!("#{id}: curves nest too deeply"));
        }
        let r = self.record(id)?;
        if ["B_SPLINE_CURVE", "B_SPLINE_CURVE_WITH_KNOTS", "BEZIER_CURVE", "UNIFORM_CURVE", "QUASI_UNIFORM_CURVE"]
            .iter()
            .any(|n| r.is(n))
        {
            return self.spline_curve(id, r);
        }
        let (name, p) = (r.parts[0].0.as_str(), r.parts[0].1.as_slice());
        match name {
            "LINE" => {
                let o = self.point(reference(p.get(1), id, "pnt")?)?;
                let d = self.vector(reference(p.get(2), id, "dir")?)?;
                if d.length() <= 0.0 {
                    return Err(format!("#{id}: LINE with a zero direction"));
                }
                Ok(Curve::Line { o, d })
            }
            "CIRCLE" => {
                let f = self.frame(reference(p.get(1), id, "position")?)?;
                let r = positive(p.get(2), id, "radius")?;
                Ok(Curve::Ellipse { f, a: r, b: r })
            }
            "ELLIPSE" => {
                let f = self.frame(reference(p.get(1), id, "position")?)?;
                let a = positive(p.get(2), id, "semi_axis_1")?;
                let b = positive(p.get(3), id, "semi_axis_2")?;
                Ok(Curve::Ellipse { f, a, b })
            }
            "POLYLINE" => {
                let l = p.get(1).and_then(Param::list).ok_or_else(|| format!("#{id}: POLYLINE without points"))?;
                let pts =
                    l.iter().map(|q| self.point(reference(Some(q), id, "point")?)).collect::<GeomResult<Vec<_>>>()?;
                if pts.len() < 2 {
                    return Err(format!("#{id}: POLYLINE of {} point", pts.len()));
                }
                Ok(Curve::Polyline(pts))
            }
            // the edge's vertices bound it; the basis curve carries the geometry
            "TRIMMED_CURVE" => self.curve(reference(p.get(1), id, "basis_curve")?, depth + 1),
            "SURFACE_CURVE" | "SEAM_CURVE" | "INTERSECTION_CURVE" | "BOUNDED_CURVE" => {
                self.curve(reference(p.get(1), id, "curve_3d")?, depth + 1)
            }
            "PCURVE" => {
                // PCURVE(name, basis_surface, DEFINITIONAL_REPRESENTATION(name, (curve), context))
                let rep = self.params(reference(p.get(2), id, "reference_to_curve")?, "DEFINITIONAL_REPRESENTATION")?;
                let item = rep
                    .get(1)
                    .and_then(Param::list)
                    .and_then(|l| l.first())
                    .and_then(Param::reference)
                    .ok_or_else(|| format!("#{id}: PCURVE whose representation holds no curve"))?;
                self.curve(item, depth + 1)
            }
            other => Err(format!("#{id}: {other} curves are not read yet")),
        }
    }

    fn spline_curve(&self, id: u64, r: &Record) -> GeomResult<Curve> {
        // simple: B_SPLINE_CURVE_WITH_KNOTS(name, degree, points, form, closed, self_int, mults, knots, spec)
        // complex: B_SPLINE_CURVE(degree, points, form, closed, self_int) + _WITH_KNOTS(mults, knots, spec)
        let (base, knots_part): (&[Param], Option<&[Param]>) = if r.complex {
            let b = r.part("B_SPLINE_CURVE").ok_or_else(|| format!("#{id}: complex curve without B_SPLINE_CURVE"))?;
            (b, r.part("B_SPLINE_CURVE_WITH_KNOTS"))
        } else {
            let (n, p) = (&r.parts[0].0, r.parts[0].1.as_slice());
            if p.len() < 6 {
                return Err(format!("#{id}: {n} with {} attributes", p.len()));
            }
            (&p[1..6], if n == "B_SPLINE_CURVE_WITH_KNOTS" { Some(&p[6..]) } else { None })
        };
        let degree = count(base.first(), id, "degree")?;
        if degree == 0 || degree > MAX_DEGREE {
            return Err(format!("#{id}: curve degree {degree} is outside 1..={MAX_DEGREE}"));
        }
        let refs = base.get(1).and_then(Param::list).ok_or_else(|| format!("#{id}: no control points"))?;
        let pts = refs
            .iter()
            .map(|q| self.point(reference(Some(q), id, "control point")?))
            .collect::<GeomResult<Vec<_>>>()?;
        let n = pts.len();
        if n <= degree {
            return Err(format!("#{id}: {n} control points for degree {degree}"));
        }
        let knots = match knots_part {
            Some(k) => expand_knots(k.first(), k.get(1), id)?,
            // Bézier (or a plain B_SPLINE_CURVE): clamped, uniform pieces
            None => implied_knots(r, n, degree),
        };
        if knots.len() != n + degree + 1 {
            return Err(format!(
                "#{id}: {} knots for {n} control points of degree {degree} (need {})",
                knots.len(),
                n + degree + 1
            ));
        }
        hitex_core::nurbs::validate_knots("curve", &knots, n, degree).map_err(|e| format!("#{id}: {e}"))?;
        let weights = match r.part("RATIONAL_B_SPLINE_CURVE") {
            Some(w) => {
                let l = w.first().and_then(Param::list).ok_or_else(|| format!("#{id}: no weights"))?;
                let w: Vec<f64> = l.iter().map(|x| number(Some(x), id, "weight")).collect::<GeomResult<_>>()?;
                if w.len() != n || w.iter().any(|x| *x <= 0.0) {
                    return Err(format!("#{id}: {} weights for {n} control points, each must be positive", w.len()));
                }
                w
            }
            None => vec![1.0; n],
        };
        let pw = pts.iter().zip(&weights).map(|(p, w)| [p.x * w, p.y * w, p.z * w, *w]).collect();
        Ok(Curve::Spline { degree, knots, pw })
    }

    /// A face's surface.
    pub(crate) fn surface(&self, id: u64, depth: usize) -> GeomResult<Surface> {
        if depth > 8 {
            return Err(format!("#{id}: surfaces nest too deeply"));
        }
        let r = self.record(id)?;
        if is_spline_surface(r) {
            return Ok(Surface::new(Frame::IDENTITY, Kind::Spline(self.spline_surface(id, r)?)));
        }
        let (name, p) = (r.parts[0].0.as_str(), r.parts[0].1.as_slice());
        match name {
            "RECTANGULAR_TRIMMED_SURFACE" => {
                // (name, basis_surface, u1, u2, v1, v2, usense, vsense): the basis within those limits
                let mut basis = self.surface(reference(p.get(1), id, "basis_surface")?, depth + 1)?;
                let mut lim = [0.0; 4];
                for (k, l) in lim.iter_mut().enumerate() {
                    *l = number(p.get(2 + k), id, ["u1", "u2", "v1", "v2"][k])?;
                }
                let angle = basis.angular();
                let scale = |d: usize| if angle[d] { self.angle_unit } else { 1.0 };
                let (mut u, mut v) = ((lim[0] * scale(0), lim[1] * scale(0)), (lim[2] * scale(1), lim[3] * scale(1)));
                if basis.periodic()[0] && u.1 <= u.0 {
                    u.1 += TAU;
                }
                if basis.periodic()[1] && v.1 <= v.0 {
                    v.1 += TAU;
                }
                let b = [(u.0.min(u.1), u.0.max(u.1)), (v.0.min(v.1), v.0.max(v.1))];
                for d in 0..2 {
                    let (lo, hi) = b[d];
                    if !(lo.is_finite() && hi.is_finite() && hi > lo) || (angle[d] && hi - lo > TAU + 1e-9) {
                        return Err(format!("#{id}: parameter limits {lo}..{hi} are empty or more than a turn"));
                    }
                }
                basis.bounds = Some(b);
                return Ok(basis);
            }
            "SURFACE_OF_LINEAR_EXTRUSION" => {
                // σ(u, v) = λ(u) + v·V
                let curve = self.curve(reference(p.get(1), id, "swept_curve")?, 0)?;
                let axis = self.vector(reference(p.get(2), id, "extrusion_axis")?)?;
                if axis.length() <= 0.0 {
                    return Err(format!("#{id}: extrusion axis of zero length"));
                }
                if let Curve::Line { d, .. } = &curve
                    && d.normalize().cross(axis.normalize()).length() < 1e-12
                {
                    return Err(format!("#{id}: a line extruded along itself sweeps no surface"));
                }
                return Ok(Surface::new(Frame::IDENTITY, Kind::Extrusion { curve, axis }).near(self.centre, self.size));
            }
            "SURFACE_OF_REVOLUTION" => {
                // σ(u, v) = λ(v) turned by u about the axis
                let curve = self.curve(reference(p.get(1), id, "swept_curve")?, 0)?;
                let ap = self.params(reference(p.get(2), id, "axis_position")?, "AXIS1_PLACEMENT")?;
                let o = self.point(reference(ap.get(1), id, "axis location")?)?;
                let z = match ap.get(2).and_then(Param::reference) {
                    Some(d) => self.direction(d)?,
                    None => DVec3::Z,
                };
                // the angle is measured from the curve's own direction off the axis
                let (t0, t1) = curve.range();
                let mut x = DVec3::ZERO;
                for k in 0..=8 {
                    let d = curve.point(t0 + (t1 - t0) * k as f64 / 8.0) - o;
                    let r = d - z * d.dot(z);
                    if r.length() > x.length() {
                        x = r;
                    }
                }
                if x.length() <= 0.0 {
                    return Err(format!("#{id}: the swept curve lies on the axis"));
                }
                return Ok(Surface::new(Frame::new(o, z, x), Kind::Revolution { curve }).near(self.centre, self.size));
            }
            "OFFSET_SURFACE" => {
                let d = number(p.get(2), id, "distance").unwrap_or(f64::NAN);
                let basis = p.get(1).and_then(Param::reference).map_or("?".into(), |b| format!("#{b}"));
                return Err(format!(
                    "OFFSET_SURFACE (distance {d} from {basis}) is not drawn yet: its exact point S + d·N needs an \
                     evaluation of its own per fragment"
                ));
            }
            _ => {}
        }
        let frame = || self.frame(reference(p.get(1), id, "position")?);
        let kind: Kind = match name {
            "PLANE" => Kind::Plane,
            "CYLINDRICAL_SURFACE" => Kind::Cylinder { r: positive(p.get(2), id, "radius")? },
            "CONICAL_SURFACE" => {
                let r = number(p.get(2), id, "radius")?;
                let a = number(p.get(3), id, "semi_angle")? * self.angle_unit;
                if r < 0.0 || a.abs() >= FRAC_PI_2 - 1e-9 {
                    return Err(format!("#{id}: cone radius {r} and semi-angle {a} rad out of range"));
                }
                Kind::Cone { r, tan: a.tan() }
            }
            "SPHERICAL_SURFACE" => Kind::Sphere { r: positive(p.get(2), id, "radius")? },
            "TOROIDAL_SURFACE" | "DEGENERATE_TOROIDAL_SURFACE" => {
                let big = number(p.get(2), id, "major_radius")?;
                let small = positive(p.get(3), id, "minor_radius")?;
                if !big.is_finite() {
                    return Err(format!("#{id}: major radius is not finite"));
                }
                Kind::Torus { big, small }
            }
            other => return Err(format!("{other} surfaces are not read yet")),
        };
        Ok(Surface::new(frame()?, kind))
    }

    fn spline_surface(&self, id: u64, r: &Record) -> GeomResult<NurbsSurface> {
        let (base, knots_part): (&[Param], Option<&[Param]>) = if r.complex {
            let b =
                r.part("B_SPLINE_SURFACE").ok_or_else(|| format!("#{id}: complex surface without B_SPLINE_SURFACE"))?;
            (b, r.part("B_SPLINE_SURFACE_WITH_KNOTS"))
        } else {
            let (n, p) = (&r.parts[0].0, r.parts[0].1.as_slice());
            if p.len() < 8 {
                return Err(format!("#{id}: {n} with {} attributes", p.len()));
            }
            (&p[1..8], if n == "B_SPLINE_SURFACE_WITH_KNOTS" { Some(&p[8..]) } else { None })
        };
        let du = count(base.first(), id, "u_degree")?;
        let dv = count(base.get(1), id, "v_degree")?;
        for (d, dir) in [(du, "u"), (dv, "v")] {
            if d == 0 || d > MAX_DEGREE {
                return Err(format!("#{id}: {dir} degree {d} is outside 1..={MAX_DEGREE}"));
            }
        }
        let rows = base.get(2).and_then(Param::list).ok_or_else(|| format!("#{id}: no control points"))?;
        let nu = rows.len();
        let nv = rows.first().and_then(Param::list).map_or(0, |r| r.len());
        if nu <= du || nv <= dv {
            return Err(format!("#{id}: {nu}×{nv} control points for degrees {du}×{dv}"));
        }
        let mut grid = vec![DVec3::ZERO; nu * nv];
        for (i, row) in rows.iter().enumerate() {
            let row = row
                .list()
                .filter(|r| r.len() == nv)
                .ok_or_else(|| format!("#{id}: control row {i} is not {nv} points"))?;
            for (j, q) in row.iter().enumerate() {
                grid[j * nu + i] = self.point(reference(Some(q), id, "control point")?)?;
            }
        }
        let weights = match r.part("RATIONAL_B_SPLINE_SURFACE") {
            Some(w) => {
                let l = w.first().and_then(Param::list).ok_or_else(|| format!("#{id}: no weights"))?;
                let mut out = vec![1.0; nu * nv];
                if l.len() != nu {
                    return Err(format!("#{id}: {} weight rows for {nu} control rows", l.len()));
                }
                for (i, row) in l.iter().enumerate() {
                    let row = row
                        .list()
                        .filter(|r| r.len() == nv)
                        .ok_or_else(|| format!("#{id}: weight row {i} is not {nv} values"))?;
                    for (j, x) in row.iter().enumerate() {
                        out[j * nu + i] = number(Some(x), id, "weight")?;
                    }
                }
                out
            }
            None => vec![1.0; nu * nv],
        };
        let (ku, kv) = match knots_part {
            Some(k) => (expand_knots(k.first(), k.get(2), id)?, expand_knots(k.get(1), k.get(3), id)?),
            None => (implied_knots(r, nu, du), implied_knots(r, nv, dv)),
        };
        let pts = grid.iter().zip(&weights).map(|(p, w)| [p.x, p.y, p.z, *w]).collect();
        NurbsSurface::new(du, dv, nu, nv, ku, kv, pts).map_err(|e| format!("#{id}: {e}"))
    }
}

/// Knots implied by a B-spline entity that lists none (ISO 10303-42):
/// uniform (−p, −p+1, …), quasi-uniform (ends repeated p+1 times, unit steps
/// between) or Bézier (pieces of p+1 points joined at knots of multiplicity p).
fn implied_knots(r: &Record, n: usize, degree: usize) -> Vec<f64> {
    let uniform = r.is("UNIFORM_SURFACE") || r.is("UNIFORM_CURVE");
    let bezier = r.is("BEZIER_SURFACE") || r.is("BEZIER_CURVE");
    if uniform {
        return (0..n + degree + 1).map(|i| i as f64 - degree as f64).collect();
    }
    if bezier && (n - 1).is_multiple_of(degree) {
        let pieces = (n - 1) / degree;
        let mut k = vec![0.0; degree + 1];
        for i in 1..pieces {
            k.extend(std::iter::repeat_n(i as f64, degree));
        }
        k.extend(std::iter::repeat_n(pieces as f64, degree + 1));
        return k;
    }
    // quasi-uniform (and a Bézier entity whose point count makes no whole pieces)
    let inner = n - degree - 1;
    let mut k = vec![0.0; degree + 1];
    for i in 1..=inner {
        k.push(i as f64);
    }
    k.extend(std::iter::repeat_n((inner + 1) as f64, degree + 1));
    k
}

fn expand_knots(mults: Option<&Param>, knots: Option<&Param>, id: u64) -> GeomResult<Vec<f64>> {
    let m = mults.and_then(Param::list).ok_or_else(|| format!("#{id}: no knot multiplicities"))?;
    let k = knots.and_then(Param::list).ok_or_else(|| format!("#{id}: no knots"))?;
    if m.len() != k.len() {
        return Err(format!("#{id}: {} multiplicities for {} knots", m.len(), k.len()));
    }
    let mut out = Vec::new();
    for (mi, ki) in m.iter().zip(k) {
        let c = count(Some(mi), id, "multiplicity")?;
        // a multiplicity can never exceed the knots the file could describe
        if c == 0 || c > MAX_DEGREE + 1 {
            return Err(format!("#{id}: knot multiplicity {c} is outside 1..={}", MAX_DEGREE + 1));
        }
        let v = number(Some(ki), id, "knot")?;
        out.extend(std::iter::repeat_n(v, c));
    }
    Ok(out)
}

pub(crate) fn reference(p: Option<&Param>, id: u64, what: &str) -> GeomResult<u64> {
    p.and_then(Param::reference).ok_or_else(|| format!("#{id}: {what} is not a reference"))
}

pub(crate) fn number(p: Option<&Param>, id: u64, what: &str) -> GeomResult<f64> {
    match p.and_then(Param::number) {
        Some(v) if v.is_finite() => Ok(v),
        _ => Err(format!("#{id}: {what} is not a number")),
    }
}

fn positive(p: Option<&Param>, id: u64, what: &str) -> GeomResult<f64> {
    let v = number(p, id, what)?;
    if v > 0.0 { Ok(v) } else { Err(format!("#{id}: {what} {v} is not positive")) }
}

fn count(p: Option<&Param>, id: u64, what: &str) -> GeomResult<usize> {
    match p {
        Some(Param::Int(i)) if *i >= 0 && *i < (1 << 24) => Ok(*i as usize),
        _ => Err(format!("#{id}: {what} is not a small non-negative integer")),
    }
}

fn coords(p: Option<&Param>, id: u64, what: &str) -> GeomResult<Vec<f64>> {
    let l = p.and_then(Param::list).ok_or_else(|| format!("#{id}: no {what}"))?;
    if l.is_empty() || l.len() > 3 {
        return Err(format!("#{id}: {} {what}", l.len()));
    }
    l.iter().map(|v| number(Some(v), id, what)).collect()
}

/// The surfaces hitex reads.
#[derive(Debug, Clone)]
pub(crate) enum Kind {
    /// `o + s·x + t·y`
    Plane,
    /// `o + r(cos s·x + sin s·y) + t·z`
    Cylinder { r: f64 },
    /// `o + (r + t·tan α)(cos s·x + sin s·y) + t·z`
    Cone { r: f64, tan: f64 },
    /// `o + r cos t(cos s·x + sin s·y) + r sin t·z`
    Sphere { r: f64 },
    /// `o + (R + r cos t)(cos s·x + sin s·y) + r sin t·z`
    Torus { big: f64, small: f64 },
    /// Its own knot parameters.
    Spline(NurbsSurface),
    /// `λ(s) + t·axis` (s: the curve's parameter)
    Extrusion { curve: Curve, axis: DVec3 },
    /// `λ(t)` turned by s about the frame's z axis through its origin
    Revolution { curve: Curve },
}

/// A surface in its own parameters.
#[derive(Debug, Clone)]
pub(crate) struct Surface {
    pub frame: Frame,
    pub kind: Kind,
    /// Parameter limits of a RECTANGULAR_TRIMMED_SURFACE.
    pub bounds: Option<[(f64, f64); 2]>,
    /// Where the model is and how far points lie from it (for surfaces
    /// inverted on a provisional patch), and that patch once built.
    near: (DVec3, f64),
    patch: std::sync::OnceLock<Option<(NurbsSurface, ParamMap)>>,
}

impl Surface {
    pub(crate) fn new(frame: Frame, kind: Kind) -> Surface {
        Surface { frame, kind, bounds: None, near: (DVec3::ZERO, 1.0), patch: std::sync::OnceLock::new() }
    }

    /// The model's centre and size, for inversion patches of unbounded surfaces.
    fn near(mut self, centre: DVec3, size: f64) -> Surface {
        self.near = (centre, if size.is_finite() && size > 0.0 { size } else { 1.0 });
        self
    }

    /// Which parameters are periodic with period 2π.
    pub(crate) fn periodic(&self) -> [bool; 2] {
        match &self.kind {
            Kind::Plane | Kind::Spline(_) => [false, false],
            Kind::Cylinder { .. } | Kind::Cone { .. } | Kind::Sphere { .. } => [true, false],
            Kind::Torus { .. } => [true, true],
            Kind::Extrusion { curve, .. } => [curve.period().is_some(), false],
            Kind::Revolution { curve } => [true, curve.period().is_some()],
        }
    }

    /// Which parameters are angles (in the file's plane-angle unit where the
    /// file gives them).
    pub(crate) fn angular(&self) -> [bool; 2] {
        match &self.kind {
            Kind::Sphere { .. } => [true, true],
            _ => self.periodic(),
        }
    }

    /// A provisional B-spline to invert points on, for surfaces with no
    /// closed-form inversion, reaching twice the model's size past its centre
    /// where the surface is unbounded; built once.
    fn inversion_patch(&self) -> Option<&(NurbsSurface, ParamMap)> {
        self.patch
            .get_or_init(|| {
                let (centre, size) = self.near;
                let reach = 2.0 * size + (centre - self.frame.o).length();
                let win = match &self.kind {
                    Kind::Extrusion { curve, axis } => {
                        let w = curve.window(centre, reach);
                        let mid = curve.point(0.5 * (w.0 + w.1));
                        let v = (centre - mid).dot(*axis) / axis.length_squared();
                        let r = reach / axis.length();
                        [w, (v - r, v + r)]
                    }
                    Kind::Revolution { curve } => [(0.0, TAU), curve.window(centre, reach)],
                    _ => return None,
                };
                self.to_nurbs(win).ok()
            })
            .as_ref()
    }

    /// The point at parameters `(s, t)`.
    pub(crate) fn point(&self, st: DVec2) -> DVec3 {
        let f = &self.frame;
        let (s, t) = (st.x, st.y);
        let radial = |rho: f64, z: f64| f.o + (f.x * s.cos() + f.y * s.sin()) * rho + f.z * z;
        match &self.kind {
            Kind::Plane => f.o + f.x * s + f.y * t,
            Kind::Cylinder { r } => radial(*r, t),
            Kind::Cone { r, tan } => radial(r + t * tan, t),
            Kind::Sphere { r } => radial(r * t.cos(), r * t.sin()),
            Kind::Torus { big, small } => radial(big + small * t.cos(), small * t.sin()),
            Kind::Spline(n) => {
                let p = n.point(s, t);
                DVec3::from_array(p)
            }
            Kind::Extrusion { curve, axis } => curve.point(s) + *axis * t,
            Kind::Revolution { curve } => {
                let d = curve.point(t) - f.o;
                let z = f.z * d.dot(f.z);
                let r = d - z;
                f.o + z + r * s.cos() + f.z.cross(r) * s.sin()
            }
        }
    }

    /// The parameters of the point nearest `q`; periodic ones are taken
    /// within half a turn of `hint` when one is given.
    pub(crate) fn project(&self, q: DVec3, hint: Option<DVec2>) -> DVec2 {
        let l = self.frame.local(q);
        let near = |a: f64, h: Option<f64>| match h {
            Some(h) => a + TAU * ((h - a) / TAU).round(),
            None => a,
        };
        let rho = l.x.hypot(l.y);
        // on the axis the angle is undefined: keep the hint's
        let angle = if rho > 1e-12 * (1.0 + l.length()) { l.y.atan2(l.x) } else { hint.map_or(0.0, |h| h.x) };
        let s = near(angle, hint.map(|h| h.x));
        match &self.kind {
            Kind::Plane => DVec2::new(l.x, l.y),
            Kind::Cylinder { .. } => DVec2::new(s, l.z),
            Kind::Cone { r, tan } => {
                // nearest point on the generator line through (r + t·tan, t) in the (ρ, z) half-plane
                let t = ((rho - r) * tan + l.z) / (1.0 + tan * tan);
                DVec2::new(s, t)
            }
            Kind::Sphere { .. } => DVec2::new(s, l.z.atan2(rho)),
            Kind::Torus { big, .. } => {
                let t = l.z.atan2(rho - big);
                DVec2::new(s, near(t, hint.map(|h| h.y)))
            }
            Kind::Spline(n) => {
                let range = n.domain();
                let start = match hint {
                    Some(h) => [h.x, h.y],
                    None => coarse_start(n, q),
                };
                let (uv, _) = hitex_core::nurbs::continuity::invert(n, range, q.to_array(), start);
                DVec2::new(uv[0], uv[1])
            }
            Kind::Extrusion { .. } | Kind::Revolution { .. } => {
                // Newton on a provisional patch reaching past the point, then back to own parameters
                let Some((n, map)) = self.inversion_patch() else { return hint.unwrap_or(DVec2::ZERO) };
                let invert =
                    |start: [f64; 2]| hitex_core::nurbs::continuity::invert(n, n.domain(), q.to_array(), start);
                // from the hint, its angles brought into the patch's turn [0, 2π) ...
                let mut best = hint.map(|h| {
                    let mut h = h;
                    for d in 0..2 {
                        if self.periodic()[d] {
                            h[d] = h[d].rem_euclid(TAU);
                        }
                    }
                    invert(map.apply(h))
                });
                // ... and from the nearest of a coarse grid when that did not land on the surface
                let on_surface = 1e-9 * (1.0 + self.near.1 + (q - self.near.0).length());
                if best.is_none_or(|b| b.1 > on_surface) {
                    let other = invert(coarse_start(n, q));
                    if best.is_none_or(|b| other.1 < b.1) {
                        best = Some(other);
                    }
                }
                let uv = best.map_or([0.0; 2], |b| b.0);
                let mut st = map.invert([uv[0], uv[1]]);
                for d in 0..2 {
                    if self.periodic()[d]
                        && let Some(h) = hint
                    {
                        st[d] += TAU * ((h[d] - st[d]) / TAU).round();
                    }
                }
                st
            }
        }
    }

    /// The natural parameter window where the surface is bounded without
    /// trims (sphere, torus, B-spline), if it has one.
    pub(crate) fn natural_window(&self) -> Option<[(f64, f64); 2]> {
        if self.bounds.is_some() {
            return self.bounds;
        }
        match &self.kind {
            Kind::Sphere { .. } => Some([(0.0, TAU), (-FRAC_PI_2, FRAC_PI_2)]),
            Kind::Torus { .. } => Some([(0.0, TAU), (0.0, TAU)]),
            Kind::Spline(n) => {
                let d = n.domain();
                Some([d.0, d.1])
            }
            _ => None,
        }
    }

    /// The exact rational B-spline over the window `[s0, s1] × [t0, t1]` of
    /// the surface's own parameters, and the map from those parameters to
    /// the B-spline's.
    pub(crate) fn to_nurbs(&self, win: [(f64, f64); 2]) -> GeomResult<(NurbsSurface, ParamMap)> {
        let [(s0, s1), (t0, t1)] = win;
        let f = &self.frame;
        let plane = |s: f64, t: f64| f.o + f.x * s + f.y * t;
        match &self.kind {
            Kind::Plane => {
                let pts = [plane(s0, t0), plane(s1, t0), plane(s0, t1), plane(s1, t1)]
                    .iter()
                    .map(|p| [p.x, p.y, p.z, 1.0])
                    .collect();
                let s = NurbsSurface::new(1, 1, 2, 2, vec![s0, s0, s1, s1], vec![t0, t0, t1, t1], pts)
                    .map_err(|e| e.to_string())?;
                Ok((s, ParamMap { s: None, t: None }))
            }
            Kind::Cylinder { r } => {
                let prof = [(*r, t0, 1.0), (*r, t1, 1.0)];
                let arc = Arc::new(s0, s1)?;
                Ok((revolve(f, &arc, &prof, 1, &[t0, t0, t1, t1])?, ParamMap { s: Some(arc), t: None }))
            }
            Kind::Cone { r, tan } => {
                let prof = [(r + t0 * tan, t0, 1.0), (r + t1 * tan, t1, 1.0)];
                let arc = Arc::new(s0, s1)?;
                Ok((revolve(f, &arc, &prof, 1, &[t0, t0, t1, t1])?, ParamMap { s: Some(arc), t: None }))
            }
            Kind::Sphere { r } => {
                let (arc, varc) = (Arc::new(s0, s1)?, Arc::new(t0, t1)?);
                let (knots, ctrl) = varc.control();
                let prof: Vec<(f64, f64, f64)> = ctrl.iter().map(|c| (r * c.0, r * c.1, c.2)).collect();
                Ok((revolve(f, &arc, &prof, 2, &knots)?, ParamMap { s: Some(arc), t: Some(varc) }))
            }
            Kind::Torus { big, small } => {
                let (arc, varc) = (Arc::new(s0, s1)?, Arc::new(t0, t1)?);
                let (knots, ctrl) = varc.control();
                let prof: Vec<(f64, f64, f64)> = ctrl.iter().map(|c| (big + small * c.0, small * c.1, c.2)).collect();
                Ok((revolve(f, &arc, &prof, 2, &knots)?, ParamMap { s: Some(arc), t: Some(varc) }))
            }
            Kind::Spline(n) => Ok((n.clone(), ParamMap { s: None, t: None })),
            Kind::Extrusion { curve, axis } => {
                let (degree, knots, ctrl, arc) = curve.to_nurbs((s0, s1))?;
                let mut pts = Vec::with_capacity(2 * ctrl.len());
                for t in [t0, t1] {
                    for (p, w) in &ctrl {
                        let q = *p + *axis * t;
                        pts.push([q.x, q.y, q.z, *w]);
                    }
                }
                let s = NurbsSurface::new(degree, 1, ctrl.len(), 2, knots, vec![t0, t0, t1, t1], pts)
                    .map_err(|e| e.to_string())?;
                Ok((s, ParamMap { s: arc, t: None }))
            }
            Kind::Revolution { curve } => {
                let (degree, knots, ctrl, varc) = curve.to_nurbs((t0, t1))?;
                let arc = Arc::new(s0, s1)?;
                // each profile point in the axis frame: (ρ along its own radial direction, z)
                let prof: Vec<(DVec3, f64)> = ctrl;
                Ok((revolve3(f, &arc, &prof, degree, &knots)?, ParamMap { s: Some(arc), t: varc }))
            }
        }
    }
}

fn coarse_start(n: &NurbsSurface, q: DVec3) -> [f64; 2] {
    let ((u0, u1), (v0, v1)) = n.domain();
    let mut best = (f64::INFINITY, [u0, v0]);
    let k = 24;
    for i in 0..=k {
        for j in 0..=k {
            let (u, v) = (u0 + (u1 - u0) * i as f64 / k as f64, v0 + (v1 - v0) * j as f64 / k as f64);
            let d = DVec3::from_array(n.point(u, v)).distance_squared(q);
            if d < best.0 {
                best = (d, [u, v]);
            }
        }
    }
    best.1
}

/// Maps a surface's own parameters to its B-spline's: angles through their
/// arcs, other parameters unchanged.
#[derive(Debug, Clone)]
pub(crate) struct ParamMap {
    pub s: Option<Arc>,
    pub t: Option<Arc>,
}

impl ParamMap {
    pub(crate) fn apply(&self, st: DVec2) -> [f64; 2] {
        let f = |a: &Option<Arc>, x: f64| a.as_ref().map_or(x, |a| a.param(x));
        [f(&self.s, st.x), f(&self.t, st.y)]
    }

    /// The surface's own parameters at B-spline parameters `uv`.
    pub(crate) fn invert(&self, uv: [f64; 2]) -> DVec2 {
        let f = |a: &Option<Arc>, x: f64| a.as_ref().map_or(x, |a| a.angle(x));
        DVec2::new(f(&self.s, uv[0]), f(&self.t, uv[1]))
    }
}

/// Revolves profile control points `(P, w)` (anywhere in space) through
/// `arc` about the frame's z axis (NURBS Book A8.1, each point turned from
/// its own radial direction).
fn revolve3(f: &Frame, arc: &Arc, profile: &[(DVec3, f64)], degree: usize, knots: &[f64]) -> GeomResult<NurbsSurface> {
    let (uknots, circle) = arc.control();
    let (nu, nv) = (circle.len(), profile.len());
    let mut pts = Vec::with_capacity(nu * nv);
    for (p, wv) in profile {
        let d = *p - f.o;
        let z = f.z * d.dot(f.z);
        let r = d - z;
        let rho = r.length();
        let x = if rho > 0.0 { r / rho } else { f.x };
        let y = f.z.cross(x);
        for (cx, cy, wu) in &circle {
            let q = f.o + z + (x * *cx + y * *cy) * rho;
            pts.push([q.x, q.y, q.z, wu * wv]);
        }
    }
    NurbsSurface::new(2, degree, nu, nv, uknots, knots.to_vec(), pts).map_err(|e| e.to_string())
}

/// Revolves a profile given in the frame's (ρ along x, z along the axis)
/// half-plane, control points `(ρ, z, w)` of degree `degree` over `knots`,
/// through `arc` about the frame's z axis.
fn revolve(
    f: &Frame,
    arc: &Arc,
    profile: &[(f64, f64, f64)],
    degree: usize,
    knots: &[f64],
) -> GeomResult<NurbsSurface> {
    let (uknots, circle) = arc.control();
    let (nu, nv) = (circle.len(), profile.len());
    let mut pts = Vec::with_capacity(nu * nv);
    for (rho, z, wv) in profile {
        for (cx, cy, wu) in &circle {
            let p = f.o + (f.x * *cx + f.y * *cy) * *rho + f.z * *z;
            pts.push([p.x, p.y, p.z, wu * wv]);
        }
    }
    NurbsSurface::new(2, degree, nu, nv, uknots, knots.to_vec(), pts).map_err(|e| e.to_string())
}

/// Applies an affine placement to a surface's control points (exact: rational
/// B-splines are invariant under affine maps of their Cartesian points).
pub(crate) fn transform_surface(s: &mut NurbsSurface, m: &DMat4) {
    for p in &mut s.points {
        let q = m.transform_point3(DVec3::new(p[0], p[1], p[2]));
        p[0] = q.x;
        p[1] = q.y;
        p[2] = q.z;
    }
}
