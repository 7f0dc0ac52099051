"""The contact LCP of a scene as a :class:`~lcpcli.core.problem.Problem`; its solution mapped back.

``build(scene, friction=K)`` returns a :class:`ContactLCP` (the problem with contact metadata in
``Problem.meta["contact"]``); ``solve(clcp, method)`` solves it with :func:`lcpcli.solve` (which
certifies the answer) and returns an :class:`Impact`: impulses, post-impact velocities, normal
velocities and kinetic energies.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lcpcli.contact.assembly import Assembly, assemble, choose_storage
from lcpcli.contact.friction import check_directions, friction_blocks
from lcpcli.contact.impact import (
    energy_increased,
    kinetic_energy,
    normal_velocities,
    post_velocities,
)
from lcpcli.contact.scene import Scene
from lcpcli.core.problem import Problem, is_sparse

#: Default method for contact LCPs: Lemke handles the symmetric PSD (often singular) M and
#: the non-symmetric frictional matrix.
DEFAULT_METHOD = "lemke"
CONVENTION = ("w = M z + q, 0 <= z _|_ w >= 0; z = impulses; normals point from B to A; "
              "q_n = (1 + eps) v_rel^- (approaching: q < 0); w_n = v_rel^+ + eps v_rel^-")


@dataclass
class ContactLCP:
    """A scene's contact LCP: the problem, its assembly and the layout of the unknowns."""

    scene: Scene
    assembly: Assembly
    problem: Problem
    friction: int                  # tangent directions per friction contact (0: frictionless)
    friction_contacts: np.ndarray  # (nf,) contacts with friction unknowns
    tangent_dirs: np.ndarray       # (nf, K, d)
    HA: Any                        # csr (n_impulses, dof * nm): A W for all impulse rows
    unknowns: list[str]            # names of the LCP unknowns, in order
    notes: list[str] = field(default_factory=list)  # what the user should know (stderr)

    @property
    def n_impulses(self) -> int:
        """Unknowns that are impulses (normal + tangential; slacks excluded)."""
        return self.scene.n_contacts + self.friction_contacts.size * self.friction


@dataclass
class Impact:
    """A solved contact LCP mapped back onto the scene."""

    result: Any                    # lcpcli.core.result.Result
    normal_impulses: np.ndarray    # (nc,)
    tangent_impulses: np.ndarray   # (nf, K)
    slacks: np.ndarray             # (nf,)
    velocity: np.ndarray           # (nb, d) after impact
    omega: np.ndarray              # (nb, r) after impact
    normal_velocity: np.ndarray    # (nc,) after impact
    energy_before: float
    energy_after: float

    @property
    def energy_increase(self) -> bool:
        return energy_increased(self.energy_before, self.energy_after)


def build(scene: Scene, friction: int = 0, storage: str = "auto") -> ContactLCP:
    """The contact LCP of ``scene`` (``friction`` = K tangent directions, 0 = frictionless)."""
    import scipy.sparse as sp

    k = check_directions(int(friction), scene.dimension)
    choose_storage(storage, 0, 0)  # validate the name early
    asm = assemble(scene, storage)
    names = [f"n[{c}]" for c in scene.contact_names]
    if k:
        fb = friction_blocks(asm, k)
        fc, dirs, kk = fb["fc"], fb["dirs"], fb["K"]
        n_rows = fb["matrix"].shape[0]
        kind = choose_storage(storage, n_rows, int(fb["matrix"].nnz))
        M = fb["matrix"].toarray() if kind == "dense" else fb["matrix"]
        q = fb["q"]
        HA = sp.vstack([asm.H, fb["HD"]]).tocsr()
        for f in fc:
            names += [f"t{i + 1}[{scene.contact_names[f]}]" for i in range(kk)]
        names += [f"lambda[{scene.contact_names[f]}]" for f in fc]
    else:
        fc, dirs, kk = np.zeros(0, dtype=np.int64), np.zeros((0, 0, scene.dimension)), 0
        M, q, HA = asm.M, asm.q, asm.H
    notes = []
    if scene.dimension == 2 and int(friction) not in (0, 2):
        notes.append(f"--friction {friction} in a 2-D scene: the tangent line has two "
                     f"directions (+t, -t), so K = 2 is used")
    if k and fc.size == 0:
        notes.append(f"--friction {k}: no contact has a friction coefficient mu > 0, so the LCP "
                     f"is frictionless")
    if scene.n_contacts == 0:
        notes.append("the scene has no contacts: the LCP is empty and no velocity changes")
    meta = {"contact": contact_meta(scene, asm, kk, fc, names)}
    problem = Problem.create(M, q, name=scene.name or "contact",
                             description=f"contact LCP of scene {scene.name!r}: "
                                         f"{scene.n_contacts} contacts, "
                                         f"{asm.modelled.size} moving bodies"
                                         + (f", friction K={kk}" if kk else ", frictionless"),
                             meta=meta)
    return ContactLCP(scene=scene, assembly=asm, problem=problem, friction=kk,
                      friction_contacts=fc, tangent_dirs=dirs, HA=HA, unknowns=names,
                      notes=notes)


