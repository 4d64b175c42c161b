//! A material from Rust: synthesise the albedo, then render its normal map with the same
//! placement, so every bump stays under its colour.
//!
//! ```sh
//! cargo run --release --example 08_material     # writes 08_albedo.png and 08_normal.png here
//! ```

use texsyn::image::io::{DecodeLimits, Encoding, Format, decode_native, encode_native};
use texsyn::synth::placement::MapKind;
use texsyn::{QuiltingConfig, Synthesizer};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/samples/materials/");
    let albedo = texsyn::load_image(format!("{dir}brick_a_albedo.png"))?;
    // The placement is what the method did, pixel by pixel; asking for it never changes the image.
    let texture =
        Synthesizer::new(QuiltingConfig { block: 64, ..Default::default() }).seed(3).size(512, 512).placement().build(&albedo)?.run()?;
    let placement = texture.placement.expect("asked for");
    texsyn::save_image(&texture.image, "08_albedo.png")?;
    // Any map of the sample's size renders with it, in its own precision and channels.
    let normal = decode_native(&std::fs::read(format!("{dir}brick_a_normal.png"))?, DecodeLimits::default())?;
    let rendered = placement.render(&normal, MapKind::Normal);
    std::fs::write("08_normal.png", encode_native(&rendered, Encoding { format: Format::Png, bit_depth: 8 })?.bytes)?;
    println!("wrote 08_albedo.png and 08_normal.png ({}x{})", placement.width(), placement.height());
    Ok(())
}
