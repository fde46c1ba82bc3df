//! Signed deviation of exact surfaces from a reference: a triangle mesh (a
//! scan's mesh, or any tessellation) or a point cloud.
//!
//! At a surface point S with unit normal N (the face's own orientation,
//! Su × Sv, outward for a solid read from STEP):
//! - against a mesh, the deviation is the distance from S to the closest point
//!   Q of the mesh, signed by which side of the surface Q lies on: positive
//!   where `(Q − S)·N > 0` (the reference stands out of the surface, "material
//!   excess"), negative where it lies behind;
//! - against a point cloud, every point P is first measured as `nurbs
//!   deviation` measures it ([`measure_points`]): inverted onto the nearest
//!   face's kept part, its deviation the distance to the foot F signed by
//!   `(P − F)·N(F)`. A grid point of a face then shows the deviation of the
//!   nearest cloud point measured on that face ([`Reference::measured_points`]),
//!   so that a point never colours a face it does not belong to, and the
//!   figures are exact however sparse the cloud (a point-to-plane offset at S
//!   would be off by the curvature times the square of P's lateral distance).
//!
//! Where the reference has nothing within `max_distance` of S (a partial scan)
//! the deviation is unknown ([`NO_DATA`]), not a large number.
//!
//! Both queries run on one bounding-volume hierarchy of triangles (a point is
//! a triangle whose three corners coincide), searched nearest box first.
//! [`deviation_grid`] samples a face on a grid of its parameter range; the
//! renderers interpolate that grid at each fragment's exact (u, v).

use super::NurbsSurface;
use super::surface::normal_f64;

/// The grid value of a surface point with no reference within the search
/// distance (a sentinel rather than NaN: shaders may assume no NaN).
pub const NO_DATA: f32 = -3.0e38;

/// Whether a grid value means "no reference here".
pub fn is_no_data(x: f32) -> bool {
    x <= -1.0e38
}

/// A bounding box.
#[derive(Debug, Clone, Copy)]
struct Aabb {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Aabb {
    fn of(t: &[[f64; 3]; 3]) -> Self {
        let mut b = Aabb { lo: t[0], hi: t[0] };
        for p in &t[1..] {
            b.grow_point(p);
        }
        b
    }
    fn grow_point(&mut self, p: &[f64; 3]) {
        for k in 0..3 {
            self.lo[k] = self.lo[k].min(p[k]);
            self.hi[k] = self.hi[k].max(p[k]);
        }
    }
    fn grow(&mut self, b: &Aabb) {
        self.grow_point(&b.lo);
        self.grow_point(&b.hi);
    }
    /// Squared distance from `p` to the box (0 inside).
    fn dist2(&self, p: &[f64; 3]) -> f64 {
        let mut d = 0.0;
        for k in 0..3 {
            let e = (self.lo[k] - p[k]).max(p[k] - self.hi[k]).max(0.0);
            d += e * e;
        }
        d
    }
}

/// A node: a box and either two children or a run of primitives.
#[derive(Debug, Clone)]
struct Node {
    bounds: Aabb,
    /// Leaf: first primitive; inner: left child (right = left + 1 is not
    /// assumed: `right` holds it).
    first: u32,
    /// Leaf: primitive count (> 0); inner: 0.
    count: u32,
    right: u32,
}

/// Largest primitives per leaf.
const LEAF: usize = 4;

/// What the reference is, which decides how a deviation is signed and measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReferenceKind {
    /// Triangles: distance to the closest point, signed by side.
    Mesh,
    /// Points: the nearest point's offset along the normal.
    Points,
}

/// A reference mesh or point cloud with its search hierarchy.
#[derive(Debug, Clone)]
pub struct Reference {
    kind: ReferenceKind,
    tris: Vec<[[f64; 3]; 3]>,
    /// Each primitive's index as given (the hierarchy reorders them).
    ids: Vec<u32>,
    /// Points measured in advance: the deviation of each, by index as given.
    values: Option<Vec<f64>>,
    nodes: Vec<Node>,
}

