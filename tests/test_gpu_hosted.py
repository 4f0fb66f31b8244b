"""Hosted solves on the GPU executor (parastokes.gpu.hosted): rigid and prescribed-motion bodies,
and scenes with them, run their CPU code in threads with every fluid product evaluated on the GPU
in launches batched over the solves.

Checked against the serial executor: Parareal iterates of a rigid sphere sedimenting by a wall
(GMRES: the direct solver's limit is lowered so that tiny surfaces take the iterative path that
large ones take), a squirmer, a bacterium (its flagellum turns: a new surface every solve) and a
scene of a rigid sphere and a rod; the launches hold one product of every solve that is still
running. Measured in the simulator: max |GPU - CPU| over the iterates 3.3e-15 (sphere), 1.6e-14
(squirmer), 2.1e-14 (bacterium), 2.0e-15 (scene) relative to the motion; the tolerance is 1e-11
(GMRES to 1e-10 propagates the products' round-off).
"""

import signal
import threading

import numpy as np
import pytest
from gpu_setup import fast_simulator, gpu, small_rods  # noqa: F401 (an autouse fixture)

from parastokes import integrate, mrs, parallel, parareal
from parastokes.kinds.rigid.shapes import Bacterium, Helix, Sphere
from parastokes.kinds.rigid.slip import Squirmer
from parastokes.kinds.rigid.system import RigidBody
from parastokes.mobility import choice
from parastokes.mrs.velocity import routed

pytestmark = pytest.mark.gpu
RTOL = 1e-11


@pytest.fixture
def iterative(monkeypatch):
    """GMRES for every multi-point solve (the path of surfaces above 200 points)."""
    monkeypatch.setattr(choice, "DENSE_MAX_POINTS", 0)


def _sphere(**kw):
    args = dict(shape=Sphere(n_points=12), epsilon=0.5, wall=True, position=(0.0, 0.0, 2.0),
                force=(0.3, 0.0, -1.0))
    return RigidBody(**(args | kw))


def _compare(body, x0, t1, coarse_dt=0.1, n_slices=2, iterations=1, node="epsilon"):
    fine = integrate.Propagator(body, "rk2", coarse_dt / 2)
    coarse = parareal.extrapolated(body, "euler", coarse_dt, lagrange={node: [1.05, 1.1]})
    kw = dict(tol=0.0, max_iterations=iterations, project=body.project)
    cpu = parareal.run(fine, coarse, x0, 0.0, t1, n_slices,
                       executor=parallel.make_executor("serial"), **kw)
    with parallel.make_executor("gpu") as executor:
        result = parareal.run(fine, coarse, x0, 0.0, t1, n_slices, executor=executor, **kw)
    motion = np.abs(cpu.states - x0).max()
    assert motion > 1e-3
    assert np.abs(result.states - cpu.states).max() <= RTOL * motion
    assert executor.launches  # its products ran on the GPU
    return executor


def test_route_sends_this_threads_velocity_calls_only():
    rng = np.random.default_rng(1)
    x, f = rng.uniform(0.5, 2.0, (5, 3)), rng.normal(size=(5, 3))
    seen, other = [], []

    def route(*args):
        seen.append(args)
        return np.zeros((5, 3))

    def elsewhere():
        other.append(mrs.velocity(x, x, f, epsilon=0.3, mu=1.0))

    with routed(route):
        sent = mrs.velocity(x, x, f, epsilon=np.full(5, 0.3), mu=2.0, wall=True)
        thread = threading.Thread(target=elsewhere)
        thread.start()
        thread.join()
        batched = mrs.velocity(x[None], x[None], f[None], epsilon=0.3, mu=1.0)
    assert np.array_equal(sent, np.zeros((5, 3)))
    (_, _, _, torques, eps, mu, wall, angular), = seen
    assert torques is None and wall and not angular
    assert eps.shape == (1, 5) and mu.tolist() == [2.0]
    assert np.array_equal(other[0], mrs.velocity(x, x, f, epsilon=0.3, mu=1.0))  # not routed
    assert np.array_equal(batched[0], other[0])  # batched calls are not routed


