//! End-to-end tests of `texsyn report`: a small real job directory (two samples, a seed and block
//! sweep, an EXR and a 16-bit output, a failed and an invalid job) is run through the binary with
//! metrics on, then reported. The tables and CSV must carry the manifest's numbers, the contact
//! sheets must hold the images pixel for pixel, and the page must render in a real headless
//! Chromium with every image decoded and every number equal to the manifest's.

use super::common::*;

use std::sync::OnceLock;

const METRICS: [&str; 6] = ["kl_gray", "kl_orientation", "acf_gray", "acf_orientation", "verbatim", "seam_visibility"];

/// The job directory and its run, made once for all tests (they only read it).
struct Run {
    out: PathBuf,
    manifest: Value,
}

fn run() -> &'static Run {
    static RUN: OnceLock<Run> = OnceLock::new();
    RUN.get_or_init(|| {
        let d = scratch("run");
        let jobs = d.join("jobs");
        for s in ["bricks_gray", "weave_gray"] {
            std::fs::create_dir_all(&jobs).unwrap();
            std::fs::copy(repo().join(format!("jobs/samples/{s}.png")), jobs.join(format!("{s}.png"))).unwrap();
            write(
                &jobs.join(format!("{s}.toml")),
                &format!(
                    "sample = \"{s}.png\"\nmethod = \"quilting\"\nmetrics = true\n[output]\npath = \"{s}/b{{block}}_s{{seed}}.png\"\n\
                     width = 100\nheight = 100\n[sweep]\nseed = [1, 2]\nblock = [20, 30]\n"
                ),
            );
        }
        // Representatives of their columns (lowest seed), so the sheets and page decode EXR and 16-bit PNG.
        write(
            &jobs.join("weave_exr.toml"),
            "sample = \"weave_gray.png\"\nmethod = \"quilting\"\nseed = 0\nmetrics = true\n[output]\npath = \"weave_gray/exr.exr\"\n\
             width = 100\nheight = 100\n[params]\nblock = 20\n",
        );
        write(
            &jobs.join("bricks_16.toml"),
            "sample = \"bricks_gray.png\"\nmethod = \"quilting\"\nseed = 0\nmetrics = true\n[output]\npath = \"bricks_gray/deep.png\"\n\
             width = 100\nheight = 100\nbit_depth = 16\n[params]\nblock = 30\n",
        );
        // One invalid job (unknown key) and one that fails (its output path is a directory).
        write(&jobs.join("typo.toml"), "sample = \"bricks_gray.png\"\nmethod = \"quilting\"\nseed = 1\nblok = 3\n[output]\npath = \"typo.png\"\nwidth = 100\nheight = 100\n");
        write(
            &jobs.join("blocked.toml"),
            "sample = \"bricks_gray.png\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"blocked.png\"\nwidth = 100\nheight = 100\n[params]\nblock = 20\n",
        );
        let out = d.join("out");
        std::fs::create_dir_all(out.join("blocked.png")).unwrap();
        run_expect(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("-q"), 1);
        let manifest: Value = serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
        let statuses: Vec<&str> = manifest["jobs"].as_array().unwrap().iter().map(|j| j["status"].as_str().unwrap()).collect();
        assert_eq!(statuses.iter().filter(|s| **s == "ok").count(), 10, "{statuses:?}");
        assert!(statuses.contains(&"failed") && statuses.contains(&"invalid"), "{statuses:?}");
        Run { out, manifest }
    })
}

/// A report of the shared run with the given extra arguments, into a fresh directory.
fn report(tag: &str, args: &[&str]) -> PathBuf {
    let dir = scratch(tag).join("report");
    run_expect(texsyn().arg("report").arg(run().out.join("manifest.json")).arg("-o").arg(&dir).args(args), 0);
    dir
}

fn ok_jobs(m: &Value) -> Vec<&Value> {
    m["jobs"].as_array().unwrap().iter().filter(|j| j["status"] == "ok" || j["status"] == "up-to-date").collect()
}

fn stem(job: &Value) -> String {
    Path::new(job["sample"]["path"].as_str().unwrap()).file_stem().unwrap().to_string_lossy().into_owned()
}

/// The value of `measure` for a job, as the manifest records it (`None` if null).
fn value(job: &Value, measure: &str) -> Option<f64> {
    if measure == "synthesis_seconds" { job["timing"]["synthesis_seconds"].as_f64() } else { job["metrics"][measure].as_f64() }
}

#[derive(Debug)]
struct Expected {
    mean: Option<f64>,
    sd: Option<f64>,
    n: usize,
}

