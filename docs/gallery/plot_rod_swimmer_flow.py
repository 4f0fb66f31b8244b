"""
A rod swimmer and its flow
==========================

The paper's rod swimmer (section 5.1) at a fifth of its length: a 12 μm Kirchhoff rod of 61
nodes 10 μm above the wall, beating with the travelling wave of eq. 36. It swims against its wave
(+x). After three quarters of a beat the flow around it is evaluated on the vertical plane
through it with :func:`parastokes.flow.velocity`, the regularized Stokeslets and rotlets of its
point loads with the wall's images (eq. 6), and drawn with matplotlib.
"""

# %%
# Swim for three quarters of a beat
# ---------------------------------
import itertools

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LogNorm

from parastokes import flow, integrate, models

rod = models.rod_swimmer(n_points=61, length=12.0, epsilon=1.0)  # σ_f = 0.2 μm, ε = 5 σ_f
times = np.linspace(0.0, 0.0375, 7)           # the beat period is 2π/f = 0.05 s
shapes = [rod.initial_state()]
for t0, t1 in itertools.pairwise(times):
    shapes.append(integrate.propagate(rod, shapes[-1], t0=t0, t1=t1, scheme="rk2", dt=1e-6))
t, x = times[-1], shapes[-1]
print(f"largest relative change of the rod's length: "
      f"{max(rod.monitor(s) for s in shapes):.1e} (the run stops at {rod.monitor_limit})")

# %%
# The flow in the plane y = 0
# ---------------------------
# ``flow.velocity(system, state, points, t=...)`` takes any (M, 3) points; below the wall (z < 0)
# there is no fluid. On the wall itself the images cancel the sources (no slip).
xs = np.linspace(-4.0, 16.0, 121)
zs = np.linspace(0.0, 16.0, 97)
X, Z = np.meshgrid(xs, zs)
points = np.column_stack([X.ravel(), np.zeros(X.size), Z.ravel()])
u = flow.velocity(rod, x, points, t=t).reshape(*X.shape, 3)
speed = np.linalg.norm(u, axis=-1)
print(f"largest speed on the plane: {speed.max():.1f} μm/s; on the wall: "
      f"{np.abs(u[0]).max():.1e} μm/s")

fig, (top, ax) = plt.subplots(2, 1, figsize=(8, 8.5), height_ratios=[1, 2.2],
                              layout="constrained")
for ti, shape, colour in zip(times, shapes, plt.cm.plasma(np.linspace(0, 0.9, len(times))),
                             strict=True):
    top.plot(shape[:, 0], shape[:, 1], color=colour, label=f"{1e3 * ti:.2f} ms")
top.set(xlabel="x (μm)", ylabel="y (μm)", ylim=(-0.8, 0.45),
        title="seen from above: the beat (eq. 36)")
top.legend(ncols=7, fontsize=7, loc="lower center")
image = ax.pcolormesh(X, Z, speed, norm=LogNorm(speed.max() * 1e-3, speed.max()),
                      cmap="viridis", shading="gouraud")
ax.streamplot(xs, zs, u[..., 0], u[..., 2], color="white", density=1.4, linewidth=0.6,
              arrowsize=0.7)
pos = rod.positions(x)
ax.plot(pos[:, 0], pos[:, 2], color="cyan", lw=2.5, label="rod")
ax.axhline(0.0, color="0.5", lw=4)
ax.set(xlabel="x (μm)", ylabel="z (μm), distance to the wall", aspect="equal",
       title=f"rod swimmer at t = {t} s: speed and streamlines in the plane y = 0")
fig.colorbar(image, label="|u| (μm/s)")
plt.show()
