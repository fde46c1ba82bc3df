//! The BTF pipeline: the index map and one codebook layout as real GPU
//! textures (2-D tiles or 3-D layers, RGBA8 sRGB, BC1 sRGB or, for an HDR
//! BTF, RGBA16F), sampled with
//! the hardware filter by `shaders/btf.wgsl`.

use super::plumbing::{
    PipelineScope, UploadScope, UploadedMesh, check_2d, sampled_texture, texture_2d, texture_entry, uniform_buffer,
    uniform_entry, write_texels,
};
use super::{GpuError, GpuRenderer, trusted_module};
use crate::btf::{BtfFrame, BtfVertex, PreparedBtf};
use crate::{Frame, RenderError};
use hitex_core::btf::Layout;
use hitex_core::btf::layout::Axis;
use hitex_core::scene::Camera;

/// The BTF shader source, before the layout's constants are prepended.
pub const BTF_WGSL: &str = concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/btf.wgsl"));

/// The WGSL of `layout`: the codes' constants ([`crate::codes::wgsl_constants`])
/// and the layout's prepended, the 2-D or 3-D branch kept.
pub fn layout_source(layout: Layout) -> String {
    let spec = layout.spec();
    let d3 = spec.depth.is_some();
    let mut out = crate::codes::wgsl_constants();
    out += &format!(
        "const FILTERED: u32 = {}u;\nconst TILE_X: u32 = {}u;\nconst TILE_Y: u32 = {}u;\nconst DEPTH_AXIS: u32 = {}u;\n",
        layout.filtered_mask(),
        spec.tile_x as u32,
        spec.tile_y as u32,
        spec.depth.map_or(6, |a| a as u32)
    );
    // keep one branch of each `//#if D3 … //#else … //#endif`
    let mut keep = true;
    for line in BTF_WGSL.lines() {
        match line.trim() {
            "//#if D3" => keep = d3,
            "//#else" => keep = !d3,
            "//#endif" => keep = true,
            _ if keep => {
                out.push_str(line);
                out.push('\n');
            }
            _ => {}
        }
    }
    out
}

pub(crate) struct BtfGpu {
    layout: Layout,
    pipeline: wgpu::RenderPipeline,
    group_layout: wgpu::BindGroupLayout,
    frame: wgpu::Buffer,
    uploaded: Option<UploadedMesh>,
}

impl BtfGpu {
    fn new(device: &wgpu::Device, layout: Layout) -> Result<Self, GpuError> {
        let scope = PipelineScope::open(device);
        let source = layout_source(layout);
        // SAFETY: btf.wgsl reads index texels at coordinates wrapped into the
        // index map, codebook texels inside tiles whose indices come from the
        // validated index map and from angular neighbours clamped or wrapped
        // into the grid, and local arrays with constant-bounded loops.
        let module = unsafe { trusted_module(device, "btf.wgsl", &source) };
        let view_dimension =
            if layout.is_3d() { wgpu::TextureViewDimension::D3 } else { wgpu::TextureViewDimension::D2 };
        let group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("btf"),
            entries: &[
                uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
                texture_entry(4),
            ],
        });
        let attributes =
            wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x3, 4 => Float32x2];
        let stride = std::mem::size_of::<BtfVertex>() as u64;
        let pipeline = super::mesh_pipeline(device, "btf", &module, &[&group_layout], stride, &attributes);
        scope.close(&format!("BTF pipeline ({})", layout.label()))?;
        let frame = uniform_buffer::<BtfFrame>(device, "btf frame");
        Ok(Self { layout, pipeline, group_layout, frame, uploaded: None })
    }
}

/// Whether an adapter of `backend` samples BC1 codebooks of the 3-D
/// layouts correctly. Mesa's GL driver (llvmpipe through OpenGL) reports
/// BC-compressed 3-D textures but samples them as black (layout (b) + BC1:
/// 18 dB against the CPU, the 2-D layouts with BC1 and (b) raw are right);
/// the same driver through Vulkan (lavapipe) samples them right. No GL
/// driver is trusted with them: wgpu's GL backend cannot tell which one it
/// runs on before the first draw.
pub fn bc1_3d_trusted(backend: wgpu::Backend) -> bool {
    backend != wgpu::Backend::Gl
}

