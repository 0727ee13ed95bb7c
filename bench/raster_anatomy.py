#!/usr/bin/env python3
"""Where the raster frame's time goes under lavapipe (docs/RASTER.md "What lavapipe does with the
network"): bench/raster_frame.py's 1280x720 scene drawn by hbrdf_raster on saved shaders, the
hybrid per-pixel frame against variants of its generated code, in interleaved rounds, CPU ms.
The variants are measurements, not products (some drop terms of the model).

    python bench/raster_anatomy.py [--model results/rgl54_hybrid_32x2.safetensors] [--material paper_white_rgb.rgl]
                                   [--lights 2] [--rounds 3] [--repeat 3] [--variants NAME...] [--asm]
                                   [--tool build/hbrdf_raster] [--tool-uniform build/hbrdf_raster_bench_uniform]

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
  buffer, uniform  every weight and bias of hbrdf_eval_pixel's network read at a constant offset from a
                 storage buffer (the Lights buffer's first point lights) or the uniform block (after the
                 camera; the bench-only build --tool-uniform); loops: constant arrays in [[unroll]] loops;
                 loops-buffer, loops-uniform: such loops reading the buffer; -blocked4 as blocked4 (WEIGHT_FORMS)
--callgrind runs one frame of "full" and "loop-test-top" under valgrind's callgrind (LP_NUM_THREADS=1,
minutes each) and prints, for the JIT function that executes the most instructions, how many of its
instructions ran how many times (the light loop's body: passes x shaded 8-lane vectors).
--asm attaches gdb to a running hbrdf_raster of the "full", "stream8", "fma" and weight-form rows, dumps the JIT code
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
import struct
import subprocess
import sys
import tempfile
import time

from hybridbrdf.raster import draw_frame
from hybridbrdf.raster.sizes import LAVAPIPE_ICD
from hybridbrdf.render import read_exr
from raster_frame import scene

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: The weight forms (docs/RASTER.md "The floor under lavapipe"): every weight and bias of the per-pixel
#: network (the first layer's wi terms, the hidden and output layers) read at constant offsets from a
#: storage buffer ("buffer": the Lights buffer the tool binds, its first point lights' positions, 3
#: weights each; the frame's light loop starts after them) or from the uniform block ("uniform": the
#: camera's block followed by the weights, the bench-only build hbrdf_raster_bench_uniform), kept in
#: constant arrays indexed in [[unroll]] loops ("loops": the generator's loops form written for the
#: per-pixel form), or such loops reading either buffer; "-blocked4": the hidden layer's sums four
#: outputs at a time.
WEIGHT_FORMS = ("buffer", "buffer-blocked4", "uniform", "uniform-blocked4", "loops", "loops-blocked4", "loops-buffer",
                "loops-buffer-blocked4", "loops-uniform", "loops-uniform-blocked4")
VARIANTS = ["f_a", "full", "no-hidden", "no-network", "no-exp", "no-energy", "blocked4", "stream8", "fma", "light-below",
            "light-above", "loop-test-top", "seg64", "seg1024", "f_a-seg64", "f_a-seg1024",
            "width512", "threads1", *WEIGHT_FORMS]
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


LITERAL = re.compile(r"(?<=[\s(\-])(\d+(?:\.\d*)?(?:e[-+]?\d+)?)f(?=[\s;)])")
NETWORK_LINE = re.compile(r"^\s*(float h[01]_\d+ =|o\[\d\] [+]?=|float a\d+ =|a\d+ \+=)")


def buffer_read(index: str, uniform: bool = False) -> str:
    """The weight at ``index`` (a GLSL int expression) of the weights stored as the Lights buffer's first
    point lights' positions (lights[2 i].xyz holds weights 3 i .. 3 i + 2), or ``uniform`` in the
    camera's block (camera.weights[i / 4][i % 4]: std140 pads a float array's elements to 16 bytes)."""
    if uniform:
        return f"camera.weights[({index}) / 4][({index}) % 4]"
    return f"lights[2u * uint(({index}) / 3)][({index}) % 3]"


def literals_to_buffer(lines, uniform: bool):
    """Every float literal of the network's statements replaced by a buffer read (the sign stays an
    operator): -> (lines, the literals' values in buffer order)."""
    values = []

    def read(m):
        values.append(float(m[1]))
        return buffer_read(str(len(values) - 1), uniform)
    return [LITERAL.sub(read, line) if NETWORK_LINE.match(line) else line for line in lines], values


def dense(rows, n_in: int):
    """Sums parsed by :func:`parse_sum` as (biases, row-major weights) over their n_in inputs (a term's
    input is named by its trailing index: x[k], h0_k)."""
    w = [0.0] * (len(rows) * n_in)
    for j, (_, terms) in enumerate(rows):
        for value, v in terms:
            w[j * n_in + int(re.search(r"(\d+)\]?$", v)[1])] = float(value.rstrip("f"))
    return [b for b, _ in rows], w


def loops_network(lines, hidden, outputs, block: int, source: str):
    """The network's three layers as [[unroll]] loops over constant arrays (or the buffer), the hidden
    layer's sums ``block`` outputs at a time, each sum's terms in the unrolled form's order:
    -> (head declarations, new lines, the values the buffer must hold: [] for the arrays)."""
    first = [i for i, line in enumerate(lines) if line.strip().startswith("float h0_")]
    rows0, rows1, outs = ([parse_sum(lines[i]) for i in idx] for idx in (first, hidden, outputs))
    _, a0 = dense(rows0, 3)
    b1, w1 = dense(rows1, len(rows0))
    b2, w2 = dense(outs, len(rows1))
    arrays = {"A0": a0, "B1": [float(b.rstrip("f")) for b in b1], "W1": w1,
              "B2": [float(b.rstrip("f")) for b in b2], "W2": w2}
    offsets, values, head = {}, [], []
    for name, vals in arrays.items():
        offsets[name] = len(values)
        values += vals
        head.append(f"const float HBRDF_{name}[{len(vals)}] = float[{len(vals)}]("
                    + ", ".join(f"{v!r}f" for v in vals) + ");")
    W = ((lambda name, i: buffer_read(f"{offsets[name]} + {i}", source == "uniform")) if source
         else (lambda name, i: f"HBRDF_{name}[{i}]"))
    n0, n1, u = len(rows0), len(rows1), "[[unroll]] for"
    new = [f"    float h0[{n0}];",
           f"    {u} (int j = 0; j < {n0}; ++j) h0[j] = hbrdf_activation(px.pre0[j] + "
           + " + ".join(f"{W('A0', f'j * 3 + {k}')} * x[{k}]" for k in range(3)) + ");",
           f"    float h1[{n1}];",
           f"    {u} (int j0 = 0; j0 < {n1}; j0 += {block}) {{",
           f"        float acc[{block}];",
           f"        {u} (int i = 0; i < {block}; ++i) acc[i] = {W('B1', 'j0 + i')};",
           f"        {u} (int k = 0; k < {n0}; ++k)",
           f"            {u} (int i = 0; i < {block}; ++i) acc[i] += {W('W1', f'(j0 + i) * {n0} + k')} * h0[k];",
           f"        {u} (int i = 0; i < {block}; ++i) h1[j0 + i] = hbrdf_activation(acc[i]);",
           "    }",
           f"    {u} (int q = 0; q < {len(outs)}; ++q) {{",
           f"        float acc = {W('B2', 'q')};",
           f"        {u} (int k = 0; k < {n1}; ++k) acc += {W('W2', f'q * {n1} + k')} * h1[k];",
           "        o[q] = acc;",
           "    }"]
    kept = lines[:first[0]] + new + lines[outputs[-1] + 1:]
    return ([], kept, values) if source else (head, kept, [])


def weight_form(text: str, name: str):
    """hbrdf_eval_pixel of the generated file ``text`` in weight form ``name`` (:data:`WEIGHT_FORMS`):
    -> (new text, the weights the buffer must hold, [] where none)."""
    start = text.index("hbrdf_eval_pixel(")
    head, lines = text[:start], text[start:].split("\n")
    hidden = [i for i, line in enumerate(lines) if line.strip().startswith("float h1_")]
    outputs = [i for i, line in enumerate(lines) if line.strip().startswith("o[")]
    block = 4 if name.endswith("blocked4") else 1
    if name.startswith("loops"):
        source = "buffer" if "buffer" in name else "uniform" if "uniform" in name else ""
        arrays, lines, values = loops_network(lines, hidden, outputs, block, source)
        cut = head.rindex("\n") + 1  # the arrays before the line where hbrdf_eval_pixel's text starts
        arrays = ["#extension GL_EXT_control_flow_attributes : require"] + arrays
        return head[:cut] + "".join(a + "\n" for a in arrays) + head[cut:] + "\n".join(lines), values
    if block > 1:
        lines = blocked(lines, hidden, outputs, block, False)
    lines, values = literals_to_buffer(lines, name.startswith("uniform"))
    return head + "\n".join(lines), values


def weights_frag(frag: str, n_weights: int, uniform: bool) -> str:
    """The fragment stage for the buffer and uniform forms: model.glsl included after the Lights buffer
    (it reads it, or the camera's block); the camera's block with ``n_weights`` more floats (uniform), or
    the light loop starting after the point lights that carry them (buffer)."""
    include, lights_end = '#include "model.glsl"\n', "vec4 lights[];\n};\n"
    at = frag.index(lights_end) + len(lights_end)
    frag = (frag[:at] + include + frag[at:]).replace(include, "", 1)
    n = -(-n_weights // 4) if uniform else -(-n_weights // 3)
    edits = ((("    vec4 position;\n} camera;", f"    vec4 position;\n    vec4 weights[{n}];\n}} camera;"),) if uniform else
             (("uint k = 0u;", f"uint k = {n}u;"), ("if (n_lights > 0u)", f"if (n_lights > {n}u)")))
    for old, new in edits:
        if old not in frag:
            raise SystemExit("weight forms: the fragment stage is not the expected one")
        frag = frag.replace(old, new)
    return frag


def weights_scene(folder: pathlib.Path, name: str, hybrid_scene: str) -> str:
    """Writes weight form ``name``'s model.glsl (and, for the buffer and uniform forms, its fragment
    stage, and a scene whose first point lights carry the weights or the weights as float32 in
    ``weights.f32``) into ``folder``; returns the row's scene."""
    text, values = weight_form((folder / "model.glsl").read_text(), name)
    (folder / "model.glsl").write_text(text)
    if not values:
        return hybrid_scene
    uniform = "uniform" in name
    (folder / "frame.frag").write_text(weights_frag((folder / "frame.frag").read_text(), len(values), uniform))
    if uniform:
        values += [0.0] * (-len(values) % 4)
        (folder / "weights.f32").write_bytes(struct.pack(f"<{len(values)}f", *values))
        return hybrid_scene
    values += [0.0] * (-len(values) % 3)
    s = json.loads(pathlib.Path(hybrid_scene).read_text())
    s["lights"] = [{"type": "point", "position": values[i:i + 3], "intensity": [0, 0, 0]}
                   for i in range(0, len(values), 3)] + s["lights"]
    (folder / "scene.json").write_text(json.dumps(s))
    return str(folder / "scene.json")


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
            elif name in WEIGHT_FORMS:
                sc = weights_scene(folder, name, scenes["hybrid"])
            else:
                (folder / "model.glsl").write_text(model_variant((folder / "model.glsl").read_text(), name))
            subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", str(folder / "frame.frag"), "-o",
                            str(folder / "frag.spv")], check=True, capture_output=True)
        rows[name] = (sc, folder, seg)
    return rows


