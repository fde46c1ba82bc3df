//! A writer of tiled GeoTIFFs with overviews, laid out as a Cloud-Optimized
//! GeoTIFF (COG): every image directory first (the full image's, then each
//! overview's, marked reduced-resolution), then the tiles, coarsest level
//! first, so that a reader of a coarse level touches only the file's start.
//! Samples are 32-bit floats, uncompressed; the georeferencing is the
//! DEM writer's ([`super::write_dem_geotiff`]).

use super::{GeoKeys, GeoRaster, block_mean, geokeys};
use crate::DataError;
use crate::crs::Crs;

/// TIFF field types.
const SHORT: u16 = 3;
const LONG: u16 = 4;
const ASCII: u16 = 2;
const DOUBLE: u16 = 12;

/// One IFD entry: tag, field type, value count and the values' bytes.
struct Entry {
    tag: u16,
    kind: u16,
    count: u32,
    bytes: Vec<u8>,
}

fn shorts(tag: u16, v: &[u16]) -> Entry {
    Entry { tag, kind: SHORT, count: v.len() as u32, bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect() }
}

fn longs(tag: u16, v: &[u32]) -> Entry {
    Entry { tag, kind: LONG, count: v.len() as u32, bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect() }
}

fn doubles(tag: u16, v: &[f64]) -> Entry {
    Entry { tag, kind: DOUBLE, count: v.len() as u32, bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect() }
}

fn ascii(tag: u16, s: &str) -> Entry {
    let mut bytes = s.as_bytes().to_vec();
    bytes.push(0);
    Entry { tag, kind: ASCII, count: bytes.len() as u32, bytes }
}

/// The mean of each 2×2 block of `r`, band by band, over the block's valid
/// samples (finite and not nodata; nodata, or NaN without one, where none
/// is): an overview of half the size, rounded up, over the same extent.
pub fn halved(r: &GeoRaster) -> GeoRaster {
    let (w, h, b) = (r.width.div_ceil(2), r.height.div_ceil(2), r.bands);
    let hole = r.nodata.map_or(f32::NAN, |n| n as f32);
    let mut data = Vec::with_capacity(w as usize * h as usize * b);
    for j in 0..h {
        for i in 0..w {
            let (xs, ys) = (2 * i..(2 * i + 2).min(r.width), 2 * j..(2 * j + 2).min(r.height));
            for k in 0..b {
                data.push(block_mean(r, k, xs.clone(), ys.clone()).unwrap_or(hole));
            }
        }
    }
    GeoRaster {
        width: w,
        height: h,
        data,
        // the factor first: a whole factor scales the pixel exactly (as decimation does)
        pixel: [r.pixel[0] * (r.width as f64 / w as f64), r.pixel[1] * (r.height as f64 / h as f64)],
        citation: r.citation.clone(),
        proj4: r.proj4.clone(),
        ..*r
    }
}

/// A COG of `r` in `crs` with `tile`-pixel tiles: the full raster, then
/// overviews by [`halved`] until one tile holds the level.
pub fn cog_bytes(r: &GeoRaster, crs: &Crs, tile: u32) -> Result<Vec<u8>, DataError> {
    // the full raster checked before any overview is made of it
    check_tile(tile)?;
    check_level(r, 0, r.bands)?;
    let mut levels = vec![r.clone()];
    while let Some(last) = levels.last()
        && (last.width > tile || last.height > tile)
        && tile > 0
    {
        let next = halved(last);
        levels.push(next);
    }
    tiled_geotiff_bytes(&levels, crs, tile)
}

/// Checks a tile size: a multiple of 16 (as TIFF asks), up to 4096.
fn check_tile(tile: u32) -> Result<(), DataError> {
    if tile == 0 || !tile.is_multiple_of(16) || tile > 4096 {
        return Err(DataError::from(format!("tiles of {tile} pixels: a multiple of 16 up to 4096 is needed")));
    }
    Ok(())
}

/// Checks that level `i` holds its samples: `bands` of them (1 or 3) on
/// each of at least one pixel.
fn check_level(l: &GeoRaster, i: usize, bands: usize) -> Result<(), DataError> {
    if bands != 1 && bands != 3 {
        return Err(DataError::from(format!("{bands} bands: 1 (elevation) or 3 (RGB) can be written")));
    }
    if l.width == 0 || l.height == 0 || l.bands != bands || l.data.len() != l.width as usize * l.height as usize * bands
    {
        return Err(DataError::from(format!(
            "level {i}: {} samples for {}×{}×{}",
            l.data.len(),
            l.width,
            l.height,
            l.bands
        )));
    }
    Ok(())
}

