"""The hbrdf command line and packaging facts (versions agree everywhere).

Commands run by :func:`helpers.run_cli_here`, in the test's process, unless the test is about
the fresh interpreter: the README's main job (a warning Python prints once per process, and
pytest records instead of printing, would pass unseen in-process) and the bad-arguments exit.
A fresh interpreter costs 2-4 s of CPU importing torch per fitting command."""

import pathlib
import re

import numpy as np
import pytest

import hybridbrdf as hb

from hybridbrdf.fit.settings import FitSettings

from helpers import ROOT, run_cli, run_cli_here


def test_demo_writes_a_png(tmp_path):
    out = tmp_path / "sub" / "slices.png"
    r = run_cli_here("demo", "--out", str(out), "--samples", "2000")
    assert r.returncode == 0, r.stderr
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert "wrote" in r.stdout
    # The demo's own check of C++ float32 against PyTorch float64.
    m = re.search(r"PyTorch float64 on the slices: ([0-9.e+-]+)", r.stdout)
    assert m and float(m.group(1)) < 2e-4
    assert not list(out.parent.glob("*.png.tmp*")) and len(list(out.parent.iterdir())) == 1


def test_bad_arguments_give_one_line_and_nonzero_exit(tmp_path):
    r = run_cli("demo", "--out", str(tmp_path / "x.png"), "--samples", "0")
    assert r.returncode != 0
    assert r.stderr.strip().count("\n") == 0 and "samples" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "x.png").exists()


def test_versions_agree():
    pyproject = (ROOT / "pyproject.toml").read_text()
    cmake = (ROOT / "CMakeLists.txt").read_text()
    header = (ROOT / "cpp/include/hybridbrdf/version.hpp").read_text()
    v_py = re.search(r'^version = "([^"]+)"', pyproject, re.M).group(1)
    v_cmake = re.search(r"project\(hybridbrdf VERSION ([0-9.]+)", cmake).group(1)
    v_hdr = re.search(r'kVersion = "([^"]+)"', header).group(1)
    assert v_py == v_cmake == v_hdr == hb.__version__ == hb._core.__version__


def test_alpha_min_is_one_constant():
    header = (ROOT / "cpp/include/hybridbrdf/spec.hpp").read_text()  # generated from spec/model.json
    assert float(re.search(r"kAlphaMin = ([0-9.e-]+);", header).group(1)) == hb.ALPHA_MIN == 1e-4
    p = hb.AnalyticParams(alpha=hb.ALPHA_MIN)
    f = hb.analytic_eval(np.array([[0.0, 0, 1]]), np.array([[0.0, 0, 1]]), p)
    assert np.isfinite(f).all() and f[0, 0] > 1e5  # a near-mirror lobe, still finite


