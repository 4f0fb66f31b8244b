"""
A vesicle in shear flow
=======================

The elastic sphere of the paper's section 5.2: an icosphere of 642 points (level 3) whose edges
are Hookean springs (docs/physics.md (14)), in the shear flow u∞ = (γ̇ z, 0, 0) (15), moving with
the regularized Stokeslets of its spring forces (eq. 6). The paper's capillary number
Ca = μ γ̇ R / κ is 1e-3 (κ = 0.1, μ = 1e-3, γ̇ = 0.1); here γ̇ = 1 makes it ten times larger, so
that the sphere flattens into an ellipsoid inclined to the flow (slowly: the deformation is still
growing after three shear times) while its membrane tank-treads around it at the rotation rate
γ̇/2 of the flow's vorticity.
"""

# %%
# Three shear times, recorded every 0.05
# --------------------------------------
import itertools

import matplotlib.pyplot as plt
import numpy as np

from parastokes import integrate, models

ves = models.vesicle(stiffness=0.1, viscosity=1e-3, shear_rate=1.0)   # Ca = 0.01
x = ves.initial_state()
times = np.linspace(0.0, 3.0, 61)
states = [x]
for t0, t1 in itertools.pairwise(times):
    x = integrate.propagate(ves, x, t0=t0, t1=t1, scheme="rk2", dt=1e-3)
    states.append(x)


def shape(state):
    """Taylor's deformation D = (L - B)/(L + B) and the long axis's angle to the flow (degrees)
    of the vesicle's section in the x-z plane, from its points' second moments."""
    d = state[:, [0, 2]] - state[:, [0, 2]].mean(axis=0)
    values, vectors = np.linalg.eigh(d.T @ d)
    long_axis, short_axis = np.sqrt(values[1]), np.sqrt(values[0])
    angle = np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1])) % 180.0
    return (long_axis - short_axis) / (long_axis + short_axis), angle


deformation, inclination = np.array([shape(s) for s in states[1:]]).T
print(f"deformation D = {deformation[-1]:.4f}, inclination {inclination[-1]:.1f} degrees "
      f"to the flow, area change {ves.monitor(states[-1]):.2e}")

# %%
# A material point on the equator turns about the y axis
# -------------------------------------------------------
# The vertex at the front of the sphere (largest x) is followed through the run; its angle in
# the x-z plane, measured from the centre, falls at about γ̇/2 for a nearly spherical vesicle.
start = np.argmax(states[0][:, 0])
path = np.array([s[start] - s.mean(axis=0) for s in states])
phase = np.unwrap(np.arctan2(path[:, 2], path[:, 0]))
rate = -np.polyfit(times, phase, 1)[0]
print(f"tank-treading rate of the material point: {rate:.3f} (γ̇/2 = {0.5 * ves.shear_rate})")

fig, (left, right) = plt.subplots(1, 2, figsize=(9, 4), layout="constrained")
for state, colour in ((states[0], "0.7"), (states[-1], "C0")):
    near = np.abs(state[:, 1]) < 0.12
    left.plot(state[near, 0], state[near, 2], ".", color=colour, ms=4)
left.plot(path[:, 0], path[:, 2], "C3-", lw=1.5, label="a material point")
left.set(xlabel="x", ylabel="z", aspect="equal",
         title="section y ≈ 0: start (grey), t = 3 (blue)")
left.legend(loc="lower right")
right.plot(times[1:], deformation, label="deformation D")
right.set(xlabel="time", ylabel="D = (L - B)/(L + B)", title="shape in the shear plane")
twin = right.twinx()
twin.plot(times[1:], inclination, "C1--", label="inclination")
twin.set_ylabel("inclination to the flow (degrees)", color="C1")
right.legend(loc="lower right")
plt.show()