/// Mean, sample standard deviation and count of each (sample, column, measure), computed here
/// from the manifest independently of the report code.
fn expected(m: &Value, column: impl Fn(&Value) -> String) -> BTreeMap<(String, String, String), Expected> {
    let mut values: BTreeMap<(String, String, String), Vec<f64>> = BTreeMap::new();
    for j in ok_jobs(m) {
        for measure in METRICS.iter().copied().chain(["synthesis_seconds"]) {
            let cell = values.entry((stem(j), column(j), measure.to_string())).or_default();
            if let Some(v) = value(j, measure) {
                cell.push(v);
            }
        }
    }
    values
        .into_iter()
        .map(|(k, v)| {
            let n = v.len();
            let mean = (n > 0).then(|| v.iter().sum::<f64>() / n as f64);
            let sd = (n > 1).then(|| (v.iter().map(|x| (x - mean.unwrap()).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt());
            (k, Expected { mean, sd, n })
        })
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1e-300)
}

/// Minimal RFC 4180 reader (the report quotes fields with commas).
fn parse_csv(text: &str) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    for line in text.lines() {
        let mut row = Vec::new();
        let mut field = String::new();
        let mut quoted = false;
        let mut chars = line.chars().peekable();
        while let Some(c) = chars.next() {
            match (c, quoted) {
                ('"', true) if chars.peek() == Some(&'"') => {
                    field.push('"');
                    chars.next();
                }
                ('"', _) => quoted = !quoted,
                (',', false) => row.push(std::mem::take(&mut field)),
                (c, _) => field.push(c),
            }
        }
        row.push(field);
        rows.push(row);
    }
    rows
}

fn csv_table(path: &Path) -> (Vec<String>, BTreeMap<String, Vec<String>>) {
    let rows = parse_csv(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())));
    let header = rows[0].clone();
    let body = rows[1..].iter().map(|r| (r[0].clone(), r.clone())).collect();
    (header, body)
}

fn num(s: &str) -> Option<f64> {
    if s.is_empty() { None } else { Some(s.parse().unwrap_or_else(|_| panic!("not a number: {s:?}"))) }
}

/// Checks a per-measure CSV against the expectation for the given column labels.
fn check_measure_csv(dir: &Path, measure: &str, exp: &BTreeMap<(String, String, String), Expected>, columns: &[String]) {
    let (header, body) = csv_table(&dir.join(format!("tables/{measure}.csv")));
    let samples: Vec<String> = {
        let mut s: Vec<String> = exp.keys().map(|k| k.0.clone()).collect();
        s.dedup();
        s
    };
    assert_eq!(body.len(), samples.len() + 1, "{measure}: a row per sample and a mean row");
    for col in columns {
        let at = |f: &str| {
            header.iter().position(|h| *h == format!("{col}:{f}")).unwrap_or_else(|| panic!("{measure}: no column {col}:{f} in {header:?}"))
        };
        let (im, isd, in_) = (at("mean"), at("sd"), at("n"));
        let mut sample_means = Vec::new();
        for s in &samples {
            let row = &body[s];
            let Some(e) = exp.get(&(s.clone(), col.clone(), measure.to_string())) else {
                assert_eq!(row[in_], "", "{measure} {s} {col}: not run");
                continue;
            };
            assert_eq!(row[in_], e.n.to_string(), "{measure} {s} {col}: n");
            match (num(&row[im]), e.mean) {
                (Some(a), Some(b)) => assert!(close(a, b), "{measure} {s} {col}: mean {a} vs manifest {b}"),
                (a, b) => assert_eq!(a, b, "{measure} {s} {col}: mean"),
            }
            match (num(&row[isd]), e.sd) {
                (Some(a), Some(b)) => assert!(close(a, b), "{measure} {s} {col}: sd {a} vs manifest {b}"),
                (a, b) => assert_eq!(a, b, "{measure} {s} {col}: sd"),
            }
            sample_means.extend(e.mean);
        }
        let mean_row = &body["mean"];
        match num(&mean_row[im]) {
            Some(a) => {
                let b = sample_means.iter().sum::<f64>() / sample_means.len() as f64;
                assert!(close(a, b), "{measure} {col}: mean row {a} vs {b}");
            }
            None => assert!(sample_means.is_empty(), "{measure} {col}: mean row missing"),
        }
    }
}

/// The default (`auto`) column: the method and the parameters that vary among its jobs. Overlap
/// defaults to round(block / 6), so it varies with the block.
fn auto_column(j: &Value) -> String {
    format!("quilting block={} overlap={}", j["params"]["block"], j["params"]["overlap"])
}

