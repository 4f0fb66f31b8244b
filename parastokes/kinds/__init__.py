"""The package's body kinds, one home each (listed in :data:`parastokes.registry.kinds.BUILTIN`).

- :mod:`.rod` (a folder): Kirchhoff rod swimmers above a wall (section 5.1);
- :mod:`.vesicle` (a folder): the spring-network sphere in shear flow (section 5.2);
- :mod:`.chain` (one module): a bead-spring chain (a polymer), written only through the public
  extension path.

Each home holds the body's mechanics, its system, its compiled parts (if any) and one
:class:`parastokes.registry.kinds.BodyKind` named ``KIND``: the config section (units and
defaults resolved by the section itself), the output layout and the drawing. Nothing outside
imports a kind by name; the registry loads it on demand.
"""
