//! A flight's per-frame work above the renderer: the camera of a path key,
//! the maps the view needs requested from the resident-map cache and its
//! page table built ([`prepare_frame`]), and the DEM meshed at the detail the
//! eye needs, with the aircraft ahead of the camera ([`Relief`]).

use super::{FlyCamera, FlyMesh, FlyPages, FlyUniform, GenericTexture};
use crate::RenderError;
use hitex_core::residency::{FrameStats, ResidentMaps, View, active_maps};
use hitex_core::terrain::path::PathKey;
use std::time::{Duration, Instant};

/// Direction towards the sun that lights the aircraft (south-east, 50° up).
const SUN: [f32; 3] = [0.49, 0.49, 0.72];

/// Where a flight's data lies in its pyramid: what the camera of a path key
/// and the active area need of a tile store.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlightArea {
    /// Levels of the pyramid.
    pub levels: u32,
    /// Texels of a map side.
    pub map_texels: u32,
    /// The data's first finest-level texel (x, y).
    pub offset: [u32; 2],
    /// The data's size in finest-level texels (x, y).
    pub extent: [f64; 2],
    /// Metres of ground per finest-level texel.
    pub ground_pixel: f64,
}

impl FlightArea {
    /// The camera at path key `k` (x and y fractions of the data, altitude in
    /// metres, pitch below the horizon becoming the paper's angle from the
    /// nadir) with a horizontal field of view of `fov` degrees.
    pub fn camera_at(&self, k: &PathKey, fov: f64) -> FlyCamera {
        let (x, y) = (self.offset[0] as f64 + k.x * self.extent[0], self.offset[1] as f64 + k.y * self.extent[1]);
        FlyCamera::new(x, y, k.altitude / self.ground_pixel, 90.0 - k.pitch, k.heading, fov)
    }
}

/// One frame ready to render: its cache traffic, uniforms and page table.
#[derive(Debug, Clone)]
pub struct PreparedFrame {
    /// The cache's traffic for this frame.
    pub stats: FrameStats,
    /// The frame's uniforms.
    pub uniform: FlyUniform,
    /// The page table of what is resident.
    pub pages: FlyPages,
    /// The cache's messages since the last frame (maps that failed to load).
    pub warnings: Vec<String>,
    /// Time spent waiting for loads (0 unless asked to wait).
    pub waited: Duration,
}

/// Requests the maps the view of `cam` needs (the active area, eq. (7), of
/// `per_side` maps a level), optionally waits up to `wait` for them to load
/// (a background thread's work, reported apart from the frame's), and
/// builds the page table of what is resident for a `w` × `h` frame.
/// `data_range(z)` is level z's data window in maps (first column, first
/// row, end column, end row).
#[allow(clippy::too_many_arguments)]
pub fn prepare_frame(
    cache: &mut ResidentMaps,
    area: &FlightArea,
    data_range: impl Fn(u32) -> [u32; 4] + Copy,
    cam: &FlyCamera,
    (w, h): (u32, u32),
    fov: f64,
    per_side: u32,
    wait: Option<Duration>,
) -> PreparedFrame {
    let eye = [cam.eye[0], cam.eye[1]];
    let view = View { fov_deg: fov, pixels: w, per_side };
    let needed = active_maps(area.levels, area.map_texels, data_range, eye, cam.eye[2], view);
    let mut stats = cache.begin_frame(&needed);
    let mut waited = Duration::ZERO;
    if let Some(limit) = wait {
        let t = Instant::now();
        cache.wait_pending(limit);
        stats = cache.begin_frame(&needed);
        waited = t.elapsed();
    }
    let warnings = cache.take_log();
    let pages = FlyPages::new(cache, area.levels, per_side, data_range, eye);
    PreparedFrame { stats, uniform: FlyUniform::new(cam, w, h, area.levels, per_side), pages, warnings, waited }
}

/// A DEM placed on a flight's maps, meshed per frame with a level of detail
/// that follows the eye, and the aircraft flown ahead of the camera.
#[derive(Debug, Clone)]
pub struct Relief {
    heights: Vec<f32>,
    w: usize,
    h: usize,
    /// Map texels of post (0, 0) and between posts.
    origin: [f64; 2],
    spacing: [f64; 2],
    /// Map texels per metre of height (with the exaggeration).
    height_scale: f64,
    /// The aircraft's texture.
    pub generic: GenericTexture,
    /// Draw the aircraft.
    pub aircraft: bool,
}

impl Relief {
    /// `heights` (metres, `w` × `h` posts, row-major from the north-west;
    /// NaN where unknown) at the centres of the DEM's pixels: its north-west
    /// corner `dem_origin` and pixel size `dem_pixel` (east, south; map
    /// units) placed on maps whose north-west corner is `map_origin` with
    /// texels of `map_pixel`; heights scaled by `exaggeration` over
    /// `ground_pixel` metres a texel.
    #[allow(clippy::too_many_arguments)]
    pub fn placed(
        heights: Vec<f32>,
        (w, h): (usize, usize),
        dem_origin: [f64; 2],
        dem_pixel: [f64; 2],
        map_origin: [f64; 2],
        map_pixel: [f64; 2],
        exaggeration: f64,
        ground_pixel: f64,
    ) -> Result<Self, RenderError> {
        if heights.len() != w * h || w == 0 || h == 0 {
            return Err(RenderError::Invalid(format!("{} heights for a {w} × {h} grid", heights.len())));
        }
        if !(exaggeration.is_finite() && exaggeration >= 0.0) {
            return Err(RenderError::Invalid(format!("exaggeration {exaggeration} must be finite and ≥ 0")));
        }
        if !(map_pixel[0] > 0.0 && map_pixel[1] > 0.0 && ground_pixel > 0.0) {
            return Err(RenderError::Invalid("the maps' texel size is not positive".into()));
        }
        // post (i, j) lies at the centre of DEM pixel (i, j); map texels count from the maps' north-west corner
        let origin = [
            (dem_origin[0] + 0.5 * dem_pixel[0] - map_origin[0]) / map_pixel[0],
            (map_origin[1] - (dem_origin[1] - 0.5 * dem_pixel[1])) / map_pixel[1],
        ];
        let spacing = [dem_pixel[0] / map_pixel[0], dem_pixel[1] / map_pixel[1]];
        Ok(Self {
            heights,
            w,
            h,
            origin,
            spacing,
            height_scale: exaggeration / ground_pixel,
            generic: GenericTexture::livery(),
            aircraft: true,
        })
    }

