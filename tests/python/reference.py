"""CONVENTIONS.md transcribed literally in NumPy float64: the textbook forms
(G1 = 2 / (1 + sqrt(1 + ...)), Fresnel with (g - c)/(g + c)), none of the
library's rewrites or guards. An independent oracle for unit directions
strictly above the horizon."""

import numpy as np


def textbook_fa(wi, wo, kd, eta, alpha):
    kd, eta = np.asarray(kd, float), np.asarray(eta, float)
    ax, ay = float(alpha[0]), float(alpha[1])
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    t = (h[:, 0] / ax) ** 2 + (h[:, 1] / ay) ** 2 + h[:, 2] ** 2
    D = 1.0 / (np.pi * ax * ay * t * t)

    def G1(w):
        return 2.0 / (1.0 + np.sqrt(1.0 + (ax * ax * w[:, 0] ** 2 + ay * ay * w[:, 1] ** 2) / w[:, 2] ** 2))

    G = G1(wi) * G1(wo)
    c = (wo * h).sum(axis=1)[:, None]
    g = np.sqrt(eta[None, :] ** 2 - 1.0 + c * c)
    q1 = (g - c) / (g + c)
    q2 = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    F = 0.5 * q1 * q1 * (1.0 + q2 * q2)
    return kd[None, :] / np.pi + F * (D * G / (4.0 * wi[:, 2] * wo[:, 2]))[:, None]
