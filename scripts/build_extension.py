#!/usr/bin/env python3
"""Build the Blender 4.2+ extension zip: ``dist/blendlib-<version>.zip``.

The zip holds the add-on (``addon/``, with ``blender_manifest.toml`` at the top of the zip),
``wheels/blendlib-<version>-py3-none-any.whl``, the bpy-free ``blendlib`` package, and the pure-Python
wheel of ruamel.yaml at the version ``requirements.txt`` pins (Unity ``.mat`` files; Blender ships no
YAML library), which Blender installs with the extension so ``import blendlib`` works where the
repository is not on ``sys.path``. numpy ships with Blender; Pillow and OpenEXR are not needed inside
Blender (they are the wheel's optional ``files`` extra, which Blender does not install).

The tools are the standard ones: ``python -m build`` (sdist, then the wheel from the sdist, with
the setuptools installed in this environment, on a copy of the sources) and Blender's own
extension builder,
``blender_ext.py build``, which ships inside the bpy wheel (``bpy/<version>/scripts/addons_core/
bl_pkg/cli/blender_ext.py``) and is what ``blender --command extension build`` runs.

    python scripts/build_extension.py            # → dist/blendlib-0.1.0.zip
    blender --command extension install-file -r user_default dist/blendlib-0.1.0.zip
    (or Edit > Preferences > Get Extensions > Install from Disk...)
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ADDON = ROOT / "addon"


class BuildError(Exception):
    """A build step failed; the message is one line."""


def versions() -> tuple[str, str]:
    """``(extension id, version)`` from ``addon/blender_manifest.toml``; the version must match pyproject's."""
    manifest = tomllib.loads((ADDON / "blender_manifest.toml").read_text(encoding="utf-8"))
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    if manifest["version"] != project["version"]:
        raise BuildError(f"addon/blender_manifest.toml version {manifest['version']} differs from "
                         f"pyproject.toml version {project['version']}")
    return manifest["id"], manifest["version"]


def blender_ext_script() -> Path:
    """``blender_ext.py`` inside the installed bpy wheel (found without importing bpy)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise BuildError("the bpy package is not installed (pip install -r requirements.txt)")
    for folder in spec.submodule_search_locations:
        found = sorted(Path(folder).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return found[-1]
    raise BuildError("blender_ext.py not found in the bpy package")


def _run(cmd: list[str], what: str) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        detail = (proc.stderr.strip() or proc.stdout.strip()).splitlines()
        raise BuildError(f"{what} failed: {detail[-1] if detail else f'exit status {proc.returncode}'}")


def source_copy(folder: Path) -> Path:
    """What the wheel is built from, copied into ``folder``: setuptools writes its ``build/``
    and ``*.egg-info`` next to the sources, and the repository stays untouched."""
    folder.mkdir(parents=True)
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        if (ROOT / name).is_file():
            shutil.copy2(ROOT / name, folder / name)
    shutil.copytree(ROOT / "blendlib", folder / "blendlib", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    return folder


def build_wheel(out_dir: Path) -> Path:
    """The ``blendlib`` wheel, built by ``python -m build`` (an sdist, then the wheel from it)."""
    source = source_copy(out_dir.parent / "source")
    _run([sys.executable, "-m", "build", "--no-isolation", "--outdir", str(out_dir), str(source)],
         "python -m build")
    wheels = sorted(out_dir.glob("blendlib-*-py3-none-any.whl"))
    if len(wheels) != 1:
        raise BuildError(f"python -m build made {len(wheels)} blendlib wheels in {out_dir}")
    return wheels[0]


#: Third-party wheels the extension bundles: pure-Python ones only (one wheel serves every platform).
BUNDLED = ("ruamel.yaml",)


def pinned(name: str) -> str:
    """``name==version`` as ``requirements.txt`` pins it."""
    for line in (ROOT / "requirements.txt").read_text(encoding="utf-8").splitlines():
        if line.split("==")[0].strip().lower() == name.lower():
            return line.strip()
    raise BuildError(f"requirements.txt does not pin {name}")


def bundled_wheels(out_dir: Path) -> list[Path]:
    """The pure-Python wheels of :data:`BUNDLED` at their pinned versions (``pip download``, which
    takes them from pip's cache when it holds them)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    wheels = []
    for name in BUNDLED:
        _run([sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:", "--dest", str(out_dir),
              pinned(name)], f"pip download {pinned(name)}")
        found = sorted(out_dir.glob(name.replace(".", "_").replace("-", "_") + "-*-py3-none-any.whl"))
        if len(found) != 1:
            raise BuildError(f"pip download {pinned(name)} gave no pure-Python wheel in {out_dir}")
        wheels.append(found[0])
    return wheels


def build(dist: Path) -> Path:
    """Build ``dist/<id>-<version>.zip`` with Blender's extension builder; returns its path."""
    ext_id, version = versions()
    dist.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="blendlib-extension-") as tmp:
        wheels = [build_wheel(Path(tmp) / "wheel"), *bundled_wheels(Path(tmp) / "bundled")]
        source = Path(tmp) / ext_id
        shutil.copytree(ADDON, source, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        (source / "wheels").mkdir()
        for wheel in wheels:
            shutil.copy2(wheel, source / "wheels" / wheel.name)
        listed = ", ".join(f'"./wheels/{wheel.name}"' for wheel in wheels)
        manifest_path = source / "blender_manifest.toml"
        manifest, count = re.subn(r"^wheels\s*=\s*\[.*?\]", f"wheels = [{listed}]",
                                  manifest_path.read_text(encoding="utf-8"), flags=re.M | re.S)
        if count != 1:
            raise BuildError("addon/blender_manifest.toml needs one 'wheels = [...]' entry")
        manifest_path.write_text(manifest, encoding="utf-8")
        target = dist / f"{ext_id}-{version}.zip"
        _run([sys.executable, str(blender_ext_script()), "build", "--source-dir", str(source),
              "--output-filepath", str(target)], "blender_ext.py build")
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dist", type=Path, default=ROOT / "dist", help="output folder (default: dist/)")
    args = parser.parse_args(argv)
    try:
        target = build(args.dist)
    except BuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    print(target)
    return 0


if __name__ == "__main__":
    sys.exit(main())
