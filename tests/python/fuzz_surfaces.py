"""The surfaces of the standing fuzz suite and the invariant each must keep:

    one-line error naming the input, or a valid result;
    no crash, no traceback, no hang, bounded memory, no file damaged.

Each ``check_*`` function takes one input (bytes, a JSON document, a string), runs it through
one surface and returns the outcome's name ("valid" or "rejected"); a broken invariant raises
:class:`Violation`. tests/python/test_fuzz.py drives them with Hypothesis (bounded, seconds);
bench/fuzz_scale.py drives them with seeded random mutations at scale and prints the counts.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import functools
import io
import json
import os
import pathlib
import struct
from typing import Callable, Dict, List

import numpy as np

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.errors import InputFileError
from hybridbrdf.model.random import random_model

VALID, REJECTED = "valid", "rejected"

#: Exception types that are a clean refusal of a bad input (their message is checked too).
CLEAN_ERRORS = (InputFileError, ValueError)


class Violation(AssertionError):
    """An input broke the invariant: the message says which surface and how."""


def _printable_line(text: str) -> bool:
    return "\n" not in text and "\r" not in text and all(ch >= " " and ch != "\x7f" for ch in text)


def expect_clean_error(surface: str, exc: BaseException, names: str, errors: tuple = CLEAN_ERRORS) -> str:
    """REJECTED when ``exc`` is a clean one-line error (one of ``errors``) naming ``names``;
    Violation otherwise."""
    if not isinstance(exc, errors):
        raise Violation(f"{surface}: {type(exc).__name__} escaped: {exc!r}"[:2000]) from exc
    msg = str(exc)
    if not _printable_line(msg):
        raise Violation(f"{surface}: error is not one printable line: {msg[:500]!r}") from exc
    if names and names not in msg:
        raise Violation(f"{surface}: error does not name {names!r}: {msg[:500]!r}") from exc
    if len(msg) > 4096:
        raise Violation(f"{surface}: error of {len(msg)} characters") from exc
    return REJECTED


# ---- byte mutations ------------------------------------------------------------------

def mutate_bytes(data: bytes, rng: np.random.Generator) -> bytes:
    """One random damage: bit flips, byte overwrites, a cut, a duplicated or deleted span,
    an integer field set to an extreme, or garbage appended. Biased toward the first KiB,
    where the headers are."""
    b = bytearray(data)
    n = max(len(b), 1)
    kind = int(rng.integers(0, 7))
    head = min(n, 1024)

    def pos():
        return int(rng.integers(0, head if rng.random() < 0.7 else n))

    if kind == 0 and b:
        for _ in range(int(rng.integers(1, 4))):
            i = pos() % len(b)
            b[i] ^= 1 << int(rng.integers(0, 8))
    elif kind == 1 and b:
        for _ in range(int(rng.integers(1, 6))):
            b[pos() % len(b)] = int(rng.integers(0, 256))
    elif kind == 2:
        b = b[:int(rng.integers(0, n))]
    elif kind == 3 and b:
        i = pos() % len(b)
        j = min(len(b), i + int(rng.integers(1, 64)))
        b = b[:j] + b[i:j] * int(rng.integers(1, 4)) + b[j:]
    elif kind == 4 and b:
        i = pos() % len(b)
        del b[i:i + int(rng.integers(1, 64))]
    elif kind == 5 and len(b) >= 8:
        i = pos() % (len(b) - 7)
        value = [0, 1, 2**31 - 1, 2**31, 2**32 - 1, 2**63 - 1, 2**64 - 1][int(rng.integers(0, 7))]
        b[i:i + 8] = struct.pack("<Q", value)
    else:
        b += rng.bytes(int(rng.integers(1, 256)))
    return bytes(b)


# ---- model files: both loaders must agree ----------------------------------------------

# Problems that come from the container reader, where the two loaders' words differ by design
# (the Python one is the safetensors package): there only "both refuse" is required.
_CONTAINER_PROBLEMS = ("not a valid safetensors file", "not a safetensors file", "truncated:",
                       "safetensors header", "safetensors data section", "__metadata__",
                       "metadata is not valid JSON (", "no such file", "cannot read", "not a regular file")


def model_seed_bytes(arch: str = "hybrid", seed: int = 0) -> bytes:
    """A small valid model file's bytes (3 materials, width 8, depth 1)."""
    import tempfile

    import torch

    torch.manual_seed(seed)  # random_model draws from torch's global generator
    _, model = random_model(arch, latent=12 if arch == "neural" else 2, width=8, depth=1)
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / "m.safetensors"
        model.save(path)
        return path.read_bytes()


def check_model_file(data: bytes, path: pathlib.Path) -> str:
    """Both loaders on one file: both accept (the same materials) or both refuse, each with
    one line naming the file; and where the problem is past the container, the same words."""
    path.write_bytes(data)
    outcomes = []
    for loader in (hb.load_model, _core.Model):
        try:
            m = loader(str(path))
            outcomes.append(("ok", list(m.materials)))
        except Exception as exc:  # noqa: BLE001 - the invariant is about which exceptions escape
            expect_clean_error(f"model loader {loader.__qualname__}", exc, str(path))
            if not isinstance(exc, hb.ModelFileError):
                raise Violation(f"model loader {loader.__qualname__}: {type(exc).__name__}, not ModelFileError")
            outcomes.append(("error", exc.problem))
    (py_kind, py_val), (cpp_kind, cpp_val) = outcomes
    if py_kind != cpp_kind:
        raise Violation(f"model loaders disagree: python {py_kind} {py_val!r}, C++ {cpp_kind} {cpp_val!r}"[:2000])
    if py_kind == "ok":
        if py_val != cpp_val:
            raise Violation(f"model loaders read different materials: {py_val} vs {cpp_val}")
        return VALID
    if not any(p in py_val for p in _CONTAINER_PROBLEMS) and py_val != cpp_val:
        raise Violation(f"model loaders' words differ: python {py_val!r}, C++ {cpp_val!r}"[:2000])
    return REJECTED


def model_with_metadata(seed_bytes: bytes, doc) -> bytes:
    """The seed file's tensors with the 'hybridbrdf' metadata replaced by ``doc`` (any JSON)."""
    import safetensors.numpy

    tensors = safetensors.numpy.load(seed_bytes)
    return safetensors.numpy.save(tensors, {"hybridbrdf": json.dumps(doc)})


