"""The frictionless contact LCP of a scene: ``w = M j + q``, ``0 <= j _|_ w >= 0``.

* ``J`` (one row per contact) holds ``[n^T, (r_a x n)^T]`` on body A's columns and
  ``[-n^T, -(r_b x n)^T]`` on body B's (2-D: ``r x n`` is the scalar ``r_x n_y - r_y n_x``);
  only dynamic bodies (neither static nor kinematic) that touch a contact get columns
  (``dof`` = 6 in 3-D, 3 in 2-D).
* ``W`` is block-diagonal: ``diag(1/m, 1/m, 1/m, I_world^-1)`` per modelled body.
* ``M = J W J^T``; entry ``(i, j)`` is non-zero only when contacts i and j share a moving body
  (the textbook multi-contact ``M_ij`` written out).  It is never formed through a dense
  ``6n x 6n`` ``W``:
  the sparse path multiplies sparse ``J`` by sparse ``H = J W`` (only pairs of rows sharing a
  body are touched); the dense path adds ``G_k W_k G_k^T`` body by body.
* ``v_rel^- = n . (pdot_a - pdot_b)`` is the normal relative velocity before impact
  (``pdot = v + omega x r``; negative = approaching).  Each contact is in one **state**:

  - ``impact``: approaching faster than its restitution threshold (``v_rel^- < -threshold``):
    Newton restitution, ``e = eps``;
  - ``resting``: approaching at most that fast (``-threshold <= v_rel^- <= 0``): no bounce,
    ``e = 0``;
  - ``separating`` (``v_rel^- > 0``): no bounce, ``e = 0``.

  ``q = (1 + e) v_rel^-`` and ``w = v_rel^+ + e v_rel^-``, so ``w >= 0`` means
  ``v_rel^+ >= -eps v_rel^- > 0`` for an impact and ``v_rel^+ >= 0`` (non-penetration) for the
  others: no contact ends approaching.  (Applying ``(1 + eps) v_rel^-`` to a separating contact,
  as the textbook formula read literally does, lets it end with ``v_rel^+ = -eps v_rel^- < 0``.)
* Effective mass of contact i: ``1 / (n^T K n)`` with the textbook
  ``K = (1/m_a + 1/m_b) E - (r_a* I_a^-1 r_a* + r_b* I_b^-1 r_b*)`` (static bodies drop out);
  ``n^T K n`` equals ``M_ii``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.contact.scene import Scene, per_contact
from lcpcli.core.errors import OptionError
from lcpcli.core.limits import check_dense_work, within_dense_budget

#: Default restitution threshold (a speed): restitution applies to every approaching contact
#: (``v_rel^- < 0``) and to no other.  Scenes carry no units, so no engine's m/s value (Box2D
#: 1 m/s, Bullet 0.2 m/s, set to damp resting-contact jitter in time stepping) is assumed.
DEFAULT_RESTITUTION_THRESHOLD = 0.0
#: Contact states (``Assembly.state`` holds the index into this tuple).
STATES = ("impact", "resting", "separating")
IMPACT, RESTING, SEPARATING = 0, 1, 2
#: Up to this many LCP rows the matrix is kept dense ("auto" storage).
DENSE_MAX_ROWS = 400
#: Above DENSE_MAX_ROWS, dense is still used when the fill ratio exceeds this.
DENSE_MIN_FILL = 0.25
STORAGES = ("auto", "dense", "sparse")


@dataclass
class Assembly:
    """The pieces of the frictionless contact LCP (see the module docstring)."""

    scene: Scene
    columns: np.ndarray        # (nb,) column block of each body, -1 if it has none
    modelled: np.ndarray       # (nm,) indices of bodies with columns, in column order
    reasons: list[str]         # per body: why it is (not) modelled
    J: Any                     # csr (nc, dof * nm)
    H: Any                     # csr (nc, dof * nm): J W
    M: Any                     # dense (nc, nc) or csr
    q: np.ndarray              # (nc,)
    v_rel: np.ndarray          # (nc,) normal relative velocity before impact
    inv_eff_mass: np.ndarray   # (nc,) n^T K n
    storage: str               # "dense" or "sparse"
    threshold: np.ndarray      # (nc,) restitution threshold used
    state: np.ndarray          # (nc,) index into STATES
    restitution_used: np.ndarray  # (nc,) e: eps for impacts, 0 otherwise

    @property
    def eff_mass(self) -> np.ndarray:
        """Effective mass ``1 / (n^T K n)`` per contact."""
        with np.errstate(divide="ignore"):
            return 1.0 / self.inv_eff_mass


def body_columns(scene: Scene) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Column block per body (-1: none), modelled body indices, and the reason for each body."""
    nb = scene.n_bodies
    touched = np.zeros(nb, dtype=bool)
    touched[scene.contact_a] = True
    touched[scene.contact_b] = True
    modelled = np.flatnonzero(touched & ~scene.fixed)
    columns = np.full(nb, -1, dtype=np.int64)
    columns[modelled] = np.arange(modelled.size)
    reasons = []
    for i in range(nb):
        if scene.static[i]:
            reasons.append("static: no unknowns (infinite mass)"
                           if touched[i] else "static, in no contact")
        elif scene.kinematic[i]:
            reasons.append("kinematic: prescribed velocity, no unknowns (infinite mass)"
                           if touched[i] else "kinematic, in no contact")
        elif touched[i]:
            reasons.append("moving, in contact: modelled")
        else:
            reasons.append("in no contact: velocity unchanged, not modelled")
    return columns, modelled, reasons


