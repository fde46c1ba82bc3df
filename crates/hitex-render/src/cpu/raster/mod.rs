//! The tiled triangle rasterizer of the CPU backend.
//!
//! * vertex stage: world → clip with the frame's matrix;
//! * clipping: near and far planes plus a guard band of ±[`GUARD`]× the
//!   viewport in x and y (Sutherland–Hodgman in homogeneous space), so that
//!   fixed-point edge functions never overflow;
//! * setup: vertices snapped to 1/256 pixel ([`SUBPIXEL_BITS`] = 8, as Vulkan
//!   implementations commonly use), integer edge functions, top-left fill rule,
//!   both windings drawn;
//! * setup runs in parallel chunks of triangles (kept in submission order);
//!   triangles wholly inside the clip volume skip the clipper; each chunk
//!   bins its triangles into bands (a counting sort), which the band tasks
//!   join in chunk order;
//! * a [`Target::deferred`] clear is made by each band's task, on its rows;
//! * traversal: the screen is cut into horizontal bands of [`BAND`] rows that
//!   rayon renders in parallel; each band walks its triangles in submission
//!   order over 8×2 blocks of 2×2 quads aligned to even pixel coordinates;
//! * per block: coverage (trivial accept and reject at the corners), early
//!   depth test (less, depth cleared to 1; conservative for programs that
//!   write depth), screen-linear barycentrics, `1/w`, depth and
//!   perspective-correct varyings for all lanes (uncovered lanes are helpers,
//!   as on a GPU);
//! * batching: covered quads of consecutive triangles with the same material
//!   and program key are packed four to a [`Block`], one call of the fragment
//!   program, so that small triangles (a tessellated NURBS patch) still fill
//!   16 lanes; a program that needs no more of a quad than the screen
//!   derivatives of two varyings ([`BlockShader::LANE_GRADS`]) gets its
//!   covered lanes packed one by one instead, sixteen to a block, each with
//!   those derivatives taken from its own quad; colours and depths are
//!   written, and depth tested, in submission order when the block is
//!   shaded: the image is that of shading each triangle at once.

// lane loops index several arrays by the same lane, as the lane code reads
#![allow(clippy::needless_range_loop)]

use super::simd::{self, LANES, Lanes};
use crate::prepare::Draw;
use glam::{Mat4, Vec3, Vec4};
use rayon::prelude::*;

mod program;
mod setup;
#[cfg(test)]
mod tests;

pub use program::*;
use setup::*;

/// Sub-pixel precision of snapped vertex positions.
pub const SUBPIXEL_BITS: u32 = 8;
const ONE: i64 = 1 << SUBPIXEL_BITS;
/// Rows per parallel band (even, so quads never straddle bands).
pub const BAND: u32 = 16;
/// Guard band: clip x and y at ±GUARD·w.
pub const GUARD: f32 = 4.0;

/// Colour and depth buffers.
pub struct Target {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGBA8 pixels.
    pub color: Vec<[u8; 4]>,
    /// Depth per pixel (1 = far).
    pub depth: Vec<f32>,
    /// A clear still to be made (see [`Target::deferred`]).
    pending: Option<[u8; 4]>,
}

impl Target {
    /// Buffers cleared to `clear` and depth 1.
    pub fn new(width: u32, height: u32, clear: [u8; 4]) -> Self {
        let n = width as usize * height as usize;
        Self { width, height, color: vec![clear; n], depth: vec![1.0; n], pending: None }
    }

    /// Buffers that the next [`rasterize`] clears to `clear` and depth 1,
    /// band by band in its workers, instead of in one pass before it (a
    /// frame's only serial pass over every pixel). Until then `color` and
    /// `depth` hold zeros; [`Target::into_rgba`] clears them if no
    /// rasterization did.
    pub fn deferred(width: u32, height: u32, clear: [u8; 4]) -> Self {
        let n = width as usize * height as usize;
        // zeroed allocations: fresh pages need no writing here
        Self { width, height, color: vec![[0; 4]; n], depth: vec![0.0; n], pending: Some(clear) }
    }

