"""The package's body kinds, one module each (listed in :data:`.bodies.registry.BUILTIN`).

- :mod:`.rod`: Kirchhoff rod swimmers above a wall (section 5.1);
- :mod:`.vesicle`: the spring-network sphere in shear flow (section 5.2);
- :mod:`.chain`: a bead-spring chain (a polymer), written only through the public extension path.

Each module holds one :class:`parastokes.bodies.registry.BodyKind` named ``KIND``: the config
section (units and defaults resolved by the section itself), the factory, the output layout and
the drawing. Nothing outside imports these modules by name; the registry loads them on demand.
"""
