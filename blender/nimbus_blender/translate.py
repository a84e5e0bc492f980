"""Blender scene → Nimbus stage: Blender's own USD exporter writes the evaluated scene
into a temporary stage, and a small overlay layer over it authors what the exporter
leaves out or writes differently from what Cycles renders (docs/blender.md):

- the volume's material (the exporter writes none): Principled Volume, Volume
  Scatter, Volume Absorption, Emission and Add Shader mapped to NimbusVolumeAPI as
  Cycles' svm_node_principled_volume and volume closures mean them; any other node
  is a warning naming the material and the node;
- fog meshes: a mesh whose material has a Volume output gets NimbusVolumeAPI with the
  same mapping, without grids (Cycles fills a mesh's inside with Density x 1);
- world fog: the World Output's Volume as a `Volume` prim with `nimbus:fill = "world"`;
- lights: `enableColorTemperature = 0` unless Temperature is on (the exporter always
  writes 1, and pxr's 6500 K is not white), a sun's intensity = its strength (the
  exporter writes strength / 4) and angle = its full angle, light groups;
- the HDRI dome's Z-up rotation and Background strength (the exporter writes neither),
  the world's light group;
- holdouts: a mesh whose `object.nimbus.holdout` is off gets `nimbus:holdout = 0`;
  curves, texts and surfaces become holdout meshes;
- volumes made by Geometry Nodes and volume instances: their own VDBs and prims;
- an orthographic camera (the exporter writes perspective ones only).

Nothing here needs pxr (Blender has no Python USD module): the overlay is usda text.
"""

import math
import os
import re
from dataclasses import dataclass, field

import bpy

ROOT = "/root"
WORLD_PRIM = f"{ROOT}/env_light"
# Volume instances (Geometry Nodes on a mesh, which the exporter leaves out;
# collection instances, which it writes without material) are defined under this
# prim by the overlay.
INSTANCES = f"{ROOT}/nimbus_volumes"
# Curves, texts and surfaces as holdout meshes (the exporter writes them as curves
# or not at all) are defined under this prim.
HOLDOUTS = f"{ROOT}/nimbus_holdouts"
# The world's volume shader (World Output > Volume) as a fog filling the world.
WORLD_VOLUME = f"{ROOT}/nimbus_world_volume"
# Grids made in memory are written here, in the translation's folder.
GENERATED_VDBS = "volumes_nimbus"


class TranslationError(Exception):
    """The scene cannot be handed to Nimbus; the message names the object."""


@dataclass
class Translation:
    """A translated scene: the stage to render and what the engine needs besides."""

    folder: str
    stage: str
    camera: str
    res: tuple
    # (x0, y0, x1, y1), rows from the top, or None for the whole frame.
    region: tuple = None
    warnings: list = field(default_factory=list)
    # Blender light group name -> Nimbus group token, for groups some source uses.
    lightgroups: dict = field(default_factory=dict)
    # The dome's prim when the world is exported (film transparency subtracts it).
    world_prim: str = None
    transparent: bool = False
    # Single-scattering albedo of the (first) volume, for the albedo pass.
    albedo: tuple = (0.0, 0.0, 0.0)
    # With motion blur: the frame nimbus.render is given (frame_current + subframe), so
    # the camera's shutter is used; None without motion blur.
    frame: float = None
    # With motion blur: the Shutter (motion_blur below).
    shutter: object = None


def prim_name(name):
    """The exporter's prim name for a Blender name (pxr's TfMakeValidIdentifier)."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not s or s[0].isdigit():
        s = "_" + s
    return s


def object_path(obj):
    """The exported Xform of `obj`: ROOT / parents / object."""
    names = []
    o = obj
    while o is not None:
        names.append(prim_name(o.name))
        o = o.parent
    return ROOT + "/" + "/".join(reversed(names))


def data_path(obj):
    """The exported gprim / light / camera / volume under the object's Xform."""
    return object_path(obj) + "/" + prim_name(obj.data.name)


# ---- materials ---------------------------------------------------------------------


def _socket_value(sock):
    v = sock.default_value
    try:
        return tuple(v)[:3]
    except TypeError:
        return v


def _linked(sock):
    return sock.links[0].from_node if sock.is_linked and sock.links else None


def _active_output(tree, idname):
    """The output node of type `idname` Cycles uses: the active one of those for All or
    Cycles, else the first."""
    out = None
    for n in tree.nodes:
        if n.bl_idname == idname and n.target in ("ALL", "CYCLES"):
            if out is None or n.is_active_output:
                out = n
    return out


def material_outputs(material):
    """(surface node, volume node) linked to the material's active Material Output,
    each None when unlinked."""
    if material is None or not material.node_tree:
        return None, None
    out = _active_output(material.node_tree, "ShaderNodeOutputMaterial")
    if out is None:
        return None, None
    return _linked(out.inputs["Surface"]), _linked(out.inputs["Volume"])


def world_volume_node(world):
    """The node linked to the Volume input of the world's active World Output, or None."""
    if world is None or not world.node_tree:
        return None
    out = _active_output(world.node_tree, "ShaderNodeOutputWorld")
    return _linked(out.inputs["Volume"]) if out is not None else None


class _Medium:
    """Coefficients per unit of the density grid (per world unit for a fog), summed
    over closures."""

    def __init__(self):
        self.sigma_s = [0.0, 0.0, 0.0]
        self.sigma_a = [0.0, 0.0, 0.0]
        self.anisotropy = []  # (weight, g)
        self.density_attribute = None
        # (overlay prims, output "path.outputs:name") of the node tree driving the
        # Density input, when there is one (_graph).
        self.density_graph = None
        # The same for a node tree driving the emission colour.
        self.emission_graph = None
        # The same for a node tree driving Principled Volume's Color (an albedo
        # multiplier), with what undoing it adds to (sigma_s, sigma_a): the socket's
        # colour in place of the white the graph's translation assumes.
        self.albedo_graph = None
        self.albedo_undo = None
        self.emission = None  # (color, strength, attribute or None = constant)
        self.blackbody = None  # (intensity, temperature, attribute, tint)

    def add(self, sigma_s, sigma_a, g=0.0):
        self.sigma_s = [a + b for a, b in zip(self.sigma_s, sigma_s)]
        self.sigma_a = [a + b for a, b in zip(self.sigma_a, sigma_a)]
        w = sum(sigma_s)
        if w > 0:
            self.anisotropy.append((w, g))


# ---- density node trees (issue 47) ---------------------------------------------------

# Where the overlay defines the node trees that drive densities: one Scope per object.
GRAPHS = f"{ROOT}/nimbus_graphs"

# Blender nodes Nimbus compiles (src/scene/blender_graph.rs), with the properties each
# needs written as inputs.
_GRAPH_NODES = {
    "ShaderNodeTexCoord": (),
    "ShaderNodeTexNoise": ("noise_dimensions", "noise_type", "normalize"),
    "ShaderNodeTexVoronoi": ("voronoi_dimensions", "feature", "distance", "normalize"),
    "ShaderNodeTexGradient": ("gradient_type",),
    "ShaderNodeValToRGB": (),
    "ShaderNodeRGBToBW": (),
    "ShaderNodeCombineXYZ": (),
    "ShaderNodeMath": ("operation", "use_clamp"),
    "ShaderNodeMapRange": ("data_type", "interpolation_type", "clamp"),
    "ShaderNodeVectorMath": ("operation",),
    "ShaderNodeMapping": ("vector_type",),
    "ShaderNodeVectorRotate": ("rotation_type", "invert"),
    "ShaderNodeSeparateXYZ": (),
    "ShaderNodeAttribute": ("attribute_name",),
    "ShaderNodeValue": (),
    "ShaderNodeClamp": ("clamp_type",),
    "ShaderNodeMix": ("data_type", "factor_mode", "blend_type", "clamp_factor",
                      "clamp_result"),
    "ShaderNodeMixRGB": ("blend_type", "use_clamp", "use_alpha"),
    "ShaderNodeInvert": (),
    "ShaderNodeVolumeInfo": (),
    "ShaderNodeFloatCurve": (),
    "ShaderNodeSeparateColor": ("mode",),
    "ShaderNodeCombineColor": ("mode",),
    "ShaderNodeHueSaturation": (),
    "ShaderNodeRGBCurve": (),
    "ShaderNodeVectorCurve": (),
    "ShaderNodeGamma": (),
    "ShaderNodeBrightContrast": (),
    "ShaderNodeTexWhiteNoise": ("noise_dimensions",),
    "ShaderNodeBlackbody": (),
    "ShaderNodeTexWave": ("wave_type", "bands_direction", "rings_direction", "wave_profile"),
    "ShaderNodeTexMagic": ("turbulence_depth",),
}
# The values of node properties Nimbus compiles where it compiles fewer than Blender
# offers (src/scene/blender_graph.rs refuses the others): another value is
# untranslatable here, so the add-on warns and keeps the socket's value instead of
# writing a stage Nimbus refuses. Every Math and Vector Math operation compiles; they
# are listed so that one a later Blender adds is caught. blender/tests checks every
# value Blender offers against the reader.
_BLEND_TYPES = {
    "MIX", "DARKEN", "MULTIPLY", "BURN", "LIGHTEN", "SCREEN", "DODGE", "ADD", "OVERLAY",
    "SOFT_LIGHT", "LINEAR_LIGHT", "DIFFERENCE", "EXCLUSION", "SUBTRACT", "DIVIDE", "HUE",
    "SATURATION", "COLOR", "VALUE"}
