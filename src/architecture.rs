//! The layer map in `lib.rs`, checked: every `crate::` and `super::` path in the library's
//! sources is read, and imports must go down the layers and form no circle. A change that
//! imports upward fails here with the file and the path, before it becomes a habit.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Top-level layers, lowest first. A module may import its own layer's modules and lower ones.
const LAYERS: &[&str] = &["files", "digest", "image", "metrics", "synth", "error", "synthesizer", "batch", "report"];

/// Inside `synth`, the same rule between its modules.
const SYNTH_LAYERS: &[&[&str]] = &[
    &["synth::error", "synth::rng"],
    &["synth::params"],
    &["synth::atlas", "synth::constraints", "synth::lattice", "synth::primitives", "synth::wrap"],
    &["synth::method"],
    &["synth::methods"],
    &["synth::advice"],
];

fn rank(module: &str) -> Option<(usize, usize)> {
    let top = module.split("::").next()?;
    let r = LAYERS.iter().position(|l| *l == top)?;
    let sub = if top == "synth" {
        SYNTH_LAYERS.iter().position(|group| group.iter().any(|g| module == *g || module.starts_with(&format!("{g}::")))).unwrap_or(0)
    } else {
        0
    };
    Some((r, sub))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("src is readable") {
        let path = entry.expect("entry").path();
        if path.is_dir() {
            if path.file_name().is_some_and(|n| n != "cli") {
                rust_files(&path, out);
            }
        } else if path.extension().is_some_and(|e| e == "rs") && path.file_name().is_some_and(|n| n != "main.rs") {
            out.push(path);
        }
    }
}

/// `src/a/b/mod.rs` → `a::b`, `src/a/b.rs` → `a::b`, `src/lib.rs` → ``.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).expect("under src").with_extension("");
    let mut parts: Vec<String> = rel.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
    if parts.last().is_some_and(|p| p == "mod" || p == "lib") {
        parts.pop();
    }
    parts.join("::")
}

/// The paths a line names, as module paths (`crate::a::b::C` → `a::b::C`; `super::x` resolved
/// against `parent`).
fn paths_in(line: &str, parent: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (prefix, base) in [("crate::", ""), ("super::", parent)] {
        let mut rest = line;
        while let Some(i) = rest.find(prefix) {
            let before = rest[..i].chars().last();
            rest = &rest[i + prefix.len()..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let path: String = rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':').collect();
            let path = path.trim_end_matches(':');
            if path.is_empty() || path.starts_with("super") {
                continue;
            }
            found.push(if base.is_empty() { path.to_string() } else { format!("{base}::{path}") });
        }
    }
    found
}

struct Graph {
    /// module → (imported module, the file and line that imports it)
    edges: BTreeMap<String, BTreeMap<String, String>>,
}

fn graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let modules: BTreeSet<String> = files.iter().map(|f| module_of(&src, f)).collect();
    let mut edges: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for file in &files {
        let module = module_of(&src, file);
        let is_mod_file = file.file_name().is_some_and(|n| n == "mod.rs" || n == "lib.rs");
        // In `a/b.rs` and in `a/b/mod.rs` alike, `super` is `a`.
        let parent = if is_mod_file || module.contains("::") { module.rsplit_once("::").map_or("", |p| p.0) } else { "" };
        let text = std::fs::read_to_string(file).expect("readable");
        // Unit tests may reach anywhere; only the code itself is layered.
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        for (n, line) in code.lines().enumerate() {
            let trimmed = line.trim_start();
            if trimmed.starts_with("//") {
                continue;
            }
            for path in paths_in(line, parent) {
                // The longest module that prefixes the path is what it imports.
                let target = modules
                    .iter()
                    .filter(|m| !m.is_empty() && (path == **m || path.starts_with(&format!("{m}::"))))
                    .max_by_key(|m| m.len());
                let Some(target) = target else { continue };
                let is_ancestor = module == *target || module.starts_with(&format!("{target}::"));
                if !is_ancestor {
                    let at = format!("{}:{}: {}", file.strip_prefix(&src).unwrap().display(), n + 1, trimmed.trim());
                    edges.entry(module.clone()).or_default().entry(target.clone()).or_insert(at);
                }
            }
        }
    }
    Graph { edges }
}

#[test]
fn imports_only_go_down_the_layers() {
    let g = graph();
    let mut upward = Vec::new();
    for (from, targets) in &g.edges {
        let Some(rf) = rank(from) else { continue };
        for (to, at) in targets {
            let Some(rt) = rank(to) else { continue };
            if rt > rf {
                upward.push(format!("{from} imports {to} (a higher layer) at {at}"));
            }
        }
    }
    assert!(upward.is_empty(), "upward imports:\n{}", upward.join("\n"));
    assert!(g.edges.len() > 20, "the scan found too few modules: {}", g.edges.len());
}

#[test]
fn modules_import_each_other_in_no_circle() {
    let g = graph();
    // Depth-first search for a back edge.
    fn visit<'a>(m: &'a str, g: &'a Graph, state: &mut BTreeMap<&'a str, u8>, stack: &mut Vec<&'a str>) -> Option<Vec<String>> {
        state.insert(m, 1);
        stack.push(m);
        for (to, at) in g.edges.get(m).into_iter().flatten() {
            match state.get(to.as_str()) {
                Some(1) => {
                    let start = stack.iter().position(|s| *s == to).unwrap_or(0);
                    let mut cycle: Vec<String> = stack[start..].iter().map(|s| s.to_string()).collect();
                    cycle.push(format!("{to}   (closing import: {at})"));
                    return Some(cycle);
                }
                Some(_) => {}
                None => {
                    if let Some(c) = visit(to, g, state, stack) {
                        return Some(c);
                    }
                }
            }
        }
        stack.pop();
        state.insert(m, 2);
        None
    }
    let mut state = BTreeMap::new();
    for m in g.edges.keys() {
        if !state.contains_key(m.as_str())
            && let Some(cycle) = visit(m, &g, &mut state, &mut Vec::new())
        {
            panic!("import circle:\n  {}", cycle.join("\n  → "));
        }
    }
}

#[test]
fn the_scanner_sees_paths_and_resolves_super() {
    assert_eq!(paths_in("use crate::synth::params::{Params, ParamSpec};", "x"), vec!["synth::params"]);
    assert_eq!(paths_in("    use super::align::{self, V};", "synth::methods::tiles"), vec!["synth::methods::tiles::align"]);
    assert_eq!(paths_in("let a = my_crate::x; // not ours", ""), Vec::<String>::new());
    assert_eq!(rank("synth::methods::tiles::export"), Some((4, 4)));
    assert!(rank("batch::run") > rank("synthesizer"));
    assert!(rank("synthesizer") > rank("error"));
}