impl Reference {
    /// A mesh of triangles (degenerate ones are kept: they are segments or points).
    pub fn mesh(triangles: Vec<[[f64; 3]; 3]>) -> Self {
        Self::build(ReferenceKind::Mesh, triangles)
    }

    /// A point cloud.
    pub fn points(points: &[[f64; 3]]) -> Self {
        Self::build(ReferenceKind::Points, points.iter().map(|p| [*p, *p, *p]).collect())
    }

    /// Points whose deviations are already measured (`values[i]` of
    /// `points[i]`; [`measure_points`]): a grid point takes the value of the
    /// nearest. Non-finite points or values are dropped.
    pub fn measured_points(points: &[[f64; 3]], values: &[f64]) -> Self {
        let (pts, vals): (Vec<[f64; 3]>, Vec<f64>) =
            points.iter().zip(values).filter(|(p, v)| v.is_finite() && p.iter().all(|x| x.is_finite())).unzip();
        let mut r = Self::build(ReferenceKind::Points, pts.iter().map(|p| [*p, *p, *p]).collect());
        r.values = Some(vals);
        r
    }

    /// Mesh or points.
    pub fn kind(&self) -> ReferenceKind {
        self.kind
    }

    /// Triangles (or points) held.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// Whether there is nothing to measure against.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// The bounds of the reference: `(lo, hi)`, or `None` when empty.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        self.nodes.first().map(|n| (n.bounds.lo, n.bounds.hi))
    }

    fn build(kind: ReferenceKind, tris: Vec<[[f64; 3]; 3]>) -> Self {
        // non-finite primitives can be nearest to nothing: drop them
        let mut tris: Vec<[[f64; 3]; 3]> =
            tris.into_iter().filter(|t| t.iter().flatten().all(|x| x.is_finite())).collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF + 1);
        let mut ids: Vec<u32> = (0..tris.len() as u32).collect();
        if !tris.is_empty() {
            let n = tris.len();
            let mut boxes: Vec<(Aabb, [f64; 3], usize)> = tris
                .iter()
                .enumerate()
                .map(|(i, t)| {
                    let c = [0, 1, 2].map(|k| (t[0][k] + t[1][k] + t[2][k]) / 3.0);
                    (Aabb::of(t), c, i)
                })
                .collect();
            split(&mut boxes, 0, n, &mut nodes);
            let order: Vec<usize> = boxes.iter().map(|b| b.2).collect();
            tris = order.iter().map(|&i| tris[i]).collect();
            ids = order.iter().map(|&i| i as u32).collect();
        }
        Reference { kind, tris, ids, values: None, nodes }
    }

    /// The closest point of the reference to `p` within `max` (inclusive),
    /// with its squared distance.
    pub fn closest(&self, p: [f64; 3], max: f64) -> Option<([f64; 3], f64)> {
        self.closest_with_id(p, max).map(|(q, d2, _)| (q, d2))
    }

    /// [`Reference::closest`] with the index (as given) of the triangle or
    /// point it lies on.
    pub fn closest_with_id(&self, p: [f64; 3], max: f64) -> Option<([f64; 3], f64, usize)> {
        if self.nodes.is_empty() || !p.iter().all(|x| x.is_finite()) {
            return None;
        }
        let mut best = max * max;
        let mut found = None;
        let mut stack: Vec<(f64, u32)> = Vec::with_capacity(64);
        stack.push((self.nodes[0].bounds.dist2(&p), 0));
        while let Some((d, i)) = stack.pop() {
            if d > best {
                continue;
            }
            let node = &self.nodes[i as usize];
            if node.count > 0 {
                let first = node.first as usize;
                for (k, t) in self.tris[first..first + node.count as usize].iter().enumerate() {
                    let q = closest_on_triangle(p, t);
                    let d2 = dist2(&p, &q);
                    if d2 <= best {
                        best = d2;
                        found = Some((q, d2, self.ids[first + k] as usize));
                    }
                }
            } else {
                let (a, b) = (node.first, node.right);
                let (da, db) = (self.nodes[a as usize].bounds.dist2(&p), self.nodes[b as usize].bounds.dist2(&p));
                // the nearer child is searched first (pushed last)
                if da <= db {
                    stack.push((db, b));
                    stack.push((da, a));
                } else {
                    stack.push((da, a));
                    stack.push((db, b));
                }
            }
        }
        found
    }

    /// The signed deviation at the surface point `s` with unit normal `n`,
    /// or `None` when nothing lies within `max`: for a mesh the signed
    /// distance to its closest point; for points the nearest one's offset
    /// along `n` (the point-to-plane distance; [`deviation_grid`] measures a
    /// cloud exactly by inverting that point onto the surface).
    pub fn signed_deviation(&self, s: [f64; 3], n: [f64; 3], max: f64) -> Option<f64> {
        let (q, d2, id) = self.closest_with_id(s, max)?;
        if let Some(v) = &self.values {
            return v.get(id).copied();
        }
        let along = (q[0] - s[0]) * n[0] + (q[1] - s[1]) * n[1] + (q[2] - s[2]) * n[2];
        Some(match self.kind {
            ReferenceKind::Points => along,
            ReferenceKind::Mesh => {
                let d = d2.sqrt();
                if along < 0.0 { -d } else { d }
            }
        })
    }
}

fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// Builds the node for `boxes[start..end]` (median split on the widest
/// axis of the centroids) and returns its index.
fn split(boxes: &mut [(Aabb, [f64; 3], usize)], start: usize, end: usize, nodes: &mut Vec<Node>) -> u32 {
    let mut bounds = boxes[start].0;
    let mut cb = Aabb { lo: boxes[start].1, hi: boxes[start].1 };
    for b in &boxes[start + 1..end] {
        bounds.grow(&b.0);
        cb.grow_point(&b.1);
    }
    let index = nodes.len() as u32;
    nodes.push(Node { bounds, first: start as u32, count: (end - start) as u32, right: 0 });
    if end - start <= LEAF {
        return index;
    }
    let ext = [0, 1, 2].map(|k| cb.hi[k] - cb.lo[k]);
    let axis = (0..3).max_by(|&a, &b| ext[a].total_cmp(&ext[b])).unwrap_or(0);
    let mid = start + (end - start) / 2;
    boxes[start..end].select_nth_unstable_by(mid - start, |a, b| a.1[axis].total_cmp(&b.1[axis]));
    let left = split(boxes, start, mid, nodes);
    let right = split(boxes, mid, end, nodes);
    nodes[index as usize] = Node { bounds, first: left, count: 0, right };
    index
}

/// The point of triangle `t` closest to `p` (Ericson, Real-Time Collision
/// Detection §5.1.5, by Voronoi regions; degenerate triangles included).
pub fn closest_on_triangle(p: [f64; 3], t: &[[f64; 3]; 3]) -> [f64; 3] {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let at = |a: [f64; 3], d: [f64; 3], s: f64| [a[0] + d[0] * s, a[1] + d[1] * s, a[2] + d[2] * s];
    let [a, b, c] = *t;
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let den = d1 - d3;
        return if den > 0.0 { at(a, ab, d1 / den) } else { a };
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let den = d2 - d6;
        return if den > 0.0 { at(a, ac, d2 / den) } else { a };
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let den = (d4 - d3) + (d5 - d6);
        return if den > 0.0 { at(b, sub(c, b), (d4 - d3) / den) } else { b };
    }
    let den = va + vb + vc;
    if den.abs() <= 0.0 || !den.is_finite() {
        // a degenerate triangle whose regions did not decide: its nearest corner
        return [a, b, c].into_iter().min_by(|x, y| dist2(x, &p).total_cmp(&dist2(y, &p))).unwrap_or(a);
    }
    let (v, w) = (vb / den, vc / den);
    [a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w]
}

/// The surface point and unit normal (Su × Sv, its limit at degenerate
/// points) at (u, v).
fn point_normal(s: &NurbsSurface, u: f64, v: f64) -> ([f64; 3], [f64; 3]) {
    let d = s.derivatives(u, v, 2);
    let ((u0, u1), (v0, v1)) = s.domain();
    let tu = if (u - u0) <= (u1 - u) { 1.0 } else { -1.0 };
    let tv = if (v - v0) <= (v1 - v) { 1.0 } else { -1.0 };
    (d.d[0][0], normal_f64(&d, tu, tv).unwrap_or([0.0, 0.0, 1.0]))
}

