"""Hostile input and interruption around fitting: damaged checkpoints fail fast with one line
naming the file, unwritable outputs fail before training, every numeric flag rejects inf, nan
and absurd values, atomic writes leave no temporaries behind (killed writers included), and
the gradients of the PyTorch BRDF and the hybrid models stay finite on the hard cases."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf import spec
from hybridbrdf.fit import checkpoint as ckpt
from hybridbrdf.cli import build_parser
from hybridbrdf.cli import main as cli_main
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.fit import fit
from hybridbrdf.model.networks import build_model
from hybridbrdf.brdf.torch_brdf import eval_analytic, pdf
from hybridbrdf.files import atomic_write_bytes, remove_stale_temporaries

from helpers import AnalyticTestSource, hard_directions, hard_pairs

P_PLAIN = hb.AnalyticParams(kd=[0.4, 0.3, 0.2], eta=1.6, alpha=0.25)
P_ANISO = hb.AnalyticParams(kd=[0.1, 0.5, 0.2], eta=2.0, alpha=(0.15, 0.35))
FAST = 5.0  # seconds: a bad checkpoint or output must fail long before any real work


class Tripwire(AnalyticTestSource):
    """A source that fails the test if evaluated: proves a failure came before the pool."""

    def _eval(self, wi, wo):
        raise AssertionError(f"source {self.name} was evaluated before the bad input was reported")


def sources(cls=AnalyticTestSource):
    return [cls("plain", P_PLAIN), cls("aniso", P_ANISO)]


def tiny(**kw):
    base = dict(width=8, depth=1, steps=20, batch=64, pool=256, eval_pairs=200, seed=5)
    base.update(kw)
    return FitSettings(**base)


def one_line_naming(err: Exception, path) -> str:
    msg = str(err)
    assert "\n" not in msg and msg.startswith(f"{path}: "), msg
    return msg


# ---- checkpoints ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def good_checkpoint(tmp_path_factory):
    """(bytes of a valid checkpoint at step 10 of tiny(), its state)."""
    path = tmp_path_factory.mktemp("ck") / "ck.pt"
    assert fit(sources(), tiny(), checkpoint=str(path), checkpoint_every=10, progress=False, stop_after=10) is None
    state, checksummed = ckpt.read(path)
    assert checksummed and state["step"] == 10
    return path.read_bytes(), state


def _flip(data: bytes, offset: int) -> bytes:
    b = bytearray(data)
    b[offset] ^= 0x5A
    return bytes(b)


def _edited(state, edit):
    """A deep copy of ``state`` changed by ``edit(state)``, encoded with a valid checksum: only
    the structural checks can catch it."""
    import copy

    s = copy.deepcopy(state)
    edit(s)
    return ckpt.encode(s)


def _set(path_keys, value):
    def edit(s):
        d = s
        for k in path_keys[:-1]:
            d = d[k]
        d[path_keys[-1]] = value
    return edit


def _nan_weight(s):
    s["module"]["mlp.hidden.0.weight"][0, 0] = float("nan")


def _other_arch(s):
    s["module"] = build_model("neural", 2, 8, 1, 12, "hardgelu").state_dict()


def _wider_layer(s):
    s["module"]["mlp.hidden.0.weight"] = torch.zeros(16, 10)


def _bare_zip(state) -> bytes:
    import io

    buf = io.BytesIO()
    torch.save(state, buf)
    return buf.getvalue()


def damaged_checkpoints(data: bytes, state):
    """(label, bytes, words the message must hold) for every kind of damage."""
    header = data.index(b"\n") + 1
    n = len(data)
    cases = [("empty", b"", "is empty"),
             ("random bytes", np.random.default_rng(1).bytes(4096), "not a hybridbrdf checkpoint"),
             ("bare zip, truncated", _bare_zip(state)[:3000], "cannot be read as a checkpoint"),
             ("bare zip, garbage", b"PK\x03\x04" + np.random.default_rng(2).bytes(2000),
              "cannot be read as a checkpoint"),
             ("wrong top-level type", ckpt.encode([1, 2, 3]), "holds a list"),
             ("a tensor", ckpt.encode(torch.zeros(3)), "holds a Tensor"),
             ("future format", data.replace(b"checkpoint 1 ", b"checkpoint 7 ", 1), "format 7")]
    for cut in (5, header - 1, header, header + 100, n // 2, n - 1):
        cases.append((f"truncated at {cut}", data[:cut], ""))
    for offset in (0, 3, header - 30, header - 1, header, header + 64, n // 3, n // 2, n - 20, n - 1):
        cases.append((f"byte flipped at {offset}", _flip(data, offset), ""))
    for key in ckpt._REQUIRED:
        cases.append((f"no {key}", _edited(state, lambda s, k=key: s.pop(k)), f"no '{key}'"))
    cases += [
        ("step -5", _edited(state, _set(["step"], -5)), "step -5 is outside [0, 20]"),
        ("step 10**12", _edited(state, _set(["step"], 10 ** 12)), "outside [0, 20]"),
        ("step a string", _edited(state, _set(["step"], "10")), "'step' is a str"),
        ("step a bool", _edited(state, _set(["step"], True)), "'step' is a bool"),
        ("step a float", _edited(state, _set(["step"], 10.0)), "'step' is a float"),
        ("names a dict", _edited(state, _set(["names"], {"a": 1})), "'names' is a dict"),
        ("other names", _edited(state, _set(["names"], ["plain", "other"])), "other materials"),
        ("other settings", _edited(state, _set(["settings", "lr"], 1e-3)), "other settings (lr: 0.001"),
        ("settings hold a tensor", _edited(state, _set(["settings", "lr"], torch.ones(2))), "not plain values"),
        ("NaN weights", _edited(state, _nan_weight), "'mlp.hidden.0.weight' holds NaN"),
        # the first layer's moment at its own shape (8 x (direction inputs + latent): 6 or 9 + 4)
        ("Inf moment", _edited(state, _set(["optimizer", "state", 0, "exp_avg"],
                                           torch.full_like(state["optimizer"]["state"][0]["exp_avg"], float("inf")))),
         "exp_avg 0 holds NaN or Inf"),
        ("negative second moment", _edited(state, _set(["optimizer", "state", 1, "exp_avg_sq"], -torch.ones(8))),
         "negative"),
        ("NaN learning rate", _edited(state, _set(["optimizer", "param_groups", 0, "lr"], float("nan"))),
         "learning rate nan"),
        ("moment of another shape", _edited(state, _set(["optimizer", "state", 0, "exp_avg"], torch.zeros(3))),
         "exp_avg 0 is torch.float32 (3)"),
        ("unknown parameter", _edited(state, _set(["optimizer", "state", 99], {})), "parameter 99"),
        ("another architecture", _edited(state, _other_arch), "another architecture"),
        ("a wider layer", _edited(state, _wider_layer), "'mlp.hidden.0.weight' is torch.float32 (16, 10)"),
        ("rng of another size", _edited(state, _set(["torch_rng"], torch.zeros(7, dtype=torch.uint8))), "torch_rng"),
        ("batch rng a float tensor", _edited(state, _set(["batch_rng"], torch.zeros(5056))), "batch_rng"),
        ("negative time", _edited(state, _set(["train_seconds"], -1.0)), "not a time"),
        ("timed beyond the step", _edited(state, _set(["timed_from_step"], 11)), "timed_from_step 11"),
        ("isotropy flipped", _edited(state, _set(["module", "isotropic"], torch.tensor([False, True]))), "isotropy"),
    ]
    return cases


def test_every_damaged_checkpoint_fails_fast_with_one_line(good_checkpoint, tmp_path):
    data, state = good_checkpoint
    cases = damaged_checkpoints(data, state)
    assert len(cases) > 45
    for label, blob, words in cases:
        path = tmp_path / "ck.pt"
        path.write_bytes(blob)
        t0 = time.perf_counter()
        with pytest.raises(hb.InputFileError) as info:
            fit(sources(Tripwire), tiny(), checkpoint=str(path), resume=True, progress=False, log=lambda m: None)
        elapsed = time.perf_counter() - t0
        msg = one_line_naming(info.value, path)
        assert words in msg, (label, msg)
        assert elapsed < FAST, (label, elapsed)
        assert path.read_bytes() == blob, label  # a refused checkpoint is left as it was


def _with_checksum(payload: bytes) -> bytes:
    import hashlib

    return ckpt.MAGIC + b"%d sha256=%s\n" % (ckpt.VERSION, hashlib.sha256(payload).hexdigest().encode()) + payload


def _deflated(zip_bytes: bytes, only: str = "") -> bytes:
    """The same zip archive with every entry whose name holds ``only`` deflated (torch.save
    stores them as is)."""
    import io
    import zipfile

    src = zipfile.ZipFile(io.BytesIO(zip_bytes))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            method = zipfile.ZIP_DEFLATED if only in info.filename else zipfile.ZIP_STORED
            dst.writestr(info.filename, src.read(info.filename), compress_type=method)
    return out.getvalue()


def _declared_size(zip_bytes: bytes, name: bytes, size: int) -> bytes:
    """The zip archive with entry ``name``'s central-directory sizes (both) set to ``size``."""
    import struct

    b = bytearray(zip_bytes)
    at = b.find(b"PK\x01\x02")
    while at >= 0:
        n = struct.unpack_from("<H", b, at + 28)[0]
        if bytes(b[at + 46:at + 46 + n]).endswith(name):
            struct.pack_into("<II", b, at + 20, size, size)
            return bytes(b)
        at = b.find(b"PK\x01\x02", at + 4)
    raise AssertionError(f"no entry {name!r}")


