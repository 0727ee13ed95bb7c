"""docs/CODEGEN.md, "In an engine": the commands and the two shaders it prints run as printed (the
generated file included by an engine's own fragment shader, compiled by glslang to SPIR-V and
checked by spirv-val where it is installed)."""

import contextlib
import io
import os
import pathlib
import re
import shlex
import shutil
import subprocess

import pytest

from hybridbrdf.codegen.main import main as codegen

ROOT = pathlib.Path(__file__).resolve().parents[2]


def section():
    text = (ROOT / "docs" / "CODEGEN.md").read_text()
    return text.split("## In an engine", 1)[1].split("\n## ", 1)[0]


def test_the_engine_shaders_compile_as_printed(tmp_path, monkeypatch):
    if shutil.which("glslangValidator") is None:
        why = "glslangValidator is not installed (scripts/setup.sh installs it)"
        if os.environ.get("HBRDF_REQUIRE_VULKAN") == "1":  # scripts/test.sh: no skip inside the README's command
            pytest.fail(why, pytrace=False)
        pytest.skip(why)
    text = section()
    shaders = re.findall(r"```(?:glsl|hlsl)\n// (\S+)\n(.*?)```", text, re.S)
    commands = re.findall(r"^    ((?:hbrdf-codegen|glslangValidator) .*)$", text, re.M)
    assert [name for name, _ in shaders] == ["engine.frag", "engine.hlsl"]
    assert len(commands) == 4, commands
    for name, body in shaders:
        (tmp_path / name).write_text(body)
    (tmp_path / "results").symlink_to(ROOT / "results")
    monkeypatch.chdir(tmp_path)
    for command in commands:
        argv = shlex.split(command)
        if argv[0] == "hbrdf-codegen":
            with contextlib.redirect_stdout(io.StringIO()):
                assert codegen(argv[1:]) in (0, None), command
        else:
            r = subprocess.run(argv, capture_output=True, text=True)
            assert r.returncode == 0, (command, r.stdout, r.stderr)
            spv = argv[argv.index("-o") + 1]
            if shutil.which("spirv-val"):
                v = subprocess.run(["spirv-val", spv], capture_output=True, text=True)
                assert v.returncode == 0, (spv, v.stderr)
    # A bare generated file is a library: without the engine's lines glslang refuses it.
    bare = subprocess.run(["glslangValidator", "-V", "-S", "frag", "materials.glsl"], capture_output=True, text=True)
    assert bare.returncode != 0
