//! Flights over a GST pyramid through the resident-map cache, prepared for
//! both backends: the camera, the ground — flat (eq. (1), solved per pixel)
//! or the DEM as a mesh ([`FlyMesh`], with other objects such as an
//! aircraft carrying a generic texture) — and the frame's *page table*: for
//! every level, the window of the active area (eq. (7)) and, per map slot of
//! it, which resident map serves it (itself, or the nearest coarser ancestor
//! while it loads). `cpu/terrain.rs` and `shaders/terrain.wgsl` read the
//! same table and filter it with the same [`FlySampler`]. [`flight`] does a
//! flight's per-frame work above the renderer: path keys to cameras, the
//! cache's requests and page table, the DEM meshed for the eye.

pub mod flight;

use glam::{Mat4, Vec3, Vec4};
use hitex_core::residency::{MapKey, ResidentMaps};
use hitex_core::texture::{ColorSpace, Image, MipPyramid};
use std::collections::HashMap;
use std::sync::Arc;

/// Side of a map in texels.
pub const MAP: u32 = 256;

/// A camera over flat ground, in finest-level texels (x east, y south, z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlyCamera {
    /// Eye position.
    pub eye: [f64; 3],
    /// Unit view direction.
    pub fwd: [f64; 3],
    /// Unit right vector.
    pub right: [f64; 3],
    /// Unit up vector of the image.
    pub up: [f64; 3],
    /// tan of half the horizontal field of view.
    pub tan_h: f64,
}

impl FlyCamera {
    /// A camera at ground point (x, y) and `altitude`, `pitch` degrees from the
    /// nadir, `heading` degrees clockwise from north, horizontal field of view `fov`.
    pub fn new(x: f64, y: f64, altitude: f64, pitch: f64, heading: f64, fov: f64) -> Self {
        let (th, hd) = (pitch.to_radians(), heading.to_radians());
        let fwd = [th.sin() * hd.sin(), -th.sin() * hd.cos(), -th.cos()];
        let right = [hd.cos(), hd.sin(), 0.0];
        // up = fwd × right
        let up = [
            fwd[1] * right[2] - fwd[2] * right[1],
            fwd[2] * right[0] - fwd[0] * right[2],
            fwd[0] * right[1] - fwd[1] * right[0],
        ];
        let l = (up[0] * up[0] + up[1] * up[1] + up[2] * up[2]).sqrt().max(1e-12);
        Self {
            eye: [x, y, altitude],
            fwd,
            right,
            up: [up[0] / l, up[1] / l, up[2] / l],
            tan_h: (fov.clamp(1.0, 170.0).to_radians() / 2.0).tan(),
        }
    }
}

/// One frame's page table and the maps it names.
#[derive(Debug, Clone)]
pub struct FlyPages {
    /// Levels of the pyramid.
    pub levels: u32,
    /// Maps per side of each level's window.
    pub per_side: u32,
    /// Per level, the first map column and row of its window.
    pub origins: Vec<[i32; 2]>,
    /// Per level and window slot (row-major), the map serving it, if any data lies there.
    pub slots: Vec<Option<MapKey>>,
    /// The texels (RGBA8 sRGB, 256×256) of every map the slots name.
    pub maps: HashMap<MapKey, Arc<Vec<u8>>>,
}

