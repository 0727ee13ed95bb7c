"""Joint fitting of a collection of BRDFs (paper Sec. 3.3, docs/CONVENTIONS.md "Fitting").

    loss = sum_materials mean_batch  L(f_ref, f_a) + L(f_ref, f_t)
    L(f1, f2) = || log(1 + cos(theta_i) f1) - log(1 + cos(theta_i) f2) ||^2   (squared norm over RGB)

Each step draws one batch of direction pairs (cosine-weighted, wi and wo
independent) from a training pool and evaluates every material on it. The pool
holds every source's values at ``pool`` pairs, computed once (readers can be
slow; the network is fast). Measured negatives (noise) are clamped to 0.

AdamW (network weights with weight decay 0.01, per-material parameters without:
decay would pull kd, eta, alpha towards the middle of their ranges), learning
rate 5e-3 with cosine decay to 0 over the run, gradient-norm clipping at 0.01.
The neural baseline has no analytic term in its loss.

Sparse fitting (paper Sec. 4.2): ``frozen=<HybridModel>`` keeps that model's
network and fits only (p, z) of the given materials, each started from the frozen
model's best-fitting material (FitSettings.sparse_init).
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
import torch

from hybridbrdf import checkpoint as ckpt
from hybridbrdf import distributed as dd
from hybridbrdf import spec
from hybridbrdf.errors import InputFileError
from hybridbrdf.metrics import cmae, cosine_hemisphere, metric_directions, smape
from hybridbrdf.model_file import HybridModel
from hybridbrdf.models import build_model
from hybridbrdf.names import name_problem, names_problem
from hybridbrdf.sources.base import BRDFSource
from hybridbrdf.util import check_writable


from hybridbrdf.fit_settings import SPARSE_INITS, FitSettings, positive_int  # noqa: F401  (re-exported)

def default_device() -> str:
    return "cuda" if torch.cuda.is_available() else "cpu"


def specular_pairs(rng: np.random.Generator, n: int, alpha: float) -> Tuple[np.ndarray, np.ndarray]:
    """n direction pairs (wi, wo) near the mirror configuration: wo cosine-weighted, a half vector
    h drawn from the GGX distribution D(h) cos(theta_h) of roughness ``alpha`` (Walter et al. 2007,
    Eq. 35-36: tan^2 theta_h = alpha^2 u / (1 - u)), wi = reflect(wo, h). Pairs whose wi falls
    below the horizon are redrawn; wi and wo swap roles at random so that the set is symmetric
    under reciprocity. float64 (n,3) each."""
    wi_out = np.empty((0, 3))
    wo_out = np.empty((0, 3))
    while len(wi_out) < n:
        m = 2 * (n - len(wi_out)) + 64  # ~half survive at grazing wo; draw extra
        wo = cosine_hemisphere(rng, m)
        u1, u2 = rng.random(m), rng.random(m)
        tan2 = alpha * alpha * u1 / np.maximum(1.0 - u1, 1e-12)
        cos_h = 1.0 / np.sqrt(1.0 + tan2)
        sin_h = np.sqrt(np.maximum(0.0, 1.0 - cos_h * cos_h))
        phi = 2.0 * np.pi * u2
        h = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], axis=1)
        wi = 2.0 * np.sum(wo * h, axis=1, keepdims=True) * h - wo
        keep = wi[:, 2] > 1e-4
        wi_out = np.concatenate([wi_out, wi[keep]])
        wo_out = np.concatenate([wo_out, wo[keep]])
    wi_out, wo_out = wi_out[:n], wo_out[:n]
    wi_out /= np.linalg.norm(wi_out, axis=1, keepdims=True)
    swap = rng.random(n) < 0.5
    wi_out[swap], wo_out[swap] = wo_out[swap].copy(), wi_out[swap].copy()
    return wi_out, wo_out


class TrainingPool:
    """Direction pairs and every source's reference values on them (float32).

    A fraction ``specular`` of the pairs comes from :func:`specular_pairs` (half vectors
    concentrated around the normal, where glossy materials put their energy), the rest is
    cosine-weighted as in the paper."""

    def __init__(self, sources: Sequence[BRDFSource], n_pairs: int, seed: int,
                 progress: Optional[Callable[[str], None]] = None,
                 specular: float = 0.0, specular_alpha: float = 0.1):
        rng = np.random.default_rng(seed + 1_000_003)
        wi = cosine_hemisphere(rng, n_pairs)
        wo = cosine_hemisphere(rng, n_pairs)
        n_spec = int(round(specular * n_pairs))
        if n_spec > 0:
            # The cosine pairs come first and are unchanged, so specular = 0 reproduces earlier pools.
            wi[n_pairs - n_spec:], wo[n_pairs - n_spec:] = specular_pairs(rng, n_spec, specular_alpha)
        ref = np.empty((len(sources), n_pairs, 3), dtype=np.float32)
        for m, src in enumerate(sources):
            if progress:
                progress(f"evaluating {src.name} ({m + 1}/{len(sources)}) on {n_pairs} pairs")
            values = np.asarray(src.eval(wi, wo), dtype=np.float64)
            if not np.isfinite(values).all():
                raise InputFileError(src.path or src.name, "source returned NaN or Inf values")
            ref[m] = np.maximum(values, 0.0)
        n_cos = n_pairs - n_spec if n_spec < n_pairs else n_pairs  # all-specular pool: best available
        #: mean cos(theta_i) f_ref over the cosine-weighted pairs and RGB, per material (M,): an
        #: unbiased estimate of the material's mean albedo-like brightness.
        self.brightness = torch.from_numpy(
            (ref[:, :n_cos] * wi[None, :n_cos, 2:3].astype(np.float32)).mean(axis=(1, 2)).astype(np.float32))
        #: mean f_ref over the same pairs (M,): the scale of a loss that does not weigh by cos(theta_i).
        self.mean_f = torch.from_numpy(ref[:, :n_cos].mean(axis=(1, 2), dtype=np.float64).astype(np.float32))
        self.wi = torch.from_numpy(wi.astype(np.float32))
        self.wo = torch.from_numpy(wo.astype(np.float32))
        self.ref = torch.from_numpy(ref)

    def repeat_materials(self, k: int) -> "TrainingPool":
        """Each material's values k times in a row (material m becomes rows m k .. m k + k - 1):
        the pool of a sparse fit from k starts per material (FitSettings.sparse_starts)."""
        self.ref = self.ref.repeat_interleave(k, dim=0)
        self.brightness = self.brightness.repeat_interleave(k)
        self.mean_f = self.mean_f.repeat_interleave(k)
        return self

    def to(self, device: str) -> "TrainingPool":
        self.wi, self.wo, self.ref = self.wi.to(device), self.wo.to(device), self.ref.to(device)
        self.brightness, self.mean_f = self.brightness.to(device), self.mean_f.to(device)
        return self


_FORMAT_TAGS = {".bsdf": "rgl", ".h5": "nbrdf", ".binary": "merl", ".bin": "utia"}


def format_tag(src: BRDFSource) -> str:
    """Short name of a source's format: rgl, nbrdf, merl, utia, synthetic (or other)."""
    if src.path is None:
        return "synthetic"
    return _FORMAT_TAGS.get(os.path.splitext(src.path)[1].lower(), "other")


