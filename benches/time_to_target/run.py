"""Time to target error (issue 48): the wall time for a frame to reach relMSE 1e-3 and 1e-4,
Nimbus (fixed spp, adaptive, adaptive + denoise) against Cycles 5.0.1 (the same three modes,
Cycles' adaptive sampling and OIDN at a Cycles user's defaults).

Run under the bpy 5.0.1 venv (it has numpy and the nimbus wheel, whose read_exr reads the
EXRs), from the project root:
    NIMBUS_BIN=target/release/nimbus $BPY_PYTHON benches/time_to_target/run.py OUT.csv
env: PEERS_SRC (the peers harness, default ../shared/peers), DATA (../shared/data), WORK (a
     scratch folder, default a new temporary one), SCENES (cloud,emissive,smoke), THREADS (2),
     MAX_RENDER (seconds: a mode stops climbing when its next rung is predicted to take longer, default 60),
     REPEAT_BELOW (a ladder point is rendered 3 times, seeds 1-3, when its first render took
     less than this many seconds, default 3; medians), REF_NB, REF_CY (reference spp per seed).

Scenes (peers JSON, written to WORK; Nimbus gets json2usda.py's stage of the same JSON):
  cloud     the harness' 64^3 chromatic cloud (make_grid.py --res 64 --seed 1), sun + sky;
  emissive  the same cloud emitting, Le = 4 (1, 0.45, 0.1) d(x) (weighted by sigma_a, Nimbus'
            model), no sun, a dim sky;
  smoke     ../shared/data/openvdb_samples/smoke.vdb, densityScale 1, the chromatic
            coefficients, g 0.3, sun + sky.
Each at the resolution in SCENE_RES, max_depth 64 (Mitsuba's convention; Cycles 62 bounces),
box filter 1 px, 2 threads.

Method. Per scene, each renderer's reference is the average of two seeds (REF_NB / REF_CY spp
each) of its own fixed-spp render: the renderers differ slightly, so each mode is measured
against its own renderer's reference, and the two references are compared with each other.
relMSE = mean over the foreground pixels (either reference differs from the sky colour by more
than 1e-5) and channels of ((x - ref)^2 - v) / (ref^2 + 0.01), with v = (ref_seed0 -
ref_seed1)^2 / 4 the per-pixel estimate of the reference's own variance (its noise adds to the
measured error in expectation; subtracting it makes the figure the error against the converged
image; the reference's own relMSE is printed). Denoised images are compared with the same
(non-denoised) reference.

Modes climb a ladder (fixed: spp; adaptive: noise threshold, 4096 spp cap, min spp at each
renderer's default, as a Cycles user has them), interleaved: at each rung every mode that is
still climbing renders once, the mode order rotating per rung. A mode stops after the rung
whose relMSE is below 1e-4, or when its next rung's predicted time
(4x the samples, or (threshold ratio)^2) exceeds MAX_RENDER, or at its ladder's end.
Time = the whole render's wall clock (Nimbus: the CLI process; Cycles: bpy.ops.render.render,
scene sync included, Python start-up and scene building excluded); sampling time = that minus
the median of three 1-spp renders of the same renderer (fixed, no denoising). The time to a
target is interpolated log-log between the two rungs whose relMSE bracket it; a target below
the first rung's error reads "<= first rung's time", one not reached "not reached".
"""

import csv
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PEERS = Path(os.environ.get("PEERS_SRC", REPO.parent / "shared" / "peers")).resolve()
DATA = Path(os.environ.get("DATA", REPO.parent / "shared" / "data")).resolve()
sys.path.insert(0, str(PEERS))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
import nimbus  # noqa: E402
from cycles_render import setup_scene  # noqa: E402
from scene_io import load_scene  # noqa: E402

