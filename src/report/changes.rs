//! What changed since an earlier run, as pictures: for every job whose pixels changed, the old
//! output, the new one and a map of where they differ, all at 1:1.
//!
//! `texsyn diff` says *that* and *why* a job's pixels changed; a reader still has to see whether
//! the change is a regression. The old images are read from where the old manifest recorded them
//! and shown only if their pixels are the ones it recorded: a nightly run that wrote into the same
//! directory has overwritten them, and the page says so instead of showing the new image twice.

use super::fmt::html as h;
use super::html::ImageRef;
use crate::batch::diff::{KeyChange, describe_changes};
use crate::image::RgbImage;

/// At most this many changed jobs get picture panels; the rest are listed (a changed algorithm
/// can change every job, and hundreds of 1:1 triples help nobody).
pub const MAX_PANELS: usize = 40;

/// How two images of one size differ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeatStats {
    pub changed: u64,
    pub pixels: u64,
    /// Largest difference of one channel, 0..=255.
    pub max: u8,
}

/// The difference map: unchanged pixels in a dim grey rendering of the new image (so the
/// structure stays recognisable), changed ones from yellow (1 level) to red (64 levels or more).
pub fn heatmap(old: &RgbImage, new: &RgbImage) -> Option<(RgbImage, HeatStats)> {
    if old.dimensions() != new.dimensions() {
        return None;
    }
    let mut stats = HeatStats { changed: 0, pixels: new.width() as u64 * new.height() as u64, max: 0 };
    let img = RgbImage::from_fn(new.width(), new.height(), |x, y| {
        let (a, b) = (old.get(x, y), new.get(x, y));
        let d = (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0);
        if d == 0 {
            let luma = (b[0] as u32 * 299 + b[1] as u32 * 587 + b[2] as u32 * 114) / 1000;
            let v = (24 + luma / 5) as u8;
            return [v, v, v];
        }
        stats.changed += 1;
        stats.max = stats.max.max(d);
        let t = (d as f32 / 64.0).min(1.0);
        [255, (230.0 * (1.0 - t)).round() as u8, 0]
    });
    Some((img, stats))
}

/// One changed output: its three panels.
pub struct Panel {
    pub output: String,
    pub old: ImageRef,
    pub new: ImageRef,
    pub heat: Result<(String, u32, u32, HeatStats), String>,
}

/// One changed job.
pub struct Changed {
    pub id: String,
    pub because: Vec<KeyChange>,
    /// Where the change was found (`--since` or `--golden`).
    pub source: &'static str,
    pub panels: Vec<Panel>,
}

fn figure(r: &ImageRef, role: &str, caption: &str) -> String {
    let body = match r {
        Ok((src, w, hgt)) => format!("<img src=\"{}\" width=\"{w}\" height=\"{hgt}\" alt=\"{role}\">", h(src)),
        Err(why) => format!("<span class=\"missing\" data-gone=\"1\">{}</span>", h(why)),
    };
    format!("<figure data-panel=\"{role}\">{body}<figcaption><b>{role}</b> {}</figcaption></figure>", h(caption))
}

/// The section of changed jobs, panels first, then those beyond [`MAX_PANELS`] as a list.
pub fn html(changed: &[Changed], beyond: &[(String, String)], since: Option<&str>) -> String {
    let mut out = String::from("<section id=\"changes\">\n<h2>Pixels changed</h2>\n");
    let what = since.map_or("against the golden digests".to_string(), |s| format!("since <code>{}</code>", h(s)));
    out.push_str(&format!(
        "<p>{} jobs changed pixels {what}. For each: the old output, the new one and where they differ (grey: same pixel; \
         yellow to red: a channel differs by 1 to 64 or more levels), all at 1:1.</p>\n",
        changed.len() + beyond.len()
    ));
    for c in changed {
        out.push_str(&format!(
            "<div class=\"change\" data-job=\"{}\" data-source=\"{}\"><h3>{}</h3><p class=\"why\">why: {}</p>\n",
            h(&c.id),
            c.source,
            h(&c.id),
            h(&describe_changes(&c.because))
        ));
        for p in &c.panels {
            out.push_str(&format!("<div class=\"row\" data-output=\"{}\">", h(&p.output)));
            out.push_str(&figure(&p.old, "old", &p.output));
            out.push_str(&figure(&p.new, "new", &p.output));
            let heat = match &p.heat {
                Ok((src, w, hgt, s)) => {
                    let caption = format!(
                        "{} of {} pixels differ ({:.2} %), largest channel difference {}",
                        s.changed,
                        s.pixels,
                        100.0 * s.changed as f64 / s.pixels.max(1) as f64,
                        s.max
                    );
                    format!(
                        "<figure data-panel=\"difference\" data-changed=\"{}\" data-max=\"{}\"><img src=\"{}\" width=\"{w}\" height=\"{hgt}\" \
                         alt=\"difference\"><figcaption><b>difference</b> {}</figcaption></figure>",
                        s.changed,
                        s.max,
                        h(src),
                        h(&caption)
                    )
                }
                Err(why) => figure(&Err(why.clone()), "difference", ""),
            };
            out.push_str(&heat);
            out.push_str("</div>\n");
        }
        out.push_str("</div>\n");
    }
    if !beyond.is_empty() {
        out.push_str(&format!(
            "<details><summary>{} more changed jobs (panels are drawn for the first {MAX_PANELS})</summary><table><thead>\
             <tr><th>job</th><th>why</th></tr></thead><tbody>\n",
            beyond.len()
        ));
        for (id, why) in beyond {
            out.push_str(&format!("<tr data-job=\"{}\"><td class=\"text\">{}</td><td class=\"text\">{}</td></tr>\n", h(id), h(id), h(why)));
        }
        out.push_str("</tbody></table></details>\n");
    }
    out.push_str("</section>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heatmap_marks_exactly_the_changed_pixels() {
        let old = RgbImage::from_fn(4, 3, |x, y| [(x * 10) as u8, (y * 10) as u8, 7]);
        let mut new = old.clone();
        new.put(1, 1, [10, 10, 8]);
        new.put(3, 2, [200, 20, 7]);
        let (map, s) = heatmap(&old, &new).unwrap();
        assert_eq!(s, HeatStats { changed: 2, pixels: 12, max: 170 });
        assert_eq!(map.get(3, 2), [255, 0, 0], "a large difference is red");
        assert_eq!(map.get(1, 1)[0], 255, "a one-level difference is still marked");
        assert!(map.get(1, 1)[1] > 200, "…in yellow");
        let grey = map.get(0, 0);
        assert!(grey[0] == grey[1] && grey[1] == grey[2], "unchanged pixels are grey");
        assert!(heatmap(&old, &RgbImage::from_fn(2, 2, |_, _| [0; 3])).is_none(), "no map across sizes");
    }
}
