//! Every SIMD level this processor runs renders the same images, bit for bit:
//! the lane code uses only operations that round identically at every width
//! (add, multiply, divide, square root; no fused multiply-add).
//!
//! One test in its own binary, because the level is process-wide.

use glam::Vec3;
use hitex_core::btf::index::IndexMap;
use hitex_core::btf::synth::{Material, SynthOptions, synthesize};
use hitex_core::btf::{AngularGrid, Layout};
use hitex_core::scene::{Camera, showcase_scene};
use hitex_render::btf::{BtfSurface, PreparedBtf};
use hitex_render::cpu::simd::{SimdLevel, level, set_level};
use hitex_render::nurbs::{NurbsMode, PreparedNurbs};
use hitex_render::{CpuRenderer, Frame, PreparedScene};

fn frames() -> Vec<(String, Frame)> {
    let cpu = CpuRenderer::new();
    let mut out = Vec::new();
    // NURBS: the block kernel (shaded, isophote) and the per-lane path (mean curvature)
    let m = hitex_io::models::load_model("teapot").expect("embedded teapot");
    let mut p = PreparedNurbs::new(m.nurbs(), &m.ranges(), 6);
    for mode in [NurbsMode::Shaded, NurbsMode::Isophote, NurbsMode::Mean] {
        p.mode = mode;
        let cam = p.camera.orbit(0.7);
        out.push((format!("teapot {mode:?}"), cpu.render_nurbs(&p, &cam, 192, 144).expect("renders")));
    }
    // a textured scene
    let scene = PreparedScene::new(&showcase_scene());
    out.push(("showcase".into(), cpu.render_view(&scene, &scene.camera, 160, 90).expect("renders")));
    // a BTF quad
    let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 8).expect("grid");
    let opts = SynthOptions { grid, size: 8, supersample: 1, exposure: 0.85 };
    let btf = synthesize(Material::Knit, &opts, &|_| {}).expect("synth");
    let pb = PreparedBtf::new(&btf, Layout::F, None, IndexMap::identity(8, 8, 16, 16), BtfSurface::quad(2.0, 2.0))
        .expect("prepared");
    let cam = Camera::new(Vec3::new(0.0, -1.4, 2.2), Vec3::ZERO, Vec3::Y, 40.0, 0.1, 10.0).expect("camera");
    out.push(("btf (f)".into(), cpu.render_btf(&pb, &cam, Vec3::new(1.0, -1.0, 2.0), 96, 72).expect("renders")));
    out
}

#[test]
fn every_level_renders_the_same_images() {
    let levels = SimdLevel::available_levels();
    let detected = level();
    eprintln!("SIMD levels on this processor: {levels:?} (detected {detected})");
    assert!(levels.contains(&SimdLevel::Scalar));
    let mut first: Option<(SimdLevel, Vec<(String, Frame)>)> = None;
    for &l in &levels {
        set_level(l).expect("available");
        assert_eq!(level(), l);
        let f = frames();
        match &first {
            None => first = Some((l, f)),
            Some((l0, f0)) => {
                for ((name, a), (_, b)) in f0.iter().zip(&f) {
                    let differing = a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)).filter(|(p, q)| p != q).count();
                    assert_eq!(differing, 0, "{name}: {l} differs from {l0} in {differing} pixels");
                }
            }
        }
    }
    set_level(detected).expect("available");
}
