"""Rigid-body scenes for contact LCPs: parsing and validation (JSON and HDF5).

Conventions:

* each contact joins body ``A`` and body ``B``; its unit normal ``n`` points **from B to A**;
  the normal impulse ``j n`` (``j >= 0``) acts on A and ``-j n`` on B;
* positions, velocities and the contact point are in world coordinates; ``r_a = p - x_a``;
* a quaternion is ``[w, x, y, z]`` (scalar first); the world inertia is ``R I R^T`` where ``I``
  is the body-frame tensor;
* ``static: true`` bodies (ground, walls) and ``kinematic: true`` bodies (prescribed velocity: a
  conveyor, a lift, a robot's hand) have inverse mass and inverse inertia zero: they get no
  unknowns and keep their velocity, which enters the relative velocity of their contacts;
  together they are the *fixed* bodies (:attr:`Scene.fixed`), the others are *dynamic*;
* per contact, ``restitution_threshold`` (speed above which an approaching contact bounces, see
  :mod:`lcpcli.contact.assembly`) and ``softness`` (relative compliance added to the diagonal)
  fall back to the scene-level value of the same key, then to the defaults there;
* 2-D scenes (``"dimension": 2``) have 3 DOF per body: positions/velocities ``(x, y)``, a scalar
  angular velocity and a scalar moment of inertia (about the axis out of the plane).

The scene is held as arrays (one row per body / per contact) so that assembling scenes with
thousands of bodies is vectorised.  Every bad input raises :class:`ProblemError` with one line.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import unit_rows
from lcpcli.core.problem import MAX_SPARSE_NNZ
from lcpcli.io import atomic_path
from lcpcli.io.files import (
    MAX_NAME_BYTES,
    MAX_TEXT_BYTES,
    check_input_file,
    read_json_file,
    too_big,
)
from lcpcli.io.writing import open_hdf5

BODY_KEYS = {"name", "mass", "inertia", "orientation", "position", "velocity",
             "angular_velocity", "static", "kinematic"}
CONTACT_KEYS = {"a", "b", "body_a", "body_b", "point", "normal", "restitution", "mu", "name",
                "restitution_threshold", "softness"}
SCENE_KEYS = {"name", "description", "dimension", "bodies", "contacts", "restitution_threshold",
              "softness"}
#: A normal whose length differs from 1 by more than this is normalised with a warning.
UNIT_TOL = 1e-6
#: Relative tolerance of the inertia symmetry test.
SYM_TOL = 1e-9
#: Largest scene accepted (bodies or contacts).
MAX_ITEMS = 10_000_000


@dataclass
class Scene:
    """A validated scene, as arrays (``nb`` bodies, ``nc`` contacts, ``d`` = dimension).

    ``inertia`` / ``inv_inertia`` are the **world** tensors, shape ``(nb, r, r)`` with
    ``r = 3`` in 3-D and ``r = 1`` in 2-D; for fixed (static or kinematic) bodies ``inv_mass``
    and ``inv_inertia`` are zero and ``mass``/``inertia`` are ``inf``/zero (unused).
    ``restitution_threshold`` and ``softness`` hold the per-contact values, NaN where a contact
    gives none (then ``threshold_default`` / ``softness_default``, the scene-level values, apply;
    None when the scene gives none either).
    """

    dimension: int
    body_names: list[str]
    static: np.ndarray            # (nb,) bool
    mass: np.ndarray              # (nb,)
    inv_mass: np.ndarray          # (nb,)
    inertia: np.ndarray           # (nb, r, r) world frame
    inv_inertia: np.ndarray       # (nb, r, r) world frame
    position: np.ndarray          # (nb, d)
    velocity: np.ndarray          # (nb, d)
    omega: np.ndarray             # (nb, r)
    contact_a: np.ndarray         # (nc,) int
    contact_b: np.ndarray         # (nc,) int
    point: np.ndarray             # (nc, d)
    normal: np.ndarray            # (nc, d) unit, from B to A
    restitution: np.ndarray       # (nc,)
    mu: np.ndarray                # (nc,) NaN where not given
    contact_names: list[str] = field(default_factory=list)
    name: str = ""
    description: str = ""
    warnings: list[str] = field(default_factory=list)
    kinematic: np.ndarray | None = None              # (nb,) bool; None: no kinematic body
    restitution_threshold: np.ndarray | None = None  # (nc,) NaN = scene-level value
    softness: np.ndarray | None = None               # (nc,) NaN = scene-level value
    threshold_default: float | None = None
    softness_default: float | None = None

    def __post_init__(self) -> None:
        nb, nc = len(self.body_names), int(self.contact_a.shape[0])
        if self.kinematic is None:
            self.kinematic = np.zeros(nb, dtype=bool)
        if self.restitution_threshold is None:
            self.restitution_threshold = np.full(nc, np.nan)
        if self.softness is None:
            self.softness = np.full(nc, np.nan)

    @property
    def fixed(self) -> np.ndarray:
        """(nb,) bool: static or kinematic (infinite mass, velocity prescribed)."""
        return self.static | self.kinematic

    @property
    def n_bodies(self) -> int:
        return len(self.body_names)

    @property
    def n_contacts(self) -> int:
        return int(self.contact_a.shape[0])

    @property
    def rot_dim(self) -> int:
        """Angular coordinates per body: 3 in 3-D, 1 in 2-D."""
        return 3 if self.dimension == 3 else 1

    @property
    def dof(self) -> int:
        """Velocity coordinates per body: 6 in 3-D, 3 in 2-D."""
        return self.dimension + self.rot_dim


# ---------------------------------------------------------------------- rotations
def quat_to_matrix(qs: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(k, 3, 3)`` from unit quaternions ``(k, 4)``, ``[w, x, y, z]``."""
    w, x, y, z = qs[:, 0], qs[:, 1], qs[:, 2], qs[:, 3]
    R = np.empty((qs.shape[0], 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - w * z)
    R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y)
    R[:, 2, 1] = 2 * (y * z + w * x)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


