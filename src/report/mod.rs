//! `texsyn report MANIFEST -o DIR`: a paper's tables, contact sheets, plot and HTML page, made
//! from a manifest alone.
//!
//! Figures assembled by hand are where comparisons stop being reproducible; here they are a pure
//! function of the manifest (numbers) and the images it points to (pictures), so anyone holding a
//! run's output directory regenerates them with one command. The pipeline: [`model`] decides which
//! jobs count and how they group, [`tables`] summarises, [`sheet`] and [`font`] draw the contact
//! sheets, [`plot`] the SVG plot, [`html`] the page; this file loads images and writes the files.
//!
//! Every file goes through the output-directory layer (atomic renames, no writes outside DIR, no
//! writes through symlinks), and never over a file the manifest refers to.

mod fmt;
pub mod font;
pub mod html;
pub mod model;
pub mod plot;
pub mod sheet;
pub mod tables;

pub use model::{GroupBy, GroupKey};

use crate::batch::manifest::Manifest;
use crate::batch::outdir::OutDir;
use crate::error::Error;
use crate::image::RgbImage;
use crate::image::io::{self as imageio, DecodeLimits, Encoding, Format};
use html::{Assets, ImageRef, Shown};
use rayon::prelude::*;
use sheet::{Cell, Picture};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Widest per-sample contact sheet before cells wrap to a new row.
const SHEET_MAX_WIDTH: u32 = 4000;
/// Width the overview's images are reduced to fit (by one integer factor for all).
const OVERVIEW_BUDGET: u32 = 2400;

pub struct ReportOptions {
    pub manifest: PathBuf,
    pub out: PathBuf,
    pub group_by: GroupBy,
    /// A method to compare the others' times with (`tes` for paper 000's Table 2): adds speed-up
    /// tables (`tables/speedup_*.csv` and a section of `tables.md`).
    pub baseline: Option<String>,
}

/// What was written, and what could not be shown.
#[derive(Debug)]
pub struct ReportSummary {
    pub index: PathBuf,
    pub files: Vec<String>,
    pub counted: usize,
    pub excluded: usize,
    /// Images that were missing, undecodable or not the pixels the manifest recorded. The report
    /// is still complete otherwise; the CLI exits 1.
    pub problems: Vec<String>,
}

/// Loads an image and checks it is the one the manifest recorded, so a picture never contradicts
/// the numbers next to it.
fn load(path: &Path, expected_sha256: &str, as_sample: bool) -> Result<RgbImage, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let native = imageio::decode_native(&bytes, DecodeLimits::default()).map_err(|e| format!("{}: {e}", path.display()))?;
    let rgb = imageio::native_to_rgb8(&native);
    // Samples are recorded by the 8-bit pixels the method saw; outputs by their stored samples.
    let digest = if as_sample { imageio::rgb_pixel_digest(&rgb) } else { native.pixel_digest() };
    if digest.sha256 != expected_sha256 {
        return Err(format!("{}: pixels differ from the manifest's record (changed since the run? see `texsyn verify`)", path.display()));
    }
    Ok(rgb)
}

/// Encodes a picture of the report at `rel` (named in the error).
fn png(img: &RgbImage, rel: &str) -> Result<Vec<u8>, Error> {
    let encoded =
        imageio::encode(img, Encoding { format: Format::Png, bit_depth: 8 }).map_err(|source| Error::Image { path: rel.into(), source })?;
    Ok(encoded.bytes)
}

/// Distinct file-name stems for the samples, in row order.
fn unique_stems(keys: impl Iterator<Item = String>) -> Vec<String> {
    let mut used = BTreeSet::new();
    keys.map(|k| {
        let base = fmt::file_stem(&k);
        let mut name = base.clone();
        let mut i = 2;
        while !used.insert(name.clone()) {
            name = format!("{base}-{i}");
            i += 1;
        }
        name
    })
    .collect()
}

/// Writes into the report directory, refusing to replace anything the manifest refers to.
struct Writer {
    dir: OutDir,
    protected: BTreeSet<PathBuf>,
    written: Vec<String>,
}

impl Writer {
    fn put(&mut self, rel: &str, bytes: &[u8]) -> Result<(), Error> {
        let path = self.dir.resolve(rel)?;
        if path.canonicalize().is_ok_and(|c| self.protected.contains(&c)) {
            return Err(Error::Containment {
                path,
                reason: "is a file the manifest refers to; write the report to a directory of its own".into(),
            });
        }
        crate::batch::outdir::write_atomic(&path, bytes)?;
        self.written.push(rel.to_string());
        Ok(())
    }
}

/// One overview row: a captioned picture per column, `None` where the group did not run on the sample.
type OverviewRow = Vec<Option<(Picture, Vec<String>)>>;

/// Per-sample results of the image stage, computed in parallel.
struct SampleImages {
    sample: ImageRef,
    shown: Vec<Shown>,
    sheet: (String, Vec<u8>),
    files: Vec<(String, Vec<u8>)>,
    /// For the overview: the pictures in column order (sample, then every group).
    overview: OverviewRow,
    problems: Vec<String>,
}

