"""Hostile input, round three (issue 45, defects 10 and 11): absurd counts and the Python API's
type confusion.

Every count a command or a public function takes is bounded by the memory it would allocate,
checked before anything is allocated, and refused in one line naming the flag or argument and
the largest count that fits (docs/CONVENTIONS.md, "Counts and memory"); a wrong type at the
public API is a one-line TypeError naming the argument, not NumPy's words from deep inside, and
not a silent conversion ("0.5" read as 0.5, True as 1). Each test below failed before the fix:
the counts with a traceback (MemoryError) or, under an address-space limit, a MemoryError; the
types accepted or refused in NumPy's words."""

from __future__ import annotations

import re
import resource
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf import cli

import fuzz_surfaces as fs
from helpers import saved_random_model

#: Address space a child process may take: room for torch, far below any absurd count.
CHILD_AS_LIMIT = 12 << 30


def _mem_total() -> int:
    """Physical memory from /proc/meminfo (the code asks sysconf): the independent figure."""
    with open("/proc/meminfo") as fh:
        return next(int(line.split()[1]) * 1024 for line in fh if line.startswith("MemTotal:"))


def _limited():
    resource.setrlimit(resource.RLIMIT_AS, (CHILD_AS_LIMIT, CHILD_AS_LIMIT))


def _hbrdf(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "hybridbrdf.cli", *args], capture_output=True, text=True,
                          preexec_fn=_limited, timeout=timeout)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path, m = saved_random_model(tmp_path_factory.mktemp("m"), "hybrid")
    return path, m


# ---- defect 10: absurd counts on the command line -------------------------------------------------

@pytest.mark.parametrize("command, flag, value", [
    ("info", "--albedo-samples", "100000000"),   # issue 45: 98 GiB, a traceback
    ("demo", "--samples", "1000000000"),         # within the old 1e9 count range: 119 GiB
    ("demo", "--samples", "1000000000000"),      # issue 45: 671 GiB
    ("bound", "--samples", "10000000"),          # 2.4 TiB of energy-table samples
    ("eval", "--pairs", "100000000"),            # within PAIRS' 1e8: ~190 GiB with the model's activations
    ("fit", "--pool", "1073741824"),             # within POOL's 2^30: 652 GiB of pairs and values
    ("fit", "--batch", "16000000"),              # within BATCH's 2^24: 8 materials' activations, 458 GiB
])
def test_absurd_counts_are_refused_in_one_line_before_allocating(tmp_path, model, command, flag, value):
    path, _ = model
    argv = {"info": ["info", str(path)], "demo": ["demo", "--out", str(tmp_path / "d.png")],
            "bound": ["bound", str(path), "--out", str(tmp_path / "b.safetensors")],
            "eval": ["eval", str(path), "synthetic:gold"],
            "fit": ["fit", "synthetic:all", "--out", str(tmp_path / "f.safetensors"), "--no-preview"]}[command]
    t0 = time.monotonic()
    r = _hbrdf(*argv, flag, value)
    seconds = time.monotonic() - t0
    lines = [line for line in r.stderr.splitlines() if line.startswith("hbrdf")]
    assert r.returncode in (1, 2), r.stderr
    assert "Traceback" not in r.stderr and "MemoryError" not in r.stderr, r.stderr[-2000:]
    assert len(lines) == 1 and flag in lines[0] and "error:" in lines[0], r.stderr
    # The bound is stated ("at most N" where the range allows it) and is honest: N fits this machine.
    m = re.search(r"at most ([\d,]+)", lines[0]) or re.search(r"in \[\d+, (\d+)\]", lines[0])
    assert m, lines[0]
    assert int(m.group(1).replace(",", "")) < int(value)
    assert not any((tmp_path / f).exists() for f in ("d.png", "b.safetensors", "f.safetensors"))
    assert seconds < 60  # refused up front (the interpreter's start is most of it)


