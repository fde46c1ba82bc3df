//! NURBS images: CPU against stored references, GPU against CPU.

mod common;

use common::*;
use hitex_render::CpuRenderer;
use hitex_render::nurbs::{NurbsMode, PreparedNurbs};

const S: u32 = 160;

fn teapot() -> PreparedNurbs {
    let m = hitex_io::models::load_model("teapot").unwrap();
    PreparedNurbs::new(m.nurbs(), &m.ranges(), 6)
}

fn modes() -> [(&'static str, NurbsMode); 7] {
    [
        ("shaded", NurbsMode::Shaded),
        ("highlight", NurbsMode::Highlight),
        ("isophote", NurbsMode::Isophote),
        ("zebra", NurbsMode::Zebra),
        ("gauss", NurbsMode::Gauss),
        ("mean", NurbsMode::Mean),
        ("vertex-normals", NurbsMode::VertexNormals),
    ]
}

#[test]
fn teapot_cpu_matches_references() {
    let cpu = CpuRenderer::new();
    let mut p = teapot();
    for (name, mode) in modes() {
        p.mode = mode;
        let f = cpu.render_nurbs(&p, &p.camera, S, S).unwrap();
        let r = reference(&format!("teapot-{name}"), &f);
        assert_images(&format!("teapot-{name}-cpu"), &f, &r, CPU_VS_REFERENCE);
    }
}

#[test]
fn teapot_has_no_nan_or_black_pixel() {
    // every covered pixel of the shaded teapot is lit: the limit normals at the
    // lid and bottom poles keep shading finite
    let cpu = CpuRenderer::new();
    let mut p = teapot();
    p.mode = NurbsMode::Normal;
    for turn in [0.0f32, 1.3, 2.9, 4.4] {
        let cam = p.camera.orbit(turn);
        let f = cpu.render_nurbs(&p, &cam, S, S).unwrap();
        let e = hitex_core::texture::linear_to_srgb_u8;
        let bg = [e(p.background.x), e(p.background.y), e(p.background.z)];
        for px in f.rgba.chunks_exact(4) {
            let is_bg = px[0].abs_diff(bg[0]) <= 8 && px[1].abs_diff(bg[1]) <= 8 && px[2].abs_diff(bg[2]) <= 8;
            // a covered pixel holds (n + 1)/2 of a unit normal (NaN would write 0, i.e. |n| = √3)
            let n: Vec<f32> = px[..3].iter().map(|&c| c as f32 / 255.0 * 2.0 - 1.0).collect();
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!(is_bg || (len - 1.0).abs() < 0.03, "pixel {px:?} is no unit normal (|n| = {len}) at turn {turn}");
        }
    }
}

#[test]
fn teapot_gpu_matches_cpu() {
    let Some(mut gpu) = gpu_or_skip("teapot_gpu_matches_cpu") else { return };
    let cpu = CpuRenderer::new();
    let mut p = teapot();
    for (name, mode) in modes() {
        p.mode = mode;
        let c = cpu.render_nurbs(&p, &p.camera, S, S).unwrap();
        let g = gpu.render_nurbs(&p, &p.camera, S, S).unwrap();
        // band modes flip whole pixels at band edges: judged like aliased images
        assert_images(&format!("teapot-{name}-gpu"), &g, &c, GPU_VS_CPU_ALIASED);
    }
}

#[test]
fn prepared_and_generic_kernels_agree_on_both_backends() {
    let cpu = CpuRenderer::new();
    let mut p = teapot();
    p.mode = NurbsMode::Mean;
    p.prepared_kernels = true;
    let a = cpu.render_nurbs(&p, &p.camera, S, S).unwrap();
    p.prepared_kernels = false;
    let b = cpu.render_nurbs(&p, &p.camera, S, S).unwrap();
    assert_images("teapot-generic-vs-prepared-cpu", &b, &a, CPU_VS_REFERENCE);
    let Some(mut gpu) = gpu_or_skip("prepared_and_generic_kernels_agree_on_both_backends") else { return };
    let g = gpu.render_nurbs(&p, &p.camera, S, S).unwrap();
    assert_images("teapot-generic-gpu", &g, &a, GPU_VS_CPU);
}

/// A wavy patch of the given degrees with non-uniform knots and varying weights.
fn wavy(p: usize, q: usize, nu: usize, nv: usize) -> hitex_core::nurbs::NurbsSurface {
    let knots = |n: usize, d: usize| -> Vec<f64> {
        let inner = n - d - 1;
        let mut k = vec![0.0; d + 1];
        for i in 1..=inner {
            let x = i as f64 / (inner + 1) as f64;
            k.push(x * x * (3.0 - 2.0 * x));
        }
        k.extend(vec![1.0; d + 1]);
        k
    };
    let mut pts = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let (x, y) = (i as f64 / (nu - 1) as f64 * 4.0 - 2.0, j as f64 / (nv - 1) as f64 * 4.0 - 2.0);
            pts.push([x, y, 0.6 * (1.3 * x).sin() * (0.9 * y).cos(), 1.0 + 0.25 * ((i + 2 * j) % 3) as f64]);
        }
    }
    hitex_core::nurbs::NurbsSurface::new(p, q, nu, nv, knots(nu, p), knots(nv, q), pts).unwrap()
}

#[test]
fn mixed_and_high_degrees_render_and_agree() {
    // degrees as real CAD exports mix them, up to 9 (and the maximum, 15)
    let patches = [wavy(9, 9, 12, 11), wavy(5, 6, 8, 9), wavy(7, 3, 9, 6), wavy(5, 1, 7, 3), wavy(15, 2, 16, 4)];
    let ranges: Vec<_> = patches.iter().map(|s| s.domain()).collect();
    let cpu = CpuRenderer::new();
    let mut gpu = gpu_or_skip("mixed_and_high_degrees_render_and_agree");
    for (k, s) in patches.iter().enumerate() {
        let mut p = PreparedNurbs::new(vec![s.clone()], &ranges[k..=k], 6);
        for mode in [NurbsMode::Shaded, NurbsMode::Mean] {
            p.mode = mode;
            let c = cpu.render_nurbs(&p, &p.camera, 96, 96).unwrap();
            let e = hitex_core::texture::linear_to_srgb_u8;
            let bg = [e(p.background.x), e(p.background.y), e(p.background.z)];
            let covered = c.rgba.chunks_exact(4).filter(|px| px[..3] != bg).count();
            assert!(covered > 96 * 96 / 10, "degree {}×{}: only {covered} pixels drawn", s.degree_u, s.degree_v);
            if let Some(g) = gpu.as_mut() {
                let f = g.render_nurbs(&p, &p.camera, 96, 96).unwrap();
                assert_images(
                    &format!("degree-{}x{}-{mode:?}-gpu", s.degree_u, s.degree_v),
                    &f,
                    &c,
                    GPU_VS_CPU_ALIASED,
                );
            }
        }
    }
}

#[test]
fn elevation_to_the_prepared_degree_keeps_the_image() {
    let s = wavy(2, 1, 5, 3);
    let range = [s.domain()];
    let cpu = CpuRenderer::new();
    let mut p = PreparedNurbs::new(vec![s], &range, 6);
    p.mode = NurbsMode::Isophote;
    let before = cpu.render_nurbs(&p, &p.camera, 96, 96).unwrap();
    assert_eq!(p.elevate_to_prepared(), 1);
    assert_eq!((p.surfaces[0].degree_u, p.surfaces[0].degree_v), (3, 3));
    let after = cpu.render_nurbs(&p, &p.camera, 96, 96).unwrap();
    assert_images("elevated-cpu", &after, &before, GPU_VS_CPU);
    if let Some(mut g) = gpu_or_skip("elevation_to_the_prepared_degree_keeps_the_image") {
        let f = g.render_nurbs(&p, &p.camera, 96, 96).unwrap();
        assert_images("elevated-gpu", &f, &before, GPU_VS_CPU_ALIASED);
    }
}

