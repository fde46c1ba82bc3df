//! The four angles and the convention in a BTF image file's name.

/// A direction as named: degrees, φ in [0, 360).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Dir {
    pub(super) theta: f32,
    pub(super) phi: f32,
}

/// A direction's identity: θ and φ in hundredths of a degree.
pub(super) type Key = (i32, i32);

impl Dir {
    pub(super) fn new(theta: f32, phi: f32) -> Self {
        let mut phi = phi.rem_euclid(360.0);
        if phi >= 360.0 {
            phi = 0.0;
        }
        Self { theta, phi }
    }

    pub(super) fn key(self) -> Key {
        ((self.theta * 100.0).round() as i32, (self.phi * 100.0).round() as i32 % 36_000)
    }

    pub(super) fn vector(self) -> [f64; 3] {
        unit(self.theta as f64, self.phi as f64)
    }
}

pub(super) fn unit(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    let (sp, cp) = phi_deg.to_radians().sin_cos();
    [st * cp, st * sp, ct]
}

/// Angle between unit vectors, radians.
pub(super) fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0).acos()
}

pub(super) fn circular_diff(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

pub(super) fn angle_str(a: f32) -> String {
    if (a - a.round()).abs() < 1e-3 { format!("{:03}", a.round() as i64) } else { format!("{a}") }
}

pub(super) fn combo_name(light: Dir, view: Dir) -> String {
    format!(
        "tl{} pl{} tv{} pv{}",
        angle_str(light.theta),
        angle_str(light.phi),
        angle_str(view.theta),
        angle_str(view.phi)
    )
}

/// What a file name says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Name {
    /// A PNG or JPEG image with `[tl, pl, tv, pv]`.
    Image([f32; 4]),
    /// An OpenEXR image with the angles.
    Exr([f32; 4]),
    /// Anything else.
    Other,
}

/// Parses one file name (without folders).
pub(super) fn parse_name(base: &str) -> Name {
    let lower = base.trim().to_ascii_lowercase();
    if lower.starts_with('.') {
        return Name::Other;
    }
    let Some((stem, ext)) = lower.rsplit_once('.') else {
        return Name::Other;
    };
    let exr = match ext {
        "png" | "jpg" | "jpeg" => false,
        "exr" => true,
        _ => return Name::Other,
    };
    let mut vals: [Option<f32>; 4] = [None; 4];
    for tok in stem.split([' ', '_', '-', '+', ',']).filter(|t| !t.is_empty()) {
        for (slot, key) in vals.iter_mut().zip(["tl", "pl", "tv", "pv"]) {
            let Some(num) = tok.strip_prefix(key) else { continue };
            if num.is_empty() || !num.chars().all(|c| c.is_ascii_digit() || c == '.') {
                continue;
            }
            let Ok(v) = num.parse::<f32>() else { continue };
            if !v.is_finite() || slot.is_some() {
                return Name::Other;
            }
            *slot = Some(v);
        }
    }
    match vals {
        [Some(tl), Some(pl), Some(tv), Some(pv)] => {
            if exr {
                Name::Exr([tl, pl, tv, pv])
            } else {
                Name::Image([tl, pl, tv, pv])
            }
        }
        _ => Name::Other,
    }
}
