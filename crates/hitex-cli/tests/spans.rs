//! `hitex terrain spans`: a tiny flight runs, writes its comparison image and
//! reports zero bank conflicts.

mod common;

use common::{hitex, tmp};
use std::path::PathBuf;

/// The number after "total bank conflicts:".
fn conflicts(stdout: &str) -> Option<u64> {
    stdout.lines().find_map(|l| l.strip_prefix("total bank conflicts:")).and_then(|v| v.trim().parse().ok())
}

fn run_ok(name: &str, extra: &[&str]) -> String {
    let d = tmp(name);
    let out = d.join("spans.png");
    let mut args = vec!["terrain", "spans", "--size", "48x32", "--frames", "2", "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = hitex(&args);
    let stdout = String::from_utf8_lossy(&o.stdout).to_string();
    assert_eq!(o.status.code(), Some(0), "{name}: {stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    let meta = std::fs::metadata(&out).unwrap_or_else(|e| panic!("{name}: no output: {e}"));
    assert!(meta.len() > 100, "{name}: output of {} bytes", meta.len());
    assert_eq!(conflicts(&stdout), Some(0), "{name}: {stdout}");
    for case in ["trilinear", "span3", "span4", "bicubic3", "bicubic4", "conventional", "span 3x3"] {
        assert!(stdout.contains(case), "{name}: no '{case}' in {stdout}");
    }
    let _ = std::fs::remove_dir_all(&d);
    stdout
}

#[test]
fn procedural_flight_has_no_bank_conflicts() {
    let s = run_ok("procedural", &["--texture-size", "128", "--pattern", "checker"]);
    // the 3×3 design holds about a quarter of the conventional memory
    assert!(s.contains("of conventional"), "{s}");
}

#[test]
fn geotiff_flight_has_no_bank_conflicts() {
    // the Landsat scene kept in the repository (the same file as ../shared/data/terrain)
    let tif = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../hitex-io/data/olinda/L7_ETMs.tif");
    run_ok("geotiff", &["--image", tif.to_str().unwrap(), "--bands", "3,2,1", "--pitch", "50"]);
}

#[test]
fn bad_arguments_exit_2() {
    let d = tmp("spans-bad");
    let out = d.join("x.png");
    for bad in [
        vec!["--pitch", "0"],
        vec!["--pattern", "nope"],
        vec!["--altitude", "-3"],
        vec!["--frames", "0"],
        vec!["--image", "/nonexistent/x.png"],
    ] {
        let mut args = vec!["terrain", "spans", "--size", "16x16", "-o", out.to_str().unwrap()];
        args.extend_from_slice(&bad);
        let o = hitex(&args);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", String::from_utf8_lossy(&o.stderr));
    }
    let _ = std::fs::remove_dir_all(&d);
}
