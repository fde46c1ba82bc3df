//! `hitex view`: a window on a scene, a NURBS model, a BTF, a tile store or a
//! ground image, for interactive inspection.
//!
//! The view is rendered by the same renderers as the headless commands (GPU
//! or CPU backend, or the CPU bank model for the span-parallel terrain
//! modes) and shown through eframe (winit + egui on wgpu); the image the
//! window shows is the frame the renderer produced, so a screenshot of a view
//! equals the headless render of the same camera.

use crate::{Backend, CliError, open_renderer, parse_size, render_frame, save};
use clap::Args;
use eframe::{egui, egui_wgpu, wgpu};
use glam::{DVec2, Vec3};
use hitex_core::btf::{Btf, Layout};
use hitex_core::residency::ResidentMaps;
use hitex_core::scene::{Camera, RenderMode, Scene};
use hitex_core::texture::MipPyramid;
use hitex_core::texture::ToneMap;
use hitex_core::texture::bc1::Bc1Encoder;
use hitex_core::texture::sampler::Wrap;
use hitex_core::texture::span::{
    BankModel, FlightView, SpanFilter, SpanOptions, SpanScheme, render_spans, render_trilinear,
};
use hitex_io::gst::StoreMeta;
use hitex_render::btf::{BtfSurface, PreparedBtf};
use hitex_render::nurbs::{NurbsMode, PreparedNurbs};
use hitex_render::terrain::FlySampler;
use hitex_render::{AnyRenderer, Job, Renderer};
use hitex_render::{Frame, PreparedScene};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `hitex view`.
#[derive(Args)]
pub struct ViewArgs {
    /// What to open: SCENE.toml; a NURBS model (teapot, surface, spray, FILE.igs,
    /// FILE.obj, FILE.json); a BTF (FILE.hbtf or a material name: corduroy, knit,
    /// leather, woven, brushed-metal); a GST tile store (folder); a ground image
    /// (.png, .jpg, .tif) for the span-parallel terrain modes.
    pub input: String,
    /// Render size of the view (default: the window's view area).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Window size in pixels.
    #[arg(long, value_parser = parse_size, default_value = "1280x800")]
    pub window: (u32, u32),
    /// Which renderer draws the view.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub backend: Backend,
    /// Display mode to start in (e.g. isophote, zebra, gauss; level, uv; span3, bicubic).
    #[arg(long)]
    pub mode: Option<String>,
    /// Write the view after --frames frames to this PNG and close (scripted use).
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Write the whole window (panels included) after --frames frames to this PNG and close.
    #[arg(long)]
    pub window_screenshot: Option<PathBuf>,
    /// Frames to show before the screenshot.
    #[arg(long, default_value_t = 3)]
    pub frames: u32,
}

/// An orbiting camera: the content's own camera until the user moves it.
struct Orbit {
    base: Camera,
    target: Vec3,
    frame: [Vec3; 3],
    yaw: f32,
    pitch: f32,
    distance: f32,
    moved: bool,
}

impl Orbit {
    fn new(base: Camera) -> Self {
        let up = base.up.normalize_or(Vec3::Y);
        let off = base.position - base.target;
        let distance = off.length().max(1e-6);
        let flat = off - up * off.dot(up);
        let e0 = if flat.length() > 1e-6 * distance { flat.normalize() } else { up.any_orthonormal_vector() };
        let e1 = up.cross(e0);
        let pitch = (off.dot(up) / distance).clamp(-1.0, 1.0).asin();
        Self { base, target: base.target, frame: [e0, e1, up], yaw: 0.0, pitch, distance, moved: false }
    }

    fn camera(&self) -> Camera {
        if !self.moved {
            return self.base;
        }
        let [e0, e1, up] = self.frame;
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        let dir = (e0 * cy + e1 * sy) * cp + up * sp;
        let mut c = self.base;
        c.position = self.target + dir * self.distance;
        c.target = self.target;
        c.near = (self.base.near * self.distance / (self.base.position - self.base.target).length().max(1e-6))
            .clamp(1e-5, c.far * 0.5);
        if c.validate().is_ok() { c } else { self.base }
    }

    fn rotate(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * 0.01;
        self.pitch = (self.pitch + dy * 0.01).clamp(-1.55, 1.55);
        self.moved = true;
    }

    fn pan(&mut self, dx: f32, dy: f32, height: f32) {
        let c = self.camera();
        let f = (c.target - c.position).normalize_or(Vec3::Z);
        let right = f.cross(self.frame[2]).normalize_or(Vec3::X);
        let up = right.cross(f);
        let scale = 2.0 * self.distance * (c.fov_y_deg.to_radians() / 2.0).tan() / height.max(1.0);
        self.target += (-right * dx + up * dy) * scale;
        self.moved = true;
    }

    fn zoom(&mut self, steps: f32) {
        self.distance = (self.distance * (-steps * 0.1).exp()).clamp(1e-4, 1e7);
        self.moved = true;
    }
}

