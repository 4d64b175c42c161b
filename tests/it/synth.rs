//! `texsyn synth`: a one-off from one sample is the job file its flags stand for — the same
//! messages, the same pixels, a manifest that verifies, and `--print-job` that joins a directory.

use crate::common::*;

#[test]
fn a_one_off_is_the_job_file_it_prints() {
    let d = scratch("synth");
    let sample = repo().join("jobs/samples/crops/pebbles_beige_128.png");
    let args = |out: &Path| -> Vec<String> {
        [
            sample.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--method",
            "double-seam",
            "--size",
            "200x180",
            "--seed",
            "6",
            "--set",
            "block=32",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let one = d.join("one/ds.png");
    let said = text(&run_ok(texsyn().arg("synth").args(args(&one))));
    assert!(said.contains("200x180 double-seam"), "{said}");
    let manifest = d.join("one/ds.manifest.json");
    run_ok(texsyn().arg("verify").arg(&manifest));
    // The printed job file, run as part of a directory, gives the same pixels.
    let printed = run_ok(texsyn().arg("synth").args(args(&d.join("ds.png"))).arg("--print-job"));
    std::fs::create_dir_all(d.join("jobs")).unwrap();
    std::fs::write(d.join("jobs/ds.toml"), &printed.stdout).unwrap();
    run_ok(texsyn().args(["run", "-q", "-o"]).arg(d.join("out")).arg(d.join("jobs")));
    let job = json(&d.join("out/manifest.json"));
    let synth = json(&manifest);
    assert_eq!(synth["jobs"][0]["outputs"][0]["pixel_digest"], job["jobs"][0]["outputs"][0]["pixel_digest"]);
    assert_eq!(synth["jobs"][0]["params"], job["jobs"][0]["params"]);
    // Mistakes get the job file's messages, named by key; nothing is written.
    let bad = run_expect(
        texsyn().arg("synth").arg(&sample).args(["-o"]).arg(d.join("bad/b.png")).args(["--set", "block=2", "--set", "cutt=dp"]),
        2,
    );
    let said = text(&bad);
    assert!(said.contains("`params.block`: 2 is out of range: allowed 3..=4096"), "{said}");
    assert!(said.contains("`params.cutt`: unknown key `cutt`; did you mean `cut`?"), "{said}");
    assert!(!d.join("bad/b.png").exists());
    let bad = run_expect(texsyn().arg("synth").arg(&sample).args(["-o", "x.txt"]), 2);
    assert!(text(&bad).contains(".png or .exr"), "{}", text(&bad));
}
