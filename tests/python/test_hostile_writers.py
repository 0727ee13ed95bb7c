"""Issue 45, the Python writers: concurrent updates in place lose nothing, a fresh fit never
replaces another fit's checkpoint, a full disk is reported naming the file, temporaries live
beside their target and are removed (SIGTERM) or found by the next write (SIGKILL), and a
replaced file keeps its permissions (docs/CONVENTIONS.md, "Writing files")."""

from __future__ import annotations

import errno
import os
import signal
import stat
import subprocess
import sys
import time

import pytest

import hybridbrdf as hb
from hybridbrdf.cli import main as cli_main
from hybridbrdf.codegen.main import main as codegen_main
from hybridbrdf.fit import checkpoint as ckpt
from hybridbrdf.fit import fit
from hybridbrdf.model.random import random_model

from test_fit_hostile import FAST, Tripwire, sources, tiny

ENOSPC_TEXT = os.strerror(errno.ENOSPC)  # "No space left on device"


@pytest.fixture
def base(tmp_path):
    """A model file of three materials (mat-0 .. mat-2) alone in its folder."""
    path = tmp_path / "m.safetensors"
    random_model("hybrid", n=3, width=8, depth=1)[1].save(path)
    return path


def error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


# ---- 1. concurrent updates in place ------------------------------------------------------

# Runs `hbrdf ARGS` as "first" or "second" of two updates of one file. The first, once it has
# read the model, waits until the second has started its command, then a second more, before
# it writes: without a lock the second reads the model the first has not yet replaced, and the
# first's update is lost whatever the scheduler does.
UPDATER = """
import os, sys, time
import hybridbrdf.cli as cli
import hybridbrdf.model.file as file
role, marks, argv = sys.argv[1], sys.argv[2], sys.argv[3:]
mark = lambda name: os.path.join(marks, name)
def wait_for(name):
    deadline = time.time() + 120
    while not os.path.exists(mark(name)) and time.time() < deadline:
        time.sleep(0.02)
def slow(load):
    def load_model(path):
        model = load(path)
        if role == "first":
            open(mark("first-read"), "w").close()
            wait_for("second-started")
            time.sleep(1.0)
        return model
    return load_model
file.load_model = slow(file.load_model)  # hbrdf edit and mix import it when they run (their --help needs no NumPy)
if argv[0] == "add":  # the adding module imports PyTorch, which edit and mix do without (3 s a process)
    import hybridbrdf.fit.adding as adding
    adding.load_model = slow(adding.load_model)
if role == "second":
    wait_for("first-read")
    open(mark("second-started"), "w").close()
sys.exit(cli.main(argv))
"""

ADD_FLAGS = ["--steps", "20", "--pool", "512", "--batch", "64", "--eval-pairs", "200", "--quiet"]


def updates(base, name):
    """The command line that adds material ``name`` to ``base`` in place, per command."""
    return {"edit": ["edit", str(base), "mat-0", "--set", "kd=0.25", "--as", name, "--out", str(base)],
            "mix": ["mix", str(base), "mat-0", "mat-1", "--t", "0.5", "--as", name, "--out", str(base)],
            "add": ["add", f"synthetic:{name}", "--to", str(base), "--out", str(base), *ADD_FLAGS]}


@pytest.mark.parametrize("command,names", [("edit", ("edA", "edB")), ("mix", ("mixA", "mixB")),
                                           ("add", ("gold", "plastic"))])
