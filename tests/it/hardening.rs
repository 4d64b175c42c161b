//! Issue #29's attacks, each as a hostile or careless user would try it: manifests made elsewhere
//! naming files outside the directories they belong to, links planted where texsyn writes, two
//! job trees in one output directory, outputs inside another job's export, a forced run killed
//! early, fills and manifests sized to exhaust memory, job files of endless unknown keys. Each
//! must end in a clear message with the documented exit code, change nothing outside the output
//! (or golden) directory, and lose no manifest entry.

use crate::common::*;

const SAMPLE: &str = "jobs/samples/pebbles_beige.png";

/// A job tree under `root/name` with quilting jobs `g.toml` (output `out_png`) and any others.
fn tree(root: &Path, name: &str, jobs: &[(&str, &str)]) -> PathBuf {
    let dir = root.join(name);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(repo().join(SAMPLE), dir.join("s.png")).unwrap();
    for (file, output) in jobs {
        std::fs::create_dir_all(dir.join(file).parent().unwrap()).unwrap();
        let body = format!(
            "sample = \"{up}s.png\"\nmethod = \"quilting\"\nseed = 3\n[output]\npath = \"{output}\"\nwidth = 96\nheight = 96\n[params]\nblock = 24\n",
            up = "../".repeat(file.matches('/').count())
        );
        std::fs::write(dir.join(file), body).unwrap();
    }
    dir
}

/// A run of one small job, and its manifest as JSON.
fn one_run(root: &Path) -> (PathBuf, Value) {
    let jobs = tree(root, "jobs", &[("sub/g.toml", "g.png")]);
    let out = root.join("out");
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(&jobs));
    let m = out.join("manifest.json");
    let v = json(&m);
    (m, v)
}

