"""Scenes read under the rules of every input (issue 23, docs/files.md "Reading").

Each hostile scene is a fixture built in ``tmp_path`` and run through ``contact-matrix`` in this
process (or, where the old reader allocated gigabytes, in a subprocess under the 1 GiB limit of
tests/cli/test_bad_inputs.py): exit 2, one ``lcpcli: error: FILE: ...`` line, no traceback.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from lcpcli.contact.scene import check_coupling, load_scene, scene_from_dict, write_scene_hdf5
from lcpcli.core.errors import ProblemError
from tests.cli.test_bad_inputs import BAD, Case, problems, run_in_process, run_subprocess

h5py = pytest.importorskip("h5py")

SCENE = {"bodies": [{"name": "ground", "static": True},
                    {"name": "ball", "mass": 1.0, "inertia": [0.4, 0.4, 0.4],
                     "position": [0, 0, 1], "velocity": [0, 0, -1]}],
         "contacts": [{"a": "ball", "b": "ground", "point": [0, 0, 0], "normal": [0, 0, 1]}]}


def _variants(d: Path) -> dict[str, Callable[..., None]]:
    """HDF5 scenes: the valid one with one dataset replaced (name -> edit of the open file)."""
    outside = d / "outside.h5"
    with h5py.File(outside, "w") as f:
        f["position"] = np.array([[0, 0, 0], [0, 0, 1.0]])
        f["x"] = np.zeros(6)
    (d / "raw.bin").write_bytes(np.zeros(3).tobytes())

    def replace(group: str, key: str, **kwargs: object) -> Callable[..., None]:
        def edit(f: h5py.File) -> None:
            del f[f"{group}/{key}"]
            f[group].create_dataset(key, **kwargs)
        return edit

    def extlink(f: h5py.File) -> None:
        del f["bodies/position"]
        f["bodies/position"] = h5py.ExternalLink(str(outside), "position")

    def vds(f: h5py.File) -> None:
        del f["bodies/velocity"]
        layout = h5py.VirtualLayout(shape=(2, 3), dtype="f8")
        layout[0, :] = h5py.VirtualSource(str(outside), "x", shape=(6,))[:3]
        f["bodies"].create_virtual_dataset("velocity", layout, fillvalue=0)

    def vds_passwd(f: h5py.File) -> None:
        del f["bodies/velocity"]
        layout = h5py.VirtualLayout(shape=(2, 3), dtype="u1")
        layout[0, :] = h5py.VirtualSource("/etc/passwd", "x", shape=(3,))
        f["bodies"].create_virtual_dataset("velocity", layout, fillvalue=0)

    def linked_group(f: h5py.File) -> None:
        del f["contacts"]
        f["contacts"] = h5py.ExternalLink(str(outside), "/")

    return {
        "extlink": extlink,
        "external_storage": replace("contacts", "point", shape=(1, 3), dtype="<f8",
                                    external=[(str(d / "raw.bin"), 0, 24)]),
        "dev_zero": replace("bodies", "angular_velocity", shape=(2, 3), dtype="<f8",
                            external=[("/dev/zero", 0, 48)]),
        "vds": vds,
        "vds_passwd": vds_passwd,
        "linked_group": linked_group,
        "huge_static": replace("bodies", "static", shape=(4 * 10**9,), dtype="u1",
                               chunks=(2**20,)),
        "huge_name": replace("bodies", "name", shape=(12 * 10**8,), dtype="S10",
                             chunks=(2**16,)),
        "huge_contacts": replace("contacts", "a", shape=(10**9,), dtype="i8", chunks=(2**20,)),
        "long_fill_names": replace("bodies", "name", shape=(10**4,), chunks=(1000,),
                                   dtype=h5py.string_dtype(), fillvalue="x" * 10**5),
        "complex_mass": replace("bodies", "mass", data=np.array([np.nan, 1.0 + 1j])),
        "text_normal": replace("contacts", "normal", data=np.array([[b"0", b"0", b"1"]])),
        "float_static": replace("bodies", "static", data=np.array([1.0, 0.0])),
        "bool_mass": replace("bodies", "mass", data=np.array([False, True])),
        "float_refs": replace("contacts", "a", data=np.array([1.0])),
        "wrong_shape": replace("bodies", "position", data=np.zeros((3, 3))),
        "scalar_dimension": lambda f: f.attrs.__setitem__("dimension", np.array([3, 3])),
    }


#: What each HDF5 scene must be refused with (the start of the reason after the file name).
H5_WORDS = {
    "extlink": "'bodies/position' is an external link",
    "external_storage": "'contacts/point' keeps its data in other files",
    "dev_zero": "'bodies/angular_velocity' keeps its data in other files",
    "vds": "'bodies/velocity' keeps its data in other files",
    "vds_passwd": "'bodies/velocity' keeps its data in other files",
    "linked_group": "'contacts' is an external link",
    "huge_static": "dataset 'bodies/static' has shape (4000000000,), expected (2,)",
    "huge_name": "dataset 'bodies/name' declares 1,200,000,000 rows",
    "huge_contacts": "dataset 'contacts/a' declares 1,000,000,000 rows",
    "long_fill_names": "dataset 'bodies/name' of 954 MiB is over the limit of 256 MiB",
    "complex_mass": "'bodies/mass' holds complex numbers",
    "text_normal": "'contacts/normal' holds byte strings",
    "float_static": "'bodies/static' holds floating-point numbers",
    "bool_mass": "'bodies/mass' holds booleans",
    "float_refs": "dataset 'contacts/a' must hold body names or 0-based indices",
    "wrong_shape": "dataset 'bodies/position' has shape (3, 3), expected (2, 3)",
    "scalar_dimension": "attribute 'dimension' must be one integer",
}
#: The cases the old reader spent gigabytes on: run under the 1 GiB address-space limit.
SUBPROCESS = {"huge_static", "huge_name", "huge_contacts", "long_fill_names"}

JSON_SCENES = {
    "deep": ('{"bodies": ' + "[" * 100_000 + "]" * 100_000 + "}",
             "invalid JSON: arrays or objects nested too deeply"),
    "int_401_digits": (json.dumps(SCENE).replace('"mass": 1.0', '"mass": ' + "9" * 401),
                       "body 'ball': 'mass' is an integer too large for a float"),
    "int_700_digits": (json.dumps(SCENE).replace('"mass": 1.0', '"mass": ' + "9" * 700),
                       "invalid JSON: Exceeds the limit of 640 digits"),
    "duplicate_key": (json.dumps(SCENE)[:-1] + ', "contacts": []}',
                      "invalid JSON: key 'contacts' appears twice"),
    "duplicate_body_key": (json.dumps(SCENE).replace('"mass": 1.0', '"mass": 1.0, "mass": 2'),
                           "invalid JSON: key 'mass' appears twice"),
    "numeric_text_mass": (json.dumps(SCENE).replace('"mass": 1.0', '"mass": "1.0"'),
                          "body 'ball': 'mass' must be a number"),
    "bool_normal": (json.dumps(SCENE).replace('"normal": [0, 0, 1]', '"normal": [0, 0, true]'),
                    "contact 1: 'normal' must be a number"),
}


@pytest.fixture(scope="module")
def scenes(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("scenes")
    (d / "scene.json").write_text(json.dumps(SCENE))
    write_scene_hdf5(load_scene(d / "scene.json"), d / "scene.h5")
    for name, edit in _variants(d).items():
        shutil.copy(d / "scene.h5", d / f"{name}.h5")
        with h5py.File(d / f"{name}.h5", "a") as f:
            edit(f)
    for name, (text, _words) in JSON_SCENES.items():
        (d / f"{name}.json").write_text(text)
    return d


def _refused(d: Path, file: str, words: str, sub: bool = False) -> None:
    case = Case(file, "lenient", ["contact-matrix", f"{{d}}/{file}"], BAD, f"{{d}}/{file}: {words}",
                sub=sub, memory=sub)
    out = run_subprocess(case, d) if sub else run_in_process(case, d)
    assert problems(case, out, d, {}) == []


def test_the_valid_scenes_are_read(scenes: Path) -> None:
    a, b = load_scene(scenes / "scene.json"), load_scene(scenes / "scene.h5")
    assert a.n_bodies == b.n_bodies == 2 and a.n_contacts == b.n_contacts == 1
    np.testing.assert_array_equal(a.normal, b.normal)
    np.testing.assert_array_equal(a.static, b.static)


@pytest.mark.parametrize("name", sorted(H5_WORDS))
def test_hdf5_scene_refused(scenes: Path, name: str) -> None:
    _refused(scenes, f"{name}.h5", H5_WORDS[name], sub=name in SUBPROCESS)


@pytest.mark.parametrize("name", sorted(JSON_SCENES))
def test_json_scene_refused(scenes: Path, name: str) -> None:
    _refused(scenes, f"{name}.json", JSON_SCENES[name][1])


def test_static_flags_as_integers_are_read(tmp_path: Path) -> None:
    """0/1 integers are flags too (anything else is not)."""
    path = tmp_path / "s.h5"
    write_scene_hdf5(scene_from_dict(SCENE), path)
    with h5py.File(path, "a") as f:
        del f["bodies/static"]
        f["bodies/static"] = np.array([1, 0], dtype=np.int8)
    assert load_scene(path).static.tolist() == [True, False]
    with h5py.File(path, "a") as f:
        del f["bodies/static"]
        f["bodies/static"] = np.array([2, 0], dtype=np.int8)
    with pytest.raises(ProblemError, match="must hold booleans"):
        load_scene(path)


def _star(n_contacts: int, dynamic_leaves: bool = False) -> dict:
    leaf = ({"mass": 1.0, "inertia": [1, 1, 1], "position": [0, 0, -1]} if dynamic_leaves
            else {"static": True})
    return {"bodies": [{"name": "hub", "mass": 1.0, "inertia": [1, 1, 1],
                        "position": [0, 0, 0], "velocity": [0, 0, -1]}]
            + [{"name": f"g{i}", **leaf} for i in range(n_contacts)],
            "contacts": [{"a": "hub", "b": f"g{i}", "point": [0, 0, 0], "normal": [0, 0, 1]}
                         for i in range(n_contacts)]}


@pytest.mark.parametrize("n", [1, 7, 40])
def test_coupling_bound_is_an_upper_bound_on_the_stored_entries(n: int) -> None:
    """check_coupling's bound (rows^2 * sum of squared contact counts on moving bodies) is
    never below what assembly stores, and it refuses above the sparse limit."""
    import lcpcli.contact.scene as scene_module
    import lcpcli.core.problem as problem_module
    from lcpcli.contact import build

    for dynamic in (False, True):
        scene = scene_from_dict(_star(n, dynamic))
        deg = np.bincount(scene.contact_a, minlength=scene.n_bodies) \
            + np.bincount(scene.contact_b, minlength=scene.n_bodies)
        deg[scene.fixed] = 0
        bound = int(np.sum(deg ** 2))
        M = build(scene, storage="sparse").problem.M
        assert M.nnz <= bound
        limit = problem_module.MAX_SPARSE_NNZ
        try:  # the limit as contact.scene reads it (imported from core.problem)
            scene_module.MAX_SPARSE_NNZ = bound - 1
            with pytest.raises(ProblemError, match="would hold up to"):
                check_coupling(scene)
            scene_module.MAX_SPARSE_NNZ = bound
            check_coupling(scene)
        finally:
            scene_module.MAX_SPARSE_NNZ = limit


def test_star_scene_refused_before_assembly(tmp_path: Path) -> None:
    """A 30,000-contact star couples 9e8 pairs, over the 5e8 limit: one line, exit 2."""
    nb = 30_001
    path = tmp_path / "star.h5"
    with h5py.File(path, "w") as f:
        gb, gc = f.create_group("bodies"), f.create_group("contacts")
        gb["static"] = np.r_[False, np.ones(nb - 1, dtype=bool)]
        gb["mass"] = np.r_[1.0, np.full(nb - 1, np.nan)]
        gb["inertia"] = np.r_[[[1.0, 1, 1]], np.full((nb - 1, 3), np.nan)]
        gb["position"] = np.zeros((nb, 3))
        gb["velocity"] = np.r_[[[0, 0, -1.0]], np.zeros((nb - 1, 3))]
        gc["a"] = np.zeros(nb - 1, dtype=np.int64)
        gc["b"] = np.arange(1, nb)
        gc["point"] = np.zeros((nb - 1, 3))
        gc["normal"] = np.tile([0, 0, 1.0], (nb - 1, 1))
    _refused(tmp_path, "star.h5", "the contact LCP would hold up to 900,000,000 stored entries")


def test_dense_storage_checked_against_the_dense_work_budget(tmp_path: Path) -> None:
    """--storage dense on 120 contacts with the budget at 100: refused, naming the override."""
    from lcpcli.core.limits import DENSE_N_ENV, DENSE_N_FLOOR

    (tmp_path / "star.json").write_text(json.dumps(_star(120)))
    case = Case("dense", "lenient", ["contact-matrix", "{d}/star.json", "--storage", "dense"],
                BAD, "{d}/star.json: n = 120: --storage dense builds M as a dense matrix",
                env={DENSE_N_ENV: str(DENSE_N_FLOOR)})
    out = run_in_process(case, tmp_path)
    assert problems(case, out, tmp_path, {}) == []
    ok = Case("ok", "lenient", ["contact-matrix", "{d}/star.json", "--storage", "dense"], 0, None,
              env={DENSE_N_ENV: "120"})
    assert problems(ok, run_in_process(ok, tmp_path), tmp_path, {}) == []


def _one_body(n_contacts: int) -> dict:
    """The issue's scene: n contacts of one moving body on the ground (M is all ones)."""
    return {"bodies": [{"name": "g", "static": True},
                       {"name": "b", "mass": 1, "inertia": [1, 1, 1], "position": [0, 0, 0],
                        "velocity": [0, 0, -1]}],
            "contacts": [{"a": "b", "b": "g", "point": [i * 1e-3, 0, 0], "normal": [0, 0, 1]}
                         for i in range(n_contacts)]}


