"""Code generation under hostile input: names, paths and scene keys never reach the
generated code raw, and codegen either writes code that compiles or stops with one line."""

import json
import os
import pathlib
import re
import shutil
import subprocess
import urllib.parse

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.codegen.literals import comment_text, float_literal, material_constant
from hybridbrdf.codegen.main import generate, main as codegen_main
from hybridbrdf.names import name_problem, names_problem, shader_constant_key
from hybridbrdf.model.random import random_model

from helpers import compile_spirv, run_cli
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


# ---- reserved identifiers, outputs over inputs, deep metadata ---------------------


@pytest.mark.parametrize("name,constant", [
    ("_a", "HBRDF_MATERIAL_A"), ("a..b", "HBRDF_MATERIAL_A_B"), ("a_-_b", "HBRDF_MATERIAL_A_B"),
    ("gold-", "HBRDF_MATERIAL_GOLD"), ("+1.x", "HBRDF_MATERIAL_1_X"), ("cc_ibiza-sunset.rgl", "HBRDF_MATERIAL_CC_IBIZA_SUNSET_RGL"),
])
def test_shader_constants_hold_no_reserved_double_underscore(name, constant):
    # "__" anywhere in an identifier is reserved in GLSL (an error in GLSL ES) and in C++.
    assert name_problem(name) is None
    got = material_constant(name)
    assert got == constant and "__" not in got and not got[len("HBRDF_MATERIAL_"):].startswith("_")


@pytest.mark.parametrize("name", ["-", "_", "...", "+-_."])
def test_a_name_without_letter_or_digit_is_refused_by_the_name_rule(name):
    problem = "name has no letter or digit, so it gives no shader constant HBRDF_MATERIAL_<NAME>"
    assert name_problem(name) == problem
    assert names_problem(["gold", name]) == f"material 1: {problem}"


def test_names_that_collapse_to_one_constant_clash():
    assert names_problem(["a_b", "a..b"]) == "materials 'a_b' and 'a..b' would share the shader constant HBRDF_MATERIAL_A_B"
    assert names_problem(["a", "_a"]) == "materials 'a' and '_a' would share the shader constant HBRDF_MATERIAL_A"
    assert names_problem(["gold", "GOLD"]) == ("materials 'gold' and 'GOLD' would share the shader constant "
                                               "HBRDF_MATERIAL_GOLD")


@pytest.mark.parametrize("names", [["a", "b..c", "_d"], ["-x-", "y+"]])
def test_both_loaders_accept_collapsed_names_and_cpp_agrees_on_clashes(tmp_path, names):
    _, model = random_model("hybrid", n=len(names), latent=2, width=8, depth=1)
    for info, name in zip(model.material_info, names):
        info["name"] = name
    path = tmp_path / "m.safetensors"
    model.save(path)
    assert hb.load_model(path).materials == names
    assert list(_core.Model(str(path)).materials) == names
    bad = tmp_path / "bad.safetensors"
    clash = "+" + names[0] + "."  # maps to the first name's constant
    model.material_info[-1]["name"] = clash
    model.save(bad)
    key = names[0].strip("-+_.").upper()
    words = (f"{bad}: materials '{names[0]}' and '{clash}' would share the shader constant "
             f"HBRDF_MATERIAL_{key}")
    for load in (hb.load_model, lambda p: _core.Model(str(p))):
        with pytest.raises(hb.ModelFileError) as info:
            load(bad)
        assert str(info.value) == words


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslang-tools not installed")
def test_punctuated_names_compile_as_glsl_es(tmp_path):
    # glslang refuses identifiers with "__" in ES profiles: the collapsed constants pass.
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    for info, name in zip(model.material_info, ["_a", "b..c", "d-"]):
        info["name"] = name
    text = generate(model, "glsl")
    consts = sorted(set(re.findall(r"HBRDF_MATERIAL_\w+", text)))
    assert consts == ["HBRDF_MATERIAL_A", "HBRDF_MATERIAL_B_C", "HBRDF_MATERIAL_D"], consts
    src = tmp_path / "t.frag"
    decls = "\n".join(f"const int {c} = {i};" for i, c in enumerate(consts))
    # GLSL ES 1.00 makes "__" an error (later versions: a warning), so it is the strict judge.
    src.write_text(f"#version 100\nprecision highp float;\n{decls}\n"
                   f"void main() {{ gl_FragColor = vec4(float({consts[0]})); }}\n")
    r = subprocess.run(["glslangValidator", str(src)], capture_output=True, text=True)
    assert r.returncode == 0 and "reserved" not in r.stdout, r.stdout + r.stderr
    src.write_text(src.read_text().replace(consts[0], "HBRDF_MATERIAL__A"))  # the old constant of "_a"
    r = subprocess.run(["glslangValidator", str(src)], capture_output=True, text=True)
    assert r.returncode != 0 and "reserved" in r.stdout  # the check can fail: glslang does refuse it