impl FlyPages {
    /// The page table for an eye above ground point `eye` (finest texels),
    /// from what `cache` holds now; `data_range(z)` bounds the maps with data
    /// (first column, first row, one past the last of each).
    pub fn new(
        cache: &ResidentMaps,
        levels: u32,
        per_side: u32,
        data_range: impl Fn(u32) -> [u32; 4],
        eye: [f64; 2],
    ) -> Self {
        let mut origins = Vec::with_capacity(levels as usize);
        let mut slots = Vec::with_capacity((levels * per_side * per_side) as usize);
        let mut maps = HashMap::new();
        for z in 0..levels {
            let span = MAP as f64 * (1u64 << (levels - 1 - z)) as f64;
            let [c0, r0, c1, r1] = data_range(z);
            let half = per_side as f64 / 2.0;
            let o = [(eye[0] / span - half).floor() as i32, (eye[1] / span - half).floor() as i32];
            origins.push(o);
            for k in 0..(per_side * per_side) as i32 {
                let (x, y) = (o[0] + k % per_side as i32, o[1] + k / per_side as i32);
                if x < c0 as i32 || y < r0 as i32 || x >= c1 as i32 || y >= r1 as i32 {
                    slots.push(None);
                    continue;
                }
                let (found, texels) = cache.lookup(MapKey { z, x: x as u32, y: y as u32 });
                maps.entry(found).or_insert(texels);
                slots.push(Some(found));
            }
        }
        Self { levels, per_side, origins, slots, maps }
    }
}

/// How a flight frame filters its maps. Its names ([`FlySampler::name`])
/// are those of the command line, the viewer and the reports (with the
/// `clap` feature, `clap::ValueEnum` derives the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum FlySampler {
    /// Per pixel, eq. (1)–(4): level from the largest partial, trilinear.
    #[default]
    #[cfg_attr(feature = "clap", value(help = "Per pixel, eq. (1)–(4)."))]
    Trilinear,
    /// 2×2 spans from 3×3 interleaved banks (eq. (8)–(10)).
    #[cfg_attr(feature = "clap", value(help = "2×2 spans, 3×3 banks."))]
    Span3,
    /// 2×2 spans from 4×4 banks (no extra blur).
    #[cfg_attr(feature = "clap", value(help = "2×2 spans, 4×4 banks."))]
    Span4,
    /// Catmull-Rom inside the 4×4-bank mspan of each span.
    #[cfg_attr(feature = "clap", value(help = "Catmull-Rom inside the 4×4-bank mspan."))]
    Bicubic,
}

impl FlySampler {
    /// Every sampler, in report order.
    pub const ALL: [FlySampler; 4] = [FlySampler::Trilinear, FlySampler::Span3, FlySampler::Span4, FlySampler::Bicubic];
    /// The sampler of a name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
    /// Name on the command line, in reports and JSON.
    pub fn name(self) -> &'static str {
        match self {
            FlySampler::Trilinear => "trilinear",
            FlySampler::Span3 => "span3",
            FlySampler::Span4 => "span4",
            FlySampler::Bicubic => "bicubic",
        }
    }
    /// Banks per side (0 for the per-pixel sampler).
    pub fn banks(self) -> u32 {
        match self {
            FlySampler::Trilinear => 0,
            FlySampler::Span3 => 3,
            FlySampler::Span4 | FlySampler::Bicubic => 4,
        }
    }
    /// The shader's code.
    pub fn code(self) -> u32 {
        self as u32
    }
}

/// A vertex of a flight mesh: position in finest-level texels (x east,
/// y south, z up) and the fragment program's inputs.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FlyVertex {
    /// Position.
    pub pos: [f32; 3],
    /// Texture position: finest-level map texels on the ground
    /// (`kind` 0), level-0 texels of the generic texture (`kind` 1).
    pub tex: [f32; 2],
    /// 0: geospecific (the page table); 1: the generic texture.
    pub kind: f32,
    /// Light factor the texture colour is multiplied by.
    pub shade: f32,
}

/// Triangles drawn instead of flat ground: the DEM mesh and other objects.
#[derive(Debug, Clone, Default)]
pub struct FlyMesh {
    /// Vertices.
    pub vertices: Vec<FlyVertex>,
    /// Triangle indices.
    pub indices: Vec<u32>,
}

