"""The package's shape: imports flow one way through the layers, with no circles, and an
import inside a function is an optional or heavy third-party dependency with its reason.

Read from the source (``ast``), so a violation fails here before it surprises anyone at run
time. The layer order is the README's "How it is built" diagram.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "voxfield"

#: Lowest first. A module may import its own layer and the layers before it, never after.
LAYERS = (
    ("base", ("voxfield", "voxfield.errors", "voxfield.checks", "voxfield.atomic",
              "voxfield.array_files",
              "voxfield.progress", "voxfield.data", "voxfield.parallel",
              "voxfield.fingerprint")),
    ("kernels", ("voxfield.kernels",)),
    ("error tables", ("voxfield.error_table",)),
    ("scenes", ("voxfield.scene",)),
    ("octrees", ("voxfield.svo",)),
    ("renderers", ("voxfield.render",)),
    ("metrics", ("voxfield.metrics",)),
    ("lighting", ("voxfield.lighting",)),
    ("probes", ("voxfield.probes",)),
    ("light field", ("voxfield.lightfield",)),
    ("studies", ("voxfield.studies",)),
    ("command line", ("voxfield.cli", "voxfield.__main__")),
)


def _modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


MODULES = _modules()


def _layer(module: str) -> int:
    best, rank = -1, None
    for index, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, rank = len(prefix), index
    assert rank is not None, f"{module} belongs to no layer; add it to LAYERS"
    return rank


def _imports(module: str) -> list[tuple[str, ast.stmt, bool]]:
    """(imported voxfield module, statement, inside a function) for every import."""
    path = MODULES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    inside = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            inside.update(id(n) for n in ast.walk(node) if n is not node)
    found = []
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        targets = {n for n in names if n in MODULES and n != module}
        if not targets and names and names[0].split(".")[0] != "voxfield":
            found.append((names[0], node, id(node) in inside))
        found.extend((t, node, id(node) in inside) for t in sorted(targets))
    return found


def test_every_module_has_a_layer():
    for module in MODULES:
        _layer(module)


def test_imports_never_climb_the_layers():
    climbing = []
    for module in MODULES:
        for target, node, _ in _imports(module):
            if target in MODULES and _layer(target) > _layer(module):
                climbing.append(f"{module}:{node.lineno} imports {target} "
                                f"({LAYERS[_layer(module)][0]} → {LAYERS[_layer(target)][0]})")
    assert not climbing, "\n".join(climbing)


def test_the_import_graph_has_no_circles():
    graph = {m: {t for t, _, _ in _imports(m) if t in MODULES} for m in MODULES}
    # A package's __init__ re-exporting its modules is not a circle with them.
    for m in graph:
        graph[m] = {t for t in graph[m] if not t.startswith(m + ".")}
    state: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for t in sorted(graph[m]):
            if state.get(t) == 1:
                circles.append(" → ".join([*stack[stack.index(t):], t]))
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert not circles, "\n".join(circles)


def test_the_library_never_imports_the_command_line():
    users = [f"{m} imports {t}" for m in MODULES
             if _layer(m) != _layer("voxfield.cli")  # the command line and its entry point
             for t, _, _ in _imports(m) if t.startswith("voxfield.cli")]
    assert not users, "\n".join(users)


def test_imports_inside_functions_are_third_party_with_a_reason():
    """Deferred imports are for optional or heavy dependencies (matplotlib, dask, OpenEXR,
    ...): never a voxfield module, and each says why on its line or the line above."""
    bad = []
    for module, path in MODULES.items():
        lines = path.read_text(encoding="utf-8").splitlines()
        for target, node, inside in _imports(module):
            if not inside:
                continue
            if target.split(".")[0] == "voxfield":
                bad.append(f"{module}:{node.lineno} defers {target}")
                continue
            here, above = lines[node.lineno - 1], lines[node.lineno - 2].strip()
            # One reason covers a run of deferred imports below it.
            k = node.lineno - 2
            while k > 0 and lines[k].strip().startswith(("from ", "import ")):
                k -= 1
            if "#" not in here and not above.startswith("#") and \
                    not lines[k].strip().startswith("#"):
                bad.append(f"{module}:{node.lineno} defers {target} without a reason")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("stem", sorted({p.stem for p in PACKAGE.rglob("*.py")} - {"__init__"}))
def test_module_names_are_unique_across_packages_but_for_kernel_pairs(stem):
    """One concept, one file name. A Numba kernel and the driver that calls it share their
    concept's name (``kernels/X.py`` beside ``render/X.py``); nothing else repeats."""
    paths = sorted(p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob(f"{stem}.py"))
    others = [p for p in paths if not p.startswith("kernels/")]
    assert len(others) <= 1, f"{stem}.py names several concepts: {paths}"
