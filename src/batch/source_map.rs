//! The source map: a placement (`synth::placement`) stored as a file, so that a result can be
//! replayed later over any map of the sample's size (`texsyn apply`), exactly.
//!
//! Encoding, version 1: an OpenEXR file with one layer of `width × height` pixels and only
//! unsigned 32-bit integer channels, so every value is exact:
//! - `X`, `Y`: the sample pixel the output pixel copies (both `4294967295` where nothing covers it);
//! - for each blend step `k = 1, 2, …` up to the longest chain: `B{k}X`, `B{k}Y` (the sample pixel
//!   blended in) and `B{k}N`, `B{k}D` (its weight `N / D`; `D = 0` where the pixel has fewer steps).
//!   Steps apply in order: `v ← (1 − N/D)·v + (N/D)·sample[B{k}X, B{k}Y]`, rounded to the image's
//!   precision after each step (kept as is for float).
//! - a text attribute `texsyn-placement` = `1 sample=WxH` (the version and the size of the images it
//!   renders from).
//!
//! Any EXR reader shows `X` and `Y` as images of where each pixel came from.

use crate::synth::placement::{Blend, Placement, UNCOVERED};
use exr::prelude::*;

const ATTRIBUTE: &str = "texsyn-placement";

/// Encodes a placement as a source-map EXR.
pub fn encode(p: &Placement) -> std::result::Result<Vec<u8>, String> {
    let (w, h) = p.dimensions();
    let (sw, _) = p.sample_size();
    let n = w as usize * h as usize;
    let steps = p.max_blends();
    let split = |s: u32| if s == UNCOVERED { (UNCOVERED, UNCOVERED) } else { (s % sw, s / sw) };
    let mut xs = Vec::with_capacity(n);
    let mut ys = Vec::with_capacity(n);
    let mut blend_channels: Vec<[Vec<u32>; 4]> = (0..steps).map(|_| [vec![0; n], vec![0; n], vec![0; n], vec![0; n]]).collect();
    for y in 0..h {
        for x in 0..w {
            let (sx, sy) = split(p.source(x, y));
            xs.push(sx);
            ys.push(sy);
            let i = y as usize * w as usize + x as usize;
            for (k, b) in p.blends_at(x, y).iter().enumerate() {
                let (bx, by) = split(b.source);
                let ch = &mut blend_channels[k];
                (ch[0][i], ch[1][i], ch[2][i], ch[3][i]) = (bx, by, b.num, b.den);
            }
        }
    }
    let mut list: Vec<AnyChannel<FlatSamples>> =
        vec![AnyChannel::new("X", FlatSamples::U32(xs)), AnyChannel::new("Y", FlatSamples::U32(ys))];
    for (k, ch) in blend_channels.into_iter().enumerate() {
        for (suffix, data) in ["X", "Y", "N", "D"].iter().zip(ch) {
            list.push(AnyChannel::new(format!("B{}{suffix}", k + 1).as_str(), FlatSamples::U32(data)));
        }
    }
    let mut attrs = LayerAttributes::named("placement");
    let (sw, sh) = p.sample_size();
    attrs.other.insert(Text::from(ATTRIBUTE), AttributeValue::Text(Text::from(format!("1 sample={sw}x{sh}").as_str())));
    let layer = Layer::new((w as usize, h as usize), attrs, Encoding::FAST_LOSSLESS, AnyChannels::sort(SmallVec::from_vec(list)));
    let mut cursor = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().non_parallel().to_buffered(&mut cursor).map_err(|e| format!("EXR encoding failed: {e}"))?;
    Ok(cursor.into_inner())
}

/// The largest source map [`decode`] reads: an output's side limit, 16384² pixels (about 2 GB of
/// placement), and the channels of the longest blend chains with room to spare.
const MAX_SIDE: u64 = crate::batch::job::MAX_OUTPUT_SIDE as u64;
const MAX_PIXELS: u64 = 1 << 28;
const MAX_CHANNELS: u64 = 64;

/// The size a source map's header declares, `(width, height, channels)` of its largest layer,
/// refused beyond the limits above. Read before anything is decoded, so that callers can weigh
/// the decoding's memory ([`decode`] holds the file's channels and the placement at once).
pub fn declared_size(bytes: &[u8]) -> std::result::Result<(u64, u64, u64), String> {
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| format!("not a readable EXR: cannot read its header: {e}"))?;
    let mut largest = (0, 0, 0);
    for header in &meta.headers {
        let (w, h) = (header.layer_size.width() as u64, header.layer_size.height() as u64);
        let channels = header.channels.list.len() as u64;
        if w > MAX_SIDE || h > MAX_SIDE || w * h > MAX_PIXELS || channels > MAX_CHANNELS {
            return Err(format!(
                "declares a {w}x{h} layer of {channels} channels; a source map is at most {MAX_SIDE} per side, {MAX_PIXELS} pixels and {MAX_CHANNELS} channels"
            ));
        }
        if w * h * channels > largest.0 * largest.1 * largest.2 {
            largest = (w, h, channels);
        }
    }
    Ok(largest)
}

