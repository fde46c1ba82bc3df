//! NURBS scenes → data both backends consume: the paper's knot and
//! control-point textures, and a coarse tessellation that only generates
//! fragments carrying (u, v, patch).
//!
//! Files: `modes` (the display modes, their shader indices and flags),
//! `packed` (the knot, control-point, trim, edge and deviation textures),
//! `mesh` (the tessellation grids fitted to a tolerance and the mesh that
//! places the fragments); here the frame uniforms, the views and
//! [`PreparedNurbs`].

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use hitex_core::nurbs::NurbsSurface;
use hitex_core::scene::Camera;

pub use crate::nurbs_model::{Density, MeshCut, model_size};

/// The degrees with straight-line kernels in both fragment programs (the
/// paper's prepared degrees); others run the any-degree loops, or are raised
/// to the nearest prepared degree above them by [`PreparedNurbs::elevate_to_prepared`].
pub const PREPARED_DEGREES: [usize; 2] = [3, 5];

/// The nearest prepared degree at or above `d` (None above the largest).
pub fn prepared_degree_for(d: usize) -> Option<usize> {
    PREPARED_DEGREES.iter().copied().find(|&p| p >= d)
}

/// A patch's parameter range `((u0, u1), (v0, v1))`.
pub type ParamRange = ((f64, f64), (f64, f64));

mod mesh;
mod modes;
mod packed;

pub use mesh::{FAN_MARK, MAX_FITTED_TRIANGLES, fitted_grids};
pub use modes::{ISOLINE_RGB, NurbsMode, SECTION_RGB, flag, mode_index, wgsl_mode_constants};
pub use packed::{
    EdgeRun, MAX_DEVIATION_GRID, MAX_EDGE_SEGMENTS, MAX_TRIM_EDGES, PackedNurbs, TrimLoops, TrimSimplified,
};

/// A tessellation vertex: coarse position, exact normal there, (u, v), patch.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct NurbsVertex {
    /// Surface point at the vertex (only places the fragments).
    pub position: [f32; 3],
    /// Exact (limit) unit normal at the vertex, for the vertex-normal mode.
    pub normal: [f32; 3],
    /// Surface parameters.
    pub uv: [f32; 2],
    /// Patch index (a whole number).
    pub patch: f32,
    /// Padding.
    pub _pad: f32,
}

/// Default tolerance of the draft mode, degrees.
pub const DEFAULT_DRAFT_TOLERANCE_DEG: f32 = 1.0;

/// Per-frame uniforms of `nurbs.wgsl` (group 0, binding 0).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct NurbsFrame {
    /// World-to-clip matrix.
    pub view_proj: [[f32; 4]; 4],
    /// Camera position.
    pub camera: [f32; 4],
    /// Unit direction towards the light.
    pub light: [f32; 4],
    /// x: mode, y: isophote bands, z: zebra / highlight stripes, w: flags
    /// ([`flag`]: prepared-degree kernels, patch boundaries, isoparametric
    /// lines, sections).
    pub params: [u32; 4],
    /// x, y: curvature range for the colour ramp (deviation mode: the
    /// tolerance and the range); z: ambient; w: 1 / the tool radius of the
    /// radius mode.
    pub ranges: [f32; 4],
    /// Linear background RGB.
    pub background: [f32; 4],
    /// Model bounding sphere: centre xyz, radius w (places the highlight-line plane).
    pub model: [f32; 4],
    /// Draft: unit pull direction xyz, w: sine of the draft tolerance.
    pub pull: [f32; 4],
    /// Overlays: xyz the section planes' unit normal divided by their
    /// spacing (a section wherever `P·xyz` is a whole number), w the
    /// isoparametric lines per patch and direction.
    pub lines: [f32; 4],
    /// The view's up axis (unit; the model's up): the zebra's light bars
    /// and the studio's horizon lie across it.
    pub up: [f32; 4],
}

/// Which model axis points up in a view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpAxis {
    /// The axis of a flat model's smallest extent (a sheet lies on its
    /// largest face), else Z (the usual CAD convention).
    Auto,
    /// A signed model axis: 0 = X, 1 = Y, 2 = Z; `true` for negative.
    Axis(usize, bool),
}

