//! GeoTIFF rasters: elevation models (float or integer samples, nodata) and
//! multi-band imagery, with their georeferencing (ModelTiepoint,
//! ModelPixelScale, GeoKeys). Read through the `tiff` crate.

use crate::IoError;
use std::io::{Read, Seek};
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;

/// Most samples (width × height × bands) accepted from one file.
pub const MAX_SAMPLES: u64 = 1 << 28;

/// A georeferenced raster, samples as f32, pixel-interleaved, rows north to south.
#[derive(Debug, Clone, PartialEq)]
pub struct GeoRaster {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Samples per pixel.
    pub bands: usize,
    /// `width × height × bands` samples.
    pub data: Vec<f32>,
    /// World coordinates (x east, y north) of the raster's top-left corner.
    pub origin: [f64; 2],
    /// Pixel size in world units (x, y), both positive.
    pub pixel: [f64; 2],
    /// The nodata value, if the file declares one.
    pub nodata: Option<f64>,
    /// Projected CRS code from the GeoKeys (ProjectedCSTypeGeoKey), if any.
    pub epsg: Option<u16>,
    /// Projection code (ProjectionGeoKey), for user-defined CRSs.
    pub projection: Option<u16>,
    /// The GeoTIFF citation (GeoAsciiParams), if any.
    pub citation: Option<String>,
}

impl GeoRaster {
    /// Sample of band `b` at column `x`, row `y`.
    pub fn get(&self, x: u32, y: u32, b: usize) -> f32 {
        self.data[(y as usize * self.width as usize + x as usize) * self.bands + b]
    }
    /// World extent: (x min, x max, y min, y max).
    pub fn extent(&self) -> (f64, f64, f64, f64) {
        let (x0, y1) = (self.origin[0], self.origin[1]);
        (x0, x0 + self.pixel[0] * self.width as f64, y1 - self.pixel[1] * self.height as f64, y1)
    }
    /// The UTM zone (positive north, negative south) the georeferencing names:
    /// EPSG codes of WGS 84 (326zz/327zz), SIRGAS 2000 (31977–31985 south),
    /// NAD83 (269zz) and ETRS89 (258zz), or a projection code 160zz/161zz. The
    /// datums differ by less than a metre, below the pixel sizes of the data.
    pub fn utm_zone(&self) -> Option<i32> {
        let from_epsg = self.epsg.and_then(|c| match c {
            32601..=32660 => Some(c as i32 - 32600),
            32701..=32760 => Some(-(c as i32 - 32700)),
            31977..=31985 => Some(-(c as i32 - 31960)),
            26901..=26923 => Some(c as i32 - 26900),
            25828..=25838 => Some(c as i32 - 25800),
            _ => None,
        });
        let from_projection = self.projection.and_then(|c| match c {
            16001..=16060 => Some(c as i32 - 16000),
            16101..=16160 => Some(-(c as i32 - 16100)),
            _ => None,
        });
        from_epsg.or(from_projection)
    }

    /// A readable name of the coordinate reference system.
    pub fn crs_name(&self) -> String {
        match (self.utm_zone(), self.epsg) {
            (Some(z), _) => format!("UTM zone {}{}", z.abs(), if z > 0 { "N" } else { "S" }),
            (None, Some(c)) if c != 32767 => format!("EPSG:{c}"),
            _ => self.citation.clone().unwrap_or_else(|| "unknown CRS".into()),
        }
    }

    /// Whether both rasters are in the same coordinate reference system (the
    /// same UTM zone, the same EPSG code, or the same citation).
    pub fn same_crs(&self, other: &GeoRaster) -> bool {
        match (self.utm_zone(), other.utm_zone()) {
            (Some(a), Some(b)) => a == b,
            _ => match (self.epsg, other.epsg) {
                (Some(a), Some(b)) if a != 32767 && b != 32767 => a == b,
                _ => self.citation == other.citation,
            },
        }
    }
}