def material_names(sources: Sequence[BRDFSource]) -> List[str]:
    """Material names for a collection: each source's name, except that names
    shared by sources of different formats (e.g. an RGL file and the NBRDF
    network fitted to it) become ``<name>.<format>``. Raises ValueError if
    names still collide."""
    names = [s.name for s in sources]
    shared = {n for n in names if names.count(n) > 1}
    out = [f"{s.name}.{format_tag(s)}" if s.name in shared else s.name for s in sources]
    dupes = sorted({n for n in out if out.count(n) > 1})
    if dupes:
        raise ValueError(f"two sources share the material name(s) {', '.join(dupes)}; names must be unique")
    # The model contract's name rule (hybridbrdf.names), checked before any training: a name the
    # loaders would refuse must not cost a fit. Names come from file names, so the error names the file.
    for src, name in zip(sources, out):
        problem = name_problem(name)
        if problem:
            raise InputFileError(src.path or name, f"material name '{name}' breaks the rule: {problem} "
                                                   f"(rename the file)")
    problem = names_problem(out)
    if problem:
        raise ValueError(f"{problem}; rename one of the files")
    return out


def log_cos_loss(f_ref: torch.Tensor, f: torch.Tensor, cos_i: torch.Tensor, eps=1.0,
                 expectile: float = 0.5) -> torch.Tensor:
    """Per-material L: mean over the batch of the squared RGB norm of
    d = log(eps + cos f_ref) - log(eps + cos f). (M,). eps = 1 is the paper's loss; a tensor of
    shape (M,) gives every material its own epsilon. ``expectile`` tau != 0.5 weighs each squared
    channel difference by 2 tau where f is below f_ref (d > 0) and 2 (1 - tau) where it is above."""
    c = cos_i[None, :, None]
    if isinstance(eps, torch.Tensor):
        e = eps[:, None, None]
        d = torch.log(e + c * f_ref) - torch.log(e + c * f)
    elif eps == 1.0:
        d = torch.log1p(c * f_ref) - torch.log1p(c * f)
    else:
        d = torch.log(eps + c * f_ref) - torch.log(eps + c * f)
    if expectile == 0.5:
        return (d * d).sum(-1).mean(-1)
    w = torch.where(d > 0, d.new_tensor(2.0 * expectile), d.new_tensor(2.0 * (1.0 - expectile)))
    return (w * d * d).sum(-1).mean(-1)


