//! BTF scenes prepared for both backends: a surface carrying per-vertex
//! P, N, U, V and T, the index map and one codebook layout (optionally BC1),
//! and the per-frame uniform block `shaders/btf.wgsl` and `cpu/btf.rs` read.

use crate::RenderError;
use glam::{Mat4, Vec2, Vec3};
use hitex_core::btf::index::IndexMap;
use hitex_core::btf::mip::BtfMip;
use hitex_core::btf::pca::LocalPca;
use hitex_core::btf::{AngularGrid, Btf, Codebook, Layout};
use hitex_core::nurbs::NurbsSurface;
use hitex_core::scene::{Camera, Mesh};
use hitex_core::texture::ToneMap;
use hitex_core::texture::bc1::{self, Bc1Encoder};

/// Largest θ count the shaders take (uniform array of 64).
pub const MAX_RENDER_THETA: usize = 64;

/// A vertex of a BTF surface: the paper's five per-pixel inputs.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BtfVertex {
    /// Position P.
    pub position: [f32; 3],
    /// Unit normal N.
    pub normal: [f32; 3],
    /// Unit U: direction of increasing u on the tangent plane.
    pub tangent_u: [f32; 3],
    /// Unit V: direction of increasing v (not necessarily orthogonal to U).
    pub tangent_v: [f32; 3],
    /// Texture coordinate T, in index-map repeats.
    pub uv: [f32; 2],
}

/// A triangle surface for BTF rendering.
#[derive(Debug, Clone, Default)]
pub struct BtfSurface {
    /// Vertices.
    pub vertices: Vec<BtfVertex>,
    /// Triangle indices.
    pub indices: Vec<u32>,
}

fn arr(v: Vec3) -> [f32; 3] {
    v.to_array()
}

/// Component of `t` in the plane normal to `n`, normalised (`fallback` when it vanishes).
fn in_plane(t: Vec3, n: Vec3, fallback: Vec3) -> Vec3 {
    let p = t - n * n.dot(t);
    let l = p.length();
    if l > 1e-12 && l.is_finite() { p / l } else { fallback }
}

impl BtfSurface {
    /// A square of side `size` in the z = 0 plane facing +z, centred at the
    /// origin; T runs over [0, `repeats`]², U = +x, V = +y.
    pub fn quad(size: f32, repeats: f32) -> Self {
        let h = size / 2.0;
        let corners = [(-h, -h, 0.0, 0.0), (h, -h, 1.0, 0.0), (h, h, 1.0, 1.0), (-h, h, 0.0, 1.0)];
        let vertices = corners
            .iter()
            .map(|&(x, y, u, v)| BtfVertex {
                position: [x, y, 0.0],
                normal: [0.0, 0.0, 1.0],
                tangent_u: [1.0, 0.0, 0.0],
                tangent_v: [0.0, 1.0, 0.0],
                uv: [u * repeats, v * repeats],
            })
            .collect();
        Self { vertices, indices: vec![0, 1, 2, 0, 2, 3] }
    }