_EXTREME_VALUES = [0, -1, 1, 2**31 - 1, 2**31, 2**32 + 32, 2**53 + 1, 2**63, 2**64 - 1, 10**30, -(2**63), 0.5, 3.5,
                   -0.0, 1e-320, 1e39, 1.7e308, "", "x", "1", "hybrid", "relu", "\n", "\x00", "\u00e9", "a" * 300,
                   None, True, False, [], {}, [1, 2], {"a": 1}]


def random_json(rng: np.random.Generator, depth: int = 0):
    """A random JSON value, biased toward the values validation code gets wrong."""
    r = rng.random()
    if r < 0.55 or depth > 2:
        return copy.deepcopy(_EXTREME_VALUES[int(rng.integers(0, len(_EXTREME_VALUES)))])  # never shared
    if r < 0.7:
        return int(rng.integers(-5, 300))
    if r < 0.8:
        return "".join(chr(int(c)) for c in rng.integers(0, 0x250, size=int(rng.integers(0, 8))))
    if r < 0.9:
        return [random_json(rng, depth + 1) for _ in range(int(rng.integers(0, 4)))]
    return {f"k{i}": random_json(rng, depth + 1) for i in range(int(rng.integers(0, 3)))}


def mutate_doc(doc, rng: np.random.Generator):
    """A copy of a JSON document with 1-3 random edits: a value replaced, a key deleted or added."""
    doc = copy.deepcopy(doc)
    for _ in range(int(rng.integers(1, 4))):
        parent, key = None, None
        node = doc
        while isinstance(node, (dict, list)) and node and rng.random() < 0.75:
            keys = list(node.keys()) if isinstance(node, dict) else list(range(len(node)))
            parent, key = node, keys[int(rng.integers(0, len(keys)))]
            node = node[key]
        if parent is None:
            continue
        action = rng.random()
        if action < 0.7:
            parent[key] = random_json(rng)
        elif action < 0.85 and isinstance(parent, dict):
            del parent[key]
        elif isinstance(parent, dict):
            parent[f"extra{int(rng.integers(0, 9))}"] = random_json(rng)
        else:
            parent.append(random_json(rng))
    return doc


def seed_metadata(seed_bytes: bytes) -> dict:
    (hlen,) = struct.unpack("<Q", seed_bytes[:8])
    return json.loads(json.loads(seed_bytes[8:8 + hlen])["__metadata__"]["hybridbrdf"])


# ---- measured-data readers ---------------------------------------------------------------

def check_source_file(data: bytes, path: pathlib.Path, directions: int = 64) -> str:
    """A measured file through hybridbrdf.sources.open_source: refused with one line naming
    it, or read and evaluated to finite values. (Not necessarily non-negative: RGL tables hold
    small negative measurement noise, -0.1 in cg_sunflower, and the reader returns what the
    file holds, as Mitsuba's measured BSDF does.)"""
    from hybridbrdf.sources import open_source

    path.write_bytes(data)
    try:
        src = open_source(str(path))
        rng = np.random.default_rng(len(data))
        wi = rng.normal(size=(directions, 3))
        wo = rng.normal(size=(directions, 3))
        wi /= np.linalg.norm(wi, axis=1, keepdims=True)
        wo /= np.linalg.norm(wo, axis=1, keepdims=True)
        f = np.asarray(src.eval(wi, wo))
    except Exception as exc:  # noqa: BLE001
        return expect_clean_error(f"reader {path.suffix}", exc, str(path))
    if not np.isfinite(f).all():
        raise Violation(f"reader {path.suffix}: accepted a file and returned non-finite values")
    return VALID


# ---- scenes ------------------------------------------------------------------------------

def check_scene(doc, origin: str = "fuzz-scene.json") -> str:
    """A scene document through the tracer's scene reader (no files opened, nothing rendered)."""
    try:
        _core.read_scene_decl(json.dumps(doc, allow_nan=True), os.getcwd(), origin)
    except Exception as exc:  # noqa: BLE001
        return expect_clean_error("scene reader", exc, origin)
    return VALID


# ---- material names through the loaders and codegen ----------------------------------------

def check_material_name(name: str, seed_bytes: bytes, path: pathlib.Path) -> str:
    """A model whose material 1 is ``name``: both loaders refuse it alike, or accept it and
    every target's code carries it only inside its constant and inert comments."""
    from hybridbrdf.codegen.main import generate

    doc = seed_metadata(seed_bytes)
    doc["materials"][1]["name"] = name
    outcome = check_model_file(model_with_metadata(seed_bytes, doc), path)
    if outcome == VALID:
        model = hb.load_model(str(path))
        for target in ("glsl", "hlsl", "cpp"):
            text = generate(model, target)
            for line in text.splitlines():
                if line.endswith("\\") or "??/" in line or (line.startswith("//") and not _printable_line(line)):
                    raise Violation(f"codegen {target}: name {name!r} made an unsafe line {line[:200]!r}")
    return outcome


# ---- command-line flags ----------------------------------------------------------------------

def _commands(parser: argparse.ArgumentParser, path: tuple = ()) -> Dict[str, argparse.ArgumentParser]:
    """Every ``hbrdf`` command at any depth (``acquire fit``, ``acquire simulate``), by its words."""
    out: Dict[str, argparse.ArgumentParser] = {}
    for action in parser._actions:  # noqa: SLF001 - argparse has no public walk over actions
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            for name, sub in action.choices.items():
                out[" ".join(path + (name,))] = sub
                out.update(_commands(sub, path + (name,)))
    return out


def cli_flags() -> List[tuple]:
    """(command, flag) for every typed flag of every ``hbrdf`` command, nested ones included."""
    from hybridbrdf.cli import build_parser

    return [(cmd, a.option_strings[-1]) for cmd, sub in _commands(build_parser()).items()
            for a in sub._actions if a.option_strings and a.type is not None]  # noqa: SLF001


@functools.lru_cache(maxsize=1)
def _parser() -> argparse.ArgumentParser:
    from hybridbrdf.cli import build_parser

    return build_parser()  # parsing does not change it, so one serves every example


