//! Any bytes as an image, with texsyn's decoding limits (tightened so that a header claiming a
//! huge image is refused before any allocation): decoded or refused, never a panic or an
//! out-of-memory.
#![no_main]

use libfuzzer_sys::fuzz_target;
use texsyn::image::io::{DecodeLimits, decode_native, decode_output, decode_rgba8, native_to_rgb8};

fuzz_target!(|data: &[u8]| {
    let limits = DecodeLimits { max_side: 4096, max_pixels: 1 << 22, max_alloc_bytes: 256 << 20 };
    if let Ok(img) = decode_native(data, limits) {
        let _ = native_to_rgb8(&img);
        let _ = img.pixel_digest();
    }
    let _ = decode_output(data, limits);
    let _ = decode_rgba8(data, limits);
});
