//! Resolution levels of a GeoTIFF: the full image, then the reduced-resolution
//! images (overviews) that a Cloud-Optimized GeoTIFF carries after it in its
//! chain of IFDs. A view that needs only a coarse picture of a large raster
//! reads one level and decodes nothing finer.
//!
//! An overview is an IFD whose NewSubfileType has bit 0 (reduced resolution)
//! and not bit 2 (a transparency mask). Its georeferencing is the full
//! image's extent over its own pixels, as GDAL writes and reads it (the
//! overview IFDs carry no GeoKeys of their own).

use super::{Claim, GeoRaster, Layout, open_decoder, read_header, read_samples};
use crate::IoError;
use std::io::{Read, Seek};
use std::path::Path;
use tiff::decoder::Decoder;
use tiff::tags::Tag;

/// Most images followed along a file's chain of IFDs.
pub const MAX_IFDS: usize = 64;

/// One resolution level of a GeoTIFF.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Level {
    /// The image's place in the file's chain of IFDs (0: the full image).
    pub ifd: usize,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

/// The levels of a GeoTIFF, finest first (level 0 is the full image), and
/// the images of its chain that are not read as levels.
#[derive(Debug, Clone, PartialEq)]
pub struct Levels {
    /// The full image, then each overview, every one smaller than the one before.
    pub levels: Vec<Level>,
    /// Reduced-resolution images passed over (another sample layout, or not
    /// smaller than the level before) and images that could not be read,
    /// one line each; masks and full-resolution pages are not
    /// levels and are passed over without a word.
    pub notes: Vec<String>,
}

impl Levels {
    /// How many times coarser than the full image level `l` is along x.
    pub fn factor(&self, l: usize) -> f64 {
        self.levels[0].width as f64 / self.levels[l].width as f64
    }

    /// The coarsest level at most `k` times coarser than the full image along
    /// both axes: what a reader that would keep one post of each `k`×`k`
    /// block reads instead of the full image (0 when no overview is fine enough).
    pub fn coarsest_within(&self, k: f64) -> usize {
        let full = self.levels[0];
        let ok = |l: &Level| {
            full.width as f64 / l.width as f64 <= k + 1e-9 && full.height as f64 / l.height as f64 <= k + 1e-9
        };
        self.levels.iter().rposition(ok).unwrap_or(0)
    }

    /// The coarsest level that still holds at least `pixels` pixels (0 when
    /// none but the full image does).
    pub fn coarsest_holding(&self, pixels: u64) -> usize {
        self.levels.iter().rposition(|l| l.width as u64 * l.height as u64 >= pixels).unwrap_or(0)
    }
}

/// Follows the chain of IFDs after the full image (the decoder's current
/// image, of layout `full`), collecting the overviews; leaves the decoder on
/// an arbitrary image.
fn scan<R: Read + Seek>(d: &mut Decoder<R>, full: &Layout) -> Levels {
    let mut levels = vec![Level { ifd: 0, width: full.width, height: full.height }];
    let mut notes = Vec::new();
    let mut ifd = 0;
    while d.more_images() {
        ifd += 1;
        if ifd >= MAX_IFDS {
            notes
                .push(format!("the chain holds more than {MAX_IFDS} images: those past image {MAX_IFDS} are not read"));
            break;
        }
        if let Err(e) = d.next_image() {
            // (a directory that cannot be read ends the chain: `more_images` turns false)
            notes.push(format!("image {ifd} of the chain cannot be read ({e}): passed over"));
            continue;
        }
        let kind = d.find_tag_unsigned::<u32>(Tag::NewSubfileType).ok().flatten().unwrap_or(0);
        if kind & 1 == 0 || kind & 4 != 0 {
            continue;
        }
        let layout = match Layout::of(d) {
            Ok(l) => l,
            Err(m) => {
                notes.push(format!("overview in image {ifd}: {m}: passed over"));
                continue;
            }
        };
        if !layout.same_samples(full) {
            notes.push(format!(
                "overview in image {ifd}: {} bands of another sample type than the full image's {}: passed over",
                layout.bands, full.bands
            ));
            continue;
        }
        let Some(prev) = levels.last() else { continue };
        let (w, h) = (layout.width, layout.height);
        if w > prev.width || h > prev.height || (w, h) == (prev.width, prev.height) {
            notes.push(format!(
                "overview in image {ifd}: {w}×{h} pixels is not smaller than the level before ({}×{}): passed over",
                prev.width, prev.height
            ));
            continue;
        }
        levels.push(Level { ifd, width: w, height: h });
    }
    Levels { levels, notes }
}

