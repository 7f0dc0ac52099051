"""The analysis layer: matrix classes, the principal pivoting transform, enumeration of
complementary cones, and the block algebra of mixed LCPs (pure functions on arrays).

Imports only :mod:`lcpcli.core`.
"""
