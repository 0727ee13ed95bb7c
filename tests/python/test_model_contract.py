"""The model contract (spec/model.json) holds in both languages.

- The generated files (cpp/include/hybridbrdf/spec.hpp, python/hybridbrdf/spec.py) are current.
- Both loaders reject every file of the shared table tests/data/malformed_models.json, with the
  same words where the table says so.
- The container: a file written by the safetensors package is read by libhybridbrdf bit for bit,
  and a file laid out by hand from the safetensors specification is read by both.
- Every value the file records is honoured: arch.pre_exp_max bounds exp() in PyTorch, in the C++
  scalar and batched paths, and in generated code.
"""

import json
import math
import os
import pathlib
import struct
import subprocess
import sys

import numpy as np
import pytest
import safetensors.numpy
import torch

import hybridbrdf as hb
from hybridbrdf import _core, spec
from hybridbrdf.model import energy
from hybridbrdf.model.file import HybridModel
from hybridbrdf.model.networks import build_model

ROOT = pathlib.Path(__file__).resolve().parents[2]
TABLE = json.loads((ROOT / "tests" / "data" / "malformed_models.json").read_text())


def test_generated_spec_files_are_current():
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "gen_spec.py"), "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_python_and_cpp_read_the_same_contract():
    assert spec.CONVENTIONS_VERSION == _core.CONVENTIONS_VERSION
    assert (spec.ALPHA_MIN, spec.ALPHA_MAX, spec.ETA_MIN, spec.ETA_MAX) == (
        _core.ALPHA_MIN, _core.ALPHA_MAX, _core.ETA_MIN, _core.ETA_MAX)


def base_model(base=TABLE["base"], output_layer="shared", arch=None) -> HybridModel:
    torch.manual_seed(0)
    mod = build_model(arch or base["arch"], base["materials"], base["width"], base["depth"], base["latent"], "hardgelu",
                      base["isotropic"], output_layer=output_layer)
    with torch.no_grad():
        for p in mod.parameters():
            p.add_(torch.randn_like(p) * 0.3)
    n = base["materials"]
    return HybridModel.from_module(mod, [f"mat-{i}" for i in range(n)], ["test"] * n, {"steps": 0})


def _value(v):
    return {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}.get(v, v) if isinstance(v, str) else v


def write_case(case, good: pathlib.Path, bad: pathlib.Path) -> None:
    """Apply one row's edits to the good file and write the result."""
    if any(key.startswith("header_") for key in case):
        bad.write_bytes(edit_container_header(case, good.read_bytes()))
        return
    if "bytes" in case:
        raw = good.read_bytes()
        how = case["bytes"]
        if how == "empty":
            data = b""
        elif how.startswith("first:"):
            data = raw[:int(how.split(":")[1])]
        elif how.startswith("append:"):
            data = raw + b"\0" * int(how.split(":")[1])
        elif how.startswith("drop_last:"):
            data = raw[:-int(how.split(":")[1])]
        else:  # header_not_json: a header of the right length that is not JSON
            (hlen,) = struct.unpack("<Q", raw[:8])
            data = raw[:8] + b"!" * hlen + raw[8 + hlen:]
        bad.write_bytes(data)
        return
    with safetensors.safe_open(str(good), framework="numpy") as f:
        meta = dict(f.metadata())
        tensors = {k: f.get_tensor(k) for k in f.keys()}
    doc = json.loads(meta["hybridbrdf"])
    if "doc_set" in case:
        keys, value = case["doc_set"]
        target = doc
        for k in keys[:-1]:
            target = target[k]
        target[keys[-1]] = value
    if "doc_delete" in case:
        keys = case["doc_delete"]
        target = doc
        for k in keys[:-1]:
            target = target[k]
        del target[keys[-1]]
    meta["hybridbrdf"] = json.dumps(doc)
    if "meta_raw" in case:
        if case["meta_raw"] is None:
            del meta["hybridbrdf"]
        else:
            meta["hybridbrdf"] = case["meta_raw"]
    if "tensor_set" in case:
        name, index, value = case["tensor_set"]
        tensors[name] = tensors[name].copy()
        tensors[name][tuple(index)] = _value(value)
    if "tensor_drop" in case:
        del tensors[case["tensor_drop"]]
    if "tensor_new" in case:
        name, shape = case["tensor_new"]
        tensors[name] = np.zeros(shape, np.float32)
    if "tensor_dtype" in case:
        name, dtype = case["tensor_dtype"]
        tensors[name] = tensors[name].astype(dtype)
    bad.write_bytes(safetensors.numpy.save(tensors, meta))