_COMPILED = {
    ("ShaderNodeMath", "operation"): {
        "ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "POWER", "LOGARITHM",
        "SQRT", "INVERSE_SQRT", "ABSOLUTE", "EXPONENT", "MINIMUM", "MAXIMUM", "LESS_THAN",
        "GREATER_THAN", "SIGN", "COMPARE", "SMOOTH_MIN", "SMOOTH_MAX", "ROUND", "FLOOR",
        "CEIL", "TRUNC", "FRACT", "MODULO", "FLOORED_MODULO", "SNAP", "PINGPONG", "SINE",
        "COSINE", "TANGENT", "ARCSINE", "ARCCOSINE", "ARCTANGENT", "ARCTAN2", "SINH",
        "COSH", "TANH", "RADIANS", "DEGREES", "WRAP"},
    ("ShaderNodeVectorMath", "operation"): {
        "ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "MULTIPLY_ADD", "CROSS_PRODUCT", "PROJECT",
        "REFLECT", "REFRACT", "FACEFORWARD", "DOT_PRODUCT", "DISTANCE", "LENGTH", "SCALE",
        "NORMALIZE", "SNAP", "FLOOR", "CEIL", "MODULO", "WRAP", "FRACTION", "ABSOLUTE",
        "POWER", "SIGN", "MINIMUM", "MAXIMUM", "SINE", "COSINE", "TANGENT"},
    ("ShaderNodeTexNoise", "noise_dimensions"): {"1D", "2D", "3D", "4D"},
    ("ShaderNodeTexVoronoi", "voronoi_dimensions"): {"3D"},
    ("ShaderNodeTexVoronoi", "feature"): {"F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE",
                                          "N_SPHERE_RADIUS"},
    ("ShaderNodeTexVoronoi", "distance"): {"EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI"},
    ("ShaderNodeTexGradient", "gradient_type"): {
        "LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "RADIAL", "SPHERICAL",
        "QUADRATIC_SPHERE"},
    ("ShaderNodeMapRange", "data_type"): {"FLOAT"},
    ("ShaderNodeMapRange", "interpolation_type"): {"LINEAR", "STEPPED", "SMOOTHSTEP",
                                                   "SMOOTHERSTEP"},
    ("ShaderNodeMapping", "vector_type"): {"POINT", "TEXTURE", "VECTOR", "NORMAL"},
    ("ShaderNodeVectorRotate", "rotation_type"): {"AXIS_ANGLE", "X_AXIS", "Y_AXIS", "Z_AXIS",
                                                  "EULER_XYZ"},
    ("ShaderNodeMix", "data_type"): {"FLOAT", "VECTOR", "RGBA"},
    # Read only where data_type is RGBA (_IRRELEVANT); every blend type compiles
    # (src/scene/blender_color.rs), listed to catch one a later Blender adds.
    ("ShaderNodeMix", "blend_type"): _BLEND_TYPES,
    ("ShaderNodeMixRGB", "blend_type"): _BLEND_TYPES,
    # Use Alpha scales the factor by Color2's alpha, which the overlay does not carry.
    ("ShaderNodeMixRGB", "use_alpha"): {False},
    ("ShaderNodeSeparateColor", "mode"): {"RGB", "HSV", "HSL"},
    ("ShaderNodeCombineColor", "mode"): {"RGB", "HSV", "HSL"},
}
# Properties a node's other settings make irrelevant (Blender keeps their values):
# (type, property) -> a test of the node that is true where the property is not read.
_IRRELEVANT = {
    ("ShaderNodeMix", "blend_type"): lambda node: node.data_type != "RGBA",
}
# Texture nodes whose unlinked Vector is Blender's Generated coordinates.
_TEXTURES = ("ShaderNodeTexNoise", "ShaderNodeTexVoronoi", "ShaderNodeTexGradient",
             "ShaderNodeTexWave", "ShaderNodeTexMagic")
# Cycles bakes a Color Ramp into this many intervals (RAMP_TABLE_SIZE).
_RAMP_TABLE = 256


class _Untranslatable(Exception):
    """A node tree Nimbus cannot compile; the message names the node."""


def _ident(sock):
    return re.sub(r"[^A-Za-z0-9_]", "_", sock.identifier)


def _value_line(sock, name):
    v = sock.default_value
    if sock.type in ("VALUE", "INT", "BOOLEAN"):
        return f"float inputs:{name} = {_f(v)}"
    if sock.type in ("VECTOR", "RGBA"):
        return f"float3 inputs:{name} = {_c(v)}"
    raise _Untranslatable(f"input '{sock.name}' of type {sock.type}")


def _texture_space(obj):
    """Cycles' generated coordinates of a mesh, p x scale - offset, from its texture
    space in float32 as Cycles computes them (mesh_texture_space)."""
    import numpy as np
    loc = np.array(obj.data.texspace_location, dtype=np.float32)
    size = np.array(obj.data.texspace_size, dtype=np.float32)
    half = np.float32(0.5)
    scale = np.where(size != 0, half / np.where(size != 0, size, 1), size).astype(np.float32)
    offset = (loc * scale - half).astype(np.float32)
    return scale, offset


# Inputs the reader needs constant (a texture's parameters: its range analysis and
# its octave count are fixed when the graph is compiled).
_CONSTANT_INPUTS = {
    "ShaderNodeTexNoise": ("Scale", "Detail", "Roughness", "Lacunarity", "Distortion",
                           "Offset", "Gain"),
    "ShaderNodeTexVoronoi": ("Scale", "Detail", "Roughness", "Lacunarity", "Randomness",
                             "Smoothness", "Exponent"),
    "ShaderNodeTexWave": ("Detail", "Detail Scale", "Detail Roughness"),
}


def _float_curve_lines(mapping):
    """A Float Curve as Cycles samples it (curvemapping_float_to_array): the curve at
    t = min + (i / 256) * (max - min), in float32 as Cycles computes t, with min and max
    its first and last points' x; and whether it extrapolates."""
    import numpy as np
    mapping.initialize()
    mapping.update()
    curve = mapping.curves[0]
    lo = np.float32(curve.points[0].location[0])
    hi = np.float32(curve.points[len(curve.points) - 1].location[0])
    span = np.float32(hi - lo)
    ts = [lo + np.float32(i) / np.float32(_RAMP_TABLE) * span for i in range(_RAMP_TABLE + 1)]
    table = [mapping.evaluate(curve, float(t)) for t in ts]
    return ["float[] inputs:table = [{}]".format(", ".join(_f(v) for v in table)),
            f"float inputs:min_x = {_f(float(lo))}",
            f"float inputs:max_x = {_f(float(hi))}",
            f"float inputs:extrapolate = {_f(mapping.extend == 'EXTRAPOLATED')}"]


def _curves_lines(mapping, rgb):
    """RGB Curves (`rgb`) or Vector Curves as Cycles bakes them
    (curvemapping_color_to_array): each channel's curve at t = min + (i / 256) * (max -
    min), in float32 as Cycles computes t, min and max the least first point's and the
    largest last point's x over the curves (RGB Curves' combined curve among them),
    the combined curve applied first for RGB Curves; and whether it extrapolates."""
    import numpy as np
    mapping.initialize()
    mapping.update()
    curves = list(mapping.curves)[:4 if rgb else 3]
    lo = min(np.float32(c.points[0].location[0]) for c in curves)
    hi = max(np.float32(c.points[len(c.points) - 1].location[0]) for c in curves)
    span = np.float32(hi - lo)
    ts = [lo + np.float32(i) / np.float32(_RAMP_TABLE) * span for i in range(_RAMP_TABLE + 1)]
    if rgb:
        ts = [mapping.evaluate(curves[3], float(t)) for t in ts]
    lines = []
    for channel, curve in zip(("red", "green", "blue"), curves):
        table = [mapping.evaluate(curve, float(t)) for t in ts]
        lines.append("float[] inputs:{}_table = [{}]".format(
            channel, ", ".join(_f(v) for v in table)))
    return lines + [f"float inputs:min_x = {_f(float(lo))}",
                    f"float inputs:max_x = {_f(float(hi))}",
                    f"float inputs:extrapolate = {_f(mapping.extend == 'EXTRAPOLATED')}"]


def _check_output(node, socket):
    """Raises _Untranslatable for an output the reader does not compile: Volume Info's
    Color (a colour grid; Nimbus' graphs read one float field)."""
    if node.bl_idname == "ShaderNodeVolumeInfo" and socket.identifier == "Color":
        raise _Untranslatable(f"node '{node.name}': its Color output (a colour grid)")


def _check_inputs(node):
    """Raises _Untranslatable for the input values the reader refuses: a linked input
    it needs constant (_CONSTANT_INPUTS, and a Stepped Map Range's Steps), a
    Mapping's linked Rotation (a constant one is compiled) and a Wave Texture's Detail
    beyond 0 to 15 or negative Detail Roughness."""
    def unlinked_value(name, default):
        # By identifier: a name finds only the sockets the node's type shows. A socket
        # this Blender does not have, or hides, is not written: its default.
        sock = next((s for s in node.inputs if s.identifier == name), None)
        if sock is None or not sock.enabled:
            return default
        if sock.is_linked:
            raise _Untranslatable(
                f"node '{node.name}': {name} is linked (Nimbus needs it constant)")
        return sock.default_value
    for name in _CONSTANT_INPUTS.get(node.bl_idname, ()):
        unlinked_value(name, None)
    if node.bl_idname == "ShaderNodeMapRange" and node.interpolation_type == "STEPPED":
        unlinked_value("Steps", 4.0)
    if node.bl_idname == "ShaderNodeTexWave":
        detail = unlinked_value("Detail", 2.0)
        roughness = unlinked_value("Detail Roughness", 0.5)
        if not (0.0 <= detail <= 15.0 and roughness >= 0.0):
            raise _Untranslatable(
                f"node '{node.name}': Detail {detail:g} or Detail Roughness {roughness:g} "
                "(Nimbus compiles Detail 0 to 15 and a Roughness from 0)")


