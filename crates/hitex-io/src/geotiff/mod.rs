//! GeoTIFF rasters: elevation models (float or integer samples, nodata) and
//! multi-band imagery, with their georeferencing (ModelTiepoint,
//! ModelPixelScale, GeoKeys). Read through the `tiff` crate.
//!
//! - this module: the georeferencing, whole-file reading and the DEM writer;
//! - `geokeys`: user-defined projections read from GeoKeys, and the keys written for a CRS;
//! - [`levels`]: the overviews of Cloud-Optimized GeoTIFFs, read level by level;
//! - [`windows`]: reading by windows (only the strips or tiles a window touches);
//! - [`tiled`]: a writer of tiled GeoTIFFs with overviews, laid out as a COG.

use crate::IoError;
use std::io::{Read, Seek};
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;

mod geokeys;
pub mod levels;
pub mod tiled;
pub mod windows;

use geokeys::{GeoKeys, geokeys, user_defined_projection};

pub use levels::{
    Coarsening, Level, LevelRead, Levels, MAX_IFDS, ViewLevel, geotiff_levels, load_for_view, load_geotiff_level,
    parse_geotiff_level, read_levels,
};
pub use tiled::{cog_bytes, halved, tiled_geotiff_bytes};
pub use windows::GeoTiffWindows;

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
    /// EPSG code of the CRS from the GeoKeys: ProjectedCSTypeGeoKey, or
    /// GeographicTypeGeoKey for a geographic model; 32767 is user-defined.
    pub epsg: Option<u16>,
    /// Projection code (ProjectionGeoKey), for user-defined CRSs.
    pub projection: Option<u16>,
    /// The GeoTIFF citation (GeoAsciiParams), if any.
    pub citation: Option<String>,
    /// A PROJ.4 definition of a CRS that no EPSG code names: a user-defined
    /// transverse Mercator read from the GeoKeys, or a reprojection's
    /// local frame.
    pub proj4: Option<String>,
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

    /// Whether both rasters are in the same coordinate reference system: the
    /// same UTM zone (whatever the datum: they differ by less than a metre),
    /// else the same definition in the coordinate library, else the same
    /// EPSG code, else (neither names one) the same citation.
    pub fn same_crs(&self, other: &GeoRaster) -> bool {
        if let (Some(a), Some(b)) = (self.utm_zone(), other.utm_zone()) {
            return a == b;
        }
        if let (Ok(a), Ok(b)) = (self.crs(), other.crs()) {
            return a == b;
        }
        match (self.epsg, other.epsg) {
            (Some(a), Some(b)) if a != 32767 && b != 32767 => a == b,
            _ => self.citation == other.citation && self.proj4 == other.proj4,
        }
    }
}

/// Writes band 1 of `r` (an elevation model) as a float GeoTIFF in `crs`,
/// atomically: north-up tiepoint and pixel scale, the CRS as its EPSG code
/// or, for a local transverse Mercator, as user-defined GeoKeys; nodata as
/// GDAL_NODATA.
pub fn write_dem_geotiff(path: &Path, r: &GeoRaster, crs: &crate::crs::Crs) -> Result<(), IoError> {
    let bytes = dem_geotiff(r, crs).map_err(|m| IoError::Write { path: path.to_path_buf(), message: m })?;
    crate::write_atomic(path, &bytes)
}

/// The GeoTIFF file [`write_dem_geotiff`] writes, in memory.
pub fn dem_geotiff_bytes(r: &GeoRaster, crs: &crate::crs::Crs) -> Result<Vec<u8>, crate::DataError> {
    dem_geotiff(r, crs).map_err(crate::DataError::from)
}

