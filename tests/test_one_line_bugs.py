"""Direct tests of round-4 arithmetic, each failing when one line is wrong (issue 50, "Tests that
catch one-line bugs"; the campaign that checked them: docs/validation.md, "Planted one-line bugs
(round 5)"): the unit of the measured step cost, staging under a recorded stop, the repulsion's
forces and torques, and the placement of suspensions. The hosted GPU launches mixing viscosities
and regularizations are in tests/test_gpu_mixed_launches.py (numba's CUDA simulator)."""

from __future__ import annotations

import math
import os
import signal
import types

import numpy as np
import pytest

from parastokes.coarse import step_cost
from parastokes.config import placement
from parastokes.core import files, signals
from parastokes.output import rundir
from parastokes.scene.repulsion import Repulsion, repulsion_loads


# ---- the unit of the measured step cost (coarse/step_cost.py) ----------------------------------
class _CpuClock:
    """``time.process_time`` of a fake process: advanced by hand by the fakes below."""

    def __init__(self) -> None:
        self.now = 0.0

    def process_time(self) -> float:
        return self.now


class _TimedSystem:
    """A System whose rate evaluation costs ``evaluation`` CPU seconds on ``clock``."""

    def __init__(self, clock: _CpuClock, evaluation: float) -> None:
        self.clock, self.evaluation = clock, evaluation

    def initial_state(self) -> np.ndarray:
        return np.zeros(3)

    def rates(self, t: float, x: np.ndarray) -> np.ndarray:
        self.clock.now += self.evaluation
        return np.zeros_like(x)


def _fake_integrate(clock: _CpuClock, per_step: float, calls: list) -> types.SimpleNamespace:
    """``integrate.run`` costing ``per_step`` CPU seconds per step of ``dt`` (recorded)."""

    def run(system, x0, t0, t1, scheme, dt, rtol=None, atol=None):
        calls.append((t0, t1, scheme, dt, rtol, atol))
        clock.now += per_step * round((t1 - t0) / dt)

    return types.SimpleNamespace(run=run, SCHEMES=step_cost.integrate.SCHEMES)


@pytest.mark.parametrize(("per_step", "evaluation", "expected"),
                         [(0.03, 0.002, 15.0), (3e-4, 1e-4, 3.0)])
def test_the_step_cost_is_cpu_seconds_per_step_over_one_evaluation(monkeypatch, per_step,
                                                                     evaluation, expected):
    """The unit is one evaluation of the rates: a step of 0.03 s against an evaluation of 2 ms
    is 15 evaluations, whatever the number of steps and the evaluations timed (not the time of
    the whole span, nor of PROBE_EVALUATIONS evaluations, nor milliseconds)."""
    clock, calls = _CpuClock(), []
    monkeypatch.setattr(step_cost, "time", clock)
    monkeypatch.setattr(step_cost, "integrate", _fake_integrate(clock, per_step, calls))
    system = _TimedSystem(clock, evaluation)
    got = step_cost.measured_evaluations(system, "ros2", 1.0, 0.8, 8, rtol=1e-5, atol=1e-7)
    assert got == pytest.approx(expected, rel=1e-12)
    # one untimed step of dt = span / steps, then the span from t0 with the tolerances
    assert calls[0][:4] == (1.0, pytest.approx(1.1), "ros2", pytest.approx(0.1))
    assert calls[1] == (1.0, pytest.approx(1.8), "ros2", pytest.approx(0.1), 1e-5, 1e-7)


def test_the_step_cost_is_measured_over_the_probe_steps_of_the_first_slice(monkeypatch):
    """An implicit or adaptive scheme is timed over the first slice ((t1 - t0) / n_slices), or
    its first ``probe`` steps (the span scaled to them); a fixed-step explicit one is its stages,
    untimed."""
    seen = []

    def measured(system, scheme, t0, span, steps, rtol, atol):
        seen.append((system, scheme, t0, span, steps, rtol, atol))
        return 7.0

    monkeypatch.setattr(step_cost, "measured_evaluations", measured)
    monkeypatch.setattr(step_cost, "build_system", lambda cfg, resolved: "body")
    cfg = types.SimpleNamespace(time=types.SimpleNamespace(t0=2.0, t1=6.0),
                                parareal=types.SimpleNamespace(n_slices=4))
    assert step_cost.evaluations_per_step(cfg, None, "rk4", 100) == 4.0
    assert step_cost.evaluations_per_step(cfg, None, "rk2", 100, rtol=1e-4) == 7.0
    assert seen.pop() == ("body", "rk2", 2.0, pytest.approx(1.0), 100, 1e-4, None)
    step_cost.evaluations_per_step(cfg, None, "ros2", 100, probe=20)
    assert seen.pop() == ("body", "ros2", 2.0, pytest.approx(0.2), 20, None, None)
    step_cost.evaluations_per_step(cfg, None, "ros2", 10, probe=20)  # fewer steps than the probe
    assert seen.pop()[3:5] == (pytest.approx(1.0), 10)


