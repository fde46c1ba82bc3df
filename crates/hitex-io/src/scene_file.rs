//! Scene files on disk.

use crate::{IoError, image_io, obj};
use hitex_core::scene::desc::LoadedNurbs;
use hitex_core::scene::{AssetLoader, Mesh, Scene, SceneDesc};
use hitex_core::texture::{ColorSpace, Image};
use std::path::{Path, PathBuf};

/// Largest scene file accepted, in bytes.
pub const MAX_SCENE_FILE_BYTES: u64 = 16 << 20;

/// Loads files relative to a base folder (the scene file's).
pub struct FileLoader {
    /// Folder that relative paths start from.
    pub base: PathBuf,
}

impl FileLoader {
    fn path(&self, p: &str) -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() { p.to_path_buf() } else { self.base.join(p) }
    }
}

impl AssetLoader for FileLoader {
    type Error = IoError;
    fn load_image(&self, path: &str, cs: ColorSpace) -> Result<Image, IoError> {
        image_io::load_image(&self.path(path), cs)
    }
    fn load_meshes(&self, path: &str) -> Result<Vec<Mesh>, IoError> {
        let p = self.path(path);
        match p.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()) {
            Some(e) if e == "obj" => obj::load_obj(&p),
            _ => Err(IoError::Format { path: p, message: "unsupported mesh format (expected .obj)".into() }),
        }
    }
    fn load_nurbs(&self, spec: &str, is_file: bool) -> Result<LoadedNurbs, IoError> {
        let spec = if is_file { self.path(spec).to_string_lossy().into_owned() } else { spec.to_string() };
        if !is_file && !crate::models::MODEL_NAMES.contains(&spec.as_str()) {
            return Err(IoError::Core(hitex_core::CoreError::InvalidScene {
                key: "nurbs.model".into(),
                message: format!("no built-in NURBS model '{spec}' (known: {})", crate::models::MODEL_NAMES.join(", ")),
            }));
        }
        let m = crate::models::load_model(&spec)?;
        Ok(m.surfaces.into_iter().map(|s| (s.surface, s.range, s.trim)).collect())
    }
}

/// Reads, validates and resolves a scene file. Errors name the scene file and
/// the key (or the line, for syntax errors), or the referenced file.
pub fn load_scene(path: &Path) -> Result<Scene, IoError> {
    let meta = std::fs::metadata(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    if meta.len() > MAX_SCENE_FILE_BYTES {
        return Err(IoError::Format {
            path: path.to_path_buf(),
            message: format!("scene file of {} bytes is too large", meta.len()),
        });
    }
    let text = std::fs::read_to_string(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    let desc = SceneDesc::from_toml(&text).map_err(|e| IoError::from(e).in_file(path))?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    desc.resolve(&FileLoader { base }).map_err(|e| e.in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> crate::test_dir::TestDir {
        crate::test_dir::TestDir::fresh(&format!("scene-{name}"))
    }

    #[test]
    fn scene_with_files_loads_relative_paths() {
        let d = dir("1");
        std::fs::write(d.join("tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
            .unwrap();
        crate::save_png(&d.join("t.png"), 2, 2, &[255; 16]).unwrap();
        let scene = "[camera]\nposition = [0, 0, 3]\ntarget = [0, 0, 0]\n[[texture]]\nname = \"t\"\nfile = \"t.png\"\n\
                     [[material]]\nname = \"m\"\ntexture = \"t\"\n[[object]]\nfile = \"tri.obj\"\n";
        std::fs::write(d.join("s.toml"), scene).unwrap();
        let s = load_scene(&d.join("s.toml")).unwrap();
        assert_eq!(s.objects.len(), 1);
        assert_eq!(s.textures[0].width(), 2);
    }

    #[test]
    fn errors_name_the_scene_file() {
        let d = dir("2");
        std::fs::write(d.join("bad.toml"), "[camera]\nposition = [0, 0, 3]\ntarget = [0, 0, 0]\nzoom = 2\n").unwrap();
        let e = load_scene(&d.join("bad.toml")).unwrap_err().to_string();
        assert!(e.contains("bad.toml") && e.contains("zoom") && e.contains("line 4"), "{e}");
        std::fs::write(d.join("nan.toml"), "[camera]\nposition = [0, 0, nan]\ntarget = [0, 0, 0]\n").unwrap();
        let e = load_scene(&d.join("nan.toml")).unwrap_err().to_string();
        assert!(e.contains("nan.toml") && e.contains("camera.position[2]"), "{e}");
        std::fs::write(
            d.join("missing.toml"),
            "[camera]\nposition = [0, 0, 3]\ntarget = [0, 0, 0]\n[[object]]\nfile = \"gone.obj\"\n",
        )
        .unwrap();
        let e = load_scene(&d.join("missing.toml")).unwrap_err().to_string();
        assert!(e.contains("gone.obj"), "{e}");
        let e = load_scene(&d.join("does-not-exist.toml")).unwrap_err().to_string();
        assert!(e.contains("does-not-exist.toml"), "{e}");
    }
}
