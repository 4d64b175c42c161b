//! Bad input: malformed job files and corrupt or hostile images.
//!
//! One table of cases. Each case builds a fresh temporary directory (job files under `jobs/`,
//! samples next to them, anything else it needs), runs `texsyn run jobs -o out -j 1 -q` from
//! that directory, and asserts:
//!
//! * the exit code;
//! * one `error:` line of stderr names the file (job file, sample or output directory) and the
//!   cause, plus any case-specific details (key, line:column);
//! * nothing panicked (no "panicked", no "RUST_BACKTRACE" in stdout or stderr);
//! * nothing was created, changed or removed anywhere in the temporary directory except under
//!   `out/` (the run's working directory is the temporary directory, so stray relative writes
//!   are caught too, and symlink targets live in it);
//! * for exit 1: a valid job placed next to the bad one (`jobs/good.toml`) still ran and wrote
//!   its output, and the manifest records every bad job as `invalid` or `failed` with the cause.
//!
//! All cases run, then the test fails once with a report of every failing case and its output.

use super::common::*;
use std::fs::File;

// ---------------------------------------------------------------------------------------------
// Fixture building: PNG chunks with real CRCs, tiny images of other formats.
// ---------------------------------------------------------------------------------------------

/// CRC-32 (IEEE 802.3, reflected, poly 0xEDB88320), as PNG chunks use it.
fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

fn adler32(data: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    for &x in data {
        a = (a + x as u32) % 65521;
        b = (b + a) % 65521;
    }
    (b << 16) | a
}

/// A zlib stream holding `data` in one stored (uncompressed) deflate block.
fn zlib_stored(data: &[u8]) -> Vec<u8> {
    assert!(data.len() <= 0xFFFF);
    let mut z = vec![0x78, 0x01, 0x01];
    let len = data.len() as u16;
    z.extend_from_slice(&len.to_le_bytes());
    z.extend_from_slice(&(!len).to_le_bytes());
    z.extend_from_slice(data);
    z.extend_from_slice(&adler32(data).to_be_bytes());
    z
}

fn png_chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut c = (data.len() as u32).to_be_bytes().to_vec();
    let mut body = kind.to_vec();
    body.extend_from_slice(data);
    c.extend_from_slice(&body);
    c.extend_from_slice(&crc32(&body).to_be_bytes());
    c
}

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];

/// A PNG whose IHDR claims `width`×`height` (8-bit RGB) with a correct CRC, followed by a tiny
/// IDAT (one black row's worth at most) and IEND: the header is valid, the size is a lie.
fn crafted_png(width: u32, height: u32) -> Vec<u8> {
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]); // bit depth 8, colour type RGB, deflate, filter 0, no interlace
    let mut png = PNG_SIGNATURE.to_vec();
    png.extend(png_chunk(b"IHDR", &ihdr));
    png.extend(png_chunk(b"IDAT", &zlib_stored(&[0u8; 64])));
    png.extend(png_chunk(b"IEND", &[]));
    png
}

/// A real, decodable `w`×`h` RGB PNG of deterministic noise (noise compresses badly, so the
/// file is large enough to truncate meaningfully).
fn noise_png(w: u32, h: u32, seed: u32) -> Vec<u8> {
    let mut state = seed.wrapping_mul(2_654_435_761).wrapping_add(12345);
    let img = image::RgbImage::from_fn(w, h, |_, _| {
        let mut px = [0u8; 3];
        for c in &mut px {
            state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
            *c = (state >> 16) as u8;
        }
        image::Rgb(px)
    });
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png).expect("encode PNG");
    bytes
}

/// A valid PNG with one byte of IHDR changed after the CRC was computed.
fn png_with_bad_ihdr_crc() -> Vec<u8> {
    let mut png = noise_png(32, 32, 3);
    // signature (8) + length (4) + "IHDR" (4) + width (4): flip a bit of the height.
    png[8 + 4 + 4 + 4 + 3] ^= 0x01;
    png
}

/// A 4×4 RGB PNG with a valid header and an IDAT of random bytes (correct chunk CRC).
fn png_with_garbage_idat() -> Vec<u8> {
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&4u32.to_be_bytes());
    ihdr.extend_from_slice(&4u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    let mut png = PNG_SIGNATURE.to_vec();
    png.extend(png_chunk(b"IHDR", &ihdr));
    let mut garbage = vec![0x78, 0x9C];
    garbage.extend(random_bytes(200));
    png.extend(png_chunk(b"IDAT", &garbage));
    png.extend(png_chunk(b"IEND", &[]));
    png
}

/// A real baseline JPEG of noise.
fn noise_jpeg(w: u32, h: u32, seed: u32) -> Vec<u8> {
    let png = noise_png(w, h, seed);
    let img = image::load_from_memory_with_format(&png, image::ImageFormat::Png).expect("decode own PNG");
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Jpeg).expect("encode JPEG");
    bytes
}

