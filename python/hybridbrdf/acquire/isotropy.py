"""Observations turned about the normal: the acquisition fits' isotropy assumption (issue 61 part 2;
docs/ACQUISITION_GAP.md, "Rows turned about the normal").

An isotropic BRDF depends on the directions only through theta_i, theta_o and the azimuth between
them, phi_i - phi_o: turning both directions of an observation about the surface normal by any
angle leaves its value unchanged. A rig photographs from a few fixed azimuths (a light stage's
lights and cameras, a phone's positions), and every model the fits use is a function of the
absolute azimuth too: anisotropic GGX's two roughnesses and the network's inputs. Fitted to the rows
as photographed, the fit learns azimuth-dependent detail the material does not have, and it shows
where no photograph looked: on paper_white from 32 light-stage photographs without noise, the
fitted texel's cMAE was 1.52x the full measurement's, and the same fit averaged over 16 turns about
the normal 1.36x (a diagnostic, not kept). With each row turned by its own uniformly drawn azimuth
(:func:`turned_about_normal`) every observation stays exact for an isotropic material and the
photographs' azimuths are spread over the circle; the fit is then 1.30x.

The assumption is the fits' default (``hbrdf acquire fit``; ``--anisotropic`` keeps the azimuths as
photographed, for brushed metals and fabrics whose anisotropy the photographs should decide). A row's
turn is drawn from the seed and the row's index, so a fit stays reproducible."""

from __future__ import annotations

import dataclasses

import numpy as np

from hybridbrdf.acquire.observations import Observations


def rotate_about_normal(w: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Directions ``w`` (M, 3) turned about the local z axis (the normal) by ``phi`` (M,) radians."""
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([c * w[:, 0] - s * w[:, 1], s * w[:, 0] + c * w[:, 1], w[:, 2]], axis=1).astype(w.dtype)


def turned_about_normal(obs: Observations, seed: int) -> Observations:
    """A copy of ``obs`` whose every row's (wi, wo) is turned about the normal by its own azimuth,
    uniform over [0, 2 pi) and drawn with ``seed``: theta_i, theta_o and phi_i - phi_o kept (so an
    isotropic BRDF's value at every row is unchanged), values, uv, shots and offsets shared."""
    phi = np.random.default_rng([int(seed), 0x150]).uniform(0.0, 2.0 * np.pi, len(obs.wi))
    return dataclasses.replace(obs, wi=rotate_about_normal(obs.wi, phi), wo=rotate_about_normal(obs.wo, phi))
