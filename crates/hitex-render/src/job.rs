//! One render API for both backends: a [`Job`] says what to draw, a
//! [`Renderer`] draws it.
//!
//! ```no_run
//! use hitex_render::{AnyRenderer, BackendChoice, Job, Renderer};
//! # fn f(model: &hitex_render::nurbs::PreparedNurbs, camera: hitex_core::scene::Camera) -> Result<(), hitex_render::RenderError> {
//! let mut r = AnyRenderer::open(BackendChoice::Auto)?;
//! let out = r.render(&Job::Nurbs { model, camera }, 512, 512)?;
//! assert_eq!(out.frame.rgba.len(), 512 * 512 * 4);
//! # Ok(()) }
//! ```
//!
//! [`CpuRenderer`], [`GpuRenderer`] and [`AnyRenderer`] (the GPU with the
//! CPU taking over when the GPU fails) all implement [`Renderer`], so one
//! loop serves every content on every backend. On an application's own
//! wgpu device ([`AnyRenderer::on_device`]) a job can also be drawn into
//! the application's texture with no read-back ([`AnyRenderer::render_into`],
//! [`GpuRenderer::render_into`]), as `hitex view` shows its frames.

use crate::btf::PreparedBtf;
use crate::cpu::CpuRenderer;
use crate::gpu::{GpuError, GpuRenderer};
use crate::nurbs::PreparedNurbs;
use crate::prepare::PreparedScene;
use crate::terrain::{FlyGround, FlyPages, FlyUniform};
use crate::{Frame, RenderError};
use hitex_core::scene::Camera;
use hitex_core::texture::span::BankModel;
use std::borrow::Cow;

/// What to render: one of the pillars' prepared contents and its view.
// a flight's uniform (matrices and sizes, ~200 bytes) is held by value: a
// job lives on the stack for one frame, and no other variant is copied often
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum Job<'a> {
    /// A textured scene (and the NURBS model it may hold).
    Scene {
        /// The prepared scene.
        scene: &'a PreparedScene,
        /// The view.
        camera: Camera,
    },
    /// A NURBS model, exact per pixel.
    Nurbs {
        /// The prepared model.
        model: &'a PreparedNurbs,
        /// The view.
        camera: Camera,
    },
    /// A BTF surface lit by a point light.
    Btf {
        /// The prepared surface.
        surface: &'a PreparedBtf,
        /// The view.
        camera: Camera,
        /// The light's position (world units).
        light: glam::Vec3,
    },
    /// One flight frame over resident terrain maps. The uniform's size must
    /// be the size asked of the render.
    Flight {
        /// Camera, sampler and sizes.
        uniform: FlyUniform,
        /// The page table of resident maps (a frame's own, or borrowed).
        pages: Cow<'a, FlyPages>,
        /// Flat ground or a mesh.
        ground: FlyGround<'a>,
        /// Record the span sampler's bank traffic (CPU backend only; costs time).
        stats: bool,
    },
}

impl Job<'_> {
    /// "scene", "NURBS model", "BTF" or "flight".
    pub fn kind(&self) -> &'static str {
        match self {
            Job::Scene { .. } => "scene",
            Job::Nurbs { .. } => "NURBS model",
            Job::Btf { .. } => "BTF",
            Job::Flight { .. } => "flight",
        }
    }

    /// The SIMD level the CPU backend runs this job's fragment program at:
    /// the process's level ([`crate::cpu::simd::level`]), or for the
    /// gather-bound textured program [`crate::cpu::simd::level_for_gathers`].
    pub fn cpu_simd_level(&self) -> crate::cpu::simd::SimdLevel {
        use crate::cpu::simd::{level, level_for_gathers};
        match self {
            Job::Scene { .. } => level_for_gathers(),
            _ => level(),
        }
    }

    fn check_flight_size(&self, width: u32, height: u32) -> Result<(), RenderError> {
        if let Job::Flight { uniform, .. } = self
            && (uniform.sizes[0], uniform.sizes[1]) != (width, height)
        {
            return Err(RenderError::Invalid(format!(
                "the flight uniform is for {}x{}, the render asks {width}x{height}",
                uniform.sizes[0], uniform.sizes[1]
            )));
        }
        Ok(())
    }
}

