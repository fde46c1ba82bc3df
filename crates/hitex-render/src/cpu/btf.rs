//! The BTF fragment program. Twin of `shaders/btf.wgsl`: same inputs (the
//! frame uniforms, the index map, the codebook in its layout), same steps in
//! the same order.
//!
//! Per fragment: renormalise N, U, V (N faces the viewer); the view and light
//! angles of the paper; their neighbouring samples on the angular grid; the
//! index map's four texels around T (4 index reads) with bilinear weights;
//! per index texel the hexa-linear interpolation over the angles through the
//! layout's reads ([`Codebook::corner`]); exposure, sRGB encoding.
//!
//! The program shades a rasterizer block of 16 lanes. The frame, both angle
//! pairs, their grid neighbours, the layout's walked combinations and the
//! filter's taps are lane vectors; the reads are gathers, one texel position
//! for all lanes at a time, from the codebook decoded to 16-bit linear
//! texels (one 64-bit word each, [`Codebook::linear_texels16`]). Every lane
//! reads, with indices clamped into the texture, so the gathers need no
//! branch; unlit and helper lanes are discarded afterwards. Taps of weight
//! zero are read as the hardware filter reads them, so that the loops have
//! the layout's fixed trip counts (combinations × taps = 16 per index texel).

// lane loops index several arrays by the same lane, as the lane code reads
#![allow(clippy::needless_range_loop)]

use super::raster::{Block, BlockShader};
use super::simd::{LANES, Lanes, V3, ddx, ddy, floor, lanes, whole_u32};
use crate::btf::{BtfFrame, BtfVertex, MAX_RENDER_THETA, PreparedBtf};
use glam::Vec3;
use hitex_core::btf::frames::acos;
use hitex_core::btf::layout::{Axis, FetchSink, HALF_UNIT, Half4, LinearTexel, ReadCounter, half_to_scaled_f32_bits};
use hitex_core::btf::{AngleLerps, AngularGrid, Codebook, angles};
use hitex_core::texture::ToneMap;

/// Varyings: world position (3), N (3), U (3), V (3), T (2).
pub const VARYINGS: usize = 14;

/// The varyings of a vertex, in the order of `VsOut` in the shader.
pub fn varyings(v: &BtfVertex) -> [f32; VARYINGS] {
    let (p, n, u, w, t) = (v.position, v.normal, v.tangent_u, v.tangent_v, v.uv);
    [p[0], p[1], p[2], n[0], n[1], n[2], u[0], u[1], u[2], w[0], w[1], w[2], t[0], t[1]]
}

/// The program: borrowed prepared data and one frame's uniforms.
pub struct BtfProgram<'a> {
    scene: &'a PreparedBtf,
    camera: Vec3,
    light: Vec3,
    exposure: f32,
    reads: ReadShape,
}

/// What the layout fixes about every pixel's reads.
struct ReadShape {
    /// The angular axes walked with two neighbours each (2..6 = θc φc θl φl).
    walk: [usize; 4],
    nwalk: usize,
    /// Per filter axis (tile x, tile y, layers): the angular axis it
    /// carries (none for u, v or an unused axis), its extent in texels, the
    /// texel offset of one step, and whether it wraps (φ layers).
    filter_axes: [(Option<usize>, u32, u32, bool); 3],
    u_on_x: bool,
    v_on_y: bool,
}

impl ReadShape {
    fn new(cb: &Codebook) -> Self {
        let spec = cb.layout.spec();
        let (walk, nwalk) = cb.layout.walked_axes();
        let angle = |a: Axis| a.is_angle().then_some(a as usize);
        let layer = cb.width * cb.height;
        Self {
            walk,
            nwalk,
            filter_axes: [
                (angle(spec.tile_x), cb.tile_w, 1, false),
                (angle(spec.tile_y), cb.tile_h, cb.width, false),
                (spec.depth.and_then(angle), cb.depth, layer, spec.depth.is_some_and(|a| a.is_phi())),
            ],
            u_on_x: spec.tile_x == Axis::U,
            v_on_y: spec.tile_y == Axis::V,
        }
    }
}

impl<'a> BtfProgram<'a> {
    /// The program for `scene` with uniforms `frame`.
    pub fn new(scene: &'a PreparedBtf, frame: &BtfFrame) -> Self {
        Self {
            scene,
            camera: Vec3::new(frame.camera[0], frame.camera[1], frame.camera[2]),
            light: Vec3::new(frame.light[0], frame.light[1], frame.light[2]),
            exposure: frame.light[3],
            reads: ReadShape::new(&scene.codebook),
        }
    }

    /// Shades one fragment in linear RGB, reporting its reads to `sink`
    /// (at MIP level 0).
    pub fn shade_linear<S: FetchSink>(&self, v: &[f32; VARYINGS], sink: &mut S) -> Vec3 {
        self.shade_linear_at(v, 0.0, sink)
    }

