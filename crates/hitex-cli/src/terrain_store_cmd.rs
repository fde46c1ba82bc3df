//! `hitex terrain build` and `hitex terrain fly`: GST pyramids on disk and
//! flights over them through the resident-map cache.

use crate::{Backend, CliError, open_renderer, parse_size, save};
use clap::Args;
use glam::DVec2;
use hitex_core::residency::{MapKey, ResidentMaps};
use hitex_core::terrain::path::{FlightPath, PathKey};
use hitex_io::gst::{
    BuildOptions, GeoTiffSource, MemorySource, ProceduralSource, Store, StoreMeta, TILE, TileSource, build_store,
    open_store, stored_dem,
};
use hitex_render::terrain::flight::{FlightArea, Relief, prepare_frame};
use hitex_render::terrain::{FlyCamera, FlyGround, FlyPages, FlySampler, FlyUniform};
use hitex_render::{Job, Renderer};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Arguments of `hitex terrain build`.
#[derive(Args)]
pub struct BuildArgs {
    /// Imagery: a GeoTIFF (bands chosen with --bands, stretched 2–98 %, read
    /// by windows), or PNG/JPEG with a world file (used as RGB; needs --dem for its CRS).
    #[arg(long, conflicts_with = "procedural")]
    pub image: Option<PathBuf>,
    /// Image bands for red, green, blue (1-based).
    #[arg(long, default_value = "3,2,1")]
    pub bands: String,
    /// Elevation model kept in the store for relief flights, checked against
    /// the imagery (reprojected into the imagery's CRS when it is in
    /// another). Alone (no --image), the store's imagery is the DEM's shaded
    /// relief, and a geographic DEM moves into a local metric frame.
    #[arg(long, num_args = 1..)]
    pub dem: Vec<PathBuf>,
    /// Instead of an image: procedural imagery of WIDTHxHEIGHT texels, generated on the fly.
    #[arg(long, value_parser = parse_big_size)]
    pub procedural: Option<(u32, u32)>,
    /// Output store: a TMS folder, or one MBTiles file (a name ending in .mbtiles).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Tiling: `local` (level 0 one map over the imagery, in its own CRS) or
    /// `mercator` (the global web-mercator tiles of EPSG:3857 that web maps
    /// and simulator scenery tools load; the imagery is reprojected).
    /// Default: mercator for MBTiles, else local.
    #[arg(long, value_enum)]
    pub profile: Option<ProfileArg>,
    /// Store form: a folder of `zoom/column/row.png` files, or one MBTiles
    /// file (SQLite; web-mercator only). Default: from the output's name.
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// This process's share of the work, INDEX/COUNT (e.g. 0/4).
    #[arg(long, value_parser = parse_shard, default_value = "0/1")]
    pub shard: (u32, u32),
    /// Refuse a build that would write more maps than this (in this shard).
    #[arg(long, default_value_t = DEFAULT_MAX_MAPS)]
    pub max_maps: u64,
    /// Build even when the estimated size exceeds the free space (e.g. on a
    /// compressing file system).
    #[arg(long)]
    pub ignore_free_space: bool,
}

/// `--profile` of `terrain build`.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ProfileArg {
    /// Level 0 is one map over the imagery, in the imagery's CRS.
    Local,
    /// Web-mercator tiles (EPSG:3857, OSGeo TMS global-mercator).
    Mercator,
}

/// `--format` of `terrain build`.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FormatArg {
    /// A folder of PNG files (TMS rows) with metadata.json and tilemapresource.xml.
    Folder,
    /// One MBTiles 1.3 file (SQLite).
    Mbtiles,
}

/// The default cap on the maps one build writes (about 4 M files, a
/// 500 000 × 500 000-texel source).
pub const DEFAULT_MAX_MAPS: u64 = 1 << 22;

/// Estimates a build's maps and bytes before any is written (the PNG size of a
/// sample map times the map count, +10 % for the coarser levels' variation)
/// and refuses it beyond `--max-maps` or the free space of the output's file
/// system.
fn check_build_size(a: &BuildArgs, meta: &StoreMeta, source: &dyn TileSource) -> Result<(), CliError> {
    let maps = meta.total_tiles().div_ceil(a.shard.1 as u64);
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    if maps > a.max_maps {
        return Err(CliError::Input(format!(
            "{}x{} texels make {maps} maps in {} levels (shard {}/{}), beyond --max-maps {}: raise the cap if that is meant, or split the build with --shard",
            meta.width, meta.height, meta.levels, a.shard.0, a.shard.1, a.max_maps
        )));
    }
    let per_map = hitex_io::gst::sample_map_bytes(source)?;
    let need = maps.saturating_mul(per_map + per_map / 10 + 512);
    if !a.ignore_free_space
        && let Some(free) = free_bytes(&a.output)
        && need > free
    {
        return Err(CliError::Input(format!(
            "{}: the store needs about {:.1} GiB ({maps} maps of about {} KiB), {:.1} GiB are free",
            a.output.display(),
            gib(need),
            per_map / 1024,
            gib(free)
        )));
    }
    if maps > 10_000 {
        eprintln!("hitex: {maps} maps in {} levels, about {:.1} GiB", meta.levels, gib(need));
    }
    Ok(())
}

