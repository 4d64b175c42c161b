//! Synthesising from Rust, without job files: a typed config, a seed and a size → a texture.
//!
//! The builder goes through the same parameter tables and method checks as a job file, so a bad
//! value is refused with the same message (naming the parameter and the allowed range) and a
//! texture made here has the same pixels as the job file with the same values.

use crate::error::Error;
use crate::image::RgbImage;
use crate::synth::method::{Method, Request, Synthesis};
use crate::synth::methods;
use crate::synth::params::{self, MethodConfig, ParamValue, Params};

/// Chooses a method, its parameters, the seed and the output size; [`Synthesizer::build`]
/// validates them against a sample.
///
/// ```no_run
/// use texsyn::{QuiltingConfig, Synthesizer};
/// let sample = texsyn::load_image("jobs/samples/bricks_gray.png")?;
/// let texture = Synthesizer::new(QuiltingConfig { block: 40, ..Default::default() })
///     .seed(7)
///     .size(512, 512)
///     .build(&sample)?
///     .run()?;
/// texsyn::save_image(&texture.image, "bricks_512.png")?;
/// # Ok::<(), texsyn::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct Synthesizer {
    method: &'static str,
    given: Vec<(String, ParamValue)>,
    seed: u64,
    size: Option<(u32, u32)>,
    placement: bool,
    tileable: bool,
}

impl Synthesizer {
    /// A synthesis with a method's typed configuration (seed 0, the sample's size until set).
    pub fn new<C: MethodConfig>(config: C) -> Synthesizer {
        Synthesizer { method: C::METHOD, given: config.to_params(), seed: 0, size: None, placement: false, tileable: false }
    }

    /// A synthesis by method name and job-file parameter values, for callers that pick the
    /// method at run time.
    pub fn by_name(method: &str, given: Vec<(String, ParamValue)>) -> Result<Synthesizer, Error> {
        let m = find(method)?;
        Ok(Synthesizer { method: m.name(), given, seed: 0, size: None, placement: false, tileable: false })
    }

    /// The seed: the only source of randomness.
    pub fn seed(mut self, seed: u64) -> Synthesizer {
        self.seed = seed;
        self
    }

    /// The output size in pixels (default: the sample's size).
    pub fn size(mut self, width: u32, height: u32) -> Synthesizer {
        self.size = Some((width, height));
        self
    }

    /// Also return the placement ([`Synthesis::placement`]): where every output pixel comes from,
    /// to render companion maps (normal, gloss…) or the sample in its own precision with
    /// [`crate::synth::placement::Placement::render`]. Never changes the pixels.
    pub fn placement(mut self) -> Synthesizer {
        self.placement = true;
        self
    }

    /// Make the output wrap seamlessly; [`Synthesizer::build`] refuses a method or size that cannot.
    pub fn tileable(mut self) -> Synthesizer {
        self.tileable = true;
        self
    }

    /// Validates every parameter (types, ranges, derived defaults) and the method's checks against
    /// this sample and size. [`Error::Params`] lists every problem, each naming its parameter.
    pub fn build(self, sample: &RgbImage) -> Result<Session<'_>, Error> {
        let method = find(self.method)?;
        let (width, height) = self.size.unwrap_or(sample.dimensions());
        if width == 0 || height == 0 {
            return Err(Error::Usage(format!("the output size must be at least 1x1 (got {width}x{height})")));
        }
        let mut params =
            params::resolve(method.params(), &self.given).map_err(|errors| Error::Params { method: method.name().into(), errors })?;
        method.resolve_for_sample(&mut params, sample.dimensions());
        let errors = method.check(&params, sample.dimensions(), (width, height));
        if !errors.is_empty() {
            return Err(Error::Params { method: method.name().into(), errors });
        }
        if self.tileable
            && let Err(why) = method.tileable(&params, sample.dimensions(), (width, height))
        {
            return Err(Error::Usage(why));
        }
        Ok(Session { method, params, sample, seed: self.seed, width, height, placement: self.placement, tileable: self.tileable })
    }
}

fn find(name: &str) -> Result<&'static dyn Method, Error> {
    methods::find(name).ok_or_else(|| Error::UnknownMethod { name: name.to_string(), known: methods::names() })
}

/// A validated synthesis, ready to run (any number of times: the result is always the same).
pub struct Session<'a> {
    method: &'static dyn Method,
    params: Params,
    sample: &'a RgbImage,
    seed: u64,
    width: u32,
    height: u32,
    placement: bool,
    tileable: bool,
}

impl Session<'_> {
    /// The fully resolved parameters, as a manifest records them.
    pub fn params(&self) -> &Params {
        &self.params
    }

    pub fn method(&self) -> &'static dyn Method {
        self.method
    }

    /// Synthesises the texture.
    pub fn run(&self) -> Result<Synthesis, Error> {
        let request = Request {
            sample: self.sample,
            width: self.width,
            height: self.height,
            params: &self.params,
            seed: self.seed,
            placement: self.placement,
            tileable: self.tileable,
            constraints: Default::default(),
        };
        self.method.synthesize(&request).map_err(|source| Error::Synthesis { method: self.method.name().into(), source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> RgbImage {
        RgbImage::from_fn(64, 64, |x, y| [(x * 4) as u8, (y * 4) as u8, ((x ^ y) * 4) as u8])
    }

    #[test]
    fn a_bad_value_gets_the_job_file_message_naming_the_parameter() {
        let s = sample();
        let err = Synthesizer::by_name("quilting", vec![params::int("block", 2)]).unwrap().build(&s).err().unwrap();
        let Error::Params { method, errors } = &err else { panic!("{err:?}") };
        assert_eq!((method.as_str(), errors[0].key.as_str()), ("quilting", "block"));
        assert!(errors[0].message.contains("out of range: allowed 3..=4096"), "{err}");
        // A method check needing the sample: a block larger than it.
        let err = Synthesizer::by_name("quilting", vec![params::int("block", 100)]).unwrap().build(&s).err().unwrap();
        assert!(err.to_string().contains("block 100 is larger than the sample (64x64)"), "{err}");
        let err = Synthesizer::by_name("quiltin", vec![]).unwrap_err();
        assert!(err.to_string().contains("unknown method `quiltin`"), "{err}");
    }

    #[test]
    fn the_same_request_gives_the_same_pixels_as_the_method_itself() {
        let s = sample();
        let session = Synthesizer::by_name("quilting", vec![params::int("block", 16)]).unwrap().seed(3).size(48, 40).build(&s).unwrap();
        let a = session.run().unwrap();
        assert_eq!(a.image.dimensions(), (48, 40));
        let m = methods::find("quilting").unwrap();
        let b = m
            .synthesize(&Request {
                sample: &s,
                width: 48,
                height: 40,
                params: session.params(),
                seed: 3,
                placement: false,
                tileable: false,
                constraints: Default::default(),
            })
            .unwrap();
        assert_eq!(a.image, b.image);
        assert_eq!(session.params().int("overlap").unwrap(), 3, "derived default filled in");
    }

    #[test]
    fn every_typed_config_names_a_registered_method() {
        use crate::*;
        let names = [
            QuiltingConfig::METHOD,
            DoubleSeamConfig::METHOD,
            PatchSamplingConfig::METHOD,
            CoevolutionConfig::METHOD,
            TesConfig::METHOD,
            WangTilesConfig::METHOD,
            RwTilesConfig::METHOD,
        ];
        assert_eq!(names.len(), methods::registry().len(), "one typed config per method");
        for name in names {
            assert!(methods::find(name).is_some(), "{name}");
        }
    }
}
