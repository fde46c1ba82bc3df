//! Geospecific-texture (GST) pyramids on disk (seed 001): 256×256-texel
//! maps for levels 0 (coarsest: one map covers everything) to N−1 (the
//! source's own resolution), in the OSGeo TMS layout that GIS tools open —
//! `STORE/{z}/{x}/{y}.png` with y counted from the south, described by
//! `STORE/tilemapresource.xml` (GDAL's TMS/WMS driver reads it) — plus
//! `STORE/metadata.json` for hitex.
//!
//! Building works tile by tile with bounded memory: the finest level reads
//! 256×256 windows of the source, every coarser tile is the 2×2 box filter
//! (linear light, alpha-weighted) of its four children read back from disk,
//! so at most a few tiles per worker thread are in memory whatever the
//! source size. `shard = (i, n)` splits the work across processes by
//! quadtree subtrees; the few coarse levels above the split are built by
//! whichever shard finds the split level complete. Every file is written to
//! a temporary name and renamed.

use crate::IoError;
use crate::geotiff::GeoTiffWindows;
use crate::image_io::write_atomic;
use hitex_core::splitmix64 as hash;
use hitex_core::texture::image::decode_table;
use hitex_core::texture::{ColorSpace, linear_to_srgb_u8};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

mod meta;
mod sources;
#[cfg(test)]
mod tests;

pub use meta::*;
pub use sources::*;

/// Options of [`build_store`].
#[derive(Debug, Clone, Copy)]
pub struct BuildOptions {
    /// This process's share: (index, count), index in 0..count.
    pub shard: (u32, u32),
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self { shard: (0, 1) }
    }
}

/// What [`build_store`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BuildReport {
    /// Levels in the pyramid.
    pub levels: u32,
    /// Maps this shard wrote.
    pub written: u64,
    /// Maps left to other shards.
    pub other_shards: u64,
    /// Level at which the work was split between shards.
    pub split_level: u32,
    /// Whether this run also built the levels above the split.
    pub built_top: bool,
}

/// The shard owning map (x, y) of level `z ≥ split`.
fn owner(meta: &StoreMeta, split: u32, z: u32, x: u32, y: u32, n: u32) -> u32 {
    let k = z - split;
    let [x0, y0, x1, _] = meta.data_range(split);
    ((((y >> k) - y0) as u64 * (x1 - x0) as u64 + ((x >> k) - x0) as u64) % n as u64) as u32
}

/// Where a build puts its maps and reads them back: a folder of PNG files
/// ([`FolderSink`]) or one MBTiles file ([`crate::mbtiles::MbTiles`]).
pub trait TileSink: Sync {
    /// Stores the PNG file of map (x, y) of level `z`.
    fn put(&self, meta: &StoreMeta, z: u32, x: u32, y: u32, png: &[u8]) -> Result<(), IoError>;
    /// The RGBA8 texels of map (x, y) of level `z`, stored before.
    fn get(&self, meta: &StoreMeta, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError>;
    /// Whether map (x, y) of level `z` is stored.
    fn has(&self, meta: &StoreMeta, z: u32, x: u32, y: u32) -> bool;
}

/// The folder form of a store: `zoom/column/row.png` files (TMS rows).
pub struct FolderSink<'a>(pub &'a Path);

impl TileSink for FolderSink<'_> {
    fn put(&self, meta: &StoreMeta, z: u32, x: u32, y: u32, png: &[u8]) -> Result<(), IoError> {
        let path = meta.tile_path(self.0, z, x, y);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)
                .map_err(|e| IoError::Write { path: dir.to_path_buf(), message: e.to_string() })?;
        }
        write_atomic(&path, png)
    }
    fn get(&self, meta: &StoreMeta, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
        read_tile(meta, self.0, z, x, y)
    }
    fn has(&self, meta: &StoreMeta, z: u32, x: u32, y: u32) -> bool {
        meta.tile_path(self.0, z, x, y).exists()
    }
}

/// Builds the pyramid of `src` into the folder `out` (created if needed),
/// calling `progress(done, total)` as maps are written (from worker threads).
pub fn build_store(
    src: &dyn TileSource,
    meta: &StoreMeta,
    out: &Path,
    opts: BuildOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<BuildReport, IoError> {
    let werr = |p: &Path, m: String| IoError::Write { path: p.to_path_buf(), message: m };
    check_build(src, meta, opts)?;
    crate::image_io::create_output_dir(out)?;
    // the description is written last: a build that fails part-way leaves no store that opens as complete
    let described = out.join("metadata.json");
    match std::fs::remove_file(&described) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(werr(&described, e.to_string())),
        _ => {}
    }
    let json = serde_json::to_string_pretty(meta).map_err(|e| werr(out, e.to_string()))?;
    let report = build_into(src, meta, &FolderSink(out), opts, progress)?;
    write_atomic(&out.join("tilemapresource.xml"), meta.tms_xml().as_bytes())?;
    write_atomic(&described, json.as_bytes())?;
    Ok(report)
}

