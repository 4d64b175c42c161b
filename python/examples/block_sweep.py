"""A notebook-style sweep: quilting one sample with several block sizes, side by side.

    pip install ./python          # from the repository root (once)
    python python/examples/block_sweep.py [SAMPLE] [OUT_DIR]

With matplotlib installed the results are shown in one figure (saved as sweep.png); without it,
each result is saved as a PNG. Every output is the same as a job file with the same values.
"""

import pathlib
import sys

import texsyn

repo = pathlib.Path(__file__).resolve().parents[2]
sample = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else repo / "jobs" / "samples" / "pebbles_beige.png"
out = pathlib.Path(sys.argv[2]) if len(sys.argv) > 2 else pathlib.Path("sweep_out")
out.mkdir(parents=True, exist_ok=True)

blocks = [20, 40, 60, 80]
results = {}
for block in blocks:
    r = texsyn.synthesize(sample, "quilting", seed=7, size=(384, 384), block=block, full=True)
    results[block] = r
    digest = r.record["outputs"][0]["pixel_digest"]["sha256"][:12]
    print(f"block {block:3}: {r.image.shape}, pixels {digest}, warnings: {r.warnings or 'none'}")

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    for block, r in results.items():
        texsyn.save(r.image, out / f"quilting_b{block}.png")
    print(f"matplotlib is not installed: wrote {len(results)} PNGs to {out}/")
else:
    fig, axes = plt.subplots(1, len(blocks), figsize=(4 * len(blocks), 4))
    for ax, (block, r) in zip(axes, results.items()):
        ax.imshow(r.image, cmap="gray" if r.image.ndim == 2 else None)
        ax.set_title(f"block = {block}")
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(out / "sweep.png", dpi=80)
    print(f"wrote {out / 'sweep.png'}")