    /// Makes a deferred clear now.
    pub fn finish_clear(&mut self) {
        if let Some(c) = self.pending.take() {
            self.color.fill(c);
            self.depth.fill(1.0);
        }
    }

    /// The colour buffer as bytes (the same allocation, not a copy).
    pub fn into_rgba(mut self) -> Vec<u8> {
        self.finish_clear();
        bytemuck::allocation::cast_vec(self.color)
    }
}

/// A conservative early depth test for programs that write their own depth
/// (which otherwise cannot test before shading): a fragment whose
/// interpolated eye distance lies more than `margin` behind the depth
/// already in the buffer at its pixel is not shaded, since its program's
/// depth could not pass the late test. `margin` must bound how much nearer
/// than its triangle a program's depth may put a fragment (for exact
/// surfaces: the tessellation's deviation); the image does not change.
#[derive(Debug, Clone, Copy)]
pub struct EarlyDepth {
    /// Eye-distance margin, world units.
    pub margin: f32,
    /// The projection's near plane (to turn depth into distance).
    pub near: f32,
    /// The projection's far plane.
    pub far: f32,
}

/// Rasterizes indexed triangles into `target`, drawing `draws` in order.
/// `positions` are world positions; `varyings` the per-vertex inputs of the
/// fragment program.
pub fn rasterize<const K: usize, S: BlockShader<K>>(
    target: &mut Target,
    view_proj: Mat4,
    positions: &[Vec3],
    varyings: &[[f32; K]],
    indices: &[u32],
    draws: &[Draw],
    shader: &S,
) {
    rasterize_early(target, view_proj, positions, varyings, indices, draws, shader, None);
}