# ---- staging under a recorded stop (core/signals.py, core/files.py, output/rundir.py) ---------
@pytest.fixture
def recorded():
    """Record a stop as the handlers do when their raise is lost (in a finalizer); forgotten
    after the test."""

    def record(signum: int) -> None:
        handler = signals.interrupt if signum == signal.SIGINT else signals.terminate
        with pytest.raises(KeyboardInterrupt):
            handler(signum)

    yield record
    signals.clear()


def test_honour_raises_the_stop_recorded_and_nothing_without_one(recorded):
    signals.honour()  # none asked for
    recorded(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt) as info:
        signals.honour()
    assert not isinstance(info.value, signals.Terminated)  # Ctrl-C exits 130, not 143
    for signum in (signal.SIGTERM, signal.SIGHUP):
        recorded(signum)  # the latest stop replaces the one before
        with pytest.raises(signals.Terminated) as info:
            signals.honour()
        assert info.value.signum == signum
        with pytest.raises(signals.Terminated):
            signals.honour()  # raised again at every safe point until cleared
    signals.clear()
    signals.honour()


def test_the_unraisable_hook_drops_only_a_recorded_stop(recorded):
    passed = []
    hook = signals.quiet(passed.append)

    def unraisable(exc):
        return types.SimpleNamespace(exc_value=exc)

    hook(unraisable(KeyboardInterrupt()))  # not recorded: shown
    recorded(signal.SIGTERM)
    hook(unraisable(signals.Terminated(signal.SIGTERM)))  # recorded: dropped
    error = unraisable(ValueError("a finalizer's own error"))
    hook(error)  # shown, stop or no stop
    assert [type(u.exc_value) for u in passed] == [KeyboardInterrupt, ValueError]


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_recorded_while_files_are_staged_moves_none_and_leaves_no_temporary(
        tmp_path, recorded, signum):
    """``claim_files``'s staging (``flow``'s .h5 + .xdmf, ``tune``'s .toml + .json): a stop
    recorded while they are written moves neither; the old pair stays whole, no .tmp is left."""
    old = {tmp_path / "a.h5": b"old h5", tmp_path / "a.xdmf": b"old xdmf"}
    for path, data in old.items():
        path.write_bytes(data)
    with pytest.raises(KeyboardInterrupt):
        with files.staged() as staging:
            staging.write(tmp_path / "a.h5", lambda handle: handle.write(b"new h5"))
            recorded(signum)  # between the two files
            staging.write(tmp_path / "a.xdmf", lambda handle: handle.write(b"new xdmf"))
    assert {p: p.read_bytes() for p in old} == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5", "a.xdmf"]
    signals.clear()
    with files.staged() as staging:  # no stop: both move in
        staging.write(tmp_path / "a.h5", lambda handle: handle.write(b"new h5"))
        staging.write(tmp_path / "a.xdmf", lambda handle: handle.write(b"new xdmf"))
    assert (tmp_path / "a.h5").read_bytes() == b"new h5"
    assert (tmp_path / "a.xdmf").read_bytes() == b"new xdmf"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5", "a.xdmf"]


def test_a_writer_that_left_no_data_moves_nothing(tmp_path):
    (tmp_path / "a.h5").write_bytes(b"old")
    with pytest.raises(files.FileWriteError, match="no data"):
        with files.staged() as staging:
            staging.write(tmp_path / "b.json", lambda handle: handle.write(b"{}"))
            staging.temporary(tmp_path / "a.h5").write_bytes(b"")  # its writer failed silently
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5"]
    assert (tmp_path / "a.h5").read_bytes() == b"old"


