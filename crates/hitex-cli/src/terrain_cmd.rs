//! `hitex terrain …`: elevation models draped with geospecific imagery.

use crate::{AnyRenderer, Backend, CliError, parse_size, save};
use clap::{Args, Subcommand};
use glam::{Mat4, Vec2, Vec3};
use hitex_core::scene::{Camera, Light, Material, Object, RenderMode, Scene};
use hitex_core::texture::{ColorSpace, Filter, Image, MipPyramid, SamplerOptions, Wrap};
use hitex_io::dem::load_elevation;
use hitex_io::geotiff::{GeoRaster, fill_holes, load_geotiff};
use hitex_render::PreparedScene;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// `hitex terrain` subcommands.
#[derive(Subcommand)]
pub enum TerrainCommand {
    /// Render a DEM draped with co-registered imagery (per-pixel trilinear MIP mapping).
    Render(RenderArgs),
    /// Maps of each MIP level the active area needs (eq. (5)–(7)) and their memory.
    ActiveArea {
        /// Horizontal field of view, degrees.
        #[arg(long, default_value_t = 45.0)]
        fov: f64,
        /// Pixels per scanline.
        #[arg(long, default_value_t = 1024)]
        width: u32,
        /// Texels per map side.
        #[arg(long, default_value_t = 256)]
        map: u32,
        /// Number of levels (0 the coarsest).
        #[arg(long, default_value_t = 9)]
        levels: u32,
    },
}

/// Arguments of `hitex terrain render`.
#[derive(Args)]
pub struct RenderArgs {
    /// Elevation model: GeoTIFF, SRTM .hgt, ESRI ASCII .asc, numpy .npy/.npz.
    #[arg(long)]
    pub dem: PathBuf,
    /// Imagery (GeoTIFF, same CRS as the DEM); without it the terrain is
    /// coloured by elevation.
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// Image bands for red, green, blue (1-based), e.g. Landsat's 3,2,1.
    #[arg(long, default_value = "3,2,1")]
    pub bands: String,
    /// Vertical exaggeration.
    #[arg(long, default_value_t = 3.0)]
    pub exaggeration: f32,
    /// Camera height above the mean terrain, metres.
    #[arg(long, default_value_t = 6000.0)]
    pub altitude: f32,
    /// Camera pitch below the horizon, degrees.
    #[arg(long, default_value_t = 40.0)]
    pub pitch: f32,
    /// Camera heading, degrees clockwise from north.
    #[arg(long, default_value_t = 0.0)]
    pub heading: f32,
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Output size, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_size, default_value = "1024x768")]
    pub size: (u32, u32),
    /// Which renderer to use.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub backend: Backend,
    /// Show the MIP level chosen per pixel instead of the imagery.
    #[arg(long)]
    pub levels: bool,
}

/// Band values stretched from their 2nd to 98th percentile into an sRGB image.
fn stretched(img: &GeoRaster, bands: [usize; 3]) -> Result<Image, CliError> {
    let mut lo_hi = [(0.0f32, 1.0f32); 3];
    for (k, &b) in bands.iter().enumerate() {
        let mut v: Vec<f32> = (0..img.width * img.height)
            .map(|i| img.data[i as usize * img.bands + b])
            .filter(|x| x.is_finite())
            .collect();
        v.sort_by(|a, b| a.total_cmp(b));
        if v.is_empty() {
            return Err(CliError::Input(format!("band {} has no finite samples", b + 1)));
        }
        let (lo, hi) = (v[v.len() * 2 / 100], v[(v.len() * 98 / 100).min(v.len() - 1)]);
        lo_hi[k] = (lo, if hi > lo { hi } else { lo + 1.0 });
    }
    Image::from_fn(img.width, img.height, ColorSpace::Srgb, |x, y| {
        let c = |k: usize| {
            let (lo, hi) = lo_hi[k];
            ((img.get(x, y, bands[k]) - lo) / (hi - lo) * 255.0).clamp(0.0, 255.0) as u8
        };
        [c(0), c(1), c(2), 255]
    })
    .map_err(|e| CliError::Input(e.to_string()))
}

