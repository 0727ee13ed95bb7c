"""NBRDF network reader (``.h5`` + ``.json``, Sztrajman et al. 2021).

The shared networks live outside the repository (``../shared/data/nbrdf``);
tests that need them skip with a reason when absent. The forward pass is
checked three ways: a float64 re-implementation here that reads the datasets
by their fixed paths and builds the Rusinkiewicz input with trigonometry and
rotation matrices (the module uses neither); hand-built tiny networks whose
outputs are computed by hand; and, where Mitsuba and the raw RGL files are
available, the direction convention against the measurements themselves.
"""

import json
import os
import pathlib
import shutil
import time

import h5py
import numpy as np
import pytest

from hybridbrdf.evaluate.metrics import smape
from hybridbrdf.sources.base import BRDFFormatError
from hybridbrdf.sources import open_source
from hybridbrdf.sources.nbrdf import NBRDFSource, nbrdf_origin, open_nbrdf

from hybridbrdf.evaluate.directions import cosine_directions

from helpers import mitsuba_f, mitsuba_measured, rot_y, rot_z

SHARED = pathlib.Path(__file__).resolve().parents[2].parent / "shared"
NBRDF_DIR = SHARED / "data" / "nbrdf"
RGL_DIR = SHARED / "data" / "rgl"
FOLDERS = {"merl": 80, "rgl": 49, "nielsen": 8}
ORIGINS = {
    "merl": "MERL (NBRDF reconstruction)",
    "rgl": "RGL (NBRDF reconstruction)",
    "nielsen": "Nielsen 2015 (NBRDF reconstruction)",
}

needs_shared = pytest.mark.skipif(not NBRDF_DIR.is_dir(), reason=f"shared NBRDF data not found at {NBRDF_DIR}")


def shared_files():
    if not NBRDF_DIR.is_dir():
        return []
    return sorted(p for folder in FOLDERS for p in (NBRDF_DIR / folder).glob("*.h5"))


# ---- independent forward pass ---------------------------------------------------


def reference_input(wi, wo):
    """(sin theta_h, 0, cos theta_h, d) with theta_h, phi_h from acos/atan2 and d
    from explicit rotation matrices Ry(-theta_h) Rz(-phi_h) wi."""
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    theta_h = np.arccos(np.clip(h[:, 2], -1.0, 1.0))
    phi_h = np.arctan2(h[:, 1], h[:, 0])
    d = np.array([rot_y(-t) @ rot_z(-p) @ w for t, p, w in zip(theta_h, phi_h, wi)])
    return np.column_stack([np.sin(theta_h), np.zeros(len(wi)), np.cos(theta_h), d])


def reference_forward(h5_path, x):
    """The published 6-21-21-3 network, read by the fixed dataset paths."""
    with h5py.File(h5_path, "r") as f:
        w = [(f[f"dense_{k}/dense_{k}/kernel:0"][()].astype(np.float64),
              f[f"dense_{k}/dense_{k}/bias:0"][()].astype(np.float64)) for k in (1, 2, 3)]
    a = np.maximum(x @ w[0][0] + w[0][1], 0.0)
    a = np.maximum(a @ w[1][0] + w[1][1], 0.0)
    y = a @ w[2][0] + w[2][1]
    return np.maximum(np.exp(y) - 1.0, 0.0)


# ---- hand-built networks ----------------------------------------------------------


