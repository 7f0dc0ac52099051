"""Invariants of ``lcpcli contact-matrix`` at the boundary (docs/contact.md): every valid scene
(2-D and 3-D; moving, static and kinematic bodies; diagonal and full inertia; restitution,
friction, thresholds and softness on or off; any storage; masses and lengths over many orders
of magnitude) exits 0 (1 or 0 with ``--solve``), its ``--json`` is strict JSON, its LCP written
with ``-o`` in every format reads back through ``lcpcli info`` and ``lcpcli solve``, holds
exactly the ``M`` and ``q`` of ``--json`` and of the library's ``build`` (bit for bit), and a
frictionless scene (a symmetric PSD M, Cottle-Pang-Stone 3.8) is ``unsolved`` only when it is
infeasible up to rounding (a jammed scene: an LP finds its Farkas vector).  Invalid scenes
(wrong types, NaN, negative masses, missing keys, unknown bodies, absurd counts) are one line,
exit 2; nothing exits 3.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from invariants import cli, one_line_error, strict_json

from lcpcli.contact import build, load_scene
from lcpcli.io import load

SETTINGS = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])


def vec(rng: np.random.Generator, d: int, scale: float) -> list[float]:
    return (rng.normal(size=d) * scale).tolist()


@st.composite
def scenes(draw: st.DrawFn) -> dict[str, Any]:
    """A valid JSON scene: 1-4 moving bodies, maybe a static ground and a kinematic body, 1-5
    contacts between two bodies that are not both fixed; units drawn from 1e-6 to 1e6."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    d = draw(st.sampled_from([2, 3]))
    length = 10.0 ** draw(st.integers(-6, 6))  # the scene's unit of length
    mass_unit = 10.0 ** draw(st.integers(-6, 6))
    bodies: list[dict[str, Any]] = []
    for k in range(draw(st.integers(1, 4))):
        m = float(mass_unit * rng.uniform(0.1, 10))
        b: dict[str, Any] = {"name": f"b{k}", "mass": m, "position": vec(rng, d, length),
                             "velocity": vec(rng, d, length)}
        if d == 2:
            b["inertia"] = float(m * length ** 2 * rng.uniform(0.05, 1))
            if rng.random() < 0.5:
                b["angular_velocity"] = float(rng.normal())
            if rng.random() < 0.3:
                b["orientation"] = float(rng.normal())
        else:
            if rng.random() < 0.5:
                b["inertia"] = (m * length ** 2 * rng.uniform(0.05, 1, 3)).tolist()
            else:  # full symmetric positive definite
                A = rng.normal(size=(3, 3))
                b["inertia"] = (m * length ** 2 * (A @ A.T + np.eye(3))).tolist()
            if rng.random() < 0.5:
                b["angular_velocity"] = vec(rng, 3, 1.0)
            if rng.random() < 0.3:
                quat = rng.normal(size=4)
                b["orientation"] = (quat / np.linalg.norm(quat)).tolist()
        bodies.append(b)
    fixed = []
    if draw(st.booleans()):
        bodies.append({"name": "ground", "static": True})
        fixed.append(len(bodies) - 1)
    if draw(st.booleans()):
        bodies.append({"name": "belt", "kinematic": True, "position": vec(rng, d, length),
                       "velocity": vec(rng, d, length)})
        fixed.append(len(bodies) - 1)
    contacts = []
    for c in range(draw(st.integers(1, 5))):
        a = int(rng.integers(0, len(bodies)))
        choices = [i for i in range(len(bodies)) if i != a and not (a in fixed and i in fixed)]
        if not choices:
            continue
        b_ = int(rng.choice(choices))
        normal = rng.normal(size=d)
        contact: dict[str, Any] = {"name": f"c{c}", "a": f"{bodies[a]['name']}",
                                   "b": f"{bodies[b_]['name']}",
                                   "point": vec(rng, d, length),
                                   "normal": (normal / np.abs(normal).max()).tolist(),
                                   "restitution": float(rng.choice([0.0, 0.5, 1.0]))}
        if rng.random() < 0.6:
            contact["mu"] = float(rng.choice([0.0, 0.3, 2.0]))
        if rng.random() < 0.2:
            contact["restitution_threshold"] = float(length * rng.uniform(0, 1))
        if rng.random() < 0.2:
            contact["softness"] = float(rng.uniform(0, 0.5))
        contacts.append(contact)
    scene: dict[str, Any] = {"name": "random", "dimension": d, "bodies": bodies,
                             "contacts": contacts}
    if draw(st.booleans()):
        scene["restitution_threshold"] = float(length * rng.uniform(0, 0.1))
    if draw(st.booleans()):
        scene["softness"] = float(rng.uniform(0, 0.1))
    return scene


