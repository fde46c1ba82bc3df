//! `hitex demo`: the embedded showcase.

use crate::{CliError, open_renderer, render_frame, save};
use hitex_core::scene::{RenderMode, Scene, showcase_scene};
use hitex_core::texture::{Filter, LevelRule};
use hitex_render::{AnyRenderer, Job, Renderer};
use hitex_render::{BackendChoice, Frame, PreparedScene};
use std::path::Path;
use std::time::Instant;

/// Places frames side by side with a 4-pixel dark gutter.
pub fn side_by_side(frames: &[Frame]) -> Frame {
    let gutter = 4u32;
    let h = frames.iter().map(|f| f.height).max().unwrap_or(1);
    let w = frames.iter().map(|f| f.width).sum::<u32>() + gutter * (frames.len().saturating_sub(1) as u32);
    let mut rgba = vec![0u8; (w * h * 4) as usize];
    for px in rgba.chunks_exact_mut(4) {
        px.copy_from_slice(&[24, 24, 28, 255]);
    }
    let mut x0 = 0u32;
    for f in frames {
        for y in 0..f.height {
            let src = &f.rgba[(y * f.width * 4) as usize..((y + 1) * f.width * 4) as usize];
            let d = ((y * w + x0) * 4) as usize;
            rgba[d..d + src.len()].copy_from_slice(src);
        }
        x0 += f.width + gutter;
    }
    Frame { width: w, height: h, rgba }
}

/// |a − b| per channel, × 8 (a difference image for the gallery).
fn diff_x8(a: &Frame, b: &Frame) -> Frame {
    let rgba = a
        .rgba
        .chunks_exact(4)
        .zip(b.rgba.chunks_exact(4))
        .flat_map(|(a, b)| {
            let d = |k: usize| ((a[k] as i32 - b[k] as i32).unsigned_abs() * 8).min(255) as u8;
            [d(0), d(1), d(2), 255]
        })
        .collect();
    Frame { width: a.width, height: a.height, rgba }
}

fn with_filter(scene: &Scene, filter: Filter) -> Scene {
    let mut s = scene.clone();
    for m in &mut s.materials {
        m.sampler.filter = filter;
    }
    s
}

/// Saves one showcase image and prints its line.
type Report<'a> = dyn FnMut(&str, &str, &Frame, f64) -> Result<(), CliError> + 'a;