@pytest.mark.slow
def test_fit_eval_info_on_synthetic_materials(tmp_path):
    out = tmp_path / "m.safetensors"
    # 30 steps, no preview: what this test reads (the materials, settings and metrics each command
    # prints and records) does not depend on the fit's progress; the default preview is
    # test_the_readme_main_job's and test_fit_preview_flags'.
    r = run_cli_here("fit", "synthetic:plastic", "synthetic:gold", "--mlp", "16x2", "--steps", "30", "--pool", "4096",
                "--eval-pairs", "5000", "--out", str(out), "--quiet", "--no-preview")
    assert r.returncode == 0, r.stderr
    assert "plastic" in r.stdout and "gold" in r.stdout and "SMAPE analytic" in r.stdout
    model = hb.load_model(out)
    assert model.materials == ["plastic", "gold"] and model.arch["width"] == 16 and model.arch["depth"] == 2
    assert model.training["steps"] == 30 and model.training["sources"] == ["synthetic:plastic", "synthetic:gold"]
    r = run_cli_here("eval", str(out), "synthetic:gold", "--pairs", "5000", "--all-metrics")
    assert r.returncode == 0, r.stderr
    ext = [line for line in r.stdout.splitlines() if line.startswith("gold")][1].split()
    # gold is reciprocal and so is its analytic fit; the reference albedo of gold at 45 degrees is < 1
    assert float(ext[3]) < 1e-6 and float(ext[4]) < 1e-4 and 0 < float(ext[6]) < 1
    # the model's largest directional albedo and where: hbrdf info's figure for the same material
    info = hb.load_model(out).albedo("gold")
    assert float(ext[9]) == pytest.approx(info["max"], abs=1e-4) and 0 < float(ext[9]) < 1.5
    assert " ".join(ext[10:]) == f"({info['argmax_deg'][0]:g}, {info['argmax_deg'][1]:g})"
    row = [line for line in r.stdout.splitlines() if line.startswith("gold")][0]
    smape_a, smape_m = (float(x) for x in row.split()[-4:-2])
    assert 0 <= smape_m <= 2 and 0 <= smape_a <= 2
    r = run_cli_here("info", str(out))
    # the default architecture since issue 60: reciprocal
    assert r.returncode == 0 and "hybrid-reciprocal, MLP 16x2 hardgelu, latent 4" in r.stdout and "gold" in r.stdout
    assert "lr 0.005, lr_schedule cosine, lr_final 0.01, clip 0.01, weight_decay 0.0, seed 0," in r.stdout, r.stdout
    assert "recipe hybridbrdf" in r.stdout, r.stdout
    assert "sparse_init" not in r.stdout  # a joint fit: no sparse settings
    for init in ("nearest", "neutral"):  # sparse fitting: the network stays, the start is recorded
        sparse = tmp_path / f"sparse_{init}.safetensors"
        r = run_cli_here("fit", "--frozen", str(out), "synthetic:gold", "--steps", "20", "--pool", "4096",
                    "--eval-pairs", "5000", "--sparse-init", init, "--out", str(sparse), "--quiet", "--no-preview")
        assert r.returncode == 0, r.stderr
        added = hb.load_model(sparse)
        assert added.training["sparse_init"] == init and added.training["frozen_from"] == str(out)
        assert all(np.array_equal(v, added.tensors[k]) for k, v in model.tensors.items()
                   if not k.startswith("materials."))
        r = run_cli_here("info", str(sparse))
        assert f"sparse_init {init}" in r.stdout and f"frozen_from {out}" in r.stdout, r.stdout
        assert "loss: loss_eps 0.1," in r.stdout, r.stdout
        assert ("sparse fit started from gold (smape " in r.stdout) == (init == "nearest"), r.stdout


def test_cli_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"\x00" * 5)
    for args, needle in (
        (("info", str(bad)), "truncated"),
        (("fit", str(tmp_path / "none.bsdf"), "--out", str(tmp_path / "o.st")), "no such file"),
        (("fit", "synthetic:unobtainium", "--out", str(tmp_path / "o.st")), "unknown synthetic material"),
        (("fit", str(bad), "--out", str(tmp_path / "o.st")), "unknown BRDF format"),
        (("fit", "synthetic:gold", "--mlp", "32by3", "--out", str(tmp_path / "o.st")), "WIDTHxDEPTH"),
    ):
        r = run_cli_here(*args)
        assert r.returncode == 1, (args, r.stderr)
        assert needle in r.stderr and r.stderr.strip().count("\n") == 0 and "Traceback" not in r.stderr, r.stderr
    assert not (tmp_path / "o.st").exists()


def test_readme_fit_synopsis_is_generated_from_fit_settings():
    from hybridbrdf.cli import fit_synopsis

    readme = (pathlib.Path(__file__).resolve().parents[2] / "README.md").read_text()
    block = readme.split("<!-- fit-synopsis")[1].split("<!-- end fit-synopsis -->")[0]
    shown = "\n".join(line[4:] for line in block.splitlines() if line.startswith("    "))
    assert shown == fit_synopsis()


