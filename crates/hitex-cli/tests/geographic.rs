//! Geographic DEMs and DEM + imagery pairs in different CRSs, as users
//! download them: reprojected into one metric CRS and rendered; and
//! Cloud-Optimized GeoTIFFs, read at the overview a view needs.

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
    dem_tile(path, 0, 0, N, N);
}

/// Posts `i0 .. i0 + w`, `j0 .. j0 + h` of [`geographic_dem`] as a tile of their own.
fn dem_tile(path: &Path, i0: u32, j0: u32, w: u32, h: u32) {
    let mut v = Vec::with_capacity((w * h) as usize);
    for j in j0..j0 + h {
        for i in i0..i0 + w {
            let (x, y) = (i as f64 / N as f64 - 0.5, j as f64 / N as f64 - 0.5);
            let z = 800.0 + 600.0 * (-(x * x + y * y) * 12.0).exp() + 200.0 * x;
            v.push(if (100..104).contains(&i) && (60..63).contains(&j) { -32768 } else { z as i16 });
        }
    }
    let (lon, lat) = (LON0 + i0 as f64 * STEP, LAT0 - j0 as f64 * STEP);
    let mut enc = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut img = enc.new_image::<colortype::GrayI16>(w, h).unwrap();
    img.encoder().write_tag(Tag::ModelPixelScaleTag, &[STEP, STEP, 0.0][..]).unwrap();
    img.encoder().write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, lon, lat, 0.0][..]).unwrap();
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

