"""Planar motion in a 3-D scene: detect the plane, so that friction needs 2 directions, not K.

A 3-D scene's impact is **planar** with plane normal ``e`` (unit) when, for every contact and
every dynamic body in contact:

1. the contact normal lies in the plane: ``n . e = 0``;
2. the body's velocity lies in the plane (``v . e = 0``) and its angular velocity is along ``e``
   (``omega x e = 0``);
3. ``e`` is a principal axis of the body's world inertia (``I e`` parallel to ``e``), so an
   in-plane impulse only spins it about ``e``;
4. each contact point lies in the plane through the centre of mass of each dynamic body it
   touches: ``(p - x) . e = 0`` (so ``r x n`` is along ``e``);
5. a fixed (static or kinematic) body's material velocity at the contact lies in the plane.

Then every velocity stays in the plane whatever the in-plane impulses are, the out-of-plane
tangential velocity is zero before and after, and Coulomb friction acts along the in-plane
tangent ``t = e x n`` only: the exact disc friction cone reduces to ``|beta| <= mu j_n``, i.e.
the two directions ``+t, -t`` (K = 2), instead of ``K`` directions of an inscribed pyramid whose
in-plane limit is ``mu j_n cos(theta)`` (``theta`` the angle from ``t`` to the nearest of the K
directions).  The LCP has ``nc + 3 nf`` unknowns instead of ``nc + (K + 1) nf``.

Each condition is checked to the relative tolerance :data:`PLANAR_TOL` (a vector ``x`` passes
``x . e = 0`` when ``|x . e| <= PLANAR_TOL |x|``).
"""

from __future__ import annotations

import numpy as np

from lcpcli.contact.assembly import point_velocity
from lcpcli.contact.scene import Scene

#: Relative tolerance of the planarity tests.
PLANAR_TOL = 1e-9


def _rows(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectors that must be orthogonal to ``e``, angular velocities and inertias that must be
    parallel to / have ``e`` as principal axis (dynamic bodies in contact only)."""
    ca, cb, p = scene.contact_a, scene.contact_b, scene.point
    fixed = scene.fixed
    perp = [scene.normal]
    bodies = np.unique(np.concatenate([ca, cb]))
    dyn = bodies[~fixed[bodies]]
    perp.append(scene.velocity[dyn])
    for side in (ca, cb):
        d = ~fixed[side]
        perp.append(p[d] - scene.position[side[d]])
        f = np.flatnonzero(fixed[side])
        if f.size:
            perp.append(point_velocity(scene, side[f], p[f]))
    return np.concatenate(perp), scene.omega[dyn], scene.inertia[dyn]


def _passes(e: np.ndarray, perp: np.ndarray, omega: np.ndarray, inertia: np.ndarray) -> bool:
    norms = np.linalg.norm(perp, axis=1)
    if np.any(np.abs(perp @ e) > PLANAR_TOL * norms):
        return False
    if omega.size and np.any(np.linalg.norm(np.cross(omega, e), axis=1)
                             > PLANAR_TOL * np.linalg.norm(omega, axis=1)):
        return False
    if inertia.size:
        Ie = inertia @ e
        off = np.linalg.norm(np.cross(Ie, e), axis=1)
        scale = np.max(np.abs(inertia.reshape(inertia.shape[0], -1)), axis=1)
        if np.any(off > PLANAR_TOL * scale):
            return False
    return True


def plane_normal(scene: Scene) -> np.ndarray | None:
    """The unit normal ``e`` of the plane of motion of a 3-D scene, or None if not planar.

    Candidates: the null direction of the vectors that must be orthogonal to ``e`` (unique when
    they span a plane); when they span a line or less, the angular velocities of the dynamic
    bodies, then the remaining null directions and the world axes.  The first candidate passing
    every condition of the module docstring is returned (sign: largest component positive).
    """
    if scene.dimension != 3 or scene.n_contacts == 0:
        return None
    perp, omega, inertia = _rows(scene)
    norms = np.linalg.norm(perp, axis=1)
    unit = perp[norms > 0] / norms[norms > 0, None]
    # most non-planar scenes show it in their first rows: skip the full SVD.  ||head e|| >
    # sqrt(h) * tol for every unit e means some row has |x . e| > tol
    head = unit[:64]
    if head.shape[0] >= 3 and \
            np.linalg.svd(head, compute_uv=False)[2] > np.sqrt(head.shape[0]) * PLANAR_TOL:
        return None
    if unit.shape[0] < 3:  # pad: the SVD then always returns the 3 right singular vectors
        unit = np.vstack([unit, np.zeros((3 - unit.shape[0], 3))])
    _, sv, vt = np.linalg.svd(unit, full_matrices=False)  # O(m): U is m x 3, not m x m
    rank = int(np.sum(sv > PLANAR_TOL * max(1.0, float(sv[0]) if sv.size else 1.0)))
    if rank >= 3:
        return None
    null = vt[rank:]
    candidates = []
    if rank == 2:
        candidates.append(null[0])
    else:
        wn = np.linalg.norm(omega, axis=1) if omega.size else np.zeros(0)
        candidates += [w / n for w, n in zip(omega, wn, strict=True) if n > 0]
        candidates += list(null) + list(np.eye(3))
    for e in candidates:
        e = e / np.linalg.norm(e)
        if _passes(e, perp, omega, inertia):
            k = int(np.argmax(np.abs(e)))
            e = -e if e[k] < 0 else e
            e[np.abs(e) < 1e-15] = 0.0
            return e + 0.0
    return None
