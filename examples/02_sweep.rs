//! A parameter sweep from Rust: the same sample and seed at several block sizes, and a bad value
//! refused with the message a job file would get.
//!
//! ```sh
//! cargo run --release --example 02_sweep                 # writes 02_block_{24,40,64}.png here
//! ```

use texsyn::{QuiltingConfig, Synthesizer};

fn main() -> Result<(), texsyn::Error> {
    let sample = texsyn::load_image(concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/samples/pebbles_beige.png"))?;
    for block in [24, 40, 64] {
        let out = Synthesizer::new(QuiltingConfig { block, ..Default::default() }).seed(1).size(256, 256).build(&sample)?.run()?;
        let name = format!("02_block_{block}.png");
        texsyn::save_image(&out.image, &name)?;
        println!("{name}: mean candidates per block {}", out.diagnostics["mean_candidates"]);
    }
    // Validation names the parameter and the allowed range, exactly as for a job file.
    match Synthesizer::new(QuiltingConfig { block: 1000, ..Default::default() }).build(&sample) {
        Err(e) => println!("refused as expected: {e}"),
        Ok(_) => unreachable!("a block larger than the sample is refused"),
    }
    Ok(())
}
