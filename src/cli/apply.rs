//! `texsyn apply`: replays a recorded placement (a job's `source_map`) over another image of the
//! sample's size — a map the job did not list as a companion, a repainted albedo, a mask.

use super::{Outcome, say};
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::execute::load_sample;
use texsyn::image::io::{self as imageio, Encoding, Format, ImageError};
use texsyn::synth::placement::MapKind;

pub const HELP: &str = "\
A map of a job with several samples (or `augment`) is replayed over one image per sample, in the
order of the job's `samples`: `texsyn apply map.exr a_normal.png b_normal.png -o normal.png`.
The output has the image's channels; its precision is the image's (8 or 16-bit PNG, float EXR)
unless --bit-depth asks for another PNG depth. Applying a job's source map over its own sample
gives the job's output, pixel for pixel.";

#[derive(clap::Args)]
pub struct Args {
    /// The source map a job wrote (`[output] source_map = \"….exr\"`).
    map: PathBuf,
    /// Any image of the job's sample size; one per sample, in order, for a job with several samples.
    #[arg(required = true, num_args = 1..)]
    image: Vec<PathBuf>,
    /// Where to write the result (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
    /// PNG bit depth, 8 or 16 (default: the image's own, 16 for a float image).
    #[arg(long)]
    bit_depth: Option<u8>,
    /// `normal`: blended pixels are renormalised as normals; `color` (default): blended as they are.
    #[arg(long, default_value = "color")]
    kind: String,
    /// Memory limit, as for `texsyn run`: a map whose rendering is estimated to need more is
    /// refused (exit 2) before it is decoded. Default: the memory available; `unlimited` for none.
    #[arg(long, value_name = "SIZE", default_value_t = super::run::MemoryLimit::available())]
    max_memory: super::run::MemoryLimit,
}

pub fn run(args: Args) -> Result<Outcome, Error> {
    let kind = MapKind::from_name(&args.kind).ok_or_else(|| Error::Usage(format!("--kind {:?}: use color or normal", args.kind)))?;
    let format = Format::from_path(&args.output)
        .ok_or_else(|| Error::Usage(format!("{}: the output must end in .png or .exr", args.output.display())))?;
    let bytes = texsyn::files::read_limited(&args.map, texsyn::files::MAX_IMAGE_FILE_BYTES).map_err(|e| Error::io(&args.map, "read", e))?;
    let declared = texsyn::batch::source_map::declared_size(&bytes)
        .map_err(|reason| Error::Image { path: args.map.clone(), source: ImageError::Decode(reason) })?;
    // The map's channels as decoded (4 B each) beside the placement made from them (source and
    // blend index, 8 B, plus blends), then the rendering in the widest precision (float RGBA)
    // and its encoding; the image itself is bounded by the decoder's limits.
    let (w, h, channels) = declared;
    let needed = texsyn::batch::memory::PROCESS_BYTES + bytes.len() as u64 + w * h * (4 * channels + 16) + 3 * 16 * w * h;
    if let Some(limit) = args.max_memory.0.filter(|&l| needed > l) {
        return Err(Error::Usage(format!(
            "{}: rendering this {w}x{h} map {}",
            args.map.display(),
            texsyn::batch::memory::too_large(needed, limit)
        )));
    }
    let map = texsyn::batch::source_map::decode_map(&bytes)
        .map_err(|reason| Error::Image { path: args.map.clone(), source: ImageError::Decode(reason) })?;
    let sizes = map.sample_sizes();
    if args.image.len() != sizes.len() {
        return Err(Error::Usage(format!(
            "the source map {} was made from {} sample{}; give one image per sample, in the job's order (got {})",
            args.map.display(),
            sizes.len(),
            if sizes.len() == 1 { "" } else { "s" },
            args.image.len()
        )));
    }
    let mut images = Vec::new();
    for (path, &(w, h)) in args.image.iter().zip(&sizes) {
        let image = load_sample(path)?;
        let (iw, ih) = image.image.dimensions();
        if (iw, ih) != (w, h) {
            return Err(Error::Usage(format!(
                "{} is {iw}x{ih}, but the source map {} renders from images of its sample's size, {w}x{h}",
                path.display(),
                args.map.display()
            )));
        }
        if let Some(first) = images.first().map(|i: &texsyn::batch::execute::LoadedSample| i.describe())
            && first != image.describe()
        {
            return Err(Error::Usage(format!(
                "{} is {} but {} is {first}; the images must share channels and precision",
                path.display(),
                image.describe(),
                args.image[0].display()
            )));
        }
        images.push(image);
    }
    let image = &images[0];
    let placement = &map.placement;
    let native = match &map.atlas {
        None => image.native_or_guide(),
        Some(atlas) => {
            let natives: Vec<_> = images.iter().map(|i| i.native_or_guide()).collect();
            std::borrow::Cow::Owned(atlas.compose(&natives.iter().map(|n| &**n).collect::<Vec<_>>(), kind))
        }
    };
    let bit_depth = match (format, args.bit_depth) {
        (Format::Exr, None) => 32,
        (Format::Exr, Some(_)) => return Err(Error::Usage("--bit-depth applies to PNG outputs only".into())),
        (Format::Png, None) => image.native_png_depth(),
        (Format::Png, Some(d @ (8 | 16))) => d,
        (Format::Png, Some(d)) => return Err(Error::Usage(format!("--bit-depth {d}: use 8 or 16"))),
    };
    let rendered = placement.render(&native, kind);
    let encoded = imageio::encode_native(&rendered, Encoding { format, bit_depth })
        .map_err(|source| Error::Image { path: args.output.clone(), source })?;
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "create", e))?;
    }
    // Written beside and renamed, so a reader never sees half a file.
    texsyn::batch::outdir::write_atomic(&args.output, &encoded.bytes)?;
    say(format!(
        "{}: {}x{} from {} ({}), pixel digest {}",
        args.output.display(),
        placement.width(),
        placement.height(),
        args.image.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "),
        image.describe(),
        encoded.pixels.pixel_digest().short()
    ));
    Ok(Outcome::Success)
}
