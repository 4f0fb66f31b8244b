"""Settings of the whole test run (docs/testing.md).

- The checkout's package under test, without the note that ``parastokes`` prints when it runs
  from a checkout in the current directory while another copy is installed
  (``cli.launch.check_shadowing``): ``.ci/run`` installs the package (``pip install ".[test]"``)
  and runs ``python -m pytest`` from the checkout, which is exactly that case, and the tests of
  one-line error messages called ``cli.main`` there. The note itself is tested in
  tests/test_faults.py (``shadowing_note``).
"""

from __future__ import annotations

import pytest

from parastokes.cli import launch


@pytest.fixture(autouse=True)
def _no_shadowing_note(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(launch, "_installed_package", lambda: None)