def edit_container_header(case, raw: bytes) -> bytes:
    """The file ``raw`` with its safetensors header edited as the row says, the tensor data kept:
    header_set [[key...], value], header_floats [key...] (a list of integers as floats) and
    header_append [[key...], value] on the parsed header, in that order, serialised by json.dumps;
    then header_text [[op, text...], ...] on that text: ["prefix", t], ["suffix", t] or
    ["replace", old, new] (the first occurrence, which must exist, so a row cannot go stale)."""
    (hlen,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8:8 + hlen])

    def parent(keys):
        target = header
        for k in keys[:-1]:
            target = target[k]
        return target

    if "header_set" in case:
        keys, value = case["header_set"]
        parent(keys)[keys[-1]] = value
    if "header_floats" in case:
        keys = case["header_floats"]
        parent(keys)[keys[-1]] = [float(v) for v in parent(keys)[keys[-1]]]
    if "header_append" in case:
        keys, value = case["header_append"]
        parent(keys)[keys[-1]].append(value)
    text = json.dumps(header)
    for op, *args in case.get("header_text", []):
        if op == "prefix":
            text = args[0] + text
        elif op == "suffix":
            text = text + args[0]
        else:
            assert op == "replace" and args[0] in text, (op, args)
            text = text.replace(args[0], args[1], 1)
    data = text.encode("utf-8")
    return struct.pack("<Q", len(data)) + data + raw[8 + hlen:]


@pytest.fixture(scope="module")
def good_files(tmp_path_factory):
    """The table's base file, with the shared output layer and with material output layers (a
    case with "output_layer": "material" starts from the second)."""
    folder = tmp_path_factory.mktemp("contract")
    out = {}
    for output_layer in ("shared", "material"):
        out[output_layer] = folder / f"good_{output_layer}.safetensors"
        base_model(output_layer=output_layer).save(out[output_layer])
    # A case with "energy_bound": true starts from the base with energy-bound tables.
    table = np.linspace(0.25, 1.0, 3 * spec.ENERGY_NODES, dtype=np.float32).reshape(3, spec.ENERGY_NODES)
    out["energy"] = folder / "good_energy.safetensors"
    energy.attach(base_model(), table).save(out["energy"])
    # A case with "arch": "hybrid-reciprocal" starts from that architecture's base (format_version 2).
    out["hybrid-reciprocal"] = folder / "good_reciprocal.safetensors"
    base_model(arch="hybrid-reciprocal").save(out["hybrid-reciprocal"])
    return out


def _base_file(good_files, case):
    if "arch" in case:
        return good_files[case["arch"]]
    return good_files["energy" if case.get("energy_bound") else case.get("output_layer", "shared")]


@pytest.fixture(scope="module")
def good_file(good_files):
    return good_files["shared"]


@pytest.mark.parametrize("case", TABLE["cases"], ids=[c["name"] for c in TABLE["cases"]])
def test_both_loaders_reject_each_malformed_file_alike(tmp_path, good_files, case):
    bad = tmp_path / "bad.safetensors"
    write_case(case, _base_file(good_files, case), bad)
    with pytest.raises(hb.ModelFileError) as py_err:
        hb.load_model(bad)
    with pytest.raises(hb.ModelFileError) as cpp_err:  # libhybridbrdf's errors are the same type
        _core.Model(str(bad))
    for lang, err in (("python", py_err), ("cpp", cpp_err)):
        text = str(err.value)
        assert text.startswith(f"{bad}: "), (lang, text)
        assert "\n" not in text, (lang, text)
        problem = text[len(f"{bad}: "):]
        if "problem" in case:
            assert problem == case["problem"], (lang, problem)
        else:
            assert case["contains"][lang] in problem, (lang, problem)


def test_the_base_files_of_the_table_are_valid(good_files):
    for path in good_files.values():
        assert hb.load_model(path).materials == _core.Model(str(path)).materials
    heads = hb.load_model(good_files["material"])
    assert heads.arch["output_layer"] == "material" and "mlp.out.weight" not in heads.tensors


