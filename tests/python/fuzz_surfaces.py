"""The surfaces of the standing fuzz suite (issue 20) and the invariant each must keep:

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
from hybridbrdf.random_model import random_model

VALID, REJECTED = "valid", "rejected"

#: Exception types that are a clean refusal of a bad input (their message is checked too).
CLEAN_ERRORS = (InputFileError, ValueError)


class Violation(AssertionError):
    """An input broke the invariant: the message says which surface and how."""


def _printable_line(text: str) -> bool:
    return "\n" not in text and "\r" not in text and all(ch >= " " and ch != "\x7f" for ch in text)


def expect_clean_error(surface: str, exc: BaseException, names: str) -> str:
    """REJECTED when ``exc`` is a clean one-line error naming ``names``; Violation otherwise."""
    if not isinstance(exc, CLEAN_ERRORS):
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
    from hybridbrdf.codegen import generate

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

def _int_and_float_flags(parser: argparse.ArgumentParser) -> Dict[str, List[argparse.Action]]:
    out: Dict[str, List[argparse.Action]] = {}
    for action in parser._actions:  # noqa: SLF001 - argparse has no public walk over actions
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            for name, sub in action.choices.items():
                out[name] = [a for a in sub._actions if a.option_strings and a.type is not None]  # noqa: SLF001
    return out


def cli_flags() -> List[tuple]:
    """(command, flag) for every typed flag of every ``hbrdf`` command."""
    from hybridbrdf.cli import build_parser

    return [(cmd, a.option_strings[-1]) for cmd, actions in _int_and_float_flags(build_parser()).items()
            for a in actions]


@functools.lru_cache(maxsize=1)
def _parser() -> argparse.ArgumentParser:
    from hybridbrdf.cli import build_parser

    return build_parser()  # parsing does not change it, so one serves every example


def check_cli_flag(command: str, flag: str, value: str) -> str:
    """``hbrdf COMMAND FLAG VALUE`` parsed (nothing run): a usage error of one line, or a value
    that is finite and of the flag's type."""
    from hybridbrdf.cli import settings_from_args

    parser = _parser()
    positional = {"fit": ["synthetic:gold"], "eval": ["m.safetensors", "synthetic:gold"], "info": ["m"],
                  "render": ["scene.json"], "demo": []}.get(command, [])
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            args = parser.parse_args([command, *positional, f"{flag}={value}"])
            if command == "fit":
                settings_from_args(args)
    except SystemExit as exc:
        if exc.code != 2:
            raise Violation(f"hbrdf {command} {flag}={value!r}: exit {exc.code}")
        last = err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else ""
        if not last.startswith("hbrdf") or "error:" not in last:
            raise Violation(f"hbrdf {command} {flag}={value!r}: no usage error line: {err.getvalue()[-500:]!r}")
        return REJECTED
    except Exception as exc:  # noqa: BLE001
        return expect_clean_error(f"hbrdf {command} {flag}", exc, "")
    v = getattr(args, flag.lstrip("-").replace("-", "_"), None)
    if isinstance(v, float) and not np.isfinite(v):
        raise Violation(f"hbrdf {command} {flag}={value!r} accepted a non-finite value {v}")
    return VALID


# ---- checkpoints -------------------------------------------------------------------------------

def checkpoint_seed(workdir: pathlib.Path):
    """(bytes, state, settings) of a valid checkpoint at step 10 of a tiny fit of synthetic:gold."""
    from hybridbrdf import checkpoint as ckpt
    from hybridbrdf.fit_settings import FitSettings
    from hybridbrdf.fitting import fit
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
    """A checkpoint through hybridbrdf.checkpoint.load (what ``hbrdf fit --resume`` runs before
    any source is opened): refused with one line naming it, or valid; never altered."""
    from hybridbrdf import checkpoint as ckpt

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
