//! Image decoding and encoding, with limits, and the canonical pixel digest.
//!
//! Decoding turns any supported file (PNG 8/16-bit gray/RGB/RGBA, JPEG, EXR) into the 8-bit RGB
//! [`RgbImage`] methods work on, refusing hostile files (huge dimensions, decompression bombs,
//! truncation, zero size) with an error instead of a crash or a multi-gigabyte allocation.
//! Encoding chooses the output format and bit depth from the job, never from the method.

use crate::digest::{Digest, Hasher};
use crate::image::RgbImage;
use std::path::Path;

/// Refusal thresholds for decoding.
#[derive(Clone, Copy, Debug)]
pub struct DecodeLimits {
    pub max_side: u32,
    pub max_pixels: u64,
    pub max_alloc_bytes: u64,
}

impl std::default::Default for DecodeLimits {
    fn default() -> Self {
        // 16k per side and 64 Mpixel are far beyond any texture sample and still decodable.
        DecodeLimits { max_side: 16_384, max_pixels: 64 << 20, max_alloc_bytes: 1 << 30 }
    }
}

/// Output file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    Png,
    Exr,
}

impl Format {
    /// The format implied by a file name's extension.
    pub fn from_path(path: &Path) -> Option<Format> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "png" => Some(Format::Png),
            "exr" => Some(Format::Exr),
            _ => None,
        }
    }
    pub fn name(&self) -> &'static str {
        match self {
            Format::Png => "png",
            Format::Exr => "exr",
        }
    }
}

/// Decoded samples in their stored precision, for pixel digests of written outputs.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    U8(Vec<u8>),
    U16(Vec<u16>),
    F32(Vec<f32>),
}

/// An image in its stored precision: `width × height × channels` samples, row-major, interleaved.
#[derive(Clone, Debug, PartialEq)]
pub struct NativeImage {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    pub samples: Samples,
}

impl NativeImage {
    pub fn from_rgb8(img: &RgbImage) -> NativeImage {
        NativeImage { width: img.width(), height: img.height(), channels: 3, samples: Samples::U8(img.as_raw().to_vec()) }
    }

    /// SHA-256 over `texsyn-pixels/1 {width}x{height}x{channels} {u8|u16le|f32le}\n` followed by
    /// the raw samples (little-endian for multi-byte types). Independent of file compression.
    pub fn pixel_digest(&self) -> Digest {
        let kind = match self.samples {
            Samples::U8(_) => "u8",
            Samples::U16(_) => "u16le",
            Samples::F32(_) => "f32le",
        };
        let mut h = pixel_hasher(self.width, self.height, self.channels, kind);
        match &self.samples {
            Samples::U8(v) => h.update(v),
            Samples::U16(v) => {
                let bytes: Vec<u8> = v.iter().flat_map(|s| s.to_le_bytes()).collect();
                h.update(&bytes);
            }
            Samples::F32(v) => {
                let bytes: Vec<u8> = v.iter().flat_map(|s| s.to_le_bytes()).collect();
                h.update(&bytes);
            }
        }
        h.finish()
    }
}

/// A hasher fed with the canonical header of [`NativeImage::pixel_digest`].
fn pixel_hasher(width: u32, height: u32, channels: u32, kind: &str) -> Hasher {
    let mut h = Hasher::new();
    h.update(format!("texsyn-pixels/1 {width}x{height}x{channels} {kind}\n").as_bytes());
    h
}

/// The pixel digest of an 8-bit RGB image (what methods see of a sample): the same as
/// `NativeImage::from_rgb8(img).pixel_digest()`, without copying the pixels.
pub fn rgb_pixel_digest(img: &RgbImage) -> Digest {
    let mut h = pixel_hasher(img.width(), img.height(), 3, "u8");
    h.update(img.as_raw());
    h.finish()
}

/// Why an image could not be read, decoded or encoded. Messages say what is wrong with the file,
/// not where it is: callers add the path.
#[derive(Debug)]
pub enum ImageError {
    /// The file could not be read.
    Io(std::io::Error),
    /// The bytes are not an image texsyn decodes (empty, truncated, corrupt, over the limits, …).
    Decode(String),
    /// The pixels could not be encoded in the requested format.
    Encode(String),
}

impl std::fmt::Display for ImageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ImageError::Io(e) => write!(f, "cannot read: {e}"),
            ImageError::Decode(m) | ImageError::Encode(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for ImageError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ImageError::Io(e) => Some(e),
            _ => None,
        }
    }
}

