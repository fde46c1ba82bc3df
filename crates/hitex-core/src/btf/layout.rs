//! The codebook layouts of the paper's Fig. 4 and the filtered reads that
//! replace the interpolation along their contiguous dimensions.
//!
//! The codebook has six axes: sample texel u, v; view θc, φc; light θl, φl.
//! A layout stores it as one texture of *tiles*: two axes run across a tile
//! (x, y), an optional third runs across the layers of a 3-D texture, and the
//! remaining axes enumerate the tiles. A GPU's bilinear/trilinear filter then
//! interpolates along the angular axes that are contiguous, so fewer reads
//! are needed per pixel (u and v never are: they come from the index map).
//!
//! | layout | tile (x, y) | layers | tiles ordered by (slow → fast) | reads |
//! |---|---|---|---|---|
//! | (a)  | u, v   | —  | θc φc θl φl | 64 |
//! | (b)  | u, v   | θl | θc φc φl    | 32 |
//! | (c)  | φc, φl | —  | θc θl v u   | 16 |
//! | (c′) | φc, φl | —  | v u θc θl   | 16 |
//! | (d)  | φc, φl | θc | θl v u      | 8  |
//! | (e)  | θc, θl | —  | φc φl v u   | 16 |
//! | (e′) | θc, θl | —  | v u φc φl   | 16 |
//! | (f)  | θc, θl | φc | φl v u      | 8  |
//!
//! Reads are per index-map corner × 4 corners (plus the 4 index reads). The
//! primed variants keep the tile contents and change the tile order: (c), (e)
//! place tiles of neighbouring sample texels side by side, (c′), (e′) tiles of
//! neighbouring angles — the figure's re-arrangement whose effect on the
//! texture cache the paper measures.
//!
//! Padding: a φ axis inside a tile holds one extra sample (φ = 0 again) so
//! that the filter can interpolate across 360°; φ along the layers of (f)
//! wraps with the sampler's repeat mode instead. θ clamps: its coordinate is
//! clamped to the first and last ring, never needing padding. Tile sides are
//! rounded up to multiples of 4 so that no BC1 block straddles two tiles (the
//! paper's condition for tiling without compression artefacts at the seams).

use super::dataset::Btf;
use super::grid::{AngularGrid, AxisLerp};
use crate::CoreError;
use crate::texture::ColorSpace;
use crate::texture::image::decode_table;
use crate::texture::sampler::floor;
use glam::{Vec3, Vec4};
use rayon::prelude::*;

/// One of the six axes of a BTF codebook.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// Sample column.
    U = 0,
    /// Sample row.
    V = 1,
    /// View polar angle.
    ThetaC = 2,
    /// View azimuth.
    PhiC = 3,
    /// Light polar angle.
    ThetaL = 4,
    /// Light azimuth.
    PhiL = 5,
}

impl Axis {
    /// An azimuth axis (wraps around the circle).
    pub fn is_phi(self) -> bool {
        matches!(self, Axis::PhiC | Axis::PhiL)
    }
    /// An angular axis (not a sample texel axis).
    pub fn is_angle(self) -> bool {
        !matches!(self, Axis::U | Axis::V)
    }
}

/// A codebook layout of Fig. 4.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Layout {
    /// (a) 2-D tiles of (u, v) images: 64 reads.
    A,
    /// (b) (u, v) tiles, θl across layers: 32 reads.
    B,
    /// (c) 2-D tiles of (φc, φl), sample texels adjacent: 16 reads.
    C,
    /// (c′) as (c), angles adjacent: 16 reads.
    C2,
    /// (d) (φc, φl) tiles, θc across layers: 8 reads.
    D,
    /// (e) 2-D tiles of (θc, θl), sample texels adjacent: 16 reads.
    E,
    /// (e′) as (e), angles adjacent: 16 reads.
    E2,
    /// (f) (θc, θl) tiles, φc across layers: 8 reads.
    F,
}

/// Where each axis goes in a layout.
#[derive(Debug, Clone, Copy)]
pub struct LayoutSpec {
    /// Axis across a tile.
    pub tile_x: Axis,
    /// Axis down a tile.
    pub tile_y: Axis,
    /// Axis across the layers of a 3-D texture.
    pub depth: Option<Axis>,
    /// Axes enumerating the tiles, slowest first.
    pub tiles: &'static [Axis],
}

use Axis::*;

impl Layout {
    /// Every layout, in the paper's order.
    pub const ALL: [Layout; 8] =
        [Layout::A, Layout::B, Layout::C, Layout::C2, Layout::D, Layout::E, Layout::E2, Layout::F];

    /// Every layout with its short name and the paper's label, the one
    /// table [`Layout::name`], [`Layout::label`] and [`Layout::parse`] read.
    const NAMES: [(Layout, &'static str, &'static str); 8] = [
        (Layout::A, "a", "(a)"),
        (Layout::B, "b", "(b)"),
        (Layout::C, "c", "(c)"),
        (Layout::C2, "c2", "(c′)"),
        (Layout::D, "d", "(d)"),
        (Layout::E, "e", "(e)"),
        (Layout::E2, "e2", "(e′)"),
        (Layout::F, "f", "(f)"),
    ];

