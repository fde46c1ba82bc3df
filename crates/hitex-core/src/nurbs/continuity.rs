//! Continuity across the edges that faces share, from the exact surfaces.
//!
//! Each face's boundary (its trimming loops, or the four sides of its
//! parameter range when untrimmed) is sampled in model space at a spacing
//! of a fraction of the model's size. Every sample is projected onto the
//! other faces near it by point inversion (Newton on |S(u, v) − P|², started
//! from the nearest boundary sample of that face), so the figures are those
//! of the surfaces themselves, not of a tessellation:
//!
//! * **G0**: the distance from the sample to the neighbour's surface;
//! * **G1**: the angle between the two unit normals (orientation-free:
//!   faces whose normals point opposite ways still join smoothly);
//! * **G2**: the jump of the normal curvature across the edge (in the
//!   direction perpendicular to the edge in the tangent plane), relative to
//!   the larger of the two curvatures and of 1/(model size), so that flat
//!   joins compare as equal.
//!
//! Consecutive samples with the same neighbour form an edge; samples with no
//! neighbour within the matching radius form naked edges. An edge is reported
//! once, from the face of lower index.

use super::surface::{NurbsSurface, v3};

/// A face to check: a surface, the parameter range it is used over and its
/// trimming loops in parameter space (closed polylines; empty: untrimmed).
#[derive(Debug, Clone, Copy)]
pub struct Face<'a> {
    /// The surface.
    pub surface: &'a NurbsSurface,
    /// Parameter range used.
    pub range: ((f64, f64), (f64, f64)),
    /// Trimming loops (closed polylines in (u, v)).
    pub loops: &'a [Vec<[f64; 2]>],
}

/// Sampling and matching settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckOptions {
    /// Samples are at most this far apart along an edge (model units).
    pub spacing: f64,
    /// A boundary sample whose distance to another face is at most this
    /// belongs to an edge shared with that face (model units); farther: naked.
    pub match_radius: f64,
}

/// Where a figure is largest.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Worst {
    /// The value.
    pub value: f64,
    /// The model point where it occurs.
    pub at: [f64; 3],
}

impl Worst {
    /// Nothing measured yet.
    const NONE: Worst = Worst { value: -1.0, at: [0.0; 3] };

    fn take(&mut self, value: f64, at: [f64; 3]) {
        if value > self.value {
            *self = Self { value, at };
        }
    }

    /// 0 where nothing was measured.
    fn settled(self) -> Self {
        if self.value < 0.0 { Self { value: 0.0, ..self } } else { self }
    }
}

/// One edge: a run of boundary samples of `face` along one neighbour (or none).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Edge {
    /// Index of the face whose boundary the edge runs along.
    pub face: usize,
    /// The face on the other side (`None`: naked edge).
    pub neighbour: Option<usize>,
    /// Boundary samples on the edge.
    pub samples: usize,
    /// Length along the samples (model units).
    pub length: f64,
    /// Largest positional gap (model units).
    pub g0: Worst,
    /// Largest angle between the normals (degrees).
    pub g1_deg: Worst,
    /// Largest relative jump of the normal curvature across the edge.
    pub g2_rel: Worst,
    /// Further faces along the edge besides the neighbour (within a
    /// twentieth of the matching radius — the default gap tolerance — at
    /// three of its samples or more, and at least a tenth of them; a
    /// corner's faces come that near at one or two): an edge
    /// shared by three faces or more, which a solid's boundary never has.
    pub also: Vec<usize>,
    /// The samples' parameters on `face`, in order along the edge (for
    /// drawing it; not part of the report).
    #[serde(skip)]
    pub path: Vec<[f64; 2]>,
    /// The same samples' parameters on the neighbour (empty when naked).
    #[serde(skip)]
    pub neighbour_path: Vec<[f64; 2]>,
}

/// One boundary sample of a face.
#[derive(Debug, Clone, Copy)]
struct Sample {
    uv: [f64; 2],
    p: [f64; 3],
}