/// Every file under `root` (not following links) with a digest of its bytes; the output
/// directory's lock file (which a refused run also takes) is left out.
fn files(root: &Path) -> BTreeMap<PathBuf, String> {
    fn walk(dir: &Path, out: &mut BTreeMap<PathBuf, String>) {
        let Ok(entries) = std::fs::read_dir(dir) else { return };
        for e in entries.flatten() {
            let p = e.path();
            let ft = e.file_type().unwrap();
            if ft.is_dir() {
                walk(&p, out);
            } else if p.file_name().is_some_and(|n| n == ".texsyn.lock") {
                continue;
            } else if ft.is_file() {
                out.insert(p.clone(), texsyn::digest::Digest::of_bytes(&std::fs::read(&p).unwrap()).sha256);
            } else {
                out.insert(p.clone(), "<link>".into());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(root, &mut out);
    out
}

#[test]
fn manifest_ids_and_paths_that_leave_their_directory_are_refused_by_every_command() {
    let root = scratch("hostile-ids");
    let (good, manifest) = one_run(&root);
    let outside = scratch("hostile-ids-target");
    let golden = root.join("deep/er/golden");
    std::fs::create_dir_all(&golden).unwrap();
    let absolute = format!("{}/x.toml", outside.display());
    let bad_ids = ["../../escaped.toml", absolute.as_str(), "a/../../../b.toml", "sub/./g.toml", "sub//g.toml", "a\\..\\b.toml"];
    for (k, bad) in bad_ids.iter().enumerate() {
        let mut m = manifest.clone();
        m["jobs"][0]["id"] = Value::String(bad.to_string());
        let path = root.join(format!("out/hostile-{k}.json"));
        std::fs::write(&path, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
        let report = root.join(format!("report-{k}"));
        let fragment_dir = root.join(format!("frag-{k}"));
        std::fs::create_dir_all(&fragment_dir).unwrap();
        let mut fragment = m.clone();
        fragment["run"]["shard"] = serde_json::json!({
            "index": 0, "count": 1, "plan_jobs": 1, "assigned": 1, "host": "h",
            "plan_digest": {"sha256": "00"}
        });
        std::fs::write(fragment_dir.join("manifest.shard-0-of-1.json"), serde_json::to_vec_pretty(&fragment).unwrap()).unwrap();
        let before = files(&root);
        let outside_before = files(&outside);
        let p = path.to_str().unwrap();
        let commands: Vec<Vec<String>> = vec![
            vec!["golden".into(), "bless".into(), golden.display().to_string(), p.into()],
            vec!["golden".into(), "check".into(), golden.display().to_string(), p.into()],
            vec!["verify".into(), p.into()],
            vec!["diff".into(), good.display().to_string(), p.into()],
            vec!["report".into(), p.into(), "-o".into(), report.display().to_string()],
            vec!["merge".into(), fragment_dir.display().to_string(), "-o".into(), fragment_dir.join("merged.json").display().to_string()],
        ];
        for args in commands {
            let out = texsyn_args(&args.iter().map(String::as_str).collect::<Vec<_>>());
            let said = text(&out);
            assert_eq!(out.status.code(), Some(2), "{args:?} with id {bad:?}:\n{said}");
            assert!(said.contains("`id`") && said.contains("not a relative path inside the job root"), "{args:?}: {said}");
            assert!(said.contains("hostile-") || said.contains("manifest.shard-0-of-1.json"), "names the file: {said}");
        }
        let after = files(&root);
        let new: Vec<_> = after.keys().filter(|p| !before.contains_key(*p)).collect();
        assert!(new.is_empty(), "id {bad:?} made files: {new:?}");
        assert_eq!(outside_before, files(&outside), "id {bad:?} wrote outside");
        assert!(!root.join("deep/escaped.json").exists() && !root.join("escaped.json").exists());
    }
    // The untouched manifest still blesses, into the golden directory only.
    run_ok(texsyn().args(["golden", "bless"]).arg(&golden).arg(&good));
    assert!(golden.join("sub/g.json").is_file());
}

#[test]
fn a_symlink_in_the_golden_directory_cannot_carry_a_write_outside() {
    let root = scratch("golden-link");
    let (good, _) = one_run(&root);
    let golden = root.join("golden");
    let elsewhere = scratch("golden-link-target");
    std::fs::create_dir_all(&golden).unwrap();
    std::os::unix::fs::symlink(&elsewhere, golden.join("sub")).unwrap();
    let out = run_expect(texsyn().args(["golden", "bless"]).arg(&golden).arg(&good), 2);
    assert!(text(&out).contains("outside the golden directory"), "{}", text(&out));
    assert!(files(&elsewhere).is_empty(), "wrote through the link");
}

#[test]
fn sizes_and_paths_in_a_manifest_are_bounded_before_anything_is_allocated() {
    let root = scratch("hostile-sizes");
    let (_, manifest) = one_run(&root);
    let cases: Vec<(&str, Value, &str)> = vec![
        ("/output_spec/width", serde_json::json!(4_000_000_000u64), "`output_spec.width`: 4000000000 is out of range 1..=65536"),
        ("/output_spec/height", serde_json::json!(0), "`output_spec.height`: 0 is out of range"),
        ("/output_spec/path", serde_json::json!("../../x.png"), "`output_spec.path`"),
        ("/output_spec/source_map", serde_json::json!("/etc/x.exr"), "`output_spec.source_map`"),
        ("/outputs/0/width", serde_json::json!(100_000), "`outputs[0].width`: 100000 is out of range"),
        ("/sample/height", serde_json::json!(3_000_000_000u64), "`sample.height`"),
        ("/output_spec/bit_depth", serde_json::json!(200), "`output_spec.bit_depth`"),
    ];
    for (pointer, value, expected) in cases {
        let mut m = manifest.clone();
        // Set (or add) the key at the pointer in the first job's record.
        let (parent, key) = pointer.rsplit_once('/').unwrap();
        let parent = m["jobs"][0].pointer_mut(parent).unwrap_or_else(|| panic!("{pointer}"));
        match parent {
            Value::Array(a) => a[key.parse::<usize>().unwrap()] = value,
            other => other[key] = value,
        }
        let path = root.join("out/sized.json");
        std::fs::write(&path, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
        for args in [vec!["verify"], vec!["golden", "check", "golden"]] {
            let mut cmd = texsyn();
            cmd.args(&args).arg(&path).current_dir(&root);
            let out = run_expect(&mut cmd, 2);
            let said = text(&out);
            assert!(said.contains(expected) && said.contains("sized.json") && said.contains("job `sub/g.toml`"), "{pointer}: {said}");
        }
    }
}

#[test]
fn verify_keeps_to_max_memory_and_says_which_jobs_it_did_not_run() {
    let root = scratch("verify-memory");
    let (m, _) = one_run(&root);
    let out = run_expect(texsyn().args(["verify", "--max-memory", "1M"]).arg(&m), 1);
    let said = text(&out);
    assert!(said.contains("NOT RUN   sub/g.toml") && said.contains("--max-memory is 1.0 MiB"), "{said}");
    run_ok(texsyn().args(["verify", "--max-memory", "1G"]).arg(&m));
}

#[test]
fn the_lock_file_is_never_written_through_a_link() {
    let root = scratch("lock-link");
    let jobs = tree(&root, "jobs", &[("g.toml", "g.png")]);
    let victim = root.join("victim.txt");
    for (kind, link) in [("symlink", true), ("hard link", false)] {
        std::fs::write(&victim, b"precious").unwrap();
        let out = root.join(format!("out-{}", u8::from(link)));
        std::fs::create_dir_all(&out).unwrap();
        if link {
            std::os::unix::fs::symlink(&victim, out.join(".texsyn.lock")).unwrap();
        } else {
            std::fs::hard_link(&victim, out.join(".texsyn.lock")).unwrap();
        }
        let o = run_expect(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(&jobs), 2);
        assert!(text(&o).contains(".texsyn.lock") && text(&o).contains(kind), "{kind}: {}", text(&o));
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious", "{kind}: the lock wrote through it");
        assert!(!out.join("manifest.json").exists());
    }
    // A shard's own lock likewise.
    let out = root.join("out-shard");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(&victim, out.join(".texsyn.shard-0-of-2.lock")).unwrap();
    run_expect(texsyn().args(["run", "-q", "--shard", "0/2", "-o"]).arg(&out).arg(&jobs), 2);
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
}

#[test]
fn two_job_trees_in_one_output_directory_are_refused_unless_asked() {
    let root = scratch("two-trees");
    let a = tree(&root, "treeA", &[("g.toml", "a/g.png"), ("h.toml", "a/h.png")]);
    let b = tree(&root, "treeB", &[("g.toml", "b/g.png")]);
    let out = root.join("out");
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(&a));
    let manifest = std::fs::read(out.join("manifest.json")).unwrap();
    let before = files(&out);
    for extra in [&[][..], &["--dry-run"][..], &["--force"][..]] {
        let o = run_expect(texsyn().args(["run", "-q"]).args(extra).arg("-o").arg(&out).arg(&b), 2);
        let said = text(&o);
        let (ra, rb) = (a.canonicalize().unwrap(), b.canonicalize().unwrap());
        assert!(said.contains(&*ra.to_string_lossy()) && said.contains(&*rb.to_string_lossy()), "{extra:?}: names both roots: {said}");
        assert!(said.contains("--allow-other-root"), "{said}");
        assert_eq!(std::fs::read(out.join("manifest.json")).unwrap(), manifest, "{extra:?}: manifest changed");
        assert_eq!(files(&out), before, "{extra:?}: files changed");
    }
    // The same root again is fine, from a job file inside it too.
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(&a));
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(a.join("h.toml")));
    // Asked for: both roots recorded, treeB's g.toml replaces treeA's, h.toml stays.
    run_ok(texsyn().args(["run", "-q", "--allow-other-root", "-o"]).arg(&out).arg(&b));
    let m = json(&out.join("manifest.json"));
    let ids: Vec<&str> = m["jobs"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap()).collect();
    assert_eq!(ids, ["g.toml", "h.toml"]);
    assert_eq!(m["jobs"][0]["outputs"][0]["path"], "b/g.png");
    assert_eq!(m["run"]["job_roots"].as_array().unwrap().len(), 2, "{}", m["run"]);
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
}

#[test]
fn an_output_inside_another_jobs_tile_export_is_refused() {
    let root = scratch("export-clash");
    let jobs = root.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    std::fs::copy(repo().join(SAMPLE), jobs.join("s.png")).unwrap();
    std::fs::write(
        jobs.join("tiles.toml"),
        "sample = \"s.png\"\nmethod = \"rw-tiles\"\nseed = 11\n[output]\npath = \"t.png\"\nwidth = 256\nheight = 256\n[params]\ntile = 64\noverlap = 8\nexport_tiles = true\n",
    )
    .unwrap();
    std::fs::write(
        jobs.join("inside.toml"),
        "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 3\n[output]\npath = \"t.tiles/tile_00.png\"\nwidth = 96\nheight = 96\n[params]\nblock = 24\n",
    )
    .unwrap();
    std::fs::write(
        jobs.join("fine.toml"),
        "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 3\n[output]\npath = \"t.tiles.png\"\nwidth = 96\nheight = 96\n[params]\nblock = 24\n",
    )
    .unwrap();
    let out = root.join("out");
    let o = run_expect(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(&jobs), 1);
    let said = text(&o);
    assert!(said.contains("`t.tiles/tile_00.png` lies in `t.tiles/`"), "{said}");
    assert!(said.contains("its extras folder `t.tiles/`"), "{said}");
    let m = json(&out.join("manifest.json"));
    let status: BTreeMap<&str, &str> =
        m["jobs"].as_array().unwrap().iter().map(|j| (j["id"].as_str().unwrap(), j["status"].as_str().unwrap())).collect();
    assert_eq!(status, BTreeMap::from([("fine.toml", "ok"), ("inside.toml", "invalid"), ("tiles.toml", "invalid")]));
    run_ok(texsyn().arg("verify").arg(out.join("manifest.json")));
}

#[test]
fn a_forced_run_killed_early_keeps_every_earlier_record() {
    let root = scratch("force-kill");
    let jobs: Vec<(String, String)> = (0..4).map(|k| (format!("j{k}.toml"), format!("j{k}.png"))).collect();
    let refs: Vec<(&str, &str)> = jobs.iter().map(|(a, b)| (a.as_str(), b.as_str())).collect();
    let dir = tree(&root, "jobs", &refs);
    // Larger outputs, so that the forced run is still busy when it is killed.
    for (file, _) in &jobs {
        let p = dir.join(file);
        let body = std::fs::read_to_string(&p).unwrap().replace("width = 96", "width = 640").replace("height = 96", "height = 640");
        std::fs::write(&p, body).unwrap();
    }
    let out = root.join("out");
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(&dir));
    let manifest = out.join("manifest.json");
    let first = json(&manifest);
    let mut child = texsyn().args(["run", "-q", "--force", "-j", "1", "-o"]).arg(&out).arg(&dir).spawn().unwrap();
    // Kill it as soon as it has rewritten the manifest for the first time (in progress).
    let started = Instant::now();
    loop {
        if let Ok(bytes) = std::fs::read(&manifest)
            && let Ok(v) = serde_json::from_slice::<Value>(&bytes)
            && v["run"]["in_progress"] == true
        {
            break;
        }
        assert!(started.elapsed() < Duration::from_secs(60), "the forced run never wrote its manifest");
        std::thread::sleep(Duration::from_millis(1));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let after = json(&manifest);
    let ids = |v: &Value| -> Vec<String> { v["jobs"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap().to_string()).collect() };
    assert_eq!(ids(&after), ids(&first), "records lost by a killed --force run");
    assert!(after["run"]["in_progress"] == true);
    assert!(after["run"]["rerunning"].as_array().is_some_and(|r| !r.is_empty()), "the earlier records are marked: {}", after["run"]);
    run_ok(texsyn().arg("verify").arg(&manifest));
    // Resumed, it finishes with nothing marked.
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(&dir));
    assert!(json(&manifest)["run"].get("rerunning").is_none());
}

#[test]
fn tiles_render_keeps_to_max_memory_and_renders_large_fills_in_strips() {
    let root = scratch("tiles-memory");
    let out = root.join("out");
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(repo().join("jobs/tiles/rw_tiles_pebbles_beige_export.toml")));
    let index = out.join("tiles/export/rw_pebbles_beige.tiles/index.json");
    let started = Instant::now();
    let o = run_expect(
        texsyn()
            .args(["tiles", "render", "--width", "65536", "--height", "65536", "--max-memory", "2G", "-o"])
            .arg(root.join("big.exr"))
            .arg(&index),
        2,
    );
    assert!(text(&o).contains("needs about") && text(&o).contains("--max-memory is 2.0 GiB"), "{}", text(&o));
    assert!(started.elapsed() < Duration::from_secs(30), "refused before rendering");
    assert!(!root.join("big.exr").exists());
    // A PNG of 4096² fits in 64 MiB: it never holds the 48 MiB image.
    let big = root.join("big.png");
    run_ok(texsyn().args(["tiles", "render", "--width", "4096", "--height", "4096", "--max-memory", "64M", "-o"]).arg(&big).arg(&index));
    let img = imageio::decode_native(&std::fs::read(&big).unwrap(), DecodeLimits::default()).unwrap();
    assert_eq!((img.width, img.height), (4096, 4096));
    // Rendered in strips, the job's own fill is the job's own pixels.
    let own = root.join("own.png");
    run_ok(texsyn().args(["tiles", "render", "-o"]).arg(&own).arg(&index));
    let m = json(&out.join("manifest.json"));
    let recorded = m["jobs"][0]["outputs"].as_array().unwrap().iter().find(|o| o["path"] == "tiles/export/rw_pebbles_beige.png").unwrap()
        ["pixel_digest"]
        .clone();
    let rendered = imageio::decode_native(&std::fs::read(&own).unwrap(), DecodeLimits::default()).unwrap().pixel_digest();
    assert_eq!(serde_json::to_value(rendered).unwrap(), recorded);
}

