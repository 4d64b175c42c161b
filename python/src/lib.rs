//! `texsyn._texsyn`: the Python door onto the texsyn crate.
//!
//! Every function here converts arguments, calls the library, and converts the answer back;
//! nothing is computed twice. Arrays are copied once on the way in (into the library's sample)
//! and handed to NumPy without a copy on the way out. Long calls release the GIL; `run` watches
//! for Ctrl-C and stops the run as the CLI does (running jobs finish, the manifest is written),
//! then raises `KeyboardInterrupt`.

use numpy::{IntoPyArray, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use texsyn::batch::execute::{LoadedSample, load_sample};
use texsyn::batch::single::{self, SingleRequest};
use texsyn::image::io::{NativeImage, Samples};
use texsyn::synth::params::ParamValue;

pyo3::create_exception!(_texsyn, TexsynError, PyRuntimeError, "texsyn could not do what was asked (the message says why).");
pyo3::create_exception!(
    _texsyn,
    ParamError,
    PyValueError,
    "A parameter is unknown, of the wrong type or out of range: the message a job file would get."
);

/// A library error as the Python exception a caller can catch: parameter problems as
/// `ParamError` (one line per parameter, as a job file lists them), the rest as `TexsynError`.
fn py_err(e: texsyn::Error) -> PyErr {
    match &e {
        texsyn::Error::Params { errors, .. } => {
            ParamError::new_err(errors.iter().map(|p| format!("`params.{}`: {}", p.key, p.message)).collect::<Vec<_>>().join("\n"))
        }
        texsyn::Error::UnknownMethod { .. } => ParamError::new_err(e.to_string()),
        _ => TexsynError::new_err(e.to_string()),
    }
}

fn json_to_py(py: Python<'_>, v: &serde_json::Value) -> PyResult<Py<PyAny>> {
    Ok(py.import("json")?.call_method1("loads", (v.to_string(),))?.unbind())
}

/// A sample given as a path (str or os.PathLike) or a NumPy array: uint8, uint16 or float32, of
/// shape (h, w) for gray or (h, w, c) with c = 1 (gray), 2 (gray + alpha), 3 (RGB), 4 (RGBA).
fn sample_from(arg: &Bound<'_, PyAny>, what: &str) -> PyResult<LoadedSample> {
    if let Ok(path) = arg.extract::<PathBuf>() {
        return load_sample(&path).map_err(py_err);
    }
    fn shape_of(shape: &[usize], what: &str) -> PyResult<(u32, u32, u32)> {
        let (h, w, c) = match *shape {
            [h, w] => (h, w, 1),
            [h, w, c] => (h, w, c),
            _ => return Err(PyValueError::new_err(format!("{what}: an image array has shape (h, w) or (h, w, c); got {shape:?}"))),
        };
        if !(1..=4).contains(&c) || w == 0 || h == 0 || w > u32::MAX as usize || h > u32::MAX as usize {
            return Err(PyValueError::new_err(format!(
                "{what}: shape {shape:?}: need at least 1x1 pixels and 1 to 4 channels (gray, gray + alpha, RGB, RGBA)"
            )));
        }
        Ok((w as u32, h as u32, c as u32))
    }
    macro_rules! try_dtype {
        ($t:ty, $variant:ident) => {
            if let Ok(a) = arg.extract::<PyReadonlyArrayDyn<'_, $t>>() {
                let (width, height, channels) = shape_of(a.shape(), what)?;
                // The one copy in: contiguous arrays as a block, others element by element in order.
                // (`as_slice` also accepts Fortran order, whose memory is not row-major.)
                let samples = match a.as_slice() {
                    Ok(s) if a.is_c_contiguous() => s.to_vec(),
                    _ => a.as_array().iter().copied().collect(),
                };
                return Ok(LoadedSample::from_native(NativeImage { width, height, channels, samples: Samples::$variant(samples) }));
            }
        };
    }
    try_dtype!(u8, U8);
    try_dtype!(u16, U16);
    try_dtype!(f32, F32);
    Err(PyValueError::new_err(format!(
        "{what}: expected a path or a NumPy array of uint8, uint16 or float32, got {}",
        arg.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into())
    )))
}

