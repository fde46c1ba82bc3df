//! Scene → data both backends consume unchanged.

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Vec3, Vec4};
use hitex_core::scene::{Camera, Light, MAX_LIGHTS, RenderMode, Scene};
use hitex_core::texture::MipPyramid;
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
    /// [`hitex_core::texture::Filter::code`].
    pub filter: u32,
    /// [`hitex_core::texture::Wrap::code`].
    pub wrap: u32,
    /// [`hitex_core::texture::LevelRule::code`].
    pub level_rule: u32,
    /// Added to λ.
    pub lod_bias: f32,
    /// Number of MIP levels of the bound texture.
    pub level_count: u32,
    /// Level-0 size of the bound texture.
    pub size: [u32; 2],
    /// Size of the GPU atlas holding every level (see [`AtlasLayout`]).
    pub atlas_size: [u32; 2],
    /// 1: light by the normal as authored, also seen from behind; 0: turn
    /// the normal towards the eye.
    pub one_sided: u32,
    /// Padding to the 16-byte alignment of `origins` in WGSL.
    pub _pad: u32,
    /// Origin of level `l` in the atlas: `origins[l / 2]` holds levels `2k`
    /// (x, y) and `2k + 1` (z, w). Up to [`MAX_ATLAS_LEVELS`] levels.
    pub origins: [[u32; 4]; MAX_ATLAS_LEVELS / 2],
}

/// Most MIP levels an atlas records (a 16384-texel side has 15).
pub const MAX_ATLAS_LEVELS: usize = 16;

/// Largest atlas side the layout aims for (the 2-D limit of common GPUs).
pub const ATLAS_SIDE_LIMIT: u32 = 16384;

/// Where each MIP level of a pyramid sits in one 2-D texture, the classic
/// layout with level 0 at the origin and the smaller levels stacked in a
/// column to its right (or, for very wide textures, in a row below it).
///
/// The GPU backend samples levels through `textureLoad(atlas, origin + xy, 0)`:
/// one level-of-detail for every pixel of a SIMD group, so no driver has to
/// honour per-pixel mip levels in texel fetches (llvmpipe's GL path does not).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AtlasLayout {
    /// Atlas width in texels.
    pub width: u32,
    /// Atlas height in texels.
    pub height: u32,
    /// Origin (x, y) of each level.
    pub origins: Vec<[u32; 2]>,
}