/// A rendered job: the image and what the backend measured on the way.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The image.
    pub frame: Frame,
    /// Span accesses and bank conflicts of a flight's span sampler, when
    /// asked for (`stats`) and the backend records them (the CPU's).
    pub banks: Option<BankModel>,
}

impl From<Frame> for Rendered {
    fn from(frame: Frame) -> Self {
        Self { frame, banks: None }
    }
}

/// A backend: renders any [`Job`].
pub trait Renderer {
    /// Human-readable name ("cpu (2 threads, avx512)", "gpu: llvmpipe (Vulkan)").
    fn name(&self) -> String;
    /// Renders `job` at `width`×`height`.
    fn render(&mut self, job: &Job<'_>, width: u32, height: u32) -> Result<Rendered, RenderError>;
}

impl Renderer for CpuRenderer {
    fn name(&self) -> String {
        format!("cpu ({} threads, {})", rayon::current_num_threads(), crate::cpu::simd::level())
    }
    fn render(&mut self, job: &Job<'_>, width: u32, height: u32) -> Result<Rendered, RenderError> {
        job.check_flight_size(width, height)?;
        Ok(match job {
            Job::Scene { scene, camera } => self.render_view(scene, camera, width, height)?.into(),
            Job::Nurbs { model, camera } => self.render_nurbs(model, camera, width, height)?.into(),
            Job::Btf { surface, camera, light } => self.render_btf(surface, camera, *light, width, height)?.into(),
            Job::Flight { uniform, pages, ground, stats } => {
                crate::check_size(width, height)?;
                let f = crate::cpu::terrain::render_fly_with(uniform, pages, *ground, *stats)?;
                Rendered { frame: f.frame, banks: f.banks }
            }
        })
    }
}

impl Renderer for GpuRenderer {
    fn name(&self) -> String {
        format!("gpu: {}", self.adapter())
    }
    fn render(&mut self, job: &Job<'_>, width: u32, height: u32) -> Result<Rendered, RenderError> {
        job.check_flight_size(width, height)?;
        Ok(match job {
            Job::Scene { scene, camera } => self.render_view(scene, camera, width, height)?,
            Job::Nurbs { model, camera } => self.render_nurbs(model, camera, width, height)?,
            Job::Btf { surface, camera, light } => self.render_btf(surface, camera, *light, width, height)?,
            Job::Flight { uniform, pages, ground, .. } => self.render_fly(uniform, pages, *ground)?,
        }
        .into())
    }
}

/// Which backend renders (on the command line `auto`, `cpu`, `gpu`; with
/// the `clap` feature, `clap::ValueEnum` derives these names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum BackendChoice {
    /// A hardware GPU if there is one, else the CPU backend (a software
    /// rasterizer is slower than the CPU backend; see [`OpenOptions`]).
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "A hardware GPU if there is one, else the CPU backend (faster than a software GPU).")
    )]
    Auto,
    /// The CPU backend.
    #[cfg_attr(feature = "clap", value(help = "The CPU backend."))]
    Cpu,
    /// wgpu on the best adapter, a software one too; an error if none exists.
    #[cfg_attr(feature = "clap", value(help = "wgpu on the best adapter, a software one (lavapipe) too."))]
    Gpu,
}

/// How [`AnyRenderer::open_with`] chooses and opens a backend.
#[derive(Debug, Clone, Copy, Default)]
pub struct OpenOptions {
    /// Let `auto` take a software GPU adapter (lavapipe, llvmpipe) too.
    pub software_for_auto: bool,
    /// Destroy the GPU device right after it opens, as a driver reset would:
    /// for testing the fallback paths.
    pub lose_device: bool,
}

/// Where [`AnyRenderer`] sends its notices.
type NoticeSink = Box<dyn FnMut(&str) + Send>;

/// One of the two backends.
pub enum Engine {
    /// The CPU backend.
    Cpu(CpuRenderer),
    /// The wgpu backend.
    Gpu(Box<GpuRenderer>),
}

