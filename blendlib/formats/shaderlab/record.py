"""THE material record: the JSON that ``python -m blendlib shaderlab`` prints for a ``.shader`` or
``.mat`` file, and that other importers (the VRM importer, issue 28) print per material.

``{"name", "material", "passes", "warnings", "extra"}``:

* ``material`` — the fields of ``Material.unity`` other than the passes (``enabled`` true: an
  imported material is in use); ``main_tex`` is the texture's file path, or null;
* ``passes`` — every pass in order, with the ``Pass`` fields of ``Material.unity`` plus
  ``drawn`` and ``reason`` (:func:`blendlib.core.vocabulary.pass_draws`, in a scene with one
  directional light: ForwardAdd passes are not drawn there); a pass left out of the material
  (disabled by the ``.mat``, ``ZTest Never``) is listed with ``drawn`` false and why;
* ``warnings`` — one line each, what is not imported or approximated;
* ``extra`` — what else the file says (tags, LightMode names as written, Fallback, properties, …).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import fields
from typing import Any

from ...core.vocabulary import CHANNELS, ONCE, PER_LIGHT, Material, Pass, pass_draws, pass_to_dict

#: Why a ForwardAdd pass is not drawn in the record's scene (one directional light).
NO_EXTRA_LIGHT = " (not in a scene with one directional light)"


def json_ready(value: Any) -> Any:
    """``value`` with dicts, tuples, sets and str enums made JSON types (a colour mask as RGBA letters)."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, (frozenset, set)):
        return [c for c in CHANNELS if c in value]
    if hasattr(value, "value") and isinstance(value, str):  # str enums
        return value.value
    return value


def pass_entry(p: Pass, passes: Sequence[Pass], excluded: str | None = None) -> dict[str, Any]:
    """A pass of ``passes`` (the material's) with ``drawn`` and ``reason``; ``excluded``: why a
    pass that is not in ``passes`` never draws."""
    entry = pass_to_dict(p)
    if excluded is not None:
        return entry | {"drawn": False, "reason": excluded}
    how, reason = pass_draws(p, tuple(passes))
    if how == PER_LIGHT:
        return entry | {"drawn": False, "reason": reason + NO_EXTRA_LIGHT}
    return entry | {"drawn": how == ONCE, "reason": reason}


def material_record(name: str, material: Material, warnings: Sequence[str] = (), extra: dict | None = None,
                    listed: Sequence[tuple[Pass, str | None]] | None = None,
                    main_tex_file: str | None = None) -> dict[str, Any]:
    """The material record (module docstring) of ``material``.

    ``listed``: every pass in order with None, or the reason it is left out of the material
    (default: the material's passes); ``main_tex_file``: the path of ``_MainTex``'s image."""
    material_fields = {"enabled": True} | {f.name: getattr(material, f.name) for f in fields(Material)
                                           if f.name not in ("name", "passes")}
    material_fields["main_tex"] = main_tex_file
    width_tex = material.outline_width_tex  # pixels are not JSON: the texture by its name
    material_fields["outline_width_tex"] = None if width_tex is None else width_tex.name
    if listed is None:
        listed = [(p, None) for p in material.passes]
    return {
        "name": name,
        "material": json_ready(material_fields),
        "passes": [pass_entry(p, material.passes, why) for p, why in listed],
        "warnings": list(warnings),
        "extra": json_ready(extra or {}),
    }


def record_json(record: dict[str, Any], indent: int | None = 2) -> str:
    return json.dumps(record, indent=indent, ensure_ascii=False)