    /// A mesh with its texture coordinates scaled by `uv_scale`; U and V are
    /// the directions of increasing u and v, from the triangles' position
    /// and texture-coordinate differences, averaged at the vertices and
    /// projected on the tangent plane.
    pub fn from_mesh(mesh: &Mesh, uv_scale: f32) -> Self {
        let n = mesh.positions.len();
        let (mut du, mut dv) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
        for t in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [t[0] as usize, t[1] as usize, t[2] as usize];
            if a >= n || b >= n || c >= n {
                continue;
            }
            let (e1, e2) = (mesh.positions[b] - mesh.positions[a], mesh.positions[c] - mesh.positions[a]);
            let uv = |i: usize| mesh.uvs.get(i).copied().unwrap_or(Vec2::ZERO);
            let (t1, t2) = (uv(b) - uv(a), uv(c) - uv(a));
            let det = t1.x * t2.y - t2.x * t1.y;
            if det.abs() < 1e-12 || !det.is_finite() {
                continue;
            }
            // ∂P/∂u and ∂P/∂v of the triangle, weighted by its area
            let pu = (e1 * t2.y - e2 * t1.y) / det;
            let pv = (e2 * t1.x - e1 * t2.x) / det;
            let area = e1.cross(e2).length();
            for i in [a, b, c] {
                du[i] += pu.normalize_or_zero() * area;
                dv[i] += pv.normalize_or_zero() * area;
            }
        }
        let vertices = (0..n)
            .map(|i| {
                let nrm = mesh.normals.get(i).copied().unwrap_or(Vec3::Z).normalize_or(Vec3::Z);
                let helper = if nrm.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
                let u = in_plane(du[i], nrm, nrm.cross(helper).normalize());
                let v = in_plane(dv[i], nrm, nrm.cross(u));
                let t = mesh.uvs.get(i).copied().unwrap_or(Vec2::ZERO) * uv_scale;
                BtfVertex {
                    position: arr(mesh.positions[i]),
                    normal: arr(nrm),
                    tangent_u: arr(u),
                    tangent_v: arr(v),
                    uv: [t.x, t.y],
                }
            })
            .collect();
        Self { vertices, indices: mesh.indices.clone() }
    }

    /// A tessellation of NURBS patches with U and V from the exact partial
    /// derivatives S_u, S_v and N from the exact (limit) normal at every
    /// vertex. T is scaled per patch by its mean side lengths so that
    /// `repeats_per_unit` index-map repeats span one model unit.
    pub fn from_nurbs(surfaces: &[NurbsSurface], density: u32, repeats_per_unit: f32) -> Self {
        let density = density.clamp(1, 512);
        let mut s = Self::default();
        for surf in surfaces {
            let ((u0, u1), (v0, v1)) = surf.domain();
            let base = s.vertices.len() as u32;
            let mut grid = Vec::with_capacity(((density + 1) * (density + 1)) as usize);
            let (mut len_u, mut len_v) = (0.0f64, 0.0f64);
            for j in 0..=density {
                for i in 0..=density {
                    let u = u0 + (u1 - u0) * i as f64 / density as f64;
                    let v = v0 + (v1 - v0) * j as f64 / density as f64;
                    let d = surf.derivatives(u, v, 1);
                    let su = Vec3::from_array(d.d[1][0].map(|x| x as f32));
                    let sv = Vec3::from_array(d.d[0][1].map(|x| x as f32));
                    len_u += su.length() as f64 * (u1 - u0);
                    len_v += sv.length() as f64 * (v1 - v0);
                    let p = surf.point(u, v).map(|x| x as f32);
                    let nrm = Vec3::from_array(surf.normal(u, v).map(|x| x as f32)).normalize_or(Vec3::Z);
                    let helper = if nrm.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
                    let tu = in_plane(su, nrm, nrm.cross(helper).normalize());
                    let tv = in_plane(sv, nrm, nrm.cross(tu));
                    grid.push((p, nrm, tu, tv, i as f32 / density as f32, j as f32 / density as f32));
                }
            }
            let count = ((density + 1) * (density + 1)) as f64;
            let (su, sv) = ((len_u / count) as f32 * repeats_per_unit, (len_v / count) as f32 * repeats_per_unit);
            for (p, nrm, tu, tv, a, b) in grid {
                s.vertices.push(BtfVertex {
                    position: p,
                    normal: arr(nrm),
                    tangent_u: arr(tu),
                    tangent_v: arr(tv),
                    uv: [a * su, b * sv],
                });
            }
            let row = density + 1;
            for j in 0..density {
                for i in 0..density {
                    let a = base + j * row + i;
                    s.indices.extend_from_slice(&[a, a + 1, a + row, a + 1, a + row + 1, a + row]);
                }
            }
        }
        s
    }

    /// Centre and radius of the bounding box.
    pub fn bounds(&self) -> (Vec3, f32) {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for v in &self.vertices {
            let p = Vec3::from_array(v.position);
            if p.is_finite() {
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if !lo.is_finite() {
            return (Vec3::ZERO, 1.0);
        }
        ((lo + hi) / 2.0, ((hi - lo) / 2.0).length().max(1e-6))
    }
}

/// Per-frame uniforms of `btf.wgsl` (std140-compatible).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BtfFrame {
    /// World to clip.
    pub view_proj: [[f32; 4]; 4],
    /// Camera position Pc (w unused).
    pub camera: [f32; 4],
    /// Light position Pl; w = exposure.
    pub light: [f32; 4],
    /// Background colour (linear).
    pub background: [f32; 4],
    /// Codebook texture width, height, layers (texels), unused.
    pub tex_size: [f32; 4],
    /// Index map width, height; θ count; φ count.
    pub sizes: [u32; 4],
    /// Tile width, height, tiles per row; tone map ([`ToneMap::code`]).
    pub tile: [u32; 4],
    /// Tile-index strides of the six axes (u, v, θc, φc, θl, φl), padded.
    pub strides: [[u32; 4]; 2],
    /// Polar angles of the grid in degrees, 4 per vector.
    pub theta: [[f32; 4]; MAX_RENDER_THETA / 4],
    /// Index-map MIP levels (1 without MIP mapping); local-PCA components
    /// + 1 (0: a raw codebook); unused ×2.
    pub mip: [u32; 4],
}

