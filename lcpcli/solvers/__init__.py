"""The solver layer: the registry of methods, their options, and the compiled kernels.

Layout: ``methods/`` holds one module per method, each defining ``METHODS``, a list of
:class:`Method` records; ``kernels/`` the compiled kernels; ``options.py`` the option parsers;
``support.py`` numerical helpers shared by methods.  Methods keep heavy imports inside their
functions, so that listing the methods (``lcpcli solve --help``) stays cheap.

Adding a method = adding one module to ``methods/``; nothing else needs to change.

:data:`DEFAULT_METHOD` lives here, in the package itself (numpy-free), so that the command line
can show it as the default of ``--method`` without loading the registry.
"""

#: The method used when none is named (``lcpcli.solve``, ``solve_many``, the contact solver,
#: batches, ``lcpcli solve`` and ``lcpcli contact --method``): the planner ``auto``.
DEFAULT_METHOD = "auto"
