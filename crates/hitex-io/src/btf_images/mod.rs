//! Measured BTF image sets in and out.
//!
//! Two naming conventions are read, with the four angles in degrees:
//!
//! * **UBO** (Bonn BTF database, UBO2003 and ATRIUM): zip archives or folders of
//!   `tl015 pl060 tv030 pv120.jpg`, space-separated;
//! * **UTIA** (Prague): folders (or zips) of `tl015_pl060_tv030_pv120.png`,
//!   underscore-separated.
//!
//! `tl`/`pl` are the light's polar angle and azimuth, `tv`/`pv` the view's.
//! Names are parsed leniently: any case, fields in any order, other tokens
//! (a material prefix) and folders inside the archive are allowed, angles
//! may have decimals. Files that do not carry all four angles, hidden files
//! and macOS `__MACOSX` resource forks, and files with other extensions are
//! listed as ignored. `.png`, `.jpg` and `.jpeg` are read through the
//! `image` crate; `.exr` (OpenEXR, half or float, the form of the UTIA
//! database's measured sets) through the `exr` crate, which makes an **HDR**
//! BTF (linear half floats beside the 8-bit display copy, see
//! [`hitex_core::btf::dataset::Hdr`]). A file whose own name lacks the view
//! angles takes them from its folder (UTIA's `tv030_pv120/tl015_pl060.exr`).
//! A set mixing 8-bit images and EXR is refused.
//!
//! EXR channels: `R`, `G`, `B` (primaries from the file's `chromaticities`
//! attribute when it has one, else Rec. 709 / sRGB), or `X`, `Y`, `Z` (CIE
//! 1931, converted to linear sRGB for D65), or `Y` alone (grey); a layer
//! prefix (`rgb.R`) is allowed. Values that are NaN, infinite or negative
//! (also colours outside the sRGB gamut after conversion) are clamped to
//! [0, 65504] and counted in [`ImageSetReport::clamped`].
//!
//! A set whose directions are exactly the target grid (all θ × φ
//! combinations, e.g. one written by [`export_image_set`]) is used as is;
//! any other set (the 81 Bonn directions on rings θ = 0, 15, …, 75° with
//! 1, 6, 12, 18, 20, 24 azimuths) is resampled onto the target grid, see
//! [`import_image_set`].
//!
//! The parts: `names` parses the file names, `sources` lists and reads the
//! files of a folder or zip archive, `openexr` decodes and writes OpenEXR, and
//! `resample` fits image sizes and blends measured directions onto the grid.

mod names;
mod openexr;
mod resample;
mod sources;

use names::*;
pub use openexr::decode_exr_image;
use openexr::*;
use resample::*;
use sources::*;

use crate::IoError;
use crate::image_io::{MAX_IMAGE_FILE_BYTES, write_atomic};
use hitex_core::btf::dataset::half_bits;
use hitex_core::btf::dataset::{MAX_BTF_SIDE, MAX_BTF_TEXELS, checked_size};
use hitex_core::btf::{AngularGrid, Btf};
use hitex_core::texture::{linear_to_srgb_u8, srgb_to_linear};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Most images accepted in one set.
pub const MAX_SET_IMAGES: usize = 1 << 20;

/// Nearest measured views (and lights) blended per target direction.
const NEIGHBOURS: usize = 4;

/// Angular distance (radians) below which a measured direction is the target.
const EXACT_RAD: f64 = 1e-6;

/// Largest difference (degrees) between a named angle and a grid angle for
/// the two to be the same direction (names carry rounded integer degrees).
const MATCH_TOL_DEG: f32 = 0.501;

/// Folder depth searched below an image-set folder.
const MAX_DEPTH: usize = 8;

/// Entries listed at most in error messages.
const LISTED_IN_ERRORS: usize = 20;

/// Entries listed at most in [`ImageSetReport::missing`].
const LISTED_IN_REPORT: usize = 1000;

/// The naming convention of an exported set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convention {
    /// Bonn: `tl015 pl060 tv030 pv120.png` (the Bonn sets are JPEG; we write
    /// PNG, so the extension is `.png`; the importer accepts both).
    Ubo,
    /// UTIA: `tl015_pl060_tv030_pv120.png`.
    Utia,
}

impl Convention {
    /// The file name of one PNG image, angles in integer degrees.
    pub fn file_name(self, tl: u32, pl: u32, tv: u32, pv: u32) -> String {
        self.file_name_as(tl, pl, tv, pv, SetFormat::Png)
    }

    /// The file name of one image in `format`, angles in integer degrees.
    pub fn file_name_as(self, tl: u32, pl: u32, tv: u32, pv: u32, format: SetFormat) -> String {
        let sep = match self {
            Convention::Ubo => ' ',
            Convention::Utia => '_',
        };
        let ext = match format {
            SetFormat::Png => "png",
            SetFormat::Exr => "exr",
        };
        format!("tl{tl:03}{sep}pl{pl:03}{sep}tv{tv:03}{sep}pv{pv:03}.{ext}")
    }
}

/// The image format of an exported set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetFormat {
    /// 8-bit sRGB PNG: the BTF's 8-bit texels (an HDR BTF's display copy).
    Png,
    /// OpenEXR, half-float linear RGB (ZIP compressed): an HDR BTF's values
    /// exactly; an 8-bit BTF's texels decoded from sRGB.
    Exr,
}

/// What [`import_image_set`] found and did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImageSetReport {
    /// Images used (after duplicates and ignored files are set aside).
    pub images: usize,
    /// Distinct measured view directions.
    pub view_dirs: usize,
    /// Distinct measured light directions.
    pub light_dirs: usize,
    /// Measured (view, light) combinations without an image, named as
    /// `tl… pl… tv… pv…` (when resampling: they were filled from their
    /// neighbours; at most 1000 are listed, then a count of the rest).
    pub missing: Vec<String>,
    /// Files whose four angles repeat an earlier file's (in name order); the
    /// first is kept.
    pub duplicated: Vec<String>,
    /// Files whose names do not follow either convention, hidden files, and
    /// files of other types.
    pub ignored: Vec<String>,
    /// Whether the images were resampled onto the target grid.
    pub resampled: bool,
    /// How the target images were made.
    pub method: String,
    /// Whether the set was OpenEXR (the BTF is HDR).
    pub hdr: bool,
    /// EXR values clamped into [0, 65504]: NaN, infinite, negative or out
    /// of the sRGB gamut after conversion.
    pub clamped: u64,
    /// The first file that had a clamped value.
    pub clamped_first: Option<String>,
}