def write_network(path, layers, activations=None, json_layers=None, layer_names=True):
    """Write a Keras-2.2.4-style weights file (and a JSON config unless
    activations is None). ``layers``: list of (kernel, bias)."""
    names = [f"dense_{k + 1}" for k in range(len(layers))]
    with h5py.File(path, "w") as f:
        if layer_names:
            f.attrs["layer_names"] = np.array([n.encode() for n in names + ["lambda_1"]])
        for name, (kernel, bias) in zip(names, layers):
            g = f.create_group(name)
            g.attrs["weight_names"] = np.array([f"{name}/kernel:0".encode(), f"{name}/bias:0".encode()])
            g.create_dataset(f"{name}/kernel:0", data=np.asarray(kernel, dtype=np.float32))
            g.create_dataset(f"{name}/bias:0", data=np.asarray(bias, dtype=np.float32))
        lam = f.create_group("lambda_1")
        lam.attrs["weight_names"] = np.array([], dtype="S1")
    if activations is not None or json_layers is not None:
        if json_layers is None:
            json_layers = [{"class_name": "Dense", "config": {"name": n, "units": int(np.shape(k)[1]), "activation": a}}
                           for n, (k, _), a in zip(names, layers, activations)]
            lam_cfg = {"name": "lambda_1", "function": ["opaque", None, None]}
            json_layers.append({"class_name": "Lambda", "config": lam_cfg})
        cfg = {"class_name": "Sequential", "config": {"name": "s", "layers": json_layers}, "keras_version": "2.2.4"}
        pathlib.Path(path).with_suffix(".json").write_text(json.dumps(cfg))


def tiny_layers():
    """hidden = act(cos theta_h, 2 d.z - 1); y = (ln 2 * hidden0, ln 3 * hidden1, -5)."""
    k1 = np.zeros((6, 2))
    k1[2, 0] = 1.0
    k1[5, 1] = 2.0
    b1 = np.array([0.0, -1.0])
    k2 = np.array([[np.log(2.0), 0.0, 0.0], [0.0, np.log(3.0), 0.0]])
    b2 = np.array([0.0, 0.0, -5.0])
    return [(k1, b1), (k2, b2)]


def tiny_cases():
    s60, c60 = np.sin(np.pi / 3), 0.5
    c30 = np.cos(np.pi / 6)
    wi = np.array([[0, 0, 1.0], [s60, 0, c60], [0, 0, 1.0]])
    wo = np.array([[0, 0, 1.0], [-s60, 0, c60], [s60, 0, c60]])
    # By hand: (1) h = d = +z. (2) h = +z, d = wi, d.z = 1/2. (3) theta_h = 30 deg,
    # d = Ry(-30 deg) (0, 0, 1) = (-1/2, 0, cos 30): cos theta_h = d.z = cos 30.
    hidden = np.array([[1.0, 1.0], [1.0, 0.0], [c30, 2 * c30 - 1]])
    return wi, wo, hidden


def test_tiny_network_by_hand(tmp_path):
    path = tmp_path / "tiny.h5"
    write_network(path, tiny_layers(), ["relu", "linear"])
    src = open_nbrdf(path)
    wi, wo, hidden = tiny_cases()
    expect = np.column_stack([2.0 ** hidden[:, 0] - 1, 3.0 ** hidden[:, 1] - 1, np.zeros(3)])  # exp(-5) - 1 < 0 -> 0
    assert np.allclose(src.eval(wi, wo), expect, rtol=1e-6, atol=1e-7)  # float32 weights (ln 2, ln 3)
    # phi_h is dropped: rotating the configuration about the normal changes nothing.
    r = rot_z(1.234)
    assert np.allclose(src.eval(wi @ r.T, wo @ r.T), src.eval(wi, wo), rtol=1e-12, atol=1e-15)
    # Below the horizon: 0.
    assert np.array_equal(src.eval(wi * [1, 1, -1], wo), np.zeros((3, 3)))
    assert [l[1].shape for l in src.layers] == [(6, 2), (2, 3)]  # sizes come from the file


def test_tiny_network_activation_from_json(tmp_path):
    path = tmp_path / "tiny.h5"
    write_network(path, tiny_layers(), ["tanh", "linear"])
    wi, wo, hidden = tiny_cases()
    t = np.tanh(hidden)
    expect = np.column_stack([2.0 ** t[:, 0] - 1, 3.0 ** t[:, 1] - 1, np.zeros(3)])
    assert np.allclose(open_nbrdf(path).eval(wi, wo), expect, rtol=1e-6, atol=1e-7)


