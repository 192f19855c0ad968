"""Finding what a shader or a material names, on a search path of folders (searched recursively):

* shaders by name — ``UsePass "Shader/PASS"``, a ``Fallback``, a ``.mat``'s built-in shader —
  through each ``.shader`` file's ``Shader "name"`` (Unity renamed its legacy shaders in 5.0, and
  ``Shader.Find`` still knows the old names: ``Transparent/Diffuse`` is found as ``Legacy
  Shaders/Transparent/Diffuse``);
* assets by guid — a ``.mat``'s shader and textures — through the ``guid:`` line of the ``.meta``
  file beside each asset;
* Unity's built-in shaders by the ``fileID`` a ``.mat`` stores with the built-in guids
  (:data:`BUILTIN_SHADERS`), then by name on the search path (give it Unity's built-in shader
  source, the "Built in shaders" download, e.g. ``shared/corpus/unity-builtin-shaders-2019.4``).

What each file says is read once per file version (path, size, modification time) and kept.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from pathlib import Path

from .programs import strip_comments

#: ``Resources/unity_builtin_extra`` (the DefaultResourcesExtra shaders) and ``Library/unity
#: default resources``: the guids a ``.mat`` names Unity's built-in shaders with.
BUILTIN_EXTRA_GUID = "0000000000000000f000000000000000"
BUILTIN_DEFAULT_GUID = "0000000000000000e000000000000000"

#: Built-in shaders by (guid, fileID), as Unity's own ``.mat`` files store them (``m_Shader:
#: {fileID: 46, guid: 0000000000000000f000000000000000, type: 0}``). Source: AssetRipper's
#: ``EngineBuiltInAssets.cs`` table, checked against real ``.mat`` files for 3, 7, 45, 46, 47,
#: 203, 10601 (research-surface.md §7); names are those of the 2019.4 source.
BUILTIN_SHADERS: dict[tuple[str, int], str] = {
    **{(BUILTIN_EXTRA_GUID, k): v for k, v in {
        1: "Legacy Shaders/Diffuse Fast", 2: "Legacy Shaders/Bumped Diffuse", 3: "Legacy Shaders/Specular",
        4: "Legacy Shaders/Bumped Specular", 5: "Legacy Shaders/Diffuse Detail", 6: "Legacy Shaders/VertexLit",
        7: "Legacy Shaders/Diffuse", 8: "Legacy Shaders/Parallax Diffuse", 9: "Legacy Shaders/Parallax Specular",
        10: "Legacy Shaders/Self-Illumin/Diffuse", 11: "Legacy Shaders/Self-Illumin/Bumped Diffuse",
        12: "Legacy Shaders/Self-Illumin/Specular", 13: "Legacy Shaders/Self-Illumin/Bumped Specular",
        14: "Legacy Shaders/Self-Illumin/VertexLit", 15: "Legacy Shaders/Self-Illumin/Parallax Diffuse",
        16: "Legacy Shaders/Self-Illumin/Parallax Specular", 20: "Legacy Shaders/Reflective/Diffuse",
        21: "Legacy Shaders/Reflective/Bumped Diffuse", 22: "Legacy Shaders/Reflective/Specular",
        23: "Legacy Shaders/Reflective/Bumped Specular", 24: "Legacy Shaders/Reflective/VertexLit",
        25: "Legacy Shaders/Reflective/Bumped Unlit", 26: "Legacy Shaders/Reflective/Bumped VertexLit",
        27: "Legacy Shaders/Reflective/Parallax Diffuse", 28: "Legacy Shaders/Reflective/Parallax Specular",
        30: "Legacy Shaders/Transparent/Diffuse", 31: "Legacy Shaders/Transparent/Bumped Diffuse",
        32: "Legacy Shaders/Transparent/Specular", 33: "Legacy Shaders/Transparent/Bumped Specular",
        34: "Legacy Shaders/Transparent/VertexLit", 35: "Legacy Shaders/Transparent/Parallax Diffuse",
        36: "Legacy Shaders/Transparent/Parallax Specular", 40: "Legacy Shaders/Lightmapped/VertexLit",
        41: "Legacy Shaders/Lightmapped/Diffuse", 42: "Legacy Shaders/Lightmapped/Bumped Diffuse",
        43: "Legacy Shaders/Lightmapped/Specular", 44: "Legacy Shaders/Lightmapped/Bumped Specular",
        45: "Standard (Specular setup)", 46: "Standard", 47: "Autodesk Interactive",
        50: "Legacy Shaders/Transparent/Cutout/VertexLit", 51: "Legacy Shaders/Transparent/Cutout/Diffuse",
        52: "Legacy Shaders/Transparent/Cutout/Bumped Diffuse", 53: "Legacy Shaders/Transparent/Cutout/Specular",
        54: "Legacy Shaders/Transparent/Cutout/Bumped Specular", 100: "Legacy Shaders/Decal", 101: "FX/Flare",
        103: "Skybox/Cubemap", 104: "Skybox/6 Sided", 106: "Skybox/Procedural", 108: "Skybox/Panoramic",
        200: "Legacy Shaders/Particles/Additive", 201: "Legacy Shaders/Particles/~Additive-Multiply",
        202: "Legacy Shaders/Particles/Additive (Soft)", 203: "Legacy Shaders/Particles/Alpha Blended",
        205: "Legacy Shaders/Particles/Multiply", 206: "Legacy Shaders/Particles/Multiply (Double)",
        207: "Legacy Shaders/Particles/Alpha Blended Premultiply", 208: "Legacy Shaders/Particles/VertexLit Blended",
        209: "Legacy Shaders/Particles/Anim Alpha Blended", 210: "Particles/Standard Surface",
        211: "Particles/Standard Unlit", 10503: "Hidden/TerrainEngine/Splatmap/Diffuse-AddPass",
        10505: "Nature/Terrain/Diffuse", 10509: "Nature/Tree Soft Occlusion Bark",
        10511: "Nature/Tree Soft Occlusion Leaves", 10512: "Legacy Shaders/Transparent/Cutout/Soft Edge Unlit",
        10600: "Nature/Tree Creator Bark", 10601: "Nature/Tree Creator Leaves",
        10606: "Nature/Tree Creator Leaves Fast",
        10620: "Nature/Terrain/Specular", 10621: "Hidden/TerrainEngine/Splatmap/Specular-AddPass",
        10623: "Nature/Terrain/Standard", 10624: "Hidden/TerrainEngine/Splatmap/Standard-AddPass",
        10700: "Mobile/Skybox", 10701: "Mobile/VertexLit", 10703: "Mobile/Diffuse", 10704: "Mobile/Bumped Diffuse",
        10705: "Mobile/Bumped Specular", 10706: "Mobile/Bumped Specular (1 Directional Realtime Light)",
        10707: "Mobile/VertexLit (Only Directional Lights)", 10708: "Mobile/Unlit (Supports Lightmap)",
        10720: "Mobile/Particles/Additive", 10721: "Mobile/Particles/Alpha Blended",
        10722: "Mobile/Particles/VertexLit Blended", 10723: "Mobile/Particles/Multiply",
        10750: "Unlit/Transparent", 10751: "Unlit/Transparent Cutout", 10752: "Unlit/Texture", 10753: "Sprites/Default",
        10755: "Unlit/Color", 10757: "Sprites/Mask", 10760: "UI/Unlit/Transparent", 10761: "UI/Unlit/Detail",
        10762: "UI/Unlit/Text", 10763: "UI/Unlit/Text Detail", 10764: "UI/Lit/Transparent", 10765: "UI/Lit/Bumped",
        10766: "UI/Lit/Detail", 10767: "UI/Lit/Refraction", 10768: "UI/Lit/Refraction Detail", 10770: "UI/Default",
        10782: "UI/Default Font", 10783: "UI/DefaultETC1", 10800: "Sprites/Diffuse", 14000: "Nature/SpeedTree",
        14001: "Nature/SpeedTree Billboard", 14002: "Nature/SpeedTree8", 17: "Hidden/InternalErrorShader",
    }.items()},
    (BUILTIN_DEFAULT_GUID, 10101): "GUI/Text Shader",
}

_SHADER_NAME_RE = re.compile(r'\bShader\s*"([^"]*)"')
_GUID_RE = re.compile(r"^guid:\s*([0-9a-fA-F]{32})\s*$", re.M)
_FILE_CACHE: dict[str, tuple[int, int, str | None]] = {}


def _cached(path: str, read) -> str | None:
    """``read(path)``, kept per file version (size, modification time)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    hit = _FILE_CACHE.get(path)
    if hit is not None and hit[:2] == (st.st_mtime_ns, st.st_size):
        return hit[2]
    value = read(path)
    _FILE_CACHE[path] = (st.st_mtime_ns, st.st_size, value)
    return value


