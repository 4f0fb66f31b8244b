"""The registry of documented numbers, ``docs/numbers.toml``: read by the pages' check and by the
tests that recompute the numbers (docs/validation.md, "How the numbers are pinned").

A group ``[NAME]`` of the registry holds named values (a number, a boolean or a list of them, one
per table row; NaN where a row has none), the ``command`` that computes them, the ``tests`` that
recompute them, and the tolerance ``rtol``/``atol`` of that recomputation (``[NAME.tolerance]``
overrides it per value). A page binds its printed numbers to the registry with HTML comments, which
markdown does not render:

- inline, right after the number: ``a factor 37<!-- rod_fig5.g3_over_g4[3] -->``;
- a whole table, on the line before it: ``<!-- numbers rod_fig5: _ | _ | g3_eta1 | g4_eta1 -->``,
  one entry per column (``_``: not bound), row i of the table showing element i of each list.

:func:`page_mismatches` finds every bound number that does not print its registered value, and
:func:`check` compares a recomputed value with the registry.
"""

from __future__ import annotations

import math
import re
import tomllib
from functools import cache
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
REGISTRY = ROOT / "docs" / "numbers.toml"
#: The pages that bind numbers to the registry.
PAGES = tuple(ROOT / "docs" / page for page in ("validation.md", "benchmarks.md", "hodmd.md"))
#: Keys of a group that are not values.
RESERVED = {"command", "tests", "rtol", "atol", "note", "tolerance"}

_INLINE = re.compile(
    r"(?P<text>[-−]?\d[\d ,]*(?:\.\d+)?(?:e[-+−]?\d+)?)\s*<!--\s*(?P<key>[\w.]+(?:\[\d+\])?)\s*-->"
)
_TABLE = re.compile(r"<!--\s*numbers\s+(?P<group>\w+)\s*:(?P<columns>[^>]*?)-->")


@cache
def registry() -> dict[str, dict[str, Any]]:
    """The groups of ``docs/numbers.toml``."""
    return tomllib.loads(REGISTRY.read_text())


def values(group: str) -> dict[str, Any]:
    """The named values of ``group``."""
    return {k: v for k, v in registry()[group].items() if k not in RESERVED}


def lookup(key: str) -> Any:
    """``group.name`` or ``group.name[i]``."""
    match = re.fullmatch(r"(\w+)\.(\w+)(?:\[(\d+)\])?", key)
    if match is None:
        raise KeyError(f"{key!r} is not GROUP.NAME or GROUP.NAME[i]")
    group, name, index = match.groups()
    value = values(group)[name]
    return value if index is None else value[int(index)]


def tolerance(group: str, name: str, index: int | None = None) -> tuple[float, float]:
    """(rtol, atol) of ``group.name`` (element ``index``): its own entry in ``[group.tolerance]``
    (a number, or a list with one per element), else the group's."""
    entry = registry()[group]
    own = entry.get("tolerance", {}).get(name, {})
    found = []
    for kind in ("rtol", "atol"):
        value = own.get(kind, entry.get(kind, 0.0))
        found.append(value[index] if isinstance(value, list) and index is not None else value)
    return found[0], found[1]


def check(group: str, name: str, computed: Any, index: int | None = None) -> None:
    """Assert that ``computed`` equals the registered ``group.name`` (element ``index`` of it) to
    the registered tolerance: abs(computed - registered) <= rtol abs(registered) + atol."""
    registered = values(group)[name]
    if index is not None:
        registered = registered[index]
    label = f"{group}.{name}" + ("" if index is None else f"[{index}]")
    if isinstance(registered, list):
        assert len(computed) == len(registered), f"{label}: {len(computed)} values, documented"
        for i, value in enumerate(computed):
            check(group, name, value, i)
        return
    if isinstance(registered, bool) or isinstance(computed, bool):
        assert computed == registered, f"{label}: computed {computed!r}, documented {registered!r}"
        return
    rtol, atol = tolerance(group, name, index)
    if math.isnan(registered):
        assert math.isnan(computed), f"{label}: computed {computed!r}, documented NaN"
        return
    assert abs(computed - registered) <= rtol * abs(registered) + atol, (
        f"{label}: computed {computed!r}, documented {registered!r} (rtol {rtol:g}, atol {atol:g};"
        f" command: {registry()[group].get('command')})"
    )


def _number(text: str) -> tuple[float, float]:
    """The printed number and half a unit of its last printed digit."""
    clean = text.replace("−", "-").replace(" ", "").replace(",", "").replace(" ", "")
    mantissa, _, exponent = clean.partition("e")
    decimals = len(mantissa.partition(".")[2])
    scale = 10.0 ** int(exponent) if exponent else 1.0
    return float(clean), 0.5 * 10.0**-decimals * scale


def printed_as(text: str, value: Any) -> bool:
    """Whether ``text`` (a table cell or an inline number) shows ``value`` at its printed digits."""
    text = text.strip().strip("*").strip()
    if isinstance(value, bool):
        return text == ("yes" if value else "no")
    if isinstance(value, float) and math.isnan(value):
        return text in ("", "—", "-")
    try:
        shown, half = _number(text)
    except ValueError:
        return False
    return abs(shown - value) <= half * (1 + 1e-9)


def bindings(page: Path) -> list[tuple[str, str, int]]:
    """(registry key, printed text, line number) of every bound number of ``page``."""
    found = []
    lines = page.read_text().splitlines()
    for number, line in enumerate(lines, 1):
        for match in _INLINE.finditer(line):
            found.append((match["key"], match["text"], number))
        table = _TABLE.search(line)
        if table is None:
            continue
        columns = [c.strip() for c in table["columns"].split("|")]
        rows = []
        for row in lines[number:]:
            if not row.startswith("|"):
                break
            rows.append(row)
        for i, row in enumerate(rows[2:]):  # header, separator
            cells = [c.strip() for c in row.strip().strip("|").split("|")]
            if len(cells) != len(columns):
                found.append((f"{table['group']}.<{len(columns)} columns>", row, number + 3 + i))
                continue
            for name, cell in zip(columns, cells, strict=True):
                if name != "_":
                    found.append((f"{table['group']}.{name}[{i}]", cell, number + 3 + i))
    return found


def page_mismatches(page: Path) -> list[str]:
    """Every bound number of ``page`` that is not its registered value at the printed digits."""
    bad = []
    for key, text, line in bindings(page):
        try:
            value = lookup(key)
        except (KeyError, IndexError, TypeError) as error:
            bad.append(f"{page.name}:{line}: {key}: not in docs/numbers.toml ({error!r})")
            continue
        if not printed_as(text, value):
            bad.append(f"{page.name}:{line}: {key} prints {text!r}, registered {value!r}")
    return bad
