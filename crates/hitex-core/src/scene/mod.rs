//! Scenes: camera, lights, meshes, materials, and the TOML description.

pub mod camera;
pub mod desc;
pub mod light;
pub mod mesh;

pub use camera::Camera;
pub use desc::{AssetLoader, NoFiles, RenderMode, SHOWCASE_TOML, SceneDesc, showcase_scene};
pub use light::Light;
pub use mesh::Mesh;

use crate::texture::{MipPyramid, SamplerOptions};
use glam::{Mat4, Vec2, Vec3, Vec4};
use std::sync::Arc;

/// A surface material: a base colour, optionally modulated by a texture, lit
/// with Lambert diffuse plus a Blinn–Phong highlight.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Name from the scene file.
    pub name: String,
    /// Linear RGBA multiplier of the texture (or the colour itself without one).
    pub base_color: Vec4,
    /// Index into [`Scene::textures`].
    pub texture: Option<usize>,
    /// How the texture is filtered.
    pub sampler: SamplerOptions,
    /// Texture coordinates are multiplied by this before lookup.
    pub uv_scale: Vec2,
    /// Strength of the specular highlight (0 = matte).
    pub specular: f32,
    /// Blinn–Phong exponent.
    pub shininess: f32,
    /// Light the surface by its normal as authored, also where the eye sees
    /// its back (height fields: a far slope's sliver at a ridge's outline is
    /// lit as the slope it is); otherwise the normal is turned to the eye.
    pub one_sided: bool,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            name: "default".into(),
            base_color: Vec4::ONE,
            texture: None,
            sampler: SamplerOptions::default(),
            uv_scale: Vec2::ONE,
            specular: 0.0,
            shininess: 32.0,
            one_sided: false,
        }
    }
}

/// One mesh placed in the world with a material.
#[derive(Debug, Clone)]
pub struct Object {
    /// The mesh, shared between objects.
    pub mesh: Arc<Mesh>,
    /// Model-to-world transform.
    pub transform: Mat4,
    /// Index into [`Scene::materials`].
    pub material: usize,
}

/// A resolved scene, ready for any backend.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The camera.
    pub camera: Camera,
    /// Light sources (at most [`MAX_LIGHTS`]).
    pub lights: Vec<Light>,
    /// Linear ambient light.
    pub ambient: Vec3,
    /// Linear background colour.
    pub background: Vec3,
    /// Texture pyramids referenced by materials.
    pub textures: Vec<Arc<MipPyramid>>,
    /// Materials referenced by objects.
    pub materials: Vec<Material>,
    /// The objects.
    pub objects: Vec<Object>,
    /// Default output size.
    pub width: u32,
    /// Default output size.
    pub height: u32,
    /// What the fragment program outputs.
    pub mode: RenderMode,
    /// NURBS patches drawn with per-pixel exact evaluation, in world space.
    pub nurbs: Vec<NurbsObject>,
    /// Display mode of every NURBS patch (`shaded`, `isophote`, …).
    pub nurbs_mode: String,
}

/// A NURBS patch placed in the scene (control points already transformed).
#[derive(Debug, Clone)]
pub struct NurbsObject {
    /// The surface in world space.
    pub surface: crate::nurbs::NurbsSurface,
    /// Parameter range drawn.
    pub range: ((f64, f64), (f64, f64)),
    /// Trimming loops in parameter space (empty: untrimmed).
    pub trim: Vec<Vec<[f64; 2]>>,
    /// Tessellation density per patch side.
    pub density: u32,
}

/// Most lights a scene may hold (the size of the GPU light array).
pub const MAX_LIGHTS: usize = 8;

impl Scene {
    /// Number of triangles over all objects.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.indices.len() / 3).sum()
    }
}