# ---------------------------------------------------------------------- loading
def load_scene(path: str | Path) -> Scene:
    """Read a scene from ``.json`` or ``.h5``/``.hdf5``; errors name the file."""
    source = str(path)
    p = Path(path)
    try:
        ext = p.suffix.lower()
        if ext == ".json":
            # the reading rules of every input (docs/files.md): a regular file, bounded JSON
            data = read_json_file(p, "a scene file", parse_constant=_reject_constant)
            return scene_from_dict(data, default_name=p.stem)
        if ext in (".h5", ".hdf5", ".hdf"):
            return read_scene_hdf5(p)
        raise ProblemError(f"unknown scene file type {ext or '(none)'} (expected .json, .h5)")
    except ProblemError as exc:
        raise exc.with_source(source) from None
    except PermissionError:
        raise ProblemError("permission denied", source) from None


def _reject_constant(name: str) -> float:
    raise ProblemError(f"{name} is not allowed in a scene (numbers must be finite)")


def scene_from_dict(data: Any, default_name: str = "") -> Scene:
    """Build and validate a scene from its decoded JSON object."""
    if not isinstance(data, dict):
        raise ProblemError("a scene is a JSON object with 'bodies' and 'contacts'")
    unknown = sorted(set(data) - SCENE_KEYS)
    if unknown:
        raise ProblemError(f"unknown scene key {unknown[0]!r} "
                           f"(known: {', '.join(sorted(SCENE_KEYS))})")
    dim = _dimension(data.get("dimension", 3))
    bodies = data.get("bodies")
    contacts = data.get("contacts")
    if not isinstance(bodies, list) or not bodies:
        raise ProblemError("'bodies' must be a non-empty list")
    if not isinstance(contacts, list):
        raise ProblemError("'contacts' must be a list")
    if len(bodies) > MAX_ITEMS or len(contacts) > MAX_ITEMS:
        raise ProblemError("scene too large")
    r = 3 if dim == 3 else 1
    nb = len(bodies)
    names: list[str] = []
    static = np.zeros(nb, dtype=bool)
    kinematic = np.zeros(nb, dtype=bool)
    mass = np.full(nb, np.nan)
    inertia = np.full((nb, r, r), np.nan)
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (nb, 1))
    pos = np.zeros((nb, dim))
    vel = np.zeros((nb, dim))
    omega = np.zeros((nb, r))
    for i, b in enumerate(bodies):
        where = f"body {i + 1}"
        _check_record(b, where, BODY_KEYS, ", ".join(sorted(BODY_KEYS)))
        name = b.get("name", f"body{i + 1}")
        if not isinstance(name, str) or not name:
            raise ProblemError(f"{where}: 'name' must be a non-empty string")
        where = f"body {name!r}"
        names.append(name)
        st = b.get("static", False)
        if not isinstance(st, bool):
            raise ProblemError(f"{where}: 'static' must be true or false")
        static[i] = st
        kin = b.get("kinematic", False)
        if not isinstance(kin, bool):
            raise ProblemError(f"{where}: 'kinematic' must be true or false")
        kinematic[i] = kin
        fixed = st or kin
        if "mass" in b and b["mass"] is not None:
            mass[i] = _scalar(b["mass"], where, "mass")
        elif not fixed:
            raise ProblemError(f"{where}: 'mass' is required for a moving body")
        if "inertia" in b and b["inertia"] is not None:
            inertia[i] = _inertia(b["inertia"], dim, where)
        elif not fixed:
            raise ProblemError(f"{where}: 'inertia' is required for a moving body")
        if "position" in b:
            pos[i] = _vec(b["position"], dim, where, "position")
        elif not fixed:
            raise ProblemError(f"{where}: 'position' is required for a moving body")
        if "velocity" in b:
            vel[i] = _vec(b["velocity"], dim, where, "velocity")
        if "angular_velocity" in b:
            omega[i] = _vec(b["angular_velocity"], r, where, "angular_velocity")
        if "orientation" in b:
            if dim == 3:
                quat[i] = _vec(b["orientation"], 4, where, "orientation")
            else:
                _scalar(b["orientation"], where, "orientation")  # an angle: inertia is scalar
    nc = len(contacts)
    ca = np.zeros(nc, dtype=np.int64)
    cb = np.zeros(nc, dtype=np.int64)
    point = np.zeros((nc, dim))
    normal = np.zeros((nc, dim))
    eps = np.zeros(nc)
    mu = np.full(nc, np.nan)
    threshold = np.full(nc, np.nan)
    soft = np.full(nc, np.nan)
    index = {}
    for i, nm in enumerate(names):
        if nm in index:
            raise ProblemError(f"two bodies are named {nm!r}")
        index[nm] = i
    cnames: list[str] = []
    for k, c in enumerate(contacts):
        where = f"contact {k + 1}"
        _check_record(c, where, CONTACT_KEYS, "a, b, point, normal, restitution, mu, name, "
                                              "restitution_threshold, softness")
        cnames.append(str(c.get("name", f"c{k + 1}")))
        for side, keys, arr in (("A", ("a", "body_a"), ca), ("B", ("b", "body_b"), cb)):
            given = [key for key in keys if key in c]
            if not given:
                raise ProblemError(f"{where}: body {side} missing (key '{keys[0]}')")
            ref = c[given[0]]
            if isinstance(ref, str):
                if ref not in index:
                    raise ProblemError(f"{where}: unknown body {ref!r}")
                arr[k] = index[ref]
            else:
                raise ProblemError(f"{where}: body {side} must be a body name, got {ref!r}")
        for key in ("point", "normal"):
            if key not in c:
                raise ProblemError(f"{where}: '{key}' is required")
        point[k] = _vec(c["point"], dim, where, "point")
        normal[k] = _vec(c["normal"], dim, where, "normal")
        if "restitution" in c:
            eps[k] = _scalar(c["restitution"], where, "restitution")
        if "mu" in c and c["mu"] is not None:
            mu[k] = _scalar(c["mu"], where, "mu")
        for key, arr in (("restitution_threshold", threshold), ("softness", soft)):
            if key in c and c[key] is not None:
                arr[k] = _scalar(c[key], where, key)
    defaults = {key: (_scalar(data[key], "scene", key) if data.get(key) is not None else None)
                for key in ("restitution_threshold", "softness")}
    return build_scene(dim, names, static, mass, inertia, quat, pos, vel, omega, ca, cb, point,
                       normal, eps, mu, contact_names=cnames,
                       name=str(data.get("name") or default_name),
                       description=str(data.get("description") or ""), kinematic=kinematic,
                       restitution_threshold=threshold, softness=soft,
                       threshold_default=defaults["restitution_threshold"],
                       softness_default=defaults["softness"])