/// The BTF pillar of the showcase: every procedural material on a quad, the
/// corduroy on the NURBS teapot under a moving light, layouts (a) | (f) |
/// (f)+BC1 with their difference, and the synthesised index map. Returns the
/// number of images written.
fn btf_showcase(r: &mut AnyRenderer, report: &mut Report<'_>, w: u32, h: u32) -> Result<usize, CliError> {
    use crate::btf_cmd::{camera_for, index_preview, index_with_progress, light_for, surface_for, synth_with_progress};
    use glam::Vec3;
    use hitex_core::btf::Layout;
    use hitex_core::btf::synth::{Material, SynthOptions};
    use hitex_core::scene::Camera;
    use hitex_core::texture::bc1::Bc1Encoder;
    use hitex_render::btf::{BtfSurface, PreparedBtf};
    let side = (w / 5).clamp(1, h.max(1));
    let mut panels = Vec::new();
    let mut ms_sum = 0.0;
    let mut corduroy = None;
    let mut woven = None;
    for m in Material::ALL {
        let btf = synth_with_progress(m, &SynthOptions::default(), true)?;
        let index = index_with_progress(&btf, 64, 7, 3, true)?;
        let surface = BtfSurface::quad(2.0, 1.0);
        let cam = camera_for(&surface, true, 1.0)?;
        let light = light_for(&surface, true, 35.0, 40.0);
        let p = PreparedBtf::new(&btf, Layout::F, None, index.clone(), surface)?;
        let t = Instant::now();
        panels.push(render_frame(r, &Job::Btf { surface: &p, camera: cam, light }, (side, side))?);
        ms_sum += t.elapsed().as_secs_f64() * 1e3;
        match m {
            Material::Corduroy => corduroy = Some((btf, index)),
            Material::Woven => woven = Some((btf, index)),
            _ => {}
        }
    }
    report(
        "btf-materials.png",
        "BTF: corduroy | knit | leather | woven | brushed metal",
        &side_by_side(&panels),
        ms_sum,
    )?;
    let Some((btf, index)) = corduroy else { return Ok(1) };
    // the corduroy on the teapot (U, V from the exact partials), light moving round
    let teapot = surface_for("teapot", 0.6)?;
    let (pw, ph) = ((w / 3).max(1), h);
    let cam = camera_for(&teapot, false, pw as f32 / ph as f32)?;
    let p = PreparedBtf::new(&btf, Layout::F, None, index.clone(), teapot.clone())?;
    let mut panels = Vec::new();
    let mut ms_sum = 0.0;
    for az in [-150.0, -63.0, 20.0] {
        let t = Instant::now();
        panels.push(render_frame(
            r,
            &Job::Btf { surface: &p, camera: cam, light: light_for(&teapot, false, az, 45.0) },
            (pw, ph),
        )?);
        ms_sum += t.elapsed().as_secs_f64() * 1e3;
    }
    report("btf-teapot.png", "BTF corduroy on the NURBS teapot, light moving round", &side_by_side(&panels), ms_sum)?;
    // layouts (a) | (f) | (f)+BC1 | |(a) − (f)+BC1| × 8
    let quad = BtfSurface::quad(2.0, 1.0);
    let cam = camera_for(&quad, true, 1.0)?;
    let light = light_for(&quad, true, 200.0, 30.0);
    let side = (w / 4).clamp(1, h.max(1));
    let mut panels = Vec::new();
    let mut ms_sum = 0.0;
    for (layout, bc1) in [(Layout::A, false), (Layout::F, false), (Layout::F, true)] {
        let p = PreparedBtf::new(&btf, layout, bc1.then_some(Bc1Encoder::Ispc), index.clone(), quad.clone())?;
        let t = Instant::now();
        panels.push(render_frame(r, &Job::Btf { surface: &p, camera: cam, light }, (side, side))?);
        ms_sum += t.elapsed().as_secs_f64() * 1e3;
    }
    panels.push(diff_x8(&panels[0], &panels[2]));
    report(
        "btf-layouts.png",
        "layout (a), 64 reads | (f), 8 reads | (f) + BC1 | |(a) − (f)+BC1| × 8",
        &side_by_side(&panels),
        ms_sum,
    )?;
    // local PCA: the raw codebook | one basis of 8 components | of 2 | the difference × 8
    let mut panels = vec![panels[1].clone()];
    let mut notes = Vec::new();
    let mut ms_sum = 0.0;
    for k in [8, 2] {
        let opts = hitex_core::btf::pca::PcaOptions { clusters: 1, components: k };
        let (pca, psnr) = crate::btf_cmd::pca_with_progress(&btf, opts, true)?;
        let p = PreparedBtf::with_pca(&pca, Layout::F, index.clone(), quad.clone())?;
        let t = Instant::now();
        panels.push(render_frame(r, &Job::Btf { surface: &p, camera: cam, light }, (side, side))?);
        ms_sum += t.elapsed().as_secs_f64() * 1e3;
        notes.push(format!("{k} components (1:{:.0}, {psnr:.1} dB)", pca.ratio()));
    }
    panels.push(diff_x8(&panels[0], &panels[1]));
    report(
        "btf-pca.png",
        &format!("BTF local PCA, layout (f): raw | {} | {} | |raw - 8 components| x 8", notes[0], notes[1]),
        &side_by_side(&panels),
        ms_sum,
    )?;
    // MIP mapping: the woven on a far, grazing quad of 24 repeats beside a 4×4
    // supersampled reference, and the corduroy on the teapot at 6 repeats,
    // each without and with the pyramid
    let (far_btf, far_index) = woven.as_ref().map(|(b, i)| (b, i)).unwrap_or((&btf, &index));
    let far_mip = crate::btf_cmd::mip_with_progress(far_btf, far_index, true)?;
    let far = BtfSurface::quad(4.0, 24.0);
    let far_cam = Camera::new(Vec3::new(0.0, -2.6, 0.9), Vec3::new(0.0, 0.4, 0.0), Vec3::Z, 40.0, 0.05, 20.0)
        .map_err(|e| CliError::Input(e.to_string()))?;
    let far_light = light_for(&far, true, 200.0, 30.0);
    let side = (w / 3).clamp(1, h.max(1));
    let off = PreparedBtf::new(far_btf, Layout::F, None, far_index.clone(), far.clone())?;
    let on = PreparedBtf::with_mip(&far_mip, Layout::F, None, far)?;
    let t = Instant::now();
    let frames = [
        render_frame(r, &Job::Btf { surface: &off, camera: far_cam, light: far_light }, (side, side))?,
        render_frame(r, &Job::Btf { surface: &on, camera: far_cam, light: far_light }, (side, side))?,
    ];
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let reference =
        render_frame(r, &Job::Btf { surface: &off, camera: far_cam, light: far_light }, (side * 4, side * 4))?
            .downsample(4);
    let psnr = |f: &Frame| hitex_render::compare_rgba(&f.rgba, &reference.rgba).0.psnr_db;
    let caption = format!(
        "BTF MIP, the woven on a far quad of 24 repeats: without ({:.1} dB) | with ({:.1} dB) | 4x4 supersampled reference",
        psnr(&frames[0]),
        psnr(&frames[1])
    );
    let [a, b] = frames;
    report("btf-mip.png", &caption, &side_by_side(&[a, b, reference]), ms)?;
    let mip = crate::btf_cmd::mip_with_progress(&btf, &index, true)?;
    let teapot = surface_for("teapot", 6.0)?;
    let (pw, ph) = ((w / 2).max(1), h);
    let cam = camera_for(&teapot, false, pw as f32 / ph as f32)?;
    let light = light_for(&teapot, false, -63.0, 45.0);
    let off = PreparedBtf::new(&btf, Layout::F, None, index.clone(), teapot.clone())?;
    let on = PreparedBtf::with_mip(&mip, Layout::F, None, teapot)?;
    let t = Instant::now();
    let pair = [
        render_frame(r, &Job::Btf { surface: &off, camera: cam, light }, (pw, ph))?,
        render_frame(r, &Job::Btf { surface: &on, camera: cam, light }, (pw, ph))?,
    ];
    report(
        "btf-mip-teapot.png",
        "BTF corduroy at 6 repeats on the teapot: without MIP | with MIP",
        &side_by_side(&pair),
        t.elapsed().as_secs_f64() * 1e3,
    )?;
    report(
        "btf-index.png",
        "index map grown from the 32x32 sample: u,v as red,green | appearance",
        &index_preview(&btf, &index),
        0.0,
    )?;
    Ok(7)
}

