"""Reading a ``.vrm`` / ``.glb`` / ``.gltf`` file: the JSON document, checked before anything uses it.

A ``.vrm`` file is a binary glTF (glb): a 12-byte header (``glTF``, version 2, total length), a
JSON chunk (type ``JSON``), then an optional binary chunk (``BIN``) — the glTF 2.0 specification,
section "GLB File Format Specification". A ``.gltf`` file is the JSON text itself; the kind is
decided by the file's first four bytes, not its name.

:func:`read_document` raises :class:`GltfError` — one line naming the file and what is wrong —
for a file that is truncated, whose JSON chunk is not JSON (or not a glTF 2.0 object), that
requires an extension nothing here can honour, or whose materials, textures or meshes refer to
indices that do not exist. Blender's glTF importer (which reads the geometry) would stop with a
traceback on most of these; checking first keeps the error to one line and the output unwritten.
"""

from __future__ import annotations

import json
import struct
import urllib.parse
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942

#: Extensions a file may *require*: those Blender's glTF importer manages (bpy 5.0,
#: ``io_scene_gltf2/io/imp/gltf2_io_gltf.py``: ``extensions_managed``) — it reads the geometry
#: and refuses any other required extension. Of these, the material importers here read
#: ``KHR_texture_transform`` and ``KHR_materials_unlit``; the others do not change what UniGLTF draws
#: (UniGLTF ignores them for the built-in pipeline's state).
REQUIRED_EXTENSIONS_SUPPORTED = frozenset({
    "KHR_materials_pbrSpecularGlossiness", "KHR_lights_punctual", "KHR_materials_unlit",
    "KHR_texture_transform", "KHR_materials_clearcoat", "KHR_mesh_quantization", "EXT_mesh_gpu_instancing",
    "KHR_draco_mesh_compression", "KHR_materials_variants", "KHR_materials_emissive_strength",
    "KHR_materials_transmission", "KHR_materials_specular", "KHR_materials_sheen", "KHR_materials_ior",
    "KHR_animation_pointer", "KHR_materials_volume", "EXT_texture_webp", "KHR_materials_anisotropy",
})


class GltfError(ValueError):
    """A file that cannot be imported; ``str()`` is one line naming the file."""


@dataclass(frozen=True)
class GltfDocument:
    """A checked glTF document: ``json`` the parsed JSON object, ``path`` the file it came from,
    ``binary`` whether it is a glb (``.vrm``, ``.glb``) rather than JSON text."""

    path: str
    json: dict[str, Any]
    binary: bool

    def list(self, key: str) -> list[Any]:
        """The top-level array ``key`` (``materials``, ``textures``, ...), empty when absent."""
        value = self.json.get(key)
        return value if isinstance(value, list) else []

    def texture_image(self, texture: int) -> int | None:
        """The image index (``textures[i].source``) of a texture, or None when it names none."""
        source = self.list("textures")[texture].get("source")
        return source if isinstance(source, int) else None

    def texture_sampler(self, texture: int) -> dict[str, Any] | None:
        """The sampler object of a texture, or None when it has none (glTF's default sampler)."""
        index = self.list("textures")[texture].get("sampler")
        return self.list("samplers")[index] if isinstance(index, int) else None

    def image_name(self, image: int) -> str:
        """The image's name, else its file name, else ``Image_<i>`` (as Blender's importer names it)."""
        entry = self.list("images")[image]
        name = entry.get("name")
        if isinstance(name, str) and name:
            return name
        uri = entry.get("uri")
        if isinstance(uri, str) and uri and not uri.startswith("data:"):
            return urllib.parse.unquote(uri).replace("\\", "/").rsplit("/", 1)[-1]
        return f"Image_{image}"


def _reject_constant(text: str) -> Any:
    raise ValueError(f"{text} is not a JSON number")