def build_scene(dim: int, names: list[str], static: np.ndarray, mass: np.ndarray,
                inertia: np.ndarray, quat: np.ndarray | None, pos: np.ndarray, vel: np.ndarray,
                omega: np.ndarray, ca: np.ndarray, cb: np.ndarray, point: np.ndarray,
                normal: np.ndarray, eps: np.ndarray, mu: np.ndarray, *,
                contact_names: list[str] | None = None, name: str = "",
                description: str = "", kinematic: np.ndarray | None = None,
                restitution_threshold: np.ndarray | None = None,
                softness: np.ndarray | None = None, threshold_default: float | None = None,
                softness_default: float | None = None) -> Scene:
    """Validate array data and derive world inertias (shared by the JSON and HDF5 readers).

    ``inertia`` is ``(nb, r, r)`` in the body frame (NaN rows allowed for fixed bodies);
    ``quat`` is ``(nb, 4)`` ``[w, x, y, z]`` or None (identity; ignored in 2-D).
    ``kinematic`` (default none), ``restitution_threshold`` and ``softness`` (per contact, NaN =
    the scene-level ``*_default``) are optional.
    """
    dim = _dimension(dim)
    r = 3 if dim == 3 else 1
    nb, nc = len(names), int(np.asarray(ca).shape[0])
    warnings: list[str] = []
    static = np.asarray(static, dtype=bool).reshape(nb)
    kinematic = np.zeros(nb, dtype=bool) if kinematic is None \
        else np.asarray(kinematic, dtype=bool).reshape(nb)
    threshold = np.full(nc, np.nan) if restitution_threshold is None \
        else np.asarray(restitution_threshold, dtype=np.float64).reshape(nc)
    soft = np.full(nc, np.nan) if softness is None \
        else np.asarray(softness, dtype=np.float64).reshape(nc)
    mass = np.asarray(mass, dtype=np.float64).reshape(nb)
    inertia = np.asarray(inertia, dtype=np.float64).reshape(nb, r, r)
    pos = np.asarray(pos, dtype=np.float64).reshape(nb, dim)
    vel = np.asarray(vel, dtype=np.float64).reshape(nb, dim)
    omega = np.asarray(omega, dtype=np.float64).reshape(nb, r)
    ca = np.asarray(ca, dtype=np.int64).reshape(nc)
    cb = np.asarray(cb, dtype=np.int64).reshape(nc)
    point = np.asarray(point, dtype=np.float64).reshape(nc, dim)
    normal = np.asarray(normal, dtype=np.float64).reshape(nc, dim)
    eps = np.asarray(eps, dtype=np.float64).reshape(nc)
    mu = np.asarray(mu, dtype=np.float64).reshape(nc)

    def body(i: int) -> str:
        return f"body {names[int(i)]!r}"

    bad = np.flatnonzero(static & kinematic)
    if bad.size:
        raise ProblemError(f"{body(bad[0])}: a body is either static or kinematic, not both")
    moving = ~(static | kinematic)

    for arr, label in ((pos, "position"), (vel, "velocity"), (omega, "angular_velocity")):
        bad = np.flatnonzero(~np.all(np.isfinite(arr.reshape(nb, -1)), axis=1))
        if bad.size:
            raise ProblemError(f"{body(bad[0])}: {label} contains NaN or Inf")
    bad = np.flatnonzero(mass < 0)
    if bad.size:
        raise ProblemError(f"{body(bad[0])}: negative mass {mass[bad[0]]:g}")
    bad = np.flatnonzero(moving & ~(np.isfinite(mass) & (mass > 0)))
    if bad.size:
        raise ProblemError(f"{body(bad[0])}: a moving body needs a finite positive mass, got "
                           f"{mass[bad[0]]:g} (mark immovable bodies 'static': true, bodies "
                           f"with a prescribed velocity 'kinematic': true)")
    bad = np.flatnonzero(moving & ~np.all(np.isfinite(inertia.reshape(nb, -1)), axis=1))
    if bad.size:
        raise ProblemError(f"{body(bad[0])}: inertia contains NaN or Inf")
    # symmetry and positive definiteness (moving bodies)
    idx = np.flatnonzero(moving)
    Ib = inertia[idx]
    scale = np.max(np.abs(Ib.reshape(idx.size, -1)), axis=1) if idx.size else np.zeros(0)
    asym = np.max(np.abs(Ib - np.swapaxes(Ib, 1, 2)).reshape(idx.size, -1), axis=1) \
        if idx.size else np.zeros(0)
    bad = np.flatnonzero(asym > SYM_TOL * np.maximum(scale, 1e-300))
    if bad.size:
        raise ProblemError(f"{body(idx[bad[0]])}: inertia tensor is not symmetric")
    if idx.size:  # eigenvalues of each tensor divided by its largest entry (no overflow)
        unit_I = Ib / np.maximum(scale, np.finfo(np.float64).tiny)[:, None, None]
        ev = np.linalg.eigvalsh(0.5 * (unit_I + np.swapaxes(unit_I, 1, 2)))
        bad = np.flatnonzero(ev[:, 0] <= 1e-14 * np.maximum(ev[:, -1], 1e-300))
        if bad.size:
            raise ProblemError(f"{body(idx[bad[0]])}: inertia tensor is not positive definite "
                               f"(smallest eigenvalue {ev[bad[0], 0] * scale[bad[0]]:g})")
    # world inertia R I R^T
    inv_mass = np.zeros(nb)
    with np.errstate(divide="ignore", over="ignore"):
        inv_mass[moving] = 1.0 / mass[moving]
    bad = np.flatnonzero(~np.isfinite(inv_mass))
    if bad.size:
        raise ProblemError(f"{body(bad[0])}: mass {mass[bad[0]]:g} is too small for double "
                           f"precision (1/mass overflows)")
    mass = np.where(moving, mass, np.inf)
    I_world = np.zeros((nb, r, r))
    I_inv = np.zeros((nb, r, r))
    if idx.size:
        if dim == 3 and quat is not None:
            quat = np.asarray(quat, dtype=np.float64).reshape(nb, 4)
            qm = quat[idx]
            if not np.all(np.isfinite(qm)):
                bad = np.flatnonzero(~np.all(np.isfinite(qm), axis=1))
                raise ProblemError(f"{body(idx[bad[0]])}: orientation contains NaN or Inf")
            qu, qn = unit_rows(qm)
            bad = np.flatnonzero(qn < 1e-12)
            if bad.size:
                raise ProblemError(f"{body(idx[bad[0]])}: orientation quaternion is zero")
            off = np.flatnonzero(np.abs(qn - 1.0) > UNIT_TOL)
            if off.size:
                warnings.append(f"{body(idx[off[0]])}: orientation quaternion of length "
                                f"{qn[off[0]]:.6g} normalised"
                                + (f" (and {off.size - 1} more)" if off.size > 1 else ""))
            R = quat_to_matrix(qu)
            Iw = R @ Ib @ np.swapaxes(R, 1, 2)
            Iinv_body = np.linalg.inv(Ib)
            Iinv = R @ Iinv_body @ np.swapaxes(R, 1, 2)
        else:
            Iw = Ib
            Iinv = np.linalg.inv(Ib)
        bad = np.flatnonzero(~np.all(np.isfinite(Iinv.reshape(idx.size, -1)), axis=1))
        if bad.size:
            raise ProblemError(f"{body(idx[bad[0]])}: inertia too small for double precision "
                               f"(its inverse overflows)")
        # halves first: I + I^T overflows for entries near the largest double
        I_world[idx] = 0.5 * Iw + 0.5 * np.swapaxes(Iw, 1, 2)
        I_inv[idx] = 0.5 * Iinv + 0.5 * np.swapaxes(Iinv, 1, 2)
    # contacts
    for arr, label in ((point, "point"), (normal, "normal")):
        bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
        if bad.size:
            raise ProblemError(f"contact {bad[0] + 1}: {label} contains NaN or Inf")
    bad = np.flatnonzero((ca < 0) | (ca >= nb) | (cb < 0) | (cb >= nb))
    if bad.size:
        raise ProblemError(f"contact {bad[0] + 1}: body index out of range 0..{nb - 1}")
    bad = np.flatnonzero(ca == cb)
    if bad.size:
        raise ProblemError(f"contact {bad[0] + 1}: bodies A and B are the same body "
                           f"{names[int(ca[bad[0]])]!r}")
    fixed = static | kinematic
    bad = np.flatnonzero(fixed[ca] & fixed[cb])
    if bad.size:
        k = int(bad[0])
        raise ProblemError(f"contact {k + 1}: both bodies ({names[int(ca[k])]!r}, "
                           f"{names[int(cb[k])]!r}) are static or kinematic: no impulse can "
                           f"act")
    normal, norms = unit_rows(normal)
    bad = np.flatnonzero(norms == 0.0)
    if bad.size:
        raise ProblemError(f"contact {bad[0] + 1}: the normal is zero")
    bad = np.flatnonzero(norms < 1e-12)
    if bad.size:
        raise ProblemError(f"contact {bad[0] + 1}: the normal is zero (length "
                           f"{norms[bad[0]]:.3g} < 1e-12)")
    off = np.flatnonzero(np.abs(norms - 1.0) > UNIT_TOL)
    if off.size:
        warnings.append(f"contact {off[0] + 1}: normal of length {norms[off[0]]:.6g} normalised"
                        + (f" (and {off.size - 1} more contacts)" if off.size > 1 else ""))
    bad = np.flatnonzero(~(np.isfinite(eps) & (eps >= 0) & (eps <= 1)))
    if bad.size:
        raise ProblemError(f"contact {bad[0] + 1}: restitution {eps[bad[0]]:g} is outside [0, 1]")
    bad = np.flatnonzero(~np.isnan(mu) & ~(np.isfinite(mu) & (mu >= 0)))
    if bad.size:
        raise ProblemError(f"contact {bad[0] + 1}: friction coefficient mu = {mu[bad[0]]:g} "
                           f"must be finite and >= 0")
    for arr, label in ((threshold, "restitution_threshold"), (soft, "softness")):
        bad = np.flatnonzero(~np.isnan(arr) & ~(np.isfinite(arr) & (arr >= 0)))
        if bad.size:
            raise ProblemError(f"contact {bad[0] + 1}: {label} = {arr[bad[0]]:g} must be finite "
                               f"and >= 0")
    check_nonnegative(threshold_default, "scene: restitution_threshold")
    check_nonnegative(softness_default, "scene: softness")
    if contact_names is None or len(contact_names) != nc:
        contact_names = [f"c{k + 1}" for k in range(nc)]
    return Scene(dimension=dim, body_names=list(names), static=static, mass=mass,
                 inv_mass=inv_mass, inertia=I_world, inv_inertia=I_inv, position=pos,
                 velocity=vel, omega=omega, contact_a=ca, contact_b=cb, point=point,
                 normal=normal, restitution=eps, mu=mu, contact_names=list(contact_names),
                 name=name, description=description, warnings=warnings, kinematic=kinematic,
                 restitution_threshold=threshold, softness=soft,
                 threshold_default=threshold_default, softness_default=softness_default)


