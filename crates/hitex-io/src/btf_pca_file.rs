//! A BTF compressed by local PCA ([`hitex_core::btf::pca`]) as a file, so
//! that the fit is made once and the compressed form is what is shipped and
//! rendered. Written by `hitex btf compress`; every command that reads an
//! `.hbtf` also reads it (the renderer straight from the basis, the others
//! from its reconstruction).
//!
//! A little-endian binary with a checked header and a CRC-32 over the
//! payload (the same CRC as [`crate::btf_file`]):
//!
//! | offset      | size      | field                                             |
//! |-------------|-----------|---------------------------------------------------|
//! | 0           | 4         | magic `b"HPCA"`                                   |
//! | 4           | 4         | `u32` version, 1                                  |
//! | 8           | 4         | `u32` header bytes = 56 + 4·θ count               |
//! | 12          | 4         | `u32` sample width in texels                      |
//! | 16          | 4         | `u32` sample height in texels                     |
//! | 20          | 4         | `u32` θ count                                     |
//! | 24          | 4         | `u32` φ count                                     |
//! | 28          | 4         | `u32` flags: bit 0 = the source BTF was HDR       |
//! | 32          | 4         | `u32` clusters (1..=1024)                         |
//! | 36          | 4         | `u32` components per cluster (0..=15)             |
//! | 40          | 4         | `f32` the source's display scale (1 for 8-bit)    |
//! | 44          | 4·θ count | `f32` polar angles in degrees                     |
//! | 44 + 4·θ    | 8         | `u64` payload length in bytes                     |
//! | 52 + 4·θ    | 4         | `u32` CRC-32 of the payload                       |
//! | header      | 2·w·h     | `u16` each sample texel's cluster, row-major (absent with one cluster) |
//! |             | 2·w·h·k   | `u16` half-float coefficients, k per texel        |
//! |             | 2·3·i·c·(k+1) | `u16` half-float basis images (i images)      |
//!
//! The payload length must equal what the shape gives, the file must end
//! exactly after it, and the payload is checked against the memory cap
//! before it is read; cluster ids, finite halves and the display scale are
//! checked by [`LocalPca::from_parts`].

use crate::IoError;
use crate::btf_file::{crc32, write_atomic_with};
use hitex_core::btf::grid::MAX_ANGLES;
use hitex_core::btf::pca::{LocalPca, MAX_PCA_CLUSTERS, MAX_PCA_COMPONENTS, PcaParts};
use hitex_core::btf::{AngularGrid, Btf};
use std::io::{Read, Write};
use std::path::Path;

/// The file signature.
pub const HPCA_MAGIC: [u8; 4] = *b"HPCA";

/// The version this module writes and reads.
pub const HPCA_VERSION: u32 = 1;

/// Flag bit: the source BTF was HDR.
pub const FLAG_HDR_SOURCE: u32 = 1;

/// Bytes of the fixed part of the header (magic to display scale).
const FIXED_HEADER: usize = 44;

/// Bytes after the θ list: payload length and CRC.
const HEADER_TAIL: usize = 12;

/// Header bytes for `theta_count` polar angles.
fn header_len(theta_count: usize) -> usize {
    FIXED_HEADER + 4 * theta_count + HEADER_TAIL
}

/// Whether `start` (a file's first bytes) is the start of a compressed BTF.
pub fn is_pca_file(start: &[u8]) -> bool {
    start.starts_with(&HPCA_MAGIC)
}

/// The header fields of a compressed BTF file.
#[derive(Debug, Clone, PartialEq)]
pub struct HpcaHeader {
    /// Format version.
    pub version: u32,
    /// Header length in bytes, the offset of the payload.
    pub header_bytes: u32,
    /// Sample width in texels.
    pub width: u32,
    /// Sample height in texels.
    pub height: u32,
    /// The angular grid.
    pub grid: AngularGrid,
    /// Whether the source BTF was HDR.
    pub hdr_source: bool,
    /// Clusters.
    pub clusters: u32,
    /// Components per cluster.
    pub components: u32,
    /// The source's display scale.
    pub ldr_scale: f32,
    /// Payload length in bytes.
    pub payload_bytes: u64,
    /// CRC-32 of the payload as recorded.
    pub crc32: u32,
}

