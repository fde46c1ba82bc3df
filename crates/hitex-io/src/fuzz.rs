//! Entry points for coverage-guided fuzzing: one per reader, taking arbitrary
//! bytes. The libFuzzer targets in `fuzz/fuzz_targets/` call these, and the
//! regression test (`tests/fuzz_corpus.rs`) replays every checked-in input
//! through the same functions on every test run, so a crash once found stays
//! fixed. The contract is the readers' own: an `Err` with a message or a valid
//! result, never a panic, hang or runaway allocation.

use hitex_core::texture::ColorSpace;
use std::path::Path;

/// A fuzzed reader.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// IGES (entities 128, 144, 142, 102, 126, 110), lenient.
    Iges,
    /// Wavefront OBJ free-form surfaces.
    ObjFreeform,
    /// hitex NURBS JSON.
    NurbsJson,
    /// Scene TOML, parsed and resolved (files are refused).
    Scene,
    /// `.hbtf` BTF files (either kind).
    Hbtf,
    /// `.hbtf` BTFs compressed by local PCA, read, then reconstructed.
    HbtfPca,
    /// BTF image-set file names: one name per line, each made a 4×4 PNG in a
    /// folder that is then imported.
    BtfNames,
    /// GeoTIFF rasters, then hole filling.
    Geotiff,
    /// SRTM `.hgt`: the first line is the file name (e.g. `N34W107`), the
    /// rest the samples, zero-padded to a 1201² tile when the first byte of
    /// the name is odd.
    Hgt,
    /// ESRI ASCII grids.
    AsciiGrid,
    /// numpy `.npy` arrays.
    Npy,
    /// numpy `.npz` archives.
    Npz,
    /// A GST store: `metadata.json` up to the first NUL byte, then one map file.
    Store,
    /// PNG and JPEG images (textures, maps, image sets).
    Image,
    /// STEP (ISO 10303-21) parts and assemblies, read to trimmed patches.
    Step,
    /// Point sets: JSON when the first byte is `{`, XYZ text otherwise.
    Points,
    /// OpenEXR images of BTF image sets, decoded to linear sRGB.
    Exr,
    /// An MBTiles store: the bytes as a file, opened, its level-0 map and
    /// its DEM read.
    Mbtiles,
    /// STL meshes, binary or ASCII.
    Stl,
    /// PLY meshes and point clouds, ASCII or binary.
    Ply,
}

impl Target {
    /// Every target.
    pub const ALL: [Target; 20] = [
        Target::Iges,
        Target::ObjFreeform,
        Target::NurbsJson,
        Target::Scene,
        Target::Hbtf,
        Target::HbtfPca,
        Target::BtfNames,
        Target::Geotiff,
        Target::Hgt,
        Target::AsciiGrid,
        Target::Npy,
        Target::Npz,
        Target::Store,
        Target::Image,
        Target::Step,
        Target::Points,
        Target::Exr,
        Target::Mbtiles,
        Target::Stl,
        Target::Ply,
    ];

    /// The target's name: its folder under `fuzz/` and its fuzz binary.
    pub fn name(self) -> &'static str {
        match self {
            Target::Iges => "iges",
            Target::ObjFreeform => "obj_freeform",
            Target::NurbsJson => "nurbs_json",
            Target::Scene => "scene",
            Target::Hbtf => "hbtf",
            Target::HbtfPca => "hbtf_pca",
            Target::BtfNames => "btf_names",
            Target::Geotiff => "geotiff",
            Target::Hgt => "hgt",
            Target::AsciiGrid => "ascii_grid",
            Target::Npy => "npy",
            Target::Npz => "npz",
            Target::Store => "store",
            Target::Image => "image",
            Target::Step => "step",
            Target::Points => "points",
            Target::Exr => "exr",
            Target::Mbtiles => "mbtiles",
            Target::Stl => "stl",
            Target::Ply => "ply",
        }
    }

    /// The target called `name`.
    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// A compressed BTF read, then reconstructed when the reconstruction is
/// small: its size is bounded only by the memory cap (see
/// [`crate::btf_pca_file::decompressed`]), which the fuzzer's own memory
/// limit is below.
fn hbtf_pca(data: &[u8]) -> bool {
    match crate::btf_pca_file::pca_from_bytes(data, "fuzz.hbtf") {
        Ok(p) if crate::btf_pca_file::reconstruction_bytes(&p) <= 64 << 20 => {
            crate::btf_pca_file::decompressed(&p, Path::new("fuzz.hbtf")).is_ok()
        }
        Ok(_) => true,
        Err(_) => false,
    }
}

