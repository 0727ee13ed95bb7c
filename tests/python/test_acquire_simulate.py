"""The capture simulator (issue 46 step 1; docs/ACQUISITION.md): its radiometry against closed
forms, its noise against the stated Poisson-Gaussian model, the mixture against the weighted sum of
its sources, the rig file's checks, and the capture folder's atomic writing and reading."""

import json
import math
import os

import numpy as np
import pytest
from PIL import Image

import hybridbrdf as hb
from hybridbrdf.acquire import capture as capture_module
from hybridbrdf.acquire.capture import CaptureError, load_capture, write_capture
from hybridbrdf.acquire.geometry import pixel_geometry
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rig import RigError, load_rig, rig_from_dict
from hybridbrdf.acquire.rigs import flash_rig, light_stage_rig
from hybridbrdf.acquire import footprint, simulate
from hybridbrdf.acquire.texel_fit import fit_analytic_texels
from hybridbrdf.cli import main
from hybridbrdf.render.tracer import write_exr
from hybridbrdf.sources.synthetic import LambertGGXDielectric

ALBEDO = np.array([0.2, 0.5, 0.8])


def lambertian():
    """kd / pi exactly: at eta = 1 the Fresnel factor, hence the GGX lobe, is 0."""
    return LambertGGXDielectric("white", kd=ALBEDO, eta=1.0, alpha_x=0.3, alpha_y=0.3)