def test_router_batches_the_products_of_all_waiting_solves():
    """Four solves, two shapes: each round is one launch per shape and kind of ε; results as
    the CPU's."""
    rng = np.random.default_rng(2)
    cases = []
    for n, wall, torques, per_source in ((6, True, False, True), (6, True, True, True),
                                         (4, False, False, True), (4, False, False, False)):
        x = rng.uniform(0.5, 2.0, (n, 3))
        cases.append((x, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)) if torques else None,
                      rng.uniform(0.2, 0.6, n) if per_source else 0.4, wall))

    def job(x, f, n, eps, wall):
        return [mrs.velocity(x, x, (k + 1) * f, epsilon=eps, mu=1.5, torques=n, wall=wall,
                             angular=True) for k in range(3)]

    router = gpu.hosted.Router()
    outcomes = router.run([lambda c=c: job(*c) for c in cases])
    # per round: one launch of the two 6-point solves, one for each 4-point one (ε per source,
    # one ε)
    assert sorted(router.launches) == [1] * 6 + [2] * 3
    for (ok, values), case in zip(outcomes, cases, strict=True):
        assert ok
        for got, want in zip(values, job(*case), strict=True):
            for g, w in zip(got, want, strict=True):
                assert np.abs(g - w).max() <= 1e-13 * np.abs(w).max()


def test_a_failed_solve_fails_alone_and_a_failed_launch_fails_its_products(monkeypatch):
    x = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 1.2]])

    def fine():
        return [mrs.velocity(x, x, x, epsilon=0.3, mu=1.0) for _ in range(3)]

    def broken():
        mrs.velocity(x, x, x, epsilon=0.3, mu=1.0)
        raise KeyError("its own error")

    router = gpu.hosted.Router()
    (ok, values), (failed, error) = router.run([fine, broken])
    assert ok and len(values) == 3 and not failed and isinstance(error, KeyError)
    assert router.launches == [2, 1, 1]

    def refuse(self):
        raise RuntimeError("launch failed")

    monkeypatch.setattr(gpu.hosted.Evaluation, "launch", refuse)
    outcomes = gpu.hosted.Router().run([fine, fine])
    assert [str(value) for _, value in outcomes] == [
        "the GPU launch of 2 products failed: RuntimeError: launch failed"] * 2
    assert outcomes[0][1] is not outcomes[1][1]


def test_rigid_sphere_by_the_wall_matches_the_cpu(iterative):
    body = _sphere()
    executor = _compare(body, body.initial_state(), 0.4)
    # initial sweep: 2 coarse steps of N_G = 2; iteration 1: 2 fine solves, 1 coarse step
    assert executor.batches == [2, 2, 2, 2]
    assert executor.launches and max(executor.launches) == 2  # one product of each solve


def test_squirmer_and_bacterium_match_the_cpu(iterative):
    """Prescribed surface motion: a squirmer's slip; a bacterium's turning flagellum."""
    squirmer = _sphere(slip=Squirmer(b1=1.0, b2=0.5), force=(0.0, 0.0, 0.0))
    _compare(squirmer, squirmer.initial_state(), 0.4)
    cell = RigidBody(shape=Bacterium(head=Sphere(0.6, 12), tail=Helix(0.3, 1.2, 1.0, 8, -1),
                                     motor_rate=-3.0),
                     epsilon=0.45, wall=True, position=(0.0, 0.0, 2.0))
    _compare(cell, cell.initial_state(), 0.2)


def test_scene_of_a_rigid_sphere_and_a_rod_matches_the_cpu(iterative):
    from parastokes.scene import Scene

    rod = small_rods(n_rods=1, height=4.0)
    sphere = _sphere(position=(0.0, 3.0, 2.0), viscosity=1.0)
    scene = Scene((rod, sphere), viscosity=1.0, wall=True)
    executor = _compare(scene, scene.initial_state(), 0.04, coarse_dt=0.02,
                        node="rigidbody.epsilon")
    assert max(executor.launches) == 2


