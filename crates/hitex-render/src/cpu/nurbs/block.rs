//! The NURBS program's block path: a block's lanes grouped by patch and
//! knot-span pair (or one window of spans a patch), each group's prepared
//! bicubic kernel run once on SIMD registers with the knots and control
//! points broadcast, bit for bit the per-lane program; and the block
//! evaluator built on the same kernel ([`eval_bicubic_block`]).

// index loops mirror the shader's loops over spans
#![allow(clippy::needless_range_loop)]

use super::*;
impl NurbsProgram<'_> {
    /// The block path of the prepared bicubic kernel: the live lanes on
    /// patches of degree 3×3 (lanes on others take the per-lane program),
    /// shaded, isophote or normal mode, no overlay. The lanes are grouped by
    /// patch and knot-span pair (neighbouring pixels mostly share both), the
    /// spans found once per patch and the knots and the 16 control points of
    /// each group broadcast; every lane then runs the same straight-line steps
    /// as [`eval_packed`] and [`NurbsProgram::lane`], in the same order, so
    /// the result is bit for bit the per-lane one. `None` when the block does
    /// not qualify.
    #[inline(always)]
    pub(super) fn block_bicubic(
        &self,
        b: &Block<VARYINGS>,
        rgba: &mut [[u8; 4]; LANES],
        depth: &mut Lanes,
    ) -> Option<()> {
        let f = self.frame;
        let t = self.packed;
        let mode = f.params[0];
        let overlays = flag::BOUNDARIES | flag::ISOLINES | flag::SECTIONS | flag::EDGES;
        if !matches!(mode, SHADED | ISOPHOTE | NORMAL)
            || f.params[3] & (flag::PREPARED | overlays) != flag::PREPARED
            || b.live == 0
        {
            return None;
        }
        // the patch of every lane
        // (float operations only, which run as vector code; equal to the
        // per-lane program's `(round().max(0) as usize).min(last)`: patch
        // numbers are whole floats far below 2²⁴, NaN gives patch 0 in both)
        let last = t.patches.saturating_sub(1) as f32;
        let pf = simd::map(&b.v[5], |x| x.round().max(0.0).min(last));
        // the lanes' parameters clamped into their patches' domains
        let (mut u, mut v) = (b.v[3], b.v[4]);
        // the kernel runs, `(patch, su, sv, spans across, spans down, lanes)`:
        // patches in order of their first lanes; a patch's lanes in one run
        // over the window of control points of all their spans where that
        // costs less ([`window`]), else a run per span pair (1 × 1 spans)
        let mut runs = [(0usize, 0usize, 0usize, 1usize, 1usize, 0u16); LANES];
        let mut count = 0;
        // the knot spans of the lanes of window runs
        let (mut su_of, mut sv_of) = ([0.0f32; LANES], [0.0f32; LANES]);
        // lanes on patches the kernel does not take; lanes past their
        // domain or on a boundary fan; lanes on trimmed patches
        let (mut other, mut outside, mut trimmed) = (0u16, 0u16, 0u16);
        let shaded = mode == SHADED;
        let mut albedo_of = [[0.0f32; LANES]; 3];
        let mut rest = b.live;
        while rest != 0 {
            let first = rest.trailing_zeros() as usize;
            let pfirst = pf[first];
            let mut members = 0u16;
            for lane in 0..LANES {
                members |= ((pf[lane] == pfirst) as u16) << lane;
            }
            members &= rest;
            rest &= !members;
            let patch = pfirst as usize;
            let pr = patch_ref(t, patch);
            if pr.p != 3 || pr.q != 3 {
                other |= members;
                continue;
            }
            let (ku, kv, nu, nv) = (pr.ku, pr.kv, pr.nu, pr.nv);
            let (u0, u1, v0, v1) = (ku[3], ku[nu], kv[3], kv[nv]);
            let mut out = 0u16;
            for lane in 0..LANES {
                let (x, y) = (b.v[3][lane], b.v[4][lane]);
                let o = (x < u0) | (x > u1) | (y < v0) | (y > v1) | is_fan(b.v[5][lane]);
                out |= (o as u16) << lane;
            }
            outside |= out & members;
            if t.trims[patch * t.trim_width as usize][0] as usize != 0 {
                trimmed |= members;
            }
            let a = if shaded { albedo(t, patch) } else { Vec3::ZERO };
            let mut m = members;
            while m != 0 {
                let lane = m.trailing_zeros() as usize;
                m &= m - 1;
                u[lane] = b.v[3][lane].max(u0).min(u1);
                v[lane] = b.v[4][lane].max(v0).min(v1);
                albedo_of[0][lane] = a.x;
                albedo_of[1][lane] = a.y;
                albedo_of[2][lane] = a.z;
            }
            let sg = span_groups(ku, kv, nu, nv, &u, &v, members)?;
            if let Some((su, sv, w, h)) = window(&sg, members) {
                runs[count] = (patch, su, sv, w, h, members);
                count += 1;
                let mut m = members;
                while m != 0 {
                    let lane = m.trailing_zeros() as usize;
                    m &= m - 1;
                    su_of[lane] = sg.su[lane] as f32;
                    sv_of[lane] = sg.sv[lane] as f32;
                }
            } else {
                for &(su, sv, lanes) in sg.iter() {
                    runs[count] = (patch, su, sv, 1, 1, lanes);
                    count += 1;
                }
            }
        }
        // the arithmetic, one register of lanes at a time, once per run
        let light = Vec3::new(f.light[0], f.light[1], f.light[2]);
        let cam = Vec3::new(f.camera[0], f.camera[1], f.camera[2]);
        let mut o = BicubicOut::default();
        let mut g = BicubicOut::default();
        // past four runs, a lane alone in its run costs less on its own
        // (the per-lane program, below) than a kernel run for it
        let mut solo = 0u16;
        let mut filled = false;
        // lanes that may be seam fragments: their runs also give the depth pushed back
        let seams = outside | trimmed;
        for &(patch, su, sv, w, h, lanes) in &runs[..count] {
            if count > 4 && lanes.count_ones() == 1 {
                solo |= lanes;
                continue;
            }
            let pr = patch_ref(t, patch);
            let (ku, kv, cp, nu) = (pr.ku, pr.kv, pr.cp, pr.nu);
            // the first run's lanes straight into the output, the others' copied over
            let out = if filled { &mut g } else { &mut o };
            let window = Window { w, h, su: &su_of, sv: &sv_of };
            let seams = seams & lanes;
            simd::run(BicubicOp {
                su,
                sv,
                window,
                lanes,
                seams,
                u: &u,
                v: &v,
                ku,
                kv,
                cp,
                nu,
                cam,
                light,
                m: &f.view_proj,
                out,
            });
            if !filled {
                filled = true;
                continue;
            }
            let mut m = lanes;
            while m != 0 {
                let lane = m.trailing_zeros() as usize;
                m &= m - 1;
                for (dst, src) in [
                    (&mut o.nx, &g.nx),
                    (&mut o.ny, &g.ny),
                    (&mut o.nz, &g.nz),
                    (&mut o.depth, &g.depth),
                    (&mut o.seam_depth, &g.seam_depth),
                    (&mut o.ndl, &g.ndl),
                    (&mut o.spec, &g.spec),
                    (&mut o.len, &g.len),
                    (&mut o.scale, &g.scale),
                    (&mut o.finite, &g.finite),
                ] {
                    dst[lane] = src[lane];
                }
            }
        }
        let n = V3 { x: o.nx, y: o.ny, z: o.nz };
        let (ndl, spec, d) = (o.ndl, o.spec, o.depth);
        // degenerate normals, solo lanes and lanes on other patches take the per-lane program
        let mut degenerate = solo | other;
        for lane in 0..LANES {
            let ok = (o.len[lane] > 1e-6 * o.scale[lane] * o.scale[lane]) & (o.finite[lane] != 0.0);
            degenerate |= (!ok as u16) << lane;
        }
        let raw = |c: Vec3| {
            let q = |x: f32| (if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) } * 255.0 + 0.5) as u8;
            [q(c.x), q(c.y), q(c.z), 255]
        };
        match mode {
            SHADED => {
                // Blinn–Phong, the same steps as `lane`
                let amb = f.ranges[2];
                let mut lin = [[0.0f32; LANES]; 3];
                for lane in 0..LANES {
                    let k = amb + ndl[lane];
                    lin[0][lane] = albedo_of[0][lane] * k + spec[lane];
                    lin[1][lane] = albedo_of[1][lane] * k + spec[lane];
                    lin[2][lane] = albedo_of[2][lane] * k + spec[lane];
                }
                let codes = simd::encode_rgb(hitex_core::texture::srgb_encoder(), &lin);
                for lane in 0..LANES {
                    if b.live & (1 << lane) != 0 {
                        rgba[lane] = codes[lane];
                    }
                }
            }
            ISOPHOTE => {
                for lane in 0..LANES {
                    if b.live & (1 << lane) != 0 {
                        rgba[lane] = raw(isophote(n.lane(lane), light, f.params[1]));
                    }
                }
            }
            _ => {
                for lane in 0..LANES {
                    if b.live & (1 << lane) != 0 {
                        rgba[lane] = raw(n.lane(lane) * 0.5 + Vec3::splat(0.5));
                    }
                }
            }
        }
        depth.copy_from_slice(&d);
        // lanes cut away (past the domain or trimmed, beyond the seam reach)
        // are discarded; seam lanes keep their colour (that of the clamped
        // parameters, as the per-lane program's) at the depth pushed back;
        // the lanes above take the per-lane path (a lane within its domain on
        // an untrimmed patch and off any fan is inside: it needs no test)
        let mut special = (trimmed | outside | degenerate) & b.live;
        while special != 0 {
            let lane = special.trailing_zeros() as usize;
            special &= special - 1;
            let g = lane_grad(b, lane);
            let v: [f32; VARYINGS] = std::array::from_fn(|j| b.v[j][lane]);
            if other & (1 << lane) != 0 {
                (rgba[lane], depth[lane]) = self.lane(&v, &g);
                continue;
            }
            let patch = pf[lane] as usize;
            let mut at = reach(t, patch, v[3], v[4], &g);
            if at == Reach::Inside && is_fan(v[5]) {
                at = Reach::Seam;
            }
            if at == Reach::Cut {
                rgba[lane] = [0, 0, 0, 0];
                depth[lane] = f32::NAN;
            } else if degenerate & (1 << lane) != 0 {
                (rgba[lane], depth[lane]) = self.lane(&v, &g);
            } else if at == Reach::Seam {
                depth[lane] = o.seam_depth[lane];
            }
        }
        Some(())
    }
}

