"""The add-on: registration, the Material.unity/Scene.unity properties, save/reload, presets, operators,
the render engine."""

from __future__ import annotations

import os
from pathlib import Path

import bpy
import numpy as np
import pytest

import addon
import blendlib
from blendlib import blender, render
from blendlib.core import colorspace
from blendlib.core.vocabulary import PASS_PRESETS, Pass, preset
from blendlib.formats import images
from tests.support.blender_fixtures import add_cube, add_plane, empty_scene, principled_material, unlit_material


@pytest.fixture(autouse=True)
def registered():
    addon.register()
    yield
    addon.unregister()


PASS_SPEC = {
    "name": ("STRING", "Pass", None),
    "cull": ("ENUM", "Back", {"Back", "Front", "Off"}),
    "zwrite": ("BOOLEAN", True, None),
    "ztest": ("ENUM", "LEqual", {"Less", "Greater", "LEqual", "GEqual", "Equal", "NotEqual", "Always"}),
    "blend": ("BOOLEAN", False, None),
    "src_blend": ("ENUM", "One", "factors"),
    "dst_blend": ("ENUM", "Zero", "factors"),
    "blend_op": ("ENUM", "Add", {"Add", "Sub", "RevSub", "Min", "Max"}),
    "separate_alpha": ("BOOLEAN", False, None),
    "src_blend_alpha": ("ENUM", "One", "factors"),
    "dst_blend_alpha": ("ENUM", "Zero", "factors"),
    "blend_op_alpha": ("ENUM", "Add", {"Add", "Sub", "RevSub", "Min", "Max"}),
    "color_mask": ("ENUM", {"R", "G", "B", "A"}, {"R", "G", "B", "A"}),
    "offset_factor": ("FLOAT", 0.0, None),
    "offset_units": ("FLOAT", 0.0, None),
    "alpha_test": ("BOOLEAN", False, None),
    "stencil": ("BOOLEAN", False, None),
    "stencil_ref": ("INT", 0, None),
    "stencil_read_mask": ("INT", 255, None),
    "stencil_write_mask": ("INT", 255, None),
    "stencil_comp": ("ENUM", "Always", {"Never", "Less", "Equal", "LEqual", "Greater", "NotEqual", "GEqual", "Always"}),
    "stencil_pass": ("ENUM", "Keep", "ops"),
    "stencil_fail": ("ENUM", "Keep", "ops"),
    "stencil_zfail": ("ENUM", "Keep", "ops"),
}
FACTORS = {"One", "Zero", "SrcColor", "SrcAlpha", "DstColor", "DstAlpha", "OneMinusSrcColor", "OneMinusSrcAlpha",
           "OneMinusDstColor", "OneMinusDstAlpha", "SrcAlphaSaturate"}
OPS = {"Keep", "Zero", "Replace", "IncrSat", "DecrSat", "Invert", "IncrWrap", "DecrWrap"}


def check_props(group, spec):
    props = group.bl_rna.properties
    for name, (kind, default, items) in spec.items():
        prop = props[name]
        assert prop.type == kind, name
        assert prop.description, name
        value = getattr(group, name)
        if kind == "FLOAT" and prop.array_length:
            np.testing.assert_allclose(tuple(value), default, atol=1e-6, err_msg=name)
        elif kind == "FLOAT":
            assert value == pytest.approx(default), name
        else:
            assert value == default, name
        if items is not None:
            items = {"factors": FACTORS, "ops": OPS}.get(items, items) if isinstance(items, str) else items
            assert set(prop.enum_items.keys()) == items, name


def test_register_unregister_twice():
    addon.register()  # second call in a row
    assert hasattr(bpy.types.Material, "unity") and hasattr(bpy.types.Scene, "unity")
    assert "UNITY_PASSES" in bpy.types.RenderEngine.bl_rna_get_subclass_py("UNITY_PASSES").bl_idname
    for idname in ("UNITY_PT_material", "UNITY_PT_camera", "UNITY_UL_passes", "UNITY_MT_presets"):
        assert hasattr(bpy.types, idname), idname
    addon.unregister()
    addon.unregister()
    assert not hasattr(bpy.types.Material, "unity") and not hasattr(bpy.types, "UNITY_PT_material")
    assert bpy.types.RenderEngine.bl_rna_get_subclass_py("UNITY_PASSES") is None
    addon.register()
    assert hasattr(bpy.types.Material, "unity")


