//! Reprojection of rasters: a [`GeoRaster`] resampled onto a north-up grid
//! of another CRS (bilinear, nodata-aware), and the grids that bring a
//! geographic DEM into a local metric frame or onto another raster's CRS.
//!
//! Each target pixel centre is taken into the source CRS. The exact
//! transformation runs on a lattice of every [`LATTICE`]-th pixel; between
//! lattice points the source position is interpolated bilinearly, and a cell
//! whose interpolated centre departs from the exact one by more than
//! [`MAX_INTERPOLATION_ERROR`] source pixels is transformed pixel by pixel.

use crate::DataError;
use crate::crs::Crs;
use crate::geotiff::GeoRaster;
use rayon::prelude::*;

/// Pixels between exactly transformed lattice points.
pub const LATTICE: usize = 16;
/// The largest error, in source pixels, of an interpolated source position.
pub const MAX_INTERPOLATION_ERROR: f64 = 0.01;

/// A north-up grid: `width`×`height` pixels from the top-left corner
/// `origin`, pixels of `pixel` units (x east, y north).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Top-left corner.
    pub origin: [f64; 2],
    /// Pixel size (x, y), both positive.
    pub pixel: [f64; 2],
}

impl Grid {
    /// The grid of a raster.
    pub fn of(r: &GeoRaster) -> Grid {
        Grid { width: r.width, height: r.height, origin: r.origin, pixel: r.pixel }
    }
    /// Centre of pixel (i, j).
    pub fn centre(&self, i: f64, j: f64) -> [f64; 2] {
        [self.origin[0] + (i + 0.5) * self.pixel[0], self.origin[1] - (j + 0.5) * self.pixel[1]]
    }
}

/// The outline of `grid` (points along its four edges, `per_side` each) in `to`.
fn outline(grid: &Grid, from: &Crs, to: &Crs, per_side: usize) -> Vec<[f64; 2]> {
    let (w, h) = (grid.width as f64, grid.height as f64);
    let mut pts = Vec::with_capacity(4 * per_side);
    for k in 0..per_side {
        let t = k as f64 / (per_side - 1) as f64;
        for (x, y) in [(t * w, 0.0), (t * w, h), (0.0, t * h), (w, t * h)] {
            pts.push([grid.origin[0] + x * grid.pixel[0], grid.origin[1] - y * grid.pixel[1]]);
        }
    }
    from.transform(to, &mut pts);
    pts.retain(|p| p[0].is_finite() && p[1].is_finite());
    pts
}

/// The extent of `grid` (in `from`) in `to`: (x min, x max, y min, y max)
/// over points along its edges, with how many of them transformed.
pub fn extent_in(grid: &Grid, from: &Crs, to: &Crs) -> ([f64; 4], usize) {
    let pts = outline(grid, from, to, 65);
    let e = pts.iter().fold([f64::MAX, f64::MIN, f64::MAX, f64::MIN], |e, q| {
        [e[0].min(q[0]), e[1].max(q[0]), e[2].min(q[1]), e[3].max(q[1])]
    });
    (e, pts.len())
}

/// The size in `to` of the central pixel of `g` (in `from`): the lengths of
/// its horizontal and vertical midlines once transformed.
fn central_pixel_in(g: &Grid, from: &Crs, to: &Crs) -> [f64; 2] {
    let c = g.centre(g.width as f64 / 2.0 - 0.5, g.height as f64 / 2.0 - 0.5);
    let mut q = [
        [c[0] - g.pixel[0] / 2.0, c[1]],
        [c[0] + g.pixel[0] / 2.0, c[1]],
        [c[0], c[1] - g.pixel[1] / 2.0],
        [c[0], c[1] + g.pixel[1] / 2.0],
    ];
    from.transform(to, &mut q);
    let len = |a: [f64; 2], b: [f64; 2]| ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    [len(q[0], q[1]), len(q[2], q[3])]
}

/// The grid in `to` that covers `src` (in `from`) with square-ish pixels of
/// the source's ground size at its centre, and at most `max_pixels` pixels.
pub fn covering_grid(src: &GeoRaster, from: &Crs, to: &Crs, max_pixels: u64) -> Result<Grid, DataError> {
    covering(src, from, to, max_pixels).map_err(DataError::from)
}

fn covering(src: &GeoRaster, from: &Crs, to: &Crs, max_pixels: u64) -> Result<Grid, String> {
    let g = Grid::of(src);
    let ([x0, x1, y0, y1], n) = extent_in(&g, from, to);
    if n < 8 {
        return Err(format!("the raster's extent does not transform into {}", to.name()));
    }
    let [px, py] = central_pixel_in(&g, from, to);
    if !(px > 0.0 && py > 0.0 && px.is_finite() && py.is_finite()) {
        return Err(format!("the raster's pixels have no size in {}", to.name()));
    }
    let (w, h) = (((x1 - x0) / px).ceil().max(1.0), ((y1 - y0) / py).ceil().max(1.0));
    if w * h > max_pixels as f64 {
        return Err(format!("in {} the raster would take {w}×{h} pixels, beyond the limit of {max_pixels}", to.name()));
    }
    Ok(Grid { width: w as u32, height: h as u32, origin: [x0, y1], pixel: [px, py] })
}