/// Where the terrain camera is: position as fractions of the extent,
/// altitude in ground units, pitch from the nadir, heading from north.
#[derive(Debug, Clone, Copy)]
struct Flight {
    x: f64,
    y: f64,
    altitude: f64,
    pitch: f64,
    heading: f64,
}

impl Flight {
    /// Keys: W/S forward/back, A/D sideways, Q/E down/up, arrows turn and tilt.
    fn steer(&mut self, i: &egui::InputState, extent: DVec2) -> bool {
        let dt = i.stable_dt.clamp(0.0, 0.1) as f64;
        let key = |k| if i.key_down(k) { 1.0 } else { 0.0 };
        let fwd = key(egui::Key::W) - key(egui::Key::S);
        let side = key(egui::Key::D) - key(egui::Key::A);
        let climb = key(egui::Key::E) - key(egui::Key::Q);
        let turn = key(egui::Key::ArrowRight) - key(egui::Key::ArrowLeft);
        let tilt = key(egui::Key::ArrowUp) - key(egui::Key::ArrowDown);
        if fwd == 0.0 && side == 0.0 && climb == 0.0 && turn == 0.0 && tilt == 0.0 {
            return false;
        }
        let h = self.heading.to_radians();
        let speed = self.altitude * dt;
        self.x += (h.sin() * fwd + h.cos() * side) * speed / extent.x.max(1.0);
        self.y += (-h.cos() * fwd + h.sin() * side) * speed / extent.y.max(1.0);
        self.altitude = (self.altitude * (climb * dt).exp()).clamp(1e-3, 1e9);
        self.heading = (self.heading + turn * 60.0 * dt).rem_euclid(360.0);
        self.pitch = (self.pitch + tilt * 30.0 * dt).clamp(0.0, 85.0);
        true
    }
}

enum Content {
    Scene { scene: Box<Scene>, prepared: Box<PreparedScene>, orbit: Orbit },
    Nurbs { prepared: Box<PreparedNurbs>, orbit: Orbit, light: [f32; 2], light_moved: bool },
    Btf(Box<BtfView>),
    Store { meta: StoreMeta, cache: Box<ResidentMaps>, flight: Flight, fov: f64, per_side: u32, stats: String },
    Ground { pyr: Box<MipPyramid>, wrap: Wrap, flight: Flight, mode: FlySampler, banks: String },
}

struct BtfView {
    btf: Btf,
    /// The local PCA of a compressed file, drawn from its basis.
    pca: Option<hitex_core::btf::pca::LocalPca>,
    map: hitex_core::btf::index::IndexMap,
    surface: BtfSurface,
    quad: bool,
    layout: Layout,
    bc1: bool,
    prepared: PreparedBtf,
    orbit: Orbit,
    light: [f32; 2],
}

/// The NURBS modes the viewer offers (deviation needs a reference: `hitex nurbs render`).
const NURBS_MODES: [NurbsMode; 13] = [
    NurbsMode::Shaded,
    NurbsMode::Isophote,
    NurbsMode::Zebra,
    NurbsMode::Reflection,
    NurbsMode::Highlight,
    NurbsMode::Draft,
    NurbsMode::Radius,
    NurbsMode::Gauss,
    NurbsMode::Mean,
    NurbsMode::K1,
    NurbsMode::K2,
    NurbsMode::VertexNormals,
    NurbsMode::Normal,
];
const LAYOUTS: [Layout; 8] = [Layout::A, Layout::B, Layout::C, Layout::C2, Layout::D, Layout::E, Layout::E2, Layout::F];

/// The choice of `list` called `name` (by the library's names).
fn pick<T: Copy>(list: &[T], name_of: impl Fn(T) -> &'static str, name: &str) -> Result<T, CliError> {
    list.iter().copied().find(|&m| name_of(m) == name).ok_or_else(|| {
        let names: Vec<&str> = list.iter().map(|&m| name_of(m)).collect();
        CliError::Input(format!("--mode {name}: this view has the modes {}", names.join(", ")))
    })
}

fn light_dir(az: f32, el: f32) -> Vec3 {
    let (a, e) = (az.to_radians(), el.to_radians());
    Vec3::new(a.cos() * e.cos(), e.sin(), a.sin() * e.cos())
}

