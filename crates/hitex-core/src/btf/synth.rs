//! Procedural BTFs: tileable height-field micro-geometry rendered for every
//! (view, light) pair of an angular grid.
//!
//! There is no measured BTF offline, so these stand in for the paper's
//! captured corduroy: each material is a periodic height field with an albedo
//! pattern and a microfacet specular layer. Every image is rendered the way
//! a BTF acquisition rig photographs a flat sample, rectified to the sample
//! plane: the pixel (x, y) looks down the view direction through the point
//! (x, y, 0) and sees the first height-field point the ray meets (masking and
//! parallax), lit by a distant light unless the height field casts a shadow
//! on it, shaded with Lambert + GGX (Smith masking, Schlick Fresnel), without
//! inter-reflections. 2×2 rays per texel antialias the images.

use super::dataset::Btf;
use super::grid::AngularGrid;
use crate::CoreError;
use crate::texture::linear_to_srgb_u8;
use crate::texture::sampler::floor;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::f32::consts::PI;

/// A built-in material.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Material {
    /// Parallel rounded wales with fibre noise (the paper's sample).
    Corduroy,
    /// Columns of V-shaped knitted stitches.
    Knit,
    /// Pebbled leather: Voronoi pebbles with creased grooves.
    Leather,
    /// Plain-weave fabric of two thread colours.
    Woven,
    /// Brushed aluminium: fine grooves along one direction, metallic.
    BrushedMetal,
}

impl Material {
    /// Every built-in material.
    pub const ALL: [Material; 5] =
        [Material::Corduroy, Material::Knit, Material::Leather, Material::Woven, Material::BrushedMetal];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Material::Corduroy => "corduroy",
            Material::Knit => "knit",
            Material::Leather => "leather",
            Material::Woven => "woven",
            Material::BrushedMetal => "brushed-metal",
        }
    }

    /// Parses a name (see [`Material::name`]).
    pub fn parse(s: &str) -> Option<Material> {
        Material::ALL.into_iter().find(|m| m.name() == s.trim().to_ascii_lowercase())
    }
}

/// A periodic micro-surface over the unit square: heights in units of the
/// sample width, linear albedo, GGX roughness α and specular reflectance.
#[derive(Debug, Clone)]
pub struct MicroSurface {
    /// Grid resolution per side.
    pub res: usize,
    /// Heights, row-major.
    pub height: Vec<f32>,
    /// Linear diffuse albedo, row-major.
    pub albedo: Vec<Vec3>,
    /// GGX roughness α.
    pub alpha: f32,
    /// Specular reflectance at normal incidence.
    pub f0: Vec3,
}

fn rand2(i: i64, j: i64, seed: u64) -> f32 {
    (crate::splitmix64((i as u64) ^ (j as u64).rotate_left(21) ^ seed.rotate_left(42)) >> 40) as f32
        / (1u64 << 24) as f32
}

/// Periodic value noise of `cells` cells per unit.
fn value_noise(p: Vec2, cells: i64, seed: u64) -> f32 {
    let q = p * cells as f32;
    let (i, j) = (floor(q.x) as i64, floor(q.y) as i64);
    let (fx, fy) = (q.x - floor(q.x), q.y - floor(q.y));
    let s = |a: f32| a * a * (3.0 - 2.0 * a);
    let r = |a: i64, b: i64| rand2(a.rem_euclid(cells), b.rem_euclid(cells), seed);
    let top = r(i, j) + (r(i + 1, j) - r(i, j)) * s(fx);
    let bot = r(i, j + 1) + (r(i + 1, j + 1) - r(i, j + 1)) * s(fx);
    top + (bot - top) * s(fy)
}

fn srgb(c: [f32; 3]) -> Vec3 {
    Vec3::from_array(c.map(crate::texture::srgb_to_linear))
}

fn cap(d: f32, r: f32) -> f32 {
    let x = (d / r).clamp(-1.0, 1.0);
    (1.0 - x * x).max(0.0).sqrt()
}

fn seg_dist(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (p - a - ab * t).length()
}

