"""The import direction of the package: each layer imports only the layers below it, and no two
modules import each other (directly or around a loop), lazy imports inside functions included.

Layers, bottom to top: errors; checks, native; spatial, targets, results; mechanism; collision;
catalog; closed_form; problem; solvers; diffik; applications (problem_files, progress, batch, reach,
path, plot, harness, benchmarks, problems, view, cli). The top-level folders ``benchmarks/`` and ``problems/``
are the packages ``optik.benchmarks`` and ``optik.problems`` (setup.py maps them) and are checked
as such. A package's ``__init__`` may import its own submodules (it re-exports them).
"""

from __future__ import annotations

import ast
import pathlib

import optik

ROOT = pathlib.Path(optik.__file__).parent

LAYERS = [
    {"errors"},
    {"checks", "native"},
    {"spatial", "targets", "results"},
    {"mechanism"},
    {"collision"},
    {"catalog"},
    {"closed_form"},
    {"problem"},
    {"solvers"},
    {"diffik"},
    {
        "problem_files",
        "progress",
        "batch",
        "reach",
        "path",
        "plot",
        "harness",
        "benchmarks",
        "problems",
        "view",
        "cli",
    },
]
LEVEL = {name: i for i, layer in enumerate(LAYERS) for name in layer}


MAPPED = {"optik.benchmarks": ROOT.parent / "benchmarks", "optik.problems": ROOT.parent / "problems"}
"""Packages whose source is a top-level folder of the repository (absent in a wheel install, where
they are folders of the package itself)."""


def _modules() -> dict[str, pathlib.Path]:
    mods = {}
    roots = [(ROOT, "optik")] + [(d, pkg) for pkg, d in MAPPED.items() if (d / "__init__.py").is_file()]
    for root, package in roots:
        for path in root.rglob("*.py"):
            parts = (*package.split("."), *path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join(parts)] = path
    return mods


def _imports(path: pathlib.Path, name: str, mods: dict[str, pathlib.Path]) -> set[str]:
    """Every optik module that ``name`` imports (resolved to a module of the package)."""
    out: set[str] = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
        for t in targets:
            while t and t not in mods:
                t = t.rpartition(".")[0]
            if t.startswith("optik.") and t != name:
                out.add(t)
    return out


def _layer(mod: str) -> str:
    return mod.split(".")[1]


def test_layers_import_only_downwards():
    mods = _modules()
    unknown = sorted({_layer(m) for m in mods if m != "optik" and _layer(m) not in LEVEL})
    assert not unknown, f"modules of no layer (add them to LAYERS): {unknown}"
    bad = []
    for name, path in mods.items():
        if name == "optik":
            continue
        for dep in _imports(path, name, mods):
            if LEVEL[_layer(dep)] > LEVEL[_layer(name)]:
                bad.append(f"{name} -> {dep}")
    assert not bad, "imports against the layer direction:\n" + "\n".join(sorted(bad))


def test_no_import_cycles():
    mods = _modules()
    graph = {}
    for name, path in mods.items():
        deps = _imports(path, name, mods)
        # a package's __init__ re-exporting its submodules is not a cycle
        graph[name] = {d for d in deps if not d.startswith(name + ".")} - {"optik"}
    # strongly connected components (Tarjan)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    cycles: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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
                cycles.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles, "modules importing each other: " + "; ".join(" <-> ".join(c) for c in cycles)
