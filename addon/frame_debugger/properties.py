"""``Scene.unity_frame_debugger``: what the Frame Debugger panel shows and edits."""

from __future__ import annotations

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

BUFFER_ITEMS = [
    ("COLOR", "Colour", "The colour buffer (stored frame values)", 0),
    ("ALPHA", "Alpha", "The colour buffer's alpha as grey", 1),
    ("DEPTH", "Depth", "The depth buffer as grey: near dark, far (cleared) white", 2),
    ("STENCIL", "Stencil", "The stencil buffer: value / 255 as grey", 3),
]


def _show(self, context) -> None:
    from . import ops

    ops.show_selected(context.scene)


def _select_from_list(self, context) -> None:
    """Selecting a row in the draw list moves the slider to that draw."""
    if 0 <= self.active_draw < len(self.draws) and self.draw != self.active_draw + 1:
        self.draw = self.active_draw + 1  # its update shows the frame


def _select_from_slider(self, context) -> None:
    if self.draw > len(self.draws):
        self.draw = len(self.draws)
        return
    if self.draw >= 1 and self.active_draw != self.draw - 1:
        self.active_draw = self.draw - 1
    _show(self, context)


class UnityFrameDebuggerDraw(bpy.types.PropertyGroup):
    """One captured draw call (the draw list of docs/json.md)"""

    index: IntProperty(name="Draw", description="Draw-call number, from 1 in draw order")
    queue: IntProperty(name="Queue", description="Render-queue number")
    distance: FloatProperty(name="Distance", description="Sort distance from the camera (scene units)")
    object: StringProperty(name="Object", description="The renderer's object")
    slot: IntProperty(name="Slot", description="Material slot index")
    material: StringProperty(name="Material", description="The material")
    pass_index: IntProperty(name="Pass", description="Index of the pass in the material's pass list")
    pass_name: StringProperty(name="Pass Name", description="Name of the pass")
    state: StringProperty(name="State", description="The pass's state as one line of ShaderLab")
    triangles: IntProperty(name="Triangles", description="Triangles drawn (neither culled nor degenerate)")
    fragments: IntProperty(name="Fragments", description="Fragments rasterised, before any test")
    written: IntProperty(name="Written", description="Fragments that passed alpha test, stencil and depth")


class UnityFrameDebuggerFragment(bpy.types.PropertyGroup):
    """One fragment of the pixel history"""

    draw: IntProperty(name="Draw", description="Draw-call number")
    object: StringProperty(name="Object", description="The renderer's object")
    pass_name: StringProperty(name="Pass", description="The pass")
    triangle: IntProperty(name="Triangle", description="Index in the evaluated mesh's loop triangles")
    polygon: IntProperty(name="Face", description="Face (polygon) index; -1: none")
    depth: FloatProperty(name="Depth", description="Window depth of the fragment (after Offset)", precision=6)
    source: FloatVectorProperty(name="Source", size=4, description="The fragment shader's RGBA")
    before: FloatVectorProperty(name="Before", size=4, description="The pixel's stored RGBA before the fragment")
    after: FloatVectorProperty(name="After", size=4, description="The pixel's stored RGBA after the fragment")
    stencil_before: IntProperty(name="Stencil Before", description="Stencil value before the fragment")
    stencil_after: IntProperty(name="Stencil After", description="Stencil value after the fragment")
    result: StringProperty(name="Result", description="written, or the test that discarded it")


class UnityFrameDebuggerSettings(bpy.types.PropertyGroup):
    """The Unity Frame Debugger's capture and selection"""

    draws: CollectionProperty(type=UnityFrameDebuggerDraw, name="Draw Calls",
                              description="The captured frame's draw calls in order")
    active_draw: IntProperty(name="Selected Draw Call", description="Row selected in the draw-call list",
                             default=0, min=0, update=_select_from_list)
    draw: IntProperty(name="Draw", description="Show the frame after this draw call (0: the cleared frame)",
                      default=0, min=0, update=_select_from_slider)
    buffer: EnumProperty(name="Buffer", items=BUFFER_ITEMS, default="COLOR",
                         description="Which buffer to show in the image \"Unity Frame Debugger\"", update=_show)
    highlight: BoolProperty(name="Highlight Draw", default=False, update=_show,
                            description="Tint the pixels the selected draw call rasterised magenta")
    capture_id: IntProperty(name="Capture", description="Which capture the lists come from (0: none)", default=0)
    status: StringProperty(name="Status", description="What the last capture or pixel pick reported")
    pixel_x: IntProperty(name="X", description="Pixel column, from the left", default=0, min=0)
    pixel_y: IntProperty(name="Y", description="Pixel row, from the top", default=0, min=0)
    fragments: CollectionProperty(type=UnityFrameDebuggerFragment, name="Fragments",
                                  description="The picked pixel's fragments in application order")
    active_fragment: IntProperty(name="Selected Fragment", description="Row selected in the fragment list", default=0)
    pixel_text: StringProperty(name="Pixel", description="The picked pixel, its clear and final colour")


CLASSES = (UnityFrameDebuggerDraw, UnityFrameDebuggerFragment, UnityFrameDebuggerSettings)


def attach() -> None:
    bpy.types.Scene.unity_frame_debugger = PointerProperty(
        type=UnityFrameDebuggerSettings, name="Unity Frame Debugger",
        description="The Unity Frame Debugger's captured draw calls and pixel history")


def detach() -> None:
    if hasattr(bpy.types.Scene, "unity_frame_debugger"):
        del bpy.types.Scene.unity_frame_debugger