def test_a_file_written_by_the_safetensors_package_is_read_by_cpp_bit_exactly(tmp_path):
    for arch, output_layer in (("hybrid", "shared"), ("analytic-input", "shared"), ("neural", "shared"),
                               ("hybrid", "material")):
        torch.manual_seed(1)
        mod = build_model(arch, 4, 8, 3, 12 if arch == "neural" else 4, "relu", [True, False, False, True],
                          output_layer=output_layer)
        with torch.no_grad():
            for p in mod.parameters():
                p.add_(torch.randn_like(p))
        model = HybridModel.from_module(mod, list("abcd"), ["t"] * 4, {})
        path = tmp_path / f"{arch}_{output_layer}.safetensors"
        model.save(path)
        read = _core.Model(str(path)).tensors()
        expected = {k: v for k, v in model.tensors.items() if not k.startswith("frames.")}
        assert set(read) == set(expected), arch
        for k, v in expected.items():
            assert read[k].shape == v.shape and read[k].tobytes() == v.tobytes(), (arch, k)


def test_a_file_laid_out_from_the_format_specification_is_read_by_both(tmp_path):
    """Written here from the safetensors layout alone (8-byte length, JSON header with
    data_offsets, data), without either codec: both readers must see the same bits."""
    model = base_model()
    header, blobs, offset = {"__metadata__": {"hybridbrdf": json.dumps(model.header())}}, [], 0
    for name in sorted(model.tensors, reverse=True):  # any order the format allows
        data = np.ascontiguousarray(model.tensors[name], dtype="<f4").tobytes()
        header[name] = {"dtype": "F32", "shape": list(model.tensors[name].shape), "data_offsets": [offset, offset + len(data)]}
        blobs.append(data)
        offset += len(data)
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 8)
    path = tmp_path / "by_hand.safetensors"
    path.write_bytes(struct.pack("<Q", len(text)) + text + b"".join(blobs))
    py = hb.load_model(path)
    cpp = _core.Model(str(path)).tensors()
    for k, v in model.tensors.items():
        assert py.tensors[k].tobytes() == v.tobytes() and cpp[k].tobytes() == v.tobytes(), k


@pytest.mark.parametrize("arch", ["hybrid", "logmul", "neural"])
def test_the_recorded_pre_exp_max_bounds_every_reader(tmp_path, arch):
    """Output layer: weights 0, biases 10 on the exp() channels and -60 on the gate, so
    f = exp(min(10, bound)) (+ a gate of 1e-26 times f_a; logmul: f_a exp(min(10, bound)))."""
    torch.manual_seed(2)
    latent = 12 if arch == "neural" else 4
    mod = build_model(arch, 1, 8, 2, latent, "hardgelu", pre_exp_max=2.0)
    with torch.no_grad():
        mod.mlp.out.weight.zero_()
        mod.mlp.out.bias.copy_(torch.tensor([10.0, 10.0, 10.0, -60.0, -60.0, -60.0][:mod.mlp.out.bias.numel()]))
    model = HybridModel.from_module(mod, ["m"], ["t"], {})
    assert model.arch["pre_exp_max"] == 2.0
    path = tmp_path / "bound.safetensors"
    model.save(path)
    rng = np.random.default_rng(0)
    wi = np.abs(rng.normal(size=(64, 3))) + [0, 0, 0.2]
    wo = np.abs(rng.normal(size=(64, 3))) + [0, 0, 0.2]
    loaded = hb.load_model(path)
    scale = loaded.eval_analytic(wi, wo, "m", dtype=torch.float64) if arch == "logmul" else 1.0
    expected = math.exp(2.0) * scale
    cpp = _core.Model(str(path))
    assert cpp.pre_exp_max == 2.0
    for got in (loaded.eval(wi, wo, "m", dtype=torch.float64), cpp.eval(wi, wo, 0), cpp.eval_scalar(wi, wo, 0)):
        assert np.allclose(got, expected, rtol=1e-5), (arch, float(np.max(got)))
    from hybridbrdf.codegen.main import generate

    for target in ("glsl", "hlsl", "cpp"):
        assert "HBRDF_PRE_EXP_MAX = 2.0f;" in generate(loaded, target), target