def overhead_rig(light, intensity, size=(40, 30), height=0.5, fov=40.0, extent=(2.0, 2.0)):
    return rig_from_dict({
        "format_version": 1, "image_size": list(size), "sample_extent": list(extent),
        "cameras": [{"position": [0, 0, height], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": fov}],
        "lights": [{"position": list(light), "intensity": list(intensity)}],
        "shots": [{"camera": 0, "light": 0}]})


def overhead_points(size, height, fov):
    """(H, W) x and y where the pixel centres' rays of a camera at (0, 0, height) looking straight
    down (image up = +y) meet z = 0: the pinhole model written out by hand."""
    w, h = size
    t = math.tan(math.radians(fov) / 2)
    x = (2 * (np.arange(w) + 0.5) / w - 1) * t * w / h * height
    y = (1 - 2 * (np.arange(h) + 0.5) / h) * t * height
    return np.broadcast_to(x[None, :], (h, w)), np.broadcast_to(y[:, None], (h, w))


@pytest.mark.parametrize("light", [(0.0, 0.0, 0.5), (0.3, -0.2, 0.4)], ids=["collocated", "apart"])
def test_lambertian_radiance_is_the_closed_form(light):
    # L = (a / pi) I cos(theta_i) / d^2; collocated at height h, cos = h / r and d = r: a I h / (pi r^3).
    intensity = np.array([2.0, 3.0, 5.0])
    rig = overhead_rig(light, intensity)
    photo = simulate(rig, Mixture([lambertian()], np.ones((1, 1, 1)))).photos[0]
    x, y = overhead_points((40, 30), 0.5, 40.0)
    dx, dy, dz = light[0] - x, light[1] - y, light[2]
    d2 = dx * dx + dy * dy + dz * dz
    expected = (ALBEDO / math.pi)[None, None, :] * intensity * (dz / np.sqrt(d2) / d2)[..., None]
    np.testing.assert_allclose(photo, expected, rtol=2e-6)
    geo = pixel_geometry(rig, 0)
    np.testing.assert_allclose(geo.uv[:, 0], (x / 2.0 + 0.5).ravel(), atol=1e-12)
    np.testing.assert_allclose(geo.uv[:, 1], (0.5 - y / 2.0).ravel(), atol=1e-12)


def test_pixels_off_the_sample_read_zero_and_the_sample_sits_where_the_rig_puts_it():
    rig = overhead_rig((0, 0, 0.5), (1, 1, 1), size=(64, 64), extent=(0.1, 0.2))
    photo = simulate(rig, Mixture([lambertian()], np.ones((1, 1, 1)))).photos[0]
    x, y = overhead_points((64, 64), 0.5, 40.0)
    inside = (np.abs(x) <= 0.05) & (np.abs(y) <= 0.1)
    assert inside.any() and (~inside).any()
    assert (photo[inside] > 0).all() and (photo[~inside] == 0).all()


@pytest.mark.parametrize("radiance", [0.0, 0.05, 0.4, 3.0])
def test_noise_mean_and_variance_are_the_poisson_gaussian_model(radiance):
    photons, read_noise, n = 50.0, 3.0, 400_000
    values = NoiseModel(photons, read_noise).apply(np.full(n, radiance), np.random.default_rng(5))
    mean_expected = radiance
    var_expected = radiance / photons + (read_noise / photons) ** 2
    assert abs(values.mean() - mean_expected) < 5 * math.sqrt(var_expected / n)
    assert abs(values.var() / var_expected - 1) < 0.02  # without the Poisson part 0.05 would be 22% low


def test_noisy_photographs_scatter_around_the_clean_ones_as_the_model_says():
    rig = flash_rig(2, size=(96, 96), flash_offset=0.0)
    mixture = Mixture([lambertian()], np.ones((1, 1, 1)))
    clean = simulate(rig, mixture).photos
    noise = NoiseModel(photons=200.0, read_noise=2.0)
    noisy = simulate(rig, mixture, noise, seed=11).photos
    z = np.concatenate([((b - a) / np.sqrt(noise.variance(a.astype(np.float64)))).ravel()
                        for a, b in zip(clean, noisy)])
    assert abs(z.mean()) < 5 / math.sqrt(z.size) and abs(z.var() - 1) < 0.03
    again = simulate(rig, mixture, noise, seed=11).photos
    other = simulate(rig, mixture, noise, seed=12).photos
    assert all(np.array_equal(a, b) for a, b in zip(noisy, again))
    assert not np.array_equal(noisy[0], other[0])


def test_a_pixel_is_the_weighted_sum_of_the_sources():
    a, b = hb.open_source("synthetic:plastic"), hb.open_source("synthetic:gold")
    w = 16
    t = np.broadcast_to(((np.arange(w) + 0.5) / w)[None, :], (w, w))  # bilinear of this is u itself
    mixture = Mixture([a, b], np.stack([1 - t, t], axis=2))
    rig = flash_rig(3, size=(48, 48))
    cap = simulate(rig, mixture)
    for k in range(len(rig.shots)):
        geo = pixel_geometry(rig, k)
        u = geo.uv[:, 0]
        inner = (u > 0.5 / w) & (u < 1 - 0.5 / w)
        g = (1 - u)[:, None] * a.eval(geo.wi, geo.wo) + u[:, None] * b.eval(geo.wi, geo.wo)
        light = rig.lights[rig.shots[k].light]
        expected = g * (geo.wi[:, 2] / geo.distance2)[:, None] * light.intensity
        got = cap.photos[k][geo.mask]
        np.testing.assert_allclose(got[inner], expected[inner], rtol=2e-6, atol=1e-9)


def test_painted_masks_composite_as_hbrdf_paint_does():
    base, l1, l2 = (hb.open_source(f"synthetic:{n}") for n in ("plastic", "gold", "velvet"))
    m1, m2 = np.full((2, 2), 0.5), np.array([[0.0, 1.0], [0.25, 0.5]])
    mix = Mixture.painted(base, [l1, l2], [m1, m2])
    # Over: the top layer keeps m2, the one below m1 of what is left, the base the rest.
    np.testing.assert_allclose(mix.weights[..., 2], m2)
    np.testing.assert_allclose(mix.weights[..., 1], m1 * (1 - m2))
    np.testing.assert_allclose(mix.weights[..., 0], (1 - m1) * (1 - m2))


def test_light_jitter_moves_the_light_not_the_stated_rig():
    rig = flash_rig(4, size=(32, 32))
    mixture = Mixture([lambertian()], np.ones((1, 1, 1)))
    cap = simulate(rig, mixture, light_jitter=0.01, seed=2)
    nominal = np.array([l.position for l in rig.lights])
    offset = cap.true_light_positions - nominal
    assert 0.001 < np.abs(offset).max() < 0.06
    assert np.array_equal(np.array([l.position for l in cap.rig.lights]), nominal)
    moved = simulate(cap.rig.__class__(rig.image_size, rig.sample_extent, rig.cameras,
                                       [type(l)(p, l.intensity) for l, p in zip(rig.lights, cap.true_light_positions)],
                                       rig.shots), mixture).photos
    for a, b in zip(cap.photos, moved):  # the photographs are the ones the true positions give
        np.testing.assert_array_equal(a, b)


def test_rig_generators():
    phone = flash_rig(5, distance=0.3, flash_offset=0.0)
    assert len(phone.shots) == len(phone.cameras) == len(phone.lights) == 5
    for cam, light in zip(phone.cameras, phone.lights):
        np.testing.assert_allclose(np.linalg.norm(cam.position), 0.3)
        np.testing.assert_array_equal(cam.position, light.position)
    np.testing.assert_allclose(phone.cameras[0].position, [0, 0, 0.3], atol=1e-15)
    stage = light_stage_rig(6, 3)
    assert (len(stage.lights), len(stage.cameras), len(stage.shots)) == (6, 3, 18)
    assert {(s.camera, s.light) for s in stage.shots} == {(c, l) for c in range(3) for l in range(6)}
    # A white Lambertian lit head-on from the rig's distance reads 1 at the sample's centre.
    white = LambertGGXDielectric("w", kd=1.0, eta=1.0, alpha_x=0.3, alpha_y=0.3)
    photo = simulate(flash_rig(1, size=(33, 33), flash_offset=0.0), Mixture([white], np.ones((1, 1, 1)))).photos[0]
    np.testing.assert_allclose(photo[16, 16], 1.0, rtol=1e-6)


def valid_rig():
    return flash_rig(2, size=(16, 12)).to_dict()


def set_path(doc, path, value):
    *head, last = path
    for key in head:
        doc = doc[key]
    if value is KeyError:
        del doc[last]
    else:
        doc[last] = value


BAD_RIGS = [
    (("lights",), [], "lights: a rig needs at least one light"),
    (("lights",), KeyError, "lights: missing"),
    (("lights", 0, "intensity"), [1, -1, 1], "lights[0].intensity[1]: must lie in [0, inf]"),
    (("lights", 1, "position"), [0, 0, -0.1], "lights[1].position: must lie above the sample plane"),
    (("cameras", 0, "fov_deg"), 0, "cameras[0].fov_deg: must lie in (0, 179]"),
    (("cameras", 0, "focal"), 35, "cameras[0].focal: unknown key"),
    (("cameras", 1, "up"), [0, 0, 0], "cameras[1].up: is zero or parallel"),
    (("cameras", 0, "position"), [0, 0, 0], "cameras[0].position: must lie above the sample plane"),
    (("shots", 0, "light"), 2, "shots[0].light: must be an index 0 to 1"),
    (("shots", 1, "image"), "../x.exr", "shots[1].image: must be a plain .exr, .png, .tif, .tiff file name"),
    (("shots", 1, "image"), "photo_000.exr", "shots[1].image: 'photo_000.exr' names two shots"),
    (("shots",), [], "shots: a rig needs at least one shot"),
    (("image_size",), [0, 12], "image_size: must be [width, height]"),
    (("sample_extent",), [0.1, "a"], "sample_extent[1]: must be a finite number"),
    (("format_version",), 2, "format_version: this library reads version 1"),
]


@pytest.mark.parametrize("where, value, words", BAD_RIGS, ids=[w.split(":")[0] for _, _, w in BAD_RIGS])
def test_a_bad_rig_is_one_line_naming_the_file_and_key(tmp_path, where, value, words):
    doc = valid_rig()
    set_path(doc, where, value)
    path = tmp_path / "rig.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(RigError) as err:
        load_rig(path)
    assert str(err.value).startswith(f"{path}: {words}"), str(err.value)
    assert "\n" not in str(err.value)


def test_rig_files_that_are_not_json_numbers_or_objects(tmp_path):
    path = tmp_path / "rig.json"
    path.write_text(json.dumps(valid_rig()).replace('"fov_deg": ', '"fov_deg": NaN, "x": ', 1))
    with pytest.raises(RigError, match=r"rig.json: rig file is not valid JSON \(NaN is not a JSON number"):
        load_rig(path)
    path.write_text("[1, 2]")
    with pytest.raises(RigError, match=r"rig.json: the rig: must be a JSON object"):
        load_rig(path)
    path.write_text(json.dumps(valid_rig()))
    assert load_rig(path).to_dict() == valid_rig()


def small_capture(seed=0):
    rig = flash_rig(3, size=(24, 20))
    mixture = Mixture.painted(hb.open_source("synthetic:plastic"), [hb.open_source("synthetic:gold")],
                              [np.tile(np.linspace(0, 1, 8), (8, 1))])
    return simulate(rig, mixture, NoiseModel(500.0, 1.0), light_jitter=0.002, seed=seed)


def test_a_capture_folder_reads_back(tmp_path):
    cap = small_capture()
    folder = write_capture(cap, tmp_path / "cap")
    rig, photos, index = load_capture(folder)
    assert rig.to_dict() == cap.rig.to_dict()
    for a, b in zip(photos, cap.photos):
        np.testing.assert_array_equal(a, b)
    sim = index["simulated"]
    assert sim["noise"] == {"model": "poisson-gaussian", "photons": 500.0, "read_noise": 1.0}
    np.testing.assert_array_equal(sim["true_light_positions"], cap.true_light_positions)
    assert [layer["source"] for layer in sim["layers"]] == ["synthetic:plastic", "synthetic:gold"]
    assert sorted(os.listdir(tmp_path)) == ["cap"]


def test_a_capture_never_replaces_another_folder_and_is_never_half_written(tmp_path, monkeypatch):
    other = tmp_path / "notes"
    other.mkdir()
    (other / "todo.txt").write_text("keep me")
    with pytest.raises(hb.InputFileError, match="notes: is a folder without capture.json"):
        write_capture(small_capture(), other)
    assert os.listdir(other) == ["todo.txt"]

    folder = tmp_path / "cap"
    write_capture(small_capture(seed=1), folder)
    before = {n: (folder / n).read_bytes() for n in os.listdir(folder)}
    calls = []

    def failing_write_exr(image, path):
        calls.append(path)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        write_exr(image, path)

    monkeypatch.setattr(capture_module, "write_exr", failing_write_exr)
    with pytest.raises(OSError):
        write_capture(small_capture(seed=2), folder)
    assert {n: (folder / n).read_bytes() for n in os.listdir(folder)} == before
    assert sorted(os.listdir(tmp_path)) == ["cap", "notes"]
    monkeypatch.undo()
    write_capture(small_capture(seed=2), folder)  # a capture is replaced
    assert (folder / "photo_000.exr").read_bytes() != before["photo_000.exr"]


def test_photographs_of_the_wrong_size_missing_or_not_finite(tmp_path):
    folder = tmp_path / "cap"
    write_capture(small_capture(), folder)
    write_exr(np.zeros((20, 25, 3), np.float32), str(folder / "photo_001.exr"))
    with pytest.raises(CaptureError, match=r"photo_001.exr: photograph is 25x20; the rig says 24x20"):
        load_capture(folder)
    bad = np.zeros((20, 24, 3), np.float32)
    bad[3, 5, 1] = np.nan
    write_exr(bad, str(folder / "photo_001.exr"))
    with pytest.raises(CaptureError, match=r"photo_001.exr: 1 values are not finite \(first at column 5, row 3\)"):
        load_capture(folder)
    os.unlink(folder / "photo_002.exr")
    with pytest.raises(CaptureError, match=r"photo_00[12].exr: "):
        load_capture(folder)


def test_the_command_writes_a_capture_and_refuses_in_one_line(tmp_path, capsys):
    mask = tmp_path / "mask.png"
    Image.fromarray(np.tile(np.arange(0, 256, 16, dtype=np.uint8), (16, 1)), "L").save(mask)
    out = tmp_path / "cap"

    def command(**flags):
        flags = {"stage": "2x3", "size": "20x16", "base": "synthetic:plastic", "layer": f"synthetic:gold={mask}",
                 "photons": "300", "read-noise": "1.5", "seed": "4", "out": str(out), **flags}
        return ["acquire", "simulate", "--quiet"] + [a for k, v in flags.items() for a in (f"--{k}", v)]

    assert main(command()) == 0
    rig, photos, index = load_capture(out)
    assert (len(rig.lights), len(rig.cameras), len(photos), rig.image_size) == (2, 3, 6, (20, 16))
    assert index["simulated"]["noise"]["photons"] == 300.0 and index["simulated"]["seed"] == 4
    assert main(command()) == 0  # a capture is replaced
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "keep.txt").write_text("x")
    for flags, words in (({"out": str(tmp_path / "other")}, "other: is a folder without capture.json"),
                         ({"out": str(tmp_path)}, f"--out holds the input {mask}"),
                         ({"photons": "0"}, "argument --photons: expected a number in (0"),
                         ({"photons": "nan"}, "argument --photons: expected a number in (0"),
                         ({"stage": "2x0"}, "argument --stage: expected KxV"),
                         ({"layer": "synthetic:gold"}, "--layer takes SOURCE=MASK"),
                         ({"base": "synthetic:nothing"}, "synthetic:nothing: unknown synthetic material")):
        capsys.readouterr()
        try:
            code = main(command(**flags))
        except SystemExit as exc:
            code = exc.code
        err = capsys.readouterr().err.strip().splitlines()
        assert code != 0 and words in err[-1] and "Traceback" not in "\n".join(err), err
    assert os.listdir(tmp_path / "other") == ["keep.txt"]


# ---- step 2's input: the observations of each texel ------------------------------------------

def test_observations_invert_the_radiometry_texel_by_texel():
    a, b = hb.open_source("synthetic:plastic"), hb.open_source("synthetic:gold")
    half = np.zeros((4, 64, 2))
    half[:, :32, 0], half[:, 32:, 1] = 1, 1  # A left of u = 0.5, B right of it (blended within 1/64 of it)
    rig = light_stage_rig(3, 2, size=(64, 48))
    cap = simulate(rig, Mixture([a, b], half))
    obs = texel_observations(rig, cap.photos, (8, 4))
    assert obs.offsets[-1] == len(obs.value) > 0 and obs.dropped["grazing"] == 0
    for t in range(32):
        i, j = t % 8, t // 8
        r = obs.rows(t)
        if r.stop == r.start:
            continue
        uv = obs.uv[r].astype(np.float64)
        assert ((uv[:, 0] >= i / 8 - 1e-6) & (uv[:, 0] <= (i + 1) / 8 + 1e-6)).all()
        assert ((uv[:, 1] >= j / 4 - 1e-6) & (uv[:, 1] <= (j + 1) / 4 + 1e-6)).all()
        if i in (3, 4):
            continue  # holds the blend at u = 0.5
        source = a if i < 4 else b
        g = source.eval(obs.wi[r].astype(np.float64), obs.wo[r].astype(np.float64))
        np.testing.assert_allclose(obs.value[r], g, rtol=2e-5, atol=1e-7)
    assert obs.counts().sum() == len(obs.value) and set(np.unique(obs.shot)) == set(range(6))


def test_observations_leave_out_grazing_pixels_and_refuse_bad_photographs():
    rig = rig_from_dict({
        "format_version": 1, "image_size": [32, 32], "sample_extent": [4.0, 4.0],  # far rows seen at wo.z < 0.05
        "cameras": [{"position": [0, -2.1, 0.1], "look_at": [0, 1, 0], "up": [0, 0, 1], "fov_deg": 50}],
        "lights": [{"position": [0, 0, 1], "intensity": [1, 1, 1]}], "shots": [{"camera": 0, "light": 0}]})
    photos = simulate(rig, Mixture([lambertian()], np.ones((1, 1, 1)))).photos
    obs = texel_observations(rig, photos, (4, 4), min_cos=0.05)
    assert obs.dropped["grazing"] > 0 and (obs.wo[:, 2] >= 0.05).all() and (obs.wi[:, 2] >= 0.05).all()
    assert obs.dropped["grazing"] + len(obs.value) == pixel_geometry(rig, 0).mask.sum()
    with pytest.raises(ValueError, match="2 photographs for the rig's 1 shots"):
        texel_observations(rig, photos * 2, (4, 4))
    with pytest.raises(ValueError, match=r"photograph 0 \(photo_000.exr\) has shape \(32, 31, 3\)"):
        texel_observations(rig, [photos[0][:, :31]], (4, 4))
    bad = photos[0].copy()
    bad[3, 3, 0] = np.inf
    with pytest.raises(ValueError, match="values that are not finite"):
        texel_observations(rig, [bad], (4, 4))


@pytest.mark.parametrize("model", ["nearest", "bilinear"])
def test_the_analytic_texel_fit_recovers_each_texels_parameters(model, monkeypatch):
    # Two f_a materials (exactly representable), left and right of u = 0.5; truth known per texel.
    # Each observation model with the truth it represents exactly (acquire/footprint.py): "nearest"
    # a map constant over each texel's cell (the weights map 16 times finer, the edge on a cell
    # boundary), "bilinear" the map at the fit's resolution, looked up between texel centres, of two
    # materials that differ in kd only (f_a is linear in kd: blending their values between texel
    # centres, as a texture unit filters a map, is blending their BRDFs, as the simulator mixes).
    monkeypatch.setattr(footprint, "MODEL", model)
    left = LambertGGXDielectric("left", kd=(0.45, 0.22, 0.08), eta=1.5, alpha_x=0.2, alpha_y=0.2)
    right = LambertGGXDielectric("right", kd=(0.1, 0.3, 0.6), eta=2.2, alpha_x=0.45, alpha_y=0.45) \
        if model == "nearest" else LambertGGXDielectric("right", kd=(0.1, 0.3, 0.6), eta=1.5, alpha_x=0.2, alpha_y=0.2)
    width = 64 if model == "nearest" else 4
    half = np.zeros((1 if model == "bilinear" else 2, width, 2))
    half[:, :width // 2, 0], half[:, width // 2:, 1] = 1, 1
    rig = light_stage_rig(8, 3, size=(32, 32))
    cap = simulate(rig, Mixture([left, right], half))
    maps = fit_analytic_texels(texel_observations(rig, cap.photos, (4, 1)), steps=200, rows_per_texel=None)
    assert (maps.counts > 0).all()
    for i, truth in ((0, left), (3, right)) if model == "nearest" else enumerate((left, left, right, right)):
        np.testing.assert_allclose(maps.kd[0, i], truth.kd, atol=0.01)
        np.testing.assert_allclose(maps.alpha[0, i], [truth.alpha_x] * 2, atol=0.01)
        np.testing.assert_allclose(maps.eta[0, i], truth.eta, atol=0.05)
    noisy = simulate(rig, Mixture([left, right], half), NoiseModel(photons=2000.0, read_noise=2.0), seed=3)
    maps = fit_analytic_texels(texel_observations(rig, noisy.photos, (4, 1)), steps=200, rows_per_texel=None)
    np.testing.assert_allclose(maps.kd[0, 0], left.kd, atol=0.02)
    np.testing.assert_allclose(maps.alpha[0, 0], [left.alpha_x] * 2, atol=0.02)
