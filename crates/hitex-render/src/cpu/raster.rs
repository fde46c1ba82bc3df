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

/// Sub-pixel precision of snapped vertex positions.
pub const SUBPIXEL_BITS: u32 = 8;
const ONE: i64 = 1 << SUBPIXEL_BITS;
/// Rows per parallel band (even, so quads never straddle bands).
pub const BAND: u32 = 16;
/// Guard band: clip x and y at ±GUARD·w.
pub const GUARD: f32 = 4.0;

/// A fragment program shading a 2×2 quad. Lanes are (0,0) (1,0) (0,1) (1,1).
pub trait QuadShader<const K: usize>: Sync {
    /// Shades the quad. `v` holds perspective-correct varyings per lane, `w`
    /// the perspective-correct clip w; bit `i` of `live` is set for lanes whose
    /// colour is written (the others are helpers: they feed derivatives, and
    /// their colour may be left uncomputed). Returns RGBA8 per lane.
    fn shade(&self, material: usize, v: &[[f32; K]; 4], w: [f32; 4], live: u8) -> [[u8; 4]; 4];

    /// True when the program computes its own depth ([`QuadShader::shade_depth`],
    /// WGSL `@builtin(frag_depth)`): the depth test then runs after shading.
    const WRITES_DEPTH: bool = false;

    /// Shades the quad and returns each lane's depth in [0, 1] as well.
    /// Programs that set [`QuadShader::WRITES_DEPTH`] implement it.
    fn shade_depth(
        &self,
        material: usize,
        v: &[[f32; K]; 4],
        w: [f32; 4],
        live: u8,
        z: [f32; 4],
    ) -> ([[u8; 4]; 4], [f32; 4]) {
        (self.shade(material, v, w, live), z)
    }
}

/// Four 2×2 quads handed to a program at once, as structure of arrays: lane
/// `4q + l` is lane `l` of quad `q` ((0,0) (1,0) (0,1) (1,1)), so that
/// screen-space derivatives stay per quad (differences of lanes within a
/// group of four, as on a GPU). The quads share a material and a program key
/// ([`BlockShader::key`]) but may come from different triangles and places
/// (small triangles are packed together); quad slots past the last filled
/// one have no live lane.
///
/// For a program that packs lanes ([`BlockShader::LANE_GRADS`]) the lanes
/// are instead single covered fragments of any triangles, in submission
/// order, the live ones first; their quads' derivatives come in [`Block::grad`].
#[derive(Clone)]
pub struct Block<const K: usize> {
    /// Material of the triangle.
    pub material: usize,
    /// Pixel column of the first quad's lane 0 (even; of a lane-packed
    /// block, of its first lane).
    pub x: u32,
    /// Pixel row of the first quad's lane 0 (even; of a lane-packed block,
    /// of its first lane).
    pub y: u32,
    /// Perspective-correct varyings: `v[j][lane]`.
    pub v: [Lanes; K],
    /// Perspective-correct clip w per lane.
    pub w: Lanes,
    /// Screen-linear depth per lane.
    pub z: Lanes,
    /// Bit `lane` set: the lane is covered and its colour is written (the
    /// others are helpers feeding derivatives; their colour may be left
    /// uncomputed).
    pub live: u16,
    /// Fine screen derivatives of the varyings named by
    /// [`BlockShader::LANE_GRADS`], per lane: `grad[g][0]` along x (WGSL
    /// `dpdxFine`) and `grad[g][1]` along y (`dpdyFine`) of varying
    /// `LANE_GRADS[g]`, from the lane's own quad as the quad layout above would
    /// give them (the same bits). Filled for lane-packing programs only.
    pub grad: [[Lanes; 2]; 2],
}

impl<const K: usize> Block<K> {
    /// Fills [`Block::grad`] for varyings `js` from the block's quads (the
    /// layout of a block that is not lane-packed).
    pub fn fill_grads(&mut self, js: [usize; 2]) {
        for g in 0..2 {
            self.grad[g] = quad_grads(&self.v[js[g]]);
        }
    }
}

/// Fine screen derivatives (d/dx, d/dy) of a lane value over a block's four
/// quads (WGSL `dpdxFine`, `dpdyFine`): within each quad, x differences of
/// its rows and y differences of its columns.
#[inline(always)]
fn quad_grads(a: &Lanes) -> [Lanes; 2] {
    let mut dx = [0.0f32; LANES];
    let mut dy = [0.0f32; LANES];
    for q in 0..LANES / 4 {
        let b = 4 * q;
        let (top, bottom) = (a[b + 1] - a[b], a[b + 3] - a[b + 2]);
        let (left, right) = (a[b + 2] - a[b], a[b + 3] - a[b + 1]);
        dx[b..b + 4].copy_from_slice(&[top, top, bottom, bottom]);
        dy[b..b + 4].copy_from_slice(&[left, right, left, right]);
    }
    [dx, dy]
}

/// A fragment program shading a [`Block`] of 16 lanes. Every [`QuadShader`]
/// is one (quad by quad); the programs rewritten for lanes implement it directly.
pub trait BlockShader<const K: usize>: Sync {
    /// True when the program computes its own depth (WGSL
    /// `@builtin(frag_depth)`): the depth test then runs after shading.
    const WRITES_DEPTH: bool = false;
    /// True for a program whose lanes are mostly gathers and per-lane table
    /// reads: it runs at [`simd::level_for_gathers`] (8 lanes on processors
    /// that split 512-bit operations in two, where moving each lane in and
    /// out of a 512-bit register costs more), the others at [`simd::level`].
    const GATHER_BOUND: bool = false;
    /// Writes the colour of every live lane into `rgba` and, for programs
    /// that write depth, each lane's depth in [0, 1] into `depth` (anything
    /// else, NaN included, discards the lane).
    fn shade_block(&self, b: &Block<K>, rgba: &mut [[u8; 4]; LANES], depth: &mut Lanes);
    /// The batch key of a triangle, from its first vertex's varyings: the
    /// rasterizer packs quads of several triangles into one block only when
    /// their material and key agree (a program that shades a block faster
    /// when its lanes share some state, e.g. one NURBS patch, keys by it).
    #[inline(always)]
    fn key(&self, _v: &[f32; K]) -> u32 {
        0
    }
    /// Whether quads of different triangles may share a block. A program
    /// that records what it shades (bank statistics) says no: a waiting quad
    /// has not written its depth yet, so the early test would let through,
    /// and the program would record, fragments that drawing the triangles
    /// one by one culls (the image is the same either way).
    #[inline(always)]
    fn packs_triangles(&self) -> bool {
        true
    }
    /// For a program that reads nothing of a quad but the screen
    /// derivatives of (at most) two varyings: their indices. The rasterizer
    /// then packs covered lanes one by one, sixteen to a block whatever
    /// quads they come from (no helper lanes), and hands each lane those
    /// derivatives from its own quad in [`Block::grad`] (the same bits the
    /// quad would give). Tessellated surfaces, whose triangles leave quads
    /// two-thirds empty, fill their blocks this way.
    const LANE_GRADS: Option<[usize; 2]> = None;
}