/// Free bytes for an unprivileged writer on the file system that holds `p`
/// (or its nearest existing ancestor).
#[cfg(unix)]
fn free_bytes(p: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt;
    let mut q = p.to_path_buf();
    while !q.exists() {
        q = match q.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        };
    }
    let c = std::ffi::CString::new(q.as_os_str().as_bytes()).ok()?;
    // SAFETY: `c` is NUL-terminated; `s` is a plain-data out-parameter.
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    let ok = unsafe { libc::statvfs(c.as_ptr(), &mut s) } == 0;
    #[allow(clippy::unnecessary_cast)]
    ok.then(|| s.f_bavail as u64 * s.f_frsize as u64)
}

#[cfg(not(unix))]
fn free_bytes(_: &Path) -> Option<u64> {
    None
}

fn parse_big_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT"))?;
    let p = |v: &str| v.trim().parse::<u32>().map_err(|_| format!("'{v}' is not a positive integer"));
    let (w, h) = (p(w)?, p(h)?);
    if w == 0 || h == 0 || w > hitex_io::gst::MAX_SOURCE_SIDE || h > hitex_io::gst::MAX_SOURCE_SIDE {
        return Err(format!("{w}x{h} is outside 1..={}", hitex_io::gst::MAX_SOURCE_SIDE));
    }
    Ok((w, h))
}

fn parse_shard(s: &str) -> Result<(u32, u32), String> {
    let (i, n) = s.split_once('/').ok_or_else(|| format!("'{s}' is not INDEX/COUNT"))?;
    let i: u32 = i.trim().parse().map_err(|_| format!("'{i}' is not an index"))?;
    let n: u32 = n.trim().parse().map_err(|_| format!("'{n}' is not a count"))?;
    if n == 0 || i >= n {
        return Err(format!("shard {i}/{n}: the index must be below the count"));
    }
    Ok((i, n))
}

/// `hitex terrain build`.
/// The store metadata of georeferenced imagery `img` described as `name`.
/// Imagery in longitude and latitude is refused: a store's texels are metric.
fn meta_for(
    img: &hitex_io::geotiff::GeoRaster,
    name: &str,
    path: &Path,
    mercator: bool,
) -> Result<StoreMeta, CliError> {
    if img.is_geographic() && !mercator {
        return Err(CliError::Input(format!(
            "{}: the imagery is in longitude and latitude ({}): a store needs it in a projected CRS; \
             build it with --profile mercator (reprojected to web mercator), reproject it first \
             (e.g. gdalwarp -t_srs EPSG:N), or use `terrain render`, which reprojects",
            path.display(),
            img.crs_name()
        )));
    }
    let crs = img.epsg.map_or_else(|| img.crs_name(), |e| format!("EPSG:{e}"));
    Ok(StoreMeta::for_source(img.width, img.height, img.origin, img.pixel, &crs, name))
}

/// The DEM a build keeps in its store: the user's file as it is, or a
/// reprojection of it written as a GeoTIFF.
enum StoredDem {
    Copy(PathBuf),
    Write(Box<(hitex_io::geotiff::GeoRaster, hitex_io::crs::Crs)>),
}

/// The DEM brought into `crs` (or, without one, into a metric CRS when it
/// is geographic), saying what was reprojected; with what to store: the
/// user's one file as it is, else the raster written as a GeoTIFF.
#[allow(clippy::type_complexity)]
fn dem_into(
    dem: crate::terrain_cmd::DemInput,
    crs: Option<&hitex_io::crs::Crs>,
) -> Result<(hitex_io::geotiff::GeoRaster, f64, StoredDem, String, Option<hitex_io::crs::Crs>), CliError> {
    let co = hitex_io::reproject::co_register(dem.raster, &dem.name, None, crs)?;
    for n in &co.notes {
        say!("{n}");
    }
    let name = co
        .crs
        .as_ref()
        .map_or_else(String::new, |c| c.epsg().map_or_else(|| c.definition().to_string(), |e| format!("EPSG:{e}")));
    let stored = match (&dem.file, &co.crs, co.notes.is_empty()) {
        (Some(f), _, true) => StoredDem::Copy(f.clone()),
        (_, Some(c), _) => StoredDem::Write(Box::new((co.dem.clone(), c.clone()))),
        (None, None, _) => {
            return Err(CliError::Input(format!(
                "{}: the mosaic's CRS cannot be resolved, so it cannot be stored as a GeoTIFF",
                dem.name.display()
            )));
        }
        (Some(f), None, false) => StoredDem::Copy(f.clone()),
    };
    Ok((co.dem, co.unit_metres, stored, name, co.crs))
}