fn check_build(src: &dyn TileSource, meta: &StoreMeta, opts: BuildOptions) -> Result<(), IoError> {
    let (i, n) = opts.shard;
    if n == 0 || i >= n {
        return Err(IoError::Core(hitex_core::CoreError::OutOfRange {
            key: "shard".into(),
            message: format!("{i}/{n}: the index must be below the count"),
        }));
    }
    let (w, h) = src.size();
    if w == 0 || h == 0 || w > MAX_SOURCE_SIDE || h > MAX_SOURCE_SIDE || (w, h) != (meta.width, meta.height) {
        return Err(IoError::Core(hitex_core::CoreError::InvalidImage(format!(
            "source of {w}x{h} texels for a pyramid of {}x{} (sides 1..={MAX_SOURCE_SIDE})",
            meta.width, meta.height
        ))));
    }
    Ok(())
}

/// Builds this shard's maps of the pyramid of `src` into `sink` (and the
/// levels above the split when the split level is then complete).
pub fn build_into(
    src: &dyn TileSource,
    meta: &StoreMeta,
    sink: &dyn TileSink,
    opts: BuildOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<BuildReport, IoError> {
    check_build(src, meta, opts)?;
    let (i, n) = opts.shard;
    // split level: the coarsest with at least n maps
    let split = (0..meta.levels).find(|&z| meta.data_count(z) >= n as u64).unwrap_or(meta.levels - 1);
    let mine = |z: u32, x: u32, y: u32| owner(meta, split, z, x, y, n) == i;
    let mut report = BuildReport { levels: meta.levels, split_level: split, ..Default::default() };
    let total: u64 =
        (split..meta.levels).map(|z| meta.data_maps(z).filter(|&(x, y)| mine(z, x, y)).count() as u64).sum();
    report.other_shards = (split..meta.levels).map(|z| meta.data_count(z)).sum::<u64>() - total;
    let done = std::sync::atomic::AtomicU64::new(0);
    let tick = || progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, total);
    // finest level from the source, then each coarser level from its children
    for z in (split..meta.levels).rev() {
        build_level(src, meta, sink, z, &|x, y| mine(z, x, y), &tick)?;
        report.written += meta.data_maps(z).filter(|&(x, y)| mine(z, x, y)).count() as u64;
    }
    // the levels above the split, once every map of the split level exists
    let complete = meta.data_maps(split).all(|(x, y)| sink.has(meta, split, x, y));
    if complete && split > 0 {
        for z in (0..split).rev() {
            build_level(src, meta, sink, z, &|_, _| true, &|| {})?;
            report.written += meta.data_count(z);
        }
        report.built_top = true;
    }
    Ok(report)
}

fn build_level(
    src: &dyn TileSource,
    meta: &StoreMeta,
    sink: &dyn TileSink,
    z: u32,
    mine: &(dyn Fn(u32, u32) -> bool + Sync),
    tick: &(dyn Fn() + Sync),
) -> Result<(), IoError> {
    let finest = z == meta.levels - 1;
    let jobs: Vec<(u32, u32)> = meta.data_maps(z).filter(|&(x, y)| mine(x, y)).collect();
    jobs.par_iter().try_for_each(|&(x, y)| -> Result<(), IoError> {
        let rgba = if finest { finest_tile(src, meta.offset, x, y)? } else { parent_tile(meta, sink, z, x, y)? };
        let png = encode_png(&rgba)
            .map_err(|e| IoError::Write { path: meta.tile_path(Path::new(""), z, x, y), message: e.message })?;
        sink.put(meta, z, x, y, &png)?;
        tick();
        Ok(())
    })
}

/// The PNG file of a map's RGBA8 texels.
pub fn encode_png(rgba: &[u8]) -> Result<Vec<u8>, crate::DataError> {
    use image::ImageEncoder;
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new(&mut buf)
        .write_image(rgba, TILE, TILE, image::ExtendedColorType::Rgba8)
        .map_err(|e| crate::DataError::from(e.to_string()))?;
    Ok(buf)
}

