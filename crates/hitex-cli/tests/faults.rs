//! Faults of the disk and the GPU, through the binary: a full disk and a
//! read-only folder while writing images, `.hbtf` files and tile stores (the
//! error names the file, the old file is intact, no temporary file is left),
//! no GPU adapter, and a GPU device lost during a render (the CPU takes over
//! under `--backend auto`; `--backend gpu` fails with a clear message; never
//! a hang).
//!
//! The disk faults need a tmpfs of their own, which needs root: without it
//! they print SKIPPED, and fail instead when `HITEX_REQUIRE_FAULTS=1` (CI).

mod common;

use common::{Tmpfs, error_lines, hitex, tmp, walk};
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn scene(dir: &Path) -> String {
    let o = hitex(&["demo", "--print-scene"]);
    assert!(o.status.success());
    let p = dir.join("scene.toml");
    std::fs::write(&p, &o.stdout).unwrap();
    p.to_string_lossy().into_owned()
}

fn render_to(scene: &str, out: &Path) -> Output {
    hitex(&["render", scene, "-o", out.to_str().unwrap(), "--size", "96x64", "--backend", "cpu"])
}

/// Renders into a fresh tmpfs, applies `fault`, renders again: exit 1 with one
/// line naming the image and `why`, and the old image byte-identical.
fn old_image_survives(name: &str, kib: u32, fault: impl Fn(&Tmpfs), why: &str) -> Option<Tmpfs> {
    let fs = Tmpfs::mount(name, kib)?;
    let scene_dir = tmp(&format!("{name}-scene"));
    let scene = scene(&scene_dir);
    let out = fs.dir.join("out.png");
    assert!(render_to(&scene, &out).status.success());
    let before = std::fs::read(&out).unwrap();
    fault(&fs);
    let o = render_to(&scene, &out);
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let e = error_lines(&o);
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(e[0].contains("out.png") && e[0].contains(why), "{e:?}");
    assert_eq!(std::fs::read(&out).unwrap(), before, "the old image changed");
    Some(fs)
}

#[test]
fn full_disk_keeps_the_old_image_and_leaves_no_temporary_file() {
    let Some(fs) = old_image_survives("fault-full-png", 256, Tmpfs::fill, "No space left on device") else { return };
    assert_eq!(fs.leftovers(&["out.png", "filler"]), Vec::<String>::new());
}