def _required_args(sub: argparse.ArgumentParser, flag: str) -> List[str]:
    """Arguments that satisfy ``sub``'s required positionals, options and exclusive groups other
    than ``flag``: without them every value ends in the same "required" usage error, which would
    hide a flag that accepts a value it should refuse. A typed option gets "1", any other "x"."""
    out: List[str] = []
    def filler(action):
        return "1" if action.type is not None else "x"
    for a in sub._actions:  # noqa: SLF001
        if not a.option_strings and not isinstance(a, argparse._SubParsersAction) and a.nargs != 0:  # noqa: SLF001
            if a.required or a.nargs in ("+", None):
                out.append(filler(a))
        elif a.required and flag not in a.option_strings:
            out += [a.option_strings[-1], filler(a)]
    for group in sub._mutually_exclusive_groups:  # noqa: SLF001
        options = [a for a in group._group_actions if a.option_strings]  # noqa: SLF001
        if group.required and options and not any(flag in a.option_strings for a in options):
            out += [options[0].option_strings[-1]] + ([filler(options[0])] if options[0].nargs != 0 else [])
    return out


def check_cli_flag(command: str, flag: str, value: str) -> str:
    """``hbrdf COMMAND FLAG VALUE`` parsed (nothing run), the command's other required arguments
    given: a usage error of one line, or a value that is finite and of the flag's type."""
    from hybridbrdf.cli import settings_from_args

    parser = _parser()
    words = command.split()
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            args = parser.parse_args([*words, *_required_args(_commands(parser)[command], flag), f"{flag}={value}"])
            if command == "fit":
                settings_from_args(args)
    except SystemExit as exc:
        if exc.code != 2:
            raise Violation(f"hbrdf {command} {flag}={value!r}: exit {exc.code}")
        last = err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else ""
        if not last.startswith("hbrdf") or "error:" not in last:
            raise Violation(f"hbrdf {command} {flag}={value!r}: no usage error line: {err.getvalue()[-500:]!r}")
        if "the following arguments are required" in last or "one of the arguments" in last:
            raise Violation(f"hbrdf {command} {flag}={value!r}: the check's own arguments fell short: {last!r}")
        return REJECTED
    except Exception as exc:  # noqa: BLE001
        return expect_clean_error(f"hbrdf {command} {flag}", exc, "")
    v = getattr(args, flag.lstrip("-").replace("-", "_"), None)
    values = v if isinstance(v, (tuple, list)) else [v]
    if any(isinstance(x, float) and not np.isfinite(x) for x in values):
        raise Violation(f"hbrdf {command} {flag}={value!r} accepted a non-finite value {v}")
    return VALID


# ---- checkpoints -------------------------------------------------------------------------------

def checkpoint_seed(workdir: pathlib.Path):
    """(bytes, state, settings) of a valid checkpoint at step 10 of a tiny fit of synthetic:gold."""
    from hybridbrdf.fit import checkpoint as ckpt
    from hybridbrdf.fit.settings import FitSettings
    from hybridbrdf.fit import fit
    from hybridbrdf.sources import open_source

    settings = FitSettings(width=8, depth=1, steps=20, batch=64, pool=256, eval_pairs=200, seed=5)
    path = workdir / "seed-checkpoint.pt"
    fit([open_source("synthetic:gold")], settings, checkpoint=str(path), checkpoint_every=10, progress=False,
        stop_after=10, log=lambda m: None)
    state, _ = ckpt.read(path)
    return path.read_bytes(), state, settings


def mutate_checkpoint_state(state, rng: np.random.Generator):
    """A copy of a checkpoint's state with one entry replaced: a random JSON value, a tensor of
    another shape, or a tensor holding NaN/Inf/huge values (re-encoded with a valid checksum, so
    only the structural checks can catch it)."""
    import torch

    state = copy.deepcopy(state)
    node = state
    while True:  # descend into nested dicts (settings, model, optimizer) now and then
        keys = list(node)
        key = keys[int(rng.integers(0, len(keys)))]
        if isinstance(node[key], dict) and node[key] and rng.random() < 0.6:
            node = node[key]
            continue
        break
    old = node[key]
    r = rng.random()
    if isinstance(old, torch.Tensor) and r < 0.5:
        t = old.clone()
        if t.numel() and t.is_floating_point():
            t.view(-1)[int(rng.integers(0, t.numel()))] = float(rng.choice([np.nan, np.inf, -np.inf, 1e38, -1.0]))
        node[key] = t
    elif isinstance(old, torch.Tensor) and r < 0.7:
        node[key] = torch.zeros(tuple(int(d) for d in rng.integers(0, 4, size=int(rng.integers(0, 3)))))
    else:
        node[key] = random_json(rng)
    return state


def check_checkpoint(data: bytes, path: pathlib.Path, settings) -> str:
    """A checkpoint through hybridbrdf.fit.checkpoint.load (what ``hbrdf fit --resume`` runs before
    any source is opened): refused with one line naming it, or valid; never altered."""
    from hybridbrdf.fit import checkpoint as ckpt

    path.write_bytes(data)
    try:
        ckpt.load(path, settings)
    except Exception as exc:  # noqa: BLE001
        outcome = expect_clean_error("checkpoint", exc, str(path))
    else:
        outcome = VALID
    if path.read_bytes() != data:
        raise Violation("checkpoint: the file was changed by reading it")
    return outcome


# ---- registry for the scale bench --------------------------------------------------------------

SURFACES: Dict[str, Callable] = {
    "model file bytes": check_model_file,
    "model metadata": check_model_file,
    "measured files": check_source_file,
    "scenes": check_scene,
    "material names": check_material_name,
    "cli flags": check_cli_flag,
    "checkpoints": check_checkpoint,
}


# ---- hostile inputs, round two: special files, structured JSON, forged sizes, -o ----
#
# Each generator below makes one input of a kind the byte and field mutations above rarely or
# never reach; check_hostile() runs it under the invariant, in this process, and adds three
# bounds: a time bound (a FIFO has its other end opened after FIFO_UNBLOCK_S, so a reader that
# opens it without checking reads an empty file late and fails the time bound instead of hanging
# the run), an address-space bound (reading /dev/zero fails at MEMORY_BOUND instead of taking the
# machine) and the error check of expect_clean_error.