fn dem_geotiff(r: &GeoRaster, crs: &crate::crs::Crs) -> Result<Vec<u8>, String> {
    use tiff::encoder::{TiffEncoder, colortype::Gray32Float};
    let GeoKeys { dir, doubles, citation } = geokeys(crs)?;
    let band: Vec<f32> = (0..r.width as usize * r.height as usize).map(|i| r.data[i * r.bands]).collect();
    let mut buf = std::io::Cursor::new(Vec::new());
    let encode = |buf: &mut std::io::Cursor<Vec<u8>>| -> Result<(), tiff::TiffError> {
        let mut enc = TiffEncoder::new(buf)?;
        let mut img = enc.new_image::<Gray32Float>(r.width, r.height)?;
        img.encoder().write_tag(Tag::ModelPixelScaleTag, &[r.pixel[0], r.pixel[1], 0.0][..])?;
        img.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, r.origin[0], r.origin[1], 0.0][..])?;
        img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &dir[..])?;
        if !doubles.is_empty() {
            img.encoder().write_tag(Tag::GeoDoubleParamsTag, &doubles[..])?;
        }
        img.encoder().write_tag(Tag::GeoAsciiParamsTag, &*citation)?;
        if let Some(n) = r.nodata.filter(|n| n.is_finite()) {
            img.encoder().write_tag(Tag::GdalNodata, &*format!("{n}"))?;
        }
        img.write_data(&band)
    };
    encode(&mut buf).map_err(|e| e.to_string())?;
    Ok(buf.into_inner())
}

/// The mean (in f64, rows then columns) of band `b`'s valid samples
/// (finite and not nodata) over columns `xs` and rows `ys`; None when none is.
pub(crate) fn block_mean(r: &GeoRaster, b: usize, xs: std::ops::Range<u32>, ys: std::ops::Range<u32>) -> Option<f32> {
    let valid = |v: f32| v.is_finite() && r.nodata.is_none_or(|n| (v as f64 - n).abs() >= 1e-6);
    let (mut sum, mut n) = (0.0f64, 0u32);
    for y in ys {
        for x in xs.clone() {
            let v = r.get(x, y, b);
            if valid(v) {
                sum += v as f64;
                n += 1;
            }
        }
    }
    (n > 0).then(|| (sum / n as f64) as f32)
}

/// Band 1 of `r` on a grid `k` times coarser: each post the mean of the
/// valid samples of a `k`×`k` block (nodata where the block has none); a
/// partial block at the east or south edge is dropped, so that every post
/// sits at its block's centre.
pub fn decimated(r: &GeoRaster, k: u32) -> GeoRaster {
    let k = k.max(1);
    let (w, h) = ((r.width / k).max(1), (r.height / k).max(1));
    let hole = r.nodata.map_or(f32::NAN, |n| n as f32);
    let mut data = Vec::with_capacity(w as usize * h as usize);
    for j in 0..h {
        for i in 0..w {
            let (xs, ys) = (i * k..((i + 1) * k).min(r.width), j * k..((j + 1) * k).min(r.height));
            data.push(block_mean(r, 0, xs, ys).unwrap_or(hole));
        }
    }
    GeoRaster {
        width: w,
        height: h,
        bands: 1,
        data,
        pixel: [r.pixel[0] * k as f64, r.pixel[1] * k as f64],
        proj4: r.proj4.clone(),
        citation: r.citation.clone(),
        ..*r
    }
}

/// Reads a GeoTIFF; errors name the file.
pub fn load_geotiff(path: &Path) -> Result<GeoRaster, IoError> {
    let file = std::fs::File::open(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    let len = file.metadata().map_err(|source| IoError::Read { path: path.to_path_buf(), source })?.len();
    parse_geotiff(std::io::BufReader::new(file), len, path)
}

fn open_decoder<R: Read + Seek>(reader: R, path: &Path) -> Result<Decoder<R>, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let mut limits = tiff::decoder::Limits::default();
    let cap = usize::try_from(crate::limits::max_bytes()).unwrap_or(usize::MAX);
    limits.decoding_buffer_size = cap;
    limits.intermediate_buffer_size = cap.min(1 << 30);
    Ok(Decoder::new(reader).map_err(|e| fmt(format!("not a TIFF file: {e}")))?.with_limits(limits))
}

/// The size and sample layout of the decoder's current image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Layout {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) bands: usize,
    bits: u8,
    color: tiff::ColorType,
}

impl Layout {
    /// Reads the current image's size and sample layout.
    pub(crate) fn of<R: Read + Seek>(d: &mut Decoder<R>) -> Result<Self, String> {
        let (width, height) = d.dimensions().map_err(|e| e.to_string())?;
        let color = d.colortype().map_err(|e| e.to_string())?;
        let (bands, bits) = match color {
            tiff::ColorType::Gray(b) => (1, b),
            tiff::ColorType::GrayA(b) => (2, b),
            tiff::ColorType::RGB(b) => (3, b),
            tiff::ColorType::RGBA(b) => (4, b),
            tiff::ColorType::Multiband { bit_depth, num_samples } => (num_samples as usize, bit_depth),
            other => return Err(format!("unsupported sample layout {other:?}")),
        };
        if width == 0 || height == 0 || bands == 0 {
            return Err(format!("an empty image: {width}×{height} pixels of {bands} bands"));
        }
        Ok(Self { width, height, bands, bits, color })
    }