impl UpAxis {
    /// Parses `auto`, `x`, `y`, `z`, `+z`, `-y`, …
    pub fn parse(s: &str) -> Result<Self, crate::RenderError> {
        let t = s.trim().to_ascii_lowercase();
        if t == "auto" {
            return Ok(Self::Auto);
        }
        let (neg, name) = match t.strip_prefix('-') {
            Some(r) => (true, r),
            None => (false, t.strip_prefix('+').unwrap_or(&t)),
        };
        let k = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => {
                return Err(crate::RenderError::Invalid(format!(
                    "'{s}' is not an axis: give auto, x, y, z, -x, -y or -z"
                )));
            }
        };
        Ok(Self::Axis(k, neg))
    }

    /// The axis as a unit vector (`Auto`: +Z).
    pub fn direction(self) -> Vec3 {
        match self {
            Self::Auto => Vec3::Z,
            Self::Axis(k, neg) => {
                let mut v = Vec3::ZERO;
                v[k.min(2)] = if neg { -1.0 } else { 1.0 };
                v
            }
        }
    }

    /// `+X`, `-Z`, … (`auto` before it is resolved).
    pub fn name(self) -> String {
        match self {
            Self::Auto => "auto".into(),
            Self::Axis(k, neg) => format!("{}{}", if neg { '-' } else { '+' }, ["X", "Y", "Z"][k.min(2)]),
        }
    }
}

/// How a model is looked at: which way is up, the turn about it and the
/// elevation above the horizontal, in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelView {
    /// The model's up axis.
    pub up: UpAxis,
    /// Turn about the up axis, degrees.
    pub turn_deg: f32,
    /// Elevation of the eye above the horizontal plane, degrees in [−89, 89].
    pub elevation_deg: f32,
}

impl ModelView {
    /// Default elevation: the eye about 23.5° above the horizontal.
    pub const ELEVATION_DEG: f32 = 23.5;
    /// Default azimuth of the eye from the −(second axis) side, degrees.
    const AZIMUTH_DEG: f32 = 29.54;
}

impl Default for ModelView {
    fn default() -> Self {
        Self { up: UpAxis::Auto, turn_deg: 0.0, elevation_deg: Self::ELEVATION_DEG }
    }
}

/// A NURBS model ready for either backend.
#[derive(Debug, Clone)]
pub struct PreparedNurbs {
    /// The surfaces (f64 reference).
    pub surfaces: Vec<NurbsSurface>,
    /// Tessellation vertices.
    pub vertices: Vec<NurbsVertex>,
    /// Triangles.
    pub indices: Vec<u32>,
    /// Knot and control-point textures.
    pub packed: PackedNurbs,
    /// Camera framing the model.
    pub camera: Camera,
    /// Display mode.
    pub mode: NurbsMode,
    /// Isophote bands over 180°.
    pub bands: u32,
    /// Zebra stripes over 180°.
    pub stripes: u32,
    /// Pull (demoulding) direction of the draft mode.
    pub pull: Vec3,
    /// Draft angles within ± this many degrees count as "no draft".
    pub draft_tolerance_deg: f32,
    /// Tool radius of the radius mode (model units; 0: 1/50 of the model's
    /// bounding diameter).
    pub tool_radius: f32,
    /// Deviation mode: `(tolerance, range)` in model units — within ±
    /// tolerance green, the colour ramps saturate at ± range.
    pub deviation_range: (f32, f32),
    /// Curvature mapped to full colour on the ramp: [Gaussian, mean,
    /// principal]; by default twice the area-weighted 75th percentile of |K|
    /// and |H| over the surface (over its curved part where flat faces hold
    /// more than a quarter of the area), and of max(|κ1|, |κ2|) over its curved part
    /// (radius of curvature below 10⁴ × the model's bounding radius; none:
    /// 1 / that radius).
    pub curvature_range: [f32; 3],
    /// Whether each default of [`PreparedNurbs::curvature_range`] was
    /// taken over the curved part alone (always for the principal ramp; for
    /// |K| and |H| where flat faces hold more than a quarter of the area).
    pub curvature_over_curved_part: [bool; 3],
    /// Linear background.
    pub background: Vec3,
    /// Use the straight-line kernels of the prepared degree (bicubic) for
    /// patches of that degree, as the paper does; otherwise the any-degree loops.
    pub prepared_kernels: bool,
    /// Draw patch boundaries (one pixel wide) over the display mode.
    pub boundaries: bool,
    /// Draw this many isoparametric lines per patch and direction (at
    /// equal steps of each patch's parameter range, its edges included; 0:
    /// none), one pixel wide, over the display mode.
    pub isolines: u32,
    /// Draw section curves of the planes `P·normal = k·spacing` (a unit
    /// normal and a spacing in model units), one pixel wide.
    pub sections: Option<(Vec3, f32)>,
    /// Draw the edges set by [`PreparedNurbs::set_edges`] (three pixels wide).
    pub edges: bool,
    /// Direction towards the light; `None`: over the viewer's shoulder.
    pub light: Option<Vec3>,
    /// Bounding sphere of the tessellation: centre, radius.
    pub bounds: (Vec3, f32),
    /// Largest distance between the exact surface and its tessellation,
    /// estimated at every cell's centre (model units).
    pub tess_deviation: f32,
    /// Let the CPU backend skip fragments that lie behind the depth already
    /// drawn by more than the tessellation's deviation allows (a conservative
    /// early depth test; the image is the same).
    pub early_depth: bool,
    id: u64,
}

