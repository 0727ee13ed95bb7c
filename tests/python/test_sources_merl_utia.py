"""MERL ``.binary`` and UTIA ``.bin`` readers.

No raw MERL or UTIA file exists on this machine, so the tests build files two
ways: raw bytes laid out here by hand from the published reading code's index
formulas (this checks the file layout and angle conventions independently of
the module's writers), and the module's writers tabulating known functions
(this checks the read-back against ground truth within the interpolation
error, whose bound is derived from the grid spacing in each test).
"""

import os

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf.evaluate.metrics import smape
from hybridbrdf.sources.base import BRDFFormatError
from hybridbrdf.sources import open_source
from hybridbrdf.sources.merl import MERLSource, open_merl, write_merl
from hybridbrdf.sources.utia import UTIASource, open_utia, read_utia_table, write_utia

from hybridbrdf.evaluate.directions import cosine_directions

from helpers import rot_y, rot_z

MERL_SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
MERL_BYTES = 12 + 3 * 90 * 90 * 180 * 8
UTIA_BYTES = 3 * 6 * 48 * 6 * 48 * 8
DEG = np.pi / 180.0


# ---- independent geometry (matrices, not the module's formulas) ------------


def dirs_from_angles(theta_h, theta_d, phi_d, phi_h):
    """wi, wo for Rusinkiewicz angles: d in the half-vector frame, then
    wi = Rz(phi_h) Ry(theta_h) d, and wo is d mirrored about that frame's normal."""
    wi, wo = [], []
    for th, td, pd, ph in zip(theta_h, theta_d, phi_d, phi_h):
        m = rot_z(ph) @ rot_y(th)
        d = np.array([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)])
        wi.append(m @ d)
        wo.append(m @ (d * [-1.0, -1.0, 1.0]))
    return np.array(wi), np.array(wo)


def spherical_deg(theta, phi):
    t, p = np.radians(theta), np.radians(phi)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)


def analytic(params):
    """Ground truth f(wi, wo) (the C++ library, float32: ~1e-6 relative, far
    below every interpolation tolerance here)."""
    return lambda wi, wo: hb.analytic_eval(wi, wo, params).astype(np.float64)


def write_merl_bytes(path, stored, dims=(90, 90, 180)):
    """A MERL file from stored (3, 90, 90, 180) values, written here by hand."""
    with open(path, "wb") as fh:
        fh.write(np.asarray(dims, dtype="<i4").tobytes())
        fh.write(np.ascontiguousarray(stored, dtype="<f8").tobytes())


# ---- MERL: layout and index conventions ------------------------------------


@pytest.fixture(scope="module")
def merl_index_file(tmp_path_factory):
    """Stored R = theta_h index i, G = theta_d index j, B = phi_d index k."""
    i, j, k = np.meshgrid(np.arange(90.0), np.arange(90.0), np.arange(180.0), indexing="ij")
    path = tmp_path_factory.mktemp("merl") / "index.binary"
    write_merl_bytes(path, np.stack([i, j, k]))
    return path


def random_rusinkiewicz(rng, n, th_max=88.0, td_max=89.0):
    th = rng.uniform(0.05, th_max, n) * DEG
    td = rng.uniform(0.05, td_max, n) * DEG
    pd = rng.uniform(-180.0, 180.0, n) * DEG
    ph = rng.uniform(-180.0, 180.0, n) * DEG
    wi, wo = dirs_from_angles(th, td, pd, ph)
    keep = (wi[:, 2] > 1e-6) & (wo[:, 2] > 1e-6)
    return th[keep], td[keep], pd[keep], wi[keep], wo[keep]