NB = os.environ.get("NIMBUS_BIN", str(REPO / "target" / "release" / "nimbus"))
THREADS = int(os.environ.get("THREADS", "2"))
MAX_RENDER = float(os.environ.get("MAX_RENDER", "60"))
REPEAT_BELOW = float(os.environ.get("REPEAT_BELOW", "3"))
REF_NB = int(os.environ.get("REF_NB", "4096"))
REF_CY = int(os.environ.get("REF_CY", "1024"))
TARGETS = (1e-3, 1e-4)
EPS = 0.01
SCENE_RES = {"cloud": (64, 48), "emissive": (64, 48), "smoke": (48, 64)}
SPP_LADDER = {"nimbus": [4, 16, 64, 256, 1024, 4096, 8192], "cycles": [4, 16, 64, 256, 1024, 4096]}
THRESH_LADDER = [0.1, 0.05, 0.02, 0.01, 0.005, 0.0025, 0.001]
CAP = 4096
MODES = {
    # name: (renderer, kind, denoise)
    "nimbus fixed": ("nimbus", "spp", False),
    "nimbus adaptive": ("nimbus", "threshold", False),
    "nimbus adaptive+denoise": ("nimbus", "threshold", True),
    "cycles fixed": ("cycles", "spp", False),
    "cycles adaptive": ("cycles", "threshold", False),
    "cycles adaptive+denoise": ("cycles", "threshold", True),
}


def scene_json(name, work):
    base = json.load(open(PEERS / "scene_cloud.json"))
    base.pop("comment", None)
    base["grid"]["npy"] = str(work / "cloud64.npy")
    base["grid"]["vdb"] = str(work / "cloud64.vdb")
    if name == "emissive":
        base["medium"]["emission"] = {"radiance": [1.0, 0.45, 0.1], "scale": 4.0,
                                      "field": "density"}
        base["sun"] = None
        base["environment"] = {"radiance": [0.02, 0.03, 0.05]}
    elif name == "smoke":
        h = 0.47619047619047616
        lo = np.array([-33.571428571428505, -12.142857142857146, -25.952380952380917])
        base["grid"] = {"vdb": str(DATA / "openvdb_samples" / "smoke.vdb"),
                        "vdb_grid_name": "density", "origin": list(lo - h / 2),
                        "voxel_size": h, "shape": [111, 222, 112]}
        base["medium"] = {"density_scale": 1.0, "sigma_a": [0.2, 0.3, 0.6],
                          "sigma_s": [1.1, 1.2, 1.0], "hg_g": 0.3, "emission": None}
        base["camera"] = {"position": [-7.4, 40.5, 160.0], "target": [-7.4, 40.5, 0.5],
                          "up": [0.0, 1.0, 0.0], "vfov_deg": 40.0}
        d = np.array([-0.45, 0.6, 0.65])
        base["sun"] = {"direction_to_sun": list(d / np.linalg.norm(d)),
                       "irradiance": [5.0, 4.75, 4.4], "angular_diameter_deg": 0.0}
        base["environment"] = {"radiance": [0.18, 0.24, 0.36]}
    w, h_ = SCENE_RES[name]
    base["camera"]["width"], base["camera"]["height"] = w, h_
    base["max_depth"] = 64
    path = work / f"{name}.json"
    json.dump(base, open(path, "w"), indent=1)
    usda = work / f"{name}.usda"
    subprocess.run([sys.executable, str(PEERS / "json2usda.py"), str(path), str(usda)],
                   check=True, stdout=subprocess.DEVNULL)
    return path, usda


def rgb(path):
    # Blender writes a single-layer EXR's channels as ".R" etc.
    ch = {k.split(".")[-1] if k.startswith(".") else k: v
          for k, v in nimbus.read_exr(str(path)).items()}
    return np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float64)


def render_nimbus(usda, out, spp, seed, threshold=None, denoise=False):
    cmd = [NB, "render", str(usda), "-o", str(out), "--spp", str(spp), "--seed", str(seed),
           "--threads", str(THREADS)]
    if threshold is not None:
        cmd += ["--noise-threshold", str(threshold)]
    if denoise:
        cmd += ["--denoise"]
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    secs = time.perf_counter() - t
    if p.returncode != 0:
        raise SystemExit(f"nimbus failed ({' '.join(cmd)}):\n{p.stderr[-2000:]}")
    return secs