impl<const K: usize, S: QuadShader<K>> BlockShader<K> for S {
    const WRITES_DEPTH: bool = <S as QuadShader<K>>::WRITES_DEPTH;
    #[inline(always)]
    fn shade_block(&self, b: &Block<K>, rgba: &mut [[u8; 4]; LANES], depth: &mut Lanes) {
        for q in 0..4 {
            let live = ((b.live >> (4 * q)) & 0xf) as u8;
            if live == 0 {
                continue;
            }
            let v: [[f32; K]; 4] = std::array::from_fn(|l| std::array::from_fn(|j| b.v[j][4 * q + l]));
            let w: [f32; 4] = std::array::from_fn(|l| b.w[4 * q + l]);
            if <S as BlockShader<K>>::WRITES_DEPTH {
                let z: [f32; 4] = std::array::from_fn(|l| b.z[4 * q + l]);
                let (c, d) = self.shade_depth(b.material, &v, w, live, z);
                for l in 0..4 {
                    rgba[4 * q + l] = c[l];
                    depth[4 * q + l] = d[l];
                }
            } else {
                let c = self.shade(b.material, &v, w, live);
                rgba[4 * q..4 * q + 4].copy_from_slice(&c);
            }
        }
    }
}

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

/// A clipped-polygon vertex: clip position and weights of the source triangle's vertices.
#[derive(Clone, Copy)]
struct ClipVert {
    clip: Vec4,
    bary: Vec3,
}

/// A triangle ready for traversal.
struct Setup<const K: usize> {
    material: usize,
    /// The program's batch key of the triangle ([`BlockShader::key`]).
    key: u32,
    /// Snapped vertices (fixed point).
    x: [i64; 3],
    y: [i64; 3],
    /// Edge bias: 0 for top-left edges, −1 otherwise (edge i is opposite vertex i).
    bias: [i64; 3],
    inv_area: f32,
    /// Screen-linear q = 1/w at vertex 0 and its differences to vertices 1 and 2.
    q: [f32; 3],
    /// Screen-linear depth z/w, same form.
    z: [f32; 3],
    /// Screen-linear varyings·q, same form.
    va: [[f32; K]; 3],
    /// Pixel bounding box (inclusive min, exclusive max).
    bx0: u32,
    by0: u32,
    bx1: u32,
    by1: u32,
    _k: std::marker::PhantomData<[f32; K]>,
}

/// Triangles per parallel task of the setup stage.
const SETUP_CHUNK: usize = 512;

/// Whether a clip-space vertex lies inside every plane [`clip_polygon`] cuts by.
#[inline]
fn inside_all(c: Vec4) -> bool {
    c.z >= 0.0
        && c.w - c.z >= 0.0
        && c.x + GUARD * c.w >= 0.0
        && GUARD * c.w - c.x >= 0.0
        && c.y + GUARD * c.w >= 0.0
        && GUARD * c.w - c.y >= 0.0
}

