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

/// Side of a map in texels.
pub const TILE: u32 = 256;

/// Largest source side accepted (2²⁴ texels: 65,536 maps across).
pub const MAX_SOURCE_SIDE: u32 = 1 << 24;

/// Imagery the pyramid is built from: any size, read by windows.
pub trait TileSource: Sync {
    /// Width and height in texels.
    fn size(&self) -> (u32, u32);
    /// RGBA8 texels (sRGB, rows north to south) of the window at (x0, y0)
    /// of `w`×`h` texels, inside the source.
    fn read(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<Vec<u8>, IoError>;
    /// One line describing the source.
    fn describe(&self) -> String;
}

/// A source held in memory (decoded imagery).
pub struct MemorySource {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// RGBA8 texels.
    pub rgba: Vec<u8>,
    /// What it is.
    pub name: String,
}

impl TileSource for MemorySource {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    fn read(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<Vec<u8>, IoError> {
        let mut out = Vec::with_capacity((w * h * 4) as usize);
        for y in y0..y0 + h {
            let i = ((y * self.width + x0) * 4) as usize;
            out.extend_from_slice(&self.rgba[i..i + (w * 4) as usize]);
        }
        Ok(out)
    }
    fn describe(&self) -> String {
        format!("{} ({}x{} texels in memory)", self.name, self.width, self.height)
    }
}

/// Synthetic aerial-like imagery of any size, generated on the fly (fields,
/// roads, towns at several scales): for testing that memory and time do not
/// grow with the source.
pub struct ProceduralSource {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Seed.
    pub seed: u64,
}

impl ProceduralSource {
    /// The texel at (x, y).
    pub fn texel(&self, x: u32, y: u32) -> [u8; 4] {
        // fields: 512-texel parcels with a crop colour, furrows, roads between them
        let (px, py) = (x / 512, y / 512);
        let h = hash(self.seed ^ ((px as u64) << 32 | py as u64));
        let (fx, fy) = (x % 512, y % 512);
        if fx < 6 || fy < 6 {
            return [150, 146, 138, 255];
        }
        let crops = [[92u8, 120, 60], [150, 140, 80], [70, 100, 50], [120, 95, 60], [60, 85, 45]];
        let c = crops[(h % 5) as usize];
        let furrow = if (h >> 8) & 1 == 0 { x } else { y };
        let stripe = if (furrow / 4).is_multiple_of(2) { 0 } else { 12 };
        let n = (hash(self.seed ^ ((x as u64) << 32 | y as u64)) & 15) as u8;
        let town =
            (h >> 16).is_multiple_of(9) && !(fx / 32 + fy / 32).is_multiple_of(3) && (fx % 32) > 4 && (fy % 32) > 4;
        if town {
            return [170u8.saturating_sub(n), 160u8.saturating_sub(n), 150, 255];
        }
        [c[0].saturating_sub(stripe) + n / 2, c[1].saturating_sub(stripe) + n / 2, c[2].saturating_sub(stripe), 255]
    }
}

impl TileSource for ProceduralSource {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    fn read(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<Vec<u8>, IoError> {
        let mut out = Vec::with_capacity((w * h * 4) as usize);
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                out.extend_from_slice(&self.texel(x, y));
            }
        }
        Ok(out)
    }
    fn describe(&self) -> String {
        format!("procedural imagery, {}x{} texels generated on the fly", self.width, self.height)
    }
}

/// Imagery from a GeoTIFF read by windows ([`GeoTiffWindows`]): three bands
/// contrast-stretched to RGB, with memory bounded by the windows and the
/// decoder's chunk cache, whatever the file's size.
pub struct GeoTiffSource {
    /// The file.
    pub tiff: GeoTiffWindows,
    /// Bands as red, green, blue (0-based).
    pub bands: [usize; 3],
    /// Per output channel, the sample range stretched to 0..255.
    pub range: [(f32, f32); 3],
    /// What it is.
    pub name: String,
}

/// Samples per band the stretch looks at, at most.
pub const STRETCH_SAMPLES: u64 = 1 << 20;

impl GeoTiffSource {
    /// Opens the bands of `tiff`, measuring each band's 2–98 % range from
    /// an even lattice of at most [`STRETCH_SAMPLES`] pixels (all of them
    /// below that), read window by window.
    pub fn new(tiff: GeoTiffWindows, bands: [usize; 3], name: String) -> Result<Self, IoError> {
        let r = &tiff.header;
        let fmt = |m: String| IoError::Format { path: name.clone().into(), message: m };
        if let Some(&b) = bands.iter().find(|&&b| b >= r.bands) {
            return Err(fmt(format!("band {} requested of {}", b + 1, r.bands)));
        }
        let pixels = r.width as u64 * r.height as u64;
        let step = pixels.div_ceil(STRETCH_SAMPLES).max(1);
        let mut picked: [Vec<f32>; 3] = Default::default();
        let win = 1024u32;
        for y0 in (0..r.height).step_by(win as usize) {
            for x0 in (0..r.width).step_by(win as usize) {
                let (w, h) = (win.min(r.width - x0), win.min(r.height - y0));
                let data = tiff.window(x0, y0, w, h)?;
                for y in 0..h {
                    for x in 0..w {
                        let g = (y0 + y) as u64 * r.width as u64 + (x0 + x) as u64;
                        if g.is_multiple_of(step) {
                            let o = (y as usize * w as usize + x as usize) * r.bands;
                            for (k, &b) in bands.iter().enumerate() {
                                picked[k].push(data[o + b]);
                            }
                        }
                    }
                }
            }
        }
        let mut range = [(0.0, 1.0); 3];
        for k in 0..3 {
            range[k] = crate::geotiff::stretch_range(std::mem::take(&mut picked[k]).into_iter())
                .ok_or_else(|| fmt(format!("band {} has no finite samples", bands[k] + 1)))?;
        }
        Ok(Self { tiff, bands, range, name })
    }
}

impl TileSource for GeoTiffSource {
    fn size(&self) -> (u32, u32) {
        (self.tiff.header.width, self.tiff.header.height)
    }
    fn read(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<Vec<u8>, IoError> {
        let b = self.tiff.header.bands;
        let data = self.tiff.window(x0, y0, w, h)?;
        let mut out = Vec::with_capacity(w as usize * h as usize * 4);
        for px in data.chunks_exact(b) {
            for k in 0..3 {
                let (lo, hi) = self.range[k];
                out.push(((px[self.bands[k]] - lo) / (hi - lo) * 255.0).clamp(0.0, 255.0) as u8);
            }
            out.push(255);
        }
        Ok(out)
    }
    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// What `metadata.json` says about a store.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoreMeta {
    /// Always "hitex-gst".
    pub format: String,
    /// Format version (1).
    pub version: u32,
    /// Map side in texels.
    pub tile_size: u32,
    /// Source width in texels (finest level).
    pub width: u32,
    /// Source height in texels.
    pub height: u32,
    /// Number of levels; level `levels − 1` is the source's resolution.
    pub levels: u32,
    /// World coordinates of the source's north-west corner.
    pub origin: [f64; 2],
    /// World units per texel at the finest level (x, y).
    pub pixel: [f64; 2],
    /// Coordinate reference system, e.g. "EPSG:31985" (empty: unknown).
    pub crs: String,
    /// Where the imagery came from.
    pub source: String,
}

impl StoreMeta {
    /// The metadata of a pyramid over a `width`×`height` source.
    pub fn for_source(width: u32, height: u32, origin: [f64; 2], pixel: [f64; 2], crs: &str, source: &str) -> Self {
        let maps = width.div_ceil(TILE).max(height.div_ceil(TILE)).max(1);
        let levels = 1 + maps.next_power_of_two().trailing_zeros();
        Self {
            format: "hitex-gst".into(),
            version: 1,
            tile_size: TILE,
            width,
            height,
            levels,
            origin,
            pixel,
            crs: crs.into(),
            source: source.into(),
        }
    }

