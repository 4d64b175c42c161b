"""What the Python door costs over the Rust library call, measured in one run.

    python python/benches/overhead.py [SIZE] [REPEATS]

For a SIZE² quilting synthesis (default 4096) from a NumPy sample, it times the whole Python call
(`texsyn.synthesize`: the array copied in, the library call, the output handed to NumPy) against
the library's own seconds for the same call (`texsyn._texsyn._library_seconds`, measured inside
Rust around the same library function), taking the minimum of REPEATS runs of each, interleaved.
It prints both and their ratio; the issue's bar is a few percent.
"""

import sys
import time

import numpy as np

import texsyn
from texsyn import _texsyn

size = int(sys.argv[1]) if len(sys.argv) > 1 else 4096
repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
rng = np.random.default_rng(1)
sample = (rng.random((256, 256, 3)) * 255).astype(np.uint8)

python_s, library_s = [], []
for _ in range(repeats):
    t = time.perf_counter()
    out = texsyn.synthesize(sample, "quilting", seed=1, size=(size, size))
    python_s.append(time.perf_counter() - t)
    library_s.append(_texsyn._library_seconds(sample, "quilting", seed=1, size=(size, size)))
assert out.shape == (size, size, 3)
p, lib = min(python_s), min(library_s)
print(f"quilting {size}x{size} from a 256x256 array, min of {repeats}:")
print(f"  library call          {lib:8.3f} s")
print(f"  Python call           {p:8.3f} s")
print(f"  overhead              {100 * (p / lib - 1):+7.2f} %")
