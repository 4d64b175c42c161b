//! Plots as hand-written SVG: synthesis time against output size, one colour per group.
//!
//! Scaling claims ("the speed-up grows with the block size") are read off a plot, not a table.
//! SVG keeps the page self-contained and needs no plotting dependency; every point carries its
//! job id and exact values as attributes so it can be checked against the manifest.

use super::fmt;
use super::model::Model;

/// The plotting area; the legend goes underneath, one line per group, so long labels (a method
/// with several varying parameters) never get cut off.
const PLOT_W: f64 = 600.0;
const PLOT_H: f64 = 340.0;
const LEFT: f64 = 70.0;
const RIGHT: f64 = 30.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 56.0;
const LEGEND_LINE: f64 = 20.0;

/// An SVG document and its size in CSS pixels (for the page's `<img>`).
pub struct Svg {
    pub text: String,
    pub width: f64,
    pub height: f64,
}

/// Colour-blind-friendly palette (Okabe–Ito), cycled.
const PALETTE: [&str; 8] = ["#0072B2", "#E69F00", "#009E73", "#D55E00", "#CC79A7", "#56B4E9", "#F0E442", "#000000"];

pub fn colour(group: usize) -> &'static str {
    PALETTE[group % PALETTE.len()]
}

/// Round tick steps (1, 2, 5 × 10^k) covering `0..=max` with about five intervals.
pub fn ticks(max: f64) -> Vec<f64> {
    if max.is_nan() || max <= 0.0 || !max.is_finite() {
        return vec![0.0, 1.0];
    }
    let raw = max / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let n = (max / step).ceil() as usize;
    (0..=n).map(|i| i as f64 * step).collect()
}

fn tick_label(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e6 {
        format!("{}M", fmt::sig(v / 1e6).trim_end_matches('0').trim_end_matches('.'))
    } else if v.abs() >= 1e3 {
        format!("{}k", fmt::sig(v / 1e3).trim_end_matches('0').trim_end_matches('.'))
    } else {
        let s = fmt::sig(v);
        if s.contains('.') && !s.contains('e') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
    }
}

