"""The fuzz suite at scale: seeded random inputs through every surface of
tests/python/fuzz_surfaces.py, counted per outcome. A broken invariant is printed with the
input that broke it and makes the exit status 1.

    python3 bench/fuzz_scale.py                 # the full run (docs/CONVENTIONS.md, "Hostile input")
    python3 bench/fuzz_scale.py --scale 0.01    # a quick look

Surfaces and their inputs: model files (byte damage: both loaders must agree), model metadata
(JSON edits: both loaders, same words), tensor values (any float32 in any tensor), material
names (both loaders, then generated GLSL/HLSL/C++ for the accepted ones), measured files (RGL,
NBRDF, MERL and UTIA readers on damaged files), scenes (the tracer's scene reader), KTX2 maps
(structure-aware damage through both readers, tests/python/fuzz_ktx2.py), glTF assets (structure-aware
damage through the bounded reader, tests/python/fuzz_gltf.py), checkpoints
(damaged bytes, and edited states re-encoded with a valid checksum), command-line
flags (every typed flag of every hbrdf command) and directions (float32 bit patterns through the
library's batched and scalar paths and torch).

Hostile inputs, round two, every one invalid and each bounded in time and memory
(tests/python/fuzz_surfaces.py, check_hostile): special files (FIFO, symlink to /dev/zero, 1 TiB
sparse file, symlink loop, folder) through every reader; structured JSON (deep nesting, wrong
types, huge counts) as model metadata and as scene files, and tabulated scenes over the tracer's
table budget; forged sizes (safetensors header lengths, shapes and offsets; Radiance HDR header
dimensions); and output over input (hbrdf-codegen -o and hbrdf render -o reaching the model or
the scene by the same path, a symlink, a hard link or a dot-dot path).

Round three (issue 45), every input invalid too: API type confusion (a wrong type or value for one
argument of a public function: edit, mix, albedo, eval, AnalyticParams, analytic_eval, sample,
pdf, BRDFSource.eval), absurd counts (10^8 .. 2^50 through the API's counts and pair counts as
broadcast views, and hbrdf's count flags), non-finite environment maps (+-Inf, NaN and negative
texels through the tracer and hbrdf view --env) and extreme geometry (planes, spheres, meshes and
cameras at 3e10 .. 3e38). The headline counts the inputs and violations of each of these kinds."""

from __future__ import annotations

import argparse
import collections
import json
import os
import pathlib
import platform
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))

import fuzz_surfaces as fs  # noqa: E402

import hybridbrdf as hb  # noqa: E402
from hybridbrdf import _core  # noqa: E402


