"""Contact LCPs from rigid-body scenes: ``w = M j + q``, ``M = J W J^T``.

* :mod:`lcpcli.contact.scene`: scene files (JSON, HDF5), validation, conventions, kinematic bodies;
* :mod:`lcpcli.contact.assembly`: ``J``, ``W``, ``M``, ``q``, the contact states (restitution
  threshold) and the effective masses;
* :mod:`lcpcli.contact.friction`: the polyhedral (Stewart-Trinkle) friction LCP;
* :mod:`lcpcli.contact.planar`: planar motion in a 3-D scene (2 friction directions, not K);
* :mod:`lcpcli.contact.islands`: independent islands, solved one by one and merged;
* :mod:`lcpcli.contact.impact`: post-impact velocities and kinetic energy;
* :mod:`lcpcli.contact.model`: the :class:`~lcpcli.core.problem.Problem` with metadata,
  softness, solve, JSON;
* :mod:`lcpcli.contact.warmstart`: impulse files (``--z0``, ``--impulses``);
* :mod:`lcpcli.contact.examples`: generated scenes (box stacks, sphere lattices).
"""

from __future__ import annotations

from lcpcli.contact.model import ContactLCP, Impact, build, solve, to_json
from lcpcli.contact.scene import Scene, load_scene, scene_from_dict

__all__ = ["ContactLCP", "Impact", "Scene", "build", "load_scene", "scene_from_dict", "solve",
           "to_json"]