#[test]
fn a_job_file_of_endless_unknown_keys_is_answered_at_once_with_a_short_list() {
    let root = scratch("unknown-keys");
    let dir = tree(&root, "jobs", &[]);
    let head = "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"o.png\"\nwidth = 64\nheight = 64\n[params]\n";
    let mut keys = String::new();
    let mut n = 0;
    while keys.len() < 10_000_000 {
        keys.push_str(&format!("unknown_parameter_{n:06}_padded_to_make_a_big_file_xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx = {n}\n"));
        n += 1;
    }
    // A typo after 80 000 unknown keys is counted with them; one among the first is suggested.
    std::fs::write(dir.join("big.toml"), format!("{head}{keys}blok = 3\n")).unwrap();
    let out = run_expect(texsyn().args(["run", "-q", "-o"]).arg(root.join("out")).arg(&dir), 1);
    let said = text(&out);
    assert!(said.contains(&format!("… and {} more unknown key(s) after the first 20", n + 1 - 20)), "{}", &said[..said.len().min(3000)]);
    assert!(said.lines().count() < 60, "{} lines", said.lines().count());
    std::fs::write(dir.join("big.toml"), format!("{head}blok = 3\n{keys}")).unwrap();
    let said = text(&run_expect(texsyn().args(["run", "-q", "-o"]).arg(root.join("out")).arg(&dir), 1));
    assert!(said.contains("did you mean `block`?"), "{}", &said[..said.len().min(3000)]);
}

