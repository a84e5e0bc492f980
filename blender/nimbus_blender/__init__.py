"""Nimbus for Blender: a render engine ("Nimbus" in the Render Engine menu).

F12 exports the evaluated scene with Blender's USD exporter, authors the volume
materials and the exporter's corrections in an overlay layer (translate.py), renders
the stage in-process with the `nimbus` Python module and shows each pass as it
finishes (engine.py). Installed as an extension (blender/build.py makes the zip with
the nimbus wheel), or imported from `blender/` and registered with `register()`
(`sys.path.insert(0, "blender"); import nimbus_blender; nimbus_blender.register()`),
as the tests do. docs/blender.md says more.
"""

from . import engine, properties, ui

_registered = False


def register():
    global _registered
    if _registered:
        return
    import bpy

    properties.register()
    bpy.utils.register_class(engine.NimbusRenderEngine)
    ui.register()
    _registered = True


def unregister():
    global _registered
    if not _registered:
        return
    import bpy

    ui.unregister()
    bpy.utils.unregister_class(engine.NimbusRenderEngine)
    properties.unregister()
    _registered = False
