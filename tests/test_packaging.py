"""Packaging basics: the LICENSE file is the license pyproject.toml declares, and CITATION.cff
names the package at its version with its license and the paper it implements (the keys that
CFF 1.2.0 requires; the full schema was checked with ``cffconvert --validate``)."""

import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def test_the_license_file_is_the_declared_mit_license():
    assert _project()["license"] == {"text": "MIT"}
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("MIT License\n\nCopyright (c) 2026 parastokes developers\n")
    assert "Permission is hereby granted, free of charge" in text


def test_the_citation_file_has_the_packages_version_license_and_the_paper():
    text = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    # (a version bump in pyproject.toml must bump it here too)
    assert re.search(r"^version: (\S+)$", text, re.M).group(1) == _project()["version"]
    yaml = pytest.importorskip("yaml")
    cff = yaml.safe_load(text)
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    assert cff["title"] == _project()["name"] and cff["license"] == "MIT"
    assert cff["message"] and cff["authors"] == [{"name": "parastokes developers"}]
    paper = cff["preferred-citation"]
    assert paper["type"] == "article"
    assert paper["title"] == "Parallel-in-time simulation of biofluids"
    assert [(a["given-names"], a["family-names"]) for a in paper["authors"]] == [
        ("Weifan", "Liu"), ("Minghao W.", "Rostami")]
    assert "doi" not in paper  # the paper's text states none: never invented


def test_the_changelog_opens_with_the_packages_version():
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    first = re.search(r"^## (\S+) ", text, re.M)
    assert first is not None and first.group(1) == _project()["version"]
