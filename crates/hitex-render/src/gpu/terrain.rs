//! The flight pipeline: resident maps in one 2-D array texture (a layer per
//! map, uploaded once while it stays resident), the frame's page table in a
//! storage buffer, `shaders/terrain.wgsl` over a full-screen triangle (flat
//! ground) or over the flight mesh (the DEM and objects, then the sky where
//! nothing was drawn). The generic texture's levels are layers of the same
//! array, kept for as long as the texture does not change.

use super::plumbing::{PipelineScope, check_2d, mesh_buffers, sampled_texture, uniform_buffer, write_texels};
use super::{GpuError, GpuRenderer, trusted_module};
use crate::terrain::{FlyGround, FlyPages, FlySampler, FlyUniform, FlyVertex, GenericTexture, MAP};
use crate::{Frame, RenderError};
use hitex_core::residency::MapKey;
use std::collections::HashMap;
use std::sync::Arc;

/// The flight shader source, before the codes' constants are prepended
/// ([`terrain_source`]).
pub const TERRAIN_WGSL: &str =
    concat!(include_str!("../../shaders/common.wgsl"), include_str!("../../shaders/terrain.wgsl"));

/// The flight shader as compiled: the codes' constants
/// ([`crate::codes::wgsl_constants`]) before [`TERRAIN_WGSL`].
pub fn terrain_source() -> String {
    format!("{}{TERRAIN_WGSL}", crate::codes::wgsl_constants())
}

/// Levels the page table holds (the shader's `origins` array).
const MAX_LEVELS: u32 = 32;

pub(crate) struct FlyGpu {
    /// Flat ground, one pipeline per sampler (by [`FlySampler::code`]).
    pipeline: Vec<wgpu::RenderPipeline>,
    /// Meshes, one pipeline per sampler.
    mesh_pipeline: Vec<wgpu::RenderPipeline>,
    sky_pipeline: wgpu::RenderPipeline,
    /// The generic texture the Generic layers hold.
    generic: Option<Arc<Vec<u8>>>,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    pages: Option<wgpu::Buffer>,
    maps: Option<wgpu::Texture>,
    capacity: u32,
    /// Map → (layer, frame last used).
    layers: HashMap<MapKey, (u32, u64)>,
    frame: u64,
}

