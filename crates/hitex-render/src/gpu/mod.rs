//! The wgpu backend: headless render to an offscreen target and readback.
//! Runs `shaders/textured.wgsl`, the twin of `cpu/textured.rs`.

mod btf;
pub mod device;
mod nurbs;
mod plumbing;
mod terrain;

/// The shaders' sources (a BTF layout's: [`layout_source`]).
pub use btf::{BTF_WGSL, bc1_3d_trusted, layout_source};
pub use nurbs::{NURBS_WGSL, nurbs_source};
pub use terrain::{TERRAIN_WGSL, terrain_source};

pub use device::{GpuContext, adapters_report};

use crate::prepare::{AtlasLayout, MAX_ATLAS_LEVELS, MaterialUniform, PreparedScene, Vertex, background_rgba8};
use crate::{Frame, RenderError, check_size};
use hitex_core::scene::Camera;
use hitex_core::texture::{ColorSpace, MipPyramid};
use plumbing::{
    PipelineScope, UploadScope, check_2d, mesh_buffers, sampled_texture, texture_entry, uniform_buffer, uniform_entry,
    write_texels,
};
use std::sync::Arc;
use thiserror::Error;
use wgpu::util::DeviceExt;

/// GPU failures.
#[derive(Debug, Error)]
pub enum GpuError {
    /// No adapter at all.
    #[error("no GPU adapter found (install Mesa's lavapipe: apt-get install mesa-vulkan-drivers libvulkan1)")]
    NoAdapter,
    /// Only a software rasterizer was found, and hardware was asked for.
    #[error("no hardware GPU: the only adapter is the software rasterizer {0}")]
    SoftwareOnly(String),
    /// The adapter refused a device.
    #[error("cannot open a GPU device: {0}")]
    Device(String),
    /// wgpu reported a validation or out-of-memory error during a render.
    #[error("GPU error during rendering: {0}")]
    Render(String),
    /// The output could not be read back.
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// The device was lost (driver reset, GPU removed, or destroyed).
    #[error("the GPU device was lost ({0})")]
    Lost(String),
    /// The GPU did not finish within the time allowed.
    #[error("the GPU did not finish within {0:.0} s (HITEX_GPU_TIMEOUT); it may hang")]
    Timeout(f64),
}

/// A render pipeline of the one shape hitex draws with: `vs_main` and
/// `fs_main` of `module`, one vertex buffer of `stride` bytes with
/// `attributes`, no culling, depth test and write (`Depth32Float`, less),
/// one RGBA8 target.
pub(crate) fn mesh_pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    groups: &[&wgpu::BindGroupLayout],
    stride: u64,
    attributes: &[wgpu::VertexAttribute],
) -> wgpu::RenderPipeline {
    let groups: Vec<Option<&wgpu::BindGroupLayout>> = groups.iter().map(|g| Some(*g)).collect();
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &groups,
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: stride,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes,
            })],
        },
        primitive: wgpu::PrimitiveState { cull_mode: None, ..Default::default() },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: wgpu::TextureFormat::Rgba8Unorm,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Creates a shader module from WGSL without naga's injected bounds checks.
///
/// # Safety
/// Every index the shader computes must be in range by construction (the
/// shaders of hitex wrap or clamp every texel, level and array index).
pub(crate) unsafe fn trusted_module(device: &wgpu::Device, label: &str, source: &str) -> wgpu::ShaderModule {
    let mut checks = wgpu::ShaderRuntimeChecks::checked();
    checks.bounds_checks = false;
    // SAFETY: forwarded to the caller
    unsafe {
        device.create_shader_module_trusted(
            wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) },
            checks,
        )
    }
}

/// The textured-mesh shader source, before the codes' constants are
/// prepended ([`textured_source`]).
pub const TEXTURED_WGSL: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/textured.wgsl"));

/// The textured-mesh shader as compiled: the codes' constants
/// ([`crate::codes::wgsl_constants`]) before [`TEXTURED_WGSL`].
pub fn textured_source() -> String {
    format!("{}{TEXTURED_WGSL}", crate::codes::wgsl_constants())
}

/// A textured scene on the device: its mesh and one bind group per material.
struct UploadedScene {
    key: u64,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    material_groups: Vec<wgpu::BindGroup>,
    _textures: Vec<wgpu::Texture>,
}

struct TargetSet {
    width: u32,
    height: u32,
    color: wgpu::Texture,
    depth: wgpu::Texture,
    readback: wgpu::Buffer,
    padded_row: u32,
}

