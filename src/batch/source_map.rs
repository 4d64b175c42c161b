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
//! Version 2, for a job with several samples or `augment` (its placement is over an atlas of
//! them, [`crate::synth::atlas`]): `X`, `Y` are in the pixel's own sample, and two more channels
//! say which: `S` (the index in the job's `samples`) and `T` (the transform: 0 as it is, 1 rot90,
//! 2 rot180, 3 rot270, 4 flip_h, 5 flip_v), likewise `B{k}S`, `B{k}T` for each blend step. The
//! attribute is `2 samples=W1xH1,W2xH2,… augment=rot90,…`: enough to rebuild the atlas from the
//! samples and replay the map over them, or over any maps of their sizes.
//!
//! Any EXR reader shows `X` and `Y` as images of where each pixel came from.

use crate::synth::atlas::{Atlas, Augment};
use crate::synth::params::Choice;
use crate::synth::placement::{Placement, UNCOVERED};
use exr::prelude::*;

const ATTRIBUTE: &str = "texsyn-placement";

/// Encodes a placement as a source-map EXR: version 1 over one sample, version 2 over an atlas
/// of several samples or transformed copies (`atlas`, whose size the placement's sample is).
pub fn encode(p: &Placement, atlas: Option<&Atlas>) -> std::result::Result<Vec<u8>, String> {
    let (w, h) = p.dimensions();
    let (sw, sh) = p.sample_size();
    let n = w as usize * h as usize;
    let steps = p.max_blends();
    // A sample index as (x, y, sample, transform) in the sample it shows.
    let split = |s: u32| -> [u32; 4] {
        if s == UNCOVERED {
            return [UNCOVERED; 4];
        }
        let (ax, ay) = (s % sw, s / sw);
        match atlas {
            None => [ax, ay, 0, 0],
            Some(a) => match a.locate(ax, ay) {
                Some((piece, (x, y))) => [x, y, piece.sample as u32, piece.transform.map_or(0, Augment::code)],
                None => [UNCOVERED; 4],
            },
        }
    };
    let fields = if atlas.is_some() { 4 } else { 2 };
    let mut base: Vec<Vec<u32>> = (0..fields).map(|_| Vec::with_capacity(n)).collect();
    let mut blend_channels: Vec<Vec<Vec<u32>>> = (0..steps).map(|_| (0..fields + 2).map(|_| vec![0; n]).collect()).collect();
    for y in 0..h {
        for x in 0..w {
            let v = split(p.source(x, y));
            for (f, ch) in base.iter_mut().enumerate() {
                ch.push(v[f]);
            }
            let i = y as usize * w as usize + x as usize;
            for (k, b) in p.blends_at(x, y).iter().enumerate() {
                let v = split(b.source);
                let ch = &mut blend_channels[k];
                for f in 0..fields {
                    ch[f][i] = v[f];
                }
                (ch[fields][i], ch[fields + 1][i]) = (b.num, b.den);
            }
        }
    }
    let names = ["X", "Y", "S", "T"];
    let mut list: Vec<AnyChannel<FlatSamples>> =
        base.into_iter().zip(names).map(|(data, name)| AnyChannel::new(name, FlatSamples::U32(data))).collect();
    let blend_names: Vec<&str> = names[..fields].iter().copied().chain(["N", "D"]).collect();
    for (k, ch) in blend_channels.into_iter().enumerate() {
        for (suffix, data) in blend_names.iter().zip(ch) {
            list.push(AnyChannel::new(format!("B{}{suffix}", k + 1).as_str(), FlatSamples::U32(data)));
        }
    }
    let mut attrs = LayerAttributes::named("placement");
    let info = match atlas {
        None => format!("1 sample={sw}x{sh}"),
        Some(a) => {
            let sizes: Vec<String> = a.sample_sizes().iter().map(|(w, h)| format!("{w}x{h}")).collect();
            let augment: Vec<&str> = a.augment().into_iter().map(Augment::name).collect();
            format!("2 samples={} augment={}", sizes.join(","), augment.join(","))
        }
    };
    attrs.other.insert(Text::from(ATTRIBUTE), AttributeValue::Text(Text::from(info.as_str())));
    let layer = Layer::new((w as usize, h as usize), attrs, Encoding::FAST_LOSSLESS, AnyChannels::sort(SmallVec::from_vec(list)));
    let mut cursor = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().non_parallel().to_buffered(&mut cursor).map_err(|e| format!("EXR encoding failed: {e}"))?;
    Ok(cursor.into_inner())
}