/// The PNG size of the finest map at the source's centre: a sample for
/// estimating a whole store's disk need before building it.
pub fn sample_map_bytes(src: &dyn TileSource) -> Result<u64, IoError> {
    let (w, h) = src.size();
    let rgba = finest_tile(src, [0, 0], (w / 2) / TILE, (h / 2) / TILE)?;
    let buf = encode_png(&rgba)
        .map_err(|e| IoError::Core(hitex_core::CoreError::InvalidImage(format!("{}: {e}", src.describe()))))?;
    Ok(buf.len() as u64)
}

/// Map (x, y) of the finest level of a grid whose data starts `offset`
/// texels from its corner: the source window, transparent outside.
fn finest_tile(src: &dyn TileSource, offset: [u32; 2], x: u32, y: u32) -> Result<Vec<u8>, IoError> {
    let (w, h) = src.size();
    let mut out = vec![0u8; (TILE * TILE * 4) as usize];
    // the map's texels in the source's coordinates
    let (dx, dy) = (x as i64 * TILE as i64 - offset[0] as i64, y as i64 * TILE as i64 - offset[1] as i64);
    let (a0, a1) = (dx.max(0), (dx + TILE as i64).min(w as i64));
    let (b0, b1) = (dy.max(0), (dy + TILE as i64).min(h as i64));
    if a1 <= a0 || b1 <= b0 {
        return Ok(out);
    }
    let (cw, ch) = ((a1 - a0) as u32, (b1 - b0) as u32);
    let window = src.read(a0 as u32, b0 as u32, cw, ch)?;
    if window.len() != (cw * ch * 4) as usize {
        return Err(IoError::Core(hitex_core::CoreError::InvalidImage(format!(
            "{}: window of {cw}x{ch} returned {} bytes",
            src.describe(),
            window.len()
        ))));
    }
    let (px, py) = ((a0 - dx) as usize, (b0 - dy) as usize);
    for row in 0..ch as usize {
        let d = ((py + row) * TILE as usize + px) * 4;
        let s = row * cw as usize * 4;
        out[d..d + cw as usize * 4].copy_from_slice(&window[s..s + cw as usize * 4]);
    }
    Ok(out)
}

/// Reads a map of the store as RGBA8, checking its size.
pub fn read_tile(meta: &StoreMeta, root: &Path, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
    let path = meta.tile_path(root, z, x, y);
    let len = std::fs::metadata(&path).map_err(|source| IoError::Read { path: path.clone(), source })?.len();
    if len > MAX_TILE_FILE_BYTES {
        let message =
            format!("map file of {len} bytes; a {TILE}x{TILE} map never needs more than {MAX_TILE_FILE_BYTES}");
        return Err(IoError::Format { path, message });
    }
    let bytes = std::fs::read(&path).map_err(|source| IoError::Read { path: path.clone(), source })?;
    decode_tile(&bytes, &path)
}

/// Largest map file accepted (a 256×256 RGBA PNG stored without compression
/// is 263 KiB).
pub const MAX_TILE_FILE_BYTES: u64 = 4 << 20;

/// Decodes one map file held in memory as RGBA8, checking its size; `path`
/// is the file named in errors.
pub fn decode_tile(bytes: &[u8], path: &Path) -> Result<Vec<u8>, IoError> {
    let path = path.to_path_buf();
    let img = crate::decode_image(bytes, &path, ColorSpace::Srgb)?;
    if img.width() != TILE || img.height() != TILE {
        return Err(IoError::Format {
            path,
            message: format!("map of {}x{} texels; the store's maps are {TILE}x{TILE}", img.width(), img.height()),
        });
    }
    Ok(img.bytes().to_vec())
}

/// Map (x, y) of level z: the 2×2 box filter of its children at z + 1, in
/// linear light, weighted by alpha; children outside the data are empty.
pub(crate) fn parent_tile(meta: &StoreMeta, sink: &dyn TileSink, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
    let [c0, r0, c1, r1] = meta.data_range(z + 1);
    let lut = decode_table(ColorSpace::Srgb);
    let mut out = vec![0u8; (TILE * TILE * 4) as usize];
    for (dx, dy) in [(0u32, 0u32), (1, 0), (0, 1), (1, 1)] {
        let (kx, ky) = (2 * x + dx, 2 * y + dy);
        if kx < c0 || ky < r0 || kx >= c1 || ky >= r1 {
            continue;
        }
        let child = sink.get(meta, z + 1, kx, ky)?;
        let half = TILE / 2;
        for py in 0..half {
            for px in 0..half {
                let mut acc = [0.0f32; 4];
                for (sx, sy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let i = (((2 * py + sy) * TILE + 2 * px + sx) * 4) as usize;
                    let a = child[i + 3] as f32 / 255.0;
                    for k in 0..3 {
                        acc[k] += lut[child[i + k] as usize] * a;
                    }
                    acc[3] += a;
                }
                let o = (((dy * half + py) * TILE + dx * half + px) * 4) as usize;
                if acc[3] > 0.0 {
                    for k in 0..3 {
                        out[o + k] = linear_to_srgb_u8(acc[k] / acc[3]);
                    }
                    out[o + 3] = (acc[3] / 4.0 * 255.0).round() as u8;
                }
            }
        }
    }
    Ok(out)
}

