"""The floors of the one import root ``mimicbench``, read from the source with ``ast`` (nothing is imported).

Every ``import`` and ``from ... import`` counts, at module level or inside a function (a lazy import
that breaks a circle at run time is still a circle in the design), and so does every string constant
that names a module exactly (``"mimicbench.baselines.npt.training:TRAINABLE"``, ``-m`` targets): a
name held as a string is an import an import reader would not see. The rules:
- no circles (a strongly connected component of more than one module);
- floors, lowest first: the package root (``__version__``), the data contract ``schemas``, the
  ``geometry`` core, the ``runtime`` (registry, options, errors, engines, training), ``datagen``,
  ``benchmark``, ``baselines``, and the roof (CLI, commands, pipeline), which alone knows every
  floor; no arrow runs from a floor to one above it, checked for every pair of floors;
- no import names a user folder bare (``import datagen``): those folders install as
  ``mimicbench.datagen`` and so on, and a bare name would load a second copy from a source checkout.
"""
from __future__ import annotations

import ast
import itertools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
USER_FOLDERS = ("schemas", "datagen", "benchmark", "baselines")
# floor name -> the module prefixes on it, lowest floor first
FLOORS = {
    "root": ("mimicbench",),
    "schemas": ("mimicbench.schemas",),
    "geometry": ("mimicbench.geometry",),
    "runtime": ("mimicbench.runtime", "mimicbench.engines", "mimicbench.training"),
    "datagen": ("mimicbench.datagen",),
    "benchmark": ("mimicbench.benchmark",),
    "baselines": ("mimicbench.baselines",),
    "roof": ("mimicbench.cli", "mimicbench.__main__", "mimicbench.commands", "mimicbench.pipeline"),
}
MODULE_STRING = re.compile(r"^(?P<module>[A-Za-z_][\w]*(?:\.[A-Za-z_]\w*)+)(?::[A-Za-z_][\w.]*)?$")


def module_files(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name (as installed) -> source file: ``mimicbench/`` and the four user folders."""
    out = {}
    for folder, prefix in [("mimicbench", [])] + [(f, ["mimicbench"]) for f in USER_FOLDERS]:
        for path in sorted((root / folder).rglob("*.py")):
            parts = prefix + list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The deepest known module that ``name`` (a dotted name, maybe ending in an attribute) lies in."""
    parts = name.split(".")
    while parts:
        dotted = ".".join(parts)
        if dotted in modules:
            return dotted
        parts.pop()
    return None


def imports_of(module: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The modules of the root that ``module`` names in an import statement or an exact string."""
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
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            match = MODULE_STRING.match(node.value)
            names = [match["module"]] if match and match["module"] in modules else []
        else:
            continue
        for name in names:
            target = _resolve(name, modules)
            if target is not None and target != module:
                out.add(target)
    return out


def bare_imports(path: Path) -> list[str]:
    """Import statements of ``path`` that name a user folder bare (``import datagen``, ``from schemas import x``)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        else:
            continue
        out += [f"{path.name}:{node.lineno}: {n}" for n in names if n.split(".")[0] in USER_FOLDERS]
    return out


def import_graph(root: Path = ROOT) -> dict[str, set[str]]:
    modules = module_files(root)
    return {m: imports_of(m, p, modules) for m, p in modules.items()}


def floor_of(module: str) -> str:
    """The floor whose longest prefix ``module`` starts with."""
    best, length = None, -1
    for floor, prefixes in FLOORS.items():
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > length:
                best, length = floor, len(prefix)
    return best


def arrows(graph: dict[str, set[str]], lower: str, upper: str) -> list[str]:
    """Every import from a module on floor ``lower`` to one on floor ``upper``."""
    return sorted(f"{m} -> {t}" for m, ts in graph.items() if floor_of(m) == lower for t in ts
                  if floor_of(t) == upper)


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



def test_the_walker_sees_circles_upward_arrows_and_names_held_as_strings(tmp_path):
    """The checker itself, on a small tree written here."""
    for pkg in ("mimicbench",) + USER_FOLDERS:
        (tmp_path / pkg).mkdir()
        (tmp_path / pkg / "__init__.py").write_text("")
    (tmp_path / "datagen" / "a.py").write_text("from mimicbench.datagen import b\n")
    (tmp_path / "datagen" / "b.py").write_text("def f():\n    from .c import g\n")
    (tmp_path / "datagen" / "c.py").write_text("import mimicbench.datagen.a as a\nimport numpy\ng = 1\n")
    (tmp_path / "datagen" / "d.py").write_text("from mimicbench.datagen.c import g\nimport datagen.a\n")
    (tmp_path / "schemas" / "x.py").write_text("from ..benchmark import y\n")
    (tmp_path / "benchmark" / "y.py").write_text("TABLE = {'m': 'mimicbench.schemas.x:z', 'n': 'mimicbench.zoo'}\n")
    graph = import_graph(tmp_path)
    assert graph["mimicbench.datagen.b"] == {"mimicbench.datagen.c"}
    assert graph["mimicbench.datagen.c"] == {"mimicbench.datagen.a"}
    assert graph["mimicbench.schemas.x"] == {"mimicbench.benchmark.y"}
    assert graph["mimicbench.benchmark.y"] == {"mimicbench.schemas.x"}  # held as a string
    assert circles(graph) == [["mimicbench.benchmark.y", "mimicbench.schemas.x"],
                              ["mimicbench.datagen.a", "mimicbench.datagen.b", "mimicbench.datagen.c"]]
    assert arrows(graph, "schemas", "benchmark") == ["mimicbench.schemas.x -> mimicbench.benchmark.y"]
    assert bare_imports(tmp_path / "datagen" / "d.py") == ["d.py:2: datagen.a"]


@pytest.fixture(scope="module")
def graph():
    return import_graph()


def test_every_module_is_walked_and_on_one_floor(graph):
    assert {m.split(".")[1] for m in graph if "." in m} >= set(USER_FOLDERS) | {"geometry", "runtime", "cli"}
    assert len(graph) > 200
    assert {m for m in graph if floor_of(m) is None} == set()
    assert "mimicbench.benchmark.batch" in graph["mimicbench.benchmark.ray_runner"]  # a lazy import counts
    assert "mimicbench.datagen.ingest.command" in graph["mimicbench.cli"]
    assert graph["mimicbench"] == set(), "the package root imports nothing"


def test_no_import_circles(graph):
    found = circles(graph)
    assert not found, "import circles:\n" + "\n".join(" <-> ".join(c) for c in found)


@pytest.mark.parametrize("lower, upper", list(itertools.combinations(FLOORS, 2)))
def test_no_arrow_runs_up(graph, lower, upper):
    up = arrows(graph, lower, upper)
    assert not up, f"the {lower} floor imports the {upper} floor above it:\n" + "\n".join(up)


def test_no_user_folder_is_imported_bare():
    paths = [p for folder in ("mimicbench", "tests", "analyses", "benchmarks", "tools", "examples") + USER_FOLDERS
             for p in sorted((ROOT / folder).rglob("*.py"))]
    found = [line for p in paths for line in bare_imports(p)]
    assert not found, "bare imports of a user folder (write mimicbench.<folder>...):\n" + "\n".join(found)
