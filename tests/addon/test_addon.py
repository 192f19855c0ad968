"""The add-on as a whole: every feature registers and unregisters symmetrically (twice in a row too),
with the bl_idnames and property names of SPEC §3; the extension zip installs and renders."""

from __future__ import annotations

import os
from pathlib import Path

import bpy
import pytest

import addon
from blendlib.formats import images


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


#: Every class the add-on registers, by bl_idname: a public API (SPEC §3; scripts and key maps
#: call the operators, files store the panels' and lists' names).
OPERATORS = {
    "pass_add", "pass_remove", "pass_move", "pass_duplicate", "apply_preset", "fill_from_principled",
    "use_standard_view", "shaderlab_import", "shaderlab_import_clipboard", "shaderlab_export", "link_unity_project",
    "sort_analyze",
    "sort_apply_advice", "frame_debugger_capture", "frame_debugger_pixel",
}
TYPES = {
    "UNITY_MT_presets", "UNITY_UL_passes", "UNITY_PT_material", "UNITY_PT_material_passes", "UNITY_PT_camera",
    "UNITY_PT_light", "UNITY_UL_sort_inversions", "UNITY_PT_sort_analysis", "UNITY_UL_frame_debugger_draws",
    "UNITY_UL_frame_debugger_fragments", "UNITY_PT_frame_debugger", "UNITY_PT_frame_debugger_pixel",
}
#: The pointer properties on Blender's types: stored in .blend files (but the window manager's).
POINTERS = {("Material", "unity"), ("Scene", "unity"), ("Light", "unity"), ("Scene", "unity_frame_debugger"),
            ("ViewLayer", "unity_analysis"), ("WindowManager", "unity_sort_results")}


def _registered_parts() -> dict:
    """What of the add-on is in Blender now."""
    return {
        "operators": {name for name in dir(bpy.ops.unity) if name in OPERATORS},
        "types": {name for name in dir(bpy.types) if name.startswith("UNITY_") and "_OT_" not in name},
        "pointers": {(owner, name) for owner, name in POINTERS if hasattr(getattr(bpy.types, owner), name)},
        "engine": bpy.types.RenderEngine.bl_rna_get_subclass_py("UNITY_PASSES") is not None,
        "panels for the engine": sum("UNITY_PASSES" in getattr(panel, "COMPAT_ENGINES", ())
                                     for panel in bpy.types.Panel.__subclasses__()),
        "load_post": [h.__name__ for h in bpy.app.handlers.load_post if h.__module__.startswith("addon.")],
    }


def test_register_unregister_twice_is_symmetric():
    addon.register()  # second call in a row
    parts = _registered_parts()
    assert parts["operators"] == OPERATORS and parts["types"] == TYPES and parts["pointers"] == POINTERS
    assert parts["engine"] and parts["panels for the engine"] > 10  # dimensions, light, world, ...
    assert parts["load_post"] == ["migrate_on_load"]  # once, however often registered
    addon.unregister()
    addon.unregister()
    assert _registered_parts() == {"operators": set(), "types": set(), "pointers": set(), "engine": False,
                                   "panels for the engine": 0, "load_post": []}
    addon.register()
    assert _registered_parts() == parts


INSTALL = r"""
import sys, importlib.abc

class Blocked(importlib.abc.MetaPathFinder):
    # The add-on inside Blender must not need the file/plot libraries of the files extra.
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("PIL", "OpenEXR", "matplotlib"):
            raise ImportError(f"blocked: {name}")
        return None

sys.meta_path.insert(0, Blocked())
import bpy, addon_utils
bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default", enable_on_install=True)
import blendlib
assert "site-packages" in blendlib.__file__, blendlib.__file__
assert hasattr(bpy.types.Material, "unity")
assert bpy.types.RenderEngine.bl_rna_get_subclass_py("UNITY_PASSES") is not None
scene = bpy.context.scene
scene.render.engine = "UNITY_PASSES"
scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 24, 100
scene.render.filepath = sys.argv[2]
bpy.ops.render.render(write_still=True)
assert not any(m.split(".")[0] in ("PIL", "OpenEXR", "matplotlib") for m in sys.modules)
# A Unity .mat reads through ruamel.yaml from the extension's bundled wheel: only site-packages under
# this test's folder stay on the path (bpy and numpy are loaded already).
assert "ruamel" not in sys.modules
sys.path[:] = [p for p in sys.path if "site-packages" not in p or p.startswith(sys.argv[3])]
from blendlib.formats.shaderlab import material_file
mat = material_file.parse_material_file(
    "--- !u!21 &2100000\nMaterial:\n  m_Name: M\n  m_Shader: {fileID: 46, guid: 0000000000000000f000000000000000}\n"
    "  m_SavedProperties:\n    m_Floats:\n    - _SrcBlend: 5\n", "m.mat")
assert mat.name == "M" and mat.floats == {"_SrcBlend": 5.0}
import ruamel.yaml
assert ruamel.yaml.__file__.startswith(sys.argv[3]), ruamel.yaml.__file__
print("OK", [m.__name__ for m in addon_utils.modules() if m.__name__.startswith("bl_ext.")])
"""


def test_extension_zip_installs_without_the_repository(tmp_path):
    """Blender's own installer takes the zip built by Blender's own builder; the add-on then
    imports blendlib from the bundled wheel and renders without Pillow, OpenEXR or matplotlib, and
    reads a Unity .mat with the bundled ruamel.yaml wheel."""
    import subprocess
    import sys
    import zipfile

    from tests.support.blender_fixtures import REPO

    proc = subprocess.run([sys.executable, str(REPO / "scripts" / "build_extension.py"), "--dist", str(tmp_path)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    zip_path = proc.stdout.strip()
    assert Path(zip_path).name == "blendlib-0.1.0.zip"
    names = zipfile.ZipFile(zip_path).namelist()
    assert {"__init__.py", "blender_manifest.toml", "jobs.py", "engine/__init__.py", "engine/render.py",
            "material_settings/properties.py", "shaderlab/ops.py", "sort_analysis/ops.py",
            "frame_debugger/ops.py"} <= set(names)
    assert "wheels/blendlib-0.1.0-py3-none-any.whl" in names
    assert "wheels/ruamel_yaml-0.19.1-py3-none-any.whl" in names  # the version requirements.txt pins
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # blendlib must come from the wheel
    env.update(HOME=str(tmp_path / "home"), XDG_CONFIG_HOME=str(tmp_path / "config"))
    image = tmp_path / "render.png"
    run = subprocess.run([sys.executable, "-c", INSTALL, zip_path, str(image), str(tmp_path)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "OK ['bl_ext.user_default.blendlib']" in run.stdout, run.stderr[-2000:]
    assert images.load(image).shape == (24, 32, 4)
