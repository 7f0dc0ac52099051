"""Contact LCPs from rigid-body scenes (seed 004): ``w = M j + q``, ``M = J W J^T``.

* :mod:`lcpcli.contact.scene`: scene files (JSON, HDF5), validation, conventions;
* :mod:`lcpcli.contact.assembly`: ``J``, ``W``, ``M``, ``q`` and the effective masses;
* :mod:`lcpcli.contact.friction`: the polyhedral (Stewart-Trinkle) friction LCP;
* :mod:`lcpcli.contact.impact`: post-impact velocities and kinetic energy;
* :mod:`lcpcli.contact.model`: the :class:`~lcpcli.core.problem.Problem` with metadata, solve, JSON.
"""

from __future__ import annotations

from lcpcli.contact.model import ContactLCP, Impact, build, solve, to_json
from lcpcli.contact.scene import Scene, load_scene, scene_from_dict

__all__ = ["ContactLCP", "Impact", "Scene", "build", "load_scene", "scene_from_dict", "solve",
           "to_json"]