def _graph(socket, obj, owner, folder_prim):
    """The node tree feeding `socket` (a linked input) as overlay prims under
    `folder_prim`: (prims, "path.outputs:name"). Raises _Untranslatable."""
    prims = {}

    def define(node):
        path = f"{folder_prim}/{prim_name(node.name)}"
        if path in prims:
            return path
        kind = node.bl_idname
        if kind not in _GRAPH_NODES:
            raise _Untranslatable(f"node '{node.name}' ({kind}) is not one Nimbus compiles")
        for prop in _GRAPH_NODES[kind]:
            allowed = _COMPILED.get((kind, prop))
            irrelevant = _IRRELEVANT.get((kind, prop), lambda _node: False)(node)
            if allowed is not None and not irrelevant and getattr(node, prop) not in allowed:
                raise _Untranslatable(
                    f"node '{node.name}': {prop} {getattr(node, prop)} is not one Nimbus "
                    "compiles")
        _check_inputs(node)
        prims[path] = None  # a cycle stops here
        lines = [f'uniform token info:id = "{kind}"']
        for prop in _GRAPH_NODES[kind]:
            v = getattr(node, prop)
            if isinstance(v, str):
                lines.append(f'uniform token inputs:{prop} = "{v}"')
            else:
                lines.append(f"float inputs:{prop} = {_f(v)}")
        if kind == "ShaderNodeValToRGB":
            ramp = node.color_ramp
            # Cycles bakes every mode (RGB, HSV, HSL; Linear, Ease, B-Spline, Cardinal,
            # Constant) through the same ColorRamp.evaluate at i/256 and reads the table
            # linearly unless Constant: so does Nimbus.
            rows = [ramp.evaluate(i / _RAMP_TABLE) for i in range(_RAMP_TABLE + 1)]
            for k, channel in enumerate(("red", "green", "blue", "alpha")):
                lines.append("float[] inputs:{}_table = [{}]".format(
                    channel, ", ".join(_f(row[k]) for row in rows)))
            lines.append(f"float inputs:interpolate = {_f(ramp.interpolation != 'CONSTANT')}")
        if kind == "ShaderNodeFloatCurve":
            lines += _float_curve_lines(node.mapping)
        if kind in ("ShaderNodeRGBCurve", "ShaderNodeVectorCurve"):
            lines += _curves_lines(node.mapping, kind == "ShaderNodeRGBCurve")
        if kind == "ShaderNodeValue":
            lines.append(f"float inputs:value = {_f(node.outputs[0].default_value)}")
        if kind == "ShaderNodeVolumeInfo" and obj.type != "VOLUME":
            raise _Untranslatable(
                f"node '{node.name}': Volume Info in a fog's density (Cycles reads it as 0)")
        if kind == "ShaderNodeAttribute" and obj.type != "VOLUME":
            raise _Untranslatable(
                f"node '{node.name}': an Attribute in a fog's density (Cycles reads it as 0)")
        if kind == "ShaderNodeAttribute" and node.attribute_type != "GEOMETRY":
            raise _Untranslatable(f"node '{node.name}': attribute type {node.attribute_type}")
        for sock in node.inputs:
            if not sock.enabled:
                continue
            name = _ident(sock)
            link = sock.links[0] if sock.is_linked and sock.links else None
            if link is not None and not link.is_muted:
                src = link.from_node
                while src.bl_idname == "NodeReroute":
                    if not src.inputs[0].is_linked:
                        raise _Untranslatable(f"reroute '{src.name}' is not linked")
                    link = src.inputs[0].links[0]
                    src = link.from_node
                _check_output(src, link.from_socket)
                up = f"{define(src)}.outputs:{_ident(link.from_socket)}"
                kind_line = "float3" if link.from_socket.type in ("VECTOR", "RGBA") else "float"
                if link.from_socket.type == "RGBA" and sock.type == "VALUE":
                    up, kind_line = to_bw(up), "float"
                lines.append(f"{kind_line} inputs:{name}.connect = <{up}>")
            elif kind in _TEXTURES and name == "Vector":
                lines.append(f"float3 inputs:Vector.connect = <{generated()}.outputs:Generated>")
            elif sock.type in ("VALUE", "INT", "BOOLEAN", "VECTOR", "RGBA"):
                lines.append(_value_line(sock, name))
        if kind == "ShaderNodeTexCoord" and obj.type in ("MESH", "VOLUME"):
            lines += generated_lines()
        prims[path] = ([], lines, "def Shader")
        return path

    def generated_lines():
        if obj.type == "VOLUME":
            # Cycles gives a Volume object no texture space: its Generated coordinates
            # are the object-space position (measured: bpy 5.0.1's Cycles renders a
            # smoke VDB's noise on Generated and on Object to the same pixels).
            return ["float3 inputs:generated_scale = (1.0, 1.0, 1.0)",
                    "float3 inputs:generated_offset = (0.0, 0.0, 0.0)"]
        if obj.type != "MESH":
            raise _Untranslatable(f"Generated texture coordinates of a {obj.type} object")
        scale, offset = _texture_space(obj)
        return [f"float3 inputs:generated_scale = {_c(scale)}",
                f"float3 inputs:generated_offset = {_c(offset)}"]

    def to_bw(output):
        """A colour linked into a float socket: Cycles converts it by its luminance,
        what an RGB to BW node computes; the overlay writes that node."""
        path = output.split(".outputs:")[0] + "_" + output.split(".outputs:")[1] + "_bw"
        prims[path] = ([], ['uniform token info:id = "ShaderNodeRGBToBW"',
                            f"float3 inputs:Color.connect = <{output}>"], "def Shader")
        return f"{path}.outputs:Val"

    def generated():
        path = f"{folder_prim}/nimbus_generated"
        if path not in prims:
            prims[path] = ([], ['uniform token info:id = "ShaderNodeTexCoord"']
                           + generated_lines(), "def Shader")
        return path

    link = socket.links[0]
    src, out = link.from_node, link.from_socket
    while src.bl_idname == "NodeReroute":
        link = src.inputs[0].links[0]
        src, out = link.from_node, link.from_socket
    if out.type not in ("VALUE", "RGBA", "VECTOR"):
        raise _Untranslatable(f"output '{out.name}' of node '{src.name}'")
    _check_output(src, out)
    output = f"{define(src)}.outputs:{_ident(out)}"
    if out.type == "RGBA" and socket.type == "VALUE":
        output = to_bw(output)
    return prims, output


# What a fog (no grids) is called in warnings, by its kind.
_FOG_NAMES = {"mesh": "a fog mesh", "world": "the world volume"}


def _density(node, sock_name, owner, warnings, default_attribute, fog=None, medium=None,
             graph=None):
    """A closure's Density input: a number (the grid `default_attribute` times it for
    Principled Volume; Cycles fills the whole volume for the others), or an Attribute
    node (optionally times a number by a Math node). Returns (number, attribute).

    `fog` ("mesh" or "world"; None for a Volume object): there are no grids, and
    Cycles reads an attribute the mesh or world does not have as 0 (svm_node_attr_init):
    an Attribute node is a warning and the input is 0 (the closure is left out).

    Any other node tree is compiled by Nimbus when `graph` = (object, overlay folder)
    is given and `medium` has no density graph yet: it becomes `medium.density_graph`
    and the number is 1."""
    sock = node.inputs[sock_name]
    src = _linked(sock)
    if src is None:
        # Cycles clamps a negative density (and strength) at 0.
        return max(float(sock.default_value), 0.0), default_attribute
    scale = 1.0
    if src.bl_idname == "ShaderNodeMath" and src.operation == "MULTIPLY":
        a, b = src.inputs[0], src.inputs[1]
        na, nb = _linked(a), _linked(b)
        if na is not None and nb is None:
            src, scale = na, float(b.default_value)
        elif nb is not None and na is None:
            src, scale = nb, float(a.default_value)
    if src.bl_idname == "ShaderNodeAttribute" and src.attribute_name:
        if fog is not None:
            warnings.append(
                f"{owner}: node '{src.name}' (Attribute '{src.attribute_name}') drives "
                f"'{node.name}'.{sock_name}: {_FOG_NAMES[fog]} has no grids (Cycles reads "
                "an attribute it lacks as 0); left out")
            return 0.0, None
        return scale, src.attribute_name
    graph_ok = graph is not None and medium is not None and fog != "world"
    if graph_ok and medium.density_graph is None:
        try:
            medium.density_graph = _graph(sock, graph[0], owner, graph[1])
            return 1.0, default_attribute
        except _Untranslatable as e:
            reason = f"{e}"
    elif graph_ok:
        reason = "a second density graph (Nimbus reads one per medium)"
    elif fog == "world":
        reason = "a density graph on the world volume is not read"
    else:
        reason = "not translated"
    warnings.append(
        f"{owner}: node '{src.name}' ({src.bl_idname}) drives "
        f"'{node.name}'.{sock_name}: {reason}; Nimbus uses {sock.default_value!r}")
    return float(sock.default_value), default_attribute


def _emission_color_graph(node, owner, medium, warnings, graph):
    """A node tree linked into Principled Volume's Emission Color: compiled by Nimbus
    (`medium.emission_graph`, the colour then replaced by white) when `graph` is given
    and it translates; else a warning, and the socket's colour."""
    sock = node.inputs["Emission Color"]
    src = _linked(sock)
    if src is None:
        return
    reason = "not translated here (a world volume)"
    if graph is not None:
        try:
            medium.emission_graph = _graph(sock, graph[0], owner, graph[1])
            color, strength, field = medium.emission
            medium.emission = ((1.0, 1.0, 1.0), strength, field)
            return
        except _Untranslatable as e:
            reason = f"{e}"
    warnings.append(
        f"{owner}: node '{src.name}' ({src.bl_idname}) drives '{node.name}'.Emission Color: "
        f"{reason}; Nimbus uses the socket's colour")


