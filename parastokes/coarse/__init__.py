"""Coarse-solver families: one module each, found by ``[coarse] kind``
(:mod:`parastokes.registry.coarse`).

The package's own family is the extrapolated G of eq. 30 (:mod:`.extrapolated`).
"""
