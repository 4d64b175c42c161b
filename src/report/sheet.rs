//! Contact sheets: the sample and each group's output side by side at one scale, captioned, as a
//! PNG that can go straight into a paper or a review.
//!
//! Images are pasted pixel for pixel (or all reduced by the same integer factor on the overview),
//! never resampled individually, so sizes and textures compare honestly across methods.

use super::font;
use crate::image::RgbImage;

const PAD: u32 = 16;
const GAP: u32 = 16;
const CAPTION_GAP: u32 = 4;
const CAPTION_PX: f32 = 13.0;
const TITLE_PX: f32 = 18.0;
/// Narrow images still get a caption column wide enough to read.
const MIN_CELL_WIDTH: u32 = 150;
const BACKGROUND: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [20, 20, 20];
const SOFT_INK: [u8; 3] = [90, 90, 90];

/// What a cell shows: the image, or a grey box of the image's recorded size saying why not.
pub enum Picture {
    Image(RgbImage),
    Missing { width: u32, height: u32, why: String },
}

impl Picture {
    fn size(&self) -> (u32, u32) {
        match self {
            Picture::Image(i) => i.dimensions(),
            Picture::Missing { width, height, .. } => (*width, *height),
        }
    }
}

/// A captioned picture; the first caption line is the heading, the rest are details.
pub struct Cell {
    pub picture: Picture,
    pub caption: Vec<String>,
}

struct Laid {
    width: u32,
    lines: Vec<(String, [u8; 3])>,
    height: u32,
}

fn lay(cell: &Cell) -> Laid {
    let (w, h) = cell.picture.size();
    let width = w.max(MIN_CELL_WIDTH);
    let mut lines = Vec::new();
    for (i, c) in cell.caption.iter().enumerate() {
        let color = if i == 0 { INK } else { SOFT_INK };
        lines.extend(font::wrap(c, CAPTION_PX, width as f32).into_iter().map(|l| (l, color)));
    }
    let height = h + CAPTION_GAP + lines.len() as u32 * font::line_height(CAPTION_PX);
    Laid { width, lines, height }
}

fn paste(canvas: &mut RgbImage, img: &RgbImage, x0: u32, y0: u32) {
    for y in 0..img.height() {
        for x in 0..img.width() {
            canvas.put(x0 + x, y0 + y, img.get(x, y));
        }
    }
}

fn draw_cell(canvas: &mut RgbImage, cell: &Cell, laid: &Laid, x0: u32, y0: u32) {
    let (w, h) = cell.picture.size();
    match &cell.picture {
        Picture::Image(img) => paste(canvas, img, x0, y0),
        Picture::Missing { why, .. } => {
            for y in 0..h {
                for x in 0..w {
                    canvas.put(x0 + x, y0 + y, [200, 200, 200]);
                }
            }
            let lh = font::line_height(CAPTION_PX);
            for (i, line) in font::wrap(why, CAPTION_PX, w.saturating_sub(8).max(20) as f32).iter().enumerate() {
                font::draw_text(canvas, (x0 + 4) as f32, (y0 + 4 + i as u32 * lh) as f32, line, CAPTION_PX, [140, 0, 0]);
            }
        }
    }
    let lh = font::line_height(CAPTION_PX);
    for (i, (line, color)) in laid.lines.iter().enumerate() {
        font::draw_text(canvas, x0 as f32, (y0 + h + CAPTION_GAP + i as u32 * lh) as f32, line, CAPTION_PX, *color);
    }
}