#[test]
fn tables_and_csv_carry_the_manifests_numbers() {
    let m = &run().manifest;
    let dir = report("tables", &[]);
    let exp = expected(m, auto_column);
    let columns = vec!["quilting block=20 overlap=3".to_string(), "quilting block=30 overlap=5".to_string()];
    for measure in METRICS.iter().copied().chain(["synthesis_seconds"]) {
        check_measure_csv(&dir, measure, &exp, &columns);
    }
    // A seed sweep gives a spread: weave at block 20 ran seeds 0 (EXR), 1 and 2.
    assert_eq!(exp[&("weave_gray".into(), columns[0].clone(), "kl_gray".into())].n, 3);

    // Per-job CSV: exactly the manifest's values, bit for bit.
    let (header, body) = csv_table(&dir.join("jobs.csv"));
    assert_eq!(body.len(), ok_jobs(m).len());
    for j in ok_jobs(m) {
        let row = &body[j["id"].as_str().unwrap()];
        for measure in METRICS.iter().copied().chain(["synthesis_seconds"]) {
            let i = header.iter().position(|h| h == measure).unwrap();
            assert_eq!(num(&row[i]), value(j, measure), "{} {measure}", j["id"]);
        }
    }

    // The wide CSV has a column block per (measure, column) and the same numbers.
    let (header, body) = csv_table(&dir.join("tables/all.csv"));
    let i = header.iter().position(|h| h == "kl_orientation:quilting block=30 overlap=5:mean").expect("wide CSV column");
    let e = &exp[&("bricks_gray".into(), columns[1].clone(), "kl_orientation".into())];
    assert!(close(num(&body["bricks_gray"][i]).unwrap(), e.mean.unwrap()));

    // Markdown: every table, every cell's rounded mean, and the jobs that did not count.
    let md = std::fs::read_to_string(dir.join("tables.md")).unwrap();
    for measure in METRICS.iter().copied().chain(["synthesis_seconds"]) {
        let section = md.split("\n## ").find(|s| s.contains(&format!("— {measure}:"))).unwrap_or_else(|| panic!("no table for {measure}"));
        let lines: Vec<&str> = section.lines().filter(|l| l.starts_with('|')).collect();
        let header: Vec<&str> = lines[0].trim_matches('|').split('|').map(str::trim).collect();
        for line in &lines[2..lines.len() - 1] {
            let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
            for col in &columns {
                let c = header.iter().position(|h| h == col).unwrap();
                let e = &exp[&(cells[0].to_string(), col.clone(), measure.to_string())];
                match e.mean {
                    Some(mean) => {
                        let shown: f64 = cells[c].split_whitespace().next().unwrap().parse().unwrap();
                        assert!((shown - mean).abs() <= 5e-4 * mean.abs(), "{measure} {}: shown {shown} vs {mean}", cells[0]);
                        if e.n > 1 {
                            assert!(cells[c].contains(&format!("(n={})", e.n)), "{measure}: {}", cells[c]);
                        }
                    }
                    None => assert!(cells[c].starts_with('—'), "{measure}: {}", cells[c]),
                }
            }
        }
        assert!(lines.last().unwrap().starts_with("| **mean**"), "{measure}: mean row");
    }
    let not_counted = md.split("## Jobs not counted").nth(1).expect("failed and invalid jobs are listed");
    assert!(not_counted.contains("| typo.toml | invalid |") && not_counted.contains("| blocked.toml | failed |"), "{not_counted}");
}

#[test]
fn grouping_is_selectable() {
    let m = &run().manifest;
    // By method alone: the block sweep pools into one column.
    let dir = report("group-method", &["--group-by", "method"]);
    let exp = expected(m, |_| "quilting".into());
    check_measure_csv(&dir, "kl_gray", &exp, &["quilting".into()]);
    assert_eq!(exp[&("bricks_gray".into(), "quilting".into(), "kl_gray".into())].n, 5);
    // By parameter: one column per block size, labelled by the parameter alone.
    let dir = report("group-param", &["--group-by", "param:block"]);
    let exp = expected(m, |j| format!("block={}", j["params"]["block"]));
    check_measure_csv(&dir, "acf_gray", &exp, &["block=20".into(), "block=30".into()]);
    // By method and seed: no spread left.
    let dir = report("group-seed", &["--group-by", "method,seed"]);
    let (header, _) = csv_table(&dir.join("tables/verbatim.csv"));
    let cols: Vec<&String> = header.iter().filter(|h| h.ends_with(":mean")).collect();
    assert_eq!(cols, ["quilting seed=0:mean", "quilting seed=1:mean", "quilting seed=2:mean"]);
}

/// Finds `img` pasted pixel for pixel in `sheet`.
fn find(sheet: &RgbImage, img: &RgbImage) -> Option<(u32, u32)> {
    let (w, h) = img.dimensions();
    for y0 in 0..=sheet.height().checked_sub(h)? {
        for x0 in 0..=sheet.width().checked_sub(w)? {
            if sheet.get(x0, y0) == img.get(0, 0) && (0..h).all(|y| (0..w).all(|x| sheet.get(x0 + x, y0 + y) == img.get(x, y))) {
                return Some((x0, y0));
            }
        }
    }
    None
}

pub fn decode(path: &Path) -> RgbImage {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    imageio::native_to_rgb8(&imageio::decode_native(&bytes, DecodeLimits::default()).unwrap())
}

#[test]
fn contact_sheets_hold_the_sample_and_each_columns_output_at_one_scale() {
    let r = run();
    let dir = report("sheets", &[]);
    for s in ["bricks_gray", "weave_gray"] {
        let sheet = decode(&dir.join(format!("sheets/{s}.png")));
        let sample = decode(&repo().join(format!("jobs/samples/{s}.png")));
        let (sx, sy) = find(&sheet, &sample).unwrap_or_else(|| panic!("{s}: the sample is not on its sheet at 1:1"));
        // Each column shows its lowest seed: block 20 and 30 for bricks (seed 0 is the 16-bit one),
        // block 20 (seed 0, the EXR) and 30 for weave.
        let shown = if s == "bricks_gray" {
            ["bricks_gray/b20_s1.png", "bricks_gray/deep.png"]
        } else {
            ["weave_gray/exr.exr", "weave_gray/b30_s1.png"]
        };
        let mut last_x = sx;
        for rel in shown {
            let out = decode(&r.out.join(rel));
            let (x, y) = find(&sheet, &out).unwrap_or_else(|| panic!("{s}: {rel} is not on the sheet at 1:1"));
            assert_eq!(y, sy, "{rel}: on the sample's row");
            assert!(x > last_x, "{rel}: columns left to right");
            last_x = x;
            // A caption is drawn right under the image.
            let ink = (y + 100..y + 120).any(|yy| (x..x + 100).any(|xx| sheet.get(xx, yy) != [255, 255, 255]));
            assert!(ink, "{rel}: caption under the image");
        }
    }
}

