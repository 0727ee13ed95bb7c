"""SVBRDF acquisition from photographs (issue 46; docs/ACQUISITION.md).

- :mod:`~hybridbrdf.acquire.rig`: a rig's cameras, lights and shots, its JSON file and checks;
- :mod:`~hybridbrdf.acquire.rigs`: rigs of real set-ups (a phone's flash, a light stage);
- :mod:`~hybridbrdf.acquire.geometry`: what each pixel sees (uv, wi, wo, distance to the light);
- :mod:`~hybridbrdf.acquire.mixture`: the ground truth, an exact mixture of measured BRDFs;
- :mod:`~hybridbrdf.acquire.noise`: the sensor's Poisson-Gaussian noise;
- :mod:`~hybridbrdf.acquire.simulation`: the photographs (:func:`simulate`); :mod:`~hybridbrdf.acquire.capture`: their folder;
- :mod:`~hybridbrdf.acquire.observations`: the photographs turned back into BRDF values per texel (a fit's input).
- :mod:`~hybridbrdf.acquire.exposure`: the pixels a fit may use (NaN pixels, under-exposed photographs);
- :mod:`~hybridbrdf.acquire.texel_rows`: rows drawn per texel per step, the resumable Adam loop;
- per-texel fits, each with ``.eval(texel, wi, wo)`` (:mod:`~hybridbrdf.acquire.evaluation`) and ``.counts``:
  :mod:`~hybridbrdf.acquire.texel_fit` (analytic only), :mod:`~hybridbrdf.acquire.hybrid_fit` (p, z on a
  frozen prior; the textured material), :mod:`~hybridbrdf.acquire.neural_fit` (a latent per texel), their
  shared stages in :mod:`~hybridbrdf.acquire.cluster_fit` (the cluster stage's choice on held-out
  photographs: :mod:`~hybridbrdf.acquire.select`);
- :mod:`~hybridbrdf.acquire.acquisition`: ``hbrdf acquire fit``'s run (checks, masking, checkpoint, output).

    rig = flash_rig(16, size=(512, 512))
    mixture = Mixture.painted(open_source("synthetic:plastic"), [open_source("synthetic:gold")], [mask])
    write_capture(simulate(rig, mixture, NoiseModel(photons=1000, read_noise=2), seed=1), "capture")
    acquire("capture", "acquired", size=(128, 128))   # per-texel (p, z) on the shipped prior

Its public names, one import deep: ``from hybridbrdf.acquire import flash_rig, Mixture, NoiseModel,
simulate, write_capture, acquire``, each loaded on first access (``Mixture``, ``simulate``, ``Capture``
and the capture folder's functions import PyTorch then): ``import hybridbrdf.acquire`` imports no NumPy.
"""

from hybridbrdf.exports import lazy_names, public_face

#: Every public name, loaded on first access (PEP 562): their modules import NumPy (Mixture's,
#: simulate's and the capture folder's PyTorch), and ``hbrdf acquire``'s parser reads
#: hybridbrdf.acquire.sizes (plain Python) without it.
_LAZY = {"acquire": "hybridbrdf.acquire.acquisition", "NoiseModel": "hybridbrdf.acquire.noise",
         **lazy_names(["Observations", "texel_observations"], "hybridbrdf.acquire.observations"),
         **lazy_names(["Camera", "Light", "Rig", "RigError", "Shot", "load_rig", "rig_from_dict"], "hybridbrdf.acquire.rig"),
         **lazy_names(["flash_rig", "light_stage_rig"], "hybridbrdf.acquire.rigs"),
         "Mixture": "hybridbrdf.acquire.mixture", **lazy_names(["Capture", "simulate"], "hybridbrdf.acquire.simulation"),
         **lazy_names(["CaptureError", "load_capture", "write_capture"], "hybridbrdf.acquire.capture")}

__all__ = ["Camera", "Capture", "CaptureError", "Light", "Mixture", "NoiseModel", "Observations", "Rig", "RigError",
           "Shot", "acquire", "flash_rig", "light_stage_rig", "load_capture", "load_rig", "rig_from_dict",
           "simulate", "texel_observations", "write_capture"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
