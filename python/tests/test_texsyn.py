"""The Python package against the CLI's own results: same pixels and digests for every method,
the job file's parameter messages, arrays in every precision, and the thin doors onto the crate."""

import hashlib
import json
import os
import pathlib
import subprocess
import sys
import threading

import numpy as np
import pytest

import texsyn

REPO = pathlib.Path(__file__).resolve().parents[2]
SAMPLES = REPO / "jobs" / "samples"
# One small job per method, on a sample each fits (as tests/it/materials.rs uses them).
CASES = [
    ("quilting", "crops/pebbles_beige_128.png", {}),
    ("double-seam", "crops/pebbles_beige_128.png", {"block": 32}),
    ("patch-sampling", "crops/hedge_leaves_128.png", {}),
    ("coevolution", "tiles_terracotta.png", {}),
    ("tes", "tiles_terracotta.png", {}),
    ("wang-tiles", "bricks_gray.png", {}),
    ("rw-tiles", "bricks_gray.png", {}),
]
SIZE = (200, 180)


def pixel_digest(a: np.ndarray) -> str:
    """texsyn's pixel digest of an array (README: the header, then the raw samples little-endian)."""
    h, w = a.shape[:2]
    c = 1 if a.ndim == 2 else a.shape[2]
    kind = {np.dtype(np.uint8): "u8", np.dtype(np.uint16): "u16le", np.dtype(np.float32): "f32le"}[a.dtype]
    header = f"texsyn-pixels/1 {w}x{h}x{c} {kind}\n".encode()
    return hashlib.sha256(header + np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<")).tobytes()).hexdigest()


def texsyn_cli() -> pathlib.Path:
    exe = REPO / "target" / "release" / "texsyn"
    if not exe.exists():
        subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=REPO, check=True)
    return exe


def write_jobs(d: pathlib.Path, threads_suffix: str = "") -> None:
    d.mkdir(parents=True, exist_ok=True)
    for method, sample, params in CASES:
        lines = [
            f'sample = "{SAMPLES / sample}"',
            f'method = "{method}"',
            "seed = 6",
            "[output]",
            f'path = "{method}.png"',
            f"width = {SIZE[0]}",
            f"height = {SIZE[1]}",
            "[params]",
        ] + [f"{k} = {v}" for k, v in params.items()]
        (d / f"{method}.toml").write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    """The CLI's run of one job per method, on two threads."""
    root = tmp_path_factory.mktemp("cli")
    write_jobs(root / "jobs")
    subprocess.run([str(texsyn_cli()), "run", str(root / "jobs"), "-o", str(root / "out"), "-q", "-j", "2"], check=True)
    manifest = json.loads((root / "out" / "manifest.json").read_text())
    return {j["id"]: j for j in manifest["jobs"]}


@pytest.mark.parametrize("method,sample,params", CASES, ids=[c[0] for c in CASES])
def test_every_method_gives_the_job_files_pixels_and_digest(cli_run, method, sample, params):
    record = cli_run[f"{method}.toml"]
    expected = record["outputs"][0]["pixel_digest"]["sha256"]
    out = texsyn.synthesize(SAMPLES / sample, method, seed=6, size=SIZE, **params)
    assert out.shape == (SIZE[1], SIZE[0], 3) and out.dtype == np.uint8
    assert pixel_digest(out) == expected
    # The one-off command, on the same values.
    one = pathlib.Path(os.environ.get("TMPDIR", "/tmp")) / f"texsyn-py-synth-{os.getpid()}" / f"{method}.png"
    sets = [a for k, v in params.items() for a in ("--set", f"{k}={v}")]
    size = f"{SIZE[0]}x{SIZE[1]}"
    subprocess.run([str(texsyn_cli()), "synth", str(SAMPLES / sample), "-o", str(one), "--method", method, "--seed", "6", "--size", size, *sets], check=True, capture_output=True)
    synth = json.loads(one.with_suffix(".manifest.json").read_text())
    assert synth["jobs"][0]["outputs"][0]["pixel_digest"]["sha256"] == expected
    full = texsyn.synthesize(str(SAMPLES / sample), method, seed=6, size=SIZE, full=True, **params)
    assert full.record["outputs"][0]["pixel_digest"]["sha256"] == expected
    assert full.record["params"] == record["params"], "the same resolved parameters"
    assert full.record["sample"]["pixel_digest"] == record["sample"]["pixel_digest"]
    np.testing.assert_array_equal(full.image, out)
    # The placement says where each pixel comes from: copied pixels are the sample's.
    x, y = full.placement["x"], full.placement["y"]
    assert x.shape == y.shape == (SIZE[1], SIZE[0])