/// Decodes a sample file into 8-bit RGB. Errors say what is wrong with the file, not where it is
/// (callers add the path).
pub fn decode_rgb8(bytes: &[u8], limits: DecodeLimits) -> Result<RgbImage, ImageError> {
    let native = decode_native(bytes, limits)?;
    Ok(native_to_rgb8(&native))
}

/// Reads and decodes a sample file.
pub fn read_rgb8(path: &Path, limits: DecodeLimits) -> Result<(RgbImage, Vec<u8>), ImageError> {
    let bytes = crate::files::read_limited(path, crate::files::MAX_IMAGE_FILE_BYTES).map_err(ImageError::Io)?;
    let img = decode_rgb8(&bytes, limits)?;
    Ok((img, bytes))
}

fn check_size(w: u32, h: u32, limits: DecodeLimits) -> Result<(), ImageError> {
    if w == 0 || h == 0 {
        return Err(ImageError::Decode(format!("image has zero size ({w}x{h})")));
    }
    if w > limits.max_side || h > limits.max_side || w as u64 * h as u64 > limits.max_pixels {
        return Err(ImageError::Decode(format!(
            "image is {w}x{h}, larger than the decoder's limit ({} per side, {} pixels); refusing to decode it",
            limits.max_side, limits.max_pixels
        )));
    }
    Ok(())
}

/// Decodes PNG, JPEG or EXR into its stored precision and channels (gray, gray + alpha, RGB,
/// RGBA; EXR as RGB, or RGBA when it has an alpha channel).
pub fn decode_native(bytes: &[u8], limits: DecodeLimits) -> Result<NativeImage, ImageError> {
    if bytes.is_empty() {
        return Err(ImageError::Decode("file is empty".into()));
    }
    if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        return decode_exr(bytes, limits);
    }
    let format = image::guess_format(bytes).map_err(|_| ImageError::Decode("not a recognised image (expected PNG, JPEG or EXR)".into()))?;
    if !matches!(format, image::ImageFormat::Png | image::ImageFormat::Jpeg) {
        return Err(ImageError::Decode(format!("unsupported image format {format:?} (expected PNG, JPEG or EXR)")));
    }
    if format == image::ImageFormat::Jpeg && !jpeg_is_complete(bytes) {
        // The JPEG decoder pads a truncated scan with flat colour instead of failing.
        return Err(ImageError::Decode("file is truncated (the JPEG has no end-of-image marker after its last scan)".into()));
    }
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut l = image::Limits::default();
    l.max_image_width = Some(limits.max_side);
    l.max_image_height = Some(limits.max_side);
    l.max_alloc = Some(limits.max_alloc_bytes);
    reader.limits(l);
    let (w, h) = reader.into_dimensions().map_err(describe_image_error)?;
    check_size(w, h, limits)?;
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let mut l = image::Limits::default();
    l.max_image_width = Some(limits.max_side);
    l.max_image_height = Some(limits.max_side);
    l.max_alloc = Some(limits.max_alloc_bytes);
    reader.limits(l);
    let img = reader.decode().map_err(describe_image_error)?;
    use image::DynamicImage as D;
    let (w, h) = (img.width(), img.height());
    let native = |channels: u32, samples: Samples| NativeImage { width: w, height: h, channels, samples };
    Ok(match img {
        D::ImageLuma8(i) => native(1, Samples::U8(i.into_raw())),
        D::ImageLumaA8(i) => native(2, Samples::U8(i.into_raw())),
        D::ImageRgb8(i) => native(3, Samples::U8(i.into_raw())),
        D::ImageRgba8(i) => native(4, Samples::U8(i.into_raw())),
        D::ImageLuma16(i) => native(1, Samples::U16(i.into_raw())),
        D::ImageLumaA16(i) => native(2, Samples::U16(i.into_raw())),
        D::ImageRgb16(i) => native(3, Samples::U16(i.into_raw())),
        D::ImageRgba16(i) => native(4, Samples::U16(i.into_raw())),
        D::ImageRgb32F(i) => native(3, Samples::F32(i.into_raw())),
        D::ImageRgba32F(i) => native(4, Samples::F32(i.into_raw())),
        other => native(3, Samples::U8(other.to_rgb8().into_raw())),
    })
}

/// Decodes an output file as stored: [`decode_native`] (kept as the name verification uses).
pub fn decode_output(bytes: &[u8], limits: DecodeLimits) -> Result<NativeImage, ImageError> {
    decode_native(bytes, limits)
}