def test_two_updates_in_place_at_once_both_land(base, tmp_path, command, names):
    marks = tmp_path / "marks"
    marks.mkdir()
    procs = [subprocess.Popen([sys.executable, "-c", UPDATER, role, str(marks), *updates(base, name)[command]],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for role, name in zip(("first", "second"), names)]
    results = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [r[1] for r in results]
    kept = hb.load_model(base).materials
    assert kept[:3] == ["mat-0", "mat-1", "mat-2"] and sorted(kept[3:]) == sorted(names), kept
    assert sorted(os.listdir(base.parent)) == ["m.safetensors", "marks"]  # no lock file, no temporary


def test_an_update_refuses_in_one_line_when_another_holds_the_file_too_long(base, tmp_path, monkeypatch, capsys):
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom hybridbrdf.files import file_lock\n"
                               "with file_lock(sys.argv[1]):\n    print('held', flush=True)\n    time.sleep(60)",
                               str(base)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        monkeypatch.setattr("hybridbrdf.files.locks.LOCK_WAIT_SECONDS", 0.3)
        before = base.read_bytes()
        assert cli_main(updates(base, "late")["edit"]) == 1
        line = error_line(capsys)
        assert line.startswith(f"hbrdf edit: error: {base}: is being written by pid {holder.pid} "), line
        assert base.read_bytes() == before
    finally:
        holder.kill()
        holder.wait()


# ---- 2. checkpoints of other fits ---------------------------------------------------------


def test_a_fresh_fit_refuses_an_existing_checkpoint_unless_resumed_or_forced(tmp_path, capsys):
    ck = tmp_path / "ck.pt"
    assert fit(sources(), tiny(), checkpoint=str(ck), checkpoint_every=10, stop_after=10, progress=False) is None
    theirs = ck.read_bytes()
    t0 = time.monotonic()
    with pytest.raises(ValueError) as err:  # another fit's materials: it would replace ck at step 10
        fit(sources(Tripwire)[:1], tiny(), checkpoint=str(ck), checkpoint_every=10, progress=False)
    assert time.monotonic() - t0 < FAST
    assert str(err.value) == f"{ck}: exists (another fit's checkpoint?): --resume continues it, --force replaces it"
    assert ck.read_bytes() == theirs
    # The command line says the same, before opening any source; --force starts afresh.
    cmd = ["fit", "synthetic:gold", "--out", str(tmp_path / "m.safetensors"), "--checkpoint", str(ck),
           "--no-preview", "--quiet", "--steps", "20", "--checkpoint-every", "10", "--pool", "256", "--batch", "64",
           "--eval-pairs", "200", "--mlp", "8x1"]
    assert cli_main(cmd) == 1
    assert error_line(capsys) == f"hbrdf fit: error: {ck}: exists (another fit's checkpoint?): --resume continues " \
                                 "it, --force replaces it"
    assert ck.read_bytes() == theirs
    capsys.readouterr()
    assert cli_main(cmd + ["--force"]) == 0
    assert ckpt.read(ck)[0]["names"] == ["gold"]  # replaced by the forced fit's


def test_a_second_fit_on_one_checkpoint_is_refused_at_once(tmp_path):
    ck = tmp_path / "ck.pt"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom hybridbrdf.files import file_lock\n"
                               "with file_lock(sys.argv[1]):\n    print('held', flush=True)\n    time.sleep(60)",
                               str(ck)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"  # as a running fit holds it
        t0 = time.monotonic()
        with pytest.raises(OSError) as err:
            fit(sources(Tripwire), tiny(), checkpoint=str(ck), resume=True, progress=False)
        assert time.monotonic() - t0 < FAST
        assert str(err.value).startswith(f"{ck}: is being written by pid {holder.pid} "), str(err.value)
        assert not ck.exists()
    finally:
        holder.kill()
        holder.wait()


# ---- 4. full disks ---------------------------------------------------------------------------


@pytest.fixture
def disk_full_on_fsync(monkeypatch, tmp_path):
    """Every fsync of a file under tmp_path fails as a full disk does where delayed allocation
    meets it (ext4, XFS, NFS); elsewhere ($TMPDIR scratch files) fsync works."""
    real = os.fsync

    def fsync(fd):
        try:
            name = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            name = str(tmp_path)  # no /proc: every fsync fails
        if name.startswith(str(tmp_path)) and stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(errno.ENOSPC, ENOSPC_TEXT)
        return real(fd)
    monkeypatch.setattr(os, "fsync", fsync)


def test_a_full_disk_is_reported_naming_the_model_and_the_old_one_is_kept(base, disk_full_on_fsync, capsys):
    before = base.read_bytes()
    for argv in (updates(base, "e")["edit"], updates(base, "x")["mix"]):
        assert cli_main(argv) == 1
        assert error_line(capsys) == f"hbrdf {argv[0]}: error: {base}: {ENOSPC_TEXT}"
        assert base.read_bytes() == before
        assert os.listdir(base.parent) == ["m.safetensors"]


def test_a_full_disk_is_reported_naming_the_generated_file_and_the_checkpoint(base, tmp_path, disk_full_on_fsync,
                                                                                capsys):
    out = tmp_path / "code" / "m.glsl"
    assert codegen_main([str(base), "--target", "glsl", "-o", str(out)]) == 1
    assert error_line(capsys) == f"hbrdf-codegen: error: {out}: {ENOSPC_TEXT}"
    assert os.listdir(out.parent) == []
    ck = tmp_path / "ck.pt"
    with pytest.raises(OSError) as err:
        fit(sources(), tiny(), checkpoint=str(ck), checkpoint_every=10, stop_after=10, progress=False)
    assert str(err.value) == f"{ck}: {ENOSPC_TEXT}" and err.value.errno == errno.ENOSPC
    assert not ck.exists()


def test_a_really_full_tmpfs_is_reported_naming_the_file(base, tmp_path, capsys):
    full = tmp_path / "full"
    full.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=128k", "tmpfs", str(full)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here (needs root): {r.stderr.decode().strip()}")
    try:
        fd = os.open(full / "filler", os.O_WRONLY | os.O_CREAT)
        try:  # fill it to the last page
            while True:
                os.write(fd, b"\0" * 4096)
        except OSError as exc:
            assert exc.errno == errno.ENOSPC
        os.close(fd)
        target = full / "m.safetensors"
        assert cli_main(["edit", str(base), "mat-0", "--set", "kd=0.5", "--as", "e", "--out", str(target)]) == 1
        assert error_line(capsys) == f"hbrdf edit: error: {target}: {ENOSPC_TEXT}"
        assert os.listdir(full) == ["filler"]  # no partial file, no temporary, no lock file
        code = full / "m.glsl"
        assert codegen_main([str(base), "--target", "glsl", "-o", str(code)]) == 1
        assert error_line(capsys) == f"hbrdf-codegen: error: {code}: {ENOSPC_TEXT}"
        assert os.listdir(full) == ["filler"]
    finally:
        subprocess.run(["umount", str(full)], check=True)


