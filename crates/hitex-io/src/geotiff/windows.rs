//! Reading a GeoTIFF by windows: only the strips or tiles a window touches
//! are decoded, so that sources far larger than memory can be processed.

use super::levels::seek_level;
use super::{Claim, GeoRaster, open_decoder, scale_heights, scaled_nodata, to_f32};
use crate::IoError;
use std::path::Path;
use tiff::decoder::Decoder;
use tiff::tags::Tag;

/// A GeoTIFF read by windows: only the strips or tiles a window touches are
/// decoded (a few are kept, within [`GeoTiffWindows::CACHE_BYTES`]), so
/// sources far larger than memory can be processed.
pub struct GeoTiffWindows {
    /// Size, bands and georeferencing (`data` is empty; nodata in metres
    /// where the file's heights are in another vertical unit).
    pub header: GeoRaster,
    /// Metres per unit of the file's heights (VerticalUnitsGeoKey): windows
    /// come back in metres, as whole reads do.
    z_scale: f64,
    path: std::path::PathBuf,
    decoder: std::sync::Mutex<Decoder<std::io::BufReader<std::fs::File>>>,
    /// Chunk (strip or tile) width and height.
    chunk: (u32, u32),
    across: u32,
    cache: std::sync::Mutex<std::collections::VecDeque<(u32, std::sync::Arc<Vec<f32>>)>>,
}

impl GeoTiffWindows {
    /// Decoded chunks kept for reuse, bytes.
    pub const CACHE_BYTES: usize = 64 << 20;

