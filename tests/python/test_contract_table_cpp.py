"""spec/activation_combine.json reproduced by libhybridbrdf, row by row, on both inference paths:
the scalar one (model_math.hpp's activate() and combine(), as HybridModel::eval runs them) and
the batched one (the per-lane functions of the kernel Model.eval runs: the portable kernel's,
AVX2+FMA's and AVX-512's, each where this CPU has it), with lanes filled with the table's rows,
counts that are not a multiple of the vector width included. A row passes when
|got - want| <= rel_tol[kind] * |want| + abs_tol (the table's _doc)."""

import json
import pathlib

import numpy as np
import pytest

from hybridbrdf import _core

ROOT = pathlib.Path(__file__).resolve().parents[2]
TABLE = json.loads((ROOT / "spec" / "activation_combine.json").read_text())
KERNELS = ["baseline", "avx2+fma", "avx512"]
CASES = ([("activation", name) for name in sorted(TABLE["activations"])] +
         [("combine", name) for name in sorted(TABLE["combines"])])


def rows_of(kind, name):
    """(inputs float32 (N, k), want float64 (N,)) of one table."""
    rows = np.asarray(TABLE["activations" if kind == "activation" else "combines"][name], dtype=np.float64)
    inputs = rows[:, :-1].astype(np.float32)
    assert np.array_equal(inputs.astype(np.float64), rows[:, :-1]), "the table's inputs are float32 values"
    return inputs, rows[:, -1]


def failures(kind, name, inputs, want, got):
    """One line per row outside the table's tolerance."""
    got = got.astype(np.float64)
    with np.errstate(invalid="ignore"):
        ok = (got == want) | (np.abs(got - want) <= TABLE["rel_tol"][kind] * np.abs(want) + TABLE["abs_tol"])
    return [f"{name}{tuple(inputs[i].tolist())}: got {got[i]!r}, want {want[i]!r}" for i in np.flatnonzero(~ok)]


@pytest.fixture(params=[("scalar", None)] + [("batched", k) for k in KERNELS],
                ids=["scalar"] + [f"batched-{k}" for k in KERNELS])
def path(request):
    """The path to check; a batched kernel this CPU (or HBRDF_SIMD) does not run is skipped."""
    name, kernel = request.param
    if kernel is not None:
        _core.limit_model_simd(kernel)
        if _core.model_simd_path() != kernel:
            _core.limit_model_simd("avx512")
            pytest.skip(f"this process does not run the {kernel} kernel")
    yield name
    _core.limit_model_simd("avx512")


@pytest.mark.parametrize("kind, name", CASES, ids=[f"{k}-{n}" for k, n in CASES])
def test_every_row(kind, name, path):
    inputs, want = rows_of(kind, name)
    got = _core._contract_math(kind, name, inputs, path)
    assert got.shape == want.shape
    bad = failures(kind, name, inputs, want, got)
    assert not bad, f"{len(bad)} of {len(want)} rows off on the {path} path:\n" + "\n".join(bad[:20])


@pytest.mark.parametrize("kind, name", CASES, ids=[f"{k}-{n}" for k, n in CASES])
def test_lanes_are_independent(kind, name, path):
    """Any count (1 to 17 rows: every remainder of 8 and 16 lanes) and any lane a row lands in
    give that row the same value, bit for bit."""
    inputs, want = rows_of(kind, name)
    whole = _core._contract_math(kind, name, inputs, path)
    for n in range(1, 18):
        got = _core._contract_math(kind, name, inputs[:n], path)
        np.testing.assert_array_equal(got, whole[:n], err_msg=f"first {n} rows")
    for shift in (1, 3, 7, 13):
        got = _core._contract_math(kind, name, np.roll(inputs, shift, axis=0), path)
        np.testing.assert_array_equal(got, np.roll(whole, shift), err_msg=f"rows moved {shift} lanes")


def test_table_names_every_activation_and_rule():
    from hybridbrdf import spec
    assert set(TABLE["activations"]) == set(spec.ACTIVATIONS), "an activation without rows"
    assert set(TABLE["combines"]) == set(spec.COMBINES), "a combine rule without rows"


@pytest.mark.parametrize("args", [
    ("softplus", "relu", np.zeros((2, 1), np.float32), "scalar"),
    ("activation", "gelu", np.zeros((2, 1), np.float32), "scalar"),
    ("combine", "mul", np.zeros((2, 4), np.float32), "batched"),
    ("activation", "relu", np.zeros((2, 1), np.float32), "vector"),
    ("combine", "gated", np.zeros((2, 3), np.float32), "scalar"),
], ids=["kind", "activation", "rule", "path", "arity"])
def test_hook_refuses_unknown_arguments(args):
    with pytest.raises(ValueError):
        _core._contract_math(*args)