/// The GPU renderer. Keeps uploaded scene data and targets between frames.
pub struct GpuRenderer {
    ctx: GpuContext,
    pipeline: wgpu::RenderPipeline,
    frame_layout: wgpu::BindGroupLayout,
    material_layout: wgpu::BindGroupLayout,
    frame_buffer: wgpu::Buffer,
    frame_group: wgpu::BindGroup,
    uploaded: Option<UploadedScene>,
    target: Option<TargetSet>,
    nurbs: Option<nurbs::NurbsGpu>,
    btf: Option<btf::BtfGpu>,
    fly: Option<terrain::FlyGpu>,
    /// The caller's colour target while [`GpuRenderer::render_into`] renders
    /// (no read-back then); `None`: the renderer's own target, read back.
    into: Option<wgpu::TextureView>,
}

impl GpuRenderer {
    /// Opens the best adapter (a software rasterizer too) and builds the pipeline.
    pub fn new() -> Result<Self, GpuError> {
        Self::on(GpuContext::new()?)
    }

    /// Opens the best adapter if it is a hardware GPU, else
    /// [`GpuError::SoftwareOnly`].
    pub fn hardware() -> Result<Self, GpuError> {
        Self::on(GpuContext::hardware()?)
    }

    /// Opens the best adapter among `backends` (e.g. `wgpu::Backends::GL`).
    pub fn with_backends(backends: wgpu::Backends) -> Result<Self, GpuError> {
        Self::on(GpuContext::with_backends(backends)?)
    }

    /// Builds the renderer on an application's own device and queue (see
    /// [`GpuContext::on_device`]).
    pub fn on_device(adapter: wgpu::Adapter, device: wgpu::Device, queue: wgpu::Queue) -> Result<Self, GpuError> {
        Self::on(GpuContext::on_device(adapter, device, queue))
    }

