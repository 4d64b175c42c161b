//! Which jobs share a section of the report.
//!
//! A nightly run mixes many job directories (a paper's sweep, a method's examples, tile sets):
//! one table over all of them has a column for every method × setting and a sea of "not run"
//! cells. So the report cuts the manifest into sections, each with the tables, sheets and plot of
//! its own jobs. The cut follows the job directories, which is how users organise work, but not
//! blindly: a paper's directory whose subdirectories only split a sweep (paper 003's `b50/` and
//! `b100/`, the same two methods at two block sizes) stays one section, so its table still puts
//! B = 50 next to B = 100.

use crate::batch::manifest::Manifest;
use std::collections::{BTreeMap, BTreeSet};

/// How the report is cut into sections (`--sections`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Sections {
    /// Split a directory into its subdirectories only where they use different sets of methods.
    #[default]
    Auto,
    /// One section per directory that holds job files.
    Dir,
    /// Everything in one section.
    One,
}

impl std::str::FromStr for Sections {
    type Err = String;
    fn from_str(s: &str) -> Result<Sections, String> {
        match s.trim() {
            "auto" => Ok(Sections::Auto),
            "dir" => Ok(Sections::Dir),
            "one" => Ok(Sections::One),
            other => Err(format!("unknown sectioning `{other}`: use auto, dir or one")),
        }
    }
}

/// A part of the report: a job directory (relative to the directory the run was given) and the
/// indices of its jobs in the manifest.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Section {
    /// `papers/003`; empty for jobs at the top of the run.
    pub name: String,
    pub jobs: Vec<usize>,
}

impl Section {
    /// How a reader sees the section's name.
    pub fn title(&self) -> String {
        if self.name.is_empty() { "jobs at the top of the run".into() } else { format!("{}/", self.name) }
    }
}

/// A directory of job ids: its own jobs and its subdirectories.
#[derive(Default)]
struct Node {
    own: Vec<usize>,
    children: BTreeMap<String, Node>,
}

impl Node {
    fn all(&self, out: &mut Vec<usize>) {
        out.extend(&self.own);
        for c in self.children.values() {
            c.all(out);
        }
    }
}

/// The directory part of a job id (`papers/003/b50/x.toml#seed=1` → `papers/003/b50`).
fn directory(id: &str) -> Vec<&str> {
    let file = id.split('#').next().unwrap_or(id);
    let mut parts: Vec<&str> = file.split('/').collect();
    parts.pop();
    parts
}

/// Cuts the manifest's jobs into sections, in directory order; every job is in exactly one.
pub fn partition(manifest: &Manifest, how: Sections) -> Vec<Section> {
    let all: Vec<usize> = (0..manifest.jobs.len()).collect();
    if how == Sections::One || manifest.jobs.is_empty() {
        return vec![Section { name: String::new(), jobs: all }];
    }
    let mut root = Node::default();
    for (i, j) in manifest.jobs.iter().enumerate() {
        let mut node = &mut root;
        for part in directory(&j.id) {
            node = node.children.entry(part.to_string()).or_default();
        }
        node.own.push(i);
    }
    let methods = |jobs: &[usize]| -> BTreeSet<&str> { jobs.iter().filter_map(|&i| manifest.jobs[i].method.as_deref()).collect() };
    let mut out = Vec::new();
    cut(&root, String::new(), how, &methods, &mut out);
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}

fn cut<'m>(node: &Node, name: String, how: Sections, methods: &dyn Fn(&[usize]) -> BTreeSet<&'m str>, out: &mut Vec<Section>) {
    let keep_whole = match how {
        Sections::One => true,
        Sections::Dir => node.children.is_empty(),
        Sections::Auto => {
            // The method sets of the directory's own jobs and of each subdirectory; one section if
            // they all agree (jobs with no method, i.e. invalid ones, do not count against it).
            let mut sets: Vec<BTreeSet<&str>> = Vec::new();
            if !node.own.is_empty() {
                sets.push(methods(&node.own));
            }
            for c in node.children.values() {
                let mut jobs = Vec::new();
                c.all(&mut jobs);
                sets.push(methods(&jobs));
            }
            let sets: Vec<&BTreeSet<&str>> = sets.iter().filter(|s| !s.is_empty()).collect();
            sets.windows(2).all(|w| w[0] == w[1])
        }
    };
    if keep_whole {
        let mut jobs = Vec::new();
        node.all(&mut jobs);
        if !jobs.is_empty() {
            jobs.sort_unstable();
            out.push(Section { name, jobs });
        }
        return;
    }
    if !node.own.is_empty() {
        out.push(Section { name: name.clone(), jobs: node.own.clone() });
    }
    for (child, c) in &node.children {
        let sub = if name.is_empty() { child.clone() } else { format!("{name}/{child}") };
        cut(c, sub, how, methods, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn manifest(jobs: &[(&str, &str)]) -> Manifest {
        let d = json!({"sha256": "00"});
        let jobs: Vec<serde_json::Value> = jobs
            .iter()
            .map(|(id, method)| {
                let method = if method.is_empty() { serde_json::Value::Null } else { json!(method) };
                json!({"id": id, "job_file": {"path": "j.toml", "digest": d}, "status": "ok", "method": method})
            })
            .collect();
        serde_json::from_value(json!({
            "format": crate::batch::manifest::FORMAT,
            "tool": {"name": "texsyn", "version": "0", "commit": "x"},
            "deterministic_digest": d,
            "jobs": jobs,
            "run": crate::batch::manifest::RunFacts::default(),
        }))
        .expect("a manifest")
    }

    fn names(s: &[Section]) -> Vec<(&str, usize)> {
        s.iter().map(|s| (s.name.as_str(), s.jobs.len())).collect()
    }

    #[test]
    fn directories_split_only_where_their_methods_differ() {
        let m = manifest(&[
            ("quilting/a.toml#seed=1", "quilting"),
            ("quilting/a.toml#seed=2", "quilting"),
            ("tiles/w.toml", "wang-tiles"),
            ("papers/003/b50/x.toml", "double-seam"),
            ("papers/003/b50/y.toml", "quilting"),
            ("papers/003/b100/x.toml", "double-seam"),
            ("papers/003/b100/y.toml", "quilting"),
            ("papers/000/c.toml", "coevolution"),
            ("top.toml", "tes"),
        ]);
        let s = partition(&m, Sections::Auto);
        assert_eq!(names(&s), [("", 1), ("papers/000", 1), ("papers/003", 4), ("quilting", 2), ("tiles", 1)]);
        let s = partition(&m, Sections::Dir);
        assert_eq!(names(&s), [("", 1), ("papers/000", 1), ("papers/003/b100", 2), ("papers/003/b50", 2), ("quilting", 2), ("tiles", 1)]);
        assert_eq!(names(&partition(&m, Sections::One)), [("", 9)]);
        // Every job exactly once.
        let mut seen: Vec<usize> = partition(&m, Sections::Auto).into_iter().flat_map(|s| s.jobs).collect();
        seen.sort();
        assert_eq!(seen, (0..9).collect::<Vec<_>>());
    }

    #[test]
    fn one_directory_of_one_kind_is_one_section() {
        let m = manifest(&[("b50/x.toml", "double-seam"), ("b100/x.toml", "double-seam"), ("b100/bad.toml", "")]);
        assert_eq!(names(&partition(&m, Sections::Auto)), [("", 3)]);
        assert_eq!("dir".parse::<Sections>(), Ok(Sections::Dir));
        assert!("by-method".parse::<Sections>().unwrap_err().contains("auto, dir or one"));
    }
}