def cross(r: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Row-wise ``r x d``: ``(m, 3)``; in 2-D the scalar ``r_x d_y - r_y d_x`` as ``(m, 1)``."""
    if r.shape[1] == 3:
        return np.cross(r, d)
    return (r[:, 0] * d[:, 1] - r[:, 1] * d[:, 0])[:, None]


def point_velocity(scene: Scene, bodies: np.ndarray, points: np.ndarray,
                   velocity: np.ndarray | None = None,
                   omega: np.ndarray | None = None) -> np.ndarray:
    """Velocity ``v + omega x r`` of the material point at ``points`` of each body."""
    v = scene.velocity if velocity is None else velocity
    w = scene.omega if omega is None else omega
    r = points - scene.position[bodies]
    if scene.dimension == 3:
        return v[bodies] + np.cross(w[bodies], r)
    om = w[bodies][:, 0]
    return v[bodies] + np.stack([-om * r[:, 1], om * r[:, 0]], axis=1)


#: Relative velocities at or below this fraction of the scene's largest point speed are 0
#: (:func:`relative_velocity`).  Two bodies resting on each other after a solved step carry
#: velocities whose difference at their contacts is the rounding left by that step's solve
#: (box stacks: 1e-16 to 7e-14 times the scene's speeds, where the smallest real relative
#: velocity was 1.4e-7 times them); 2^-40 = 9.1e-13 lies between, far below any speed a
#: velocity-level model can tell from rest.
VELOCITY_NOISE = 2.0 ** -40


def relative_velocity(scene: Scene, contacts: np.ndarray, dirs: np.ndarray,
                      velocity: np.ndarray | None = None,
                      omega: np.ndarray | None = None) -> np.ndarray:
    """``d . (pdot_a - pdot_b)`` at each listed contact (static bodies' velocities included).

    A value at or below :data:`VELOCITY_NOISE` times the scene's largest point speed (over
    every contact's two bodies, ``|v| + |omega| |r|``) is 0: rounding noise.  Such values were
    the LCP's ``q`` in rows whose every term was noise, which no certificate passes (each row's
    error is relative to its own terms: ``q_i = -5e-16`` asks for impulses of that size in
    exact proportions), while ``q_i = 0`` is answered exactly (docs/contact.md)."""
    a, b = scene.contact_a[contacts], scene.contact_b[contacts]
    p = scene.point[contacts]
    va = point_velocity(scene, a, p, velocity, omega)
    vb = point_velocity(scene, b, p, velocity, omega)
    value = np.einsum("ij,ij->i", dirs, va - vb)
    with np.errstate(over="ignore", invalid="ignore"):
        floor = VELOCITY_NOISE * point_speed_scale(scene, velocity, omega)
    if not np.isfinite(floor):  # speeds past the largest double: refused by the caller
        return value
    return np.where(np.abs(value) <= floor, 0.0, value)


def point_speed_scale(scene: Scene, velocity: np.ndarray | None = None,
                      omega: np.ndarray | None = None) -> float:
    """The largest ``|v| + |omega| |r|`` (norms) over both bodies of every contact (0 for none;
    Inf or NaN beyond the largest double)."""
    if scene.n_contacts == 0:
        return 0.0
    v = scene.velocity if velocity is None else velocity
    w = scene.omega if omega is None else omega
    bodies = np.concatenate([scene.contact_a, scene.contact_b])
    r = np.linalg.norm(np.concatenate([scene.point, scene.point]) - scene.position[bodies],
                       axis=1)
    return float(np.max(np.linalg.norm(v[bodies], axis=1)
                        + np.linalg.norm(w[bodies], axis=1) * r))  # NaN propagates


def _side_blocks(scene: Scene, bodies: np.ndarray, points: np.ndarray, dirs: np.ndarray,
                 sign: float) -> tuple[np.ndarray, np.ndarray]:
    """Jacobian block ``g`` and ``h = W g`` of one side, shape ``(m, dof)`` each."""
    r = points - scene.position[bodies]
    lin = sign * dirs
    ang = sign * cross(r, dirs)
    g = np.concatenate([lin, ang], axis=1)
    h = np.concatenate([lin * scene.inv_mass[bodies][:, None],
                        np.einsum("ijk,ik->ij", scene.inv_inertia[bodies], ang)], axis=1)
    return g, h


def direction_rows(scene: Scene, columns: np.ndarray, n_modelled: int, contacts: np.ndarray,
                   dirs: np.ndarray) -> tuple[Any, Any]:
    """Sparse ``J`` and ``H = J W`` rows for direction ``dirs[i]`` at contact ``contacts[i]``.

    Row i: ``[d^T, (r_a x d)^T]`` on A's columns, ``[-d^T, -(r_b x d)^T]`` on B's (moving
    bodies only).
    """
    import scipy.sparse as sp

    dof = scene.dof
    m = contacts.shape[0]
    rows, cols, gdat, hdat = [], [], [], []
    p = scene.point[contacts]
    for side, sign in ((scene.contact_a, 1.0), (scene.contact_b, -1.0)):
        bodies = side[contacts]
        keep = np.flatnonzero(columns[bodies] >= 0)
        if keep.size == 0:
            continue
        g, h = _side_blocks(scene, bodies[keep], p[keep], dirs[keep], sign)
        rows.append(np.repeat(keep, dof))
        cols.append((columns[bodies[keep]][:, None] * dof + np.arange(dof)).ravel())
        gdat.append(g.ravel())
        hdat.append(h.ravel())
    shape = (m, dof * n_modelled)
    if not rows:
        return sp.csr_matrix(shape), sp.csr_matrix(shape)
    r_all, c_all = np.concatenate(rows), np.concatenate(cols)
    J = sp.csr_matrix((np.concatenate(gdat), (r_all, c_all)), shape=shape)
    H = sp.csr_matrix((np.concatenate(hdat), (r_all, c_all)), shape=shape)
    return J, H


def effective_mass_K(scene: Scene) -> np.ndarray:
    """The textbook effective-mass ``K`` per contact, ``(nc, d, d)``: ``sum (1/m) E - r* I^-1
    r*`` over moving sides.

    In 2-D, ``-r* I^-1 r*`` becomes ``r_perp r_perp^T / I`` with ``r_perp = (-r_y, r_x)``.
    """
    nc, d = scene.n_contacts, scene.dimension
    K = np.zeros((nc, d, d))
    eye = np.eye(d)
    for side in (scene.contact_a, scene.contact_b):
        r = scene.point - scene.position[side]
        K += scene.inv_mass[side][:, None, None] * eye
        if d == 3:
            S = skew(r)
            K -= S @ scene.inv_inertia[side] @ S
        else:
            rp = np.stack([-r[:, 1], r[:, 0]], axis=1)
            K += scene.inv_inertia[side][:, 0, 0][:, None, None] * rp[:, :, None] * rp[:, None, :]
    return K


def skew(r: np.ndarray) -> np.ndarray:
    """``r*`` with ``r* n = r x n``, shape ``(m, 3, 3)``."""
    S = np.zeros((r.shape[0], 3, 3))
    S[:, 0, 1], S[:, 0, 2] = -r[:, 2], r[:, 1]
    S[:, 1, 0], S[:, 1, 2] = r[:, 2], -r[:, 0]
    S[:, 2, 0], S[:, 2, 1] = -r[:, 1], r[:, 0]
    return S


def gram(J: Any, H: Any) -> Any:
    """``J W J^T`` as ``J H^T`` (sparse), symmetrised to remove rounding asymmetry."""
    G = (J @ H.T).tocsr()
    G = ((G + G.T) * 0.5).tocsr()
    G.sum_duplicates()
    G.eliminate_zeros()
    return G


def dense_gram_by_body(scene: Scene, columns: np.ndarray, contacts: np.ndarray,
                       dirs: np.ndarray) -> np.ndarray:
    """The same ``J W J^T`` built densely body by body (``M[c, c] += G_k W_k G_k^T``).

    Independent of the sparse path; used for small problems and as its reference in tests.
    """
    m = contacts.shape[0]
    out = np.zeros((m, m))
    p = scene.point[contacts]
    idx, bods, gs, hs = [], [], [], []
    for side, sign in ((scene.contact_a, 1.0), (scene.contact_b, -1.0)):
        bodies = side[contacts]
        keep = np.flatnonzero(columns[bodies] >= 0)
        g, h = _side_blocks(scene, bodies[keep], p[keep], dirs[keep], sign)
        idx.append(keep)
        bods.append(bodies[keep])
        gs.append(g)
        hs.append(h)
    idx_a, bod_a = np.concatenate(idx), np.concatenate(bods)
    g_a, h_a = np.concatenate(gs), np.concatenate(hs)
    order = np.argsort(bod_a, kind="stable")
    idx_a, bod_a, g_a, h_a = idx_a[order], bod_a[order], g_a[order], h_a[order]
    cuts = np.flatnonzero(np.diff(bod_a)) + 1
    for sel in np.split(np.arange(bod_a.size), cuts):
        if sel.size == 0:
            continue
        c = idx_a[sel]
        out[np.ix_(c, c)] += g_a[sel] @ h_a[sel].T
    return 0.5 * (out + out.T)


def choose_storage(storage: str, n_rows: int, nnz_estimate: int) -> str:
    """``auto``: dense up to :data:`DENSE_MAX_ROWS` rows or when dense fill pays, and only
    within the dense-work budget (:func:`lcpcli.core.limits.within_dense_budget`: a dense M
    above it is never built); else sparse."""
    if storage not in STORAGES:
        raise OptionError(f"storage must be one of {', '.join(STORAGES)}, got {storage!r}")
    if storage != "auto":
        return storage
    if not within_dense_budget(n_rows):
        return "sparse"
    if n_rows <= DENSE_MAX_ROWS or filled(n_rows, nnz_estimate):
        return "dense"
    return "sparse"


def filled(n_rows: int, nnz_estimate: int) -> bool:
    """Whether at least :data:`DENSE_MIN_FILL` of an ``n_rows`` square M is stored: kept
    sparse, it would take more memory and time than dense (CSR: 12 bytes an entry)."""
    return nnz_estimate >= DENSE_MIN_FILL * n_rows * n_rows


def check_auto_storage(storage: str, n_rows: int, nnz_estimate: int) -> None:
    """Before M is assembled: ProblemError (exit 2) when ``auto`` storage meets an M filled
    enough to be dense (:func:`filled`) but over the dense-work budget.  Dense is refused by the
    budget and sparse would cost more than dense (n = 12,000 contacts on one body: 16 s and
    5.1 GB as CSR, 9 s and 2.3 GB dense), so neither is built; ``--storage sparse`` or
    ``LCPCLI_MAX_DENSE_N`` asks for one."""
    if storage == "auto" and not within_dense_budget(n_rows) and filled(n_rows, nnz_estimate):
        check_dense_work(n_rows, f"--storage auto keeps M dense when a quarter of it or more "
                                 f"is filled (here up to {nnz_estimate / n_rows ** 2:.0%})",
                         instead="use --storage sparse", cubic=False)


def pair_count(scene: Scene, columns: np.ndarray) -> int:
    """Upper bound on the stored entries of M: sum over modelled bodies of (contacts on it)^2."""
    deg = np.zeros(scene.n_bodies, dtype=np.int64)
    np.add.at(deg, scene.contact_a, 1)
    np.add.at(deg, scene.contact_b, 1)
    deg[columns < 0] = 0
    return int(np.sum(deg * deg))


def contact_states(v_rel: np.ndarray, eps: np.ndarray,
                   threshold: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """State index (into :data:`STATES`) and restitution used ``e``, per contact."""
    state = np.where(v_rel < -threshold, IMPACT, np.where(v_rel > 0, SEPARATING, RESTING))
    return state.astype(np.int8), np.where(state == IMPACT, eps, 0.0)


def assemble(scene: Scene, storage: str = "auto",
             restitution_threshold: float | None = None) -> Assembly:
    """Build the frictionless contact LCP of ``scene`` (see the module docstring).

    ``restitution_threshold`` replaces the scene-level threshold (contacts that give their own
    keep it); the default is :data:`DEFAULT_RESTITUTION_THRESHOLD`.
    """
    columns, modelled, reasons = body_columns(scene)
    nc = scene.n_contacts
    pairs = pair_count(scene, columns)
    check_auto_storage(storage, nc, pairs)  # before anything of M's size is built
    contacts = np.arange(nc)
    J, H = direction_rows(scene, columns, modelled.size, contacts, scene.normal)
    kind = choose_storage(storage, nc, pairs)
    M = dense_gram_by_body(scene, columns, contacts, scene.normal) if kind == "dense" \
        else gram(J, H)
    v_rel = relative_velocity(scene, contacts, scene.normal)
    scene_thr = scene.threshold_default if restitution_threshold is None \
        else restitution_threshold
    threshold = per_contact(scene.restitution_threshold, scene_thr,
                            DEFAULT_RESTITUTION_THRESHOLD)
    state, e = contact_states(v_rel, scene.restitution, threshold)
    q = (1.0 + e) * v_rel
    K = effective_mass_K(scene)
    inv_eff = np.einsum("ci,cij,cj->c", scene.normal, K, scene.normal)
    return Assembly(scene=scene, columns=columns, modelled=modelled, reasons=reasons, J=J, H=H,
                    M=M, q=q, v_rel=v_rel, inv_eff_mass=inv_eff, storage=kind,
                    threshold=threshold, state=state, restitution_used=e)
