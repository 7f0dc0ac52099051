"""Time stepping a scene: one contact LCP per step, each warm-started from the step before.

A velocity-level stepper in the style of Stewart & Trinkle and Anitescu & Potra (and of Box2D,
ODE, Bullet, whose solvers keep the last step's impulses): at every step of length ``dt``

1. gravity changes the dynamic bodies' velocities: ``v <- v + g dt``;
2. the contact LCP of the scene with these velocities (:func:`lcpcli.contact.build`) is solved
   (:func:`lcpcli.contact.solve`); with ``warm`` its warm start is the previous step's
   impulses and the basis its pivoting ended on (:attr:`lcpcli.contact.Impact.basic`), matched
   by unknown name (:func:`lcpcli.contact.warmstart.match_by_name`, as ``contact-matrix --z0``
   matches them), so each island starts pivoting from its previous basis
   (:func:`lcpcli.contact.islands.solve_problems`);
3. the post-impact velocities integrate the positions: ``x <- x + v^+ dt``, and every contact
   point moves with the body on its A side (the contact set and the normals are kept: a
   resting stack's contacts; a separating contact gets no impulse from the LCP).

Rotations are not integrated (the example boxes have isotropic inertia, ``m / 6 I``, so their
world inertia does not depend on the orientation); this stepper exists to produce the
sequences of nearby LCPs that warm starts are for (benchmarks/bench_contact_steps.py,
docs/contact.md), not as a simulator.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.contact.model import build, solve
from lcpcli.contact.scene import Scene
from lcpcli.solvers import DEFAULT_METHOD

#: Gravity (m/s^2), along -z in 3-D (-y in 2-D).
GRAVITY = 9.81


@dataclass
class Step:
    """One step's solve: ``seconds`` (:func:`lcpcli.contact.solve`, the LCP build excluded),
    ``pivots`` (iterations summed over the islands), ``warm_islands`` (islands the warm start
    answered), ``islands``, ``status`` (the scene's verdict) and ``z`` (the impulses)."""

    seconds: float
    pivots: int
    warm_islands: int
    islands: int
    status: str
    z: np.ndarray


def advance(scene: Scene, velocity: np.ndarray, omega: np.ndarray, dt: float) -> Scene:
    """The scene ``dt`` later: positions moved by ``velocity dt``, contact points with their A
    body, velocities ``velocity``, ``omega``, and then gravity applied for the next step."""
    moved = velocity * dt
    moved[scene.static] = 0.0
    vel = velocity.copy()
    vel[~scene.static, scene.dimension - 1] -= GRAVITY * dt
    return dataclasses.replace(scene, position=scene.position + moved,
                               point=scene.point + moved[scene.contact_a], velocity=vel,
                               omega=omega.copy())


def simulate(scene: Scene, steps: int, dt: float = 0.01, *, warm: bool = True,
             friction: int = 4, softness: float | None = None, method: str = DEFAULT_METHOD,
             **options: Any) -> list[Step]:
    """Step ``scene`` ``steps`` times (see the module docstring); one :class:`Step` each.
    ``friction``, ``softness``: as :func:`lcpcli.contact.build` takes them; ``method`` and
    ``options``: as :func:`lcpcli.contact.solve` takes them."""
    from lcpcli.contact.warmstart import match_by_name

    out: list[Step] = []
    vel = scene.velocity.copy()
    vel[~scene.static, scene.dimension - 1] -= GRAVITY * dt
    scene = dataclasses.replace(scene, velocity=vel)
    prev: tuple[np.ndarray, np.ndarray, list[str]] | None = None
    for _ in range(steps):
        clcp = build(scene, friction=friction, softness=softness)
        z0 = basis0 = None
        if warm and prev is not None:
            z0 = match_by_name(prev[0], prev[2], clcp.unknowns)[0]
            # the previous basis by name too (a new contact's unknowns start nonbasic)
            basis0 = match_by_name(prev[1], prev[2], clcp.unknowns)[0] > 0.5
        t = time.perf_counter()
        impact = solve(clcp, method, z0=z0, basis0=basis0, **options)
        seconds = time.perf_counter() - t
        reports = impact.islands or []
        out.append(Step(seconds, int(sum(r["iterations"] for r in reports)),
                        int(sum(bool(r["warm"]) for r in reports)), len(reports),
                        impact.result.status, impact.result.z))
        basic = impact.result.z > 0 if impact.basic is None else impact.basic
        prev = (impact.result.z, basic.astype(np.float64), clcp.unknowns)
        scene = advance(scene, impact.velocity, impact.omega, dt)
    return out