/// True when register `c` of `w` lanes holds one of `lanes`.
#[inline(always)]
fn holds(lanes: u16, c: usize, w: usize) -> bool {
    (lanes as u32 >> (c * w)) & ((1u32 << w) - 1) != 0
}

/// What the bicubic lane kernel hands back per lane.
#[derive(Default)]
struct BicubicOut {
    nx: Lanes,
    ny: Lanes,
    nz: Lanes,
    depth: Lanes,
    /// The depth of a seam fragment: the point pushed back by
    /// [`SEAM_DEPTH_SCALE`] (in the registers holding `seams` lanes).
    seam_depth: Lanes,
    ndl: Lanes,
    spec: Lanes,
    len: Lanes,
    scale: Lanes,
    /// 1 where S_u × S_v is finite.
    finite: Lanes,
}

/// The bicubic point, normal, depth and Blinn–Phong terms of the lanes of
/// one run (one span pair, or a [`Window`] of spans on one patch), one
/// register of lanes at a time: the steps of [`eval_packed`]
/// (`basis_ders_fixed::<f32, 3, 4>`, `sums`, the quotient rule),
/// [`exact_normal`] and [`NurbsProgram::lane`] in the same order, with the
/// knots and control points broadcast.
struct BicubicOp<'a> {
    /// The knot spans (of the window's first column and row).
    su: usize,
    sv: usize,
    window: Window<'a>,
    /// The run's lanes: registers holding none of them are skipped (their
    /// lanes are another run's, or read by nobody).
    lanes: u16,
    /// Lanes that may be seam fragments: the registers holding one also
    /// give the seam depth.
    seams: u16,
    u: &'a Lanes,
    v: &'a Lanes,
    ku: &'a [f32],
    kv: &'a [f32],
    cp: &'a [[f32; 4]],
    nu: usize,
    cam: Vec3,
    light: Vec3,
    m: &'a [[f32; 4]; 4],
    out: &'a mut BicubicOut,
}