def _albedo_graph(node, owner, medium, warnings, graph):
    """A node tree linked into Principled Volume's Color, compiled by Nimbus as an
    albedo multiplier (`medium.albedo_graph`, nimbus:albedo) when it translates and
    Cycles' coefficients are those of one: Absorption Color black and unlinked (then
    sigma_s + sigma_a = Density, whatever the colour, as nimbus:albedo keeps it) and no
    emission (whose source needs the absorption the multiplier moves). Returns whether
    it was; the caller warns otherwise, and uses the socket's colour."""
    sock = node.inputs["Color"]
    src = _linked(sock)
    if src is None:
        return False
    absorption = node.inputs["Absorption Color"]
    emits = (float(node.inputs["Emission Strength"].default_value) > 0
             or float(node.inputs["Blackbody Intensity"].default_value) > 0
             or _linked(node.inputs["Emission Strength"]) is not None)
    if graph is None:
        reason = "not translated here (a world volume)"
    elif medium.albedo_graph is not None:
        reason = "a second Color graph in one medium is not translated"
    elif _linked(absorption) is not None or max(_socket_value(absorption)[:3]) > 0:
        reason = ("translated only with Absorption Color black (then the extinction "
                  "does not depend on the colour)")
    elif emits:
        reason = "translated only in a medium that does not emit"
    else:
        try:
            medium.albedo_graph = _graph(sock, graph[0], owner, graph[1])
            return True
        except _Untranslatable as e:
            reason = f"{e}"
    warnings.append(
        f"{owner}: node '{src.name}' ({src.bl_idname}) drives '{node.name}'.Color: "
        f"{reason}; Nimbus uses the socket's colour")
    return False


def _closure(node, owner, medium, warnings, weight=1.0, fog=None, graph=None):
    """Adds the volume closure `node` (Cycles' meaning) to `medium`. `owner` names the
    node tree in warnings ("material 'M'", "world 'W'"); `fog` as in _density."""
    kind = node.bl_idname
    if kind == "ShaderNodeAddShader":
        for sock in node.inputs:
            n = _linked(sock)
            if n is not None:
                _closure(n, owner, medium, warnings, weight, fog, graph)
        return
    if kind == "ShaderNodeVolumePrincipled":
        # svm_node_principled_volume: sigma_s = C D d(x),
        # sigma_a = max(1 - C, 0) max(1 - sqrt(A), 0) D d(x); without the attribute
        # (a mesh, the world) d = 1.
        attr = None if fog else (node.inputs["Density Attribute"].default_value or "density")
        d, attr = _density(node, "Density", owner, warnings, attr, fog, medium, graph)
        c = [max(x, 0.0) for x in _socket_value(node.inputs["Color"])]
        a = [max(x, 0.0) for x in _socket_value(node.inputs["Absorption Color"])]
        g = float(node.inputs["Anisotropy"].default_value)
        s = [weight * d * x for x in c]
        ab = [weight * d * max(1.0 - x, 0.0) * max(1.0 - math.sqrt(y), 0.0) for x, y in zip(c, a)]
        if _albedo_graph(node, owner, medium, warnings, graph if fog != "world" else None):
            # Color is the graph's multiplier c(x) of white: sigma_s = c D d and
            # sigma_a = (1 - c) D d, so the medium is white scattering D d.
            white = [weight * d] * 3
            medium.albedo_undo = ([x - y for x, y in zip(s, white)], ab)
            s, ab = white, [0.0, 0.0, 0.0]
        medium.add(s, ab, g)
        medium.density_attribute = medium.density_attribute or attr
        if node.inputs["Color Attribute"].default_value and not fog:
            warnings.append(
                f"{owner}: '{node.name}'.Color Attribute "
                f"'{node.inputs['Color Attribute'].default_value}' is not translated; "
                "Nimbus uses Color")
        for linked in ("Color", "Absorption Color", "Anisotropy"):
            n = _linked(node.inputs[linked])
            if n is not None and linked != "Color":
                warnings.append(
                    f"{owner}: node '{n.name}' drives '{node.name}'."
                    f"{linked}: not translated; Nimbus uses the socket's value")
        # Emission Strength is a plain input (not times the density): a number is a
        # constant source, an Attribute node (optionally times a number) its grid.
        strength, field = _density(node, "Emission Strength", owner, warnings, None, fog)
        if strength > 0:
            medium.emission = (_socket_value(node.inputs["Emission Color"]),
                               weight * strength, field)
            _emission_color_graph(node, owner, medium, warnings, graph if fog != "world" else None)
        bb = float(node.inputs["Blackbody Intensity"].default_value)
        if bb > 0 and fog:
            temperature = float(node.inputs["Temperature"].default_value)
            warnings.append(
                f"{owner}: '{node.name}'.Blackbody Intensity {bb:g}: Cycles renders the "
                f"blackbody of Temperature {temperature:g} K in {_FOG_NAMES[fog]}; Nimbus' "
                "blackbody needs a temperature grid; left out")
        elif bb > 0:
            tint = [1.0, 1.0, 1.0]
            if "Blackbody Tint" in node.inputs:
                tint = list(_socket_value(node.inputs["Blackbody Tint"]))[:3]
            medium.blackbody = (
                weight * bb,
                float(node.inputs["Temperature"].default_value),
                node.inputs["Temperature Attribute"].default_value or "temperature",
                tint,
            )
        return
    if kind == "ShaderNodeVolumeScatter":
        phase = getattr(node, "phase", "HENYEY_GREENSTEIN")
        if phase != "HENYEY_GREENSTEIN":
            warnings.append(
                f"{owner}: node '{node.name}' uses the {phase} phase "
                "function; Nimbus renders Henyey-Greenstein with its Anisotropy")
        d, attr = _density(node, "Density", owner, warnings, None, fog, medium,
                           graph if fog else None)
        c = [max(x, 0.0) for x in _socket_value(node.inputs["Color"])]
        medium.add([weight * d * x for x in c], [0.0, 0.0, 0.0],
                   float(node.inputs["Anisotropy"].default_value))
        medium.density_attribute = medium.density_attribute or attr
        return
    if kind == "ShaderNodeVolumeAbsorption":
        d, attr = _density(node, "Density", owner, warnings, None, fog, medium,
                           graph if fog else None)
        c = [max(x, 0.0) for x in _socket_value(node.inputs["Color"])]
        medium.add([0.0, 0.0, 0.0], [weight * d * max(1.0 - x, 0.0) for x in c])
        medium.density_attribute = medium.density_attribute or attr
        return
    if kind == "ShaderNodeEmission":
        medium.emission = (_socket_value(node.inputs["Color"]),
                           weight * float(node.inputs["Strength"].default_value), None)
        return
    warnings.append(
        f"{owner}: node '{node.name}' ({kind}) is not a volume shader "
        "Nimbus translates (Principled Volume, Volume Scatter, Volume Absorption, Emission, "
        "Add Shader); left out")


def _medium_attrs(medium, who, warnings, density_field=None):
    """The NimbusVolumeAPI attributes of `medium` and its single-scattering albedo.
    `who` names the object or world in warnings; `density_field` the density grid
    (None for a fog: density 1, coefficients per world unit)."""
    if medium.albedo_graph is not None and (
            len(medium.anisotropy) > 1 or medium.emission is not None
            or medium.blackbody is not None):
        # The multiplier would scale every closure's scattering, and an emission
        # source needs the absorption it moves: the socket's colour instead.
        ds, da = medium.albedo_undo
        medium.sigma_s = [a + b for a, b in zip(medium.sigma_s, ds)]
        medium.sigma_a = [a + b for a, b in zip(medium.sigma_a, da)]
        medium.albedo_graph = None
        warnings.append(
            f"{who}: a node tree drives Principled Volume's Color beside another "
            "scattering or emitting closure: not translated; Nimbus uses the socket's "
            "colour")
    # Nimbus' coefficients are per unit of density x densityScale: factor out the
    # largest so the colours stay in a readable range.
    scale = max(max(medium.sigma_s), max(medium.sigma_a), 1e-30)
    g = 0.0
    if medium.anisotropy:
        w = sum(x for x, _ in medium.anisotropy)
        g = sum(x * y for x, y in medium.anisotropy) / w
    attrs = {}
    if density_field is not None:
        attrs["token nimbus:densityField"] = f'"{density_field}"'
    if medium.density_graph is not None:
        # The density is the graph's value (times the grid): the graph times `scale`
        # drives nimbus:densityScale (src/scene/blender_graph.rs).
        graph_prims, output = medium.density_graph
        folder = output.rsplit("/", 1)[0]
        node = f"{folder}/nimbus_density_scale"
        graph_prims[node] = ([], [
            'uniform token info:id = "ShaderNodeMath"',
            'uniform token inputs:operation = "MULTIPLY"',
            f"float inputs:Value.connect = <{output}>",
            f"float inputs:Value_001 = {_f(scale)}",
        ], "def Shader")
        attrs["float nimbus:densityScale.connect"] = f"<{node}.outputs:Value>"
    else:
        attrs["float nimbus:densityScale"] = _f(scale)
    if medium.albedo_graph is not None:
        attrs["color3f nimbus:albedo.connect"] = f"<{medium.albedo_graph[1]}>"
    attrs.update({
        "color3f nimbus:scattering": _c([x / scale for x in medium.sigma_s]),
        "color3f nimbus:absorption": _c([x / scale for x in medium.sigma_a]),
        "float nimbus:anisotropy": _f(g),
    })
    # Cycles (svm_node_principled_volume, the Emission closure) emits Strength x Color
    # (and the blackbody) per unit length wherever the shader runs, whatever the
    # density: Nimbus' emissionKind "source" means exactly that (docs/usd.md), S/mu_a
    # collected at absorption events. Without an emission field the source is constant.
    if medium.emission is not None or medium.blackbody is not None:
        attrs["uniform token nimbus:emissionKind"] = '"source"'
        color, strength, field = medium.emission or ((0.0, 0.0, 0.0), 0.0, None)
        source = [strength * max(c, 0.0) for c in list(color)[:3]]
        if any(c > 0 and a <= 0 for c, a in zip(source, medium.sigma_a)):
            warnings.append(
                f"{who}: emission in a channel without absorption: Nimbus "
                "collects emission where the medium absorbs (docs/usd.md, Emission), so "
                "that channel emits nothing")
        k = max(source)
        if field is not None:
            attrs["token nimbus:emissionField"] = f'"{field}"'
        if medium.emission_graph is not None:
            # The colour graph times emissionScale (the strength): source is white.
            attrs["color3f nimbus:emissionColor.connect"] = f"<{medium.emission_graph[1]}>"
        else:
            attrs["color3f nimbus:emissionColor"] = _c(
                [c / k for c in source] if k > 0 else [1.0, 1.0, 1.0])
        # 0 turns the constant field off (blackbody only).
        attrs["float nimbus:emissionScale"] = _f(k)
    if medium.blackbody is not None:
        intensity, temperature, attribute, tint = medium.blackbody
        if max(tint) != min(tint):
            warnings.append(
                f"{who}: Blackbody Tint {tuple(tint)} is not grey: Nimbus' "
                "blackbody has no tint; it uses the mean")
        intensity *= sum(tint) / 3.0
        # Cycles: sigma_SB 1e-6 / pi T^4; Nimbus: intensity (T / 1000 K)^4.
        cycles_1000k = 5.670373e-8 * 1e-6 / math.pi * 1e12
        attrs["token nimbus:temperatureField"] = f'"{attribute}"'
        attrs["float nimbus:temperatureScale"] = _f(temperature)
        attrs["float nimbus:blackbodyIntensity"] = _f(intensity * cycles_1000k)
    st = [a + b for a, b in zip(medium.sigma_s, medium.sigma_a)]
    albedo = tuple(s / t if t > 0 else 0.0 for s, t in zip(medium.sigma_s, st))
    return attrs, albedo


