"""The bottom layer: what every other part of the package may import, importing no other part.

- :mod:`.contracts`: the typed contracts (``System``, ``Propagator``, ...) and the shared errors;
- :mod:`.values`: small value types of the run (names of phases, ...);
- :mod:`.plugins`: how a ``"package.module:Name"`` string or an entry point becomes an object;
- :mod:`.files`: safe reading and atomic writing of files (every command that writes uses it).
"""
