//! One synthesis from a sample already in memory, made exactly as a job would make it: the output
//! in the sample's own precision and channels, and a record with the manifest's keys and digests.
//!
//! Job files go through the plan and the runner; callers without one (the Python package, a
//! one-off command) come here, so that the same method, parameters, seed and sample give the same
//! pixels and the same pixel digest whichever door they came through.

use crate::batch::execute::{LoadedSample, main_output};
use crate::batch::job::OutputSpec;
use crate::batch::manifest;
use crate::digest::Digest;
use crate::error::Error;
use crate::image::io::{Format, NativeImage, Samples};
use crate::synth::advice;
use crate::synth::method::Synthesis;
use crate::synth::params::ParamValue;
use crate::synthesizer::Synthesizer;
use std::time::Instant;

/// What to make: a method by name with job-file parameter values, a seed, a size (the sample's
/// when `None`), whether it wraps, and whether to return the placement.
#[derive(Clone, Debug)]
pub struct SingleRequest {
    pub method: String,
    pub params: Vec<(String, ParamValue)>,
    pub seed: u64,
    pub size: Option<(u32, u32)>,
    pub tileable: bool,
    pub placement: bool,
}

/// A finished synthesis.
pub struct Single {
    /// The output in the sample's precision and channels (what a job's PNG at the sample's depth,
    /// or its EXR for a float sample, stores).
    pub image: NativeImage,
    /// The method's result: its 8-bit image, seams, diagnostics and (when asked for, or needed to
    /// render a sample that is not 8-bit RGB) the placement.
    pub synthesis: Synthesis,
    /// The manifest keys of a job record: method, algorithm version, resolved params and their
    /// digest, seed, sample, output spec, content key, outputs with their pixel digest, warnings,
    /// diagnostics and timing.
    pub record: serde_json::Value,
    /// Plain sentences when the method and parameters do not fit the sample (`texsyn advise`).
    pub warnings: Vec<String>,
    /// Seconds in the method's synthesis call alone.
    pub synthesis_seconds: f64,
}

/// The output spec a job would have for this sample and size: PNG at the sample's depth, EXR for
/// a float sample. Its path is empty: no file is written.
fn output_spec(sample: &LoadedSample, width: u32, height: u32, tileable: bool) -> OutputSpec {
    let float = matches!(sample.native.as_ref().map(|n| &n.samples), Some(Samples::F32(_)));
    let (format, bit_depth) = if float { (Format::Exr, 32) } else { (Format::Png, sample.native_png_depth()) };
    OutputSpec { path: String::new(), width, height, format, bit_depth, native_depth: false, tileable, source_map: None }
}

/// Synthesises from `sample` as a job with these values would, validating them with the job
/// file's messages ([`Error::Params`] names each parameter).
pub fn synthesize(sample: &LoadedSample, req: &SingleRequest) -> Result<Single, Error> {
    let mut builder = Synthesizer::by_name(&req.method, req.params.clone())?.seed(req.seed);
    if let Some((w, h)) = req.size {
        builder = builder.size(w, h);
    }
    if req.tileable {
        builder = builder.tileable();
    }
    if req.placement || sample.native.is_some() {
        builder = builder.placement();
    }
    let session = builder.build(&sample.image)?;
    let method = session.method();
    let params_json = session.params().to_json();
    let started = Instant::now();
    let synthesis = session.run()?;
    let synthesis_seconds = started.elapsed().as_secs_f64();
    let (width, height) = synthesis.image.dimensions();
    let image = main_output(&synthesis, sample);
    let spec = output_spec(sample, width, height, req.tileable);
    let spec_json = spec.to_json();
    let warnings: Vec<String> = advice::warning(&advice::analyse(&sample.image), method.name(), session.params()).into_iter().collect();
    let content_key =
        manifest::content_key(method.name(), method.algorithm_version(), &params_json, req.seed, &sample.pixel_digest, &spec_json);
    let record = serde_json::json!({
        "method": method.name(),
        "algorithm_version": method.algorithm_version(),
        "params_digest": Digest::of_json(&params_json),
        "params": params_json,
        "seed": req.seed,
        "sample": {
            "file_digest": sample.file_digest,
            "pixel_digest": sample.pixel_digest,
            "width": sample.image.width(),
            "height": sample.image.height(),
        },
        "output_spec": spec_json,
        "content_key": content_key,
        "outputs": [{
            "format": spec.format.name(),
            "bit_depth": spec.bit_depth,
            "width": width,
            "height": height,
            "pixel_digest": image.pixel_digest(),
        }],
        "seams": synthesis.seams,
        "diagnostics": synthesis.diagnostics,
        "warnings": warnings,
        "timing": {"synthesis_seconds": synthesis_seconds},
    });
    Ok(Single { image, synthesis, record, warnings, synthesis_seconds })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::RgbImage;

    #[test]
    fn the_output_and_its_digest_are_the_methods_own_for_an_8_bit_sample() {
        let img = RgbImage::from_fn(64, 64, |x, y| [(x * 4) as u8, (y * 4) as u8, ((x ^ y) * 4) as u8]);
        let sample = LoadedSample::from_native(NativeImage::from_rgb8(&img));
        let req = SingleRequest {
            method: "quilting".into(),
            params: vec![crate::synth::params::int("block", 16)],
            seed: 3,
            size: Some((48, 40)),
            tileable: false,
            placement: false,
        };
        let a = synthesize(&sample, &req).unwrap();
        let b = synthesize(&sample, &req).unwrap();
        assert_eq!(a.image, b.image);
        assert_eq!(a.image, NativeImage::from_rgb8(&a.synthesis.image));
        assert_eq!(a.record["outputs"][0]["pixel_digest"], serde_json::to_value(a.image.pixel_digest()).unwrap());
        assert_eq!(a.record["params"]["overlap"], 3, "resolved parameters are recorded");
        let bad = SingleRequest { params: vec![crate::synth::params::int("block", 2)], ..req };
        assert!(synthesize(&sample, &bad).err().unwrap().to_string().contains("`block`: 2 is out of range"));
    }
}