def _finished_run(out, names=("summary.json", "trajectory.h5", "error_decay.png")):
    with rundir.claim(out, resume=False, overwrite=False) as directory:
        for name in names:
            (directory.staging / name).write_text(f"old {name}")
        directory.commit()


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_a_stop_recorded_before_a_runs_commit_keeps_the_old_results_whole(tmp_path, recorded,
                                                                          signum):
    out = tmp_path / "run"
    _finished_run(out)
    before = {p.name: p.read_text() for p in out.iterdir() if p.is_file()}
    with pytest.raises(KeyboardInterrupt):
        with rundir.claim(out, resume=False, overwrite=True) as directory:
            for name in ("summary.json", "trajectory.h5"):  # no figure this time
                (directory.staging / name).write_text(f"new {name}")
            recorded(signum)
            directory.commit()
    after = {p.name: p.read_text() for p in out.iterdir() if p.is_file()}
    assert after == before  # not one new file in, not the old figure removed, the lock released
    assert not (out / rundir.STAGING).exists()  # the partial results dropped
    signals.clear()
    with rundir.claim(out, resume=False, overwrite=True) as directory:  # no stop: replaced whole
        for name in ("summary.json", "trajectory.h5"):
            (directory.staging / name).write_text(f"new {name}")
        assert directory.commit() == ["summary.json", "trajectory.h5"]
    assert sorted(p.name for p in out.iterdir()) == [rundir.MANIFEST, "summary.json",
                                                      "trajectory.h5"]
    assert (out / "summary.json").read_text() == "new summary.json"


def test_a_commit_cut_short_is_completed_by_the_next_claim(tmp_path):
    """A stop after the commit's record is written (a SIGKILL mid-move): the next claim moves the
    rest, so the directory holds the new results whole, never a mixture."""
    out = tmp_path / "run"
    _finished_run(out)
    staging = out / rundir.STAGING
    staging.mkdir()
    for name in ("summary.json", "trajectory.h5"):
        (staging / name).write_text(f"new {name}")
    rundir._write_names(staging / rundir._COMMIT, ["summary.json", "trajectory.h5"])
    os.replace(staging / "summary.json", out / "summary.json")  # the move cut short
    with rundir.locked(out):
        pass
    assert (out / "trajectory.h5").read_text() == "new trajectory.h5"
    assert (out / "summary.json").read_text() == "new summary.json"
    assert not (out / "error_decay.png").exists() and not staging.exists()


# ---- the repulsion's forces and torques (scene/repulsion.py) -----------------------------------
def _surface(points, center):
    """A surface that is not a sphere: lab-frame ``points`` about the reference point ``center``."""
    return types.SimpleNamespace(points=np.asarray(points, dtype=float),
                                 center=np.asarray(center, dtype=float))


def _sphere_surface(center, radius=1.0, n=42):
    from parastokes.kinds.rigid import RigidBody, Sphere

    body = RigidBody(shape=Sphere(radius, n), epsilon=0.2, position=tuple(center))
    return body.surface(0.0, body.initial_state())


def _moment(force, torque, surfaces, origin):
    """The total moment about ``origin`` of the loads (force at each reference point plus its
    torque about it)."""
    centers = np.array([s.center for s in surfaces])
    return np.sum(np.cross(centers - origin, force) + torque, axis=0)