/// Reads a GeoTIFF; errors name the file.
pub fn load_geotiff(path: &Path) -> Result<GeoRaster, IoError> {
    let file = std::fs::File::open(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    let len = file.metadata().map_err(|source| IoError::Read { path: path.to_path_buf(), source })?.len();
    parse_geotiff(std::io::BufReader::new(file), len, path)
}

/// Reads a GeoTIFF of `len` bytes from `reader`; `path` is the file named in
/// errors. The declared raster is checked against [`MAX_SAMPLES`], against
/// what `len` bytes can hold and against the memory cap before it is decoded.
pub fn parse_geotiff<R: Read + Seek>(reader: R, len: u64, path: &Path) -> Result<GeoRaster, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let mut limits = tiff::decoder::Limits::default();
    let cap = usize::try_from(crate::limits::max_bytes()).unwrap_or(usize::MAX);
    limits.decoding_buffer_size = cap;
    limits.intermediate_buffer_size = cap.min(1 << 30);
    let mut d = Decoder::new(reader).map_err(|e| fmt(format!("not a TIFF file: {e}")))?.with_limits(limits);
    let (w, h) = d.dimensions().map_err(|e| fmt(e.to_string()))?;
    let (bands, bits) = match d.colortype().map_err(|e| fmt(e.to_string()))? {
        tiff::ColorType::Gray(b) => (1, b),
        tiff::ColorType::GrayA(b) => (2, b),
        tiff::ColorType::RGB(b) => (3, b),
        tiff::ColorType::RGBA(b) => (4, b),
        tiff::ColorType::Multiband { bit_depth, num_samples } => (num_samples as usize, bit_depth),
        other => return Err(fmt(format!("unsupported sample layout {other:?}"))),
    };
    let samples = w as u64 * h as u64 * bands as u64;
    if w == 0 || h == 0 || bands == 0 || samples > MAX_SAMPLES {
        return Err(fmt(format!("{w}×{h} pixels of {bands} bands is outside the limit of {MAX_SAMPLES} samples")));
    }
    let what = format!("a {w}×{h} raster of {bands} band{}", if bands == 1 { "" } else { "s" });
    let raw = samples * (bits as u64).div_ceil(8).max(1);
    crate::limits::check_claim(&what, Some(raw), len, crate::limits::ANY_RATIO).map_err(fmt)?;
    crate::limits::check_cap(&what, Some(raw + samples * 4)).map_err(fmt)?;
    let tie =
        d.get_tag_f64_vec(Tag::ModelTiepointTag).map_err(|_| fmt("no ModelTiepoint tag: not georeferenced".into()))?;
    let scale = d
        .get_tag_f64_vec(Tag::ModelPixelScaleTag)
        .map_err(|_| fmt("no ModelPixelScale tag: not georeferenced".into()))?;
    if tie.len() < 6
        || scale.len() < 2
        || !tie.iter().chain(&scale).all(|v| v.is_finite())
        || scale[0] <= 0.0
        || scale[1] <= 0.0
    {
        return Err(fmt(format!("unusable georeferencing: tiepoint {tie:?}, pixel scale {scale:?}")));
    }
    // top-left corner in world coordinates (raster space is pixel-is-area)
    let origin = [tie[3] - tie[0] * scale[0], tie[4] + tie[1] * scale[1]];
    let nodata =
        d.get_tag_ascii_string(Tag::GdalNodata).ok().and_then(|s| s.trim().trim_end_matches('\0').parse::<f64>().ok());
    let keys = d.get_tag_u16_vec(Tag::GeoKeyDirectoryTag).unwrap_or_default();
    let key = |id: u16| keys.chunks_exact(4).skip(1).find(|k| k[0] == id && k[1] == 0).map(|k| k[3]);
    let (epsg, projection) = (key(3072), key(3074));
    let citation =
        d.get_tag_ascii_string(Tag::Unknown(34737)).ok().map(|s| s.trim_end_matches(['|', '\0']).to_string());
    let data: Vec<f32> = match d.read_image().map_err(|e| fmt(format!("cannot decode the samples: {e}")))? {
        DecodingResult::U8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::U32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        _ => return Err(fmt("unsupported sample format".into())),
    };
    if data.len() as u64 != samples {
        return Err(fmt(format!("{} samples decoded, {samples} declared", data.len())));
    }
    Ok(GeoRaster {
        width: w,
        height: h,
        bands,
        data,
        origin,
        pixel: [scale[0], scale[1]],
        nodata,
        epsg,
        projection,
        citation,
    })
}

