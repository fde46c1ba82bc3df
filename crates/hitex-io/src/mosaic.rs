//! Several elevation tiles as one raster: SRTM-style 1°×1° tiles, GLO-30
//! tiles, or the pieces of a larger DEM, in one CRS or several.
//!
//! The mosaic takes the first tile's CRS and pixel size, on the first tile's
//! pixel lattice, over the union of the tiles' extents. A tile in the same
//! CRS with the same pixel size on the same lattice is copied sample for
//! sample (shared edge posts, as adjacent SRTM tiles have, land on the same
//! pixel); any other tile is reprojected onto its part of the grid.

use crate::IoError;
use crate::crs::Crs;
use crate::geotiff::GeoRaster;
use crate::reproject::{Grid, clip_to, reproject};
use std::path::{Path, PathBuf};

/// The elevation files of a folder (by extension: .tif, .tiff, .hgt, .asc,
/// .npz; a .npy holds no georeferencing), sorted by name.
pub fn dem_files(dir: &Path) -> Result<Vec<PathBuf>, IoError> {
    let rd = std::fs::read_dir(dir).map_err(|source| IoError::Read { path: dir.to_path_buf(), source })?;
    let mut v: Vec<PathBuf> = rd
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.is_file()
                && p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "tif" | "tiff" | "hgt" | "asc" | "npz"))
        })
        .collect();
    v.sort();
    if v.is_empty() {
        let message = "no elevation files (.tif, .hgt, .asc, .npz) in this folder".into();
        return Err(IoError::Format { path: dir.to_path_buf(), message });
    }
    Ok(v)
}

/// A tile with its extent in the mosaic's CRS, whether it lies on the
/// mosaic's lattice, and its CRS when that is another.
struct Part {
    raster: GeoRaster,
    path: PathBuf,
    extent: [f64; 4],
    aligned: bool,
    crs: Option<Crs>,
}

/// Relative difference of pixel sizes below which two tiles share a resolution.
const SAME_PIXEL: f64 = 1e-6;

