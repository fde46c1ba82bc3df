use super::*;

fn tmp(name: &str) -> crate::test_dir::TestDir {
    crate::test_dir::TestDir::at(&format!("gst-{name}"))
}

#[test]
fn geometry_of_a_pyramid() {
    let m = StoreMeta::for_source(1000, 600, [0.0, 0.0], [1.0, 1.0], "", "");
    assert_eq!(m.levels, 3); // 4×3 maps → 4 per side → levels 0..2
    assert_eq!(m.data_range(2), [0, 0, 4, 3]);
    assert_eq!(m.data_range(1), [0, 0, 2, 2]);
    assert_eq!(m.data_range(0), [0, 0, 1, 1]);
    assert_eq!(m.total_tiles(), 12 + 4 + 1);
    // TMS rows count from the south of the padded 2^z grid
    assert!(m.tile_path(Path::new("s"), 2, 1, 0).ends_with("2/1/3.png"));
    assert!(m.tms_xml().contains("<TileSet href=\"0\" units-per-pixel=\"4\""));
}

#[test]
fn build_read_and_shards_agree() {
    let src = ProceduralSource { width: 700, height: 520, seed: 3 };
    let meta = StoreMeta::for_source(700, 520, [500_000.0, 9_100_000.0], [2.0, 2.0], "EPSG:31985", "test");
    let one = tmp("one");
    let r = build_store(&src, &meta, &one, BuildOptions::default(), &|_, _| {}).unwrap();
    assert_eq!(r.written, meta.total_tiles());
    assert_eq!(open_store(&one).unwrap(), meta);
    // a finest map equals the source window
    let t = read_tile(&meta, &one, 2, 1, 1).unwrap();
    assert_eq!(&t[0..4], &src.texel(256, 256));
    // outside the data: transparent
    let edge = read_tile(&meta, &one, 2, 2, 2).unwrap();
    assert_eq!(edge[(255 * TILE as usize + 255) * 4 + 3], 0);
    // three shards, run one after another, build the same files
    let three = tmp("three");
    let mut written = 0;
    let mut top = 0;
    for i in 0..3 {
        let r = build_store(&src, &meta, &three, BuildOptions { shard: (i, 3) }, &|_, _| {}).unwrap();
        written += r.written;
        top += r.built_top as u32;
    }
    assert_eq!(top, 1, "only the last shard finds the split level complete");
    assert_eq!(written, meta.total_tiles());
    for z in 0..meta.levels {
        for (x, y) in meta.data_maps(z) {
            assert_eq!(read_tile(&meta, &one, z, x, y).unwrap(), read_tile(&meta, &three, z, x, y).unwrap());
        }
    }
    let _ = std::fs::remove_dir_all(&one);
    let _ = std::fs::remove_dir_all(&three);
}

