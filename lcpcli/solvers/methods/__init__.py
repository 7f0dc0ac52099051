"""The solver methods, one module each (scanned by :mod:`lcpcli.solvers.registry`).
"""
