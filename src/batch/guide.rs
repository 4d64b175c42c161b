//! A guided job's guides, decoded and checked the same way for a run (`plan`) and a re-run from a
//! manifest (`verify`): the target has the output's size, the source the sample's.

use crate::batch::execute::LoadedSample;
use crate::synth::constraints::Guide;
use std::path::Path;

/// The guides of a job: the target image, and the sample's own guide when given.
pub struct GuideImages<'a> {
    pub target: (&'a Path, &'a LoadedSample),
    pub source: Option<(&'a Path, &'a LoadedSample)>,
    pub weight: f64,
    pub passes: u32,
}

impl GuideImages<'_> {
    /// What goes into the content key and the output spec: both guides' pixels (or that the
    /// source is the sample's luminance) and the weight.
    pub fn spec(&self) -> serde_json::Value {
        serde_json::json!({
            "target": { "pixels": self.target.1.pixel_digest },
            "source": match self.source {
                Some((_, l)) => serde_json::json!({ "pixels": l.pixel_digest }),
                None => serde_json::json!("luminance"),
            },
            "weight": self.weight,
            "passes": self.passes,
        })
    }

    /// The guide a method follows, checked against the sample (at `sample_path`) and the output
    /// size. `Err` is (the job-file key, the message).
    pub fn guide(&self, sample: &LoadedSample, sample_path: &Path, output: (u32, u32)) -> Result<Guide, (&'static str, String)> {
        let (tw, th) = self.target.1.image.dimensions();
        if (tw, th) != output {
            return Err((
                "guide.target",
                format!(
                    "target guide `{}` is {tw}x{th} but the output is {}x{}; the target guide must have the output's size",
                    self.target.0.display(),
                    output.0,
                    output.1
                ),
            ));
        }
        let (sw, sh) = sample.image.dimensions();
        let source = match self.source {
            Some((path, l)) => {
                if l.image.dimensions() != (sw, sh) {
                    return Err((
                        "guide.source",
                        format!(
                            "source guide `{}` is {}x{} but the sample `{}` is {sw}x{sh}; the source guide must have the sample's size",
                            path.display(),
                            l.image.width(),
                            l.image.height(),
                            sample_path.display()
                        ),
                    ));
                }
                &l.image
            }
            None => &sample.image,
        };
        Ok(Guide::from_images(&self.target.1.image, source, self.weight, self.passes, self.source.is_none()))
    }
}
