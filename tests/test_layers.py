"""The layer rules, read from the source (no imports executed):

- only ``blendlib/blender/`` and ``addon/`` import bpy (or Blender's other modules);
- ``blendlib/core/`` imports nothing of the project outside ``core/``;
- ``blendlib/formats/`` imports ``core/`` at most, never ``blender/`` or ``cli/``;
- ``blendlib/explain/`` (the tools that explain a frame) imports ``core/`` only;
- nothing in ``blendlib/`` imports the tests or the add-on.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "blendlib"
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
    "blender": {"core", "formats", "explain", "blender", "bpy"},
    "cli": {"core", "formats", "explain", "blender", "cli", "blendlib"},
}


@pytest.mark.parametrize("folder", sorted(RULES))
def test_layer_imports(folder):
    allowed = RULES[folder] | {None}
    bad = []
    for path in modules(PACKAGE / folder):
        for line, module in project_imports(path):
            layer = layer_of(module)
            if layer not in allowed and not (layer == "blendlib" and "blendlib" in allowed):
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
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
    assert {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()} >= set(RULES)


def test_the_rules_catch_a_violation(tmp_path):
    """The checker itself: a core module importing the Blender layer and bpy is reported as such."""
    probe = tmp_path / "probe.py"
    probe.write_text("from ..blender import render\nimport bpy\nfrom . import raster\n")
    found = project_imports(probe, package="blendlib.core")
    assert found == [(1, "blendlib.blender"), (1, "blendlib.blender.render"), (2, "bpy"),
                     (3, "blendlib.core"), (3, "blendlib.core.raster")]
    assert [layer_of(m) for _, m in found] == ["blender", "blender", "bpy", "core", "core"]
