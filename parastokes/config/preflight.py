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
  and its Jacobian hooks once (:func:`parastokes.stiff.jacobian.probe_hooks`), a
  :class:`~parastokes.bodies.contract.BodyError` naming the method otherwise (in a scene, the
  body too);
- a scene with rigid bodies makes its first coupled mobility solve (:func:`_first_solve`), which
  a run's warm-up makes first: a solve that fails there (loads or a repulsion beyond floating
  point) is a :class:`ConfigError` naming the body with the largest load and its value;
- one of the package's bodies whose rates are not a solve takes F's first step
  (:func:`_first_step`): a step that is not finite there is refused, naming the parameter whose
  magnitude floating point cannot step (``bending = 1e300``), or ``fine.dt``;
- a linearly implicit scheme on a system without a stiff part (no ``A``: it runs as an explicit
  scheme) gets a note (:func:`implicit_without_stiff_part`), added to ``resolved.warnings``.

The package's own bodies are not probed otherwise (they keep the contract by their tests).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import integrate
from ..bodies import contract
from ..core.contracts import StepFailure
from ..stiff import jacobian
from .build import Setup, build
from .checks import Resolved
from .errors import ConfigError
from .schema import Config

__all__ = ["implicit_without_stiff_part", "preflight"]


def _named(system: Any, body: Any) -> str:
    """How a message names ``body`` of ``system``: ``""`` for the system itself, else its
    index and name in the scene."""
    if body is system:
        return ""
    index = next(i for i, b in enumerate(system.bodies) if b is body)
    return f"bodies[{index}] ({system.names[index]!r}): "


def _probe_users(system: Any, t: float, dt: float) -> None:
    """Each user's body of ``system`` called at its initial state (contract and Jacobian
    hooks); its BodyError names it in a scene."""
    for body in contract.user_bodies(system):
        try:
            x = contract.probe(body, t, dt)
            jacobian.probe_hooks(body, t, x)
        except contract.BodyError as error:
            where = _named(system, body)
            if not where:
                raise
            raise contract.BodyError(f"{where}{error}", error.method) from None


def _size(surface: Any) -> float:
    """The largest component of a surface's force and torque."""
    return max(float(np.abs(surface.force).max()), float(np.abs(surface.torque).max()))


def _largest_load(scene: Any, t: float, x: np.ndarray) -> str:
    """The rigid body of ``scene`` with the largest force or torque at ``(t, x)`` (its own and
    the repulsion's), as ``"'name' has a load of 1e+200"``, and the repulsion when it is that
    load's larger part."""
    surfaces = scene.implicit_surfaces(t, x)
    sizes = np.nan_to_num([_size(s) for s in surfaces], nan=np.inf)
    k = int(np.argmax(sizes))
    index = scene.implicit_bodies[k]
    text = f"{scene.names[index]!r} has a load (force or torque) of {sizes[k]:.3g}"
    own = _size(scene.bodies[index].surface(t, scene.blocks(x)[index]))
    repulsion = scene.repulsion
    if repulsion is not None and not own >= 0.5 * sizes[k]:
        text += (f", mostly from [scene] repulsion (range {repulsion.range:g}, force "
                 f"{repulsion.force:g})")
    return text


def _first_solve(setup: Setup, source: str) -> None:
    """A scene's first coupled mobility solve at its initial state (its rigid bodies', with
    the repulsion), made here as the run's warm-up would: a failure is a :class:`ConfigError`
    of ``bodies`` naming the body with the largest load and its value."""
    system, t = setup.system, setup.config.time.t0
    if not getattr(system, "implicit_bodies", ()):
        return
    x = system.initial_state()
    try:
        system.rates(t, x)
    except StepFailure as error:
        load = _largest_load(system, t, x)
        raise ConfigError([("bodies", f"the scene's first mobility solve (at the initial "
                                      f"state) failed: {error}; body {load}")], source) from None


#: Rates beyond this size at the initial state are values beyond what floating point can step
#: (a parameter of 1e300): no smaller step is the fix.
HUGE_RATES = 1e100


