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

/// GeoKeys of a user-defined projected CRS (ProjectedCSTypeGeoKey and
/// ProjectionGeoKey 32767, the method in ProjCoordTransGeoKey) as a PROJ.4
/// definition, for the methods elevation products use: transverse Mercator
/// (1), Mercator (7), Lambert conformal conic with two standard parallels
/// (8) and one (9), Lambert azimuthal equal-area (10), Albers equal-area
/// (11) and polar stereographic (15, variants A and B). The datum is that
/// of GeographicTypeGeoKey (an EPSG code; WGS 84 when absent), angles in
/// degrees, lengths in metres, feet or US survey feet
/// (ProjLinearUnitsGeoKey). Parameter keys as GDAL writes them, with the
/// natural-origin keys standing in for missing false-origin ones. Other
/// methods and units give None: the CRS is then named by its citation only.
fn user_defined_projection(keys: &[u16], doubles: &[f64]) -> Option<String> {
    let entry = |id: u16| keys.chunks_exact(4).skip(1).find(|k| k[0] == id);
    let short = |id: u16| entry(id).filter(|k| k[1] == 0).map(|k| k[3]);
    let double = |id: u16| {
        entry(id)
            .filter(|k| k[1] == 34736 && k[2] == 1)
            .and_then(|k| doubles.get(k[3] as usize).copied())
            .filter(|v| v.is_finite())
    };
    if short(3072) != Some(32767) || short(3074) != Some(32767) {
        return None;
    }
    // angles in degrees only (GeogAngularUnitsGeoKey 9102)
    if !matches!(short(2054), None | Some(9102)) {
        return None;
    }
    // the datum of the geographic CRS: its definition without the method
    let datum = match short(2048) {
        None | Some(4326) => "+datum=WGS84".to_string(),
        Some(code) => {
            let def = crs_definitions::from_code(code)?.proj4;
            let rest = def.strip_prefix("+proj=longlat ")?;
            rest.split_whitespace().filter(|p| !matches!(*p, "+no_defs" | "+type=crs")).collect::<Vec<_>>().join(" ")
        }
    };
    let (units, metres) = match short(3076) {
        None | Some(9001) => ("m", 1.0),
        Some(9002) => ("ft", 0.3048),
        Some(9003) => ("us-ft", 1200.0 / 3937.0),
        Some(_) => return None,
    };
    // a key, else its stand-in
    let either = |a: u16, b: u16| double(a).or_else(|| double(b));
    let lat_ok = |v: f64| v.abs() <= 90.0;
    // false easting and northing in metres (PROJ's +x_0, +y_0 are metres whatever +units)
    let offsets = |e: u16, n: u16| (either(e, 3082).unwrap_or(0.0) * metres, either(n, 3083).unwrap_or(0.0) * metres);
    let (method, (fe, fn_)) = match short(3075)? {
        1 => {
            let (lon, lat, k) = (double(3080)?, double(3081)?, double(3092).unwrap_or(1.0));
            if !(lat_ok(lat) && lat.abs() < 90.0 && k > 0.0) {
                return None;
            }
            let (fe, fn_) = offsets(3082, 3083);
            if datum == "+datum=WGS84" && units == "m" {
                // the form a local metric frame is written in (read back equal)
                return Some(crate::crs::tm_definition(lon, lat, k, fe, fn_));
            }
            (format!("+proj=tmerc +lat_0={lat} +lon_0={lon} +k={k}"), (fe, fn_))
        }
        7 => {
            let lon = double(3080).or_else(|| double(3088))?;
            // Mercator (2SP) by its standard parallel, (1SP) by its scale
            let m = match double(3078) {
                Some(ts) if lat_ok(ts) && ts.abs() < 90.0 => format!("+proj=merc +lon_0={lon} +lat_ts={ts}"),
                _ => format!("+proj=merc +lon_0={lon} +k={}", double(3092).unwrap_or(1.0)),
            };
            (m, offsets(3082, 3083))
        }
        8 | 11 => {
            let (p1, p2) = (double(3078)?, double(3079)?);
            let (lat0, lon0) = (either(3085, 3081)?, either(3084, 3080)?);
            if ![p1, p2, lat0].iter().all(|v| lat_ok(*v)) {
                return None;
            }
            let name = if short(3075) == Some(8) { "lcc" } else { "aea" };
            (format!("+proj={name} +lat_1={p1} +lat_2={p2} +lat_0={lat0} +lon_0={lon0}"), offsets(3086, 3087))
        }
        9 => {
            let (lat0, lon0, k) = (double(3081)?, double(3080)?, double(3092).unwrap_or(1.0));
            if !(lat_ok(lat0) && lat0 != 0.0 && k > 0.0) {
                return None;
            }
            (format!("+proj=lcc +lat_1={lat0} +lat_0={lat0} +lon_0={lon0} +k={k}"), offsets(3082, 3083))
        }
        10 => {
            let (lat0, lon0) = (either(3089, 3081)?, either(3088, 3080)?);
            if !lat_ok(lat0) {
                return None;
            }
            (format!("+proj=laea +lat_0={lat0} +lon_0={lon0}"), offsets(3082, 3083))
        }
        15 => {
            let lat = double(3081)?;
            let lon0 = either(3095, 3080)?;
            if !(lat_ok(lat) && lat != 0.0) {
                return None;
            }
            let pole = if lat > 0.0 { 90 } else { -90 };
            // variant A: origin at the pole, a scale there; variant B: the
            // latitude of true scale
            let m = if lat.abs() == 90.0 {
                format!("+proj=stere +lat_0={pole} +lon_0={lon0} +k={}", double(3092).unwrap_or(1.0))
            } else {
                format!("+proj=stere +lat_0={pole} +lat_ts={lat} +lon_0={lon0}")
            };
            (m, offsets(3082, 3083))
        }
        _ => return None,
    };
    Some(format!("{method} +x_0={fe} +y_0={fn_} +units={units} {datum} +no_defs"))
}

