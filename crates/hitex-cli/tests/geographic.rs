//! Geographic DEMs and DEM + imagery pairs in different CRSs, as users
//! download them: reprojected into one metric CRS and rendered.

mod common;

use common::{error_lines, hitex, tmp};
use geographiclib_rs::{Geodesic, InverseGeodesic};
use std::path::Path;
use tiff::encoder::{TiffEncoder, colortype};
use tiff::tags::Tag;

/// Posts per side and their spacing (3″, as SRTM 3 and GLO-90).
const N: u32 = 241;
const STEP: f64 = 3.0 / 3600.0;
/// The first post's centre (PixelIsPoint): 46.2°N 7.0°E.
const LON0: f64 = 7.0;
const LAT0: f64 = 46.2;

/// An int16 geographic DEM (EPSG:4326, PixelIsPoint, GDAL nodata −32768 in a
/// small block), a hill on a slope.
fn geographic_dem(path: &Path) {
    let mut v = Vec::with_capacity((N * N) as usize);
    for j in 0..N {
        for i in 0..N {
            let (x, y) = (i as f64 / N as f64 - 0.5, j as f64 / N as f64 - 0.5);
            let h = 800.0 + 600.0 * (-(x * x + y * y) * 12.0).exp() + 200.0 * x;
            v.push(if (100..104).contains(&i) && (60..63).contains(&j) { -32768 } else { h as i16 });
        }
    }
    let mut enc = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut img = enc.new_image::<colortype::GrayI16>(N, N).unwrap();
    img.encoder().write_tag(Tag::ModelPixelScaleTag, &[STEP, STEP, 0.0][..]).unwrap();
    img.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, LON0, LAT0, 0.0][..]).unwrap();
    let keys: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326];
    img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &keys[..]).unwrap();
    img.encoder().write_tag(Tag::GdalNodata, "-32768").unwrap();
    img.write_data(&v).unwrap();
}

/// RGB imagery in UTM zone 32N (EPSG:32632) over the DEM's area, 60 m pixels.
fn utm_imagery(path: &Path) {
    let (w, h) = (320u32, 360u32);
    let data: Vec<u8> = (0..w * h).flat_map(|k| [((k % w) * 255 / w) as u8, ((k / w) * 255 / h) as u8, 128]).collect();
    let mut enc = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut img = enc.new_image::<colortype::RGB8>(w, h).unwrap();
    img.encoder().write_tag(Tag::ModelPixelScaleTag, &[60.0, 60.0, 0.0][..]).unwrap();
    // 7.0°E 46.2°N is about E 346 000, N 5 118 000 in zone 32N
    img.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, 340_000.0, 5_122_000.0, 0.0][..]).unwrap();
    let keys: [u16; 12] = [1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32632];
    img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &keys[..]).unwrap();
    img.write_data(&data).unwrap();
}

/// Fraction of the picture that is not sky.
fn covered(png: &Path) -> f64 {
    let img = image::open(png).unwrap().to_rgba8();
    let sky = [
        hitex_core::texture::linear_to_srgb_u8(0.45),
        hitex_core::texture::linear_to_srgb_u8(0.6),
        hitex_core::texture::linear_to_srgb_u8(0.85),
    ];
    img.pixels().filter(|p| p.0[..3] != sky).count() as f64 / (img.width() * img.height()) as f64
}

/// "… posts at X × Y m" from a note.
fn spacing(out: &str) -> (f64, f64) {
    let line = out.lines().find(|l| l.contains("posts at")).unwrap_or_else(|| panic!("no spacing in {out}"));
    let rest = line.split("posts at ").nth(1).unwrap();
    let mut it = rest.split([' ', '×', 'm', ')']).filter(|s| !s.is_empty());
    (it.next().unwrap().parse().unwrap(), it.next().unwrap().parse().unwrap())
}

#[test]
fn a_geographic_dem_renders_in_metres() {
    let d = tmp("geographic-dem");
    let (dem, out) = (d.join("dem.tif"), d.join("out.png"));
    geographic_dem(&dem);
    let o = hitex(&[
        "terrain",
        "render",
        "--dem",
        dem.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "160x120",
        "--backend",
        "cpu",
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{stdout}{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("reprojected from EPSG:4326 to a local metric frame"), "{stdout}");
    assert!(stdout.contains("filled"), "the nodata block is filled: {stdout}");
    // the post spacing in metres against an independent geodesic computation
    // across one post at the DEM's centre
    let (lat, lon) = (LAT0 - STEP * (N - 1) as f64 / 2.0, LON0 + STEP * (N - 1) as f64 / 2.0);
    let g = Geodesic::wgs84();
    let east: f64 = g.inverse(lat, lon - STEP / 2.0, lat, lon + STEP / 2.0);
    let north: f64 = g.inverse(lat - STEP / 2.0, lon, lat + STEP / 2.0, lon);
    let (sx, sy) = spacing(&stdout);
    assert!((sx / east - 1.0).abs() < 1e-3, "east spacing {sx} m against the geodesic {east} m");
    assert!((sy / north - 1.0).abs() < 1e-3, "north spacing {sy} m against the geodesic {north} m");
    let c = covered(&out);
    assert!(c > 0.3, "the terrain covers {:.0} % of the picture", c * 100.0);
}

#[test]
fn a_geographic_dem_under_utm_imagery_renders_in_the_imagery_crs() {
    let d = tmp("geographic-pair");
    let (dem, img, out) = (d.join("dem.tif"), d.join("img.tif"), d.join("out.png"));
    geographic_dem(&dem);
    utm_imagery(&img);
    let o = hitex(&[
        "terrain",
        "render",
        "--dem",
        dem.to_str().unwrap(),
        "--image",
        img.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "160x120",
        "--backend",
        "cpu",
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{stdout}{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("reprojected from EPSG:4326 to EPSG:32632"), "{stdout}");
    assert!(covered(&out) > 0.3);
    // the other way round: the imagery into a CRS of the user's choice
    let o = hitex(&[
        "terrain",
        "render",
        "--dem",
        dem.to_str().unwrap(),
        "--image",
        img.to_str().unwrap(),
        "--crs",
        "EPSG:3035",
        "-o",
        out.to_str().unwrap(),
        "--size",
        "160x120",
        "--backend",
        "cpu",
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{stdout}{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("img.tif: reprojected from EPSG:32632 to EPSG:3035"), "{stdout}");
    assert!(covered(&out) > 0.3);
}

#[test]
fn crs_mistakes_get_one_line_each() {
    let d = tmp("geographic-bad");
    let (dem, out) = (d.join("dem.tif"), d.join("out.png"));
    geographic_dem(&dem);
    for (crs, says) in [
        ("EPSG:4326", "is geographic"),
        ("EPSG:1", "EPSG:1 is not in the coordinate library's register"),
        ("UTM32", "neither EPSG:N nor a PROJ.4 definition"),
    ] {
        let o =
            hitex(&["terrain", "render", "--dem", dem.to_str().unwrap(), "--crs", crs, "-o", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "--crs {crs}");
        let e = error_lines(&o);
        assert!(e.len() == 1 && e[0].contains(says), "--crs {crs}: {e:?}");
    }
    assert!(!out.exists());
}
