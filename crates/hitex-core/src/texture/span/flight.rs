//! A flight over flat textured ground rendered both ways: per pixel with
//! the analytic Jacobian (eq. (2)) and in 2×2 spans from the banks; and the
//! comparison of the two frames.

use super::{BankModel, SPAN_PIXELS, SpanOptions, sample_span};
use crate::frame::Frame;
use crate::texture::image::linear_to_srgb_u8;
use crate::texture::pyramid::MipPyramid;
use crate::texture::sampler::{Filter, Jacobian, LevelRule, SamplerOptions, Wrap, sample};
use glam::{Vec2, Vec4};
use rayon::prelude::*;

/// A pinhole camera flying over flat textured ground (eq. (1) for a
/// horizontal face). Ground coordinates are level-0 texels (x east = u,
/// y south = v); the camera looks `pitch_deg` below the horizon towards
/// `heading_deg` (clockwise from north, i.e. from −y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlightView {
    /// Eye position over the ground, level-0 texels.
    pub position: [f64; 2],
    /// Height of the eye above the ground, level-0 texels.
    pub altitude: f64,
    /// Pitch below the horizon, degrees.
    pub pitch_deg: f64,
    /// Heading, degrees clockwise from north.
    pub heading_deg: f64,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl FlightView {
    /// The paper's `k = n_pxl / (2 tan(ψ_FOV/2))`: pixels per unit of tan(angle).
    pub fn k(&self) -> f64 {
        self.width as f64 / (2.0 * (self.fov_deg.to_radians() / 2.0).tan())
    }

    fn usable(&self) -> bool {
        [self.position[0], self.position[1], self.altitude, self.pitch_deg, self.heading_deg, self.fov_deg]
            .iter()
            .all(|v| v.is_finite())
            && self.altitude > 0.0
            && self.fov_deg > 0.0
            && self.fov_deg < 180.0
    }

    /// Forward, right and up unit vectors (z up).
    fn basis(&self) -> [[f64; 3]; 3] {
        let (p, h) = (self.pitch_deg.to_radians(), self.heading_deg.to_radians());
        let d = [h.sin(), -h.cos()];
        let f = [d[0] * p.cos(), d[1] * p.cos(), -p.sin()];
        let r = [h.cos(), h.sin(), 0.0];
        // u = f × r
        let u = [f[1] * r[2] - f[2] * r[1], f[2] * r[0] - f[0] * r[2], f[0] * r[1] - f[1] * r[0]];
        [f, r, u]
    }

    /// Ground point seen through pixel `(x, y)`'s centre and its derivatives
    /// with respect to the screen x and y (texels per pixel); None above the
    /// horizon or for an unusable camera.
    pub fn map_point_and_jacobian(&self, x: f64, y: f64) -> Option<([f64; 2], [[f64; 2]; 2])> {
        if !self.usable() {
            return None;
        }
        let [f, r, u] = self.basis();
        let k = self.k();
        let xs = x + 0.5 - self.width as f64 / 2.0;
        let ys = y + 0.5 - self.height as f64 / 2.0;
        let d: [f64; 3] = std::array::from_fn(|i| k * f[i] + xs * r[i] - ys * u[i]);
        if d[2].is_nan() || d[2] >= -1e-12 {
            return None;
        }
        let h = self.altitude;
        let t = -h / d[2];
        let p = [self.position[0] + t * d[0], self.position[1] + t * d[1]];
        // ∂P/∂xs = t r + (h r_z / d_z²) d;  ∂P/∂ys = −t u − (h u_z / d_z²) d
        let dz2 = d[2] * d[2];
        let (ax, ay) = (h * r[2] / dz2, -h * u[2] / dz2);
        let jx = [t * r[0] + ax * d[0], t * r[1] + ax * d[1]];
        let jy = [-t * u[0] + ay * d[0], -t * u[1] + ay * d[1]];
        (p[0].is_finite() && p[1].is_finite()).then_some((p, [jx, jy]))
    }

    /// Ground point through pixel `(x, y)`'s centre (eq. (1)); None above the horizon.
    pub fn map_point(&self, x: u32, y: u32) -> Option<[f64; 2]> {
        self.map_point_and_jacobian(x as f64, y as f64).map(|(p, _)| p)
    }

    /// Texture coordinates and the analytic Jacobian (uv per pixel) at pixel
    /// `(x, y)` for a texture whose level 0 is `tex_w`×`tex_h`.
    pub fn uv(&self, tex_w: u32, tex_h: u32, x: u32, y: u32) -> Option<(Vec2, Jacobian)> {
        let (p, [jx, jy]) = self.map_point_and_jacobian(x as f64, y as f64)?;
        let (w, h) = (tex_w.max(1) as f64, tex_h.max(1) as f64);
        let uv = Vec2::new((p[0] / w) as f32, (p[1] / h) as f32);
        let jac = Jacobian::new(
            Vec2::new((jx[0] / w) as f32, (jx[1] / h) as f32),
            Vec2::new((jy[0] / w) as f32, (jy[1] / h) as f32),
        );
        Some((uv, jac))
    }
}

/// Colour of pixels above the horizon (sRGB).
pub const SKY: [u8; 4] = [178, 203, 237, 255];