impl AtlasLayout {
    /// Layout for a pyramid whose level 0 is `w`×`h` with `levels` levels
    /// (sizes halve, floor, down to 1 as in [`MipPyramid`]).
    pub fn new(w: u32, h: u32, levels: usize) -> Self {
        let size = |l: usize| ((w >> l).max(1), (h >> l).max(1));
        let mut origins = vec![[0u32, 0u32]];
        let (w1, _) = size(1.min(levels.saturating_sub(1)));
        if levels <= 1 {
            return Self { width: w, height: h, origins };
        }
        if w + w1 <= ATLAS_SIDE_LIMIT || w < h {
            // column to the right
            let mut y = 0;
            for l in 1..levels {
                origins.push([w, y]);
                y += size(l).1;
            }
            Self { width: w + w1, height: h.max(y), origins }
        } else {
            // row below
            let (_, h1) = size(1);
            let mut x = 0;
            for l in 1..levels {
                origins.push([x, h]);
                x += size(l).0;
            }
            Self { width: w.max(x), height: h + h1, origins }
        }
    }
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
    /// NURBS patches drawn after the meshes into the same colour and depth.
    pub nurbs: Option<crate::nurbs::PreparedNurbs>,
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
            let layout = AtlasLayout::new(size[0], size[1], level_count as usize);
            let mut origins = [[0u32; 4]; MAX_ATLAS_LEVELS / 2];
            for (l, o) in layout.origins.iter().enumerate().take(MAX_ATLAS_LEVELS) {
                origins[l / 2][2 * (l % 2)] = o[0];
                origins[l / 2][2 * (l % 2) + 1] = o[1];
            }
            materials.push(MaterialUniform {
                base_color: m.base_color.to_array(),
                uv_scale: m.uv_scale.to_array(),
                specular: m.specular,
                shininess: m.shininess,
                has_texture: tex.is_some() as u32,
                filter: m.sampler.filter.code(),
                wrap: m.sampler.wrap.code(),
                level_rule: m.sampler.level_rule.code(),
                lod_bias: m.sampler.lod_bias,
                level_count: level_count.min(MAX_ATLAS_LEVELS as u32),
                size,
                atlas_size: [layout.width, layout.height],
                one_sided: m.one_sided as u32,
                _pad: 0,
                origins,
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
            nurbs: prepare_nurbs(scene),
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

/// The scene's NURBS patches, lit by its first directional light (or from
/// the first point light's direction towards the patches' centre).
fn prepare_nurbs(scene: &Scene) -> Option<crate::nurbs::PreparedNurbs> {
    if scene.nurbs.is_empty() {
        return None;
    }
    let surfaces: Vec<_> = scene.nurbs.iter().map(|n| n.surface.clone()).collect();
    let ranges: Vec<_> = scene.nurbs.iter().map(|n| n.range).collect();
    let densities: Vec<_> = scene.nurbs.iter().map(|n| n.density).collect();
    let mut p = crate::nurbs::PreparedNurbs::with_densities(surfaces, &ranges, &densities);
    if scene.nurbs.iter().any(|n| !n.trim.is_empty()) {
        let trims: Vec<_> = scene.nurbs.iter().map(|n| n.trim.clone()).collect();
        p.set_trims(&trims);
    }
    p.mode = crate::nurbs::NurbsMode::from_name(&scene.nurbs_mode).unwrap_or_default();
    p.background = scene.background;
    p.camera = scene.camera;
    p.light = scene.lights.iter().find_map(|l| match *l {
        Light::Directional { direction, .. } => Some(-direction),
        _ => None,
    });
    if p.light.is_none()
        && let Some(Light::Point { position, .. }) = scene.lights.first()
    {
        p.light = Some(*position - p.bounds.0);
    }
    Some(p)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atlas_levels_do_not_overlap_and_fit() {
        for (w, h) in [(512u32, 512u32), (10, 3), (1, 1), (1, 64), (300, 7), (12000, 16), (16, 12000)] {
            let levels = 1 + (w.max(h) as f32).log2().floor() as usize;
            let a = AtlasLayout::new(w, h, levels);
            assert_eq!(a.origins.len(), levels);
            let rects: Vec<(u32, u32, u32, u32)> =
                (0..levels).map(|l| (a.origins[l][0], a.origins[l][1], (w >> l).max(1), (h >> l).max(1))).collect();
            for (i, r) in rects.iter().enumerate() {
                assert!(r.0 + r.2 <= a.width && r.1 + r.3 <= a.height, "{w}x{h} level {i} outside");
                for s in &rects[i + 1..] {
                    let apart = r.0 + r.2 <= s.0 || s.0 + s.2 <= r.0 || r.1 + r.3 <= s.1 || s.1 + s.3 <= r.1;
                    assert!(apart, "{w}x{h}: levels overlap");
                }
            }
            assert!(a.width <= ATLAS_SIDE_LIMIT && a.height <= ATLAS_SIDE_LIMIT, "{w}x{h} → {}x{}", a.width, a.height);
        }
    }

    #[test]
    fn uniform_layouts_match_wgsl() {
        // offsets of the WGSL struct members (see shaders/textured.wgsl)
        assert_eq!(std::mem::size_of::<MaterialUniform>(), 64 + 16 + 128);
        assert_eq!(std::mem::offset_of!(MaterialUniform, origins), 80);
        assert_eq!(std::mem::size_of::<FrameUniform>(), 128 + 32 * MAX_LIGHTS);
    }
}
