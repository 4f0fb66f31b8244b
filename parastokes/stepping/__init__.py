"""Import paths of round 2 and 3 for compiled bodies (docs/extending.md), kept so that their code
runs unchanged; each module here *is* the module it names (no copy):

- ``parastokes.stepping.loop``: :mod:`parastokes.integrate.loop`;
- ``parastokes.stepping.fluid``: :mod:`parastokes.fluid.compiled`;
- ``parastokes.stepping.registry``: :mod:`parastokes.registry.loops`.

The package itself imports none of them; new code imports the modules where they live.
"""