/// Lane arithmetic on one register of a pulp level.
#[derive(Clone, Copy)]
struct R<S: pulp::Simd>(S);

impl<S: pulp::Simd> R<S> {
    #[inline(always)]
    fn k(self, x: f32) -> S::f32s {
        self.0.splat_f32s(x)
    }
    #[inline(always)]
    fn add(self, a: S::f32s, b: S::f32s) -> S::f32s {
        self.0.add_f32s(a, b)
    }
    #[inline(always)]
    fn sub(self, a: S::f32s, b: S::f32s) -> S::f32s {
        self.0.sub_f32s(a, b)
    }
    #[inline(always)]
    fn mul(self, a: S::f32s, b: S::f32s) -> S::f32s {
        self.0.mul_f32s(a, b)
    }
    #[inline(always)]
    fn div(self, a: S::f32s, b: S::f32s) -> S::f32s {
        self.0.div_f32s(a, b)
    }
    #[inline(always)]
    fn sqrt(self, a: S::f32s) -> S::f32s {
        self.0.sqrt_f32s(a)
    }
    /// `a > 0 ? a : 0` (as `a.max(0.0)` for every non-NaN a, and 0 for NaN)
    #[inline(always)]
    fn pos(self, a: S::f32s) -> S::f32s {
        let z = self.k(0.0);
        self.0.select_f32s(self.0.less_than_f32s(z, a), a, z)
    }
    /// `(d.xyz − s·d.w) · (1/w)`: a first derivative by the quotient rule
    /// (`rw` = 1/w).
    #[inline(always)]
    fn quotient(self, d: &[S::f32s; 4], s: [S::f32s; 3], rw: S::f32s) -> [S::f32s; 3] {
        [
            self.mul(self.sub(d[0], self.mul(s[0], d[3])), rw),
            self.mul(self.sub(d[1], self.mul(s[1], d[3])), rw),
            self.mul(self.sub(d[2], self.mul(s[2], d[3])), rw),
        ]
    }
    /// Row `i` of `m · (p, 1)` in glam's order: ((c0·x + c1·y) + c2·z) + c3·1.
    #[inline(always)]
    fn clip_row(self, m: &[[f32; 4]; 4], i: usize, p: [S::f32s; 3]) -> S::f32s {
        let a = self.add(self.mul(self.k(m[0][i]), p[0]), self.mul(self.k(m[1][i]), p[1]));
        self.add(self.add(a, self.mul(self.k(m[2][i]), p[2])), self.mul(self.k(m[3][i]), self.k(1.0)))
    }
    #[inline(always)]
    fn dot(self, a: [S::f32s; 3], b: [S::f32s; 3]) -> S::f32s {
        self.add(self.add(self.mul(a[0], b[0]), self.mul(a[1], b[1])), self.mul(a[2], b[2]))
    }
    /// `v.normalize_or_zero()` as glam computes it: `v · (1 / |v|)`, zero where
    /// that factor is not finite and positive.
    #[inline(always)]
    fn normalize_or_zero(self, v: [S::f32s; 3]) -> [S::f32s; 3] {
        let rcp = self.div(self.k(1.0), self.sqrt(self.dot(v, v)));
        // finite and > 0: 0 < rcp < inf (NaN fails both)
        let ok = self.0.less_than_f32s(rcp, self.k(f32::INFINITY));
        let pos = self.0.less_than_f32s(self.k(0.0), rcp);
        let r = self.0.select_f32s(ok, self.0.select_f32s(pos, rcp, self.k(0.0)), self.k(0.0));
        [self.mul(v[0], r), self.mul(v[1], r), self.mul(v[2], r)]
    }
}