def training_loss(ref: torch.Tensor, f_t: torch.Tensor, f_a: Optional[torch.Tensor], cos_i: torch.Tensor,
                  eps, eps_analytic=None, loss_cos: bool = True, analytic_expectile: float = 0.5) -> torch.Tensor:
    """Per-material loss of one batch (M,): L(f_ref, f_t) + L(f_ref, f_a) (CONVENTIONS, paper
    Sec. 3.3), the analytic term left out when ``f_a`` is None (the neural baseline).
    ``eps_analytic`` (default ``eps``) is the analytic term's epsilon; ``loss_cos=False`` drops
    the cos(theta_i) weight inside the logarithm (FitSettings.loss_cos); ``analytic_expectile`` makes
    the analytic term asymmetric (FitSettings.analytic_expectile)."""
    weight = cos_i if loss_cos else torch.ones_like(cos_i)
    loss = log_cos_loss(ref, f_t, weight, eps)
    if f_a is not None:
        loss = loss + log_cos_loss(ref, f_a, weight, eps if eps_analytic is None else eps_analytic,
                                   analytic_expectile)
    return loss


def _optimizer(module, settings: FitSettings, frozen: bool):
    net = [p for n, p in module.named_parameters() if n.startswith(("mlp.", "frames."))]
    per_material = [p for n, p in module.named_parameters() if not n.startswith(("mlp.", "frames."))]
    if frozen:
        for p in net:
            p.requires_grad_(False)
        groups = [{"params": per_material, "weight_decay": 0.0}]
    else:
        groups = [{"params": net, "weight_decay": settings.weight_decay, "lr": settings.lr * settings.network_lr},
                  {"params": per_material, "weight_decay": 0.0}]
    opt = torch.optim.AdamW(groups, lr=settings.lr)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda step: lr_factor(settings, step))
    return opt, sched


def lr_factor(settings: FitSettings, step: int) -> float:
    """The learning rate of step ``step`` (0-based) as a fraction of ``settings.lr``:
    cosine, 1/2 (1 + cos(pi t)), or exponential, lr_final^t, with t = step / steps."""
    t = min(step, settings.steps) / settings.steps
    if settings.lr_schedule == "exponential":
        return settings.lr_final ** t
    return 0.5 * (1.0 + math.cos(math.pi * t))


