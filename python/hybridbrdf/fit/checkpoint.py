"""Fit checkpoints: written atomically with a checksum, validated before any expensive work.

A checkpoint file is one header line and a ``torch.save`` payload::

    hybridbrdf checkpoint 1 sha256=<64 hex digits of the SHA-256 of the payload>\\n
    <payload: torch.save of the state dict, loaded with weights_only=True>

The state dict holds ``module`` (the model's state_dict), ``optimizer`` and ``scheduler``
(their state_dicts), ``step`` (steps done), ``settings`` (the FitSettings as a dict),
``names`` (material names), ``torch_rng`` and ``batch_rng`` (the global and the batch
generator's states), ``train_seconds`` and ``timed_from_step`` (see :func:`save_fit_state`).

Reading checks, in this order, and stops at the first problem with an
:class:`~hybridbrdf.errors.InputFileError` whose one-line message names the file:
the file (a readable regular file), the header and the checksum (byte flips, truncation),
the payload's zip entries (stored as torch.save stores them, never compressed, so that what
torch.load allocates is bounded by the file's size: no decompression bomb), the payload
(loadable, a dict), its structure (every key, of its type), the settings (the
fit's own), the step (0 <= step <= settings.steps; = steps: the fit is done) and every
number (finite; Adam's second moments >= 0); then, against the model and optimiser the fit
builds (:func:`restore`), the material names, every tensor's shape and the optimiser's
parameter groups. Nothing is loaded into the model until all of it passed.

Checkpoints written before the header existed (a bare ``torch.save`` zip) are still read,
with every check but the checksum: damage to their bytes cannot be detected.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import math
import os
import zipfile
from typing import Any, Dict, List, Tuple

import torch

from hybridbrdf.errors import InputFileError
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.inputs import check_input_file, read_input_bytes
from hybridbrdf.files import atomic_write_bytes

#: The header's first words; the version follows, then the checksum.
MAGIC = b"hybridbrdf checkpoint "
VERSION = 1
_LEGACY_MAGIC = b"PK\x03\x04"  # a bare torch.save (zip) from before the header
_MAX_HEADER = 256

#: Keys every checkpoint has, with their types; _OPTIONAL may be missing from older ones.
_REQUIRED = {"module": dict, "optimizer": dict, "scheduler": dict, "step": int, "settings": dict,
             "names": list, "torch_rng": torch.Tensor}
_OPTIONAL = {"train_seconds": (float, int), "timed_from_step": int, "batch_rng": torch.Tensor}
#: Settings that may differ between the run that wrote a checkpoint and the one resuming it.
#: Settings a resumed fit may change: where it runs, what it reports, and the recipe's name (a
#: label; the values it set are compared one by one).
_FREE_SETTINGS = ("sources", "device", "eval_pairs", "recipe")
_ADAM_STATE = ("step", "exp_avg", "exp_avg_sq")


class CheckpointError(InputFileError):
    """A checkpoint that cannot be resumed: missing, damaged, malformed or from another fit."""


# ---- writing ---------------------------------------------------------------------------


def encode(state: Dict[str, Any]) -> bytes:
    """The bytes of a checkpoint file holding ``state``: header line, then the payload."""
    buf = io.BytesIO()
    torch.save(state, buf)
    payload = buf.getvalue()
    return MAGIC + b"%d sha256=%s\n" % (VERSION, hashlib.sha256(payload).hexdigest().encode()) + payload


def check_not_another_fits(path, resume: bool, force: bool) -> None:
    """Refuse to start a fresh fit (not ``resume``) over an existing checkpoint file ``path``
    unless ``force``: its first checkpoint would replace another fit's, which could then never
    be resumed. Raises :class:`CheckpointError` naming the file."""
    if not resume and not force and os.path.lexists(path):
        raise CheckpointError(path, "exists (another fit's checkpoint?): --resume continues it, --force replaces it")


def save(path, state: Dict[str, Any]) -> None:
    """Write ``state`` to the checkpoint file ``path`` atomically."""
    atomic_write_bytes(path, encode(state))


def save_fit_state(path, module, opt, sched, step: int, settings: FitSettings, names: List[str],
                   train_seconds: float, timed_from_step: int, gen: torch.Generator) -> None:
    """Write a fit's checkpoint after ``step`` steps: what :func:`restore` loads back.

    ``train_seconds``: training time of the steps from ``timed_from_step`` on (0 unless the fit
    once resumed a checkpoint that kept no time), so that a resumed fit records the time of the
    whole fit, not of its last segment. ``batch_rng``: the batch generator's state, so that a
    resume continues the batch sequence without replaying it (docs/FITTING.md, "Checkpoints")."""
    save(path, {"module": module.state_dict(), "optimizer": opt.state_dict(), "scheduler": sched.state_dict(),
                "step": step, "settings": dataclasses.asdict(settings), "names": names,
                "torch_rng": torch.get_rng_state(), "batch_rng": gen.get_state(),
                "train_seconds": float(train_seconds), "timed_from_step": int(timed_from_step)})


# ---- reading ---------------------------------------------------------------------------


def _read_bytes(path: str) -> bytes:
    # A FIFO or a device could block or never end: hybridbrdf.inputs refuses them before opening.
    # No size bound beyond the file's own: a checkpoint holds the optimiser's state of up to
    # spec.MAX_MATERIALS materials, gigabytes by design, and a regular file's size is what it holds.
    size = check_input_file(path, "checkpoint file", None, CheckpointError)
    # ... but not beyond this machine's memory: the whole file is read at once, and a sparse
    # file of a terabyte (no disk used) raised MemoryError with no file named.
    memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if size > memory:
        raise CheckpointError(path, f"checkpoint file of {size} bytes is larger than this machine's memory "
                                    f"({memory} bytes)")
    return read_input_bytes(path, "checkpoint file", size, CheckpointError)


def _payload(path: str, data: bytes) -> Tuple[bytes, bool]:
    """(payload, checksummed) of a checkpoint file's bytes; the header and checksum verified."""
    if not data:
        raise CheckpointError(path, "is empty (a checkpoint interrupted before its first write?)")
    if data.startswith(_LEGACY_MAGIC):
        return data, False
    if not data.startswith(MAGIC):
        raise CheckpointError(path, "is not a hybridbrdf checkpoint (unknown header)")
    end = data.find(b"\n", 0, _MAX_HEADER)
    words = data[len(MAGIC):end].split(b" ") if end > 0 else []
    if len(words) != 2 or not words[0].isdigit() or not words[1].startswith(b"sha256="):
        raise CheckpointError(path, "checkpoint header is damaged")
    if int(words[0]) != VERSION:
        raise CheckpointError(path, f"checkpoint format {int(words[0])} is not one this hybridbrdf reads ({VERSION})")
    payload = data[end + 1:]
    if hashlib.sha256(payload).hexdigest().encode() != words[1][len(b"sha256="):]:
        raise CheckpointError(path, "checkpoint is damaged: its content does not match its SHA-256 checksum "
                                    "(truncated or altered)")
    return payload, True


