//! B-rep faces to trimmed rational B-spline patches.
//!
//! A face (`ADVANCED_FACE`, `FACE_SURFACE`) is its surface bounded by loops of
//! oriented edges. Each edge is sampled adaptively along its curve between its
//! vertices, in the direction its `same_sense` and orientation give, until the
//! surface point at the middle of every parameter-space chord lies within the
//! chord tolerance of the true edge point. Parameters come from the edge's
//! PCURVE on that surface where the file has one, otherwise by inverting the
//! 3-D point on the surface (closed form on analytic surfaces, Newton on
//! B-splines), unwrapped along the loop so that angles stay continuous.
//!
//! Loops that wind once around a periodic parameter (the two circles that
//! bound a cylinder's side, a sphere's cap) bound no area on their own; they
//! are cut at one seam angle and closed along the far side of the face, on
//! the side the B-rep orientation says the face lies (material to the left of
//! each loop, seen from the face normal), so that the even–odd rule of the
//! renderer keeps exactly the face.

use super::geometry::{Curve, Kind, Model, Surface, reference};
use super::part21::Param;
use crate::iges::IgesSurface;
use glam::{DVec2, DVec3};
use hitex_core::nurbs::NurbsSurface;
use std::f64::consts::TAU;

/// Deepest chord bisection along one edge piece (2¹² samples).
const MAX_BISECT: usize = 12;

/// Most trim samples of one face (a damaged file whose edges lie off their
/// surface would otherwise bisect every piece to the bottom).
pub(crate) const MAX_FACE_SAMPLES: usize = 1 << 18;