def test_merl_index_conventions_linear(merl_index_file, rng):
    """Trilinear interpolation of a table linear in its indices is exact, so the
    read value *is* the continuous index the reader computed: it must be the
    published one (sqrt parameterisation for theta_h, phi_d folded into [0, pi))."""
    src = open_merl(merl_index_file)
    th, td, pd, wi, wo = random_rusinkiewicz(rng, 3000)
    w = np.mod(pd, np.pi) / np.pi * 180.0
    inner = w < 179.0  # the last phi_d interval wraps to k = 0 (tested below)
    got = src.eval(wi[inner], wo[inner]) / MERL_SCALE
    assert np.allclose(got[:, 0], np.sqrt(th[inner] / (np.pi / 2)) * 90.0, rtol=0, atol=1e-8)
    assert np.allclose(got[:, 1], td[inner] / (np.pi / 2) * 90.0, rtol=0, atol=1e-8)
    assert np.allclose(got[:, 2], w[inner], rtol=0, atol=1e-8)


def test_merl_index_conventions_nearest(merl_index_file, rng):
    """The "nearest" mode is BRDFRead.cpp's lookup: each index truncated."""
    src = open_merl(merl_index_file, interpolation="nearest")
    th, td, pd, wi, wo = random_rusinkiewicz(rng, 3000)
    u = np.sqrt(th / (np.pi / 2)) * 90.0
    v = td / (np.pi / 2) * 90.0
    w = np.mod(pd, np.pi) / np.pi * 180.0
    # Stay clear of integer boundaries, where rounding may pick either side.
    clear = [(np.abs(x - np.round(x)) > 1e-6) for x in (u, v, w)]
    keep = clear[0] & clear[1] & clear[2]
    got = src.eval(wi[keep], wo[keep]) / MERL_SCALE
    assert np.allclose(got[:, 0], np.floor(u[keep]), rtol=0, atol=1e-9)
    assert np.allclose(got[:, 1], np.floor(v[keep]), rtol=0, atol=1e-9)
    assert np.allclose(got[:, 2], np.floor(w[keep]), rtol=0, atol=1e-9)


def test_merl_phi_d_periodic_and_theta_clamped(merl_index_file):
    src = open_merl(merl_index_file)
    # phi_d at 179.5 degrees: halfway between k = 179 and k = 0 (phi_d = pi = 0 by reciprocity).
    th, td, pd = np.array([20.0]) * DEG, np.array([30.0]) * DEG, np.array([179.5]) * DEG
    wi, wo = dirs_from_angles(th, td, pd, [0.7])
    assert src.eval(wi, wo)[0, 2] / MERL_SCALE[2] == pytest.approx(0.5 * 179 + 0.5 * 0, abs=1e-8)
    # Past the last theta_h node (88.02 degrees) and theta_d node (89 degrees): held at the last node.
    wi, wo = dirs_from_angles([89.5 * DEG], [0.5 * DEG], [90.0 * DEG], [0.0])
    assert src.eval(wi, wo)[0, 0] / MERL_SCALE[0] == pytest.approx(89.0, abs=1e-8)
    wi, wo = dirs_from_angles([0.5 * DEG], [89.6 * DEG], [90.0 * DEG], [0.0])
    assert src.eval(wi, wo)[0, 1] / MERL_SCALE[1] == pytest.approx(89.0, abs=1e-8)


def test_merl_cell_centre_is_mean_of_corners(tmp_path, rng):
    """At the centre of a cell in index space, trilinear interpolation is the
    mean of the 8 corners, whatever the table."""
    stored = rng.random((3, 90, 90, 180))
    path = tmp_path / "random.binary"
    write_merl_bytes(path, stored)
    src = open_merl(path)
    for i, j, k in [(10, 20, 30), (44, 3, 100), (50, 30, 179)]:  # all above the horizon
        th = ((i + 0.5) / 90.0) ** 2 * np.pi / 2
        wi, wo = dirs_from_angles([th], [(j + 0.5) * DEG], [(k + 0.5) * DEG], [1.0])
        assert wi[0, 2] > 0 and wo[0, 2] > 0
        corners = [stored[:, i + a, j + b, (k + c) % 180] for a in (0, 1) for b in (0, 1) for c in (0, 1)]
        assert np.allclose(src.eval(wi, wo)[0], np.mean(corners, axis=0) * MERL_SCALE, rtol=1e-9)


