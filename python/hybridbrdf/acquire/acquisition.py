"""``hbrdf acquire fit``'s run: a capture folder (or rig file) in, a textured-material folder out
(docs/ACQUISITION.md, "The fit on a frozen prior").

    acquire("capture", "out/acquired", size=(128, 128), steps=300)

Everything that can be refused is refused before the fit: the output (an existing folder that is
not a textured material's, or one holding the capture), the checkpoint (a fresh run over another
run's checkpoint without ``force``), the capture (its rig and photographs), a capture with nothing
usable (:mod:`~hybridbrdf.acquire.exposure`). The run keeps a checkpoint beside the output,
``.<out>.acquire-checkpoint`` (every 50 steps and after each stage, written atomically with a
checksum, held under its lock so that a second run on it is refused), which ``resume`` continues
and a finished run removes; the output folder is written whole or not at all."""

from __future__ import annotations

import json
import os
from typing import TYPE_CHECKING, Callable, Optional, Tuple

from hybridbrdf import spec
from hybridbrdf.acquire.exposure import stated_noise_floor, stated_noise_model, usable_pixels
from hybridbrdf.acquire.isotropy import turned_about_normal
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.sizes import STEPS, default_finetune
from hybridbrdf.errors import InputFileError
from hybridbrdf.limits import check_count
from hybridbrdf.model.file import load_model
from hybridbrdf.model.prior import load_prior
from hybridbrdf.files import file_lock, make_parent_folder

if TYPE_CHECKING:  # annotations only: the fit's modules (PyTorch) load when acquire() runs
    from hybridbrdf.acquire.hybrid_fit import HybridMaps
    from hybridbrdf.acquire.texel_rows import Progress

#: Peak bytes per texel of the map, an estimate with a margin: the 128x128 run of docs/ACQUISITION.md
#: peaked at 1.56 GB, about 0.8 GB of it the photographs, observations and libraries, the rest
#: (about 46 KiB a texel) the 8 rows per texel and their activations through the network with autograd.
BYTES_PER_TEXEL = 64 * 1024
#: The fit's report in the written folder: the clusters, what each chose and how well (docs/ACQUISITION.md).
REPORT_FILE = "acquisition.json"


def checkpoint_path(out) -> str:
    """The checkpoint of a run writing ``out``: ``.<name>.acquire-checkpoint`` beside it."""
    out = os.path.abspath(os.fspath(out))
    return os.path.join(os.path.dirname(out), f".{os.path.basename(out)}.acquire-checkpoint")


def _inside(path: str, folder: str) -> bool:
    path, folder = os.path.realpath(path), os.path.realpath(folder)
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def check_output(out: str, capture: str) -> None:
    """Refuse, in one line naming ``out``, an output that would destroy an input or another folder."""
    if _inside(capture, out):
        raise InputFileError(out, f"holds the capture {capture}; writing it would destroy that input")
    if os.path.lexists(out):
        if not os.path.isdir(out):
            raise InputFileError(out, "exists and is not a folder")
        if os.listdir(out) and not os.path.isfile(os.path.join(out, spec.SVBRDF["index_file"])):
            raise InputFileError(out, f"is a folder without {spec.SVBRDF['index_file']}; refusing to replace it")


def _observations(capture: str, size: Tuple[int, int], log: Callable[[str], None], turn_seed: Optional[int] = None):
    """(rig, observations, index, usable-pixel report) of ``capture`` onto a ``size`` map: its
    photographs read, saturated, non-finite and under-exposed pixels left out (each count logged);
    with ``turn_seed`` each observation turned about the normal (:mod:`~hybridbrdf.acquire.isotropy`)."""
    from hybridbrdf.acquire.capture import load_capture

    rig, photos, index, saturated = load_capture(capture, finite=False, saturation=True)
    masks, report = usable_pixels(rig, photos, stated_noise_floor(index), where=capture, saturated=saturated)
    if report["saturated"]:
        log(f"{report['saturated']} pixels saturated (a channel at the encoding's largest code): left out")
    if report["not finite"]:
        log(f"{report['not finite']} pixels not finite: left out")
    if report["under-exposed"]:
        log(f"{len(report['under-exposed'])} of {len(photos)} photographs under-exposed (most sample pixels below "
            f"3x the noise floor): left out ({', '.join(rig.shots[k].image for k in report['under-exposed'])})")
    obs = texel_observations(rig, photos, size, usable=masks)
    counts = obs.counts()
    log(f"{len(obs.value):,} observations, {int(counts.min())} to {int(counts.max())} per texel "
        f"({int((counts == 0).sum())} texels unseen); left out: "
        + (", ".join(f"{n} {why}" for why, n in obs.dropped.items() if n) or "none"))
    if turn_seed is not None:
        obs = turned_about_normal(obs, turn_seed)
        log("isotropic: each observation turned about the normal by its own azimuth (--anisotropic: as photographed)")
    return rig, obs, index, report


def _resumed_state(ckpt: str, settings: dict, log: Callable[[str], None]) -> dict:
    """The fit state of checkpoint ``ckpt``, refused when another run's ``settings`` wrote it."""
    from hybridbrdf.fit import checkpoint

    saved, _ = checkpoint.read(ckpt)
    if saved.get("settings") != settings:
        raise checkpoint.CheckpointError(ckpt, f"is another run's (settings {saved.get('settings')}); --force starts afresh")
    state = saved.get("fit")
    log(f"resuming from {ckpt}: stages done: {', '.join(k for k in state if not k.endswith('_partial')) or 'none'}")
    return state


