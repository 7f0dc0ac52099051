"""Rendering for the terminal (rich tables, Markdown, plots): results in, text out.

Used only by :mod:`lcpcli.cli`; nothing here computes.
"""
