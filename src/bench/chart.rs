//! A bar chart PNG of per-pass milliseconds for `sphereshade bench --chart`,
//! drawn with the image crate and a tiny built-in 3x5 bitmap font (no font
//! files needed): one stacked bar per run, one colour per pass.

use crate::output::RunStats;
use image::{Rgb, RgbImage};

/// 3x5 glyphs, five rows of three bits (MSB = left column).
fn glyph(c: char) -> [u8; 5] {
    match c.to_ascii_uppercase() {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
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
        '_' => [0, 0, 0, 0, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        ':' => [0, 2, 0, 2, 0],
        '(' => [1, 2, 2, 2, 1],
        ')' => [4, 2, 2, 2, 4],
        '/' => [1, 1, 2, 4, 4],
        '%' => [5, 1, 2, 4, 5],
        '=' => [0, 7, 0, 7, 0],
        _ => [0; 5],
    }
}

const SCALE: u32 = 2;
/// Advance per character in pixels.
pub const CHAR_W: u32 = 4 * SCALE;
pub const CHAR_H: u32 = 5 * SCALE;

/// Draws `text` with its top-left corner at (x, y).
pub fn draw_text(img: &mut RgbImage, x: u32, y: u32, text: &str, color: Rgb<u8>) {
    for (i, c) in text.chars().enumerate() {
        let g = glyph(c);
        let x0 = x + i as u32 * CHAR_W;
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    for dy in 0..SCALE {
                        for dx in 0..SCALE {
                            let (px, py) = (x0 + col * SCALE + dx, y + row as u32 * SCALE + dy);
                            if px < img.width() && py < img.height() {
                                img.put_pixel(px, py, color);
                            }
                        }
                    }
                }
            }
        }
    }
}

fn fill(img: &mut RgbImage, x: u32, y: u32, w: u32, h: u32, c: Rgb<u8>) {
    for py in y..(y + h).min(img.height()) {
        for px in x..(x + w).min(img.width()) {
            img.put_pixel(px, py, c);
        }
    }
}

/// Colour of the `i`-th pass name (in order of first appearance).
pub fn pass_color(i: usize) -> Rgb<u8> {
    const PALETTE: [[u8; 3]; 18] = [
        [78, 121, 167],
        [242, 142, 43],
        [225, 87, 89],
        [118, 183, 178],
        [89, 161, 79],
        [237, 201, 72],
        [176, 122, 161],
        [255, 157, 167],
        [156, 117, 95],
        [186, 176, 172],
        [31, 119, 180],
        [148, 103, 189],
        [44, 160, 44],
        [214, 39, 40],
        [23, 190, 207],
        [188, 189, 34],
        [127, 127, 127],
        [140, 86, 75],
    ];
    Rgb(PALETTE[i % PALETTE.len()])
}

const LABEL_CHARS: u32 = 50;
const ROW: u32 = 22;

/// One stacked bar per run (total median ms split into pass medians).
pub fn bar_chart(runs: &[RunStats]) -> RgbImage {
    let mut names: Vec<&str> = Vec::new();
    for r in runs {
        for p in &r.passes {
            if !names.contains(&p.name.as_str()) {
                names.push(&p.name);
            }
        }
    }
    let width = 1200u32;
    let legend_rows = names.len().div_ceil(6) as u32;
    let top = 10 + legend_rows * 16 + 10;
    let height = top + runs.len() as u32 * ROW + 30;
    let mut img = RgbImage::from_pixel(width, height, Rgb([250, 250, 250]));
    let ink = Rgb([30, 30, 30]);
    for (i, n) in names.iter().enumerate() {
        let (x, y) = (10 + (i as u32 % 6) * 195, 10 + (i as u32 / 6) * 16);
        fill(&mut img, x, y, 12, CHAR_H, pass_color(i));
        draw_text(&mut img, x + 18, y, n, ink);
    }
    let max = runs.iter().map(|r| r.total_ms.median).fold(1e-9, f64::max);
    let x0 = 10 + LABEL_CHARS * CHAR_W + 10;
    let bar_w = width - x0 - 90;
    for (k, r) in runs.iter().enumerate() {
        let y = top + k as u32 * ROW;
        let input = r.input.rsplit('/').next().unwrap_or(&r.input);
        let label = format!(
            "{} {}x{} {} {} {}{}",
            input,
            r.width,
            r.height,
            r.shadows,
            r.ssdo,
            r.raster,
            if r.opacity < 1.0 {
                format!(" a{:.1}", r.opacity)
            } else {
                String::new()
            }
        );
        let label: String = label.chars().take(LABEL_CHARS as usize).collect();
        draw_text(&mut img, 10, y + 5, &label, ink);
        let mut x = x0;
        for p in &r.passes {
            let w = ((p.median_ms / max) * bar_w as f64).round() as u32;
            let i = names.iter().position(|n| *n == p.name).unwrap_or(0);
            fill(&mut img, x, y + 2, w, ROW - 6, pass_color(i));
            x += w;
        }
        draw_text(
            &mut img,
            x + 6,
            y + 5,
            &format!("{:.0}", r.total_ms.median),
            ink,
        );
    }
    let foot = height - 20;
    let note = format!(
        "median ms per frame, {} on {}",
        "timestamp queries",
        runs.first().map_or("", |r| r.device.as_str())
    );
    draw_text(&mut img, 10, foot, &note, Rgb([90, 90, 90]));
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glyphs_differ_and_text_draws() {
        let digits: Vec<[u8; 5]> = "0123456789".chars().map(glyph).collect();
        for i in 0..10 {
            for j in 0..i {
                assert_ne!(digits[i], digits[j], "digits {i} and {j} look the same");
            }
        }
        let mut img = RgbImage::from_pixel(40, 12, Rgb([255, 255, 255]));
        draw_text(&mut img, 0, 0, "1.5", Rgb([0, 0, 0]));
        let ink = img.pixels().filter(|p| p.0 == [0, 0, 0]).count() as u32;
        // '1' has 8 set cells, '.' 1, '5' 11, each SCALE^2 pixels
        assert_eq!(ink, (8 + 1 + 11) * SCALE * SCALE);
    }
}