/// Time (s) vs output pixels for every counted job that has both, plus each group's mean per
/// output size joined by a line.
pub fn time_vs_pixels(model: &Model) -> Svg {
    let points: Vec<(usize, &str, u64, f64)> = model
        .entries
        .iter()
        .filter_map(|e| {
            let o = e.output.as_ref()?;
            Some((e.group, e.job_id.as_str(), o.width as u64 * o.height as u64, e.synthesis_seconds?))
        })
        .collect();
    let xmax = points.iter().map(|p| p.2 as f64).fold(0.0, f64::max);
    let ymax = points.iter().map(|p| p.3).fold(0.0, f64::max);
    // Headroom, so the largest point does not sit on the frame.
    let (xt, yt) = (ticks(xmax * 1.05), ticks(ymax * 1.05));
    let (xend, yend) = (*xt.last().unwrap(), *yt.last().unwrap());
    let (pw, ph) = (PLOT_W, PLOT_H);
    // A generous estimate of the legend's text width (12 px font), so it always fits.
    let legend_w = model.groups.iter().map(|g| g.label.chars().count() as f64 * 7.5 + 30.0).fold(0.0, f64::max);
    let width = (LEFT + pw + RIGHT).max(LEFT + legend_w + RIGHT).ceil();
    let height = TOP + ph + BOTTOM + LEGEND_LINE * model.groups.len() as f64 + 10.0;
    let legend_top = TOP + ph + BOTTOM;
    let sx = |x: f64| LEFT + x / xend * pw;
    let sy = |y: f64| TOP + ph - y / yend * ph;

    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" viewBox=\"0 0 {width} {height}\" \
         font-family=\"DejaVu Sans, Verdana, sans-serif\" font-size=\"12\" data-plot=\"time_vs_pixels\">\n\
         <rect width=\"{width}\" height=\"{height}\" fill=\"white\"/>\n\
         <text x=\"{LEFT}\" y=\"24\" font-size=\"15\">Synthesis time vs output size</text>\n"
    );
    for &v in &xt {
        let x = sx(v);
        s.push_str(&format!(
            "<line x1=\"{x:.1}\" y1=\"{TOP}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#e4e4e4\"/>\
             <text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n",
            TOP + ph,
            TOP + ph + 18.0,
            tick_label(v)
        ));
    }
    for &v in &yt {
        let y = sy(v);
        s.push_str(&format!(
            "<line x1=\"{LEFT}\" y1=\"{y:.1}\" x2=\"{:.1}\" y2=\"{y:.1}\" stroke=\"#e4e4e4\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>\n",
            LEFT + pw,
            LEFT - 6.0,
            y + 4.0,
            tick_label(v)
        ));
    }
    s.push_str(&format!(
        "<rect x=\"{LEFT}\" y=\"{TOP}\" width=\"{pw}\" height=\"{ph}\" fill=\"none\" stroke=\"#444\"/>\n\
         <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">output size (pixels)</text>\n\
         <text transform=\"translate(18 {:.1}) rotate(-90)\" text-anchor=\"middle\">synthesis time (s)</text>\n",
        LEFT + pw / 2.0,
        TOP + ph + 40.0,
        TOP + ph / 2.0
    ));
    if points.is_empty() {
        s.push_str(&format!(
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">no job recorded a synthesis time</text>\n",
            LEFT + pw / 2.0,
            TOP + ph / 2.0
        ));
    }
    for (g, group) in model.groups.iter().enumerate() {
        let mine: Vec<&(usize, &str, u64, f64)> = points.iter().filter(|p| p.0 == g).collect();
        if mine.is_empty() {
            continue;
        }
        let mut sizes: Vec<u64> = mine.iter().map(|p| p.2).collect();
        sizes.sort();
        sizes.dedup();
        let means: Vec<(f64, f64)> = sizes
            .iter()
            .map(|&px| {
                let ts: Vec<f64> = mine.iter().filter(|p| p.2 == px).map(|p| p.3).collect();
                (px as f64, ts.iter().sum::<f64>() / ts.len() as f64)
            })
            .collect();
        if means.len() > 1 {
            let pts: Vec<String> = means.iter().map(|(x, y)| format!("{:.1},{:.1}", sx(*x), sy(*y))).collect();
            s.push_str(&format!(
                "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\" opacity=\"0.7\"/>\n",
                pts.join(" "),
                colour(g)
            ));
        }
        for p in mine {
            s.push_str(&format!(
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"4\" fill=\"{}\" fill-opacity=\"0.75\" data-job=\"{}\" data-pixels=\"{}\" \
                 data-seconds=\"{}\"><title>{}: {} px, {} s</title></circle>\n",
                sx(p.2 as f64),
                sy(p.3),
                colour(g),
                fmt::html(p.1),
                p.2,
                fmt::full(p.3),
                fmt::html(p.1),
                p.2,
                fmt::sig(p.3)
            ));
        }
        let ly = legend_top + 6.0 + g as f64 * LEGEND_LINE;
        let lx = LEFT + 6.0;
        s.push_str(&format!(
            "<circle cx=\"{lx:.1}\" cy=\"{ly:.1}\" r=\"5\" fill=\"{}\"/><text x=\"{:.1}\" y=\"{:.1}\">{}</text>\n",
            colour(g),
            lx + 10.0,
            ly + 4.0,
            fmt::html(&group.label)
        ));
    }
    s.push_str("</svg>\n");
    Svg { text: s, width, height }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_maximum() {
        assert_eq!(ticks(583_696.0), vec![0.0, 200_000.0, 400_000.0, 600_000.0]);
        assert_eq!(ticks(0.37), vec![0.0, 0.1, 0.2, 0.30000000000000004, 0.4]);
        assert_eq!(ticks(0.0), vec![0.0, 1.0]);
        assert_eq!(tick_label(200_000.0), "200k");
        assert_eq!(tick_label(1_500_000.0), "1.5M");
        assert_eq!(tick_label(0.2), "0.2");
    }
}