/// Opens `input` as the content it is.
fn open(input: &str, mode: Option<&str>, aspect: f32) -> Result<Content, CliError> {
    let path = Path::new(input);
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    if path.is_dir() || ext == "mbtiles" {
        let store = std::sync::Arc::new(hitex_io::gst::Store::open(path)?);
        let meta = store.meta.clone();
        let cache = crate::terrain_store_cmd::open_cache(store, 400)?;
        let fov = 45.0;
        let extent = DVec2::new(meta.width as f64, meta.height as f64);
        let flight = Flight {
            x: 0.5,
            y: 0.8,
            altitude: extent.max_element() * meta.ground_pixel() / 10.0,
            pitch: 60.0,
            heading: 0.0,
        };
        if let Some(m) = mode
            && m != "trilinear"
        {
            return Err(CliError::Input(format!(
                "--mode {m}: a store is flown per-pixel trilinear; open the imagery itself for span3, span4, bicubic"
            )));
        }
        return Ok(Content::Store { meta, cache: Box::new(cache), flight, fov, per_side: 6, stats: String::new() });
    }
    match ext.as_str() {
        "toml" => {
            let mut scene = hitex_io::load_scene(path)?;
            if let Some(m) = mode {
                scene.mode = pick(&RenderMode::ALL.map(|(_, m)| m), RenderMode::name, m)?;
            }
            let prepared = PreparedScene::new(&scene);
            let orbit = Orbit::new(prepared.camera);
            Ok(Content::Scene { scene: Box::new(scene), prepared: Box::new(prepared), orbit })
        }
        "png" | "jpg" | "jpeg" | "tif" | "tiff" => {
            let (pyr, wrap, _) = crate::terrain_cmd::ground_texture(Some(path), "3,2,1", "bricks", 1024)?;
            let side = pyr.width().max(pyr.height()) as f64;
            let flight = Flight { x: 0.5, y: 0.5, altitude: 0.3 * side, pitch: 60.0, heading: 30.0 };
            let mode = mode.map_or(Ok(FlySampler::Trilinear), |m| pick(&FlySampler::ALL, FlySampler::name, m))?;
            Ok(Content::Ground { pyr: Box::new(pyr), wrap, flight, mode, banks: String::new() })
        }
        "hbtf" => open_btf(input, mode, aspect),
        _ if hitex_core::btf::synth::Material::parse(input).is_some() => open_btf(input, mode, aspect),
        _ => {
            let model = hitex_io::models::load_model(input)?;
            let (mut prepared, _) = crate::nurbs_cmd::prepare(&model, hitex_render::nurbs::Density::Auto, None);
            if let Some(m) = mode {
                prepared.mode = pick(&NURBS_MODES, NurbsMode::name, m)?;
            }
            // the model's up axis and a view fitted to the window, clear of a legend
            let legend = crate::nurbs_cmd::has_legend(prepared.mode);
            let window = crate::nurbs_cmd::view_window((aspect * 600.0) as u32, 600, legend);
            prepared.camera = prepared.view_camera(&Default::default(), aspect, window);
            let orbit = Orbit::new(prepared.camera);
            Ok(Content::Nurbs { prepared: Box::new(prepared), orbit, light: [45.0, 40.0], light_moved: false })
        }
    }
}

fn open_btf(input: &str, mode: Option<&str>, aspect: f32) -> Result<Content, CliError> {
    let layout = match mode {
        None => Layout::F,
        Some(m) => Layout::parse(m).ok_or_else(|| {
            CliError::Input(format!("--mode {m}: a BTF view takes a layout: a, b, c, c2, d, e, e2 or f"))
        })?,
    };
    let (btf, pca) = crate::btf_cmd::load_or_synth_pca(input, true)?;
    let map = crate::btf_cmd::index_with_progress(&btf, 128, 1, 3, true)?;
    let surface = crate::btf_cmd::surface_for("sphere", 4.0)?;
    let camera = crate::btf_cmd::camera_for(&surface, false, aspect)?;
    let mut prepared = match &pca {
        Some(p) => PreparedBtf::with_pca(p, layout, map.clone(), surface.clone())?,
        None => PreparedBtf::new(&btf, layout, None, map.clone(), surface.clone())?,
    };
    // an HDR BTF is shown through the tone map `btf render` uses by default
    prepared.tone_map = if btf.is_hdr() { ToneMap::Aces } else { ToneMap::None };
    Ok(Content::Btf(Box::new(BtfView {
        btf,
        pca,
        map,
        surface,
        quad: false,
        layout,
        bc1: false,
        prepared,
        orbit: Orbit::new(camera),
        light: [30.0, 45.0],
    })))
}

