"""SVBRDF acquisition from photographs (issue 46; docs/ACQUISITION.md).

- :mod:`~hybridbrdf.acquire.rig`: a rig's cameras, lights and shots, its JSON file and checks;
- :mod:`~hybridbrdf.acquire.rigs`: rigs of real set-ups (a phone's flash, a light stage);
- :mod:`~hybridbrdf.acquire.geometry`: what each pixel sees (uv, wi, wo, distance to the light);
- :mod:`~hybridbrdf.acquire.mixture`: the ground truth, an exact mixture of measured BRDFs;
- :mod:`~hybridbrdf.acquire.noise`: the sensor's Poisson-Gaussian noise;
- :mod:`~hybridbrdf.acquire.simulate`: the photographs; :mod:`~hybridbrdf.acquire.capture`: their folder;
- :mod:`~hybridbrdf.acquire.observations`: the photographs turned back into BRDF values per texel (a fit's input).
- :mod:`~hybridbrdf.acquire.texel_fit`: fits per texel from the observations (analytic only so far).

    rig = flash_rig(16, size=(512, 512))
    mixture = Mixture.painted(open_source("synthetic:plastic"), [open_source("synthetic:gold")], [mask])
    write_capture(simulate(rig, mixture, NoiseModel(photons=1000, read_noise=2), seed=1), "capture")
"""
