"""Config is pure data; the run layer (parastokes.run.session) starts the executor and warms up.

Building a configuration whose executor is a process pool starts no process; ``session.start``
does, and stops it on exit; ``parastokes check`` starts nothing.
"""

from __future__ import annotations

import multiprocessing
import subprocess
import sys

import pytest
from configs import small_rod

from parastokes import cli, config, parallel
from parastokes.parallel import ProcessExecutor
from parastokes.run import session

PROCESSES = small_rod(
    model="epsilon = 5",
    rest='[execution]\nexecutor = "processes"\nworkers = 2\nallow_oversubscribe = true\n'
    '[run]\nmode = "parareal"\n',
)


def _children() -> set[int]:
    return {p.pid for p in multiprocessing.active_children()}


def test_building_a_config_starts_no_process_and_the_session_starts_its_workers():
    before = _children()
    cfg, resolved = config.loads(PROCESSES)
    setup = config.build(cfg, resolved)
    assert _children() == before  # building constructs values only
    assert not hasattr(setup, "executor")
    with session.start(setup) as running:
        assert running.setup is setup
        assert isinstance(running.executor, ProcessExecutor)
        assert running.executor.workers == 2
        started = _children() - before
        assert set(running.executor.worker_pids) == started and len(started) == 2
    assert running.executor is None  # shut down on exit
    assert _children() == before


def test_the_session_warms_up_this_process_for_the_timed_serial_run(monkeypatch):
    warmed = []

    class Recorder:  # a stand-in for WarmUp
        def __init__(self, system):
            self.system = system

        def __call__(self):
            warmed.append(self.system)

    monkeypatch.setattr(session, "WarmUp", Recorder)
    cfg, resolved = config.loads(PROCESSES, overrides=['run.mode="serial"'])
    setup = config.build(cfg, resolved)
    assert warmed == []  # not by building
    with session.start(setup) as running:
        assert running.executor is None  # a serial run needs no pool
        assert warmed == [setup.system]


def test_an_mpi_launch_with_too_few_ranks_is_refused_and_its_pool_shut_down(monkeypatch):
    class FewRanks:
        workers = 2
        stopped = False

        def shutdown(self):
            FewRanks.stopped = True

    monkeypatch.setattr(parallel, "make_executor", lambda *args, **kwargs: FewRanks())
    cfg, resolved = config.loads(
        small_rod(model="epsilon = 5", rest='[execution]\nexecutor = "mpi"\n')
    )
    assert resolved.workers is None and resolved.n_auxiliary == 4
    setup = config.build(cfg, resolved)
    with pytest.raises(config.ConfigError, match=r"execution\.allow_oversubscribe") as caught:
        session.start(setup)
    assert "execution.workers" in dict(caught.value.issues)
    assert FewRanks.stopped


def test_check_starts_no_process_and_no_session(tmp_path, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("parastokes check started an executor")

    monkeypatch.setattr(session, "start", refuse)
    monkeypatch.setattr(parallel, "make_executor", refuse)
    path = tmp_path / "run.toml"
    path.write_text(PROCESSES)
    before = _children()
    assert cli.main(["check", str(path), "-q"]) == 0
    assert _children() == before


def test_importing_and_building_a_config_loads_no_run_layer():
    code = (
        "import sys; from parastokes import config; "
        f"cfg, r = config.loads({PROCESSES!r}); config.build(cfg, r); "
        "loaded = {'parastokes.run.session', 'parastokes.run.warmup'} & set(sys.modules); "
        "assert not loaded, loaded"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=600)