def test_tiny_network_without_json_uses_published_activations(tmp_path):
    path = tmp_path / "tiny.h5"
    write_network(path, tiny_layers(), activations=None)
    assert not path.with_suffix(".json").exists()
    wi, wo, hidden = tiny_cases()
    expect = np.column_stack([2.0 ** hidden[:, 0] - 1, 3.0 ** hidden[:, 1] - 1, np.zeros(3)])
    assert np.allclose(open_nbrdf(path).eval(wi, wo), expect, rtol=1e-6, atol=1e-7)
    # Neither layer_names nor JSON: groups dense_<n> in numeric order.
    write_network(path, tiny_layers(), activations=None, layer_names=False)
    assert np.allclose(open_nbrdf(path).eval(wi, wo), expect, rtol=1e-6, atol=1e-7)


def test_origin_from_folder(tmp_path):
    for folder, label in ORIGINS.items():
        p = tmp_path / "data" / "nbrdf" / folder
        p.mkdir(parents=True)
        write_network(p / "m.h5", tiny_layers(), ["relu", "linear"])
        src = open_source(p / "m.h5")
        assert isinstance(src, NBRDFSource) and src.origin == label and src.name == "m" and src.isotropic
    assert nbrdf_origin(tmp_path / "merl" / "m.h5") == "NBRDF network"  # not under nbrdf/
    assert nbrdf_origin(tmp_path / "nbrdf" / "m.h5") == "NBRDF network"


# ---- the shared networks ------------------------------------------------------------


@needs_shared
def test_every_shared_network_opens_and_evaluates(rng):
    files = shared_files()
    counts = {k: sum(1 for p in files if p.parent.name == k) for k in FOLDERS}
    assert counts == FOLDERS
    n = 10_000
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    for p in files:
        src = open_source(p)
        assert isinstance(src, NBRDFSource), p
        assert src.name == p.stem and src.isotropic is True and src.origin == ORIGINS[p.parent.name]
        assert [l[1].shape for l in src.layers] == [(6, 21), (21, 21), (21, 3)]
        assert [l[3] for l in src.layers] == ["relu", "relu", "linear"]
        f = src.eval(wi, wo)
        assert f.shape == (n, 3) and np.isfinite(f).all() and (f >= 0).all(), p
        assert f.max() > 0, p


@needs_shared
@pytest.mark.parametrize("rel", ["merl/alum-bronze.h5", "merl/gold-metallic-paint.h5", "rgl/paper_white_rgb.h5",
                                 "rgl/cc_ibiza_sunset_rgb.h5", "nielsen/bluebook.h5"])
def test_forward_matches_independent_implementation(rel, rng):
    path = NBRDF_DIR / rel
    if not path.exists():
        pytest.skip(f"{path} not in the shared data")
    n = 3000
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    expect = reference_forward(path, reference_input(wi, wo))
    got = open_nbrdf(path).eval(wi, wo)
    assert np.allclose(got, expect, rtol=1e-9, atol=1e-12)


@needs_shared
def test_reciprocity_is_measured_not_assumed(rng):
    """The input is built from wi, so f(wi, wo) != f(wo, wi) in general. This
    measures the asymmetry (SMAPE) per folder; it asserts only sanity."""
    n = 10_000
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    report = {}
    for p in shared_files():
        src = open_nbrdf(p)
        report.setdefault(p.parent.name, []).append((smape(src.eval(wi, wo), src.eval(wo, wi)), p.stem))
    for folder, vals in report.items():
        s = np.array([v for v, _ in vals])
        assert np.isfinite(s).all() and (s >= 0).all() and (s <= 2).all()
        worst = max(vals)
        print(f"NBRDF reciprocity SMAPE {folder}: median {np.median(s):.3f}, max {worst[0]:.3f} ({worst[1]})")