static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1 << 40);

impl PreparedNurbs {
    /// Tessellates every patch over its parameter range into a
    /// `density`×`density` grid and frames the model with a camera.
    pub fn new(surfaces: Vec<NurbsSurface>, ranges: &[ParamRange], density: u32) -> Self {
        let densities = vec![density; surfaces.len()];
        Self::with_densities(surfaces, ranges, &densities)
    }

    /// Like [`PreparedNurbs::new`] for a model whose patches carry trim
    /// loops (`trims[k]` for patch k; empty: untrimmed). Models read from
    /// files (IGES 144/142, free-form OBJ) go through this one, so that no
    /// caller can drop their trims by forgetting a step.
    pub fn trimmed(surfaces: Vec<NurbsSurface>, ranges: &[ParamRange], trims: &[TrimLoops], density: u32) -> Self {
        let mut p = Self::new(surfaces, ranges, density);
        if trims.iter().any(|t| !t.is_empty()) {
            p.set_trims(trims);
        }
        p
    }

    /// Like [`PreparedNurbs::new`] with a tessellation density per patch.
    pub fn with_densities(surfaces: Vec<NurbsSurface>, ranges: &[ParamRange], densities: &[u32]) -> Self {
        let grids: Vec<(u32, u32)> = densities.iter().map(|&d| (d, d)).collect();
        Self::with_grids(surfaces, ranges, &grids)
    }

