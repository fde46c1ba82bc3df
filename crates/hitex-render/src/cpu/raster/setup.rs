//! Triangle set-up: clipping against the near and far planes and the guard
//! band, snapping, integer edge functions, and the chunks of triangles set up
//! in parallel and binned into bands.

use super::*;

/// A clipped-polygon vertex: clip position and weights of the source triangle's vertices.
#[derive(Clone, Copy)]
pub(super) struct ClipVert {
    pub(super) clip: Vec4,
    pub(super) bary: Vec3,
}

/// A triangle ready for traversal.
pub(super) struct Setup<const K: usize> {
    pub(super) material: usize,
    /// The program's batch key of the triangle ([`BlockShader::key`]).
    pub(super) key: u32,
    /// Snapped vertices (fixed point).
    pub(super) x: [i64; 3],
    pub(super) y: [i64; 3],
    /// Edge bias: 0 for top-left edges, −1 otherwise (edge i is opposite vertex i).
    pub(super) bias: [i64; 3],
    pub(super) inv_area: f32,
    /// Screen-linear q = 1/w at vertex 0 and its differences to vertices 1 and 2.
    pub(super) q: [f32; 3],
    /// Screen-linear depth z/w, same form.
    pub(super) z: [f32; 3],
    /// Screen-linear varyings·q, same form.
    pub(super) va: [[f32; K]; 3],
    /// Pixel bounding box (inclusive min, exclusive max).
    pub(super) bx0: u32,
    pub(super) by0: u32,
    pub(super) bx1: u32,
    pub(super) by1: u32,
    pub(super) _k: std::marker::PhantomData<[f32; K]>,
}

/// Triangles per parallel task of the setup stage.
pub(super) const SETUP_CHUNK: usize = 512;

/// Whether a clip-space vertex lies inside every plane [`clip_polygon`] cuts by.
#[inline]
pub(super) fn inside_all(c: Vec4) -> bool {
    c.z >= 0.0
        && c.w - c.z >= 0.0
        && c.x + GUARD * c.w >= 0.0
        && GUARD * c.w - c.x >= 0.0
        && c.y + GUARD * c.w >= 0.0
        && GUARD * c.w - c.y >= 0.0
}

pub(super) fn clip_polygon(poly: &mut Vec<ClipVert>, scratch: &mut Vec<ClipVert>) {
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

/// The setup stage's chunks of about [`SETUP_CHUNK`] triangles each, in
/// submission order: each a list of `(material, first index, end index)`
/// pieces of whole triangles, so that a draw longer than a chunk spans
/// several and many short draws share one.
pub(super) fn setup_chunks(draws: &[Draw]) -> Vec<Vec<(usize, usize, usize)>> {
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
pub(super) struct SetupChunk<const K: usize> {
    pub(super) tris: Vec<Setup<K>>,
    /// Band `b`'s list is `items[start[b]..start[b + 1]]`.
    pub(super) start: Vec<u32>,
    pub(super) items: Vec<u32>,
}

impl<const K: usize> SetupChunk<K> {
    /// Bins `tris` into `bands` bands of [`BAND`] rows (a counting sort).
    pub(super) fn binned(tris: Vec<Setup<K>>, bands: usize) -> Self {
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
    pub(super) fn in_band(&self, b: usize) -> &[u32] {
        &self.items[self.start[b] as usize..self.start[b + 1] as usize]
    }
}

/// The conservative early test's constants (see [`EarlyDepth`]).
#[derive(Clone, Copy)]
pub(super) struct OccParams {
    pub(super) margin: f32,
    pub(super) near: f32,
    /// 1 / r, r = far / (near − far).
    pub(super) inv_r: f32,
}

/// A vertex after the vertex stage: its clip position and, when it lies
/// inside every clip plane, what the triangles sharing it need of it.
#[derive(Clone, Copy)]
pub(super) struct Post<const K: usize> {
    pub(super) clip: Vec4,
    /// Inside every plane [`clip_polygon`] cuts by (and finite).
    pub(super) inside: bool,
    /// Snapped screen position (fixed point).
    pub(super) x: i64,
    pub(super) y: i64,
    /// 1/w.
    pub(super) q: f32,
    /// Depth z/w.
    pub(super) z: f32,
    /// Varyings·q.
    pub(super) vq: [f32; K],
}

/// Snapped screen position, 1/w and depth of a clip-space position.
#[inline(always)]
pub(super) fn project(clip: Vec4, wf: f32, hf: f32) -> (i64, i64, f32, f32) {
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
pub(super) fn setup<const K: usize>(
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
pub(super) fn assemble<const K: usize>(
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
pub(super) fn round_half_away(v: f32) -> i64 {
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
pub(super) fn edge(ax: i64, ay: i64, bx: i64, by: i64, px: i64, py: i64) -> i64 {
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
pub(super) fn edge_to_f32(e: i64) -> f32 {
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 2^52 + 2^51
    (f64::from_bits((e as u64).wrapping_add(MAGIC.to_bits())) - MAGIC) as f32
}

/// The lane offsets (in pixels) of a block: quad `q` (left to right), lane
/// `l` of the quad ((0,0) (1,0) (0,1) (1,1)) is lane `4q + l`.
#[inline(always)]
pub(super) const fn lane_dx(lane: usize) -> i64 {
    ((lane / 4) * 2 + (lane & 1)) as i64
}
#[inline(always)]
pub(super) const fn lane_dy(lane: usize) -> i64 {
    ((lane >> 1) & 1) as i64
}
