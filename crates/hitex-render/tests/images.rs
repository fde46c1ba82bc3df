//! Image tests: each scene is written once and run on every backend, CPU
//! against a stored reference, GPU against the CPU, each with its own tolerance.

mod common;

use common::*;
use hitex_core::scene::{RenderMode, Scene, showcase_scene};
use hitex_core::texture::{Filter, LevelRule, Wrap};
use hitex_render::{CpuRenderer, PreparedScene};

const W: u32 = 240;
const H: u32 = 136;

fn cases() -> Vec<(String, Scene)> {
    let base = showcase_scene();
    let mut out = Vec::new();
    for (name, mode) in [
        ("shaded", RenderMode::Shaded),
        ("level", RenderMode::Level),
        ("uv", RenderMode::Uv),
        ("normal", RenderMode::Normal),
    ] {
        let mut s = base.clone();
        s.mode = mode;
        out.push((format!("showcase-{name}"), s));
    }
    for (name, filter) in [("nearest", Filter::Nearest), ("bilinear", Filter::Bilinear)] {
        let mut s = base.clone();
        s.materials.iter_mut().for_each(|m| m.sampler.filter = filter);
        out.push((format!("showcase-{name}"), s));
    }
    let mut s = base.clone();
    s.materials.iter_mut().for_each(|m| {
        m.sampler.level_rule = LevelRule::VulkanRho;
        m.sampler.wrap = Wrap::Mirror;
        m.sampler.lod_bias = 0.5;
    });
    out.push(("showcase-rho-mirror-bias".into(), s));
    let mut s = base.clone();
    s.materials.iter_mut().for_each(|m| m.sampler.wrap = Wrap::Clamp);
    s.camera = s.camera.orbit(2.2);
    out.push(("showcase-clamp-orbit".into(), s));
    out
}

#[test]
fn cpu_matches_references() {
    let cpu = CpuRenderer::new();
    for (name, scene) in cases() {
        let p = PreparedScene::new(&scene);
        let f = cpu.render_view(&p, &p.camera, W, H).unwrap();
        let r = reference(&name, &f);
        assert_images(&format!("{name}-cpu"), &f, &r, CPU_VS_REFERENCE);
    }
}

#[test]
fn gpu_matches_cpu() {
    let Some(mut gpu) = gpu_or_skip("gpu_matches_cpu") else { return };
    eprintln!("gpu: {}", gpu.adapter());
    let cpu = CpuRenderer::new();
    for (name, scene) in cases() {
        let p = PreparedScene::new(&scene);
        let c = cpu.render_view(&p, &p.camera, W, H).unwrap();
        let g = gpu.render_view(&p, &p.camera, W, H).unwrap();
        let aliased = name.ends_with("nearest") || name.ends_with("bilinear");
        assert_images(&format!("{name}-gpu"), &g, &c, if aliased { GPU_VS_CPU_ALIASED } else { GPU_VS_CPU });
    }
}

#[test]
fn gpu_reuses_uploads_across_views_and_sizes() {
    let Some(mut gpu) = gpu_or_skip("gpu_reuses_uploads_across_views_and_sizes") else { return };
    let cpu = CpuRenderer::new();
    let p = PreparedScene::new(&showcase_scene());
    for (i, (w, h)) in [(64u32, 48u32), (130, 70), (64, 48)].into_iter().enumerate() {
        let cam = p.camera.orbit(i as f32);
        let g = gpu.render_view(&p, &cam, w, h).unwrap();
        let c = cpu.render_view(&p, &cam, w, h).unwrap();
        assert_images(&format!("reuse-{i}-gpu"), &g, &c, GPU_VS_CPU);
    }
}

/// The GL fallback (Mesa's llvmpipe through EGL) against the CPU. Not required
/// by HITEX_REQUIRE_GPU: machines with Vulkan may lack a usable EGL.
#[test]
fn gl_backend_matches_cpu() {
    let mut gl = match hitex_render::GpuRenderer::with_backends(wgpu::Backends::GL) {
        Ok(g) => g,
        Err(e) => {
            common::say_skipped(&format!("SKIPPED gl_backend_matches_cpu: no GL adapter ({e})"));
            return;
        }
    };
    eprintln!("gl: {}", gl.adapter());
    let cpu = CpuRenderer::new();
    for (name, scene) in cases().into_iter().take(4) {
        let p = PreparedScene::new(&scene);
        let c = cpu.render_view(&p, &p.camera, W, H).unwrap();
        let g = gl.render_view(&p, &p.camera, W, H).unwrap();
        assert_images(&format!("{name}-gl"), &g, &c, GPU_VS_CPU);
    }
}

/// Meshes and NURBS patches in one frame: same camera, same depth buffer.
#[test]
fn scene_with_nurbs_agrees_on_both_backends() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/teapot-on-checker.toml");
    let scene = hitex_io::load_scene(&path).unwrap();
    assert_eq!(scene.nurbs.len(), 32);
    let p = PreparedScene::new(&scene);
    let c = CpuRenderer::new().render_view(&p, &p.camera, W, H).unwrap();
    let r = reference("teapot-on-checker", &c);
    assert_images("teapot-on-checker-cpu", &c, &r, CPU_VS_REFERENCE);
    let Some(mut gpu) = gpu_or_skip("scene_with_nurbs_agrees_on_both_backends") else { return };
    let g = gpu.render_view(&p, &p.camera, W, H).unwrap();
    assert_images("teapot-on-checker-gpu", &g, &c, GPU_VS_CPU);
}