    /// Finest-level texels per texel of level `z`.
    pub fn scale(&self, z: u32) -> u64 {
        1u64 << (self.levels - 1 - z.min(self.levels - 1))
    }

    /// Maps holding data at level `z` (columns, rows from the north).
    pub fn data_tiles(&self, z: u32) -> (u32, u32) {
        let span = TILE as u64 * self.scale(z);
        ((self.width as u64).div_ceil(span) as u32, (self.height as u64).div_ceil(span) as u32)
    }

    /// The TMS file of map (x, y-from-north) at level `z`: `z/x/y_south.png`.
    pub fn tile_path(&self, root: &Path, z: u32, x: u32, y: u32) -> PathBuf {
        let y_tms = (1u32 << z) - 1 - y;
        root.join(z.to_string()).join(x.to_string()).join(format!("{y_tms}.png"))
    }

    /// Bytes of all maps of all levels (RGBA8).
    pub fn total_tiles(&self) -> u64 {
        (0..self.levels).map(|z| self.data_tiles(z)).map(|(c, r)| c as u64 * r as u64).sum()
    }

    /// `tilemapresource.xml` (OSGeo TMS 1.0.0), the pyramid anchored at the
    /// source's north-west corner and padded to 2^z maps per side.
    pub fn tms_xml(&self) -> String {
        let side = TILE as f64 * (1u64 << (self.levels - 1)) as f64;
        let (minx, maxy) = (self.origin[0], self.origin[1]);
        let (maxx, miny) = (minx + side * self.pixel[0], maxy - side * self.pixel[1]);
        let mut s = String::from("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
        s += "<TileMap version=\"1.0.0\" tilemapservice=\"http://tms.osgeo.org/1.0.0\">\n";
        s += "  <Title>hitex geospecific texture pyramid</Title>\n";
        s += &format!("  <Abstract>{}</Abstract>\n", xml_escape(&self.source));
        s += &format!("  <SRS>{}</SRS>\n", xml_escape(&self.crs));
        s += &format!("  <BoundingBox minx=\"{minx}\" miny=\"{miny}\" maxx=\"{maxx}\" maxy=\"{maxy}\"/>\n");
        s += &format!("  <Origin x=\"{minx}\" y=\"{miny}\"/>\n");
        s += &format!("  <TileFormat width=\"{TILE}\" height=\"{TILE}\" mime-type=\"image/png\" extension=\"png\"/>\n");
        s += "  <TileSets profile=\"none\">\n";
        for z in 0..self.levels {
            let upp = self.pixel[0] * self.scale(z) as f64;
            s += &format!("    <TileSet href=\"{z}\" units-per-pixel=\"{upp}\" order=\"{z}\"/>\n");
        }
        s += "  </TileSets>\n</TileMap>\n";
        s
    }
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

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
    let (cols, _) = meta.data_tiles(split);
    (((y >> k) as u64 * cols as u64 + (x >> k) as u64) % n as u64) as u32
}

/// Builds the pyramid of `src` into `out` (created if needed), calling
/// `progress(done, total)` as maps are written (from worker threads).
pub fn build_store(
    src: &dyn TileSource,
    meta: &StoreMeta,
    out: &Path,
    opts: BuildOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<BuildReport, IoError> {
    let (i, n) = opts.shard;
    let werr = |p: &Path, m: String| IoError::Write { path: p.to_path_buf(), message: m };
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
    crate::image_io::create_output_dir(out)?;
    // the description is written last: a build that fails part-way leaves no store that opens as complete
    let described = out.join("metadata.json");
    match std::fs::remove_file(&described) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(werr(&described, e.to_string())),
        _ => {}
    }
    let json = serde_json::to_string_pretty(meta).map_err(|e| werr(out, e.to_string()))?;
    // split level: the coarsest with at least n maps
    let split = (0..meta.levels)
        .find(|&z| {
            let (c, r) = meta.data_tiles(z);
            c as u64 * r as u64 >= n as u64
        })
        .unwrap_or(meta.levels - 1);
    let mine = |z: u32, x: u32, y: u32| owner(meta, split, z, x, y, n) == i;
    let mut report = BuildReport { levels: meta.levels, split_level: split, ..Default::default() };
    let total: u64 = (split..meta.levels)
        .map(|z| {
            let (c, r) = meta.data_tiles(z);
            (0..r).flat_map(|y| (0..c).map(move |x| (x, y))).filter(|&(x, y)| mine(z, x, y)).count() as u64
        })
        .sum();
    report.other_shards = (split..meta.levels)
        .map(|z| {
            let (c, r) = meta.data_tiles(z);
            c as u64 * r as u64
        })
        .sum::<u64>()
        - total;
    let done = std::sync::atomic::AtomicU64::new(0);
    let tick = || progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, total);
    // finest level from the source, then each coarser level from its children
    for z in (split..meta.levels).rev() {
        build_level(src, meta, out, z, &|x, y| mine(z, x, y), &tick)?;
        let (c, r) = meta.data_tiles(z);
        report.written +=
            (0..r).flat_map(|y| (0..c).map(move |x| (x, y))).filter(|&(x, y)| mine(z, x, y)).count() as u64;
    }
    // the levels above the split, once every map of the split level exists
    let (c, r) = meta.data_tiles(split);
    let complete = (0..r).all(|y| (0..c).all(|x| meta.tile_path(out, split, x, y).exists()));
    if complete && split > 0 {
        for z in (0..split).rev() {
            build_level(src, meta, out, z, &|_, _| true, &|| {})?;
            let (c, r) = meta.data_tiles(z);
            report.written += c as u64 * r as u64;
        }
        report.built_top = true;
    }
    write_atomic(&out.join("tilemapresource.xml"), meta.tms_xml().as_bytes())?;
    write_atomic(&described, json.as_bytes())?;
    Ok(report)
}

fn build_level(
    src: &dyn TileSource,
    meta: &StoreMeta,
    out: &Path,
    z: u32,
    mine: &(dyn Fn(u32, u32) -> bool + Sync),
    tick: &(dyn Fn() + Sync),
) -> Result<(), IoError> {
    let (cols, rows) = meta.data_tiles(z);
    let finest = z == meta.levels - 1;
    let jobs: Vec<(u32, u32)> =
        (0..rows).flat_map(|y| (0..cols).map(move |x| (x, y))).filter(|&(x, y)| mine(x, y)).collect();
    jobs.par_iter().try_for_each(|&(x, y)| -> Result<(), IoError> {
        let rgba = if finest { finest_tile(src, x, y)? } else { parent_tile(meta, out, z, x, y)? };
        let path = meta.tile_path(out, z, x, y);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)
                .map_err(|e| IoError::Write { path: dir.to_path_buf(), message: e.to_string() })?;
        }
        crate::save_png(&path, TILE, TILE, &rgba)?;
        tick();
        Ok(())
    })
}