/// Geographic CRSs whose datum a user-defined projection may be written
/// on (GeographicTypeGeoKey): WGS 84, NAD83, ETRS89, RGF93, GDA94,
/// GDA2020, JGD2000, NZGD2000, OSGB 1936, NAD27-era Clarke 1866 (JAD69),
/// Makassar (Bessel).
const GEOGRAPHIC_CODES: [u16; 11] = [4326, 4269, 4258, 4171, 4283, 7844, 4612, 4167, 4277, 4242, 4257];

/// A GeoKey and its value in the directory.
type ShortKey = (u16, u16);
/// A GeoKey and its value in GeoDoubleParams.
type DoubleKey = (u16, f64);

/// The GeoKeys (short keys, double keys) that describe a PROJ.4 definition
/// of one of the projections [`user_defined_projection`] reads, so that a
/// DEM written in it reads back in the same CRS; None for any other.
fn user_defined_keys(def: &str) -> Option<(Vec<ShortKey>, Vec<DoubleKey>)> {
    let mut p: std::collections::BTreeMap<&str, &str> = std::collections::BTreeMap::new();
    let mut datum = Vec::new();
    for part in def.split_whitespace() {
        let (k, v) = part.strip_prefix('+')?.split_once('=').unwrap_or((part.trim_start_matches('+'), ""));
        match k {
            "datum" | "ellps" | "towgs84" | "a" | "b" | "rf" | "nadgrids" | "pm" => datum.push(part),
            "no_defs" | "type" => {}
            _ => {
                p.insert(k, v);
            }
        }
    }
    let datum = datum.join(" ");
    let geog = GEOGRAPHIC_CODES.into_iter().find(|&c| {
        let d = crs_definitions::from_code(c).map(|d| d.proj4).unwrap_or("");
        let rest: Vec<&str> = d
            .strip_prefix("+proj=longlat ")
            .unwrap_or("")
            .split_whitespace()
            .filter(|x| !matches!(*x, "+no_defs" | "+type=crs"))
            .collect();
        rest.join(" ") == datum
    })?;
    let num = |k: &str| p.get(k).and_then(|v| v.parse::<f64>().ok()).filter(|v| v.is_finite());
    let (unit, metres) = match p.get("units").copied() {
        None | Some("m") => (9001, 1.0),
        Some("ft") => (9002, 0.3048),
        Some("us-ft") => (9003, 1200.0 / 3937.0),
        Some(_) => return None,
    };
    let (lon0, lat0) = (num("lon_0").unwrap_or(0.0), num("lat_0").unwrap_or(0.0));
    let (fe, fn_) = (num("x_0").unwrap_or(0.0) / metres, num("y_0").unwrap_or(0.0) / metres);
    let k = num("k").or_else(|| num("k0")).unwrap_or(1.0);
    let known = |keys: &[&str]| p.keys().all(|k| keys.contains(k));
    let (method, mut d): (u16, Vec<(u16, f64)>) = match *p.get("proj")? {
        "tmerc" if known(&["proj", "lon_0", "lat_0", "k", "k0", "x_0", "y_0", "units"]) => {
            (1, vec![(3080, lon0), (3081, lat0), (3092, k), (3082, fe), (3083, fn_)])
        }
        "merc" if known(&["proj", "lon_0", "lat_ts", "k", "k0", "x_0", "y_0", "units"]) => match num("lat_ts") {
            Some(ts) => (7, vec![(3080, lon0), (3078, ts), (3082, fe), (3083, fn_)]),
            None => (7, vec![(3080, lon0), (3092, k), (3082, fe), (3083, fn_)]),
        },
        m @ ("lcc" | "aea")
            if known(&["proj", "lon_0", "lat_0", "lat_1", "lat_2", "k", "k0", "x_0", "y_0", "units"]) =>
        {
            let p1 = num("lat_1")?;
            match num("lat_2") {
                Some(p2) if m == "aea" || p2 != p1 => (
                    if m == "lcc" { 8 } else { 11 },
                    vec![(3078, p1), (3079, p2), (3085, lat0), (3084, lon0), (3086, fe), (3087, fn_)],
                ),
                // one standard parallel: the latitude of origin (1SP)
                _ if m == "lcc" && p1 == lat0 => {
                    (9, vec![(3081, lat0), (3080, lon0), (3092, k), (3082, fe), (3083, fn_)])
                }
                _ => return None,
            }
        }
        "laea" if known(&["proj", "lon_0", "lat_0", "x_0", "y_0", "units"]) => {
            (10, vec![(3089, lat0), (3088, lon0), (3082, fe), (3083, fn_)])
        }
        "stere"
            if known(&["proj", "lon_0", "lat_0", "lat_ts", "k", "k0", "x_0", "y_0", "units"]) && lat0.abs() == 90.0 =>
        {
            match num("lat_ts").filter(|t| t.abs() != 90.0) {
                Some(ts) if ts.signum() == lat0.signum() => {
                    (15, vec![(3081, ts), (3095, lon0), (3082, fe), (3083, fn_)])
                }
                Some(_) => return None,
                None => (15, vec![(3081, lat0), (3095, lon0), (3092, k), (3082, fe), (3083, fn_)]),
            }
        }
        _ => return None,
    };
    d.sort_by_key(|e| e.0);
    let shorts = vec![(2048, geog), (3072, 32767), (3074, 32767), (3075, method), (3076, unit)];
    Some((shorts, d))
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
    let werr = |m: String| m;
    let mut keys: Vec<u16> = Vec::new();
    let mut doubles: Vec<f64> = Vec::new();
    let geographic = crs.is_geographic();
    // the CRS's name as the citation (GTCitationGeoKey in GeoAsciiParams)
    let citation: String = crs.name().replace('°', " deg").chars().filter(|c| c.is_ascii() && *c != '|').collect();
    let citation = format!("{citation}|");
    let cite_len = u16::try_from(citation.len()).map_err(|_| werr("the CRS's name is too long".into()))?;
    keys.extend_from_slice(&[1024, 0, 1, if geographic { 2 } else { 1 }, 1025, 0, 1, 1, 1026, 34737, cite_len, 0]);
    match crs.epsg() {
        Some(c) => keys.extend_from_slice(&[if geographic { 2048 } else { 3072 }, 0, 1, c]),
        None => {
            let Some((shorts, params)) = user_defined_keys(crs.definition()) else {
                return Err(werr(format!(
                    "{} has no EPSG code and is not a projection GeoKeys can describe (transverse Mercator, \
                     Mercator, Lambert conformal conic, Lambert azimuthal equal-area, Albers or polar \
                     stereographic on the datum of a geographic EPSG code, in metres or feet)",
                    crs.name()
                )));
            };
            // keys in ascending order, as the directory requires
            let mut all: Vec<(u16, Option<u16>, f64)> = shorts.iter().map(|&(id, v)| (id, Some(v), 0.0)).collect();
            all.extend(params.iter().map(|&(id, v)| (id, None, v)));
            all.sort_by_key(|e| e.0);
            for (id, short, v) in all {
                match short {
                    Some(x) => keys.extend_from_slice(&[id, 0, 1, x]),
                    None => {
                        keys.extend_from_slice(&[id, 34736, 1, doubles.len() as u16]);
                        doubles.push(v);
                    }
                }
            }
        }
    }
    let mut dir = vec![1u16, 1, 0, (keys.len() / 4) as u16];
    dir.extend_from_slice(&keys);
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
    encode(&mut buf).map_err(|e| werr(e.to_string()))?;
    Ok(buf.into_inner())
}

