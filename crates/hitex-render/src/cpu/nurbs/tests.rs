use super::block::*;
use super::*;

/// The lane-parallel span count equals `find_span` on clamped knot
/// vectors with interior multiplicities up to 4, on vectors whose end
/// spans are empty (start or end multiplicity 5) and on falling knots,
/// at random parameters, the knots themselves and both ends.
#[test]
fn lane_spans_equal_find_span() {
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32
    };
    for case in 0..2000 {
        let inner = (rnd() * 12.0) as usize;
        let mut interior: Vec<f32> = (0..inner).map(|_| (rnd() * 8.0).round() / 8.0).collect();
        interior.sort_by(f32::total_cmp);
        let mut k = vec![0.0f32; 4];
        k.extend(interior.iter().filter(|&&x| x > 0.0 && x < 1.0));
        k.extend([1.0f32; 4]);
        match case % 4 {
            1 => k.insert(0, 0.0),
            2 => k.push(1.0),
            3 if k.len() > 9 => k.swap(5, 6),
            _ => {}
        }
        let n = k.len() - 4;
        if n < 4 {
            continue;
        }
        let (lo, hi) = (k[3], k[n]);
        let x: Lanes = std::array::from_fn(|lane| match lane {
            0 => lo,
            1 => hi,
            2..=5 => k[(3 + lane) % k.len()].max(lo).min(hi),
            _ => lo + (hi - lo) * rnd(),
        });
        let s = lane_spans(&k, n, &x);
        for lane in 0..LANES {
            assert_eq!(s[lane] as usize, find_span(n - 1, 3, x[lane], &k), "knots {k:?} x {}", x[lane]);
        }
    }
}

/// The studio by hand: a viewer looking along +X at a mirror whose
/// normal leans back towards it by half the reflected ray's elevation.
#[test]
fn studio_lights_where_its_soft_boxes_are() {
    let (forward, up, view) = (Vec3::X, Vec3::Z, Vec3::NEG_X);
    let tilt = |deg: f32| {
        let a = deg.to_radians();
        Vec3::new(-a.cos(), 0.0, a.sin())
    };
    // reflected elevation 15° and 40°: the first two soft boxes
    assert!((studio(tilt(7.5), view, forward, up) - 1.0).abs() < 1e-5);
    assert!((studio(tilt(20.0), view, forward, up) - 1.0).abs() < 1e-5);
    // 28°: between them, the sky's grade
    let sky = 0.08 + 0.17 * 28.0 / 90.0;
    assert!((studio(tilt(14.0), view, forward, up) - sky).abs() < 1e-4);
    // head on: the horizon, no box
    assert!((studio(tilt(0.0), view, forward, up) - 0.08).abs() < 1e-5);
    // a floor seen from above reflects the sky ahead; seen from below, the floor
    let down = Vec3::new(1.0, 0.0, -1.0).normalize();
    assert!((studio(Vec3::Z, -down, forward, up) - (0.08 + 0.17 * 0.5)).abs() < 1e-4);
    assert!((studio(Vec3::NEG_Z, -Vec3::new(1.0, 0.0, 1.0).normalize(), forward, up) - 0.03).abs() < 1e-6);
    // a wall facing the viewer, seen from 20° above, reflects the cove's box at −20°
    assert!(
        (studio(Vec3::NEG_X, (tilt(0.0) + Vec3::Z * 20f32.to_radians().tan()).normalize(), forward, up) - 0.6).abs()
            < 1e-4
    );
    // the side light at azimuth 100° (to the viewer's right seen from behind)
    let side = up.cross(-forward);
    let r = ((-forward) * 100f32.to_radians().cos() + side * 100f32.to_radians().sin() + up * 25f32.to_radians().tan())
        .normalize();
    let n = (r + view).normalize();
    assert!((studio(n, view, forward, up) - 0.8).abs() < 1e-4);
}

