"""The settings of a fit, defined once (no torch needed to read them).

:class:`FitSettings` is recorded in every model file (``training``); its fields carry the
command line's flags, help texts and defaults (:func:`hybridbrdf.cli.add_fit_flags`), the
section ``hbrdf info`` prints each one in, and through :func:`hybridbrdf.cli.fit_synopsis`
the README's synopsis.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field, fields
from typing import List, Optional

from hybridbrdf import spec

ARCHS = tuple(spec.ARCHS)
ACTIVATIONS = tuple(spec.ACTIVATIONS)
OUTPUT_LAYERS = tuple(spec.OUTPUT_LAYERS)

#: Starting points of sparse fitting (FitSettings.sparse_init).
SPARSE_INITS = ("nearest", "neutral")

#: Learning-rate decays over a fit's steps (FitSettings.lr_schedule): ``cosine`` from lr to 0 (the
#: paper's), ``exponential`` from lr to lr * lr_final at a constant rate, which spends a larger
#: share of the steps at small rates (docs/LOSS.md, "The learning-rate decay").
LR_SCHEDULES = ("cosine", "exponential")

#: Named sets of defaults (``--recipe``). ``hybridbrdf``, the default, is the field defaults of
#: :class:`FitSettings`, each chosen on a measured figure (docs/FITTING.md, "Defaults and the
#: figures they come from"); ``paper`` reproduces the paper's Sec. 3.3 settings (AdamW at
#: PyTorch's default decay, log(1 + cos f), symmetric loss, cosine-weighted pairs only, 200k
#: steps, 32x3, latent 4) for comparison; ``fast`` fits an RGL-sized collection in under half an
#: hour on two CPU cores: the default loss at a higher learning rate, decayed exponentially, on a
#: 16x2 network with material output layers, which needs no (p, z) refit afterwards where one
#: shared output layer did (docs/LOSS.md, "Fitting in 30 minutes", holds the figures). The default
#: architecture is ``hybrid-reciprocal``; ``paper`` keeps the paper's ``hybrid``, and so does ``fast``,
#: where the reciprocal 16x2 network measured 4-10% higher mean SMAPE on RGL 54 over two seeds
#: (docs/RECIPROCITY.md, "Reciprocal by default"). A flag given explicitly overrides its recipe value.
RECIPES = {
    "hybridbrdf": {},
    "paper": dict(arch="hybrid", width=32, depth=3, latent=4, steps=200_000, batch=1024, lr=5e-3, clip=0.01, weight_decay=0.01,
                  loss_eps=1.0, loss_eps_relative=False, analytic_loss_eps=None, loss_cos=True,
                  analytic_expectile=0.5, specular=0.0, output_layer="shared"),
    "fast": dict(arch="hybrid", width=16, depth=2, latent=4, steps=58_000, batch=1024, lr=4e-2, lr_schedule="exponential",
                 lr_final=0.01, loss_eps=0.01, analytic_expectile=0.9, specular=0.1, output_layer="material"),
}
RECIPE_NAMES = tuple(RECIPES)

#: Steps of a sparse fit (``hbrdf add``, :func:`hybridbrdf.add`) when none are given: four times
#: as many end no better in cMAE (docs/BENCHMARKS_HISTORY.md, "Adding measurements later"), and
#: these keep adding a material within its budget of minutes.
ADD_STEPS = 5000

#: Loss epsilon of ``hbrdf add`` (both its sparse fit and its fine-tune) when no recipe or
#: --loss-eps is given: a loss more relative in dark regions than a joint fit's 0.1. Chosen on 29
#: materials no prior had seen, on both metrics (docs/ADDING.md, "`hbrdf add`'s loss epsilon"): the
#: prior-minus-five rows beat the released model 5 of 5 with a mean SMAPE below the joint fit's,
#: which neither 0.1 (SMAPE) nor 0.01 (4 of 5) does.
ADD_LOSS_EPS = 0.03

#: Steps of ``hbrdf add``'s fine-tune onto the shipped prior (after its ADD_STEPS sparse steps):
#: the network trained together with the new materials (docs/ADDING.md, "Adding to the prior").
FINETUNE_STEPS = 5000

#: ``hbrdf add --refine``'s limit on how far a base material may move: SMAPE of the refined
#: model against the base's own output on the metric pairs (docs/ADDING.md, "Refining a
#: collection"). 0.75: above the largest drift of the measured NBRDF-MERL refine (a dark material,
#: where SMAPE is most sensitive; its figures are in docs/ADDING.md), so the limit refuses a
#: refine that moves a material further than any of those did (SMAPE 2 is a material replaced by
#: another).
MAX_DRIFT = 0.75


def _setting(default, help: str, section: str, flag: Optional[str] = None, **cli):
    """A FitSettings field with what the command line, ``hbrdf info`` and the docs say of it:
    ``help`` (argparse text; %(default)s allowed), ``section`` ("network", "training",
    "loss", "sparse" or "run": where ``hbrdf info`` prints it), ``flag`` (None: no flag of
    its own) and argparse keywords (``type``, ``choices``, ``metavar``, ``action``)."""
    meta = {"help": help, "section": section, "flag": flag, "cli": cli}
    if isinstance(default, list):
        return field(default_factory=list, metadata=meta)
    return field(default=default, metadata=meta)


class Number:
    """The range of a numeric setting, in one place for the command line and for Python.

    ``Number(int, 1, 10**9)(text)`` is an argparse type: it parses ``text`` ("2e4" allowed for
    integers) and raises ``argparse.ArgumentTypeError`` (argparse prints one line) for inf, nan,
    fractions and values outside the range; :meth:`problem` is the same check of a value set
    from Python or read from a checkpoint (:meth:`FitSettings.check`). Every number is finite:
    inf and nan mean nothing in a fit setting and would surface hours later as an
    OverflowError or a NaN loss."""

    def __init__(self, kind: type, lo: float, hi: float, lo_open: bool = False, hi_open: bool = False):
        self.kind, self.lo, self.hi, self.lo_open, self.hi_open = kind, lo, hi, lo_open, hi_open

    def describe(self) -> str:
        """The range in words: "an integer in [1, 1000000000]", "a number > 0"."""
        noun = "an integer" if self.kind is int else "a number"
        fmt = str if self.kind is int else (lambda v: f"{v:g}")
        if math.isinf(self.hi) and math.isinf(self.lo):
            return f"a finite {noun.split()[-1]}"
        if math.isinf(self.hi):
            return f"{noun} {'>' if self.lo_open else '>='} {fmt(self.lo)}"
        return (f"{noun} in {'(' if self.lo_open else '['}{fmt(self.lo)}, "
                f"{fmt(self.hi)}{')' if self.hi_open else ']'}")

    def problem(self, value) -> Optional[str]:
        """Why ``value`` is not in the range ("must be ..., got ..."), or None."""
        ok_type = isinstance(value, int) if self.kind is int else isinstance(value, (int, float))
        if isinstance(value, bool) or not ok_type:
            return f"must be {self.describe()}, got {value!r}"
        if isinstance(value, float) and not math.isfinite(value):  # (an int may pass float's range: no float())
            return f"must be {self.describe()}, got {value!r}"
        below = value <= self.lo if self.lo_open else value < self.lo
        above = value >= self.hi if self.hi_open else value > self.hi
        return f"must be {self.describe()}, got {value!r}" if below or above else None

    def __call__(self, text: str):
        try:
            value = self._parse(text)
        except (ValueError, OverflowError):
            value = None
        if value is None or self.problem(value):
            raise argparse.ArgumentTypeError(f"expected {self.describe()}, got {text!r}")
        return value

    def _parse(self, text: str):
        if self.kind is float:
            return float(text)
        try:
            return int(text)
        except ValueError:
            v = float(text)  # "2e4"; inf and nan fail below, fractions too
            if not math.isfinite(v) or v != int(v):
                raise ValueError(text) from None
            return int(v)


#: The largest count any integer flag takes (steps, --checkpoint-every, --pairs): far beyond any
#: real run (the paper trained 200k steps) and small enough that no count overflows a torch
#: index or a float64 schedule.
MAX_COUNT = 10 ** 9
STEPS = Number(int, 1, MAX_COUNT)
#: Direction pairs per step: 2^24 pairs x materials already needs gigabytes for the network's activations.
BATCH = Number(int, 1, 1 << 24)
#: Training pool pairs: 2^30 x 3 float32 values per source is 12 GiB a material.
POOL = Number(int, 1, 1 << 30)
#: Metric pairs: 10^8 pairs take ~10 GiB of float64 directions and values (CONVENTIONS uses 10^6).
PAIRS = Number(int, 1, 10 ** 8)
LATENT = Number(int, 0, spec.MAX_LATENT)
#: Seeds NumPy and torch both take.
SEED = Number(int, 0, 2 ** 32 - 1)
POSITIVE = Number(float, 0.0, math.inf, lo_open=True)
NON_NEGATIVE = Number(float, 0.0, math.inf)
UNIT = Number(float, 0.0, 1.0)
EXPECTILE = Number(float, 0.5, 1.0, hi_open=True)
SPECULAR_ALPHA = Number(float, 0.0, 1.0, lo_open=True)
LR_FINAL = Number(float, 0.0, 1.0, lo_open=True)
#: f_c starts at exp(fc_init): above the pre-exp clamp it would be clamped, below -80 it is 0 in float32.
FC_INIT = Number(float, -spec.PRE_EXP_MAX_LIMIT, spec.PRE_EXP_MAX)


def positive_int(text: str) -> int:
    """argparse type: a positive integer up to :data:`MAX_COUNT` ("2e4" allowed); rejects inf,
    nan, fractions and larger values with a one-line error."""
    return STEPS(text)


@dataclass
class FitSettings:
    """Everything that defines a fit; recorded in the model file.

    The one definition of the fit settings: ``hbrdf fit``'s flags, their help and defaults
    (:func:`hybridbrdf.cli.build_parser`), the settings ``hbrdf info`` prints and the README's
    synopsis (:func:`fit_synopsis`, checked by a test) all come from these fields."""

    #: hybrid-reciprocal by default (issue 60): exactly reciprocal, f(wi, wo) = f(wo, wi), and measured at
    #: least as faithful as ``hybrid`` with this recipe (docs/RECIPROCITY.md, "Reciprocal by default");
    #: the ``fast`` and ``paper`` recipes keep ``hybrid``.
    arch: str = _setting("hybrid-reciprocal", "model architecture (default: %(default)s; --recipe fast and paper: "
                         "hybrid)", "network", "--arch", choices=ARCHS)
    #: width and depth share one flag, --mlp WIDTHxDEPTH.
    width: int = _setting(32, "hidden layers as WIDTHxDEPTH (default: 32x3)", "network", "--mlp", metavar="WxD")
    depth: int = _setting(3, "set by --mlp", "network")
    latent: int = _setting(4, "latent dimensions per material (default: 4, or 12 for --arch neural)", "network",
                           "--latent", type=LATENT)
    activation: str = _setting("hardgelu", "hidden activation (default: %(default)s)", "network", "--activation",
                               choices=ACTIVATIONS)
    #: "material": each material its own output layer, 6 x width + 6 floats (spec/model.json, output_layers).
    #: The default: on the synthetic materials it fits more accurately than one shared output layer,
    #: and the exact-f_a control (plastic) no longer ends worse than its f_a (docs/FITTING.md).
    output_layer: str = _setting("material", "output layer: each material's own ('material': 6 x width + 6 more floats "
                                 "per material, the same multiply-adds per evaluation; the neural baseline always shares its) or one "
                                 "shared by every material ('shared': the paper's model and recipe) "
                                 "(default: %(default)s; docs/FITTING.md)", "network", "--output-layer",
                                 choices=OUTPUT_LAYERS)
    #: bound every fitted material's directional albedo at spec.ENERGY_TARGET by a table k(cos theta)
    #: per material, f = k(wi.z) k(wo.z) f_t, computed after the fit (docs/ENERGY.md).
    #: never leave a material worse than its own f_a (the table's "!"): restart its correction, else
    #: remove it (material output layers only; docs/FITTING.md, "Never worse than f_a").
    analytic_guard: bool = _setting(True, "leave a material whose hybrid ends worse than its own f_a as it is (by "
                                    "default its correction is restarted from a neutral head on the fitted network, "
                                    "else removed so that it is its f_a; material output layers only; "
                                    "docs/FITTING.md, \"Never worse than f_a\")", "network", "--no-analytic-guard",
                                    action="store_false")
    energy_bound: bool = _setting(True, "do not bound the fitted materials' directional albedo (by default every "
                                  "material gets an energy-bound table after the fit, f = k(wi.z) k(wo.z) f_t with "
                                  "k <= 1, so that it reflects at most 0.99 of the light it receives; docs/ENERGY.md)",
                                  "network", "--no-energy-bound", action="store_false")
    #: the named set of defaults the settings started from (RECIPES); a label only: the values
    #: themselves are what a checkpoint compares.
    recipe: str = _setting("hybridbrdf", "defaults to start from: hybridbrdf (this project's measured best), paper "
                           "(the paper's Sec. 3.3 settings, for comparison) or fast (16x2 with material output layers at lr 0.04 decayed exponentially, 58k steps: "
                           "a 54-material collection in under 30 minutes on 2 cores with --compile; its f_a is an "
                           "upper envelope); flags given override them (default: %(default)s)", "training",
                           "--recipe", choices=RECIPE_NAMES)
    #: 120k: with half as many steps a collection's network left some sparse-added RGL files behind
    #: the released model, with these none (docs/BENCHMARKS_HISTORY.md, "Weight decay off").
    steps: int = _setting(120_000, f"optimiser steps (default: %(default)s; hbrdf add: {ADD_STEPS})", "training", "--steps",
                          type=STEPS)
    batch: int = _setting(1024, "direction pairs per step (default: %(default)s)", "training", "--batch",
                          type=BATCH)
    lr: float = _setting(5e-3, "AdamW learning rate at the first step, decayed by --lr-schedule (default: "
                         "%(default)s)", "training", "--lr", type=POSITIVE)
    lr_schedule: str = _setting("cosine", "decay of the learning rate over --steps: cosine (to 0) or exponential "
                                "(to --lr times --lr-final) (default: %(default)s)", "training", "--lr-schedule",
                                choices=LR_SCHEDULES)
    #: The exponential decay's last rate as a fraction of ``lr``. 0.01, two decades: from --recipe
    #: fast's rate it spends a large share of the last steps at the rates at which the default
    #: schedule's hardest highlight converged (docs/LOSS.md, "The learning-rate decay").
    lr_final: float = _setting(0.01, "with --lr-schedule exponential: the last step's learning rate as a fraction "
                               "of --lr (default: %(default)s)", "training", "--lr-final", type=LR_FINAL)
    clip: float = _setting(0.01, "gradient-norm clipping (the paper's 0.01)", "training")
    #: 0: decoupled decay shrinks a network shared by many materials by exp(-wd sum(lr)); without it
    #: more sparse-added RGL files beat the released model (docs/FITTING.md, "Defaults and the
    #: figures they come from"). The paper's AdamW implies torch's 0.01 (--recipe paper).
    weight_decay: float = _setting(
        0.0, "AdamW weight decay of the shared network (not of p or z) (default: %(default)s; --recipe paper: "
        "0.01, torch's default, which the paper's AdamW implies)", "training", "--weight-decay", type=NON_NEGATIVE)
    seed: int = _setting(0, "random seed (default: %(default)s)", "training", "--seed", type=SEED)
    pool: int = _setting(1 << 18, "direction pairs in the training pool, evaluated once per source "
                         "(default: %(default)s)", "training", "--pool", type=POOL)
    eval_pairs: int = _setting(100_000, "pairs for the metrics stored with the model (default: %(default)s; "
                               "CONVENTIONS uses 1e6)", "training", "--eval-pairs", type=PAIRS)
    #: epsilon of the loss log(eps + cos f); 1 is the paper's log(1 + cos f). Smaller values make the
    #: loss relative in dark regions (see docs/LOSS.md, "Dark regions").
    loss_eps: float = _setting(0.1, "epsilon of the loss log(eps + cos f); 1 = the paper's log(1 + cos f), smaller "
                               "values weigh relative errors in dark regions (default: %(default)s)", "loss",
                               "--loss-eps", type=POSITIVE)
    #: scale the loss epsilon per material by its mean cos f_ref over the cosine-weighted pool pairs
    #: (eps_m = loss_eps * mean cos f_ref), which makes the loss invariant to a material's brightness.
    #: See docs/LOSS.md, "Dark materials".
    loss_eps_relative: bool = _setting(False, "scale --loss-eps per material by its mean cos f (brightness-invariant "
                                       "loss; for collections with very dark materials)", "loss",
                                       "--loss-eps-relative", action="store_true")
    #: epsilon of the analytic term L(f_ref, f_a) of the loss; None uses ``loss_eps``. Scaled per
    #: material like ``loss_eps`` when ``loss_eps_relative``. An ablation knob: a larger value makes
    #: the analytic term nearly linear and small beside the hybrid term, f_a then drifts and the
    #: hybrid loses too (measured in docs/LOSS.md, "The analytic term's epsilon").
    analytic_loss_eps: Optional[float] = _setting(
        None, "epsilon of the analytic term L(f_ref, f_a) of the loss (default: --loss-eps); an ablation knob: a "
        "larger value lets f_a drift and costs the hybrid too (docs/FITTING.md)", "loss", "--analytic-loss-eps",
        type=POSITIVE, metavar="EPS")
    #: weigh f by cos(theta_i) inside the loss, log(eps + cos f), as the paper does. False fits
    #: log(eps + f): grazing pairs, whose cos f falls below eps, then keep their relative weight
    #: (docs/LOSS.md, "Grazing angles"); with ``loss_eps_relative`` eps then scales with mean f.
    loss_cos: bool = _setting(True, "fit log(eps + f) instead of the paper's log(eps + cos f), so grazing angles "
                              "keep their relative weight (docs/LOSS.md, \"Grazing angles\")", "loss",
                              "--loss-no-cos", action="store_false")
    #: expectile tau of the analytic term (Newey & Powell 1987, asymmetric least squares): errors
    #: where f_a falls *below* f_ref weigh 2 tau, errors above weigh 2 (1 - tau). 0.5 is the paper's
    #: symmetric loss; tau > 0.5 fits f_a as an upper envelope of the data, which the gate
    #: f_g in (0, 1) can dim where f_a overshoots, instead of a compromise whose peak the
    #: correction exp(o) must build (docs/LOSS.md, "An upper envelope for the analytic part").
    analytic_expectile: float = _setting(
        0.5, "expectile tau in [0.5, 1) of the analytic loss term: tau > 0.5 weighs f_a below the data more, "
        "fitting an upper envelope the gate can dim, for a hybrid whose f_a is never rendered alone "
        "(default: %(default)s, the paper's loss: f_a stays a fit)", "loss",
        "--analytic-expectile", type=EXPECTILE)
    #: fraction of the training pool drawn around the mirror configuration (half vector from a GGX
    #: distribution of roughness ``specular_alpha``) instead of cosine-weighted; 0 is the paper's
    #: sampling. See docs/LOSS.md, "Specular pairs".
    specular: float = _setting(0.1, "fraction of the training pool drawn around the mirror direction instead of "
                               "cosine-weighted; weighs the specular peaks that dominate cMAE (default: %(default)s; "
                               "0 is the paper's sampling)", "loss", "--specular", type=UNIT)
    specular_alpha: float = _setting(0.1, "GGX roughness of the half-vector distribution of --specular pairs "
                                     "(default: %(default)s)", "loss", "--specular-alpha", type=SPECULAR_ALPHA)
    #: initial pre-exp bias of the hybrid correction f_c (f_c starts at exp(fc_init)).
    fc_init: float = _setting(spec.FC_INIT, "initial pre-exp bias of the hybrid correction f_c = exp(o) "
                              "(default: %(default)s)", "loss", "--fc-init", type=FC_INIT)
    #: where sparse fitting (``frozen=``) starts each new material's (p, z): "nearest" copies the
    #: frozen model's material whose (p, z) has the lowest training loss on the new material's
    #: pool; "neutral" starts from the joint fit's grey rough dielectric with z ~ 0. See
    #: docs/ADDING.md, "Sparse fitting".
    sparse_init: str = _setting("nearest", "with --frozen: start each source's (p, z) from MODEL's best-fitting "
                                "material (nearest) or from the neutral grey rough lobe with z ~ 0 (neutral) "
                                "(default: %(default)s)", "sparse", "--sparse-init", choices=SPARSE_INITS)
    #: sparse fitting from several starts: the ``sparse_starts`` best-scoring materials of the frozen
    #: model each start one fit of every new material (all in one batch), and the fit with the
    #: lowest training loss is kept. See docs/ADDING.md, "Sparse fitting".
    sparse_starts: int = _setting(1, "with --frozen or hbrdf add (--sparse-init nearest): fit each source from its "
                                  "N best-scoring materials at once and keep the fit with the lowest training loss "
                                  "(costs N times the steps' work) (default: %(default)s)", "sparse",
                                  "--sparse-starts", type=Number(int, 1, 64), metavar="N")
    #: A warm start (``fit(init=...)``, ``hbrdf fit --init``, and the fine-tune of ``hbrdf add``):
    #: MODEL's network, every weight trained; each source starts from MODEL's material of the same
    #: name, else (sparse_init "nearest") from its best-fitting one. See docs/ADDING.md, "Warm starts".
    init_from: Optional[str] = _setting(None, "start from MODEL's network (trained further) and, per source, "
                                        "MODEL's material of the same name or else its best-fitting one; "
                                        "'prior' names the shipped prior of --arch (the reciprocal one by default); the network "
                                        "settings are MODEL's",
                                        "training", "--init", metavar="MODEL")
    #: The network's learning rate as a fraction of ``lr`` (per-material parameters keep ``lr``): a
    #: warm start that moves a fitted network slower than the new materials' (p, z).
    network_lr: float = _setting(1.0, "the network's learning rate as a fraction of --lr; the per-material "
                                 "parameters keep --lr (default: %(default)s)", "training", "--network-lr",
                                 type=POSITIVE)
    device: str = _setting("cpu", "torch device (default: cuda when available, else cpu)", "run", "--device", metavar="DEVICE")
    sources: List[str] = _setting([], "the sources' specs as given", "run")
    frozen_from: Optional[str] = _setting(None, "sparse fitting: keep MODEL's network, fit only (p, z) of the "
                                          "sources", "sparse", "--frozen", metavar="MODEL")

    @classmethod
    def from_recipe(cls, recipe: str = "hybridbrdf", **values) -> "FitSettings":
        """Settings of the named recipe (:data:`RECIPES`), with ``values`` overriding it:
        ``FitSettings.from_recipe("paper", steps=10_000)``."""
        if recipe not in RECIPES:
            raise ValueError(f"recipe must be one of {', '.join(RECIPE_NAMES)}, got {recipe!r}")
        return cls(**{**RECIPES[recipe], **values, "recipe": recipe})

    def network_output_layer(self) -> str:
        """The output layer the fit builds: ``output_layer``, except for the neural baseline, whose
        output layer is always shared (material output layers belong to the analytic architectures)."""
        return self.output_layer if spec.ARCHS.get(self.arch, {}).get("analytic", True) else "shared"

    def check(self) -> None:
        """Raise ValueError naming the first setting out of its range (the flags' own ranges,
        :class:`Number`, and the model contract's size limits)."""
        for f in fields(self):
            rng = f.metadata.get("cli", {}).get("type")
            value = getattr(self, f.name)
            if isinstance(rng, Number) and value is not None:
                problem = rng.problem(value)
                if problem:
                    raise ValueError(f"{f.name} {problem}")
        for name, limit in (("width", spec.MAX_WIDTH), ("depth", spec.MAX_DEPTH)):
            problem = Number(int, 1, limit).problem(getattr(self, name))
            if problem:
                raise ValueError(f"{name} {problem}")
        problem = POSITIVE.problem(self.clip)
        if problem:
            raise ValueError(f"clip {problem}")
        for name, choices in (("arch", ARCHS), ("activation", ACTIVATIONS), ("output_layer", OUTPUT_LAYERS),
                              ("sparse_init", SPARSE_INITS),
                              ("recipe", RECIPE_NAMES), ("lr_schedule", LR_SCHEDULES)):
            if getattr(self, name) not in choices:
                raise ValueError(f"{name} must be one of {', '.join(choices)}, got {getattr(self, name)!r}")


def parse_mlp(text: str):
    """'32x3' -> (width 32, depth 3), within the model contract's limits."""
    try:
        w, d = text.lower().split("x")
        width, depth = int(w), int(d)
    except ValueError:
        raise ValueError(f"--mlp must look like WIDTHxDEPTH (e.g. 32x3), got {text!r}") from None
    if not (1 <= width <= spec.MAX_WIDTH and 1 <= depth <= spec.MAX_DEPTH):
        raise ValueError(f"--mlp needs a width in [1, {spec.MAX_WIDTH}] and a depth in [1, {spec.MAX_DEPTH}], "
                         f"got {text!r}")
    return width, depth