def test_arrays_in_every_precision_give_the_sample_precision_back():
    rng = np.random.default_rng(5)
    base = rng.integers(0, 255, size=(64, 64, 3), dtype=np.uint8)
    for arr in [base, base[:, :, 0], (base.astype(np.uint16) * 257), base.astype(np.float32) / 255.0, np.dstack([base, base[:, :, :1]])]:
        out = texsyn.synthesize(arr, "quilting", seed=3, size=(96, 80), block=16)
        assert out.dtype == arr.dtype
        assert out.shape[:2] == (80, 96)
        assert out.ndim == arr.ndim and (arr.ndim == 2 or out.shape[2] == arr.shape[2])
        again = texsyn.synthesize(np.asfortranarray(arr), "quilting", seed=3, size=(96, 80), block=16)
        np.testing.assert_array_equal(out, again)
        full = texsyn.synthesize(arr, "quilting", seed=3, size=(96, 80), block=16, full=True)
        assert full.record["outputs"][0]["pixel_digest"]["sha256"] == pixel_digest(out)


def test_a_wrong_parameter_gets_the_job_files_message(tmp_path):
    with pytest.raises(texsyn.ParamError) as e:
        texsyn.synthesize(SAMPLES / "crops/pebbles_beige_128.png", "quilting", block=2)
    assert "`params.block`: 2 is out of range: allowed 3..=4096" in str(e.value)
    # The job file's message for the same value, from the CLI.
    (tmp_path / "j.toml").write_text(
        f'sample = "{SAMPLES / "crops/pebbles_beige_128.png"}"\nmethod = "quilting"\nseed = 1\n'
        '[output]\npath = "o.png"\nwidth = 64\nheight = 64\n[params]\nblock = 2\n'
    )
    cli = subprocess.run([str(texsyn_cli()), "run", str(tmp_path / "j.toml"), "-o", str(tmp_path / "out"), "-q"], capture_output=True, text=True)
    assert "`params.block`: 2 is out of range: allowed 3..=4096" in cli.stderr
    with pytest.raises(texsyn.ParamError, match="unknown key `blok`; did you mean `block`"):
        texsyn.synthesize(SAMPLES / "crops/pebbles_beige_128.png", "quilting", blok=30)
    with pytest.raises(texsyn.ParamError, match="expected a number, string or boolean"):
        texsyn.synthesize(SAMPLES / "crops/pebbles_beige_128.png", "quilting", block=[30])
    with pytest.raises(texsyn.ParamError, match="unknown method"):
        texsyn.synthesize(SAMPLES / "crops/pebbles_beige_128.png", "quiltin")
    with pytest.raises(ValueError, match="shape"):
        texsyn.synthesize(np.zeros((4, 4, 7), np.uint8))
    with pytest.raises(texsyn.TexsynError, match="missing.png"):
        texsyn.synthesize(tmp_path / "missing.png")


def test_run_verify_diff_and_progress(tmp_path):
    write_jobs(tmp_path / "jobs")
    events = []
    m1 = texsyn.run(tmp_path / "jobs", tmp_path / "out", jobs_parallel=1, progress=events.append)
    assert len(m1["jobs"]) == len(CASES) and all(j["status"] == "ok" for j in m1["jobs"])
    kinds = [e["event"] for e in events]
    assert kinds.count("planned") == 1 and kinds[-1] == "done" and kinds.count("finished") == len(CASES)
    assert kinds.index("planned") < kinds.index("started")
    m2 = texsyn.run([tmp_path / "jobs"], tmp_path / "out2", jobs_parallel=2)
    assert m1["deterministic_digest"] == m2["deterministic_digest"], "results never depend on the thread count"
    report = texsyn.verify(tmp_path / "out" / "manifest.json")
    assert report["ok"] and all(j["outcome"] == "verified" for j in report["jobs"].values())
    d = texsyn.diff(tmp_path / "out" / "manifest.json", tmp_path / "out2" / "manifest.json")
    assert d["pixels_changed"] == [] and d["unchanged"] == len(CASES)
    with pytest.raises(texsyn.TexsynError):
        texsyn.verify(tmp_path / "nothing.json")


