"""The layer rules, read from the source (no imports executed):

- only ``blendlib/blender/`` and ``addon/`` import bpy (or Blender's other modules);
- ``blendlib/core/`` imports nothing of the project outside ``core/``;
- ``blendlib/formats/`` imports ``core/`` at most, never ``blender/``, ``runtime/`` or ``cli/``;
- ``blendlib/explain/`` (the tools that explain a frame) imports ``core/`` only;
- ``blendlib/runtime/`` (processes and threads) imports ``core/`` only; core, formats and explain
  never import it, the Blender layer and the command line may;
- nothing in ``blendlib/`` imports the tests or the add-on;
- ``addon/`` imports only the library's faces: ``blendlib`` itself, ``blendlib.blender``,
  ``blendlib.formats``, ``blendlib.explain``, ``blendlib.runtime`` (and their modules) and
  ``blendlib.core.vocabulary`` — never another module of the core;
- no import circle anywhere in ``blendlib/``: module-level and function-level imports alike
  make a graph of every module's project imports, and a cycle is reported with its path.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "blendlib"
ADDON = ROOT / "addon"
BLENDER_MODULES = {"bpy", "bpy_extras", "mathutils", "gpu", "gpu_extras", "bmesh", "blf", "imbuf", "addon_utils",
                   "bl_ui"}


def project_imports(path: Path, package: str | None = None) -> list[tuple[int, str]]:
    """(line, absolute dotted module) of every import in ``path``, relative imports resolved
    against ``package`` (default: the package the file lies in under the repository root)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    if package is None:
        package = ".".join(path.relative_to(ROOT).parts[:-1])
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            found.append((node.lineno, module))
            if node.module is None or node.level:
                found += [(node.lineno, f"{module}.{alias.name}") for alias in node.names]
    return found