def _check_archive(path: str, payload: bytes) -> None:
    """Refuse a zip payload whose entries would expand beyond the file before torch.load opens it.
    torch.save stores every entry as is (no compression), so a checkpoint's content is never
    larger than the file: that is the budget. A deflated entry is a decompression bomb waiting
    to happen (a small zip can expand a thousandfold in torch.load before any check runs), and an
    entry that declares more bytes than the file holds would size an allocation by a lie. Only
    the central directory is read here (what torch's reader allocates by), not the data."""
    if not payload.startswith(_LEGACY_MAGIC):
        return  # not a zip: torch's other formats are not compressed either
    try:
        infos = zipfile.ZipFile(io.BytesIO(payload)).infolist()
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError, OSError, NotImplementedError) as exc:
        raise CheckpointError(path, f"cannot be read as a checkpoint ({type(exc).__name__}: "
                                    f"{(str(exc).splitlines() or [''])[0][:200]})") from None
    total = 0
    for info in infos:
        if info.compress_type != zipfile.ZIP_STORED or info.file_size != info.compress_size:
            raise CheckpointError(path, f"checkpoint entry '{info.filename[:100]}' is compressed ({info.compress_size} "
                                        f"bytes that expand to {info.file_size}); torch.save never compresses, so "
                                        "this is not a checkpoint hybridbrdf wrote")
        total += info.file_size
    if total > len(payload):
        raise CheckpointError(path, f"checkpoint entries declare {total} bytes, more than the {len(payload)} "
                                    "bytes of the file hold")


