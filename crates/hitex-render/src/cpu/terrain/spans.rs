//! The span samplers of the flat-ground program (seed 001): 2×2 texel
//! spans read from 3×3 or 4×4 banks, bilinear or bicubic within a span,
//! on lanes and per pixel, and the bank model they feed.

use super::*;

impl Program<'_> {
    /// Four flat-ground spans on one block: the 8×2 pixels from column `x0`
    /// of rows `py` and `py + 1`, lanes in quad order (span `s` on lanes
    /// 4s … 4s + 3: (0,0) (1,0) (0,1) (1,1)). The same operations as
    /// [`Program::shade_flat_span`] without bank statistics, in the same
    /// order: rays and filters on lanes, each span's level on its own, the
    /// texel reads lane by lane.
    #[inline(always)]
    pub(super) fn shade_spans_lanes(&self, x0: u32, py: u32) -> [Lanes; 3] {
        let px: Lanes = std::array::from_fn(|i| (x0 + 2 * (i as u32 / 4) + (i as u32 & 1)) as f32 + 0.5);
        let pyl: Lanes = std::array::from_fn(|i| (py + ((i as u32 >> 1) & 1)) as f32 + 0.5);
        let (gx, gy, ok) = self.ground_lanes(&px, &pyl);
        let h = self.u.sizes[1] as f32;
        let skies = [sky(py as f32 + 0.5, h), sky((py + 1) as f32 + 0.5, h)];
        let mut out = [[0.0f32; LANES]; 3];
        for i in 0..LANES {
            for ch in 0..3 {
                out[ch][i] = skies[(i >> 1) & 1][ch];
            }
        }
        if ok == 0 {
            return out;
        }
        let (c, wanted) = self.spans_lanes(&gx, &gy, ok);
        for i in 0..LANES {
            if wanted >> i & 1 == 0 {
                continue;
            }
            let o = Self::over_ground([c[0][i], c[1][i], c[2][i], c[3][i]]);
            for ch in 0..3 {
                out[ch][i] = o[ch];
            }
        }
        out
    }

    /// The span sampler over the four spans of a block whose points are
    /// (gx, gy) on the lanes in `ok` (quad order, span `s` on lanes 4s …
    /// 4s + 3): linear RGBA per lane, and the lanes filled (those of spans
    /// with at least one point).
    #[inline(always)]
    pub(super) fn spans_lanes(&self, gx: &Lanes, gy: &Lanes, ok: u32) -> ([Lanes; 4], u32) {
        let sampler = self.u.sampler();
        let b = sampler.banks() as i32;
        let bicubic = sampler == FlySampler::Bicubic;
        let cap = self.pages.levels as i32 - 1 + VIRTUAL;
        // each span's level from its footprint, as Program::span
        let (mut ks, mut gs, mut live) = ([0i32; 4], [0.0f32; 4], 0u32);
        for s in 0..4 {
            let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
            for i in 4 * s..4 * s + 4 {
                if ok >> i & 1 == 1 {
                    lo = [lo[0].min(gx[i]), lo[1].min(gy[i])];
                    hi = [hi[0].max(gx[i]), hi[1].max(gy[i])];
                }
            }
            if lo[0] > hi[0] {
                continue;
            }
            live |= 0xf << (4 * s);
            let e = (hi[0] - lo[0]).max(hi[1] - lo[1]);
            let lam = (2.0 * e / (b - 2) as f32).log2();
            let (mut k, mut g) = (0i32, 0.0f32);
            if lam > 0.0 {
                let f = floor(lam);
                (k, g) = if f >= cap as f32 { (cap, 0.0) } else { (f as i32, lam - f) };
            }
            let fits = |k: i32| {
                let sc = f32::from_bits(((127 - k) as u32) << 23);
                floor(hi[0] * sc - 0.5) - floor(lo[0] * sc - 0.5) + 2.0 <= b as f32
                    && floor(hi[1] * sc - 0.5) - floor(lo[1] * sc - 0.5) + 2.0 <= b as f32
            };
            while k < cap && !fits(k) {
                k += 1;
            }
            (ks[s], gs[s]) = (k, g);
        }
        let wanted = ok & live;
        let c0 = self.spans_level_lanes(gx, gy, wanted, &ks, b, bicubic);
        let mut second = 0u32;
        for s in 0..4 {
            if gs[s] > 0.0 {
                second |= 0xf << (4 * s);
            }
        }
        let second = second & wanted;
        let c1 = if second != 0 { self.spans_level_lanes(gx, gy, second, &ks.map(|k| k + 1), b, bicubic) } else { c0 };
        let mut out = c0;
        for i in 0..LANES {
            if second >> i & 1 == 1 {
                let g = gs[i / 4];
                for ch in 0..4 {
                    out[ch][i] = c0[ch][i] + (c1[ch][i] - c0[ch][i]) * g;
                }
            }
        }
        (out, wanted)
    }

    /// [`Program::span_level`] for the four spans of a block at levels
    /// `ks[s]` (finest-numbered, virtual above the coarsest), lanes in
    /// `wanted` only; linear RGBA.
    #[inline(always)]
    fn spans_level_lanes(
        &self,
        gx: &Lanes,
        gy: &Lanes,
        wanted: u32,
        ks: &[i32; 4],
        b: i32,
        bicubic: bool,
    ) -> [Lanes; 4] {
        let last = self.pages.levels as i32 - 1;
        // a virtual level reads the coarsest level with the coarsest's taps
        let (mut qx, mut qy) = ([0.0f32; LANES], [0.0f32; LANES]);
        for i in 0..LANES {
            let k = ks[i / 4].min(last);
            let sc = f32::from_bits(((127 - k) as u32) << 23);
            qx[i] = gx[i] * sc - 0.5;
            qy[i] = gy[i] * sc - 0.5;
        }
        let (mut fx, mut fy) = ([0i32; LANES], [0i32; LANES]);
        let (mut tx, mut ty) = ([0.0f32; LANES], [0.0f32; LANES]);
        for i in 0..LANES {
            let (a, c) = (floor(qx[i]), floor(qy[i]));
            tx[i] = qx[i] - a;
            ty[i] = qy[i] - c;
            fx[i] = if wanted >> i & 1 == 1 { whole_i32(a) } else { 0 };
            fy[i] = if wanted >> i & 1 == 1 { whole_i32(c) } else { 0 };
        }
        // each span's block origin from its points (bicubic taps stay inside it)
        let mut origin = [[0i32; 2]; 4];
        for s in 0..4 {
            let (mut lo, mut hi, mut any) = ([i32::MAX; 2], [i32::MIN; 2], false);
            for i in 4 * s..4 * s + 4 {
                if wanted >> i & 1 == 1 {
                    lo = [lo[0].min(fx[i]), lo[1].min(fy[i])];
                    hi = [hi[0].max(fx[i]), hi[1].max(fy[i])];
                    any = true;
                }
            }
            if !any {
                continue;
            }
            for a in 0..2 {
                origin[s][a] = if bicubic { lo[a] - 1 + (hi[a] - lo[a] + 4 - b).max(0) / 2 } else { lo[a] };
            }
        }
        let mut out = [[0.0f32; LANES]; 4];
        let mut memo = ([-1; 3], None);
        if !bicubic {
            // each lane's blend right after its reads: the texels stay in
            // registers (written to lane arrays and read back as vectors,
            // the loads wait for the stores: no store forwarding)
            for i in 0..LANES {
                if wanted >> i & 1 == 0 {
                    continue;
                }
                let k = ks[i / 4];
                let z = if k > last { 0 } else { (last - k) as u32 };
                let (x, y) = (fx[i], fy[i]);
                let q = [
                    self.texel_memo(&mut memo, z, x, y),
                    self.texel_memo(&mut memo, z, x + 1, y),
                    self.texel_memo(&mut memo, z, x, y + 1),
                    self.texel_memo(&mut memo, z, x + 1, y + 1),
                ];
                let blended = lerp2(q, tx[i], ty[i]);
                for ch in 0..4 {
                    out[ch][i] = blended[ch];
                }
            }
            return out;
        }
        // Catmull-Rom taps clamped into the span's B×B block, each lane's
        // filter right after its reads (see the bilinear case above)
        for i in 0..LANES {
            if wanted >> i & 1 == 0 {
                continue;
            }
            let k = ks[i / 4];
            let z = if k > last { 0 } else { (last - k) as u32 };
            let o = origin[i / 4];
            let (wx, wy) = (catmull_rom(tx[i]), catmull_rom(ty[i]));
            let (mut acc, mut lo, mut hi) = ([0.0f32; 4], [f32::INFINITY; 4], [f32::NEG_INFINITY; 4]);
            for (j, wyj) in wy.iter().enumerate() {
                let y = (fy[i] + j as i32 - 1).clamp(o[1], o[1] + b - 1);
                for (t, wxt) in wx.iter().enumerate() {
                    let x = (fx[i] + t as i32 - 1).clamp(o[0], o[0] + b - 1);
                    let q = self.texel_memo(&mut memo, z, x, y);
                    for ch in 0..4 {
                        acc[ch] += q[ch] * (wxt * wyj);
                        lo[ch] = lo[ch].min(q[ch]);
                        hi[ch] = hi[ch].max(q[ch]);
                    }
                }
            }
            for ch in 0..4 {
                out[ch][i] = acc[ch].clamp(lo[ch], hi[ch]);
            }
        }
        out
    }

    /// The block origin and every point's taps of a span at finest-numbered
    /// level `k` (see [`Program::span_level`]).
    #[inline(always)]
    fn span_taps(pts: &[Option<[f32; 2]>; 4], k: i32, b: i32, bicubic: bool) -> ([i32; 2], [Option<[Axis; 2]>; 4]) {
        // 2^−k, exactly (k is a level number, far inside the exponent range)
        let s = f32::from_bits(((127 - k) as u32) << 23);
        let mut q = [None; 4];
        for i in 0..4 {
            if let Some(p) = pts[i] {
                q[i] = Some([p[0] * s - 0.5, p[1] * s - 0.5]);
            }
        }
        let mut origin = [0i32; 2];
        for a in 0..2 {
            let (mut lo, mut hi, mut any) = (i32::MAX, i32::MIN, false);
            for q in q.iter().flatten() {
                let f = floor(q[a]) as i32;
                lo = lo.min(f);
                hi = hi.max(f);
                any = true;
            }
            if !any {
                (lo, hi) = (0, 0);
            }
            origin[a] = if bicubic { lo - 1 + (hi - lo + 4 - b).max(0) / 2 } else { lo };
        }
        let mut taps = [None; 4];
        for i in 0..4 {
            if let Some(q) = q[i] {
                taps[i] = Some([axis(q[0], bicubic, origin[0], b), axis(q[1], bicubic, origin[1], b)]);
            }
        }
        (origin, taps)
    }

    /// Filters the points of a span at finest-numbered level `k` (virtual above the coarsest).
    #[inline(always)]
    fn span_level(
        &self,
        pts: &[Option<[f32; 2]>; 4],
        k: i32,
        b: i32,
        bicubic: bool,
        banks: Option<&mut BankModel>,
    ) -> [[f32; 4]; 4] {
        let last = self.pages.levels as i32 - 1;
        let (origin, taps) = Self::span_taps(pts, k, b, bicubic);
        if let Some(banks) = banks {
            let n = if bicubic { 4 } else { 2 };
            let mut texels = Vec::with_capacity(64);
            for [ax, ay] in taps.iter().flatten() {
                for &y in &ay.i[..n] {
                    for &x in &ax.i[..n] {
                        texels.push([x as i64, y as i64]);
                    }
                }
            }
            banks.record(k as usize, [origin[0] as i64, origin[1] as i64], &texels);
        }
        // a virtual level takes the coarsest level's values
        let (z, taps) =
            if k > last { (0u32, Self::span_taps(pts, last, b, bicubic).1) } else { ((last - k) as u32, taps) };
        let mut out = [[0.0f32; 4]; 4];
        let mut memo = ([-1; 3], None);
        for (o, t) in out.iter_mut().zip(&taps) {
            let Some([ax, ay]) = t else { continue };
            if !bicubic {
                let c = [
                    self.texel_memo(&mut memo, z, ax.i[0], ay.i[0]),
                    self.texel_memo(&mut memo, z, ax.i[1], ay.i[0]),
                    self.texel_memo(&mut memo, z, ax.i[0], ay.i[1]),
                    self.texel_memo(&mut memo, z, ax.i[1], ay.i[1]),
                ];
                *o = lerp2(c, ax.w[1], ay.w[1]);
                continue;
            }
            let mut acc = [0.0f32; 4];
            let (mut lo, mut hi) = ([f32::INFINITY; 4], [f32::NEG_INFINITY; 4]);
            for j in 0..4 {
                for i in 0..4 {
                    let c = self.texel_memo(&mut memo, z, ax.i[i], ay.i[j]);
                    let w = ax.w[i] * ay.w[j];
                    for ch in 0..4 {
                        acc[ch] += c[ch] * w;
                        lo[ch] = lo[ch].min(c[ch]);
                        hi[ch] = hi[ch].max(c[ch]);
                    }
                }
            }
            for ch in 0..4 {
                o[ch] = acc[ch].clamp(lo[ch], hi[ch]);
            }
        }
        out
    }

    /// The span sampler over the four points of a span (None: no ground there).
    #[inline(always)]
    pub(super) fn span(
        &self,
        pts: [Option<[f32; 2]>; 4],
        sampler: FlySampler,
        mut banks: Option<&mut BankModel>,
    ) -> [[f32; 4]; 4] {
        let b = sampler.banks() as i32;
        let bicubic = sampler == FlySampler::Bicubic;
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for p in pts.iter().flatten() {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        if lo[0] > hi[0] {
            return [[0.0; 4]; 4];
        }
        let e = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let lam = (2.0 * e / (b - 2) as f32).log2();
        let cap = self.pages.levels as i32 - 1 + VIRTUAL;
        let (mut k, mut g) = (0i32, 0.0f32);
        if lam > 0.0 {
            let f = floor(lam);
            (k, g) = if f >= cap as f32 { (cap, 0.0) } else { (f as i32, lam - f) };
        }
        // rounding guard: the finer level's bilinear footprint must fit B texels
        let fits = |k: i32| {
            let s = f32::from_bits(((127 - k) as u32) << 23);
            floor(hi[0] * s - 0.5) - floor(lo[0] * s - 0.5) + 2.0 <= b as f32
                && floor(hi[1] * s - 0.5) - floor(lo[1] * s - 0.5) + 2.0 <= b as f32
        };
        let mut raised = false;
        while k < cap && !fits(k) {
            k += 1;
            raised = true;
        }
        if let Some(m) = banks.as_deref_mut() {
            m.spans += 1;
            m.guard_raises += u64::from(raised);
            m.level_sum += k as f64 + g as f64;
        }
        let c0 = self.span_level(&pts, k, b, bicubic, banks.as_deref_mut());
        if g <= 0.0 {
            return c0;
        }
        let c1 = self.span_level(&pts, k + 1, b, bicubic, banks);
        let mut out = c0;
        for i in 0..4 {
            for ch in 0..4 {
                out[i][ch] = c0[i][ch] + (c1[i][ch] - c0[i][ch]) * g;
            }
        }
        out
    }

    /// Linear RGB of the flat-ground span whose top-left pixel is (px, py),
    /// recording its bank traffic in `banks` (the statistics pass; the
    /// frames without statistics run [`Program::shade_spans_lanes`]).
    #[inline(always)]
    pub(super) fn shade_flat_span(&self, px: u32, py: u32, banks: Option<&mut BankModel>) -> [[f32; 3]; 4] {
        let mut pts: [Option<[f32; 2]>; 4] = [None; 4];
        for (i, p) in pts.iter_mut().enumerate() {
            *p = self.ground((px + (i as u32 & 1)) as f32 + 0.5, (py + (i as u32 >> 1)) as f32 + 0.5);
        }
        let c = self.span(pts, self.u.sampler(), banks);
        let mut out = [[0.0f32; 3]; 4];
        for (i, o) in out.iter_mut().enumerate() {
            *o = match pts[i] {
                Some(_) => Self::over_ground(c[i]),
                None => sky((py + (i as u32 >> 1)) as f32 + 0.5, self.u.sizes[1] as f32),
            };
        }
        out
    }
}
