"""The rod: Kirchhoff rod swimmers above a wall (paper section 5.1, Table 2, eq. 36), in one folder.

- :mod:`.mechanics`: the compiled rod mechanics (half-point frames, strains, point loads: eqs.
  9-12; the preferred strain, eq. 36);
- :mod:`.system`: :class:`~.system.RodSystem` (the System contract: rates, advance, Θ = (ε, μ, a))
  and its factories ``rod``/``rod_swimmer`` (public as :mod:`parastokes.models`);
- :mod:`.compiled`: its parts for the compiled loop of steps (:mod:`parastokes.integrate.loop`),
  registered for the exact type ``RodSystem`` when :mod:`.system` is imported;
- :mod:`.jacobian`: the Jacobian of its loads by compiled segment-wise central differences (its
  ``load_jacobian`` hook, for the linearly implicit schemes);
- :mod:`.transfer`: the cubic-spline grid transfer between rod grids (Remark 4, eqs. 32-33);
- :mod:`.kind`: the registered kind ``KIND``: config section ``RodModel`` (its own units and
  defaults), output layout and drawing;
- :mod:`.reference`: plain-numpy oracles of the compiled mechanics (for tests).

The registry loads :mod:`.kind` on demand (:data:`parastokes.registry.kinds.BUILTIN`); this
package imports nothing, so a module that needs only the mechanics (the GPU backend) loads only it.
"""
