//! A colour legend drawn into a rendered frame: a vertical ramp with its
//! range written beside it in a small built-in pixel font (digits, sign,
//! point, exponent), so curvature maps carry their scale.

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

/// Draws the diverging ramp for `[-range, range]` at the right edge of the
/// frame with the values at its top, middle and bottom.
pub fn diverging_legend(f: &mut Frame, range: f32) {
    let scale = (f.height as i64 / 200).clamp(1, 4);
    let bar_w = 6 * scale;
    let label_w = 4 * scale * 8;
    let x0 = f.width as i64 - bar_w - label_w - 4 * scale;
    let (y0, y1) = (f.height as i64 / 5, f.height as i64 * 4 / 5);
    for y in y0..y1 {
        let t = 1.0 - 2.0 * (y - y0) as f32 / (y1 - y0 - 1).max(1) as f32;
        let c = diverging(t);
        let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        for x in x0..x0 + bar_w {
            put(f, x, y, [q(c.x), q(c.y), q(c.z)]);
        }
    }
    let white = [235, 235, 235];
    let lx = x0 + bar_w + 2 * scale;
    text(f, lx, y0, scale, &format!("+{range:.2e}"), white);
    text(f, lx, (y0 + y1) / 2 - 2 * scale, scale, " 0", white);
    text(f, lx, y1 - 5 * scale, scale, &format!("-{range:.2e}"), white);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legend_draws_ramp_and_labels_inside_the_frame() {
        let mut f = Frame { width: 200, height: 120, rgba: vec![0; 200 * 120 * 4] };
        diverging_legend(&mut f, 0.25);
        let lit = f.rgba.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(lit > 300, "{lit}");
        // every format character has a glyph
        for ch in format!("+{:.2e}-{:.2e}", 0.25f32, 123.0f32).chars() {
            assert!(glyph(ch).is_some(), "{ch}");
        }
        // tiny frames do not panic
        let mut t = Frame { width: 3, height: 2, rgba: vec![0; 24] };
        diverging_legend(&mut t, 1.0);
    }
}