/// Elevation colours (green lowlands, brown hills, white peaks) as a texture.
fn hypsometric(heights: &[f32], w: u32, h: u32) -> Result<Image, CliError> {
    let lo = heights.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = heights.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let stops = [[40.0, 110.0, 60.0], [150.0, 170.0, 90.0], [140.0, 100.0, 60.0], [245.0, 245.0, 245.0]];
    Image::from_fn(w, h, ColorSpace::Srgb, |x, y| {
        let t = ((heights[(y * w + x) as usize] - lo) / (hi - lo).max(1e-6)).clamp(0.0, 1.0) * 2.999;
        let (i, f) = (t as usize, t.fract());
        let c = |k: usize| (stops[i][k] + (stops[i + 1][k] - stops[i][k]) * f) as u8;
        [c(0), c(1), c(2), 255]
    })
    .map_err(|e| CliError::Input(e.to_string()))
}

fn render(a: RenderArgs) -> Result<(), CliError> {
    for (name, v) in
        [("--exaggeration", a.exaggeration), ("--altitude", a.altitude), ("--pitch", a.pitch), ("--heading", a.heading)]
    {
        if !v.is_finite() {
            return Err(CliError::Input(format!("{name} must be finite")));
        }
    }
    if !(1.0..=89.0).contains(&a.pitch) || a.altitude <= 0.0 {
        return Err(CliError::Input("--pitch must be in 1..=89 degrees and --altitude positive".into()));
    }
    let bands: Vec<usize> = a
        .bands
        .split(',')
        .map(|s| s.trim().parse::<usize>().ok().filter(|&b| b >= 1).map(|b| b - 1))
        .collect::<Option<Vec<_>>>()
        .filter(|v| v.len() == 3)
        .ok_or_else(|| CliError::Input(format!("--bands '{}' is not three 1-based band numbers", a.bands)))?;
    let mut dem = load_elevation(&a.dem)?;
    let filled = fill_holes(&mut dem);
    if filled > 0 {
        println!("filled {filled} missing elevation samples from their neighbours");
    }
    let heights: Vec<f32> = (0..dem.width * dem.height).map(|i| dem.data[i as usize * dem.bands]).collect();
    let (pyramid, image_extent) = match &a.image {
        Some(path) => {
            let img = load_geotiff(path)?;
            if let Some(b) = bands.iter().find(|&&b| b >= img.bands) {
                return Err(CliError::Input(format!(
                    "{}: band {} requested, the image has {}",
                    path.display(),
                    b + 1,
                    img.bands
                )));
            }
            if !dem.same_crs(&img) {
                return Err(CliError::Input(format!(
                    "{} is in {} but {} is in {}: reproject one of them first",
                    a.dem.display(),
                    dem.crs_name(),
                    path.display(),
                    img.crs_name()
                )));
            }
            (MipPyramid::build(stretched(&img, [bands[0], bands[1], bands[2]])?), img.extent())
        }
        None => (MipPyramid::build(hypsometric(&heights, dem.width, dem.height)?), dem.extent()),
    };
    // texture coordinates of each post from the georeferencing of both rasters
    let (ix0, ix1, iy0, iy1) = image_extent;
    let uv = |i: usize, j: usize| {
        let wx = dem.origin[0] + (i as f64 + 0.5) * dem.pixel[0];
        let wy = dem.origin[1] - (j as f64 + 0.5) * dem.pixel[1];
        Vec2::new(((wx - ix0) / (ix1 - ix0)) as f32, ((iy1 - wy) / (iy1 - iy0)) as f32)
    };
    // post spacing in metres: geographic DEMs (degrees) are converted at their latitude
    let spacing = if dem.epsg == Some(4326) {
        let lat = (dem.origin[1] - dem.pixel[1] * dem.height as f64 / 2.0).to_radians();
        [(dem.pixel[0] * 111_320.0 * lat.cos()) as f32, (dem.pixel[1] * 110_540.0) as f32]
    } else {
        [dem.pixel[0] as f32, dem.pixel[1] as f32]
    };
    let mesh =
        hitex_core::terrain::grid_mesh(&heights, dem.width as usize, dem.height as usize, spacing, a.exaggeration, uv)
            .map_err(|e| CliError::Input(format!("{}: {e}", a.dem.display())))?;
    let mean = heights.iter().map(|&h| h as f64).sum::<f64>() / heights.len() as f64;
    let target = Vec3::new(0.0, mean as f32 * a.exaggeration, 0.0);
    let (p, h) = (a.pitch.to_radians(), a.heading.to_radians());
    let dir = Vec3::new(h.sin() * p.cos(), -p.sin(), -h.cos() * p.cos());
    let dist = a.altitude / p.sin();
    let camera = Camera::new(target - dir * dist, target, Vec3::Y, 45.0, (dist * 0.01).max(1.0), dist * 40.0)
        .map_err(|e| CliError::Input(e.to_string()))?;
    let material = Material {
        name: "imagery".into(),
        texture: Some(0),
        sampler: SamplerOptions { filter: Filter::Trilinear, wrap: Wrap::Clamp, ..Default::default() },
        ..Default::default()
    };
    let scene = Scene {
        camera,
        lights: vec![Light::Directional { direction: Vec3::new(-0.4, -1.0, 0.3), color: Vec3::ONE, intensity: 0.9 }],
        ambient: Vec3::splat(0.45),
        background: Vec3::new(0.45, 0.6, 0.85),
        textures: vec![Arc::new(pyramid)],
        materials: vec![material],
        objects: vec![Object { mesh: Arc::new(mesh), transform: Mat4::IDENTITY, material: 0 }],
        width: a.size.0,
        height: a.size.1,
        mode: if a.levels { RenderMode::Level } else { RenderMode::Shaded },
        nurbs: Vec::new(),
        nurbs_mode: "shaded".into(),
    };
    let prepared = PreparedScene::new(&scene);
    let mut r = AnyRenderer::open(a.backend.into())?;
    let t = Instant::now();
    let f = r.render(&prepared, &prepared.camera, a.size.0, a.size.1)?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    save(&f, &a.output)?;
    println!(
        "wrote {} ({}x{}, DEM {}x{} posts at {:.1} m, {}, {}, {}) in {ms:.1} ms",
        a.output.display(),
        a.size.0,
        a.size.1,
        dem.width,
        dem.height,
        spacing[0],
        if a.image.is_some() { "draped with imagery" } else { "coloured by elevation" },
        dem.crs_name(),
        r.name()
    );
    Ok(())
}

/// Runs a `hitex terrain` subcommand.
pub fn run(cmd: TerrainCommand) -> Result<(), CliError> {
    match cmd {
        TerrainCommand::Render(a) => render(a),
        TerrainCommand::ActiveArea { fov, width, map, levels } => {
            let a = hitex_core::terrain::active_area(fov, width, map, levels)
                .map_err(|e| CliError::Input(e.to_string()))?;
            println!("active area for FOV {fov}°, {width} px per scanline, {map}×{map}-texel maps (eq. (7)):");
            println!(
                "{:>5} {:>22} {:>10} {:>6} {:>12}",
                "level", "covers |x| ≤ (maps L0)", "per side", "maps", "memory"
            );
            let bytes = map as u64 * map as u64 * 4;
            for l in &a {
                println!(
                    "{:>5} {:>22.4} {:>10} {:>6} {:>9.1} MiB",
                    l.level,
                    l.radius,
                    l.per_side,
                    l.maps,
                    (l.maps as u64 * bytes) as f64 / 1048576.0
                );
            }
            let total: u32 = a.iter().map(|l| l.maps).sum();
            println!("total: {total} maps, {:.1} MiB as RGBA8", (total as u64 * bytes) as f64 / 1048576.0);
            Ok(())
        }
    }
}
