"""Static checks as tests: ruff (the lint rules of pyproject.toml) and mypy (the type hints,
``[tool.mypy]`` of pyproject.toml) find nothing."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

api = pytest.importorskip("mypy.api", reason='the test extra has mypy: pip install ".[test]"')

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_finds_nothing():
    done = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "."], cwd=ROOT, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_mypy_finds_nothing(monkeypatch):
    monkeypatch.chdir(ROOT)  # this checkout's package, not an installed one
    report, errors, status = api.run(["--config-file", "pyproject.toml"])
    assert status == 0, report + errors
