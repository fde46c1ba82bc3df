use super::*;
use crate::gst::{BuildOptions, FolderSink, MemorySource, Store, build_into, read_tile};

fn tmp(name: &str) -> crate::test_dir::TestDir {
    crate::test_dir::TestDir::fresh(&format!("mbtiles-{name}"))
}

/// A web-mercator store over 600×450 texels near Olinda at zoom 14 and a
/// source of that size (a gradient with a transparent corner).
fn sample() -> (StoreMeta, MemorySource) {
    let (x, y) = (-3_882_000.0, -892_000.0);
    let meta = StoreMeta::mercator([x, y - 4300.0, x + 5700.0, y], 14, "sample").unwrap();
    let (w, h) = (meta.width, meta.height);
    let mut rgba = Vec::with_capacity((w * h * 4) as usize);
    for j in 0..h {
        for i in 0..w {
            let a = if i < 20 && j < 20 { 0 } else { 255 };
            rgba.extend_from_slice(&[(i % 256) as u8, (j % 256) as u8, ((i + j) % 256) as u8, a]);
        }
    }
    (meta, MemorySource { width: w, height: h, rgba, name: "sample".into() })
}

/// A test folder named after `name` holding `good.mbtiles`, hitex's
/// build of [`sample`]; with the sample's description and source.
fn built(name: &str) -> (crate::test_dir::TestDir, StoreMeta, MemorySource, PathBuf) {
    let d = tmp(name);
    let (meta, src) = sample();
    let good = d.join("good.mbtiles");
    build_mbtiles(&src, &meta, &good, &[], &|_, _| {}).unwrap();
    (d, meta, src, good)
}

#[test]
fn an_mbtiles_build_holds_the_folder_builds_maps() {
    let d = tmp("build");
    let (meta, src) = sample();
    assert!(meta.levels >= 2);
    let file = d.join("s.mbtiles");
    let dem = vec![("dem.tif".to_string(), b"not really a tiff".to_vec())];
    let r = build_mbtiles(&src, &meta, &file, &dem, &|_, _| {}).unwrap();
    assert_eq!(r.written, meta.total_tiles());
    let folder = d.join("folder");
    std::fs::create_dir_all(&folder).unwrap();
    build_into(&src, &meta, &FolderSink(&folder), BuildOptions::default(), &|_, _| {}).unwrap();
    // an SQLite reader sees the tiles, rows from the south, and the metadata
    let conn = Connection::open(&file).unwrap();
    let n: i64 = conn.query_row("SELECT count(*) FROM tiles", [], |r| r.get(0)).unwrap();
    assert_eq!(n as u64, meta.total_tiles());
    let get = |k: &str| -> String {
        conn.query_row("SELECT value FROM metadata WHERE name = ?1", [k], |r| r.get(0)).unwrap()
    };
    assert_eq!(get("format"), "png");
    assert_eq!(get("name"), "s");
    assert_eq!(get("minzoom"), meta.zoom(0).to_string());
    assert_eq!(get("maxzoom"), "14");
    let b: Vec<f64> = get("bounds").split(',').map(|v| v.parse().unwrap()).collect();
    let want = meta.lon_lat_bounds().unwrap();
    for k in 0..4 {
        assert!((b[k] - want[k]).abs() < 1e-6, "{b:?} vs {want:?}");
    }
    let (minz, maxz): (i64, i64) = conn
        .query_row("SELECT min(zoom_level), max(zoom_level) FROM tiles", [], |r| Ok((r.get(0)?, r.get(1)?)))
        .unwrap();
    assert_eq!((minz, maxz), (meta.zoom(0) as i64, 14));
    drop(conn);
    // and hitex reads back the folder build's maps, bit for bit
    let store = Store::open(&file).unwrap();
    assert!(store.is_mbtiles());
    assert_eq!(store.meta, meta);
    for z in 0..meta.levels {
        for (x, y) in meta.data_maps(z) {
            assert_eq!(store.read_tile(z, x, y).unwrap(), read_tile(&meta, &folder, z, x, y).unwrap(), "{z}/{x}/{y}");
        }
    }
    let (name, bytes) = store.dem().unwrap().unwrap();
    assert!(name.ends_with("dem.tif") && bytes == dem[0].1);
    // no partial file left beside it
    let left: Vec<_> = std::fs::read_dir(&d).unwrap().flatten().map(|e| e.file_name()).collect();
    assert_eq!(left.len(), 2, "{left:?}");
    // packed from the folder form: the same tiles, byte for byte
    std::fs::write(folder.join("metadata.json"), serde_json::to_string(&meta).unwrap()).unwrap();
    std::fs::write(folder.join("dem.tif"), &dem[0].1).unwrap();
    let packed = d.join("p.mbtiles");
    assert_eq!(pack_folder(&folder, &packed, &|_, _| {}).unwrap(), meta.total_tiles());
    let (a, b) = (Connection::open(&file).unwrap(), Connection::open(&packed).unwrap());
    let all = |c: &Connection| -> Vec<(i64, i64, i64, Vec<u8>)> {
        let mut st = c.prepare("SELECT * FROM tiles ORDER BY zoom_level, tile_column, tile_row").unwrap();
        st.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?))).unwrap().map(Result::unwrap).collect()
    };
    assert_eq!(all(&a), all(&b));
}

