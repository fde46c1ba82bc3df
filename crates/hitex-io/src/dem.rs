//! Elevation models in the formats users have: GeoTIFF, SRTM `.hgt`, ESRI
//! ASCII grid `.asc`, numpy `.npy` and `.npz` (with `dx`, `dy`, `xmin`,
//! `xmax`, `ymin`, `ymax` scalars when present). All come back as a
//! one-band [`GeoRaster`]; declared sizes are checked against the data first.

use crate::geotiff::{GeoRaster, MAX_SAMPLES, load_geotiff};
use crate::limits::DEFLATE_RATIO;
use crate::{DataError, IoError};
use std::io::Read;
use std::path::Path;

/// Reads an elevation model, choosing the format by extension.
pub fn load_elevation(path: &Path) -> Result<GeoRaster, IoError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    if ext == "tif" || ext == "tiff" {
        return load_geotiff(path);
    }
    let meta = std::fs::metadata(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    if meta.len() > 4 * MAX_SAMPLES {
        let message = format!("file of {} bytes is beyond the size limit", meta.len());
        return Err(IoError::Format { path: path.to_path_buf(), message });
    }
    let bytes = std::fs::read(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    parse_elevation(&bytes, path)
}

/// What looks wrong with a raster read as an elevation model, though it is
/// readable: more than one band (heights are taken from band 1), or bands of
/// whole numbers in 0–255 (colour imagery, not heights). One line each.
pub fn elevation_warnings(r: &GeoRaster) -> Vec<String> {
    let mut w = Vec::new();
    if r.bands > 1 {
        let bytes = r.data.iter().all(|&x| x.fract() == 0.0 && (0.0..=255.0).contains(&x));
        w.push(format!(
            "{} bands{}: an elevation model has one; heights are taken from band 1",
            r.bands,
            if bytes { " of whole numbers in 0–255 (this looks like colour imagery)" } else { "" }
        ));
    }
    // a bare array (.npy, an .npz without x/y) says nothing of where its
    // posts are: meshed one metre apart, which is said
    let bare = r.epsg.is_none()
        && r.projection.is_none()
        && r.proj4.is_none()
        && r.pixel == [1.0, 1.0]
        && r.origin == [0.0, r.height as f64];
    if bare {
        w.push(
            "no georeferencing (a bare array): posts are taken 1 m apart, heights in metres; \
             a GeoTIFF, .hgt, .asc or an .npz with x/y coordinates places them"
                .into(),
        );
    }
    w
}

/// Parses an elevation model held in memory, choosing the format by the
/// extension of `path` (which is also the file named in errors; an `.hgt`
/// file's name gives its corner).
pub fn parse_elevation(bytes: &[u8], path: &Path) -> Result<GeoRaster, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    match ext.as_str() {
        "tif" | "tiff" => crate::geotiff::parse_geotiff(std::io::Cursor::new(bytes), bytes.len() as u64, path),
        "hgt" => hgt(bytes, name).map_err(fmt),
        "asc" => ascii_grid(&String::from_utf8_lossy(bytes)).map_err(fmt),
        "npy" => npy(bytes).map(|(w, h, data)| plain(w, h, data)).map_err(fmt),
        "npz" => npz(bytes).map_err(fmt),
        _ => Err(fmt("unknown elevation format (expected .tif, .hgt, .asc, .npy or .npz)".into())),
    }
}

fn plain(w: u32, h: u32, data: Vec<f32>) -> GeoRaster {
    GeoRaster {
        width: w,
        height: h,
        bands: 1,
        data,
        origin: [0.0, h as f64],
        pixel: [1.0, 1.0],
        nodata: None,
        epsg: None,
        projection: None,
        citation: None,
        proj4: None,
    }
}

/// SRTM: big-endian i16 squares of 1201² (3″) or 3601² (1″) posts; the file
/// name (e.g. `N34W107`) gives the south-west corner; −32768 marks voids.
pub fn parse_hgt(bytes: &[u8], name: &str) -> Result<GeoRaster, DataError> {
    hgt(bytes, name).map_err(DataError::from)
}

