//! `texsyn synth`: one photo, no job file. The flags are turned into the job file a user would
//! write (`--print-job` shows it), which is validated and run like any other.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::single::{OneOff, OneOffMask};

pub const HELP: &str = "\
Writes OUT and its manifest beside it (OUT's name with .manifest.json), which `texsyn verify`
re-runs. Parameters are the job file's [params] keys: --set block=40 --set cut=dp. Mistakes get
the job file's messages, named by key. --print-job prints the equivalent job file instead of
running it, so that a one-off can join a job directory.";

#[derive(clap::Args)]
pub struct Args {
    /// The sample image (PNG 8/16-bit, JPEG, EXR), or several to learn from together. With
    /// --inpaint, the samples the fill copies from (default: IMAGE itself; name IMAGE among
    /// them to copy from it too).
    #[arg(required_unless_present = "inpaint", num_args = 1..)]
    sample: Vec<PathBuf>,
    /// Also search turned or mirrored copies of the samples: any of rot90, rot180, rot270,
    /// flip_h, flip_v, comma-separated.
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    augment: Vec<String>,
    /// Repair IMAGE instead: fill the pixels --mask marks (or --mask-channel), keep every other one.
    #[arg(long, value_name = "IMAGE", requires = "inpaint_mask")]
    inpaint: Option<PathBuf>,
    /// With --inpaint: the mask image, white = fill.
    #[arg(long, value_name = "MASK", group = "inpaint_mask", requires = "inpaint")]
    mask: Option<PathBuf>,
    /// Texture transfer: follow TARGET's light and dark (an image of the output's size; with no
    /// --size, the output takes TARGET's size). With --inpaint, TARGET has IMAGE's size and
    /// leads the fill of the hole (quilting and patch-sampling).
    #[arg(long, value_name = "TARGET")]
    guide: Option<PathBuf>,
    /// With --guide: the sample's guide (default: the sample's luminance).
    #[arg(long, value_name = "SOURCE", requires = "guide")]
    guide_source: Option<PathBuf>,
    /// With --guide: the guide's share of a block's error, 0..=1 (default 0.7).
    #[arg(long, value_name = "W", requires = "guide")]
    guide_weight: Option<f64>,
    /// With --guide: passes of the iteration, 1..=8 (default 3).
    #[arg(long, value_name = "N", requires = "guide")]
    guide_passes: Option<u32>,
    /// Pixels of the sample that may be copied (white) and never (black); with several samples,
    /// one per sample in their order (`--sample-mask none` for a sample without one).
    #[arg(long, value_name = "MASK")]
    sample_mask: Vec<String>,
    /// Also write the placement beside OUT as `{OUT's stem}.map.exr` (for `texsyn apply`).
    #[arg(long)]
    source_map: bool,
    /// With --inpaint: fill where this channel of IMAGE is below half (`a`: the transparent pixels).
    #[arg(long, value_name = "CHANNEL", group = "inpaint_mask", requires = "inpaint")]
    mask_channel: Option<String>,
    /// The image to write (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
    /// The method (`texsyn methods` lists them).
    #[arg(short, long, default_value = "quilting")]
    method: String,
    /// Output size WxH (default: the sample's).
    #[arg(long, value_name = "WxH")]
    size: Option<String>,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Make the output wrap seamlessly.
    #[arg(long)]
    tileable: bool,
    /// A parameter, `key=value` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Print the equivalent job file and run nothing.
    #[arg(long)]
    print_job: bool,
    /// Memory limit, as for `texsyn run` (default: the memory available; `unlimited` for none).
    #[arg(long, value_name = "SIZE", default_value_t = super::run::MemoryLimit::available())]
    max_memory: super::run::MemoryLimit,
}

pub(super) fn parse_size(s: &str) -> Result<(u32, u32), Error> {
    let bad = || Error::Usage(format!("--size {s:?}: use WxH, e.g. 512x512"));
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((w.trim().parse().map_err(|_| bad())?, h.trim().parse().map_err(|_| bad())?))
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let mut params = Vec::new();
    for kv in &args.set {
        let (k, v) = kv.split_once('=').ok_or_else(|| Error::Usage(format!("--set {kv:?}: use key=value, e.g. --set block=40")))?;
        params.push((k.trim().to_string(), OneOff::param_value(v.trim())));
    }
    let inpaint = match (&args.inpaint, args.mask, args.mask_channel) {
        (None, None, None) => None,
        (None, ..) => return Err(Error::Usage("--mask and --mask-channel go with --inpaint IMAGE".into())),
        (Some(_), Some(m), _) => Some(OneOffMask::File(m)),
        (Some(_), None, Some(c)) => Some(OneOffMask::Channel(c)),
        (Some(_), None, None) => return Err(Error::Usage("--inpaint needs --mask MASK or --mask-channel CHANNEL".into())),
    };
    if inpaint.is_some() && args.size.is_some() {
        return Err(Error::Usage("--inpaint makes an output of the image's size: leave --size out".into()));
    }
    let (sample, more_samples, inpaint_from) = match args.inpaint {
        Some(image) => (image, Vec::new(), args.sample),
        None => {
            let mut samples = args.sample.into_iter();
            (samples.next().expect("clap requires a sample or --inpaint"), samples.collect(), Vec::new())
        }
    };
    let guide = args.guide.map(|t| std::path::absolute(&t).unwrap_or(t));
    let size = match (&args.size, &guide) {
        (Some(s), _) => Some(parse_size(s)?),
        (None, Some(t)) => Some(texsyn::batch::execute::load_sample(t)?.image.dimensions()),
        (None, None) => None,
    };
    let one = OneOff {
        sample,
        more_samples,
        inpaint_from,
        augment: args.augment,
        sample_masks: args.sample_mask.into_iter().map(|m| (m != "none").then(|| PathBuf::from(m))).collect(),
        guide_source: args.guide_source,
        guide_weight: args.guide_weight,
        guide_passes: args.guide_passes,
        source_map: args.source_map,
        inpaint,
        guide,
        output: args.output,
        method: args.method,
        size,
        seed: args.seed,
        tileable: args.tileable,
        params,
        max_memory: args.max_memory.0,
    };
    if args.print_job {
        say(one.job_text(one.size()?).trim_end());
        return Ok(Outcome::Success);
    }
    let done = one.run()?;
    for w in &done.record.warnings {
        eprintln!("warning: {w}");
    }
    let out = &done.record.outputs[0];
    say(format!(
        "{}: {}x{} {} ({}), pixels {}; manifest {}",
        one.output.display(),
        out.width,
        out.height,
        done.record.method.as_deref().unwrap_or(""),
        out.format,
        out.pixel_digest.short(),
        done.manifest.display()
    ));
    Ok(Outcome::Success)
}
