"""The System contract (docs/contracts.md) through ``parastokes.testing.check_system``: every
registered body kind, a user's body, and broken systems that each part of the check must catch."""

from __future__ import annotations

import dataclasses

import pytest
from documented import check
from rods import helix_rod
from user_body import SedimentingCloud

from parastokes import integrate
from parastokes.registry import kinds as registry
from parastokes.testing import check_system

#: Kinds whose every evaluation is a linear solve: their full check is slow (tests/test_rigid.py
#: runs it with fewer steps in the default run).
SOLVED_KINDS = {"rigid", "squirmer", "bacterium"}
#: Kinds whose fitted orders (forward Euler, RK2, RK4) docs/validation.md section 3 prints:
#: ``[physics_orders]`` of docs/numbers.toml.
PRINTED_ORDERS = {"vesicle"}
SCHEMES = ("euler", "rk2", "rk4")


@pytest.mark.parametrize("name", [
    pytest.param(name, marks=pytest.mark.slow) if name in SOLVED_KINDS else name
    for name in sorted(registry.BUILTIN)
])
def test_every_registered_kind_keeps_the_contract(name):
    system, state, horizon = registry.get(name).example()
    orders = check_system(system, state, horizon=horizon)
    if name in PRINTED_ORDERS:
        check("physics_orders", name, [orders[s] for s in SCHEMES])


def test_a_rod_with_3d_frame_dynamics_keeps_the_contract():
    """The helix-relaxing rod: w changes direction, so RK4's order needs the RKMK brackets."""
    rod = helix_rod()
    x = integrate.propagate(rod, rod.initial_state(), 0.0, 2.0, "rk2", 0.05)
    orders = check_system(rod, x, horizon=1.0)
    check("physics_orders", "rod", [orders[s] for s in SCHEMES])


def test_a_users_body_keeps_the_contract():
    check_system(SedimentingCloud(n_points=16), horizon=2.0)


# ---- each part of the check catches its own defect ----------------------------------------------
@dataclasses.dataclass(frozen=True)
class TwoParamsAtOnce(SedimentingCloud):
    def with_params(self, **theta):
        return dataclasses.replace(super().with_params(**theta), weight=2.0)


@dataclasses.dataclass(frozen=True)
class HeavyPickle(SedimentingCloud):
    table: tuple = tuple(range(2000))


@dataclasses.dataclass(frozen=True)
class DriftingProjection(SedimentingCloud):
    def project(self, state):
        return state * (1.0 + 1e-9)


@dataclasses.dataclass(frozen=True)
class LaggingAdvance(SedimentingCloud):
    """An advance with an O(dt²) error of its own: x + dt r + dt² (1, 1, 1)."""

    def advance(self, state, rates, dt):
        return state + dt * rates + dt * dt


@dataclasses.dataclass(frozen=True)
class InPlaceAdvance(SedimentingCloud):
    def advance(self, state, rates, dt):
        state += dt * rates
        return state.copy()


@dataclasses.dataclass(frozen=True)
class WrongCompiledLoop(SedimentingCloud):
    """A compiled loop that takes one step fewer than asked."""

    def wrong_steps(self, scheme, x, t0, dt, n, limit, stop_above):
        return integrate._python_steps(self, scheme, x, t0, dt, n - 1, limit, stop_above)


@pytest.fixture(autouse=True, scope="module")
def _register_the_wrong_loop():
    """A compiled loop is registered for an exact type (parastokes.registry.loops)."""
    from parastokes.registry import loops

    loops.register(WrongCompiledLoop, lambda system: system.wrong_steps)


@pytest.mark.parametrize(
    ("system", "part"),
    [
        (TwoParamsAtOnce(n_points=8), "with_params"),
        (HeavyPickle(n_points=8), "pickle"),
        (DriftingProjection(n_points=8), "project"),
        (InPlaceAdvance(n_points=8), "rates: advance modified its inputs"),
        (WrongCompiledLoop(n_points=8), "compiled loop"),
    ],
    ids=["with_params", "pickle", "project", "advance", "compiled"],
)
def test_each_broken_part_is_named(system, part):
    with pytest.raises(AssertionError, match=f"check_system\\({type(system).__name__}\\): {part}"):
        check_system(system, horizon=2.0)


def test_a_scheme_that_loses_its_order_is_named():
    """An advance that is only first-order accurate (it drops half of the rates' change along the
    step) keeps every scheme at order 1: the check names the first scheme of higher order."""
    with pytest.raises(AssertionError, match=r"order: rk2: fitted order 1\.\d+"):
        check_system(LaggingAdvance(n_points=8), horizon=2.0)


# ---- the typed contracts (parastokes.core.contracts)
# ------------------------------------------------
def test_the_packages_parts_satisfy_the_protocols():
    from parastokes import parareal
    from parastokes.core import contracts

    for name in sorted(registry.BUILTIN):
        system, _, _ = registry.get(name).example()
        assert isinstance(system, contracts.System)
        fine = integrate.Propagator(system, "rk2", 1e-3)
        assert isinstance(fine, contracts.Propagator)
        assert not isinstance(fine, contracts.CoarseSolver)
    coarse = parareal.extrapolated(system, "euler", 1e-2, richardson={"m": 1, "r": 0.5})
    assert isinstance(coarse, contracts.CoarseSolver) and coarse.n_auxiliary == 2
    assert isinstance(SedimentingCloud(), contracts.System)


def test_a_system_missing_members_is_named():
    class Half:
        def rates(self, t, x):
            return x

    with pytest.raises(AssertionError, match=r"members: missing advance, initial_state"):
        check_system(Half())


@pytest.mark.parametrize(
    ("n_auxiliary", "workers", "ok"),
    [(4, 4, True), (5, 4, False), (8, 1, True), (8, None, True)],
)
def test_the_rule_n_g_at_most_n_c_lives_in_one_place(n_auxiliary, workers, ok):
    """Config checks, the MPI build check and parareal.run all word it through this function."""
    from parastokes.core.contracts import oversubscription

    problem = oversubscription(n_auxiliary, workers)
    assert (problem is None) == ok
    if not ok:
        assert f"N_G = {n_auxiliary}" in problem and f"N_c = {workers}" in problem


@dataclasses.dataclass(frozen=True)
class StiffCloud(SedimentingCloud):
    """The cloud with every point tied to its start by a spring relaxing at the rate 1e4: the
    default horizon (from the sedimentation speed) is far beyond the schemes' stability limit."""

    def rates(self, t, state):
        return super().rates(t, state) - 1e4 * (state - self.initial_state())


def test_a_stiff_system_is_checked_on_a_stable_horizon_and_a_given_unstable_one_is_named():
    """No blow-up escapes as such: the default horizon (about 0.3 here, where every scheme blows
    up) is shortened until all are stable, where the spring pins the points and the order check
    names the round-off; a horizon given by the user is kept and its blow-up named."""
    with pytest.raises(AssertionError, match=r"order: euler: the errors are at round-off level"
                       r" \(steps \[16, 32, 64, 128\] on a horizon of 0\.00"):
        check_system(StiffCloud(n_points=16))
    with pytest.raises(AssertionError, match=r"order: .* blows up .* pass a shorter horizon"):
        check_system(StiffCloud(n_points=16), horizon=1.0)