/// Reads an image file as 8-bit RGBA (`width`, `height`, samples); images without alpha are
/// opaque. Errors say what is wrong with the file (callers add the path).
pub fn decode_rgba8(bytes: &[u8], limits: DecodeLimits) -> Result<(u32, u32, Vec<u8>), ImageError> {
    let native = decode_output(bytes, limits)?;
    let (w, h) = (native.width, native.height);
    if native.channels == 4 {
        let data = match native.samples {
            Samples::U8(v) => v,
            Samples::U16(v) => v.iter().map(|&s| ((s as u32 * 255 + 32767) / 65535) as u8).collect(),
            Samples::F32(_) => return Err(ImageError::Decode("floating-point RGBA is not supported here".into())),
        };
        return Ok((w, h, data));
    }
    let rgb = native_to_rgb8(&native);
    let data = rgb.as_raw().chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect();
    Ok((w, h, data))
}

/// Encodes 8-bit RGBA samples as PNG.
pub fn encode_rgba8_png(width: u32, height: u32, data: &[u8]) -> Result<Encoded, ImageError> {
    if data.len() != width as usize * height as usize * 4 {
        return Err(ImageError::Encode(format!("RGBA data of {} bytes does not match {width}x{height}", data.len())));
    }
    let mut bytes = Vec::new();
    image::ImageEncoder::write_image(image::codecs::png::PngEncoder::new(&mut bytes), data, width, height, image::ExtendedColorType::Rgba8)
        .map_err(|e| ImageError::Encode(format!("PNG encoding failed: {e}")))?;
    Ok(Encoded { bytes, pixels: NativeImage { width, height, channels: 4, samples: Samples::U8(data.to_vec()) } })
}

/// Whether an end-of-image marker (FF D9) follows the last start-of-scan marker (FF DA). Inside
/// entropy-coded data 0xFF is always stuffed or a restart marker, so neither can occur there; an
/// EXIF thumbnail's own markers come before the main scan.
fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let last = |marker: u8| bytes.windows(2).rposition(|w| w[0] == 0xFF && w[1] == marker);
    match (last(0xDA), last(0xD9)) {
        (Some(sos), Some(eoi)) => eoi > sos,
        _ => false,
    }
}

fn describe_image_error(e: image::ImageError) -> ImageError {
    ImageError::Decode(describe_image_error_text(e))
}

fn describe_image_error_text(e: image::ImageError) -> String {
    match e {
        image::ImageError::Limits(l) => format!("image exceeds the decoder's limits ({l}); refusing to decode it"),
        image::ImageError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "file is truncated (unexpected end of data)".into()
        }
        other => format!("cannot decode image: {other}"),
    }
}

fn decode_exr(bytes: &[u8], limits: DecodeLimits) -> Result<NativeImage, ImageError> {
    use exr::prelude::*;
    let meta = MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| ImageError::Decode(format!("cannot read EXR header: {e}")))?;
    let header = meta.headers.first().ok_or_else(|| ImageError::Decode("EXR file has no layers".into()))?;
    let size = header.layer_size;
    if size.width() > u32::MAX as usize || size.height() > u32::MAX as usize {
        return Err(ImageError::Decode("EXR layer is impossibly large".into()));
    }
    check_size(size.width() as u32, size.height() as u32, limits)?;
    let has_alpha = header.channels.list.iter().any(|c| c.name.eq("A"));
    let c = if has_alpha { 4 } else { 3 };
    // The exr crate validates chunk tables against the header; a panic inside it is still turned
    // into an error rather than taking the process down.
    let result = std::panic::catch_unwind(|| {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .rgba_channels(
                move |resolution, _| (resolution.width(), vec![0f32; resolution.width() * resolution.height() * c]),
                move |(w, px): &mut (usize, Vec<f32>), pos: Vec2<usize>, (r, g, b, a): (f32, f32, f32, f32)| {
                    let i = (pos.y() * *w + pos.x()) * c;
                    px[i] = r;
                    px[i + 1] = g;
                    px[i + 2] = b;
                    if c == 4 {
                        px[i + 3] = a;
                    }
                },
            )
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(bytes))
    });
    let image = match result {
        Ok(Ok(img)) => img,
        Ok(Err(e)) => return Err(ImageError::Decode(format!("cannot decode EXR: {e}"))),
        Err(_) => return Err(ImageError::Decode("cannot decode EXR: the decoder failed on malformed data".into())),
    };
    let (w, h) = (image.layer_data.size.width() as u32, image.layer_data.size.height() as u32);
    let (_, px) = image.layer_data.channel_data.pixels;
    Ok(NativeImage { width: w, height: h, channels: c as u32, samples: Samples::F32(px) })
}