fn codebook_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &PreparedBtf,
    backend: wgpu::Backend,
) -> Result<wgpu::Texture, GpuError> {
    let cb = &scene.codebook;
    let d3 = cb.layout.is_3d();
    let limits = device.limits();
    let max = if d3 { limits.max_texture_dimension_3d } else { limits.max_texture_dimension_2d };
    if cb.width > max || cb.height > max || cb.depth > max {
        return Err(GpuError::Render(format!(
            "codebook layout {} needs {}x{}x{} texels; the device allows {max} per side",
            cb.layout.label(),
            cb.width,
            cb.height,
            cb.depth
        )));
    }
    let (format, bytes, row_bytes, rows): (_, &[u8], u32, u32) = match &scene.bc1 {
        Some(blocks) => {
            let f = device.features();
            let need = if d3 {
                wgpu::Features::TEXTURE_COMPRESSION_BC | wgpu::Features::TEXTURE_COMPRESSION_BC_SLICED_3D
            } else {
                wgpu::Features::TEXTURE_COMPRESSION_BC
            };
            if !f.contains(need) {
                return Err(GpuError::Render(format!(
                    "the adapter cannot sample BC1 {} textures",
                    if d3 { "3-D" } else { "2-D" }
                )));
            }
            if d3 && !bc1_3d_trusted(backend) {
                return Err(GpuError::Render(format!(
                    "layout {} with BC1 needs a BC1 3-D texture, which the {backend} backend samples wrongly \
                     (black on Mesa); use a Vulkan adapter, the CPU backend, a 2-D layout or no BC1",
                    cb.layout.label()
                )));
            }
            (wgpu::TextureFormat::Bc1RgbaUnormSrgb, blocks, cb.width / 4 * 8, cb.height / 4)
        }
        // an HDR codebook: its linear half floats, RGBA16F
        None if cb.is_hdr() => {
            (wgpu::TextureFormat::Rgba16Float, bytemuck::cast_slice(&cb.half), cb.width * 8, cb.height)
        }
        None => (wgpu::TextureFormat::Rgba8UnormSrgb, &cb.texels, cb.width * 4, cb.height),
    };
    let size = wgpu::Extent3d { width: cb.width, height: cb.height, depth_or_array_layers: cb.depth };
    let dimension = if d3 { wgpu::TextureDimension::D3 } else { wgpu::TextureDimension::D2 };
    let tex = sampled_texture(device, "btf codebook", size, dimension, format);
    write_texels(queue, &tex, wgpu::Origin3d::ZERO, bytes, (row_bytes, rows), size);
    Ok(tex)
}

/// The index atlas of `scene`: level 0 at the origin, levels 1, 2, … stacked
/// top to bottom in a column at x = level 0's width. Returns its width, height
/// and texels (u | v << 16).
pub(crate) fn index_atlas(scene: &PreparedBtf) -> (u32, u32, Vec<u32>) {
    let idx = &scene.index;
    let coarse = scene.mip.get(1..).unwrap_or(&[]);
    let column_w = coarse.iter().map(|l| l.width).max().unwrap_or(0);
    let column_h: u32 = coarse.iter().map(|l| l.height).sum();
    let (w, h) = (idx.width + column_w, idx.height.max(column_h));
    let mut texels = vec![0u32; w as usize * h as usize];
    let mut put = |map: &hitex_core::btf::index::IndexMap, ox: u32, oy: u32| {
        for y in 0..map.height {
            for x in 0..map.width {
                let e = map.entries[(y * map.width + x) as usize];
                texels[((oy + y) * w + ox + x) as usize] = e[0] as u32 | (e[1] as u32) << 16;
            }
        }
    };
    put(idx, 0, 0);
    let mut oy = 0;
    for l in coarse {
        put(l, idx.width, oy);
        oy += l.height;
    }
    (w, h, texels)
}