def _graph_target(obj, prims):
    """Where `obj`'s density node tree goes in the overlay (None: not translated)."""
    return None if prims is None else (obj, f"{GRAPHS}/{prim_name(obj.name)}")


def _add_graph(medium, prims):
    """Adds the overlay prims of `medium`'s node trees (density, emission colour) to
    `prims`."""
    for graph in (medium.density_graph, medium.emission_graph, medium.albedo_graph):
        if graph is None:
            continue
        graph_prims, output = graph
        prims[GRAPHS] = ([], [], "def Scope")
        prims[output.rsplit("/", 1)[0]] = ([], [], "def Scope")
        prims.update(graph_prims)


def volume_medium(obj, warnings, prims=None):
    """The NimbusVolumeAPI attributes of a Volume object's material, and its albedo.
    With `prims` (the overlay's), a node tree driving the Density is translated there."""
    material = obj.active_material
    if material is None:
        # An evaluated instance (Geometry Nodes' Set Material) has no active material
        # but its slots: Cycles shades a volume with its first.
        material = next((s.material for s in obj.material_slots if s.material), None)
    medium = _Medium()
    if material is None or not material.node_tree:
        # Cycles' default volume shader: a Principled Volume with its defaults.
        medium.add([0.5] * 3, [0.5 * (1.0 - 0.0)] * 3, 0.0)
        medium.density_attribute = "density"
    else:
        src = material_outputs(material)[1]
        if src is None:
            raise TranslationError(
                f"object '{obj.name}': material '{material.name}' has no volume shader "
                "connected to its Material Output's Volume input")
        _closure(src, f"material '{material.name}'", medium, warnings,
                 graph=_graph_target(obj, prims))
    if medium.density_attribute is None:
        warnings.append(
            f"object '{obj.name}': the density of material "
            f"'{material.name if material else ''}' is a constant (Cycles fills the volume's "
            "active voxels with it); Nimbus uses the grid 'density' times it")
        medium.density_attribute = "density"
    result = _medium_attrs(medium, f"object '{obj.name}'", warnings, medium.density_attribute)
    _add_graph(medium, prims)
    return result


def fog_mesh_medium(obj, warnings, prims=None):
    """A mesh whose material has a Volume output link is a fog mesh (docs/blender.md:
    Cycles fills its inside with Density x 1): (material, NimbusVolumeAPI attributes
    without fields, albedo), or None when no material of the evaluated mesh has one."""
    materials = [s.material for s in obj.material_slots if s.material is not None]
    fogs = [m for m in materials if material_outputs(m)[1] is not None]
    if not fogs:
        return None
    material = fogs[0]
    if len({m.name for m in materials}) > 1:
        warnings.append(
            f"object '{obj.name}': several materials; Nimbus fills the whole mesh with the "
            f"volume of material '{material.name}' (Cycles: each material's volume inside "
            "the faces it is on)")
    surface, src = material_outputs(material)
    if surface is not None:
        warnings.append(
            f"object '{obj.name}': material '{material.name}' has a Surface shader "
            f"('{surface.name}') besides its Volume: Nimbus renders the fog only, the "
            "surface is not rendered (Cycles draws the surface, and shows the fog inside "
            "only through a transmitting or transparent surface)")
    medium = _Medium()
    _closure(src, f"material '{material.name}'", medium, warnings, fog="mesh",
             graph=_graph_target(obj, prims))
    attrs, albedo = _medium_attrs(medium, f"object '{obj.name}'", warnings)
    _add_graph(medium, prims)
    return material, attrs, albedo


def world_fog_medium(world, warnings):
    """The world's Volume output as a homogeneous fog filling the world: (NimbusVolumeAPI
    attributes without fields, albedo), or None without a Volume link."""
    src = world_volume_node(world)
    if src is None:
        return None
    medium = _Medium()
    _closure(src, f"world '{world.name}'", medium, warnings, fog="world")
    return _medium_attrs(medium, f"world '{world.name}'", warnings)


def _f(x):
    return repr(float(x))


def _c(v):
    return "({}, {}, {})".format(*(repr(float(x)) for x in list(v)[:3]))


# ---- lights and world ----------------------------------------------------------------


def _medium_lines(obj, attrs, groups, used):
    """The overlay lines of a medium's NimbusVolumeAPI attributes, with the object's
    light group when some source uses it (recorded in `used`)."""
    lines = [f"{k} = {v}" for k, v in attrs.items()]
    group = getattr(obj, "lightgroup", "")
    if group and group in groups:
        lines.append(f'token nimbus:lightGroup = "{_group_token(group)}"')
        used.add(group)
    return lines


def _group_token(name):
    if "'" in name or '"' in name or "\\" in name:
        raise TranslationError(f"light group '{name}': quotes and backslashes are not allowed")
    return name


def light_lines(obj, warnings):
    """Attributes restoring a light's Blender values over the export (docs/blender.md)."""
    light = obj.data
    lines = []
    if not light.use_temperature:
        lines.append("bool inputs:enableColorTemperature = 0")
    if light.type == "SUN":
        lines.append(f"float inputs:intensity = {_f(light.energy)}")
        lines.append(f"float inputs:angle = {_f(math.degrees(light.angle))}")
    if light.type in ("POINT", "SPOT") and getattr(light, "use_soft_falloff", False):
        warnings.append(
            f"light '{obj.name}': Soft Falloff is on; Nimbus renders a true sphere light "
            "(turn it off to match Cycles)")
    elif light.type in ("POINT", "SPOT") and light.shadow_soft_size > 0:
        # Cycles' sphere lights what lies inside it (smoke around a fire's bulb) with
        # its radiance from every direction; UsdLux's sphere emits outwards only.
        lines.append("bool nimbus:lightsInterior = 1")
    if light.type == "SPOT" and light.spot_blend > 0:
        warnings.append(
            f"light '{obj.name}': spot blend {light.spot_blend:.2f}: UsdLux's cone softness "
            "fades by a different curve than Cycles' blend (docs/blender.md)")
    if light.type == "AREA" and light.shape in ("ELLIPSE", "RECTANGLE") and \
            light.shape == "ELLIPSE" and abs(light.size - light.size_y) > 1e-6:
        warnings.append(
            f"light '{obj.name}': an ellipse is exported as a disk of the mean radius")
    return lines


def _world_background(world):
    """The Background node feeding the active World Output's Surface, or None."""
    out = _active_output(world.node_tree, "ShaderNodeOutputWorld")
    src = _linked(out.inputs["Surface"]) if out is not None else None
    return src if src is not None and src.bl_idname == "ShaderNodeBackground" else None


def hdri_lines(world, warnings):
    """The dome of an Environment Texture world: the exporter writes its image but not
    the Background's Strength (the dome rendered at intensity 1)."""
    lines = ["float3 xformOp:rotateXYZ = (90, 0, 90)"]
    bg = _world_background(world)
    if bg is None:
        warnings.append(f"world '{world.name}': no Background node at the World Output; "
                        "the dome's intensity is 1")
        return lines
    strength = bg.inputs["Strength"]
    if strength.is_linked:
        warnings.append(f"world '{world.name}': Background Strength is driven by a node; "
                        f"Nimbus uses {strength.default_value!r}")
    lines.append(f"float inputs:intensity = {_f(strength.default_value)}")
    env = _linked(bg.inputs["Color"])
    if env is not None and env.bl_idname == "ShaderNodeTexEnvironment":
        if env.inputs["Vector"].is_linked:
            warnings.append(f"world '{world.name}': the Environment Texture's Vector input "
                            "(a mapping) is not translated")
    elif env is not None:
        warnings.append(f"world '{world.name}': node '{env.name}' between the Environment "
                        "Texture and the Background is not translated")
    return lines


def _world_is_hdri(world):
    if world is None or not world.node_tree:
        return False
    return any(n.bl_idname == "ShaderNodeTexEnvironment" and n.image is not None
               for n in world.node_tree.nodes)


# ---- the overlay -----------------------------------------------------------------------


# In place of a prim's api schemas in write_overlay: deactivate the prim.
INACTIVE = ["<inactive>"]


def exported_prims(text, type_name):
    """Paths of the prims of `type_name` defined in the exporter's usda `text` (its
    layout: one `def Type "name"` a line, nested by four spaces a level)."""
    stack, found = [], []
    for m in re.finditer(r'^( *)def (\w+) "([^"]+)"', text, re.M):
        depth = len(m.group(1)) // 4
        del stack[depth:]
        stack.append(m.group(3))
        if m.group(2) == type_name:
            found.append("/" + "/".join(stack))
    return found


