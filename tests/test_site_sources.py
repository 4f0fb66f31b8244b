"""What the site shows from the sources, checked without building it (the build: docs/
documentation.md): the docstrings' literals are literals (``x`` where reStructuredText sees it:
not after "0.." or "~", not glued to a word, not in a NumPy "Returns" type), an attribute's
documentation is its text and not a type (docs/_ext/apiref.py), and no formula of a Markdown page
is read as emphasis."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
import sys
from pathlib import Path

import pytest

import parastokes

docutils_core = pytest.importorskip("docutils.core")
napoleon = pytest.importorskip("sphinx.ext.napoleon.docstring")
from docutils import nodes  # noqa: E402
from sphinx.ext.napoleon import Config  # noqa: E402

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _docstrings():
    """(where, docstring, what) of every module, class, function and method of the package that
    imports here (the GPU modules need numba's CUDA target)."""
    for info in pkgutil.walk_packages(parastokes.__path__, "parastokes."):
        try:
            module = importlib.import_module(info.name)
        except Exception:  # (a GPU module without numba-cuda: not on this machine's site)
            continue
        yield info.name, module.__doc__, "module"
        for name, obj in vars(module).items():
            if getattr(obj, "__module__", None) != info.name:
                continue
            if inspect.isclass(obj):
                yield f"{info.name}.{name}", obj.__doc__, "class"
                for attr, member in vars(obj).items():
                    if inspect.isfunction(member):
                        yield f"{info.name}.{name}.{attr}", member.__doc__, "method"
            elif inspect.isfunction(obj):
                yield f"{info.name}.{name}", obj.__doc__, "function"


def _unseen_literals(text: str, what: str) -> list[str]:
    """The paragraphs of ``text`` (after napoleon, as the API pages use it) in which a double
    backtick is left as text, and the type fields that hold one."""
    lines = napoleon.NumpyDocstring(inspect.cleandoc(text), Config(), what=what).lines()
    bad = [line for line in lines if re.match(r"\s*:r?type[^:]*:.*``", line)]
    tree = docutils_core.publish_doctree("\n".join(lines), settings_overrides={
        "report_level": 5, "halt_level": 5})
    for node in tree.findall(nodes.Text):
        if "``" in node.astext() and not isinstance(node.parent, nodes.literal):
            bad.append(node.astext()[:120])
    return bad


def test_every_double_backtick_of_the_docstrings_is_a_literal():
    found = {where: bad for where, doc, what in _docstrings() if doc
             for bad in [_unseen_literals(doc, what)] if bad}
    assert not found


def test_a_glued_literal_is_found():
    assert _unseen_literals("Steps of size ~``dt``; j = 0..``count``.", "function")
    assert _unseen_literals("Returns\n-------\nu, or (u, w) when ``angular``: arrays\n",
                            "function")
    assert not _unseen_literals("Steps of size about ``dt``; ``x``'s (``y``).", "function")


def test_an_attributes_documentation_is_its_text_not_a_type(monkeypatch):
    """napoleon reads "Columns of the state: c (0-2), ..." as a type and a description (the API
    page showed the type "Columns of the state" and the rest cut off); docs/_ext/apiref.py keeps
    the text whole."""
    text = ["Coefficients of ``h f_t`` in the stages' right-hand sides (f_t: the rates'",
            "derivative in time at the step's start)."]
    plain = napoleon.NumpyDocstring(text, Config(), what="attribute", name="g").lines()
    assert any(line.startswith(":type:") for line in plain)  # napoleon alone
    monkeypatch.syspath_prepend(str(DOCS / "_ext"))
    apiref = importlib.import_module("apiref")
    monkeypatch.setattr(napoleon.GoogleDocstring, "_consume_inline_attribute",
                        apiref.prose_attribute)
    for style in (napoleon.NumpyDocstring, napoleon.GoogleDocstring):
        assert style(text, Config(), what="attribute", name="g").lines()[:2] == text
    sys.modules.pop("apiref", None)


def test_no_formula_of_a_markdown_page_is_read_as_emphasis():
    """CommonMark opens emphasis at "_" after a parenthesis: "G2(x_new)_S − G2(x_old)_S" showed
    "S − G2(x_old)" in italics (docs/hodmd.md); such an underscore is escaped."""
    markdown_it = pytest.importorskip("markdown_it")
    md = markdown_it.MarkdownIt("commonmark").enable("table")
    for page in sorted(DOCS.glob("*.md")):
        html = md.render(page.read_text(encoding="utf-8"))
        for em in re.findall(r"<em>(.*?)</em>", html, re.S):
            assert not re.search(r"[_^=]", re.sub(r"<[^>]+>", "", em)), (page.name, em)
    before = "+ [G2(x_new)_S − G2(x_old)_S] + H(T_n)),\nx_new = X_{n-1}^k, x_old = X_{n-1}^{k-1}."
    assert "<em>S − G2(x_old)" in md.render(before)  # as the page was: found