impl GpuRenderer {
    fn prepare_btf(&mut self, scene: &PreparedBtf, frame: &BtfFrame) -> Result<(), RenderError> {
        let layout = scene.layout();
        if self.btf.as_ref().is_none_or(|b| b.layout != layout) {
            self.btf = Some(BtfGpu::new(&self.ctx.device, layout)?);
        }
        let device = &self.ctx.device;
        let queue = &self.ctx.queue;
        let Some(bg) = self.btf.as_mut() else {
            return Err(RenderError::Gpu(GpuError::Render("BTF pipeline missing".into())));
        };
        if bg.uploaded.as_ref().is_none_or(|u| u.id != scene.id()) {
            let scope = UploadScope::open(device);
            let codebook = codebook_texture(device, queue, scene, self.ctx.info.backend)?;
            // the index map, with its coarser MIP levels (if any) stacked in a
            // column to its right: one atlas read at texture level 0 (btf.wgsl's
            // index_level_rect places the levels the same way)
            let (atlas_w, atlas_h, texels) = index_atlas(scene);
            check_2d(device, "the index map with its MIP levels", (atlas_w, atlas_h))?;
            let index_tex = texture_2d(
                device,
                queue,
                "btf index",
                (atlas_w, atlas_h),
                wgpu::TextureFormat::Rg16Uint,
                bytemuck::cast_slice(&texels),
            )?;
            let repeat_depth = layout.spec().depth.is_some_and(|a| matches!(a, Axis::PhiC | Axis::PhiL));
            let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("btf codebook"),
                address_mode_u: wgpu::AddressMode::ClampToEdge,
                address_mode_v: wgpu::AddressMode::ClampToEdge,
                address_mode_w: if repeat_depth { wgpu::AddressMode::Repeat } else { wgpu::AddressMode::ClampToEdge },
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                mipmap_filter: wgpu::MipmapFilterMode::Nearest,
                ..Default::default()
            });
            // a local-PCA codebook's clusters and coefficients (one texel of zeros otherwise)
            let (pca_w, pca_h, pca_halves) = match &scene.pca {
                Some(p) => (p.texels_per * p.sample_w, p.sample_h, p.gpu.as_slice()),
                None => (1, 1, &[0u16; 4][..]),
            };
            check_2d(device, "the PCA coefficients", (pca_w, pca_h))?;
            let pca_tex = texture_2d(
                device,
                queue,
                "btf pca coefficients",
                (pca_w, pca_h),
                wgpu::TextureFormat::Rgba16Float,
                bytemuck::cast_slice(pca_halves),
            )?;
            let pca_view = pca_tex.create_view(&Default::default());
            let cb_view = codebook.create_view(&Default::default());
            let idx_view = index_tex.create_view(&Default::default());
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("btf"),
                layout: &bg.group_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: bg.frame.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&idx_view) },
                    wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&cb_view) },
                    wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::Sampler(&sampler) },
                    wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&pca_view) },
                ],
            });
            let mesh = UploadedMesh::new(device, "btf", scene.id(), &scene.vertices, &scene.indices, group);
            scope.close("BTF upload")?;
            bg.uploaded = Some(mesh);
        }
        queue.write_buffer(&bg.frame, 0, bytemuck::bytes_of(frame));
        Ok(())
    }

    /// Renders a BTF surface seen by `camera`, lit by a point light at
    /// `light`, with `btf.wgsl`, and reads it back.
    pub fn render_btf(
        &mut self,
        scene: &PreparedBtf,
        camera: &Camera,
        light: glam::Vec3,
        width: u32,
        height: u32,
    ) -> Result<Frame, RenderError> {
        self.check_output(width, height)?;
        let frame = scene.frame(camera, light, width, height);
        self.prepare_btf(scene, &frame)?;
        self.ensure_target(width, height);
        let e = hitex_core::texture::linear_to_srgb_u8;
        let b = scene.background;
        let clear = [e(b.x), e(b.y), e(b.z), 255];
        self.pass_and_read(width, height, clear, |pass| {
            if let Some(bg) = self.btf.as_ref()
                && let Some(up) = bg.uploaded.as_ref()
            {
                up.draw(pass, &bg.pipeline);
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::btf::BtfSurface;
    use hitex_core::btf::synth::{Material, SynthOptions, synthesize};
    use hitex_core::btf::{AngularGrid, index::IndexMap};

    #[test]
    fn the_index_atlas_stacks_the_levels_where_the_shader_looks() {
        let grid = AngularGrid::new(vec![0.0, 40.0], 4).unwrap();
        let btf = synthesize(Material::Knit, &SynthOptions { grid, size: 4, supersample: 1, exposure: 1.0 }, &|_| {})
            .unwrap();
        let map = IndexMap::identity(4, 4, 24, 8);
        let mip = hitex_core::btf::mip::build_mip(&btf, &map, &|_, _| {}).unwrap();
        let p = PreparedBtf::with_mip(&mip, Layout::F, None, BtfSurface::quad(2.0, 1.0)).unwrap();
        let (w, h, texels) = index_atlas(&p);
        // levels 24x8, 12x4, 6x2, 3x1, 1x1: a 12-wide column of 4 + 2 + 1 + 1 = 8 rows
        assert_eq!(p.mip.len(), 5);
        assert_eq!((w, h), (36, 8));
        // the origin of each level as index_level_rect computes it in btf.wgsl
        let rect = |k: u32| {
            let oy: u32 = (1..k).map(|j| (8u32 >> j).max(1)).sum();
            if k == 0 { (0, 0) } else { (24, oy) }
        };
        for (k, level) in p.mip.iter().enumerate() {
            let (ox, oy) = rect(k as u32);
            assert_eq!((level.width, level.height), ((24u32 >> k).max(1), (8u32 >> k).max(1)));
            for y in 0..level.height {
                for x in 0..level.width {
                    let e = level.entries[(y * level.width + x) as usize];
                    assert_eq!(
                        texels[((oy + y) * w + ox + x) as usize],
                        e[0] as u32 | (e[1] as u32) << 16,
                        "level {k}"
                    );
                }
            }
        }
    }
}
