"""Fitting on a CUDA device (docs/FITTING.md, "Fitting on a GPU"): run wherever torch sees a GPU,
skipped with a reason everywhere else (this project's CI machine has none).

A CUDA fit must give the CPU fit's model up to float rounding (same seed, same batches: the batch
indices are drawn on the CPU generator whatever the device), write a model file that the CPU
loaders and the C++ library read, resume from a checkpoint, and, on two GPUs, run data-parallel
over NCCL under torchrun."""

import os
import subprocess
import sys

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.fit import fit

CUDA = torch.cuda.is_available()
pytestmark = pytest.mark.skipif(not CUDA, reason="no CUDA device visible to torch")

SOURCES = ["synthetic:gold", "synthetic:plastic", "synthetic:brushed_aluminium"]


def settings(device: str, steps: int = 400) -> FitSettings:
    return FitSettings(width=16, depth=2, steps=steps, batch=512, pool=16384, eval_pairs=50_000, seed=5,
                       device=device)


def fitted(device: str, **kw):
    sources = [hb.open_source(s) for s in SOURCES]
    return fit(sources, settings(device), progress=False, log=lambda msg: None, **kw)


def test_cuda_fit_matches_the_cpu_fit(tmp_path):
    cpu, gpu = fitted("cpu"), fitted("cuda")
    # 400 AdamW steps of float32 arithmetic in another order (cuBLAS, fused kernels): the weights
    # drift apart by rounding only; a wrong batch, seed or device copy moves them by O(0.1).
    worst = max(float(np.max(np.abs(cpu.tensors[k] - gpu.tensors[k]))) for k in cpu.tensors)
    assert worst < 5e-3, worst
    for a, b in zip(cpu.material_info, gpu.material_info):
        assert abs(a["metrics"]["smape"] - b["metrics"]["smape"]) < 0.01 * max(a["metrics"]["smape"], 1e-3)
    # The model file of a GPU fit is an ordinary model file: CPU loaders and the C++ library read it.
    path = tmp_path / "gpu.safetensors"
    gpu.save_checked(str(path))
    back = hb.load_model(str(path))
    wi = np.array([[0.3, 0.1, 0.95]]); wo = np.array([[-0.2, 0.3, 0.93]])
    np.testing.assert_allclose(back.eval(wi, wo, back.materials[0]), gpu.eval(wi, wo, gpu.materials[0]),
                               rtol=1e-5)


def test_cuda_fit_resumes_from_a_checkpoint(tmp_path):
    ck = str(tmp_path / "ck.pt")
    whole = fitted("cuda")
    sources = [hb.open_source(s) for s in SOURCES]
    assert fit(sources, settings("cuda"), checkpoint=ck, stop_after=150, progress=False,
               log=lambda msg: None) is None
    resumed = fit(sources, settings("cuda"), checkpoint=ck, resume=True, progress=False, log=lambda msg: None)
    worst = max(float(np.max(np.abs(whole.tensors[k] - resumed.tensors[k]))) for k in whole.tensors)
    assert worst < 1e-4, worst


@pytest.mark.skipif(torch.cuda.device_count() < 2, reason="NCCL data-parallel needs two GPUs")
def test_two_gpus_over_nccl(tmp_path):
    args = ["fit", *SOURCES, "--mlp", "16x2", "--batch", "512", "--pool", "16384", "--eval-pairs", "20000",
            "--steps", "300", "--seed", "3", "--device", "cuda", "--quiet"]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    one = subprocess.run([sys.executable, "-m", "hybridbrdf.cli", *args, "--out", "one.safetensors"],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    two = subprocess.run([sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2",
                          "-m", "hybridbrdf.cli", *args, "--out", "two.safetensors"],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert one.returncode == 0, one.stderr
    assert two.returncode == 0, two.stderr
    a, b = hb.load_model(str(tmp_path / "one.safetensors")), hb.load_model(str(tmp_path / "two.safetensors"))
    worst = max(float(np.max(np.abs(a.tensors[k] - b.tensors[k]))) for k in a.tensors)
    assert worst < 5e-3, worst