def check_nonnegative(x: float | None, label: str) -> None:
    """ProblemError unless ``x`` is None or a finite number >= 0."""
    if x is not None and not (math.isfinite(float(x)) and float(x) >= 0):
        raise ProblemError(f"{label} = {x:g} must be finite and >= 0")


def per_contact(values: np.ndarray, scene_value: float | None, default: float) -> np.ndarray:
    """A per-contact parameter: the contact's own value, else the scene's, else ``default``."""
    fallback = default if scene_value is None else float(scene_value)
    return np.where(np.isnan(values), fallback, values)


def check_coupling(scene: Scene, rows_per_contact: int = 1) -> None:
    """Refuse, before any assembly, a scene whose contact LCP would be too large to store.

    M couples every pair of contact rows that share a moving body, so
    ``rows_per_contact^2 * sum over moving bodies of (contacts on it)^2`` bounds its stored
    entries (a star of 200,000 contacts on one body: 4e10).  Above the sparse-matrix limit of
    problem files (:data:`lcpcli.core.problem.MAX_SPARSE_NNZ`) it is a ProblemError; O(nc).
    """

    nb = scene.n_bodies
    deg = np.bincount(scene.contact_a, minlength=nb) + np.bincount(scene.contact_b, minlength=nb)
    deg[scene.fixed] = 0
    bound = int(np.sum(deg.astype(np.int64) ** 2)) * rows_per_contact ** 2
    if bound > MAX_SPARSE_NNZ:
        hub = int(np.argmax(deg))
        raise ProblemError(f"the contact LCP would hold up to {bound:,} stored entries (limit "
                           f"{MAX_SPARSE_NNZ:,}): body {scene.body_names[hub]!r} touches "
                           f"{int(deg[hub]):,} contacts and M couples every pair of rows on a "
                           f"moving body")


