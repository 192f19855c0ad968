"""Unity material files (``.mat``, SPEC §11.5) and texture importer settings (``.meta``).

:func:`read_material_file` reads the ``Material`` document (class 21) of a ``.mat`` into a
:class:`UnityMaterialFile`: the name, the shader reference, the saved properties, the render
queue, keywords, tag overrides and disabled passes. Saved properties come in three layouts
(research-surface.md §9.2), all read:

* Unity 4 – 5.4: ``m_Floats: { data: {first: {name: _X}, second: V}, data: … }`` (a repeated key);
* Unity 5.5 – 5.6: ``m_Floats: [ {first: {name: _X}, second: V}, … ]``;
* 2017.1 on: ``m_Floats: [ {_X: V}, … ]`` (and ``m_Ints`` from 2021.2).

Keywords: ``m_ShaderKeywords`` (a space-separated string, a list in Unity 4), or from 2021.2
``m_ValidKeywords`` and ``m_InvalidKeywords`` (both are keywords set on the material).

:func:`read_texture_settings` reads a texture's ``.meta`` (``TextureImporter``) for the sampler
settings Unity gives it: mipmaps (``mipmaps.enableMipMap``; a Sprite, ``textureType`` 8, has none
unless stated), ``filterMode`` (0 Point, 1 Bilinear, 2 Trilinear, -1 default Bilinear),
``wrapMode``/``wrapU`` (0 Repeat, 1 Clamp, -1 default Repeat), ``sRGBTexture`` and
``mipMapsPreserveCoverage`` with its ``alphaTestReferenceValue``; without a ``.meta``, Unity's
defaults for the Default texture type (mipmaps on, Bilinear, Repeat, sRGB).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ...core.vocabulary import TextureFilter, TextureWrap
from .state import MaterialValues
from .unity_yaml import Repeated, UnityFileError, load_documents

MATERIAL_CLASS_ID = 21


@dataclass(frozen=True)
class TextureSlot:
    """A texture property of ``m_TexEnvs``: the texture by guid (None: none), tiling and offset."""

    guid: str | None
    file_id: int
    scale: tuple[float, float] = (1.0, 1.0)
    offset: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class UnityMaterialFile:
    """What a ``.mat`` file says (see the module docstring); ``shader_file_id``/``shader_guid``:
    the ``m_Shader`` reference (``shader_guid`` None: no shader)."""

    path: str
    name: str
    shader_file_id: int
    shader_guid: str | None
    floats: dict[str, float] = field(default_factory=dict)
    colors: dict[str, tuple[float, float, float, float]] = field(default_factory=dict)
    textures: dict[str, TextureSlot] = field(default_factory=dict)
    keywords: frozenset[str] = frozenset()
    custom_render_queue: int = -1
    tags: dict[str, str] = field(default_factory=dict)
    disabled_passes: tuple[str, ...] = ()

    @property
    def values(self) -> MaterialValues:
        """The property values a shader's ``[_Prop]`` references read."""
        return MaterialValues(self.floats, self.colors)


def _number(text: Any, what: str, path: str) -> float:
    try:
        value = float(str(text).strip())
    except ValueError:
        raise UnityFileError(f"{what} is not a number: {text!r}", 0, 0, path) from None
    if not math.isfinite(value):
        raise UnityFileError(f"{what} is not finite: {text!r}", 0, 0, path)
    return value


def _entries(table: Any) -> list[tuple[str, Any]]:
    """``(name, value)`` of a saved-property table in any of the three layouts."""
    if table in (None, "", "{}"):
        return []
    if isinstance(table, dict) and "data" in table:  # Unity 4 – 5.4: repeated 'data' keys
        data = table["data"]
        items = list(data) if isinstance(data, Repeated) else [data]
    elif isinstance(table, list):
        items = table
    else:
        items = []
    out = []
    for item in items:
        if not isinstance(item, dict):
            continue
        if "first" in item and "second" in item:  # {first: {name: X}, second: V}
            first = item["first"]
            name = first.get("name") if isinstance(first, dict) else first
            out.append((str(name), item["second"]))
        elif len(item) == 1:  # {X: V}
            ((name, value),) = item.items()
            out.append((str(name), value))
    return out


def _pair(value: Any, keys: tuple[str, str], default: tuple[float, float], what: str, path: str):
    if not isinstance(value, dict):
        return default
    return tuple(_number(value.get(k, d), what, path) for k, d in zip(keys, default, strict=True))


def _keywords(material: dict) -> frozenset[str]:
    words: list[str] = []
    for key in ("m_ShaderKeywords", "m_ValidKeywords", "m_InvalidKeywords"):
        value = material.get(key)
        if isinstance(value, str):
            words += value.split()
        elif isinstance(value, list):
            words += [str(v) for v in value]
    return frozenset(words)


def read_material_file(path: str) -> UnityMaterialFile:
    """Read a ``.mat`` file; :class:`~.unity_yaml.UnityFileError` (one line) when it is not one."""
    try:
        with open(path, encoding="utf-8-sig") as fh:
            text = fh.read()
    except UnicodeDecodeError as exc:
        raise UnityFileError(f"not UTF-8 text ({exc.reason})", 0, 0, path) from None
    return parse_material_file(text, path)