/// The overview pages of a report section (`sheets/overview.png`, `overview-2.png`, …).
fn overview_pages(sheets: &Path) -> Vec<RgbImage> {
    let mut pages = vec![decode(&sheets.join("overview.png"))];
    for i in 2.. {
        let p = sheets.join(format!("overview-{i}.png"));
        if !p.exists() {
            break;
        }
        pages.push(decode(&p));
    }
    pages
}

#[test]
fn the_overview_shows_every_seed_legibly_within_2000_px() {
    let r = run();
    let dir = report("overview", &[]);
    let pages = overview_pages(&dir.join("sheets"));
    for p in &pages {
        assert!(p.width() <= 2040, "an overview page is {} px wide", p.width());
    }
    // Every counted job, not one seed per column: the outputs are 100 px, so they stay 1:1.
    for j in ok_jobs(&r.manifest) {
        let out = decode(&r.out.join(j["outputs"][0]["path"].as_str().unwrap()));
        assert!(pages.iter().any(|p| find(p, &out).is_some()), "{} is not on the overview", j["id"]);
    }
    // A sample larger than 255 px is reduced by an integer factor to at least 128 px: bricks is
    // 256 px, so it appears at 1:2, each pixel the mean of a 2×2 block.
    let bricks = decode(&repo().join("jobs/samples/bricks_gray.png"));
    let half = RgbImage::from_fn(128, 128, |x, y| {
        let mut sum = [0u32; 3];
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let p = bricks.get(2 * x + dx, 2 * y + dy);
            for c in 0..3 {
                sum[c] += p[c] as u32;
            }
        }
        [0, 1, 2].map(|c| ((sum[c] + 2) / 4) as u8)
    });
    assert!(pages.iter().any(|p| find(p, &half).is_some()), "the 256 px sample at 1:2 on the overview");
}

// ---------------------------------------------------------------------------------------------
// Headless Chromium

fn chromium() -> PathBuf {
    if let Some(p) = std::env::var_os("TEXSYN_CHROMIUM") {
        return PathBuf::from(p);
    }
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        for dir in std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()) {
            let p = dir.join(name);
            if p.is_file() {
                return p;
            }
        }
    }
    panic!(
        "headless Chromium is required for this test and was not found on PATH (nor in TEXSYN_CHROMIUM). \
         Install it with `apt-get install -y chromium` (Debian; .ci/run does this)."
    );
}

/// The page's DOM after its scripts ran, as Chromium serialises it.
pub fn dump_dom(page: &Path) -> String {
    let profile = scratch("chromium-profile");
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    let mut child = Command::new(chromium())
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--virtual-time-budget=5000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--dump-dom")
        .arg(&url)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("chromium starts");
    let stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || std::io::read_to_string(stdout).unwrap_or_default());
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("chromium did not finish within 120 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let dom = reader.join().unwrap();
    let _ = std::fs::remove_dir_all(&profile);
    assert!(dom.contains("</html>"), "chromium printed no DOM: {dom:?}");
    dom
}

/// One start tag: name, attributes, and the text up to its closing tag (tags stripped).
pub struct Tag {
    pub name: String,
    pub attrs: BTreeMap<String, String>,
    pub text: String,
}

fn unescape(s: &str) -> String {
    s.replace("&quot;", "\"")
        .replace("&#39;", "'")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&nbsp;", "\u{a0}")
        .replace("&amp;", "&")
}