def render_cycles(sc, out, spp, seed, threshold=None, denoise=False):
    scene = setup_scene(sc, spp, THREADS, seed)
    cy = scene.cycles
    if threshold is not None:  # a Cycles user's defaults but the threshold
        cy.use_adaptive_sampling = True
        cy.adaptive_threshold = threshold
        cy.adaptive_min_samples = 0
    if denoise:  # the defaults: OIDN, albedo + normal, accurate prefilter, high quality
        cy.use_denoising = True
        cy.denoiser = "OPENIMAGEDENOISE"
        cy.denoising_input_passes = "RGB_ALBEDO_NORMAL"
        cy.denoising_prefilter = "ACCURATE"
        cy.denoising_quality = "HIGH"
    scene.render.filepath = str(out)
    scene.render.use_file_extension = False
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t


class Scene:
    def __init__(self, name, work):
        self.name = name
        self.work = work / name
        self.work.mkdir(exist_ok=True)
        self.json, self.usda = scene_json(name, work)
        self.sc = load_scene(str(self.json))
        self.bg = np.array(self.sc["env_radiance"] if self.sc.get("env_radiance") is not None
                           else [0, 0, 0], dtype=np.float64)
        self.n = 0

    def render(self, renderer, spp, seed, threshold=None, denoise=False):
        self.n += 1
        out = self.work / f"{renderer}_{self.n}.exr"
        if renderer == "nimbus":
            secs = render_nimbus(self.usda, out, spp, seed, threshold, denoise)
        else:
            secs = render_cycles(self.sc, out, spp, seed, threshold, denoise)
        return rgb(out), secs


def interp_time(points, target):
    """points: [(seconds, relmse)] in ladder order -> (seconds, note)."""
    if not points:
        return None, "no renders"
    if points[0][1] <= target:
        return points[0][0], "<="
    for (t0, e0), (t1, e1) in zip(points, points[1:]):
        if e0 > target >= e1:
            if e1 <= 0 or t1 <= t0:
                return t1, "<="
            f = (math.log(e0) - math.log(target)) / (math.log(e0) - math.log(e1))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0))), ""
    return None, (f"not reached (lowest relMSE {min(e for _, e in points):.2e}; last rung "
                  f"{points[-1][0]:.1f} s)")


def log(msg):
    print(msg, flush=True)


