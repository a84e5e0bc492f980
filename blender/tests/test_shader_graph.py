"""Density node trees (issue 47; docs/shaders.md, "Blender node trees"): a node tree
driving a volume shader's Density is written into the overlay as UsdShade prims with
Blender's node types, and Nimbus compiles it (src/scene/blender_graph.rs) with Cycles'
semantics. The translation test reads the overlay; the render test compares F12 with
Cycles through conftest.against_cycles (image and 8 x 8 block means)."""

import math
import re
import subprocess

import bpy
import pytest

from conftest import against_cycles
from test_fog import (_camera, _mesh_object, _node_material, _render_settings, _world,
                      translated)


def noise_ramp_material(name="cloud"):
    """The issue's scene (a) material: Noise Texture (Scale 2, Detail 4, its Vector the
    default Generated coordinates) -> Color Ramp (black at 0.4, white at 0.6, linear)
    -> Math Multiply x 2 -> Principled Volume Density; Color 0.8, Anisotropy 0.2."""
    m, nt, out = _node_material(name)
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    pv.inputs["Anisotropy"].default_value = 0.2
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.0
    noise.inputs["Detail"].default_value = 4.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position = 0.4
    ramp.color_ramp.elements[1].position = 0.6
    times = nt.nodes.new("ShaderNodeMath")
    times.operation = "MULTIPLY"
    times.inputs[1].default_value = 2.0
    nt.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], times.inputs[0])
    nt.links.new(times.outputs["Value"], pv.inputs["Density"])
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    return m


def _sun(strength):
    """A sun of `strength` W/m^2, angle 0, from rotation (0.6, 0.2, 0) (both scenes')."""
    data = bpy.data.lights.new("sun", "SUN")
    data.energy = strength
    data.angle = 0.0
    sun = bpy.data.objects.new("sun", data)
    sun.rotation_euler = (0.6, 0.2, 0.0)
    bpy.context.scene.collection.objects.link(sun)
    return sun


def _cube_scene(name, material):
    """Scene (a)'s set-up: a cube [-1, 1]^3 object `name` of `material` lit by a sun
    (strength 3, angle 0), black world, film transparent, camera 5.5 units away,
    32 x 32."""
    scene = _render_settings((32, 32), True)
    _world()
    _mesh_object(name, "cube", material)
    _sun(3.0)
    _camera((0.0, -5.5, 0.5), (1.5, 0.0, 0.0))
    return scene


def noise_cube_scene():
    """Scene (a): a cube of that material (_cube_scene)."""
    return _cube_scene("noise cube", noise_ramp_material())


def test_a_noise_ramp_density_is_translated_as_a_graph(addon, tmp_path):
    """The overlay defines one Shader per node (Blender's node types as ids), the
    Noise Texture's unlinked Vector as Generated coordinates of the cube's texture
    space (scale 0.5, offset -0.5: [-1, 1] -> [0, 1]), the ramp as its 257-entry
    tables, and connects the cube's nimbus:densityScale to the graph times the
    coefficients' scale; no warning says a node drives the Density."""
    noise_cube_scene()
    t, prims = translated(tmp_path)
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    text = open(t.stage).read()
    ids = re.findall(r'info:id = "(\w+)"', text)
    # The ramp's Color into the Math node's float: Cycles' implicit conversion, its
    # luminance, written as an RGB to BW node.
    assert sorted(ids) == sorted(["ShaderNodeTexNoise", "ShaderNodeTexCoord",
                                  "ShaderNodeValToRGB", "ShaderNodeRGBToBW",
                                  "ShaderNodeMath", "ShaderNodeMath"])
    assert "float3 inputs:generated_scale = (0.5, 0.5, 0.5)" in text
    assert "float3 inputs:generated_offset = (-0.5, -0.5, -0.5)" in text
    for channel in ("red", "green", "blue"):
        table = re.search(rf"float\[\] inputs:{channel}_table = \[([^\]]*)\]", text).group(1)
        values = [float(x) for x in table.split(",")]
        assert len(values) == 257
        # Black up to 0.4 (entry 102.4), white from 0.6 (entry 153.6), linear between.
        assert values[102] == 0.0 and values[154] == 1.0 and 0.0 < values[128] < 1.0
    assert re.search(r"float nimbus:densityScale\.connect = <[^>]*nimbus_density_scale"
                     r"\.outputs:Value>", text)


# Cycles renders a heterogeneous (graph-driven) volume with its null-scattering
# estimators, measured 0.2-0.5 % bright against references (conftest.against_cycles'
# default bias); the tolerance is 5 combined standard errors of the two means plus that
# bias, set before the first run.
CYCLES_BIAS = 0.005


def test_a_noise_ramp_cube_against_cycles(addon, tmp_path):
    """Scene (a) through the add-on against Cycles 5.0.1, 4 seeds x 32 spp each, max
    depth 8: image means of alpha and R, G, B over the pixels where either's mean alpha
    > 0.01, and 8 x 8 block means, |N - C| <= 5 combined standard errors + 0.5 % of
    Cycles' (conftest.against_cycles)."""
    noise_cube_scene()
    ok, report, n = against_cycles(bpy.context.scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\nnoise cube (scene a), sun, against Cycles ({n} pixels):\n" + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


def test_generated_coordinates_of_a_volume_object_are_its_object_space(addon, smoke_vdb,
                                                                       tmp_path):
    """Cycles gives a Volume object no texture space (measured: the smoke's noise on
    Generated and on Object renders to the same pixels in bpy 5.0.1's Cycles): the
    overlay's Generated of a Volume object is the identity of object space."""
    from conftest import smoke_scene

    smoke_scene(smoke_vdb, res=16, lights=("sun",), world=False)
    smoke_density_graph()
    t, _ = translated(tmp_path)
    text = open(t.stage).read()
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    assert "float3 inputs:generated_scale = (1.0, 1.0, 1.0)" in text
    assert "float3 inputs:generated_offset = (0.0, 0.0, 0.0)" in text


def smoke_density_graph():
    """The issue's scene (b) material on the smoke: Density = (Noise Texture (Scale
    0.5, on Generated) x 0.5 + 0.5) x 4, times the density grid (Principled Volume's
    Density Attribute)."""
    nt, pv, half = _smoke_half_noise()
    four = nt.nodes.new("ShaderNodeMath")
    four.operation = "MULTIPLY"
    four.inputs[1].default_value = 4.0
    nt.links.new(half, four.inputs[0])
    nt.links.new(four.outputs["Value"], pv.inputs["Density"])


def _smoke_half_noise():
    """The smoke's node tree, its Principled Volume, and Noise Texture (Scale 0.5, on
    Generated) x 0.5 + 0.5 (a Math Multiply Add's output) added to it."""
    obj = bpy.data.objects["smoke"]
    nt = obj.data.materials[0].node_tree
    pv = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeVolumePrincipled")
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 0.5
    half = nt.nodes.new("ShaderNodeMath")
    half.operation = "MULTIPLY_ADD"
    half.inputs[1].default_value = 0.5
    half.inputs[2].default_value = 0.5
    nt.links.new(noise.outputs["Fac"], half.inputs[0])
    return nt, pv, half.outputs["Value"]


def test_the_smoke_times_noise_against_cycles(addon, smoke_vdb, tmp_path):
    """Scene (b): the smoke VDB of ../shared/data (conftest.smoke_scene: its chromatic
    Principled Volume, a sun, black world, film transparent) with Density = the density
    grid x (Noise x 0.5 + 0.5) x 4, 32 x 32, 4 seeds x 32 spp, against Cycles 5.0.1:
    image and 8 x 8 block means within 5 combined standard errors + 0.5 % of Cycles'
    (its null-scattering bias, as above)."""
    from conftest import smoke_scene

    scene, _, _ = smoke_scene(smoke_vdb, res=32, lights=("sun",), world=False)
    smoke_density_graph()
    ok, report, n = against_cycles(scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\nsmoke x noise (scene b), sun, against Cycles ({n} pixels):\n" + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


def gradient_emission_material(name="glow"):
    """The issue's scene (c) material on a fog sphere: Density = a spherical Gradient
    Texture on Object coordinates (1 at the centre, 0 at radius 1) x Noise Texture
    (Scale 3, Detail 2) x 4; Emission Color = a Color Ramp of the same noise (deep red
    at 0.3, yellow at 0.7), Emission Strength 2; Color 0.5 (so the medium absorbs)."""
    m, nt, out = _node_material(name)
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    pv.inputs["Emission Strength"].default_value = 2.0
    coords = nt.nodes.new("ShaderNodeTexCoord")
    gradient = nt.nodes.new("ShaderNodeTexGradient")
    gradient.gradient_type = "SPHERICAL"
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    falloff = nt.nodes.new("ShaderNodeMath")
    falloff.operation = "MULTIPLY"
    four = nt.nodes.new("ShaderNodeMath")
    four.operation = "MULTIPLY"
    four.inputs[1].default_value = 4.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position = 0.3
    ramp.color_ramp.elements[0].color = (0.8, 0.05, 0.0, 1.0)
    ramp.color_ramp.elements[1].position = 0.7
    ramp.color_ramp.elements[1].color = (1.0, 0.9, 0.1, 1.0)
    nt.links.new(coords.outputs["Object"], gradient.inputs["Vector"])
    nt.links.new(gradient.outputs["Fac"], falloff.inputs[0])
    nt.links.new(noise.outputs["Fac"], falloff.inputs[1])
    nt.links.new(falloff.outputs["Value"], four.inputs[0])
    nt.links.new(four.outputs["Value"], pv.inputs["Density"])
    nt.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], pv.inputs["Emission Color"])
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    return m


