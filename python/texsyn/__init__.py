"""texsyn from Python: reproducible texture synthesis with NumPy arrays in and out.

Every function is a thin door onto the texsyn crate (the same code the ``texsyn`` command runs),
so a synthesis made here has the same pixels and pixel digest as a job file with the same method,
parameters, seed and size::

    import texsyn
    out = texsyn.synthesize("pebbles.png", "quilting", seed=7, size=(512, 512), block=40)
    res = texsyn.synthesize(sample_array, "patch-sampling", seed=1, full=True)
    res.image, res.placement["x"], res.warnings, res.record["outputs"][0]["pixel_digest"]

Long calls release the GIL. ``run`` stops cleanly on Ctrl-C (running jobs finish, the manifest is
written) and raises ``KeyboardInterrupt``.
"""

from ._texsyn import (
    ParamError,
    Synthesis,
    TexsynError,
    __version__,
    advise,
    diff,
    eval,
    methods,
    run,
    save,
    synthesize,
    verify,
)

__all__ = [
    "ParamError",
    "Synthesis",
    "TexsynError",
    "__version__",
    "advise",
    "diff",
    "eval",
    "methods",
    "run",
    "save",
    "synthesize",
    "verify",
]