/// An image as a NumPy array of shape (h, w) for one channel, else (h, w, c); no copy.
fn image_to_py(py: Python<'_>, img: NativeImage) -> PyResult<Py<PyAny>> {
    let (h, w, c) = (img.height as usize, img.width as usize, img.channels as usize);
    macro_rules! shaped {
        ($v:expr) => {{
            let flat = $v.into_pyarray(py);
            if c == 1 { flat.reshape([h, w])?.into_any().unbind() } else { flat.reshape([h, w, c])?.into_any().unbind() }
        }};
    }
    Ok(match img.samples {
        Samples::U8(v) => shaped!(v),
        Samples::U16(v) => shaped!(v),
        Samples::F32(v) => shaped!(v),
    })
}

/// Python values as job-file parameter values (bool before int: a Python bool is an int).
fn params_from(params: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<(String, ParamValue)>> {
    let mut out = Vec::new();
    for (k, v) in params.into_iter().flat_map(|d| d.iter()) {
        let key: String = k.extract()?;
        let value = if let Ok(b) = v.cast::<pyo3::types::PyBool>() {
            ParamValue::Bool(b.is_true())
        } else if let Ok(i) = v.extract::<i64>() {
            ParamValue::Int(i)
        } else if let Ok(f) = v.extract::<f64>() {
            ParamValue::Float(f)
        } else if let Ok(s) = v.extract::<String>() {
            ParamValue::Str(s)
        } else {
            let found = v.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into());
            return Err(ParamError::new_err(format!("`params.{key}`: expected a number, string or boolean, found {found}")));
        };
        out.push((key, value));
    }
    Ok(out)
}

/// What `synthesize` asks of the library; `full` adds the placement, warnings and record.
fn request(
    method: &str,
    seed: u64,
    size: Option<(u32, u32)>,
    tileable: bool,
    full: bool,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<SingleRequest> {
    Ok(SingleRequest { method: method.to_string(), params: params_from(params)?, seed, size, tileable, placement: full, describe: full })
}

/// The result of `synthesize(..., full=True)`.
#[pyclass(module = "texsyn", frozen, get_all)]
struct Synthesis {
    /// The output, in the sample's channels and precision.
    image: Py<PyAny>,
    /// Where every output pixel comes from: a dict with `x` and `y` (int32 arrays of the output's
    /// shape, -1 where no sample pixel was copied) and `sample_size` (w, h).
    placement: Py<PyAny>,
    /// Plain sentences when the method and parameters do not fit the sample (`texsyn advise`).
    warnings: Vec<String>,
    /// The manifest entry of this synthesis as a dict, with its digests.
    record: Py<PyAny>,
}

#[pymethods]
impl Synthesis {
    fn __repr__(&self, py: Python<'_>) -> String {
        let shape = self.image.bind(py).getattr("shape").map(|s| s.to_string()).unwrap_or_default();
        format!("<texsyn.Synthesis image{shape} warnings={}>", self.warnings.len())
    }
}

fn placement_to_py(py: Python<'_>, p: &texsyn::synth::placement::Placement) -> PyResult<Py<PyAny>> {
    let (w, h) = p.dimensions();
    let (sw, _) = p.sample_size();
    let mut xs = Vec::with_capacity(p.sources().len());
    let mut ys = Vec::with_capacity(p.sources().len());
    for &s in p.sources() {
        let (x, y) = if s == texsyn::synth::placement::UNCOVERED { (-1, -1) } else { ((s % sw) as i32, (s / sw) as i32) };
        xs.push(x);
        ys.push(y);
    }
    let d = PyDict::new(py);
    d.set_item("x", xs.into_pyarray(py).reshape([h as usize, w as usize])?)?;
    d.set_item("y", ys.into_pyarray(py).reshape([h as usize, w as usize])?)?;
    d.set_item("sample_size", p.sample_size())?;
    Ok(d.into_any().unbind())
}

/// Makes a texture from `sample` (a path or a NumPy array) exactly as a job file with the same
/// method, parameters, seed and size would: the same pixels and pixel digest. Returns the output
/// array in the sample's channels and precision, or with `full=True` a `Synthesis` with the
/// placement, warnings and the manifest record. Parameters are the job file's `[params]` keys;
/// a wrong key, type or range raises `ParamError`.
///
/// The everyday jobs take keyword arguments named like the job file's keys: `sample` may be a
/// list (several samples), `augment` a list of transforms, `sample_mask` a mask (or a list, one
/// per sample, `None` for none), `inpaint` the mask of pixels to fill in `sample` (an image, white
/// = fill, or a channel name such as "a") with `inpaint_from` the samples the fill copies from
/// (default: `sample` itself), `guide` a target guide with `guide_source`,
/// `guide_weight` and `guide_passes`. These run through the job file they stand for (as
/// `texsyn synth` does), so they are validated with the same messages and give the same pixels.
#[pyfunction]
#[pyo3(signature = (
    sample, method="quilting", *, seed=0, size=None, tileable=false, full=false, augment=None, sample_mask=None,
    inpaint=None, inpaint_from=None, guide=None, guide_source=None, guide_weight=None, guide_passes=None, **params
))]
#[allow(clippy::too_many_arguments)]
fn synthesize(
    py: Python<'_>,
    sample: &Bound<'_, PyAny>,
    method: &str,
    seed: u64,
    size: Option<(u32, u32)>,
    tileable: bool,
    full: bool,
    augment: Option<Vec<String>>,
    sample_mask: Option<&Bound<'_, PyAny>>,
    inpaint: Option<&Bound<'_, PyAny>>,
    inpaint_from: Option<&Bound<'_, PyAny>>,
    guide: Option<&Bound<'_, PyAny>>,
    guide_source: Option<&Bound<'_, PyAny>>,
    guide_weight: Option<f64>,
    guide_passes: Option<u32>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let several = sample.cast::<pyo3::types::PyList>().is_ok() || sample.cast::<pyo3::types::PyTuple>().is_ok();
    if several || augment.is_some() || sample_mask.is_some() || inpaint.is_some() || guide.is_some() {
        let job = EverydayJob {
            method,
            seed,
            size,
            tileable,
            full,
            augment,
            sample_mask,
            inpaint,
            inpaint_from,
            guide,
            guide_source,
            guide_weight,
            guide_passes,
        };
        return job.run(py, sample, params);
    }
    if inpaint_from.is_some() {
        return Err(PyValueError::new_err("inpaint_from goes with inpaint=MASK"));
    }
    if guide_source.is_some() || guide_weight.is_some() || guide_passes.is_some() {
        return Err(PyValueError::new_err("guide_source, guide_weight and guide_passes go with guide=TARGET"));
    }
    let sample = sample_from(sample, "sample")?;
    let req = request(method, seed, size, tileable, full, params)?;
    let done = py.detach(|| single::synthesize(&sample, &req)).map_err(py_err)?;
    let image = image_to_py(py, done.image)?;
    if !full {
        return Ok(image);
    }
    let placement = match &done.synthesis.placement {
        Some(p) => placement_to_py(py, p)?,
        None => py.None(),
    };
    let result = Synthesis { image, placement, warnings: done.warnings, record: json_to_py(py, &done.record)? };
    Ok(Py::new(py, result)?.into_any())
}