/// A store's imagery from elevations alone: the DEM's shaded relief, at
/// least 1,024 texels on its longer side (up to 8 texels a post).
#[allow(clippy::type_complexity)]
fn relief_source(
    d: crate::terrain_cmd::DemInput,
) -> Result<(Box<dyn TileSource>, StoreMeta, StoredDem, Option<hitex_io::crs::Crs>), CliError> {
    let name = d.name.clone();
    let (mut dem, unit, stored, crs, crs_of) = dem_into(d, None)?;
    let filled = hitex_io::geotiff::fill_holes(&mut dem);
    if filled > 0 {
        say!("filled {filled} missing elevation samples from their neighbours");
    }
    let (w, h) = (dem.width, dem.height);
    let heights: Vec<f32> = (0..w as usize * h as usize).map(|i| dem.data[i * dem.bands]).collect();
    let k = 1024u32.div_ceil(w.max(h)).clamp(1, 8);
    let spacing = [dem.pixel[0] * unit, dem.pixel[1] * unit];
    let img = hitex_core::terrain::shaded_relief(&heights, w, h, spacing, k)
        .map_err(|e| CliError::Input(format!("{}: {e}", name.display())))?;
    let name = format!("{} (shaded relief, {k}×{k} texels a post)", name.display());
    let meta = StoreMeta::for_source(
        w * k,
        h * k,
        dem.origin,
        [dem.pixel[0] / k as f64, dem.pixel[1] / k as f64],
        &crs,
        &name,
    );
    let src = MemorySource { width: w * k, height: h * k, rgba: img.bytes().to_vec(), name };
    Ok((Box::new(src), meta, stored, crs_of))
}

