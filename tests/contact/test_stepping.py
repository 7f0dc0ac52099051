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


def test_islands_of_a_stepped_scene_get_the_verdicts_of_a_stack_one_by_one() -> None:
    """docs/batch.md: a stack gets exactly the verdicts lcpcli.solve gives its problems one by
    one.  One step into 20 box stacks, Lemke leaves a friction impulse of about 1e-16 on a
    contact whose normal impulse is 0; its friction-cone row (all of whose terms are such
    impulses) then reads w_i / s_i = -1.  The batched kernel retries with rounding-level z's
    at 0 (TINY_Z); the one-problem polish did not, so island 1 was solved in a stack and
    unsolved alone.  Every solved answer passes the independent check."""
    import dataclasses

    import lcpcli
    from lcpcli.contact import build, solve
    from tests.references import componentwise_error

    scene = box_stacks(20, seed=1)
    velocity = scene.velocity.copy()
    velocity[~scene.static, 2] -= GRAVITY * 0.01
    scene = dataclasses.replace(scene, velocity=velocity)
    impact = solve(build(scene, friction=4))
    clcp = build(advance(scene, impact.velocity, impact.omega, 0.01), friction=4)
    M, q = clcp.problem.M.toarray(), clcp.problem.q
    blocks = [clcp.layout.unknowns(k) for k in range(clcp.layout.count)]
    Ms = np.stack([M[np.ix_(b, b)] for b in blocks])
    qs = np.stack([q[b] for b in blocks])
    stacked = lcpcli.solve_many(Ms, qs, "lemke")
    for k in range(len(blocks)):
        alone = lcpcli.solve(Ms[k], qs[k], method="lemke")
        assert alone.status == stacked.statuses()[k], k
        if alone.solved:
            assert componentwise_error(Ms[k], qs[k], alone.z) <= alone.certificate.tol


def test_steps_of_resting_stacks_are_certified() -> None:
    """20 box stacks stepped cold: after the first step the resting contacts' relative
    velocities are rounding noise (|v_rel| from 1e-16 to 7e-14 times the scene's speeds), and
    as the LCP's q they made rows of noise alone, which no method could certify: steps 2, 3
    and 5 were `unsolved` (6 of 20 islands at step 2, errors 0.2-0.5).  Such velocities are 0
    now (assembly.VELOCITY_NOISE); every island of every step is certified, and each answer
    passes the independent check."""
    from lcpcli.contact import build, solve
    from tests.references import componentwise_error

    steps = simulate(box_stacks(20, seed=1), 5, warm=False)
    assert [s.status for s in steps] == ["solved"] * 5
    scene = box_stacks(20, seed=1)
    for _ in range(2):
        clcp = build(scene, friction=4)
        impact = solve(clcp)
        assert impact.result.status == "solved"
        M = clcp.problem.M
        M = M.toarray() if hasattr(M, "toarray") else M
        assert componentwise_error(M, clcp.problem.q, impact.result.z) <= 1e-8
        scene = advance(scene, impact.velocity, impact.omega, 0.01)


def test_relative_velocity_noise_floor_is_relative_to_the_scene() -> None:
    """A relative velocity at most VELOCITY_NOISE times the scene's largest point speed is 0;
    one just above it, or any in a scene whose speeds are all that small, is kept."""
    from lcpcli.contact.assembly import VELOCITY_NOISE, point_speed_scale, relative_velocity

    scene = box_stacks(2, 1, seed=0)
    velocity = np.zeros_like(scene.velocity)
    omega = np.zeros_like(scene.omega)
    dyn = np.flatnonzero(~scene.static)
    contacts = np.arange(scene.n_contacts)
    on_first = contacts[np.isin(scene.contact_a, dyn[:1])]
    velocity[dyn[0], 2] = 1e-17                      # box 1 at rest within 1e-17
    alone = relative_velocity(scene, contacts, scene.normal, velocity, omega)
    assert np.all(alone[on_first] != 0.0)            # nothing else moves: that is its scale
    velocity[dyn[1], 0] = 1.0                        # box 2 slides at 1 m/s
    scale = point_speed_scale(scene, velocity, omega)
    assert scale >= 1.0
    both = relative_velocity(scene, contacts, scene.normal, velocity, omega)
    assert np.all(both[on_first] == 0.0)
    velocity[dyn[0], 2] = 2 * VELOCITY_NOISE * scale
    kept = relative_velocity(scene, contacts, scene.normal, velocity, omega)
    assert np.all(np.abs(kept[on_first]) > VELOCITY_NOISE * scale)