/// A 1×1 GIF89a.
fn tiny_gif() -> Vec<u8> {
    vec![
        0x47, 0x49, 0x46, 0x38, 0x39, 0x61, 0x01, 0x00, 0x01, 0x00, 0x80, 0x00, 0x00, 0xFF, 0xFF, 0xFF, 0x00, 0x00, 0x00, 0x21, 0xF9, 0x04,
        0x01, 0x00, 0x00, 0x00, 0x00, 0x2C, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01, 0x00, 0x00, 0x02, 0x02, 0x44, 0x01, 0x00, 0x3B,
    ]
}

/// A 1×1 24-bit BMP.
fn tiny_bmp() -> Vec<u8> {
    let pixel_row = [0x00u8, 0x00, 0xFF, 0x00]; // one BGR pixel, padded to 4 bytes
    let file_size = 14 + 40 + pixel_row.len() as u32;
    let mut b = Vec::new();
    b.extend_from_slice(b"BM");
    b.extend_from_slice(&file_size.to_le_bytes());
    b.extend_from_slice(&[0, 0, 0, 0]);
    b.extend_from_slice(&54u32.to_le_bytes());
    b.extend_from_slice(&40u32.to_le_bytes()); // BITMAPINFOHEADER
    b.extend_from_slice(&1i32.to_le_bytes());
    b.extend_from_slice(&1i32.to_le_bytes());
    b.extend_from_slice(&1u16.to_le_bytes());
    b.extend_from_slice(&24u16.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend_from_slice(&(pixel_row.len() as u32).to_le_bytes());
    b.extend_from_slice(&2835i32.to_le_bytes());
    b.extend_from_slice(&2835i32.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend_from_slice(&pixel_row);
    b
}

/// The EXR magic number and version field, then garbage.
fn corrupt_exr() -> Vec<u8> {
    let mut b = vec![0x76, 0x2F, 0x31, 0x01, 0x02, 0x00, 0x00, 0x00];
    let mut s = 0x1234_5678u32;
    for _ in 0..512 {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        b.push(s as u8);
    }
    b
}

fn random_bytes(n: usize) -> Vec<u8> {
    let mut s = 0x9E37_79B9u32;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as u8
        })
        .collect()
}

/// Job file text from lines (line k of the file is `lines[k - 1]`, so positions are easy to read).
fn toml(lines: &[&str]) -> String {
    let mut s = lines.join("\n");
    s.push('\n');
    s
}

/// The valid job every case starts from (line numbers in the comments):
const L1_SAMPLE: &str = r#"sample = "s.png""#; // 1
const L2_METHOD: &str = r#"method = "quilting""#; // 2
const L3_SEED: &str = "seed = 7"; // 3
const L4_OUTPUT: &str = "[output]"; // 4
const L5_PATH: &str = r#"path = "x.png""#; // 5
const L6_WIDTH: &str = "width = 64"; // 6
const L7_HEIGHT: &str = "height = 64"; // 7
const L8_PARAMS: &str = "[params]"; // 8
const L9_BLOCK: &str = "block = 16"; // 9

/// The base job with line `n` (1-based) replaced by `text` (several lines allowed).
fn base_with(n: usize, text: &str) -> String {
    let mut lines = vec![L1_SAMPLE, L2_METHOD, L3_SEED, L4_OUTPUT, L5_PATH, L6_WIDTH, L7_HEIGHT, L8_PARAMS, L9_BLOCK];
    lines[n - 1] = text;
    toml(&lines)
}

fn base_plus(extra: &[&str]) -> String {
    let mut lines = vec![L1_SAMPLE, L2_METHOD, L3_SEED, L4_OUTPUT, L5_PATH, L6_WIDTH, L7_HEIGHT, L8_PARAMS, L9_BLOCK];
    lines.extend_from_slice(extra);
    toml(&lines)
}

/// A job reading `sample` with otherwise valid settings.
fn job_for_sample(sample: &str) -> String {
    toml(&[&format!("sample = {sample:?}"), L2_METHOD, L3_SEED, L4_OUTPUT, L5_PATH, L6_WIDTH, L7_HEIGHT, L8_PARAMS, L9_BLOCK])
}

// ---------------------------------------------------------------------------------------------
// The table.
// ---------------------------------------------------------------------------------------------

#[derive(Clone)]
enum Entry {
    Text(String),
    Bytes(Vec<u8>),
    Dir,
    /// A symlink to this target (`@TMP@` is replaced by the case's temporary directory).
    Symlink(String),
}