#: A refusal must come within this many seconds (the checks are a stat and a few reads).
HOSTILE_TIME_S = 2.0
#: Seconds after which a FIFO's other end is opened (> HOSTILE_TIME_S: a waiting reader fails).
FIFO_UNBLOCK_S = 3.0
#: Growth of this process's address space allowed while one hostile input is read.
MEMORY_BOUND = 1 << 30

SPECIAL_KINDS = ("fifo", "dev-zero", "sparse", "symlink-loop", "folder")


def _readers() -> Dict[str, tuple]:
    """name -> (file name, reader(path)): every reader that opens a file a user names."""
    from hybridbrdf.fit import checkpoint
    from hybridbrdf.render.tracer import load_scene_dict
    from hybridbrdf.sources import open_source

    def environment(path):  # the tracer's environment-map reader (C++), through a 4 x 4 render
        from hybridbrdf.render.tracer import render

        render({"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 4, "height": 4},
                "environment": {"type": "file", "file": os.fspath(path)},
                "objects": [{"type": "sphere", "material": {"type": "analytic"}}], "spp": 1, "threads": 1})

    return {"model (Python)": ("m.safetensors", hb.load_model), "model (C++)": ("m.safetensors", _core.Model),
            "scene": ("s.json", load_scene_dict), "checkpoint": ("ck.pt", checkpoint.read),
            "MERL": ("x.binary", open_source), "RGL": ("x.bsdf", open_source), "UTIA": ("x.bin", open_source),
            "NBRDF": ("x.h5", open_source), "environment map": ("e.hdr", environment)}


READERS = tuple(_readers()) if getattr(_core, "HAVE_RENDERER", False) else \
    tuple(r for r in _readers() if r != "environment map")


@contextlib.contextmanager
def _memory_bound(extra: int = MEMORY_BOUND):
    import resource

    with open("/proc/self/status") as fh:
        used = next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmSize:"))
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = used + extra if hard == resource.RLIM_INFINITY else min(used + extra, hard)
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def check_hostile(surface: str, call: Callable[[], object], names: str, may_accept: bool = False,
                  errors: tuple = CLEAN_ERRORS) -> str:
    """``call()`` must raise a clean one-line error (one of ``errors``) naming ``names`` within
    HOSTILE_TIME_S and MEMORY_BOUND; returning is a Violation too (the input is invalid by
    construction) unless ``may_accept``, for generators that can make valid inputs."""
    import time

    t0 = time.monotonic()
    try:
        with _memory_bound():
            call()
        outcome = VALID
    except Exception as exc:  # noqa: BLE001
        outcome = expect_clean_error(surface, exc, names, errors)
    if outcome == VALID and not may_accept:
        raise Violation(f"{surface}: accepted")
    seconds = time.monotonic() - t0
    if seconds > HOSTILE_TIME_S:
        raise Violation(f"{surface}: refused after {seconds:.1f} s (read or waited on before the check)")
    return outcome


