//! Non-uniform rational B-spline surfaces (seed 004): knot spans, basis
//! functions and their derivatives (The NURBS Book, A2.1–A2.3), rational
//! surface derivatives (A4.4), normals with limits at degenerate points,
//! curvatures, knot insertion (A5.1) and exact degree elevation.
//!
//! The math is generic over [`Real`] so that the f64 reference and the f32
//! path the fragment programs mirror share one text.

// The kernels follow the book's index arithmetic on purpose (spans, triangles
// of basis values): index loops read closer to the algorithms than iterators.
#![allow(clippy::needless_range_loop)]

pub mod basis;
pub mod continuity;
pub mod deviation;
pub mod elevate;
pub mod knots;
pub mod measure;
pub mod surface;

pub use basis::{MAX_DEGREE, basis_ders_fixed, basis_ders_paper, basis_funs, ders_basis_funs};
pub use knots::{find_span, validate_knots};
pub use surface::{Curvature, NurbsSurface, SurfaceDerivs};

use thiserror::Error;

/// Floating-point types the evaluator runs on.
pub trait Real:
    Copy
    + PartialOrd
    + std::fmt::Debug
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
    + std::ops::AddAssign
    + std::ops::SubAssign
{
    /// 0
    const ZERO: Self;
    /// 1
    const ONE: Self;
    /// Conversion from f64 (rounding for f32).
    fn from_f64(v: f64) -> Self;
    /// Conversion to f64.
    fn to_f64(self) -> f64;
}

impl Real for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn from_f64(v: f64) -> Self {
        v
    }
    fn to_f64(self) -> f64 {
        self
    }
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    fn to_f64(self) -> f64 {
        self as f64
    }
}

/// An invalid NURBS definition. Messages name the offending field and index.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum NurbsError {
    /// Degree outside 1..=MAX_DEGREE.
    #[error("degree {degree} in {dir} is outside 1..={MAX_DEGREE}")]
    Degree {
        /// "u" or "v".
        dir: &'static str,
        /// The degree given.
        degree: usize,
    },
    /// Knot count ≠ control points + degree + 1, or too few control points.
    #[error("{dir}: {message}")]
    Counts {
        /// "u" or "v".
        dir: &'static str,
        /// What is wrong.
        message: String,
    },
    /// Knots decreasing, not finite, or an empty parameter range.
    #[error("{dir} knots: {message}")]
    Knots {
        /// "u" or "v".
        dir: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A control point with a non-finite coordinate or a weight ≤ 0.
    #[error("control point ({i}, {j}): {message}")]
    ControlPoint {
        /// Index along u.
        i: usize,
        /// Index along v.
        j: usize,
        /// What is wrong.
        message: String,
    },
}