/// [`rasterize`] with a conservative early depth test ([`EarlyDepth`]) for
/// programs that write depth.
#[allow(clippy::too_many_arguments)]
pub fn rasterize_early<const K: usize, S: BlockShader<K>>(
    target: &mut Target,
    view_proj: Mat4,
    positions: &[Vec3],
    varyings: &[[f32; K]],
    indices: &[u32],
    draws: &[Draw],
    shader: &S,
    early: Option<EarlyDepth>,
) {
    let (width, height) = (target.width, target.height);
    // depth d in [0, 1] of distance w: d = r (near / w − 1), r = far / (near − far)
    let occ = early.filter(|_| S::WRITES_DEPTH).map(|o| {
        let r = o.far / (o.near - o.far);
        OccParams { margin: o.margin, near: o.near, inv_r: 1.0 / r }
    });
    // vertex stage: clip position and, for a vertex inside every clip plane,
    // its snapped screen position, 1/w, depth and varyings·q, computed once
    // for the triangles that share it
    let (wf, hf) = (width as f32, height as f32);
    let post: Vec<Post<K>> = positions
        .par_iter()
        .zip(varyings.par_iter())
        .with_min_len(1024)
        .map(|(p, a)| {
            let clip = view_proj * p.extend(1.0);
            let inside = clip.is_finite() && inside_all(clip);
            let mut v = Post { clip, inside, x: 0, y: 0, q: 0.0, z: 0.0, vq: [0.0; K] };
            if inside {
                (v.x, v.y, v.q, v.z) = project(clip, wf, hf);
                v.vq = std::array::from_fn(|j| a[j] * v.q);
            }
            v
        })
        .collect();

    // clipping, setup and binning, in submission order: chunks of a draw's
    // triangles in parallel, each set-up triangle named by its chunk and
    // its place there (flattening the chunks into one vector would copy
    // every set-up triangle once more per frame)
    let chunks = setup_chunks(draws);
    let bands = height.div_ceil(BAND) as usize;
    let tris: Vec<SetupChunk<K>> = chunks
        .par_iter()
        .map(|pieces| {
            let mut out = Vec::with_capacity(pieces.iter().map(|p| (p.2 - p.1) / 3).sum());
            let mut poly = Vec::with_capacity(12);
            let mut scratch = Vec::with_capacity(12);
            for (material, t) in
                pieces.iter().flat_map(|&(m, i0, i1)| indices[i0..i1].chunks_exact(3).map(move |t| (m, t)))
            {
                let idx = [t[0] as usize, t[1] as usize, t[2] as usize];
                let pv = idx.map(|i| &post[i]);
                // wholly inside every clip plane: no polygon to cut, and the
                // vertices are projected already
                if pv.iter().all(|v| v.inside) {
                    let key = shader.key(&varyings[idx[0]]);
                    let xs = pv.map(|v| v.x);
                    let ys = pv.map(|v| v.y);
                    let (qs, zs, vals) = (pv.map(|v| v.q), pv.map(|v| v.z), pv.map(|v| v.vq));
                    out.extend(assemble(xs, ys, qs, zs, vals, material, key, width, height));
                    continue;
                }
                let c = pv.map(|v| v.clip);
                if !c.iter().all(|c| c.is_finite()) {
                    continue;
                }
                let key = shader.key(&varyings[idx[0]]);
                let verts = [
                    ClipVert { clip: c[0], bary: Vec3::X },
                    ClipVert { clip: c[1], bary: Vec3::Y },
                    ClipVert { clip: c[2], bary: Vec3::Z },
                ];
                poly.clear();
                poly.extend_from_slice(&verts);
                clip_polygon(&mut poly, &mut scratch);
                for i in 1..poly.len().saturating_sub(1) {
                    let fan = [poly[0], poly[i], poly[i + 1]];
                    out.extend(setup(fan, idx, varyings, material, key, width, height));
                }
            }
            SetupChunk::binned(out, bands)
        })
        .collect();

    // traversal, one band per task (which also makes a deferred clear of its rows)
    let pending = target.pending.take();
    let w = width as usize;
    let band_px = w * BAND as usize;
    target.color.par_chunks_mut(band_px).zip(target.depth.par_chunks_mut(band_px)).enumerate().for_each(
        |(b, (color, depth))| {
            if let Some(c) = pending {
                color.fill(c);
                depth.fill(1.0);
            }
            let y_band = b as u32 * BAND;
            let rows = (color.len() / w) as u32;
            // the band's triangles, in submission order
            let mut bin = Vec::with_capacity(tris.iter().map(|c| c.in_band(b).len()).sum());
            for (c, chunk) in tris.iter().enumerate() {
                bin.extend(chunk.in_band(b).iter().map(|&i| (c as u32, i)));
            }
            simd::run_at(
                if S::GATHER_BOUND { simd::level_for_gathers() } else { simd::level() },
                BandOp { tris: &tris, bin: &bin, shader, color, depth, width, y_band, rows, occ },
            );
        },
    );
}

/// The traversal of one band (its triangles in submission order), compiled
/// per SIMD level.
struct BandOp<'a, const K: usize, S> {
    tris: &'a [SetupChunk<K>],
    bin: &'a [(u32, u32)],
    shader: &'a S,
    color: &'a mut [[u8; 4]],
    depth: &'a mut [f32],
    width: u32,
    y_band: u32,
    rows: u32,
    /// The conservative early depth test, if any.
    occ: Option<OccParams>,
}

impl<const K: usize, S: BlockShader<K>> pulp::WithSimd for BandOp<'_, K, S> {
    type Output = ();
    #[inline(always)]
    fn with_simd<Sm: pulp::Simd>(self, simd: Sm) {
        let mut batch = Batch::<K>::new();
        // the farthest depth of each 8×2 cell of the band, for the
        // conservative early test of whole blocks (programs that write depth)
        let hiz = match self.occ {
            Some(_) => Hiz::of(self.depth, self.width as usize),
            None => Hiz { max: Vec::new(), cells_w: 0, width: self.width as usize },
        };
        let mut out = Out { shader: self.shader, color: self.color, depth: self.depth, hiz };
        let pack = self.shader.packs_triangles();
        for (k, &(c, i)) in self.bin.iter().enumerate() {
            // the set-up of a triangle a few ahead, on its way into the cache
            // (set-ups come from the other workers' chunks)
            if let Some(&(nc, ni)) = self.bin.get(k + PREFETCH_AHEAD) {
                prefetch(&self.tris[nc as usize].tris[ni as usize]);
            }
            let t = &self.tris[c as usize].tris[i as usize];
            raster_band(simd, t, &mut batch, &mut out, self.width, self.y_band, self.rows, self.occ);
            if !pack {
                batch.flush(&mut out);
            }
        }
        batch.flush(&mut out);
    }
}

