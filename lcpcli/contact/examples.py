"""Generated example scenes (benchmarks, tests, samples): box stacks and sphere lattices.

Both are deterministic for a given ``seed``; lengths in metres, masses in kilograms, velocities
in m/s (the scenes themselves carry no units).

* :func:`box_stacks`: ``n_stacks`` separate stacks of ``height`` unit boxes on one static
  ground, 4 corner contacts per box (the 4 coplanar corners make each layer's block of M lose
  one rank).  The ground is static, so each stack is its own island.
* :func:`sphere_lattice`: ``nx x ny x nz`` touching unit spheres (radius 0.5) on a cubic grid on
  the ground, one contact per neighbouring pair and one per bottom sphere: one island of about
  ``3 nx ny nz`` contacts, with random velocities (about half the contacts separating).
"""

from __future__ import annotations

import numpy as np

from lcpcli.contact.scene import Scene, build_scene


def box_stacks(n_stacks: int, height: int = 3, seed: int = 0, mu: float = 0.5,
               max_restitution: float = 0.8) -> Scene:
    """``n_stacks`` stacks of ``height`` boxes (mass 0.5..2, 4 corner contacts each).

    Box ``i`` of a stack sits on box ``i - 1`` (the ground for ``i = 0``); velocities are random
    with a downward bias (``v_z ~ N(-0.5, 1)``), angular velocities ``N(0, 0.3)``, restitution
    uniform in ``[0, max_restitution]``, friction coefficient ``mu`` on every contact.
    """
    rng = np.random.default_rng(seed)
    nb = 1 + n_stacks * height
    names = ["ground"] + [f"s{s}b{i}" for s in range(n_stacks) for i in range(height)]
    static = np.zeros(nb, dtype=bool)
    static[0] = True
    mass = np.full(nb, np.nan)
    mass[1:] = rng.uniform(0.5, 2.0, nb - 1)
    inertia = np.full((nb, 3, 3), np.nan)
    inertia[1:] = mass[1:, None, None] / 6.0 * np.eye(3)
    side = int(np.ceil(np.sqrt(max(n_stacks, 1))))
    stack = np.repeat(np.arange(n_stacks), height)
    level = np.tile(np.arange(height), n_stacks)
    pos = np.zeros((nb, 3))
    pos[1:, 0] = 2.0 * (stack % side) + rng.normal(size=nb - 1) * 0.05
    pos[1:, 1] = 2.0 * (stack // side) + rng.normal(size=nb - 1) * 0.05
    pos[1:, 2] = 0.5 + level
    vel = np.zeros((nb, 3))
    vel[1:] = rng.normal(size=(nb - 1, 3)) * [0.5, 0.5, 1.0] - [0.0, 0.0, 0.5]
    omega = np.zeros((nb, 3))
    omega[1:] = rng.normal(size=(nb - 1, 3)) * 0.3
    upper = np.arange(1, nb)
    lower = np.where(level == 0, 0, upper - 1)
    corners = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    ca = np.repeat(upper, 4)
    cb = np.repeat(lower, 4)
    point = np.repeat(pos[upper], 4, axis=0)
    point[:, :2] += np.tile(corners, (upper.size, 1))
    point[:, 2] -= 0.5
    nc = ca.size
    normal = np.tile([0.0, 0.0, 1.0], (nc, 1))
    eps = rng.uniform(0.0, max_restitution, nc)
    return build_scene(3, names, static, mass, inertia, None, pos, vel, omega, ca, cb, point,
                       normal, eps, np.full(nc, float(mu)), name=f"box_stacks_{n_stacks}x{height}")


def sphere_lattice(nx: int, ny: int, nz: int, seed: int = 0, mu: float = 0.5,
                   max_restitution: float = 0.8, speed: float = 1.0) -> Scene:
    """Touching spheres (radius 0.5, mass 1) at ``(i, j, k + 0.5)`` on the static ground.

    Contacts: each pair of grid neighbours (normal along the axis, from the lower-index sphere B
    to the higher-index sphere A) and each bottom sphere with the ground.  Velocities
    ``N(0, speed)`` per component, no spin.
    """
    rng = np.random.default_rng(seed)
    n = nx * ny * nz
    nb = n + 1
    idx = np.arange(n).reshape(nx, ny, nz) + 1
    names = ["ground"] + [f"p{i}_{j}_{k}" for i in range(nx) for j in range(ny)
                          for k in range(nz)]
    static = np.zeros(nb, dtype=bool)
    static[0] = True
    mass = np.full(nb, 1.0)
    mass[0] = np.nan
    inertia = np.full((nb, 3, 3), np.nan)
    inertia[1:] = 0.1 * np.eye(3)
    gi, gj, gk = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    pos = np.zeros((nb, 3))
    pos[1:] = np.stack([gi.ravel(), gj.ravel(), gk.ravel() + 0.5], axis=1)
    vel = np.zeros((nb, 3))
    vel[1:] = rng.normal(size=(n, 3)) * speed
    a_list, b_list, n_list = [], [], []
    for axis in range(3):
        sl_a = [slice(None)] * 3
        sl_b = [slice(None)] * 3
        sl_a[axis] = slice(1, None)
        sl_b[axis] = slice(None, -1)
        a = idx[tuple(sl_a)].ravel()
        a_list.append(a)
        b_list.append(idx[tuple(sl_b)].ravel())
        e = np.zeros(3)
        e[axis] = 1.0
        n_list.append(np.tile(e, (a.size, 1)))
    bottom = idx[:, :, 0].ravel()
    a_list.append(bottom)
    b_list.append(np.zeros(bottom.size, dtype=np.int64))
    n_list.append(np.tile([0.0, 0.0, 1.0], (bottom.size, 1)))
    ca, cb, normal = np.concatenate(a_list), np.concatenate(b_list), np.concatenate(n_list)
    point = pos[ca] - 0.5 * normal
    nc = ca.size
    eps = rng.uniform(0.0, max_restitution, nc)
    return build_scene(3, names, static, mass, inertia, None, pos, vel, np.zeros((nb, 3)), ca, cb,
                       point, normal, eps, np.full(nc, float(mu)),
                       name=f"sphere_lattice_{nx}x{ny}x{nz}")