/// The levels of the GeoTIFF read from `reader` (`path` names it in errors):
/// the full image must be readable; overviews that are not are passed over
/// and noted.
pub fn read_levels<R: Read + Seek>(reader: R, path: &Path) -> Result<Levels, IoError> {
    let mut d = open_decoder(reader, path)?;
    let full = Layout::of(&mut d).map_err(|m| IoError::Format { path: path.to_path_buf(), message: m })?;
    Ok(scan(&mut d, &full))
}

/// The levels of the GeoTIFF at `path` ([`read_levels`]).
pub fn geotiff_levels(path: &Path) -> Result<Levels, IoError> {
    let file = std::fs::File::open(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    read_levels(std::io::BufReader::new(file), path)
}

/// The georeferencing of `level` of the raster whose full image is `full`:
/// the same extent over the level's pixels.
pub(super) fn level_header(full: &GeoRaster, level: &Level) -> GeoRaster {
    GeoRaster {
        width: level.width,
        height: level.height,
        data: Vec::new(),
        // the factor first: a whole factor scales the pixel exactly (as decimation does)
        pixel: [
            full.pixel[0] * (full.width as f64 / level.width as f64),
            full.pixel[1] * (full.height as f64 / level.height as f64),
        ],
        citation: full.citation.clone(),
        proj4: full.proj4.clone(),
        ..*full
    }
}

/// Positions the decoder on level `level` (after reading the full image's
/// header from it): checks the level exists and its size as `claim` asks;
/// returns the level's georeferenced header and the heights' scale.
pub(super) fn seek_level<R: Read + Seek>(
    d: &mut Decoder<R>,
    len: u64,
    path: &Path,
    level: usize,
    claim: Claim,
) -> Result<(GeoRaster, f64), IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    if level == 0 {
        return read_header(d, len, path, claim);
    }
    // the full image's georeferencing, without reading or claiming its samples
    let (full, z_scale) = read_header(d, len, path, Claim::Header)?;
    let layout = Layout::of(d).map_err(fmt)?;
    let levels = scan(d, &layout);
    let Some(l) = levels.levels.get(level).copied() else {
        let n = levels.levels.len();
        return Err(fmt(format!(
            "level {level}: the file holds {n} level{} (the full image and {} overview{})",
            if n == 1 { "" } else { "s" },
            n - 1,
            if n == 2 { "" } else { "s" }
        )));
    };
    d.seek_to_image(l.ifd).map_err(|e| fmt(format!("overview in image {}: {e}", l.ifd)))?;
    let here = Layout::of(d).map_err(fmt)?;
    here.check(len, claim).map_err(|m| fmt(format!("overview in image {}: {m}", l.ifd)))?;
    Ok((level_header(&full, &l), z_scale))
}

/// Reads level `level` of a GeoTIFF of `len` bytes from `reader` (0: the
/// whole image, as [`super::parse_geotiff`]; 1, 2, …: its overviews, finest
/// first); only that level's samples are decoded and checked against the
/// memory cap.
pub fn parse_geotiff_level<R: Read + Seek>(
    reader: R,
    len: u64,
    path: &Path,
    level: usize,
) -> Result<GeoRaster, IoError> {
    let mut d = open_decoder(reader, path)?;
    let (r, z_scale) = seek_level(&mut d, len, path, level, Claim::Whole)?;
    read_samples(&mut d, r, z_scale, path)
}

/// Reads level `level` of the GeoTIFF at `path` ([`parse_geotiff_level`]).
pub fn load_geotiff_level(path: &Path, level: usize) -> Result<GeoRaster, IoError> {
    let file = std::fs::File::open(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    let len = file.metadata().map_err(|source| IoError::Read { path: path.to_path_buf(), source })?.len();
    parse_geotiff_level(std::io::BufReader::new(file), len, path, level)
}

/// How [`load_for_view`] turns "at least `cap` pixels" into a decimation factor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coarsening {
    /// The factor rounded up (at least 2), as a reader that keeps one post
    /// of each whole k×k block: an overview at most that much coarser.
    WholeBlocks,
    /// The factor as it is: the overview keeps at least `cap` pixels' worth
    /// of detail (imagery resampled onto a view).
    Exact,
}