impl FlyMesh {
    /// Appends `other`.
    pub fn append(&mut self, other: &FlyMesh) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }
    /// Number of triangles.
    pub fn triangles(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A generic (repeating, non-geospecific) texture for objects: its MIP
/// levels, each padded into a 256×256 map so that the GPU keeps them as
/// layers beside the resident maps.
#[derive(Debug, Clone)]
pub struct GenericTexture {
    /// Side of level 0 (a power of two ≤ 256).
    pub side: u32,
    /// Per level, 256×256 RGBA8 sRGB texels (the level in the top-left corner).
    pub levels: Vec<Arc<Vec<u8>>>,
}

impl GenericTexture {
    /// The MIP levels of a square power-of-two `image` (side ≤ 256).
    pub fn new(image: Image) -> Result<Self, crate::RenderError> {
        let side = image.width();
        if side != image.height() || !side.is_power_of_two() || side > MAP {
            return Err(crate::RenderError::Invalid(format!(
                "a generic texture is square, a power of two and at most {MAP} texels"
            )));
        }
        let pyr = MipPyramid::build(image);
        let levels = (0..pyr.level_count())
            .map(|l| {
                let img = pyr.level(l);
                let (w, h) = (img.width() as usize, img.height() as usize);
                let mut t = vec![0u8; (MAP * MAP * 4) as usize];
                for y in 0..h {
                    let o = y * MAP as usize * 4;
                    t[o..o + w * 4].copy_from_slice(&img.bytes()[y * w * 4..(y + 1) * w * 4]);
                }
                Arc::new(t)
            })
            .collect();
        Ok(Self { side, levels })
    }

    /// A painted livery: white with a blue cheat line, panel lines and a red tail band.
    pub fn livery() -> Self {
        let n = 256u32;
        let data = (0..n * n)
            .map(|i| {
                let (x, y) = (i % n, i / n);
                let mut c = [236u8, 238, 240, 255];
                if (100..124).contains(&y) {
                    c = [30, 60, 150, 255];
                }
                if (124..130).contains(&y) {
                    c = [200, 40, 40, 255];
                }
                if x % 32 == 0 || y % 64 == 0 {
                    c = [c[0] / 2 + 40, c[1] / 2 + 40, c[2] / 2 + 40, 255];
                }
                if (4..28).contains(&(x % 32)) && (60..76).contains(&y) {
                    c = [40, 50, 70, 255]; // windows
                }
                c
            })
            .collect();
        match Image::new(n, n, ColorSpace::Srgb, data)
            .map_err(|e| crate::RenderError::Invalid(e.to_string()))
            .and_then(Self::new)
        {
            Ok(t) => t,
            // 256×256 sRGB is always a valid generic texture
            Err(_) => Self { side: 1, levels: vec![Arc::new(vec![255; (MAP * MAP * 4) as usize])] },
        }
    }
}

/// Per-frame uniforms of `terrain.wgsl` (std140-compatible).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FlyUniform {
    /// World (finest texels) to clip space, for meshes (column-major).
    pub view_proj: [[f32; 4]; 4],
    /// Eye (finest texels); w = tan of half the horizontal field of view.
    pub eye: [f32; 4],
    /// View direction.
    pub fwd: [f32; 4],
    /// Right vector.
    pub right: [f32; 4],
    /// Up vector.
    pub up: [f32; 4],
    /// Width, height, levels, maps per window side.
    pub sizes: [u32; 4],
    /// Sampler code ([`FlySampler::code`]), first layer of the generic
    /// texture (set by the GPU backend), its levels, its level-0 side.
    pub params: [u32; 4],
}

impl FlyUniform {
    /// The uniforms of `cam` at `width`×`height` over `levels` levels.
    pub fn new(cam: &FlyCamera, width: u32, height: u32, levels: u32, per_side: u32) -> Self {
        let v = |a: [f64; 3], w: f64| [a[0] as f32, a[1] as f32, a[2] as f32, w as f32];
        Self {
            view_proj: cam.view_proj(width, height).to_cols_array_2d(),
            eye: v(cam.eye, cam.tan_h),
            fwd: v(cam.fwd, 0.0),
            right: v(cam.right, 0.0),
            up: v(cam.up, 0.0),
            sizes: [width, height, levels, per_side],
            params: [0; 4],
        }
    }