#[test]
fn patch_boundaries_overlay_on_both_backends() {
    let cpu = CpuRenderer::new();
    let mut p = teapot();
    p.mode = NurbsMode::Shaded;
    let plain = cpu.render_nurbs(&p, &p.camera, S, S).unwrap();
    p.boundaries = true;
    let c = cpu.render_nurbs(&p, &p.camera, S, S).unwrap();
    let lines = c.rgba.chunks_exact(4).filter(|px| px[..3] == [20, 20, 24]).count();
    let before = plain.rgba.chunks_exact(4).filter(|px| px[..3] == [20, 20, 24]).count();
    assert!(lines > before + 200, "{lines} boundary pixels (plain: {before})");
    if let Some(mut g) = gpu_or_skip("patch_boundaries_overlay_on_both_backends") {
        let f = g.render_nurbs(&p, &p.camera, S, S).unwrap();
        assert_images("teapot-boundaries-gpu", &f, &c, GPU_VS_CPU_ALIASED);
    }
}

#[test]
fn trimmed_hole_is_cut_on_both_backends() {
    // a unit square with a circular hole of radius 0.3 in parameter space
    let s = wavy(1, 1, 2, 2);
    let range = [s.domain()];
    let mut p = PreparedNurbs::new(vec![s.clone()], &range, 4);
    p.mode = NurbsMode::Normal;
    let circle: Vec<[f64; 2]> = (0..=64)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / 64.0;
            [0.5 + 0.3 * a.cos(), 0.5 + 0.3 * a.sin()]
        })
        .collect();
    let outer = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]];
    let full = CpuRenderer::new().render_nurbs(&p, &p.camera, 96, 96).unwrap();
    p.set_trims(&[vec![outer, circle]]);
    let cpu = CpuRenderer::new().render_nurbs(&p, &p.camera, 96, 96).unwrap();
    // the patch's centre (u, v) = (0.5, 0.5) projects near the image centre: background there now
    let e = hitex_core::texture::linear_to_srgb_u8;
    let bg = [e(p.background.x), e(p.background.y), e(p.background.z)];
    let drawn = |f: &hitex_render::Frame| f.rgba.chunks_exact(4).filter(|px| px[..3] != bg).count();
    let (a, b) = (drawn(&full), drawn(&cpu));
    // the hole removes π·0.3² ≈ 28 % of the square's area (perspective changes it a little)
    let cut = 1.0 - b as f64 / a as f64;
    assert!((0.18..0.38).contains(&cut), "cut {cut}: {a} → {b} pixels");
    if let Some(mut g) = gpu_or_skip("trimmed_hole_is_cut_on_both_backends") {
        let f = g.render_nurbs(&p, &p.camera, 96, 96).unwrap();
        assert_images("trimmed-hole-gpu", &f, &cpu, GPU_VS_CPU_ALIASED);
    }
}

/// Pixels drawn farther than `r` pixels from every pixel whose centre's
/// ray meets the plane z = 0 inside the disc of radius `radius` about the
/// origin (the exact outline of a trimmed disc), seen by `cam`.
fn past_the_disc(f: &hitex_render::Frame, cam: &hitex_core::scene::Camera, radius: f32, bg: [u8; 3], r: i64) -> usize {
    let (w, h) = (f.width as i64, f.height as i64);
    let inv = cam.view_proj(w as f32 / h as f32).inverse();
    let inside: Vec<bool> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let ndc = glam::Vec2::new(2.0 * x / w as f32 - 1.0, 1.0 - 2.0 * y / h as f32);
            let a = inv.project_point3(ndc.extend(0.0));
            let b = inv.project_point3(ndc.extend(1.0));
            let t = a.z / (a.z - b.z);
            let p = a + (b - a) * t;
            t > 0.0 && p.truncate().length() <= radius
        })
        .collect();
    (0..w * h)
        .filter(|&i| {
            let px = &f.rgba[4 * i as usize..4 * i as usize + 3];
            if px == bg {
                return false;
            }
            let (x, y) = (i % w, i / w);
            !(-r..=r).any(|dy| {
                (-r..=r).any(|dx| {
                    let (xx, yy) = (x + dx, y + dy);
                    xx >= 0 && yy >= 0 && xx < w && yy < h && inside[(yy * w + xx) as usize]
                })
            })
        })
        .count()
}

#[test]
fn an_oblique_trimmed_disc_stays_within_its_outline() {
    // a disc of radius 0.6 trimmed from a flat square whose parameter axes
    // run at 45° to the view, seen 10° above its plane: each pixel moves
    // (u, v) far along the line of sight and little across it, so a seam
    // reach measured in fwidths of u and v drew the disc 3.6 pixels wider at
    // its sides; measured on screen it stays under a pixel
    let (c, e) = (std::f64::consts::FRAC_1_SQRT_2, 1.0);
    // S(u, v) = (u − v, u + v − 1, 0)·√2·e over [0, 1]²: centre (½, ½) at the origin
    let corner = |u: f64, v: f64| [(u - v) * 2.0 * c * e, (u + v - 1.0) * 2.0 * c * e, 0.0, 1.0];
    let pts = vec![corner(0.0, 0.0), corner(0.0, 1.0), corner(1.0, 0.0), corner(1.0, 1.0)];
    let s = hitex_core::nurbs::NurbsSurface::new(1, 1, 2, 2, vec![0.0, 0.0, 1.0, 1.0], vec![0.0, 0.0, 1.0, 1.0], pts)
        .unwrap();
    // radius 0.6 in space is 0.6 / (2·e) = 0.3 in parameters
    let disc: Vec<[f64; 2]> = (0..=96)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / 96.0;
            [0.5 + 0.3 * a.cos(), 0.5 + 0.3 * a.sin()]
        })
        .collect();
    let mut p = PreparedNurbs::new(vec![s.clone()], &[s.domain()], 8);
    p.set_trims(&[vec![disc]]);
    let elev = 10f32.to_radians();
    let cam = hitex_core::scene::Camera::new(
        glam::Vec3::new(0.0, -5.0 * elev.cos(), 5.0 * elev.sin()),
        glam::Vec3::ZERO,
        glam::Vec3::Z,
        10.0,
        0.1,
        100.0,
    )
    .unwrap();
    let bg = {
        let e = hitex_core::texture::linear_to_srgb_u8;
        [e(p.background.x), e(p.background.y), e(p.background.z)]
    };
    let (w, h) = (320, 120);
    let cpu = CpuRenderer::new().render_nurbs(&p, &cam, w, h).unwrap();
    let drawn = cpu.rgba.chunks_exact(4).filter(|px| px[..3] != bg).count();
    assert!(drawn > 2000, "{drawn} pixels of the disc");
    // every drawn pixel within a pixel of the exact outline (the polyline is
    // inside the circle; the seam reach adds at most 0.75 pixel)
    let past = past_the_disc(&cpu, &cam, 0.6, bg, 1);
    assert_eq!(past, 0, "cpu: {past} pixels drawn more than a pixel past the disc");
    if let Some(mut g) = gpu_or_skip("an_oblique_trimmed_disc_stays_within_its_outline") {
        let f = g.render_nurbs(&p, &cam, w, h).unwrap();
        let past = past_the_disc(&f, &cam, 0.6, bg, 1);
        assert_eq!(past, 0, "gpu: {past} pixels drawn more than a pixel past the disc");
        assert_images("oblique-disc-gpu", &f, &cpu, GPU_VS_CPU_ALIASED);
    }
}