/// Quantises any stored precision and channel count to the 8-bit RGB methods work on (what the
/// search sees): gray is repeated in R, G and B, alpha is dropped, 16 bits are rounded to 8, float
/// (linear light) is encoded as sRGB.
pub fn native_to_rgb8(img: &NativeImage) -> RgbImage {
    let c = img.channels as usize;
    let rgb_of = |px: &[u8]| -> [u8; 3] { if c < 3 { [px[0]; 3] } else { [px[0], px[1], px[2]] } };
    let eight: Vec<u8> = match &img.samples {
        Samples::U8(v) => v.clone(),
        Samples::U16(v) => v.iter().map(|&s| ((s as u32 * 255 + 32767) / 65535) as u8).collect(),
        Samples::F32(v) => v.iter().map(|&s| unit_to_u8(linear_to_srgb(s as f64))).collect(),
    };
    if c == 3 {
        return RgbImage::from_raw(img.width, img.height, eight).expect("decoded size matches");
    }
    let data: Vec<u8> = eight.chunks_exact(c).flat_map(rgb_of).collect();
    RgbImage::from_raw(img.width, img.height, data).expect("decoded size matches")
}

fn unit_to_u8(v: f64) -> u8 {
    if v.is_nan() { 0 } else { (v * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8 }
}

/// The sRGB transfer function (IEC 61966-2-1), both directions, on unit scale.
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
}

pub fn linear_to_srgb(v: f64) -> f64 {
    if v <= 0.0031308 { v * 12.92 } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// How an output is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Encoding {
    pub format: Format,
    /// 8 or 16 for PNG; 32 (float) for EXR.
    pub bit_depth: u8,
}

/// An encoded output: the file bytes and the stored pixels they decode to.
pub struct Encoded {
    pub bytes: Vec<u8>,
    pub pixels: NativeImage,
}

/// Rows per strip when an 8-bit PNG is compressed from an image in memory ([`encode_to`]).
const PNG_STRIP_ROWS: u32 = 64;

/// Encodes like [`encode`] straight into `w` (the same bytes) and returns the pixel digest of
/// what was stored. 8-bit PNG is compressed strip by strip into IDAT chunks of 1 MiB as they fill
/// ([`encode_png_strips`]): besides the image only one strip and the compressor's window are held.
/// (Compressing the whole image first, as the `image` crate's PNG encoder does, kept the whole
/// compressed stream, grown by doubling: up to twice the raw image again.)
pub fn encode_to(img: &RgbImage, enc: Encoding, w: &mut dyn std::io::Write) -> Result<Digest, ImageError> {
    if (enc.format, enc.bit_depth) == (Format::Png, 8) {
        let (width, height) = img.dimensions();
        let row = width as usize * 3;
        let raw = img.as_raw();
        return encode_png_strips_with(width, height, PNG_STRIP_ROWS, png::Compression::Fast, w, &mut |y0, rows| {
            rows.copy_from_slice(&raw[y0 as usize * row..y0 as usize * row + rows.len()]);
        });
    }
    let encoded = encode(img, enc)?;
    w.write_all(&encoded.bytes).map_err(ImageError::Io)?;
    Ok(encoded.pixels.pixel_digest())
}

/// Encodes an 8-bit RGB PNG of `width × height` from strips of `strip_rows` rows that
/// `render(y0, rows)` fills, into `w` as it goes; returns the pixel digest. Memory: one strip and
/// the compressor's window, whatever the size. The same pixels and filter as [`encode`], at
/// zlib's default level (smaller files, slower than `encode`'s fast compressor).
pub fn encode_png_strips(
    width: u32,
    height: u32,
    strip_rows: u32,
    w: &mut dyn std::io::Write,
    render: &mut dyn FnMut(u32, &mut [u8]),
) -> Result<Digest, ImageError> {
    encode_png_strips_with(width, height, strip_rows, png::Compression::Balanced, w, render)
}

