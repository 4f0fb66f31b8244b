"""
A body of your own: an elastic ring in shear
============================================

parastokes runs any class that keeps the System contract (docs/contracts.md,
docs/extending.md). Points that push on the fluid and move with it need only their forces:
derive from :class:`parastokes.bodies.base.PointsInShear` and write ``forces(state)``. Here a
ring of beads joined by Hookean springs, started as an ellipse in the shear plane of
u∞ = (γ̇ z, 0, 0): the springs pull it back toward a circle while the shear turns it.
:func:`parastokes.testing.check_system` checks it against the contract, and then integration,
Parareal and the flow anywhere take it as they take the package's own bodies.
"""

# %%
# The body: one method of physics
# -------------------------------
import itertools
from dataclasses import dataclass, field

import matplotlib.pyplot as plt
import numpy as np

from parastokes import flow, integrate, parallel, parareal
from parastokes.bodies.base import PointsInShear, replace_params
from parastokes.fluid import Blocks
from parastokes.testing import check_system


@dataclass(frozen=True)
class ElasticRing(PointsInShear):
    """``n_beads`` beads on a circle of radius ``radius`` in the x-z plane, neighbours joined by
    springs of stiffness ``stiffness``; started stretched by ``aspect`` along x."""

    n_beads: int = 24
    radius: float = 1.0
    aspect: float = 1.5
    stiffness: float = 5.0
    epsilon: float = 0.1
    viscosity: float = 1.0
    shear_rate: float = 1.0
    n_threads: int | None = None
    target_blocks: Blocks | None = field(default=None, init=False)

    def circle(self):
        angle = np.linspace(0.0, 2 * np.pi, self.n_beads, endpoint=False)
        return self.radius * np.column_stack([np.cos(angle), np.zeros_like(angle),
                                              np.sin(angle)])

    def initial_state(self):
        return self.circle() * [self.aspect, 1.0, 1.0 / self.aspect]

    def forces(self, state):
        """Each spring pulls its two beads toward (or apart from) each other."""
        rest = np.linalg.norm(np.roll(self.circle(), -1, axis=0) - self.circle(), axis=1)
        bond = np.roll(state, -1, axis=0) - state
        length = np.linalg.norm(bond, axis=1, keepdims=True)
        pull = self.stiffness * (length - rest[:, None]) * bond / length
        return pull - np.roll(pull, 1, axis=0)

    @property
    def params(self):
        return {"epsilon": self.epsilon, "viscosity": self.viscosity,
                "stiffness": self.stiffness}

    def with_params(self, **theta):
        return replace_params(self, theta)

    monitor_limit = 1.0

    def monitor(self, state):
        """The largest relative change of the distance between neighbours' of the circle."""
        rest = np.linalg.norm(np.roll(self.circle(), -1, axis=0) - self.circle(), axis=1)
        bond = np.linalg.norm(np.roll(state, -1, axis=0) - state, axis=1)
        return float(np.abs(bond / rest - 1.0).max())


ring = ElasticRing()
orders = check_system(ring, horizon=0.5, counts=(16, 32))  # ros34pw2: order 3 from 64 steps
print("contract ok; fitted orders:", ", ".join(f"{k} {v:.2f}" for k, v in orders.items()))

# %%
# Integrate it, and solve it with Parareal
# ----------------------------------------
x0 = ring.initial_state()
times = np.linspace(0.0, 4.0, 9)
states = [x0]
for t0, t1 in itertools.pairwise(times):
    states.append(integrate.propagate(ring, states[-1], t0=t0, t1=t1, scheme="rk2", dt=0.01))

fine = integrate.Propagator(ring, "rk2", 0.01)
coarse = parareal.extrapolated(ring, "euler", 0.05, lagrange={"epsilon": [0.12, 0.13]})
with parallel.make_executor("serial") as ex:
    res = parareal.run(fine, coarse, x0, t0=0.0, t1=4.0, n_slices=8, tol=0.0, max_iterations=3,
                       executor=ex, reference=parareal.serial_solution(fine, x0, 0.0, 4.0, 8))
print("Parareal errors η^k:", ", ".join(f"{e:.1e}" for e in res.errors))
print(f"Parareal's last iterate against the steps above: "
      f"{np.abs(res.states[-1] - states[-1]).max():.1e}")

# %%
# The ring and its flow
# ---------------------
# ``flow.velocity`` takes the ring too: ``PointsInShear`` supplies its point loads.
xs = np.linspace(-2.5, 2.5, 81)
X, Z = np.meshgrid(xs, xs)
points = np.column_stack([X.ravel(), np.zeros(X.size), Z.ravel()])
u = flow.velocity(ring, states[2], points, t=times[2], background=False).reshape(*X.shape, 3)

fig, (left, right) = plt.subplots(1, 2, figsize=(9, 4.2), layout="constrained")
for t, state, colour in zip(times[::2], states[::2], plt.cm.viridis(np.linspace(0, 1, 5)),
                            strict=True):
    closed = np.vstack([state, state[:1]])
    left.plot(closed[:, 0], closed[:, 2], "o-", color=colour, ms=2.5, label=f"t = {t:g}")
left.set(xlabel="x", ylabel="z", aspect="equal", title="relaxing and turning in the shear")
left.legend(fontsize=8)
right.streamplot(xs, xs, u[..., 0], u[..., 2], color=np.hypot(u[..., 0], u[..., 2]),
                 cmap="viridis", density=1.2, linewidth=0.8)
closed = np.vstack([states[2], states[2][:1]])
right.plot(closed[:, 0], closed[:, 2], "k-", lw=2)
right.set(xlabel="x", ylabel="z", aspect="equal", title=f"its own flow at t = {times[2]:g}")
plt.show()
