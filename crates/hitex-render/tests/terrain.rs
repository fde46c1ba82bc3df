//! Flights over a map pyramid: the GPU agrees with the CPU twin (flat ground
//! and meshes, every sampler), a frame whose maps are still loading has no
//! holes, the span samplers are conflict-free, and a flat mesh renders what
//! the per-pixel ground solve renders.

mod common;

use common::{GPU_VS_CPU, assert_images, gpu_or_skip};
use hitex_core::residency::{Loader, MapKey, ResidentMaps, View, active_maps};
use hitex_core::terrain::{LodOptions, lod_mesh};
use hitex_render::Frame;
use hitex_render::cpu::terrain::{render_fly, render_fly_with};
use hitex_render::terrain::{FlyCamera, FlyGround, FlyMesh, FlyPages, FlySampler, FlyUniform, GenericTexture, MAP};
use std::sync::Arc;
use std::time::Duration;

const LEVELS: u32 = 4; // 8×8 maps at the finest level: 2048² texels

/// Maps of a checkerboard whose colour depends on the level and the map.
fn loader() -> Arc<Loader> {
    Arc::new(|k: MapKey| {
        let mut t = vec![0u8; (MAP * MAP * 4) as usize];
        for y in 0..MAP {
            for x in 0..MAP {
                let on = ((x / 16) + (y / 16)) % 2 == 0;
                let i = ((y * MAP + x) * 4) as usize;
                let base = [40 + 50 * k.z as u8, 90 + 20 * (k.x % 4) as u8, 60 + 30 * (k.y % 4) as u8];
                let c = if on { base } else { [base[0] / 2, base[1] / 2, base[2] / 2] };
                t[i..i + 4].copy_from_slice(&[c[0], c[1], c[2], 255]);
            }
        }
        Ok(t)
    })
}

fn tiles(z: u32) -> [u32; 4] {
    [0, 0, 1 << z, 1 << z]
}

fn frame(wait: bool) -> (FlyUniform, FlyPages) {
    let cam = FlyCamera::new(1000.0, 1100.0, 120.0, 62.0, 35.0, 50.0);
    let (w, h) = (96, 64);
    let mut cache = ResidentMaps::new(400, loader()).unwrap();
    let needed = active_maps(
        LEVELS,
        MAP,
        tiles,
        [cam.eye[0], cam.eye[1]],
        cam.eye[2],
        View { fov_deg: 50.0, pixels: w, per_side: 6 },
    );
    cache.begin_frame(&needed);
    if wait {
        cache.wait_pending(Duration::from_secs(10));
        cache.begin_frame(&needed);
    }
    let pages = FlyPages::new(&cache, LEVELS, 6, tiles, [cam.eye[0], cam.eye[1]]);
    (FlyUniform::new(&cam, w, h, LEVELS, 6), pages)
}

#[test]
fn cpu_frames_have_no_holes_while_maps_load() {
    for wait in [false, true] {
        let (u, pages) = frame(wait);
        let f = render_fly(&u, &pages, FlyGround::Flat).unwrap().frame;
        // every pixel below the horizon shows imagery: none is the bare ground colour
        let e = hitex_core::texture::linear_to_srgb_u8;
        let g = hitex_render::terrain::GROUND;
        let ground = [e(g[0]), e(g[1]), e(g[2]), 255];
        let bare = f.rgba.chunks_exact(4).filter(|p| *p == ground).count();
        assert_eq!(bare, 0, "wait {wait}: {bare} pixels without imagery");
    }
}

#[test]
fn gpu_flight_matches_cpu() {
    let Some(mut gpu) = gpu_or_skip("gpu_flight_matches_cpu") else { return };
    for wait in [false, true] {
        let (u, pages) = frame(wait);
        let c = render_fly(&u, &pages, FlyGround::Flat).unwrap().frame;
        let g = gpu.render_fly(&u, &pages, FlyGround::Flat).unwrap();
        assert_images(&format!("fly-wait-{wait}"), &g, &c, GPU_VS_CPU);
    }
}

fn camera() -> FlyCamera {
    FlyCamera::new(1000.0, 1100.0, 120.0, 62.0, 35.0, 50.0)
}

/// A mesh over the 2048² ground: zero heights (flat) or hills, with an aircraft.
fn mesh(hills: bool, aircraft: bool) -> FlyMesh {
    let n = 129;
    let heights: Vec<f32> =
        (0..n * n)
            .map(|i| {
                if hills {
                    25.0 * (((i % n) as f32) * 0.11).sin() * (((i / n) as f32) * 0.07).cos() + 25.0
                } else {
                    0.0
                }
            })
            .collect();
    let cam = camera();
    let opts = LodOptions {
        origin: [0.0, 0.0],
        spacing: [16.0, 16.0],
        height_scale: 1.0,
        eye: cam.eye,
        pixels_per_tan: 96.0 / (2.0 * cam.tan_h),
        max_edge_px: 6.0,
        block: 16,
    };
    let mut m = FlyMesh::from_lod(&lod_mesh(&heights, n, n, &opts).unwrap());
    if aircraft {
        let at: [f64; 3] = std::array::from_fn(|i| cam.eye[i] + cam.fwd[i] * 50.0);
        m.append(&FlyMesh::aircraft(at, 35.0, 12.0, [0.5, 0.5, 0.7]));
    }
    m
}

