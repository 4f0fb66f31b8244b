"""Settings of the whole test run (docs/design.md, "Tests").

- The tests run on every core with pytest-xdist (``-n auto --dist loadgroup`` in pyproject.toml's
  ``addopts``; ``-n 0`` runs them in this one process). The scheduler below sends each test file
  to one worker as a whole, so that a module-scoped fixture is computed once, and the tests of
  one ``xdist_group`` to one worker, one after the other: the tests marked ``mpi`` are the group
  ``processes`` (each launches ``mpiexec -n 2``, whose ranks poll while they wait; two at once on
  two cores ran each past its time limit).
- The checkout's package under test, without the note that ``parastokes`` prints when it runs
  from a checkout in the current directory while another copy is installed
  (``cli.launch.check_shadowing``): ``.ci/run`` installs the package (``pip install ".[test]"``)
  and runs ``python -m pytest`` from the checkout, which is exactly that case, and the tests of
  one-line error messages call ``cli.main`` there. The note itself is tested in
  tests/test_faults.py (``shadowing_note``).
"""

from __future__ import annotations

import pytest

from parastokes.cli import launch

#: The xdist group of the tests that start several busy processes of their own.
PROCESSES = "processes"


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.get_closest_marker("mpi") is not None:
            item.add_marker(pytest.mark.xdist_group(PROCESSES))


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """``--dist loadgroup``, with a test outside every group scheduled with its file (xdist's own
    loadgroup schedules such a test alone, which computes a module's fixtures on each worker that
    gets one of its tests)."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class FileOrGroup(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            scope = super()._split_scope(nodeid)
            return scope.split("::", 1)[0] if scope == nodeid else scope

    return FileOrGroup(config, log)


@pytest.fixture(autouse=True)
def _no_shadowing_note(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(launch, "_installed_package", lambda: None)