static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

/// A BTF ready to render on either backend.
#[derive(Debug, Clone)]
pub struct PreparedBtf {
    id: u64,
    /// Surface vertices.
    pub vertices: Vec<BtfVertex>,
    /// Triangle indices.
    pub indices: Vec<u32>,
    /// The codebook in its layout. With BC1, its texels are the decoded
    /// blocks: exactly what the GPU's decoder hands its filter.
    pub codebook: Codebook,
    /// BC1 blocks of the codebook (slice by slice), when compressed.
    pub bc1: Option<Vec<u8>>,
    /// The codebook's texels decoded to linear RGB in 16-bit fixed point
    /// ([`Codebook::linear_texels16`]): the CPU twin's copy of what the
    /// GPU's sRGB (and BC1) decoder feeds its filter. Empty for an HDR
    /// BTF: both backends read its linear half floats ([`Codebook::half`]),
    /// as the GPU's `Rgba16Float` texture holds them.
    pub linear: Vec<u64>,
    /// The index map.
    pub index: IndexMap,
    /// The angular grid.
    pub grid: AngularGrid,
    /// Background (linear RGB).
    pub background: Vec3,
    /// Scale of the codebook's radiance.
    pub exposure: f32,
    /// The tone map applied after the exposure, before the sRGB encoding.
    pub tone_map: ToneMap,
    /// The index map's MIP levels (level 0 first) when the BTF is MIP
    /// mapped ([`PreparedBtf::with_mip`]), else empty.
    pub mip: Vec<IndexMap>,
    /// Every MIP level's entries as `su | sv << 16`, level after level.
    pub(crate) mip_entries: Vec<u32>,
    /// Where each level starts in `mip_entries`.
    pub(crate) mip_offsets: Vec<u32>,
    /// The coefficients of a local-PCA codebook ([`PreparedBtf::with_pca`]).
    pub(crate) pca: Option<PcaTables>,
}

/// The per-texel half of a local-PCA BTF as both programs read it: for each
/// sample texel its cluster and its coefficients, decoded (CPU) and as
/// RGBA16F texels (GPU: `texels_per` texels a sample texel, the cluster in
/// the first channel, then the coefficients).
#[derive(Debug, Clone)]
pub(crate) struct PcaTables {
    /// Principal components per cluster.
    pub(crate) components: u32,
    /// Sample width in texels.
    pub(crate) sample_w: u32,
    /// Sample height in texels.
    pub(crate) sample_h: u32,
    /// Per sample texel, row-major: the cluster.
    pub(crate) cluster: Vec<u32>,
    /// Per sample texel: `components` coefficients.
    pub(crate) coefs: Vec<f32>,
    /// RGBA16F texels per sample texel on the GPU.
    pub(crate) texels_per: u32,
    /// The GPU texture's halves, `texels_per × sample_w` texels a row.
    pub(crate) gpu: Vec<u16>,
}

impl PcaTables {
    /// Sample texel `e`'s row-major index.
    #[inline(always)]
    pub(crate) fn texel(&self, su: u32, sv: u32) -> usize {
        (sv * self.sample_w + su) as usize
    }
}