    /// Short name: "a", "b", "c", "c2", "d", "e", "e2", "f".
    pub fn name(self) -> &'static str {
        Self::NAMES.iter().find(|n| n.0 == self).map_or("a", |n| n.1)
    }

    /// The paper's label: "(a)" … "(c′)" … "(f)".
    pub fn label(self) -> &'static str {
        Self::NAMES.iter().find(|n| n.0 == self).map_or("(a)", |n| n.2)
    }

    /// Parses a short name, or the label with or without its parentheses
    /// ("c′", also typed "c'").
    pub fn parse(s: &str) -> Option<Layout> {
        let s = s.trim().to_ascii_lowercase().replace('\'', "′");
        Self::NAMES
            .iter()
            .find(|(_, name, label)| s == *name || s == *label || s == label[1..label.len() - 1])
            .map(|n| n.0)
    }

    /// Where each axis goes.
    pub fn spec(self) -> LayoutSpec {
        let s = |tile_x, tile_y, depth, tiles| LayoutSpec { tile_x, tile_y, depth, tiles };
        match self {
            Layout::A => s(U, V, None, &[ThetaC, PhiC, ThetaL, PhiL]),
            Layout::B => s(U, V, Some(ThetaL), &[ThetaC, PhiC, PhiL]),
            Layout::C => s(PhiC, PhiL, None, &[ThetaC, ThetaL, V, U]),
            Layout::C2 => s(PhiC, PhiL, None, &[V, U, ThetaC, ThetaL]),
            Layout::D => s(PhiC, PhiL, Some(ThetaC), &[ThetaL, V, U]),
            Layout::E => s(ThetaC, ThetaL, None, &[PhiC, PhiL, V, U]),
            Layout::E2 => s(ThetaC, ThetaL, None, &[V, U, PhiC, PhiL]),
            Layout::F => s(ThetaC, ThetaL, Some(PhiC), &[PhiL, V, U]),
        }
    }

    /// True for the 3-D texture layouts (b), (d), (f).
    pub fn is_3d(self) -> bool {
        self.spec().depth.is_some()
    }

    /// Bit `a` set when angular axis `a` is interpolated by the texture filter.
    pub fn filtered_mask(self) -> u32 {
        let s = self.spec();
        let mut m = 0;
        for a in [Some(s.tile_x), Some(s.tile_y), s.depth].into_iter().flatten() {
            if a.is_angle() {
                m |= 1 << a as u32;
            }
        }
        m
    }

    /// The angular axes the filter does not interpolate (walked by the
    /// shader with two neighbours each), and how many there are.
    pub fn walked_axes(self) -> ([usize; 4], usize) {
        let filtered = self.filtered_mask();
        let mut walk = [0usize; 4];
        let mut n = 0;
        for a in 2..6 {
            if filtered & (1 << a) == 0 {
                walk[n] = a;
                n += 1;
            }
        }
        (walk, n)
    }

    /// Codebook reads per pixel: 4 index corners × 2^(angular axes not filtered).
    pub fn codebook_reads(self) -> u32 {
        4 * (1 << (4 - self.filtered_mask().count_ones()))
    }

    /// Texels one read touches: 1 (texel load), 4 (bilinear), 8 (trilinear).
    pub fn texels_per_read(self) -> u32 {
        match (self.filtered_mask() != 0, self.is_3d()) {
            (false, _) => 1,
            (true, false) => 4,
            (true, true) => 8,
        }
    }
}

fn round4(n: u32) -> u32 {
    n.div_ceil(4) * 4
}

/// A codebook laid out as one RGBA8 (sRGB) texture, as the GPU receives it.
#[derive(Debug, Clone)]
pub struct Codebook {
    /// The layout.
    pub layout: Layout,
    /// Texture width in texels.
    pub width: u32,
    /// Texture height in texels.
    pub height: u32,
    /// Layers (1 for the 2-D layouts).
    pub depth: u32,
    /// Tile width in texels (padded).
    pub tile_w: u32,
    /// Tile height in texels (padded).
    pub tile_h: u32,
    /// Tiles per texture row.
    pub tile_cols: u32,
    /// Number of tiles.
    pub tile_count: u32,
    /// Tile-index stride of each axis (0 for axes not enumerating tiles).
    pub strides: [u32; 6],
    /// Logical length of each axis: sample width, height, θ, φ, θ, φ counts.
    pub lens: [u32; 6],
    /// RGBA8 texels, sRGB-encoded, layer by layer, rows top to bottom.
    pub texels: Vec<u8>,
    /// For an HDR BTF, the same texels as linear RGBA half floats, one
    /// 64-bit word each: R | G << 16 | B << 32 | A << 48 (A = 1.0), which
    /// is the byte order of an `Rgba16Float` texture; empty otherwise.
    pub half: Vec<u64>,
}