def command(args, row, repeat: int, out: str = "frame_out.exr"):
    sc, folder, seg = row
    tool = args.tool_uniform if (folder / "weights.f32").exists() else args.tool
    cmd = [tool, sc, str(folder / "vert.spv"), str(folder / "frag.spv"), "--out", str(folder / out),
           "--repeat", str(repeat), "--sphere-segments", str(seg)]
    return cmd + ([] if folder.name == "fa" else ["--model-material", "m"])


def weight_forms_differ(args, rows, work: pathlib.Path) -> dict:
    """{weight form row: the largest absolute difference of its frame (as measured) from "full"'s}: the
    forms compute the same sums in the same order, so 0 unless a rewrite went wrong."""
    full = (str(work / "hybrid.json"), work / "hybrid", 256)  # "full" as prepare() makes it
    subprocess.run(command(args, full, 0, "weight_forms_reference.exr"), check=True, capture_output=True,
                   env=row_env("full", full))
    reference = read_exr(full[1] / "weight_forms_reference.exr")
    return {name: float(abs(read_exr(row[1] / "frame_out.exr") - reference).max())
            for name, row in rows.items() if name in WEIGHT_FORMS}


def row_env(name: str, row) -> dict:
    """The environment row ``name`` runs in: lavapipe, the row's llvmpipe settings, its uniform weights."""
    weights = row[1] / "weights.f32"
    return dict(os.environ, VK_DRIVER_FILES=LAVAPIPE_ICD, **ENVIRONMENT.get(name, {}),
                **({"HBRDF_BENCH_UNIFORM": str(weights)} if weights.exists() else {}))


