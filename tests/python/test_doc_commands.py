"""Every command line README.md and docs/*.md show works as printed (issue 57; doc_commands.py
extracts them: ``hbrdf``, ``hbrdf-codegen``, ``python bench/``, ``python -m``, ``torchrun``).

(a) Each one is parsed by the real parser of its program, without running it: ``hbrdf``'s
    ``build_parser()``, ``hbrdf-codegen``'s, each bench script's own ``argparse`` (the script runs
    up to its ``parse_args`` and stops there), torchrun's ``get_args_parser()``, pytest's own (its
    ``--collect-only``: the files exist and ``-k`` selects tests). A synopsis is parsed in each of
    the argument lists it stands for (doc_commands.expand), CAPITALISED placeholders replaced by
    ``PLACEHOLDERS``. A flag that no longer exists, a value its type refuses or a required
    argument left out fails here.
(b) The commands of ``RUN`` (a few seconds each) run as printed, by the shell, in a scratch folder
    laid out like the repository (``results``, ``scenes``) with ``../shared`` beside it, and must
    exit 0 and write the files they promise. A synopsis in ``RUN`` runs its minimal form (no
    optional flags), which it shows with real paths.
(c) ``NOT_RUN`` lists every other command that is not a synopsis, with the reason (a fit, a full
    benchmark, a file it overwrites); ``NOT_COMMANDS`` the lines that only look like one (a
    program's output). A new command in the documents fails until it is put in one of them.
"""

import json
import os
import pathlib
import re
import shlex
import subprocess
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from doc_commands import ROOT, documented_commands, expand, is_synopsis  # noqa: E402
from helpers import run_shared_path  # noqa: E402

SHARED = ROOT.parent / "shared"
MODEL = "results/rgl54_fast.safetensors"  # tracked: a model every placeholder MODEL can name
MASK = "scenes/textured_mask.png"

#: What a placeholder of a synopsis becomes when it is parsed (paths relative to the repository).
PLACEHOLDERS = {
    "MODEL": MODEL, "BASE": MODEL, "MODEL2": "out/model2.safetensors", "M": "out/M", "CK": "out/fit.ckpt",
    "SOURCE": "synthetic:gold", "MATERIAL": "paper_white_rgb.rgl", "MATERIAL_OR_FILE": "synthetic:gold",
    "A": "paper_white_rgb.rgl", "B": "vch_golden_yellow_rgb.rgl", "NAME": "new_material",
    "MASK": MASK, "MASK.png": MASK, "ALBEDO": MASK, "ALBEDO.png": MASK, "ROUGHNESS": MASK, "R.png": MASK,
    "DIR": "out/dir", "SRC": "out/dir", "DIR2": "out/dir2", "CAPTURE": "out/capture", "RIG.json": "out/rig.json", "OUT": "out/materials.glsl",
    "SCENE.json": "scenes/sphere_env.json", "S.json": "scenes/sphere_env.json", "OUT.exr": "out/image.exr",
    "OUT.png": "out/image.png", "MAP.exr": "out/environment.exr", "HOST0:29500": "localhost:29500",
    "MODEL_OR_SVBRDF": MODEL, "OUT.glb": "out/asset.glb", "FILE.obj": "out/mesh.obj",
    "N": "2", "K": "0", "EV": "0.5", "EPS": "0.1", "DEVICE": "cpu", "KxV": "2x3", "WxH": "8x8", "D": "0.3", "P": "1000", "E": "2", "S": "0.001",
}
#: "hbrdf fit ..." stands for a whole fit command line.
ELLIPSES = {"hbrdf fit ...": "hbrdf fit SOURCE... --out MODEL2"}

