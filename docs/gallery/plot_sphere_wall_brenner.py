"""
A sphere sedimenting toward a wall, against Brenner
===================================================

A rigid sphere of radius a = 1 μm (400 surface points) falls under its buoyant weight toward the
plane wall z = 0, from a height of three radii (``experiments/sphere_sediments_to_wall.toml``).
Every evaluation of its velocity is a mobility solve: the surface forces, U and Ω such that the
surface moves rigidly and the forces balance the weight (Khatri & Cortez's augmented system, with
the wall's images). Far from the wall it would fall at Stokes' speed U₀ = F / (6πμa) = 1 μm/s;
near it the drag grows by Brenner's (1961) exact factor λ(h/a), so its height h obeys
dh/dt = -U₀ / λ(h/a), solved here with scipy for comparison.
"""

# %%
# The sphere, from its configuration file
# ---------------------------------------
import itertools
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from scipy.integrate import solve_ivp

import parastokes
from parastokes import config, integrate
from parastokes.mobility.wall_series import brenner_perpendicular

experiments = Path(parastokes.__file__).parents[1] / "experiments"  # of the repository
cfg, resolved = config.load(experiments / "sphere_sediments_to_wall.toml")
sphere = config.build(cfg, resolved).system       # a parastokes.kinds.rigid.RigidBody
radius, u_stokes = 1.0, 1.0                      # μm, μm/s (the config's force is 6πμa × 1 μm/s)

# %%
# Fall for 2.5 s with the config's fine solver (RK2, τ = 0.02 s)
# --------------------------------------------------------------
# Row 0 of the state is the pose: the centre, the orientation quaternion and a phase; row 0 of
# the rates is (U, Ω, ...).
times = np.linspace(0.0, 2.5, 26)
x = sphere.initial_state()
heights, speeds = [], []
for t0, t1 in itertools.pairwise(times):
    heights.append(x[0, 2])
    speeds.append(-sphere.rates(t0, x)[0, 2])
    x = integrate.propagate(sphere, x, t0=t0, t1=t1, scheme=cfg.fine.scheme, dt=cfg.fine.dt)
heights.append(x[0, 2])
speeds.append(-sphere.rates(times[-1], x)[0, 2])
heights, speeds = np.array(heights), np.array(speeds)

brenner = solve_ivp(lambda t, h: [-u_stokes / brenner_perpendicular(h[0] / radius)],
                    (0.0, times[-1]), [heights[0]], t_eval=times, rtol=1e-10, atol=1e-12).y[0]
factor = np.array([1.0 / brenner_perpendicular(h / radius) for h in heights])
print(f"height after {times[-1]} s: {heights[-1]:.4f} μm (Brenner: {brenner[-1]:.4f} μm)")
print(f"largest speed error against Brenner: {np.max(np.abs(speeds / factor - 1)):.2%}")

fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.8), layout="constrained")
left.plot(times, brenner, "k-", lw=3, alpha=0.3, label="Brenner (1961), exact")
left.plot(times, heights, "C0o", ms=4, label="parastokes, 400 points")
left.plot(times, heights[0] - u_stokes * times, "k:", label="Stokes, no wall")
left.set(xlabel="time (s)", ylabel="height of the centre h (μm)", ylim=(1.0, 3.05),
         title="sedimenting toward the wall z = 0")
left.legend()
h_curve = np.linspace(1.05, 3.2, 200)
right.plot(h_curve, [1.0 / brenner_perpendicular(h) for h in h_curve], "k-", lw=3, alpha=0.3,
           label="1/λ(h/a), Brenner")
right.plot(heights / radius, speeds / u_stokes, "C0o", ms=4, label="parastokes")
right.set(xlabel="h / a", ylabel="speed / Stokes speed", title="the wall's slowing")
right.legend()
plt.show()