/// The renderer an application opens: the backend asked for, and under
/// `auto` the CPU backend taking over for good when the GPU fails (no
/// adapter, device lost, out of memory, hang). Nothing is printed: what
/// happened is kept as notices ([`AnyRenderer::take_notices`]) or handed
/// to a callback ([`AnyRenderer::on_notice`]).
pub struct AnyRenderer {
    engine: Engine,
    auto: bool,
    /// Why `auto` chose the CPU backend, said in the name.
    why_cpu: Option<String>,
    notices: Vec<String>,
    sink: Option<NoticeSink>,
}

impl std::fmt::Debug for AnyRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AnyRenderer").field("name", &self.name()).finish()
    }
}

impl AnyRenderer {
    /// Opens the backend `choice` names with default options.
    pub fn open(choice: BackendChoice) -> Result<Self, GpuError> {
        Self::open_with(choice, OpenOptions::default())
    }

    /// Opens the backend `choice` names. Only `Gpu` can fail (no adapter,
    /// no device); `auto` falls back to the CPU backend with a notice.
    pub fn open_with(choice: BackendChoice, options: OpenOptions) -> Result<Self, GpuError> {
        let software_ok = choice != BackendChoice::Auto || options.software_for_auto;
        let gpu = || -> Result<GpuRenderer, GpuError> {
            let g = if software_ok { GpuRenderer::new()? } else { GpuRenderer::hardware()? };
            if options.lose_device {
                g.context().lose_device();
            }
            Ok(g)
        };
        let mut r =
            Self { engine: Engine::Cpu(CpuRenderer::new()), auto: false, why_cpu: None, notices: vec![], sink: None };
        match choice {
            BackendChoice::Cpu => {}
            BackendChoice::Gpu => r.engine = Engine::Gpu(Box::new(gpu()?)),
            BackendChoice::Auto => {
                r.auto = true;
                match gpu() {
                    Ok(g) => r.engine = Engine::Gpu(Box::new(g)),
                    // said in the name, which callers print anyway
                    Err(GpuError::SoftwareOnly(_)) => {
                        r.why_cpu = Some("auto: no hardware GPU, and the software one is slower".into())
                    }
                    Err(e) => r.notices.push(format!(
                        "GPU backend unavailable ({}); falling back to the CPU backend",
                        first_line(&e.to_string())
                    )),
                }
            }
        }
        Ok(r)
    }

    /// The renderer `choice` names on an application's own device (see
    /// [`GpuRenderer::on_device`]): `Cpu` the CPU backend; `Gpu` the device;
    /// `Auto` the device if it is a hardware GPU (or a software one with
    /// [`OpenOptions::software_for_auto`]), else the CPU backend, said in the
    /// name; under `auto`, as [`AnyRenderer::open_with`] does, a renderer that
    /// cannot be built on the device leaves the CPU with a notice, and the CPU
    /// takes over when a render fails. On a device hitex does not own, the
    /// failures seen are those a render reports (validation, out of memory, a
    /// lost device); [`OpenOptions::lose_device`] destroys the application's
    /// device.
    pub fn on_device(
        choice: BackendChoice,
        options: OpenOptions,
        adapter: wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
    ) -> Result<Self, GpuError> {
        let mut r =
            Self { engine: Engine::Cpu(CpuRenderer::new()), auto: false, why_cpu: None, notices: vec![], sink: None };
        let software = !crate::gpu::device::is_hardware(&adapter.get_info());
        match choice {
            BackendChoice::Cpu => {}
            BackendChoice::Auto if software && !options.software_for_auto => {
                r.auto = true;
                r.why_cpu = Some("auto: no hardware GPU, and the software one is slower".into());
            }
            _ => {
                r.auto = choice == BackendChoice::Auto;
                match GpuRenderer::on_device(adapter, device, queue) {
                    Ok(g) => {
                        if options.lose_device {
                            g.context().lose_device();
                        }
                        r.engine = Engine::Gpu(Box::new(g));
                    }
                    // auto: the CPU, said once, as `open_with` does
                    Err(e) if r.auto => r.notices.push(format!(
                        "GPU backend unavailable ({}); falling back to the CPU backend",
                        first_line(&e.to_string())
                    )),
                    Err(e) => return Err(e),
                }
            }
        }
        Ok(r)
    }

