//! Shared helpers of the image tests: backends, references, tolerances.
#![allow(dead_code)]

use hitex_render::{Frame, GpuRenderer, ImageDiff, compare_rgba};
use std::path::{Path, PathBuf};

/// Tolerance of an image comparison, with its metric named.
#[derive(Debug, Clone, Copy)]
pub struct Tolerance {
    /// Largest mean absolute channel difference (8-bit steps).
    pub mean_abs: f64,
    /// Largest 99th percentile of per-pixel max channel difference (8-bit steps).
    pub p99: u8,
}

/// CPU against its own stored reference: same code, same machine class.
pub const CPU_VS_REFERENCE: Tolerance = Tolerance { mean_abs: 0.05, p99: 1 };
/// GPU (any Mesa/LLVM version) against the CPU: float rounding, the GPU's
/// log2/pow approximations and rasterizer details move a few pixels by a few
/// steps (measured on lavapipe: mean ≤ 0.08, p99 ≤ 1).
pub const GPU_VS_CPU: Tolerance = Tolerance { mean_abs: 0.4, p99: 3 };
/// GPU against CPU without MIP mapping: minified, aliased texels turn a
/// rounding difference of 10⁻⁶ in uv into a different texel (measured on
/// lavapipe: mean ≤ 0.42, p99 ≤ 5 for bilinear).
pub const GPU_VS_CPU_ALIASED: Tolerance = Tolerance { mean_abs: 1.2, p99: 16 };

/// The GPU renderer, or `None` with a visible message when no adapter exists.
/// With `HITEX_REQUIRE_GPU=1` a missing adapter fails the test instead.
pub fn gpu_or_skip(test: &str) -> Option<GpuRenderer> {
    match GpuRenderer::new() {
        Ok(g) => Some(g),
        Err(e) => {
            if std::env::var("HITEX_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("{test}: HITEX_REQUIRE_GPU=1 but no GPU backend: {e}");
            }
            say_skipped(&format!("SKIPPED {test}: no GPU adapter ({e})"));
            None
        }
    }
}

pub fn out_dir() -> PathBuf {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/test-output");
    let _ = std::fs::create_dir_all(&d);
    d
}

pub fn save(path: &Path, w: u32, h: u32, rgba: &[u8]) {
    if let Err(e) = hitex_io::save_png(path, w, h, rgba) {
        eprintln!("could not write {}: {e}", path.display());
    }
}

/// Compares `actual` with `expected` under `tol`; on failure writes
/// `<name>.actual.png`, `<name>.expected.png` and `<name>.diff.png` into
/// `target/test-output/` and panics with the metrics.
pub fn assert_images(name: &str, actual: &Frame, expected: &Frame, tol: Tolerance) -> ImageDiff {
    assert_eq!((actual.width, actual.height), (expected.width, expected.height), "{name}: sizes differ");
    let (d, diff) = compare_rgba(&actual.rgba, &expected.rgba);
    eprintln!("{name}: {d}");
    if d.mean_abs > tol.mean_abs || d.p99 > tol.p99 {
        let dir = out_dir();
        save(&dir.join(format!("{name}.actual.png")), actual.width, actual.height, &actual.rgba);
        save(&dir.join(format!("{name}.expected.png")), expected.width, expected.height, &expected.rgba);
        save(&dir.join(format!("{name}.diff.png")), actual.width, actual.height, &diff);
        panic!("{name}: {d} exceeds {tol:?}; images in {}", dir.display());
    }
    d
}

/// The stored reference `tests/images/<name>.png`; `HITEX_BLESS=1` rewrites it from `frame`.
pub fn reference(name: &str, frame: &Frame) -> Frame {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/images").join(format!("{name}.png"));
    if std::env::var("HITEX_BLESS").is_ok_and(|v| v == "1") {
        save(&path, frame.width, frame.height, &frame.rgba);
    }
    let img = match hitex_io::load_image(&path, hitex_core::texture::ColorSpace::Srgb) {
        Ok(i) => i,
        Err(e) => panic!("reference {}: {e} (run with HITEX_BLESS=1 to create it)", path.display()),
    };
    Frame { width: img.width(), height: img.height(), rgba: img.bytes().to_vec() }
}

/// Prints a test's SKIPPED line to the process's standard error itself,
/// past the test harness's capture, so that a skip is seen in every log.
pub fn say_skipped(msg: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{msg}");
}