/// What a face became: a patch, or why not.
pub(crate) fn build_face(m: &Model, face_id: u64, tol: f64) -> Result<IgesSurface, String> {
    let r = m.record(face_id)?;
    let p = r
        .part("ADVANCED_FACE")
        .or_else(|| r.part("FACE_SURFACE"))
        .ok_or_else(|| format!("#{face_id} is {}, not a face", r.type_name()))?;
    let bounds = p.get(1).and_then(Param::list).ok_or_else(|| format!("#{face_id}: no bounds"))?;
    let surf_id = reference(p.get(2), face_id, "face_geometry")?;
    let same_sense = p.get(3).and_then(Param::logical).unwrap_or(true);
    let surf = m.surface(surf_id, 0).map_err(|e| format!("surface #{surf_id}: {e}"))?;

    let mut loops: Vec<(Vec<DVec2>, bool)> = Vec::new();
    let mut poles: Vec<DVec2> = Vec::new();
    let mut budget = MAX_FACE_SAMPLES;
    for b in bounds {
        let bid = reference(Some(b), face_id, "bound")?;
        let br = m.record(bid)?;
        let bp = br
            .part("FACE_OUTER_BOUND")
            .or_else(|| br.part("FACE_BOUND"))
            .ok_or_else(|| format!("#{bid} is {}, not a face bound", br.type_name()))?;
        let loop_id = reference(bp.get(1), bid, "bound")?;
        let orientation = bp.get(2).and_then(Param::logical).unwrap_or(true);
        let lr = m.record(loop_id)?;
        if let Some(vl) = lr.part("VERTEX_LOOP") {
            let v = vertex(m, reference(vl.get(1), loop_id, "loop_vertex")?)?;
            poles.push(surf.project(v, None));
            continue;
        }
        if let Some(pl) = lr.part("POLY_LOOP") {
            let pts = pl.get(1).and_then(Param::list).ok_or_else(|| format!("#{loop_id}: POLY_LOOP without points"))?;
            let mut out: Vec<DVec2> = Vec::new();
            for q in pts {
                let x = m.point(reference(Some(q), loop_id, "polygon point")?)?;
                out.push(surf.project(x, out.last().copied()));
            }
            let Some(&f) = out.first() else {
                return Err(format!("POLY_LOOP #{loop_id} has no points"));
            };
            out.push(f);
            loops.push((out, orientation));
            continue;
        }
        let el = lr
            .part("EDGE_LOOP")
            .ok_or_else(|| format!("#{loop_id} is {}, not an edge, vertex or poly loop", lr.type_name()))?;
        let edges = el.get(1).and_then(Param::list).ok_or_else(|| format!("#{loop_id}: EDGE_LOOP without edges"))?;
        let mut pts: Vec<DVec2> = Vec::new();
        for oe in edges {
            let oe_id = reference(Some(oe), loop_id, "edge")?;
            let op = m.params(oe_id, "ORIENTED_EDGE")?;
            let edge_id = reference(op.get(3), oe_id, "edge_element")?;
            let forward = op.get(4).and_then(Param::logical).unwrap_or(true);
            let ec = m.params(edge_id, "EDGE_CURVE")?;
            let (v1, v2) = (reference(ec.get(1), edge_id, "edge_start")?, reference(ec.get(2), edge_id, "edge_end")?);
            let geom = reference(ec.get(3), edge_id, "edge_geometry")?;
            let same = ec.get(4).and_then(Param::logical).unwrap_or(true);
            let (vs, ve) = if forward { (v1, v2) } else { (v2, v1) };
            sample_edge(m, &surf, surf_id, geom, (vs, ve), same == forward, tol, &mut pts, &mut budget)
                .map_err(|e| format!("edge #{edge_id}: {e}"))?;
        }
        if pts.len() < 2 {
            return Err(format!("loop #{loop_id} has fewer than two points"));
        }
        budget = budget.saturating_sub(pts.len());
        loops.push((pts, orientation));
    }

    let (window, mut trims) = window_and_loops(&surf, loops, &poles, same_sense)?;
    let (mut nurbs, map) = surf.to_nurbs(window)?;
    for l in &mut trims {
        for p in l.iter_mut() {
            let uv = map.apply(*p);
            *p = DVec2::new(uv[0], uv[1]);
        }
    }
    let (lo, hi) = (map.apply(DVec2::new(window[0].0, window[1].0)), map.apply(DVec2::new(window[0].1, window[1].1)));
    // within the B-spline's domain (a swept B-spline curve keeps its own range)
    let dom = nurbs.domain();
    let mut range = ((lo[0].max(dom.0.0), hi[0].min(dom.0.1)), (lo[1].max(dom.1.0), hi[1].min(dom.1.1)));
    if let Kind::Spline(n) = &surf.kind {
        range = n.domain();
    }
    if !same_sense {
        // the face's normal is the surface's reversed: reverse u so that Su × Sv
        // points out of the face (mirrored about the knot vector's ends, as reverse_u does)
        let c = nurbs.knots_u[0] + nurbs.knots_u[nurbs.knots_u.len() - 1];
        nurbs = reverse_u(&nurbs);
        for l in &mut trims {
            for p in l.iter_mut() {
                p.x = c - p.x;
            }
        }
        range = ((c - range.0.1, c - range.0.0), range.1);
    }
    // a vertex found twice in a row (an edge of no length where a loop meets
    // a seam, or two points that the parameter map rounds alike) carries
    // nothing: dropped, so that every export reads back point for point
    let trim = trims
        .into_iter()
        .map(|l| {
            let mut l: Vec<[f64; 2]> = l.into_iter().map(|p| [p.x, p.y]).collect();
            l.dedup();
            l
        })
        .collect();
    Ok(IgesSurface { surface: nurbs, range, directory_entry: face_id as usize, trim })
}

fn vertex(m: &Model, id: u64) -> Result<DVec3, String> {
    let v = m.params(id, "VERTEX_POINT")?;
    m.point(reference(v.get(1), id, "vertex_geometry")?)
}

/// The PCURVE of edge geometry `geom` on surface `surf_id`, if the file has one.
fn pcurve_on(m: &Model, geom: u64, surf_id: u64) -> Option<Curve> {
    let r = m.record(geom).ok()?;
    let p = r.part("SURFACE_CURVE").or_else(|| r.part("SEAM_CURVE")).or_else(|| r.part("INTERSECTION_CURVE"))?;
    for pc in p.get(2)?.list()? {
        let Some(id) = pc.reference() else { continue };
        let Ok(pp) = m.params(id, "PCURVE") else { continue };
        if pp.get(1).and_then(Param::reference) == Some(surf_id) {
            return m.curve(id, 0).ok();
        }
    }
    None
}

