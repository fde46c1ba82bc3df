//! The native BTF file, `.hbtf`: a versioned little-endian binary with a
//! checked header and a CRC-32 over the texels.
//!
//! | offset      | size      | field                                             |
//! |-------------|-----------|---------------------------------------------------|
//! | 0           | 4         | magic `b"HBTF"`                                   |
//! | 4           | 4         | `u32` version, 1 or 2                             |
//! | 8           | 4         | `u32` header bytes = 44 + 4·θ count (+ 16 with HDR) |
//! | 12          | 4         | `u32` sample width in texels                      |
//! | 16          | 4         | `u32` sample height in texels                     |
//! | 20          | 4         | `u32` θ count                                     |
//! | 24          | 4         | `u32` φ count                                     |
//! | 28          | 4         | `u32` flags: bit 0 = HDR payload (version 2 only) |
//! | 32          | 4·θ count | `f32` polar angles in degrees                     |
//! | 32 + 4·θ    | 8         | `u64` payload length in bytes                     |
//! | 40 + 4·θ    | 4         | `u32` CRC-32 (IEEE, as zip and PNG) of the payload |
//! | 44 + 4·θ    | 8         | HDR only: `u64` HDR payload length in bytes       |
//! | 52 + 4·θ    | 4         | HDR only: `u32` CRC-32 of the HDR payload         |
//! | 56 + 4·θ    | 4         | HDR only: `f32` display scale ([`Hdr::ldr_scale`]) |
//! | header      | payload   | RGB8 texels exactly as [`Btf::texels`]            |
//! | + payload   | HDR payload | HDR only: linear RGB half floats ([`Hdr::half`]), `u16` little-endian |
//!
//! An 8-bit BTF is written as version 1 (readable by every earlier build); a
//! BTF with linear half-float RGB (imported from OpenEXR) as version 2 with
//! flag bit 0. Half floats must be finite and non-negative.
//!
//! Every declared size is checked against the shape limits of
//! [`checked_size`] and against the bytes actually present before anything
//! is allocated, so a header claiming gigabytes in a small file is refused at
//! once. Nothing may follow the payload.

use crate::IoError;
use hitex_core::btf::dataset::Hdr;
use hitex_core::btf::dataset::checked_size;
use hitex_core::btf::grid::MAX_ANGLES;
use hitex_core::btf::{AngularGrid, Btf};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// The file signature.
pub const HBTF_MAGIC: [u8; 4] = *b"HBTF";

/// The newest version this module writes and reads (version 1, 8-bit
/// only, is read and written too).
pub const HBTF_VERSION: u32 = 2;

/// Flag bit: the file carries an HDR payload.
pub const FLAG_HDR: u32 = 1;

/// Bytes of the fixed part of the header (magic to flags).
const FIXED_HEADER: usize = 32;

/// Bytes after the θ list: payload length and CRC.
const HEADER_TAIL: usize = 12;

/// Bytes of the HDR fields after the tail: length, CRC, display scale.
const HDR_TAIL: usize = 16;

/// Chunk in which the payload is written, read and checksummed.
const CHUNK: usize = 1 << 20;

/// The header of an `.hbtf` file.
#[derive(Debug, Clone, PartialEq)]
pub struct HbtfHeader {
    /// Format version (1 or 2).
    pub version: u32,
    /// Header length in bytes, the offset of the payload.
    pub header_bytes: u32,
    /// Sample width in texels.
    pub width: u32,
    /// Sample height in texels.
    pub height: u32,
    /// The angular grid.
    pub grid: AngularGrid,
    /// Flags (0 in version 1; [`FLAG_HDR`] in version 2).
    pub flags: u32,
    /// Payload length in bytes (RGB8 texels).
    pub payload_bytes: u64,
    /// CRC-32 of the payload as recorded in the header.
    pub crc32: u32,
    /// The HDR payload's length in bytes, CRC-32 and display scale, when
    /// the file has one.
    pub hdr: Option<HdrFields>,
}

/// The header fields of an HDR payload.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HdrFields {
    /// Length in bytes (2 per half float, 3 half floats per texel).
    pub bytes: u64,
    /// CRC-32 of the payload's bytes.
    pub crc32: u32,
    /// [`Hdr::ldr_scale`].
    pub ldr_scale: f32,
}

