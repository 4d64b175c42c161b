//! How much memory a job needs, and the limit a run keeps to (`texsyn run --max-memory`).
//!
//! Why this exists: a job's memory grows with its output (an 8192² fill holds 200 MB of pixels
//! before anything else), and a run starts as many jobs as it has threads. Without a model, a large
//! job, or several medium ones at once, ends in the kernel's OOM killer, which takes the whole run
//! (and its manifest) with it. With one, a job that cannot fit is refused at validation with its
//! estimate and the limit, and the scheduler never starts jobs whose estimates together exceed
//! the limit. Results never depend on either: only when a job starts does.
//!
//! A job's estimate is [`Method::peak_memory`] (the method's own working set, output image
//! included; stated by each method from measurements) plus what the runner holds around it: the
//! process itself and a share per thread of the pool, the decoded sample, the encoder's buffers, the plan's analysis of the sample
//! (the advice, [`crate::synth::advice::peak_memory`]) and, if the job asks for metrics, their
//! analysis of the output. Large tile fills are rendered and written strip by strip
//! ([`crate::batch::execute::renders_in_strips`]); their estimate is the method's working set
//! without the image ([`Method::strip_peak_memory`]). `tests/it/memory.rs` checks the estimates
//! against the peak RSS of real runs, for every method.

use crate::batch::execute::renders_in_strips;
use crate::batch::job::OutputSpec;
use crate::image::io::Format;
use crate::synth::method::Method;
use crate::synth::params::Params;
use std::sync::{Condvar, Mutex};
use std::time::Duration;

pub const KIB: u64 = 1 << 10;
pub const MIB: u64 = 1 << 20;
pub const GIB: u64 = 1 << 30;

/// What the process holds whatever it runs: code, the allocator's arenas, thread stacks, the plan.
/// Measured: `texsyn run` of a 64² job peaks at about 12 MB (VmHWM); rounded up.
pub const PROCESS_BYTES: u64 = 24 * MIB;

/// The process and, for every thread of the current rayon pool (the run's `-j`, which a job's
/// method uses), what the method adds per thread ([`Method::thread_memory`]).
fn process_bytes(method: &dyn Method, params: &Params, sample: (u32, u32)) -> u64 {
    PROCESS_BYTES + method.thread_memory(params, sample) * rayon::current_num_threads() as u64
}

/// The peak memory of one job, in bytes: the runner's share plus the method's.
///
/// The peak is whichever phase is largest: the plan's analysis of the sample (the advice: a 12 MP
/// photo's is larger than its 1024² quilting), synthesis (the method's working set), encoding (the
/// output image plus the encoder's buffers) or metrics (the output plus their analyses); the
/// decoded sample and the process itself are there throughout.
pub fn job_estimate(method: &dyn Method, params: &Params, sample: (u32, u32), output: &OutputSpec, metrics: bool) -> u64 {
    job_estimate_with(method, params, sample, output, metrics, None)
}

/// What a job renders from its placement ([`job_estimate_with`]): companions, a source map, a
/// main output rendered from a sample that is not 8-bit RGB.
#[derive(Clone, Copy, Debug)]
pub struct Materials {
    pub companions: usize,
    pub source_map: bool,
}

/// [`job_estimate`] of a job that also renders from its placement: the placement (a source per
/// pixel, blend chains where the method feathers: at most 20 B per output pixel), one rendering at
/// a time in the widest precision (float RGBA, 16 B per pixel, twice while it is converted and
/// encoded) and the source map's integer channels (two, plus four per blend step; about 40 B per pixel in all).
/// Such a job is never rendered in strips.
pub fn job_estimate_with(
    method: &dyn Method,
    params: &Params,
    sample: (u32, u32),
    output: &OutputSpec,
    metrics: bool,
    materials: Option<Materials>,
) -> u64 {
    let out_px = u64::from(output.width) * u64::from(output.height);
    let raw = out_px * 3;
    let sample_bytes = u64::from(sample.0) * u64::from(sample.1) * 3;
    if let Some(m) = materials {
        let rendering = if m.companions > 0 || output.format == Format::Exr || output.bit_depth == 16 { 32 * out_px } else { 0 };
        let map = if m.source_map { 40 * out_px } else { 0 };
        // Companion samples are decoded like the sample (at most float RGBA each).
        let companions = m.companions as u64 * u64::from(sample.0) * u64::from(sample.1) * 16;
        return job_estimate_with(method, params, sample, output, metrics, None).max(
            process_bytes(method, params, sample) + 2 * sample_bytes + method.peak_memory(params, sample, (output.width, output.height)),
        ) + 20 * out_px
            + rendering.max(map)
            + companions;
    }
    if renders_in_strips(method, output, metrics) {
        // One strip at a time (counted by the method) and the PNG compressor's window and buffer.
        let strips = method.strip_peak_memory(params, sample, (output.width, output.height)) + 4 * MIB;
        return process_bytes(method, params, sample) + 2 * sample_bytes + strips.max(analysis_estimate(sample));
    }
    let synthesis = method.peak_memory(params, sample, (output.width, output.height));
    // 8-bit PNG is compressed strip by strip beside the image (a strip, the compressor's window
    // and a 1 MiB chunk); 16-bit PNG first widens the samples (twice, native and big-endian) and
    // keeps the whole compressed stream (at worst the raw rows plus a little); EXR holds the
    // linear floats plus its own compressed blocks.
    let encoding = match (output.format, output.bit_depth) {
        (Format::Png, 8) => raw + 4 * MIB,
        (Format::Png, _) => raw + 4 * raw + 2 * raw + raw / 32,
        (Format::Exr, _) => raw + 4 * raw + 4 * raw + raw / 8,
    };
    // The metrics' analyses of the output (gray levels, gradients, orientation histograms and
    // FFT autocorrelations in f64): measured at about 90 bytes per output pixel.
    let metrics_bytes = if metrics { raw + 96 * out_px } else { 0 };
    process_bytes(method, params, sample) + 2 * sample_bytes + analysis_estimate(sample).max(synthesis).max(encoding).max(metrics_bytes)
}

