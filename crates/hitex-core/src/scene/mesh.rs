//! Indexed triangle meshes with normals, texture coordinates and tangents.

use crate::CoreError;
use glam::{Vec2, Vec3, Vec4};
use std::f32::consts::{PI, TAU};

/// An indexed triangle mesh. All attribute arrays have one entry per vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Name (file or procedural shape) used in messages.
    pub name: String,
    /// Positions (model space).
    pub positions: Vec<Vec3>,
    /// Unit normals.
    pub normals: Vec<Vec3>,
    /// Texture coordinates.
    pub uvs: Vec<Vec2>,
    /// Unit tangents along +u; `w` = ±1 is the handedness of the bitangent
    /// (`B = w · N × T` points along +v).
    pub tangents: Vec<Vec4>,
    /// Three indices per triangle.
    pub indices: Vec<u32>,
}

/// Most vertices or triangles a mesh may have (keeps index math in u32 and
/// allocations sane for hostile files).
pub const MAX_MESH_ELEMENTS: usize = 1 << 26;

impl Mesh {
    /// Builds and validates a mesh. Missing normals are computed (area-weighted
    /// face normals), missing texture coordinates are zero, tangents are always
    /// derived from positions and texture coordinates.
    pub fn new(
        name: &str,
        positions: Vec<Vec3>,
        normals: Option<Vec<Vec3>>,
        uvs: Option<Vec<Vec2>>,
        indices: Vec<u32>,
    ) -> Result<Self, CoreError> {
        let err = |m: String| CoreError::InvalidMesh { name: name.to_string(), message: m };
        if positions.is_empty() || indices.is_empty() {
            return Err(err("the mesh has no triangles".into()));
        }
        if positions.len() > MAX_MESH_ELEMENTS || indices.len() / 3 > MAX_MESH_ELEMENTS {
            return Err(err(format!("more than {MAX_MESH_ELEMENTS} vertices or triangles")));
        }
        if !indices.len().is_multiple_of(3) {
            return Err(err(format!("{} indices is not a multiple of 3", indices.len())));
        }
        let n = positions.len();
        if let Some(i) = indices.iter().position(|&i| i as usize >= n) {
            return Err(err(format!("index {} at position {i} is out of range ({n} vertices)", indices[i])));
        }
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(err(format!("vertex {i} has a non-finite position {:?}", positions[i])));
        }
        let normals = match normals {
            Some(v) if v.len() == n => v,
            Some(v) => return Err(err(format!("{} normals for {n} vertices", v.len()))),
            None => face_weighted_normals(&positions, &indices),
        };
        let uvs = match uvs {
            Some(v) if v.len() == n => v,
            Some(v) => return Err(err(format!("{} texture coordinates for {n} vertices", v.len()))),
            None => vec![Vec2::ZERO; n],
        };
        if let Some(i) = uvs.iter().position(|t| !t.is_finite()) {
            return Err(err(format!("vertex {i} has non-finite texture coordinates")));
        }
        // repair zero or non-finite normals rather than shading NaN
        let faces = face_weighted_normals(&positions, &indices);
        let normals: Vec<Vec3> = normals
            .iter()
            .zip(&faces)
            .map(|(nv, f)| nv.try_normalize().or_else(|| f.try_normalize()).unwrap_or(Vec3::Z))
            .collect();
        let tangents = tangents(&positions, &normals, &uvs, &indices);
        Ok(Self { name: name.to_string(), positions, normals, uvs, tangents, indices })
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// A unit square in the xz-plane centred at the origin, facing +y,
    /// with texture coordinates 0..1 (u along +x, v along +z).
    pub fn plane() -> Self {
        let p = vec![
            Vec3::new(-0.5, 0.0, -0.5),
            Vec3::new(0.5, 0.0, -0.5),
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(-0.5, 0.0, 0.5),
        ];
        let t = vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)];
        Self::procedural("plane", p, Some(vec![Vec3::Y; 4]), t, vec![0, 2, 1, 0, 3, 2])
    }

    /// A unit cube centred at the origin, each face mapped to the full 0..1 square.
    pub fn cube() -> Self {
        let mut p = Vec::new();
        let mut nrm = Vec::new();
        let mut t = Vec::new();
        let mut idx = Vec::new();
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let mut n = Vec3::ZERO;
                n[axis] = sign;
                // any u ⟂ n with v = n × u gives u × v = n: outward, counter-clockwise
                let u = if axis == 1 { Vec3::X } else { Vec3::Y.cross(n) };
                let v = n.cross(u);
                let base = p.len() as u32;
                for (a, b) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
                    p.push(n * 0.5 + u * (a - 0.5) + v * (b - 0.5));
                    nrm.push(n);
                    t.push(Vec2::new(a, 1.0 - b));
                }
                // wind counter-clockwise seen from outside
                idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
            }
        }
        Self::procedural("cube", p, Some(nrm), t, idx)
    }

    /// A unit-radius UV sphere: u around the equator, v from north to south pole.
    pub fn sphere(segments: u32, rings: u32) -> Self {
        let (segments, rings) = (segments.max(3), rings.max(2));
        let mut p = Vec::new();
        let mut t = Vec::new();
        for r in 0..=rings {
            let v = r as f32 / rings as f32;
            let theta = v * PI;
            for s in 0..=segments {
                let u = s as f32 / segments as f32;
                let phi = u * TAU;
                p.push(Vec3::new(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin()));
                t.push(Vec2::new(u, v));
            }
        }
        let row = segments + 1;
        let mut idx = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                let a = r * row + s;
                let b = a + row;
                idx.extend_from_slice(&[a, b, a + 1, a + 1, b, b + 1]);
            }
        }
        let n = p.clone();
        Self::procedural("sphere", p, Some(n), t, idx)
    }

    /// A torus about the y-axis with major radius 1 and minor radius `minor`.
    pub fn torus(minor: f32, segments: u32, sides: u32) -> Self {
        let (segments, sides) = (segments.max(3), sides.max(3));
        let mut p = Vec::new();
        let mut nrm = Vec::new();
        let mut t = Vec::new();
        for i in 0..=segments {
            let u = i as f32 / segments as f32;
            let a = u * TAU;
            let c = Vec3::new(a.cos(), 0.0, -a.sin());
            for j in 0..=sides {
                let v = j as f32 / sides as f32;
                let b = v * TAU;
                let n = c * b.cos() + Vec3::Y * b.sin();
                p.push(c + n * minor);
                nrm.push(n);
                t.push(Vec2::new(u, v));
            }
        }
        let row = sides + 1;
        let mut idx = Vec::new();
        for i in 0..segments {
            for j in 0..sides {
                let a = i * row + j;
                let b = a + row;
                idx.extend_from_slice(&[a, b, a + 1, a + 1, b, b + 1]);
            }
        }
        Self::procedural("torus", p, Some(nrm), t, idx)
    }

    fn procedural(name: &str, p: Vec<Vec3>, n: Option<Vec<Vec3>>, t: Vec<Vec2>, idx: Vec<u32>) -> Self {
        match Self::new(name, p, n, Some(t), idx) {
            Ok(m) => m,
            Err(e) => unreachable!("procedural mesh {name} is valid: {e}"),
        }
    }
}

