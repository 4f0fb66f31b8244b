"""scheme="auto": explicit while the accuracy sets the step, implicit once stiffness does, and
back (parastokes.integrate.auto)."""

from __future__ import annotations

import dataclasses
import logging
import math
import pickle

import numpy as np
import pytest
from ivp import Counted

from parastokes import integrate
from parastokes.integrate import auto
from parastokes.integrate.schemes import real_stability_boundary


@dataclasses.dataclass(frozen=True)
class Calming(Counted):
    """The stiff rate λ_2 = -1e4 until ``calm_at``, -1 after (y' = λ(t) (y - sin t) + cos t)."""

    calm_at: float = 0.3

    def rates(self, t, x):
        self.calls[0] += 1
        lam = np.array([[-1.0], [-1e4 if t < self.calm_at else -1.0]])
        return lam * (x - math.sin(t)) + math.cos(t)


def _run(system, rtol, scheme="auto", t1=1.0):
    return integrate.run(system, system.initial_state(), 0.0, t1, scheme, 1e-4, rtol=rtol)


def test_a_stiff_problem_switches_to_implicit_and_takes_far_fewer_steps(caplog):
    with caplog.at_level(logging.INFO, logger="parastokes.integrate.auto"):
        run = _run(Counted(lam=(-1.0, -1e4)), 1e-3, t1=0.3)
    explicit = _run(Counted(lam=(-1.0, -1e4)), 1e-3, "rk45", t1=0.3)
    assert [name for _, name, _ in run.switches] == [auto.IMPLICIT]
    t, _, reason = run.switches[0]
    assert 0 < t < 0.05 and "stiff: h ρ > 0.9 x rk45's stability boundary 3.31" in reason
    assert f"auto: {auto.IMPLICIT} from t={t:.10g}, stiff" in caplog.text
    assert run.n_steps + run.n_rejected < (explicit.n_steps + explicit.n_rejected) / 20
    by = {name: (accepted, rejected) for name, accepted, rejected in run.by_scheme}
    assert by["rk45"][0] >= auto.STIFF_STEPS  # explicit until the test has seen enough steps
    assert sum(a for a, _ in by.values()) == run.n_steps
    error = np.abs(run.state - Counted(lam=(-1.0, -1e4)).exact(0.3)).max()
    assert error < 3e-3


def test_a_nonstiff_problem_stays_explicit_within_its_tolerance():
    system = Counted(lam=(-1.0, -2.0))
    for rtol in (1e-3, 1e-6):
        run = _run(system, rtol)
        assert run.switches == () and dict((n, a) for n, a, _ in run.by_scheme)[auto.IMPLICIT] == 0
        assert np.abs(run.state - system.exact(1.0)).max() < 3 * rtol


def test_auto_switches_back_once_the_stiffness_is_gone():
    run = _run(Calming(lam=(-1.0, -1e4)), 1e-4, t1=2.0)
    assert [name for _, name, _ in run.switches] == [auto.IMPLICIT, "rk45"]
    (t_stiff, _, _), (t_calm, _, reason) = run.switches
    # BACK_STEPS implicit steps after the stiffness ends (t = 0.3), the large ones of ros34pw2
    assert t_stiff < 0.05 and 0.3 < t_calm < 1.5 and reason.startswith("not stiff")


def test_auto_is_deterministic_and_propagators_take_it():
    system = Counted(lam=(-1.0, -1e4))
    a, b = _run(system, 1e-4), _run(system, 1e-4)
    assert np.array_equal(a.state, b.state)
    assert (a.n_steps, a.n_rejected, a.switches) == (b.n_steps, b.n_rejected, b.switches)
    fine = integrate.Propagator(system, "auto", 1e-4, rtol=1e-4)
    assert np.array_equal(pickle.loads(pickle.dumps(fine))(0.0, 1.0, system.initial_state()),
                          a.state)
    assert np.array_equal(integrate.propagate(system, system.initial_state(), 0.0, 1.0, "auto",
                                              1e-4, rtol=1e-4), a.state)


def test_auto_needs_rtol():
    system = Counted()
    with pytest.raises(ValueError, match=r"^rtol: required by the scheme 'auto'"):
        integrate.run(system, system.initial_state(), 0.0, 1.0, "auto", 0.1)
    with pytest.raises(ValueError, match=r"^rtol: required by the scheme 'auto'"):
        integrate.Propagator(system, "auto", 0.1)
    with pytest.raises(ValueError, match=r"^rtol: required by the scheme 'auto'"):
        integrate.Propagator(system, "auto", 0.1, atol=1e-3)
    with pytest.raises(ValueError, match=r"^scheme: 'auto' chooses its own steps"):
        integrate.step(system, "auto", 0.0, system.initial_state(), 0.1)


def test_the_eigenvalue_estimate_of_a_step_on_a_linear_problem():
    """On y' = λ y the two last stages of Dormand-Prince differ by λ times their arguments'
    difference: ρ = |λ| exactly (to round-off)."""
    system = Counted(lam=(-300.0,), forced=False)
    stepper = integrate.explicit.PairStepper(system, integrate.SCHEMES["rk45"])
    stepper.step_with_estimate(0.0, np.array([[1.0]]), 1e-3)
    rho, _ = auto.pair_rho(stepper.scheme, stepper.k, 1e-3)
    assert rho == pytest.approx(300.0, rel=1e-9)
    assert real_stability_boundary(stepper.scheme) == pytest.approx(3.3066, abs=2e-4)


def test_auto_takes_no_fixed_steps_anywhere():
    """'auto' is adaptive only: a fixed-step run and the stability search refuse it in one line
    (integrate.schemes.fixed_step_scheme), before a step is taken."""
    system = Calming()
    with pytest.raises(ValueError, match="rtol: required by the scheme 'auto'"):
        integrate.run(system, system.initial_state(), 0.0, 1.0, "auto", 1e-3)
    with pytest.raises(ValueError, match="'auto' takes adaptive steps only"):
        integrate.is_stable(system, "auto", 1e-3, 1e-2)
    assert system.calls[0] == 0
    assert integrate.schemes.fixed_step_scheme("rk2") is integrate.SCHEMES["rk2"]
