//! The scene file: a TOML description, validated and resolved into a [`Scene`].
//!
//! Unknown keys are rejected, every number is checked to be finite, and every
//! error names the key (`camera.fov_y`, `object[2].material`, ...). Files the
//! scene refers to are loaded through an [`AssetLoader`] so that this crate
//! stays free of file formats. [`SHOWCASE_TOML`] is the embedded default scene
//! and a commented example of every key.

use super::{Camera, Light, MAX_LIGHTS, Material, Mesh, Object, Scene};
use crate::CoreError;
use crate::error::{finite, finite3};
use crate::texture::procedural::Pattern;
use crate::texture::{ColorSpace, Filter, Image, LevelRule, MipPyramid, SamplerOptions, Wrap};
use glam::{EulerRot, Mat4, Quat, Vec2, Vec4};
use serde::Deserialize;
use std::collections::HashMap;
use std::sync::Arc;

/// The embedded showcase scene (textured meshes over a checkered ground
/// receding to the horizon).
pub const SHOWCASE_TOML: &str = include_str!("showcase.toml");

/// Largest accepted output side in pixels.
pub const MAX_OUTPUT_SIDE: u32 = 16384;

/// What the fragment program writes. Its names ([`RenderMode::name`]) are
/// those of scene files and the command line (with the `clap` feature,
/// `clap::ValueEnum` derives the same names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RenderMode {
    /// Lit, textured surfaces.
    #[default]
    Shaded,
    /// The (scaled) texture coordinates, fractional part as red and green.
    Uv,
    /// The MIP level λ chosen per pixel, as a colour ramp (level 0 blue … 10+ red).
    Level,
    /// The world-space normal mapped to RGB.
    Normal,
}

impl RenderMode {
    /// Every mode with its name.
    pub const ALL: [(&'static str, RenderMode); 4] = [
        ("shaded", RenderMode::Shaded),
        ("uv", RenderMode::Uv),
        ("level", RenderMode::Level),
        ("normal", RenderMode::Normal),
    ];
    /// The scene-file and command-line name of the mode.
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(_, m)| *m == self).map_or("shaded", |(n, _)| n)
    }
    /// Index used by both backends' fragment programs.
    pub fn index(self) -> u32 {
        match self {
            RenderMode::Shaded => 0,
            RenderMode::Uv => 1,
            RenderMode::Level => 2,
            RenderMode::Normal => 3,
        }
    }
}

/// Top level of a scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// Output defaults.
    #[serde(default)]
    pub render: RenderDesc,
    /// The camera.
    pub camera: CameraDesc,
    /// `[[light]]` tables.
    #[serde(default, rename = "light")]
    pub lights: Vec<LightDesc>,
    /// `[[texture]]` tables.
    #[serde(default, rename = "texture")]
    pub textures: Vec<TextureDesc>,
    /// `[[material]]` tables.
    #[serde(default, rename = "material")]
    pub materials: Vec<MaterialDesc>,
    /// `[[object]]` tables.
    #[serde(default, rename = "object")]
    pub objects: Vec<ObjectDesc>,
    /// `[[nurbs]]` tables.
    #[serde(default, rename = "nurbs")]
    pub nurbs: Vec<NurbsDesc>,
}

/// `[[nurbs]]`: a NURBS model (`surface`, `teapot`, `spray`) or file (IGES,
/// OBJ free-form, hitex JSON), placed like an object.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NurbsDesc {
    /// Built-in model name.
    pub model: Option<String>,
    /// File, relative to the scene file.
    pub file: Option<String>,
    /// Translation.
    #[serde(default)]
    pub translate: [f32; 3],
    /// Rotation in degrees about x, then y, then z.
    #[serde(default)]
    pub rotate: [f32; 3],
    /// Scale per axis.
    #[serde(default = "d_white")]
    pub scale: [f32; 3],
    /// Tessellation density per patch side (only places fragments).
    #[serde(default = "d_density")]
    pub density: u32,
}

fn d_density() -> u32 {
    8
}

fn d_nurbs_mode() -> String {
    "shaded".into()
}

