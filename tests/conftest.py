"""Settings of the whole test run (docs/design.md, "Tests").

- The tests run on every core with pytest-xdist (``-n auto --dist loadgroup`` in pyproject.toml's
  ``addopts``; ``-n 0`` runs them in this one process). The scheduler below sends each test file
  to one worker as a whole, so that a module-scoped fixture is computed once, and the tests of
  one ``xdist_group`` to one worker, one after the other: the tests marked ``mpi`` are the group
  ``processes`` (each launches ``mpiexec -n 2``, whose ranks poll while they wait; two at once on
  two cores ran each past its time limit).
- Each worker's thread pools wait without spinning and BLAS starts one thread
  (``OMP_WAIT_POLICY=PASSIVE``, ``OPENBLAS_NUM_THREADS=1`` unless the environment sets them; set
  here, before numpy and numba are loaded, so the workers and the tests' subprocesses inherit
  them): the workers already occupy the cores, and a spinning OpenMP pool (numba's ``omp`` layer)
  or a BLAS thread preempted by the other worker made each small parallel region wait for a time
  slice (tests/test_rigid.py's contract of the bacterium: 113 s instead of 59 s on the loaded
  2-core machine, under ``-n 0``). The package limits BLAS to the fluid's threads in its solves
  anyway (``mobility.threads``); a test that asks for more (``threadpool_limits``) still gets them.
- The checkout's package under test, without the note that ``parastokes`` prints when it runs
  from a checkout in the current directory while another copy is installed
  (``cli.launch.check_shadowing``): ``.ci/run`` installs the package (``pip install ".[test]"``)
  and runs ``python -m pytest`` from the checkout, which is exactly that case, and the tests of
  one-line error messages call ``cli.main`` there. The note itself is tested in
  tests/test_faults.py (``shadowing_note``).
"""

from __future__ import annotations

import os

for _variable, _value in (("OMP_WAIT_POLICY", "PASSIVE"), ("OPENBLAS_NUM_THREADS", "1")):
    os.environ.setdefault(_variable, _value)

import pytest  # noqa: E402 (after the thread settings)

from parastokes.cli import launch  # noqa: E402

#: The xdist group of the tests that start several busy processes of their own.
PROCESSES = "processes"


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("mpi") is not None:
            item.add_marker(pytest.mark.xdist_group(PROCESSES))


def scope_of(nodeid: str) -> str:
    """The unit a worker gets whole: the test's ``xdist_group`` (the suffix ``@NAME`` that
    ``--dist loadgroup`` appends to the test's id; an ``@`` inside the brackets of a parameter
    is not one), else its file."""
    if nodeid.rfind("@") > nodeid.rfind("]"):
        return nodeid.rpartition("@")[2]
    return nodeid.split("::", 1)[0]


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """``--dist loadgroup`` by :func:`scope_of` (xdist's own loadgroup schedules a test outside
    every group alone, which computes a module's fixtures on each worker that gets one of its
    tests)."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class FileOrGroup(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return scope_of(nodeid)

    return FileOrGroup(config, log)


@pytest.fixture(autouse=True)
def _no_shadowing_note(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(launch, "_installed_package", lambda: None)