#[test]
fn step_parts_render_alike_on_both_backends() {
    // trims from B-rep loops (winding loops closed at a seam, pcurves, projected circles),
    // analytic faces as rational quadratics, assembly placements
    for (name, size) in [("face_recognition_sample_part.stp", (160, 120)), ("as1-oc-214.stp", (200, 130))] {
        let path = format!("{}/../hitex-io/data/cad/{name}", env!("CARGO_MANIFEST_DIR"));
        let m = hitex_io::models::load_model(&path).unwrap();
        let mut p = PreparedNurbs::trimmed(m.nurbs(), &m.ranges(), &m.trims(), 6);
        p.set_colors(&m.colors);
        let cpu = CpuRenderer::new().render_nurbs(&p, &p.camera, size.0, size.1).unwrap();
        if name.starts_with("as1") {
            // the file's colours: blue nuts, a yellow-green plate
            let blue = cpu.rgba.chunks_exact(4).filter(|c| c[2] as i32 > c[0] as i32 + 100 && c[2] > c[1]).count();
            let yellow = cpu.rgba.chunks_exact(4).filter(|c| c[0] > 120 && c[1] > 150 && c[2] < 60).count();
            assert!(blue > 20 && yellow > 500, "{blue} blue, {yellow} yellow pixels");
        }
        let e = hitex_core::texture::linear_to_srgb_u8;
        let bg = [e(p.background.x), e(p.background.y), e(p.background.z)];
        let drawn = cpu.rgba.chunks_exact(4).filter(|px| px[..3] != bg).count();
        assert!(drawn > (size.0 * size.1 / 8) as usize, "{name}: {drawn} model pixels");
        if let Some(mut g) = gpu_or_skip("step_parts_render_alike_on_both_backends") {
            let f = g.render_nurbs(&p, &p.camera, size.0, size.1).unwrap();
            assert_images(&format!("step-{name}-gpu"), &f, &cpu, GPU_VS_CPU_ALIASED);
        }
    }
}

#[test]
fn second_prepared_degree_and_elevation_to_the_nearest_prepared_degree() {
    let cpu = CpuRenderer::new();
    let mut gpu = gpu_or_skip("second_prepared_degree_and_elevation_to_the_nearest_prepared_degree");
    for (p, q, nu, nv) in [(5, 5, 8, 7), (3, 5, 6, 7), (5, 3, 7, 5), (4, 2, 6, 4)] {
        let s = wavy(p, q, nu, nv);
        let range = [s.domain()];
        let mut prep = PreparedNurbs::new(vec![s], &range, 6);
        prep.mode = NurbsMode::Mean;
        prep.prepared_kernels = false;
        let generic = cpu.render_nurbs(&prep, &prep.camera, 96, 96).unwrap();
        prep.prepared_kernels = true;
        if (p, q) == (4, 2) {
            // 4 → 5 and 2 → 3: the nearest prepared degrees above
            assert_eq!(prep.elevate_to_prepared(), 1);
            assert_eq!((prep.surfaces[0].degree_u, prep.surfaces[0].degree_v), (5, 3));
        }
        let fixed = cpu.render_nurbs(&prep, &prep.camera, 96, 96).unwrap();
        assert_images(&format!("prepared-{p}x{q}-cpu"), &fixed, &generic, GPU_VS_CPU);
        if let Some(g) = gpu.as_mut() {
            let f = g.render_nurbs(&prep, &prep.camera, 96, 96).unwrap();
            assert_images(&format!("prepared-{p}x{q}-gpu"), &f, &fixed, GPU_VS_CPU);
        }
    }
}

/// Pixels where `f` shows the background but a dense tessellation covers
/// every pixel within `r` of it (cracks, not the silhouette differences a
/// coarse tessellation has).
fn cracks(f: &hitex_render::Frame, dense: &hitex_render::Frame, bg: [u8; 3], r: usize) -> Vec<usize> {
    let (w, h) = (f.width as usize, f.height as usize);
    let is_bg = |g: &hitex_render::Frame, i: usize| g.rgba[i * 4..i * 4 + 3] == bg;
    // erode the dense coverage by r: rows, then columns
    let covered: Vec<bool> = (0..w * h).map(|i| !is_bg(dense, i)).collect();
    let mut rows = vec![false; w * h];
    for y in 0..h {
        for x in r..w.saturating_sub(r) {
            rows[y * w + x] = (x - r..=x + r).all(|k| covered[y * w + k]);
        }
    }
    let mut out = Vec::new();
    for y in r..h.saturating_sub(r) {
        for x in 0..w {
            let i = y * w + x;
            if (y - r..=y + r).all(|k| rows[k * w + x]) && is_bg(f, i) {
                out.push(i);
            }
        }
    }
    out
}

/// Two halves of a tube (exact rational quadratic arcs) meeting at x = 1.
fn split_tube() -> Vec<hitex_core::nurbs::NurbsSurface> {
    let r = std::f64::consts::FRAC_1_SQRT_2;
    // a half circle of radius 1 in the y–z plane: two 90° arcs
    let arc = [(1.0, 0.0, 1.0), (1.0, 1.0, r), (0.0, 1.0, 1.0), (-1.0, 1.0, r), (-1.0, 0.0, 1.0)];
    let half = |x0: f64| {
        let mut pts = Vec::new();
        for &(y, z, w) in &arc {
            for x in [x0, x0 + 1.0] {
                pts.push([x, y, z, w]);
            }
        }
        hitex_core::nurbs::NurbsSurface::new(
            1,
            2,
            2,
            5,
            vec![0.0, 0.0, 1.0, 1.0],
            vec![0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 1.0],
            pts,
        )
        .unwrap()
    };
    vec![half(0.0), half(1.0)]
}

fn assert_no_cracks(name: &str, p: &PreparedNurbs, dense: &PreparedNurbs, cams: &[hitex_core::scene::Camera]) {
    let cpu = CpuRenderer::new();
    let e = hitex_core::texture::linear_to_srgb_u8;
    let bg = [e(p.background.x), e(p.background.y), e(p.background.z)];
    let mut found = Vec::new();
    for (k, cam) in cams.iter().enumerate() {
        let mut f = cpu.render_nurbs(p, cam, 640, 480).unwrap();
        let reference = cpu.render_nurbs(dense, cam, 640, 480).unwrap();
        let holes = cracks(&f, &reference, bg, 8);
        if !holes.is_empty() {
            for &i in &holes {
                f.rgba[i * 4..i * 4 + 3].copy_from_slice(&[255, 0, 0]);
            }
            save(&out_dir().join(format!("cracks-{name}-{k}.png")), f.width, f.height, &f.rgba);
        }
        found.push(holes.len());
    }
    assert!(found.iter().all(|&n| n == 0), "{name}: cracks per view {found:?}; marked red in {}", out_dir().display());
}