    /// width × height × bands (None past 64 bits).
    fn samples(&self) -> Option<u64> {
        (self.width as u64 * self.height as u64).checked_mul(self.bands as u64)
    }

    /// Whether `other` stores its samples as this image does.
    pub(crate) fn same_samples(&self, other: &Layout) -> bool {
        self.bands == other.bands && self.bits == other.bits && self.color == other.color
    }

    /// Checks the declared size as `claim` asks ([`Claim`]).
    pub(crate) fn check(&self, len: u64, claim: Claim) -> Result<(), String> {
        let (w, h, bands) = (self.width, self.height, self.bands);
        let what = format!("a {w}×{h} raster of {bands} band{}", if bands == 1 { "" } else { "s" });
        let samples = self.samples();
        if claim != Claim::Header && samples.is_none_or(|n| n > MAX_SAMPLES) {
            return Err(format!("{w}×{h} pixels of {bands} bands is outside the limit of {MAX_SAMPLES} samples"));
        }
        let raw = samples.and_then(|n| n.checked_mul((self.bits as u64).div_ceil(8).max(1)));
        if claim == Claim::Whole {
            crate::limits::check_claim(&what, raw, len, crate::limits::ANY_RATIO).map_err(|e| e.to_string())?;
            let decoded = raw.zip(samples).and_then(|(r, n)| r.checked_add(n.checked_mul(4)?));
            crate::limits::check_cap(&what, decoded).map_err(|e| e.to_string())?;
        } else {
            crate::limits::check_backing(&what, raw, len, crate::limits::ANY_RATIO).map_err(|e| e.to_string())?;
        }
        Ok(())
    }
}

/// What a reader will do with an image whose declared size it checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Claim {
    /// Decode it whole: at most [`MAX_SAMPLES`], backed by the file's bytes,
    /// within the memory cap.
    Whole,
    /// Read it by windows: at most [`MAX_SAMPLES`], backed by the file's bytes.
    Windows,
    /// Read its georeferencing only (the full image above an overview that
    /// is read): backed by the file's bytes.
    Header,
}

