"""The Nimbus render engine: F12 translates the scene (translate.py), renders it
in-process with nimbus.render (the wheel in Blender's Python) and copies each pass's
image into Blender's render result."""

import os
import shutil
import tempfile
import time
import traceback

import bpy
import numpy as np

from . import translate

# Nimbus AOVs as Blender passes: (view-layer toggle, Blender pass name, nimbus AOV).
AOV_PASSES = [
    ("use_pass_lookups", "Nimbus Lookups", "lookups"),
    ("use_pass_collisions", "Nimbus Real Collisions", "real_collisions"),
    ("use_pass_collisions", "Nimbus Null Collisions", "null_collisions"),
    ("use_pass_max_throughput", "Nimbus Max Throughput", "max_throughput"),
    ("use_pass_variance", "Nimbus Variance", "variance"),
    ("use_pass_samples", "Nimbus Samples", "samples"),
]
ALBEDO_PASS = "Denoising Albedo"
# The layer of light the camera sees straight from the dome (subtracted for a
# transparent film, as Cycles leaves the background out).
WORLD_DIRECT = "nimbus_world_direct"

# What the last render handed to nimbus.render (tests compare the add-on's image with
# a render of the same stage): {"stage", "kwargs", "seconds", "translate_seconds", ...}.
last_render = {}

# Headless Blender (bpy from PyPI, the tests) has no Esc key: a test sets this to a
# callable returning True to stand in for the key press; test_break() is asked too.
break_hook = None


def lightgroup_pass(name):
    """Cycles' pass name for light group `name`."""
    return f"Combined_{name}"


def _blender_rows(a):
    """Nimbus rows run top to bottom, Blender's bottom to top; flattened float32."""
    return np.ascontiguousarray(a[::-1], dtype=np.float32).ravel()