impl HbtfHeader {
    /// Number of images (directions²).
    pub fn images(&self) -> usize {
        self.grid.directions() * self.grid.directions()
    }
}

/// Header bytes for `theta_count` polar angles.
fn header_len(theta_count: usize, hdr: bool) -> usize {
    FIXED_HEADER + 4 * theta_count + HEADER_TAIL + if hdr { HDR_TAIL } else { 0 }
}

/// The half floats as little-endian bytes.
fn half_bytes(half: &[u16]) -> impl Iterator<Item = Vec<u8>> + '_ {
    half.chunks(CHUNK / 2).map(|c| c.iter().flat_map(|h| h.to_le_bytes()).collect())
}

/// The serialised header of `btf` with the payloads' CRCs.
fn encode_header(btf: &Btf, crc: u32, hdr_crc: u32) -> Vec<u8> {
    let grid = btf.grid();
    let n = grid.theta_count();
    let hdr = btf.hdr();
    let (version, flags) = if hdr.is_some() { (2, FLAG_HDR) } else { (1, 0) };
    let len = header_len(n, hdr.is_some());
    let mut h = Vec::with_capacity(len);
    h.extend_from_slice(&HBTF_MAGIC);
    for v in [version, len as u32, btf.width(), btf.height(), n as u32, grid.phi_count() as u32, flags] {
        h.extend_from_slice(&v.to_le_bytes());
    }
    for &t in grid.theta_deg() {
        h.extend_from_slice(&t.to_le_bytes());
    }
    h.extend_from_slice(&(btf.texels().len() as u64).to_le_bytes());
    h.extend_from_slice(&crc.to_le_bytes());
    if let Some(hdr) = hdr {
        h.extend_from_slice(&(hdr.half.len() as u64 * 2).to_le_bytes());
        h.extend_from_slice(&hdr_crc.to_le_bytes());
        h.extend_from_slice(&hdr.ldr_scale.to_le_bytes());
    }
    h
}

/// Writes `btf` as an `.hbtf` file (version 1, or 2 with its HDR payload),
/// atomically: the data goes to a temporary file in the same folder, is
/// synced, and is renamed over `path`; on any failure the temporary file is
/// removed and `path` is untouched. The payload is written in 1 MiB chunks
/// straight from the BTF.
pub fn write_hbtf(path: &Path, btf: &Btf) -> Result<(), IoError> {
    let crc = crc32(btf.texels());
    let hdr_crc = btf.hdr().map_or(0, |h| {
        let mut c = Crc32::new();
        half_bytes(&h.half).for_each(|b| c.update(&b));
        c.finish()
    });
    let header = encode_header(btf, crc, hdr_crc);
    write_atomic_with(path, |w| {
        w.write_all(&header)?;
        for chunk in btf.texels().chunks(CHUNK) {
            w.write_all(chunk)?;
        }
        if let Some(h) = btf.hdr() {
            for b in half_bytes(&h.half) {
                w.write_all(&b)?;
            }
        }
        Ok(())
    })
}