def same_bits(a: Any, b: Any) -> bool:
    a = a.toarray() if hasattr(a, "toarray") else np.asarray(a, dtype=np.float64)
    b = b.toarray() if hasattr(b, "toarray") else np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def json_matrix(M: Any, n: int) -> np.ndarray:
    """The ``M`` of ``--json`` (rows, or CSR parts) as a dense array."""
    if isinstance(M, dict):
        out = np.zeros(M["shape"])
        for i in range(M["shape"][0]):
            for k in range(M["indptr"][i], M["indptr"][i + 1]):
                out[i, M["indices"][k]] += M["data"][k]
        return out
    return np.asarray(M, dtype=np.float64).reshape(n, n)


def infeasible_up_to_rounding(M: np.ndarray, q: np.ndarray) -> bool:
    """Whether a Farkas vector exists to rounding level: ``y >= 0``, ``sum y = 1``,
    ``M^T y <= 1e-9 max|M|``, ``q^T y < -1e-9 max|q|`` (an LP, scipy's HiGHS).  A jammed scene
    (force closure: ``J^T y = 0``, so ``M y = 0``) has one, but M's null space is exact only up
    to rounding, so no solver can prove it on the data as given (docs/contact.md)."""
    from scipy.optimize import linprog

    n = q.size
    if n == 0:
        return False
    tol = 1e-9 * max(float(np.abs(M).max()), 1e-300)
    res = linprog(q, A_ub=M.T, b_ub=np.full(n, tol), A_eq=np.ones((1, n)), b_eq=[1.0],
                  bounds=[(0, None)] * n, method="highs")
    return bool(res.status == 0 and res.fun < -1e-9 * float(np.abs(q).max()))


#: A jammed 2-D scene (five contacts between two bodies: M has rank 3 up to rounding, and the
#: scene is infeasible): every method ends 'unsolved' (docs/contact.md, "Frictional LCPs").
JAMMED_2D = {
    "name": "jammed", "dimension": 2,
    "bodies": [{"name": "b0", "mass": 9.502977483140349, "inertia": 7.805881952757768,
                "position": [1.6098510411990912, -1.637984323552583],
                "velocity": [-1.3347051873170552, -2.3928703745008923],
                "angular_velocity": 0.36539305740527883},
               {"name": "b1", "mass": 3.9664828088318154, "inertia": 0.9061605297509756,
                "position": [0.04166747698626032, -1.4321320408276685],
                "velocity": [0.8155081526581629, -0.05934892110612115]}],
    "contacts": [{"a": "b1", "b": "b0", "point": p, "normal": nrm, "restitution": e}
                 for p, nrm, e in (
                     ([-0.3158726803157823, 0.962201321360403], [-0.6277025805549699, -1.0], 0.5),
                     ([2.140613125929898, 0.5552487520819189], [0.7522960161557666, -1.0], 0.5),
                     ([-0.6605014625485379, -0.5749016578117795], [0.07988099983775497, -1.0],
                      0.0),
                     ([-2.2534700899596594, -0.8879567278997413], [-1.0, -0.638918871027431],
                      0.0),
                     ([0.21131654455440244, 1.9523913206676557], [-0.4150662347152192, 1.0],
                      0.0))],
}