/// A `synthesize` call with the everyday jobs' arguments: run as the job file it stands for.
struct EverydayJob<'a, 'py> {
    method: &'a str,
    seed: u64,
    size: Option<(u32, u32)>,
    tileable: bool,
    full: bool,
    augment: Option<Vec<String>>,
    sample_mask: Option<&'a Bound<'py, PyAny>>,
    inpaint: Option<&'a Bound<'py, PyAny>>,
    inpaint_from: Option<&'a Bound<'py, PyAny>>,
    guide: Option<&'a Bound<'py, PyAny>>,
    guide_source: Option<&'a Bound<'py, PyAny>>,
    guide_weight: Option<f64>,
    guide_passes: Option<u32>,
}

/// A scratch folder for one call's images and output, removed when dropped.
struct Scratch(PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl EverydayJob<'_, '_> {
    fn run(self, py: Python<'_>, sample: &Bound<'_, PyAny>, params: Option<&Bound<'_, PyDict>>) -> PyResult<Py<PyAny>> {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let dir = std::env::temp_dir().join(format!("texsyn-py-{}-{}", std::process::id(), NEXT.fetch_add(1, Ordering::Relaxed)));
        std::fs::create_dir_all(&dir).map_err(|e| TexsynError::new_err(format!("{}: cannot create: {e}", dir.display())))?;
        let scratch = Scratch(dir);
        let mut count = 0;
        // A path as it is (absolute), an array written as texsyn reads it back, bit for bit.
        let mut file = |arg: &Bound<'_, PyAny>, what: &str| -> PyResult<PathBuf> {
            if let Ok(path) = arg.extract::<PathBuf>() {
                return std::path::absolute(&path).map_err(|e| TexsynError::new_err(format!("{}: {e}", path.display())));
            }
            let loaded = sample_from(arg, what)?;
            let native = loaded.native_or_guide().into_owned();
            let (ext, bit_depth) = match native.samples {
                Samples::U8(_) => ("png", 8),
                Samples::U16(_) => ("png", 16),
                Samples::F32(_) => ("exr", 32),
            };
            count += 1;
            let path = scratch.0.join(format!("{count}-{}.{ext}", what.replace(|c: char| !c.is_ascii_alphanumeric(), "_")));
            let format = texsyn::image::io::Format::from_path(&path).expect("png or exr");
            let encoded = texsyn::image::io::encode_native(&native, texsyn::image::io::Encoding { format, bit_depth })
                .map_err(|source| py_err(texsyn::Error::Image { path: path.clone(), source }))?;
            std::fs::write(&path, &encoded.bytes).map_err(|e| TexsynError::new_err(format!("{}: {e}", path.display())))?;
            Ok(path)
        };
        fn list<'py>(arg: &Bound<'py, PyAny>) -> Option<Vec<Bound<'py, PyAny>>> {
            if arg.cast::<pyo3::types::PyList>().is_ok() || arg.cast::<pyo3::types::PyTuple>().is_ok() {
                arg.try_iter().ok()?.collect::<PyResult<Vec<_>>>().ok()
            } else {
                None
            }
        }
        let samples: Vec<PathBuf> = match list(sample) {
            Some(items) if items.is_empty() => return Err(PyValueError::new_err("sample: the list of samples is empty")),
            Some(items) => items.iter().enumerate().map(|(i, s)| file(s, &format!("sample {}", i + 1))).collect::<PyResult<_>>()?,
            None => vec![file(sample, "sample")?],
        };
        let sample_masks: Vec<Option<PathBuf>> = match self.sample_mask {
            None => Vec::new(),
            Some(m) => match list(m) {
                Some(items) => items
                    .iter()
                    .enumerate()
                    .map(|(i, m)| if m.is_none() { Ok(None) } else { file(m, &format!("sample_mask {}", i + 1)).map(Some) })
                    .collect::<PyResult<_>>()?,
                None => vec![Some(file(m, "sample_mask")?)],
            },
        };
        let inpaint = match self.inpaint {
            None => None,
            Some(m) => match m.extract::<String>() {
                Ok(c) if c.len() == 1 => Some(single::OneOffMask::Channel(c)),
                _ => Some(single::OneOffMask::File(file(m, "inpaint")?)),
            },
        };
        let inpaint_from: Vec<PathBuf> = match self.inpaint_from {
            None => Vec::new(),
            Some(_) if inpaint.is_none() => return Err(PyValueError::new_err("inpaint_from goes with inpaint=MASK")),
            Some(f) => match list(f) {
                Some(items) if items.is_empty() => return Err(PyValueError::new_err("inpaint_from: the list of samples is empty")),
                Some(items) => {
                    items.iter().enumerate().map(|(i, s)| file(s, &format!("inpaint_from {}", i + 1))).collect::<PyResult<_>>()?
                }
                None => vec![file(f, "inpaint_from")?],
            },
        };
        if inpaint.is_some() && samples.len() > 1 {
            return Err(PyValueError::new_err(
                "with inpaint, `sample` is the one image to repair; pass the samples to copy from as inpaint_from=[...]",
            ));
        }
        let guide = self.guide.map(|g| file(g, "guide")).transpose()?;
        let guide_source = self.guide_source.map(|g| file(g, "guide_source")).transpose()?;
        if guide.is_none() && (guide_source.is_some() || self.guide_weight.is_some() || self.guide_passes.is_some()) {
            return Err(PyValueError::new_err("guide_source, guide_weight and guide_passes go with guide=TARGET"));
        }
        let float = load_sample(&samples[0]).map_err(py_err)?.native.as_ref().is_some_and(|n| matches!(n.samples, Samples::F32(_)));
        let output = scratch.0.join(if float { "out.exr" } else { "out.png" });
        let size = match (self.size, &guide, &inpaint) {
            (Some(s), _, _) => Some(s),
            (None, Some(t), None) => Some(load_sample(t).map_err(py_err)?.image.dimensions()),
            _ => None,
        };
        let params = params_from(params)?.into_iter().map(|(k, v)| (k, single::OneOff::param_text(&v))).collect();
        let mut samples = samples.into_iter();
        let one = single::OneOff {
            sample: samples.next().expect("at least one sample"),
            more_samples: samples.collect(),
            augment: self.augment.unwrap_or_default(),
            sample_masks,
            inpaint,
            inpaint_from,
            guide,
            guide_source,
            guide_weight: self.guide_weight,
            guide_passes: self.guide_passes,
            source_map: self.full,
            output: output.clone(),
            method: self.method.to_string(),
            size,
            seed: self.seed,
            tileable: self.tileable,
            params,
            max_memory: None,
        };
        let done = py.detach(|| one.run()).map_err(|e| match e {
            // The job file is the call's own: its problems read as the arguments'.
            texsyn::Error::Usage(m) if m.contains("`params.") => ParamError::new_err(m),
            e => py_err(e),
        })?;
        let image = load_sample(&output).map_err(py_err)?.native_or_guide().into_owned();
        let image = image_to_py(py, image)?;
        if !self.full {
            return Ok(image);
        }
        let map_path = scratch.0.join("out.map.exr");
        let bytes = std::fs::read(&map_path).map_err(|e| TexsynError::new_err(format!("{}: {e}", map_path.display())))?;
        let map = texsyn::batch::source_map::decode_map(&bytes).map_err(TexsynError::new_err)?;
        let placement = match &map.atlas {
            None => placement_to_py(py, &map.placement)?,
            Some(atlas) => atlas_placement_to_py(py, &map.placement, atlas)?,
        };
        let record = serde_json::to_value(&done.record).map_err(|e| TexsynError::new_err(e.to_string()))?;
        let result = Synthesis { image, placement, warnings: done.record.warnings.clone(), record: json_to_py(py, &record)? };
        Ok(Py::new(py, result)?.into_any())
    }
}

