//! Builds a tile store of procedural imagery and flies over it with hitex as
//! a library: the maps a frame needs (the active area, eq. (7)) are loaded
//! by the resident-map cache in the background, each frame renders through
//! the page table of what is resident, and every frame is saved.
//!
//! ```text
//! cargo run --release -p hitex-render --example fly_store -- out-dir
//! ```

use hitex_core::residency::{Loader, MapKey, ResidentMaps};
use hitex_io::gst::{BuildOptions, ProceduralSource, StoreMeta, TILE, build_store, open_store, read_tile};
use hitex_render::terrain::flight::{FlightArea, prepare_frame};
use hitex_render::terrain::{FlyCamera, FlyGround};
use hitex_render::{AnyRenderer, BackendChoice, Job, Renderer};
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

/// Builds a `side`² store under `out/store` and saves `frames` flight frames
/// of `w`×`h` as `out/frame-N.png`; returns the renderer's name.
pub fn run(out: &Path, side: u32, frames: u32, (w, h): (u32, u32)) -> Result<String, Box<dyn std::error::Error>> {
    // 1. the store: a TMS pyramid of 256×256 maps, built from any TileSource
    let store = out.join("store");
    let src = ProceduralSource { width: side, height: side, seed: 7 };
    let meta = StoreMeta::for_source(side, side, [0.0, 0.0], [1.0, 1.0], "", "procedural");
    build_store(&src, &meta, &store, BuildOptions::default(), &|_, _| {})?;
    let meta = open_store(&store)?;
    // 2. the resident maps: at most 200, loaded from the store in the background
    let root = store.clone();
    let m = meta.clone();
    let loader: Arc<Loader> = Arc::new(move |k: MapKey| Ok(read_tile(&m, &root, k.z, k.x, k.y)?));
    let mut cache = ResidentMaps::new(200, loader)?;
    // maps per side of each level's window (eq. (7)) for this field of view and width
    let fov = 45.0;
    let per_side = hitex_core::terrain::active_area(fov, w, TILE, meta.levels)?.first().map_or(6, |l| l.per_side);
    let area = FlightArea {
        levels: meta.levels,
        map_texels: TILE,
        offset: meta.offset,
        extent: [meta.width as f64, meta.height as f64],
        ground_pixel: meta.ground_pixel(),
    };
    let wait = Duration::from_secs(30);
    let mut renderer = AnyRenderer::open(BackendChoice::Auto)?;
    for i in 0..frames {
        // 3. a camera circling the middle, looking at it 30° below the horizon
        //    (x east, y south, heading clockwise from north, pitch from the nadir)
        let (r, a) = (0.35 * side as f64, std::f64::consts::TAU * i as f64 / frames.max(1) as f64);
        let (cx, cy) = (side as f64 / 2.0 + r * a.cos(), side as f64 / 2.0 + r * a.sin());
        let heading = (-a.cos()).atan2(a.sin()).to_degrees();
        let cam = FlyCamera::new(cx, cy, side as f64 / 8.0, 60.0, heading, fov);
        // 4. the maps this view needs (the active area) requested, waited
        //    for, then the page table of what is resident and the uniforms
        let f = prepare_frame(&mut cache, &area, |z| meta.data_range(z), &cam, (w, h), fov, per_side, Some(wait));
        // 5. render on any backend and save
        let (uniform, pages) = (f.uniform, f.pages);
        let job = Job::Flight { uniform, pages: Cow::Owned(pages), ground: FlyGround::Flat, stats: false };
        let frame = renderer.render(&job, w, h)?.frame;
        hitex_io::save_png(&out.join(format!("frame-{i}.png")), frame.width, frame.height, &frame.rgba)?;
    }
    Ok(renderer.name())
}

#[allow(dead_code)]
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args_os().nth(1).map(PathBuf::from).unwrap_or_else(|| "fly-out".into());
    std::fs::create_dir_all(&out)?;
    let name = run(&out, 4096, 8, (1024, 768))?;
    println!("wrote 8 frames into {} with {name}", out.display());
    Ok(())
}