impl PreparedBtf {
    /// Lays `btf` out as `layout` (compressed with `bc1` when given) over
    /// `surface`, reading sample texels through `index`.
    pub fn new(
        btf: &Btf,
        layout: Layout,
        bc1: Option<Bc1Encoder>,
        index: IndexMap,
        surface: BtfSurface,
    ) -> Result<Self, RenderError> {
        let invalid = |e: hitex_core::CoreError| RenderError::Invalid(e.to_string());
        if btf.grid().theta_count() > MAX_RENDER_THETA {
            return Err(RenderError::Invalid(format!(
                "the renderer takes at most {MAX_RENDER_THETA} polar angles; this BTF has {}",
                btf.grid().theta_count()
            )));
        }
        if index.entries.iter().any(|e| e[0] as u32 >= btf.width() || e[1] as u32 >= btf.height()) {
            return Err(RenderError::Invalid("the index map names texels outside the BTF sample".into()));
        }
        if index.width == 0 || index.height == 0 || index.entries.len() != (index.width * index.height) as usize {
            return Err(RenderError::Invalid("the index map is empty or inconsistent".into()));
        }
        if btf.is_hdr() && bc1.is_some() {
            return Err(RenderError::Invalid(
                "BC1 holds 8-bit colours and this BTF is HDR (half floats); render it uncompressed".into(),
            ));
        }
        let mut codebook = Codebook::build(btf, layout).map_err(invalid)?;
        let blocks = match bc1 {
            Some(enc) => {
                let blocks = bc1::encode(&codebook.texels, codebook.width, codebook.height, codebook.depth, enc)
                    .map_err(invalid)?;
                codebook.texels =
                    bc1::decode(&blocks, codebook.width, codebook.height, codebook.depth).map_err(invalid)?;
                Some(blocks)
            }
            None => None,
        };
        Ok(Self::assemble(codebook, blocks, index, btf.grid(), surface, None))
    }

    /// A prepared BTF at exposure 1, no tone map, no MIP levels.
    fn assemble(
        codebook: Codebook,
        bc1: Option<Vec<u8>>,
        index: IndexMap,
        grid: &AngularGrid,
        surface: BtfSurface,
        pca: Option<PcaTables>,
    ) -> Self {
        // an HDR codebook is read from its half floats (`codebook.half`) by both backends
        let linear = if codebook.is_hdr() { Vec::new() } else { codebook.linear_texels16() };
        Self {
            linear,
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            vertices: surface.vertices,
            indices: surface.indices,
            codebook,
            bc1,
            index,
            grid: grid.clone(),
            background: Vec3::new(0.02, 0.02, 0.025),
            exposure: 1.0,
            tone_map: ToneMap::None,
            mip: Vec::new(),
            mip_entries: Vec::new(),
            mip_offsets: Vec::new(),
            pca,
        }
    }

    /// A BTF compressed by local PCA ([`hitex_core::btf::pca`]) over
    /// `surface`, read through `index` (which names texels of the original
    /// sample): the basis laid out as `layout` in half floats, read with the
    /// same hexa-linear reads as a raw codebook, and blended per pixel with
    /// the coefficients of the index texels (those of one cluster blended
    /// first, so that a pixel reads each basis image once per cluster among
    /// its four index texels). No BC1, no MIP mapping.
    pub fn with_pca(pca: &LocalPca, layout: Layout, index: IndexMap, surface: BtfSurface) -> Result<Self, RenderError> {
        let invalid = |e: hitex_core::CoreError| RenderError::Invalid(e.to_string());
        if pca.grid().theta_count() > MAX_RENDER_THETA {
            return Err(RenderError::Invalid(format!(
                "the renderer takes at most {MAX_RENDER_THETA} polar angles; this BTF has {}",
                pca.grid().theta_count()
            )));
        }
        if index.width == 0 || index.height == 0 || index.entries.len() != (index.width * index.height) as usize {
            return Err(RenderError::Invalid("the index map is empty or inconsistent".into()));
        }
        let (w, h) = (pca.width(), pca.height());
        if index.entries.iter().any(|e| e[0] as u32 >= w || e[1] as u32 >= h) {
            return Err(RenderError::Invalid("the index map names texels outside the BTF sample".into()));
        }
        let k = pca.components();
        let codebook =
            Codebook::build_signed(pca.grid(), k + 1, pca.clusters(), pca.basis_halves(), layout).map_err(invalid)?;
        let texels_per = (k + 1).div_ceil(4);
        let mut cluster = Vec::with_capacity((w * h) as usize);
        let mut coefs = Vec::with_capacity((w * h * k) as usize);
        let mut gpu = vec![0u16; (w * h * texels_per * 4) as usize];
        for y in 0..h {
            for x in 0..w {
                let c = pca.cluster_of(x, y);
                cluster.push(c);
                let t = (y * w + x) as usize;
                let slots = &mut gpu[t * texels_per as usize * 4..(t + 1) * texels_per as usize * 4];
                slots[0] = hitex_core::btf::pca::signed_half_bits(c as f32);
                for (j, &a) in pca.coefs_of(x, y).iter().enumerate() {
                    coefs.push(hitex_core::btf::dataset::half_value(a));
                    slots[j + 1] = a;
                }
            }
        }
        let tables = PcaTables { components: k, sample_w: w, sample_h: h, cluster, coefs, texels_per, gpu };
        Ok(Self::assemble(codebook, None, index, pca.grid(), surface, Some(tables)))
    }