/// The raster's size, band layout and georeferencing (no samples); checks
/// the declared size as `claim` asks.
fn read_header<R: Read + Seek>(
    d: &mut Decoder<R>,
    len: u64,
    path: &Path,
    claim: Claim,
) -> Result<(GeoRaster, f64), IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let layout = Layout::of(d).map_err(fmt)?;
    layout.check(len, claim).map_err(fmt)?;
    let (w, h, bands) = (layout.width, layout.height, layout.bands);
    let keys = d.get_tag_u16_vec(Tag::GeoKeyDirectoryTag).unwrap_or_default();
    let key = |id: u16| keys.chunks_exact(4).skip(1).find(|k| k[0] == id && k[1] == 0).map(|k| k[3]);
    // the world position of pixel (i, j): x = a·i + b·j + c, y = d·i + e·j + f
    // (i, j at the pixel's corner under PixelIsArea, at its centre under PixelIsPoint)
    let affine = match d.get_tag_f64_vec(Tag::ModelTransformationTag) {
        Ok(m) => {
            if m.len() < 16 || !m.iter().all(|v| v.is_finite()) {
                return Err(fmt(format!("ModelTransformation of {} values: 16 finite values expected", m.len())));
            }
            [m[0], m[1], m[3], m[4], m[5], m[7]]
        }
        Err(_) => {
            let tie = d
                .get_tag_f64_vec(Tag::ModelTiepointTag)
                .map_err(|_| fmt("no ModelTiepoint or ModelTransformation tag: not georeferenced".into()))?;
            let scale = d
                .get_tag_f64_vec(Tag::ModelPixelScaleTag)
                .map_err(|_| fmt("no ModelPixelScale tag: not georeferenced".into()))?;
            if tie.len() < 6 || scale.len() < 2 || !tie.iter().chain(&scale).all(|v| v.is_finite()) {
                return Err(fmt(format!("unusable georeferencing: tiepoint {tie:?}, pixel scale {scale:?}")));
            }
            [scale[0], 0.0, tie[3] - tie[0] * scale[0], 0.0, -scale[1], tie[4] + tie[1] * scale[1]]
        }
    };
    let [a, b, c, dd, e, f] = affine;
    if b != 0.0 || dd != 0.0 {
        return Err(fmt(format!(
            "a rotated or sheared raster (pixel axes x = {a}·i + {b}·j, y = {dd}·i + {e}·j): only north-up rasters are read"
        )));
    }
    if !(a > 0.0 && e < 0.0) {
        return Err(fmt(format!(
            "unusable georeferencing: pixel size {a} × {} (positive east, rows from north expected)",
            -e
        )));
    }
    // RasterTypeGeoKey 2 (PixelIsPoint, as SRTM-style grids are): the
    // georeferenced position is the first pixel's centre
    let half = if key(1025) == Some(2) { 0.5 } else { 0.0 };
    let origin = [c - half * a, f - half * e];
    let nodata =
        d.get_tag_ascii_string(Tag::GdalNodata).ok().and_then(|s| s.trim().trim_end_matches('\0').parse::<f64>().ok());
    // ProjectedCSTypeGeoKey, or GeographicTypeGeoKey for a geographic model (GTModelTypeGeoKey 2)
    let geographic = key(1024) == Some(2) || (key(1024).is_none() && key(3072).is_none() && key(3074).is_none());
    let epsg = key(3072).or_else(|| key(2048).filter(|_| geographic));
    let projection = key(3074);
    let proj4 = user_defined_projection(&keys, &d.get_tag_f64_vec(Tag::GeoDoubleParamsTag).unwrap_or_default());
    // VerticalUnitsGeoKey: heights in feet come back in metres
    let z_scale = match key(4099) {
        None | Some(9001) | Some(32767) => 1.0,
        Some(9002) => 0.3048,
        Some(9003) => 1200.0 / 3937.0,
        Some(u) => {
            return Err(fmt(format!(
                "vertical unit code {u} (VerticalUnitsGeoKey) is not one of metre (9001), foot (9002), US survey foot (9003)"
            )));
        }
    };
    let citation =
        d.get_tag_ascii_string(Tag::Unknown(34737)).ok().map(|s| s.trim_end_matches(['|', '\0']).to_string());
    let r = GeoRaster {
        width: w,
        height: h,
        bands,
        data: Vec::new(),
        origin,
        pixel: [a, -e],
        nodata,
        epsg,
        projection,
        citation,
        proj4,
    };
    Ok((r, z_scale))
}

/// Reads a GeoTIFF of `len` bytes from `reader`; `path` is the file named in
/// errors. The declared raster is checked against [`MAX_SAMPLES`], against
/// what `len` bytes can hold and against the memory cap before it is decoded.
pub fn parse_geotiff<R: Read + Seek>(reader: R, len: u64, path: &Path) -> Result<GeoRaster, IoError> {
    let mut d = open_decoder(reader, path)?;
    let (r, z_scale) = read_header(&mut d, len, path, Claim::Whole)?;
    read_samples(&mut d, r, z_scale, path)
}

/// Decodes the samples of the decoder's current image into `r` (whose size
/// is that image's, already checked), heights and nodata scaled by `z_scale`.
fn read_samples<R: Read + Seek>(
    d: &mut Decoder<R>,
    mut r: GeoRaster,
    z_scale: f64,
    path: &Path,
) -> Result<GeoRaster, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let samples = r.width as u64 * r.height as u64 * r.bands as u64;
    let data = to_f32(d.read_image().map_err(|e| fmt(format!("cannot decode the samples: {e}")))?).map_err(fmt)?;
    if data.len() as u64 != samples {
        return Err(fmt(format!("{} samples decoded, {samples} declared", data.len())));
    }
    r.data = data;
    scale_heights(&mut r.data, z_scale);
    r.nodata = scaled_nodata(r.nodata, z_scale);
    Ok(r)
}

/// Heights read in the file's vertical unit, in metres (`z_scale` metres a unit).
fn scale_heights(data: &mut [f32], z_scale: f64) {
    if z_scale != 1.0 {
        data.iter_mut().for_each(|v| *v = (*v as f64 * z_scale) as f32);
    }
}

