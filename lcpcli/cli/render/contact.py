"""Rich renderables for ``lcpcli contact-matrix`` (no computing here)."""

from __future__ import annotations

from typing import Any

from rich.console import Group
from rich.table import Table
from rich.text import Text

from lcpcli.cli.render.common import STATUS_STYLE, fmt
from lcpcli.contact.assembly import STATES

#: Tables longer than this show the head and tail only.
MAX_ROWS = 30
#: M and q are printed as a table up to this many unknowns.
MAX_MATRIX = 12


def _rows(n: int) -> list[int]:
    if n <= MAX_ROWS:
        return list(range(n))
    return list(range(MAX_ROWS // 2)) + [-1] + list(range(n - MAX_ROWS // 2, n))


def _vec(v: Any) -> str:
    try:
        items = list(v)
    except TypeError:
        return fmt(v)
    return fmt(items[0]) if len(items) == 1 else "(" + ", ".join(fmt(x) for x in items) + ")"


def render_scene(clcp: Any, file: str | None = None, out: str | None = None) -> Group:
    """Scene summary, effective masses, and M, q when small."""
    scene, asm, prob = clcp.scene, clcp.assembly, clcp.problem
    head = Table.grid(padding=(0, 2))
    head.add_column(style="bold")
    head.add_column()
    head.add_row("scene", f"{file or ''}{' : ' + scene.name if scene.name else ''}")
    head.add_row("dimension", f"{scene.dimension}-D ({scene.dof} DOF per body)")
    n_static = int(scene.static.sum())
    n_kin = int(scene.kinematic.sum())
    n_fixed = n_static + n_kin
    head.add_row("bodies", f"{scene.n_bodies} ({n_static} static, "
                           + (f"{n_kin} kinematic, " if n_kin else "")
                           + f"{asm.modelled.size} moving in contact: modelled, "
                             f"{scene.n_bodies - n_fixed - asm.modelled.size} moving in no "
                             f"contact: not modelled)")
    counts = [int((asm.state == i).sum()) for i in range(len(STATES))]
    head.add_row("contacts", f"{scene.n_contacts}"
                 + (f" ({clcp.friction_contacts.size} with friction, K = {clcp.friction})"
                    if clcp.friction else " (frictionless)")
                 + "; " + ", ".join(f"{c} {name}" for c, name in zip(counts, STATES, strict=True)))
    if clcp.plane is not None:
        reduced = clcp.friction and clcp.friction_contacts.size
        head.add_row("planar", f"motion in the plane with normal {_vec(clcp.plane)}"
                     + (f": friction reduced to the 2 in-plane directions (asked K = "
                        f"{clcp.requested_friction})" if reduced else ""))
    sizes = clcp.island_sizes()
    if clcp.islands.count:
        head.add_row("islands", f"{clcp.islands.count} (unknowns per island: "
                                f"{int(sizes.min())}..{int(sizes.max())})")
    if clcp.regularisation.any():
        head.add_row("softness", f"{int((clcp.softness > 0).sum())} soft contacts "
                                 f"(softness {fmt(float(clcp.softness.max()))} max): "
                                 f"M_ii * softness added to M's diagonal")
    head.add_row("LCP", f"{prob.summary()}: w = M z + q, z = impulses; "
                        f"M = J W J^T with J {asm.J.shape[0]} x {asm.J.shape[1]}")
    if out:
        head.add_row("written", out)
    parts: list[Any] = [head, Text("")]
    bt = Table(title="bodies", title_justify="left")
    for col in ("body", "mass", "velocity", "angular velocity", "modelled"):
        bt.add_column(col, justify="right" if col == "mass" else "left")
    for i in _rows(scene.n_bodies):
        if i < 0:
            bt.add_row("...", "", "", "", f"({scene.n_bodies - MAX_ROWS} rows not shown)")
            continue
        mass = "static" if scene.static[i] else "kinematic" if scene.kinematic[i] \
            else fmt(scene.mass[i])
        bt.add_row(scene.body_names[i], mass, _vec(scene.velocity[i]), _vec(scene.omega[i]),
                   asm.reasons[i])
    parts += [bt, Text("")]
    if scene.n_contacts == 0:
        return Group(*parts, Text("no contacts: nothing to model"))
    ct = Table(title="contacts (normal from B to A)", title_justify="left")
    cols = ("#", "contact", "A", "B", "eps", "mu", "v_rel-", "state", "q", "n^T K n", "m_eff")
    for col in cols:
        ct.add_column(col, justify="left" if col in ("contact", "A", "B", "state") else "right")
    for c in _rows(scene.n_contacts):
        if c < 0:
            ct.add_row("...", f"({scene.n_contacts - MAX_ROWS} rows not shown: use --json)",
                       *[""] * (len(cols) - 2))
            continue
        mu = "-" if scene.mu[c] != scene.mu[c] else fmt(scene.mu[c])
        ct.add_row(str(c + 1), scene.contact_names[c], scene.body_names[scene.contact_a[c]],
                   scene.body_names[scene.contact_b[c]], fmt(scene.restitution[c]), mu,
                   fmt(asm.v_rel[c]), STATES[int(asm.state[c])], fmt(asm.q[c]),
                   fmt(asm.inv_eff_mass[c]), fmt(asm.eff_mass[c]))
    parts.append(ct)
    if prob.n <= MAX_MATRIX:
        M = prob.dense_M()
        mt = Table(title="M and q  (w = M z + q)", title_justify="left")
        mt.add_column("row")
        for j in range(prob.n):
            mt.add_column(f"z{j + 1}", justify="right")
        mt.add_column("q", justify="right", style="bold")
        for i, name in enumerate(clcp.unknowns):
            mt.add_row(f"w{i + 1} {name}", *[fmt(x) for x in M[i]], fmt(prob.q[i]))
        parts += [Text(""), mt]
    else:
        parts += [Text(""), Text(f"M ({prob.n} x {prob.n}, {prob.summary()}) and q not shown: "
                                 f"write them with -o or use --json")]
    for w in scene.warnings:
        parts.append(Text(f"warning: {w}", style="yellow"))
    return Group(*parts)


def render_impact(clcp: Any, impact: Any) -> Group:
    """Verdict, impulses, post-impact velocities and energies."""
    scene, res = clcp.scene, impact.result
    head = Table.grid(padding=(0, 2))
    head.add_column(style="bold")
    head.add_column()
    head.add_row("status", Text(res.status, style=STATUS_STYLE.get(res.status, "")))
    head.add_row("method", f"{res.method} ({res.iterations} pivots/iterations)")
    head.add_row("message", res.message)
    head.add_row("residual", f"{res.certificate.residual:.3e}  ||min(z, w)||_inf, "
                             f"error {res.certificate.error:.3e}")
    if impact.islands is not None:
        head.add_row("islands", f"{len(impact.islands)} solved separately, results merged and "
                                f"certified on the whole-scene LCP")
    parts: list[Any] = [Text(""), head, Text("")]
    if scene.n_contacts == 0:
        return Group(*parts, Text("no contacts: no impulse, no velocity changes"))
    if impact.islands is not None and len(impact.islands) > 1:
        parts += [_island_table(impact.islands), Text("")]
    it = Table(title="impulses and normal velocities", title_justify="left")
    cols = ["#", "contact", "state", "normal impulse", "v_rel-", "v_rel+", "-e v_rel-"]
    if clcp.friction:
        cols += ["friction sum", "mu j_n"]
    for col in cols:
        it.add_column(col, justify="left" if col == "contact" else "right")
    fpos = {int(f): i for i, f in enumerate(clcp.friction_contacts)}
    for c in _rows(scene.n_contacts):
        if c < 0:
            it.add_row("...", "(rows not shown: use --json)", *[""] * (len(cols) - 2))
            continue
        row = [str(c + 1), scene.contact_names[c], STATES[int(clcp.assembly.state[c])],
               fmt(impact.normal_impulses[c]), fmt(clcp.assembly.v_rel[c]),
               Text(fmt(impact.normal_velocity[c]),
                    style="bold red" if impact.approaching[c] else ""),
               fmt(-clcp.assembly.restitution_used[c] * clcp.assembly.v_rel[c])]
        if clcp.friction:
            if c in fpos:
                row += [fmt(impact.tangent_impulses[fpos[c]].sum()),
                        fmt(scene.mu[c] * impact.normal_impulses[c])]
            else:
                row += ["-", "-"]
        it.add_row(*row)
    parts += [it, Text("")]
    vt = Table(title="velocities after impact (modelled bodies)", title_justify="left")
    for col in ("body", "linear before", "linear after", "angular before", "angular after"):
        vt.add_column(col)
    mod = list(clcp.assembly.modelled)
    shown = mod if len(mod) <= MAX_ROWS else mod[: MAX_ROWS // 2] + [-1] + mod[-MAX_ROWS // 2:]
    for i in shown:
        if i < 0:
            vt.add_row("...", f"({len(mod) - MAX_ROWS} rows not shown)", "", "", "")
            continue
        vt.add_row(scene.body_names[i], _vec(scene.velocity[i]), _vec(impact.velocity[i]),
                   _vec(scene.omega[i]), _vec(impact.omega[i]))
    parts += [vt, Text("")]
    e = Table.grid(padding=(0, 2))
    e.add_column(style="bold")
    e.add_column()
    e.add_row("kinetic energy before", fmt(impact.energy_before))
    e.add_row("kinetic energy after", fmt(impact.energy_after))
    if impact.energy_increase:
        e.add_row("WARNING", Text("kinetic energy increased: Newton restitution on simultaneous "
                                  "contacts can do this", style="bold red"))
    n_app = int(impact.approaching.sum())
    e.add_row("contacts ending approaching",
              Text(f"{n_app}" + (" (soft contacts allow it)" if n_app and
                                 clcp.regularisation.any() else ""),
                   style="bold red" if n_app else ""))
    parts.append(e)
    return Group(*parts)


def _island_table(islands: list[dict[str, Any]]) -> Table:
    """Per island: contacts, bodies, unknowns, method, status, iterations (head and tail)."""
    t = Table(title="islands (solved separately)", title_justify="left")
    cols = ("island", "contacts", "bodies", "unknowns", "method", "status", "iterations",
            "error", "warm")
    for col in cols:
        t.add_column(col, justify="left" if col in ("method", "status") else "right")
    for i in _rows(len(islands)):
        if i < 0:
            t.add_row("...", f"({len(islands) - MAX_ROWS} rows not shown: use --json)",
                      *[""] * (len(cols) - 2))
            continue
        r = islands[i]
        t.add_row(str(r["index"]), str(r["contacts"]), str(r["bodies"]), str(r["unknowns"]),
                  r["method"], Text(r["status"], style=STATUS_STYLE.get(r["status"], "")),
                  str(r["iterations"]), "-" if r["error"] is None else f"{r['error']:.1e}",
                  "yes" if r["warm"] else "")
    return t