/// A placement over several samples or turned copies: `x`, `y` in each pixel's own sample, and
/// `sample` (its index) and `transform` (0 as it is, 1 rot90, 2 rot180, 3 rot270, 4 flip_h,
/// 5 flip_v), each an int32 array of the output's shape (-1 where nothing was copied).
fn atlas_placement_to_py(
    py: Python<'_>,
    p: &texsyn::synth::placement::Placement,
    atlas: &texsyn::synth::atlas::Atlas,
) -> PyResult<Py<PyAny>> {
    let (w, h) = p.dimensions();
    let (sw, _) = p.sample_size();
    let n = p.sources().len();
    let (mut xs, mut ys, mut ss, mut ts) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    for &s in p.sources() {
        let found = (s != texsyn::synth::placement::UNCOVERED).then(|| atlas.locate(s % sw, s / sw)).flatten();
        let (x, y, i, t) = match found {
            Some((piece, (x, y))) => (x as i32, y as i32, piece.sample as i32, piece.transform.map_or(0, |t| t.code()) as i32),
            None => (-1, -1, -1, -1),
        };
        xs.push(x);
        ys.push(y);
        ss.push(i);
        ts.push(t);
    }
    let d = PyDict::new(py);
    for (name, v) in [("x", xs), ("y", ys), ("sample", ss), ("transform", ts)] {
        d.set_item(name, v.into_pyarray(py).reshape([h as usize, w as usize])?)?;
    }
    Ok(d.into_any().unbind())
}