def test_the_device_scripts_rigid_section_runs_and_checks(tmp_path):
    """benchmarks/gpu.py --smoke --sections rigid on the simulator: the hosted batch against a
    process pool (whose workers solve the tiny suspension densely: GMRES's tolerance apart)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "gpu.json"
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1", "PYTHONPATH": str(root)}
    subprocess.run([sys.executable, "benchmarks/gpu.py", "--smoke", "--sections", "rigid",
                    "--json", str(out)], cwd=root, env=env, check=True, capture_output=True,
                   timeout=600)
    rigid = json.loads(out.read_text())["rigid"]
    assert rigid["bodies"] == 2 and rigid["members"] == 2
    assert rigid["launches"] > 0 and rigid["mean_launch_batch"] == 2.0
    assert rigid["max_rel_diff"] < 1e-8


class _CpuEvaluation:
    """The CPU kernels in place of the GPU launch (``Router(evaluation=...)``, as
    benchmarks/suspension.py's part hosted)."""

    def __init__(self, targets, sources, forces, torques, epsilon, mu, wall, launch=None):
        self.u, self.w = mrs.velocity(targets, sources, forces, epsilon=epsilon, mu=mu,
                                      torques=torques, wall=wall, angular=True)

    def launch(self):
        pass

    def result(self):
        return self.u, self.w


def test_concurrent_hosted_solves_equal_the_serial_solve_bit_for_bit():
    """Four hosted mobility solves of 64 spheres at once (their threads share the sphere's
    body-frame factorization and its caches) against one serial solve. Before scipy's LAPACK
    calls were serialized (mobility.threads.LAPACK) they corrupted each other: 14 GMRES
    iterations instead of 10 and forces off by 11 %, or a heap corruption: this test failed or
    crashed in 1 of 3 runs without the lock."""
    from parastokes import config

    data = {"scene": {"viscosity": 1e-6, "wall": True},
            "suspensions": [{"name": "s", "placement": "lattice", "counts": [4, 4, 4],
                             "spacing": 4.0, "center": [0.0, 0.0, 9.0],
                             "body": {"kind": "rigid", "radius": 1.0, "n_points": 42,
                                      "force": [0.0, 0.0, -2e-5]}}],
            "time": {"t1": 0.1}, "fine": {"dt": 0.05}, "coarse": {"dt_ratio": 2},
            "parareal": {"n_slices": 2}, "execution": {"executor": "serial"}}
    cfg = config.parse(data)
    scene = config.build(cfg, config.resolve(cfg)).system
    x0 = scene.initial_state()
    serial = scene.coupled(0.0, x0).solution
    router = gpu.hosted.Router(evaluation=_CpuEvaluation)
    for _ in range(3):
        outcomes = router.run([lambda: scene.coupled(0.0, x0).solution] * 4)
        for ok, solution in outcomes:
            assert ok
            assert solution.info.iterations == serial.info.iterations
            assert np.array_equal(solution.forces, serial.forces)
    assert set(router.launches) == {4}


def test_ctrl_c_while_solves_wait_closes_the_router_and_releases_them():
    """Ctrl-C reaches the calling thread while it waits for the solves: it is raised there, and
    every solve thread waiting on a product gets an error instead of waiting forever."""
    import _thread

    x = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 1.2]])
    errors = []

    def interrupting():
        _thread.interrupt_main()  # Ctrl-C, while the router waits for this solve
        return mrs.velocity(x, x, x, epsilon=0.3, mu=1.0)

    def waiting():
        try:
            return mrs.velocity(x, x, x, epsilon=0.3, mu=1.0)
        except RuntimeError as exc:
            errors.append(str(exc))
            raise

    router = gpu.hosted.Router()
    # Python's own Ctrl-C handler, even when this suite runs with SIGINT ignored (a background
    # job of a shell without job control: interrupt_main then does nothing)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            router.run([interrupting, waiting])
    finally:
        signal.signal(signal.SIGINT, previous)
    for _ in range(50):  # the released threads end (they are daemons: never a hang at exit)
        if not [t for t in threading.enumerate() if t.name.startswith("parastokes-gpu-host")]:
            break
        threading.Event().wait(0.1)
    assert not [t for t in threading.enumerate() if t.name.startswith("parastokes-gpu-host")]
    assert errors in ([], ["the GPU router was closed"])