    /// Like [`PreparedNurbs::trimmed`] with each patch's own grid, cells
    /// along u and along v (e.g. from [`fitted_grids`]); a patch beyond
    /// `grids` takes 8×8, sides are clamped to 1…256.
    pub fn trimmed_grids(
        surfaces: Vec<NurbsSurface>,
        ranges: &[ParamRange],
        trims: &[TrimLoops],
        grids: &[(u32, u32)],
    ) -> Self {
        let mut p = Self::with_grids(surfaces, ranges, grids);
        if trims.iter().any(|t| !t.is_empty()) {
            p.set_trims(trims);
        }
        p
    }
    /// The paper's design for shaders without loops: raises every patch whose
    /// degree lies below a prepared degree (3 or 5) to the nearest one above
    /// it by exact degree elevation, so that the prepared kernels evaluate it.
    /// The surfaces, their parameterisation and so the tessellation stay the
    /// same. Returns how many patches were elevated.
    pub fn elevate_to_prepared(&mut self) -> usize {
        let mut count = 0;
        for s in &mut self.surfaces {
            let (Some(pu), Some(pv)) = (prepared_degree_for(s.degree_u), prepared_degree_for(s.degree_v)) else {
                continue;
            };
            if (pu, pv) == (s.degree_u, s.degree_v) {
                continue;
            }
            while s.degree_u < pu {
                *s = s.elevate(true);
            }
            while s.degree_v < pv {
                *s = s.elevate(false);
            }
            count += 1;
        }
        if count > 0 {
            // trims stay: elevation keeps the parameterisation
            let (width, trims) = (self.packed.trim_width, std::mem::take(&mut self.packed.trims));
            let colors = std::mem::take(&mut self.packed.colors);
            let simplified = std::mem::take(&mut self.packed.trims_simplified);
            let deviation = (self.packed.deviation_width, std::mem::take(&mut self.packed.deviation));
            let edges = (self.packed.edges_width, std::mem::take(&mut self.packed.edges));
            self.packed = PackedNurbs::new(&self.surfaces);
            self.packed.trim_width = width;
            self.packed.trims = trims;
            self.packed.colors = colors;
            self.packed.trims_simplified = simplified;
            (self.packed.deviation_width, self.packed.deviation) = deviation;
            (self.packed.edges_width, self.packed.edges) = edges;
            self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        count
    }

    /// The up axis `Auto` resolves to: for a flat model (its thinnest extent
    /// under half the middle one) the axis of that extent, else +Z.
    pub fn detect_up(&self) -> UpAxis {
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for v in &self.vertices {
            for t in 0..3 {
                lo[t] = lo[t].min(v.position[t]);
                hi[t] = hi[t].max(v.position[t]);
            }
        }
        let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
        if !ext.iter().all(|e| e.is_finite()) {
            return UpAxis::Axis(2, false);
        }
        // a flat part (its thinnest extent under half the middle one) lies on
        // its largest face; anything else stands on Z, the usual CAD convention
        let mut order = [0, 1, 2];
        order.sort_by(|&a, &b| ext[a].total_cmp(&ext[b]));
        let k = if ext[order[0]] < 0.5 * ext[order[1]] { order[0] } else { 2 };
        UpAxis::Axis(k, false)
    }

    /// A camera showing the whole model from `view`, fitted into the window
    /// `[x0, x1] × [y0, y1]` of normalised device coordinates of a frame of
    /// `aspect` (width / height), with the same field of view as
    /// [`PreparedNurbs::camera`]. Falls back to that camera if the model has
    /// no finite vertex.
    pub fn view_camera(&self, view: &ModelView, aspect: f32, window: [f32; 4]) -> Camera {
        let up = match view.up {
            UpAxis::Auto => self.detect_up(),
            a => a,
        };
        let UpAxis::Axis(k, neg) = up else { return self.camera };
        let k = k.min(2);
        let unit = |i: usize| Vec3::from_array(std::array::from_fn(|t| if t == i % 3 { 1.0 } else { 0.0 }));
        // (a, b, up) right-handed: Z-up gives (X, Y, Z)
        let sign = if neg { -1.0 } else { 1.0 };
        let (a, b, u) = (unit(k + 1) * sign, unit(k + 2), unit(k) * sign);
        let az = (ModelView::AZIMUTH_DEG + view.turn_deg).to_radians();
        let el = view.elevation_deg.clamp(-89.0, 89.0).to_radians();
        let toward = (a * az.sin() - b * az.cos()) * el.cos() + u * el.sin();
        let points: Vec<Vec3> = self.vertices.iter().map(|v| Vec3::from_array(v.position)).collect();
        Camera::framing(&points, toward, u, self.camera.fov_y_deg, aspect, window).unwrap_or(self.camera)
    }

    /// The margin of the conservative early depth test: how much nearer
    /// than its triangle a fragment's exact point may lie — the
    /// tessellation's deviation, with half as much again for the estimate
    /// (taken at cell centres) and a hair of the model's size.
    pub fn early_depth_margin(&self) -> f32 {
        1.5 * self.tess_deviation + 1e-5 * self.bounds.1
    }

    /// Gives patches their albedo for the shaded mode (see [`PackedNurbs::set_colors`]).
    pub fn set_colors(&mut self, colors: &[Option<[f32; 3]>]) {
        self.packed.set_colors(colors);
        self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Gives patches polylines to draw over the display mode (see
    /// [`PackedNurbs::set_edges`]) and turns the overlay on.
    pub fn set_edges(&mut self, runs: &[Vec<EdgeRun>]) {
        self.packed.set_edges(runs);
        self.edges = true;
        self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Gives patches a deviation grid for the deviation mode (see
    /// [`PackedNurbs::set_deviation`]; [`hitex_core::nurbs::deviation::deviation_grid`]
    /// computes one).
    pub fn set_deviation(&mut self, grid: usize, values: &[Vec<f32>]) {
        self.packed.set_deviation(grid, values);
        self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Trims patches by loops in their parameter space (see [`PackedNurbs::set_trims`]).
    pub fn set_trims(&mut self, trims: &[TrimLoops]) {
        self.packed.set_trims(trims);
        self.id = NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Identity of the uploaded content (geometry and packed textures).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Frame uniforms for `camera` at `width`×`height`.
    pub fn frame(&self, camera: &Camera, width: u32, height: u32) -> NurbsFrame {
        let vp: Mat4 = camera.view_proj(width as f32 / height as f32);
        // light over the viewer's shoulder
        let view_dir = (camera.target - camera.position).normalize();
        let right = view_dir.cross(camera.up).normalize_or_zero();
        let light = self
            .light
            .and_then(|l| l.try_normalize())
            .unwrap_or_else(|| (-view_dir + right * 0.4 + camera.up.normalize() * 0.6).normalize());
        let range = self.curvature_range[self.curvature_slot()];
        let sections = self
            .sections
            .and_then(|(n, spacing)| (spacing > 0.0 && spacing.is_finite()).then(|| n.normalize_or_zero() / spacing))
            .filter(|a| a.is_finite() && *a != Vec3::ZERO);
        let flags = if self.prepared_kernels { flag::PREPARED } else { 0 }
            | if self.boundaries { flag::BOUNDARIES } else { 0 }
            | if self.isolines > 0 { flag::ISOLINES } else { 0 }
            | if sections.is_some() { flag::SECTIONS } else { 0 }
            | if self.edges { flag::EDGES } else { 0 };
        NurbsFrame {
            view_proj: vp.to_cols_array_2d(),
            camera: camera.position.extend(1.0).to_array(),
            light: light.extend(0.0).to_array(),
            params: [self.mode.index(), self.bands, self.stripes, flags],
            ranges: if self.mode == NurbsMode::Deviation {
                [self.deviation_range.0, self.deviation_range.1, 0.12, 1.0 / self.effective_tool_radius()]
            } else {
                [-range, range, 0.12, 1.0 / self.effective_tool_radius()]
            },
            background: self.background.extend(1.0).to_array(),
            model: self.bounds.0.extend(self.bounds.1).to_array(),
            pull: self.pull.normalize_or(Vec3::Z).extend(self.draft_tolerance_deg.to_radians().sin()).to_array(),
            lines: sections.unwrap_or(Vec3::ZERO).extend(self.isolines as f32).to_array(),
            up: camera.up.normalize_or(Vec3::Z).extend(0.0).to_array(),
        }
    }

    /// Which [`PreparedNurbs::curvature_range`] the display mode's ramp
    /// uses: 0 Gaussian, 2 principal, 1 mean (and every other mode).
    pub fn curvature_slot(&self) -> usize {
        match self.mode {
            NurbsMode::Gauss => 0,
            NurbsMode::K1 | NurbsMode::K2 => 2,
            _ => 1,
        }
    }

    /// The radius mode's tool radius: as set, else 1/50 of the model's
    /// bounding diameter.
    pub fn effective_tool_radius(&self) -> f32 {
        if self.tool_radius > 0.0 && self.tool_radius.is_finite() {
            self.tool_radius
        } else {
            (self.bounds.1 / 25.0).max(f32::MIN_POSITIVE)
        }
    }

    /// Number of patches.
    pub fn patch_count(&self) -> usize {
        self.surfaces.len()
    }
}