def with_kinematic(scene: Scene, names: list[str]) -> Scene:
    """A copy of ``scene`` in which the bodies ``names`` are kinematic (prescribed velocity).

    Each keeps its position and velocity; its mass and inertia are no longer used.  A static body
    named here becomes kinematic (the same thing for the LCP: no unknowns).  ProblemError for an
    unknown name or when a contact would join two fixed bodies.
    """

    if not names:
        return scene
    index = {nm: i for i, nm in enumerate(scene.body_names)}
    kin = scene.kinematic.copy()
    static = scene.static.copy()
    for nm in names:
        if nm not in index:
            raise ProblemError(f"--kinematic: unknown body {nm!r}")
        kin[index[nm]] = True
        static[index[nm]] = False
    fixed = kin | static
    bad = np.flatnonzero(fixed[scene.contact_a] & fixed[scene.contact_b])
    if bad.size:
        k = int(bad[0])
        raise ProblemError(f"contact {k + 1}: both bodies "
                           f"({scene.body_names[int(scene.contact_a[k])]!r}, "
                           f"{scene.body_names[int(scene.contact_b[k])]!r}) are static or "
                           f"kinematic: no impulse can act")
    inv_mass = np.where(fixed, 0.0, scene.inv_mass)
    inv_inertia = np.where(fixed[:, None, None], 0.0, scene.inv_inertia)
    mass = np.where(fixed, np.inf, scene.mass)
    inertia = np.where(fixed[:, None, None], 0.0, scene.inertia)
    return dataclasses.replace(scene, kinematic=kin, static=static, inv_mass=inv_mass,
                               inv_inertia=inv_inertia, mass=mass, inertia=inertia,
                               warnings=list(scene.warnings))


