"""Code generation under hostile input (issue 20): names, paths and scene keys never reach the
generated code raw, and codegen either writes code that compiles or stops with one line."""

import json
import shutil
import subprocess
import urllib.parse

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.codegen import comment_text, float_literal, generate, main as codegen_main, material_constant
from hybridbrdf.names import name_problem, names_problem, shader_constant_key
from hybridbrdf.random_model import random_model

from helpers import compile_spirv
from test_codegen import every_function_shader

# A file name that, pasted raw into a '//' comment, ends it (newline), injects a directive
# and splices the following line into a comment (backslash); scene keys add the trigraph ??/.
HOSTILE_FILE = 'm\n#error injected\nstatic int x = 1;\\\r%??.safetensors'  # no '/': one file


def _comment_lines_are_inert(text: str) -> None:
    for line in text.splitlines():
        assert not line.endswith("\\") and "??/" not in line, line
        if line.startswith("//"):
            assert all(" " <= ch <= "~" for ch in line), line


@pytest.fixture()
def hostile_model_file(tmp_path):
    _, model = random_model("hybrid", latent=4, width=8, depth=1)
    path = tmp_path / HOSTILE_FILE
    model.save(path)
    return path


@pytest.mark.parametrize("target", ["cpp", "glsl", "hlsl", "brdfexplorer"])
def test_a_hostile_file_name_stays_inside_its_comment(tmp_path, hostile_model_file, target, capsys):
    out = tmp_path / f"out.{target}"
    assert codegen_main([str(hostile_model_file), "--target", target, "--materials", "mat-1", "-o", str(out)]) == 0
    text = out.read_text()
    _comment_lines_are_inert(text)
    assert "#error" not in text.replace("%0A#error", "")  # only ever percent-encoded
    if target == "cpp":
        (tmp_path / "use.cpp").write_text('#include "out.cpp"\nint main() { return 0; }\n')
        for extra in ([], ["-trigraphs"]):  # as a compiler that honours trigraphs (??/ = backslash) would
            r = subprocess.run(["g++", "-std=c++17", *extra, "-Wall", "-Werror", "-fsyntax-only",
                                "-I", str(tmp_path), str(tmp_path / "use.cpp")], capture_output=True, text=True)
            assert r.returncode == 0, r.stderr[:2000]
    elif target in ("glsl", "hlsl") and shutil.which("glslangValidator"):
        src = every_function_shader(tmp_path, target, text, "mat-1")
        compile_spirv(src, tmp_path / f"{target}.spv", target, include_dir=tmp_path)