impl Content {
    fn kind(&self) -> &'static str {
        match self {
            Content::Scene { .. } => "scene",
            Content::Nurbs { .. } => "NURBS model",
            Content::Btf(_) => "BTF",
            Content::Store { .. } => "tile store",
            Content::Ground { .. } => "ground image",
        }
    }

    /// Whether the view is drawn by the renderer alone (so that the GPU can
    /// draw it into the window's texture): not the CPU bank model's ground,
    /// nor a NURBS mode whose legend is drawn onto the image.
    fn drawn_by_the_renderer(&self) -> bool {
        match self {
            Content::Nurbs { prepared, .. } => !crate::nurbs_cmd::has_legend(prepared.mode),
            Content::Ground { .. } => false,
            _ => true,
        }
    }

    /// Renders the current view at `w`×`h`: into `into` (a texture on the
    /// GPU renderer's device, `w`×`h`) when given and the GPU draws it, else
    /// as an image.
    fn render(&mut self, r: &mut AnyRenderer, w: u32, h: u32, into: Option<&wgpu::Texture>) -> Result<Shown, CliError> {
        let into = into.filter(|_| self.drawn_by_the_renderer());
        let run = |r: &mut AnyRenderer, job: &Job<'_>| -> Result<Shown, CliError> {
            match into {
                Some(t) => Ok(r.render_into(job, t)?.map_or(Shown::InTexture, |out| Shown::Image(out.frame))),
                None => Ok(Shown::Image(render_frame(r, job, (w, h))?)),
            }
        };
        match self {
            Content::Scene { prepared, orbit, .. } => run(r, &Job::Scene { scene: prepared, camera: orbit.camera() }),
            Content::Nurbs { prepared, orbit, light, light_moved } => {
                // the model's own light (as the headless render has it) until the sliders move
                if *light_moved {
                    prepared.light = Some(light_dir(light[0], light[1]));
                }
                let job = Job::Nurbs { model: prepared, camera: orbit.camera() };
                let mut shown = run(r, &job)?;
                if let Shown::Image(f) = &mut shown {
                    crate::nurbs_cmd::mode_legend(f, prepared, false);
                }
                Ok(shown)
            }
            Content::Btf(b) => {
                let light = crate::btf_cmd::light_for(&b.surface, b.quad, b.light[0], b.light[1]);
                run(r, &Job::Btf { surface: &b.prepared, camera: b.orbit.camera(), light })
            }
            Content::Store { meta, cache, flight, fov, per_side, stats } => {
                let key = hitex_core::terrain::path::PathKey {
                    t: 0.0,
                    x: flight.x,
                    y: flight.y,
                    altitude: flight.altitude,
                    // the key's pitch is below the horizon; the flight's from the nadir
                    pitch: 90.0 - flight.pitch,
                    heading: flight.heading,
                };
                let cam = crate::terrain_store_cmd::flight_area(meta).camera_at(&key, *fov);
                *per_side = hitex_core::terrain::active_area(*fov, w, hitex_io::gst::TILE, meta.levels.max(1))
                    .ok()
                    .and_then(|l| l.first().map(|l| l.per_side))
                    .unwrap_or(6);
                let mut start = Instant::now();
                let (s, u, pages) = crate::terrain_store_cmd::frame_setup(
                    cache,
                    meta,
                    &cam,
                    (w, h),
                    *fov,
                    *per_side,
                    false,
                    &mut start,
                );
                *stats = format!(
                    "maps: {} needed, {} resident ({:.1} MiB), {} requested, {} missing, {} failed",
                    s.needed,
                    s.resident,
                    s.bytes as f64 / (1u64 << 20) as f64,
                    s.requested,
                    s.missing,
                    s.failed
                );
                let job = Job::Flight {
                    uniform: u,
                    pages: std::borrow::Cow::Owned(pages),
                    ground: hitex_render::terrain::FlyGround::Flat,
                    stats: false,
                };
                run(r, &job)
            }
            Content::Ground { pyr, wrap, flight, mode, banks } => {
                let view = FlightView {
                    position: [flight.x * pyr.width() as f64, flight.y * pyr.height() as f64],
                    altitude: flight.altitude,
                    pitch_deg: 90.0 - flight.pitch,
                    heading_deg: flight.heading,
                    fov_deg: 45.0,
                    width: w,
                    height: h,
                };
                let (scheme, filter) = match mode {
                    FlySampler::Trilinear => {
                        banks.clear();
                        return Ok(Shown::Image(render_trilinear(pyr, &view, *wrap)));
                    }
                    FlySampler::Span3 => (SpanScheme::Banks3x3, SpanFilter::Bilinear),
                    FlySampler::Span4 => (SpanScheme::Banks4x4, SpanFilter::Bilinear),
                    FlySampler::Bicubic => (SpanScheme::Banks4x4, SpanFilter::Bicubic),
                };
                let opts = SpanOptions { scheme, filter, wrap: *wrap, level_shift: 0 };
                let mut model = BankModel::new(scheme);
                let f = render_spans(pyr, &view, &opts, &mut model);
                *banks = format!(
                    "{} spans, {} bank accesses, {} conflicts, mean λ {:.2}",
                    model.spans,
                    model.accesses,
                    model.conflicts,
                    model.mean_level()
                );
                Ok(Shown::Image(f))
            }
        }
    }

    /// Mouse and keys on the view; true when the view changed.
    fn interact(&mut self, resp: &egui::Response, i: &egui::InputState, height: f32) -> bool {
        let orbit = match self {
            Content::Scene { orbit, .. } | Content::Nurbs { orbit, .. } => Some(orbit),
            Content::Btf(b) => Some(&mut b.orbit),
            _ => None,
        };
        let d = resp.drag_delta();
        let scroll = if resp.hovered() { i.smooth_scroll_delta.y } else { 0.0 };
        if let Some(o) = orbit {
            let mut changed = false;
            if resp.dragged_by(egui::PointerButton::Primary) && d != egui::Vec2::ZERO {
                o.rotate(d.x, d.y);
                changed = true;
            }
            if (resp.dragged_by(egui::PointerButton::Secondary) || resp.dragged_by(egui::PointerButton::Middle))
                && d != egui::Vec2::ZERO
            {
                o.pan(d.x, d.y, height);
                changed = true;
            }
            if scroll != 0.0 {
                o.zoom(scroll / 50.0);
                changed = true;
            }
            return changed;
        }
        let (flight, extent) = match self {
            Content::Store { flight, meta, .. } => (flight, DVec2::new(meta.width as f64, meta.height as f64)),
            Content::Ground { flight, pyr, .. } => (flight, DVec2::new(pyr.width() as f64, pyr.height() as f64)),
            _ => return false,
        };
        let mut changed = flight.steer(i, extent);
        if resp.dragged_by(egui::PointerButton::Primary) && d != egui::Vec2::ZERO {
            flight.heading = (flight.heading + d.x as f64 * 0.2).rem_euclid(360.0);
            flight.pitch = (flight.pitch - d.y as f64 * 0.2).clamp(0.0, 85.0);
            changed = true;
        }
        if scroll != 0.0 {
            flight.altitude = (flight.altitude * (-scroll as f64 / 500.0).exp()).clamp(1e-3, 1e9);
            changed = true;
        }
        changed
    }

    /// The side panel's controls; true when the view must be redrawn.
    fn controls(&mut self, ui: &mut egui::Ui) -> Result<bool, CliError> {
        let mut changed = false;
        match self {
            Content::Scene { scene, prepared, .. } => {
                let before = scene.mode;
                mode_box(ui, &RenderMode::ALL.map(|(_, m)| m), RenderMode::name, &mut scene.mode);
                if scene.mode != before {
                    let camera = prepared.camera;
                    **prepared = PreparedScene::new(scene);
                    prepared.camera = camera;
                    changed = true;
                }
                ui.label(format!("{} triangles", prepared.triangle_count()));
                if let Some(n) = &prepared.nurbs {
                    ui.label(format!("{} NURBS patches", n.patch_count()));
                }
            }
            Content::Nurbs { prepared, light, light_moved, .. } => {
                let before = prepared.mode;
                mode_box(ui, &NURBS_MODES, NurbsMode::name, &mut prepared.mode);
                changed |= prepared.mode != before;
                changed |= ui.checkbox(&mut prepared.boundaries, "patch boundaries").changed();
                changed |= ui.add(egui::Slider::new(&mut prepared.bands, 2..=60).text("isophote bands")).changed();
                changed |= ui.add(egui::Slider::new(&mut prepared.stripes, 2..=60).text("zebra stripes")).changed();
                if light_sliders(ui, light) {
                    *light_moved = true;
                    changed = true;
                }
                ui.label(format!("{} patches, exact point and normal per pixel", prepared.surfaces.len()));
            }
            Content::Btf(b) => {
                let (layout, bc1) = (b.layout, b.bc1);
                egui::ComboBox::from_label("layout").selected_text(b.layout.label()).show_ui(ui, |ui| {
                    for l in LAYOUTS {
                        ui.selectable_value(&mut b.layout, l, l.label());
                    }
                });
                if let Some(p) = &b.pca {
                    // the basis is half floats, which BC1 cannot hold
                    b.bc1 = false;
                    ui.label(format!(
                        "local PCA {}×{} (1:{:.1}), drawn from the basis",
                        p.clusters(),
                        p.components(),
                        p.ratio()
                    ));
                } else if b.btf.is_hdr() {
                    // BC1 holds 8-bit colours only
                    b.bc1 = false;
                    ui.label("HDR texels (half floats), ACES tone map");
                } else {
                    ui.checkbox(&mut b.bc1, "BC1 (DXT1)");
                }
                if (layout, bc1) != (b.layout, b.bc1) {
                    let enc = b.bc1.then_some(Bc1Encoder::Ispc);
                    let tone = b.prepared.tone_map;
                    b.prepared = match &b.pca {
                        Some(p) => PreparedBtf::with_pca(p, b.layout, b.map.clone(), b.surface.clone())?,
                        None => PreparedBtf::new(&b.btf, b.layout, enc, b.map.clone(), b.surface.clone())?,
                    };
                    b.prepared.tone_map = tone;
                    changed = true;
                }
                changed |= light_sliders(ui, &mut b.light);
                let reads = b.layout.codebook_reads() as usize;
                ui.label(match &b.pca {
                    Some(p) => format!(
                        "{} codebook reads per cluster among the 4 index texels + 4 index reads per pixel",
                        reads * (p.components() as usize + 1) / 4
                    ),
                    None => format!("{reads} codebook reads + 4 index reads per pixel"),
                });
                ui.label(format!(
                    "{} images of {}x{} texels",
                    b.btf.grid().directions().pow(2),
                    b.btf.width(),
                    b.btf.height()
                ));
            }
            Content::Store { stats, flight, .. } => {
                ui.label("per-pixel trilinear through the resident maps");
                ui.label(stats.as_str());
                flight_label(ui, flight);
            }
            Content::Ground { mode, banks, flight, .. } => {
                let before = *mode;
                mode_box(ui, &FlySampler::ALL, FlySampler::name, mode);
                changed |= *mode != before;
                if !banks.is_empty() {
                    ui.label(banks.as_str());
                }
                flight_label(ui, flight);
            }
        }
        Ok(changed)
    }

    /// Maps still loading: keep redrawing until they are in.
    fn settling(&self) -> bool {
        matches!(self, Content::Store { stats, .. } if !stats.contains(" 0 missing"))
    }
}