/// Appends the samples of one oriented edge, from vertex `ends.0` to `ends.1`,
/// in the surface's parameters.
#[allow(clippy::too_many_arguments)]
fn sample_edge(
    m: &Model,
    surf: &Surface,
    surf_id: u64,
    geom: u64,
    ends: (u64, u64),
    along: bool,
    tol: f64,
    out: &mut Vec<DVec2>,
    budget: &mut usize,
) -> Result<(), String> {
    let curve = m.curve(geom, 0)?;
    let (a, b) = (vertex(m, ends.0)?, vertex(m, ends.1)?);
    let (mut ta, mut tb) = (curve.param_of(a), curve.param_of(b));
    if let Some(period) = curve.period() {
        if along {
            if tb <= ta + 1e-12 {
                tb += period;
            }
        } else if tb >= ta - 1e-12 {
            tb -= period;
        }
    } else if ends.0 == ends.1 {
        // a closed curve of a non-periodic parameter, once around
        let (t0, t1) = curve.range();
        (ta, tb) = if along { (t0, t1) } else { (t1, t0) };
    }
    let pcurve = if matches!(surf.kind, Kind::Spline(_)) { pcurve_on(m, geom, surf_id) } else { None };
    // a PCURVE is parametrised like its 3-D curve, angles in the file's unit
    let scale = if matches!(curve, Curve::Ellipse { .. }) { 1.0 / m.angle_unit } else { 1.0 };
    let uv_of = |t: f64, hint: Option<DVec2>| -> DVec2 {
        match &pcurve {
            Some(pc) => pc.point(t * scale).truncate(),
            None => surf.project(curve.point(t), hint),
        }
    };
    let n0 = curve.pieces(ta, tb).max(if curve.is_straight() && pcurve.is_none() { 1 } else { 2 });
    let mut prev = (ta, uv_of(ta, out.last().copied()));
    if out.last().is_none_or(|l| l.distance(prev.1) > 0.0) {
        out.push(prev.1);
    }
    for k in 1..=n0 {
        let t = ta + (tb - ta) * k as f64 / n0 as f64;
        let next = (t, uv_of(t, Some(prev.1)));
        bisect(&curve, surf, &uv_of, prev, next, tol, 0, out);
        out.push(next.1);
        prev = next;
        if out.len() > *budget {
            return Err(format!(
                "its trims need more than {MAX_FACE_SAMPLES} samples at a chord of {tol:.3e}: \
                 an edge may lie off its surface (or set a coarser --chord)"
            ));
        }
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn bisect(
    curve: &Curve,
    surf: &Surface,
    uv_of: &dyn Fn(f64, Option<DVec2>) -> DVec2,
    a: (f64, DVec2),
    b: (f64, DVec2),
    tol: f64,
    depth: usize,
    out: &mut Vec<DVec2>,
) {
    if depth >= MAX_BISECT {
        return;
    }
    let tm = 0.5 * (a.0 + b.0);
    let chord = surf.point(0.5 * (a.1 + b.1));
    let truth = curve.point(tm);
    if chord.distance(truth) <= tol {
        return;
    }
    let mid = (tm, uv_of(tm, Some(a.1)));
    bisect(curve, surf, uv_of, a, mid, tol, depth + 1, out);
    out.push(mid.1);
    bisect(curve, surf, uv_of, mid, b, tol, depth + 1, out);
}

/// The parameter window the face needs and its loops as closed polygons in
/// it (see the module notes for loops that wind around a periodic parameter).
type Loops = Vec<Vec<DVec2>>;

fn window_and_loops(
    surf: &Surface,
    loops: Vec<(Vec<DVec2>, bool)>,
    poles: &[DVec2],
    same_sense: bool,
) -> Result<([(f64, f64); 2], Loops), String> {
    let periodic = surf.periodic();
    let natural = surf.natural_window();
    let mut out: Vec<Vec<DVec2>> = Vec::new();
    let mut windings: Vec<(Vec<DVec2>, i32, bool, usize)> = Vec::new();
    for (l, orientation) in loops {
        let (first, last) = (l[0], l[l.len() - 1]);
        let w = [0, 1].map(|d| if periodic[d] { ((last[d] - first[d]) / TAU).round() as i32 } else { 0 });
        match w {
            [0, 0] => {
                let mut l = l;
                // close the polygon exactly (its ends are one vertex, found twice)
                if let Some(last) = l.last_mut() {
                    if last.distance(first) < 1e-9 * (1.0 + first.length()) {
                        *last = first;
                    } else {
                        l.push(first);
                    }
                }
                out.push(l)
            }
            [ws, 0] => windings.push((l, ws, orientation, 0)),
            [0, wt] => windings.push((l, wt, orientation, 1)),
            _ => return Err("a loop winds around both parameters of the surface".into()),
        }
    }
    let mut window = [(f64::INFINITY, f64::NEG_INFINITY); 2];
    let grow = |win: &mut [(f64, f64); 2], p: DVec2| {
        for d in 0..2 {
            win[d].0 = win[d].0.min(p[d]);
            win[d].1 = win[d].1.max(p[d]);
        }
    };
    if let Some((_, _, _, d)) = windings.first() {
        let d = *d;
        let o = 1 - d;
        if windings.iter().any(|w| w.3 != d) {
            return Err("loops wind around different parameters".into());
        }
        let seam = windings[0].0[0][d];
        // the far side along the other parameter, on the side the face lies
        let (l0, w0, or0, _) = &windings[0];
        let mut dir = *w0 as f64 * if *or0 { 1.0 } else { -1.0 } * if same_sense { 1.0 } else { -1.0 };
        if d == 1 {
            // (s, t) → (t, s) swaps the loop's handedness
            dir = -dir;
        }
        let mut ext = (f64::INFINITY, f64::NEG_INFINITY);
        for p in windings.iter().flat_map(|w| w.0.iter()).chain(out.iter().flatten()).chain(poles) {
            ext = (ext.0.min(p[o]), ext.1.max(p[o]));
        }
        if let Some(nat) = natural {
            // a sphere's cap closes at its pole
            if matches!(surf.kind, Kind::Sphere { .. }) {
                ext = if dir > 0.0 { (ext.0, nat[o].1) } else { (nat[o].0, ext.1) };
            }
        }
        let _ = l0;
        let far = if dir > 0.0 { ext.1 } else { ext.0 };
        for (l, w, _, _) in windings {
            let mut poly = cut_at_seam(&l, d, w, seam);
            let (start, end) = (poly[0], poly[poly.len() - 1]);
            let mut a = end;
            a[o] = far;
            let mut b = start;
            b[o] = far;
            poly.extend([a, b, start]);
            out.push(poly);
        }
        // loops that do not wind are moved into the seam's turn
        for l in out.iter_mut() {
            let mean = l.iter().map(|p| p[d]).sum::<f64>() / l.len() as f64;
            let k = ((mean - seam) / TAU).floor();
            for p in l.iter_mut() {
                p[d] -= k * TAU;
            }
        }
        window[d] = (seam, seam + TAU);
        window[o] = ext;
    } else {
        for p in out.iter().flatten().chain(poles) {
            grow(&mut window, *p);
        }
    }
    if out.is_empty() {
        match natural {
            Some(n) => return Ok((n, out)),
            None => return Err("a face without edge loops on an unbounded surface".into()),
        }
    }
    if let Kind::Spline(n) = &surf.kind {
        let d = n.domain();
        return Ok(([d.0, d.1], out));
    }
    // a margin past the loops, so that the renderer can draw the face a little
    // past its trims where neighbours meet (not across a full turn)
    for d in 0..2 {
        let (lo, hi) = window[d];
        if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) || !lo.is_finite() || !hi.is_finite() {
            return Err(format!("the loops span no area (parameter {} from {lo} to {hi})", ["u", "v"][d]));
        }
        let pad = 0.01 * (hi - lo);
        let full = periodic[d] && hi - lo >= TAU - 1e-9;
        if !full {
            let (mut a, mut b) = (lo - pad, hi + pad);
            if periodic[d] && b - a > TAU {
                let c = 0.5 * (lo + hi);
                (a, b) = (c - 0.5 * TAU, c + 0.5 * TAU);
            }
            if let Some(nat) = natural
                && !periodic[d]
            {
                (a, b) = (a.max(nat[d].0), b.min(nat[d].1));
            }
            window[d] = (a, b);
        }
    }
    Ok((window, out))
}

/// A loop that winds `w` (±1) times around parameter `d`, as an open polyline
/// running once across `[seam, seam + 2π]`.
fn cut_at_seam(l: &[DVec2], d: usize, w: i32, seam: f64) -> Vec<DVec2> {
    let w = w.signum() as f64;
    let mut pts: Vec<DVec2> = l.to_vec();
    // the first point inside [seam, seam + 2π)
    let k = ((pts[0][d] - seam) / TAU).floor();
    for p in pts.iter_mut() {
        p[d] -= k * TAU;
    }
    let cross = if w > 0.0 { seam + TAU } else { seam };
    let delta = -w * TAU;
    let n = pts.len() - 1;
    let i = (0..n).find(|&i| (pts[i][d] - cross) * w < 0.0 && (pts[i + 1][d] - cross) * w >= 0.0);
    let Some(i) = i else {
        // already from seam to seam (the first loop starts on it)
        return pts;
    };
    let (a, b) = (pts[i], pts[i + 1]);
    let f = if (b[d] - a[d]).abs() > 0.0 { (cross - a[d]) / (b[d] - a[d]) } else { 0.0 };
    let c = a.lerp(b, f);
    let mut shift = c;
    shift[d] += delta;
    let mut poly = vec![shift];
    for p in &pts[i + 1..=n] {
        let mut q = *p;
        q[d] += delta;
        poly.push(q);
    }
    poly.extend_from_slice(&pts[1..=i]);
    poly.push(c);
    poly
}

/// The surface with its u direction reversed (same points, normal flipped).
fn reverse_u(s: &NurbsSurface) -> NurbsSurface {
    let (u0, u1) = (s.knots_u[0], s.knots_u[s.knots_u.len() - 1]);
    let knots_u = s.knots_u.iter().rev().map(|k| u0 + u1 - k).collect();
    let mut points = Vec::with_capacity(s.points.len());
    for j in 0..s.count_v {
        for i in (0..s.count_u).rev() {
            points.push(s.points[j * s.count_u + i]);
        }
    }
    NurbsSurface { knots_u, points, ..s.clone() }
}

/// The centre and size of the model's vertices (the default chord tolerance
/// is a fraction of the size).
pub(crate) fn vertex_extent(records: &std::collections::HashMap<u64, super::part21::Record>) -> (DVec3, f64) {
    let m = Model { records, angle_unit: 1.0, centre: DVec3::ZERO, size: 1.0 };
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for (id, r) in records {
        if r.is("VERTEX_POINT")
            && let Ok(p) = vertex(&m, *id)
            && p.is_finite()
        {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    let size = (hi - lo).length();
    if size.is_finite() { (0.5 * (lo + hi), size) } else { (DVec3::ZERO, 0.0) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_winding_loop_is_cut_at_the_seam() {
        // once around from 1.0, increasing, at t = 2
        let l: Vec<DVec2> = (0..=16).map(|k| DVec2::new(1.0 + TAU * k as f64 / 16.0, 2.0)).collect();
        let p = cut_at_seam(&l, 0, 1, 0.3);
        assert!((p[0].x - 0.3).abs() < 1e-12 && (p[p.len() - 1].x - 0.3 - TAU).abs() < 1e-12, "{p:?}");
        assert!(p.windows(2).all(|w| w[1].x >= w[0].x - 1e-12));
        // decreasing
        let l: Vec<DVec2> = l.iter().rev().copied().collect();
        let p = cut_at_seam(&l, 0, -1, 0.3);
        assert!((p[0].x - 0.3 - TAU).abs() < 1e-12 && (p[p.len() - 1].x - 0.3).abs() < 1e-12, "{p:?}");
    }

    #[test]
    fn reversing_u_keeps_the_points_and_flips_the_normal() {
        let s = crate::models::single_surface();
        let r = reverse_u(&s);
        let ((u0, u1), (v0, v1)) = s.domain();
        for (u, v) in [(0.2, 0.3), (0.7, 0.9), (0.5, 0.5)] {
            let (u, v) = (u0 + (u1 - u0) * u, v0 + (v1 - v0) * v);
            let (a, b) = (s.point(u, v), r.point(u0 + u1 - u, v));
            assert!((0..3).all(|k| (a[k] - b[k]).abs() < 1e-12));
            let (na, nb) = (s.normal(u, v), r.normal(u0 + u1 - u, v));
            assert!((0..3).all(|k| (na[k] + nb[k]).abs() < 1e-9), "{na:?} {nb:?}");
        }
    }
}