def _first_step(setup: Setup, source: str) -> None:
    """One step of F (its scheme at ``fine.dt``) from the initial state of one of the
    package's bodies whose rates are not a solve (a rod, a vesicle, a chain), as the run's first
    fine step: a step that is not finite is a :class:`ConfigError` of ``model`` naming the
    largest parameter when the rates there are beyond :data:`HUGE_RATES`, else ``fine.dt``.
    (Adaptive steps shrink a failed first step themselves; a user's body is probed by
    :func:`parastokes.bodies.contract.probe`, a scene by :func:`_first_solve`.)"""
    cfg, system = setup.config, setup.system
    if (cfg.fine.rtol is not None or not contract.is_builtin(system)
            or hasattr(system, "bodies") or hasattr(system, "surface")):
        return
    t, x = cfg.time.t0, system.initial_state()
    with np.errstate(all="ignore"):
        y = integrate.step(system, cfg.fine.scheme, t, x, cfg.fine.dt)
        if np.isfinite(y).all():
            return
        rates = float(np.abs(system.rates(t, x)).max())
    if rates > HUGE_RATES:
        name, value = max(system.params.items(), key=lambda item: abs(item[1]))
        raise ConfigError([("model", f"the rates at the initial state reach {rates:.3g}, and "
                                     "one fine step from there is not finite: values beyond "
                                     "what floating point holds, which no smaller step fixes; "
                                     f"check the parameters' magnitudes and units (the largest: "
                                     f"{name} = {value:g})")], source)
    raise ConfigError([("fine.dt", f"one step of {cfg.fine.scheme} of {cfg.fine.dt:g} from the "
                                   "initial state is not finite: reduce fine.dt")], source)


def _schemes(cfg: Config) -> list[tuple[str, str]]:
    """The ``(key, scheme)`` of every solver of ``cfg``: F's, and G's (its auxiliary solvers',
    or a HODMD G's ``g1`` and ``g2``)."""
    found: list[tuple[str, str]] = [("fine.scheme", cfg.fine.scheme)]
    coarse = cfg.coarse
    for key, section in (("coarse", coarse), ("coarse.g1", getattr(coarse, "g1", None)),
                         ("coarse.g2", getattr(coarse, "g2", None))):
        name = getattr(section, "scheme", None)
        if isinstance(name, str):
            found.append((f"{key}.scheme", name))
    return found


def _stiff(system: Any) -> bool:
    """Whether a linearly implicit scheme finds an ``A`` for ``system`` (a scene: for one of its
    bodies; :func:`parastokes.stiff.jacobian.has_stiff_part`)."""
    bodies = getattr(system, "bodies", None)
    if bodies is not None and contract.is_builtin(system):
        return any(_stiff(body) for body in bodies)
    return jacobian.has_stiff_part(system)


def implicit_without_stiff_part(cfg: Config, system: Any) -> str | None:
    """A note when a solver of ``cfg`` uses a linearly implicit scheme and ``system`` has no
    stiff part: with ``A = 0`` the scheme is explicit in effect (and no more stable)."""
    keys = [(key, name) for key, name in _schemes(cfg)
            if getattr(integrate.SCHEMES.get(name), "implicit", False)]
    if not keys or _stiff(system):
        return None
    listed = ", ".join(f"{key} = {name!r}" for key, name in keys)
    return (f"{listed}: a linearly implicit scheme, but this body has no stiff part (no "
            "stiff_jacobian, and no loads on the fluid: a rigid or prescribed-motion body), so "
            "it runs with A = 0, as an explicit scheme of its order, no more stable; an "
            "explicit scheme (rk2) takes the same steps for less work")


def preflight(cfg: Config, resolved: Resolved, source: str = "") -> Setup:
    """The :class:`Setup` of ``cfg``, its users' bodies probed at their initial states, a
    scene's first mobility solve made; raises :class:`ConfigError` or
    :class:`~parastokes.bodies.contract.BodyError`. Adds its note to ``resolved.warnings``."""
    try:
        setup = build(cfg, resolved)
    except contract.BodyError:
        raise
    except ValueError as error:  # a system or solver that refuses its values
        where = "bodies" if cfg.model.kind == "scene" else "model"
        raise ConfigError([(where, str(error))], source) from None
    _probe_users(setup.system, cfg.time.t0, cfg.fine.dt)
    _first_solve(setup, source)
    _first_step(setup, source)
    note = implicit_without_stiff_part(cfg, setup.system)
    if note and note not in resolved.warnings:
        resolved.warnings.append(note)
    return setup
