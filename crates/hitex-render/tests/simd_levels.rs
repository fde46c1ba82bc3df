//! Every SIMD level this processor runs renders the same images, bit for bit:
//! the lane code uses only operations that round identically at every width
//! (add, multiply, divide, square root; no fused multiply-add).
//!
//! One test in its own binary, because the level is process-wide.

use glam::Vec3;
use hitex_core::btf::index::IndexMap;
use hitex_core::btf::synth::{Material, SynthOptions, synthesize};
use hitex_core::btf::{AngularGrid, Layout};
use hitex_core::residency::MapKey;
use hitex_core::scene::{Camera, showcase_scene};
use hitex_render::btf::{BtfSurface, PreparedBtf};
use hitex_render::cpu::simd::{SimdLevel, level, set_level};
use hitex_render::cpu::terrain::render_fly;
use hitex_render::nurbs::{NurbsMode, PreparedNurbs};
use hitex_render::terrain::{FlyCamera, FlyGround, FlyPages, FlySampler, FlyUniform, MAP};
use hitex_render::{CpuRenderer, Frame, PreparedScene};
use std::collections::HashMap;
use std::sync::Arc;

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
    // a flight over flat ground: the per-pixel lane rows and the span rows
    let pages = flight_pages();
    let fly = FlyCamera::new(1000.0, 1100.0, 150.0, 55.0, 30.0, 50.0);
    for sampler in [FlySampler::Trilinear, FlySampler::Span3] {
        let u = FlyUniform::new(&fly, 120, 80, pages.levels, pages.per_side).with_sampler(sampler);
        let f = render_fly(&u, &pages, FlyGround::Flat).expect("renders").frame;
        out.push((format!("flight {}", sampler.name()), f));
    }
    out
}

/// Three levels of 4×4 maps with hashed texels around the flight.
fn flight_pages() -> FlyPages {
    let (levels, per) = (3u32, 4u32);
    let (mut slots, mut maps, mut origins) = (Vec::new(), HashMap::new(), Vec::new());
    for z in 0..levels {
        let o = [(1i32 << z) - 2, (1i32 << z) - 2];
        origins.push(o);
        for k in 0..(per * per) as i32 {
            let (x, y) = (o[0] + k % per as i32, o[1] + k / per as i32);
            if x < 0 || y < 0 {
                slots.push(None);
                continue;
            }
            let key = MapKey { z, x: x as u32, y: y as u32 };
            maps.entry(key).or_insert_with(|| {
                let t: Vec<u8> = (0..MAP * MAP * 4)
                    .map(|i| ((i ^ (key.x * 977) ^ (key.y * 4099) ^ (z * 131)).wrapping_mul(2_654_435_761) >> 24) as u8)
                    .collect();
                Arc::new(t)
            });
            slots.push(Some(key));
        }
    }
    FlyPages { levels, per_side: per, origins, slots, maps }
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
