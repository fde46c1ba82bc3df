//! Reads a NURBS model (an IGES file, or the embedded Utah teapot), evaluates
//! one exact point and normal, and renders the model shaded and as
//! isophotes with hitex as a library.
//!
//! ```text
//! cargo run --release -p hitex-render --example render_nurbs -- part.igs out-dir
//! ```

use hitex_render::nurbs::{Density, NurbsMode, PreparedNurbs};
use hitex_render::{AnyRenderer, BackendChoice, Job, Renderer};
use std::path::{Path, PathBuf};

/// Renders `model` (a file path, or `teapot`) into `out/shaded.png` and
/// `out/isophotes.png`; returns the exact point and unit normal at the
/// middle of the first patch's parameter range.
pub fn run(model: &str, out: &Path, size: u32) -> Result<([f64; 3], [f64; 3]), Box<dyn std::error::Error>> {
    let m = hitex_io::models::load_model(model)?;
    for w in &m.warnings {
        eprintln!("{model}: {w}");
    }
    let first = m.surfaces.first().ok_or("the model has no surfaces")?;
    // exact evaluation in f64, on the surface as the file defines it
    let ((u0, u1), (v0, v1)) = first.range;
    let (u, v) = (0.5 * (u0 + u1), 0.5 * (v0 + v1));
    let point = first.surface.point(u, v);
    let normal = first.surface.normal(u, v);
    // prepared for rendering with the patches' trims and the faces' colours,
    // each patch's mesh fitted to its surface
    let (mut prepared, cut) =
        PreparedNurbs::from_parts(m.nurbs(), &m.ranges(), &m.trims(), &m.colors, Density::Auto, None);
    println!("mesh: {cut}");
    let mut renderer = AnyRenderer::open(BackendChoice::Auto)?;
    std::fs::create_dir_all(out)?;
    for (name, mode) in [("shaded", NurbsMode::Shaded), ("isophotes", NurbsMode::Isophote)] {
        prepared.mode = mode;
        let job = Job::Nurbs { model: &prepared, camera: prepared.camera };
        let frame = renderer.render(&job, size, size)?.frame;
        hitex_io::save_png(&out.join(format!("{name}.png")), frame.width, frame.height, &frame.rgba)?;
    }
    Ok((point, normal))
}

#[allow(dead_code)]
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let model = args.next().unwrap_or_else(|| "teapot".into());
    let out = args.next().map(PathBuf::from).unwrap_or_else(|| "nurbs-out".into());
    let (p, n) = run(&model, &out, 512)?;
    println!("{model}: first patch's middle at {p:?}, normal {n:?}");
    println!("wrote {0}/shaded.png and {0}/isophotes.png", out.display());
    Ok(())
}