/// [`encode_png_strips`] at a given compression: the fills use zlib's default level (tiles repeat
/// far apart, which it finds); images in memory use the fast compressor, as they always have.
fn encode_png_strips_with(
    width: u32,
    height: u32,
    strip_rows: u32,
    compression: png::Compression,
    w: &mut dyn std::io::Write,
    render: &mut dyn FnMut(u32, &mut [u8]),
) -> Result<Digest, ImageError> {
    let fail = |e: png::EncodingError| ImageError::Encode(format!("PNG encoding failed: {e}"));
    let mut encoder = png::Encoder::new(w, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(compression);
    encoder.set_filter(png::Filter::Adaptive);
    let mut writer = encoder.write_header().map_err(fail)?;
    let mut stream = writer.stream_writer_with_size(1 << 20).map_err(fail)?;
    let mut digest = pixel_hasher(width, height, 3, "u8");
    let row = width as usize * 3;
    let mut strip = vec![0u8; row * strip_rows.clamp(1, height.max(1)) as usize];
    let mut y0 = 0;
    while y0 < height {
        let n = strip_rows.max(1).min(height - y0);
        let rows = &mut strip[..row * n as usize];
        render(y0, rows);
        digest.update(rows);
        std::io::Write::write_all(&mut stream, rows).map_err(ImageError::Io)?;
        y0 += n;
    }
    stream.finish().map_err(fail)?;
    writer.finish().map_err(fail)?;
    Ok(digest.finish())
}

/// Encodes an 8-bit RGB image as PNG (8 or 16 bits) or EXR (32-bit float, linear light: the sRGB
/// values are linearised, since EXR holds scene-linear data).
pub fn encode(img: &RgbImage, enc: Encoding) -> Result<Encoded, ImageError> {
    let (w, h) = img.dimensions();
    match (enc.format, enc.bit_depth) {
        (Format::Png, 8) => {
            let mut bytes = Vec::new();
            encode_to(img, enc, &mut bytes)?;
            Ok(Encoded { bytes, pixels: NativeImage::from_rgb8(img) })
        }
        (Format::Png, 16) => {
            let wide: Vec<u16> = img.as_raw().iter().map(|&v| v as u16 * 257).collect();
            let ne: Vec<u8> = wide.iter().flat_map(|s| s.to_ne_bytes()).collect();
            let mut bytes = Vec::new();
            image::ImageEncoder::write_image(image::codecs::png::PngEncoder::new(&mut bytes), &ne, w, h, image::ExtendedColorType::Rgb16)
                .map_err(|e| ImageError::Encode(format!("PNG encoding failed: {e}")))?;
            Ok(Encoded { bytes, pixels: NativeImage { width: w, height: h, channels: 3, samples: Samples::U16(wide) } })
        }
        (Format::Exr, _) => {
            use exr::prelude::*;
            let lut: Vec<f32> = (0..256).map(|v| srgb_to_linear(v as f64 / 255.0) as f32).collect();
            let linear: Vec<f32> = img.as_raw().iter().map(|&v| lut[v as usize]).collect();
            let width = w as usize;
            let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
                let i = (pos.y() * width + pos.x()) * 3;
                (linear[i], linear[i + 1], linear[i + 2])
            });
            let layer = Layer::new((w as usize, h as usize), LayerAttributes::named("texsyn"), Encoding::FAST_LOSSLESS, channels);
            let image = Image::from_layer(layer);
            let mut cursor = std::io::Cursor::new(Vec::new());
            image.write().non_parallel().to_buffered(&mut cursor).map_err(|e| ImageError::Encode(format!("EXR encoding failed: {e}")))?;
            Ok(Encoded {
                bytes: cursor.into_inner(),
                pixels: NativeImage { width: w, height: h, channels: 3, samples: Samples::F32(linear) },
            })
        }
        (Format::Png, d) => Err(ImageError::Encode(format!("PNG bit depth {d} is not supported (use 8 or 16)"))),
    }
}