/// The boundary loops of `f` in (u, v): its trims, or its range's rectangle.
fn loops(f: &Face) -> Vec<Vec<[f64; 2]>> {
    if !f.loops.is_empty() {
        return f.loops.to_vec();
    }
    let ((u0, u1), (v0, v1)) = f.range;
    vec![vec![[u0, v0], [u1, v0], [u1, v1], [u0, v1], [u0, v0]]]
}

/// Samples of the segment `a`–`b` of a loop at `spacing`: enough equal
/// parameter steps for its length, estimated from 8 chords.
fn segment_samples(s: &NurbsSurface, a: [f64; 2], b: [f64; 2], spacing: f64) -> usize {
    let at = |t: f64| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
    let mut len = 0.0;
    let mut prev = s.point(a[0], a[1]);
    for k in 1..=8 {
        let q = at(k as f64 / 8.0);
        let p = s.point(q[0], q[1]);
        len += v3::len(v3::sub(p, prev));
        prev = p;
    }
    ((len / spacing).ceil() as usize).clamp(1, MAX_SEGMENT_SAMPLES)
}

/// Most samples taken along one segment of a loop.
const MAX_SEGMENT_SAMPLES: usize = 100_000;

/// Samples a closed loop at most `spacing` apart in model space (each
/// segment cut into equal parameter steps, enough for its longest chord).
fn sample_loop(s: &NurbsSurface, lp: &[[f64; 2]], spacing: f64) -> Vec<Sample> {
    let mut out = Vec::new();
    for w in lp.windows(2) {
        let (a, b) = (w[0], w[1]);
        let n = segment_samples(s, a, b, spacing);
        for k in 0..n {
            let t = k as f64 / n as f64;
            let uv = [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
            out.push(Sample { uv, p: s.point(uv[0], uv[1]) });
        }
    }
    out
}

/// The boundary samples [`check`] takes at `spacing`, counted before any is
/// taken (the work and memory of a check grow with it: a caller bounds it).
pub fn sample_count(faces: &[Face], spacing: f64) -> u64 {
    use rayon::prelude::*;
    let spacing = spacing.max(1e-12);
    faces
        .par_iter()
        .map(|f| {
            loops(f)
                .iter()
                .flat_map(|l| l.windows(2).map(|w| segment_samples(f.surface, w[0], w[1], spacing) as u64))
                .sum::<u64>()
        })
        .sum()
}

/// Closest point of `s` over `range` to `p` by Newton on |S − p|², from
/// `start`; returns (u, v) and the distance.
pub fn invert(s: &NurbsSurface, range: ((f64, f64), (f64, f64)), p: [f64; 3], start: [f64; 2]) -> ([f64; 2], f64) {
    use v3::*;
    let ((u0, u1), (v0, v1)) = range;
    let (mut u, mut v) = (start[0].clamp(u0, u1), start[1].clamp(v0, v1));
    let mut best = (u, v, f64::INFINITY);
    for _ in 0..32 {
        let d = s.derivatives(u, v, 2);
        let r = sub(d.d[0][0], p);
        let dist = len(r);
        if dist < best.2 {
            best = (u, v, dist);
        }
        let (su, sv) = (d.d[1][0], d.d[0][1]);
        let (fu, fv) = (dot(r, su), dot(r, sv));
        let a = dot(su, su) + dot(r, d.d[2][0]);
        let b = dot(su, sv) + dot(r, d.d[1][1]);
        let c = dot(sv, sv) + dot(r, d.d[0][2]);
        let det = a * c - b * b;
        let (du, dv) = if det.abs() > 1e-300 && det.is_finite() {
            ((-fu * c + fv * b) / det, (fu * b - fv * a) / det)
        } else {
            // gradient step where the Hessian is singular
            let g = dot(su, su).max(dot(sv, sv)).max(1e-300);
            (-fu / g, -fv / g)
        };
        if !(du.is_finite() && dv.is_finite()) {
            break;
        }
        let (nu, nv) = ((u + du).clamp(u0, u1), (v + dv).clamp(v0, v1));
        let moved = (nu - u).abs() + (nv - v).abs();
        (u, v) = (nu, nv);
        if moved <= 1e-14 * (1.0 + (u1 - u0).abs() + (v1 - v0).abs()) {
            break;
        }
    }
    let p2 = s.point(u, v);
    let dist = v3::len(v3::sub(p2, p));
    if dist < best.2 { ([u, v], dist) } else { ([best.0, best.1], best.2) }
}

/// Normal curvature of `s` at (u, v) in the model direction `dir` (in the
/// tangent plane), with the normal `n` giving its sign.
fn normal_curvature(s: &NurbsSurface, uv: [f64; 2], dir: [f64; 3], n: [f64; 3]) -> f64 {
    use v3::*;
    let d = s.derivatives(uv[0], uv[1], 2);
    let (su, sv) = (d.d[1][0], d.d[0][1]);
    let (e, f, g) = (dot(su, su), dot(su, sv), dot(sv, sv));
    let det = e * g - f * f;
    if det.abs() <= 1e-300 || !det.is_finite() {
        return 0.0;
    }
    // dir = a·Su + b·Sv (least squares)
    let (x, y) = (dot(su, dir), dot(sv, dir));
    let a = (g * x - f * y) / det;
    let b = (e * y - f * x) / det;
    let (l, m, nn) = (dot(d.d[2][0], n), dot(d.d[1][1], n), dot(d.d[0][2], n));
    let first = e * a * a + 2.0 * f * a * b + g * b * b;
    if first <= 1e-300 {
        return 0.0;
    }
    (l * a * a + 2.0 * m * a * b + nn * b * b) / first
}

/// Whether two boundary points of one face, at `a` and `b` in its
/// parameters, lie on opposite sides of its domain (a closed face's seam,
/// where the face meets itself) rather than along one stretch of boundary.
fn across_seam(f: &Face, a: [f64; 2], b: [f64; 2]) -> bool {
    let ((u0, u1), (v0, v1)) = f.range;
    (a[0] - b[0]).abs() > 0.5 * (u1 - u0) || (a[1] - b[1]).abs() > 0.5 * (v1 - v0)
}

/// Finds the edges of `faces` and measures each. `size` is the model's size
/// (bounding-box diagonal), the scale of the relative G2 floor.
pub fn check(faces: &[Face], opts: &CheckOptions, size: f64) -> Vec<Edge> {
    check_with_progress(faces, opts, size, &|| {})
}

/// [`check`], calling `face_done` as each face's boundary has been measured
/// (from any thread), for a progress display.
pub fn check_with_progress(faces: &[Face], opts: &CheckOptions, size: f64, face_done: &(dyn Fn() + Sync)) -> Vec<Edge> {
    use rayon::prelude::*;
    use std::collections::HashMap;
    let spacing = opts.spacing.max(1e-12);
    // boundary samples per face, loop by loop
    let boundaries: Vec<Vec<Vec<Sample>>> =
        faces.par_iter().map(|f| loops(f).iter().map(|l| sample_loop(f.surface, l, spacing)).collect()).collect();
    // spatial hash of every sample: cell → (face, loop, index)
    let cell = (opts.match_radius + spacing).max(1e-12);
    let key = |p: [f64; 3]| p.map(|x| (x / cell).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<(usize, usize, usize)>> = HashMap::new();
    for (fi, ls) in boundaries.iter().enumerate() {
        for (li, l) in ls.iter().enumerate() {
            for (si, s) in l.iter().enumerate() {
                grid.entry(key(s.p)).or_default().push((fi, li, si));
            }
        }
    }
    let curvature_floor = 1.0 / size.max(1e-300);
    let per_face: Vec<Vec<Edge>> = boundaries
        .par_iter()
        .enumerate()
        .map(|(fa, ls)| {
            let face_a = &faces[fa];
            let mut edges = Vec::new();
            for l in ls {
                // each sample: every face within reach (face, uv there, distance), nearest first
                let n = l.len();
                let all: Vec<Vec<(usize, [f64; 2], f64)>> = (0..n)
                    .map(|j| {
                        let s = &l[j];
                        // the edge's direction here
                        let t = v3::sub(l[(j + 1) % n].p, l[(j + n - 1) % n].p);
                        // nearest boundary sample of every other face near this one
                        let k = key(s.p);
                        let mut near: HashMap<usize, (f64, [f64; 2])> = HashMap::new();
                        for dx in -1..=1 {
                            for dy in -1..=1 {
                                for dz in -1..=1 {
                                    let Some(c) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else { continue };
                                    for &(fb, lb, sb) in c {
                                        let o = boundaries[fb][lb][sb];
                                        // a face meets itself only across a seam: far off in its parameters
                                        if fb == fa && !across_seam(face_a, s.uv, o.uv) {
                                            continue;
                                        }
                                        let d = v3::len(v3::sub(o.p, s.p));
                                        let e = near.entry(fb).or_insert((f64::INFINITY, o.uv));
                                        if d < e.0 {
                                            *e = (d, o.uv);
                                        }
                                    }
                                }
                            }
                        }
                        let mut found: Vec<(usize, [f64; 2], f64)> = near
                            .into_iter()
                            .filter(|(_, (d, _))| *d <= opts.match_radius + spacing)
                            .filter_map(|(fb, (_, uv))| {
                                let f = &faces[fb];
                                let (uvb, dist) = invert(f.surface, f.range, s.p, uv);
                                // a gap across a shared edge is across it; an
                                // offset along the edge is a boundary running
                                // away from a corner the faces only touch at
                                let off = v3::sub(s.p, f.surface.point(uvb[0], uvb[1]));
                                let tl = v3::len(t);
                                let along = if tl > 0.0 { v3::dot(off, t).abs() / tl } else { 0.0 };
                                let across_edge = dist <= 1e-9 * opts.match_radius.max(1e-300) || along <= 0.5 * dist;
                                (dist <= opts.match_radius && across_edge).then_some((fb, uvb, dist))
                            })
                            .collect();
                        found.sort_by(|a, b| a.2.total_cmp(&b.2).then(a.0.cmp(&b.0)));
                        found
                    })
                    .collect();
                let mut matched: Vec<Option<(usize, [f64; 2], f64)>> = all.iter().map(|f| f.first().copied()).collect();
                // where faces meet at a corner every one of them is at distance
                // 0: a sample keeps its neighbours' face when that face is
                // within reach too, so that corners make no one-sample edges
                for j in 0..n {
                    let prev = matched[(j + n - 1) % n].map(|m| m.0);
                    let next = matched[(j + 1) % n].map(|m| m.0);
                    let mine = matched[j].map(|m| m.0);
                    for side in [prev, next] {
                        if side.is_some()
                            && side != mine
                            && prev != mine
                            && next != mine
                            && let Some(m) = all[j].iter().find(|m| Some(m.0) == side)
                        {
                            matched[j] = Some(*m);
                            break;
                        }
                    }
                }
                if n == 0 {
                    continue;
                }
                // where two faces are equally near along one stretch (parts
                // of an assembly touching, faces lying on each other), the
                // nearest of them flips with rounding from sample to sample:
                // a sample keeps the face of the sample before it while that
                // face is as near as the nearest (within a thousandth of the
                // matching radius), so that the edges found do not depend on
                // the spacing (walked from a change of face, twice round so
                // that the wrap settles)
                let tie = 1e-3 * opts.match_radius;
                let change = (0..n).find(|&i| matched[i].map(|m| m.0) != matched[(i + n - 1) % n].map(|m| m.0));
                if let Some(c) = change {
                    for i in 1..2 * n {
                        let j = (c + i) % n;
                        let before = matched[(j + n - 1) % n].map(|m| m.0);
                        if before.is_some()
                            && before != matched[j].map(|m| m.0)
                            && let Some(m) = all[j].iter().find(|m| Some(m.0) == before)
                            && all[j].first().is_some_and(|best| m.2 <= best.2 + tie)
                        {
                            matched[j] = Some(*m);
                        }
                    }
                }
                // runs of one neighbour along the loop
                let id = |m: &Option<(usize, [f64; 2], f64)>| m.map(|x| x.0);
                // start a run where the neighbour changes (a loop with one
                // neighbour throughout is one run)
                let start = (0..n).find(|&i| id(&matched[i]) != id(&matched[(i + n - 1) % n])).unwrap_or(0);
                let mut i = 0;
                while i < n {
                    let first = (start + i) % n;
                    let who = id(&matched[first]);
                    let mut edge = Edge {
                        face: fa,
                        neighbour: who,
                        samples: 0,
                        length: 0.0,
                        g0: Worst::NONE,
                        g1_deg: Worst::NONE,
                        g2_rel: Worst::NONE,
                        also: Vec::new(),
                        path: Vec::new(),
                        neighbour_path: Vec::new(),
                    };
                    let mut others: HashMap<usize, usize> = HashMap::new();
                    while i < n && id(&matched[(start + i) % n]) == who {
                        let j = (start + i) % n;
                        let s = l[j];
                        let next = l[(j + 1) % n];
                        let prev = l[(j + n - 1) % n];
                        edge.samples += 1;
                        edge.length += v3::len(v3::sub(next.p, s.p));
                        edge.path.push(s.uv);
                        for m in &all[j] {
                            if Some(m.0) != who && m.0 != fa && m.2 <= 0.05 * opts.match_radius {
                                *others.entry(m.0).or_default() += 1;
                            }
                        }
                        if let Some((fb, uvb, dist)) = matched[j] {
                            edge.neighbour_path.push(uvb);
                            let fb_face = &faces[fb];
                            edge.g0.take(dist, s.p);
                            let na = face_a.surface.normal(s.uv[0], s.uv[1]);
                            let mut nb = fb_face.surface.normal(uvb[0], uvb[1]);
                            if v3::dot(na, nb) < 0.0 {
                                nb = v3::scale(nb, -1.0);
                            }
                            let angle = v3::dot(na, nb).clamp(-1.0, 1.0).acos().to_degrees();
                            edge.g1_deg.take(angle, s.p);
                            // across the edge: in the tangent plane, perpendicular to it
                            let t = v3::sub(next.p, prev.p);
                            let across = v3::cross(na, t);
                            let al = v3::len(across);
                            if al > 0.0 {
                                let dir = v3::scale(across, 1.0 / al);
                                let ka = normal_curvature(face_a.surface, s.uv, dir, na);
                                let kb = normal_curvature(fb_face.surface, uvb, dir, nb);
                                let rel = (ka - kb).abs() / ka.abs().max(kb.abs()).max(curvature_floor);
                                edge.g2_rel.take(rel, s.p);
                            }
                        }
                        i += 1;
                    }
                    if who.is_some() && edge.samples >= 3 {
                        // a corner's faces come within reach at one or two samples
                        edge.also = others
                            .into_iter()
                            .filter(|(_, c)| *c >= 3 && 10 * c >= edge.samples)
                            .map(|(f, _)| f)
                            .collect();
                        edge.also.sort_unstable();
                    }
                    edge.g0 = edge.g0.settled();
                    edge.g1_deg = edge.g1_deg.settled();
                    edge.g2_rel = edge.g2_rel.settled();
                    edges.push(edge);
                }
            }
            face_done();
            edges
        })
        .collect();
    // each shared edge once: from the face of lower index
    per_face.into_iter().flatten().filter(|e| e.neighbour.is_none_or(|b| e.face < b)).collect()
}

/// Two faces lying on each other over an area (a face exported twice, or
/// faces of touching parts that coincide).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Overlap {
    /// The face whose samples were measured (of the pair, the one with the
    /// larger share on the other).
    pub face: usize,
    /// The face it lies on.
    pub other: usize,
    /// The share of `face`'s interior samples lying on `other`.
    pub fraction: f64,
    /// One such sample.
    pub at: [f64; 3],
}

/// Pairs of faces lying on each other: each face's interior (an `n`×`n`
/// grid of its parameter range at cell centres, kept where its trims keep
/// it) is measured against the faces its bounds cannot rule out, as `nurbs
/// deviation` measures points (inversion onto the kept part of the face); a
/// pair is reported when at least two samples and a twentieth of one face's
/// samples lie within `tol` of the other face. Faces that only meet along
/// an edge have no interior sample within `tol` of each other.
pub fn overlaps(faces: &[Face], tol: f64, n: usize) -> Vec<Overlap> {
    use super::measure::{DistanceFace, inside_loops};
    use rayon::prelude::*;
    let measured: Vec<DistanceFace> = faces.iter().map(|f| DistanceFace::new(f.surface, f.range, f.loops)).collect();
    let n = n.max(1);
    let found: Vec<Vec<Overlap>> = faces
        .par_iter()
        .enumerate()
        .map(|(a, f)| {
            let ((u0, u1), (v0, v1)) = f.range;
            let mut kept = 0usize;
            let mut hits: std::collections::BTreeMap<usize, (usize, [f64; 3])> = Default::default();
            for i in 0..n {
                for j in 0..n {
                    let uv =
                        [u0 + (u1 - u0) * (i as f64 + 0.5) / n as f64, v0 + (v1 - v0) * (j as f64 + 0.5) / n as f64];
                    if !f.loops.is_empty() && !inside_loops(f.loops, uv) {
                        continue;
                    }
                    kept += 1;
                    let p = f.surface.point(uv[0], uv[1]);
                    for (b, g) in measured.iter().enumerate() {
                        if b == a || g.lower_bound(p) > tol {
                            continue;
                        }
                        if g.distance(p).0 <= tol {
                            hits.entry(b).or_insert((0, p)).0 += 1;
                        }
                    }
                }
            }
            hits.into_iter()
                .filter(|(_, (c, _))| *c >= 2 && 20 * c >= kept)
                .map(|(b, (c, at))| Overlap { face: a, other: b, fraction: c as f64 / kept.max(1) as f64, at })
                .collect()
        })
        .collect();
    // each pair once, from the face with the larger share on the other
    let mut pairs: std::collections::BTreeMap<(usize, usize), Overlap> = Default::default();
    for o in found.into_iter().flatten() {
        let key = (o.face.min(o.other), o.face.max(o.other));
        match pairs.get(&key) {
            Some(old) if old.fraction >= o.fraction => {}
            _ => {
                pairs.insert(key, o);
            }
        }
    }
    pairs.into_values().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three half-planes meeting along one line (a T of sheets): the edge
    /// names its third face; a face given twice overlaps itself entirely,
    /// while faces meeting along an edge do not overlap.
    #[test]
    fn a_third_face_on_an_edge_and_a_face_given_twice_are_found() {
        let a = quad([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        let b = quad([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0], [2.0, 1.0, 0.0]]);
        let c = quad([[1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0]]);
        let edges = run(&[a.clone(), b.clone(), c.clone()]);
        let t: Vec<_> = edges.iter().filter(|e| !e.also.is_empty()).collect();
        assert_eq!(t.len(), 1, "{edges:#?}");
        assert_eq!((t[0].face, t[0].neighbour, t[0].also.clone()), (0, Some(1), vec![2]));
        // two sheets only: no third face anywhere
        assert!(run(&[a.clone(), b.clone()]).iter().all(|e| e.also.is_empty()));
        // overlaps: a given twice, against b and c that only touch it
        let surfaces = [a.clone(), b, c, a];
        let faces: Vec<Face> = surfaces.iter().map(|s| Face { surface: s, range: s.domain(), loops: &[] }).collect();
        let o = overlaps(&faces, 1e-6, 8);
        assert_eq!(o.len(), 1, "{o:?}");
        assert_eq!((o[0].face, o[0].other), (0, 3));
        assert!((o[0].fraction - 1.0).abs() < 1e-12);
    }

    /// A bilinear patch from four corners.
    fn quad(p: [[f64; 3]; 4]) -> NurbsSurface {
        let pts = vec![
            [p[0][0], p[0][1], p[0][2], 1.0],
            [p[1][0], p[1][1], p[1][2], 1.0],
            [p[2][0], p[2][1], p[2][2], 1.0],
            [p[3][0], p[3][1], p[3][2], 1.0],
        ];
        NurbsSurface::new(1, 1, 2, 2, vec![0.0, 0.0, 1.0, 1.0], vec![0.0, 0.0, 1.0, 1.0], pts).unwrap()
    }

    fn run(surfaces: &[NurbsSurface]) -> Vec<Edge> {
        let faces: Vec<Face> = surfaces.iter().map(|s| Face { surface: s, range: s.domain(), loops: &[] }).collect();
        check(&faces, &CheckOptions { spacing: 0.05, match_radius: 0.02 }, 3.0)
    }

    #[test]
    fn a_fold_a_gap_and_naked_sides_are_measured() {
        // two unit squares sharing x = 1, the second folded up by 30°
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let a = quad([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        let b = quad([[1.0, 0.0, 0.0], [1.0 + c, 0.0, s], [1.0, 1.0, 0.0], [1.0 + c, 1.0, s]]);
        let edges = run(&[a.clone(), b]);
        let shared: Vec<_> = edges.iter().filter(|e| e.neighbour.is_some()).collect();
        assert_eq!(shared.len(), 1, "{edges:#?}");
        let e = shared[0];
        assert!(e.g0.value < 1e-9, "gap {}", e.g0.value);
        assert!((e.g1_deg.value - 30.0).abs() < 1e-6, "angle {}", e.g1_deg.value);
        assert!((e.length - 1.0).abs() < 0.06, "length {}", e.length);
        // the six other sides are naked
        let naked: f64 = edges.iter().filter(|e| e.neighbour.is_none()).map(|e| e.length).sum();
        assert!((naked - 6.0).abs() < 0.2, "naked length {naked}");
        // lifted by 0.005 along z: a gap of exactly that, no fold
        let b = quad([[1.0, 0.0, 0.005], [2.0, 0.0, 0.005], [1.0, 1.0, 0.005], [2.0, 1.0, 0.005]]);
        let edges = run(&[a, b]);
        let e = edges.iter().find(|e| e.neighbour.is_some()).expect("still matched");
        assert!((e.g0.value - 0.005).abs() < 1e-9, "gap {}", e.g0.value);
        assert!(e.g1_deg.value < 1e-6);
    }

    #[test]
    fn a_cylinder_meeting_a_plane_tangentially_jumps_in_curvature_only() {
        // quarter cylinder of radius 1 about the y axis from (0,0,1) to (1,0,0)
        // scaled… here: the arc x = sin t, z = cos t − 1 for t in [0, π/2] meets
        // the plane z = 0, x ≤ 0 tangentially at x = 0
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let mut pts = Vec::new();
        for y in [0.0, 1.0] {
            pts.push([0.0, y, 0.0, 1.0]);
            pts.push([1.0, y, 0.0, w]);
            pts.push([1.0, y, -1.0, 1.0]);
        }
        let cyl =
            NurbsSurface::new(2, 1, 3, 2, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0], vec![0.0, 0.0, 1.0, 1.0], pts).unwrap();
        let plane = quad([[-1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
        let edges = run(&[plane, cyl]);
        let e = edges.iter().find(|e| e.neighbour.is_some()).expect("shared edge");
        assert!(e.g0.value < 1e-9);
        assert!(e.g1_deg.value < 1e-4, "tangent: {}", e.g1_deg.value);
        // curvature 0 against 1: a relative jump of 1
        assert!((e.g2_rel.value - 1.0).abs() < 1e-6, "g2 {}", e.g2_rel.value);
    }

    #[test]
    fn faces_equally_near_make_one_edge_at_any_spacing() {
        // the base square's side x = 1 is met by two faces at once, each the
        // nearer along part of it (cubic sides along y: A: z = 3a·t(1−t)(1−2t),
        // B: z = 3b·t(1−t) with b = a/2, so A is the nearer only for t in
        // (¼, ¾)); with a far below the matching radius both lie on the
        // edge (faces touching in an assembly): one edge at every spacing;
        // with a larger, A and B are told apart the same way at every spacing
        let base = quad([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        let wavy = |z: [f64; 4]| {
            let mut pts = Vec::new();
            for j in 0..4 {
                let y = j as f64 / 3.0;
                pts.push([1.0, y, z[j], 1.0]);
                pts.push([2.0, y, z[j], 1.0]);
            }
            let k = vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
            NurbsSurface::new(1, 3, 2, 4, vec![0.0, 0.0, 1.0, 1.0], k, pts).unwrap()
        };
        for (a, want) in [(1e-6, 1), (0.05, 3)] {
            let fa = wavy([0.0, a, -a, 0.0]);
            let fb = wavy([0.0, a / 2.0, a / 2.0, 0.0]);
            let surfaces = [base.clone(), fa, fb];
            let faces: Vec<Face> =
                surfaces.iter().map(|s| Face { surface: s, range: s.domain(), loops: &[] }).collect();
            for spacing in [0.05, 0.02, 0.005] {
                let edges = check(&faces, &CheckOptions { spacing, match_radius: 0.02 }, 3.0);
                let shared: Vec<_> = edges.iter().filter(|e| e.face == 0 && e.neighbour.is_some()).collect();
                assert_eq!(shared.len(), want, "a = {a}, spacing {spacing}: {shared:#?}");
                let length: f64 = shared.iter().map(|e| e.length).sum();
                assert!((length - 1.0).abs() < 0.1, "a = {a}, spacing {spacing}: shared length {length}");
            }
        }
    }

    #[test]
    fn the_sample_count_is_known_before_sampling() {
        // a unit square's perimeter at spacing 0.01: 4 sides of 100 samples
        let sq = quad([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        let faces = [Face { surface: &sq, range: sq.domain(), loops: &[] }];
        assert_eq!(sample_count(&faces, 0.01), 400);
        assert_eq!(sample_count(&faces, 0.3), 16);
        let taken: usize = loops(&faces[0]).iter().map(|l| sample_loop(&sq, l, 0.01).len()).sum();
        assert_eq!(taken, 400);
    }

    #[test]
    fn point_inversion_finds_the_closest_point() {
        let s = crate::nurbs::surface::tests::quarter_cylinder();
        // a point at radius 1.5 on the 30° ray, height 0.8: 0.5 from the cylinder
        let t = 30f64.to_radians();
        let p = [1.5 * t.cos(), 1.5 * t.sin(), 0.8];
        let (uv, d) = invert(&s, s.domain(), p, [0.9, 0.1]);
        assert!((d - 0.5).abs() < 1e-12, "distance {d}");
        let q = s.point(uv[0], uv[1]);
        assert!((q[2] - 0.8).abs() < 1e-12 && (q[1].atan2(q[0]) - t).abs() < 1e-12);
    }
}
