"""Spectral tools of the thin-film material (``synthetic:thin_film``): the CIE 1931 colour-matching
functions, spectral-to-linear-sRGB weights and the Airy thin-film reflectance, integrated over
:data:`WAVELENGTHS_NM`."""

from __future__ import annotations

import numpy as np

#: Wavelengths (nm) at which the thin-film reflectance is integrated: 380-780 nm
#: in 5 nm steps. The interference phase 2 eta_film d cos / lambda (cycles) moves
#: by 2 eta_film d x 5 nm / lambda^2 between samples: at most 0.1 cycle at 380 nm
#: for an optical thickness eta_film d <= MAX_OPTICAL_THICKNESS_NM, so the sum
#: resolves every fringe (0.06 cycle for the built-in film).
WAVELENGTHS_NM = np.linspace(380.0, 780.0, 81)
MAX_OPTICAL_THICKNESS_NM = 1500.0

#: CIE XYZ -> linear sRGB (Rec. 709 primaries, D65 white; IEC 61966-2-1).
XYZ_TO_LINEAR_SRGB = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)


def cie1931_xyz(wavelength_nm) -> np.ndarray:
    """CIE 1931 2-degree colour matching functions, (L,) -> (L, 3).

    The multi-lobe piecewise-Gaussian fit of Wyman, Sloan & Shirley 2013,
    "Simple Analytic Approximations to the CIE XYZ Color Matching Functions",
    JCGT 2(2), Sec. 2.1 (within about 1% of the tabulated functions), so that
    the library carries no table.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)

    def g(mu, inv_sigma_lo, inv_sigma_hi):
        t = (lam - mu) * np.where(lam < mu, inv_sigma_lo, inv_sigma_hi)
        return np.exp(-0.5 * t * t)

    x = 0.362 * g(442.0, 0.0624, 0.0374) + 1.056 * g(599.8, 0.0264, 0.0323) - 0.065 * g(501.1, 0.0490, 0.0382)
    y = 0.821 * g(568.8, 0.0213, 0.0247) + 0.286 * g(530.9, 0.0613, 0.0322)
    z = 1.217 * g(437.0, 0.0845, 0.0278) + 0.681 * g(459.0, 0.0385, 0.0725)
    return np.stack([x, y, z], axis=-1)


def spectral_to_rgb_weights(wavelength_nm, cmf=None) -> np.ndarray:
    """Weights W (3, L) with rgb = W @ R(lambda) for a reflectance spectrum R.

    W = diag(1 / (M X 1)) M X^T with X the colour matching functions at the
    sample wavelengths (``cmf``, default :func:`cie1931_xyz`) and M the
    XYZ -> linear sRGB matrix: reflectances are integrated under an
    equal-energy illuminant and white-balanced per channel, so that a flat
    spectrum R(lambda) = r maps to rgb = (r, r, r) exactly (each row of W
    sums to 1). Rows have negative entries: saturated spectra can fall
    outside [0, 1] and are clamped by the caller.
    """
    xyz = cie1931_xyz(wavelength_nm) if cmf is None else np.asarray(cmf, dtype=np.float64)
    w = XYZ_TO_LINEAR_SRGB @ xyz.T  # (3, L)
    return w / w.sum(axis=1, keepdims=True)


def _amplitude(a, b):
    """Fresnel amplitude (a - b) / (a + b) for a, b >= 0; -1 where both vanish
    (an interface between equal indices met at exactly grazing incidence:
    the limit from above)."""
    den = a + b
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0.0, (a - b) / np.where(den > 0.0, den, 1.0), -1.0)


def thin_film_reflectance(cos_theta_i, eta_film: float, thickness_nm: float, eta_base: float,
                          wavelength_nm) -> np.ndarray:
    """Airy reflectance of a dielectric film on a dielectric base, (M,) x (L,) -> (M, L).

    Light comes from air (index 1), crosses a non-absorbing film of index
    ``eta_film`` and thickness ``thickness_nm`` and meets a dielectric base
    ``eta_base`` (both >= 1, non-dispersive). Per polarisation the reflected
    amplitude is the Airy sum of all internal reflections (Born & Wolf 1.6.4;
    Belcour & Barla 2017, "A Practical Extension to Microfacet Theory for the
    Modeling of Varying Iridescence", ACM TOG 36(4), Sec. 3):

        r = (r12 + r23 e^{i delta}) / (1 + r12 r23 e^{i delta}),
        delta = 4 pi eta_film d cos(theta_2) / lambda,

    with real Fresnel amplitudes r12, r23 (s: (n_a c_a - n_b c_b)/(n_a c_a +
    n_b c_b), p: (n_b c_a - n_a c_b)/(n_b c_a + n_a c_b)). All cosines are
    real because eta_film, eta_base >= 1 (no total internal reflection), so
    |r|^2 = (r12^2 + r23^2 + 2 r12 r23 cos delta) / (1 + r12^2 r23^2 + 2 r12
    r23 cos delta), evaluated as 1 - (1 - r12^2)(1 - r23^2) / (1 + r12^2 r23^2
    + 2 r12 r23 cos delta) (the same value). Returns (R_s + R_p) / 2. With
    d = 0, eta_film = 1 or eta_film = eta_base it reduces to the
    single-interface Fresnel formula.
    """
    c1 = np.clip(np.asarray(cos_theta_i, dtype=np.float64), 0.0, 1.0)[:, None]
    inv_lam = 1.0 / np.asarray(wavelength_nm, dtype=np.float64)[None, :]
    n2, n3 = float(eta_film), float(eta_base)
    sin2_1 = (1.0 - c1) * (1.0 + c1)
    c2 = np.sqrt(1.0 - sin2_1 / (n2 * n2))  # real: n2 >= 1
    c3 = np.sqrt(1.0 - sin2_1 / (n3 * n3))  # real: n2 sin(theta_2) = sin(theta_1) <= 1 <= n3
    cos_delta = np.cos(((4.0 * np.pi * n2 * thickness_nm) * c2) * inv_lam)
    # |1 + r12 r23 e^{i delta}|^2 - |r12 + r23 e^{i delta}|^2 = (1 - r12^2)(1 - r23^2), so
    # R = 1 - (1 - r12^2)(1 - r23^2) / |1 + r12 r23 e^{i delta}|^2: one division per
    # sample, and exactly 1 where the film transmits nothing (r12 = -1 at grazing).
    loss = np.zeros(np.broadcast_shapes(c1.shape, inv_lam.shape))
    for r12, r23 in (
        (_amplitude(c1, n2 * c2), _amplitude(n2 * c2, n3 * c3)),  # s
        (_amplitude(n2 * c1, c2), _amplitude(n3 * c2, n2 * c3)),  # p
    ):
        transmit = 0.5 * (1.0 - r12 * r12) * (1.0 - r23 * r23)
        den = (2.0 * r12 * r23) * cos_delta
        den += 1.0 + r12 * r12 * r23 * r23
        # den vanishes only for a free film (eta_base = 1) at exactly grazing
        # incidence, where transmit = 0 too and |r| -> 1.
        np.maximum(den, np.finfo(np.float64).tiny, out=den)
        np.divide(transmit, den, out=den)
        loss += den
    return 1.0 - loss
