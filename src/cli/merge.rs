//! `texsyn merge`: one manifest from the fragments of a run split with `--shard`.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::{manifest, merge, outdir};

#[derive(clap::Args)]
pub struct Args {
    /// The shared output directory holding the fragments (manifest.shard-I-of-N.json).
    dir: PathBuf,
    /// Where to write the merged manifest (default DIR/manifest.json; it must be in DIR, since its
    /// paths are relative to DIR).
    #[arg(short, long)]
    out: Option<PathBuf>,
    /// The job files and directories the shards ran, to name the jobs of shards that wrote
    /// nothing and to check the fragments were planned from them.
    #[arg(long, num_args = 1..)]
    jobs: Option<Vec<PathBuf>>,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let out = args.out.unwrap_or_else(|| args.dir.join(manifest::FILE_NAME));
    let dir_real = args.dir.canonicalize().map_err(|e| Error::io(&args.dir, "open", e))?;
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(std::path::Path::new("."));
    if parent.canonicalize().ok().as_ref() != Some(&dir_real) {
        return Err(Error::Usage(format!(
            "{}: the merged manifest must be written in {} (its paths are relative to it)",
            out.display(),
            args.dir.display()
        )));
    }
    let m = merge::merge(&args.dir, args.jobs.as_deref())?;
    outdir::write_atomic(&out, &m.manifest.to_bytes())?;
    let count = m.manifest.run.merged_from.first().map_or(0, |f| f.count);
    for s in &m.missing_shards {
        say(format!("MISSING   shard {s}/{count}: no fragment (the task did not run, or wrote nothing)"));
    }
    for s in &m.unfinished_shards {
        say(format!("UNFINISHED shard {s}/{count}: its fragment says the run did not finish (killed?); re-submit it"));
    }
    for id in &m.missing_jobs {
        say(format!("MISSING   {id}"));
    }
    for (id, why) in &m.failed {
        say(format!("FAILED    {id}: {}", why.lines().next().unwrap_or("")));
    }
    eprintln!(
        "texsyn merge: {} fragment(s) of {count}, {} jobs ({} ok, {} up to date, {} failed, {} invalid), {} missing shard(s), {} missing job(s); manifest: {}",
        m.fragments.len(),
        m.manifest.jobs.len(),
        m.manifest.run.ran,
        m.manifest.run.up_to_date,
        m.manifest.run.failed,
        m.manifest.run.invalid,
        m.missing_shards.len(),
        m.missing_jobs.len(),
        out.display()
    );
    Ok(if m.complete() { Outcome::Success } else { Outcome::Problems })
}