fn mode_box<T: Copy + PartialEq>(ui: &mut egui::Ui, list: &[T], name_of: impl Fn(T) -> &'static str, value: &mut T) {
    egui::ComboBox::from_label("mode").selected_text(name_of(*value)).show_ui(ui, |ui| {
        for &m in list {
            ui.selectable_value(value, m, name_of(m));
        }
    });
}

fn light_sliders(ui: &mut egui::Ui, light: &mut [f32; 2]) -> bool {
    let a = ui.add(egui::Slider::new(&mut light[0], 0.0..=360.0).text("light azimuth °")).changed();
    let e = ui.add(egui::Slider::new(&mut light[1], 5.0..=90.0).text("light elevation °")).changed();
    a || e
}

fn flight_label(ui: &mut egui::Ui, f: &Flight) {
    ui.label(format!(
        "x {:.3}, y {:.3}, altitude {:.0}, pitch {:.0}° below the horizon, heading {:.0}°",
        f.x,
        f.y,
        f.altitude,
        90.0 - f.pitch,
        f.heading
    ));
    ui.label("W/S A/D fly, Q/E down/up, arrows or drag turn and tilt, wheel altitude");
}

/// What a render gave the window.
enum Shown {
    /// An image to upload (the CPU's, or a GPU's read back).
    Image(Frame),
    /// The view drawn into the window's texture on the GPU ([`GpuView`]).
    InTexture,
}