    /// Builds the pipeline on an opened context.
    fn on(ctx: GpuContext) -> Result<Self, GpuError> {
        let device = &ctx.device;
        let scope = PipelineScope::open(device);
        // Bounds checks are ours, not naga's: every texel index goes through
        // wrap_index() against the level size, every level through the clamp of
        // λ to [0, level_count − 1], and the light loop stops at min(count, 8);
        // naga's injected checks would cost time on every texel load.
        // SAFETY: the shader indexes only in-range texels, levels and array elements.
        let module = unsafe { trusted_module(device, "textured.wgsl", &textured_source()) };
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("frame"),
            entries: &[uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
        });
        let material_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("material"),
            entries: &[uniform_entry(0, wgpu::ShaderStages::FRAGMENT), texture_entry(1)],
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2];
        let pipeline = mesh_pipeline(
            device,
            "textured",
            &module,
            &[&frame_layout, &material_layout],
            std::mem::size_of::<Vertex>() as u64,
            &attributes,
        );
        scope.close("pipeline")?;
        let frame_buffer = uniform_buffer::<crate::prepare::FrameUniform>(device, "frame");
        let frame_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("frame"),
            layout: &frame_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: frame_buffer.as_entire_binding() }],
        });
        Ok(Self {
            ctx,
            pipeline,
            frame_layout,
            material_layout,
            frame_buffer,
            frame_group,
            uploaded: None,
            target: None,
            nurbs: None,
            btf: None,
            fly: None,
            into: None,
        })
    }

    /// Renders `job` into `target`, a texture of the application's on this
    /// renderer's device (see [`GpuRenderer::on_device`]), with no read-back:
    /// the image stays on the GPU for the application to show or use, the
    /// same pixels [`Renderer::render`](crate::Renderer::render) would read
    /// back at the texture's size. The texture must be 2-D, one layer, one
    /// sample, [`wgpu::TextureFormat::Rgba8Unorm`] (the renderer's output:
    /// sRGB-encoded bytes, as egui's native textures take them) and usable
    /// as a render attachment; level 0 is drawn. Textures that are not are
    /// refused by what they lack; a texture of another device is a
    /// programming error that wgpu itself stops on (wgpu textures do not say
    /// which device made them).
    pub fn render_into(&mut self, job: &crate::Job<'_>, target: &wgpu::Texture) -> Result<(), RenderError> {
        check_target(target)?;
        let (w, h) = (target.width(), target.height());
        self.into = Some(target.create_view(&wgpu::TextureViewDescriptor {
            label: Some("caller's target"),
            format: Some(wgpu::TextureFormat::Rgba8Unorm),
            dimension: Some(wgpu::TextureViewDimension::D2),
            base_mip_level: 0,
            mip_level_count: Some(1),
            ..Default::default()
        }));
        let r = crate::Renderer::render(self, job, w, h);
        self.into = None;
        r.map(|_| ())
    }

    /// Description of the adapter in use.
    pub fn adapter(&self) -> String {
        self.ctx.describe()
    }

    /// The open device and its adapter.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Uploads every level of `pyr` into one atlas texture laid out by
    /// [`AtlasLayout`] (the same layout the material uniform describes).
    fn upload_texture(&self, pyr: &MipPyramid) -> Result<wgpu::Texture, GpuError> {
        let format = match pyr.color_space() {
            ColorSpace::Srgb => wgpu::TextureFormat::Rgba8UnormSrgb,
            ColorSpace::Linear => wgpu::TextureFormat::Rgba8Unorm,
        };
        let levels = pyr.level_count().min(MAX_ATLAS_LEVELS);
        let layout = AtlasLayout::new(pyr.width(), pyr.height(), levels);
        check_2d(
            &self.ctx.device,
            &format!("the MIP atlas of a {}x{} texture", pyr.width(), pyr.height()),
            (layout.width, layout.height),
        )?;
        let size = wgpu::Extent3d { width: layout.width, height: layout.height, depth_or_array_layers: 1 };
        let tex = sampled_texture(&self.ctx.device, "mip atlas", size, wgpu::TextureDimension::D2, format);
        for (l, img) in pyr.levels().iter().enumerate().take(levels) {
            let o = layout.origins[l];
            write_texels(
                &self.ctx.queue,
                &tex,
                wgpu::Origin3d { x: o[0], y: o[1], z: 0 },
                img.bytes(),
                (4 * img.width(), img.height()),
                wgpu::Extent3d { width: img.width(), height: img.height(), depth_or_array_layers: 1 },
            );
        }
        Ok(tex)
    }

    fn upload(&mut self, scene: &PreparedScene) -> Result<(), GpuError> {
        let key = scene.id();
        if self.uploaded.as_ref().is_some_and(|u| u.key == key) {
            return Ok(());
        }
        let device = &self.ctx.device;
        let (vertices, indices) = mesh_buffers(device, "scene", &scene.vertices, &scene.indices);
        let white = match hitex_core::texture::Image::filled(1, 1, ColorSpace::Srgb, [255; 4]) {
            Ok(img) => MipPyramid::single(img),
            Err(_) => unreachable!("a 1x1 image is valid"),
        };
        let mut textures = Vec::new();
        let mut groups = Vec::new();
        let mut cache: Vec<(*const MipPyramid, usize)> = Vec::new();
        for (m, t) in scene.materials.iter().zip(&scene.material_textures) {
            let pyr: &MipPyramid = t.as_deref().unwrap_or(&white);
            let ptr = pyr as *const MipPyramid;
            let ti = match cache.iter().find(|(p, _)| *p == ptr && t.is_some()) {
                Some((_, i)) => *i,
                None => {
                    textures.push(self.upload_texture(pyr)?);
                    cache.push((ptr, textures.len() - 1));
                    textures.len() - 1
                }
            };
            let ubuf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("material"),
                contents: bytemuck::bytes_of::<MaterialUniform>(m),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let view = textures[ti].create_view(&Default::default());
            groups.push(device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("material"),
                layout: &self.material_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: ubuf.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&view) },
                ],
            }));
        }
        let _ = &self.frame_layout;
        self.uploaded = Some(UploadedScene { key, vertices, indices, material_groups: groups, _textures: textures });
        Ok(())
    }

    fn ensure_target(&mut self, width: u32, height: u32) {
        if self.target.as_ref().is_some_and(|t| t.width == width && t.height == height) {
            return;
        }
        let device = &self.ctx.device;
        let size = wgpu::Extent3d { width, height, depth_or_array_layers: 1 };
        let color = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("color"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let depth = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("depth"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Depth32Float,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let padded_row = (4 * width).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: padded_row as u64 * height as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        self.target = Some(TargetSet { width, height, color, depth, readback, padded_row });
    }

    /// Renders `scene` seen by `camera` and reads the image back.
    pub fn render_view(
        &mut self,
        scene: &PreparedScene,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Frame, RenderError> {
        self.check_output(width, height)?;
        self.upload(scene)?;
        if let Some(n) = &scene.nurbs {
            self.prepare_nurbs(n, camera, width, height)?;
        }
        self.ensure_target(width, height);
        let frame = scene.frame_uniform(camera, width, height);
        self.ctx.queue.write_buffer(&self.frame_buffer, 0, bytemuck::bytes_of(&frame));
        let Some(up) = self.uploaded.as_ref() else {
            return Err(RenderError::Gpu(GpuError::Render("resources missing after upload".into())));
        };
        self.pass_and_read(width, height, background_rgba8(&frame), |pass| {
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.frame_group, &[]);
            pass.set_vertex_buffer(0, up.vertices.slice(..));
            pass.set_index_buffer(up.indices.slice(..), wgpu::IndexFormat::Uint32);
            for d in &scene.draws {
                pass.set_bind_group(1, &up.material_groups[d.material], &[]);
                pass.draw_indexed(d.first_index..d.first_index + d.index_count, 0, 0..1);
            }
            if scene.nurbs.is_some() {
                self.draw_nurbs(pass);
            }
        })
    }

    fn check_output(&self, width: u32, height: u32) -> Result<(), RenderError> {
        check_size(width, height)?;
        self.ctx.alive()?;
        let max = self.ctx.device.limits().max_texture_dimension_2d;
        if width > max || height > max {
            return Err(RenderError::Invalid(format!(
                "{width}x{height} exceeds the adapter's limit of {max} pixels per side"
            )));
        }
        Ok(())
    }

    /// Clears the target to `bg`, records one render pass with `draw`, copies
    /// the colour target out and reads it back; wgpu errors become [`GpuError`].
    fn pass_and_read(
        &self,
        width: u32,
        height: u32,
        bg: [u8; 4],
        draw: impl FnOnce(&mut wgpu::RenderPass<'_>),
    ) -> Result<Frame, RenderError> {
        let Some(tg) = self.target.as_ref() else {
            return Err(RenderError::Gpu(GpuError::Render("render target missing".into())));
        };
        let device = &self.ctx.device;
        let scope = UploadScope::open(device);
        let own_view;
        let color_view = match &self.into {
            Some(v) => v,
            None => {
                own_view = tg.color.create_view(&Default::default());
                &own_view
            }
        };
        let depth_view = tg.depth.create_view(&Default::default());
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("frame"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: bg[0] as f64 / 255.0,
                            g: bg[1] as f64 / 255.0,
                            b: bg[2] as f64 / 255.0,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            draw(&mut pass);
        }
        if self.into.is_some() {
            // drawn into the caller's texture: nothing to read back
            self.ctx.queue.submit([enc.finish()]);
            self.ctx.alive()?;
            scope.close("")?;
            return Ok(Frame { width, height, rgba: Vec::new() });
        }
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &tg.color,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &tg.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(tg.padded_row),
                    rows_per_image: Some(height),
                },
            },
            wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        );
        self.ctx.queue.submit([enc.finish()]);
        self.ctx.alive()?;
        scope.close("")?;
        let rgba = read_back(&self.ctx, &tg.readback, width, height, tg.padded_row)?;
        Ok(Frame { width, height, rgba })
    }
}