#: Commands run as printed (b): the command -> the files it promises (relative to the scratch folder).
RUN = {
    "hbrdf-codegen results/rgl54_fast.safetensors --target glsl --materials paper_white_rgb.rgl -o materials.glsl":
        ["materials.glsl"],
    "hbrdf-codegen results/rgl54_fast.safetensors --target hlsl --materials paper_white_rgb.rgl -o materials.hlsl":
        ["materials.hlsl"],
    "hbrdf-codegen results/rgl54_fast.safetensors --target glsl --materials paper_white_rgb.rgl --per-pixel -o pixel.glsl":
        ["pixel.glsl"],
    # RENDERING.md's synopsis; its minimal form is the page's example scene.
    "hbrdf render scenes/sphere_env.json -o out/sphere.exr --png out/sphere.png [--spp N] [--max-depth N] "
    "[--neural-max-depth N] [--sampler cosine|ggx|mis|tabulated] [--nee|--no-nee] [--seed N] [--threads N] "
    "[... one flag per setting below] [--exposure EV] [--tonemap clamp|aces] [--quiet]":
        ["out/sphere.exr", "out/sphere.png"],
}

RGL = "../shared/data/rgl ../shared/data/nbrdf/rgl"
FIT_120K = "the 120k-step fit of the 54 RGL materials: hours"
#: Commands not run (c): the command -> why.
NOT_RUN = {
    "hbrdf fit synthetic:all --steps 3000 --out out/synthetic.safetensors":
        "the README's main job, about a minute (scripts/test.sh's first stage runs it)",
    "python3 -m pytest tests/python/test_svbrdf.py": "a test file of this suite",
    "hbrdf demo --out out/analytic_slices.png": "8-19 s here (10^6 samples per strategy, matplotlib, torch); "
                                                "test_cli_and_packaging.py runs it with --samples 2000",
    "python3 -m pytest tests/python/test_fitting.py -k resume": "tests of this suite (fits)",
    "hbrdf acquire fit capture --out acquired": "a per-texel fit of a 512x512 capture: minutes",
    "/usr/bin/time -v hbrdf acquire fit capture --out acquired --quiet": "the same fit, its memory measured",
    "python bench/svbrdf_mixture.py --write-masks M --mask-size 512": "writes 512x512 masks; 10 s",
    "/usr/bin/time -v hbrdf acquire simulate --flash 16 --size 512x512 --base ../shared/data/rgl/paper_white_rgb.bsdf "
    "--layer ../shared/data/rgl/vch_golden_yellow_rgb.bsdf=M/mask1.png --layer "
    "../shared/data/nbrdf/rgl/ilm_l3_37_metallic_rgb.h5=M/mask2.png --photons 1000 --read-noise 2 "
    "--light-jitter 0.001 --seed 1 --out capture --quiet": "16 photographs of 512x512: 13.5 s, after the masks above",
    "python bench/acquire_compare.py": "the acquisition sweep: an hour",
    "python bench/acquire_verdict.py --machine M2": "the acquisition sweep on three rigs with seeds: 40 minutes on M2",
    "python bench/acquire_verdict.py --rig light-stage --models analytic,hybrid_heldout,neural_heldout --machine X1": (
        "the light-stage verdict, 3 seeds of three models: 30 minutes on X1"),
    "python bench/acquire_verdict.py --rig light-stage --models analytic,hybrid_heldout,neural_heldout --machine M1": (
        "the light-stage verdict, 3 seeds of three models: 19 minutes on M1"),
    "python bench/acquire_verdict.py --rig flash,flash-multiview --models analytic,hybrid_heldout,neural_heldout --machine M1": (
        "the flash and multi-view flash verdict, 3 seeds of three models: 19 minutes on M1"),
    "python bench/acquire_gap.py --samples napoli2 --seeds 0 --configs base,select --machine M2":
        "two acquisition fits per capture at two noise levels, scored against hbrdf add references: minutes",
    "python bench/acquire_gap.py --seeds 0,1 --configs finetune200 --machine M2":
        "eight acquisition fits (two samples, two noise levels, two seeds) against hbrdf add references: 20 minutes",
    "python bench/acquire_gap.py --seeds 0,1 --configs finetune200 --machine X1":
        "eight acquisition fits (two samples, two noise levels, two seeds) against hbrdf add references: 25 minutes",
    "python bench/acquire_compare.py --plot results/acquire_compare_X1.jsonl":
        "overwrites the tracked figure docs/figures/acquire_compare.png",
    "hbrdf fit --frozen results/rgl54_hybrid_32x2_e09_120k.safetensors ../shared/data/rgl ../shared/data/nbrdf/rgl "
    "--steps 3000 --loss-eps 0.1 --specular 0.1 --analytic-expectile 0.9 --compile --eval-pairs 1000000 "
    "--out results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors": "a sparse refit of 54 materials: minutes",
    "python bench/rgl_paper_comparison.py results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors":
        "10^6 pairs per material against the paper's table: 20 s",
    "python bench/rgl_paper_comparison.py results/rgl49_hybrid_32x2_e01_wd0_120k_sparse_rgl5.safetensors":
        "needs the model of the sparse_heldout run above (not tracked)",
    "python bench/sparse_heldout.py --with-reconstructions --steps 120000 --sparse-steps 5000 --loss-eps 0.1 "
    "--specular 0.1 --analytic-expectile 0.9 --weight-decay 0 --compile --checkpoint out/sp_e01_120k_wd0/ckpt.pt "
    "--out-dir out/sp_e01_120k_wd0": FIT_120K,
    "python bench/bench_analytic.py": "a timing benchmark (7 repeats of 2^20 pairs per strategy)",
    "python bench/speed_guard.py": "scripts/test.sh's speed-guard stage: 14 s",
    "python bench/speed_guard.py --timed --runs 5": "a timing benchmark",
    "python bench/bench_inference.py --out docs/figures/cost_accuracy": "overwrites tracked figures; minutes",
    "python bench/render_cost.py --runs 1": "a rendering benchmark: minutes",
    "python bench/gpu_measure.py prepare": "compiles every shader variant for the GPU machine: minutes",
    "python3 bench/gpu_measure.py device": "runs on the GPU machine only",
    f"hbrdf fit {RGL} --arch hybrid --mlp 32x2 --latent 4 --activation hardgelu --steps 60000 --loss-eps 0.01 "
    "--eval-pairs 1000000 --out results/rgl54_hybrid_32x2.safetensors": "a 60k-step fit of 54 materials: an hour",
    "python bench/rgl_paper_comparison.py results/rgl54_hybrid_32x2.safetensors":
        "10^6 pairs per material against the paper's table: 20 s",
    f"hbrdf fit {RGL} --arch hybrid --mlp 32x2 --latent 4 --activation hardgelu --steps 60000 --loss-eps 0.01 "
    "--specular 0.1 --eval-pairs 1000000 --out results/rgl54_hybrid_32x2_spec.safetensors":
        "a 60k-step fit of 54 materials: an hour",
    "python bench/rgl_paper_comparison.py results/rgl54_hybrid_32x2_e09_120k.safetensors":
        "10^6 pairs per material against the paper's table: 20 s",
    "python bench/sparse_heldout.py --steps 20000 --sparse-steps 5000 --sparse-init neutral": "fits: an hour",
    "python bench/sparse_heldout.py --with-reconstructions --steps 20000 --sparse-steps 5000 --specular 0.1 "
    "--analytic-expectile 0.9 --compile": "fits: an hour",
    "python bench/bench_fit_time.py --schedules cosine,old --snapshot-every 200 --out out/fit_time_cosine "
    "--save-model results/rgl54_hybrid_32x2_fast58k_refit01.safetensors": "fits of 54 materials: hours",
    "python bench/fp16_cost.py results/rgl54_hybrid_32x2.safetensors ../shared/data/rgl":
        "10^6 pairs per material in two precisions: a minute",
    "python bench/half_arith_accuracy.py": "half-precision arithmetic emulated over 5 materials: 30 s",
    "python bench/dialect_speed.py [--rounds 5] [--pairs 1048576]": "a timing benchmark of every dialect",
    "hbrdf fit synthetic:all --steps 3000 --arch hybrid --out A.safetensors": "a 3000-step fit: a minute",
    "hbrdf fit synthetic:all --steps 3000 --arch hybrid-reciprocal --out B.safetensors": "a 3000-step fit: a minute",
    "hbrdf eval A.safetensors synthetic:all --all-metrics": "evaluates the fit above (not run)",
    "python bench/bench_training.py --steps 150": "a training-speed benchmark: a minute",
    "python bench/bench_distributed.py --steps 600": "two fits of 54 materials under torchrun: a minute",
    f"hbrdf fit {RGL} --recipe fast --compile --out M.safetensors": "the 30-minute recipe",
    f"hbrdf fit {RGL} --recipe fast --mlp 32x2 --steps 15000 --latent 64 --loss-eps 0.1 --compile --out "
    "M.safetensors": "a 15k-step fit of 54 materials: 20 minutes",
    f"hbrdf fit {RGL} --recipe fast --mlp 32x2 --output-layer shared --compile --out M.safetensors":
        "the 30-minute recipe",
    f"hbrdf fit --frozen M.safetensors {RGL} --steps 3000 --loss-eps 0.05 --specular 0.1 --analytic-expectile 0.9 "
    "--compile --out M2.safetensors": "a sparse refit of the fit above",
    "python bench/bench_fit_time.py --snapshot-every 200 --save-model "
    "results/rgl54_hybrid_32x2_fast58k_exp_refit005.safetensors": "fits of 54 materials: hours",
    "python bench/render_error.py --hybrid results/rgl54_hybrid_32x3_10k.safetensors --neural "
    "results/rgl54_neural_32x3_10k.safetensors ../shared/data/rgl --size 128 --spp 256":
        "reference renders at 2048 spp: minutes",
    "python bench/render_selective.py --size 256 --spp 32": "a rendering benchmark: a minute",
    "python bench/viewer_load.py --runs 3": "starts chromium three times: a minute",
}
NOT_RUN.update({  # docs/GLTF.md: each fallback fit takes seconds; test_gltf.py runs hbrdf export on one material
    "hbrdf export results/rgl54_fast.safetensors --gltf out/two.glb --material paper_white_rgb.rgl "
    "vch_golden_yellow_rgb.rgl": "two fallback fits, 5-20 s; test_gltf.py exports the same two materials",
    "python bench/gltf_fallback.py": "fits the fallback of each of the shipped prior's 142 materials: minutes"})