    /// Opens `path`: reads the header and georeferencing only.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        Self::open_level(path, 0)
    }

    /// Opens level `level` of `path` (0: the full image; 1, 2, …: its
    /// overviews, finest first, see [`super::levels`]): windows are then
    /// read from that level, in its pixels, and `header` describes it.
    pub fn open_level(path: &Path, level: usize) -> Result<Self, IoError> {
        let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
        let file = std::fs::File::open(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
        let len = file.metadata().map_err(|source| IoError::Read { path: path.to_path_buf(), source })?.len();
        let mut d = open_decoder(std::io::BufReader::new(file), path)?;
        let (mut header, z_scale) = seek_level(&mut d, len, path, level, Claim::Windows)?;
        header.nodata = scaled_nodata(header.nodata, z_scale);
        let planar = d.get_tag_u32(Tag::PlanarConfiguration).unwrap_or(1);
        if planar != 1 {
            return Err(fmt("bands stored as separate planes: windowed reading needs interleaved bands".into()));
        }
        let chunk = d.chunk_dimensions();
        if chunk.0 == 0 || chunk.1 == 0 {
            return Err(fmt(format!("chunks of {}×{} pixels", chunk.0, chunk.1)));
        }
        let chunk_bytes = chunk.0 as usize * chunk.1 as usize * header.bands * 4;
        if chunk_bytes > Self::CACHE_BYTES {
            return Err(fmt(format!(
                "strips or tiles of {}×{} pixels are too large to read by windows",
                chunk.0, chunk.1
            )));
        }
        let across = header.width.div_ceil(chunk.0);
        Ok(Self {
            header,
            z_scale,
            path: path.to_path_buf(),
            decoder: std::sync::Mutex::new(d),
            chunk,
            across,
            cache: std::sync::Mutex::new(std::collections::VecDeque::new()),
        })
    }

    /// Samples of chunk `i` (its data part: `chunk_data_dimensions`), bands interleaved.
    fn chunk(&self, i: u32) -> Result<std::sync::Arc<Vec<f32>>, IoError> {
        let fmt = |m: String| IoError::Format { path: self.path.clone(), message: m };
        if let Ok(c) = self.cache.lock()
            && let Some((_, v)) = c.iter().find(|(k, _)| *k == i)
        {
            return Ok(v.clone());
        }
        let (v, dims) = {
            let mut d = self.decoder.lock().map_err(|_| fmt("the decoder failed earlier".into()))?;
            let r = d.read_chunk(i).map_err(|e| fmt(format!("strip or tile {i}: {e}")))?;
            (to_f32(r).map_err(fmt)?, d.chunk_data_dimensions(i))
        };
        if v.len() < dims.0 as usize * dims.1 as usize * self.header.bands {
            return Err(fmt(format!("strip or tile {i}: {} samples, {}×{} pixels declared", v.len(), dims.0, dims.1)));
        }
        let v = std::sync::Arc::new(v);
        if let Ok(mut c) = self.cache.lock() {
            let per = (self.chunk.0 as usize * self.chunk.1 as usize * self.header.bands * 4).max(1);
            while !c.is_empty() && (c.len() + 1) * per > Self::CACHE_BYTES {
                c.pop_front();
            }
            c.push_back((i, v.clone()));
        }
        Ok(v)
    }

    /// Samples of the window at (x0, y0) of `w`×`h` pixels (inside the
    /// raster), bands interleaved, rows north to south; heights in metres
    /// (the same values as a whole read's).
    pub fn window(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<Vec<f32>, IoError> {
        let r = &self.header;
        if x0.checked_add(w).is_none_or(|x| x > r.width) || y0.checked_add(h).is_none_or(|y| y > r.height) {
            return Err(IoError::Format {
                path: self.path.clone(),
                message: format!("window {w}×{h} at ({x0}, {y0}) outside the {}×{} raster", r.width, r.height),
            });
        }
        let b = r.bands;
        let mut out = vec![0.0f32; w as usize * h as usize * b];
        let (cw, ch) = self.chunk;
        for cy in y0 / ch..(y0 + h).div_ceil(ch) {
            for cx in x0 / cw..(x0 + w).div_ceil(cw) {
                let data = self.chunk(cy * self.across + cx)?;
                // the chunk's data width: tiles are padded, the last strip is shorter
                let dw = cw.min(r.width - cx * cw) as usize;
                let (ox, oy) = (cx * cw, cy * ch);
                let (xa, xb) = (x0.max(ox), (x0 + w).min(ox + cw));
                let stride = if data.len() >= cw as usize * ch as usize * b { cw as usize } else { dw };
                for y in y0.max(oy)..(y0 + h).min(oy + ch) {
                    let src = ((y - oy) as usize * stride + (xa - ox) as usize) * b;
                    let dst = ((y - y0) as usize * w as usize + (xa - x0) as usize) * b;
                    let n = (xb - xa) as usize * b;
                    let Some(s) = data.get(src..src + n) else {
                        return Err(IoError::Format {
                            path: self.path.clone(),
                            message: format!("strip or tile at ({cx}, {cy}) is short"),
                        });
                    };
                    out[dst..dst + n].copy_from_slice(s);
                }
            }
        }
        scale_heights(&mut out, self.z_scale);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::super::load_geotiff;
    use super::*;

    #[test]
    fn windows_read_what_the_whole_file_holds() {
        let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/data/olinda/L7_ETMs.tif"));
        let whole = load_geotiff(path).unwrap();
        let win = GeoTiffWindows::open(path).unwrap();
        assert_eq!((win.header.width, win.header.height, win.header.bands), (whole.width, whole.height, whole.bands));
        assert_eq!(win.header.origin, whole.origin);
        let (w, h, b) = (whole.width, whole.height, whole.bands);
        for (x0, y0, ww, hh) in
            [(0, 0, w, h), (0, 0, 1, 1), (w - 1, h - 1, 1, 1), (17, 100, 256, 200), (300, 3, 49, 349)]
        {
            let got = win.window(x0, y0, ww, hh).unwrap();
            for y in 0..hh {
                for x in 0..ww {
                    for k in 0..b {
                        let i = ((y * ww + x) as usize) * b + k;
                        assert_eq!(
                            got[i],
                            whole.get(x0 + x, y0 + y, k),
                            "window ({x0},{y0}) {ww}×{hh} at ({x},{y}) band {k}"
                        );
                    }
                }
            }
        }
        assert!(win.window(w - 1, 0, 2, 1).is_err());
        assert!(win.window(0, u32::MAX, 1, 2).is_err());
    }

    #[test]
    fn windows_of_a_dem_in_feet_come_back_in_metres_as_whole_reads_do() {
        use tiff::encoder::{TiffEncoder, colortype};
        let dir = crate::test_dir::TestDir::fresh("windows-feet");
        let path = dir.join("feet.tif");
        let (w, h) = (5u32, 4u32);
        let mut v: Vec<i16> = (0..(w * h) as i16).map(|k| 100 + 7 * k).collect();
        v[6] = -9999;
        {
            let file = std::fs::File::create(&path).unwrap();
            let mut enc = TiffEncoder::new(file).unwrap();
            let mut img = enc.new_image::<colortype::GrayI16>(w, h).unwrap();
            img.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0][..]).unwrap();
            img.encoder().write_tag(Tag::ModelPixelScaleTag, &[30.0, 30.0, 0.0][..]).unwrap();
            // projected UTM 32N, heights in feet (VerticalUnitsGeoKey 9002)
            let keys: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32632, 4099, 0, 1, 9002];
            img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &keys[..]).unwrap();
            img.encoder().write_tag(Tag::GdalNodata, "-9999").unwrap();
            img.write_data(&v).unwrap();
        }
        let whole = load_geotiff(&path).unwrap();
        let win = GeoTiffWindows::open(&path).unwrap();
        // 100 ft = 30.48 m; nodata converted alike, so it still matches its samples
        assert!((whole.data[0] - 30.48).abs() < 1e-4, "{}", whole.data[0]);
        assert_eq!(win.header.nodata, whole.nodata);
        assert_eq!(win.window(0, 0, w, h).unwrap(), whole.data);
        let part = win.window(1, 1, 2, 2).unwrap();
        assert_eq!(part, [whole.get(1, 1, 0), whole.get(2, 1, 0), whole.get(1, 2, 0), whole.get(2, 2, 0)]);
        assert_eq!(part[0] as f64, whole.nodata.unwrap());
    }
}