    /// Whether the codebook is a local-PCA basis ([`PreparedBtf::with_pca`]).
    pub fn is_pca(&self) -> bool {
        self.pca.is_some()
    }

    /// A MIP-mapped BTF ([`hitex_core::btf::mip::build_mip`]): the stacked
    /// codebook laid out as `layout`, the level-0 map as the index, and
    /// every level chosen per pixel from the screen-to-index-map Jacobian
    /// (seed 001, eq. 2) and blended trilinearly. Where a pixel is at level
    /// 0, it renders the bits the BTF without MIP mapping renders (without
    /// BC1, whose blocks see the stacked arrangement).
    pub fn with_mip(
        mip: &BtfMip,
        layout: Layout,
        bc1: Option<Bc1Encoder>,
        surface: BtfSurface,
    ) -> Result<Self, RenderError> {
        let Some(first) = mip.levels.first() else {
            return Err(RenderError::Invalid("a MIP pyramid without levels".into()));
        };
        let mut p = Self::new(&mip.btf, layout, bc1, first.clone(), surface)?;
        let (w, h) = (mip.btf.width(), mip.btf.height());
        let mut offsets = Vec::with_capacity(mip.levels.len());
        let mut entries = Vec::new();
        for (k, l) in mip.levels.iter().enumerate() {
            let (lw, lh) = ((first.width >> k).max(1), (first.height >> k).max(1));
            if (l.width, l.height) != (lw, lh) || l.entries.len() != (lw * lh) as usize {
                return Err(RenderError::Invalid(format!(
                    "MIP level {k} is {}x{}; a MIP chain of a {}x{} map needs {lw}x{lh}",
                    l.width, l.height, first.width, first.height
                )));
            }
            if l.entries.iter().any(|e| e[0] as u32 >= w || e[1] as u32 >= h) {
                return Err(RenderError::Invalid(format!("MIP level {k} names texels outside the codebook")));
            }
            offsets.push(entries.len() as u32);
            entries.extend(l.entries.iter().map(|e| e[0] as u32 | (e[1] as u32) << 16));
        }
        p.mip = mip.levels.clone();
        p.mip_entries = entries;
        p.mip_offsets = offsets;
        Ok(p)
    }

    /// Index-map MIP levels: 1 without MIP mapping.
    pub fn mip_levels(&self) -> usize {
        self.mip.len().max(1)
    }

    /// Identity of this content (GPU uploads are cached by it).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// Whether the codebook holds linear half floats (an HDR BTF).
    pub fn is_hdr(&self) -> bool {
        self.codebook.is_hdr()
    }

    /// The layout.
    pub fn layout(&self) -> Layout {
        self.codebook.layout
    }

    /// The uniforms for a camera, a point light at `light` and an output size.
    pub fn frame(&self, camera: &Camera, light: Vec3, width: u32, height: u32) -> BtfFrame {
        let vp: Mat4 = camera.view_proj(width as f32 / height as f32);
        let cb = &self.codebook;
        let mut theta = [[0.0f32; 4]; MAX_RENDER_THETA / 4];
        for (i, t) in self.grid.theta_deg().iter().enumerate().take(MAX_RENDER_THETA) {
            theta[i / 4][i % 4] = *t;
        }
        let s = cb.strides;
        BtfFrame {
            view_proj: vp.to_cols_array_2d(),
            camera: camera.position.extend(1.0).to_array(),
            light: [light.x, light.y, light.z, self.exposure],
            background: self.background.extend(1.0).to_array(),
            tex_size: [cb.width as f32, cb.height as f32, cb.depth as f32, 0.0],
            sizes: [self.index.width, self.index.height, self.grid.theta_count() as u32, self.grid.phi_count() as u32],
            tile: [cb.tile_w, cb.tile_h, cb.tile_cols, self.tone_map.code()],
            strides: [[s[0], s[1], s[2], s[3]], [s[4], s[5], 0, 0]],
            theta,
            mip: [self.mip_levels() as u32, self.pca.as_ref().map_or(0, |p| p.components + 1), 0, 0],
        }
    }
}