def test_the_library_raises_the_packages_model_file_error(tmp_path):
    bad = tmp_path / "bad\udcff.safetensors"  # a path with an undecodable byte round-trips
    bad.write_bytes(b"\x10\x00\x00\x00\x00\x00\x00\x00{\"a\xff\x01\": 1, }xxxxxxxxxxx")
    assert _core.ModelFileError is hb.ModelFileError
    with pytest.raises(hb.ModelFileError) as err:
        _core.Model(str(bad))
    assert err.value.path == str(bad)
    assert "\n" not in str(err.value) and "\x01" not in err.value.problem and "\ufffd" not in err.value.problem
    str(err.value).encode("utf-8", "surrogateescape")  # printable: no raw bytes that could not be shown


# ---- the file's size, checked before its data is read -------------------------

_MEMORY_PROBE = r"""
import resource, sys
import hybridbrdf as hb
from hybridbrdf import _core
loader = {"python": hb.load_model, "cpp": lambda p: _core.Model(p)}[sys.argv[1]]
if len(sys.argv) > 3:  # an address-space cap this far above what the process holds now
    with open("/proc/self/statm") as fh:
        held = int(fh.read().split()[0]) * resource.getpagesize()
    cap = held + int(sys.argv[3])
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
try:
    loader(sys.argv[2])
    print("ACCEPTED")
except hb.ModelFileError as exc:
    print(str(exc))
print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024)
"""


def _load_in_child(lang, path, address_headroom=None):
    """(message, peak resident growth in bytes) of loading ``path`` in a fresh process."""
    args = [sys.executable, "-c", _MEMORY_PROBE, lang, str(path)] + ([str(address_headroom)] if address_headroom else [])
    r = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stderr.strip() == "", (lang, r.returncode, r.stderr[-2000:])
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 2, (lang, r.stdout)
    return lines[0], int(lines[1])


def test_a_sparse_file_much_longer_than_its_header_declares_costs_no_memory(tmp_path, good_file):
    """1.5 GB on paper, a few KB on disk: libhybridbrdf once read it whole (1.77 GB resident)
    before finding the data section longer than the header declares."""
    path = tmp_path / "sparse.safetensors"
    path.write_bytes(good_file.read_bytes())
    extra = 1_500_000_000
    os.truncate(path, path.stat().st_size + extra)
    for lang in ("python", "cpp"):
        message, grown = _load_in_child(lang, path)
        assert message.startswith(f"{path}: "), (lang, message)
        if lang == "cpp":
            assert message == f"{path}: safetensors data section has {extra} bytes after the last tensor"
        assert grown < 200_000_000, (lang, grown)


def test_a_file_longer_than_any_model_the_contract_allows_is_refused_from_its_size(tmp_path, good_file):
    path = tmp_path / "huge.safetensors"
    path.write_bytes(good_file.read_bytes())
    limit = 8 + spec.MAX_HEADER_BYTES + spec.MAX_DATA_BYTES
    os.truncate(path, limit + 1)  # sparse: nothing is written
    expected = f"{path}: model file too long: {limit + 1} bytes (a model file is at most {limit} bytes)"
    for lang in ("python", "cpp"):
        message, grown = _load_in_child(lang, path)
        assert message == expected, (lang, message)
        assert grown < 200_000_000, (lang, grown)


def test_a_well_formed_file_too_big_for_the_memory_at_hand_is_an_error_not_bad_alloc(tmp_path, good_file):
    """A header that declares 1 GiB of tensor data, laid out exactly (a sparse file), loaded with
    only 256 MiB of address space to spare: a one-line error, never std::bad_alloc or MemoryError."""
    raw = good_file.read_bytes()
    (hlen,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8:8 + hlen])
    data_len = len(raw) - 8 - hlen
    big = 1 << 30
    header["zzz.padding"] = {"dtype": "F32", "shape": [big // 4], "data_offsets": [data_len, data_len + big]}
    text = json.dumps(header).encode()
    path = tmp_path / "big.safetensors"
    path.write_bytes(struct.pack("<Q", len(text)) + text + raw[8 + hlen:])
    os.truncate(path, 8 + len(text) + data_len + big)
    expected = f"{path}: needs {data_len + big} bytes of tensor data, more than this process could allocate"
    for lang in ("python", "cpp"):
        message, _ = _load_in_child(lang, path, address_headroom=256 << 20)
        assert message == expected, (lang, message)
