//! Scene → data both backends consume unchanged.

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Vec3, Vec4};
use hitex_core::scene::{Camera, Light, MAX_LIGHTS, RenderMode, Scene};
use hitex_core::texture::{Filter, LevelRule, MipPyramid, Wrap};
use std::sync::Arc;

/// One vertex in world space (binding 0 of `textured.wgsl`'s vertex stage).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Vertex {
    /// World position.
    pub position: [f32; 3],
    /// World unit normal.
    pub normal: [f32; 3],
    /// Texture coordinates (before the material's `uv_scale`).
    pub uv: [f32; 2],
}

/// One light as the fragment programs see it.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct LightUniform {
    /// xyz: direction of travel (w = 0) or position (w = 1).
    pub vector: [f32; 4],
    /// Linear RGB × intensity; w unused.
    pub radiance: [f32; 4],
}

/// Per-frame uniforms (group 0, binding 0).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FrameUniform {
    /// World-to-clip matrix, column-major.
    pub view_proj: [[f32; 4]; 4],
    /// Camera position; w unused.
    pub camera: [f32; 4],
    /// Linear ambient RGB; w unused.
    pub ambient: [f32; 4],
    /// Linear background RGB; w unused.
    pub background: [f32; 4],
    /// x: mode index, y: number of lights, z, w unused.
    pub params: [u32; 4],
    /// The lights; the first `params.y` are used.
    pub lights: [LightUniform; MAX_LIGHTS],
}

/// Per-material uniforms (group 1, binding 0).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct MaterialUniform {
    /// Linear RGBA multiplier.
    pub base_color: [f32; 4],
    /// Texture-coordinate scale.
    pub uv_scale: [f32; 2],
    /// Highlight strength.
    pub specular: f32,
    /// Highlight exponent.
    pub shininess: f32,
    /// 1 if a texture is bound, else 0 (a 1×1 white texture is bound instead).
    pub has_texture: u32,
    /// 0 nearest, 1 bilinear, 2 trilinear.
    pub filter: u32,
    /// 0 repeat, 1 clamp, 2 mirror.
    pub wrap: u32,
    /// 0 max-partial, 1 vulkan-rho.
    pub level_rule: u32,
    /// Added to λ.
    pub lod_bias: f32,
    /// Number of MIP levels of the bound texture.
    pub level_count: u32,
    /// Level-0 size of the bound texture.
    pub size: [u32; 2],
}

/// A range of indices drawn with one material.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Draw {
    /// First index in [`PreparedScene::indices`].
    pub first_index: u32,
    /// Number of indices (3 per triangle).
    pub index_count: u32,
    /// Index into [`PreparedScene::materials`].
    pub material: usize,
}

/// Everything a backend needs for a frame.
#[derive(Debug, Clone)]
pub struct PreparedScene {
    /// All vertices of all objects, world space.
    pub vertices: Vec<Vertex>,
    /// Triangle indices into `vertices`.
    pub indices: Vec<u32>,
    /// Draw calls in scene order.
    pub draws: Vec<Draw>,
    /// Material uniforms.
    pub materials: Vec<MaterialUniform>,
    /// Texture bound per material (`None`: 1×1 white).
    pub material_textures: Vec<Option<Arc<MipPyramid>>>,
    /// The camera (view changes go through [`PreparedScene::frame_uniform`]).
    pub camera: Camera,
    /// Lights.
    pub lights: Vec<Light>,
    /// Ambient light.
    pub ambient: Vec3,
    /// Background colour.
    pub background: Vec3,
    /// Output mode.
    pub mode: RenderMode,
    /// Identity of the uploaded content: GPU backends keep uploads per id.
    /// Call [`PreparedScene::touch`] after changing geometry or materials.
    id: u64,
}

static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