/// Reads a BTF image set (a folder or zip archive named in either convention)
/// onto an angular grid.
///
/// * `grid`: the target grid; `None` takes the set's own grid when its
///   directions are a regular θ list × φ count (all combinations present),
///   else [`AngularGrid::paper`].
/// * `size`: each image is centre-cropped to a square and box-filtered (area
///   weights, in linear light) to `size`×`size`; `None` keeps the images'
///   size. All images of a set must have the same size.
/// * `progress(done, total)`: called after each image read and each target
///   image built (`total` counts both).
///
/// When every target direction is a measured one (within half a degree, as
/// integer-degree names allow), the images are used directly and every
/// target (view, light) combination must have its image, else the error lists
/// the missing ones. Otherwise the set is **resampled**: each target image is
/// an inverse-distance blend in linear light (sRGB decoded, re-encoded after
/// blending) of the 4 nearest measured view directions × the 4 nearest
/// measured light directions, distances being angles between unit vectors on
/// the hemisphere and weights ∝ 1/d² (the product of the view and light
/// weights, renormalised over the combinations that have an image); a
/// measured direction within 1e-6 rad of the target is copied. Target θ
/// beyond the outermost measured ring (grazing angles) is extrapolated by
/// clamping to that ring at the same azimuth. A target whose 4 × 4
/// neighbourhood has no image at all (sparse sets) blends the 4 nearest
/// measured (view, light) pairs by dv² + dl² instead.
///
/// Duplicates (the same four angles twice) keep the first file in name
/// order. Errors name the file: unreadable, corrupt or differently sized
/// images, a set mixing EXR and 8-bit images, or a set with no image named in
/// either convention. EXR sets are blended in their linear values (no
/// encoding), and make an HDR BTF.
pub fn import_image_set(
    path: &Path,
    grid: Option<AngularGrid>,
    size: Option<u32>,
    progress: &dyn Fn(usize, usize),
) -> Result<(Btf, ImageSetReport), IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    if let Some(s) = size
        && (s == 0 || s > MAX_BTF_SIDE)
    {
        return Err(fmt(format!("image size {s} is outside 1..={MAX_BTF_SIDE}")));
    }
    let (mut source, listed) = Source::open(path)?;
    let mut report = ImageSetReport::default();

    // names → kept entries (light, view)
    let mut entries: Vec<(Listed, Dir, Dir)> = Vec::new();
    let mut seen: HashMap<(Key, Key), usize> = HashMap::new();
    // the first EXR and the first 8-bit image: a set is one or the other
    let (mut first_exr, mut first_ldr): (Option<String>, Option<String>) = (None, None);
    for item in listed {
        let mut name = parse_name(&item.base);
        if name == Name::Other
            && !item.base.starts_with('.')
            && let Some(folder) = item.shown.rsplit(['/', '\\']).nth(1)
        {
            // UTIA: the view angles in the folder's name (tv030_pv120/tl015_pl060.exr)
            name = parse_name(&format!("{folder}_{}", item.base));
        }
        match name {
            Name::Other => report.ignored.push(item.shown),
            Name::Image([tl, pl, tv, pv]) | Name::Exr([tl, pl, tv, pv]) => {
                let first = if matches!(name, Name::Exr(_)) { &mut first_exr } else { &mut first_ldr };
                first.get_or_insert_with(|| item.shown.clone());
                if let (Some(e), Some(l)) = (&first_exr, &first_ldr) {
                    return Err(fmt(format!(
                        "the set mixes OpenEXR and 8-bit images ({e} and {l}); import one kind at a time"
                    )));
                }
                if !(0.0..90.0).contains(&tl) || !(0.0..90.0).contains(&tv) {
                    report.ignored.push(item.shown);
                    continue;
                }
                let (light, view) = (Dir::new(tl, pl), Dir::new(tv, pv));
                let key = (light.key(), view.key());
                if seen.contains_key(&key) {
                    report.duplicated.push(item.shown);
                    continue;
                }
                if entries.len() >= MAX_SET_IMAGES {
                    return Err(fmt(format!("more than {MAX_SET_IMAGES} images")));
                }
                seen.insert(key, entries.len());
                entries.push((item, light, view));
            }
        }
    }
    if entries.is_empty() {
        return Err(fmt(format!(
            "no image named like 'tl015 pl060 tv030 pv120.jpg' (Bonn) or 'tl015_pl060_tv030_pv120.png' (UTIA); \
             {} files ignored",
            report.ignored.len()
        )));
    }
    let (views, view_index) = distinct(entries.iter().map(|e| e.2));
    let (lights, light_index) = distinct(entries.iter().map(|e| e.1));
    // (measured view, measured light) → entry
    let pairs: HashMap<(usize, usize), usize> = entries
        .iter()
        .enumerate()
        .filter_map(|(i, e)| Some(((*view_index.get(&e.2.key())?, *light_index.get(&e.1.key())?), i)))
        .collect();
    report.images = entries.len();
    report.view_dirs = views.len();
    report.light_dirs = lights.len();

    // plan: the target grid, and the images used directly or blended
    let both = |g: &AngularGrid| Some((match_grid(g, &views)?, match_grid(g, &lights)?));
    let target = match grid {
        Some(g) => g,
        None => infer_grid(&views, &lights).filter(|g| both(g).is_some()).unwrap_or_else(AngularGrid::paper),
    };
    let d = target.directions();
    let direct = both(&target);
    let needed: Vec<usize> = if let Some((vm, lm)) = &direct {
        let mut slots = Vec::with_capacity(d * d);
        let mut missing = Vec::new();
        'outer: for &mv in vm {
            for &ml in lm {
                match pairs.get(&(mv, ml)) {
                    Some(&e) => slots.push(e),
                    None => {
                        missing.push(combo_name(lights[ml], views[mv]));
                        if missing.len() >= LISTED_IN_ERRORS {
                            break 'outer;
                        }
                    }
                }
            }
        }
        if !missing.is_empty() {
            let (mut mult_v, mut mult_l) = (vec![0u64; views.len()], vec![0u64; lights.len()]);
            vm.iter().for_each(|&i| mult_v[i] += 1);
            lm.iter().for_each(|&i| mult_l[i] += 1);
            let present: u64 = pairs.keys().map(|&(v, l)| mult_v[v] * mult_l[l]).sum();
            let absent = (d * d) as u64 - present;
            return Err(fmt(format!(
                "the images lie on the grid {} but {absent} of its {} (view, light) combinations {} no image: {}{}",
                describe_grid(&target),
                d * d,
                if absent == 1 { "has" } else { "have" },
                missing.join(", "),
                if absent > missing.len() as u64 { ", …" } else { "" }
            )));
        }
        slots
    } else {
        (0..entries.len()).collect()
    };

    // the shape is checked before any image is decoded when the size is given, else after the first
    let mut unique: Vec<usize> = needed.clone();
    unique.sort_unstable();
    unique.dedup();
    let check_shape = |sw: u32, sh: u32| -> Result<(), IoError> {
        checked_size(&target, sw, sh).map_err(|e| {
            fmt(format!(
                "a BTF of {sw}x{sh} texels on the grid {} is too large ({e}); choose a smaller size",
                describe_grid(&target)
            ))
        })?;
        let measured = unique.len() as u64 * sw as u64 * sh as u64;
        if measured > MAX_BTF_TEXELS {
            return Err(fmt(format!(
                "{} images of {sw}x{sh} texels exceed the limit of {MAX_BTF_TEXELS} texels; choose a smaller size",
                unique.len()
            )));
        }
        Ok(())
    };
    if let Some(s) = size {
        check_shape(s, s)?;
    }

    // read the images that are used: 8-bit sRGB, or linear f32 from EXR
    let hdr = first_exr.is_some();
    report.hdr = hdr;
    let lut = linear_lut();
    let total = unique.len() + d * d;
    let mut slot_of = vec![usize::MAX; entries.len()];
    let mut store: Vec<u8> = Vec::new();
    let mut store_hdr: Vec<f32> = Vec::new();
    let mut first: Option<(u32, u32, PathBuf)> = None;
    let (mut sw, mut sh) = (0u32, 0u32);
    for (k, &e) in unique.iter().enumerate() {
        let item = &entries[e].0;
        let at = Source::err_path(path, item);
        let bytes = source.read(path, item)?;
        let (w, h, rgb, linear) = if hdr {
            let img = decode_exr(&bytes, &at)?;
            if img.clamped > 0 {
                report.clamped += img.clamped;
                report.clamped_first.get_or_insert_with(|| item.shown.clone());
            }
            (img.width, img.height, Vec::new(), img.rgb)
        } else {
            let (w, h, rgb) = decode_rgb(&bytes, &at)?;
            (w, h, rgb, Vec::new())
        };
        match &first {
            None => {
                (sw, sh) = size.map_or((w, h), |s| (s, s));
                check_shape(sw, sh)?;
                // 8-bit: 3 bytes a texel read and 3 of the BTF; HDR: 12 read, and
                // 12 + 6 + 3 a texel of the linear BTF, its halves and display copy
                let (per_read, per_out) = if hdr { (12, 21) } else { (3, 3) };
                let texels = crate::limits::product(&[sw as u64, sh as u64]).unwrap_or(u64::MAX);
                let claim = (unique.len() as u64)
                    .checked_mul(per_read)
                    .and_then(|a| Some(a + ((d * d) as u64).checked_mul(per_out)?))
                    .and_then(|a| a.checked_mul(texels));
                crate::limits::check_cap(&format!("{} images of {sw}x{sh} texels", unique.len()), claim)
                    .map_err(|e| fmt(e.to_string()))?;
                if hdr {
                    store_hdr.reserve_exact(unique.len() * sw as usize * sh as usize * 3);
                } else {
                    store.reserve_exact(unique.len() * sw as usize * sh as usize * 3);
                }
                first = Some((w, h, at.clone()));
            }
            Some((w0, h0, p0)) if (*w0, *h0) != (w, h) => {
                return Err(IoError::Format {
                    path: at,
                    message: format!(
                        "image is {w}x{h} but {} is {w0}x{h0}; all images of a set must have the same size",
                        p0.display()
                    ),
                });
            }
            Some(_) => {}
        }
        slot_of[e] = k;
        if hdr {
            store_hdr.extend_from_slice(&fit(linear, w, h, size, |v| v, |v| v));
        } else {
            store.extend_from_slice(&fit(rgb, w, h, size, |c| lut[c as usize], linear_to_srgb_u8));
        }
        progress(k + 1, total);
    }
    let done = unique.len();
    let n = sw as usize * sh as usize * 3;
    let image = |e: usize| &store[slot_of[e] * n..(slot_of[e] + 1) * n];
    let image_hdr = |e: usize| &store_hdr[slot_of[e] * n..(slot_of[e] + 1) * n];
    // the 8-bit BTF (an HDR one is made from the linear values at the end)
    let mut btf = match hdr {
        true => None,
        false => Some(Btf::zeroed(target.clone(), sw, sh).map_err(|e| IoError::from(e).in_file(path))?),
    };
    // the HDR BTF's linear values, image by image
    let mut linear_out: Vec<f32> = if hdr { vec![0.0; d * d * n] } else { Vec::new() };
    let to_btf = |btf: Option<Btf>, linear_out: Vec<f32>| -> Result<Btf, IoError> {
        match btf {
            Some(b) => Ok(b),
            None => Btf::from_linear(target.clone(), sw, sh, &linear_out).map_err(|e| IoError::from(e).in_file(path)),
        }
    };

    if direct.is_some() {
        for (idx, &e) in needed.iter().enumerate() {
            match btf.as_mut() {
                Some(b) => b.image_mut(idx / d, idx % d).copy_from_slice(image(e)),
                None => linear_out[idx * n..(idx + 1) * n].copy_from_slice(image_hdr(e)),
            }
            progress(done + idx + 1, total);
        }
        report.resampled = false;
        report.method = format!("direct: the images lie on the grid {}; no resampling", describe_grid(&target));
        return Ok((to_btf(btf, linear_out)?, report));
    }

    // resampling
    let missing_count = views.len() * lights.len() - pairs.len();
    'm: for (mv, &view) in views.iter().enumerate() {
        for (ml, &light) in lights.iter().enumerate() {
            if !pairs.contains_key(&(mv, ml)) {
                if report.missing.len() >= LISTED_IN_REPORT {
                    report.missing.push(format!("… and {} more", missing_count - LISTED_IN_REPORT));
                    break 'm;
                }
                report.missing.push(combo_name(light, view));
            }
        }
    }
    let view_vecs: Vec<[f64; 3]> = views.iter().map(|v| v.vector()).collect();
    let light_vecs: Vec<[f64; 3]> = lights.iter().map(|v| v.vector()).collect();
    let view_max = views.iter().map(|v| v.theta).fold(0.0, f32::max);
    let light_max = lights.iter().map(|v| v.theta).fold(0.0, f32::max);
    let light_lookups: Vec<[f64; 3]> = (0..d).map(|l| lookup(&target, l, light_max)).collect();
    let light_nbrs: Vec<Vec<(usize, f32)>> = light_lookups.iter().map(|&t| neighbours(t, &light_vecs)).collect();
    let mut pair_list: Vec<(usize, usize, usize)> = pairs.iter().map(|(&(v, l), &e)| (v, l, e)).collect();
    pair_list.sort_unstable();
    let mut acc = vec![0f32; n];
    let mut fallbacks = 0usize;
    for v in 0..d {
        let vt = lookup(&target, v, view_max);
        let vn = neighbours(vt, &view_vecs);
        for (l, ln) in light_nbrs.iter().enumerate() {
            let mut blend: Vec<(usize, f32)> = Vec::with_capacity(vn.len() * ln.len());
            for &(mv, wv) in &vn {
                for &(ml, wl) in ln {
                    if let Some(&e) = pairs.get(&(mv, ml)) {
                        blend.push((e, wv * wl));
                    }
                }
            }
            let mut wsum: f32 = blend.iter().map(|b| b.1).sum();
            if blend.is_empty() || wsum <= 0.0 {
                fallbacks += 1;
                let lt = light_lookups[l];
                let mut near: Vec<(f64, usize)> = pair_list
                    .iter()
                    .map(|&(mv, ml, e)| (angle(vt, view_vecs[mv]).powi(2) + angle(lt, light_vecs[ml]).powi(2), e))
                    .collect();
                near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                blend = match near.first() {
                    Some(&(x, e)) if x < EXACT_RAD * EXACT_RAD => vec![(e, 1.0)],
                    _ => near.iter().take(NEIGHBOURS).map(|&(x, e)| (e, (1.0 / x) as f32)).collect(),
                };
                wsum = blend.iter().map(|b| b.1).sum();
            }
            acc.iter_mut().for_each(|a| *a = 0.0);
            for &(e, w) in &blend {
                if hdr {
                    for (a, &c) in acc.iter_mut().zip(image_hdr(e)) {
                        *a += w * c;
                    }
                } else {
                    for (a, &c) in acc.iter_mut().zip(image(e)) {
                        *a += w * lut[c as usize];
                    }
                }
            }
            let inv = if wsum > 0.0 { 1.0 / wsum } else { 0.0 };
            match btf.as_mut() {
                Some(b) => {
                    for (o, &a) in b.image_mut(v, l).iter_mut().zip(&acc) {
                        *o = linear_to_srgb_u8(a * inv);
                    }
                }
                None => {
                    let i = v * d + l;
                    for (o, &a) in linear_out[i * n..(i + 1) * n].iter_mut().zip(&acc) {
                        *o = a * inv;
                    }
                }
            }
            progress(done + v * d + l + 1, total);
        }
    }
    report.resampled = true;
    let btf = to_btf(btf, linear_out)?;
    report.method = format!(
        "resampled onto the grid {} by inverse-distance weighting in linear light: per target (view, light), the \
         {NEIGHBOURS} nearest measured views × {NEIGHBOURS} nearest measured lights by angle between unit vectors, \
         weights ∝ 1/d² (exact hits copied); target θ beyond the outermost measured ring ({view_max}° view, \
         {light_max}° light) clamped to that ring at the same azimuth{}",
        describe_grid(&target),
        if fallbacks > 0 {
            format!(
                "; {fallbacks} targets without a measured neighbour pair used the {NEIGHBOURS} nearest measured pairs"
            )
        } else {
            String::new()
        }
    );
    Ok((btf, report))
}