impl FlyGpu {
    fn new(device: &wgpu::Device) -> Result<Self, GpuError> {
        // a shader the driver's compiler rejects is an internal error, not a validation one
        let scope = PipelineScope::open(device);
        // SAFETY: terrain.wgsl indexes `origins` with z < levels ≤ 32 (checked
        // before upload), `slots` with slot indices inside the window of each
        // level (the table holds levels × per_side² entries), and reads layers
        // the table names, all below the array's layer count.
        let module = unsafe { trusted_module(device, "terrain.wgsl", &terrain_source()) };
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty,
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("fly"),
            entries: &[
                entry(
                    0,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                entry(
                    1,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                entry(
                    2,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                ),
            ],
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("fly"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let vertex_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<FlyVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x2, 2 => Float32, 3 => Float32],
        };
        let make = |label: &str,
                    vs: &str,
                    fs: &str,
                    buffers: &[Option<wgpu::VertexBufferLayout>],
                    depth: wgpu::DepthStencilState,
                    sampler: u32| {
            let constants = [("SAMPLER", sampler as f64)];
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pl),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers,
                },
                primitive: wgpu::PrimitiveState::default(),
                depth_stencil: Some(depth),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fs),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    targets: &[Some(wgpu::ColorTargetState {
                        format: wgpu::TextureFormat::Rgba8Unorm,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let depth = |write: bool, compare| wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(write),
            depth_compare: Some(compare),
            stencil: Default::default(),
            bias: Default::default(),
        };
        // the full-screen triangle ignores depth; the mesh tests and writes it;
        // the sky fills what is still at the far plane
        // one pipeline per sampler: the sampler is an override constant, so
        // each compiles only its own path (a uniform branch over all four
        // slowed the trilinear path on a software driver)
        let pipeline = FlySampler::ALL
            .iter()
            .map(|s| make("fly", "vs_main", "fs_main", &[], depth(false, wgpu::CompareFunction::Always), s.code()))
            .collect();
        let mesh_pipeline = FlySampler::ALL
            .iter()
            .map(|s| {
                let layout = Some(vertex_layout.clone());
                make("fly mesh", "vs_mesh", "fs_mesh", &[layout], depth(true, wgpu::CompareFunction::Less), s.code())
            })
            .collect();
        let sky_pipeline = make("fly sky", "vs_sky", "fs_sky", &[], depth(false, wgpu::CompareFunction::LessEqual), 0);
        scope.close("flight pipeline")?;
        let uniform = uniform_buffer::<FlyUniform>(device, "fly");
        Ok(Self {
            pipeline,
            mesh_pipeline,
            sky_pipeline,
            generic: None,
            layout,
            uniform,
            pages: None,
            maps: None,
            capacity: 0,
            layers: HashMap::new(),
            frame: 0,
        })
    }

    /// Gives every map of `pages` a layer (uploading the new ones, reusing
    /// the layers of maps this frame does not use) and the generic texture
    /// its levels in the array's last layers; returns the table and the
    /// generic texture's first layer.
    fn sync(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pages: &FlyPages,
        generic: Option<&GenericTexture>,
    ) -> Result<(Vec<[i32; 2]>, u32), GpuError> {
        self.frame += 1;
        let glevels = generic.map_or(0, |g| g.levels.len() as u32);
        let need = pages.maps.len() as u32 + glevels;
        let max = device.limits().max_texture_array_layers;
        if need > max {
            return Err(GpuError::Render(format!("{need} resident maps in one frame; the device holds {max} layers")));
        }
        let fresh = self.maps.is_none() || need > self.capacity;
        if fresh {
            // room for this frame's maps and as many again, in a power of two
            // of layers: lavapipe read wrong layers of a 114-layer array
            // (measured; 64 and 128 layers read right)
            // (a caller's device may allow fewer than 64)
            self.capacity = (need * 2).next_power_of_two().max(64).min(max);
            check_2d(device, "the resident maps", (MAP, MAP))?;
            let size = wgpu::Extent3d { width: MAP, height: MAP, depth_or_array_layers: self.capacity };
            let format = wgpu::TextureFormat::Rgba8UnormSrgb;
            self.maps = Some(sampled_texture(device, "resident maps", size, wgpu::TextureDimension::D2, format));
            self.layers.clear();
            self.generic = None;
        }
        let Some(tex) = self.maps.as_ref() else {
            return Err(GpuError::Render("map array missing".into()));
        };
        let upload = |layer: u32, texels: &[u8]| {
            let size = wgpu::Extent3d { width: MAP, height: MAP, depth_or_array_layers: 1 };
            write_texels(queue, tex, wgpu::Origin3d { x: 0, y: 0, z: layer }, texels, (MAP * 4, MAP), size);
        };
        // the generic texture: the last layers, uploaded when it changes
        let first_generic = self.capacity - glevels;
        if let Some(g) = generic {
            let same = matches!((g.levels.first(), &self.generic), (Some(l), Some(k)) if Arc::ptr_eq(l, k));
            if !same {
                if g.levels.iter().any(|l| l.len() != (MAP * MAP * 4) as usize) {
                    return Err(GpuError::Render("a generic texture level is not a full map".into()));
                }
                // maps living in those layers move out
                self.layers.retain(|_, v| v.0 < first_generic);
                for (i, t) in g.levels.iter().enumerate() {
                    upload(first_generic + i as u32, t);
                }
                self.generic = g.levels.first().cloned();
            }
        }
        let pool = first_generic;
        for k in pages.maps.keys() {
            if let Some(l) = self.layers.get_mut(k) {
                l.1 = self.frame;
            }
        }
        let mut free: Vec<u32> = {
            let used: std::collections::HashSet<u32> = self.layers.values().map(|l| l.0).collect();
            (0..pool).filter(|l| !used.contains(l)).collect()
        };
        for (k, texels) in &pages.maps {
            if self.layers.contains_key(k) {
                continue;
            }
            let layer = match free.pop() {
                Some(l) => l,
                None => {
                    // the least recently used layer this frame does not need
                    let victim = self
                        .layers
                        .iter()
                        .filter(|(_, v)| v.1 < self.frame)
                        .min_by_key(|(_, v)| v.1)
                        .map(|(k, v)| (*k, v.0));
                    let Some((vk, vl)) = victim else {
                        return Err(GpuError::Render("no free map layer".into()));
                    };
                    self.layers.remove(&vk);
                    vl
                }
            };
            if texels.len() != (MAP * MAP * 4) as usize {
                return Err(GpuError::Render(format!("map z{} x{} y{} has {} bytes", k.z, k.x, k.y, texels.len())));
            }
            upload(layer, texels);
            self.layers.insert(*k, (layer, self.frame));
        }
        let slots = pages
            .slots
            .iter()
            .map(|s| match s.and_then(|k| self.layers.get(&k).map(|l| (l.0, k.z))) {
                Some((layer, z)) => [layer as i32, z as i32],
                None => [-1, 0],
            })
            .collect();
        Ok((slots, first_generic))
    }
}

impl GpuRenderer {
    /// Renders one flight frame with `terrain.wgsl` and reads it back.
    pub fn render_fly(
        &mut self,
        u: &FlyUniform,
        pages: &FlyPages,
        ground: FlyGround<'_>,
    ) -> Result<Frame, RenderError> {
        let (w, h) = (u.sizes[0], u.sizes[1]);
        self.check_output(w, h)?;
        if pages.levels == 0 || pages.levels > MAX_LEVELS || pages.origins.len() != pages.levels as usize {
            return Err(RenderError::Invalid(format!(
                "{} levels; the flight shader takes 1..={MAX_LEVELS}",
                pages.levels
            )));
        }
        let per = pages.per_side as usize;
        if pages.slots.len() != pages.levels as usize * per * per
            || u.sizes[2] != pages.levels
            || u.sizes[3] != pages.per_side
        {
            return Err(RenderError::Invalid("the page table does not match the uniforms".into()));
        }
        if self.fly.is_none() {
            self.fly = Some(FlyGpu::new(&self.ctx.device)?);
        }
        let device = &self.ctx.device;
        let queue = &self.ctx.queue;
        let Some(fg) = self.fly.as_mut() else {
            return Err(RenderError::Gpu(GpuError::Render("flight pipeline missing".into())));
        };
        let (mesh, generic) = match ground {
            FlyGround::Flat => (None, None),
            FlyGround::Mesh { mesh, generic } => {
                if mesh.indices.iter().any(|&i| i as usize >= mesh.vertices.len()) {
                    return Err(RenderError::Invalid("a flight mesh index is out of range".into()));
                }
                (Some(mesh), Some(generic))
            }
        };
        let (slots, first_generic) = fg.sync(device, queue, pages, generic)?;
        let mut u = *u;
        u.params[1] = first_generic;
        if let Some(g) = generic {
            u.params[2] = g.levels.len() as u32;
            u.params[3] = g.side;
        } else {
            u.params[2] = 0;
        }
        let u = &u;
        // page table: 32 origins, then the slots
        let mut bytes: Vec<i32> = Vec::with_capacity(MAX_LEVELS as usize * 4 + slots.len() * 2);
        for z in 0..MAX_LEVELS as usize {
            let o = pages.origins.get(z).copied().unwrap_or([0, 0]);
            bytes.extend_from_slice(&[o[0], o[1], 0, 0]);
        }
        for s in &slots {
            bytes.extend_from_slice(s);
        }
        let size = (bytes.len() * 4) as u64;
        if fg.pages.as_ref().is_none_or(|b| b.size() < size) {
            fg.pages = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("page table"),
                size: size.next_power_of_two(),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        let (Some(pbuf), Some(maps)) = (fg.pages.as_ref(), fg.maps.as_ref()) else {
            return Err(RenderError::Gpu(GpuError::Render("flight resources missing".into())));
        };
        queue.write_buffer(pbuf, 0, bytemuck::cast_slice(&bytes));
        queue.write_buffer(&fg.uniform, 0, bytemuck::bytes_of(u));
        let view = maps.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("fly"),
            layout: &fg.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: fg.uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: pbuf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&view) },
            ],
        });
        let buffers = mesh.filter(|m| !m.indices.is_empty()).map(|m| {
            let (v, i) = mesh_buffers(device, "fly", &m.vertices, &m.indices);
            (v, i, (m.indices.len() / 3 * 3) as u32)
        });
        self.ensure_target(w, h);
        let Some(fg) = self.fly.as_ref() else {
            return Err(RenderError::Gpu(GpuError::Render("flight pipeline missing".into())));
        };
        let flat = mesh.is_none();
        let code = u.sampler().code() as usize;
        let (Some(flat_pipeline), Some(mesh_pipeline)) = (fg.pipeline.get(code), fg.mesh_pipeline.get(code)) else {
            return Err(RenderError::Gpu(GpuError::Render("no flight pipeline for the sampler".into())));
        };
        self.pass_and_read(w, h, [0, 0, 0, 255], |pass| {
            pass.set_bind_group(0, &group, &[]);
            if flat {
                pass.set_pipeline(flat_pipeline);
                pass.draw(0..3, 0..1);
                return;
            }
            if let Some((v, i, n)) = &buffers {
                pass.set_pipeline(mesh_pipeline);
                pass.set_vertex_buffer(0, v.slice(..));
                pass.set_index_buffer(i.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..*n, 0, 0..1);
            }
            pass.set_pipeline(&fg.sky_pipeline);
            pass.draw(0..3, 0..1);
        })
    }
}