def test_a_progress_callback_that_raises_stops_the_run_and_reraises(tmp_path):
    write_jobs(tmp_path / "jobs")

    def boom(event):
        if event["event"] == "finished":
            raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        texsyn.run(tmp_path / "jobs", tmp_path / "out", jobs_parallel=1, progress=boom)
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["run"]["in_progress"] is False and manifest["run"]["not_run"], "stopped like an interrupted run"


def test_ctrl_c_stops_a_run_cleanly_and_raises_keyboard_interrupt(tmp_path):
    write_jobs(tmp_path / "jobs")
    script = f"""
import os, signal, threading, time, texsyn
fired = []
def progress(e):
    if e["event"] == "started" and not fired:
        fired.append(1)
        threading.Timer(0.05, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        # Hold the run here until the signal has come: a loaded machine may start the timer's
        # thread only after the small jobs are all done.
        time.sleep(1.0)
try:
    texsyn.run({str(tmp_path / "jobs")!r}, {str(tmp_path / "out")!r}, jobs_parallel=1, progress=progress)
    print("NOT INTERRUPTED")
except KeyboardInterrupt:
    print("INTERRUPTED")
"""
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert "INTERRUPTED" in p.stdout and "NOT" not in p.stdout, p.stdout + p.stderr
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["run"]["in_progress"] is False


def test_the_gil_is_released_during_synthesis():
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(1)
            stop.wait(0.005)

    t = threading.Thread(target=tick)
    t.start()
    texsyn.synthesize(SAMPLES / "crops/pebbles_beige_128.png", "quilting", seed=1, size=(768, 768))
    stop.set()
    t.join()
    assert len(ticks) > 5, "another Python thread ran while texsyn worked"


def test_methods_advise_and_eval_are_the_librarys():
    names = [m["name"] for m in texsyn.methods()]
    assert names == [c[0] for c in CASES] or set(names) == {c[0] for c in CASES}
    q = next(m for m in texsyn.methods() if m["name"] == "quilting")
    assert any(p["name"] == "block" for p in q["params"])
    a = texsyn.advise(SAMPLES / "bricks_gray.png")
    assert {m["method"] for m in a["methods"]} == set(names) and "analysis" in a
    sample = SAMPLES / "crops/pebbles_beige_128.png"
    out = texsyn.synthesize(sample, "quilting", seed=2, size=(160, 160))
    scores = texsyn.eval(sample, out)
    assert set(scores) >= {"kl_gray", "kl_orientation", "verbatim"} and scores["seam_visibility"] is None
    cli = subprocess.run([str(texsyn_cli()), "advise", "--json", str(SAMPLES / "bricks_gray.png")], capture_output=True, text=True, check=True)
    assert json.loads(cli.stdout)["analysis"] == a["analysis"]


def test_one_thread_gives_the_same_pixels_as_all_of_them():
    code = (
        "import texsyn, hashlib, sys\n"
        f"a = texsyn.synthesize({str(SAMPLES / 'crops/hedge_leaves_128.png')!r}, 'patch-sampling', seed=4, size=(240, 200))\n"
        "sys.stdout.write(hashlib.sha256(a.tobytes()).hexdigest())\n"
    )
    one = subprocess.run([sys.executable, "-c", code], env={**os.environ, "RAYON_NUM_THREADS": "1"}, capture_output=True, text=True, check=True)
    here = texsyn.synthesize(SAMPLES / "crops/hedge_leaves_128.png", "patch-sampling", seed=4, size=(240, 200))
    assert one.stdout == hashlib.sha256(here.tobytes()).hexdigest()


GUIDED = SAMPLES / "guided"


