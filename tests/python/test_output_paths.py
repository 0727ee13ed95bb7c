"""One rule for output paths (docs/CONVENTIONS.md, "Writing files"; issue 57): every command creates
the missing folders on the way to its output, and refuses in one line naming the output, before
any work, when a folder cannot be made (here: a file stands where a folder must go).

The commands run in this process (`hybridbrdf.cli.main`, `hybridbrdf.codegen.main.main`): the rule
is the commands' code, not the interpreter's start."""

import contextlib
import io
import os

import pytest

import hybridbrdf as hb
from hybridbrdf.cli import main as hbrdf
from hybridbrdf.codegen.main import main as codegen
from hybridbrdf.errors import InputFileError
from hybridbrdf.files import make_parent_folder


def run(command, argv):
    """(exit status, stderr) of a command run in this process."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            status = command(argv)
        except SystemExit as exc:  # argparse, and a command that exits
            status = exc.code
    return status, err.getvalue()


def test_make_parent_folder_creates_the_way_and_names_the_output_when_it_cannot(tmp_path):
    out = tmp_path / "a" / "b" / "m.safetensors"
    assert make_parent_folder(out) == str(tmp_path / "a" / "b")
    assert (tmp_path / "a" / "b").is_dir() and not out.exists()
    (tmp_path / "file").write_text("in the way")
    with pytest.raises(InputFileError) as err:
        make_parent_folder(tmp_path / "file" / "sub" / "m.safetensors")
    assert str(tmp_path / "file" / "sub" / "m.safetensors") in str(err.value)
    assert "is a file, not a folder" in str(err.value)
    assert not (tmp_path / "file" / "sub").exists()


# (command, argv before --out, what --out names): commands whose run takes a second or two here.
def commands(prior):
    return [
        ("hbrdf-codegen", codegen, [prior, "--target", "glsl"], "generated.glsl"),
        ("hbrdf view", hbrdf, ["view", prior], "page.html"),
        ("hbrdf demo", hbrdf, ["demo", "--samples", "2000"], "slices.png"),
        ("hbrdf acquire simulate", hbrdf,
         ["acquire", "simulate", "--flash", "2", "--size", "8x8", "--base", "synthetic:gold", "--quiet"], "capture"),
    ]


@pytest.mark.parametrize("index", range(4), ids=["codegen", "view", "demo", "acquire-simulate"])
def test_every_command_creates_missing_folders_and_refuses_a_file_in_the_way(tmp_path, index):
    name, command, argv, leaf = commands(str(hb.prior_path()))[index]
    out = tmp_path / "new" / "deeper" / leaf
    status, err = run(command, [*argv, "--out", str(out)])
    assert status in (0, None), (name, err)
    assert os.path.lexists(out), name
    (tmp_path / "blocked").write_text("a file where the folder must go")
    bad = tmp_path / "blocked" / "sub" / leaf
    status, err = run(command, [*argv, "--out", str(bad)])
    lines = err.strip().splitlines()
    assert status not in (0, None), name
    assert len(lines) == 1 and str(bad) in lines[0], (name, err)
    assert not os.path.lexists(tmp_path / "blocked" / "sub")


def test_acquire_fit_creates_missing_folders_like_every_command(tmp_path, monkeypatch):
    """It used to fail instead, naming its hidden checkpoint beside the missing folder."""
    from hybridbrdf.acquire import cluster_fit, hybrid_fit

    monkeypatch.setattr(cluster_fit, "CLUSTER_STEPS", 5)
    # The kd edits' energy tables are hbrdf paint's tests; where the output goes does not touch them.
    monkeypatch.setattr(hybrid_fit, "bound_bright_kd", lambda model, names, kd_maps, log: (model, names))
    capture = tmp_path / "capture"
    status, err = run(hbrdf, ["acquire", "simulate", "--flash", "6", "--size", "24x24", "--base", "synthetic:gold",
                              "--quiet", "--out", str(capture)])
    assert status in (0, None), err
    out = tmp_path / "new" / "deeper" / "acquired"
    status, err = run(hbrdf, ["acquire", "fit", str(capture), "--out", str(out), "--size", "2x2", "--steps", "5",
                              "--quiet"])
    assert status in (0, None), err
    assert (out / "svbrdf.json").is_file()
    (tmp_path / "blocked").write_text("a file where the folder must go")
    bad = tmp_path / "blocked" / "sub" / "acquired"
    status, err = run(hbrdf, ["acquire", "fit", str(capture), "--out", str(bad), "--size", "2x2", "--steps", "5",
                              "--quiet"])
    lines = err.strip().splitlines()
    assert status not in (0, None) and len(lines) == 1 and str(bad) in lines[0], err
