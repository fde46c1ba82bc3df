//! Colour legends drawn into a rendered frame: a vertical ramp with its
//! range written beside it and a title with units above it, in a small
//! built-in 3×5 pixel font (digits, capitals, a few signs), so analysis
//! images carry their scale. Legends sit in a strip at the right edge whose
//! width [`legend_width`] gives, so that a view can be framed clear of it.

use crate::Frame;
use crate::cpu::nurbs::diverging;

/// 3×5 glyphs, rows top to bottom, bit 2 = left column.
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 2, 2],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '-' => [0, 0, 7, 0, 0],
        '+' => [0, 2, 7, 2, 0],
        '.' => [0, 0, 0, 0, 2],
        'e' => [0, 7, 7, 4, 7],
        ' ' => [0; 5],
        '/' => [1, 1, 2, 4, 4],
        '(' => [1, 2, 2, 2, 1],
        ')' => [4, 2, 2, 2, 4],
        ',' => [0, 0, 0, 2, 4],
        ':' => [0, 2, 0, 2, 0],
        '=' => [0, 7, 0, 7, 0],
        '%' => [5, 1, 2, 4, 5],
        '|' => [2, 2, 2, 2, 2],
        '<' => [1, 2, 4, 2, 1],
        '>' => [4, 2, 1, 2, 4],
        '²' => [6, 1, 2, 7, 0],
        '°' => [2, 5, 2, 0, 0],
        '×' => [0, 5, 2, 5, 0],
        '±' => [2, 7, 2, 0, 7],
        '−' => [0, 0, 7, 0, 0],
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [3, 4, 4, 4, 3],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'F' => [7, 4, 6, 4, 4],
        'G' => [3, 4, 5, 5, 3],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 2],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [2, 5, 5, 5, 2],
        'P' => [6, 5, 6, 4, 4],
        'Q' => [2, 5, 5, 6, 3],
        'R' => [6, 5, 6, 5, 5],
        'S' => [3, 4, 2, 1, 6],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        c if c.is_ascii_lowercase() && c != 'e' => return glyph(c.to_ascii_uppercase()),
        _ => return None,
    })
}

fn put(f: &mut Frame, x: i64, y: i64, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as u32) < f.width && (y as u32) < f.height {
        let i = (y as usize * f.width as usize + x as usize) * 4;
        f.rgba[i..i + 3].copy_from_slice(&c);
    }
}

/// Writes `text` with its top-left corner at (x, y), each font pixel `scale` wide.
pub fn text(f: &mut Frame, x: i64, y: i64, scale: i64, s: &str, color: [u8; 3]) {
    let mut cx = x;
    for ch in s.chars() {
        if let Some(g) = glyph(ch) {
            for (row, bits) in g.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        for dy in 0..scale {
                            for dx in 0..scale {
                                put(f, cx + col as i64 * scale + dx, y + row as i64 * scale + dy, color);
                            }
                        }
                    }
                }
            }
        }
        cx += 4 * scale;
    }
}

/// Font pixels per glyph pixel for a `width`×`height` frame: larger on
/// taller frames, and never so large that the strip takes more than a
/// third of the width (0: the frame is too narrow for a legend).
fn scale_for(width: u32, height: u32) -> i64 {
    (height as i64 / 150).clamp(1, 4).min(width as i64 / (STRIP * 3))
}

/// Characters per line the legend strip holds (a value label such as
/// `-1.00e-12` beside the ramp included).
const COLUMNS: i64 = 11;

/// The strip's width in font pixels.
const STRIP: i64 = COLUMNS * 4 + 3;

/// Width in pixels of the strip at the right edge of a `width`×`height`
/// frame that a legend covers (none when the frame is too small to hold one).
pub fn legend_width(width: u32, height: u32) -> u32 {
    (STRIP * scale_for(width, height)) as u32
}

/// Value labels with the fewest digits that still tell the range apart from
/// zero (`±1.00e-6`, never `±0.0000`).
pub fn format_value(v: f32) -> String {
    let a = v.abs();
    if a != 0.0 && !(0.01..1e4).contains(&a) { format!("{v:.2e}") } else { format!("{v:.3}") }
}

/// Draws the diverging ramp for `[-range, range]` in the legend strip at the
/// right edge of the frame, with the values at its top, middle and bottom
/// and up to four `title` lines (name, units, how the range was chosen)
/// above it. Lines longer than the strip are cut.
pub fn diverging_legend(f: &mut Frame, range: f32, title: &[&str]) {
    let labels = [format!("+{}", format_value(range)), " 0".into(), format!("-{}", format_value(range))];
    ramp(f, title, 4, 0, &diverging, &labels);
}