fn face_weighted_normals(p: &[Vec3], idx: &[u32]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; p.len()];
    for t in idx.chunks_exact(3) {
        let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let f = (p[b] - p[a]).cross(p[c] - p[a]);
        if f.is_finite() {
            n[a] += f;
            n[b] += f;
            n[c] += f;
        }
    }
    n.iter().map(|v| v.normalize_or_zero()).collect()
}

/// Per-vertex tangents from the uv parameterisation: each triangle's
/// ∂P/∂u and ∂P/∂v are accumulated, then Gram–Schmidt against the normal.
fn tangents(p: &[Vec3], n: &[Vec3], uv: &[Vec2], idx: &[u32]) -> Vec<Vec4> {
    let mut tu = vec![Vec3::ZERO; p.len()];
    let mut tv = vec![Vec3::ZERO; p.len()];
    for t in idx.chunks_exact(3) {
        let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let (e1, e2) = (p[b] - p[a], p[c] - p[a]);
        let (d1, d2) = (uv[b] - uv[a], uv[c] - uv[a]);
        let det = d1.x * d2.y - d2.x * d1.y;
        if det.abs() < 1e-20 || !det.is_finite() {
            continue;
        }
        let r = 1.0 / det;
        let su = (e1 * d2.y - e2 * d1.y) * r;
        let sv = (e2 * d1.x - e1 * d2.x) * r;
        for i in [a, b, c] {
            tu[i] += su;
            tv[i] += sv;
        }
    }
    (0..p.len())
        .map(|i| {
            let nn = n[i];
            let t = (tu[i] - nn * nn.dot(tu[i])).try_normalize().unwrap_or_else(|| nn.any_orthonormal_vector());
            let w = if nn.cross(t).dot(tv[i]) < 0.0 { -1.0 } else { 1.0 };
            t.extend(w)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_meshes_are_refused() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(Mesh::new("m", vec![], None, None, vec![]).is_err());
        assert!(Mesh::new("m", p.clone(), None, None, vec![]).is_err());
        assert!(Mesh::new("m", p.clone(), None, None, vec![0, 1]).is_err());
        assert!(Mesh::new("m", p.clone(), None, None, vec![0, 1, 3]).is_err());
        assert!(Mesh::new("m", vec![Vec3::NAN, Vec3::X, Vec3::Y], None, None, vec![0, 1, 2]).is_err());
        assert!(Mesh::new("m", p.clone(), Some(vec![Vec3::Z]), None, vec![0, 1, 2]).is_err());
        let e = Mesh::new("m", p.clone(), None, None, vec![0, 1, 7]).unwrap_err().to_string();
        assert!(e.contains("'m'") && e.contains("index 7"), "{e}");
        assert!(Mesh::new("m", p, None, None, vec![0, 1, 2]).is_ok());
    }

    #[test]
    fn degenerate_triangles_get_finite_frames() {
        let p = vec![Vec3::ZERO, Vec3::ZERO, Vec3::ZERO];
        let m = Mesh::new("d", p, Some(vec![Vec3::ZERO; 3]), None, vec![0, 1, 2]).unwrap();
        assert!(m.normals.iter().all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-6));
        assert!(m.tangents.iter().all(|t| t.is_finite()));
    }

    #[test]
    fn tangents_follow_u_and_bitangents_follow_v() {
        for m in [Mesh::plane(), Mesh::sphere(16, 8), Mesh::torus(0.3, 16, 8), Mesh::cube()] {
            for t in m.indices.chunks_exact(3) {
                let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
                let (e1, e2) = (m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]);
                let (d1, d2) = (m.uvs[b] - m.uvs[a], m.uvs[c] - m.uvs[a]);
                let det = d1.x * d2.y - d2.x * d1.y;
                if det.abs() < 1e-6 || e1.cross(e2).length() < 1e-6 {
                    continue;
                }
                let dpdu = (e1 * d2.y - e2 * d1.y) / det;
                let tan = m.tangents[a];
                assert!(tan.truncate().dot(dpdu) > 0.0, "{}: tangent against +u", m.name);
                // winding agrees with the stored normal
                assert!(e1.cross(e2).dot(m.normals[a]) > 0.0, "{}: winding", m.name);
            }
        }
    }
}