def measure(args, rows):
    best = {name: float("inf") for name in rows}
    for r in range(args.rounds):
        for name, row in rows.items():
            env = row_env(name, row)
            p = subprocess.run(command(args, row, args.repeat), capture_output=True, text=True, env=env)
            if p.returncode != 0:
                raise SystemExit(f"{name}: {p.stderr.strip().splitlines()[-1:]}")
            stats = dict(line.split(" ", 1) for line in p.stdout.splitlines() if " " in line)
            best[name] = min(best[name], float(stats["best_cpu_ms"]))
    return best


def jit_counts(args, row) -> dict:
    """Instruction counts of the JIT code hbrdf_raster's rasterizer threads execute (gdb + objdump)."""
    env = row_env("", row)
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
            "broadcasts": count(r"^vp?broadcast|\{1to(8|16)\}"), "jumps": count(r"^j"),
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
    ap.add_argument("--variants", nargs="+", choices=VARIANTS,
                    default=[v for v in VARIANTS if v != "no-energy" and v not in WEIGHT_FORMS],
                    help="rows to draw (default: all but no-energy and the weight forms)")
    ap.add_argument("--asm", action="store_true", help="count the JIT code's instructions of full, stream8, fma and the "
                                                         "weight forms (gdb)")
    ap.add_argument("--callgrind", action="store_true", help="count the light loop's passes under callgrind (minutes)")
    ap.add_argument("--tool", default=os.environ.get("HBRDF_RASTER", str(ROOT / "build" / "hbrdf_raster")))
    ap.add_argument("--tool-uniform", default=str(ROOT / "build" / "hbrdf_raster_bench_uniform"),
                    help="the bench-only build of hbrdf_raster the uniform rows run (cmake --build build --target "
                         "hbrdf_raster_bench_uniform)")
    args = ap.parse_args()
    args.variants = ["f_a"] + [v for v in args.variants if v != "f_a"]
    if any("uniform" in v for v in args.variants) and not os.access(args.tool_uniform, os.X_OK):
        raise SystemExit(f"{args.tool_uniform}: not built (cmake --build build --target hbrdf_raster_bench_uniform)")
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
        if any(name in WEIGHT_FORMS for name in rows):
            print("frame's largest difference from full's: " + ", ".join(
                f"{name} {d:.3g}" for name, d in weight_forms_differ(args, rows, pathlib.Path(tmp)).items()))
        if args.callgrind:
            callgrind_passes(args, rows)
        for name in ("full", "stream8", "fma", *WEIGHT_FORMS) if args.asm else ():
            if name in rows:
                print(f"JIT code of {name}: " + ", ".join(f"{k} {v}" for k, v in jit_counts(args, rows[name]).items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