def write_overlay(path, exported, prims, metadata=()):
    """`prims`: prim path -> (api schemas, attribute lines[, specifier]). An overlay
    layer that sublayers Blender's export and `over`s those prims, or defines them
    with the specifier given (e.g. "def Volume"); a defined prim's parents must be
    defined too (an `over` alone is not rendered). `metadata`: more layer metadata
    lines (e.g. "timeCodesPerSecond = 24")."""
    tree = {}
    for prim, content in prims.items():
        node = tree
        for name in prim.strip("/").split("/"):
            node = node.setdefault(name, {})
        node[None] = content

    def emit(node, indent):
        text = ""
        for name, child in node.items():
            if name is None:
                continue
            schemas, lines, *spec = child.get(None, ([], []))
            spec = spec[0] if spec else "over"
            meta = ""
            if schemas == INACTIVE:
                meta = " (\n{0}    active = false\n{0})".format(indent)
            elif schemas:
                listed = ", ".join(f'"{s}"' for s in schemas)
                meta = f" (\n{indent}    prepend apiSchemas = [{listed}]\n{indent})"
            text += f'{indent}{spec} "{name}"{meta}\n{indent}{{\n'
            text += "".join(f"{indent}    {line}\n" for line in lines)
            text += emit(child, indent + "    ")
            text += f"{indent}}}\n"
        return text

    with open(path, "w") as f:
        header = "".join(f"    {line}\n" for line in metadata)
        f.write(f"#usda 1.0\n(\n{header}    subLayers = [@./{exported}@]\n)\n\n"
                + emit(tree, ""))


def render_size(scene):
    r = scene.render
    pct = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * pct)), max(1, int(r.resolution_y * pct))


def border_region(scene, width, height):
    """Blender's border (fractions from the bottom left) as Nimbus' region (pixels,
    rows from the top, x1 and y1 exclusive), or None."""
    r = scene.render
    if not r.use_border:
        return None
    x0 = int(round(r.border_min_x * width))
    x1 = int(round(r.border_max_x * width))
    y0 = height - int(round(r.border_max_y * height))
    y1 = height - int(round(r.border_min_y * height))
    if x0 >= x1 or y0 >= y1 or (x0, y0, x1, y1) == (0, 0, width, height):
        return None
    return (x0, y0, x1, y1)


def check_volumes(depsgraph):
    """Every volume's grids load (a missing or unreadable VDB is an error naming the
    object, before anything is exported)."""
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != "VOLUME":
            continue
        grids = obj.data.grids
        if obj.data.is_sequence and grids.frame_filepath == "":
            # A sequence with no file at this frame (its mode leaves it out here):
            # Blender renders nothing of it, and neither does the export.
            continue
        ok = grids.load()
        if not ok or grids.error_message:
            path = grids.frame_filepath or obj.data.filepath
            raise TranslationError(
                f"volume '{obj.name}': cannot read '{bpy.path.abspath(path)}': "
                f"{grids.error_message or 'no grids'}")
        if len(grids) == 0:
            raise TranslationError(f"volume '{obj.name}': the volume has no grids")


def is_generated(obj):
    """The evaluated volume `obj`'s grids were made in memory (Geometry Nodes, a volume
    modifier) rather than read unchanged from a file."""
    if not obj.data.grids.frame_filepath:
        return True
    return any(m.show_render for m in obj.original.modifiers)


def volume_file(obj, folder, name):
    """A VDB holding the evaluated grids of `obj`: its own file when unchanged, else
    the grids written by Blender (VolumeGrids.save) into `folder`."""
    grids = obj.data.grids
    if not is_generated(obj):
        return bpy.path.abspath(grids.frame_filepath)
    os.makedirs(os.path.join(folder, GENERATED_VDBS), exist_ok=True)
    path = os.path.join(folder, GENERATED_VDBS, name + ".vdb")
    grids.load()
    if not grids.save(path) or not os.path.isfile(path):
        raise TranslationError(f"volume '{obj.name}': cannot write its grids to '{path}'")
    return path


def _matrix(m):
    """Blender's matrix_world (column vectors) as USD's matrix4d (row vectors)."""
    rows = ", ".join("(" + ", ".join(repr(float(m[r][c])) for r in range(4)) + ")"
                     for c in range(4))
    return f"matrix4d xformOp:transform = ({rows})"


def ortho_camera_lines(cam, width, height):
    """An orthographic Blender camera as a UsdGeomCamera: Blender's view plane
    (BKE_camera_params_compute_viewplane: the fitted dimension spans ortho_scale, the
    shift is in units of it) as apertures and offsets in tenths of a unit."""
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if width >= height else "VERTICAL"
    viewfac = width if fit == "HORIZONTAL" else height
    pixel = cam.ortho_scale / viewfac
    return [
        'token projection = "orthographic"',
        f"float horizontalAperture = {_f(10 * pixel * width)}",
        f"float verticalAperture = {_f(10 * pixel * height)}",
        f"float horizontalApertureOffset = {_f(10 * cam.shift_x * cam.ortho_scale)}",
        f"float verticalApertureOffset = {_f(10 * cam.shift_y * cam.ortho_scale)}",
        f"float2 clippingRange = ({_f(cam.clip_start)}, {_f(cam.clip_end)})",
    ]


def _curves_tubes(curves, sides=6):
    """Hair curves (a Curves object) as the tubes Cycles renders: `sides`-gon prisms of
    each point's radius along each segment. Returns (points, counts, indices)."""
    import numpy as np

    n = len(curves.points)
    pos = np.empty(n * 3, np.float32)
    curves.points.foreach_get("position", pos)
    pos = pos.reshape(n, 3).astype(np.float64)
    rad = np.empty(n, np.float32)
    curves.points.foreach_get("radius", rad)
    offsets = np.empty(len(curves.curves) + 1, np.int32)
    curves.curve_offset_data.foreach_get("value", offsets)
    angles = np.linspace(0.0, 2 * math.pi, sides, endpoint=False)
    points, counts, indices = [], [], []
    for c in range(len(curves.curves)):
        p = pos[offsets[c]:offsets[c + 1]]
        r = rad[offsets[c]:offsets[c + 1]]
        if len(p) < 2:
            continue
        # Per point: the ring around the tangent (central differences).
        t = np.gradient(p, axis=0)
        t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
        base = len(points)
        for i in range(len(p)):
            a = np.array([1.0, 0.0, 0.0]) if abs(t[i][0]) < 0.9 else np.array([0.0, 1.0, 0.0])
            u = np.cross(t[i], a)
            u /= np.linalg.norm(u)
            v = np.cross(t[i], u)
            for ang in angles:
                points.append(p[i] + r[i] * (math.cos(ang) * u + math.sin(ang) * v))
        for i in range(len(p) - 1):
            for k in range(sides):
                k1 = (k + 1) % sides
                a0, a1 = base + i * sides + k, base + i * sides + k1
                b0, b1 = a0 + sides, a1 + sides
                counts.append(4)
                indices += [a0, a1, b1, b0]
    return points, counts, indices


def holdout_mesh(obj, matrix, prims, warnings):
    """Defines the evaluated curve, text or surface `obj` as a holdout mesh (the
    exporter's meshes leave them out): Object.to_mesh's polygons (a curve's bevel or
    extrusion), or a hair Curves object's tubes; nothing when it has no surface."""
    if obj.type == "CURVES":
        points, counts, indices = _curves_tubes(obj.data)
    else:
        mesh = obj.to_mesh()
        try:
            points = [v.co[:] for v in mesh.vertices]
            counts = [len(p.vertices) for p in mesh.polygons]
            indices = [i for p in mesh.polygons for i in p.vertices]
        finally:
            obj.to_mesh_clear()
    if not counts:
        warnings.append(f"object '{obj.name}': a curve without a surface (no bevel, "
                        "extrusion or radius) holds nothing out")
        return
    xf = f"{HOLDOUTS}/{prim_name(obj.name)}"
    prims[HOLDOUTS] = ([], [], "def Xform")
    prims[xf] = ([], [_matrix(matrix), 'uniform token[] xformOpOrder = ["xformOp:transform"]'],
                 "def Xform")
    pts = ", ".join("({}, {}, {})".format(*(repr(float(x)) for x in p)) for p in points)
    prims[xf + "/mesh"] = ([], [
        f"int[] faceVertexCounts = [{', '.join(map(str, counts))}]",
        f"int[] faceVertexIndices = [{', '.join(map(str, indices))}]",
        f"point3f[] points = [{pts}]",
    ], "def Mesh")


# ---- motion blur (issue 45) -----------------------------------------------------------

# The xformOp the overlay writes an object's motion in (it replaces the exporter's ops).
MOTION_OP = "xformOp:transform:nimbus_motion"


@dataclass
class Shutter:
    """Blender's Motion Blur as Cycles reads it (intern/cycles/blender/camera.cpp,
    object.cpp's sync_motion): the shutter lasts `length` frames and, by Position,
    starts on the frame (START: [F, F + length]), is centred on it (CENTER) or ends on
    it (END: [F - length, F]), F = frame_current + subframe. `open`, `close`: its ends
    relative to F, in frames (= the overlay's time codes: camera shutter:open/close)."""

    frame: float
    length: float
    position: str
    open: float
    close: float
    fps: float

    @property
    def middle(self):
        return self.frame + 0.5 * (self.open + self.close)

    def step_times(self, steps):
        """Cycles' motion step times of an object with `steps` steps (object_motion_steps:
        2^motion_steps + 1, evenly over the shutter, the middle one at its middle; 0:
        not blurred, synced once at the shutter's middle)."""
        if steps < 2:
            return [self.middle]
        # As Cycles: the middle plus relative times -1 .. 1 of half the shutter (the
        # middle step exactly the middle).
        return [self.middle + (2.0 * k / (steps - 1) - 1.0) * 0.5 * self.length
                for k in range(steps)]


def motion_blur(scene, view_layer):
    """The scene's Shutter, or None when motion blur is off (Render > Motion Blur, and
    the view layer's Use Motion Blur, as Cycles' integrator reads both)."""
    r = scene.render
    if not (r.use_motion_blur and getattr(view_layer, "use_motion_blur", True)):
        return None
    s = float(r.motion_blur_shutter)
    if not s > 0:
        return None
    position = r.motion_blur_position
    opened = {"START": 0.0, "CENTER": -0.5 * s, "END": -s}[position]
    return Shutter(frame=scene.frame_current + scene.frame_subframe, length=s,
                   position=position, open=opened, close=opened + s,
                   fps=r.fps / r.fps_base)