    /// [`BtfProgram::shade_linear`] at MIP level of detail `lod` (the
    /// index map's log₂ footprint, [`BtfProgram::lod_lanes`]): its two
    /// levels' index texels blended trilinearly.
    pub fn shade_linear_at<S: FetchSink>(&self, v: &[f32; VARYINGS], lod: f32, sink: &mut S) -> Vec3 {
        let at = |i: usize| Vec3::new(v[i], v[i + 1], v[i + 2]);
        let p = at(0);
        // per-pixel frame; the normal faces the viewer
        let mut n = at(3).normalize_or(Vec3::Z);
        let u = at(6).normalize_or(Vec3::X);
        let w = at(9).normalize_or(Vec3::Y);
        if n.dot(self.camera - p) < 0.0 {
            n = -n;
        }
        // light below the surface: no light
        if n.dot(self.light - p) <= 0.0 {
            return Vec3::ZERO;
        }
        // view and light angles, their neighbouring samples
        let (tc, pc) = angles(p, n, u, w, self.camera);
        let (tl, pl) = angles(p, n, u, w, self.light);
        let g = &self.scene.grid;
        let l = AngleLerps { tc: g.lerp_theta(tc), pc: g.lerp_phi(pc), tl: g.lerp_theta(tl), pl: g.lerp_phi(pl) };
        // index map: four texels around T, bilinear weights (4 index reads),
        // at the level pair of `lod` when MIP mapped
        let cb: &Codebook = &self.scene.codebook;
        let (l0, l1, t) = self.level_pair(lod);
        let mut corners = Vec::with_capacity(8);
        for (level, lw) in [(l0, 1.0 - t), (l1, t)] {
            if lw == 0.0 && level == l1 {
                continue;
            }
            let map = self.scene.mip.get(level).unwrap_or(&self.scene.index);
            let (x0, x1, fx) = index_taps(v[12], map.width);
            let (y0, y1, fy) = index_taps(v[13], map.height);
            for (x, y, w) in [
                (x0, y0, (1.0 - fx) * (1.0 - fy)),
                (x1, y0, fx * (1.0 - fy)),
                (x0, y1, (1.0 - fx) * fy),
                (x1, y1, fx * fy),
            ] {
                corners.push((map.get(x, y), w * lw));
            }
        }
        let mut acc = Vec3::ZERO;
        if let Some(p) = &self.scene.pca {
            acc = self.pca_pixel(p, &corners, &l, sink);
        } else if S::COUNTS {
            for (e, wgt) in corners {
                // hexa-linear over the angles through the layout's reads
                acc += cb.corner(e[0] as u32, e[1] as u32, &l, sink) * wgt;
            }
        } else {
            // the same reads with the per-pixel invariants hoisted
            let plan = cb.plan(&l);
            let mut a4 = glam::Vec4::ZERO;
            let half: &[Half4] = bytemuck::cast_slice(&cb.half);
            for (e, wgt) in corners {
                let (su, sv) = (e[0] as u32, e[1] as u32);
                a4 += if cb.is_hdr() {
                    cb.corner_planned_linear(&plan, su, sv, half)
                } else {
                    cb.corner_planned_linear(&plan, su, sv, &self.scene.linear)
                } * wgt;
            }
            acc = a4.truncate();
        }
        acc * self.exposure
    }

    /// The local-PCA twin of the reads of one pixel ([`BtfProgram::pca_lanes`]
    /// on one lane): per cluster among the index texels, in order of first
    /// appearance, their coefficients blended, then the cluster's basis
    /// images read once each.
    fn pca_pixel<S: FetchSink>(
        &self,
        p: &crate::btf::PcaTables,
        corners: &[([u16; 2], f32)],
        l: &AngleLerps,
        sink: &mut S,
    ) -> Vec3 {
        let cb = &self.scene.codebook;
        let k = p.components as usize;
        let plan = (!S::COUNTS).then(|| cb.plan(l));
        let half: &[Half4] = bytemuck::cast_slice(&cb.half);
        let texel = |e: [u16; 2]| p.texel(e[0] as u32, e[1] as u32).min(p.cluster.len() - 1);
        let mut done = vec![false; corners.len()];
        let mut acc = glam::Vec4::ZERO;
        for q in 0..corners.len() {
            if done[q] {
                continue;
            }
            let c = p.cluster[texel(corners[q].0)];
            let mut bw = [0f32; 1 + hitex_core::btf::pca::MAX_PCA_COMPONENTS];
            for r in q..corners.len() {
                let t = texel(corners[r].0);
                if !done[r] && p.cluster[t] == c {
                    done[r] = true;
                    let w = corners[r].1;
                    bw[0] += w;
                    for j in 0..k {
                        bw[j + 1] += w * p.coefs[t * k + j];
                    }
                }
            }
            for (j, &b) in bw.iter().enumerate().take(k + 1) {
                let v = match &plan {
                    Some(plan) => cb.corner_planned_linear(plan, j as u32, c, half),
                    None => cb.corner(j as u32, c, l, sink).extend(0.0),
                };
                acc += v * b;
            }
        }
        acc.truncate()
    }

    /// The MIP level pair of a level of detail and the second's weight
    /// (level 0 alone without MIP mapping or when magnified).
    #[inline(always)]
    fn level_pair(&self, lod: f32) -> (usize, usize, f32) {
        let top = self.scene.mip_levels() - 1;
        let lod = if lod.is_nan() { 0.0 } else { lod.clamp(0.0, top as f32) };
        let l0 = floor(lod);
        let k = l0 as usize;
        (k, (k + 1).min(top), lod - l0)
    }

    /// The level of detail of a block's lanes: log₂ of the larger screen
    /// derivative of the index-map coordinates, in level-0 texels (seed 001,
    /// eq. 2, the Vulkan ρ), from the fine derivatives within each quad.
    #[inline(always)]
    pub fn lod_lanes(&self, v: &[Lanes; VARYINGS]) -> Lanes {
        let (w, h) = (self.scene.index.width as f32, self.scene.index.height as f32);
        let (ux, uy, vx, vy) = (ddx(&v[12]), ddy(&v[12]), ddx(&v[13]), ddy(&v[13]));
        lanes!(|i| {
            let (a, b, c, d) = (ux[i] * w, vx[i] * h, uy[i] * w, vy[i] * h);
            let rho = (a * a + b * b).max(c * c + d * d).sqrt();
            if rho.is_finite() && rho > 0.0 { rho.log2() } else { 0.0 }
        })
    }

