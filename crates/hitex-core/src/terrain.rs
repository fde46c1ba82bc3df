//! Terrain: the active area of seed 001 (eq. (5)–(7)), meshes from
//! elevation grids, and flight paths ([`path`]).

pub mod path;

use crate::CoreError;
use crate::scene::Mesh;
use crate::texture::{ColorSpace, Image};
use glam::{Vec2, Vec3};

/// Maps needed at one MIP level of the geospecific texture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelMaps {
    /// Level, 0 the coarsest (one map per unit of ground), finer levels up.
    pub level: u32,
    /// Half-width of the square the level must cover, in level-0 map widths.
    pub radius: f64,
    /// Maps per side of that square.
    pub per_side: u32,
    /// Maps at this level.
    pub maps: u64,
}

/// The active area of eq. (7): over every altitude and pitch with the view
/// inside the field of view, level L is needed out to
/// `|x_a| ≤ n_pxl / (2 sin ψ_FOV) · 2^−L` texels of level L, i.e.
/// `n_pxl / (2 sin ψ_FOV · N_map) · 2^−L` level-0 map widths; a square of
/// that half-width holds `2·⌈n_pxl / (2 sin ψ_FOV · N_map)⌉` maps of level L
/// per side. With ψ = 45°, 1024 pixels and 256-texel maps: 2.83·2^−L, 6×6
/// maps per level, 324 maps for levels 0..=8.
pub fn active_area(fov_deg: f64, pixels: u32, map_texels: u32, levels: u32) -> Result<Vec<LevelMaps>, CoreError> {
    if !(fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 180.0) {
        return Err(CoreError::OutOfRange {
            key: "fov".into(),
            message: format!("{fov_deg} is outside (0, 180) degrees"),
        });
    }
    if pixels == 0 || map_texels == 0 || levels == 0 || levels > 32 {
        return Err(CoreError::OutOfRange {
            key: "pixels/map/levels".into(),
            message: "need pixels ≥ 1, map ≥ 1, levels in 1..=32".into(),
        });
    }
    let r0 = pixels as f64 / (2.0 * fov_deg.to_radians().sin() * map_texels as f64);
    // 2·⌈r0⌉ maps per side must be a count (a field of view near 180° over
    // a wide scanline asks for more maps than any store holds)
    let half = r0.ceil().max(1.0);
    if half > (u32::MAX / 2) as f64 {
        return Err(CoreError::OutOfRange {
            key: "fov".into(),
            message: format!(
                "{fov_deg}° over {pixels} pixels of {map_texels}-texel maps needs {:.3e} maps per side",
                2.0 * half
            ),
        });
    }
    let per_side = 2 * half as u32;
    Ok((0..levels)
        .map(|l| LevelMaps {
            level: l,
            radius: r0 * 2f64.powi(-(l as i32)),
            per_side,
            maps: per_side as u64 * per_side as u64,
        })
        .collect())
}

/// Eq. (6): the level needed at ground distance `x` from the nadir for
/// altitude `h` and pitch `theta` (from the nadir), with `k` pixels per unit
/// of tan(angle): `l = log2(k h / ((x² + h²) cos²(θ − ε)))`, ε = atan(x/h).
/// Distances in level-0 texels; the result is the level in the paper's
/// numbering (higher = finer).
pub fn level_at(x: f64, h: f64, theta: f64, k: f64) -> f64 {
    let eps = (x / h).atan();
    (k * h / ((x * x + h * h) * (theta - eps).cos().powi(2))).log2()
}