/// The program's f32 lookup of a deviation grid agrees with the f64
/// twin in the core, no-data nodes and parameters outside the domain
/// included.
#[test]
fn deviation_lookup_agrees_with_the_core() {
    use hitex_core::nurbs::deviation::{NO_DATA, grid_value, is_no_data};
    let s = hitex_core::nurbs::NurbsSurface::new(
        1,
        1,
        2,
        2,
        vec![0.5, 0.5, 2.0, 2.0],
        vec![-1.0, -1.0, 3.0, 3.0],
        vec![[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [1.0, 1.0, 0.0, 1.0]],
    )
    .unwrap();
    let g = 7;
    let values: Vec<f32> =
        (0..g * g).map(|k| if k == 30 { NO_DATA } else { ((k * 37) % 11) as f32 * 0.013 - 0.05 }).collect();
    let mut t = PackedNurbs::new(std::slice::from_ref(&s));
    t.set_deviation(g, std::slice::from_ref(&values));
    let mut state = 11u32;
    let mut rnd = || {
        state = state.wrapping_mul(1664525).wrapping_add(1013904223);
        (state >> 8) as f32 / (1 << 24) as f32
    };
    let (mut holes, mut worst) = (0, 0.0f32);
    for _ in 0..2000 {
        let (u, v) = (rnd() * 2.0, rnd() * 5.0 - 1.5);
        let got = deviation_at(&t, 0, u, v);
        let want = grid_value(&values, g, s.domain(), u as f64, v as f64);
        assert_eq!(is_no_data(got), is_no_data(want), "({u}, {v})");
        if is_no_data(got) {
            holes += 1;
        } else {
            worst = worst.max((got - want).abs());
        }
    }
    assert!(holes > 20 && worst < 1e-6, "{holes} holes, worst {worst}");
    // a patch without a grid has no data
    let bare = PackedNurbs::new(std::slice::from_ref(&s));
    assert!(is_no_data(deviation_at(&bare, 0, 1.0, 1.0)));
}
use hitex_core::nurbs::NurbsSurface;

/// A rational 6×5 control net with varied weights.
fn net_6x5() -> Vec<[f64; 4]> {
    let mut pts = Vec::new();
    for j in 0..5 {
        for i in 0..6 {
            let (x, y) = (i as f64, j as f64);
            pts.push([x, y, (x * 0.9).sin() * (y * 0.7).cos(), 1.0 + 0.3 * ((i + j) % 3) as f64]);
        }
    }
    pts
}

/// A rational bicubic on that net with interior knots u 0.3, 0.55 and v 0.6.
fn bicubic_6x5() -> NurbsSurface {
    let knots_u = vec![0.0, 0.0, 0.0, 0.0, 0.3, 0.55, 1.0, 1.0, 1.0, 1.0];
    let knots_v = vec![0.0, 0.0, 0.0, 0.0, 0.6, 1.0, 1.0, 1.0, 1.0];
    NurbsSurface::new(3, 3, 6, 5, knots_u, knots_v, net_6x5()).unwrap()
}

#[test]
fn principal_curvatures_match_the_f64_reference() {
    // the f32 program's κ1 ≥ κ2 (from K and H of its own second
    // derivatives) against the f64 evaluator's, over a rational bicubic
    // with interior knots, on both kernels
    let s = bicubic_6x5();
    let packed = PackedNurbs::new(std::slice::from_ref(&s));
    let mut worst = 0.0f64;
    for prepared in [true, false] {
        for j in 0..13 {
            for i in 0..13 {
                let (u, v) = (0.02 + 0.96 * i as f32 / 12.0, 0.02 + 0.96 * j as f32 / 12.0);
                let e = eval_packed(&packed, 0, u, v, true, prepared);
                let (k1, k2) = principal(curvatures(&e, exact_normal(&e, Vec3::Z)));
                let c = s.curvature(u as f64, v as f64);
                let scale = c.principal[0].abs().max(c.principal[1].abs()).max(0.05);
                for (got, want) in [(k1, c.principal[0]), (k2, c.principal[1])] {
                    worst = worst.max((got as f64 - want).abs() / scale);
                }
                assert!(k1 >= k2, "κ1 {k1} < κ2 {k2} at ({u}, {v})");
            }
        }
    }
    assert!(worst < 2e-3, "largest relative deviation {worst}");
}

#[test]
fn principal_of_hand_worked_cases() {
    // sphere of radius 2: K = ¼, H = ½ → both ½; saddle z = xy at the
    // origin: K = −1, H = 0 → ±1; cylinder of radius 4: K = 0, H = ⅛ → ¼, 0
    assert_eq!(principal((0.25, 0.5)), (0.5, 0.5));
    assert_eq!(principal((-1.0, 0.0)), (1.0, -1.0));
    assert_eq!(principal((0.0, 0.125)), (0.25, 0.0));
    // rounding that makes H² − K slightly negative gives κ1 = κ2 = H, not NaN
    assert_eq!(principal((0.25 + 1e-7, 0.5)), (0.5, 0.5));
}

#[test]
fn block_evaluator_equals_the_per_parameter_one() {
    let s = bicubic_6x5();
    let packed = PackedNurbs::new(&[s]);
    let (mut taken, mut refused) = (0, 0);
    for row in 0..40 {
        for start in [0.0f32, 0.2, 0.28, 0.5, 0.9] {
            let u: Lanes = std::array::from_fn(|l| start + 0.005 * l as f32);
            let v: Lanes = [row as f32 / 39.0; LANES];
            let Some(b) = eval_bicubic_block(&packed, 0, &u, &v) else {
                refused += 1;
                continue;
            };
            taken += 1;
            for l in 0..LANES {
                let e = eval_packed(&packed, 0, u[l], v[l], false, true);
                let n = e.su.cross(e.sv).normalize();
                assert_eq!([b.p[0][l], b.p[1][l], b.p[2][l]], e.s.to_array(), "point ({}, {})", u[l], v[l]);
                assert_eq!([b.n[0][l], b.n[1][l], b.n[2][l]], n.to_array(), "normal ({}, {})", u[l], v[l]);
            }
        }
    }
    // blocks straddling u = 0.3 or u = 0.55 take one pass per span
    assert!(taken == 200 && refused == 0, "{taken} taken, {refused} refused");
}

/// The screen map is the Jacobian's inverse: a hand-worked diagonal and
/// shear, and none where the Jacobian is singular or not finite.
#[test]
fn to_pixels_inverts_the_jacobian() {
    // u grows 2 a pixel right, v 4 a pixel down: (du, dv) = (1, 1) is (½, ¼) pixel
    assert_eq!(to_pixels(&[2.0, 0.0, 0.0, 4.0], 1.0), Some([0.5, 0.0, 0.0, 0.25]));
    // in units of 2 pixels
    assert_eq!(to_pixels(&[2.0, 0.0, 0.0, 4.0], 2.0), Some([0.25, 0.0, 0.0, 0.125]));
    // a shear: x → (1, 0), y → (1, 1); (du, dv) = (1, 1) is one pixel down
    let m = to_pixels(&[1.0, 1.0, 0.0, 1.0], 1.0).unwrap();
    assert_eq!((m[0] + m[1], m[2] + m[3]), (0.0, 1.0));
    assert_eq!(to_pixels(&[1.0, 2.0, 2.0, 4.0], 1.0), None);
    assert_eq!(to_pixels(&[f32::NAN, 0.0, 0.0, 1.0], 1.0), None);
    assert_eq!(to_pixels(&[f32::INFINITY, 0.0, 0.0, 1.0], 1.0), None);
}

/// A fragment cut away by a trimming loop is a seam fragment within
/// [`SEAM_REACH`] pixels of the loop on screen and cut beyond, however
/// foreshortened the face: here each pixel across the edge moves (u, v)
/// by 0.001·(1, −1) and each pixel along it by l·(1, 1), up to twenty
/// times more (scaling u and v by their fwidths reached 11 pixels).
#[test]
fn the_seam_reach_is_a_distance_on_screen() {
    let s = bicubic_6x5();
    let mut prepared = crate::nurbs::PreparedNurbs::new(vec![s.clone()], &[s.domain()], 4);
    // a diamond kept: |u − ½| + |v − ½| ≤ ¼; the edge (½, ¼)–(¾, ½) faces (1, −1)
    let diamond = vec![[0.5, 0.25], [0.75, 0.5], [0.5, 0.75], [0.25, 0.5], [0.5, 0.25]];
    prepared.set_trims(&[vec![diamond]]);
    let t = &prepared.packed;
    let step = 0.001f32;
    for l in [0.001f32, 0.004, 0.02] {
        let g: UvGrad = [step, l, -step, l];
        for (k, want) in
            [(-2.0, Reach::Inside), (0.3, Reach::Seam), (0.7, Reach::Seam), (0.8, Reach::Cut), (3.0, Reach::Cut)]
        {
            let (u, v) = (0.625 + k * step, 0.375 - k * step);
            assert_eq!(reach(t, 0, u, v, &g), want, "{k} pixels across, {l} along");
        }
    }
}

/// The block path and the per-lane path give the same bits: colour and
/// depth of every lane, in the three modes the block path takes, with
/// the lanes of a block on one patch, on two bicubic patches of
/// different domains (one trimmed), or on a bicubic and a quartic one;
/// on one span pair, in window runs, in runs per pair and alone in their
/// run; inside, at seams and on boundary fans.
#[test]
fn block_bicubic_equals_the_per_lane_program_bit_for_bit() {
    // the first patch: nine knot spans across, so that lanes near one
    // point take windows and scattered lanes spread past a window's reach
    let net0: Vec<[f64; 4]> = (0..5)
        .flat_map(|j| {
            (0..12).map(move |i| {
                let (x, y) = (i as f64 * 0.5, j as f64);
                [x, y, (x * 0.9).sin() * (y * 0.7).cos(), 1.0 + 0.3 * ((i + j) % 3) as f64]
            })
        })
        .collect();
    let mut ku0 = vec![0.0; 4];
    ku0.extend((1..9).map(|i| i as f64 / 9.0));
    ku0.extend([1.0; 4]);
    let s = NurbsSurface::new(3, 3, 12, 5, ku0, bicubic_6x5().knots_v.clone(), net0).unwrap();
    // a second patch: the first moved and bent, over a smaller domain
    let mut net = net_6x5();
    for (i, p) in net.iter_mut().enumerate() {
        p[0] += 0.3;
        p[2] += 0.1 * (i % 3) as f64 * p[3];
    }
    let ku2 = vec![0.1, 0.1, 0.1, 0.1, 0.35, 0.6, 0.9, 0.9, 0.9, 0.9];
    let kv2 = vec![0.05, 0.05, 0.05, 0.05, 0.5, 0.95, 0.95, 0.95, 0.95];
    let s2 = NurbsSurface::new(3, 3, 6, 5, ku2, kv2, net.clone()).unwrap();
    // a third, quartic in u: the per-lane program's
    let ku3 = vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0, 1.0, 1.0];
    let s3 = NurbsSurface::new(4, 3, 6, 5, ku3, s.knots_v.clone(), net).unwrap();
    let ranges = [s.domain(), s2.domain(), s3.domain()];
    let mut prepared = crate::nurbs::PreparedNurbs::new(vec![s.clone(), s2, s3], &ranges, 4);
    // the second trimmed: a hole of radius 0.2 at (0.5, 0.5)
    let circle: Vec<[f64; 2]> = (0..=48)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / 48.0;
            [0.5 + 0.2 * a.cos(), 0.5 + 0.2 * a.sin()]
        })
        .collect();
    let outer = vec![[0.1, 0.05], [0.9, 0.05], [0.9, 0.95], [0.1, 0.95], [0.1, 0.05]];
    prepared.set_trims(&[vec![], vec![outer, circle], vec![]]);
    assert_eq!(prepared.packed.control[2 * prepared.packed.cp_width as usize][0], 4.0, "the quartic is kept");
    let cam =
        hitex_core::scene::Camera::new(Vec3::new(2.5, -6.0, 5.0), Vec3::new(2.5, 2.0, 0.0), Vec3::Z, 40.0, 0.1, 100.0)
            .unwrap();
    let (mut checked, mut many_spans, mut mixed, mut cut, mut quartic) = (0, 0, 0, 0, 0);
    let (mut windowed, mut split, mut seams, mut fans) = (0, 0, 0, 0);
    for mode in [SHADED, ISOPHOTE, NORMAL] {
        let mut frame = prepared.frame(&cam, 64, 48);
        frame.params[0] = mode;
        frame.params[3] = 1;
        let prog = NurbsProgram::new(&frame, &prepared.packed);
        for k in 0..260 {
            // 16 lanes near one point: most blocks share spans, some straddle a knot;
            // past 200, quads scattered over the patch (packed from several
            // triangles): many span pairs, lanes alone in theirs
            let (cu, cv) = ((k % 20) as f32 / 19.0, (k / 20 % 10) as f32 / 9.0);
            let scatter = |lane: usize| {
                let q = (lane / 4 * 7 + k * 3) % 13;
                let solo = if lane % 4 == 3 { 0.31 * (lane / 4) as f32 } else { 0.0 };
                (((q as f32 * 0.077 + solo) % 1.0), ((q as f32 * 0.131 + solo * 1.7) % 1.0))
            };
            let mut b = Block::<VARYINGS> {
                material: 0,
                x: 0,
                y: 0,
                v: [[0.0; LANES]; VARYINGS],
                w: [1.0; LANES],
                z: [0.5; LANES],
                live: 0xffff ^ (1 << (k % 16)),
                grad: [[[0.0; LANES]; 2]; 2],
            };
            for lane in 0..LANES {
                b.v[2][lane] = 1.0;
                b.v[3][lane] = (cu + 0.004 * (lane % 8) as f32).min(1.0);
                b.v[4][lane] = (cv + 0.004 * (lane / 8) as f32).min(1.0);
                if k >= 200 {
                    let (su, sv) = scatter(lane);
                    b.v[3][lane] = su + 0.002 * (lane % 2) as f32;
                    b.v[4][lane] = sv + 0.002 * (lane / 2 % 2) as f32;
                }
                // two blocks in three: the second or the third patch on some quads
                if k % 3 != 0 && (lane / 4 + k / 3) % 2 == 1 {
                    b.v[5][lane] = (k % 3) as f32;
                }
                // one block in seven: some lanes on a boundary fan of their patch
                if k % 7 == 0 && lane % 5 == 1 {
                    b.v[5][lane] += crate::nurbs::FAN_MARK;
                }
            }
            if k % 3 != 0 {
                mixed += 1;
            }
            b.fill_grads([3, 4]);
            {
                // patch 0: its header and knots lead the packed rows
                let t = &prepared.packed;
                let (nu, nv) = (t.control[0][2] as usize, t.control[0][3] as usize);
                let ku = &t.knots_u[1..1 + t.knots_u[0] as usize];
                let kv = &t.knots_v[1..1 + t.knots_v[0] as usize];
                let mut on0 = 0u16;
                for lane in 0..LANES {
                    on0 |= ((b.v[5][lane].round() == 0.0) as u16) << lane;
                }
                let clamp = |x: &Lanes| simd::map(x, |x| x.clamp(0.0, 1.0));
                let (u, v) = (clamp(&b.v[3]), clamp(&b.v[4]));
                if k >= 200 && span_groups(ku, kv, nu, nv, &b.v[3], &b.v[4], b.live).is_some_and(|g| g.len > 4) {
                    many_spans += 1;
                }
                if let Some(g) = span_groups(ku, kv, nu, nv, &u, &v, b.live & on0) {
                    let w = window(&g, b.live & on0).is_some();
                    windowed += w as usize;
                    // runs per span pair, more than four in the block: lanes alone in theirs
                    split += (!w && g.len > 4) as usize;
                }
            }
            let mut rgba = [[0u8; 4]; LANES];
            let mut depth = [f32::NAN; LANES];
            if prog.block_bicubic(&b, &mut rgba, &mut depth).is_none() {
                continue;
            }
            checked += 1;
            for lane in 0..LANES {
                if b.live & (1 << lane) == 0 {
                    continue;
                }
                let v: [f32; VARYINGS] = std::array::from_fn(|j| b.v[j][lane]);
                let (c, d) = prog.lane(&v, &lane_grad(&b, lane));
                cut += d.is_nan() as usize;
                // seam lanes the kernel shades (bicubic patch, a normal that is not degenerate)
                let patch = v[5].round() as usize;
                let mut at = reach(&prepared.packed, patch, v[3], v[4], &lane_grad(&b, lane));
                if at == Reach::Inside && is_fan(v[5]) {
                    at = Reach::Seam;
                    fans += 1;
                }
                let e = eval_packed(&prepared.packed, patch, v[3], v[4], false, true);
                let sound = e.su.cross(e.sv).length() > 1e-6 * (e.su.length() + e.sv.length()).powi(2);
                seams += (at == Reach::Seam && patch != 2 && sound) as usize;
                quartic += (v[5] == 2.0) as usize;
                assert_eq!(rgba[lane], c, "mode {mode} block {k} lane {lane}");
                assert_eq!(depth[lane].to_bits(), d.to_bits(), "mode {mode} block {k} lane {lane}");
            }
        }
    }
    assert!(checked > 3 * 250, "the block path took only {checked} blocks");
    assert!(mixed > 160, "only {mixed} blocks over two patches");
    assert!(cut > 100 && quartic > 500, "{cut} lanes cut away, {quartic} on the quartic patch");
    assert!(many_spans >= 9, "only {many_spans} blocks over more than four span pairs");
    assert!(windowed >= 30 && seams >= 30, "only {windowed} window runs, {seams} seam lanes");
    assert!(split >= 9 && fans >= 30, "only {split} blocks of runs per span pair, {fans} fan lanes");
}