    /// The same frame filtered by `sampler`.
    pub fn with_sampler(mut self, sampler: FlySampler) -> Self {
        self.params[0] = sampler.code();
        self
    }

    /// The same frame with objects textured by `generic`.
    pub fn with_generic(mut self, generic: &GenericTexture) -> Self {
        self.params[2] = generic.levels.len() as u32;
        self.params[3] = generic.side;
        self
    }

    /// The sampler the frame uses.
    pub fn sampler(&self) -> FlySampler {
        match self.params[0] {
            1 => FlySampler::Span3,
            2 => FlySampler::Span4,
            3 => FlySampler::Bicubic,
            _ => FlySampler::Trilinear,
        }
    }
}

impl FlyCamera {
    /// World (finest texels) to clip space: the same rays as the flat
    /// ground's per-pixel solve (x right = `right`, y up = `up`, depth 0..1).
    pub fn view_proj(&self, width: u32, height: u32) -> Mat4 {
        let f = |a: [f64; 3]| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32);
        let (eye, fwd, right, up) = (f(self.eye), f(self.fwd), f(self.right), f(self.up));
        let view = Mat4::from_cols(
            Vec4::new(right.x, up.x, -fwd.x, 0.0),
            Vec4::new(right.y, up.y, -fwd.y, 0.0),
            Vec4::new(right.z, up.z, -fwd.z, 0.0),
            Vec4::new(-right.dot(eye), -up.dot(eye), fwd.dot(eye), 1.0),
        );
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        let tan_v = self.tan_h as f32 / aspect;
        // near and far from the altitude: the DEM lies within a few altitudes
        let alt = (self.eye[2] as f32).abs().max(1.0);
        let (near, far) = (alt * 0.02, alt * 400.0);
        let r = far / (near - far);
        let proj = Mat4::from_cols(
            Vec4::new(1.0 / self.tan_h as f32, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 1.0 / tan_v, 0.0, 0.0),
            Vec4::new(0.0, 0.0, r, -1.0),
            Vec4::new(0.0, 0.0, r * near, 0.0),
        );
        proj * view
    }
}

/// Colour of the sky above the horizon, linear RGB.
pub fn sky(py: f32, height: f32) -> [f32; 3] {
    let s = 1.0 - py / height;
    [0.55 + 0.2 * s, 0.68 + 0.15 * s, 0.86]
}

/// Linear colour of ground where no map holds data.
pub const GROUND: [f32; 3] = [0.05, 0.06, 0.05];

/// What a flight frame draws under the sky.
#[derive(Debug, Clone, Copy, Default)]
pub enum FlyGround<'a> {
    /// Flat ground at z = 0, solved per pixel (eq. (1)).
    #[default]
    Flat,
    /// Triangles: the DEM mesh and objects with the generic texture.
    Mesh {
        /// The triangles.
        mesh: &'a FlyMesh,
        /// The texture of `kind` 1 vertices.
        generic: &'a GenericTexture,
    },
}

impl FlyMesh {
    /// The DEM mesh of `lod` (geospecific: kind 0, unlit imagery).
    pub fn from_lod(lod: &hitex_core::terrain::LodMesh) -> Self {
        let vertices = lod
            .positions
            .iter()
            .zip(&lod.tex)
            .map(|(p, t)| FlyVertex { pos: *p, tex: *t, kind: 0.0, shade: 1.0 })
            .collect();
        Self { vertices, indices: lod.indices.clone() }
    }

