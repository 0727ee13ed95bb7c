#!/usr/bin/env python3
"""Where the raster frame's time goes under lavapipe (docs/RASTER.md "What lavapipe does with the
network"): bench/raster_frame.py's 1280x720 scene drawn by hbrdf_raster on saved shaders, the
hybrid per-pixel frame against variants of its generated code, in interleaved rounds, CPU ms.
The variants are measurements, not products (some drop terms of the model).

    python bench/raster_anatomy.py [--model results/rgl54_hybrid_32x2.safetensors] [--material paper_white_rgb.rgl]
                                   [--lights 2] [--rounds 3] [--repeat 3] [--variants NAME...] [--asm]
                                   [--tool build/hbrdf_raster]

Rows (each drawn --rounds times, all rows interleaved round by round, each time the best of --repeat
frames after a warm-up; a row's figure is its best CPU ms over the rounds, and its ratio to "f_a"):
  f_a            the same material evaluated as f_a (the frame every ratio is against)
  full           the hybrid as hbrdf raster draws it (generated per-pixel form)
  no-hidden      hbrdf_eval_pixel with the hidden-to-hidden layer dropped (h1_j = h0_j): that layer's cost
  no-network     with every layer after the first dropped (o[j] = h0_j)
  no-exp         the output combine without exp and the sigmoid (f = o + g f_a): the transcendentals' cost
  no-energy      without the energy scale at wi.z per light (models with energy tables)
  blocked4       the hidden layer's sums four outputs at a time, input by input (same terms, same order per sum)
  stream8        eight at a time, and the output layer's sums fed by each block as it is computed
  fma            blocked by eight, each multiply-add written as GLSL fma() (does llvmpipe emit FMA instructions?)
  light-below    the one-directional-light scene lit from below (almost no lane lit): does llvmpipe skip the network?
  light-above    the same light from above (every lane lit)
  loop-test-top  the former light loop, its exit test at the top (a for loop): one more pass of the body
  seg64, seg1024 the sphere tessellated with 64 / 1024 segments instead of 256 (more, smaller triangles);
                 f_a-seg64, f_a-seg1024 the f_a frame so
  width512       full with LP_NATIVE_VECTOR_WIDTH=512 (16 lanes a vector where the CPU has AVX-512)
  threads1       full with LP_NUM_THREADS=1 (one rasterizer thread)
--callgrind runs one frame of "full" and "loop-test-top" under valgrind's callgrind (LP_NUM_THREADS=1,
minutes each) and prints, for the JIT function that executes the most instructions, how many of its
instructions ran how many times (the light loop's body: passes x shaded 8-lane vectors).
--asm attaches gdb to a running hbrdf_raster of the "full" and "stream8" rows, dumps the JIT code
mapping its rasterizer threads execute, and counts its instructions with objdump (x86-64 only).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

from hybridbrdf.raster import draw_frame
from hybridbrdf.raster.sizes import LAVAPIPE_ICD
from hybridbrdf.render import read_exr
from raster_frame import scene

ROOT = pathlib.Path(__file__).resolve().parents[1]
VARIANTS = ["f_a", "full", "no-hidden", "no-network", "no-exp", "no-energy", "blocked4", "stream8", "fma", "light-below",
            "light-above", "loop-test-top", "seg64", "seg1024", "f_a-seg64", "f_a-seg1024",
            "width512", "threads1"]
#: Rows that differ by llvmpipe's environment only (diagnostics, not products).
ENVIRONMENT = {"width512": {"LP_NATIVE_VECTOR_WIDTH": "512"}, "threads1": {"LP_NUM_THREADS": "1"}}


def parse_sum(line: str):
    """``float hI_J = hbrdf_activation(b +- w * v ...);`` or ``o[J] = b +- w * v ...;`` -> (b, [(w, v)])."""
    expr = line[line.index("(") + 1:line.rindex(")")] if "hbrdf_activation" in line else line.split("=", 1)[1].rstrip(";")
    tokens = expr.replace(" - ", " + -").split(" + ")
    return tokens[0].strip(), [tuple(t.strip() for t in term.split(" * ")) for term in tokens[1:]]


def blocked(lines, hidden, outputs, block: int, stream: bool):
    """The hidden layer h1 (statement indices ``hidden``) as sums of ``block`` outputs at a time, input
    by input; with ``stream`` the output layer's sums (``outputs``) take each block's h1 at once."""
    rows, outs = [parse_sum(lines[i]) for i in hidden], [parse_sum(lines[i]) for i in outputs]
    n_in = 1 + max(int(v.split("_")[1]) for _, terms in rows for _, v in terms)
    new = [f"    o[{q}] = {b};" for q, (b, _) in enumerate(outs)] if stream else []
    for j0 in range(0, len(rows), block):
        js = range(j0, min(len(rows), j0 + block))
        new += [f"    float a{j} = {rows[j][0]};" for j in js]
        for k in range(n_in):
            new += [f"    a{j} += {w} * {v};" for j in js for w, v in rows[j][1] if v == f"h0_{k}"]
        new += [f"    float h1_{j} = hbrdf_activation(a{j});" for j in js]
        if stream:
            new += [f"    o[{q}] += {w} * {v};" for j in js for q, (_, terms) in enumerate(outs) for w, v in terms
                    if v == f"h1_{j}"]
    kept = [line for i, line in enumerate(lines) if not (stream and i in outputs)]
    first = hidden[0]
    return kept[:first] + new + kept[first + len(hidden):]


def model_variant(text: str, name: str) -> str:
    """hbrdf_eval_pixel of the generated file ``text`` rewritten as variant ``name``."""
    start = text.index("hbrdf_eval_pixel(")
    head, lines = text[:start], text[start:].split("\n")
    hidden = [i for i, line in enumerate(lines) if line.strip().startswith("float h1_")]
    outputs = [i for i, line in enumerate(lines) if line.strip().startswith("o[")]
    if name in ("no-hidden", "no-network", "blocked4", "stream8", "fma") and not hidden:
        raise SystemExit(f"{name}: the model has no hidden-to-hidden layer (depth 1)")
    if name == "no-hidden":
        for j, i in enumerate(hidden):
            lines[i] = f"    float h1_{j} = h0_{j};"
    elif name == "no-network":
        for i in hidden:
            lines[i] = ""
        for q, i in enumerate(outputs):
            lines[i] = f"    o[{q}] = h0_{q};"
    elif name in ("blocked4", "stream8", "fma"):
        lines = blocked(lines, hidden, outputs, 4 if name == "blocked4" else 8, name == "stream8")
        if name == "fma":
            lines = [re.sub(r"^    (a\d+) \+= (\S+) \* (h0_\d+);$", r"    \1 = fma(\2, \3, \1);", line) for line in lines]
    elif name == "no-exp":
        lines = [re.sub(r"hbrdf_combine\(o\[(\d)\], o\[(\d)\], (fa\.\w)\)", r"(o[\1] + o[\2] * \3)", line) for line in lines]
        lines = [re.sub(r"hbrdf_combine\(o\[(\d)\], (fa\.\w)\)", r"(o[\1] + \2)", line) for line in lines]
    elif name == "no-energy":
        body = "\n".join(lines)
        if "hbrdf_energy_scale(wi.z, m) * px.k_wo" not in body:
            raise SystemExit("no-energy: the model has no energy table")
        return head + body.replace("hbrdf_energy_scale(wi.z, m) * px.k_wo", "px.k_wo")
    return head + "\n".join(lines)


def loop_test_at_top(frag: str) -> str:
    """The fragment stage with the light loop's exit test at its top (the template's former for loop)."""
    for old, new in (("uint k = 0u;\n    if (n_lights > 0u) while (true) {", "for (uint k = 0u; k < n_lights; ++k) {"),
                     ("        if (++k >= n_lights) break;\n", "")):
        if old not in frag:
            raise SystemExit("loop-test-top: the fragment stage's light loop is not the expected one")
        frag = frag.replace(old, new)
    return frag


def prepare(args, work: pathlib.Path):
    """Scenes and compiled shader folders of every row: {name: (scene, folder, segments)}."""
    scenes = {}
    for tag, evaluate in (("fa", "analytic"), ("hybrid", "full")):
        for extra in ("", "-above", "-below"):
            s = scene(args.model, args.material, evaluate, 1280, 720, args.lights)
            if extra:
                s["lights"] = [{"type": "directional", "direction": [0, 1 if extra == "-above" else -1, 0],
                                "irradiance": [1, 1, 1]}]
            (work / f"{tag}{extra}.json").write_text(json.dumps(s))
            scenes[tag + extra] = str(work / f"{tag}{extra}.json")
    for tag in ("fa", "hybrid"):
        draw_frame(scenes[tag], work / f"{tag}.exr", lavapipe=True, tool=args.tool, keep_shaders=work / tag)
    # Covered pixels: a point light at the camera lights every point the camera sees.
    s = json.loads(pathlib.Path(scenes["fa"]).read_text())
    s["lights"] = [{"type": "point", "position": s["camera"]["position"], "intensity": [1, 1, 1]}]
    (work / "headlight.json").write_text(json.dumps(s))
    draw_frame(work / "headlight.json", work / "headlight.exr", lavapipe=True, tool=args.tool, sphere_segments=256)
    args.covered = int((read_exr(work / "headlight.exr").max(axis=2) > 0).sum())
    rows = {}
    for name in args.variants:
        folder, sc, seg = work / "hybrid", scenes["hybrid"], 256
        if name.startswith("f_a"):
            folder, sc = work / "fa", scenes["fa"]
            seg = int(name[7:]) if name.startswith("f_a-seg") else seg
        elif name in ("light-below", "light-above"):
            sc = scenes["hybrid-" + name.split("-")[1]]
        elif name.startswith("seg"):
            seg = int(name[3:])
        elif name != "full" and name not in ENVIRONMENT:
            folder = work / name
            folder.mkdir()
            for f in ("frame.frag", "vert.spv", "model.glsl"):
                shutil.copy(work / "hybrid" / f, folder / f)
            if name == "loop-test-top":
                (folder / "frame.frag").write_text(loop_test_at_top((folder / "frame.frag").read_text()))
            else:
                (folder / "model.glsl").write_text(model_variant((folder / "model.glsl").read_text(), name))
            subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", str(folder / "frame.frag"), "-o",
                            str(folder / "frag.spv")], check=True, capture_output=True)
        rows[name] = (sc, folder, seg)
    return rows


def command(args, row, repeat: int):
    sc, folder, seg = row
    cmd = [args.tool, sc, str(folder / "vert.spv"), str(folder / "frag.spv"), "--out", str(folder / "frame_out.exr"),
           "--repeat", str(repeat), "--sphere-segments", str(seg)]
    return cmd + ([] if folder.name == "fa" else ["--model-material", "m"])


def measure(args, rows):
    best = {name: float("inf") for name in rows}
    for r in range(args.rounds):
        for name, row in rows.items():
            env = dict(os.environ, VK_DRIVER_FILES=LAVAPIPE_ICD, **ENVIRONMENT.get(name, {}))
            p = subprocess.run(command(args, row, args.repeat), capture_output=True, text=True, env=env)
            if p.returncode != 0:
                raise SystemExit(f"{name}: {p.stderr.strip().splitlines()[-1:]}")
            stats = dict(line.split(" ", 1) for line in p.stdout.splitlines() if " " in line)
            best[name] = min(best[name], float(stats["best_cpu_ms"]))
    return best


def jit_counts(args, row) -> dict:
    """Instruction counts of the JIT code hbrdf_raster's rasterizer threads execute (gdb + objdump)."""
    env = dict(os.environ, VK_DRIVER_FILES=LAVAPIPE_ICD)
    proc = subprocess.Popen(command(args, row, 100), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        for _ in range(60):
            time.sleep(2)
            g = subprocess.run(["gdb", "-p", str(proc.pid), "-batch", "-ex", "thread apply all x/i $pc", "-ex",
                                "info proc mappings"], capture_output=True, text=True, timeout=120).stdout
            pcs = [int(m, 16) for m in re.findall(r"=> (0x[0-9a-f]+):\s", g)]
            # "info proc mappings": start end size offset perms [file]; JIT code is anonymous and executable
            mapping = r"(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+0x\w+\s+0x0\s+\S*x\S*\s*$"
            maps = [(int(a, 16), int(b, 16)) for a, b in re.findall(mapping, g, re.M)]
            hits = sorted({m for m in maps for pc in pcs if m[0] <= pc < m[1]}, key=lambda m: m[0] - m[1])
            if hits and hits[0][1] - hits[0][0] >= 16384:
                break
        else:
            raise SystemExit("--asm: no rasterizer thread caught in JIT code")
        lo, hi = hits[0]
        dump = pathlib.Path(row[1]) / "jit.bin"
        subprocess.run(["gdb", "-p", str(proc.pid), "-batch", "-ex", f"dump binary memory {dump} {lo} {hi}"],
                       capture_output=True, timeout=120)
    finally:
        proc.kill()
        proc.wait()
    asm = subprocess.run(["objdump", "-D", "-b", "binary", "-mi386:x86-64", str(dump)], capture_output=True, text=True).stdout
    ops = [line.split("\t")[2] for line in asm.splitlines() if line.count("\t") >= 2]
    count = lambda pattern: sum(1 for op in ops if re.search(pattern, op))  # noqa: E731
    return {"instructions": len(ops), "vmulps": count(r"^vmulps"), "vaddps": count(r"^vaddps"),
            "vfmadd": count(r"^vfn?m(add|sub)"), "movabs": count(r"^movabs"),
            "stack stores": count(r"^vmov\w+\s+%[xyz]mm\d+,\S*\(%rsp\)"),
            "stack loads": count(r"^vmov\w+\s+\S*\(%rsp\),%[xyz]mm"), "ymm16-31": count(r"%ymm(1[6-9]|2\d|3[01])\b")}


def callgrind_passes(args, rows) -> None:
    """One frame of "full" and "loop-test-top" under callgrind, side by side: the hottest JIT
    function's instructions grouped by how often each ran (most instruction executions first)."""
    env = dict(os.environ, VK_DRIVER_FILES=LAVAPIPE_ICD, LP_NUM_THREADS="1")
    runs = {}
    for name in ("full", "loop-test-top"):
        out = rows[name][1] / "callgrind.out"
        runs[name] = (out, subprocess.Popen(["valgrind", "--tool=callgrind", "--smc-check=all-non-file", "--dump-instr=yes",
                                             f"--callgrind-out-file={out}"] + command(args, rows[name], 0),
                                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env))
    for name, (out, proc) in runs.items():
        proc.wait()
        counts = jit_executions(out)
        groups = {}
        for n in counts.values():
            groups[n] = groups.get(n, 0) + 1
        top = sorted(groups.items(), key=lambda g: -g[0] * g[1])[:3]
        print(f"callgrind {name}: hottest JIT function {sum(counts.values()):,} instructions executed; "
              + "; ".join(f"{k:,} instructions x {n:,} times" for n, k in top))


def jit_executions(path: pathlib.Path) -> dict:
    """{instruction address: executions} of the callgrind file's costliest function named by an address
    (JIT code has no symbol). Names are compressed: "(id) name" once, "(id)" after (fn= and cfn= alike)."""
    names, per_fn, fn, addr, skip = {}, {}, None, 0, False
    for line in path.read_text().splitlines():
        m = re.match(r"c?fn=\((\d+)\)(?: (.*))?$", line)
        if m:
            names.setdefault(m[1], m[2])
            if line.startswith("fn="):
                fn = m[1] if re.fullmatch(r"0x[0-9a-f]+", names[m[1]] or "") else None
            continue
        if line.startswith("calls="):
            skip = True  # the next line is the call's inclusive cost, not an instruction of fn
            continue
        if fn is None or not line or line[0] not in "+-0123456789":
            continue
        first = line.split()[0]
        addr = int(first, 16) if first.startswith("0x") else addr + int(first) if first[0] in "+-" else addr
        if skip:
            skip = False
            continue
        counts = per_fn.setdefault(fn, {})
        counts[addr] = counts.get(addr, 0) + int(line.split()[-1])
    return max(per_fn.values(), key=lambda c: sum(c.values()))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results/rgl54_hybrid_32x2.safetensors"))
    ap.add_argument("--material", default="paper_white_rgb.rgl")
    ap.add_argument("--lights", type=int, choices=[1, 2, 4], default=2)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--variants", nargs="+", choices=VARIANTS, default=[v for v in VARIANTS if v != "no-energy"])
    ap.add_argument("--asm", action="store_true", help="count the JIT code's instructions of full, stream8 and fma (gdb)")
    ap.add_argument("--callgrind", action="store_true", help="count the light loop's passes under callgrind (minutes)")
    ap.add_argument("--tool", default=os.environ.get("HBRDF_RASTER", str(ROOT / "build" / "hbrdf_raster")))
    args = ap.parse_args()
    args.variants = ["f_a"] + [v for v in args.variants if v != "f_a"]
    if args.callgrind:
        args.variants += [v for v in ("full", "loop-test-top") if v not in args.variants]
    with tempfile.TemporaryDirectory(prefix="raster_anatomy_") as tmp:
        rows = prepare(args, pathlib.Path(tmp))
        best = measure(args, rows)
        print(f"{os.path.basename(args.model)} {args.material}, 1280x720, {args.lights} light(s) (light-*: one); "
              f"{platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}; best of {args.repeat} "
              f"frames x {args.rounds} interleaved rounds; {args.covered:,} of 1280 x 720 pixels covered")
        for name, ms in best.items():
            print(f"{name:14s} CPU {ms:8.1f} ms  x{ms / best['f_a']:.2f} f_a")
        if args.callgrind:
            callgrind_passes(args, rows)
        for name in ("full", "stream8", "fma") if args.asm else ():
            if name in rows:
                print(f"JIT code of {name}: " + ", ".join(f"{k} {v}" for k, v in jit_counts(args, rows[name]).items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