    /// A block's 16 lanes in linear RGB (R, G, B lanes): the same steps as
    /// [`BtfProgram::shade_linear`] on lane vectors — the per-pixel frame,
    /// both angle pairs, their neighbours on the angular grid, the walked
    /// combinations and the filter's taps — then per lane the reads. Lanes
    /// not in `live` (and unlit ones) are left black.
    #[inline(always)]
    pub fn shade_lanes(&self, v: &[Lanes; VARYINGS], live: u16) -> [Lanes; 3] {
        let at = |i: usize| V3 { x: v[i], y: v[i + 1], z: v[i + 2] };
        let p = at(0);
        // per-pixel frame; the normal faces the viewer
        let n = normalize_or(&at(3), Vec3::Z);
        let u = normalize_or(&at(6), Vec3::X);
        let w = normalize_or(&at(9), Vec3::Y);
        let to_cam = sub_from(self.camera, &p);
        let ndc = n.dot(&to_cam);
        let flip = lanes!(|i| if ndc[i] < 0.0 { -1.0 } else { 1.0 });
        let n =
            V3 { x: lanes!(|i| n.x[i] * flip[i]), y: lanes!(|i| n.y[i] * flip[i]), z: lanes!(|i| n.z[i] * flip[i]) };
        // light below the surface: no light
        let ndl = n.dot(&sub_from(self.light, &p));
        let mut lit = 0u16;
        for i in 0..LANES {
            lit |= ((ndl[i] > 0.0) as u16) << i;
        }
        lit &= live;
        let mut out = [[0.0; LANES]; 3];
        if lit == 0 {
            return out;
        }
        // view and light angles, their neighbouring samples (axes θc φc θl φl)
        let (tc, pc) = angles_lanes(&p, &n, &u, &w, self.camera);
        let (tl, pl) = angles_lanes(&p, &n, &u, &w, self.light);
        let g = &self.scene.grid;
        let l = [lerp_theta(g, &tc), lerp_phi(g, &pc), lerp_theta(g, &tl), lerp_phi(g, &pl)];
        match (self.reads.nwalk, self.scene.is_hdr()) {
            (4, false) => self.read_lanes::<16, 1, false>(v, lit, &l, &mut out),
            (3, false) => self.read_lanes::<8, 2, false>(v, lit, &l, &mut out),
            (2, false) => self.read_lanes::<4, 4, false>(v, lit, &l, &mut out),
            (_, false) => self.read_lanes::<2, 8, false>(v, lit, &l, &mut out),
            (4, true) => self.read_lanes::<16, 1, true>(v, lit, &l, &mut out),
            (3, true) => self.read_lanes::<8, 2, true>(v, lit, &l, &mut out),
            (2, true) => self.read_lanes::<4, 4, true>(v, lit, &l, &mut out),
            (_, true) => self.read_lanes::<2, 8, true>(v, lit, &l, &mut out),
        }
        out
    }