/// A grid mesh of `w`×`h` posts `spacing` apart (x east, z south, y up),
/// heights scaled by `exaggeration`, centred on the grid's middle, with
/// texture coordinates from `uv(column, row)`.
pub fn grid_mesh(
    heights: &[f32],
    w: usize,
    h: usize,
    spacing: [f32; 2],
    exaggeration: f32,
    uv: impl Fn(usize, usize) -> Vec2,
) -> Result<Mesh, CoreError> {
    if w < 2 || h < 2 || heights.len() != w * h {
        return Err(CoreError::InvalidMesh {
            name: "terrain".into(),
            message: format!("{w}×{h} posts with {} heights", heights.len()),
        });
    }
    let (cx, cz) = ((w - 1) as f32 * spacing[0] / 2.0, (h - 1) as f32 * spacing[1] / 2.0);
    let mut p = Vec::with_capacity(w * h);
    let mut t = Vec::with_capacity(w * h);
    for j in 0..h {
        for i in 0..w {
            p.push(Vec3::new(
                i as f32 * spacing[0] - cx,
                heights[j * w + i] * exaggeration,
                j as f32 * spacing[1] - cz,
            ));
            t.push(uv(i, j));
        }
    }
    let mut idx = Vec::with_capacity((w - 1) * (h - 1) * 6);
    for j in 0..h - 1 {
        for i in 0..w - 1 {
            let a = (j * w + i) as u32;
            let (b, c, d) = (a + w as u32, a + 1, a + w as u32 + 1);
            idx.extend_from_slice(&[a, b, c, c, b, d]);
        }
    }
    Mesh::new("terrain", p, None, Some(t), idx)
}

/// A DEM mesh whose resolution follows the distance to the eye.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LodMesh {
    /// Positions (map x, map y, height), in the units of the map transform.
    pub positions: Vec<[f32; 3]>,
    /// Map position of each vertex (x, y).
    pub tex: Vec<[f32; 2]>,
    /// Triangle indices.
    pub indices: Vec<u32>,
    /// Blocks drawn at each post step (index k: step 2^k).
    pub blocks_per_step: Vec<u32>,
}

/// How [`lod_mesh`] places a DEM grid and chooses its detail.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodOptions {
    /// Map position of post (0, 0) and the map step between posts (x, y).
    pub origin: [f64; 2],
    /// Map units between posts.
    pub spacing: [f64; 2],
    /// Map units per height unit (e.g. texels per metre × exaggeration).
    pub height_scale: f64,
    /// Eye position in map units (x, y, height).
    pub eye: [f64; 3],
    /// Pixels per unit of tan(angle) of the camera (`k` of eq. (6)).
    pub pixels_per_tan: f64,
    /// Largest projected edge of a cell, pixels.
    pub max_edge_px: f64,
    /// Cells per block side (a power of two).
    pub block: usize,
}