/// Display modes a scene may ask of its NURBS patches.
pub const NURBS_MODES: [&str; 8] =
    ["shaded", "isophote", "zebra", "highlight", "gauss", "mean", "vertex-normals", "normal"];

/// A NURBS model as a loader returns it: surfaces with parameter ranges and trims.
pub type LoadedNurbs = Vec<(crate::nurbs::NurbsSurface, ((f64, f64), (f64, f64)), Vec<Vec<[f64; 2]>>)>;

/// `[render]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    /// Output width in pixels.
    #[serde(default = "d_width")]
    pub width: u32,
    /// Output height in pixels.
    #[serde(default = "d_height")]
    pub height: u32,
    /// Linear RGB background.
    #[serde(default = "d_background")]
    pub background: [f32; 3],
    /// Linear RGB ambient light.
    #[serde(default = "d_ambient")]
    pub ambient: [f32; 3],
    /// Output mode.
    #[serde(default)]
    pub mode: RenderMode,
    /// Display mode of NURBS patches.
    #[serde(default = "d_nurbs_mode")]
    pub nurbs_mode: String,
}

impl Default for RenderDesc {
    fn default() -> Self {
        Self {
            width: d_width(),
            height: d_height(),
            background: d_background(),
            ambient: d_ambient(),
            mode: RenderMode::Shaded,
            nurbs_mode: d_nurbs_mode(),
        }
    }
}

/// `[camera]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Eye position.
    pub position: [f32; 3],
    /// Point looked at.
    pub target: [f32; 3],
    /// Up direction.
    #[serde(default = "d_up")]
    pub up: [f32; 3],
    /// Vertical field of view, degrees.
    #[serde(default = "d_fov")]
    pub fov_y: f32,
    /// Near clipping distance.
    #[serde(default = "d_near")]
    pub near: f32,
    /// Far clipping distance.
    #[serde(default = "d_far")]
    pub far: f32,
}

/// Kind of a `[[light]]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LightKind {
    /// Needs `direction`.
    Directional,
    /// Needs `position`.
    Point,
}

/// `[[light]]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDesc {
    /// `"directional"` or `"point"`.
    #[serde(rename = "type")]
    pub kind: LightKind,
    /// Direction of travel (directional lights).
    pub direction: Option<[f32; 3]>,
    /// Position (point lights).
    pub position: Option<[f32; 3]>,
    /// Linear RGB colour.
    #[serde(default = "d_white")]
    pub color: [f32; 3],
    /// Scale of the colour.
    #[serde(default = "d_one")]
    pub intensity: f32,
}

/// `[[texture]]`: either a procedural `pattern` or an image `file`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextureDesc {
    /// Name materials refer to.
    pub name: String,
    /// `checker`, `uv-grid` or `bricks`.
    pub pattern: Option<String>,
    /// Image file (PNG or JPEG), relative to the scene file.
    pub file: Option<String>,
    /// Side of a procedural pattern in texels.
    #[serde(default = "d_tex_size")]
    pub size: u32,
    /// `srgb` (colour images) or `linear` (data).
    #[serde(default)]
    pub color_space: ColorSpaceDesc,
    /// Build a MIP pyramid (true) or keep level 0 only.
    #[serde(default = "d_true")]
    pub mipmaps: bool,
}

/// Colour space names in scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ColorSpaceDesc {
    /// sRGB-encoded colour.
    #[default]
    Srgb,
    /// Linear data.
    Linear,
}

/// Filter names in scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FilterDesc {
    /// [`Filter::Nearest`]
    Nearest,
    /// [`Filter::Bilinear`]
    Bilinear,
    /// [`Filter::Trilinear`]
    #[default]
    Trilinear,
}

/// Wrap names in scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WrapDesc {
    /// [`Wrap::Repeat`]
    #[default]
    Repeat,
    /// [`Wrap::Clamp`]
    Clamp,
    /// [`Wrap::Mirror`]
    Mirror,
}

/// Level-rule names in scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LevelRuleDesc {
    /// [`LevelRule::MaxPartial`] (the paper's eq. (2)).
    #[default]
    MaxPartial,
    /// [`LevelRule::VulkanRho`].
    VulkanRho,
}