/// The point and first partials of a bicubic patch at one register of
/// lanes sharing spans (`su`, `sv`): basis (eq. 6), homogeneous sums over the
/// 4×4 control points from (`su` − 3, `sv` − 3), quotient rule.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn point_partials<S: pulp::Simd>(
    r: R<S>,
    su: usize,
    sv: usize,
    u: S::f32s,
    v: S::f32s,
    ku: &[f32],
    kv: &[f32],
    cp: &[[f32; 4]],
    nu: usize,
) -> [[S::f32s; 3]; 3] {
    let bu = basis3(r, su, u, ku);
    let bv = basis3(r, sv, v, kv);
    // homogeneous sums over the 4×4 control points
    let (i0, j0) = (su - 3, sv - 3);
    let zero = r.k(0.0);
    let mut a = [[zero; 4]; 3];
    for s in 0..4 {
        let row = (j0 + s) * nu + i0;
        let mut t0 = [zero; 4];
        let mut t1 = [zero; 4];
        for q in 0..4 {
            let c = cp[row + q];
            for k in 0..4 {
                t0[k] = r.add(t0[k], r.mul(r.k(c[k]), bu[0][q]));
                t1[k] = r.add(t1[k], r.mul(r.k(c[k]), bu[1][q]));
            }
        }
        for k in 0..4 {
            a[0][k] = r.add(a[0][k], r.mul(t0[k], bv[0][s]));
            a[1][k] = r.add(a[1][k], r.mul(t1[k], bv[0][s]));
            a[2][k] = r.add(a[2][k], r.mul(t0[k], bv[1][s]));
        }
    }
    // rational quotient rule, one division (as `eval_packed`)
    let rw = r.div(r.k(1.0), a[0][3]);
    let sp = [r.mul(a[0][0], rw), r.mul(a[0][1], rw), r.mul(a[0][2], rw)];
    [sp, r.quotient(&a[1], sp, rw), r.quotient(&a[2], sp, rw)]
}