/// Triangles between the one traversed and the one whose set-up is fetched.
const PREFETCH_AHEAD: usize = 2;

/// Asks for the cache lines of `v` (a hint: no effect on results).
#[inline(always)]
fn prefetch<T>(v: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = (v as *const T).cast::<i8>();
        let mut off = 0;
        while off < std::mem::size_of::<T>() {
            // SAFETY: SSE is part of the x86-64 baseline, and a prefetch
            // neither reads into the program nor faults, whatever the address
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(off)) };
            off += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = v;
}

/// The band's program and buffers.
struct Out<'a, S> {
    shader: &'a S,
    color: &'a mut [[u8; 4]],
    depth: &'a mut [f32],
    /// Cell maxima of `depth` (empty without the conservative early test).
    hiz: Hiz,
}

/// A bound on the largest depth of each 8×2 pixel cell of a band (cells
/// aligned to multiples of 8 columns and 2 rows): 1 (the far plane, which
/// bounds every depth) until the program writes into the cell, then the
/// maximum of the cell's depths, recomputed as they are written. A block
/// whose nearest possible fragment lies more than the early test's margin
/// behind the farthest depth of the cells under it cannot pass, and is
/// skipped before any lane is interpolated.
struct Hiz {
    max: Vec<f32>,
    cells_w: usize,
    width: usize,
}

impl Hiz {
    /// The cells of a band's depth buffer (`width` pixels a row), every
    /// one bounded by the far plane.
    fn of(depth: &[f32], width: usize) -> Self {
        let cells_w = width.div_ceil(8);
        let rows = depth.len() / width;
        Self { max: vec![1.0; cells_w * rows.div_ceil(2)], cells_w, width }
    }

    /// Recomputes cell (`cx`, `cy`) from the depths under it (every depth
    /// lies in [0, 1]: the clear value or a fragment's that passed).
    #[inline(always)]
    fn refresh(&mut self, depth: &[f32], cx: usize, cy: usize) {
        let (x0, x1) = (8 * cx, (8 * cx + 8).min(self.width));
        let rows = depth.len() / self.width;
        if x1 - x0 == 8 && 2 * cy + 2 <= rows {
            // a whole cell: two rows of eight, as vector maxima
            let i = 2 * cy * self.width + x0;
            let (a, b) = (&depth[i..i + 8], &depth[i + self.width..i + self.width + 8]);
            let mut m = [0.0f32; 8];
            for k in 0..8 {
                m[k] = if a[k] > b[k] { a[k] } else { b[k] };
            }
            for h in [4, 2, 1] {
                for k in 0..h {
                    m[k] = if m[k] > m[k + h] { m[k] } else { m[k + h] };
                }
            }
            self.max[cy * self.cells_w + cx] = m[0];
            return;
        }
        let mut m = 0.0f32;
        for y in 2 * cy..(2 * cy + 2).min(rows) {
            for &d in &depth[y * self.width + x0..y * self.width + x1] {
                m = m.max(d);
            }
        }
        self.max[cy * self.cells_w + cx] = m;
    }

    /// The farthest depth under the 8×2 block at band column `x`, row `y` (even).
    #[inline(always)]
    fn block(&self, x: u32, y: u32) -> f32 {
        let row = (y / 2) as usize * self.cells_w;
        // the cells of the block's first and last columns
        let last = x as usize + 7;
        let (c0, c1) = ((x / 8) as usize, (last / 8).min(self.cells_w - 1));
        self.max[row + c0].max(self.max[row + c1])
    }
}