def test_count_bound_follows_this_machines_memory():
    """check_count's limit is the physical memory (/proc/meminfo read independently) and its
    "at most" is the largest count that fits it."""
    from hybridbrdf.limits import check_count

    if resource.getrlimit(resource.RLIMIT_AS)[0] != resource.RLIM_INFINITY:
        pytest.skip("under ulimit -v the bound is what the limit leaves, not the physical memory")
    total = _mem_total()
    each = 1000
    fits = total // each - 1
    check_count("--x", fits, each)  # fits: no error
    with pytest.raises(ValueError) as err:
        check_count("--x", total // each + 10, each)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("--x ")
    most = int(re.search(r"at most ([\d,]+)", msg).group(1).replace(",", ""))
    assert abs(most - total // each) <= 1


def test_stated_costs_cover_the_measured_peaks(tmp_path, model):
    """The bytes per unit each bound uses are not below the peak resident memory measured in a
    fresh process: the bound refuses too early rather than too late."""
    path, _ = model
    code = f"""
import os, resource, sys, numpy as np, torch
import hybridbrdf as hb
from hybridbrdf.model import sizes
from hybridbrdf.sources import open_source
m = hb.load_model({str(path)!r})
src = open_source("synthetic:gold")
n = 1_000_000
rng = np.random.default_rng(0)
wi = rng.normal(size=(1, 3)); wi[:, 2] = 1.0
wi = np.broadcast_to(wi, (n, 3)); wo = wi  # views: what a call copies is the call's cost
for f in (lambda k: m.eval(wi[:k], wo[:k], 0), lambda k: m.eval(wi[:k], wo[:k], 0, dtype=torch.float32),
          lambda k: src.eval(wi[:k], wo[:k]), lambda k: hb.analytic_eval(wi[:k], wo[:k], hb.AnalyticParams()),
          lambda k: m.albedo(0, samples=k)):
    f(10)
for name, f, k, cost in (
        ("library eval", lambda k: m.eval(wi[:k], wo[:k], 0), n, m.bytes_per_pair()),
        ("torch eval", lambda k: m.eval(wi[:k], wo[:k], 0, dtype=torch.float32), n, m.bytes_per_pair(torch.float32)),
        ("source eval", lambda k: src.eval(wi[:k], wo[:k]), n, hb.sources.base.BYTES_PER_PAIR),
        ("analytic eval", lambda k: hb.analytic_eval(wi[:k], wo[:k], hb.AnalyticParams()), n,
         hb.brdf.analytic.BYTES_PER_PAIR),
        ("albedo", lambda k: m.albedo(0, samples=k), 20_000, sizes.albedo_bytes_per_sample(m.bytes_per_pair()))):
    sys.stdout.flush()
    if os.fork() == 0:  # a child per call: its high-water mark starts at the parent's current RSS
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        f(k)
        peak = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024 / k
        print(f"{{name}} {{peak:.1f}} {{cost}}", flush=True)
        os._exit(0)
    os.wait()
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    print(r.stdout)  # the figures (pytest -s shows them)
    for line in r.stdout.splitlines():
        name, peak, cost = line.rsplit(" ", 2)
        assert float(peak) <= float(cost), f"{name}: measured {peak} bytes a unit, bound uses {cost}"


# ---- progress on stderr ----------------------------------------------------------------------------

def test_info_shows_progress_when_slow_and_is_quiet_when_asked(model, capsys, monkeypatch):
    path, _ = model
    assert cli.main(["info", str(path), "--albedo-samples", "16"]) == 0
    assert capsys.readouterr().err == ""  # quick and stderr no terminal: no bar
    monkeypatch.setattr(cli, "PROGRESS_DELAY_S", 0.0)  # "slow" from the start; stderr is no terminal here
    assert cli.main(["info", str(path), "--albedo-samples", "16"]) == 0
    out, err = capsys.readouterr()
    assert out.count("max directional albedo") == 3 and "materials/s" not in out  # the bar stays on stderr
    assert re.search(r"albedo: .*\d+/3", err), err  # the bar counts the 3 materials
    assert cli.main(["info", str(path), "--albedo-samples", "16", "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_bound_and_eval_show_progress_when_slow(model, tmp_path, capsys, monkeypatch):
    _, m = model
    infos = [dict(info) for info in m.material_info]
    infos[0]["name"] = "gold"  # matched to synthetic:gold by name
    path = tmp_path / "gold.safetensors"
    type(m)(dict(m.arch), infos, dict(m.tensors), dict(m.training)).save(path)
    monkeypatch.setattr(cli, "PROGRESS_DELAY_S", 0.0)
    assert cli.main(["bound", str(path), "--out", str(tmp_path / "b.safetensors"), "--samples", "64"]) == 0
    assert re.search(r"energy bound: .*\d+/3", capsys.readouterr().err)  # 0/3 at first, then every 10 s
    assert cli.main(["eval", str(path), "synthetic:gold", "--pairs", "1000"]) == 0
    out, err = capsys.readouterr()
    assert re.search(r"eval: .*\d+/1", err) and "gold" in out
    assert cli.main(["eval", str(path), "synthetic:gold", "--pairs", "1000", "--quiet"]) == 0
    assert capsys.readouterr().err == ""


# ---- defect 11: type confusion at the public API ---------------------------------------------------

def _one_line(exc_info, *names):
    msg = str(exc_info.value)
    assert "\n" not in msg and len(msg) < 400, msg
    for n in names:
        assert n in msg, msg


@pytest.mark.parametrize("call, exc, names", [
    (lambda m: m.edit("mat-0", 5, kd=0.5), TypeError, ("name", "int")),                 # issue 45
    (lambda m: m.edit("mat-0", "e", kd="0.5"), TypeError, ("kd", "str")),
    (lambda m: m.edit("mat-0", "e", alpha=[0.1, "x"]), TypeError, ("alpha",)),
    (lambda m: m.edit("mat-0", "e", eta=True), TypeError, ("eta", "bool")),
    (lambda m: m.edit("mat-0", "e", kd=None, eta=None, alpha=None, conserve_energy="no"), TypeError,
     ("conserve_energy",)),
    (lambda m: m.edit(True, "e", kd=0.5), TypeError, ("material", "bool")),
    (lambda m: m.edit(1.0, "e", kd=0.5), TypeError, ("material", "float")),
    (lambda m: m.mix("mat-0", "mat-1", "0.5", "b"), TypeError, ("t must be", "str")),     # issue 45
    (lambda m: m.mix("mat-0", "mat-1", True, "b"), TypeError, ("t must be", "bool")),     # issue 45
    (lambda m: m.mix("mat-0", "mat-1", [0.5], "b"), TypeError, ("t must be", "list")),
    (lambda m: m.mix("mat-0", "mat-1", 0.5, ["b"]), TypeError, ("name", "list")),
    (lambda m: m.mix("mat-0", "mat-1", 0.5, "b", conserve_energy=1), TypeError, ("conserve_energy", "int")),
    (lambda m: m.albedo("mat-0", samples=True), TypeError, ("samples", "bool")),
    (lambda m: m.albedo("mat-0", samples=64.0), TypeError, ("samples", "float")),
    (lambda m: m.eval([["a", "b", "c"]], [[0, 0, 1]], 0), TypeError, ("wi",)),
    (lambda m: m.eval([[0, 0, 1]], "wo", 0), TypeError, ("wo", "str")),
    (lambda m: m.eval(np.array([[True, False, True]]), [[0, 0, 1]], 0), TypeError, ("wi", "bool")),
    (lambda m: m.eval([[0, 0, 1]], [[0, 0, 1]], 0, dtype=torch.float16), TypeError, ("dtype",)),
    (lambda m: m.eval([[0, 0, 1], [0, 0]], [[0, 0, 1]] * 2, 0), ValueError, ("wi", "different lengths")),
    (lambda m: hb.AnalyticParams(kd="0.5"), TypeError, ("kd",)),
    (lambda m: hb.AnalyticParams(alpha=None), TypeError, ("alpha",)),
    (lambda m: hb.sample([[0, 0, 1]], [[0.5, 0.5]], hb.AnalyticParams(), strategy=5), TypeError, ("strategy",)),
    (lambda m: hb.pdf([[0, 0, 1]], [[0, 0, 1]], hb.AnalyticParams(), strategy=None), TypeError, ("strategy",)),
    (lambda m: hb.analytic_eval(["x"], [[0, 0, 1]], hb.AnalyticParams()), TypeError, ("wi",)),
    (lambda m: hb.open_source("synthetic:gold").eval(np.zeros((2, 3), object), np.zeros((2, 3)) + 1), TypeError,
     ("wi", "object")),
], ids=lambda v: None)
def test_wrong_types_are_refused_naming_the_argument(model, call, exc, names):
    _, m = model
    with pytest.raises(exc) as info:
        call(m)
    _one_line(info, *names)


def test_numbers_pass_where_strings_and_bools_do_not(model):
    """The checks refuse nothing the API documents (NumPy scalars, ints, tuples, an index), and
    refuse the same values given as a string or a bool."""
    _, m = model
    blend = m.mix(np.int64(0), "mat-1", np.float32(0.25), "b", conserve_energy=np.bool_(False))
    assert blend.material_info[-1]["mix"]["t"] == 0.25
    edited = m.edit("mat-0", "e", kd=(0.2, 0.3, 0.4), alpha=np.float64(0.2))
    assert edited.analytic_params("e").kd.tolist() == pytest.approx([0.2, 0.3, 0.4])
    assert m.mix("mat-0", "mat-1", 1, "c").latent("c").tolist() == m.latent("mat-1").tolist()
    wi = np.array([[0.0, 0.0, 1.0]], np.float32)
    assert np.isfinite(m.eval(wi, wi, 0)).all() and np.isfinite(m.eval(wi.tolist(), wi, 0, dtype=torch.float64)).all()
    for t in ("0.25", np.bool_(True)):
        with pytest.raises(TypeError, match="t must be"):
            m.mix(np.int64(0), "mat-1", t, "b")
    with pytest.raises(TypeError, match="kd must be"):
        m.edit("mat-0", "e", kd=("0.2", "0.3", "0.4"))


# ---- defect 11: pair counts bounded before allocating ---------------------------------------------

_VIEW = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (10**9, 3))  # 24 bytes of data, 10^9 rows
_U = np.broadcast_to(np.array([0.5, 0.5]), (10**9, 2))


@pytest.mark.parametrize("call", [
    lambda m: m.eval(_VIEW, _VIEW, 0),                                        # issue 45: libhybridbrdf
    lambda m: m.eval(_VIEW, _VIEW, 0, dtype=torch.float32),                   # PyTorch
    lambda m: m.eval_analytic(_VIEW, _VIEW, 0),
    lambda m: hb.analytic_eval(_VIEW, _VIEW, hb.AnalyticParams()),
    lambda m: hb.pdf(_VIEW, _VIEW, hb.AnalyticParams()),
    lambda m: hb.sample(_VIEW, _U, hb.AnalyticParams()),
    lambda m: hb.open_source("synthetic:gold").eval(_VIEW, _VIEW),
    lambda m: m.albedo(0, samples=10**9),
], ids=["eval", "eval torch", "eval_analytic", "analytic_eval", "pdf", "sample", "source eval", "albedo"])
def test_billion_pair_calls_are_refused_before_allocating(model, call):
    """Under a 1 GiB address-space allowance (fuzz_surfaces' bound) and 2 s: a one-line
    ValueError naming the argument and the largest count that fits, not a MemoryError."""
    _, m = model
    assert fs.check_hostile("billion pairs", lambda: call(m), "at most") == fs.REJECTED
