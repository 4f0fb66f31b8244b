"""The vesicle: a spring-network sphere in shear flow (paper section 5.2), in one folder.

- :mod:`.mechanics`: the compiled Hookean edge springs (docs/physics.md (14));
- :mod:`.system`: :class:`~.system.VesicleSystem` (the System contract: rates, advance,
  Θ = (ε, μ, κ)) and its factory ``vesicle`` (public as :mod:`parastokes.models`);
- :mod:`.compiled`: its parts for the compiled loop of steps (:mod:`parastokes.integrate.loop`),
  registered for the exact type ``VesicleSystem`` when :mod:`.system` is imported;
- :mod:`.kind`: the registered kind ``KIND``: config section ``VesicleModel`` (its own units and
  defaults), output layout and drawing;
- :mod:`.reference`: the plain-numpy oracle of the spring forces (for tests).

The registry loads :mod:`.kind` on demand (:data:`parastokes.registry.kinds.BUILTIN`); this
package imports nothing, so a module that needs only the mechanics (the GPU backend) loads only it.
"""
