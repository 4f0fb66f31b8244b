"""
A scene: a rod swimmer and a vesicle in one fluid
=================================================

Several bodies of any kinds share one fluid as a :class:`parastokes.scene.Scene`: every
evaluation sums the regularized Stokeslets of all their points (each with its own ε), with the
wall's images and the background shear, so each body moves in the flow of the others.
``experiments/quick/scene_rod_passes_vesicle.toml`` puts a vesicle of 162 points 2.5 μm above a
beating rod swimmer (31 nodes) in the shear flow u∞ = (100 z, 0, 0) μm/s, which carries the
vesicle over the rod. The quick variant runs a tenth of the beat.
"""

# %%
# The scene from its configuration file
# -------------------------------------
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LogNorm

import parastokes
from parastokes import config, flow, integrate

experiments = Path(parastokes.__file__).parents[1] / "experiments"  # of the repository
cfg, resolved = config.load(experiments / "quick" / "scene_rod_passes_vesicle.toml")
scene = config.build(cfg, resolved).system
print("bodies:", ", ".join(scene.names), "| Θ:", ", ".join(scene.params))

x0 = scene.initial_state()
t1 = cfg.time.t1
x1 = integrate.propagate(scene, x0, t0=0.0, t1=t1, scheme=cfg.fine.scheme, dt=cfg.fine.dt)
rod0, vesicle0 = scene.blocks(scene.positions(x0))
rod1, vesicle1 = scene.blocks(scene.positions(x1))
gap0 = vesicle0.mean(axis=0) - rod0.mean(axis=0)
gap1 = vesicle1.mean(axis=0) - rod1.mean(axis=0)
print(f"in {t1} s the shear carried the rod {rod1[:, 0].mean() - rod0[:, 0].mean():.2f} μm "
      f"and the vesicle {vesicle1[:, 0].mean() - vesicle0[:, 0].mean():.2f} μm along x;")
print(f"the vesicle gained {gap1[0] - gap0[0]:.3f} μm on the rod (the shear's difference "
      f"across their 2.5 μm: {100.0 * 2.5 * t1:.3f} μm) and rose by {gap1[2] - gap0[2]:.4f} μm")

# %%
# The bodies' own flow
# --------------------
# ``flow.velocity`` evaluates the scene's flow anywhere; ``background=False`` leaves the shear
# out and shows what the bodies add to it.
xs, zs = np.linspace(-4.0, 14.0, 145), np.linspace(0.0, 16.0, 129)
X, Z = np.meshgrid(xs, zs)
points = np.column_stack([X.ravel(), np.zeros(X.size), Z.ravel()])
u = flow.velocity(scene, x1, points, t=t1, background=False).reshape(*X.shape, 3)
speed = np.linalg.norm(u, axis=-1)

fig, ax = plt.subplots(figsize=(8, 6), layout="constrained")
image = ax.pcolormesh(X, Z, speed, norm=LogNorm(speed.max() * 1e-3, speed.max()),
                      shading="gouraud")
ax.streamplot(xs, zs, u[..., 0], u[..., 2], color="white", density=1.3, linewidth=0.5,
              arrowsize=0.6)
near = np.abs(vesicle0[:, 1]) < 0.2
ax.plot(vesicle0[near, 0], vesicle0[near, 2], ".", color="0.8", ms=3, label="vesicle at t = 0")
near = np.abs(vesicle1[:, 1]) < 0.2
ax.plot(vesicle1[near, 0], vesicle1[near, 2], ".", color="magenta", ms=3,
        label=f"vesicle at t = {t1} s")
ax.plot(rod0[:, 0], rod0[:, 2], color="0.8", lw=1.5, label="rod at t = 0")
ax.plot(rod1[:, 0], rod1[:, 2], color="cyan", lw=2.5, label=f"rod at t = {t1} s")
ax.axhline(0.0, color="0.5", lw=4)
ax.set(xlabel="x (μm)", ylabel="z (μm)", aspect="equal",
       title="the bodies' flow in the plane y = 0 (shear left out)")
ax.legend(loc="lower left", fontsize=8)
fig.colorbar(image, label="|u - u∞| (μm/s)", shrink=0.8)
plt.show()