def test_a_rigid_configuration_runs_on_the_gpu_executor_as_on_the_serial(iterative, tmp_path):
    """``parastokes run`` of a rigid sphere with ``executor = "gpu"`` (hosted) against the serial
    executor: the same Parareal result to round-off."""
    from parastokes import config
    from parastokes.run import execution

    def run(kind):
        cfg = config.parse({
            "model": {"kind": "rigid", "shape": "sphere", "n_points": 12, "wall": True,
                      "viscosity": 1.0, "position": [0.0, 0.0, 2.0], "force": [0.3, 0.0, -1.0]},
            "time": {"t1": 0.4}, "fine": {"dt": 0.05},
            "coarse": {"dt_ratio": 2, "lagrange": {"epsilon": [1.05, 1.1]}},
            "parareal": {"n_slices": 2, "max_iterations": 1}, "run": {"mode": "parareal"},
            "output": {"figures": False}, "execution": {"executor": kind}})
        return execution.execute(cfg, config.resolve(cfg), tmp_path / kind)

    serial, hosted = run("serial"), run("gpu")
    start = np.array([[0.0, 0.0, 2.0]])
    motion = np.abs(np.array(serial["final_positions"])[:1] - start).max()
    assert motion > 1e-3
    diff = np.abs(np.array(hosted["final_positions"]) - np.array(serial["final_positions"]))
    assert diff.max() <= RTOL * motion
    assert hosted["increments"] == pytest.approx(serial["increments"], rel=1e-6)


@pytest.mark.parametrize("kw", [dict(scheme="ros2", dt=1e-2), dict(scheme="lieuler", dt=1e-2),
                                dict(scheme="ros2-krylov", dt=1e-2),
                                dict(scheme="ros2", dt=1e-2, rtol=1e-6)])
def test_implicit_and_adaptive_solves_run_hosted(kw):
    """The device loop runs fixed steps of explicit tableaux; a linearly implicit or adaptive
    propagator (docs/stiff.md) of a body with device parts runs hosted instead (it failed
    before): on the simulator as on the CPU to round-off; four at once with the CPU kernels in
    place of the launches, bit for bit as one alone (their threads share nothing unsafe)."""
    rods = small_rods()
    x0 = rods.initial_state()
    fine = integrate.Propagator(rods, **kw)
    assert gpu.batch.batch_key(fine, (0.0, 0.04, x0)) is None
    cpu = fine(0.0, 0.04, x0)
    launches = []
    (ok, value), = gpu.batch.run_calls([(fine, (0.0, 0.04, x0), {})], launches=launches)
    assert ok and launches
    assert np.abs(value - cpu).max() <= RTOL * np.abs(cpu - x0).max()
    outcomes = gpu.hosted.Router(evaluation=_CpuEvaluation).run([lambda: fine(0.0, 0.04, x0)] * 4)
    assert all(ok and np.array_equal(value, cpu) for ok, value in outcomes)


def test_a_stop_lost_in_a_finalizer_ends_the_batch_at_the_next_round():
    """A SIGTERM whose raise was lost (recorded by core.signals) stops the router before its
    next launch, releasing the solves."""
    from parastokes.core import signals

    x = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 1.2]])
    with pytest.raises(signals.Terminated):
        signals.terminate(signal.SIGTERM)  # the handler's raise, "lost"
    try:
        with pytest.raises(signals.Terminated):
            gpu.hosted.Router().run([lambda: mrs.velocity(x, x, x, epsilon=0.3, mu=1.0)])
    finally:
        signals.clear()


def test_a_hosted_solve_does_not_depend_on_its_batch(iterative):
    """Each target sums its sources in a fixed order whatever the launch holds: a rigid solve
    alone and beside another one (another ε, another start) give the same bits."""
    body = _sphere()
    x0 = body.initial_state()
    fine = integrate.Propagator(body, "rk2", 0.05)
    other = integrate.Propagator(body.with_params(epsilon=0.55), "rk2", 0.05)
    (_, alone), = gpu.batch.run_calls([(fine, (0.0, 0.1, x0), {})])
    launches = []
    (_, together), _ = gpu.batch.run_calls([(fine, (0.0, 0.1, x0), {}),
                                            (other, (0.1, 0.2, x0), {})], launches=launches)
    assert max(launches) == 2  # they shared launches
    assert np.array_equal(alone, together)