/// The nodata value as [`scale_heights`] converts the samples, so that it
/// still matches them exactly.
fn scaled_nodata(nodata: Option<f64>, z_scale: f64) -> Option<f64> {
    if z_scale == 1.0 { nodata } else { nodata.map(|n| ((n as f32) as f64 * z_scale) as f32 as f64) }
}

fn to_f32(r: DecodingResult) -> Result<Vec<f32>, String> {
    Ok(match r {
        DecodingResult::U8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::U32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        _ => return Err("unsupported sample format".into()),
    })
}

/// The 2nd and 98th percentile of a band's finite samples (the contrast
/// stretch of imagery), from at most `1 << 20` samples taken evenly.
pub fn stretch_range(samples: impl Iterator<Item = f32>) -> Option<(f32, f32)> {
    let mut v: Vec<f32> = samples.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let (lo, hi) = (v[v.len() * 2 / 100], v[(v.len() * 98 / 100).min(v.len() - 1)]);
    Some((lo, if hi > lo { hi } else { lo + 1.0 }))
}

/// Whether `path` names PNG or JPEG imagery (georeferenced by a world file).
pub fn is_world_image(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| {
        let e = e.to_ascii_lowercase();
        e == "png" || e == "jpg" || e == "jpeg"
    })
}

/// The world file beside `image`: `name.pgw` / `name.jgw` (first and last
/// letter of the extension + w), `name.pngw` / `name.jpgw`, or `name.wld`.
pub fn world_file_for(image: &Path) -> Option<std::path::PathBuf> {
    let ext = image.extension()?.to_str()?.to_ascii_lowercase();
    let short = format!("{}{}w", ext.chars().next()?, ext.chars().last()?);
    [short, format!("{ext}w"), "wld".to_string()]
        .into_iter()
        .flat_map(|e| [image.with_extension(&e), image.with_extension(e.to_ascii_uppercase())])
        .find(|p| p.is_file())
}

/// Parses an ESRI world file (six numbers, one per line: x pixel size, two
/// rotation terms, negative y pixel size, x and y of the upper-left pixel's
/// centre) into the raster's north-west corner and pixel size. Rotated
/// rasters are refused.
pub fn parse_world_file(text: &str, path: &Path) -> Result<([f64; 2], [f64; 2]), IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let lines: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    if lines.len() != 6 {
        return Err(fmt(format!("a world file has 6 numbers, one per line; this one has {} lines", lines.len())));
    }
    let mut v = [0.0f64; 6];
    for (k, l) in lines.iter().enumerate() {
        v[k] = l
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| fmt(format!("line {}: '{l}' is not a finite number", k + 1)))?;
    }
    let [a, d, b, e, c, f] = v;
    if b != 0.0 || d != 0.0 {
        return Err(fmt(format!("line 2–3: rotation terms {d}, {b}: rotated rasters are not supported")));
    }
    if a <= 0.0 || e >= 0.0 {
        return Err(fmt(format!("pixel size {a} × {e}: x must be positive and y negative (rows run north to south)")));
    }
    Ok(([c - a / 2.0, f - e / 2.0], [a, -e]))
}