#[test]
fn samples_that_are_devices_or_fifos_are_refused_without_reading_them() {
    let root = scratch("device-sample");
    let dir = tree(&root, "jobs", &[]);
    let fifo = dir.join("pipe.png");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    for (name, sample) in [("zero.toml", "/dev/zero"), ("fifo.toml", "pipe.png")] {
        std::fs::write(
            dir.join(name),
            format!("sample = \"{sample}\"\nmethod = \"quilting\"\nseed = 1\n[output]\npath = \"{name}.png\"\nwidth = 64\nheight = 64\n"),
        )
        .unwrap();
    }
    let out = run_expect(texsyn().args(["run", "-q", "-o"]).arg(root.join("out")).arg(&dir), 1);
    let said = text(&out);
    assert_eq!(said.matches("is not a file").count(), 2, "{said}");
    // A manifest names its sample freely: verify's bounded read refuses the device at once.
    let (m, mut v) = one_run(&scratch("device-sample-manifest"));
    v["jobs"][0]["sample"]["path"] = Value::String("/dev/zero".into());
    std::fs::write(&m, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
    let said = text(&run_expect(texsyn().arg("verify").arg(&m), 3));
    assert!(said.contains("/dev/zero") && said.contains("not a regular file"), "{said}");
}

#[test]
fn apply_weighs_a_source_map_before_decoding_it() {
    let root = scratch("apply-memory");
    let dir = tree(&root, "jobs", &[]);
    std::fs::write(
        dir.join("m.toml"),
        "sample = \"s.png\"\nmethod = \"quilting\"\nseed = 3\n[output]\npath = \"m.png\"\nwidth = 96\nheight = 96\nsource_map = \"m.exr\"\n[params]\nblock = 24\n",
    )
    .unwrap();
    let out = root.join("out");
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(&out).arg(&dir));
    let o = run_expect(
        texsyn().args(["apply", "--max-memory", "1M"]).arg(out.join("m.exr")).arg(dir.join("s.png")).arg("-o").arg(root.join("a.png")),
        2,
    );
    assert!(text(&o).contains("rendering this 96x96 map needs about"), "{}", text(&o));
    assert!(!root.join("a.png").exists());
    run_ok(texsyn().arg("apply").arg(out.join("m.exr")).arg(dir.join("s.png")).arg("-o").arg(root.join("a.png")));
    // Applied over its own sample, the map gives the job's output.
    let a = imageio::decode_native(&std::fs::read(root.join("a.png")).unwrap(), DecodeLimits::default()).unwrap();
    let m = imageio::decode_native(&std::fs::read(out.join("m.png")).unwrap(), DecodeLimits::default()).unwrap();
    assert_eq!(a.pixel_digest(), m.pixel_digest());
}

#[test]
fn slurm_scripts_and_report_listings_do_not_follow_planted_links() {
    let root = scratch("slurm-link");
    let jobs = tree(&root, "jobs", &[("g.toml", "g.png")]);
    let out = root.join("out");
    let elsewhere = scratch("slurm-link-target");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("slurm")).unwrap();
    let o = run_expect(texsyn().args(["slurm", "--shards", "2", "-o"]).arg(&out).arg(&jobs), 2);
    assert!(text(&o).contains("outside the output directory"), "{}", text(&o));
    assert!(files(&elsewhere).is_empty());
    // A report directory whose file listing is a device: refused, not read forever.
    let (m, _) = one_run(&scratch("report-listing"));
    let report = root.join("report");
    std::fs::create_dir_all(&report).unwrap();
    std::os::unix::fs::symlink("/dev/zero", report.join(".texsyn-report")).unwrap();
    let o = run(texsyn().arg("report").arg(&m).arg("-o").arg(&report));
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("not a regular file"), "{}", text(&o));
}