# ---- 5. temporaries ---------------------------------------------------------------------------

# `hbrdf edit ... --out BASE` that stops in the verify step of its write (reading the written
# model back) until it is killed; "verifying" is created when it gets there.
STOPS_IN_VERIFY = """
import os, sys, time
import hybridbrdf.model.file as file
target, marker, argv = os.path.abspath(sys.argv[1]), sys.argv[2], sys.argv[3:]
load = file.load_model
def load_model(path):
    if os.path.abspath(path) != target and "unbounded" not in path:  # the written model (not the energy
        # bound's scratch copy), read back before it replaces target
        open(marker, "w").close()
        time.sleep(120)
    return load(path)
file.load_model = load_model
from hybridbrdf.cli import main
sys.exit(main(argv))
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_a_write_killed_while_verifying_leaves_nothing_behind(base, tmp_path, sig, capsys):
    scratch = tmp_path / "tmpdir"
    scratch.mkdir()
    marker = tmp_path / "verifying"
    before = base.read_bytes()
    proc = subprocess.Popen([sys.executable, "-c", STOPS_IN_VERIFY, str(base), str(marker),
                             *updates(base, "killed")["edit"]], env={**os.environ, "TMPDIR": str(scratch)},
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not marker.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.02)
    assert marker.exists(), proc.communicate()[1]
    proc.send_signal(sig)
    proc.wait(timeout=60)
    assert proc.returncode == -sig
    assert base.read_bytes() == before
    assert os.listdir(scratch) == []  # nothing written outside the target's folder
    left = sorted(os.listdir(base.parent))
    if sig == signal.SIGTERM:
        assert left == ["m.safetensors", "tmpdir", "verifying"], left
    else:  # the dead writer's temporary, beside its target, with its pid in its name
        assert any(n.startswith(f".m.safetensors.tmp-{proc.pid}-") for n in left), left
        assert cli_main(updates(base, "next")["edit"]) == 0  # the next write finds and removes it
        assert sorted(os.listdir(base.parent)) == ["m.safetensors", "tmpdir", "verifying"]


# ---- 6. permissions ----------------------------------------------------------------------------


def test_a_replaced_file_keeps_its_permissions_and_a_new_one_gets_the_umask(base, tmp_path, capsys):
    os.chmod(base, 0o600)
    for argv in (updates(base, "e")["edit"], updates(base, "x")["mix"]):
        assert cli_main(argv) == 0
        assert stat.S_IMODE(os.stat(base).st_mode) == 0o600
    code = tmp_path / "m.glsl"
    old = os.umask(0o022)
    try:
        assert codegen_main([str(base), "--target", "glsl", "-o", str(code)]) == 0
        assert stat.S_IMODE(os.stat(code).st_mode) == 0o644  # a new file: 0666 less the umask
        os.chmod(code, 0o640)
        assert codegen_main([str(base), "--target", "glsl", "-o", str(code)]) == 0
        assert stat.S_IMODE(os.stat(code).st_mode) == 0o640
    finally:
        os.umask(old)


# `hbrdf edit ... --out BASE` that stops while its energy bound is fitted (the unbounded model is
# then a scratch file libhybridbrdf reads) until it is killed; "bounding" is created when it is there.
STOPS_IN_ENERGY_BOUND = """
import sys, time
import hybridbrdf.model.energy as energy
marker, argv = sys.argv[1], sys.argv[2:]
def contributions(*args, **kwargs):
    open(marker, "w").close()
    time.sleep(120)