# ---- MERL: round trip of a known BRDF ----------------------------------------

MERL_PARAMS = hb.AnalyticParams(kd=[0.2, 0.3, 0.5], eta=1.5, alpha=0.3)


@pytest.fixture(scope="module")
def merl_analytic_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("merl") / "analytic.binary"
    write_merl(path, analytic(MERL_PARAMS))
    return path


def test_merl_write_marks_unmeasurable_nodes_missing(merl_analytic_file):
    """write_merl(function) stores -1 exactly where a node direction is at or
    below the horizon (built here with rotation matrices)."""
    src = open_merl(merl_analytic_file)
    th = (np.arange(90) / 90.0) ** 2 * np.pi / 2
    j, k = np.arange(90) * DEG, np.arange(180) * DEG
    # one theta_h slice at a time keeps the matrix route fast enough
    for i in (0, 45, 80, 89):
        TD, PD = np.meshgrid(j, k, indexing="ij")
        wi, wo = dirs_from_angles(np.full(TD.size, th[i]), TD.ravel(), PD.ravel(), np.zeros(TD.size))
        below = (wi[:, 2] <= 1e-12) | (wo[:, 2] <= 1e-12)
        assert np.array_equal(src.missing[i].ravel(), below)
    assert src.n_missing == int(src.missing.sum()) > 0


def test_merl_roundtrip_within_interpolation_error(merl_analytic_file, rng):
    """Read-back against the analytic BRDF at cosine-weighted pairs.

    Tolerance from the grid: trilinear interpolation errs by at most
    sum_a (h_a^2 / 8) |d^2 f / da^2|. The GGX lobe (alpha = 0.3) has a relative
    curvature in theta_h of about 4 / alpha^2 = 44 rad^-2; inside it
    (theta_h < alpha) the square-root grid spaces theta_h by < 0.9 degrees
    (0.016 rad), so < 1.4e-3 relative; the 1-degree theta_d and phi_d steps
    move only Fresnel and Smith terms, which are flatter. Cells next to the
    horizon are filled from neighbours (first order), hence 1% of pairs may
    exceed the pointwise bound. The mean (SMAPE) must be well inside it.
    """
    src = open_merl(merl_analytic_file)
    n = 20000
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    truth = analytic(MERL_PARAMS)(wi, wo)
    got = src.eval(wi, wo)
    assert np.isfinite(got).all() and (got >= 0).all()
    err = np.abs(got - truth)
    within = (err <= 3e-3 * truth + 1e-4).all(axis=1)
    assert within.mean() >= 0.99, within.mean()
    s_lin = smape(truth, got)
    assert s_lin < 1e-3
    # The check resolves a 10% change of roughness: it fails for the wrong material.
    other = analytic(hb.AnalyticParams(kd=[0.2, 0.3, 0.5], eta=1.5, alpha=0.33))(wi, wo)
    assert smape(other, got) > 5e-3
    # The reference lookup (truncation) is first order: worse, but bounded by h |f'|.
    s_near = smape(truth, open_merl(merl_analytic_file, interpolation="nearest").eval(wi, wo))
    assert s_lin < s_near < 2e-2
    print(f"MERL read-back SMAPE: linear {s_lin:.2e}, nearest {s_near:.2e}; "
          f"max rel err {np.max(err / np.maximum(truth, 1e-3)):.2e}")


def test_merl_is_reciprocal(merl_analytic_file, rng):
    src = open_merl(merl_analytic_file)
    wi, wo = cosine_directions(rng, 5000), cosine_directions(rng, 5000)
    assert np.allclose(src.eval(wi, wo), src.eval(wo, wi), rtol=1e-9, atol=0)