fn sample_images(m: &model::Model, s: usize, stem: &str) -> Result<SampleImages, Error> {
    let info = &m.samples[s];
    let mut problems = Vec::new();
    let mut files = Vec::new();
    let sample_pic = match load(&info.path, &info.pixel_digest, true) {
        Ok(img) => Picture::Image(img),
        Err(e) => {
            problems.push(e.clone());
            Picture::Missing { width: info.width, height: info.height, why: e }
        }
    };
    let sample_ref = match &sample_pic {
        Picture::Image(img) => {
            let rel = format!("images/samples/{stem}.png");
            files.push((rel.clone(), png(img, &rel)?));
            Ok((rel, img.width(), img.height()))
        }
        Picture::Missing { why, .. } => Err(why.clone()),
    };
    let sample_caption = vec![format!("sample {}", info.key), format!("{}×{}", info.width, info.height)];
    let mut cells = vec![Cell { picture: clone_picture(&sample_pic), caption: sample_caption.clone() }];
    let mut overview: OverviewRow = vec![Some((sample_pic, vec![info.key.clone(), format!("{}×{}", info.width, info.height)]))];
    let mut shown = Vec::new();
    for (g, group) in m.groups.iter().enumerate() {
        // The lowest seed stands for the column (job id breaks ties), so reruns pick the same one.
        let mut candidates: Vec<usize> =
            m.entries.iter().enumerate().filter(|(_, e)| e.sample == s && e.group == g && e.output.is_some()).map(|(i, _)| i).collect();
        candidates.sort_by(|&a, &b| (m.entries[a].seed, &m.entries[a].job_id).cmp(&(m.entries[b].seed, &m.entries[b].job_id)));
        let Some(&ei) = candidates.first() else {
            overview.push(None);
            continue;
        };
        let e = &m.entries[ei];
        let o = e.output.as_ref().expect("filtered on outputs");
        let pic = match load(&o.path, &o.pixel_digest, false) {
            Ok(img) => Picture::Image(img),
            Err(err) => {
                problems.push(err.clone());
                Picture::Missing { width: o.width, height: o.height, why: err }
            }
        };
        let image = match &pic {
            Picture::Image(img) => {
                let rel = format!("images/outputs/{stem}/{:02}-{}.png", g + 1, fmt::file_stem(&group.label));
                files.push((rel.clone(), png(img, &rel)?));
                Ok((rel, img.width(), img.height()))
            }
            Picture::Missing { why, .. } => Err(why.clone()),
        };
        let n = candidates.len();
        let seed_line = match (e.seed, n) {
            (Some(sd), 1) => format!("seed {sd} · {}×{}", o.width, o.height),
            (Some(sd), n) => format!("seed {sd} (1 of {n}) · {}×{}", o.width, o.height),
            (None, _) => format!("{}×{}", o.width, o.height),
        };
        let mut caption = vec![group.label.clone()];
        if !group.params_label.is_empty() {
            caption.push(group.params_label.clone());
        }
        caption.push(seed_line);
        cells.push(Cell { picture: clone_picture(&pic), caption });
        overview.push(Some((pic, vec![group.label.clone()])));
        shown.push(Shown { group: g, entry: ei, image });
    }
    let title = format!("{}: the sample, then one output per column, all at 1:1 pixels. Columns: {}", info.key, m.grouping);
    let sheet_img = sheet::compose(&title, &sheet::flow(cells, SHEET_MAX_WIDTH), false);
    let rel = format!("sheets/{stem}.png");
    let sheet = (rel.clone(), png(&sheet_img, &rel)?);
    Ok(SampleImages { sample: sample_ref, shown, sheet, files, overview, problems })
}

fn clone_picture(p: &Picture) -> Picture {
    match p {
        Picture::Image(i) => Picture::Image(i.clone()),
        Picture::Missing { width, height, why } => Picture::Missing { width: *width, height: *height, why: why.clone() },
    }
}

fn overview_sheet(m: &model::Model, rows: Vec<OverviewRow>) -> Result<Vec<u8>, Error> {
    let ncols = m.groups.len() + 1;
    let widths: Vec<u32> = (0..ncols)
        .map(|c| {
            rows.iter()
                .filter_map(|r| match r.get(c)? {
                    Some((Picture::Image(i), _)) => Some(i.width()),
                    Some((Picture::Missing { width, .. }, _)) => Some(*width),
                    None => None,
                })
                .max()
                .unwrap_or(0)
        })
        .collect();
    let k = sheet::reduction_for(&widths, OVERVIEW_BUDGET);
    let cells: Vec<Vec<Option<Cell>>> = rows
        .into_iter()
        .map(|r| {
            r.into_iter()
                .map(|c| {
                    c.map(|(pic, caption)| {
                        let picture = match pic {
                            Picture::Image(i) => Picture::Image(sheet::downscale(&i, k)),
                            Picture::Missing { width, height, why } => {
                                Picture::Missing { width: width.div_ceil(k), height: height.div_ceil(k), why }
                            }
                        };
                        Cell { picture, caption }
                    })
                })
                .collect()
        })
        .collect();
    let scale = if k == 1 { "1:1 pixels".to_string() } else { format!("every image reduced 1:{k}") };
    let title = format!("Overview: one row per sample, the sample then one output per column; {scale}. Columns: {}", m.grouping);
    png(&sheet::compose(&title, &cells, true), "sheets/overview.png")
}

