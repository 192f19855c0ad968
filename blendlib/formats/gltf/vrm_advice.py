"""Sort advice in VRM terms (issue 28, SPEC §11.6): the changes of a VRM Add-on MToon material's own
settings that draw it earlier or later, or that stop it sorting against others (bpy-free).

:class:`VrmSettings` is what :func:`blendlib.explain.advice.advise` asks for a material whose Unity
state comes from the VRM Add-on (``settings=`` there): for a wanted queue it lists the changes, each
as the change to write (the :class:`~.vrm_addon.AddonMToon` fields, JSON), the
:class:`~blendlib.core.vocabulary.Material` UniVRM then draws (through the same export and import as
the live material, :func:`~.vrm_addon.addon_material`) and a sentence. The advice measures each by
rendering, as it measures a queue offset.

What a VRM avatar can change, by the exporter its armature selects:

* VRM 1.0: ``renderQueueOffsetNumber``, which MToon's validator clamps: Transparent ``3000 +
  clamp(offset, −9, 0)``, Transparent With Z-Write ``2501 + clamp(offset, 0, 9)``; Opaque and Cutout
  force it to 0 (:func:`.vrm1.validated_queue`). An offset outside the clamp is never proposed
  (UniVRM would draw it at the clamp).
* VRM 0.x: ``mtoon0_render_queue``, exported as ``renderQueue`` and used as stored by the legacy
  loader; proposed within MToon 0.x's ranges for the mode (``MToonUtils`` / vrm-specification #36:
  Transparent 2951–3000, Transparent With Z-Write 2501–2550), the ranges MToon's inspector keeps.
* the render mode: a Transparent material as Transparent With Z-Write (it writes depth: what lies
  behind it and comes later fails the depth test; it moves to queue 2501 + offset, 0.x 2501), or as
  Cutout (alpha tested at its ``alpha_cutoff``, queue 2450): the VRM ways out of a self-overlap.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from ...core.vocabulary import Material
from .vrm_addon import AddonMToon, addon_material

#: MToon 0.x's render queue ranges per mode (inclusive), which ``mtoon0_render_queue`` stays in.
MTOON0_QUEUES = {"Transparent": (2951, 3000), "Transparent With Z-Write": (2501, 2550)}
#: MToon 1.0's ``renderQueueOffsetNumber`` clamp per mode and the queue it adds to.
MTOON1_OFFSETS = {"Transparent": (-9, 0, 3000), "Transparent With Z-Write": (0, 9, 2501)}

Option = tuple[dict[str, Any], Material, str]


@dataclass(frozen=True)
class VrmSettings:
    """A VRM Add-on material's MToon settings (``mtoon``) and the export its armature selects (``spec``:
    ``"0.x"`` or ``"1.0"``)."""

    mtoon: AddonMToon
    spec: str

    def material(self, changed: AddonMToon, old: Material) -> Material:
        """The Material UniVRM draws for ``changed`` (``old``'s name and texture pixels kept)."""
        return replace(addon_material(changed, self.spec).material, name=old.name, main_tex=old.main_tex)

    def _queue_fields(self, mode: str, queue: int) -> dict[str, int] | None:
        """The settings that put a material of render ``mode`` at ``queue`` (None: outside the clamp)."""
        if self.spec == "1.0":
            low, high, base = MTOON1_OFFSETS.get(mode, (0, 0, None))
            if base is None or not low <= queue - base <= high:
                return None
            return {"render_queue_offset_number": queue - base}
        low, high = MTOON0_QUEUES.get(mode, (0, -1))
        return {"mtoon0_render_queue": queue} if low <= queue <= high else None

    def _option(self, fields: dict[str, Any], old: Material, what: str) -> Option:
        changed = replace(self.mtoon, **fields)
        material = self.material(changed, old)
        change = {"material": old.name, "vrm": fields, "vrm_spec": self.spec}
        return change, material, f"{what} (queue {material.render_queue})"

    def options(self, old: Material, *, after: int | None = None, before: int | None = None) -> list[Option]:
        """The changes to try for material ``old`` (as drawn now): its queue setting that draws it after
        queue ``after`` or before queue ``before`` (when the clamp allows), then the render modes that
        write depth or test alpha (for a Transparent material; Cutout also for Transparent With Z-Write)."""
        mtoon, name = self.mtoon, f"VRM material '{old.name}'"
        mode = mtoon.render_mode
        out = []
        for target in (None if after is None else after + 1, None if before is None else before - 1):
            fields = None if target is None else self._queue_fields(mode, target)
            if fields is not None:
                (key, value), = fields.items()
                label = "Render Queue Offset Number" if key == "render_queue_offset_number" else "Render Queue"
                out.append(self._option(fields, old, f"set the {label} of {name} to {value}"))
        if mode == "Transparent":
            fields: dict[str, Any] = {"transparent_with_z_write": True}
            if self.spec == "0.x":
                fields["mtoon0_render_queue"] = MTOON0_QUEUES["Transparent With Z-Write"][0]
            out.append(self._option(fields, old, f"set {name} to Transparent With Z-Write (it writes depth)"))
        if mode in ("Transparent", "Transparent With Z-Write"):
            fields = {"alpha_mode": "MASK"}
            if self.spec == "0.x":
                fields["mtoon0_render_queue"] = 2450
            out.append(self._option(fields, old, f"set {name} to Cutout (alpha cutoff {mtoon.alpha_cutoff:g})"))
        return out