def acquire(capture, out, prior=None, size: Tuple[int, int] = (128, 128), steps: int = STEPS, seed: int = 0,
            resume: bool = False, force: bool = False, progress: Optional[Progress] = None,
            log: Callable[[str], None] = lambda msg: None, warn: Callable[[str], None] = lambda msg: None,
            refit_heads: bool = False, finetune_network: Optional[int] = None, select: bool = False,
            isotropic: bool = True) -> HybridMaps:
    """Fit per-texel (p, z) maps on ``prior`` (a hybrid model file; None: the shipped prior) to the
    photographs of ``capture`` onto a ``size`` (W, H) map and write the textured material ``out``
    (:meth:`HybridMaps.save`) with :data:`REPORT_FILE`, the clusters and what each chose
    (:mod:`~hybridbrdf.acquire.cluster_report`: its lines go to ``log`` once the clusters are known,
    a warning per cluster no prior material explains to ``warn``). ``resume`` continues the
    checkpoint of an interrupted run with the same settings; ``force`` starts afresh over one.
    ``refit_heads``: each cluster's output layer refitted to its rows (:func:`fit_hybrid_texels`;
    docs/ACQUISITION_GAP.md). ``finetune_network``: steps fine-tuning the prior's network on the capture,
    its materials replayed (:mod:`~hybridbrdf.acquire.network_tune`; the report holds the replay's drift);
    None: :func:`~hybridbrdf.acquire.sizes.default_finetune` (200 from 32 photographs on, else 0); 0: none.
    ``select``: each cluster's prior material chosen among the training shots' best 3 on held-out
    photographs, then refitted on all (:mod:`~hybridbrdf.acquire.select`; the report holds every
    candidate's held-out loss). ``isotropic``: each observation turned about the normal by its own azimuth
    before the fit (:mod:`~hybridbrdf.acquire.isotropy`; False: the azimuths as photographed, for anisotropic
    samples). Returns the fit, its report as ``maps.report``."""
    from hybridbrdf.acquire.cluster_report import POOR_EXCESS, cluster_report, report_logger
    from hybridbrdf.acquire.hybrid_fit import fit_hybrid_texels
    from hybridbrdf.fit import checkpoint

    capture, out = os.path.abspath(os.fspath(capture)), os.path.abspath(os.fspath(out))
    check_count("--size (texels)", int(size[0]) * int(size[1]), BYTES_PER_TEXEL)
    check_output(out, capture)
    make_parent_folder(out)  # as every command does; its checkpoint and lock live beside it
    ckpt = checkpoint_path(out)
    checkpoint.check_not_another_fits(ckpt, resume, force)
    if resume and not os.path.lexists(ckpt):
        raise checkpoint.CheckpointError(ckpt, "no checkpoint to resume (run without --resume)")
    model = load_prior() if prior is None else load_model(prior)
    rig, obs, index, report = _observations(capture, size, log, turn_seed=seed if isotropic else None)
    finetune_network = default_finetune(len(rig.shots)) if finetune_network is None else finetune_network
    settings = {"capture": capture, "prior": model.path or "", "size": [int(size[0]), int(size[1])],
                "steps": int(steps), "seed": int(seed), **({"refit_heads": True} if refit_heads else {}),
                **({"finetune_network": int(finetune_network)} if finetune_network else {}),
                **({"select": True} if select else {}), **({} if isotropic else {"anisotropic": True})}
    with file_lock(ckpt, wait=0):
        state = _resumed_state(ckpt, settings, log) if resume else None

        def save_state(fit_state):
            checkpoint.save(ckpt, {"settings": settings, "fit": fit_state})

        chosen, labelled = [], []

        def on_clusters(family, labels, clusters):
            chosen[:] = cluster_report(family, model.materials, obs, rig, labels, clusters, seed,
                                       stated_noise_model(index), report["floor"])
            labelled[:] = [labels]
            if clusters.get("held_out_shots") is not None:
                held = clusters["held_out_shots"]
                log(f"held-out choice: {len(held)} of {len(rig.shots)} photographs held out (shots "
                    f"{', '.join(str(k) for k in held) or 'none: too few to hold any out'}); each cluster's material "
                    f"chosen on them, then refitted on all")
            report_logger(log, warn)(chosen)

        maps = fit_hybrid_texels(obs, model, steps=steps, seed=seed, progress=progress, state=state,
                                 save_state=save_state, log=log, on_clusters=on_clusters, refit_heads=refit_heads,
                                 finetune_network=finetune_network, select=select)
        layer = maps.layer.reshape(-1)
        if finetune_network:
            drift = maps.model.training["acquisition_finetune"]["drift"]
            log(f"network fine-tune: the prior's {len(model.materials)} materials replayed moved by SMAPE "
                f"{drift['median_smape']:.4f} (median), {drift['worst_smape']:.4f} at worst ({drift['worst_material']})")
        maps.report = {"format_version": 1, "poor_excess": POOR_EXCESS, "refit_heads": bool(refit_heads),
                       "finetune_network": int(finetune_network), "select": bool(select), "isotropic": bool(isotropic),
                       "layers": maps.layers,
                       **({"replay_drift": maps.model.training["acquisition_finetune"]["drift"]} if finetune_network else {}),
                       "clusters": [{**c, "layer": maps.layers[int(layer[labelled[0] == c["cluster"]][0])]}
                                    for c in chosen if c["texels"]]}
        log(f"writing {out}: the model (its energy-bound checks) and {len(maps.layers)} layer(s) of maps")
        maps.save(out, extra={REPORT_FILE: (json.dumps(maps.report, indent=1) + "\n").encode()})
        if os.path.lexists(ckpt):
            os.unlink(ckpt)
    return maps
