//! Several samples and turned copies against Embark (issue #28), part of the peers bench:
//!
//!     cargo bench --bench peers -- samples     # only this part
//!
//! Two cases, one thread, 256² outputs, whole processes: the two photos of one gravel bed
//! (`jobs/samples/guided/gravel_gray_{left,right}.png`), texsyn `samples = [...]` against Embark
//! `generate left right`; and one sample with its turned and mirrored copies, texsyn
//! `augment = [all five]` against Embark `flip-and-rotate` (its seven copies). texsyn runs
//! quilting with its defaults. Quality: paper 003's four measures of each output against the
//! first sample (lower is better), with ratios texsyn / Embark.

use super::inpaint::measures;
use std::path::{Path, PathBuf};
use std::process::Command;

const SIZE: u32 = 256;

pub fn run(work: &Path, embark: Option<&Path>, reps: usize, time: &dyn Fn(usize, &mut dyn FnMut() -> Command) -> Option<f64>) {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let guided = repo.join("jobs/samples/guided");
    println!("\nseveral samples and turned copies, {SIZE}² outputs, one thread; quality: paper 003's measures against the first sample");
    println!("(lower is better), ratios texsyn / Embark (< 1: texsyn closer)\n");
    println!(
        "{:<28} {:>9} {:>9} {:>8}   {:>20} {:>20} {:>20} {:>20}",
        "case", "texsyn s", "Embark s", "speed", "kl_gray t/E", "kl_orient t/E", "acf_gray t/E", "acf_orient t/E"
    );
    let two = [guided.join("gravel_gray_left.png"), guided.join("gravel_gray_right.png")];
    let cases: Vec<(String, Vec<PathBuf>, &str, &str)> = vec![
        ("two photos (gravel)".into(), two.to_vec(), "", "generate"),
        (
            "pebbles + 5 copies".into(),
            vec![repo.join("jobs/samples/pebbles_beige.png")],
            "augment = [\"rot90\", \"rot180\", \"rot270\", \"flip_h\", \"flip_v\"]\n",
            "flip-and-rotate",
        ),
        (
            "cork + 5 copies".into(),
            vec![repo.join("jobs/samples/cork.png")],
            "augment = [\"rot90\", \"rot180\", \"rot270\", \"flip_h\", \"flip_v\"]\n",
            "flip-and-rotate",
        ),
    ];
    for (k, (name, samples, augment, subcommand)) in cases.iter().enumerate() {
        let dir = work.join(format!("samples-{k}"));
        let jobs = dir.join("jobs");
        std::fs::create_dir_all(&jobs).expect("bench dir");
        let list: Vec<String> = samples.iter().map(|p| format!("\"{}\"", p.display())).collect();
        std::fs::write(
            jobs.join("s.toml"),
            format!(
                "samples = [{}]\n{augment}method = \"quilting\"\nseed = 3\n[output]\npath = \"s.png\"\nwidth = {SIZE}\nheight = {SIZE}\n",
                list.join(", ")
            ),
        )
        .expect("job file");
        let tt = time(reps, &mut || {
            let mut c = Command::new(env!("CARGO_BIN_EXE_texsyn"));
            c.arg("run").arg(&jobs).arg("-o").arg(dir.join("out")).args(["-j", "1", "-q", "--force"]);
            c
        });
        let embark_out = dir.join("embark.png");
        let et = embark.and_then(|e| {
            time(reps, &mut || {
                let mut c = Command::new(e);
                c.args(["--no-progress", "--threads", "1", "--seed", "3", "--out-size", &format!("{SIZE}x{SIZE}"), "-o"])
                    .arg(&embark_out)
                    .arg(subcommand)
                    .args(samples);
                c
            })
        });
        let Some(tt) = tt else {
            println!("{name:<28} texsyn failed");
            continue;
        };
        let first = texsyn::load_image(&samples[0]).expect("sample");
        let ours = measures(&first, &texsyn::load_image(dir.join("out/s.png")).expect("texsyn output"));
        let theirs = et.and_then(|_| texsyn::load_image(&embark_out).ok()).map(|img| measures(&first, &img));
        let cell = |i: usize| match theirs {
            Some(t) => format!("{:.3}/{:.3} {:>5.2}", ours[i], t[i], ours[i] / t[i]),
            None => format!("{:.3}/—", ours[i]),
        };
        let speed = et.map(|e| format!("{:.1}×", e / tt)).unwrap_or_else(|| "—".into());
        let ets = et.map(|e| format!("{e:.3}")).unwrap_or_else(|| "—".into());
        println!("{name:<28} {tt:>9.3} {ets:>9} {speed:>8}   {:>20} {:>20} {:>20} {:>20}", cell(0), cell(1), cell(2), cell(3));
    }
}