/// PNG or JPEG imagery with its world file: three bands (red, green, blue,
/// 0–255), CRS unknown (world files carry none).
pub fn load_world_image(path: &Path) -> Result<GeoRaster, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let world = world_file_for(path)
        .ok_or_else(|| fmt("no world file beside it (.pgw/.jgw, .pngw/.jpgw or .wld): not georeferenced".into()))?;
    let text = std::fs::read_to_string(&world).map_err(|source| IoError::Read { path: world.clone(), source })?;
    let (origin, pixel) = parse_world_file(&text, &world)?;
    let img = crate::load_image(path, hitex_core::texture::ColorSpace::Srgb)?;
    let data = img.bytes().chunks_exact(4).flat_map(|p| [p[0] as f32, p[1] as f32, p[2] as f32]).collect();
    Ok(GeoRaster {
        width: img.width(),
        height: img.height(),
        bands: 3,
        data,
        origin,
        pixel,
        nodata: None,
        epsg: None,
        projection: None,
        citation: None,
        proj4: None,
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
        // kept in the repository (the same files as ../shared/data/terrain)
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/olinda").join(name)
    }

    #[test]
    fn olinda_pair_is_co_registered() {
        let (dp, ip) = (data("olinda_dem_utm25s.tif"), data("L7_ETMs.tif"));
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
    fn decimation_averages_blocks_and_keeps_their_centres() {
        let r = GeoRaster {
            width: 5,
            height: 4,
            bands: 1,
            data: (0..20).map(|i| if i == 6 { -9999.0 } else { i as f32 }).collect(),
            origin: [100.0, 50.0],
            pixel: [10.0, 5.0],
            nodata: Some(-9999.0),
            epsg: Some(32632),
            projection: None,
            citation: None,
            proj4: None,
        };
        let d = decimated(&r, 2);
        // the fifth column is a partial block: dropped
        assert_eq!((d.width, d.height, d.pixel, d.origin), (2, 2, [20.0, 10.0], [100.0, 50.0]));
        // block (0, 0): 0, 1, 5 and the hole at 6
        assert_eq!(d.data, vec![2.0, (2.0 + 3.0 + 7.0 + 8.0) / 4.0, (10.0 + 11.0 + 15.0 + 16.0) / 4.0, 15.0]);
        assert_eq!(d.epsg, Some(32632));
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
            proj4: None,
        };
        assert_eq!(fill_holes(&mut r), 2);
        assert!((r.data[4] - 1.5).abs() < 1e-6, "{}", r.data[4]);
        assert!((r.data[6] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn non_tiff_and_ungeoreferenced_files_are_errors() {
        let dir = crate::test_dir::TestDir::fresh("geotiff");
        let p = dir.join("x.tif");
        std::fs::write(&p, b"II*\0garbage").unwrap();
        assert!(load_geotiff(&p).unwrap_err().to_string().contains("x.tif"));
        let png = dir.join("y.tif");
        crate::save_png(&png, 2, 2, &[0; 16]).unwrap();
        assert!(load_geotiff(&png).is_err());
        assert!(load_geotiff(&dir.join("missing.tif")).is_err());
    }

    #[test]
    fn stretch_ranges_are_the_2nd_and_98th_percentiles() {
        // 2nd and 98th percentiles; non-finite samples ignored; a flat band still spans 1
        let ramp = (0..100).map(|i| i as f32).chain([f32::NAN, f32::INFINITY]);
        assert_eq!(stretch_range(ramp), Some((2.0, 98.0)));
        assert_eq!(stretch_range([5.0f32; 10].into_iter()), Some((5.0, 6.0)));
        assert_eq!(stretch_range([f32::NAN].into_iter()), None);
    }

    #[test]
    fn world_files_are_read_and_bad_ones_refused() {
        let p = Path::new("x.pgw");
        let (o, px) = parse_world_file("28.5\n0\n0\n-28.5\n290014.25\n9120985.75\n", p).unwrap();
        assert_eq!(o, [290000.0, 9121000.0]);
        assert_eq!(px, [28.5, 28.5]);
        for bad in [
            "28.5\n0\n0\n-28.5\n1\n",
            "28.5\n0\n0\n-28.5\n1\nnorth\n",
            "28.5\n0.1\n0\n-28.5\n1\n2\n",
            "28.5\n0\n0\n28.5\n1\n2\n",
            "0\n0\n0\n-1\n1\n2\n",
            "1\n0\n0\n-1\ninf\n2\n",
        ] {
            let e = parse_world_file(bad, p).unwrap_err().to_string();
            assert!(e.contains("x.pgw"), "{e}");
        }
        // an image and its world file, found by name
        let dir = crate::test_dir::TestDir::fresh("world");
        let png = dir.join("ortho.png");
        crate::save_png(&png, 2, 1, &[255, 0, 0, 255, 0, 0, 255, 255]).unwrap();
        assert!(load_world_image(&png).unwrap_err().to_string().contains("no world file"));
        std::fs::write(dir.join("ortho.pgw"), "10\n0\n0\n-10\n105\n195\n").unwrap();
        let r = load_world_image(&png).unwrap();
        assert_eq!((r.width, r.height, r.bands, r.origin, r.pixel), (2, 1, 3, [100.0, 200.0], [10.0, 10.0]));
        assert_eq!(&r.data[..6], &[255.0, 0.0, 0.0, 0.0, 0.0, 255.0]);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