/// Why `target` cannot take [`GpuRenderer::render_into`]'s image, if it cannot.
fn check_target(target: &wgpu::Texture) -> Result<(), RenderError> {
    let bad = |why: String| Err(RenderError::Invalid(format!("the target texture {why}")));
    if target.dimension() != wgpu::TextureDimension::D2 || target.depth_or_array_layers() != 1 {
        return bad(format!(
            "must be 2-D with one layer, not {:?} with {}",
            target.dimension(),
            target.depth_or_array_layers()
        ));
    }
    if target.format() != wgpu::TextureFormat::Rgba8Unorm {
        return bad(format!("must be Rgba8Unorm (sRGB-encoded bytes), not {:?}", target.format()));
    }
    if target.sample_count() != 1 {
        return bad(format!("must have one sample, not {}", target.sample_count()));
    }
    if !target.usage().contains(wgpu::TextureUsages::RENDER_ATTACHMENT) {
        return bad("needs TextureUsages::RENDER_ATTACHMENT".into());
    }
    check_size(target.width(), target.height())
}

fn read_back(
    ctx: &GpuContext,
    buf: &wgpu::Buffer,
    width: u32,
    height: u32,
    padded_row: u32,
) -> Result<Vec<u8>, GpuError> {
    let slice = buf.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.wait()?;
    // the wait ran the callback; if it did not, the device is gone rather than slow
    match rx.try_recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(GpuError::Readback(e.to_string())),
        Err(_) => {
            ctx.alive()?;
            return Err(GpuError::Readback("the GPU finished but the image was never mapped".into()));
        }
    }
    let mut out = Vec::with_capacity(width as usize * height as usize * 4);
    {
        let view = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
        for row in view.chunks(padded_row as usize).take(height as usize) {
            out.extend_from_slice(&row[..4 * width as usize]);
        }
    }
    buf.unmap();
    Ok(out)
}

/// Keeps `Arc` in the public signature set used by callers sharing pyramids.
pub type SharedPyramid = Arc<MipPyramid>;