def test_spec_properties_and_defaults():
    empty_scene()
    mat = bpy.data.materials.new("M")
    u = mat.unity
    check_props(u, {
        "enabled": ("BOOLEAN", False, None),
        "queue": ("ENUM", "Geometry", {"Background", "Geometry", "AlphaTest", "Transparent", "Overlay"}),
        "queue_offset": ("INT", 0, None),
        "color": ("FLOAT", (1, 1, 1, 1), None),
        "main_tex_tiling": ("FLOAT", (1, 1), None),
        "main_tex_offset": ("FLOAT", (0, 0), None),
        "main_tex_filter": ("ENUM", "Bilinear", {"Bilinear", "Point"}),
        "main_tex_wrap": ("ENUM", "Repeat", {"Repeat", "Clamp"}),
        "alpha_scale": ("FLOAT", 1.0, None),
        "cutoff": ("FLOAT", 0.5, None),
        "lighting": ("ENUM", "Lambert", {"Lambert", "Unlit"}),
    })
    props = u.bl_rna.properties
    assert props["color"].subtype == "COLOR_GAMMA" and props["main_tex"].fixed_type.identifier == "Image"
    assert props["passes"].type == "COLLECTION" and "active_pass_index" in props
    p = u.passes.add()
    check_props(p, PASS_SPEC)
    assert p.bl_rna.properties["color_mask"].is_enum_flag
    s = bpy.context.scene.unity
    check_props(s, {
        "color_space": ("ENUM", "Gamma", {"Gamma", "Linear"}),
        "hdr": ("BOOLEAN", False, None),
        "clear_color": ("FLOAT", (0.19, 0.30, 0.47, 0.0), None),
        "ambient_from_world": ("BOOLEAN", True, None),
        "ambient_color": ("FLOAT", (0.2, 0.2, 0.2), None),
        "sort_mode": ("ENUM", "Default", {"Default", "Perspective", "Orthographic", "CustomAxis"}),
        "sort_axis": ("FLOAT", (0, 0, 1), None),
    })
    for name in ("clear_color", "ambient_color"):
        assert s.bl_rna.properties[name].subtype == "COLOR_GAMMA"


def test_properties_survive_save_and_reload(tmp_path):
    empty_scene()
    img = bpy.data.images.new("Tex", 2, 2)
    img.use_fake_user = True
    mat = bpy.data.materials.new("Glass")
    mat.use_fake_user = True
    u = mat.unity
    u.enabled, u.queue, u.queue_offset, u.color = True, "Transparent", 1, (0.1, 0.2, 0.3, 0.4)
    u.main_tex, u.main_tex_tiling, u.main_tex_filter, u.cutoff = img, (2.0, 3.0), "Point", 0.25
    p = u.passes.add()
    p.name, p.color_mask, p.ztest, p.blend, p.src_blend = "P1", {"R", "A"}, "Greater", True, "SrcAlphaSaturate"
    p.stencil, p.stencil_ref, p.stencil_comp, p.stencil_zfail = True, 7, "NotEqual", "DecrWrap"
    q = u.passes.add()
    q.color_mask = set()
    s = bpy.context.scene.unity
    s.color_space, s.hdr, s.clear_color, s.sort_mode = "Linear", True, (0.5, 0.5, 0.5, 1.0), "CustomAxis"
    path = tmp_path / "props.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    expected = blender.read_group(u, blender.MATERIAL_FIELDS)
    expected_scene = blender.read_group(s, blender.SCENE_FIELDS)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    u = bpy.data.materials["Glass"].unity
    assert (u.enabled, u.queue, u.queue_offset, u.main_tex.name, u.main_tex_filter) == \
        (True, "Transparent", 1, "Tex", "Point")
    assert [(x.name, x.color_mask, x.ztest, x.src_blend, x.stencil_ref, x.stencil_zfail) for x in u.passes] == [
        ("P1", {"R", "A"}, "Greater", "SrcAlphaSaturate", 7, "DecrWrap"), ("Pass", set(), "LEqual", "One", 0, "Keep")]
    assert bpy.context.scene.unity.color_space == "Linear" and bpy.context.scene.unity.sort_mode == "CustomAxis"
    # Without the add-on, the bridge reads the same values from the stored ID properties.
    addon.unregister()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    mat = bpy.data.materials["Glass"]
    assert not hasattr(mat, "unity")
    got = blender.read_group(blender.unity_props(mat), blender.MATERIAL_FIELDS)
    assert got["main_tex"].name == "Tex"
    got["main_tex"] = expected["main_tex"] = None
    assert got == expected
    assert blender.read_group(blender.unity_props(bpy.context.scene), blender.SCENE_FIELDS) == expected_scene


