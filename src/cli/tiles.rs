//! `texsyn tiles render`: fill any size from an exported tile set alone.

use super::Outcome;
use std::path::PathBuf;
use texsyn::Error;
use texsyn::batch::memory;
use texsyn::image::io::{self as imageio, Encoding, Format};
use texsyn::synth::method::STRIP_ROWS;
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
        /// Memory limit, as for `texsyn run`: a fill estimated to need more is refused (exit 2)
        /// before anything is rendered. PNG fills are rendered and compressed strip by strip
        /// (the tile set and one strip in memory, whatever the size); EXR fills are held whole.
        /// Default: the memory available at start; `unlimited` for none.
        #[arg(long, value_name = "SIZE", default_value_t = super::run::MemoryLimit::available())]
        max_memory: super::run::MemoryLimit,
    },
}

/// The largest side `render` accepts.
const MAX_SIDE: u32 = 65_536;

pub fn run(cmd: Command) -> Result<Outcome, Error> {
    let Command::Render { index, out, width, height, seed, tiling, max_memory } = cmd;
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
    let needed = estimate(&loaded, w, h, format);
    if let Some(limit) = max_memory.0.filter(|&l| needed > l) {
        let hint = if format == Format::Exr { "; a PNG output is rendered strip by strip and needs far less" } else { "" };
        return Err(Error::Usage(format!("{}: a {w}x{h} fill {}{hint}", out.display(), memory::too_large(needed, limit))));
    }
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "create", e))?;
    }
    let started = std::time::Instant::now();
    let pixels = match format {
        Format::Png => {
            // Rendered while it is compressed, STRIP_ROWS rows at a time: the same pixels as a whole render.
            let render = loaded.rows(w, h, seed, order);
            let mut failure = None;
            let written = texsyn::batch::outdir::write_atomic_streamed(&out, |sink| {
                imageio::encode_png_strips(w, h, STRIP_ROWS, sink, &mut |y0, rows| render(y0, rows)).map_err(|e| {
                    let io = std::io::Error::other(e.to_string());
                    failure = Some(e);
                    io
                })
            });
            match (written, failure) {
                (Ok((pixels, _)), _) => pixels,
                (Err(_), Some(source)) => return Err(Error::Image { path: out.clone(), source }),
                (Err(e), None) => return Err(e),
            }
        }
        Format::Exr => {
            let img = loaded.render(w, h, seed, order);
            let encoded =
                imageio::encode(&img, Encoding { format, bit_depth: 32 }).map_err(|source| Error::Image { path: out.clone(), source })?;
            texsyn::batch::outdir::write_atomic(&out, &encoded.bytes)?;
            encoded.pixels.pixel_digest()
        }
    };
    let fill = started.elapsed().as_secs_f64();
    eprintln!(
        "{}: {w}x{h} from {} {} tiles (seed {seed}), filled and written in {fill:.3} s (needed about {}); pixels {}",
        out.display(),
        ix.tiles.len(),
        ix.method,
        memory::human(needed),
        pixels.short()
    );
    Ok(Outcome::Success)
}

/// The peak memory of a fill, in the terms of `run`'s model (`batch::memory`): the process, the
/// decoded tile set, the tiling (a byte per tile position; positions are at least a quarter of a
/// tile apart in each direction) and, for PNG, one strip and the compressor's buffers; for EXR,
/// the whole image and its encoding (linear floats and compressed blocks).
fn estimate(loaded: &export::Loaded, w: u32, h: u32, format: Format) -> u64 {
    let tile = u64::from(loaded.index().tile.max(8));
    let tiling = (u64::from(w) * 4 / tile + 4) * (u64::from(h) * 4 / tile + 4);
    let base = memory::PROCESS_BYTES + loaded.tile_bytes() + tiling;
    let raw = 3 * u64::from(w) * u64::from(h);
    match format {
        Format::Png => base + 2 * 3 * u64::from(w) * u64::from(STRIP_ROWS) + 4 * memory::MIB,
        Format::Exr => base + raw + 4 * raw + 4 * raw + raw / 8,
    }
}