@pytest.mark.skipif(not hasattr(_core, "read_scene_decl"), reason="built without the renderer")
def test_hostile_scene_keys_and_file_name_stay_inside_comments(tmp_path, hostile_model_file):
    scene = {"camera": {"width": 8, "height": 8},
             "materials": {"good": {"type": "model", "file": hostile_model_file.name, "material": "mat-0"},
                           "x\n#error scene key??/": {"type": "analytic", "kd": [0.5, 0.5, 0.5], "eta": 1.5, "alpha": 0.3}},
             "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "good"},
                         {"type": "sphere", "center": [3, 0, 0], "radius": 1, "material": "x\n#error scene key??/"}]}
    scene_path = tmp_path / "scene\n#error name.json"
    scene_path.write_text(json.dumps(scene))
    out = tmp_path / "out.h"
    rc = codegen_main([str(hostile_model_file), "--target", "cpp", "--scene", str(scene_path), "-o", str(out)])
    assert rc == 0
    text = out.read_text()
    _comment_lines_are_inert(text)
    assert "%0A#error scene key%3F%3F/" in text
    (tmp_path / "use.cpp").write_text('#include "out.h"\nint main() { return 0; }\n')
    r = subprocess.run(["g++", "-std=c++17", "-fsyntax-only", "-I", str(tmp_path), str(tmp_path / "use.cpp")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[:2000]


def test_comment_text_keeps_only_inert_printable_ascii():
    rng = np.random.default_rng(7)
    for _ in range(2000):
        s = "".join(chr(c) for c in rng.integers(0, 0x3000, size=int(rng.integers(0, 12))))
        t = comment_text(s)
        assert all(" " <= ch <= "~" and ch not in "\\?" for ch in t)
        assert urllib.parse.unquote(t, errors="strict") == s  # reversible: nothing is lost
    assert comment_text("gold-1.rgl") == "gold-1.rgl"  # ordinary names read as they are
    assert comment_text("a\nb\\c??/%") == "a%0Ab%5Cc%3F%3F/%25"


@pytest.mark.parametrize("name,problem", [
    ("gold", None), ("a" * 64, None), ("cc_ibiza-sunset.rgl+2", None),
    ("a" * 65, "name is 65 characters long"), ("gold\n", "name character 5 is U+000A"),
    ("gold leaf", "name character 5 is ' '"), ("x\\", "name character 2 is '\\'"), ("é", "name character 1 is U+00E9"),
])
def test_the_name_rule(name, problem):
    got = name_problem(name)
    assert (got is None) if problem is None else got.startswith(problem), got


def test_names_must_stay_distinct_as_shader_constants():
    assert shader_constant_key("gold-1.a") == "GOLD_1_A"
    assert names_problem(["gold-1", "gold_1"]) == ("materials 'gold-1' and 'gold_1' would share the shader "
                                                   "constant HBRDF_MATERIAL_GOLD_1")
    assert names_problem(["Gold", "gold"]).startswith("materials 'Gold' and 'gold'")
    assert names_problem(["a", "b"]) is None
    assert material_constant("cc_ibiza-sunset.rgl") == "HBRDF_MATERIAL_CC_IBIZA_SUNSET_RGL"


def test_a_name_the_loaders_refuse_is_refused_by_codegen_too():
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    model.material_info[0]["name"] = "gold\n#error x"  # a model built in memory, never loaded
    with pytest.raises(ValueError, match="name character 5 is U\\+000A"):
        generate(model, "cpp", ["gold\n#error x"])


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslang-tools not installed")
def test_the_longest_valid_name_compiles_in_every_shader_language(tmp_path):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    path = tmp_path / "m.safetensors"
    model.material_info[1]["name"] = "N" * 64
    model.save(path)
    model = hb.load_model(path)
    for target in ("glsl", "hlsl"):
        src = every_function_shader(tmp_path, target, generate(model, target), "N" * 64)
        compile_spirv(src, tmp_path / f"{target}.spv", target, include_dir=tmp_path)


def test_float_literals_refuse_values_no_language_can_write():
    for bad in (float("inf"), float("nan"), 1e39, -3.5e38):
        with pytest.raises(ValueError, match="not finite in float32"):
            float_literal(bad)
    lit = float_literal(3.4e38)  # the largest finite values still print, and read back exactly
    assert np.float32(float(lit[:-1])) == np.float32(3.4e38)


def test_fp16_refuses_weights_beyond_the_half_range(tmp_path):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    model.tensors["mlp.out.weight"][0, 0] = 7e4
    with pytest.raises(ValueError, match="half-precision range"):
        generate(model, "glsl", precision="fp16")
    generate(model, "glsl", precision="fp32")  # fp32 holds it


@pytest.mark.parametrize("args,problem", [
    (["--materials", "mat-0,nope"], "no material 'nope' in the model (it has: mat-0, mat-1, mat-2)"),
    (["--materials", "mat-0,mat-0"], "material 'mat-0' is listed twice"),
    (["--target", "brdfexplorer", "--materials", "mat-1,nope"], "no material 'nope'"),
    (["--target", "brdfexplorer", "--materials", "mat-1,mat-1"], "material 'mat-1' is listed twice"),
    (["--target", "brdfexplorer", "--scene", "SCENE"], "a BRDF Explorer file shows one material"),
])
def test_bad_material_selections_give_one_line(tmp_path, capsys, args, problem):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    path = tmp_path / "m.safetensors"
    model.save(path)
    scene = tmp_path / "s.json"
    scene.write_text("{}")
    args = [a.replace("SCENE", str(scene)) for a in args]
    target = [] if "--target" in args else ["--target", "glsl"]
    out = tmp_path / "out.txt"
    assert codegen_main([str(path), *target, *args, "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert problem in err and "\n" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("make_out", [
    lambda d: d,                                   # a directory
    lambda d: d / "file.txt" / "out.glsl",         # parent is a file
])
def test_bad_output_paths_fail_before_generating(tmp_path, capsys, make_out):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    path = tmp_path / "m.safetensors"
    model.save(path)
    (tmp_path / "file.txt").write_text("keep")
    out = make_out(tmp_path)
    assert codegen_main([str(path), "--target", "glsl", "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert str(out) in err and "\n" not in err, err
    assert (tmp_path / "file.txt").read_text() == "keep"


@pytest.mark.skipif(not hasattr(_core, "read_scene_decl"), reason="built without the renderer")
def test_scene_errors_with_hostile_keys_stay_one_line(tmp_path, hostile_model_file, capsys):
    scene = {"camera": {"width": 8, "height": 8},
             "materials": {"x\n#error\x1b[2J": {"type": "velvet"}}, "objects": []}
    scene_path = tmp_path / "s.json"
    scene_path.write_text(json.dumps(scene))
    assert codegen_main([str(hostile_model_file), "--target", "cpp", "--scene", str(scene_path),
                         "-o", str(tmp_path / "o.h")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "\x1b" not in err, err
