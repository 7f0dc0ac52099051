"""Time stepping with warm starts (lcpcli.contact.stepping)."""

from __future__ import annotations

import numpy as np

from lcpcli.contact.examples import box_stacks
from lcpcli.contact.stepping import GRAVITY, advance, simulate
from lcpcli.contact.warmstart import match_by_name


def test_advance_moves_bodies_and_points_and_applies_gravity() -> None:
    scene = box_stacks(2, 3, seed=4)
    v = np.random.default_rng(1).standard_normal(scene.velocity.shape)
    nxt = advance(scene, v, scene.omega, 0.01)
    dyn = ~scene.static
    assert np.allclose(nxt.position[dyn], scene.position[dyn] + 0.01 * v[dyn])
    assert np.array_equal(nxt.position[scene.static], scene.position[scene.static])
    assert np.allclose(nxt.point, scene.point + 0.01 * v[scene.contact_a])
    assert np.allclose(nxt.velocity[dyn, 2], v[dyn, 2] - GRAVITY * 0.01)
    assert np.array_equal(nxt.velocity[dyn, :2], v[dyn, :2])


def test_match_by_name_drops_and_adds() -> None:
    z0, hits = match_by_name(np.array([1.0, 2.0, 3.0]), ["a", "b", "c"], ["c", "x", "a"])
    assert z0.tolist() == [3.0, 0.0, 1.0] and hits == 2


def test_warm_steps_certify_like_cold_in_fewer_pivots() -> None:
    """Eight stacks stepped 12 times: every step the warm run solves is certified on the
    whole scene (its verdict), the warm start answers most islands, and the pivots per step
    fall against the cold run's; a step solved cold is solved warm too."""
    scene = box_stacks(8, 3, seed=1, max_restitution=0.0)
    cold = simulate(scene, 12, warm=False)
    warm = simulate(scene, 12, warm=True)
    assert [s.islands for s in warm] == [8] * 12
    assert warm[0].warm_islands == 0 and warm[0].pivots == cold[0].pivots  # nothing before
    assert all(w.status == "solved" for w, c in zip(warm, cold, strict=True)
               if c.status == "solved")
    assert np.mean([s.warm_islands for s in warm[1:]]) >= 6
    assert sum(s.pivots for s in warm[1:]) < 0.6 * sum(s.pivots for s in cold[1:])