/// Lays rows of cells under a title. With `aligned`, cells line up in columns (the overview's
/// sample × group grid, where a row may lack a group); otherwise each row packs its own cells.
pub fn compose(title: &str, rows: &[Vec<Option<Cell>>], aligned: bool) -> RgbImage {
    let laid: Vec<Vec<Option<Laid>>> = rows.iter().map(|r| r.iter().map(|c| c.as_ref().map(lay)).collect()).collect();
    let ncols = rows.iter().map(Vec::len).max().unwrap_or(0);
    let col_widths: Vec<u32> =
        (0..ncols).map(|c| laid.iter().filter_map(|r| r.get(c)?.as_ref().map(|l| l.width)).max().unwrap_or(0)).collect();
    let widths_of = |r: &Vec<Option<Laid>>| -> Vec<u32> {
        if aligned { col_widths[..r.len()].to_vec() } else { r.iter().map(|c| c.as_ref().map_or(0, |l| l.width)).collect() }
    };
    let content_width = laid
        .iter()
        .map(|r| {
            let ws = widths_of(r);
            ws.iter().sum::<u32>() + GAP * ws.len().saturating_sub(1) as u32
        })
        .max()
        .unwrap_or(0)
        .max(300);
    let title_lines = font::wrap(title, TITLE_PX, content_width as f32);
    let title_h = title_lines.len() as u32 * font::line_height(TITLE_PX);
    let row_heights: Vec<u32> = laid.iter().map(|r| r.iter().flatten().map(|l| l.height).max().unwrap_or(0)).collect();
    let width = PAD * 2 + content_width;
    let height = PAD * 2 + title_h + GAP + row_heights.iter().sum::<u32>() + GAP * row_heights.len().saturating_sub(1) as u32;
    let mut canvas = RgbImage::from_fn(width, height, |_, _| BACKGROUND);
    for (i, line) in title_lines.iter().enumerate() {
        font::draw_text(&mut canvas, PAD as f32, (PAD + i as u32 * font::line_height(TITLE_PX)) as f32, line, TITLE_PX, INK);
    }
    let mut y = PAD + title_h + GAP;
    for ((row, lrow), rh) in rows.iter().zip(&laid).zip(&row_heights) {
        let mut x = PAD;
        for ((cell, l), w) in row.iter().zip(lrow).zip(widths_of(lrow)) {
            if let (Some(cell), Some(l)) = (cell, l) {
                draw_cell(&mut canvas, cell, l, x, y);
            }
            x += w + GAP;
        }
        y += rh + GAP;
    }
    canvas
}

/// Packs cells into rows no wider than `max_width` (a sweep with many columns would otherwise
/// give a sheet too wide to view).
pub fn flow(cells: Vec<Cell>, max_width: u32) -> Vec<Vec<Option<Cell>>> {
    let mut rows: Vec<Vec<Option<Cell>>> = Vec::new();
    let mut row: Vec<Option<Cell>> = Vec::new();
    let mut used = 0;
    for cell in cells {
        let w = cell.picture.size().0.max(MIN_CELL_WIDTH);
        if !row.is_empty() && used + GAP + w > max_width {
            rows.push(std::mem::take(&mut row));
            used = 0;
        }
        used += if row.is_empty() { w } else { GAP + w };
        row.push(Some(cell));
    }
    if !row.is_empty() {
        rows.push(row);
    }
    rows
}

/// Splits rows into pages whose rows together stay within `max_height` pixels (a page holds at
/// least one row), so a long contact sheet stays an image a viewer can open.
pub fn paginate(rows: Vec<Vec<Option<Cell>>>, max_height: u32) -> Vec<Vec<Vec<Option<Cell>>>> {
    let mut pages: Vec<Vec<Vec<Option<Cell>>>> = Vec::new();
    let mut page = Vec::new();
    let mut used = 0;
    for row in rows {
        let h = row.iter().flatten().map(|c| lay(c).height).max().unwrap_or(0) + GAP;
        if !page.is_empty() && used + h > max_height {
            pages.push(std::mem::take(&mut page));
            used = 0;
        }
        used += h;
        page.push(row);
    }
    if !page.is_empty() {
        pages.push(page);
    }
    pages
}

/// The integer reduction that brings an image's longer side down to between `min_side` and
/// twice that (1 for images that are already small): thumbnails stay legible and are still an
/// exact block average of the image.
pub fn thumbnail_factor(width: u32, height: u32, min_side: u32) -> u32 {
    (width.max(height) / min_side.max(1)).max(1)
}

/// Reduces by an integer factor, each output pixel the mean of its `k × k` block (clipped at the
/// edges), so every image on a sheet shrinks alike.
pub fn downscale(img: &RgbImage, k: u32) -> RgbImage {
    if k <= 1 {
        return img.clone();
    }
    let (w, h) = img.dimensions();
    RgbImage::from_fn(w.div_ceil(k), h.div_ceil(k), |x, y| {
        let mut sum = [0u32; 3];
        let mut n = 0;
        for sy in y * k..((y + 1) * k).min(h) {
            for sx in x * k..((x + 1) * k).min(w) {
                let p = img.get(sx, sy);
                for c in 0..3 {
                    sum[c] += p[c] as u32;
                }
                n += 1;
            }
        }
        [0, 1, 2].map(|c| ((sum[c] + n / 2) / n) as u8)
    })
}