/// A tiled GeoTIFF of `levels` (the full raster, then its overviews, each
/// smaller than the one before, all of one extent and of 1 or 3 bands) in
/// `crs`, with `tile`×`tile` tiles (a multiple of 16), laid out as a COG.
pub fn tiled_geotiff_bytes(levels: &[GeoRaster], crs: &Crs, tile: u32) -> Result<Vec<u8>, DataError> {
    let bad = |m: String| DataError::from(m);
    let Some(full) = levels.first() else { return Err(bad("no image to write".into())) };
    check_tile(tile)?;
    let bands = full.bands;
    for (i, l) in levels.iter().enumerate() {
        check_level(l, i, bands)?;
        if i > 0 {
            let p = &levels[i - 1];
            if l.width > p.width || l.height > p.height || (l.width, l.height) == (p.width, p.height) {
                return Err(bad(format!("level {i} of {}×{} is not smaller than the one before", l.width, l.height)));
            }
        }
    }
    let GeoKeys { dir, doubles: params, citation } = geokeys(crs).map_err(bad)?;
    let tile_bytes = tile as usize * tile as usize * bands * 4;
    let mut buf: Vec<u8> = b"II*\0".to_vec();
    buf.extend_from_slice(&8u32.to_le_bytes());
    // per level: where its tile offsets are to be written
    let mut offsets_at = Vec::with_capacity(levels.len());
    let mut next_at: Option<usize> = None;
    for (i, l) in levels.iter().enumerate() {
        let (across, down) = (l.width.div_ceil(tile), l.height.div_ceil(tile));
        let n = across as usize * down as usize;
        let mut e = vec![
            longs(254, &[(i > 0) as u32]),
            longs(256, &[l.width]),
            longs(257, &[l.height]),
            shorts(258, &vec![32; bands]),
            shorts(259, &[1]),
            shorts(262, &[if bands == 3 { 2 } else { 1 }]),
            shorts(277, &[bands as u16]),
            shorts(284, &[1]),
            longs(322, &[tile]),
            longs(323, &[tile]),
            longs(324, &vec![0; n]),
            longs(325, &vec![tile_bytes as u32; n]),
            shorts(339, &vec![3; bands]),
        ];
        if i == 0 {
            e.push(doubles(33550, &[full.pixel[0], full.pixel[1], 0.0]));
            e.push(doubles(33922, &[0.0, 0.0, 0.0, full.origin[0], full.origin[1], 0.0]));
            e.push(shorts(34735, &dir));
            if !params.is_empty() {
                e.push(doubles(34736, &params));
            }
            e.push(ascii(34737, &citation));
            if let Some(nd) = full.nodata.filter(|n| n.is_finite()) {
                e.push(ascii(42113, &format!("{nd}")));
            }
        }
        // the directory, its values past 4 bytes just after it
        if buf.len() % 2 == 1 {
            buf.push(0);
        }
        let here = buf.len() as u32;
        match next_at {
            Some(at) => buf[at..at + 4].copy_from_slice(&here.to_le_bytes()),
            None => buf[4..8].copy_from_slice(&here.to_le_bytes()),
        }
        let extra = buf.len() + 2 + 12 * e.len() + 4;
        buf.extend_from_slice(&(e.len() as u16).to_le_bytes());
        let mut values: Vec<u8> = Vec::new();
        let mut tile_offsets = 0;
        for x in &e {
            buf.extend_from_slice(&x.tag.to_le_bytes());
            buf.extend_from_slice(&x.kind.to_le_bytes());
            buf.extend_from_slice(&x.count.to_le_bytes());
            let at = if x.bytes.len() <= 4 {
                let at = buf.len();
                let mut v = x.bytes.clone();
                v.resize(4, 0);
                buf.extend_from_slice(&v);
                at
            } else {
                let at = extra + values.len();
                buf.extend_from_slice(&(at as u32).to_le_bytes());
                values.extend_from_slice(&x.bytes);
                if values.len() % 2 == 1 {
                    values.push(0);
                }
                at
            };
            if x.tag == 324 {
                tile_offsets = at;
            }
        }
        next_at = Some(buf.len());
        buf.extend_from_slice(&0u32.to_le_bytes());
        buf.extend_from_slice(&values);
        offsets_at.push(tile_offsets);
    }
    // the tiles, coarsest level first; past the raster's edge, zeros
    for (i, l) in levels.iter().enumerate().rev() {
        let (across, down) = (l.width.div_ceil(tile), l.height.div_ceil(tile));
        for ty in 0..down {
            for tx in 0..across {
                let offset = u32::try_from(buf.len()).map_err(|_| bad("the file would pass 4 GiB".into()))?;
                let k = (ty * across + tx) as usize;
                let at = offsets_at[i] + 4 * k;
                buf[at..at + 4].copy_from_slice(&offset.to_le_bytes());
                for y in ty * tile..(ty + 1) * tile {
                    for x in tx * tile..(tx + 1) * tile {
                        for b in 0..bands {
                            let v = if x < l.width && y < l.height { l.get(x, y, b) } else { 0.0 };
                            buf.extend_from_slice(&v.to_le_bytes());
                        }
                    }
                }
            }
        }
    }
    Ok(buf)
}
