//! GPU set-up shared by every program: error scopes, mesh buffers, the
//! uploaded mesh of a content, sampled textures and their uploads, and the
//! common bind-group layout entries.

use super::GpuError;
use wgpu::util::DeviceExt;

/// Error scopes around pipeline creation: a shader the driver's compiler
/// rejects is an internal error, a bad layout a validation one.
pub(crate) struct PipelineScope {
    // fields drop in order: the scope pushed last first
    validation: wgpu::ErrorScopeGuard,
    internal: wgpu::ErrorScopeGuard,
}

impl PipelineScope {
    /// Opens the scopes on `device`.
    pub(crate) fn open(device: &wgpu::Device) -> Self {
        let internal = device.push_error_scope(wgpu::ErrorFilter::Internal);
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        Self { validation, internal }
    }

    /// Closes the scopes: the first error as a device error naming `what`.
    pub(crate) fn close(self, what: &str) -> Result<(), GpuError> {
        let validation = pollster::block_on(self.validation.pop());
        if let Some(e) = validation.or(pollster::block_on(self.internal.pop())) {
            return Err(GpuError::Device(format!("{what} creation failed: {e}")));
        }
        Ok(())
    }
}

/// Error scopes around uploads and passes: out of memory and validation.
pub(crate) struct UploadScope {
    // fields drop in order: the scope pushed last first
    oom: wgpu::ErrorScopeGuard,
    validation: wgpu::ErrorScopeGuard,
}

impl UploadScope {
    /// Opens the scopes on `device`.
    pub(crate) fn open(device: &wgpu::Device) -> Self {
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        Self { oom, validation }
    }

    /// Closes the scopes: the first error as a render error, prefixed by
    /// `what` when it is not empty.
    pub(crate) fn close(self, what: &str) -> Result<(), GpuError> {
        let oom = pollster::block_on(self.oom.pop());
        let validation = pollster::block_on(self.validation.pop());
        match oom.or(validation) {
            Some(e) if what.is_empty() => Err(GpuError::Render(e.to_string())),
            Some(e) => Err(GpuError::Render(format!("{what}: {e}"))),
            None => Ok(()),
        }
    }
}

/// A vertex and an index buffer filled from slices (`label vertices`,
/// `label indices`).
pub(crate) fn mesh_buffers<V: bytemuck::Pod>(
    device: &wgpu::Device,
    label: &str,
    vertices: &[V],
    indices: &[u32],
) -> (wgpu::Buffer, wgpu::Buffer) {
    let v = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(&format!("{label} vertices")),
        contents: bytemuck::cast_slice(vertices),
        usage: wgpu::BufferUsages::VERTEX,
    });
    let i = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(&format!("{label} indices")),
        contents: bytemuck::cast_slice(indices),
        usage: wgpu::BufferUsages::INDEX,
    });
    (v, i)
}

/// A content's mesh on the device with its one bind group, kept while the
/// content (by its id) stays the same.
pub(crate) struct UploadedMesh {
    /// The content's id.
    pub(crate) id: u64,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    group: wgpu::BindGroup,
    count: u32,
}

impl UploadedMesh {
    /// Uploads `vertices` and `indices` for content `id`, drawn with `group`.
    pub(crate) fn new<V: bytemuck::Pod>(
        device: &wgpu::Device,
        label: &str,
        id: u64,
        vertices: &[V],
        indices: &[u32],
        group: wgpu::BindGroup,
    ) -> Self {
        let (vertices_buf, indices_buf) = mesh_buffers(device, label, vertices, indices);
        Self { id, vertices: vertices_buf, indices: indices_buf, group, count: indices.len() as u32 }
    }

    /// Records the indexed draw of the mesh with `pipeline` into `pass`.
    pub(crate) fn draw(&self, pass: &mut wgpu::RenderPass<'_>, pipeline: &wgpu::RenderPipeline) {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.group, &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.count, 0, 0..1);
    }
}

/// A uniform buffer binding visible to `visibility`.
pub(crate) fn uniform_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A non-filterable float 2-D texture read by the fragment stage.
pub(crate) fn texture_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A uniform buffer of `T`, written each frame.
pub(crate) fn uniform_buffer<T>(device: &wgpu::Device, label: &str) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: std::mem::size_of::<T>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// A texture that shaders sample and copies fill: one level, one sample.
pub(crate) fn sampled_texture(
    device: &wgpu::Device,
    label: &str,
    size: wgpu::Extent3d,
    dimension: wgpu::TextureDimension,
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

/// Copies `bytes` into the box `size` of `tex`'s level 0 at `origin`: rows
/// of `row_bytes` bytes, `rows` of them an image (block rows for compressed
/// formats).
pub(crate) fn write_texels(
    queue: &wgpu::Queue,
    tex: &wgpu::Texture,
    origin: wgpu::Origin3d,
    bytes: &[u8],
    (row_bytes, rows): (u32, u32),
    size: wgpu::Extent3d,
) {
    queue.write_texture(
        wgpu::TexelCopyTextureInfo { texture: tex, mip_level: 0, origin, aspect: wgpu::TextureAspect::All },
        bytes,
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row_bytes), rows_per_image: Some(rows) },
        size,
    );
}

/// Refuses a 2-D texture of `width` × `height` texels beyond the device's
/// limit per side, naming `what` needs it.
pub(crate) fn check_2d(device: &wgpu::Device, what: &str, (width, height): (u32, u32)) -> Result<(), GpuError> {
    let max = device.limits().max_texture_dimension_2d;
    if width > max || height > max {
        return Err(GpuError::Render(format!(
            "{what} needs {width}x{height} texels; the device allows {max} per side"
        )));
    }
    Ok(())
}

/// A sampled 2-D texture of one level holding `bytes` (an uncompressed
/// format, rows packed), refused ([`check_2d`]) beyond the device's limit.
pub(crate) fn texture_2d(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    bytes: &[u8],
) -> Result<wgpu::Texture, GpuError> {
    check_2d(device, &format!("the {label} texture"), (width, height))?;
    let size = wgpu::Extent3d { width, height, depth_or_array_layers: 1 };
    let tex = sampled_texture(device, label, size, wgpu::TextureDimension::D2, format);
    let row_bytes = format.block_copy_size(None).unwrap_or(4) * width;
    write_texels(queue, &tex, wgpu::Origin3d::ZERO, bytes, (row_bytes, height), size);
    Ok(tex)
}
