//! `hitex terrain build` and `hitex terrain fly` as a user runs them.

mod common;

use common::{error_lines, hitex, tmp};

#[test]
fn build_in_shards_then_fly_with_a_corrupt_map() {
    let d = tmp("store-fly");
    let store = d.join("store");
    let s = store.to_str().unwrap();
    for shard in ["0/2", "1/2"] {
        let o = hitex(&["terrain", "build", "--procedural", "1300x900", "-o", s, "--shard", shard]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert!(store.join("tilemapresource.xml").exists() && store.join("metadata.json").exists());
    // 6×4 maps at the finest level (z = 3), the single map of level 0
    assert!(store.join("3/5/4.png").exists() && store.join("0/0/0.png").exists());
    // a corrupt map: the flight falls back to a coarser one, says so once, and keeps flying
    std::fs::write(store.join("3/2/5.png"), b"garbage").unwrap();
    let frames = d.join("frames");
    let o = hitex(&[
        "terrain",
        "fly",
        s,
        "--frames",
        "3",
        "--size",
        "96x64",
        "--altitude",
        "300",
        "--wait",
        "-o",
        frames.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("median") && text.contains("resident maps"), "{text}");
    for f in 0..3 {
        assert!(frames.join(format!("frame-{f:04}.png")).exists());
    }
    let warn: Vec<_> = error_lines(&o).into_iter().filter(|l| l.contains("3/2/5.png")).collect();
    assert!(warn.len() <= 1, "{warn:?}");
}

#[test]
fn bad_store_input_gives_one_clear_line() {
    let d = tmp("store-bad");
    let out = d.join("o");
    for (args, needle) in [
        (vec!["terrain", "build", "-o", out.to_str().unwrap()], "--procedural"),
        (vec!["terrain", "build", "--procedural", "100x100", "-o", out.to_str().unwrap(), "--shard", "3/2"], "3/2"),
        (vec!["terrain", "fly", d.to_str().unwrap(), "-o", out.to_str().unwrap()], "metadata.json"),
    ] {
        let o = hitex(&args);
        let lines = error_lines(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {lines:?} {}", String::from_utf8_lossy(&o.stderr));
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(needle),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // a flight path putting the camera below the ground
    let store = d.join("s");
    let o = hitex(&["terrain", "build", "--procedural", "300x300", "-o", store.to_str().unwrap()]);
    assert!(o.status.success());
    let path = d.join("p.toml");
    std::fs::write(&path, "[[key]]\nt = 0\nx = 0.5\ny = 0.5\naltitude = -10\npitch = 30\nheading = 0\n").unwrap();
    let o = hitex(&[
        "terrain",
        "fly",
        store.to_str().unwrap(),
        "--path",
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let lines = error_lines(&o);
    assert_eq!(o.status.code(), Some(2), "{lines:?}");
    assert!(lines[0].contains("p.toml") && lines[0].contains("below the ground"), "{lines:?}");
}

#[test]
fn bench_terrain_reports_every_case() {
    let args = "bench terrain --frames 2 --size 64x48 --source 512 --backends cpu --json";
    let o = hitex(&args.split(' ').collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let cases: Vec<&str> = v["rows"].as_array().unwrap().iter().filter_map(|r| r["case"].as_str()).collect();
    for c in ["trilinear", "span3", "span4", "bicubic"] {
        assert!(cases.contains(&c), "{c} missing in {cases:?}");
    }
    for s in v["spans"].as_array().unwrap() {
        assert_eq!(s["bank_conflicts"].as_u64(), Some(0), "{s}");
    }
    assert!(v["resident_maps"].as_u64().unwrap() >= 1);
}

/// The Olinda pair kept beside the readers (the same files as ../shared/data/terrain).
fn olinda(name: &str) -> String {
    format!("{}/../hitex-io/data/olinda/{name}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn olinda_relief_flight_with_the_span_samplers() {
    let d = tmp("store-olinda");
    let store = d.join("store");
    let s = store.to_str().unwrap();
    let (dem, image) = (olinda("olinda_dem_utm25s.tif"), olinda("L7_ETMs.tif"));
    let o = hitex(&["terrain", "build", "--image", &image, "--dem", &dem, "-o", s]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(store.join("dem.tif").exists());
    for sampler in ["trilinear", "span3", "span4", "bicubic"] {
        let frames = d.join(format!("frames-{sampler}"));
        let o = hitex(&[
            "terrain",
            "fly",
            s,
            "--frames",
            "2",
            "--size",
            "96x64",
            "--altitude",
            "2500",
            "--pitch",
            "28",
            "--wait",
            "--stats",
            "--backend",
            "cpu",
            "--sampler",
            sampler,
            "-o",
            frames.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{sampler}: {}", String::from_utf8_lossy(&o.stderr));
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains("relief from") && text.contains(sampler), "{text}");
        if sampler != "trilinear" {
            assert!(text.contains("bank conflicts: 0 in"), "{sampler}: {text}");
        }
        assert!(frames.join("frame-0001.png").exists());
    }
    // the camera below the (exaggerated) relief, and relief asked of a store without a DEM
    let o = hitex(&[
        "terrain",
        "fly",
        s,
        "--frames",
        "1",
        "--altitude",
        "1",
        "--exaggeration",
        "50",
        "-o",
        d.join("x").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("below the ground"), "{}", String::from_utf8_lossy(&o.stderr));
    let flat = d.join("flat");
    let o = hitex(&["terrain", "build", "--procedural", "300x300", "-o", flat.to_str().unwrap()]);
    assert!(o.status.success());
    let o =
        hitex(&["terrain", "fly", flat.to_str().unwrap(), "--ground", "relief", "-o", d.join("y").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("holds no DEM"), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A 3-band 8-bit GeoTIFF of `side`² pixels in strips, UTM 25S.
fn write_geotiff(path: &std::path::Path, side: u32) {
    use tiff::encoder::{TiffEncoder, colortype::RGB8};
    use tiff::tags::Tag;
    let data: Vec<u8> = (0..side * side)
        .flat_map(|i| {
            let (x, y) = (i % side, i / side);
            [(x ^ y) as u8, (x / 8) as u8, (y / 8) as u8]
        })
        .collect();
    let mut enc = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut img = enc.new_image::<RGB8>(side, side).unwrap();
    img.encoder().write_tag(Tag::ModelPixelScaleTag, &[30.0f64, 30.0, 0.0][..]).unwrap();
    img.encoder().write_tag(Tag::ModelTiepointTag, &[0.0f64, 0.0, 0.0, 290_000.0, 9_120_000.0, 0.0][..]).unwrap();
    img.encoder().write_tag(Tag::GeoKeyDirectoryTag, &[1u16, 1, 0, 1, 3072, 0, 1, 31985][..]).unwrap();
    img.write_data(&data).unwrap();
}

#[test]
fn a_geotiff_larger_than_the_memory_cap_builds_by_windows() {
    let d = tmp("store-windows");
    let big = d.join("big.tif");
    write_geotiff(&big, 2048); // 12 MiB of samples, 48 MiB as f32
    let b = big.to_str().unwrap();
    // read whole, the raster is refused under an 8 MiB cap ...
    let o = hitex(&["--max-memory", "8M", "terrain", "render", "--dem", b, "-o", d.join("r.png").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("memory"), "{}", String::from_utf8_lossy(&o.stderr));
    // ... while the pyramid is built window by window under the same cap
    let store = d.join("store");
    let o = hitex(&["--max-memory", "8M", "terrain", "build", "--image", b, "-o", store.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // 8×8 maps at the finest level; a map's texels are the stretched source's
    assert!(store.join("3/7/0.png").exists() && store.join("0/0/0.png").exists());
    let t = image::open(store.join("3/0/7.png")).unwrap().to_rgba8();
    assert_eq!((t.width(), t.height()), (256, 256));
    // band 3 (y / 8) rises southwards: the map's rows do too
    assert!(t.get_pixel(0, 200)[0] > t.get_pixel(0, 10)[0], "{:?} {:?}", t.get_pixel(0, 200), t.get_pixel(0, 10));
}

#[test]
fn png_imagery_with_a_world_file_builds_and_renders() {
    let d = tmp("store-world");
    let png = d.join("ortho.png");
    // 64×64 pixels of 160 m over the Olinda DEM's area (UTM 25S)
    let img = image::RgbaImage::from_fn(64, 64, |x, y| image::Rgba([(x * 4) as u8, (y * 4) as u8, 128, 255]));
    img.save(&png).unwrap();
    let dem = olinda("olinda_dem_utm25s.tif");
    let (p, out) = (png.to_str().unwrap(), d.join("r.png"));
    // no world file: not georeferenced
    let o = hitex(&["terrain", "render", "--dem", &dem, "--image", p, "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no world file"), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::write(d.join("ortho.pgw"), "160\n0\n0\n-160\n288856\n9120680\n").unwrap();
    let o = hitex(&[
        "terrain",
        "render",
        "--dem",
        &dem,
        "--image",
        p,
        "--size",
        "64x48",
        "--backend",
        "cpu",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("names no CRS"));
    // a store from it, which needs the DEM for its CRS
    let store = d.join("store");
    let o = hitex(&["terrain", "build", "--image", p, "-o", store.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--dem"), "{}", String::from_utf8_lossy(&o.stderr));
    let o = hitex(&["terrain", "build", "--image", p, "--dem", &dem, "-o", store.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let meta = std::fs::read_to_string(store.join("metadata.json")).unwrap();
    assert!(meta.contains("288776") && meta.contains("\"width\": 64"), "{meta}");
    // far from the DEM: the extents do not overlap
    std::fs::write(d.join("ortho.pgw"), "160\n0\n0\n-160\n100\n100\n").unwrap();
    let o = hitex(&["terrain", "render", "--dem", &dem, "--image", p, "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("do not overlap"), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Every file below `dir` with its bytes, by path relative to `dir`.
fn files_of(dir: &std::path::Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut all = Vec::new();
    common::walk(dir, &mut all);
    all.into_iter()
        .map(|p| {
            let rel = std::path::Path::new(&p).strip_prefix(dir).unwrap().to_string_lossy().into_owned();
            (rel, std::fs::read(&p).unwrap())
        })
        .collect()
}

#[test]
fn shards_run_at_the_same_time_build_the_store_of_one_process() {
    let d = tmp("store-concurrent");
    let (one, many) = (d.join("one"), d.join("many"));
    let o = hitex(&["terrain", "build", "--procedural", "3000x2000", "-o", one.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // four processes at once into one folder, as an array job runs them
    let n = 4;
    let children: Vec<_> = (0..n)
        .map(|i| {
            std::process::Command::new(env!("CARGO_BIN_EXE_hitex"))
                .args(["terrain", "build", "--procedural", "3000x2000", "-o", many.to_str().unwrap()])
                .args(["--shard", &format!("{i}/{n}")])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (a, b) = (files_of(&one), files_of(&many));
    assert!(a.len() > 20, "{} files", a.len());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>(), "the same files, no temporaries left");
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs between the single and the concurrent build");
    }
}

#[test]
fn olinda_as_web_mercator_tiles_flies_like_the_local_store() {
    let d = tmp("store-mercator");
    let (dem, image) = (olinda("olinda_dem_utm25s.tif"), olinda("L7_ETMs.tif"));
    let (local, file, folder, packed) =
        (d.join("local"), d.join("olinda.mbtiles"), d.join("mercator"), d.join("packed.mbtiles"));
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let o = hitex(&["terrain", "build", "--image", &image, "--dem", &dem, "-o", &s(&local)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // an .mbtiles name: web mercator in one SQLite file, the DEM inside
    let o = hitex(&["terrain", "build", "--image", &image, "--dem", &dem, "-o", &s(&file)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("web mercator (EPSG:3857): zoom 11 to 13") && text.contains("with its DEM"), "{text}");
    // the folder form in two shards, packed after: the same file content
    for shard in ["0/2", "1/2"] {
        let o = hitex(&[
            "terrain",
            "build",
            "--image",
            &image,
            "--dem",
            &dem,
            "--profile",
            "mercator",
            "-o",
            &s(&folder),
            "--shard",
            shard,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert!(folder.join("13/3302/3913.png").exists(), "global TMS tiles: Olinda's zoom-13 tile");
    let xml = std::fs::read_to_string(folder.join("tilemapresource.xml")).unwrap();
    assert!(xml.contains("profile=\"global-mercator\"") && xml.contains("EPSG:3857"), "{xml}");
    let o = hitex(&["terrain", "pack", &s(&folder), "-o", &s(&packed)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (std::fs::read(&file).unwrap(), std::fs::read(&packed).unwrap());
    assert!(a.len() > 100_000 && b.len() > 100_000);
    // the same view over both stores: above the imagery's centre, 3 km up, 40° below the horizon,
    // heading 30° from UTM grid north; the mercator flight's key names the same ground point and
    // direction, computed here through the coordinate library
    let meta = |p: std::path::PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (ml, mm) = (meta(local.join("metadata.json")), meta(folder.join("metadata.json")));
    let f = |v: &serde_json::Value, k: &str, i: usize| v[k][i].as_f64().unwrap();
    let centre = [
        f(&ml, "origin", 0) + ml["width"].as_f64().unwrap() / 2.0 * f(&ml, "pixel", 0),
        f(&ml, "origin", 1) - ml["height"].as_f64().unwrap() / 2.0 * f(&ml, "pixel", 1),
    ];
    let utm = hitex_io::crs::Crs::from_epsg(31985).unwrap();
    let merc = hitex_io::crs::Crs::from_epsg(3857).unwrap();
    let mut q = [centre, [centre[0], centre[1] + 100.0]];
    utm.transform(&merc, &mut q);
    let convergence = (q[1][0] - q[0][0]).atan2(q[1][1] - q[0][1]).to_degrees();
    let px = f(&mm, "pixel", 0);
    let data = [f(&mm, "origin", 0) + f(&mm, "offset", 0) * px, f(&mm, "origin", 1) - f(&mm, "offset", 1) * px];
    let (mx, my) = (
        (q[0][0] - data[0]) / px / mm["width"].as_f64().unwrap(),
        (data[1] - q[0][1]) / px / mm["height"].as_f64().unwrap(),
    );
    let key = |x: f64, y: f64, altitude: f64, pitch: f64, heading: f64| {
        format!("[[key]]\nt = 0\nx = {x}\ny = {y}\naltitude = {altitude}\npitch = {pitch}\nheading = {heading}\n")
    };
    let mut n = 0;
    // one frame of `key` over `store` (with `extra` flags): what the command said, the frame's pixels
    let mut fly_with = |store: &std::path::Path, key: String, extra: &[&str]| -> (String, Vec<u8>) {
        n += 1;
        let (path, frames) = (d.join(format!("k{n}.toml")), d.join(format!("f{n}")));
        std::fs::write(&path, key).unwrap();
        let (store, path, frames) = (s(store), s(&path), s(&frames));
        let mut args = vec![
            "terrain",
            "fly",
            &store,
            "--path",
            &path,
            "--frames",
            "1",
            "--size",
            "256x160",
            "--wait",
            "--backend",
            "cpu",
            "-o",
            &frames,
        ];
        args.extend_from_slice(extra);
        let o = hitex(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let text = String::from_utf8_lossy(&o.stdout).to_string();
        (text, image::open(std::path::Path::new(&frames).join("frame-0000.png")).unwrap().to_rgba8().into_raw())
    };
    let mut fly = |store: &std::path::Path, key: String| {
        let (text, pixels) = fly_with(store, key, &[]);
        assert!(text.contains("relief from"), "{text}");
        pixels
    };
    let psnr = |a: &[u8], b: &[u8]| hitex_render::compare::compare_rgba(a, b).0.psnr_db;
    // straight down from 6 km: the ground registered within a texel
    let nadir = fly(&local, key(0.5, 0.5, 6000.0, 90.0, 30.0));
    let merc_nadir = fly(&file, key(mx, my, 6000.0, 90.0, 30.0 + convergence));
    let packed_nadir = fly(&packed, key(mx, my, 6000.0, 90.0, 30.0 + convergence));
    assert_eq!(merc_nadir, packed_nadir, "the packed file flies as the built one");
    // the same view 60 m (about 3 texels) east: what a misregistration would cost
    let shifted =
        fly(&file, key(mx + 60.0 / 18.92 / mm["width"].as_f64().unwrap(), my, 6000.0, 90.0, 30.0 + convergence));
    let (aligned, off) = (psnr(&nadir, &merc_nadir), psnr(&nadir, &shifted));
    // oblique, 3 km up, 40° below the horizon over the relief
    let oblique = psnr(
        &fly(&local, key(0.5, 0.5, 3000.0, 40.0, 30.0)),
        &fly(&file, key(mx, my, 3000.0, 40.0, 30.0 + convergence)),
    );
    println!(
        "local store vs web-mercator MBTiles, same view: nadir {aligned:.1} dB (60 m off: {off:.1} dB), oblique {oblique:.1} dB"
    );
    // the same ground seen through two resamplings (UTM 28.5 m texels, mercator 18.9 m)
    assert!(aligned > 28.0 && aligned > off + 3.0, "nadir {aligned} dB, 60 m off {off} dB");
    assert!(oblique > 19.0, "oblique {oblique} dB");
    // the same file as another tool leaves it (no hitex description, no DEM,
    // only its zoom-13 tiles): flown over flat ground, the same frame as
    // hitex's own file, its coarser levels built alike on reading
    let foreign = d.join("foreign.mbtiles");
    std::fs::copy(&file, &foreign).unwrap();
    rusqlite::Connection::open(&foreign)
        .unwrap()
        .execute_batch(
            "DELETE FROM metadata WHERE name = 'hitex'; DROP TABLE hitex_files; DELETE FROM tiles WHERE zoom_level < 13;",
        )
        .unwrap();
    let flat = ["--ground", "flat"];
    let (_, own) = fly_with(&file, key(mx, my, 3000.0, 40.0, 30.0), &flat);
    let (text, other) = fly_with(&foreign, key(mx, my, 3000.0, 40.0, 30.0), &flat);
    assert!(text.contains("another tool") && text.contains("flat ground"), "{text}");
    assert!(own == other, "another tool's copy of the file flies as hitex's own");
    // the pieces a user gets wrong, one line each
    let o = hitex(&["terrain", "build", "--procedural", "300x300", "-o", &s(&d.join("p.mbtiles"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no place on Earth"), "{}", String::from_utf8_lossy(&o.stderr));
    let o = hitex(&[
        "terrain",
        "build",
        "--image",
        &image,
        "--format",
        "mbtiles",
        "--profile",
        "local",
        "-o",
        &s(&d.join("l.mbtiles")),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let o = hitex(&["terrain", "pack", &s(&local), "-o", &s(&d.join("x.mbtiles"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("local pyramid"), "{}", String::from_utf8_lossy(&o.stderr));
    let o = hitex(&["terrain", "build", "--image", &image, "-o", &s(&d.join("s.mbtiles")), "--shard", "0/2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("terrain pack"), "{}", String::from_utf8_lossy(&o.stderr));
}