/// The Olinda pair (SRTM-derived DEM and Landsat 7 ETM+ bands, UTM 25S),
/// embedded so that the showcase needs no files.
/// A machined part exported as STEP AP214 (planes, cylinders, cones).
const MACHINED_PART: &[u8] = include_bytes!("../../hitex-io/data/cad/face_recognition_sample_part.stp");
const OLINDA_DEM: &[u8] = include_bytes!("../../hitex-io/data/olinda/olinda_dem_utm25s.tif");
const OLINDA_IMAGE: &[u8] = include_bytes!("../../hitex-io/data/olinda/L7_ETMs.tif");

/// The terrain pillar of the showcase over the real Olinda pair: a GST
/// store built from the Landsat bands 3,2,1 with the DEM copied in
/// (`out/olinda/store`), three frames of a flight over the relief with an
/// aircraft carrying a generic texture, and one view per sampler —
/// per-pixel trilinear | span 3×3 | span 4×4 | |trilinear − span 3×3| × 8.
fn terrain_showcase(
    out: &Path,
    backend: BackendChoice,
    w: u32,
    h: u32,
    report: &mut Report<'_>,
) -> Result<usize, CliError> {
    use crate::terrain_store_cmd::{BuildArgs, FlyArgs, GroundArg, build, fly};
    use hitex_render::terrain::FlySampler;
    let dir = out.join("olinda");
    hitex_io::create_output_dir(&dir)?;
    let (dem, image) = (dir.join("olinda_dem_utm25s.tif"), dir.join("L7_ETMs.tif"));
    hitex_io::write_atomic(&dem, OLINDA_DEM)?;
    hitex_io::write_atomic(&image, OLINDA_IMAGE)?;
    let store = dir.join("store");
    say!("  terrain: building the Olinda GST store (Landsat 7 bands 3,2,1 + DEM) in {}", store.display());
    build(BuildArgs {
        image: Some(image),
        bands: "3,2,1".into(),
        dem: vec![dem],
        procedural: None,
        output: store.clone(),
        profile: None,
        format: None,
        shard: (0, 1),
        max_maps: crate::terrain_store_cmd::DEFAULT_MAX_MAPS,
        ignore_free_space: false,
    })?;
    let flight = |frames: u32, size: (u32, u32), sampler: FlySampler, output: std::path::PathBuf| FlyArgs {
        store: store.clone(),
        path: None,
        frames,
        size,
        budget: 400,
        altitude: Some(2500.0),
        pitch: 28.0,
        fov: 45.0,
        wait: true,
        output,
        backend,
        ground: GroundArg::Relief,
        sampler,
        exaggeration: 3.0,
        no_aircraft: false,
        stats: true,
    };
    let load = |path: &Path| -> Result<Frame, CliError> {
        let img = hitex_io::load_image(path, hitex_core::texture::ColorSpace::Srgb)?;
        Ok(Frame { width: img.width(), height: img.height(), rgba: img.bytes().to_vec() })
    };
    let frames_dir = out.join("terrain-flight");
    let t = Instant::now();
    fly(flight(3, ((w / 3).max(2) & !1, h & !1), FlySampler::Trilinear, frames_dir.clone()))?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let panels = (0..3).map(|f| load(&frames_dir.join(format!("frame-{f:04}.png")))).collect::<Result<Vec<_>, _>>()?;
    report(
        "terrain-flight.png",
        "Olinda: relief ×3 and an aircraft, Landsat maps through the resident-map cache (3 frames)",
        &side_by_side(&panels),
        ms,
    )?;
    let size = ((w / 4).max(2) & !1, (h / 2).max(2) & !1);
    let t = Instant::now();
    let mut panels = Vec::new();
    for s in [FlySampler::Trilinear, FlySampler::Span3, FlySampler::Span4] {
        let d = out.join(format!("terrain-{}", s.name()));
        fly(flight(1, size, s, d.clone()))?;
        panels.push(load(&d.join("frame-0000.png"))?);
    }
    let ms = t.elapsed().as_secs_f64() * 1e3;
    panels.push(diff_x8(&panels[0], &panels[1]));
    report(
        "terrain-spans.png",
        "Olinda: trilinear | span 3x3 | span 4x4 | |trilinear - span 3x3| x 8",
        &side_by_side(&panels),
        ms,
    )?;
    Ok(2)
}