/// A store open for reading: the folder form or one MBTiles file.
pub struct Store {
    /// Its description.
    pub meta: StoreMeta,
    /// The folder or file.
    pub path: PathBuf,
    mbtiles: Option<crate::mbtiles::MbTiles>,
}

impl Store {
    /// Opens the store at `path`: a folder `hitex terrain build` made, or an
    /// MBTiles file it wrote.
    pub fn open(path: &Path) -> Result<Store, IoError> {
        let named = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("mbtiles"));
        if named && path.is_file() {
            let (db, meta) = crate::mbtiles::MbTiles::open(path)?;
            return Ok(Store { meta, path: path.to_path_buf(), mbtiles: Some(db) });
        }
        if path.is_file() {
            use std::io::Read;
            let mut head = [0u8; 16];
            let n = std::fs::File::open(path)
                .and_then(|mut f| f.read(&mut head))
                .map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
            if crate::mbtiles::is_sqlite(&head[..n]) {
                let (db, meta) = crate::mbtiles::MbTiles::open(path)?;
                return Ok(Store { meta, path: path.to_path_buf(), mbtiles: Some(db) });
            }
        }
        Ok(Store { meta: open_store(path)?, path: path.to_path_buf(), mbtiles: None })
    }

    /// Whether it is one MBTiles file.
    pub fn is_mbtiles(&self) -> bool {
        self.mbtiles.is_some()
    }

    /// Whether it is an MBTiles file made by another tool (imagery only;
    /// see [`crate::mbtiles`]).
    pub fn is_foreign(&self) -> bool {
        self.mbtiles.as_ref().is_some_and(|m| m.is_foreign())
    }

    /// Map (x, y-from-north) of level `z` as RGBA8, its size checked.
    pub fn read_tile(&self, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
        match &self.mbtiles {
            Some(db) => db.read_map(&self.meta, z, x, y),
            None => read_tile(&self.meta, &self.path, z, x, y),
        }
    }

    /// The elevation model stored with the maps, if any: its name (a path
    /// for errors, its extension the format) and bytes.
    pub fn dem(&self) -> Result<Option<(PathBuf, Vec<u8>)>, IoError> {
        match &self.mbtiles {
            Some(db) => {
                let Some(name) = db.file_names()?.into_iter().find(|n| n.starts_with("dem.")) else { return Ok(None) };
                Ok(db.file(&name)?.map(|b| (self.path.join(name), b)))
            }
            None => {
                let Some(p) = stored_dem(&self.path) else { return Ok(None) };
                let len = std::fs::metadata(&p).map_err(|source| IoError::Read { path: p.clone(), source })?.len();
                if len > crate::mbtiles::MAX_STORED_FILE_BYTES {
                    return Err(IoError::Format {
                        path: p,
                        message: format!("file of {len} bytes is beyond the size limit"),
                    });
                }
                let bytes = std::fs::read(&p).map_err(|source| IoError::Read { path: p.clone(), source })?;
                Ok(Some((p, bytes)))
            }
        }
    }
}

/// The elevation model a folder store holds beside its maps (`dem.*`).
pub fn stored_dem(store: &Path) -> Option<PathBuf> {
    let entries = std::fs::read_dir(store).ok()?;
    let mut found: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.file_stem().is_some_and(|s| s == "dem") && p.is_file())
        .collect();
    found.sort();
    found.into_iter().next()
}

/// Opens a store: reads and checks `metadata.json`.
pub fn open_store(root: &Path) -> Result<StoreMeta, IoError> {
    if root.is_file() {
        return Err(IoError::Format {
            path: root.to_path_buf(),
            message: "a file, not a tile store (the folder `hitex terrain build -o` makes)".into(),
        });
    }
    let path = root.join("metadata.json");
    let text = std::fs::read_to_string(&path).map_err(|source| IoError::Read { path: path.clone(), source })?;
    parse_store_meta(&text, &path)
}