/// For the overhead benchmark: the library's own seconds for the call (synthesis and rendering
/// of the output, no conversion), to compare with the whole Python call.
#[pyfunction]
#[pyo3(signature = (sample, method="quilting", *, seed=0, size=None, **params))]
fn _library_seconds(
    py: Python<'_>,
    sample: &Bound<'_, PyAny>,
    method: &str,
    seed: u64,
    size: Option<(u32, u32)>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<f64> {
    let sample = sample_from(sample, "sample")?;
    let req = request(method, seed, size, false, false, params)?;
    py.detach(|| {
        let t = std::time::Instant::now();
        single::synthesize(&sample, &req).map(|_| t.elapsed().as_secs_f64())
    })
    .map_err(py_err)
}

/// Sends a run's events to a Python callable as dicts; remembers the first exception it raises
/// and stops the run then.
struct Progress {
    callback: Option<Py<PyAny>>,
    failure: std::sync::Mutex<Option<PyErr>>,
    stop: Arc<AtomicBool>,
}

impl texsyn::Observer for Progress {
    fn event(&self, event: &texsyn::Event) {
        let Some(cb) = &self.callback else { return };
        use texsyn::Event as E;
        let v = match event {
            E::Invalid { id, errors } => {
                serde_json::json!({"event": "invalid", "id": id, "errors": errors.iter().map(|e| e.to_string()).collect::<Vec<_>>()})
            }
            E::Planned { to_run } => serde_json::json!({"event": "planned", "to_run": to_run}),
            E::Started { id } => serde_json::json!({"event": "started", "id": id}),
            E::Finished { record, seconds, .. } => serde_json::json!({
                "event": "finished", "id": record.id, "status": record.status.name(), "error": record.error, "seconds": seconds,
            }),
            E::Warning(w) => serde_json::json!({"event": "warning", "message": w}),
            E::Done { summary, manifest } => serde_json::json!({
                "event": "done", "ran": summary.ran, "up_to_date": summary.up_to_date, "failed": summary.failed,
                "invalid": summary.invalid, "interrupted": summary.interrupted, "manifest": manifest.display().to_string(),
            }),
        };
        Python::attach(|py| {
            let result = json_to_py(py, &v).and_then(|d| cb.call1(py, (d,)));
            if let Err(e) = result {
                let mut f = self.failure.lock().expect("progress");
                if f.is_none() {
                    *f = Some(e);
                }
                self.stop.store(true, Ordering::SeqCst);
            }
        });
    }
}

fn paths_from(arg: &Bound<'_, PyAny>) -> PyResult<Vec<PathBuf>> {
    if let Ok(p) = arg.extract::<PathBuf>() {
        return Ok(vec![p]);
    }
    arg.try_iter()?.map(|p| p?.extract::<PathBuf>()).collect()
}

fn memory_limit(max_memory: Option<&Bound<'_, PyAny>>) -> PyResult<Option<u64>> {
    match max_memory {
        None => Ok(texsyn::batch::memory::available()),
        Some(v) if v.is_none() => Ok(texsyn::batch::memory::available()),
        Some(v) => {
            if let Ok(n) = v.extract::<u64>() {
                return Ok(Some(n));
            }
            let s: String = v.extract()?;
            if s == "unlimited" {
                return Ok(None);
            }
            texsyn::batch::memory::parse_size(&s).map(Some).map_err(|e| PyValueError::new_err(format!("max_memory: {e}")))
        }
    }
}

/// Runs `work` on its own thread while this one, without the GIL, waits for it and checks for
/// Ctrl-C every 100 ms: on one it sets `stop` (the run finishes its running jobs and writes the
/// manifest, as the CLI does on SIGINT), waits, and raises `KeyboardInterrupt`.
fn interruptible<T: Send + 'static>(py: Python<'_>, stop: Arc<AtomicBool>, work: impl FnOnce() -> T + Send + 'static) -> PyResult<T> {
    // The answer and its arrival, shared with the worker (a Mutex and Condvar: both Sync, so this
    // thread can wait on them without the GIL).
    let slot = Arc::new((std::sync::Mutex::new(None::<T>), std::sync::Condvar::new()));
    let worker_slot = slot.clone();
    let handle = std::thread::spawn(move || {
        let value = work();
        *worker_slot.0.lock().expect("answer") = Some(value);
        worker_slot.1.notify_all();
    });
    let mut interrupted: Option<PyErr> = None;
    loop {
        let answer = py.detach(|| {
            let guard = slot.0.lock().expect("answer");
            let (mut guard, _) = slot.1.wait_timeout_while(guard, Duration::from_millis(100), |v| v.is_none()).expect("answer");
            guard.take()
        });
        if let Some(value) = answer {
            let _ = py.detach(move || handle.join());
            return match interrupted {
                Some(e) => Err(e),
                None => Ok(value),
            };
        }
        if handle.is_finished() && slot.0.lock().expect("answer").is_none() {
            return Err(TexsynError::new_err("the run's thread stopped without an answer (a panic inside texsyn)"));
        }
        if interrupted.is_none()
            && let Err(e) = py.check_signals()
        {
            stop.store(true, Ordering::SeqCst);
            interrupted = Some(e);
        }
    }
}