/// The plan's analysis of a sample of `size` ([`crate::synth::advice::peak_memory`]), which every
/// job that runs has (an inpainting job's is of a part of its image, so no larger).
pub fn analysis_estimate(size: (u32, u32)) -> u64 {
    crate::synth::advice::peak_memory(size)
}

/// A size as people write it: plain bytes (`1048576`), or a number with a unit, `K`, `M`, `G`, `T`
/// (powers of 1024, also written `KiB`, `MB`, `GiB`, …; case does not matter), e.g. `2G`, `512M`,
/// `1.5GiB`.
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let bad = || format!("`{text}` is not a size; write bytes or a number with K, M, G or T (powers of 1024), e.g. 2G, 512M, 1.5GiB");
    let value: f64 = number.parse().map_err(|_| bad())?;
    let scale = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kb" | "kib" => KIB,
        "m" | "mb" | "mib" => MIB,
        "g" | "gb" | "gib" => GIB,
        "t" | "tb" | "tib" => 1 << 40,
        _ => return Err(bad()),
    };
    let bytes = value * scale as f64;
    if !bytes.is_finite() || bytes < 1.0 || bytes > u64::MAX as f64 {
        return Err(format!("`{text}` is not a usable memory limit (at least 1 byte)"));
    }
    Ok(bytes.round() as u64)
}

/// A size for people: `512 B`, `3.0 MiB`, `38.6 GiB`.
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if bytes >= GIB {
        format!("{:.1} GiB", b / GIB as f64)
    } else if bytes >= MIB {
        format!("{:.1} MiB", b / MIB as f64)
    } else if bytes >= KIB {
        format!("{:.1} KiB", b / KIB as f64)
    } else {
        format!("{bytes} B")
    }
}

/// The memory the kernel says is available for new work (`MemAvailable` in `/proc/meminfo`), or
/// `None` where that cannot be read (not Linux): then no limit is applied unless one is given.
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    meminfo_field(&text, "MemAvailable:")
}

/// Gives the memory of freed blocks back to the system, from every thread's arena of the
/// allocator (glibc's `malloc_trim`; elsewhere nothing).
///
/// Why: the estimates count the bytes a job holds, and freed bytes count only if the next
/// allocation cannot reuse them. glibc keeps one arena per thread, and a thread reuses only its
/// own: a 12 MP photo's analysis at planning left its transforms (about 100 MB) in two threads'
/// arenas, and a 1024² quilting of it on 16 threads peaked at 269–278 MiB against an estimate
/// of 229 MiB (its live heap: 146 MiB); trimmed after the plan, and with `main`'s trim threshold
/// of 32 MiB, 192 MiB. A run calls it once, after planning: after every job it cost 4 s on the
/// bundled 476 jobs (25 s).
pub fn release_freed() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[allow(unsafe_code)]
    // SAFETY: `malloc_trim` only returns free pages to the system, taking each arena's lock.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// The peak resident set size of this process so far (`VmHWM` in `/proc/self/status`), where
/// the platform reports it.
pub fn peak_rss() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    meminfo_field(&text, "VmHWM:")
}

