"""Type stubs of texsyn's native module (see texsyn/__init__.py for the overview)."""

import os
from typing import Any, Callable, Dict, List, Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

PathLike = Union[str, "os.PathLike[str]"]
Image = Union[npt.NDArray[np.uint8], npt.NDArray[np.uint16], npt.NDArray[np.float32]]
Sample = Union[PathLike, Image]
Param = Union[int, float, bool, str]

class TexsynError(RuntimeError):
    """texsyn could not do what was asked (the message says why)."""

class ParamError(ValueError):
    """A parameter is unknown, of the wrong type or out of range: the message a job file would get."""

class Synthesis:
    """The result of ``synthesize(..., full=True)``."""

    image: Image
    """The output, in the sample's channels and precision."""
    placement: Optional[Dict[str, Any]]
    """``x``, ``y``: int32 arrays of the output's shape (-1 where nothing was copied); ``sample_size``: (w, h)."""
    warnings: List[str]
    """Plain sentences when the method and parameters do not fit the sample (``texsyn advise``)."""
    record: Dict[str, Any]
    """The manifest entry of this synthesis, with its digests."""

@overload
def synthesize(
    sample: Union[Sample, Sequence[Sample]],
    method: str = "quilting",
    *,
    seed: int = 0,
    size: Optional[Tuple[int, int]] = None,
    tileable: bool = False,
    full: Literal[False] = False,
    augment: Optional[Sequence[str]] = None,
    sample_mask: Union[Sample, Sequence[Optional[Sample]], None] = None,
    inpaint: Union[Sample, str, None] = None,
    inpaint_from: Union[Sample, Sequence[Sample], None] = None,
    guide: Optional[Sample] = None,
    guide_source: Optional[Sample] = None,
    guide_weight: Optional[float] = None,
    guide_passes: Optional[int] = None,
    **params: Param,
) -> Image: ...
@overload
def synthesize(
    sample: Union[Sample, Sequence[Sample]],
    method: str = "quilting",
    *,
    seed: int = 0,
    size: Optional[Tuple[int, int]] = None,
    tileable: bool = False,
    full: Literal[True],
    augment: Optional[Sequence[str]] = None,
    sample_mask: Union[Sample, Sequence[Optional[Sample]], None] = None,
    inpaint: Union[Sample, str, None] = None,
    inpaint_from: Union[Sample, Sequence[Sample], None] = None,
    guide: Optional[Sample] = None,
    guide_source: Optional[Sample] = None,
    guide_weight: Optional[float] = None,
    guide_passes: Optional[int] = None,
    **params: Param,
) -> Synthesis: ...
def synthesize(
    sample: Union[Sample, Sequence[Sample]],
    method: str = "quilting",
    *,
    seed: int = 0,
    size: Optional[Tuple[int, int]] = None,
    tileable: bool = False,
    full: bool = False,
    augment: Optional[Sequence[str]] = None,
    sample_mask: Union[Sample, Sequence[Optional[Sample]], None] = None,
    inpaint: Union[Sample, str, None] = None,
    inpaint_from: Union[Sample, Sequence[Sample], None] = None,
    guide: Optional[Sample] = None,
    guide_source: Optional[Sample] = None,
    guide_weight: Optional[float] = None,
    guide_passes: Optional[int] = None,
    **params: Param,
) -> Union[Image, Synthesis]:
    """Makes a texture from ``sample`` (a path or an array of shape (h, w) or (h, w, c), c in 1..4,
    uint8/uint16/float32) as a job file with the same values would: the same pixels and digest.

    ``size`` is (width, height), the sample's by default. ``params`` are the job file's ``[params]``
    keys (``texsyn.methods()`` lists them); a wrong key, type or range raises ``ParamError``.
    ``full=True`` returns a ``Synthesis`` with the placement, warnings and manifest record.

    The everyday jobs take the job file's keys: ``sample`` may be a list of samples, ``augment``
    a list of transforms (rot90, rot180, rot270, flip_h, flip_v), ``sample_mask`` a mask (white =
    may be copied) or one per sample (``None`` for none), ``inpaint`` the pixels of ``sample`` to
    fill (a mask, white = fill, or a channel name like "a") with ``inpaint_from`` the samples the
    fill copies from (default: ``sample`` itself; list ``sample`` among them to copy from it too),
    ``guide`` a target guide (texture
    transfer) with ``guide_source``, ``guide_weight`` and ``guide_passes``. They run through the
    job file they stand for, with its messages and its pixels; with several samples or
    ``augment`` the placement also has ``sample`` and ``transform`` arrays."""

def run(
    jobs: Union[PathLike, Sequence[PathLike]],
    out: PathLike,
    *,
    jobs_parallel: Optional[int] = None,
    force: bool = False,
    shard: Optional[str] = None,
    max_memory: Union[int, str, None] = None,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
) -> Dict[str, Any]:
    """Runs job files and directories into ``out`` as ``texsyn run`` does; returns the manifest.

    ``progress`` gets one dict per event (``event``: planned, started, finished, warning, invalid,
    done). Ctrl-C stops the run like the CLI and raises ``KeyboardInterrupt``."""

def verify(manifest: PathLike, *, jobs_parallel: Optional[int] = None, max_memory: Union[int, str, None] = None) -> Dict[str, Any]:
    """Re-runs every recorded job and compares pixels: ``{"ok", "manifest_problems", "jobs"}``."""

def diff(old: PathLike, new: PathLike) -> Dict[str, Any]:
    """What changed between two manifests (``texsyn diff --json``)."""

def methods() -> List[Dict[str, Any]]:
    """Every method: ``name``, ``summary``, ``algorithm_version``, ``params`` (name, kind, default, doc)."""

def advise(sample: Sample) -> Dict[str, Any]:
    """The sample's analysis and each method's fit with its defaults (``texsyn advise --json``)."""

def eval(sample: Sample, image: Sample, metrics: Optional[List[str]] = None) -> Dict[str, Optional[float]]:
    """Paper 003's measures and the verbatim fraction of ``image`` against ``sample``."""

def save(image: Image, path: PathLike) -> None:
    """Writes an array as texsyn writes outputs: PNG (8-bit for uint8, else 16-bit) or EXR, by the extension."""