def parse_material_file(text: str, path: str = "<string>") -> UnityMaterialFile:
    """:func:`read_material_file` of the file's text."""
    docs = load_documents(text, path)
    material = next((body.get("Material") for class_id, _, body in docs
                     if isinstance(body, dict) and class_id in (MATERIAL_CLASS_ID, None) and "Material" in body),
                    None)
    if not isinstance(material, dict):
        raise UnityFileError("no Material document (--- !u!21) in the file: not a Unity material", 0, 0, path)
    shader = material.get("m_Shader")
    if not isinstance(shader, dict):
        raise UnityFileError("the material has no m_Shader", 0, 0, path)
    file_id = int(_number(shader.get("fileID", 0), "m_Shader fileID", path))
    guid = shader.get("guid")
    guid = str(guid).lower() if guid not in (None, "") and file_id != 0 else None
    props = material.get("m_SavedProperties")
    props = props if isinstance(props, dict) else {}
    floats: dict[str, float] = {}
    for table in ("m_Floats", "m_Ints"):
        for name, value in _entries(props.get(table)):
            floats[name] = _number(value, f"m_Floats {name}", path)
    colors: dict[str, tuple[float, float, float, float]] = {}
    for name, value in _entries(props.get("m_Colors")):
        if isinstance(value, dict):
            colors[name] = tuple(_number(value.get(k, 0), f"m_Colors {name}", path) for k in "rgba")
    textures: dict[str, TextureSlot] = {}
    for name, value in _entries(props.get("m_TexEnvs")):
        if not isinstance(value, dict):
            continue
        ref = value.get("m_Texture") if isinstance(value.get("m_Texture"), dict) else {}
        tex_file_id = int(_number(ref.get("fileID", 0), f"m_TexEnvs {name} fileID", path))
        tex_guid = ref.get("guid")
        textures[name] = TextureSlot(
            str(tex_guid).lower() if tex_guid and tex_file_id != 0 else None, tex_file_id,
            _pair(value.get("m_Scale"), ("x", "y"), (1.0, 1.0), f"m_TexEnvs {name} m_Scale", path),
            _pair(value.get("m_Offset"), ("x", "y"), (0.0, 0.0), f"m_TexEnvs {name} m_Offset", path))
    queue = _number(material.get("m_CustomRenderQueue", -1), "m_CustomRenderQueue", path)
    if queue != -1 and not 0 <= queue <= 5000:  # -1: the shader's queue; Unity's queues run 0..5000
        raise UnityFileError(f"m_CustomRenderQueue {queue:g} is neither -1 nor within 0..5000", 0, 0, path)
    queue = int(queue)
    tags = material.get("stringTagMap")
    disabled = material.get("disabledShaderPasses")
    return UnityMaterialFile(
        path=path, name=str(material.get("m_Name") or ""), shader_file_id=file_id, shader_guid=guid,
        floats=floats, colors=colors, textures=textures, keywords=_keywords(material), custom_render_queue=queue,
        tags={str(k): str(v) for k, v in tags.items()} if isinstance(tags, dict) else {},
        disabled_passes=tuple(str(p) for p in disabled) if isinstance(disabled, list) else ())


# --------------------------------------------------------------------------- texture importer settings


@dataclass(frozen=True)
class TextureSettings:
    """A texture asset's sampler settings as Unity's importer gives them (module docstring)."""

    path: str
    mipmaps: bool = True
    filter: TextureFilter = TextureFilter.Bilinear
    wrap: TextureWrap = TextureWrap.Repeat
    srgb: bool = True
    preserve_coverage: bool = False
    coverage_cutoff: float = 0.5
    from_meta: bool = False  # False: no .meta beside the texture, Unity's defaults

    def to_json(self) -> dict[str, Any]:
        return {"file": self.path, "mipmaps": self.mipmaps, "filter": self.filter.value, "wrap": self.wrap.value,
                "srgb": self.srgb, "preserve_coverage": self.preserve_coverage,
                "coverage_cutoff": self.coverage_cutoff, "from_meta": self.from_meta}


_FILTERS = {0: TextureFilter.Point, 1: TextureFilter.Bilinear, 2: TextureFilter.Trilinear}
_WRAPS = {0: TextureWrap.Repeat, 1: TextureWrap.Clamp}
SPRITE_TEXTURE_TYPE = 8


def read_texture_settings(texture_path: str) -> TextureSettings:
    """The importer settings of ``texture_path`` from ``texture_path + ".meta"`` (Unity's defaults
    when there is none); UnityFileError when the ``.meta`` is not valid YAML."""
    meta = texture_path + ".meta"
    try:
        with open(meta, encoding="utf-8-sig") as fh:
            text = fh.read()
    except OSError:
        return TextureSettings(texture_path)
    ((_, _, body),) = load_documents(text, meta)[:1]
    importer = body.get("TextureImporter") if isinstance(body, dict) else None
    if not isinstance(importer, dict):
        return TextureSettings(texture_path, from_meta=True)

    def number(table: Any, key: str, default: float) -> float:
        if not isinstance(table, dict) or key not in table:
            return default
        return _number(table[key], f"TextureImporter {key}", meta)

    mips = importer.get("mipmaps")
    settings = importer.get("textureSettings")
    sprite = number(importer, "textureType", 0) == SPRITE_TEXTURE_TYPE
    wrap = number(settings, "wrapU", number(settings, "wrapMode", -1))
    return TextureSettings(
        texture_path,
        mipmaps=bool(number(mips, "enableMipMap", 0 if sprite else 1)),
        filter=_FILTERS.get(int(number(settings, "filterMode", -1)), TextureFilter.Bilinear),
        wrap=_WRAPS.get(int(wrap), TextureWrap.Repeat),
        srgb=bool(number(mips, "sRGBTexture", 1)),
        preserve_coverage=bool(number(mips, "mipMapsPreserveCoverage", 0)),
        coverage_cutoff=number(mips, "alphaTestReferenceValue", 0.5),
        from_meta=True)