def test_islands_of_resting_stacks_that_lemke_ends_on_a_ray_or_drifts_on() -> None:
    """Two islands (72 unknowns, rank 42, twelve zero diagonal entries) of
    ``box_stacks(20, seed=0)`` stepped cold 62 and 52 times (tests/contact/data).  On the first,
    Lemke ended on a ray with its artificial variable at rounding level (z0 ~ 1e-17): the point
    solves the problem up to a change of q below rounding, and its polish is certified (the ray
    was `unsolved`).  On the second, every method auto tried failed; Murty's least-index
    pivoting, now auto's last pivoting fallback (n <= 200), certifies it.  Over 8,000 islands of
    four such runs: `auto` unsolved on 19 before, 1 after."""
    from pathlib import Path

    import lcpcli
    from tests.references import componentwise_error

    data = np.load(Path(__file__).with_name("data") / "resting_islands.npz")
    M, q = data["M_ray"], data["q_ray"]
    ray = lcpcli.solve(M, q, "lemke-tableau")
    assert ray.status == "solved" and "at rounding level" in ray.message, ray.message
    assert componentwise_error(M, q, ray.z) <= ray.certificate.tol
    M, q = data["M_murty"], data["q_murty"]
    res = lcpcli.solve(M, q)
    assert res.status == "solved" and res.info["chosen"] == "murty", res.message
    assert componentwise_error(M, q, res.z) <= res.certificate.tol


def test_an_island_whose_lemke_path_goes_astray_is_solved_with_a_generic_covering_vector() -> None:
    """The one island of those 8,000 that nothing certified (``box_stacks(20, seed=0)``, step
    20 cold; n = 72, M singular, equal q_i at the four corners of each box): with d all ones
    the tableau ended on a ray at z0 = 3.8e-13 and the revised method drifted to z0 = -0.38
    (exact rational Lemke solves it in 69 pivots: floating point decides a tie of the third
    ratio test that the exact ratios break otherwise).  Lemke retries such a ray once with
    a generic covering vector, which solves it; a covering vector given by the user is kept."""
    from pathlib import Path

    import lcpcli
    from lcpcli.solvers.methods.lemke import generic_covering
    from tests.references import componentwise_error

    data = np.load(Path(__file__).with_name("data") / "astray_island.npz")
    M, q = data["M"], data["q"]
    for method in ("lemke-tableau", "lemke", "auto"):
        res = lcpcli.solve(M, q, method)
        assert res.status == "solved", (method, res.message)
        assert componentwise_error(M, q, res.z) <= res.certificate.tol
    res = lcpcli.solve(M, q, "lemke-tableau")
    assert "with a generic covering vector" in res.message
    traced = lcpcli.solve(M, q, "lemke-tableau", trace=True)  # the same verdict as untraced
    assert traced.status == "solved" and np.array_equal(traced.z, res.z), traced.message
    given = lcpcli.solve(M, q, "lemke-tableau", covering=np.ones(len(q)))
    assert given.status == "unsolved" and "generic" not in given.message
    # the next island that failed once that one was solved (the same run, step 24): the
    # revised method's answer drifted (certified error 2.09, no polish certifies it); auto now
    # tries the tableau method as a fallback (n <= 200), which certifies it
    M, q = data["M_drift"], data["q_drift"]
    res = lcpcli.solve(M, q)
    assert res.status == "solved" and res.info["chosen"] == "lemke-tableau", res.message
    assert componentwise_error(M, q, res.z) <= res.certificate.tol
    d = generic_covering(1000)
    assert np.all((d >= 1.0) & (d < 2.0)) and np.unique(d).size == 1000
    assert np.array_equal(generic_covering(72), d[:72])  # the same vector every run