/// Half-float 1.0.
const HALF_ONE: u64 = 0x3c00;

/// Hexa-linear weights and neighbours of one pixel's four angles.
#[derive(Debug, Clone, Copy)]
pub struct AngleLerps {
    /// View polar angle.
    pub tc: AxisLerp,
    /// View azimuth.
    pub pc: AxisLerp,
    /// Light polar angle.
    pub tl: AxisLerp,
    /// Light azimuth.
    pub pl: AxisLerp,
}

impl AngleLerps {
    fn axis(&self, a: usize) -> &AxisLerp {
        match a {
            2 => &self.tc,
            3 => &self.pc,
            4 => &self.tl,
            _ => &self.pl,
        }
    }
}

/// Per-pixel invariants of the reads (see [`Codebook::plan`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct PixelPlan {
    /// (angular tile-index share, weight) per walked combination.
    pub combos: [(u32, f32); 16],
    /// Number of combinations.
    pub n_combos: usize,
    /// (texel offset from the read's base, weight) of the filter's non-zero taps.
    pub taps: [(usize, f32); 8],
    /// Number of taps.
    pub n_taps: usize,
    /// The tile's x axis is the sample column.
    pub u_on_x: bool,
    /// The tile's y axis is the sample row.
    pub v_on_y: bool,
}

/// Receives the reads of the CPU twin: one call per texture instruction and
/// one per texel the hardware filter touches (for read counts and the
/// texture-cache model). The no-op `()` compiles away.
pub trait FetchSink {
    /// False for sinks that ignore every call: the twin may then skip the
    /// bookkeeping (and zero-weight texels) that only counting needs.
    const COUNTS: bool = true;
    /// One texture instruction (load or filtered sample).
    fn read(&mut self) {}
    /// One texel of a read's footprint, (x, y, layer).
    fn texel(&mut self, _x: u32, _y: u32, _z: u32) {}
}

impl FetchSink for () {
    const COUNTS: bool = false;
}

/// Counts texture instructions and texels.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct ReadCounter {
    /// Texture instructions.
    pub reads: u64,
    /// Texels touched.
    pub texels: u64,
}

impl FetchSink for ReadCounter {
    fn read(&mut self) {
        self.reads += 1;
    }
    fn texel(&mut self, _x: u32, _y: u32, _z: u32) {
        self.texels += 1;
    }
}

/// A decoded codebook texel: linear RGBA in units of [`LinearTexel::UNIT`].
pub trait LinearTexel: Copy {
    /// Linear value of one unit.
    const UNIT: f32;
    /// The texel in units.
    fn value(self) -> Vec4;
}

impl LinearTexel for Vec4 {
    const UNIT: f32 = 1.0;
    #[inline(always)]
    fn value(self) -> Vec4 {
        self
    }
}

/// A texel of [`Codebook::linear_texels16`].
impl LinearTexel for u64 {
    const UNIT: f32 = 1.0 / 65535.0;
    #[inline(always)]
    fn value(self) -> Vec4 {
        let c = |s: u32| ((self >> s) & 0xffff) as i32 as f32;
        Vec4::new(c(0), c(16), c(32), c(48))
    }
}

/// A texel of [`Codebook::half`]: four linear half floats. A finite half's
/// magnitude bits moved up by 13 are an f32 of its magnitude × 2⁻¹¹²
/// (subnormal halves included) and its sign bit moved up by 16 is the f32's,
/// so decoding is two shifts, and the unit is 2¹¹².
#[repr(transparent)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Half4(pub u64);

/// The bits of the f32 of a finite half's value × 2⁻¹¹² (see [`Half4`]).
#[inline(always)]
pub fn half_to_scaled_f32_bits(h: u16) -> u32 {
    let h = h as u32;
    (h & 0x8000) << 16 | (h & 0x7fff) << 13
}

/// 2¹¹², the unit of [`Half4`] values.
pub const HALF_UNIT: f32 = f32::from_bits((127 + 112) << 23);

impl LinearTexel for Half4 {
    const UNIT: f32 = HALF_UNIT;
    #[inline(always)]
    fn value(self) -> Vec4 {
        let c = |s: u32| f32::from_bits(half_to_scaled_f32_bits((self.0 >> s) as u16));
        Vec4::new(c(0), c(16), c(32), c(48))
    }
}

/// Largest texture side used when arranging tiles (the 3-D limit of wgpu's
/// defaults and of Mesa's GL; 2-D layouts use up to 16384).
pub const MAX_SIDE_3D: u32 = 2048;

/// Largest 2-D texture side used when arranging tiles.
pub const MAX_SIDE_2D: u32 = 16384;