def run_scene(name, work, rows):
    s = Scene(name, work)
    log(f"== {name}: {SCENE_RES[name][0]}x{SCENE_RES[name][1]}, load {os.getloadavg()[0]:.2f}")
    # references: two seeds each, interleaved
    refs = {"nimbus": [], "cycles": []}
    for seed in (101, 102):
        for r, spp in (("nimbus", REF_NB), ("cycles", REF_CY)):
            img, secs = s.render(r, spp, seed)
            refs[r].append(img)
            log(f"  reference {r} {spp} spp seed {seed}: {secs:.1f} s")
    ref, var, refrel = {}, {}, {}
    mask = np.zeros(refs["nimbus"][0].shape[:2], bool)
    for r, (a, b) in refs.items():
        ref[r] = (a + b) / 2
        var[r] = (a - b) ** 2 / 4
        mask |= np.abs(ref[r] - s.bg).max(-1) > 1e-5

    def relmse(img, r):
        d = ((img - ref[r]) ** 2 - var[r]) / (ref[r] ** 2 + EPS)
        return float(d[mask].mean())

    for r in refs:
        refrel[r] = float((var[r] / (ref[r] ** 2 + EPS))[mask].mean())
    cross = float(((ref["nimbus"] - ref["cycles"]) ** 2 / (ref["cycles"] ** 2 + EPS))[mask].mean())
    mean_ratio = ref["nimbus"][mask].mean(0) / ref["cycles"][mask].mean(0)
    log(f"  {int(mask.sum())} foreground px; reference relMSE (its own noise): Nimbus "
        f"{refrel['nimbus']:.2e}, Cycles {refrel['cycles']:.2e}; Nimbus ref vs Cycles ref "
        f"relMSE {cross:.2e}, mean ratio (R,G,B) {np.round(mean_ratio, 4)}")
    # 1-spp renders, three each, interleaved
    one = {"nimbus": [], "cycles": []}
    for seed in (1, 2, 3):
        for r in one:
            one[r].append(s.render(r, 1, seed)[1])
    one = {r: statistics.median(v) for r, v in one.items()}
    log(f"  1-spp render (median of 3): Nimbus {one['nimbus']:.2f} s, Cycles {one['cycles']:.2f} s")
    points = {m: [] for m in MODES}
    active = list(MODES)
    stop_note = {}
    for rung in range(max(len(THRESH_LADDER), *map(len, SPP_LADDER.values()))):
        k = rung % len(active) if active else 0
        for mode in active[k:] + active[:k]:
            renderer, kind, dn = MODES[mode]
            ladder = SPP_LADDER[renderer] if kind == "spp" else THRESH_LADDER
            if rung >= len(ladder):
                continue
            spp = ladder[rung] if kind == "spp" else CAP
            thr = None if kind == "spp" else ladder[rung]
            trials = []
            for seed in (1, 2, 3):
                img, secs = s.render(renderer, spp, seed, thr, dn)
                trials.append((secs, relmse(img, renderer)))
                if secs >= REPEAT_BELOW:
                    break
            secs = statistics.median(t for t, _ in trials)
            err = statistics.median(e for _, e in trials)
            points[mode].append((secs, err))
            row = dict(scene=name, mode=mode, spp=spp, threshold=thr if thr else "",
                       renders=len(trials), seconds=round(secs, 3),
                       sampling_s=round(secs - one[renderer], 3), relmse=f"{err:.4e}")
            rows.append(row)
            log(f"  {mode:24} {'spp ' + str(spp) if thr is None else 'threshold ' + str(thr):16}"
                f" {len(trials)}x  {secs:7.2f} s (sampling {secs - one[renderer]:7.2f})  "
                f"relMSE {err:.3e}")
        done = []
        for mode in active:
            renderer, kind, _ = MODES[mode]
            ladder = SPP_LADDER[renderer] if kind == "spp" else THRESH_LADDER
            pts = points[mode]
            if rung + 1 >= len(ladder):
                done.append(mode)
                stop_note[mode] = "ladder's end"
            elif pts[-1][1] < TARGETS[-1]:
                done.append(mode)
            else:
                # the next rung's predicted time: 4x the samples, or (t/t')^2 as many
                grow = (ladder[rung + 1] / ladder[rung] if kind == "spp"
                        else (ladder[rung] / ladder[rung + 1]) ** 2)
                if pts[-1][0] * grow > MAX_RENDER:
                    done.append(mode)
                    stop_note[mode] = (f"next rung ({ladder[rung + 1]}) predicted "
                                       f"{pts[-1][0] * grow:.0f} s > {MAX_RENDER:.0f} s")
                    log(f"  {mode}: stops, {stop_note[mode]}")
        active = [m for m in active if m not in done]
        if not active:
            break
    for mode in stop_note:
        rows.append(dict(scene=name, mode=mode, spp="", threshold="", renders=0, seconds="",
                         sampling_s="", relmse="", note=f"stopped: {stop_note[mode]}"))


def fmt(t, note):
    if t is None:
        return note
    return f"{note}{t:.2f}" if note == "<=" else f"{t:.2f}"