#[test]
fn seams_between_patches_leave_no_cracks() {
    // neighbours tessellated independently: the shared edge of the tube's
    // halves is cut into 6 chords on one side and 9 on the other, and the
    // teapot's patches are cut at a few densities
    let tube = split_tube();
    let ranges: Vec<_> = tube.iter().map(|s| s.domain()).collect();
    let p = PreparedNurbs::with_densities(tube.clone(), &ranges, &[6, 9]);
    let dense = PreparedNurbs::with_densities(tube, &ranges, &[96, 96]);
    let cams: Vec<_> = [0.0f32, 0.5, 1.2, 2.5, 3.6].iter().map(|&t| dense.camera.orbit(t)).collect();
    assert_no_cracks("tube", &p, &dense, &cams);

    let m = hitex_io::models::load_model("teapot").unwrap();
    let dense = PreparedNurbs::new(m.nurbs(), &m.ranges(), 64);
    let cams: Vec<_> = [0.0f32, 90.0, 180.0, 270.0].iter().map(|t| dense.camera.orbit(t.to_radians())).collect();
    for density in [3, 4, 8] {
        let p = PreparedNurbs::new(m.nurbs(), &m.ranges(), density);
        assert_no_cracks(&format!("teapot-{density}"), &p, &dense, &cams);
    }
}

#[test]
fn faces_meeting_along_trims_leave_no_pinholes() {
    // a disc and the square around it, cut from one plane by two different
    // polylines of the same circle (67 and 48 chords, less than half a pixel
    // apart): each face is drawn up to 0.75 pixel on screen past its trim, behind
    // the other, so no pixel between the two polylines shows the background
    let s = wavy(1, 1, 2, 2);
    let circle = |n: usize, phase: f64| -> Vec<[f64; 2]> {
        (0..=n)
            .map(|i| {
                let a = std::f64::consts::TAU * (i as f64 + phase) / n as f64;
                [0.5 + 0.3 * a.cos(), 0.5 + 0.3 * a.sin()]
            })
            .collect()
    };
    let outer = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]];
    let faces = vec![s.clone(), s.clone()];
    let ranges = [s.domain(), s.domain()];
    let mut p = PreparedNurbs::new(faces.clone(), &ranges, 8);
    p.set_trims(&[vec![outer, circle(48, 0.0)], vec![circle(67, 0.5)]]);
    let mut whole = PreparedNurbs::new(vec![s.clone()], &[s.domain()], 8);
    whole.mode = p.mode;
    let cams: Vec<_> = [0.0f32, 0.8, 2.0].iter().map(|&t| whole.camera.orbit(t)).collect();
    assert_no_cracks("trims", &p, &whole, &cams);
    if let Some(mut g) = gpu_or_skip("faces_meeting_along_trims_leave_no_pinholes") {
        let e = hitex_core::texture::linear_to_srgb_u8;
        let bg = [e(p.background.x), e(p.background.y), e(p.background.z)];
        for cam in &cams {
            let f = g.render_nurbs(&p, cam, 640, 480).unwrap();
            let reference = CpuRenderer::new().render_nurbs(&whole, cam, 640, 480).unwrap();
            let holes = cracks(&f, &reference, bg, 8);
            assert!(holes.is_empty(), "gpu: {} pixels of background between the faces", holes.len());
        }
    }
}

#[test]
fn every_frame_size_renders() {
    // blocks at the right and bottom edges have lanes outside the frame;
    // none may be read or written
    let cpu = CpuRenderer::new();
    for name in ["teapot", "surface", "spray"] {
        let m = hitex_io::models::load_model(name).unwrap();
        let mut p = PreparedNurbs::new(m.nurbs(), &m.ranges(), 4);
        for mode in [NurbsMode::Shaded, NurbsMode::Isophote, NurbsMode::Gauss] {
            p.mode = mode;
            for (w, h) in (1..=80).map(|s| (s, s)).chain([(107, 80), (17, 640), (100, 1), (1, 100), (9, 3)]) {
                let f = cpu.render_nurbs(&p, &p.camera, w, h).unwrap();
                assert_eq!(f.rgba.len(), (w * h * 4) as usize, "{name} {w}x{h}");
            }
        }
    }
}

