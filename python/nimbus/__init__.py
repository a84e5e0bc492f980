"""Nimbus: a heterogeneous volume renderer for USD stages with OpenVDB fields.

The module calls the library's render session (the same code as ``nimbus render``),
never the command line::

    import nimbus
    info = nimbus.info("scenes/cloud/cloud.usda")
    r = nimbus.render("scenes/cloud/cloud.usda", spp=64, res=(320, 240), aovs=["lookups"])
    r.rgba              # numpy float32 (H, W, 4)
    r.aovs["lookups"]   # numpy float32 (H, W)
    r.stats             # dict, the JSON of ``nimbus render --stats``
    r.write("cloud.exr")
"""

from . import schema
from ._nimbus import (
    Cancelled,
    Error,
    OutputError,
    RenderResult,
    SettingsError,
    StageError,
    VdbError,
    aov_names,
    compare,
    info,
    read_exr,
    render,
    scheme_names,
    tracker_names,
    transmittance_names,
    vdb_reader,
)

__all__ = [
    "Cancelled",
    "Error",
    "OutputError",
    "RenderResult",
    "SettingsError",
    "StageError",
    "VdbError",
    "aov_names",
    "compare",
    "info",
    "read_exr",
    "render",
    "schema",
    "scheme_names",
    "tracker_names",
    "transmittance_names",
    "vdb_reader",
]