/// `grid` clipped to where `other` (a grid in `other_crs`) covers it, in
/// whole pixels of `grid`; None where they do not overlap.
pub fn clip_to(grid: &Grid, crs: &Crs, other: &Grid, other_crs: &Crs) -> Option<Grid> {
    let ([x0, x1, y0, y1], n) = extent_in(other, other_crs, crs);
    if n == 0 {
        return None;
    }
    let i0 = ((x0 - grid.origin[0]) / grid.pixel[0]).floor().max(0.0);
    let i1 = ((x1 - grid.origin[0]) / grid.pixel[0]).ceil().min(grid.width as f64);
    let j0 = ((grid.origin[1] - y1) / grid.pixel[1]).floor().max(0.0);
    let j1 = ((grid.origin[1] - y0) / grid.pixel[1]).ceil().min(grid.height as f64);
    if i1 <= i0 || j1 <= j0 {
        return None;
    }
    Some(Grid {
        width: (i1 - i0) as u32,
        height: (j1 - j0) as u32,
        origin: [grid.origin[0] + i0 * grid.pixel[0], grid.origin[1] - j0 * grid.pixel[1]],
        pixel: grid.pixel,
    })
}

/// Source pixel positions (column and row, pixel centres at whole numbers)
/// of every pixel of row `j` of `dst`, exact at lattice points and
/// interpolated between.
fn source_positions(dst: &Grid, src: &Grid, to_src: &dyn Fn(&mut [[f64; 2]]), j: usize) -> Vec<[f64; 2]> {
    let w = dst.width as usize;
    let to_pixel =
        |p: [f64; 2]| [(p[0] - src.origin[0]) / src.pixel[0] - 0.5, (src.origin[1] - p[1]) / src.pixel[1] - 0.5];
    let exact_row = |jj: f64, cols: &[usize]| -> Vec<[f64; 2]> {
        let mut pts: Vec<[f64; 2]> = cols.iter().map(|&i| dst.centre(i as f64, jj)).collect();
        to_src(&mut pts);
        pts.into_iter().map(to_pixel).collect()
    };
    // the lattice rows above and below this row, and the lattice columns
    let j0 = j / LATTICE * LATTICE;
    let j1 = (j0 + LATTICE).min(dst.height as usize - 1).max(j0);
    let cols: Vec<usize> = (0..w).step_by(LATTICE).chain(std::iter::once(w - 1)).collect();
    let (top, bottom) = (exact_row(j0 as f64, &cols), exact_row(j1 as f64, &cols));
    let ty = if j1 > j0 { (j - j0) as f64 / (j1 - j0) as f64 } else { 0.0 };
    let mut out = Vec::with_capacity(w);
    for (c, pair) in cols.windows(2).enumerate() {
        let (a, b) = (pair[0], pair[1]);
        let left = lerp(top[c], bottom[c], ty);
        let right = lerp(top[c + 1], bottom[c + 1], ty);
        // the cell's middle, interpolated against exact
        let mid = (a + b) / 2;
        let interp = lerp(left, right, if b > a { (mid - a) as f64 / (b - a) as f64 } else { 0.0 });
        let exact = exact_row(j as f64, &[mid])[0];
        let good = left.iter().chain(&right).all(|v| v.is_finite())
            && (interp[0] - exact[0]).abs() <= MAX_INTERPOLATION_ERROR
            && (interp[1] - exact[1]).abs() <= MAX_INTERPOLATION_ERROR;
        let bad = !good;
        let end = if c + 2 == cols.len() { b + 1 } else { b };
        if bad {
            out.extend(exact_row(j as f64, &(a..end).collect::<Vec<_>>()));
        } else {
            for i in a..end {
                out.push(lerp(left, right, if b > a { (i - a) as f64 / (b - a) as f64 } else { 0.0 }));
            }
        }
    }
    out
}

