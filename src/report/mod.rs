//! `texsyn report MANIFEST -o DIR`: the page a nightly run's reader opens in the morning, and a
//! paper's tables, contact sheets and plot, made from a manifest alone.
//!
//! Figures assembled by hand are where comparisons stop being reproducible; here they are a pure
//! function of the manifest (numbers) and the images it points to (pictures), so anyone holding a
//! run's output directory regenerates them with one command. The pipeline: [`sections`] cuts the
//! manifest by job directory, [`model`] decides which jobs of a section count and how they group,
//! [`tables`] summarises, [`sheet`] and [`font`] draw the contact sheets, [`plot`] the SVG plot,
//! [`summary`] and [`changes`] lead the page with what failed and what changed, [`html`] writes
//! it; this file loads images and writes the files.
//!
//! Every file goes through the output-directory layer (atomic renames, no writes outside DIR, no
//! writes through symlinks), and never over a file the manifest refers to. The report lists what
//! it wrote in `.texsyn-report`, and the next report into the same directory removes what it no
//! longer writes, so a page never sits among stale pictures of an older run.

mod changes;
mod fmt;
pub mod font;
pub mod html;
pub mod model;
pub mod plot;
mod sections;
pub mod sheet;
mod summary;
pub mod tables;

pub use model::{GroupBy, GroupKey};
pub use sections::Sections;

use crate::batch::diff::{self, Diff, Thresholds};
use crate::batch::golden::{self, CheckReport};
use crate::batch::manifest::Manifest;
use crate::batch::outdir::OutDir;
use crate::error::Error;
use crate::image::RgbImage;
use crate::image::io::{self as imageio, DecodeLimits, Encoding, Format};
use html::{Assets, ImageRef, Part, Shown};
use rayon::prelude::*;
use sections::Section;
use sheet::{Cell, Picture};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Widest per-sample contact sheet before cells wrap to a new row.
const SHEET_MAX_WIDTH: u32 = 4000;
/// The overview's pages: at most this wide and (but for one tall row) this high.
const OVERVIEW_WIDTH: u32 = 2000;
const OVERVIEW_PAGE_HEIGHT: u32 = 2000;
/// Overview thumbnails are reduced by an integer factor to a longer side of at least this.
const THUMB_MIN_SIDE: u32 = 128;
/// The list of files the last report wrote into its directory.
const LISTING: &str = ".texsyn-report";

pub struct ReportOptions {
    pub manifest: PathBuf,
    pub out: PathBuf,
    pub group_by: GroupBy,
    /// A method to compare the others' times with (`tes` for paper 000's Table 2): adds speed-up
    /// tables (`tables/speedup_*.csv` and a section of `tables.md`).
    pub baseline: Option<String>,
    /// An earlier run's manifest: the page leads with what changed since, with old | new |
    /// difference panels for every job whose pixels changed.
    pub since: Option<PathBuf>,
    /// A golden directory (`golden/`): the page says which outputs differ from it.
    pub golden: Option<PathBuf>,
    pub sections: Sections,
}

impl ReportOptions {
    pub fn new(manifest: impl Into<PathBuf>, out: impl Into<PathBuf>) -> ReportOptions {
        ReportOptions {
            manifest: manifest.into(),
            out: out.into(),
            group_by: GroupBy::default(),
            baseline: None,
            since: None,
            golden: None,
            sections: Sections::default(),
        }
    }
}

/// What was written, and what could not be shown.
#[derive(Debug)]
pub struct ReportSummary {
    pub index: PathBuf,
    pub files: Vec<String>,
    pub counted: usize,
    pub excluded: usize,
    pub sections: usize,
    /// With `--since`: jobs whose pixels changed.
    pub pixels_changed: Option<usize>,
    /// Files of the previous report in the directory that this one no longer writes, removed.
    pub removed: Vec<String>,
    /// Images that were missing, undecodable or not the pixels the manifest recorded. The report
    /// is still complete otherwise; the CLI exits 1.
    pub problems: Vec<String>,
}

