//! Text on raster images, with the bundled DejaVu Sans (`assets/fonts/`, Bitstream Vera licence).
//!
//! Contact sheets must look the same on every machine, so the font travels inside the binary
//! instead of being looked up on the system.

use crate::image::RgbImage;
use ab_glyph::{Font, FontRef, PxScale, ScaleFont, point};
use std::sync::OnceLock;

static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(FONT_BYTES).expect("the bundled font parses"))
}

/// Height of one line of text at `px` pixels, including the font's line gap.
pub fn line_height(px: f32) -> u32 {
    let f = font().as_scaled(PxScale::from(px));
    (f.ascent() - f.descent() + f.line_gap()).ceil() as u32
}

/// Advance width of a single line.
pub fn text_width(s: &str, px: f32) -> f32 {
    let f = font().as_scaled(PxScale::from(px));
    let mut w = 0.0;
    let mut prev = None;
    for c in s.chars() {
        let id = f.glyph_id(c);
        if let Some(p) = prev {
            w += f.kern(p, id);
        }
        w += f.h_advance(id);
        prev = Some(id);
    }
    w
}

/// Greedy word wrap to `max_width` pixels; a word wider than a line (a long job id) is broken
/// between characters rather than allowed to overflow into the neighbouring cell.
pub fn wrap(s: &str, px: f32, max_width: f32) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in s.split(' ').filter(|w| !w.is_empty()) {
        let candidate = if line.is_empty() { word.to_string() } else { format!("{line} {word}") };
        if text_width(&candidate, px) <= max_width {
            line = candidate;
            continue;
        }
        if !line.is_empty() {
            lines.push(std::mem::take(&mut line));
        }
        for c in word.chars() {
            let mut next = line.clone();
            next.push(c);
            if text_width(&next, px) > max_width && !line.is_empty() {
                lines.push(std::mem::take(&mut line));
                line.push(c);
            } else {
                line = next;
            }
        }
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// Draws one line with its top at `y`, alpha-blending the glyph coverage over the image;
/// pixels outside the image are clipped.
pub fn draw_text(img: &mut RgbImage, x: f32, y: f32, s: &str, px: f32, color: [u8; 3]) {
    let scale = PxScale::from(px);
    let f = font().as_scaled(scale);
    let baseline = y + f.ascent();
    let mut caret = x;
    let mut prev = None;
    let (w, h) = img.dimensions();
    for c in s.chars() {
        let id = f.glyph_id(c);
        if let Some(p) = prev {
            caret += f.kern(p, id);
        }
        let glyph = id.with_scale_and_position(scale, point(caret, baseline));
        caret += f.h_advance(id);
        prev = Some(id);
        let Some(outline) = font().outline_glyph(glyph) else { continue };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, coverage| {
            let px_x = bounds.min.x as i64 + gx as i64;
            let px_y = bounds.min.y as i64 + gy as i64;
            if px_x < 0 || px_y < 0 || px_x >= w as i64 || px_y >= h as i64 {
                return;
            }
            let a = coverage.clamp(0.0, 1.0);
            let old = img.get(px_x as u32, px_y as u32);
            let mut new = [0u8; 3];
            for k in 0..3 {
                new[k] = (old[k] as f32 * (1.0 - a) + color[k] as f32 * a).round() as u8;
            }
            img.put(px_x as u32, px_y as u32, new);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ink_bounds(img: &RgbImage) -> Option<(u32, u32, u32, u32)> {
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
        for y in 0..img.height() {
            for x in 0..img.width() {
                if img.get(x, y) != [255, 255, 255] {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
                }
            }
        }
        (x0 != u32::MAX).then_some((x0, y0, x1, y1))
    }

    #[test]
    fn text_lands_where_it_is_drawn_and_is_as_wide_as_measured() {
        let mut img = RgbImage::from_fn(200, 40, |_, _| [255, 255, 255]);
        draw_text(&mut img, 10.0, 5.0, "quilting", 16.0, [0, 0, 0]);
        let (x0, y0, x1, y1) = ink_bounds(&img).expect("text leaves ink");
        let w = text_width("quilting", 16.0);
        assert!((10..=12).contains(&x0), "left edge {x0}");
        assert!((x1 as f32) <= 10.0 + w + 1.0 && (x1 as f32) >= 10.0 + w - 4.0, "right edge {x1} vs width {w}");
        assert!(y0 >= 5 && y1 < 5 + line_height(16.0), "rows {y0}..{y1}");
    }

    #[test]
    fn wrapping_respects_the_width_and_keeps_every_character() {
        let s = "quilting block=50 overlap=8 tolerance=0.1 papers/003/b50/bricks_gray.toml#seed=3";
        let lines = wrap(s, 13.0, 120.0);
        assert!(lines.len() > 2);
        for l in &lines {
            assert!(text_width(l, 13.0) <= 120.0, "{l}");
        }
        assert_eq!(lines.concat().replace(' ', ""), s.replace(' ', ""));
    }
}
