//! `hitex view` under Xvfb: a few frames in a real window, a screenshot, and
//! the screenshot equal to the headless render of the same camera; without a
//! display, one clear message.
//!
//! Needs Xvfb (installed by scripts/ensure-deps.sh): without it the window
//! tests print SKIPPED, and fail instead when `HITEX_REQUIRE_VIEWER=1` (CI).
#![cfg(feature = "viewer")]

mod common;

use common::{error_lines, hitex, tmp};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A virtual X server on a display of its own, stopped when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start(n: u32) -> Option<Xvfb> {
        let display = format!(":{n}");
        let child = Command::new("Xvfb")
            .args([display.as_str(), "-screen", "0", "1280x800x24", "-nolisten", "tcp"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn();
        let Ok(child) = child else {
            let msg = "SKIPPED viewer: Xvfb is not installed (scripts/ensure-deps.sh installs it)";
            if std::env::var("HITEX_REQUIRE_VIEWER").is_ok_and(|v| v == "1") {
                panic!("{msg}, and HITEX_REQUIRE_VIEWER=1");
            }
            common::say_skipped(msg);
            return None;
        };
        let x = Xvfb { child, display };
        let socket = format!("/tmp/.X11-unix/X{n}");
        let start = Instant::now();
        while !Path::new(&socket).exists() {
            assert!(start.elapsed() < Duration::from_secs(20), "Xvfb {} did not start", x.display);
            std::thread::sleep(Duration::from_millis(50));
        }
        Some(x)
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn view(display: &str, args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_hitex"))
        .arg("view")
        .args(args)
        .env("DISPLAY", display)
        .env_remove("WAYLAND_DISPLAY")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(240) {
            let _ = child.kill();
            panic!("hitex view {args:?} did not close");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    child.wait_with_output().unwrap()
}

fn pixels(p: &Path) -> (u32, u32, Vec<u8>) {
    let img = image::open(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())).into_rgba8();
    (img.width(), img.height(), img.into_raw())
}

/// Mean absolute difference in 8-bit steps.
fn mean_diff(a: &[u8], b: &[u8]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (*x as f64 - *y as f64).abs()).sum::<f64>() / a.len().max(1) as f64
}

/// Where the window screenshot `win` shows the image `view` pixel for pixel:
/// the least mean |Δ| of `view` against the window's pixels at an offset
/// whose first row matches (within two steps a channel), if one does.
fn shown_in(win: &(u32, u32, Vec<u8>), view: &(u32, u32, Vec<u8>)) -> Option<f64> {
    let ((ww, wh, w), (vw, vh, v)) =
        ((win.0 as usize, win.1 as usize, &win.2), (view.0 as usize, view.1 as usize, &view.2));
    let row = |y: usize, x: usize, n: usize| &w[(y * ww + x) * 4..(y * ww + x + n) * 4];
    let near = |a: &[u8], b: &[u8]| a.iter().zip(b).all(|(p, q)| p.abs_diff(*q) <= 2);
    let mut best: Option<f64> = None;
    for y in 0..=wh.saturating_sub(vh) {
        for x in 0..=ww.saturating_sub(vw) {
            if !near(row(y, x, vw), &v[..vw * 4]) {
                continue;
            }
            let crop: Vec<u8> = (0..vh).flat_map(|r| row(y + r, x, vw).to_vec()).collect();
            let d = mean_diff(&crop, v);
            best = Some(best.map_or(d, |b: f64| b.min(d)));
        }
    }
    best
}

#[test]
fn screenshots_equal_the_headless_renders() {
    // a display number of this process's own, not locked by another server
    let n = (90 + std::process::id() % 100..400).find(|n| !Path::new(&format!("/tmp/.X{n}-lock")).exists());
    let Some(x) = Xvfb::start(n.unwrap_or(399)) else { return };
    let d = tmp("view");
    let scene = d.join("scene.toml");
    std::fs::write(&scene, hitex_core::scene::SHOWCASE_TOML).unwrap();
    let scene = scene.to_str().unwrap();
    let shot = |name: &str| d.join(name).to_string_lossy().into_owned();
    // a BTF compressed by local PCA: the view draws it from its basis, as `btf render` does
    let (raw, pca) = (shot("w.hbtf"), shot("w-pca.hbtf"));
    let o = hitex(&["btf", "synth", "woven", "-o", &raw, "--size", "8", "--theta", "0,30,60", "--phi", "6"]);
    assert!(o.status.success(), "{o:?}");
    assert!(hitex(&["btf", "compress", &raw, "--pca", "1,2", "-o", &pca]).status.success());
    let cases: Vec<(Vec<String>, Vec<String>, &str)> = vec![
        (
            vec![pca.clone(), "--backend".into(), "cpu".into()],
            ["btf", "render", &pca, "--on", "sphere", "--repeats", "4", "--backend", "cpu"].map(String::from).to_vec(),
            "btf-pca-cpu",
        ),
        (
            vec![scene.into(), "--backend".into(), "cpu".into()],
            vec!["render".into(), scene.into(), "--backend".into(), "cpu".into()],
            "scene-cpu",
        ),
        (
            vec!["surface".into(), "--mode".into(), "isophote".into(), "--backend".into(), "cpu".into()],
            vec![
                "nurbs".into(),
                "render".into(),
                "surface".into(),
                "--mode".into(),
                "isophote".into(),
                "--backend".into(),
                "cpu".into(),
            ],
            "nurbs-cpu",
        ),
        (
            vec![scene.into(), "--backend".into(), "auto".into()],
            vec!["render".into(), scene.into(), "--backend".into(), "auto".into()],
            "scene-auto",
        ),
        // the GPU draws on the window's own device, into the texture the window shows
        (
            vec![scene.into(), "--backend".into(), "gpu".into()],
            vec!["render".into(), scene.into(), "--backend".into(), "gpu".into()],
            "scene-gpu",
        ),
        (
            vec!["surface".into(), "--mode".into(), "isophote".into(), "--backend".into(), "gpu".into()],
            ["nurbs", "render", "surface", "--mode", "isophote", "--backend", "gpu"].map(String::from).to_vec(),
            "nurbs-gpu",
        ),
    ];
    for (view_args, render_args, name) in cases {
        let png = shot(&format!("{name}-view.png"));
        let mut a: Vec<&str> = view_args.iter().map(String::as_str).collect();
        a.extend(["--size", "160x120", "--frames", "3", "--screenshot", &png]);
        let window = shot(&format!("{name}-window.png"));
        a.extend(["--window-screenshot", &window]);
        let o = view(&x.display, &a);
        assert!(
            o.status.success(),
            "{name}: {}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        let said = String::from_utf8_lossy(&o.stdout);
        assert!(said.contains("wrote"), "{name}: {o:?}");
        let in_texture = said.contains("drawn into the window's texture on the GPU");
        // (auto draws in place on a hardware GPU, on the CPU otherwise)
        if !name.ends_with("auto") {
            assert_eq!(in_texture, name.ends_with("gpu"), "{name}: {said}");
        }
        let reference = shot(&format!("{name}-render.png"));
        let mut r: Vec<&str> = render_args.iter().map(String::as_str).collect();
        r.extend(["--size", "160x120", "-o", &reference]);
        let o = hitex(&r);
        assert!(o.status.success(), "{name}: {o:?}");
        let (va, vb) = (pixels(Path::new(&png)), pixels(Path::new(&reference)));
        assert_eq!((va.0, va.1), (vb.0, vb.1), "{name}: sizes differ");
        // the same renderer draws both: the CPU backend exactly, a GPU within the parity tolerance
        let m = mean_diff(&va.2, &vb.2);
        let tolerance = if name.ends_with("cpu") { 0.0 } else { 0.4 };
        assert!(m <= tolerance, "{name}: mean |Δ| {m} > {tolerance}");
        println!("{name}: view screenshot vs headless render, mean |Δ| = {m:.4}");
        // what the window shows is that image (drawn in place on the GPU, uploaded otherwise)
        let shown = shown_in(&pixels(Path::new(&window)), &va);
        assert!(shown.is_some_and(|d| d <= 0.5), "{name}: the window does not show the view ({shown:?})");
        println!("{name}: window's view area vs view screenshot, mean |Δ| = {:.4}", shown.unwrap_or(f64::NAN));
    }
    // a display but no adapter to draw the window with: one clear message, no panic
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_hitex"));
    cmd.args(["view", "surface", "--frames", "1", "--screenshot", &shot("none.png")]);
    let o = cmd.env("DISPLAY", &x.display).env("WGPU_BACKEND", "metal").output().unwrap();
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let e: Vec<String> = error_lines(&o).into_iter().filter(|l| l.contains("error")).collect();
    assert!(e.len() == 1 && e[0].contains("cannot open a window") && e[0].contains("lavapipe"), "{e:?}");
}

#[test]
fn without_a_display_one_clear_message() {
    let d = tmp("view-nodisplay");
    let scene = d.join("scene.toml");
    std::fs::write(&scene, hitex_core::scene::SHOWCASE_TOML).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_hitex"))
        .args(["view", scene.to_str().unwrap()])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let e = error_lines(&o);
    assert!(e.len() == 1 && e[0].contains("no display") && e[0].contains("hitex render"), "{e:?}");
    // bad input is reported before any window is asked for
    let o = hitex(&["view", "nowhere.igs"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let o = hitex(&["view", "surface", "--mode", "sparkle"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    assert!(error_lines(&o).iter().any(|l| l.contains("isophote")), "{o:?}");
}
