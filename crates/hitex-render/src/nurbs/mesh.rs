//! The coarse tessellation that places the fragments: grids fitted to a
//! tolerance, matched sides between patches, fans along trimmed boundaries.

use super::*;

/// Most triangles [`fitted_grids`] gives a model (about 200 MB of
/// vertices and indices at the largest).
pub const MAX_FITTED_TRIANGLES: u64 = 1 << 22;

/// Each patch's tessellation grid (cells along u, along v) such that the
/// mesh that places fragments lies within `tol` model units of the exact
/// surface along its grid lines: at least `min` cells a side and one a
/// knot span, refined per direction until the largest sag of a cell's edge
/// (the distance between the surface at the edge's middle and the chord's
/// middle, over lines across the patch) is at most `tol`, up to 256 cells a
/// side. Where the mesh falls short of the surface (a convex silhouette
/// seen between grid lines), the exact fragments beyond it are not drawn:
/// a whole-turn cylinder on an 8×8 grid loses a polygon's sag (7.6 % of
/// its radius) at its silhouette, one fitted to a quarter pixel draws the
/// circle. A model whose grids would exceed [`MAX_FITTED_TRIANGLES`] has
/// every side scaled down evenly to fit (the sag then exceeds `tol`).
pub fn fitted_grids(surfaces: &[NurbsSurface], ranges: &[ParamRange], min: u32, tol: f64) -> Vec<(u32, u32)> {
    use rayon::prelude::*;
    let min = min.clamp(1, 256);
    let tol = if tol.is_finite() && tol > 0.0 { tol } else { f64::MAX };
    let grids: Vec<(u32, u32)> = surfaces
        .par_iter()
        .enumerate()
        .map(|(k, s)| {
            let ((u0, u1), (v0, v1)) = ranges.get(k).copied().unwrap_or_else(|| s.domain());
            // knot spans inside the range: a grid line on every knot would
            // need more, one cell a span at least
            let spans = |knots: &[f64], a: f64, b: f64| -> u32 {
                let mut inner: Vec<f64> = knots.iter().copied().filter(|&t| t > a && t < b).collect();
                inner.dedup();
                (inner.len() as u32 + 1).min(256)
            };
            let mut nu = min.max(spans(&s.knots_u, u0, u1));
            let mut nv = min.max(spans(&s.knots_v, v0, v1));
            // refine each direction over lines across the other one's grid
            for _ in 0..4 {
                let su = grid_sag(s, (u0, u1), (v0, v1), nu, nv.min(32), false);
                let sv = grid_sag(s, (v0, v1), (u0, u1), nv, nu.min(32), true);
                let grow = |n: u32, sag: f64| -> u32 {
                    if sag <= tol || n >= 256 {
                        n
                    } else {
                        // a sag falls with the square of the cells a side
                        let want = (n as f64 * (sag / tol).sqrt() * 1.05).ceil();
                        (want.min(256.0) as u32).max(n + 1)
                    }
                };
                let (gu, gv) = (grow(nu, su), grow(nv, sv));
                if (gu, gv) == (nu, nv) {
                    break;
                }
                (nu, nv) = (gu, gv);
            }
            (nu, nv)
        })
        .collect();
    let total: u64 = grids.iter().map(|&(a, b)| 2 * a as u64 * b as u64).sum();
    if total <= MAX_FITTED_TRIANGLES {
        return grids;
    }
    let f = (MAX_FITTED_TRIANGLES as f64 / total as f64).sqrt();
    grids.iter().map(|&(a, b)| (((a as f64 * f) as u32).max(1), ((b as f64 * f) as u32).max(1))).collect()
}

/// The largest sag of the `n` cells along one direction of a patch (its
/// range `along`), over `lines` + 1 lines at equal steps of the other
/// (`across`); `v_first`: the direction is v. Non-finite points are passed over.
fn grid_sag(s: &NurbsSurface, along: (f64, f64), across: (f64, f64), n: u32, lines: u32, v_first: bool) -> f64 {
    let at = |t: f64, c: f64| if v_first { s.point(c, t) } else { s.point(t, c) };
    let step = |r: (f64, f64), i: f64, m: u32| r.0 + (r.1 - r.0) * i / m as f64;
    let mut worst = 0.0f64;
    for j in 0..=lines {
        let c = step(across, j as f64, lines);
        let mut a = at(along.0, c);
        for i in 0..n {
            let b = at(step(along, (i + 1) as f64, n), c);
            let m = at(step(along, i as f64 + 0.5, n), c);
            let d = (0..3).map(|t| (m[t] - 0.5 * (a[t] + b[t])).powi(2)).sum::<f64>().sqrt();
            if d.is_finite() {
                worst = worst.max(d);
            }
            a = b;
        }
    }
    worst
}

