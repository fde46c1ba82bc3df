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
    /// Finest-level texels from the grid's north-west corner (`origin`) to
    /// the data's (0, 0 for a pyramid anchored at its data).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub offset: [u32; 2],
    /// The tiling the maps belong to: a local pyramid, or the global
    /// web-mercator one (EPSG:3857, the tiles web maps load).
    #[serde(default, skip_serializing_if = "Profile::is_local")]
    pub profile: Profile,
    /// The level-0 map's place in the global tiling: zoom, column, row from
    /// the north (0, 0, 0 for a local pyramid).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub tiles: [u32; 3],
}

fn is_zero<const N: usize>(v: &[u32; N]) -> bool {
    v.iter().all(|&x| x == 0)
}

/// How a store's maps are tiled.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Level 0 is one map over the source, in the source's CRS.
    #[default]
    Local,
    /// The global web-mercator tiles (EPSG:3857, OSGeo TMS
    /// `global-mercator`): level z is zoom `tiles[0] + z`.
    Mercator,
}

impl Profile {
    fn is_local(&self) -> bool {
        *self == Profile::Local
    }
}

/// Half the web-mercator world's side, metres (π × 6,378,137).
pub const MERCATOR_HALF: f64 = std::f64::consts::PI * MERCATOR_RADIUS;
/// The web-mercator sphere's radius, metres.
pub const MERCATOR_RADIUS: f64 = 6_378_137.0;
/// Deepest web-mercator zoom a store is built at (about 2 cm a texel).
pub const MAX_MERCATOR_ZOOM: u32 = 23;

/// Levels of a pyramid whose finest level spans `w`×`h` texels.
fn levels_for(w: u64, h: u64) -> u32 {
    let maps = w.div_ceil(TILE as u64).max(h.div_ceil(TILE as u64)).max(1);
    1 + maps.next_power_of_two().trailing_zeros()
}