@pytest.mark.parametrize("name", list(PASS_PRESETS))
def test_presets_set_documented_state(name):
    empty_scene()
    mat = bpy.data.materials.new("M")
    mat.unity.queue_offset = 5
    mat.unity.passes.add().name = "old"
    with bpy.context.temp_override(material=mat):
        assert bpy.ops.unity.apply_preset(preset=name) == {"FINISHED"}
    queue, passes = preset(name)
    assert mat.unity.enabled and mat.unity.queue == queue.value and mat.unity.queue_offset == 0
    from addon.operators import pass_from_item

    assert tuple(pass_from_item(p) for p in mat.unity.passes) == passes
    assert all(isinstance(p, Pass) for p in passes)


def test_pass_list_operators_and_preview():
    empty_scene()
    mat = bpy.data.materials.new("M")
    u = mat.unity
    with bpy.context.temp_override(material=mat):
        bpy.ops.unity.pass_add()
        u.passes[0].blend = True
        u.passes[0].src_blend = "SrcAlpha"
        bpy.ops.unity.pass_duplicate()
        assert len(u.passes) == 2 and u.passes[1].src_blend == "SrcAlpha" and u.active_pass_index == 1
        u.passes[1].name = "Second"
        u.passes[1].cull = "Off"
        bpy.ops.unity.pass_move(direction="UP")
        assert [p.name for p in u.passes] == ["Second", "Pass 1"] and u.active_pass_index == 0
        bpy.ops.unity.pass_remove()
        assert [p.name for p in u.passes] == ["Pass 1"]
    from addon.ui import shaderlab_preview

    assert shaderlab_preview(u.passes[0]) == "Cull Back ZWrite On ZTest LEqual Blend SrcAlpha Zero"


def test_fill_from_principled():
    empty_scene()
    mat, bsdf = principled_material("P", (0.5, 0.0, 1.0, 1.0), 0.3)
    with bpy.context.temp_override(material=mat):
        assert bpy.ops.unity.fill_from_principled() == {"FINISHED"}
    np.testing.assert_allclose(mat.unity.color, (0.735357, 0.0, 1.0, 0.3), atol=1e-5)  # sRGB-encoded 0.5
    img = bpy.data.images.new("T", 2, 2)
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = img
    mat.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    with bpy.context.temp_override(material=mat):
        bpy.ops.unity.fill_from_principled()
    assert mat.unity.main_tex == img and tuple(mat.unity.color)[:3] == (1.0, 1.0, 1.0)


def glass_scene(color_space="Gamma", hdr=False):
    scene = empty_scene(40, 30)
    scene.render.engine = "UNITY_PASSES"
    scene.unity.color_space = color_space
    scene.unity.hdr = hdr
    add_cube("Back", 2.0, (0.5, 2, 0.3), unlit_material("Red", (0.9, 0.1, 0.1, 1.0)))
    glass = unlit_material("Glass", (0.2, 0.6, 1.0, 0.5))
    with bpy.context.temp_override(material=glass):
        bpy.ops.unity.apply_preset(preset="Alpha Blend Both Sided")
    add_cube("Glass", 2.0, (-0.5, 0, 0), glass)
    return scene


@pytest.mark.parametrize("color_space,hdr", [("Gamma", False), ("Linear", False), ("Linear", True)])
def test_engine_write_still_equals_blendlib_render(tmp_path, color_space, hdr):
    scene = glass_scene(color_space, hdr)
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(tmp_path / "still.png")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    frame = render(scene)
    png = images.load(tmp_path / "still.png")
    expected = blender.linear_rgba(frame, opaque=True)
    # 8-bit file of Combined under the Standard view: the stored 8-bit values, alpha 255.
    want = images.to_uint8(frame.color[..., :3]) if not hdr else \
        images.to_uint8(np.where(expected[..., :3] <= 0.0031308, expected[..., :3] * 12.92,
                                  1.055 * np.maximum(expected[..., :3], 0) ** (1 / 2.4) - 0.055))
    got = images.to_uint8(png[..., :3])
    assert np.abs(got.astype(int) - want.astype(int)).max() <= (0 if not hdr else 1)
    assert (png[..., 3] == 1.0).all()
    assert len(np.unique(got.reshape(-1, 3), axis=0)) >= 3  # clear, red, glass: not an empty frame
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(tmp_path / "still.exr")
    bpy.ops.render.render(write_still=True)
    np.testing.assert_array_equal(images.load(tmp_path / "still.exr"), expected)