/// The payload's three arrays' lengths in halves (ids, none with one
/// cluster; coefficients; basis) for a shape, or None past 64 bits.
fn array_lens(grid: &AngularGrid, width: u32, height: u32, clusters: u32, components: u32) -> Option<[u64; 3]> {
    let n = u64::from(width) * u64::from(height);
    let k = u64::from(components);
    let d = grid.directions() as u64;
    let basis = (d * d).checked_mul(u64::from(clusters))?.checked_mul(k + 1)?.checked_mul(3)?;
    Some([if clusters > 1 { n } else { 0 }, n.checked_mul(k)?, basis])
}

/// The header's bytes for `p` and a payload CRC.
fn encode_header(p: &LocalPca, crc: u32, payload: u64) -> Vec<u8> {
    let grid = p.grid();
    let n = grid.theta_count();
    let len = header_len(n);
    let mut h = Vec::with_capacity(len);
    h.extend_from_slice(&HPCA_MAGIC);
    let flags = if p.is_hdr() { FLAG_HDR_SOURCE } else { 0 };
    for v in [HPCA_VERSION, len as u32, p.width(), p.height(), n as u32, grid.phi_count() as u32, flags] {
        h.extend_from_slice(&v.to_le_bytes());
    }
    h.extend_from_slice(&p.clusters().to_le_bytes());
    h.extend_from_slice(&p.components().to_le_bytes());
    h.extend_from_slice(&p.ldr_scale().to_le_bytes());
    for &t in grid.theta_deg() {
        h.extend_from_slice(&t.to_le_bytes());
    }
    h.extend_from_slice(&payload.to_le_bytes());
    h.extend_from_slice(&crc.to_le_bytes());
    h
}

/// The payload: cluster ids (none with one cluster), coefficients, basis,
/// as little-endian halves.
fn payload(p: &LocalPca) -> Vec<u8> {
    let ids: &[u16] = if p.clusters() > 1 { p.cluster_ids() } else { &[] };
    [ids, p.coef_halves(), p.basis_halves()].iter().flat_map(|a| a.iter().flat_map(|h| h.to_le_bytes())).collect()
}

/// The whole file of `p`.
pub fn pca_file_bytes(p: &LocalPca) -> Vec<u8> {
    let body = payload(p);
    let mut out = encode_header(p, crc32(&body), body.len() as u64);
    out.extend_from_slice(&body);
    out
}

/// Writes `p` to `path` atomically (a temporary file renamed over it).
pub fn write_pca_file(path: &Path, p: &LocalPca) -> Result<(), IoError> {
    let body = payload(p);
    let header = encode_header(p, crc32(&body), body.len() as u64);
    write_atomic_with(path, |w| {
        w.write_all(&header)?;
        w.write_all(&body)
    })
}

