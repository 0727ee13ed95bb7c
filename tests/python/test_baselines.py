"""The C++ baselines of the cost table (hybridbrdf/baselines.hpp) compute what the
Python readers compute: _core.MerlTable is the MERL reader's nearest-cell lookup
(BRDFRead.cpp's) and _core.NbrdfNetwork the NBRDF reader's network, on a random
table and on a published network of ../shared/data; bad shapes are refused."""

import pathlib

import numpy as np
import pytest

from hybridbrdf import _core
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.sources.merl import MERL_DIMS, MERL_SCALES, MERLSource
from hybridbrdf.sources.nbrdf import open_nbrdf

from helpers import hard_pairs, valid_upper

NBRDF = pathlib.Path(__file__).resolve().parents[3] / "shared" / "data" / "nbrdf" / "merl" / "alum-bronze.h5"


def _pairs(n, seed):
    rng = np.random.default_rng(seed)
    return cosine_directions(rng, n).astype(np.float32), cosine_directions(rng, n).astype(np.float32)


def test_merl_table_is_the_readers_nearest_lookup():
    rng = np.random.default_rng(1)
    raw = rng.random((3, *MERL_DIMS)) * 1500.0  # stored values; the reader applies MERL_SCALES
    src = MERLSource(raw, interpolation="nearest")
    table = _core.MerlTable(np.moveaxis(raw, 0, -1) * MERL_SCALES)
    assert table.memory_bytes == 90 * 90 * 180 * 3 * 4
    wi, wo = _pairs(200_000, 2)
    got = table.eval(wi, wo)
    ref = src.eval(wi.astype(np.float64), wo.astype(np.float64))
    same = np.all(np.isclose(got, ref, rtol=1e-6), axis=1)
    # Cell indices come from float32 angles here and float64 there: a pair within rounding of
    # a cell boundary may land in the neighbouring cell, nothing more.
    assert same.mean() > 0.999, same.mean()
    # Hard inputs: finite, and 0 wherever a direction is at or below the horizon or invalid.
    hwi, hwo = hard_pairs()
    f = table.eval(hwi, hwo)
    assert np.isfinite(f).all() and (f[~(valid_upper(hwi) & valid_upper(hwo))] == 0).all()


@pytest.mark.skipif(not NBRDF.exists(), reason="needs ../shared/data/nbrdf")
def test_nbrdf_network_is_the_readers_network():
    src = open_nbrdf(NBRDF)
    net = _core.NbrdfNetwork([(k.T.astype(np.float32), b.astype(np.float32)) for _, k, b, _ in src.layers])
    assert net.memory_bytes == 4 * sum(k.size + b.size for _, k, b, _ in src.layers)
    wi, wo = _pairs(50_000, 3)
    got = net.eval(wi, wo).astype(np.float64)
    ref = src.eval(wi.astype(np.float64), wo.astype(np.float64))
    rel = np.abs(got - ref) / np.maximum(np.abs(ref), 1e-3)
    assert rel.max() < 1e-4, rel.max()
    hwi, hwo = hard_pairs()
    f = net.eval(hwi, hwo)
    assert np.isfinite(f).all() and (f >= 0).all() and (f[~(valid_upper(hwi) & valid_upper(hwo))] == 0).all()


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match="90 x 90 x 180"):
        _core.MerlTable(np.zeros(10, dtype=np.float32))
    w = np.zeros((21, 5), dtype=np.float32)
    with pytest.raises(ValueError, match="takes 5 inputs, expected 6"):
        _core.NbrdfNetwork([(w, np.zeros(21, dtype=np.float32))])
    with pytest.raises(ValueError, match="expected 3"):
        _core.NbrdfNetwork([(np.zeros((4, 6), dtype=np.float32), np.zeros(4, dtype=np.float32))])
