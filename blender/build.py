#!/usr/bin/env python3
"""Builds the installable Blender extension zip: blender/nimbus_blender/ (the package
and its blender_manifest.toml) with the nimbus wheel in wheels/, listed in the
manifest's `wheels`, as Blender 4.2+ extensions bundle Python wheels. The zip is what
`blender --command extension build` makes from the same folder (that command needs
the Blender binary; the `bpy` module from PyPI has none).

    python3 blender/build.py [--wheel target/python-wheels/nimbus-*.whl] [--out dist]

Without --wheel the newest wheel in target/python-wheels is used, and if there is
none it is built (maturin, as .ci/run's python-wheel stage does). Install the zip in
Blender with Edit > Preferences > Get Extensions > Install from Disk (docs/blender.md).
"""

import argparse
import glob
import os
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "blender" / "nimbus_blender"


def find_wheel(explicit):
    if explicit:
        return Path(explicit)
    wheels = sorted(glob.glob(str(REPO / "target" / "python-wheels" / "nimbus-*.whl")),
                    key=os.path.getmtime)
    if wheels:
        return Path(wheels[-1])
    subprocess.run(
        [sys.executable, "-m", "maturin", "build", "--release", "--ignore-rust-version",
         "--locked", "--manifest-path", str(REPO / "python" / "Cargo.toml"),
         "--out", str(REPO / "target" / "python-wheels")],
        check=True)
    return find_wheel(None)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--wheel", help="the nimbus wheel to bundle")
    ap.add_argument("--out", default=str(REPO / "dist"), help="folder of the zip")
    o = ap.parse_args()
    wheel = find_wheel(o.wheel)
    if not wheel.is_file():
        sys.exit(f"no wheel at {wheel}")
    manifest_text = (PACKAGE / "blender_manifest.toml").read_text()
    manifest_text, n = re.subn(r"(?m)^wheels = \[.*\]$",
                               f'wheels = ["./wheels/{wheel.name}"]', manifest_text)
    if n != 1:
        sys.exit("blender_manifest.toml: no `wheels = [...]` line to fill")
    manifest = tomllib.loads(manifest_text)
    for key in ("schema_version", "id", "version", "name", "type", "blender_version_min",
                "license", "maintainer", "tagline"):
        if key not in manifest:
            sys.exit(f"blender_manifest.toml: no {key}")
    os.makedirs(o.out, exist_ok=True)
    zip_path = Path(o.out) / f"{manifest['id']}-{manifest['version']}.zip"
    with zipfile.ZipFile(zip_path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("blender_manifest.toml", manifest_text)
        for path in sorted(PACKAGE.rglob("*")):
            rel = path.relative_to(PACKAGE)
            if path.is_dir() or "__pycache__" in rel.parts or rel.name == "blender_manifest.toml":
                continue
            z.write(path, str(rel))
        z.write(wheel, f"wheels/{wheel.name}")
    print(f"{zip_path} ({zip_path.stat().st_size / 1e6:.1f} MB): nimbus_blender with {wheel.name}")


if __name__ == "__main__":
    main()
