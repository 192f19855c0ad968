"""``python -m blendlib import FILE.vrm|.glb|.gltf -o OUT.blend [--json]``: the .blend it writes, the
per-material JSON record, and one error line with nothing written for a bad file."""

from __future__ import annotations

import json

import pytest

from tests.support.blender_fixtures import one_line_error, run_cli
from tests.support.gltf_docs import corpus_dir, triangles_document, write_glb, write_gltf

CORPUS = corpus_dir()

CHECK = r"""
import sys, json, bpy
sys.path.insert(0, ".")
from blendlib import blender
from blendlib.blender import vrm_addon
blender.open_blend(sys.argv[1])
scene = bpy.context.scene

def image(m):  # _MainTex: of the Unity settings, or of the VRM Add-on's settings when those are off
    derived = vrm_addon.derived_material(m)
    return getattr(derived[1] if derived else blender.material_values(m)["main_tex"], "name", None)

out = {"camera": scene.camera.name if scene.camera else None,
       "suns": [o.name for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN"],
       "materials": {m.name: [blender.material_values(m)["enabled"], blender.material_from_blender(m).render_queue,
                              image(m), vrm_addon.summary(m) is not None]
                     for m in bpy.data.materials},
       "packed": all(i.packed_file is not None for i in bpy.data.images),
       "size": [scene.render.resolution_x, scene.render.resolution_y]}
print(json.dumps(out))
"""


@pytest.mark.skipif(CORPUS is None, reason="shared/corpus not found beside the repository")
def test_import_a_vrm_writes_a_blend_and_the_json_records(tmp_path):
    out = tmp_path / "avatar.blend"
    proc = run_cli("import", str(CORPUS / "vrm-addon" / "mtoon1_2_20_61_vrm0.vrm"), "-o", str(out), "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["vrm"] == "0.x" and data["output"] == str(out)
    records = {r["name"]: r for r in data["materials"]}
    assert [r["index"] for r in data["materials"]] == [0, 1, 2, 3]
    transparent = records["Transparent"]
    assert transparent["importer"] == "VRM 0.x VRM/MToon"
    assert transparent["extra"]["render_queue"] == 2952
    assert [p["light_mode"] for p in transparent["passes"]] == ["ForwardBase", "ForwardBase", "ForwardAdd",
                                                               "ShadowCaster"]
    assert [p["drawn"] for p in transparent["passes"]] == [True, True, False, False]
    # the shading approximation is said once, as a warning
    warnings = [line for line in proc.stderr.splitlines() if line.startswith("warning: ")]
    assert sum("approximated by Lambert" in w for w in warnings) == 1
    check = run_cli(str(out), code=CHECK)
    assert check.returncode == 0, check.stderr
    state = json.loads(check.stdout.splitlines()[-1])
    # MToon materials of a .vrm: the VRM Add-on's settings (Unity settings off), the same state
    assert state["materials"]["Transparent"] == [False, 2952, "16.png", True]
    assert state["materials"]["TransparentWithZWrite"] == [False, 2550, "3.png", True]
    assert state["camera"] == "VRM Camera" and state["suns"] == ["VRM Sun"]
    assert state["packed"] and state["size"] == [768, 1024]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["avatar.blend"]  # no temporary file left


def test_import_a_gltf_without_json_prints_a_summary(tmp_path):
    source = write_gltf(tmp_path / "m.gltf", triangles_document([{"name": "Glass", "alphaMode": "BLEND"}]))
    out = tmp_path / "m.blend"
    proc = run_cli("import", str(source), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "Glass: glTF Standard, queue 3000, 5 passes" in proc.stdout
    assert out.exists()


def _glb(tmp_path, name, **extra):
    doc = triangles_document([{"name": "M", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                             textures=1)
    doc.update(extra)
    return write_glb(tmp_path / name, doc)


@pytest.mark.parametrize("make,message", [
    (lambda p: p.write_bytes(_glb(p.parent, "x.vrm").read_bytes()[:60]), "truncated: the glb header says"),
    (lambda p: p.write_bytes(b"glTF" + (2).to_bytes(4, "little") + (28).to_bytes(4, "little")
                             + (8).to_bytes(4, "little") + b"JSON" + b"{nope!! "),
     "the JSON chunk is not JSON"),
    (lambda p: _glb(p.parent, p.name, extensionsUsed=["EXT_unknown"], extensionsRequired=["EXT_unknown"]),
     "unknown required extension 'EXT_unknown'"),
    (lambda p: write_glb(p, triangles_document([{"name": "M", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 9}}}], textures=1)),
     "baseColorTexture.index 9 is out of range: the file has 1 textures"),
])
def test_bad_files_are_one_error_line_and_nothing_written(tmp_path, make, message):
    source = tmp_path / "bad.vrm"
    make(source)
    out = tmp_path / "out.blend"
    proc = run_cli("import", str(source), "-o", str(out))
    one_line_error(proc, message)
    assert str(source) in proc.stderr
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "x.vrm") == ["bad.vrm"]


def test_bad_outputs(tmp_path):
    source = write_gltf(tmp_path / "m.gltf", triangles_document([{"name": "M"}]))
    one_line_error(run_cli("import", str(source), "-o", str(tmp_path / "m.png")), "the import writes a .blend file")
    one_line_error(run_cli("import", str(source), "-o", str(tmp_path / "no" / "m.blend")),
                   "m.blend: cannot write in")
    one_line_error(run_cli("import", str(tmp_path / "missing.vrm"), "-o", str(tmp_path / "m.blend")),
                   "missing.vrm: no such file")