/// Streams `write` into a temporary file next to `path` and renames it over
/// `path`; the temporary file never outlives a failure.
pub(crate) fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<&std::fs::File>) -> std::io::Result<()>,
) -> Result<(), IoError> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let werr = |m: String| IoError::Destination { path: path.to_path_buf(), message: m };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().ok_or_else(|| werr("not a file path".into()))?;
    crate::image_io::create_output_dir(&dir)?;
    let tmp = dir.join(format!(
        ".{}.{}-{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(|e| crate::image_io::output_error(path, &e))?;
    let result = (|| -> std::io::Result<()> {
        let mut w = std::io::BufWriter::with_capacity(CHUNK, &file);
        write(&mut w)?;
        w.flush()?;
        drop(w);
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    drop(file);
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(crate::image_io::output_error(path, &e));
    }
    Ok(())
}

/// Reads an `.hbtf` file, checking its header, sizes and CRC. A BTF
/// compressed by local PCA ([`crate::btf_pca_file`]) is read too, as its
/// reconstruction ([`crate::btf_pca_file::decompressed`]).
pub fn read_hbtf(path: &Path) -> Result<Btf, IoError> {
    let rerr = |source: std::io::Error| IoError::Read { path: path.to_path_buf(), source };
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let file = std::fs::File::open(path).map_err(rerr)?;
    let len = file.metadata().map_err(rerr)?.len();
    let mut r = std::io::BufReader::new(file);
    if crate::btf_pca_file::is_pca_file(std::io::BufRead::fill_buf(&mut r).map_err(rerr)?) {
        let p = crate::btf_pca_file::read_pca_file(path)?;
        return crate::btf_pca_file::decompressed(&p, path);
    }
    let header = read_header(&mut r, len, path)?;
    // the header checks bound the payloads by both the shape limit and the file length
    let mut read_payload = |n: u64, what: &str, recorded: u32| -> Result<Vec<u8>, IoError> {
        let mut bytes = vec![0u8; n as usize];
        let mut done = 0usize;
        let mut crc = Crc32::new();
        while done < bytes.len() {
            let end = (done + CHUNK).min(bytes.len());
            r.read_exact(&mut bytes[done..end]).map_err(|e| {
                if e.kind() == std::io::ErrorKind::UnexpectedEof {
                    fmt(format!("the file ends inside the {what} (byte {} of {})", done, bytes.len()))
                } else {
                    rerr(e)
                }
            })?;
            crc.update(&bytes[done..end]);
            done = end;
        }
        check_crc(crc.finish(), recorded).map_err(|m| fmt(format!("{what}: {m}")))?;
        Ok(bytes)
    };
    let texels = read_payload(header.payload_bytes, "payload", header.crc32)?;
    let half = match header.hdr {
        Some(h) => Some(read_payload(h.bytes, "HDR payload", h.crc32)?),
        None => None,
    };
    let mut probe = [0u8; 1];
    if r.read(&mut probe).map_err(rerr)? != 0 {
        return Err(fmt("data follows the payload (the file grew after it was written)".into()));
    }
    assemble(header, texels, half.as_deref(), path)
}

/// The BTF of a checked header and its payloads; half floats must be
/// finite and non-negative.
fn assemble(header: HbtfHeader, texels: Vec<u8>, half: Option<&[u8]>, path: &Path) -> Result<Btf, IoError> {
    let hdr = match (header.hdr, half) {
        (Some(f), Some(bytes)) => {
            let half: Vec<u16> = bytes.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect();
            if let Some(i) = half.iter().position(|&h| h & 0x8000 != 0 || h & 0x7c00 == 0x7c00) {
                return Err(IoError::Format {
                    path: path.to_path_buf(),
                    message: format!(
                        "HDR payload value {i} (texel {}, channel {}) is {:#06x}: negative, infinite or NaN; \
                         HDR texels are finite and non-negative",
                        i / 3,
                        i % 3,
                        half[i]
                    ),
                });
            }
            if !(f.ldr_scale.is_finite() && f.ldr_scale > 0.0 && f.ldr_scale <= 1.0) {
                return Err(IoError::Format {
                    path: path.to_path_buf(),
                    message: format!("HDR display scale {} is outside (0, 1]", f.ldr_scale),
                });
            }
            Some(Hdr { half, ldr_scale: f.ldr_scale })
        }
        _ => None,
    };
    Btf::from_parts(header.grid, header.width, header.height, texels, hdr).map_err(|e| IoError::from(e).in_file(path))
}

/// Reads and checks only the header of an `.hbtf` file (for `hitex btf
/// info`): magic, version, sizes and that the file holds exactly the declared
/// payload. The CRC is reported but not verified; [`read_hbtf`] verifies it.
pub fn read_hbtf_header(path: &Path) -> Result<HbtfHeader, IoError> {
    let rerr = |source: std::io::Error| IoError::Read { path: path.to_path_buf(), source };
    let file = std::fs::File::open(path).map_err(rerr)?;
    let len = file.metadata().map_err(rerr)?.len();
    let header = read_header(&mut std::io::BufReader::new(file), len, path)?;
    check_trailing(len, &header).map_err(|m| IoError::Format { path: path.to_path_buf(), message: m })?;
    Ok(header)
}

/// Parses a whole `.hbtf` file held in memory (either kind, as
/// [`read_hbtf`]); `name` is the file named in errors. All checks of
/// [`read_hbtf`] apply.
pub fn hbtf_from_bytes(bytes: &[u8], name: &str) -> Result<Btf, IoError> {
    let path = Path::new(name);
    if crate::btf_pca_file::is_pca_file(bytes) {
        let p = crate::btf_pca_file::pca_from_bytes(bytes, name)?;
        return crate::btf_pca_file::decompressed(&p, path);
    }
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let mut r = bytes;
    let header = read_header(&mut r, bytes.len() as u64, path)?;
    check_trailing(bytes.len() as u64, &header).map_err(fmt)?;
    let start = header.header_bytes as usize;
    let payload = &bytes[start..start + header.payload_bytes as usize];
    check_crc(crc32(payload), header.crc32).map_err(|m| fmt(format!("payload: {m}")))?;
    let half = match header.hdr {
        Some(h) => {
            let half = &bytes[start + payload.len()..];
            check_crc(crc32(half), h.crc32).map_err(|m| fmt(format!("HDR payload: {m}")))?;
            Some(half)
        }
        None => None,
    };
    let texels = payload.to_vec();
    assemble(header, texels, half, path)
}

fn check_crc(actual: u32, recorded: u32) -> Result<(), String> {
    if actual != recorded {
        return Err(format!(
            "payload CRC-32 is {actual:#010x} but the header records {recorded:#010x} (the texels are corrupt)"
        ));
    }
    Ok(())
}

fn check_trailing(file_len: u64, h: &HbtfHeader) -> Result<(), String> {
    let payloads = h.payload_bytes + h.hdr.map_or(0, |f| f.bytes);
    let end = h.header_bytes as u64 + payloads;
    if file_len > end {
        return Err(format!("{} bytes follow the {payloads}-byte payload", file_len - end));
    }
    Ok(())
}

/// Reads the header from `r`, which is at the start of a file of `file_len`
/// bytes, and checks it: magic, version, flags, header length, grid, shape
/// limits, and that the declared payload equals the shape's size and fits in
/// the rest of the file.
fn read_header(r: &mut impl Read, file_len: u64, path: &Path) -> Result<HbtfHeader, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let mut read = |buf: &mut [u8], what: &str, at: usize| -> Result<(), IoError> {
        r.read_exact(buf).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                fmt(format!("the file ends inside the header: {what} at byte {at} (file of {file_len} bytes)"))
            } else {
                IoError::Read { path: path.to_path_buf(), source: e }
            }
        })
    };
    let mut fixed = [0u8; FIXED_HEADER];
    read(&mut fixed[..4], "magic", 0)?;
    if fixed[..4] != HBTF_MAGIC {
        let what = match crate::binary_kind(&fixed[..4]) {
            Some(kind) => kind.to_string(),
            None => format!("magic {}", fixed[..4].escape_ascii()),
        };
        return Err(fmt(format!("not an .hbtf file ({what}; an .hbtf starts with \"HBTF\")")));
    }
    read(&mut fixed[4..], "fixed header fields", 4)?;
    let field = |i: usize| u32::from_le_bytes([fixed[i], fixed[i + 1], fixed[i + 2], fixed[i + 3]]);
    let (version, header_bytes, width, height) = (field(4), field(8), field(12), field(16));
    let (theta_count, phi_count, flags) = (field(20), field(24), field(28));
    if !(1..=HBTF_VERSION).contains(&version) {
        return Err(fmt(format!(
            "format version {version} is not supported (this build reads versions 1 to {HBTF_VERSION})"
        )));
    }
    if version == 1 && flags != 0 {
        return Err(fmt(format!("header flags {flags:#x} are unknown (version 1 has none)")));
    }
    if flags & !FLAG_HDR != 0 {
        return Err(fmt(format!("header flags {flags:#x} are unknown (version 2 knows only bit 0, HDR)")));
    }
    let has_hdr = flags & FLAG_HDR != 0;
    if theta_count == 0 || theta_count as usize > MAX_ANGLES {
        return Err(fmt(format!("header declares {theta_count} polar angles; 1..={MAX_ANGLES} are allowed")));
    }
    if phi_count == 0 || phi_count as usize > MAX_ANGLES {
        return Err(fmt(format!("header declares {phi_count} azimuths; 1..={MAX_ANGLES} are allowed")));
    }
    let theta_count = theta_count as usize;
    let want = header_len(theta_count, has_hdr);
    if header_bytes as usize != want {
        return Err(fmt(format!(
            "header length field is {header_bytes} bytes; {theta_count} polar angles make a {want}-byte header"
        )));
    }
    if file_len < want as u64 {
        return Err(fmt(format!("the file of {file_len} bytes is shorter than its {want}-byte header")));
    }
    let mut list = vec![0u8; 4 * theta_count];
    read(&mut list, "polar angle list", FIXED_HEADER)?;
    let theta: Vec<f32> = list.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    let grid = AngularGrid::new(theta, phi_count as usize).map_err(|e| fmt(format!("header grid: {e}")))?;
    let size = checked_size(&grid, width, height).map_err(|e| fmt(format!("header shape: {e}")))?;
    let mut tail = [0u8; HEADER_TAIL];
    let tail_at = FIXED_HEADER + 4 * theta_count;
    read(&mut tail, "payload length and CRC", tail_at)?;
    let payload_bytes = u64::from_le_bytes([tail[0], tail[1], tail[2], tail[3], tail[4], tail[5], tail[6], tail[7]]);
    let crc = u32::from_le_bytes([tail[8], tail[9], tail[10], tail[11]]);
    if payload_bytes != size as u64 {
        return Err(fmt(format!(
            "header declares a payload of {payload_bytes} bytes; {width}x{height} texels × {}² directions need {size}",
            grid.directions()
        )));
    }
    let hdr = if has_hdr {
        let mut t = [0u8; HDR_TAIL];
        read(&mut t, "HDR payload length, CRC and display scale", tail_at + HEADER_TAIL)?;
        let bytes = u64::from_le_bytes([t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7]]);
        let f = HdrFields {
            bytes,
            crc32: u32::from_le_bytes([t[8], t[9], t[10], t[11]]),
            ldr_scale: f32::from_le_bytes([t[12], t[13], t[14], t[15]]),
        };
        if bytes != 2 * size as u64 {
            return Err(fmt(format!(
                "header declares an HDR payload of {bytes} bytes; {width}x{height} texels × {}² directions of \
                 half-float RGB need {}",
                grid.directions(),
                2 * size as u64
            )));
        }
        Some(f)
    } else {
        None
    };
    let total = payload_bytes + hdr.map_or(0, |f| f.bytes);
    let remaining = file_len - want as u64;
    if total > remaining {
        return Err(fmt(format!(
            "header declares payloads of {total} bytes but only {remaining} follow the header (truncated file)"
        )));
    }
    // an HDR payload is held twice while it is decoded into half floats
    let held = payload_bytes + 2 * hdr.map_or(0, |f| f.bytes);
    crate::limits::check_cap("the payload", Some(held)).map_err(|e| fmt(e.to_string()))?;
    Ok(HbtfHeader { version, header_bytes, width, height, grid, flags, payload_bytes, crc32: crc, hdr })
}