def test_a_glowing_gradient_noise_sphere_against_cycles(addon, tmp_path):
    """Scene (c): a fog sphere (UV sphere of radius 1) of that material, lit only by its
    emission and a dim sun (strength 1), black world, film transparent, 32 x 32; the
    overlay connects nimbus:emissionColor to the ramp and writes no warning about a
    driven input; against Cycles 5.0.1, 4 seeds x 32 spp: image and 8 x 8 block means
    within 5 combined standard errors + 0.5 % of Cycles' (as above)."""
    scene = _render_settings((32, 32), True)
    _world()
    _mesh_object("glow", "sphere", gradient_emission_material())
    _sun(1.0)
    _camera((0.0, -5.5, 0.0), (math.pi / 2, 0.0, 0.0))
    (tmp_path / "overlay").mkdir()
    t, _ = translated(tmp_path / "overlay")
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    assert re.search(r"color3f nimbus:emissionColor\.connect = <[^>]*outputs:Color>",
                     open(t.stage).read())
    ok, report, n = against_cycles(scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\nglowing sphere (scene c) against Cycles ({n} pixels):\n" + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


def noise_colour_material(name="tinted", absorption=(0.0, 0.0, 0.0, 1.0), mode=None):
    """Scene (a)'s material with its Color driven too: a Color Ramp of the same noise
    (a blue-grey 0.2, 0.35, 0.8 at 0.45, a warm white 1.0, 0.9, 0.7 at 0.6), so the
    albedo varies through the cloud; Absorption Color `absorption`. `mode`: None, or
    the ramp's (color_mode, interpolation) with a third stop, red (0.9, 0.2, 0.3) at
    0.52."""
    m = noise_ramp_material(name)
    nt = m.node_tree
    pv = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeVolumePrincipled")
    noise = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeTexNoise")
    pv.inputs["Absorption Color"].default_value = absorption
    tint = nt.nodes.new("ShaderNodeValToRGB")
    tint.name = "tint"
    tint.color_ramp.elements[0].position = 0.45
    tint.color_ramp.elements[0].color = (0.2, 0.35, 0.8, 1.0)
    tint.color_ramp.elements[1].position = 0.6
    tint.color_ramp.elements[1].color = (1.0, 0.9, 0.7, 1.0)
    if mode is not None:
        tint.color_ramp.color_mode, tint.color_ramp.interpolation = mode
        tint.color_ramp.elements.new(0.52).color = (0.9, 0.2, 0.3, 1.0)
    nt.links.new(noise.outputs["Fac"], tint.inputs["Fac"])
    nt.links.new(tint.outputs["Color"], pv.inputs["Color"])
    return m


def noise_colour_scene(absorption=(0.0, 0.0, 0.0, 1.0)):
    """Scene (a) with that material."""
    return _cube_scene("tinted cube", noise_colour_material(absorption=absorption))


def test_a_colour_ramp_on_principled_color_is_an_albedo_graph(addon, tmp_path):
    """A node tree driving Principled Volume's Color (Absorption Color black, no
    emission) connects nimbus:albedo to the ramp's Color; the medium is white
    scattering (sigma_s = Density, sigma_a = 0), the ramp's table is written, and no
    warning says a node drives the Color."""
    noise_colour_scene()
    t, _ = translated(tmp_path)
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    text = open(t.stage).read()
    assert re.search(r"color3f nimbus:albedo\.connect = <[^>]*/tint\.outputs:Color>", text)
    assert "color3f nimbus:scattering = (1.0, 1.0, 1.0)" in text
    assert "color3f nimbus:absorption = (0.0, 0.0, 0.0)" in text
    table = re.search(r'def Shader "tint"[^}]*float\[\] inputs:blue_table = \[([^\]]*)\]',
                      text).group(1)
    values = [float(x) for x in table.split(",")]
    assert len(values) == 257 and values[0] == pytest.approx(0.8) and values[-1] == \
        pytest.approx(0.7)


def test_a_colour_graph_with_absorption_colour_is_refused_naming_the_node(addon, tmp_path):
    """With a non-black Absorption Color Cycles' extinction depends on the colour, which
    an albedo multiplier cannot give: the Color keeps the socket's value, with a warning
    naming the node and why."""
    noise_colour_scene(absorption=(0.5, 0.5, 0.5, 1.0))
    t, _ = translated(tmp_path)
    text = open(t.stage).read()
    assert "nimbus:albedo.connect" not in text
    warned = [w for w in t.warnings if "'tint'" in w and ".Color" in w]
    assert warned and "Absorption Color black" in warned[0], t.warnings


def test_a_colour_ramp_albedo_cube_against_cycles(addon, tmp_path):
    """Scene (a) with its Color from a Color Ramp of the noise, through the add-on
    against Cycles 5.0.1: 4 seeds x 32 spp each, image and 8 x 8 block means of alpha
    and R, G, B within 5 combined standard errors + 0.5 % of Cycles' (as above). The
    ramp's ends differ per channel, so a colour read wrong shows in R against B."""
    noise_colour_scene()
    ok, report, n = against_cycles(bpy.context.scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\ntinted noise cube, sun, against Cycles ({n} pixels):\n" + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


@pytest.mark.parametrize("mode", [("HSV", "B_SPLINE"), ("HSL", "CARDINAL"),
                                  ("RGB", "EASE")])
def test_a_colour_ramp_of_every_mode_against_cycles(addon, tmp_path, mode):
    """The tinted cube with a three-stop Color Ramp in HSV with B-Spline, HSL with
    Cardinal, or RGB with Ease (stop 64: the add-on writes every mode, the table
    Blender's ColorRamp.evaluate gives, as Cycles bakes it), against Cycles 5.0.1 as
    above; no warning names the ramp."""
    _cube_scene("tinted cube", noise_colour_material(mode=mode))
    (tmp_path / "overlay").mkdir()
    t, _ = translated(tmp_path / "overlay")
    assert not [w for w in t.warnings if "'tint'" in w], t.warnings
    ok, report, n = against_cycles(bpy.context.scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\ntinted noise cube, ramp {mode}, sun, against Cycles ({n} pixels):\n"
          + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


def voronoi_material(name="cells", interpolation="LINEAR", feature="F1",
                     from_range=(0.1, 0.6), metric="EUCLIDEAN", detail=0.0):
    """A Voronoi density: Voronoi Texture (3D, `feature`, `metric`, Scale 2.5,
    Randomness 1, its Vector the default Generated coordinates) -> Distance (Radius for
    N-Sphere Radius) -> Map Range (From `from_range`, To 3 .. 0, clamped;
    `interpolation`, Steps 3) -> Principled Volume Density; Color 0.8, Anisotropy 0.3:
    with F1 dense cell centres fading towards the cell walls."""
    m, nt, out = _node_material(name)
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    pv.inputs["Anisotropy"].default_value = 0.3
    cells = nt.nodes.new("ShaderNodeTexVoronoi")
    cells.feature = feature
    cells.distance = metric
    cells.inputs["Scale"].default_value = 2.5
    if detail:
        cells.inputs["Detail"].default_value = detail
        cells.inputs["Roughness"].default_value = 0.6
    fade = nt.nodes.new("ShaderNodeMapRange")
    fade.clamp = True
    fade.interpolation_type = interpolation
    if interpolation == "STEPPED":  # the socket exists only then
        fade.inputs["Steps"].default_value = 3.0
    fade.inputs["From Min"].default_value = from_range[0]
    fade.inputs["From Max"].default_value = from_range[1]
    fade.inputs["To Min"].default_value = 3.0
    fade.inputs["To Max"].default_value = 0.0
    output = "Radius" if feature == "N_SPHERE_RADIUS" else "Distance"
    nt.links.new(cells.outputs[output], fade.inputs["Value"])
    nt.links.new(fade.outputs["Result"], pv.inputs["Density"])
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    return m


def test_a_voronoi_cube_against_cycles(addon, tmp_path):
    """That material on scene (a)'s cube, sun and camera, through the add-on against
    Cycles 5.0.1 (its Voronoi equals Nimbus' to the bit against Geometry Nodes,
    tests/blender_voronoi.rs; this checks the whole path: the overlay, the Generated
    coordinates, the majorants): the overlay has the Voronoi node and no warning says a
    node drives the Density; 4 seeds x 32 spp, image and 8 x 8 block means within 5
    combined standard errors + 0.5 % of Cycles' (as above)."""
    scene = _cube_scene("voronoi cube", voronoi_material())
    (tmp_path / "overlay").mkdir()
    t, _ = translated(tmp_path / "overlay")
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    assert 'info:id = "ShaderNodeTexVoronoi"' in open(t.stage).read()
    ok, report, n = against_cycles(scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\nvoronoi cube, sun, against Cycles ({n} pixels):\n" + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


def _graph_cube_against_cycles(scene, tmp_path, tokens, label):
    """The add-on's overlay of `scene` (no warning says a node drives the Density, every
    string of `tokens` in it), then `scene` against Cycles 5.0.1 (conftest.against_cycles:
    4 seeds x 32 spp, image and 8 x 8 block means within 5 combined standard errors +
    0.5 %), its report printed under `label`."""
    (tmp_path / "overlay").mkdir()
    t, _ = translated(tmp_path / "overlay")
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    text = open(t.stage).read()
    assert all(token in text for token in tokens), tokens
    ok, report, n = against_cycles(scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\n{label}, sun, against Cycles ({n} pixels):\n" + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


# Each feature's Map Range From range: where its values fall at Scale 2.5.
VORONOI_FEATURES = {
    "F2": (0.4, 1.1),  # dense where the second point is near: between cells
    "SMOOTH_F1": (0.0, 0.5),  # F1 rounded off (Smoothness 1)
    "DISTANCE_TO_EDGE": (0.0, 0.2),  # 3 at the walls, 0 inside: a cellular shell
    "N_SPHERE_RADIUS": (0.2, 0.45),  # constant per cell: blocks of density
}


@pytest.mark.parametrize("metric", ["MANHATTAN", "CHEBYCHEV"])
def test_a_voronoi_cube_of_another_metric_against_cycles(addon, tmp_path, metric):
    """The F1 Voronoi cube with the Manhattan or Chebychev metric (stop 64; equal to the
    bit to Geometry Nodes, tests/blender_voronoi.rs; Map Range From 0.1 .. 0.9 for
    Manhattan's longer distances), against Cycles 5.0.1 as above."""
    scene = _cube_scene(f"voronoi {metric}",
                        voronoi_material(f"cells {metric}", metric=metric,
                                         from_range=(0.1, 0.9 if metric == "MANHATTAN"
                                                     else 0.5)))
    _graph_cube_against_cycles(scene, tmp_path, [f'"{metric}"'],
                               f"voronoi cube, F1 {metric}")


@pytest.mark.parametrize("feature", sorted(VORONOI_FEATURES))
def test_a_voronoi_cube_of_each_feature_against_cycles(addon, tmp_path, feature):
    """The Voronoi cube with the features compiled since stop 64 (each equal to the bit
    to Geometry Nodes, Smooth F1 within 1e-5 of it: tests/blender_voronoi.rs), against
    Cycles 5.0.1 as the F1 one above: no warning says a node drives the Density, the
    overlay has the feature, 4 seeds x 32 spp, image and 8 x 8 block means within 5
    combined standard errors + 0.5 %."""
    scene = _cube_scene(f"voronoi {feature}",
                        voronoi_material(f"cells {feature}", feature=feature,
                                         from_range=VORONOI_FEATURES[feature]))
    _graph_cube_against_cycles(scene, tmp_path, [f'"{feature}"'],
                               f"voronoi cube, {feature}")


@pytest.mark.parametrize("feature", ["F1", "DISTANCE_TO_EDGE"])
def test_a_fractal_voronoi_cube_against_cycles(addon, tmp_path, feature):
    """The Voronoi cube with Detail 2.5 and Roughness 0.6 (stop 65: Cycles' fractal
    Voronoi, within 1e-5 of Geometry Nodes, tests/blender_voronoi.rs; F1's octaves sum,
    so Map Range From 0.3 .. 1.2), against Cycles 5.0.1 as the one-octave ones."""
    from_range = (0.3, 1.2) if feature == "F1" else VORONOI_FEATURES[feature]
    scene = _cube_scene(f"voronoi {feature} detail",
                        voronoi_material(f"cells {feature} detail", feature=feature,
                                         from_range=from_range, detail=2.5))
    _graph_cube_against_cycles(scene, tmp_path, ["inputs:Detail = 2.5"],
                               f"voronoi cube, {feature}, Detail 2.5")


@pytest.mark.parametrize("interpolation", ["STEPPED", "SMOOTHERSTEP"])
def test_a_voronoi_cube_mapped_stepped_or_smoother_against_cycles(addon, tmp_path,
                                                                   interpolation):
    """The Voronoi cube with its Map Range Stepped (3 steps: terraced cells) or Smoother
    Step (stop 63; the node's values equal Geometry Nodes' to the bit,
    tests/blender_math.rs), against Cycles 5.0.1 as the Linear one above: no warning
    says a node drives the Density, the overlay has the interpolation, 4 seeds x 32
    spp, image and 8 x 8 block means within 5 combined standard errors + 0.5 %."""
    scene = _cube_scene(f"voronoi {interpolation}",
                        voronoi_material(f"cells {interpolation}", interpolation))
    _graph_cube_against_cycles(scene, tmp_path, [f'"{interpolation}"'],
                               f"voronoi cube, Map Range {interpolation}")


def _mapped_material(name, vector_type):
    """Density = Map Range of a Noise Texture (Scale 2, Detail 2) from [0.42, 0.62] to
    [0, 5], clamped, the noise's Vector the cube's Object coordinates through a Mapping
    of `vector_type` with Location (0.2, 0, -0.3), Rotation (0.4, -0.9, 1.3) and Scale
    (3, 1, 0.5): noise stretched and turned, so a rotation taken about the wrong axes
    or in the wrong order moves its streaks; Color 0.8."""
    m, nt, out = _node_material(name)
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    coords = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.name = "turn"
    mapping.vector_type = vector_type
    if "Location" in mapping.inputs and mapping.inputs["Location"].enabled:
        mapping.inputs["Location"].default_value = (0.2, 0.0, -0.3)
    mapping.inputs["Rotation"].default_value = (0.4, -0.9, 1.3)
    mapping.inputs["Scale"].default_value = (3.0, 1.0, 0.5)
    nt.links.new(coords.outputs["Object"], mapping.inputs["Vector"])
    _shaped_noise_density(nt, mapping.outputs["Vector"], pv)
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    return m


def _shaped_noise_density(nt, vector, pv):
    """`pv`'s Density = Map Range of a Noise Texture (Scale 2, Detail 2) at `vector` from
    [0.42, 0.62] to [0, 5], clamped."""
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.0
    noise.inputs["Detail"].default_value = 2.0
    shape = nt.nodes.new("ShaderNodeMapRange")
    shape.inputs["From Min"].default_value = 0.42
    shape.inputs["From Max"].default_value = 0.62
    shape.inputs["To Min"].default_value = 0.0
    shape.inputs["To Max"].default_value = 5.0
    nt.links.new(vector, noise.inputs["Vector"])
    nt.links.new(noise.outputs["Fac"], shape.inputs["Value"])
    nt.links.new(shape.outputs["Result"], pv.inputs["Density"])


@pytest.mark.parametrize("vector_type", ["POINT", "TEXTURE"])
def test_a_rotated_mapping_noise_cube_against_cycles(addon, tmp_path, vector_type):
    """A Mapping with a Rotation (stop 64; every type's values match Geometry Nodes',
    tests/blender_math.rs) of type Point (scale, rotate, move) or Texture (the inverse)
    feeding the noise of a cube (_mapped_material) through the add-on, against Cycles
    5.0.1 as above: no warning says a node drives the Density, the overlay has the
    rotation, 4 seeds x 32 spp, image and 8 x 8 block means within 5 combined standard
    errors + 0.5 %."""
    scene = _cube_scene(f"mapped {vector_type}", _mapped_material(f"turned {vector_type}",
                                                                  vector_type))
    _graph_cube_against_cycles(scene, tmp_path,
                               [f'"{vector_type}"', "float3 inputs:Rotation = (0.4"],
                               f"noise cube through a rotated Mapping ({vector_type})")


def _swirled_material(name, kind):
    """Density = the Map Range of _mapped_material (Noise Scale 2, Detail 2, [0.42, 0.62]
    -> [0, 5]) at the cube's Object coordinates turned per point: with kind "SWIRL" by a
    Vector Rotate about Z through an Angle of 2.5 x the point's distance from the
    centre (a twist, Center (0.1, 0, 0)); with "MAPPING" by a Mapping (Point) whose
    Rotation is linked, 1.5 x the Object coordinates (Vector Math Scale). Turned the
    wrong way or about the wrong axis, the noise's streaks move; Color 0.8."""
    m, nt, out = _node_material(name)
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    coords = nt.nodes.new("ShaderNodeTexCoord").outputs["Object"]
    vm = nt.nodes.new("ShaderNodeVectorMath")
    nt.links.new(coords, vm.inputs[0])
    if kind == "SWIRL":
        vm.operation = "LENGTH"
        angle = nt.nodes.new("ShaderNodeMath")
        angle.operation = "MULTIPLY"
        angle.inputs[1].default_value = 2.5
        nt.links.new(vm.outputs["Value"], angle.inputs[0])
        turn = nt.nodes.new("ShaderNodeVectorRotate")
        turn.rotation_type = "Z_AXIS"
        turn.inputs["Center"].default_value = (0.1, 0.0, 0.0)
        nt.links.new(angle.outputs["Value"], turn.inputs["Angle"])
    else:
        vm.operation = "SCALE"
        vm.inputs["Scale"].default_value = 1.5
        turn = nt.nodes.new("ShaderNodeMapping")
        turn.vector_type = "POINT"
        nt.links.new(vm.outputs["Vector"], turn.inputs["Rotation"])
    turn.name = "turn"
    nt.links.new(coords, turn.inputs["Vector"])
    _shaped_noise_density(nt, turn.outputs["Vector"], pv)
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    return m


@pytest.mark.parametrize("kind", ["SWIRL", "MAPPING"])
def test_a_swirled_noise_cube_against_cycles(addon, tmp_path, kind):
    """A rotation that changes from point to point (stop 74; tests/blender_math.rs checks
    Vector Rotate's values against Geometry Nodes'): a Vector Rotate whose Angle is
    linked, or a Mapping whose Rotation is, feeding the noise of a cube
    (_swirled_material) through the add-on, against Cycles 5.0.1 as above: no warning
    says a node drives the Density, the overlay links the angle, 4 seeds x 32 spp,
    image and 8 x 8 block means within 5 combined standard errors + 0.5 %."""
    scene = _cube_scene(f"swirled {kind}", _swirled_material(f"swirl {kind}", kind))
    linked = {"SWIRL": "inputs:Angle.connect", "MAPPING": "inputs:Rotation.connect"}[kind]
    _graph_cube_against_cycles(scene, tmp_path, [linked],
                               f"noise cube turned per point ({kind})")


def _power_material(name="cubed", operation="POWER"):
    """Density = Math `operation` (Noise Texture (Scale 2, Detail 4) Fac, 3) x 8: with
    POWER the noise cubed, denser cores and thinner edges; Color 0.8."""
    m, nt, out = _node_material(name)
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.0
    noise.inputs["Detail"].default_value = 4.0
    power = nt.nodes.new("ShaderNodeMath")
    power.name = "shape"
    power.operation = operation
    power.inputs[1].default_value = 3.0
    times = nt.nodes.new("ShaderNodeMath")
    times.operation = "MULTIPLY"
    times.inputs[1].default_value = 8.0
    nt.links.new(noise.outputs["Fac"], power.inputs[0])
    nt.links.new(power.outputs["Value"], times.inputs[0])
    nt.links.new(times.outputs["Value"], pv.inputs["Density"])
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    return m


def _power_scene(operation="POWER"):
    return _cube_scene("cubed cube", _power_material(operation=operation))


def test_a_property_value_nimbus_does_not_compile_is_a_warning(addon, tmp_path):
    """A Voronoi Texture in dimensions Nimbus does not compile (2D) drives the Density:
    the add-on warns naming the node and the value and writes no graph (the socket's
    value), instead of a stage Nimbus would refuse. (Every Math and Vector Math
    operation compiles since stop 62, Reflect and Refract the last; every Voronoi
    feature and metric since stop 64.)"""
    m, nt, out = _node_material("second")
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    vor = nt.nodes.new("ShaderNodeTexVoronoi")
    vor.name = "cells"
    vor.voronoi_dimensions = "2D"
    nt.links.new(vor.outputs["Distance"], pv.inputs["Density"])
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    _cube_scene("second cube", m)
    t, _ = translated(tmp_path)
    warned = [w for w in t.warnings if "'cells'" in w and "2D" in w]
    assert warned and "drives" in warned[0], t.warnings
    assert "nimbus:densityScale.connect" not in open(t.stage).read()


def _first_output(node):
    return next((o for o in node.outputs if o.enabled and o.type in ("VALUE", "VECTOR", "RGBA")),
                next(o for o in node.outputs if o.enabled))


def test_every_property_value_either_compiles_or_warns(addon, nimbus_bin, tmp_path):
    """The add-on and the reader agree on what compiles. For every value Blender 5.0.1
    offers of every enum property the add-on writes (each Math and Vector Math
    operation, Noise and Voronoi dimensions, Voronoi feature and distance, Gradient
    type, Map Range data and interpolation types, Mapping type), one cube whose Density
    that node drives: the value is in translate._COMPILED (or the property is not
    listed there) and translates with no warning, or it is not and the add-on warns
    naming the node. Then `nimbus info` reads the whole stage: a value the add-on
    writes but the reader refuses fails here, not at a user's F12. So do linked
    constant inputs (a Value node into a Noise Texture's Scale), which must warn; a
    Mapping with a constant Rotation, one whose Rotation is linked (stop 74) and a
    Voronoi with Detail 2 (stop 65) translate."""
    from nimbus_blender import translate

    _render_settings((32, 32), True)
    _world()
    _sun(3.0)
    _camera((0.0, -5.5, 0.5), (1.5, 0.0, 0.0))
    expect = {}  # node name -> whether it should translate

    def cube(name, node_kind, configure, translates):
        m, nt, out = _node_material(name)
        pv = nt.nodes.new("ShaderNodeVolumePrincipled")
        node = nt.nodes.new(node_kind)
        node.name = name
        configure(node, nt)
        nt.links.new(_first_output(node), pv.inputs["Density"])
        nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
        _mesh_object(name, "cube", m, size=0.1, location=(3.0 * len(expect), 9.0, 0.0))
        expect[name] = translates

    probe = _node_material("probe")[1]

    def settable(kind, values):
        node = probe.nodes.new(kind)
        try:
            for k, x in values.items():
                setattr(node, k, x)
            return True
        except TypeError:
            return False
        finally:
            probe.nodes.remove(node)

    for kind, props in translate._GRAPH_NODES.items():
        for prop in props:
            rna = getattr(bpy.types, kind).bl_rna.properties[prop]
            if rna.type != "ENUM":
                continue
            allowed = translate._COMPILED.get((kind, prop))
            # A Mix's blend type is read only when it mixes colours.
            setup = {"blend_type": {"data_type": "RGBA"}}.get(prop, {}) \
                if kind == "ShaderNodeMix" else {}
            for item in rna.enum_items:
                name = f"{kind[len('ShaderNode'):]}_{prop}_{item.identifier}"
                values = {**setup, prop: item.identifier}
                if not settable(kind, values):
                    continue  # a value of another tree type (Mix's Rotation: Geometry Nodes)
                cube(name, kind,
                     lambda n, _nt, v=values: [setattr(n, k, x) for k, x in v.items()],
                     allowed is None or item.identifier in allowed)

    def linked_scale(node, nt):
        value = nt.nodes.new("ShaderNodeValue")
        value.outputs[0].default_value = 3.0
        nt.links.new(value.outputs[0], node.inputs["Scale"])

    cube("noise_linked_scale", "ShaderNodeTexNoise", linked_scale, False)
    cube("voronoi_detail_2", "ShaderNodeTexVoronoi",
         lambda n, _nt: setattr(n.inputs["Detail"], "default_value", 2.0), True)
    cube("mapping_rotated", "ShaderNodeMapping",
         lambda n, _nt: setattr(n.inputs["Rotation"], "default_value", (0.0, 0.0, 0.3)), True)

    def linked_rotation(node, nt):
        value = nt.nodes.new("ShaderNodeCombineXYZ")
        nt.links.new(value.outputs[0], node.inputs["Rotation"])

    cube("mapping_linked_rotation", "ShaderNodeMapping", linked_rotation, True)
    # A float Mix ignores its blend type, whatever it is; Volume Info has no grids on a
    # fog mesh (Cycles reads 0).
    cube("mix_float_hue", "ShaderNodeMix",
         lambda n, _nt: setattr(n, "blend_type", "HUE"), True)
    cube("volume_info_on_fog", "ShaderNodeVolumeInfo", lambda n, _nt: None, False)
    assert len(expect) > 100, len(expect)

    t, _ = translated(tmp_path)
    wrong = []
    for name, translates in expect.items():
        warned = [w for w in t.warnings if f"node '{name}'" in w]
        if translates == bool(warned):
            wrong.append((name, translates, warned))
    assert not wrong, wrong
    info = subprocess.run([str(nimbus_bin), "info", t.stage], capture_output=True, text=True)
    assert info.returncode == 0, info.stderr[-3000:]


def _grey_principled(nt):
    """A Principled Volume of Color 0.8 and Anisotropy 0.3 (the graph cubes')."""
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    pv.inputs["Anisotropy"].default_value = 0.3
    return pv


def _into_density(nt, pv, out, socket, factor):
    """`socket` x `factor` (a Math Multiply) into `pv`'s Density, and `pv` into the
    material output `out`."""
    times = nt.nodes.new("ShaderNodeMath")
    times.operation = "MULTIPLY"
    times.inputs[1].default_value = factor
    nt.links.new(socket, times.inputs[0])
    nt.links.new(times.outputs["Value"], pv.inputs["Density"])
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])


def mix_material(blend):
    """A density of two textures mixed by the Mix node (stop 65): with `blend` FLOAT,
    Mix (Float) of 0 and a Noise Texture's Fac (Scale 2.5, Detail 2) by a spherical
    Gradient (Object coordinates) as the factor; else Mix (Color, `blend`, factor 0.8)
    of the Gradient's Color and the Invert of the Noise's Color. Then Clamp (Range, Min
    0.9 > Max 0, so Cycles swaps them; the colour through its luminance) x 2 into
    Principled Volume's Density; Color 0.8, Anisotropy 0.3."""
    m, nt, out = _node_material(f"mixed {blend}")
    pv = _grey_principled(nt)
    coords = nt.nodes.new("ShaderNodeTexCoord")
    gradient = nt.nodes.new("ShaderNodeTexGradient")
    gradient.gradient_type = "SPHERICAL"
    nt.links.new(coords.outputs["Object"], gradient.inputs["Vector"])
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.5
    mix = nt.nodes.new("ShaderNodeMix")
    sockets = {s.identifier: s for s in mix.inputs}
    if blend == "FLOAT":
        mix.data_type = "FLOAT"
        nt.links.new(gradient.outputs["Fac"], sockets["Factor_Float"])
        sockets["A_Float"].default_value = 0.0
        nt.links.new(noise.outputs["Fac"], sockets["B_Float"])
        result = next(o for o in mix.outputs if o.identifier == "Result_Float")
    else:
        mix.data_type = "RGBA"
        mix.blend_type = blend
        sockets["Factor_Float"].default_value = 0.8
        invert = nt.nodes.new("ShaderNodeInvert")
        nt.links.new(noise.outputs["Color"], invert.inputs["Color"])
        nt.links.new(gradient.outputs["Color"], sockets["A_Color"])
        nt.links.new(invert.outputs["Color"], sockets["B_Color"])
        result = next(o for o in mix.outputs if o.identifier == "Result_Color")
    clamp = nt.nodes.new("ShaderNodeClamp")
    clamp.clamp_type = "RANGE"
    clamp.inputs["Min"].default_value = 0.9
    clamp.inputs["Max"].default_value = 0.0
    nt.links.new(result, clamp.inputs["Value"])
    _into_density(nt, pv, out, clamp.outputs["Result"], 2.0)
    return m


@pytest.mark.parametrize("blend", ["FLOAT", "OVERLAY", "SCREEN", "DIFFERENCE"])
def test_a_mixed_clamped_density_cube_against_cycles(addon, tmp_path, blend):
    """Mix (Float, or Color with Overlay, Screen or Difference), Invert Color and Clamp
    (stop 65; Mix and Clamp within 2 ulps of Geometry Nodes, tests/blender_math.rs) in
    a cube's density (mix_material), against Cycles 5.0.1 as above: no warning says a
    node drives the Density, the overlay has the nodes, 4 seeds x 32 spp, image and
    8 x 8 block means within 5 combined standard errors + 0.5 %. It can fail: Cycles
    given Lighten for Nimbus' Screen, the alpha's worst block was 2.3 times its
    tolerance (Screen for Overlay: 41 times; a one-off run)."""
    scene = _cube_scene(f"mixed {blend}", mix_material(blend))
    tokens = ['"ShaderNodeMix"', '"ShaderNodeClamp"', '"RANGE"']
    if blend != "FLOAT":
        tokens += ['"ShaderNodeInvert"', f'"{blend}"']
    _graph_cube_against_cycles(scene, tmp_path, tokens, f"mixed cube, {blend}")


def curve_material(points=((0.0, 0.0), (0.45, 0.1), (0.6, 0.9), (1.0, 1.0))):
    """Density = Float Curve (an S through `points`, Blender's automatic handles; its
    factor 1) of a Noise Texture's Fac (Scale 2, Detail 4) x 4; Color 0.8, Anisotropy
    0.3: the noise's mid-range made a sharp-edged cloud."""
    m, nt, out = _node_material("curved")
    pv = _grey_principled(nt)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.0
    noise.inputs["Detail"].default_value = 4.0
    curve = nt.nodes.new("ShaderNodeFloatCurve")
    c = curve.mapping.curves[0]
    for p, xy in zip(c.points, points[:2]):
        p.location = xy
    for xy in points[2:]:
        c.points.new(*xy)
    curve.mapping.update()
    nt.links.new(noise.outputs["Fac"], curve.inputs["Value"])
    _into_density(nt, pv, out, curve.outputs["Value"], 4.0)
    return m


def test_a_float_curve_of_noise_cube_against_cycles(addon, tmp_path):
    """Float Curve (stop 65: the add-on writes the curve as Cycles samples it, 257
    entries; the lookup within 8 ulps of Geometry Nodes inside the curve's points,
    tests/blender_math.rs) in a cube's density (curve_material), against Cycles 5.0.1
    as above. It can fail: Cycles given the S with its middle points at 0.4 and 0.55
    in x (0.05 to the left), R's image mean was 4.9 times its tolerance and the alpha's
    worst block 13.6 times (a one-off run)."""
    scene = _cube_scene("curved cube", curve_material())
    _graph_cube_against_cycles(scene, tmp_path, ['"ShaderNodeFloatCurve"', "inputs:table"],
                               "float curve of noise cube")


def hsv_material(saturation=1.6):
    """Density = the saturation (Separate Color, HSV: Green) of a Mix (Color, blend
    Saturation, factor 0.8) of the Hue/Saturation/Value (Hue 0.35, Saturation
    `saturation`, Value 1.1, Fac 0.9) of a Noise Texture's Color (Scale 2, Detail 2)
    with that Color itself, x 6; Color 0.8, Anisotropy 0.3."""
    m, nt, out = _node_material("hsv")
    pv = _grey_principled(nt)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.0
    hsv = nt.nodes.new("ShaderNodeHueSaturation")
    for name, value in (("Hue", 0.35), ("Saturation", saturation), ("Value", 1.1),
                        ("Fac", 0.9)):
        hsv.inputs[name].default_value = value
    mix = nt.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "SATURATION"
    sockets = {s.identifier: s for s in mix.inputs}
    sockets["Factor_Float"].default_value = 0.8
    separate = nt.nodes.new("ShaderNodeSeparateColor")
    separate.mode = "HSV"
    nt.links.new(noise.outputs["Color"], hsv.inputs["Color"])
    nt.links.new(hsv.outputs["Color"], sockets["A_Color"])
    nt.links.new(noise.outputs["Color"], sockets["B_Color"])
    result = next(o for o in mix.outputs if o.identifier == "Result_Color")
    nt.links.new(result, separate.inputs["Color"])
    _into_density(nt, pv, out, separate.outputs["Green"], 6.0)
    return m


def test_an_hsv_density_cube_against_cycles(addon, tmp_path):
    """Hue/Saturation/Value, Mix's Saturation blend and Separate Color in HSV (stop 65:
    Cycles' rgb_to_hsv and hsv_to_rgb; the Mix and the conversions within 16 ulps of
    Geometry Nodes on [0, 1], tests/blender_math.rs) in a cube's density
    (hsv_material), against Cycles 5.0.1 as above."""
    scene = _cube_scene("hsv cube", hsv_material())
    _graph_cube_against_cycles(scene, tmp_path, ['"ShaderNodeHueSaturation"',
                                                 '"SATURATION"', '"HSV"'],
                               "hsv cube")


def test_volume_info_density_in_the_smoke_against_cycles(addon, smoke_vdb, tmp_path):
    """Volume Info's Density (stop 65: the grid named density, as an Attribute node
    reads it) in scene (b)'s graph: Density = Volume Info Density x (Noise x 0.5 + 0.5)
    x 2, times the density grid (Principled Volume's Density Attribute), so the density
    grid squared; against Cycles 5.0.1 as scene (b)."""
    from conftest import smoke_scene

    scene, _, _ = smoke_scene(smoke_vdb, res=32, lights=("sun",), world=False)
    nt, pv, half = _smoke_half_noise()
    info = nt.nodes.new("ShaderNodeVolumeInfo")
    times = nt.nodes.new("ShaderNodeMath")
    times.operation = "MULTIPLY"
    two = nt.nodes.new("ShaderNodeMath")
    two.operation = "MULTIPLY"
    two.inputs[1].default_value = 2.0
    nt.links.new(half, times.inputs[0])
    nt.links.new(info.outputs["Density"], times.inputs[1])
    nt.links.new(times.outputs["Value"], two.inputs[0])
    nt.links.new(two.outputs["Value"], pv.inputs["Density"])
    _graph_cube_against_cycles(scene, tmp_path, ['"ShaderNodeVolumeInfo"'],
                               "smoke x volume info density x noise")


def test_a_cross_product_of_noise_is_translated_as_a_graph(addon, nimbus_bin, tmp_path):
    """Vector Math Cross Product (stop 61) of the Noise Texture's Color with (1, 0, 0), its Y into the
    Density: the add-on writes the graph, no warning, and Nimbus reads it."""
    m, nt, out = _node_material("crossed")
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    noise = nt.nodes.new("ShaderNodeTexNoise")
    cross = nt.nodes.new("ShaderNodeVectorMath")
    cross.operation = "CROSS_PRODUCT"
    cross.inputs[1].default_value = (1.0, 0.0, 0.0)
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(noise.outputs["Color"], cross.inputs[0])
    nt.links.new(cross.outputs["Vector"], sep.inputs["Vector"])
    nt.links.new(sep.outputs["Y"], pv.inputs["Density"])
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    _cube_scene("crossed cube", m)
    t, _ = translated(tmp_path)
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    text = open(t.stage).read()
    assert 'inputs:operation = "CROSS_PRODUCT"' in text
    assert "nimbus:densityScale.connect" in text
    info = subprocess.run([str(nimbus_bin), "info", t.stage], capture_output=True, text=True)
    assert info.returncode == 0, info.stderr
    assert "graph" in info.stdout, info.stdout


def test_a_wrap_of_noise_is_translated_as_a_graph(addon, tmp_path):
    """Math Wrap (Value, Max, Min) is one of the operations the add-on writes."""
    _power_scene("WRAP")
    t, _ = translated(tmp_path)
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    text = open(t.stage).read()
    assert 'inputs:operation = "WRAP"' in text
    assert "nimbus:densityScale.connect" in text


def test_a_power_of_noise_cube_against_cycles(addon, tmp_path):
    """Density = Power(Noise, 3) x 8 (Math Power, one of the operations added with
    tests/blender_math.rs) through the add-on against Cycles 5.0.1, as above: 4 seeds x
    32 spp, image and 8 x 8 block means within 5 combined standard errors + 0.5 % of
    Cycles'; no warning says a node drives the Density."""
    scene = _power_scene()
    (tmp_path / "overlay").mkdir()
    t, _ = translated(tmp_path / "overlay")
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    ok, report, n = against_cycles(scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\nnoise cubed, sun, against Cycles ({n} pixels):\n" + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


def _multifractal_scene():
    """Scene (a)'s cube with Density = Noise Texture (type Multifractal, Scale 2, Detail
    4, Roughness 0.5) Fac x 1.5: a product of octaves (values about 0.2 to 2.5), one of
    the types bounded by the range analysis since stop 60; Color 0.8."""
    m, nt, out = _node_material("multifractal")
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.noise_type = "MULTIFRACTAL"
    noise.inputs["Scale"].default_value = 2.0
    noise.inputs["Detail"].default_value = 4.0
    noise.inputs["Roughness"].default_value = 0.5
    times = nt.nodes.new("ShaderNodeMath")
    times.operation = "MULTIPLY"
    times.inputs[1].default_value = 1.5
    nt.links.new(noise.outputs["Fac"], times.inputs[0])
    nt.links.new(times.outputs["Value"], pv.inputs["Density"])
    nt.links.new(pv.outputs["Volume"], out.inputs["Volume"])
    return _cube_scene("multifractal cube", m)


def test_a_multifractal_noise_cube_against_cycles(addon, tmp_path):
    """A Noise Texture of type Multifractal on the Density through the add-on against
    Cycles 5.0.1, as the cubes above: 4 seeds x 32 spp, image and 8 x 8 block means
    within 5 combined standard errors + 0.5 % of Cycles'; the overlay writes the type and
    no warning says a node drives the Density."""
    scene = _multifractal_scene()
    (tmp_path / "overlay").mkdir()
    t, _ = translated(tmp_path / "overlay")
    assert not [w for w in t.warnings if "drives" in w], t.warnings
    assert 'inputs:noise_type = "MULTIFRACTAL"' in open(t.stage).read()
    ok, report, n = against_cycles(scene, tmp_path, seeds=(0, 1, 2, 3), spp=32,
                                   bias=CYCLES_BIAS, block=8)
    print(f"\nmultifractal noise, sun, against Cycles ({n} pixels):\n" + "\n".join(report))
    assert n > 100
    assert ok, "\n".join(report)


def _low_dimensional_noise_scene(dimensions):
    """Scene (a)'s cube with Density = Noise Texture in `dimensions` ("1D": of W, the
    cube's Object x + z through Separate XYZ and an Add, Scale 3, Detail 2.5; "2D": of
    the Object coordinates' x and y, Scale 2, Detail 3, Distortion 0.3) Fac x 3;
    Color 0.8."""
    m, nt, out = _node_material(f"noise {dimensions}")
    pv = nt.nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    coords = nt.nodes.new("ShaderNodeTexCoord")
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.noise_dimensions = dimensions
    if dimensions == "1D":
        split = nt.nodes.new("ShaderNodeSeparateXYZ")
        add = nt.nodes.new("ShaderNodeMath")
        add.operation = "ADD"
        nt.links.new(coords.outputs["Object"], split.inputs["Vector"])
        nt.links.new(split.outputs["X"], add.inputs[0])
        nt.links.new(split.outputs["Z"], add.inputs[1])
        nt.links.new(add.outputs["Value"], noise.inputs["W"])
        noise.inputs["Scale"].default_value = 3.0
        noise.inputs["Detail"].default_value = 2.5
    else:
        nt.links.new(coords.outputs["Object"], noise.inputs["Vector"])
        noise.inputs["Scale"].default_value = 2.0
        noise.inputs["Detail"].default_value = 3.0
        noise.inputs["Distortion"].default_value = 0.3
    _into_density(nt, pv, out, noise.outputs["Fac"], 3.0)
    return _cube_scene(f"noise {dimensions} cube", m)


@pytest.mark.parametrize("dimensions", ["1D", "2D"])
def test_a_low_dimensional_noise_cube_against_cycles(addon, tmp_path, dimensions):
    """The Noise Texture in 1D and 2D (stop 68: equal to the bit to Cycles' renders in
    tests/blender_noise.rs) on the Density through the add-on against Cycles 5.0.1, as
    the cubes above: the overlay writes the dimensions, no warning says a node drives
    the Density, 4 seeds x 32 spp, image and 8 x 8 block means within 5 combined
    standard errors + 0.5 % of Cycles'."""
    scene = _low_dimensional_noise_scene(dimensions)
    _graph_cube_against_cycles(scene, tmp_path, [f'"{dimensions}"'],
                               f"noise cube, {dimensions}")


def curves_material():
    """Density = Brightness/Contrast (Bright 0.05, Contrast 0.3) of Gamma 1.8 of RGB
    Curves (red an S through (0.3, 0.15) and (0.7, 0.9), the combined curve through
    (0.5, 0.6)) of a Noise Texture's Color (Scale 2, Detail 2) whose Vector is the
    Generated coordinates through Vector Curves (X through (0, 0.1), Y through
    (0.5, 0.4)), through its luminance, x 4; Emission Color = Blackbody of the noise's
    Fac x 5000 + 1000 K, Emission Strength 0.5; Color 0.8, Anisotropy 0.3."""
    m, nt, out = _node_material("curves")
    pv = _grey_principled(nt)
    coords = nt.nodes.new("ShaderNodeTexCoord")
    vcurves = nt.nodes.new("ShaderNodeVectorCurve")
    vcurves.mapping.curves[0].points.new(0.0, 0.1)
    vcurves.mapping.curves[1].points.new(0.5, 0.4)
    vcurves.mapping.update()
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.0
    curves = nt.nodes.new("ShaderNodeRGBCurve")
    curves.mapping.curves[0].points.new(0.3, 0.15)
    curves.mapping.curves[0].points.new(0.7, 0.9)
    curves.mapping.curves[3].points.new(0.5, 0.6)
    curves.mapping.update()
    gamma = nt.nodes.new("ShaderNodeGamma")
    gamma.inputs["Gamma"].default_value = 1.8
    bc = nt.nodes.new("ShaderNodeBrightContrast")
    bc.inputs["Bright"].default_value = 0.05
    bc.inputs["Contrast"].default_value = 0.3
    kelvin = nt.nodes.new("ShaderNodeMath")
    kelvin.operation = "MULTIPLY_ADD"
    kelvin.inputs[1].default_value = 5000.0
    kelvin.inputs[2].default_value = 1000.0
    blackbody = nt.nodes.new("ShaderNodeBlackbody")
    nt.links.new(coords.outputs["Generated"], vcurves.inputs["Vector"])
    nt.links.new(vcurves.outputs["Vector"], noise.inputs["Vector"])
    nt.links.new(noise.outputs["Color"], curves.inputs["Color"])
    nt.links.new(curves.outputs["Color"], gamma.inputs["Color"])
    nt.links.new(gamma.outputs["Color"], bc.inputs["Color"])
    nt.links.new(noise.outputs["Fac"], kelvin.inputs[0])
    nt.links.new(kelvin.outputs["Value"], blackbody.inputs["Temperature"])
    nt.links.new(blackbody.outputs["Color"], pv.inputs["Emission Color"])
    pv.inputs["Emission Strength"].default_value = 0.5
    _into_density(nt, pv, out, bc.outputs["Color"], 4.0)
    return m


def test_curves_gamma_contrast_and_blackbody_cube_against_cycles(addon, tmp_path):
    """RGB Curves, Vector Curves, Gamma, Brightness/Contrast and Blackbody (stop 67;
    against Geometry Nodes in tests/blender_math.rs: the curves within 8 ulps inside
    their points, Gamma and Blackbody equal to the bit) in a cube's density and
    emission colour (curves_material), against Cycles 5.0.1 as above."""
    scene = _cube_scene("curves cube", curves_material())
    _graph_cube_against_cycles(scene, tmp_path, ['"ShaderNodeRGBCurve"', '"ShaderNodeVectorCurve"',
                                                 '"ShaderNodeGamma"', '"ShaderNodeBrightContrast"',
                                                 '"ShaderNodeBlackbody"', "inputs:red_table"],
                               "curves, gamma, contrast and blackbody cube")


def textures_material():
    """Density = a Wave Texture (Rings, Spherical, Saw, Scale 0.4, Distortion 0.5, Detail
    2, on Object coordinates: about two and a half rings across the cube) x the Magic Texture's Fac (Depth 3, Scale 1.2, Distortion
    1.5) x (0.8 + 0.2 x White Noise 3D of the Generated coordinates' floor at 8 cells
    per unit: a constant per cell, not per point), x 6; Color 0.8, Anisotropy 0.3."""
    m, nt, out = _node_material("textures")
    pv = _grey_principled(nt)
    coords = nt.nodes.new("ShaderNodeTexCoord")
    wave = nt.nodes.new("ShaderNodeTexWave")
    wave.wave_type = "RINGS"
    wave.rings_direction = "SPHERICAL"
    wave.wave_profile = "SAW"
    for name, value in (("Scale", 0.4), ("Distortion", 0.5), ("Detail", 2.0)):
        wave.inputs[name].default_value = value
    magic = nt.nodes.new("ShaderNodeTexMagic")
    magic.turbulence_depth = 3
    magic.inputs["Scale"].default_value = 1.2
    magic.inputs["Distortion"].default_value = 1.5
    cells = nt.nodes.new("ShaderNodeVectorMath")
    cells.operation = "SCALE"
    cells.inputs["Scale"].default_value = 8.0
    floor = nt.nodes.new("ShaderNodeVectorMath")
    floor.operation = "FLOOR"
    white = nt.nodes.new("ShaderNodeTexWhiteNoise")
    speckle = nt.nodes.new("ShaderNodeMath")
    speckle.operation = "MULTIPLY_ADD"
    speckle.inputs[1].default_value = 0.2
    speckle.inputs[2].default_value = 0.8
    product = nt.nodes.new("ShaderNodeMath")
    product.operation = "MULTIPLY"
    product2 = nt.nodes.new("ShaderNodeMath")
    product2.operation = "MULTIPLY"
    nt.links.new(coords.outputs["Object"], wave.inputs["Vector"])
    nt.links.new(coords.outputs["Generated"], cells.inputs["Vector"])
    nt.links.new(cells.outputs["Vector"], floor.inputs["Vector"])
    nt.links.new(floor.outputs["Vector"], white.inputs["Vector"])
    nt.links.new(white.outputs["Value"], speckle.inputs[0])
    nt.links.new(wave.outputs["Fac"], product.inputs[0])
    nt.links.new(magic.outputs["Fac"], product.inputs[1])
    nt.links.new(product.outputs["Value"], product2.inputs[0])
    nt.links.new(speckle.outputs["Value"], product2.inputs[1])
    _into_density(nt, pv, out, product2.outputs["Value"], 6.0)
    return m


def test_wave_magic_and_white_noise_cube_against_cycles(addon, tmp_path):
    """The Wave, Magic and White Noise Textures (stop 67; against Geometry Nodes in
    tests/blender_math.rs: White Noise equal to the bit, Wave within 1e-5 and Magic
    within its derived bound, Geometry Nodes computing those two in another order) in a
    cube's density (textures_material), against Cycles 5.0.1 as above."""
    scene = _cube_scene("textures cube", textures_material())
    _graph_cube_against_cycles(scene, tmp_path, ['"ShaderNodeTexWave"', '"ShaderNodeTexMagic"',
                                                 '"ShaderNodeTexWhiteNoise"', '"SPHERICAL"'],
                               "wave, magic and white noise cube")
