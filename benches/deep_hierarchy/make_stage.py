#!/usr/bin/env python3
"""Writes a stage whose volume sits under DEPTH nested Xforms (issue 34): the
example cloud, its camera, sun and sky, with /World/L0/L1/.../L{DEPTH-1}/Cloud.

    python3 make_stage.py DEPTH OUT.usda VDB

Plain text, no pxr needed; tests/hostile_inputs.rs writes the same stage in Rust
(`deep_stage`)."""
import sys


def deep_stage(depth: int, vdb: str) -> str:
    chain = "".join(f'def Xform "L{i}" {{\n' for i in range(depth))
    close = "}\n" * depth
    volume_path = "/World/" + "".join(f"L{i}/" for i in range(depth)) + "Cloud"
    return f'''#usda 1.0
(
    defaultPrim = "World"
    renderSettingsPrimPath = "/Render/Settings"
)

def Xform "World"
{{
{chain}def Volume "Cloud" (
    prepend apiSchemas = ["NimbusVolumeAPI"]
)
{{
    rel field:density = <{volume_path}/density>
    float nimbus:densityScale = 24
    def OpenVDBAsset "density"
    {{
        asset filePath = @{vdb}@
        token fieldName = "density"
    }}
}}
{close}
    def Camera "Camera"
    {{
        float focalLength = 50
        float horizontalAperture = 36
        float verticalAperture = 27
        float2 clippingRange = (0.1, 1000)
        double3 xformOp:translate = (0, -0.5, 4.2)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}

    def DistantLight "Sun"
    {{
        float inputs:intensity = 6
        float3 xformOp:rotateXYZ = (-30, 80, 0)
        uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    }}
}}

def Scope "Render"
{{
    def RenderSettings "Settings"
    {{
        rel camera = </World/Camera>
        uniform int2 resolution = (32, 24)
    }}
}}
'''


if __name__ == "__main__":
    depth, out, vdb = int(sys.argv[1]), sys.argv[2], sys.argv[3]
    with open(out, "w") as f:
        f.write(deep_stage(depth, vdb))