def test_merl_source_attributes(merl_analytic_file):
    src = open_source(merl_analytic_file)
    assert isinstance(src, MERLSource)
    assert src.name == "analytic" and src.isotropic is True
    assert "MERL" in src.origin and src.path == os.fspath(merl_analytic_file)


# ---- MERL: missing cells -----------------------------------------------------


def test_merl_missing_cells_are_filled_from_neighbours(tmp_path, rng):
    stored = 1.0 + rng.random((3, 90, 90, 180))
    stored[:, 30:35, 40:45, :] = -1.0           # a block missing in every channel
    stored[1, 60, 60, 60] = -0.5                # one cell negative in G only: missing as a whole
    path = tmp_path / "holes.binary"
    write_merl_bytes(path, stored)
    src = open_merl(path, interpolation="nearest")
    assert src.n_missing == 5 * 5 * 180 + 1
    assert src.missing[30:35, 40:45].all() and src.missing[60, 60, 60]

    def at_node(i, j, k):
        th = ((i + 0.25) / 90.0) ** 2 * np.pi / 2  # inside cell (i, j, k): truncation picks it
        wi, wo = dirs_from_angles([th], [(j + 0.25) * DEG], [(k + 0.25) * DEG], [0.3])
        return src.eval(wi, wo)[0] / MERL_SCALE

    # A corner of the block touches two valid cells (i-1 and j-1): their mean.
    expect = 0.5 * (stored[:, 29, 40, 77] + stored[:, 30, 39, 77])
    assert np.allclose(at_node(30, 40, 77), expect, rtol=1e-12)
    # The lone cell: mean of its 6 valid neighbours, all channels.
    nb = [stored[:, 59, 60, 60], stored[:, 61, 60, 60], stored[:, 60, 59, 60],
          stored[:, 60, 61, 60], stored[:, 60, 60, 59], stored[:, 60, 60, 61]]
    assert np.allclose(at_node(60, 60, 60), np.mean(nb, axis=0), rtol=1e-12)
    # The centre of the block: filled from filled cells, inside the range of the valid data.
    centre = at_node(32, 42, 10)
    assert np.isfinite(centre).all() and (centre >= 1.0).all() and (centre <= 2.0).all()
    # No marker ever leaks into an evaluation.
    wi, wo = cosine_directions(rng, 20000), cosine_directions(rng, 20000)
    for mode in ("linear", "nearest"):
        f = open_merl(path, interpolation=mode).eval(wi, wo)
        assert np.isfinite(f).all() and (f >= 1.0 * MERL_SCALE.min()).all()


def test_merl_all_missing_is_an_error(tmp_path):
    path = tmp_path / "empty.binary"
    write_merl_bytes(path, -np.ones((3, 90, 90, 180)))
    with pytest.raises(BRDFFormatError, match="every MERL cell is missing"):
        open_merl(path)


# ---- MERL: malformed files -----------------------------------------------------


def check_malformed(path, data, message):
    """``data`` written to ``path`` is refused by open_source with a one-line error naming
    the path and matching ``message``."""
    path.write_bytes(data)
    with pytest.raises(BRDFFormatError, match=message) as info:
        open_source(path)
    assert info.value.path == os.fspath(path) and str(info.value).startswith(os.fspath(path) + ": ")


@pytest.fixture
def good_merl_bytes(rng):
    return np.asarray([90, 90, 180], "<i4").tobytes() + rng.random(3 * 90 * 90 * 180).astype("<f8").tobytes()


@pytest.mark.parametrize(
    "mutate,message",
    [
        (lambda b: b[:-100], "truncated MERL file"),
        (lambda b: b[:12], "truncated MERL file"),
        (lambda b: b[:7], "shorter than the 12-byte dims header"),
        (lambda b: b"", "shorter than the 12-byte dims header"),
        (lambda b: b + b"\0" * 8, "MERL file too long"),
        (lambda b: np.asarray([90, 90, 360], "<i4").tobytes() + b[12:], "dims header is 90 90 360"),
        (lambda b: np.asarray([180, 90, 90], "<i4").tobytes() + b[12:], "dims header is 180 90 90"),
        (lambda b: b[:12 + 8 * 1000] + np.float64(np.nan).tobytes() + b[12 + 8 * 1001:], "1 non-finite values"),
        (lambda b: b[:-8] + np.float64(np.inf).tobytes(), "channel B, theta_h index 89"),
    ],
)
def test_merl_malformed_files(tmp_path, good_merl_bytes, mutate, message):
    check_malformed(tmp_path / "bad.binary", mutate(good_merl_bytes), message)


