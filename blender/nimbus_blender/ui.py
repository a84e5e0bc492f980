"""Panels of the Render, View Layer and Object properties for the Nimbus engine."""

import bpy


class _NimbusPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {"NIMBUS"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class NIMBUS_PT_sampling(_NimbusPanel, bpy.types.Panel):
    bl_label = "Sampling"
    bl_context = "render"

    def draw(self, context):
        s = context.scene.nimbus
        col = self.layout.column()
        col.use_property_split = True
        col.prop(s, "samples")
        row = col.row(heading="Noise Threshold", align=True)
        row.prop(s, "use_adaptive_sampling", text="")
        sub = row.row()
        sub.active = s.use_adaptive_sampling
        sub.prop(s, "adaptive_threshold", text="")
        sub = col.row()
        sub.active = s.use_adaptive_sampling
        sub.prop(s, "adaptive_min_samples")
        col.prop(s, "time_limit")
        col.prop(s, "use_denoising")
        row = col.row(align=True)
        row.prop(s, "seed")
        row.prop(s, "use_animated_seed", text="", icon="TIME")
        col.prop(s, "max_depth")


class NIMBUS_PT_tracking(_NimbusPanel, bpy.types.Panel):
    bl_label = "Tracking"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        s = context.scene.nimbus
        col = self.layout.column()
        col.use_property_split = True
        col.prop(s, "tracker")
        col.prop(s, "scheme")
        col.prop(s, "transmittance")
        col.prop(s, "control")
        col.prop(s, "octree_depth")
        col.prop(s, "keep_files")


class NIMBUS_PT_passes(_NimbusPanel, bpy.types.Panel):
    bl_label = "Nimbus Passes"
    bl_context = "view_layer"

    def draw(self, context):
        vl = context.view_layer.nimbus
        col = self.layout.column(heading="Include")
        col.use_property_split = True
        for p in ("use_pass_lookups", "use_pass_collisions", "use_pass_max_throughput",
                  "use_pass_variance", "use_pass_samples", "use_pass_albedo"):
            col.prop(vl, p)
        col.label(text="Light groups: View Layer > Light Groups (Combined_NAME passes)")


class NIMBUS_PT_object(_NimbusPanel, bpy.types.Panel):
    bl_label = "Nimbus"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.object is not None and \
            context.object.type == "MESH"

    def draw(self, context):
        self.layout.prop(context.object.nimbus, "holdout")


CLASSES = (NIMBUS_PT_sampling, NIMBUS_PT_tracking, NIMBUS_PT_passes, NIMBUS_PT_object)


def _compatible_panels():
    """Blender's own panels that work for any engine listing itself in COMPAT_ENGINES
    (output, format, film, light and world properties)."""
    wanted = {
        "RENDER_PT_format", "RENDER_PT_frame_range", "RENDER_PT_output", "RENDER_PT_film",
        "RENDER_PT_color_management", "DATA_PT_light", "DATA_PT_EEVEE_light",
        "DATA_PT_camera", "DATA_PT_lens", "DATA_PT_camera_dof", "WORLD_PT_context_world",
        "VIEWLAYER_PT_layer_passes_lightgroups", "DATA_PT_volume_file", "DATA_PT_volume_grids",
        "DATA_PT_volume_render", "EEVEE_MATERIAL_PT_context_material", "MATERIAL_PT_preview",
    }
    for name in wanted:
        panel = getattr(bpy.types, name, None)
        if panel is not None and hasattr(panel, "COMPAT_ENGINES"):
            yield panel


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    for p in _compatible_panels():
        p.COMPAT_ENGINES.add("NIMBUS")


def unregister():
    for p in _compatible_panels():
        p.COMPAT_ENGINES.discard("NIMBUS")
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