fn next_id() -> u64 {
    NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl PreparedScene {
    /// Identity of the content (changes with [`PreparedScene::touch`]).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Marks geometry, materials or textures as changed, so that GPU
    /// backends upload them again.
    pub fn touch(&mut self) {
        self.id = next_id();
    }

    /// Transforms every object to world space and packs the uniforms.
    pub fn new(scene: &Scene) -> Self {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let mut draws = Vec::new();
        for o in &scene.objects {
            let base = vertices.len() as u32;
            let nmat = Mat3::from_mat4(o.transform).inverse().transpose();
            for i in 0..o.mesh.positions.len() {
                let p = o.transform.transform_point3(o.mesh.positions[i]);
                let n = (nmat * o.mesh.normals[i]).try_normalize().unwrap_or(Vec3::Y);
                vertices.push(Vertex { position: p.to_array(), normal: n.to_array(), uv: o.mesh.uvs[i].to_array() });
            }
            let first = indices.len() as u32;
            indices.extend(o.mesh.indices.iter().map(|i| i + base));
            draws.push(Draw { first_index: first, index_count: o.mesh.indices.len() as u32, material: o.material });
        }
        let mut materials = Vec::new();
        let mut material_textures = Vec::new();
        for m in &scene.materials {
            let tex = m.texture.map(|t| scene.textures[t].clone());
            let (level_count, size) =
                tex.as_ref().map(|t| (t.level_count() as u32, [t.width(), t.height()])).unwrap_or((1, [1, 1]));
            materials.push(MaterialUniform {
                base_color: m.base_color.to_array(),
                uv_scale: m.uv_scale.to_array(),
                specular: m.specular,
                shininess: m.shininess,
                has_texture: tex.is_some() as u32,
                filter: match m.sampler.filter {
                    Filter::Nearest => 0,
                    Filter::Bilinear => 1,
                    Filter::Trilinear => 2,
                },
                wrap: match m.sampler.wrap {
                    Wrap::Repeat => 0,
                    Wrap::Clamp => 1,
                    Wrap::Mirror => 2,
                },
                level_rule: match m.sampler.level_rule {
                    LevelRule::MaxPartial => 0,
                    LevelRule::VulkanRho => 1,
                },
                lod_bias: m.sampler.lod_bias,
                level_count,
                size,
            });
            material_textures.push(tex);
        }
        Self {
            vertices,
            indices,
            draws,
            materials,
            material_textures,
            camera: scene.camera,
            lights: scene.lights.clone(),
            ambient: scene.ambient,
            background: scene.background,
            mode: scene.mode,
            id: next_id(),
        }
    }

    /// Frame uniforms for an output of `width`×`height` with `camera`.
    pub fn frame_uniform(&self, camera: &Camera, width: u32, height: u32) -> FrameUniform {
        let vp = camera.view_proj(width as f32 / height as f32);
        let mut lights = [LightUniform::zeroed(); MAX_LIGHTS];
        for (slot, l) in lights.iter_mut().zip(&self.lights) {
            *slot = match *l {
                Light::Directional { direction, color, intensity } => LightUniform {
                    vector: direction.normalize().extend(0.0).to_array(),
                    radiance: (color * intensity).extend(0.0).to_array(),
                },
                Light::Point { position, color, intensity } => LightUniform {
                    vector: position.extend(1.0).to_array(),
                    radiance: (color * intensity).extend(0.0).to_array(),
                },
            };
        }
        FrameUniform {
            view_proj: vp.to_cols_array_2d(),
            camera: camera.position.extend(1.0).to_array(),
            ambient: self.ambient.extend(0.0).to_array(),
            background: self.background.extend(1.0).to_array(),
            params: [self.mode.index(), self.lights.len().min(MAX_LIGHTS) as u32, 0, 0],
            lights,
        }
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// The background colour as the framebuffer stores it (sRGB-encoded).
pub fn background_rgba8(frame: &FrameUniform) -> [u8; 4] {
    let b = Vec4::from_array(frame.background);
    [
        hitex_core::texture::linear_to_srgb_u8(b.x),
        hitex_core::texture::linear_to_srgb_u8(b.y),
        hitex_core::texture::linear_to_srgb_u8(b.z),
        255,
    ]
}