def motion_steps(obj):
    """Cycles' number of motion steps of `obj` (object_motion_steps): 0 when its
    Object > Motion Blur is off, else 2^Steps + 1 (3 by default). Without the Cycles
    add-on's settings, Cycles' defaults."""
    c = getattr(obj, "cycles", None)
    if c is None:
        return 3
    if not getattr(c, "use_motion_blur", True):
        return 0
    return 2 ** max(1, int(getattr(c, "motion_steps", 1))) + 1


def _default_frame_set(scene):
    def frame_set(frame, subframe):
        scene.frame_set(frame, subframe=subframe)
    return frame_set


def _at(frame_set, time):
    whole = math.floor(time)
    frame_set(int(whole), float(time - whole))


def sample_motion(depsgraph, shutter, objects, frame_set):
    """`objects`: {name: times}. Evaluates the scene at every time (frame_set(frame,
    subframe), Blender's own evaluation, as Cycles' sync_motion does) and returns
    {name: {time: matrix_world}}; the frame is restored to the shutter's frame."""
    times = sorted({t for ts in objects.values() for t in ts})
    out = {name: {} for name in objects}
    try:
        for time in times:
            _at(frame_set, time)
            for name, ts in objects.items():
                if time in ts:
                    obj = bpy.data.objects[name].evaluated_get(depsgraph)
                    out[name][time] = obj.matrix_world.copy()
    finally:
        _at(frame_set, shutter.frame)
    return out


def _moves(matrices, reference):
    return any(max(abs(m[r][c] - reference[r][c]) for r in range(4) for c in range(4))
               > 1e-7 * (1.0 + max(abs(reference[r][c]) for r in range(4) for c in range(4)))
               for m in matrices)


def _matrix_value(m):
    rows = ", ".join("(" + ", ".join(repr(float(m[r][c])) for r in range(4)) + ")"
                     for c in range(4))
    return f"({rows})"


def motion_lines(samples, parent_world):
    """An object's sampled world matrices as the overlay's time samples of its local
    transform (the exported Xform's parent chain is the parents' at the frame:
    local(t) = parent_world^-1 world(t)), replacing the exporter's xformOps."""
    inverse = parent_world.inverted() if parent_world is not None else None
    keys = []
    for time in sorted(samples):
        m = samples[time] if inverse is None else inverse @ samples[time]
        keys.append(f"{time!r}: {_matrix_value(m)}")
    return [f"matrix4d {MOTION_OP}.timeSamples = {{{', '.join(keys)}}}",
            f'uniform token[] xformOpOrder = ["{MOTION_OP}"]']


def shutter_warnings(scene, shutter, warnings):
    """What of Blender's shutter Nimbus does not render."""
    r = scene.render
    curve = r.motion_blur_shutter_curve
    try:
        flat = all(abs(curve.evaluate(curve.curves[0], x / 16) - 1.0) < 1e-6
                   for x in range(17))
    except Exception:  # noqa: BLE001 - an unreadable curve is reported as not flat
        flat = False
    if not flat:
        warnings.append(
            f"scene '{scene.name}': the Motion Blur Shutter Curve is not flat; Nimbus' "
            "shutter is open evenly over its interval (a box)")
    rolling = getattr(getattr(scene, "cycles", None), "rolling_shutter_type", "NONE")
    if rolling != "NONE":
        warnings.append(
            f"scene '{scene.name}': Rolling Shutter {rolling} is not translated; Nimbus "
            "opens the whole frame's shutter at once")


def velocity_lines(obj, shutter, warnings):
    """A Volume object's velocity blur as Cycles renders it (blender/volume.cpp and the
    kernel's volume_shader_motion_blur), in NimbusVolumeAPI attributes. Cycles picks
    the grid named Velocity Grid, else one named `velocity`, and moves each lookup by
    -(t - t0) k v(x), t the sample's time over the shutter in [0, 1], t0 = 0.5 for a
    centred shutter and 0 otherwise, k = Velocity Scale x shutter / fps for Velocity
    Unit Second and Velocity Scale itself for Frame (whatever the shutter). Nimbus
    moves it by -(tau - F) nimbus:velocityScale / timeCodesPerSecond v(x), tau - F in
    frames = (t - t0) x shutter and timeCodesPerSecond = the scene's fps (the overlay
    authors it): Second -> Velocity Scale, Frame -> Velocity Scale x fps / shutter.
    Without a usable grid, nimbus:velocityScale = 0 (Nimbus would otherwise take a
    `vel` grid Cycles does not)."""
    # The evaluated volume's, as Cycles reads them (loading a file sets Velocity Grid
    # to the velocity grid Blender finds in it).
    vol = settings = obj.data
    grids = {g.name: g for g in vol.grids}
    who = f"object '{obj.name}'"
    named = settings.velocity_grid
    chosen = None
    if named and named in grids:
        chosen = named
    elif "velocity" in grids:
        chosen = "velocity"
        if named and named != "velocity":
            warnings.append(
                f"{who}: Velocity Grid '{named}' is not a grid of the volume; Nimbus "
                "blurs by the grid 'velocity', as Cycles does")
    components = [n for n in (vol.velocity_x_grid, vol.velocity_y_grid, vol.velocity_z_grid)
                  if n]
    off = ["float nimbus:velocityScale = 0.0"]
    if chosen is None:
        if components:
            warnings.append(
                f"{who}: the velocity is in three grids ({', '.join(components)}); Nimbus "
                "reads one vector grid: the volume is not blurred by velocity (Cycles "
                "combines them)")
        elif named and named != "velocity":
            warnings.append(
                f"{who}: Velocity Grid '{named}' is not a grid of the volume (grids: "
                f"{', '.join(sorted(grids)) or 'none'}); no velocity blur, as in Cycles")
        return off
    kind = getattr(grids[chosen], "data_type", "VECTOR_FLOAT")
    if kind != "VECTOR_FLOAT":
        warnings.append(
            f"{who}: the velocity grid '{chosen}' is {kind}, not a vector grid; no "
            "velocity blur")
        return off
    scale = float(settings.velocity_scale)
    if scale < 0:
        warnings.append(
            f"{who}: Velocity Scale {scale:g} is negative; Nimbus' velocity scale cannot "
            "be: no velocity blur")
        return off
    if settings.velocity_unit == "SECOND":
        # Cycles scales by the shutter only for objects it blurs (object_need_motion_attribute).
        nimbus_scale = scale if motion_steps(obj.original) > 0 else 0.0
    else:
        nimbus_scale = scale * shutter.fps / shutter.length
    if shutter.position == "END" and nimbus_scale > 0:
        warnings.append(
            f"{who}: with Position End on Frame Cycles advects the velocity grid over "
            "t + 1 - shutter of the shutter (kernel volume_shader_motion_blur), not "
            "over the shutter before the frame; Nimbus advects over [frame - shutter, "
            "frame]")
    return [f'token nimbus:velocityField = "{prim_name(chosen)}"',
            f"float nimbus:velocityScale = {_f(nimbus_scale)}"]


