//! The `hitex` binary as a user runs it: outputs, exit codes and error lines.

mod common;

use common::{error_lines, hitex, tmp};
use std::path::Path;

/// Runs `hitex render` on a scene text and expects exit code 2 with one error
/// line containing every needle.
fn bad_scene(name: &str, text: &str, needles: &[&str]) {
    let d = tmp(name);
    let scene = d.join(format!("{name}.toml"));
    std::fs::write(&scene, text).unwrap();
    let out = d.join("out.png");
    let o =
        hitex(&["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap(), "--backend", "cpu", "--size", "32x32"]);
    let lines = error_lines(&o);
    assert_eq!(o.status.code(), Some(2), "{name}: {lines:?}");
    assert_eq!(lines.len(), 1, "{name}: expected one error line, got {lines:?}");
    assert!(
        lines[0].contains(&format!("{name}.toml"))
            || needles.iter().any(|n| n.ends_with(".obj") || n.ends_with(".png")),
        "{name}: {lines:?}"
    );
    for n in needles {
        assert!(lines[0].contains(n), "{name}: '{n}' missing in {lines:?}");
    }
    assert!(!out.exists(), "{name}: an output was written");
}

const CAM: &str = "[camera]\nposition = [0, 1, 4]\ntarget = [0, 0, 0]\n";

#[test]
fn bad_input_gives_one_clear_line_and_exit_2() {
    bad_scene("unknown-key", &format!("{CAM}zoom = 2\n"), &["zoom", "line 4"]);
    bad_scene("wrong-type", "[camera]\nposition = \"up there\"\ntarget = [0, 0, 0]\n", &["line 2"]);
    bad_scene("nan", "[camera]\nposition = [0, nan, 4]\ntarget = [0, 0, 0]\n", &["camera.position[1]", "not finite"]);
    bad_scene(
        "infinite",
        &format!("{CAM}[[object]]\nmesh = \"cube\"\ntranslate = [inf, 0, 0]\n"),
        &["object[0].translate[0]"],
    );
    bad_scene("same-point", "[camera]\nposition = [1, 2, 3]\ntarget = [1, 2, 3]\n", &["degenerate camera", "target"]);
    bad_scene("fov-zero", &format!("{CAM}fov_y = 0\n"), &["fov_y"]);
    bad_scene("fov-180", &format!("{CAM}fov_y = 180\n"), &["fov_y"]);
    bad_scene("syntax", "[camera\nposition = [0, 1, 4]\n", &["line 1"]);
    bad_scene(
        "no-material",
        &format!("{CAM}[[object]]\nmesh = \"cube\"\nmaterial = \"gold\"\n"),
        &["object[0].material", "gold"],
    );

    // referenced files: missing, empty mesh, corrupt image
    let d = tmp("files");
    std::fs::write(d.join("empty.obj"), "# nothing here\nv 0 0 0\n").unwrap();
    std::fs::write(d.join("corrupt.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    for (name, body, needle) in [
        ("missing-mesh", "[[object]]\nfile = \"gone.obj\"\n", "gone.obj"),
        ("empty-mesh", "[[object]]\nfile = \"empty.obj\"\n", "empty.obj"),
        ("corrupt-image", "[[texture]]\nname = \"t\"\nfile = \"corrupt.png\"\n", "corrupt.png"),
    ] {
        let scene = d.join(format!("{name}.toml"));
        std::fs::write(&scene, format!("{CAM}{body}")).unwrap();
        let o =
            hitex(&["render", scene.to_str().unwrap(), "-o", d.join("x.png").to_str().unwrap(), "--backend", "cpu"]);
        let lines = error_lines(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {lines:?}");
        assert_eq!(lines.len(), 1, "{name}: {lines:?}");
        assert!(lines[0].contains(needle), "{name}: {lines:?}");
    }

    // a missing scene file
    let o = hitex(&["render", "/no/such/scene.toml", "-o", "x.png"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(error_lines(&o)[0].contains("/no/such/scene.toml"));
    // a malformed size
    let o = hitex(&["demo", "--size", "0x10"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn render_writes_a_png() {
    let d = tmp("render");
    let scene = d.join("s.toml");
    let o = hitex(&["demo", "--print-scene"]);
    assert!(o.status.success());
    std::fs::write(&scene, &o.stdout).unwrap();
    let out = d.join("s.png");
    let o = hitex(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--backend",
        "cpu",
        "--size",
        "80x45",
        "--mode",
        "level",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = hitex_png_size(&out);
    assert_eq!(img, (80, 45));
    assert!(String::from_utf8_lossy(&o.stdout).contains("wrote"));
}

fn hitex_png_size(p: &Path) -> (u32, u32) {
    let bytes = std::fs::read(p).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    let w = u32::from_be_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]);
    let h = u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]);
    (w, h)
}

#[test]
fn demo_renders_the_showcase() {
    let d = tmp("demo");
    let o = hitex(&["demo", "--out", d.to_str().unwrap(), "--backend", "cpu", "--size", "96x54"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["showcase.png", "showcase-levels.png", "filters.png", "level-rules.png", "uv-normal.png"] {
        assert!(d.join(f).exists(), "{f} missing");
    }
    assert_eq!(hitex_png_size(&d.join("showcase.png")), (96, 54));
    assert!(String::from_utf8_lossy(&o.stdout).contains(" ms"));
}

#[test]
fn bench_texture_json_has_the_shared_shape() {
    let require = std::env::var("HITEX_REQUIRE_GPU").is_ok_and(|v| v == "1");
    let o = hitex(&["bench", "texture", "--json", "--frames", "2", "--size", "64x48"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["bench"], "texture");
    let rows = v["rows"].as_array().unwrap();
    for r in rows {
        for k in ["case", "backend", "adapter", "width", "height", "frames", "ms_median", "fps_median"] {
            assert!(!r[k].is_null(), "row lacks {k}: {r}");
        }
        assert!(r["ms_median"].as_f64().unwrap() > 0.0);
    }
    let cpu = rows.iter().filter(|r| r["backend"] == "cpu").count();
    let gpu = rows.iter().filter(|r| r["backend"] == "gpu").count();
    assert_eq!(cpu, 3);
    if require {
        assert_eq!(gpu, 3, "HITEX_REQUIRE_GPU=1 but the GPU backend did not run");
        assert_eq!(v["ratios"].as_array().unwrap().len(), 3);
    } else if gpu == 0 {
        common::say_skipped("SKIPPED GPU part of bench_texture_json_has_the_shared_shape: no adapter");
    }
}

#[test]
fn bench_btf_mip_adds_the_minified_cases() {
    let o = hitex(&[
        "bench",
        "btf",
        "--layouts",
        "f",
        "--no-bc1",
        "--mip",
        "--backends",
        "cpu",
        "--frames",
        "1",
        "--sample",
        "8",
        "--size",
        "160x120",
        "--quad",
        "96",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let cases: Vec<&str> = v["rows"].as_array().unwrap().iter().map(|r| r["case"].as_str().unwrap()).collect();
    assert_eq!(cases, ["layout-f", "layout-f-r8", "layout-f-r8-mip"]);
    // the pyramid keeps the minified quad's codebook reads local: less traffic per pixel
    let bytes = |case: &str| {
        let rows = v["cache_model"].as_array().unwrap();
        rows.iter().find(|r| r["case"] == case).unwrap()["bytes_per_pixel"].as_f64().unwrap()
    };
    assert!(bytes("layout-f-r8-mip") < bytes("layout-f-r8"), "{}", v["cache_model"]);
}

#[test]
fn bench_runs_every_simd_level_and_checks_they_agree() {
    let o = hitex(&["bench", "nurbs", "--backends", "cpu", "--frames", "1", "--size", "48x48", "--simd", "all"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("cpu ms by SIMD level") && s.contains("scalar"), "{s}");
    assert!(!s.contains(" NO"), "a level rendered another image: {s}");
    // JSON: one CPU row per case and level, each naming its level and whether its image agrees
    let o =
        hitex(&["bench", "nurbs", "--backends", "cpu", "--frames", "1", "--size", "48x48", "--simd", "all", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = v["rows"].as_array().unwrap();
    let levels: std::collections::BTreeSet<&str> = rows.iter().map(|r| r["simd"].as_str().unwrap()).collect();
    assert!(levels.len() >= 2 && levels.contains("scalar"), "{levels:?}");
    assert!(rows.iter().all(|r| r["same_image"] == true), "{rows:?}");
    // one level, and a level that does not exist
    let o = hitex(&[
        "bench",
        "texture",
        "--backends",
        "cpu",
        "--frames",
        "1",
        "--size",
        "32x32",
        "--simd",
        "scalar",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["rows"].as_array().unwrap().iter().all(|r| r["simd"] == "scalar"), "{v}");
    // unless a level is asked for, the textured program runs at 8 lanes at
    // most on processors that split 512-bit operations, else at the detected level
    let o = hitex(&["bench", "texture", "--backends", "cpu", "--frames", "1", "--size", "32x32", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let want = hitex_render::cpu::simd::level_for_gathers();
    if hitex_render::cpu::simd::splits_512() {
        assert_ne!(want.name(), "avx512");
    }
    assert!(v["rows"].as_array().unwrap().iter().all(|r| r["simd"] == want.name()), "{v} (want {want})");
    let o = hitex(&["bench", "texture", "--simd", "avx9"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("names no level"));
}

#[test]
fn info_lists_adapters() {
    let o = hitex(&["info"]);
    assert!(o.status.success());
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(s.contains("cpu backend"));
    assert!(s.lines().any(|l| l.starts_with("processor: ") && l.len() > "processor: ".len()), "{s}");
    assert!(s.contains("adapter") || s.contains("no GPU adapter"));
}

#[test]
fn nurbs_commands_work_and_refuse_bad_input() {
    let d = tmp("nurbs");
    // render a model on the CPU
    let out = d.join("teapot.png");
    let o = hitex(&[
        "nurbs",
        "render",
        "teapot",
        "--mode",
        "isophote",
        "-o",
        out.to_str().unwrap(),
        "--backend",
        "cpu",
        "--size",
        "64x64",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(hitex_png_size(&out), (64, 64));
    // info names the repairs of the sloppy teapot file
    let o = hitex(&["nurbs", "info", "teapot"]);
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && s.contains("32 patches") && s.contains("repaired:"), "{s}");
    // eval as JSON
    let o = hitex(&["nurbs", "eval", "surface", "--patch", "0", "--uv", "0.5,0.5", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["normal"].as_array().unwrap().len() == 3 && v["gaussian"].is_number());

    // a trimmed surface (IGES 144/142/126)
    let holed = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/holed-square.igs");
    let o = hitex(&["nurbs", "info", holed]);
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && s.contains("trimmed by 2 loops"), "{s}");
    let o = hitex(&[
        "nurbs",
        "render",
        holed,
        "--mode",
        "shaded",
        "-o",
        d.join("holed.png").to_str().unwrap(),
        "--backend",
        "cpu",
        "--size",
        "64x64",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // export and read back, both formats
    for ext in ["json", "igs"] {
        let f = d.join(format!("spray.{ext}"));
        let o = hitex(&["nurbs", "export", "spray", "-o", f.to_str().unwrap()]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let o = hitex(&["nurbs", "info", f.to_str().unwrap()]);
        let s = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success() && s.contains("266 patches") && !s.contains("repaired"), "{s}");
    }

    // bad input: one line, exit 2, naming the file and record
    let bad = d.join("bad.igs");
    let mut text = String::new();
    text += &format!("{:<72}S{:>7}\n", "x", 1);
    text += &format!("{:<72}G{:>7}\n", "1H,,1H;;", 1);
    text += &format!("{:<72}D{:>7}\n", format!("{:>8}{:>8}", 128, 1), 1);
    text += &format!("{:<72}D{:>7}\n", format!("{:>8}", 128), 2);
    text += &format!("{:<64}{:>8}P{:>7}\n", "128,99999,99999,3,3,0,0,1,0,0,0.;", 1, 1);
    std::fs::write(&bad, text).unwrap();
    for args in [
        vec!["nurbs", "info", bad.to_str().unwrap()],
        vec!["nurbs", "render", bad.to_str().unwrap(), "-o", d.join("x.png").to_str().unwrap(), "--backend", "cpu"],
    ] {
        let o = hitex(&args);
        let lines = error_lines(&o);
        assert_eq!(o.status.code(), Some(2), "{lines:?}");
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(
            lines[0].contains("bad.igs") && lines[0].contains("directory entry 1") && lines[0].contains("entity 128"),
            "{lines:?}"
        );
    }
    let garbage = d.join("garbage.igs");
    std::fs::write(&garbage, b"\x00\x01 not an iges file at all").unwrap();
    let o = hitex(&["nurbs", "info", garbage.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(error_lines(&o)[0].contains("garbage.igs"));
    for args in [
        vec!["nurbs", "info", "no-such-model"],
        vec!["nurbs", "eval", "teapot", "--patch", "99", "--uv", "0.5,0.5"],
        vec!["nurbs", "eval", "teapot", "--patch", "0", "--uv", "7,0.5"],
        vec!["nurbs", "eval", "teapot", "--patch", "0", "--uv", "nan,0.5"],
    ] {
        let o = hitex(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {:?}", error_lines(&o));
    }
}

#[test]
fn bench_nurbs_json_names_models() {
    let o = hitex(&["bench", "nurbs", "--json", "--frames", "1", "--size", "48x48", "--backends", "cpu"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["bench"], "nurbs");
    let rows = v["rows"].as_array().unwrap();
    assert!(rows.iter().any(|r| r["case"].as_str().unwrap().starts_with("teapot")));
    assert!(rows.iter().any(|r| r["case"].as_str().unwrap().starts_with("surface")));
}

#[test]
fn scene_with_nurbs_renders_and_bad_nurbs_entries_are_refused() {
    let d = tmp("scene-nurbs");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/teapot-on-checker.toml");
    let out = d.join("t.png");
    let o = hitex(&["render", scene, "-o", out.to_str().unwrap(), "--backend", "cpu", "--size", "96x54"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(hitex_png_size(&out), (96, 54));
    bad_scene("nurbs-model", &format!("{CAM}[[nurbs]]\nmodel = \"kettle\"\n"), &["kettle"]);
    bad_scene("nurbs-mode", &format!("[render]\nnurbs_mode = \"glow\"\n{CAM}"), &["render.nurbs_mode", "glow"]);
    bad_scene("nurbs-scale", &format!("{CAM}[[nurbs]]\nmodel = \"teapot\"\nscale = [0, 1, 1]\n"), &["nurbs[0].scale"]);
    bad_scene("nurbs-both", &format!("{CAM}[[nurbs]]\nmodel = \"teapot\"\nfile = \"x.igs\"\n"), &["nurbs[0]"]);
}

#[test]
fn terrain_active_area_and_render() {
    let o = hitex(&["terrain", "active-area"]);
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && s.contains("total: 324 maps"), "{s}");
    let o = hitex(&["terrain", "active-area", "--fov", "0"]);
    assert_eq!(o.status.code(), Some(2));
    // a wide field of view needs billions of maps: counted in 64 bits, not wrapped
    let o = hitex(&["terrain", "active-area", "--fov", "179.99"]);
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && s.contains("total: 4727937600 maps"), "{s}");
    assert!(s.contains("525326400") && s.contains("TiB"), "{s}");
    let o = hitex(&["terrain", "active-area", "--width", "1000000000"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));

    // the Olinda pair kept in the repository (the same files as ../shared/data/terrain)
    let dem = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/olinda/olinda_dem_utm25s.tif");
    let img = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/olinda/L7_ETMs.tif");
    let d = tmp("terrain");
    let out = d.join("t.png");
    let o = hitex(&[
        "terrain",
        "render",
        "--dem",
        dem,
        "--image",
        img,
        "-o",
        out.to_str().unwrap(),
        "--backend",
        "cpu",
        "--size",
        "96x64",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("UTM zone 25S"));
    // an npz DEM without imagery is coloured by elevation
    let npz = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/jacksboro_fault_dem.npz");
    let o =
        hitex(&["terrain", "render", "--dem", npz, "-o", out.to_str().unwrap(), "--backend", "cpu", "--size", "96x64"]);
    assert!(
        o.status.success() && String::from_utf8_lossy(&o.stdout).contains("coloured by elevation"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(hitex_png_size(&out), (96, 64));
    // bad input: band out of range, swapped files (an 8-band request), not a GeoTIFF
    let o = hitex(&[
        "terrain",
        "render",
        "--dem",
        dem,
        "--image",
        img,
        "--bands",
        "7,2,1",
        "-o",
        out.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(error_lines(&o)[0].contains("band 7"), "{:?}", error_lines(&o));
    let fake = d.join("fake.tif");
    std::fs::write(&fake, b"not a tiff").unwrap();
    let o = hitex(&[
        "terrain",
        "render",
        "--dem",
        fake.to_str().unwrap(),
        "--image",
        img,
        "-o",
        out.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(error_lines(&o)[0].contains("fake.tif"));
}

#[test]
fn btf_synth_info_index_render_export_import() {
    let d = tmp("btf");
    let h = d.join("w.hbtf");
    let hs = h.to_str().unwrap();
    let o = hitex(&[
        "btf",
        "synth",
        "woven",
        "-o",
        hs,
        "--size",
        "8",
        "--theta",
        "0,30,60",
        "--phi",
        "6",
        "--supersample",
        "1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = hitex(&["btf", "info", hs]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("8x8 texels") && text.contains("(f)") && text.contains("324 images"), "{text}");
    let idx = d.join("i.png");
    let o = hitex(&["btf", "index", hs, "--size", "24", "-o", idx.to_str().unwrap(), "--passes", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(d.join("i-preview.png").exists());
    for (layout, bc1) in [("a", false), ("f", true), ("c2", false)] {
        let out = d.join(format!("r-{layout}.png"));
        let mut args = vec!["btf", "render", hs, "--layout", layout, "--index", idx.to_str().unwrap()];
        args.extend(["-o", out.to_str().unwrap(), "--size", "64x48", "--backend", "cpu"]);
        if bc1 {
            args.push("--bc1");
        }
        let o = hitex(&args);
        assert!(o.status.success(), "{layout}: {}", String::from_utf8_lossy(&o.stderr));
        assert!(out.exists());
    }
    // image set round trip
    let set = d.join("set");
    let o = hitex(&["btf", "export", hs, "-o", set.to_str().unwrap(), "--convention", "ubo"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let back = d.join("back.hbtf");
    let o = hitex(&["btf", "import", set.to_str().unwrap(), "-o", back.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&h).unwrap(), std::fs::read(&back).unwrap(), "export + import changed the BTF");
}

#[test]
fn a_compressed_btf_is_written_once_and_rendered_from_its_file() {
    let d = tmp("btf-pca");
    let (h, c) = (d.join("w.hbtf"), d.join("w-pca.hbtf"));
    let (hs, cs) = (h.to_str().unwrap(), c.to_str().unwrap());
    let o = hitex(&["btf", "synth", "woven", "-o", hs, "--size", "8", "--theta", "0,30,60", "--phi", "6"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = hitex(&["btf", "compress", hs, "--pca", "1,2", "-o", cs]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // smaller than the source on disk, and said to be compressed
    assert!(std::fs::metadata(&c).unwrap().len() * 4 < std::fs::metadata(&h).unwrap().len());
    let o = hitex(&["btf", "info", cs]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("compressed: local PCA, 1 cluster × 2 components") && text.contains("324 images"), "{text}");
    // rendered from the file: the image of fitting the same PCA at render time
    let idx = d.join("i.png");
    let o = hitex(&["btf", "index", hs, "--size", "16", "-o", idx.to_str().unwrap(), "--passes", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let render = |input: &str, extra: &[&str], out: &str| {
        let out = d.join(out);
        let mut args = vec!["btf", "render", input, "--index", idx.to_str().unwrap(), "--size", "64x48"];
        args.extend(["--backend", "cpu", "-o", out.to_str().unwrap()]);
        args.extend(extra);
        let o = hitex(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (std::fs::read(out).unwrap(), String::from_utf8_lossy(&o.stdout).to_string())
    };
    let (from_file, said) = render(cs, &[], "file.png");
    assert!(said.contains("local PCA 1x2 read from the file"), "{said}");
    let (fitted, _) = render(hs, &["--pca", "1,2"], "fitted.png");
    assert_eq!(from_file, fitted, "the stored PCA renders unlike the same fit made at render time");
    // what does not apply to a compressed file is refused by name
    for (extra, want) in [(&["--pca", "4,3"][..], "already compressed"), (&["--bc1"][..], "drop --bc1")] {
        let out = d.join("x.png");
        let mut args = vec!["btf", "render", cs, "-o", out.to_str().unwrap()];
        args.extend(extra);
        let o = hitex(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.code() == Some(2) && err.contains("w-pca.hbtf") && err.contains(want), "{err}");
    }
    let o = hitex(&["btf", "compress", cs, "--pca", "2,1", "-o", d.join("again.hbtf").to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("already compressed"));
    // other commands read its reconstruction
    let set = d.join("set");
    let o = hitex(&["btf", "export", cs, "-o", set.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn btf_render_falls_back_without_mip_where_the_pyramid_cannot_fit() {
    // a 4×600 sample: its pyramid would stack more than 1024 rows
    let d = tmp("btf-tall");
    let h = d.join("tall.hbtf");
    let grid = hitex_core::btf::AngularGrid::new(vec![0.0, 40.0], 2).unwrap();
    let n = hitex_core::btf::dataset::checked_size(&grid, 4, 600).unwrap();
    let texels = (0..n).map(|i| (i * 37 % 251) as u8).collect();
    let btf = hitex_core::btf::Btf::new(grid, 4, 600, texels).unwrap();
    hitex_io::btf_file::write_hbtf(&h, &btf).unwrap();
    let idx = d.join("i.png");
    let out = d.join("r.png");
    let base = [h.to_str().unwrap(), "-o", out.to_str().unwrap(), "--size", "48x32", "--backend", "cpu"];
    // index map: the plain tiling, written by the index command at 8 texels a side
    let o = hitex(&["btf", "index", base[0], "--size", "8", "-o", idx.to_str().unwrap(), "--passes", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut args = vec!["btf", "render"];
    args.extend(base);
    args.extend(["--index", idx.to_str().unwrap()]);
    // auto: rendered without MIP, and told so
    let o = hitex(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("without MIP mapping") && err.contains("1024"), "{err}");
    assert!(String::from_utf8_lossy(&o.stdout).contains("without MIP"));
    // on: a clear refusal, nothing written
    std::fs::remove_file(&out).unwrap();
    args.extend(["--mip", "on"]);
    let o = hitex(&args);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("exceeds the sample side limit"));
    assert!(!out.exists());
}

/// One EXR image of constant RGB (half floats) in memory.
fn exr_rgb(w: usize, h: usize, rgb: [f32; 3]) -> Vec<u8> {
    use exr::prelude::*;
    let ch = |n: &str, v: f32| AnyChannel::new(n, FlatSamples::F16(vec![f16::from_f32(v); w * h]));
    let chans = AnyChannels::sort(vec![ch("R", rgb[0]), ch("G", rgb[1]), ch("B", rgb[2])].into());
    let layer = Layer::new((w, h), LayerAttributes::default(), Encoding::FAST_LOSSLESS, chans);
    let mut out = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut out).unwrap();
    out.into_inner()
}

#[test]
fn btf_hdr_exr_import_render_export() {
    let d = tmp("btf-hdr");
    // a UTIA-style HDR set: one folder per view, radiance up to 12
    let set = d.join("set");
    for (tv, pv) in [(0, 0), (45, 0), (45, 90), (45, 180), (45, 270)] {
        let f = set.join(format!("tv{tv:03}_pv{pv:03}"));
        std::fs::create_dir_all(&f).unwrap();
        for (tl, pl) in [(0, 0), (45, 0), (45, 90), (45, 180), (45, 270)] {
            let v = 0.2 + (tl + pl + tv) as f32 / 30.0;
            std::fs::write(f.join(format!("tl{tl:03}_pl{pl:03}.exr")), exr_rgb(4, 4, [v, 0.5 * v, 0.25])).unwrap();
        }
    }
    let h = d.join("hdr.hbtf");
    let hs = h.to_str().unwrap();
    let o = hitex(&["btf", "import", set.to_str().unwrap(), "-o", hs, "--theta", "0,45", "--phi", "4"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("HDR") && text.contains("version 2"), "{text}");
    let o = hitex(&["btf", "info", hs]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("HDR, linear RGB half floats up to 12.2"), "{text}");
    // rendered with an exposure and each tone map on the CPU
    let mut images = Vec::new();
    for tone in ["none", "reinhard", "aces"] {
        let out = d.join(format!("r-{tone}.png"));
        let o = hitex(&[
            "btf",
            "render",
            hs,
            "-o",
            out.to_str().unwrap(),
            "--size",
            "64x48",
            "--backend",
            "cpu",
            "--exposure",
            "-1.5",
            "--tone-map",
            tone,
        ]);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(text.contains(&format!("exposure -1.5 stops, tone map {tone}")), "{text}");
        images.push(std::fs::read(&out).unwrap());
    }
    assert!(images[0] != images[1] && images[1] != images[2]);
    // BC1 is refused for HDR texels
    let o = hitex(&["btf", "render", hs, "-o", d.join("bc.png").to_str().unwrap(), "--bc1", "--backend", "cpu"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("HDR"));
    // EXR export keeps the values: export, import, export again gives the same files
    let (e1, e2) = (d.join("e1"), d.join("e2"));
    let o = hitex(&["btf", "export", hs, "-o", e1.to_str().unwrap(), "--format", "exr"]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).contains("values exactly"));
    let back = d.join("back.hbtf");
    assert!(hitex(&["btf", "import", e1.to_str().unwrap(), "-o", back.to_str().unwrap()]).status.success());
    assert_eq!(std::fs::read(&h).unwrap(), std::fs::read(&back).unwrap(), "EXR export + import changed the HDR BTF");
    assert!(
        hitex(&["btf", "export", back.to_str().unwrap(), "-o", e2.to_str().unwrap(), "--format", "exr"])
            .status
            .success()
    );
    let name = "tl045_pl090_tv045_pv180.exr";
    assert_eq!(std::fs::read(e1.join(name)).unwrap(), std::fs::read(e2.join(name)).unwrap());
}

#[test]
fn btf_bad_input_gives_one_clear_line() {
    let d = tmp("btf-bad");
    let h = d.join("t.hbtf");
    let o = hitex(&["btf", "synth", "knit", "-o", h.to_str().unwrap(), "--size", "4", "--theta", "0,45", "--phi", "4"]);
    assert!(o.status.success());
    // truncated file
    let bytes = std::fs::read(&h).unwrap();
    let cut = d.join("cut.hbtf");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = d.join("o.png");
    let o = hitex(&["btf", "render", cut.to_str().unwrap(), "-o", out.to_str().unwrap(), "--backend", "cpu"]);
    let lines = error_lines(&o);
    assert_eq!(o.status.code(), Some(2), "{lines:?}");
    assert!(lines.len() == 1 && lines[0].contains("cut.hbtf"), "{lines:?}");
    assert!(!out.exists());
    // unknown layout, material, surface; decreasing angles
    for (args, needle) in [
        (vec!["btf", "render", h.to_str().unwrap(), "--layout", "g", "-o", "x.png"], "layout 'g'"),
        (vec!["btf", "synth", "velvet", "-o", "x.hbtf"], "velvet"),
        (vec!["btf", "render", h.to_str().unwrap(), "--on", "cone", "-o", "x.png"], "cone"),
        (vec!["btf", "synth", "knit", "-o", "x.hbtf", "--theta", "30,10"], "theta[1]"),
    ] {
        let o = hitex(&args);
        let lines = error_lines(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {lines:?}");
        assert!(lines.len() == 1 && lines[0].contains(needle), "{args:?}: {lines:?}");
    }
    // an index map naming texels outside the sample
    let idx = d.join("big.png");
    image::RgbImage::from_pixel(4, 4, image::Rgb([200, 0, 0])).save(&idx).unwrap();
    let o =
        hitex(&["btf", "render", h.to_str().unwrap(), "--index", idx.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let lines = error_lines(&o);
    assert_eq!(o.status.code(), Some(2), "{lines:?}");
    assert!(lines[0].contains("big.png") && lines[0].contains("outside"), "{lines:?}");
}

#[test]
fn draft_mode_reports_its_pull_and_refuses_bad_flags() {
    let d = tmp("draft");
    let out = d.join("d.png");
    let o = hitex(&[
        "nurbs",
        "render",
        "teapot",
        "--mode",
        "draft",
        "--pull",
        "-z",
        "--draft-tolerance",
        "2.5",
        "--size",
        "64x48",
        "--backend",
        "cpu",
        "-o",
        out.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("draft against pull (0.00, 0.00, -1.00)") && text.contains("±2.5°"), "{text}");
    assert!(out.exists());
    for (flag, value, says) in [
        ("--draft-tolerance", "95", "--draft-tolerance 95 must be in 0…89 degrees"),
        ("--pull", "0,0,0", "no direction"),
        ("--pull", "up", "is not an axis"),
        ("--min-radius", "0", "--min-radius 0 must be finite and positive"),
    ] {
        let o = hitex(&["nurbs", "render", "teapot", "--mode", "draft", flag, value, "-o", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(err.contains(says), "{flag} {value}: {err}");
    }
}

#[test]
fn principal_curvature_modes_and_line_overlays_report_and_refuse_bad_flags() {
    let d = tmp("k1-lines");
    let out = d.join("k.png");
    let o = hitex(&[
        "nurbs",
        "render",
        "teapot",
        "--mode",
        "k2",
        "--isolines",
        "3",
        "--sections",
        "-z,0.25",
        "--size",
        "96x64",
        "--backend",
        "cpu",
        "-o",
        out.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("max(|κ1|, |κ2|)") && text.contains("towards the viewer"), "{text}");
    assert!(text.contains("isoparametric lines: 3 per patch"), "{text}");
    assert!(text.contains("sections (magenta): the planes (0.00, 0.00, -1.00) · P = k × 0.250"), "{text}");
    let img = image::open(&out).unwrap().to_rgba8();
    let count = |rgb: [u8; 3]| img.pixels().filter(|p| p.0[..3] == rgb).count();
    assert!(count(hitex_render::nurbs::ISOLINE_RGB) > 50, "isoline pixels");
    assert!(count(hitex_render::nurbs::SECTION_RGB) > 50, "section pixels");
    for (flag, value, says) in [
        ("--sections", "z,0", "spacing 0 must be finite and positive"),
        ("--sections", "z", "is not AXIS,SPACING"),
        ("--sections", "up,1", "is not an axis"),
        ("--sections", "1,0,0,nan", "spacing NaN must be finite and positive"),
        ("--isolines", "0", "--isolines 0 must be in 1…1000"),
    ] {
        let o = hitex(&["nurbs", "render", "teapot", flag, value, "-o", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(err.contains(says), "{flag} {value}: {err}");
    }
}

#[test]
fn nurbs_check_measures_edges_and_gates_on_tolerances() {
    // the teapot's patches meet exactly (G0), some only with tangent planes (G1)
    let o = hitex(&["nurbs", "check", "teapot", "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["faces"], 32);
    assert!(v["shared_edges"].as_u64().unwrap() >= 40, "{}", v["shared_edges"]);
    assert!(v["naked_edges"].as_u64().unwrap() >= 4, "{}", v["naked_edges"]);
    let edges = v["edges"].as_array().unwrap();
    let gap = edges.iter().map(|e| e["g0"]["value"].as_f64().unwrap()).fold(0.0, f64::max);
    assert!(gap < 1e-12, "largest gap {gap}");
    assert!(edges.iter().any(|e| e["class"] == "G1") && edges.iter().any(|e| e["class"] == "G2"));
    // a G2 requirement fails on the G1 seams: exit 1, named
    let o = hitex(&["nurbs", "check", "teapot", "--g2", "0.1"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("check failed: teapot:") && err.contains("exceed the tolerances"), "{err}");
    for (flag, value) in [("--g0", "0"), ("--g1", "-1"), ("--spacing", "nan")] {
        let o = hitex(&["nurbs", "check", "teapot", flag, value]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(err.contains(&format!("{flag} ")) && err.contains("finite and positive"), "{err}");
    }
}

#[test]
fn step_assemblies_read_render_and_check() {
    let cad = Path::new(env!("CARGO_MANIFEST_DIR")).join("../hitex-io/data/cad");
    let asm = cad.join("as1-oc-214.stp");
    let asm = asm.to_str().unwrap();
    let o = hitex(&["nurbs", "info", asm]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("160 patches, 160 trimmed"), "{out}");
    assert!(out.contains("STEP AUTOMOTIVE_DESIGN") && out.contains("lengths in mm"), "{out}");
    assert!(out.contains("25 PLANE, 28 RATIONAL_B_SPLINE_SURFACE; 160 placed in 18 part instances"), "{out}");
    assert!(out.contains("trims sampled to a chord of"), "{out}");
    // rendered: the model covers a fair part of the frame, on the background elsewhere
    let d = tmp("step");
    let png = d.join("as1.png");
    let o = hitex(&["nurbs", "render", asm, "-o", png.to_str().unwrap(), "--backend", "cpu", "--size", "320x200"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&png).unwrap().to_rgba8();
    let bg = *img.get_pixel(0, 0);
    let model = img.pixels().filter(|p| **p != bg).count();
    assert!(model > 320 * 200 / 4, "{model} model pixels");
    // every part is closed: the check finds no naked edge and passes its default gap
    let part = cad.join("face_recognition_sample_part.stp");
    let o = hitex(&["nurbs", "check", part.to_str().unwrap(), "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!((v["faces"].as_u64(), v["naked_edges"].as_u64()), (Some(23), Some(0)), "{v}");
    // --chord: a finer chord samples the trims more densely; a bad one is refused by name
    let points = |chord: &str| -> usize {
        let o = hitex(&["nurbs", "info", part.to_str().unwrap(), "--chord", chord]);
        let out = String::from_utf8_lossy(&o.stdout).to_string();
        assert!(out.contains(&format!("trims sampled to a chord of {chord}")) || out.contains("(--chord)"), "{out}");
        out.lines()
            .filter_map(|l| l.split("loops of ").nth(1).or_else(|| l.split("loop of ").nth(1)))
            .flat_map(|t| {
                t.split(" points")
                    .next()
                    .unwrap_or("")
                    .split(" / ")
                    .map(|n| n.trim().parse::<usize>().unwrap_or(0))
                    .collect::<Vec<_>>()
            })
            .sum()
    };
    let (fine, coarse) = (points("0.001"), points("1"));
    assert!(fine > 2 * coarse, "{fine} vs {coarse} trim points");
    let o = hitex(&["nurbs", "render", part.to_str().unwrap(), "--chord", "-1", "-o", png.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--chord -1 must be finite and positive"));
}

#[test]
fn nurbs_info_json_and_deviation_measure_trimmed_faces() {
    let plate = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds/step/plate-with-hole.stp");
    let plate = plate.to_str().unwrap();
    // a 40 × 30 plate at z = 0 with a hole of radius 5 at (10, 5)
    let o = hitex(&["nurbs", "info", plate, "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["faces"], 1);
    assert_eq!(v["census"]["plane"], 1);
    assert_eq!(v["census"]["bspline"], 0);
    assert_eq!(v["units"], "unitless");
    let area = v["area"].as_f64().unwrap();
    let want = 1200.0 - std::f64::consts::PI * 25.0;
    assert!((area - want).abs() < 0.1, "{area} vs {want}");
    let bbox: Vec<f64> = v["bbox"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let expect = [-20.0, -15.0, 0.0, 20.0, 15.0, 0.0];
    assert!(bbox.iter().zip(expect).all(|(a, b)| (a - b).abs() < 0.2), "{bbox:?}");
    // IGES and named models count as B-spline patches
    let o = hitex(&["nurbs", "info", "teapot", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!((v["faces"].as_u64(), v["census"]["bspline"].as_u64()), (Some(32), Some(32)));

    // above the plate, over the hole's centre (to its rim) and beside the plate
    let d = tmp("deviation");
    let pts = d.join("probe.json");
    std::fs::write(&pts, r#"{"points": [[0, 0, 2], [10, 5, 0], [30, 0, 0]]}"#).unwrap();
    let o = hitex(&["nurbs", "deviation", plate, "--points", pts.to_str().unwrap(), "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    let dist: Vec<f64> = v["distances"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    // to within the trims' chord tolerance (1/10 000 of the 50-unit diagonal)
    for (got, want) in dist.iter().zip([2.0, 5.0, 10.0]) {
        assert!((got - want).abs() <= 5e-3, "{dist:?}");
    }
    assert!((v["max"].as_f64().unwrap() - 10.0).abs() < 1e-9 && v["worst"]["index"] == 2);
    assert!((v["rms"].as_f64().unwrap() - (43.0f64).sqrt()).abs() < 5e-3);
    // the same as XYZ text, in words
    let xyz = d.join("probe.xyz");
    std::fs::write(&xyz, "0 0 2\n10 5 0\n30 0 0\n").unwrap();
    let o = hitex(&["nurbs", "deviation", plate, "--points", xyz.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("3 points to 1 faces") || out.contains("3 points to 1 face"), "{out}");
    assert!(out.contains("max 10") && out.contains("point 2"), "{out}");
}

/// The teapot's own tessellation (24×24 per patch) as a binary STL, each
/// vertex moved by `lift` along its exact normal.
fn teapot_mesh(path: &std::path::Path, lift: f32) -> usize {
    let m = hitex_io::models::load_model("teapot").unwrap();
    let p = hitex_render::nurbs::PreparedNurbs::new(m.nurbs(), &m.ranges(), 24);
    let at = |i: u32| {
        let v = &p.vertices[i as usize];
        [0, 1, 2].map(|k| (v.position[k] + lift * v.normal[k]) as f64)
    };
    let tris: Vec<[[f64; 3]; 3]> = p.indices.chunks_exact(3).map(|t| [at(t[0]), at(t[1]), at(t[2])]).collect();
    std::fs::write(path, hitex_io::stl::to_binary_stl(&tris)).unwrap();
    tris.len()
}

#[test]
fn deviation_mode_measures_a_mesh_and_a_cloud_and_refuses_bad_flags() {
    let d = tmp("deviation-mode");
    let out = d.join("dev.png");
    let render = |reference: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "nurbs",
            "render",
            "teapot",
            "--mode",
            "deviation",
            "--reference",
            reference.to_str().unwrap(),
            "--size",
            "96x64",
            "--backend",
            "cpu",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        hitex(&args)
    };
    // the surface against its own tessellation: within the tessellation's
    // chord error everywhere (the teapot's 24×24 cells deviate < 0.003)
    let mesh = d.join("scan.stl");
    let n = teapot_mesh(&mesh, 0.0);
    let o = render(&mesh, &["--tolerance", "0.003"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains(&format!("({n} triangles")), "{text}");
    assert!(text.contains("within ±0.003000: 100.0 %") && text.contains("no reference within"), "{text}");
    // lifted by 0.01 along the normals: +0.01 within the chord error
    teapot_mesh(&mesh, 0.01);
    let o = render(&mesh, &["--range", "0.02"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let grid = text.lines().find(|l| l.starts_with("grid: ")).expect("grid line");
    let mean: f64 = grid.split("mean ").nth(1).unwrap().split(',').next().unwrap().parse().unwrap();
    assert!((mean - 0.01).abs() < 0.002, "{grid}");
    // the same triangles as binary PLY: the same figures
    let ply = d.join("scan.ply");
    let tris = hitex_io::stl::load_stl(&mesh).unwrap();
    std::fs::write(&ply, hitex_io::ply::to_binary_ply(&tris)).unwrap();
    let o = render(&ply, &["--range", "0.02"]);
    let same = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(same.lines().find(|l| l.starts_with("grid: ")), Some(grid), "{same}");
    // the independent reference samples, as points: on the surface to 1e-9
    let samples = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/teapot_reference_samples.xyz");
    let o = render(std::path::Path::new(samples), &[]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cloud = text.lines().find(|l| l.starts_with("cloud: ")).expect("cloud line");
    assert!(cloud.starts_with("cloud: 200 of 200 points"), "{cloud}");
    let max: f64 = cloud.split("max ").nth(1).unwrap().split(',').next().unwrap().parse().unwrap();
    assert!(max.abs() < 1e-9, "{cloud}");
    // refusals
    let far = d.join("far.xyz");
    std::fs::write(&far, "100 100 100\n101 100 100\n").unwrap();
    for (reference, extra, says) in [
        (far.as_path(), vec![], "no point of the reference"),
        (mesh.as_path(), vec!["--tolerance", "-1"], "--tolerance -1 must be finite and positive"),
        (mesh.as_path(), vec!["--deviation-grid", "91"], "--deviation-grid 91 must be in 2…90"),
        (d.join("open.ply").as_path(), vec![], "without an `end_header` line"),
    ] {
        if reference.extension().is_some_and(|e| e == "ply") {
            std::fs::write(reference, "ply\n").unwrap();
        }
        let o = render(reference, &extra);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{says}: {err}");
        assert!(err.contains(says), "{says}: {err}");
    }
    let o = hitex(&["nurbs", "render", "teapot", "--mode", "deviation", "-o", out.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--mode deviation needs --reference FILE"));
    let o = hitex(&["nurbs", "render", "teapot", "--reference", mesh.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--reference is read by --mode deviation only"));
}

#[test]
fn continuity_overlay_reports_the_classes_of_check_and_refuses_bad_flags() {
    let d = tmp("continuity-overlay");
    let out = d.join("c.png");
    let part = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/cad/face_recognition_sample_part.stp");
    let o = hitex(&[
        "nurbs",
        "render",
        part,
        "--continuity",
        "--size",
        "160x120",
        "--backend",
        "cpu",
        "-o",
        out.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = text.lines().find(|l| l.starts_with("continuity: ")).expect("a continuity line");
    // the machined part is a closed solid: no naked edge, creases where its faces meet
    assert!(line.contains("G0 (orange)") && !line.contains("naked"), "{line}");
    // the check command finds the same number of edges
    let o = hitex(&["nurbs", "check", part]);
    let check = String::from_utf8_lossy(&o.stdout);
    let n: String = line.trim_start_matches("continuity: ").chars().take_while(char::is_ascii_digit).collect();
    assert!(check.contains(&format!("{n} edges")) || check.contains(&format!("{n} shared")), "{n}: {check}");
    // the orange of a crease is in the picture
    let img = image::open(&out).unwrap().to_rgba8();
    assert!(img.pixels().filter(|p| p.0[..3] == [255, 140, 20]).count() > 50);
    for (args, says) in [
        (vec!["--continuity", "--g1", "200"], "--g1 200 must be below 180 degrees"),
        (vec!["--continuity", "--g0", "0"], "--g0 0 must be finite and positive"),
        (vec!["--g2", "0.5"], "--g2 is read with --continuity only"),
    ] {
        let mut all = vec!["nurbs", "render", "teapot", "-o", out.to_str().unwrap()];
        all.extend(args);
        let o = hitex(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{says}: {err}");
        assert!(err.contains(says), "{says}: {err}");
    }
}

#[test]
fn check_reports_faces_lying_on_each_other_and_edges_of_three_faces() {
    let d = tmp("check-overlaps");
    // the teapot with its first patch given twice
    let json = d.join("teapot.json");
    let o = hitex(&["nurbs", "export", "teapot", "-o", json.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let patches = v["patches"].as_array_mut().unwrap();
    let first = patches[0].clone();
    patches.push(first);
    let twice = d.join("twice.json");
    std::fs::write(&twice, serde_json::to_vec(&v).unwrap()).unwrap();
    let o = hitex(&["nurbs", "check", twice.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("1 pair of faces lying on each other") && text.contains("  0–32: 100 %"), "{text}");
    // the copy's edges lie on the original's: each is met by a third face
    assert!(text.contains("shared by three faces or more"), "{text}");
    let o = hitex(&["nurbs", "check", twice.to_str().unwrap(), "--json"]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["overlaps"].as_array().unwrap().len(), 1);
    assert!(j["non_manifold_edges"].as_u64().unwrap() > 0);
    // the teapot and the machined part as they are: neither
    let part = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data/cad/face_recognition_sample_part.stp");
    for model in ["teapot", part] {
        let o = hitex(&["nurbs", "check", model]);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(
            text.contains("no faces lie on each other") && !text.contains("three faces or more"),
            "{model}: {text}"
        );
    }
}

/// `nurbs render` fits the mesh that places fragments to the surface by
/// default and says how it cut it; `--density N` keeps a fixed N×N grid, and
/// a tighter `--mesh-chord` cuts finer.
#[test]
fn nurbs_render_fits_its_mesh_and_says_so() {
    let d = tmp("mesh-fit");
    let out = d.join("t.png");
    let triangles = |extra: &[&str]| -> (usize, String) {
        let mut args =
            vec!["nurbs", "render", "teapot", "--size", "64x48", "--backend", "cpu", "-o", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = hitex(&args);
        assert!(o.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&o.stderr));
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        let line =
            text.lines().find(|l| l.starts_with("mesh placing the fragments: ")).expect("a mesh line").to_string();
        let n: String = line["mesh placing the fragments: ".len()..]
            .chars()
            .filter(|c| *c != ',')
            .take_while(char::is_ascii_digit)
            .collect();
        (n.parse().unwrap(), line)
    };
    let (auto, line) = triangles(&[]);
    assert!(line.contains("(auto, 8 to ") && line.contains("model units of the surface"), "{line}");
    let (fixed, line) = triangles(&["--density", "8"]);
    assert!(line.contains("8×8 cells a patch"), "{line}");
    // the teapot's 32 patches, 8×8 cells of two triangles, its seams matched
    assert!((32 * 8 * 8 * 2..32 * 8 * 8 * 3).contains(&fixed), "{line}");
    let (fine, line) = triangles(&["--mesh-chord", "0.0005"]);
    assert!(auto > fixed && fine > auto, "{fixed} fixed, {auto} auto, {fine} with a tighter chord: {line}");
}