def test_a_decompression_bomb_checkpoint_is_refused_before_it_expands(good_checkpoint, tmp_path):
    """1 MB of deflated zeros with a valid checksum once grew `hbrdf fit --resume` to 1.28 GB
    before "checkpoint has no 'module'". Here 64 MB of zeros in 65 KB: refused from the zip's
    directory, before torch.load, with the process barely growing; also the checkpoint's own
    entries deflated, and a stored entry that declares more bytes than the file holds."""
    import resource

    _, state = good_checkpoint
    bomb = _deflated(_bare_zip({"x": torch.zeros(16 << 20)}), only="/data/")
    assert len(bomb) < 200_000
    cases = [("bomb, checksummed", _with_checksum(bomb), "checkpoint entry 'archive/data/0' is compressed ("),
             ("bomb, bare zip", bomb, "checkpoint entry 'archive/data/0' is compressed ("),
             ("the checkpoint deflated", _with_checksum(_deflated(_bare_zip(state))), "is compressed ("),
             ("an entry declaring 2 GB", _with_checksum(_declared_size(_bare_zip(state), b"/data/0", 2 << 30)),
              "checkpoint entries declare ")]
    for label, blob, words in cases:
        path = tmp_path / "ck.pt"
        path.write_bytes(blob)
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        with pytest.raises(hb.InputFileError) as info:
            fit(sources(Tripwire), tiny(), checkpoint=str(path), resume=True, progress=False, log=lambda m: None)
        msg = one_line_naming(info.value, path)
        assert words in msg, (label, msg)
        assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - peak < 32 * 1024, label  # KiB: under 32 MB
        assert path.read_bytes() == blob, label