@SETTINGS
@example(scene=JAMMED_2D, friction=0, storage="auto", out="json", do_solve=True)
@given(scene=scenes(), friction=st.sampled_from([0, 0, 4, 8]),
       storage=st.sampled_from(["auto", "dense", "sparse"]),
       out=st.sampled_from(["json", "npz", "h5", "dat"]), do_solve=st.booleans())
def test_random_scenes(tmp_path: Path, scene: dict, friction: int, storage: str, out: str,
                       do_solve: bool) -> None:
    folder = tmp_path / str(np.random.default_rng().integers(1 << 40))
    folder.mkdir()
    path = folder / "scene.json"
    path.write_text(json.dumps(scene))
    if scene["dimension"] == 2 and friction:
        friction = 2
    target = folder / f"lcp.{out}"
    args = ["contact-matrix", path, "--friction", str(friction), "--storage", storage,
            "-o", target, "--json"] + (["--solve"] if do_solve else [])
    code, stdout, err = cli(*args)
    assert code in ((0, 1) if do_solve else (0,)), err
    assert "internal error" not in err and "Traceback" not in err, err
    doc = strict_json(stdout)
    n = len(doc["q"])
    M_json = json_matrix(doc["M"], n)
    # the library builds the same LCP
    clcp = build(load_scene(path), friction=friction, storage=storage)
    assert same_bits(clcp.problem.M, M_json) and same_bits(clcp.problem.q, doc["q"])
    # the written LCP: the same M and q, read back by info and solve
    written = load(target)
    assert same_bits(written.M, M_json) and same_bits(written.q, doc["q"])
    code_i, out_i, err_i = cli("info", target, "--json")
    assert code_i == 0, err_i
    strict_json(out_i)
    code_s, out_s, err_s = cli("solve", target, "--json")
    assert code_s in (0, 1), err_s
    row = strict_json(out_s)
    if friction == 0 and row["status"] == "unsolved":  # symmetric PSD: solved, or infeasible
        assert infeasible_up_to_rounding(M_json, np.asarray(doc["q"])), row["message"]
    if do_solve:
        assert doc["status"] in ("solved", "no_solution", "unsolved")
        assert code == (0 if doc["status"] == "solved" else 1)
        if friction == 0 and doc["status"] == "unsolved":
            assert infeasible_up_to_rounding(M_json, np.asarray(doc["q"])), doc["message"]
        if doc["status"] == "solved":
            z = np.asarray(doc["impulses"], dtype=np.float64)
            assert z.shape == (n,) and np.all(z >= 0)


# ---------------------------------------------------------------------------- invalid scenes
BAD = {
    "mass_text": ("bodies", 0, "mass", "1.0"),
    "mass_negative": ("bodies", 0, "mass", -1.0),
    "mass_zero": ("bodies", 0, "mass", 0.0),
    "mass_bool": ("bodies", 0, "mass", True),
    "mass_nan": ("bodies", 0, "mass", math.nan),
    "position_inf": ("bodies", 0, "position", [math.inf] * 3),
    "position_short": ("bodies", 0, "position", [1.0]),
    "inertia_negative": ("bodies", 0, "inertia", -1.0),
    "inertia_not_spd": ("bodies", 0, "inertia", [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0],
                                                 [0.0, 0.0, 1.0]]),
    "velocity_text": ("bodies", 0, "velocity", "fast"),
    "static_text": ("bodies", 0, "static", "yes"),
    "static_and_kinematic": ("bodies", 0, "kinematic", True),
    "normal_zero": ("contacts", 0, "normal", [0.0, 0.0, 0.0]),
    "normal_nan": ("contacts", 0, "normal", [math.nan, 0.0, 1.0]),
    "restitution_2": ("contacts", 0, "restitution", 2.0),
    "mu_negative": ("contacts", 0, "mu", -0.5),
    "unknown_body": ("contacts", 0, "a", "nobody"),
    "self_contact": ("contacts", 0, "b", "b0"),
    "point_dict": ("contacts", 0, "point", {"x": 1}),
    "threshold_negative": ("contacts", 0, "restitution_threshold", -1.0),
    "softness_inf": ("contacts", 0, "softness", math.inf),
    "unknown_key": ("contacts", 0, "restiution", 0.5),
}


