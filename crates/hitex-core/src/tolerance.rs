//! Named tolerances shared by tests and comparisons.
//!
//! Every comparison in hitex states which constant it uses, so a change of
//! tolerance is one edit in one place.

/// Relative/absolute tolerance for single-precision math that went through a
/// handful of operations (interpolation, one normalisation).
pub const EPS_F32: f32 = 1e-5;
/// Tolerance for double-precision reference math.
pub const EPS_F64: f64 = 1e-12;
/// One step of an 8-bit colour channel.
pub const ONE_U8_STEP: f32 = 1.0 / 255.0;

/// Asserts that two floating-point values (or the components of two
/// equal-length slices/arrays) differ by at most `eps`.
///
/// ```
/// use hitex_core::assert_near;
/// assert_near!(0.1_f32 + 0.2, 0.3, 1e-6);
/// assert_near!([1.0_f32, 2.0], [1.0, 2.0 + 1e-7], 1e-6);
/// ```
#[macro_export]
macro_rules! assert_near {
    ($a:expr, $b:expr, $eps:expr) => {{
        let a = $a;
        let b = $b;
        let eps = $eps;
        $crate::tolerance::NearCheck::check_near(&a, &b, eps, stringify!($a), stringify!($b));
    }};
}

/// Implementation detail of [`assert_near!`].
pub trait NearCheck<Rhs: ?Sized = Self> {
    /// Panics with a descriptive message when the values differ by more than `eps`.
    fn check_near(&self, other: &Rhs, eps: f64, a: &str, b: &str);
}

macro_rules! near_scalar {
    ($t:ty) => {
        impl NearCheck for $t {
            fn check_near(&self, other: &$t, eps: f64, a: &str, b: &str) {
                let d = (*self as f64 - *other as f64).abs();
                assert!(d <= eps, "assert_near failed: {a} = {} vs {b} = {} (|diff| = {d:e} > {eps:e})", self, other);
            }
        }
    };
}
near_scalar!(f32);
near_scalar!(f64);

impl<T: NearCheck, const N: usize> NearCheck for [T; N] {
    fn check_near(&self, other: &[T; N], eps: f64, a: &str, b: &str) {
        for (i, (x, y)) in self.iter().zip(other.iter()).enumerate() {
            x.check_near(y, eps, &format!("{a}[{i}]"), &format!("{b}[{i}]"));
        }
    }
}

impl<T: NearCheck> NearCheck for [T] {
    fn check_near(&self, other: &[T], eps: f64, a: &str, b: &str) {
        assert_eq!(self.len(), other.len(), "assert_near: {a} and {b} differ in length");
        for (i, (x, y)) in self.iter().zip(other.iter()).enumerate() {
            x.check_near(y, eps, &format!("{a}[{i}]"), &format!("{b}[{i}]"));
        }
    }
}

impl<T: NearCheck> NearCheck for Vec<T> {
    fn check_near(&self, other: &Vec<T>, eps: f64, a: &str, b: &str) {
        self.as_slice().check_near(other.as_slice(), eps, a, b);
    }
}

impl NearCheck for glam::Vec3 {
    fn check_near(&self, other: &glam::Vec3, eps: f64, a: &str, b: &str) {
        self.to_array().check_near(&other.to_array(), eps, a, b);
    }
}

impl NearCheck for glam::Vec4 {
    fn check_near(&self, other: &glam::Vec4, eps: f64, a: &str, b: &str) {
        self.to_array().check_near(&other.to_array(), eps, a, b);
    }
}

impl NearCheck for glam::Vec2 {
    fn check_near(&self, other: &glam::Vec2, eps: f64, a: &str, b: &str) {
        self.to_array().check_near(&other.to_array(), eps, a, b);
    }
}
