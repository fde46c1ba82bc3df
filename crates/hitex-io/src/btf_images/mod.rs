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
mod tests;