@needs_shared
def test_direction_convention_against_raw_rgl(rng):
    """The d vector is built from wi, the light. Where the raw RGL file is
    available, Mitsuba 3's ``measured`` plugin (the project's RGL oracle:
    f(wi, wo) = eval(si.wi = wo, wi) / wi.z) tells which order the network was
    trained in: the stated one must fit the measurement better than the swap."""
    names = ["paper_white_rgb", "colodur_napoli_4f_rgb"]
    if not all((RGL_DIR / f"{n}.bsdf").exists() and (NBRDF_DIR / "rgl" / f"{n}.h5").exists() for n in names):
        pytest.skip("raw RGL files or their NBRDF networks not in the shared data")
    n = 1500
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    keep = (wi[:, 2] > 0.05) & (wo[:, 2] > 0.05)  # Mitsuba's value is divided by wi.z
    wi, wo = wi[keep], wo[keep]
    for name in names:
        ref = mitsuba_f(mitsuba_measured(RGL_DIR / f"{name}.bsdf"), wi, wo)
        src = open_nbrdf(NBRDF_DIR / "rgl" / f"{name}.h5")
        stated, swapped = smape(ref, src.eval(wi, wo)), smape(ref, src.eval(wo, wi))
        print(f"{name}: SMAPE to raw RGL {stated:.4f} (d from wi), {swapped:.4f} (d from wo)")
        assert stated < swapped


@needs_shared
def test_evaluation_speed(rng):
    path = NBRDF_DIR / "merl" / "alum-bronze.h5"
    if not path.exists():
        pytest.skip(f"{path} not in the shared data")
    src = open_nbrdf(path)
    n = 100_000
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    src.eval(wi[:100], wo[:100])
    best = min(_timed(src.eval, wi, wo) for _ in range(3))
    print(f"NBRDF eval: {n} pairs in {best * 1e3:.1f} ms ({n / best / 1e6:.2f} M pairs/s)")
    assert best < 10.0  # catches only a pathological slowdown (measured ~0.1 s)


def _timed(fn, *args):
    t0 = time.perf_counter()
    fn(*args)
    return time.perf_counter() - t0


# ---- malformed files ----------------------------------------------------------------


def standard_layers(rng):
    return [(rng.normal(size=(6, 21)) * 0.3, rng.normal(size=21) * 0.1),
            (rng.normal(size=(21, 21)) * 0.3, rng.normal(size=21) * 0.1),
            (rng.normal(size=(21, 3)) * 0.3, rng.normal(size=3) * 0.1)]


def test_standard_random_network_opens(tmp_path, rng):
    path = tmp_path / "ok.h5"
    write_network(path, standard_layers(rng), ["relu", "relu", "linear"])
    assert np.isfinite(open_nbrdf(path).eval(cosine_directions(rng, 10), cosine_directions(rng, 10))).all()


def _drop_group(path, name):
    with h5py.File(path, "a") as f:
        del f[name]


def _set_dataset(path, name, value):
    with h5py.File(path, "a") as f:
        del f[name]
        f[name] = value


def _nan_weight(path):
    with h5py.File(path, "a") as f:
        f["dense_2/dense_2/kernel:0"][3, 4] = np.nan


def _json(layers_fn):
    def mutate(path):
        jp = pathlib.Path(path).with_suffix(".json")
        cfg = json.loads(jp.read_text())
        cfg["config"]["layers"] = layers_fn(cfg["config"]["layers"])
        jp.write_text(json.dumps(cfg))
    return mutate


def _with(i, **kw):
    def f(layers):
        layers[i]["config"].update(kw)
        return layers
    return f