impl MicroSurface {
    /// The micro-surface of a built-in material at `res`² grid points.
    pub fn of(material: Material, res: usize) -> Self {
        let res = res.max(8);
        let mut height = vec![0.0; res * res];
        let mut albedo = vec![Vec3::ZERO; res * res];
        let (alpha, f0);
        match material {
            Material::Corduroy => {
                alpha = 0.55;
                f0 = Vec3::splat(0.03);
                let (pile, groove) = (srgb([0.55, 0.16, 0.12]), srgb([0.25, 0.06, 0.05]));
                fill(res, &mut height, &mut albedo, |p| {
                    let wales = 4.0;
                    let c = (p.x * wales).fract() - 0.5;
                    let ridge = cap(c, 0.42);
                    let fibre = value_noise(p, 32, 7) * 0.5 + value_noise(Vec2::new(p.x, p.y * 0.25), 64, 9) * 0.5;
                    let h = 0.07 * ridge + 0.006 * fibre;
                    let a = groove.lerp(pile, ridge.sqrt()) * (0.85 + 0.3 * fibre);
                    (h, a)
                });
            }
            Material::Knit => {
                alpha = 0.7;
                f0 = Vec3::splat(0.03);
                let wool = srgb([0.78, 0.74, 0.62]);
                let shade = srgb([0.30, 0.36, 0.55]);
                fill(res, &mut height, &mut albedo, |p| {
                    let (cols, rows) = (4.0, 5.0);
                    let q = Vec2::new((p.x * cols).fract(), (p.y * rows).fract());
                    let row = floor(p.y * rows) as i64;
                    let mut h: f32 = 0.0;
                    // the V of one stitch and the legs reaching into the next row
                    for dy in [-1.0f32, 0.0, 1.0] {
                        let o = Vec2::new(0.0, dy);
                        let l = seg_dist(q, Vec2::new(0.08, -0.1) + o, Vec2::new(0.5, 0.9) + o);
                        let r = seg_dist(q, Vec2::new(0.92, -0.1) + o, Vec2::new(0.5, 0.9) + o);
                        h = h.max(cap(l, 0.2)).max(cap(r, 0.2));
                    }
                    let fuzz = value_noise(p, 48, 3);
                    let stripe = if row.rem_euclid(5) == 2 { shade } else { wool };
                    (0.08 * h + 0.008 * fuzz, stripe * (0.55 + 0.45 * h) * (0.9 + 0.2 * fuzz))
                });
            }
            Material::Leather => {
                alpha = 0.38;
                f0 = Vec3::splat(0.04);
                let tan = srgb([0.42, 0.24, 0.13]);
                fill(res, &mut height, &mut albedo, |p| {
                    let cells = 7i64;
                    let q = p * cells as f32;
                    let (ci, cj) = (floor(q.x) as i64, floor(q.y) as i64);
                    let (mut d1, mut d2) = (9.0f32, 9.0f32);
                    for dj in -1..=1 {
                        for di in -1..=1 {
                            let (i, j) = (ci + di, cj + dj);
                            let (wi, wj) = (i.rem_euclid(cells), j.rem_euclid(cells));
                            let c = Vec2::new(
                                i as f32 + 0.15 + 0.7 * rand2(wi, wj, 11),
                                j as f32 + 0.15 + 0.7 * rand2(wi, wj, 12),
                            );
                            let d = (q - c).length();
                            if d < d1 {
                                d2 = d1;
                                d1 = d;
                            } else if d < d2 {
                                d2 = d;
                            }
                        }
                    }
                    let edge = ((d2 - d1) / 0.25).clamp(0.0, 1.0);
                    let dome = edge.sqrt() * (1.0 - 0.35 * d1);
                    let grain = value_noise(p, 40, 5);
                    let h = 0.05 * dome + 0.004 * grain;
                    (h, tan * (0.6 + 0.4 * dome) * (0.9 + 0.2 * grain))
                });
            }
            Material::Woven => {
                alpha = 0.45;
                f0 = Vec3::splat(0.04);
                let (warp_c, weft_c) = (srgb([0.16, 0.26, 0.58]), srgb([0.86, 0.68, 0.22]));
                fill(res, &mut height, &mut albedo, |p| {
                    let n = 6.0;
                    let (gx, gy) = (p.x * n, p.y * n);
                    let (i, j) = (floor(gx) as i64, floor(gy) as i64);
                    let (fx, fy) = (gx.fract() - 0.5, gy.fract() - 0.5);
                    let warp_over = (i + j).rem_euclid(2) == 0;
                    // warp threads run along y (profile across x), weft along x
                    let undulate = |f: f32, over: bool| {
                        let s = (f * PI).cos();
                        if over { 0.6 + 0.4 * s } else { 0.6 - 0.4 * s }
                    };
                    let warp = cap(fx, 0.45) * undulate(fy, warp_over);
                    let weft = cap(fy, 0.45) * undulate(fx, !warp_over);
                    let fibre = value_noise(p, 64, 21);
                    let (h, a) = if warp >= weft { (warp, warp_c) } else { (weft, weft_c) };
                    (0.06 * h + 0.003 * fibre, a * (0.6 + 0.4 * h))
                });
            }
            Material::BrushedMetal => {
                alpha = 0.22;
                f0 = srgb([0.91, 0.92, 0.92]);
                fill(res, &mut height, &mut albedo, |p| {
                    // grooves along x: height varies with y only (plus a faint wobble)
                    let g = value_noise(Vec2::new(p.x * 0.0625, p.y), 96, 31) * 0.7
                        + value_noise(Vec2::new(p.x * 0.125, p.y), 48, 37) * 0.3;
                    (0.012 * g, Vec3::ZERO)
                });
            }
        }
        Self { res, height, albedo, alpha, f0 }
    }

