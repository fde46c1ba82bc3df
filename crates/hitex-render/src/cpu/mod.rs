//! The CPU reference renderer.
//!
//! [`raster`] turns triangles into 2×2 pixel quads with perspective-correct
//! varyings; each fragment program (one file per program, named like its WGSL
//! twin in `shaders/`) shades a whole quad so that screen-space derivatives
//! are lane differences, as on a GPU.

pub mod btf;
pub mod nurbs;
pub mod raster;
pub mod sampler;
pub mod simd;
pub mod terrain;
pub mod textured;

use crate::prepare::PreparedScene;
use crate::{Frame, RenderError, check_size};
use hitex_core::scene::Camera;

/// The CPU backend. Uses the rayon thread pool (all cores unless
/// `RAYON_NUM_THREADS` says otherwise).
#[derive(Debug, Default, Clone)]
pub struct CpuRenderer;

impl CpuRenderer {
    /// A CPU renderer.
    pub fn new() -> Self {
        Self
    }

    /// Renders `scene` seen by `camera`.
    pub fn render_view(
        &self,
        scene: &PreparedScene,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Frame, RenderError> {
        check_size(width, height)?;
        let frame = scene.frame_uniform(camera, width, height);
        let program = textured::TexturedProgram::new(scene, &frame);
        let mut target = raster::Target::deferred(width, height, crate::prepare::background_rgba8(&frame));
        let varyings: Vec<[f32; textured::VARYINGS]> = scene.vertices.iter().map(textured::varyings).collect();
        let positions: Vec<glam::Vec3> = scene.vertices.iter().map(|v| glam::Vec3::from_array(v.position)).collect();
        let view_proj = glam::Mat4::from_cols_array_2d(&frame.view_proj);
        raster::rasterize(&mut target, view_proj, &positions, &varyings, &scene.indices, &scene.draws, &program);
        if let Some(n) = &scene.nurbs {
            Self::raster_nurbs(&mut target, n, camera, width, height);
        }
        Ok(Frame { width, height, rgba: target.into_rgba() })
    }

    fn raster_nurbs(
        target: &mut raster::Target,
        scene: &crate::nurbs::PreparedNurbs,
        camera: &Camera,
        width: u32,
        height: u32,
    ) {
        let frame = scene.frame(camera, width, height);
        let program = nurbs::NurbsProgram::new(&frame, &scene.packed);
        Self::draw_nurbs(target, scene, camera, &frame, &program);
    }

    /// Draws the tessellation of `scene` with `program` (the NURBS program
    /// bound to `frame`).
    fn draw_nurbs<S: raster::BlockShader<{ nurbs::VARYINGS }>>(
        target: &mut raster::Target,
        scene: &crate::nurbs::PreparedNurbs,
        camera: &Camera,
        frame: &crate::nurbs::NurbsFrame,
        program: &S,
    ) {
        use rayon::prelude::*;
        let varyings: Vec<[f32; nurbs::VARYINGS]> = scene.vertices.par_iter().map(nurbs::varyings).collect();
        let positions: Vec<glam::Vec3> =
            scene.vertices.par_iter().map(|v| glam::Vec3::from_array(v.position)).collect();
        let draws = [crate::prepare::Draw { first_index: 0, index_count: scene.indices.len() as u32, material: 0 }];
        let view_proj = glam::Mat4::from_cols_array_2d(&frame.view_proj);
        // fragments too far behind what is drawn already are not evaluated;
        // triangles are submitted nearest first so that most hidden ones are
        let early = scene.early_depth.then_some(raster::EarlyDepth {
            margin: scene.early_depth_margin(),
            near: camera.near,
            far: camera.far,
        });
        let sorted;
        let indices = if early.is_some() {
            // the squared distance of each triangle's centroid (non-negative,
            // so its bits order as the value does; NaN, a degenerate vertex,
            // last), computed in parallel
            let eye = camera.position;
            let keys: Vec<u32> = scene
                .indices
                .par_chunks_exact(3)
                .map(|t| {
                    let c = t.iter().map(|&i| positions[i as usize]).fold(glam::Vec3::ZERO, |a, p| a + p) / 3.0;
                    let d = (c - eye).length_squared();
                    if d.is_nan() { u32::MAX } else { d.to_bits() }
                })
                .collect();
            let order = order_by_key(&keys);
            let mut out = vec![0u32; 3 * order.len()];
            out.par_chunks_mut(3).zip(order.par_iter()).for_each(|(o, &k)| {
                o.copy_from_slice(&scene.indices[3 * k as usize..3 * k as usize + 3]);
            });
            sorted = out;
            &sorted
        } else {
            &scene.indices
        };
        raster::rasterize_early(target, view_proj, &positions, &varyings, indices, &draws, program, early);
    }
}

/// The places `0..keys.len()` ordered by their keys, ties in place order:
/// a least-significant-digit radix sort (three stable passes of 11 bits,
/// a pass skipped when every key shares its digit), linear in the count
/// where a comparison sort of a frame's tens of thousands of triangles took
/// a serial part of the frame.
fn order_by_key(keys: &[u32]) -> Vec<u32> {
    const BITS: u32 = 11;
    const DIGITS: usize = 1 << BITS;
    let digit = |k: u32, pass: u32| (k >> (BITS * pass)) as usize & (DIGITS - 1);
    // the three passes' histograms in one read of the keys
    let mut counts = vec![[0u32; DIGITS]; 3];
    for &k in keys {
        for (pass, c) in counts.iter_mut().enumerate() {
            c[digit(k, pass as u32)] += 1;
        }
    }
    let mut order: Vec<u32> = (0..keys.len() as u32).collect();
    let mut next = vec![0u32; keys.len()];
    for (pass, count) in counts.iter().enumerate() {
        if count.iter().any(|&n| n as usize == keys.len()) {
            continue;
        }
        let mut start = [0u32; DIGITS];
        let mut sum = 0;
        for (s, &n) in start.iter_mut().zip(count) {
            *s = sum;
            sum += n;
        }
        for &i in &order {
            let d = digit(keys[i as usize], pass as u32);
            next[start[d] as usize] = i;
            start[d] += 1;
        }
        std::mem::swap(&mut order, &mut next);
    }
    order
}

impl CpuRenderer {
    /// Renders a NURBS model seen by `camera`: the tessellation generates
    /// fragments, `cpu/nurbs.rs` evaluates each one exactly.
    pub fn render_nurbs(
        &self,
        scene: &crate::nurbs::PreparedNurbs,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Frame, RenderError> {
        check_size(width, height)?;
        let bg = scene.background;
        let clear = [
            hitex_core::texture::linear_to_srgb_u8(bg.x),
            hitex_core::texture::linear_to_srgb_u8(bg.y),
            hitex_core::texture::linear_to_srgb_u8(bg.z),
            255,
        ];
        let mut target = raster::Target::deferred(width, height, clear);
        Self::raster_nurbs(&mut target, scene, camera, width, height);
        Ok(Frame { width, height, rgba: target.into_rgba() })
    }
}

impl CpuRenderer {
    /// Renders a BTF surface seen by `camera`, lit by a point light at
    /// `light`, with `cpu/btf.rs`.
    pub fn render_btf(
        &self,
        scene: &crate::btf::PreparedBtf,
        camera: &Camera,
        light: glam::Vec3,
        width: u32,
        height: u32,
    ) -> Result<Frame, RenderError> {
        check_size(width, height)?;
        let frame = scene.frame(camera, light, width, height);
        let e = hitex_core::texture::linear_to_srgb_u8;
        let bg = scene.background;
        let mut target = raster::Target::deferred(width, height, [e(bg.x), e(bg.y), e(bg.z), 255]);
        let program = btf::BtfProgram::new(scene, &frame);
        let varyings: Vec<[f32; btf::VARYINGS]> = scene.vertices.iter().map(btf::varyings).collect();
        let positions: Vec<glam::Vec3> = scene.vertices.iter().map(|v| glam::Vec3::from_array(v.position)).collect();
        let draws = [crate::prepare::Draw { first_index: 0, index_count: scene.indices.len() as u32, material: 0 }];
        let view_proj = glam::Mat4::from_cols_array_2d(&frame.view_proj);
        raster::rasterize(&mut target, view_proj, &positions, &varyings, &scene.indices, &draws, &program);
        Ok(Frame { width, height, rgba: target.into_rgba() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nurbs::{NurbsMode, PreparedNurbs};
    use raster::{Block, BlockShader};
    use simd::{LANES, Lanes};

    /// The radix order is that of sorting (key, place) pairs: keys with
    /// many ties, keys whose upper digits all agree (passes skipped), NaN's
    /// key, none and one.
    #[test]
    fn radix_order_is_the_sorted_order_ties_in_place_order() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let sets: Vec<Vec<u32>> = vec![
            vec![],
            vec![5],
            (0..5000).map(|_| next() as u32 % 97).collect(),
            (0..5000).map(|_| 0x4000_0000 | (next() as u32 & 0x3ff)).collect(),
            (0..5000).map(|_| (1.0 + (next() % 1000) as f32 * 0.25).to_bits()).chain([u32::MAX, 0]).collect(),
            (0..20000).map(|_| next() as u32).collect(),
        ];
        for keys in sets {
            let mut expected: Vec<(u32, u32)> = keys.iter().enumerate().map(|(i, &k)| (k, i as u32)).collect();
            expected.sort_unstable();
            let expected: Vec<u32> = expected.into_iter().map(|(_, i)| i).collect();
            assert_eq!(order_by_key(&keys), expected, "{} keys", keys.len());
        }
    }

    /// The NURBS program handed its lanes in quads, as the rasterizer hands
    /// them to a program that does not pack lanes (and the derivatives taken
    /// from each quad by the program).
    struct InQuads<'a>(nurbs::NurbsProgram<'a>);
    impl BlockShader<{ nurbs::VARYINGS }> for InQuads<'_> {
        const WRITES_DEPTH: bool = true;
        fn shade_block(&self, b: &Block<{ nurbs::VARYINGS }>, rgba: &mut [[u8; 4]; LANES], depth: &mut Lanes) {
            let mut quads = b.clone();
            quads.fill_grads([3, 4]);
            self.0.shade_block(&quads, rgba, depth);
        }
    }