fn hgt(bytes: &[u8], name: &str) -> Result<GeoRaster, String> {
    let n = match bytes.len() {
        l if l == 1201 * 1201 * 2 => 1201,
        l if l == 3601 * 3601 * 2 => 3601,
        l => return Err(format!("{l} bytes is neither a 1201² nor a 3601² SRTM tile")),
    };
    let parse = |s: &str| -> Option<(f64, f64)> {
        let s = s.to_ascii_uppercase();
        let lat: f64 = s.get(1..3)?.parse().ok()?;
        let lon: f64 = s.get(4..7)?.parse().ok()?;
        let lat = if s.starts_with('S') {
            -lat
        } else if s.starts_with('N') {
            lat
        } else {
            return None;
        };
        let lon = match s.get(3..4)? {
            "W" => -lon,
            "E" => lon,
            _ => return None,
        };
        Some((lat, lon))
    };
    let (lat, lon) = parse(name).ok_or_else(|| format!("file name '{name}' is not of the form N34W107"))?;
    let data: Vec<f32> = bytes.chunks_exact(2).map(|c| i16::from_be_bytes([c[0], c[1]]) as f32).collect();
    let step = 1.0 / (n - 1) as f64;
    Ok(GeoRaster {
        width: n as u32,
        height: n as u32,
        bands: 1,
        data,
        origin: [lon - step / 2.0, lat + 1.0 + step / 2.0],
        pixel: [step, step],
        nodata: Some(-32768.0),
        epsg: Some(4326),
        projection: None,
        citation: Some("WGS 84 geographic".into()),
        proj4: None,
    })
}

/// ESRI ASCII grid: `ncols`, `nrows`, `xllcorner|xllcenter`,
/// `yllcorner|yllcenter`, `cellsize`, optional `NODATA_value`, then rows from north.
pub fn parse_ascii_grid(text: &str) -> Result<GeoRaster, DataError> {
    ascii_grid(text).map_err(DataError::from)
}

fn ascii_grid(text: &str) -> Result<GeoRaster, String> {
    let mut tokens = text.split_whitespace().peekable();
    let mut header = std::collections::HashMap::new();
    while let Some(t) = tokens.peek() {
        if t.parse::<f64>().is_ok() {
            break;
        }
        let key = tokens.next().unwrap_or_default().to_ascii_lowercase();
        let v = tokens.next().ok_or_else(|| format!("header key '{key}' has no value"))?;
        let v: f64 = v.parse().map_err(|_| format!("header {key}: '{v}' is not a number"))?;
        header.insert(key, v);
    }
    let get = |k: &str| header.get(k).copied().ok_or_else(|| format!("header lacks '{k}'"));
    let (w, h, cell) = (get("ncols")?, get("nrows")?, get("cellsize")?);
    if w < 1.0
        || h < 1.0
        || w.fract() != 0.0
        || h.fract() != 0.0
        || cell.is_nan()
        || cell <= 0.0
        || w * h > MAX_SAMPLES as f64
    {
        return Err(format!("ncols {w}, nrows {h}, cellsize {cell} are not a usable grid"));
    }
    let (w, h) = (w as usize, h as usize);
    // every value takes at least one digit and one separator
    if w * h > text.len() / 2 + 1 {
        return Err(format!(
            "ncols × nrows = {} values declared, but {} bytes of text hold at most {}",
            w * h,
            text.len(),
            text.len() / 2 + 1
        ));
    }
    let (x0, y0) =
        match (header.get("xllcorner"), header.get("xllcenter"), header.get("yllcorner"), header.get("yllcenter")) {
            (Some(&x), _, Some(&y), _) => (x, y),
            (_, Some(&x), _, Some(&y)) => (x - cell / 2.0, y - cell / 2.0),
            _ => return Err("header needs xllcorner/yllcorner or xllcenter/yllcenter".into()),
        };
    let mut data = Vec::with_capacity(w * h);
    for (i, t) in tokens.enumerate() {
        if i >= w * h {
            return Err(format!("more than ncols × nrows = {} values", w * h));
        }
        data.push(t.parse::<f32>().map_err(|_| format!("value {} ('{t}') is not a number", i + 1))?);
    }
    if data.len() != w * h {
        return Err(format!("{} values for a {w}×{h} grid", data.len()));
    }
    Ok(GeoRaster {
        width: w as u32,
        height: h as u32,
        bands: 1,
        data,
        origin: [x0, y0 + cell * h as f64],
        pixel: [cell, cell],
        nodata: header.get("nodata_value").copied(),
        epsg: None,
        projection: None,
        citation: None,
        proj4: None,
    })
}

