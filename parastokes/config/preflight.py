"""Before a run's workers start: the configuration built, and a user's body called once.

:func:`preflight` is what ``parastokes check`` and every run (:func:`parastokes.run.execute`,
before its run directory is claimed) do after the checks of :mod:`.checks`, so that a
configuration one accepts the other does not refuse:

- :func:`parastokes.config.build` makes the system, F and G (pure); a system that refuses its
  values (a ``ValueError`` of its construction) is a :class:`ConfigError` of ``[model]``
  (``[[bodies]]`` for a scene);
- every body whose type is not the package's own (:func:`parastokes.bodies.contract.user_bodies`)
  is called once at its initial state (:func:`parastokes.bodies.contract.probe`: signatures,
  shapes, real finite values; one evaluation of its forces and rates, one advance and projection),
  a :class:`~parastokes.bodies.contract.BodyError` naming the method otherwise.

The package's own bodies are not called (they keep the contract by their tests; a call would load
their compiled kernels).
"""

from __future__ import annotations

from ..bodies import contract
from .build import Setup, build
from .checks import Resolved
from .errors import ConfigError
from .schema import Config

__all__ = ["preflight"]


def preflight(cfg: Config, resolved: Resolved, source: str = "") -> Setup:
    """The :class:`Setup` of ``cfg``, its users' bodies probed at their initial states; raises
    :class:`ConfigError` or :class:`~parastokes.bodies.contract.BodyError`."""
    try:
        setup = build(cfg, resolved)
    except contract.BodyError:
        raise
    except ValueError as error:  # a system or solver that refuses its values
        where = "bodies" if cfg.model.kind == "scene" else "model"
        raise ConfigError([(where, str(error))], source) from None
    for body in contract.user_bodies(setup.system):
        contract.probe(body, cfg.time.t0, cfg.fine.dt)
    return setup