/// A small start-tag scanner, enough for the serialised DOM (attributes are double-quoted).
pub fn tags(html: &str) -> Vec<Tag> {
    let mut out = Vec::new();
    let b = html.as_bytes();
    let mut i = 0;
    while let Some(off) = html[i..].find('<') {
        i += off + 1;
        if i >= b.len() || !b[i].is_ascii_alphabetic() {
            continue;
        }
        let name_end = html[i..].find(|c: char| c.is_whitespace() || c == '>' || c == '/').map_or(html.len(), |e| i + e);
        let name = html[i..name_end].to_ascii_lowercase();
        let mut j = name_end;
        let mut attrs = BTreeMap::new();
        loop {
            while j < b.len() && (b[j] as char).is_whitespace() {
                j += 1;
            }
            if j >= b.len() || b[j] == b'>' || b[j] == b'/' {
                break;
            }
            let key_end = html[j..].find(['=', ' ', '>']).map_or(html.len(), |e| j + e);
            let key = html[j..key_end].to_string();
            j = key_end;
            if j < b.len() && b[j] == b'=' && b[j + 1] == b'"' {
                let vend = html[j + 2..].find('"').unwrap() + j + 2;
                attrs.insert(key, unescape(&html[j + 2..vend]));
                j = vend + 1;
            } else {
                attrs.insert(key, String::new());
            }
        }
        let gt = html[j..].find('>').map_or(html.len(), |e| j + e);
        let close = format!("</{name}>");
        let text = html[gt + 1..].find(&close).map_or(String::new(), |e| {
            let mut t = String::new();
            let mut in_tag = false;
            for c in html[gt + 1..gt + 1 + e].chars() {
                match c {
                    '<' => in_tag = true,
                    '>' => in_tag = false,
                    c if !in_tag => t.push(c),
                    _ => {}
                }
            }
            unescape(&t)
        });
        out.push(Tag { name, attrs, text });
        i = gt;
    }
    out
}

/// The number a reader sees must be the exact value rounded to four significant digits.
fn assert_shown(text: &str, exact: f64, what: &str) {
    let shown: f64 = text.split_whitespace().next().unwrap_or("").parse().unwrap_or_else(|_| panic!("{what}: shows {text:?}"));
    let tolerance = if exact == 0.0 { 0.0 } else { 0.5 * 10f64.powi(exact.abs().log10().floor() as i32 - 3) * (1.0 + 1e-9) };
    assert!((shown - exact).abs() <= tolerance, "{what}: shows {shown}, manifest has {exact}");
}

#[test]
fn html_page_renders_in_headless_chromium_with_every_image_and_the_manifests_numbers() {
    let m = &run().manifest;
    let dir = report("html", &[]);
    let source = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(!source.contains("http://") && !source.contains("https://"), "no network references");
    let n_img = tags(&source).iter().filter(|t| t.name == "img").count();
    // 2 samples, 4 shown outputs, 2 sheets, the overview and the plot.
    assert_eq!(n_img, 10, "images on the page");

    let dom = dump_dom(&dir.join("index.html"));
    let all = tags(&dom);
    let body = all.iter().find(|t| t.name == "body").expect("a body");
    assert_eq!(
        body.attrs.get("data-images-ok").map(String::as_str),
        Some(format!("{n_img}/{n_img}").as_str()),
        "every image decoded in Chromium; failed: {:?}",
        body.attrs.get("data-images-failed")
    );

    // Per-job values: exactly the manifest's, for every ok job and every measure.
    let mut seen = 0;
    for j in ok_jobs(m) {
        let id = j["id"].as_str().unwrap();
        for measure in METRICS.iter().copied().chain(["synthesis_seconds"]) {
            let cell = all
                .iter()
                .find(|t| {
                    t.name == "td"
                        && t.attrs.get("data-job").map(String::as_str) == Some(id)
                        && t.attrs.get("data-metric").map(String::as_str) == Some(measure)
                })
                .unwrap_or_else(|| panic!("no cell for {id} {measure}"));
            match value(j, measure) {
                Some(v) => {
                    let shown: f64 = cell.attrs["data-value"].parse().unwrap();
                    assert_eq!(shown.to_bits(), v.to_bits(), "{id} {measure}: data-value");
                    assert_shown(&cell.text, v, &format!("{id} {measure}"));
                }
                None => assert_eq!(cell.text, "undefined", "{id} {measure}"),
            }
            seen += 1;
        }
    }
    assert_eq!(seen, 10 * 7);

    // Table cells: mean, spread and count as computed from the manifest here.
    let exp = expected(m, auto_column);
    let mut cells = 0;
    for ((sample, col, measure), e) in &exp {
        let cell = all
            .iter()
            .find(|t| {
                t.name == "td"
                    && t.attrs.get("data-sample") == Some(sample)
                    && t.attrs.get("data-group") == Some(col)
                    && t.attrs.get("data-metric") == Some(measure)
            })
            .unwrap_or_else(|| panic!("no table cell {sample} {col} {measure}"));
        assert_eq!(cell.attrs["data-n"], e.n.to_string(), "{sample} {col} {measure}");
        match e.mean {
            Some(mean) => {
                assert!(close(cell.attrs["data-value"].parse().unwrap(), mean), "{sample} {col} {measure}");
                assert_shown(&cell.text, mean, &format!("{sample} {col} {measure}"));
            }
            None => assert!(!cell.attrs.contains_key("data-value") && cell.text.starts_with('—')),
        }
        if let Some(sd) = e.sd {
            assert!(close(cell.attrs["data-sd"].parse().unwrap(), sd), "{sample} {col} {measure} sd");
            let shown_sd = cell.text.split("± ").nth(1).expect("spread shown");
            assert_shown(shown_sd, sd, &format!("{sample} {col} {measure} sd"));
        }
        cells += 1;
    }
    assert_eq!(cells, 2 * 2 * 7);

    // Provenance, one click away: tool commit, digest, every job's pixel digest and seed.
    let details = all.iter().find(|t| t.name == "details" && t.attrs.get("data-role").map(String::as_str) == Some("provenance"));
    assert!(details.is_some(), "provenance in a <details>");
    let commit = all.iter().find_map(|t| t.attrs.get("data-commit")).expect("commit shown");
    assert_eq!(commit, m["tool"]["commit"].as_str().unwrap());
    let digest = all.iter().find_map(|t| t.attrs.get("data-digest")).expect("deterministic digest shown");
    assert_eq!(digest, m["deterministic_digest"]["sha256"].as_str().unwrap());
    assert!(dom.contains("recomputed from the manifest: matches"));
    for j in ok_jobs(m) {
        let pd = j["outputs"][0]["pixel_digest"]["sha256"].as_str().unwrap();
        assert!(all.iter().any(|t| t.attrs.get("data-pixel-digest").map(String::as_str) == Some(pd)), "{} digest", j["id"]);
    }
    // The jobs that did not count are listed with their status.
    for (id, status) in [("typo.toml", "invalid"), ("blocked.toml", "failed")] {
        assert!(
            all.iter().any(|t| t.name == "tr"
                && t.attrs.get("data-job").map(String::as_str) == Some(id)
                && t.attrs.get("data-status").map(String::as_str) == Some(status)),
            "{id} listed as {status}"
        );
    }
    // The plot has a point per job with its exact time and size.
    let svg = std::fs::read_to_string(dir.join("plots/time_vs_pixels.svg")).unwrap();
    let points: Vec<Tag> = tags(&svg).into_iter().filter(|t| t.name == "circle" && t.attrs.contains_key("data-job")).collect();
    assert_eq!(points.len(), 10);
    for p in &points {
        let j = ok_jobs(m).into_iter().find(|j| j["id"] == p.attrs["data-job"].as_str()).unwrap();
        assert_eq!(p.attrs["data-seconds"].parse::<f64>().unwrap(), j["timing"]["synthesis_seconds"].as_f64().unwrap());
        assert_eq!(p.attrs["data-pixels"], "10000");
    }
}

