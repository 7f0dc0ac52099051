"""Compiled kernels of the solver methods (no Python objects inside the hot loops).
"""