/// A numpy `.npy` array of one or two dimensions (i1/i2/i4/u1/u2/f4/f8, either
/// byte order, C or Fortran order) as (width, height, samples).
pub fn parse_npy(bytes: &[u8]) -> Result<(u32, u32, Vec<f32>), DataError> {
    npy(bytes).map_err(DataError::from)
}

fn npy(bytes: &[u8]) -> Result<(u32, u32, Vec<f32>), String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy array (missing \\x93NUMPY magic)".into());
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12),
        v => return Err(format!("unsupported .npy version {v}")),
    };
    let header = bytes.get(start..start + hlen).ok_or("header runs past the end of the file")?;
    let header = String::from_utf8_lossy(header);
    let field = |k: &str| -> Option<String> {
        let i = header.find(&format!("'{k}'"))?;
        let rest = header[i + k.len() + 2..].trim_start().strip_prefix(':')?.trim_start();
        Some(rest.to_string())
    };
    let descr = field("descr")
        .and_then(|s| s.strip_prefix('\'').and_then(|r| r.split('\'').next()).map(str::to_string))
        .ok_or("header lacks 'descr'")?;
    let fortran = field("fortran_order").is_some_and(|s| s.starts_with("True"));
    let shape_s = field("shape").ok_or("header lacks 'shape'")?;
    let inner = shape_s.strip_prefix('(').and_then(|s| s.split(')').next()).ok_or("malformed shape")?;
    let dims: Vec<usize> = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("shape ({inner}) is not numbers"))?;
    let (h, w) = match dims.as_slice() {
        [] => (1, 1),
        [n] => (1, *n),
        [h, w] => (*h, *w),
        _ => return Err(format!("a {}-dimensional array is not an elevation grid", dims.len())),
    };
    if w == 0 || h == 0 || (w as u64).checked_mul(h as u64).is_none_or(|n| n > MAX_SAMPLES) {
        return Err(format!("shape {h}×{w} is outside the limit"));
    }
    let (little, kind, size) = {
        let b = descr.as_bytes();
        if b.len() < 3 {
            return Err(format!("dtype '{descr}' is not understood"));
        }
        let little = b[0] != b'>';
        let size: usize =
            descr.get(2..).and_then(|d| d.parse().ok()).ok_or_else(|| format!("dtype '{descr}' is not understood"))?;
        (little, b[1], size)
    };
    if !matches!(size, 1 | 2 | 4 | 8) {
        return Err(format!("dtype '{descr}' is not supported"));
    }
    let body = &bytes[start + hlen..];
    if body.len() < w * h * size {
        return Err(format!("{} data bytes for {h}×{w} values of {size} bytes", body.len()));
    }
    crate::limits::check_cap(&format!("a {h}×{w} array"), Some(w as u64 * h as u64 * 4)).map_err(|e| e.to_string())?;
    let val = |c: &[u8]| -> Option<f32> {
        let mut a = [0u8; 8];
        a[..c.len()].copy_from_slice(c);
        if !little {
            a[..c.len()].reverse();
        }
        Some(match (kind, size) {
            (b'i', 1) => a[0] as i8 as f32,
            (b'u', 1) => a[0] as f32,
            (b'i', 2) => i16::from_le_bytes([a[0], a[1]]) as f32,
            (b'u', 2) => u16::from_le_bytes([a[0], a[1]]) as f32,
            (b'i', 4) => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f32,
            (b'f', 4) => f32::from_le_bytes([a[0], a[1], a[2], a[3]]),
            (b'f', 8) => f64::from_le_bytes(a) as f32,
            _ => return None,
        })
    };
    let raw: Vec<f32> = body[..w * h * size]
        .chunks_exact(size)
        .map(val)
        .collect::<Option<_>>()
        .ok_or(format!("dtype '{descr}' is not supported"))?;
    let data = if fortran { (0..w * h).map(|k| raw[(k % w) * h + k / w]).collect() } else { raw };
    Ok((w as u32, h as u32, data))
}