#[test]
fn a_missing_image_is_reported_and_the_rest_is_still_written() {
    let r = run();
    let d = scratch("missing");
    // A copy of the run without one shown output.
    let copy = d.join("out");
    let status = Command::new("cp").arg("-r").arg(&r.out).arg(&copy).status().unwrap();
    assert!(status.success());
    std::fs::remove_file(copy.join("bricks_gray/b20_s1.png")).unwrap();
    let report = d.join("report");
    let out = run_expect(texsyn().arg("report").arg(copy.join("manifest.json")).arg("-o").arg(&report), 1);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bricks_gray/b20_s1.png"), "{err}");
    let page = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(page.contains("image unavailable"), "placeholder on the page");
    assert!(decode(&report.join("sheets/bricks_gray.png")).width() > 0, "the sheet is still drawn");
    // A tampered image is refused too: its pixels are not the ones the numbers describe.
    std::fs::copy(copy.join("weave_gray/b30_s2.png"), copy.join("weave_gray/b30_s1.png")).unwrap();
    let out = run_expect(texsyn().arg("report").arg(copy.join("manifest.json")).arg("-o").arg(&report), 1);
    assert!(String::from_utf8_lossy(&out.stderr).contains("differ from the manifest"));
}

#[test]
fn bad_manifests_and_usage_exit_2() {
    let d = scratch("bad");
    let garbage = d.join("manifest.json");
    std::fs::write(&garbage, "{ not json").unwrap();
    let wrong_type = d.join("wrong.json");
    let mut m = run().manifest.clone();
    m["jobs"][0]["metrics"]["kl_gray"] = Value::String("low".into());
    std::fs::write(&wrong_type, serde_json::to_vec(&m).unwrap()).unwrap();
    for (args, why) in [
        (vec![d.join("absent.json").display().to_string(), "-o".into(), d.join("r1").display().to_string()], "missing manifest"),
        (vec![garbage.display().to_string(), "-o".into(), d.join("r2").display().to_string()], "not JSON"),
        (vec![wrong_type.display().to_string(), "-o".into(), d.join("r3").display().to_string()], "metric not a number"),
        (vec![run().out.join("manifest.json").display().to_string()], "no -o"),
        (
            vec![
                run().out.join("manifest.json").display().to_string(),
                "-o".into(),
                d.join("r4").display().to_string(),
                "--group-by".into(),
                "colour".into(),
            ],
            "unknown grouping",
        ),
    ] {
        let out = texsyn().arg("report").args(&args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{why}: {}", String::from_utf8_lossy(&out.stderr));
    }
    for r in ["r1", "r2", "r3", "r4"] {
        assert!(!d.join(r).join("index.html").exists(), "{r}: nothing written");
    }
}

#[test]
fn the_report_writes_only_inside_its_directory() {
    let d = scratch("contain");
    let outside = d.join("outside");
    std::fs::create_dir_all(&outside).unwrap();
    let report = d.join("report");
    std::fs::create_dir_all(&report).unwrap();
    std::os::unix::fs::symlink(&outside, report.join("sheets")).unwrap();
    let out = texsyn().arg("report").arg(run().out.join("manifest.json")).arg("-o").arg(&report).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("outside the output directory"));
    assert_eq!(std::fs::read_dir(&outside).unwrap().count(), 0, "nothing written through the symlink");
    // And never over a file the manifest refers to: reporting into the run directory itself, whose
    // `images/samples/` would be a sample's own path here.
    let d2 = scratch("protect");
    let run_dir = d2.join("out");
    assert!(Command::new("cp").arg("-r").arg(&run().out).arg(&run_dir).status().unwrap().success());
    let m: Value = serde_json::from_slice(&std::fs::read(run_dir.join("manifest.json")).unwrap()).unwrap();
    let mut m = m;
    for j in m["jobs"].as_array_mut().unwrap() {
        if j["status"] == "ok" && j["sample"]["path"].as_str().unwrap().ends_with("bricks_gray.png") {
            j["sample"]["path"] = "images/samples/bricks_gray.png".into();
        }
    }
    std::fs::create_dir_all(run_dir.join("images/samples")).unwrap();
    std::fs::copy(repo().join("jobs/samples/bricks_gray.png"), run_dir.join("images/samples/bricks_gray.png")).unwrap();
    std::fs::write(run_dir.join("manifest.json"), serde_json::to_vec(&m).unwrap()).unwrap();
    let before = std::fs::read(run_dir.join("images/samples/bricks_gray.png")).unwrap();
    let out = texsyn().arg("report").arg(run_dir.join("manifest.json")).arg("-o").arg(&run_dir).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("the manifest refers to"));
    assert_eq!(std::fs::read(run_dir.join("images/samples/bricks_gray.png")).unwrap(), before);
}

