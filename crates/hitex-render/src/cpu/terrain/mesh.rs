//! The DEM mesh's fragment program: the terrain program on rasterized
//! relief quads, with the bank model per worker thread when statistics are
//! asked for.

use super::*;

/// The mesh fragment program: lanes (0,0) (1,0) (0,1) (1,1) of a quad;
/// varyings map x, map y, kind, light.
pub(super) struct MeshProgram<'a> {
    pub(super) prog: &'a Program<'a>,
    /// Bank models, one per worker thread (empty: no statistics).
    pub(super) banks: Vec<Mutex<BankModel>>,
}

impl MeshProgram<'_> {
    /// One quad, lanes (0,0) (1,0) (0,1) (1,1): the reference program, and
    /// the one that records bank traffic and shades objects.
    pub(super) fn shade_quad(&self, v: &[[f32; 4]; 4]) -> [[u8; 4]; 4] {
        let p: [[f32; 2]; 4] = std::array::from_fn(|i| [v[i][0], v[i][1]]);
        // fine differences, as dpdxFine / dpdyFine
        let dx = |row: usize| [p[2 * row + 1][0] - p[2 * row][0], p[2 * row + 1][1] - p[2 * row][1]];
        let dy = |col: usize| [p[col + 2][0] - p[col][0], p[col + 2][1] - p[col][1]];
        let foot = |i: usize| {
            let (a, b) = (dx(i >> 1), dy(i & 1));
            a[0].abs().max(a[1].abs()).max(b[0].abs()).max(b[1].abs())
        };
        let kind = v[0][2];
        let colour: [[f32; 4]; 4] = if kind > 0.5 {
            std::array::from_fn(|i| self.prog.generic(p[i], foot(i)))
        } else {
            match self.prog.u.sampler() {
                FlySampler::Trilinear => std::array::from_fn(|i| self.prog.trilinear(p[i], foot(i))),
                s if self.banks.is_empty() => self.prog.span(p.map(Some), s, None),
                s => {
                    let slot = rayon::current_thread_index().unwrap_or(0) % self.banks.len();
                    match self.banks[slot].lock() {
                        Ok(mut m) => self.prog.span(p.map(Some), s, Some(&mut m)),
                        Err(_) => self.prog.span(p.map(Some), s, None),
                    }
                }
            }
        };
        std::array::from_fn(|i| {
            let l = v[i][3];
            let c = colour[i];
            if kind > 0.5 { encode([c[0] * l, c[1] * l, c[2] * l]) } else { encode(Program::over_ground(c)) }
        })
    }

    /// Ground of a block (16 lanes, four quads) without bank statistics: the
    /// same operations as [`MeshProgram::shade_quad`], on lane vectors.
    #[inline(always)]
    pub(super) fn shade_ground_lanes(&self, b: &Block<4>) -> [Lanes; 4] {
        let prog = self.prog;
        let (gx, gy) = (&b.v[0], &b.v[1]);
        if prog.u.sampler() != FlySampler::Trilinear {
            return prog.spans_lanes(gx, gy, 0xffff).0;
        }
        // the footprint from the quads' fine differences (dpdxFine / dpdyFine)
        let (dxx, dxy, dyx, dyy) = (ddx(gx), ddx(gy), ddy(gx), ddy(gy));
        let levels = prog.pages.levels;
        let top = (levels - 1) as f32;
        let (mut z0, mut z1, mut t) = ([0u32; LANES], [0u32; LANES], [0.0f32; LANES]);
        for i in 0..LANES {
            let foot = dxx[i].abs().max(dxy[i].abs()).max(dyx[i].abs()).max(dyy[i].abs());
            let zf = (top - crate::cpu::simd::log2(foot.max(1e-9))).clamp(0.0, top);
            let f = floor(zf);
            z0[i] = whole_u32(f);
            z1[i] = (z0[i] + 1).min(levels - 1);
            t[i] = zf - f;
        }
        let a = prog.bilinear_lanes(&z0, 0xffff, 0xffff, gx, gy);
        let mut second = 0u32;
        for i in 0..LANES {
            second |= (((z1[i] != z0[i]) & (t[i] > 0.0)) as u32) << i;
        }
        let c = if second != 0 { prog.bilinear_lanes(&z1, second, 0xffff, gx, gy) } else { a };
        let mut out = a;
        for ch in 0..4 {
            for i in 0..LANES {
                let bv = if second >> i & 1 == 1 { c[ch][i] } else { a[ch][i] };
                out[ch][i] = a[ch][i] + (bv - a[ch][i]) * t[i];
            }
        }
        out
    }
}

impl BlockShader<4> for MeshProgram<'_> {
    /// Objects (generic texture) apart from the ground: a block is shaded
    /// by one of the two programs.
    #[inline(always)]
    fn key(&self, v: &[f32; 4]) -> u32 {
        (v[2] > 0.5) as u32
    }

    /// Frames that record bank traffic record exactly the quads that
    /// drawing triangle by triangle shades.
    #[inline(always)]
    fn packs_triangles(&self) -> bool {
        self.banks.is_empty()
    }

    #[inline(always)]
    fn shade_block(&self, b: &Block<4>, rgba: &mut [[u8; 4]; LANES], _depth: &mut Lanes) {
        let first = (b.live.trailing_zeros() as usize).min(LANES - 1);
        // objects (generic texture) and frames that record bank traffic: quad by quad
        if b.v[2][first] > 0.5 || !self.banks.is_empty() {
            for q in 0..4 {
                if (b.live >> (4 * q)) & 0xf == 0 {
                    continue;
                }
                let v: [[f32; 4]; 4] = std::array::from_fn(|l| std::array::from_fn(|k| b.v[k][4 * q + l]));
                let c = self.shade_quad(&v);
                rgba[4 * q..4 * q + 4].copy_from_slice(&c);
            }
            return;
        }
        let c = self.shade_ground_lanes(b);
        let enc = hitex_core::texture::srgb_encoder();
        let mut lin = [[0.0f32; LANES]; 3];
        for i in 0..LANES {
            let o = Program::over_ground([c[0][i], c[1][i], c[2][i], c[3][i]]);
            for ch in 0..3 {
                lin[ch][i] = o[ch];
            }
        }
        *rgba = crate::cpu::simd::encode_rgb(enc, &lin);
    }
}