    /// Packing the NURBS program's lanes one by one, whatever patch and
    /// quad they come from, draws the bytes that packing whole quads of one
    /// patch draws: trimmed faces, seams and boundary fans, mixed degrees,
    /// the block path's modes and the per-lane ones, with an overlay.
    #[test]
    fn nurbs_lanes_packed_one_by_one_draw_the_bytes_of_quads() {
        let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../hitex-io/data");
        let mut models = Vec::new();
        let holed = hitex_io::models::load_model(&format!("{data}/holed-square.igs")).unwrap();
        let mut p = PreparedNurbs::new(holed.nurbs(), &holed.ranges(), 8);
        p.set_trims(&holed.surfaces.iter().map(|s| s.trim.clone()).collect::<Vec<_>>());
        models.push(("holed square", p));
        let part = hitex_io::models::load_model(&format!("{data}/cad/face_recognition_sample_part.stp")).unwrap();
        models.push(("STEP part", PreparedNurbs::trimmed(part.nurbs(), &part.ranges(), &part.trims(), 6)));
        for (name, density) in [("teapot", 8), ("spray", 4)] {
            let m = hitex_io::models::load_model(name).unwrap();
            models.push((name, PreparedNurbs::new(m.nurbs(), &m.ranges(), density)));
        }
        let (w, h) = (200, 150);
        let mut drawn = 0;
        for (name, mut p) in models {
            for (mode, boundaries) in [
                (NurbsMode::Shaded, false),
                (NurbsMode::Isophote, false),
                (NurbsMode::Normal, false),
                (NurbsMode::Zebra, false),
                (NurbsMode::Shaded, true),
            ] {
                (p.mode, p.boundaries) = (mode, boundaries);
                for turn in [0.0f32, 2.3, 4.1] {
                    let cam = p.camera.orbit(turn);
                    let frame = p.frame(&cam, w, h);
                    let mut lanes = raster::Target::new(w, h, [0, 0, 0, 0]);
                    let program = nurbs::NurbsProgram::new(&frame, &p.packed);
                    CpuRenderer::draw_nurbs(&mut lanes, &p, &cam, &frame, &program);
                    let mut quads = raster::Target::new(w, h, [0, 0, 0, 0]);
                    let program = InQuads(nurbs::NurbsProgram::new(&frame, &p.packed));
                    CpuRenderer::draw_nurbs(&mut quads, &p, &cam, &frame, &program);
                    let (a, b) = (lanes.into_rgba(), quads.into_rgba());
                    let differ = a.chunks_exact(4).zip(b.chunks_exact(4)).filter(|(x, y)| x != y).count();
                    assert_eq!(differ, 0, "{name}, {mode:?}, boundaries {boundaries}, turn {turn}: pixels differ");
                    drawn += a.chunks_exact(4).filter(|c| c[3] != 0).count();
                }
            }
        }
        assert!(drawn > 4 * 5 * 3 * (w * h / 10) as usize, "only {drawn} pixels drawn to compare");
    }
}
