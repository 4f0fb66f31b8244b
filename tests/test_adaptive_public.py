"""The adaptive steps and the Jacobian's refresh through the public path (``integrate.run(...,
rtol=...)``, a fixed-step ``integrate.run``), so that they hold wherever the controller lives:
on y' = Λ y (two decoupled rates, the exact Jacobian) one ROS2 step multiplies each rate by R(z)
and its embedded linearly implicit Euler step by R_low(z), z = hλ, so the error estimate of
every step, and hence the whole sequence of accepted and rejected steps of the controller
documented in docs/stiff.md (RMS norm, accept at err <= 1, next step h (0.9 / err)^(1/2)
within [0.2 h, 5 h], at most 0.5 h after a rejection, the last step cut to end at t1; the
Jacobian rebuilt every 5 steps tried, its factorization kept within the scheme's ``reuse`` range
of step ratios), is known in closed form. Part of the one-line-bug tests (docs/validation.md,
"Planted one-line bugs (round 5)")."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_stiff import Forced

from parastokes import integrate

GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
#: A controller bug can take ever smaller steps (a factor below 1 after every accepted step): such a
#: run fails here within the limit instead of the suite's 900 s (the runs take about 1 s each).
pytestmark = pytest.mark.timeout(120)

LAM = np.array([-1.0, -40.0])
T1 = 0.5


def _ratios(z: np.ndarray, z_lu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R of a ROS2 step of z = hλ whose stages solve with the factorization of I - γ z_lu (a
    W-method: the LU of an earlier step h_lu kept, docs/stiff.md), and R_low of its embedded
    solution (b_low = (1, 0): x + h k1); z_lu = z is R(z) = 1 + 2z/D - z/D² + z²/(2D²)."""
    d = 1.0 - GAMMA * z_lu
    return 1.0 + 2 * z / d - z / d**2 + z**2 / (2 * d**2), 1.0 + z / d


def _controller(x, t0, t1, h0, rtol, atol):
    """The documented controller on y' = LAM y, by hand: (state, accepted, rejected, last h).
    The Jacobian is rebuilt every 5 steps tried (its LU dropped), and the LU of the step h_lu
    kept while h / h_lu stays within the scheme's ``reuse`` range."""
    t, h, accepted, rejected = t0, min(h0, t1 - t0), 0, 0
    low_ratio, high_ratio = integrate.SCHEMES["ros2"].reuse
    h_lu = None
    while t < t1:
        last = t + h >= t1 * (1 - 1e-14)
        step = t1 - t if last else h
        if (accepted + rejected) % 5 == 0 or not low_ratio <= step / h_lu <= high_ratio:
            h_lu = step
        r, low = _ratios(step * LAM, h_lu * LAM)
        new = r[:, None] * x
        scale = atol + rtol * np.maximum(np.abs(x), np.abs(new))
        err = math.sqrt(np.mean(((new - low[:, None] * x) / scale) ** 2))
        if err <= 1.0:
            t, x, accepted = (t1 if last else t + step), new, accepted + 1
            factor = min(5.0, max(0.2, 0.9 * err ** -0.5))
        else:
            rejected += 1
            factor = max(0.2, min(0.5, 0.9 * err ** -0.5))
        h = step * factor
    return x, accepted, rejected, h


@pytest.mark.parametrize(("h0", "rtol", "atol"), [(1.0, 1e-3, 1e-3), (0.05, 1e-3, 1.0),
                                                   (0.01, 1e-8, 1e-3)])
def test_the_adaptive_steps_are_the_documented_controllers(h0, rtol, atol):
    """Counts of accepted and rejected steps, the last step tried and the state: the controller
    by hand (rejections included: the first step of 0.2 is too large)."""
    system = Forced(lam=tuple(LAM), forced=False)
    x0 = system.initial_state()
    want, accepted, rejected, last = _controller(x0, 0.0, T1, h0, rtol, atol)
    run = integrate.run(system, x0, 0.0, T1, "ros2", h0, rtol=rtol, atol=atol)
    assert (run.n_steps, run.n_rejected) == (accepted, rejected)
    assert run.dt == pytest.approx(last, rel=1e-9)
    np.testing.assert_allclose(run.state, want, rtol=1e-9, atol=1e-300)


def test_rtol_and_atol_each_matter_alone():
    """Each tolerance alone sets the steps: a looser rtol (atol fixed) or a looser atol (rtol
    fixed) takes fewer accepted steps, as the controller by hand says."""
    system = Forced(lam=tuple(LAM), forced=False)
    x0 = system.initial_state()
    counts = {}
    for rtol, atol in ((1e-3, 1e-3), (1e-2, 1e-3), (1e-3, 1e-2)):
        run = integrate.run(system, x0, 0.0, T1, "ros2", 1e-3, rtol=rtol, atol=atol)
        counts[rtol, atol] = run.n_steps
        assert run.n_steps == _controller(x0, 0.0, T1, 1e-3, rtol, atol)[1]
    assert counts[1e-2, 1e-3] < counts[1e-3, 1e-3] > counts[1e-3, 1e-2]


class _Counted(Forced):
    """Forced whose ``stiff_jacobian`` calls are counted."""

    calls: list

    def stiff_jacobian(self, t, x):
        self.calls.append(t)
        return super().stiff_jacobian(t, x)


def test_the_jacobian_is_rebuilt_every_five_steps():
    """docs/stiff.md: ``A`` rebuilt every ``stiff.stepper.REFRESH`` = 5 steps (at steps 0, 5, 10
    of 12), not at every step and not only once."""
    system = _Counted(lam=tuple(LAM), forced=False)
    object.__setattr__(system, "calls", [])
    integrate.run(system, system.initial_state(), 0.0, 1.2, "ros2", 0.1)
    assert system.calls == pytest.approx([0.0, 0.5, 1.0])