    /// The reads of the lit lanes: per lane, four index texels, each the
    /// `NC` walked combinations × the filter's `NT` taps of one sample
    /// texel (taps of weight zero read too, as the hardware filter does).
    /// `HDR`: the texels are [`Half4`] words (their weights carry the unit
    /// 2¹¹², so that no product is subnormal), else 16-bit fixed point.
    #[inline(always)]
    fn read_lanes<const NC: usize, const NT: usize, const HDR: bool>(
        &self,
        v: &[Lanes; VARYINGS],
        lit: u16,
        l: &[LaneLerp; 4],
        out: &mut [Lanes; 3],
    ) {
        let r = &self.reads;
        let cb: &Codebook = &self.scene.codebook;
        // walked combinations: angular tile-index share and weight per lane
        let mut ck = [[0u32; LANES]; NC];
        let mut cw = [[1.0f32; LANES]; NC];
        for c in 0..NC {
            for (bit, &a) in r.walk[..r.nwalk].iter().enumerate() {
                let ax = &l[a - 2];
                let stride = cb.strides[a];
                let hi = c & (1 << bit) != 0;
                for i in 0..LANES {
                    let (idx, wi) = if hi { (ax.i1[i], ax.t[i]) } else { (ax.i0[i], 1.0 - ax.t[i]) };
                    ck[c][i] += idx * stride;
                    cw[c][i] *= wi;
                }
            }
        }
        // the filter's taps inside a tile: texel offset and weight per lane
        let mut to = [[0u32; LANES]; NT];
        let mut tw = [[1.0f32; LANES]; NT];
        let mut n = 1;
        for (axis, extent, scale, wrap) in r.filter_axes {
            let Some(a) = axis else { continue };
            let ax = &l[a - 2];
            let mut i0 = [0u32; LANES];
            let mut i1 = [0u32; LANES];
            let mut f = [0.0f32; LANES];
            for i in 0..LANES {
                let c = ax.coord[i];
                let fl = floor(c);
                f[i] = c - fl;
                let k = whole_u32(fl).min(extent - 1);
                i0[i] = k;
                // k < extent: wrapping is one comparison, not a division
                i1[i] = if k + 1 < extent {
                    k + 1
                } else if wrap {
                    0
                } else {
                    k
                };
            }
            // taps so far take the first neighbour; their copies the second
            for t in 0..n {
                for i in 0..LANES {
                    to[t + n][i] = to[t][i] + i1[i] * scale;
                    tw[t + n][i] = tw[t][i] * f[i];
                    to[t][i] += i0[i] * scale;
                    tw[t][i] *= 1.0 - f[i];
                }
            }
            n *= 2;
        }
        debug_assert_eq!(n, NT);
        let idx = &self.scene.index;
        // index map: four texels around T per lane, bilinear weights; with
        // MIP mapping four per level of the lane's pair (8 when a lane blends)
        let mut at = [[0u32; LANES]; 8];
        let mut wgt = [[0.0f32; LANES]; 8];
        let (entries, nq): (&[u32], usize) = if self.scene.mip.len() > 1 {
            let lod = self.lod_lanes(v);
            let mut blend = false;
            for i in 0..LANES {
                let (l0, l1, t) = self.level_pair(lod[i]);
                blend |= t > 0.0 && lit & (1 << i) != 0;
                for (s, (level, lw)) in [(l0, 1.0 - t), (l1, t)].into_iter().enumerate() {
                    let map = &self.scene.mip[level];
                    let base = self.scene.mip_offsets[level];
                    let (x0, x1, fx) = index_taps(v[12][i], map.width);
                    let (y0, y1, fy) = index_taps(v[13][i], map.height);
                    let (r0, r1) = (base + y0 * map.width, base + y1 * map.width);
                    let q = 4 * s;
                    at[q][i] = r0 + x0;
                    at[q + 1][i] = r0 + x1;
                    at[q + 2][i] = r1 + x0;
                    at[q + 3][i] = r1 + x1;
                    wgt[q][i] = (1.0 - fx) * (1.0 - fy) * lw;
                    wgt[q + 1][i] = fx * (1.0 - fy) * lw;
                    wgt[q + 2][i] = (1.0 - fx) * fy * lw;
                    wgt[q + 3][i] = fx * fy * lw;
                }
            }
            (&self.scene.mip_entries, if blend { 8 } else { 4 })
        } else {
            let (x0, x1, fx) = index_taps_lanes(&v[12], idx.width);
            let (y0, y1, fy) = index_taps_lanes(&v[13], idx.height);
            for i in 0..LANES {
                let (x0, x1, fx, y0, y1, fy) = (x0[i], x1[i], fx[i], y0[i], y1[i], fy[i]);
                let (r0, r1) = (y0 * idx.width, y1 * idx.width);
                at[0][i] = r0 + x0;
                at[1][i] = r0 + x1;
                at[2][i] = r1 + x0;
                at[3][i] = r1 + x1;
                wgt[0][i] = (1.0 - fx) * (1.0 - fy);
                wgt[1][i] = fx * (1.0 - fy);
                wgt[2][i] = (1.0 - fx) * fy;
                wgt[3][i] = fx * fy;
            }
            (bytemuck::cast_slice(&idx.entries), 4)
        };
        let texels: &[u64] = if HDR { &cb.half } else { &self.scene.linear };
        if entries.is_empty() || texels.is_empty() {
            return;
        }
        // k / cols as a multiply and a shift, exact for every k below the
        // tile count (m = ⌈2^s / cols⌉ with 2^s ≥ tile count × cols: the
        // excess k·(m − 2^s/cols)/2^s stays below 1/cols); lanes that read
        // nothing may hold larger k, whose quotient only has to stay in u64
        // (m < 2^32) and whose index is clamped below
        let (magic, magic_shift) = div_magic(cb.tile_cols, cb.tile_count);
        let reads = LaneReads::<NC, NT, HDR> {
            ck: &ck,
            cw: &cw,
            to: &to,
            tw: &tw,
            texels,
            // a u32 sum cannot pass u32::MAX: the clamp runs on 32-bit lanes
            last_texel: (texels.len() - 1).min(u32::MAX as usize) as u32,
            tile_step: cb.tile_h * cb.width,
            tile_w: cb.tile_w,
            cols: cb.tile_cols,
            magic,
            magic_shift,
        };
        // indices clamped to the last element need no bounds check
        let last_entry = entries.len() - 1;
        let width = cb.width;
        let (su_on_x, sv_on_y) = (r.u_on_x as u32, r.v_on_y as u32);
        let mut acc = [[0.0f32; LANES]; 3];
        if let Some(p) = &self.scene.pca {
            self.pca_lanes(p, &reads, entries, &at, &wgt, nq, lit, &mut acc);
        } else {
            // every lane reads (clamped indices), so that the reads are gathers
            for q in 0..nq {
                // the index texel: sample texel (su, sv) (one read)
                let mut key = [0u32; LANES];
                let mut shift = [0u32; LANES];
                for i in 0..LANES {
                    let e = entries[(at[q][i] as usize).min(last_entry)];
                    let (su, sv) = (e & 0xffff, e >> 16);
                    key[i] = su * cb.strides[0] + sv * cb.strides[1];
                    shift[i] = sv * sv_on_y * width + su * su_on_x;
                }
                // hexa-linear over the angles through the layout's reads
                let corner = reads.corner(&key, &shift);
                for ch in 0..3 {
                    for i in 0..LANES {
                        acc[ch][i] += corner[ch][i] * wgt[q][i];
                    }
                }
            }
        }
        let scale = if HDR { self.exposure } else { self.exposure * <u64 as LinearTexel>::UNIT };
        for ch in 0..3 {
            for i in 0..LANES {
                out[ch][i] = if lit & (1 << i) != 0 { acc[ch][i] * scale } else { 0.0 };
            }
        }
    }

