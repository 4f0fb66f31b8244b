"""The code blocks of the Markdown pages, and what their markers say about running them
(docs/documentation.md, "Every example is a test"; tests/test_docs_examples.py runs them).

A marker is an HTML comment on the lines right above a fence (no blank line between), which
neither GitHub nor the site shows:

- ``<!-- example: skip REASON -->``: not run (it needs MPI, a GPU, a cluster, or names from the
  surrounding text); still checked without running (:func:`static_problems`);
- ``<!-- example: quick OLD => NEW; OLD2 => NEW2 -->``: run with these replacements (the page
  shows the paper's scale, the test runs the quick one); each OLD must occur in the block;
- ``<!-- example: setup CODE -->``: Python run just before the block, for the names it takes
  from the text around it (several such lines: one line of code each);
- ``<!-- example: after COMMAND; COMMAND -->``: ``parastokes`` commands run first in the page's
  folder (the run whose output the block reads);
- ``<!-- example: file NAME -->``: the block is a file of the reader's, written to NAME;
- ``<!-- example: prints TEXT -->``: what the block prints contains TEXT (the page quotes it);
- ``<!-- file: NAME -->``, ``<!-- append: NAME -->``, ``<!-- run: NAME -->``: docs/extending.md's
  walk-through, run by tests/test_extending.py.

Unmarked blocks run, in order, after the page's earlier runnable blocks (one interpreter per page,
one namespace, in an empty folder, like a notebook).
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: The pages whose code blocks are examples.
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
#: The markers of docs/extending.md's walk-through (tests/test_extending.py's BLOCK).
WALK_THROUGH = ("file", "append", "run")

_FENCE = re.compile(r"^(?P<indent>\s*)```(?P<lang>[^\s`]*)(\s[^`]*)?$")
_MARKER = re.compile(r"^\s*<!--\s*(?P<kind>example:\s*\w+|[\w-]+:?)\s*(?P<args>.*?)\s*-->\s*$")


@dataclass
class Block:
    """A fenced code block: its page, the line of its opening fence, language, code, markers."""

    page: Path
    line: int
    lang: str
    code: str
    markers: dict[str, list[str]] = field(default_factory=dict)

    @property
    def label(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    @property
    def runs(self) -> bool:
        """Run by tests/test_docs_examples.py: a Python block without a skip, file or
        walk-through marker."""
        return self.lang == "python" and not ({"skip", "file", *WALK_THROUGH} & set(self.markers))

    def marker(self, kind: str, sep: str = ";") -> str:
        """The arguments of the markers of ``kind``, in page order, joined by ``sep``."""
        return sep.join(self.markers.get(kind, []))

    def runnable_code(self) -> str:
        """The code as run: the ``quick`` replacements made; ValueError naming an OLD that the
        block does not contain. Padded with newlines so that tracebacks give the page's lines."""
        code = self.code
        for rule in filter(None, (r.strip() for r in self.marker("quick").split(";"))):
            old, _, new = (part.strip() for part in rule.partition("=>"))
            if old not in code:
                raise ValueError(f"{self.label}: the quick replacement's {old!r} is not in the "
                                 "block")
            code = code.replace(old, new)
        setup = self.marker("setup", "\n")
        if not setup:
            return "\n" * self.line + code
        return setup + "\n" * max(1, self.line - setup.count("\n")) + code

    def commands(self) -> list[str]:
        """The ``after`` commands, in order."""
        return [c.strip() for c in self.marker("after").split(";") if c.strip()]


def blocks(page: Path) -> list[Block]:
    """Every fenced block of ``page``, with the markers right above it."""
    lines = page.read_text().split("\n")
    found = []
    i = 0
    while i < len(lines):
        fence = _FENCE.match(lines[i])
        if not fence:
            i += 1
            continue
        indent = fence["indent"]
        end = i + 1
        while not re.match(r"^\s*```\s*$", lines[end]):
            end += 1
        markers = {}
        k = i - 1
        while k >= 0 and (marker := _MARKER.match(lines[k])):
            kind = marker["kind"].removeprefix("example:").strip().rstrip(":")
            markers.setdefault(kind, []).insert(0, marker["args"])
            k -= 1
        code = "\n".join(line[len(indent):] for line in lines[i + 1:end])
        found.append(Block(page, i + 1, fence["lang"], code + "\n", markers))
        i = end + 1
    return found


def python_blocks() -> list[Block]:
    """The ``python`` blocks of every page."""
    return [b for page in PAGES for b in blocks(page) if b.lang == "python"]


# ---- checks without running ---------------------------------------------------------------------
def _bindings(tree: ast.AST) -> tuple[dict[str, Any], list[str]]:
    """The names a block imports from parastokes, and the imports that fail."""
    bound: dict[str, Any] = {}
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "parastokes":
            module = importlib.import_module(node.module)
            for alias in node.names:
                try:
                    obj = getattr(module, alias.name)
                except AttributeError:
                    try:
                        obj = importlib.import_module(f"{node.module}.{alias.name}")
                    except ImportError:
                        problems.append(f"line {node.lineno}: cannot import {alias.name!r} from "
                                        f"{node.module}")
                        continue
                bound[alias.asname or alias.name] = obj
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "parastokes":
                    module = importlib.import_module(alias.name)
                    if alias.asname:
                        bound[alias.asname] = module
                    else:
                        bound["parastokes"] = importlib.import_module("parastokes")
    return bound, problems


def _resolve(node: ast.expr, bound: dict[str, Any], problems: list[str]) -> Any:
    """The object an expression ``a.b.c`` rooted at an imported name stands for (None when it is
    not such an expression); a missing attribute of a module is a problem."""
    if isinstance(node, ast.Name):
        return bound.get(node.id)
    if isinstance(node, ast.Attribute):
        base = _resolve(node.value, bound, problems)
        if base is None:
            return None
        try:
            return getattr(base, node.attr)
        except AttributeError:
            if isinstance(base, ModuleType):
                problems.append(f"line {node.lineno}: {base.__name__} has no {node.attr!r}")
            return None
    return None


def static_problems(code: str) -> list[str]:
    """What is wrong with a block without running it: its imports from parastokes, the attributes
    of parastokes modules it names, and the arguments of its calls of parastokes functions and
    classes (bound to their signatures). Names the block assigns itself are not followed."""
    tree = ast.parse(code)
    bound, problems = _bindings(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            _resolve(node, bound, problems)
        if not isinstance(node, ast.Call):
            continue
        target = _resolve(node.func, bound, [])
        if target is None or not callable(target) or any(
                isinstance(a, ast.Starred) for a in node.args) or any(
                k.arg is None for k in node.keywords):
            continue
        try:
            signature = inspect.signature(target)
        except (TypeError, ValueError):  # compiled functions without a signature
            continue
        try:
            signature.bind(*node.args, **{k.arg: k.value for k in node.keywords})
        except TypeError as error:
            problems.append(f"line {node.lineno}: {ast.unparse(node.func)}(...): {error}")
    return problems