def main(out_csv):
    work = Path(os.environ.get("WORK") or tempfile.mkdtemp(prefix="time_to_target-"))
    work.mkdir(parents=True, exist_ok=True)
    if not (work / "cloud64.vdb").exists():
        subprocess.run([sys.executable, str(PEERS / "make_grid.py"), str(work / "cloud64.npy"),
                        "--res", "64", "--seed", "1"], check=True)
        (work / "scene_cloud.json").write_text((PEERS / "scene_cloud.json").read_text())
        subprocess.run([sys.executable, str(PEERS / "npy2vdb.py"),
                        str(work / "scene_cloud.json")], check=True)
    log(f"nimbus {NB}; bpy {bpy.app.version_string}; {THREADS} threads; work {work}; "
        f"load {os.getloadavg()}")
    rows = []
    t0 = time.time()
    for name in os.environ.get("SCENES", "cloud,emissive,smoke").split(","):
        run_scene(name, work, rows)
        log(f"  ({(time.time() - t0) / 60:.1f} min so far)")
    keys = ["scene", "mode", "spp", "threshold", "renders", "seconds", "sampling_s", "relmse",
            "note"]
    with open(out_csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in keys})
    summarize(out_csv)
    log(f"total {(time.time() - t0) / 60:.1f} min; load {os.getloadavg()}")


def summarize(csv_path):
    """The time-to-target table and the Cycles/Nimbus ratios, from the CSV."""
    rows = list(csv.DictReader(open(csv_path)))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    tt = {}
    log("\n| scene | mode | relMSE 1e-3: s (sampling s) | relMSE 1e-4: s (sampling s) |")
    log("|---|---|---|---|")
    for name in scenes:
        for mode in MODES:
            rs = [r for r in rows if r["scene"] == name and r["mode"] == mode]
            pts = [(float(r["seconds"]), float(r["relmse"])) for r in rs if r["seconds"]]
            one = [float(r["seconds"]) - float(r["sampling_s"]) for r in rs if r["seconds"]]
            stop = [r["note"] for r in rs if r.get("note")]
            cells = []
            for target in TARGETS:
                t, note = interp_time(pts, target)
                if t is None:
                    tt[name, mode, target] = None
                    cells.append(note + (f"; {stop[0]}" if stop else ""))
                else:
                    tt[name, mode, target] = (t, t - one[0])
                    cells.append(f"{fmt(t, note)} ({fmt(t - one[0], note)})")
            log(f"| {name} | {mode} | {cells[0]} | {cells[1]} |")
    log("\nCycles time / Nimbus time to the target, the best mode of each (> 1: Nimbus sooner):")
    for name in scenes:
        for target in TARGETS:
            best = {}
            for r in ("nimbus", "cycles"):
                ts = [(tt[name, m, target], m) for m in MODES
                      if MODES[m][0] == r and tt[name, m, target] is not None]
                best[r] = min(ts) if ts else None
            if best["nimbus"] and best["cycles"]:
                (nt, ns), nm = best["nimbus"]
                (ct, cs), cm = best["cycles"]
                log(f"  {name} {target:g}: Nimbus {nm} {nt:.2f} s ({ns:.2f} sampling), Cycles "
                    f"{cm} {ct:.2f} s ({cs:.2f} sampling): whole render {ct / nt:.2f}x, "
                    f"sampling {cs / max(ns, 1e-3):.2f}x")
            else:
                log(f"  {name} {target:g}: no ratio: "
                    + ", ".join(f"{r} {'reached' if best[r] else 'not reached'}" for r in best))
    log("Same mode, Cycles / Nimbus (whole render; sampling):")
    for name in scenes:
        for target in TARGETS:
            parts = []
            for kind in ("fixed", "adaptive", "adaptive+denoise"):
                a, b = tt[name, f"nimbus {kind}", target], tt[name, f"cycles {kind}", target]
                parts.append(f"{kind} " + (f"{b[0] / a[0]:.2f}x; {b[1] / max(a[1], 1e-3):.2f}x"
                                           if a and b else "-"))
            log(f"  {name} {target:g}: " + ", ".join(parts))


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--summary":
        summarize(sys.argv[2])
    else:
        main(sys.argv[1] if len(sys.argv) > 1 else
             str(REPO / "benches" / "time_to_target" / "time_to_target.csv"))