    /// The reads of a local-PCA codebook for the lit lanes: per lane, the
    /// clusters of its `nq` index texels in order of first appearance; per
    /// cluster the coefficients of its index texels blended by their
    /// weights, then every basis image of that cluster read once (the same
    /// hexa-linear reads as a raw codebook's, at sample texel (j, cluster))
    /// and weighted by the blended coefficient j (1 for the mean). A pass
    /// runs while some lane has index texels left; lanes with none read
    /// with zero weights.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn pca_lanes<const NC: usize, const NT: usize, const HDR: bool>(
        &self,
        p: &crate::btf::PcaTables,
        reads: &LaneReads<'_, NC, NT, HDR>,
        entries: &[u32],
        at: &[[u32; LANES]; 8],
        wgt: &[[f32; LANES]; 8],
        nq: usize,
        lit: u16,
        acc: &mut [Lanes; 3],
    ) {
        let cb = &self.scene.codebook;
        let r = &self.reads;
        let k = p.components as usize;
        let last_entry = entries.len() - 1;
        let last_texel = p.cluster.len() - 1;
        // each index texel's sample texel, cluster
        let mut texel = [[0usize; LANES]; 8];
        let mut cl = [[0u32; LANES]; 8];
        for q in 0..nq {
            for i in 0..LANES {
                let e = entries[(at[q][i] as usize).min(last_entry)];
                let t = p.texel(e & 0xffff, e >> 16).min(last_texel);
                texel[q][i] = t;
                cl[q][i] = p.cluster[t];
            }
        }
        let mut pending = [0u16; 8];
        for pq in pending.iter_mut().take(nq) {
            *pq = lit;
        }
        let (su_on_x, sv_on_y) = (r.u_on_x as u32, r.v_on_y as u32);
        loop {
            // each lane's cluster for this pass: that of its first pending index texel
            let mut target = [0u32; LANES];
            let mut any = 0u16;
            for q in (0..nq).rev() {
                for i in 0..LANES {
                    if pending[q] & (1 << i) != 0 {
                        target[i] = cl[q][i];
                    }
                }
                any |= pending[q];
            }
            if any == 0 {
                return;
            }
            // the coefficients of the pending index texels of that cluster, blended
            let mut bw = [[0.0f32; LANES]; 1 + hitex_core::btf::pca::MAX_PCA_COMPONENTS];
            for q in 0..nq {
                for i in 0..LANES {
                    if pending[q] & (1 << i) != 0 && cl[q][i] == target[i] {
                        pending[q] &= !(1 << i);
                        let w = wgt[q][i];
                        bw[0][i] += w;
                        let a = &p.coefs[texel[q][i] * k..(texel[q][i] + 1) * k];
                        for j in 0..k {
                            bw[j + 1][i] += w * a[j];
                        }
                    }
                }
            }
            // the cluster's basis images at the pixel's angles
            for (j, bj) in bw.iter().enumerate().take(k + 1) {
                let mut key = [0u32; LANES];
                let mut shift = [0u32; LANES];
                for i in 0..LANES {
                    key[i] = j as u32 * cb.strides[0] + target[i] * cb.strides[1];
                    shift[i] = target[i] * sv_on_y * cb.width + j as u32 * su_on_x;
                }
                let corner = reads.corner(&key, &shift);
                for ch in 0..3 {
                    for i in 0..LANES {
                        acc[ch][i] += corner[ch][i] * bj[i];
                    }
                }
            }
        }
    }

    /// Reads per fragment at these varyings (texture instructions, texels).
    pub fn count_reads(&self, v: &[f32; VARYINGS]) -> ReadCounter {
        let mut c = ReadCounter::default();
        self.shade_linear(v, &mut c);
        c
    }
}

/// The multiplier m and shift s with ⌊k·m / 2^s⌋ = ⌊k / d⌋ for every
/// k < `bound` (m = ⌈2^s / d⌉, 2^s the least power of two ≥ bound · d); m
/// stays below 2^32 while bound < 2^31, so k·m of any u32 k fits a u64.
fn div_magic(d: u32, bound: u32) -> (u64, u32) {
    let d = d.max(1) as u64;
    let need = (bound.max(1) as u64) * d;
    let s = (64 - (need - 1).leading_zeros()).min(63);
    ((1u64 << s).div_ceil(d), s)
}

/// What a block's codebook reads share: the walked combinations' tile
/// shares and weights, the filter's tap offsets and weights, the texels and
/// the tile arithmetic.
struct LaneReads<'a, const NC: usize, const NT: usize, const HDR: bool> {
    ck: &'a [[u32; LANES]; NC],
    cw: &'a [[f32; LANES]; NC],
    to: &'a [[u32; LANES]; NT],
    tw: &'a [[f32; LANES]; NT],
    texels: &'a [u64],
    last_texel: u32,
    tile_step: u32,
    tile_w: u32,
    cols: u32,
    /// k / cols as a multiply and a shift ([`div_magic`]).
    magic: u64,
    magic_shift: u32,
}

