//! Renders a BTF material on a quad with hitex as a library: a procedural
//! woven BTF, a synthesised index map, layout (f), one point light.
//!
//! ```text
//! cargo run --release -p hitex-render --example render_btf -- btf.png
//! ```

use glam::Vec3;
use hitex_core::btf::index::{SynthesisOptions, synthesize_index};
use hitex_core::btf::synth::{Material, SynthOptions, synthesize};
use hitex_core::btf::{AngularGrid, Layout};
use hitex_core::scene::Camera;
use hitex_render::btf::{BtfSurface, PreparedBtf};
use hitex_render::{AnyRenderer, BackendChoice, Job, Renderer};
use std::path::{Path, PathBuf};

/// Renders the material into `out` (PNG) at `width`×`height`; returns the
/// renderer's name.
pub fn run(out: &Path, width: u32, height: u32) -> Result<String, Box<dyn std::error::Error>> {
    // 1. the material: a BTF of 4 elevations × 8 azimuths for view and light,
    //    a 16×16-texel sample per (view, light) pair
    let grid = AngularGrid::new(vec![0.0, 20.0, 40.0, 60.0], 8)?;
    let btf = synthesize(Material::Woven, &SynthOptions { grid, size: 16, supersample: 1, exposure: 0.85 }, &|_| {})?;
    // 2. an index map that tiles the surface without visible repetition
    let index = synthesize_index(&btf, &SynthesisOptions { width: 64, height: 64, ..Default::default() }, &|_, _| {})?;
    // 3. prepared once for rendering: codebook layout (f), uncompressed
    let surface = PreparedBtf::new(&btf, Layout::F, None, index, BtfSurface::quad(2.0, 2.0))?;
    // 4. any backend: a hardware GPU if there is one, else the CPU backend
    let mut renderer = AnyRenderer::open(BackendChoice::Auto)?;
    let camera = Camera::new(Vec3::new(0.0, -1.6, 2.0), Vec3::ZERO, Vec3::Y, 40.0, 0.1, 10.0)?;
    let job = Job::Btf { surface: &surface, camera, light: Vec3::new(1.5, 1.0, 2.0) };
    let frame = renderer.render(&job, width, height)?.frame;
    hitex_io::save_png(out, frame.width, frame.height, &frame.rgba)?;
    Ok(renderer.name())
}

#[allow(dead_code)]
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args_os().nth(1).map(PathBuf::from).unwrap_or_else(|| "btf.png".into());
    let name = run(&out, 640, 480)?;
    println!("wrote {} with {name}", out.display());
    Ok(())
}