/// The signed deviation of `surface` from `reference` at a `grid`×`grid`
/// lattice of `range` (row-major, v outer: value `j·grid + i` at
/// `u = u0 + (u1 − u0)·i/(grid − 1)`, `v` likewise with j), [`NO_DATA`]
/// where nothing lies within `max_distance`. `grid` is at least 2.
pub fn deviation_grid(
    surface: &NurbsSurface,
    range: ((f64, f64), (f64, f64)),
    reference: &Reference,
    grid: usize,
    max_distance: f64,
) -> Vec<f32> {
    let g = grid.max(2);
    let ((u0, u1), (v0, v1)) = range;
    let mut out = Vec::with_capacity(g * g);
    for j in 0..g {
        let v = v0 + (v1 - v0) * j as f64 / (g - 1) as f64;
        for i in 0..g {
            let u = u0 + (u1 - u0) * i as f64 / (g - 1) as f64;
            let (s, n) = point_normal(surface, u, v);
            out.push(reference.signed_deviation(s, n, max_distance).map_or(NO_DATA, |d| d as f32));
        }
    }
    out
}

/// Measures every point against `faces` as `nurbs deviation` does: the
/// nearest face's kept part by point inversion, the distance signed by the
/// side of the face's normal the point lies on. `None` for a point farther
/// than `max_distance` from every face.
pub fn measure_point(faces: &[super::measure::DistanceFace], p: [f64; 3], max_distance: f64) -> Option<(usize, f64)> {
    let (d, face, uv) = super::measure::nearest_face(faces, p)?;
    if d.is_nan() || d > max_distance {
        return None;
    }
    let (f, n) = point_normal(faces[face].surface(), uv[0], uv[1]);
    let along = (p[0] - f[0]) * n[0] + (p[1] - f[1]) * n[1] + (p[2] - f[2]) * n[2];
    Some((face, if along < 0.0 { -d } else { d }))
}

/// [`measure_point`] for every point, grouped by face: for each face the
/// points measured on it and their signed deviations.
pub fn measure_points(
    faces: &[super::measure::DistanceFace],
    points: &[[f64; 3]],
    max_distance: f64,
) -> Vec<(Vec<[f64; 3]>, Vec<f64>)> {
    let mut out = vec![(Vec::new(), Vec::new()); faces.len()];
    for p in points {
        if let Some((face, d)) = measure_point(faces, *p, max_distance) {
            out[face].0.push(*p);
            out[face].1.push(d);
        }
    }
    out
}

