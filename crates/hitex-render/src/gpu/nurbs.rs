//! The NURBS pipeline: the paper's knot and control-point textures, a coarse
//! tessellation generating fragments, `shaders/nurbs.wgsl` evaluating each.

use super::plumbing::{PipelineScope, UploadedMesh, texture_2d, texture_entry, uniform_buffer, uniform_entry};
use super::{GpuError, GpuRenderer, trusted_module};
use crate::nurbs::{NurbsFrame, NurbsVertex, PreparedNurbs};
use crate::{Frame, RenderError};
use hitex_core::scene::Camera;

/// The NURBS shader source.
pub const NURBS_WGSL: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/nurbs.wgsl"));

/// The NURBS shader as compiled: the codes' constants
/// ([`crate::codes::wgsl_constants`]) and the display modes' `MODE_*`
/// constants (generated from [`crate::nurbs::mode_index`]) before [`NURBS_WGSL`].
pub fn nurbs_source() -> String {
    format!("{}{}{NURBS_WGSL}", crate::codes::wgsl_constants(), crate::nurbs::wgsl_mode_constants())
}

pub(crate) struct NurbsGpu {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    frame: wgpu::Buffer,
    uploaded: Option<UploadedMesh>,
}

impl NurbsGpu {
    fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        let scope = PipelineScope::open(device);
        // SAFETY: nurbs.wgsl indexes knots and control points through spans
        // found inside validated knot vectors, and its local arrays with
        // r ≤ p ≤ MAX_DEGREE (validated when the surfaces were built).
        let module = unsafe { trusted_module(device, "nurbs.wgsl", &nurbs_source()) };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("nurbs"),
            entries: &[
                uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                texture_entry(1),
                texture_entry(2),
                texture_entry(3),
                texture_entry(4),
                texture_entry(5),
                texture_entry(6),
            ],
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Float32];
        let pipeline = super::mesh_pipeline(
            device,
            "nurbs",
            &module,
            &[&layout],
            std::mem::size_of::<NurbsVertex>() as u64,
            &attributes,
        );
        scope.close("NURBS pipeline")?;
        let frame = uniform_buffer::<NurbsFrame>(device, "nurbs frame");
        Ok(Self { pipeline, layout, frame, uploaded: None })
    }
}

fn float_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    format: wgpu::TextureFormat,
    width: u32,
    rows: u32,
    bytes: &[u8],
) -> Result<wgpu::Texture, GpuError> {
    texture_2d(device, queue, label, (width, rows), format, bytes)
}

impl GpuRenderer {
    /// Uploads a NURBS model (once per content) and writes its frame uniforms
    /// for `camera`; [`GpuRenderer::draw_nurbs`] then records its draw.
    pub(crate) fn prepare_nurbs(
        &mut self,
        scene: &PreparedNurbs,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<(), RenderError> {
        if self.nurbs.is_none() {
            self.nurbs = Some(NurbsGpu::new(&self.ctx.device)?);
        }
        let device = &self.ctx.device;
        let queue = &self.ctx.queue;
        let Some(ng) = self.nurbs.as_mut() else {
            return Err(RenderError::Gpu(GpuError::Render("NURBS pipeline missing".into())));
        };
        if ng.uploaded.as_ref().is_none_or(|u| u.id != scene.id()) {
            let t = &scene.packed;
            let rows = t.patches.max(1);
            let ku = float_texture(
                device,
                queue,
                "u knots",
                wgpu::TextureFormat::R32Float,
                t.knot_width,
                rows,
                bytemuck::cast_slice(&t.knots_u),
            )?;
            let kv = float_texture(
                device,
                queue,
                "v knots",
                wgpu::TextureFormat::R32Float,
                t.knot_width,
                rows,
                bytemuck::cast_slice(&t.knots_v),
            )?;
            let cp = float_texture(
                device,
                queue,
                "control points",
                wgpu::TextureFormat::Rgba32Float,
                t.cp_width,
                rows,
                bytemuck::cast_slice(&t.control),
            )?;
            let tr = float_texture(
                device,
                queue,
                "trims",
                wgpu::TextureFormat::Rgba32Float,
                t.trim_width,
                rows,
                bytemuck::cast_slice(&t.trims),
            )?;
            let dv = float_texture(
                device,
                queue,
                "deviation",
                wgpu::TextureFormat::R32Float,
                t.deviation_width,
                rows,
                bytemuck::cast_slice(&t.deviation),
            )?;
            let ed = float_texture(
                device,
                queue,
                "edges",
                wgpu::TextureFormat::Rgba32Float,
                t.edges_width,
                rows,
                bytemuck::cast_slice(&t.edges),
            )?;
            let views = [
                ku.create_view(&Default::default()),
                kv.create_view(&Default::default()),
                cp.create_view(&Default::default()),
                tr.create_view(&Default::default()),
                dv.create_view(&Default::default()),
                ed.create_view(&Default::default()),
            ];
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("nurbs"),
                layout: &ng.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: ng.frame.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&views[0]) },
                    wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&views[1]) },
                    wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&views[2]) },
                    wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&views[3]) },
                    wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::TextureView(&views[4]) },
                    wgpu::BindGroupEntry { binding: 6, resource: wgpu::BindingResource::TextureView(&views[5]) },
                ],
            });
            ng.uploaded = Some(UploadedMesh::new(device, "nurbs", scene.id(), &scene.vertices, &scene.indices, group));
        }
        let frame = scene.frame(camera, width, height);
        queue.write_buffer(&ng.frame, 0, bytemuck::bytes_of(&frame));
        Ok(())
    }

    /// Records the draw of the prepared NURBS model into `pass`.
    pub(crate) fn draw_nurbs(&self, pass: &mut wgpu::RenderPass<'_>) {
        if let Some(ng) = self.nurbs.as_ref()
            && let Some(up) = ng.uploaded.as_ref()
        {
            up.draw(pass, &ng.pipeline);
        }
    }

    /// Renders a NURBS model seen by `camera` with `nurbs.wgsl` and reads it back.
    pub fn render_nurbs(
        &mut self,
        scene: &PreparedNurbs,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Frame, RenderError> {
        self.check_output(width, height)?;
        self.prepare_nurbs(scene, camera, width, height)?;
        self.ensure_target(width, height);
        let e = hitex_core::texture::linear_to_srgb_u8;
        let bg = [e(scene.background.x), e(scene.background.y), e(scene.background.z), 255];
        self.pass_and_read(width, height, bg, |pass| self.draw_nurbs(pass))
    }
}
