//! Wavefront OBJ meshes (polygonal part), read through `tobj`.
//!
//! Polygons are triangulated, one mesh per `o`/`g` group. Texture coordinates
//! are flipped to hitex's convention (v down, row 0 at the top of the image).
//! When `tobj` refuses a file, the offending line is located and quoted.

use crate::IoError;
use glam::{Vec2, Vec3};
use hitex_core::scene::Mesh;
use std::path::Path;

/// Largest OBJ file accepted, in bytes.
pub const MAX_OBJ_FILE_BYTES: u64 = 1 << 31;

/// Reads every group of an OBJ file as a mesh.
pub fn load_obj(path: &Path) -> Result<Vec<Mesh>, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let meta = std::fs::metadata(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    if meta.len() > MAX_OBJ_FILE_BYTES {
        return Err(fmt(format!("file of {} bytes exceeds the {MAX_OBJ_FILE_BYTES}-byte limit", meta.len())));
    }
    crate::limits::check_text_file(crate::limits::TextKind::ObjMesh, meta.len()).map_err(|e| fmt(e.to_string()))?;
    let bytes = std::fs::read(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    let text = String::from_utf8_lossy(&bytes);
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let mut reader = std::io::BufReader::new(text.as_bytes());
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &opts, |_| Err(tobj::LoadError::OpenFileFailed))
        .map_err(|e| match locate_error(&text) {
            Some((line, content)) => fmt(format!("{e} at line {line}: `{content}`")),
            None => fmt(format!("{e}")),
        })?;
    let mut meshes = Vec::new();
    for (k, m) in models.iter().enumerate() {
        let g = &m.mesh;
        if g.indices.is_empty() {
            continue;
        }
        let name = if m.name.is_empty() { format!("group {k}") } else { m.name.clone() };
        let positions: Vec<Vec3> = g.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let n = positions.len();
        let normals = (g.normals.len() == 3 * n)
            .then(|| g.normals.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect());
        let uvs = (g.texcoords.len() == 2 * n)
            .then(|| g.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], 1.0 - c[1])).collect());
        let mesh = Mesh::new(&format!("{}:{name}", path.display()), positions, normals, uvs, g.indices.clone())
            .map_err(|e| fmt(format!("group '{name}': {e}")))?;
        meshes.push(mesh);
    }
    if meshes.is_empty() {
        return Err(fmt("the file has no faces".into()));
    }
    Ok(meshes)
}

/// First line that is not valid OBJ geometry, as (1-based number, text).
fn locate_error(text: &str) -> Option<(usize, String)> {
    let (mut nv, mut nt, mut nn) = (0i64, 0i64, 0i64);
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut it = line.split_whitespace();
        let Some(tag) = it.next() else { continue };
        let rest: Vec<&str> = it.collect();
        let floats = |lo: usize, hi: usize| {
            rest.len() >= lo && rest.len() <= hi && rest.iter().all(|s| s.parse::<f32>().is_ok())
        };
        let ok = match tag {
            "v" => {
                nv += 1;
                floats(3, 7)
            }
            "vt" => {
                nt += 1;
                floats(1, 3)
            }
            "vn" => {
                nn += 1;
                floats(3, 3)
            }
            "f" => {
                rest.len() >= 3
                    && rest.iter().all(|v| {
                        let parts: Vec<&str> = v.split('/').collect();
                        let idx_ok = |s: Option<&&str>, n: i64, required: bool| match s {
                            None => !required,
                            Some(&"") => !required,
                            Some(s) => {
                                s.parse::<i64>().map(|k| (k > 0 && k <= n) || (k < 0 && -k <= n)).unwrap_or(false)
                            }
                        };
                        parts.len() <= 3
                            && idx_ok(parts.first(), nv, true)
                            && idx_ok(parts.get(1), nt, false)
                            && idx_ok(parts.get(2), nn, false)
                    })
            }
            _ => true,
        };
        if !ok {
            return Some((i + 1, raw.trim().chars().take(80).collect()));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `text` as file `name` in a folder of its own, which goes with the
    /// returned guard (at the end of the statement that reads the file).
    fn write(name: &str, text: &str) -> File {
        let d = crate::test_dir::TestDir::fresh(&format!("obj-{name}"));
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        File(p, d)
    }

    struct File(std::path::PathBuf, #[allow(dead_code)] crate::test_dir::TestDir);

    impl std::ops::Deref for File {
        type Target = std::path::Path;
        fn deref(&self) -> &std::path::Path {
            &self.0
        }
    }

    const QUAD: &str =
        "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";

    #[test]
    fn quad_is_triangulated_and_v_flipped() {
        let m = load_obj(&write("quad.obj", QUAD)).unwrap();
        assert_eq!(m.len(), 1);
        assert_eq!(m[0].triangle_count(), 2);
        // vt (0,0) is the bottom-left of the image: our v = 1
        let i = m[0].positions.iter().position(|p| *p == Vec3::ZERO).unwrap();
        assert_eq!(m[0].uvs[i], Vec2::new(0.0, 1.0));
        // normals were computed: +z
        assert!((m[0].normals[i] - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn malformed_files_name_file_and_line() {
        let e = load_obj(&write("badv.obj", "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n")).unwrap_err().to_string();
        assert!(e.contains("badv.obj") && e.contains("line 2"), "{e}");
        let e = load_obj(&write("badf.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")).unwrap_err().to_string();
        assert!(e.contains("badf.obj") && e.contains("line 4"), "{e}");
        let e = load_obj(&write("noface.obj", "v 0 0 0\nv 1 0 0\n")).unwrap_err().to_string();
        assert!(e.contains("noface.obj") && e.contains("no faces"), "{e}");
        let e = load_obj(&write("empty.obj", "")).unwrap_err().to_string();
        assert!(e.contains("empty.obj"), "{e}");
        let e = load_obj(&write("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")).unwrap_err().to_string();
        assert!(e.contains("nan.obj") && e.contains("non-finite"), "{e}");
        let e = load_obj(&write("bin.obj", "\u{0}\u{1}\u{2}garbage\u{7f}")).unwrap_err().to_string();
        assert!(e.contains("bin.obj"), "{e}");
        let e = load_obj(Path::new("/no/such/file.obj")).unwrap_err().to_string();
        assert!(e.contains("file.obj"), "{e}");
    }
}
