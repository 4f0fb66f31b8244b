"""scheme="auto", round 5 fourth session: the Euler phase where stability alone sets the step,
the W-method's probe that sizes a trial of the exact Jacobian's scheme, and the prices of an
implicit step (parastokes.integrate.auto; docs/stiff.md, "`scheme = "auto"`")."""

from __future__ import annotations

import logging
import math
import re

import numpy as np
import pytest
from ivp import Counted

from parastokes import integrate
from parastokes.integrate import auto
from parastokes.integrate.controller import SAFETY


def test_the_euler_step_and_the_pairs_from_rho():
    """Forward Euler's boundary on the negative real axis is 2 (|1 + z| = 1 at z = -2); its
    step in a phase 0.9 x 2/ρ, rk23's where stability limits it 0.9 x 2.5127/ρ."""
    assert auto.EULER_BOUNDARY == pytest.approx(2.0, abs=1e-9)
    assert auto.euler_step(1e4) == pytest.approx(0.9 * 2.0 / 1e4, rel=1e-9)
    assert auto.euler_step(250.0) == pytest.approx(0.9 * 2.0 / 250.0, rel=1e-9)
    assert auto.pair_step(1e4) == pytest.approx(0.9 * 2.5127 / 1e4, rel=1e-4)


def test_the_cost_of_an_euler_step_and_its_break_even():
    """One evaluation a step, two a chunk of 32 (the rates at its end, a power step): 1.0625;
    the implicit step that breaks even with Euler's h is h C_I / 1.0625."""
    assert auto.EULER_COST == 1.0625 and auto.EULER_EVERY == 32
    assert auto.PAIR_COST == 3.125
    costs = auto.Costs(auto.EULER_COST, 85.0)
    assert costs.break_even(1e-5) == pytest.approx(1e-5 * 80.0, rel=1e-15)


def test_an_euler_chunk_gets_its_share_of_the_tolerance():
    assert auto.euler_share(0.25, 1.0) == 0.25
    assert auto.euler_share(1.0, 1.0) == 1.0
    assert auto.euler_share(3.0, 1.0) == 1.0  # never more than the whole tolerance


def test_the_drift_of_an_euler_chunk_is_half_its_step_times_the_change_of_the_rates():
    """|h/2 (f_end - f_start)| in the controller's norm: the RMS over the entries of
    h/2 Δf / (atol + rtol |x|), here with Δf = (4, -6), h = 0.1, x = (1, 3), rtol = 0.01,
    atol = 0.001: (0.2 / 0.011, -0.3 / 0.031)."""
    system = Counted(lam=(-1.0, -2.0))
    x = np.array([[1.0], [3.0]])
    f0, f1 = np.array([[1.0], [2.0]]), np.array([[5.0], [-4.0]])
    expected = math.sqrt(((0.2 / 0.011) ** 2 + (0.3 / 0.031) ** 2) / 2)
    assert auto.euler_drift(system, x, f0, f1, 0.1, (0.01, 0.001)) == pytest.approx(
        expected, rel=1e-12)
    assert auto.euler_drift(system, x, f1, f1, 0.1, (0.01, 0.001)) == 0.0


def test_the_euler_phase_backs_off_by_its_dropped_work():
    """RETRY x the dropped chunks' evaluations x 2^(n-1) x min(over, ERR_MAX)^(1/2) after the
    n-th failed phase whose last chunk's drift was ``over`` times its share."""
    assert auto.euler_retry(1, 68.0, 1.0) == pytest.approx(auto.RETRY * 68.0, rel=1e-15)
    assert auto.euler_retry(3, 68.0, 1.0) == pytest.approx(auto.RETRY * 68.0 * 4.0, rel=1e-15)
    assert auto.euler_retry(2, 68.0, 25.0) == pytest.approx(auto.RETRY * 68.0 * 2 * 5, rel=1e-15)
    assert auto.euler_retry(1, 68.0, 1e9) == auto.euler_retry(1, 68.0, auto.ERR_MAX)


def test_the_probe_sizes_the_trial_by_the_controllers_law():
    """A probe of error err points to trial x min(1, 0.9 err^(-1/(q+1))); the trial is taken
    there where that is at least PROBE_GAIN x the break-even step, none below."""
    assert auto.probe_step(1.0, 0.5, 2) == 1.0  # accepted: not enlarged
    assert auto.probe_step(1.0, 8.0, 2) == pytest.approx(SAFETY / 2.0, rel=1e-15)
    assert auto.probe_step(2.0, 27.0, 2) == pytest.approx(2.0 * SAFETY / 3.0, rel=1e-15)
    assert auto.probe_step(1.0, 16.0, 3) == pytest.approx(SAFETY / 2.0, rel=1e-15)
    assert auto.probe_step(1.0, math.inf, 2) == 0.0
    gain = auto.PROBE_GAIN
    assert auto.PROBE_GAIN == 1.2
    trial = gain * 0.375  # an accepted probe: the trial itself, exactly PROBE_GAIN x 0.375
    assert auto.sized_trial(trial, 0.5, 2, 0.375) == trial  # at the boundary: taken
    assert auto.sized_trial(trial, 0.5, 2, 0.375 * (1 + 1e-12)) is None
    step = auto.probe_step(1.0, 8.0, 2)
    assert auto.sized_trial(1.0, 8.0, 2, 0.99 * step / gain) == step