NOT_RUN.update({  # docs/RECIPROCITY.md's RGL 54 block: a long fit and 10^6-pair evaluations of 54 materials
    "OMP_NUM_THREADS=1 hbrdf fit ../shared/data/rgl ../shared/data/nbrdf/rgl --recipe fast --arch hybrid-reciprocal "
    "--compile --out results/rgl54_fast_reciprocal.safetensors": "a 58,000-step fit: hours on one thread",
    "hbrdf eval results/rgl54_fast_reciprocal.safetensors ../shared/data/nbrdf/rgl --all-metrics":
        "49 materials at 10^6 pairs: minutes; test_reciprocity.py reads the same file",
    "python bench/rgl_paper_comparison.py results/rgl54_fast_reciprocal.safetensors":
        "10^6 pairs on five raw files: minutes (the same script runs on rgl54_fast elsewhere)",
    "python bench/reciprocal_fidelity.py results/rgl54_fast.safetensors results/rgl54_fast_reciprocal.safetensors "
    "../shared/data/nbrdf/rgl ../shared/data/rgl": "54 sources, both models, both orders: about 4 minutes",
    "python bench/reciprocal_fidelity.py --pairs 100000 python/hybridbrdf/data/prior.safetensors "
    "python/hybridbrdf/data/prior_reciprocal.safetensors ../shared/data/rgl ../shared/data/nbrdf/rgl "
    "../shared/data/nbrdf/merl ../shared/data/nbrdf/nielsen": "142 sources, both priors, both orders: 10 minutes"})