struct Case {
    name: &'static str,
    /// Paths relative to the temporary directory; `@TMP@` in text is replaced by its absolute path.
    files: Vec<(&'static str, Entry)>,
    exit: i32,
    /// The file the message must name (a job file, a sample, or the output directory).
    names: &'static str,
    /// What went wrong, as the message must say it (`a|b`: either). Also required in the manifest's
    /// `error` for exit 1.
    cause: &'static str,
    /// More substrings required on the same `error:` line (key, `file:line:col`, hints).
    also: Vec<&'static str>,
    /// Job ids the manifest must record as `invalid` or `failed` (exit 1 only).
    bad_ids: Vec<&'static str>,
    /// Put a valid job (`jobs/good.toml`) next to the bad one and check that it still ran.
    with_good: bool,
    /// Hold the output directory's lock while running.
    hold_lock: bool,
    /// Arguments after `texsyn run` (default: `jobs -o out -j 1 -q`).
    args: Option<Vec<&'static str>>,
}

fn jobs_case(name: &'static str, job: String, cause: &'static str, also: Vec<&'static str>) -> Case {
    Case {
        name,
        files: vec![("jobs/bad.toml", Entry::Text(job)), ("jobs/s.png", Entry::Bytes(noise_png(64, 64, 1)))],
        exit: 1,
        names: "bad.toml",
        cause,
        also,
        bad_ids: vec!["bad.toml"],
        with_good: true,
        hold_lock: false,
        args: None,
    }
}

/// A valid job file whose sample is the hostile file `jobs/<sample_name>`.
fn image_case(name: &'static str, sample_name: &'static str, bytes: Vec<u8>, cause: &'static str) -> Case {
    Case {
        name,
        files: vec![
            ("jobs/bad.toml", Entry::Text(job_for_sample(sample_name))),
            (leak(format!("jobs/{sample_name}")), Entry::Bytes(bytes)),
        ],
        exit: 1,
        names: sample_name,
        cause,
        also: vec!["bad.toml"],
        bad_ids: vec!["bad.toml"],
        with_good: true,
        hold_lock: false,
        args: None,
    }
}

fn leak(s: String) -> &'static str {
    Box::leak(s.into_boxed_str())
}