/// Lanes of one patch on several knot spans, evaluated in one run over the
/// window of control points all their spans cover: each lane's basis
/// functions sit at its span's place in the window, zero elsewhere.
struct Window<'a> {
    /// Spans across (u) and down (v): 1 × 1 for lanes on one span pair.
    w: usize,
    h: usize,
    /// The lanes' spans, as floats.
    su: &'a Lanes,
    sv: &'a Lanes,
}

/// The most spans a window run covers along a direction.
const WINDOW_SPANS: usize = 4;

/// The window run of a patch's lanes `members` on the span pairs `sg`,
/// `(first su, first sv, spans across, spans down)`, when one run over the
/// window costs less than a run per pair: the sums over the control points
/// (about 0.7 of a run) grow with the window's area, the rest does not.
pub(super) fn window(sg: &SpanGroups, members: u16) -> Option<(usize, usize, usize, usize)> {
    if sg.len < 2 {
        return None;
    }
    let (mut a0, mut a1, mut b0, mut b1) = (u32::MAX, 0, u32::MAX, 0);
    let mut m = members;
    while m != 0 {
        let lane = m.trailing_zeros() as usize;
        m &= m - 1;
        (a0, a1) = (a0.min(sg.su[lane]), a1.max(sg.su[lane]));
        (b0, b1) = (b0.min(sg.sv[lane]), b1.max(sg.sv[lane]));
    }
    let (w, h) = ((a1 - a0 + 1) as usize, (b1 - b0 + 1) as usize);
    // in tenths of a 4×4 run: 3 + 0.7 · area / 16, against one a pair
    let cost = 48 + 7 * (w + 3) * (h + 3);
    (w <= WINDOW_SPANS && h <= WINDOW_SPANS && cost < 160 * sg.len).then_some((a0 as usize, b0 as usize, w, h))
}

/// A window's basis functions and first derivatives ([`window_basis`]).
type WindowBasis<S> = [[<S as pulp::Simd>::f32s; WINDOW_SPANS + 3]; 2];

/// The cubic basis functions and first derivatives of every lane placed at
/// its span's columns of a window of `n` spans from span `s0`
/// (`spans`: each lane's span), zero elsewhere: [`basis3`] once per span.
#[inline(always)]
fn window_basis<S: pulp::Simd>(r: R<S>, s0: usize, n: usize, x: S::f32s, spans: S::f32s, k: &[f32]) -> WindowBasis<S> {
    let zero = r.k(0.0);
    let mut b = [[zero; WINDOW_SPANS + 3]; 2];
    for i in 0..n {
        let on = r.0.equal_f32s(spans, r.k((s0 + i) as f32));
        let [f, d] = basis3(r, s0 + i, x, k);
        for j in 0..4 {
            b[0][i + j] = r.0.select_f32s(on, f[j], b[0][i + j]);
            b[1][i + j] = r.0.select_f32s(on, d[j], b[1][i + j]);
        }
    }
    b
}

/// [`point_partials`] over a window of `n` = (across, down) spans from the
/// spans `s0`, the basis placed by [`window_basis`]: the sums take the
/// same terms in the same order for every lane, with zero terms before and
/// after (adding them leaves every bit unchanged).
#[inline(always)]
fn window_partials<S: pulp::Simd>(
    r: R<S>,
    s0: (usize, usize),
    n: (usize, usize),
    (bu, bv): &(WindowBasis<S>, WindowBasis<S>),
    cp: &[[f32; 4]],
    nu: usize,
) -> [[S::f32s; 3]; 3] {
    let (i0, j0) = (s0.0 - 3, s0.1 - 3);
    let zero = r.k(0.0);
    let mut a = [[zero; 4]; 3];
    for s in 0..n.1 + 3 {
        let row = (j0 + s) * nu + i0;
        let mut t0 = [zero; 4];
        let mut t1 = [zero; 4];
        for q in 0..n.0 + 3 {
            let c = cp[row + q];
            for k in 0..4 {
                t0[k] = r.add(t0[k], r.mul(r.k(c[k]), bu[0][q]));
                t1[k] = r.add(t1[k], r.mul(r.k(c[k]), bu[1][q]));
            }
        }
        for k in 0..4 {
            a[0][k] = r.add(a[0][k], r.mul(t0[k], bv[0][s]));
            a[1][k] = r.add(a[1][k], r.mul(t1[k], bv[0][s]));
            a[2][k] = r.add(a[2][k], r.mul(t0[k], bv[1][s]));
        }
    }
    let rw = r.div(r.k(1.0), a[0][3]);
    let sp = [r.mul(a[0][0], rw), r.mul(a[0][1], rw), r.mul(a[0][2], rw)];
    [sp, r.quotient(&a[1], sp, rw), r.quotient(&a[2], sp, rw)]
}