impl<const NC: usize, const NT: usize, const HDR: bool> LaneReads<'_, NC, NT, HDR> {
    /// The hexa-linear interpolation over the angles, through the layout's
    /// reads, of the sample texel whose tile share is `key` and in-tile
    /// offset `shift`, per lane (RGB lanes, in texel units). `HDR`: the
    /// texels are [`Half4`] words (their weights carry the unit 2¹¹², so
    /// that no product is subnormal), else 16-bit fixed point.
    #[inline(always)]
    fn corner(&self, key: &[u32; LANES], shift: &[u32; LANES]) -> [Lanes; 3] {
        let mut corner = [[0.0f32; LANES]; 3];
        for c in 0..NC {
            let mut base = [0u32; LANES];
            for i in 0..LANES {
                let k = self.ck[c][i].wrapping_add(key[i]);
                let row = ((k as u64 * self.magic) >> self.magic_shift) as u32;
                base[i] = row
                    .wrapping_mul(self.tile_step)
                    .wrapping_add(k.wrapping_sub(row.wrapping_mul(self.cols)).wrapping_mul(self.tile_w))
                    .wrapping_add(shift[i]);
            }
            for t in 0..NT {
                let mut px = [0u64; LANES];
                for i in 0..LANES {
                    px[i] = self.texels[(base[i].wrapping_add(self.to[t][i])).min(self.last_texel) as usize];
                }
                if HDR {
                    let h = |p: u64, s: u32| f32::from_bits(half_to_scaled_f32_bits((p >> s) as u16));
                    for i in 0..LANES {
                        let w = self.cw[c][i] * self.tw[t][i] * HALF_UNIT;
                        corner[0][i] += h(px[i], 0) * w;
                        corner[1][i] += h(px[i], 16) * w;
                        corner[2][i] += h(px[i], 32) * w;
                    }
                } else {
                    for i in 0..LANES {
                        let w = self.cw[c][i] * self.tw[t][i];
                        corner[0][i] += (px[i] & 0xffff) as i32 as f32 * w;
                        corner[1][i] += ((px[i] >> 16) & 0xffff) as i32 as f32 * w;
                        corner[2][i] += ((px[i] >> 32) & 0xffff) as i32 as f32 * w;
                    }
                }
            }
        }
        corner
    }
}

/// The two index texels around texture coordinate `t` (index-map repeats)
/// on a wrapping axis of `size` texels, and the weight of the second.
#[inline(always)]
pub fn index_taps(t: f32, size: u32) -> (u32, u32, f32) {
    let t = if t.is_finite() { t.clamp(-1.0e6, 1.0e6) } else { 0.0 };
    let x = t * size as f32 - 0.5;
    let f0 = floor(x);
    let n = size as i64;
    let i0 = f0 as i64;
    // inside the map (the common case) without a division
    let wrap = |i: i64| if (0..n).contains(&i) { i } else { i.rem_euclid(n) };
    (wrap(i0) as u32, wrap(i0 + 1) as u32, x - f0)
}

/// [`index_taps`] on lanes: the wrap by a float remainder with one
/// correction each way (exact while |t·size| < 2²⁴); lanes beyond, where the
/// float product itself is no longer exact, take the integer path.
#[inline(always)]
fn index_taps_lanes(t: &Lanes, size: u32) -> ([u32; LANES], [u32; LANES], Lanes) {
    let n = size as f32;
    let mut i0 = [0u32; LANES];
    let mut i1 = [0u32; LANES];
    let mut f = [0.0f32; LANES];
    let mut far = false;
    for i in 0..LANES {
        let ti = if t[i].is_finite() { t[i].clamp(-1.0e6, 1.0e6) } else { 0.0 };
        let x = ti * n - 0.5;
        let f0 = floor(x);
        far |= f0.abs() >= 16_777_216.0;
        let mut r = f0 - n * floor(f0 / n);
        r = if r < 0.0 { r + n } else { r };
        r = if r >= n { r - n } else { r };
        let k = whole_u32(r).min(size - 1);
        i0[i] = k;
        i1[i] = if k + 1 < size { k + 1 } else { 0 };
        f[i] = x - f0;
    }
    if far {
        for i in 0..LANES {
            (i0[i], i1[i], f[i]) = index_taps(t[i], size);
        }
    }
    (i0, i1, f)
}

impl BlockShader<VARYINGS> for BtfProgram<'_> {
    #[inline(always)]
    fn shade_block(&self, b: &Block<VARYINGS>, rgba: &mut [[u8; 4]; LANES], _depth: &mut Lanes) {
        let c = self.shade_lanes(&b.v, b.live);
        // one loop per tone map, the map inlined into it
        match self.scene.tone_map {
            ToneMap::None => encode_lanes(&c, b.live, rgba, |x| x),
            ToneMap::Reinhard => encode_lanes(&c, b.live, rgba, |x| ToneMap::Reinhard.apply(x)),
            ToneMap::Aces => encode_lanes(&c, b.live, rgba, |x| ToneMap::Aces.apply(x)),
        }
    }
}

/// The live lanes of linear RGB `c`, tone-mapped by `tone` and sRGB-encoded
/// (all lanes encoded as one lane loop a channel, [`super::simd::encode_rgb`]).
#[inline(always)]
fn encode_lanes(c: &[Lanes; 3], live: u16, rgba: &mut [[u8; 4]; LANES], tone: impl Fn(f32) -> f32) {
    let enc = hitex_core::texture::srgb_encoder();
    let toned = [lanes!(|i| tone(c[0][i])), lanes!(|i| tone(c[1][i])), lanes!(|i| tone(c[2][i]))];
    let codes = super::simd::encode_rgb(enc, &toned);
    for i in 0..LANES {
        if live & (1 << i) != 0 {
            rgba[i] = codes[i];
        }
    }
}

