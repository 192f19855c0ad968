"""Packaging: one name (package, distribution, extension), a plain ``pip install .`` that runs,
and Pillow/OpenEXR/matplotlib needed only where files are read or plots drawn."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import tomllib
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _clean_env() -> dict[str, str]:
    """The environment without PYTHONPATH, so that only what is installed can be imported."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}


def test_one_name_for_package_distribution_and_extension():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    manifest = tomllib.loads((ROOT / "addon" / "blender_manifest.toml").read_text())
    assert project["project"]["name"] == manifest["id"] == "blendlib"
    assert project["project"]["version"] == manifest["version"]
    assert project["build-system"]["build-backend"] == "setuptools.build_meta"
    # the wheel Blender installs pulls only numpy (which Blender ships)
    assert project["project"]["dependencies"] == ["numpy>=1.26"]
    files_extra = project["project"]["optional-dependencies"]["files"]
    assert {"Pillow", "OpenEXR"} <= {r.split(">")[0].split("=")[0] for r in files_extra}


BLOCKED = textwrap.dedent('''
    import importlib.abc, pkgutil, sys

    class Blocked(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in ("PIL", "OpenEXR", "matplotlib"):
                raise ImportError(f"blocked: {name}")
            return None

    sys.meta_path.insert(0, Blocked())
    import numpy as np
    import blendlib
    for info in pkgutil.walk_packages(blendlib.__path__, "blendlib."):
        if info.name != "blendlib.__main__":
            __import__(info.name)
    import addon
    addon.register()
    addon.unregister()
    from blendlib.cli import build_parser
    assert "compare" in build_parser().format_help()
    from blendlib.formats import images
    np.save(sys.argv[1] + "/a.npy", np.zeros((2, 3, 4), np.float32))
    assert images.load(sys.argv[1] + "/a.npy").shape == (2, 3, 4)
    for call in (lambda: images.save(sys.argv[1] + "/a.png", np.zeros((2, 2, 4))),
                 lambda: images.save(sys.argv[1] + "/a.exr", np.zeros((2, 2, 4)))):
        try:
            call()
        except images.ImageIOError as exc:
            print(exc)
    assert not any(m.split(".")[0] in ("PIL", "OpenEXR", "matplotlib") for m in sys.modules)
    print("OK")
''')


def test_blendlib_and_the_addon_import_without_pillow_openexr_matplotlib(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    run = subprocess.run([sys.executable, "-c", BLOCKED, str(tmp_path)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = run.stdout.splitlines()
    assert lines[-1] == "OK"
    assert "PNG files need the Pillow package (pip install 'blendlib[files]')" in lines
    assert "EXR files need the OpenEXR package (pip install 'blendlib[files]')" in lines
    assert not list(tmp_path.glob("a.png")) and not list(tmp_path.glob("a.exr"))


def test_pip_install_gives_a_working_python_m_blendlib(tmp_path):
    """A non-editable install (the wheel pip builds from the repository) into a fresh venv runs
    ``python -m blendlib --help`` from elsewhere; numpy comes from this environment."""
    from scripts.build_extension import source_copy

    wheels = tmp_path / "wheels"
    source = source_copy(tmp_path / "source")  # setuptools writes build/ and *.egg-info beside the sources
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                            "-w", str(wheels), str(source)], capture_output=True, text=True, env=_clean_env())
    assert build.returncode == 0, build.stderr[-2000:]
    (wheel,) = wheels.glob("blendlib-*.whl")
    target = tmp_path / "venv"
    venv.create(target, with_pip=False)
    python = target / "bin" / "python"
    install = subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "-q",
                              str(wheel)], capture_output=True, text=True, env=_clean_env())
    assert install.returncode == 0, install.stderr[-2000:]
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                               capture_output=True, text=True, check=True).stdout.strip())
    # numpy from this environment, after the venv's own site-packages (a .pth line appends)
    numpy_dir = Path(__import__("numpy").__file__).parent.parent
    (site / "outer.pth").write_text(f"{numpy_dir}\n")
    run = subprocess.run([str(python), "-c", "import blendlib, runpy, sys; print(blendlib.__file__); "
                          "sys.argv = ['blendlib', '--help']; runpy.run_module('blendlib', run_name='__main__')"],
                         cwd=tmp_path, capture_output=True, text=True, env=_clean_env(), timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    first, *rest = run.stdout.splitlines()
    assert Path(first).is_relative_to(site)
    assert "usage: python -m blendlib" in "\n".join(rest) and "compare" in "\n".join(rest)
    help_run = subprocess.run([str(python), "-m", "blendlib", "--help"], cwd=tmp_path, capture_output=True,
                              text=True, env=_clean_env(), timeout=120)
    assert help_run.returncode == 0 and help_run.stdout.startswith("usage: python -m blendlib"), help_run.stderr