/// Quads waiting to be shaded together: up to four covered 2×2 quads, from
/// any triangles of one material and program key, packed into one block so
/// that small triangles still fill the program's lanes. Each quad keeps its
/// own four lanes (helpers included), so derivatives are unchanged; colours
/// and depths are written in submission order when the block is shaded, and
/// the depth test is made then, so the image is that of shading each
/// triangle's quads at once. For a lane-packing program
/// ([`BlockShader::LANE_GRADS`]) up to sixteen covered lanes wait instead.
struct Batch<const K: usize> {
    block: Block<K>,
    /// Pixel index within the band of each lane (read for live lanes only).
    pixel: [u32; LANES],
    /// The 8×2 depth-bound cell of each lane's pixel, `(row << 16) | column`.
    cell: [u32; LANES],
    /// Lane slots filled (four a quad).
    used: usize,
    /// Material and key of the quads.
    key: (usize, u32),
    rgba: [[u8; 4]; LANES],
    zout: Lanes,
}

impl<const K: usize> Batch<K> {
    fn new() -> Self {
        Self {
            block: Block {
                material: 0,
                x: 0,
                y: 0,
                v: [[0.0; LANES]; K],
                w: [1.0; LANES],
                z: [0.0; LANES],
                live: 0,
                grad: [[[0.0; LANES]; 2]; 2],
            },
            pixel: [0; LANES],
            cell: [0; LANES],
            used: 0,
            key: (0, 0),
            rgba: [[0; 4]; LANES],
            zout: [0.0; LANES],
        }
    }