@pytest.mark.parametrize("name,opener,kind", [("x.binary", open_merl, "MERL"), ("x.bin", open_utia, "UTIA")])
def test_a_folder_is_refused_by_name(tmp_path, name, opener, kind):
    folder = tmp_path / name
    folder.mkdir()
    with pytest.raises(BRDFFormatError, match=f"is a folder, not a {kind} file$"):
        opener(folder)


def test_merl_absent_file(tmp_path):
    with pytest.raises(BRDFFormatError, match="absent.binary: no such file$"):
        open_merl(tmp_path / "absent.binary")


def test_write_merl_checks_and_is_atomic(tmp_path):
    path = tmp_path / "t.binary"
    table = np.full((90, 90, 180, 3), 0.25)
    write_merl(path, table)
    assert path.stat().st_size == MERL_BYTES
    stored = np.frombuffer(path.read_bytes(), "<f8", offset=12).reshape(3, 90, 90, 180)
    assert np.allclose(stored[:, 5, 6, 7], 0.25 / MERL_SCALE)
    write_merl(path, table * 2)  # replaces the file; no temporary left behind
    assert sorted(os.listdir(tmp_path)) == ["t.binary"]
    with pytest.raises(ValueError, match="shape"):
        write_merl(tmp_path / "u.binary", np.zeros((90, 90, 90, 3)))
    bad = table.copy()
    bad[1, 2, 3, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        write_merl(tmp_path / "u.binary", bad)
    assert sorted(os.listdir(tmp_path)) == ["t.binary"]


# ---- UTIA: layout and conventions ----------------------------------------------


def utia_reference_index(c, ti, pi, tv, pv):
    """Flat index of the published reader (TBRDF.cpp / ALTA data_utia):
    isp*nr*nc + nc*(npi*iti + ipi) + npv*itv + ipv, nr = npi*nti, nc = npv*ntv."""
    nti = ntv = 6
    npi = npv = 48
    nr, nc = npi * nti, npv * ntv
    return c * nr * nc + nc * (npi * ti + pi) + npv * tv + pv


def test_utia_file_layout_matches_reference_reader(tmp_path, rng):
    """File value n = its own flat index; reading at node (ti, pi, tv, pv) must
    give, per channel, the index the reference formula computes."""
    path = tmp_path / "layout.bin"
    path.write_bytes(np.arange(3 * 6 * 48 * 6 * 48, dtype="<f8").tobytes())
    src = open_utia(path)
    n = 400
    ti, tv = rng.integers(1, 6, n), rng.integers(1, 6, n)  # theta = 0 has no azimuth
    pi, pv = rng.integers(0, 48, n), rng.integers(0, 48, n)
    wi = spherical_deg(15.0 * ti, 7.5 * pi)  # illumination: theta_i, phi_i
    wo = spherical_deg(15.0 * tv, 7.5 * pv)  # view: theta_v, phi_v
    got = src.eval(wi, wo)
    for c in range(3):
        assert np.allclose(got[:, c], utia_reference_index(c, ti, pi, tv, pv), rtol=0, atol=1e-6)
    # theta = 0 (the normal): azimuth index 0 by convention
    got0 = src.eval(spherical_deg(np.zeros(1), np.zeros(1)), spherical_deg([45.0], [30.0]))
    assert np.allclose(got0[0], [utia_reference_index(c, 0, 0, 3, 4) for c in range(3)], atol=1e-6)


def g_nonreciprocal(wi, wo):
    """A smooth, anisotropic, non-reciprocal test function: swapping wi and wo,
    or x and y, changes it."""
    return np.stack(
        [
            1.0 + 0.3 * wi[:, 0] + 0.1 * wo[:, 1],
            1.0 + 0.2 * wi[:, 1] * wo[:, 0] + 0.3 * wi[:, 2],
            2.0 + 0.5 * wo[:, 0] - 0.25 * wi[:, 1] + wo[:, 2] ** 2,
        ],
        axis=1,
    )


def test_utia_write_read_exact_at_nodes(tmp_path, rng):
    path = tmp_path / "g.bin"
    write_utia(path, g_nonreciprocal)
    assert path.stat().st_size == UTIA_BYTES
    src = open_utia(path)
    assert isinstance(src, UTIASource) and src.isotropic is False
    n = 400
    ti, tv = rng.integers(1, 6, n), rng.integers(1, 6, n)
    pi, pv = rng.integers(0, 48, n), rng.integers(0, 48, n)
    wi, wo = spherical_deg(15.0 * ti, 7.5 * pi), spherical_deg(15.0 * tv, 7.5 * pv)
    assert np.allclose(src.eval(wi, wo), g_nonreciprocal(wi, wo), rtol=1e-12, atol=0)
    # Illumination and view are not interchangeable: the swapped function differs.
    assert not np.allclose(src.eval(wi, wo), g_nonreciprocal(wo, wi), rtol=1e-3)
    # write_utia's table form and read_utia_table agree with each other and with the layout.
    table = rng.random((6, 48, 6, 48, 3))
    write_utia(path, table)
    assert np.array_equal(read_utia_table(path), table)
    flat = np.frombuffer(path.read_bytes(), "<f8")
    assert flat[utia_reference_index(2, 4, 10, 1, 47)] == table[4, 10, 1, 47, 2]


def test_utia_cell_centre_is_mean_of_corners_and_phi_wraps(tmp_path, rng):
    table = rng.random((6, 48, 6, 48, 3))
    path = tmp_path / "r.bin"
    write_utia(path, table)
    src = open_utia(path)
    for ti, pi, tv, pv in [(1, 5, 2, 30), (0, 47, 4, 47), (3, 0, 0, 12)]:
        wi = spherical_deg([15.0 * ti + 7.5], [7.5 * pi + 3.75])
        wo = spherical_deg([15.0 * tv + 7.5], [7.5 * pv + 3.75])
        corners = [table[ti + a, (pi + b) % 48, tv + c, (pv + d) % 48]
                   for a in (0, 1) for b in (0, 1) for c in (0, 1) for d in (0, 1)]
        assert np.allclose(src.eval(wi, wo)[0], np.mean(corners, axis=0), rtol=1e-12)


def test_utia_beyond_last_elevation(tmp_path, rng):
    table = rng.random((6, 48, 6, 48, 3))
    path = tmp_path / "r.bin"
    write_utia(path, table)
    wi = spherical_deg([82.5], [15.0])  # halfway from the last node (75) to the horizon
    wo = spherical_deg([30.0], [90.0])
    last, before = table[5, 2, 2, 12], table[4, 2, 2, 12]
    assert np.allclose(open_utia(path).eval(wi, wo)[0], last, rtol=1e-12)
    # The reference code extrapolates the 60-75 interval: 1.5 f(75) - 0.5 f(60).
    extrapolated = open_utia(path, theta_beyond="extrapolate").eval(wi, wo)[0]
    assert np.allclose(extrapolated, 1.5 * last - 0.5 * before, rtol=1e-12)
    with pytest.raises(ValueError, match="theta_beyond"):
        open_utia(path, theta_beyond="wrap")


# ---- UTIA: round trip of an anisotropic BRDF -----------------------------------

UTIA_PARAMS = hb.AnalyticParams(kd=[0.2, 0.3, 0.5], eta=1.5, alpha=(0.5, 0.25))
UTIA_ROTATED = hb.AnalyticParams(kd=[0.2, 0.3, 0.5], eta=1.5, alpha=(0.25, 0.5))


def test_utia_roundtrip_anisotropic_within_interpolation_error(tmp_path, rng):
    """Read-back against the analytic BRDF at cosine-weighted pairs with both
    elevations <= 75 degrees (inside the grid).

    Tolerance from the grid: quadrilinear interpolation errs by at most
    sum_a (h_a^2 / 8) |d^2 f / da^2|. The half vector moves by about half the
    direction step: <= 7.5 deg (0.13 rad) for a 15-degree elevation step and
    <= 3.75 deg (0.065 rad) for a 7.5-degree azimuth step. The lobe's relative
    curvature is about 4 / alpha_min^2 = 64 rad^-2, so the specular part may
    be off by up to (0.13^2 + 0.065^2) / 8 * 64 = 0.17 relative, inside the
    lobe only: 99% of pairs must be within 0.17 relative, and the mean (SMAPE)
    an order of magnitude below (0.02). The same read-back compared with the
    material rotated by 90 degrees must be clearly worse: the grid resolves
    the anisotropy and its orientation.
    """
    path = tmp_path / "aniso.bin"
    write_utia(path, analytic(UTIA_PARAMS))
    src = open_source(path)
    assert isinstance(src, UTIASource) and src.isotropic is False and src.name == "aniso"
    n = 40000
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    inside = (wi[:, 2] >= np.cos(75 * DEG)) & (wo[:, 2] >= np.cos(75 * DEG))
    wi, wo = wi[inside], wo[inside]
    truth = analytic(UTIA_PARAMS)(wi, wo)
    got = src.eval(wi, wo)
    rel = np.abs(got - truth) / truth
    assert np.quantile(rel, 0.99) < 0.17
    s = smape(truth, got)
    assert s < 0.02
    s_rot = smape(analytic(UTIA_ROTATED)(wi, wo), got)
    assert s_rot > 3 * s
    print(f"UTIA read-back SMAPE {s:.2e} (90-degree rotated material: {s_rot:.2e}); "
          f"relative error median {np.median(rel):.2e}, 99th percentile {np.quantile(rel, 0.99):.2e}")


def test_utia_grazing_clamped_stays_in_data_range(tmp_path, rng):
    path = tmp_path / "aniso.bin"
    write_utia(path, analytic(UTIA_PARAMS))
    wi, wo = cosine_directions(rng, 20000), cosine_directions(rng, 20000)
    f = open_utia(path).eval(wi, wo)
    assert np.isfinite(f).all() and (f >= 0).all()


# ---- UTIA: malformed files -------------------------------------------------------


@pytest.mark.parametrize(
    "mutate,message",
    [
        (lambda b: b[:-8], "truncated UTIA file"),
        (lambda b: b"", "truncated UTIA file: 0 bytes"),
        (lambda b: b + b"\0" * 8, "UTIA file too long"),
        (lambda b: np.float64(np.nan).tobytes() + b[8:], "channel R, theta_i 0, phi_i 0"),
        (lambda b: b[:-8] + np.float64(-np.inf).tobytes(), "1 non-finite values"),
    ],
)
def test_utia_malformed_files(tmp_path, rng, mutate, message):
    check_malformed(tmp_path / "bad.bin", mutate(rng.random(3 * 6 * 48 * 6 * 48).astype("<f8").tobytes()), message)


def test_utia_writer_checks(tmp_path):
    with pytest.raises(ValueError, match="shape"):
        write_utia(tmp_path / "y.bin", np.zeros((3, 6, 48, 6, 48)))
    with pytest.raises(ValueError, match="non-finite"):
        write_utia(tmp_path / "y.bin", lambda wi, wo: np.full((len(wi), 3), np.nan))
    assert not (tmp_path / "y.bin").exists()
