//! texsyn: reproducible texture synthesis driven by TOML job files.
//!
//! # Layers
//!
//! Each layer imports only from the layers below it; the `texsyn` binary (`src/cli/`) sits on
//! top and is the only code that prints or chooses an exit code.
//!
//! ```text
//!  cli/      (binary)  one file per subcommand, the exit-code policy, progress display
//!  ─────────────────────────────────────────────────────────────────────────────────────
//!  report/   tables, contact sheets, plot, HTML page        ← reads a manifest
//!  batch/    job files → plan → execute → run → manifest; verify, golden; observer
//!  synthesizer   the builder: typed config + seed + size → validated Session → texture
//!  error     texsyn::Error, wrapping the layers' own errors below
//!  synth/    Method trait, params + typed configs, SynthError, rng, lattice,
//!            methods/{quilting, double_seam, patch_sampling, near_regular/, tiles/},
//!            primitives/ (internal building blocks)
//!  metrics/  objective measures (KL, autocorrelation, verbatim copies, seam visibility)
//!  image/    RgbImage, decoding/encoding with limits, pixel digests, seam grids
//!  digest    SHA-256 and canonical JSON
//!  files     bounded reads and link-refusing opens of paths that come from outside
//! ```
//!
//! `docs/methods.md` describes every method and the choices the code makes where the papers are
//! silent; code comments cite it as `docs/methods.md §N` (methods) or `Bn` (building blocks).
//!
//! # Use from Rust
//!
//! Synthesise one texture with a typed configuration (see `examples/01_synthesize.rs`):
//!
//! ```no_run
//! use texsyn::{QuiltingConfig, Synthesizer};
//! let sample = texsyn::load_image("jobs/samples/bricks_gray.png")?;
//! let out = Synthesizer::new(QuiltingConfig::default()).seed(7).size(386, 386).build(&sample)?.run()?;
//! texsyn::save_image(&out.image, "quilted.png")?;
//! # Ok::<(), texsyn::Error>(())
//! ```
//!
//! Run job directories with [`run`] and an [`Observer`] of your own, re-check a manifest with
//! [`verify`]. Everything below the names re-exported here is reachable through the layer
//! modules, but only these names are the supported face of the library.

pub mod batch;
pub mod digest;
mod error;
pub mod files;
pub mod image;
pub mod metrics;
pub mod report;
pub mod synth;
mod synthesizer;

#[cfg(test)]
mod architecture;

pub use batch::observer::{Event, Observer, Silent};
pub use batch::run::{RunOptions, Summary, run};
pub use batch::verify::verify;
pub use error::{Error, Result};
pub use image::RgbImage;
pub use synth::error::SynthError;
pub use synth::method::{Method, Synthesis};
pub use synth::methods::double_seam::DoubleSeamConfig;
pub use synth::methods::near_regular::coevolution::CoevolutionConfig;
pub use synth::methods::near_regular::tes::TesConfig;
pub use synth::methods::patch_sampling::PatchSamplingConfig;
pub use synth::methods::quilting::QuiltingConfig;
pub use synth::methods::tiles::rw_tiles::RwTilesConfig;
pub use synth::methods::tiles::wang_tiles::WangTilesConfig;
pub use synth::params::{MethodConfig, ParamValue};
pub use synthesizer::{Session, Synthesizer};

/// Reads an image (PNG 8/16-bit, JPEG, EXR) as the 8-bit RGB every method works on.
pub fn load_image(path: impl AsRef<std::path::Path>) -> Result<RgbImage> {
    Ok(batch::execute::load_sample(path.as_ref())?.image)
}

/// Writes an image as PNG (8-bit) or EXR (32-bit float, linear), chosen by the extension; the
/// file is written atomically.
pub fn save_image(img: &RgbImage, path: impl AsRef<std::path::Path>) -> Result<()> {
    use image::io::{Encoding, Format};
    let path = path.as_ref();
    let format =
        Format::from_path(path).ok_or_else(|| Error::Usage(format!("{}: the file name must end in .png or .exr", path.display())))?;
    let bit_depth = if format == Format::Exr { 32 } else { 8 };
    let encoded = image::io::encode(img, Encoding { format, bit_depth }).map_err(|source| Error::Image { path: path.into(), source })?;
    batch::outdir::write_atomic(path, &encoded.bytes)
}