    /// Height at a point of the periodic square (bilinear).
    pub fn height_at(&self, p: Vec2) -> f32 {
        bilinear(&self.height, self.res, p)
    }

    fn albedo_at(&self, p: Vec2) -> Vec3 {
        let n = self.res as f32;
        let (x, y) = (floor(p.x * n) as i64, floor(p.y * n) as i64);
        let r = self.res as i64;
        self.albedo[(y.rem_euclid(r) * r + x.rem_euclid(r)) as usize]
    }

    fn normal_at(&self, p: Vec2) -> Vec3 {
        let e = 0.5 / self.res as f32;
        let dx = (self.height_at(p + Vec2::new(e, 0.0)) - self.height_at(p - Vec2::new(e, 0.0))) / (2.0 * e);
        let dy = (self.height_at(p + Vec2::new(0.0, e)) - self.height_at(p - Vec2::new(0.0, e))) / (2.0 * e);
        Vec3::new(-dx, -dy, 1.0).normalize()
    }

    fn max_height(&self) -> f32 {
        self.height.iter().copied().fold(0.0, f32::max)
    }

    /// First point of the height field met by the ray that reaches (x, y, 0)
    /// travelling along −`dir` (dir points from the surface to the eye).
    fn trace(&self, xy: Vec2, dir: Vec3, hmax: f32) -> Vec2 {
        if dir.z >= 0.9999 {
            return xy;
        }
        let step = 0.35 / self.res as f32;
        let horiz = Vec2::new(dir.x, dir.y);
        let hl = horiz.length();
        let slope = dir.z / hl.max(1e-6);
        let mut t = (hmax + 1e-4) / slope; // horizontal distance where the ray is at hmax
        let unit = horiz / hl.max(1e-6);
        let at = |t: f32| (xy + unit * t, t * slope);
        let mut prev = t;
        while t > 0.0 {
            let (p, z) = at(t);
            if z <= self.height_at(p) {
                // refine between prev (above) and t (below)
                let (mut a, mut b) = (prev, t);
                for _ in 0..8 {
                    let m = 0.5 * (a + b);
                    let (pm, zm) = at(m);
                    if zm <= self.height_at(pm) { b = m } else { a = m }
                }
                return at(b).0;
            }
            prev = t;
            t -= step;
        }
        at(0.0).0
    }

    /// 1 where the light along `dir` reaches grid point (i, j), 0 in shadow.
    fn lit(&self, i: usize, j: usize, dir: Vec3, hmax: f32) -> f32 {
        let n = self.res as f32;
        let p0 = Vec2::new(i as f32 / n, j as f32 / n);
        let z0 = self.height[j * self.res + i] + 0.002;
        let horiz = Vec2::new(dir.x, dir.y);
        let hl = horiz.length();
        if hl < 1e-6 {
            return 1.0;
        }
        let slope = dir.z / hl;
        let unit = horiz / hl;
        let step = 0.5 / n;
        let mut t = step;
        while z0 + t * slope <= hmax {
            if self.height_at(p0 + unit * t) > z0 + t * slope {
                return 0.0;
            }
            t += step;
        }
        1.0
    }
}