/// A decoded source map: the placement, over the atlas of its samples for version 2.
pub struct SourceMap {
    /// Over one sample (version 1) or over `atlas` (version 2).
    pub placement: Placement,
    pub atlas: Option<Atlas>,
}

impl SourceMap {
    /// The sizes of the images it renders from, one per sample.
    pub fn sample_sizes(&self) -> Vec<(u32, u32)> {
        match &self.atlas {
            None => vec![self.placement.sample_size()],
            Some(a) => a.sample_sizes(),
        }
    }
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

/// Decodes a source map written by [`encode`] into its placement (over the atlas of its samples
/// for version 2); the error says what is wrong with the file.
pub fn decode(bytes: &[u8]) -> std::result::Result<Placement, String> {
    decode_map(bytes).map(|m| m.placement)
}

/// Decodes a source map of either version; the error says what is wrong with the file.
pub fn decode_map(bytes: &[u8]) -> std::result::Result<SourceMap, String> {
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
    let size = |s: &str| -> Option<(u32, u32)> {
        let (a, b) = s.split_once('x')?;
        Some((a.parse::<u32>().ok()?, b.parse::<u32>().ok()?))
    };
    let atlas = if let Some(rest) = info.strip_prefix("2 ") {
        let bad = || format!("malformed version 2 source map attribute `{info}`");
        let (samples, augment) = rest.split_once(' ').ok_or_else(bad)?;
        let sizes: Vec<(u32, u32)> =
            samples.strip_prefix("samples=").ok_or_else(bad)?.split(',').map(size).collect::<Option<_>>().ok_or_else(bad)?;
        let augment: Vec<Augment> = match augment.strip_prefix("augment=").ok_or_else(bad)? {
            "" => Vec::new(),
            list => list.split(',').map(Augment::parse).collect::<Option<_>>().ok_or_else(bad)?,
        };
        if sizes.is_empty()
            || sizes.len() > 4096
            || sizes.iter().any(|&(w, h)| w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_PIXELS)
        {
            return Err(bad());
        }
        Some(Atlas::layout(&sizes, &augment))
    } else {
        None
    };
    let sample = match &atlas {
        Some(a) => a.dimensions(),
        None => info
            .strip_prefix("1 sample=")
            .and_then(size)
            .ok_or_else(|| format!("unsupported source map `{info}` (this texsyn reads versions 1 and 2)"))?,
    };
    let (w, h) = (layer.size.width() as u32, layer.size.height() as u32);
    let channel = |name: &str| -> Option<&Vec<u32>> {
        layer.channel_data.list.iter().find(|c| c.name.eq(name)).and_then(|c| match &c.sample_data {
            FlatSamples::U32(v) => Some(v),
            _ => None,
        })
    };
    // Where (x, y) of sample `s` under transform `t` lies in what the placement renders from.
    let place = |x: u32, y: u32, s: u32, t: u32| -> std::result::Result<(u32, u32), String> {
        match &atlas {
            None if x < sample.0 && y < sample.1 => Ok((x, y)),
            None => Err(format!("source map points at ({x}, {y}), outside its {}x{} sample", sample.0, sample.1)),
            Some(a) => {
                let transform = Augment::from_code(t).ok_or_else(|| format!("source map has an unknown transform code {t}"))?;
                a.position(s as usize, transform, x, y).ok_or_else(|| {
                    format!("source map points at ({x}, {y}) of sample {s} under transform {t}, which its samples do not have")
                })
            }
        }
    };
    let zeros = vec![0u32; w as usize * h as usize];
    let pick = |name: &str| -> Option<&Vec<u32>> { if atlas.is_some() { channel(name) } else { Some(&zeros) } };
    let (Some(xs), Some(ys), Some(ss), Some(ts)) = (channel("X"), channel("Y"), pick("S"), pick("T")) else {
        return Err("source map lacks its integer X and Y channels (and S and T for version 2)".into());
    };
    let mut p = Placement::new(w, h, sample);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            if xs[i] == UNCOVERED {
                continue;
            }
            let (sx, sy) = place(xs[i], ys[i], ss[i], ts[i])?;
            p.copy(x, y, sx, sy);
        }
    }
    let mut k = 1;
    while let (Some(bx), Some(by), Some(bs), Some(bt), Some(bn), Some(bd)) = (
        channel(&format!("B{k}X")),
        channel(&format!("B{k}Y")),
        pick(&format!("B{k}S")),
        pick(&format!("B{k}T")),
        channel(&format!("B{k}N")),
        channel(&format!("B{k}D")),
    ) {
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if bd[i] == 0 {
                    continue;
                }
                let (sx, sy) = place(bx[i], by[i], bs[i], bt[i])?;
                if xs[i] == UNCOVERED {
                    return Err(format!("source map blends into uncovered pixel ({x}, {y})"));
                }
                p.blend(x, y, sx, sy, bn[i], bd[i]);
            }
        }
        k += 1;
    }
    Ok(SourceMap { placement: p, atlas })
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
        let bytes = encode(&p, None).unwrap();
        let back = decode(&bytes).unwrap();
        assert_eq!(back.sample_size(), (7, 4));
        let s = RgbImage::from_fn(7, 4, |x, y| [(x * 30) as u8, (y * 60) as u8, 90]);
        assert_eq!(back.render_rgb8(&s), p.render_rgb8(&s));
        assert_eq!(back.blends_at(1, 0), p.blends_at(1, 0));
        assert_eq!(back.source(3, 1), UNCOVERED);
    }

    #[test]
    fn version_2_names_each_pixels_sample_and_transform_and_round_trips() {
        let atlas = Atlas::layout(&[(7, 4), (5, 6)], &[Augment::Rot90]);
        let (aw, ah) = atlas.dimensions();
        let mut p = Placement::new(4, 2, (aw, ah));
        let at = |s, t, x, y| atlas.position(s, t, x, y).unwrap();
        let (x0, y0) = at(1, Some(Augment::Rot90), 4, 2);
        p.copy(0, 0, x0, y0);
        let (x1, y1) = at(0, None, 6, 3);
        p.copy(1, 0, x1, y1);
        let (x2, y2) = at(1, None, 0, 5);
        p.blend(1, 0, x2, y2, 1, 4);
        let bytes = encode(&p, Some(&atlas)).unwrap();
        let map = decode_map(&bytes).unwrap();
        assert_eq!(map.atlas.as_ref(), Some(&atlas));
        assert_eq!(map.sample_sizes(), vec![(7, 4), (5, 6)]);
        assert_eq!(map.placement, p);
        // Any EXR reader sees the sample, transform and pixel in the sample's own coordinates.
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .from_buffered(std::io::Cursor::new(&bytes))
            .unwrap();
        let ch = |name: &str| match &image.layer_data.channel_data.list.iter().find(|c| c.name.eq(name)).unwrap().sample_data {
            FlatSamples::U32(v) => v.clone(),
            _ => panic!(),
        };
        assert_eq!((ch("X")[0], ch("Y")[0], ch("S")[0], ch("T")[0]), (4, 2, 1, 1));
        assert_eq!((ch("B1X")[1], ch("B1Y")[1], ch("B1S")[1], ch("B1T")[1], ch("B1N")[1], ch("B1D")[1]), (0, 5, 1, 0, 1, 4));
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
