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
        let both = draw(&[[-s, -s, s, -s, s, s], [-s, -s, s, s, -s, s]], 16, 16).iter().filter(|&&n| n == 1).count();
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
    let draws =
        [d(1, 3 * long), d(1 + 3 * long, 0), d(1 + 3 * long, 3 * 50 + 2), d(1 + 3 * (long + 50), 3 * (n - long - 50))];
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
    let program = || Ids::<DEPTH, PACK, LP> { blocks: 0.into(), quads: 0.into(), lanes: 0.into(), mixed: false.into() };
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
        let n =
            if LP { b.live.count_ones() as usize } else { (0..4).filter(|q| (b.live >> (4 * q)) & 0xf != 0).count() };
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