/// The smallest integer reduction that brings a row of images of these widths within `budget`.
pub fn reduction_for(widths: &[u32], budget: u32) -> u32 {
    let total: u32 = widths.iter().sum::<u32>() + GAP * widths.len().saturating_sub(1) as u32;
    total.div_ceil(budget.max(1)).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn find(sheet: &RgbImage, img: &RgbImage) -> Option<(u32, u32)> {
        for y0 in 0..=sheet.height().saturating_sub(img.height()) {
            for x0 in 0..=sheet.width().saturating_sub(img.width()) {
                if (0..img.height()).all(|y| (0..img.width()).all(|x| sheet.get(x0 + x, y0 + y) == img.get(x, y))) {
                    return Some((x0, y0));
                }
            }
        }
        None
    }

    #[test]
    fn images_are_pasted_unscaled_left_to_right_with_captions_below() {
        let a = RgbImage::from_fn(40, 30, |x, y| [x as u8 * 5, y as u8 * 7, 9]);
        let b = RgbImage::from_fn(60, 50, |x, y| [200, x as u8, y as u8 * 3]);
        let rows = vec![vec![
            Some(Cell { picture: Picture::Image(a.clone()), caption: vec!["sample".into()] }),
            Some(Cell { picture: Picture::Image(b.clone()), caption: vec!["quilting".into(), "block=20".into()] }),
        ]];
        let sheet = compose("title", &rows, false);
        let pa = find(&sheet, &a).expect("sample pasted 1:1");
        let pb = find(&sheet, &b).expect("output pasted 1:1");
        assert_eq!(pa.1, pb.1, "same row");
        assert!(pb.0 >= pa.0 + MIN_CELL_WIDTH, "second cell to the right of the first");
        // Caption ink directly under each image.
        let ink_below = |x0: u32, y0: u32, w: u32| (y0..y0 + 20).any(|y| (x0..x0 + w).any(|x| sheet.get(x, y) != BACKGROUND));
        assert!(ink_below(pa.0, pa.1 + 30 + CAPTION_GAP, 40));
        assert!(ink_below(pb.0, pb.1 + 50 + CAPTION_GAP, 60));
    }

    #[test]
    fn flow_wraps_wide_rows() {
        let cell = |w| Cell { picture: Picture::Missing { width: w, height: 10, why: "gone".into() }, caption: vec![] };
        let rows = flow(vec![cell(300), cell(300), cell(300)], 700);
        assert_eq!(rows.iter().map(Vec::len).collect::<Vec<_>>(), [2, 1]);
    }

    #[test]
    fn thumbnails_stay_at_least_the_minimum_side_and_pages_split_rows() {
        for (w, h) in [(1280, 1280), (384, 256), (768, 100), (255, 255), (129, 40)] {
            let k = thumbnail_factor(w, h, 128);
            let side = w.max(h).div_ceil(k);
            assert!((128..256).contains(&side), "{w}×{h}: 1:{k} gives {side}");
        }
        assert_eq!(thumbnail_factor(100, 60, 128), 1, "small images stay 1:1");
        let row = || vec![Some(Cell { picture: Picture::Image(RgbImage::new(100, 100)), caption: vec!["x".into()] })];
        let pages = paginate((0..7).map(|_| row()).collect(), 400);
        assert!(pages.len() > 1 && pages.iter().all(|p| !p.is_empty()));
        assert_eq!(pages.iter().map(Vec::len).sum::<usize>(), 7, "no row lost");
    }

    #[test]
    fn downscale_averages_blocks() {
        let img = RgbImage::from_fn(4, 3, |x, _| if x % 2 == 0 { [0, 0, 0] } else { [200, 100, 50] });
        let d = downscale(&img, 2);
        assert_eq!(d.dimensions(), (2, 2));
        assert_eq!(d.get(0, 0), [100, 50, 25]);
        assert_eq!(reduction_for(&[1000, 1000], 1016), 2);
        assert_eq!(reduction_for(&[100], 1000), 1);
    }
}