#[inline]
fn encode(c: Vec4) -> [u8; 4] {
    [linear_to_srgb_u8(c.x), linear_to_srgb_u8(c.y), linear_to_srgb_u8(c.z), 255]
}

/// Renders `view` with the per-pixel trilinear sampler (eq. (1)–(4), level
/// from the analytic Jacobian by eq. (2)): the conventional design.
pub fn render_trilinear(pyr: &MipPyramid, view: &FlightView, wrap: Wrap) -> Frame {
    let (w, h) = (view.width, view.height);
    let opts = SamplerOptions { filter: Filter::Trilinear, wrap, level_rule: LevelRule::MaxPartial, lod_bias: 0.0 };
    let (tw, th) = (pyr.width(), pyr.height());
    let mut rgba = vec![0u8; w as usize * h as usize * 4];
    rgba.par_chunks_mut((w as usize * 4).max(1)).enumerate().for_each(|(y, row)| {
        for (x, px) in row.chunks_exact_mut(4).enumerate() {
            let c = match view.uv(tw, th, x as u32, y as u32) {
                Some((uv, jac)) => encode(sample(pyr, &opts, uv, jac)),
                None => SKY,
            };
            px.copy_from_slice(&c);
        }
    });
    Frame { width: w, height: h, rgba }
}

/// Renders `view` in 2×2 spans with [`sample_span`]; adds the bank traffic to
/// `banks`. Spans on the right or bottom edge of odd sizes have fewer pixels.
pub fn render_spans(pyr: &MipPyramid, view: &FlightView, opts: &SpanOptions, banks: &mut BankModel) -> Frame {
    let (w, h) = (view.width, view.height);
    let (tw, th) = (pyr.width(), pyr.height());
    let mut rgba = vec![0u8; w as usize * h as usize * 4];
    let logging = banks.log.is_some();
    let scheme = opts.scheme;
    let models: Vec<BankModel> = rgba
        .par_chunks_mut((w as usize * 8).max(1))
        .enumerate()
        .map(|(sy, rows)| {
            let mut m = if logging { BankModel::with_log(scheme) } else { BankModel::new(scheme) };
            let rows_here = rows.len() / (w as usize * 4).max(1);
            for sx in 0..w.div_ceil(2) {
                let mut uv = [Vec2::NAN; 4];
                for (i, &(dx, dy)) in SPAN_PIXELS.iter().enumerate() {
                    let (x, y) = (2 * sx + dx, 2 * sy as u32 + dy);
                    if let Some((p, _)) = (x < w && y < h).then(|| view.uv(tw, th, x, y)).flatten() {
                        uv[i] = p;
                    }
                }
                let c = sample_span(pyr, opts, uv, &mut m);
                for (i, &(dx, dy)) in SPAN_PIXELS.iter().enumerate() {
                    let x = (2 * sx + dx) as usize;
                    if x >= w as usize || dy as usize >= rows_here {
                        continue;
                    }
                    let o = (dy as usize * w as usize + x) * 4;
                    let px = if uv[i].is_finite() { encode(c[i]) } else { SKY };
                    rows[o..o + 4].copy_from_slice(&px);
                }
            }
            m
        })
        .collect();
    for m in models {
        banks.merge(m);
    }
    Frame { width: w, height: h, rgba }
}

/// Peak signal-to-noise ratio over RGB, dB (∞ for identical frames, NaN for
/// frames of different sizes): [`crate::metrics::psnr_rgb`].
pub fn psnr(a: &Frame, b: &Frame) -> f64 {
    if a.width != b.width || a.height != b.height {
        return f64::NAN;
    }
    crate::metrics::psnr_rgb(&a.rgba, &b.rgba)
}

/// Mean SSIM of the luma (1 for identical frames, NaN for frames of
/// different sizes): [`crate::metrics::ssim_luma`].
pub fn ssim(a: &Frame, b: &Frame) -> f64 {
    if a.width != b.width || a.height != b.height {
        return f64::NAN;
    }
    crate::metrics::ssim_luma(&a.rgba, &b.rgba, a.width, a.height)
}

/// A frame rendered both ways and compared.
#[derive(Debug, Clone)]
pub struct FrameComparison {
    /// Per-pixel trilinear (the conventional design).
    pub trilinear: Frame,
    /// Span-parallel mapping.
    pub span: Frame,
    /// Bank traffic of the span frame.
    pub banks: BankModel,
    /// [`psnr`] of the span frame against the trilinear one.
    pub psnr: f64,
    /// [`ssim`] of the span frame against the trilinear one.
    pub ssim: f64,
}

/// Renders `view` per pixel (trilinear) and in spans and compares them.
pub fn render_both(pyr: &MipPyramid, view: &FlightView, opts: &SpanOptions) -> FrameComparison {
    let trilinear = render_trilinear(pyr, view, opts.wrap);
    let mut banks = BankModel::new(opts.scheme);
    let span = render_spans(pyr, view, opts, &mut banks);
    let (p, s) = (psnr(&trilinear, &span), ssim(&trilinear, &span));
    FrameComparison { trilinear, span, banks, psnr: p, ssim: s }
}