/// Groups the `lanes` by their knot-span pair: `(su, sv, lanes of the
/// pair)`, the first group the first lane's (`None` when no lane is given).
/// A lane is in span s when k[s] ≤ x < k[s+1], or at the domain's end when
/// s is the last non-empty span: exactly `find_span`'s answer.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn span_groups(
    ku: &[f32],
    kv: &[f32],
    nu: usize,
    nv: usize,
    u: &Lanes,
    v: &Lanes,
    lanes: u16,
) -> Option<SpanGroups> {
    if lanes == 0 {
        return None;
    }
    let (su, sv) = (lane_spans(ku, nu, u), lane_spans(kv, nv, v));
    let id: [u32; LANES] = std::array::from_fn(|lane| su[lane] << 16 | sv[lane]);
    // the groups, each led by its first lane
    let mut groups = SpanGroups { groups: [(0, 0, 0); LANES], len: 0, su, sv };
    let mut rest = lanes;
    while rest != 0 {
        let first = rest.trailing_zeros() as usize;
        let key = id[first];
        let mut same = 0u16;
        for lane in 0..LANES {
            same |= ((id[lane] == key) as u16) << lane;
        }
        let members = same & rest;
        groups.groups[groups.len] = (su[first] as usize, sv[first] as usize, members);
        groups.len += 1;
        rest &= !members;
    }
    Some(groups)
}

/// The cubic knot span of every lane's parameter `x` (within the domain
/// [k[3], k[n]], `n` control points), as `find_span` gives it. Where the
/// knots rise (never fall) over the domain and both end spans are
/// non-empty, as a valid clamped vector has them, the span is 3 plus the
/// number of knots k[4..n] at or below x: those knots are a prefix, so the
/// count lands on the one span with k[s] ≤ x < k[s+1], and at x = k[n] on
/// the last span n − 1. Lane-parallel compares, no search; other knot
/// vectors (and long ones) take `find_span` lane by lane.
#[inline(always)]
pub(super) fn lane_spans(k: &[f32], n: usize, x: &Lanes) -> [u32; LANES] {
    let inner = &k[4..n.max(4)];
    let counted = inner.len() <= 32 && k[3] < k[4] && k[n - 1] < k[n] && k[3..=n].windows(2).all(|w| w[0] <= w[1]);
    let mut s = [3u32; LANES];
    if counted {
        for &knot in inner {
            for lane in 0..LANES {
                s[lane] += (knot <= x[lane]) as u32;
            }
        }
    } else {
        for lane in 0..LANES {
            s[lane] = find_span(n - 1, 3, x[lane], k) as u32;
        }
    }
    s
}

/// The knot-span pairs of a block's lanes: `(su, sv, lanes)`.
pub(super) struct SpanGroups {
    groups: [(usize, usize, u16); LANES],
    pub(super) len: usize,
    /// The spans of every lane (those of the lanes grouped).
    su: [u32; LANES],
    sv: [u32; LANES],
}

impl SpanGroups {
    fn iter(&self) -> std::slice::Iter<'_, (usize, usize, u16)> {
        self.groups[..self.len].iter()
    }
}

/// Exact points and unit normals of 16 parameters on one bicubic patch.
#[derive(Debug, Clone, Copy, Default)]
pub struct BlockPointNormal {
    /// Points: x, y, z per lane.
    pub p: [Lanes; 3],
    /// Unit normals `S_u × S_v / |S_u × S_v|` (not oriented; NaN where the
    /// cross product vanishes).
    pub n: [Lanes; 3],
}

struct PointNormalOp<'a> {
    su: usize,
    sv: usize,
    /// The group's lanes: registers holding none of them are skipped.
    lanes: u16,
    u: &'a Lanes,
    v: &'a Lanes,
    ku: &'a [f32],
    kv: &'a [f32],
    cp: &'a [[f32; 4]],
    nu: usize,
    out: &'a mut BlockPointNormal,
}

impl pulp::WithSimd for PointNormalOp<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        let r = R(simd);
        let (u, _) = S::as_simd_f32s(self.u);
        let (v, _) = S::as_simd_f32s(self.v);
        for c in 0..LANES / S::F32_LANES {
            if !holds(self.lanes, c, S::F32_LANES) {
                continue;
            }
            let [sp, s_u, s_v] = point_partials(r, self.su, self.sv, u[c], v[c], self.ku, self.kv, self.cp, self.nu);
            let cr = [
                r.sub(r.mul(s_u[1], s_v[2]), r.mul(s_u[2], s_v[1])),
                r.sub(r.mul(s_u[2], s_v[0]), r.mul(s_u[0], s_v[2])),
                r.sub(r.mul(s_u[0], s_v[1]), r.mul(s_u[1], s_v[0])),
            ];
            let rcp = r.div(r.k(1.0), r.sqrt(r.dot(cr, cr)));
            for k in 0..3 {
                S::as_mut_simd_f32s(&mut self.out.p[k]).0[c] = sp[k];
                S::as_mut_simd_f32s(&mut self.out.n[k]).0[c] = r.mul(cr[k], rcp);
            }
        }
    }
}

