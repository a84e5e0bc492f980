"""Attribute names of Nimbus' USD schema (``nimbus::scene::schema::tokens``).

``NimbusVolumeAPI`` (on a Volume) and ``NimbusRenderSettingsAPI`` (on a
RenderSettings prim) carry these properties; ``VOLUME_API`` and
``RENDER_SETTINGS_API`` are the API schema names to apply.
"""

from ._nimbus import _schema_tokens as _t

DENSITY_FIELD: str = _t["DENSITY_FIELD"]
DENSITY_SCALE: str = _t["DENSITY_SCALE"]
ABSORPTION: str = _t["ABSORPTION"]
SCATTERING: str = _t["SCATTERING"]
ANISOTROPY: str = _t["ANISOTROPY"]
TEMPERATURE_FIELD: str = _t["TEMPERATURE_FIELD"]
TEMPERATURE_SCALE: str = _t["TEMPERATURE_SCALE"]
BLACKBODY_INTENSITY: str = _t["BLACKBODY_INTENSITY"]
EMISSION_FIELD: str = _t["EMISSION_FIELD"]
EMISSION_COLOR: str = _t["EMISSION_COLOR"]
EMISSION_SCALE: str = _t["EMISSION_SCALE"]
ALBEDO_FIELD: str = _t["ALBEDO_FIELD"]
SAMPLES: str = _t["SAMPLES"]
MAX_DEPTH: str = _t["MAX_DEPTH"]
SEED: str = _t["SEED"]
TRACKER: str = _t["TRACKER"]
SCHEME: str = _t["SCHEME"]
TRANSMITTANCE: str = _t["TRANSMITTANCE"]
CONTROL: str = _t["CONTROL"]
OCTREE_DEPTH: str = _t["OCTREE_DEPTH"]
PREVIEW_NAME: str = _t["PREVIEW_NAME"]
VOLUME_API: str = _t["VOLUME_API"]
RENDER_SETTINGS_API: str = _t["RENDER_SETTINGS_API"]

del _t