/// Reads and checks the header at the start of `bytes` (at least the
/// header's length; `file_len` the whole file's): every field, and that the
/// payload it declares is the shape's and ends the file exactly.
fn parse_header(bytes: &[u8], file_len: u64, path: &Path) -> Result<HpcaHeader, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    if !is_pca_file(bytes) {
        return Err(fmt("not a compressed BTF (an .hbtf of local PCA starts with \"HPCA\")".into()));
    }
    if bytes.len() < FIXED_HEADER {
        return Err(fmt(format!("the file ends inside the header (byte {} of {FIXED_HEADER})", bytes.len())));
    }
    let field = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let (version, header_bytes, width, height) = (field(4), field(8), field(12), field(16));
    let (theta_count, phi_count, flags, clusters, components) = (field(20), field(24), field(28), field(32), field(36));
    let ldr_scale = f32::from_bits(field(40));
    if version != HPCA_VERSION {
        return Err(fmt(format!(
            "compressed BTF version {version} is not supported (this build reads {HPCA_VERSION})"
        )));
    }
    if flags & !FLAG_HDR_SOURCE != 0 {
        return Err(fmt(format!("header flags {flags:#x} are unknown (version 1 knows only bit 0, HDR source)")));
    }
    if theta_count == 0 || theta_count as usize > MAX_ANGLES {
        return Err(fmt(format!("header declares {theta_count} polar angles; 1..={MAX_ANGLES} are allowed")));
    }
    if phi_count == 0 || phi_count as usize > MAX_ANGLES {
        return Err(fmt(format!("header declares {phi_count} azimuths; 1..={MAX_ANGLES} are allowed")));
    }
    let want = header_len(theta_count as usize);
    if header_bytes as usize != want {
        return Err(fmt(format!(
            "header length field is {header_bytes} bytes; {theta_count} polar angles make a {want}-byte header"
        )));
    }
    if bytes.len() < want || file_len < want as u64 {
        return Err(fmt(format!("the file of {file_len} bytes is shorter than its {want}-byte header")));
    }
    let hdr_source = flags & FLAG_HDR_SOURCE != 0;
    if !(ldr_scale.is_finite() && ldr_scale > 0.0 && ldr_scale <= 1.0) || (!hdr_source && ldr_scale != 1.0) {
        return Err(fmt(format!(
            "display scale {ldr_scale} is not {}",
            if hdr_source { "in (0, 1]" } else { "1, as an 8-bit source's is" }
        )));
    }
    let theta: Vec<f32> = bytes[FIXED_HEADER..want - HEADER_TAIL]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let grid = AngularGrid::new(theta, phi_count as usize).map_err(|e| fmt(format!("header grid: {e}")))?;
    hitex_core::btf::dataset::checked_size(&grid, width, height).map_err(|e| fmt(format!("header shape: {e}")))?;
    if clusters == 0 || clusters as usize > MAX_PCA_CLUSTERS {
        return Err(fmt(format!("header declares {clusters} clusters; 1..={MAX_PCA_CLUSTERS} are allowed")));
    }
    if components as usize > MAX_PCA_COMPONENTS {
        return Err(fmt(format!("header declares {components} components; 0..={MAX_PCA_COMPONENTS} are allowed")));
    }
    let tail = &bytes[want - HEADER_TAIL..want];
    let payload_bytes = u64::from_le_bytes([tail[0], tail[1], tail[2], tail[3], tail[4], tail[5], tail[6], tail[7]]);
    let crc = u32::from_le_bytes([tail[8], tail[9], tail[10], tail[11]]);
    let need = array_lens(&grid, width, height, clusters, components)
        .and_then(|l| l.iter().try_fold(0u64, |a, &b| a.checked_add(b)))
        .and_then(|h| h.checked_mul(2))
        .ok_or_else(|| fmt("the declared shape needs more than 2^64 bytes".into()))?;
    if payload_bytes != need {
        return Err(fmt(format!(
            "header declares a payload of {payload_bytes} bytes; {width}x{height} texels, {clusters} clusters × \
             {components} components over {}² directions need {need}",
            grid.directions()
        )));
    }
    let end = want as u64 + need;
    if file_len < end {
        return Err(fmt(format!(
            "header declares a payload of {need} bytes but only {} follow the header (truncated file)",
            file_len - want as u64
        )));
    }
    if file_len > end {
        return Err(fmt(format!("{} bytes follow the {need}-byte payload", file_len - end)));
    }
    // the payload's bytes and its halves are held at once
    crate::limits::check_cap("the compressed BTF's payload", need.checked_mul(2)).map_err(|e| fmt(e.to_string()))?;
    Ok(HpcaHeader {
        version,
        header_bytes,
        width,
        height,
        grid,
        hdr_source,
        clusters,
        components,
        ldr_scale,
        payload_bytes,
        crc32: crc,
    })
}

/// The compressed BTF of a checked header and its payload bytes.
fn assemble(h: HpcaHeader, body: &[u8], path: &Path) -> Result<LocalPca, IoError> {
    let fmt = |m: String| IoError::Format { path: path.to_path_buf(), message: m };
    let actual = crc32(body);
    if actual != h.crc32 {
        return Err(fmt(format!(
            "payload CRC-32 is {actual:#010x} but the header records {:#010x} (the data is corrupt)",
            h.crc32
        )));
    }
    let lens = array_lens(&h.grid, h.width, h.height, h.clusters, h.components)
        .ok_or_else(|| fmt("the declared shape needs more than 2^64 bytes".into()))?;
    let halves = |from: usize, n: u64| -> Vec<u16> {
        body[from..from + 2 * n as usize].chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect()
    };
    // one cluster: every texel's id is 0, and the file holds none
    let cluster = if h.clusters > 1 { halves(0, lens[0]) } else { vec![0; h.width as usize * h.height as usize] };
    let coefs = halves(2 * lens[0] as usize, lens[1]);
    let basis = halves(2 * (lens[0] + lens[1]) as usize, lens[2]);
    LocalPca::from_parts(PcaParts {
        grid: h.grid,
        width: h.width,
        height: h.height,
        clusters: h.clusters,
        components: h.components,
        cluster,
        coefs,
        basis,
        ldr_scale: h.ldr_scale,
        hdr: h.hdr_source,
    })
    .map_err(|e| {
        fmt(match e {
            hitex_core::CoreError::InvalidImage(m) => m,
            other => other.to_string(),
        })
    })
}

