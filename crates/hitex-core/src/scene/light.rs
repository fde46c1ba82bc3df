//! Light sources.

use glam::Vec3;

/// A light source. Colours are linear RGB, multiplied by `intensity`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// Parallel light travelling along `direction` (from the light towards the scene).
    Directional {
        /// Direction of travel (need not be unit length; not zero).
        direction: Vec3,
        /// Linear RGB colour.
        color: Vec3,
        /// Scale of the colour.
        intensity: f32,
    },
    /// Light from a point, falling off with the inverse square of distance.
    Point {
        /// World position.
        position: Vec3,
        /// Linear RGB colour.
        color: Vec3,
        /// Radiant intensity: irradiance at distance 1.
        intensity: f32,
    },
}
