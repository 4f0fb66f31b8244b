"""Solves that run on the host with their fluid products on the GPU, batched across solves.

A system without device parts (:mod:`.stepping`), such as a rigid or prescribed-motion body
(:mod:`parastokes.kinds.rigid`: every rate evaluation is a mobility solve, GMRES on the fluid
operator) or a scene with one, cannot be stepped by the device kernels; nor can a solve with a
linearly implicit scheme or adaptive steps (:mod:`parastokes.stiff`). Its solves still spend
nearly all their time in products of the fluid operator: the direct sums of
:func:`parastokes.mrs.velocity`, O(N²) for N surface points, against O(N) for GMRES's vectors and
the bodies' own blocks. :func:`run_calls` runs B such solves (the fine solves of a parallel
sweep, the auxiliary solvers of an extrapolated coarse step) each in a thread of its own, the
CPU code unchanged, with their :func:`parastokes.mrs.velocity` calls routed
(:func:`parastokes.mrs.velocity.routed`) to one :class:`Router`. The router lets the threads run
until every one of them waits on a product (or has finished), then evaluates all the waiting
products in one kernel launch per shape (:class:`.velocity.Evaluation`: batched over the solves,
each with its own points, ε, per source where the scene's bodies differ, and μ), hands each
thread its result and lets them run to their next product. All products of one round are of
every body's points at once: the launches are batched over bodies, slices and auxiliary solvers.

The kernels are those of the device path (:mod:`.kernels`, the CPU kernels' pair functions): a
solve's products equal the CPU's to round-off, so its result equals the CPU's up to round-off
propagated through GMRES (its iterates depend continuously on the products); each target's sum
runs in a fixed order whatever the batch, so a solve's result does not depend on what it is
batched with. Everything else (the Runge-Kutta loop, GMRES, the per-body blocks, the checks and
their errors) is the CPU's own code. The host parts of the B solves share the GIL (numpy
releases it in its larger operations; scipy's LAPACK calls are serialized,
:data:`parastokes.mobility.threads.LAPACK`); launches, transfers and the waits run in the calling
thread only.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core import signals
from ..mrs.velocity import routed
from .stepping import Launch
from .velocity import Evaluation

__all__ = ["Router", "run_calls", "warm_up"]

#: ``(True, value)`` or ``(False, exception)`` for one call.
Outcome = tuple[bool, Any]


@dataclass
class _Product:
    """One waiting product: the validated arguments of one :func:`parastokes.mrs.velocity` call
    (unbatched; ``eps`` one number, or one per source), and its result once evaluated."""

    targets: np.ndarray
    sources: np.ndarray
    forces: np.ndarray
    torques: np.ndarray | None
    eps: np.ndarray
    mu: float
    wall: bool
    angular: bool
    result: Any = None
    done: bool = False

    @property
    def fast(self) -> bool:
        """u from forces in free space (as ``mrs.velocity`` decides: torques all zero count as
        none)."""
        return not self.wall and not self.angular and (
            self.torques is None or not np.any(self.torques))

    def key(self) -> tuple:
        """What products of one launch share: shapes, the wall, the kernel, ε per source."""
        return (self.targets.shape[0], self.sources.shape[0], self.wall, self.fast,
                self.eps.ndim == 1)


@dataclass
class Router:
    """Collects the products of the solve threads and evaluates them in batched launches (see
    the module). ``launches`` records, per launch, how many products it held; ``evaluation``
    makes a launch (:class:`.velocity.Evaluation`'s arguments, ``launch()`` and ``result()``;
    a stand-in on the CPU kernels measures the host's share without a device,
    benchmarks/suspension.py)."""

    launch: Launch | None = None
    evaluation: Callable[..., Any] = Evaluation
    launches: list[int] = field(default_factory=list)
    _cond: threading.Condition = field(default_factory=threading.Condition)
    _waiting: list[_Product] = field(default_factory=list)
    _running: int = 0
    _closed: BaseException | None = None

    def product(self, targets: Any, sources: Any, forces: Any, torques: Any, eps: np.ndarray,
                mu: np.ndarray, wall: bool, angular: bool) -> Any:
        """The :data:`parastokes.mrs.velocity.Route` of the solve threads: wait for this
        product's turn in a launch, return its u (or (u, w))."""
        item = _Product(np.asarray(targets, dtype=float), np.asarray(sources, dtype=float),
                        np.asarray(forces, dtype=float),
                        None if torques is None else np.asarray(torques, dtype=float),
                        np.asarray(eps, dtype=float)[0], float(np.asarray(mu)[0]), wall, angular)
        with self._cond:
            if self._closed is not None:
                raise RuntimeError("the GPU router was closed") from self._closed
            self._waiting.append(item)
            self._cond.notify_all()
            while not item.done:
                self._cond.wait()
        if isinstance(item.result, BaseException):
            raise item.result
        return item.result

    def _evaluate(self, items: list[_Product]) -> None:
        """One launch for ``items`` (one :meth:`_Product.key`); each gets its result, or the
        launch's exception."""
        first = items[0]
        try:
            torques = None if first.fast else np.stack([
                np.zeros_like(p.sources) if p.torques is None else p.torques for p in items])
            evaluation = self.evaluation(
                np.stack([p.targets for p in items]), np.stack([p.sources for p in items]),
                np.stack([p.forces for p in items]), torques, np.stack([p.eps for p in items]),
                np.array([p.mu for p in items]), first.wall, self.launch)
            evaluation.launch()
            u, w = evaluation.result()
        except Exception as exc:
            for p in items:  # (one exception per thread: each raises and annotates its own)
                p.result = RuntimeError(f"the GPU launch of {len(items)} products failed: "
                                        f"{type(exc).__name__}: {exc}")
                p.result.__cause__ = exc
            return
        self.launches.append(len(items))
        for b, p in enumerate(items):
            p.result = (u[b], None if w is None else w[b]) if p.angular else u[b]

    def run(self, jobs: Sequence[Callable[[], Any]]) -> list[Outcome]:
        """Run every job in its own thread with its products routed here; evaluate the products
        in rounds until all jobs have finished. Returns their outcomes in order."""
        outcomes: list[Outcome | None] = [None] * len(jobs)

        def work(index: int, job: Callable[[], Any]) -> None:
            try:
                with routed(self.product):
                    outcomes[index] = True, job()
            except BaseException as exc:
                outcomes[index] = False, exc
            finally:
                with self._cond:
                    self._running -= 1
                    self._cond.notify_all()

        threads = [threading.Thread(target=work, args=(i, job), daemon=True,
                                    name=f"parastokes-gpu-host-{i}")
                   for i, job in enumerate(jobs)]
        self._running = len(threads)
        batch: list[_Product] = []
        try:
            for thread in threads:
                thread.start()
            while True:
                with self._cond:
                    while self._running and len(self._waiting) < self._running:
                        self._cond.wait()
                    if not self._running:
                        break
                    batch, self._waiting = self._waiting, []
                signals.honour()  # a stop lost in a finalizer ends the batch here
                groups: dict[tuple, list[_Product]] = {}
                for item in batch:
                    groups.setdefault(item.key(), []).append(item)
                for items in groups.values():
                    self._evaluate(items)
                with self._cond:
                    for item in batch:
                        item.done = True
                    self._cond.notify_all()
        except BaseException as exc:  # (Ctrl-C, SIGTERM): release the waiting threads
            with self._cond:
                self._closed = exc
                for item in [*batch, *self._waiting]:
                    if not item.done:
                        item.result = RuntimeError("the GPU router was closed")
                        item.done = True
                self._cond.notify_all()
            raise
        for thread in threads:
            thread.join()
        done = [outcome for outcome in outcomes if outcome is not None]
        assert len(done) == len(jobs)  # (every job has its outcome)
        return done


def run_calls(calls: Sequence[tuple[Callable[..., Any], tuple]],
              launch: Launch | None = None) -> tuple[list[Outcome], list[int]]:
    """Run ``fn(*args)`` for every call on the host, their fluid products batched on the GPU
    (see the module). Returns the outcomes in call order and the launches' batch sizes."""
    router = Router(launch)
    outcomes = router.run([functools.partial(fn, *args) for fn, args in calls])
    return outcomes, router.launches


def warm_up(wall: bool, launch: Launch | None = None) -> None:
    """Compile the kernels that hosted products use (one tiny launch each, ε per source: the
    rigid surfaces' and the scenes' products): above the ``wall``, the full kernel; in free
    space, the force-only kernel (mobility solves) and the full one (bodies with torques)."""
    points = np.array([[[0.0, 0.0, 1.0], [0.0, 0.5, 1.5]]])
    eps, mu = np.full((1, 2), 0.1), np.ones(1)
    for torques in ([points] if wall else [None, points]):
        evaluation = Evaluation(points, points, points, torques, eps, mu, wall, launch)
        evaluation.launch()
        evaluation.result()