    /// Renders `job` into `target`, a texture on the device of the GPU in use
    /// ([`GpuRenderer::render_into`]): `Ok(None)` when drawn there, with no
    /// read-back. On the CPU backend (or when the render reports a GPU
    /// failure under `auto`, the CPU then taking over for good) the image is
    /// rendered on the CPU and returned instead, for the application to show
    /// as it shows any image. The call returns once the frame is submitted: a
    /// GPU that hangs afterwards is not seen here.
    pub fn render_into(&mut self, job: &Job<'_>, target: &wgpu::Texture) -> Result<Option<Rendered>, RenderError> {
        let (w, h) = (target.width(), target.height());
        let Engine::Gpu(g) = &mut self.engine else {
            return self.render(job, w, h).map(Some);
        };
        let r = g.render_into(job, target);
        for e in g.context().take_uncaptured() {
            self.notice(format!("GPU error: {e}"));
        }
        match r {
            Ok(()) => Ok(None),
            Err(RenderError::Gpu(e)) if self.auto => {
                self.notice(format!(
                    "GPU backend failed ({}); continuing on the CPU backend",
                    first_line(&e.to_string())
                ));
                let mut cpu = CpuRenderer::new();
                let out = cpu.render(job, w, h);
                self.engine = Engine::Cpu(cpu);
                out.map(Some)
            }
            Err(e) => Err(e),
        }
    }

    /// Sends every notice, those already kept first, to `sink` from now on
    /// (e.g. a line on stderr) instead of keeping them.
    pub fn on_notice(&mut self, mut sink: impl FnMut(&str) + Send + 'static) {
        for n in self.notices.drain(..) {
            sink(&n);
        }
        self.sink = Some(Box::new(sink));
    }

    /// The notices kept so far (a GPU that failed, the CPU taking over).
    pub fn take_notices(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notices)
    }

    /// The backend in use.
    pub fn engine(&self) -> &Engine {
        &self.engine
    }

    /// The backend in use, mutable (e.g. the GPU's context).
    pub fn engine_mut(&mut self) -> &mut Engine {
        &mut self.engine
    }

    /// True when the GPU backend renders.
    pub fn is_gpu(&self) -> bool {
        matches!(self.engine, Engine::Gpu(_))
    }

    fn notice(&mut self, n: String) {
        match &mut self.sink {
            Some(s) => s(&n),
            None => self.notices.push(n),
        }
    }
}

impl Renderer for AnyRenderer {
    /// The backend's name, with why `auto` chose the CPU where that is not obvious.
    fn name(&self) -> String {
        let name = match &self.engine {
            Engine::Cpu(c) => c.name(),
            Engine::Gpu(g) => g.name(),
        };
        match (&self.why_cpu, &self.engine) {
            (Some(n), Engine::Cpu(_)) => format!("{name}; {n}"),
            _ => name,
        }
    }

    /// Renders on the backend in use; a GPU failure under `auto` moves this
    /// renderer to the CPU for good and renders the job again there.
    fn render(&mut self, job: &Job<'_>, width: u32, height: u32) -> Result<Rendered, RenderError> {
        let first = match &mut self.engine {
            Engine::Cpu(c) => c.render(job, width, height),
            Engine::Gpu(g) => {
                let r = g.render(job, width, height);
                for e in g.context().take_uncaptured() {
                    self.notice(format!("GPU error: {e}"));
                }
                r
            }
        };
        match first {
            Err(RenderError::Gpu(e)) if self.auto => {
                self.notice(format!(
                    "GPU backend failed ({}); continuing on the CPU backend",
                    first_line(&e.to_string())
                ));
                let mut cpu = CpuRenderer::new();
                let r = cpu.render(job, width, height);
                self.engine = Engine::Cpu(cpu);
                r
            }
            r => r,
        }
    }
}

fn first_line(s: &str) -> &str {
    s.lines().next().unwrap_or_default()
}