/// Geomipmapping: the grid is cut into blocks of `block`×`block` cells; each
/// block takes the largest power-of-two post step whose cells project to at
/// most `max_edge_px` pixels at the block's nearest distance to the eye, and
/// skirts hang from its edges (down to below the block's lowest post) so that
/// neighbours of different steps leave no crack. The triangle count follows
/// the view, not the DEM's size.
pub fn lod_mesh(heights: &[f32], w: usize, h: usize, o: &LodOptions) -> Result<LodMesh, CoreError> {
    let bad = |message: String| CoreError::InvalidMesh { name: "terrain".into(), message };
    if w < 2 || h < 2 || heights.len() != w * h {
        return Err(bad(format!("{w}×{h} posts with {} heights", heights.len())));
    }
    if !o.block.is_power_of_two() || o.block < 2 {
        return Err(bad(format!("block of {} cells is not a power of two ≥ 2", o.block)));
    }
    let finite = [o.origin[0], o.origin[1], o.spacing[0], o.spacing[1], o.height_scale, o.eye[0], o.eye[1], o.eye[2]];
    if finite.iter().any(|v| !v.is_finite()) || o.spacing[0] <= 0.0 || o.spacing[1] <= 0.0 {
        return Err(bad("the grid placement is not finite and positive".into()));
    }
    let height = |i: usize, j: usize| {
        let v = heights[j.min(h - 1) * w + i.min(w - 1)];
        if v.is_finite() { v as f64 } else { 0.0 }
    };
    let post = |i: usize, j: usize| {
        [o.origin[0] + i as f64 * o.spacing[0], o.origin[1] + j as f64 * o.spacing[1], height(i, j) * o.height_scale]
    };
    let cell = o.spacing[0].max(o.spacing[1]);
    let max_step = o.block.trailing_zeros() as usize;
    let mut m = LodMesh { blocks_per_step: vec![0; max_step + 1], ..Default::default() };
    let (bw, bh) = ((w - 1).div_ceil(o.block), (h - 1).div_ceil(o.block));
    for bj in 0..bh {
        for bi in 0..bw {
            let (i0, j0) = (bi * o.block, bj * o.block);
            let (i1, j1) = ((i0 + o.block).min(w - 1), (j0 + o.block).min(h - 1));
            // nearest distance from the eye to the block's box
            let (a, b) = (post(i0, j0), post(i1, j1));
            let (mut lo_z, mut hi_z) = (f64::INFINITY, f64::NEG_INFINITY);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let z = height(i, j) * o.height_scale;
                    lo_z = lo_z.min(z);
                    hi_z = hi_z.max(z);
                }
            }
            let gap = |v: f64, p: f64, q: f64| {
                if v < p.min(q) {
                    p.min(q) - v
                } else if v > p.max(q) {
                    v - p.max(q)
                } else {
                    0.0
                }
            };
            let d = (gap(o.eye[0], a[0], b[0]).powi(2)
                + gap(o.eye[1], a[1], b[1]).powi(2)
                + gap(o.eye[2], lo_z, hi_z).powi(2))
            .sqrt()
            .max(cell);
            // a cell of step s spans s·cell map units, ≈ s·cell·k/d pixels
            let allowed = o.max_edge_px * d / (cell * o.pixels_per_tan.max(1e-9));
            let k = if allowed >= 1.0 { (allowed.log2().floor() as usize).min(max_step) } else { 0 };
            let step = 1usize << k;
            m.blocks_per_step[k] += 1;
            // posts of the block at this step (the last row/column always included)
            let ticks = |lo: usize, hi: usize| {
                let mut t: Vec<usize> = (lo..hi).step_by(step).collect();
                t.push(hi);
                t
            };
            let (xs, ys) = (ticks(i0, i1), ticks(j0, j1));
            let base = m.positions.len() as u32;
            for &j in &ys {
                for &i in &xs {
                    let p = post(i, j);
                    m.positions.push([p[0] as f32, p[1] as f32, p[2] as f32]);
                    m.tex.push([p[0] as f32, p[1] as f32]);
                }
            }
            let nx = xs.len() as u32;
            for r in 0..ys.len() as u32 - 1 {
                for c in 0..nx - 1 {
                    let v = base + r * nx + c;
                    m.indices.extend_from_slice(&[v, v + nx, v + 1, v + 1, v + nx, v + nx + 1]);
                }
            }
            // skirts along the four edges, down to below the block's lowest post
            let drop = (lo_z - (hi_z - lo_z).max(cell * step as f64)) as f32;
            let edges: [Vec<u32>; 4] = [
                (0..nx).map(|c| base + c).collect(),
                (0..ys.len() as u32).map(|r| base + r * nx + nx - 1).collect(),
                (0..nx).rev().map(|c| base + (ys.len() as u32 - 1) * nx + c).collect(),
                (0..ys.len() as u32).rev().map(|r| base + r * nx).collect(),
            ];
            for e in edges {
                for pair in e.windows(2) {
                    let (t0, t1) = (pair[0] as usize, pair[1] as usize);
                    let s0 = m.positions.len() as u32;
                    for t in [t0, t1] {
                        let p = m.positions[t];
                        m.positions.push([p[0], p[1], drop]);
                        m.tex.push(m.tex[t]);
                    }
                    m.indices.extend_from_slice(&[pair[0], s0, pair[1], pair[1], s0, s0 + 1]);
                }
            }
        }
    }
    Ok(m)
}

/// Elevation colours (green lowlands, brown hills, white peaks) as a texture;
/// heights at or below zero are sea (blue, darker with depth) when the
/// model also has land, so that a coast reads as one.
pub fn hypsometric(heights: &[f32], w: u32, h: u32) -> Result<Image, CoreError> {
    let lo = heights.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = heights.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let sea = lo <= 0.0 && hi > 0.0;
    let land_lo = if sea { 0.0 } else { lo };
    let stops = [[40.0, 110.0, 60.0], [150.0, 170.0, 90.0], [140.0, 100.0, 60.0], [245.0, 245.0, 245.0]];
    let (shallow, deep) = ([70.0f32, 125.0, 175.0], [20.0f32, 50.0, 110.0]);
    Image::from_fn(w, h, ColorSpace::Srgb, |x, y| {
        let z = heights[(y * w + x) as usize];
        if sea && z <= 0.0 {
            let d = if lo < 0.0 { (z / lo).clamp(0.0, 1.0) } else { 0.0 };
            let c = |k: usize| (shallow[k] + (deep[k] - shallow[k]) * d) as u8;
            return [c(0), c(1), c(2), 255];
        }
        let t = ((z - land_lo) / (hi - land_lo).max(1e-6)).clamp(0.0, 1.0) * 2.999;
        let (i, f) = (t as usize, t.fract());
        let c = |k: usize| (stops[i][k] + (stops[i + 1][k] - stops[i][k]) * f) as u8;
        [c(0), c(1), c(2), 255]
    })
}