#[test]
fn packed_f32_evaluation_tracks_the_f64_reference() {
    let s = NurbsSurface::new(
        3,
        2,
        6,
        5,
        vec![0.0, 0.0, 0.0, 0.0, 0.3, 0.55, 1.0, 1.0, 1.0, 1.0],
        vec![0.0, 0.0, 0.0, 0.4, 0.6, 1.0, 1.0, 1.0],
        net_6x5(),
    )
    .unwrap();
    let packed = PackedNurbs::new(&[s.clone(), s.elevate(true)]);
    for k in 0..=20 {
        for l in 0..=20 {
            let (u, v) = (k as f64 / 20.0, l as f64 / 20.0);
            let r = s.derivatives(u, v, 2);
            for patch in 0..2 {
                let e = eval_packed(&packed, patch, u as f32, v as f32, true, patch == 0);
                let pairs = [
                    (e.s, r.d[0][0]),
                    (e.su, r.d[1][0]),
                    (e.sv, r.d[0][1]),
                    (e.suu, r.d[2][0]),
                    (e.suv, r.d[1][1]),
                    (e.svv, r.d[0][2]),
                ];
                for (i, (a, b)) in pairs.iter().enumerate() {
                    let scale = 1.0 + b.iter().map(|x| x.abs()).fold(0.0, f64::max);
                    for t in 0..3 {
                        assert!(
                            (a[t] as f64 - b[t]).abs() < 2e-4 * scale,
                            "patch {patch} ({u}, {v}) d{i}[{t}]: {} vs {}",
                            a[t],
                            b[t]
                        );
                    }
                }
            }
        }
    }
}