/// A nightly directory mixing job directories: `quilt/` (quilting, a seed sweep and a failing
/// job), `seams/b20` and `seams/b30` (double-seam at two blocks: one sweep, one section) and
/// `tiles/` (wang-tiles). Built once for the tests below.
fn mixed_run() -> &'static PathBuf {
    static RUN: OnceLock<PathBuf> = OnceLock::new();
    RUN.get_or_init(|| {
        let d = scratch("mixed");
        let jobs = d.join("jobs");
        let sample = repo().join("jobs/samples/crops/pebbles_beige_128.png");
        let s = sample.to_str().unwrap();
        let job = |rel: &str, body: String| write(&jobs.join(rel), &body);
        job(
            "quilt/a.toml",
            format!("sample = \"{s}\"\nmethod = \"quilting\"\n[output]\npath = \"quilt/a{{seed}}.png\"\nwidth = 96\nheight = 96\n[sweep]\nseed = [1, 2, 3]\n"),
        );
        job("quilt/broken.toml", format!("sample = \"{s}\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"blocked.png\"\nwidth = 96\nheight = 96\n"));
        for b in [20, 30] {
            job(
                &format!("seams/b{b}/x.toml"),
                format!(
                    "sample = \"{s}\"\nmethod = \"double-seam\"\nseed = 1\n[output]\npath = \"seams/b{b}.png\"\nwidth = 96\nheight = 96\n[params]\nblock = {b}\n"
                ),
            );
        }
        job("tiles/w.toml", format!("sample = \"{s}\"\nmethod = \"wang-tiles\"\nseed = 1\n[output]\npath = \"tiles/w.png\"\nwidth = 128\nheight = 128\n"));
        let out = d.join("out");
        std::fs::create_dir_all(out.join("blocked.png")).unwrap();
        run_expect(texsyn().arg("run").arg(&jobs).arg("-o").arg(&out).arg("-q"), 1);
        out
    })
}

#[test]
fn a_mixed_run_gets_a_section_per_job_directory_with_only_its_columns() {
    let out = mixed_run();
    let dir = scratch("mixed-report").join("report");
    run_ok(texsyn().arg("report").arg(out.join("manifest.json")).arg("-o").arg(&dir));
    let page = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let all = tags(&page);
    let sections: Vec<&str> = all
        .iter()
        .filter(|t| t.name == "section" && t.attrs.contains_key("data-section"))
        .map(|t| t.attrs["data-section"].as_str())
        .collect();
    // seams/b20 and seams/b30 split a sweep of one method: one section, its table B=20 beside B=30.
    assert_eq!(sections, ["quilt/", "seams/", "tiles/"]);
    let (header, _) = csv_table(&dir.join("sections/seams/tables/synthesis_seconds.csv"));
    assert!(header.iter().any(|h| h.contains("block=20")) && header.iter().any(|h| h.contains("block=30")), "{header:?}");
    assert!(!header.iter().any(|h| h.contains("quilting") || h.contains("wang")), "only the section's own methods: {header:?}");
    // No column of any table in which every cell is "not run".
    let mut columns: BTreeMap<(String, String), (usize, usize)> = BTreeMap::new();
    for t in all.iter().filter(|t| t.name == "td" && t.attrs.contains_key("data-group") && t.attrs.contains_key("data-n")) {
        let c = columns.entry((t.attrs["data-metric"].clone(), t.attrs["data-group"].clone())).or_default();
        c.0 += 1;
        c.1 += usize::from(t.text == "not run");
    }
    assert!(!columns.is_empty());
    for ((measure, group), (cells, not_run)) in &columns {
        assert!(not_run < cells, "{measure} {group}: every cell is \"not run\"");
    }
    // The summary comes first: counts, then the failure with its error text, then the slowest jobs.
    let summary = page.find("id=\"summary\"").expect("a summary");
    assert!(summary < page.find("data-section=").unwrap(), "the summary leads the page");
    let count =
        |k: &str| all.iter().find(|t| t.attrs.get("data-count").map(String::as_str) == Some(k)).map(|t| t.attrs["data-value"].clone());
    assert_eq!(count("jobs").as_deref(), Some("7"));
    assert_eq!(count("failed").as_deref(), Some("1"));
    let failure = all
        .iter()
        .find(|t| t.name == "li" && t.attrs.get("data-job").map(String::as_str) == Some("quilt/broken.toml"))
        .expect("failure listed");
    assert!(failure.text.contains("blocked.png"), "the error text is shown: {}", failure.text);
    assert!(page.contains("class=\"slowest\""));
    // Each section has its own overview with every seed.
    for s in ["quilt", "seams", "tiles"] {
        assert!(dir.join(format!("sections/{s}/sheets/overview.png")).is_file(), "{s}: overview");
    }
    let pages = overview_pages(&dir.join("sections/quilt/sheets"));
    for seed in 1..=3 {
        let img = decode(&out.join(format!("quilt/a{seed}.png")));
        assert!(pages.iter().any(|p| find(p, &img).is_some()), "seed {seed} on the quilt overview");
    }
}