/// Parses a whole compressed BTF file held in memory; `name` is the file
/// named in errors.
pub fn pca_from_bytes(bytes: &[u8], name: &str) -> Result<LocalPca, IoError> {
    let path = Path::new(name);
    let h = parse_header(bytes, bytes.len() as u64, path)?;
    let start = h.header_bytes as usize;
    assemble(h, &bytes[start..], path)
}

/// Reads and checks only the header of a compressed BTF file.
pub fn read_pca_header(path: &Path) -> Result<HpcaHeader, IoError> {
    let rerr = |source: std::io::Error| IoError::Read { path: path.to_path_buf(), source };
    let file = std::fs::File::open(path).map_err(rerr)?;
    let len = file.metadata().map_err(rerr)?.len();
    let mut start = Vec::new();
    // the longest header: 56 + 4·MAX_ANGLES bytes
    file.take(header_len(MAX_ANGLES) as u64).read_to_end(&mut start).map_err(rerr)?;
    parse_header(&start, len, path)
}

/// Reads a compressed BTF file: the header checked before the payload is
/// read, then the CRC and every array.
pub fn read_pca_file(path: &Path) -> Result<LocalPca, IoError> {
    let rerr = |source: std::io::Error| IoError::Read { path: path.to_path_buf(), source };
    let h = read_pca_header(path)?;
    let mut file = std::fs::File::open(path).map_err(rerr)?;
    let mut bytes = Vec::with_capacity(h.header_bytes as usize + h.payload_bytes as usize);
    (&mut file).take(h.header_bytes as u64 + h.payload_bytes).read_to_end(&mut bytes).map_err(rerr)?;
    // the file may have changed since its header was read
    let again = parse_header(&bytes, bytes.len() as u64, path)?;
    if again != h {
        return Err(IoError::Format { path: path.to_path_buf(), message: "the file changed while it was read".into() });
    }
    let start = h.header_bytes as usize;
    assemble(h, &bytes[start..], path)
}

/// Bytes [`LocalPca::decompress`] holds at its peak per texel: the linear
/// f32 RGB it reconstructs, then the texels made of it (8-bit RGB; or half
/// floats and their 8-bit display copy for an HDR source).
fn reconstruction_bytes_per_texel(hdr: bool) -> u64 {
    12 + if hdr { 6 + 3 } else { 3 }
}

/// Bytes the reconstruction of `p` holds at its peak.
pub fn reconstruction_bytes(p: &LocalPca) -> u64 {
    let d = p.grid().directions() as u64;
    let texels = d * d * u64::from(p.width()) * u64::from(p.height());
    texels.saturating_mul(reconstruction_bytes_per_texel(p.is_hdr()))
}

