"""Where the command runs: the rank and size of an MPI launch (a launch of several copies
without the futures launcher is refused), and a note when a checkout in the current
directory shadows the installed package."""

from __future__ import annotations

import os
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

_RANK_VARIABLES = ("PMI_RANK", "OMPI_COMM_WORLD_RANK", "PMIX_RANK")


_SIZE_VARIABLES = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE")


def is_manager() -> bool:
    """False on the non-root ranks of an MPI launch (read from the launcher's environment)."""
    return all(os.environ.get(name, "0") == "0" for name in _RANK_VARIABLES)


def mpi_processes() -> int:
    """The number of processes of the MPI launch this process belongs to (1 without one)."""
    sizes = [os.environ.get(name, "") for name in _SIZE_VARIABLES]
    return max([int(v) for v in sizes if v.isdigit()] or [1])


def _under_futures_launcher() -> bool:
    """Whether ``python -m mpi4py.futures`` runs this process (its pool of the other ranks)."""
    core = sys.modules.get("mpi4py.futures._core")
    return getattr(core, "SharedPool", None) is not None


def check_launch(argv: Sequence[str]) -> None:
    """Refuse an MPI launch of several copies of the command (each would run everything)."""
    size = mpi_processes()
    if size > 1 and not _under_futures_launcher():
        command = f"mpiexec -n {size} python -m mpi4py.futures -m parastokes {shlex.join(argv)}"
        raise ValueError(
            f"launched as {size} MPI processes without the futures launcher: each would run the "
            f"whole problem into the same directory. Use\n    {command}\nwith "
            'execution.executor = "mpi" (docs/parallel.md, "mpi")'
        )


def shadowing_note(package: Path, cwd: Path, installed: Path | None) -> str | None:
    """A note when the package directory ``package`` that runs lies in the current directory
    ``cwd`` (``python -m`` puts it first on the path: a checkout's parent folder, or a checkout's
    root) while another copy is installed in ``installed`` (None: none)."""
    if installed is None or package.parent != cwd or installed == package:
        return None
    return (
        f"note: running the parastokes of {package} (python -m looks in the current directory "
        f"first), not the installed one in {installed}; run from another directory to use the "
        "installed package"
    )


def _installed_package() -> Path | None:
    """The directory of the installed (non-editable) parastokes, if there is one."""
    from importlib import metadata

    try:
        located = Path(str(metadata.distribution("parastokes").locate_file("parastokes")))
    except metadata.PackageNotFoundError:
        return None
    return located.resolve() if (located / "__init__.py").is_file() else None


def check_shadowing() -> None:
    """Print :func:`shadowing_note` if the package runs from the current directory."""
    here = Path(__file__).resolve().parents[1]
    if here.parent != Path.cwd().resolve():
        return
    note = shadowing_note(here, Path.cwd().resolve(), _installed_package())
    if note and is_manager():
        print(note, file=sys.stderr)
