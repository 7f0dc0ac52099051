"""Contact modelling (issue 15): contact states, islands, kinematic bodies, planar reduction,
softness, warm start, the pyramid error and the simultaneous-impact law.

Expected numbers are derived by hand in the comments (unit masses unless said otherwise).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lcpcli.contact import build, load_scene, scene_from_dict, solve, to_json
from lcpcli.contact.assembly import DEFAULT_RESTITUTION_THRESHOLD, IMPACT, RESTING, SEPARATING
from lcpcli.contact.examples import box_stacks, sphere_lattice
from lcpcli.contact.friction import tangent_basis
from lcpcli.contact.impact import momentum
from lcpcli.contact.islands import find_islands
from lcpcli.contact.planar import plane_normal
from lcpcli.contact.scene import build_scene, with_kinematic, write_scene_hdf5
from lcpcli.core.errors import OptionError, ProblemError
from tests.contact.test_contact import box_stack, random_scene, run_inprocess

SAMPLES = Path(__file__).resolve().parents[2] / "samples"


def ball(name: str, z: float, vz: float, mass: float = 1.0, **extra) -> dict:
    return {"name": name, "mass": mass, "inertia": [0.1, 0.1, 0.1], "position": [0, 0, z],
            "velocity": [0, 0, vz], **extra}


def floor_contact(a: str, b: str, z: float, eps: float, **extra) -> dict:
    return {"a": a, "b": b, "point": [0, 0, z], "normal": [0, 0, 1], "restitution": eps, **extra}


# ---------------------------------------------------------------------- contact states
def test_separating_contact_gets_no_bounce_issue_example() -> None:
    """Issue 15: B touches the ground moving up at +1, A hits B from above at -3, eps = 0.5.

    M = [[2, -1], [-1, 1]] (contact 1: A above B, contact 2: B on the ground).
    Old law q = (1 + eps) v^- on both: q = (-6, 1.5) -> j = (4.5, 3), B ends at -0.5 (into the
    ground).  New: the ground contact separates (v^- = +1), so q2 = v^- = 1:
    2 j1 - j2 = 6, -j1 + j2 = -1 -> j = (5, 4); A: -3 + 5 = 2, B: 1 - 5 + 4 = 0.
    """
    clcp = build(load_scene(SAMPLES / "scene_separating_ball.json"))
    asm = clcp.assembly
    assert asm.v_rel == pytest.approx([-4.0, 1.0])
    assert asm.state.tolist() == [IMPACT, SEPARATING]
    assert asm.restitution_used.tolist() == [0.5, 0.0]
    assert clcp.problem.q == pytest.approx([-6.0, 1.0])
    impact = solve(clcp)
    assert impact.result.solved
    assert impact.normal_impulses == pytest.approx([5.0, 4.0], abs=1e-12)
    assert impact.velocity[1] == pytest.approx([0, 0, 2.0], abs=1e-12)
    assert impact.velocity[2] == pytest.approx([0, 0, 0.0], abs=1e-12)
    assert impact.normal_velocity == pytest.approx([2.0, 0.0], abs=1e-12)
    assert not impact.approaching.any()
    assert impact.energy_before == pytest.approx(5.0) and impact.energy_after == pytest.approx(2.0)


@pytest.mark.parametrize(("vz", "threshold", "bounce"), [
    (-3.0, 0.0, True), (-3.0, 1.0, True), (-0.5, 1.0, False), (-1.0, 1.0, False),
    (0.0, 0.0, False),
])
def test_restitution_threshold(vz: float, threshold: float, bounce: bool) -> None:
    """A ball (m = 2) on the ground: it bounces with -eps v only when v < -threshold."""
    data = {"restitution_threshold": threshold,
            "bodies": [{"name": "g", "static": True}, ball("b", 0.5, vz, mass=2.0)],
            "contacts": [floor_contact("b", "g", 0.0, 0.6)]}
    impact = solve(build(scene_from_dict(data)))
    assert impact.result.solved
    expected = -0.6 * vz if bounce else 0.0
    assert impact.velocity[1][2] == pytest.approx(expected, abs=1e-12)
    assert impact.normal_impulses[0] == pytest.approx(2.0 * (expected - vz), abs=1e-12)


def test_threshold_precedence_contact_over_option_over_scene() -> None:
    data = {"restitution_threshold": 5.0,
            "bodies": [{"name": "g", "static": True}, ball("b1", 0.5, -2.0), ball("b2", 0.5, -2.0)],
            "contacts": [floor_contact("b1", "g", 0.0, 0.5),
                         floor_contact("b2", "g", 0.0, 0.5, restitution_threshold=0.1)]}
    scene = scene_from_dict(data)
    assert build(scene).assembly.threshold.tolist() == [5.0, 0.1]
    clcp = build(scene, restitution_threshold=1.0)
    assert clcp.assembly.threshold.tolist() == [1.0, 0.1]
    assert clcp.assembly.state.tolist() == [IMPACT, IMPACT]
    del data["restitution_threshold"]
    assert build(scene_from_dict(data)).assembly.threshold.tolist() == \
        [DEFAULT_RESTITUTION_THRESHOLD, 0.1]
    assert build(scene).assembly.state.tolist() == [RESTING, IMPACT]


def _all_test_scenes() -> list[tuple[str, object, int]]:
    scenes: list[tuple[str, object, int]] = []
    for path in sorted(SAMPLES.glob("scene_*.json")):
        scene = load_scene(path)
        for k in (0, 2 if scene.dimension == 2 else 4):
            scenes.append((path.name, scene, k))
    for seed in range(4):
        scenes.append((f"stack{seed}", box_stack(5, seed, tilt=0.05 * (seed % 2)), 4))
    scenes.append(("stacks", box_stacks(6, 3, seed=3), 4))
    scenes.append(("lattice", sphere_lattice(5, 4, 3, seed=2), 0))
    scenes.append(("lattice-friction", sphere_lattice(3, 3, 2, seed=4), 4))
    for seed in range(3):
        scenes.append((f"random{seed}", random_scene(40, 60, seed=seed), 0))
    return scenes


def test_no_contact_ends_approaching_in_any_sample_or_test_scene() -> None:
    """Every solved scene: v_rel^+ >= 0 at every contact (rigid contacts, default threshold)."""
    solved = 0
    for name, scene, k in _all_test_scenes():
        clcp = build(scene, friction=k)
        impact = solve(clcp)
        if not impact.result.solved:  # jammed random scenes may have no solution
            assert name.startswith("random"), (name, impact.result.message)
            continue
        solved += 1
        scale = max(1.0, float(np.abs(clcp.assembly.v_rel).max()))
        assert impact.normal_velocity.min() >= -1e-8 * scale, name
        assert not impact.approaching.any(), name
        # impacts leave at least -eps v^-, the others at least 0
        e = clcp.assembly.restitution_used
        assert np.all(impact.normal_velocity + e * clcp.assembly.v_rel >= -1e-8 * scale), name
    assert solved >= 20


def test_states_in_json_and_text(capsys) -> None:
    code, out, err = run_inprocess(capsys, "contact-matrix",
                                   str(SAMPLES / "scene_separating_ball.json"), "--solve", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["states"] == {"impact": 1, "resting": 0, "separating": 1}
    assert [c["state"] for c in d["contacts"]] == ["impact", "separating"]
    assert [c["restitution_used"] for c in d["contacts"]] == [0.5, 0.0]
    assert d["approaching_after"] == 0 and d["min_normal_velocity"] == pytest.approx(0, abs=1e-12)
    code, out, _ = run_inprocess(capsys, "contact-matrix",
                                 str(SAMPLES / "scene_separating_ball.json"), "--solve")
    assert code == 0 and "separating" in out and "contacts ending approaching" in out


# ---------------------------------------------------------------------- simultaneous impact
def test_newtons_cradle_simultaneous_impact() -> None:
    """Balls 1, 2, 3 (m = 1, eps = 1), ball 1 at v = 1; c12 approaching (-1), c23 resting (0).

    u1 = 1 - j1, u2 = j1 - j2, u3 = j2; w1 = (u2 - u1) - 1 = 2 j1 - j2 - 2, w2 = 2 j2 - j1.
    Both active: j = (4/3, 2/3), u = (-1/3, 2/3, 2/3) (sequential impacts: (0, 0, 1)).
    Momentum 1 and energy 1/2 are kept.
    """
    clcp = build(load_scene(SAMPLES / "scene_cradle.json"))
    assert clcp.assembly.state.tolist() == [IMPACT, RESTING]
    impact = solve(clcp)
    assert impact.result.solved
    assert impact.normal_impulses == pytest.approx([4 / 3, 2 / 3], abs=1e-12)
    assert impact.velocity[:, 0] == pytest.approx([-1 / 3, 2 / 3, 2 / 3], abs=1e-12)
    assert impact.energy_after == pytest.approx(0.5, abs=1e-12)
    p, _ = momentum(clcp.scene, impact.velocity, impact.omega)
    assert p == pytest.approx([1, 0, 0], abs=1e-12)


# ---------------------------------------------------------------------- islands
def test_islands_of_stacks_and_merge_order() -> None:
    scene = box_stacks(5, 3, seed=7)
    isl = find_islands(scene)
    assert isl.count == 5 and isl.sizes().tolist() == [12] * 5
    assert isl.body_counts().tolist() == [3] * 5
    assert isl.body_island[0] == -1  # the static ground belongs to no island
    clcp = build(scene, friction=4)
    assert clcp.island_sizes().tolist() == [12 * 6] * 5
    for k in range(5):  # island k holds stack k's unknowns, in the scene's order
        idx = clcp.layout.unknowns(k)
        assert np.all(np.diff(idx) > 0)
        assert set(clcp.unknown_contact[idx].tolist()) == set(range(12 * k, 12 * k + 12))
    a = solve(clcp)
    b = solve(clcp, "lemke", islands=False)
    assert a.result.solved and b.result.solved and len(a.islands) == 5 and b.islands is None
    # frictional z need not be unique; the post-impact velocities are compared
    assert np.allclose(a.velocity, b.velocity, atol=1e-9)
    assert np.allclose(a.omega, b.omega, atol=1e-9)
    # frictionless with a positive definite M per island: z is unique, compare it directly
    lat = build(sphere_lattice(3, 2, 2, seed=1))
    za, zb = solve(lat).result.z, solve(lat, islands=False).result.z
    assert np.allclose(za, zb, atol=1e-10)


def test_island_json_report(capsys) -> None:
    code, out, err = run_inprocess(capsys, "contact-matrix", str(SAMPLES / "scene_conveyor.json"),
                                   "--solve", "--friction", "4", "--json")
    assert code == 0, err
    d = json.loads(out)
    isl = d["islands"]
    assert isl["count"] == 2 and isl["contacts"] == [4, 4] and isl["unknowns"] == [24, 24]
    assert isl["solved_separately"] is True
    for rep in isl["per_island"]:
        assert rep["status"] == "solved" and rep["method"] and rep["bodies"] == 1
        assert rep["error"] <= 1e-8
    assert [c["island"] for c in d["contacts"]] == [1] * 4 + [2] * 4
    assert [b["island"] for b in d["bodies"]] == [None, 1, 2]
    code, out, _ = run_inprocess(capsys, "contact-matrix", str(SAMPLES / "scene_conveyor.json"),
                                 "--solve", "--json", "--no-islands")
    assert code == 0 and json.loads(out)["islands"]["solved_separately"] is False


def test_island_without_solution_proves_the_scene_has_none() -> None:
    """Island 2 is a ball touching two walls that must bounce off the right one (eps 0.8) while
    the left contact separates (v+ >= 0): no solution (Lemke's ray on a PSD M)."""
    data = {"bodies": [{"name": "g", "static": True}, ball("free", 0.5, -1.0),
                       {"name": "left", "static": True}, {"name": "right", "static": True},
                       {"name": "jam", "mass": 1, "inertia": [1, 1, 1], "position": [10, 0, 0],
                        "velocity": [1.0, 0, 0]}],
            "contacts": [floor_contact("free", "g", 0.0, 0.5),
                         {"a": "jam", "b": "left", "point": [9, 0, 0], "normal": [1, 0, 0],
                          "restitution": 0.8},
                         {"a": "jam", "b": "right", "point": [11, 0, 0], "normal": [-1, 0, 0],
                          "restitution": 0.8}]}
    impact = solve(build(scene_from_dict(data)))
    assert impact.result.status == "no_solution"
    assert [r["status"] for r in impact.islands] == ["solved", "no_solution"]
    assert "island 2" in impact.result.message


def test_written_lcp_is_the_whole_scene(tmp_path, capsys) -> None:
    from lcpcli.io import load

    out = tmp_path / "lcp.npz"
    code, _, err = run_inprocess(capsys, "contact-matrix", str(SAMPLES / "scene_conveyor.json"),
                                 "--friction", "4", "-o", str(out), "--solve")
    assert code == 0, err
    prob = load(out)
    assert prob.n == 48 and prob.meta["contact"]["islands"] == 2
    assert [c["island"] for c in prob.meta["contact"]["contacts"]] == [0] * 4 + [1] * 4


def test_parallel_islands_match_serial(monkeypatch) -> None:
    import lcpcli.contact.islands as islands

    clcp = build(box_stacks(6, 2, seed=5), friction=4)
    serial = solve(clcp)
    monkeypatch.setattr(islands, "PARALLEL_MIN_UNKNOWNS", 0)
    parallel = solve(clcp, jobs=2)
    assert parallel.result.solved
    assert np.array_equal(parallel.result.z, serial.result.z)
    with pytest.raises(OptionError):
        solve(clcp, jobs=0)


def test_default_solve_handles_big_sparse_scenes(capsys, tmp_path, monkeypatch) -> None:
    """One island of 1,116 frictionless contacts stored sparse: auto (the default) solves it
    where a dense-only method would be refused (the limit is lowered to provoke that)."""
    import lcpcli.solvers.registry

    scene = sphere_lattice(8, 8, 6, seed=3)
    path = tmp_path / "lattice.h5"
    write_scene_hdf5(scene, path)
    code, out, err = run_inprocess(capsys, "contact-matrix", str(path), "--solve", "--json",
                                   "--storage", "sparse")
    assert code == 0, err
    d = json.loads(out)
    assert d["status"] == "solved" and d["islands"]["count"] == 1
    assert d["islands"]["unknowns"] == [scene.n_contacts] and d["approaching_after"] == 0
    monkeypatch.setattr(lcpcli.solvers.registry, "MAX_DENSIFY_ENTRIES", 1000)
    code, _, err = run_inprocess(capsys, "contact-matrix", str(path), "--solve", "--storage",
                                 "sparse", "--method", "lemke")
    assert code == 2 and "dense" in err
    code, out, err = run_inprocess(capsys, "contact-matrix", str(path), "--solve", "--json",
                                   "--storage", "sparse")
    assert code == 0 and json.loads(out)["status"] == "solved", err


# ---------------------------------------------------------------------- kinematic bodies
def paddle_scene(kinematic: bool) -> dict:
    paddle = {"name": "paddle", "position": [0, 0, 0], "velocity": [0, 0, 2.0]}
    paddle.update({"kinematic": True} if kinematic else
                  {"mass": 5.0, "inertia": [1, 1, 1]})
    return {"bodies": [paddle, ball("b1", 0.5, 0.0), ball("b2", 0.5, 0.0)],
            "contacts": [{"a": "b1", "b": "paddle", "point": [0, 0, 0], "normal": [0, 0, 1],
                          "restitution": 1.0},
                         {"a": "b2", "b": "paddle", "point": [0, 0, 0], "normal": [0, 0, 1],
                          "restitution": 1.0}]}


def test_kinematic_paddle() -> None:
    """A kinematic paddle at +2 hits two balls at rest (eps = 1): v_rel = -2 for each, so each
    ball leaves at 2 + 2 = 4; the paddle keeps +2 and connects no island."""
    scene = scene_from_dict(paddle_scene(True))
    clcp = build(scene)
    assert clcp.islands.count == 2 and clcp.assembly.modelled.tolist() == [1, 2]
    impact = solve(clcp)
    assert impact.velocity[:, 2] == pytest.approx([2.0, 4.0, 4.0], abs=1e-12)
    assert impact.normal_impulses == pytest.approx([4.0, 4.0], abs=1e-12)
    assert impact.energy_before == 0.0 and impact.energy_after == pytest.approx(16.0)
    # the same bodies named kinematic on the command line / in the library
    again = with_kinematic(scene_from_dict(paddle_scene(False)), ["paddle"])
    assert again.kinematic.tolist() == [True, False, False]
    other = solve(build(again))
    assert np.allclose(other.velocity, impact.velocity, atol=1e-12)
    # a dynamic paddle joins the two balls into one island
    assert build(scene_from_dict(paddle_scene(False))).islands.count == 1


def test_kinematic_cli_and_errors(tmp_path, capsys) -> None:
    f = tmp_path / "p.json"
    f.write_text(json.dumps(paddle_scene(False)))
    code, out, err = run_inprocess(capsys, "contact-matrix", str(f), "--solve", "--json",
                                   "--kinematic", "paddle")
    assert code == 0, err
    d = json.loads(out)
    assert d["bodies"][0]["kinematic"] is True and d["bodies"][0]["mass"] is None
    assert [v["linear"][2] for v in d["velocities"]] == pytest.approx([2, 4, 4])
    code, _, err = run_inprocess(capsys, "contact-matrix", str(f), "--kinematic", "nobody")
    assert code == 2 and "unknown body 'nobody'" in err
    bad = paddle_scene(True)
    bad["bodies"][0]["static"] = True
    with pytest.raises(ProblemError, match="either static or kinematic"):
        scene_from_dict(bad)
    bad = paddle_scene(True)
    bad["bodies"].append({"name": "g", "static": True})
    bad["contacts"].append({"a": "paddle", "b": "g", "point": [0, 0, 0], "normal": [0, 0, 1]})
    with pytest.raises(ProblemError, match="static or kinematic"):
        scene_from_dict(bad)


# ---------------------------------------------------------------------- planar reduction
def embed_2d(scene2):
    """The 2-D scene as a 3-D scene in the plane z = 0 (spin about z)."""
    nb, nc = scene2.n_bodies, scene2.n_contacts
    inertia3 = np.zeros((nb, 3, 3))
    inertia3[:, 0, 0] = inertia3[:, 1, 1] = 1.0
    inertia3[:, 2, 2] = scene2.inertia[:, 0, 0]
    inertia3[scene2.static] = np.eye(3)
    return build_scene(3, scene2.body_names, scene2.static, scene2.mass, inertia3, None,
                       np.c_[scene2.position, np.zeros(nb)], np.c_[scene2.velocity, np.zeros(nb)],
                       np.c_[np.zeros((nb, 2)), scene2.omega], scene2.contact_a,
                       scene2.contact_b, np.c_[scene2.point, np.zeros(nc)],
                       np.c_[scene2.normal, np.zeros(nc)], scene2.restitution, scene2.mu)


def test_planar_3d_scene_reduces_to_the_2d_lcp() -> None:
    scene2 = load_scene(SAMPLES / "scene_2d_boxes.json")
    scene3 = embed_2d(scene2)
    assert plane_normal(scene3) == pytest.approx([0, 0, 1])
    c2, c3 = build(scene2, friction=2), build(scene3, friction=4)
    assert c3.friction == 2 and c3.problem.n == c2.problem.n == 3 + 3 * 2 + 3
    assert any("planar motion" in note for note in c3.notes)
    assert np.allclose(c3.problem.dense_M(), c2.problem.dense_M(), atol=1e-12)
    i2, i3 = solve(c2), solve(c3)
    assert np.allclose(i3.velocity[:, :2], i2.velocity, atol=1e-9)
    assert np.allclose(i3.omega[:, 2], i2.omega[:, 0], atol=1e-9)
    assert np.allclose(i3.velocity[:, 2], 0.0) and np.allclose(i3.omega[:, :2], 0.0)
    full = build(scene3, friction=4, planar=False)
    assert full.problem.n == 3 + 3 * 4 + 3 and full.plane is None


def test_planar_sample_36_to_24_unknowns(capsys) -> None:
    path = str(SAMPLES / "scene_planar_3d.json")
    code, out, err = run_inprocess(capsys, "contact-matrix", path, "--friction", "4", "--solve",
                                   "--json")
    assert code == 0, err
    d = json.loads(out)
    assert len(d["unknowns"]) == 24 and d["friction_directions"] == 2
    assert d["planar"] == {"plane_normal": [0.0, 1.0, 0.0], "friction_reduced": True}
    assert "planar motion" in err and "24 unknowns instead of 36" in err
    assert all(abs(v["linear"][1]) < 1e-12 for v in d["velocities"])
    code, out, _ = run_inprocess(capsys, "contact-matrix", path, "--friction", "4", "--json",
                                 "--no-planar")
    assert len(json.loads(out)["unknowns"]) == 36
    code, out, _ = run_inprocess(capsys, "contact-matrix", path, "--friction", "4")
    assert "planar" in out and "reduced" in out


def test_non_planar_scenes_are_not_reduced() -> None:
    assert plane_normal(box_stacks(2, 2, seed=1)) is None
    assert plane_normal(random_scene(10, 12, seed=2)) is None
    # a tilted inertia breaks planarity even when all vectors lie in a plane
    data = {"bodies": [{"name": "g", "static": True},
                       {"name": "b", "mass": 1, "inertia": [[1, 0.2, 0], [0.2, 1, 0.3],
                                                             [0, 0.3, 1]],
                        "position": [0, 0, 0.5], "velocity": [1, 0, -1]}],
            "contacts": [{"a": "b", "b": "g", "point": [0.5, 0, 0], "normal": [0, 0, 1],
                          "mu": 0.5}]}
    assert plane_normal(scene_from_dict(data)) is None
    data["bodies"][1]["inertia"] = [1, 2, 3]
    assert plane_normal(scene_from_dict(data)) == pytest.approx([0, 1, 0])


# ---------------------------------------------------------------------- pyramid error
def puck(theta: float, mu: float = 0.2) -> dict:
    """Mass 1, contact at the centre of mass (no torque), sliding at 0.5 in the direction at
    angle theta from t1 (towards t2), falling at 1 onto the ground (eps = 0): j_n = 1."""
    t1, t2 = tangent_basis(np.array([[0.0, 0.0, 1.0]]))
    u = np.cos(theta) * t1[0] + np.sin(theta) * t2[0]
    v = (0.5 * u + [0, 0, -1.0]).tolist()
    return {"bodies": [{"name": "g", "static": True},
                       {"name": "puck", "mass": 1, "inertia": [1, 1, 1], "position": [0, 0, 0],
                        "velocity": v}],
            "contacts": [{"a": "puck", "b": "g", "point": [0, 0, 0], "normal": [0, 0, 1],
                          "mu": mu}]}


@pytest.mark.parametrize(("k", "theta", "speed"), [
    (4, np.pi / 4, 0.5 - 0.2 / np.sqrt(2)),   # 0.358579: the issue's 0.3586
    (8, np.pi / 4, 0.3),                      # 45 degrees is a direction of K = 8: exact
    (4, 0.0, 0.3),                            # along a direction: exact
    (8, np.pi / 8, 0.5 - 0.2 * np.cos(np.pi / 8)),
    (16, np.pi / 16, 0.5 - 0.2 * np.cos(np.pi / 16)),
])
def test_pyramid_error_cos_pi_over_k(k: int, theta: float, speed: float) -> None:
    """Sliding midway between two of the K directions, the inscribed pyramid's friction is
    mu j_n cos(pi / K) instead of mu j_n: tangential speed 0.5 - 0.2 cos(pi / K) (exact cone:
    0.3).  The direction of sliding is kept (the two neighbouring directions share equally)."""
    clcp = build(scene_from_dict(puck(theta)), friction=k, planar=False)
    impact = solve(clcp)
    assert impact.result.solved
    v = impact.velocity[1]
    assert v[2] == pytest.approx(0.0, abs=1e-12)
    assert np.hypot(v[0], v[1]) == pytest.approx(speed, abs=1e-9)
    t1, t2 = tangent_basis(np.array([[0.0, 0.0, 1.0]]))
    u = np.cos(theta) * t1[0] + np.sin(theta) * t2[0]
    assert v[:2] / np.hypot(v[0], v[1]) == pytest.approx(u[:2], abs=1e-9)


def test_planar_puck_gets_the_exact_cone() -> None:
    """The puck's motion is planar (plane spanned by n and the sliding direction): the planar
    reduction uses +-t along the sliding direction, which is the exact Coulomb law: 0.3."""
    clcp = build(scene_from_dict(puck(np.pi / 4)), friction=4)
    assert clcp.plane is not None and clcp.friction == 2
    v = solve(clcp).velocity[1]
    assert np.hypot(v[0], v[1]) == pytest.approx(0.3, abs=1e-12)


# ---------------------------------------------------------------------- softness
def test_softness_single_ball() -> None:
    """m = 2 at -3 on the ground, eps = 0.5, softness S = 0.25: M11 = 1/2, R = S M11 = 1/8,
    q = -4.5; w = (M11 + R) j + q = 0 -> j = 4.5 / 0.625 = 7.2; v+ = -3 + 7.2 / 2 = 0.6
    (rigid: j = 9, v+ = 1.5)."""
    data = {"bodies": [{"name": "g", "static": True}, ball("b", 0.5, -3.0, mass=2.0)],
            "contacts": [floor_contact("b", "g", 0.0, 0.5)]}
    clcp = build(scene_from_dict(data), softness=0.25)
    assert clcp.regularisation == pytest.approx([0.125])
    assert clcp.problem.M[0, 0] == pytest.approx(0.625)
    impact = solve(clcp)
    assert impact.normal_impulses[0] == pytest.approx(7.2, abs=1e-12)
    assert impact.velocity[1][2] == pytest.approx(0.6, abs=1e-12)
    data["softness"] = 0.25  # scene-level key: the same
    assert solve(build(scene_from_dict(data))).normal_impulses[0] == pytest.approx(7.2)
    assert solve(build(scene_from_dict(data), softness=0.0)).normal_impulses[0] == \
        pytest.approx(9.0)


def test_softness_makes_the_cube_lcp_unique_and_lets_it_sink(capsys) -> None:
    """Cube on 4 corners (M rank 3): each corner has M_ii = 1 + 6 * 0.5 = 4 and (M 1)_i = 4.
    With softness S the symmetric solution solves c (4 + 4 S) = 1.8: z_i = 0.45 / (1 + S),
    unique (M + R is PD).  S = 0.5: z_i = 0.3, v_z+ = -1.5 + 4 * 0.3 = -0.3 (soft: sinks)."""
    path = str(SAMPLES / "scene_cube_on_plane.json")
    code, out, err = run_inprocess(capsys, "contact-matrix", path, "--solve", "--json",
                                   "--softness", "0.5")
    assert code == 0, err
    d = json.loads(out)
    # (the sample's inertia 0.1666667 is 1/6 to 7 digits, hence the 1e-7)
    assert d["impulses"] == pytest.approx([0.3] * 4, abs=1e-7)
    assert d["velocities"][1]["linear"][2] == pytest.approx(-0.3, abs=1e-7)
    assert d["approaching_after"] == 4 and "soft contacts allow it" in err
    assert [c["softness"] for c in d["contacts"]] == [0.5] * 4
    assert np.linalg.eigvalsh(np.array(d["M"])).min() > 0


def test_softness_applies_to_friction_rows() -> None:
    clcp = build(load_scene(SAMPLES / "scene_cube_on_plane.json"), friction=4, softness=0.1)
    M0 = build(load_scene(SAMPLES / "scene_cube_on_plane.json"), friction=4).problem.dense_M()
    diag = np.diag(clcp.problem.dense_M()) - np.diag(M0)
    assert diag[:20] == pytest.approx(0.1 * np.diag(M0)[:20])
    assert np.all(diag[20:] == 0)  # slack rows are not impulses


# ---------------------------------------------------------------------- warm start
def test_warm_start_from_impulses_file(tmp_path, capsys) -> None:
    path = str(SAMPLES / "scene_conveyor.json")
    imp = tmp_path / "step1.json"
    code, out1, err = run_inprocess(capsys, "contact-matrix", path, "--friction", "4", "--solve",
                                    "--json", "--impulses", str(imp))
    assert code == 0, err
    saved = json.loads(imp.read_text())
    assert saved["format"] == "lcpcli-contact-impulses" and saved["status"] == "solved"
    code, out2, err = run_inprocess(capsys, "contact-matrix", path, "--friction", "4", "--solve",
                                    "--json", "--z0", str(imp))
    assert code == 0, err
    assert "48 of 48 unknowns matched by name" in err
    d1, d2 = json.loads(out1), json.loads(out2)
    for rep in d2["islands"]["per_island"]:
        assert rep["warm"] is True and rep["iterations"] == 0 and rep["method"] == "z0"
    assert d2["impulses"] == pytest.approx(d1["impulses"], abs=1e-12)
    # the --json output and an .npz impulses file work too
    js = tmp_path / "out.json"
    js.write_text(out1)
    npz = tmp_path / "step1.npz"
    code, _, err = run_inprocess(capsys, "contact-matrix", path, "--friction", "4", "--solve",
                                 "--z0", str(js), "--impulses", str(npz))
    assert code == 0 and "matched by name" in err
    code, out3, err = run_inprocess(capsys, "contact-matrix", path, "--friction", "4", "--solve",
                                    "--json", "--z0", str(npz))
    assert code == 0 and all(r["warm"] for r in json.loads(out3)["islands"]["per_island"])


def test_warm_start_policy_small_and_big_islands() -> None:
    """A z0 that is not a solution: small islands are solved cold; an island of at least
    WARM_NEWTON_MIN_N unknowns starts Newton from z0 (fewer iterations than cold)."""
    import dataclasses

    from lcpcli.contact.islands import WARM_NEWTON_MIN_N

    small = build(box_stacks(3, 2, seed=4), friction=4)
    first = solve(small)
    bad = solve(small, z0=first.result.z * 0.5)
    assert bad.result.solved and not any(r["warm"] for r in bad.islands)
    scene = sphere_lattice(12, 12, 8, seed=6)
    assert scene.n_contacts >= WARM_NEWTON_MIN_N
    rng = np.random.default_rng(1)
    step1 = solve(build(scene))
    nxt = build(dataclasses.replace(scene, velocity=scene.velocity
                                    * (1 + 0.01 * rng.normal(size=scene.velocity.shape))))
    cold, warm = solve(nxt), solve(nxt, z0=step1.result.z)
    assert warm.result.solved and warm.islands[0]["warm"] and warm.islands[0]["method"] == "newton"
    assert warm.result.iterations < cold.result.iterations
    assert np.allclose(warm.velocity, cold.velocity, atol=1e-8)


def test_warm_start_by_name_when_the_scene_changes(tmp_path) -> None:
    from lcpcli.contact.warmstart import warm_start, write_impulses

    f = tmp_path / "imp.json"
    write_impulses(f, ["n[a]", "n[b]", "n[gone]"], np.array([1.0, 2.0, 3.0]))
    z0, basis0, note = warm_start(f, ["n[b]", "n[new]", "n[a]"])
    assert z0.tolist() == [2.0, 0.0, 1.0] and "2 of 3 unknowns matched" in note
    assert basis0 is None  # a file without a basis: the caller starts from z0's support
    plain = tmp_path / "z.json"
    plain.write_text(json.dumps({"z": [1.0, 2.0]}))  # lcpcli solve --json: by position
    assert warm_start(plain, ["n[a]", "n[b]"])[0].tolist() == [1.0, 2.0]
    with pytest.raises(ProblemError, match="has 2 values but the contact LCP has 3"):
        warm_start(plain, ["n[a]", "n[b]", "n[c]"])


@pytest.mark.parametrize("z0,words", [
    ("nan", "the warm start z0 contains NaN or Inf"),
    ("short", "the warm start z0 has 3 values but the contact LCP has 4"),
    ("bool", "the warm start z0 holds booleans"),
    ("complex", "the warm start z0 holds complex numbers"),
])
def test_library_warm_start_follows_the_data_rule_in_library_words(z0, words) -> None:
    """contact.solve(z0=...) in a library call: the data rule of M and q (booleans were taken
    as impulses 0/1, complex numbers cast), and messages that name z0, not the CLI's --z0."""
    clcp = build(load_scene(SAMPLES / "scene_cube_on_plane.json"))
    n = clcp.problem.n
    given = {"nan": np.full(n, np.nan), "short": np.zeros(n - 1),
             "bool": np.zeros(n, bool), "complex": np.zeros(n, complex)}[z0]
    with pytest.raises(OptionError) as err:
        solve(clcp, z0=given)
    assert str(err.value).startswith(words) and "--z0" not in str(err.value)


def test_bad_warm_start_and_new_options_exit_2(tmp_path, capsys) -> None:
    path = str(SAMPLES / "scene_two_balls.json")
    short = tmp_path / "short.json"
    short.write_text("[1.0]")
    out = tmp_path / "imp.json"
    cases = [
        (["--solve", "--z0", str(short)], "has 1 values"),
        (["--z0", str(short)], "--z0 needs --solve"),
        (["--solve", "--impulses", str(tmp_path / "x.txt")], ".json or .npz"),
        (["--solve", "--softness", "-1"], "--softness"),
        (["--solve", "--restitution-threshold", "-0.5"], "--restitution-threshold"),
        (["--solve", "--jobs", "0"], "--jobs"),
        (["--solve", "--z0", str(tmp_path / "missing.json"), "--impulses", str(out)],
         "no such file"),
    ]
    for args, word in cases:
        code, _, err = run_inprocess(capsys, "contact-matrix", path, *args)
        assert code == 2 and word in err and len(err.strip().splitlines()) == 1, (args, err)
        assert "Traceback" not in err
    assert not out.exists()


# ---------------------------------------------------------------------- files
def test_new_scene_keys_round_trip_through_hdf5(tmp_path) -> None:
    data = paddle_scene(True)
    data["restitution_threshold"] = 0.3
    data["softness"] = 0.2
    data["contacts"][0]["restitution_threshold"] = 0.05
    data["contacts"][1]["softness"] = 0.0
    scene = scene_from_dict(data)
    write_scene_hdf5(scene, tmp_path / "s.h5")
    again = load_scene(tmp_path / "s.h5")
    assert again.kinematic.tolist() == [True, False, False]
    assert again.threshold_default == 0.3 and again.softness_default == 0.2
    assert np.array_equal(again.restitution_threshold, scene.restitution_threshold,
                          equal_nan=True)
    assert np.array_equal(again.softness, scene.softness, equal_nan=True)
    a, b = build(scene), build(again)
    assert a.softness.tolist() == b.softness.tolist() == [0.2, 0.0]
    assert a.assembly.threshold.tolist() == b.assembly.threshold.tolist() == [0.05, 0.3]
    assert np.allclose(a.problem.dense_M(), b.problem.dense_M())


@pytest.mark.parametrize(("key", "value", "word"), [
    ("restitution_threshold", -1.0, "restitution_threshold"),
    ("softness", float("inf"), "softness"),
    ("kinematic", "yes", "kinematic"),
])
def test_bad_new_keys(key: str, value, word: str) -> None:
    data = paddle_scene(False)
    if key == "kinematic":
        data["bodies"][0][key] = value
    else:
        data["contacts"][0][key] = value
    with pytest.raises(ProblemError, match=word):
        scene_from_dict(data)
    if key != "kinematic":
        data = paddle_scene(False)
        data[key] = value
        with pytest.raises(ProblemError, match=word):
            scene_from_dict(data)


def test_to_json_without_solve_has_islands_but_no_per_island() -> None:
    d = to_json(build(load_scene(SAMPLES / "scene_conveyor.json")))
    assert d["islands"]["count"] == 2 and "per_island" not in d["islands"]


def test_newton_on_structurally_singular_jacobians_writes_nothing(capfd) -> None:
    """Newton on the whole-scene LCP of 12 box stacks meets Jacobians with empty columns;
    SuperLU's column ordering then called BLAS with invalid arguments, and OpenBLAS wrote
    '** On entry to DTRSV parameter number 6 had an illegal value' (172 lines) on stdout,
    under `lcpcli solve --json`'s one object.  Such a matrix is singular: no LU is tried
    (lcpcli.solvers.support.sparse_lu), and Newton takes its Levenberg-Marquardt step."""
    import lcpcli

    clcp = build(box_stacks(12, seed=1), friction=4)
    assert clcp.problem.sparse
    capfd.readouterr()
    r = lcpcli.solve(clcp.problem, "newton")
    out, err = capfd.readouterr()
    assert "illegal value" not in out and "illegal value" not in err
    assert r.status in ("solved", "unsolved")


def test_sparse_lu_refuses_singular_matrices() -> None:
    """sparse_lu: None for a structurally singular matrix (an empty column, a column holding
    only an explicit zero) and an exactly singular one; the factorization otherwise."""
    import scipy.sparse as sp

    from lcpcli.solvers.support import sparse_lu

    empty_column = sp.csc_matrix(np.array([[1.0, 0.0], [2.0, 0.0]]))
    explicit_zero = sp.csc_matrix((np.array([1.0, 0.0]), np.array([0, 1]), np.array([0, 1, 2])))
    singular = sp.csc_matrix(np.array([[1.0, 2.0], [2.0, 4.0]]))
    assert sparse_lu(empty_column) is None and sparse_lu(explicit_zero) is None
    assert sparse_lu(singular) is None
    lu = sparse_lu(sp.csc_matrix(np.array([[2.0, 1.0], [1.0, 3.0]])))
    assert np.allclose(lu.solve(np.array([3.0, 4.0])), [1.0, 1.0])