/// The BTF a compressed one stands for ([`LocalPca::decompress`]), its
/// peak size checked against the memory cap first. The reconstruction is
/// not bounded by the file's length: compression by local PCA legitimately
/// reaches 1:1000 of the raw texels and more, so only the cap bounds it.
pub fn decompressed(p: &LocalPca, path: &Path) -> Result<Btf, IoError> {
    crate::limits::check_cap("the BTF reconstructed from its local PCA", Some(reconstruction_bytes(p)))
        .map_err(|e| IoError::Format { path: path.to_path_buf(), message: e.to_string() })?;
    p.decompress().map_err(|e| IoError::from(e).in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hitex_core::btf::pca::{PcaOptions, fit};

    fn small() -> LocalPca {
        use hitex_core::btf::synth::{Material, SynthOptions, synthesize};
        let grid = AngularGrid::new(vec![0.0, 35.0, 70.0], 6).unwrap();
        let opts = SynthOptions { grid, size: 8, supersample: 1, ..Default::default() };
        let btf = synthesize(Material::Knit, &opts, &|_| {}).unwrap();
        fit(&btf, PcaOptions { clusters: 3, components: 2 }, &|_, _| {}).unwrap()
    }

    #[test]
    fn a_compressed_btf_reads_back_bit_for_bit() {
        let p = small();
        let bytes = pca_file_bytes(&p);
        assert_eq!(pca_from_bytes(&bytes, "k.hbtf").unwrap(), p);
        let dir = crate::test_dir::TestDir::fresh("hpca");
        let path = dir.join("k.hbtf");
        write_pca_file(&path, &p).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), bytes);
        assert_eq!(read_pca_file(&path).unwrap(), p);
        let h = read_pca_header(&path).unwrap();
        assert_eq!((h.clusters, h.components, h.width, h.hdr_source), (3, 2, 8, false));
        // every reader of .hbtf takes it, as its reconstruction
        assert_eq!(crate::btf_file::read_hbtf(&path).unwrap(), p.decompress().unwrap());
        assert_eq!(crate::btf_file::hbtf_from_bytes(&bytes, "k.hbtf").unwrap(), p.decompress().unwrap());
    }

    #[test]
    fn an_hdr_source_keeps_its_flag_and_display_scale() {
        let grid = AngularGrid::new(vec![0.0, 45.0], 4).unwrap();
        let d = grid.directions();
        // values up to 40: a display scale below 1
        let linear: Vec<f32> = (0..d * d * 4 * 3).map(|i| 0.01 + (i % 97) as f32 * 0.4).collect();
        let btf = Btf::from_linear(grid, 2, 2, &linear).unwrap();
        let p = fit(&btf, PcaOptions { clusters: 2, components: 1 }, &|_, _| {}).unwrap();
        assert!(p.is_hdr() && p.ldr_scale() < 1.0);
        let back = pca_from_bytes(&pca_file_bytes(&p), "hdr.hbtf").unwrap();
        assert_eq!(back, p);
        assert!(decompressed(&back, Path::new("hdr.hbtf")).unwrap().is_hdr());
    }

    #[test]
    fn malformed_compressed_btfs_are_refused_by_name() {
        let p = small();
        let good = pca_file_bytes(&p);
        let n = p.grid().theta_count();
        let refused = |f: &dyn Fn(&mut Vec<u8>), want: &str| {
            let mut b = good.clone();
            f(&mut b);
            let e = pca_from_bytes(&b, "bad.hbtf").unwrap_err().to_string();
            assert!(e.contains("bad.hbtf") && e.contains(want), "{want}: {e}");
        };
        let put = |b: &mut Vec<u8>, at: usize, v: u32| b[at..at + 4].copy_from_slice(&v.to_le_bytes());
        refused(&|b| b.truncate(20), "ends inside the header");
        refused(&|b| put(b, 4, 2), "version 2");
        refused(&|b| put(b, 28, 6), "flags 0x6");
        refused(&|b| put(b, 20, 0), "0 polar angles");
        refused(&|b| put(b, 8, 7), "header length field is 7");
        refused(&|b| put(b, 32, 0), "0 clusters");
        refused(&|b| put(b, 32, 4096), "4096 clusters");
        refused(&|b| put(b, 36, 99), "99 components");
        refused(&|b| put(b, 12, 0), "header shape");
        // more clusters than the payload holds: the declared length no longer matches
        refused(&|b| put(b, 32, 4), "need");
        refused(&|b| b.truncate(b.len() - 1), "truncated file");
        refused(&|b| b.push(0), "1 bytes follow");
        let body = header_len(n);
        refused(&|b| b[body + 3] ^= 1, "CRC-32");
        // a cluster id past the count, with a CRC that matches it
        let recrc = |b: &mut Vec<u8>| {
            let c = crc32(&b[body..]);
            b[body - 4..body].copy_from_slice(&c.to_le_bytes());
        };
        refused(
            &|b| {
                b[body..body + 2].copy_from_slice(&7u16.to_le_bytes());
                recrc(b)
            },
            "in cluster 7 of 3",
        );
        refused(
            &|b| {
                let at = b.len() - 2;
                b[at..].copy_from_slice(&0x7e00u16.to_le_bytes());
                recrc(b)
            },
            "infinite or NaN",
        );
        refused(&|b| put(b, 40, 0f32.to_bits()), "display scale 0 is not 1");
        refused(&|b| put(b, 40, f32::NAN.to_bits()), "display scale NaN");
        refused(&|b| put(b, 40, 0.5f32.to_bits()), "as an 8-bit source's is");
        assert!(pca_from_bytes(b"HBTF", "x.hbtf").unwrap_err().to_string().contains("starts with \"HPCA\""));
    }
}
