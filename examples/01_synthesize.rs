//! Synthesise one texture from Rust: a method's typed configuration, a seed, a size.
//!
//! ```sh
//! cargo run --release --example 01_synthesize            # writes 01_quilted.png here
//! ```

use texsyn::{QuiltingConfig, Synthesizer};

fn main() -> Result<(), texsyn::Error> {
    let sample = texsyn::load_image(concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/samples/bricks_gray.png"))?;
    // Every field not named keeps the method's default (the same defaults job files get).
    let config = QuiltingConfig { block: 40, tolerance: 0.1, ..Default::default() };
    let session = Synthesizer::new(config).seed(7).size(384, 384).build(&sample)?;
    println!("resolved parameters: {}", session.params().to_json());
    let texture = session.run()?;
    texsyn::save_image(&texture.image, "01_quilted.png")?;
    println!("wrote 01_quilted.png ({}x{})", texture.image.width(), texture.image.height());
    Ok(())
}