/// For each boundary polyline (patch, side, density, points), whether
/// another side's polyline has every one of its points within `tol`
/// (neighbours sampled alike, whose tessellations already meet).
fn matched_sides(sides: &[(usize, usize, u32, Vec<[f64; 3]>)], tol: f64) -> Vec<bool> {
    use std::collections::HashMap;
    let key = |p: &[f64; 3]| -> Option<[i64; 3]> {
        let k = p.map(|x| (x / tol).floor());
        k.iter().all(|x| x.is_finite() && x.abs() < 1e15).then(|| k.map(|x| x as i64))
    };
    // every side under the cells of its points
    let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, side) in sides.iter().enumerate() {
        for p in &side.3 {
            if let Some(c) = key(p) {
                let list = cells.entry(c).or_default();
                if list.last() != Some(&i) {
                    list.push(i);
                }
            }
        }
    }
    let near = |p: &[f64; 3], q: &[f64; 3]| (0..3).all(|t| (p[t] - q[t]).abs() <= tol);
    sides
        .iter()
        .enumerate()
        .map(|(i, side)| {
            let pts = &side.3;
            // a collapsed side (a pole) has no seam to close
            if pts.iter().all(|p| near(p, &pts[0])) {
                return true;
            }
            let Some(c) = key(&pts[0]) else { return false };
            let mut candidates = Vec::new();
            for d in 0..27i64 {
                let cell = [c[0] + d % 3 - 1, c[1] + (d / 3) % 3 - 1, c[2] + d / 9 - 1];
                if let Some(list) = cells.get(&cell) {
                    candidates.extend(list.iter().copied().filter(|&j| j != i));
                }
            }
            candidates.sort_unstable();
            candidates.dedup();
            candidates.iter().any(|&j| pts.iter().all(|p| sides[j].3.iter().any(|q| near(p, q))))
        })
        .collect()
}

/// Added to the patch index of boundary-fan vertices: the programs round the
/// index, and draw fan fragments behind any surface truly there.
pub const FAN_MARK: f32 = 0.25;

/// Largest number of halvings of a boundary segment in its fan.
const FAN_LEVELS: u32 = 3;

/// Triangles closing the lens between one boundary segment's chord and its
/// curve: the curve's midpoint joined to the chord, then each half again,
/// until the sag left is below 1/4^[`FAN_LEVELS`] of the chord's (or
/// vanishes). `at(t)` gives the boundary parameter pair at `t`, `push` takes
/// one vertex (parameters, point, normal).
fn boundary_fan(
    s: &NurbsSurface,
    at: &dyn Fn(f64) -> (f64, f64),
    ta: f64,
    tb: f64,
    level: u32,
    floor: f64,
    push: &mut dyn FnMut((f64, f64), [f64; 3], [f64; 3]),
) {
    let tm = 0.5 * (ta + tb);
    let (a, b, m) = (at(ta), at(tb), at(tm));
    let (pa, pb, pm) = (s.point(a.0, a.1), s.point(b.0, b.1), s.point(m.0, m.1));
    let sag = (0..3).map(|t| pm[t] - 0.5 * (pa[t] + pb[t])).map(|x| x * x).sum::<f64>().sqrt();
    if !(sag.is_finite() && sag > floor && pa.iter().chain(&pb).chain(&pm).all(|x| x.is_finite())) {
        return;
    }
    for (uv, p) in [(a, pa), (b, pb), (m, pm)] {
        push(uv, p, s.normal(uv.0, uv.1));
    }
    if level + 1 < FAN_LEVELS {
        let floor = if level == 0 { sag / 4f64.powi(FAN_LEVELS as i32) } else { floor };
        boundary_fan(s, at, ta, tm, level + 1, floor, push);
        boundary_fan(s, at, tm, tb, level + 1, floor, push);
    }
}

