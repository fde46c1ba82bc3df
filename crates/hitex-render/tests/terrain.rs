//! Flights over a map pyramid: the GPU agrees with the CPU twin, and a frame
//! whose maps are still loading has no holes.

mod common;

use common::{GPU_VS_CPU, assert_images, gpu_or_skip};
use hitex_core::residency::{Loader, MapKey, ResidentMaps, View, active_maps};
use hitex_render::terrain::{FlyCamera, FlyPages, FlyUniform, MAP};
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

fn tiles(z: u32) -> (u32, u32) {
    (1 << z, 1 << z)
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
        let f = hitex_render::cpu::terrain::render_fly(&u, &pages).unwrap();
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
        let c = hitex_render::cpu::terrain::render_fly(&u, &pages).unwrap();
        let g = gpu.render_fly(&u, &pages).unwrap();
        assert_images(&format!("fly-wait-{wait}"), &g, &c, GPU_VS_CPU);
    }
}