pub fn build(a: BuildArgs) -> Result<(), CliError> {
    let mbtiles_name = a.output.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("mbtiles"));
    let format = a.format.unwrap_or(if mbtiles_name { FormatArg::Mbtiles } else { FormatArg::Folder });
    let profile =
        a.profile.unwrap_or(if format == FormatArg::Mbtiles { ProfileArg::Mercator } else { ProfileArg::Local });
    let mercator = profile == ProfileArg::Mercator;
    match format {
        FormatArg::Folder => crate::folder_output(&a.output, "terrain build (a tile store)")?,
        FormatArg::Mbtiles => {
            crate::file_output(&a.output, &["mbtiles"], "terrain build --format mbtiles (one SQLite file)")?;
            if !mercator {
                return Err(CliError::Input(
                    "--format mbtiles holds web-mercator tiles: use --profile mercator (the default for MBTiles)"
                        .into(),
                ));
            }
            if a.shard != (0, 1) {
                return Err(CliError::Input(format!(
                    "--shard {}/{}: shards build the folder form (--profile mercator -o FOLDER); \
                     pack the finished folder into one file with `hitex terrain pack FOLDER -o {}`",
                    a.shard.0,
                    a.shard.1,
                    a.output.display()
                )));
            }
        }
    }
    let t = Instant::now();
    let dem_in = if a.dem.is_empty() { None } else { Some(crate::terrain_cmd::load_dem_input(&a.dem)?) };
    let mut stored: Option<StoredDem> = None;
    type Crs = hitex_io::crs::Crs;
    let (source, meta, crs): (Box<dyn TileSource>, StoreMeta, Option<Crs>) = match (&a.image, a.procedural) {
        (Some(path), _) if hitex_io::geotiff::is_world_image(path) => {
            let Some(d) = dem_in else {
                return Err(CliError::Input(format!(
                    "{}: a world file names no CRS; give --dem so that the imagery takes the DEM's",
                    path.display()
                )));
            };
            let (img, rgb) = crate::terrain_cmd::world_imagery(path, &d.raster, &d.name)?;
            let name = format!("{} (world file)", path.display());
            let meta = meta_for(&img, &name, path, mercator)?;
            let crs = d.raster.crs().ok();
            stored = Some(dem_into(d, None)?.2);
            let src = MemorySource { width: img.width, height: img.height, rgba: rgb.bytes().to_vec(), name };
            (Box::new(src) as Box<dyn TileSource>, meta, crs)
        }
        (Some(path), _) => {
            // read by windows: memory stays bounded whatever the file's size
            let tiff = hitex_io::geotiff::GeoTiffWindows::open(path)?;
            let img = tiff.header.clone();
            if let Some(d) = dem_in {
                let name = d.name.clone();
                if d.raster.same_crs(&img) {
                    crate::terrain_cmd::check_coregistered(&d.raster, &img, &name, path)?;
                    stored = Some(dem_into(d, None)?.2);
                } else {
                    // the DEM moves into the imagery's CRS
                    let crs = img.crs().map_err(|m| {
                        CliError::Input(format!("{}: cannot reproject the DEM into it: {m}", path.display()))
                    })?;
                    let (dem, _, s, _, _) = dem_into(d, Some(&crs))?;
                    crate::terrain_cmd::check_coregistered(&dem, &img, &name, path)?;
                    stored = Some(s);
                }
            }
            let bands = crate::terrain_cmd::parse_bands(&a.bands, &img, path)?;
            let name = format!("{} bands {}", path.display(), a.bands);
            let meta = meta_for(&img, &name, path, mercator)?;
            let crs = img.crs().ok();
            (Box::new(GeoTiffSource::new(tiff, bands, name)?), meta, crs)
        }
        (None, Some((w, h))) => {
            let src = ProceduralSource { width: w, height: h, seed: 1 };
            let meta = StoreMeta::for_source(w, h, [0.0, 0.0], [1.0, 1.0], "", &src.describe());
            (Box::new(src), meta, None)
        }
        (None, None) => match dem_in {
            Some(d) => {
                let (src, meta, s, crs) = relief_source(d)?;
                stored = Some(s);
                (src, meta, crs)
            }
            None => {
                return Err(CliError::Input(
                    "give --image IMAGE.tif, --dem DEM alone, or --procedural WIDTHxHEIGHT".into(),
                ));
            }
        },
    };
    let (source, meta) = if mercator {
        let Some(from) = crs else {
            return Err(CliError::Input(if a.procedural.is_some() {
                "procedural imagery has no place on Earth: web-mercator tiles (--profile mercator, MBTiles) \
                 need imagery with a CRS"
                    .to_string()
            } else {
                format!(
                    "{}: its CRS ({}) cannot be resolved, so it cannot be placed on web-mercator tiles",
                    meta.source,
                    if meta.crs.is_empty() { "none" } else { &meta.crs }
                )
            }));
        };
        let inner = hitex_io::reproject::Grid {
            width: meta.width,
            height: meta.height,
            origin: meta.origin,
            pixel: meta.pixel,
        };
        let fail = |m: String| CliError::Input(format!("{}: {m}", meta.source));
        let (zoom, bounds) = hitex_io::reproject::mercator_zoom(&inner, &from).map_err(|e| fail(e.message))?;
        let merc = StoreMeta::mercator(bounds, zoom, &meta.source).map_err(|e| fail(e.message))?;
        let to = Crs::from_epsg(3857).map_err(|e| fail(e.to_string()))?;
        let grid = hitex_io::reproject::Grid {
            width: merc.width,
            height: merc.height,
            origin: merc.data_origin(),
            pixel: merc.pixel,
        };
        say!(
            "imagery reprojected from {} to web mercator (EPSG:3857): zoom {} to {}, {}x{} texels at zoom {zoom} ({:.2} m on the ground)",
            from.name(),
            merc.zoom(0),
            merc.zoom(merc.levels - 1),
            merc.width,
            merc.height,
            merc.ground_pixel()
        );
        if let Some(s) = stored.take() {
            stored = Some(dem_to_mercator(s, &to)?);
        }
        (
            Box::new(hitex_io::reproject::ReprojectedSource::new(source, inner, from, to, grid)) as Box<dyn TileSource>,
            merc,
        )
    } else {
        (source, meta)
    };
    check_build_size(&a, &meta, source.as_ref())?;
    if format == FormatArg::Mbtiles {
        return build_mbtiles_file(&a, source.as_ref(), &meta, stored, t);
    }
    // a store of another source is not overwritten map by map (the shards of
    // one build share theirs); a DEM left by an earlier build goes
    if let Ok(old) = hitex_io::gst::open_store(&a.output)
        && (old.width, old.height, &old.source, old.profile) != (meta.width, meta.height, &meta.source, meta.profile)
    {
        return Err(CliError::Input(format!(
            "{} holds a store of another source ({}, {}x{}): build into an empty folder, or remove it first",
            a.output.display(),
            old.source,
            old.width,
            old.height
        )));
    }
    // nor is a folder of other files made a store in passing
    if hitex_io::gst::open_store(&a.output).is_err()
        && let Ok(entries) = std::fs::read_dir(&a.output)
    {
        let store_like = |n: &str| {
            n == "metadata.json"
                || n == "tilemapresource.xml"
                || n.starts_with("dem.")
                || n.starts_with('.')
                || (!n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
        };
        let foreign: Vec<String> = entries
            .flatten()
            .filter_map(|e| e.file_name().to_str().map(str::to_string))
            .filter(|n| !store_like(n))
            .collect();
        if let Some(first) = foreign.first() {
            return Err(CliError::Input(format!(
                "{} holds other files ({first}{}), not a tile store: build into a new or empty folder",
                a.output.display(),
                if foreign.len() > 1 { format!(" and {} more", foreign.len() - 1) } else { String::new() }
            )));
        }
    }
    if stored.is_none()
        && let Some(old) = stored_dem(&a.output)
    {
        std::fs::remove_file(&old).map_err(|e| CliError::Input(format!("{}: {e}", old.display())))?;
        say!("removed {} (an earlier build's DEM; this build has none)", old.display());
    }
    let pb = build_progress(&meta);
    let report = build_store(source.as_ref(), &meta, &a.output, BuildOptions { shard: a.shard }, &|done, total| {
        pb.set_length(total);
        pb.set_position(done);
    })?;
    pb.finish_and_clear();
    if let Some(s) = stored {
        // one DEM in the store: an earlier build's of another format goes
        let (name, bytes) = dem_file(s)?;
        let target = a.output.join(name);
        if let Some(old) = stored_dem(&a.output)
            && old != target
        {
            std::fs::remove_file(&old).map_err(|e| CliError::Input(format!("{}: {e}", old.display())))?;
        }
        hitex_io::write_atomic(&target, &bytes)?;
    }
    say!(
        "{}: {} of {TILE}×{TILE} maps from {}; shard {}/{} wrote {} ({} left to other shards{}) in {:.1} s",
        a.output.display(),
        crate::count(report.levels as usize, "level", "levels"),
        meta.source,
        a.shard.0,
        a.shard.1,
        crate::count(report.written as usize, "map", "maps"),
        report.other_shards,
        if report.built_top { "; levels above the split built" } else { "" },
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `hitex terrain pack`: a web-mercator folder store into one MBTiles file.
pub fn pack(store: &Path, output: &Path) -> Result<(), CliError> {
    crate::file_output(output, &["mbtiles"], "terrain pack (one MBTiles file)")?;
    let t = Instant::now();
    let meta = open_store(store)?;
    let pb = build_progress(&meta);
    let n = hitex_io::mbtiles::pack_folder(store, output, &|done, total| {
        pb.set_length(total);
        pb.set_position(done);
    })?;
    pb.finish_and_clear();
    say!(
        "{}: MBTiles of {} (zoom {} to {}) packed from {} in {:.1} s",
        output.display(),
        crate::count(n as usize, "tile", "tiles"),
        meta.zoom(0),
        meta.zoom(meta.levels - 1),
        store.display(),
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

fn build_progress(meta: &StoreMeta) -> crate::progress::Progress {
    crate::progress::Progress::new(
        meta.total_tiles(),
        "build",
        "maps",
        "{prefix:>8} [{bar:30}] {pos}/{len} maps {elapsed} (eta {eta})",
    )
}

/// The name (`dem.EXT`) and bytes of the DEM a store keeps.
fn dem_file(s: StoredDem) -> Result<(String, Vec<u8>), CliError> {
    Ok(match s {
        StoredDem::Copy(d) => {
            let ext = d.extension().and_then(|e| e.to_str()).unwrap_or("tif").to_string();
            let bytes = std::fs::read(&d).map_err(|source| hitex_io::IoError::Read { path: d.clone(), source })?;
            (format!("dem.{ext}"), bytes)
        }
        StoredDem::Write(w) => {
            let bytes = hitex_io::geotiff::dem_geotiff_bytes(&w.0, &w.1)
                .map_err(|e| CliError::Input(format!("the DEM cannot be written as a GeoTIFF: {e}")))?;
            ("dem.tif".to_string(), bytes)
        }
    })
}

/// The DEM a web-mercator store keeps: reprojected onto EPSG:3857 (`to`).
fn dem_to_mercator(s: StoredDem, to: &hitex_io::crs::Crs) -> Result<StoredDem, CliError> {
    let (raster, crs, name) = match s {
        StoredDem::Copy(p) => {
            let r = crate::terrain_cmd::load_dem(&p)?;
            let c = r.crs().map_err(|m| CliError::Input(format!("{}: cannot reproject it: {m}", p.display())))?;
            (r, c, p.display().to_string())
        }
        StoredDem::Write(w) => {
            let (r, c) = *w;
            (r, c, "the DEM".to_string())
        }
    };
    if crs == *to {
        return Ok(StoredDem::Write(Box::new((raster, crs))));
    }
    let grid = hitex_io::reproject::covering_grid(&raster, &crs, to, hitex_io::geotiff::MAX_SAMPLES)
        .map_err(|m| CliError::Input(format!("{name}: {m}")))?;
    let r = hitex_io::reproject::reproject(&raster, &crs, to, &grid, Some(3857));
    say!("DEM reprojected from {} to web mercator (EPSG:3857): {}x{} posts", crs.name(), r.width, r.height);
    Ok(StoredDem::Write(Box::new((r, to.clone()))))
}

/// `terrain build --format mbtiles`: one SQLite file, written whole.
fn build_mbtiles_file(
    a: &BuildArgs,
    source: &dyn TileSource,
    meta: &StoreMeta,
    stored: Option<StoredDem>,
    t: Instant,
) -> Result<(), CliError> {
    if a.output.exists() {
        match hitex_io::gst::Store::open(&a.output) {
            Ok(old) if old.meta.source != meta.source => {
                return Err(CliError::Input(format!(
                    "{} holds a store of another source ({}): give another name, or remove it first",
                    a.output.display(),
                    old.meta.source
                )));
            }
            Ok(_) => {}
            Err(e) => return Err(CliError::Input(format!("{e}; hitex does not replace it"))),
        }
    }
    let files = stored.map(dem_file).transpose()?.into_iter().collect::<Vec<_>>();
    let pb = build_progress(meta);
    let report = hitex_io::mbtiles::build_mbtiles(source, meta, &a.output, &files, &|done, total| {
        pb.set_length(total);
        pb.set_position(done);
    })?;
    pb.finish_and_clear();
    say!(
        "{}: MBTiles of {} ({} of {TILE}×{TILE} maps, zoom {} to {}) from {}{} in {:.1} s",
        a.output.display(),
        crate::count(report.written as usize, "tile", "tiles"),
        crate::count(report.levels as usize, "level", "levels"),
        meta.zoom(0),
        meta.zoom(meta.levels - 1),
        meta.source,
        if files.is_empty() { String::new() } else { format!(", with its DEM ({})", files[0].0) },
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Arguments of `hitex terrain fly`.
#[derive(Args)]
pub struct FlyArgs {
    /// The store: a folder or an MBTiles file `hitex terrain build` wrote, or a raster MBTiles
    /// file made by another tool (its imagery over flat ground).
    pub store: PathBuf,
    /// Flight path TOML: `[[key]]` tables with t, x, y (fractions of the extent), altitude (m above
    /// the datum), pitch (degrees below the horizon), heading (degrees from north); default: an orbit.
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Frames to render.
    #[arg(long, default_value_t = 24)]
    pub frames: u32,
    /// Frame size.
    #[arg(long, value_parser = parse_size, default_value = "1024x768")]
    pub size: (u32, u32),
    /// Resident-map budget (the paper's setting needs 324).
    #[arg(long, default_value_t = 400)]
    pub budget: usize,
    /// Orbit altitude in metres above the datum (default: a tenth of the
    /// extent above the highest ground, exaggerated).
    #[arg(long, allow_negative_numbers = true)]
    pub altitude: Option<f64>,
    /// Orbit pitch below the horizon, degrees (90 looks straight down).
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub pitch: f64,
    /// Horizontal field of view, degrees.
    #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
    pub fov: f64,
    /// Render each frame only after its maps have loaded (deterministic frames).
    #[arg(long)]
    pub wait: bool,
    /// Output folder for frame PNGs.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Which renderer to use.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub backend: Backend,
    /// Ground: the store's DEM as a mesh (relief), flat ground (eq. (1)), or
    /// relief when the store holds a DEM (auto).
    #[arg(long, value_enum, default_value_t = GroundArg::Auto)]
    pub ground: GroundArg,
    /// Texture filter: per-pixel trilinear, 2×2 spans from 3×3 / 4×4 banks, or bicubic.
    #[arg(long, value_enum, default_value_t = FlySampler::Trilinear)]
    pub sampler: FlySampler,
    /// Heights × this over the relief.
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
    pub exaggeration: f64,
    /// No aircraft ahead of the camera (relief only).
    #[arg(long)]
    pub no_aircraft: bool,
    /// Record every span access in the bank model and report conflicts (CPU
    /// backend, span samplers); without it frames are only rendered.
    #[arg(long)]
    pub stats: bool,
}

/// What the flight draws under the sky.
#[derive(Clone, Copy, clap::ValueEnum, PartialEq, Eq, Debug)]
pub enum GroundArg {
    /// Relief when the store holds a DEM, else flat.
    Auto,
    /// Flat ground at height 0, solved per pixel.
    Flat,
    /// The store's DEM as a mesh.
    Relief,
}

/// The DEM a store holds beside its maps (`dem.*`, copied in by `terrain
/// build --dem`), placed on them, and where it came from; None without one.
pub fn open_relief(store: &Store, exaggeration: f64) -> Result<Option<(Relief, PathBuf)>, CliError> {
    let meta = &store.meta;
    let Some((path, bytes)) = store.dem()? else { return Ok(None) };
    if !(exaggeration.is_finite() && exaggeration >= 0.0) {
        return Err(CliError::Input(format!("--exaggeration {exaggeration} must be finite and ≥ 0")));
    }
    let mut dem = crate::terrain_cmd::parse_dem(&bytes, &path)?;
    let filled = hitex_io::geotiff::fill_holes(&mut dem);
    if filled == (dem.width as usize * dem.height as usize) {
        return Err(CliError::Input(format!("{}: every elevation sample is nodata", path.display())));
    }
    if meta.pixel[0] <= 0.0 || meta.pixel[1] <= 0.0 {
        return Err(CliError::Input(format!("{}: the store's texel size is not positive", store.path.display())));
    }
    let heights: Vec<f32> = (0..dem.width as usize * dem.height as usize).map(|i| dem.data[i * dem.bands]).collect();
    let relief = Relief::placed(
        heights,
        (dem.width as usize, dem.height as usize),
        dem.origin,
        dem.pixel,
        meta.origin,
        meta.pixel,
        exaggeration,
        meta.ground_pixel(),
    )
    .map_err(|e| CliError::Input(format!("{}: {e}", path.display())))?;
    Ok(Some((relief, path)))
}

/// A flight path file (`[[key]]` tables, see `hitex_core::terrain::path`).
fn load_path(path: &Path) -> Result<FlightPath, CliError> {
    let text = std::fs::read_to_string(path).map_err(|e| CliError::Input(format!("{}: {e}", path.display())))?;
    FlightPath::parse(&text).map_err(|e| CliError::Input(format!("{}: {e}", path.display())))
}

/// The resident-map cache of a store, loading its maps (files or MBTiles rows).
pub fn open_cache(store: Arc<Store>, budget: usize) -> Result<ResidentMaps, CliError> {
    let loader: Arc<hitex_core::residency::Loader> = Arc::new(move |k: MapKey| Ok(store.read_tile(k.z, k.x, k.y)?));
    ResidentMaps::new(budget, loader).map_err(|e| CliError::Input(e.to_string()))
}

/// Where a store's data lies, for the cameras of path keys and the active area.
pub fn flight_area(meta: &StoreMeta) -> FlightArea {
    FlightArea {
        levels: meta.levels,
        map_texels: TILE,
        offset: meta.offset,
        extent: [meta.width as f64, meta.height as f64],
        ground_pixel: meta.ground_pixel(),
    }
}

/// One frame's cache traffic, uniforms and page table
/// ([`prepare_frame`]), the cache's messages printed as warnings; with
/// `wait`, the time spent waiting for loads is moved out of the frame
/// (`start` advances).
#[allow(clippy::too_many_arguments)]
pub fn frame_setup(
    cache: &mut ResidentMaps,
    meta: &StoreMeta,
    cam: &FlyCamera,
    size: (u32, u32),
    fov: f64,
    per_side: u32,
    wait: bool,
    start: &mut Instant,
) -> (hitex_core::residency::FrameStats, FlyUniform, FlyPages) {
    let wait = wait.then_some(Duration::from_secs(30));
    let f = prepare_frame(cache, &flight_area(meta), |z| meta.data_range(z), cam, size, fov, per_side, wait);
    *start += f.waited;
    for line in f.warnings {
        eprintln!("hitex: warning: {line}");
    }
    (f.stats, f.uniform, f.pages)
}

/// Removes the frames (`frame-NNNN.png`) of an earlier flight into `dir`
/// that this one, of `frames` frames, does not overwrite, so that the
/// folder holds one flight; other files are left alone.
fn remove_stale_frames(dir: &Path, frames: u32) -> Result<(), CliError> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Ok(()) };
    let mut removed = 0usize;
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(n) = name.to_str().and_then(|n| n.strip_prefix("frame-")).and_then(|n| n.strip_suffix(".png")) else {
            continue;
        };
        if n.len() >= 4 && n.bytes().all(|b| b.is_ascii_digit()) && n.parse::<u64>().is_ok_and(|k| k >= frames as u64) {
            std::fs::remove_file(e.path()).map_err(|err| CliError::Input(format!("{}: {err}", e.path().display())))?;
            removed += 1;
        }
    }
    if removed > 0 {
        eprintln!(
            "hitex: note: {}: removed {} of an earlier, longer flight",
            dir.display(),
            crate::count(removed, "frame", "frames")
        );
    }
    Ok(())
}

/// `hitex terrain fly`.
pub fn fly(a: FlyArgs) -> Result<(), CliError> {
    crate::keep_going_on_closed_stdout();
    if a.frames == 0 || a.frames > 100_000 {
        return Err(CliError::Input(format!("--frames {} must be in 1 to 100000", a.frames)));
    }
    if a.budget == 0 {
        return Err(CliError::Input(
            "--budget 0: the cache must hold at least one map (the paper's setting holds 324)".into(),
        ));
    }
    crate::folder_output(&a.output, "terrain fly (one PNG per frame)")?;
    if !(a.fov.is_finite() && a.fov > 0.0 && a.fov < 180.0) {
        return Err(CliError::Input(format!("--fov {} must be in (0, 180) degrees", a.fov)));
    }
    let store = Arc::new(Store::open(&a.store)?);
    let meta = store.meta.clone();
    if store.is_foreign() {
        say!(
            "{}: {}: its imagery, zooms {} to {}, over flat ground",
            a.store.display(),
            meta.source,
            meta.zoom(0),
            meta.zoom(meta.levels - 1)
        );
    }
    hitex_io::create_output_dir(&a.output)?;
    remove_stale_frames(&a.output, a.frames)?;
    let (w, h) = a.size;
    let extent = DVec2::new(meta.width as f64, meta.height as f64);
    let metres = meta.ground_pixel();
    let relief = match a.ground {
        GroundArg::Flat => None,
        GroundArg::Auto => open_relief(&store, a.exaggeration)?,
        GroundArg::Relief => Some(open_relief(&store, a.exaggeration)?.ok_or_else(|| {
            CliError::Input(format!(
                "{} holds no DEM (dem.*): build it with --dem, or fly --ground flat",
                a.store.display()
            ))
        })?),
    };
    if a.no_aircraft && relief.is_none() {
        eprintln!(
            "hitex: warning: --no-aircraft: the aircraft flies over relief only; this flight is over flat ground"
        );
    }
    let relief = relief.map(|(mut r, path)| {
        r.aircraft = !a.no_aircraft;
        (r, path)
    });
    let keys = match &a.path {
        Some(p) => load_path(p)?,
        None => {
            // by default a tenth of the extent above the highest ground
            let top = relief.as_ref().map_or(0.0, |(r, _)| r.highest() * a.exaggeration);
            let alt = a.altitude.unwrap_or(top.max(0.0) + extent.x.max(extent.y) * metres / 10.0);
            if !(alt.is_finite() && alt > 0.0) {
                return Err(CliError::Input(format!("--altitude {alt}: the camera is below the ground")));
            }
            if !(a.pitch > 0.0 && a.pitch <= 90.0) {
                return Err(CliError::Input(format!(
                    "--pitch {}° must be in (0, 90] below the horizon (90 looks straight down)",
                    a.pitch
                )));
            }
            // an orbit round the centre, looking inwards
            let keys = (0..=16)
                .map(|i| {
                    let ang = i as f64 / 16.0 * std::f64::consts::TAU;
                    PathKey {
                        t: i as f64,
                        x: 0.5 - 0.3 * ang.sin(),
                        y: 0.5 + 0.3 * ang.cos(),
                        altitude: alt,
                        pitch: a.pitch,
                        heading: ang.to_degrees(),
                    }
                })
                .collect();
            FlightPath::new(keys).map_err(|e| CliError::Input(e.to_string()))?
        }
    };
    let per_side = hitex_core::terrain::active_area(a.fov, w, TILE, meta.levels.max(1))
        .map_err(|e| CliError::Input(e.to_string()))?
        .first()
        .map_or(6, |l| l.per_side);
    let sampler = a.sampler;
    let mut cache = open_cache(store.clone(), a.budget)?;
    let mut renderer = open_renderer(a.backend)?;
    let (t0, t1) = keys.span();
    let mut times = Vec::new();
    let mut peak = (0usize, 0usize);
    say!(
        "flying over {} ({}, {}x{} texels, {}) at {w}x{h}, {}, budget {}, {}:",
        a.store.display(),
        crate::count(meta.levels as usize, "level", "levels"),
        meta.width,
        meta.height,
        match &relief {
            Some((_, path)) => format!("relief from {} ×{}", path.display(), a.exaggeration),
            None => "flat ground".into(),
        },
        sampler.name(),
        crate::count(a.budget, "map", "maps"),
        renderer.name()
    );
    say!(
        "{:>6} {:>9} {:>7} {:>9} {:>9} {:>8} {:>7} {:>10} {:>10} {:>10}",
        "frame",
        "ms",
        "needed",
        "resident",
        "requested",
        "missing",
        "failed",
        "memory",
        "triangles",
        "conflicts"
    );
    let mut conflicts = (0u64, 0u64);
    for f in 0..a.frames.max(1) {
        // a path ends on its last key; an orbit is periodic (its last key is its first)
        let t = match (&a.path, a.frames) {
            (_, 0 | 1) => t0,
            (Some(_), n) => t0 + (t1 - t0) * f as f64 / (n - 1) as f64,
            (None, n) => t0 + (t1 - t0) * f as f64 / n as f64,
        };
        let k = keys.at(t);
        let mut start = Instant::now();
        let cam = flight_area(&meta).camera_at(&k, a.fov);
        if let Some((r, _)) = &relief {
            let ground = r.height_at(cam.eye[0], cam.eye[1]);
            if cam.eye[2] <= ground {
                return Err(CliError::Input(format!(
                    "frame {f}: the camera ({:.0} m) is below the ground ({:.0} m with the exaggeration)",
                    cam.eye[2] * metres,
                    ground * metres
                )));
            }
        }
        let (stats, u, pages) = frame_setup(&mut cache, &meta, &cam, (w, h), a.fov, per_side, a.wait, &mut start);
        let u = u.with_sampler(sampler);
        let mesh = relief
            .as_ref()
            .map(|(r, path)| r.mesh(&cam, w).map_err(|e| CliError::Input(format!("{}: {e}", path.display()))))
            .transpose()?;
        let ground = match (&relief, &mesh) {
            (Some((r, _)), Some(m)) => FlyGround::Mesh { mesh: m, generic: &r.generic },
            _ => FlyGround::Flat,
        };
        let hitex_render::Rendered { frame, banks } = renderer.render(
            &Job::Flight { uniform: u, pages: std::borrow::Cow::Borrowed(&pages), ground, stats: a.stats },
            u.sizes[0],
            u.sizes[1],
        )?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        times.push(ms);
        peak = (peak.0.max(stats.resident), peak.1.max(stats.bytes));
        save(&frame, &a.output.join(format!("frame-{f:04}.png")))?;
        if let Some(b) = &banks {
            conflicts = (conflicts.0 + b.conflicts, conflicts.1 + b.accesses);
        }
        say!(
            "{f:>6} {ms:>9.1} {:>7} {:>9} {:>9} {:>8} {:>7} {:>6.1} MiB {:>10} {:>10}",
            stats.needed,
            stats.resident,
            stats.requested,
            stats.missing,
            stats.failed,
            stats.bytes as f64 / 1048576.0,
            mesh.as_ref().map_or(0, |m| m.triangles()),
            banks.as_ref().map_or_else(|| "-".to_string(), |b| b.conflicts.to_string())
        );
    }
    if sampler != FlySampler::Trilinear {
        if conflicts.1 > 0 {
            say!("bank conflicts: {} in {} span accesses ({} banks)", conflicts.0, conflicts.1, sampler.banks().pow(2));
        } else if !a.stats {
            say!("bank conflicts: not recorded (--stats records them on the CPU backend)");
        } else {
            say!("bank conflicts: not modelled on {} (the CPU backend records them)", renderer.name());
        }
    }
    let med = crate::bench::median(&mut times);
    say!(
        "median {med:.1} ms per frame ({}); at most {} resident {} ({:.1} MiB), budget {}; frames in {}",
        renderer.name(),
        peak.0,
        if peak.0 == 1 { "map" } else { "maps" },
        peak.1 as f64 / 1048576.0,
        a.budget,
        a.output.display()
    );
    Ok(())
}