def start_from_nearest(module, frozen: HybridModel, pool: "TrainingPool", eps, eps_analytic,
                       settings: FitSettings, n_pairs: int = 8192, chunk: int = 64, starts: int = 1,
                       rows: Optional[Sequence[int]] = None) -> List[int]:
    """Sparse fitting's starting point (FitSettings.sparse_init = "nearest"): give every new
    material the (p, z) of the frozen model's material with the lowest training loss on the
    new material's pool values, and return those materials' indices. With ``starts`` = k > 1
    the pool and the module hold each new material k times in a row (rows m k + j), and row
    m k + j starts from the j-th best material (FitSettings.sparse_starts).

    Only (p, z) move in a sparse fit, and the loss over them is far from convex: a glossy
    measurement started from the neutral grey rough lobe must first narrow alpha by orders of
    magnitude while z wanders through codes the network never saw. A collection that holds a
    similar material already knows a (p, z) the network decodes well. Scoring all of them
    costs one forward pass per candidate on ``n_pairs`` pool pairs (spread over the cosine and
    specular parts of the pool), a few training steps' worth. ``rows``: set only these
    materials (a warm start keeps the others' own (p, z)); every material is scored."""
    dev = pool.wi.device
    step = max(1, pool.wi.shape[0] // n_pairs)
    idx = torch.arange(0, pool.wi.shape[0], step, device=dev)[:n_pairs]
    wi, wo, ref = pool.wi[idx], pool.wo[idx], pool.ref[:, idx]
    cand = {k[len("materials."):]: torch.from_numpy(v).to(dev) for k, v in frozen.tensors.items()
            if k.startswith("materials.")}
    n_new, n_cand = ref.shape[0], cand["z"].shape[0]

    def for_material(e, m: int, k: int):
        """The new material m's epsilon (scalar or per material) for k candidates."""
        return e[m].expand(k) if isinstance(e, torch.Tensor) else e

    losses = torch.empty(n_new, n_cand, device=dev)
    with torch.no_grad():
        for lo in range(0, n_cand, chunk):
            c = {k: v[lo:lo + chunk] for k, v in cand.items()}
            if "kd" in c:
                head = (c["head_weight"], c["head_bias"]) if "head_weight" in c else None
                f_t, f_a = module.evaluate(wi, wo, c["kd"], c["eta"], c["alpha"], c["z"], head)
            else:
                f_t, f_a = module.evaluate(wi, wo, c["z"])
            k = f_t.shape[0]
            for m in range(n_new):
                losses[m, lo:lo + chunk] = training_loss(
                    ref[m].expand_as(f_t), f_t, f_a, wi[:, 2], for_material(eps, m, k),
                    for_material(eps_analytic, m, k), settings.loss_cos, settings.analytic_expectile)
        order = torch.argsort(losses, dim=1, stable=True)
        best = [int(order[m, m % starts]) for m in range(n_new)]
        for m, k in enumerate(best):
            if rows is not None and m not in rows:
                continue
            if "kd" in cand:
                module.set_analytic(m, cand["kd"][k], cand["eta"][k], cand["alpha"][k])
            module.z[m] = cand["z"][k]
            if "head_weight" in cand:
                module.head_weight[m] = cand["head_weight"][k]
                module.head_bias[m] = cand["head_bias"][k]
    return best


def best_starts(module, pool: "TrainingPool", starts: int, eps, eps_analytic, settings: FitSettings,
                n_pairs: int = 65536, chunk: int = 16384) -> List[int]:
    """The row of each new material's best fit in a sparse fit from ``starts`` starts per
    material (rows m k .. m k + k - 1): the lowest training loss on ``n_pairs`` pool pairs
    spread over its cosine and specular parts, the loss the fit minimised."""
    dev = pool.wi.device
    step = max(1, pool.wi.shape[0] // n_pairs)
    idx = torch.arange(0, pool.wi.shape[0], step, device=dev)[:n_pairs]
    total = torch.zeros(pool.ref.shape[0], device=dev)
    with torch.no_grad():
        for lo in range(0, len(idx), chunk):
            i = idx[lo:lo + chunk]
            f_t, f_a = module(pool.wi[i], pool.wo[i])
            total += training_loss(pool.ref[:, i], f_t, f_a if spec.ARCHS[settings.arch]["analytic"] else None,
                                   pool.wi[i, 2], eps, eps_analytic,
                                   settings.loss_cos, settings.analytic_expectile) * len(i)
    per_start = total.reshape(-1, starts)
    return [m * starts + int(j) for m, j in enumerate(per_start.argmin(dim=1))]


def _keep_materials(module, rows: List[int], settings: FitSettings, iso: List[bool]):
    """A module of the same network holding only the per-material parameters of ``rows``."""
    kept = build_model(settings.arch, len(rows), settings.width, settings.depth, settings.latent,
                       settings.activation, iso, output_layer=settings.network_output_layer())
    index = torch.tensor(rows, device=next(module.parameters()).device)
    shared = ("mlp.", "frames.")
    kept.load_state_dict({k: (v if k.startswith(shared) else v[index]) for k, v in module.state_dict().items()})
    return kept


def _save_checkpoint(path: str, module, opt, sched, step: int, settings: FitSettings, names: List[str],
                     train_seconds: float, timed_from_step: int, gen: torch.Generator) -> None:
    # train_seconds: training time of the steps from timed_from_step on (0 unless the fit once
    # resumed a checkpoint that kept no time), so that a resumed fit records the time of the
    # whole fit, not of its last segment. batch_rng: the batch generator's state, so that a
    # resume continues the batch sequence without replaying it (docs/FITTING.md, "Checkpoints").
    ckpt.save(path, {"module": module.state_dict(), "optimizer": opt.state_dict(), "scheduler": sched.state_dict(),
                     "step": step, "settings": dataclasses.asdict(settings), "names": names,
                     "torch_rng": torch.get_rng_state(), "batch_rng": gen.get_state(),
                     "train_seconds": float(train_seconds), "timed_from_step": int(timed_from_step)})


class FitInterrupted(KeyboardInterrupt):
    """A fit stopped by SIGINT or SIGTERM after a finished step: ``step`` steps done, written to
    ``checkpoint`` when there is one. ``str()`` says what to do next, in one line."""

    def __init__(self, step: int, checkpoint: Optional[str]):
        self.step, self.checkpoint = step, checkpoint
        super().__init__(f"interrupted after step {step}; " + (
            f"checkpoint {checkpoint} written: continue with the same command and --resume" if checkpoint
            else "nothing saved (no --checkpoint)"))


def frozen_arch_settings(settings: FitSettings, frozen: HybridModel) -> FitSettings:
    """Set ``settings``' network fields (arch, width, depth, latent, activation, output layer) to
    those of the frozen model a sparse fit keeps; returns ``settings``. With material output
    layers each new material gets (and fits) a head of its own on the frozen hidden layers."""
    a = frozen.arch
    settings.arch, settings.width, settings.depth = a["kind"], a["width"], a["depth"]
    settings.latent, settings.activation = a["latent"], a["activation"]
    settings.output_layer = a.get("output_layer", "shared")
    return settings


def fit(sources: Sequence[BRDFSource], settings: FitSettings, frozen: Optional[HybridModel] = None,
        init: Optional[HybridModel] = None, checkpoint: Optional[str] = None, checkpoint_every: int = 1000, resume: bool = False,
        progress: bool = True, log: Callable[[str], None] = print,
        stop_after: Optional[int] = None, compile_step: bool = False,
        ranks: Optional[dd.Ranks] = None,
        observe: Optional[Callable[[int, torch.nn.Module], None]] = None) -> Optional[HybridModel]:
    """Fit ``sources`` jointly; returns the fitted :class:`HybridModel` (with per-material metrics).

    ``checkpoint``: file written every ``checkpoint_every`` steps (atomically);
    with ``resume`` an existing checkpoint is continued, reproducing the
    uninterrupted run exactly (same batches, optimiser state and RNG).
    ``stop_after``: write the checkpoint after that many steps and return None
    (splits a long fit into bounded jobs; requires ``checkpoint``).
    ``compile_step``: run the model and the loss of each step through ``torch.compile``
    (TorchInductor fuses the element-wise GGX, gate and loss arithmetic of the forward
    and backward passes; docs/FITTING.md, "Training speed"). The first step then takes
    the compilation time (recorded as ``compile_seconds``); the result differs from an
    eager fit only by float rounding, and a checkpoint resumes either way.

    Before any source is evaluated, ``checkpoint`` must be writable and, when resumed, pass
    every check of :mod:`hybridbrdf.checkpoint` (checksum, structure, settings, step, finite
    values, shapes); otherwise :class:`~hybridbrdf.errors.InputFileError` naming the file.

    ``init``: a warm start from a fitted model (FitSettings.init_from names its file): its
    network is loaded and trained further (at ``lr * network_lr``), each source starts from
    ``init``'s material of the same name, else (sparse_init "nearest") from the one whose
    (p, z) fits it best, as a sparse fit starts; the network settings are ``init``'s. A model
    fitted with ``frozen=`` and then continued with ``init=`` is ``hbrdf add``'s fine-tune.

    ``ranks``: this process's place in a data-parallel fit (:func:`hybridbrdf.distributed.join`
    under torchrun): every rank trains on its share of the same global batch, gradients are
    averaged by DistributedDataParallel, and only rank 0 logs, writes checkpoints and returns
    the model (the others return None). SIGINT or SIGTERM stops the fit after the step in
    progress on every rank; with ``checkpoint`` rank 0 writes it first; then
    :class:`FitInterrupted` is raised. A rank that loses the others raises
    :class:`~hybridbrdf.distributed.RankLostError`; neither writes a model.

    ``observe(step, module)``: called on rank 0 after every optimiser step (``step`` steps done)
    with the module being fitted, e.g. to snapshot it for a time-to-accuracy curve
    (bench/bench_fit_time.py); it must not change the module.
    """
    ranks = ranks or dd.Ranks()
    dd.check_batch_split(settings.batch, ranks)
    if not ranks.main:
        progress, log = False, (lambda msg: None)
    if stop_after is not None and not checkpoint:
        raise ValueError("stop_after needs a checkpoint file to stop into")
    settings.check()
    if not sources:
        raise ValueError("no BRDF sources to fit")
    names = material_names(sources)
    torch.manual_seed(settings.seed)
    iso = [bool(s.isotropic) for s in sources]

    if frozen is not None and init is not None:
        raise ValueError("a fit keeps a frozen network or starts from one (init), not both")
    start_model = frozen if frozen is not None else init  # whose network the fit starts from
    if start_model is not None:
        frozen_arch_settings(settings, start_model)
    # Sparse fitting from several starts: every new material k times over (rows m k + j).
    starts = (min(settings.sparse_starts, len(frozen.materials))
              if frozen is not None and settings.sparse_init == "nearest" else 1)
    if starts > 1 and checkpoint:
        raise ValueError("--sparse-starts above 1 fits without --checkpoint (a sparse fit is minutes long)")
    if checkpoint and ranks.main:
        check_writable(checkpoint, "checkpoint")
    saved = None
    if resume and checkpoint and os.path.exists(checkpoint):
        # Before any expensive work: a checkpoint that cannot be resumed must not cost the pool.
        saved, checksummed = ckpt.load(checkpoint, settings)
        if not checksummed:
            log(f"{checkpoint}: checkpoint from an earlier hybridbrdf has no checksum; damage cannot be detected")
    module = build_model(settings.arch, len(sources) * starts, settings.width, settings.depth, settings.latent,
                         settings.activation, [i for i in iso for _ in range(starts)],
                         output_layer=settings.network_output_layer())
    if spec.ARCHS[settings.arch]["combine"] == "gated" and start_model is None:
        module.set_output_bias(slice(0, 3), settings.fc_init)
    own_rows: List[int] = []  # warm start: the sources that start from init's material of their name
    if start_model is not None:
        state = {k: torch.from_numpy(v) for k, v in start_model.tensors.items() if not k.startswith("materials.")}
        module.load_state_dict(state, strict=False)
        if "materials.head_weight" in start_model.tensors:
            # A new material's head starts as the mean of the frozen model's (sparse_init
            # "nearest" then replaces it with the nearest material's).
            with torch.no_grad():
                module.head_weight[:] = torch.from_numpy(start_model.tensors["materials.head_weight"].mean(axis=0))
                module.head_bias[:] = torch.from_numpy(start_model.tensors["materials.head_bias"].mean(axis=0))
    if init is not None:
        own_rows = [m for m, n in enumerate(names) if n in init.materials]
        with torch.no_grad():
            for m in own_rows:
                k = init.materials.index(names[m])
                row = {key[len("materials."):]: torch.from_numpy(v[k]) for key, v in init.tensors.items()
                       if key.startswith("materials.")}
                if "kd" in row:
                    module.set_analytic(m, row["kd"], row["eta"], row["alpha"])
                module.z[m] = row["z"]
                if "head_weight" in row:
                    module.head_weight[m] = row["head_weight"]
                    module.head_bias[m] = row["head_bias"]

    module.to(settings.device)
    opt, sched = _optimizer(module, settings, frozen is not None)
    gen = torch.Generator(device="cpu").manual_seed(settings.seed)
    start = 0
    # Training time of the steps from ``timed_from`` to ``start`` (from the checkpoint). A
    # checkpoint that predates that record kept no time: the clock then starts at the resume.
    earlier_seconds, timed_from = 0.0, 0
    if saved is not None:
        ckpt.restore(checkpoint, saved, names, module, opt, sched)
        start = saved["step"]
        if "train_seconds" in saved:
            earlier_seconds, timed_from = float(saved["train_seconds"]), saved["timed_from_step"]
        else:
            timed_from = start
        if "batch_rng" in saved:
            gen.set_state(saved["batch_rng"])
        else:  # an older checkpoint: replay its batches (start <= steps: checked)
            for _ in range(start):
                torch.randint(0, settings.pool, (settings.batch,), generator=gen)
        log(f"resuming from {checkpoint} at step {start}")
    # After the checkpoint: evaluating every source on the pool is the expensive part of the set-up.
    pool = TrainingPool(sources, settings.pool, settings.seed, log if progress else None,
                        settings.specular, settings.specular_alpha).repeat_materials(starts).to(settings.device)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=settings.steps, initial=start, desc=f"fit {settings.arch} {settings.width}x{settings.depth}",
                   unit="step", dynamic_ncols=True, mininterval=0.5)
    module.train()
    has_analytic = spec.ARCHS[settings.arch]["analytic"]
    # A black material (brightness 0) falls back to the smallest epsilon float32 keeps well above
    # the cos f values it is compared with (1e-6 of a typical 0.1-1 brightness).
    scale = (torch.clamp(pool.brightness if settings.loss_cos else pool.mean_f, min=1e-6)
             if settings.loss_eps_relative else 1.0)
    eps = settings.loss_eps * scale
    eps_analytic = (settings.loss_eps if settings.analytic_loss_eps is None else settings.analytic_loss_eps) * scale

    start_names: Optional[List[str]] = None
    if init is not None and start == 0 and settings.sparse_init == "nearest" and len(own_rows) < len(names):
        rest = [m for m in range(len(names)) if m not in own_rows]
        chosen = start_from_nearest(module, init, pool, eps, eps_analytic, settings, rows=rest)
        log("warm start: " + ", ".join(f"{names[m]} <- {init.materials[chosen[m]]}" for m in rest))
    if frozen is not None and start == 0 and settings.sparse_init == "nearest":
        chosen = start_from_nearest(module, frozen, pool, eps, eps_analytic, settings, starts=starts)
        start_names = [frozen.materials[k] for k in chosen]
        log("sparse fit starts from " + ", ".join(
            f"{n} <- {' | '.join(start_names[m * starts:(m + 1) * starts])}" for m, n in enumerate(names)))

    net = dd.wrap(module, ranks, settings.device)  # DistributedDataParallel under torchrun

    def batch_loss(wi: torch.Tensor, wo: torch.Tensor, ref: torch.Tensor) -> torch.Tensor:
        f_t, f_a = net(wi, wo)
        return training_loss(ref, f_t, f_a if has_analytic else None, wi[:, 2], eps, eps_analytic,
                             settings.loss_cos, settings.analytic_expectile).sum()

    if compile_step:
        # Every batch has the same shapes, so one static graph serves the whole fit.
        batch_loss = torch.compile(batch_loss, dynamic=False)
    compile_seconds = None
    saved_step = start if saved is not None else None  # the step of the newest checkpoint on disk
    t0 = time.perf_counter()
    stop = dd.StopRequest().install()
    try:
        for step in range(start, settings.steps):
            # Every rank draws the same global batch and trains on its share of it.
            idx = torch.randint(0, settings.pool, (settings.batch,), generator=gen)
            idx = dd.share(idx, ranks).to(settings.device)
            wi, wo, ref = pool.wi[idx], pool.wo[idx], pool.ref[:, idx]
            try:
                loss = batch_loss(wi, wo, ref)
                if not torch.isfinite(loss):
                    raise FloatingPointError(
                        f"loss became {loss.item()} at step {step}; lower --lr or check the sources")
                opt.zero_grad(set_to_none=True)
                loss.backward()  # under DistributedDataParallel: gradients averaged over the ranks
                stopping_now = dd.any_rank(stop.requested is not None, ranks, settings.device)
            except RuntimeError as exc:
                if not ranks.distributed:
                    raise
                # gloo's "[file.cc:537] Read error [addr]:port: Connection reset by peer. This is ..." -> its gist
                reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                reason = re.sub(r"^\[[^\]]*\]\s*", "", reason).split(". ")[0]
                kept = f"checkpoint {checkpoint} (step {saved_step})" if saved_step is not None else "no checkpoint"
                raise dd.RankLostError(f"rank {ranks.rank} of {ranks.world}: lost the other ranks at step {step} "
                                       f"({reason}); kept: {kept}, no model written") from None
            torch.nn.utils.clip_grad_norm_([p for p in module.parameters() if p.requires_grad], settings.clip)
            opt.step()
            sched.step()
            if observe is not None and ranks.main:
                observe(step + 1, module)
            if compile_step and compile_seconds is None:
                # The first compiled step builds the graphs; the throughput counts the steps after it.
                compile_seconds = time.perf_counter() - t0
            if bar is not None:
                bar.update(1)
                if step % 20 == 0:
                    bar.set_postfix(loss=f"{loss.item() / len(sources):.4g}")  # .item(): no autograd warning
            stopping = stop_after is not None and step + 1 == stop_after and step + 1 < settings.steps
            if checkpoint and (stopping or stopping_now or
                               ((step + 1) % checkpoint_every == 0 and step + 1 < settings.steps)):
                # Once per step even where stop_after falls on a regular checkpoint.
                if ranks.main:
                    _save_checkpoint(checkpoint, module, opt, sched, step + 1, settings, names,
                                     earlier_seconds + time.perf_counter() - t0, timed_from, gen)
                saved_step = step + 1
            if stopping_now:
                raise FitInterrupted(step + 1, checkpoint)
            if stopping:
                return None
    finally:
        stop.restore()
        if bar is not None:
            bar.close()
    elapsed = time.perf_counter() - t0
    if not ranks.main:
        return None
    if starts > 1:
        keep = best_starts(module, pool, starts, eps, eps_analytic, settings)
        module = _keep_materials(module, keep, settings, iso)
        start_names = [start_names[r] for r in keep]
        log("kept the fits started from " + ", ".join(f"{n} <- {s}" for n, s in zip(names, start_names)))
    module.eval().cpu()

    training = dataclasses.asdict(settings)
    training["train_seconds"] = round(earlier_seconds + elapsed, 3)
    if timed_from:
        # Resumed (perhaps more than once) from a checkpoint that kept no time.
        training["train_seconds_from_step"] = timed_from
    if start:
        training["resumed_at_step"] = start
    timed_steps, timed_seconds = settings.steps - start, elapsed
    if compile_seconds is not None:
        training["compile_seconds"] = round(compile_seconds, 3)
        timed_steps, timed_seconds = timed_steps - 1, elapsed - compile_seconds
    training["pairs_x_materials_per_second"] = (
        round(timed_steps * settings.batch * len(sources) * starts / timed_seconds) if timed_seconds > 0 else None)
    model = HybridModel.from_module(module, names, [s.origin for s in sources], training)
    metrics = evaluate(model, sources, n_pairs=settings.eval_pairs, names=names)
    for info, row in zip(model.material_info, metrics):
        info["metrics"] = {k: v for k, v in row.items() if k not in ("material", "origin")}
    if start_names is not None:
        # What the sparse fit started from and how far that start was off: the frozen network bounds
        # what (p, z) can reach, so a fit that ends near its start says the network, not the
        # optimiser, is the limit (docs/FITTING.md, "Sparse fitting").
        start_metrics = evaluate(frozen, sources, n_pairs=settings.eval_pairs, names=start_names)
        for info, name, row in zip(model.material_info, start_names, start_metrics):
            info["sparse_start"] = {"material": name, "smape": row["smape"], "cmae": row["cmae"]}
    return model


def source_material(model, src: BRDFSource) -> Optional[str]:
    """The model material a source was fitted as: ``<name>`` or, where a collection held the same
    name in two formats, ``<name>.<format>`` (see material_names); None if the model lacks both."""
    return next((c for c in (src.name, f"{src.name}.{format_tag(src)}") if c in model.materials), None)


def evaluate(model: HybridModel, sources: Sequence[BRDFSource], n_pairs: int = 1_000_000,
             seed: int = 7, names: Optional[Sequence[str]] = None, extended: bool = False) -> List[Dict[str, object]]:
    """Per-material metrics of CONVENTIONS on ``n_pairs`` seeded cosine-weighted pairs:
    SMAPE and cMAE of the full model and (hybrid kinds) of its analytic part.
    Sources are matched to the model's materials by name (``<name>`` or
    ``<name>.<format>``, see material_names), or by the given ``names``.

    ``extended`` adds MAE, the reciprocity error (SMAPE between f(wi, wo) and
    f(wo, wi) on min(n_pairs, 10^5) pairs) and the directional albedo at
    theta_o = 45 degrees (mean RGB), for the reference, the analytic part and the model."""
    wi, wo = metric_directions(n_pairs, seed)
    rows = []
    for i, src in enumerate(sources):
        if names is not None:
            name = names[i]
        else:
            name = source_material(model, src)
            if name is None:
                raise KeyError(f"material {src.name!r} is not in the model (it has {', '.join(model.materials)})")
        ref = src.eval(wi, wo)
        f, fa = model._eval(wi, wo, name, torch.float32)
        row: Dict[str, object] = {"material": name, "origin": src.origin,
                                  "smape": smape(ref, f), "cmae": cmae(ref, f, wi[:, 2])}
        if fa is not None:
            row["smape_analytic"] = smape(ref, fa)
            row["cmae_analytic"] = cmae(ref, fa, wi[:, 2])
        if extended:
            row.update(_extended_metrics(model, name, src, ref, f, fa, min(n_pairs, 100_000), seed))
        rows.append(row)
    return rows


def _extended_metrics(model, name, src, ref, f, fa, n_small, seed) -> Dict[str, float]:
    from hybridbrdf.metrics import directional_albedo, mae, reciprocity_error

    full = lambda a, b: model._eval(a, b, name, torch.float32)[0]  # noqa: E731
    analytic = lambda a, b: model._eval(a, b, name, torch.float32)[1]  # noqa: E731
    out = {"mae": mae(ref, f), "reciprocity_reference": reciprocity_error(src.eval, n_small, seed),
           "reciprocity": reciprocity_error(full, n_small, seed),
           "albedo45_reference": float(directional_albedo(src.eval, math.pi / 4, n_small, seed).mean()),
           "albedo45": float(directional_albedo(full, math.pi / 4, n_small, seed).mean())}
    if fa is not None:
        out["mae_analytic"] = mae(ref, fa)
        out["reciprocity_analytic"] = reciprocity_error(analytic, n_small, seed)
        out["albedo45_analytic"] = float(directional_albedo(analytic, math.pi / 4, n_small, seed).mean())
    return out


def format_extended_table(rows: List[Dict[str, object]]) -> str:
    """MAE, reciprocity error and albedo at 45 degrees: reference (ref), analytic part (a), model (m)."""
    has_a = any("mae_analytic" in r for r in rows)
    dash = float("nan")
    lines = [f"{'material':28s} {'MAE a':>9s} {'MAE m':>9s} {'recip ref':>9s} {'recip a':>9s} {'recip m':>9s} "
             f"{'alb45 ref':>9s} {'alb45 a':>9s} {'alb45 m':>9s}"]
    for r in rows:
        lines.append(f"{r['material'][:28]:28s} {r.get('mae_analytic', dash) if has_a else dash:9.5f} {r['mae']:9.5f} "
                     f"{r['reciprocity_reference']:9.4f} {r.get('reciprocity_analytic', dash):9.2e} "
                     f"{r['reciprocity']:9.4f} {r['albedo45_reference']:9.4f} {r.get('albedo45_analytic', dash):9.4f} "
                     f"{r['albedo45']:9.4f}")
    return "\n".join(lines)


#: A model metric counts as worse than its analytic part's (the table's "!") beyond these margins:
#: 10% of the analytic part's value plus a floor, SMAPE 0.001 (0.1% relative error) and cMAE 5e-5
#: (a twentieth of a percent of a mid-grey diffuse value), below which two fits of the same exact
#: material differ by their optimiser's noise alone.
WORSE_MARGIN = {"smape": (0.1, 1e-3), "cmae": (0.1, 5e-5)}


def worse_than_analytic(row: Dict[str, object], metric: str) -> bool:
    """True when the model's ``metric`` (smape or cmae) is worse than its analytic part's beyond
    :data:`WORSE_MARGIN`."""
    rel, floor = WORSE_MARGIN[metric]
    a = float(row[metric + "_analytic"])
    return float(row[metric]) > a + rel * a + floor


def format_table(rows: List[Dict[str, object]], n_pairs: int) -> str:
    """The per-material table `hbrdf fit` and `hbrdf eval` print. A model metric worse than its
    own analytic part's (beyond :data:`WORSE_MARGIN`) is marked "!" and a note under the table
    says what to do about it."""
    has_a = any("smape_analytic" in r for r in rows)
    head = f"{'material':28s} {'reference':32s} " + (
        f"{'SMAPE analytic':>14s} {'SMAPE model':>12s} {'cMAE analytic':>14s} {'cMAE model':>11s}" if has_a
        else f"{'SMAPE model':>12s} {'cMAE model':>11s}")
    lines = [f"metrics on {n_pairs} cosine-weighted pairs (seed 7); negatives in references clamped to 0", head]
    worse = []
    for r in rows:
        if has_a:
            mark_s = "!" if worse_than_analytic(r, "smape") else " "
            mark_c = "!" if worse_than_analytic(r, "cmae") else " "
            if mark_s + mark_c != "  ":
                worse.append(str(r["material"]))
            lines.append(f"{r['material'][:28]:28s} {str(r['origin'])[:32]:32s} {r['smape_analytic']:14.4f} "
                         f"{r['smape']:11.4f}{mark_s} {r['cmae_analytic']:14.5f} {r['cmae']:10.5f}{mark_c}")
        else:
            lines.append(f"{r['material'][:28]:28s} {str(r['origin'])[:32]:32s} {r['smape']:12.4f} {r['cmae']:11.5f}")
    if rows:
        mean = lambda k: np.mean([r[k] for r in rows])  # noqa: E731
        if has_a:
            lines.append(f"{'mean':28s} {'':32s} {mean('smape_analytic'):14.4f} {mean('smape'):12.4f} "
                         f"{mean('cmae_analytic'):14.5f} {mean('cmae'):11.5f}")
        else:
            lines.append(f"{'mean':28s} {'':32s} {mean('smape'):12.4f} {mean('cmae'):11.5f}")
    if worse:
        shown = ", ".join(worse[:6]) + (f" and {len(worse) - 6} more" if len(worse) > 6 else "")
        lines.append(f"! the model is less accurate than its own analytic part on {shown}: the network's correction "
                     f"has not converged there (fit longer: --steps), or the material needs no correction (render it "
                     f"with f_a alone: a scene material with \"evaluate\": \"analytic\", docs/RENDERING.md)")
    return "\n".join(lines)