/// The samples an image is stored as under `enc`: the same channels (EXR: gray becomes RGB, gray +
/// alpha RGBA), converted to the encoding's precision. Integer to integer widens by `× 257` or
/// rounds `(v·255 + 32767) / 65535`; integer to EXR decodes sRGB to linear light; EXR to integer
/// encodes sRGB. Alpha is never transfer-encoded. Float to float is untouched: values above 1 and
/// below 0 stay.
pub fn stored_samples(img: &NativeImage, enc: Encoding) -> Result<NativeImage, ImageError> {
    let c = img.channels as usize;
    if !(1..=4).contains(&c) {
        return Err(ImageError::Encode(format!("{c} channels cannot be stored")));
    }
    let has_alpha = c == 2 || c == 4;
    let is_alpha = |k: usize| has_alpha && k % c == c - 1;
    if enc.format == Format::Png && matches!((&img.samples, enc.bit_depth), (Samples::U8(_), 8) | (Samples::U16(_), 16)) {
        return Ok(img.clone());
    }
    let unit: Vec<f64> = match &img.samples {
        Samples::U8(v) => v.iter().map(|&x| f64::from(x) / 255.0).collect(),
        Samples::U16(v) => v.iter().map(|&x| f64::from(x) / 65535.0).collect(),
        Samples::F32(v) => v.iter().map(|&x| f64::from(x)).collect(),
    };
    let float_in = matches!(img.samples, Samples::F32(_));
    let samples = match (enc.format, enc.bit_depth, &img.samples) {
        (Format::Png, 16, Samples::U8(v)) => Samples::U16(v.iter().map(|&x| u16::from(x) * 257).collect()),
        (Format::Png, 8, Samples::U16(v)) => Samples::U8(v.iter().map(|&x| ((u32::from(x) * 255 + 32767) / 65535) as u8).collect()),
        (Format::Png, 8, Samples::F32(_)) => Samples::U8(
            unit.iter().enumerate().map(|(k, &v)| if is_alpha(k) { unit_to_u8(v) } else { unit_to_u8(linear_to_srgb(v)) }).collect(),
        ),
        (Format::Png, 16, Samples::F32(_)) => Samples::U16(
            unit.iter()
                .enumerate()
                .map(|(k, &v)| {
                    let v = if is_alpha(k) { v } else { linear_to_srgb(v) };
                    if v.is_nan() { 0 } else { (v * 65535.0 + 0.5).floor().clamp(0.0, 65535.0) as u16 }
                })
                .collect(),
        ),
        (Format::Png, d, _) => return Err(ImageError::Encode(format!("PNG bit depth {d} is not supported (use 8 or 16)"))),
        (Format::Exr, _, _) => {
            let lin: Vec<f32> = if float_in {
                unit.iter().map(|&v| v as f32).collect()
            } else {
                unit.iter().enumerate().map(|(k, &v)| if is_alpha(k) { v as f32 } else { srgb_to_linear(v) as f32 }).collect()
            };
            // EXR holds colour: gray is stored as R = G = B.
            let lin = if c <= 2 {
                lin.chunks_exact(c).flat_map(|p| if c == 1 { vec![p[0]; 3] } else { vec![p[0], p[0], p[0], p[1]] }).collect()
            } else {
                lin
            };
            let channels = if has_alpha { 4 } else { 3 };
            return Ok(NativeImage { width: img.width, height: img.height, channels, samples: Samples::F32(lin) });
        }
    };
    Ok(NativeImage { width: img.width, height: img.height, channels: img.channels, samples })
}

/// Encodes an image in any precision and channel count ([`stored_samples`] says what is stored)
/// into `w`; returns the pixel digest of what was stored.
pub fn encode_native_to(img: &NativeImage, enc: Encoding, w: &mut dyn std::io::Write) -> Result<Digest, ImageError> {
    let stored = stored_samples(img, enc)?;
    let (width, height) = (stored.width, stored.height);
    match &stored.samples {
        Samples::U8(v) => {
            let color = match stored.channels {
                1 => image::ExtendedColorType::L8,
                2 => image::ExtendedColorType::La8,
                3 => image::ExtendedColorType::Rgb8,
                _ => image::ExtendedColorType::Rgba8,
            };
            image::ImageEncoder::write_image(image::codecs::png::PngEncoder::new(w), v, width, height, color)
                .map_err(|e| ImageError::Encode(format!("PNG encoding failed: {e}")))?;
        }
        Samples::U16(v) => {
            let color = match stored.channels {
                1 => image::ExtendedColorType::L16,
                2 => image::ExtendedColorType::La16,
                3 => image::ExtendedColorType::Rgb16,
                _ => image::ExtendedColorType::Rgba16,
            };
            // The encoder takes native-endian samples (and writes PNG's big-endian itself).
            let ne: Vec<u8> = v.iter().flat_map(|s| s.to_ne_bytes()).collect();
            image::ImageEncoder::write_image(image::codecs::png::PngEncoder::new(w), &ne, width, height, color)
                .map_err(|e| ImageError::Encode(format!("PNG encoding failed: {e}")))?;
        }
        Samples::F32(v) => {
            use exr::prelude::*;
            let wu = width as usize;
            let c = stored.channels as usize;
            let size = (wu, height as usize);
            let attrs = LayerAttributes::named("texsyn");
            let mut cursor = std::io::Cursor::new(Vec::new());
            let fail = |e: exr::error::Error| ImageError::Encode(format!("EXR encoding failed: {e}"));
            if c == 4 {
                let channels = SpecificChannels::rgba(|pos: Vec2<usize>| {
                    let i = (pos.y() * wu + pos.x()) * 4;
                    (v[i], v[i + 1], v[i + 2], v[i + 3])
                });
                Image::from_layer(Layer::new(size, attrs, exr::prelude::Encoding::FAST_LOSSLESS, channels))
                    .write()
                    .non_parallel()
                    .to_buffered(&mut cursor)
                    .map_err(fail)?;
            } else {
                let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
                    let i = (pos.y() * wu + pos.x()) * 3;
                    (v[i], v[i + 1], v[i + 2])
                });
                Image::from_layer(Layer::new(size, attrs, exr::prelude::Encoding::FAST_LOSSLESS, channels))
                    .write()
                    .non_parallel()
                    .to_buffered(&mut cursor)
                    .map_err(fail)?;
            }
            w.write_all(&cursor.into_inner()).map_err(ImageError::Io)?;
        }
    }
    Ok(stored.pixel_digest())
}

