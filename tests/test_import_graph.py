"""The layers point one way: no import cycle among brdflab's modules (issue 39).

Every ``import`` and ``from … import …`` of every module under ``brdflab/`` and ``cli/`` (installed as
``brdflab.cli``) counts, at module level or inside a function alike: an import deferred into a function
hides a cycle from Python's loader but not from a reader. ``from package import name`` is an edge to the
submodule when ``name`` is one, else to the package. A package's ``__init__`` re-exports; the edge from a
submodule to the package that contains it is not counted (Python imports the parent first by design).
"""

from __future__ import annotations

import ast
from pathlib import Path

from tests.conftest import ROOT


def _modules() -> dict[str, Path]:
    mods = {}
    for base, prefix in ((ROOT / "brdflab", "brdflab"), (ROOT / "cli", "brdflab.cli")):
        for path in base.rglob("*.py"):
            rel = path.relative_to(base).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            mods[".".join([prefix, *parts])] = path
    return mods


def import_graph() -> dict[str, set[str]]:
    """Module name → the brdflab modules it imports (see the module docstring for the rules)."""
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = name.split(".") if is_pkg else name.split(".")[:-1]
                    base = base[: len(base) - node.level + 1]
                    src = ".".join(base + ([node.module] if node.module else []))
                else:
                    src = node.module or ""
                for a in node.names:
                    sub = f"{src}.{a.name}"
                    targets.append(sub if sub in mods else src)
            for t in targets:
                while t and t not in mods:  # ``import brdflab.x.y`` of a non-module attribute
                    t = t.rpartition(".")[0]
                if t and t != name and not name.startswith(t + "."):
                    graph[name].add(t)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle():
    found = cycles(import_graph())
    assert not found, "import cycles among brdflab's modules:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_the_cycle_check_sees_a_cycle_deferred_into_a_function():
    """Negative control: a cycle through a function-level import (as report/jinja.py <-> page.py had) is found."""
    graph = import_graph()
    assert "brdflab.pages.jinja" in graph["brdflab.pages.page"]
    planted = {k: set(v) for k, v in graph.items()}
    planted["brdflab.pages.jinja"].add("brdflab.pages.page")  # jinja importing page closes a loop
    assert any("brdflab.pages.page" in c and "brdflab.pages.jinja" in c for c in cycles(planted))
    # the old kernels -> workers -> film -> kernels circle, through aot's function-level import
    planted = {k: set(v) for k, v in graph.items()}
    planted["brdflab.kernels.aot"].add("brdflab.workers")
    assert any({"brdflab.kernels.aot", "brdflab.workers", "brdflab.film"} <= set(c) for c in cycles(planted))


def test_the_graph_reads_imports_inside_functions():
    """The kernels' build reaches the process utilities from inside a function: the edge is seen."""
    assert "brdflab.processes" in import_graph()["brdflab.kernels.aot"]


def test_no_module_is_named_like_a_public_function():
    """``bl.render``, ``bl.validate``, ``bl.report`` … are functions; no module of brdflab has such a name (a
    submodule would shadow or be shadowed by the function on the package)."""
    import inspect

    import brdflab as bl

    functions = {n for n in bl.__all__ if not n.startswith("_") and inspect.isroutine(getattr(bl, n))}
    assert {"render", "validate", "report", "check", "plot", "fit", "compare"} <= functions
    clashes = sorted(m for m in _modules() if m.rpartition(".")[2] in functions)
    assert not clashes, clashes