NOT_RUN.update({f"hbrdf-codegen out/textured --target {target} -o material.{target}": (
    "needs the folder scenes/textured.json's paint command writes; test_codegen_textured.py runs these as printed")
    for target in ("glsl", "hlsl", "slang", "wgsl")})
NOT_RUN.update({f"python bench/compare_models.py {args}": "fits of every width and depth: hours" for args in [
    f"{RGL} --mlp 32x3,16x3 --threads 1 --out-dir out/compare_rgl",
    "../shared/data/nbrdf/merl --mlp 32x3,16x3 --threads 1 --out-dir out/compare_merl",
    "../shared/data/rgl synthetic:all --mlp 16x2,16x3,32x2,32x3,64x2,64x3 --threads 1 --out-dir out/cost",
    f"{RGL} --mlp 16x3,32x3 --loss-eps 0.1 --loss-eps-relative --threads 1 --out-dir out/rel_rgl",
    "../shared/data/nbrdf/merl --mlp 16x3,32x3 --loss-eps 0.1 --loss-eps-relative --threads 1 --out-dir out/rel_merl",
    f"{RGL} --mlp 16x3,32x3 --loss-eps 0.1 --loss-eps-relative --loss-no-cos --threads 1 --out-dir out/nocos/rgl",
    f"{RGL} --mlp 16x3,32x3 --loss-eps 0.05 --loss-eps-relative --loss-no-cos --threads 1 --out-dir out/k05/rgl",
    "../shared/data/nbrdf/merl --mlp 16x3,32x3 --loss-eps 0.05 --loss-eps-relative --loss-no-cos --threads 1 "
    "--out-dir out/k05/merl"]})