def parse_json(data: bytes, where: str) -> Any:
    """Strict JSON (UTF-8, no NaN/Infinity, as Blender's importer reads it); GltfError otherwise."""
    try:
        return json.loads(data.decode("utf-8-sig"), parse_constant=_reject_constant)
    except UnicodeDecodeError as exc:
        raise GltfError(f"{where} is not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except (ValueError, RecursionError) as exc:
        raise GltfError(f"{where} is not JSON: {' '.join(str(exc).split())}") from None


def split_glb(data: bytes, name: str) -> tuple[bytes, bytes | None]:
    """(JSON chunk, BIN chunk or None) of glb bytes; GltfError for a truncated or malformed container."""
    if len(data) < 12:
        raise GltfError(f"{name}: truncated: {len(data)} bytes, shorter than the 12-byte glb header")
    _magic, version, length = struct.unpack_from("<4sII", data, 0)
    if version != 2:
        raise GltfError(f"{name}: glb version {version}; only glTF 2.0 is supported")
    if length > len(data):
        raise GltfError(f"{name}: truncated: the glb header says {length} bytes, the file has {len(data)}")
    if len(data) < 20:
        raise GltfError(f"{name}: truncated: no JSON chunk after the glb header")
    chunk_length, chunk_type = struct.unpack_from("<II", data, 12)
    if chunk_type != CHUNK_JSON:
        raise GltfError(f"{name}: the first glb chunk is not the JSON chunk (type 0x{chunk_type:08x})")
    if 20 + chunk_length > length:
        raise GltfError(f"{name}: truncated: the JSON chunk needs {chunk_length} bytes, "
                        f"{max(0, length - 20)} are left")
    json_chunk = data[20:20 + chunk_length]
    offset = 20 + chunk_length
    binary = None
    if offset + 8 <= length:
        bin_length, bin_type = struct.unpack_from("<II", data, offset)
        if bin_type == CHUNK_BIN:
            if offset + 8 + bin_length > length:
                raise GltfError(f"{name}: truncated: the BIN chunk needs {bin_length} bytes, "
                                f"{length - offset - 8} are left")
            binary = data[offset + 8:offset + 8 + bin_length]
    return json_chunk, binary


def read_document(path: str | Path) -> GltfDocument:
    """Read and check a ``.vrm``, ``.glb`` or ``.gltf`` file (:func:`check_document`)."""
    path = Path(path)
    name = str(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise GltfError(f"{name}: no such file") from None
    except IsADirectoryError:
        raise GltfError(f"{name}: is a directory") from None
    except OSError as exc:
        raise GltfError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if data[:4] == GLB_MAGIC:
        json_chunk, _ = split_glb(data, name)
        document = GltfDocument(name, parse_json(json_chunk, f"{name}: the JSON chunk"), binary=True)
    else:
        if path.suffix.lower() in (".vrm", ".glb"):
            raise GltfError(f"{name}: not a glb file (it does not start with 'glTF')")
        document = GltfDocument(name, parse_json(data, name), binary=False)
    check_document(document)
    return document


def document_from_json(data: dict[str, Any], path: str = "<json>") -> GltfDocument:
    """A checked document from an already parsed JSON object (tests, the VRM Add-on's settings)."""
    document = GltfDocument(path, data, binary=False)
    check_document(document)
    return document


# --------------------------------------------------------------------------- checks


def _where(document: GltfDocument) -> str:
    return document.path


def _index(value: Any, count: int, what: str, document: GltfDocument, target: str) -> None:
    if not isinstance(value, int) or isinstance(value, bool):
        raise GltfError(f"{_where(document)}: {what} is not an index ({json.dumps(value)})")
    if not 0 <= value < count:
        raise GltfError(f"{_where(document)}: {what} {value} is out of range: the file has {count} {target}")


def texture_references(material: dict[str, Any]) -> Iterator[tuple[str, Any]]:
    """(where, index) of every texture a glTF material refers to: the core textureInfos, those of
    ``VRMC_materials_mtoon`` and of any other extension (objects with an ``index``)."""
    def walk(node: Any, where: str) -> Iterator[tuple[str, Any]]:
        if isinstance(node, dict):
            for key, value in node.items():
                if key.endswith("Texture") and isinstance(value, dict) and "index" in value:
                    yield f"{where}.{key}.index", value["index"]
                if isinstance(value, (dict, list)) and key != "extras":
                    yield from walk(value, f"{where}.{key}")
        elif isinstance(node, list):
            for i, value in enumerate(node):
                yield from walk(value, f"{where}[{i}]")

    yield from walk(material, "")


def check_document(document: GltfDocument) -> None:
    """Raise :class:`GltfError` for the first thing that stops an import (see the module docstring)."""
    data = document.json
    where = _where(document)
    if not isinstance(data, dict):
        raise GltfError(f"{where}: the JSON is not an object (a glTF document is one)")
    asset = data.get("asset")
    if not isinstance(asset, dict) or "version" not in asset:
        raise GltfError(f"{where}: no asset.version: not a glTF document")
    if str(asset["version"]) != "2.0":
        raise GltfError(f"{where}: glTF version {asset['version']}; only 2.0 is supported")
    for key in ("materials", "textures", "images", "samplers", "meshes", "extensionsRequired", "extensionsUsed"):
        if key in data and not isinstance(data[key], list):
            raise GltfError(f"{where}: {key} is not an array")
    for extension in document.list("extensionsRequired"):
        if extension not in REQUIRED_EXTENSIONS_SUPPORTED:
            raise GltfError(f"{where}: unknown required extension {extension!r} "
                            "(extensionsRequired; neither Blender's glTF importer nor this one reads it)")
    images, samplers = len(document.list("images")), len(document.list("samplers"))
    textures, materials = document.list("textures"), document.list("materials")
    for i, texture in enumerate(textures):
        if not isinstance(texture, dict):
            raise GltfError(f"{where}: textures[{i}] is not an object")
        if "source" in texture:
            _index(texture["source"], images, f"textures[{i}].source", document, "images")
        if "sampler" in texture:
            _index(texture["sampler"], samplers, f"textures[{i}].sampler", document, "samplers")
    for i, sampler in enumerate(document.list("samplers")):
        if not isinstance(sampler, dict):
            raise GltfError(f"{where}: samplers[{i}] is not an object")
    for i, material in enumerate(materials):
        if not isinstance(material, dict):
            raise GltfError(f"{where}: materials[{i}] is not an object")
        for path, index in texture_references(material):
            _index(index, len(textures), f"materials[{i}]{path}", document, "textures")
    for m, mesh in enumerate(document.list("meshes")):
        primitives = mesh.get("primitives") if isinstance(mesh, dict) else None
        if not isinstance(primitives, list):
            raise GltfError(f"{where}: meshes[{m}] has no primitives array")
        for p, primitive in enumerate(primitives):
            if not isinstance(primitive, dict):
                raise GltfError(f"{where}: meshes[{m}].primitives[{p}] is not an object")
            if "material" in primitive:
                _index(primitive["material"], len(materials), f"meshes[{m}].primitives[{p}].material",
                       document, "materials")
    vrm0 = (data.get("extensions") or {}).get("VRM") if isinstance(data.get("extensions"), dict) else None
    if isinstance(vrm0, dict) and "materialProperties" in vrm0:
        properties = vrm0["materialProperties"]
        if not isinstance(properties, list) or not all(isinstance(p, dict) for p in properties):
            raise GltfError(f"{where}: extensions.VRM.materialProperties is not an array of objects")
        for i, entry in enumerate(properties):
            textures_of = entry.get("textureProperties", {})
            if not isinstance(textures_of, dict):
                raise GltfError(f"{where}: extensions.VRM.materialProperties[{i}].textureProperties is not an object")
            for key, index in textures_of.items():
                _index(index, len(textures), f"extensions.VRM.materialProperties[{i}].textureProperties.{key}",
                       document, "textures")


# --------------------------------------------------------------------------- writing


def glb_bytes(data: dict[str, Any], binary: bytes | None) -> bytes:
    """A glb file of a JSON object and an optional BIN chunk (chunks padded to 4 bytes: the JSON
    with spaces, the BIN with zeros, as the specification asks)."""
    text = json.dumps(data, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), CHUNK_JSON) + text
    if binary is not None:
        padded = binary + b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(padded), CHUNK_BIN) + padded
    return struct.pack("<4sII", GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def read_binary_chunk(path: str | Path) -> bytes | None:
    """The BIN chunk of a glb file (None for a ``.gltf`` or a glb without one)."""
    data = Path(path).read_bytes()
    if data[:4] != GLB_MAGIC:
        return None
    return split_glb(data, str(path))[1]