/// The view drawn on the window's own GPU device: a texture of the view's
/// size that the renderer draws into and egui shows as it is, with no
/// read-back and no upload.
struct GpuView {
    state: egui_wgpu::RenderState,
    texture: Option<(wgpu::Texture, egui::TextureId)>,
}

impl GpuView {
    /// The texture for a `w`×`h` view (made, or remade at a new size, and
    /// registered with egui); `None` beyond the device's texture limit (the
    /// render then refuses the size by name, through the read-back path).
    fn texture_for(&mut self, w: u32, h: u32) -> Option<&wgpu::Texture> {
        let max = self.state.device.limits().max_texture_dimension_2d;
        if w > max || h > max {
            return None;
        }
        let fits = self.texture.as_ref().is_some_and(|(t, _)| (t.width(), t.height()) == (w, h));
        if !fits {
            let device = &self.state.device;
            let t = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("hitex view"),
                size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            });
            let view = t.create_view(&Default::default());
            let mut egui_renderer = self.state.renderer.write();
            let id = match self.texture.take() {
                Some((_, id)) => {
                    egui_renderer.update_egui_texture_from_wgpu_texture(device, &view, wgpu::FilterMode::Nearest, id);
                    id
                }
                None => egui_renderer.register_native_texture(device, &view, wgpu::FilterMode::Nearest),
            };
            self.texture = Some((t, id));
        }
        self.texture.as_ref().map(|(t, _)| t)
    }
}

struct ViewApp {
    content: Content,
    renderer: AnyRenderer,
    /// The window's device, when the GPU renderer draws on it.
    gpu: Option<GpuView>,
    /// The texture shown: egui's copy of an image, or the GPU's own.
    shown: Option<egui::TextureId>,
    /// The size of the view last drawn.
    drawn: Option<(u32, u32)>,
    size: Option<(u32, u32)>,
    texture: Option<egui::TextureHandle>,
    /// The last image (none when the GPU drew into its texture).
    last: Option<Frame>,
    /// Whether the view shown was drawn into the window's texture.
    in_texture: bool,
    dirty: bool,
    frame_ms: f64,
    frames: u32,
    screenshot: Option<(PathBuf, u32)>,
    window_screenshot: Option<(PathBuf, u32)>,
    shots: u32,
    status: String,
    failure: std::sync::Arc<std::sync::Mutex<Option<CliError>>>,
}

impl ViewApp {
    fn shoot(&mut self, path: &Path) {
        // a view drawn on the GPU is read back for its screenshot
        if self.last.is_none()
            && let Some((w, h)) = self.drawn
        {
            match self.content.render(&mut self.renderer, w, h, None) {
                Ok(Shown::Image(f)) => self.last = Some(f),
                Ok(Shown::InTexture) => {}
                Err(e) => {
                    self.status = format!("screenshot failed: {e}");
                    return;
                }
            }
        }
        self.status = match &self.last {
            Some(f) => match save(f, path) {
                Ok(()) => format!("wrote {} ({}x{})", path.display(), f.width, f.height),
                Err(CliError::Input(e) | CliError::Internal(e) | CliError::Check(e) | CliError::Unavailable(e)) => {
                    format!("screenshot failed: {e}")
                }
            },
            None => "nothing rendered yet".into(),
        };
    }

    fn fail(&mut self, ctx: &egui::Context, e: CliError) {
        if let Ok(mut f) = self.failure.lock() {
            f.get_or_insert(e);
        }
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }
}

