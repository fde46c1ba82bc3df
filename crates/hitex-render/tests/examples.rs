//! The library examples run here, so that they keep building and working.

#[path = "../examples/fly_store.rs"]
mod fly_store;
#[path = "../examples/render_btf.rs"]
mod render_btf;
#[path = "../examples/render_nurbs.rs"]
mod render_nurbs;

use std::path::Path;

fn out_dir(name: &str) -> std::path::PathBuf {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/test-output/examples").join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Pixels whose channels sum above `floor` (not background, not black).
fn lit(path: &Path, floor: u32) -> (usize, usize) {
    let img = image::open(path).unwrap().to_rgba8();
    let n = img.pixels().filter(|p| p[0] as u32 + p[1] as u32 + p[2] as u32 > floor).count();
    (n, (img.width() * img.height()) as usize)
}

#[test]
fn the_btf_example_renders_a_lit_material() {
    let out = out_dir("btf").join("btf.png");
    let name = render_btf::run(&out, 160, 120).unwrap();
    assert!(!name.is_empty());
    let (n, all) = lit(&out, 60);
    assert!(n > all / 5, "{n} of {all} pixels lit");
}

#[test]
fn the_nurbs_example_evaluates_and_renders_the_teapot() {
    let dir = out_dir("nurbs");
    let (p, n) = render_nurbs::run("teapot", &dir, 128).unwrap();
    assert!(p.iter().all(|c| c.is_finite()));
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    assert!((len - 1.0).abs() < 1e-9, "unit normal, got length {len}");
    for f in ["shaded.png", "isophotes.png"] {
        let (lit, all) = lit(&dir.join(f), 100);
        assert!(lit > all / 10, "{f}: {lit} of {all} pixels on the model");
    }
}

#[test]
fn the_nurbs_example_keeps_the_trims_of_a_trimmed_model() {
    // an IGES square with a hole cut by a trim loop (a repository fixture)
    let part = Path::new(env!("CARGO_MANIFEST_DIR")).join("../hitex-io/data/holed-square.igs");
    let dir = out_dir("holed-square");
    render_nurbs::run(part.to_str().unwrap(), &dir, 96).unwrap();
    let m = hitex_io::models::load_model(part.to_str().unwrap()).unwrap();
    assert!(m.trims().iter().any(|t| !t.is_empty()), "the fixture is trimmed");
    // the same model without its trims covers more pixels than the example's image
    let mut untrimmed = hitex_render::nurbs::PreparedNurbs::new(m.nurbs(), &m.ranges(), 8);
    untrimmed.mode = hitex_render::nurbs::NurbsMode::Shaded;
    let f = hitex_render::CpuRenderer::new().render_nurbs(&untrimmed, &untrimmed.camera, 96, 96).unwrap();
    let bg = [f.rgba[0], f.rgba[1], f.rgba[2]];
    let cover = |rgba: &[u8]| rgba.chunks_exact(4).filter(|p| p[..3] != bg).count();
    let img = image::open(dir.join("shaded.png")).unwrap().to_rgba8();
    let (with, without) = (cover(img.as_raw()), cover(&f.rgba));
    assert!(with + 200 < without, "trimmed covers {with} pixels, untrimmed {without}: the hole is missing");
}

#[test]
fn the_flight_example_builds_a_store_and_flies_over_it() {
    let dir = out_dir("fly");
    let name = fly_store::run(&dir, 1024, 2, (96, 64)).unwrap();
    assert!(!name.is_empty());
    assert!(dir.join("store/tilemapresource.xml").exists() || dir.join("store").read_dir().unwrap().count() > 1);
    for i in 0..2 {
        let img = image::open(dir.join(format!("frame-{i}.png"))).unwrap().to_rgba8();
        // imagery below the horizon: many colours, not the bare ground colour
        let colours: std::collections::HashSet<[u8; 4]> = img.pixels().map(|p| p.0).collect();
        assert!(colours.len() > 100, "frame {i}: {} colours", colours.len());
    }
}