/// CRC-32/IEEE (reflected polynomial 0xEDB88320, as zip, PNG and gzip),
/// slicing by 8 bytes.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = Crc32::new();
    c.update(bytes);
    c.finish()
}

/// An incremental CRC-32/IEEE.
#[derive(Debug, Clone, Copy)]
pub struct Crc32(u32);

const CRC_TABLES: [[u32; 256]; 8] = {
    let mut t = [[0u32; 256]; 8];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        t[0][i] = c;
        i += 1;
    }
    let mut s = 1;
    while s < 8 {
        let mut i = 0;
        while i < 256 {
            let prev = t[s - 1][i];
            t[s][i] = (prev >> 8) ^ t[0][(prev & 0xff) as usize];
            i += 1;
        }
        s += 1;
    }
    t
};

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// A CRC of no bytes.
    pub fn new() -> Self {
        Self(!0)
    }

    /// Adds bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        let t = &CRC_TABLES;
        let mut c = self.0;
        let mut chunks = bytes.chunks_exact(8);
        for b in &mut chunks {
            let lo = c ^ u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            c = t[7][(lo & 0xff) as usize]
                ^ t[6][((lo >> 8) & 0xff) as usize]
                ^ t[5][((lo >> 16) & 0xff) as usize]
                ^ t[4][(lo >> 24) as usize]
                ^ t[3][b[4] as usize]
                ^ t[2][b[5] as usize]
                ^ t[1][b[6] as usize]
                ^ t[0][b[7] as usize];
        }
        for &b in chunks.remainder() {
            c = (c >> 8) ^ t[0][((c ^ b as u32) & 0xff) as usize];
        }
        self.0 = c;
    }

    /// The CRC of the bytes added so far.
    pub fn finish(&self) -> u32 {
        !self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn tmpdir(name: &str) -> crate::test_dir::TestDir {
        crate::test_dir::TestDir::fresh(&format!("io-btf-file-{name}"))
    }

    fn small_btf(seed: u32) -> Btf {
        let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 4).unwrap();
        let n = checked_size(&grid, 3, 2).unwrap();
        let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(1);
        let texels = (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                (s >> 24) as u8
            })
            .collect();
        Btf::new(grid, 3, 2, texels).unwrap()
    }

    fn bytes_of(btf: &Btf) -> Vec<u8> {
        let hdr_crc = btf.hdr().map_or(0, |h| crc32(&half_bytes(&h.half).collect::<Vec<_>>().concat()));
        let mut b = encode_header(btf, crc32(btf.texels()), hdr_crc);
        b.extend_from_slice(btf.texels());
        if let Some(h) = btf.hdr() {
            half_bytes(&h.half).for_each(|c| b.extend_from_slice(&c));
        }
        b
    }

    #[test]
    fn crc32_matches_the_standard_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 + 3) as u8).collect();
        let mut c = Crc32::new();
        for part in data.chunks(13) {
            c.update(part);
        }
        assert_eq!(c.finish(), crc32(&data));
    }

    #[test]
    fn btf_file_round_trip() {
        let d = tmpdir("round");
        let p = d.join("a.hbtf");
        let btf = small_btf(1);
        write_hbtf(&p, &btf).unwrap();
        assert_eq!(read_hbtf(&p).unwrap(), btf);
        let h = read_hbtf_header(&p).unwrap();
        assert_eq!((h.version, h.width, h.height, h.grid.clone()), (1, 3, 2, btf.grid().clone()));
        assert_eq!(h.payload_bytes, btf.texels().len() as u64);
        assert_eq!(h.header_bytes as u64 + h.payload_bytes, std::fs::metadata(&p).unwrap().len());
        assert_eq!(h.images(), 144);
        assert_eq!(hbtf_from_bytes(&std::fs::read(&p).unwrap(), "mem").unwrap(), btf);
        // overwriting works and leaves only the file
        write_hbtf(&p, &small_btf(2)).unwrap();
        assert_eq!(read_hbtf(&p).unwrap(), small_btf(2));
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    }

    #[test]
    fn btf_file_truncated_at_every_7th_byte_is_an_error() {
        let d = tmpdir("trunc");
        let bytes = bytes_of(&small_btf(3));
        for k in (0..bytes.len()).step_by(7) {
            let e = hbtf_from_bytes(&bytes[..k], "cut.hbtf").unwrap_err().to_string();
            assert!(e.contains("cut.hbtf"), "{k}: {e}");
        }
        for k in [0, 5, 31, 40, 56, 57, 100, bytes.len() - 1] {
            let p = d.join(format!("cut{k}.hbtf"));
            std::fs::write(&p, &bytes[..k]).unwrap();
            let e = read_hbtf(&p).unwrap_err().to_string();
            assert!(e.contains(&format!("cut{k}.hbtf")), "{e}");
            assert!(read_hbtf_header(&p).is_err());
        }
        // trailing bytes are refused too
        let mut long = bytes.clone();
        long.push(0);
        assert!(hbtf_from_bytes(&long, "long").unwrap_err().to_string().contains("follow"));
        let p = d.join("long.hbtf");
        std::fs::write(&p, &long).unwrap();
        assert!(read_hbtf(&p).is_err() && read_hbtf_header(&p).is_err());
    }

    fn set_u32(b: &mut [u8], at: usize, v: u32) {
        b[at..at + 4].copy_from_slice(&v.to_le_bytes());
    }

    #[test]
    fn btf_file_absurd_headers_are_refused() {
        let good = bytes_of(&small_btf(4));
        let check = |b: Vec<u8>, needle: &str| {
            let e = hbtf_from_bytes(&b, "bad.hbtf").unwrap_err().to_string();
            assert!(e.contains("bad.hbtf") && e.contains(needle), "{needle}: {e}");
        };
        let mut b = good.clone();
        set_u32(&mut b, 12, 1_000_000);
        check(b, "side");
        let mut b = good.clone();
        set_u32(&mut b, 20, 1_000_000_000);
        check(b, "polar angles");
        let mut b = good.clone();
        set_u32(&mut b, 24, 0);
        check(b, "azimuths");
        let mut b = good.clone();
        set_u32(&mut b, 8, 9999);
        check(b, "header length");
        let mut b = good.clone();
        set_u32(&mut b, 28, 1);
        check(b, "flags");
        let mut b = good.clone();
        b[36..40].copy_from_slice(&95f32.to_le_bytes());
        check(b, "grid");
        let mut b = good.clone();
        b[44..52].copy_from_slice(&(2u64 << 30).to_le_bytes());
        check(b, "payload");

        // the paper's 48 MiB shape claimed in a 1 KiB file: refused from the header alone
        let grid = AngularGrid::paper();
        let size = checked_size(&grid, 32, 32).unwrap();
        let mut h = Vec::new();
        h.extend_from_slice(b"HBTF");
        for v in [1u32, header_len(8, false) as u32, 32, 32, 8, 16, 0] {
            h.extend_from_slice(&v.to_le_bytes());
        }
        for t in grid.theta_deg() {
            h.extend_from_slice(&t.to_le_bytes());
        }
        h.extend_from_slice(&(size as u64).to_le_bytes());
        h.extend_from_slice(&0u32.to_le_bytes());
        h.resize(1024, 0);
        let t = std::time::Instant::now();
        check(h, "truncated");
        assert!(t.elapsed().as_secs_f32() < 1.0);
    }

    #[test]
    fn btf_file_bad_magic_version_and_crc() {
        let good = bytes_of(&small_btf(5));
        let mut b = good.clone();
        b[0] = b'X';
        assert!(hbtf_from_bytes(&b, "m").unwrap_err().to_string().contains("magic"));
        let mut b = good.clone();
        set_u32(&mut b, 4, 3);
        assert!(hbtf_from_bytes(&b, "v").unwrap_err().to_string().contains("version 3"));
        // a flipped payload bit
        let mut b = good.clone();
        let last = b.len() - 1;
        b[last] ^= 0x10;
        assert!(hbtf_from_bytes(&b, "c").unwrap_err().to_string().contains("CRC"));
        // a flipped CRC bit, through the file reader
        let mut b = good.clone();
        b[52] ^= 1;
        let d = tmpdir("crc");
        let p = d.join("crc.hbtf");
        std::fs::write(&p, &b).unwrap();
        let e = read_hbtf(&p).unwrap_err().to_string();
        assert!(e.contains("crc.hbtf") && e.contains("CRC"), "{e}");
        // the header alone still reads
        assert!(read_hbtf_header(&p).is_ok());
    }

    fn hdr_btf(seed: u32) -> Btf {
        let grid = AngularGrid::new(vec![0.0, 30.0, 60.0], 4).unwrap();
        let n = checked_size(&grid, 3, 2).unwrap();
        let linear: Vec<f32> =
            (0..n).map(|i| (((i as u32).wrapping_mul(2_654_435_761) ^ seed) % 5000) as f32 / 700.0).collect();
        Btf::from_linear(grid, 3, 2, &linear).unwrap()
    }

    #[test]
    fn btf_file_version_2_carries_the_hdr_payload() {
        let d = tmpdir("v2");
        let p = d.join("h.hbtf");
        let btf = hdr_btf(3);
        write_hbtf(&p, &btf).unwrap();
        let h = read_hbtf_header(&p).unwrap();
        assert_eq!((h.version, h.flags), (2, FLAG_HDR));
        let f = h.hdr.unwrap();
        assert_eq!(f.bytes, 2 * h.payload_bytes);
        assert_eq!(f.ldr_scale, btf.hdr().unwrap().ldr_scale);
        assert_eq!(h.header_bytes as u64 + 3 * h.payload_bytes, std::fs::metadata(&p).unwrap().len());
        assert_eq!(read_hbtf(&p).unwrap(), btf);
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(hbtf_from_bytes(&bytes, "mem").unwrap(), btf);
        // an 8-bit BTF is still written as version 1
        write_hbtf(&p, &small_btf(1)).unwrap();
        assert_eq!(read_hbtf_header(&p).unwrap().version, 1);
        // broken HDR files: every cut, a flipped HDR bit, a NaN half, a bad scale, a wrong length
        for k in (0..bytes.len()).step_by(5) {
            let e = hbtf_from_bytes(&bytes[..k], "cut.hbtf").unwrap_err().to_string();
            assert!(e.contains("cut.hbtf"), "{k}: {e}");
        }
        let mut b = bytes.clone();
        let last = b.len() - 2;
        b[last] ^= 1;
        assert!(hbtf_from_bytes(&b, "c").unwrap_err().to_string().contains("HDR payload: payload CRC"));
        let at = h.header_bytes as usize + h.payload_bytes as usize;
        let mut b = bytes.clone();
        b[at..at + 2].copy_from_slice(&0x7e00u16.to_le_bytes());
        let crc = crc32(&b[at..]);
        // the HDR fields close the header: length, CRC, display scale
        let crc_at = h.header_bytes as usize - 8;
        b[crc_at..crc_at + 4].copy_from_slice(&crc.to_le_bytes());
        let e = hbtf_from_bytes(&b, "nan.hbtf").unwrap_err().to_string();
        assert!(e.contains("nan.hbtf") && e.contains("NaN") && e.contains("texel 0"), "{e}");
        let mut b = bytes.clone();
        b[crc_at + 4..crc_at + 8].copy_from_slice(&2.5f32.to_le_bytes());
        assert!(hbtf_from_bytes(&b, "s").unwrap_err().to_string().contains("display scale"));
        let mut b = bytes.clone();
        b[crc_at - 8..crc_at].copy_from_slice(&7u64.to_le_bytes());
        assert!(hbtf_from_bytes(&b, "l").unwrap_err().to_string().contains("HDR payload of 7 bytes"));
        let mut b = bytes.clone();
        set_u32(&mut b, 28, 3);
        assert!(hbtf_from_bytes(&b, "f").unwrap_err().to_string().contains("flags"));
    }

    #[test]
    fn btf_file_failed_writes_leave_nothing_behind() {
        let d = tmpdir("nowrite");
        let btf = small_btf(6);
        // a file where a folder must be
        std::fs::write(d.join("plain"), b"x").unwrap();
        let e = write_hbtf(&d.join("plain/dir/x.hbtf"), &btf).unwrap_err();
        assert!(matches!(e, IoError::Destination { .. }), "{e}");
        assert!(e.to_string().contains("plain"), "{e}");
        std::fs::remove_file(d.join("plain")).unwrap();
        // missing folders are created
        write_hbtf(&d.join("new/dir/x.hbtf"), &btf).unwrap();
        std::fs::remove_dir_all(d.join("new")).unwrap();
        // the target is a folder: the rename fails after the data was written
        std::fs::create_dir(d.join("taken.hbtf")).unwrap();
        let e = write_hbtf(&d.join("taken.hbtf"), &btf).unwrap_err().to_string();
        assert!(e.contains("taken.hbtf"), "{e}");
        let names: Vec<_> = std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("taken.hbtf")], "temporary file left behind");
        // a read-only folder (root may write there anyway: then only check no temp file remains)
        let ro = d.join("ro");
        std::fs::create_dir(&ro).unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        }
        let r = write_hbtf(&ro.join("y.hbtf"), &btf);
        let left: Vec<_> = std::fs::read_dir(&ro).unwrap().map(|e| e.unwrap().file_name()).collect();
        match r {
            Err(e) => {
                assert!(e.to_string().contains("y.hbtf"), "{e}");
                assert!(left.is_empty(), "{left:?}");
            }
            Ok(()) => assert_eq!(left, vec![std::ffi::OsString::from("y.hbtf")]),
        }
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

        #[test]
        fn btf_file_arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let _ = hbtf_from_bytes(&bytes, "fuzz");
        }

        #[test]
        fn btf_file_mutated_files_never_panic(at in 0usize..2700, value in any::<u8>(), cut in 0usize..2700) {
            let mut b = bytes_of(&small_btf(7));
            let at = at % b.len();
            b[at] = value;
            b.truncate(cut.max(at + 1));
            if let Ok(btf) = hbtf_from_bytes(&b, "fuzz") {
                // only unchanged texels decode (the CRC covers the payload, not the angles)
                let original = small_btf(7);
                prop_assert_eq!(btf.texels(), original.texels());
            }
        }
    }
}