class NimbusRenderEngine(bpy.types.RenderEngine):
    bl_idname = "NIMBUS"
    bl_label = "Nimbus"
    bl_use_preview = False
    bl_use_postprocess = True

    def status(self, text):
        """The status line (Blender's render info text)."""
        self.update_stats("", text)

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        vl = renderlayer.nimbus
        for prop, name, _ in AOV_PASSES:
            if getattr(vl, prop):
                self.register_pass(scene, renderlayer, name, 1, "X", "VALUE")
        if vl.use_pass_albedo:
            self.register_pass(scene, renderlayer, ALBEDO_PASS, 3, "RGB", "COLOR")
        for lg in renderlayer.lightgroups:
            self.register_pass(scene, renderlayer, lightgroup_pass(lg.name), 3, "RGB", "COLOR")

    def render(self, depsgraph):
        # Nothing may escape to Blender: every failure is a report.
        try:
            self._render(depsgraph)
        except translate.TranslationError as e:
            self.report({"ERROR"}, f"Nimbus: {e}")
        except Exception as e:  # noqa: BLE001 - reported, never raised into Blender
            kind = type(e).__name__
            if kind == "Cancelled":
                return
            traceback.print_exc()
            self.report({"ERROR"}, f"Nimbus: {kind}: {e}")

    def _render(self, depsgraph):
        start = time.perf_counter()
        try:
            import nimbus
        except ImportError as e:
            raise translate.TranslationError(
                f"the nimbus Python module is not installed in Blender's Python ({e}); "
                "install the add-on zip built by blender/build.py") from e
        scene = depsgraph.scene
        view_layer = depsgraph.view_layer
        settings = scene.nimbus
        self.status("Nimbus: exporting the scene")
        folder = tempfile.mkdtemp(prefix="nimbus-blender-")
        try:
            t = translate.translate(depsgraph, folder, frame_set=self.frame_set)
            translated = time.perf_counter()
            for w in t.warnings:
                self.report({"WARNING"}, f"Nimbus: {w}")
            self._render_stage(nimbus, scene, view_layer, settings, t, start, translated)
        finally:
            if settings.keep_files:
                print(f"Nimbus: the translated stage is {os.path.join(folder, 'scene_nimbus.usda')}")
            else:
                shutil.rmtree(folder, ignore_errors=True)

    def _render_stage(self, nimbus, scene, view_layer, settings, t, start, translated):
        vl = view_layer.nimbus
        aovs = [aov for prop, _, aov in AOV_PASSES if getattr(vl, prop)]
        aovs = list(dict.fromkeys(aovs))
        groups = {}
        for lg in view_layer.lightgroups:
            if lg.name in t.lightgroups:
                layer = f"lg{len(groups)}"
                groups[lg.name] = layer
                aovs.append(f"{layer}=C.*<[LO].'{t.lightgroups[lg.name]}'>")
        subtract_world = t.transparent and t.world_prim is not None
        if subtract_world:
            aovs.append(f"{WORLD_DIRECT}=C<L.'{t.world_prim}'>")
        seed = settings.seed + (scene.frame_current if settings.use_animated_seed else 0)
        kwargs = dict(
            camera=t.camera,
            res=t.res,
            region=t.region,
            spp=settings.samples,
            seed=seed,
            max_depth=settings.max_depth,
            tracker=settings.tracker,
            scheme=settings.scheme,
            transmittance=settings.transmittance,
            control=settings.control,
            time_limit=settings.time_limit if settings.time_limit > 0 else None,
            noise_threshold=(settings.adaptive_threshold if settings.use_adaptive_sampling
                             else None),
            min_spp=(settings.adaptive_min_samples
                     if settings.use_adaptive_sampling and settings.adaptive_min_samples > 0
                     else None),
            octree_depth=settings.octree_depth if settings.octree_depth > 0 else None,
            threads=scene.render.threads,
            aovs=aovs,
            denoise=settings.use_denoising,
        )
        if t.frame is not None:
            # Motion blur: the frame the camera's shutter opens around (docs/blender.md).
            kwargs["frame"] = t.frame
        if settings.use_denoising:
            _use_blenders_oidn()
        # Pass registration, then the result (Blender crops it to the border).
        for prop, name, _ in AOV_PASSES:
            if getattr(vl, prop):
                self.add_pass(name, 1, "X")
        if vl.use_pass_albedo:
            self.add_pass(ALBEDO_PASS, 3, "RGB")
        for lg in view_layer.lightgroups:
            self.add_pass(lightgroup_pass(lg.name), 3, "RGB")
        w, h = t.res
        x0, y0, x1, y1 = t.region or (0, 0, w, h)
        # With a border Blender's result is the border's pixels, at (0, 0).
        result = self.begin_result(0, 0, x1 - x0, y1 - y0)
        if result is None or (result.resolution_x, result.resolution_y) != (x1 - x0, y1 - y0):
            size = None if result is None else (result.resolution_x, result.resolution_y)
            raise translate.TranslationError(
                f"scene '{scene.name}': Blender's render result is {size}, Nimbus renders "
                f"{x1 - x0}x{y1 - y0} (region {t.region} of {w}x{h})")
        layer = result.layers[0]
        combined = layer.passes["Combined"]
        opaque = not t.transparent
        total = settings.samples

        # The estimated error after the last pass, as the CLI's progress line says it.
        noise = {}

        def on_noise(spp, estimate, converged):
            noise["text"] = pass_noise(estimate, converged)

        def show(spp, total_spp, rgba):
            if opaque:
                rgba = rgba.copy()
                rgba[..., 3] = 1.0
            combined.rect.foreach_set(_blender_rows(rgba))
            self.update_result(result)
            text = f"Nimbus: {spp} / {total_spp or '-'} samples"
            if "text" in noise:
                text += ", " + noise["text"]
            self.status(text)
            return None

        def progress(done, total_rows):
            if total_rows:
                self.update_progress(min(done / total_rows, 1.0))

        def cancel():
            return self.test_break() or (break_hook is not None and break_hook())

        self.status("Nimbus: loading the stage")
        render_start = time.perf_counter()
        try:
            r = nimbus.render(t.stage, on_pass=show, on_noise=on_noise,
                              progress=progress, cancel=cancel, **kwargs)
        except nimbus.Cancelled:
            self.end_result(result)
            raise
        except nimbus.Error as e:
            self.end_result(result, cancel=True)
            raise translate.TranslationError(_name_object(str(e), scene)) from e
        rendered = time.perf_counter()
        rgba = r.rgba.copy()
        if subtract_world:
            rgba[..., :3] -= r.aovs[WORLD_DIRECT]
        if opaque:
            rgba[..., 3] = 1.0
        combined.rect.foreach_set(_blender_rows(rgba))
        for prop, name, aov in AOV_PASSES:
            if getattr(vl, prop):
                layer.passes[name].rect.foreach_set(_blender_rows(r.aovs[aov]))
        if vl.use_pass_albedo and "albedo" in r.aovs:
            # Denoised: the albedo the denoiser used (first-scatter, per pixel).
            layer.passes[ALBEDO_PASS].rect.foreach_set(_blender_rows(r.aovs["albedo"]))
        elif vl.use_pass_albedo:
            albedo = r.rgba[..., 3:4] * np.asarray(t.albedo, np.float32)
            layer.passes[ALBEDO_PASS].rect.foreach_set(_blender_rows(albedo))
        zero = np.zeros(r.rgba.shape[:2] + (3,), np.float32)
        for lg in view_layer.lightgroups:
            img = r.aovs[groups[lg.name]] if lg.name in groups else zero
            if subtract_world and lg.name == getattr(scene.world, "lightgroup", None):
                img = img - r.aovs[WORLD_DIRECT]
            layer.passes[lightgroup_pass(lg.name)].rect.foreach_set(_blender_rows(img))
        self.end_result(result)
        end = time.perf_counter()
        last_render.clear()
        last_render.update(
            stage=t.stage, kwargs=kwargs, spp=r.spp, warnings=t.warnings,
            translate_seconds=translated - start, render_call_seconds=rendered - render_start,
            render_seconds=r.stats["wall_seconds"], total_seconds=end - start,
            lightgroup_layers=groups, transparent=t.transparent,
            world_subtracted=subtract_world)
        noise = f"noise {r.stats['estimated_noise']:.4f}, "
        if r.stats.get("converged_pixels") is not None:
            noise = (f"mean {r.stats['mean_samples_per_pixel']:.1f} samples, " + noise +
                     f"{100 * r.stats['converged_pixels']:.0f}% converged, ")
        self.status(f"Nimbus: {r.spp} samples in {r.stats['passes']} passes, "
                    f"{noise}{end - start:.2f} s")


