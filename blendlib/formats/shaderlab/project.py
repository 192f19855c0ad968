"""Unity project content: a ``.mat`` file imported with its shader and texture (SPEC §11.5), and the
``.mat`` files of a project by material name (Link Unity Project).

:func:`import_material_file` reads the ``.mat`` (:mod:`.material_file`), finds its shader — a
project shader through the ``.meta`` carrying its guid, one of Unity's built-in shaders by its
``fileID`` (:data:`.assets.BUILTIN_SHADERS`) and then by name — on the search path (the ``.mat``'s
project ``Assets/`` folder, or its own folder outside a project, then the given folders), and
imports the shader with the material's values, keywords, disabled passes and render queue
(:func:`.importer.parse_shaderlab`). The main texture (``_MainTex``, or the shader's
``[MainTexture]``) gives ``main_tex_tiling``/``main_tex_offset`` (``m_Scale``/``m_Offset``), and
its image file (through its guid) the sampler settings its ``.meta`` states
(:func:`.material_file.read_texture_settings`).
"""

from __future__ import annotations

import os
import re
from dataclasses import replace
from pathlib import Path

from .assets import BUILTIN_DEFAULT_GUID, BUILTIN_EXTRA_GUID, BUILTIN_SHADERS, AssetSearch
from .importer import ShaderLabResult, parse_shaderlab
from .material_file import read_material_file, read_texture_settings
from .unity_yaml import UnityFileError

_M_NAME_RE = re.compile(r"^  m_Name: ?(.*)$", re.M)
_MATERIAL_DOC_RE = re.compile(r"^Material:[ \t]*$", re.M)


def project_folder(path: str | os.PathLike) -> Path:
    """The ``Assets/`` folder a file lies in (its own folder when it lies in none)."""
    path = Path(path).resolve()
    for parent in path.parents:
        if parent.name == "Assets":
            return parent
    return path.parent


def import_material_file(path: str | os.PathLike, search_folders: tuple[str | os.PathLike, ...] = ()
                         ) -> ShaderLabResult:
    """Import a ``.mat`` file (module docstring). Errors — not a Unity material, its shader not
    found, the shader malformed — raise :class:`~.unity_yaml.UnityFileError` /
    :class:`~.diagnostics.ShaderLabError` (one line); OSError when it cannot be read."""
    path = str(path)
    mat = read_material_file(path)
    search = AssetSearch([project_folder(path), *search_folders])
    if mat.shader_guid is None:
        raise UnityFileError("the material has no shader (m_Shader fileID 0)", 0, 0, path)
    if mat.shader_guid in (BUILTIN_EXTRA_GUID, BUILTIN_DEFAULT_GUID):
        name = BUILTIN_SHADERS.get((mat.shader_guid, mat.shader_file_id))
        if name is None:
            raise UnityFileError(f"m_Shader is built-in shader fileID {mat.shader_file_id}, which is not one this "
                                 "importer knows (docs/unity-shaders.md lists them)", 0, 0, path)
        shader_path = search.shader_path(name)
        if shader_path is None:
            raise UnityFileError(f"the built-in shader {name!r} (fileID {mat.shader_file_id}) is not on the search "
                                 f"path ({search.describe()}): pass Unity's built-in shader source with --search",
                                 0, 0, path)
    else:
        shader_path = search.asset_path(mat.shader_guid)
        if shader_path is None:
            raise UnityFileError(f"no .meta file with the shader's guid {mat.shader_guid} on the search path "
                                 f"({search.describe()})", 0, 0, path)
        if not shader_path.lower().endswith(".shader"):
            raise UnityFileError(f"the shader's guid {mat.shader_guid} is {shader_path}, not a .shader file "
                                 "(Shader Graph and compiled shaders are not read)", 0, 0, path)
    with open(shader_path, encoding="utf-8-sig") as fh:
        text = fh.read()
    result = parse_shaderlab(text, shader_path, search=search.with_folders([Path(shader_path).parent]),
                             values=mat.values, keywords=mat.keywords, disabled_passes=mat.disabled_passes,
                             material_name=mat.name, custom_render_queue=mat.custom_render_queue)
    shader_name = Path(shader_path).name
    warnings = [f"{shader_name}:{w}" for w in result.warnings]
    material = result.material
    extra = dict(result.extra) | {"material_file": path, "shader_file": shader_path,
                                  "string_tag_map": dict(mat.tags), "disabled_passes": list(mat.disabled_passes)}
    tex_name = result.extra.get("main_tex_property")
    main_tex_file = None
    textures = {}
    for prop, slot in mat.textures.items():
        entry: dict = {"guid": slot.guid, "scale": list(slot.scale), "offset": list(slot.offset)}
        if slot.guid is not None:
            file = search.asset_path(slot.guid)
            if file is None:
                entry["missing"] = True
                if prop == tex_name:
                    warnings.append(f"{Path(path).name}: texture {prop} (guid {slot.guid}) is not on the search path; "
                                    "drawn without it (white)")
            else:
                settings = read_texture_settings(file)
                entry |= settings.to_json()
                if prop == tex_name:
                    main_tex_file = file
                    material = replace(material, main_tex_mipmaps=settings.mipmaps, main_tex_filter=settings.filter,
                                       main_tex_wrap=settings.wrap,
                                       main_tex_preserve_coverage=settings.preserve_coverage)
                    if settings.preserve_coverage and settings.coverage_cutoff != material.cutoff:
                        warnings.append(f"{Path(path).name}: {prop}'s mipmaps preserve coverage at "
                                        f"{settings.coverage_cutoff:g} (its importer), drawn at the cutoff "
                                        f"{material.cutoff:g}")
        if prop == tex_name:
            material = replace(material, main_tex_tiling=slot.scale, main_tex_offset=slot.offset)
        textures[prop] = entry
    extra["textures"] = textures
    return ShaderLabResult(material, tuple(warnings), extra, result.listed, main_tex_file)


def project_materials(folder: str | os.PathLike) -> dict[str, list[str]]:
    """The ``.mat`` files under ``folder`` (a project, or its ``Assets/``) by their ``m_Name``, in
    path order; the name is read from the file's text (no YAML parse: a project holds thousands)."""
    root = Path(folder)
    if (root / "Assets").is_dir():
        root = root / "Assets"
    out: dict[str, list[str]] = {}
    for base, dirs, names in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(names):
            if not name.lower().endswith(".mat"):
                continue
            file = os.path.join(base, name)
            try:
                with open(file, encoding="utf-8-sig", errors="replace") as fh:
                    text = fh.read(1 << 16)
            except OSError:
                continue
            doc = _MATERIAL_DOC_RE.search(text)
            m = _M_NAME_RE.search(text, doc.end()) if doc is not None else None
            if m is not None:
                out.setdefault(m.group(1).strip(), []).append(file)
    return out