energy._contributions = contributions
from hybridbrdf.cli import main
sys.exit(main(argv))
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_scratch_files_in_tmpdir_are_removed_on_sigterm_and_after_sigkill(base, tmp_path, sig, monkeypatch, capsys):
    scratch = tmp_path / "tmpdir"
    scratch.mkdir()
    marker = tmp_path / "bounding"
    proc = subprocess.Popen([sys.executable, "-c", STOPS_IN_ENERGY_BOUND, str(marker),
                             *updates(base, "killed")["edit"]], env={**os.environ, "TMPDIR": str(scratch)},
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not marker.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.02)
    assert marker.exists(), proc.communicate()[1]
    assert os.listdir(scratch)  # the unbounded model, written for libhybridbrdf
    proc.send_signal(sig)
    proc.wait(timeout=60)
    assert proc.returncode == -sig
    if sig == signal.SIGKILL:  # nothing could clean up: the next command does
        monkeypatch.setattr("tempfile.tempdir", str(scratch))
        assert cli_main(updates(base, "next")["edit"]) == 0
    assert os.listdir(scratch) == []


def test_the_demo_plot_keeps_the_mode_of_the_file_it_replaces(tmp_path, capsys):
    out = tmp_path / "slices.png"
    old = os.umask(0o022)
    try:
        assert cli_main(["demo", "--out", str(out), "--samples", "2000"]) == 0
        assert stat.S_IMODE(os.stat(out).st_mode) == 0o644  # a new file: 0666 less the umask
        os.chmod(out, 0o640)
        assert cli_main(["demo", "--out", str(out), "--samples", "2000"]) == 0
        assert stat.S_IMODE(os.stat(out).st_mode) == 0o640
    finally:
        os.umask(old)
    assert os.listdir(tmp_path) == ["slices.png"]