/// Band 1 of `r` on a grid `k` times coarser: each post the mean of the
/// valid samples of a `k`×`k` block (nodata where the block has none); a
/// partial block at the east or south edge is dropped, so that every post
/// sits at its block's centre.
pub fn decimated(r: &GeoRaster, k: u32) -> GeoRaster {
    let k = k.max(1);
    let (w, h) = ((r.width / k).max(1), (r.height / k).max(1));
    let valid = |v: f32| v.is_finite() && r.nodata.is_none_or(|n| (v as f64 - n).abs() >= 1e-6);
    let hole = r.nodata.map_or(f32::NAN, |n| n as f32);
    let mut data = Vec::with_capacity(w as usize * h as usize);
    for j in 0..h {
        for i in 0..w {
            let (mut sum, mut n) = (0.0f64, 0u32);
            for y in j * k..((j + 1) * k).min(r.height) {
                for x in i * k..((i + 1) * k).min(r.width) {
                    let v = r.get(x, y, 0);
                    if valid(v) {
                        sum += v as f64;
                        n += 1;
                    }
                }
            }
            data.push(if n > 0 { (sum / n as f64) as f32 } else { hole });
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

/// The raster's size, band layout and georeferencing (no samples); checks
/// the declared size against the file's `len` bytes, and, when `whole`, the
/// decoded raster against the memory cap.
fn read_header<R: Read + Seek>(
    d: &mut Decoder<R>,
    len: u64,
    path: &Path,
    whole: bool,
) -> Result<(GeoRaster, f64), IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
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
    if whole {
        crate::limits::check_claim(&what, Some(raw), len, crate::limits::ANY_RATIO).map_err(|e| fmt(e.to_string()))?;
        crate::limits::check_cap(&what, Some(raw + samples * 4)).map_err(|e| fmt(e.to_string()))?;
    } else {
        // read by windows: only the claim against the file's bytes matters
        crate::limits::check_backing(&what, Some(raw), len, crate::limits::ANY_RATIO)
            .map_err(|e| fmt(e.to_string()))?;
    }
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
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let mut d = open_decoder(reader, path)?;
    let (mut r, z_scale) = read_header(&mut d, len, path, true)?;
    let samples = r.width as u64 * r.height as u64 * r.bands as u64;
    let data = to_f32(d.read_image().map_err(|e| fmt(format!("cannot decode the samples: {e}")))?).map_err(fmt)?;
    if data.len() as u64 != samples {
        return Err(fmt(format!("{} samples decoded, {samples} declared", data.len())));
    }
    r.data = data;
    if z_scale != 1.0 {
        r.data.iter_mut().for_each(|v| *v = (*v as f64 * z_scale) as f32);
        // the same conversion as the samples', so that nodata still matches them exactly
        r.nodata = r.nodata.map(|n| ((n as f32) as f64 * z_scale) as f32 as f64);
    }
    Ok(r)
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

/// A GeoTIFF read by windows: only the strips or tiles a window touches are
/// decoded (a few are kept, within [`GeoTiffWindows::CACHE_BYTES`]), so
/// sources far larger than memory can be processed.
pub struct GeoTiffWindows {
    /// Size, bands and georeferencing (`data` is empty).
    pub header: GeoRaster,
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
        let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
        let file = std::fs::File::open(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
        let len = file.metadata().map_err(|source| IoError::Read { path: path.to_path_buf(), source })?.len();
        let mut d = open_decoder(std::io::BufReader::new(file), path)?;
        let (header, _) = read_header(&mut d, len, path, false)?;
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
    /// raster), bands interleaved, rows north to south.
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
        Ok(out)
    }
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

    /// A GeoKey directory of a user-defined projection: short keys, then
    /// double keys (values in GeoDoubleParams order).
    fn user_keys(shorts: &[(u16, u16)], doubles: &[(u16, f64)]) -> (Vec<u16>, Vec<f64>) {
        let mut k = vec![1u16, 1, 0, (shorts.len() + doubles.len() + 2) as u16, 3072, 0, 1, 32767, 3074, 0, 1, 32767];
        for (id, v) in shorts {
            k.extend_from_slice(&[*id, 0, 1, *v]);
        }
        for (i, (id, _)) in doubles.iter().enumerate() {
            k.extend_from_slice(&[*id, 34736, 1, i as u16]);
        }
        (k, doubles.iter().map(|d| d.1).collect())
    }

    /// The projected coordinates of `lon_lat` (in the geographic CRS of
    /// EPSG code `geog`) under the user-defined projection of the keys.
    fn project(shorts: &[(u16, u16)], doubles: &[(u16, f64)], geog: u16, lon_lat: [f64; 2]) -> [f64; 2] {
        let (k, d) = user_keys(shorts, doubles);
        let def = user_defined_projection(&k, &d).expect("a supported projection");
        let crs = crate::crs::Crs::from_definition(&def, "test").unwrap();
        crate::crs::Crs::from_epsg(geog).unwrap().point(&crs, lon_lat)
    }

    /// The worked examples of EPSG Guidance Note 7-2 (coordinate conversions
    /// and transformations), entered as the GeoKeys a user-defined
    /// projection carries: every method the reader maps, on the ellipsoids,
    /// units and parameter keys of those examples.
    #[test]
    fn user_defined_projections_match_the_epsg_worked_examples() {
        let dms = |d: f64, m: f64, s: f64| d.signum() * (d.abs() + m / 60.0 + s / 3600.0);
        let close = |p: [f64; 2], e: [f64; 2], tol: f64| {
            assert!((p[0] - e[0]).abs() < tol && (p[1] - e[1]).abs() < tol, "{p:?}, expected {e:?}");
        };
        // Lambert conic conformal (2SP), NAD27 / Texas South Central on Clarke
        // 1866 (here through JAD69's Clarke 1866, no datum shift), US survey feet
        let p = project(
            &[(3075, 8), (2048, 4242), (3076, 9003)],
            &[
                (3078, dms(28.0, 23.0, 0.0)),
                (3079, dms(30.0, 17.0, 0.0)),
                (3085, dms(27.0, 50.0, 0.0)),
                (3084, -99.0),
                (3086, 2_000_000.0),
                (3087, 0.0),
            ],
            4242,
            [-96.0, 28.5],
        );
        close(p, [2_963_503.91, 254_759.80], 0.05);
        // Lambert conic conformal (1SP), JAD69 / Jamaica National Grid
        let p = project(
            &[(3075, 9), (2048, 4242)],
            &[(3081, 18.0), (3080, -77.0), (3092, 1.0), (3082, 250_000.0), (3083, 150_000.0)],
            4242,
            [dms(-76.0, 56.0, 37.26), dms(17.0, 55.0, 55.80)],
        );
        close(p, [255_966.58, 142_493.51], 0.02);
        // Lambert azimuthal equal area, ETRS89 / LAEA Europe (GRS 1980)
        let p = project(
            &[(3075, 10), (2048, 4258)],
            &[(3089, 52.0), (3088, 10.0), (3082, 4_321_000.0), (3083, 3_210_000.0)],
            4258,
            [5.0, 50.0],
        );
        close(p, [3_962_799.45, 2_999_718.85], 0.02);
        // Mercator (1SP), Makassar / NEIEZ (Bessel 1841)
        let p = project(
            &[(3075, 7), (2048, 4257)],
            &[(3080, 110.0), (3092, 0.997), (3082, 3_900_000.0), (3083, 900_000.0)],
            4257,
            [120.0, -3.0],
        );
        close(p, [5_009_726.58, 569_150.82], 0.02);
        // polar stereographic (variant A), WGS 84 / UPS North
        let p = project(
            &[(3075, 15), (2048, 4326)],
            &[(3081, 90.0), (3095, 0.0), (3092, 0.994), (3082, 2_000_000.0), (3083, 2_000_000.0)],
            4326,
            [44.0, 73.0],
        );
        close(p, [3_320_416.75, 632_668.43], 0.02);
        // polar stereographic (variant B), WGS 84 / Australian Antarctic Polar Stereographic
        let p = project(
            &[(3075, 15)],
            &[(3081, -71.0), (3095, 70.0), (3082, 6_000_000.0), (3083, 6_000_000.0)],
            4326,
            [120.0, -75.0],
        );
        close(p, [7_255_380.79, 7_053_389.56], 0.02);
        // Albers equal area: the same point as EPSG:5070 (NAD83 / Conus Albers) puts it
        let keys = [(3078, 29.5), (3079, 45.5), (3085, 23.0), (3084, -96.0), (3086, 0.0), (3087, 0.0)];
        let p = project(&[(3075, 11), (2048, 4269)], &keys, 4269, [-100.0, 40.0]);
        let q =
            crate::crs::Crs::from_epsg(4269).unwrap().point(&crate::crs::Crs::from_epsg(5070).unwrap(), [-100.0, 40.0]);
        close(p, q, 1e-6);
        // transverse Mercator off WGS 84: OSGB 1936 / British National Grid
        let p = project(
            &[(3075, 1), (2048, 4277)],
            &[(3081, 49.0), (3080, -2.0), (3092, 0.999_601_271_7), (3082, 400_000.0), (3083, -100_000.0)],
            4277,
            [0.5, 50.5],
        );
        close(p, [577_274.99, 69_740.50], 0.02);
    }

    #[test]
    fn user_defined_projections_outside_the_methods_read_are_left_unnamed() {
        // oblique Mercator (3): not mapped
        let (k, d) = user_keys(&[(3075, 3)], &[(3081, 4.0), (3080, 115.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        // grads (9105) as the angular unit
        let (k, d) = user_keys(&[(3075, 9), (2054, 9105)], &[(3081, 52.0), (3080, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        // a linear unit other than metre and feet (9004: chain, say)
        let (k, d) = user_keys(&[(3075, 9), (3076, 9004)], &[(3081, 52.0), (3080, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        // a missing parameter, a latitude past the pole
        let (k, d) = user_keys(&[(3075, 8)], &[(3078, 30.0), (3085, 20.0), (3084, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        let (k, d) = user_keys(&[(3075, 10)], &[(3081, 95.0), (3080, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
        // an unknown geographic CRS
        let (k, d) = user_keys(&[(3075, 9), (2048, 1)], &[(3081, 52.0), (3080, 0.0)]);
        assert_eq!(user_defined_projection(&k, &d), None);
    }

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