def test_every_fit_setting_flag_reaches_fit_settings_and_hbrdf_info():
    """Each FitSettings field with a flag: set to a non-default value on the command line, it
    arrives in FitSettings; and hbrdf info prints every recorded setting of its section."""
    import dataclasses

    from hybridbrdf.cli import _settings_line, build_parser, settings_from_args
    from hybridbrdf.fit.settings import FitSettings

    fields = [f for f in dataclasses.fields(FitSettings) if f.metadata.get("flag")]
    assert {f.name for f in fields} >= {"arch", "width", "steps", "loss_eps", "specular", "sparse_init", "frozen_from"}
    argv = ["fit", "synthetic:gold", "--out", "x.safetensors"]
    wanted = {}
    for f in fields:
        cli = f.metadata["cli"]
        if cli.get("action") == "store_true":
            argv.append(f.metadata["flag"]); wanted[f.name] = True
        elif cli.get("action") == "store_false":
            argv.append(f.metadata["flag"]); wanted[f.name] = False
        elif "choices" in cli:
            value = [c for c in cli["choices"] if c != f.default][0]
            argv += [f.metadata["flag"], value]; wanted[f.name] = value
        elif f.name == "width":
            argv += ["--mlp", "8x5"]; wanted.update(width=8, depth=5)
        elif f.name in ("device", "frozen_from", "init_from"):  # strings: any value
            argv += [f.metadata["flag"], "elsewhere"]; wanted[f.name] = "elsewhere"
        else:  # 7, or inside the flag's range (fit_settings.Number) where 7 is outside it
            value = 0.7 if cli["type"].problem(7) else 7
            argv += [f.metadata["flag"], str(value)]; wanted[f.name] = value
    settings = settings_from_args(build_parser().parse_args(argv))
    for name, value in wanted.items():
        assert getattr(settings, name) == value, name
    recorded = dataclasses.asdict(settings)
    line = _settings_line("loss", recorded, ("loss",))
    for f in dataclasses.fields(FitSettings):
        if f.metadata["section"] == "loss":
            assert f"{f.name} {recorded[f.name]}" in line, f.name
    # Unset flags keep FitSettings' defaults (the parser holds no copy of them).
    plain = settings_from_args(build_parser().parse_args(["fit", "synthetic:gold", "--out", "x"]))
    assert dataclasses.replace(plain, device="cpu", sources=[]) == FitSettings()


def test_recipe_paper_sets_the_papers_values_and_flags_still_win():
    """--recipe paper: the paper's Sec. 3.3 settings (eps 1, symmetric loss, cosine pairs only,
    decay 0.01, 200k steps, 32x3); a flag given explicitly overrides its recipe value. The
    paper's values are spelled out here from the paper's text, not read from RECIPES."""
    from hybridbrdf.cli import build_parser, settings_from_args

    def parsed(*flags, command="fit"):
        argv = [command, "synthetic:gold", "--out", "x", *flags]
        return settings_from_args(build_parser().parse_args(argv), sparse=command == "add")

    paper = parsed("--recipe", "paper")
    assert (paper.recipe, paper.loss_eps, paper.analytic_expectile, paper.specular, paper.weight_decay,
            paper.steps, paper.batch, paper.lr, paper.clip, paper.width, paper.depth, paper.latent) == \
        ("paper", 1.0, 0.5, 0.0, 0.01, 200_000, 1024, 0.005, 0.01, 32, 3, 4)
    mixed = parsed("--recipe", "paper", "--loss-eps", "0.3", "--steps", "77")
    assert (mixed.loss_eps, mixed.steps, mixed.specular) == (0.3, 77, 0.0)
    ours = parsed()
    assert (ours.recipe, ours.loss_eps, ours.analytic_expectile, ours.specular, ours.weight_decay, ours.steps) == \
        ("hybridbrdf", 0.1, 0.5, 0.1, 0.0, 120_000)
    # fast: the schedule bench/bench_fit_time.py measured (docs/LOSS.md, "Fitting in 30 minutes").
    fast = parsed("--recipe", "fast")
    assert (fast.recipe, fast.width, fast.depth, fast.latent, fast.steps, fast.lr, fast.lr_schedule, fast.lr_final,
            fast.loss_eps, fast.analytic_expectile, fast.specular, fast.weight_decay, fast.output_layer) == \
        ("fast", 16, 2, 4, 58_000, 0.04, "exponential", 0.01, 0.01, 0.9, 0.1, 0.0, "material")
    assert parsed("--recipe", "fast", "--mlp", "32x2").width == 32
    assert parsed("--recipe", "fast", "--output-layer", "shared").output_layer == "shared"
    # hbrdf add: a sparse fit's steps, whatever the recipe, unless given.
    from hybridbrdf.fit.settings import ADD_STEPS

    assert parsed(command="add").steps == ADD_STEPS == parsed("--recipe", "paper", command="add").steps
    assert parsed("--steps", "9", command="add").steps == 9
    r = run_cli("fit", "synthetic:gold", "--out", "x", "--recipe", "fancy")
    assert r.returncode == 2 and "invalid choice: 'fancy'" in r.stderr