/// Loads an image and checks it is the one the manifest recorded, so a picture never contradicts
/// the numbers next to it.
fn load(path: &Path, expected_sha256: &str, as_sample: bool) -> Result<RgbImage, String> {
    let bytes = crate::files::read_limited(path, crate::files::MAX_IMAGE_FILE_BYTES)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let native = imageio::decode_native(&bytes, DecodeLimits::default()).map_err(|e| format!("{}: {e}", path.display()))?;
    let rgb = imageio::native_to_rgb8(&native);
    // Outputs and samples are recorded by their stored samples; manifests before native-precision
    // samples recorded a sample by the 8-bit pixels the method saw (the same for 8-bit RGB).
    let matches =
        native.pixel_digest().sha256 == expected_sha256 || (as_sample && imageio::rgb_pixel_digest(&rgb).sha256 == expected_sha256);
    if !matches {
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

/// The files an earlier report listed in `dir`; refuses a directory that holds a report page
/// this tool did not list (an older report, or someone else's page), whose files it cannot tell
/// from the user's.
fn previous_listing(dir: &Path) -> Result<Vec<String>, Error> {
    let listing = dir.join(LISTING);
    match crate::files::read_limited(&listing, crate::files::MAX_JSON_BYTES) {
        Ok(bytes) => Ok(String::from_utf8_lossy(&bytes).lines().map(str::to_string).filter(|l| !l.is_empty()).collect()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if dir.join("index.html").exists() {
                return Err(Error::Usage(format!(
                    "{} already holds a report page (index.html) without the list of its files ({LISTING}), so its stale \
                     files cannot be told from yours; remove the directory or write the report to another one",
                    dir.display()
                )));
            }
            Ok(Vec::new())
        }
        Err(e) => Err(Error::io(&listing, "read", e)),
    }
}

/// Removes the files of the previous report that this one did not write (never one the manifest
/// refers to), then the directories that became empty.
fn remove_stale(w: &Writer, previous: &[String], listing: &[String]) -> Vec<String> {
    let now: BTreeSet<&str> = listing.iter().map(String::as_str).chain([LISTING]).collect();
    let mut removed = Vec::new();
    for rel in previous {
        let safe = !rel.starts_with('/') && !rel.split('/').any(|c| c == ".." || c.is_empty());
        if !safe || now.contains(rel.as_str()) || !w.dir.root().join(rel).exists() {
            continue;
        }
        let Ok(path) = w.dir.resolve(rel) else { continue };
        let is_file = std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file());
        if !is_file || path.canonicalize().is_ok_and(|c| w.protected.contains(&c)) {
            continue;
        }
        if std::fs::remove_file(&path).is_ok() {
            removed.push(rel.clone());
            let mut dir = path.parent();
            while let Some(d) = dir {
                if d == w.dir.root() || std::fs::remove_dir(d).is_err() {
                    break;
                }
                dir = d.parent();
            }
        }
    }
    removed
}

/// Per-sample results of the image stage, computed in parallel.
struct SampleImages {
    sample: ImageRef,
    shown: Vec<Shown>,
    sheet: (String, Vec<u8>),
    files: Vec<(String, Vec<u8>)>,
    /// The overview's cells: the sample, then every counted job on it.
    thumbnails: Vec<Cell>,
    problems: Vec<String>,
}

/// A legible thumbnail of a picture, and its reduction.
fn thumbnail(p: &Picture) -> (Picture, u32) {
    match p {
        Picture::Image(i) => {
            let k = sheet::thumbnail_factor(i.width(), i.height(), THUMB_MIN_SIDE);
            (Picture::Image(sheet::downscale(i, k)), k)
        }
        Picture::Missing { width, height, why } => {
            let k = sheet::thumbnail_factor(*width, *height, THUMB_MIN_SIDE);
            (Picture::Missing { width: width.div_ceil(k), height: height.div_ceil(k), why: why.clone() }, k)
        }
    }
}

fn scale_text(k: u32) -> String {
    if k == 1 { "1:1".into() } else { format!("1:{k}") }
}

fn sample_images(m: &model::Model, s: usize, stem: &str, prefix: &str) -> Result<SampleImages, Error> {
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
            let rel = format!("{prefix}images/samples/{stem}.png");
            files.push((rel.clone(), png(img, &rel)?));
            Ok((rel, img.width(), img.height()))
        }
        Picture::Missing { why, .. } => Err(why.clone()),
    };
    let (thumb, k) = thumbnail(&sample_pic);
    let mut thumbnails = vec![Cell {
        picture: thumb,
        caption: vec![format!("sample {}", info.key), format!("{}×{} · {}", info.width, info.height, scale_text(k))],
    }];
    let sample_caption = vec![format!("sample {}", info.key), format!("{}×{}", info.width, info.height)];
    let mut cells = vec![Cell { picture: sample_pic, caption: sample_caption }];
    let mut shown = Vec::new();
    for (g, group) in m.groups.iter().enumerate() {
        // Every job of the column, lowest seed first (job id breaks ties): the first stands for
        // the column on the sheet and the page, all of them are on the overview.
        let mut members: Vec<usize> =
            m.entries.iter().enumerate().filter(|(_, e)| e.sample == s && e.group == g && e.output.is_some()).map(|(i, _)| i).collect();
        members.sort_by(|&a, &b| (m.entries[a].seed, &m.entries[a].job_id).cmp(&(m.entries[b].seed, &m.entries[b].job_id)));
        let n = members.len();
        for (rank, &ei) in members.iter().enumerate() {
            let e = &m.entries[ei];
            let o = e.output.as_ref().expect("filtered on outputs");
            let pic = match load(&o.path, &o.pixel_digest, false) {
                Ok(img) => Picture::Image(img),
                Err(err) => {
                    problems.push(err.clone());
                    Picture::Missing { width: o.width, height: o.height, why: err }
                }
            };
            let (thumb, k) = thumbnail(&pic);
            let seed = e.seed.map(|sd| format!("seed {sd} · ")).unwrap_or_default();
            thumbnails.push(Cell {
                picture: thumb,
                caption: vec![group.label.clone(), format!("{seed}{}×{} · {}", o.width, o.height, scale_text(k))],
            });
            if rank > 0 {
                continue;
            }
            let image = match &pic {
                Picture::Image(img) => {
                    let rel = format!("{prefix}images/outputs/{stem}/{:02}-{}.png", g + 1, fmt::file_stem(&group.label));
                    files.push((rel.clone(), png(img, &rel)?));
                    Ok((rel, img.width(), img.height()))
                }
                Picture::Missing { why, .. } => Err(why.clone()),
            };
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
            // Masks and guides first, then the output: input, mask or guide and result side by side.
            let mut inputs = Vec::new();
            for (k, (what, info)) in e.inputs.iter().enumerate() {
                let picture = match load(&info.path, &info.pixel_digest, true) {
                    Ok(img) => {
                        let rel =
                            format!("{prefix}images/outputs/{stem}/{:02}-{}-input-{}.png", g + 1, fmt::file_stem(&group.label), k + 1);
                        files.push((rel.clone(), png(&img, &rel)?));
                        inputs.push((what.clone(), info.recorded_path.clone(), Ok((rel, img.width(), img.height()))));
                        Picture::Image(img)
                    }
                    Err(err) => {
                        problems.push(err.clone());
                        inputs.push((what.clone(), info.recorded_path.clone(), Err(err.clone())));
                        Picture::Missing { width: info.width, height: info.height, why: err }
                    }
                };
                cells.push(Cell { picture, caption: vec![format!("{what} of {}", group.label)] });
            }
            cells.push(Cell { picture: pic, caption });
            // Companions (normal, gloss… maps) beside the output they share a placement with.
            let mut companions = Vec::new();
            for (k, (label, c)) in e.companions.iter().enumerate() {
                let shown_c = match load(&c.path, &c.pixel_digest, false) {
                    Ok(img) => {
                        let rel =
                            format!("{prefix}images/outputs/{stem}/{:02}-{}-companion-{}.png", g + 1, fmt::file_stem(&group.label), k + 1);
                        files.push((rel.clone(), png(&img, &rel)?));
                        Ok((rel, img.width(), img.height()))
                    }
                    Err(err) => {
                        problems.push(err.clone());
                        Err(err)
                    }
                };
                companions.push((label.clone(), shown_c));
            }
            shown.push(Shown { group: g, entry: ei, image, companions, inputs });
        }
    }
    let title = format!("{}: the sample, then one output per column, all at 1:1 pixels. Columns: {}", info.key, m.grouping);
    let sheet_img = sheet::compose(&title, &sheet::flow(cells, SHEET_MAX_WIDTH), false);
    let rel = format!("{prefix}sheets/{stem}.png");
    let sheet = (rel.clone(), png(&sheet_img, &rel)?);
    Ok(SampleImages { sample: sample_ref, shown, sheet, files, thumbnails, problems })
}

