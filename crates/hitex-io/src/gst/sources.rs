//! The sources a pyramid is built from: a [`TileSource`] reads texel
//! windows; in memory, procedural, or a GeoTIFF read window by window.

use super::*;

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