/// Draws the deviation mode's scale in the legend strip: the ramp from
/// `+range` (top) to `-range` (bottom) with the tolerance band, its values,
/// a swatch for "no data", and up to three `title` lines above it.
pub fn deviation_legend(f: &mut Frame, tolerance: f32, range: f32, title: &[&str]) {
    use crate::cpu::nurbs::deviation_base;
    let middle =
        if tolerance > 0.0 && tolerance < range { format!("±{}", format_value(tolerance)) } else { " 0".into() };
    let labels = [format!("+{}", format_value(range)), middle, format!("-{}", format_value(range))];
    let color = |t: f32| deviation_base(t * range, tolerance, range);
    let Some((scale, x0, bar_w, y1)) = ramp(f, title, 3, 2, &color, &labels) else { return };
    let ys = y1 + 7 * scale;
    if ys + 5 * scale <= f.height as i64 {
        let c = quantise(deviation_base(hitex_core::nurbs::deviation::NO_DATA, tolerance, range));
        for dy in 0..5 * scale {
            for dx in 0..bar_w {
                put(f, x0 + dx, ys + dy, c);
            }
        }
        text(f, x0 + bar_w + 2 * scale, ys, scale, "NO DATA", [235, 235, 235]);
    }
}

fn quantise(c: glam::Vec3) -> [u8; 3] {
    [c.x, c.y, c.z].map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

/// A vertical ramp in the legend strip: up to `max_title` title lines, the
/// bar coloured by `color(t)` for t from +1 (top) to −1 (bottom), `labels`
/// at its top, middle and bottom, and `reserve` text lines kept free below
/// it. Returns the font scale, the strip's left edge, the bar's width and
/// its bottom, or `None` when the frame is too small for a legend.
fn ramp(
    f: &mut Frame,
    title: &[&str],
    max_title: usize,
    reserve: i64,
    color: &dyn Fn(f32) -> glam::Vec3,
    labels: &[String; 3],
) -> Option<(i64, i64, i64, i64)> {
    if legend_width(f.width, f.height) == 0 {
        return None;
    }
    let scale = scale_for(f.width, f.height);
    let bar_w = 6 * scale;
    let x0 = f.width as i64 - legend_width(f.width, f.height) as i64 + scale;
    let white = [235, 235, 235];
    let line = 7 * scale;
    let lines = title.len().min(max_title) as i64;
    let top = (f.height as i64 / 6).max(lines * line + 2 * scale);
    for (k, t) in title.iter().take(max_title).enumerate() {
        let cut: String = t.chars().take(COLUMNS as usize).collect();
        text(f, x0, top - (lines - k as i64) * line, scale, &cut, white);
    }
    let (y0, y1) = (top + 2 * scale, f.height as i64 * 5 / 6 - reserve * line);
    for y in y0..y1 {
        let c = quantise(color(1.0 - 2.0 * (y - y0) as f32 / (y1 - y0 - 1).max(1) as f32));
        for x in x0..x0 + bar_w {
            put(f, x, y, c);
        }
    }
    let lx = x0 + bar_w + 2 * scale;
    text(f, lx, y0, scale, &labels[0], white);
    text(f, lx, (y0 + y1) / 2 - 2 * scale, scale, &labels[1], white);
    text(f, lx, y1 - 5 * scale, scale, &labels[2], white);
    Some((scale, x0, bar_w, y1))
}

/// Draws a key of discrete colours (e.g. MIP levels) in the legend strip:
/// one swatch and label per entry, under up to two title lines, on a dark
/// backing so that it reads over any image.
pub fn swatch_legend(f: &mut Frame, title: &[&str], entries: &[([u8; 3], String)]) {
    if legend_width(f.width, f.height) == 0 {
        return;
    }
    let scale = scale_for(f.width, f.height);
    let x0 = f.width as i64 - legend_width(f.width, f.height) as i64 + scale;
    let white = [235, 235, 235];
    let line = 7 * scale;
    let mut y = (f.height as i64 / 6).max(2 * scale);
    let rows = (title.len().min(2) + entries.len()) as i64;
    let bottom = (y + rows * line + scale).min(f.height as i64);
    for by in (y - 2 * scale).max(0)..bottom {
        for bx in (x0 - scale).max(0)..f.width as i64 {
            let i = (by as usize * f.width as usize + bx as usize) * 4;
            for c in &mut f.rgba[i..i + 3] {
                *c = (*c as u16 * 3 / 10) as u8;
            }
        }
    }
    for t in title.iter().take(2) {
        let cut: String = t.chars().take(COLUMNS as usize).collect();
        text(f, x0, y, scale, &cut, white);
        y += line;
    }
    for (c, label) in entries {
        if y + line > f.height as i64 {
            break;
        }
        for dy in 0..5 * scale {
            for dx in 0..5 * scale {
                put(f, x0 + dx, y + dy, *c);
            }
        }
        let cut: String = label.chars().take(COLUMNS as usize - 2).collect();
        text(f, x0 + 7 * scale, y, scale, &cut, white);
        y += line;
    }
}

/// The MIP-level key: the ramp's colour of each level `0..levels` (at most
/// 11: the ramp's last colour stands for every level above).
pub fn level_legend(f: &mut Frame, levels: usize) {
    let entries: Vec<([u8; 3], String)> = (0..levels.clamp(1, 11))
        .map(|l| {
            let c = crate::cpu::textured::level_color(l as f32);
            let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            ([q(c.x), q(c.y), q(c.z)], if l == 10 && levels > 11 { "10+".to_string() } else { l.to_string() })
        })
        .collect();
    swatch_legend(f, &["MIP LEVEL"], &entries);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legend_draws_ramp_and_labels_inside_the_frame() {
        let mut f = Frame { width: 200, height: 120, rgba: vec![0; 200 * 120 * 4] };
        diverging_legend(&mut f, 0.25, &["MEAN", "CURVATURE", "1/LENGTH"]);
        let lit = f.rgba.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(lit > 300, "{lit}");
        // nothing drawn left of the strip the framing keeps clear
        let strip = legend_width(200, 120) as usize;
        assert!(strip > 0);
        for y in 0..120 {
            for x in 0..200 - strip {
                assert_eq!(f.rgba[(y * 200 + x) * 4..][..3], [0, 0, 0], "({x}, {y})");
            }
        }
        // every character the legends write has a glyph
        for v in [0.25f32, 123.0, 1e-6, 5e5, 0.0] {
            for ch in format!("+{}-{}", format_value(v), format_value(v)).chars() {
                assert!(glyph(ch).is_some(), "{ch}");
            }
        }
        for ch in "GAUSSIAN CURVATURE 1/LENGTH² ±2×P75 OF |K| LEVEL MIP: (RANGE)°%".chars() {
            assert!(glyph(ch).is_some(), "{ch}");
        }
        // tiny frames do not panic and draw nothing
        let mut t = Frame { width: 3, height: 2, rgba: vec![0; 24] };
        diverging_legend(&mut t, 1.0, &["X"]);
        swatch_legend(&mut t, &["X"], &[([255, 0, 0], "0".into())]);
        assert!(t.rgba.iter().all(|&b| b == 0));
    }

    #[test]
    fn every_label_fits_and_narrow_tall_frames_keep_their_legend() {
        for (w, h) in [(512u32, 512u32), (300, 600), (320, 320), (1600, 1200), (160, 120)] {
            let strip = legend_width(w, h);
            assert!(strip > 0 && strip * 3 <= w, "{w}x{h}: strip {strip}");
            let scale = scale_for(w, h) as u32;
            let mut f = Frame { width: w, height: h, rgba: vec![0; (w * h * 4) as usize] };
            // the widest labels: nine characters beside the ramp, eleven in the title
            diverging_legend(&mut f, 1.5e-12, &["PRINCIPAL K", "1/LENGTH", "±2×P75|H|", "CURVED PART"]);
            let lit = |x: u32| (0..h).any(|y| f.rgba[((y * w + x) * 4) as usize..][..3] != [0, 0, 0]);
            // nothing cut at the right edge: the last columns stay clear
            for x in w - 2 * scale..w {
                assert!(!lit(x), "{w}x{h}: column {x} lit");
            }
            assert!((w - strip..w).any(lit), "{w}x{h}: no legend");
        }
    }

    #[test]
    fn small_ranges_keep_their_digits() {
        assert_eq!(format_value(1e-6), "1.00e-6");
        assert_eq!(format_value(0.25), "0.250");
        assert_eq!(format_value(0.0), "0.000");
        assert_ne!(format_value(0.00004), "0.000");
    }
}