/// `[[material]]`
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    /// Name objects refer to.
    pub name: String,
    /// Texture name, if any.
    pub texture: Option<String>,
    /// Linear RGBA multiplier.
    #[serde(default = "d_color")]
    pub color: [f32; 4],
    /// Texture filter.
    #[serde(default)]
    pub filter: FilterDesc,
    /// Texture wrap mode.
    #[serde(default)]
    pub wrap: WrapDesc,
    /// Level selection rule.
    #[serde(default)]
    pub level_rule: LevelRuleDesc,
    /// Added to the MIP level.
    #[serde(default)]
    pub lod_bias: f32,
    /// Multiplies texture coordinates.
    #[serde(default = "d_uv_scale")]
    pub uv_scale: [f32; 2],
    /// Highlight strength.
    #[serde(default)]
    pub specular: f32,
    /// Highlight exponent.
    #[serde(default = "d_shininess")]
    pub shininess: f32,
    /// Light by the normal as authored, also seen from behind (height
    /// fields); by default the normal is turned towards the eye.
    #[serde(default)]
    pub one_sided: bool,
}

/// `[[object]]`: a procedural `mesh` or a mesh `file`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    /// `plane`, `cube`, `sphere` or `torus`.
    pub mesh: Option<String>,
    /// Mesh file (Wavefront OBJ), relative to the scene file.
    pub file: Option<String>,
    /// Material name (the first material when omitted; a white matte one if
    /// the scene has none).
    pub material: Option<String>,
    /// Translation.
    #[serde(default)]
    pub translate: [f32; 3],
    /// Rotation in degrees about x, then y, then z.
    #[serde(default)]
    pub rotate: [f32; 3],
    /// Scale per axis.
    #[serde(default = "d_white")]
    pub scale: [f32; 3],
}

fn d_width() -> u32 {
    960
}
fn d_height() -> u32 {
    540
}
fn d_background() -> [f32; 3] {
    [0.35, 0.5, 0.75]
}
fn d_ambient() -> [f32; 3] {
    [0.12, 0.13, 0.16]
}
fn d_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn d_fov() -> f32 {
    45.0
}
fn d_near() -> f32 {
    0.05
}
fn d_far() -> f32 {
    1000.0
}
fn d_white() -> [f32; 3] {
    [1.0; 3]
}
fn d_one() -> f32 {
    1.0
}
fn d_tex_size() -> u32 {
    512
}
fn d_true() -> bool {
    true
}
fn d_color() -> [f32; 4] {
    [1.0; 4]
}
fn d_uv_scale() -> [f32; 2] {
    [1.0; 2]
}
fn d_shininess() -> f32 {
    32.0
}

/// Loads the files a scene refers to. Paths are as written in the scene file;
/// the loader resolves them (usually against the scene file's directory).
pub trait AssetLoader {
    /// Error of the loader; core validation errors convert into it.
    type Error: From<CoreError>;
    /// Reads an image file.
    fn load_image(&self, path: &str, color_space: ColorSpace) -> Result<Image, Self::Error>;
    /// Reads a mesh file; one mesh per group/object in the file.
    fn load_meshes(&self, path: &str) -> Result<Vec<Mesh>, Self::Error>;
    /// Reads a NURBS model: a built-in name (`is_file` false) or a file.
    fn load_nurbs(&self, spec: &str, is_file: bool) -> Result<LoadedNurbs, Self::Error>;
}

/// A loader for scenes that must not touch the file system (the embedded
/// showcase): every file reference is an error.
pub struct NoFiles;

impl AssetLoader for NoFiles {
    type Error = CoreError;
    fn load_image(&self, path: &str, _: ColorSpace) -> Result<Image, CoreError> {
        Err(CoreError::InvalidScene {
            key: "texture.file".into(),
            message: format!("'{path}': this scene may not load files"),
        })
    }
    fn load_meshes(&self, path: &str) -> Result<Vec<Mesh>, CoreError> {
        Err(CoreError::InvalidScene {
            key: "object.file".into(),
            message: format!("'{path}': this scene may not load files"),
        })
    }
    fn load_nurbs(&self, spec: &str, _: bool) -> Result<LoadedNurbs, CoreError> {
        Err(CoreError::InvalidScene {
            key: "nurbs".into(),
            message: format!("'{spec}': this scene may not load NURBS models"),
        })
    }
}

