//! STL meshes (binary and ASCII), the form in which scanners and CAD
//! systems exchange triangles, and the reference a surface is measured
//! against ([`load_reference`]: STL, OBJ, PLY, or a point file).
//!
//! Binary: an 80-byte header, a little-endian u32 triangle count, then 50
//! bytes a triangle (normal, three vertices as f32, a 16-bit attribute). A
//! file whose size is exactly that of its claimed count is binary, whatever
//! its header says (some exporters begin binary headers with `solid`);
//! otherwise a file beginning with `solid` is read as ASCII (`vertex x y z`
//! lines, three a facet). Facet normals are ignored: the side is the
//! vertices' order. Every error names the file and the triangle or line.

use crate::{DataError, IoError};
use std::path::Path;

/// A triangle's three corners.
pub type Triangle = [[f64; 3]; 3];

/// Bytes a binary STL triangle takes in the file.
const RECORD: u64 = 50;

/// Bytes a triangle takes in memory as read ([`Triangle`]).
const HELD: u64 = 72;

/// Reads the triangles of an STL file.
pub fn load_stl(path: &Path) -> Result<Vec<Triangle>, IoError> {
    let read = |source| IoError::Read { path: path.to_path_buf(), source };
    let fmt = |message: String| IoError::Format { path: path.to_path_buf(), message };
    let meta = std::fs::metadata(path).map_err(read)?;
    // binary: held triangles are 72/50 of the file; ASCII: about a tenth of it
    crate::limits::check_cap("reading this STL file", Some(meta.len().saturating_mul(HELD) / RECORD))
        .map_err(|e| fmt(e.to_string()))?;
    let bytes = std::fs::read(path).map_err(read)?;
    stl(&bytes).map_err(fmt)
}

/// Parses STL bytes (binary or ASCII).
pub fn parse_stl(bytes: &[u8]) -> Result<Vec<Triangle>, DataError> {
    stl(bytes).map_err(DataError::from)
}

fn stl(bytes: &[u8]) -> Result<Vec<Triangle>, String> {
    let claimed = bytes.get(80..84).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as u64);
    let len = bytes.len() as u64;
    let exact_binary = claimed.is_some_and(|n| 84 + n * RECORD == len);
    let ascii = bytes.trim_ascii_start().starts_with(b"solid");
    let tris =
        if exact_binary || !ascii { binary(bytes, claimed)? } else { ascii_stl(&String::from_utf8_lossy(bytes))? };
    if tris.is_empty() {
        return Err("no triangles".into());
    }
    Ok(tris)
}

fn binary(bytes: &[u8], claimed: Option<u64>) -> Result<Vec<Triangle>, String> {
    let Some(n) = claimed else {
        return Err(format!(
            "{} bytes: too short for a binary STL header (84 bytes) and does not begin with `solid` (ASCII STL)",
            bytes.len()
        ));
    };
    let len = bytes.len() as u64;
    let need = 84 + n * RECORD;
    if len < need {
        return Err(format!(
            "binary STL claims {n} triangles ({need} bytes) but the file has {len} bytes: truncated after triangle {}",
            (len.saturating_sub(84)) / RECORD
        ));
    }
    crate::limits::check_cap("the STL file's triangles", n.checked_mul(HELD)).map_err(|e| e.to_string())?;
    let mut tris = Vec::with_capacity(n as usize);
    for (k, rec) in bytes[84..need as usize].chunks_exact(RECORD as usize).enumerate() {
        let f = |i: usize| f32::from_le_bytes([rec[i], rec[i + 1], rec[i + 2], rec[i + 3]]) as f64;
        let t: Triangle = [0, 1, 2].map(|v| [0, 1, 2].map(|c| f(12 + 12 * v + 4 * c)));
        if !t.iter().flatten().all(|x| x.is_finite()) {
            return Err(format!("triangle {k}: a vertex is not finite"));
        }
        tris.push(t);
    }
    Ok(tris)
}

fn ascii_stl(text: &str) -> Result<Vec<Triangle>, String> {
    let mut tris = Vec::new();
    let mut corners: Vec<[f64; 3]> = Vec::with_capacity(3);
    let mut facet_line = 0;
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("facet") => {
                if !corners.is_empty() {
                    return Err(format!("line {n}: a facet begins before the one at line {facet_line} has 3 vertices"));
                }
                facet_line = n;
            }
            Some("vertex") => {
                let mut p = [0.0f64; 3];
                for c in &mut p {
                    let w = words.next().ok_or_else(|| format!("line {n}: `vertex` needs x y z: `{}`", line.trim()))?;
                    *c = w.parse().map_err(|_| format!("line {n}: '{w}' is not a number: `{}`", line.trim()))?;
                    if !c.is_finite() {
                        return Err(format!("line {n}: '{w}' is not finite"));
                    }
                }
                if corners.len() == 3 {
                    return Err(format!(
                        "line {n}: a fourth vertex in the facet at line {facet_line} (STL facets are triangles)"
                    ));
                }
                corners.push(p);
            }
            Some("endfacet") => {
                if corners.len() != 3 {
                    return Err(format!(
                        "line {n}: the facet at line {facet_line} has {} vertices, not 3",
                        corners.len()
                    ));
                }
                tris.push([corners[0], corners[1], corners[2]]);
                corners.clear();
                // keep memory within the cap as the facets come
                if tris.len() % 65536 == 0 {
                    crate::limits::check_cap("the STL file's triangles", Some(tris.len() as u64 * HELD))
                        .map_err(|e| e.to_string())?;
                }
            }
            _ => {}
        }
    }
    if !corners.is_empty() {
        return Err(format!("the facet at line {facet_line} is not closed by `endfacet`"));
    }
    Ok(tris)
}