impl eframe::App for ViewApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        let mut controls_changed = Ok(false);
        egui::Panel::left("controls").resizable(false).default_size(300.0).show(ui, |ui| {
            ui.heading(format!("hitex view: {}", self.content.kind()));
            let backend = match self.content {
                Content::Ground { mode: FlySampler::Trilinear, .. } => "cpu (reference sampler)".to_string(),
                Content::Ground { .. } => "cpu (emulated bank memory)".to_string(),
                _ => self.renderer.name(),
            };
            ui.label(format!("backend: {backend}"));
            if self.in_texture {
                // render_into returns once the frame is submitted; the window shows it when drawn
                ui.label(format!("frame: {:.1} ms to submit ({} rendered)", self.frame_ms, self.frames));
                ui.label("drawn into the window's texture on the GPU, no read-back");
            } else {
                ui.label(format!("frame: {:.1} ms ({} rendered)", self.frame_ms, self.frames));
            }
            ui.separator();
            controls_changed = self.content.controls(ui);
            ui.separator();
            ui.label("drag: orbit (left), pan (right); wheel: zoom; P or F12: view screenshot; F11: window screenshot");
            if !self.status.is_empty() {
                ui.label(self.status.as_str());
            }
        });
        match controls_changed {
            Ok(c) => self.dirty |= c,
            Err(e) => return self.fail(&ctx, e),
        }
        egui::CentralPanel::default().show(ui, |ui| {
            // the view area, never more than the window (egui's first layout pass may know no size yet)
            let avail = ui.available_size().min(ctx.content_rect().size()).max(egui::vec2(16.0, 16.0));
            let ppp = ctx.pixels_per_point();
            let (w, h) = self.size.unwrap_or((
                ((avail.x * ppp) as u32).clamp(16, hitex_core::scene::desc::MAX_OUTPUT_SIDE),
                ((avail.y * ppp) as u32).clamp(16, hitex_core::scene::desc::MAX_OUTPUT_SIDE),
            ));
            let stale = self.drawn != Some((w, h));
            let scripted = self.screenshot.is_some() || self.window_screenshot.is_some();
            if self.dirty || stale || self.content.settling() || scripted {
                let t = Instant::now();
                let into = match (&mut self.gpu, self.renderer.is_gpu()) {
                    (Some(g), true) => g.texture_for(w, h),
                    _ => None,
                };
                match self.content.render(&mut self.renderer, w, h, into) {
                    Ok(shown) => {
                        self.frame_ms = t.elapsed().as_secs_f64() * 1e3;
                        self.frames += 1;
                        self.drawn = Some((w, h));
                        self.dirty = false;
                        match shown {
                            Shown::Image(f) => {
                                let img = egui::ColorImage::from_rgba_unmultiplied([w as usize, h as usize], &f.rgba);
                                let tex = match &mut self.texture {
                                    Some(tex) => {
                                        tex.set(img, egui::TextureOptions::NEAREST);
                                        tex
                                    }
                                    None => self.texture.insert(ctx.load_texture(
                                        "view",
                                        img,
                                        egui::TextureOptions::NEAREST,
                                    )),
                                };
                                self.shown = Some(tex.id());
                                self.last = Some(f);
                                self.in_texture = false;
                            }
                            Shown::InTexture => {
                                if self.frames == 1 {
                                    say!("view: drawn into the window's texture on the GPU, no read-back");
                                }
                                self.shown = self.gpu.as_ref().and_then(|g| g.texture.as_ref().map(|(_, id)| *id));
                                self.last = None;
                                self.in_texture = true;
                            }
                        }
                    }
                    Err(e) => return self.fail(&ctx, e),
                }
            }
            if let Some(id) = self.shown {
                let shown = egui::vec2(w as f32 / ppp, h as f32 / ppp);
                let fit = (avail.x / shown.x).min(avail.y / shown.y).min(1.0);
                let tex = egui::load::SizedTexture::new(id, shown);
                let img =
                    egui::Image::from_texture(tex).fit_to_exact_size(shown * fit).sense(egui::Sense::click_and_drag());
                let resp = ui.add(img);
                let moved = ctx.input(|i| self.content.interact(&resp, i, h as f32));
                self.dirty |= moved;
            }
        });
        if ctx.input(|i| i.key_pressed(egui::Key::F12) || i.key_pressed(egui::Key::P)) {
            self.shots += 1;
            let path = PathBuf::from(format!("hitex-view-{:04}.png", self.shots));
            self.shoot(&path);
        }
        if ctx.input(|i| i.key_pressed(egui::Key::F11)) {
            self.shots += 1;
            let path = PathBuf::from(format!("hitex-window-{:04}.png", self.shots));
            self.status = format!("wrote {}", path.display());
            window_shot(&ctx, path, false);
        }
        if let Some((path, after)) = self.screenshot.clone()
            && self.frames >= after
        {
            self.shoot(&path);
            say!("{}", self.status);
            self.screenshot = None;
            if self.window_screenshot.is_none() {
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
        if let Some((path, after)) = self.window_screenshot.clone()
            && self.frames >= after
        {
            // the next frame is captured; the callback closes the window
            self.window_screenshot = None;
            window_shot(&ctx, path, true);
        }
        if self.dirty || self.content.settling() || self.screenshot.is_some() || self.window_screenshot.is_some() {
            ctx.request_repaint();
        } else if matches!(self.content, Content::Store { .. } | Content::Ground { .. }) {
            // keys held for flying arrive as state, not events
            ctx.request_repaint_after(std::time::Duration::from_millis(16));
        }
    }
}

