#!/usr/bin/env python3
"""Build the Blender 4.2+ extension zip: ``dist/unity_passes-<version>.zip``.

The zip holds the add-on package (``addon/``: ``__init__.py`` and ``blender_manifest.toml`` at
the top of the zip) and ``wheels/unity_passes_blendlib-<version>-py3-none-any.whl``, a pure-Python
wheel of the bpy-free ``blendlib`` package that Blender installs with the extension, so
``import blendlib`` works where the repository is not on ``sys.path``. numpy ships with Blender.

    python scripts/build_extension.py            # → dist/unity_passes-0.1.0.zip
    blender --command extension install-file -r user_default dist/unity_passes-0.1.0.zip
    (or Edit > Preferences > Get Extensions > Install from Disk...)

No network, no Blender needed to build. Deterministic: fixed timestamps, sorted entries.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import re
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DIST_NAME = "unity_passes_blendlib"
STAMP = (2024, 1, 1, 0, 0, 0)
SKIP_DIRS = {"__pycache__", ".pytest_cache"}


def manifest_version(text: str) -> str:
    match = re.search(r'^version\s*=\s*"([^"]+)"', text, re.M)
    if not match:
        raise SystemExit("error: addon/blender_manifest.toml has no version")
    return match.group(1)


def package_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*")
                  if p.is_file() and not SKIP_DIRS & set(p.relative_to(folder).parts) and p.suffix != ".pyc")


def _write(zf: zipfile.ZipFile, name: str, data: bytes) -> None:
    info = zipfile.ZipInfo(name, date_time=STAMP)
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    zf.writestr(info, data)


def build_wheel(out_dir: Path, version: str) -> Path:
    """A py3-none-any wheel of ``blendlib`` (``.py`` files only)."""
    wheel = out_dir / f"{DIST_NAME}-{version}-py3-none-any.whl"
    info_dir = f"{DIST_NAME}-{version}.dist-info"
    entries: list[tuple[str, bytes]] = []
    for path in package_files(ROOT / "blendlib"):
        if path.suffix == ".py":
            entries.append((f"blendlib/{path.relative_to(ROOT / 'blendlib').as_posix()}", path.read_bytes()))
    entries.append((f"{info_dir}/METADATA", (
        "Metadata-Version: 2.1\n"
        f"Name: {DIST_NAME}\n"
        f"Version: {version}\n"
        "Summary: Unity built-in pipeline renderer core (bpy-free) for the Unity Passes Blender extension\n"
        "Requires-Python: >=3.11\n").encode()))
    entries.append((f"{info_dir}/WHEEL", (
        b"Wheel-Version: 1.0\nGenerator: unity-passes build_extension.py\n"
        b"Root-Is-Purelib: true\nTag: py3-none-any\n")))
    entries.append((f"{info_dir}/top_level.txt", b"blendlib\n"))
    record = []
    for name, data in entries:
        digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
        record.append(f"{name},sha256={digest},{len(data)}")
    record.append(f"{info_dir}/RECORD,,")
    entries.append((f"{info_dir}/RECORD", ("\n".join(record) + "\n").encode()))
    out_dir.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(wheel, "w") as zf:
        for name, data in entries:
            _write(zf, name, data)
    return wheel


def build(dist: Path) -> Path:
    addon = ROOT / "addon"
    manifest = (addon / "blender_manifest.toml").read_text()
    version = manifest_version(manifest)
    wheel_dir = dist / "wheels"
    wheel = build_wheel(wheel_dir, version)
    wheel_entry = f"./wheels/{wheel.name}"
    manifest, count = re.subn(r"^wheels\s*=\s*\[.*?\]", f'wheels = ["{wheel_entry}"]', manifest, flags=re.M | re.S)
    if count != 1:
        raise SystemExit("error: addon/blender_manifest.toml needs one 'wheels = [...]' line")
    target = dist / f"unity_passes-{version}.zip"
    tmp = target.with_suffix(".zip.part")
    with zipfile.ZipFile(tmp, "w") as zf:
        for path in package_files(addon):
            rel = path.relative_to(addon).as_posix()
            if rel == "blender_manifest.toml":
                continue
            _write(zf, rel, path.read_bytes())
        _write(zf, "blender_manifest.toml", manifest.encode())
        _write(zf, wheel_entry[2:], wheel.read_bytes())
    tmp.replace(target)
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dist", type=Path, default=ROOT / "dist", help="output folder (default: dist/)")
    args = parser.parse_args(argv)
    target = build(args.dist)
    print(target)
    return 0


if __name__ == "__main__":
    sys.exit(main())