/// A shaded relief of a DEM, `k`×`k` texels a post: the elevation colours
/// of [`hypsometric`] on heights interpolated bilinearly between posts,
/// lit by a sun in the north-west 45° above the horizon (the cartographic
/// convention) with a third of ambient light. `spacing` is the post
/// spacing (x, y) in the heights' unit, so that slopes are true. For a
/// store built from elevations alone, which a flight then drapes over the
/// same DEM.
pub fn shaded_relief(heights: &[f32], w: u32, h: u32, spacing: [f64; 2], k: u32) -> Result<Image, CoreError> {
    if heights.len() != w as usize * h as usize || w == 0 || h == 0 || k == 0 {
        return Err(CoreError::OutOfRange {
            key: "shaded relief".into(),
            message: format!("{} heights for {w}×{h} posts at {k} texels a post", heights.len()),
        });
    }
    let colours = hypsometric(heights, w, h)?;
    let at = |x: f64, y: f64| -> f64 {
        let (x, y) = (x.clamp(0.0, (w - 1) as f64), y.clamp(0.0, (h - 1) as f64));
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w as usize - 1), (y0 + 1).min(h as usize - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let v = |i: usize, j: usize| heights[j * w as usize + i] as f64;
        let top = v(x0, y0) + (v(x1, y0) - v(x0, y0)) * fx;
        let bot = v(x0, y1) + (v(x1, y1) - v(x0, y1)) * fx;
        top + (bot - top) * fy
    };
    let colour = |x: f64, y: f64| -> [f64; 3] {
        let (x, y) = (x.clamp(0.0, (w - 1) as f64), y.clamp(0.0, (h - 1) as f64));
        let (x0, y0) = (x.floor() as u32, y.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let c = |i: u32, j: u32, ch: usize| colours.texel(i, j)[ch] as f64;
        std::array::from_fn(|ch| {
            let top = c(x0, y0, ch) + (c(x1, y0, ch) - c(x0, y0, ch)) * fx;
            let bot = c(x0, y1, ch) + (c(x1, y1, ch) - c(x0, y1, ch)) * fx;
            top + (bot - top) * fy
        })
    };
    // towards the sun: north-west (rows run south), 45° up
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let sun = [-0.5, 0.5, s];
    Image::from_fn(w * k, h * k, ColorSpace::Srgb, |tx, ty| {
        let (x, y) = ((tx as f64 + 0.5) / k as f64 - 0.5, (ty as f64 + 0.5) / k as f64 - 0.5);
        // slopes east and north over one post
        let dzdx = (at(x + 0.5, y) - at(x - 0.5, y)) / spacing[0];
        let dzdy = (at(x, y - 0.5) - at(x, y + 0.5)) / spacing[1];
        let n = [-dzdx, -dzdy, 1.0];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let lit = ((n[0] * sun[0] + n[1] * sun[1] + n[2] * sun[2]) / len).max(0.0);
        // flat ground keeps its colour: shade relative to a level surface
        let shade = (1.0 / 3.0 + 2.0 / 3.0 * lit) / (1.0 / 3.0 + 2.0 / 3.0 * s);
        let c = colour(x, y);
        let q = |v: f64| (v * shade).round().clamp(0.0, 255.0) as u8;
        [q(c[0]), q(c[1]), q(c[2]), 255]
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_papers_setting_needs_324_maps() {
        let a = active_area(45.0, 1024, 256, 9).unwrap();
        assert!((a[0].radius - 2.83).abs() < 0.01, "{}", a[0].radius);
        assert!((a[3].radius - 2.83 / 8.0).abs() < 0.01);
        assert!(a.iter().all(|l| l.maps == 36));
        assert_eq!(a.iter().map(|l| l.maps).sum::<u64>(), 324);
        assert!(active_area(0.0, 1024, 256, 9).is_err());
        assert!(active_area(45.0, 0, 256, 9).is_err());
    }

    #[test]
    fn eq6_is_bounded_by_eq7() {
        // for every altitude and pitch with the point in view, l(x) ≤ log2(n / (2 sin ψ x))
        let (psi, n) = (45f64.to_radians(), 1024.0);
        let k = n / (2.0 * (psi / 2.0).tan());
        for h in [10.0f64, 100.0, 1000.0] {
            for theta_deg in (0..=89).step_by(7) {
                let theta = (theta_deg as f64).to_radians();
                for x in [1.0f64, 10.0, 100.0, 1000.0, 10000.0] {
                    let eps = (x / h).atan();
                    if (theta - eps).abs() > psi / 2.0 {
                        continue;
                    }
                    let l = level_at(x, h, theta, k);
                    let bound = (n / (2.0 * psi.sin() * x)).log2();
                    assert!(l <= bound + 1e-9, "h {h} θ {theta_deg} x {x}: {l} > {bound}");
                }
            }
        }
    }

    #[test]
    fn grid_mesh_faces_up() {
        let m =
            grid_mesh(&[0.0, 1.0, 2.0, 3.0, 4.0, 5.0], 3, 2, [10.0, 10.0], 1.0, |i, j| Vec2::new(i as f32, j as f32))
                .unwrap();
        assert_eq!(m.triangle_count(), 4);
        assert!(m.normals.iter().all(|n| n.y > 0.0));
        assert!(grid_mesh(&[0.0; 3], 3, 2, [1.0, 1.0], 1.0, |_, _| Vec2::ZERO).is_err());
    }

    fn lod_options(eye: [f64; 3]) -> LodOptions {
        LodOptions {
            origin: [0.0, 0.0],
            spacing: [4.0, 4.0],
            height_scale: 1.0,
            eye,
            pixels_per_tan: 1024.0 / (2.0 * (22.5f64).to_radians().tan()),
            max_edge_px: 8.0,
            block: 16,
        }
    }

    #[test]
    fn lod_follows_the_distance_not_the_grid() {
        let (w, h) = (257, 257);
        let heights: Vec<f32> = (0..w * h).map(|i| ((i % w) as f32 * 0.1).sin() * 5.0).collect();
        let near = lod_mesh(&heights, w, h, &lod_options([512.0, 512.0, 50.0])).unwrap();
        let far = lod_mesh(&heights, w, h, &lod_options([512.0, 512.0, 50_000.0])).unwrap();
        // near the eye the finest step is used, far away the coarsest
        assert!(near.blocks_per_step[0] > 0, "{:?}", near.blocks_per_step);
        assert_eq!(far.blocks_per_step[4], 256, "{:?}", far.blocks_per_step);
        assert!(far.indices.len() * 20 < near.indices.len(), "{} vs {}", far.indices.len(), near.indices.len());
        // every index is in range and every vertex finite
        for m in [&near, &far] {
            assert!(m.indices.iter().all(|&i| (i as usize) < m.positions.len()));
            assert!(m.positions.iter().flatten().all(|v| v.is_finite()));
            assert_eq!(m.positions.len(), m.tex.len());
        }
    }

    #[test]
    fn lod_posts_sit_on_the_grid_and_skirts_hang_below() {
        let (w, h) = (33, 17);
        let heights: Vec<f32> = (0..w * h).map(|i| (i / w) as f32).collect();
        let m = lod_mesh(&heights, w, h, &lod_options([0.0, 0.0, 1.0e6])).unwrap();
        for p in &m.positions {
            let (i, j) = (p[0] / 4.0, p[1] / 4.0);
            assert_eq!(i.fract(), 0.0);
            assert_eq!(j.fract(), 0.0);
            // a post at its height, or a skirt vertex below every post of the grid's rows it spans
            assert!(p[2] == j || p[2] < j - 0.5, "{p:?}");
        }
        assert!(lod_mesh(&heights, w, h, &LodOptions { block: 3, ..lod_options([0.0; 3]) }).is_err());
        assert!(lod_mesh(&heights[1..], w, h, &lod_options([0.0; 3])).is_err());
        assert!(lod_mesh(&heights, w, h, &LodOptions { spacing: [f64::NAN, 1.0], ..lod_options([0.0; 3]) }).is_err());
    }
}