/// Writes every image of `btf` as an RGB PNG into `dir` (created if needed),
/// each atomically, named in `convention` with the angles rounded to integer
/// degrees (φ of azimuth `j` is `j · 360 / phi_count`). Bonn names end in
/// `.png` too, since the files are PNG. Returns the number of files written.
/// A grid whose angles round to the same integer degree is refused (the
/// names would collide).
pub fn export_image_set(btf: &Btf, dir: &Path, convention: Convention) -> Result<usize, IoError> {
    export_image_set_with(btf, dir, convention, &mut |_, _| {})
}

/// [`export_image_set`], calling `progress(done, total)` after each image.
pub fn export_image_set_with(
    btf: &Btf,
    dir: &Path,
    convention: Convention,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<usize, IoError> {
    export_image_set_as(btf, dir, convention, SetFormat::Png, progress)
}
/// [`export_image_set_with`] in a chosen image format.
pub fn export_image_set_as(
    btf: &Btf,
    dir: &Path,
    convention: Convention,
    format: SetFormat,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<usize, IoError> {
    let g = btf.grid();
    let theta: Vec<u32> = g.theta_deg().iter().map(|t| t.round() as u32).collect();
    let phi: Vec<u32> = (0..g.phi_count()).map(|j| g.phi_deg(j).round() as u32 % 360).collect();
    for (what, list) in [("polar", &theta), ("azimuth", &phi)] {
        let unique: BTreeSet<u32> = list.iter().copied().collect();
        if unique.len() != list.len() {
            return Err(IoError::Format {
                path: dir.to_path_buf(),
                message: format!(
                    "two {what} angles of the grid round to the same integer degree ({list:?}); the file names would collide"
                ),
            });
        }
    }
    crate::image_io::create_output_dir(dir)?;
    let (w, h) = (btf.width(), btf.height());
    let pc = g.phi_count();
    let mut count = 0;
    for v in 0..g.directions() {
        for l in 0..g.directions() {
            let name = convention.file_name_as(theta[l / pc], phi[l % pc], theta[v / pc], phi[v % pc], format);
            let path = dir.join(name);
            let buf = match format {
                SetFormat::Png => {
                    use image::ImageEncoder;
                    let mut buf = Vec::new();
                    image::codecs::png::PngEncoder::new(&mut buf)
                        .write_image(btf.image(v, l), w, h, image::ExtendedColorType::Rgb8)
                        .map_err(|e| IoError::Write { path: path.clone(), message: e.to_string() })?;
                    buf
                }
                SetFormat::Exr => {
                    exr_bytes(btf, v, l).map_err(|message| IoError::Write { path: path.clone(), message })?
                }
            };
            write_atomic(&path, &buf)?;
            count += 1;
            progress(count, g.directions() * g.directions());
        }
    }
    Ok(count)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn tmpdir(name: &str) -> crate::test_dir::TestDir {
        crate::test_dir::TestDir::fresh(&format!("io-btf-images-{name}"))
    }

    fn noise(seed: u32, n: usize) -> Vec<u8> {
        let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(12345);
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                (s >> 24) as u8
            })
            .collect()
    }

    fn small_btf() -> Btf {
        let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 4).unwrap();
        let n = checked_size(&grid, 4, 4).unwrap();
        Btf::new(grid, 4, 4, noise(1, n)).unwrap()
    }

    fn png(w: u32, h: u32, rgb: &[u8]) -> Vec<u8> {
        use image::ImageEncoder;
        let mut buf = Vec::new();
        image::codecs::png::PngEncoder::new(&mut buf).write_image(rgb, w, h, image::ExtendedColorType::Rgb8).unwrap();
        buf
    }

    fn quiet(_: usize, _: usize) {}

    #[test]
    fn btf_names_parse_leniently() {
        assert_eq!(parse_name("tl015 pl060 tv030 pv120.jpg"), Name::Image([15.0, 60.0, 30.0, 120.0]));
        assert_eq!(parse_name("TL000_PL000_TV075_PV345.PNG"), Name::Image([0.0, 0.0, 75.0, 345.0]));
        assert_eq!(parse_name("wool_tv030_pv120_tl015_pl060.jpeg"), Name::Image([15.0, 60.0, 30.0, 120.0]));
        assert_eq!(parse_name("tl15.5 pl0 tv0 pv0.png"), Name::Image([15.5, 0.0, 0.0, 0.0]));
        assert_eq!(parse_name("tl000_pl000_tv000_pv000.exr"), Name::Exr([0.0; 4]));
        for bad in [
            "readme.txt",
            "tl000 pl000 tv000.png",
            "tl000 pl000 tv000 pv000.txt",
            "._tl000 pl000 tv000 pv000.jpg",
            "tl000 tl010 pl000 tv000 pv000.png",
            "tl000 pl000 tv000 pv000",
        ] {
            assert_eq!(parse_name(bad), Name::Other, "{bad}");
        }
    }

    #[test]
    fn btf_image_set_round_trips_in_both_conventions() {
        let btf = small_btf();
        for (conv, sample) in
            [(Convention::Ubo, "tl030 pl090 tv060 pv270.png"), (Convention::Utia, "tl030_pl090_tv060_pv270.png")]
        {
            let d = tmpdir(&format!("rt-{conv:?}"));
            assert_eq!(export_image_set(&btf, &d.join("set"), conv).unwrap(), 144);
            assert!(d.join("set").join(sample).is_file());
            let calls = std::cell::Cell::new(0);
            let (back, rep) = import_image_set(&d.join("set"), None, None, &|_, t| {
                calls.set(calls.get() + 1);
                assert_eq!(t, 288);
            })
            .unwrap();
            assert_eq!(calls.get(), 288);
            assert!(!rep.resampled, "{}", rep.method);
            assert!(rep.method.starts_with("direct"), "{}", rep.method);
            assert_eq!((rep.images, rep.view_dirs, rep.light_dirs), (144, 12, 12));
            assert!(rep.missing.is_empty() && rep.duplicated.is_empty() && rep.ignored.is_empty());
            assert_eq!(back, btf);
            // the same grid asked for explicitly
            let (again, _) = import_image_set(&d.join("set"), Some(btf.grid().clone()), None, &quiet).unwrap();
            assert_eq!(again, btf);
        }
    }

    #[test]
    fn btf_image_set_from_a_zip_with_folders() {
        let btf = small_btf();
        let d = tmpdir("zip");
        export_image_set(&btf, &d.join("set"), Convention::Ubo).unwrap();
        let zp = d.join("set.zip");
        let mut z = zip::ZipWriter::new(std::fs::File::create(&zp).unwrap());
        let opts = zip::write::SimpleFileOptions::default();
        z.add_directory("wool/", opts).unwrap();
        let mut names: Vec<_> = std::fs::read_dir(d.join("set")).unwrap().map(|e| e.unwrap().file_name()).collect();
        names.sort();
        for (i, name) in names.iter().enumerate() {
            let bytes = std::fs::read(d.join("set").join(name)).unwrap();
            let mut entry = format!("wool/rectified/{}", name.to_string_lossy());
            if i % 2 == 0 {
                entry = entry.to_uppercase();
            }
            z.start_file(entry, opts).unwrap();
            z.write_all(&bytes).unwrap();
        }
        z.start_file("wool/readme.txt", opts).unwrap();
        z.write_all(b"Bonn BTF").unwrap();
        z.start_file("__MACOSX/wool/._tl000 pl000 tv000 pv000.png", opts).unwrap();
        z.write_all(b"resource fork").unwrap();
        z.finish().unwrap();
        let (back, rep) = import_image_set(&zp, None, None, &quiet).unwrap();
        assert_eq!(back, btf);
        assert_eq!(rep.ignored.len(), 2, "{:?}", rep.ignored);
        assert!(rep.ignored.iter().any(|n| n.ends_with("readme.txt")));
        assert!(!rep.resampled);
    }

    /// Seven directions on three rings, all 49 (view, light) images.
    fn irregular_set(dir: &Path) -> Vec<(Dir, Dir, Vec<u8>)> {
        let dirs = [(0, 0), (30, 0), (30, 120), (30, 240), (60, 60), (60, 180), (60, 300)];
        std::fs::create_dir_all(dir).unwrap();
        let mut out = Vec::new();
        for (i, &(tv, pv)) in dirs.iter().enumerate() {
            for (j, &(tl, pl)) in dirs.iter().enumerate() {
                let rgb = noise((i * 7 + j) as u32 + 100, 4 * 4 * 3);
                let name = Convention::Ubo.file_name(tl, pl, tv, pv).replace(".png", ".jpg");
                // JPEG names with PNG content: the content decides
                std::fs::write(dir.join(name), png(4, 4, &rgb)).unwrap();
                out.push((Dir::new(tv as f32, pv as f32), Dir::new(tl as f32, pl as f32), rgb));
            }
        }
        out
    }

    #[test]
    fn btf_irregular_sets_are_resampled() {
        let d = tmpdir("irregular");
        let set = irregular_set(&d.join("set"));
        let (btf, rep) = import_image_set(&d.join("set"), None, None, &quiet).unwrap();
        assert!(rep.resampled);
        assert!(rep.method.contains("inverse-distance") && rep.method.contains("clamped"), "{}", rep.method);
        assert_eq!((rep.images, rep.view_dirs, rep.light_dirs), (49, 7, 7));
        assert!(rep.missing.is_empty());
        assert_eq!(btf.grid(), &AngularGrid::paper());
        let g = btf.grid();
        // measured directions on the paper grid: (0, 0) → (0, 0); (30, 0) → (3, 0); (60, 180) → (6, 8)
        for ((tv, pv), (tl, pl)) in [((0, 0), (0, 0)), ((3, 0), (6, 8)), ((6, 8), (3, 0)), ((0, 5), (6, 8))] {
            let (v, l) = (g.direction(tv, pv), g.direction(tl, pl));
            let vd = Dir::new(g.theta_deg()[tv], if tv == 0 { 0.0 } else { g.phi_deg(pv) });
            let ld = Dir::new(g.theta_deg()[tl], if tl == 0 { 0.0 } else { g.phi_deg(pl) });
            let (_, _, want) = set.iter().find(|(a, b, _)| a.key() == vd.key() && b.key() == ld.key()).unwrap();
            for (a, b) in btf.image(v, l).iter().zip(want) {
                assert!((*a as i32 - *b as i32).abs() <= 1, "{a} vs {b}");
            }
        }
        // a grazing target (θ = 70°) blends the 60° ring at its azimuth: (60, 180) is exact there
        let (v, l) = (g.direction(7, 8), g.direction(0, 0));
        let (_, _, want) = set.iter().find(|(a, b, _)| a.key() == (6000, 18000) && b.key() == (0, 0)).unwrap();
        assert_eq!(btf.image(v, l), &want[..]);
        // size: a 2x2 box filter of every image
        let (small, _) = import_image_set(&d.join("set"), None, Some(2), &quiet).unwrap();
        assert_eq!((small.width(), small.height()), (2, 2));
        let lut = linear_lut();
        let want = fit(set[0].2.clone(), 4, 4, Some(2), |c: u8| lut[c as usize], linear_to_srgb_u8);
        let mean = (lut[set[0].2[0] as usize]
            + lut[set[0].2[3] as usize]
            + lut[set[0].2[12] as usize]
            + lut[set[0].2[15] as usize])
            / 4.0;
        assert_eq!(want[0], linear_to_srgb_u8(mean));
        assert!(small.image(0, 0).iter().zip(&want).all(|(a, b)| (*a as i32 - *b as i32).abs() <= 1));
    }

    #[test]
    fn btf_image_set_sparse_and_duplicated() {
        let d = tmpdir("sparse");
        let set = irregular_set(&d.join("set"));
        // drop one combination and duplicate another under the other convention
        std::fs::remove_file(d.join("set").join("tl030 pl120 tv060 pv300.jpg")).unwrap();
        std::fs::write(d.join("set").join("tl000_pl000_tv000_pv000.png"), png(4, 4, &set[1].2)).unwrap();
        std::fs::write(d.join("set").join("notes.md"), b"x").unwrap();
        let (btf, rep) = import_image_set(&d.join("set"), None, None, &quiet).unwrap();
        assert_eq!(rep.missing, vec!["tl030 pl120 tv060 pv300".to_string()]);
        assert_eq!(rep.duplicated, vec!["tl000_pl000_tv000_pv000.png".to_string()]);
        assert_eq!(rep.ignored, vec!["notes.md".to_string()]);
        assert_eq!(rep.images, 48);
        // the first file is kept
        assert_eq!(btf.image(0, 0), &set[0].2[..]);
    }

    #[test]
    fn btf_image_set_errors_name_the_file() {
        let btf = small_btf();
        let d = tmpdir("errors");
        let set = d.join("set");
        export_image_set(&btf, &set, Convention::Utia).unwrap();
        // missing image of a regular set
        std::fs::remove_file(set.join("tl030_pl090_tv060_pv270.png")).unwrap();
        let e = import_image_set(&set, None, None, &quiet).unwrap_err().to_string();
        assert!(e.contains("tl030 pl090 tv060 pv270") && e.contains("1 of its 144"), "{e}");
        export_image_set(&btf, &set, Convention::Utia).unwrap();
        // corrupt image
        let f = set.join("tl000_pl000_tv030_pv180.png");
        std::fs::write(&f, b"\x89PNG\r\n\x1a\n garbage").unwrap();
        let e = import_image_set(&set, None, None, &quiet).unwrap_err().to_string();
        assert!(e.contains("tl000_pl000_tv030_pv180.png"), "{e}");
        // a different size
        std::fs::write(&f, png(2, 2, &[9; 12])).unwrap();
        let e = import_image_set(&set, None, None, &quiet).unwrap_err().to_string();
        assert!(e.contains("tl000_pl000_tv030_pv180.png") && e.contains("same size"), "{e}");
        std::fs::remove_file(&f).unwrap();
        // an EXR among PNGs
        std::fs::write(set.join("tl000_pl000_tv030_pv180.exr"), b"v/1\x01").unwrap();
        let e = import_image_set(&set, None, None, &quiet).unwrap_err().to_string();
        assert!(e.contains("mixes OpenEXR and 8-bit") && e.contains("tl000_pl000_tv030_pv180.exr"), "{e}");
        // nothing usable; not a folder or zip; missing path; absurd size
        let empty = d.join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        std::fs::write(empty.join("a.txt"), b"x").unwrap();
        assert!(import_image_set(&empty, None, None, &quiet).unwrap_err().to_string().contains("1 files ignored"));
        let e = import_image_set(&empty.join("a.txt"), None, None, &quiet).unwrap_err().to_string();
        assert!(e.contains("a.txt") && e.contains("zip"), "{e}");
        assert!(import_image_set(&d.join("nope"), None, None, &quiet).unwrap_err().to_string().contains("nope"));
        assert!(import_image_set(&empty, None, Some(0), &quiet).is_err());
        // a BTF too large for the target grid is refused before the images are read
        let set2 = d.join("set2");
        irregular_set(&set2);
        let e = import_image_set(&set2, None, Some(1024), &quiet).unwrap_err().to_string();
        assert!(e.contains("too large"), "{e}");
    }

    /// An analytic HDR value of texel `i` of image (view, light): above 1
    /// for many texels, never representable in 8 bits.
    fn hdr_value(view: usize, light: usize, i: usize) -> f32 {
        0.003 + 0.37 * (i % 7) as f32 + 1.9 * light as f32 / 11.0 + 0.011 * view as f32 + 0.5 * (i % 3) as f32
    }

    fn hdr_btf() -> Btf {
        let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 4).unwrap();
        let d = grid.directions();
        let n = 4 * 4 * 3;
        let linear: Vec<f32> = (0..d * d * n).map(|k| hdr_value(k / n / d, k / n % d, k % n)).collect();
        Btf::from_linear(grid, 4, 4, &linear).unwrap()
    }

    /// An EXR file of named channels from f32 planes (stored as `half` or f32).
    fn exr_file(w: usize, h: usize, planes: &[(&str, Vec<f32>)], half: bool) -> Vec<u8> {
        use exr::prelude::*;
        let chans: Vec<AnyChannel<FlatSamples>> = planes
            .iter()
            .map(|(n, v)| {
                let data = if half {
                    FlatSamples::F16(v.iter().map(|&x| f16::from_f32(x)).collect())
                } else {
                    FlatSamples::F32(v.clone())
                };
                AnyChannel::new(*n, data)
            })
            .collect();
        let layer =
            Layer::new((w, h), LayerAttributes::default(), Encoding::FAST_LOSSLESS, AnyChannels::sort(chans.into()));
        let mut out = std::io::Cursor::new(Vec::new());
        Image::from_layer(layer).write().to_buffered(&mut out).unwrap();
        out.into_inner()
    }

    #[test]
    fn btf_exr_sets_round_trip_at_half_precision() {
        let btf = hdr_btf();
        assert!(btf.is_hdr());
        let h = btf.hdr().unwrap();
        // values above 1: the display copy is scaled down by the 99.9th percentile
        assert!(h.ldr_scale < 0.5, "{}", h.ldr_scale);
        let d = tmpdir("exr-rt");
        let set = d.join("set");
        let n = export_image_set_as(&btf, &set, Convention::Utia, SetFormat::Exr, &mut |_, _| {}).unwrap();
        assert_eq!(n, 144);
        assert!(set.join("tl030_pl090_tv060_pv270.exr").is_file());
        let (back, rep) = import_image_set(&set, None, None, &quiet).unwrap();
        assert!(rep.hdr && rep.clamped == 0 && !rep.resampled, "{rep:?}");
        // the half floats come back bit for bit, so the values are those written to half precision
        assert_eq!(back.hdr(), btf.hdr());
        assert_eq!(back, btf);
        let g = btf.grid().directions();
        for (k, &hb) in back.hdr().unwrap().half.iter().enumerate() {
            let want = hdr_value(k / 48 / g, k / 48 % g, k % 48);
            let got = hitex_core::btf::dataset::half_value(hb);
            assert!((got - want).abs() <= want * 4.9e-4, "{k}: {got} vs {want}");
        }
        // PNG export writes the display copy; 8-bit BTFs export to EXR decoded from sRGB
        let png_set = d.join("png");
        export_image_set_as(&btf, &png_set, Convention::Utia, SetFormat::Png, &mut |_, _| {}).unwrap();
        let (ldr, rep) = import_image_set(&png_set, None, None, &quiet).unwrap();
        assert!(!rep.hdr && !ldr.is_hdr());
        assert_eq!(ldr.texels(), btf.texels());
        let small = small_btf();
        let e8 = d.join("e8");
        export_image_set_as(&small, &e8, Convention::Ubo, SetFormat::Exr, &mut |_, _| {}).unwrap();
        let (lifted, _) = import_image_set(&e8, None, None, &quiet).unwrap();
        assert!(lifted.is_hdr());
        assert_eq!(lifted.texels(), small.texels(), "sRGB → half → sRGB keeps every 8-bit code");
    }

    #[test]
    fn btf_exr_float_xyz_grey_and_utia_folders() {
        let grid = AngularGrid::new(vec![0.0, 45.0], 2).unwrap();
        let d = tmpdir("exr-kinds");
        let (w, h) = (3, 2);
        let rgb_of = |k: usize| [0.2 + 0.1 * k as f32, 1.5 + 0.05 * k as f32, 0.7];
        // XYZ of a linear sRGB colour (the inverse of the reader's matrix)
        let to_xyz = |c: [f32; 3]| {
            let m = [
                [0.4124564, 0.3575761, 0.1804375],
                [0.2126729, 0.7151522, 0.0721750],
                [0.0193339, 0.119192, 0.9503041],
            ];
            [0, 1, 2].map(|r| m[r][0] * c[0] + m[r][1] * c[1] + m[r][2] * c[2])
        };
        for kind in ["float", "xyz", "grey"] {
            let set = d.join(kind);
            for (vi, &(tv, pv)) in [(0, 0), (45, 0), (45, 180)].iter().enumerate() {
                let _ = vi;
                // UTIA: one folder per view, the file names carry the light
                let folder = set.join(format!("tv{tv:03}_pv{pv:03}"));
                std::fs::create_dir_all(&folder).unwrap();
                for &(tl, pl) in &[(0, 0), (45, 0), (45, 180)] {
                    let k = (tv + pv + tl + pl) as usize / 45;
                    let c = rgb_of(k);
                    let planes: Vec<(&str, Vec<f32>)> = match kind {
                        "float" => vec![("R", vec![c[0]; w * h]), ("G", vec![c[1]; w * h]), ("B", vec![c[2]; w * h])],
                        "xyz" => {
                            let x = to_xyz(c);
                            vec![("X", vec![x[0]; w * h]), ("Y", vec![x[1]; w * h]), ("Z", vec![x[2]; w * h])]
                        }
                        _ => vec![("Y", vec![c[1]; w * h])],
                    };
                    std::fs::write(
                        folder.join(format!("tl{tl:03}_pl{pl:03}.exr")),
                        exr_file(w, h, &planes, kind != "float"),
                    )
                    .unwrap();
                }
            }
            let (btf, rep) = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap();
            // θ = 0 is on the grid once per azimuth: filled by exact copies (a resampling)
            assert!(rep.hdr && rep.ignored.is_empty(), "{kind}: {rep:?}");
            assert_eq!(rep.images, 9);
            let g = btf.grid();
            for (v, &(tv, pv)) in [(0u32, 0u32), (45, 0), (45, 180)].iter().enumerate() {
                for (l, &(tl, pl)) in [(0u32, 0u32), (45, 0), (45, 180)].iter().enumerate() {
                    let _ = (v, l);
                    let dir = |t: u32, p: u32| if t == 0 { 0 } else { g.phi_count() + (p / 180) as usize };
                    let got = btf.texel_linear(dir(tv, pv), dir(tl, pl), 2, 1);
                    let c = rgb_of((tv + pv + tl + pl) as usize / 45);
                    let want = if kind == "grey" { [c[1]; 3] } else { c };
                    for ch in 0..3 {
                        assert!(
                            (got[ch] - want[ch]).abs() <= 4e-3 * want[ch].max(0.1),
                            "{kind} {ch}: {got:?} vs {want:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn exr_chromaticities_map_the_files_white_to_srgb_white() {
        // Rec. 709 itself; CIE XYZ stored as RGB (white E, a blue of y = 0); ACES AP0 (white ≈ D60)
        let xyz_e = [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0], [1.0 / 3.0, 1.0 / 3.0]];
        let ap0 = [[0.7347, 0.2653], [0.0, 1.0], [0.0001, -0.077], [0.32168, 0.33767]];
        for c in [REC709, xyz_e, ap0] {
            let m = mul3(&XYZ_TO_SRGB, &rgb_to_xyz(&c).unwrap());
            for (r, row) in m.iter().enumerate() {
                let white: f64 = row.iter().sum();
                assert!((white - 1.0).abs() < 2e-3, "{c:?}: row {r} maps white to {white}");
            }
        }
        // Rec. 709 primaries give the identity
        let m = mul3(&XYZ_TO_SRGB, &rgb_to_xyz(&REC709).unwrap());
        for (r, row) in m.iter().enumerate() {
            for (k, &v) in row.iter().enumerate() {
                assert!((v - if r == k { 1.0 } else { 0.0 }).abs() < 2e-3, "{m:?}");
            }
        }
        // a degenerate white is refused
        assert!(rgb_to_xyz(&[[0.64, 0.33], [0.3, 0.6], [0.15, 0.06], [0.3, 0.0]]).is_none());
    }

    #[test]
    fn btf_exr_bad_input_is_refused_or_clamped_and_said() {
        let d = tmpdir("exr-bad");
        let grid = AngularGrid::new(vec![0.0], 1).unwrap();
        let one = |set: &Path, planes: &[(&str, Vec<f32>)], w: usize, h: usize| {
            std::fs::create_dir_all(set).unwrap();
            std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), exr_file(w, h, planes, true)).unwrap();
        };
        // missing channels: named
        let set = d.join("missing");
        one(&set, &[("R", vec![1.0; 4]), ("G", vec![1.0; 4])], 2, 2);
        let e = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap_err().to_string();
        assert!(
            e.contains("tl000_pl000_tv000_pv000.exr") && e.contains("G, R") && e.contains("needs R, G and B"),
            "{e}"
        );
        // NaN, infinite and negative values: clamped and counted
        let set = d.join("nan");
        one(
            &set,
            &[("R", vec![f32::NAN, 1.0, -2.0, 0.5]), ("G", vec![f32::INFINITY, 0.0, 0.0, 0.0]), ("B", vec![0.25; 4])],
            2,
            2,
        );
        let (btf, rep) = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap();
        assert_eq!(rep.clamped, 3, "{rep:?}");
        assert_eq!(rep.clamped_first.as_deref(), Some("tl000_pl000_tv000_pv000.exr"));
        assert_eq!(btf.texel_linear(0, 0, 0, 0), [0.0, 65504.0, 0.25]);
        assert_eq!(btf.texel_linear(0, 0, 0, 1)[0], 0.0);
        // mixed sizes
        let set = d.join("sizes");
        let g2 = AngularGrid::new(vec![0.0, 40.0], 1).unwrap();
        std::fs::create_dir_all(&set).unwrap();
        let rgb = |n: usize| vec![("R", vec![0.5; n]), ("G", vec![0.5; n]), ("B", vec![0.5; n])];
        for (i, (tl, tv)) in [(0, 0), (0, 40), (40, 0), (40, 40)].iter().enumerate() {
            let (w, h) = if i == 3 { (3, 2) } else { (2, 2) };
            std::fs::write(set.join(format!("tl{tl:03}_pl000_tv{tv:03}_pv000.exr")), exr_file(w, h, &rgb(w * h), true))
                .unwrap();
        }
        let e = import_image_set(&set, Some(g2), None, &quiet).unwrap_err().to_string();
        assert!(e.contains("tl040_pl000_tv040_pv000.exr") && e.contains("same size"), "{e}");
        // not an EXR at all; a truncated one
        let set = d.join("junk");
        std::fs::create_dir_all(&set).unwrap();
        std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), b"v/1\x01junk").unwrap();
        let e = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap_err().to_string();
        assert!(e.contains("tl000_pl000_tv000_pv000.exr") && e.contains("OpenEXR"), "{e}");
        let good = exr_file(4, 4, &rgb(16), true);
        for cut in [20, good.len() / 2, good.len() - 3] {
            std::fs::write(set.join("tl000_pl000_tv000_pv000.exr"), &good[..cut]).unwrap();
            let e = import_image_set(&set, Some(grid.clone()), None, &quiet).unwrap_err().to_string();
            assert!(e.contains("tl000_pl000_tv000_pv000.exr"), "{cut}: {e}");
        }
    }

    #[test]
    fn btf_exr_sets_resample_in_linear_light() {
        // an irregular HDR set: the blend is in linear values, above 1 kept
        let d = tmpdir("exr-resample");
        let set = d.join("set");
        std::fs::create_dir_all(&set).unwrap();
        let rgb = |v: f32| vec![("R", vec![v; 4]), ("G", vec![v; 4]), ("B", vec![v; 4])];
        for (tv, pv) in [(0, 0), (20, 0), (20, 120), (20, 240)] {
            for (tl, pl) in [(0, 0), (20, 0), (20, 120), (20, 240)] {
                std::fs::write(
                    set.join(format!("tl{tl:03}_pl{pl:03}_tv{tv:03}_pv{pv:03}.exr")),
                    exr_file(2, 2, &rgb(4.0), true),
                )
                .unwrap();
            }
        }
        let target = AngularGrid::new(vec![0.0, 10.0], 4).unwrap();
        let (btf, rep) = import_image_set(&set, Some(target), None, &quiet).unwrap();
        assert!(rep.resampled && rep.hdr, "{rep:?}");
        for h in &btf.hdr().unwrap().half {
            assert_eq!(hitex_core::btf::dataset::half_value(*h), 4.0);
        }
    }

    #[test]
    fn btf_export_refuses_colliding_names() {
        let grid = AngularGrid::new(vec![10.0, 10.4], 2).unwrap();
        let btf = Btf::zeroed(grid, 1, 1).unwrap();
        let d = tmpdir("collide");
        assert!(export_image_set(&btf, &d.join("x"), Convention::Ubo).unwrap_err().to_string().contains("collide"));
    }
}