/// Runs job files and directories into `out`, as `texsyn run` does, and returns the manifest as
/// a dict. `jobs_parallel` is the number of worker threads (results never depend on it), `shard`
/// "I/N", `max_memory` bytes or "2G" / "unlimited" (default: the memory available). `progress`,
/// if given, is called with one dict per event (planned, started, finished, warning, invalid,
/// done). Ctrl-C stops the run like the CLI (running jobs finish, the manifest is written) and
/// raises KeyboardInterrupt.
#[pyfunction]
#[pyo3(signature = (jobs, out, *, jobs_parallel=None, force=false, shard=None, max_memory=None, progress=None))]
fn run(
    py: Python<'_>,
    jobs: &Bound<'_, PyAny>,
    out: PathBuf,
    jobs_parallel: Option<usize>,
    force: bool,
    shard: Option<String>,
    max_memory: Option<&Bound<'_, PyAny>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Py<PyAny>> {
    if jobs_parallel == Some(0) {
        return Err(PyValueError::new_err("jobs_parallel must be at least 1"));
    }
    let inputs = paths_from(jobs)?;
    let shard = shard.map(|s| texsyn::batch::shard::Shard::parse(&s)).transpose().map_err(py_err)?;
    let stop = Arc::new(AtomicBool::new(false));
    let mut opts = texsyn::RunOptions::new(&out);
    opts.threads = jobs_parallel;
    opts.force = force;
    opts.shard = shard;
    opts.max_memory = memory_limit(max_memory)?;
    opts.interrupt = Some(stop.clone());
    let observer = Arc::new(Progress { callback: progress, failure: std::sync::Mutex::new(None), stop: stop.clone() });
    let worker = observer.clone();
    interruptible(py, stop, move || texsyn::run(&inputs, &opts, &*worker))?.map_err(py_err)?;
    if let Some(e) = observer.failure.lock().expect("progress").take() {
        return Err(e);
    }
    let name = match shard {
        Some(s) => s.fragment_name(),
        None => texsyn::batch::manifest::FILE_NAME.to_string(),
    };
    let bytes = std::fs::read(out.join(&name)).map_err(|e| TexsynError::new_err(format!("{}: {e}", out.join(&name).display())))?;
    Ok(py.import("json")?.call_method1("loads", (String::from_utf8_lossy(&bytes).into_owned(),))?.unbind())
}