/// The grid's value at (u, v) in `range`: bilinear between its four nodes,
/// [`NO_DATA`] when one of them has none. The twin of the fragment programs'
/// lookup, in f64.
pub fn grid_value(values: &[f32], grid: usize, range: ((f64, f64), (f64, f64)), u: f64, v: f64) -> f32 {
    let g = grid.max(2);
    let ((u0, u1), (v0, v1)) = range;
    let s = if u1 > u0 { ((u - u0) / (u1 - u0)).clamp(0.0, 1.0) * (g - 1) as f64 } else { 0.0 };
    let t = if v1 > v0 { ((v - v0) / (v1 - v0)).clamp(0.0, 1.0) * (g - 1) as f64 } else { 0.0 };
    let (i, j) = ((s.floor() as usize).min(g - 2), (t.floor() as usize).min(g - 2));
    let (a, b) = (s - i as f64, t - j as f64);
    let at = |i: usize, j: usize| values.get(j * g + i).copied().unwrap_or(NO_DATA);
    let c = [at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)];
    if c.iter().any(|&x| is_no_data(x)) {
        return NO_DATA;
    }
    let c = c.map(f64::from);
    let top = c[0] + (c[1] - c[0]) * a;
    let bottom = c[2] + (c[3] - c[2]) * a;
    (top + (bottom - top) * b) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(state: &mut u64) -> f64 {
        *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The hierarchy finds what a search of every triangle finds.
    #[test]
    fn closest_point_matches_brute_force() {
        let mut s = 7u64;
        let tris: Vec<[[f64; 3]; 3]> = (0..500)
            .map(|_| {
                let c = [lcg(&mut s) * 10.0, lcg(&mut s) * 10.0, lcg(&mut s) * 10.0];
                [0, 1, 2].map(|_| [c[0] + lcg(&mut s), c[1] + lcg(&mut s), c[2] + lcg(&mut s)])
            })
            .collect();
        let r = Reference::mesh(tris.clone());
        for _ in 0..300 {
            let p = [lcg(&mut s) * 12.0 - 1.0, lcg(&mut s) * 12.0 - 1.0, lcg(&mut s) * 12.0 - 1.0];
            let want = tris.iter().map(|t| dist2(&p, &closest_on_triangle(p, t))).fold(f64::INFINITY, f64::min);
            let (_, got) = r.closest(p, f64::INFINITY).expect("a triangle");
            assert!((got - want).abs() <= 1e-12 * want.max(1.0), "{got} vs {want}");
            // and nothing within a radius below the nearest
            assert!(r.closest(p, 0.99 * want.sqrt()).is_none());
        }
    }

    /// Closest points in each Voronoi region of a triangle, by hand.
    #[test]
    fn closest_point_on_a_triangle_by_region() {
        let t = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        let cases = [
            ([0.5, 0.5, 3.0], [0.5, 0.5, 0.0]),   // face
            ([-1.0, -1.0, 0.0], [0.0, 0.0, 0.0]), // vertex a
            ([3.0, -1.0, 1.0], [2.0, 0.0, 0.0]),  // vertex b
            ([-1.0, 3.0, 0.0], [0.0, 2.0, 0.0]),  // vertex c
            ([1.0, -2.0, 0.0], [1.0, 0.0, 0.0]),  // edge ab
            ([-2.0, 1.0, 5.0], [0.0, 1.0, 0.0]),  // edge ac
            ([2.0, 2.0, 0.0], [1.0, 1.0, 0.0]),   // edge bc
        ];
        for (p, want) in cases {
            let q = closest_on_triangle(p, &t);
            assert!(dist2(&q, &want) < 1e-24, "{p:?}: {q:?} vs {want:?}");
        }
        // degenerate: a point and a segment
        let pt = [[1.0, 2.0, 3.0]; 3];
        assert_eq!(closest_on_triangle([5.0, 5.0, 5.0], &pt), [1.0, 2.0, 3.0]);
        let seg = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!(dist2(&closest_on_triangle([1.0, 1.0, 0.0], &seg), &[1.0, 0.0, 0.0]) < 1e-24);
    }

    /// A bilinear patch z = 0 on [0,1]² (normal +z) against the plane z = δ
    /// as a mesh and as a cloud, and against z = −δ: every node reads ±δ.
    #[test]
    fn an_offset_plane_reads_its_offset_with_its_sign() {
        let sheet = NurbsSurface::new(
            1,
            1,
            2,
            2,
            vec![0.0, 0.0, 1.0, 1.0],
            vec![0.0, 0.0, 1.0, 1.0],
            vec![[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [1.0, 1.0, 0.0, 1.0]],
        )
        .expect("a sheet");
        let range = sheet.domain();
        for delta in [0.01, -0.02] {
            // a mesh larger than the sheet
            let z = delta;
            let mesh = Reference::mesh(vec![
                [[-1.0, -1.0, z], [2.0, -1.0, z], [2.0, 2.0, z]],
                [[-1.0, -1.0, z], [2.0, 2.0, z], [-1.0, 2.0, z]],
            ]);
            // a cloud of spacing 0.05 over the sheet and a margin
            let cloud: Vec<[f64; 3]> =
                (0..30).flat_map(|i| (0..30).map(move |j| [i as f64 * 0.05 - 0.2, j as f64 * 0.05 - 0.2, z])).collect();
            let cloud = Reference::points(&cloud);
            for r in [&mesh, &cloud] {
                let g = deviation_grid(&sheet, range, r, 9, 1.0);
                assert_eq!(g.len(), 81);
                for x in &g {
                    assert!((*x as f64 - delta).abs() < 1e-7, "{:?}: {x} vs {delta}", r.kind());
                }
                let mid = grid_value(&g, 9, range, 0.37, 0.61);
                assert!((mid as f64 - delta).abs() < 1e-7);
            }
            // beyond the search distance: no data
            let far = deviation_grid(&sheet, range, &mesh, 3, 0.5 * delta.abs());
            assert!(far.iter().all(|&x| is_no_data(x)));
            assert!(is_no_data(grid_value(&far, 3, range, 0.5, 0.5)));
        }
    }

    /// A sparse cloud on the cylinder of radius 1 + δ reads δ at every node of
    /// the quarter cylinder of radius 1, although its nearest points lie
    /// well aside of the nodes; and a point nearer another face colours
    /// only that one.
    #[test]
    fn a_sparse_cloud_on_an_offset_cylinder_reads_its_offset() {
        let s = super::super::surface::tests::quarter_cylinder();
        let faces = [super::super::measure::DistanceFace::new(&s, s.domain(), &[])];
        let delta = 0.01;
        let cloud: Vec<[f64; 3]> = (0..7)
            .flat_map(|i| {
                let a = std::f64::consts::FRAC_PI_2 * i as f64 / 6.0;
                (0..5).map(move |j| [(1.0 + delta) * a.cos(), (1.0 + delta) * a.sin(), 0.5 * j as f64])
            })
            .collect();
        let measured = measure_points(&faces, &cloud, 1.0);
        assert_eq!(measured[0].0.len(), cloud.len());
        let r = Reference::measured_points(&measured[0].0, &measured[0].1);
        let g = deviation_grid(&s, s.domain(), &r, 17, 1.0);
        for (k, x) in g.iter().enumerate() {
            assert!((*x as f64 - delta).abs() < 1e-6, "node {k}: {x}");
        }
        // inside the cylinder: negative; beyond the search distance: unmeasured
        assert!(
            (measure_point(&faces, [0.5f64.sqrt() * 0.9, 0.5f64.sqrt() * 0.9, 1.0], 1.0).expect("near").1 + 0.1).abs()
                < 1e-9
        );
        assert!(measure_point(&faces, [5.0, 5.0, 1.0], 1.0).is_none());
        // the point-to-plane offset at the node alone is off by far more
        let r = Reference::points(&cloud);
        let (p, n) = point_normal(&s, 0.08, 0.13);
        let naive = r.signed_deviation(p, n, 1.0).expect("a point");
        assert!((naive.abs() - delta).abs() > 1e-3, "{naive}");
    }

    /// The deviation of a curved surface from its own tessellation stays
    /// within the tessellation's chord error, and vanishes at its vertices.
    #[test]
    fn a_surface_deviates_from_its_tessellation_within_the_chord_error() {
        let s = super::super::surface::tests::quarter_cylinder();
        let ((u0, u1), (v0, v1)) = s.domain();
        let n = 16;
        let at =
            |i: usize, j: usize| s.point(u0 + (u1 - u0) * i as f64 / n as f64, v0 + (v1 - v0) * j as f64 / n as f64);
        let mut tris = Vec::new();
        for i in 0..n {
            for j in 0..n {
                tris.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                tris.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        // chord error: 1 − cos(φ/2) for the widest arc φ between neighbouring
        // vertices along u (a rational quadratic's parameter is not the angle)
        let chord = (0..n)
            .map(|i| {
                let (a, b) = (at(i, 0), at(i + 1, 0));
                let c = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
                1.0 - (1.0 - c * c / 4.0).sqrt()
            })
            .fold(0.0, f64::max);
        let r = Reference::mesh(tris);
        let g = deviation_grid(&s, s.domain(), &r, 33, 1.0);
        let worst = g.iter().map(|x| x.abs() as f64).fold(0.0, f64::max);
        assert!(worst <= chord * 1.0001 && worst > 0.3 * chord, "{worst} vs chord {chord}");
        // grid nodes on tessellation vertices (every other node of 33 on 16 cells)
        for j in (0..33).step_by(2) {
            for i in (0..33).step_by(2) {
                assert!((g[j * 33 + i] as f64).abs() < 1e-7);
            }
        }
    }
}
