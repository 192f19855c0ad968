"""Reading .vrm/.glb/.gltf files: the glb container and the checks that stop an import with one line."""

from __future__ import annotations

import json
import struct

import pytest

from blendlib.formats.gltf import GltfError, read_document
from blendlib.formats.gltf.container import glb_bytes, split_glb
from tests.support.gltf_docs import triangles_document, write_glb, write_gltf


def _doc(**extra):
    doc = triangles_document([{"name": "A", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                             textures=1)
    doc.update(extra)
    return doc


def test_glb_and_gltf_read_the_same_document(tmp_path):
    glb = read_document(write_glb(tmp_path / "a.vrm", _doc()))
    text = read_document(write_gltf(tmp_path / "a.gltf", _doc()))
    assert glb.binary and not text.binary
    assert glb.json["materials"] == text.json["materials"]
    assert glb.texture_image(0) == 0 and glb.image_name(0) == "tex0.png"


def test_glb_chunks_round_trip():
    data = glb_bytes({"asset": {"version": "2.0"}}, b"\1\2\3")
    magic, version, length = struct.unpack_from("<4sII", data)
    assert (magic, version, length) == (b"glTF", 2, len(data)) and length % 4 == 0
    json_chunk, binary = split_glb(data, "x")
    assert json.loads(json_chunk) == {"asset": {"version": "2.0"}}
    assert binary == b"\1\2\3\0"  # padded to 4 bytes


@pytest.mark.parametrize("cut,message", [
    (8, r"a.vrm: truncated: 8 bytes, shorter than the 12-byte glb header"),
    (100, r"a.vrm: truncated: the glb header says \d+ bytes, the file has 100"),
])
def test_truncated_vrm(tmp_path, cut, message):
    path = write_glb(tmp_path / "a.vrm", _doc())
    path.write_bytes(path.read_bytes()[:cut])
    with pytest.raises(GltfError, match=message) as info:
        read_document(path)
    assert "\n" not in str(info.value)


def test_truncated_chunk_inside_a_consistent_header(tmp_path):
    data = bytearray(glb_bytes({"asset": {"version": "2.0"}}, None))
    struct.pack_into("<I", data, 12, 4096)  # the JSON chunk claims more than the file holds
    (tmp_path / "a.glb").write_bytes(bytes(data))
    with pytest.raises(GltfError, match=r"truncated: the JSON chunk needs 4096 bytes"):
        read_document(tmp_path / "a.glb")


def test_json_chunk_that_is_not_json(tmp_path):
    text = b'{"asset": {"version": "2.0"}, "materials": [' + b" " * 3
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    (tmp_path / "a.vrm").write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
    with pytest.raises(GltfError, match=r"a.vrm: the JSON chunk is not JSON: Expecting value: line 1"):
        read_document(tmp_path / "a.vrm")


def test_json_with_nan_or_no_asset(tmp_path):
    (tmp_path / "nan.gltf").write_text('{"asset": {"version": "2.0"}, "x": NaN}')
    with pytest.raises(GltfError, match=r"nan.gltf is not JSON: NaN is not a JSON number"):
        read_document(tmp_path / "nan.gltf")
    (tmp_path / "none.gltf").write_text('{"materials": []}')
    with pytest.raises(GltfError, match=r"none.gltf: no asset.version: not a glTF document"):
        read_document(tmp_path / "none.gltf")
    (tmp_path / "one.gltf").write_text('{"asset": {"version": "1.0"}}')
    with pytest.raises(GltfError, match=r"glTF version 1.0; only 2.0 is supported"):
        read_document(tmp_path / "one.gltf")


def test_a_vrm_that_is_not_a_glb(tmp_path):
    (tmp_path / "a.vrm").write_text('{"asset": {"version": "2.0"}}')
    with pytest.raises(GltfError, match=r"a.vrm: not a glb file"):
        read_document(tmp_path / "a.vrm")


def test_unknown_required_extension(tmp_path):
    doc = _doc(extensionsUsed=["KHR_texture_basisu"], extensionsRequired=["KHR_texture_basisu"])
    with pytest.raises(GltfError, match=r"unknown required extension 'KHR_texture_basisu'"):
        read_document(write_glb(tmp_path / "a.glb", doc))
    # A required extension Blender's importer manages is fine.
    doc = _doc(extensionsUsed=["KHR_texture_transform"], extensionsRequired=["KHR_texture_transform"])
    assert read_document(write_glb(tmp_path / "b.glb", doc)).json["extensionsRequired"] == ["KHR_texture_transform"]


@pytest.mark.parametrize("edit,message", [
    (lambda d: d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(index=5),
     r"materials\[0\]\.pbrMetallicRoughness\.baseColorTexture\.index 5 is out of range: the file has 1 textures"),
    (lambda d: d["materials"][0].update(extensions={"VRMC_materials_mtoon": {"shadeMultiplyTexture": {"index": 2}}}),
     r"materials\[0\]\.extensions\.VRMC_materials_mtoon\.shadeMultiplyTexture\.index 2 is out of range"),
    (lambda d: d["textures"][0].update(source=3), r"textures\[0\]\.source 3 is out of range: the file has 1 images"),
    (lambda d: d.update(extensions={"VRM": {"materialProperties": [{"textureProperties": {"_MainTex": 7}}]}}),
     r"materialProperties\[0\]\.textureProperties\._MainTex 7 is out of range"),
    (lambda d: d["meshes"][0]["primitives"][0].update(material=4),
     r"meshes\[0\]\.primitives\[0\]\.material 4 is out of range: the file has 1 materials"),
    (lambda d: d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"].update(index="0"),
     r"baseColorTexture\.index is not an index \(\"0\"\)"),
])
def test_indices_out_of_range(tmp_path, edit, message):
    doc = _doc()
    edit(doc)
    with pytest.raises(GltfError, match=message):
        read_document(write_glb(tmp_path / "a.vrm", doc))


def test_missing_file(tmp_path):
    with pytest.raises(GltfError, match=r"nothere.vrm: no such file"):
        read_document(tmp_path / "nothere.vrm")
