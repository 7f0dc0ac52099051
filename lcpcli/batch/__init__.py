"""Batch solving: many problems from files, folders, globs and multi-problem files.

The layer above :mod:`lcpcli.api` and :mod:`lcpcli.io`; the CLI's ``solve`` uses it for more
than one problem.
"""