/// [`encode_native_to`] into memory.
pub fn encode_native(img: &NativeImage, enc: Encoding) -> Result<Encoded, ImageError> {
    let mut bytes = Vec::new();
    encode_native_to(img, enc, &mut bytes)?;
    let pixels = stored_samples(img, enc)?;
    Ok(Encoded { bytes, pixels })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img() -> RgbImage {
        RgbImage::from_fn(17, 9, |x, y| [(x * 15) as u8, (y * 28) as u8, (x * y) as u8])
    }

    #[test]
    fn png8_round_trips_exactly() {
        let e = encode(&img(), Encoding { format: Format::Png, bit_depth: 8 }).unwrap();
        let back = decode_native(&e.bytes, DecodeLimits::default()).unwrap();
        assert_eq!(back, e.pixels);
        assert_eq!(native_to_rgb8(&back), img());
    }

    #[test]
    fn encoding_into_a_writer_gives_the_same_bytes_and_digest() {
        for (format, bit_depth) in [(Format::Png, 8), (Format::Png, 16), (Format::Exr, 32)] {
            let enc = Encoding { format, bit_depth };
            let whole = encode(&img(), enc).unwrap();
            let mut streamed = Vec::new();
            let digest = encode_to(&img(), enc, &mut streamed).unwrap();
            assert_eq!(streamed, whole.bytes, "{format:?} {bit_depth}");
            assert_eq!(digest, whole.pixels.pixel_digest());
        }
        assert_eq!(rgb_pixel_digest(&img()), NativeImage::from_rgb8(&img()).pixel_digest());
    }

    #[test]
    fn png_in_strips_has_the_same_pixels() {
        let whole = img();
        for strip in [1, 4, 9, 100] {
            let mut bytes = Vec::new();
            let digest = encode_png_strips(17, 9, strip, &mut bytes, &mut |y0, rows| {
                rows.copy_from_slice(&whole.as_raw()[y0 as usize * 17 * 3..][..rows.len()]);
            })
            .unwrap();
            assert_eq!(digest, rgb_pixel_digest(&whole));
            let back = decode_native(&bytes, DecodeLimits::default()).unwrap();
            assert_eq!(back.pixel_digest(), digest, "strips of {strip}");
        }
    }

    #[test]
    fn native_encodings_round_trip_with_their_digest() {
        let u16s: Vec<u16> = (0..17 * 9 * 3).map(|i| (i * 911 % 65536) as u16).collect();
        let f32s: Vec<f32> = (0..17 * 9 * 4).map(|i| i as f32 / 50.0 - 1.0).collect();
        let cases = [
            (NativeImage { width: 17, height: 9, channels: 3, samples: Samples::U16(u16s.clone()) }, Format::Png, 16),
            (NativeImage { width: 17, height: 9, channels: 1, samples: Samples::U16(u16s[..153].to_vec()) }, Format::Png, 16),
            (NativeImage { width: 17, height: 9, channels: 2, samples: Samples::U8(vec![7; 17 * 9 * 2]) }, Format::Png, 8),
            (NativeImage { width: 17, height: 9, channels: 4, samples: Samples::F32(f32s) }, Format::Exr, 32),
            (NativeImage { width: 17, height: 9, channels: 3, samples: Samples::U16(u16s) }, Format::Png, 8),
        ];
        for (img, format, bit_depth) in cases {
            let enc = Encoding { format, bit_depth };
            let e = encode_native(&img, enc).unwrap();
            let back = decode_native(&e.bytes, DecodeLimits::default()).unwrap();
            assert_eq!(back, e.pixels, "{format:?} {bit_depth} {} channels", img.channels);
            let mut w = Vec::new();
            assert_eq!(encode_native_to(&img, enc, &mut w).unwrap(), back.pixel_digest());
        }
    }

    #[test]
    fn png16_round_trips_and_quantises_back() {
        let e = encode(&img(), Encoding { format: Format::Png, bit_depth: 16 }).unwrap();
        let back = decode_native(&e.bytes, DecodeLimits::default()).unwrap();
        assert_eq!(back, e.pixels);
        assert!(matches!(back.samples, Samples::U16(_)));
        assert_eq!(native_to_rgb8(&back), img());
    }

    #[test]
    fn exr_is_linear_and_round_trips() {
        let e = encode(&img(), Encoding { format: Format::Exr, bit_depth: 32 }).unwrap();
        let back = decode_native(&e.bytes, DecodeLimits::default()).unwrap();
        assert_eq!(back.pixel_digest(), e.pixels.pixel_digest());
        assert_eq!(native_to_rgb8(&back), img());
        if let Samples::F32(v) = &back.samples {
            // sRGB 128 is about 0.2158 in linear light.
            let probe = RgbImage::from_fn(1, 1, |_, _| [128, 128, 128]);
            let e2 = encode(&probe, Encoding { format: Format::Exr, bit_depth: 32 }).unwrap();
            if let Samples::F32(p) = e2.pixels.samples {
                assert!((p[0] - 0.2158).abs() < 1e-3, "{}", p[0]);
            }
            assert_eq!(v.len(), 17 * 9 * 3);
        } else {
            panic!("EXR decoded to integers");
        }
    }

    #[test]
    fn rgba_png_round_trips_with_its_alpha() {
        let data: Vec<u8> = (0..5 * 3).flat_map(|i| [i as u8, 2 * i as u8, 3 * i as u8, if i % 2 == 0 { 255 } else { 0 }]).collect();
        let e = encode_rgba8_png(5, 3, &data).unwrap();
        let back = decode_output(&e.bytes, DecodeLimits::default()).unwrap();
        assert_eq!(back, e.pixels);
        assert_eq!(back.channels, 4);
        assert_eq!(decode_rgba8(&e.bytes, DecodeLimits::default()).unwrap(), (5, 3, data));
        // An RGB file reads as opaque RGBA, and its recorded pixels are still RGB.
        let rgb = encode(&img(), Encoding { format: Format::Png, bit_depth: 8 }).unwrap();
        assert_eq!(decode_output(&rgb.bytes, DecodeLimits::default()).unwrap().channels, 3);
        let (_, _, opaque) = decode_rgba8(&rgb.bytes, DecodeLimits::default()).unwrap();
        assert!(opaque.chunks_exact(4).all(|p| p[3] == 255));
        assert!(encode_rgba8_png(5, 3, &[0; 7]).is_err());
    }

    #[test]
    fn pixel_digest_depends_on_pixels_and_shape_only() {
        let a = NativeImage::from_rgb8(&img());
        let mut b = a.clone();
        assert_eq!(a.pixel_digest(), b.pixel_digest());
        b.width = 9;
        b.height = 17;
        assert_ne!(a.pixel_digest(), b.pixel_digest());
    }

    #[test]
    fn hostile_inputs_are_refused_with_reasons() {
        let good = encode(&img(), Encoding { format: Format::Png, bit_depth: 8 }).unwrap().bytes;
        let l = DecodeLimits::default();
        assert!(decode_native(&[], l).unwrap_err().to_string().contains("empty"));
        assert!(decode_native(b"hello world", l).unwrap_err().to_string().contains("not a recognised image"));
        let truncated = &good[..good.len() / 2];
        assert!(decode_native(truncated, l).is_err());
        let mut jpeg = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::jpeg::JpegEncoder::new(&mut jpeg),
            img().as_raw(),
            17,
            9,
            image::ExtendedColorType::Rgb8,
        )
        .unwrap();
        assert!(decode_native(&jpeg, l).is_ok());
        assert!(decode_native(&jpeg[..jpeg.len() - 40], l).unwrap_err().to_string().contains("truncated"));
        let tiny = DecodeLimits { max_side: 10, ..l };
        assert!(decode_native(&good, tiny).unwrap_err().to_string().contains("limit"));
    }
}