def _keep(path) -> bytes:
    return pathlib.Path(path).read_bytes()


@pytest.mark.parametrize("how", ["same path", "symlink to the model", "hard link to the model", "scene", "scene via .."])
def test_codegen_refuses_to_write_over_its_inputs(tmp_path, capsys, how):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    path = tmp_path / "m.safetensors"
    model.save(path)
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps({"camera": {"width": 8, "height": 8},
                                 "materials": {"a": {"type": "model", "file": "m.safetensors", "material": "mat-0"}},
                                 "objects": []}))
    before = {p: _keep(p) for p in (path, scene)}
    args = [str(path), "--target", "glsl"]
    if how == "same path":
        out = path
    elif how == "symlink to the model":
        out = tmp_path / "link.glsl"
        out.symlink_to(path)
    elif how == "hard link to the model":
        out = tmp_path / "hard.glsl"
        os.link(path, out)
    else:
        args += ["--scene", str(scene)]
        (tmp_path / "sub").mkdir()
        out = scene if how == "scene" else tmp_path / "sub" / ".." / "s.json"
    assert codegen_main(args + ["-o", str(out)]) == 1
    err = capsys.readouterr().err
    named = str(scene) if how.startswith("scene") else str(path)
    assert err == (f"hbrdf-codegen: error: {out}: -o/--out names the input {named}; writing it would destroy "
                   f"that input\n"), err
    assert {p: _keep(p) for p in (path, scene)} == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []  # no temporary left


def _model_with_deep_metadata(tmp_path, levels: int) -> pathlib.Path:
    """A valid model file whose metadata holds a free-form record nested ``levels`` deep."""
    import safetensors.numpy

    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    good = tmp_path / "good.safetensors"
    model.save(good)
    with safetensors.safe_open(str(good), framework="numpy") as f:
        meta = dict(f.metadata())
        tensors = {k: f.get_tensor(k) for k in f.keys()}
    meta["hybridbrdf"] = '{"deep": ' + "[" * levels + "]" * levels + ", " + meta["hybridbrdf"][1:]
    path = tmp_path / "deep.safetensors"
    path.write_bytes(safetensors.numpy.save(tensors, meta))
    return path


def test_deeply_nested_metadata_is_one_line_everywhere(tmp_path, capsys):
    path = _model_with_deep_metadata(tmp_path, 5000)  # ~10 KB; json.loads raised RecursionError
    words = f"{path}: 'hybridbrdf' metadata: JSON nested deeper than 64 levels"
    with pytest.raises(hb.ModelFileError) as info:
        hb.load_model(path)
    assert str(info.value) == words
    with pytest.raises(hb.ModelFileError) as info:  # libhybridbrdf refuses it in the same words
        _core.Model(str(path))
    assert str(info.value) == words
    out = tmp_path / "o.glsl"
    assert codegen_main([str(path), "--target", "glsl", "-o", str(out)]) == 1
    assert capsys.readouterr().err == f"hbrdf-codegen: error: {words}\n"
    assert not out.exists()
    r = run_cli("info", str(path))
    assert r.returncode == 1 and r.stderr == f"hbrdf info: error: {words}\n", r.stderr


def test_metadata_at_the_depth_bound_loads_in_both_loaders(tmp_path):
    path = _model_with_deep_metadata(tmp_path, 63)  # 64 with the object around it
    assert hb.load_model(path).materials == ["mat-0", "mat-1", "mat-2"]
    assert list(_core.Model(str(path)).materials) == ["mat-0", "mat-1", "mat-2"]