fn frames_of(
    gpu: &mut Option<hitex_render::GpuRenderer>,
    u: &FlyUniform,
    pages: &FlyPages,
    ground: FlyGround<'_>,
) -> (Frame, Option<Frame>) {
    let c = render_fly(u, pages, ground).unwrap().frame;
    let g = gpu.as_mut().map(|g| g.render_fly(u, pages, ground).unwrap());
    (c, g)
}

#[test]
fn flat_mesh_renders_the_per_pixel_ground() {
    // the mesh path (view-projection matrix, rasterizer, quad derivatives)
    // sees the same ground as the per-pixel solve of eq. (1)
    let (u, pages) = frame(true);
    let generic = GenericTexture::livery();
    let m = mesh(false, false);
    let flat = render_fly(&u, &pages, FlyGround::Flat).unwrap().frame;
    let meshed = render_fly(&u, &pages, FlyGround::Mesh { mesh: &m, generic: &generic }).unwrap().frame;
    // the flat render shows bare ground colour up to the horizon where the mesh (2048² texels) ends in sky:
    // compare the lower two thirds of the image only
    let rows = (u.sizes[1] / 3) as usize * u.sizes[0] as usize * 4;
    let (a, b) = (&flat.rgba[rows..], &meshed.rgba[rows..]);
    let (d, _) = hitex_render::compare_rgba(a, b);
    eprintln!("flat vs flat mesh: {d}");
    assert!(d.mean_abs < 1.5 && d.p99 <= 12, "{d}");
}

#[test]
fn gpu_meshes_and_spans_match_cpu() {
    let mut gpu = gpu_or_skip("gpu_meshes_and_spans_match_cpu");
    let (u, pages) = frame(true);
    let generic = GenericTexture::livery();
    let hills = mesh(true, true);
    for s in FlySampler::ALL {
        let u = u.with_sampler(s).with_generic(&generic);
        for (name, ground) in [("flat", FlyGround::Flat), ("mesh", FlyGround::Mesh { mesh: &hills, generic: &generic })]
        {
            let (c, g) = frames_of(&mut gpu, &u, &pages, ground);
            if let Some(g) = g {
                assert_images(&format!("fly-{name}-{}", s.name()), &g, &c, GPU_VS_CPU);
            }
        }
    }
}

#[test]
fn mesh_blocks_render_what_the_quad_program_renders() {
    // without statistics the DEM mesh is shaded on 16-lane blocks; with them,
    // quad by quad (the reference): the two frames are the same bytes
    let (u, pages) = frame(true);
    let generic = GenericTexture::livery();
    let hills = mesh(true, true);
    for s in FlySampler::ALL {
        let u = u.with_sampler(s).with_generic(&generic);
        let ground = FlyGround::Mesh { mesh: &hills, generic: &generic };
        let blocks = render_fly_with(&u, &pages, ground, false).unwrap().frame;
        let quads = render_fly_with(&u, &pages, ground, true).unwrap().frame;
        let differing = blocks.rgba.chunks_exact(4).zip(quads.rgba.chunks_exact(4)).filter(|(a, b)| a != b).count();
        assert_eq!(differing, 0, "{}: {differing} pixels differ", s.name());
        let colours: std::collections::HashSet<&[u8]> = blocks.rgba.chunks_exact(4).collect();
        assert!(colours.len() > 200, "{}: {} colours", s.name(), colours.len());
    }
}

#[test]
fn spans_are_conflict_free_and_3x3_reads_a_level_coarser() {
    let (u, pages) = frame(true);
    let generic = GenericTexture::livery();
    let hills = mesh(true, true);
    for (name, ground) in [("flat", FlyGround::Flat), ("mesh", FlyGround::Mesh { mesh: &hills, generic: &generic })] {
        let reference = render_fly(&u, &pages, ground).unwrap();
        assert!(reference.banks.is_none());
        let mut mean_level = Vec::new();
        for s in [FlySampler::Span3, FlySampler::Span4, FlySampler::Bicubic] {
            let f = render_fly(&u.with_sampler(s), &pages, ground).unwrap();
            let banks = f.banks.unwrap();
            let level = banks.mean_level();
            eprintln!(
                "{name} {}: {} spans, {} accesses, {} conflicts, mean level {level:.2}",
                s.name(),
                banks.spans,
                banks.accesses,
                banks.conflicts
            );
            assert!(banks.accesses > 1000, "{name} {}: {} accesses", s.name(), banks.accesses);
            assert_eq!(banks.conflicts, 0, "{name} {}", s.name());
            assert_eq!(banks.guard_raises, 0, "{name} {}", s.name());
            mean_level.push(level);
        }
        // λ = log2(2E/(B − 2)): 3×3 banks read exactly one level coarser than 4×4
        assert!((mean_level[0] - mean_level[1] - 1.0).abs() < 0.05, "{name}: {mean_level:?}");
        assert!((mean_level[1] - mean_level[2]).abs() < 1e-9, "{name}: {mean_level:?}");
    }
}