def make_special_file(path: pathlib.Path, kind: str) -> None:
    """``path`` (which must not exist) as a FIFO, a symlink to /dev/zero, a sparse file of 1 TiB
    (over every format's cap, no disk used), a symlink to itself, or a folder."""
    if kind == "fifo":
        import subprocess

        os.mkfifo(path)
        # Opened read-write, which does not block, and only while it is still the FIFO.
        subprocess.Popen(["sh", "-c", 'sleep "$1"; [ -p "$2" ] && exec 3<>"$2"', "unblock", str(FIFO_UNBLOCK_S),
                          os.fspath(path)], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    elif kind == "dev-zero":
        os.symlink("/dev/zero", path)
    elif kind == "sparse":
        with open(path, "wb") as fh:
            fh.truncate(1 << 40)
    elif kind == "symlink-loop":
        os.symlink(path.name, path)
    elif kind == "folder":
        os.mkdir(path)
    else:
        raise ValueError(f"unknown special file kind {kind!r}")


def _remove(path: pathlib.Path) -> None:
    if path.is_dir() and not path.is_symlink():
        os.rmdir(path)
    elif os.path.lexists(path):
        os.unlink(path)


def check_special_file(reader: str, kind: str, workdir: pathlib.Path, tag: str = "") -> str:
    """One reader on one special file, which is removed afterwards."""
    name, call = _readers()[reader]
    path = workdir / f"{kind}{tag}-{name}"
    make_special_file(path, kind)
    try:
        return check_hostile(f"{reader} on a {kind}", lambda: call(str(path)), str(path))
    finally:
        _remove(path)


# Structured JSON: text, not documents, so that nesting deeper than Python's own recursion limit
# can be written at all.

JSON_KINDS = ("deep nesting", "wrong types", "huge counts")
_WRONG = [None, True, "x", 1.5, -1, [], {}, [[]], {"a": {}}, 2**64, "1e999", -0.0]
_HUGE = [2**31, 2**32 + 1, 2**53 + 1, 2**63, 2**64, 10**30, 1e308, -(2**63), 2**40]


def _paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _paths(v, prefix + (i,))


def hostile_json_text(seed_doc, kind: str, rng: np.random.Generator) -> str:
    """A JSON text built from ``seed_doc``: a value nested 65 to 100000 levels deep at a random
    place ("deep nesting"), a random value replaced by one of another type ("wrong types"), or a
    number or list replaced by a huge count ("huge counts": 2^31 ... 1e308, or 10^5 copies)."""
    doc = copy.deepcopy(seed_doc)
    paths = [p for p in _paths(doc) if p]
    path = paths[int(rng.integers(0, len(paths)))]
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    marker = "\"@@HOSTILE@@\""
    if kind == "deep nesting":
        depth = int(rng.choice([65, 100, 1000, 5000, 100000]))
        opener = "[" if rng.random() < 0.5 else "{\"a\": "
        closer = "]" if opener == "[" else "}"
        parent[path[-1]] = "@@HOSTILE@@"
        return json.dumps(doc).replace(marker, opener * depth + "1" + closer * depth, 1)
    if kind == "wrong types":
        old = parent[path[-1]]
        choices = [v for v in _WRONG if type(v) is not type(old)]
        parent[path[-1]] = copy.deepcopy(choices[int(rng.integers(0, len(choices)))])
        return json.dumps(doc)
    if kind == "huge counts":
        old = parent[path[-1]]
        if isinstance(old, list) and old and rng.random() < 0.5:
            parent[path[-1]] = old * max(1, 100000 // len(old))
        elif isinstance(old, dict) and old and rng.random() < 0.5:
            first = next(iter(old.values()))
            parent[path[-1]] = {f"k{i}": copy.deepcopy(first) for i in range(20000)}
        else:
            parent[path[-1]] = _HUGE[int(rng.integers(0, len(_HUGE)))]
        return json.dumps(doc)
    raise ValueError(f"unknown JSON kind {kind!r}")


def model_with_metadata_text(seed_bytes: bytes, text: str) -> bytes:
    """The seed file's tensors with the 'hybridbrdf' metadata replaced by ``text`` (any string)."""
    import safetensors.numpy

    return safetensors.numpy.save(safetensors.numpy.load(seed_bytes), {"hybridbrdf": text})


def check_scene_file(text: str, path: pathlib.Path) -> str:
    """A scene file's text through the front end's reader and the tracer's scene reader: refused
    in one line naming the file within the time and memory bounds, or read."""
    path.write_text(text)

    def read():
        from hybridbrdf.render.tracer import load_scene_dict

        data, base, origin = load_scene_dict(str(path))
        if hasattr(_core, "read_scene_decl"):
            _core.read_scene_decl(json.dumps(data, allow_nan=True), base, origin)

    return check_hostile("scene file", read, str(path), may_accept=True)


def tabulated_scene_text(n_materials: int) -> str:
    """A scene of ``n_materials`` anisotropic materials under the tabulated sampler at 1 degree:
    ~210 MB of tables each, over the tracer's budget from 6 on (limits.hpp)."""
    mats = {f"m{i}": {"type": "analytic", "alpha": [0.1, 0.3]} for i in range(n_materials)}
    return json.dumps({"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 4, "height": 4},
                       "sampler": "tabulated", "materials": mats,
                       "objects": [{"type": "sphere", "radius": 0.5, "material": "m0"}]})


def check_tabulated_budget(n_materials: int, path: pathlib.Path) -> str:
    """A scene whose tables are over the budget: refused at load, before any table is built."""
    from hybridbrdf.render.tracer import render

    path.write_text(tabulated_scene_text(n_materials))
    return check_hostile(f"tabulated scene of {n_materials} materials", lambda: render(str(path)), str(path))


# Forged sizes.

def forged_safetensors(seed_bytes: bytes, rng: np.random.Generator) -> bytes:
    """The seed model with one declared size forged: the header length (past the file, or 2^63),
    a tensor's shape (2^40 elements) or its data_offsets (past the file, reversed, 2^64 - 1)."""
    (hlen,) = struct.unpack("<Q", seed_bytes[:8])
    header = json.loads(seed_bytes[8:8 + hlen])
    body = seed_bytes[8 + hlen:]
    r = int(rng.integers(0, 6))
    if r == 0:
        return struct.pack("<Q", [len(seed_bytes), 2**63, 2**64 - 1, hlen + 1][int(rng.integers(0, 4))]) + seed_bytes[8:]
    names = sorted(k for k in header if k != "__metadata__")
    t = header[names[int(rng.integers(0, len(names)))]]
    if r == 1:
        t["shape"] = [2**20, 2**20]
    elif r == 2:
        t["shape"] = [2**62, 4]
    elif r == 3:
        t["data_offsets"] = [t["data_offsets"][0], len(body) + 2**40]
    elif r == 4:
        t["data_offsets"] = [t["data_offsets"][1], t["data_offsets"][0] - 1]
    else:
        t["data_offsets"] = [0, 2**64 - 1]
    text = json.dumps(header).encode()
    return struct.pack("<Q", len(text)) + text + body


def forged_hdr(rng: np.random.Generator) -> bytes:
    """A Radiance header declaring up to 2^31 x 2^31 texels over a few bytes of pixel data."""
    big = [8, 4096, 32768, 65535, 2**27, 2**31 - 1, 2**31, 2**40]
    w, h = (big[int(rng.integers(0, len(big)))] for _ in range(2))
    header = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + b"-Y %d +X %d\n" % (h, w)
    return header + bytes(rng.integers(0, 256, int(rng.integers(0, 64)), dtype=np.uint8))


def check_hdr_file(data: bytes, path: pathlib.Path) -> str:
    """An environment map through the tracer's reader (a 4 x 4 render): a forged header is refused."""
    path.write_bytes(data)
    return check_hostile("environment map", lambda: _readers()["environment map"][1](str(path)), str(path))


# Output equals input: a command told to write over a file it reads must refuse in one line
# (exit 1, no traceback) and leave every file as it was.

OUTPUT_KINDS = ("same path", "symlink", "hard link", "dot-dot path")


def _alias(target: pathlib.Path, kind: str, workdir: pathlib.Path) -> str:
    if kind == "same path":
        return str(target)
    if kind == "dot-dot path":
        (workdir / "sub").mkdir(exist_ok=True)
        return str(workdir / "sub" / ".." / target.name)
    alias = workdir / f"alias-{kind.replace(' ', '-')}{target.suffix}"
    if os.path.lexists(alias):
        os.unlink(alias)
    (os.symlink if kind == "symlink" else os.link)(target, alias)
    return str(alias)


def check_output_over_input(command: str, kind: str, which: str, workdir: pathlib.Path, seed_bytes: bytes) -> str:
    """``hbrdf-codegen ... -o X`` or ``hbrdf render ... -o X`` where X reaches one of its inputs
    (``which``: "model" or "scene") through ``kind``: exit 1, one stderr line, nothing changed."""
    model = workdir / "m.safetensors"
    model.write_bytes(seed_bytes)
    scene = workdir / "s.json"
    scene.write_text(json.dumps({"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 4, "height": 4},
                                 "materials": {"p": {"type": "model", "file": "m.safetensors",
                                                     "material": seed_metadata(seed_bytes)["materials"][0]["name"]}},
                                 "objects": [{"type": "sphere", "material": "p"}], "spp": 1}))
    before = {p: p.read_bytes() for p in (model, scene)}
    out = _alias(model if which == "model" else scene, kind, workdir)
    if command == "codegen":
        from hybridbrdf.codegen.main import main

        argv, prog = [str(model), "--target", "glsl", "--scene", str(scene), "-o", out], "hbrdf-codegen"
    else:
        from hybridbrdf.cli import main

        argv, prog = ["render", str(scene), "-o", out, "--quiet"], "hbrdf render"
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    except Exception as exc:  # noqa: BLE001
        raise Violation(f"{prog} -o {which} ({kind}): {type(exc).__name__} escaped: {exc!r}"[:2000]) from exc
    text = err.getvalue()
    if rc != 1 or text.count("\n") != 1 or "Traceback" in text or not text.startswith(f"{prog}: error: "):
        raise Violation(f"{prog} -o {which} ({kind}): exit {rc}, stderr {text[-500:]!r}")
    if "would destroy that input" not in text:
        raise Violation(f"{prog} -o {which} ({kind}): refused for another reason: {text.strip()[:500]!r}")
    for p, data in before.items():
        if p.read_bytes() != data:
            raise Violation(f"{prog} -o {which} ({kind}): {p.name} was changed")
    return REJECTED


# ---- hostile inputs, round three (issue 45): API type confusion, absurd counts, non-finite
# environment maps, extreme geometry ----
#
# Every input below is invalid by construction and must be refused within HOSTILE_TIME_S and
# MEMORY_BOUND (check_hostile): the Python API with a one-line TypeError or ValueError naming the
# argument (docs/CONVENTIONS.md, "Counts and memory"), counts before anything is allocated (a
# count of 10^9 and more under a 1 GiB address-space allowance), environment maps and geometry
# with one line naming the scene file (docs/RENDERING.md, "Limits and validation").

#: A refusal at the public API: a wrong type, a value out of range, an unknown material.
API_ERRORS = (TypeError, ValueError, KeyError)

_ROWS = 10 ** 9  # rows of the broadcast views: 24 bytes of data each, 10^9 rows


def _view(cols: int, rows: int = _ROWS) -> np.ndarray:
    return np.broadcast_to(np.linspace(0.2, 0.9, cols), (rows, cols))


#: Wrong values by the kind of argument they are given for: each is invalid for every argument
#: of its kind (a string where a number belongs, a bool where a count or a name does, ...).
WRONG = {
    "count": [True, "64", 64.0, [64], np.float64(64), 1 + 2j, -1, 0, 10 ** 12, 2 ** 63, 2 ** 70],
    "real": [None, True, False, "0.5", b"0.5", [0.5], {"t": 0.5}, 0.5 + 0j, float("nan"), float("inf"), -0.1, 1.5,
             np.bool_(True), np.array([0.5, 0.5])],
    "name": [None, 5, True, 1.5, b"new", ["new"], ("new",), np.int64(3), {"new": 1}],
    "material": [None, True, False, 1.5, b"mat-0", ["mat-0"], ("mat-0",), -1, 3, 2 ** 70, "no such material",
                 np.float64(0), np.bool_(False)],
    "parameter": [True, "0.5", b"0.5", [0.5, "x"], {"a": 1}, float("nan"), -1.0, [0.1] * 5, np.zeros((2, 2)),
                  np.array(["0.5"]), 1 + 1j],
    "flag": [None, "no", "True", 1, 0, [True], np.float64(1.0)],
    "rows": [None, "wi", b"xyz", 5, [["a", "b", "c"]], np.zeros((2, 3), object), np.ones((2, 3), bool),
             np.zeros((2, 4)), np.zeros(3), [[1, 2, 3], [1, 2]], np.zeros((2, 3), complex), _view(3)],
    "strategy": [None, 5, b"mis", ["mis"], "MIS ", "nope"],
    "dtype": ["float32", np.float32, 5, "torch.float64"],
}

#: (surface, argument, kind, call(model, source, value)): one argument of one public function
#: given the wrong value. ``model`` is a HybridModel read from a file with materials mat-0..2.
API_ARGUMENTS = [
    ("model.edit", "name", "name", lambda m, s, v: m.edit("mat-0", v, kd=0.5)),
    ("model.edit", "material", "material", lambda m, s, v: m.edit(v, "new", kd=0.5)),
    ("model.edit", "kd", "parameter", lambda m, s, v: m.edit("mat-0", "new", kd=v)),
    ("model.edit", "eta", "parameter", lambda m, s, v: m.edit("mat-0", "new", eta=v)),
    ("model.edit", "alpha", "parameter", lambda m, s, v: m.edit("mat-0", "new", alpha=v)),
    ("model.edit", "conserve_energy", "flag", lambda m, s, v: m.edit("mat-0", "new", kd=0.5, conserve_energy=v)),
    ("model.mix", "t", "real", lambda m, s, v: m.mix("mat-0", "mat-1", v, "new")),
    ("model.mix", "name", "name", lambda m, s, v: m.mix("mat-0", "mat-1", 0.5, v)),
    ("model.mix", "material", "material", lambda m, s, v: m.mix(v, "mat-1", 0.5, "new")),
    ("model.mix", "conserve_energy", "flag", lambda m, s, v: m.mix("mat-0", "mat-1", 0.5, "new", conserve_energy=v)),
    ("model.albedo", "samples", "count", lambda m, s, v: m.albedo("mat-0", samples=v)),
    ("model.albedo", "material", "material", lambda m, s, v: m.albedo(v, samples=16)),
    ("model.eval", "wi", "rows", lambda m, s, v: m.eval(v, [[0.0, 0.0, 1.0]], 0)),
    ("model.eval", "wo", "rows", lambda m, s, v: m.eval([[0.0, 0.0, 1.0]], v, 0)),
    ("model.eval (torch)", "wi", "rows", lambda m, s, v: m.eval(v, [[0.0, 0.0, 1.0]], 0, dtype=_torch().float32)),
    ("model.eval", "material", "material", lambda m, s, v: m.eval([[0.0, 0.0, 1.0]], [[0.0, 0.0, 1.0]], v)),
    ("model.eval", "dtype", "dtype", lambda m, s, v: m.eval([[0.0, 0.0, 1.0]], [[0.0, 0.0, 1.0]], 0, dtype=v)),
    ("model.eval_analytic", "wo", "rows", lambda m, s, v: m.eval_analytic([[0.0, 0.0, 1.0]], v, 0)),
    ("AnalyticParams", "kd", "parameter", lambda m, s, v: hb.AnalyticParams(kd=v)),
    ("AnalyticParams", "alpha", "parameter", lambda m, s, v: hb.AnalyticParams(alpha=v)),
    ("analytic_eval", "wi", "rows", lambda m, s, v: hb.analytic_eval(v, [[0.0, 0.0, 1.0]], hb.AnalyticParams())),
    ("pdf", "wo", "rows", lambda m, s, v: hb.pdf([[0.0, 0.0, 1.0]], v, hb.AnalyticParams())),
    ("pdf", "strategy", "strategy", lambda m, s, v: hb.pdf([[0.0, 0.0, 1.0]], [[0.0, 0.0, 1.0]], hb.AnalyticParams(), v)),
    ("sample", "wo", "rows", lambda m, s, v: hb.sample(v, [[0.5, 0.5]], hb.AnalyticParams())),
    ("sample", "strategy", "strategy", lambda m, s, v: hb.sample([[0.0, 0.0, 1.0]], [[0.5, 0.5]], hb.AnalyticParams(), v)),
    ("BRDFSource.eval", "wi", "rows", lambda m, s, v: s.eval(v, [[0.0, 0.0, 1.0]])),
]

# What an error must contain to name the argument: its name ("t " for t, which any word holds).
_NAMED_BY = {"t": "t "}


def _torch():
    import torch

    return torch


def api_seed(workdir: pathlib.Path):
    """(model, source) the API generators call: a small random model read from a file (materials
    mat-0, mat-1, mat-2) and synthetic:gold."""
    import torch

    from hybridbrdf.sources import open_source

    torch.manual_seed(0)
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    path = workdir / "api-model.safetensors"
    model.save(path)
    return hb.load_model(path), open_source("synthetic:gold")


def api_type_confusion(rng: np.random.Generator):
    """(surface, argument, value, call): one public function with one argument given a wrong value."""
    surface, argument, kind, call = API_ARGUMENTS[int(rng.integers(0, len(API_ARGUMENTS)))]
    values = WRONG[kind]
    value = values[int(rng.integers(0, len(values)))]
    return surface, argument, value, call


def check_api_call(surface: str, argument: str, value, call, model, source) -> str:
    """``surface`` with ``argument`` = ``value`` (wrong by construction): a one-line TypeError,
    ValueError or KeyError naming the argument, within the time and memory bounds."""
    return check_hostile(f"{surface}({argument}={value!r:.60})", lambda: call(model, source, value),
                         _NAMED_BY.get(argument, argument), errors=API_ERRORS)


#: (surface, argument, call(model, count)): every public count and pair count, given an absurd
#: one. Pair counts come as broadcast views (24 bytes whatever their rows): nothing but the check
#: stops a copy.
API_COUNTS = [
    ("model.albedo", "samples", lambda m, n: m.albedo("mat-0", samples=n)),
    ("energy.tables", "samples", lambda m, n: _energy().tables(m, ["mat-0"], samples=n)),
    ("demo.run_demo", "--samples", lambda m, n: _demo().run_demo("/nonexistent/never-written.png", samples=n)),
    ("model.eval", "wi rows", lambda m, n: m.eval(_view(3, n), _view(3, n), 0)),
    ("model.eval (torch)", "wi rows", lambda m, n: m.eval(_view(3, n), _view(3, n), 0, dtype=_torch().float64)),
    ("model.eval_analytic", "wi rows", lambda m, n: m.eval_analytic(_view(3, n), _view(3, n), 1)),
    ("analytic_eval", "wi rows", lambda m, n: hb.analytic_eval(_view(3, n), _view(3, n), hb.AnalyticParams())),
    ("sample", "wo rows", lambda m, n: hb.sample(_view(3, n), _view(2, n), hb.AnalyticParams())),
    ("pdf", "wi rows", lambda m, n: hb.pdf(_view(3, n), _view(3, n), hb.AnalyticParams(), "ggx")),
    ("BRDFSource.eval", "wi rows", lambda m, n: _gold().eval(_view(3, n), _view(3, n))),
]

#: Absurd counts: from past the machine's memory at the smallest per-unit cost to 2^50 (NumPy
#: refuses views of more than 2^63 bytes itself).
ABSURD = [10 ** 9, 3 * 10 ** 9, 10 ** 10, 10 ** 12, 2 ** 40, 2 ** 50]


def _energy():
    from hybridbrdf.model import energy

    return energy


def _demo():
    from hybridbrdf import demo

    return demo


@functools.lru_cache(maxsize=1)
def _gold():
    from hybridbrdf.sources import open_source

    return open_source("synthetic:gold")


def absurd_count(rng: np.random.Generator):
    """(surface, argument, count, call): one public count or pair count at an absurd size."""
    surface, argument, call = API_COUNTS[int(rng.integers(0, len(API_COUNTS)))]
    return surface, argument, ABSURD[int(rng.integers(0, len(ABSURD)))], call


def check_absurd_count(surface: str, argument: str, count: int, call, model) -> str:
    """Refused in one line naming the argument and the largest count that fits ("at most"),
    before allocating: within 2 s and a 1 GiB address-space allowance."""
    def run():
        try:
            call(model, count)
        except ValueError as exc:
            if "at most" not in str(exc):
                raise Violation(f"{surface}({argument}={count}): refused without its bound: {exc}") from exc
            raise

    return check_hostile(f"{surface}({argument}={count})", run, argument, errors=(ValueError,))


#: hbrdf's count flags (docs/CONVENTIONS.md, "Counts and memory"): COMMAND, FLAG.
COUNT_FLAGS = [("info", "--albedo-samples"), ("demo", "--samples"), ("bound", "--samples"), ("eval", "--pairs"),
               ("fit", "--pool"), ("fit", "--batch"), ("fit", "--eval-pairs")]
#: Counts for them: within the flags' ranges (refused by memory) and beyond (refused by range).
CLI_COUNTS = [10 ** 8, 3 * 10 ** 8, 10 ** 9, 10 ** 12, 2 ** 63, 10 ** 30]


def check_cli_count(command: str, flag: str, count: int, workdir: pathlib.Path, model_path: pathlib.Path) -> str:
    """``hbrdf COMMAND ... FLAG COUNT`` run in this process: exit 1 or 2 with one error line
    naming the flag, nothing written, within the time and memory bounds (no MemoryError)."""
    from hybridbrdf.cli import main

    out = workdir / f"count-{command}.out"
    argv = {"info": ["info", str(model_path)], "demo": ["demo", "--out", str(out)],
            "bound": ["bound", str(model_path), "--out", str(out)],
            "eval": ["eval", str(model_path), "synthetic:gold"],
            "fit": ["fit", "synthetic:gold", "--out", str(out), "--no-preview", "--quiet"]}[command] + [flag, str(count)]
    err = io.StringIO()
    result = {}

    def run():
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                result["rc"] = main(argv)
        except SystemExit as exc:
            result["rc"] = exc.code
        raise ValueError(f"{flag} exit {result['rc']}")  # the outcome is checked below

    check_hostile(f"hbrdf {command} {flag} {count}", run, flag)
    lines = [line for line in err.getvalue().splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith(f"hbrdf {command}") and "error:" in line]
    if result.get("rc") not in (1, 2) or len(errors) != 1 or flag not in errors[0] or "Traceback" in err.getvalue():
        raise Violation(f"hbrdf {command} {flag} {count}: exit {result.get('rc')}, stderr {err.getvalue()[-500:]!r}")
    if os.path.lexists(out):
        raise Violation(f"hbrdf {command} {flag} {count}: wrote {out.name}")
    return REJECTED


# Non-finite and negative environment texels: refused at load with one line naming the scene file
# (docs/RENDERING.md, "Environment texels"), through the tracer and through hbrdf view --env.

ENV_KINDS = ("one +inf texel", "one -inf texel", "one nan texel", "all nan", "all negative", "one negative texel",
             "one huge negative")


def hostile_environment(kind: str, rng: np.random.Generator, path: pathlib.Path) -> None:
    """An EXR environment map at ``path`` (8 to 64 texels wide, 2:1) of ``kind``."""
    from hybridbrdf.render.tracer import write_exr

    w = int(rng.choice([8, 16, 64]))
    img = rng.uniform(0.0, 4.0, (w // 2, w, 3)).astype(np.float32)
    y, x, c = int(rng.integers(0, w // 2)), int(rng.integers(0, w)), int(rng.integers(0, 3))
    if kind == "all nan":
        img[:] = np.nan
    elif kind == "all negative":
        img = -img - np.float32(1e-3)
    else:
        img[y, x, c] = {"one +inf texel": np.inf, "one -inf texel": -np.inf, "one nan texel": np.nan,
                        "one negative texel": -float(rng.uniform(1e-6, 1.0)), "one huge negative": -3e38}[kind]
    write_exr(img, str(path))


def check_environment(kind: str, rng: np.random.Generator, workdir: pathlib.Path, through: str = "render") -> str:
    """A hostile map through ``render()`` of a 4 x 4 scene file ("render") or the viewer's
    environment (``hbrdf view --env``, "view"): refused in one line naming the scene file (the
    map for the viewer, which has no scene file)."""
    env = workdir / "hostile-env.exr"
    hostile_environment(kind, rng, env)
    if through == "view":
        from hybridbrdf.viewer.lighting import environment_spec, page_environment

        return check_hostile(f"hbrdf view --env ({kind})", lambda: page_environment(environment_spec(str(env))),
                             str(env))
    from hybridbrdf.render.tracer import render

    scene = workdir / "hostile-env.json"
    scene.write_text(json.dumps({"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 4, "height": 4},
                                 "environment": {"type": "file", "file": str(env)},
                                 "objects": [{"type": "sphere", "material": {"type": "analytic"}}],
                                 "spp": 1, "threads": 1}))
    return check_hostile(f"environment map ({kind})", lambda: render(str(scene)), str(scene))


# Extreme geometry: objects far beyond float32's reach at the camera's scale.

GEOMETRY_KINDS = ("huge plane", "huge sphere", "far sphere", "huge mesh", "far camera")


def extreme_geometry_scene(kind: str, rng: np.random.Generator, workdir: pathlib.Path) -> dict:
    """A 4 x 4 scene (camera at distance ~3) with one object of ``kind`` at 3e10 .. 3e38."""
    big = float(rng.choice([3e10, 1e12 + 1, 1e15, 1e20, 1e30, 3e38]))
    analytic = {"type": "analytic"}
    camera = {"position": [0, 0, 3], "look_at": [0, 0, 0], "width": 4, "height": 4}
    if kind == "huge plane":
        obj = {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": big, "material": analytic}
    elif kind == "huge sphere":
        obj = {"type": "sphere", "center": [0, 0, 0], "radius": big, "material": analytic}
    elif kind == "far sphere":
        obj = {"type": "sphere", "center": [big, 0, 0], "radius": 1, "material": analytic}
    elif kind == "huge mesh":
        mesh = workdir / "hostile-mesh.obj"
        mesh.write_text(f"v {-big} -1 {-big}\nv {big} -1 {-big}\nv 0 -1 {big}\nf 1 2 3\n")
        obj = {"type": "mesh", "file": str(mesh), "material": analytic}
    elif kind == "far camera":
        camera = dict(camera, position=[big, 0, 3], look_at=[big, 0, 0])
        obj = {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": analytic}
    else:
        raise ValueError(f"unknown geometry kind {kind!r}")
    return {"camera": camera, "objects": [obj], "spp": 1, "threads": 1}


def check_extreme_geometry(kind: str, rng: np.random.Generator, workdir: pathlib.Path) -> str:
    """A scene file with extreme geometry through ``render()``: refused in one line naming the file."""
    from hybridbrdf.render.tracer import render

    scene = workdir / "hostile-geometry.json"
    scene.write_text(json.dumps(extreme_geometry_scene(kind, rng, workdir)))
    return check_hostile(f"scene geometry ({kind})", lambda: render(str(scene)), str(scene))