def modules(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*.py"))


def layer_of(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "blendlib":
        return parts[1] if len(parts) > 1 else "blendlib"
    if parts[0] in BLENDER_MODULES:
        return "bpy"
    if parts[0] in ("addon", "tests"):
        return parts[0]
    return None


RULES = {
    # folder: layers it may import
    "core": {"core"},
    "formats": {"core", "formats"},
    "explain": {"core", "explain"},  # frame debugger, pixel history, sorted reference: consumers of core records
    "runtime": {"core", "runtime"},  # band helper process, viewport scheduler, allocator: machinery over core
    "blender": {"core", "formats", "explain", "runtime", "blender", "bpy"},
    "cli": {"core", "formats", "explain", "runtime", "blender", "cli", "blendlib"},
}


def layer_violations(path: Path, allowed: set[str], package: str | None = None) -> list[str]:
    """The imports of ``path`` outside the layers in ``allowed`` (``blendlib`` = the top-level package)."""
    bad = []
    for line, module in project_imports(path, package):
        layer = layer_of(module)
        if layer is not None and layer not in allowed:
            bad.append(f"{path.name}:{line} imports {module}")
    return bad


@pytest.mark.parametrize("folder", sorted(RULES))
def test_layer_imports(folder):
    bad = []
    for path in modules(PACKAGE / folder):
        bad += [f"{path.relative_to(ROOT).parent}/{v}" for v in layer_violations(path, RULES[folder])]
    assert not bad, "\n".join(bad)


def test_only_the_blender_layer_and_the_addon_import_bpy():
    bad = []
    for path in modules(PACKAGE):
        if path.is_relative_to(PACKAGE / "blender"):
            continue
        bad += [f"{path.relative_to(ROOT)}:{line} imports {m}" for line, m in project_imports(path)
                if layer_of(m) in ("bpy", "addon", "tests")]
    assert not bad, "\n".join(bad)


def test_every_package_module_is_in_a_layer():
    top = {p.name for p in PACKAGE.iterdir() if p.suffix == ".py"}
    assert top <= {"__init__.py", "__main__.py", "testing.py"}, top
    assert {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()} == set(RULES)


@pytest.mark.parametrize("package,source,expected", [
    ("blendlib.core", "from ..blender import render\nimport bpy\nfrom . import raster\n",
     ["probe.py:1 imports blendlib.blender", "probe.py:1 imports blendlib.blender.render", "probe.py:2 imports bpy"]),
    ("blendlib.core", "def f():\n    from ..runtime import bandprocs\n",
     ["probe.py:2 imports blendlib.runtime", "probe.py:2 imports blendlib.runtime.bandprocs"]),
    ("blendlib.explain", "from blendlib.runtime.scheduler import ViewportScheduler\n",
     ["probe.py:1 imports blendlib.runtime.scheduler"]),
    ("blendlib.runtime", "from ..core import pipeline\nfrom . import allocator\nfrom ..blender import viewport\n",
     ["probe.py:3 imports blendlib.blender", "probe.py:3 imports blendlib.blender.viewport"]),
    ("blendlib.blender", "from ..runtime.bandprocs import BandRenderer\n", []),
])
def test_the_rules_catch_a_violation(tmp_path, package, source, expected):
    """The checker itself: imports outside a layer's rules are reported, the allowed ones are not."""
    probe = tmp_path / "probe.py"
    probe.write_text(source)
    assert layer_violations(probe, RULES[package.split(".")[1]], package) == expected


def test_the_import_resolution(tmp_path):
    """Relative imports resolve against the package; ``from . import x`` names the module x."""
    probe = tmp_path / "probe.py"
    probe.write_text("from ..blender import render\nimport bpy\nfrom . import raster\n")
    found = project_imports(probe, package="blendlib.core")
    assert found == [(1, "blendlib.blender"), (1, "blendlib.blender.render"), (2, "bpy"),
                     (3, "blendlib.core"), (3, "blendlib.core.raster")]
    assert [layer_of(m) for _, m in found] == ["blender", "blender", "bpy", "core", "core"]


# ------------------------------------------------------------------ the add-on's imports

#: What the add-on may import of the library: the top-level package, these layers' modules, and
#: the one core module every layer shares (the ShaderLab vocabulary).
ADDON_FACES = ("blendlib.blender", "blendlib.formats", "blendlib.explain", "blendlib.runtime")
ADDON_CORE = {"blendlib.core.vocabulary"}


def addon_violations(path: Path, package: str | None = None) -> list[str]:
    """The imports of ``path`` (an add-on module) of the library beyond its faces."""
    bad = []
    for line, module in project_imports(path, package):
        if layer_of(module) is None or not module.startswith("blendlib"):
            continue
        if module == "blendlib" or module in ADDON_CORE or module.startswith(ADDON_FACES):
            continue
        bad.append(f"{path.name}:{line} imports {module}")
    return bad


def test_the_addon_imports_only_the_library_faces():
    bad = []
    for path in modules(ADDON):
        bad += [f"{path.relative_to(ROOT).parent}/{v}" for v in addon_violations(path)]
    assert not bad, "\n".join(bad)


def test_the_addon_rule_catches_a_violation(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("import blendlib\nfrom blendlib import RenderCancelled, SceneError\n"
                     "from blendlib.core.vocabulary import Pass\nimport blendlib.runtime.scheduler\n"
                     "from blendlib.explain import framedebug\n"
                     "from blendlib.core.pipeline import RenderCancelled\n"
                     "def f():\n    from blendlib.core import scene\n")
    assert addon_violations(probe, "addon") == ["probe.py:6 imports blendlib.core.pipeline",
                                                "probe.py:8 imports blendlib.core"]


# ------------------------------------------------------------------ import circles


def module_name(path: Path, root: Path = ROOT) -> str:
    """The dotted name of a module file (a package's ``__init__.py`` is the package)."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(folder: Path, root: Path = ROOT) -> dict[str, set[str]]:
    """Module → the modules of ``folder`` it imports, at module level or inside functions.

    An import of ``a.b.c`` also runs the packages ``a.b`` and ``a`` (their ``__init__``), except
    those the importing module lies in (they are already being imported); names imported from a
    module (``from a.b import f``) count as the module."""
    paths = modules(folder)
    names = {module_name(p, root) for p in paths}
    graph: dict[str, set[str]] = {}
    for path in paths:
        me = module_name(path, root)
        package = ".".join(path.relative_to(root).parts[:-1])
        own = {package.rsplit(".", k)[0] for k in range(package.count(".") + 1)} | {me}
        edges = set()
        for _, target in project_imports(path, package):
            parts = target.split(".")
            for k in range(len(parts), 0, -1):
                name = ".".join(parts[:k])
                if name in names and name not in own:
                    edges.add(name)
        graph[me] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle as its path (first module repeated at the end), or None."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state:
            found = visit(start)
            if found:
                return found
    return None


def test_no_import_circle_in_the_package():
    graph = import_graph(PACKAGE)
    # The graph holds what the checks rely on: package faces, their modules, and the
    # function-level imports of the top-level package.
    assert "blendlib.core.merger" in graph["blendlib.explain.sorted_reference"]
    assert "blendlib.core.merger.ordering" in graph["blendlib.core.merger"]
    assert "blendlib.explain.sorted_reference" in graph["blendlib.explain.advice"]
    assert "blendlib.explain.advice" in graph["blendlib"]
    cycle = find_cycle(graph)
    assert cycle is None, "import circle: " + " → ".join(cycle)


def test_the_cycle_finder_catches_a_planted_cycle(tmp_path):
    """A circle hidden in a function-level import is found, with its path; the same modules
    without it are not one (nor are a package's own submodules importing their siblings)."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from .a import f\n")
    (pkg / "sub" / "a.py").write_text("from .b import g\n\ndef f():\n    return g()\n")
    (pkg / "sub" / "b.py").write_text("def g():\n    from ..c import h\n    return h()\n")
    (pkg / "c.py").write_text("def h():\n    return 1\n")
    assert find_cycle(import_graph(pkg, tmp_path)) is None
    (pkg / "c.py").write_text("def h():\n    from .sub import a\n    return a\n")
    assert find_cycle(import_graph(pkg, tmp_path)) == ["pkg.c", "pkg.sub", "pkg.sub.a", "pkg.sub.b", "pkg.c"]