/// The overview: every counted job's output as a thumbnail, a row (or more) per sample, in pages
/// at most [`OVERVIEW_WIDTH`] wide.
fn overview_pages(title: &str, per_sample: Vec<Vec<Cell>>) -> Vec<RgbImage> {
    let content = OVERVIEW_WIDTH - 2 * 16;
    let rows: Vec<Vec<Option<Cell>>> = per_sample.into_iter().flat_map(|cells| sheet::flow(cells, content)).collect();
    let pages = sheet::paginate(rows, OVERVIEW_PAGE_HEIGHT);
    let n = pages.len();
    pages
        .into_iter()
        .enumerate()
        .map(|(i, rows)| {
            let page = if n > 1 { format!(" (page {} of {n})", i + 1) } else { String::new() };
            let t = format!(
                "{title}{page}: every counted job, a row per sample (the sample first), images reduced by an integer factor to about \
                 {THUMB_MIN_SIDE} px where larger (scale under each)"
            );
            sheet::compose(&t, &rows, false)
        })
        .collect()
}

/// One section's tables, pictures and page assets, its files written.
struct SectionOut {
    title: Option<String>,
    model: model::Model,
    tables: Vec<tables::Table>,
    assets: Assets,
    markdown: String,
}

fn build_section(
    manifest: &Manifest,
    sec: &Section,
    multi: bool,
    base: &Path,
    opts: &ReportOptions,
    w: &mut Writer,
    problems: &mut Vec<String>,
) -> Result<SectionOut, Error> {
    let sub = Manifest {
        format: manifest.format.clone(),
        tool: manifest.tool.clone(),
        deterministic_digest: manifest.deterministic_digest.clone(),
        jobs: sec.jobs.iter().map(|&i| manifest.jobs[i].clone()).collect(),
        run: manifest.run.clone(),
    };
    let m = model::build(&sub, base, &opts.group_by);
    let slug = fmt::file_stem(&sec.name.replace('/', "_"));
    let prefix = if multi { format!("sections/{slug}/") } else { String::new() };
    let anchor = if multi { format!("section-{slug}-") } else { String::new() };
    let mut assets = Assets {
        samples: Vec::new(),
        shown: Vec::new(),
        sheets: Vec::new(),
        overview: Vec::new(),
        anchor,
        plot: format!("{prefix}plots/time_vs_pixels.svg"),
        plot_size: (0.0, 0.0),
        markdown: "tables.md".into(),
        csvs: Vec::new(),
        csv_all: format!("{prefix}tables/all.csv"),
        jobs_csv: format!("{prefix}jobs.csv"),
    };
    let title = multi.then(|| sec.title());
    if m.entries.is_empty() && multi {
        // Only failed or invalid jobs: the page lists them; no tables or pictures to draw.
        return Ok(SectionOut { title, model: m, tables: Vec::new(), assets, markdown: String::new() });
    }
    let stems = unique_stems(m.samples.iter().map(|s| s.key.clone()));
    let per_sample: Vec<SampleImages> =
        (0..m.samples.len()).into_par_iter().map(|s| sample_images(&m, s, &stems[s], &prefix)).collect::<Result<_, _>>()?;
    let mut thumbs = Vec::new();
    for si in per_sample {
        for (rel, bytes) in &si.files {
            w.put(rel, bytes)?;
        }
        w.put(&si.sheet.0, &si.sheet.1)?;
        assets.sheets.push(si.sheet.0);
        assets.samples.push(si.sample);
        assets.shown.push(si.shown);
        problems.extend(si.problems);
        thumbs.push(si.thumbnails);
    }
    if !m.samples.is_empty() {
        let name = if multi { sec.title() } else { "Overview".into() };
        let pages = overview_pages(&name, thumbs);
        let encoded: Vec<(String, Vec<u8>)> = pages
            .par_iter()
            .enumerate()
            .map(|(i, page)| {
                let rel = if i == 0 { format!("{prefix}sheets/overview.png") } else { format!("{prefix}sheets/overview-{}.png", i + 1) };
                png(page, &rel).map(|b| (rel, b))
            })
            .collect::<Result<_, _>>()?;
        for (rel, bytes) in encoded {
            w.put(&rel, &bytes)?;
            assets.overview.push(rel);
        }
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
        let rel = if *n == 1 { format!("{prefix}tables/{stem}.csv") } else { format!("{prefix}tables/{stem}-{n}.csv") };
        w.put(&rel, tables::csv(&m, t).as_bytes())?;
        assets.csvs.push((t.measure.clone(), rel));
    }
    w.put(&assets.csv_all.clone(), tables::csv_all(&m, &tables).as_bytes())?;
    w.put(&assets.jobs_csv.clone(), tables::jobs_csv(&m).as_bytes())?;
    let mut markdown = tables::markdown(&m, &tables, &source);
    if let Some(baseline) = &opts.baseline {
        let has_baseline = m.groups.iter().any(|g| g.method.as_deref() == Some(baseline.as_str()));
        if has_baseline {
            let speedups = tables::speedups(&m, &tables, baseline);
            for t in &speedups {
                let rel = format!("{prefix}tables/speedup_{}.csv", fmt::file_stem(&t.measure));
                w.put(&rel, tables::speedup_csv(&m, t).as_bytes())?;
            }
            markdown.push_str(&tables::speedup_markdown(&m, &speedups));
        }
    }
    Ok(SectionOut { title, model: m, tables, assets, markdown })
}