/// Runs one input through `target`. Returns whether the reader accepted it
/// (for corpus statistics); a panic is the only failure.
pub fn run(target: Target, data: &[u8]) -> bool {
    let text = || String::from_utf8_lossy(data);
    match target {
        Target::Iges => crate::iges::parse_iges(&text(), "fuzz.igs").is_ok(),
        Target::ObjFreeform => crate::obj_freeform::parse_obj_freeform(&text()).is_ok(),
        Target::NurbsJson => crate::nurbs_json::parse_nurbs_json(&text()).is_ok(),
        Target::Scene => match hitex_core::scene::SceneDesc::from_toml(&text()) {
            Ok(d) => d.resolve(&hitex_core::scene::NoFiles).is_ok(),
            Err(_) => false,
        },
        Target::Hbtf if crate::btf_pca_file::is_pca_file(data) => hbtf_pca(data),
        Target::Hbtf => crate::btf_file::hbtf_from_bytes(data, "fuzz.hbtf").is_ok(),
        Target::HbtfPca => hbtf_pca(data),
        Target::BtfNames => btf_names(data),
        Target::Geotiff => {
            let path = Path::new("fuzz.tif");
            // the overviews of a COG, each read as its own level (at most 4)
            let mut levels_read = false;
            if let Ok(levels) = crate::geotiff::read_levels(std::io::Cursor::new(data), path) {
                for l in 1..levels.levels.len().min(5) {
                    let got =
                        crate::geotiff::parse_geotiff_level(std::io::Cursor::new(data), data.len() as u64, path, l);
                    levels_read |= got.is_ok();
                }
            }
            match crate::geotiff::parse_geotiff(std::io::Cursor::new(data), data.len() as u64, path) {
                Ok(mut r) => {
                    crate::geotiff::fill_holes(&mut r);
                    // its CRS, and a small reprojection into a local frame
                    if let Ok(from) = r.crs() {
                        let (x0, x1, y0, y1) = r.extent();
                        let centre = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
                        let wgs = crate::crs::Crs::wgs84();
                        let c = from.point(&wgs, centre);
                        if let Ok(to) = crate::crs::Crs::local(c[0], c[1])
                            && let Ok(g) = crate::reproject::covering_grid(&r, &from, &to, 1 << 16)
                        {
                            crate::reproject::reproject(&r, &from, &to, &g, None);
                        }
                    }
                    true
                }
                Err(_) => levels_read,
            }
        }
        Target::Hgt => {
            let (name, body) = split_at_byte(data, b'\n');
            let name = String::from_utf8_lossy(name);
            let mut body = body.to_vec();
            if name.as_bytes().first().is_some_and(|b| b % 2 == 1) {
                body.resize(1201 * 1201 * 2, 0);
            }
            let path = format!("{}.hgt", name.trim().replace(['/', '\\', '\0'], "_"));
            dem(&body, Path::new(&path))
        }
        Target::AsciiGrid => dem(data, Path::new("fuzz.asc")),
        Target::Npy => dem(data, Path::new("fuzz.npy")),
        Target::Npz => dem(data, Path::new("fuzz.npz")),
        Target::Store => {
            let (meta, tile) = split_at_byte(data, 0);
            let path = Path::new("store/metadata.json");
            let meta_ok = crate::gst::parse_store_meta(&String::from_utf8_lossy(meta), path).is_ok();
            let tile_ok = crate::gst::decode_tile(tile, Path::new("store/0/0/0.png")).is_ok();
            meta_ok && tile_ok
        }
        Target::Image => crate::decode_image(data, Path::new("fuzz.png"), ColorSpace::Srgb).is_ok(),
        Target::Step => crate::step::parse_step(data, "fuzz.stp", &crate::step::StepOptions::default()).is_ok(),
        Target::Points => crate::points::parse_points(&text(), data.first() == Some(&b'{')).is_ok(),
        Target::Exr => crate::btf_images::decode_exr_image(data, Path::new("fuzz.exr")).is_ok(),
        Target::Mbtiles => {
            // SQLite opens files, not bytes
            static RUN: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
            let k = RUN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let path = std::env::temp_dir().join(format!("hitex-fuzz-{}-{k}.mbtiles", std::process::id()));
            if std::fs::write(&path, data).is_err() {
                return false;
            }
            let ok = match crate::gst::Store::open(&path) {
                Ok(store) => store.read_tile(0, 0, 0).is_ok() && store.dem().is_ok(),
                Err(_) => false,
            };
            let _ = std::fs::remove_file(&path);
            ok
        }
        Target::Stl => match crate::stl::parse_stl(data) {
            // and the search hierarchy built on them, queried once
            Ok(t) => hitex_core::nurbs::deviation::Reference::mesh(t).closest([0.0; 3], f64::INFINITY).is_some(),
            Err(_) => false,
        },
        Target::Ply => match crate::ply::parse_ply(data) {
            // and the search hierarchy built on the mesh, queried once
            Ok(crate::stl::ReferenceData::Mesh(t)) => {
                hitex_core::nurbs::deviation::Reference::mesh(t).closest([0.0; 3], f64::INFINITY).is_some()
            }
            Ok(crate::stl::ReferenceData::Points(p)) => !p.is_empty(),
            Err(_) => false,
        },
    }
}

