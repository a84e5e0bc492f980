"""A stage of N instances of one VDB scattered over a 2,000-unit field, seen from above:
`make_stage.py VDB N` (a PointInstancer), or `make_stage.py VDB explicit` (1,000 Volume
prims, each with its own OpenVDBAsset prim naming the same file). Seeded: the same
stage every run."""
import random
import sys

vdb, n = sys.argv[1], sys.argv[2]
explicit = n == "explicit"
count = 1000 if explicit else int(n)
rng = random.Random(43)
pos = [(rng.uniform(-1000, 1000), rng.uniform(-1000, 1000), rng.uniform(0, 40)) for _ in range(count)]
out = ['#usda 1.0\n(\n    upAxis = "Z"\n)\n']
if explicit:
    for i, p in enumerate(pos):
        out.append(
            f'def Volume "v{i}"\n{{\n    double3 xformOp:translate = {p}\n'
            '    uniform token[] xformOpOrder = ["xformOp:translate"]\n'
            f'    rel field:density = </v{i}/f>\n'
            f'    def OpenVDBAsset "f"\n    {{\n        asset filePath = @{vdb}@\n'
            '        token fieldName = "density"\n    }\n}\n')
else:
    out.append('def PointInstancer "clouds"\n{\n    rel prototypes = </clouds/P/smoke>\n')
    out.append(f'    int[] protoIndices = [{", ".join("0" * 1 for _ in pos)}]\n')
    out.append(f'    point3f[] positions = [{", ".join(str(p) for p in pos)}]\n')
    out.append('    def Scope "P"\n    {\n        def Volume "smoke"\n        {\n'
               '            rel field:density = </clouds/P/smoke/f>\n'
               f'            def OpenVDBAsset "f"\n            {{\n                asset filePath = @{vdb}@\n'
               '                token fieldName = "density"\n            }\n        }\n    }\n}\n')
out.append('def Camera "cam"\n{\n    float focalLength = 20\n    double3 xformOp:translate = (0, 0, 1500)\n'
           '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
           'def DistantLight "sun"\n{\n}\n'
           'def RenderSettings "settings"\n{\n    rel camera = </cam>\n}\n')
sys.stdout.write("".join(out))
