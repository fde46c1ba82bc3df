//! The memory cap for anything sized from a file.
//!
//! Every reader checks what a file *claims* before it allocates: a declared
//! image size, array shape, payload length or archive entry size must fit both
//! the data the file actually holds (its length times the largest expansion
//! its compression can give) and one process-wide cap, so that a 2 GB claim in
//! a 1 KB header is refused at once instead of being allocated.
//!
//! The cap defaults to [`DEFAULT_MAX_BYTES`] and is set by the environment
//! variable `HITEX_MAX_MEMORY` (bytes, or with a `K`, `M`, `G` or `T` suffix:
//! `512M`, `2G`) or by [`set_max_bytes`] (the CLI's `--max-memory`).

use std::sync::atomic::{AtomicU64, Ordering};

/// The cap when nothing else is said: 8 GiB.
pub const DEFAULT_MAX_BYTES: u64 = 8 << 30;

/// Largest expansion of DEFLATE data (zlib's bound: 1032 output bytes per
/// input byte), which bounds PNG, zip/npz entries and deflated TIFF strips.
pub const DEFLATE_RATIO: u64 = 1032;

/// A bound on the expansion of the other compressed formats hitex reads
/// (baseline JPEG needs at least a few bits per 8×8 block; TIFF LZW and
/// PackBits expand far less than this).
pub const ANY_RATIO: u64 = 4096;

/// A size that cannot be parsed, or a claim refused before allocating.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LimitError {
    /// Text that is not a size (`unit`: a letter other than K, M, G, T, B).
    #[error("'{text}' is not a size such as 512M or 2G{}", if *.unit { " (units K, M, G, T)" } else { "" })]
    NotASize {
        /// The text given.
        text: String,
        /// Whether its unit letter is the fault.
        unit: bool,
    },
    /// A size below one byte or beyond 2^63.
    #[error("'{0}' is not a usable size (at least 1 byte)")]
    Unusable(String),
    /// A claim beyond the memory cap.
    #[error(
        "{what} needs {} ({claimed} bytes), beyond the memory cap of {} (raise it with --max-memory or HITEX_MAX_MEMORY)",
        human(*.claimed),
        human(*.cap)
    )]
    BeyondCap {
        /// What claims the memory.
        what: String,
        /// Bytes claimed.
        claimed: u64,
        /// The cap in force.
        cap: u64,
    },
    /// A claim that overflowed 64 bits.
    #[error("{0} claims more than 2^64 bytes")]
    Overflow(String),
    /// A claim beyond what the file's data can decode to.
    #[error(
        "{what} claims {} but the file holds only {available} bytes of data for it (at most {} once decoded)",
        human(*.claimed),
        human(*.bound)
    )]
    Unbacked {
        /// What claims the memory.
        what: String,
        /// Bytes claimed.
        claimed: u64,
        /// Bytes of data in the file for it.
        available: u64,
        /// The most those bytes decode to.
        bound: u64,
    },
}

/// 0 = not yet read from the environment.
static CAP: AtomicU64 = AtomicU64::new(0);

/// Parses `512M`, `2G`, `1048576`, `1.5G` (binary multiples).
pub fn parse_bytes(s: &str) -> Result<u64, LimitError> {
    let t = s.trim();
    let (num, mult) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let m: u64 = match c.to_ascii_uppercase() {
                'K' => 1 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                'B' => 1,
                _ => return Err(LimitError::NotASize { text: s.to_string(), unit: true }),
            };
            (&t[..i], m)
        }
        _ => (t, 1),
    };
    let v: f64 = num.trim().parse().map_err(|_| LimitError::NotASize { text: s.to_string(), unit: false })?;
    let bytes = v * mult as f64;
    if !bytes.is_finite() || bytes < 1.0 || bytes > u64::MAX as f64 / 2.0 {
        return Err(LimitError::Unusable(s.to_string()));
    }
    Ok(bytes as u64)
}

/// The cap in force, in bytes: [`set_max_bytes`]'s, else
/// [`DEFAULT_MAX_BYTES`]. The library reads no environment; the `hitex`
/// binary sets it from `--max-memory` or `HITEX_MAX_MEMORY`.
pub fn max_bytes() -> u64 {
    match CAP.load(Ordering::Relaxed) {
        0 => DEFAULT_MAX_BYTES,
        c => c,
    }
}

/// Sets the cap (e.g. from `--max-memory`); it wins over the environment.
pub fn set_max_bytes(bytes: u64) {
    CAP.store(bytes.max(1), Ordering::Relaxed);
}

fn human(b: u64) -> String {
    match b {
        b if b >= 1 << 30 => format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64),
        b if b >= 1 << 20 => format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64),
        b if b >= 1 << 10 => format!("{:.1} KiB", b as f64 / 1024.0),
        b => format!("{b} bytes"),
    }
}

/// Checks that `claimed` bytes for `what` fit the cap. `None` means the claim
/// overflowed 64 bits.
pub fn check_cap(what: &str, claimed: Option<u64>) -> Result<u64, LimitError> {
    check_against(what, claimed, max_bytes())
}

fn check_against(what: &str, claimed: Option<u64>, cap: u64) -> Result<u64, LimitError> {
    match claimed {
        Some(c) if c <= cap => Ok(c),
        Some(c) => Err(LimitError::BeyondCap { what: what.to_string(), claimed: c, cap }),
        None => Err(LimitError::Overflow(what.to_string())),
    }
}

/// Checks a claim against the data that backs it: `claimed` bytes decoded
/// from `available` bytes of input that expands at most `ratio` times, and
/// against the cap.
pub fn check_claim(what: &str, claimed: Option<u64>, available: u64, ratio: u64) -> Result<u64, LimitError> {
    check_cap(what, claimed)?;
    check_backing(what, claimed, available, ratio)
}

