//! Image files.

use crate::IoError;
use hitex_core::texture::{ColorSpace, Image};
use std::io::Write;
use std::path::Path;

/// Largest image file accepted, in bytes (a sanity cap against hostile input).
pub const MAX_IMAGE_FILE_BYTES: u64 = 1 << 30;

/// Reads a PNG or JPEG file into an RGBA8 image (see [`decode_image`]).
pub fn load_image(path: &Path, color_space: ColorSpace) -> Result<Image, IoError> {
    let meta = std::fs::metadata(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    if meta.len() > MAX_IMAGE_FILE_BYTES {
        let message = format!("file of {} bytes exceeds the {MAX_IMAGE_FILE_BYTES}-byte limit", meta.len());
        return Err(IoError::Format { path: path.to_path_buf(), message });
    }
    let bytes = std::fs::read(path).map_err(|source| IoError::Read { path: path.to_path_buf(), source })?;
    decode_image(&bytes, path, color_space)
}

/// Decodes a PNG or JPEG held in memory; `path` is the file named in errors.
/// The declared dimensions are checked against
/// [`hitex_core::texture::image::MAX_IMAGE_SIDE`], against what the file's
/// length can hold and against the memory cap before any pixel is decoded.
pub fn decode_image(bytes: &[u8], path: &Path, color_space: ColorSpace) -> Result<Image, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let reader = || {
        image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|source| IoError::Read { path: path.to_path_buf(), source })
    };
    let probe = reader()?;
    let ratio = match probe.format() {
        Some(image::ImageFormat::Png) => crate::limits::DEFLATE_RATIO,
        Some(image::ImageFormat::Jpeg) => crate::limits::ANY_RATIO,
        _ => return Err(fmt("not a PNG or JPEG image (unrecognised signature)".into())),
    };
    let decoder = probe.into_decoder().map_err(|e| fmt(format!("cannot read the image header: {e}")))?;
    let (w, h) = image::ImageDecoder::dimensions(&decoder);
    let raw = image::ImageDecoder::total_bytes(&decoder);
    drop(decoder);
    let side = hitex_core::texture::image::MAX_IMAGE_SIDE;
    if w == 0 || h == 0 || w > side || h > side {
        return Err(fmt(format!("declared size {w}x{h} is outside 1..={side} per side")));
    }
    // the decoded samples must come out of the file's bytes; with the RGBA8 copy they must fit the cap
    let what = format!("a {w}x{h} image");
    crate::limits::check_claim(&what, Some(raw), bytes.len() as u64, ratio).map_err(|e| fmt(e.to_string()))?;
    crate::limits::check_cap(&what, raw.checked_add(w as u64 * h as u64 * 4)).map_err(|e| fmt(e.to_string()))?;
    let img = reader()?.decode().map_err(|e| fmt(format!("cannot decode the image: {e}")))?.into_rgba8();
    let (w, h) = img.dimensions();
    let texels: Vec<[u8; 4]> = img.into_raw().chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
    Image::new(w, h, color_space, texels).map_err(|e| fmt(e.to_string()))
}

/// Classifies a failed output operation: a path that cannot hold a file
/// (through a file, a missing device, a refused name) is the user's
/// [`IoError::Destination`]; everything else (disk full, read-only file
/// system, I/O error) an [`IoError::Write`].
pub fn output_error(path: &Path, e: &std::io::Error) -> IoError {
    use std::io::ErrorKind as K;
    let message = e.to_string();
    match e.kind() {
        K::NotFound | K::NotADirectory | K::IsADirectory | K::InvalidFilename | K::InvalidInput => {
            IoError::Destination { path: path.to_path_buf(), message }
        }
        _ => IoError::Write { path: path.to_path_buf(), message },
    }
}

