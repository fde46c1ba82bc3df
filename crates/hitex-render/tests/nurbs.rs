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