/// Renders the showcase images into `out`.
/// A synthetic scan of `model`: its tessellation (24×24 per patch) with a
/// bump of +0.03 on the side facing the default view and a dent of −0.02 at
/// the top of the lid, both Gaussian along the exact normal; written to
/// `teapot-scan.stl` and `teapot-scan.xyz` in `out` so that the picture can
/// be made again from the command line.
#[allow(clippy::type_complexity)]
fn teapot_scan(
    model: &hitex_io::models::NurbsModel,
    out: &Path,
) -> Result<(Vec<hitex_io::stl::Triangle>, Vec<[f64; 3]>), CliError> {
    let p = crate::nurbs_cmd::prepare(model, hitex_render::nurbs::Density::Fixed(24), None).0;
    let view = hitex_render::nurbs::ModelView::default();
    let eye = p.view_camera(&view, 1.0, [-1.0, 1.0, -1.0, 1.0]).position;
    let pos = |v: &hitex_render::nurbs::NurbsVertex| glam::Vec3::from_array(v.position);
    let near = |key: &dyn Fn(glam::Vec3) -> f32| {
        p.vertices.iter().map(pos).min_by(|a, b| key(*a).total_cmp(&key(*b))).unwrap_or(glam::Vec3::ZERO)
    };
    let bump = near(&|v| (v - eye).length());
    let dent = near(&|v| -v.z);
    let moved: Vec<[f64; 3]> = p
        .vertices
        .iter()
        .map(|v| {
            let x = pos(v);
            let n = glam::Vec3::from_array(v.normal);
            let g = |c: glam::Vec3, a: f32, s: f32| a * (-(x - c).length_squared() / (s * s)).exp();
            (x + n * (g(bump, 0.03, 0.35) + g(dent, -0.02, 0.25))).as_dvec3().to_array()
        })
        .collect();
    let tris: Vec<hitex_io::stl::Triangle> =
        p.indices.chunks_exact(3).map(|t| [0, 1, 2].map(|k| moved[t[k] as usize])).collect();
    hitex_io::write_atomic(&out.join("teapot-scan.stl"), &hitex_io::stl::to_binary_stl(&tris))?;
    let xyz: String = moved.iter().map(|q| format!("{} {} {}\n", q[0], q[1], q[2])).collect();
    hitex_io::write_atomic(&out.join("teapot-scan.xyz"), xyz.as_bytes())?;
    Ok((tris, moved))
}