/// Creates `dir` and its missing parents (every output of hitex does this,
/// files and folders alike); a path that cannot be a folder is the user's
/// [`IoError::Destination`].
pub fn create_output_dir(dir: &Path) -> Result<(), IoError> {
    if dir.as_os_str().is_empty() || dir.is_dir() {
        return Ok(());
    }
    if let Some(file) = dir.ancestors().find(|a| a.exists() && !a.is_dir()) {
        return Err(IoError::Destination {
            path: dir.to_path_buf(),
            message: format!("{} is a file, not a folder", file.display()),
        });
    }
    std::fs::create_dir_all(dir).map_err(|e| output_error(dir, &e))
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a
/// rename, so that an interrupted or failed write leaves no partial file.
/// Missing folders on the way are created.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    let werr = |m: String| IoError::Destination { path: path.to_path_buf(), message: m };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let name = path.file_name().ok_or_else(|| werr("not a file path".into()))?;
    create_output_dir(&dir)?;
    let tmp = dir.join(format!(".{}.tmp{}", name.to_string_lossy(), std::process::id()));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(output_error(path, &e));
    }
    Ok(())
}

/// Encodes RGBA8 pixels (`width`×`height`, rows top to bottom) as PNG and
/// writes them atomically.
pub fn save_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<(), IoError> {
    let werr = |m: String| IoError::Write { path: path.to_path_buf(), message: m };
    if rgba.len() != width as usize * height as usize * 4 {
        return Err(werr(format!("{} bytes for a {width}x{height} RGBA image", rgba.len())));
    }
    let mut buf = Vec::new();
    {
        use image::ImageEncoder;
        image::codecs::png::PngEncoder::new(&mut buf)
            .write_image(rgba, width, height, image::ExtendedColorType::Rgba8)
            .map_err(|e| werr(e.to_string()))?;
    }
    write_atomic(path, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmpdir(name: &str) -> crate::test_dir::TestDir {
        crate::test_dir::TestDir::fresh(&format!("io-{name}"))
    }

    #[test]
    fn png_round_trip() {
        let d = tmpdir("png");
        let p = d.join("a.png");
        let px: Vec<u8> = (0..2 * 3 * 4).map(|i| (i * 10) as u8).collect();
        save_png(&p, 2, 3, &px).unwrap();
        let img = load_image(&p, ColorSpace::Srgb).unwrap();
        assert_eq!((img.width(), img.height()), (2, 3));
        assert_eq!(img.bytes(), &px[..]);
        // no temporary file is left behind
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    }

    #[test]
    fn broken_images_name_the_file() {
        let d = tmpdir("broken");
        let missing = d.join("missing.png");
        let e = load_image(&missing, ColorSpace::Srgb).unwrap_err().to_string();
        assert!(e.contains("missing.png"), "{e}");

        let garbage = d.join("garbage.png");
        std::fs::write(&garbage, b"this is not an image at all").unwrap();
        let e = load_image(&garbage, ColorSpace::Srgb).unwrap_err().to_string();
        assert!(e.contains("garbage.png") && e.contains("signature"), "{e}");

        // a real PNG cut in half
        let good = d.join("good.png");
        save_png(&good, 64, 64, &vec![200; 64 * 64 * 4]).unwrap();
        let bytes = std::fs::read(&good).unwrap();
        let cut = d.join("cut.png");
        std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
        let e = load_image(&cut, ColorSpace::Srgb).unwrap_err().to_string();
        assert!(e.contains("cut.png"), "{e}");

        // a PNG header claiming 100000 x 100000 pixels is refused before decoding
        let mut huge = bytes[..33].to_vec();
        huge[16..20].copy_from_slice(&100_000u32.to_be_bytes());
        huge[20..24].copy_from_slice(&100_000u32.to_be_bytes());
        let hp = d.join("huge.png");
        std::fs::write(&hp, &huge).unwrap();
        let e = load_image(&hp, ColorSpace::Srgb).unwrap_err().to_string();
        assert!(e.contains("huge.png"), "{e}");
    }

    #[test]
    fn missing_folders_are_created_and_a_file_on_the_path_is_the_users_error() {
        let d = tmpdir("nowrite");
        let p = d.join("no/such/dir/x.png");
        save_png(&p, 1, 1, &[0, 0, 0, 255]).unwrap();
        assert!(p.is_file());
        let e = save_png(&p.join("y.png"), 1, 1, &[0, 0, 0, 255]).unwrap_err();
        assert!(matches!(e, IoError::Destination { .. }), "{e}");
        assert!(e.to_string().contains("x.png is a file"), "{e}");
    }
}
