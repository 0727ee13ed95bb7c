"""The ``raster`` part of bench/gpu_measure.py: bench/raster_frame.py's frame (docs/RASTER.md "Cost")
drawn by build/hbrdf_raster on the lent GPU, so that the hybrid frame's cost against the f_a-only
frame is measured on a GPU, not only under lavapipe.

``prepare_raster`` (here; the package, glslangValidator) writes .gpu/raster/: the rows of
raster_frame.py's default table (its --models, --material, --forms, size and --sphere-segments) at 1,
2 and 4 lights, and the textured row (``hbrdf paint`` as docs/RASTER.md's, painted into
.gpu/raster/textured). Per row a scene file and the SPIR-V the frame needs (one shader pair per
material row: the light count is the tool's, not the shader's), with the models copied beside the
scenes (relative paths: the GPU machine's copy of the repository sits at another root); the manifest
gets each row's argument list for hbrdf_raster, paths relative to .gpu (the tool runs there), the
same list as hybridbrdf.raster.draw_frame's.

``raster_speed`` (there; plain Python) draws every row ``--rounds`` times, interleaved, each the best
of ``--raster-repeat`` frames after the tool's warm-up frame, and prints best and median device ms
(Vulkan timestamps around the render pass) and their ratio to the f_a row of the same light count.
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
LIGHT_COUNTS = (1, 2, 4)
TOOL = "hbrdf_raster"


# ---- prepare (here) ----------------------------------------------------------------------


def raster_frame_defaults():
    """raster_frame.py's own defaults, read from its parser (so that the rows are its rows)."""
    sys.path.insert(0, str(ROOT / "bench"))
    import raster_frame

    return raster_frame, raster_frame.parse_args([])


def prepare_raster(gpu: pathlib.Path) -> dict:
    """Writes gpu/raster/ and the tool; returns the manifest's "raster" entry."""
    raster_frame, args = raster_frame_defaults()
    out = gpu / "raster"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    shutil.copy2(ROOT / "build" / TOOL, gpu / TOOL)
    models = []
    for m in args.models:  # the scenes name copies beside them
        shutil.copy2(m, out / os.path.basename(m))
        models.append(str(out / os.path.basename(m)))
    # The textured row: docs/RASTER.md's folder (scenes/textured.json's), 16x2 layers, a 128 x 64 weights map;
    # the folder's name is the row's label.
    painted = out / "painted_rgl54_fast"
    subprocess.run([sys.executable, "-m", "hybridbrdf.cli", "paint", str(ROOT / "results/rgl54_fast.safetensors"),
                    "--base", "paper_white_rgb.rgl", "--layer",
                    f"vch_golden_yellow_rgb.rgl={ROOT / 'scenes/textured_mask.png'}", "--out", str(painted)],
                   check=True, capture_output=True)
    args.svbrdf, args.lights = [str(painted)], list(LIGHT_COUNTS)
    shaders, rows = {}, []
    for label, model, evaluate, lights, per_pixel in raster_frame.rows_of(args, models):
        key = f"{evaluate}_{pathlib.Path(model).stem}"
        scene = raster_frame.scene(model, args.material, evaluate, args.width, args.height, lights)
        material = scene["materials"]["m"]
        material["svbrdf" if evaluate == "textured" else "file"] = os.path.basename(model)  # beside the scene
        path = out / f"{key}_{lights}.json"
        path.write_text(json.dumps(scene, indent=1))
        if key not in shaders:
            shaders[key] = frame_args(path, out / key, per_pixel)
        rows.append({"label": label.removesuffix(f", {lights} light(s)"), "lights": lights,
                     "f_a": evaluate == "analytic", "args": [os.path.relpath(path, gpu), *shaders[key]]})
    fixed = ["--sphere-segments", str(args.sphere_segments)]
    return {"tool": TOOL, "rows": [dict(r, args=r["args"] + fixed) for r in rows], "size": [args.width, args.height],
            "material": args.material, "models": [os.path.relpath(m, ROOT) for m in args.models],
            "sphere_segments": args.sphere_segments}