/// A numpy `.npz` archive: the largest 2-D array is the elevation; scalars
/// `dx`, `dy`, `xmin`, `ymax` (as in `jacksboro_fault_dem.npz`) georeference it.
pub fn parse_npz(bytes: &[u8]) -> Result<GeoRaster, DataError> {
    npz(bytes).map_err(DataError::from)
}

fn npz(bytes: &[u8]) -> Result<GeoRaster, String> {
    let mut zip =
        zip::ZipArchive::new(std::io::Cursor::new(bytes)).map_err(|e| format!("not a .npz (zip) archive: {e}"))?;
    let mut arrays = Vec::new();
    for i in 0..zip.len() {
        let mut f = zip.by_index(i).map_err(|e| format!("entry {i}: {e}"))?;
        let name = f.name().map(|n| n.trim_end_matches(".npy").to_string()).unwrap_or_else(|_| format!("entry {i}"));
        if f.size() > 8 * MAX_SAMPLES {
            return Err(format!("entry {name} of {} bytes is beyond the size limit", f.size()));
        }
        // the declared size is only a claim: reserve what the compressed bytes can give, read at most the claim
        let what = format!("entry {name}");
        let claim = crate::limits::check_claim(&what, Some(f.size()), f.compressed_size(), DEFLATE_RATIO)
            .map_err(|e| e.to_string())?;
        let mut buf = Vec::with_capacity(claim.min(1 << 24) as usize);
        (&mut f).take(claim).read_to_end(&mut buf).map_err(|e| format!("entry {name}: {e}"))?;
        if buf.len() as u64 != claim {
            return Err(format!("entry {name}: {} bytes inflated, {claim} declared", buf.len()));
        }
        let arr = npy(&buf).map_err(|e| format!("entry {name}: {e}"))?;
        arrays.push((name, arr));
    }
    let scalar = |k: &str| arrays.iter().find(|(n, a)| n == k && a.0 * a.1 == 1).map(|(_, a)| a.2[0] as f64);
    let (name, (w, h, data)) = arrays
        .iter()
        .filter(|(_, a)| a.1 > 1 && a.0 > 1)
        .max_by_key(|(_, a)| a.0 as u64 * a.1 as u64)
        .cloned()
        .ok_or("the archive holds no 2-D array")?;
    let mut r = plain(w, h, data);
    if let (Some(dx), Some(dy), Some(xmin), Some(ymax)) = (scalar("dx"), scalar("dy"), scalar("xmin"), scalar("ymax"))
        && dx > 0.0
        && dy > 0.0
    {
        r.origin = [xmin, ymax];
        r.pixel = [dx, dy];
    }
    r.citation = Some(format!("npz array '{name}'"));
    // arc-second spacings within longitude/latitude bounds: geographic degrees
    if r.pixel[0] < 0.01 && (-180.0..=360.0).contains(&r.origin[0]) && (-90.0..=90.0).contains(&r.origin[1]) {
        r.epsg = Some(4326);
        r.citation = Some(format!("npz array '{name}', geographic degrees (from its spacing)"));
    }
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_grid_by_hand_and_broken() {
        let g = parse_ascii_grid(
            "ncols 3\nnrows 2\nxllcorner 100\nyllcorner 200\ncellsize 10\nNODATA_value -9999\n1 2 3\n4 -9999 6\n",
        )
        .unwrap();
        assert_eq!((g.width, g.height, g.origin, g.pixel), (3, 2, [100.0, 220.0], [10.0, 10.0]));
        assert_eq!(g.get(2, 1, 0), 6.0);
        assert_eq!(g.nodata, Some(-9999.0));
        for (bad, needle) in [
            ("ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n4 5\n", "5 values"),
            ("ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\n1 2 3 4 5 6\n", "cellsize"),
            ("ncols 99999999\nnrows 99999999\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n", "usable"),
            ("ncols 1\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\nx\n", "'x'"),
            ("ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 x\n", "not a number"),
        ] {
            let e = parse_ascii_grid(bad).unwrap_err();
            assert!(e.message.contains(needle), "{bad:?}: {e}");
        }
    }

    fn npy(descr: &str, shape: &str, body: &[u8]) -> Vec<u8> {
        let mut h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        while (10 + h.len() + 1) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend_from_slice(&(h.len() as u16).to_le_bytes());
        b.extend_from_slice(h.as_bytes());
        b.extend_from_slice(body);
        b
    }

    #[test]
    fn npy_by_hand_and_broken() {
        let body: Vec<u8> = [1i16, -2, 3, 4, 5, 6].iter().flat_map(|v| v.to_le_bytes()).collect();
        let (w, h, d) = parse_npy(&npy("<i2", "(2, 3)", &body)).unwrap();
        assert_eq!((w, h, d), (3, 2, vec![1.0, -2.0, 3.0, 4.0, 5.0, 6.0]));
        let be: Vec<u8> = [1.5f32, 2.5].iter().flat_map(|v| v.to_be_bytes()).collect();
        assert_eq!(parse_npy(&npy(">f4", "(2,)", &be)).unwrap().2, vec![1.5, 2.5]);
        assert!(parse_npy(b"PK\x03\x04").unwrap_err().message.contains("magic"));
        assert!(parse_npy(&npy("<i2", "(2, 3)", &body[..4])).unwrap_err().message.contains("data bytes"));
        assert!(parse_npy(&npy("<c8", "(1,)", &[0; 8])).unwrap_err().message.contains("not supported"));
        assert!(parse_npy(&npy("<i2", "(2, 3, 4)", &body)).unwrap_err().message.contains("3-dimensional"));
        assert!(parse_npy(&npy("<i2", "(99999999, 99999999)", &body)).unwrap_err().message.contains("limit"));
    }

    #[test]
    fn a_bare_array_is_said_to_have_no_georeferencing() {
        let body: Vec<u8> = [1i16, -2, 3, 4, 5, 6].iter().flat_map(|v| v.to_le_bytes()).collect();
        let r = parse_elevation(&npy("<i2", "(2, 3)", &body), Path::new("bare.npy")).unwrap();
        let w = elevation_warnings(&r);
        assert!(w.iter().any(|w| w.contains("no georeferencing")), "{w:?}");
        let g = parse_ascii_grid("ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 30\n1 2\n3 4\n").unwrap();
        assert!(elevation_warnings(&g).is_empty());
    }

    #[test]
    fn hgt_by_name_and_size() {
        let bytes = vec![0u8; 1201 * 1201 * 2];
        let g = parse_hgt(&bytes, "S09W036").unwrap();
        assert_eq!((g.width, g.height), (1201, 1201));
        assert!(
            (g.origin[0] - (-36.0 - 0.5 / 1200.0)).abs() < 1e-12 && (g.origin[1] - (-8.0 + 0.5 / 1200.0)).abs() < 1e-12
        );
        assert!(parse_hgt(&bytes[..100], "N00E000").is_err());
        assert!(parse_hgt(&bytes, "tile").is_err());
    }

    #[test]
    fn jacksboro_npz_loads_with_its_georeferencing() {
        // kept in the repository (the same file as ../shared/data/terrain)
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/jacksboro_fault_dem.npz");
        let g = load_elevation(&p).unwrap();
        assert_eq!((g.width, g.height), (403, 344));
        assert!(g.pixel[0] > 0.0 && g.data.iter().all(|v| v.is_finite()));
        assert!(parse_npz(b"not a zip").unwrap_err().message.contains("zip"));
    }
}
