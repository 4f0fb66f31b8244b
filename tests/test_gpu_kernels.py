"""The batched GPU kernels (parastokes.gpu.kernels) against the CPU kernels and the numpy oracle.

Measured in the simulator: max |GPU - CPU| / max |CPU| = 1.6e-16 to 2.2e-16 (u and w, free and
wall, forces and torques), 4e-16 to 5.5e-16 against the oracle; the tolerance is 1e-13. The pair
formulas are the CPU kernels' own functions, so what differs is the order of the sums (each target
sums its sources in sy interleaved lanes, then adds the lanes).
"""

import os

import numpy as np
import pytest
from gpu_setup import fast_simulator, gpu  # noqa: F401 (an autouse fixture)
from numba import cuda, float64

from parastokes import mrs

pytestmark = pytest.mark.gpu
RTOL = 1e-13


@pytest.fixture(scope="module")
def batch():
    rng = np.random.default_rng(7)
    b, n = 3, 7
    points = rng.uniform(0.0, 2.0, (b, n, 3))
    points[..., 2] += 0.3  # above the wall
    return dict(
        points=points,
        forces=rng.normal(size=(b, n, 3)),
        torques=rng.normal(size=(b, n, 3)),
        eps=np.array([0.3, 0.5, 0.8]),
        mu=np.array([1.0, 2.0, 0.5]),
    )


def _close(gpu_value, cpu_value):
    scale = np.abs(cpu_value).max()
    assert np.abs(gpu_value - cpu_value).max() <= RTOL * scale


@pytest.mark.parametrize("wall", [False, True])
@pytest.mark.parametrize("loads", ["forces", "torques", "both"])
def test_batched_full_kernel_matches_cpu_kernel_and_oracle(batch, wall, loads):
    x = batch["points"]
    f = batch["forces"] if loads != "torques" else np.zeros_like(x)
    n = batch["torques"] if loads != "forces" else None
    kw = dict(epsilon=batch["eps"], mu=batch["mu"], torques=n, wall=wall, angular=True)
    u, w = gpu.velocity(x, x, f, **kw)
    u_cpu, w_cpu = mrs.velocity(x, x, f, **kw)
    _close(u, u_cpu)
    _close(w, w_cpu)
    for b in range(x.shape[0]):  # each member with its own ε and μ, against the oracle
        u_ref, w_ref = mrs.reference.velocity(
            x[b], x[b], f[b], epsilon=batch["eps"][b], mu=batch["mu"][b],
            torques=None if n is None else n[b], wall=wall, angular=True,
        )
        _close(u[b], u_ref)
        _close(w[b], w_ref)


def test_free_force_kernel_matches_cpu_kernel_with_other_targets(batch):
    x = batch["points"]
    targets = x[:, :5] + 0.1
    u = gpu.velocity(targets, x, batch["forces"], epsilon=batch["eps"], mu=batch["mu"])
    _close(u, mrs.velocity(targets, x, batch["forces"], epsilon=batch["eps"], mu=batch["mu"]))


@pytest.mark.parametrize("wall", [False, True])
def test_epsilon_per_source_matches_the_cpu_kernel(batch, wall):
    """Each source with its own blob (a scene's bodies, a rigid surface's points)."""
    x, f = batch["points"], batch["forces"]
    eps = np.random.default_rng(3).uniform(0.2, 0.9, x.shape[:2])
    for kw in (dict(), dict(torques=batch["torques"], angular=True)):
        got = gpu.velocity(x, x, f, epsilon=eps, mu=batch["mu"], wall=wall, **kw)
        want = mrs.velocity(x, x, f, epsilon=eps, mu=batch["mu"], wall=wall, **kw)
        for g, c in zip(got if kw else [got], want if kw else [want], strict=True):
            _close(g, c)


def test_a_member_does_not_depend_on_its_batch(batch):
    """Every target sums its sources in the same order whatever the batch: bit-identical."""
    x, f, n = batch["points"], batch["forces"], batch["torques"]
    together = gpu.velocity(x, x, f, epsilon=batch["eps"], mu=batch["mu"], torques=n,
                            wall=True, angular=True)
    alone = gpu.velocity(x[1], x[1], f[1], epsilon=batch["eps"][1], mu=batch["mu"][1],
                         torques=n[1], wall=True, angular=True)
    assert np.array_equal(together[0][1], alone[0])
    assert np.array_equal(together[1][1], alone[1])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (dict(epsilon=np.array([0.3, 0.5])), "epsilon"),
        (dict(mu=-1.0), "mu"),
        (dict(forces=np.zeros((3, 6, 3))), "forces"),
        (dict(wall=True, targets=-np.ones((3, 7, 3))), "targets: points below the wall"),
        (dict(targets=np.full((3, 7, 3), 1e19)), "targets: coordinates beyond"),
        (dict(epsilon=np.full((3, 6), 0.3)), "epsilon: one per source needs shape"),
    ],
)
def test_bad_input_is_refused_naming_the_argument(batch, change, message):
    kw = dict(targets=batch["points"], sources=batch["points"], forces=batch["forces"],
              epsilon=batch["eps"], mu=batch["mu"])
    kw.update(change)
    with pytest.raises(ValueError, match=message):
        gpu.velocity(**kw)


def test_a_shared_array_is_one_array_for_the_whole_block():
    """The harness's fix of the simulator (gpu_setup): every thread of a block gets the same
    ``cuda.shared.array``, even with a thread switch after every instruction or so (unfixed, about
    1 launch in 40 of this kernel summed the wrong array)."""
    import sys

    if os.environ.get("NUMBA_ENABLE_CUDASIM") != "1":
        pytest.skip("a property of the simulator")

    @cuda.jit
    def block_sum(out):
        t = cuda.threadIdx.x
        part = cuda.shared.array(32, float64)
        part[t] = 1.0
        cuda.syncthreads()
        if t == 0:
            total = 0.0
            for i in range(32):
                total += part[i]
            out[cuda.blockIdx.x] = total

    previous = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        sums = []
        for _ in range(40):
            out = np.zeros(4)
            block_sum[4, 32](out)
            sums.append(out)
    finally:
        sys.setswitchinterval(previous)
    assert np.all(np.array(sums) == 32.0)