/// `pc − p` per lane.
#[inline(always)]
fn sub_from(pc: Vec3, p: &V3) -> V3 {
    V3 { x: lanes!(|i| pc.x - p.x[i]), y: lanes!(|i| pc.y - p.y[i]), z: lanes!(|i| pc.z - p.z[i]) }
}

/// Lane-wise `normalize_or(fallback)` (as glam's: zero, infinite or NaN
/// lengths take the fallback).
#[inline(always)]
fn normalize_or(v: &V3, fallback: Vec3) -> V3 {
    let d = v.dot(v);
    let mut o = V3::splat(fallback);
    for i in 0..LANES {
        let rcp = 1.0 / d[i].sqrt();
        if rcp.is_finite() && rcp != 0.0 {
            o.x[i] = v.x[i] * rcp;
            o.y[i] = v.y[i] * rcp;
            o.z[i] = v.z[i] * rcp;
        }
    }
    o
}

/// [`hitex_core::btf::angles`] on a block's lanes (the steps of its
/// four-lane twin `angles4`, in the same order).
#[inline(always)]
fn angles_lanes(p: &V3, n: &V3, u: &V3, v: &V3, pc: Vec3) -> (Lanes, Lanes) {
    use std::f32::consts::{FRAC_PI_2, PI, TAU};
    let c = sub_from(pc, p);
    let len = lanes!(|i| (c.x[i] * c.x[i] + c.y[i] * c.y[i] + c.z[i] * c.z[i]).sqrt());
    let c1 = V3 { x: lanes!(|i| c.x[i] / len[i]), y: lanes!(|i| c.y[i] / len[i]), z: lanes!(|i| c.z[i] / len[i]) };
    // θ = acos(C′·N)
    let s = c1.dot(n);
    let theta = lanes!(|i| acos(s[i].clamp(-1.0, 1.0)));
    // R = N × C′, φ = acos(U·R′) − π/2
    let r = n.cross(&c1);
    let rl = lanes!(|i| (r.x[i] * r.x[i] + r.y[i] * r.y[i] + r.z[i] * r.z[i]).sqrt());
    let r1 = V3 { x: lanes!(|i| r.x[i] / rl[i]), y: lanes!(|i| r.y[i] / rl[i]), z: lanes!(|i| r.z[i] / rl[i]) };
    let t = u.dot(&r1);
    let sense = n.cross(u).dot(v);
    let side = c1.dot(u);
    let mut th = [0.0; LANES];
    let mut ph = [0.0; LANES];
    for i in 0..LANES {
        let mut phi = acos(t[i].clamp(-1.0, 1.0)) - FRAC_PI_2;
        // correction with V: sense of rotation, then the far half circle
        if sense[i] < 0.0 {
            phi = -phi;
        }
        if side[i] < 0.0 {
            phi = PI - phi;
        }
        phi -= TAU * floor(phi / TAU);
        // NaN fails every comparison: degenerate lanes take (0, 0)
        let good = len[i] > 0.0 && len[i].is_finite() && !theta[i].is_nan();
        let has_r = rl[i] > 1e-7 && !phi.is_nan();
        th[i] = if good { theta[i] } else { 0.0 };
        ph[i] = if good && has_r { phi } else { 0.0 };
    }
    (th, ph)
}

/// One angular axis's neighbours on a block's lanes ([`AxisLerp`] per lane).
struct LaneLerp {
    i0: [u32; LANES],
    i1: [u32; LANES],
    t: Lanes,
    coord: Lanes,
}

/// [`AngularGrid::lerp_theta`] on lanes: the ring above is found by
/// counting the rings at or below (the list is strictly increasing).
#[inline(always)]
fn lerp_theta(g: &AngularGrid, theta: &Lanes) -> LaneLerp {
    let th = g.theta_deg();
    let n = th.len();
    let deg = lanes!(|i| if theta[i].is_finite() { theta[i].to_degrees() } else { 0.0 });
    let mut count = [0u32; LANES];
    for &r in th {
        for i in 0..LANES {
            count[i] += (r <= deg[i]) as u32;
        }
    }
    let mut o = LaneLerp { i0: [0; LANES], i1: [0; LANES], t: [0.0; LANES], coord: [0.0; LANES] };
    if n == 1 {
        return o;
    }
    let last = (n - 1) as u32;
    let (first, top) = (th[0], th[n - 1]);
    // a fixed-size copy, so that the per-lane reads need no bounds check
    let mut ring = [0.0f32; MAX_RENDER_THETA];
    let m = n.min(MAX_RENDER_THETA);
    ring[..m].copy_from_slice(&th[..m]);
    for i in 0..LANES {
        let i1 = count[i].clamp(1, last);
        let i0 = i1 - 1;
        let (a, b) = (ring[i0 as usize % MAX_RENDER_THETA], ring[i1 as usize % MAX_RENDER_THETA]);
        let t = ((deg[i] - a) / (b - a)).clamp(0.0, 1.0);
        // below the first ring: ring 0; at or above the last: the last
        let below = deg[i] <= first;
        let above = !below && deg[i] >= top;
        o.i0[i] = if below {
            0
        } else if above {
            last
        } else {
            i0
        };
        o.i1[i] = if below {
            0
        } else if above {
            last
        } else {
            i1
        };
        o.t[i] = if below || above { 0.0 } else { t };
        o.coord[i] = if below {
            0.0
        } else if above {
            last as f32
        } else {
            i0 as f32 + t
        };
    }
    o
}