#: Lines of code blocks that look like commands but are not (file, the line's start) -> what they are.
NOT_COMMANDS = {("docs/FITTING.md", "hbrdf fit /work/shared/data/rgl"): "bench_distributed.py's output"}


def program_and_argv(words):
    """(program, argv) of a command's shell words: ``hbrdf``, ``hbrdf-codegen``, ``torchrun``,
    ``pytest`` (``python -m pytest``) or a script's path (``python bench/x.py``)."""
    while words and (re.fullmatch(r"[A-Z_]+=\S*", words[0]) or words[0] in ("/usr/bin/time", "-v")):
        words = words[1:]
    if words[0] in ("python", "python3"):
        if words[1] == "-m":
            assert words[2] == "pytest", f"python -m {words[2]}: no parser known for it here"
            return "pytest", words[3:]
        return words[1], words[2:]
    return words[0], words[1:]


def argument_lists(command):
    """The argument lists a documented command stands for: itself, or a synopsis's expansions."""
    if not is_synopsis(command, PLACEHOLDERS):
        return [shlex.split(command)]
    for short, whole in ELLIPSES.items():
        command = re.sub(re.escape(short) + r"(?= |$)", whole, command)
    return expand(command, PLACEHOLDERS)


#: Runs in a fresh interpreter at the repository's root: parses each [program, argv] with the
#: program's own parser and prints, per item, "" or the parser's last line of complaint.
PARSE_RUNNER = r'''
import argparse, contextlib, io, json, os, runpy, sys


class Parsed(Exception):
    pass


_parse_args = argparse.ArgumentParser.parse_args


def _stop_after_parsing(self, args=None, namespace=None):
    _parse_args(self, args, namespace)
    raise Parsed()


def _bench(script, argv):
    sys.argv = [script, *argv]
    sys.path.insert(0, os.path.dirname(os.path.abspath(script)))
    argparse.ArgumentParser.parse_args = _stop_after_parsing
    try:
        runpy.run_path(script, run_name="__main__")
    except Parsed:
        return ""
    finally:
        argparse.ArgumentParser.parse_args = _parse_args
        sys.path.pop(0)
    return "the script ended without parsing its arguments"


def _parse(program, argv):
    if program == "hbrdf":
        from hybridbrdf.cli import build_parser
        build_parser().parse_args(argv)
    elif program == "hbrdf-codegen":
        from hybridbrdf.codegen.main import build_parser
        build_parser().parse_args(argv)
    elif program == "torchrun":
        from torch.distributed.run import get_args_parser
        a = get_args_parser().parse_args(argv)
        if a.training_script != "hbrdf" or not a.no_python:
            return f"torchrun runs {a.training_script}, not --no-python hbrdf"
        return parse("hbrdf", a.training_script_args)
    elif program == "pytest":
        import pytest
        code = pytest.main(["--collect-only", "-q", "-p", "no:cacheprovider", *argv])
        return "" if code == 0 else f"pytest --collect-only {' '.join(argv)}: exit {int(code)}"
    else:
        return _bench(program, argv)
    return ""


def parse(program, argv):
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            return _parse(program, argv)
    except SystemExit as exc:
        return "" if exc.code in (0, None) else (err.getvalue().strip().splitlines() or [f"exit {exc.code}"])[-1]
    except Exception as exc:
        return f"{type(exc).__name__}: {exc}"


items = json.load(sys.stdin)
print(json.dumps([parse(program, argv) for program, argv in items]))
'''