fn fill(res: usize, height: &mut [f32], albedo: &mut [Vec3], f: impl Fn(Vec2) -> (f32, Vec3)) {
    for j in 0..res {
        for i in 0..res {
            let (h, a) = f(Vec2::new(i as f32 / res as f32, j as f32 / res as f32));
            height[j * res + i] = h;
            albedo[j * res + i] = a;
        }
    }
}

fn bilinear(v: &[f32], res: usize, p: Vec2) -> f32 {
    let n = res as f32;
    let (x, y) = (p.x * n, p.y * n);
    let (x0, y0) = (floor(x), floor(y));
    let (fx, fy) = (x - x0, y - y0);
    let r = res as i64;
    let at = |i: i64, j: i64| v[(j.rem_euclid(r) * r + i.rem_euclid(r)) as usize];
    let (i, j) = (x0 as i64, y0 as i64);
    let top = at(i, j) + (at(i + 1, j) - at(i, j)) * fx;
    let bot = at(i, j + 1) + (at(i + 1, j + 1) - at(i, j + 1)) * fx;
    top + (bot - top) * fy
}

/// Options of [`synthesize`].
#[derive(Debug, Clone)]
pub struct SynthOptions {
    /// Angular grid (the paper's 8 × 16 by default).
    pub grid: AngularGrid,
    /// Sample width and height in texels (32 × 32 in the paper).
    pub size: u32,
    /// Rays per texel side (2 → 4 rays per texel).
    pub supersample: u32,
    /// Irradiance scale: 1 makes a white Lambertian facet facing the light 1.0.
    pub exposure: f32,
}

impl Default for SynthOptions {
    fn default() -> Self {
        Self { grid: AngularGrid::paper(), size: 32, supersample: 2, exposure: 0.85 }
    }
}

/// GGX microfacet specular term times N·L, with Smith masking-shadowing.
fn ggx(n: Vec3, v: Vec3, l: Vec3, alpha: f32, f0: Vec3) -> Vec3 {
    let nl = n.dot(l);
    let nv = n.dot(v);
    if nl <= 0.0 || nv <= 0.0 {
        return Vec3::ZERO;
    }
    let h = (v + l).normalize();
    let nh = n.dot(h).max(0.0);
    let a2 = alpha * alpha;
    let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let g1 = |c: f32| 2.0 * c / (c + (a2 + (1.0 - a2) * c * c).sqrt());
    let f = f0 + (Vec3::ONE - f0) * (1.0 - v.dot(h).max(0.0)).powi(5);
    f * (d * g1(nl) * g1(nv) / (4.0 * nv * nl) * nl)
}