/// The earlier run a report compares with.
struct Since {
    source: String,
    manifest: Manifest,
    base: PathBuf,
    diff: Diff,
}

fn base_of(manifest_path: &Path) -> PathBuf {
    let base = manifest_path.parent().map(Path::to_path_buf).unwrap_or_default();
    if base.as_os_str().is_empty() { PathBuf::from(".") } else { base }
}

/// Old | new | difference for one changed job; the pictures are written under `changes/`.
fn change_panels(
    id: &str,
    outputs: &[String],
    since: Option<&Since>,
    manifest: &Manifest,
    base: &Path,
    n: usize,
) -> Result<(Vec<changes::Panel>, Vec<(String, Vec<u8>)>), Error> {
    let new_rec = manifest.job(id);
    let old_rec = since.and_then(|s| s.manifest.job(id));
    let mut panels = Vec::new();
    let mut files = Vec::new();
    for (k, out_path) in outputs.iter().enumerate() {
        let stem = format!("changes/{n:03}-{}-{}", fmt::file_stem(id), k + 1);
        let new_out = new_rec.and_then(|r| r.outputs.iter().find(|o| o.path == *out_path));
        let old_out = old_rec.and_then(|r| r.outputs.iter().find(|o| o.path == *out_path));
        let new_img = match new_out {
            Some(o) => load(&base.join(&o.path), &o.pixel_digest.sha256, false),
            None => Err(format!("{out_path}: not an output of this run")),
        };
        let old_img = match (since, old_out) {
            (None, _) => Err("golden/ keeps digests, not images: report with --since OLD_MANIFEST to see the old pixels".to_string()),
            (Some(_), None) => Err(format!("{out_path}: not an output of the old run")),
            (Some(s), Some(o)) => load(&s.base.join(&o.path), &o.pixel_digest.sha256, false)
                .map_err(|e| format!("the old image is gone or was overwritten (its pixels are not the old manifest's): {e}")),
        };
        let mut put = |img: &RgbImage, role: &str| -> Result<ImageRef, Error> {
            let rel = format!("{stem}-{role}.png");
            files.push((rel.clone(), png(img, &rel)?));
            Ok(Ok((rel, img.width(), img.height())))
        };
        let old = match &old_img {
            Ok(i) => put(i, "old")?,
            Err(e) => Err(e.clone()),
        };
        let new = match &new_img {
            Ok(i) => put(i, "new")?,
            Err(e) => Err(e.clone()),
        };
        let heat = match (&old_img, &new_img) {
            (Ok(a), Ok(b)) => match changes::heatmap(a, b) {
                Some((map, stats)) => match put(&map, "difference")? {
                    Ok((rel, w, h)) => Ok((rel, w, h, stats)),
                    Err(e) => Err(e),
                },
                None => Err(format!("sizes differ: old {}×{}, new {}×{}", a.width(), a.height(), b.width(), b.height())),
            },
            _ => Err("no difference without both images".to_string()),
        };
        panels.push(changes::Panel { output: out_path.clone(), old, new, heat });
    }
    Ok((panels, files))
}

