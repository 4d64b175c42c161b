//! Output paths: `{seed}`, `{method}` and `{<param>}` templates, and the check that a path stays
//! inside the output directory.

use crate::synth::params::Params;
use std::path::{Component, Path};

/// Replaces `{seed}`, `{method}` and `{<param>}` in an output path template.
pub fn expand_template(template: &str, method: &str, seed: u64, params: &Params) -> Result<String, String> {
    let mut out = String::new();
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        let close = after.find('}').ok_or_else(|| format!("unclosed `{{` in output path `{template}`"))?;
        let name = &after[..close];
        let value = match name {
            "seed" => seed.to_string(),
            "method" => method.to_string(),
            _ => match params.get(name) {
                Some(v) => v.display(),
                None => {
                    let mut valid: Vec<&str> = vec!["seed", "method"];
                    valid.extend(params.0.keys().map(String::as_str));
                    return Err(format!("unknown placeholder `{{{name}}}` in output path; available: {}", valid.join(", ")));
                }
            },
        };
        out.push_str(&value);
        rest = &after[close + 1..];
    }
    if rest.contains('}') {
        return Err(format!("unmatched `}}` in output path `{template}`"));
    }
    out.push_str(rest);
    Ok(out)
}

/// Checks that an output path stays inside the output directory and normalises it to a relative,
/// `/`-separated path without `.` components.
pub fn normalise_output_path(path: &str) -> Result<String, String> {
    if path.contains('\0') {
        return Err("output path contains a NUL byte".into());
    }
    let p = Path::new(path);
    let mut parts = Vec::new();
    for c in p.components() {
        match c {
            Component::Normal(s) => {
                let s = s.to_string_lossy();
                if s.starts_with('.') && s.ends_with(".tmp") {
                    return Err(format!("output path `{path}` uses a reserved temporary-file name"));
                }
                parts.push(s.into_owned())
            }
            Component::CurDir => {}
            Component::ParentDir => {
                return Err(format!("output path `{path}` must stay inside the output directory (no `..`)"));
            }
            Component::RootDir | Component::Prefix(_) => {
                return Err(format!("output path `{path}` must be relative to the output directory, not absolute"));
            }
        }
    }
    if parts.is_empty() {
        return Err(format!("output path `{path}` names no file"));
    }
    if parts.len() == 1 && parts[0] == "manifest.json" {
        return Err("output path `manifest.json` is reserved for the manifest".into());
    }
    Ok(parts.join("/"))
}
