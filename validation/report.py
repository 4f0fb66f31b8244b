"""What the validation scripts share: writing their results and printing their claims."""

from __future__ import annotations

import json
from pathlib import Path


def write_results(results: dict, path: Path) -> None:
    """The results as indented JSON at ``path`` (its folder created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=1) + "\n")


def print_claims(results: dict) -> None:
    """One line per claim of ``results["claims"]``: ``holds`` or ``FAILS``."""
    for name, holds in results["claims"].items():
        print(f"{'holds' if holds else 'FAILS'}: {name}")