def _phase(monkeypatch, drift, share, t1=1.0, rho=1e3):
    """An Euler phase on y' = (-1, -ρ) y from (0, 2) to t1 whose chunks all have ``drift``
    and ``share``: its decisions alone."""
    monkeypatch.setattr(auto, "euler_drift", lambda *args: drift)
    monkeypatch.setattr(auto, "euler_share", lambda *args: share)
    system = Counted(lam=(-1.0, -rho), forced=False)
    phase = auto._Euler(system, rho, np.ones((2, 1)), math.inf, t1, (1e-3, 1e-4), 100.0, True)
    x0 = system.initial_state()
    t, x = phase.run(0.0, x0, t1)
    return phase, t, x, x0


def test_a_chunk_within_its_share_is_kept_and_one_beyond_is_dropped_with_the_first(monkeypatch):
    """drift == share: every chunk kept to the end; drift above it: the second chunk fails and
    both are dropped (the first is checked with the second), the phase ending where it began."""
    phase, t, x, x0 = _phase(monkeypatch, 0.5, 0.5)
    assert t == 1.0 and phase.wants == "" and phase.rejected == 0
    assert phase.steps == pytest.approx(1.0 / auto.euler_step(1e3), rel=0.05)  # ρ converging
    # forward Euler on y' = λ y, λ = (-1, -1e3): y (1 + h λ)^n, h = 1.8e-3 (ρ = 1e3)
    assert np.all(np.abs(x - x0 * np.exp(np.array([[-1.0], [-1e3]]))) < 2e-3)
    phase, t, x, x0 = _phase(monkeypatch, 0.5 * (1 + 1e-12), 0.5)
    assert (t, phase.wants, phase.steps) == (0.0, "pair", 0)
    assert phase.rejected == phase.dropped == 2 * auto.EULER_EVERY and x is x0


def test_no_euler_phase_without_time_for_two_chunks(monkeypatch):
    phase, t, _, _ = _phase(monkeypatch, 0.0, 1.0, t1=2 * auto.EULER_EVERY * auto.euler_step(1e3))
    assert (t, phase.wants, phase.steps, phase.dropped) == (0.0, "end", 0, 0)


def test_auto_runs_euler_where_stability_alone_sets_the_step(caplog, monkeypatch):
    """y' = λ (y - sin t) + cos t, λ = (-1, -1e3), rtol 1e-2 over [0, 2], the implicit steps
    priced out (1e6 evaluations a stage set): stability sets rk23's step, and forward Euler at
    0.9 x 2/ρ (ρ = 1e3 by the power iteration) covers the run in chunks within the tolerance,
    for about half of rk23's evaluations alone, within 3 x rtol of the closed form."""
    monkeypatch.setattr(auto, "STEP_EVALS", {True: 1e6, False: 1e6})
    system = Counted(lam=(-1.0, -1e3))
    with caplog.at_level(logging.INFO, logger="parastokes.integrate.auto"):
        run = integrate.run(system, system.initial_state(), 0.0, 2.0, "auto", 1e-4, rtol=1e-2)
    evaluations = system.calls[0]
    alone = Counted(lam=(-1.0, -1e3))
    integrate.run(alone, alone.initial_state(), 0.0, 2.0, "rk23", 1e-4, rtol=1e-2)
    assert [s for _, s, _ in run.switches] == ["euler"]
    step = float(re.search(r"euler at 0.9 x 2/ρ = (\S+) ", run.switches[0][2]).group(1))
    assert step == pytest.approx(0.9 * 2 / 1e3, rel=1e-3)
    by = {name: (accepted, rejected) for name, accepted, rejected in run.by_scheme}
    assert by["euler"][0] > 0.9 * 2.0 / step and by["euler"][1] == 0
    assert evaluations < 0.55 * alone.calls[0]  # 1.0625/1.8 against 3.125/2.6: 0.49
    assert np.abs(run.state - system.exact(2.0)).max() < 3e-2


def test_the_fitted_prices_recover_known_ones():
    """fit_prices on runs whose CPU is exactly S sets + P products evaluations: S and P."""
    from bench_modules import benchmark_module

    with benchmark_module("adaptive") as ad:
        runs = [{"cpu": (11.0 * s + 1.5 * p) * e, "evaluation": e, "sets": s, "products": p}
                for s, p, e in [(13, 0, 3e-4), (30, 0, 4e-4), (11, 470, 3e-4), (20, 740, 5e-4)]]
        assert ad.fit_prices(runs) == pytest.approx((11.0, 1.5), rel=1e-10)