def test_the_resume_command_refuses_a_bomb_with_exit_1(tmp_path):
    path = tmp_path / "ck.pt"
    blob = _with_checksum(_deflated(_bare_zip({"x": torch.zeros(16 << 20)}), only="/data/"))
    path.write_bytes(blob)
    r = subprocess.run([sys.executable, "-m", "hybridbrdf.cli", "fit", "synthetic:plastic", "--steps", "20",
                        "--checkpoint", str(path), "--resume", "--out", str(tmp_path / "m.safetensors")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and str(path) in lines[0] and "is compressed (" in lines[0], r.stderr[-2000:]
    assert "Traceback" not in r.stderr and path.read_bytes() == blob
    assert not (tmp_path / "m.safetensors").exists()


def test_a_checkpoint_at_the_last_step_finishes_the_fit(good_checkpoint, tmp_path):
    _, state = good_checkpoint

    def done(s):  # step = steps: nothing left to train, and the cosine schedule is at 0
        s["step"] = 20
        for g in s["optimizer"]["param_groups"]:
            g["lr"] = 0.0

    path = tmp_path / "ck.pt"
    path.write_bytes(_edited(state, done))
    model = fit(sources(), tiny(), checkpoint=str(path), resume=True, progress=False, log=lambda m: None)
    assert model.training["resumed_at_step"] == 20
    with pytest.raises(hb.InputFileError, match=r"learning rate 0\.0025, the schedule gives .* at step 15"):
        path.write_bytes(_edited(state, _set(["step"], 15)))  # a step its learning rate does not belong to
        fit(sources(Tripwire), tiny(), checkpoint=str(path), resume=True, progress=False, log=lambda m: None)


def test_the_cli_prints_one_line_for_a_damaged_checkpoint(good_checkpoint, tmp_path, capsys):
    data, state = good_checkpoint
    path = tmp_path / "ck.pt"
    # The source does not exist: the checkpoint is refused before any source is opened.
    argv = ["fit", str(tmp_path / "missing.binary"), "--out", str(tmp_path / "m.safetensors"), "--checkpoint",
            str(path), "--resume", "--quiet", "--mlp", "8x1", "--steps", "20", "--batch", "64", "--pool", "256",
            "--seed", "5"]
    for blob, words in ((data[: len(data) // 2], "SHA-256"), (_flip(data, len(data) // 2), "SHA-256"),
                        (b"", "is empty"), (_edited(state, _set(["step"], 10 ** 12)), "outside [0, 20]")):
        path.write_bytes(blob)
        t0 = time.perf_counter()
        assert cli_main(argv) == 1
        err = capsys.readouterr().err
        assert time.perf_counter() - t0 < FAST
        assert err.count("\n") == 1 and err.startswith(f"hbrdf fit: error: {path}: ") and words in err, err
        assert "Traceback" not in err
    assert not (tmp_path / "m.safetensors").exists()


def test_a_resumed_fit_matches_with_new_and_legacy_checkpoints(tmp_path):
    """The batch generator's state in the checkpoint replaces the replay of every earlier batch;
    a checkpoint from before it (and before the checksum) still resumes, by the replay."""
    full = fit(sources(), tiny(), progress=False)
    ck = tmp_path / "ck.pt"
    assert fit(sources(), tiny(), checkpoint=str(ck), checkpoint_every=10, progress=False, stop_after=10) is None
    state, _ = ckpt.read(ck)
    legacy = tmp_path / "legacy.pt"
    bare = dict(state)
    del bare["batch_rng"]
    legacy.write_bytes(_bare_zip(bare))
    said = []
    for path in (ck, legacy):
        resumed = fit(sources(), tiny(), checkpoint=str(path), resume=True, progress=False, log=said.append)
        for k in full.tensors:
            assert np.array_equal(full.tensors[k], resumed.tensors[k]), (path, k)
    assert any("no checksum" in m for m in said)


# ---- outputs -------------------------------------------------------------------------


def _fit_argv(tmp_path, out, *extra):
    # The source does not exist: an output problem must be reported before it is looked at.
    return ["fit", str(tmp_path / "missing.binary"), "--out", str(out), "--quiet", *extra]


@pytest.mark.parametrize("case", ["folder", "parent is a file", "under a file", "same as checkpoint",
                                  "checkpoint is a folder", "resume without checkpoint"])
def test_unwritable_outputs_fail_before_anything_else(tmp_path, capsys, case):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    out, extra, named = tmp_path / "m.safetensors", [], None
    if case == "folder":
        out = named = tmp_path
    elif case == "parent is a file":
        out = named = a_file / "m.safetensors"
    elif case == "under a file":
        out = named = a_file / "sub" / "m.safetensors"
    elif case == "same as checkpoint":
        extra, named = ["--checkpoint", str(out)], out
    elif case == "checkpoint is a folder":
        extra, named = ["--checkpoint", str(tmp_path)], tmp_path
    else:
        extra = ["--resume"]
    t0 = time.perf_counter()
    assert cli_main(_fit_argv(tmp_path, out, *extra)) == 1
    err = capsys.readouterr().err
    assert time.perf_counter() - t0 < FAST
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert (f"error: {named}: " in err) if named else "--resume needs --checkpoint" in err, err


def test_out_may_not_overwrite_a_source(tmp_path, capsys):
    from hybridbrdf.sources.merl import write_merl

    src = tmp_path / "m.binary"
    write_merl(src, np.full((90, 90, 180, 3), 0.1))
    before = src.read_bytes()
    assert cli_main(["fit", str(src), "--out", str(src), "--quiet", "--steps", "1"]) == 1
    err = capsys.readouterr().err
    assert f"error: {src}: --out names one of the sources" in err and err.count("\n") == 1
    assert src.read_bytes() == before


def test_a_read_only_folder_fails_before_training(tmp_path, capsys):
    """A folder this process may not create files in: a 0555 folder, or for root (who writes
    anywhere else) sysfs, which refuses new files to everyone."""
    if os.geteuid() == 0:
        folder = "/sys"
        if not os.path.isdir(folder) or os.path.exists("/sys/m.safetensors"):
            pytest.skip("no sysfs to stand in for a read-only folder")
    else:
        folder = str(tmp_path / "ro")
        os.mkdir(folder, 0o555)
    out = os.path.join(folder, "m.safetensors")
    t0 = time.perf_counter()
    try:
        assert cli_main(_fit_argv(tmp_path, out)) == 1
    finally:
        if folder != "/sys":
            os.chmod(folder, 0o755)
    err = capsys.readouterr().err
    assert time.perf_counter() - t0 < FAST
    assert err.count("\n") == 1 and f"error: {out}: cannot write the model into {folder}: " in err, err
    assert not os.path.exists(out)


# ---- numeric flags -------------------------------------------------------------------

INT_FLAGS = ["--steps", "--batch", "--pool", "--eval-pairs", "--latent", "--seed", "--checkpoint-every"]
FLOAT_FLAGS = ["--lr", "--weight-decay", "--loss-eps", "--analytic-loss-eps", "--analytic-expectile", "--specular",
               "--specular-alpha", "--fc-init", "--lr-final"]


OUT_OF_RANGE = {"--lr": ["0", "-1"], "--weight-decay": ["-1e-9"], "--loss-eps": ["0"], "--analytic-loss-eps": ["0"],
                "--analytic-expectile": ["1", "0.4"], "--specular": ["1.5", "-0.1"], "--specular-alpha": ["0", "2"],
                "--fc-init": ["100", "-1e30"], "--lr-final": ["0", "1.5", "-0.01"]}


@pytest.mark.parametrize("flag", INT_FLAGS + FLOAT_FLAGS)
def test_every_numeric_flag_rejects_nonsense_in_one_line(flag, capsys):
    bad = ["inf", "-inf", "nan", "NaN", "1e400", "-1e400", "x", ""] + (
        ["-1", "1.5", "1e30", "1e12", "99999999999999999999999", "9" * 400] if flag in INT_FLAGS else OUT_OF_RANGE[flag])
    for value in bad:
        with pytest.raises(SystemExit) as info:
            build_parser().parse_args(["fit", "synthetic:gold", "--out", "m", f"{flag}={value}"])
        assert info.value.code == 2
        last = capsys.readouterr().err.strip().splitlines()[-1]
        assert last.startswith(f"hbrdf fit: error: argument {flag}: expected "), last
        assert value in last, last


def test_eval_pairs_are_checked_before_the_model_is_read(tmp_path, capsys):
    for value, words in (("inf", "argument --pairs: expected an integer"), ("5e8", "--pairs must be an integer in")):
        try:
            code = cli_main(["eval", str(tmp_path / "missing.safetensors"), "synthetic:gold", f"--pairs={value}"])
        except SystemExit as exc:  # argparse's own error
            code = exc.code
        assert code in (1, 2)
        last = capsys.readouterr().err.strip().splitlines()[-1]
        assert words in last and "missing.safetensors" not in last, last


def test_numeric_flags_take_their_whole_range():
    args = build_parser().parse_args(["fit", "synthetic:gold", "--out", "m", "--steps", "2e4", "--seed", "0",
                                      "--latent", "0", "--specular", "1", "--fc-init", "-4", "--weight-decay", "0",
                                      "--analytic-expectile", "0.5", "--pool", "1073741824"])
    assert (args.steps, args.seed, args.latent, args.specular, args.pool) == (20000, 0, 0, 1.0, 1 << 30)


@pytest.mark.parametrize("field,value", [("steps", 10 ** 12), ("steps", 2.5), ("lr", float("nan")),
                                         ("lr", float("inf")), ("loss_eps", float("nan")), ("seed", -1),
                                         ("fc_init", float("nan")), ("batch", True), ("width", 100_000),
                                         ("depth", 0), ("clip", float("nan")), ("arch", "resnet")])
def test_settings_set_from_python_are_checked_too(field, value):
    with pytest.raises(ValueError, match=f"^{field} must be"):
        tiny(**{field: value}).check()


# ---- atomic writes -------------------------------------------------------------------


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_the_next_write_removes_temporaries_of_dead_writers(tmp_path):
    dest = tmp_path / "model.safetensors"
    dead = tmp_path / f".model.safetensors.tmp-{_dead_pid()}-abc123"
    alive = tmp_path / f".model.safetensors.tmp-{os.getppid()}-def456"  # a live writer's: kept
    other = tmp_path / f".other.safetensors.tmp-{_dead_pid()}-abc123"  # another destination's: kept
    for p in (dead, alive, other):
        p.write_bytes(b"half a file")
    atomic_write_bytes(dest, b"the whole file")
    assert dest.read_bytes() == b"the whole file"
    assert not dead.exists() and alive.exists() and other.exists()
    assert remove_stale_temporaries(tmp_path / "other.safetensors") == [str(other)]


def test_every_writer_goes_through_the_atomic_write():
    """The model file, checkpoints, generated code and written measurements: one writer, so one
    place that cleans up (the grep keeps a new writer from bypassing it)."""
    import pathlib

    pkg = pathlib.Path(hb.__file__).resolve().parent
    writers = {p.relative_to(pkg).as_posix() for p in pkg.rglob("*.py") if "atomic_write_bytes(" in p.read_text()}
    assert {"files/atomic.py", "model/file.py", "fit/checkpoint.py", "codegen/main.py", "sources/merl.py",
            "sources/utia.py", "viewer/page.py"} <= writers


WRITER = """
import faulthandler, signal, sys
from hybridbrdf.files import atomic_write_bytes
faulthandler.register(signal.SIGUSR1)  # the test asks for our stack if we do not end
data = bytes(range(256)) * (1 << 14)  # 4 MiB: most of the loop's time is spent inside a write
print("ready", flush=True)
while True:
    atomic_write_bytes(sys.argv[1], data)
"""

# How long a signalled writer may take to end (its writes fsync, and a busy VM disk can hold one
# for seconds); a writer that is really stuck shows its stack in the failure.
WRITER_EXIT_S = 120


def _default_sigint():
    """The writer's SIGINT as a foreground process has it: a test run started in the background
    (`cmd &` in a script) inherits SIGINT ignored, Python then installs no KeyboardInterrupt
    handler in the writer, and SIGINT would never stop it (two runs of 2026-11-28 lost 30 and
    240 s that way, a stall first taken for the disk's)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _wait_or_show_stack(p):
    try:
        p.wait(timeout=WRITER_EXIT_S)
    except subprocess.TimeoutExpired:
        p.send_signal(signal.SIGUSR1)  # faulthandler: the Python stack to stderr
        time.sleep(1.0)
        p.kill()
        _, err = p.communicate()
        pytest.fail(f"the writer did not end within {WRITER_EXIT_S} s of the signal; "
                    f"its stack:\n{err.decode(errors='replace')}")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_writer_stopped_by_a_signal_leaves_no_temporary(tmp_path, sig):
    dest = tmp_path / "out.bin"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    for delay in (0.05, 0.21, 0.43):
        p = subprocess.Popen([sys.executable, "-c", WRITER, str(dest)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, env=env, preexec_fn=_default_sigint)
        assert p.stdout.readline().strip() == b"ready"
        time.sleep(delay)
        p.send_signal(sig)
        _wait_or_show_stack(p)
        # The process still ends as the signal ends it (Python re-raises an uncaught Ctrl-C too).
        assert p.returncode == -sig, p.stderr.read()
        assert sorted(os.listdir(tmp_path)) == (["out.bin"] if dest.exists() else [])
        if dest.exists():
            assert dest.read_bytes() == bytes(range(256)) * (1 << 14)


# ---- gradients -----------------------------------------------------------------------


def _hard_batch(dtype):
    """The shared hard directions crossed with themselves, plus grazing rows (0 < z <= 1e-4),
    extreme lengths, denormals and wi = +-wo."""
    np_dtype = np.float32 if dtype == torch.float32 else np.float64
    wi, wo = hard_pairs(np_dtype)
    rng = np.random.default_rng(3)
    n = 300
    g = rng.normal(size=(n, 3))
    g[:, :2] /= np.linalg.norm(g[:, :2], axis=1, keepdims=True)
    g[:, 2] = rng.uniform(0.0, 1e-4, n)
    u = rng.normal(size=(n, 3))
    u[:, 2] = np.abs(u[:, 2])
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    scale = rng.choice([1e-30, 1e-18, 1e18, 1e30], size=(n, 1))
    tiny = np.finfo(np_dtype).smallest_subnormal
    extra_wi = np.concatenate([g, u * scale, u, u, g, [[tiny, tiny, 1.0]]])
    extra_wo = np.concatenate([u, g * scale[::-1], u, -u, g, [[0.0, 0.0, tiny]]])
    return np.concatenate([wi, extra_wi]), np.concatenate([wo, extra_wo])


def _params(dtype, corner):
    kd, eta, alpha = {"plain": ([0.3, 0.5, 0.7], [1.5, 1.33, 2.0], [0.3, 0.2]),
                      "edges": ([0.0, 1.0, 0.5], [1.0, 10.0, 1.0], [hb.ALPHA_MIN, 1.0]),
                      "mirror": ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [hb.ALPHA_MIN, hb.ALPHA_MIN]),
                      "eta near 1": ([0.2, 0.2, 0.2], [1.0000001, 1.000001, 1.001], [hb.ALPHA_MIN, 0.3])}[corner]
    return [torch.tensor(v, dtype=dtype, requires_grad=True) for v in (kd, eta, alpha)]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("corner", ["plain", "edges", "mirror", "eta near 1"])
def test_gradients_are_finite_on_every_hard_row(dtype, corner):
    wi_np, wo_np = _hard_batch(dtype)
    for fn in ("eval", "cosine", "ggx", "mis"):
        wi = torch.tensor(wi_np, dtype=dtype, requires_grad=True)
        wo = torch.tensor(wo_np, dtype=dtype, requires_grad=True)
        kd, eta, alpha = _params(dtype, corner)
        out = eval_analytic(wi, wo, kd, eta, alpha) if fn == "eval" else pdf(wi, wo, kd, eta, alpha, fn)
        assert torch.isfinite(out).all(), fn
        out.sum().backward()
        for name, t in (("wi", wi), ("wo", wo), ("kd", kd), ("eta", eta), ("alpha", alpha)):
            if t.grad is not None:  # the cosine density depends on wi only
                bad = ~torch.isfinite(t.grad)
                assert not bad.any(), (fn, name, wi_np[bad.any(-1)][:3] if t.grad.ndim > 1 else t.grad)


def test_one_below_horizon_row_leaves_the_shared_alpha_gradient_finite():
    wi = torch.tensor([[0.3, 0.1, 0.9], [0.0, 0.0, 1.0]], dtype=torch.float64)
    wo = torch.tensor([[-0.2, 0.1, 0.95], [0.0, 0.0, -1.0]], dtype=torch.float64)  # row 2 straight down
    alpha = torch.tensor([0.3, 0.3], dtype=torch.float64, requires_grad=True)
    pdf(wi, wo, [0.5] * 3, [1.5] * 3, alpha, "ggx").sum().backward()
    assert torch.isfinite(alpha.grad).all() and (alpha.grad != 0).all()


@pytest.mark.parametrize("fn", ["eval", "ggx", "mis"])
def test_gradients_on_valid_rows_match_finite_differences(fn):
    """float64 gradcheck, directions of non-unit length included (normalisation's own backward)."""
    rng = np.random.default_rng(11)
    n = 6

    def upper(k):
        w = rng.normal(size=(k, 3))
        w[:, 2] = np.abs(w[:, 2]) + 0.2
        return w * rng.choice([1e-3, 1.0, 1e3], size=(k, 1))

    wi = torch.tensor(upper(n), requires_grad=True)
    wo = torch.tensor(upper(n), requires_grad=True)
    kd = torch.tensor([0.3, 0.5, 0.7], dtype=torch.float64, requires_grad=True)
    eta = torch.tensor([1.2, 1.5, 3.0], dtype=torch.float64, requires_grad=True)
    alpha = torch.tensor([0.2, 0.45], dtype=torch.float64, requires_grad=True)

    def f(wi, wo, kd, eta, alpha):
        return eval_analytic(wi, wo, kd, eta, alpha) if fn == "eval" else pdf(wi, wo, kd, eta, alpha, fn)

    assert torch.autograd.gradcheck(f, (wi, wo, kd, eta, alpha), eps=1e-7, atol=1e-6, rtol=1e-4)


@pytest.mark.parametrize("arch", list(spec.ARCHS))
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_models_forward_and_backward_stay_finite_on_hard_rows(arch, dtype):
    wi_np, wo_np = _hard_batch(dtype)
    torch.manual_seed(0)
    model = build_model(arch, 3, 16, 2, 4 if spec.ARCHS[arch]["analytic"] else 12, "hardgelu", [True, False, True]).to(dtype)
    if spec.ARCHS[arch]["analytic"]:
        with torch.no_grad():  # the range's edges: alpha at ALPHA_MIN, eta at 1, kd at 0
            model.alpha_raw[0] = -40.0
            model.eta_raw[1] = -40.0
            model.kd_raw[2] = -40.0
    wi = torch.tensor(wi_np, dtype=dtype, requires_grad=True)
    wo = torch.tensor(wo_np, dtype=dtype, requires_grad=True)
    f_t, f_a = model(wi, wo)
    assert torch.isfinite(f_t).all() and (f_a is None or torch.isfinite(f_a).all())
    loss = torch.log1p(f_t).sum() + (torch.log1p(f_a).sum() if f_a is not None else 0.0)
    loss.backward()
    for name, p in list(model.named_parameters()) + [("wi", wi), ("wo", wo)]:
        assert p.grad is not None and torch.isfinite(p.grad).all(), name


def test_hard_directions_table_is_in_the_batch():
    # The shared table (tests/data/hard_directions.json) drives the batch above.
    assert len(hard_directions()) >= 20
