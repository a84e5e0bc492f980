"""Type stubs of the compiled module ``nimbus._nimbus`` (re-exported by ``nimbus``)."""

import os
from typing import Any, Callable, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

StrPath = Union[str, "os.PathLike[str]"]
Image = Union[StrPath, npt.ArrayLike]

class Error(Exception):
    """Base class of every error Nimbus raises; the message is the CLI's."""

class StageError(Error):
    """The stage could not be opened, composed or read (a malformed prim, a missing file)."""

class VdbError(Error):
    """A VDB file could not be read (missing grid, bad file, unsupported type)."""

class SettingsError(Error):
    """A keyword argument or stage setting is invalid, or the scene cannot be rendered as asked."""

class OutputError(Error):
    """An output file (EXR, stats JSON, preview PNG, temporary stage) could not be written."""

class Cancelled(Exception):
    """The caller stopped the render: ``cancel()`` returned True or ``on_pass``
    returned False. Not a ``nimbus.Error``."""

class RenderResult:
    """A finished render. Holds the film, so ``write`` writes what ``nimbus render`` writes."""

    rgba: npt.NDArray[np.float32]
    """Beauty and alpha, shape (height, width, 4), row 0 at the top."""
    aovs: dict[str, npt.NDArray[np.float32]]
    """The AOVs asked for with ``aovs=``, each (height, width); split layers
    (``lightgroup:G``, ``direct``, ...) are (height, width, 3) under their layer name
    (``lightgroup_G``)."""
    stats: dict[str, Any]
    """What ``nimbus render --stats`` writes (counters, timings, tracker, analysis)."""
    warnings: list[str]
    """The session's warnings (also issued with ``warnings.warn``)."""
    auto_summary: Optional[str]
    """What ``tracker="auto"`` chose and why (None when a tracker was named)."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def spp(self) -> int:
        """Samples per pixel actually taken."""
    @property
    def seed(self) -> int: ...
    @property
    def tracker(self) -> str: ...
    def write(
        self,
        path: StrPath,
        *,
        aovs: Optional[Sequence[str]] = None,
        stats: Optional[StrPath] = None,
        preview: Optional[StrPath] = None,
    ) -> None:
        """Write the EXR as ``nimbus render -o PATH`` does (R, G, B, A, lookups and the
        render's AOVs, or ``aovs``; a stage's other RenderProducts too), and the stats
        JSON / preview PNG when given. Raises OutputError."""

def render(
    stage: Optional[StrPath] = None,
    *,
    stage_text: Optional[str] = None,
    base_dir: Optional[StrPath] = None,
    spp: Optional[int] = None,
    res: Optional[Tuple[int, int]] = None,
    region: Optional[Tuple[int, int, int, int]] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    sampler: Optional[str] = None,
    max_depth: Optional[int] = None,
    majorant_cell: Optional[int] = None,
    octree_depth: Optional[int] = None,
    octree_prune: Optional[float] = None,
    tracker: Optional[str] = None,
    scheme: Optional[str] = None,
    transmittance: Optional[str] = None,
    control: Optional[float] = None,
    reduced_termination: bool = False,
    no_absorption_events: bool = False,
    majorant_scale: float = 1.0,
    profile: bool = False,
    no_specialise: bool = False,
    aovs: Optional[Sequence[str]] = None,
    time_limit: Optional[float] = None,
    noise_threshold: Optional[float] = None,
    min_spp: Optional[int] = None,
    denoise: Optional[bool] = None,
    strict: bool = False,
    no_default_lights: bool = False,
    grid: Optional[str] = None,
    camera: Optional[str] = None,
    frame: Optional[float] = None,
    output: Optional[StrPath] = None,
    stats: Optional[StrPath] = None,
    preview: Optional[StrPath] = None,
    progress: Optional[Callable[[int, Optional[int]], Any]] = None,
    on_pass: Optional[
        Callable[[int, Optional[int], npt.NDArray[np.float32]], Optional[bool]]
    ] = None,
    on_noise: Optional[Callable[[int, float, Optional[float]], Any]] = None,
    cancel: Optional[Callable[[], bool]] = None,
) -> RenderResult:
    """Render a stage (a .usda/.usdc/.usdz path, a .vdb file, or usda text in
    ``stage_text`` whose relative asset paths resolve against ``base_dir``, default the
    working directory).

    The keyword arguments are ``nimbus render``'s flags (``--max-depth`` is
    ``max_depth``), with the same meaning and defaults; None leaves the choice to the
    stage, and the stage's silence to the schema fallbacks. ``tracker`` is "auto" or one
    of ``tracker_names()``. ``output``/``stats``/``preview`` write files as ``-o``,
    ``--stats`` and ``--preview`` do; without them nothing is written.

    ``region=(x0, y0, x1, y1)`` renders only those pixels (``--region``): the arrays
    are the region's. ``aovs`` also takes the splits ``direct``, ``indirect``,
    ``emission``, ``lightgroup:G`` (returned as (H, W, 3) arrays).

    The GIL is released while the stage loads and renders. On the calling thread:
    ``progress(done, total)`` as rows finish (``total`` is spp * rows, None with a time
    limit alone); ``on_pass(spp, total_spp, rgba)`` after each pass of the progressive
    render with a copy of the image so far; ``on_noise(spp, noise, converged)`` after
    each pass, before ``on_pass`` (``noise``: the mean of adaptive sampling's per-pixel
    noise estimate, the stats' ``estimated_noise``; ``converged``: the share of pixels
    adaptive sampling stopped, None without it); ``cancel()`` every 20 ms. ``on_pass``
    returning False or ``cancel()`` returning True raises Cancelled at once; Ctrl-C
    raises KeyboardInterrupt at once.

    Raises StageError, VdbError, SettingsError or OutputError (all ``nimbus.Error``).
    """

def info(
    stage: Optional[StrPath] = None,
    *,
    stage_text: Optional[str] = None,
    base_dir: Optional[StrPath] = None,
    frame: Optional[float] = None,
    octree_depth: int = 8,
) -> dict[str, Any]:
    """What ``nimbus info --json`` prints (the same description, from the same library
    function), as a dict. For a stage (``"kind": "stage"``): "volumes" (each with its
    "fields", their grids and the grid as loaded), "lights", "camera",
    "render_settings", "holdouts", "analysis" (the scene analysis), "auto" (what
    ``tracker="auto"`` picks and why), "vdb_reader", "warnings". For a .vdb file
    (``"kind": "vdb"``) its "grids"; for a deep EXR (``"kind": "deep_exr"``) its windows
    and sample counts. Keys ending in ``_seconds`` are build times."""

def compare(a: Image, b: Image) -> dict[str, Any]:
    """Per-channel error of ``a`` against reference ``b``, computed by the function
    ``nimbus compare --json`` prints: each an EXR path or an array (H, W, C) with
    channels R, G, B[, A]. Values are
    clamped to ±65504; relmse = mean (a-b)^2 / (b^2 + 0.01). Keys "channels" (a list
    of dicts with channel, mse, relmse, rmse, mean_a, mean_b, nonfinite_a,
    nonfinite_b) and "rgb" (their mean over R, G, B)."""

def read_exr(path: StrPath) -> dict[str, npt.NDArray[np.float32]]:
    """Every channel of an EXR as a float32 (H, W) array, by channel name."""

def tracker_names() -> list[str]:
    """Tracker names ``render(tracker=...)`` accepts besides "auto"."""

def scheme_names() -> list[str]: ...
def transmittance_names() -> list[str]: ...
def aov_names() -> list[str]:
    """Every AOV (EXR channel) name ``render(aovs=...)`` accepts."""

def vdb_reader() -> str:
    """The VDB reader in use: "openvdb" (the C++ bridge) or "rust" (NIMBUS_VDB_READER picks one)."""

_schema_tokens: dict[str, str]