/// Builds the report. Errors (exit 2) are a manifest that cannot be read or a directory that
/// cannot be written; images that cannot be shown are `problems` in the summary instead.
pub fn report(opts: &ReportOptions) -> Result<ReportSummary, Error> {
    let manifest = Manifest::load(&opts.manifest)?;
    let base = base_of(&opts.manifest);
    let since = match &opts.since {
        None => None,
        Some(p) => {
            let old = Manifest::load(p)?;
            let diff = diff::diff(&old, &manifest, &Thresholds::default());
            Some(Since { source: p.display().to_string(), base: base_of(p), manifest: old, diff })
        }
    };
    let golden: Option<CheckReport> = opts.golden.as_ref().map(|g| golden::check(g, &manifest)).transpose()?;

    let mut protected = BTreeSet::new();
    let mut protect = |p: PathBuf| {
        if let Ok(c) = p.canonicalize() {
            protected.insert(c);
        }
    };
    protect(opts.manifest.clone());
    let olds = since.iter().map(|s| (&s.manifest, s.base.clone()));
    for (m, b) in std::iter::once((&manifest, base.clone())).chain(olds) {
        for j in &m.jobs {
            if let Some(s) = &j.sample {
                protect(b.join(&s.path));
            }
            for o in &j.outputs {
                protect(b.join(&o.path));
            }
        }
    }
    let previous = previous_listing(&opts.out)?;
    let dir = OutDir::open(&opts.out)?;
    let mut w = Writer { dir, protected, written: Vec::new() };
    let mut problems = Vec::new();

    let sections = sections::partition(&manifest, opts.sections);
    let multi = sections.len() > 1;
    let mut outs = Vec::new();
    for sec in &sections {
        outs.push(build_section(&manifest, sec, multi, &base, opts, &mut w, &mut problems)?);
    }
    if let Some(b) = &opts.baseline
        && !manifest.jobs.iter().any(|j| j.status.is_success() && j.method.as_deref() == Some(b.as_str()))
    {
        problems.push(format!("--baseline {b}: no counted job of that method; no speed-up tables"));
    }
    let markdown = if multi {
        let mut md = format!("# texsyn tables: {}\n\nOne part per section of the report.\n", opts.manifest.display());
        for o in &outs {
            md.push_str(&format!("\n---\n\n# Section {}\n\n", o.title.as_deref().unwrap_or("")));
            md.push_str(if o.markdown.is_empty() { "No counted jobs.\n" } else { &o.markdown });
        }
        md
    } else {
        outs.first().map(|o| o.markdown.clone()).unwrap_or_default()
    };
    w.put("tables.md", markdown.as_bytes())?;

    // What changed: the diff's pixel changes, then golden mismatches the diff did not cover.
    let mut to_show: Vec<(String, Vec<String>, Vec<diff::KeyChange>, &'static str)> = Vec::new();
    if let Some(s) = &since {
        for p in &s.diff.pixels_changed {
            to_show.push((p.id.clone(), p.outputs.clone(), p.because.clone(), "since"));
        }
    }
    if let Some(g) = &golden {
        for (id, out) in &g.mismatched_outputs {
            if !to_show.iter().any(|t| t.0 == *id) {
                to_show.push((id.clone(), vec![out.clone()], Vec::new(), "golden"));
            }
        }
    }
    let mut changed = Vec::new();
    let mut beyond = Vec::new();
    for (n, (id, outputs, because, source)) in to_show.into_iter().enumerate() {
        if n >= changes::MAX_PANELS {
            let why = if source == "golden" { "differs from golden".into() } else { diff::describe_changes(&because) };
            beyond.push((id, why));
            continue;
        }
        let (panels, files) = change_panels(&id, &outputs, since.as_ref(), &manifest, &base, n + 1)?;
        for (rel, bytes) in &files {
            w.put(rel, bytes)?;
        }
        changed.push(changes::Changed { id, because, source, panels });
    }
    let changes_html = if since.is_some() || golden.as_ref().is_some_and(|g| !g.mismatched.is_empty()) {
        changes::html(&changed, &beyond, since.as_ref().map(|s| s.source.as_str()))
    } else {
        String::new()
    };
    let golden_source = opts.golden.as_ref().map(|g| g.display().to_string());
    let summary_html = summary::html(
        &manifest,
        &summary::Comparison {
            since: since.as_ref().map(|s| (s.source.as_str(), &s.diff)),
            golden: golden.as_ref().zip(golden_source.as_deref()).map(|(g, d)| (d, g)),
        },
    );

    let source = opts.manifest.display().to_string();
    let digest_ok = manifest.recompute_digest() == manifest.deterministic_digest;
    if !digest_ok {
        problems.push(format!("{source}: the deterministic digest does not match the content (edited after the run?)"));
    }
    let parts: Vec<Part> =
        outs.iter().map(|o| Part { title: o.title.clone(), model: &o.model, tables: &o.tables, assets: &o.assets }).collect();
    let page = html::page(&parts, &manifest, &source, digest_ok, &problems, &summary_html, &changes_html);
    // The listing names the page too, so a later report knows the whole set.
    let mut listing: Vec<String> = w.written.clone();
    listing.push("index.html".into());
    listing.sort();
    listing.dedup();
    w.put(LISTING, (listing.join("\n") + "\n").as_bytes())?;
    let removed = remove_stale(&w, &previous, &listing);
    // Last, so a reader never opens a page whose files are not all there yet.
    w.put("index.html", page.as_bytes())?;
    Ok(ReportSummary {
        index: opts.out.join("index.html"),
        files: w.written,
        counted: outs.iter().map(|o| o.model.entries.len()).sum(),
        excluded: outs.iter().map(|o| o.model.excluded.len()).sum(),
        sections: outs.len(),
        pixels_changed: since.as_ref().map(|s| s.diff.pixels_changed.len()),
        removed,
        problems,
    })
}