/// Re-runs every recorded job of a manifest and compares pixels, as `texsyn verify` does.
/// Returns {"ok": bool, "manifest_problems": [...], "jobs": {id: {"outcome": "verified" |
/// "skipped" | "mismatch" | "too-large", "problems": [...]}}}.
#[pyfunction]
#[pyo3(signature = (manifest, *, jobs_parallel=None, max_memory=None))]
fn verify(py: Python<'_>, manifest: PathBuf, jobs_parallel: Option<usize>, max_memory: Option<&Bound<'_, PyAny>>) -> PyResult<Py<PyAny>> {
    use texsyn::batch::verify::Outcome;
    let limit = memory_limit(max_memory)?;
    let report = py.detach(|| texsyn::batch::verify::verify_within(&manifest, jobs_parallel, limit)).map_err(py_err)?;
    let jobs: serde_json::Map<String, serde_json::Value> = report
        .jobs
        .iter()
        .map(|(id, o)| {
            let (outcome, problems) = match o {
                Outcome::Verified => ("verified", vec![]),
                Outcome::Skipped(w) => ("skipped", vec![w.clone()]),
                Outcome::Mismatch(p) => ("mismatch", p.clone()),
                Outcome::TooLarge(w) => ("too-large", vec![w.clone()]),
            };
            (id.clone(), serde_json::json!({"outcome": outcome, "problems": problems}))
        })
        .collect();
    json_to_py(py, &serde_json::json!({"ok": report.ok(), "manifest_problems": report.manifest_problems, "jobs": jobs}))
}

/// What changed between two manifests, as `texsyn diff --json` says it: jobs added, removed,
/// failing now or fixed, pixels changed (with the inputs that changed), times and metrics moved.
#[pyfunction]
fn diff(py: Python<'_>, old: PathBuf, new: PathBuf) -> PyResult<Py<PyAny>> {
    use texsyn::batch::manifest::Manifest;
    let (a, b) = (Manifest::load(&old).map_err(py_err)?, Manifest::load(&new).map_err(py_err)?);
    let d = py.detach(|| texsyn::batch::diff::diff(&a, &b, &Default::default()));
    json_to_py(py, &serde_json::to_value(&d).map_err(|e| TexsynError::new_err(e.to_string()))?)
}

