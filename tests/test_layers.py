"""The import layers (docs/design.md, "Layers"): the import-linter contract of pyproject.toml holds
(`lint-imports`, as .ci/run runs it), it fails on an import from a lower layer to a higher one, no
import circle joins modules of different folders, and no two folders reach each other."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import grimp

ROOT = Path(__file__).resolve().parents[1]
LINT = "import sys; from importlinter.cli import lint_imports_command; lint_imports_command()"


def _lint(root: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", LINT, "--no-cache", "--no-logo"], cwd=root,
                          capture_output=True, text=True, timeout=300)


def test_the_import_contract_holds():
    done = _lint(ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "0 broken" in done.stdout


def test_the_contract_refuses_an_import_from_the_fluid_up_into_the_executors(tmp_path):
    """The circle of issue #33 began with fluid.py importing parallel: the contract names it."""
    shutil.copytree(ROOT / "parastokes", tmp_path / "parastokes",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    fluid = tmp_path / "parastokes" / "fluid" / "__init__.py"
    text = fluid.read_text()
    assert "from .. import mrs\n" in text
    fluid.write_text(text.replace("from .. import mrs\n", "from .. import mrs, parallel  # noqa\n"))
    done = _lint(tmp_path)
    assert done.returncode != 0
    assert "parastokes.fluid is not allowed to import parastokes.parallel" in done.stdout


def _circles(graph: grimp.ImportGraph) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    edges = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in graph.modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for start in sorted(edges):
        if start in index:
            continue
        work = [(start, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = len(index)
                stack.append(node)
                on_stack.add(node)
            if i < len(edges[node]):
                work.append((node, i + 1))
                nxt = edges[node][i]
                if nxt not in index:
                    work.append((nxt, 0))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(component)
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
    return found


def _folder(module: str, graph: grimp.ImportGraph) -> str:
    """The folder (package) a module's file is in."""
    return module if graph.find_children(module) else module.rpartition(".")[0]


def test_no_import_circle_joins_modules_of_different_folders():
    graph = grimp.build_graph("parastokes", cache_dir=None)
    across = [sorted(c) for c in _circles(graph) if len({_folder(m, graph) for m in c}) > 1]
    assert not across, across
    # the check sees circles: one within a folder is allowed (e.g. a kind's system and its
    # compiled parts)
    assert any("parastokes.kinds.rod.system" in c for c in _circles(graph))


def top_folder(module: str) -> str:
    """The top-level folder (or public module) of ``parastokes`` a module belongs to."""
    return module.split(".")[1] if module.count(".") else module


def mutual_folders(graph: grimp.ImportGraph, package: str = "parastokes") -> list[tuple[str, str]]:
    """The pairs of top-level folders of ``package`` that reach each other through imports (each
    directly or through other folders): what a layered tree must not have."""
    edges: dict[str, set[str]] = {}
    for module in graph.modules:
        if not module.startswith(package + "."):
            continue
        for imported in graph.find_modules_directly_imported_by(module):
            if imported.startswith(package + ".") and top_folder(imported) != top_folder(module):
                edges.setdefault(top_folder(module), set()).add(top_folder(imported))
    reach: dict[str, set[str]] = {}
    for start in edges:
        seen: set[str] = set()
        todo = [start]
        while todo:
            for nxt in edges.get(todo.pop(), ()):
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        reach[start] = seen
    return sorted((a, b) for a in reach for b in reach[a] if a < b and a in reach.get(b, ()))


def test_no_two_folders_reach_each_other():
    graph = grimp.build_graph("parastokes", cache_dir=None)
    assert mutual_folders(graph) == []
    # the folders are measured, not just the modules: every layer of the contract is seen
    folders = {top_folder(m) for m in graph.modules if m.startswith("parastokes.")}
    assert {"core", "registry", "integrate", "kinds", "run", "cli"} <= folders


def test_the_folder_measure_finds_a_pair_through_a_third_folder():
    graph = grimp.ImportGraph()
    for module in ("p", "p.a", "p.a.x", "p.b", "p.b.y", "p.c", "p.c.z"):
        graph.add_module(module)
    graph.add_import(importer="p.a.x", imported="p.b.y")
    graph.add_import(importer="p.b.y", imported="p.c.z")
    assert mutual_folders(graph, "p") == []
    graph.add_import(importer="p.c.z", imported="p.a.x")   # a -> b -> c -> a
    assert mutual_folders(graph, "p") == [("a", "b"), ("a", "c"), ("b", "c")]


def test_the_import_paths_of_the_older_guides_are_the_modules_themselves():
    """A body written from the extension guide of rounds 2 and 3 imports these paths: each is the
    very module that moved (one object, so a registration through either is one registration)."""
    import importlib

    moved = {"parastokes.stepping.loop": "parastokes.integrate.loop",
             "parastokes.stepping.fluid": "parastokes.fluid.compiled",
             "parastokes.stepping.registry": "parastokes.registry.loops",
             "parastokes.bodies.registry": "parastokes.registry.kinds",
             "parastokes.coarse.registry": "parastokes.registry.coarse"}
    for old, new in moved.items():
        assert importlib.import_module(old) is importlib.import_module(new), old
    from parastokes.stepping import loop, registry

    assert loop.register_parts is importlib.import_module(moved["parastokes.stepping.loop"]) \
        .register_parts
    assert registry.compiled_loop.__module__ == "parastokes.registry.loops"
