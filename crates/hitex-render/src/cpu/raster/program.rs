//! The program interface: a fragment program shades a [`Block`] of 16
//! lanes (four 2×2 quads) through [`BlockShader`], or one quad through
//! [`QuadShader`], with its derivatives per quad.

use super::*;

/// A fragment program shading a 2×2 quad. Lanes are (0,0) (1,0) (0,1) (1,1).
pub trait QuadShader<const K: usize>: Sync {
    /// Shades the quad. `v` holds perspective-correct varyings per lane, `w`
    /// the perspective-correct clip w; bit `i` of `live` is set for lanes whose
    /// colour is written (the others are helpers: they feed derivatives, and
    /// their colour may be left uncomputed). Returns RGBA8 per lane.
    fn shade(&self, material: usize, v: &[[f32; K]; 4], w: [f32; 4], live: u8) -> [[u8; 4]; 4];

    /// True when the program computes its own depth ([`QuadShader::shade_depth`],
    /// WGSL `@builtin(frag_depth)`): the depth test then runs after shading.
    const WRITES_DEPTH: bool = false;

    /// Shades the quad and returns each lane's depth in [0, 1] as well.
    /// Programs that set [`QuadShader::WRITES_DEPTH`] implement it.
    fn shade_depth(
        &self,
        material: usize,
        v: &[[f32; K]; 4],
        w: [f32; 4],
        live: u8,
        z: [f32; 4],
    ) -> ([[u8; 4]; 4], [f32; 4]) {
        (self.shade(material, v, w, live), z)
    }
}

/// Four 2×2 quads handed to a program at once, as structure of arrays: lane
/// `4q + l` is lane `l` of quad `q` ((0,0) (1,0) (0,1) (1,1)), so that
/// screen-space derivatives stay per quad (differences of lanes within a
/// group of four, as on a GPU). The quads share a material and a program key
/// ([`BlockShader::key`]) but may come from different triangles and places
/// (small triangles are packed together); quad slots past the last filled
/// one have no live lane.
///
/// For a program that packs lanes ([`BlockShader::LANE_GRADS`]) the lanes
/// are instead single covered fragments of any triangles, in submission
/// order, the live ones first; their quads' derivatives come in [`Block::grad`].
#[derive(Clone)]
pub struct Block<const K: usize> {
    /// Material of the triangle.
    pub material: usize,
    /// Pixel column of the first quad's lane 0 (even; of a lane-packed
    /// block, of its first lane).
    pub x: u32,
    /// Pixel row of the first quad's lane 0 (even; of a lane-packed block,
    /// of its first lane).
    pub y: u32,
    /// Perspective-correct varyings: `v[j][lane]`.
    pub v: [Lanes; K],
    /// Perspective-correct clip w per lane.
    pub w: Lanes,
    /// Screen-linear depth per lane.
    pub z: Lanes,
    /// Bit `lane` set: the lane is covered and its colour is written (the
    /// others are helpers feeding derivatives; their colour may be left
    /// uncomputed).
    pub live: u16,
    /// Fine screen derivatives of the varyings named by
    /// [`BlockShader::LANE_GRADS`], per lane: `grad[g][0]` along x (WGSL
    /// `dpdxFine`) and `grad[g][1]` along y (`dpdyFine`) of varying
    /// `LANE_GRADS[g]`, from the lane's own quad as the quad layout above would
    /// give them (the same bits). Filled for lane-packing programs only.
    pub grad: [[Lanes; 2]; 2],
}

impl<const K: usize> Block<K> {
    /// Fills [`Block::grad`] for varyings `js` from the block's quads (the
    /// layout of a block that is not lane-packed).
    pub fn fill_grads(&mut self, js: [usize; 2]) {
        for g in 0..2 {
            self.grad[g] = quad_grads(&self.v[js[g]]);
        }
    }
}