/// Builds the report. Errors (exit 2) are a manifest that cannot be read or a directory that
/// cannot be written; images that cannot be shown are `problems` in the summary instead.
pub fn report(opts: &ReportOptions) -> Result<ReportSummary, Error> {
    let manifest = Manifest::load(&opts.manifest)?;
    let base = opts.manifest.parent().map(Path::to_path_buf).unwrap_or_default();
    let base = if base.as_os_str().is_empty() { PathBuf::from(".") } else { base };
    let m = model::build(&manifest, &base, &opts.group_by);

    let mut protected = BTreeSet::new();
    let mut protect = |p: PathBuf| {
        if let Ok(c) = p.canonicalize() {
            protected.insert(c);
        }
    };
    protect(opts.manifest.clone());
    for j in &manifest.jobs {
        if let Some(s) = &j.sample {
            protect(base.join(&s.path));
        }
        for o in &j.outputs {
            protect(base.join(&o.path));
        }
    }
    let mut w = Writer { dir: OutDir::open(&opts.out)?, protected, written: Vec::new() };

    let stems = unique_stems(m.samples.iter().map(|s| s.key.clone()));
    let per_sample: Vec<SampleImages> =
        (0..m.samples.len()).into_par_iter().map(|s| sample_images(&m, s, &stems[s])).collect::<Result<_, _>>()?;

    let mut problems = Vec::new();
    let mut assets = Assets {
        samples: Vec::new(),
        shown: Vec::new(),
        sheets: Vec::new(),
        overview: None,
        plot: "plots/time_vs_pixels.svg".into(),
        plot_size: (0.0, 0.0),
        markdown: "tables.md".into(),
        csvs: Vec::new(),
        csv_all: "tables/all.csv".into(),
        jobs_csv: "jobs.csv".into(),
    };
    let mut overview_rows = Vec::new();
    for si in per_sample {
        for (rel, bytes) in &si.files {
            w.put(rel, bytes)?;
        }
        w.put(&si.sheet.0, &si.sheet.1)?;
        assets.sheets.push(si.sheet.0);
        assets.samples.push(si.sample);
        assets.shown.push(si.shown);
        problems.extend(si.problems);
        overview_rows.push(si.overview);
    }
    if !m.samples.is_empty() {
        let bytes = overview_sheet(&m, overview_rows)?;
        w.put("sheets/overview.png", &bytes)?;
        assets.overview = Some("sheets/overview.png".into());
    }
    let svg = plot::time_vs_pixels(&m);
    assets.plot_size = (svg.width, svg.height);
    w.put(&assets.plot.clone(), svg.text.as_bytes())?;

    let source = opts.manifest.display().to_string();
    let tables = tables::build(&m);
    let mut csv_names: BTreeMap<String, usize> = BTreeMap::new();
    for t in &tables {
        let stem = fmt::file_stem(&t.measure);
        let n = csv_names.entry(stem.clone()).or_default();
        *n += 1;
        let rel = if *n == 1 { format!("tables/{stem}.csv") } else { format!("tables/{stem}-{n}.csv") };
        w.put(&rel, tables::csv(&m, t).as_bytes())?;
        assets.csvs.push((t.measure.clone(), rel));
    }
    w.put(&assets.csv_all.clone(), tables::csv_all(&m, &tables).as_bytes())?;
    w.put(&assets.jobs_csv.clone(), tables::jobs_csv(&m).as_bytes())?;
    let mut markdown = tables::markdown(&m, &tables, &source);
    if let Some(baseline) = &opts.baseline {
        if !m.groups.iter().any(|g| g.method.as_deref() == Some(baseline.as_str())) {
            problems.push(format!("--baseline {baseline}: no counted job of that method; no speed-up tables"));
        }
        let speedups = tables::speedups(&m, &tables, baseline);
        for t in &speedups {
            let rel = format!("tables/speedup_{}.csv", fmt::file_stem(&t.measure));
            w.put(&rel, tables::speedup_csv(&m, t).as_bytes())?;
        }
        markdown.push_str(&tables::speedup_markdown(&m, &speedups));
    }
    w.put(&assets.markdown.clone(), markdown.as_bytes())?;

    let digest_ok = manifest.recompute_digest() == manifest.deterministic_digest;
    if !digest_ok {
        problems.push(format!("{source}: the deterministic digest does not match the content (edited after the run?)"));
    }
    // Last, so a reader never opens a page whose files are not all there yet.
    w.put("index.html", html::page(&m, &tables, &assets, &manifest, &source, digest_ok, &problems).as_bytes())?;
    Ok(ReportSummary {
        index: opts.out.join("index.html"),
        files: w.written,
        counted: m.entries.len(),
        excluded: m.excluded.len(),
        problems,
    })
}
