"""How the test run itself is set up (tests/conftest.py, pyproject.toml's pytest settings): the
scheduling units of the xdist workers, the group of the MPI tests, the thread settings and the
installed copy's note left out."""

from __future__ import annotations

import os
import shlex
import tomllib
from pathlib import Path

import conftest
import pytest

from parastokes.cli import launch

PYPROJECT = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())


def test_a_worker_gets_a_file_or_a_group_whole():
    assert conftest.scope_of("tests/test_a.py::test_b") == "tests/test_a.py"
    assert conftest.scope_of("tests/test_a.py::test_b[x-1]") == "tests/test_a.py"
    assert conftest.scope_of("tests/test_a.py::Case::test_b") == "tests/test_a.py"
    assert conftest.scope_of("tests/test_a.py::test_b[x@y]") == "tests/test_a.py"  # a parameter
    assert conftest.scope_of("tests/test_a.py::test_b@processes") == "processes"
    assert conftest.scope_of("tests/test_a.py::test_b[x@y]@processes") == "processes"


class _Item:
    def __init__(self, *markers: str):
        self.markers = [getattr(pytest.mark, name) for name in markers]

    def get_closest_marker(self, name):
        return next((m for m in self.markers if m.name == name), None)

    def add_marker(self, marker):
        self.markers.append(marker)


def test_the_mpi_tests_are_one_group_and_the_others_none():
    mpi, other = _Item("mpi"), _Item("gpu")
    conftest.pytest_collection_modifyitems([mpi, other])
    assert mpi.get_closest_marker("xdist_group").args == (conftest.PROCESSES,)
    assert other.get_closest_marker("xdist_group") is None


def test_the_run_uses_every_core_with_the_scheduler_of_conftest():
    options = shlex.split(PYPROJECT["tool"]["pytest"]["ini_options"]["addopts"])
    assert options[options.index("-n") + 1] == "auto"
    assert options[options.index("--dist") + 1] == "loadgroup"  # what scope_of schedules
    assert any(r.startswith("pytest-xdist") for r in PYPROJECT["project"]["optional-dependencies"]
               ["test"])


def test_thread_pools_wait_without_spinning_and_blas_starts_one_thread():
    """(Unless the environment of the run set them otherwise: CI's does not.)"""
    assert os.environ["OMP_WAIT_POLICY"] == "PASSIVE"
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1"


def test_no_installed_copy_is_seen_so_no_note_is_printed(monkeypatch, capsys):
    assert launch._installed_package() is None
    monkeypatch.chdir(Path(launch.__file__).resolve().parents[2])  # the checkout's root
    launch.check_shadowing()
    assert capsys.readouterr().err == ""


class _Dist:
    """The run's configuration with ``--dist`` replaced (and one local worker, as under -n 1)."""

    def __init__(self, config, dist):
        self._config, self._dist = config, dist

    def getvalue(self, name):
        return {"dist": self._dist, "tx": ["popen"]}.get(name) or self._config.getvalue(name)

    def __getattr__(self, name):
        return getattr(self._config, name)


def test_the_scheduler_of_loadgroup_is_by_file_or_group_and_other_modes_are_xdists(request):
    pytest.importorskip("xdist")
    scheduler = conftest.pytest_xdist_make_scheduler(_Dist(request.config, "loadgroup"), None)
    assert scheduler._split_scope("tests/test_a.py::test_b[1]") == "tests/test_a.py"
    assert scheduler._split_scope("tests/test_a.py::test_b@processes") == "processes"
    assert conftest.pytest_xdist_make_scheduler(_Dist(request.config, "loadfile"), None) is None
