"""The add-on's settings: `scene.nimbus` (the render settings, with the Nimbus schema's
fallbacks as defaults: schemas/generatedSchema.usda, NimbusRenderSettingsAPI),
`view_layer.nimbus` (which passes to write) and `object.nimbus` (holdout toggle)."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty

# The library's names, for when the wheel is missing (the menus still draw; rendering
# then reports the missing module). Kept equal to nimbus.tracker_names() and friends by
# tests/blender_addon (test_settings_match_the_module).
_TRACKERS = ["naive-delta", "delta", "weighted-delta", "decomposition",
             "decomposition-weighted", "spectral", "spectral-decomposition", "spectral-mis",
             "ratio-select"]
_SCHEMES = ["max", "avg", "hist-max", "hist-avg"]
_TRANSMITTANCES = ["ratio", "residual-ratio", "telescoping", "tracking"]


def _names(fn, fallback):
    try:
        import nimbus

        return list(getattr(nimbus, fn)())
    except Exception:  # noqa: BLE001 - no wheel: the fallback list
        return fallback


def _items(names):
    return [(n, n, n) for n in names]


TRACKER_ITEMS = [("auto", "auto", "Nimbus picks a tracker for the scene (nimbus info says why)")] + \
    _items(_names("tracker_names", _TRACKERS))
SCHEME_ITEMS = _items(_names("scheme_names", _SCHEMES))
TRANSMITTANCE_ITEMS = _items(_names("transmittance_names", _TRANSMITTANCES))


class NimbusRenderSettings(bpy.types.PropertyGroup):
    """`scene.nimbus`: what `nimbus render` takes as flags, with the schema's defaults."""

    samples: IntProperty(
        name="Samples", description="Samples per pixel (nimbus:samples)", default=16, min=1,
        soft_max=65536)
    seed: IntProperty(name="Seed", description="Random seed (nimbus:seed)", default=0, min=0)
    use_animated_seed: BoolProperty(
        name="Animated Seed", description="Add the frame number to the seed", default=False)
    max_depth: IntProperty(
        name="Max Depth",
        description="Scattering events per path at most (nimbus:maxDepth); Cycles' Volume "
                    "Bounces + 1", default=64, min=1, soft_max=1024)
    tracker: EnumProperty(
        name="Tracker", description="Free-path sampler (nimbus:tracker)", items=TRACKER_ITEMS,
        default="auto")
    scheme: EnumProperty(
        name="Scheme", description="Majorant scheme for chromatic media (nimbus:scheme)",
        items=SCHEME_ITEMS, default="hist-avg")
    transmittance: EnumProperty(
        name="Transmittance", description="Shadow-ray estimator (nimbus:transmittance)",
        items=TRANSMITTANCE_ITEMS, default="ratio")
    control: FloatProperty(
        name="Control", description="Control (residual) extinction fraction (nimbus:control)",
        default=0.05, min=0.0, max=1.0)
    time_limit: FloatProperty(
        name="Time Limit", description="Seconds of rendering at most (0: none); with it the "
        "samples are a cap", default=0.0, min=0.0, subtype="TIME_ABSOLUTE", unit="TIME_ABSOLUTE")
    # Cycles' names and defaults for the same settings (scene.cycles.*), off by default.
    use_adaptive_sampling: BoolProperty(
        name="Noise Threshold", description="Adaptive sampling: each pixel stops once its "
        "noise estimate (Cycles' measure) is below the threshold (nimbus:noiseThreshold)",
        default=False)
    adaptive_threshold: FloatProperty(
        name="Noise Threshold", description="Noise level at which a pixel stops taking "
        "samples, as Cycles' Noise Threshold", default=0.01, min=0.0001, max=1.0,
        precision=4)
    adaptive_min_samples: IntProperty(
        name="Min Samples", description="Samples every pixel takes before it may stop "
        "(nimbus:minSamples; 0: the square root of the samples, at least 16)", default=0,
        min=0)
    # Cycles' name (scene.cycles.use_denoising); off by default here.
    use_denoising: BoolProperty(
        name="Denoise", description="Denoise the image with Open Image Denoise, guided by "
        "the volume's first-scatter albedo (nimbus:denoise); light group passes are denoised "
        "each on its own", default=False)
    octree_depth: IntProperty(
        name="Octree Depth", description="Majorant octree depth (nimbus:octreeDepth; 0: chosen "
        "from the grid)", default=0, min=0, max=12)
    keep_files: BoolProperty(
        name="Keep Stage", description="Keep the translated USD stage (its folder is printed "
        "and in the render's stats line) instead of deleting it after the render",
        default=False)


class NimbusViewLayerSettings(bpy.types.PropertyGroup):
    """`view_layer.nimbus`: the passes Nimbus writes besides Combined and light groups."""

    use_pass_lookups: BoolProperty(name="Lookups", description="Density lookups per sample",
                                   default=False)
    use_pass_collisions: BoolProperty(
        name="Collisions", description="Real and null collisions per sample", default=False)
    use_pass_max_throughput: BoolProperty(
        name="Max Throughput", description="Largest path throughput per sample", default=False)
    use_pass_variance: BoolProperty(
        name="Variance", description="Sample variance of the luminance", default=False)
    use_pass_samples: BoolProperty(
        name="Samples", description="Samples each pixel took (adaptive sampling stops "
        "pixels early)", default=False)
    use_pass_albedo: BoolProperty(
        name="Denoising Albedo", description="The volume's single-scattering albedo times "
        "alpha, for the Denoise node's Albedo input", default=False)


class NimbusObjectSettings(bpy.types.PropertyGroup):
    """`object.nimbus`: a mesh is a black holdout in Nimbus unless this is off."""

    holdout: BoolProperty(
        name="Holdout", description="Render this mesh as a black matte occluder "
        "(nimbus:holdout); off leaves it out of Nimbus' render", default=True)


CLASSES = (NimbusRenderSettings, NimbusViewLayerSettings, NimbusObjectSettings)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.nimbus = PointerProperty(type=NimbusRenderSettings)
    bpy.types.ViewLayer.nimbus = PointerProperty(type=NimbusViewLayerSettings)
    bpy.types.Object.nimbus = PointerProperty(type=NimbusObjectSettings)


def unregister():
    del bpy.types.Object.nimbus
    del bpy.types.ViewLayer.nimbus
    del bpy.types.Scene.nimbus
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