#[test]
fn coarser_levels_average_in_linear_light() {
    // a 512×256 source: left half black, right half white → level 0 is grey in linear light
    let mut rgba = vec![0u8; 512 * 256 * 4];
    for y in 0..256 {
        for x in 0..512 {
            let v = if x % 2 == 0 { 0 } else { 255 };
            rgba[(y * 512 + x) * 4..(y * 512 + x) * 4 + 4].copy_from_slice(&[v, v, v, 255]);
        }
    }
    let src = MemorySource { width: 512, height: 256, rgba, name: "stripes".into() };
    let meta = StoreMeta::for_source(512, 256, [0.0, 0.0], [1.0, 1.0], "", "");
    let d = tmp("linear");
    build_store(&src, &meta, &d, BuildOptions::default(), &|_, _| {}).unwrap();
    assert_eq!(meta.levels, 2);
    let t = read_tile(&meta, &d, 0, 0, 0).unwrap();
    // mean of 0 and 1 in linear light is sRGB code 188, not 128
    assert_eq!(t[0], 188);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn bad_stores_and_options_are_refused() {
    let d = tmp("bad");
    std::fs::create_dir_all(&d).unwrap();
    assert!(open_store(&d).is_err());
    std::fs::write(d.join("metadata.json"), "{\"format\": \"x\"}").unwrap();
    assert!(open_store(&d).is_err());
    let meta = StoreMeta::for_source(300, 300, [0.0, 0.0], [1.0, 1.0], "", "");
    let mut lie = meta.clone();
    lie.levels = 9;
    std::fs::write(d.join("metadata.json"), serde_json::to_string(&lie).unwrap()).unwrap();
    let e = open_store(&d).unwrap_err().to_string();
    assert!(e.contains("metadata.json") && e.contains("levels"), "{e}");
    let src = ProceduralSource { width: 300, height: 300, seed: 1 };
    assert!(build_store(&src, &meta, &d, BuildOptions { shard: (2, 2) }, &|_, _| {}).is_err());
    let small = ProceduralSource { width: 100, height: 300, seed: 1 };
    assert!(build_store(&small, &meta, &d, BuildOptions::default(), &|_, _| {}).is_err());
    // a corrupt map is an error naming it
    build_store(&src, &meta, &d, BuildOptions::default(), &|_, _| {}).unwrap();
    let p = meta.tile_path(&d, 1, 0, 0);
    std::fs::write(&p, b"not a png").unwrap();
    let e = read_tile(&meta, &d, 1, 0, 0).unwrap_err().to_string();
    assert!(e.contains(&p.display().to_string()), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

/// The web-mercator tile of (lon, lat) at `zoom`, by the slippy-map
/// formula (column, row from the north).
fn slippy(lon: f64, lat: f64, zoom: u32) -> (u32, u32) {
    let n = (1u64 << zoom) as f64;
    let phi = lat.to_radians();
    let x = ((lon + 180.0) / 360.0 * n).floor();
    let y = ((1.0 - (phi.tan() + 1.0 / phi.cos()).ln() / std::f64::consts::PI) / 2.0 * n).floor();
    (x as u32, y as u32)
}

#[test]
fn mercator_pyramids_sit_on_the_global_tiles() {
    use crate::crs::Crs;
    let merc = Crs::from_epsg(3857).unwrap();
    for (lon, lat, zoom) in [(-34.8712, -7.9954, 13), (13.3777, 52.5163, 17), (-0.01, 51.48, 15), (151.2, -33.86, 12)] {
        // EPSG:3857 from PROJ's definition against the spherical formula
        let p = Crs::wgs84().point(&merc, [lon, lat]);
        assert!((p[0] - MERCATOR_RADIUS * lon.to_radians()).abs() < 1e-3, "{p:?}");
        assert!((p[1] - MERCATOR_RADIUS * lat.to_radians().tan().asinh()).abs() < 1e-3, "{p:?}");
        let meta =
            StoreMeta::mercator([p[0] - 3000.0, p[1] - 2000.0, p[0] + 3000.0, p[1] + 2000.0], zoom, "t").unwrap();
        let f = meta.levels - 1;
        assert_eq!(meta.zoom(f), zoom);
        assert_eq!(meta.data_range(0), [0, 0, 1, 1], "level 0 is one map");
        // the finest map holding the point is the point's tile at that zoom
        let tx = ((p[0] - meta.origin[0]) / meta.pixel[0]) as u32 / TILE;
        let ty = ((meta.origin[1] - p[1]) / meta.pixel[1]) as u32 / TILE;
        let (xt, yt) = slippy(lon, lat, zoom);
        assert_eq!(meta.global_tile(f, tx, ty), (xt, yt), "({lon}, {lat}) at zoom {zoom}");
        let tms = (1u32 << zoom) - 1 - yt;
        assert!(meta.tile_path(Path::new("s"), f, tx, ty).ends_with(format!("{zoom}/{xt}/{tms}.png")));
        // and a deeper zoom − levels + 1 would not hold the extent in one map
        if meta.levels > 1 {
            assert!(meta.data_count(1) > 1);
        }
        // lon/lat bounds hold the point
        let [w, so, e, n] = meta.lon_lat_bounds().unwrap();
        assert!(w < lon && lon < e && so < lat && lat < n);
        // described and read back the same; a tampered placement is refused
        let json = serde_json::to_string(&meta).unwrap();
        assert_eq!(parse_store_meta(&json, Path::new("m.json")).unwrap(), meta);
        for bad in [
            StoreMeta { pixel: [meta.pixel[0] * 2.0; 2], ..meta.clone() },
            StoreMeta { origin: [meta.origin[0] + meta.pixel[0] / 2.0, meta.origin[1]], ..meta.clone() },
            StoreMeta { tiles: [meta.tiles[0], meta.tiles[1] + 1, meta.tiles[2]], ..meta.clone() },
            StoreMeta { crs: "EPSG:31985".into(), ..meta.clone() },
            StoreMeta { profile: Profile::Local, ..meta.clone() },
        ]
        .into_iter()
        // (a local description of a pyramid at global tile 0/0/0 is a valid one)
        .filter(|b| b.profile == Profile::Mercator || b.tiles != [0, 0, 0])
        {
            let j = serde_json::to_string(&bad).unwrap();
            assert!(parse_store_meta(&j, Path::new("m.json")).is_err(), "{j}");
        }
    }
    // an extent across the prime meridian and the equator needs zoom 0 as level 0
    let m = StoreMeta::mercator([-1000.0, -1000.0, 1000.0, 1000.0], 10, "t").unwrap();
    assert_eq!((m.tiles, m.levels), ([0, 0, 0], 11));
    assert_eq!(m.data_range(10), [511, 511, 513, 513]);
    // local stores keep their description as before
    let local = StoreMeta::for_source(300, 300, [0.0, 0.0], [1.0, 1.0], "", "");
    let j = serde_json::to_string(&local).unwrap();
    assert!(!j.contains("offset") && !j.contains("profile") && !j.contains("tiles"), "{j}");
    assert!(StoreMeta::mercator([0.0, 0.0, 1.0, 1.0], MAX_MERCATOR_ZOOM + 1, "t").is_err());
    assert!(StoreMeta::mercator([0.0, 0.0, f64::NAN, 1.0], 5, "t").is_err());
}

#[test]
fn mercator_ground_texels_match_the_local_frame() {
    use crate::crs::Crs;
    let merc = Crs::from_epsg(3857).unwrap();
    for (lon, lat) in [(-34.87, -8.0), (10.0, 45.0), (25.0, 65.0)] {
        let p = Crs::wgs84().point(&merc, [lon, lat]);
        let meta = StoreMeta::mercator([p[0] - 2000.0, p[1] - 2000.0, p[0] + 2000.0, p[1] + 2000.0], 14, "t").unwrap();
        // one texel east at the data's centre, measured in the local metric frame there
        let [x0, y1] = meta.data_origin();
        let c = [x0 + meta.width as f64 / 2.0 * meta.pixel[0], y1 - meta.height as f64 / 2.0 * meta.pixel[1]];
        let ll = merc.point(&Crs::wgs84(), c);
        let local = Crs::local(ll[0], ll[1]).unwrap();
        let mut q = [[c[0] - 50.0 * meta.pixel[0], c[1]], [c[0] + 50.0 * meta.pixel[0], c[1]]];
        merc.transform(&local, &mut q);
        let metres = ((q[1][0] - q[0][0]).powi(2) + (q[1][1] - q[0][1]).powi(2)).sqrt() / 100.0;
        // the sphere's cos φ against the ellipsoid: within 0.3 % (e²·sin²φ/2 at most)
        let rel = (meta.ground_pixel() - metres).abs() / metres;
        assert!(rel < 3e-3, "at {lat}°: {} vs {metres} m ({rel})", meta.ground_pixel());
    }
}

#[test]
fn a_grid_with_an_offset_builds_only_its_data() {
    let src = ProceduralSource { width: 300, height: 200, seed: 5 };
    let mut meta = StoreMeta::for_source(300, 200, [0.0, 0.0], [1.0, 1.0], "", "t");
    meta.offset = [400, 130];
    meta.levels = levels_for(700, 330);
    assert_eq!(meta.levels, 3);
    assert_eq!(meta.data_range(2), [1, 0, 3, 2]);
    assert_eq!(meta.data_range(1), [0, 0, 2, 1]);
    let d = tmp("offset");
    let r = build_store(&src, &meta, &d, BuildOptions::default(), &|_, _| {}).unwrap();
    assert_eq!(r.written, meta.total_tiles());
    assert_eq!(meta.total_tiles(), 4 + 2 + 1);
    // source texel (0, 0) lies at grid texel (400, 130): map (1, 0) of the finest level, at (144, 130)
    let t = read_tile(&meta, &d, 2, 1, 0).unwrap();
    assert_eq!(&t[((130 * TILE + 144) * 4) as usize..][..4], &src.texel(0, 0));
    assert_eq!(t[((129 * TILE + 144) * 4 + 3) as usize], 0, "above the data: transparent");
    assert!(!meta.tile_path(&d, 2, 0, 0).exists(), "no map outside the data");
    let _ = std::fs::remove_dir_all(&d);
}
