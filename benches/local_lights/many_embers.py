"""Writes embers.usda with N sphere lights instead of twelve, to measure what the choice
among many local lights costs as N grows (issue 44: render/light_choice.rs picks one per
vertex by power over squared distance, a walk over every light).

usage: python3 benches/local_lights/many_embers.py N OUT.usda

The lights are placed uniformly in the box of embers.usda's twelve (seed 44), radius
0.5, their total intensity that of the twelve (54,000), so the image's brightness stays
comparable. OUT must sit in benches/local_lights/ (the VDB path is relative).
"""
import random
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main():
    n, out = int(sys.argv[1]), Path(sys.argv[2])
    src = (HERE / "embers.usda").read_text()
    head = src[: src.index('    def SphereLight "Ember00"')]
    pos = [tuple(map(float, m)) for m in
           re.findall(r"translate = \(([-\d.]+), ([-\d.]+), ([-\d.]+)\)", src)[1:]]
    total = sum(float(i) for i in re.findall(r"inputs:intensity = ([\d.]+)", src))
    lo = [min(p[k] for p in pos) for k in range(3)]
    hi = [max(p[k] for p in pos) for k in range(3)]
    rng = random.Random(44)
    lights = []
    for i in range(n):
        x = [rng.uniform(lo[k], hi[k]) for k in range(3)]
        lights.append(f'''    def SphereLight "Ember{i:04d}"
    {{
        float inputs:intensity = {total / n:.3f}
        color3f inputs:color = (1, 0.6, 0.3)
        float inputs:radius = 0.5
        double3 xformOp:translate = ({x[0]:.3f}, {x[1]:.3f}, {x[2]:.3f})
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
''')
    out.write_text(head + "".join(lights) + "}\n" + src[src.index('\ndef Scope "Render"'):])


if __name__ == "__main__":
    main()