#[test]
fn full_disk_while_writing_a_btf_file() {
    let Some(fs) = Tmpfs::mount("fault-full-hbtf", 64) else { return };
    let out = fs.dir.join("m.hbtf");
    // 8×8 texels × (8×16)² directions × 3 bytes = 3 MiB: does not fit 64 KiB
    let o = hitex(&["btf", "synth", "corduroy", "--size", "8", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let e = error_lines(&o);
    assert!(e.iter().any(|l| l.contains("m.hbtf") && l.contains("No space left on device")), "{e:?}");
    assert_eq!(fs.leftovers(&[]), Vec::<String>::new(), "a partial .hbtf was left behind");
}

#[test]
fn full_disk_while_building_a_store_leaves_no_store_that_opens() {
    let Some(fs) = Tmpfs::mount("fault-full-store", 192) else { return };
    let store = fs.dir.join("store");
    // refused up front: the estimate exceeds the free space
    let o = hitex(&["terrain", "build", "--procedural", "2048x2048", "-o", store.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    assert!(error_lines(&o).iter().any(|l| l.contains("GiB are free")), "{o:?}");
    assert!(!store.exists(), "a refused build wrote something");
    // past the estimate, the disk fills during the build
    let o =
        hitex(&["terrain", "build", "--procedural", "2048x2048", "--ignore-free-space", "-o", store.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let e = error_lines(&o);
    assert!(e.iter().any(|l| l.contains("No space left on device")), "{e:?}");
    let left = fs.leftovers(&[]);
    assert!(left.iter().all(|f| f.ends_with(".png")), "temporary or description files left: {left:?}");
    // the partial store is not taken for a complete one
    let o = hitex(&["terrain", "fly", store.to_str().unwrap(), "--frames", "1", "-o", "/nonexistent"]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    assert!(error_lines(&o).iter().any(|l| l.contains("metadata.json")), "{o:?}");
}

#[test]
fn read_only_folder_keeps_the_old_image() {
    let Some(fs) = old_image_survives("fault-ro", 1024, Tmpfs::read_only, "Read-only file system") else { return };
    let o = hitex(&["btf", "synth", "corduroy", "--size", "4", "-o", fs.dir.join("m.hbtf").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    assert!(error_lines(&o).iter().any(|l| l.contains("m.hbtf") && l.contains("Read-only")), "{o:?}");
}

/// Runs hitex with extra environment, failing the test if it has not ended
/// within `limit` (a hang is a defect, not a slow run).
fn hitex_env(args: &[&str], env: &[(&str, &str)], limit: Duration) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_hitex"));
    cmd.args(args).stdout(Stdio::piped()).stderr(Stdio::piped());
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut child = cmd.spawn().unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            panic!("hitex {args:?} with {env:?} hung for {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

fn gpu_present() -> bool {
    let o = hitex(&["info"]);
    let present = !String::from_utf8_lossy(&o.stdout).contains("no GPU adapter found");
    if !present {
        let msg = "SKIPPED device-lost fault: no GPU adapter";
        if std::env::var("HITEX_REQUIRE_GPU").is_ok_and(|v| v == "1") {
            panic!("{msg}, and HITEX_REQUIRE_GPU=1");
        }
        common::say_skipped(msg);
    }
    present
}

#[test]
fn no_adapter_falls_back_under_auto_and_fails_clearly_under_gpu() {
    let d = tmp("fault-noadapter");
    let scene = scene(&d);
    let out = d.join("a.png");
    // a backend this build does not have: no adapter at all
    let env = [("WGPU_BACKEND", "metal")];
    let args = ["render", &scene, "-o", out.to_str().unwrap(), "--size", "48x32"];
    let o = hitex_env(&[&args[..], &["--backend", "auto"]].concat(), &env, Duration::from_secs(120));
    assert!(o.status.success(), "{o:?}");
    assert!(
        error_lines(&o).iter().any(|l| l.contains("no GPU adapter found") && l.contains("falling back to the CPU")),
        "{o:?}"
    );
    assert!(out.is_file());
    let o = hitex_env(&[&args[..], &["--backend", "gpu"]].concat(), &env, Duration::from_secs(120));
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let e = error_lines(&o);
    assert!(e.len() == 1 && e[0].contains("no GPU adapter found") && e[0].contains("mesa-vulkan-drivers"), "{e:?}");
}

#[test]
fn lost_device_hands_the_frame_to_the_cpu() {
    if !gpu_present() {
        return;
    }
    let d = tmp("fault-lost");
    let scene = scene(&d);
    let (lost, cpu) = (d.join("lost.png"), d.join("cpu.png"));
    // auto takes a software adapter only when told to
    let env = [("HITEX_GPU_FAULT", "device-lost"), ("HITEX_SOFTWARE_GPU", "1")];
    let limit = Duration::from_secs(180);
    let o = hitex_env(&["render", &scene, "-o", lost.to_str().unwrap(), "--size", "96x64"], &env, limit);
    assert!(o.status.success(), "{o:?}");
    let e = error_lines(&o);
    assert!(
        e.iter().any(|l| l.contains("GPU device was lost") && l.contains("continuing on the CPU backend")),
        "{e:?}"
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("cpu"), "{o:?}");
    assert!(render_to(&scene, &cpu).status.success());
    assert_eq!(
        std::fs::read(&lost).unwrap(),
        std::fs::read(&cpu).unwrap(),
        "the fallback frame differs from the CPU's"
    );
    // asked for the GPU explicitly: a clear failure, exit 1, no image
    let other = d.join("gpu.png");
    let o = hitex_env(
        &["render", &scene, "-o", other.to_str().unwrap(), "--size", "96x64", "--backend", "gpu"],
        &env,
        limit,
    );
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let e = error_lines(&o);
    assert!(e.len() == 1 && e[0].contains("GPU device was lost"), "{e:?}");
    assert!(!other.exists());
    // a flight: every frame goes on on the CPU
    let store = d.join("store");
    assert!(hitex(&["terrain", "build", "--procedural", "512x512", "-o", store.to_str().unwrap()]).status.success());
    let frames = d.join("frames");
    let o = hitex_env(
        &[
            "terrain",
            "fly",
            store.to_str().unwrap(),
            "--frames",
            "3",
            "--size",
            "64x48",
            "-o",
            frames.to_str().unwrap(),
        ],
        &env,
        limit,
    );
    assert!(o.status.success(), "{o:?}");
    let n = error_lines(&o).iter().filter(|l| l.contains("continuing on the CPU backend")).count();
    assert_eq!(n, 1, "the fallback is announced once: {o:?}");
}

#[test]
fn a_store_modified_while_flying() {
    let d = tmp("fault-store-changes");
    let store = d.join("store");
    let s = store.to_str().unwrap().to_string();
    assert!(hitex(&["terrain", "build", "--procedural", "2048x2048", "-o", &s]).status.success());
    let frames = d.join("frames");
    let mut child = Command::new(env!("CARGO_BIN_EXE_hitex"))
        .args(["terrain", "fly", &s, "--frames", "40", "--size", "160x120", "--altitude", "250", "--backend", "cpu"])
        .args(["-o", frames.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // while it flies: maps corrupted, truncated, deleted and rewritten, the description replaced
    let mut tiles = Vec::new();
    walk(&store, &mut tiles);
    // all but the level-0 map, which the flight pins when it starts (and refuses to start without)
    tiles.retain(|t| t.ends_with(".png") && !t.ends_with("/0/0/0.png"));
    tiles.sort();
    let start = Instant::now();
    let mut k = 0usize;
    while child.try_wait().unwrap().is_none() {
        assert!(start.elapsed() < Duration::from_secs(300), "the flight hung");
        let t = &tiles[(k * 7919) % tiles.len()];
        match k % 4 {
            0 => drop(std::fs::write(t, b"not a png")),
            1 => drop(std::fs::remove_file(t)),
            2 => {
                if let Ok(bytes) = std::fs::read(t) {
                    let _ = std::fs::write(t, &bytes[..bytes.len() / 3]);
                }
            }
            // the description once the flight has read it (a store without one is refused, rightly)
            _ if frames.join("frame-0000.png").exists() => {
                drop(std::fs::write(store.join("metadata.json"), b"{\"format\": \"changed\"}"))
            }
            _ => {}
        }
        k += 1;
        std::thread::sleep(Duration::from_millis(1));
    }
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in 0..40 {
        assert!(frames.join(format!("frame-{f:04}.png")).exists(), "frame {f} missing");
    }
    // each damaged map is reported at most once
    let lines = error_lines(&o);
    let mut named: Vec<&String> = lines.iter().collect();
    named.sort();
    let before = named.len();
    named.dedup();
    assert_eq!(before, named.len(), "a warning repeated: {lines:?}");
    assert!(k > 10, "the store was changed only {k} times");
    println!("the store changed {k} times during the flight; {} distinct warnings", lines.len());
}
