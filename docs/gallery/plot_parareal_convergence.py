"""
Parareal convergence and the speedup report
===========================================

The demo's rod swimmer (a fifth of the paper's rod at its grid spacing, section 5.1) solved by
Parareal (Algorithm 1) on 8 slices, with the coarse solver of the demo: forward Euler at
τ_c = 16 τ_f, a step that is unstable at ε⁰ = 5 σ_f but stable at the Lagrange nodes
ε = 5.6 σ_f and 5.65 σ_f, extrapolated back to ε⁰ (eq. 18). The serial fine solution is the
reference, so the true error η^k of eq. 34 is known next to the increment η̃^k that a run
without it stops on.
"""

# %%
# The fine and the coarse propagators
# -----------------------------------
import matplotlib.pyplot as plt
import numpy as np

from parastokes import integrate, models, parallel, parareal

rod = models.rod_swimmer(n_points=61, length=12.0, epsilon=1.0)  # σ_f = 0.2 μm, ε⁰ = 5 σ_f
x0 = rod.initial_state()
fine = integrate.Propagator(rod, "rk2", 1e-6)
coarse = parareal.extrapolated(rod, "euler", 16e-6, lagrange={"epsilon": [1.12, 1.13]})

# %%
# Parareal against the serial fine solution
# -----------------------------------------
# The serial executor runs the slices one after the other and gives the same numbers, bit for
# bit, as a pool of processes (``parallel.make_executor("processes", workers=8)``, which needs
# the ``if __name__ == "__main__":`` guard in a script).
t1, n_slices = 8e-3, 8
reference = parareal.serial_solution(fine, x0, 0.0, t1, n_slices)
with parallel.make_executor("serial") as ex:
    res = parareal.run(fine, coarse, x0, t0=0.0, t1=t1, n_slices=n_slices, tol=0.0,
                       max_iterations=4, executor=ex, reference=reference,
                       positions=rod.positions, project=rod.project)

for k, (increment, error) in enumerate(zip(res.increments, res.errors, strict=True), start=1):
    print(f"k = {k}: increment {increment:.3e}, error {error:.3e}")

# %%
# The speedup report
# ------------------
# ``res.speedup()`` gives eq. 14 with the measured γ_G/γ_F (the cost of a coarse step over a
# fine one, per slice) and the bound of eq. 15; the measured speedup of a serial executor is of
# course below 1. :func:`parastokes.parareal.predict` carries the measured ratio over to more
# cores, one slice per core, at the iteration count that reaches the error wanted.
report = res.speedup()
print(f"gamma_G / gamma_F = {report['gamma_ratio']:.4f}")
print(f"theoretical speedup (eq. 14) after K = {res.iterations}: {report['theoretical']:.3f}, "
      f"bound (eq. 15): {report['bound']:.3f}")
k_needed = next(k for k, e in enumerate(res.errors, start=1) if e < 1e-6)
cores = [2, 4, 8, 16, 32, 64]
predicted = parareal.predict(report["gamma_ratio"], k_needed, cores)

fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
k = np.arange(1, res.iterations + 1)
left.semilogy(k, res.errors, "o-", label=r"error $\eta^k$ (eq. 34)")
left.semilogy(k, res.increments, "s--", label=r"increment $\tilde\eta^k$")
left.set(xlabel="iteration k", ylabel="relative error at T", xticks=k,
         title=f"{n_slices} slices, N_G = 2 auxiliary solvers")
left.legend()
right.plot(cores, [row[1] for row in predicted], "o-")
right.set_xscale("log", base=2)
right.set_xticks(cores, [str(c) for c in cores])
right.minorticks_off()
right.set(xlabel="cores N_c (one slice each)", ylabel="speedup (eq. 14)",
          title=f"predicted for η < 1e-6 (N_it = {k_needed})")
plt.show()