#[test]
fn broken_mbtiles_files_are_named_errors() {
    let (d, meta, src, good) = built("broken");
    let err = |p: &Path| match Store::open(p) {
        Ok(s) => s.read_tile(0, 0, 0).err().map(|e| e.to_string()).unwrap_or_else(|| "ok".into()),
        Err(e) => e.to_string(),
    };
    // not SQLite at all, and a truncated file
    let p = d.join("text.mbtiles");
    std::fs::write(&p, "hello").unwrap();
    assert!(err(&p).contains("text.mbtiles"), "{}", err(&p));
    let bytes = std::fs::read(&good).unwrap();
    let p = d.join("cut.mbtiles");
    std::fs::write(&p, &bytes[..bytes.len() / 3]).unwrap();
    let e = err(&p);
    assert!(e.contains("cut.mbtiles") && e != "ok", "{e}");
    // SQLite without the tables
    let p = d.join("empty.mbtiles");
    Connection::open(&p).unwrap().execute_batch("CREATE TABLE t (x);").unwrap();
    assert!(err(&p).contains("not an MBTiles file"), "{}", err(&p));
    // a description that lies about its levels
    let p = d.join("lie.mbtiles");
    std::fs::copy(&good, &p).unwrap();
    let mut lie = meta.clone();
    lie.levels += 1;
    Connection::open(&p)
        .unwrap()
        .execute("UPDATE metadata SET value = ?1 WHERE name = 'hitex'", [serde_json::to_string(&lie).unwrap()])
        .unwrap();
    assert!(err(&p).contains("levels"), "{}", err(&p));
    // a missing tile, an oversized one, a corrupt one
    let p = d.join("holes.mbtiles");
    std::fs::copy(&good, &p).unwrap();
    Connection::open(&p).unwrap().execute("DELETE FROM tiles WHERE zoom_level = ?1", [meta.zoom(0)]).unwrap();
    assert!(err(&p).contains("no tile"), "{}", err(&p));
    let p = d.join("big.mbtiles");
    std::fs::copy(&good, &p).unwrap();
    Connection::open(&p)
        .unwrap()
        .execute("UPDATE tiles SET tile_data = zeroblob(?1) WHERE zoom_level = ?2", params![5 << 20, meta.zoom(0)])
        .unwrap();
    assert!(err(&p).contains("bytes"), "{}", err(&p));
    let p = d.join("bad.mbtiles");
    std::fs::copy(&good, &p).unwrap();
    Connection::open(&p)
        .unwrap()
        .execute("UPDATE tiles SET tile_data = x'89504e47' WHERE zoom_level = ?1", [meta.zoom(0)])
        .unwrap();
    let e = err(&p);
    assert!(e.contains("bad.mbtiles") && e.contains(&format!("{}/", meta.zoom(0))), "{e}");
    // a destination that is not an MBTiles file is left alone
    let p = d.join("mine.mbtiles");
    std::fs::write(&p, "my notes").unwrap();
    assert!(build_mbtiles(&src, &meta, &p, &[], &|_, _| {}).is_err());
    assert_eq!(std::fs::read_to_string(&p).unwrap(), "my notes");
    // a local pyramid is no MBTiles
    let local = StoreMeta::for_source(300, 300, [0.0, 0.0], [1.0, 1.0], "", "");
    let psrc = crate::gst::ProceduralSource { width: 300, height: 300, seed: 1 };
    assert!(build_mbtiles(&psrc, &local, &d.join("local.mbtiles"), &[], &|_, _| {}).is_err());
    assert!(!d.join("local.mbtiles").exists());
    let left: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// A copy of `good` as another tool would have made it: no hitex row, no
/// stored files, `sql` applied on top.
fn foreign_copy(good: &Path, to: &Path, sql: &str) {
    std::fs::copy(good, to).unwrap();
    let c = Connection::open(to).unwrap();
    c.execute_batch("DELETE FROM metadata WHERE name = 'hitex'; DROP TABLE hitex_files;").unwrap();
    c.execute_batch(sql).unwrap();
}

fn png(w: u32, h: u32, rgba: &[u8]) -> Vec<u8> {
    use image::ImageEncoder;
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new(&mut buf).write_image(rgba, w, h, image::ExtendedColorType::Rgba8).unwrap();
    buf
}

#[test]
fn another_tools_mbtiles_reads_as_the_same_store() {
    let (d, meta, _, good) = built("foreign");
    assert!(meta.levels >= 3, "{}", meta.levels);
    let hitex = Store::open(&good).unwrap();
    // only the finest zoom kept: every coarser level is built on reading
    let p = d.join("only14.mbtiles");
    foreign_copy(&good, &p, "DELETE FROM tiles WHERE zoom_level < 14;");
    let other = Store::open(&p).unwrap();
    assert_eq!(other.meta.levels, meta.levels);
    assert_eq!((other.meta.width, other.meta.height, other.meta.offset), (meta.width, meta.height, meta.offset));
    assert_eq!((other.meta.origin, other.meta.tiles), (meta.origin, meta.tiles));
    assert!(other.meta.source.contains("another tool"), "{}", other.meta.source);
    assert!(other.dem().unwrap().is_none());
    // the same filter over the same children: the same bits, twice (kept maps)
    for _ in 0..2 {
        for z in 0..meta.levels {
            for (x, y) in meta.data_maps(z) {
                assert!(other.read_tile(z, x, y).unwrap() == hitex.read_tile(z, x, y).unwrap(), "{z}/{x}/{y}");
            }
        }
    }
    // a zoom between two the file holds is built from the one below it
    let p = d.join("gap.mbtiles");
    foreign_copy(&good, &p, "DELETE FROM tiles WHERE zoom_level = 13;");
    let gap = Store::open(&p).unwrap();
    for z in 0..meta.levels {
        for (x, y) in meta.data_maps(z) {
            assert!(gap.read_tile(z, x, y).unwrap() == hitex.read_tile(z, x, y).unwrap(), "{z}/{x}/{y}");
        }
    }
    // without a bounds row the extent is the deepest tiles' squares
    let p = d.join("nobounds.mbtiles");
    foreign_copy(&good, &p, "DELETE FROM metadata WHERE name = 'bounds';");
    let nb = Store::open(&p).unwrap();
    let deepest = meta.data_range(meta.levels - 1);
    assert_eq!(nb.meta.offset, [deepest[0] * TILE, deepest[1] * TILE]);
    assert_eq!(nb.meta.width, (deepest[2] - deepest[0]) * TILE);
    assert_eq!(nb.meta.tiles, meta.tiles);
    // a JPEG tile reads within JPEG's error; a tile the file omits is transparent
    let (x, y) = meta.data_maps(meta.levels - 1).nth(1).unwrap();
    let (col, row) = (meta.global_tile(meta.levels - 1, x, y).0, meta.tms_row(meta.levels - 1, y));
    let want = hitex.read_tile(meta.levels - 1, x, y).unwrap();
    let rgb: Vec<u8> = want.chunks_exact(4).flat_map(|c| [c[0], c[1], c[2]]).collect();
    let mut jpg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 95)
        .encode(&rgb, TILE, TILE, image::ExtendedColorType::Rgb8)
        .unwrap();
    let p = d.join("jpeg.mbtiles");
    foreign_copy(&good, &p, "UPDATE metadata SET value = 'jpg' WHERE name = 'format';");
    Connection::open(&p)
        .unwrap()
        .execute(
            "UPDATE tiles SET tile_data = ?1 WHERE zoom_level = 14 AND tile_column = ?2 AND tile_row = ?3",
            params![jpg, col, row],
        )
        .unwrap();
    let got = Store::open(&p).unwrap().read_tile(meta.levels - 1, x, y).unwrap();
    // over the texels inside the data (JPEG has no alpha: opaque everywhere)
    let (mut sum, mut n) = (0.0, 0);
    for (g, w) in got.chunks_exact(4).zip(want.chunks_exact(4)) {
        assert_eq!(g[3], 255);
        if w[3] == 255 {
            sum += (0..3).map(|k| (g[k] as f64 - w[k] as f64).abs()).sum::<f64>();
            n += 3;
        }
    }
    assert!(n > 30_000 && sum / n as f64 <= 3.0 && got != want, "mean |Δ| {} over {n}", sum / n as f64);
    let p = d.join("hole.mbtiles");
    foreign_copy(
        &good,
        &p,
        &format!("DELETE FROM tiles WHERE zoom_level = 14 AND tile_column = {col} AND tile_row = {row};"),
    );
    assert!(Store::open(&p).unwrap().read_tile(meta.levels - 1, x, y).unwrap().iter().all(|&b| b == 0));
}