/// What a surface is measured against: triangles or points.
#[derive(Debug, Clone, PartialEq)]
pub enum ReferenceData {
    /// A mesh (STL, OBJ, PLY with faces).
    Mesh(Vec<Triangle>),
    /// A point cloud (XYZ text, `{"points": …}` JSON, PLY without faces).
    Points(Vec<[f64; 3]>),
}

/// Reads a reference by its extension: `.stl`, `.obj` (every group's
/// triangles), `.ply` ([`crate::ply::load_ply`]: faces, else points), otherwise a point file ([`crate::points::load_points`]:
/// `.xyz`, `.txt`, `.pts`, `.json`).
pub fn load_reference(path: &Path) -> Result<ReferenceData, IoError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("stl") => load_stl(path).map(ReferenceData::Mesh),
        Some("obj") => {
            let meshes = crate::obj::load_obj(path)?;
            let mut tris = Vec::new();
            for m in &meshes {
                for t in m.indices.chunks_exact(3) {
                    let p = |i: u32| m.positions.get(i as usize).map(|v| [v.x as f64, v.y as f64, v.z as f64]);
                    if let (Some(a), Some(b), Some(c)) = (p(t[0]), p(t[1]), p(t[2])) {
                        tris.push([a, b, c]);
                    }
                }
            }
            if tris.is_empty() {
                return Err(IoError::Format { path: path.to_path_buf(), message: "no triangles".into() });
            }
            Ok(ReferenceData::Mesh(tris))
        }
        Some("ply") => crate::ply::load_ply(path),
        _ => crate::points::load_points(path).map(ReferenceData::Points),
    }
}

/// Writes triangles as binary STL (for tests and round trips).
pub fn to_binary_stl(tris: &[Triangle]) -> Vec<u8> {
    let mut out = Vec::with_capacity(84 + tris.len() * RECORD as usize);
    let mut header = [b' '; 80];
    header[..17].copy_from_slice(b"binary STL, hitex");
    out.extend_from_slice(&header);
    out.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        let (a, b, c) = (t[0], t[1], t[2]);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let n = if l > 0.0 { n.map(|x| x / l) } else { [0.0; 3] };
        for x in n.iter().chain(a.iter()).chain(b.iter()).chain(c.iter()) {
            out.extend_from_slice(&(*x as f32).to_le_bytes());
        }
        out.extend_from_slice(&[0, 0]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "solid cube\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 1\n   vertex 1 0 1\n   vertex 1 1 1\n  endloop\n endfacet\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 1\n   vertex 1 1 1\n   vertex 0 1 1e0\n  endloop\n endfacet\nendsolid cube\n";

    #[test]
    fn ascii_and_binary_read_the_same_triangles() {
        let a = parse_stl(ASCII.as_bytes()).expect("ascii");
        assert_eq!(a.len(), 2);
        assert_eq!(a[1][2], [0.0, 1.0, 1.0]);
        let b = parse_stl(&to_binary_stl(&a)).expect("binary");
        assert_eq!(a, b);
        // a binary file whose header begins with `solid` is still binary
        let mut c = to_binary_stl(&a);
        c[..5].copy_from_slice(b"solid");
        assert_eq!(parse_stl(&c).expect("binary with solid header"), a);
    }

    #[test]
    fn malformed_files_name_the_triangle_or_line() {
        let bin = to_binary_stl(&parse_stl(ASCII.as_bytes()).unwrap_or_default());
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (bin[..bin.len() - 10].to_vec(), "truncated after triangle 1"),
            (b"hello".to_vec(), "too short for a binary STL header"),
            (ASCII.replace("vertex 1 0 1", "vertex 1 x 1").into_bytes(), "line 5: 'x' is not a number"),
            (
                ASCII
                    .replace("   vertex 1 1 1\n  endloop\n endfacet\n facet", "  endloop\n endfacet\n facet")
                    .into_bytes(),
                "has 2 vertices, not 3",
            ),
            (ASCII.replace("vertex 0 1 1e0", "vertex 0 1 inf").into_bytes(), "is not finite"),
            (b"solid empty\nendsolid empty\n".to_vec(), "no triangles"),
            (ASCII.replace(" endfacet\nendsolid", "endsolid").into_bytes(), "not closed by `endfacet`"),
        ];
        for (bytes, want) in cases {
            let e = parse_stl(&bytes).expect_err(want);
            assert!(e.message.contains(want), "{e} lacks '{want}'");
        }
        // a count claiming more than the cap is refused before allocating
        let mut huge = bin.clone();
        huge[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(parse_stl(&huge).expect_err("huge").message.contains("claims 4294967295 triangles"));
        // non-finite binary vertices
        let mut nan = bin;
        nan[84 + 12..84 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(parse_stl(&nan).expect_err("nan").message.contains("triangle 0: a vertex is not finite"));
    }
}