fn clip_polygon(poly: &mut Vec<ClipVert>, scratch: &mut Vec<ClipVert>) {
    // plane distances: inside when ≥ 0
    let planes: [fn(Vec4) -> f32; 6] = [
        |c| c.z,
        |c| c.w - c.z,
        |c| c.x + GUARD * c.w,
        |c| GUARD * c.w - c.x,
        |c| c.y + GUARD * c.w,
        |c| GUARD * c.w - c.y,
    ];
    for plane in planes {
        if poly.is_empty() {
            return;
        }
        scratch.clear();
        for i in 0..poly.len() {
            let a = poly[i];
            let b = poly[(i + 1) % poly.len()];
            let (da, db) = (plane(a.clip), plane(b.clip));
            if da >= 0.0 {
                scratch.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                let t = da / (da - db);
                scratch.push(ClipVert { clip: a.clip + (b.clip - a.clip) * t, bary: a.bary + (b.bary - a.bary) * t });
            }
        }
        std::mem::swap(poly, scratch);
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

/// The setup stage's chunks of about [`SETUP_CHUNK`] triangles each, in
/// submission order: each a list of `(material, first index, end index)`
/// pieces of whole triangles, so that a draw longer than a chunk spans
/// several and many short draws share one.
fn setup_chunks(draws: &[Draw]) -> Vec<Vec<(usize, usize, usize)>> {
    let mut chunks = Vec::new();
    let mut current = Vec::new();
    let mut filled = 0;
    for d in draws {
        let (mut first, mut left) = (d.first_index as usize, d.index_count as usize / 3);
        while left > 0 {
            let take = left.min(SETUP_CHUNK - filled);
            current.push((d.material, first, first + 3 * take));
            (first, left, filled) = (first + 3 * take, left - take, filled + take);
            if filled == SETUP_CHUNK {
                chunks.push(std::mem::take(&mut current));
                filled = 0;
            }
        }
    }
    if !current.is_empty() {
        chunks.push(current);
    }
    chunks
}

/// The set-up triangles of one chunk of the setup stage, and which of them
/// each band of rows meets (lists in the chunk's order, back to back).
struct SetupChunk<const K: usize> {
    tris: Vec<Setup<K>>,
    /// Band `b`'s list is `items[start[b]..start[b + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
}

impl<const K: usize> SetupChunk<K> {
    /// Bins `tris` into `bands` bands of [`BAND`] rows (a counting sort).
    fn binned(tris: Vec<Setup<K>>, bands: usize) -> Self {
        let range = |t: &Setup<K>| ((t.by0 / BAND) as usize, ((t.by1 - 1) / BAND) as usize);
        let mut start = vec![0u32; bands + 1];
        for t in &tris {
            let (b0, b1) = range(t);
            for n in &mut start[b0 + 1..=b1 + 1] {
                *n += 1;
            }
        }
        for b in 0..bands {
            start[b + 1] += start[b];
        }
        let mut next = start.clone();
        let mut items = vec![0u32; start[bands] as usize];
        for (i, t) in tris.iter().enumerate() {
            let (b0, b1) = range(t);
            for n in &mut next[b0..=b1] {
                items[*n as usize] = i as u32;
                *n += 1;
            }
        }
        Self { tris, start, items }
    }

    /// The chunk's triangles that band `b` meets.
    #[inline]
    fn in_band(&self, b: usize) -> &[u32] {
        &self.items[self.start[b] as usize..self.start[b + 1] as usize]
    }
}

/// The conservative early test's constants (see [`EarlyDepth`]).
#[derive(Clone, Copy)]
struct OccParams {
    margin: f32,
    near: f32,
    /// 1 / r, r = far / (near − far).
    inv_r: f32,
}

/// A vertex after the vertex stage: its clip position and, when it lies
/// inside every clip plane, what the triangles sharing it need of it.
#[derive(Clone, Copy)]
struct Post<const K: usize> {
    clip: Vec4,
    /// Inside every plane [`clip_polygon`] cuts by (and finite).
    inside: bool,
    /// Snapped screen position (fixed point).
    x: i64,
    y: i64,
    /// 1/w.
    q: f32,
    /// Depth z/w.
    z: f32,
    /// Varyings·q.
    vq: [f32; K],
}

/// Snapped screen position, 1/w and depth of a clip-space position.
#[inline(always)]
fn project(clip: Vec4, wf: f32, hf: f32) -> (i64, i64, f32, f32) {
    let q = 1.0 / clip.w;
    let (nx, ny, nz) = (clip.x * q, clip.y * q, clip.z * q);
    // viewport: NDC y up, pixel rows down
    let sx = (nx * 0.5 + 0.5) * wf;
    let sy = (0.5 - ny * 0.5) * hf;
    (round_half_away(sx * ONE as f32), round_half_away(sy * ONE as f32), q, nz)
}

/// Set-up of a vertex of a clipped polygon: its position as [`project`]
/// gives it, and the source triangle's varyings mixed by its weights.
#[allow(clippy::too_many_arguments)]
fn setup<const K: usize>(
    fan: [ClipVert; 3],
    idx: [usize; 3],
    varyings: &[[f32; K]],
    material: usize,
    key: u32,
    width: u32,
    height: u32,
) -> Option<Setup<K>> {
    let (wf, hf) = (width as f32, height as f32);
    let mut x = [0i64; 3];
    let mut y = [0i64; 3];
    let mut qs = [0.0f32; 3];
    let mut zs = [0.0f32; 3];
    let mut vals = [[0.0f32; K]; 3];
    for (k, v) in fan.iter().enumerate() {
        let q;
        (x[k], y[k], q, zs[k]) = project(v.clip, wf, hf);
        qs[k] = q;
        let (a, b, c) = (&varyings[idx[0]], &varyings[idx[1]], &varyings[idx[2]]);
        for (j, out) in vals[k].iter_mut().enumerate() {
            *out = (v.bary.x * a[j] + v.bary.y * b[j] + v.bary.z * c[j]) * q;
        }
    }
    assemble(x, y, qs, zs, vals, material, key, width, height)
}

/// A triangle's set-up from its projected vertices: orientation, edge
/// biases, bounding box, and the screen-linear forms of q, depth and
/// varyings·q.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn assemble<const K: usize>(
    mut x: [i64; 3],
    mut y: [i64; 3],
    mut qs: [f32; 3],
    mut zs: [f32; 3],
    mut vals: [[f32; K]; 3],
    material: usize,
    key: u32,
    width: u32,
    height: u32,
) -> Option<Setup<K>> {
    // orientation: make the signed area positive (clockwise on screen)
    let area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
    if area == 0 {
        return None;
    }
    if area < 0 {
        x.swap(1, 2);
        y.swap(1, 2);
        qs.swap(1, 2);
        zs.swap(1, 2);
        vals.swap(1, 2);
    }
    let area = area.abs();
    // edge i runs from vertex i+1 to vertex i+2 (opposite vertex i)
    let mut bias = [0i64; 3];
    for (i, b) in bias.iter_mut().enumerate() {
        let (a, c) = ((i + 1) % 3, (i + 2) % 3);
        let (dx, dy) = (x[c] - x[a], y[c] - y[a]);
        let top_left = (dy == 0 && dx > 0) || dy < 0;
        *b = if top_left { 0 } else { -1 };
    }
    let minx = x.iter().copied().min().unwrap_or(0);
    let maxx = x.iter().copied().max().unwrap_or(0);
    let miny = y.iter().copied().min().unwrap_or(0);
    let maxy = y.iter().copied().max().unwrap_or(0);
    // pixels whose centre (p + ½) can lie inside
    let px0 = ((minx - ONE / 2).div_euclid(ONE)).max(0);
    let px1 = ((maxx - ONE / 2).div_euclid(ONE) + 1).min(width as i64);
    let py0 = ((miny - ONE / 2).div_euclid(ONE)).max(0);
    let py1 = ((maxy - ONE / 2).div_euclid(ONE) + 1).min(height as i64);
    if px0 >= px1 || py0 >= py1 {
        return None;
    }
    let diff = |a: &[f32; K], b: &[f32; K]| -> [f32; K] { std::array::from_fn(|j| a[j] - b[j]) };
    let va = [vals[0], diff(&vals[1], &vals[0]), diff(&vals[2], &vals[0])];
    Some(Setup {
        material,
        key,
        x,
        y,
        bias,
        inv_area: (1.0 / area as f64) as f32,
        q: [qs[0], qs[1] - qs[0], qs[2] - qs[0]],
        z: [zs[0], zs[1] - zs[0], zs[2] - zs[0]],
        va,
        bx0: px0 as u32,
        by0: py0 as u32,
        bx1: px1 as u32,
        by1: py1 as u32,
        _k: std::marker::PhantomData,
    })
}

/// `v.round() as i64` (halves away from zero) without the library call
/// that `round` is on the baseline x86-64 target: the truncating
/// conversion is one instruction, and below 2²³ the fraction it leaves is
/// exact (above, every f32 is an integer and the fraction is zero).
#[inline(always)]
fn round_half_away(v: f32) -> i64 {
    let t = v as i64;
    let f = v - t as f32;
    if f >= 0.5 {
        t + 1
    } else if f <= -0.5 {
        t - 1
    } else {
        t
    }
}

/// Edge function of edge (a → b) at fixed-point p: positive inside.
#[inline]
fn edge(ax: i64, ay: i64, bx: i64, by: i64, px: i64, py: i64) -> i64 {
    (bx - ax) * (py - ay) - (by - ay) * (px - ax)
}

/// `e as f32` for an edge function value, in vector operations only (x86
/// below AVX-512 has no vector conversion from i64, and `as f32` runs lane
/// by lane): `e` added to the bits of 2⁵² + 2⁵¹ is that double's integer
/// `e` (exact for |e| < 2⁵¹), the subtraction leaves `e` exactly as an f64,
/// which rounds to the nearest f32 as the direct conversion does. Edge
/// values stay below 2⁵⁰: snapped coordinates lie within the guard band of
/// a frame of at most 16,384 pixels a side, |x| < 2.5 · 16,384 · 256 < 2²⁴,
/// so differences are below 2²⁵ and an edge function, a difference of two
/// products of them, below 2⁵⁰ at every pixel of the frame.
#[inline(always)]
fn edge_to_f32(e: i64) -> f32 {
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 2^52 + 2^51
    (f64::from_bits((e as u64).wrapping_add(MAGIC.to_bits())) - MAGIC) as f32
}

/// The lane offsets (in pixels) of a block: quad `q` (left to right), lane
/// `l` of the quad ((0,0) (1,0) (0,1) (1,1)) is lane `4q + l`.
#[inline(always)]
const fn lane_dx(lane: usize) -> i64 {
    ((lane / 4) * 2 + (lane & 1)) as i64
}
#[inline(always)]
const fn lane_dy(lane: usize) -> i64 {
    ((lane >> 1) & 1) as i64
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes the lane's first varying as the red channel and counts coverage in green.
    struct Probe;
    impl QuadShader<1> for Probe {
        fn shade(&self, _: usize, v: &[[f32; 1]; 4], _: [f32; 4], _: u8) -> [[u8; 4]; 4] {
            v.map(|a| [(a[0] * 255.0).round().clamp(0.0, 255.0) as u8, 1, 0, 255])
        }
    }

    /// Draws in NDC with w = 1 and z = 0.5, with an additive-coverage check via
    /// a no-depth trick: each triangle at a slightly nearer depth.
    fn draw(tris: &[[f32; 6]], w: u32, h: u32) -> Vec<u32> {
        let mut count = vec![0u32; (w * h) as usize];
        for (k, t) in tris.iter().enumerate() {
            let mut target = Target::new(w, h, [0, 0, 0, 0]);
            let z = 0.5 - k as f32 * 0.01;
            let pos: Vec<Vec3> = (0..3).map(|i| Vec3::new(t[2 * i], t[2 * i + 1], z)).collect();
            let vary = vec![[0.5f32]; 3];
            let draws = [Draw { first_index: 0, index_count: 3, material: 0 }];
            rasterize(&mut target, Mat4::IDENTITY, &pos, &vary, &[0, 1, 2], &draws, &Probe);
            for (c, px) in count.iter_mut().zip(&target.color) {
                *c += px[1] as u32;
            }
        }
        count
    }

    #[test]
    fn edge_conversion_matches_as_f32_below_two_to_the_51() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut cases = vec![0i64, 1, -1, (1 << 24) + 1, -(1 << 24) - 1, (1 << 50) - 1, -(1 << 50), (1 << 51) - 1];
        for _ in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            // magnitudes spread over every exponent up to 2^51
            cases.push(((x >> 13) as i64) >> (x % 52));
        }
        for e in cases {
            assert_eq!(edge_to_f32(e).to_bits(), (e as f32).to_bits(), "{e}");
        }
    }

    #[test]
    fn rounding_matches_the_library_round() {
        let mut v = vec![0.0f32, 0.5, -0.5, 1.5, -1.5, 2.5, 0.49999997, -0.49999997, 8388607.5, 8388608.0, 1e9, -1e9];
        let mut x = 0.123f32;
        for _ in 0..100_000 {
            x = (x * 3.7 + 0.31).fract();
            v.push((x - 0.5) * 4.0 * 4096.0 * 256.0);
            v.push(((x * 4096.0).round() + 0.5) * if x > 0.5 { 1.0 } else { -1.0 });
        }
        for a in v {
            assert_eq!(round_half_away(a), a.round() as i64, "{a}");
        }
    }

    /// Triangles from a few pixels to larger than the frame cover exactly the
    /// pixels whose centres the snapped edge functions put inside, evaluated
    /// pixel by pixel (the traversal's blocks, trivial accepts and rejects
    /// and lane masks change nothing).
    #[test]
    fn coverage_is_that_of_the_edge_functions_at_every_size() {
        let (w, h) = (200u32, 150u32);
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        for k in 0..400 {
            // up to 300 pixels: every vertex inside the guard band, so that no
            // clipped vertex is snapped anew
            let ext = [6.0f32, 40.0, 63.9, 64.1, 66.0, 130.0, 300.0][k % 7];
            let (cx, cy) = (rnd() * w as f32, rnd() * h as f32);
            let pts: [(f32, f32); 3] = std::array::from_fn(|_| (cx + (rnd() - 0.5) * ext, cy + (rnd() - 0.5) * ext));
            let ndc: Vec<Vec3> =
                pts.iter().map(|&(x, y)| Vec3::new(x / w as f32 * 2.0 - 1.0, 1.0 - y / h as f32 * 2.0, 0.5)).collect();
            let mut target = Target::new(w, h, [0, 0, 0, 0]);
            let draws = [Draw { first_index: 0, index_count: 3, material: 0 }];
            rasterize(&mut target, Mat4::IDENTITY, &ndc, &[[0.5f32]; 3], &[0, 1, 2], &draws, &Probe);
            // the reference: the same snapping, orientation and fill rule, per pixel
            let snap: Vec<(i64, i64)> = ndc
                .iter()
                .map(|p| {
                    let (x, y, _, _) = project(p.extend(1.0), w as f32, h as f32);
                    (x, y)
                })
                .collect();
            let (mut x, mut y) = ([snap[0].0, snap[1].0, snap[2].0], [snap[0].1, snap[1].1, snap[2].1]);
            let area = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
            if area < 0 {
                x.swap(1, 2);
                y.swap(1, 2);
            }
            for py in 0..h {
                for px in 0..w {
                    let (sx, sy) = (px as i64 * ONE + ONE / 2, py as i64 * ONE + ONE / 2);
                    let inside = area != 0
                        && (0..3).all(|i| {
                            let (a, b) = ((i + 1) % 3, (i + 2) % 3);
                            let (dx, dy) = (x[b] - x[a], y[b] - y[a]);
                            let bias = if (dy == 0 && dx > 0) || dy < 0 { 0 } else { -1 };
                            edge(x[a], y[a], x[b], y[b], sx, sy) + bias >= 0
                        });
                    let drawn = target.color[(py * w + px) as usize][1] == 1;
                    assert_eq!(drawn, inside, "triangle {k} (extent {ext} px) at pixel ({px}, {py})");
                }
            }
        }
    }

    #[test]
    fn shared_edges_are_covered_exactly_once() {
        // a square split along its diagonal, corners on pixel centres and on pixel corners
        for s in [0.5f32, 0.75, 0.6251] {
            let tris = [[-s, -s, s, -s, s, s], [-s, -s, s, s, -s, s]];
            let c = draw(&tris, 16, 16);
            assert!(c.iter().all(|&n| n <= 1), "double coverage at s = {s}");
            // and the whole interior is covered
            let covered = c.iter().filter(|&&n| n == 1).count();
            let both =
                draw(&[[-s, -s, s, -s, s, s], [-s, -s, s, s, -s, s]], 16, 16).iter().filter(|&&n| n == 1).count();
            assert_eq!(covered, both);
        }
        // a fan of triangles around a centre on a pixel centre: every pixel at most once
        let mut fan = Vec::new();
        let n = 7;
        for i in 0..n {
            let a0 = i as f32 / n as f32 * std::f32::consts::TAU;
            let a1 = (i + 1) as f32 / n as f32 * std::f32::consts::TAU;
            fan.push([1.0 / 16.0, 1.0 / 16.0, 0.9 * a0.cos(), 0.9 * a0.sin(), 0.9 * a1.cos(), 0.9 * a1.sin()]);
        }
        let c = draw(&fan, 16, 16);
        assert!(c.iter().all(|&n| n <= 1), "double coverage in the fan");
        assert!(c.iter().filter(|&&n| n == 1).count() > 100);
    }

    /// Colours a lane by its triangle's id (varying 0) and, when it writes
    /// depth, moves it by varying 1; counts the blocks, quads and lanes it
    /// shades and whether a block mixed keys. `LP`: it packs lanes.
    struct Ids<const DEPTH: bool, const PACK: bool, const LP: bool> {
        blocks: std::sync::atomic::AtomicUsize,
        quads: std::sync::atomic::AtomicUsize,
        lanes: std::sync::atomic::AtomicUsize,
        mixed: std::sync::atomic::AtomicBool,
    }
    impl<const DEPTH: bool, const PACK: bool, const LP: bool> BlockShader<2> for Ids<DEPTH, PACK, LP> {
        const WRITES_DEPTH: bool = DEPTH;
        const LANE_GRADS: Option<[usize; 2]> = if LP { Some([0, 1]) } else { None };
        fn shade_block(&self, b: &Block<2>, rgba: &mut [[u8; 4]; LANES], depth: &mut Lanes) {
            use std::sync::atomic::Ordering::Relaxed;
            self.blocks.fetch_add(1, Relaxed);
            self.lanes.fetch_add(b.live.count_ones() as usize, Relaxed);
            let mut key = None;
            for lane in 0..LANES {
                if b.live & (1 << lane) != 0 {
                    let id = b.v[0][lane].round() as u32;
                    rgba[lane] = [id as u8, (id >> 8) as u8, 7, 255];
                    depth[lane] = b.z[lane] + b.v[1][lane];
                    if key.is_some_and(|k| k != self.key(&[b.v[0][lane], 0.0])) {
                        self.mixed.store(true, Relaxed);
                    }
                    key = Some(self.key(&[b.v[0][lane], 0.0]));
                }
            }
            for q in 0..4 {
                self.quads.fetch_add(((b.live >> (4 * q)) & 0xf != 0) as usize, Relaxed);
            }
        }
        fn key(&self, v: &[f32; 2]) -> u32 {
            (v[0].round() as u32 / 16) % 3
        }
        fn packs_triangles(&self) -> bool {
            PACK
        }
    }

    /// Small overlapping triangles at scattered depths, each with its id
    /// (and, for programs that write depth, a depth offset) as varyings.
    fn confetti(n: usize) -> (Vec<Vec3>, Vec<[f32; 2]>, Vec<u32>) {
        let mut seed = 12345u32;
        let mut next = move || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let (mut pos, mut vary, mut idx) = (Vec::new(), Vec::new(), Vec::new());
        for id in 0..n {
            let (cx, cy, z) = (next() * 2.0 - 1.0, next() * 2.0 - 1.0, 0.2 + 0.6 * next());
            let off = (next() - 0.5) * 0.3;
            for _ in 0..3 {
                pos.push(Vec3::new(cx + (next() - 0.5) * 0.3, cy + (next() - 0.5) * 0.3, z));
                vary.push([id as f32, off]);
                idx.push(idx.len() as u32);
            }
        }
        (pos, vary, idx)
    }

    /// Triangles in several setup chunks and draws (a draw longer than a
    /// chunk and not a whole number of chunks, an empty one, one starting at
    /// an index that is not a multiple of 3, one with two indices past its
    /// last triangle), set up and binned chunk by chunk, draw the image of
    /// drawing them one by one: all at one depth, so that where they overlap
    /// the first drawn is seen. A deferred clear gives the image of a clear
    /// made first, also where nothing is drawn.
    fn chunks_keep_submission_order<const DEPTH: bool>() {
        let (mut pos, mut vary, tri_idx) = confetti(SETUP_CHUNK + 500);
        for (p, a) in pos.iter_mut().zip(&mut vary) {
            p.z = 0.5;
            a[1] = 0.0;
        }
        // one index in front, so that the draws after the first start at 3k + 1
        let idx: Vec<u32> = std::iter::once(0).chain(tri_idx.iter().copied()).collect();
        let (w, h) = (61, 47);
        let p = Ids::<DEPTH, true, false> { blocks: 0.into(), quads: 0.into(), lanes: 0.into(), mixed: false.into() };
        let d = |first: u32, count: u32| Draw { first_index: first, index_count: count, material: 0 };
        let long = SETUP_CHUNK as u32 + 200;
        let n = tri_idx.len() as u32 / 3;
        let draws = [
            d(1, 3 * long),
            d(1 + 3 * long, 0),
            d(1 + 3 * long, 3 * 50 + 2),
            d(1 + 3 * (long + 50), 3 * (n - long - 50)),
        ];
        let clear = [9, 8, 7, 6];
        let mut all = Target::deferred(w, h, clear);
        rasterize(&mut all, Mat4::IDENTITY, &pos, &vary, &idx, &draws, &p);
        let mut one = Target::new(w, h, clear);
        for t in 0..n {
            rasterize(&mut one, Mat4::IDENTITY, &pos, &vary, &idx, &[d(1 + 3 * t, 3)], &p);
        }
        assert!(all.color == one.color && all.depth == one.depth, "depth program: {DEPTH}");
        let cleared = all.color.iter().filter(|&&c| c == clear).count();
        assert!(cleared > 0 && cleared < all.color.len() / 2, "{cleared} pixels of the clear colour");
        // the order matters: drawn last first, the image differs
        let mut reversed = Target::new(w, h, clear);
        for t in (0..n).rev() {
            rasterize(&mut reversed, Mat4::IDENTITY, &pos, &vary, &idx, &[d(1 + 3 * t, 3)], &p);
        }
        assert!(reversed.color != one.color);
        assert_eq!(Target::deferred(3, 2, clear).into_rgba(), clear.repeat(6));
    }

    /// Set-up chunks hold every whole triangle once, in order, at most
    /// [`SETUP_CHUNK`] a chunk and all but the last full: many short draws
    /// share a chunk, a long one spans several.
    #[test]
    fn setup_chunks_pack_short_draws_and_split_long_ones() {
        let d = |m: usize, first: u32, tris: u32, extra: u32| Draw {
            first_index: first,
            index_count: 3 * tris + extra,
            material: m,
        };
        let mut draws: Vec<Draw> = (0..300).map(|k| d(k % 3, 7 + 6 * k as u32, 2, k as u32 % 3)).collect();
        draws.push(d(5, 1, 3 * SETUP_CHUNK as u32 + 10, 2));
        draws.push(d(6, 4, 0, 1));
        let chunks = setup_chunks(&draws);
        let got: Vec<(usize, usize)> =
            chunks.iter().flatten().flat_map(|&(m, i0, i1)| (i0..i1).step_by(3).map(move |i| (m, i))).collect();
        let want: Vec<(usize, usize)> = draws
            .iter()
            .flat_map(|d| (0..d.index_count as usize / 3).map(move |t| (d.material, d.first_index as usize + 3 * t)))
            .collect();
        assert_eq!(got, want);
        let sizes: Vec<usize> = chunks.iter().map(|c| c.iter().map(|p| (p.2 - p.1) / 3).sum()).collect();
        assert_eq!(sizes.len(), want.len().div_ceil(SETUP_CHUNK));
        assert!(sizes[..sizes.len() - 1].iter().all(|&n| n == SETUP_CHUNK), "{sizes:?}");
        assert!(chunks[0].len() > 200 && chunks.iter().all(|c| c.iter().all(|p| p.2 > p.1)));
    }

    #[test]
    fn chunks_keep_submission_order_with_and_without_program_depth() {
        chunks_keep_submission_order::<false>();
        chunks_keep_submission_order::<true>();
    }

    fn batching_matches_drawing_one_by_one<const DEPTH: bool, const PACK: bool, const LP: bool>() {
        let (pos, vary, idx) = confetti(400);
        let (w, h) = (61, 47);
        let program =
            || Ids::<DEPTH, PACK, LP> { blocks: 0.into(), quads: 0.into(), lanes: 0.into(), mixed: false.into() };
        // all at once: quads of several triangles share blocks
        let mut all = Target::new(w, h, [0, 0, 0, 0]);
        let draws = [Draw { first_index: 0, index_count: idx.len() as u32, material: 0 }];
        let p = program();
        rasterize(&mut all, Mat4::IDENTITY, &pos, &vary, &idx, &draws, &p);
        // one triangle per call: nothing can be packed
        let mut one = Target::new(w, h, [0, 0, 0, 0]);
        let q = program();
        for t in 0..idx.len() / 3 {
            let d = [Draw { first_index: 3 * t as u32, index_count: 3, material: 0 }];
            rasterize(&mut one, Mat4::IDENTITY, &pos, &vary, &idx, &d, &q);
        }
        assert!(all.color == one.color, "colours differ (writes depth: {DEPTH}, lanes packed: {LP})");
        assert!(all.depth.iter().zip(&one.depth).all(|(a, b)| a.to_bits() == b.to_bits()));
        use std::sync::atomic::Ordering::Relaxed;
        let (blocks, quads, lanes) = (p.blocks.load(Relaxed), p.quads.load(Relaxed), p.lanes.load(Relaxed));
        // lanes waiting in a batch have not yet written depth, so the early
        // test may pass a few more; never fewer
        let (alone, alone_lanes) = (q.quads.load(Relaxed), q.lanes.load(Relaxed));
        assert!(!p.mixed.load(Relaxed), "a block mixed program keys");
        if !PACK {
            // a program that records what it shades sees exactly the sequential lanes
            assert_eq!(lanes, alone_lanes, "lanes shaded without packing");
            if !LP {
                assert_eq!(quads, alone, "quads shaded without packing");
            }
            return;
        }
        assert!(
            lanes >= alone_lanes && lanes <= alone_lanes + alone_lanes / 20,
            "{lanes} lanes shaded packed, {alone_lanes} one by one"
        );
        let alone_blocks = q.blocks.load(Relaxed);
        if LP {
            // sixteen lanes a block but where the key changes or a band ends
            assert!(
                lanes >= 10 * blocks && blocks * 2 < alone_blocks,
                "lanes were not packed: {blocks} blocks for {lanes} lanes ({alone_blocks} blocks one by one)"
            );
        } else {
            assert!(quads >= alone && quads <= alone + alone / 20, "{quads} quads shaded packed, {alone} one by one");
            assert!(
                quads >= 3 * blocks && blocks * 4 < alone_blocks * 3,
                "quads were not packed: {blocks} blocks for {quads} quads ({alone_blocks} blocks one by one)"
            );
        }
        assert!(all.color.iter().filter(|c| c[2] == 7).count() > (w * h / 4) as usize, "too little drawn to compare");
    }

    /// Colours a lane by the screen derivatives of its two varyings: taken
    /// from [`Block::grad`] when it packs lanes (`LP`), else from its quad.
    struct Grads<const LP: bool>;
    impl<const LP: bool> BlockShader<2> for Grads<LP> {
        const LANE_GRADS: Option<[usize; 2]> = if LP { Some([1, 0]) } else { None };
        fn shade_block(&self, b: &Block<2>, rgba: &mut [[u8; 4]; LANES], _: &mut Lanes) {
            let mut own = b.clone();
            if !LP {
                own.fill_grads([1, 0]);
            }
            let g = &own.grad;
            for lane in 0..LANES {
                let h = g[0][0][lane].to_bits() ^ g[0][1][lane].to_bits().rotate_left(8);
                let h = h ^ g[1][0][lane].to_bits().rotate_left(16) ^ g[1][1][lane].to_bits().rotate_left(24);
                rgba[lane] = [h as u8, (h >> 8) as u8, (h >> 16) as u8 | 1, (h >> 24) as u8 | 1];
            }
        }
    }

    #[test]
    fn packed_lanes_carry_the_derivatives_of_their_quads() {
        let (mut pos, mut vary, idx) = confetti(300);
        // varyings that change across a triangle, non-linearly over the frame
        for (a, p) in vary.iter_mut().zip(&mut pos) {
            *a = [a[0] + 5.0 * p.x * p.y, 3.0 * p.y + p.x * p.x];
            // in front of the camera below, at distances 1 to 3
            *p = Vec3::new(p.x, p.y, -1.0 - 2.5 * p.z - 0.3 * p.x);
        }
        // a perspective view (as in the early-depth test), so that the
        // derivatives change within a triangle
        let r = FAR / (NEAR - FAR);
        let view_proj = Mat4::from_cols(
            Vec4::new(1.1, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 1.4, 0.0, 0.0),
            Vec4::new(0.0, 0.0, r, -1.0),
            Vec4::new(0.0, 0.0, r * NEAR, 0.0),
        );
        let draws = [Draw { first_index: 0, index_count: idx.len() as u32, material: 0 }];
        let mut quads = Target::new(64, 53, [0, 0, 0, 0]);
        rasterize(&mut quads, view_proj, &pos, &vary, &idx, &draws, &Grads::<false>);
        let mut lanes = Target::new(64, 53, [0, 0, 0, 0]);
        rasterize(&mut lanes, view_proj, &pos, &vary, &idx, &draws, &Grads::<true>);
        assert!(quads.color == lanes.color, "lane-packed derivatives differ from their quads'");
        let drawn: std::collections::HashSet<[u8; 4]> = quads.color.iter().filter(|c| c[3] != 0).copied().collect();
        assert!(drawn.len() > 500, "only {} distinct derivatives drawn", drawn.len());
    }

    /// A program that writes depth up to `MARGIN` nearer than its triangle
    /// (varying 1), as the NURBS program's exact point may lie: the early
    /// depth test, lane by lane and block by block, must cull only what the
    /// late test would reject.
    struct Nearer<const LP: bool> {
        quads: std::sync::atomic::AtomicUsize,
    }
    const NEAR: f32 = 0.5;
    const FAR: f32 = 50.0;
    const MARGIN: f32 = 0.4;
    impl<const LP: bool> BlockShader<2> for Nearer<LP> {
        const WRITES_DEPTH: bool = true;
        const LANE_GRADS: Option<[usize; 2]> = if LP { Some([0, 1]) } else { None };
        fn shade_block(&self, b: &Block<2>, rgba: &mut [[u8; 4]; LANES], depth: &mut Lanes) {
            let r = FAR / (NEAR - FAR);
            for lane in 0..LANES {
                if b.live & (1 << lane) != 0 {
                    let id = b.v[0][lane].round() as u32;
                    rgba[lane] = [id as u8, (id >> 8) as u8, 7, 255];
                    depth[lane] = r * (NEAR / (b.w[lane] - b.v[1][lane]) - 1.0);
                }
            }
            // lanes, for a program that packs them
            let n = if LP {
                b.live.count_ones() as usize
            } else {
                (0..4).filter(|q| (b.live >> (4 * q)) & 0xf != 0).count()
            };
            self.quads.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        }
    }

    #[test]
    fn early_depth_culls_only_what_the_late_test_rejects() {
        early_depth_culls_only_what_the_late_test_rejects_for::<false>();
        early_depth_culls_only_what_the_late_test_rejects_for::<true>();
    }

    fn early_depth_culls_only_what_the_late_test_rejects_for<const LP: bool>() {
        // a near wall over the left half, then small triangles at scattered
        // distances, some in front of it and most behind
        let mut seed = 777u32;
        let mut next = move || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let (mut pos, mut vary, mut idx) = (Vec::new(), Vec::new(), Vec::new());
        let mut tri = |p: [Vec3; 3], id: f32, off: f32| {
            idx.extend((0..3).map(|k| (pos.len() + k) as u32));
            pos.extend(p);
            vary.extend([[id, off]; 3]);
        };
        tri([Vec3::new(-3.0, -3.0, -2.0), Vec3::new(0.1, -3.0, -2.0), Vec3::new(0.1, 3.0, -2.0)], 1.0, 0.0);
        tri([Vec3::new(-3.0, -3.0, -2.0), Vec3::new(0.1, 3.0, -2.0), Vec3::new(-3.0, 3.0, -2.0)], 1.0, 0.0);
        for k in 0..600 {
            let d = 1.0 + 12.0 * next();
            let (cx, cy) = ((2.0 * next() - 1.0) * 0.8 * d, (2.0 * next() - 1.0) * 0.8 * d);
            let s = 0.08 * d;
            let c = Vec3::new(cx, cy, -d);
            let p = [c, c + Vec3::new(s, 0.3 * s, 0.2), c + Vec3::new(0.2 * s, s, -0.3)];
            tri(p, (k + 2) as f32, MARGIN * next());
        }
        // the camera's projection (depth r·(near/w − 1), r = far/(near − far)), looking down −z
        let r = FAR / (NEAR - FAR);
        let view_proj = Mat4::from_cols(
            Vec4::new(1.1, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 1.4, 0.0, 0.0),
            Vec4::new(0.0, 0.0, r, -1.0),
            Vec4::new(0.0, 0.0, r * NEAR, 0.0),
        );
        let (w, h) = (83, 64);
        let draws = [Draw { first_index: 0, index_count: idx.len() as u32, material: 0 }];
        let late = Nearer::<LP> { quads: 0.into() };
        let mut all = Target::new(w, h, [0, 0, 0, 0]);
        rasterize(&mut all, view_proj, &pos, &vary, &idx, &draws, &late);
        let early = Nearer::<LP> { quads: 0.into() };
        let mut culled = Target::new(w, h, [0, 0, 0, 0]);
        let e = EarlyDepth { margin: MARGIN, near: NEAR, far: FAR };
        rasterize_early(&mut culled, view_proj, &pos, &vary, &idx, &draws, &early, Some(e));
        assert!(all.color == culled.color, "the early test changed the image (lanes packed: {LP})");
        assert!(all.depth.iter().zip(&culled.depth).all(|(a, b)| a.to_bits() == b.to_bits()));
        use std::sync::atomic::Ordering::Relaxed;
        let (a, b) = (late.quads.load(Relaxed), early.quads.load(Relaxed));
        assert!(b * 4 < a * 3, "too little culled to test: {b} of {a} quads (lanes) shaded");
        assert!(all.color.iter().filter(|c| c[0] == 1).count() > (w * h / 4) as usize, "the wall is not drawn");
    }

    #[test]
    fn packed_quads_draw_as_triangles_one_by_one() {
        batching_matches_drawing_one_by_one::<false, true, false>();
        batching_matches_drawing_one_by_one::<true, true, false>();
        batching_matches_drawing_one_by_one::<false, false, false>();
        batching_matches_drawing_one_by_one::<true, false, false>();
    }

    #[test]
    fn packed_lanes_draw_as_triangles_one_by_one() {
        batching_matches_drawing_one_by_one::<false, true, true>();
        batching_matches_drawing_one_by_one::<true, true, true>();
        batching_matches_drawing_one_by_one::<false, false, true>();
        batching_matches_drawing_one_by_one::<true, false, true>();
    }

    #[test]
    fn top_left_rule_on_pixel_aligned_square() {
        // square from pixel-centre 2 to pixel-centre 6 (NDC on an 8x8 target):
        // left and top edges through centres are included, right and bottom not
        let c = |p: f32| p / 8.0 * 2.0 - 1.0; // pixel x → NDC x
        let (a, b) = (c(2.5), c(6.5));
        // NDC y is up: pixel row r has NDC 1 − (r + ½)/4
        let r = |p: f32| 1.0 - p / 8.0 * 2.0;
        let (ta, tb) = (r(2.5), r(6.5));
        let cnt = draw(&[[a, ta, b, ta, b, tb], [a, ta, b, tb, a, tb]], 8, 8);
        let covered: Vec<(usize, usize)> = (0..64).filter(|&i| cnt[i] == 1).map(|i| (i % 8, i / 8)).collect();
        assert_eq!(covered.len(), 16, "{covered:?}");
        assert!(covered.iter().all(|&(x, y)| (2..6).contains(&x) && (2..6).contains(&y)));
    }

    #[test]
    fn perspective_correct_interpolation() {
        // a triangle with w varying: varying = 0 at a near vertex, 1 at far ones;
        // at a pixel, the value must match the exact ray-plane intersection
        let mut target = Target::new(8, 8, [0, 0, 0, 0]);
        let pos = vec![Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
        // custom matrix: w = 1 + 3·(x+1)/2 via a projective map x → x, w → 1.5x + 2.5
        let m = Mat4::from_cols(
            Vec4::new(1.0, 0.0, 0.0, 1.5),
            Vec4::new(0.0, 1.0, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 1.0, 0.0),
            Vec4::new(0.0, 0.0, 0.5, 2.5),
        );
        let vary = vec![[0.0f32], [1.0], [0.0]];
        let draws = [Draw { first_index: 0, index_count: 3, material: 0 }];
        rasterize(&mut target, m, &pos, &vary, &[0, 1, 2], &draws, &Probe);
        // along the bottom pixel row, x_ndc = (px+½)/4 − 1 = X/w with X = x, w = 1.5x + 2.5
        // → x = 2.5·x_ndc / (1 − 1.5·x_ndc); varying = (x + 1)/2 on the bottom edge (y → −1)
        let row = 7usize;
        for px in 0..3usize {
            let c = target.color[row * 8 + px];
            if c[1] == 0 {
                continue;
            }
            let xn = (px as f32 + 0.5) / 4.0 - 1.0;
            let yn = 1.0 - (row as f32 + 0.5) / 4.0;
            // solve world (x, y) from NDC: x = 2.5 xn / (1 − 1.5 xn), y = yn (1.5 x + 2.5)
            let x = 2.5 * xn / (1.0 - 1.5 * xn);
            let _y = yn * (1.5 * x + 2.5);
            let expect = (x + 1.0) / 2.0;
            let got = c[0] as f32 / 255.0;
            assert!((got - expect).abs() <= 1.0 / 255.0, "pixel {px}: {got} vs {expect}");
        }
    }

    #[test]
    fn triangles_behind_the_eye_or_degenerate_are_skipped() {
        let mut target = Target::new(8, 8, [0, 0, 0, 0]);
        // all vertices at z < 0 (in front of near plane): clipped away
        let pos = vec![Vec3::new(-1.0, -1.0, -0.5), Vec3::new(1.0, -1.0, -0.5), Vec3::new(0.0, 1.0, -0.5)];
        let draws = [Draw { first_index: 0, index_count: 3, material: 0 }];
        rasterize(&mut target, Mat4::IDENTITY, &pos, &[[0.0]; 3], &[0, 1, 2], &draws, &Probe);
        // zero-area and NaN triangles
        let pos2 = vec![Vec3::new(0.0, 0.0, 0.5), Vec3::new(0.0, 0.0, 0.5), Vec3::new(f32::NAN, 0.0, 0.5)];
        rasterize(
            &mut target,
            Mat4::IDENTITY,
            &pos2,
            &[[0.0]; 3],
            &[0, 1, 2, 0, 1, 1],
            &[Draw { first_index: 0, index_count: 6, material: 0 }],
            &Probe,
        );
        assert!(target.color.iter().all(|c| c[1] == 0));
    }
}
