"""Post-impact state from contact impulses: velocities, normal velocities, kinetic energy.

With ``A`` the stacked Jacobian rows of the LCP's impulse unknowns (normal rows, then tangent
rows) and ``x`` those impulses, the velocity jump of the modelled bodies is
``v^+ - v^- = W A^T x`` (computed as ``(A W)^T x``, never forming ``W`` densely).  Bodies without
columns (static, kinematic, or in no contact) keep their velocities.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.contact.assembly import relative_velocity
from lcpcli.contact.scene import Scene

#: Relative margin above which kinetic energy after the impact counts as an increase.
ENERGY_TOL = 1e-9
#: A contact *ends approaching* when ``v_rel^+ < -APPROACH_TOL * max|v_rel^-|`` (the certificate
#: allows ``w`` to miss 0 by about its tolerance times the data's scale, so well below this).
APPROACH_TOL = 1e-6


def post_velocities(scene: Scene, modelled: np.ndarray, HA: Any,
                    x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear ``(nb, d)`` and angular ``(nb, r)`` velocities after applying impulses ``x``.

    ``HA`` is ``A W`` (sparse, one row per impulse unknown); ``x`` the impulses.  A velocity
    beyond the largest double is Inf (or NaN), as in :func:`kinetic_energy` (null in JSON).
    """
    d, dof = scene.dimension, scene.dof
    with np.errstate(over="ignore", invalid="ignore"):
        jump = np.asarray(HA.T @ x).ravel().reshape(modelled.size, dof)
        v = scene.velocity.copy()
        w = scene.omega.copy()
        v[modelled] += jump[:, :d]
        w[modelled] += jump[:, d:]
    return v, w


def normal_velocities(scene: Scene, velocity: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Normal relative velocity ``n . (pdot_a - pdot_b)`` at every contact for given velocities
    (Inf or NaN beyond the largest double, as :func:`post_velocities`)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return relative_velocity(scene, np.arange(scene.n_contacts), scene.normal, velocity,
                                 omega)


def approaching(v_after: np.ndarray, v_before: np.ndarray) -> np.ndarray:
    """Boolean mask of the contacts whose ``v_rel^+`` is negative beyond rounding."""
    scale = float(np.max(np.abs(v_before))) if v_before.size else 0.0
    return v_after < -APPROACH_TOL * (scale if scale > 0 else 1.0)


def kinetic_energy(scene: Scene, velocity: np.ndarray, omega: np.ndarray) -> float:
    """``sum over dynamic bodies of (m |v|^2 + omega^T I_world omega) / 2``.

    Static and kinematic bodies (infinite mass, prescribed velocity) are left out.  Inf when
    the energy exceeds the largest double (masses or velocities near the ends of the range;
    written as null in JSON).
    """
    mv = ~scene.fixed
    with np.errstate(over="ignore", under="ignore"):
        lin = np.sum(scene.mass[mv] * np.sum(velocity[mv] ** 2, axis=1))
        ang = np.einsum("bi,bij,bj->", omega[mv], scene.inertia[mv], omega[mv])
        return 0.5 * float(lin) + 0.5 * float(ang)


def energy_increased(before: float, after: float) -> bool:
    """True when ``after`` exceeds ``before`` by more than rounding (relative ENERGY_TOL)."""
    return after > before + ENERGY_TOL * max(abs(before), abs(after), 1e-300)


def momentum(scene: Scene, velocity: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, Any]:
    """Total linear momentum and angular momentum about the origin of the dynamic bodies."""
    mv = ~scene.fixed
    p = np.sum(scene.mass[mv][:, None] * velocity[mv], axis=0)
    Iw = np.einsum("bij,bj->bi", scene.inertia[mv], omega[mv])
    if scene.dimension == 3:
        L = np.sum(np.cross(scene.position[mv], scene.mass[mv][:, None] * velocity[mv]) + Iw,
                   axis=0)
    else:
        x, mvv = scene.position[mv], scene.mass[mv][:, None] * velocity[mv]
        L = float(np.sum(x[:, 0] * mvv[:, 1] - x[:, 1] * mvv[:, 0] + Iw[:, 0]))
    return p, L