impl StoreMeta {
    /// The metadata of a pyramid over a `width`×`height` source.
    pub fn for_source(width: u32, height: u32, origin: [f64; 2], pixel: [f64; 2], crs: &str, source: &str) -> Self {
        let levels = levels_for(width as u64, height as u64);
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
            offset: [0, 0],
            profile: Profile::Local,
            tiles: [0, 0, 0],
        }
    }

    /// The metadata of a web-mercator pyramid at `zoom` over the EPSG:3857
    /// extent `bounds` (x min, y min, x max, y max, metres): level 0 is the
    /// deepest-zoom tile holding the whole extent, the finest level is `zoom`.
    pub fn mercator(bounds: [f64; 4], zoom: u32, source: &str) -> Result<Self, crate::DataError> {
        Self::mercator_meta(bounds, zoom, source).map_err(crate::DataError::from)
    }

    fn mercator_meta(bounds: [f64; 4], zoom: u32, source: &str) -> Result<Self, String> {
        if zoom > MAX_MERCATOR_ZOOM {
            return Err(format!("zoom {zoom} is beyond {MAX_MERCATOR_ZOOM}"));
        }
        let [x0, y0, x1, y1] = bounds;
        if !bounds.iter().all(|v| v.is_finite()) || x1 <= x0 || y1 <= y0 {
            return Err(format!("no web-mercator extent ({x0}, {y0}) to ({x1}, {y1})"));
        }
        let side = TILE as u64 * (1u64 << zoom);
        let pixel = 2.0 * MERCATOR_HALF / side as f64;
        let clamp = |v: f64| v.clamp(0.0, side as f64);
        let (c0, c1) = (clamp(((x0 + MERCATOR_HALF) / pixel).floor()), clamp(((x1 + MERCATOR_HALF) / pixel).ceil()));
        let (r0, r1) = (clamp(((MERCATOR_HALF - y1) / pixel).floor()), clamp(((MERCATOR_HALF - y0) / pixel).ceil()));
        let (c0, c1, r0, r1) = (c0 as u64, (c1 as u64).max(c0 as u64 + 1), r0 as u64, (r1 as u64).max(r0 as u64 + 1));
        let (w, h) = (c1 - c0, r1 - r0);
        if w > MAX_SOURCE_SIDE as u64 || h > MAX_SOURCE_SIDE as u64 {
            return Err(format!("{w}x{h} texels at zoom {zoom}, beyond {MAX_SOURCE_SIDE} a side"));
        }
        // the smallest k whose zoom − k tile holds the extent
        let k = (0..=zoom)
            .find(|&k| {
                let span = TILE as u64 * (1u64 << k);
                c0 / span == (c1 - 1) / span && r0 / span == (r1 - 1) / span
            })
            .unwrap_or(zoom);
        let span = TILE as u64 * (1u64 << k);
        if span > MAX_SOURCE_SIDE as u64 {
            return Err(format!(
                "the extent straddles the edge of zoom-{} tiles: its pyramid would be {span} texels across at zoom {zoom}, \
                 beyond {MAX_SOURCE_SIDE}; build it with the local profile",
                zoom - k
            ));
        }
        let (tx, ty) = (c0 / span, r0 / span);
        let origin = [-MERCATOR_HALF + (tx * span) as f64 * pixel, MERCATOR_HALF - (ty * span) as f64 * pixel];
        Ok(Self {
            format: "hitex-gst".into(),
            version: 1,
            tile_size: TILE,
            width: w as u32,
            height: h as u32,
            levels: k + 1,
            origin,
            pixel: [pixel, pixel],
            crs: "EPSG:3857".into(),
            source: source.into(),
            offset: [(c0 - tx * span) as u32, (r0 - ty * span) as u32],
            profile: Profile::Mercator,
            tiles: [zoom - k, tx as u32, ty as u32],
        })
    }

    /// World coordinates of the data's north-west corner.
    pub fn data_origin(&self) -> [f64; 2] {
        [self.origin[0] + self.offset[0] as f64 * self.pixel[0], self.origin[1] - self.offset[1] as f64 * self.pixel[1]]
    }

    /// Metres on the ground per finest texel along x: the pixel size, or
    /// for web mercator the pixel size times the cosine of the data's
    /// central latitude (the projection's scale there).
    pub fn ground_pixel(&self) -> f64 {
        match self.profile {
            Profile::Local => self.pixel[0],
            Profile::Mercator => {
                let y = self.data_origin()[1] - self.height as f64 / 2.0 * self.pixel[1];
                self.pixel[0] * (y / MERCATOR_RADIUS).sinh().atan().cos()
            }
        }
    }

    /// The data's extent in longitude and latitude (west, south, east,
    /// north, degrees) for a web-mercator store.
    pub fn lon_lat_bounds(&self) -> Option<[f64; 4]> {
        if self.profile != Profile::Mercator {
            return None;
        }
        let [x0, y1] = self.data_origin();
        let (x1, y0) = (x0 + self.width as f64 * self.pixel[0], y1 - self.height as f64 * self.pixel[1]);
        let lon = |x: f64| (x / MERCATOR_RADIUS).to_degrees();
        let lat = |y: f64| (y / MERCATOR_RADIUS).sinh().atan().to_degrees();
        Some([lon(x0), lat(y0), lon(x1), lat(y1)])
    }

    /// The global zoom of level `z` (equal to `z` for a local pyramid).
    pub fn zoom(&self, z: u32) -> u32 {
        self.tiles[0] + z
    }

    /// The global column and row (from the north) of map (x, y) of level `z`.
    pub fn global_tile(&self, z: u32, x: u32, y: u32) -> (u32, u32) {
        ((self.tiles[1] << z) + x, (self.tiles[2] << z) + y)
    }

    /// Finest-level texels per texel of level `z`.
    pub fn scale(&self, z: u32) -> u64 {
        1u64 << (self.levels - 1 - z.min(self.levels - 1))
    }

    /// Maps holding data at level `z`: first column, first row (from the
    /// north), and one past the last of each.
    pub fn data_range(&self, z: u32) -> [u32; 4] {
        let span = TILE as u64 * self.scale(z);
        let (ox, oy) = (self.offset[0] as u64, self.offset[1] as u64);
        [
            (ox / span) as u32,
            (oy / span) as u32,
            (ox + self.width as u64).div_ceil(span) as u32,
            (oy + self.height as u64).div_ceil(span) as u32,
        ]
    }

    /// The maps of level `z` holding data, row by row.
    pub fn data_maps(&self, z: u32) -> impl Iterator<Item = (u32, u32)> {
        let [x0, y0, x1, y1] = self.data_range(z);
        (y0..y1).flat_map(move |y| (x0..x1).map(move |x| (x, y)))
    }

    /// How many maps of level `z` hold data.
    pub fn data_count(&self, z: u32) -> u64 {
        let [x0, y0, x1, y1] = self.data_range(z);
        (x1 - x0) as u64 * (y1 - y0) as u64
    }

    /// The TMS row (counted from the south) of map row `y` (from the north) of level `z`.
    pub fn tms_row(&self, z: u32, y: u32) -> u32 {
        let (_, gy) = self.global_tile(z, 0, y);
        ((1u64 << self.zoom(z)) - 1 - gy as u64) as u32
    }

    /// The TMS file of map (x, y-from-north) at level `z`:
    /// `zoom/column/row_from_south.png`.
    pub fn tile_path(&self, root: &Path, z: u32, x: u32, y: u32) -> PathBuf {
        let (gx, _) = self.global_tile(z, x, y);
        root.join(self.zoom(z).to_string()).join(gx.to_string()).join(format!("{}.png", self.tms_row(z, y)))
    }

    /// Maps of all levels.
    pub fn total_tiles(&self) -> u64 {
        (0..self.levels).map(|z| self.data_count(z)).sum()
    }

    /// `tilemapresource.xml` (OSGeo TMS 1.0.0): a local pyramid anchored at
    /// its grid's north-west corner and padded to 2^z maps per side, or the
    /// `global-mercator` profile.
    pub fn tms_xml(&self) -> String {
        let ([minx, maxy], [w, h]) = match self.profile {
            // the padded grid
            Profile::Local => (self.origin, [TILE as f64 * (1u64 << (self.levels - 1)) as f64; 2]),
            // the data
            Profile::Mercator => (self.data_origin(), [self.width as f64, self.height as f64]),
        };
        let (maxx, miny) = (minx + w * self.pixel[0], maxy - h * self.pixel[1]);
        let (profile, ox, oy) = match self.profile {
            Profile::Local => ("none", minx, miny),
            Profile::Mercator => ("global-mercator", -MERCATOR_HALF, -MERCATOR_HALF),
        };
        let mut s = String::from("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
        s += "<TileMap version=\"1.0.0\" tilemapservice=\"http://tms.osgeo.org/1.0.0\">\n";
        s += "  <Title>hitex geospecific texture pyramid</Title>\n";
        s += &format!("  <Abstract>{}</Abstract>\n", xml_escape(&self.source));
        s += &format!("  <SRS>{}</SRS>\n", xml_escape(&self.crs));
        s += &format!("  <BoundingBox minx=\"{minx}\" miny=\"{miny}\" maxx=\"{maxx}\" maxy=\"{maxy}\"/>\n");
        s += &format!("  <Origin x=\"{ox}\" y=\"{oy}\"/>\n");
        s += &format!("  <TileFormat width=\"{TILE}\" height=\"{TILE}\" mime-type=\"image/png\" extension=\"png\"/>\n");
        s += &format!("  <TileSets profile=\"{profile}\">\n");
        for z in 0..self.levels {
            let upp = self.pixel[0] * self.scale(z) as f64;
            let zoom = self.zoom(z);
            s += &format!("    <TileSet href=\"{zoom}\" units-per-pixel=\"{upp}\" order=\"{zoom}\"/>\n");
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
    let want = levels_for(meta.offset[0] as u64 + meta.width as u64, meta.offset[1] as u64 + meta.height as u64);
    if meta.levels != want {
        return bad(format!(
            "{} levels; a {}x{} source {}has {want}",
            meta.levels,
            meta.width,
            meta.height,
            if meta.offset == [0, 0] {
                String::new()
            } else {
                format!("{:?} texels from the grid's corner ", meta.offset)
            }
        ));
    }
    match meta.profile {
        Profile::Local if meta.tiles != [0, 0, 0] => {
            return bad(format!("a local pyramid placed at global tile {:?}", meta.tiles));
        }
        Profile::Mercator => {
            let [zoom, x, y] = meta.tiles;
            let finest = zoom as u64 + meta.levels as u64 - 1;
            if finest > MAX_MERCATOR_ZOOM as u64 || x as u64 >= 1u64 << zoom || y as u64 >= 1u64 << zoom {
                return bad(format!("web-mercator tile {:?} with {} levels", meta.tiles, meta.levels));
            }
            let again = StoreMeta::mercator(
                {
                    let [x0, y1] = meta.data_origin();
                    let (x1, y0) = (x0 + meta.width as f64 * meta.pixel[0], y1 - meta.height as f64 * meta.pixel[1]);
                    let inset = meta.pixel[0] / 4.0;
                    [x0 + inset, y0 + inset, x1 - inset, y1 - inset]
                },
                finest as u32,
                &meta.source,
            );
            match again {
                Ok(m)
                    if (m.offset, m.tiles, m.width, m.height) == (meta.offset, meta.tiles, meta.width, meta.height)
                        && (m.pixel[0] - meta.pixel[0]).abs() <= 1e-9 * m.pixel[0]
                        && m.origin.iter().zip(&meta.origin).all(|(a, b)| (a - b).abs() <= 1e-3 * m.pixel[0])
                        && meta.crs == "EPSG:3857" => {}
                _ => {
                    return bad(format!(
                        "web-mercator tile {:?}, offset {:?}, pixel {:?}, CRS '{}' do not describe one zoom-{finest} extent",
                        meta.tiles, meta.offset, meta.pixel, meta.crs
                    ));
                }
            }
        }
        Profile::Local => {}
    }
    if !meta.origin.iter().chain(meta.pixel.iter()).all(|v| v.is_finite()) || meta.pixel.iter().any(|&p| p <= 0.0) {
        return bad("origin and pixel size must be finite, pixel sizes positive".into());
    }
    Ok(meta)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> crate::test_dir::TestDir {
        crate::test_dir::TestDir::at(&format!("gst-{name}"))
    }

    #[test]
    fn geometry_of_a_pyramid() {
        let m = StoreMeta::for_source(1000, 600, [0.0, 0.0], [1.0, 1.0], "", "");
        assert_eq!(m.levels, 3); // 4×3 maps → 4 per side → levels 0..2
        assert_eq!(m.data_range(2), [0, 0, 4, 3]);
        assert_eq!(m.data_range(1), [0, 0, 2, 2]);
        assert_eq!(m.data_range(0), [0, 0, 1, 1]);
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
            for (x, y) in meta.data_maps(z) {
                assert_eq!(read_tile(&meta, &one, z, x, y).unwrap(), read_tile(&meta, &three, z, x, y).unwrap());
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

    /// The web-mercator tile of (lon, lat) at `zoom`, by the slippy-map
    /// formula (column, row from the north).
    fn slippy(lon: f64, lat: f64, zoom: u32) -> (u32, u32) {
        let n = (1u64 << zoom) as f64;
        let phi = lat.to_radians();
        let x = ((lon + 180.0) / 360.0 * n).floor();
        let y = ((1.0 - (phi.tan() + 1.0 / phi.cos()).ln() / std::f64::consts::PI) / 2.0 * n).floor();
        (x as u32, y as u32)
    }

    #[test]
    fn mercator_pyramids_sit_on_the_global_tiles() {
        use crate::crs::Crs;
        let merc = Crs::from_epsg(3857).unwrap();
        for (lon, lat, zoom) in
            [(-34.8712, -7.9954, 13), (13.3777, 52.5163, 17), (-0.01, 51.48, 15), (151.2, -33.86, 12)]
        {
            // EPSG:3857 from PROJ's definition against the spherical formula
            let p = Crs::wgs84().point(&merc, [lon, lat]);
            assert!((p[0] - MERCATOR_RADIUS * lon.to_radians()).abs() < 1e-3, "{p:?}");
            assert!((p[1] - MERCATOR_RADIUS * lat.to_radians().tan().asinh()).abs() < 1e-3, "{p:?}");
            let meta =
                StoreMeta::mercator([p[0] - 3000.0, p[1] - 2000.0, p[0] + 3000.0, p[1] + 2000.0], zoom, "t").unwrap();
            let f = meta.levels - 1;
            assert_eq!(meta.zoom(f), zoom);
            assert_eq!(meta.data_range(0), [0, 0, 1, 1], "level 0 is one map");
            // the finest map holding the point is the point's tile at that zoom
            let tx = ((p[0] - meta.origin[0]) / meta.pixel[0]) as u32 / TILE;
            let ty = ((meta.origin[1] - p[1]) / meta.pixel[1]) as u32 / TILE;
            let (xt, yt) = slippy(lon, lat, zoom);
            assert_eq!(meta.global_tile(f, tx, ty), (xt, yt), "({lon}, {lat}) at zoom {zoom}");
            let tms = (1u32 << zoom) - 1 - yt;
            assert!(meta.tile_path(Path::new("s"), f, tx, ty).ends_with(format!("{zoom}/{xt}/{tms}.png")));
            // and a deeper zoom − levels + 1 would not hold the extent in one map
            if meta.levels > 1 {
                assert!(meta.data_count(1) > 1);
            }
            // lon/lat bounds hold the point
            let [w, so, e, n] = meta.lon_lat_bounds().unwrap();
            assert!(w < lon && lon < e && so < lat && lat < n);
            // described and read back the same; a tampered placement is refused
            let json = serde_json::to_string(&meta).unwrap();
            assert_eq!(parse_store_meta(&json, Path::new("m.json")).unwrap(), meta);
            for bad in [
                StoreMeta { pixel: [meta.pixel[0] * 2.0; 2], ..meta.clone() },
                StoreMeta { origin: [meta.origin[0] + meta.pixel[0] / 2.0, meta.origin[1]], ..meta.clone() },
                StoreMeta { tiles: [meta.tiles[0], meta.tiles[1] + 1, meta.tiles[2]], ..meta.clone() },
                StoreMeta { crs: "EPSG:31985".into(), ..meta.clone() },
                StoreMeta { profile: Profile::Local, ..meta.clone() },
            ]
            .into_iter()
            // (a local description of a pyramid at global tile 0/0/0 is a valid one)
            .filter(|b| b.profile == Profile::Mercator || b.tiles != [0, 0, 0])
            {
                let j = serde_json::to_string(&bad).unwrap();
                assert!(parse_store_meta(&j, Path::new("m.json")).is_err(), "{j}");
            }
        }
        // an extent across the prime meridian and the equator needs zoom 0 as level 0
        let m = StoreMeta::mercator([-1000.0, -1000.0, 1000.0, 1000.0], 10, "t").unwrap();
        assert_eq!((m.tiles, m.levels), ([0, 0, 0], 11));
        assert_eq!(m.data_range(10), [511, 511, 513, 513]);
        // local stores keep their description as before
        let local = StoreMeta::for_source(300, 300, [0.0, 0.0], [1.0, 1.0], "", "");
        let j = serde_json::to_string(&local).unwrap();
        assert!(!j.contains("offset") && !j.contains("profile") && !j.contains("tiles"), "{j}");
        assert!(StoreMeta::mercator([0.0, 0.0, 1.0, 1.0], MAX_MERCATOR_ZOOM + 1, "t").is_err());
        assert!(StoreMeta::mercator([0.0, 0.0, f64::NAN, 1.0], 5, "t").is_err());
    }

    #[test]
    fn mercator_ground_texels_match_the_local_frame() {
        use crate::crs::Crs;
        let merc = Crs::from_epsg(3857).unwrap();
        for (lon, lat) in [(-34.87, -8.0), (10.0, 45.0), (25.0, 65.0)] {
            let p = Crs::wgs84().point(&merc, [lon, lat]);
            let meta =
                StoreMeta::mercator([p[0] - 2000.0, p[1] - 2000.0, p[0] + 2000.0, p[1] + 2000.0], 14, "t").unwrap();
            // one texel east at the data's centre, measured in the local metric frame there
            let [x0, y1] = meta.data_origin();
            let c = [x0 + meta.width as f64 / 2.0 * meta.pixel[0], y1 - meta.height as f64 / 2.0 * meta.pixel[1]];
            let ll = merc.point(&Crs::wgs84(), c);
            let local = Crs::local(ll[0], ll[1]).unwrap();
            let mut q = [[c[0] - 50.0 * meta.pixel[0], c[1]], [c[0] + 50.0 * meta.pixel[0], c[1]]];
            merc.transform(&local, &mut q);
            let metres = ((q[1][0] - q[0][0]).powi(2) + (q[1][1] - q[0][1]).powi(2)).sqrt() / 100.0;
            // the sphere's cos φ against the ellipsoid: within 0.3 % (e²·sin²φ/2 at most)
            let rel = (meta.ground_pixel() - metres).abs() / metres;
            assert!(rel < 3e-3, "at {lat}°: {} vs {metres} m ({rel})", meta.ground_pixel());
        }
    }

    #[test]
    fn a_grid_with_an_offset_builds_only_its_data() {
        let src = ProceduralSource { width: 300, height: 200, seed: 5 };
        let mut meta = StoreMeta::for_source(300, 200, [0.0, 0.0], [1.0, 1.0], "", "t");
        meta.offset = [400, 130];
        meta.levels = levels_for(700, 330);
        assert_eq!(meta.levels, 3);
        assert_eq!(meta.data_range(2), [1, 0, 3, 2]);
        assert_eq!(meta.data_range(1), [0, 0, 2, 1]);
        let d = tmp("offset");
        let r = build_store(&src, &meta, &d, BuildOptions::default(), &|_, _| {}).unwrap();
        assert_eq!(r.written, meta.total_tiles());
        assert_eq!(meta.total_tiles(), 4 + 2 + 1);
        // source texel (0, 0) lies at grid texel (400, 130): map (1, 0) of the finest level, at (144, 130)
        let t = read_tile(&meta, &d, 2, 1, 0).unwrap();
        assert_eq!(&t[((130 * TILE + 144) * 4) as usize..][..4], &src.texel(0, 0));
        assert_eq!(t[((129 * TILE + 144) * 4 + 3) as usize], 0, "above the data: transparent");
        assert!(!meta.tile_path(&d, 2, 0, 0).exists(), "no map outside the data");
        let _ = std::fs::remove_dir_all(&d);
    }
}
