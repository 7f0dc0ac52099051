"""Polyhedral (pyramid) friction: the Stewart-Trinkle / Anitescu-Potra impulse LCP.

Only contacts with a friction coefficient ``mu > 0`` get friction unknowns ("model only what the
scene needs"); call them the ``nf`` friction contacts.  Each gets ``K`` unit tangent directions
``d_1..d_K`` spread evenly around its normal (3-D: ``d_k = cos(2 pi k/K) t1 + sin(2 pi k/K) t2``;
2-D: the two directions ``+t``, ``-t``), ``K`` impulses ``beta >= 0`` along them, and one slack
``lambda >= 0`` (an estimate of the sliding speed).

Unknowns, in this order (blocks, each in contact order)::

    z = [ j_n (nc) | beta (nf * K, contact-major: beta[f, 1..K]) | lambda (nf) ]

With ``N`` the normal rows and ``D`` the tangent rows of the contact Jacobian, ``W`` the inverse
mass matrix, ``E`` the ``(nf K) x nf`` block-diagonal matrix of ones columns and ``U`` the
``nf x nc`` matrix holding ``mu_f`` at (f, contact of f)::

        [ w_n ]   [ N W N^T   N W D^T   0 ] [ j_n    ]   [ (1 + eps) N v^- ]
        [ w_t ] = [ D W N^T   D W D^T   E ] [ beta   ] + [ D v^-           ]
        [ s   ]   [ U         -E^T      0 ] [ lambda ]   [ 0               ]

``w_n = v_n^+ + eps v_n^-`` (Newton restitution), ``w_t = D v^+ + lambda e >= 0`` (friction
opposes sliding), ``s = mu j_n - sum_k beta_k >= 0`` (the friction pyramid).  This is the LCP of
Stewart & Trinkle (1996) and Anitescu & Potra (1997) solved with Lemke in Drake and Bullet;
Lemke's method processes it (the matrix is copositive on the relevant cone).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.contact.assembly import Assembly, direction_rows, relative_velocity
from lcpcli.core.errors import OptionError


def tangent_basis(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents ``t1, t2`` with ``(t1, t2, n)`` right-handed, per 3-D normal."""
    n = normals
    # cross n with the world axis least aligned with it (deterministic, well conditioned)
    axis = np.zeros_like(n)
    axis[np.arange(n.shape[0]), np.argmin(np.abs(n), axis=1)] = 1.0
    t1 = np.cross(axis, n)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    t2 = np.cross(n, t1)
    return t1, t2


def tangent_directions(normals: np.ndarray, k: int,
                       plane: np.ndarray | None = None) -> np.ndarray:
    """``(m, K, d)`` unit tangent directions per contact.

    2-D: ``+t`` and ``-t`` with ``t = (-n_y, n_x)`` (``K = 2``).  3-D with ``plane`` (the unit
    normal ``e`` of a planar scene, see :mod:`lcpcli.contact.planar`): ``+t, -t`` with
    ``t = e x n`` (``K = 2``).  Otherwise K directions around ``n``.
    """
    if normals.shape[1] == 2:
        t = np.stack([-normals[:, 1], normals[:, 0]], axis=1)
        return np.stack([t, -t], axis=1)
    if plane is not None:
        t = np.cross(plane, normals)
        t /= np.linalg.norm(t, axis=1)[:, None]
        t[np.abs(t) < 1e-15] = 0.0
        return np.stack([t, -t], axis=1) + 0.0
    t1, t2 = tangent_basis(normals)
    ang = 2.0 * np.pi * np.arange(k) / k
    c, s = np.cos(ang), np.sin(ang)
    dirs = c[None, :, None] * t1[:, None, :] + s[None, :, None] * t2[:, None, :]
    # exact +-t1, +-t2 for K = 4 (no 1e-17 noise)
    dirs[np.abs(dirs) < 1e-15] = 0.0
    return dirs


def check_directions(k: int, dimension: int) -> int:
    """The number of tangent directions actually used (OptionError if ``k`` cannot work)."""
    if k < 0:
        raise OptionError(f"--friction K must be >= 0, got {k}")
    if k == 0:
        return 0
    if dimension == 2:
        if k < 2:
            raise OptionError("--friction K must be 2 in a 2-D scene (the directions +t, -t)")
        return 2
    if k < 3:
        raise OptionError(f"--friction K must be >= 3 in 3-D (K directions must positively "
                          f"span the tangent plane; K = 4 gives +-t1, +-t2), got {k}")
    if k > 64:
        raise OptionError(f"--friction K = {k} is more than 64 directions")
    return k


def friction_blocks(asm: Assembly, k: int, plane: np.ndarray | None = None) -> dict[str, Any]:
    """Sparse blocks and data of the frictional LCP (see the module docstring).

    ``plane``: the plane normal of a planar 3-D scene (two in-plane directions, ``K = 2``).

    Returns ``fc`` (friction contact indices), ``dirs`` ``(nf, K, d)``, ``D``/``HD`` (tangent
    rows and ``D W``), ``Dv`` (``D v^-``) and the sparse ``matrix`` and vector ``q``.
    """
    import scipy.sparse as sp

    scene = asm.scene
    nc = scene.n_contacts
    mu = np.nan_to_num(scene.mu, nan=0.0)
    fc = np.flatnonzero(mu > 0)
    nf = fc.size
    reduced = 2 if (scene.dimension == 2 or plane is not None) else k
    dirs = tangent_directions(scene.normal[fc], k, plane) if nf \
        else np.zeros((0, reduced, scene.dimension))
    kk = reduced
    rows_c = np.repeat(fc, kk)
    flat_dirs = dirs.reshape(nf * kk, scene.dimension)
    D, HD = direction_rows(scene, asm.columns, asm.modelled.size, rows_c, flat_dirs)
    Dv = relative_velocity(scene, rows_c, flat_dirs)
    N, HN = asm.J, asm.H
    A = sp.vstack([N, D]).tocsr()
    HA = sp.vstack([HN, HD]).tocsr()
    G = (A @ HA.T).tocsr()
    G = ((G + G.T) * 0.5).tocsr()
    E = sp.csr_matrix((np.ones(nf * kk), (np.arange(nf * kk), np.repeat(np.arange(nf), kk))),
                      shape=(nf * kk, nf))
    U = sp.csr_matrix((mu[fc], (np.arange(nf), fc)), shape=(nf, nc))
    top = sp.hstack([G, sp.vstack([sp.csr_matrix((nc, nf)), E])])
    bottom = sp.hstack([U, -E.T, sp.csr_matrix((nf, nf))])
    matrix = sp.vstack([top, bottom]).tocsr()
    matrix.eliminate_zeros()
    q = np.concatenate([asm.q, Dv, np.zeros(nf)])
    return {"fc": fc, "dirs": dirs, "K": kk, "D": D, "HD": HD, "Dv": Dv, "matrix": matrix,
            "q": q}