/// A level read by [`load_for_view`] in place of the full image.
#[derive(Debug, Clone, PartialEq)]
pub struct LevelRead {
    /// The level's samples and georeferencing.
    pub raster: GeoRaster,
    /// Its number (1: the finest overview).
    pub level: usize,
    /// How many overviews the file has.
    pub overviews: usize,
    /// How many times coarser than the full image it is along x.
    pub factor: f64,
    /// The full image's columns and rows.
    pub full: (u32, u32),
}

/// What [`load_for_view`] found: the level read (None: the caller needs the
/// full image) and the lines worth telling a user (overviews passed over, an
/// overview that could not be read and was given up for the full image).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewLevel {
    /// The overview read, or None.
    pub read: Option<LevelRead>,
    /// One line each, without the file's name.
    pub notes: Vec<String>,
}

/// Reads the coarsest level of the GeoTIFF at `path` that still serves a
/// view needing `cap` pixels of it: with `k` = √(full pixels / cap), the
/// coarsest overview at most `k` times coarser (`how` rounds `k`). None in
/// [`ViewLevel::read`] when the full image is within `cap`, the file has no
/// overview fine enough, or the overview chosen cannot be read (said in a
/// note): the caller then reads the full image its own way.
pub fn load_for_view(path: &Path, cap: u64, how: Coarsening) -> Result<ViewLevel, IoError> {
    let levels = geotiff_levels(path)?;
    let mut notes = levels.notes.clone();
    let full = levels.levels[0];
    let pixels = full.width as u64 * full.height as u64;
    if pixels <= cap.max(1) || levels.levels.len() < 2 {
        return Ok(ViewLevel { read: None, notes });
    }
    let k = (pixels as f64 / cap.max(1) as f64).sqrt();
    let l = levels.coarsest_within(match how {
        Coarsening::WholeBlocks => k.ceil().max(2.0),
        Coarsening::Exact => k,
    });
    if l == 0 {
        return Ok(ViewLevel { read: None, notes });
    }
    match load_geotiff_level(path, l) {
        Ok(raster) => Ok(ViewLevel {
            read: Some(LevelRead {
                raster,
                level: l,
                overviews: levels.levels.len() - 1,
                factor: levels.factor(l),
                full: (full.width, full.height),
            }),
            notes,
        }),
        Err(e) => {
            // the caller names the file
            let why = match e {
                IoError::Format { message, .. } => message,
                IoError::Read { source, .. } => source.to_string(),
                other => other.to_string(),
            };
            notes.push(format!("overview {l} cannot be read ({why}); the full image is read instead"));
            Ok(ViewLevel { read: None, notes })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tiled::{cog_bytes, halved, tiled_geotiff_bytes};
    use super::super::{GeoTiffWindows, parse_geotiff};
    use super::*;
    use crate::crs::Crs;
    use std::io::Cursor;

    /// A 200×150 DEM in UTM 32N: a ramp with a hole of nodata.
    fn dem() -> GeoRaster {
        let (w, h) = (200u32, 150u32);
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (40..43).contains(&x) && (20..22).contains(&y) { -9999.0 } else { 100.0 + x as f32 * 0.5 + y as f32 }
            })
            .collect();
        GeoRaster {
            width: w,
            height: h,
            bands: 1,
            data,
            origin: [400_000.0, 5_100_000.0],
            pixel: [30.0, 30.0],
            nodata: Some(-9999.0),
            epsg: Some(32632),
            projection: None,
            citation: None,
            proj4: None,
        }
    }

    fn utm() -> Crs {
        Crs::from_epsg(32632).unwrap()
    }

    #[test]
    fn overviews_are_read_level_by_level() {
        let r = dem();
        let bytes = cog_bytes(&r, &utm(), 64).unwrap();
        let path = Path::new("dem-cog.tif");
        let levels = read_levels(Cursor::new(&bytes), path).unwrap();
        let sizes: Vec<(u32, u32)> = levels.levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(200, 150), (100, 75), (50, 38)]);
        assert_eq!(levels.levels.iter().map(|l| l.ifd).collect::<Vec<_>>(), [0, 1, 2]);
        assert!(levels.notes.is_empty(), "{:?}", levels.notes);
        // level 0 is the whole file, as the whole-file reader gives it
        let len = bytes.len() as u64;
        let whole = parse_geotiff(Cursor::new(&bytes), len, path).unwrap();
        assert_eq!(whole.data, r.data);
        assert_eq!(parse_geotiff_level(Cursor::new(&bytes), len, path, 0).unwrap(), whole);
        // each overview: the 2×2 means written, over the full extent, nodata kept
        let mut want = r.clone();
        for (l, &size) in sizes.iter().enumerate().skip(1) {
            want = halved(&want);
            let got = parse_geotiff_level(Cursor::new(&bytes), len, path, l).unwrap();
            assert_eq!((got.width, got.height), size);
            assert_eq!(got.data, want.data, "level {l}");
            assert_eq!(got.extent(), whole.extent(), "level {l}");
            assert_eq!((got.epsg, got.nodata), (Some(32632), Some(-9999.0)));
        }
        // a level past the last is refused by name
        let e = parse_geotiff_level(Cursor::new(&bytes), len, path, 3).unwrap_err().to_string();
        assert!(e.contains("dem-cog.tif") && e.contains("3 levels (the full image and 2 overviews)"), "{e}");
    }

    #[test]
    fn windows_read_an_overview() {
        let dir = crate::test_dir::TestDir::fresh("geotiff-levels");
        let path = dir.join("cog.tif");
        let r = dem();
        std::fs::write(&path, cog_bytes(&r, &utm(), 32).unwrap()).unwrap();
        let l2 = load_geotiff_level(&path, 2).unwrap();
        let win = GeoTiffWindows::open_level(&path, 2).unwrap();
        assert_eq!((win.header.width, win.header.height), (l2.width, l2.height));
        assert_eq!((win.header.origin, win.header.pixel), (l2.origin, l2.pixel));
        // across tile edges (32 pixels) and up to the padded last tiles
        assert_eq!(win.window(0, 0, l2.width, l2.height).unwrap(), l2.data);
        let part = win.window(30, 10, 20, 28).unwrap();
        for y in 0..28 {
            for x in 0..20 {
                assert_eq!(part[(y * 20 + x) as usize], l2.get(30 + x, 10 + y, 0));
            }
        }
        assert_eq!(GeoTiffWindows::open(&path).unwrap().window(0, 0, 200, 150).unwrap(), r.data);
        assert!(GeoTiffWindows::open_level(&path, 4).err().is_some_and(|e| e.to_string().contains("cog.tif")));
        // an RGB image, its overview as one window
        let rgb =
            GeoRaster { bands: 3, data: (0..200 * 150 * 3).map(|i| (i % 251) as f32).collect(), nodata: None, ..dem() };
        std::fs::write(&path, cog_bytes(&rgb, &utm(), 64).unwrap()).unwrap();
        let win = GeoTiffWindows::open_level(&path, 1).unwrap();
        assert_eq!(win.window(0, 0, 100, 75).unwrap(), halved(&rgb).data);
    }

    #[test]
    fn a_coarse_level_reads_only_the_files_start() {
        // the tiles lie coarsest first: cut the full image's tiles off and
        // the overviews still read, the full image is refused by name
        let r = dem();
        let bytes = cog_bytes(&r, &utm(), 64).unwrap();
        let full_tiles = 3 * 4 * 64 * 64 * 4;
        let cut = &bytes[..bytes.len() - full_tiles];
        let path = Path::new("cut.tif");
        let len = cut.len() as u64;
        assert_eq!(parse_geotiff_level(Cursor::new(cut), len, path, 1).unwrap().data, halved(&r).data);
        let e = parse_geotiff_level(Cursor::new(cut), len, path, 0).unwrap_err().to_string();
        assert!(e.contains("cut.tif"), "{e}");
    }

    #[test]
    fn a_view_reads_the_coarsest_level_that_serves_it() {
        let dir = crate::test_dir::TestDir::fresh("geotiff-view-level");
        let path = dir.join("cog.tif");
        let r = dem();
        // levels 200×150, 100×75, 50×38 in uncompressed 64×64 tiles, coarsest first
        let bytes = cog_bytes(&r, &utm(), 64).unwrap();
        std::fs::write(&path, &bytes).unwrap();
        let read = |cap, how| load_for_view(&path, cap, how).unwrap();
        // the full image within the cap: nothing read
        assert_eq!(read(30_000, Coarsening::Exact), ViewLevel { read: None, notes: vec![] });
        // 4× fewer pixels: k = 2, the first overview
        let v = read(7_500, Coarsening::Exact).read.unwrap();
        assert_eq!((v.level, v.overviews, v.factor, v.full), (1, 2, 2.0, (200, 150)));
        assert_eq!(v.raster.data, halved(&r).data);
        // k = 1.5: exact keeps the detail (the full image), whole blocks round up to 2
        assert!(read(13_334, Coarsening::Exact).read.is_none());
        assert_eq!(read(13_334, Coarsening::WholeBlocks).read.unwrap().level, 1);
        // far coarser than the last overview: the coarsest there is
        assert_eq!(read(10, Coarsening::Exact).read.unwrap().level, 2);
        assert_eq!(read(0, Coarsening::WholeBlocks).read.unwrap().level, 2);
        // the first overview's last tiles cut off: said, and the full image left to the caller
        let tile = 64 * 64 * 4;
        std::fs::write(&path, &bytes[..bytes.len() - 12 * tile - 3 * tile]).unwrap();
        let v = read(7_500, Coarsening::Exact);
        assert!(v.read.is_none());
        assert!(v.notes.iter().any(|n| n.starts_with("overview 1 cannot be read")), "{:?}", v.notes);
        // a plain GeoTIFF has no overviews
        std::fs::write(&path, tiled_geotiff_bytes(std::slice::from_ref(&r), &utm(), 64).unwrap()).unwrap();
        assert!(read(10, Coarsening::Exact).read.is_none());
    }

    #[test]
    fn coarsest_levels_by_factor_and_by_size() {
        let l = |ifd, width, height| Level { ifd, width, height };
        let levels =
            Levels { levels: vec![l(0, 1000, 800), l(1, 500, 400), l(3, 250, 200), l(4, 125, 100)], notes: vec![] };
        assert_eq!(levels.coarsest_within(1.0), 0);
        assert_eq!(levels.coarsest_within(1.99), 0);
        assert_eq!(levels.coarsest_within(2.0), 1);
        assert_eq!(levels.coarsest_within(7.9), 2);
        assert_eq!(levels.coarsest_within(100.0), 3);
        assert_eq!(levels.factor(2), 4.0);
        assert_eq!(levels.coarsest_holding(1), 3);
        assert_eq!(levels.coarsest_holding(50_000), 2);
        assert_eq!(levels.coarsest_holding(50_001), 1);
        assert_eq!(levels.coarsest_holding(10_000_000), 0);
        // a level coarser along one axis: the coarser axis decides
        let odd = Levels { levels: vec![l(0, 1000, 800), l(1, 1000, 200)], notes: vec![] };
        assert_eq!(odd.coarsest_within(2.0), 0);
        assert_eq!(odd.coarsest_within(4.0), 1);
    }

    /// A strip TIFF of `images`: (NewSubfileType, width, height, RGB?).
    fn chain(images: &[(u32, u32, u32, bool)]) -> Vec<u8> {
        use tiff::encoder::{TiffEncoder, colortype};
        let mut buf = Cursor::new(Vec::new());
        let mut enc = TiffEncoder::new(&mut buf).unwrap();
        for (i, &(kind, w, h, rgb)) in images.iter().enumerate() {
            let n = (w * h) as usize;
            if rgb {
                let mut img = enc.new_image::<colortype::RGB32Float>(w, h).unwrap();
                img.encoder().write_tag(Tag::NewSubfileType, kind).unwrap();
                img.write_data(&vec![1.0f32; n * 3]).unwrap();
            } else {
                let mut img = enc.new_image::<colortype::Gray32Float>(w, h).unwrap();
                img.encoder().write_tag(Tag::NewSubfileType, kind).unwrap();
                if i == 0 {
                    img.encoder().write_tag(Tag::ModelPixelScaleTag, &[30.0, 30.0, 0.0][..]).unwrap();
                    img.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, 4e5, 5.1e6, 0.0][..]).unwrap();
                    img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &[1u16, 1, 0, 1, 3072, 0, 1, 32632][..]).unwrap();
                }
                img.write_data(&vec![2.0f32; n]).unwrap();
            }
        }
        buf.into_inner()
    }

    #[test]
    fn images_that_are_no_overviews_are_passed_over() {
        let path = Path::new("chain.tif");
        // a page (0), a mask (5), an RGB overview, one not smaller, then a true one
        let bytes = chain(&[
            (0, 64, 48, false),
            (0, 64, 48, false),
            (5, 32, 24, false),
            (1, 32, 24, true),
            (1, 64, 48, false),
            (1, 16, 12, false),
        ]);
        let levels = read_levels(Cursor::new(&bytes), path).unwrap();
        assert_eq!(levels.levels, [Level { ifd: 0, width: 64, height: 48 }, Level { ifd: 5, width: 16, height: 12 }]);
        assert_eq!(levels.notes.len(), 2, "{:?}", levels.notes);
        assert!(levels.notes[0].contains("image 3") && levels.notes[0].contains("sample type"), "{:?}", levels.notes);
        assert!(levels.notes[1].contains("image 4") && levels.notes[1].contains("not smaller"), "{:?}", levels.notes);
        let l1 = parse_geotiff_level(Cursor::new(&bytes), bytes.len() as u64, path, 1).unwrap();
        assert_eq!((l1.width, l1.height, l1.pixel), (16, 12, [120.0, 120.0]));
        assert!(l1.data.iter().all(|&v| v == 2.0));
        // a chain pointing past the file's end: the full image still reads, the break is noted
        let mut broken = cog_bytes(&dem(), &utm(), 64).unwrap();
        let n = u16::from_le_bytes([broken[8], broken[9]]) as usize;
        let at = 10 + 12 * n;
        broken[at..at + 4].copy_from_slice(&0x7fff_fff0u32.to_le_bytes());
        let levels = read_levels(Cursor::new(&broken), path).unwrap();
        assert_eq!(levels.levels.len(), 1);
        assert!(
            levels.notes[0].contains("image 1") && levels.notes[0].contains("cannot be read"),
            "{:?}",
            levels.notes
        );
        assert_eq!(parse_geotiff(Cursor::new(&broken), broken.len() as u64, path).unwrap().data, dem().data);
    }

    #[test]
    fn sizes_past_64_bits_are_refused_not_wrapped() {
        // one strip of 2³¹ × 2³¹ pixels of 4 bands of f64: 2⁶⁴ samples and more
        let entries: [(u16, u16, u32); 10] = [
            (256, 4, 1 << 31),
            (257, 4, 1 << 31),
            (258, 3, 64),
            (259, 3, 1),
            (262, 3, 1),
            (273, 4, 8),
            (277, 3, 4),
            (279, 4, 4),
            (284, 3, 1),
            (339, 3, 3),
        ];
        let mut b = b"II*\x00".to_vec();
        b.extend_from_slice(&8u32.to_le_bytes());
        b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
        for (tag, kind, v) in entries {
            b.extend_from_slice(&tag.to_le_bytes());
            b.extend_from_slice(&kind.to_le_bytes());
            b.extend_from_slice(&1u32.to_le_bytes());
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&[0; 8]);
        let path = Path::new("huge.tif");
        let len = b.len() as u64;
        // whole: past MAX_SAMPLES; the full image above an overview: its claim past 2⁶⁴ bytes
        for (l, says) in [(0, "outside the limit"), (1, "claims more than 2^64 bytes")] {
            let e = parse_geotiff_level(Cursor::new(&b), len, path, l).unwrap_err().to_string();
            assert!(e.contains("huge.tif") && e.contains(says), "{e}");
        }
        assert!(read_levels(Cursor::new(&b), path).is_ok_and(|l| l.levels.len() == 1));
    }

    #[test]
    fn the_writer_refuses_what_it_cannot_write() {
        let r = dem();
        let e = |levels: &[GeoRaster], tile| tiled_geotiff_bytes(levels, &utm(), tile).unwrap_err().to_string();
        assert!(e(&[], 64).contains("no image"));
        assert!(e(std::slice::from_ref(&r), 40).contains("multiple of 16"));
        assert!(e(&[r.clone(), r.clone()], 64).contains("not smaller"));
        let two = GeoRaster { bands: 2, data: vec![0.0; 200 * 150 * 2], ..dem() };
        assert!(e(&[two], 64).contains("2 bands"));
        let short = GeoRaster { data: vec![0.0; 10], ..dem() };
        assert!(e(std::slice::from_ref(&short), 64).contains("level 0"));
        // refused before any overview is made of it
        assert!(cog_bytes(&short, &utm(), 64).unwrap_err().to_string().contains("level 0"));
        assert!(cog_bytes(&dem(), &utm(), 8).unwrap_err().to_string().contains("multiple of 16"));
        let flat = GeoRaster { height: 0, data: vec![], ..dem() };
        assert!(e(&[flat], 64).contains("level 0"));
    }
}