/// Map (x, y) of the finest level: the source window, transparent outside.
/// The PNG size of the finest map at the source's centre: a sample for
/// estimating a whole store's disk need before building it.
pub fn sample_map_bytes(src: &dyn TileSource) -> Result<u64, IoError> {
    let (w, h) = src.size();
    let rgba = finest_tile(src, (w / 2) / TILE, (h / 2) / TILE)?;
    let mut buf = Vec::new();
    {
        use image::ImageEncoder;
        image::codecs::png::PngEncoder::new(&mut buf)
            .write_image(&rgba, TILE, TILE, image::ExtendedColorType::Rgba8)
            .map_err(|e| IoError::Core(hitex_core::CoreError::InvalidImage(format!("{}: {e}", src.describe()))))?;
    }
    Ok(buf.len() as u64)
}

fn finest_tile(src: &dyn TileSource, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
    let (w, h) = src.size();
    let (x0, y0) = (x * TILE, y * TILE);
    let (cw, ch) = (TILE.min(w - x0), TILE.min(h - y0));
    let window = src.read(x0, y0, cw, ch)?;
    if window.len() != (cw * ch * 4) as usize {
        return Err(IoError::Core(hitex_core::CoreError::InvalidImage(format!(
            "{}: window of {cw}x{ch} returned {} bytes",
            src.describe(),
            window.len()
        ))));
    }
    let mut out = vec![0u8; (TILE * TILE * 4) as usize];
    for row in 0..ch {
        let d = (row * TILE * 4) as usize;
        let s = (row * cw * 4) as usize;
        out[d..d + (cw * 4) as usize].copy_from_slice(&window[s..s + (cw * 4) as usize]);
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
fn parent_tile(meta: &StoreMeta, root: &Path, z: u32, x: u32, y: u32) -> Result<Vec<u8>, IoError> {
    let (cc, cr) = meta.data_tiles(z + 1);
    let lut = decode_table(ColorSpace::Srgb);
    let mut out = vec![0u8; (TILE * TILE * 4) as usize];
    for (dx, dy) in [(0u32, 0u32), (1, 0), (0, 1), (1, 1)] {
        let (kx, ky) = (2 * x + dx, 2 * y + dy);
        if kx >= cc || ky >= cr {
            continue;
        }
        let child = read_tile(meta, root, z + 1, kx, ky)?;
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

/// Parses and checks a store's `metadata.json` held in memory; `path` is the
/// file named in errors.
pub fn parse_store_meta(text: &str, path: &Path) -> Result<StoreMeta, IoError> {
    let path = path.to_path_buf();
    let meta: StoreMeta =
        serde_json::from_str(text).map_err(|e| IoError::Format { path: path.clone(), message: e.to_string() })?;
    let bad = |m: String| Err(IoError::Format { path: path.clone(), message: m });
    if meta.format != "hitex-gst" || meta.version != 1 {
        return bad(format!("format '{}' version {}: not a hitex GST store (version 1)", meta.format, meta.version));
    }
    if meta.tile_size != TILE {
        return bad(format!("maps of {} texels; hitex builds {TILE}", meta.tile_size));
    }
    if meta.width == 0 || meta.height == 0 || meta.width > MAX_SOURCE_SIDE || meta.height > MAX_SOURCE_SIDE {
        return bad(format!("source of {}x{} texels", meta.width, meta.height));
    }
    let want = StoreMeta::for_source(meta.width, meta.height, meta.origin, meta.pixel, "", "").levels;
    if meta.levels != want {
        return bad(format!("{} levels; a {}x{} source has {want}", meta.levels, meta.width, meta.height));
    }
    if !meta.origin.iter().chain(meta.pixel.iter()).all(|v| v.is_finite()) || meta.pixel.iter().any(|&p| p <= 0.0) {
        return bad("origin and pixel size must be finite, pixel sizes positive".into());
    }
    Ok(meta)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("hitex-gst-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn geometry_of_a_pyramid() {
        let m = StoreMeta::for_source(1000, 600, [0.0, 0.0], [1.0, 1.0], "", "");
        assert_eq!(m.levels, 3); // 4×3 maps → 4 per side → levels 0..2
        assert_eq!(m.data_tiles(2), (4, 3));
        assert_eq!(m.data_tiles(1), (2, 2));
        assert_eq!(m.data_tiles(0), (1, 1));
        assert_eq!(m.total_tiles(), 12 + 4 + 1);
        // TMS rows count from the south of the padded 2^z grid
        assert!(m.tile_path(Path::new("s"), 2, 1, 0).ends_with("2/1/3.png"));
        assert!(m.tms_xml().contains("<TileSet href=\"0\" units-per-pixel=\"4\""));
    }

    #[test]
    fn build_read_and_shards_agree() {
        let src = ProceduralSource { width: 700, height: 520, seed: 3 };
        let meta = StoreMeta::for_source(700, 520, [500_000.0, 9_100_000.0], [2.0, 2.0], "EPSG:31985", "test");
        let one = tmp("one");
        let r = build_store(&src, &meta, &one, BuildOptions::default(), &|_, _| {}).unwrap();
        assert_eq!(r.written, meta.total_tiles());
        assert_eq!(open_store(&one).unwrap(), meta);
        // a finest map equals the source window
        let t = read_tile(&meta, &one, 2, 1, 1).unwrap();
        assert_eq!(&t[0..4], &src.texel(256, 256));
        // outside the data: transparent
        let edge = read_tile(&meta, &one, 2, 2, 2).unwrap();
        assert_eq!(edge[(255 * TILE as usize + 255) * 4 + 3], 0);
        // three shards, run one after another, build the same files
        let three = tmp("three");
        let mut written = 0;
        let mut top = 0;
        for i in 0..3 {
            let r = build_store(&src, &meta, &three, BuildOptions { shard: (i, 3) }, &|_, _| {}).unwrap();
            written += r.written;
            top += r.built_top as u32;
        }
        assert_eq!(top, 1, "only the last shard finds the split level complete");
        assert_eq!(written, meta.total_tiles());
        for z in 0..meta.levels {
            let (c, rows) = meta.data_tiles(z);
            for y in 0..rows {
                for x in 0..c {
                    assert_eq!(read_tile(&meta, &one, z, x, y).unwrap(), read_tile(&meta, &three, z, x, y).unwrap());
                }
            }
        }
        let _ = std::fs::remove_dir_all(&one);
        let _ = std::fs::remove_dir_all(&three);
    }

    #[test]
    fn coarser_levels_average_in_linear_light() {
        // a 512×256 source: left half black, right half white → level 0 is grey in linear light
        let mut rgba = vec![0u8; 512 * 256 * 4];
        for y in 0..256 {
            for x in 0..512 {
                let v = if x % 2 == 0 { 0 } else { 255 };
                rgba[(y * 512 + x) * 4..(y * 512 + x) * 4 + 4].copy_from_slice(&[v, v, v, 255]);
            }
        }
        let src = MemorySource { width: 512, height: 256, rgba, name: "stripes".into() };
        let meta = StoreMeta::for_source(512, 256, [0.0, 0.0], [1.0, 1.0], "", "");
        let d = tmp("linear");
        build_store(&src, &meta, &d, BuildOptions::default(), &|_, _| {}).unwrap();
        assert_eq!(meta.levels, 2);
        let t = read_tile(&meta, &d, 0, 0, 0).unwrap();
        // mean of 0 and 1 in linear light is sRGB code 188, not 128
        assert_eq!(t[0], 188);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn bad_stores_and_options_are_refused() {
        let d = tmp("bad");
        std::fs::create_dir_all(&d).unwrap();
        assert!(open_store(&d).is_err());
        std::fs::write(d.join("metadata.json"), "{\"format\": \"x\"}").unwrap();
        assert!(open_store(&d).is_err());
        let meta = StoreMeta::for_source(300, 300, [0.0, 0.0], [1.0, 1.0], "", "");
        let mut lie = meta.clone();
        lie.levels = 9;
        std::fs::write(d.join("metadata.json"), serde_json::to_string(&lie).unwrap()).unwrap();
        let e = open_store(&d).unwrap_err().to_string();
        assert!(e.contains("metadata.json") && e.contains("levels"), "{e}");
        let src = ProceduralSource { width: 300, height: 300, seed: 1 };
        assert!(build_store(&src, &meta, &d, BuildOptions { shard: (2, 2) }, &|_, _| {}).is_err());
        let small = ProceduralSource { width: 100, height: 300, seed: 1 };
        assert!(build_store(&small, &meta, &d, BuildOptions::default(), &|_, _| {}).is_err());
        // a corrupt map is an error naming it
        build_store(&src, &meta, &d, BuildOptions::default(), &|_, _| {}).unwrap();
        let p = meta.tile_path(&d, 1, 0, 0);
        std::fs::write(&p, b"not a png").unwrap();
        let e = read_tile(&meta, &d, 1, 0, 0).unwrap_err().to_string();
        assert!(e.contains(&p.display().to_string()), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