/// Bounds at tile edges written to 7 decimals (as tools write them) lie up
/// to 6 mm outside the tiles: at zoom 17 (1.2 m texels) the extent takes
/// in no texel, and so no level, beyond them.
#[test]
fn bounds_at_tile_edges_to_seven_decimals_take_in_no_extra_texel() {
    let (d, _, _, good) = built("foreign-edges");
    // one zoom-12 tile's square (column 1625, row 2063 from the north), its zoom-17 tiles
    let p = d.join("z17.mbtiles");
    foreign_copy(
        &good,
        &p,
        "UPDATE metadata SET value = '-37.1777344,-1.4061088,-37.0898438,-1.3182431' WHERE name = 'bounds';
         DELETE FROM tiles WHERE zoom_level < 14; UPDATE tiles SET zoom_level = 17;",
    );
    let m = Store::open(&p).unwrap().meta;
    assert_eq!((m.width, m.height, m.offset), (8192, 8192, [0, 0]));
    assert_eq!((m.levels, m.tiles), (6, [12, 1625, 2063]));
}

#[test]
fn tiles_of_512_texels_are_four_maps_each() {
    let (d, meta, _, good) = built("foreign512");
    let hitex = Store::open(&good).unwrap();
    // zoom-13 tiles of 512 texels stitched from the zoom-14 maps, rows from the north
    let fine = meta.levels - 1;
    let [x0, y0, x1, y1] = meta.data_range(fine);
    let p = d.join("big.mbtiles");
    foreign_copy(&good, &p, "DELETE FROM tiles; INSERT INTO metadata VALUES ('scheme', 'xyz');");
    let conn = Connection::open(&p).unwrap();
    let mut done = std::collections::HashSet::new();
    for y in y0..y1 {
        for x in x0..x1 {
            let (gx, gy) = meta.global_tile(fine, x, y);
            if !done.insert((gx / 2, gy / 2)) {
                continue;
            }
            let mut big = vec![0u8; (4 * TILE * TILE * 4) as usize];
            for (dx, dy) in [(0u32, 0u32), (1, 0), (0, 1), (1, 1)] {
                let (cx, cy) = ((gx / 2 * 2 + dx) - (gx - x), (gy / 2 * 2 + dy) - (gy - y));
                if cx < x0 || cy < y0 || cx >= x1 || cy >= y1 {
                    continue;
                }
                let m = hitex.read_tile(fine, cx, cy).unwrap();
                for j in 0..TILE {
                    let o = (((dy * TILE + j) * 2 * TILE + dx * TILE) * 4) as usize;
                    let i = (j * TILE * 4) as usize;
                    big[o..o + (TILE * 4) as usize].copy_from_slice(&m[i..i + (TILE * 4) as usize]);
                }
            }
            conn.execute(
                "INSERT INTO tiles VALUES (13, ?1, ?2, ?3)",
                params![gx / 2, gy / 2, png(2 * TILE, 2 * TILE, &big)],
            )
            .unwrap();
        }
    }
    drop(conn);
    let other = Store::open(&p).unwrap();
    assert_eq!((other.meta.tiles, other.meta.levels, other.meta.offset), (meta.tiles, meta.levels, meta.offset));
    for z in 0..meta.levels {
        for (x, y) in meta.data_maps(z) {
            assert!(other.read_tile(z, x, y).unwrap() == hitex.read_tile(z, x, y).unwrap(), "{z}/{x}/{y}");
        }
    }
}

