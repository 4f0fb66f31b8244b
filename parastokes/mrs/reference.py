"""Plain-numpy regularized Stokeslet kernels: the readable oracle.

Every formula is written once, as in the physics notes of docs/kernels.md (numbers in brackets
refer to them, "eq. N" to Liu & Rostami). Each function takes the pair differences of a set of
targets and sources as ``(M, N, 3)`` arrays and returns the velocity contribution summed over
sources, multiplied by μ (so the caller divides by the viscosity once). The compiled kernels in
:mod:`parastokes.mrs.compiled` must agree with these to round-off; the tests check it.

Blob: φ_ε(r) = 15 ε⁴ / (8π r_ε⁷) (eq. 3); torque parts regularized with ψ_ε(r) = 3ε²/(4π r_ε⁵)
("variant L", the default of the paper's authors), or with φ_ε too ("variant Φ", free space only:
:func:`rotlet_phi`, :func:`rotlet_phi_curl`).
"""

from __future__ import annotations

import numpy as np

EIGHT_PI = 8.0 * np.pi
E3 = np.array([0.0, 0.0, 1.0])


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...k,...k->...", a, b)


def _pairs(targets: np.ndarray, sources: np.ndarray) -> np.ndarray:
    return targets[:, None, :] - sources[None, :, :]


def stokeslet(r: np.ndarray, f: np.ndarray, eps: float) -> np.ndarray:
    """Force -> velocity, the regularized Stokeslet [1], eqs. 4 and 6 (times μ)."""
    r2 = _dot(r, r)
    re3 = (r2 + eps**2) ** 1.5
    h1 = (r2 + 2 * eps**2) / (EIGHT_PI * re3)
    h2 = 1.0 / (EIGHT_PI * re3)
    return np.sum(h1[..., None] * f + (h2 * _dot(f, r))[..., None] * r, axis=1)


def stokeslet_curl(r: np.ndarray, f: np.ndarray, eps: float) -> np.ndarray:
    """Force -> angular velocity w = ½ curl u [2] (times μ)."""
    r2 = _dot(r, r)
    q = (2 * r2 + 5 * eps**2) / (EIGHT_PI * (r2 + eps**2) ** 2.5)
    return np.sum(0.5 * q[..., None] * np.cross(f, r), axis=1)


def rotlet(r: np.ndarray, n: np.ndarray, eps: float) -> np.ndarray:
    """Torque -> velocity, the regularized rotlet [3] (times μ)."""
    r2 = _dot(r, r)
    return np.sum(np.cross(n, r) / (EIGHT_PI * (r2 + eps**2) ** 1.5)[..., None], axis=1)


def rotlet_curl(r: np.ndarray, n: np.ndarray, eps: float) -> np.ndarray:
    """Torque -> angular velocity, the regularized potential dipole [4] (times μ)."""
    r2 = _dot(r, r)
    re5 = (r2 + eps**2) ** 2.5
    p1 = (r2 - 2 * eps**2) / (4 * np.pi * re5)
    p2 = -3.0 / (4 * np.pi * re5)
    return np.sum(-0.25 * (p1[..., None] * n + (p2 * _dot(n, r))[..., None] * r), axis=1)


def rotlet_phi(r: np.ndarray, n: np.ndarray, eps: float) -> np.ndarray:
    """Torque -> velocity with the blob φ_ε (variant Φ of docs/physics.md section 1): ½ Q n × r
    (times μ)."""
    r2 = _dot(r, r)
    q = (2 * r2 + 5 * eps**2) / (EIGHT_PI * (r2 + eps**2) ** 2.5)
    return np.sum(0.5 * q[..., None] * np.cross(n, r), axis=1)


def rotlet_phi_curl(r: np.ndarray, n: np.ndarray, eps: float) -> np.ndarray:
    """Torque -> angular velocity, variant Φ: ¼ [D1 n + D2 (n·r) r] (times μ)."""
    r2 = _dot(r, r)
    e2 = eps**2
    re7 = EIGHT_PI * (r2 + e2) ** 3.5
    d1 = (10 * e2**2 - 7 * e2 * r2 - 2 * r2**2) / re7
    d2 = (21 * e2 + 6 * r2) / re7
    return np.sum(0.25 * (d1[..., None] * n + (d2 * _dot(n, r))[..., None] * r), axis=1)


def _image_geometry(targets: np.ndarray, sources: np.ndarray, eps: float):
    """R = x - y*, h, R3 = z + h, R², R_ε (section 2 of docs/physics.md), all (M, N[, 3])."""
    h = np.broadcast_to(sources[None, :, 2], (targets.shape[0], sources.shape[0]))
    img = sources * np.array([1.0, 1.0, -1.0])
    big_r = _pairs(targets, img)
    r2 = _dot(big_r, big_r)
    re = np.sqrt(r2 + eps**2)
    return big_r, h, big_r[..., 2], r2, re


