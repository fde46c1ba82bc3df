//! Terrain: the active area of seed 001 (eq. (5)–(7)) and meshes from
//! elevation grids.

use crate::CoreError;
use crate::scene::Mesh;
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
    pub maps: u32,
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
    Ok((0..levels)
        .map(|l| {
            let per_side = 2 * (r0.ceil() as u32).max(1);
            LevelMaps { level: l, radius: r0 * 2f64.powi(-(l as i32)), per_side, maps: per_side * per_side }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_papers_setting_needs_324_maps() {
        let a = active_area(45.0, 1024, 256, 9).unwrap();
        assert!((a[0].radius - 2.83).abs() < 0.01, "{}", a[0].radius);
        assert!((a[3].radius - 2.83 / 8.0).abs() < 0.01);
        assert!(a.iter().all(|l| l.maps == 36));
        assert_eq!(a.iter().map(|l| l.maps).sum::<u32>(), 324);
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
}