/// The block evaluator: exact points and unit normals of patch `patch` of
/// the packed textures at 16 parameters, in f32, with the prepared bicubic
/// kernel on SIMD lanes (the current [`simd::level`]), once per pair of knot
/// spans the parameters fall in. `None` when the patch is not bicubic (call
/// [`eval_packed`] per parameter then). Parameters are clamped into the domain.
pub fn eval_bicubic_block(t: &PackedNurbs, patch: usize, u: &Lanes, v: &Lanes) -> Option<BlockPointNormal> {
    if patch >= t.patches as usize {
        return None;
    }
    let PatchRef { p, q, nu, nv, ku, kv, cp } = patch_ref(t, patch);
    if p != 3 || q != 3 {
        return None;
    }
    let (u0, u1, v0, v1) = (ku[3], ku[nu], kv[3], kv[nv]);
    let u = simd::map(u, |x| x.max(u0).min(u1));
    let v = simd::map(v, |x| x.max(v0).min(v1));
    let groups = span_groups(ku, kv, nu, nv, &u, &v, 0xffff)?;
    let mut out = BlockPointNormal::default();
    for (k, &(su, sv, lanes)) in groups.iter().enumerate() {
        if k == 0 {
            simd::run(PointNormalOp { su, sv, lanes, u: &u, v: &v, ku, kv, cp, nu, out: &mut out });
            continue;
        }
        let mut g = BlockPointNormal::default();
        simd::run(PointNormalOp { su, sv, lanes, u: &u, v: &v, ku, kv, cp, nu, out: &mut g });
        for lane in (0..LANES).filter(|l| lanes & (1 << l) != 0) {
            for c in 0..3 {
                out.p[c][lane] = g.p[c][lane];
                out.n[c][lane] = g.n[c][lane];
            }
        }
    }
    Some(out)
}

/// Cubic basis functions and first derivatives at `u` (knots of `span`
/// shared): the steps of `basis_ders_fixed::<f32, 3, 4>` in the same order.
#[inline(always)]
fn basis3<S: pulp::Simd>(r: R<S>, span: usize, u: S::f32s, k: &[f32]) -> [[S::f32s; 4]; 2] {
    BicubicOp::basis(r, span, u, k)
}

impl BicubicOp<'_> {
    /// Cubic basis functions and first derivatives at `u` (knots of `span` shared).
    #[inline(always)]
    fn basis<S: pulp::Simd>(r: R<S>, span: usize, u: S::f32s, k: &[f32]) -> [[S::f32s; 4]; 2] {
        let zero = r.k(0.0);
        let mut n = [zero; 4];
        n[0] = r.k(1.0);
        let mut left = [zero; 4];
        let mut right = [zero; 4];
        let mut row_p1 = [zero; 4];
        for j in 1..=3 {
            left[j] = r.sub(u, r.k(k[span + 1 - j]));
            right[j] = r.sub(r.k(k[span + j]), u);
            let mut saved = zero;
            for q in 0..j {
                // the reciprocal knot difference, one scalar for every lane
                let temp = r.mul(n[q], r.k(1.0 / (k[span + q + 1] - k[span + 1 + q - j])));
                n[q] = r.add(saved, r.mul(right[q + 1], temp));
                saved = r.mul(left[j - q], temp);
            }
            n[j] = saved;
            if j == 2 {
                row_p1 = n;
            }
        }
        // N'_{·,3} from the row of degree 2 (eq. 6)
        let first = span + 1 - 3;
        let mut d = [zero; 4];
        for q in 0..=3 {
            let i = first + q - 1;
            let mut v = zero;
            if q >= 1 {
                let den = k[i + 3] - k[i];
                if den > 0.0 {
                    v = r.add(v, r.mul(row_p1[q - 1], r.k(1.0 / den)));
                }
            }
            if q < 3 {
                let den = k[i + 4] - k[i + 1];
                if den > 0.0 {
                    v = r.sub(v, r.mul(row_p1[q], r.k(1.0 / den)));
                }
            }
            d[q] = r.mul(r.k(3.0), v);
        }
        [n, d]
    }
}