def test_a_checkpoint_from_before_a_setting_existed_resumes_with_the_papers_value(tmp_path):
    """A setting added after a checkpoint was written had its paper value then (each setting was
    introduced with the paper's behaviour as default): such a checkpoint resumes under --recipe
    paper and is refused, naming the setting, under the default recipe."""
    from hybridbrdf.fit import checkpoint as ckpt
    from hybridbrdf.fit import fit
    from hybridbrdf.sources import open_source

    path = tmp_path / "ck.pt"
    settings = FitSettings.from_recipe("paper", width=8, depth=1, latent=2, steps=4, batch=64, pool=512,
                                       eval_pairs=500)
    assert fit([open_source("synthetic:gold")], settings, checkpoint=str(path), checkpoint_every=2, stop_after=2,
               progress=False, log=lambda m: None) is None
    state, _ = ckpt.load(str(path), settings)
    for key in ("specular", "sparse_starts", "recipe"):  # as an older hybridbrdf wrote it
        del state["settings"][key]
    ckpt.save(str(path), state)
    ckpt.load(str(path), settings)  # resumes
    ours = FitSettings(width=8, depth=1, latent=2, steps=4, batch=64, pool=512, eval_pairs=500, loss_eps=1.0,
                       weight_decay=0.01)
    with pytest.raises(ckpt.CheckpointError, match=r"specular: 0.0 -> 0.1") as err:
        ckpt.load(str(path), ours)
    assert "sparse_starts" not in str(err.value)  # absent: 1 then, 1 now


def _readme_main_job():
    """The README's main job: the `hbrdf fit ...` of its first command block, as words."""
    readme = (ROOT / "README.md").read_text()
    line = next(ln.strip() for ln in readme.splitlines() if ln.strip().startswith("bash scripts/setup.sh && hbrdf fit"))
    return line.split("&&", 1)[1].split()


@pytest.mark.slow
def test_the_readme_main_job_prints_no_warning_and_ends_with_a_picture(tmp_path):
    """A newcomer's first run, shortened: the README's command with 40 steps. Its
    output holds no warning (Python's, PyTorch's or the project's), and it writes and names a PNG
    of the fitted materials next to the model."""
    words = _readme_main_job()
    assert words[:2] == ["hbrdf", "fit"] and "--steps" in words and "--out" in words, words
    words[words.index("--steps") + 1] = "40"  # no warning the fit can print depends on its step count
    out = tmp_path / "synthetic.safetensors"
    words[words.index("--out") + 1] = str(out)
    r = run_cli(*words[1:], "--pool", "16384", "--eval-pairs", "20000")
    assert r.returncode == 0, r.stderr[-2000:]
    both = r.stdout + r.stderr
    assert "warning" not in both.lower(), [ln for ln in both.splitlines() if "warning" in ln.lower()]
    png = out.with_suffix(".png")
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
    assert f"wrote {png}: 8 materials as spheres" in r.stdout


def test_fit_preview_flags(tmp_path):
    out = tmp_path / "m.safetensors"
    common = ("fit", "synthetic:plastic", "--mlp", "8x1", "--steps", "20", "--pool", "4096", "--eval-pairs", "2000")
    r = run_cli_here(*common, "--out", str(out), "--no-preview", "--quiet")
    assert r.returncode == 0, r.stderr
    assert not list(tmp_path.glob("*.png")) and "as spheres" not in r.stdout
    pic = tmp_path / "pics" / "plastic.png"
    r = run_cli_here(*common, "--out", str(out), "--preview", str(pic), "--quiet")
    assert r.returncode == 0, r.stderr
    assert pic.read_bytes()[:4] == b"\x89PNG" and f"wrote {pic}: 1 material as spheres" in r.stdout
    r = run_cli_here(*common, "--out", str(out), "--preview", str(out), "--quiet")
    assert r.returncode == 1 and "--out and --preview name the same file" in r.stderr
    assert r.stderr.strip().count("\n") == 0