@pytest.mark.parametrize(
    "mutate,message",
    [
        (lambda p: _drop_group(p, "dense_2"), "missing group 'dense_2'"),
        (lambda p: _drop_group(p, "dense_3/dense_3/bias:0"), "missing dataset 'dense_3/dense_3/bias:0'"),
        (lambda p: _set_dataset(p, "dense_1/dense_1/kernel:0", np.zeros((6, 20), np.float32)),
         r"bias has shape \(21,\)"),
        (lambda p: _set_dataset(p, "dense_2/dense_2/kernel:0", np.zeros((20, 21), np.float32)), r"expected \(21, n\)"),
        (lambda p: _set_dataset(p, "dense_1/dense_1/kernel:0", np.zeros((5, 21), np.float32)), r"expected \(6, n\)"),
        (lambda p: (_set_dataset(p, "dense_3/dense_3/kernel:0", np.zeros((21, 4), np.float32)),
                    _set_dataset(p, "dense_3/dense_3/bias:0", np.zeros(4, np.float32))), "has 3 units but"),
        (lambda p: (_set_dataset(p, "dense_3/dense_3/kernel:0", np.zeros((21, 4), np.float32)),
                    _set_dataset(p, "dense_3/dense_3/bias:0", np.zeros(4, np.float32)),
                    pathlib.Path(p).with_suffix(".json").unlink()), "expected 3 \\(RGB\\)"),
        (lambda p: _set_dataset(p, "dense_1/dense_1/bias:0", np.zeros((21, 1), np.float32)), "bias has shape"),
        (lambda p: _set_dataset(p, "dense_1/dense_1/bias:0", np.array([b"x"] * 21)), "non-numeric"),
        (_nan_weight, "'dense_2' weights hold non-finite values"),
        (_json(_with(0, activation="swish")), "unsupported activation 'swish'"),
        (_json(_with(1, activation={"class_name": "Custom"})), "unsupported activation"),
        (_json(_with(1, units=22)), "has 22 units"),
        (_json(_with(2, name="dense_9")), "do not match the weights file"),
        (_json(lambda layers: layers[:-1]), "last layer is not the Lambda"),
        (_json(lambda layers: [{"class_name": "BatchNormalization", "config": {"name": "bn"}}] + layers),
         "unsupported Keras layer class 'BatchNormalization'"),
        (lambda p: pathlib.Path(p).with_suffix(".json").write_text("{not json"), "not valid JSON"),
        (lambda p: pathlib.Path(p).with_suffix(".json").write_text("[1, 2]"), "no list of layers"),
    ],
)
def test_malformed_networks(tmp_path, rng, mutate, message):
    path = tmp_path / "bad.h5"
    write_network(path, standard_layers(rng), ["relu", "relu", "linear"])
    mutate(path)
    with pytest.raises(BRDFFormatError, match=message) as info:
        open_source(path)
    assert os.path.basename(info.value.path) in ("bad.h5", "bad.json")


@pytest.mark.parametrize(
    "content",
    [b"", b"\x89HDF\r\n\x1a\n" + b"\0" * 100, os.urandom(4096)],
    ids=["empty", "header-only", "random"],
)
def test_not_hdf5(tmp_path, content):
    path = tmp_path / "junk.h5"
    path.write_bytes(content)
    with pytest.raises(BRDFFormatError, match="not a readable Keras HDF5 weights file") as info:
        open_source(path)
    assert info.value.path == os.fspath(path)


def test_truncated_hdf5(tmp_path, rng):
    good = tmp_path / "good.h5"
    write_network(good, standard_layers(rng), ["relu", "relu", "linear"])
    data = good.read_bytes()
    for cut in (len(data) // 2, len(data) - 64):
        path = tmp_path / f"cut{cut}.h5"
        path.write_bytes(data[:cut])
        shutil.copy(good.with_suffix(".json"), path.with_suffix(".json"))
        with pytest.raises(BRDFFormatError) as info:
            open_nbrdf(path)
        assert info.value.path == os.fspath(path)


def test_missing_file(tmp_path):
    with pytest.raises(BRDFFormatError, match="no such file"):
        open_nbrdf(tmp_path / "absent.h5")


@pytest.mark.parametrize("shape", [(6, 2**26), (6, 2**28), (2**40, 2**20)])
def test_huge_declared_datasets_are_refused_before_reading(tmp_path, shape):
    """A small file can declare a chunked dataset of gigabytes (chunks never written read as
    zeros); the shape is checked from the header before any value is read."""
    import resource
    import time

    path = tmp_path / "bomb.h5"
    write_network(path, tiny_layers(), activations=["relu", "relu"])
    with h5py.File(path, "a") as f:
        del f["dense_1"]["dense_1/kernel:0"]
        f["dense_1"].create_dataset("dense_1/kernel:0", shape=shape, dtype=np.float32, chunks=(1, 1024),
                                    maxshape=(None, None))
    assert path.stat().st_size < 100_000
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    with pytest.raises(BRDFFormatError, match=r"values, more than 1048576") as info:
        open_source(str(path))
    assert time.perf_counter() - t0 < 2.0
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss_before < 200_000  # KiB: nothing of the dataset