fn scene_err(key: String, message: impl Into<String>) -> CoreError {
    CoreError::InvalidScene { key, message: message.into() }
}

fn finite_n(key: &str, v: &[f32]) -> Result<(), CoreError> {
    for (i, c) in v.iter().enumerate() {
        finite(&format!("{key}[{i}]"), *c as f64)?;
    }
    Ok(())
}

/// A TOML error on one line: `line L, column C: message` (the position
/// once, from the error's span into `text`).
pub fn toml_message(text: &str, e: &toml::de::Error) -> String {
    let msg = e.message().trim_end().replace('\n', " ");
    match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            format!("line {line}, column {col}: {msg}")
        }
        None => msg,
    }
}

impl SceneDesc {
    /// Parses TOML text (syntax, types and unknown keys are checked here; the
    /// message carries line and column).
    pub fn from_toml(text: &str) -> Result<Self, CoreError> {
        toml::from_str(text).map_err(|e| CoreError::Toml(toml_message(text, &e)))
    }

    /// The embedded showcase.
    pub fn showcase() -> Self {
        match Self::from_toml(SHOWCASE_TOML) {
            Ok(d) => d,
            Err(e) => unreachable!("embedded showcase scene parses: {e}"),
        }
    }

    /// Validates every value and loads every referenced file.
    pub fn resolve<L: AssetLoader>(&self, loader: &L) -> Result<Scene, L::Error> {
        let r = &self.render;
        if r.width == 0 || r.height == 0 || r.width > MAX_OUTPUT_SIDE || r.height > MAX_OUTPUT_SIDE {
            return Err(scene_err(
                "render.width/height".into(),
                format!("{}x{} is outside 1..={MAX_OUTPUT_SIDE}", r.width, r.height),
            )
            .into());
        }
        let background = finite3("render.background", r.background)?;
        let ambient = finite3("render.ambient", r.ambient)?;

        // camera
        let c = &self.camera;
        let camera = Camera {
            position: finite3("camera.position", c.position)?,
            target: finite3("camera.target", c.target)?,
            up: finite3("camera.up", c.up)?,
            fov_y_deg: finite("camera.fov_y", c.fov_y as f64)? as f32,
            near: finite("camera.near", c.near as f64)? as f32,
            far: finite("camera.far", c.far as f64)? as f32,
        };
        camera.validate()?;

        // lights
        if self.lights.len() > MAX_LIGHTS {
            return Err(scene_err(
                "light".into(),
                format!("{} lights; at most {MAX_LIGHTS} are supported", self.lights.len()),
            )
            .into());
        }
        let mut lights = Vec::new();
        for (i, l) in self.lights.iter().enumerate() {
            let k = format!("light[{i}]");
            let color = finite3(&format!("{k}.color"), l.color)?;
            let intensity = finite(&format!("{k}.intensity"), l.intensity as f64)? as f32;
            if color.min_element() < 0.0 || intensity < 0.0 {
                return Err(scene_err(k, "color and intensity must not be negative").into());
            }
            lights.push(match l.kind {
                LightKind::Directional => {
                    let d = l.direction.ok_or_else(|| scene_err(k.clone(), "a directional light needs 'direction'"))?;
                    let direction = finite3(&format!("{k}.direction"), d)?;
                    if direction.length() == 0.0 {
                        return Err(scene_err(format!("{k}.direction"), "direction is zero").into());
                    }
                    Light::Directional { direction, color, intensity }
                }
                LightKind::Point => {
                    let p = l.position.ok_or_else(|| scene_err(k.clone(), "a point light needs 'position'"))?;
                    Light::Point { position: finite3(&format!("{k}.position"), p)?, color, intensity }
                }
            });
        }

        // textures
        let mut tex_index = HashMap::new();
        let mut textures = Vec::new();
        for (i, t) in self.textures.iter().enumerate() {
            let k = format!("texture[{i}]");
            if tex_index.insert(t.name.clone(), i).is_some() {
                return Err(scene_err(format!("{k}.name"), format!("duplicate texture name '{}'", t.name)).into());
            }
            let cs = match t.color_space {
                ColorSpaceDesc::Srgb => ColorSpace::Srgb,
                ColorSpaceDesc::Linear => ColorSpace::Linear,
            };
            let img = match (&t.pattern, &t.file) {
                (Some(p), None) => {
                    let pat = Pattern::from_name(p).ok_or_else(|| {
                        let names: Vec<_> = Pattern::ALL.iter().map(|p| p.name()).collect();
                        scene_err(
                            format!("{k}.pattern"),
                            format!("unknown pattern '{p}' (known: {})", names.join(", ")),
                        )
                    })?;
                    if t.size == 0 || t.size > 8192 {
                        return Err(scene_err(format!("{k}.size"), format!("{} is outside 1..=8192", t.size)).into());
                    }
                    pat.render(t.size)?
                }
                (None, Some(f)) => loader.load_image(f, cs)?,
                _ => return Err(scene_err(k, "give exactly one of 'pattern' or 'file'").into()),
            };
            textures.push(Arc::new(if t.mipmaps { MipPyramid::build(img) } else { MipPyramid::single(img) }));
        }

        // materials
        let mut mat_index = HashMap::new();
        let mut materials = Vec::new();
        for (i, m) in self.materials.iter().enumerate() {
            let k = format!("material[{i}]");
            if mat_index.insert(m.name.clone(), i).is_some() {
                return Err(scene_err(format!("{k}.name"), format!("duplicate material name '{}'", m.name)).into());
            }
            finite_n(&format!("{k}.color"), &m.color)?;
            finite_n(&format!("{k}.uv_scale"), &m.uv_scale)?;
            finite(&format!("{k}.lod_bias"), m.lod_bias as f64)?;
            finite(&format!("{k}.specular"), m.specular as f64)?;
            finite(&format!("{k}.shininess"), m.shininess as f64)?;
            if m.shininess < 0.0 || m.specular < 0.0 {
                return Err(scene_err(k, "specular and shininess must not be negative").into());
            }
            let texture = match &m.texture {
                None => None,
                Some(n) => Some(
                    *tex_index
                        .get(n)
                        .ok_or_else(|| scene_err(format!("{k}.texture"), format!("no texture named '{n}'")))?,
                ),
            };
            materials.push(Material {
                name: m.name.clone(),
                base_color: Vec4::from_array(m.color),
                texture,
                sampler: SamplerOptions {
                    filter: match m.filter {
                        FilterDesc::Nearest => Filter::Nearest,
                        FilterDesc::Bilinear => Filter::Bilinear,
                        FilterDesc::Trilinear => Filter::Trilinear,
                    },
                    wrap: match m.wrap {
                        WrapDesc::Repeat => Wrap::Repeat,
                        WrapDesc::Clamp => Wrap::Clamp,
                        WrapDesc::Mirror => Wrap::Mirror,
                    },
                    level_rule: match m.level_rule {
                        LevelRuleDesc::MaxPartial => LevelRule::MaxPartial,
                        LevelRuleDesc::VulkanRho => LevelRule::VulkanRho,
                    },
                    lod_bias: m.lod_bias,
                },
                uv_scale: Vec2::from_array(m.uv_scale),
                specular: m.specular,
                shininess: m.shininess,
                one_sided: m.one_sided,
            });
        }
        if materials.is_empty() {
            materials.push(Material::default());
        }

        // objects
        let mut objects = Vec::new();
        let mut cache: HashMap<String, Vec<Arc<Mesh>>> = HashMap::new();
        for (i, o) in self.objects.iter().enumerate() {
            let k = format!("object[{i}]");
            let translate = finite3(&format!("{k}.translate"), o.translate)?;
            let rotate = finite3(&format!("{k}.rotate"), o.rotate)?;
            let scale = finite3(&format!("{k}.scale"), o.scale)?;
            if scale.abs().min_element() == 0.0 {
                return Err(scene_err(format!("{k}.scale"), "a zero scale flattens the object").into());
            }
            let material = match &o.material {
                None => 0,
                Some(n) => *mat_index
                    .get(n)
                    .ok_or_else(|| scene_err(format!("{k}.material"), format!("no material named '{n}'")))?,
            };
            let meshes = match (&o.mesh, &o.file) {
                (Some(name), None) => {
                    let m = match name.as_str() {
                        "plane" => Mesh::plane(),
                        "cube" => Mesh::cube(),
                        "sphere" => Mesh::sphere(64, 32),
                        "torus" => Mesh::torus(0.35, 64, 24),
                        _ => {
                            return Err(scene_err(
                                format!("{k}.mesh"),
                                format!("unknown mesh '{name}' (known: plane, cube, sphere, torus)"),
                            )
                            .into());
                        }
                    };
                    vec![Arc::new(m)]
                }
                (None, Some(f)) => {
                    if let Some(m) = cache.get(f) {
                        m.clone()
                    } else {
                        let m: Vec<Arc<Mesh>> = loader.load_meshes(f)?.into_iter().map(Arc::new).collect();
                        cache.insert(f.clone(), m.clone());
                        m
                    }
                }
                _ => return Err(scene_err(k, "give exactly one of 'mesh' or 'file'").into()),
            };
            let rot =
                Quat::from_euler(EulerRot::XYZ, rotate.x.to_radians(), rotate.y.to_radians(), rotate.z.to_radians());
            let transform = Mat4::from_scale_rotation_translation(scale, rot, translate);
            for mesh in meshes {
                objects.push(Object { mesh, transform, material });
            }
        }

        // NURBS patches: control points through the object's affine transform (exact)
        if !NURBS_MODES.contains(&r.nurbs_mode.as_str()) {
            return Err(scene_err(
                "render.nurbs_mode".into(),
                format!("unknown mode '{}' (known: {})", r.nurbs_mode, NURBS_MODES.join(", ")),
            )
            .into());
        }
        let mut nurbs = Vec::new();
        for (i, n) in self.nurbs.iter().enumerate() {
            let k = format!("nurbs[{i}]");
            let translate = finite3(&format!("{k}.translate"), n.translate)?;
            let rotate = finite3(&format!("{k}.rotate"), n.rotate)?;
            let scale = finite3(&format!("{k}.scale"), n.scale)?;
            if scale.abs().min_element() == 0.0 {
                return Err(scene_err(format!("{k}.scale"), "a zero scale flattens the model").into());
            }
            if n.density == 0 || n.density > 256 {
                return Err(scene_err(format!("{k}.density"), format!("{} is outside 1..=256", n.density)).into());
            }
            let loaded = match (&n.model, &n.file) {
                (Some(m), None) => loader.load_nurbs(m, false)?,
                (None, Some(f)) => loader.load_nurbs(f, true)?,
                _ => return Err(scene_err(k, "give exactly one of 'model' or 'file'").into()),
            };
            let rot =
                Quat::from_euler(EulerRot::XYZ, rotate.x.to_radians(), rotate.y.to_radians(), rotate.z.to_radians());
            let m = Mat4::from_scale_rotation_translation(scale, rot, translate).as_dmat4();
            for (mut surface, range, trim) in loaded {
                for c in &mut surface.points {
                    let p = m.transform_point3(glam::DVec3::new(c[0], c[1], c[2]));
                    c[0] = p.x;
                    c[1] = p.y;
                    c[2] = p.z;
                }
                nurbs.push(super::NurbsObject { surface, range, trim, density: n.density });
            }
        }

        Ok(Scene {
            nurbs,
            nurbs_mode: r.nurbs_mode.clone(),
            camera,
            lights,
            ambient,
            background,
            textures,
            materials,
            objects,
            width: r.width,
            height: r.height,
            mode: r.mode,
        })
    }
}