/// Fine screen derivatives (d/dx, d/dy) of a lane value over a block's four
/// quads (WGSL `dpdxFine`, `dpdyFine`): within each quad, x differences of
/// its rows and y differences of its columns.
#[inline(always)]
pub(super) fn quad_grads(a: &Lanes) -> [Lanes; 2] {
    let mut dx = [0.0f32; LANES];
    let mut dy = [0.0f32; LANES];
    for q in 0..LANES / 4 {
        let b = 4 * q;
        let (top, bottom) = (a[b + 1] - a[b], a[b + 3] - a[b + 2]);
        let (left, right) = (a[b + 2] - a[b], a[b + 3] - a[b + 1]);
        dx[b..b + 4].copy_from_slice(&[top, top, bottom, bottom]);
        dy[b..b + 4].copy_from_slice(&[left, right, left, right]);
    }
    [dx, dy]
}

/// A fragment program shading a [`Block`] of 16 lanes. Every [`QuadShader`]
/// is one (quad by quad); the programs rewritten for lanes implement it directly.
pub trait BlockShader<const K: usize>: Sync {
    /// True when the program computes its own depth (WGSL
    /// `@builtin(frag_depth)`): the depth test then runs after shading.
    const WRITES_DEPTH: bool = false;
    /// True for a program whose lanes are mostly gathers and per-lane table
    /// reads: it runs at [`simd::level_for_gathers`] (8 lanes on processors
    /// that split 512-bit operations in two, where moving each lane in and
    /// out of a 512-bit register costs more), the others at [`simd::level`].
    const GATHER_BOUND: bool = false;
    /// Writes the colour of every live lane into `rgba` and, for programs
    /// that write depth, each lane's depth in [0, 1] into `depth` (anything
    /// else, NaN included, discards the lane).
    fn shade_block(&self, b: &Block<K>, rgba: &mut [[u8; 4]; LANES], depth: &mut Lanes);
    /// The batch key of a triangle, from its first vertex's varyings: the
    /// rasterizer packs quads of several triangles into one block only when
    /// their material and key agree (a program that shades a block faster
    /// when its lanes share some state, e.g. one NURBS patch, keys by it).
    #[inline(always)]
    fn key(&self, _v: &[f32; K]) -> u32 {
        0
    }
    /// Whether quads of different triangles may share a block. A program
    /// that records what it shades (bank statistics) says no: a waiting quad
    /// has not written its depth yet, so the early test would let through,
    /// and the program would record, fragments that drawing the triangles
    /// one by one culls (the image is the same either way).
    #[inline(always)]
    fn packs_triangles(&self) -> bool {
        true
    }
    /// For a program that reads nothing of a quad but the screen
    /// derivatives of (at most) two varyings: their indices. The rasterizer
    /// then packs covered lanes one by one, sixteen to a block whatever
    /// quads they come from (no helper lanes), and hands each lane those
    /// derivatives from its own quad in [`Block::grad`] (the same bits the
    /// quad would give). Tessellated surfaces, whose triangles leave quads
    /// two-thirds empty, fill their blocks this way.
    const LANE_GRADS: Option<[usize; 2]> = None;
}

impl<const K: usize, S: QuadShader<K>> BlockShader<K> for S {
    const WRITES_DEPTH: bool = <S as QuadShader<K>>::WRITES_DEPTH;
    #[inline(always)]
    fn shade_block(&self, b: &Block<K>, rgba: &mut [[u8; 4]; LANES], depth: &mut Lanes) {
        for q in 0..4 {
            let live = ((b.live >> (4 * q)) & 0xf) as u8;
            if live == 0 {
                continue;
            }
            let v: [[f32; K]; 4] = std::array::from_fn(|l| std::array::from_fn(|j| b.v[j][4 * q + l]));
            let w: [f32; 4] = std::array::from_fn(|l| b.w[4 * q + l]);
            if <S as BlockShader<K>>::WRITES_DEPTH {
                let z: [f32; 4] = std::array::from_fn(|l| b.z[4 * q + l]);
                let (c, d) = self.shade_depth(b.material, &v, w, live, z);
                for l in 0..4 {
                    rgba[4 * q + l] = c[l];
                    depth[4 * q + l] = d[l];
                }
            } else {
                let c = self.shade(b.material, &v, w, live);
                rgba[4 * q..4 * q + 4].copy_from_slice(&c);
            }
        }
    }
}
