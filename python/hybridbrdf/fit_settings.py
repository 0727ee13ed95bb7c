"""The settings of a fit, defined once (no torch needed to read them).

:class:`FitSettings` is recorded in every model file (``training``); its fields carry the
command line's flags, help texts and defaults (:func:`hybridbrdf.cli.add_fit_flags`), the
section ``hbrdf info`` prints each one in, and through :func:`hybridbrdf.cli.fit_synopsis`
the README's synopsis.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field
from typing import List, Optional

from hybridbrdf import spec

ARCHS = tuple(spec.ARCHS)
ACTIVATIONS = tuple(spec.ACTIVATIONS)

#: Starting points of sparse fitting (FitSettings.sparse_init).
SPARSE_INITS = ("nearest", "neutral")


def _setting(default, help: str, section: str, flag: Optional[str] = None, **cli):
    """A FitSettings field with what the command line, ``hbrdf info`` and the docs say of it:
    ``help`` (argparse text; %(default)s allowed), ``section`` ("network", "training",
    "loss", "sparse" or "run": where ``hbrdf info`` prints it), ``flag`` (None: no flag of
    its own) and argparse keywords (``type``, ``choices``, ``metavar``, ``action``)."""
    meta = {"help": help, "section": section, "flag": flag, "cli": cli}
    if isinstance(default, list):
        return field(default_factory=list, metadata=meta)
    return field(default=default, metadata=meta)


def positive_int(text: str) -> int:
    """argparse type: a positive integer ("2e4" allowed); rejects inf, nan and fractions."""
    try:
        v = float(text)
        if not math.isfinite(v) or v != int(v):
            raise ValueError
        v = int(v)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


@dataclass
class FitSettings:
    """Everything that defines a fit; recorded in the model file.

    The one definition of the fit settings: ``hbrdf fit``'s flags, their help and defaults
    (:func:`hybridbrdf.cli.build_parser`), the settings ``hbrdf info`` prints and the README's
    synopsis (:func:`fit_synopsis`, checked by a test) all come from these fields."""

    arch: str = _setting("hybrid", "model architecture (default: %(default)s)", "network", "--arch",
                         choices=ARCHS)
    #: width and depth share one flag, --mlp WIDTHxDEPTH.
    width: int = _setting(32, "hidden layers as WIDTHxDEPTH (default: 32x3)", "network", "--mlp", metavar="WxD")
    depth: int = _setting(3, "set by --mlp", "network")
    latent: int = _setting(4, "latent dimensions per material (default: 4, or 12 for --arch neural)", "network",
                           "--latent", type=int)
    activation: str = _setting("hardgelu", "hidden activation (default: %(default)s)", "network", "--activation",
                               choices=ACTIVATIONS)
    steps: int = _setting(2000, "optimiser steps (default: %(default)s)", "training", "--steps", type=positive_int)
    batch: int = _setting(1024, "direction pairs per step (default: %(default)s)", "training", "--batch",
                          type=positive_int)
    lr: float = _setting(5e-3, "AdamW learning rate, cosine-decayed (default: %(default)s)", "training", "--lr",
                         type=float)
    clip: float = _setting(0.01, "gradient-norm clipping (the paper's 0.01)", "training")
    weight_decay: float = _setting(
        0.01, "AdamW weight decay of the shared network (not of p or z) (default: %(default)s, torch's default, "
        "which the paper's AdamW implies)", "training", "--weight-decay", type=float)
    seed: int = _setting(0, "random seed (default: %(default)s)", "training", "--seed", type=int)
    pool: int = _setting(1 << 18, "direction pairs in the training pool, evaluated once per source "
                         "(default: %(default)s)", "training", "--pool", type=positive_int)
    eval_pairs: int = _setting(100_000, "pairs for the metrics stored with the model (default: %(default)s; "
                               "CONVENTIONS uses 1e6)", "training", "--eval-pairs", type=positive_int)
    #: epsilon of the loss log(eps + cos f); 1 is the paper's log(1 + cos f). Smaller values make the
    #: loss relative in dark regions (see docs/FITTING.md, "Dark regions").
    loss_eps: float = _setting(1.0, "epsilon of the loss log(eps + cos f); 1 = the paper's log(1 + cos f), smaller "
                               "values weigh relative errors in dark regions (default: %(default)s)", "loss",
                               "--loss-eps", type=float)
    #: scale the loss epsilon per material by its mean cos f_ref over the cosine-weighted pool pairs
    #: (eps_m = loss_eps * mean cos f_ref), which makes the loss invariant to a material's brightness.
    #: See docs/FITTING.md, "Dark materials".
    loss_eps_relative: bool = _setting(False, "scale --loss-eps per material by its mean cos f (brightness-invariant "
                                       "loss; for collections with very dark materials)", "loss",
                                       "--loss-eps-relative", action="store_true")
    #: epsilon of the analytic term L(f_ref, f_a) of the loss; None uses ``loss_eps``. Scaled per
    #: material like ``loss_eps`` when ``loss_eps_relative``. An ablation knob: a larger value makes
    #: the analytic term nearly linear and small beside the hybrid term, f_a then drifts and the
    #: hybrid loses too (measured in docs/FITTING.md, "The analytic term's epsilon").
    analytic_loss_eps: Optional[float] = _setting(
        None, "epsilon of the analytic term L(f_ref, f_a) of the loss (default: --loss-eps); an ablation knob: a "
        "larger value lets f_a drift and costs the hybrid too (docs/FITTING.md)", "loss", "--analytic-loss-eps",
        type=float, metavar="EPS")
    #: weigh f by cos(theta_i) inside the loss, log(eps + cos f), as the paper does. False fits
    #: log(eps + f): grazing pairs, whose cos f falls below eps, then keep their relative weight
    #: (docs/FITTING.md, "Grazing angles"); with ``loss_eps_relative`` eps then scales with mean f.
    loss_cos: bool = _setting(True, "fit log(eps + f) instead of the paper's log(eps + cos f), so grazing angles "
                              "keep their relative weight (docs/FITTING.md, \"Grazing angles\")", "loss",
                              "--loss-no-cos", action="store_false")
    #: expectile tau of the analytic term (Newey & Powell 1987, asymmetric least squares): errors
    #: where f_a falls *below* f_ref weigh 2 tau, errors above weigh 2 (1 - tau). 0.5 is the paper's
    #: symmetric loss; tau > 0.5 fits f_a as an upper envelope of the data, which the gate
    #: f_g in (0, 1) can dim where f_a overshoots, instead of a compromise whose peak the
    #: correction exp(o) must build (docs/FITTING.md, "An upper envelope for the analytic part").
    analytic_expectile: float = _setting(
        0.5, "expectile tau in [0.5, 1) of the analytic loss term: tau > 0.5 weighs f_a below the data more, "
        "fitting an upper envelope the gate can dim (default: %(default)s, the paper's loss)", "loss",
        "--analytic-expectile", type=float)
    #: fraction of the training pool drawn around the mirror configuration (half vector from a GGX
    #: distribution of roughness ``specular_alpha``) instead of cosine-weighted; 0 is the paper's
    #: sampling. See docs/FITTING.md, "Specular pairs".
    specular: float = _setting(0.0, "fraction of the training pool drawn around the mirror direction instead of "
                               "cosine-weighted; weighs the specular peaks that dominate cMAE (default: %(default)s, "
                               "the paper's sampling)", "loss", "--specular", type=float)
    specular_alpha: float = _setting(0.1, "GGX roughness of the half-vector distribution of --specular pairs "
                                     "(default: %(default)s)", "loss", "--specular-alpha", type=float)
    #: initial pre-exp bias of the hybrid correction f_c (f_c starts at exp(fc_init)).
    fc_init: float = _setting(-4.0, "initial pre-exp bias of the hybrid correction f_c = exp(o) "
                              "(default: %(default)s)", "loss", "--fc-init", type=float)
    #: where sparse fitting (``frozen=``) starts each new material's (p, z): "nearest" copies the
    #: frozen model's material whose (p, z) has the lowest training loss on the new material's
    #: pool; "neutral" starts from the joint fit's grey rough dielectric with z ~ 0. See
    #: docs/FITTING.md, "Sparse fitting".
    sparse_init: str = _setting("nearest", "with --frozen: start each source's (p, z) from MODEL's best-fitting "
                                "material (nearest) or from the neutral grey rough lobe with z ~ 0 (neutral) "
                                "(default: %(default)s)", "sparse", "--sparse-init", choices=SPARSE_INITS)
    device: str = _setting("cpu", "torch device (default: cuda when available, else cpu)", "run", "--device", metavar="DEVICE")
    sources: List[str] = _setting([], "the sources' specs as given", "run")
    frozen_from: Optional[str] = _setting(None, "sparse fitting: keep MODEL's network, fit only (p, z) of the "
                                          "sources", "sparse", "--frozen", metavar="MODEL")

    def check(self) -> None:
        for name in ("width", "depth", "steps", "batch", "pool", "eval_pairs"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if self.latent < 0:
            raise ValueError(f"latent must be >= 0, got {self.latent}")
        if not (self.lr > 0 and math.isfinite(self.lr)):
            raise ValueError(f"lr must be positive, got {self.lr}")
        if not (self.weight_decay >= 0 and math.isfinite(self.weight_decay)):
            raise ValueError(f"weight_decay must be >= 0, got {self.weight_decay}")
        if not (self.loss_eps > 0 and math.isfinite(self.loss_eps)):
            raise ValueError(f"loss_eps must be positive, got {self.loss_eps}")
        if self.analytic_loss_eps is not None and not (self.analytic_loss_eps > 0
                                                       and math.isfinite(self.analytic_loss_eps)):
            raise ValueError(f"analytic_loss_eps must be positive, got {self.analytic_loss_eps}")
        if not 0.5 <= self.analytic_expectile < 1.0:
            raise ValueError(f"analytic_expectile must be in [0.5, 1), got {self.analytic_expectile}")
        if not 0.0 <= self.specular <= 1.0:
            raise ValueError(f"specular must be in [0, 1], got {self.specular}")
        if not (0.0 < self.specular_alpha <= 1.0):
            raise ValueError(f"specular_alpha must be in (0, 1], got {self.specular_alpha}")
        if self.sparse_init not in SPARSE_INITS:
            raise ValueError(f"sparse_init must be one of {', '.join(SPARSE_INITS)}, got {self.sparse_init!r}")


def parse_mlp(text: str):
    """'32x3' -> (width 32, depth 3)."""
    try:
        w, d = text.lower().split("x")
        width, depth = int(w), int(d)
    except ValueError:
        raise ValueError(f"--mlp must look like WIDTHxDEPTH (e.g. 32x3), got {text!r}") from None
    if width < 1 or depth < 1:
        raise ValueError(f"--mlp needs positive width and depth, got {text!r}")
    return width, depth