/// The methods with their summaries, algorithm versions and parameters (name, kind, default,
/// doc), as `texsyn methods` lists them.
#[pyfunction]
fn methods(py: Python<'_>) -> PyResult<Py<PyAny>> {
    let list: Vec<serde_json::Value> = texsyn::synth::methods::registry()
        .iter()
        .map(|m| {
            let params: Vec<serde_json::Value> = m
                .params()
                .iter()
                .map(|p| serde_json::json!({"name": p.name, "kind": p.kind.describe(), "default": p.default.describe(), "doc": p.doc}))
                .collect();
            serde_json::json!({"name": m.name(), "summary": m.summary(), "algorithm_version": m.algorithm_version(), "params": params})
        })
        .collect();
    json_to_py(py, &serde_json::Value::Array(list))
}

/// What the sample is (lattice, orientation, stochastic) and how each method fits it with its
/// defaults, as `texsyn advise --json` says it.
#[pyfunction]
fn advise(py: Python<'_>, sample: &Bound<'_, PyAny>) -> PyResult<Py<PyAny>> {
    use texsyn::synth::{advice, methods, params};
    let loaded = sample_from(sample, "sample")?;
    let v = py.detach(|| {
        let a = advice::analyse(&loaded.image);
        let verdicts: Vec<serde_json::Value> = methods::registry()
            .iter()
            .filter_map(|m| {
                params::resolve(m.params(), &[]).ok().map(|d| serde_json::json!({"method": m.name(), "fit": advice::fit(&a, m.name(), &d)}))
            })
            .collect();
        serde_json::json!({"analysis": a, "methods": verdicts})
    });
    json_to_py(py, &v)
}

/// Scores `image` against `sample` (paths or arrays) with the metrics texsyn records (paper 003's
/// measures and the verbatim-copy fraction; seam visibility needs a method's grid and is None
/// here), as `texsyn eval` does. Returns {name: value or None}.
#[pyfunction]
#[pyo3(signature = (sample, image, metrics=None))]
fn eval(py: Python<'_>, sample: &Bound<'_, PyAny>, image: &Bound<'_, PyAny>, metrics: Option<Vec<String>>) -> PyResult<Py<PyAny>> {
    let (s, o) = (sample_from(sample, "sample")?, sample_from(image, "image")?);
    let names: Vec<String> = metrics.unwrap_or_else(|| texsyn::metrics::METRIC_NAMES.iter().map(|s| s.to_string()).collect());
    let values = py
        .detach(|| {
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            texsyn::metrics::evaluate(&names, &s.image, &o.image, None)
        })
        .map_err(|e| ParamError::new_err(e.to_string()))?;
    json_to_py(py, &serde_json::to_value(values).map_err(|e| TexsynError::new_err(e.to_string()))?)
}

/// Writes an array as texsyn writes outputs (atomically): PNG (8-bit for uint8, 16-bit for
/// uint16 and float32, which is scaled to 0..65535) or EXR (32-bit float), by the extension.
#[pyfunction]
fn save(py: Python<'_>, image: &Bound<'_, PyAny>, path: PathBuf) -> PyResult<()> {
    use texsyn::image::io::{Encoding, Format};
    let loaded = sample_from(image, "image")?;
    let native = loaded.native_or_guide().into_owned();
    let format =
        Format::from_path(&path).ok_or_else(|| PyValueError::new_err(format!("{}: the file must end in .png or .exr", path.display())))?;
    let bit_depth = match (format, &native.samples) {
        (Format::Exr, _) => 32,
        (Format::Png, Samples::U8(_)) => 8,
        (Format::Png, _) => 16,
    };
    py.detach(|| {
        let encoded = texsyn::image::io::encode_native(&native, Encoding { format, bit_depth })
            .map_err(|source| texsyn::Error::Image { path: path.clone(), source })?;
        texsyn::batch::outdir::write_atomic(&path, &encoded.bytes)
    })
    .map_err(py_err)
}

#[pymodule]
fn _texsyn(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("TexsynError", py.get_type::<TexsynError>())?;
    m.add("ParamError", py.get_type::<ParamError>())?;
    m.add_class::<Synthesis>()?;
    m.add_function(wrap_pyfunction!(synthesize, m)?)?;
    m.add_function(wrap_pyfunction!(_library_seconds, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(verify, m)?)?;
    m.add_function(wrap_pyfunction!(diff, m)?)?;
    m.add_function(wrap_pyfunction!(methods, m)?)?;
    m.add_function(wrap_pyfunction!(advise, m)?)?;
    m.add_function(wrap_pyfunction!(eval, m)?)?;
    m.add_function(wrap_pyfunction!(save, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