/// The tiles as one raster (see the module's description), with one line per
/// reprojected tile for the user. Refused, naming the file: a tile whose CRS
/// cannot be resolved while others differ, a tile in the first's CRS with
/// another pixel size, a tile that does not touch the others (a gap), and a
/// mosaic beyond [`crate::geotiff::MAX_SAMPLES`].
pub fn mosaic(tiles: Vec<(GeoRaster, PathBuf)>) -> Result<(GeoRaster, Vec<String>), IoError> {
    let err = |p: &Path, m: String| IoError::Format { path: p.to_path_buf(), message: m };
    let mut tiles = tiles.into_iter();
    let Some((first, first_path)) = tiles.next() else {
        return Err(err(Path::new(""), "no elevation tiles given".into()));
    };
    let rest: Vec<(GeoRaster, PathBuf)> = tiles.collect();
    if rest.is_empty() {
        return Ok((first, Vec::new()));
    }
    let crs = first.crs().ok();
    let px = first.pixel;
    // each tile's extent in the first's CRS, and whether it sits on the first's lattice
    let mut parts: Vec<Part> = Vec::new();
    for (t, p) in std::iter::once((first, first_path)).chain(rest) {
        if p.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("npy")) {
            return Err(err(&p, "a .npy array holds no georeferencing: it cannot be placed in a mosaic".into()));
        }
        let same = parts.first().is_none_or(|f| t.same_crs(&f.raster));
        let (e, aligned, tc) = if same {
            if (t.pixel[0] / px[0] - 1.0).abs() > SAME_PIXEL || (t.pixel[1] / px[1] - 1.0).abs() > SAME_PIXEL {
                return Err(err(
                    &p,
                    format!(
                        "pixels of {} × {} where the mosaic's first tile has {} × {}: tiles of one CRS must share a resolution",
                        t.pixel[0], t.pixel[1], px[0], px[1]
                    ),
                ));
            }
            let (x0, x1, y0, y1) = t.extent();
            let f = parts.first().map_or(t.origin, |f| f.raster.origin);
            let off = [(t.origin[0] - f[0]) / px[0], (f[1] - t.origin[1]) / px[1]];
            let aligned = off.iter().all(|o| (o - o.round()).abs() < 1e-6);
            ([x0, x1, y0, y1], aligned, None)
        } else {
            let (Some(to), Ok(from)) = (&crs, t.crs()) else {
                return Err(err(
                    &p,
                    "in another CRS than the first tile, and one of the two cannot be resolved".into(),
                ));
            };
            let (e, n) = crate::reproject::extent_in(&Grid::of(&t), &from, to);
            if n == 0 {
                return Err(err(&p, format!("its extent does not transform into {}", to.name())));
            }
            (e, false, Some(from))
        };
        parts.push(Part { raster: t, path: p, extent: e, aligned, crs: tc });
    }
    // the tiles form one connected area (touching within a pixel): no island
    let touches = |a: &[f64; 4], b: &[f64; 4]| {
        a[0] <= b[1] + px[0] && b[0] <= a[1] + px[0] && a[2] <= b[3] + px[1] && b[2] <= a[3] + px[1]
    };
    let mut reached = vec![false; parts.len()];
    let mut stack = vec![0usize];
    reached[0] = true;
    while let Some(i) = stack.pop() {
        for j in 0..parts.len() {
            if !reached[j] && touches(&parts[i].extent, &parts[j].extent) {
                reached[j] = true;
                stack.push(j);
            }
        }
    }
    if let Some(k) = reached.iter().position(|r| !r) {
        return Err(err(
            &parts[k].path,
            format!("is cut off from {} by a gap: a mosaic must be one connected area", parts[0].path.display()),
        ));
    }
    // the union on the first tile's lattice
    let f = parts[0].raster.origin;
    let u = parts.iter().fold([f64::MAX, f64::MIN, f64::MAX, f64::MIN], |u, q| {
        [u[0].min(q.extent[0]), u[1].max(q.extent[1]), u[2].min(q.extent[2]), u[3].max(q.extent[3])]
    });
    let i0 = ((u[0] - f[0]) / px[0] + 1e-6).floor();
    let i1 = ((u[1] - f[0]) / px[0] - 1e-6).ceil();
    let j0 = ((f[1] - u[3]) / px[1] + 1e-6).floor();
    let j1 = ((f[1] - u[2]) / px[1] - 1e-6).ceil();
    let (w, h) = (i1 - i0, j1 - j0);
    if !(w >= 1.0 && h >= 1.0) || w * h > crate::geotiff::MAX_SAMPLES as f64 {
        return Err(err(
            &parts[0].path,
            format!(
                "the mosaic of {} tiles would be {w}×{h} posts, beyond the limit of {}",
                parts.len(),
                crate::geotiff::MAX_SAMPLES
            ),
        ));
    }
    // the corner exactly as the westernmost and northernmost tiles on the lattice have it
    let on = |q: &Part, axis: usize, at: f64| {
        let o = if axis == 0 { (q.raster.origin[0] - f[0]) / px[0] } else { (f[1] - q.raster.origin[1]) / px[1] };
        (q.aligned || std::ptr::eq(q, &parts[0])) && (o - at).abs() < 1e-6
    };
    let x0 = parts.iter().find(|q| on(q, 0, i0)).map_or(f[0] + i0 * px[0], |q| q.raster.origin[0]);
    let y0 = parts.iter().find(|q| on(q, 1, j0)).map_or(f[1] - j0 * px[1], |q| q.raster.origin[1]);
    let grid = Grid { width: w as u32, height: h as u32, origin: [x0, y0], pixel: px };
    let nodata = parts[0].raster.nodata;
    let hole = nodata.map_or(f32::NAN, |n| n as f32);
    let valid = |v: f32, nd: Option<f64>| v.is_finite() && nd.is_none_or(|n| (v as f64 - n).abs() >= 1e-6);
    let mut data = vec![hole; grid.width as usize * grid.height as usize];
    let mut notes = Vec::new();
    for Part { raster: t, path: p, aligned, crs: tc, .. } in &parts {
        if *aligned {
            let ox = ((t.origin[0] - grid.origin[0]) / px[0]).round() as usize;
            let oy = ((grid.origin[1] - t.origin[1]) / px[1]).round() as usize;
            for y in 0..(t.height as usize).min(grid.height as usize - oy.min(grid.height as usize)) {
                for x in 0..(t.width as usize).min(grid.width as usize - ox.min(grid.width as usize)) {
                    let v = t.data[(y * t.width as usize + x) * t.bands];
                    if valid(v, t.nodata) {
                        data[(oy + y) * grid.width as usize + ox + x] = v;
                    }
                }
            }
            continue;
        }
        // reprojected (or resampled off the lattice) onto its part of the grid
        let (from, to) = match (tc, &crs) {
            (Some(from), Some(to)) => (from.clone(), to.clone()),
            _ => match &crs {
                Some(c) => (c.clone(), c.clone()),
                None => {
                    return Err(err(
                        p,
                        "off the first tile's pixel lattice, and the CRS cannot be resolved to resample it".into(),
                    ));
                }
            },
        };
        let Some(sub) = clip_to(&grid, &to, &Grid::of(t), &from) else { continue };
        let r = reproject(t, &from, &to, &sub, None);
        let ox = ((sub.origin[0] - grid.origin[0]) / px[0]).round() as usize;
        let oy = ((grid.origin[1] - sub.origin[1]) / px[1]).round() as usize;
        for y in 0..(sub.height as usize).min(grid.height as usize - oy.min(grid.height as usize)) {
            for x in 0..(sub.width as usize).min(grid.width as usize - ox.min(grid.width as usize)) {
                let v = r.data[(y * sub.width as usize + x) * r.bands];
                let slot = &mut data[(oy + y) * grid.width as usize + ox + x];
                if valid(v, t.nodata) && !valid(*slot, nodata) {
                    *slot = v;
                }
            }
        }
        notes.push(format!(
            "{}: {} onto the mosaic's grid",
            p.display(),
            if tc.is_some() {
                format!("reprojected from {} to {}", from.name(), to.name())
            } else {
                "resampled".into()
            }
        ));
    }
    let first = &parts[0].raster;
    let empty = data.iter().filter(|v| !valid(**v, nodata)).count();
    if empty * 10 > data.len() {
        notes.push(format!(
            "{} % of the mosaic's extent has no tile (filled from the neighbouring posts)",
            empty * 100 / data.len()
        ));
    }
    let r = GeoRaster {
        width: grid.width,
        height: grid.height,
        bands: 1,
        data,
        origin: grid.origin,
        pixel: px,
        nodata,
        epsg: first.epsg,
        projection: first.projection,
        citation: first.citation.clone(),
        proj4: first.proj4.clone(),
    };
    Ok((r, notes))
}