/// A `Name:   1234 kB` line's value in bytes.
fn meminfo_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let mut parts = line[name.len()..].split_whitespace();
    let value: u64 = parts.next()?.parse().ok()?;
    let scale = match parts.next() {
        Some("kB") => KIB,
        None => 1,
        Some(_) => return None,
    };
    Some(value * scale)
}

/// The message of a job that cannot fit under the limit.
pub fn too_large(estimate: u64, limit: u64) -> String {
    format!(
        "needs about {} (estimated peak memory) but --max-memory is {}; make the output smaller or raise --max-memory",
        human(estimate),
        human(limit)
    )
}

/// The scheduler's memory budget: jobs take their estimate before they start and give it back when
/// they finish, so the estimates of the jobs running at once never add up to more than the limit.
/// Only *when* a job starts depends on it, never what it computes.
pub struct Budget {
    limit: u64,
    used: Mutex<u64>,
    freed: Condvar,
}

impl Budget {
    /// A budget of `limit` bytes (`None`: no limit).
    pub fn new(limit: Option<u64>) -> Budget {
        Budget { limit: limit.unwrap_or(u64::MAX), used: Mutex::new(0), freed: Condvar::new() }
    }

    /// Takes `bytes` (at most the whole limit), waiting until it fits; dropping the reservation
    /// gives it back (also when a job panics). While waiting on a rayon worker it runs other work
    /// queued there, so a pool of one thread still makes progress.
    pub fn acquire(&self, bytes: u64) -> Reservation<'_> {
        let bytes = bytes.min(self.limit);
        loop {
            if self.try_take(bytes) {
                return Reservation { budget: self, bytes };
            }
            if rayon::current_thread_index().is_some() && matches!(rayon::yield_now(), Some(rayon::Yield::Executed)) {
                continue;
            }
            let used = self.used.lock().expect("memory budget");
            if self.limit - *used >= bytes {
                continue;
            }
            let _ = self.freed.wait_timeout(used, Duration::from_millis(20)).expect("memory budget");
        }
    }

    fn try_take(&self, bytes: u64) -> bool {
        let mut used = self.used.lock().expect("memory budget");
        if self.limit - *used >= bytes {
            *used += bytes;
            true
        } else {
            false
        }
    }

    fn release(&self, bytes: u64) {
        let mut used = self.used.lock().unwrap_or_else(|e| e.into_inner());
        *used -= bytes;
        self.freed.notify_all();
    }
}

/// Bytes taken from a [`Budget`], given back when dropped.
pub struct Reservation<'a> {
    budget: &'a Budget,
    bytes: u64,
}

impl Reservation<'_> {
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

impl Drop for Reservation<'_> {
    fn drop(&mut self) {
        self.budget.release(self.bytes);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_in_the_usual_spellings() {
        assert_eq!(parse_size("1048576"), Ok(MIB));
        assert_eq!(parse_size("2G"), Ok(2 * GIB));
        assert_eq!(parse_size("512M"), Ok(512 * MIB));
        assert_eq!(parse_size("512mb"), Ok(512 * MIB));
        assert_eq!(parse_size("1.5GiB"), Ok(3 * GIB / 2));
        assert_eq!(parse_size("64 KiB"), Ok(64 * KIB));
        for bad in ["", "G", "2X", "-1G", "1.2.3M", "0", "two"] {
            let e = parse_size(bad).unwrap_err();
            assert!(e.contains(bad), "{bad}: {e}");
        }
    }

    #[test]
    fn proc_fields_read_in_bytes() {
        let status = "Name:\ttexsyn\nVmPeak:\t  100 kB\nVmHWM:\t   2048 kB\n";
        assert_eq!(meminfo_field(status, "VmHWM:"), Some(2 * MIB));
        assert_eq!(meminfo_field(status, "VmRSS:"), None);
        assert_eq!(human(38 * GIB + 600 * MIB), "38.6 GiB");
        assert_eq!(human(3 * MIB), "3.0 MiB");
    }

    #[test]
    fn the_budget_never_hands_out_more_than_the_limit() {
        let b = Budget::new(Some(100));
        let first = b.acquire(60);
        assert_eq!(first.bytes(), 60);
        assert!(!b.try_take(50));
        assert!(b.try_take(40));
        b.release(40);
        drop(first);
        let whole = b.acquire(1000);
        assert_eq!(whole.bytes(), 100, "a job larger than the limit takes the whole limit");
        assert!(!b.try_take(1));
        drop(whole);
        let waited = std::thread::scope(|s| {
            let big = b.acquire(70);
            let t = s.spawn(|| b.acquire(50).bytes());
            std::thread::sleep(Duration::from_millis(50));
            drop(big);
            t.join().unwrap()
        });
        assert_eq!(waited, 50);
        assert!(b.try_take(100), "everything was given back");
    }
}