pub fn run(out: &Path, backend: BackendChoice, (w, h): (u32, u32)) -> Result<(), CliError> {
    hitex_io::create_output_dir(out)?;
    let mut r = open_renderer(backend)?;
    say!("hitex demo: rendering with {}", r.name());
    let base = showcase_scene();
    let mut total = 0.0;
    let mut images = 0;
    let mut render = |scene: &Scene, w: u32, h: u32| -> Result<(Frame, f64), CliError> {
        let p = PreparedScene::new(scene);
        let t = Instant::now();
        let f = render_frame(&mut r, &Job::Scene { scene: &p, camera: p.camera }, (w, h))?;
        Ok((f, t.elapsed().as_secs_f64() * 1e3))
    };
    let mut report = |name: &str, what: &str, f: &Frame, ms: f64| -> Result<(), CliError> {
        let path = out.join(name);
        save(f, &path)?;
        total += ms;
        images += 1;
        say!("  {:<28} {:>5}x{:<5} {ms:>8.1} ms  {what}", path.display(), f.width, f.height);
        Ok(())
    };

    // 1. the showcase, trilinear
    let (f, ms) = render(&base, w, h)?;
    report("showcase.png", "textured meshes, per-pixel trilinear MIP mapping", &f, ms)?;

    // 2. the MIP level chosen per pixel
    let mut lv = base.clone();
    lv.mode = RenderMode::Level;
    let (f, ms) = render(&lv, w, h)?;
    report("showcase-levels.png", "MIP level per pixel (blue 0 … red 9)", &f, ms)?;

    // 3. nearest | bilinear | trilinear on the same view
    let (pw, ph) = ((w / 3).max(1), h);
    let mut panels = Vec::new();
    let mut ms_sum = 0.0;
    for filter in [Filter::Nearest, Filter::Bilinear, Filter::Trilinear] {
        let (f, ms) = render(&with_filter(&base, filter), pw, ph)?;
        ms_sum += ms;
        panels.push(f);
    }
    report("filters.png", "nearest | bilinear | trilinear", &side_by_side(&panels), ms_sum)?;

    // 4. level rules: the paper's max |partial| against Vulkan's rho
    let mut panels = Vec::new();
    let mut ms_sum = 0.0;
    for rule in [LevelRule::MaxPartial, LevelRule::VulkanRho] {
        let mut s = base.clone();
        s.mode = RenderMode::Level;
        for m in &mut s.materials {
            m.sampler.level_rule = rule;
        }
        let (f, ms) = render(&s, (w / 2).max(1), h)?;
        ms_sum += ms;
        panels.push(f);
    }
    report("level-rules.png", "level: paper eq. (2) max |partial| | Vulkan rho", &side_by_side(&panels), ms_sum)?;

    // 5. uv and normal views
    let mut uv = base.clone();
    uv.mode = RenderMode::Uv;
    let mut nr = base.clone();
    nr.mode = RenderMode::Normal;
    let (a, ma) = render(&uv, (w / 2).max(1), h)?;
    let (b, mb) = render(&nr, (w / 2).max(1), h)?;
    report("uv-normal.png", "texture coordinates | normals", &side_by_side(&[a, b]), ma + mb)?;

    // 6–9. NURBS: exact per-pixel evaluation (seed 004)
    use hitex_render::nurbs::NurbsMode;
    let teapot = hitex_io::models::load_model("teapot")?;
    let surface = hitex_io::models::load_model("surface")?;
    let side = h.min(w / 2).max(1);
    let mut nurbs = |model: &hitex_io::models::NurbsModel,
                     mode: NurbsMode,
                     density: u32,
                     turn: f32|
     -> Result<(Frame, f64), CliError> {
        let mut p = crate::nurbs_cmd::prepare(model, hitex_render::nurbs::Density::Fixed(density), None).0;
        p.mode = mode;
        let cam = if crate::nurbs_cmd::has_legend(mode) {
            // framed clear of the legend strip
            let view = hitex_render::nurbs::ModelView { turn_deg: turn.to_degrees(), ..Default::default() };
            p.view_camera(&view, 1.0, crate::nurbs_cmd::view_window(side, side, true))
        } else {
            p.camera.orbit(turn)
        };
        let t = Instant::now();
        let mut f = render_frame(&mut r, &Job::Nurbs { model: &p, camera: cam }, (side, side))?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        crate::nurbs_cmd::mode_legend(&mut f, &p, false);
        Ok((f, ms))
    };
    let (a, ma) = nurbs(&teapot, NurbsMode::Shaded, 8, 0.0)?;
    let (b, mb) = nurbs(&teapot, NurbsMode::Isophote, 8, 0.0)?;
    report(
        "teapot.png",
        "NURBS teapot, exact per-pixel point and normal: shaded | isophotes",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;
    let (a, ma) = nurbs(&teapot, NurbsMode::Zebra, 8, 0.6)?;
    let (b, mb) = nurbs(&surface, NurbsMode::Zebra, 8, 0.0)?;
    report("zebra.png", "reflection lines: teapot | 6x14 rational surface", &side_by_side(&[a, b]), ma + mb)?;
    let spray = hitex_io::models::load_model("spray")?;
    let (a, ma) = nurbs(&surface, NurbsMode::Gauss, 8, 0.0)?;
    let (b, mb) = nurbs(&spray, NurbsMode::Mean, 4, 0.5)?;
    report(
        "curvature.png",
        "Gaussian curvature of the surface | mean curvature of the 266-patch spray",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;
    let (a, ma) = nurbs(&teapot, NurbsMode::Isophote, 3, 0.0)?;
    let (b, mb) = nurbs(&teapot, NurbsMode::VertexNormals, 3, 0.0)?;
    report(
        "fig4-isophotes.png",
        "paper Fig. 4: per-pixel normals | interpolated vertex normals",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;
    let (a, ma) = nurbs(&teapot, NurbsMode::K1, 8, 0.6)?;
    let (b, mb) = nurbs(&teapot, NurbsMode::K2, 8, 0.6)?;
    report(
        "principal.png",
        "principal curvatures of the teapot, exact per pixel: larger k1 | smaller k2",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;
    let mut pull = |dir: glam::Vec3, tolerance: f32| -> Result<(Frame, f64), CliError> {
        let mut p = crate::nurbs_cmd::prepare(&teapot, hitex_render::nurbs::Density::Fixed(8), None).0;
        p.mode = NurbsMode::Draft;
        p.pull = dir;
        p.draft_tolerance_deg = tolerance;
        let view = hitex_render::nurbs::ModelView::default();
        let cam = p.view_camera(&view, 1.0, crate::nurbs_cmd::view_window(side, side, true));
        let t = Instant::now();
        let mut f = render_frame(&mut r, &Job::Nurbs { model: &p, camera: cam }, (side, side))?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        crate::nurbs_cmd::mode_legend(&mut f, &p, false);
        Ok((f, ms))
    };
    let (a, ma) = pull(glam::Vec3::Z, 1.0)?;
    let (b, mb) = pull(glam::Vec3::X, 3.0)?;
    report(
        "draft.png",
        "draft against a pull direction, exact per pixel: +Z within 1 deg | +X within 3 deg",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;

    let mut lines = |isolines: u32, sections: Option<(glam::Vec3, f32)>| -> Result<(Frame, f64), CliError> {
        let mut p = crate::nurbs_cmd::prepare(&teapot, hitex_render::nurbs::Density::Fixed(8), None).0;
        p.mode = NurbsMode::Shaded;
        p.isolines = isolines;
        // twelve sections over the model's height
        p.sections = sections.map(|(n, k)| (n, 2.0 * p.bounds.1 / k));
        let cam = p.camera.orbit(0.6);
        let t = Instant::now();
        let f = render_frame(&mut r, &Job::Nurbs { model: &p, camera: cam }, (side, side))?;
        Ok((f, t.elapsed().as_secs_f64() * 1e3))
    };
    let (a, ma) = lines(4, None)?;
    let (b, mb) = lines(0, Some((glam::Vec3::Z, 16.0)))?;
    report(
        "lines.png",
        "teapot: 4 isoparametric lines per patch | sections z = const, exact per pixel",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;

    // a synthetic scan of the teapot (its tessellation with a bump on the
    // body and a dent in the lid), as a mesh and as points, and the exact
    // surface coloured by its deviation from each
    let (scan, points) = teapot_scan(&teapot, out)?;
    let mut deviation = |data: hitex_io::stl::ReferenceData, name: &str| -> Result<(Frame, f64), CliError> {
        let mut p = crate::nurbs_cmd::prepare(&teapot, hitex_render::nurbs::Density::Fixed(8), None).0;
        p.mode = NurbsMode::Deviation;
        let opts = crate::nurbs_cmd::DeviationOptions {
            grid: 48,
            tolerance: Some(0.004),
            range: Some(0.04),
            max_distance: None,
        };
        for line in crate::nurbs_cmd::set_up_deviation(&mut p, &teapot, data, name, &opts)? {
            say!("  {line}");
        }
        let view = hitex_render::nurbs::ModelView::default();
        let cam = p.view_camera(&view, 1.0, crate::nurbs_cmd::view_window(side, side, true));
        let t = Instant::now();
        let mut f = render_frame(&mut r, &Job::Nurbs { model: &p, camera: cam }, (side, side))?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        crate::nurbs_cmd::mode_legend(&mut f, &p, true);
        Ok((f, ms))
    };
    let (a, ma) = deviation(hitex_io::stl::ReferenceData::Mesh(scan), "teapot-scan.stl")?;
    let (b, mb) = deviation(hitex_io::stl::ReferenceData::Points(points), "teapot-scan.xyz")?;
    report(
        "deviation.png",
        "deviation from a scan, exact surface points: mesh (teapot-scan.stl) | its vertices (teapot-scan.xyz)",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;

    // the edges `nurbs check` finds, by class: the teapot and a machined part
    // (written out beside the pictures, to try the commands on)
    let part_path = out.join("face_recognition_sample_part.stp");
    hitex_io::write_atomic(&part_path, MACHINED_PART)?;
    let part = hitex_io::models::load_model(&part_path.to_string_lossy())?;
    let mut continuity = |model: &hitex_io::models::NurbsModel, turn: f32| -> Result<(Frame, f64), CliError> {
        let mut p = crate::nurbs_cmd::prepare(model, hitex_render::nurbs::Density::Fixed(8), None).0;
        let line = crate::nurbs_cmd::set_up_continuity(&mut p, model, None, None, None)?;
        say!("  {}: {line}", model.name);
        let view = hitex_render::nurbs::ModelView { turn_deg: turn, ..Default::default() };
        let cam = p.view_camera(&view, 1.0, crate::nurbs_cmd::view_window(side, side, true));
        let t = Instant::now();
        let mut f = render_frame(&mut r, &Job::Nurbs { model: &p, camera: cam }, (side, side))?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let entries: Vec<([u8; 3], String)> =
            crate::nurbs_cmd::CONTINUITY_CLASSES.iter().map(|(_, rgb, label)| (*rgb, label.to_string())).collect();
        hitex_render::legend::swatch_legend(&mut f, &["CONTINUITY"], &entries);
        Ok((f, ms))
    };
    let (a, ma) = continuity(&teapot, 0.0)?;
    let (b, mb) = continuity(&part, 40.0)?;
    report(
        "continuity.png",
        "edges by the continuity they reach (nurbs check): teapot | machined part (STEP)",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;

    // a mirror in the procedural studio: the teapot and the machined part
    let mut studio = |model: &hitex_io::models::NurbsModel, turn: f32| -> Result<(Frame, f64), CliError> {
        let mut p = crate::nurbs_cmd::prepare(model, hitex_render::nurbs::Density::Fixed(8), None).0;
        p.mode = NurbsMode::Reflection;
        let view = hitex_render::nurbs::ModelView { turn_deg: turn, ..Default::default() };
        let cam = p.view_camera(&view, 1.0, crate::nurbs_cmd::view_window(side, side, false));
        let t = Instant::now();
        let f = render_frame(&mut r, &Job::Nurbs { model: &p, camera: cam }, (side, side))?;
        Ok((f, t.elapsed().as_secs_f64() * 1e3))
    };
    let (a, ma) = studio(&teapot, 0.0)?;
    let (b, mb) = studio(&spray, 30.0)?;
    report(
        "reflection.png",
        "a mirror in a procedural studio, exact normals: teapot | 266-patch spray bottle",
        &side_by_side(&[a, b]),
        ma + mb,
    )?;

    // 10–13. BTF (seed 000): procedural materials, index synthesis, layouts
    btf_showcase(&mut r, &mut report, w, h)?;

    // 14–15. Terrain (seed 001): a flight through the resident-map cache, span-parallel mapping
    terrain_showcase(out, backend, w, h, &mut report)?;

    say!("hitex demo: {images} images in {}, {total:.0} ms of rendering", out.display());
    Ok(())
}