impl pulp::WithSimd for BicubicOp<'_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        let r = R(simd);
        let w = S::F32_LANES;
        let (u, _) = S::as_simd_f32s(self.u);
        let (v, _) = S::as_simd_f32s(self.v);
        let o = self.out;
        for c in 0..LANES / w {
            if !holds(self.lanes, c, w) {
                continue;
            }
            let zero = r.k(0.0);
            let win = &self.window;
            let [sp, s_u, s_v] = if win.w == 1 && win.h == 1 {
                point_partials(r, self.su, self.sv, u[c], v[c], self.ku, self.kv, self.cp, self.nu)
            } else {
                let spans = (S::as_simd_f32s(win.su).0[c], S::as_simd_f32s(win.sv).0[c]);
                let b = (
                    window_basis(r, self.su, win.w, u[c], spans.0, self.ku),
                    window_basis(r, self.sv, win.h, v[c], spans.1, self.kv),
                );
                window_partials(r, (self.su, self.sv), (win.w, win.h), &b, self.cp, self.nu)
            };
            // the depth of a seam fragment: the point pushed back from the camera
            if holds(self.seams, c, w) {
                let (cam, scale) = ([r.k(self.cam.x), r.k(self.cam.y), r.k(self.cam.z)], r.k(SEAM_DEPTH_SCALE));
                let at = [0, 1, 2].map(|k| r.add(cam[k], r.mul(r.sub(sp[k], cam[k]), scale)));
                S::as_mut_simd_f32s(&mut o.seam_depth).0[c] =
                    r.div(r.clip_row(self.m, 2, at), r.clip_row(self.m, 3, at));
            }
            // exact normal (degenerate lanes are redone per lane by the caller)
            let cr = [
                r.sub(r.mul(s_u[1], s_v[2]), r.mul(s_u[2], s_v[1])),
                r.sub(r.mul(s_u[2], s_v[0]), r.mul(s_u[0], s_v[2])),
                r.sub(r.mul(s_u[0], s_v[1]), r.mul(s_u[1], s_v[0])),
            ];
            let len = r.sqrt(r.dot(cr, cr));
            let scale = r.add(r.sqrt(r.dot(s_u, s_u)), r.sqrt(r.dot(s_v, s_v)));
            let rcp = r.div(r.k(1.0), len);
            let mut n = [r.mul(cr[0], rcp), r.mul(cr[1], rcp), r.mul(cr[2], rcp)];
            // finite: x − x is 0 for finite x, NaN otherwise
            let fin = r.add(r.add(r.sub(cr[0], cr[0]), r.sub(cr[1], cr[1])), r.sub(cr[2], cr[2]));
            let finite = r.0.select_f32s(r.0.less_than_f32s(fin, r.k(1.0)), r.k(1.0), zero);
            // two-sided: towards the camera
            let view = r.normalize_or_zero([
                r.sub(r.k(self.cam.x), sp[0]),
                r.sub(r.k(self.cam.y), sp[1]),
                r.sub(r.k(self.cam.z), sp[2]),
            ]);
            let back = r.0.less_than_f32s(r.dot(n, view), zero);
            for x in &mut n {
                *x = r.0.select_f32s(back, r.0.neg_f32s(*x), *x);
            }
            // depth of the exact point (glam's order: ((c0·x + c1·y) + c2·z) + c3·1)
            let depth = r.div(r.clip_row(self.m, 2, sp), r.clip_row(self.m, 3, sp));
            // Blinn–Phong terms
            let l = [r.k(self.light.x), r.k(self.light.y), r.k(self.light.z)];
            let ndl = r.pos(r.dot(n, l));
            let h = r.normalize_or_zero([r.add(l[0], view[0]), r.add(l[1], view[1]), r.add(l[2], view[2])]);
            let nh = r.pos(r.dot(n, h));
            let x2 = r.mul(nh, nh);
            let x3 = r.mul(x2, nh);
            let x6 = r.mul(x3, x3);
            let x12 = r.mul(x6, x6);
            let x24 = r.mul(x12, x12);
            let p48 = r.mul(x24, x24);
            let lit = r.0.less_than_f32s(zero, ndl);
            let spec = r.0.select_f32s(lit, r.mul(r.k(0.35), p48), zero);
            for (dst, val) in [
                (&mut o.nx, n[0]),
                (&mut o.ny, n[1]),
                (&mut o.nz, n[2]),
                (&mut o.depth, depth),
                (&mut o.ndl, ndl),
                (&mut o.spec, spec),
                (&mut o.len, len),
                (&mut o.scale, scale),
                (&mut o.finite, finite),
            ] {
                S::as_mut_simd_f32s(dst).0[c] = val;
            }
        }
    }
}