def parse_all(items):
    """[(where, command, argv)] -> [(where, command, argv, complaint)] for those that do not parse."""
    jobs = [program_and_argv(argv) for _, _, argv in items]
    unique = sorted({json.dumps(job) for job in jobs})  # the same line in two documents is parsed once
    r = subprocess.run([sys.executable, "-c", PARSE_RUNNER], input=json.dumps([json.loads(j) for j in unique]),
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    complaint = dict(zip(unique, json.loads(r.stdout.strip().splitlines()[-1])))
    return [(*item, complaint[json.dumps(job)]) for item, job in zip(items, jobs) if complaint[json.dumps(job)]]


def commands():
    """[(where, command)] of the documents, less NOT_COMMANDS."""
    return [(w, c) for w, c in documented_commands()
            if not any(w.split(":")[0] == doc and c.startswith(start) for doc, start in NOT_COMMANDS)]


#: Commands as a doc would show them wrongly, each of which must be refused (the breakage part).
BROKEN = [
    "hbrdf render SCENE.json -o OUT.exr --no-such-flag",            # a flag that does not exist
    "hbrdf-codegen MODEL --target glsl",                               # -o left out
    "hbrdf fit SOURCE... --out MODEL [--steps many]",                  # a value its type refuses
    "hbrdf acquire simulate (--flash N | --stage KxV) --base SOURCE --out DIR --photons P --sensor x",
    "torchrun --standalone --nproc_per_node 2 --no-python hbrdf fit --out MODEL",   # SOURCE left out
    "python bench/half_arith_accuracy.py --no-such-flag",
    "python3 -m pytest tests/python/test_svbrdf.py -k no_test_has_this_name",
]


@pytest.fixture(scope="module")
def parsed(tmp_path_factory):
    """(items, broken, complaints) for every argument list of the documents and of BROKEN, in one
    runner per test run (7 s of CPU on M2, most of it importing torch and the two pytest
    collections). Under pytest-xdist each worker ran the runner (10-12 s each in the CI run of
    2e7ebb2): the first writes its complaints into the folder the run's workers share (fresh for
    every run, so no earlier run's answers are read) under a name keyed by every argument list, the
    other reads them. Only the first reader is marked slow: when both were, they started first on
    the two workers, and one worker sat on the lock, idle, for the whole runner (18 s of wall on
    M2 under load); the unmarked one runs among the short tests, by when the answers are written
    (and waits for them otherwise)."""
    import hashlib

    items = [(w, c, argv) for w, c in commands() for argv in argument_lists(c)]
    broken = [("BROKEN", c, argv) for c in BROKEN for argv in argument_lists(c)]
    if "PYTEST_XDIST_WORKER" not in os.environ:
        return items, broken, parse_all(items + broken)
    key = hashlib.sha256(json.dumps(items + broken).encode()).hexdigest()[:16]
    with run_shared_path(tmp_path_factory, f"test_doc_commands-parsed-{key}.json") as path:
        if not path.exists():
            path.write_text(json.dumps(parse_all(items + broken)))
    return items, broken, [tuple(c) for c in json.loads(path.read_text())]


@pytest.mark.slow  # the runner imports torch, every bench script and two pytest collections: 10-20 s
def test_every_documented_command_parses(parsed):
    items, broken, complaints = parsed
    failed = [f"{w}: {shlex.join(argv)}\n    {why}" for w, c, argv, why in complaints if w != "BROKEN"]
    assert not failed, "documented commands their parsers refuse:\n" + "\n".join(failed)
    programs = {program_and_argv(argv)[0].split("/")[0] for _, _, argv in items}
    assert {"hbrdf", "hbrdf-codegen", "torchrun", "pytest", "bench"} <= programs, programs
    assert len(items) >= 100, len(items)


def test_commands_the_parsers_refuse_are_reported(parsed):  # not slow: reads the runner's answers (above)
    """The same runner refuses each of BROKEN (an unknown flag, a missing required argument, a
    bad value, an unknown bench flag, a pytest -k that selects nothing)."""
    _, broken, complaints = parsed
    refused = {c for w, c, _, _ in complaints if w == "BROKEN"}
    assert refused == set(BROKEN), set(BROKEN) - refused
    why = {c: w for _, c, _, w in complaints}
    assert "unrecognized arguments: --no-such-flag" in why[BROKEN[0]]
    assert "required: -o/--out" in why[BROKEN[1]]
    assert "exit 5" in why[BROKEN[6]]


def test_every_documented_command_is_classified():
    """Each command is a synopsis (parsed only), or RUN, or NOT_RUN with its reason; no entry of
    RUN or NOT_RUN is stale."""
    shown = {c for _, c in commands()}
    unclassified = [f"{w}: {c}" for w, c in commands()
                    if c not in RUN and c not in NOT_RUN and not is_synopsis(c, PLACEHOLDERS)]
    assert not unclassified, "put these in RUN or NOT_RUN (with the reason):\n" + "\n".join(unclassified)
    stale = [c for c in list(RUN) + list(NOT_RUN) if c not in shown]
    assert not stale, "no longer in the documents:\n" + "\n".join(stale)
    assert all(reason for reason in NOT_RUN.values())


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """A folder laid out like the repository's root for the commands (results, scenes) with
    ../shared beside it."""
    top = tmp_path_factory.mktemp("docs")
    (top / "main").mkdir()
    for folder in ("results", "scenes"):
        os.symlink(ROOT / folder, top / "main" / folder)
    if SHARED.is_dir():
        os.symlink(SHARED, top / "shared")
    return top / "main"


@pytest.mark.parametrize("command", sorted(RUN))
def test_short_commands_run_as_printed(command, scratch):
    line = shlex.join(expand(command, {})[0]) if is_synopsis(command, PLACEHOLDERS) else command
    assert not re.search(r"\b[A-Z]{2,}\b", line), line  # a minimal form shows no placeholder
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    r = subprocess.run(line, shell=True, cwd=scratch, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, f"{line}\n{r.stderr[-2000:]}"
    missing = [f for f in RUN[command] if not (scratch / f).is_file() or (scratch / f).stat().st_size == 0]
    assert not missing, f"{line} did not write {missing}"