impl Codebook {
    /// Lays `btf` out as `layout`. Fails when the texture would exceed the
    /// side limits (a grid or sample too large for one texture).
    pub fn build(btf: &Btf, layout: Layout) -> Result<Self, CoreError> {
        let hdr = btf.is_hdr();
        Self::build_from(btf.grid(), btf.width(), btf.height(), layout, hdr, &|view, light, x, y| {
            (btf.texel(view, light, x, y), btf.texel_half(view, light, x, y).unwrap_or([0; 3]))
        })
    }

    /// Lays out a signed half-float BTF (a local-PCA basis,
    /// [`super::pca::LocalPca::basis_halves`]: three halves per texel,
    /// image-major, `width`×`height` texels per image) as `layout`, as
    /// [`Codebook::build`] lays out an HDR BTF. The 8-bit texels hold the
    /// values clamped to [0, 1], sRGB-encoded (a display copy).
    pub fn build_signed(
        grid: &AngularGrid,
        width: u32,
        height: u32,
        halves: &[u16],
        layout: Layout,
    ) -> Result<Self, CoreError> {
        let d = grid.directions();
        let per = width as usize * height as usize * 3;
        if halves.len() != d * d * per {
            return Err(CoreError::InvalidImage(format!(
                "signed BTF of {} halves; {width}x{height} texels × {d}² directions need {}",
                halves.len(),
                d * d * per
            )));
        }
        Self::build_from(grid, width, height, layout, true, &|view, light, x, y| {
            let o = (view * d + light) * per + (y * width + x) as usize * 3;
            let h = [halves[o], halves[o + 1], halves[o + 2]];
            let e = |h: u16| crate::texture::linear_to_srgb_u8(super::dataset::half_value(h).clamp(0.0, 1.0));
            ([e(h[0]), e(h[1]), e(h[2])], h)
        })
    }

    /// The layout walk of [`Codebook::build`] over a texel source: per
    /// (view, light, x, y) its 8-bit sRGB texel and, when `hdr`, its halves.
    #[allow(clippy::type_complexity)]
    fn build_from(
        g: &AngularGrid,
        sample_w: u32,
        sample_h: u32,
        layout: Layout,
        hdr: bool,
        source: &(dyn Fn(usize, usize, u32, u32) -> ([u8; 3], [u16; 3]) + Sync),
    ) -> Result<Self, CoreError> {
        let spec = layout.spec();
        let lens = [
            sample_w,
            sample_h,
            g.theta_count() as u32,
            g.phi_count() as u32,
            g.theta_count() as u32,
            g.phi_count() as u32,
        ];
        let padded = |a: Axis| {
            let n = lens[a as usize];
            if a.is_phi() { round4(n + 1) } else { round4(n) }
        };
        let (tile_w, tile_h) = (padded(spec.tile_x), padded(spec.tile_y));
        let depth = spec.depth.map_or(1, |a| lens[a as usize]);
        let mut strides = [0u32; 6];
        let mut count: u64 = 1;
        for &a in spec.tiles.iter().rev() {
            strides[a as usize] = count as u32;
            count *= lens[a as usize] as u64;
        }
        let max_side = if spec.depth.is_some() { MAX_SIDE_3D } else { MAX_SIDE_2D };
        // near-square arrangement of the tiles
        let cols = ((count as f64 * tile_h as f64 / tile_w as f64).sqrt().ceil() as u64).clamp(1, count.max(1));
        let rows = count.div_ceil(cols);
        let (width, height) = (cols * tile_w as u64, rows * tile_h as u64);
        if width > max_side as u64 || height > max_side as u64 {
            return Err(CoreError::InvalidImage(format!(
                "layout {} needs a {width}x{height}x{depth} texture; the limit is {max_side} per side",
                layout.label()
            )));
        }
        let (width, height) = (width as u32, height as u32);
        let mut cb = Codebook {
            layout,
            width,
            height,
            depth,
            tile_w,
            tile_h,
            tile_cols: cols as u32,
            tile_count: count as u32,
            strides,
            lens,
            texels: Vec::new(),
            half: Vec::new(),
        };
        let row_bytes = width as usize * 4;
        let mut texels = vec![0u8; row_bytes * height as usize * depth as usize];
        // an HDR BTF also gets its half floats, from the same walk: each texel names its source
        let mut half = vec![0u64; if hdr { texels.len() / 4 } else { 0 }];
        let half_rows: Vec<&mut [u64]> = if hdr { half.chunks_mut(width as usize).collect() } else { Vec::new() };
        let mut half_rows: Vec<Option<&mut [u64]>> = half_rows.into_iter().map(Some).collect();
        half_rows.resize_with(texels.len() / row_bytes.max(1), || None);
        texels.par_chunks_mut(row_bytes).zip(half_rows.into_par_iter()).enumerate().for_each(|(r, (row, mut hrow))| {
            let (z, y) = (r as u32 / height, r as u32 % height);
            let (trow, iy) = (y / tile_h, y % tile_h);
            for x in 0..width {
                let k = trow * cb.tile_cols + x / tile_w;
                if k >= cb.tile_count {
                    continue;
                }
                let idx = cb.source_of(&spec, k, x % tile_w, iy, z);
                let view = g.direction(idx[2] as usize, idx[3] as usize);
                let light = g.direction(idx[4] as usize, idx[5] as usize);
                let (t, th) = source(view, light, idx[0], idx[1]);
                row[x as usize * 4..x as usize * 4 + 4].copy_from_slice(&[t[0], t[1], t[2], 255]);
                if let Some(h) = hrow.as_deref_mut() {
                    h[x as usize] = th[0] as u64 | (th[1] as u64) << 16 | (th[2] as u64) << 32 | HALF_ONE << 48;
                }
            }
        });
        cb.half = half;
        cb.texels = texels;
        Ok(cb)
    }

