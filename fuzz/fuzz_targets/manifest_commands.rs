//! Any bytes as a manifest handed to the commands that act on one: `verify`, `golden check` and
//! `golden bless`, `merge` (as a shard fragment), `diff` and `report`. Each must answer with a
//! result or an error, never panic, abort or allocate without bound; and none may write outside
//! the directory it was given: the workspace holds only what the commands own, and a canary
//! folder beside them stays empty.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use texsyn::batch::manifest::Manifest;

/// The workspace: `run/` (the manifest), `deep/er/golden/`, `frag/`, `report/`, and `canary/`.
fn workspace() -> &'static PathBuf {
    static WS: OnceLock<PathBuf> = OnceLock::new();
    WS.get_or_init(|| {
        let ws = std::env::temp_dir().join(format!("texsyn-fuzz-commands-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&ws);
        for d in ["run", "deep/er/golden", "frag", "report", "canary"] {
            std::fs::create_dir_all(ws.join(d)).unwrap();
        }
        ws
    })
}

/// Every path under `dir`, not following links.
fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        if e.file_type().is_ok_and(|t| t.is_dir()) {
            walk(&p, out);
        }
        out.push(p);
    }
}

fuzz_target!(|data: &[u8]| {
    let ws = workspace();
    let Ok(m) = Manifest::parse(Path::new("fuzz/manifest.json"), data) else { return };
    let manifest = ws.join("run/manifest.json");
    std::fs::write(&manifest, data).unwrap();
    // Re-runs are bounded like a run's: nothing bigger than 256 MiB starts.
    let _ = texsyn::batch::verify::verify_within(&manifest, Some(1), Some(256 << 20));
    let golden = ws.join("deep/er/golden");
    let _ = texsyn::batch::golden::check(&golden, &m);
    let _ = texsyn::batch::golden::bless(&golden, &m);
    let _ = texsyn::batch::diff::diff(&m, &m, &Default::default());
    let _ = texsyn::batch::diff::diff(&Manifest::new(Vec::new(), Default::default()), &m, &Default::default());
    std::fs::write(ws.join("frag/manifest.shard-0-of-1.json"), data).unwrap();
    let _ = texsyn::batch::merge::merge(&ws.join("frag"), None);
    let _ = texsyn::report::report(&texsyn::report::ReportOptions::new(&manifest, ws.join("report")));

    let mut found = Vec::new();
    walk(ws, &mut found);
    let allowed = ["run", "deep/er/golden", "frag", "report", "canary", "deep", "deep/er"];
    for p in &found {
        let rel = p.strip_prefix(ws).unwrap();
        let inside = allowed.iter().any(|a| rel == Path::new(a))
            || ["run", "deep/er/golden", "frag", "report"].iter().any(|a| rel.starts_with(a) && rel != Path::new(a));
        assert!(inside, "a command wrote {} outside the directory it was given", p.display());
    }
    // Clean up what the commands own, so that each input starts alike.
    for d in ["deep/er/golden", "report", "frag"] {
        let _ = std::fs::remove_dir_all(ws.join(d));
        std::fs::create_dir_all(ws.join(d)).unwrap();
    }
});