def frame_args(scene: pathlib.Path, folder: pathlib.Path, per_pixel: bool) -> list:
    """hbrdf_raster's arguments after the scene for the frame of ``scene``: draw_frame's own list
    (hybridbrdf.raster.frame.frame_inputs; its --out, --png and --repeat left to the device), the
    SPIR-V and texture files written into ``folder``, paths relative to .gpu (folder's grandparent)."""
    from hybridbrdf.raster.frame import frame_inputs
    from hybridbrdf.raster.shaders import frame_plan

    folder.mkdir(parents=True)
    args = frame_inputs(frame_plan(str(scene)), folder, "glsl", per_pixel)
    gpu = folder.parent.parent
    return [os.path.relpath(a, gpu) if os.path.isabs(a) else a for a in args]


# ---- device (there; plain Python) ----------------------------------------------------------


def parse_report(stdout: str) -> dict:
    """hbrdf_raster's report (hybridbrdf.raster.frame._parse_report's reading): "key value" lines,
    numbers as floats but for the device's name and the size."""
    stats = {}
    for line in stdout.splitlines():
        key, _, value = line.partition(" ")
        try:
            stats[key] = float(value) if key not in ("device", "size") else value
        except ValueError:
            stats[key] = value
    return stats


def draw(gpu, row, repeat, env, out_exr, png=None) -> dict:
    """One run of the tool on ``row``: the warm-up frame and ``repeat`` timed ones; its report."""
    cmd = [str(gpu / TOOL), *row["args"], "--out", str(out_exr), "--repeat", str(repeat)]
    cmd += ["--png", str(png)] if png else []
    r = subprocess.run(cmd, cwd=gpu, env=env, capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        said = [ln for ln in r.stderr.splitlines() if ln.strip()]
        raise RuntimeError(f"{row['label']}, {row['lights']} light(s): exit {r.returncode}: "
                           f"{said[-1] if said else ''}"[:400])
    return parse_report(r.stdout)


def raster_speed(args, gpu: pathlib.Path, choose_driver, runner_env) -> None:
    """The device half: ``choose_driver(probe)`` picks the Vulkan driver as the vk part does (probe: one
    f_a frame), ``runner_env()`` the environment with .gpu/lib on the library path."""
    man = json.loads((gpu / "manifest.json").read_text()).get("raster")
    if not man:
        raise RuntimeError("this .gpu has no raster part: run bench/gpu_measure.py prepare again")
    rows, work = man["rows"], pathlib.Path(tempfile.mkdtemp(prefix="hbrdf-raster-"))
    exr = work / "frame.exr"
    device_name = choose_driver(lambda: draw(gpu, rows[0], 0, runner_env(), exr)["device"])
    smi = ["nvidia-smi", "--query-gpu=name,clocks.sm,clocks.max.sm,temperature.gpu,power.draw", "--format=csv,noheader"]
    smi = smi if shutil.which("nvidia-smi") else None
    t0 = time.time()  # warm-up, uncounted: the costliest row, so that the clocks are up before the first timing
    draw(gpu, max(rows, key=lambda r: (not r["f_a"], r["lights"])), 5 * args.raster_repeat, runner_env(), exr)
    print(f"{len(rows)} rows, {man['size'][0]}x{man['size'][1]}, {man['material']}, sphere segments "
          f"{man['sphere_segments']}; {args.rounds} interleaved rounds x {args.raster_repeat} timed frames "
          f"(warm-up {time.time() - t0:.1f} s)", flush=True)
    if smi:
        print(f"nvidia-smi before: {subprocess.run(smi, capture_output=True, text=True).stdout.strip()}")
    runs, failed = {}, {}
    png_row = next((i for i, r in enumerate(rows) if not r["f_a"] and r["lights"] == 2), None)
    for rnd in range(args.rounds):
        for i in (range(len(rows)) if rnd % 2 == 0 else reversed(range(len(rows)))):  # no row always first
            if i in failed or len(failed) >= 3:  # a broken driver: stop spending device time on it
                continue
            png = (pathlib.Path(os.environ["OUT"]) / "gpu_raster_frame.png"
                   if rnd == 0 and i == png_row and os.environ.get("OUT") else None)  # one frame to look at
            try:
                runs.setdefault(i, []).append(draw(gpu, rows[i], args.raster_repeat, runner_env(), exr, png))
            except Exception as e:  # noqa: BLE001
                failed[i] = str(e)
                print(f"FAILED {e}", flush=True)
    if smi:
        print(f"nvidia-smi after:  {subprocess.run(smi, capture_output=True, text=True).stdout.strip()}")
    figures = raster_table(rows, runs, failed)
    if os.environ.get("OUT"):  # the figures, for the record (the device tool brings $OUT back)
        (pathlib.Path(os.environ["OUT"]) / "gpu_raster.json").write_text(json.dumps(
            {"device": device_name, "size": man["size"], "material": man["material"], "models": man["models"],
             "rounds": args.rounds, "repeat": args.raster_repeat, "rows": figures}, indent=1))
    shutil.rmtree(work, ignore_errors=True)


def raster_table(rows, runs, failed) -> list:
    """Prints the table; returns its figures. A row's best ms is its best over the rounds, its median
    the median of the rounds' medians; ratios to the f_a row of the same light count."""
    figures = []
    for i, row in enumerate(rows):
        fig = {"label": row["label"], "lights": row["lights"]}
        if i in runs:
            rs = runs[i]
            fig.update(best_ms=min(r["best_ms"] for r in rs), best_cpu_ms=min(r.get("best_cpu_ms", 0) for r in rs))
            if all("best_gpu_ms" in r for r in rs):
                fig.update(best_gpu_ms=min(r["best_gpu_ms"] for r in rs),
                           median_gpu_ms=statistics.median(r["median_gpu_ms"] for r in rs))
            fig["triangles"] = rs[0].get("triangles")
        else:
            fig["failed"] = failed.get(i, "not run")
        figures.append(fig)
    base = {f["lights"]: f for f, row in zip(figures, rows) if row["f_a"]}
    timed = "device" if any("best_gpu_ms" in f for f in figures) else "host"
    key = "best_gpu_ms" if timed == "device" else "best_ms"
    print(f"{'frame':58s} {'lights':>6s} {'best ms':>8s} {'median ms':>9s} {'host ms':>8s} {'CPU ms':>8s} "
          f"{'x f_a':>6s} {'x f_a med':>9s}")
    for f in figures:
        if "failed" in f:
            print(f"{f['label'][:58]:58s} {f['lights']:6d} FAILED: {f['failed'][:200]}")
            continue
        b, nan = base.get(f["lights"], {}), float("nan")
        f["x_f_a"] = f[key] / b[key] if key in f and key in b else None
        ratio = f"{f['x_f_a']:.2f}" if f["x_f_a"] else "-"
        med = (f"{f['median_gpu_ms'] / b['median_gpu_ms']:.2f}" if "median_gpu_ms" in f and "median_gpu_ms" in b
               else "-")
        print(f"{f['label'][:58]:58s} {f['lights']:6d} {f.get(key, nan):8.3f} {f.get('median_gpu_ms', nan):9.3f} "
              f"{f['best_ms']:8.3f} {f['best_cpu_ms']:8.1f} {ratio:>6s} {med:>9s}")
    print(f"\nbest / median ms: {'Vulkan timestamps around the render pass' if timed == 'device' else 'host clock'}; "
          "x f_a: / the f_a frame's of the same light count; host ms: submit + fence wait; CPU ms: the tool's "
          "process (lavapipe's work)")
    return figures