/// Replaces nodata and non-finite samples of band 0 by the mean of their
/// valid neighbours, growing inwards until every hole is filled; returns how
/// many samples were filled.
pub fn fill_holes(r: &mut GeoRaster) -> usize {
    let (w, h) = (r.width as usize, r.height as usize);
    let bad = |v: f32, nd: Option<f64>| !v.is_finite() || nd.is_some_and(|n| (v as f64 - n).abs() < 1e-6);
    let mut holes: Vec<usize> = (0..w * h).filter(|&i| bad(r.data[i * r.bands], r.nodata)).collect();
    let total = holes.len();
    if total == w * h {
        for i in holes {
            r.data[i * r.bands] = 0.0;
        }
        return total;
    }
    let mut valid: Vec<bool> = (0..w * h).map(|i| !bad(r.data[i * r.bands], r.nodata)).collect();
    while !holes.is_empty() {
        let mut next = Vec::new();
        let mut filled = Vec::new();
        for &i in &holes {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            let (mut sum, mut n) = (0.0f64, 0);
            for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                let (nx, ny) = (x + dx, y + dy);
                if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                    let j = ny as usize * w + nx as usize;
                    if valid[j] {
                        sum += r.data[j * r.bands] as f64;
                        n += 1;
                    }
                }
            }
            if n > 0 { filled.push((i, (sum / n as f64) as f32)) } else { next.push(i) }
        }
        for (i, v) in filled {
            r.data[i * r.bands] = v;
            valid[i] = true;
        }
        holes = next;
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/terrain").join(name)
    }

    #[test]
    fn olinda_pair_is_co_registered() {
        let (dp, ip) = (data("olinda_dem_utm25s.tif"), data("L7_ETMs.tif"));
        if !dp.exists() || !ip.exists() {
            eprintln!("SKIPPED olinda_pair_is_co_registered: shared data not found");
            return;
        }
        let dem = load_geotiff(&dp).unwrap();
        let img = load_geotiff(&ip).unwrap();
        assert_eq!((dem.width, dem.height, dem.bands), (111, 111, 1));
        assert_eq!((img.width, img.height, img.bands), (349, 352, 6));
        assert!(dem.same_crs(&img), "{} vs {}", dem.crs_name(), img.crs_name());
        assert_eq!(dem.utm_zone(), Some(-25));
        assert_eq!(dem.origin, img.origin);
        assert!((dem.pixel[0] - 90.0).abs() < 0.1 && (img.pixel[0] - 28.5).abs() < 0.1);
        assert!(dem.data.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn holes_are_filled_from_neighbours() {
        let mut r = GeoRaster {
            width: 3,
            height: 3,
            bands: 1,
            data: vec![1.0, 1.0, 1.0, 1.0, f32::NAN, 3.0, -9999.0, 1.0, 1.0],
            origin: [0.0, 0.0],
            pixel: [1.0, 1.0],
            nodata: Some(-9999.0),
            epsg: None,
            projection: None,
            citation: None,
        };
        assert_eq!(fill_holes(&mut r), 2);
        assert!((r.data[4] - 1.5).abs() < 1e-6, "{}", r.data[4]);
        assert!((r.data[6] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn non_tiff_and_ungeoreferenced_files_are_errors() {
        let dir = std::env::temp_dir().join(format!("hitex-geotiff-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("x.tif");
        std::fs::write(&p, b"II*\0garbage").unwrap();
        assert!(load_geotiff(&p).unwrap_err().to_string().contains("x.tif"));
        let png = dir.join("y.tif");
        crate::save_png(&png, 2, 2, &[0; 16]).unwrap();
        assert!(load_geotiff(&png).is_err());
        assert!(load_geotiff(&dir.join("missing.tif")).is_err());
    }
}