/// Renders the BTF of `material` on the grid of `opts`, calling `progress`
/// with the number of view directions finished (from worker threads).
pub fn synthesize(
    material: Material,
    opts: &SynthOptions,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Btf, CoreError> {
    let size = opts.size;
    let ss = opts.supersample.clamp(1, 8);
    let mut btf = Btf::zeroed(opts.grid.clone(), size, size)?;
    let surf = MicroSurface::of(material, (size as usize * 2).max(64));
    let hmax = surf.max_height();
    let grid = &opts.grid;
    let dirs = grid.directions();
    let dir_vec = |d: usize| grid.vector(d / grid.phi_count(), d % grid.phi_count());
    // cast shadows: one map per light direction over the height-field grid
    let res = surf.res;
    let shadows: Vec<Vec<f32>> = (0..dirs)
        .into_par_iter()
        .map(|d| {
            let l = dir_vec(d);
            (0..res * res).map(|k| surf.lit(k % res, k / res, l, hmax)).collect()
        })
        .collect();
    let image_bytes = btf.image_bytes();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let exposure = opts.exposure;
    btf.texels_mut().par_chunks_mut(dirs * image_bytes).enumerate().for_each(|(view, block)| {
        let v = dir_vec(view);
        // what each ray sees: hit point, its normal and albedo
        let n_rays = (size * size * ss * ss) as usize;
        let mut hits = Vec::with_capacity(n_rays);
        for y in 0..size {
            for x in 0..size {
                for sy in 0..ss {
                    for sx in 0..ss {
                        let xy = Vec2::new(
                            (x as f32 + (sx as f32 + 0.5) / ss as f32) / size as f32,
                            (y as f32 + (sy as f32 + 0.5) / ss as f32) / size as f32,
                        );
                        let q = surf.trace(xy, v, hmax);
                        hits.push((q, surf.normal_at(q), surf.albedo_at(q)));
                    }
                }
            }
        }
        let per_texel = (ss * ss) as usize;
        for light in 0..dirs {
            let l = dir_vec(light);
            let shadow = &shadows[light];
            let img = &mut block[light * image_bytes..(light + 1) * image_bytes];
            for (t, px) in img.chunks_exact_mut(3).enumerate() {
                let mut sum = Vec3::ZERO;
                for &(q, n, a) in &hits[t * per_texel..(t + 1) * per_texel] {
                    let lit = bilinear(shadow, res, q);
                    if lit <= 0.0 {
                        continue;
                    }
                    let nl = n.dot(l).max(0.0);
                    let diffuse = a * nl;
                    let spec = ggx(n, v, l, surf.alpha, surf.f0);
                    sum += (diffuse + spec) * lit;
                }
                let c = sum * (exposure / per_texel as f32);
                px.copy_from_slice(&[linear_to_srgb_u8(c.x), linear_to_srgb_u8(c.y), linear_to_srgb_u8(c.z)]);
            }
        }
        progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
    });
    Ok(btf)
}

/// An 8×8 corduroy on a two-elevation, four-azimuth grid: the small sample
/// the index-synthesis, feature and seam tests share.
#[cfg(test)]
pub(crate) fn tiny_corduroy() -> Btf {
    let grid = AngularGrid::new(vec![0.0, 40.0], 4).unwrap();
    synthesize(Material::Corduroy, &SynthOptions { grid, size: 8, supersample: 1, exposure: 0.85 }, &|_| {}).unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small(material: Material) -> Btf {
        let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 8).unwrap();
        let opts = SynthOptions { grid, size: 8, supersample: 1, exposure: 0.85 };
        synthesize(material, &opts, &|_| {}).unwrap()
    }

    fn mean(img: &[u8]) -> f32 {
        img.iter().map(|&b| b as f32).sum::<f32>() / img.len() as f32
    }

    #[test]
    fn grazing_light_is_darker_than_overhead() {
        for m in [Material::Corduroy, Material::Leather, Material::Woven, Material::Knit] {
            let b = small(m);
            let g = b.grid();
            let top = mean(b.image(0, g.direction(0, 0)));
            let low = mean(b.image(0, g.direction(2, 3)));
            assert!(top > low, "{}: overhead {top} vs grazing {low}", m.name());
        }
    }

    #[test]
    fn corduroy_wales_cast_shadows_across_not_along() {
        // light from +x (across the wales) shadows the grooves; along y it does not
        let b = small(Material::Corduroy);
        let g = b.grid();
        let across = mean(b.image(0, g.direction(2, 0)));
        let along = mean(b.image(0, g.direction(2, 2)));
        assert!(along > across * 1.05, "along {along} across {across}");
    }

    #[test]
    fn metal_has_a_mirror_peak() {
        let b = small(Material::BrushedMetal);
        let g = b.grid();
        // view θ=30° φ=0, light at the mirror direction θ=30° φ=180°
        let mirror = mean(b.image(g.direction(1, 0), g.direction(1, 4)));
        let off = mean(b.image(g.direction(1, 0), g.direction(1, 0)));
        assert!(mirror > 2.0 * off, "mirror {mirror} off {off}");
    }

    #[test]
    fn samples_tile_seamlessly() {
        // opposite edges of an image differ no more than neighbouring columns do
        let b = small(Material::Woven);
        let img = b.image(0, 0);
        let w = b.width() as usize;
        let col = |x: usize| (0..w).map(|y| img[(y * w + x) * 3] as f32).collect::<Vec<_>>();
        let d = |a: &[f32], c: &[f32]| a.iter().zip(c).map(|(p, q)| (p - q).abs()).sum::<f32>();
        let seam = d(&col(w - 1), &col(0));
        let inner: f32 = (0..w - 1).map(|x| d(&col(x), &col(x + 1))).sum::<f32>() / (w - 1) as f32;
        assert!(seam < 2.5 * inner + 1.0, "seam {seam} vs inner {inner}");
    }

    #[test]
    fn names_round_trip() {
        for m in Material::ALL {
            assert_eq!(Material::parse(m.name()), Some(m));
        }
        assert_eq!(Material::parse("velvet"), None);
    }
}
