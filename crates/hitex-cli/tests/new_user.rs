//! What a new user meets on the way in: pipes, negative numbers, output
//! names, the backend `auto` chooses, exports that must keep everything.

mod common;

use common::{error_lines, hitex, tmp};
use std::io::Read;
use std::process::{Command, Stdio};

fn teapot() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/teapot.igs").to_string()
}

/// Runs `args` as a small CPU render into `out`.
fn tiny(args: &[&str], out: &std::path::Path) -> std::process::Output {
    let tail = ["--size", "32x24", "--backend", "cpu", "-o", out.to_str().unwrap()];
    hitex(&[args, &tail[..]].concat())
}

fn holed() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/holed-square.igs").to_string()
}

#[test]
fn a_closed_pipe_ends_quietly() {
    for args in [vec!["nurbs", "info", &teapot()[..]], vec!["btf", "info", "knit"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_hitex"))
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("hitex runs");
        // read one line's worth, then close the pipe as `head -1` does
        let mut out = child.stdout.take().expect("stdout");
        let mut first = [0u8; 1];
        let _ = out.read(&mut first);
        drop(out);
        let mut err = String::new();
        let _ = child.stderr.take().expect("stderr").read_to_string(&mut err);
        let status = child.wait().expect("hitex ends");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert_ne!(status.code(), Some(101), "{args:?}: {err}");
    }
}

#[test]
fn negative_numbers_are_numbers() {
    let d = tmp("negative");
    let out = d.join("k.png");
    let o = hitex(&[
        "btf",
        "render",
        "knit",
        "--light-azimuth",
        "-30",
        "--size",
        "32x24",
        "--backend",
        "cpu",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // a parameter pair with a negative first value reaches hitex's own check
    let o = hitex(&["nurbs", "eval", "teapot", "--uv", "-0.1,0.5"]);
    assert_eq!(o.status.code(), Some(2));
    let e = error_lines(&o);
    assert!(e.len() == 1 && e[0].contains("outside the patch domain"), "{e:?}");
    // a negative repeat count is refused by its own message, not by the parser
    let o = hitex(&["btf", "render", "knit", "--repeats", "-2", "-o", out.to_str().unwrap()]);
    let e = error_lines(&o);
    assert!(e.len() == 1 && e[0].contains("--repeats -2 must be in (0, 1000]"), "{e:?}");
}

#[test]
fn the_output_extension_names_the_format() {
    let d = tmp("extension");
    let jpg = d.join("k.jpg");
    let o = tiny(&["btf", "render", "knit"], &jpg);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&jpg).unwrap();
    assert_eq!(&bytes[..3], &[0xff, 0xd8, 0xff], "a .jpg holds JPEG");
    let png = d.join("k.PNG");
    let o = tiny(&["btf", "render", "knit"], &png);
    assert!(o.status.success());
    assert_eq!(&std::fs::read(&png).unwrap()[..4], b"\x89PNG");
    // refused before any work, nothing written
    let txt = d.join("k.txt");
    let o = hitex(&["nurbs", "render", "teapot", "-o", txt.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!txt.exists());
    // missing folders are created, as for every output
    let nested = d.join("a/b/c.png");
    let o = tiny(&["nurbs", "render", "teapot"], &nested);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(nested.is_file());
}

#[test]
fn auto_names_its_backend_and_why() {
    let d = tmp("auto");
    let out = d.join("t.png");
    let o = hitex(&["nurbs", "render", "teapot", "--size", "32x24", "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    // on a machine whose only adapter is a software rasterizer, auto takes the
    // CPU and says why; with a hardware GPU it names the GPU
    assert!(
        text.contains("auto: no hardware GPU") || text.contains("gpu: ") || stderr.contains("falling back to the CPU"),
        "{text}"
    );
    assert!(!stderr.lines().any(|l| l.contains("error")), "a line saying error on success: {stderr}");
}

#[test]
fn nurbs_export_keeps_trims_in_every_format() {
    let d = tmp("export-trims");
    let info = |path: &str| -> String {
        let o = hitex(&["nurbs", "info", path]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let original = info(&holed());
    assert!(original.contains("trim"), "{original}");
    for ext in ["igs", "obj", "json"] {
        let out = d.join(format!("back.{ext}"));
        let o = hitex(&["nurbs", "export", &holed(), "-o", out.to_str().unwrap()]);
        assert!(o.status.success(), "{ext}: {}", String::from_utf8_lossy(&o.stderr));
        let back = info(out.to_str().unwrap());
        // the per-patch lines (degrees, trims, loop sizes) are the same
        let trims = |s: &str| -> Vec<String> {
            s.lines().filter(|l| l.starts_with(' ') && l.contains("trim")).map(str::to_string).collect()
        };
        assert_eq!(trims(&original), trims(&back), "{ext}");
    }
}

#[test]
fn suspicious_inputs_are_named_on_stderr() {
    let d = tmp("suspicious");
    // a free-form OBJ cut off in the middle of its vertices
    let full = d.join("t.obj");
    assert!(hitex(&["nurbs", "export", "teapot", "-o", full.to_str().unwrap()]).status.success());
    let text = std::fs::read_to_string(&full).unwrap();
    let cut = d.join("cut.obj");
    std::fs::write(&cut, &text[..text.len() - 300]).unwrap();
    let out = d.join("o.png");
    let o = tiny(&["nurbs", "render", cut.to_str().unwrap()], &out);
    assert!(o.status.success());
    let e = error_lines(&o);
    assert!(e.iter().any(|l| l.contains("warning") && l.contains("truncated")), "{e:?}");
    // six-band imagery given as a DEM
    let image = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/olinda/L7_ETMs.tif");
    let o = tiny(&["terrain", "render", "--dem", image], &out);
    assert!(o.status.success());
    let e = error_lines(&o);
    assert!(e.iter().any(|l| l.contains("6 bands") && l.contains("colour imagery")), "{e:?}");
}

/// Pixels of `path` that differ from its top-left (background) pixel.
fn model_pixels(path: &std::path::Path) -> (image::RgbImage, Vec<(u32, u32)>) {
    let img = image::open(path).unwrap().to_rgb8();
    let bg = *img.get_pixel(0, 0);
    let px = img.enumerate_pixels().filter(|(_, _, p)| **p != bg).map(|(x, y, _)| (x, y)).collect();
    (img, px)
}

#[test]
fn every_view_is_framed_and_the_legend_stays_clear() {
    let d = tmp("framing");
    // at every turn and elevation the whole model is in the frame, not touching its edges
    for (turn, elevation) in [("0", "23.5"), ("90", "23.5"), ("180", "-40"), ("270", "80")] {
        let out = d.join(format!("t{turn}.png"));
        let o = hitex(&[
            "nurbs",
            "render",
            "teapot",
            "--turn",
            turn,
            "--elevation",
            elevation,
            "--size",
            "160x120",
            "--backend",
            "cpu",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(String::from_utf8_lossy(&o.stdout).contains("view: up +Z"), "{}", String::from_utf8_lossy(&o.stdout));
        let (img, px) = model_pixels(&out);
        assert!(px.len() > 2000, "turn {turn}: {} model pixels", px.len());
        let touches = px.iter().any(|&(x, y)| x == 0 || y == 0 || x + 1 == img.width() || y + 1 == img.height());
        assert!(!touches, "turn {turn} elevation {elevation}: the model reaches the frame's edge");
    }
    // a curvature map: the model left of the legend strip, the legend inside it
    let out = d.join("mean.png");
    let o = hitex(&[
        "nurbs",
        "render",
        "teapot",
        "--mode",
        "mean",
        "--size",
        "320x240",
        "--backend",
        "cpu",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let strip = hitex_render::legend::legend_width(320, 240);
    assert!(strip > 0);
    let plain = d.join("mean-plain.png");
    let o = hitex(&[
        "nurbs",
        "render",
        "teapot",
        "--mode",
        "shaded",
        "--size",
        "320x240",
        "--backend",
        "cpu",
        "-o",
        plain.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    let (_, px) = model_pixels(&out);
    assert!(px.iter().any(|&(x, _)| x >= 320 - strip), "no legend drawn");
    // the framing for a legend leaves the strip and a margin free: the shaded
    // model (no legend) fills wider than the curvature one
    let right = |v: &[(u32, u32)]| v.iter().map(|p| p.0).filter(|&x| x < 320 - strip).max().unwrap();
    let (_, shaded) = model_pixels(&plain);
    assert!(right(&px) + 4 < 320 - strip, "the model runs into the legend strip");
    assert!(right(&shaded) > right(&px), "the legend's strip was not kept clear");
    // an up axis the user names; bad values refused
    let o = tiny(&["nurbs", "render", "teapot", "--up", "-y"], &d.join("y.png"));
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("up -Y"));
    for bad in [vec!["--up", "w"], vec!["--elevation", "90"], vec!["--elevation", "nan"]] {
        let o = tiny(&[&["nurbs", "render", "teapot"], &bad[..]].concat(), &d.join("bad.png"));
        assert_eq!(o.status.code(), Some(2), "{bad:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(bad[0]) && e.lines().count() <= 4, "{bad:?}: {e}");
    }
}

#[test]
fn tiny_curvature_ranges_keep_their_digits() {
    let d = tmp("tiny-range");
    let o = tiny(&["nurbs", "render", "teapot", "--mode", "gauss", "--range", "1e-6"], &d.join("g.png"));
    assert!(o.status.success());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("1.00e-6") && !out.contains("0.0000"), "{out}");
}

/// Pixels at least 40 levels darker (mean of RGB) than all but the darkest
/// of their eight neighbours: isolated specks, not edges or notches.
fn specks(path: &std::path::Path) -> usize {
    let img = image::open(path).unwrap().to_rgb8();
    let lum = |x: u32, y: u32| img.get_pixel(x, y).0.iter().map(|&c| c as i32).sum::<i32>() / 3;
    let mut n = 0;
    for y in 1..img.height() - 1 {
        for x in 1..img.width() - 1 {
            let mut around: Vec<i32> = (0..9).filter(|&k| k != 4).map(|k| lum(x + k % 3 - 1, y + k / 3 - 1)).collect();
            around.sort_unstable();
            if around[1] - lum(x, y) >= 40 {
                n += 1;
            }
        }
    }
    n
}

#[test]
fn ridge_outlines_are_clean_on_both_backends() {
    // the far slope's slivers at a ridge's outline used to be lit as their
    // underside: isolated dark pixels along every ridge
    let dem = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/jacksboro_fault_dem.npz");
    let d = tmp("ridges");
    let require = std::env::var("HITEX_REQUIRE_GPU").is_ok_and(|v| v == "1");
    for backend in ["cpu", "gpu"] {
        let out = d.join(format!("{backend}.png"));
        let o = hitex(&[
            "terrain",
            "render",
            "--dem",
            dem,
            "--size",
            "640x480",
            "--backend",
            backend,
            "-o",
            out.to_str().unwrap(),
        ]);
        if backend == "gpu" && !o.status.success() && !require {
            eprintln!("SKIPPED ridge outlines on the GPU backend: {}", String::from_utf8_lossy(&o.stderr));
            continue;
        }
        assert!(o.status.success(), "{backend}: {}", String::from_utf8_lossy(&o.stderr));
        let n = specks(&out);
        assert!(n <= 2, "{backend}: {n} dark specks along the ridges");
    }
}

#[test]
fn pitch_is_below_the_horizon_everywhere() {
    let d = tmp("pitch");
    let store = d.join("store");
    let o = hitex(&["terrain", "build", "--procedural", "300x300", "-o", store.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let dem = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/jacksboro_fault_dem.npz");
    let out = d.join("o.png");
    let frames = d.join("frames");
    let (s, o_, f) = (store.to_str().unwrap(), out.to_str().unwrap(), frames.to_str().unwrap());
    // one convention and one wording for out-of-range pitches
    for args in [
        vec!["terrain", "render", "--dem", dem, "--pitch", "95", "-o", o_],
        vec!["terrain", "spans", "--pitch", "95", "--frames", "1", "-o", o_],
        vec!["terrain", "fly", s, "--pitch", "95", "--frames", "1", "-o", f],
    ] {
        let o = hitex(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let e = error_lines(&o).join("\n");
        assert!(e.contains("must be in (0, 90] below the horizon (90 looks straight down)"), "{args:?}: {e}");
    }
    // straight down is 90 everywhere, and a grazing 0.5 is a pitch too
    for pitch in ["90", "0.5"] {
        for args in [
            vec!["terrain", "render", "--dem", dem, "--size", "64x48", "--backend", "cpu", "-o", o_],
            vec!["terrain", "spans", "--size", "64x48", "--frames", "1", "-o", o_],
            vec!["terrain", "fly", s, "--frames", "1", "--size", "64x48", "--backend", "cpu", "-o", f],
        ] {
            let o = hitex(&[&args[..], &["--pitch", pitch][..]].concat());
            assert!(o.status.success(), "{args:?} --pitch {pitch}: {}", String::from_utf8_lossy(&o.stderr));
        }
    }
    // a path key in the old sense (0 = straight down) is refused with the convention named
    let path = d.join("path.toml");
    std::fs::write(&path, "[[key]]\nt = 0\nx = 0.5\ny = 0.5\naltitude = 100\npitch = 0\nheading = 0\n").unwrap();
    let o = hitex(&["terrain", "fly", s, "--path", path.to_str().unwrap(), "--frames", "1", "-o", f]);
    assert_eq!(o.status.code(), Some(2));
    assert!(error_lines(&o).join("\n").contains("below the horizon"));
}

#[test]
fn second_pass_defects_stay_fixed() {
    let d = tmp("second-pass");
    let p = |n: &str| d.join(n).to_str().unwrap().to_string();
    // a truncated IGES: the lost entities are said by every command, not only `info`
    let text = std::fs::read_to_string(teapot()).unwrap();
    let cut: String = text.lines().take(300).map(|l| format!("{l}\n")).collect();
    std::fs::write(d.join("cut.igs"), cut).unwrap();
    for args in [
        vec!["nurbs", "render", &p("cut.igs")[..], "--size", "32x24", "--backend", "cpu", "-o", &p("c.png")[..]],
        vec!["nurbs", "export", &p("cut.igs")[..], "-o", &p("c.json")[..]],
    ] {
        let o = hitex(&args);
        assert!(o.status.success(), "{args:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("warning") && e.contains("truncated"), "{args:?}: {e}");
    }
    // values that made empty or meaningless pictures are refused, naming the flag
    let dem = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/jacksboro_fault_dem.npz");
    std::fs::write(d.join("nd.asc"), "ncols 3\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 30\nNODATA_value -9999\n-9999 -9999 -9999\n-9999 -9999 -9999\n-9999 -9999 -9999\n").unwrap();
    for (args, flag) in [
        (vec!["nurbs", "render", "teapot", "--density", "0", "-o", &p("x.png")[..]], "--density"),
        (vec!["nurbs", "render", "teapot", "--stripes", "0", "-o", &p("x.png")[..]], "--stripes"),
        (vec!["terrain", "render", "--dem", dem, "--exaggeration=-3", "-o", &p("x.png")[..]], "--exaggeration"),
        (vec!["terrain", "render", "--dem", &p("nd.asc")[..], "-o", &p("x.png")[..]], "no elevation sample"),
        (vec!["terrain", "spans", "--step", "0", "-o", &p("x.png")[..]], "--step"),
        (vec!["btf", "synth", "knit", "--supersample", "0", "-o", &p("k.hbtf")[..]], "--supersample"),
        (vec!["btf", "synth", "knit", "-o", &p("k.png")[..]], ".hbtf"),
    ] {
        let o = hitex(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let e = error_lines(&o).join("\n");
        assert!(e.contains(flag) && !e.contains("--bands"), "{args:?}: {e}");
    }
    // a store is not rebuilt from another source over the old one; an old DEM goes
    let st = p("store");
    let olinda = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/olinda");
    let image = format!("{olinda}/L7_ETMs.tif");
    let odem = format!("{olinda}/olinda_dem_utm25s.tif");
    if std::path::Path::new(&image).exists() {
        let o = hitex(&["terrain", "build", "--image", &image, "--dem", &odem, "-o", &st]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let o = hitex(&["terrain", "build", "--procedural", "512x512", "-o", &st]);
        assert_eq!(o.status.code(), Some(2));
        assert!(error_lines(&o).join("\n").contains("another source"));
        let o = hitex(&["terrain", "build", "--image", &image, "-o", &st]);
        assert!(o.status.success());
        assert!(String::from_utf8_lossy(&o.stdout).contains("removed"), "{}", String::from_utf8_lossy(&o.stdout));
        assert!(!d.join("store/dem.tif").exists());
    } else {
        panic!("the in-repo Olinda fixture is missing: {image}");
    }
    // `| head -1` does not stop a command whose product is files
    let fly_out = d.join("frames");
    let mut child = Command::new(env!("CARGO_BIN_EXE_hitex"))
        .args(["terrain", "fly", &st, "--frames", "3", "--size", "48x32", "--backend", "cpu", "-o"])
        .arg(&fly_out)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("hitex runs");
    drop(child.stdout.take());
    let status = child.wait().expect("hitex ends");
    assert!(status.success(), "{status:?}");
    for f in 0..3 {
        assert!(fly_out.join(format!("frame-{f:04}.png")).exists(), "frame {f} missing");
    }
}

#[test]
fn flags_are_named_and_material_names_work_everywhere() {
    let d = tmp("flags");
    let p = |n: &str| d.join(n).to_str().unwrap().to_string();
    for (args, flag) in [
        (vec!["terrain", "active-area", "--width", "0"], "--width"),
        (vec!["terrain", "active-area", "--fov", "0"], "--fov"),
        (vec!["terrain", "active-area", "--levels", "40"], "--levels"),
        (vec!["btf", "synth", "knit", "--size", "0", "-o", &p("k.hbtf")[..]], "--size"),
        (vec!["btf", "synth", "knit", "--phi", "0", "-o", &p("k.hbtf")[..]], "--phi"),
        (vec!["btf", "index", "knit", "--size", "0", "-o", &p("i.png")[..]], "--size"),
    ] {
        let o = hitex(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let e = error_lines(&o).join("\n");
        assert!(e.contains(flag), "{args:?}: {e}");
    }
    // a material name where a file is taken; a square side as WxH
    let o = hitex(&["btf", "info", "leather"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = hitex(&["btf", "index", "knit", "--size", "16x16", "-o", &p("i.png")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = hitex(&["btf", "index", "knit", "--size", "16x8", "-o", &p("i.png")]);
    assert_eq!(o.status.code(), Some(2));
    // a small DEM is framed by default; a terrain out of view is said
    std::fs::write(
        d.join("t4.asc"),
        "ncols 4\nnrows 4\nxllcorner 0\nyllcorner 0\ncellsize 30\n1 2 3 4\n2 3 4 5\n3 4 5 6\n4 5 6 7\n",
    )
    .unwrap();
    let out = d.join("t4.png");
    let o =
        hitex(&["terrain", "render", "--dem", &p("t4.asc"), "--size", "64x48", "--backend", "cpu", "-o", &p("t4.png")]);
    assert!(o.status.success());
    let (img, px) = model_pixels(&out);
    let sky = img.get_pixel(0, 0).0;
    let ground = img.pixels().filter(|q| q.0 != sky).count();
    assert!(ground * 4 > px.len().max(1) && ground > 64 * 48 / 4, "the DEM covers {ground} pixels");
    let o = hitex(&[
        "terrain",
        "render",
        "--dem",
        &p("t4.asc"),
        "--altitude",
        "1e9",
        "--size",
        "64x48",
        "--backend",
        "cpu",
        "-o",
        &p("far.png"),
    ]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("out of view"));
}

#[test]
fn a_long_build_reports_progress_where_no_bar_can_show() {
    // stderr captured (not a terminal): a line at every tenth once a second has passed
    let d = tmp("build-progress");
    let st = d.join("store");
    let o = hitex(&["terrain", "build", "--procedural", "8000x8000", "-o", st.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("1365/1365 maps (100%)"), "{e}");
    // a build under a second stays quiet
    let o = hitex(&["terrain", "build", "--procedural", "300x300", "-o", d.join("small").to_str().unwrap()]);
    assert!(o.status.success());
    assert!(!String::from_utf8_lossy(&o.stderr).contains("maps ("));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn one_flag_name_one_meaning() {
    // --bands picks image channels in the terrain commands; the isophote count
    // is --isophotes (the old name still works), the level view --show-levels
    let d = tmp("flag-names");
    let out = d.join("o.png");
    let o_ = out.to_str().unwrap();
    let dem = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/jacksboro_fault_dem.npz");
    for args in [
        vec!["nurbs", "render", "teapot", "--mode", "isophote", "--isophotes", "6"],
        vec!["nurbs", "render", "teapot", "--mode", "isophote", "--bands", "6"],
        vec!["terrain", "render", "--dem", dem, "--show-levels"],
        vec!["terrain", "render", "--dem", dem, "--levels"],
    ] {
        let o = hitex(&[&args[..], &["--size", "48x32", "--backend", "cpu", "-o", o_][..]].concat());
        assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    }
    let o = hitex(&["nurbs", "render", "teapot", "--isophotes", "0", "-o", o_]);
    assert_eq!(o.status.code(), Some(2));
    assert!(error_lines(&o).join("\n").contains("--isophotes 0 must be in 1..=1000"));
    let help = hitex(&["nurbs", "render", "--help"]);
    assert!(String::from_utf8_lossy(&help.stdout).contains("--isophotes"));
}

#[test]
fn a_flight_past_the_imagery_says_so() {
    let d = tmp("mirror");
    // a 64×64 image: imagery has edges, unlike the repeating patterns
    let img = d.join("img.png");
    let px: Vec<u8> = (0..64 * 64).flat_map(|i| [(i % 64 * 4) as u8, (i / 64 * 4) as u8, 90]).collect();
    image::save_buffer(&img, &px, 64, 64, image::ColorType::Rgb8).unwrap();
    let out = d.join("o.png");
    let (i, o_) = (img.to_str().unwrap(), out.to_str().unwrap());
    let base = ["terrain", "spans", "--image", i, "--size", "32x24", "--frames", "3", "-o", o_];
    // 20 texels a frame from the centre: out of the image at the third frame
    let o = hitex(&[&base[..], &["--step", "20"][..]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let e = error_lines(&o).join("\n");
    assert!(e.contains("warning: the flight leaves the 64x64 image at frame 3 of 3"), "{e}");
    assert!(e.contains("mirrored, not real ground"), "{e}");
    // a flight that stays inside is not warned about
    let o = hitex(&[&base[..], &["--step", "5"][..]].concat());
    assert!(o.status.success());
    assert!(!error_lines(&o).iter().any(|l| l.contains("warning")), "{:?}", error_lines(&o));
}

#[test]
fn long_work_reports_progress_where_no_bar_can_show() {
    // every command with a bar prints lines at each tenth where stderr is
    // not a terminal; HITEX_PROGRESS_AFTER=0 drops the one-second delay
    let run = |args: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_hitex"))
            .args(args)
            .env("HITEX_PROGRESS_AFTER", "0")
            .output()
            .unwrap();
        assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let d = tmp("progress-lines");
    let h = d.join("w.hbtf");
    let hs = h.to_str().unwrap();
    let e = run(&["btf", "synth", "woven", "-o", hs, "--size", "8", "--theta", "0,30,60", "--phi", "4"]);
    assert!(e.contains("hitex: synth: ") && e.contains("view directions (100%)"), "{e}");
    let e = run(&["btf", "export", hs, "-o", d.join("set").to_str().unwrap()]);
    // 12 view × 12 light directions, at every tenth
    assert!(e.contains("hitex: export: 144/144 images (100%)"), "{e}");
    assert!(e.lines().filter(|l| l.starts_with("hitex: export: ")).count() >= 5, "{e}");
    let out = d.join("spans.png");
    let e = run(&["terrain", "spans", "--size", "32x24", "--frames", "2", "-o", out.to_str().unwrap()]);
    assert!(e.contains("hitex: spans: 10/10 (100%)"), "{e}");
    // and nothing without the switch on work this short
    let o = hitex(&["btf", "export", hs, "-o", d.join("set2").to_str().unwrap()]);
    assert!(o.status.success());
    assert!(!String::from_utf8_lossy(&o.stderr).contains("hitex: export:"));
    let _ = std::fs::remove_dir_all(&d);
}