    /// Shades the waiting lanes and writes those that pass the depth test.
    #[inline(always)]
    fn flush<S: BlockShader<K>>(&mut self, out: &mut Out<'_, S>) {
        if self.used == 0 {
            return;
        }
        let b = &self.block;
        out.shader.shade_block(b, &mut self.rgba, &mut self.zout);
        let mut written = 0u16;
        for lane in 0..self.used {
            if b.live & (1 << lane) == 0 {
                continue;
            }
            let i = self.pixel[lane] as usize;
            // the program's depth (out-of-range depth is clipped), else the triangle's
            let d = if S::WRITES_DEPTH { self.zout[lane] } else { b.z[lane] };
            let pass = if S::WRITES_DEPTH { (0.0..=1.0).contains(&d) && d < out.depth[i] } else { d < out.depth[i] };
            if pass {
                out.depth[i] = d;
                out.color[i] = self.rgba[lane];
                written |= 1 << lane;
            }
        }
        // the cells under the lanes written (consecutive lanes mostly share theirs)
        if !out.hiz.max.is_empty() {
            let mut last = u32::MAX;
            while written != 0 {
                let cell = self.cell[written.trailing_zeros() as usize];
                written &= written - 1;
                if cell != last {
                    out.hiz.refresh(out.depth, (cell & 0xffff) as usize, (cell >> 16) as usize);
                    last = cell;
                }
            }
        }
        self.used = 0;
        self.block.live = 0;
    }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn raster_band<const K: usize, S: BlockShader<K>, Sm: pulp::Simd>(
    simd: Sm,
    t: &Setup<K>,
    batch: &mut Batch<K>,
    out: &mut Out<'_, S>,
    width: u32,
    y_band: u32,
    rows: u32,
    occ: Option<OccParams>,
) {
    let y0 = t.by0.max(y_band) & !1;
    let y1 = t.by1.min(y_band + rows);
    let x0 = t.bx0 & !1;
    let x1 = t.bx1;
    if y0 >= y1 {
        return;
    }
    let (x, y) = (t.x, t.y);
    // edge i opposite vertex i: from vertex i+1 to vertex i+2
    let ea = [(1usize, 2usize), (2, 0), (0, 1)];
    // per-pixel steps of each edge function (written out: `ea.map` compiled
    // to a call per triangle)
    let step_x: [i64; 3] = [-(y[2] - y[1]) * ONE, -(y[0] - y[2]) * ONE, -(y[1] - y[0]) * ONE];
    let step_y: [i64; 3] = [(x[2] - x[1]) * ONE, (x[0] - x[2]) * ONE, (x[1] - x[0]) * ONE];
    // per-lane offsets of each edge function within a block
    let offs: [[i64; LANES]; 3] = std::array::from_fn(|i| {
        let mut o = [0i64; LANES];
        for (lane, v) in o.iter_mut().enumerate() {
            *v = lane_dx(lane) * step_x[i] + lane_dy(lane) * step_y[i];
        }
        o
    });
    // the block's extreme offsets (its corners 0, 7·sx, sy, 7·sx + sy) for
    // trivial reject and accept: the sums of the extremes along each axis
    let corner = |i: usize| -> (i64, i64) {
        let (a, b) = (7 * step_x[i], step_y[i]);
        (a.min(0) + b.min(0), a.max(0) + b.max(0))
    };
    let corners = [corner(0), corner(1), corner(2)];
    // the nearest eye distance of any fragment, less the early test's margin:
    // q = 1/w is largest at a vertex (bounded up by a part in a million for
    // its rounding within the triangle)
    let near_lim = occ.and_then(|p| {
        let q = t.q[0].max(t.q[0] + t.q[1]).max(t.q[0] + t.q[2]) * (1.0 + 1e-6);
        (q > 0.0 && q.is_finite()).then(|| (1.0 / q - p.margin, p))
    });
    // the edge functions at the first block's lane 0, stepped two rows a
    // block row (exact: integers)
    let (px, py) = (x0 as i64 * ONE + ONE / 2, y0 as i64 * ONE + ONE / 2);
    let mut e_first: [i64; 3] = [0; 3];
    for (i, (a, b)) in ea.iter().enumerate() {
        e_first[i] = edge(x[*a], y[*a], x[*b], y[*b], px, py);
    }
    let mut qy = y0;
    while qy < y1 {
        let mut e_row = e_first;
        for i in 0..3 {
            e_first[i] += 2 * step_y[i];
        }
        // rows of this pair inside the band and the frame
        let row_ok = [qy < y_band + rows, qy + 1 < y_band + rows];
        let mut qx = x0;
        while qx < x1 {
            // trivial reject: an edge negative at every corner of the block
            let mut outside = (0..3).any(|i| e_row[i] + corners[i].1 + t.bias[i] < 0);
            // hidden: more than the margin behind the farthest depth already
            // under the block (the lane test of `raster_block`, for every
            // lane at once)
            if !outside && let Some((lim, p)) = near_lim {
                let d = out.hiz.block(qx, qy - y_band);
                outside = d < 1.0 && lim * (d * p.inv_r + 1.0) > p.near;
            }
            if !outside {
                let full = (0..3).all(|i| e_row[i] + corners[i].0 + t.bias[i] >= 0);
                let mut mask = if full {
                    0xffff
                } else {
                    // every edge function ≥ 0, lane by lane (one vector compare per edge)
                    let mut inside = [true; LANES];
                    for i in 0..3 {
                        let e = e_row[i] + t.bias[i];
                        for lane in 0..LANES {
                            inside[lane] &= e + offs[i][lane] >= 0;
                        }
                    }
                    let mut m = 0u16;
                    for lane in 0..LANES {
                        m |= (inside[lane] as u16) << lane;
                    }
                    m
                };
                // lanes past the frame's right side or the band's last row
                if qx + 8 > width || !row_ok[1] {
                    for lane in 0..LANES {
                        if qx + lane_dx(lane) as u32 >= width || !row_ok[lane_dy(lane) as usize] {
                            mask &= !(1 << lane);
                        }
                    }
                }
                if mask != 0 {
                    raster_block(simd, t, batch, out, width, y_band, qx, qy, mask, &e_row, &offs, occ);
                }
            }
            for (i, e) in e_row.iter_mut().enumerate() {
                *e += 8 * step_x[i];
            }
            qx += 8;
        }
        qy += 2;
    }
}

/// Perspective-correct varyings of a block's lanes, `(a0 + λ1·a1 + λ2·a2)·w`,
/// one register of lanes at a time. Written with the level's vector type:
/// as plain lane loops the compiler vectorised across the varyings instead
/// and wrote each lane with a scatter (8 % of a NURBS frame).
#[inline(always)]
fn interpolate<const K: usize, Sm: pulp::Simd>(
    s: Sm,
    t: &Setup<K>,
    l1: &Lanes,
    l2: &Lanes,
    w: &Lanes,
    v: &mut [Lanes; K],
) {
    let (l1, _) = Sm::as_simd_f32s(l1);
    let (l2, _) = Sm::as_simd_f32s(l2);
    let (w, _) = Sm::as_simd_f32s(w);
    for j in 0..K {
        let (a0, a1, a2) = (s.splat_f32s(t.va[0][j]), s.splat_f32s(t.va[1][j]), s.splat_f32s(t.va[2][j]));
        let (row, _) = Sm::as_mut_simd_f32s(&mut v[j]);
        for c in 0..row.len() {
            let e = s.add_f32s(s.add_f32s(a0, s.mul_f32s(l1[c], a1)), s.mul_f32s(l2[c], a2));
            row[c] = s.mul_f32s(e, w[c]);
        }
    }
}

/// One 8×2 block of a triangle: interpolation, the early depth tests, and
/// its covered quads added to the batch.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn raster_block<const K: usize, S: BlockShader<K>, Sm: pulp::Simd>(
    simd: Sm,
    t: &Setup<K>,
    batch: &mut Batch<K>,
    out: &mut Out<'_, S>,
    width: u32,
    y_band: u32,
    qx: u32,
    qy: u32,
    mut mask: u16,
    e_row: &[i64; 3],
    offs: &[[i64; LANES]; 3],
    occ: Option<OccParams>,
) {
    // screen-linear barycentrics λ1 = E(edge 2→0)/A, λ2 = E(edge 0→1)/A
    let mut l1 = [0.0f32; LANES];
    let mut l2 = [0.0f32; LANES];
    for lane in 0..LANES {
        l1[lane] = edge_to_f32(e_row[1] + offs[1][lane]) * t.inv_area;
        l2[lane] = edge_to_f32(e_row[2] + offs[2][lane]) * t.inv_area;
    }
    let mut z = [0.0f32; LANES];
    for lane in 0..LANES {
        z[lane] = t.z[0] + l1[lane] * t.z[1] + l2[lane] * t.z[2];
    }
    let index = |lane: usize| -> usize {
        let (lx, ly) = (qx + lane_dx(lane) as u32, qy + lane_dy(lane) as u32 - y_band);
        ly as usize * width as usize + lx as usize
    };
    // the depths under the lanes: two rows of eight when the block lies
    // within the band and the frame, else lane by lane (1, the far plane,
    // under lanes off the band)
    let mut under = [1.0f32; LANES];
    if !S::WRITES_DEPTH || occ.is_some() {
        let (w, i0) = (width as usize, index(0));
        if qx + 8 <= width && i0 + w + 8 <= out.depth.len() {
            let (r0, r1) = (&out.depth[i0..i0 + 8], &out.depth[i0 + w..i0 + w + 8]);
            for (lane, d) in under.iter_mut().enumerate() {
                let x = lane_dx(lane) as usize;
                *d = if lane_dy(lane) == 0 { r0[x] } else { r1[x] };
            }
        } else {
            for (lane, d) in under.iter_mut().enumerate() {
                if mask & (1 << lane) != 0 {
                    *d = out.depth[index(lane)];
                }
            }
        }
    }
    // early depth test, unless the program computes depth itself (the
    // buffer may not yet hold the batch's quads: the test is made again
    // when they are written)
    if !S::WRITES_DEPTH {
        let mut pass = 0u16;
        for lane in 0..LANES {
            pass |= ((z[lane] < under[lane]) as u16) << lane;
        }
        mask &= pass;
        if mask == 0 {
            return;
        }
    }
    // perspective-correct w for all lanes (uncovered ones are helpers)
    let mut w = [0.0f32; LANES];
    for lane in 0..LANES {
        let q = t.q[0] + l1[lane] * t.q[1] + l2[lane] * t.q[2];
        w[lane] = 1.0 / q;
    }
    // conservative early depth: lanes more than the margin behind what the
    // buffer already holds cannot pass the late test
    if let Some(p) = occ {
        let mut hidden = 0u16;
        for lane in 0..LANES {
            let d = under[lane];
            // nothing drawn yet: depth 1 (the far plane); the distance
            // of depth d is near / (d/r + 1), with d/r + 1 > 0 for d < 1
            // (r = far / (near − far) < −1): compared without dividing
            // (`&`, not `&&`: both sides are computed for every lane, as
            // vector code, instead of a branch a lane)
            hidden |= (((d < 1.0) & ((w[lane] - p.margin) * (d * p.inv_r + 1.0) > p.near)) as u16) << lane;
        }
        mask &= !hidden;
        if mask == 0 {
            return;
        }
    }
    const {
        if let Some(js) = S::LANE_GRADS {
            assert!(js[0] < K && js[1] < K, "LANE_GRADS names a varying the program does not have");
        }
    }
    let key = (t.material, t.key);
    // the depth-bound cell of a lane's pixel
    let cell = |lane: usize| -> u32 {
        let (lx, ly) = (qx + lane_dx(lane) as u32, qy + lane_dy(lane) as u32 - y_band);
        ((ly / 2) << 16) | (lx / 8)
    };
    // every quad covered (large triangles): the block is shaded as it is
    if mask == 0xffff || (S::LANE_GRADS.is_none() && (0..4).all(|quad| (mask >> (4 * quad)) & 0xf != 0)) {
        batch.flush(out);
        let b = &mut batch.block;
        interpolate(simd, t, &l1, &l2, &w, &mut b.v);
        if let Some(js) = S::LANE_GRADS {
            b.fill_grads(js);
        }
        b.w = w;
        b.z = z;
        b.live = mask;
        b.material = t.material;
        (b.x, b.y) = (qx, qy);
        for lane in 0..LANES {
            batch.pixel[lane] = index(lane) as u32;
            batch.cell[lane] = cell(lane);
        }
        batch.key = key;
        batch.used = LANES;
        batch.flush(out);
        return;
    }
    let mut v = [[0.0f32; LANES]; K];
    interpolate(simd, t, &l1, &l2, &w, &mut v);
    if let Some(js) = S::LANE_GRADS {
        // the covered lanes join the batch one by one, in order, each with
        // the derivatives of its quad
        let grad = [quad_grads(&v[js[0]]), quad_grads(&v[js[1]])];
        if batch.used > 0 && batch.key != key {
            batch.flush(out);
        }
        let mut rest = mask;
        while rest != 0 {
            let lane = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if batch.used == LANES {
                batch.flush(out);
            }
            let n = batch.used;
            let b = &mut batch.block;
            for j in 0..K {
                b.v[j][n] = v[j][lane];
            }
            for g in 0..2 {
                b.grad[g][0][n] = grad[g][0][lane];
                b.grad[g][1][n] = grad[g][1][lane];
            }
            b.w[n] = w[lane];
            b.z[n] = z[lane];
            b.live |= 1 << n;
            b.material = t.material;
            if n == 0 {
                b.x = qx + lane_dx(lane) as u32;
                b.y = qy + lane_dy(lane) as u32;
            }
            batch.pixel[n] = index(lane) as u32;
            batch.cell[n] = cell(lane);
            batch.key = key;
            batch.used += 1;
        }
        return;
    }
    // the covered quads join the batch, in order
    for quad in 0..4 {
        let live = (mask >> (4 * quad)) & 0xf;
        if live == 0 {
            continue;
        }
        if batch.used == LANES || (batch.used > 0 && batch.key != key) {
            batch.flush(out);
        }
        let (src, dst) = (4 * quad, batch.used);
        let b = &mut batch.block;
        for j in 0..K {
            b.v[j][dst..dst + 4].copy_from_slice(&v[j][src..src + 4]);
        }
        b.w[dst..dst + 4].copy_from_slice(&w[src..src + 4]);
        b.z[dst..dst + 4].copy_from_slice(&z[src..src + 4]);
        for l in 0..4 {
            batch.pixel[dst + l] = index(src + l) as u32;
            batch.cell[dst + l] = cell(src + l);
        }
        b.live |= live << dst;
        b.material = t.material;
        if dst == 0 {
            b.x = qx + 2 * quad as u32;
            b.y = qy;
        }
        batch.key = key;
        batch.used += 4;
    }
}
