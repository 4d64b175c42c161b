//! `texsyn tiles render`: fill any size from an exported tile set alone.

use super::Outcome;
use std::path::PathBuf;
use texsyn::Error;
use texsyn::image::io::{Encoding, Format};
use texsyn::synth::methods::tiles::export;
use texsyn::synth::methods::tiles::wang::TilingOrder;
use texsyn::synth::params::Choice;

#[derive(clap::Subcommand)]
pub enum Command {
    /// Render a texture of any size by copying tiles from an exported tile set. With no options
    /// it reproduces the job's own output exactly; --seed, --width, --height give others.
    Render {
        /// The export's index.json (in `{output}.tiles/`).
        index: PathBuf,
        /// The image to write (.png or .exr).
        #[arg(short, long)]
        out: PathBuf,
        /// Output width (default: the job's).
        #[arg(long)]
        width: Option<u32>,
        /// Output height (default: the job's).
        #[arg(long)]
        height: Option<u32>,
        /// Seed of the tile arrangement (default: the job's).
        #[arg(long)]
        seed: Option<u64>,
        /// `keyed` or `scanline` (default: the job's).
        #[arg(long)]
        tiling: Option<String>,
    },
}

/// The largest side `render` accepts.
const MAX_SIDE: u32 = 65_536;

pub fn run(cmd: Command) -> Result<Outcome, Error> {
    let Command::Render { index, out, width, height, seed, tiling } = cmd;
    let loaded = export::load(&index).map_err(|e| Error::Manifest { path: e.file, reason: e.reason })?;
    let ix = loaded.index();
    let (w, h) = (width.unwrap_or(ix.output[0]), height.unwrap_or(ix.output[1]));
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(Error::Usage(format!("--width and --height must be 1..={MAX_SIDE} (got {w}x{h})")));
    }
    let tiling = tiling.as_deref().unwrap_or(&ix.tiling);
    let order = TilingOrder::parse(tiling).ok_or_else(|| Error::Usage(format!("tiling `{tiling}` is not keyed or scanline")))?;
    let format = Format::from_path(&out).ok_or_else(|| Error::Usage(format!("{}: the output must end in .png or .exr", out.display())))?;
    let seed = seed.unwrap_or(ix.seed);
    let started = std::time::Instant::now();
    let img = loaded.render(w, h, seed, order);
    let fill = started.elapsed().as_secs_f64();
    let bit_depth = if format == Format::Exr { 32 } else { 8 };
    let encoded =
        texsyn::image::io::encode(&img, Encoding { format, bit_depth }).map_err(|source| Error::Image { path: out.clone(), source })?;
    texsyn::batch::outdir::write_atomic(&out, &encoded.bytes)?;
    eprintln!(
        "{}: {w}x{h} from {} {} tiles (seed {seed}), filled in {fill:.3} s; pixels {}",
        out.display(),
        ix.tiles.len(),
        ix.method,
        encoded.pixels.pixel_digest().short()
    );
    Ok(Outcome::Success)
}