@pytest.mark.parametrize("extra", [[], ["--solve"], ["--solve", "-o", "{d}/out.json"]])
def test_auto_storage_never_builds_a_dense_m_over_the_budget(tmp_path: Path, extra: list[str]
                                                              ) -> None:
    """--storage auto on a filled M over the dense-work budget (n = 12,000 built a dense M of
    2.3 GB in 9 s; sparse took 5.1 GB): refused before M is assembled, naming the scene file,
    with or without --solve, and nothing is written."""
    from lcpcli.core.limits import DENSE_N_ENV

    (tmp_path / "scene.json").write_text(json.dumps(_one_body(150)))
    case = Case("auto", "memory", ["contact-matrix", "{d}/scene.json", *extra], BAD,
                "{d}/scene.json: n = 150: --storage auto keeps M dense when a quarter of it or "
                "more is filled", absent=("out.json",), env={DENSE_N_ENV: "120"})
    assert problems(case, run_in_process(case, tmp_path), tmp_path, {}) == []


def test_auto_storage_goes_sparse_over_the_budget_and_solve_refusals_name_the_scene(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A sparse M over the dense-work budget stays sparse under --storage auto (also per
    island) and solves with a sparse method; a method that needs the dense M is refused before
    anything is written, naming the scene file (it named none)."""
    from lcpcli.contact.assembly import choose_storage
    from lcpcli.core.limits import DENSE_N_ENV

    (tmp_path / "star.json").write_text(json.dumps(_star(150)))  # one moving body, 150 contacts
    ok = Case("ok", "lenient", ["contact-matrix", "{d}/star.json", "--storage", "sparse",
                                "--solve", "-m", "pgs"], 0, None, env={DENSE_N_ENV: "120"})
    assert problems(ok, run_in_process(ok, tmp_path), tmp_path, {}) == []
    bad = Case("lemke", "lenient", ["contact-matrix", "{d}/star.json", "--storage", "sparse",
                                    "--solve", "-m", "lemke", "-o", "{d}/out.json"], BAD,
               "{d}/star.json: n = 150: method 'lemke", absent=("out.json",),
               env={DENSE_N_ENV: "120"})
    assert problems(bad, run_in_process(bad, tmp_path), tmp_path, {}) == []
    assert choose_storage("auto", 150, 150 * 150) == "dense"
    monkeypatch.setenv(DENSE_N_ENV, "120")
    assert choose_storage("auto", 150, 150 * 150) == "sparse"
    assert choose_storage("auto", 110, 110) == "dense"  # small: dense, whatever the fill


def test_every_hdf5_column_reads_as_its_json_twin(tmp_path: Path) -> None:
    """Orientation, body-frame inertia, angular velocity, kinematic flags, name references and
    per-contact parameters: the checked HDF5 reader gives the scene the JSON reader gives."""
    rng = np.random.default_rng(3)
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    inertia = np.diag([1.0, 2.0, 3.0])
    scene = {"bodies": [{"name": "ground", "static": True},
                        {"name": "belt", "kinematic": True, "velocity": [1.0, 0, 0],
                         "position": [0, 0, 0]},
                        {"name": "box", "mass": 2.0, "inertia": inertia.tolist(),
                         "orientation": quat.tolist(), "position": [0, 0, 1],
                         "velocity": [0, 0.5, -1], "angular_velocity": [0.1, 0.2, 0.3]}],
             "contacts": [{"a": "box", "b": "ground", "point": [0, 0, 0.5],
                           "normal": [0, 0, 1], "restitution": 0.5, "mu": 0.3},
                          {"a": "box", "b": "belt", "point": [0.1, 0, 0.5],
                           "normal": [0, 0, 1], "softness": 0.01}]}
    path = tmp_path / "full.h5"
    with h5py.File(path, "w") as f:
        gb, gc = f.create_group("bodies"), f.create_group("contacts")
        gb["name"] = np.array([b["name"] for b in scene["bodies"]], dtype=h5py.string_dtype())
        gb["static"] = np.array([True, False, False])
        gb["kinematic"] = np.array([0, 1, 0], dtype=np.uint8)
        gb["mass"] = np.array([np.nan, np.nan, 2.0])
        gb["inertia"] = np.stack([np.full((3, 3), np.nan), np.full((3, 3), np.nan), inertia])
        gb["orientation"] = np.array([[np.nan] * 4, [np.nan] * 4, quat])
        gb["position"] = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 1.0]])
        gb["velocity"] = np.array([[0, 0, 0], [1.0, 0, 0], [0, 0.5, -1]])
        gb["angular_velocity"] = np.array([[0, 0, 0], [0, 0, 0], [0.1, 0.2, 0.3]])
        gc["a"] = np.array([b"box", b"box"])
        gc["b"] = np.array([0, 1], dtype=np.int32)
        gc["point"] = np.array([[0, 0, 0.5], [0.1, 0, 0.5]])
        gc["normal"] = np.array([[0, 0, 1.0], [0, 0, 1.0]])
        gc["restitution"] = np.array([0.5, 0.0])
        gc["mu"] = np.array([0.3, np.nan])
        gc["softness"] = np.array([np.nan, 0.01])
    a, b = scene_from_dict(scene), load_scene(path)
    for key in ("static", "kinematic", "mass", "inv_mass", "inertia", "inv_inertia", "position",
                "velocity", "omega", "contact_a", "contact_b", "point", "normal", "restitution",
                "mu", "softness"):
        np.testing.assert_allclose(getattr(a, key), getattr(b, key), rtol=1e-14, atol=0,
                                   err_msg=key)


@pytest.mark.parametrize("scale", [1e308, 3e-9])
def test_a_quaternion_of_any_length_is_normalised_without_overflow(scale: float) -> None:
    """An orientation ``(1, 1, 0, 0)`` scaled by 1e308 (its length overflows: normalised by
    that length it became zero, the inertia zero, with a numpy warning) or by 3e-9 is the
    same rotation: the same world inertia, bit for bit, and one warning naming its length."""
    import warnings

    samples = Path(__file__).resolve().parents[2] / "samples"
    data = json.loads((samples / "scene_cube_on_plane.json").read_text())
    cube = next(b for b in data["bodies"] if b.get("orientation"))
    cube["orientation"] = [1.0, 1.0, 0.0, 0.0]
    plain = scene_from_dict(data)
    cube["orientation"] = [scale, scale, 0.0, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        scaled = scene_from_dict(data)
    np.testing.assert_array_equal(scaled.inertia, plain.inertia)
    np.testing.assert_array_equal(scaled.inv_inertia, plain.inv_inertia)
    assert any("orientation quaternion of length" in w for w in scaled.warnings)