/// Checks a claim against the data that backs it only (for data read in
/// bounded pieces, where the whole is never held).
pub fn check_backing(what: &str, claimed: Option<u64>, available: u64, ratio: u64) -> Result<u64, LimitError> {
    let Some(c) = claimed else { return Err(LimitError::Overflow(what.to_string())) };
    // a small constant allows for headers and tables that expand more
    let bound = available.saturating_mul(ratio).saturating_add(1 << 16);
    if c > bound {
        return Err(LimitError::Unbacked { what: what.to_string(), claimed: c, available, bound });
    }
    Ok(c)
}

/// Memory a text reader holds at its peak per byte of its file (the text,
/// the records parsed from it and the model built from them), measured on
/// exports of the real CAD files (a 9 MB STEP assembly, its 15 MB IGES, 9 MB
/// OBJ and 7 MB JSON exports) and a mesh, rounded up; points: the worst case
/// of `0 0 0` lines (6 bytes of text, 24 bytes of coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TextKind {
    /// STEP (ISO 10303-21): measured 9.6 bytes a byte.
    Step,
    /// IGES: measured 8.3.
    Iges,
    /// OBJ free-form: measured 2.9.
    ObjFreeform,
    /// The native JSON model: measured 1.8.
    Json,
    /// XYZ or JSON points: at most 5.
    Points,
    /// A polygon mesh in OBJ: measured 2.3 (a 46 MB grid with texture coordinates).
    ObjMesh,
}

impl TextKind {
    /// Bytes of memory per byte of text.
    pub fn ratio(self) -> u64 {
        match self {
            TextKind::Step => 12,
            TextKind::Iges => 10,
            TextKind::ObjFreeform => 4,
            TextKind::Json => 3,
            TextKind::Points => 5,
            TextKind::ObjMesh => 4,
        }
    }
    fn name(self) -> &'static str {
        match self {
            TextKind::Step => "STEP",
            TextKind::Iges => "IGES",
            TextKind::ObjFreeform => "OBJ",
            TextKind::Json => "JSON",
            TextKind::Points => "point",
            TextKind::ObjMesh => "OBJ mesh",
        }
    }
}

/// Checks, before a text file is read whole, that reading it fits the cap:
/// its `len` bytes times what its reader holds per byte ([`TextKind::ratio`]).
pub fn check_text_file(kind: TextKind, len: u64) -> Result<u64, LimitError> {
    check_text_against(kind, len, max_bytes())
}

fn check_text_against(kind: TextKind, len: u64, cap: u64) -> Result<u64, LimitError> {
    let what = format!("reading this {} file of {} ({}x in memory)", kind.name(), human(len), kind.ratio());
    check_against(&what, len.checked_mul(kind.ratio()), cap)
}

/// `a * b * c` in u64, `None` on overflow.
pub fn product(factors: &[u64]) -> Option<u64> {
    factors.iter().try_fold(1u64, |acc, &f| acc.checked_mul(f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_bytes("512M"), Ok(512 << 20));
        assert_eq!(parse_bytes("2g"), Ok(2 << 30));
        assert_eq!(parse_bytes("1.5K"), Ok(1536));
        assert_eq!(parse_bytes(" 4096 "), Ok(4096));
        for bad in ["", "G", "-1M", "0", "1X", "nanG", "inf"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn claims_are_checked_against_the_data_and_the_cap() {
        // a 2 GB claim backed by 1 KB of deflated data
        let e = check_claim("image", Some(2 << 30), 1024, DEFLATE_RATIO).unwrap_err();
        assert!(matches!(e, LimitError::Unbacked { available: 1024, .. }), "{e}");
        assert!(e.to_string().contains("holds only 1024 bytes"), "{e}");
        // honest claims pass
        assert_eq!(check_claim("image", Some(4 << 20), 1 << 20, DEFLATE_RATIO), Ok(4 << 20));
        assert!(check_cap("x", None).unwrap_err().to_string().contains("2^64"));
        let e = check_cap("x", Some(u64::MAX / 2)).unwrap_err();
        assert!(matches!(e, LimitError::BeyondCap { .. }) && e.to_string().contains("--max-memory"), "{e}");
        assert_eq!(
            parse_bytes("1X").unwrap_err().to_string(),
            "'1X' is not a size such as 512M or 2G (units K, M, G, T)"
        );
        assert_eq!(parse_bytes("1.2.3").unwrap_err().to_string(), "'1.2.3' is not a size such as 512M or 2G");
        assert_eq!(product(&[1 << 32, 1 << 31, 4]), None);
        assert_eq!(product(&[3, 5, 7]), Some(105));
    }

    #[test]
    fn text_files_are_weighed_by_what_their_reader_holds() {
        let cap = 100 << 20;
        // 9 MB of STEP takes about 110 MB: beyond a 100 MB cap; as JSON it fits
        let e = check_text_against(TextKind::Step, 9 << 20, cap).unwrap_err();
        assert_eq!(
            e.to_string(),
            "reading this STEP file of 9.0 MiB (12x in memory) needs 108.0 MiB (113246208 bytes), beyond the \
             memory cap of 100.0 MiB (raise it with --max-memory or HITEX_MAX_MEMORY)"
        );
        assert_eq!(check_text_against(TextKind::Json, 9 << 20, cap), Ok(27 << 20));
        assert!(matches!(check_text_against(TextKind::Iges, u64::MAX / 4, cap), Err(LimitError::Overflow(_))));
    }
}