def test_everyday_jobs_take_the_job_files_keys_as_arguments(tmp_path):
    """Several samples, augment, sample masks, inpainting and guides: the same pixels as the
    job file they stand for, arrays or paths alike, and the placement names sample and transform."""
    left, right = GUIDED / "gravel_gray_left.png", GUIDED / "gravel_gray_right.png"
    # Several samples (one as an array) with augment: the job file's pixels.
    job = tmp_path / "remix.toml"
    job.write_text(
        f'samples = ["{left}", "{right}"]\naugment = ["rot90", "flip_h"]\nmethod = "quilting"\nseed = 4\n'
        '[output]\npath = "remix.png"\nwidth = 120\nheight = 100\n[params]\nblock = 32\n'
    )
    subprocess.run([str(texsyn_cli()), "run", str(job), "-o", str(tmp_path / "out"), "-q"], check=True)
    expected = json.loads((tmp_path / "out" / "manifest.json").read_text())["jobs"][0]["outputs"][0]["pixel_digest"]["sha256"]
    res = texsyn.synthesize([left, right], "quilting", seed=4, size=(120, 100), augment=["rot90", "flip_h"], full=True, block=32)
    assert pixel_digest(res.image) == expected
    p = res.placement
    assert set(np.unique(p["sample"])) <= {0, 1} and set(np.unique(p["transform"])) <= {0, 1, 4}
    assert (p["sample"] == 1).any() and (p["transform"] > 0).any()
    # A sample mask per sample: no pixel comes from the top half of the right photo.
    mask = np.full((256, 128), 255, np.uint8)
    mask[:128] = 0
    res = texsyn.synthesize([str(left), str(right)], "quilting", seed=4, size=(120, 100), sample_mask=[None, mask], full=True, block=32)
    from_right = res.placement["sample"] == 1
    assert from_right.any() and (res.placement["y"][from_right] >= 128).all()
    # Inpainting: every known pixel stays; a channel or a mask image.
    image = GUIDED / "cork_cable.png"
    hole = GUIDED / "cork_cable_mask.png"
    out = texsyn.synthesize(image, "quilting", seed=2, inpaint=hole, block=32)
    original = texsyn.synthesize(image, "quilting", seed=2, inpaint=np.zeros((256, 256), np.uint8), block=32)  # nothing to fill
    box = np.zeros((256, 256), np.uint8)
    box[100:140, 60:180] = 255
    boxed = texsyn.synthesize(image, "quilting", seed=2, inpaint=box, block=32)
    np.testing.assert_array_equal(boxed[box == 0], original[box == 0])
    assert (boxed[box == 255] != original[box == 255]).any(axis=1).sum() > 1000, "the hole is filled"
    job = tmp_path / "heal.toml"
    job.write_text(f'method = "quilting"\nseed = 2\n[inpaint]\nimage = "{image}"\nmask = "{hole}"\n[output]\npath = "heal.png"\n[params]\nblock = 32\n')
    subprocess.run([str(texsyn_cli()), "run", str(job), "-o", str(tmp_path / "heal"), "-q"], check=True)
    heal = json.loads((tmp_path / "heal" / "manifest.json").read_text())["jobs"][0]["outputs"][0]["pixel_digest"]["sha256"]
    assert pixel_digest(out) == heal
    # Inpainting from another photo (and its mirror image): the job file's pixels; the placement
    # shows the known pixels as the image's own (sample 0) and the fill from the other (sample 1).
    gravel_hole = np.zeros((256, 128), np.uint8)
    gravel_hole[100:160, 30:100] = 255
    res = texsyn.synthesize(left, "quilting", seed=8, inpaint=gravel_hole, inpaint_from=[right], augment=["flip_h"], full=True, block=24)
    inside = gravel_hole == 255
    assert (res.placement["sample"][inside] == 1).all() and (res.placement["sample"][~inside] == 0).all()
    np.testing.assert_array_equal(res.image[~inside], np.asarray(texsyn.synthesize(left, "quilting", seed=8, inpaint=np.zeros((256, 128), np.uint8), block=24))[~inside])
    with pytest.raises(ValueError, match="inpaint_from goes with inpaint"):
        texsyn.synthesize(left, inpaint_from=[right])
    with pytest.raises(ValueError, match="pass the samples to copy from as inpaint_from"):
        texsyn.synthesize([left, right], inpaint=gravel_hole)
    # A guide: the output takes the target's size; weight and passes reach the job file.
    out = texsyn.synthesize(SAMPLES / "pebbles_beige.png", "quilting", seed=1, guide=GUIDED / "target_rings.png", guide_weight=0.7, guide_passes=1)
    header = (GUIDED / "target_rings.png").read_bytes()[16:24]
    assert out.shape[:2] == (int.from_bytes(header[4:], "big"), int.from_bytes(header[:4], "big"))
    # Mistakes get the job file's messages.
    with pytest.raises(texsyn.TexsynError, match="unknown transform `rot45`"):
        texsyn.synthesize(left, augment=["rot45"])
    with pytest.raises(texsyn.TexsynError, match="tes learns from one sample"):
        texsyn.synthesize([left, right], "tes")
    with pytest.raises(ValueError, match="go with guide"):
        texsyn.synthesize(left, guide_weight=0.3)