/// Decodes a source map written by [`encode`]; the error says what is wrong with the file.
pub fn decode(bytes: &[u8]) -> std::result::Result<Placement, String> {
    // The header first: a small file may declare any size, and the decoder allocates what it
    // declares before reading a pixel.
    declared_size(bytes)?;
    let read = std::panic::catch_unwind(|| {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(bytes))
    });
    let image = match read {
        Ok(Ok(i)) => i,
        Ok(Err(e)) => return Err(format!("not a readable EXR: {e}")),
        Err(_) => return Err("not a readable EXR: the decoder failed on malformed data".into()),
    };
    let layer = &image.layer_data;
    let info = match layer.attributes.other.get(&Text::from(ATTRIBUTE)) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        _ => return Err(format!("not a texsyn source map (no `{ATTRIBUTE}` attribute)")),
    };
    let sample = info
        .strip_prefix("1 sample=")
        .and_then(|s| s.split_once('x'))
        .and_then(|(a, b)| Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?)))
        .ok_or_else(|| format!("unsupported source map `{info}` (this texsyn reads version 1)"))?;
    let (w, h) = (layer.size.width() as u32, layer.size.height() as u32);
    let channel = |name: &str| -> Option<&Vec<u32>> {
        layer.channel_data.list.iter().find(|c| c.name.eq(name)).and_then(|c| match &c.sample_data {
            FlatSamples::U32(v) => Some(v),
            _ => None,
        })
    };
    let (Some(xs), Some(ys)) = (channel("X"), channel("Y")) else {
        return Err("source map lacks its integer X and Y channels".into());
    };
    let mut p = Placement::new(w, h, sample);
    let check = |x: u32, y: u32| -> std::result::Result<(), String> {
        if x >= sample.0 || y >= sample.1 {
            Err(format!("source map points at ({x}, {y}), outside its {}x{} sample", sample.0, sample.1))
        } else {
            Ok(())
        }
    };
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if xs[i] == UNCOVERED {
                continue;
            }
            check(xs[i], ys[i])?;
            p.copy(x, y, xs[i], ys[i]);
        }
    }
    let mut k = 1;
    while let (Some(bx), Some(by), Some(bn), Some(bd)) =
        (channel(&format!("B{k}X")), channel(&format!("B{k}Y")), channel(&format!("B{k}N")), channel(&format!("B{k}D")))
    {
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if bd[i] == 0 {
                    continue;
                }
                check(bx[i], by[i])?;
                if xs[i] == UNCOVERED {
                    return Err(format!("source map blends into uncovered pixel ({x}, {y})"));
                }
                let b = Blend { source: by[i] * sample.0 + bx[i], num: bn[i], den: bd[i] };
                p.blend(x, y, bx[i], by[i], b.num, b.den);
            }
        }
        k += 1;
    }
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::RgbImage;

    #[test]
    fn round_trips_copies_blends_and_uncovered_pixels() {
        let mut p = Placement::new(5, 3, (7, 4));
        p.copy(0, 0, 6, 3);
        p.copy(1, 0, 2, 1);
        p.blend(1, 0, 3, 1, 2, 5);
        p.blend(1, 0, 0, 0, 1, 3);
        p.copy(4, 2, 1, 1);
        p.blend(4, 2, 5, 2, 3, 4);
        let bytes = encode(&p).unwrap();
        let back = decode(&bytes).unwrap();
        assert_eq!(back.sample_size(), (7, 4));
        let s = RgbImage::from_fn(7, 4, |x, y| [(x * 30) as u8, (y * 60) as u8, 90]);
        assert_eq!(back.render_rgb8(&s), p.render_rgb8(&s));
        assert_eq!(back.blends_at(1, 0), p.blends_at(1, 0));
        assert_eq!(back.source(3, 1), UNCOVERED);
    }

    #[test]
    fn other_files_are_refused_with_a_reason() {
        assert!(decode(b"not an exr").unwrap_err().contains("not a readable EXR"));
        let img = crate::image::io::encode(
            &RgbImage::new(4, 4),
            crate::image::io::Encoding { format: crate::image::io::Format::Exr, bit_depth: 32 },
        )
        .unwrap();
        assert!(decode(&img.bytes).unwrap_err().contains("not a texsyn source map"));
    }
}