#[test]
fn the_conservative_early_depth_changes_no_pixel() {
    // fragments behind the depth already drawn by more than the
    // tessellation's deviation allows are skipped; every image stays the same
    // bit for bit
    let cpu = CpuRenderer::new();
    let holed = {
        let m = hitex_io::models::load_model(concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/holed-square.igs"))
            .unwrap();
        let mut p = PreparedNurbs::new(m.nurbs(), &m.ranges(), 8);
        let trims: Vec<_> = m.surfaces.iter().map(|s| s.trim.clone()).collect();
        p.set_trims(&trims);
        p
    };
    let mut models = vec![holed];
    for (name, density) in [("teapot", 8), ("spray", 4), ("surface", 8), ("teapot", 2)] {
        let m = hitex_io::models::load_model(name).unwrap();
        models.push(PreparedNurbs::new(m.nurbs(), &m.ranges(), density));
    }
    assert!(models[1].tess_deviation > 0.0, "the teapot's tessellation departs from it");
    for mut p in models {
        for mode in [NurbsMode::Shaded, NurbsMode::Isophote, NurbsMode::Mean] {
            p.mode = mode;
            for turn in [0.0f32, 1.1, 2.3, 3.9, 5.2] {
                let cam = p.camera.orbit(turn);
                p.early_depth = true;
                let with = cpu.render_nurbs(&p, &cam, 200, 150).unwrap();
                p.early_depth = false;
                let without = cpu.render_nurbs(&p, &cam, 200, 150).unwrap();
                let differ =
                    with.rgba.chunks_exact(4).zip(without.rgba.chunks_exact(4)).filter(|(a, b)| a != b).count();
                assert_eq!(
                    differ,
                    0,
                    "{} patches, mode {mode:?}, turn {turn}: {differ} pixels differ",
                    p.patch_count()
                );
            }
        }
    }
}

/// One Bézier patch, quadratic in u and linear in v, on 3×2 homogeneous
/// control points (u fastest), tessellated `density`² times.
fn quadratic_by_linear(pts: Vec<[f64; 4]>, density: u32) -> PreparedNurbs {
    let s = hitex_core::nurbs::NurbsSurface::new(
        2,
        1,
        3,
        2,
        vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        vec![0.0, 0.0, 1.0, 1.0],
        pts,
    )
    .unwrap();
    let range = [s.domain()];
    PreparedNurbs::new(vec![s], &range, density)
}

/// A quarter of a surface of revolution about +Z: radius `r0` at z = 0,
/// `r1` at z = `height`; the parametric normal Su × Sv points outwards, or,
/// with u reversed, inwards. As a single prepared patch in `mode`.
fn quarter_turn(r0: f64, r1: f64, height: f64, inwards: bool, mode: NurbsMode) -> PreparedNurbs {
    let w = std::f64::consts::FRAC_1_SQRT_2;
    let mut pts = Vec::new();
    for (z, r) in [(0.0, r0), (height, r1)] {
        let mut row = vec![[r, 0.0, z, 1.0], [r, r, z, w], [0.0, r, z, 1.0]];
        if inwards {
            row.reverse();
        }
        pts.extend(row);
    }
    let mut p = quadratic_by_linear(pts, 6);
    p.mode = mode;
    p
}

/// A quarter frustum narrowing upwards (radius 1 at z = 0, 0.9 at z = 1):
/// every point's draft against +Z is atan(0.1) = 5.71°, its parametric
/// normal pointing outwards and up.
fn quarter_frustum() -> PreparedNurbs {
    quarter_turn(1.0, 0.9, 1.0, false, NurbsMode::Draft)
}

/// Pixels of each draft class (positive, within, negative) by their hue.
fn draft_classes(f: &hitex_render::Frame) -> [usize; 3] {
    let mut n = [0; 3];
    for px in f.rgba.chunks_exact(4) {
        let (r, g, b) = (px[0] as f32, px[1] as f32, px[2] as f32);
        if g > 1.8 * r && g > 1.8 * b {
            n[0] += 1;
        } else if r > 2.0 * b && g > 2.0 * b && g > 0.6 * r {
            n[1] += 1;
        } else if r > 2.5 * g && r > 2.5 * b {
            n[2] += 1;
        }
    }
    n
}

#[test]
fn draft_classes_follow_the_exact_angle_on_both_backends() {
    let cpu = CpuRenderer::new();
    let mut gpu = gpu_or_skip("draft_classes_follow_the_exact_angle_on_both_backends");
    // (pull, tolerance) → the one class every covered pixel must show
    let cases = [
        (glam::Vec3::Z, 3.0, 0),
        (glam::Vec3::NEG_Z, 3.0, 2),
        (glam::Vec3::Z, 8.0, 1),
        (glam::Vec3::Z, 5.5, 0),
        (glam::Vec3::Z, 5.9, 1),
    ];
    for (pull, tol, want) in cases {
        let mut p = quarter_frustum();
        p.pull = pull;
        p.draft_tolerance_deg = tol;
        let f = cpu.render_nurbs(&p, &p.camera, 96, 96).unwrap();
        let n = draft_classes(&f);
        let covered: usize = n.iter().sum();
        assert!(covered > 800, "{pull} ±{tol}°: only {covered} classified pixels ({n:?})");
        assert_eq!(n[want], covered, "{pull} ±{tol}°: classes {n:?}, want all in class {want}");
        if let Some(g) = gpu.as_mut() {
            let gf = g.render_nurbs(&p, &p.camera, 96, 96).unwrap();
            assert_images(&format!("draft-{tol}-gpu"), &gf, &f, GPU_VS_CPU_ALIASED);
            assert_eq!(draft_classes(&gf)[want], draft_classes(&gf).iter().sum::<usize>());
        }
    }
}

/// A quarter cylinder of radius 1 about +Z, its parametric normal outwards
/// (convex) or inwards (concave, radius 1).
fn quarter_cylinder(inwards: bool) -> PreparedNurbs {
    quarter_turn(1.0, 1.0, 1.5, inwards, NurbsMode::Radius)
}

/// Pixels of each radius class (tight, concave, convex or flat) by their hue.
fn radius_classes(f: &hitex_render::Frame, bg: [u8; 3]) -> [usize; 3] {
    let mut n = [0; 3];
    let mut model = 0;
    for px in f.rgba.chunks_exact(4) {
        let (r, g, b) = (px[0] as f32, px[1] as f32, px[2] as f32);
        if px[..3].iter().zip(bg).all(|(a, b)| a.abs_diff(b) <= 3) {
            continue;
        }
        model += 1;
        if r > 2.5 * g && r > 2.5 * b {
            n[0] += 1;
        } else if b > 1.5 * r && b > g {
            n[1] += 1;
        } else if (r - g).abs() < 0.15 * g && b >= r {
            n[2] += 1;
        }
    }
    // every pixel of the model shows one of the classes
    let classified: usize = n.iter().sum();
    assert!(classified * 100 >= model * 98, "{classified} of {model} model pixels classified: {n:?}");
    n
}

#[test]
fn radius_classes_follow_the_exact_curvature_on_both_backends() {
    let cpu = CpuRenderer::new();
    let mut gpu = gpu_or_skip("radius_classes_follow_the_exact_curvature_on_both_backends");
    // (inwards, tool radius) → the one class every covered pixel must show
    for (inwards, radius, want) in [(false, 0.5, 2), (true, 0.5, 1), (true, 2.0, 0), (true, 0.98, 1), (true, 1.02, 0)] {
        let mut p = quarter_cylinder(inwards);
        p.tool_radius = radius;
        let e = hitex_core::texture::linear_to_srgb_u8;
        let bg = [e(p.background.x), e(p.background.y), e(p.background.z)];
        let f = cpu.render_nurbs(&p, &p.camera, 96, 96).unwrap();
        let n = radius_classes(&f, bg);
        let covered: usize = n.iter().sum();
        assert!(covered > 800, "inwards {inwards} R {radius}: only {covered} classified pixels ({n:?})");
        assert_eq!(n[want], covered, "inwards {inwards} R {radius}: classes {n:?}, want all in class {want}");
        if let Some(g) = gpu.as_mut() {
            let gf = g.render_nurbs(&p, &p.camera, 96, 96).unwrap();
            assert_images(&format!("radius-{inwards}-{radius}-gpu"), &gf, &f, GPU_VS_CPU_ALIASED);
            let gn = radius_classes(&gf, bg);
            assert_eq!(gn[want], gn.iter().sum::<usize>(), "gpu: {gn:?}");
        }
    }
}

/// The colour byte the programs write for a ramp value in [0, 1].
fn byte(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

fn near(px: &[u8], c: [u8; 3], tol: u8) -> bool {
    px[..3].iter().zip(c).all(|(a, b)| a.abs_diff(b) <= tol)
}

#[test]
fn principal_curvatures_of_a_cylinder_on_both_backends() {
    // radius 1: κ = ∓1 across the axis and 0 along it; with the range 2 the
    // curved direction maps to ±½ of the ramp. Seen from outside the
    // surface bends away from the viewer (κ1 = 0, κ2 = −1), from inside
    // towards it (κ1 = +1, κ2 = 0): every model pixel shows one of the two
    // pairs, on both backends.
    let ramp = |t: f32| hitex_render::cpu::nurbs::diverging(t).to_array().map(byte);
    let (white, blue, red) = (ramp(0.0), ramp(-0.5), ramp(0.5));
    let cpu = CpuRenderer::new();
    let mut gpu = gpu_or_skip("principal_curvatures_of_a_cylinder_on_both_backends");
    for inwards in [false, true] {
        let mut p = quarter_turn(1.0, 1.0, 1.5, inwards, NurbsMode::K1);
        p.curvature_range[2] = 2.0;
        let e = hitex_core::texture::linear_to_srgb_u8;
        let bg = [e(p.background.x), e(p.background.y), e(p.background.z)];
        let mut frames = vec![];
        for mode in [NurbsMode::K1, NurbsMode::K2] {
            p.mode = mode;
            let c = cpu.render_nurbs(&p, &p.camera, 96, 96).unwrap();
            if let Some(g) = gpu.as_mut() {
                let f = g.render_nurbs(&p, &p.camera, 96, 96).unwrap();
                assert_images(&format!("k-{mode:?}-{inwards}-gpu"), &f, &c, GPU_VS_CPU_ALIASED);
                frames.push(("gpu", mode, f));
            }
            frames.push(("cpu", mode, c));
        }
        for be in ["cpu", "gpu"] {
            let get = |m: NurbsMode| frames.iter().find(|(b, mm, _)| *b == be && *mm == m).map(|f| &f.2);
            let (Some(k1), Some(k2)) = (get(NurbsMode::K1), get(NurbsMode::K2)) else { continue };
            let (mut outside, mut inside, mut model) = (0, 0, 0);
            for (a, b) in k1.rgba.chunks_exact(4).zip(k2.rgba.chunks_exact(4)) {
                if near(a, bg, 2) && near(b, bg, 2) {
                    continue;
                }
                model += 1;
                outside += (near(a, white, 2) && near(b, blue, 2)) as usize;
                inside += (near(a, red, 2) && near(b, white, 2)) as usize;
            }
            assert!(model > 800, "{be} inwards {inwards}: {model} model pixels");
            // silhouette pixels blend with the background: allow 3 %
            assert!(
                (outside + inside) * 100 >= model * 97,
                "{be} inwards {inwards}: {outside} outside + {inside} inside of {model} pixels"
            );
        }
    }
}

/// A flat unit square in z = 0 whose x runs as u² (a quadratic Bézier in u
/// with x control values 0, 0, 1), y as v; seen straight from above, so
/// that screen columns are affine in x.
fn square_u_squared() -> (PreparedNurbs, hitex_core::scene::Camera) {
    let mut pts = Vec::new();
    for y in [0.0, 1.0] {
        for x in [0.0, 0.0, 1.0] {
            pts.push([x, y, 0.0, 1.0]);
        }
    }
    let p = quadratic_by_linear(pts, 8);
    let cam = hitex_core::scene::Camera {
        position: glam::Vec3::new(0.5, 0.5, 2.0),
        target: glam::Vec3::new(0.5, 0.5, 0.0),
        up: glam::Vec3::Y,
        fov_y_deg: 35.0,
        near: 0.5,
        far: 4.0,
    };
    (p, cam)
}

#[test]
fn isoparametric_lines_and_sections_fall_where_the_exact_surface_puts_them() {
    // 4 isolines per direction: u = ¼, ½, ¾ lie at x = u² = 0.0625, 0.25,
    // 0.5625; sections x = k/4 at x = 0.25, 0.5, 0.75. Along the row through
    // y = 0.4 (between the v lines) every overlay pixel must lie within a
    // pixel of one of those x, and each of them must be drawn (a section
    // drawn over an isoline wins, so x = 0.25 shows the section).
    const W: u32 = 200;
    let (mut p, cam) = square_u_squared();
    p.isolines = 4;
    p.sections = Some((glam::Vec3::X, 0.25));
    let vp = cam.view_proj(1.0);
    let column = |x: f32| {
        let c = vp * glam::Vec4::new(x, 0.4, 0.0, 1.0);
        (c.x / c.w * 0.5 + 0.5) * W as f32
    };
    let row = {
        let c = vp * glam::Vec4::new(0.5, 0.4, 0.0, 1.0);
        ((0.5 - c.y / c.w * 0.5) * W as f32) as usize
    };
    let check = |name: &str, f: &hitex_render::Frame| {
        let line = &f.rgba[row * W as usize * 4..(row + 1) * W as usize * 4];
        let at = |rgb: [u8; 3]| -> Vec<f32> {
            line.chunks_exact(4).enumerate().filter(|(_, px)| px[..3] == rgb).map(|(i, _)| i as f32 + 0.5).collect()
        };
        let (iso, sec) = (at(hitex_render::nurbs::ISOLINE_RGB), at(hitex_render::nurbs::SECTION_RGB));
        for (what, got, want) in [("isoline", &iso, vec![0.0625, 0.5625]), ("section", &sec, vec![0.25, 0.5, 0.75])] {
            let cols: Vec<f32> = want.iter().map(|&x| column(x)).collect();
            for (x, c) in want.iter().zip(&cols) {
                assert!(
                    got.iter().any(|g| (g - c).abs() <= 1.0),
                    "{name}: no {what} at x = {x} (column {c}); got {got:?}"
                );
            }
            for g in got.iter() {
                // the patch's edges x = 0, 1 are isolines and section planes too
                let edges = [column(0.0), column(1.0)];
                assert!(
                    cols.iter().chain(&edges).any(|c| (g - c).abs() <= 1.5),
                    "{name}: {what} pixel at column {g}, wanted near {cols:?}"
                );
            }
            // one pixel wide, two where a line falls between two pixel centres
            assert!(got.len() <= 2 * (want.len() + 2), "{name}: {} {what} pixels", got.len());
        }
    };
    let cpu = CpuRenderer::new();
    let c = cpu.render_nurbs(&p, &cam, W, W).unwrap();
    check("cpu", &c);
    if let Some(mut g) = gpu_or_skip("isoparametric_lines_and_sections_fall_where_the_exact_surface_puts_them") {
        let f = g.render_nurbs(&p, &cam, W, W).unwrap();
        check("gpu", &f);
        assert_images("isolines-sections-gpu", &f, &c, GPU_VS_CPU_ALIASED);
    }
}

#[test]
fn the_principal_ramp_is_scaled_by_the_curved_part_alone() {
    // a unit quarter cylinder beside a plane of 16 times its area: the
    // plane's zeros would make the area-weighted P75 zero; the curved part
    // alone gives 2 × 1
    let cyl = quarter_turn(1.0, 1.0, 1.5, false, NurbsMode::K1).surfaces[0].clone();
    let pts = vec![[-4.0, -4.0, -1.0, 1.0], [4.0, -4.0, -1.0, 1.0], [-4.0, 4.0, -1.0, 1.0], [4.0, 4.0, -1.0, 1.0]];
    let plane =
        hitex_core::nurbs::NurbsSurface::new(1, 1, 2, 2, vec![0.0, 0.0, 1.0, 1.0], vec![0.0, 0.0, 1.0, 1.0], pts)
            .unwrap();
    let ranges = [cyl.domain(), plane.domain()];
    let p = PreparedNurbs::new(vec![cyl, plane.clone()], &ranges, 6);
    assert!((p.curvature_range[2] - 2.0).abs() < 1e-3, "{:?}", p.curvature_range);
    // the mean curvature too (H = ½ on the cylinder); the Gaussian is zero
    // everywhere: 1 / the bounding radius squared
    assert!((p.curvature_range[1] - 1.0).abs() < 1e-3, "{:?}", p.curvature_range);
    assert!((p.curvature_range[0] * p.bounds.1 * p.bounds.1 - 1.0).abs() < 0.05, "{:?}", p.curvature_range);
    assert_eq!(p.curvature_over_curved_part, [true, true, true]);
    // a model without curvature: 1 / its bounding radius, not a scale of nothing
    let p = PreparedNurbs::new(vec![plane.clone()], &[plane.domain()], 6);
    assert!((p.curvature_range[2] * p.bounds.1 - 1.0).abs() < 0.05, "{:?} r {}", p.curvature_range, p.bounds.1);
}

/// Pixels of each deviation class (within tolerance, outside, inside, no
/// data) by their hue.
fn deviation_classes(f: &hitex_render::Frame) -> [usize; 4] {
    let mut n = [0; 4];
    for px in f.rgba.chunks_exact(4) {
        let (r, g, b) = (px[0] as f32, px[1] as f32, px[2] as f32);
        if g > 1.8 * r && g > 1.8 * b {
            n[0] += 1;
        } else if r > 2.5 * b && r > 40.0 {
            n[1] += 1;
        } else if b > 1.4 * r && b >= g && b > 40.0 {
            n[2] += 1;
        } else if (r - g).abs() <= 6.0 && (g - b).abs() <= 8.0 && r > 30.0 {
            n[3] += 1;
        }
    }
    n
}

/// The quarter cylinder of radius 1 (normal outwards) against a fine mesh
/// of the cylinder of radius 1 + lift: every covered pixel shows the class
/// of the lift, on both backends alike.
#[test]
fn deviation_classes_follow_the_reference_on_both_backends() {
    use hitex_core::nurbs::deviation::{Reference, deviation_grid};
    let cpu = CpuRenderer::new();
    let mut gpu = gpu_or_skip("deviation_classes_follow_the_reference_on_both_backends");
    let cylinder = |r: f64| {
        let n = 512;
        let at = |i: usize, z: f64| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            [r * a.cos(), r * a.sin(), z]
        };
        let tris: Vec<[[f64; 3]; 3]> = (0..n)
            .flat_map(|i| [[at(i, -1.0), at(i + 1, -1.0), at(i + 1, 3.0)], [at(i, -1.0), at(i + 1, 3.0), at(i, 3.0)]])
            .collect();
        Reference::mesh(tris)
    };
    // (lift, search distance) → the class every covered pixel must show
    let cases = [(0.02, 1.0, 1), (-0.02, 1.0, 2), (0.002, 1.0, 0), (0.02, 0.01, 3)];
    for (lift, max, want) in cases {
        let mut p = quarter_cylinder(false);
        p.mode = NurbsMode::Deviation;
        p.deviation_range = (0.005, 0.04);
        let s = &p.surfaces[0];
        let g = deviation_grid(s, s.domain(), &cylinder(1.0 + lift), 17, max);
        p.set_deviation(17, &[g]);
        let f = cpu.render_nurbs(&p, &p.camera, 96, 96).unwrap();
        let n = deviation_classes(&f);
        let covered: usize = n.iter().sum();
        assert!(covered > 800, "lift {lift}: only {covered} classified pixels ({n:?})");
        assert_eq!(n[want], covered, "lift {lift}: classes {n:?}, want all in class {want}");
        if let Some(gp) = gpu.as_mut() {
            let gf = gp.render_nurbs(&p, &p.camera, 96, 96).unwrap();
            assert_images(&format!("deviation-{lift}-{max}-gpu"), &gf, &f, GPU_VS_CPU_ALIASED);
            assert_eq!(deviation_classes(&gf)[want], deviation_classes(&gf).iter().sum::<usize>());
        }
    }
}

/// Edges drawn over the display mode: a run across the middle of the
/// quarter cylinder and one along its lower side show in their colours on
/// both backends alike, about three pixels wide; none without the flag.
#[test]
fn drawn_edges_show_in_their_colours_on_both_backends() {
    let cpu = CpuRenderer::new();
    let mut gpu = gpu_or_skip("drawn_edges_show_in_their_colours_on_both_backends");
    let count = |f: &hitex_render::Frame, rgb: [u8; 3]| {
        f.rgba.chunks_exact(4).filter(|p| p[0] == rgb[0] && p[1] == rgb[1] && p[2] == rgb[2]).count()
    };
    let (red, green) = ([235, 35, 35], [60, 200, 90]);
    let mut p = quarter_cylinder(false);
    p.mode = NurbsMode::Shaded;
    let plain = cpu.render_nurbs(&p, &p.camera, 128, 128).unwrap();
    let middle: Vec<[f64; 2]> = (0..=20).map(|i| [0.5, i as f64 / 20.0]).collect();
    let side: Vec<[f64; 2]> = (0..=20).map(|i| [i as f64 / 20.0, 0.0]).collect();
    p.set_edges(&[vec![(middle, red), (side, green)]]);
    let f = cpu.render_nurbs(&p, &p.camera, 128, 128).unwrap();
    let (r, g) = (count(&f, red), count(&f, green));
    assert_eq!((count(&plain, red), count(&plain, green)), (0, 0));
    // the sheet stands almost edge-on in this view: the middle line runs some
    // 40 pixels down the frame, two to three wide
    assert!((40..600).contains(&r), "{r} red pixels");
    assert!(g > 20, "{g} green pixels");
    if let Some(gp) = gpu.as_mut() {
        let gf = gp.render_nurbs(&p, &p.camera, 128, 128).unwrap();
        assert_images("edges-gpu", &gf, &f, GPU_VS_CPU_ALIASED);
        let (gr, gg) = (count(&gf, red), count(&gf, green));
        assert!(gr.abs_diff(r) * 10 <= r && gg.abs_diff(g) * 5 <= g, "GPU {gr}/{gg} vs CPU {r}/{g}");
    }
}

/// The reflection mode on the teapot shows the studio's
/// soft boxes (bright pixels) against its sky and floor (dark ones), on both
/// backends alike.
#[test]
fn reflection_shows_the_studio_on_both_backends() {
    let cpu = CpuRenderer::new();
    let mut gpu = gpu_or_skip("reflection_shows_the_studio_on_both_backends");
    let mut p = teapot();
    p.mode = NurbsMode::Reflection;
    let f = cpu.render_nurbs(&p, &p.camera, 128, 128).unwrap();
    let grey = |f: &hitex_render::Frame| {
        let (mut bright, mut dark) = (0, 0);
        let bg = &f.rgba[..4];
        for px in f.rgba.chunks_exact(4).filter(|px| *px != bg) {
            assert!(px[0] == px[1] && px[1] == px[2], "not grey: {px:?}");
            if px[0] >= 200 {
                bright += 1;
            } else if px[0] < 110 && px[0] > 0 {
                dark += 1;
            }
        }
        (bright, dark)
    };
    let (bright, dark) = grey(&f);
    assert!(bright > 300 && dark > 300, "{bright} bright, {dark} dark pixels");
    if let Some(g) = gpu.as_mut() {
        let gf = g.render_nurbs(&p, &p.camera, 128, 128).unwrap();
        assert_images("reflection-gpu", &gf, &f, GPU_VS_CPU_ALIASED);
    }
}

/// A whole turn of a cylinder as one patch (radius 1, z from 0 to 2): u
/// around (four exact rational quadratic arcs), v along the axis.
fn whole_turn_cylinder() -> hitex_core::nurbs::NurbsSurface {
    let w = std::f64::consts::FRAC_1_SQRT_2;
    let ring = [
        (1.0, 0.0, 1.0),
        (1.0, 1.0, w),
        (0.0, 1.0, 1.0),
        (-1.0, 1.0, w),
        (-1.0, 0.0, 1.0),
        (-1.0, -1.0, w),
        (0.0, -1.0, 1.0),
        (1.0, -1.0, w),
        (1.0, 0.0, 1.0),
    ];
    let mut pts = Vec::new();
    for z in [0.0, 2.0] {
        pts.extend(ring.iter().map(|&(x, y, w)| [x, y, z, w]));
    }
    hitex_core::nurbs::NurbsSurface::new(
        2,
        1,
        9,
        2,
        vec![0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0],
        vec![0.0, 0.0, 1.0, 1.0],
        pts,
    )
    .unwrap()
}

/// Fitted grids follow the sag of a circle, r (1 − cos(π/n)) ≤ tol, around a
/// whole-turn cylinder and keep the least grid along its straight lines and
/// on a plane; a patch of many knot spans gets a cell a span at least.
#[test]
fn fitted_grids_follow_the_curvature() {
    use hitex_render::nurbs::fitted_grids;
    let cyl = whole_turn_cylinder();
    let plane = hitex_core::nurbs::NurbsSurface::new(
        1,
        1,
        2,
        2,
        vec![0.0, 0.0, 1.0, 1.0],
        vec![0.0, 0.0, 1.0, 1.0],
        vec![[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [1.0, 1.0, 0.0, 1.0]],
    )
    .unwrap();
    // a straight line cut into 40 knot spans (degree 1 in u)
    let knots: Vec<f64> =
        std::iter::once(0.0).chain((0..=40).map(|i| i as f64 / 40.0)).chain(std::iter::once(1.0)).collect();
    let pts: Vec<[f64; 4]> = (0..2).flat_map(|j| (0..41).map(move |i| [i as f64 / 40.0, j as f64, 0.0, 1.0])).collect();
    let spans = hitex_core::nurbs::NurbsSurface::new(1, 1, 41, 2, knots, vec![0.0, 0.0, 1.0, 1.0], pts).unwrap();
    for tol in [1e-2, 1e-3, 1e-4] {
        let surfaces = [cyl.clone(), plane.clone(), spans.clone()];
        let ranges: Vec<_> = surfaces.iter().map(|s| s.domain()).collect();
        let g = fitted_grids(&surfaces, &ranges, 8, tol);
        // the least n with 1 − cos(π / n) ≤ tol (the rational arcs' speed
        // varies, so the fitted grid may need a few more)
        let least = (std::f64::consts::PI / (1.0 - tol).acos()).ceil() as u32;
        assert!(g[0].0 >= least && g[0].0 <= least * 13 / 10 + 2, "tol {tol}: {} around, least {least}", g[0].0);
        assert_eq!(g[0].1, 8, "tol {tol}: along the axis");
        assert_eq!(g[1], (8, 8), "tol {tol}: plane");
        assert_eq!(g[2], (40, 8), "tol {tol}: 40 knot spans");
        // and the mesh's measured deviation is within the tolerance
        let p = PreparedNurbs::with_grids(surfaces.to_vec(), &ranges, &g);
        assert!((p.tess_deviation as f64) <= tol * 1.01, "tol {tol}: deviation {}", p.tess_deviation);
    }
    // a model past the triangle budget is scaled down evenly
    let many = vec![cyl.clone(); 200];
    let ranges: Vec<_> = many.iter().map(|s| s.domain()).collect();
    let g = fitted_grids(&many, &ranges, 256, 1e-9);
    let total: u64 = g.iter().map(|&(a, b)| 2 * a as u64 * b as u64).sum();
    assert!(
        total <= hitex_render::nurbs::MAX_FITTED_TRIANGLES && total > hitex_render::nurbs::MAX_FITTED_TRIANGLES / 2
    );
}

/// Seen side-on, a whole-turn cylinder on a fitted mesh covers what a
/// 256-cell reference covers to within a pixel in every row (the same
/// pixels in this view);
/// on an 8×8 grid its silhouette is the octagon's, pixels short.
#[test]
fn fitted_mesh_draws_the_exact_silhouette() {
    let cpu = CpuRenderer::new();
    let cyl = whole_turn_cylinder();
    let range = [cyl.domain()];
    // seen from a direction between two of the octagon's corners
    let a = std::f32::consts::PI / 8.0;
    let cam = hitex_core::scene::Camera {
        position: glam::Vec3::new(6.0 * a.sin(), -6.0 * a.cos(), 1.0),
        target: glam::Vec3::new(0.0, 0.0, 1.0),
        up: glam::Vec3::Z,
        fov_y_deg: 35.0,
        near: 1.0,
        far: 20.0,
    };
    let fitted = hitex_render::nurbs::fitted_grids(std::slice::from_ref(&cyl), &range, 8, 2.0 * 2f64.sqrt() / 4000.0);
    let widths = |grid: (u32, u32)| -> Vec<usize> {
        let p = PreparedNurbs::with_grids(vec![cyl.clone()], &range, &[grid]);
        let f = cpu.render_nurbs(&p, &cam, 320, 320).unwrap();
        let bg = f.rgba[..4].to_vec();
        (0..320).map(|y| (0..320).filter(|&x| f.rgba[(y * 320 + x) * 4..][..4] != bg[..]).count()).collect()
    };
    let (reference, auto, coarse) = (widths((256, 8)), widths(fitted[0]), widths((8, 8)));
    let worst = |w: &[usize]| w.iter().zip(&reference).map(|(a, b)| a.abs_diff(*b)).max().unwrap_or(0);
    assert!(reference.iter().filter(|&&w| w > 50).count() > 100, "the cylinder fills the frame: {reference:?}");
    assert!(worst(&auto) <= 1, "fitted {:?}: rows differ by up to {} pixels", fitted[0], worst(&auto));
    assert!(worst(&coarse) >= 4, "8×8: rows differ by only {} pixels", worst(&coarse));
}

/// Trimming loops beyond the texture's row are simplified, not thinned
/// evenly: a 20,000-edge circle with a one-point spike keeps its spike and
/// stays within the stated tolerance of the loop as given; a loop that
/// fits is packed as it is.
#[test]
fn trims_past_the_texture_row_are_simplified_keeping_their_shape() {
    use hitex_render::nurbs::MAX_TRIM_EDGES;
    let s = wavy(1, 1, 2, 2);
    let range = [s.domain()];
    let mut p = PreparedNurbs::new(vec![s], &range, 4);
    let n = 20_000;
    let spike = n / 2 + 1;
    let circle: Vec<[f64; 2]> = (0..=n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            let r = if i == spike { 0.32 } else { 0.3 };
            [0.5 + r * a.cos(), 0.5 + r * a.sin()]
        })
        .collect();
    let outer = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]];
    p.set_trims(&[vec![outer.clone(), circle.clone()]]);
    let t = &p.packed;
    let kept = t.trims[0][0] as usize;
    assert!(kept <= MAX_TRIM_EDGES && kept > 100, "{kept} edges kept");
    let info = &t.trims_simplified;
    assert_eq!(info.len(), 1);
    assert_eq!((info[0].patch, info[0].edges, info[0].kept), (0, n + 4, kept));
    // the spike's tip is a vertex of the packed loop (even thinning by 3 drops it)
    let edges = &t.trims[1..1 + kept];
    let tip = circle[spike];
    assert!(
        edges.iter().any(|e| ((e[0] as f64 - tip[0]).hypot(e[1] as f64 - tip[1])) < 1e-6),
        "the spike at {tip:?} was lost"
    );
    // every given point lies within the tolerance (of the loops' box, here
    // 1 × 1) of the packed edges, to f32 rounding
    let dist = |q: [f64; 2]| -> f64 {
        edges
            .iter()
            .map(|e| {
                let (a, b) = ([e[0] as f64, e[1] as f64], [e[2] as f64, e[3] as f64]);
                let d = [b[0] - a[0], b[1] - a[1]];
                let len2 = d[0] * d[0] + d[1] * d[1];
                let t = if len2 > 0.0 {
                    (((q[0] - a[0]) * d[0] + (q[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (q[0] - a[0] - t * d[0]).hypot(q[1] - a[1] - t * d[1])
            })
            .fold(f64::INFINITY, f64::min)
    };
    let worst = circle.iter().map(|&q| dist(q)).fold(0.0, f64::max);
    assert!(worst <= info[0].tolerance + 1e-6, "{worst} beyond the stated {}", info[0].tolerance);
    assert!(info[0].tolerance < 1e-4, "tolerance {}", info[0].tolerance);
    // a loop that fits is packed point for point, with nothing reported
    let small: Vec<[f64; 2]> = circle.iter().step_by(10).copied().collect();
    p.set_trims(&[vec![outer, small.clone()]]);
    assert!(p.packed.trims_simplified.is_empty());
    assert_eq!(p.packed.trims[0][0] as usize, 4 + small.len() - 1);
}