fn cases() -> Vec<Case> {
    let mut v = vec![
        // --- TOML syntax and encoding -------------------------------------------------------
        jobs_case("malformed_toml_unquoted_string", base_with(2, "method = quilting"), "malformed TOML", vec!["bad.toml:2:10"]),
        jobs_case("malformed_toml_unclosed_table", base_with(8, "[params"), "malformed TOML", vec!["bad.toml:8:"]),
        jobs_case("malformed_toml_duplicate_key", base_plus(&["block = 20"]), "malformed TOML|duplicate", vec!["bad.toml:10:"]),
        jobs_case("non_utf8_job_file", String::new(), "not valid UTF-8", vec![]),
        jobs_case("empty_job_file", String::new(), "missing required key `sample`", vec![]),
        // --- unknown keys ---------------------------------------------------------------------
        jobs_case(
            "unknown_top_level_key_suggests",
            base_with(2, r#"metod = "quilting""#),
            "did you mean `method`",
            vec!["bad.toml:2:1", "`metod`"],
        ),
        jobs_case(
            "unknown_top_level_key_lists_valid",
            base_with(3, "seed = 7\ncolour = 1"),
            "unknown key `colour`",
            vec!["bad.toml:4:1", "valid keys: sample, method, seed"],
        ),
        jobs_case("unknown_output_key", base_with(6, "widht = 64"), "did you mean `width`", vec!["bad.toml:6:1", "`output.widht`"]),
        jobs_case("unknown_param_suggests", base_with(9, "blok = 16"), "did you mean `block`", vec!["bad.toml:9:1", "`params.blok`"]),
        // --- wrong types ----------------------------------------------------------------------
        jobs_case(
            "width_is_a_string",
            base_with(6, r#"width = "64""#),
            "expected an integer, found a string",
            vec!["bad.toml:6:9", "`output.width`"],
        ),
        jobs_case(
            "block_is_a_float",
            base_with(9, "block = 16.5"),
            "expected an integer, found a float",
            vec!["bad.toml:9:", "`params.block`"],
        ),
        jobs_case("seed_is_a_string", base_with(3, r#"seed = "7""#), "expected an integer, found a string", vec!["bad.toml:3:8", "`seed`"]),
        jobs_case(
            "method_is_an_array",
            base_with(2, r#"method = ["quilting"]"#),
            "expected a string",
            vec!["bad.toml:2:10", "`method`", "found an array"],
        ),
        jobs_case(
            "output_is_not_a_table",
            toml(&[L1_SAMPLE, L2_METHOD, L3_SEED, r#"output = "x.png""#]),
            "expected a table",
            vec!["bad.toml:4:10", "`output`"],
        ),
        // --- out-of-range values --------------------------------------------------------------
        jobs_case("seed_negative", base_with(3, "seed = -1"), "non-negative", vec!["bad.toml:3:8", "`seed`"]),
        jobs_case("seed_overflows_u64", base_with(3, "seed = 99999999999999999999"), "out of range", vec!["bad.toml:3:", "`seed`"]),
        jobs_case("width_zero", base_with(6, "width = 0"), "0 is out of range", vec!["bad.toml:6:9", "`output.width`", "1..=65536"]),
        jobs_case("height_huge", base_with(7, "height = 1000000"), "1000000 is out of range", vec!["bad.toml:7:10", "`output.height`"]),
        jobs_case("block_1", base_with(9, "block = 1"), "1 is out of range", vec!["bad.toml:9:", "`params.block`", "3..=4096"]),
        jobs_case("tolerance_negative", base_plus(&["tolerance = -1"]), "-1 is out of range", vec!["bad.toml:10:", "`params.tolerance`"]),
        jobs_case(
            "overlap_more_than_half_block",
            base_plus(&["overlap = 9"]),
            "more than half the block",
            vec!["bad.toml:10:", "`params.overlap`"],
        ),
        jobs_case(
            "cut_zigzag",
            base_plus(&[r#"cut = "zigzag""#]),
            "\"zigzag\" is not allowed",
            vec!["bad.toml:10:", "`params.cut`", "dp | none"],
        ),
        jobs_case(
            "blend_feather_with_cut_dp",
            base_plus(&[r#"blend = "feather""#, r#"cut = "dp""#]),
            "cut = \"none\"",
            vec!["bad.toml:10:", "`params.blend`"],
        ),
        jobs_case(
            "unknown_method_lists_available",
            base_with(2, r#"method = "quilt""#),
            "unknown method `quilt`",
            vec!["bad.toml:2:10", "available: quilting"],
        ),
        // --- the sample -----------------------------------------------------------------------
        jobs_case(
            "missing_sample_file",
            base_with(1, r#"sample = "nope.png""#),
            "nope.png` does not exist",
            vec!["bad.toml:1:10", "`sample`"],
        ),
        // --- missing required keys ------------------------------------------------------------
        jobs_case(
            "missing_sample_key",
            toml(&[L2_METHOD, L3_SEED, L4_OUTPUT, L5_PATH, L6_WIDTH, L7_HEIGHT]),
            "missing required key `sample`",
            vec![],
        ),
        jobs_case(
            "missing_method_key",
            toml(&[L1_SAMPLE, L3_SEED, L4_OUTPUT, L5_PATH, L6_WIDTH, L7_HEIGHT]),
            "missing required key `method`",
            vec![],
        ),
        jobs_case(
            "missing_seed_key",
            toml(&[L1_SAMPLE, L2_METHOD, L4_OUTPUT, L5_PATH, L6_WIDTH, L7_HEIGHT]),
            "missing required key `seed`",
            vec![],
        ),
        jobs_case(
            "missing_output_table",
            toml(&[L1_SAMPLE, L2_METHOD, L3_SEED, L8_PARAMS, L9_BLOCK]),
            "missing required table [output]",
            vec![],
        ),
        jobs_case(
            "missing_output_width",
            toml(&[L1_SAMPLE, L2_METHOD, L3_SEED, L4_OUTPUT, L5_PATH, L7_HEIGHT]),
            "missing required key `output.width`",
            vec![],
        ),
        // --- output paths ---------------------------------------------------------------------
        jobs_case(
            "output_path_absolute",
            base_with(5, r#"path = "@TMP@/escaped_absolute.png""#),
            "not absolute",
            vec!["bad.toml:5:8", "`output.path`"],
        ),
        jobs_case("output_path_dotdot", base_with(5, r#"path = "../escaped.png""#), "no `..`", vec!["bad.toml:5:8", "`output.path`"]),
        jobs_case(
            "output_path_nested_dotdot",
            base_with(5, r#"path = "a/../../escaped.png""#),
            "no `..`",
            vec!["bad.toml:5:8", "`output.path`"],
        ),
        jobs_case(
            "output_path_manifest_json",
            base_with(5, r#"path = "manifest.json""#),
            "reserved for the manifest",
            vec!["bad.toml:5:8", "`output.path`"],
        ),
        jobs_case("output_path_nul_byte", base_with(5, r#"path = "x\u0000.png""#), "NUL", vec!["bad.toml:5:8", "`output.path`"]),
        jobs_case(
            "output_extension_jpg",
            base_with(5, r#"path = "x.jpg""#),
            "must end in .png or .exr",
            vec!["bad.toml:5:8", "`output.path`"],
        ),
        jobs_case(
            "bit_depth_12",
            base_plus(&[]).replace("height = 64\n", "height = 64\nbit_depth = 12\n"),
            "bit depth 12 is not supported",
            vec!["bad.toml:8:13", "`output.bit_depth`"],
        ),
        jobs_case(
            "bit_depth_on_exr",
            base_with(5, r#"path = "x.exr""#).replace("height = 64\n", "height = 64\nbit_depth = 16\n"),
            "applies to PNG only",
            vec!["bad.toml:8:13", "`output.bit_depth`"],
        ),
        jobs_case(
            "unknown_placeholder_in_output_path",
            base_with(5, r#"path = "x_{foo}.png""#),
            "unknown placeholder `{foo}`",
            vec!["bad.toml:5:8", "`output.path`"],
        ),
        jobs_case(
            "lattice_rows_zero",
            base_with(2, r#"method = "coevolution""#).replace("block = 16\n", "rows = 0\ncols = 4\n"),
            "0 is out of range: allowed 1..=4096, or \"cover\"",
            vec!["bad.toml:9:1", "`params.rows`"],
        ),
        jobs_case(
            "tile_odd_overlap",
            base_with(2, r#"method = "rw-tiles""#).replace("block = 16\n", "tile = 32\noverlap = 5\n"),
            "overlap 5 must be even",
            vec!["bad.toml:10:", "`params.overlap`"],
        ),
        // --- sweeps ---------------------------------------------------------------------------
        jobs_case(
            "sweep_unknown_key",
            base_plus(&["[sweep]", "blok = [16, 20]"]),
            "did you mean `block`",
            vec!["bad.toml:11:1", "`sweep.blok`"],
        ),
        jobs_case(
            "sweep_empty_list",
            base_with(3, "").replace("path = \"x.png\"", "path = \"x{seed}.png\"") + "[sweep]\nseed = []\n",
            "sweep list is empty",
            vec!["bad.toml:11:8", "`sweep.seed`"],
        ),
        jobs_case(
            "sweep_duplicate_value",
            base_with(3, "").replace("path = \"x.png\"", "path = \"x{seed}.png\"") + "[sweep]\nseed = [1, 2, 1]\n",
            "appears twice",
            vec!["bad.toml:11:15", "`sweep.seed`"],
        ),
        jobs_case(
            "sweep_range_from_after_to",
            base_with(3, "").replace("path = \"x.png\"", "path = \"x{seed}.png\"") + "[sweep]\nseed = { from = 3, to = 1 }\n",
            "from 3 is after to 1",
            vec!["bad.toml:11:8", "`sweep.seed`"],
        ),
        jobs_case(
            "seed_both_top_level_and_sweep",
            base_with(5, r#"path = "x{seed}.png""#) + "[sweep]\nseed = [1, 2]\n",
            "both at the top level and in [sweep]",
            vec!["bad.toml:3:8", "`seed`"],
        ),
        // --- the method's own checks, which need the decoded sample ---------------------------
        Case {
            name: "block_larger_than_sample",
            files: vec![
                ("jobs/bad.toml", Entry::Text(job_for_sample("small.png").replace("block = 16", "block = 50"))),
                ("jobs/small.png", Entry::Bytes(noise_png(32, 32, 2))),
            ],
            exit: 1,
            names: "bad.toml",
            cause: "larger than the sample",
            also: vec!["bad.toml:9:", "`params.block`", "32x32"],
            bad_ids: vec!["bad.toml"],
            with_good: true,
            hold_lock: false,
            args: None,
        },
        // --- hostile images -------------------------------------------------------------------
        image_case("image_empty_file", "empty.png", Vec::new(), "empty"),
        image_case("image_random_bytes", "random.png", random_bytes(4096), "not a recognised image"),
        image_case(
            "image_truncated_png",
            "truncated.png",
            {
                let p = noise_png(64, 64, 5);
                p[..p.len() / 2].to_vec()
            },
            "truncated|unexpected end",
        ),
        image_case("image_header_only_png", "header_only.png", noise_png(64, 64, 6)[..33].to_vec(), "truncated|unexpected end"),
        image_case("image_png_claims_100000x100000", "huge.png", crafted_png(100_000, 100_000), "limit"),
        image_case("image_png_16384x16384_bomb", "bomb.png", crafted_png(16_384, 16_384), "limit"),
        image_case("image_png_zero_width", "zero.png", crafted_png(0, 64), "zero|dimension"),
        image_case("image_png_bad_ihdr_crc", "badcrc.png", png_with_bad_ihdr_crc(), "CRC|checksum"),
        image_case("image_gif_unsupported", "anim.gif", tiny_gif(), "unsupported image format"),
        image_case("image_bmp_unsupported", "pic.bmp", tiny_bmp(), "unsupported image format"),
        image_case("image_corrupt_exr", "broken.exr", corrupt_exr(), "EXR"),
        image_case("image_png_corrupt_idat", "garbled.png", png_with_garbage_idat(), "corrupt|invalid|deflate|zlib|decompress"),
        image_case(
            "image_truncated_jpeg",
            "truncated.jpg",
            {
                let j = noise_jpeg(64, 64, 7);
                j[..j.len() / 2].to_vec()
            },
            "truncated|unexpected end",
        ),
        Case {
            name: "sample_is_a_directory",
            files: vec![("jobs/bad.toml", Entry::Text(job_for_sample("dir.png"))), ("jobs/dir.png", Entry::Dir)],
            exit: 1,
            names: "dir.png",
            cause: "is not a file",
            also: vec!["bad.toml:1:10", "`sample`"],
            bad_ids: vec!["bad.toml"],
            with_good: true,
            hold_lock: false,
            args: None,
        },
        Case {
            name: "sample_is_a_symlink_to_dev_zero",
            files: vec![("jobs/bad.toml", Entry::Text(job_for_sample("zero.png"))), ("jobs/zero.png", Entry::Symlink("/dev/zero".into()))],
            exit: 1,
            names: "zero.png",
            cause: "is not a file",
            also: vec!["bad.toml:1:10", "`sample`"],
            bad_ids: vec!["bad.toml"],
            with_good: true,
            hold_lock: false,
            args: None,
        },
        // --- several jobs ---------------------------------------------------------------------
        Case {
            name: "two_jobs_write_the_same_output",
            files: vec![
                ("jobs/a.toml", Entry::Text(base_with(5, r#"path = "same.png""#))),
                ("jobs/b.toml", Entry::Text(base_with(5, r#"path = "same.png""#).replace("seed = 7", "seed = 8"))),
                ("jobs/s.png", Entry::Bytes(noise_png(64, 64, 1))),
            ],
            exit: 1,
            names: "a.toml",
            cause: "also written by b.toml",
            also: vec!["a.toml:5:", "`output.path`", "same.png"],
            bad_ids: vec!["a.toml", "b.toml"],
            with_good: true,
            hold_lock: false,
            args: None,
        },
        // --- the output directory -------------------------------------------------------------
        Case {
            name: "symlinked_dir_in_output_points_outside",
            files: vec![
                ("jobs/bad.toml", Entry::Text(base_with(5, r#"path = "link/x.png""#))),
                ("jobs/s.png", Entry::Bytes(noise_png(64, 64, 1))),
                ("outside", Entry::Dir),
                ("out", Entry::Dir),
                ("out/link", Entry::Symlink("@TMP@/outside".into())),
            ],
            exit: 1,
            names: "bad.toml",
            cause: "outside the output directory",
            also: vec!["link/x.png"],
            bad_ids: vec!["bad.toml"],
            with_good: true,
            hold_lock: false,
            args: None,
        },
        Case {
            name: "symlinked_output_file_points_outside",
            files: vec![
                ("jobs/bad.toml", Entry::Text(base_with(5, r#"path = "x.png""#))),
                ("jobs/s.png", Entry::Bytes(noise_png(64, 64, 1))),
                ("victim.png", Entry::Bytes(b"do not overwrite".to_vec())),
                ("out", Entry::Dir),
                ("out/x.png", Entry::Symlink("@TMP@/victim.png".into())),
            ],
            exit: 1,
            names: "bad.toml",
            cause: "symlink",
            also: vec!["x.png"],
            bad_ids: vec!["bad.toml"],
            with_good: true,
            hold_lock: false,
            args: None,
        },
        Case {
            name: "no_job_files",
            files: vec![("jobs", Entry::Dir), ("jobs/notes.txt", Entry::Text("not a job".into()))],
            exit: 2,
            names: "jobs",
            cause: "no job files",
            also: vec![],
            bad_ids: vec![],
            with_good: false,
            hold_lock: false,
            args: None,
        },
        Case {
            name: "job_file_argument_missing",
            files: vec![("jobs/s.png", Entry::Bytes(noise_png(64, 64, 1)))],
            exit: 2,
            names: "missing.toml",
            cause: "No such file|not found|does not exist",
            also: vec![],
            bad_ids: vec![],
            with_good: false,
            hold_lock: false,
            args: Some(vec!["jobs/missing.toml", "-o", "out", "-j", "1", "-q"]),
        },
        Case {
            name: "output_directory_is_a_file",
            files: vec![
                ("jobs/s.png", Entry::Bytes(noise_png(64, 64, 1))),
                ("jobs/ok.toml", Entry::Text(base_plus(&[]))),
                ("out", Entry::Text("a file".into())),
            ],
            exit: 2,
            names: "out",
            cause: "cannot create output directory|Not a directory|File exists",
            also: vec![],
            bad_ids: vec![],
            with_good: false,
            hold_lock: false,
            args: None,
        },
        Case {
            name: "output_directory_locked",
            files: vec![
                ("jobs/s.png", Entry::Bytes(noise_png(64, 64, 1))),
                ("jobs/ok.toml", Entry::Text(base_plus(&[]))),
                ("out", Entry::Dir),
            ],
            exit: 2,
            names: "out",
            cause: "another texsyn run",
            also: vec![],
            bad_ids: vec![],
            with_good: false,
            hold_lock: true,
            args: None,
        },
    ];
    // The non-UTF-8 file is bytes, not text.
    for c in &mut v {
        if c.name == "non_utf8_job_file" {
            c.files[0].1 = Entry::Bytes(
                format!("{L1_SAMPLE}\n{L2_METHOD}\n# caf")
                    .into_bytes()
                    .into_iter()
                    .chain([0xE9, 0xFF, b'\n'])
                    .chain(toml(&[L3_SEED, L4_OUTPUT, L5_PATH, L6_WIDTH, L7_HEIGHT]).into_bytes())
                    .collect(),
            );
        }
    }
    v
}

// ---------------------------------------------------------------------------------------------
// Running one case.
// ---------------------------------------------------------------------------------------------

fn good_job() -> String {
    toml(&[
        r#"sample = "good.png""#,
        r#"method = "quilting""#,
        "seed = 3",
        "[output]",
        r#"path = "good/out.png""#,
        "width = 48",
        "height = 48",
        "[params]",
        "block = 16",
    ])
}

/// Everything under `root` (not following symlinks): relative path -> what it is.
fn snapshot(root: &Path) -> BTreeMap<PathBuf, String> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<PathBuf, String>) {
        let Ok(entries) = std::fs::read_dir(dir) else { return };
        for e in entries.flatten() {
            let p = e.path();
            let rel = p.strip_prefix(root).unwrap().to_path_buf();
            let Ok(meta) = std::fs::symlink_metadata(&p) else { continue };
            let ft = meta.file_type();
            if ft.is_symlink() {
                out.insert(rel, format!("symlink -> {}", std::fs::read_link(&p).map(|t| t.display().to_string()).unwrap_or_default()));
            } else if ft.is_dir() {
                out.insert(rel, "dir".into());
                walk(root, &p, out);
            } else if ft.is_file() {
                let bytes = std::fs::read(&p).unwrap_or_default();
                out.insert(rel, format!("file {} bytes, crc {:08x}", bytes.len(), crc32(&bytes)));
            } else {
                out.insert(rel, "other".into());
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(root, root, &mut out);
    out
}

fn under_out(rel: &Path) -> bool {
    rel.components().next().is_some_and(|c| c.as_os_str() == "out")
}

/// Changes outside `out/` between two snapshots.
fn changes_outside_out(before: &BTreeMap<PathBuf, String>, after: &BTreeMap<PathBuf, String>) -> Vec<String> {
    let mut changes = Vec::new();
    for (p, what) in after {
        if under_out(p) {
            continue;
        }
        match before.get(p) {
            None => changes.push(format!("created {} ({what})", p.display())),
            Some(old) if old != what => changes.push(format!("changed {} ({old} -> {what})", p.display())),
            _ => {}
        }
    }
    for p in before.keys() {
        if !under_out(p) && !after.contains_key(p) {
            changes.push(format!("removed {}", p.display()));
        }
    }
    changes
}

/// Does `text` contain `pattern` (`a|b`: either)?
fn contains_any(text: &str, pattern: &str) -> bool {
    pattern.split('|').any(|alt| text.contains(alt))
}

struct Outcome {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    problems: Vec<String>,
}

fn run_case(base: &Path, idx: usize, case: &Case) -> Outcome {
    let tmp = base.join(format!("case{idx:02}"));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(tmp.join("jobs")).unwrap();
    let tmp_str = tmp.display().to_string();
    let mut files = case.files.clone();
    if case.with_good {
        files.push(("jobs/good.toml", Entry::Text(good_job())));
        files.push(("jobs/good.png", Entry::Bytes(noise_png(64, 64, 9))));
    }
    for (rel, entry) in &files {
        let path = tmp.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        match entry {
            Entry::Text(t) => std::fs::write(&path, t.replace("@TMP@", &tmp_str)).unwrap(),
            Entry::Bytes(b) => std::fs::write(&path, b).unwrap(),
            Entry::Dir => std::fs::create_dir_all(&path).unwrap(),
            Entry::Symlink(target) => std::os::unix::fs::symlink(target.replace("@TMP@", &tmp_str), &path).unwrap(),
        }
    }
    let _lock = case.hold_lock.then(|| {
        let f = File::options().read(true).write(true).create(true).truncate(false).open(tmp.join("out/.texsyn.lock")).unwrap();
        f.lock().unwrap();
        f
    });

    let before = snapshot(&tmp);
    let stdout_path = base.join(format!("case{idx:02}.stdout"));
    let stderr_path = base.join(format!("case{idx:02}.stderr"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_texsyn"))
        .arg("run")
        .args(case.args.clone().unwrap_or_else(|| vec!["jobs", "-o", "out", "-j", "1", "-q"]))
        .current_dir(&tmp)
        .env_remove("RUST_BACKTRACE")
        .env_remove("RUST_LIB_BACKTRACE")
        .stdin(Stdio::null())
        .stdout(File::create(&stdout_path).unwrap())
        .stderr(File::create(&stderr_path).unwrap())
        .spawn()
        .expect("run texsyn");
    let started = Instant::now();
    let mut problems = Vec::new();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if started.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            let _ = child.wait();
            problems.push("texsyn did not finish within 120 s (killed)".to_string());
            break None;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let code = status.and_then(|s| s.code());
    if let Some(s) = status.filter(|s| s.code().is_none()) {
        problems.push(format!("texsyn was killed by a signal: {s:?}"));
    }
    let stdout = String::from_utf8_lossy(&std::fs::read(&stdout_path).unwrap_or_default()).into_owned();
    let stderr = String::from_utf8_lossy(&std::fs::read(&stderr_path).unwrap_or_default()).into_owned();
    let after = snapshot(&tmp);

    // Exit code.
    if code != Some(case.exit) {
        problems.push(format!("exit code {code:?}, expected {}", case.exit));
    }
    // No panic.
    for (stream, text) in [("stderr", &stderr), ("stdout", &stdout)] {
        for marker in ["panicked", "RUST_BACKTRACE"] {
            if text.contains(marker) {
                problems.push(format!("{stream} contains {marker:?} (a panic)"));
            }
        }
    }
    // One error line names the file and the cause (and the details).
    let mut required: Vec<&str> = vec![case.names, case.cause];
    required.extend(case.also.iter().copied());
    let line_ok = stderr.lines().any(|l| l.starts_with("error:") && required.iter().all(|r| contains_any(l, r)));
    if !line_ok {
        problems.push(format!("no `error:` line of stderr contains all of {required:?}"));
    }
    // Nothing written outside the output directory.
    for c in changes_outside_out(&before, &after) {
        problems.push(format!("outside the output directory: {c}"));
    }
    // Exit 1: the valid job still ran; the manifest records the bad ones with the cause.
    if case.exit == 1 {
        if case.with_good && !tmp.join("out/good/out.png").is_file() {
            problems.push("the valid job's output out/good/out.png was not written".into());
        }
        match std::fs::read(tmp.join("out/manifest.json")).ok().and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok()) {
            None => problems.push("out/manifest.json is missing or not JSON".into()),
            Some(m) => {
                let jobs = m["jobs"].as_array().cloned().unwrap_or_default();
                let find = |id: &str| jobs.iter().find(|j| j["id"] == id).cloned();
                if case.with_good {
                    match find("good.toml") {
                        Some(j) if j["status"] == "ok" => {}
                        other => problems.push(format!("manifest: good.toml should be ok, found {other:?}")),
                    }
                }
                for id in &case.bad_ids {
                    match find(id) {
                        None => problems.push(format!("manifest: no record for {id}")),
                        Some(j) => {
                            let status = j["status"].as_str().unwrap_or("");
                            if status != "invalid" && status != "failed" {
                                problems.push(format!("manifest: {id} has status {status:?}, expected invalid or failed"));
                            }
                            let error = j["error"].as_str().unwrap_or("");
                            let cause = if *id == "b.toml" { "also written by a.toml" } else { case.cause };
                            if !contains_any(error, cause) {
                                problems.push(format!("manifest: {id}'s error {error:?} does not contain {cause:?}"));
                            }
                        }
                    }
                }
            }
        }
    }
    if problems.is_empty() {
        let _ = std::fs::remove_dir_all(&tmp);
        let _ = std::fs::remove_file(&stdout_path);
        let _ = std::fs::remove_file(&stderr_path);
    }
    Outcome { code, stdout, stderr, problems }
}

#[test]
fn bad_input_is_refused_with_a_message_naming_the_file_and_the_cause() {
    let cases = cases();
    assert!(cases.len() >= 30, "the issue asks for at least 30 cases, have {}", cases.len());
    let mut names: Vec<&str> = cases.iter().map(|c| c.name).collect();
    names.sort();
    names.dedup();
    assert_eq!(names.len(), cases.len(), "case names must be unique");

    let base = std::env::temp_dir().join(format!("texsyn-bad-input-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    std::fs::create_dir_all(&base).unwrap();

    let verbose = std::env::var_os("TEXSYN_TEST_VERBOSE").is_some();
    let mut failures = Vec::new();
    for (i, case) in cases.iter().enumerate() {
        let o = run_case(&base, i, case);
        let verdict = if o.problems.is_empty() { "ok  " } else { "FAIL" };
        eprintln!("{verdict} {:<44} exit {:?}", case.name, o.code);
        if verbose {
            eprintln!("     stderr: {}", o.stderr.trim_end().replace('\n', "\n             "));
        }
        if !o.problems.is_empty() {
            failures.push(format!(
                "case {} ({}):\n  - {}\n  exit code: {:?}\n  stderr:\n    {}\n  stdout:\n    {}",
                i,
                case.name,
                o.problems.join("\n  - "),
                o.code,
                o.stderr.trim_end().replace('\n', "\n    "),
                o.stdout.trim_end().replace('\n', "\n    "),
            ));
        }
    }
    if failures.is_empty() {
        let _ = std::fs::remove_dir_all(&base);
    }
    assert!(
        failures.is_empty(),
        "{} of {} bad-input cases failed (their directories are kept under {}):\n\n{}",
        failures.len(),
        cases.len(),
        base.display(),
        failures.join("\n\n")
    );
}
