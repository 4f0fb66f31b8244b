"""
A squirmer and a bacterium above a wall
=======================================

Two force- and torque-free swimmers of ``experiments/``, each moved by a mobility solve at every
evaluation (docs/bodies.md, "Rigid and prescribed-motion bodies"):

- a **squirmer** (``squirmer.toml``: Blake's B1 = 1 μm/s, a puller with B2 = 2 μm/s) started
  2.5 radii above the wall and tilted 20° toward it: it turns as it nears the wall and leaves it
  again;
- a **bacterium** (``bacterium_wall.toml``: E. coli's left-handed helical flagellum turning
  counter-clockwise seen from behind at 100 Hz, the head counter-rotating): near a wall the two
  rotations roll it sideways in opposite directions and it swims in circles, clockwise seen from
  above (Lauga et al. 2006), the tighter the closer it is.
"""

# %%
# The squirmer: 14 s of swimming
# ------------------------------
# 200 surface points instead of the config's 400 (``config.load`` takes the ``--set``
# overrides of the command line) and a step of 0.2 s keep this example short.
import itertools
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import parastokes
from parastokes import config, integrate

experiments = Path(parastokes.__file__).parents[1] / "experiments"  # of the repository
cfg, resolved = config.load(experiments / "squirmer.toml", ["model.n_points=200"])
squirmer = config.build(cfg, resolved).system
times = np.linspace(0.0, 14.0, 15)
x = squirmer.initial_state()
path = [x[0, :3]]
for t0, t1 in itertools.pairwise(times):
    x = integrate.propagate(squirmer, x, t0=t0, t1=t1, scheme="rk2", dt=0.2)
    path.append(x[0, :3])
path = np.array(path)
closest = path[:, 2].min()
speed = np.linalg.norm(np.diff(path, axis=0), axis=1) / np.diff(times)
print(f"squirmer: closest approach {closest:.2f} μm (centre), mean speed {speed.mean():.3f} μm/s")

# %%
# Far from any wall the same surface swims at Blake's 2 B1/3, to the error of 200 points (it falls
# with more points: docs/validation.md, "Rigid and prescribed-motion bodies").
cfg, resolved = config.load(experiments / "squirmer.toml", ["model.n_points=200",
                                                            "model.wall=false"])
free = config.build(cfg, resolved).system
free_speed = np.linalg.norm(free.rates(0.0, free.initial_state())[0, :3])
print(f"squirmer in free space: {free_speed:.3f} μm/s (Blake: 2 B1/3 = {2 / 3:.3f} μm/s)")

# %%
# The bacterium: its motion averaged over a turn of the flagellum
# ----------------------------------------------------------------
# Row 0 of a rigid body's state is its pose (centre, orientation quaternion, the flagellum's phase
# φ); ``project`` rebuilds the surface from it. The velocity U and angular velocity Ω averaged over
# evenly spaced phases give the mean motion: a circle of radius ``|U| / Ω_z`` seen from above.
cfg, resolved = config.load(experiments / "bacterium_wall.toml")
bacterium = config.build(cfg, resolved).system


def mean_motion(height, phases=6):
    """(U, Ω) of the bacterium with its head's axis at ``height``, averaged over ``phases``."""
    x = bacterium.initial_state()
    x[0, 2] = height
    rows = []
    for phase in np.linspace(0.0, 2 * np.pi, phases, endpoint=False):
        y = x.copy()
        y[0, 7] = phase
        rows.append(bacterium.rates(0.0, bacterium.project(y))[0])
    mean = np.mean(rows, axis=0)
    return mean[:3], mean[3:6]


heights = [0.9, 1.2, 1.5, 2.5]                       # μm; the head's semi-minor axis is 0.5 μm
motions = [mean_motion(h) for h in heights]
radii = [np.hypot(*u[:2]) / w[2] for u, w in motions]
for h, r in zip(heights, radii, strict=True):
    sense = "counterclockwise" if r > 0 else "clockwise"
    print(f"bacterium at h = {h} μm: circles of radius {abs(r):.0f} μm, {sense} seen from above")

fig, (left, right) = plt.subplots(1, 2, figsize=(9.5, 4), layout="constrained")
for h, (u, w) in zip(heights[:3], motions[:3], strict=True):
    t = np.linspace(0.0, 2 * np.pi / abs(w[2]), 400)        # one full circle
    heading = np.arctan2(u[1], u[0]) + w[2] * t
    speed_xy = np.hypot(u[0], u[1])
    xy = np.cumsum(speed_xy * np.column_stack([np.cos(heading), np.sin(heading)]), axis=0)
    left.plot(xy[:, 0] * t[1], xy[:, 1] * t[1], label=f"head at {h} μm")
left.plot([0], [0], "ko")
left.set(xlabel="x (μm)", ylabel="y (μm)", aspect="equal",
         title="bacterium seen from above (mean motion)")
left.legend(fontsize=8)
right.fill_between([path[:, 0].min() - 1, path[:, 0].max() + 1], -0.3, 0, color="0.7")
right.plot(path[:, 0], path[:, 2], "C0o-", ms=3, label="squirmer's centre, every 1 s")
right.axhline(1.0, color="0.5", ls=":", lw=1, label="one radius: touching")
right.set(xlabel="x (μm)", ylabel="z (μm)", ylim=(-0.3, 3.0),
          title="squirmer, side view: approach and escape")
right.legend(fontsize=8, loc="upper right")
plt.show()