def contact_meta(scene: Scene, asm: Assembly, k: int, fc: np.ndarray,
                 names: list[str]) -> dict[str, Any]:
    """What a saved LCP carries so that a solution can be mapped back onto the scene."""
    names_b = scene.body_names
    return {
        "version": 1,
        "scene": scene.name,
        "dimension": scene.dimension,
        "convention": CONVENTION,
        "ordering": ("[normal impulses (one per contact) | tangent impulses (K per friction "
                     "contact, contact-major) | slacks lambda (one per friction contact)]")
        if k else "normal impulses, one per contact, in contact order",
        "friction_directions": k,
        "friction_contacts": [int(f) for f in fc],
        "unknowns": names,
        "contacts": [{"name": nm, "a": names_b[a], "b": names_b[b], "restitution": e,
                      "mu": None if m != m else m}
                     for nm, a, b, e, m in zip(scene.contact_names, scene.contact_a.tolist(),
                                               scene.contact_b.tolist(),
                                               scene.restitution.tolist(), scene.mu.tolist(),
                                               strict=True)],
        "bodies": [{"name": nm, "static": st, "column_block": col if col >= 0 else None}
                   for nm, st, col in zip(names_b, scene.static.tolist(),
                                          asm.columns.tolist(), strict=True)],
    }


def solve(clcp: ContactLCP, method: str = DEFAULT_METHOD, tol: float | None = None,
          **options: Any) -> Impact:
    """Solve the contact LCP with :func:`lcpcli.solve` and map the impulses back."""
    from lcpcli.api import solve as solve_problem

    check_method(clcp, method)
    result = solve_problem(clcp.problem, method, tol=tol, **options)
    return impact_from(clcp, result.z, result)


def check_method(clcp: ContactLCP, method: str) -> None:
    """OptionError for an unknown method, or a densifying method on a huge sparse LCP."""
    from lcpcli.api import check_dense_ok
    from lcpcli.solvers.registry import get_method

    check_dense_ok(clcp.problem, get_method(method))


def impact_from(clcp: ContactLCP, z: np.ndarray, result: Any = None) -> Impact:
    """Post-impact state for the LCP unknowns ``z`` (see :mod:`lcpcli.contact.impact`)."""
    scene = clcp.scene
    nc, nf, k = scene.n_contacts, clcp.friction_contacts.size, clcp.friction
    z = np.asarray(z, dtype=np.float64)
    x = z[: clcp.n_impulses]
    v, w = post_velocities(scene, clcp.assembly.modelled, clcp.HA, x)
    return Impact(result=result, normal_impulses=z[:nc].copy(),
                  tangent_impulses=z[nc: nc + nf * k].reshape(nf, k).copy(),
                  slacks=z[nc + nf * k:].copy(), velocity=v, omega=w,
                  normal_velocity=normal_velocities(scene, v, w),
                  energy_before=kinetic_energy(scene, scene.velocity, scene.omega),
                  energy_after=kinetic_energy(scene, v, w))


# ---------------------------------------------------------------------- JSON
def matrix_json(M: Any) -> Any:
    """Dense M as a list of rows; sparse M as the project's CSR object."""
    if is_sparse(M):
        from lcpcli.io.sparse import sparse_parts

        parts = sparse_parts(M)
        return {k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in parts.items()}
    return np.asarray(M).tolist()


def to_json(clcp: ContactLCP, impact: Impact | None = None) -> dict[str, Any]:
    """The ``contact-matrix --json`` object (keys listed in docs/contact.md)."""
    scene, asm = clcp.scene, clcp.assembly
    nc = scene.n_contacts
    bodies = []
    for i, nm in enumerate(scene.body_names):
        bodies.append({"name": nm, "static": bool(scene.static[i]),
                       "modelled": bool(asm.columns[i] >= 0), "reason": asm.reasons[i],
                       "mass": None if scene.static[i] else float(scene.mass[i]),
                       "velocity": scene.velocity[i].tolist(),
                       "angular_velocity": _ang(scene, scene.omega[i])})
    contacts = []
    fpos = {int(f): i for i, f in enumerate(clcp.friction_contacts)}
    for c in range(nc):
        entry = {"name": scene.contact_names[c],
                 "a": scene.body_names[int(scene.contact_a[c])],
                 "b": scene.body_names[int(scene.contact_b[c])],
                 "point": scene.point[c].tolist(), "normal": scene.normal[c].tolist(),
                 "restitution": float(scene.restitution[c]),
                 "mu": None if np.isnan(scene.mu[c]) else float(scene.mu[c]),
                 "normal_velocity_before": float(asm.v_rel[c]),
                 "inverse_effective_mass": float(asm.inv_eff_mass[c]),
                 "effective_mass": _finite(asm.eff_mass[c]),
                 "unknown": c}
        if c in fpos:
            entry["tangent_directions"] = clcp.tangent_dirs[fpos[c]].tolist()
        contacts.append(entry)
    out: dict[str, Any] = {
        "scene": scene.name, "dimension": scene.dimension,
        "M": matrix_json(clcp.problem.M), "q": clcp.problem.q.tolist(),
        "unknowns": clcp.unknowns, "storage": "sparse" if clcp.problem.sparse else "dense",
        "friction_directions": clcp.friction,
        "bodies": bodies, "contacts": contacts, "warnings": list(scene.warnings) + list(clcp.notes),
    }
    if impact is not None:
        res = impact.result
        out.update({
            "impulses": [float(x) for x in res.z] if res is not None
            else impact.normal_impulses.tolist(),
            "velocities": [{"name": nm, "linear": impact.velocity[i].tolist(),
                            "angular": _ang(scene, impact.omega[i])}
                           for i, nm in enumerate(scene.body_names)],
            "normal_velocities": impact.normal_velocity.tolist(),
            "energy_before": impact.energy_before,
            "energy_after": impact.energy_after,
            "energy_increase": impact.energy_increase,
            "status": res.status if res is not None else None,
        })
        if res is not None:
            out.update({"method": res.method, "message": res.message,
                        "residual": _finite(res.certificate.residual),
                        "error": _finite(res.certificate.error)})
    return out


def _ang(scene: Scene, w: np.ndarray) -> Any:
    return float(w[0]) if scene.dimension == 2 else w.tolist()


def _finite(x: float) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None