def test_torques_are_lever_arm_cross_force_at_the_contact_points():
    """By hand: body 0's closest point (1, 0, 0), body 1's (1, 0.3, 0) (gap 0.3 of the range 0.5):
    F = F0 (1 - 0.3/0.5)^2 = 0.32 F0, body 0 pushed along -y at (1, 0, 0), body 1 along +y at
    (1, 0.3, 0); torques (p - c) x F about each reference point."""
    law = Repulsion(range=0.5, force=2.0)
    a = _surface([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]], [0.0, 0.0, 0.0])
    b = _surface([[1.0, 0.3, 0.0], [3.0, 2.3, 0.0], [2.0, 2.3, 1.0]], [2.0, 1.3, 0.0])
    force, torque = repulsion_loads([a, b], law)
    m = 2.0 * (1 - 0.3 / 0.5) ** 2
    np.testing.assert_allclose(force, [[0.0, -m, 0.0], [0.0, m, 0.0]], rtol=1e-12, atol=1e-15)
    # (1, 0, 0) x (0, -m, 0) = (0, 0, -m); (-1, -1, 0) x (0, m, 0) = (0, 0, -m)
    np.testing.assert_allclose(torque, [[0.0, 0.0, -m], [0.0, 0.0, -m]], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(_moment(force, torque, [a, b], np.zeros(3)), 0.0, atol=1e-14)


def test_a_sphere_pushes_another_body_at_its_closest_point_and_feels_no_torque():
    law = Repulsion(range=0.5, force=1.0)
    ball = _sphere_surface((0.0, 0.0, 0.0), radius=0.5)
    other = _surface([[0.0, 0.7, 0.0], [0.0, 2.7, 0.0], [1.0, 1.7, 0.0]], [1.0, 0.7, 0.0])
    for order in ((ball, other), (other, ball)):
        force, torque = repulsion_loads(list(order), law)
        f_ball, f_other = (force[0], force[1]) if order[0] is ball else (force[1], force[0])
        t_ball, t_other = (torque[0], torque[1]) if order[0] is ball else (torque[1], torque[0])
        m = 1.0 * (1 - 0.2 / 0.5) ** 2  # gap 0.7 - 0.5
        np.testing.assert_allclose(f_ball, [0.0, -m, 0.0], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(f_other, [0.0, m, 0.0], rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(t_ball, 0.0)
        np.testing.assert_allclose(t_other, np.cross([-1.0, 0.0, 0.0], [0.0, m, 0.0]),
                                   rtol=1e-12, atol=1e-15)


def test_two_spheres_of_different_radii_feel_the_law_at_their_gap():
    law = Repulsion(range=0.5, force=3.0)
    for gap in (0.05, 0.2, 0.45):
        a, b = _sphere_surface((0.0, 0.0, 0.0), 1.0), _sphere_surface((0.0, 0.0, 1.5 + gap), 0.5)
        force, torque = repulsion_loads([a, b], law)
        np.testing.assert_allclose(force[1], [0.0, 0.0, 3.0 * (1 - gap / 0.5) ** 2], rtol=1e-12)
        np.testing.assert_array_equal(force[0], -force[1])
        np.testing.assert_array_equal(torque, 0.0)  # through the centres
    force, _ = repulsion_loads([a, _sphere_surface((0.0, 0.0, 2.0), 0.5)], law)  # gap = range
    np.testing.assert_array_equal(force, 0.0)
    assert law.magnitude(0.5 - 1e-9) > 0.0 and law.magnitude(-0.1) == pytest.approx(3 * 1.2**2)


def test_a_cluster_of_bodies_balances_forces_and_moments_about_any_origin():
    """Newton's third law and the moment balance: for pair forces along the line of their contact
    points, sum F = 0 and sum (c x F + torque) = 0 about any origin, each pair exactly; bodies of
    very different reach (a large one beside small ones) included."""
    rng = np.random.default_rng(5)
    surfaces = []
    for center, size in [((0, 0, 0), 3.0), ((3.2, 0.4, 0), 0.3), ((0.5, 3.25, 0.3), 0.3),
                         ((3.5, 3.5, 3.5), 0.4)]:
        shell = rng.normal(size=(60, 3))
        shell *= size / np.linalg.norm(shell, axis=1, keepdims=True)
        surfaces.append(_surface(np.array(center) + shell, center))
    surfaces[0] = _surface(surfaces[0].points * [1.0, 1.0, 0.35], (0, 0, 0))  # a flat ellipsoid
    top = surfaces[0].points[np.argmax(surfaces[0].points[:, 2])]
    surfaces.append(_sphere_surface(top + [0.0, 0.0, 0.8], 0.6))  # 0.2 above its top point
    force, torque = repulsion_loads(surfaces, Repulsion(range=0.6, force=1.0))
    pushed = np.linalg.norm(force, axis=1) > 0
    assert pushed.tolist() == [True, True, True, False, True]  # the fourth out of range
    assert np.linalg.norm(torque[:3], axis=1).min() > 0
    np.testing.assert_allclose(force.sum(axis=0), 0.0, atol=1e-14)
    for origin in (np.zeros(3), np.array([10.0, -7.0, 3.0])):
        np.testing.assert_allclose(_moment(force, torque, surfaces, origin), 0.0, atol=1e-13)


def test_the_wall_turns_a_body_about_its_lowest_point():
    law = Repulsion(range=0.5, force=2.0)
    tilted = _surface([[1.0, 0.0, 0.2], [-1.0, 0.0, 1.8], [0.0, 1.0, 1.0]], [0.0, 0.0, 1.0])
    force, torque = repulsion_loads([tilted, _sphere_surface((5.0, 0.0, 1.2))], law, wall=True)
    m1, m2 = 2.0 * (1 - 0.2 / 0.5) ** 2, 2.0 * (1 - 0.2 / 0.5) ** 2
    np.testing.assert_allclose(force, [[0, 0, m1], [0, 0, m2]], rtol=1e-12)
    # lever (1, 0, -0.8) x (0, 0, m1) = (0, -m1, 0); the sphere: none
    np.testing.assert_allclose(torque, [[0.0, -m1, 0.0], [0.0, 0.0, 0.0]], rtol=1e-12,
                               atol=1e-15)


# ---- the distribution of placed bodies (config/placement.py, config/suspension.py) -------------
def _ks_uniform(u: np.ndarray) -> float:
    """The Kolmogorov-Smirnov distance of the sample ``u`` from the uniform law on [0, 1]."""
    u = np.sort(u)
    n = len(u)
    return float(max(np.max(np.arange(1, n + 1) / n - u), np.max(u - np.arange(n) / n)))


#: The KS distance below which a sample of n passes at the 1 % level (1.63 / sqrt(n)).
def _ks_limit(n: int) -> float:
    return 1.63 / math.sqrt(n)


def test_random_centres_fill_the_sphere_uniformly():
    """Dilute (the exclusion negligible): the centres of bodies of bounding radius 1 in a sphere of
    radius 12 fill the ball of radius 11 uniformly: (r / 11)^3, the direction's z, and the
    azimuth are each uniform on [0, 1] (KS at 1 %, seed fixed)."""
    rng = np.random.default_rng(3)
    c, drawn = placement.random_centers(3000, "sphere", [1.0, -2.0, 20.0], None, 12.0, 1.0,
                                        0.05, rng)
    assert len(c) == 3000 and drawn == 3072  # (12 batches of 256: nothing rejected)
    d = c - [1.0, -2.0, 20.0]
    r = np.linalg.norm(d, axis=1)
    assert r.max() <= 11.0 and r.max() > 10.95
    for u in ((r / 11.0) ** 3, 0.5 * (d[:, 2] / r + 1.0),
              (np.arctan2(d[:, 1], d[:, 0]) + np.pi) / (2 * np.pi)):
        assert _ks_uniform(u) < _ks_limit(len(u))
    assert _ks_uniform((r / 11.0) ** 2) > 5 * _ks_limit(len(r))  # the test tells r^2 from r^3


def test_random_centres_fill_the_box_uniformly():
    rng = np.random.default_rng(4)
    c, _ = placement.random_centers(2000, "box", [0.0, 5.0, 10.0], [20.0, 16.0, 12.0], None, 1.5,
                                    0.05, rng)
    half = np.array([10.0, 8.0, 6.0]) - 1.5
    u = (c - [0.0, 5.0, 10.0] + half) / (2 * half)
    assert u.min() >= 0.0 and u.max() <= 1.0
    for axis in range(3):
        assert _ks_uniform(u[:, axis]) < _ks_limit(len(u))


def test_the_quick_clouds_spheres_fill_their_sphere_and_keep_their_distance():
    """The shipped quick cloud (100 spheres of radius 1, seed 1, in a sphere of radius 12): the
    centres in the ball of radius 11 with (r / 11)^3 uniform, no two closer than 2 radii plus
    the gap, deterministic for the seed."""
    from pathlib import Path

    from parastokes import config

    path = Path(__file__).resolve().parents[1] / "experiments" / "quick" / "cloud_sediments.toml"
    cfg, _ = config.load(path)
    c = np.array([b.position for b in cfg.model.bodies])
    assert len(c) == 100
    r = np.linalg.norm(c, axis=1)
    assert r.max() <= 11.0
    assert _ks_uniform((r / 11.0) ** 3) < _ks_limit(100)
    apart = np.linalg.norm(c[:, None] - c[None], axis=-1) + 1e9 * np.eye(100)
    body = cfg.model.bodies[0].build()
    assert apart.min() >= 2.0 + max(0.2, 2 * body.epsilon)
    again, _ = config.load(path)
    assert np.array_equal(c, [b.position for b in again.model.bodies])


def test_random_centres_keep_their_distance_and_no_more():
    """Dense (60 bodies where about 66 fit): every pair at least ``distance`` apart, the closest
    ones not much farther (the exclusion is the distance, not its square or double), across
    cells of the neighbour grid; the same seed gives the same bits."""
    args = (60, "sphere", [0.0, 0.0, 0.0], None, 5.0, 0.5, 1.7)
    c, drawn = placement.random_centers(*args, np.random.default_rng(11))
    assert len(c) == 60 and drawn > 1000  # many candidates refused
    apart = np.linalg.norm(c[:, None] - c[None], axis=-1) + 1e9 * np.eye(len(c))
    assert apart.min() >= 1.7 and apart.min() < 1.72
    again, _ = placement.random_centers(*args, np.random.default_rng(11))
    other, _ = placement.random_centers(*args, np.random.default_rng(12))
    assert np.array_equal(c, again) and not np.array_equal(c[:10], other[:10])


def test_a_lattice_has_its_spacing_exactly_and_is_centred():
    c = placement.lattice([3, 2, 4], [1.5, 2.0, 0.5], [1.0, -2.0, 7.0])
    assert c.shape == (24, 3)
    np.testing.assert_allclose(c.mean(axis=0), [1.0, -2.0, 7.0], rtol=0, atol=1e-12)
    grid = c.reshape(3, 2, 4, 3)  # x slowest, z fastest
    np.testing.assert_allclose(np.diff(grid[..., 0], axis=0), 1.5, rtol=1e-12)
    np.testing.assert_allclose(np.diff(grid[..., 1], axis=1), 2.0, rtol=1e-12)
    np.testing.assert_allclose(np.diff(grid[..., 2], axis=2), 0.5, rtol=1e-12)
    np.testing.assert_allclose(c[0], [-0.5, -3.0, 6.25])
    np.testing.assert_array_equal(placement.lattice([1, 1, 1], [9.0] * 3, [1.0, 2.0, 3.0]),
                                  [[1.0, 2.0, 3.0]])


# ---- the best serial run's interval and problem checks (parareal/best_serial.py) --------------
def test_the_best_serial_run_is_checked_against_f_and_the_interval_it_was_measured_over(
        tmp_path):
    """Measured runs of F = rk2 at 1e-6 over T = 0.002: the same F over another T, another
    step or another scheme is refused naming both; the same problem (to round-off) is not; the
    best run reaching a target is the one with the least CPU relative to F."""
    import json

    from parastokes.parareal.best_serial import load_serial_runs

    path = tmp_path / "serial.json"
    path.write_text(json.dumps({"cases": {"tiny": {
        "t1": 0.002, "reference": {"scheme": "rk2", "dt": 1e-6},
        "rows": [{"scheme": "rk2", "dt": 4e-6, "error": 1e-7, "cpu": 2.5, "fine_cpu": 10.0},
                 {"scheme": "euler", "dt": 2e-6, "error": 1e-4, "cpu": 1.0, "fine_cpu": 10.0},
                 {"scheme": "rk4", "dt": 1e-5, "error": 1e-9, "cpu": 5.0, "fine_cpu": 10.0}]}}}))
    runs = load_serial_runs(path)
    runs.check_fine("rk2", 1e-6 * (1 + 1e-12), 0.002 * (1 - 1e-12))
    for scheme, dt, span in (("rk2", 1e-6, 0.004), ("rk2", 1e-6, 0.001), ("rk2", 2e-6, 0.002),
                             ("rk4", 1e-6, 0.002)):
        with pytest.raises(ValueError, match=r"measured against F = rk2 at dt = 1e-06 over "
                                             r"T = 0.002, but the configuration's F is"):
            runs.check_fine(scheme, dt, span)
    assert runs.best(1e-3).scheme == "euler"  # 10x less CPU than F; rk2 4x, rk4 2x
    assert runs.best(1e-7).scheme == "rk2"  # euler's error is too large
    assert runs.best(1e-9).scheme == "rk4" and runs.best(1e-10) is runs.reference
