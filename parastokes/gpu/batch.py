"""Group propagator calls into GPU batches: one batch per system structure, scheme and blow-up
factor, Θ, start state, time span and step free per member.

A call ``fn(*args)`` is batched when ``fn`` is an :class:`parastokes.integrate.Propagator` of a
system that the GPU path reproduces (its exact type has device parts,
:func:`parastokes.gpu.stepping.device_parts`) called as
``fn(t_start, t_end, x)``: the fine solves of a parallel sweep, the auxiliary solvers of an
extrapolated coarse step (on the coarse grid too). Each member follows :func:`integrate.run`
exactly: ``n_steps`` equal steps of ``(t_end - t_start)/n``, the start state projected, the result
projected, :class:`integrate.BlowUpError` on a blow-up.

A propagator call ``fn(t_start, t_end, x)`` of any other system (a rigid or prescribed-motion
body, a scene with one, a user's body without device parts), or with a linearly implicit scheme
or adaptive steps (``rtol``/``atol``: :mod:`parastokes.stiff`), is *hosted* (:func:`hosted_call`):
all such calls of a batch run on the host together, each its own CPU solve, with their fluid
products evaluated on the GPU in batched launches (:mod:`.hosted`). Any other call runs here, on
the CPU, in order, as the serial executor would run it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .. import integrate
from ..core.contracts import System
from . import hosted, stepping

__all__ = ["Outcome", "batch_key", "gpu_call", "hosted_call", "run_calls"]

#: ``(True, value)`` or ``(False, exception)`` for one call.
Outcome = tuple[bool, Any]


def batch_key(fn: Any, args: tuple) -> tuple | None:
    """What members of one batch share, or None when the call is not batched on the GPU."""
    if not isinstance(fn, integrate.Propagator) or len(args) != 3:
        return None  # (a propagator's ``counted``, with rtol, runs hosted)
    if integrate.lookup(fn.scheme).implicit or fn.rtol is not None or fn.atol is not None:
        return None  # the device loop runs fixed steps of explicit tableaux: hosted instead
    system = stepping.gpu_system(fn.system)
    if system is None:
        return None
    neutral = dict.fromkeys(system.params, 1.0)
    structure = system.with_params(**neutral)
    if "n_threads" in getattr(structure, "__dataclass_fields__", {}):
        structure = dataclasses.replace(structure, n_threads=None)
    return structure, fn.scheme, fn.blowup_factor


def gpu_call(fn: Any, args: tuple, kwargs: dict) -> bool:
    """Whether the call runs on the GPU, batched or hosted: a propagator call
    ``fn(t_start, t_end, x)``, or its ``counted`` (an adaptive auxiliary solve)."""
    owner = getattr(fn, "__self__", None)
    counted = isinstance(owner, integrate.Propagator) and fn == owner.counted
    return (isinstance(fn, integrate.Propagator) or counted) and len(args) == 3 and not kwargs


def hosted_call(fn: Any, args: tuple, kwargs: dict) -> bool:
    """Whether the call runs hosted (see the module): a GPU call (:func:`gpu_call`) that
    :func:`batch_key` does not batch."""
    return gpu_call(fn, args, kwargs) and batch_key(fn, args) is None


def _prepare(fn: integrate.Propagator, args: tuple) -> stepping.Member | Outcome:
    """The member of a call, or its outcome when no step needs to be taken (or the call is bad)."""
    t_start, t_end, x = args
    try:
        n = integrate.n_steps(t_start, t_end, fn.dt)
        x = fn.system.project(np.array(x, dtype=float))
    except Exception as exc:
        return False, exc
    if n == 0:
        return True, x
    system = stepping.gpu_system(fn.system)
    assert system is not None  # a batched call (batch_key)
    return stepping.Member(system, x, float(t_start), (t_end - t_start) / n, n)


def _run_group(
    calls: list[tuple[int, integrate.Propagator, tuple]],
    outcomes: list[Outcome | None],
    launch: stepping.Launch | None,
) -> None:
    members, where = [], []
    for index, fn, args in calls:
        prepared = _prepare(fn, args)
        if isinstance(prepared, stepping.Member):
            members.append(prepared)
            where.append((index, fn))
        else:
            outcomes[index] = prepared
    if not members:
        return
    first = where[0][1]
    limit = first.blowup_factor * first.system.monitor_limit
    try:
        results = stepping.solve(integrate.explicit_scheme(first.scheme), members, limit, launch)
    except Exception as exc:
        for index, _ in where:
            outcomes[index] = False, exc
        return
    for (index, fn), member, steps in zip(where, members, results, strict=True):
        try:
            result = integrate.run_result(fn.system, member.t0, member.h, steps, fn.blowup_factor)
        except Exception as exc:
            outcomes[index] = False, exc
        else:
            outcomes[index] = True, result.state


def run_calls(
    calls: Sequence[tuple[Callable[..., Any], tuple, dict]],
    launch: stepping.Launch | None = None,
    launches: list[int] | None = None,
) -> list[Outcome]:
    """Run ``fn(*args, **kwargs)`` for every call: batched on the GPU where possible (one batch
    per :func:`batch_key`), hosted with batched fluid products (:func:`hosted_call`), the rest in
    order on the CPU. Returns the outcomes in call order; ``launches`` (a list) gets the batch
    size of each launch of the hosted calls' products."""
    outcomes: list[Outcome | None] = [None] * len(calls)
    groups: dict[tuple, list] = {}
    host: list[int] = []
    for index, (fn, args, kwargs) in enumerate(calls):
        key = batch_key(fn, args) if gpu_call(fn, args, kwargs) else None
        if key is not None:
            groups.setdefault(key, []).append((index, fn, args))
        elif gpu_call(fn, args, kwargs):
            host.append(index)
        else:
            try:
                outcomes[index] = True, fn(*args, **kwargs)
            except Exception as exc:
                outcomes[index] = False, exc
    for group in groups.values():
        _run_group(group, outcomes, launch)
    if host:
        results, sizes = hosted.run_calls([calls[i][:2] for i in host], launch)
        for index, outcome in zip(host, results, strict=True):
            outcomes[index] = outcome
        if launches is not None:
            launches.extend(sizes)
    done = [outcome for outcome in outcomes if outcome is not None]
    assert len(done) == len(calls)  # (every call has its outcome)
    return done


def warm_up(system: System, launch: stepping.Launch | None = None) -> None:
    """Compile the GPU kernels that solves of ``system`` use (one tiny RK2 step; for a hosted
    system, the velocity kernels of its products), so that timings that follow measure work."""
    gpu = stepping.gpu_system(system)
    if gpu is None:
        hosted.warm_up(bool(getattr(system, "wall", False)), launch)
        return
    x = gpu.project(np.array(gpu.initial_state(), dtype=float))
    stepping.solve(integrate.explicit_scheme("rk2"), [stepping.Member(gpu, x, 0.0, 1e-12, 1)],
                   integrate.BLOWUP_FACTOR * gpu.monitor_limit, launch)
