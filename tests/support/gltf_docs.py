"""Small glTF / VRM documents for the import tests, built from numbers (no third-party asset).

:func:`triangles_document` makes a valid glTF 2.0 document with one triangle per material (so
Blender's importer creates every material), optionally one texture per material (a 2x2 PNG), and
lets a test add what it checks (VRM 0.x ``materialProperties``, ``VRMC_materials_mtoon``, required
extensions, ...). :func:`write_gltf` / :func:`write_glb` write it as a ``.gltf`` (buffer as a data URI)
or a ``.glb`` / ``.vrm`` (buffer as the BIN chunk).
"""

from __future__ import annotations

import base64
import copy
import json
import struct
import zlib
from pathlib import Path
from typing import Any

from blendlib.formats.gltf.container import glb_bytes

REPO = Path(__file__).resolve().parents[2]


def corpus_dir() -> Path | None:
    """``shared/corpus`` beside the repository (the main checkout) or at /work/shared (a worktree)."""
    for candidate in (REPO.parent / "shared" / "corpus", REPO.parents[1] / "shared" / "corpus",
                      Path("/work/shared/corpus")):
        if (candidate / "vrm-addon").is_dir():
            return candidate
    return None


def png_bytes(rgba: list[list[tuple[int, int, int, int]]]) -> bytes:
    """An 8-bit RGBA PNG of rows of pixels (first row = top of the image)."""
    height, width = len(rgba), len(rgba[0])
    raw = b"".join(b"\0" + bytes(c for px in row for c in px) for row in rgba)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def _triangle_buffer(count: int) -> tuple[bytes, list[dict], list[dict]]:
    """Positions, normals and UVs of ``count`` triangles side by side (facing +Z), as one buffer."""
    positions, normals, uvs = b"", b"", b""
    for i in range(count):
        x = 1.5 * i
        for px, py, u, v in ((x, 0.0, 0.0, 1.0), (x + 1.0, 0.0, 1.0, 1.0), (x, 1.0, 0.0, 0.0)):
            positions += struct.pack("<3f", px, py, 0.0)
            normals += struct.pack("<3f", 0.0, 0.0, 1.0)
            uvs += struct.pack("<2f", u, v)
    data = positions + normals + uvs
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(positions)},
             {"buffer": 0, "byteOffset": len(positions), "byteLength": len(normals)},
             {"buffer": 0, "byteOffset": len(positions) + len(normals), "byteLength": len(uvs)}]
    accessors = []
    for i in range(count):
        accessors += [
            {"bufferView": 0, "byteOffset": 36 * i, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [1.5 * i, 0.0, 0.0], "max": [1.5 * i + 1.0, 1.0, 0.0]},
            {"bufferView": 1, "byteOffset": 36 * i, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 2, "byteOffset": 24 * i, "componentType": 5126, "count": 3, "type": "VEC2"},
        ]
    return data, views, accessors


def triangles_document(materials: list[dict[str, Any]], *, textures: int = 0,
                       samplers: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    """A glTF document with one mesh (one triangle) per material and ``textures`` textures, each a
    2x2 PNG (texture i uses sampler i when ``samplers`` has one). The buffer is kept under the key
    ``"__buffer__"`` until written."""
    data, views, accessors = _triangle_buffer(len(materials))
    doc: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": "Unity Passes tests"},
        "scene": 0, "scenes": [{"nodes": list(range(len(materials)))}],
        "nodes": [{"name": f"Object{i}", "mesh": i} for i in range(len(materials))],
        "meshes": [{"name": f"Mesh{i}", "primitives": [{
            "attributes": {"POSITION": 3 * i, "NORMAL": 3 * i + 1, "TEXCOORD_0": 3 * i + 2}, "material": i}]}
            for i in range(len(materials))],
        "materials": copy.deepcopy(materials),
        "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(data)}],
        "__buffer__": data,
    }
    if textures:
        pixel = png_bytes([[(255, 0, 0, 255), (0, 255, 0, 128)], [(0, 0, 255, 255), (255, 255, 255, 0)]])
        doc["images"] = [{"name": f"tex{i}.png", "mimeType": "image/png",
                          "uri": "data:image/png;base64," + base64.b64encode(pixel).decode()} for i in range(textures)]
        doc["textures"] = [{"source": i} | ({"sampler": i} if samplers and i < len(samplers) else {})
                           for i in range(textures)]
        if samplers:
            doc["samplers"] = copy.deepcopy(samplers)
    return doc


def write_gltf(path: Path, doc: dict[str, Any]) -> Path:
    """``doc`` as a ``.gltf`` file (the buffer as a base64 data URI)."""
    doc = dict(doc)
    data = doc.pop("__buffer__")
    doc["buffers"] = [{"byteLength": len(data),
                       "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}]
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def write_glb(path: Path, doc: dict[str, Any]) -> Path:
    """``doc`` as a glb file (``.glb`` or ``.vrm``: the buffer is the BIN chunk)."""
    doc = dict(doc)
    data = doc.pop("__buffer__")
    path.write_bytes(glb_bytes(doc, data))
    return path