    /// The six sample indices of tile `k`'s texel (`ix`, `iy`) in layer `z`.
    fn source_of(&self, spec: &LayoutSpec, k: u32, ix: u32, iy: u32, z: u32) -> [u32; 6] {
        let lens = self.lens;
        let mut idx = [0u32; 6];
        let mut rest = k;
        for &a in spec.tiles.iter().rev() {
            idx[a as usize] = rest % lens[a as usize];
            rest /= lens[a as usize];
        }
        idx[spec.tile_x as usize] = self.logical(spec.tile_x, ix);
        idx[spec.tile_y as usize] = self.logical(spec.tile_y, iy);
        if let Some(a) = spec.depth {
            idx[a as usize] = z;
        }
        idx
    }

    /// Whether the codebook holds linear half floats (an HDR BTF).
    pub fn is_hdr(&self) -> bool {
        !self.half.is_empty()
    }

    /// Logical sample of a padded in-tile position: φ wraps, others clamp.
    fn logical(&self, a: Axis, i: u32) -> u32 {
        let n = self.lens[a as usize];
        if a.is_phi() { i % n } else { i.min(n - 1) }
    }

    /// Bytes of the RGBA8 texture.
    pub fn bytes(&self) -> u64 {
        self.texels.len() as u64
    }

    /// One RGBA8 texel.
    #[inline]
    pub fn texel(&self, x: u32, y: u32, z: u32) -> [u8; 4] {
        let i = ((z as usize * self.height as usize + y as usize) * self.width as usize + x as usize) * 4;
        [self.texels[i], self.texels[i + 1], self.texels[i + 2], self.texels[i + 3]]
    }

    #[inline]
    fn linear(&self, x: u32, y: u32, z: u32) -> Vec3 {
        if self.is_hdr() {
            let i = (z as usize * self.height as usize + y as usize) * self.width as usize + x as usize;
            let h = self.half[i];
            let f = |s: u32| super::dataset::half_value((h >> s) as u16);
            return Vec3::new(f(0), f(16), f(32));
        }
        let t = self.texel(x, y, z);
        srgb3([t[0], t[1], t[2]])
    }

    /// The hexa-linear interpolation of sample texel (`su`, `sv`) at the
    /// pixel's angles, in linear RGB, read through this layout with the
    /// texture filter emulated as the GPU applies it (CPU twin of
    /// `fetch_corner` in `btf.wgsl`).
    pub fn corner<S: FetchSink>(&self, su: u32, sv: u32, l: &AngleLerps, sink: &mut S) -> Vec3 {
        let spec = self.layout.spec();
        let filtered = self.layout.filtered_mask();
        // the angular axes the shader walks, each with two neighbours
        let (walk, nwalk) = self.layout.walked_axes();
        let mut acc = Vec3::ZERO;
        for combo in 0..(1u32 << nwalk) {
            // discrete index per axis and the combination's weight
            let mut idx = [su, sv, 0, 0, 0, 0];
            let mut w = 1.0f32;
            for (bit, &a) in walk[..nwalk].iter().enumerate() {
                let ax = l.axis(a);
                if combo & (1 << bit) != 0 {
                    idx[a] = ax.i1 as u32;
                    w *= ax.t;
                } else {
                    idx[a] = ax.i0 as u32;
                    w *= 1.0 - ax.t;
                }
            }
            // tile origin
            let mut k = 0;
            for &a in spec.tiles {
                k += idx[a as usize] * self.strides[a as usize];
            }
            let ox = (k % self.tile_cols) * self.tile_w;
            let oy = (k / self.tile_cols) * self.tile_h;
            let coord =
                |a: Axis| -> f32 { if a.is_angle() { l.axis(a as usize).coord } else { idx[a as usize] as f32 } };
            let x = ox as f32 + coord(spec.tile_x) + 0.5;
            let y = oy as f32 + coord(spec.tile_y) + 0.5;
            let value = match (filtered, spec.depth) {
                (0, _) => {
                    sink.read();
                    let (tx, ty) = (x as u32, y as u32);
                    sink.texel(tx, ty, 0);
                    self.linear(tx, ty, 0)
                }
                (_, None) => self.bilinear(x, y, 0, sink),
                (_, Some(a)) => self.trilinear(x, y, coord(a) + 0.5, a.is_phi(), sink),
            };
            acc += value * w;
        }
        acc
    }

