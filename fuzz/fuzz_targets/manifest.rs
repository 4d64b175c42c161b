//! Any bytes as a manifest: parsing and the checks made before anything acts on it must answer
//! with a manifest or an error, never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use texsyn::batch::manifest::Manifest;

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = Manifest::parse(std::path::Path::new("fuzz/manifest.json"), data) {
        let _ = m.recompute_digest();
        let _ = m.to_bytes();
    }
});