    /// A small airliner `length` finest texels long, its centre at `pos`,
    /// flying towards `heading` degrees (clockwise from north), lit by `sun`
    /// (unit vector towards the sun); textured with the generic texture.
    pub fn aircraft(pos: [f64; 3], heading: f64, length: f64, sun: [f32; 3]) -> Self {
        let l = length as f32;
        let hd = heading.to_radians() as f32;
        let (fwd, right, up) = (Vec3::new(hd.sin(), -hd.cos(), 0.0), Vec3::new(hd.cos(), hd.sin(), 0.0), Vec3::Z);
        let c = Vec3::new(pos[0] as f32, pos[1] as f32, pos[2] as f32);
        let world = |p: Vec3| c + fwd * p.x * l + right * p.y * l + up * p.z * l;
        let sun = Vec3::from_array(sun).normalize_or_zero();
        let mut m = FlyMesh::default();
        // one flat-shaded quad (two triangles), texture in generic texels
        let mut quad = |p: [Vec3; 4], t: [[f32; 2]; 4]| {
            let w = p.map(world);
            let n = (w[1] - w[0]).cross(w[3] - w[0]).normalize_or_zero();
            let shade = 0.4 + 0.6 * n.dot(sun).abs();
            let base = m.vertices.len() as u32;
            for k in 0..4 {
                m.vertices.push(FlyVertex { pos: w[k].to_array(), tex: t[k], kind: 1.0, shade });
            }
            m.indices.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
        };
        // fuselage: an 8-sided tube over rings (x, radius), the texture's
        // v running from the crown (0) down each side to the keel (256)
        let rings = [(-0.5f32, 0.02f32), (-0.42, 0.05), (0.34, 0.055), (0.44, 0.04), (0.5, 0.006)];
        let sides = 8;
        let ring = |x: f32, r: f32, k: usize| {
            let a = k as f32 / sides as f32 * std::f32::consts::TAU;
            Vec3::new(x, r * a.sin(), r * a.cos())
        };
        let v_of = |k: usize| {
            let f = k as f32 / sides as f32;
            256.0 * if f <= 0.5 { 2.0 * f } else { 2.0 - 2.0 * f }
        };
        for w in rings.windows(2) {
            let ((x0, r0), (x1, r1)) = (w[0], w[1]);
            for k in 0..sides {
                let (u0, u1) = ((x0 + 0.5) * 512.0, (x1 + 0.5) * 512.0);
                quad(
                    [ring(x0, r0, k), ring(x1, r1, k), ring(x1, r1, k + 1), ring(x0, r0, k + 1)],
                    [[u0, v_of(k)], [u1, v_of(k)], [u1, v_of(k + 1)], [u0, v_of(k + 1)]],
                );
            }
        }
        // wings, tailplane (swept, thin boxes reduced to two faces) and fin
        let white = |x: f32, y: f32| [x * 256.0 + 8.0, 20.0 + y * 40.0];
        for (root, tip, span, chord, tchord, z) in
            [(0.02f32, -0.14f32, 0.5f32, 0.2f32, 0.07f32, -0.02f32), (-0.38, -0.46, 0.17, 0.09, 0.04, 0.01)]
        {
            for side in [-1.0f32, 1.0] {
                let p = [
                    Vec3::new(root, 0.0, z),
                    Vec3::new(root - chord, 0.0, z),
                    Vec3::new(tip - tchord, side * span, z + 0.02),
                    Vec3::new(tip, side * span, z + 0.02),
                ];
                quad(p, [white(0.0, 0.0), white(0.3, 0.0), white(0.3, 1.0), white(0.0, 1.0)]);
            }
        }
        let fin = [
            Vec3::new(-0.36, 0.0, 0.04),
            Vec3::new(-0.5, 0.0, 0.04),
            Vec3::new(-0.52, 0.0, 0.2),
            Vec3::new(-0.44, 0.0, 0.2),
        ];
        // the fin carries the tail band (the texture's red rows)
        quad(fin, [[0.0, 124.0], [40.0, 124.0], [40.0, 130.0], [0.0, 130.0]]);
        m
    }
}