def translate(depsgraph, folder, frame_set=None):
    """Exports the evaluated scene of `depsgraph` into `folder` and writes the overlay;
    returns the Translation. Raises TranslationError naming the object at fault.
    `frame_set(frame, subframe)` evaluates the scene at another time for motion blur
    (the render engine's RenderEngine.frame_set; by default scene.frame_set)."""
    scene = depsgraph.scene
    view_layer = depsgraph.view_layer
    if scene.camera is None:
        raise TranslationError(f"scene '{scene.name}': no camera")
    check_volumes(depsgraph)
    exported = os.path.join(folder, "scene.usda")
    world = scene.world
    kwargs = dict(
        filepath=exported,
        selected_objects_only=False,
        export_animation=False,
        export_materials=False,
        export_lights=True,
        export_cameras=True,
        export_volumes=True,
        export_meshes=True,
        export_curves=False,
        export_hair=False,
        export_uvmaps=False,
        export_normals=False,
        export_armatures=False,
        export_shapekeys=False,
        convert_world_material=world is not None,
        relative_paths=True,
        root_prim_path=ROOT,
        evaluation_mode="RENDER",
    )
    try:
        with bpy.context.temp_override(scene=scene, view_layer=view_layer):
            result = bpy.ops.wm.usd_export(**kwargs)
    except RuntimeError as e:
        raise TranslationError(f"scene '{scene.name}': Blender's USD export failed: {e}") from e
    if "FINISHED" not in result or not os.path.isfile(exported):
        raise TranslationError(f"scene '{scene.name}': Blender's USD export wrote nothing")
    text = open(exported).read()

    warnings = []
    prims = {}
    t = Translation(folder=folder, stage=os.path.join(folder, "scene_nimbus.usda"),
                    camera=data_path(scene.camera), res=render_size(scene), warnings=warnings)
    t.region = border_region(scene, *t.res)
    t.transparent = scene.render.film_transparent
    shutter = motion_blur(scene, view_layer)
    # Motion blur: object name -> (kind, world matrix and parent's at the frame).
    moving = {}

    def track(obj, kind, matrix):
        if shutter is not None:
            parent = obj.parent.matrix_world.copy() if obj.parent is not None else None
            moving[obj.name] = (kind, matrix.copy(), parent)
    groups = {lg.name for lg in view_layer.lightgroups}
    used = set()
    albedo = None

    def exists(path):
        return f'"{path.rsplit("/", 1)[1]}"' in text

    seen = set()
    fog_instances = set()
    volume_paths = set()
    instances = 0
    for inst in depsgraph.object_instances:
        obj = inst.object
        if inst.is_instance and obj.type == "VOLUME":
            # The exporter writes no volume for a Geometry Nodes volume on a mesh, and
            # one without material for a collection instance (deactivated below): the
            # overlay defines every instance, with its grids and material.
            k = instances
            instances += 1
            xf = f"{INSTANCES}/{prim_name(obj.name)}_{k}"
            vdb = volume_file(obj, folder, f"instance_{prim_name(obj.name)}_{k}")
            attrs, a = volume_medium(obj, warnings, prims)
            vol = xf + "/volume"
            lines = [f"{key} = {v}" for key, v in attrs.items()]
            prims[INSTANCES] = ([], [], "def Xform")
            prims[xf] = ([], [_matrix(inst.matrix_world),
                              'uniform token[] xformOpOrder = ["xformOp:transform"]'],
                         "def Xform")
            for g in obj.data.grids:
                field = f"{vol}/{prim_name(g.name)}"
                lines.append(f"rel field:{prim_name(g.name)} = <{field}>")
                prims[field] = ([], [f'token fieldName = "{g.name}"',
                                     f"asset filePath = @{vdb}@"], "def OpenVDBAsset")
            if shutter is not None:
                lines += velocity_lines(obj, shutter, warnings)
            prims[vol] = (["NimbusVolumeAPI"], lines, "def Volume")
            albedo = albedo or a
            continue
        if inst.is_instance or obj.name in seen:
            if inst.is_instance and obj.type == "LIGHT":
                warnings.append(f"object '{obj.name}': instances are not translated")
            elif (inst.is_instance and obj.type == "MESH" and obj.name not in fog_instances
                  and any(material_outputs(s.material)[1] is not None
                          for s in obj.material_slots if s.material is not None)):
                fog_instances.add(obj.name)
                warnings.append(
                    f"object '{obj.name}': instances of a mesh with a volume material are "
                    "not translated as fog (they render as the exporter writes them)")
            continue
        seen.add(obj.name)
        path = data_path(obj) if obj.data is not None else None
        if obj.type == "VOLUME":
            if not exists(path):
                raise TranslationError(f"volume '{obj.name}': not in Blender's export ({path})")
            volume_paths.add(path)
            if is_generated(obj):
                # The exporter writes such grids to volumes/<data name>.vdb, one file
                # for all volumes of that (evaluated) name: each gets its own here.
                vdb = volume_file(obj, folder, prim_name(obj.name))
                for g in obj.data.grids:
                    prims[f"{path}/{prim_name(g.name)}"] = ([], [f"asset filePath = @{vdb}@"])
            attrs, a = volume_medium(obj, warnings, prims)
            prims[path] = (["NimbusVolumeAPI"], _medium_lines(obj, attrs, groups, used))
            if shutter is not None:
                prims[path][1].extend(velocity_lines(obj, shutter, warnings))
            track(obj, "volume", inst.matrix_world)
            albedo = albedo or a
        elif obj.type == "LIGHT":
            if not exists(path):
                warnings.append(f"light '{obj.name}': not in Blender's export; left out")
                continue
            lines = light_lines(obj, warnings)
            track(obj, "light", inst.matrix_world)
            schemas = []
            group = getattr(obj, "lightgroup", "")
            if group and group in groups:
                schemas.append("NimbusLightAPI")
                lines.append(f'token nimbus:lightGroup = "{_group_token(group)}"')
                used.add(group)
            if lines:
                prims[path] = (schemas, lines)
        elif obj.type == "MESH":
            if any(m.type == "FLUID" and m.fluid_type == "DOMAIN" for m in obj.modifiers):
                # Cycles renders a domain's cache as a volume and never its mesh.
                warnings.append(
                    f"object '{obj.name}': a fluid domain is not translated (bake its cache "
                    "as OpenVDB and load a frame as a Volume object); its mesh is left out")
                if exists(path):
                    prims[path] = ([], ["bool nimbus:holdout = 0"])
            else:
                fog = None
                if exists(path) and len(obj.data.polygons) > 0:
                    fog = fog_mesh_medium(obj, warnings, prims)
                if exists(path) and (fog is not None or obj.nimbus.holdout):
                    track(obj, "fog mesh" if fog is not None else "holdout mesh",
                          inst.matrix_world)
                if fog is not None:
                    # A fog mesh (docs/blender.md): the reader makes it no holdout.
                    _, attrs, a = fog
                    prims[path] = (["NimbusVolumeAPI"], _medium_lines(obj, attrs, groups, used))
                    albedo = albedo or a
                elif not obj.nimbus.holdout and exists(path):
                    prims[path] = ([], ["bool nimbus:holdout = 0"])
        elif obj.type in ("CURVE", "FONT", "SURFACE", "CURVES"):
            if obj.nimbus.holdout:
                holdout_mesh(obj, inst.matrix_world, prims, warnings)
                track(obj, "holdout curve", inst.matrix_world)
    if world is not None and exists(WORLD_PRIM):
        t.world_prim = WORLD_PRIM
        lines, schemas = [], []
        if _world_is_hdri(world):
            lines += hdri_lines(world, warnings)
        group = getattr(world, "lightgroup", "")
        if group and group in groups:
            schemas.append("NimbusLightAPI")
            lines.append(f'token nimbus:lightGroup = "{_group_token(group)}"')
            used.add(group)
        if lines:
            prims[WORLD_PRIM] = (schemas, lines)
    fog = world_fog_medium(world, warnings) if world is not None else None
    if fog is not None:
        # Cycles' world volume is infinite (docs/blender.md): a Volume filling the world.
        attrs, a = fog
        lines = ['uniform token nimbus:fill = "world"']
        lines += [f"{k} = {v}" for k, v in attrs.items()]
        group = getattr(world, "lightgroup", "")
        if group and group in groups:
            lines.append(f'token nimbus:lightGroup = "{_group_token(group)}"')
            used.add(group)
        prims[WORLD_VOLUME] = (["NimbusVolumeAPI"], lines, "def Volume")
        albedo = albedo or a
    # The exporter writes some volume instances itself (a collection instance: under
    # the instancer, without material); the overlay defines every instance, so the
    # exporter's copies are deactivated.
    if any(p.startswith(INSTANCES + "/") for p in prims):
        for vol in exported_prims(text, "Volume"):
            if vol not in volume_paths:
                prims[vol] = (INACTIVE, [])
    cam = scene.camera.data
    if cam.type == "PANO":
        raise TranslationError(
            f"camera '{scene.camera.name}': panoramic cameras are not supported (Nimbus "
            "renders perspective and orthographic ones)")
    if cam.type == "ORTHO":
        # Blender 5.0.1's exporter writes only perspective cameras (an orthographic one
        # leaves its Xform empty): the overlay defines the Camera.
        prims[t.camera] = ([], ortho_camera_lines(cam, *t.res), "def Camera")
    elif not exists(t.camera):
        raise TranslationError(
            f"camera '{scene.camera.name}': not in Blender's export ({cam.type} cameras "
            "are not exported; Nimbus renders perspective and orthographic ones)")
    t.lightgroups = {g: g for g in sorted(used)}
    t.albedo = albedo or (0.0, 0.0, 0.0)
    metadata = []
    if shutter is not None:
        camera = scene.camera.evaluated_get(depsgraph)
        track(camera, "camera", camera.matrix_world)
        motion_overlay(depsgraph, scene, shutter, moving, prims, t, warnings,
                       frame_set or _default_frame_set(scene))
        # Time codes are Blender's frames; seconds are the scene's (velocity blur).
        metadata.append(f"timeCodesPerSecond = {_f(shutter.fps)}")
        t.frame = shutter.frame
        t.shutter = shutter
    write_overlay(t.stage, os.path.basename(exported), prims, metadata)
    return t


def motion_overlay(depsgraph, scene, shutter, moving, prims, t, warnings, frame_set):
    """Motion blur in the overlay: the camera's shutter:open/close, and the objects'
    transforms sampled at Cycles' times. The camera and Volume objects: at their
    motion steps over the shutter (Nimbus interpolates between the samples linearly,
    as Cycles between its steps); lights, which Cycles does not blur (it syncs them
    only at the shutter's middle; Nimbus would blur a USD stage's moving local light),
    and objects Nimbus does not blur (holdouts, fog meshes): where they are at the
    shutter's middle, the time Cycles syncs an object
    it does not blur at, with a warning when they move while the shutter is open."""
    prims.setdefault(t.camera, ([], []))
    prims[t.camera][1].extend([f"double shutter:open = {_f(shutter.open)}",
                               f"double shutter:close = {_f(shutter.close)}"])
    shutter_warnings(scene, shutter, warnings)
    plan = {}
    for name, (kind, _, _) in moving.items():
        obj = bpy.data.objects[name]
        if kind in ("camera", "volume"):
            plan[name] = set(shutter.step_times(motion_steps(obj)))
        else:
            # Its ends and middle: whether it moves; its place at the middle.
            plan[name] = set(shutter.step_times(3))
    samples = sample_motion(depsgraph, shutter, plan, frame_set)
    ends = f"frames {shutter.frame + shutter.open:g} to {shutter.frame + shutter.close:g}"
    for name, (kind, at_frame, parent) in moving.items():
        got = samples[name]
        if not _moves(got.values(), at_frame):
            continue
        obj = bpy.data.objects[name]
        path = t.camera.rsplit("/", 1)[0] if kind == "camera" else object_path(obj)
        if kind in ("camera", "volume"):
            prims.setdefault(path, ([], []))
            prims[path][1].extend(motion_lines(got, parent))
            continue
        middle = {shutter.middle: got[shutter.middle]}
        if kind == "holdout curve":
            where = "at the frame"
        else:
            where = f"where it is at the shutter's middle (frame {shutter.middle:g})"
            if _moves(middle.values(), at_frame):
                prims.setdefault(path, ([], []))
                prims[path][1].extend(motion_lines(middle, parent))
        if kind == "light":
            warnings.append(
                f"light '{name}': moves while the shutter is open ({ends}); Cycles does "
                f"not blur lights, and the add-on renders it as Cycles does: {where}")
        else:
            warnings.append(
                f"object '{name}': moves while the shutter is open ({ends}); Nimbus blurs "
                f"the camera and Volume objects only: this {kind} is rendered {where}, "
                "not blurred (Cycles blurs it)")