#[test]
fn a_report_replaces_its_own_stale_files_and_refuses_a_foreign_page() {
    let out = mixed_run();
    let dir = scratch("stale").join("report");
    let manifest = out.join("manifest.json");
    // First one section (files at the top), then per directory: the old layout's files go.
    run_ok(texsyn().arg("report").arg(&manifest).arg("-o").arg(&dir).args(["--sections", "one"]));
    assert!(dir.join("sheets/overview.png").is_file() && dir.join("tables/all.csv").is_file());
    std::fs::write(dir.join("notes.txt"), "mine").unwrap();
    let o = run_ok(texsyn().arg("report").arg(&manifest).arg("-o").arg(&dir));
    assert!(text(&o).contains("stale files of the previous report removed"), "{}", text(&o));
    assert!(!dir.join("sheets").exists() && !dir.join("tables").exists(), "the old layout is gone");
    assert!(dir.join("sections/quilt/sheets/overview.png").is_file());
    assert_eq!(std::fs::read_to_string(dir.join("notes.txt")).unwrap(), "mine", "files the report did not write stay");
    let listed = std::fs::read_to_string(dir.join(".texsyn-report")).unwrap();
    for f in walk(&dir) {
        let rel = f.strip_prefix(&dir).unwrap().to_string_lossy().into_owned();
        assert!(rel == "notes.txt" || rel.starts_with(".texsyn") || listed.lines().any(|l| l == rel), "{rel} is not listed");
    }
    // A page this tool did not list: refused, nothing touched.
    let foreign = scratch("foreign").join("report");
    std::fs::create_dir_all(&foreign).unwrap();
    std::fs::write(foreign.join("index.html"), "<p>someone else's</p>").unwrap();
    let o = run_expect(texsyn().arg("report").arg(&manifest).arg("-o").arg(&foreign), 2);
    assert!(text(&o).contains("without the list of its files"), "{}", text(&o));
    assert_eq!(std::fs::read_to_string(foreign.join("index.html")).unwrap(), "<p>someone else's</p>");
}

#[test]
fn golden_mismatches_lead_the_page_with_the_new_image() {
    let out = mixed_run();
    let d = scratch("golden-report");
    let golden = d.join("golden");
    run_ok(texsyn().args(["golden", "bless"]).arg(&golden).arg(out.join("manifest.json")));
    // Someone's change moved one output: its golden digest no longer matches.
    let file = golden.join("tiles/w.json");
    let text_before = std::fs::read_to_string(&file).unwrap();
    let digest = pixels(&out.join("tiles/w.png"));
    std::fs::write(&file, text_before.replace(&digest, &"0".repeat(64))).unwrap();
    let dir = d.join("report");
    run_ok(texsyn().arg("report").arg(out.join("manifest.json")).arg("-o").arg(&dir).arg("--golden").arg(&golden));
    let page = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let all = tags(&page);
    let g = all.iter().find(|t| t.attrs.contains_key("data-golden-mismatched")).expect("a golden block");
    assert_eq!(g.attrs["data-golden-mismatched"], "1");
    assert_eq!(g.attrs["data-golden-matched"], "5");
    let change =
        all.iter().find(|t| t.name == "div" && t.attrs.get("data-job").map(String::as_str) == Some("tiles/w.toml")).expect("panels");
    assert_eq!(change.attrs["data-source"], "golden");
    assert!(page.contains("golden/ keeps digests, not images"), "says why there is no old image");
    assert!(page.find("id=\"changes\"").unwrap() < page.find("data-section=").unwrap(), "changes before the sections");
}
