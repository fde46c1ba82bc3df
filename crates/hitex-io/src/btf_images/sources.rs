//! The files of an image set: listed from a folder or zip archive, read,
//! and decoded from PNG or JPEG.

use super::*;

/// Where one file of a set is.
#[derive(Debug, Clone)]
pub(super) enum Loc {
    File(PathBuf),
    Zip(usize),
}

/// One file of a set.
#[derive(Debug, Clone)]
pub(super) struct Listed {
    /// Relative path or archive entry, as reported.
    pub(super) shown: String,
    /// The file name without folders.
    pub(super) base: String,
    pub(super) loc: Loc,
}

/// A folder or a zip archive of images.
pub(super) enum Source {
    Dir,
    Zip(zip::ZipArchive<std::fs::File>),
}

impl Source {
    pub(super) fn open(path: &Path) -> Result<(Source, Vec<Listed>), IoError> {
        let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
        let meta = std::fs::metadata(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
        let mut listed = Vec::new();
        let source = if meta.is_dir() {
            walk(path, path, 0, &mut listed)?;
            Source::Dir
        } else {
            let file =
                std::fs::File::open(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
            let mut zip = zip::ZipArchive::new(file).map_err(|e| {
                // the zip crate's words ("Could not find EOCD") mean: no
                // archive directory at the end, i.e. not a zip or a cut one
                let why = match e {
                    zip::result::ZipError::InvalidArchive(_) => {
                        "no zip directory at its end (not a zip archive, or a truncated one)".to_string()
                    }
                    e => e.to_string(),
                };
                fmt(format!("neither a folder nor a readable zip archive: {why}"))
            })?;
            for i in 0..zip.len() {
                let f = zip.by_index_raw(i).map_err(|e| fmt(format!("zip entry {i}: {e}")))?;
                if f.is_dir() {
                    continue;
                }
                let shown = String::from_utf8_lossy(f.name_raw()).into_owned();
                let base = shown.rsplit(['/', '\\']).next().unwrap_or(&shown).to_string();
                let base = if shown.split(['/', '\\']).any(|c| c == "__MACOSX") { format!(".{base}") } else { base };
                listed.push(Listed { shown, base, loc: Loc::Zip(i) });
            }
            Source::Zip(zip)
        };
        listed.sort_by(|a, b| a.shown.cmp(&b.shown));
        Ok((source, listed))
    }

    /// The path named in errors about `item`.
    pub(super) fn err_path(root: &Path, item: &Listed) -> PathBuf {
        match &item.loc {
            Loc::File(p) => p.clone(),
            Loc::Zip(_) => PathBuf::from(format!("{}:{}", root.display(), item.shown)),
        }
    }

    pub(super) fn read(&mut self, root: &Path, item: &Listed) -> Result<Vec<u8>, IoError> {
        let at = Self::err_path(root, item);
        let fmt = |m: String| IoError::Format { path: at.clone(), message: m };
        let too_big = |n: u64| fmt(format!("file of {n} bytes exceeds the {MAX_IMAGE_FILE_BYTES}-byte limit"));
        match (&mut *self, &item.loc) {
            (_, Loc::File(p)) => {
                let rerr = |source: std::io::Error| IoError::Read { path: p.clone(), source };
                let len = std::fs::metadata(p).map_err(rerr)?.len();
                if len > MAX_IMAGE_FILE_BYTES {
                    return Err(too_big(len));
                }
                std::fs::read(p).map_err(rerr)
            }
            (Source::Zip(zip), Loc::Zip(i)) => {
                let f = zip.by_index(*i).map_err(|e| fmt(format!("cannot open the zip entry: {e}")))?;
                if f.size() > MAX_IMAGE_FILE_BYTES {
                    return Err(too_big(f.size()));
                }
                let mut buf = Vec::with_capacity(f.size().min(64 << 20) as usize);
                f.take(MAX_IMAGE_FILE_BYTES + 1)
                    .read_to_end(&mut buf)
                    .map_err(|e| fmt(format!("cannot read the zip entry: {e}")))?;
                if buf.len() as u64 > MAX_IMAGE_FILE_BYTES {
                    return Err(too_big(buf.len() as u64));
                }
                Ok(buf)
            }
            (Source::Dir, Loc::Zip(_)) => Err(fmt("internal: an archive entry in a folder set".into())),
        }
    }
}

pub(super) fn walk(root: &Path, dir: &Path, depth: usize, out: &mut Vec<Listed>) -> Result<(), IoError> {
    let rerr = |source: std::io::Error| IoError::Read { path: dir.to_path_buf(), source };
    let mut items = std::fs::read_dir(dir).map_err(rerr)?.collect::<Result<Vec<_>, _>>().map_err(rerr)?;
    items.sort_by_key(|e| e.file_name());
    for e in items {
        let p = e.path();
        let base = e.file_name().to_string_lossy().into_owned();
        let shown = p.strip_prefix(root).unwrap_or(&p).to_string_lossy().into_owned();
        // follows symbolic links to files, never into folders (no cycles)
        let ft = e.file_type().map_err(|source| IoError::Read { path: p.clone(), source })?;
        if ft.is_dir() {
            if depth < MAX_DEPTH && !base.starts_with('.') && base != "__MACOSX" {
                walk(root, &p, depth + 1, out)?;
            }
        } else if ft.is_file() || p.is_file() {
            out.push(Listed { shown, base, loc: Loc::File(p) });
        }
    }
    Ok(())
}

/// Decodes a PNG or JPEG to RGB8, checking the declared size first.
pub(super) fn decode_rgb(bytes: &[u8], path: &Path) -> Result<(u32, u32, Vec<u8>), IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let reader = || -> Result<_, IoError> {
        let r = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
        if r.format().is_none() {
            return Err(fmt("not a PNG or JPEG image (unrecognised signature)".into()));
        }
        Ok(r)
    };
    let (w, h) = reader()?.into_dimensions().map_err(|e| fmt(format!("cannot read the image header: {e}")))?;
    let side = hitex_core::texture::image::MAX_IMAGE_SIDE;
    if w == 0 || h == 0 || w > side || h > side {
        return Err(fmt(format!("declared size {w}x{h} is outside 1..={side} per side")));
    }
    let img = reader()?.decode().map_err(|e| fmt(format!("cannot decode the image: {e}")))?.into_rgb8();
    let (w, h) = img.dimensions();
    Ok((w, h, img.into_raw()))
}
