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