/// Flies two frames over `store` into `frames`: how many show ground.
fn fly_two_frames(store: &Path, frames: &Path) -> usize {
    let (s, f) = (store.to_str().unwrap(), frames.to_str().unwrap());
    let args = ["terrain", "fly", s, "--frames", "2", "--size", "96x64", "--wait", "--backend", "cpu", "--pitch", "35"];
    let o = hitex(&[&args[..], &["-o", f]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    frames_with_ground(frames)
}

/// Frames in `dir` that show terrain (not all sky).
fn frames_with_ground(dir: &Path) -> usize {
    std::fs::read_dir(dir).unwrap().flatten().filter(|e| covered(&e.path()) > 0.2).count()
}

#[test]
fn a_geographic_dem_alone_builds_a_store_and_flies() {
    let d = tmp("geographic-store");
    let (dem, store, frames) = (d.join("dem.tif"), d.join("store"), d.join("frames"));
    geographic_dem(&dem);
    let o = hitex(&["terrain", "build", "--dem", dem.to_str().unwrap(), "-o", store.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{stdout}{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("reprojected from EPSG:4326 to a local metric frame") && stdout.contains("shaded relief"),
        "{stdout}"
    );
    // the store keeps the reprojected DEM, its CRS written as user-defined GeoKeys
    let kept = hitex_io::geotiff::load_geotiff(&store.join("dem.tif")).unwrap();
    let crs = kept.crs().unwrap();
    assert!(!crs.is_geographic() && crs.name().starts_with("a local metric frame"), "{crs:?}");
    assert!((kept.pixel[0] - 64.4).abs() < 0.5 && (kept.pixel[1] - 92.6).abs() < 0.5, "{:?}", kept.pixel);
    assert_eq!(fly_two_frames(&store, &frames), 2);
}

#[test]
fn a_geographic_dem_under_utm_imagery_builds_with_the_dem_in_the_imagery_crs() {
    let d = tmp("geographic-store-pair");
    let (dem, img, store, frames) = (d.join("dem.tif"), d.join("img.tif"), d.join("store"), d.join("frames"));
    geographic_dem(&dem);
    utm_imagery(&img);
    let o = hitex(&[
        "terrain",
        "build",
        "--image",
        img.to_str().unwrap(),
        "--bands",
        "1,2,3",
        "--dem",
        dem.to_str().unwrap(),
        "-o",
        store.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{stdout}{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("reprojected from EPSG:4326 to EPSG:32632"), "{stdout}");
    let kept = hitex_io::geotiff::load_geotiff(&store.join("dem.tif")).unwrap();
    assert_eq!(kept.epsg, Some(32632));
    assert_eq!(fly_two_frames(&store, &frames), 2);
}

#[test]
fn four_tiles_render_as_the_dem_they_were_cut_from() {
    let d = tmp("geographic-mosaic");
    let tiles = d.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    // 2×2 tiles sharing their edge posts, as adjacent SRTM tiles do
    let half = N / 2;
    for (name, i0, j0) in [("nw", 0, 0), ("ne", half, 0), ("sw", 0, half), ("se", half, half)] {
        dem_tile(&tiles.join(format!("{name}.tif")), i0, j0, half + 1, half + 1);
    }
    let whole = d.join("whole.tif");
    geographic_dem(&whole);
    let render = |dem: &[&str], out: &Path| {
        let mut args = vec!["terrain", "render", "--dem"];
        args.extend_from_slice(dem);
        let o = out.to_str().unwrap();
        args.extend_from_slice(&["-o", o, "--size", "160x120", "--backend", "cpu"]);
        let o = hitex(&args);
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{stdout}{}", String::from_utf8_lossy(&o.stderr));
        stdout
    };
    let (a, b, c) = (d.join("whole.png"), d.join("folder.png"), d.join("files.png"));
    render(&[whole.to_str().unwrap()], &a);
    let said = render(&[tiles.to_str().unwrap()], &b);
    assert!(said.contains("a mosaic of 4 tiles, 241x241 posts"), "{said}");
    let names: Vec<String> = ["se", "nw", "sw", "ne"]
        .iter()
        .map(|n| tiles.join(format!("{n}.tif")).to_string_lossy().into_owned())
        .collect();
    let names: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
    render(&names, &c);
    let (pa, pb, pc) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), std::fs::read(&c).unwrap());
    assert!(pa == pb, "the mosaic of the folder renders otherwise than the whole DEM");
    assert!(pa == pc, "the mosaic of the files, in any order, renders otherwise than the whole DEM");
}

/// A raster in UTM zone 32N with `bands` bands over 12 × 10 km from E 400 000, N 5 110 000.
fn utm_raster(w: u32, h: u32, bands: usize, f: impl Fn(f64, f64, usize) -> f32) -> hitex_io::geotiff::GeoRaster {
    let data = (0..w * h)
        .flat_map(|k| {
            let (x, y) = ((k % w) as f64 / w as f64, (k / w) as f64 / h as f64);
            (0..bands).map(move |b| (x, y, b))
        })
        .map(|(x, y, b)| f(x, y, b))
        .collect();
    hitex_io::geotiff::GeoRaster {
        width: w,
        height: h,
        bands,
        data,
        origin: [400_000.0, 5_110_000.0],
        pixel: [12_000.0 / w as f64, 10_000.0 / h as f64],
        nodata: None,
        epsg: Some(32632),
        projection: None,
        citation: None,
        proj4: None,
    }
}

fn render_args<'a>(dem: &'a str, image: Option<&'a str>, out: &'a str, full: bool) -> Vec<&'a str> {
    let mut a = vec!["terrain", "render", "--dem", dem, "-o", out, "--size", "160x120", "--backend", "cpu"];
    if let Some(i) = image {
        a.extend(["--image", i]);
    }
    if full {
        a.push("--full-resolution");
    }
    a
}

#[test]
fn a_cloud_optimized_geotiff_is_read_at_the_overview_the_view_needs() {
    let d = tmp("cog");
    let (dem, img) = (d.join("dem-cog.tif"), d.join("img-cog.tif"));
    let utm = hitex_io::crs::Crs::from_epsg(32632).unwrap();
    // 1.2 M posts: more than the 1 M a 160×120 view meshes, so every second post is enough
    let hill = utm_raster(1200, 1000, 1, |x, y, _| {
        let (dx, dy) = (x - 0.5, y - 0.5);
        (300.0 + 500.0 * (-(dx * dx + dy * dy) * 10.0).exp() + 80.0 * (x * 40.0).sin() * (y * 30.0).cos()) as f32
    });
    std::fs::write(&dem, hitex_io::geotiff::cog_bytes(&hill, &utm, 256).unwrap()).unwrap();
    // 1.2 M texels: twice as many as 16 a pixel along each axis
    let photo = utm_raster(1280, 960, 3, |x, y, b| {
        [x * 200.0 + 20.0, y * 180.0 + 30.0, 90.0 + 60.0 * (x * 25.0).sin()][b] as f32
    });
    std::fs::write(&img, hitex_io::geotiff::cog_bytes(&photo, &utm, 256).unwrap()).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (dem_s, img_s) = (s(&dem), s(&img));
    let run = |image: Option<&str>, full: bool, name: &str| {
        let out = s(&d.join(name));
        let o = hitex(&render_args(&dem_s, image, &out, full));
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{stdout}{}", String::from_utf8_lossy(&o.stderr));
        let png = image::open(&out).unwrap().to_rgba8();
        (stdout, png)
    };
    // the DEM alone: its first overview is the 2×2 means that decimation makes of the full posts
    let (said, coarse) = run(None, false, "overview.png");
    assert!(
        said.contains("dem-cog.tif: read overview 1 of 3 (600x500 posts, 2x coarser) of the full 1200x1000"),
        "{said}"
    );
    assert!(!said.contains("meshed"), "{said}");
    let (said, full) = run(None, true, "full.png");
    assert!(!said.contains("overview"), "{said}");
    assert!(said.contains("meshed 600x500 posts (the means of 2x2 blocks)"), "{said}");
    assert!(coarse == full, "the overview renders as the decimated full DEM, byte for byte");
    // with imagery: the first overview of the photo too, within a step or two of the full photo
    let (said, coarse) = run(Some(&img_s), false, "overview-img.png");
    assert!(
        said.contains("img-cog.tif: read overview 1 of 3 (640x480 texels, 2x coarser) of the full 1280x960"),
        "{said}"
    );
    let (_, full) = run(Some(&img_s), true, "full-img.png");
    let (mut sum, mut worst) = (0u64, 0u8);
    for (a, b) in coarse.as_raw().iter().zip(full.as_raw()) {
        sum += a.abs_diff(*b) as u64;
        worst = worst.max(a.abs_diff(*b));
    }
    let mean = sum as f64 / coarse.as_raw().len() as f64;
    assert!(mean < 1.5 && mean > 0.0, "mean |Δ| {mean:.3} steps, worst {worst}");
}
