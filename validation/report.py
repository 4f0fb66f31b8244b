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


def toml_values(numbers: dict) -> str:
    """``numbers`` (name -> number, boolean or list of them) as the value lines of a group of
    docs/numbers.toml, at full precision (``nan`` for NaN), for pasting into the registry."""

    def one(value) -> str:
        if isinstance(value, bool):
            return "true" if value else "false"
        return repr(float(value))

    return "\n".join(
        f"{name} = [{', '.join(one(v) for v in value)}]"
        if isinstance(value, list)
        else f"{name} = {one(value)}"
        for name, value in numbers.items()
    )