def run(name, n, make_input, check, counts, failures, budget_s=None):
    t0 = time.perf_counter()
    done = 0
    for i in range(n):
        args = make_input(i)
        try:
            counts[name][check(*args)] += 1
        except fs.Violation as v:
            counts[name]["VIOLATION"] += 1
            if len(failures) < 50:
                failures.append(f"{name}: {v}"[:600])
        done += 1
        if budget_s and time.perf_counter() - t0 > budget_s:
            break
    counts[name]["_seconds"] = round(time.perf_counter() - t0, 1)
    return done


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every surface's input count")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    k = args.scale
    rng = np.random.default_rng(args.seed)
    counts = collections.defaultdict(collections.Counter)
    failures = []
    work = pathlib.Path(tempfile.mkdtemp(prefix="hbrdf-fuzz-"))
    seeds = {a: fs.model_seed_bytes(a) for a in ("hybrid", "neural")}
    docs = {a: fs.seed_metadata(s) for a, s in seeds.items()}
    path = work / "m.safetensors"
    archs = list(seeds)

    run("model file bytes", int(40_000 * k),
        lambda i: (fs.mutate_bytes(seeds[archs[i % 2]], rng), path), fs.check_model_file, counts, failures)
    run("model metadata", int(40_000 * k),
        lambda i: (fs.model_with_metadata(seeds[archs[i % 2]], fs.mutate_doc(docs[archs[i % 2]], rng)), path),
        fs.check_model_file, counts, failures)

    import safetensors.numpy

    base_tensors = safetensors.numpy.load(seeds["hybrid"])
    meta = {"hybridbrdf": json.dumps(docs["hybrid"])}
    names = sorted(base_tensors)
    bit_patterns = np.concatenate([rng.integers(0, 2**32, 64, dtype=np.uint64).astype(np.uint32),
                                   np.array([0x7F800000, 0xFF800000, 0x7FC00000, 0x00000001, 0x7F7FFFFF,
                                             0xFF7FFFFF, 0x80000000], np.uint32)])

    def tensor_input(i):
        t = dict(base_tensors)
        name = names[i % len(names)]
        flat = t[name].reshape(-1).copy()
        flat[int(rng.integers(0, flat.size))] = bit_patterns[int(rng.integers(0, len(bit_patterns)))].view(np.float32) \
            if rng.random() < 0.5 else np.float32(rng.normal() * 10.0 ** rng.integers(-3, 39))
        t[name] = flat.reshape(t[name].shape)
        return safetensors.numpy.save(t, meta), path

    run("tensor values", int(20_000 * k), tensor_input, fs.check_model_file, counts, failures)

    alphabet = list("abcXYZ019_.+-")

    def name_input(i):
        if rng.random() < 0.5:
            name = "".join(rng.choice(alphabet, size=int(rng.integers(1, 70))))
        else:
            name = "".join(chr(int(c)) for c in rng.integers(0, 0x300, size=int(rng.integers(0, 8))))
        return name, seeds["hybrid"], path

    run("material names (+codegen)", int(3_000 * k), name_input, fs.check_material_name, counts, failures)

    # Measured files: small valid seeds of each format, damaged.
    from test_sources_nbrdf import tiny_layers, write_network
    from test_sources_rgl import synthetic_fields, write_tensor

    rgl_seed = write_tensor(work / "seed.bsdf", synthetic_fields(rng=np.random.default_rng(1))).read_bytes()
    write_network(work / "seed.h5", tiny_layers(), activations=["relu", "relu"])
    h5_seed = (work / "seed.h5").read_bytes()
    from hybridbrdf.sources.merl import write_merl
    from hybridbrdf.sources.utia import write_utia
    from hybridbrdf.sources.synthetic import open_synthetic

    gold = open_synthetic("gold")
    write_merl(work / "seed.binary", gold)
    write_utia(work / "seed.bin", gold)
    merl_seed, utia_seed = (work / "seed.binary").read_bytes(), (work / "seed.bin").read_bytes()
    for label, seed, ext, n in (("RGL .bsdf", rgl_seed, ".bsdf", 20_000), ("NBRDF .h5", h5_seed, ".h5", 10_000),
                                ("MERL .binary", merl_seed, ".binary", 300), ("UTIA .bin", utia_seed, ".bin", 300)):
        run(f"measured files: {label}", int(n * k), lambda i, s=seed, e=ext: (fs.mutate_bytes(s, rng), work / f"x{e}"),
            fs.check_source_file, counts, failures)

    if hasattr(_core, "read_scene_decl"):
        scene = json.loads((ROOT / "scenes" / "sphere_env.json").read_text())
        run("scenes", int(200_000 * k), lambda i: (fs.mutate_doc(scene, rng),), fs.check_scene, counts, failures)

    ck_bytes, ck_state, ck_settings = fs.checkpoint_seed(work)
    from hybridbrdf.fit import checkpoint as ckpt

    run("checkpoint bytes", int(20_000 * k),
        lambda i: (fs.mutate_bytes(ck_bytes, rng), work / "ck.pt", ck_settings), fs.check_checkpoint, counts, failures)
    run("checkpoint structure", int(5_000 * k),
        lambda i: (ckpt.encode(fs.mutate_checkpoint_state(ck_state, rng)), work / "ck.pt", ck_settings),
        fs.check_checkpoint, counts, failures)

    if hasattr(_core, "render_read_ktx2"):  # KTX2 maps (issue 58): both readers, same levels or same words
        import fuzz_ktx2

        ktx2_seeds = list(fuzz_ktx2.seed_files().values())
        run("KTX2 files (both readers)", int(20_000 * k),
            lambda i: (fuzz_ktx2.mutate_ktx2(ktx2_seeds[i % len(ktx2_seeds)], rng), work / "t.ktx2"),
            fuzz_ktx2.check_ktx2, counts, failures)

    import fuzz_gltf  # glTF assets (issue 59): the bounded reader refuses in one line or reads every part

    gltf_seeds = list(fuzz_gltf.seed_assets().values())
    run("glTF assets (bounded reader)", int(20_000 * k),
        lambda i: (fuzz_gltf.mutate_gltf(gltf_seeds[i % 2], rng), work / ("t.glb" if i % 2 == 0 else "t.gltf")),
        fuzz_gltf.check_gltf, counts, failures)

    flags = fs.cli_flags()
    values = ["0", "-1", "1", "inf", "-inf", "nan", "1e999", "4294967297", "2147483648", "-0", "1.5", "1e-400",
              "9" * 400, "0x10", "1_000", " 3", "+5", "", "1e308", "-1e-320", "2**31", "७"]

    def flag_input(i):
        cmd, flag = flags[i % len(flags)]
        v = values[int(rng.integers(0, len(values)))] if rng.random() < 0.6 else \
            "".join(chr(int(c)) for c in rng.integers(32, 0x250, size=int(rng.integers(0, 8))))
        return cmd, flag, v

    run("cli flags", int(60_000 * k), flag_input, fs.check_cli_flag, counts, failures)

    # Directions: float32 bit patterns (1/4 fully random, the rest hostile specials mixed with
    # normal values) through the library's batched and scalar paths and torch.
    model_path = work / "seed-model.safetensors"
    model_path.write_bytes(seeds["hybrid"])
    cpp_model, py_model = _core.Model(str(model_path)), hb.load_model(model_path)
    specials = np.array([0.0, -0.0, 1e-45, -1e-45, 1e-38, 1e-30, 1e30, -1e30, 1e-4, -1e-4, np.inf, -np.inf, np.nan,
                         1.0, -1.0, 3.4e38], np.float32)
    n_dir = int(1_000_000 * k)
    t0 = time.perf_counter()
    bad = 0
    batch = 50_000
    for start in range(0, n_dir, batch):
        m = min(batch, n_dir - start)
        d = rng.normal(size=(m, 6)).astype(np.float32)
        mask = rng.random((m, 6)) < 0.3
        d[mask] = specials[rng.integers(0, len(specials), int(mask.sum()))]
        raw = rng.random(m) < 0.25
        d[raw] = rng.integers(0, 2**32, (int(raw.sum()), 6), dtype=np.uint64).astype(np.uint32).view(np.float32)
        wi, wo = np.ascontiguousarray(d[:, :3]), np.ascontiguousarray(d[:, 3:])
        mat = start // batch % 3
        for label, f in (("batched", cpp_model.eval(wi, wo, mat)), ("scalar", cpp_model.eval_scalar(wi, wo, mat)),
                         ("analytic", cpp_model.eval_analytic(wi, wo, mat)), ("torch float32", py_model.eval(wi, wo, mat))):
            f = np.asarray(f)
            ok = np.isfinite(f).all(axis=1) & (f >= 0).all(axis=1)
            counts[f"directions: {label}"]["valid"] += int(ok.sum())
            counts[f"directions: {label}"]["VIOLATION"] += int((~ok).sum())
            if (~ok).any() and len(failures) < 50:
                failures.append(f"directions {label}: wi {wi[~ok][0]} wo {wo[~ok][0]} -> {f[~ok][0]}")
            bad += int((~ok).sum())
    for label in ("batched", "scalar", "analytic", "torch float32"):
        counts[f"directions: {label}"]["_seconds"] = round(time.perf_counter() - t0, 1)

    hostile_round_two(k, rng, work, seeds, docs, counts, failures)
    hostile_round_three(k, rng, work, counts, failures)

    def inputs(c):
        return sum(v for key, v in c.items() if not key.startswith("_"))

    total = sum(inputs(c) for c in counts.values())
    violations = sum(c["VIOLATION"] for c in counts.values())
    groups = []
    for kind in HOSTILE_KINDS:
        cs = [c for name, c in counts.items() if name.startswith(kind + ":")]
        groups.append(f"{kind} {sum(inputs(c) for c in cs):,} ({sum(c['VIOLATION'] for c in cs)} violations)")
    print(f"# fuzz_scale: {total:,} inputs, {violations} violations; of them {', '.join(groups)} "
          f"(seed {args.seed}, scale {args.scale}; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, simd {hb.simd_path()})")
    print(f"| surface | inputs | valid | rejected (one line) | violations | seconds |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, c in counts.items():
        n = sum(v for key, v in c.items() if not key.startswith("_"))
        print(f"| {name} | {n:,} | {c['valid']:,} | {c['rejected']:,} | {c['VIOLATION']} | {c['_seconds']} |")
    for f in failures:
        print("VIOLATION", f)
    return 1 if violations else 0


HOSTILE_KINDS = ("special files", "structured JSON", "forged sizes", "output over input", "API type confusion",
                 "absurd counts", "non-finite environment maps", "extreme geometry")


def refused(check):
    """``check`` where every input is invalid by construction: "valid" is a violation too."""
    def refused_check(*args):
        outcome = check(*args)
        if outcome != fs.REJECTED:
            raise fs.Violation(f"{check.__name__}: a forged input was accepted")
        return outcome
    return refused_check


def hostile_round_two(k, rng, work, seeds, docs, counts, failures):
    """The hostile inputs of round two, named "<kind>: <surface>" so that the headline can count each kind."""
    hostile = work / "hostile"
    hostile.mkdir()
    for reader in fs.READERS:
        run(f"special files: {reader}", int(200 * k),
            lambda i, r=reader: (r, fs.SPECIAL_KINDS[i % len(fs.SPECIAL_KINDS)], hostile, str(i)),
            fs.check_special_file, counts, failures)
    archs = list(seeds)
    scene = json.loads((ROOT / "scenes" / "sphere_env.json").read_text())
    for kind in fs.JSON_KINDS:
        run(f"structured JSON: model metadata, {kind}", int(3_000 * k),
            lambda i, kd=kind: (fs.model_with_metadata_text(seeds[archs[i % 2]],
                                                            fs.hostile_json_text(docs[archs[i % 2]], kd, rng)),
                                work / "h.safetensors"),
            fs.check_model_file, counts, failures)
        run(f"structured JSON: scene files, {kind}", int(5_000 * k),
            lambda i, kd=kind: (fs.hostile_json_text(scene, kd, rng), work / "h.json"),
            fs.check_scene_file, counts, failures)
    if getattr(_core, "HAVE_RENDERER", False):
        run("structured JSON: tabulated scenes over the budget", int(300 * k),
            lambda i: (int(rng.integers(6, 2000)), work / "t.json"), fs.check_tabulated_budget, counts, failures)
    run("forged sizes: safetensors", int(10_000 * k),
        lambda i: (fs.forged_safetensors(seeds[archs[i % 2]], rng), work / "f.safetensors"),
        refused(fs.check_model_file), counts, failures)
    if getattr(_core, "HAVE_RENDERER", False):
        run("forged sizes: Radiance HDR header", int(3_000 * k),
            lambda i: (fs.forged_hdr(rng), work / "f.hdr"), fs.check_hdr_file, counts, failures)
    cases = [(c, kd, w) for c in ("codegen", "render") for kd in fs.OUTPUT_KINDS for w in ("model", "scene")
             if c == "codegen" or getattr(_core, "HAVE_RENDERER", False)]
    out = work / "out"
    out.mkdir()
    run("output over input: hbrdf-codegen -o, hbrdf render -o", int(400 * k),
        lambda i: (*cases[i % len(cases)], out, seeds["hybrid"]), fs.check_output_over_input, counts, failures)


def hostile_round_three(k, rng, work, counts, failures):
    """The hostile inputs of round three (issue 45), every one invalid: wrong types at the public
    API, absurd counts through the API and hbrdf's count flags, non-finite or negative environment
    texels through the tracer and hbrdf view --env, geometry beyond float32's reach."""
    third = work / "round3"
    third.mkdir()
    model, source = fs.api_seed(third)
    run("API type confusion: public functions", int(20_000 * k),
        lambda i: (*fs.api_type_confusion(rng), model, source), fs.check_api_call, counts, failures)
    run("absurd counts: API counts and pair counts", int(3_000 * k),
        lambda i: (*fs.absurd_count(rng), model), fs.check_absurd_count, counts, failures)
    run("absurd counts: hbrdf count flags", int(1_000 * k),
        lambda i: (*fs.COUNT_FLAGS[i % len(fs.COUNT_FLAGS)], fs.CLI_COUNTS[int(rng.integers(0, len(fs.CLI_COUNTS)))],
                   third, pathlib.Path(model.path)), fs.check_cli_count, counts, failures)
    if getattr(_core, "HAVE_RENDERER", False):
        run("non-finite environment maps: render, hbrdf view --env", int(1_000 * k),
            lambda i: (fs.ENV_KINDS[i % len(fs.ENV_KINDS)], rng, third, ("render", "view")[i // len(fs.ENV_KINDS) % 2]),
            fs.check_environment, counts, failures)
        run("extreme geometry: spheres, planes, meshes, camera", int(2_000 * k),
            lambda i: (fs.GEOMETRY_KINDS[i % len(fs.GEOMETRY_KINDS)], rng, third), fs.check_extreme_geometry,
            counts, failures)


if __name__ == "__main__":
    sys.exit(main())