# ---------------------------------------------------------------------- HDF5
def read_scene_hdf5(path: Path) -> Scene:
    """HDF5 scene: groups ``bodies`` and ``contacts`` of column datasets (see docs/contact.md).

    Read under the rules of the problem readers (:mod:`lcpcli.io.hdf5_format`, docs/files.md):
    no external or user-defined link is followed, no dataset keeps its data in another file
    (external storage, virtual datasets), numeric columns hold real numbers, and every
    dataset's shape and type are checked from its header against the body and contact counts
    before any data is read (a dataset declared huge costs nothing).
    """
    from lcpcli.io.hdf5_format import H5_ERRORS, damaged, open_file

    check_input_file(path, "a scene file")  # a regular file: a FIFO would hang h5py
    with open_file(path) as f:
        try:
            return _scene_from_hdf5(f, path)
        except ProblemError:
            raise
        except H5_ERRORS as exc:
            raise damaged(exc) from None


def _h5_group(f: Any, key: str) -> Any:
    import h5py

    from lcpcli.io.hdf5_format import child

    node = child(f, key, key)
    if node is None:
        raise ProblemError("an HDF5 scene needs groups 'bodies' and 'contacts'")
    if not isinstance(node, h5py.Group):
        raise ProblemError(f"'{key}' must be a group of datasets")
    return node


def _h5_head(g: Any, key: str, kinds: str | None = "iuf") -> Any:
    """The dataset ``key`` of group ``g`` (None if absent), checked without reading its data:
    stored in this file, of an accepted type (``kinds``; None: the caller checks)."""
    from lcpcli.io.hdf5_format import dataset

    return dataset(g, key, f"{g.name.strip('/')}/{key}", kinds)


def _h5_shape(d: Any, shapes: tuple[tuple[int, ...], ...]) -> None:
    """ProblemError unless the declared shape of ``d`` is one of ``shapes`` (before reading)."""
    if tuple(d.shape) not in shapes:
        raise ProblemError(f"dataset '{d.name.strip('/')}' has shape {tuple(d.shape)}, "
                           f"expected {shapes[0]}")


def _h5_count(d: Any, label: str) -> int:
    """The row count a 1-D dataset declares (bodies or contacts), within :data:`MAX_ITEMS`."""
    if len(d.shape) != 1:
        raise ProblemError(f"dataset '{label}' has shape {tuple(d.shape)}, expected one row "
                           f"per item")
    count = int(d.shape[0])
    if count > MAX_ITEMS:
        raise ProblemError(f"dataset '{label}' declares {count:,} rows (limit {MAX_ITEMS:,})")
    return count


def _h5_text_kind(d: Any) -> bool:
    import h5py

    return d.dtype.kind in "SU" or h5py.check_string_dtype(d.dtype) is not None


def _h5_text(d: Any, label: str) -> list[str]:
    """A 1-D string column (names) of at most MAX_ITEMS rows and MAX_TEXT_BYTES declared in all
    (fixed-length strings: rows x size; variable-length: rows x fill value), checked from the
    header before reading."""

    count = _h5_count(d, label)
    if not _h5_text_kind(d):
        raise ProblemError(f"dataset '{label}' must hold strings, not {d.dtype}")
    # fixed-length strings: the item size; variable-length ones may repeat a long fill value
    # in every row never written (a 100 KB file can declare 100 GB that way)
    fill = d.fillvalue if d.dtype.kind not in "SU" else None
    per_row = d.dtype.itemsize if d.dtype.kind in "SU" else \
        len(fill) if isinstance(fill, (bytes, str)) else 0
    if count * per_row > MAX_TEXT_BYTES:
        raise too_big(count * per_row, MAX_TEXT_BYTES, f"dataset '{label}'")
    raw = d[()] if count else np.zeros(0, dtype=object)
    return [x.decode("utf-8", errors="replace") if isinstance(x, bytes) else str(x)
            for x in np.ravel(raw)]


def _h5_flags(g: Any, key: str, nb: int) -> np.ndarray:
    """A per-body flag column (``static``, ``kinematic``): booleans, or integers 0/1."""
    d = _h5_head(g, key, "biu")
    if d is None:
        return np.zeros(nb, dtype=bool)
    _h5_shape(d, ((nb,),))
    raw = np.asarray(d[()]).reshape(-1)
    if raw.dtype.kind != "b" and np.any((raw != 0) & (raw != 1)):
        raise ProblemError(f"dataset 'bodies/{key}' must hold booleans (or 0/1)")
    return raw.astype(bool)


def _h5_real(g: Any, key: str, shapes: tuple[tuple[int, ...], ...], fill: float | None,
             missing_shape: tuple[int, ...]) -> np.ndarray:
    """A real column: header checked (type, then shape among ``shapes``), then read as
    float64; absent: ``fill`` of ``missing_shape`` (``fill`` None: the column is required)."""
    from lcpcli.io.hdf5_format import read_float

    d = _h5_head(g, key)
    if d is None:
        if fill is None:
            raise ProblemError(f"dataset '{g.name.strip('/')}/{key}' is missing")
        return np.full(missing_shape, fill)
    _h5_shape(d, shapes)
    return read_float(d)