    /// What is common to every read of one pixel — the angular part of each
    /// walked combination (tile-index share and weight) and the filter's
    /// texel offsets and weights inside a tile, which depend only on the
    /// angles — computed once per pixel instead of once per read.
    pub fn plan(&self, l: &AngleLerps) -> PixelPlan {
        let spec = self.layout.spec();
        let mut plan = PixelPlan::default();
        // walked combinations
        let (walk, nwalk) = self.layout.walked_axes();
        for combo in 0..(1u32 << nwalk) {
            let (mut k, mut w) = (0u32, 1.0f32);
            for (bit, &a) in walk[..nwalk].iter().enumerate() {
                let ax = l.axis(a);
                let (i, wi) = if combo & (1 << bit) != 0 { (ax.i1, ax.t) } else { (ax.i0, 1.0 - ax.t) };
                k += i as u32 * self.strides[a];
                w *= wi;
            }
            plan.combos[plan.n_combos] = (k, w);
            plan.n_combos += 1;
        }
        // the filter's taps along each in-tile axis and the layers
        let taps = |a: Axis, extent: u32| -> [(u32, f32); 2] {
            if !a.is_angle() {
                return [(0, 1.0), (0, 0.0)];
            }
            let c = l.axis(a as usize).coord;
            let i0 = floor(c);
            let f = c - i0;
            let i0 = (i0.max(0.0) as u32).min(extent - 1);
            [(i0, 1.0 - f), ((i0 + 1).min(extent - 1), f)]
        };
        let tx = taps(spec.tile_x, self.tile_w);
        let ty = taps(spec.tile_y, self.tile_h);
        let layer = self.width as usize * self.height as usize;
        let tz: [(usize, f32); 2] = match spec.depth {
            None => [(0, 1.0), (0, 0.0)],
            Some(a) => {
                let c = l.axis(a as usize).coord;
                let i0 = floor(c);
                let f = c - i0;
                let d = self.depth;
                let z0 = (i0.max(0.0) as u32).min(d - 1);
                let z1 = if a.is_phi() { (z0 + 1) % d } else { (z0 + 1).min(d - 1) };
                [(z0 as usize * layer, 1.0 - f), (z1 as usize * layer, f)]
            }
        };
        for &(z, wz) in &tz {
            for &(y, wy) in &ty {
                for &(x, wx) in &tx {
                    let w = wx * wy * wz;
                    if w != 0.0 {
                        plan.taps[plan.n_taps] = (z + y as usize * self.width as usize + x as usize, w);
                        plan.n_taps += 1;
                    }
                }
            }
        }
        plan.u_on_x = spec.tile_x == Axis::U;
        plan.v_on_y = spec.tile_y == Axis::V;
        plan
    }

    /// The texels decoded to linear RGB (alpha 1), one SIMD vector each:
    /// what the GPU's sRGB decoder hands its filter, cached for the CPU twin.
    pub fn linear_texels(&self) -> Vec<Vec4> {
        if self.is_hdr() {
            let f = |h: u64, s: u32| super::dataset::half_value((h >> s) as u16);
            return self.half.par_iter().map(|&h| Vec4::new(f(h, 0), f(h, 16), f(h, 32), 1.0)).collect();
        }
        let lut = decode_table(ColorSpace::Srgb);
        self.texels
            .par_chunks(4 * 4096)
            .flat_map_iter(|c| {
                c.chunks_exact(4).map(|t| Vec4::new(lut[t[0] as usize], lut[t[1] as usize], lut[t[2] as usize], 1.0))
            })
            .collect()
    }

    /// The texels decoded to linear RGB as 16-bit fixed point (1.0 =
    /// 65535), one word each: R | G << 16 | B << 32 | A << 48, alpha 1.
    /// Half the bytes of [`Codebook::linear_texels`] for an error of at
    /// most 7.7·10⁻⁶ (half a unit), far below what an 8-bit output shows;
    /// one 64-bit word a texel lets a renderer gather whole texels.
    pub fn linear_texels16(&self) -> Vec<u64> {
        let lut = decode_table(ColorSpace::Srgb);
        let q = |b: u8| (lut[b as usize].clamp(0.0, 1.0) * 65535.0 + 0.5) as u64;
        self.texels
            .par_chunks(4 * 4096)
            .flat_map_iter(|c| c.chunks_exact(4).map(|t| q(t[0]) | q(t[1]) << 16 | q(t[2]) << 32 | 0xffff << 48))
            .collect()
    }

