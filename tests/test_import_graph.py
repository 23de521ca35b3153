"""The import graph of the five packages, read from the source with `ast` (nothing is imported).

Every `import` and `from ... import` counts, at module level or inside a function: a lazy import
that breaks a circle at run time is still a circle in the design. Two rules:
- no circles (a strongly connected component of more than one module, or a module importing itself);
- `schemas` (the data contract, the lowest layer) imports nothing from the packages built on it.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("mimicbench", "schemas", "datagen", "benchmark", "baselines")


def module_files(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> source file, for every .py file of the five packages."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The deepest known module that `name` (a dotted name, maybe ending in an attribute) lies in."""
    parts = name.split(".")
    while parts:
        dotted = ".".join(parts)
        if dotted in modules:
            return dotted
        parts.pop()
    return None


def imports_of(module: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The modules of the five packages that `module` names in any import statement."""
    is_package = path.name == "__init__.py"
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".") if is_package else module.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module
            # `from a.b import c`: c is the submodule a.b.c when that file exists, else a name in a.b
            names = [f"{prefix}.{a.name}" for a in node.names]
        else:
            continue
        for name in names:
            target = _resolve(name, modules)
            if target is not None and target != module:
                out.add(target)
    return out


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    modules = module_files(root)
    return {m: imports_of(m, p, modules) for m, p in modules.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative), each sorted."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    m = stack.pop()
                    on_stack.discard(m)
                    component.append(m)
                    if m == node:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return sorted(out)


def test_the_walker_sees_a_circle_and_an_upward_import(tmp_path):
    """The checker itself, on a small tree written here: a -> b -> c -> a, and schemas -> benchmark."""
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
        (tmp_path / pkg / "__init__.py").write_text("")
    (tmp_path / "datagen" / "a.py").write_text("from datagen import b\n")
    (tmp_path / "datagen" / "b.py").write_text("def f():\n    from .c import g\n")
    (tmp_path / "datagen" / "c.py").write_text("import datagen.a as a\nimport numpy\ng = 1\n")
    (tmp_path / "datagen" / "d.py").write_text("from datagen.c import g\n")
    (tmp_path / "schemas" / "x.py").write_text("from ..benchmark import y\n")
    (tmp_path / "benchmark" / "y.py").write_text("from schemas.x import z\n")
    graph = import_graph(tmp_path)
    assert graph["datagen.b"] == {"datagen.c"} and graph["datagen.c"] == {"datagen.a"}
    assert graph["schemas.x"] == {"benchmark.y"}
    assert circles(graph) == [["benchmark.y", "schemas.x"], ["datagen.a", "datagen.b", "datagen.c"]]
    assert upward_from_schemas(graph) == ["schemas.x -> benchmark.y"]


def upward_from_schemas(graph: dict[str, set[str]]) -> list[str]:
    return sorted(f"{m} -> {t}" for m, ts in graph.items() if m.split(".")[0] == "schemas"
                  for t in ts if t.split(".")[0] != "schemas")


@pytest.fixture(scope="module")
def graph():
    return import_graph()


def test_every_package_is_walked(graph):
    assert {m.split(".")[0] for m in graph} == set(PACKAGES) and len(graph) > 200
    assert {"schemas.errors", "schemas.weights"} <= graph["schemas.character"] | graph["schemas.shards"] | graph["schemas.manifest"]
    assert "benchmark.batch" in graph["benchmark.ray_runner"]  # a lazy import inside a function counts


def test_no_import_circles(graph):
    found = circles(graph)
    assert not found, "import circles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_schemas_imports_nothing_built_on_it(graph):
    up = upward_from_schemas(graph)
    assert not up, "schemas imports up into the packages built on it:\n" + "\n".join(up)