/// [`AngularGrid::lerp_phi`] on lanes.
#[inline(always)]
fn lerp_phi(g: &AngularGrid, phi: &Lanes) -> LaneLerp {
    let count = g.phi_count() as u32;
    let n = count as f32;
    let mut o = LaneLerp { i0: [0; LANES], i1: [0; LANES], t: [0.0; LANES], coord: [0.0; LANES] };
    for i in 0..LANES {
        let mut x = if phi[i].is_finite() { phi[i] / std::f32::consts::TAU * n } else { 0.0 };
        x -= n * floor(x / n);
        if x >= n {
            x = 0.0;
        }
        let i0 = whole_u32(floor(x)).min(count - 1);
        o.i0[i] = i0;
        o.i1[i] = if i0 + 1 == count { 0 } else { i0 + 1 };
        o.t[i] = (x - i0 as f32).clamp(0.0, 1.0);
        o.coord[i] = x;
    }
    o
}

/// The fragments of `scene` seen by `camera` at `width`×`height`, in the
/// order a GPU shades them — 2×2 quads, quads row by row — each with its
/// perspective-correct varyings. Found by casting a ray through every pixel
/// centre (for the texture-cache model, which needs one ordered stream;
/// rendering itself goes through the rasterizer).
pub fn fragments_in_quad_order(scene: &PreparedBtf, frame: &BtfFrame, width: u32, height: u32) -> Vec<[f32; VARYINGS]> {
    let vp = glam::Mat4::from_cols_array_2d(&frame.view_proj);
    let inv = vp.inverse();
    let tris: Vec<[usize; 3]> = scene
        .indices
        .chunks_exact(3)
        .filter(|t| t.iter().all(|&i| (i as usize) < scene.vertices.len()))
        .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
        .collect();
    let pos = |i: usize| Vec3::from_array(scene.vertices[i].position);
    let vary: Vec<[f32; VARYINGS]> = scene.vertices.iter().map(varyings).collect();
    let mut out = Vec::new();
    let hit = |px: u32, py: u32| -> Option<[f32; VARYINGS]> {
        let ndc_x = (px as f32 + 0.5) / width as f32 * 2.0 - 1.0;
        let ndc_y = 1.0 - (py as f32 + 0.5) / height as f32 * 2.0;
        let a = inv.project_point3(Vec3::new(ndc_x, ndc_y, 0.0));
        let b = inv.project_point3(Vec3::new(ndc_x, ndc_y, 1.0));
        let dir = b - a;
        let mut best: Option<(f32, usize, f32, f32)> = None;
        for (k, t) in tris.iter().enumerate() {
            // Möller–Trumbore
            let (p0, p1, p2) = (pos(t[0]), pos(t[1]), pos(t[2]));
            let (e1, e2) = (p1 - p0, p2 - p0);
            let h = dir.cross(e2);
            let det = e1.dot(h);
            if det.abs() < 1e-12 {
                continue;
            }
            let s = a - p0;
            let u = s.dot(h) / det;
            let q = s.cross(e1);
            let v = dir.dot(q) / det;
            let d = e2.dot(q) / det;
            if u < 0.0 || v < 0.0 || u + v > 1.0 || !(0.0..=1.0).contains(&d) {
                continue;
            }
            if best.is_none_or(|b| d < b.0) {
                best = Some((d, k, u, v));
            }
        }
        best.map(|(_, k, u, v)| {
            let t = tris[k];
            std::array::from_fn(|i| vary[t[0]][i] * (1.0 - u - v) + vary[t[1]][i] * u + vary[t[2]][i] * v)
        })
    };
    for qy in (0..height).step_by(2) {
        for qx in (0..width).step_by(2) {
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (px, py) = (qx + dx, qy + dy);
                if px < width
                    && py < height
                    && let Some(v) = hit(px, py)
                {
                    out.push(v);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::div_magic;

    #[test]
    fn division_by_multiply_and_shift_is_exact_below_the_bound() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let mut cases: Vec<(u32, u32)> = vec![(1, 1), (1, 1 << 30), (3, 7), (7, 4096), (64, 1 << 20), (65535, 1 << 16)];
        for _ in 0..300 {
            let d = (next() % 70_000) as u32 + 1;
            let bound = (next() % (1 << 26)) as u32 + 1;
            cases.push((d, bound));
        }
        for (d, bound) in cases {
            let (m, s) = div_magic(d, bound);
            assert!(m <= 1 << 32, "{d} {bound}: m = {m}");
            let check = |k: u32| assert_eq!(((k as u64 * m) >> s) as u32, k / d, "{k} / {d} (bound {bound})");
            // both ends, every remainder's worst case near the bound, and random values
            for k in [0, 1, d - 1, d, bound - 1, bound.saturating_sub(d)] {
                if k < bound {
                    check(k);
                }
            }
            for q in [(bound - 1) / d, (bound - 1) / d / 2] {
                for r in [0, d - 1] {
                    let k = q as u64 * d as u64 + r as u64;
                    if k < bound as u64 {
                        check(k as u32);
                    }
                }
            }
            for _ in 0..64 {
                check((next() % bound as u64) as u32);
            }
            // any u32 k keeps k·m inside u64 (lanes that read nothing)
            let _ = (u32::MAX as u64).checked_mul(m).expect("k·m overflows");
        }
    }
}