def pass_noise(estimate, converged):
    """The status line's error: "noise 0.0123" (the mean per-pixel noise estimate
    adaptive sampling stops on, the CLI's progress line's), and with adaptive sampling
    the share of pixels converged."""
    text = f"noise {estimate:.4f}"
    if converged is not None:
        text += f", {100 * converged:.0f}% converged"
    return text


def _blenders_oidn():
    """Blender's own Open Image Denoise library (the one Cycles uses), or None: in
    Blender's process the module denoises with it, not with the library the wheel was
    built against (another machine's path, and a second OIDN and TBB in one process)."""
    import bpy
    # Blender keeps its libraries in `lib` beside its version folder (`5.0`), in the
    # application and in the bpy module alike.
    local = bpy.utils.resource_path("LOCAL")
    folders = [os.path.join(os.path.dirname(local), "lib"),
               os.path.join(os.path.dirname(bpy.app.binary_path or ""), "lib")]
    for folder in folders:
        path = os.path.join(folder, "libOpenImageDenoise.so.2")
        if os.path.isfile(path):
            return path
    return None


def _use_blenders_oidn():
    """Points nimbus at Blender's OIDN (NIMBUS_OIDN_LIBRARY) unless the user set one;
    read once, at the first denoise of the process."""
    if not os.environ.get("NIMBUS_OIDN_LIBRARY"):
        path = _blenders_oidn()
        if path:
            os.environ["NIMBUS_OIDN_LIBRARY"] = path


def _name_object(message, scene):
    """A Nimbus error names prims (/root/OBJECT/DATA, or the overlay's
    /root/nimbus_volumes/OBJECT_K for a volume instance): add the Blender object's
    name."""
    for obj in scene.objects:
        if obj.data is not None and translate.data_path(obj) in message:
            return f"object '{obj.name}': {message}"
        instance = f"{translate.INSTANCES}/{translate.prim_name(obj.name)}_"
        if instance in message:
            return f"object '{obj.name}': {message}"
    return message