def _scene_from_hdf5(f: Any, path: Path) -> Scene:
    from lcpcli.io.hdf5_format import attr_int, attr_text

    dim = _dimension(attr_int(f, "dimension") if "dimension" in f.attrs else 3)
    r = 3 if dim == 3 else 1
    gb, gc = _h5_group(f, "bodies"), _h5_group(f, "contacts")
    # the counts from the headers first: every other dataset is checked against them
    name_d = _h5_head(gb, "name", None)
    if name_d is not None:
        names = _h5_text(name_d, "bodies/name")
    else:
        mass_d = _h5_head(gb, "mass")
        n_guess = _h5_count(mass_d, "bodies/mass") if mass_d is not None else 0
        names = [f"body{i + 1}" for i in range(n_guess)]
    nb = len(names)
    if nb == 0:
        raise ProblemError("the scene has no bodies")
    if len(set(names)) != nb:
        raise ProblemError("two bodies have the same name")
    a_d, b_d = (_h5_head(gc, key, None) for key in ("a", "b"))
    for key, d in (("a", a_d), ("b", b_d)):
        if d is None:
            raise ProblemError(f"dataset 'contacts/{key}' is missing")
    nc = _h5_count(a_d, "contacts/a")
    _h5_shape(b_d, ((nc,),))
    static = _h5_flags(gb, "static", nb)
    kinematic = _h5_flags(gb, "kinematic", nb)
    mass = _h5_real(gb, "mass", ((nb,),), np.nan, (nb,))
    if dim == 2:
        inertia = _h5_real(gb, "inertia", ((nb,), (nb, 1), (nb, 1, 1)), np.nan, (nb,))
    else:
        inertia = _h5_real(gb, "inertia", ((nb, 3), (nb, 3, 3)), np.nan, (nb,))
    inertia = _inertia_array(inertia, nb, dim)
    quat = None  # identity; 2-D scenes have no orientation
    if dim == 3 and _h5_head(gb, "orientation") is not None:
        quat = _h5_real(gb, "orientation", ((nb, 4),), None, (nb, 4))
    pos = _h5_real(gb, "position", ((nb, dim),), 0.0, (nb, dim))
    vel = _h5_real(gb, "velocity", ((nb, dim),), 0.0, (nb, dim))
    omega = _h5_real(gb, "angular_velocity", ((nb, r), (nb,)) if r == 1 else ((nb, r),), 0.0,
                     (nb, r))
    ca = _body_refs(a_d, "a", names)
    cb = _body_refs(b_d, "b", names)
    point = _h5_real(gc, "point", ((nc, dim),), None, (nc, dim))
    normal = _h5_real(gc, "normal", ((nc, dim),), None, (nc, dim))
    eps = _h5_real(gc, "restitution", ((nc,),), 0.0, (nc,))
    mu = _h5_real(gc, "mu", ((nc,),), np.nan, (nc,))
    threshold = _h5_real(gc, "restitution_threshold", ((nc,),), np.nan, (nc,))
    soft = _h5_real(gc, "softness", ((nc,),), np.nan, (nc,))
    dynamic = ~(static | kinematic)
    bad = np.flatnonzero(dynamic & np.isnan(mass))
    if bad.size:
        raise ProblemError(f"body {names[bad[0]]!r}: 'mass' is required for a moving body")
    bad = np.flatnonzero(dynamic & np.isnan(inertia).all(axis=(1, 2)))
    if bad.size:
        raise ProblemError(f"body {names[bad[0]]!r}: 'inertia' is required for a moving "
                           f"body")
    if quat is not None:
        quat = np.where(np.isnan(quat), np.array([1.0, 0, 0, 0]), quat)
    defaults = {}
    for key in ("restitution_threshold", "softness"):
        value = _attr(f.attrs.get(key)) if key in f.attrs else None
        if value is not None and (isinstance(value, (bool, str))
                                  or not isinstance(value, (int, float))):
            raise ProblemError(f"root attribute '{key}' must be a number")
        defaults[key] = None if value is None else float(value)
    return build_scene(dim, names, static, mass, inertia, quat, pos, vel,
                       omega.reshape(nb, r), ca, cb, point, normal, eps, mu,
                       name=attr_text(f, "name", MAX_NAME_BYTES) or path.stem,
                       description=attr_text(f, "description", MAX_NAME_BYTES),
                       kinematic=kinematic, restitution_threshold=threshold, softness=soft,
                       threshold_default=defaults["restitution_threshold"],
                       softness_default=defaults["softness"])


def _attr(x: Any) -> Any:
    if isinstance(x, bytes):
        return x.decode()
    if isinstance(x, np.generic):
        return x.item()
    return x


def _inertia_array(arr: np.ndarray, nb: int, dim: int) -> np.ndarray:
    if dim == 2:
        if arr.shape not in ((nb,), (nb, 1), (nb, 1, 1)):
            raise ProblemError(f"dataset 'bodies/inertia' has shape {arr.shape}, expected ({nb},)")
        return arr.reshape(nb, 1, 1)
    if arr.shape == (nb,) and np.isnan(arr).all():
        return np.full((nb, 3, 3), np.nan)
    if arr.shape == (nb, 3):
        out = np.zeros((nb, 3, 3))
        out[:, [0, 1, 2], [0, 1, 2]] = arr
        out[np.isnan(arr).any(axis=1)] = np.nan
        return out
    if arr.shape == (nb, 3, 3):
        return arr
    raise ProblemError(f"dataset 'bodies/inertia' has shape {arr.shape}, expected ({nb}, 3) "
                       f"or ({nb}, 3, 3)")