    /// [`Codebook::corner`] with the pixel's [`PixelPlan`] over decoded
    /// texels ([`Codebook::linear_texels`] or [`Codebook::linear_texels16`]):
    /// the same reads and weights (texels of zero weight skipped), for
    /// rendering; RGB in x, y, z.
    #[inline]
    pub fn corner_planned_linear<T: LinearTexel>(&self, plan: &PixelPlan, su: u32, sv: u32, linear: &[T]) -> Vec4 {
        let (su_k, sv_k) = (su * self.strides[0], sv * self.strides[1]);
        let (dx, dy) = (if plan.u_on_x { su } else { 0 }, if plan.v_on_y { sv } else { 0 });
        let w = self.width as usize;
        let mut acc = Vec4::ZERO;
        for &(k_ang, wc) in &plan.combos[..plan.n_combos] {
            let k = k_ang + su_k + sv_k;
            let (col, row) = (k % self.tile_cols, k / self.tile_cols);
            let base = (row * self.tile_h + dy) as usize * w + (col * self.tile_w + dx) as usize;
            for &(off, wt) in &plan.taps[..plan.n_taps] {
                acc += linear[base + off].value() * (wc * wt);
            }
        }
        acc * T::UNIT
    }

    /// A bilinear read at texel-space (x, y) of layer z, clamp-to-edge.
    fn bilinear<S: FetchSink>(&self, x: f32, y: f32, z: u32, sink: &mut S) -> Vec3 {
        sink.read();
        let (x0, x1, fx) = axis_taps(x, self.width, false);
        let (y0, y1, fy) = axis_taps(y, self.height, false);
        for (tx, ty) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
            sink.texel(tx, ty, z);
        }
        let top = self.linear(x0, y0, z).lerp(self.linear(x1, y0, z), fx);
        let bottom = self.linear(x0, y1, z).lerp(self.linear(x1, y1, z), fx);
        top.lerp(bottom, fy)
    }

    /// A trilinear read of the 3-D texture; layers clamp, or wrap when `repeat`.
    fn trilinear<S: FetchSink>(&self, x: f32, y: f32, z: f32, repeat: bool, sink: &mut S) -> Vec3 {
        sink.read();
        let (x0, x1, fx) = axis_taps(x, self.width, false);
        let (y0, y1, fy) = axis_taps(y, self.height, false);
        let (z0, z1, fz) = axis_taps(z, self.depth, repeat);
        let mut layer = |zz: u32| {
            for (tx, ty) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
                sink.texel(tx, ty, zz);
            }
            let top = self.linear(x0, y0, zz).lerp(self.linear(x1, y0, zz), fx);
            let bottom = self.linear(x0, y1, zz).lerp(self.linear(x1, y1, zz), fx);
            top.lerp(bottom, fy)
        };
        let a = layer(z0);
        let b = layer(z1);
        a.lerp(b, fz)
    }
}

/// The two texels a linear filter reads along one axis of `size` texels at
/// texel-space coordinate `c` (centres at i + 0.5), and the weight of the
/// second: clamp-to-edge, or repeat.
#[inline]
pub fn axis_taps(c: f32, size: u32, repeat: bool) -> (u32, u32, f32) {
    let c = c - 0.5;
    let f0 = floor(c);
    let f = c - f0;
    let i0 = f0 as i64;
    let n = size as i64;
    if repeat {
        (i0.rem_euclid(n) as u32, (i0 + 1).rem_euclid(n) as u32, f)
    } else {
        (i0.clamp(0, n - 1) as u32, (i0 + 1).clamp(0, n - 1) as u32, f)
    }
}

/// The reference: hexa-linear interpolation of sample texel (`su`, `sv`)
/// straight from the codebook, 16 angular neighbours, in linear RGB.
pub fn reference_corner(btf: &Btf, su: u32, sv: u32, l: &AngleLerps) -> Vec3 {
    let g = btf.grid();
    let mut acc = Vec3::ZERO;
    for combo in 0..16u32 {
        let pick = |bit: u32, ax: &AxisLerp| {
            if combo & (1 << bit) != 0 { (ax.i1, ax.t) } else { (ax.i0, 1.0 - ax.t) }
        };
        let (tc, w0) = pick(0, &l.tc);
        let (pc, w1) = pick(1, &l.pc);
        let (tl, w2) = pick(2, &l.tl);
        let (pl, w3) = pick(3, &l.pl);
        let t = btf.texel(g.direction(tc, pc), g.direction(tl, pl), su, sv);
        acc += srgb3(t) * (w0 * w1 * w2 * w3);
    }
    acc
}