fn lerp(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

/// `src` (in `from`) resampled onto `dst` (in `to`): bilinear between the
/// valid neighbours of each position (weights renormalised where some are
/// nodata), nodata outside the source. The result's nodata is the source's,
/// or NaN; its georeferencing names `to` by `epsg` (None for a CRS without
/// an EPSG code, such as the local frame).
pub fn reproject(src: &GeoRaster, from: &Crs, to: &Crs, dst: &Grid, epsg: Option<u16>) -> GeoRaster {
    let b = src.bands;
    let nodata = src.nodata.map_or(f32::NAN, |n| n as f32);
    let is_valid = |v: f32| v.is_finite() && src.nodata.is_none_or(|n| (v as f64 - n).abs() >= 1e-6);
    let sg = Grid::of(src);
    let to_src = |pts: &mut [[f64; 2]]| to.transform(from, pts);
    let (sw, sh) = (src.width as i64, src.height as i64);
    let mut data = vec![nodata; dst.width as usize * dst.height as usize * b];
    data.par_chunks_mut(dst.width as usize * b).enumerate().for_each(|(j, row)| {
        let pos = source_positions(dst, &sg, &to_src, j);
        for (i, p) in pos.iter().enumerate() {
            // the source's edge lies half a pixel beyond its outer pixel centres
            if !(p[0] >= -0.5 && p[1] >= -0.5 && p[0] <= sw as f64 - 0.5 && p[1] <= sh as f64 - 0.5) {
                continue;
            }
            let (x0, y0) = (p[0].floor(), p[1].floor());
            let (fx, fy) = (p[0] - x0, p[1] - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            for band in 0..b {
                let (mut acc, mut wsum) = (0.0f64, 0.0f64);
                for (dx, dy, w) in
                    [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)]
                {
                    let (x, y) = (x0 + dx, y0 + dy);
                    if w <= 0.0 || x < 0 || y < 0 || x >= sw || y >= sh {
                        continue;
                    }
                    let v = src.data[(y as usize * sw as usize + x as usize) * b + band];
                    if is_valid(v) {
                        acc += w * v as f64;
                        wsum += w;
                    }
                }
                if wsum > 1e-9 {
                    row[i * b + band] = (acc / wsum) as f32;
                }
            }
        }
    });
    GeoRaster {
        width: dst.width,
        height: dst.height,
        bands: b,
        data,
        origin: dst.origin,
        pixel: dst.pixel,
        nodata: src.nodata.or(Some(f64::NAN)).filter(|n| !n.is_nan()),
        epsg,
        projection: None,
        citation: Some(to.name().to_string()),
        proj4: epsg.is_none().then(|| to.definition().to_string()),
    }
}

/// A DEM and its imagery brought into one metric CRS by [`co_register`].
#[derive(Debug)]
pub struct CoRegistered {
    /// The elevation model, posts in the common CRS (heights unchanged).
    pub dem: GeoRaster,
    /// The imagery on a grid of the common CRS, clipped to the DEM.
    pub image: Option<GeoRaster>,
    /// The common CRS (None when the DEM names none: it is taken as metric).
    pub crs: Option<Crs>,
    /// Metres per unit of the common CRS.
    pub unit_metres: f64,
    /// What was reprojected, one line each, for the user.
    pub notes: Vec<String>,
}

/// Brings a DEM (`dem_path`) and optional imagery (`image_path`) into one
/// metric CRS: `crs` when given; else the imagery's when the DEM is
/// geographic and the imagery projected; else the DEM's own when it is
/// projected; else (a geographic DEM alone, or with geographic imagery) a
/// local metric frame at the DEM's centre ([`Crs::local`]). The DEM moves
/// onto a grid of the common CRS covering it, the imagery onto one covering
/// the DEM at the imagery's resolution. Rasters already in the common CRS
/// are left untouched. Errors name the file they concern.
pub fn co_register(
    dem: GeoRaster,
    dem_path: &std::path::Path,
    image: Option<(GeoRaster, &std::path::Path)>,
    crs: Option<&Crs>,
) -> Result<CoRegistered, crate::IoError> {
    use crate::IoError;
    let err = |p: &std::path::Path, m: String| IoError::Format { path: p.to_path_buf(), message: m };
    let dem_crs = dem.crs();
    let img_crs = image.as_ref().map(|(i, _)| i.crs());
    let target = match (crs, &dem_crs) {
        (Some(c), _) => Some(c.clone()),
        (None, Ok(d)) if d.is_geographic() => match &img_crs {
            Some(Ok(i)) if !i.is_geographic() => Some(i.clone()),
            _ => {
                let (x0, x1, y0, y1) = dem.extent();
                Some(Crs::local((x0 + x1) / 2.0, (y0 + y1) / 2.0).map_err(|m| err(dem_path, m.to_string()))?)
            }
        },
        (None, Ok(d)) => Some(d.clone()),
        (None, Err(_)) => None,
    };
    if let Some(t) = &target
        && t.is_geographic()
    {
        return Err(err(
            dem_path,
            format!("{} is geographic: terrain is meshed in a projected (metric) CRS", t.name()),
        ));
    }
    let mut notes = Vec::new();
    let max_pixels = crate::geotiff::MAX_SAMPLES / dem.bands.max(1) as u64;
    // imagery that names the DEM's own CRS (the same EPSG code or UTM zone) stays as it is
    let image_in_place = |img: &GeoRaster, t: &Crs| img.same_crs(&dem) && dem_crs.as_ref().is_ok_and(|d| d == t);
    let image_in_place = image.as_ref().zip(target.as_ref()).is_some_and(|((i, _), t)| image_in_place(i, t));
    let dem = match (&target, &dem_crs) {
        (Some(t), Ok(d)) if t != d => {
            let grid = covering_grid(&dem, d, t, max_pixels).map_err(|m| err(dem_path, m.message))?;
            let bytes = grid.width as u64 * grid.height as u64 * dem.bands as u64 * 4;
            crate::limits::check_cap("the reprojected DEM", Some(bytes)).map_err(|m| err(dem_path, m.to_string()))?;
            let r = reproject(&dem, d, t, &grid, t.epsg());
            notes.push(format!(
                "{}: reprojected from {} to {} ({}×{} posts at {:.2} × {:.2} m)",
                dem_path.display(),
                d.name(),
                t.name(),
                grid.width,
                grid.height,
                grid.pixel[0] * t.unit_metres(),
                grid.pixel[1] * t.unit_metres()
            ));
            r
        }
        (Some(_), Err(m)) => return Err(err(dem_path, format!("cannot reproject: {m}"))),
        _ => dem,
    };
    let image = match (image, &target) {
        (Some((img, path)), Some(t)) => {
            if image_in_place {
                return Ok(CoRegistered {
                    dem,
                    image: Some(img),
                    crs: target.clone(),
                    unit_metres: t.unit_metres(),
                    notes,
                });
            }
            let ic = img.crs().map_err(|m| err(path, format!("cannot reproject: {m}")))?;
            if &ic == t {
                Some(img)
            } else {
                let full = covering_grid(&img, &ic, t, u64::MAX).map_err(|m| err(path, m.message))?;
                let grid = clip_to(&full, t, &Grid::of(&dem), t).ok_or_else(|| {
                    err(path, format!("does not overlap {} after reprojection into {}", dem_path.display(), t.name()))
                })?;
                if grid.width as u64 * grid.height as u64 * img.bands as u64 > max_pixels {
                    return Err(err(
                        path,
                        format!(
                            "in {} the imagery over the DEM would take {}×{} pixels of {} bands, beyond the limit of {max_pixels} samples",
                            t.name(),
                            grid.width,
                            grid.height,
                            img.bands
                        ),
                    ));
                }
                let bytes = grid.width as u64 * grid.height as u64 * img.bands as u64 * 4;
                crate::limits::check_cap("the reprojected imagery", Some(bytes))
                    .map_err(|m| err(path, m.to_string()))?;
                let r = reproject(&img, &ic, t, &grid, t.epsg());
                notes.push(format!(
                    "{}: reprojected from {} to {} ({}×{} pixels over the DEM)",
                    path.display(),
                    ic.name(),
                    t.name(),
                    grid.width,
                    grid.height
                ));
                Some(r)
            }
        }
        (Some((img, _)), None) => Some(img),
        (None, _) => None,
    };
    let unit_metres = target.as_ref().map_or(1.0, |t| t.unit_metres());
    Ok(CoRegistered { dem, image, crs: target, unit_metres, notes })
}

/// Imagery read window by window in another CRS: each window of the target
/// grid reads the source window that covers it (one read per window, so
/// memory stays bounded whatever the source's size) and resamples it
/// bilinearly in linear light, weighted by alpha; transparent outside the
/// source.
pub struct ReprojectedSource {
    inner: Box<dyn crate::gst::TileSource>,
    inner_grid: Grid,
    from: Crs,
    to: Crs,
    grid: Grid,
    name: String,
}

/// The largest source window one target window may read (texels).
pub const MAX_REPROJECTED_WINDOW: u64 = 1 << 26;

impl ReprojectedSource {
    /// `inner` (on `inner_grid` in `from`) seen on `grid` (in `to`).
    pub fn new(inner: Box<dyn crate::gst::TileSource>, inner_grid: Grid, from: Crs, to: Crs, grid: Grid) -> Self {
        let name = format!("{}, reprojected from {} to {}", inner.describe(), from.name(), to.name());
        Self { inner, inner_grid, from, to, grid, name }
    }
}

impl crate::gst::TileSource for ReprojectedSource {
    fn size(&self) -> (u32, u32) {
        (self.grid.width, self.grid.height)
    }

    fn read(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<Vec<u8>, crate::IoError> {
        let g = &self.grid;
        let win = Grid {
            width: w,
            height: h,
            origin: [g.origin[0] + x0 as f64 * g.pixel[0], g.origin[1] - y0 as f64 * g.pixel[1]],
            pixel: g.pixel,
        };
        let mut out = vec![0u8; w as usize * h as usize * 4];
        if w == 0 || h == 0 {
            return Ok(out);
        }
        let to_src = |pts: &mut [[f64; 2]]| self.to.transform(&self.from, pts);
        let pos: Vec<Vec<[f64; 2]>> =
            (0..h as usize).map(|j| source_positions(&win, &self.inner_grid, &to_src, j)).collect();
        let (sw, sh) = (self.inner_grid.width as f64, self.inner_grid.height as f64);
        let inside = |p: &[f64; 2]| p[0] >= -0.5 && p[1] >= -0.5 && p[0] <= sw - 0.5 && p[1] <= sh - 0.5;
        let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for p in pos.iter().flatten().filter(|p| inside(p)) {
            b = [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])];
        }
        if b[0] > b[2] {
            return Ok(out);
        }
        // the texels the bilinear taps reach
        let sx0 = (b[0].floor().max(0.0)) as u32;
        let sy0 = (b[1].floor().max(0.0)) as u32;
        let sx1 = ((b[2].floor() + 1.0).min(sw - 1.0)) as u32;
        let sy1 = ((b[3].floor() + 1.0).min(sh - 1.0)) as u32;
        let (rw, rh) = (sx1 - sx0 + 1, sy1 - sy0 + 1);
        if rw as u64 * rh as u64 > MAX_REPROJECTED_WINDOW {
            return Err(crate::IoError::Core(hitex_core::CoreError::InvalidImage(format!(
                "{}: a {w}x{h} window would read {rw}x{rh} source texels (beyond {MAX_REPROJECTED_WINDOW}); \
                 the target grid is much coarser than the source",
                self.name
            ))));
        }
        let src = self.inner.read(sx0, sy0, rw, rh)?;
        if src.len() != rw as usize * rh as usize * 4 {
            return Err(crate::IoError::Core(hitex_core::CoreError::InvalidImage(format!(
                "{}: window of {rw}x{rh} returned {} bytes",
                self.inner.describe(),
                src.len()
            ))));
        }
        let lut = hitex_core::texture::image::decode_table(hitex_core::texture::ColorSpace::Srgb);
        for (j, row) in pos.iter().enumerate() {
            for (i, p) in row.iter().enumerate() {
                if !inside(p) {
                    continue;
                }
                let (fx, fy) = (p[0].floor(), p[1].floor());
                let (tx, ty) = (p[0] - fx, p[1] - fy);
                let (mut acc, mut alpha, mut wsum) = ([0.0f64; 3], 0.0f64, 0.0f64);
                for (dx, dy, wt) in [
                    (0.0, 0.0, (1.0 - tx) * (1.0 - ty)),
                    (1.0, 0.0, tx * (1.0 - ty)),
                    (0.0, 1.0, (1.0 - tx) * ty),
                    (1.0, 1.0, tx * ty),
                ] {
                    let (x, y) = (fx + dx, fy + dy);
                    if wt <= 0.0 || x < sx0 as f64 || y < sy0 as f64 || x > sx1 as f64 || y > sy1 as f64 {
                        continue;
                    }
                    let k = ((y as u32 - sy0) as usize * rw as usize + (x as u32 - sx0) as usize) * 4;
                    let a = src[k + 3] as f64 / 255.0;
                    for c in 0..3 {
                        acc[c] += wt * a * lut[src[k + c] as usize] as f64;
                    }
                    alpha += wt * a;
                    wsum += wt;
                }
                if wsum <= 1e-12 || alpha <= 1e-12 {
                    continue;
                }
                let o = (j * w as usize + i) * 4;
                for c in 0..3 {
                    out[o + c] = hitex_core::texture::linear_to_srgb_u8((acc[c] / alpha) as f32);
                }
                out[o + 3] = ((alpha / wsum) * 255.0).round().clamp(0.0, 255.0) as u8;
            }
        }
        Ok(out)
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// The web-mercator zoom whose texels are no larger than the ground size
/// of `src`'s central pixel, and `src`'s extent in EPSG:3857 (x min, y min,
/// x max, y max).
pub fn mercator_zoom(src: &Grid, from: &Crs) -> Result<(u32, [f64; 4]), DataError> {
    zoom_of(src, from).map_err(DataError::from)
}

fn zoom_of(src: &Grid, from: &Crs) -> Result<(u32, [f64; 4]), String> {
    let merc = Crs::from_epsg(3857).map_err(|e| e.to_string())?;
    let ([x0, x1, y0, y1], n) = extent_in(src, from, &merc);
    if n < 8 {
        return Err("the imagery's extent does not transform into web mercator (EPSG:3857)".into());
    }
    let [px, py] = central_pixel_in(src, from, &merc);
    let p = px.min(py);
    if !(p > 0.0 && p.is_finite()) {
        return Err("the imagery's pixels have no size in web mercator (EPSG:3857)".into());
    }
    let world = 2.0 * crate::gst::MERCATOR_HALF / crate::gst::TILE as f64;
    let zoom = (world / p).log2().ceil().max(0.0);
    if zoom > crate::gst::MAX_MERCATOR_ZOOM as f64 {
        return Err(format!(
            "its texels of {p:.4} m in web mercator need zoom {zoom}, beyond {}",
            crate::gst::MAX_MERCATOR_ZOOM
        ));
    }
    Ok((zoom as u32, [x0, y0, x1, y1]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geotiff::parse_geotiff;
    use std::path::Path;
    use tiff::encoder::{TiffEncoder, colortype};
    use tiff::tags::Tag;

    /// An int16 GeoTIFF of `w`×`h` samples with the given georeferencing tags and GeoKeys.
    fn int16_tiff(
        w: u32,
        h: u32,
        v: &[i16],
        georef: &[(Tag, Vec<f64>)],
        keys: &[[u16; 4]],
        nodata: Option<&str>,
    ) -> Vec<u8> {
        let mut buf = std::io::Cursor::new(Vec::new());
        let mut enc = TiffEncoder::new(&mut buf).unwrap();
        let mut img = enc.new_image::<colortype::GrayI16>(w, h).unwrap();
        for (tag, vals) in georef {
            img.encoder().write_tag(*tag, &vals[..]).unwrap();
        }
        let mut dir = vec![1u16, 1, 0, keys.len() as u16];
        keys.iter().for_each(|k| dir.extend_from_slice(k));
        img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &dir[..]).unwrap();
        if let Some(n) = nodata {
            img.encoder().write_tag(Tag::GdalNodata, n).unwrap();
        }
        img.write_data(v).unwrap();
        buf.into_inner()
    }

    fn parse(bytes: &[u8]) -> Result<GeoRaster, crate::IoError> {
        parse_geotiff(std::io::Cursor::new(bytes), bytes.len() as u64, Path::new("t.tif"))
    }

    const GEOGRAPHIC_POINT: [[u16; 4]; 3] = [[1024, 0, 1, 2], [1025, 0, 1, 2], [2048, 0, 1, 4326]];

    /// A DEM in a user-defined Lambert conformal conic (the parameters of
    /// RGF93 / Lambert-93 as GeoKeys and GeoDoubleParams, no EPSG code) is
    /// read into that projection: its posts lie where EPSG:2154 puts them.
    #[test]
    fn user_defined_lambert_conic_keys_are_read_as_their_projection() {
        let tie = (Tag::ModelTiepointTag, vec![0.0, 0.0, 0.0, 650_000.0, 6_860_000.0, 0.0]);
        let scale = (Tag::ModelPixelScaleTag, vec![25.0, 25.0, 0.0]);
        let doubles = (Tag::GeoDoubleParamsTag, vec![49.0, 44.0, 46.5, 3.0, 700_000.0, 6_600_000.0]);
        let keys = [
            [1024, 0, 1, 1],
            [2048, 0, 1, 4171],
            [3072, 0, 1, 32767],
            [3074, 0, 1, 32767],
            [3075, 0, 1, 8],
            [3076, 0, 1, 9001],
            [3078, 34736, 1, 0],
            [3079, 34736, 1, 1],
            [3085, 34736, 1, 2],
            [3084, 34736, 1, 3],
            [3086, 34736, 1, 4],
            [3087, 34736, 1, 5],
        ];
        let b = int16_tiff(4, 3, &[100; 12], &[tie, scale, doubles], &keys, None);
        let r = parse(&b).unwrap();
        let crs = r.crs().unwrap();
        assert!(!crs.is_geographic() && crs.unit_metres() == 1.0, "{crs:?}");
        let l93 = Crs::from_epsg(2154).unwrap();
        let wgs = Crs::wgs84();
        for corner in [[650_000.0, 6_860_000.0], [650_100.0, 6_859_925.0]] {
            let (a, b) = (crs.point(&wgs, corner), l93.point(&wgs, corner));
            assert!((a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9, "{a:?} vs {b:?}");
        }
        // Paris lies near the tiepoint
        let p = crs.point(&wgs, [650_000.0, 6_860_000.0]);
        assert!((p[0] - 2.3).abs() < 0.1 && (p[1] - 48.85).abs() < 0.1, "{p:?}");
    }

    #[test]
    fn geographic_keys_pixel_is_point_and_feet_are_read() {
        let tie = (Tag::ModelTiepointTag, vec![0.0, 0.0, 0.0, 7.0, 46.0, 0.0]);
        let scale = (Tag::ModelPixelScaleTag, vec![0.001, 0.001, 0.0]);
        let b = int16_tiff(4, 3, &[1; 12], &[tie.clone(), scale.clone()], &GEOGRAPHIC_POINT, Some("-32768"));
        let r = parse(&b).unwrap();
        assert_eq!(r.epsg, Some(4326));
        assert!(r.crs().unwrap().is_geographic() && r.is_geographic());
        // PixelIsPoint: the tiepoint is the first post's centre
        assert!((r.origin[0] - 6.9995).abs() < 1e-12 && (r.origin[1] - 46.0005).abs() < 1e-12, "{:?}", r.origin);
        assert_eq!(r.nodata, Some(-32768.0));
        // PixelIsArea (the default): the tiepoint is the corner
        let keys = [[1024, 0, 1, 2], [2048, 0, 1, 4326]];
        let r = parse(&int16_tiff(4, 3, &[1; 12], &[tie.clone(), scale.clone()], &keys, None)).unwrap();
        assert_eq!(r.origin, [7.0, 46.0]);
        // heights in feet come back in metres, nodata with them
        let keys = [[1024, 0, 1, 1], [3072, 0, 1, 32632], [4099, 0, 1, 9002]];
        let r = parse(&int16_tiff(2, 1, &[100, -9999], &[tie.clone(), scale.clone()], &keys, Some("-9999"))).unwrap();
        assert_eq!(r.epsg, Some(32632));
        assert!((r.data[0] - 30.48).abs() < 1e-4, "{}", r.data[0]);
        assert_eq!(r.data[1] as f64, r.nodata.unwrap());
        // an unknown vertical unit is refused by name
        let keys = [[4099, 0, 1, 9036]];
        let e = parse(&int16_tiff(1, 1, &[1], &[tie, scale], &keys, None)).unwrap_err().to_string();
        assert!(e.contains("t.tif") && e.contains("9036"), "{e}");
    }

    #[test]
    fn model_transformation_is_read_and_rotation_refused() {
        let keys = [[1024, 0, 1, 1], [3072, 0, 1, 32633]];
        let m = vec![30.0, 0.0, 0.0, 400_000.0, 0.0, -30.0, 0.0, 5_000_000.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        let r = parse(&int16_tiff(2, 2, &[1; 4], &[(Tag::ModelTransformationTag, m)], &keys, None)).unwrap();
        assert_eq!((r.origin, r.pixel), ([400_000.0, 5_000_000.0], [30.0, 30.0]));
        let m = vec![30.0, 5.0, 0.0, 400_000.0, 0.0, -30.0, 0.0, 5_000_000.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        let e = parse(&int16_tiff(2, 2, &[1; 4], &[(Tag::ModelTransformationTag, m)], &keys, None)).unwrap_err();
        assert!(e.to_string().contains("rotated"), "{e}");
    }

    /// A geographic raster of a smooth function of longitude and latitude.
    fn geographic(w: u32, h: u32, f: impl Fn(f64, f64) -> f64) -> GeoRaster {
        let (origin, pixel) = ([6.9, 46.1], [0.2 / w as f64, 0.2 / h as f64]);
        let data = (0..w * h)
            .map(|k| {
                let (i, j) = ((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
                f(origin[0] + i * pixel[0], origin[1] - j * pixel[1]) as f32
            })
            .collect();
        GeoRaster {
            width: w,
            height: h,
            bands: 1,
            data,
            origin,
            pixel,
            nodata: None,
            epsg: Some(4326),
            projection: None,
            citation: None,
            proj4: None,
        }
    }

    #[test]
    fn reprojection_samples_the_source_where_each_pixel_lies() {
        let f = |lon: f64, lat: f64| 1000.0 * (lon - 7.0) + 500.0 * (lat - 46.0);
        let src = geographic(200, 200, f);
        let (from, to) = (Crs::wgs84(), Crs::local(7.0, 46.0).unwrap());
        let grid = covering_grid(&src, &from, &to, 1 << 24).unwrap();
        // about 0.2° × 0.2° at 46°N: 15.5 km × 22.2 km
        assert!((grid.pixel[0] * 200.0 - 15_470.0).abs() < 60.0, "{:?}", grid);
        assert!((grid.pixel[1] * 200.0 - 22_240.0).abs() < 60.0, "{:?}", grid);
        let r = reproject(&src, &from, &to, &grid, None);
        let (mut inside, mut worst) = (0, 0.0f64);
        for j in 0..grid.height {
            for i in 0..grid.width {
                let v = r.data[(j * grid.width + i) as usize];
                let p = to.point(&from, grid.centre(i as f64, j as f64));
                let within = p[0] > 6.9 + 0.0006 && p[0] < 7.1 - 0.0006 && p[1] > 45.9 + 0.0006 && p[1] < 46.1 - 0.0006;
                if within {
                    inside += 1;
                    // bilinear of a linear function is exact up to f32 rounding
                    worst = worst.max((v as f64 - f(p[0], p[1])).abs());
                }
                if p[0] < 6.9 - 0.001 || p[0] > 7.1 + 0.001 || p[1] < 45.9 - 0.001 || p[1] > 46.1 + 0.001 {
                    assert!(v.is_nan(), "({i}, {j}) outside the source holds {v}");
                }
            }
        }
        assert!(inside > 30_000 && worst < 0.02, "{inside} pixels inside, worst error {worst}");
    }

    #[test]
    fn interpolated_positions_stay_within_their_bound() {
        let src = geographic(300, 300, |_, _| 0.0);
        let (from, to) = (Crs::wgs84(), Crs::from_epsg(32632).unwrap());
        let grid = covering_grid(&src, &from, &to, 1 << 24).unwrap();
        let sg = Grid::of(&src);
        let to_src = |p: &mut [[f64; 2]]| to.transform(&from, p);
        for j in [0, 7, 16, 100, grid.height as usize - 1] {
            let got = source_positions(&grid, &sg, &to_src, j);
            assert_eq!(got.len(), grid.width as usize);
            for (i, g) in got.iter().enumerate() {
                let e = to.point(&from, grid.centre(i as f64, j as f64));
                let e = [(e[0] - sg.origin[0]) / sg.pixel[0] - 0.5, (sg.origin[1] - e[1]) / sg.pixel[1] - 0.5];
                assert!(
                    (g[0] - e[0]).abs() <= 2.0 * MAX_INTERPOLATION_ERROR
                        && (g[1] - e[1]).abs() <= 2.0 * MAX_INTERPOLATION_ERROR,
                    "row {j} column {i}: {g:?} against {e:?}"
                );
            }
        }
    }

    #[test]
    fn dems_written_in_a_local_frame_or_an_epsg_crs_read_back_the_same() {
        let d = crate::test_dir::TestDir::fresh("dem-roundtrip");
        let src = geographic(40, 30, |lon, lat| 100.0 * lon + lat);
        for to in [Crs::local(7.0, 46.0).unwrap(), Crs::from_epsg(32632).unwrap()] {
            let grid = covering_grid(&src, &Crs::wgs84(), &to, 1 << 20).unwrap();
            let mut r = reproject(&src, &Crs::wgs84(), &to, &grid, to.epsg());
            r.nodata = Some(-9999.0);
            r.data.iter_mut().filter(|v| v.is_nan()).for_each(|v| *v = -9999.0);
            let path = d.join("dem.tif");
            crate::geotiff::write_dem_geotiff(&path, &r, &to).unwrap();
            let back = crate::geotiff::load_geotiff(&path).unwrap();
            assert_eq!((back.width, back.height, back.origin, back.pixel), (r.width, r.height, r.origin, r.pixel));
            assert_eq!(back.data, r.data);
            assert_eq!(back.nodata, Some(-9999.0));
            let crs = back.crs().unwrap();
            assert!(crs == to, "{crs:?} read back for {to:?}");
            assert_eq!(crs.name(), to.name());
        }
        // projections without an EPSG code go out as user-defined GeoKeys
        // and come back as the same projection (points agree to 1e-6 m)
        for def in [
            "+proj=lcc +lat_1=45 +lat_2=47 +lon_0=7 +datum=WGS84 +units=m",
            "+proj=lcc +lat_1=46 +lat_0=46 +lon_0=7.5 +k=0.9998 +x_0=600000 +y_0=200000 +ellps=GRS80 +units=m",
            "+proj=aea +lat_1=44 +lat_2=48 +lat_0=45 +lon_0=8 +x_0=1000 +y_0=-500 +datum=WGS84 +units=us-ft",
            "+proj=laea +lat_0=46 +lon_0=7 +x_0=4321000 +y_0=3210000 +ellps=GRS80",
            "+proj=merc +lon_0=5 +lat_ts=40 +datum=WGS84 +units=ft",
            "+proj=tmerc +lat_0=46 +lon_0=7 +k=0.9996 +x_0=500000 +ellps=GRS80 +units=m",
            "+proj=stere +lat_0=90 +lat_ts=60 +lon_0=7 +x_0=2000000 +y_0=2000000 +datum=WGS84",
        ] {
            let to = Crs::from_definition(def, "a user's projection").unwrap();
            let grid = covering_grid(&src, &Crs::wgs84(), &to, 1 << 20).unwrap();
            let r = reproject(&src, &Crs::wgs84(), &to, &grid, None);
            let path = d.join("user.tif");
            crate::geotiff::write_dem_geotiff(&path, &r, &to).unwrap();
            let back = crate::geotiff::load_geotiff(&path).unwrap();
            let crs = back.crs().unwrap_or_else(|e| panic!("{def}: {e}"));
            assert_eq!(crs.unit_metres(), to.unit_metres(), "{def}");
            for lon_lat in [[7.0, 46.0], [6.2, 45.1], [8.9, 47.3]] {
                let (a, b) = (Crs::wgs84().point(&crs, lon_lat), Crs::wgs84().point(&to, lon_lat));
                assert!((a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6, "{def}: {a:?} vs {b:?}");
            }
        }
        // a CRS that GeoKeys cannot name (no supported method, or a datum of
        // no known geographic code) is refused, nothing written
        for def in ["+proj=eqc +lon_0=7 +datum=WGS84 +units=m", "+proj=lcc +lat_1=45 +lat_2=47 +lon_0=7 +ellps=intl"] {
            let other = Crs::from_definition(def, "a conic").unwrap();
            let path = d.join("other.tif");
            let e = crate::geotiff::write_dem_geotiff(&path, &src, &other).unwrap_err().to_string();
            assert!(e.contains("a conic") && !path.exists(), "{e}");
        }
        std::fs::remove_dir_all(&d).ok();
    }
}