def read(path) -> Tuple[Dict[str, Any], bool]:
    """(state, checksummed): the state dict of the checkpoint file ``path``, header, checksum
    and top-level type verified (not yet its content: see :func:`check`). ``checksummed`` is
    False for a checkpoint from before the header (no damage detection)."""
    path = os.fspath(path)
    payload, checksummed = _payload(path, _read_bytes(path))
    _check_archive(path, payload)
    try:
        state = torch.load(io.BytesIO(payload), map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for bad zips and pickles; all mean "unreadable"
        first = (str(exc).strip().splitlines() or [""])[0].split(". ")[0][:200]  # torch's first sentence
        raise CheckpointError(path, f"cannot be read as a checkpoint ({type(exc).__name__}: {first})") from None
    if not isinstance(state, dict):
        raise CheckpointError(path, f"checkpoint holds {_a(type(state).__name__)}, not a dict of training state")
    return state, checksummed


# ---- checks that need only the file and the settings ------------------------------------


def _check_structure(path: str, state: Dict[str, Any]) -> None:
    for key, kind in _REQUIRED.items():
        if key not in state:
            raise CheckpointError(path, f"checkpoint has no '{key}'")
        if not isinstance(state[key], kind) or (kind is int and isinstance(state[key], bool)):
            raise CheckpointError(path, f"checkpoint's '{key}' is {_a(type(state[key]).__name__)}, "
                                        f"not {_a(kind.__name__)}")
    for key, kind in _OPTIONAL.items():
        if key in state and (not isinstance(state[key], kind) or isinstance(state[key], bool)):
            raise CheckpointError(path, f"checkpoint's '{key}' is {_a(type(state[key]).__name__)}")
    if ("train_seconds" in state) != ("timed_from_step" in state):
        raise CheckpointError(path, "checkpoint has one of 'train_seconds' and 'timed_from_step' without the other")
    if not all(isinstance(n, str) for n in state["names"]):
        raise CheckpointError(path, "checkpoint's 'names' are not all strings")
    for key, value in state["module"].items():
        if not isinstance(key, str) or not isinstance(value, torch.Tensor):
            raise CheckpointError(path, f"checkpoint's module entry {key!r} is not a named tensor")


def _a(noun: str) -> str:
    """``noun`` with its indefinite article: "an int", "a dict"."""
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"


def _plain(value) -> bool:
    """JSON-like: what dataclasses.asdict(FitSettings) holds."""
    if isinstance(value, (list, tuple)):
        return all(_plain(v) for v in value)
    return value is None or isinstance(value, (bool, int, float, str))


def _check_settings(path: str, saved_settings: Dict[str, Any], settings: FitSettings) -> None:
    bad = sorted(str(k) for k, v in saved_settings.items() if not isinstance(k, str) or not _plain(v))
    if bad:
        raise CheckpointError(path, f"checkpoint's settings {', '.join(bad)} are not plain values")
    # A setting added after the checkpoint was written had its paper value then: every setting
    # was introduced with the paper's behaviour as its default (the "paper" recipe).
    defaults = dataclasses.asdict(FitSettings.from_recipe("paper"))
    saved = {k: v for k, v in {**defaults, **saved_settings}.items() if k not in _FREE_SETTINGS}
    mine = {k: v for k, v in dataclasses.asdict(settings).items() if k not in _FREE_SETTINGS}
    if saved != mine:
        keys = list(mine) + [k for k in saved if k not in mine]
        diff = ", ".join(f"{k}: {saved.get(k)!r} -> {mine.get(k)!r}" for k in keys if saved.get(k) != mine.get(k))
        raise CheckpointError(path, f"checkpoint was written with other settings ({diff})")


def _finite(t: torch.Tensor) -> bool:
    return not t.is_floating_point() or bool(torch.isfinite(t).all())


def _check_rng(path: str, state: Dict[str, Any], key: str, expected: torch.Tensor) -> None:
    t = state[key]
    if t.dtype != torch.uint8 or t.shape != expected.shape:
        raise CheckpointError(path, f"checkpoint's '{key}' is a {t.dtype} tensor of shape {tuple(t.shape)}, "
                                    f"not a generator state ({expected.numel()} bytes)")


def _check_numbers(path: str, state: Dict[str, Any], steps: int) -> None:
    step = state["step"]
    if not 0 <= step <= steps:
        raise CheckpointError(path, f"checkpoint's step {step} is outside [0, {steps}] (the fit's --steps)")
    for key, t in state["module"].items():
        if not _finite(t):
            raise CheckpointError(path, f"checkpoint's module tensor '{key}' holds NaN or Inf")
    if "train_seconds" in state and not (math.isfinite(state["train_seconds"]) and state["train_seconds"] >= 0):
        raise CheckpointError(path, f"checkpoint's train_seconds {state['train_seconds']!r} is not a time")
    if "timed_from_step" in state and not 0 <= state["timed_from_step"] <= step:
        raise CheckpointError(path, f"checkpoint's timed_from_step {state['timed_from_step']} is outside [0, {step}]")
    _check_rng(path, state, "torch_rng", torch.get_rng_state())
    if "batch_rng" in state:
        _check_rng(path, state, "batch_rng", torch.Generator(device="cpu").get_state())


def check(path, state: Dict[str, Any], settings: FitSettings) -> None:
    """Everything about a checkpoint's ``state`` that needs no model: its structure, that it
    was written by a fit with these ``settings``, its step and its numbers (finite).
    Raises :class:`CheckpointError` naming ``path``."""
    path = os.fspath(path)
    _check_structure(path, state)
    _check_settings(path, state["settings"], settings)
    _check_numbers(path, state, settings.steps)


def load(path, settings: FitSettings) -> Tuple[Dict[str, Any], bool]:
    """:func:`read` and :func:`check`: (state, checksummed) of a checkpoint a fit with
    ``settings`` can resume. Cheap (no sources, no model): ``hbrdf fit --resume`` calls it
    before opening any source."""
    state, checksummed = read(path)
    check(path, state, settings)
    return state, checksummed


# ---- checks against the fit's model and optimiser, then restoring -----------------------


def _shape(t: torch.Tensor) -> str:
    return "(" + ", ".join(str(d) for d in t.shape) + ")"


def _check_module(path: str, saved: Dict[str, torch.Tensor], module) -> None:
    mine = module.state_dict()
    missing, extra = sorted(set(mine) - set(saved)), sorted(set(saved) - set(mine))
    if missing or extra:
        what = (f"lacks {', '.join(missing[:3])}" if missing else f"has unknown {', '.join(extra[:3])}")
        raise CheckpointError(path, f"checkpoint's model {what} (another architecture?)")
    for key, t in mine.items():
        s = saved[key]
        if s.shape != t.shape or s.dtype != t.dtype:
            raise CheckpointError(path, f"checkpoint's tensor '{key}' is {s.dtype} {_shape(s)}, the fit builds "
                                        f"{t.dtype} {_shape(t)} (another architecture?)")
    if "isotropic" in mine and not torch.equal(saved["isotropic"].cpu(), mine["isotropic"].cpu()):
        raise CheckpointError(path, "checkpoint's isotropy flags differ from the sources'")


def _check_group(path: str, i: int, group: Any, fresh: Dict[str, Any], expected_lr: float, step: int) -> None:
    if not isinstance(group, dict) or group.get("params") != fresh["params"]:
        raise CheckpointError(path, f"checkpoint's optimiser group {i} does not hold the fit's parameters")
    for key, value in fresh.items():
        if key not in ("params", "lr") and group.get(key) != value:
            raise CheckpointError(path, f"checkpoint's optimiser group {i} has {key} {group.get(key)!r}, "
                                        f"the fit uses {value!r}")
    lr = group.get("lr")
    if isinstance(lr, bool) or not isinstance(lr, (int, float)) or not math.isclose(lr, expected_lr, rel_tol=1e-6,
                                                                                     abs_tol=1e-12):
        raise CheckpointError(path, f"checkpoint's optimiser group {i} has learning rate {lr!r}, "
                                    f"the schedule gives {expected_lr!r} at step {step}")


def _check_moments(path: str, index: Any, entry: Any, param: torch.Tensor) -> None:
    if not isinstance(entry, dict) or set(entry) != set(_ADAM_STATE):
        raise CheckpointError(path, f"checkpoint's optimiser state {index!r} is not AdamW's "
                                    f"({', '.join(_ADAM_STATE)})")
    if not all(isinstance(entry[k], torch.Tensor) for k in _ADAM_STATE):
        raise CheckpointError(path, f"checkpoint's optimiser state {index!r} holds a non-tensor")
    n, m, v = entry["step"], entry["exp_avg"], entry["exp_avg_sq"]
    if n.numel() != 1 or not n.is_floating_point() or not (math.isfinite(float(n)) and float(n) >= 0):
        raise CheckpointError(path, f"checkpoint's optimiser state {index!r} has a bad step count")
    for name, t in (("exp_avg", m), ("exp_avg_sq", v)):
        if t.shape != param.shape or t.dtype != param.dtype:
            raise CheckpointError(path, f"checkpoint's optimiser {name} {index!r} is {t.dtype} {_shape(t)}, "
                                        f"its parameter {param.dtype} {_shape(param)}")
        if not _finite(t):
            raise CheckpointError(path, f"checkpoint's optimiser {name} {index!r} holds NaN or Inf")
    if bool((v < 0).any()):  # Adam divides by sqrt(exp_avg_sq)
        raise CheckpointError(path, f"checkpoint's optimiser exp_avg_sq {index!r} holds negative values")


def _check_optimizer(path: str, saved: Dict[str, Any], opt, sched, step: int) -> None:
    fresh = opt.state_dict()
    groups, states = saved.get("param_groups"), saved.get("state")
    if not isinstance(groups, list) or len(groups) != len(fresh["param_groups"]) or not isinstance(states, dict):
        raise CheckpointError(path, "checkpoint's optimiser state is not the fit's (parameter groups differ)")
    for i, (group, mine) in enumerate(zip(groups, fresh["param_groups"])):
        expected_lr = sched.base_lrs[i] * sched.lr_lambdas[i](step)
        _check_group(path, i, group, mine, expected_lr, step)
    params = [p for g in opt.param_groups for p in g["params"]]
    for index, entry in states.items():
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(params):
            raise CheckpointError(path, f"checkpoint's optimiser state names parameter {index!r}, "
                                        f"the fit has {len(params)}")
        _check_moments(path, index, entry, params[index])


def restore(path, state: Dict[str, Any], names: List[str], module, opt, sched) -> None:
    """Check a :func:`load`-ed ``state`` against the fit's material ``names``, ``module`` and
    AdamW ``opt``, then load it into them, the LambdaLR ``sched`` and the global torch RNG.
    Raises :class:`CheckpointError` (and changes nothing) when they do not match."""
    path = os.fspath(path)
    if state["names"] != names:
        raise CheckpointError(path, "checkpoint was written for other materials; refusing to resume")
    step = state["step"]
    _check_module(path, state["module"], module)
    _check_optimizer(path, state["optimizer"], opt, sched, step)
    module.load_state_dict(state["module"])
    opt.load_state_dict(state["optimizer"])
    # The schedule is a function of the step alone; rebuilding its state from the step leaves
    # nothing in the file that could set it otherwise.
    sched.load_state_dict({**sched.state_dict(), "last_epoch": step, "_step_count": step + 1,
                           "_last_lr": [g["lr"] for g in opt.param_groups]})
    torch.set_rng_state(state["torch_rng"])