    /// The highest post, metres (before exaggeration).
    pub fn highest(&self) -> f64 {
        self.heights.iter().filter(|h| h.is_finite()).fold(0.0f64, |m, &h| m.max(h as f64))
    }

    /// Ground height (map texels) under map point (x, y): the nearest post, 0 off the grid.
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        let (i, j) =
            (((x - self.origin[0]) / self.spacing[0]).round(), ((y - self.origin[1]) / self.spacing[1]).round());
        if !(i >= 0.0 && j >= 0.0 && i < self.w as f64 && j < self.h as f64) {
            return 0.0;
        }
        let v = self.heights[j as usize * self.w + i as usize] as f64 * self.height_scale;
        if v.is_finite() { v } else { 0.0 }
    }

    /// The frame's mesh: the DEM at the detail the eye needs (edges of at
    /// most 6 pixels on a frame `width` pixels wide), and the aircraft.
    pub fn mesh(&self, cam: &FlyCamera, width: u32) -> Result<FlyMesh, RenderError> {
        let opts = hitex_core::terrain::LodOptions {
            origin: self.origin,
            spacing: self.spacing,
            height_scale: self.height_scale,
            eye: cam.eye,
            pixels_per_tan: width as f64 / (2.0 * cam.tan_h),
            max_edge_px: 6.0,
            block: 32,
        };
        let lod = hitex_core::terrain::lod_mesh(&self.heights, self.w, self.h, &opts)
            .map_err(|e| RenderError::Invalid(e.to_string()))?;
        let mut mesh = FlyMesh::from_lod(&lod);
        if self.aircraft {
            let agl = (cam.eye[2] - self.height_at(cam.eye[0], cam.eye[1])).max(1.0);
            let d = 0.45 * agl;
            let at: [f64; 3] =
                std::array::from_fn(|i| cam.eye[i] + cam.fwd[i] * d + cam.right[i] * 0.12 * d - cam.up[i] * 0.12 * d);
            // the camera's heading: right = (cos h, sin h)
            let heading = cam.right[1].atan2(cam.right[0]).to_degrees();
            mesh.append(&FlyMesh::aircraft(at, heading, 0.16 * d, SUN));
        }
        Ok(mesh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn posts_sit_at_pixel_centres_on_the_maps() {
        // a 3 × 2 DEM of 30 m pixels whose north-west corner is 60 m east and
        // 30 m south of the maps' (10 m texels, y north-up map units)
        let heights = vec![0.0, 10.0, 20.0, 30.0, 40.0, f32::NAN];
        let r =
            Relief::placed(heights, (3, 2), [60.0, -30.0], [30.0, 30.0], [0.0, 0.0], [10.0, 10.0], 2.0, 10.0).unwrap();
        // post (1, 0) at the pixel centre: 60 + 45 = 105 m east → texel 10.5; 30 + 15 = 45 m south → texel 4.5
        assert_eq!(r.height_at(10.5, 4.5), 10.0 * 2.0 / 10.0);
        // post (0, 1): 7.5, 7.5; nearest-post lookup
        assert_eq!(r.height_at(7.9, 7.1), 30.0 * 0.2);
        // unknown and off the grid read 0
        assert_eq!(r.height_at(13.5, 7.5), 0.0);
        assert_eq!(r.height_at(-5.0, 4.5), 0.0);
        assert_eq!(r.highest(), 40.0);
        let bad = Relief::placed(vec![0.0; 5], (3, 2), [0.0; 2], [1.0; 2], [0.0; 2], [1.0; 2], 1.0, 1.0);
        assert!(bad.unwrap_err().to_string().contains("5 heights for a 3 × 2 grid"));
        let bad = Relief::placed(vec![0.0; 6], (3, 2), [0.0; 2], [1.0; 2], [0.0; 2], [1.0; 2], -1.0, 1.0);
        assert!(bad.unwrap_err().to_string().contains("exaggeration -1"));
    }

    #[test]
    fn a_path_key_is_placed_over_the_data() {
        let area =
            FlightArea { levels: 5, map_texels: 256, offset: [100, 200], extent: [4096.0, 2048.0], ground_pixel: 30.0 };
        let k = PathKey { t: 0.0, x: 0.25, y: 0.5, altitude: 3000.0, pitch: 90.0, heading: 0.0 };
        let cam = area.camera_at(&k, 45.0);
        assert_eq!(cam.eye, [100.0 + 1024.0, 200.0 + 1024.0, 100.0]);
        // pitch 90° below the horizon looks straight down
        assert!(cam.fwd[2] < -0.999_999, "{:?}", cam.fwd);
    }
}