def _body_refs(d: Any, key: str, names: list[str]) -> np.ndarray:
    """Contact ends from a checked dataset header: body names or 0-based body indices."""
    if _h5_text_kind(d):
        index = {nm: i for i, nm in enumerate(names)}
        refs = _h5_text(d, f"contacts/{key}")
        out = np.empty(len(refs), dtype=np.int64)
        for k, s in enumerate(refs):
            if s not in index:
                raise ProblemError(f"contact {k + 1}: unknown body {s[:80]!r}")
            out[k] = index[s]
        return out
    if d.dtype.kind not in "iu":
        raise ProblemError(f"dataset 'contacts/{key}' must hold body names or 0-based indices")
    raw = np.ravel(d[()])
    bad = np.flatnonzero((raw < 0) | (raw >= len(names)))
    if bad.size:
        raise ProblemError(f"contact {bad[0] + 1}: body index {raw[bad[0]]} out of range "
                           f"0..{len(names) - 1}")
    return raw.astype(np.int64)


def write_scene_hdf5(scene: Scene, path: str | Path) -> None:
    """Write ``scene`` as an HDF5 scene (world inertias, identity orientations), atomically."""
    import h5py


    nb = scene.n_bodies
    with atomic_path(Path(path)) as tmp, open_hdf5(tmp, "w") as f:
        f.attrs["dimension"] = scene.dimension
        if scene.name:
            f.attrs["name"] = scene.name
        for key, value in (("restitution_threshold", scene.threshold_default),
                           ("softness", scene.softness_default)):
            if value is not None:
                f.attrs[key] = float(value)
        gb = f.create_group("bodies")
        gb.create_dataset("name", data=np.array(scene.body_names, dtype=object),
                          dtype=h5py.string_dtype())
        gb.create_dataset("static", data=scene.static)
        if scene.kinematic.any():
            gb.create_dataset("kinematic", data=scene.kinematic)
        gb.create_dataset("mass", data=np.where(scene.fixed, np.nan, scene.mass))
        inertia = scene.inertia.copy()
        inertia[scene.fixed] = np.nan
        gb.create_dataset("inertia",
                          data=inertia.reshape(nb) if scene.dimension == 2 else inertia)
        gb.create_dataset("position", data=scene.position)
        gb.create_dataset("velocity", data=scene.velocity)
        gb.create_dataset("angular_velocity",
                          data=scene.omega.reshape(nb) if scene.dimension == 2 else scene.omega)
        gc = f.create_group("contacts")
        gc.create_dataset("a", data=scene.contact_a)
        gc.create_dataset("b", data=scene.contact_b)
        gc.create_dataset("point", data=scene.point)
        gc.create_dataset("normal", data=scene.normal)
        gc.create_dataset("restitution", data=scene.restitution)
        gc.create_dataset("mu", data=scene.mu)
        for key, arr in (("restitution_threshold", scene.restitution_threshold),
                         ("softness", scene.softness)):
            if not np.isnan(arr).all():
                gc.create_dataset(key, data=arr)


# ---------------------------------------------------------------------- JSON helpers
def _dimension(x: Any) -> int:
    if isinstance(x, bool) or x not in (2, 3):
        raise ProblemError(f"'dimension' must be 2 or 3, got {x!r}")
    return int(x)


def _scalar(x: Any, where: str, label: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ProblemError(f"{where}: '{label}' must be a number, got {repr(x)[:40]}")
    try:
        v = float(x)
    except OverflowError:  # an integer beyond float64 (the data rule: a real number)
        raise ProblemError(f"{where}: '{label}' is an integer too large for a float") from None
    if not math.isfinite(v):
        raise ProblemError(f"{where}: '{label}' is NaN or Inf")
    return v


def _vec(x: Any, n: int, where: str, label: str) -> np.ndarray:
    if n == 1 and isinstance(x, (int, float)) and not isinstance(x, bool):
        x = [x]
    if not isinstance(x, list) or len(x) != n:
        raise ProblemError(f"{where}: '{label}' must be a list of {n} numbers")
    return np.array([_scalar(v, where, label) for v in x])


def _inertia(x: Any, dim: int, where: str) -> np.ndarray:
    if dim == 2:
        v = _scalar(x[0] if isinstance(x, list) and len(x) == 1 else x, where, "inertia")
        return np.array([[v]])
    if isinstance(x, list) and len(x) == 3 and all(not isinstance(v, list) for v in x):
        return np.diag(_vec(x, 3, where, "inertia"))
    if isinstance(x, list) and len(x) == 3 and all(isinstance(v, list) for v in x):
        return np.array([_vec(row, 3, where, "inertia") for row in x])
    raise ProblemError(f"{where}: 'inertia' must be 3 numbers (diagonal) or a 3x3 matrix")


def _check_record(item: Any, where: str, keys: set[str] | frozenset[str], known: str) -> None:
    """ProblemError unless ``item`` is an object whose keys are all in ``keys``."""
    if not isinstance(item, dict):
        raise ProblemError(f"{where}: expected an object")
    bad = sorted(set(item) - keys)
    if bad:
        raise ProblemError(f"{where}: unknown key {bad[0]!r} (known: {known})")