/// Resolves the embedded showcase scene.
pub fn showcase_scene() -> Scene {
    match SceneDesc::showcase().resolve(&NoFiles) {
        Ok(s) => s,
        Err(e) => unreachable!("embedded showcase scene resolves: {e}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        match SceneDesc::from_toml(text) {
            Err(e) => e.to_string(),
            Ok(d) => match d.resolve(&NoFiles) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("scene was accepted:\n{text}"),
            },
        }
    }

    const CAM: &str = "[camera]\nposition = [0, 1, 5]\ntarget = [0, 0, 0]\n";

    #[test]
    fn showcase_resolves() {
        let s = showcase_scene();
        assert!(s.objects.len() >= 4 && !s.textures.is_empty() && !s.lights.is_empty());
    }

    #[test]
    fn minimal_scene_resolves_with_defaults() {
        let s =
            SceneDesc::from_toml(&format!("{CAM}[[object]]\nmesh = \"cube\"\n")).unwrap().resolve(&NoFiles).unwrap();
        assert_eq!(s.materials.len(), 1);
        assert_eq!((s.width, s.height), (960, 540));
    }

    #[test]
    fn unknown_key_names_key_and_line() {
        let e = err(&format!("{CAM}fov = 30\n"));
        assert!(e.contains("fov") && e.contains("line 4"), "{e}");
    }

    #[test]
    fn wrong_type_names_line() {
        let e = err("[camera]\nposition = \"here\"\ntarget = [0, 0, 0]\n");
        assert!(e.contains("line 2"), "{e}");
    }

    #[test]
    fn non_finite_numbers_name_the_key() {
        let e = err("[camera]\nposition = [0, nan, 5]\ntarget = [0, 0, 0]\n");
        assert!(e.contains("camera.position[1]") && e.contains("not finite"), "{e}");
        let e = err(&format!("{CAM}[[light]]\ntype = \"point\"\nposition = [0, 0, inf]\n"));
        assert!(e.contains("light[0].position[2]"), "{e}");
        let e = err(&format!("{CAM}[[material]]\nname = \"m\"\nlod_bias = -inf\n"));
        assert!(e.contains("material[0].lod_bias"), "{e}");
    }

    #[test]
    fn degenerate_cameras() {
        let e = err("[camera]\nposition = [1, 1, 1]\ntarget = [1, 1, 1]\n");
        assert!(e.contains("degenerate camera") && e.contains("target"), "{e}");
        let e = err(&format!("{CAM}fov_y = 0\n"));
        assert!(e.contains("fov_y"), "{e}");
        let e = err(&format!("{CAM}fov_y = 180\n"));
        assert!(e.contains("fov_y"), "{e}");
    }

    #[test]
    fn dangling_references_and_bad_names() {
        assert!(
            err(&format!("{CAM}[[object]]\nmesh = \"cube\"\nmaterial = \"gold\"\n")).contains("object[0].material")
        );
        assert!(err(&format!("{CAM}[[material]]\nname = \"m\"\ntexture = \"t\"\n")).contains("material[0].texture"));
        assert!(err(&format!("{CAM}[[object]]\nmesh = \"teapot\"\n")).contains("object[0].mesh"));
        assert!(err(&format!("{CAM}[[texture]]\nname = \"t\"\npattern = \"zebra\"\n")).contains("texture[0].pattern"));
        assert!(err(&format!("{CAM}[[texture]]\nname = \"t\"\n")).contains("exactly one"));
        assert!(err(&format!("{CAM}[[light]]\ntype = \"directional\"\n")).contains("direction"));
        assert!(err(&format!("{CAM}[[light]]\ntype = \"spot\"\n")).contains("spot"));
        assert!(err(&format!("{CAM}[render]\nwidth = 0\n")).contains("render.width"));
        assert!(err(&format!("{CAM}[[object]]\nmesh = \"cube\"\nscale = [1, 0, 1]\n")).contains("object[0].scale"));
        assert!(err(&format!("{CAM}[[object]]\nfile = \"x.obj\"\n")).contains("x.obj"));
    }
}
