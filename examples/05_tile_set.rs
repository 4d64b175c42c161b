//! A tile set through the library API, without job files: build the RW-Tiles 8-tile set from a
//! bundled 128×128 crop, keep it, and fill two textures of different sizes from it by copying.
//! The small one is exactly the top-left corner of the large one (keyed tiling), which is what
//! lets a renderer stream a texture of any size tile row by tile row.
//!
//! ```sh
//! cargo run --release --example 05_tile_set                 # writes tile_set_{small,large}.png here
//! cargo run --release --example 05_tile_set -- out_dir      # or into out_dir
//! ```

use std::path::PathBuf;
use std::time::Instant;
use texsyn::image::io::{self as imageio, DecodeLimits, Encoding, Format};
use texsyn::synth::methods::tiles::common::PixelError;
use texsyn::synth::methods::tiles::rw_tiles;
use texsyn::synth::methods::tiles::wang::{TileSet, TilingOrder};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out_dir = std::env::args().nth(1).map(PathBuf::from).unwrap_or_else(|| PathBuf::from("."));
    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let crop = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("jobs/samples/crops/pebbles_beige_128.png");
    let (sample, _) = imageio::read_rgb8(&crop, DecodeLimits::default())?;

    // Tile 64 (rhombus diagonals), overlap 8, the 8-tile parity set, seed 7: the paper's setting.
    let started = Instant::now();
    let set = rw_tiles::build_tile_set(&sample, 64, 8, TileSet::Minimal, PixelError::Squared, 7)?;
    println!("built {} tiles in {:.1} ms", set.tiles.len(), started.elapsed().as_secs_f64() * 1e3);

    let mut images = Vec::new();
    for (name, w, h) in [("small", 300u32, 200u32), ("large", 2048, 2048)] {
        let started = Instant::now();
        let tiling = set.tile_output(TilingOrder::Keyed, w, h, 7);
        let image = set.render(&tiling, w, h);
        println!("filled {w}x{h} in {:.1} ms (tile usage {:?})", started.elapsed().as_secs_f64() * 1e3, tiling.usage(set.set));
        let path = out_dir.join(format!("tile_set_{name}.png"));
        let encoded = imageio::encode(&image, Encoding { format: Format::Png, bit_depth: 8 })?;
        std::fs::write(&path, &encoded.bytes).map_err(|e| format!("{}: {e}", path.display()))?;
        println!("wrote {}", path.display());
        images.push(image);
    }
    assert_eq!(images[1].crop(0, 0, 300, 200), images[0], "the small texture is a corner of the large one");
    println!("the 300x200 texture is exactly the top-left corner of the 2048x2048 one");
    Ok(())
}