impl PreparedNurbs {
    /// Like [`PreparedNurbs::new`] with a grid per patch: `grids[k]` cells
    /// along u and along v (8×8 beyond the slice; each side clamped to 1…256).
    pub fn with_grids(surfaces: Vec<NurbsSurface>, ranges: &[ParamRange], grids: &[(u32, u32)]) -> Self {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let mut sides: Vec<(usize, usize, u32, Vec<[f64; 3]>)> = Vec::new();
        let mut deviation = 0.0f32;
        for (k, s) in surfaces.iter().enumerate() {
            let ((u0, u1), (v0, v1)) = ranges.get(k).copied().unwrap_or_else(|| s.domain());
            let (nu, nv) = grids.get(k).copied().unwrap_or((8, 8));
            let (nu, nv) = (nu.clamp(1, 256), nv.clamp(1, 256));
            let base = vertices.len() as u32;
            let grid =
                |a: f64, b: f64, n: u32| (0..=n).map(|i| a + (b - a) * i as f64 / n as f64).collect::<Vec<f64>>();
            let (us, vs) = (grid(u0, u1, nu), grid(v0, v1, nv));
            for &v in &vs {
                for &u in &us {
                    let p = s.point(u, v);
                    let n = s.normal(u, v);
                    if p.iter().all(|x| x.is_finite()) {
                        for t in 0..3 {
                            lo[t] = lo[t].min(p[t]);
                            hi[t] = hi[t].max(p[t]);
                        }
                    }
                    vertices.push(NurbsVertex {
                        position: p.map(|x| x as f32),
                        normal: n.map(|x| x as f32),
                        uv: [u as f32, v as f32],
                        patch: k as f32,
                        _pad: 0.0,
                    });
                }
            }
            let row = nu + 1;
            for j in 0..nv {
                for i in 0..nu {
                    let a = base + j * row + i;
                    indices.extend_from_slice(&[a, a + 1, a + row, a + 1, a + row + 1, a + row]);
                    // the deviation at the cell's centre from its corners' mean
                    let (uc, vc) =
                        (0.5 * (us[i as usize] + us[i as usize + 1]), 0.5 * (vs[j as usize] + vs[j as usize + 1]));
                    let exact = s.point(uc, vc);
                    let corners = [a, a + 1, a + row, a + row + 1].map(|c| vertices[c as usize].position);
                    let d = (0..3)
                        .map(|t| exact[t] as f32 - corners.iter().map(|c| c[t]).sum::<f32>() / 4.0)
                        .map(|x| x * x)
                        .sum::<f32>()
                        .sqrt();
                    if d.is_finite() {
                        deviation = deviation.max(d);
                    }
                }
            }
            // the boundary polylines, for the fans below
            for side in 0..4 {
                // sides 0 and 1 run along v, 2 and 3 along u
                let density = if side < 2 { nv } else { nu };
                let pts = (0..=density as usize)
                    .map(|i| {
                        let (u, v) = (
                            if side == 0 {
                                u0
                            } else if side == 1 {
                                u1
                            } else {
                                us[i]
                            },
                            if side == 2 {
                                v0
                            } else if side == 3 {
                                v1
                            } else {
                                vs[i]
                            },
                        );
                        s.point(u, v)
                    })
                    .collect();
                sides.push((k, side, density, pts));
            }
        }
        // boundary fans: each side's chords are joined to the curve they cut
        // across. Neighbours tessellated independently cut a shared curve into
        // different chords; each fills up to the curve (within 1/64 of its
        // chords' sag), so no background shows between them, and nothing
        // reaches past the true surface. A side whose polyline another side
        // repeats point for point needs none (the teapot's seams).
        let extent = (0..3).map(|t| (hi[t] - lo[t]).powi(2)).sum::<f64>().sqrt();
        let matched = matched_sides(&sides, 1e-9 * extent.max(1e-300));
        for ((k, side, density, _), matched) in sides.iter().zip(matched) {
            if matched {
                continue;
            }
            let (k, density) = (*k, *density);
            let s = &surfaces[k];
            let ((u0, u1), (v0, v1)) = ranges.get(k).copied().unwrap_or_else(|| s.domain());
            let at: Box<dyn Fn(f64) -> (f64, f64)> = match side {
                0 => Box::new(|t| (u0, t)),
                1 => Box::new(|t| (u1, t)),
                2 => Box::new(|t| (t, v0)),
                _ => Box::new(|t| (t, v1)),
            };
            let (a, b) = if *side < 2 { (v0, v1) } else { (u0, u1) };
            let mut push = |uv: (f64, f64), p: [f64; 3], n: [f64; 3]| {
                indices.push(vertices.len() as u32);
                vertices.push(NurbsVertex {
                    position: p.map(|x| x as f32),
                    normal: n.map(|x| x as f32),
                    uv: [uv.0 as f32, uv.1 as f32],
                    patch: k as f32 + FAN_MARK,
                    _pad: 0.0,
                });
            };
            for i in 0..density {
                let (ta, tb) = (a + (b - a) * i as f64 / density as f64, a + (b - a) * (i + 1) as f64 / density as f64);
                boundary_fan(s, at.as_ref(), ta, tb, 0, 0.0, &mut push);
            }
        }
        let center =
            Vec3::new(((lo[0] + hi[0]) / 2.0) as f32, ((lo[1] + hi[1]) / 2.0) as f32, ((lo[2] + hi[2]) / 2.0) as f32);
        let radius = (0..3).map(|t| (hi[t] - lo[t]) / 2.0).map(|x| x * x).sum::<f64>().sqrt().max(1e-6) as f32;
        let fov = 35.0f32;
        let dist = radius / (fov.to_radians() / 2.0).sin() * 0.95;
        let dir = Vec3::new(0.85, -1.5, 0.75).normalize();
        let camera = Camera {
            position: center + dir * dist,
            target: center,
            up: Vec3::Z,
            fov_y_deg: fov,
            near: (dist - radius * 1.5).max(dist * 0.01),
            far: dist + radius * 1.5,
        };
        let packed = PackedNurbs::new(&surfaces);
        // curvature ranges: twice the area-weighted 75th percentile of |K| and
        // |H| over a 6×6 sample grid per patch, each sample weighted by the
        // surface area it stands for (|S_u × S_v| du dv), so that many small,
        // sharply curved patches (fillets, rims) do not set the scale of the
        // large ones
        let mut ks = Vec::new();
        let mut hs = Vec::new();
        let mut ps = Vec::new();
        let (mut ks_curved, mut hs_curved) = (Vec::new(), Vec::new());
        for s in &surfaces {
            let ((u0, u1), (v0, v1)) = s.domain();
            let cell = (u1 - u0) * (v1 - v0) / 36.0;
            for k in 0..36 {
                let u = u0 + (u1 - u0) * ((k % 6) as f64 + 0.5) / 6.0;
                let v = v0 + (v1 - v0) * ((k / 6) as f64 + 0.5) / 6.0;
                let c = s.curvature(u, v);
                let d = s.derivatives(u, v, 1);
                let (a, b) = (d.d[1][0], d.d[0][1]);
                let n = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
                let area = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() * cell;
                if c.gaussian.is_finite() && c.mean.is_finite() && area.is_finite() {
                    ks.push((c.gaussian.abs(), area));
                    hs.push((c.mean.abs(), area));
                    if c.gaussian.abs() * (radius as f64).powi(2) > 1e-8 {
                        ks_curved.push((c.gaussian.abs(), area));
                    }
                    if c.mean.abs() * radius as f64 > 1e-4 {
                        hs_curved.push((c.mean.abs(), area));
                    }
                    // the principal ramp is scaled by the curved part alone:
                    // on a machined part most of the area is planes, whose
                    // zero would set a scale of nothing
                    let k = c.principal[0].abs().max(c.principal[1].abs());
                    if k.is_finite() && k * radius as f64 > 1e-4 {
                        ps.push((k, area));
                    }
                }
            }
        }
        let pick = |mut v: Vec<(f64, f64)>| -> f32 {
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            let total: f64 = v.iter().map(|x| x.1).sum();
            let mut acc = 0.0;
            let mut at = v.last().map_or(0.5, |x| x.0);
            for (value, w) in &v {
                acc += w;
                if acc >= 0.75 * total {
                    at = *value;
                    break;
                }
            }
            2.0 * at as f32
        };
        let r = radius.max(f32::MIN_POSITIVE);
        let principal_range = if ps.is_empty() { 1.0 / r } else { pick(ps).max(1e-12) };
        // |K| and |H| over the whole surface, unless flat faces hold more
        // than a quarter of the area (a machined part): their zeros would
        // set a scale of nothing, and the curved part alone sets it
        let over = |all: Vec<(f64, f64)>, curved: Vec<(f64, f64)>, floor: f32, none: f32| -> (f32, bool) {
            let whole = pick(all);
            if whole / 2.0 > floor {
                (whole.max(1e-12), false)
            } else if curved.is_empty() {
                (none, true)
            } else {
                (pick(curved).max(1e-12), true)
            }
        };
        let (k_range, k_curved) = over(ks, ks_curved, 1e-8 / (r * r), 1.0 / (r * r));
        let (h_range, h_curved) = over(hs, hs_curved, 1e-4 / r, 1.0 / r);
        let curvature_range = [k_range, h_range, principal_range];
        let curvature_over_curved_part = [k_curved, h_curved, true];
        Self {
            surfaces,
            vertices,
            indices,
            packed,
            camera,
            mode: NurbsMode::Shaded,
            bands: 12,
            stripes: 10,
            pull: Vec3::Z,
            draft_tolerance_deg: DEFAULT_DRAFT_TOLERANCE_DEG,
            tool_radius: 0.0,
            deviation_range: (0.0, 1.0),
            curvature_range,
            curvature_over_curved_part,
            background: Vec3::new(0.06, 0.07, 0.09),
            prepared_kernels: true,
            boundaries: false,
            isolines: 0,
            sections: None,
            edges: false,
            light: None,
            bounds: (center, radius),
            tess_deviation: deviation,
            early_depth: true,
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }
}