@SETTINGS
@given(scene=scenes(), how=st.sampled_from(sorted(BAD) + ["missing_mass", "missing_position",
                                                         "missing_point", "missing_a",
                                                         "bodies_empty", "bodies_dict",
                                                         "dimension_4", "duplicate_name",
                                                         "huge_friction", "not_object"]))
def test_invalid_scenes_one_line_exit_2(tmp_path: Path, scene: dict, how: str) -> None:
    """One line on stderr, exit 2, nothing on stdout and no output file."""
    folder = tmp_path / str(np.random.default_rng().integers(1 << 40))
    folder.mkdir()
    d = scene["dimension"]
    if not scene["contacts"]:  # every drawn contact joined two fixed bodies
        scene["contacts"] = [{"a": "b0", "b": "b0", "point": [0.0] * d, "normal": [1.0] * d}]
    scene["bodies"][0].pop("static", None)
    scene["contacts"][0]["a"] = "b0"  # the first contact touches the moving body b0
    if scene["contacts"][0]["b"] == "b0":
        scene["contacts"][0]["b"] = next(b["name"] for b in scene["bodies"][1:]) \
            if len(scene["bodies"]) > 1 else "b0"
    if scene["contacts"][0]["b"] == "b0" and how != "self_contact":
        scene["bodies"].append({"name": "floor", "static": True})
        scene["contacts"][0]["b"] = "floor"
    extra: list[str] = []
    text: str | None = None
    if how in BAD:
        where, k, key, value = BAD[how]
        if isinstance(value, list) and len(value) == 3 and key in ("position", "normal") \
                and d == 2:
            value = value[:2]
        if how == "inertia_not_spd" and d == 2:
            value = -2.0
        scene[where][k][key] = value
        if how == "static_and_kinematic":
            scene["bodies"][0]["static"] = True
    elif how.startswith("missing_"):
        key = how[len("missing_"):]
        scene["bodies" if key in ("mass", "position") else "contacts"][0].pop(key, None)
    elif how == "bodies_empty":
        scene["bodies"] = []
    elif how == "bodies_dict":
        scene["bodies"] = {"b0": scene["bodies"][0]}
    elif how == "dimension_4":
        scene["dimension"] = 4
    elif how == "duplicate_name":
        scene["bodies"].append(dict(scene["bodies"][0]))
    elif how == "huge_friction":  # (2-D: K = 2 is used, with a note)
        extra = ["--friction", str(10**9) if d == 3 else "-1"]
    else:
        text = json.dumps([scene])
    path = folder / "scene.json"
    path.write_text(text if text is not None else json.dumps(scene))
    target = folder / "lcp.npz"
    code, out, err = cli("contact-matrix", path, "--solve", "-o", target, "--json", *extra)
    one_line_error(code, err)
    assert out == "" and not target.exists()


def test_bad_option_after_scene_warning_is_one_line(tmp_path: Path) -> None:
    """A scene that loads with a warning (a normal of length 2, normalised) and an option
    refused afterwards (3-D friction with K = 2 < 3): the warning was printed before the error,
    two lines on stderr; now the refusal is the one line."""
    scene = {"dimension": 3, "bodies": [{"name": "g", "static": True},
                                        {"name": "b", "mass": 1.0, "inertia": [1.0, 1.0, 1.0],
                                         "position": [0.0, 0.0, 1.0]}],
             "contacts": [{"a": "b", "b": "g", "point": [0.0, 0.0, 0.0],
                           "normal": [0.0, 0.0, 2.0], "mu": 0.5}]}
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    for args in (["--friction", "2"], ["--friction", "1000"], ["--solve", "--z0", "nope.json"]):
        code, out, err = cli("contact-matrix", path, "--json", *args)
        one_line_error(code, err)
        assert out == ""
    code, out, err = cli("contact-matrix", path, "--json", "--friction", "4")
    assert code == 0 and "normal of length 2 normalised" in err, err
