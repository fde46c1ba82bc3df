//! Flights over a GST pyramid through the resident-map cache, prepared for
//! both backends: the camera over flat ground (eq. (1)), and the frame's
//! *page table* — for every level, the window of the active area (eq. (7))
//! and, per map slot of it, which resident map serves it (itself, or the
//! nearest coarser ancestor while it loads). `cpu/terrain.rs` and
//! `shaders/terrain.wgsl` read the same table.

use hitex_core::residency::{MapKey, ResidentMaps};
use std::collections::HashMap;
use std::sync::Arc;

/// Side of a map in texels.
pub const MAP: u32 = 256;

/// A camera over flat ground, in finest-level texels (x east, y south, z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlyCamera {
    /// Eye position.
    pub eye: [f64; 3],
    /// Unit view direction.
    pub fwd: [f64; 3],
    /// Unit right vector.
    pub right: [f64; 3],
    /// Unit up vector of the image.
    pub up: [f64; 3],
    /// tan of half the horizontal field of view.
    pub tan_h: f64,
}

impl FlyCamera {
    /// A camera at ground point (x, y) and `altitude`, `pitch` degrees from the
    /// nadir, `heading` degrees clockwise from north, horizontal field of view `fov`.
    pub fn new(x: f64, y: f64, altitude: f64, pitch: f64, heading: f64, fov: f64) -> Self {
        let (th, hd) = (pitch.to_radians(), heading.to_radians());
        let fwd = [th.sin() * hd.sin(), -th.sin() * hd.cos(), -th.cos()];
        let right = [hd.cos(), hd.sin(), 0.0];
        // up = fwd × right
        let up = [
            fwd[1] * right[2] - fwd[2] * right[1],
            fwd[2] * right[0] - fwd[0] * right[2],
            fwd[0] * right[1] - fwd[1] * right[0],
        ];
        let l = (up[0] * up[0] + up[1] * up[1] + up[2] * up[2]).sqrt().max(1e-12);
        Self {
            eye: [x, y, altitude],
            fwd,
            right,
            up: [up[0] / l, up[1] / l, up[2] / l],
            tan_h: (fov.clamp(1.0, 170.0).to_radians() / 2.0).tan(),
        }
    }
}

/// One frame's page table and the maps it names.
#[derive(Debug, Clone)]
pub struct FlyPages {
    /// Levels of the pyramid.
    pub levels: u32,
    /// Maps per side of each level's window.
    pub per_side: u32,
    /// Per level, the first map column and row of its window.
    pub origins: Vec<[i32; 2]>,
    /// Per level and window slot (row-major), the map serving it, if any data lies there.
    pub slots: Vec<Option<MapKey>>,
    /// The texels (RGBA8 sRGB, 256×256) of every map the slots name.
    pub maps: HashMap<MapKey, Arc<Vec<u8>>>,
}

impl FlyPages {
    /// The page table for an eye above ground point `eye` (finest texels),
    /// from what `cache` holds now; `data_tiles(z)` bounds the maps with data.
    pub fn new(
        cache: &ResidentMaps,
        levels: u32,
        per_side: u32,
        data_tiles: impl Fn(u32) -> (u32, u32),
        eye: [f64; 2],
    ) -> Self {
        let mut origins = Vec::with_capacity(levels as usize);
        let mut slots = Vec::with_capacity((levels * per_side * per_side) as usize);
        let mut maps = HashMap::new();
        for z in 0..levels {
            let span = MAP as f64 * (1u64 << (levels - 1 - z)) as f64;
            let (cols, rows) = data_tiles(z);
            let half = per_side as f64 / 2.0;
            let o = [(eye[0] / span - half).floor() as i32, (eye[1] / span - half).floor() as i32];
            origins.push(o);
            for k in 0..(per_side * per_side) as i32 {
                let (x, y) = (o[0] + k % per_side as i32, o[1] + k / per_side as i32);
                if x < 0 || y < 0 || x as u32 >= cols || y as u32 >= rows {
                    slots.push(None);
                    continue;
                }
                let (found, texels) = cache.lookup(MapKey { z, x: x as u32, y: y as u32 });
                maps.entry(found).or_insert(texels);
                slots.push(Some(found));
            }
        }
        Self { levels, per_side, origins, slots, maps }
    }
}

/// Per-frame uniforms of `terrain.wgsl` (std140-compatible).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FlyUniform {
    /// Eye (finest texels); w = tan of half the horizontal field of view.
    pub eye: [f32; 4],
    /// View direction.
    pub fwd: [f32; 4],
    /// Right vector.
    pub right: [f32; 4],
    /// Up vector.
    pub up: [f32; 4],
    /// Width, height, levels, maps per window side.
    pub sizes: [u32; 4],
}

impl FlyUniform {
    /// The uniforms of `cam` at `width`×`height` over `levels` levels.
    pub fn new(cam: &FlyCamera, width: u32, height: u32, levels: u32, per_side: u32) -> Self {
        let v = |a: [f64; 3], w: f64| [a[0] as f32, a[1] as f32, a[2] as f32, w as f32];
        Self {
            eye: v(cam.eye, cam.tan_h),
            fwd: v(cam.fwd, 0.0),
            right: v(cam.right, 0.0),
            up: v(cam.up, 0.0),
            sizes: [width, height, levels, per_side],
        }
    }
}

/// Colour of the sky above the horizon, linear RGB.
pub fn sky(py: f32, height: f32) -> [f32; 3] {
    let s = 1.0 - py / height;
    [0.55 + 0.2 * s, 0.68 + 0.15 * s, 0.86]
}

/// Linear colour of ground where no map holds data.
pub const GROUND: [f32; 3] = [0.05, 0.06, 0.05];