def test_render_final_uses_modifier_render_levels_like_f12(tmp_path):
    """A Subdivision modifier at viewport level 0 and render level 3: render_final (and so the
    CLI) sees the render-level mesh exactly as F12 does; render() sees the viewport one."""
    scene = glass_scene()
    glass = bpy.data.objects["Glass"]
    mod = glass.modifiers.new("Subdivision", "SUBSURF")
    mod.levels, mod.render_levels = 0, 3
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(tmp_path / "f12.png")
    assert bpy.ops.render.render(write_still=True) == {"FINISHED"}
    f12 = images.to_uint8(images.load(tmp_path / "f12.png")[..., :3])
    final = blender.render_final(scene)
    viewport = render(scene)
    assert scene.render.engine == "UNITY_PASSES"  # restored after render_final
    np.testing.assert_array_equal(images.to_uint8(final.color[..., :3]), f12)
    changed = np.any(final.color != viewport.color, axis=2).sum()
    assert changed > 20, "the rounded (render-level) cube must differ from the level-0 cube"


def test_engine_result_passes():
    from addon.engine import result_arrays

    glass_scene("Linear")
    frame = render()
    assert frame.encoded  # Linear LDR stores sRGB-encoded codes
    arrays = result_arrays(frame)
    h, w = frame.depth.shape
    np.testing.assert_array_equal(arrays["Depth"].reshape(h, w)[::-1], frame.depth)
    np.testing.assert_array_equal(arrays["UnityAlpha"].reshape(h, w)[::-1], frame.color[..., 3])
    assert frame.depth.min() < 1.0 and frame.color[..., 3].min() == 0.0  # clear alpha 0 around the cubes
    combined = arrays["Combined"].reshape(h, w, 4)[::-1]
    assert (combined[..., 3] == 1).all()
    np.testing.assert_allclose(combined[..., :3], colorspace.decode_fast(frame.color[..., :3]), atol=1e-6)


def test_engine_errors_are_reports_and_write_nothing(tmp_path):
    scene = glass_scene()
    scene.camera = None
    scene.render.filepath = str(tmp_path / "nocam.png")
    with pytest.raises(RuntimeError, match="no camera"):
        bpy.ops.render.render(write_still=True)
    assert not (tmp_path / "nocam.png").exists()


def test_engine_cancel_writes_nothing(tmp_path, monkeypatch):
    scene = glass_scene()
    scene.render.filepath = str(tmp_path / "cancel.png")
    calls = []
    original = blendlib.render_scene

    def cancelling(draw, progress=None, should_cancel=None):
        calls.append(should_cancel)
        return original(draw, progress=progress, should_cancel=lambda: True)

    monkeypatch.setattr(blendlib, "render_scene", cancelling)
    with pytest.raises(RuntimeError, match="cancelled"):
        bpy.ops.render.render(write_still=True)
    assert calls and callable(calls[0])  # the engine passes its test_break
    assert not os.listdir(tmp_path)


def test_engine_animation_renders_each_frame(tmp_path):
    scene = glass_scene()
    glass = bpy.data.objects["Glass"]
    scene.frame_start, scene.frame_end = 1, 2
    glass.location = (-3, 0, 0)
    glass.keyframe_insert("location", frame=1)
    glass.location = (3, 0, 0)
    glass.keyframe_insert("location", frame=2)
    scene.render.filepath = str(tmp_path / "anim_#")
    scene.render.image_settings.file_format = "PNG"
    bpy.ops.render.render(animation=True)
    a, b = images.load(tmp_path / "anim_1.png"), images.load(tmp_path / "anim_2.png")
    assert a.shape == b.shape == (30, 40, 4) and not np.array_equal(a, b)


def test_plane_renders_with_disabled_material_lambert():
    empty_scene(16, 16)
    add_plane("Plane", 10.0)
    frame = render()
    assert np.allclose(frame.color, frame.color[0, 0])  # the plane fills the frame
    assert not np.allclose(frame.color[0, 0], blender.scene_settings(bpy.context.scene)["clear_color"], atol=1e-3)


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
print("OK", [m.__name__ for m in addon_utils.modules() if m.__name__.startswith("bl_ext.")])
"""


def test_extension_zip_installs_without_the_repository(tmp_path):
    """Blender's own installer takes the zip built by Blender's own builder; the add-on then
    imports blendlib from the bundled wheel and renders without Pillow, OpenEXR or matplotlib."""
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
    assert {"__init__.py", "blender_manifest.toml", "engine.py"} <= set(names)
    assert "wheels/blendlib-0.1.0-py3-none-any.whl" in names
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # blendlib must come from the wheel
    env.update(HOME=str(tmp_path / "home"), XDG_CONFIG_HOME=str(tmp_path / "config"))
    image = tmp_path / "render.png"
    run = subprocess.run([sys.executable, "-c", INSTALL, zip_path, str(image)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "OK ['bl_ext.user_default.blendlib']" in run.stdout, run.stderr[-2000:]
    assert images.load(image).shape == (24, 32, 4)
