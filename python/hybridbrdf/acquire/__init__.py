"""SVBRDF acquisition from photographs (issue 46; docs/ACQUISITION.md).

- :mod:`~hybridbrdf.acquire.rig`: a rig's cameras, lights and shots, its JSON file and checks;
- :mod:`~hybridbrdf.acquire.rigs`: rigs of real set-ups (a phone's flash, a light stage);
- :mod:`~hybridbrdf.acquire.geometry`: what each pixel sees (uv, wi, wo, distance to the light);
- :mod:`~hybridbrdf.acquire.mixture`: the ground truth, an exact mixture of measured BRDFs;
- :mod:`~hybridbrdf.acquire.noise`: the sensor's Poisson-Gaussian noise;
- :mod:`~hybridbrdf.acquire.simulate`: the photographs; :mod:`~hybridbrdf.acquire.capture`: their folder;
- :mod:`~hybridbrdf.acquire.observations`: the photographs turned back into BRDF values per texel (a fit's input).
- :mod:`~hybridbrdf.acquire.exposure`: the pixels a fit may use (NaN pixels, under-exposed photographs);
- :mod:`~hybridbrdf.acquire.texel_rows`: rows drawn per texel per step, the resumable Adam loop;
- per-texel fits, each with ``.eval(texel, wi, wo)`` (:mod:`~hybridbrdf.acquire.evaluation`) and ``.counts``:
  :mod:`~hybridbrdf.acquire.texel_fit` (analytic only), :mod:`~hybridbrdf.acquire.hybrid_fit` (p, z on a
  frozen prior; the textured material), :mod:`~hybridbrdf.acquire.neural_fit` (a latent per texel), their
  shared stages in :mod:`~hybridbrdf.acquire.cluster_fit`;
- :mod:`~hybridbrdf.acquire.acquisition`: ``hbrdf acquire fit``'s run (checks, masking, checkpoint, output).

    rig = flash_rig(16, size=(512, 512))
    mixture = Mixture.painted(open_source("synthetic:plastic"), [open_source("synthetic:gold")], [mask])
    write_capture(simulate(rig, mixture, NoiseModel(photons=1000, read_noise=2), seed=1), "capture")
    acquire("capture", "acquired", size=(128, 128))   # per-texel (p, z) on the shipped prior
"""