def _shader_name(path: str) -> str | None:
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            head = fh.read(1 << 16)
    except OSError:
        return None
    m = _SHADER_NAME_RE.search(strip_comments(head))
    return m.group(1) if m else None


def _meta_guid(path: str) -> str | None:
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            head = fh.read(4096)
    except OSError:
        return None
    m = _GUID_RE.search(head)
    return m.group(1).lower() if m else None


def _files(folder: Path, suffix: str) -> list[str]:
    """The files under ``folder`` whose names end with ``suffix``, sorted (hidden folders skipped)."""
    out = []
    for root, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        out += [os.path.join(root, n) for n in sorted(names) if n.lower().endswith(suffix)]
    return out


class AssetSearch:
    """The folders a shader's or a material's names are looked up in, in order (each recursively)."""

    def __init__(self, folders: Iterable[str | os.PathLike]) -> None:
        self.folders: list[Path] = []
        for folder in folders:
            path = Path(folder)
            if path.is_dir() and path.resolve() not in [f.resolve() for f in self.folders]:
                self.folders.append(path)
        self._names: dict[str, str] | None = None
        self._guids: dict[str, str] | None = None

    def with_folders(self, folders: Iterable[str | os.PathLike]) -> AssetSearch:
        """This search path with ``folders`` in front."""
        return AssetSearch([*folders, *self.folders])

    def describe(self) -> str:
        return ", ".join(str(f) for f in self.folders) or "no folder"

    def _index(self, suffix: str, read) -> dict[str, str]:
        """``read(path)`` → path for every file of the folders ending with ``suffix`` (the first
        file wins a key two files share)."""
        index: dict[str, str] = {}
        for folder in self.folders:
            for path in _files(folder, suffix):
                key = _cached(path, read)
                if key is not None:
                    index.setdefault(key, path)
        return index

    def shader_path(self, name: str) -> str | None:
        """The ``.shader`` file of the shader named ``name`` (Unity's old name for a Legacy shader too)."""
        if self._names is None:
            self._names = self._index(".shader", _shader_name)
        names = self._names
        for candidate in (name, f"Legacy Shaders/{name}"):
            if candidate in names:
                return names[candidate]
        lower = {k.lower(): v for k, v in names.items()}
        return lower.get(name.lower()) or lower.get(f"legacy shaders/{name.lower()}")

    def asset_path(self, guid: str) -> str | None:
        """The asset whose ``.meta`` file carries ``guid`` (the ``.meta`` path without ``.meta``)."""
        if self._guids is None:
            self._guids = {guid: path[:-len(".meta")] for guid, path in self._index(".meta", _meta_guid).items()}
        return self._guids.get(str(guid).lower())
