//! `hitex terrain …`: elevation models draped with geospecific imagery.

use crate::{Backend, CliError, open_renderer, parse_size, render_frame, save};
use clap::{Args, Subcommand};
use glam::{Mat4, Vec2, Vec3};
use hitex_core::scene::{Camera, Light, Material, Object, RenderMode, Scene};
use hitex_core::texture::procedural::Pattern;
use hitex_core::texture::{ColorSpace, Filter, Image, MipPyramid, SamplerOptions, Wrap};
use hitex_io::dem::load_elevation;
use hitex_io::geotiff::{GeoRaster, fill_holes, load_geotiff};
use hitex_render::PreparedScene;
use hitex_render::{Job, Renderer};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// `hitex terrain` subcommands.
#[derive(Subcommand)]
pub enum TerrainCommand {
    /// Render a DEM draped with co-registered imagery (per-pixel trilinear MIP mapping).
    Render(RenderArgs),
    /// Build a GST pyramid store (TMS layout) from imagery, tile by tile.
    Build(crate::terrain_store_cmd::BuildArgs),
    /// Fly over a store through the resident-map cache, writing PNG frames.
    Fly(crate::terrain_store_cmd::FlyArgs),
    /// Pack a finished web-mercator store folder (e.g. built by shards) into one MBTiles file.
    Pack {
        /// The store folder (built with --profile mercator).
        store: PathBuf,
        /// The MBTiles file to write.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Maps of each MIP level the active area needs (eq. (5)–(7)) and their memory.
    ActiveArea {
        /// Horizontal field of view, degrees.
        #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
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
    /// Fly over a texture and compare per-pixel trilinear with span-parallel
    /// mapping from 3×3 / 4×4 interleaved banks (eq. (8)–(10)).
    Spans(SpansArgs),
}

/// Arguments of `hitex terrain spans`.
#[derive(Args)]
pub struct SpansArgs {
    /// Ground texture: PNG/JPEG, or GeoTIFF (.tif/.tiff, bands from --bands);
    /// default: a procedural pattern.
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// GeoTIFF bands for red, green, blue (1-based).
    #[arg(long, default_value = "3,2,1")]
    pub bands: String,
    /// Procedural pattern when no --image is given: checker, uv-grid, bricks.
    #[arg(long, default_value = "bricks")]
    pub pattern: String,
    /// Side of the procedural texture, texels.
    #[arg(long, default_value_t = 1024)]
    pub texture_size: u32,
    /// Eye height above the ground in level-0 texels (default: 0.3 × the texture's longer side).
    #[arg(long, allow_negative_numbers = true)]
    pub altitude: Option<f64>,
    /// Pitch below the horizon, degrees.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub pitch: f64,
    /// Heading, degrees clockwise from north.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub heading: f64,
    /// Horizontal field of view, degrees.
    #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
    pub fov: f64,
    /// Frames along the straight path.
    #[arg(long, default_value_t = 8)]
    pub frames: u32,
    /// Ground distance flown per frame in texels (default: altitude / 4).
    #[arg(long, allow_negative_numbers = true)]
    pub step: Option<f64>,
    /// Frame size, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_size, default_value = "1024x768")]
    pub size: (u32, u32),
    /// Output PNG: trilinear | span 3×3 | span 4×4 | |trilinear − span 3×3| × 8 (last frame).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Arguments of `hitex terrain render`.
#[derive(Args)]
pub struct RenderArgs {
    /// Elevation model: GeoTIFF, SRTM .hgt, ESRI ASCII .asc, numpy .npy/.npz;
    /// several files or a folder of them are tiles of one mosaic.
    #[arg(long, num_args = 1.., required = true)]
    pub dem: Vec<PathBuf>,
    /// Imagery: a GeoTIFF (reprojected when its CRS is not the DEM's), or
    /// PNG/JPEG with a world file in the DEM's CRS (.pgw/.jgw/.wld; used as
    /// RGB); without it the terrain is coloured by elevation.
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// Image bands for red, green, blue (1-based), e.g. Landsat's 3,2,1.
    #[arg(long, default_value = "3,2,1")]
    pub bands: String,
    /// Vertical exaggeration.
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
    pub exaggeration: f32,
    /// Camera height above the mean terrain, metres (default: 0.6 × the DEM's longer side, so
    /// that the whole model is in view).
    #[arg(long, allow_negative_numbers = true)]
    pub altitude: Option<f32>,
    /// Camera pitch below the horizon, degrees.
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    pub pitch: f32,
    /// Camera heading, degrees clockwise from north.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub heading: f32,
    /// Output PNG.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Output size, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_size, default_value = "1024x768")]
    pub size: (u32, u32),
    /// The projected CRS to render in (EPSG:N or a PROJ.4 definition): the
    /// DEM and the imagery are reprojected into it. Default: the DEM's own
    /// when projected; for a geographic DEM the imagery's, or a local metric
    /// frame at the DEM's centre.
    #[arg(long)]
    pub crs: Option<String>,
    /// Which renderer to use.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub backend: Backend,
    /// Show the MIP level chosen per pixel instead of the imagery (`--levels`
    /// is the older name; `active-area --levels` counts levels).
    #[arg(long = "show-levels", visible_alias = "levels")]
    pub levels: bool,
    /// Read the full-resolution DEM and imagery even where a GeoTIFF holds
    /// overviews (a Cloud-Optimized GeoTIFF's coarser levels): by default a
    /// DEM is read at the coarsest level that still has as many posts as
    /// the view can show, and imagery at the coarsest with at least 16
    /// texels per pixel of the view.
    #[arg(long)]
    pub full_resolution: bool,
}

/// The level of a GeoTIFF that a view needs: the coarsest overview at most
/// `k` times coarser than the full image (`k` from the full image's size
/// against `cap` pixels: `ceil` rounds it up, as decimating by whole blocks
/// does), with a line saying what was read; None when the full image is
/// needed (or is within the cap, or the file has no overviews, or the
/// overview cannot be read: said in a warning).
fn overview_for(path: &Path, what: &str, cap: u64, ceil: bool) -> Result<Option<GeoRaster>, CliError> {
    use hitex_io::geotiff::Coarsening;
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    if ext != "tif" && ext != "tiff" {
        return Ok(None);
    }
    let how = if ceil { Coarsening::WholeBlocks } else { Coarsening::Exact };
    let v = hitex_io::geotiff::load_for_view(path, cap, how)?;
    for n in &v.notes {
        eprintln!("hitex: warning: {}: {n}", path.display());
    }
    let Some(l) = v.read else { return Ok(None) };
    say!(
        "{}: read overview {} of {} ({}x{} {what}, {:.0}x coarser) of the full {}x{}: enough for the view \
         (--full-resolution reads the full image)",
        path.display(),
        l.level,
        l.overviews,
        l.raster.width,
        l.raster.height,
        l.factor,
        l.full.0,
        l.full.1
    );
    Ok(Some(l.raster))
}

/// Band values stretched from their 2nd to 98th percentile into an sRGB image.
pub(crate) fn stretched(img: &GeoRaster, bands: [usize; 3]) -> Result<Image, CliError> {
    let mut lo_hi = [(0.0f32, 1.0f32); 3];
    for (k, &b) in bands.iter().enumerate() {
        let v = (0..img.width as usize * img.height as usize).map(|i| img.data[i * img.bands + b]);
        lo_hi[k] = hitex_io::geotiff::stretch_range(v)
            .ok_or_else(|| CliError::Input(format!("band {} has no finite samples", b + 1)))?;
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

/// PNG/JPEG imagery georeferenced by its world file, checked against the
/// DEM: world files carry no CRS, so the DEM's is assumed (and said); the
/// extents must overlap. Returns the raster and its pixels as RGB.
pub(crate) fn world_imagery(
    path: &std::path::Path,
    dem: &GeoRaster,
    dem_path: &std::path::Path,
) -> Result<(GeoRaster, Image), CliError> {
    let mut img = hitex_io::geotiff::load_world_image(path)?;
    eprintln!(
        "hitex: note: {} is georeferenced by a world file, which names no CRS: taken to be the DEM's ({})",
        path.display(),
        dem.crs_name()
    );
    img.epsg = dem.epsg;
    img.projection = dem.projection;
    img.citation = dem.citation.clone();
    img.proj4 = dem.proj4.clone();
    check_coregistered(dem, &img, dem_path, path)?;
    let rgb = world_rgb(&img)?;
    Ok((img, rgb))
}

/// The pixels of world-file imagery (bands 1–3, 0–255) as RGB.
fn world_rgb(img: &GeoRaster) -> Result<Image, CliError> {
    Image::from_fn(img.width, img.height, ColorSpace::Srgb, |x, y| {
        let c = |k: usize| img.get(x, y, k).clamp(0.0, 255.0) as u8;
        [c(0), c(1), c(2), 255]
    })
    .map_err(|e| CliError::Input(e.to_string()))
}

/// `--bands "3,2,1"` as 0-based indices.
fn parse_band_list(s: &str) -> Result<[usize; 3], CliError> {
    let v: Vec<usize> = s
        .split(',')
        .map(|s| s.trim().parse::<usize>().ok().filter(|&b| b >= 1).map(|b| b - 1))
        .collect::<Option<Vec<_>>>()
        .filter(|v| v.len() == 3)
        .ok_or_else(|| CliError::Input(format!("--bands '{s}' is not three 1-based band numbers")))?;
    Ok([v[0], v[1], v[2]])
}

fn check_bands(bands: [usize; 3], img: &GeoRaster, path: &std::path::Path) -> Result<[usize; 3], CliError> {
    if let Some(b) = bands.iter().find(|&&b| b >= img.bands) {
        return Err(CliError::Input(format!(
            "{}: band {} requested, the image has {}",
            path.display(),
            b + 1,
            img.bands
        )));
    }
    Ok(bands)
}

/// `--bands` checked against the image: 0-based indices.
pub(crate) fn parse_bands(s: &str, img: &GeoRaster, path: &std::path::Path) -> Result<[usize; 3], CliError> {
    check_bands(parse_band_list(s)?, img, path)
}

/// The DEM and the imagery must share their CRS and overlap.
pub(crate) fn check_coregistered(
    dem: &GeoRaster,
    img: &GeoRaster,
    dem_path: &std::path::Path,
    img_path: &std::path::Path,
) -> Result<(), CliError> {
    if !dem.same_crs(img) {
        return Err(CliError::Input(format!(
            "{} is in {} but {} is in {}: reproject one of them first",
            dem_path.display(),
            dem.crs_name(),
            img_path.display(),
            img.crs_name()
        )));
    }
    let (a0, a1, b0, b1) = dem.extent();
    let (c0, c1, d0, d1) = img.extent();
    if a1 <= c0 || c1 <= a0 || b1 <= d0 || d1 <= b0 {
        return Err(CliError::Input(format!(
            "{} and {} do not overlap (x {a0:.0}..{a1:.0} vs {c0:.0}..{c1:.0}, y {b0:.0}..{b1:.0} vs {d0:.0}..{d1:.0})",
            dem_path.display(),
            img_path.display()
        )));
    }
    Ok(())
}

fn hypsometric(heights: &[f32], w: u32, h: u32) -> Result<Image, CliError> {
    hitex_core::terrain::hypsometric(heights, w, h).map_err(|e| CliError::Input(e.to_string()))
}

/// The elevation model of `--dem`: one file, or tiles (several files, or
/// the elevation files of a folder) as one mosaic.
pub(crate) struct DemInput {
    /// The raster.
    pub raster: hitex_io::geotiff::GeoRaster,
    /// What names it in messages: the file, the folder, or the first tile.
    pub name: PathBuf,
    /// The one file it was read from (None for a mosaic).
    pub file: Option<PathBuf>,
}

/// Reads `--dem`'s files or folders; several tiles become one mosaic (said
/// on stdout, with each tile that had to be reprojected).
pub(crate) fn load_dem_input(paths: &[PathBuf]) -> Result<DemInput, CliError> {
    let mut files = Vec::new();
    for p in paths {
        if p.is_dir() {
            files.extend(hitex_io::mosaic::dem_files(p)?);
        } else {
            files.push(p.clone());
        }
    }
    let name = match (paths, files.as_slice()) {
        ([one], [_, _, ..]) => one.clone(),
        (_, [first, rest @ ..]) if !rest.is_empty() => {
            PathBuf::from(format!("{} (+{} tiles)", first.display(), rest.len()))
        }
        (_, [only]) => only.clone(),
        _ => return Err(CliError::Input("--dem: no elevation file given".into())),
    };
    if let [only] = files.as_slice() {
        return Ok(DemInput { raster: load_dem(only)?, name, file: Some(only.clone()) });
    }
    let mut tiles = Vec::with_capacity(files.len());
    for f in &files {
        let r = load_elevation(f)?;
        for w in hitex_io::dem::elevation_warnings(&r) {
            eprintln!("hitex: warning: {}: {w}", f.display());
        }
        tiles.push((r, f.clone()));
    }
    let n = tiles.len();
    let (raster, notes) = hitex_io::mosaic::mosaic(tiles)?;
    for l in &notes {
        say!("{l}");
    }
    say!("{}: a mosaic of {n} tiles, {}x{} posts", name.display(), raster.width, raster.height);
    let nodata = |v: f32| !v.is_finite() || raster.nodata.is_some_and(|nd| (v as f64 - nd).abs() < 1e-6);
    if raster.data.iter().all(|&v| nodata(v)) {
        return Err(CliError::Input(format!("{}: no elevation sample in any tile", name.display())));
    }
    Ok(DemInput { raster, name, file: None })
}

/// Reads an elevation model, saying on stderr what looks wrong with it.
pub(crate) fn load_dem(path: &std::path::Path) -> Result<hitex_io::geotiff::GeoRaster, CliError> {
    checked_dem(load_elevation(path)?, path)
}

/// An elevation model held in memory (`path` names it and its extension
/// gives the format), checked as [`load_dem`] checks a file.
pub(crate) fn parse_dem(bytes: &[u8], path: &std::path::Path) -> Result<hitex_io::geotiff::GeoRaster, CliError> {
    checked_dem(hitex_io::dem::parse_elevation(bytes, path)?, path)
}

fn checked_dem(
    dem: hitex_io::geotiff::GeoRaster,
    path: &std::path::Path,
) -> Result<hitex_io::geotiff::GeoRaster, CliError> {
    let nodata = |v: f32| !v.is_finite() || dem.nodata.is_some_and(|n| (v as f64 - n).abs() < 1e-6);
    if (0..dem.width as usize * dem.height as usize).all(|i| nodata(dem.data[i * dem.bands])) {
        return Err(CliError::Input(format!(
            "{}: no elevation sample: every one of its {}x{} is nodata or not a number",
            path.display(),
            dem.width,
            dem.height
        )));
    }
    for w in hitex_io::dem::elevation_warnings(&dem) {
        eprintln!("hitex: warning: {}: {w}", path.display());
    }
    Ok(dem)
}

fn render(a: RenderArgs) -> Result<(), CliError> {
    for (name, v) in [
        ("--exaggeration", a.exaggeration),
        ("--altitude", a.altitude.unwrap_or(1.0)),
        ("--pitch", a.pitch),
        ("--heading", a.heading),
    ] {
        if !v.is_finite() {
            return Err(CliError::Input(format!("{name} must be finite")));
        }
    }
    // as `terrain fly` has it
    if a.exaggeration < 0.0 {
        return Err(CliError::Input(format!("--exaggeration {} must be finite and ≥ 0", a.exaggeration)));
    }
    if !(a.pitch > 0.0 && a.pitch <= 90.0) {
        return Err(CliError::Input(format!(
            "--pitch {}° must be in (0, 90] below the horizon (90 looks straight down)",
            a.pitch
        )));
    }
    if let Some(alt) = a.altitude
        && alt <= 0.0
    {
        return Err(CliError::Input(format!("--altitude {alt} must be positive")));
    }
    crate::image_out(&a.output)?;
    let bands = parse_band_list(&a.bands)?;
    // no more posts than the picture can show: a 1″ tile is 13 M posts for a 0.8 M-pixel view
    let pixels = a.size.0 as u64 * a.size.1 as u64;
    let post_cap = (4 * pixels).max(1 << 20);
    let coarse_dem = match a.dem.as_slice() {
        [only] if !a.full_resolution && only.is_file() => overview_for(only, "posts", post_cap, true)?,
        _ => None,
    };
    let DemInput { raster: dem, name: dem_name, .. } = match coarse_dem {
        Some(r) => DemInput { raster: checked_dem(r, &a.dem[0])?, name: a.dem[0].clone(), file: None },
        None => load_dem_input(&a.dem)?,
    };
    let crs = a
        .crs
        .as_deref()
        .map(hitex_io::crs::Crs::parse)
        .transpose()
        .map_err(|m| CliError::Input(format!("--crs: {m}")))?;
    // imagery: a world file takes the DEM's own CRS (before any reprojection)
    let (image, world) = match &a.image {
        Some(path) if hitex_io::geotiff::is_world_image(path) => {
            (Some((world_imagery(path, &dem, &dem_name)?.0, path.as_path())), true)
        }
        Some(path) => {
            let coarse = if a.full_resolution { None } else { overview_for(path, "texels", 16 * pixels, false)? };
            let img = match coarse {
                Some(img) => img,
                None => load_geotiff(path)?,
            };
            check_bands(bands, &img, path)?;
            (Some((img, path.as_path())), false)
        }
        None => (None, false),
    };
    // one metric CRS for both: geographic DEMs and imagery in another CRS are reprojected
    let same = image.as_ref().is_none_or(|(i, _)| dem.same_crs(i));
    let geographic = dem.is_geographic();
    let co = if crs.is_some() || geographic || !same {
        let co = hitex_io::reproject::co_register(dem, &dem_name, image, crs.as_ref())?;
        for n in &co.notes {
            say!("{n}");
        }
        co
    } else {
        // a CRS in feet keeps its posts in feet: the spacing goes to metres as the heights did
        let unit_metres = dem.crs().map_or(1.0, |c| c.unit_metres());
        hitex_io::reproject::CoRegistered {
            dem,
            image: image.map(|(i, _)| i),
            crs: None,
            unit_metres,
            notes: Vec::new(),
        }
    };
    let (mut dem, image, unit) = (co.dem, co.image, co.unit_metres);
    if let (Some(img), Some(path)) = (&image, &a.image) {
        check_coregistered(&dem, img, &dem_name, path)?;
    }
    let filled = fill_holes(&mut dem);
    if filled > 0 {
        let why = if co.notes.is_empty() { "" } else { " (nodata, or outside the source after reprojection)" };
        say!("filled {filled} missing elevation samples from their neighbours{why}");
    }
    let (posts, cap) = (dem.width as u64 * dem.height as u64, post_cap);
    if posts > cap {
        let k = ((posts as f64 / cap as f64).sqrt().ceil() as u32).max(2);
        let (w0, h0) = (dem.width, dem.height);
        dem = hitex_io::geotiff::decimated(&dem, k);
        say!(
            "meshed {}x{} posts (the means of {k}x{k} blocks): the DEM's {w0}x{h0} are more than 4 a pixel of {}x{}",
            dem.width,
            dem.height,
            a.size.0,
            a.size.1
        );
    }
    let heights: Vec<f32> = (0..dem.width * dem.height).map(|i| dem.data[i as usize * dem.bands]).collect();
    let (pyramid, image_extent) = match &image {
        Some(img) if world => (MipPyramid::build(world_rgb(img)?), img.extent()),
        Some(img) => (MipPyramid::build(stretched(img, bands)?), img.extent()),
        None => (MipPyramid::build(hypsometric(&heights, dem.width, dem.height)?), dem.extent()),
    };
    // texture coordinates of each post from the georeferencing of both rasters
    let (ix0, ix1, iy0, iy1) = image_extent;
    let uv = |i: usize, j: usize| {
        let wx = dem.origin[0] + (i as f64 + 0.5) * dem.pixel[0];
        let wy = dem.origin[1] - (j as f64 + 0.5) * dem.pixel[1];
        Vec2::new(((wx - ix0) / (ix1 - ix0)) as f32, ((iy1 - wy) / (iy1 - iy0)) as f32)
    };
    // post spacing in metres (the CRS's unit may be the foot)
    let spacing = [(dem.pixel[0] * unit) as f32, (dem.pixel[1] * unit) as f32];
    let mesh =
        hitex_core::terrain::grid_mesh(&heights, dem.width as usize, dem.height as usize, spacing, a.exaggeration, uv)
            .map_err(|e| CliError::Input(format!("{}: {e}", dem_name.display())))?;
    let mean = heights.iter().map(|&h| h as f64).sum::<f64>() / heights.len() as f64;
    let target = Vec3::new(0.0, mean as f32 * a.exaggeration, 0.0);
    let (p, h) = (a.pitch.to_radians(), a.heading.to_radians());
    let dir = Vec3::new(h.sin() * p.cos(), -p.sin(), -h.cos() * p.cos());
    let altitude = a.altitude.unwrap_or_else(|| {
        0.6 * (spacing[0] * dem.width as f32).abs().max((spacing[1] * dem.height as f32).abs()).max(1.0)
    });
    let dist = altitude / p.sin();
    // straight down, the heading gives the image's up
    let up = if a.pitch < 90.0 { Vec3::Y } else { Vec3::new(h.sin(), 0.0, -h.cos()) };
    let camera = Camera::new(target - dir * dist, target, up, 45.0, (dist * 0.01).max(1.0), dist * 40.0)
        .map_err(|e| CliError::Input(e.to_string()))?;
    let material = Material {
        name: "imagery".into(),
        texture: Some(0),
        sampler: SamplerOptions { filter: Filter::Trilinear, wrap: Wrap::Clamp, ..Default::default() },
        // a height field: a far slope's sliver at a ridge's outline is lit as
        // the slope it is, not as its dark underside
        one_sided: true,
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
    let mut r = open_renderer(a.backend)?;
    let t = Instant::now();
    let mut f = render_frame(&mut r, &Job::Scene { scene: &prepared, camera: prepared.camera }, a.size)?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    // a terrain that covers (almost) nothing is said, not left as a sky picture
    let e = hitex_core::texture::linear_to_srgb_u8;
    let bg = [e(0.45), e(0.6), e(0.85)];
    let covered = f.rgba.chunks_exact(4).filter(|p| p[..3] != bg).count();
    if covered * 1000 < f.rgba.len() / 4 {
        eprintln!(
            "hitex: warning: the terrain covers {covered} of {} pixels: it is out of view at altitude {altitude} m, pitch {}°, heading {}°",
            f.rgba.len() / 4,
            a.pitch,
            a.heading
        );
    }
    if a.levels {
        hitex_render::legend::level_legend(&mut f, scene.textures[0].level_count());
    }
    save(&f, &a.output)?;
    say!(
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

/// The flight texture and its wrap mode (imagery mirrors, patterns repeat).
fn spans_texture(a: &SpansArgs) -> Result<(MipPyramid, Wrap, String), CliError> {
    ground_texture(a.image.as_deref(), &a.bands, &a.pattern, a.texture_size)
}

/// A ground texture: a PNG/JPEG, a GeoTIFF's `bands` stretched to RGB, or
/// the procedural `pattern` of `texture_size`² texels; with its wrap mode and
/// a description.
pub(crate) fn ground_texture(
    image: Option<&Path>,
    bands: &str,
    pattern: &str,
    texture_size: u32,
) -> Result<(MipPyramid, Wrap, String), CliError> {
    match image {
        Some(path) => {
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase();
            let img = if ext == "tif" || ext == "tiff" {
                let raster = load_geotiff(path)?;
                let bands = parse_bands(bands, &raster, path)?;
                stretched(&raster, bands)?
            } else {
                hitex_io::load_image(path, ColorSpace::Srgb)?
            };
            let name = format!("{} ({}x{})", path.display(), img.width(), img.height());
            Ok((MipPyramid::build(img), Wrap::Mirror, name))
        }
        None => {
            let p = Pattern::from_name(pattern).ok_or_else(|| {
                let names: Vec<&str> = Pattern::ALL.iter().map(|p| p.name()).collect();
                CliError::Input(format!("--pattern '{pattern}' is not one of {}", names.join(", ")))
            })?;
            if !(4..=8192).contains(&texture_size) {
                return Err(CliError::Input("--texture-size must be in 4 to 8192".into()));
            }
            let img = p.render(texture_size).map_err(|e| CliError::Input(e.to_string()))?;
            Ok((MipPyramid::build(img), Wrap::Repeat, format!("procedural {} {texture_size}²", p.name())))
        }
    }
}

/// `hitex terrain spans`: per case the median time per frame, PSNR and SSIM
/// against per-pixel trilinear, bank conflicts, and the memory of each design.
pub(crate) fn spans(a: SpansArgs) -> Result<(), CliError> {
    crate::keep_going_on_closed_stdout();
    use hitex_core::texture::span::{
        BankModel, FlightView, SpanFilter, SpanOptions, SpanScheme, memory_for_pyramid, psnr, render_spans,
        render_trilinear, ssim,
    };
    for (name, v) in [("--pitch", a.pitch), ("--heading", a.heading), ("--fov", a.fov)] {
        if !v.is_finite() {
            return Err(CliError::Input(format!("{name} must be finite")));
        }
    }
    if !(a.pitch > 0.0 && a.pitch <= 90.0) {
        return Err(CliError::Input(format!(
            "--pitch {}° must be in (0, 90] below the horizon (90 looks straight down)",
            a.pitch
        )));
    }
    if !(1.0..=170.0).contains(&a.fov) {
        return Err(CliError::Input(format!("--fov {} must be in 1 to 170 degrees", a.fov)));
    }
    crate::image_out(&a.output)?;
    if a.frames == 0 || a.frames > 10_000 {
        return Err(CliError::Input(format!("--frames {} must be in 1 to 10000", a.frames)));
    }
    let (pyr, wrap, name) = spans_texture(&a)?;
    let altitude = a.altitude.unwrap_or(0.3 * pyr.width().max(pyr.height()) as f64);
    let step = a.step.unwrap_or(altitude / 4.0);
    if !altitude.is_finite() || altitude <= 0.0 {
        return Err(CliError::Input(format!("--altitude {altitude} must be positive")));
    }
    let side = pyr.width().max(pyr.height()) as f64;
    if !(step.is_finite() && step > 0.0 && step <= side) {
        return Err(CliError::Input(format!(
            "--step {step} must be in (0, {side}] texels per frame (the texture's side)"
        )));
    }
    let _ = pyr.linear_level(0); // decode once, outside the timings
    let (w, h) = a.size;
    let hd = a.heading.to_radians();
    let start = [pyr.width() as f64 / 2.0, pyr.height() as f64 / 2.0];
    let views: Vec<FlightView> = (0..a.frames)
        .map(|i| FlightView {
            position: [start[0] + hd.sin() * step * i as f64, start[1] - hd.cos() * step * i as f64],
            altitude,
            pitch_deg: a.pitch,
            heading_deg: a.heading,
            fov_deg: a.fov,
            width: w,
            height: h,
        })
        .collect();
    if wrap == Wrap::Mirror {
        // imagery has edges: past them the sampler mirrors it, which looks
        // like terrain but is not; say where the flight leaves the image
        let (iw, ih) = (pyr.width() as f64, pyr.height() as f64);
        let inside = |p: [f64; 2]| (0.0..=iw).contains(&p[0]) && (0.0..=ih).contains(&p[1]);
        match views.iter().position(|v| !inside(v.position)) {
            Some(k) => eprintln!(
                "hitex: warning: the flight leaves the {}x{} image at frame {} of {} (--step {step:.1} texels a frame); past its edges the imagery is mirrored, not real ground",
                pyr.width(),
                pyr.height(),
                k + 1,
                views.len()
            ),
            None => say!("past the image's edges (towards the horizon) the imagery is mirrored"),
        }
    }
    say!(
        "flight over {name}: {} {w}x{h}, altitude {altitude:.1} texels, pitch {}°, heading {}°, FOV {}°, {} levels",
        crate::count(a.frames as usize, "frame", "frames"),
        a.pitch,
        a.heading,
        a.fov,
        pyr.level_count()
    );
    // per-pixel trilinear: the reference
    let pb = crate::btf_cmd::bar(views.len() as u64 * 5, "spans");
    let mut times = Vec::new();
    let mut reference: Vec<hitex_render::Frame> = Vec::new();
    for v in &views {
        let t = Instant::now();
        reference.push(render_trilinear(&pyr, v, wrap));
        times.push(t.elapsed().as_secs_f64() * 1e3);
        pb.inc(1);
    }
    pb.suspend(|| {
        say!(
            "{:<10} {:>9} {:>10} {:>8} {:>10} {:>12} {:>10} {:>8}",
            "case",
            "ms/frame",
            "PSNR dB",
            "SSIM",
            "conflicts",
            "accesses",
            "words",
            "mean λ"
        )
    });
    pb.suspend(|| {
        say!(
            "{:<10} {:>9.2} {:>10} {:>8} {:>10} {:>12} {:>10} {:>8}",
            "trilinear",
            crate::bench::median(&mut times),
            "-",
            "-",
            "-",
            "-",
            "-",
            "-"
        )
    });
    let cases = [
        ("span3", SpanScheme::Banks3x3, SpanFilter::Bilinear),
        ("span4", SpanScheme::Banks4x4, SpanFilter::Bilinear),
        ("bicubic3", SpanScheme::Banks3x3, SpanFilter::Bicubic),
        ("bicubic4", SpanScheme::Banks4x4, SpanFilter::Bicubic),
    ];
    let mut total_conflicts = 0u64;
    let mut last: Vec<hitex_render::Frame> = Vec::new();
    for (label, scheme, filter) in cases {
        let opts = SpanOptions { scheme, filter, wrap, level_shift: 0 };
        let mut banks = BankModel::new(scheme);
        let (mut times, mut p, mut s) = (Vec::new(), 0.0, 0.0);
        let mut frame = None;
        for (v, r) in views.iter().zip(&reference) {
            let t = Instant::now();
            let f = render_spans(&pyr, v, &opts, &mut banks);
            times.push(t.elapsed().as_secs_f64() * 1e3);
            p += psnr(r, &f);
            s += ssim(r, &f);
            frame = Some(f);
            pb.inc(1);
        }
        let n = views.len() as f64;
        total_conflicts += banks.conflicts;
        pb.suspend(|| {
            say!(
                "{label:<10} {:>9.2} {:>10.2} {:>8.4} {:>10} {:>12} {:>10} {:>8.2}",
                crate::bench::median(&mut times),
                p / n,
                s / n,
                banks.conflicts,
                banks.accesses,
                banks.words,
                banks.mean_level()
            )
        });
        if banks.guard_raises > 0 {
            pb.suspend(|| say!("  ({} spans raised by the rounding guard)", banks.guard_raises));
        }
        if filter == SpanFilter::Bilinear {
            last.extend(frame);
        }
    }
    pb.finish_and_clear();
    say!("total bank conflicts: {total_conflicts}");
    // the rule is tight: one level finer (on 3×3 banks: eq. (9) taken literally) conflicts
    for scheme in [SpanScheme::Banks3x3, SpanScheme::Banks4x4] {
        let opts = SpanOptions { scheme, filter: SpanFilter::Bilinear, wrap, level_shift: -1 };
        let mut banks = BankModel::new(scheme);
        let _ = render_spans(&pyr, &views[0], &opts, &mut banks);
        say!(
            "  check, {} banks one level finer than the rule (frame 1): {} conflicts, {} of {} accesses conflicted",
            scheme.name(),
            banks.conflicts,
            banks.conflicted_accesses,
            banks.accesses
        );
    }
    let m3 = memory_for_pyramid(&pyr, SpanScheme::Banks3x3);
    let m4 = memory_for_pyramid(&pyr, SpanScheme::Banks4x4);
    let mib = |b: u64| b as f64 / 1_048_576.0;
    say!("texture memory ({} texels in {} levels, RGBA8):", pyr.texel_count(), pyr.level_count());
    say!(
        "  conventional: {} pixel processors × full copy, {} banks: {:.2} MiB",
        m3.pixel_processors,
        m3.conventional_banks,
        mib(m3.conventional_bytes)
    );
    for (label, m) in [("span 3x3", m3), ("span 4x4", m4)] {
        say!(
            "  {label}: one shared copy in {} banks: {:.2} MiB ({:.4} of conventional; {:.4} without bank padding)",
            m.span_banks,
            mib(m.span_bytes),
            m.ratio(),
            m.unpadded_ratio()
        );
    }
    // trilinear | span 3×3 | span 4×4 | |trilinear − span 3×3| × 8, last frame
    let (Some(tri), [s3, s4]) = (reference.last(), last.as_slice()) else {
        return Err(CliError::Internal("no frame rendered".into()));
    };
    let (wu, hu) = (w as usize, h as usize);
    let mut out = vec![0u8; wu * 4 * hu * 4];
    for y in 0..hu {
        for x in 0..wu {
            let i = (y * wu + x) * 4;
            let row = y * wu * 4;
            let diff: [u8; 4] = std::array::from_fn(|c| {
                if c == 3 { 255 } else { (tri.rgba[i + c].abs_diff(s3.rgba[i + c]) as u32 * 8).min(255) as u8 }
            });
            for (k, src) in [&tri.rgba[i..i + 4], &s3.rgba[i..i + 4], &s4.rgba[i..i + 4], &diff[..]].iter().enumerate()
            {
                let o = (row + k * wu + x) * 4;
                out[o..o + 4].copy_from_slice(src);
            }
        }
    }
    crate::save(&hitex_render::Frame { width: w * 4, height: h, rgba: out }, &a.output)?;
    say!("wrote {} (trilinear | span 3x3 | span 4x4 | |trilinear − span 3x3| × 8)", a.output.display());
    Ok(())
}

/// The widest scanline `terrain active-area` takes (pixels).
const MAX_SCANLINE: u32 = 1 << 20;

/// A byte count in the binary unit that keeps it readable (`12.0 MiB`, `4.3 TiB`).
fn binary_size(bytes: f64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = bytes;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < units.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 { format!("{v:.0} B") } else { format!("{v:.1} {}", units[u]) }
}

/// Runs a `hitex terrain` subcommand.
pub fn run(cmd: TerrainCommand) -> Result<(), CliError> {
    match cmd {
        TerrainCommand::Render(a) => render(a),
        TerrainCommand::Build(a) => crate::terrain_store_cmd::build(a),
        TerrainCommand::Fly(a) => crate::terrain_store_cmd::fly(a),
        TerrainCommand::Pack { store, output } => crate::terrain_store_cmd::pack(&store, &output),
        TerrainCommand::Spans(a) => spans(a),
        TerrainCommand::ActiveArea { fov, width, map, levels } => {
            // the flags by name, before the library's own check
            if !(fov.is_finite() && fov > 0.0 && fov < 180.0) {
                return Err(CliError::Input(format!("--fov {fov} must be in (0, 180) degrees")));
            }
            for (flag, v) in [("--width", width), ("--map", map)] {
                if v == 0 {
                    return Err(CliError::Input(format!(
                        "{flag} 0: give at least 1 {}",
                        if flag == "--map" { "texel" } else { "pixel" }
                    )));
                }
            }
            if !(1..=32).contains(&levels) {
                return Err(CliError::Input(format!("--levels {levels} must be in 1 to 32")));
            }
            if width > MAX_SCANLINE {
                return Err(CliError::Input(format!("--width {width}: a scanline of at most {MAX_SCANLINE} pixels")));
            }
            let a = hitex_core::terrain::active_area(fov, width, map, levels)
                .map_err(|e| CliError::Input(e.to_string()))?;
            say!("active area for FOV {fov}°, {width} px per scanline, {map}×{map}-texel maps (eq. (7)):");
            say!("{:>5} {:>22} {:>10} {:>6} {:>12}", "level", "covers |x| ≤ (maps L0)", "per side", "maps", "memory");
            let bytes = map as f64 * map as f64 * 4.0;
            for l in &a {
                say!(
                    "{:>5} {:>22.4} {:>10} {:>6} {:>13}",
                    l.level,
                    l.radius,
                    l.per_side,
                    l.maps,
                    binary_size(l.maps as f64 * bytes)
                );
            }
            let total: u64 = a.iter().map(|l| l.maps).sum();
            say!(
                "total: {}, {} as RGBA8",
                crate::count(total as usize, "map", "maps"),
                binary_size(total as f64 * bytes)
            );
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sea_is_blue_and_the_land_keeps_its_ramp() {
        // a coast: sea at 0 and -20 m, land up to 100 m
        let heights = [-20.0, 0.0, 1.0, 100.0];
        let img = hypsometric(&heights, 4, 1).unwrap();
        let px = |x: u32| img.texel(x, 0);
        for x in [0, 1] {
            let p = px(x);
            assert!(p[2] > p[1] && p[2] > p[0], "sea at {x}: {p:?}");
        }
        assert!(px(0)[2] < px(1)[2], "deeper water is darker");
        let shore = px(2);
        assert!(shore[1] > shore[2], "land just above the sea is green: {shore:?}");
        assert!(px(3)[..3].iter().all(|&c| c >= 240), "the highest land is white: {:?}", px(3));
        // a model without sea (all above zero, or all below) uses the whole ramp
        let inland = hypsometric(&[200.0, 300.0], 2, 1).unwrap();
        assert!(inland.texel(0, 0)[1] > inland.texel(0, 0)[2]);
        let basin = hypsometric(&[-400.0, -100.0], 2, 1).unwrap();
        assert!(basin.texel(0, 0)[1] > basin.texel(0, 0)[2]);
    }
}
