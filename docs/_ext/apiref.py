"""Small Sphinx additions for the generated API reference (docs/api/index.rst).

- ``.. public-names::``: a table of public names (an autosummary table) whose links go to where
  each object is defined. A package re-exports names from its modules (``parastokes.parareal.run``
  is defined in ``parastokes.parareal.algorithm``); each object is documented once, in its home
  module, and the table lists the names a user imports. Its content lists names, or its option
  ``:all-of: PACKAGE`` takes the package's ``__all__``, so new public names appear by themselves.
- Summaries that do not stop at "eq.": autosummary's one-line summary of an object is its first
  sentence, and the docstrings cite the paper's equations as "eq. 30".
- Sibling-relative references: ``:mod:`.registry``` in a docstring of ``parastokes.coarse.x``
  means ``parastokes.registry.coarse``, as in a relative import; Sphinx alone searches every
  module ending in ``.registry`` and finds several.
- Attribute docs are prose: napoleon reads the first line of the documentation of an attribute,
  a constant or a property as ``type: description`` when it holds a colon, so "Columns of the
  state: ..." showed "Columns of the state" as its type and the rest cut off (``Rosenbrock.g``,
  75 others). Their types come from the annotations; the text stays whole.
"""

from __future__ import annotations

import importlib
import inspect
import sys
from types import ModuleType
from typing import ClassVar

from docutils.parsers.rst import directives
from sphinx import addnodes
from sphinx.application import Sphinx
from sphinx.ext import autosummary
from sphinx.ext.autosummary import Autosummary
from sphinx.ext.napoleon.docstring import GoogleDocstring
from sphinx.transforms.post_transforms import SphinxPostTransform


def home(name: str) -> str:
    """The dotted name under which the object ``name`` (a public address) is documented: where a
    function or class is defined; the name itself for modules and other values."""
    module_name, _, attribute = name.rpartition(".")
    obj = getattr(importlib.import_module(module_name), attribute)
    obj = getattr(obj, "py_func", obj)  # a numba dispatcher: its Python function
    if inspect.isclass(obj) or inspect.isroutine(obj):
        return f"{obj.__module__}.{obj.__qualname__}"
    return name


def public_names(package: str) -> list[str]:
    """The names of ``package.__all__`` defined elsewhere (not modules), as dotted names: those
    that the page of ``package`` does not document itself."""
    module = importlib.import_module(package)
    names = [f"{package}.{name}" for name in module.__all__
             if not isinstance(getattr(module, name), ModuleType)]
    return [name for name in names if home(name).rpartition(".")[0] != package]


class PublicNames(Autosummary):
    """An autosummary table of public addresses, each linked to its object's home."""

    option_spec: ClassVar = {**Autosummary.option_spec, "all-of": directives.unchanged}

    def run(self):
        if "all-of" in self.options:
            package = self.options["all-of"]  # the current module: its names, relative to it
            self.content = self.content.__class__(
                [name.removeprefix(f"{package}.") for name in public_names(package)])
        return super().run() if self.content else []

    def get_items(self, names: list[str]) -> list[tuple[str, str | None, str, str]]:
        items = []
        for display, signature, summary, real_name in super().get_items(names):
            items.append((display.removeprefix("parastokes."), signature, summary,
                          home(real_name)))
        return items


class SiblingReferences(SphinxPostTransform):
    """``.name`` in a docstring of module ``a.b.m`` (or of package ``a.b``) means ``a.b.name``."""

    default_priority = 5  # before the references are resolved (10)

    def run(self, **kwargs) -> None:
        objects = self.env.get_domain("py").objects
        for node in self.document.findall(addnodes.pending_xref):
            if node.get("refdomain") != "py" or not node.get("refspecific"):
                continue
            context = node.get("py:module")
            if not context or context not in sys.modules:
                continue
            package = context if hasattr(sys.modules[context], "__path__") else \
                context.rpartition(".")[0]
            target = f"{package}.{node['reftarget']}"
            if target in objects:
                node["reftarget"] = target
                node["refspecific"] = False


#: Abbreviations that end no sentence, added to autosummary's own (its module's global, read by
#: its ``extract_summary``).
ABBREVIATIONS = ("eq.", "eqs.", "Eq.", "Eqs.")


def prose_attribute(self: GoogleDocstring) -> tuple[str, list[str]]:
    """napoleon's ``_consume_inline_attribute`` without the inline type: (no type, the whole
    documentation parsed as a docstring of its own, sections included)."""
    lines = [self._lines.next(), *self._dedent(self._consume_to_end())]
    return "", self.__class__(lines, self._config).lines()


def setup(app: Sphinx) -> dict:
    GoogleDocstring._consume_inline_attribute = prose_attribute  # (NumpyDocstring's too)
    autosummary.WELL_KNOWN_ABBREVIATIONS = tuple(
        dict.fromkeys((*autosummary.WELL_KNOWN_ABBREVIATIONS, *ABBREVIATIONS)))
    app.add_directive("public-names", PublicNames)
    app.add_post_transform(SiblingReferences)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
