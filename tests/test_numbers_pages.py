"""The pages print what docs/numbers.toml registers, and every registered group is recomputed.

The registry is the one place the documented numbers live (docs/validation.md, "How the numbers
are pinned"): a number a page binds to it must show the registered value at its printed digits, so
the page cannot drift from what the tests recompute; and every group names the tests that recompute
it, which must exist and use it.
"""

from __future__ import annotations

import math
import re

import pytest
from documented import PAGES, RESERVED, ROOT, bindings, page_mismatches, printed_as, registry


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_bound_number_prints_its_registered_value(page):
    assert not page_mismatches(page)


def test_the_validation_page_binds_numbers_of_every_section():
    keys = {key.split(".")[0] for key, _, _ in bindings(ROOT / "docs" / "validation.md")}
    assert {"rod_fig3", "rod_fig5", "coarse_slices"} <= keys


@pytest.mark.parametrize("group", sorted(registry()))
def test_every_group_is_recomputed_by_a_named_test(group):
    entry = registry()[group]
    assert entry.get("command"), f"{group}: no command"
    assert entry.get("tests"), f"{group}: no test"
    assert set(entry) - RESERVED, f"{group}: no values"
    for name in entry.get("tolerance", {}):
        assert name in entry, f"{group}: a tolerance for {name!r}, which it does not have"
    for test in entry["tests"]:
        path, _, function = test.partition("::")
        source = (ROOT / path).read_text()
        assert re.search(rf"^def {function}\(", source, re.M), f"{group}: no {test}"
        assert f'"{group}"' in source, f"{path} does not read the group {group!r}"


def test_printed_digits():
    """The page check's rule: a printed number stands for every value that rounds to it."""
    assert printed_as("3.57e-09", 3.5700115e-09) and not printed_as("3.57e-09", 3.576e-09)
    assert printed_as("37", 37.02) and not printed_as("37", 37.6)
    assert printed_as("1.43", 1.4251) and not printed_as("1.43", 1.4249)
    assert printed_as("14 161", 14161.2) and printed_as("−1.6e-21", -1.597e-21)
    assert printed_as("yes", True) and printed_as("no", False) and not printed_as("no", True)
    assert printed_as("—", math.nan) and not printed_as("0.75", math.nan)