/// Decodes an sRGB8 triple to linear RGB.
#[inline]
pub fn srgb3(t: [u8; 3]) -> Vec3 {
    let lut = decode_table(ColorSpace::Srgb);
    Vec3::new(lut[t[0] as usize], lut[t[1] as usize], lut[t[2] as usize])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::grid::AngularGrid;

    /// A BTF of pseudo-random texels on an irregular grid (3 θ, 5 φ, 6×4 texels).
    pub(crate) fn random_btf() -> Btf {
        let grid = AngularGrid::new(vec![0.0, 25.0, 65.0], 5).unwrap();
        let mut b = Btf::zeroed(grid, 6, 4).unwrap();
        let mut s: u32 = 12345;
        for t in b.texels_mut() {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            *t = (s >> 16) as u8;
        }
        b
    }

    fn lerps(g: &AngularGrid, k: u32) -> AngleLerps {
        let f = |i: u32| ((k * 7919 + i * 104_729) % 10_007) as f32 / 10_007.0;
        AngleLerps {
            tc: g.lerp_theta(f(1) * 1.4),
            pc: g.lerp_phi(f(2) * 7.0 - 0.3),
            tl: g.lerp_theta(f(3) * 1.4),
            pl: g.lerp_phi(f(4) * 7.0 - 0.3),
        }
    }

    #[test]
    fn every_layout_matches_the_reference() {
        let b = random_btf();
        for layout in Layout::ALL {
            let cb = Codebook::build(&b, layout).unwrap();
            for k in 0..400 {
                let l = lerps(b.grid(), k);
                let (su, sv) = (k % 6, (k / 6) % 4);
                let want = reference_corner(&b, su, sv, &l);
                let got = cb.corner(su, sv, &l, &mut ());
                assert!((want - got).abs().max_element() < 2e-5, "{}: {got} vs {want} at {k}", layout.label());
            }
        }
    }

    #[test]
    fn planned_reads_equal_the_generic_ones() {
        let b = random_btf();
        for layout in Layout::ALL {
            let cb = Codebook::build(&b, layout).unwrap();
            let linear = cb.linear_texels();
            let linear16 = cb.linear_texels16();
            for k in 0..300 {
                let l = lerps(b.grid(), k);
                let (su, sv) = (k % 6, (k / 6) % 4);
                let want = cb.corner(su, sv, &l, &mut ());
                let plan = cb.plan(&l);
                let lin = cb.corner_planned_linear(&plan, su, sv, &linear).truncate();
                assert!((want - lin).abs().max_element() < 1e-4, "{}: {lin} vs {want}", layout.label());
                // 16-bit texels: within half a unit per texel (weights sum to 1)
                let q = cb.corner_planned_linear(&plan, su, sv, &linear16).truncate();
                assert!((lin - q).abs().max_element() < 1e-5, "{}: {q} vs {lin}", layout.label());
            }
        }
    }

    #[test]
    fn reads_per_layout_are_the_papers() {
        let b = random_btf();
        let want = [64, 32, 16, 16, 8, 16, 16, 8];
        for (layout, w) in Layout::ALL.into_iter().zip(want) {
            assert_eq!(layout.codebook_reads(), w, "{}", layout.label());
            let cb = Codebook::build(&b, layout).unwrap();
            let mut c = ReadCounter::default();
            for corner in 0..4 {
                cb.corner(corner, 1, &lerps(b.grid(), 3), &mut c);
            }
            assert_eq!(c.reads, w as u64, "{}", layout.label());
            assert_eq!(c.texels, w as u64 * layout.texels_per_read() as u64, "{}", layout.label());
        }
    }

    #[test]
    fn paper_sized_layouts_fit_their_textures() {
        let b = Btf::zeroed(AngularGrid::paper(), 32, 32).unwrap();
        for layout in Layout::ALL {
            let cb = Codebook::build(&b, layout).unwrap();
            let limit = if layout.is_3d() { MAX_SIDE_3D } else { MAX_SIDE_2D };
            assert!(cb.width <= limit && cb.height <= limit, "{}", layout.label());
            assert_eq!(cb.tile_w % 4, 0);
            assert_eq!(cb.tile_h % 4, 0);
            // (a), (b), (e), (e′), (f) hold exactly 64 MiB; the φ tiles of (c), (d) carry padding
            let mib = cb.bytes() as f64 / (1 << 20) as f64;
            assert!((64.0..=110.0).contains(&mib), "{} {mib} MiB", layout.label());
        }
    }

    #[test]
    fn names_parse() {
        for l in Layout::ALL {
            assert_eq!(Layout::parse(l.name()), Some(l));
            assert_eq!(Layout::parse(l.label()), Some(l));
        }
        let names: Vec<&str> = Layout::ALL.iter().map(|l| l.name()).collect();
        assert_eq!(names, ["a", "b", "c", "c2", "d", "e", "e2", "f"]);
        assert_eq!((Layout::C2.label(), Layout::E2.label(), Layout::F.label()), ("(c′)", "(e′)", "(f)"));
        assert_eq!(Layout::parse("c'"), Some(Layout::C2));
        assert_eq!(Layout::parse(" E′ "), Some(Layout::E2));
        assert_eq!(Layout::parse("g"), None);
        assert_eq!(Layout::parse("()"), None);
    }
}