/// Captures the whole window on the next frame and writes it to `path`.
fn window_shot(ctx: &egui::Context, path: PathBuf, then_close: bool) {
    let c = ctx.clone();
    ctx.request_screenshot(move |img| {
        let rgba: Vec<u8> = img.pixels.iter().flat_map(|p| p.to_array()).collect();
        match hitex_io::save_png(&path, img.size[0] as u32, img.size[1] as u32, &rgba) {
            Ok(()) => say!("wrote {} ({}x{}, the window)", path.display(), img.size[0], img.size[1]),
            Err(e) => eprintln!("hitex: window screenshot failed: {e}"),
        }
        if then_close {
            c.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    });
    ctx.request_repaint();
}

/// Why no window can be opened, and what to use instead.
fn no_window(why: &str) -> CliError {
    CliError::Unavailable(format!(
        "{why}. Without a window, render headless: hitex render, hitex nurbs render, hitex btf render, \
         hitex terrain fly or hitex terrain spans (with --backend cpu where there is no GPU)"
    ))
}

/// `hitex view`.
pub fn run(a: ViewArgs) -> Result<(), CliError> {
    if a.frames == 0 || a.frames > 100_000 {
        return Err(CliError::Input("--frames must be in 1 to 100000".into()));
    }
    let aspect = a.size.map_or(a.window.0 as f32 / a.window.1 as f32, |(w, h)| w as f32 / h as f32);
    // the input is checked before any window opens
    let content = open(&a.input, a.mode.as_deref(), aspect)?;
    if std::env::var_os("DISPLAY").is_none_or(|d| d.is_empty()) {
        return Err(no_window("no display: DISPLAY is not set (hitex view opens an X11 window)"));
    }
    // the CPU renderer opens now; a GPU one on the window's own device once it is open
    let renderer = open_renderer(Backend::Cpu)?;
    let failure = std::sync::Arc::new(std::sync::Mutex::new(None));
    let mut app = ViewApp {
        content,
        renderer,
        gpu: None,
        shown: None,
        drawn: None,
        in_texture: false,
        size: a.size,
        texture: None,
        last: None,
        dirty: true,
        frame_ms: 0.0,
        frames: 0,
        screenshot: a.screenshot.clone().map(|p| (p, a.frames)),
        window_screenshot: a.window_screenshot.clone().map(|p| (p, a.frames)),
        shots: 0,
        status: String::new(),
        failure: failure.clone(),
    };
    // the window's device asks for what hitex draws with (BC layouts, float filtering, the adapter's limits)
    let mut setup = egui_wgpu::WgpuSetupCreateNew::without_display_handle();
    setup.device_descriptor = std::sync::Arc::new(hitex_render::gpu::device::device_descriptor);
    let wgpu_options =
        egui_wgpu::WgpuConfiguration { wgpu_setup: egui_wgpu::WgpuSetup::CreateNew(setup), ..Default::default() };
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(format!("hitex view {}", a.input))
            .with_inner_size([a.window.0 as f32, a.window.1 as f32]),
        wgpu_options,
        ..Default::default()
    };
    let backend = a.backend;
    let opened = failure.clone();
    let run = eframe::run_native(
        "hitex",
        options,
        Box::new(move |cc| {
            if backend != Backend::Cpu {
                // the GPU renderer on the window's device, drawing into a texture egui shows;
                // without the window's device, one of its own (read back), as also under the
                // fault switch, which must not destroy the device the window draws with
                let options = crate::open_options();
                let renderer = match cc.wgpu_render_state.as_ref().filter(|_| !options.lose_device) {
                    Some(rs) => {
                        let (ad, dev, q) = (rs.adapter.clone(), rs.device.clone(), rs.queue.clone());
                        let r = AnyRenderer::on_device(backend, options, ad, dev, q)
                            .map_err(|e| CliError::Internal(e.to_string()));
                        app.gpu = Some(GpuView { state: rs.clone(), texture: None });
                        r.map(|mut r| {
                            r.on_notice(|n| eprintln!("hitex: {n}"));
                            r
                        })
                    }
                    None => open_renderer(backend),
                };
                match renderer {
                    Ok(r) => app.renderer = r,
                    Err(e) => {
                        let msg = e.to_string();
                        if let Ok(mut f) = opened.lock() {
                            f.get_or_insert(e);
                        }
                        return Err(msg.into());
                    }
                }
            }
            Ok(Box::new(app))
        }),
    );
    if let Some(e) = failure.lock().ok().and_then(|mut f| f.take()) {
        return Err(e);
    }
    run.map_err(|e| {
        no_window(&format!(
            "cannot open a window ({e}): it needs X11 and a wgpu adapter (a GPU, or Mesa's lavapipe: \
                 apt-get install mesa-vulkan-drivers libvulkan1)"
        ))
    })
}