fn split_at_byte(data: &[u8], sep: u8) -> (&[u8], &[u8]) {
    match data.iter().position(|&b| b == sep) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[]),
    }
}

fn dem(bytes: &[u8], path: &Path) -> bool {
    match crate::dem::parse_elevation(bytes, path) {
        Ok(mut r) => {
            crate::geotiff::fill_holes(&mut r);
            true
        }
        Err(_) => false,
    }
}

/// Makes a folder holding one small PNG per line of `data` and imports it as
/// an image set, with and without a target size.
fn btf_names(data: &[u8]) -> bool {
    static PNG: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    static SERIAL: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let png = PNG.get_or_init(|| {
        let mut out = Vec::new();
        let img = image::RgbImage::from_fn(4, 4, |x, y| image::Rgb([(x * 60) as u8, (y * 60) as u8, 128]));
        // encoding a 4×4 image into memory cannot fail; an empty file is still a valid fuzz input
        let _ = img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png);
        out
    });
    let n = SERIAL.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("hitex-fuzz-names-{}-{n}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    if std::fs::create_dir_all(&dir).is_err() {
        return false;
    }
    for line in String::from_utf8_lossy(data).lines().take(64) {
        let name: String = line.chars().filter(|c| !matches!(c, '/' | '\\' | '\0')).take(120).collect();
        if name.is_empty() || name == "." || name == ".." {
            continue;
        }
        let _ = std::fs::write(dir.join(name), png);
    }
    let none = |_: usize, _: usize| {};
    // the grid inferred from the names (or the paper's 8 × 16 when they form none), one texel per image
    let ok = crate::btf_images::import_image_set(&dir, None, Some(1), &none).is_ok();
    // a small given grid, which irregular sets are resampled onto
    if let Ok(grid) = hitex_core::btf::AngularGrid::new(vec![0.0, 40.0], 3) {
        let _ = crate::btf_images::import_image_set(&dir, Some(grid), Some(2), &none);
    }
    let _ = std::fs::remove_dir_all(&dir);
    ok
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for t in Target::ALL {
            assert_eq!(Target::from_name(t.name()), Some(t));
        }
        assert_eq!(Target::from_name("nope"), None);
    }

    #[test]
    fn every_target_accepts_a_valid_input_and_refuses_garbage() {
        let garbage = b"\x00\xffnot a file of any kind\x01";
        for t in Target::ALL {
            assert!(!run(t, garbage), "{} accepted garbage", t.name());
        }
        assert!(run(Target::Iges, include_bytes!("../data/holed-square.igs")));
        assert!(run(Target::Scene, hitex_core::scene::SHOWCASE_TOML.as_bytes()));
        assert!(run(Target::Step, include_bytes!("../../../fuzz/seeds/step/plate-with-hole.stp")));
        let names = b"tl000 pl000 tv000 pv000.png\ntl045 pl000 tv000 pv000.png\n\
                      tl000 pl000 tv045 pv000.png\ntl045 pl000 tv045 pv000.png\n";
        assert!(run(Target::BtfNames, names));
        // an MBTiles file of hitex's and one made by another tool (no hitex row)
        assert!(run(Target::Mbtiles, include_bytes!("../../../fuzz/seeds/mbtiles/tiny.mbtiles")));
        assert!(run(Target::Mbtiles, include_bytes!("../../../fuzz/seeds/mbtiles/foreign.mbtiles")));
    }
}