def blakelet_image(targets, sources, f, eps) -> np.ndarray:
    """Force -> velocity image part [5] (regularized Blakelet, sign-corrected), times μ."""
    big_r, h, r3, r2, re = _image_geometry(targets, sources, eps)
    e2 = eps**2
    fb = np.broadcast_to(f[None], big_r.shape)
    fs = fb * np.array([1.0, 1.0, -1.0])
    rf = _dot(big_r, fb)
    rfs = _dot(big_r, fs)
    i3, i5 = re**-3, re**-5
    x = lambda a: a[..., None]  # noqa: E731
    out = -(x(r2 + 2 * e2) * fb + x(rf) * big_r) * x(i3)
    out += 2 * x(h**2) * (x(i3 - 3 * e2 * i5) * fs - 3 * x(rfs * i5) * big_r)
    out += 2 * x(h) * (
        x(rfs * (r2 + 4 * e2) * i5) * E3
        - x(r3 * i3) * fs
        + x(fb[..., 2] * i3) * big_r
        + 3 * x(r3 * rfs * i5) * big_r
    )
    out -= x(6 * h * e2 * i5) * (x(rf) * E3 - x(r3) * fb)
    return np.sum(out, axis=1) / EIGHT_PI


def blakelet_image_curl(targets, sources, f, eps) -> np.ndarray:
    """Force -> angular velocity image part [6], times μ."""
    big_r, h, r3, r2, re = _image_geometry(targets, sources, eps)
    e2 = eps**2
    fb = np.broadcast_to(f[None], big_r.shape)
    i5, i7 = re**-5, re**-7
    k = r3 * (2 * r2 + 7 * e2)
    a = -(2 * r2 + 5 * e2) * i5 / 2 - (3 * h * k - 15 * e2 * h**2) * i7
    b = -h * (4 * r2 + e2) * i5 + h * (6 * r3 * k - 30 * e2 * h * r3) * i7
    c = 6 * h * i5
    d = -6 * h * (k - 5 * e2 * h) * i7
    g = fb[..., 1] * big_r[..., 0] - fb[..., 0] * big_r[..., 1]
    out = (
        a[..., None] * np.cross(fb, big_r)
        + b[..., None] * np.cross(fb, E3)
        + (c * g)[..., None] * big_r
        + (d * g)[..., None] * E3
    )
    return np.sum(out, axis=1) / EIGHT_PI


def rotlet_image(targets, sources, n, eps) -> np.ndarray:
    """Torque -> velocity image part [7] (variant L), times μ."""
    big_r, h, r3, r2, re = _image_geometry(targets, sources, eps)
    e2 = eps**2
    nb = np.broadcast_to(n[None], big_r.shape)
    b = np.cross(nb, E3)
    z = targets[:, None, 2]
    i3, i5 = re**-3, re**-5
    out = (
        -np.cross(nb, big_r) * i3[..., None]
        + ((2 * h * (r2 - 2 * e2) + 6 * e2 * r3) * i5)[..., None] * b
        + (6 * z * i5 * _dot(big_r, b))[..., None] * big_r
    )
    return np.sum(out, axis=1) / EIGHT_PI


def rotlet_image_curl(targets, sources, n, eps) -> np.ndarray:
    """Torque -> angular velocity image part [8] (variant L), times μ."""
    big_r, h, r3, r2, re = _image_geometry(targets, sources, eps)
    e2 = eps**2
    nb = np.broadcast_to(n[None], big_r.shape)
    i3, i5, i7 = re**-3, re**-5, re**-7
    k = r3 * (2 * r2 + 7 * e2) - 5 * e2 * h
    a = (7 * r2 + 4 * e2) * i5 / 2 - 3 * r3 * k * i7
    b = -4.5 * i5
    c = 3 * r3 * i5
    d = 3 * k * i7
    e = -3 * i3
    nr = _dot(nb, big_r)
    n3 = nb[..., 2]
    out = (
        a[..., None] * nb
        + (b * nr)[..., None] * big_r
        + (c * n3)[..., None] * big_r
        + (d * nr + e * n3)[..., None] * E3
    )
    return np.sum(out, axis=1) / EIGHT_PI


def velocity(
    targets: np.ndarray,
    sources: np.ndarray,
    forces: np.ndarray,
    *,
    epsilon: float,
    mu: float,
    torques: np.ndarray | None = None,
    wall: bool = False,
    angular: bool = False,
    torque_blob: str = "psi",
):
    """Oracle of :func:`parastokes.mrs.velocity` for one system (no validation, no batching).

    Returns ``u`` (M, 3), or ``(u, w)`` when ``angular`` is true.
    """
    targets = np.asarray(targets, dtype=float)
    sources = np.asarray(sources, dtype=float)
    forces = np.asarray(forces, dtype=float)
    r = _pairs(targets, sources)
    fb = np.broadcast_to(forces[None], r.shape)
    u = stokeslet(r, fb, epsilon)
    w = stokeslet_curl(r, fb, epsilon)
    if wall:
        u = u + blakelet_image(targets, sources, forces, epsilon)
        w = w + blakelet_image_curl(targets, sources, forces, epsilon)
    if torques is not None:
        torques = np.asarray(torques, dtype=float)
        nb = np.broadcast_to(torques[None], r.shape)
        if torque_blob == "phi":
            u = u + rotlet_phi(r, nb, epsilon)
            w = w + rotlet_phi_curl(r, nb, epsilon)
        else:
            u = u + rotlet(r, nb, epsilon)
            w = w + rotlet_curl(r, nb, epsilon)
        if wall:
            u = u + rotlet_image(targets, sources, torques, epsilon)
            w = w + rotlet_image_curl(targets, sources, torques, epsilon)
    return (u / mu, w / mu) if angular else u / mu
