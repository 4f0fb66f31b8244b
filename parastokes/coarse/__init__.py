"""Coarse-solver families: one module each, found by ``[coarse] kind``
(:mod:`parastokes.coarse.registry`).

The package's own family is the extrapolated G of eq. 30 (:mod:`.extrapolated`).
"""