#[test]
fn foreign_mbtiles_hitex_cannot_fly_are_named_errors() {
    let (d, meta, _, good) = built("foreign-bad");
    let err = |name: &str, sql: &str| -> String {
        let p = d.join(name);
        foreign_copy(&good, &p, sql);
        let e = match Store::open(&p) {
            Ok(s) => s
                .read_tile(meta.levels - 1, meta.data_range(meta.levels - 1)[0], meta.data_range(meta.levels - 1)[1])
                .err()
                .map(|e| e.to_string())
                .unwrap_or_else(|| "ok".into()),
            Err(e) => e.to_string(),
        };
        assert!(e.contains(name), "{name}: {e}");
        e
    };
    assert!(err("webp.mbtiles", "UPDATE metadata SET value = 'webp' WHERE name = 'format';").contains("\"webp\""));
    assert!(err("pbf.mbtiles", "UPDATE metadata SET value = 'pbf' WHERE name = 'format';").contains("vector tiles"));
    assert!(err("scheme.mbtiles", "INSERT INTO metadata VALUES ('scheme', 'quadkey');").contains("quadkey"));
    assert!(err("empty.mbtiles", "DELETE FROM tiles;").contains("no tiles"));
    assert!(err("zoom.mbtiles", "UPDATE tiles SET zoom_level = 30 WHERE zoom_level = 14;").contains("zooms"));
    assert!(err("bounds.mbtiles", "UPDATE metadata SET value = '-35,-8' WHERE name = 'bounds';").contains("bounds"));
    assert!(
        err("flip.mbtiles", "UPDATE metadata SET value = '-34,-8,-35,-7' WHERE name = 'bounds';").contains("bounds")
    );
    let odd = png(300, 300, &vec![9u8; 300 * 300 * 4]);
    let p = d.join("odd.mbtiles");
    foreign_copy(&good, &p, "");
    Connection::open(&p)
        .unwrap()
        .execute("UPDATE tiles SET tile_data = ?1 WHERE zoom_level = 14", params![odd])
        .unwrap();
    let e = Store::open(&p).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("300x300") && e.contains("odd.mbtiles"), "{e}");
    // a wide extent over only its deepest tiles: too many to build level 0 from
    let e = err(
        "wide.mbtiles",
        "UPDATE metadata SET value = '-40,-12,-30,-2' WHERE name = 'bounds'; DELETE FROM tiles WHERE zoom_level < 14;",
    );
    assert!(e.contains("coarser zooms"), "{e}");
    // a corrupt tile names its zoom, column and row
    let e = err("corrupt.mbtiles", "UPDATE tiles SET tile_data = x'89504e47' WHERE zoom_level = 14;");
    assert!(e.contains("corrupt.mbtiles/14/") && e.contains("image"), "{e}");
}
