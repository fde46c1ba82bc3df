//! Point sets to measure against a model: `{"points": [[x, y, z], …]}` JSON,
//! or `.xyz` text (three numbers a line, separated by spaces, tabs or commas;
//! further columns such as normals or colours are ignored; `#` starts a
//! comment), or the vertices of a PLY file ([`crate::ply`]). Every error
//! names the file and the point or line.

use crate::{DataError, IoError};
use std::path::Path;

/// Largest point file read, in bytes.
pub const MAX_POINTS_FILE_BYTES: u64 = 1 << 30;

/// Reads the points of `path` (`.json`, `.ply` (its vertices), otherwise XYZ text).
pub fn load_points(path: &Path) -> Result<Vec<[f64; 3]>, IoError> {
    if path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("ply")) {
        return crate::ply::load_ply_vertices(path);
    }
    let read = |source| IoError::Read { path: path.to_path_buf(), source };
    let meta = std::fs::metadata(path).map_err(read)?;
    if meta.len() > MAX_POINTS_FILE_BYTES {
        return Err(IoError::Format {
            path: path.to_path_buf(),
            message: format!("{} bytes exceeds the {MAX_POINTS_FILE_BYTES}-byte limit", meta.len()),
        });
    }
    crate::limits::check_text_file(crate::limits::TextKind::Points, meta.len())
        .map_err(|e| IoError::Format { path: path.to_path_buf(), message: e.to_string() })?;
    let bytes = std::fs::read(path).map_err(read)?;
    if let Some(kind) = crate::binary_kind(&bytes) {
        return Err(IoError::Format {
            path: path.to_path_buf(),
            message: format!("{kind}, not a point file (XYZ text: x y z per line, or .json)"),
        });
    }
    let json = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("json"));
    parse_points(&String::from_utf8_lossy(&bytes), json).map_err(|e| e.in_file(path))
}

/// Parses point text: JSON when `json`, otherwise XYZ.
pub fn parse_points(text: &str, json: bool) -> Result<Vec<[f64; 3]>, DataError> {
    points(text, json).map_err(DataError::from)
}

fn points(text: &str, json: bool) -> Result<Vec<[f64; 3]>, String> {
    let pts = if json { parse_json(text)? } else { parse_xyz(text)? };
    if pts.is_empty() {
        return Err("no points".into());
    }
    Ok(pts)
}

#[derive(serde::Deserialize)]
struct PointsJson {
    points: Vec<[f64; 3]>,
}

fn parse_json(text: &str) -> Result<Vec<[f64; 3]>, String> {
    // read straight into the points (a generic JSON tree would take many times the file's size)
    let v: PointsJson = serde_json::from_str(text).map_err(|e| {
        if e.is_data() { format!("expected {{\"points\": [[x, y, z], …]}}: {e}") } else { format!("not JSON: {e}") }
    })?;
    if let Some(i) = v.points.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
        return Err(format!("point {i} is not finite"));
    }
    Ok(v.points)
}

fn parse_xyz(text: &str) -> Result<Vec<[f64; 3]>, String> {
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(|c: char| c.is_whitespace() || c == ',').filter(|f| !f.is_empty()).collect();
        if fields.len() < 3 {
            return Err(format!(
                "line {}: {} value{} where x y z were expected",
                n + 1,
                fields.len(),
                if fields.len() == 1 { "" } else { "s" }
            ));
        }
        let mut p = [0.0; 3];
        for k in 0..3 {
            p[k] = fields[k]
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("line {}: `{}` is not a finite number", n + 1, fields[k]))?;
        }
        out.push(p);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_forms_read_and_bad_ones_name_the_place() {
        assert_eq!(
            parse_points("{\"points\": [[1, 2, 3], [4.5, -5, 6e-1]]}", true).unwrap(),
            vec![[1.0, 2.0, 3.0], [4.5, -5.0, 0.6]]
        );
        let xyz = "# scan\n1 2 3\n\n4.5,-5,0.6 0 0 1   # with a normal\n";
        assert_eq!(parse_points(xyz, false).unwrap(), vec![[1.0, 2.0, 3.0], [4.5, -5.0, 0.6]]);
        for (text, json, want) in [
            ("{\"points\": [[1, 2]]}", true, "invalid length 2, expected an array of length 3 at line 1"),
            ("{\"points\": [[1, 2, \"a\"]]}", true, "invalid type: string \"a\", expected f64"),
            ("{\"pts\": []}", true, "expected {\"points\""),
            ("{\"points\": []}", true, "no points"),
            ("{\"points\": [[1, 2", true, "not JSON"),
            ("1 2 3\n4 5\n", false, "line 2: 2 values"),
            ("1 2 nan\n", false, "line 1: `nan` is not a finite number"),
            ("# only a comment\n", false, "no points"),
        ] {
            let e = parse_points(text, json).unwrap_err();
            assert!(e.message.contains(want), "{text}: {e}");
        }
    }

    #[test]
    fn a_binary_file_is_named_not_quoted() {
        let dir = crate::test_dir::TestDir::fresh("points");
        let tif = dir.join("l7.tif");
        std::fs::write(&tif, b"II*\0\x08\0\0\0\x11\0\0\x01\x03\0 1 2 3").unwrap();
        let e = load_points(&tif).unwrap_err().to_string();
        assert!(e.contains("a TIFF image, not a point file") && !e.contains('\0'), "{e}");
        let raw = dir.join("raw.xyz");
        std::fs::write(&raw, b"1 2 3\n\0\0\0\n").unwrap();
        assert!(load_points(&raw).unwrap_err().to_string().contains("binary data"));
        assert_eq!(crate::binary_kind(b"1 2 3\n"), None);
        std::fs::remove_dir_all(&dir).ok();
    }
}
