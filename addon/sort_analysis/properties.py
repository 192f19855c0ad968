"""``ViewLayer.unity_analysis`` and the window manager's rows of the last sort analysis."""

from __future__ import annotations

import json

import bpy

REFERENCE_PASS = "UnitySortedReference"
ERROR_PASS = "UnitySortError"
OVERDRAW_PASS = "UnityOverdraw"


class UnitySortAnalysisSettings(bpy.types.PropertyGroup):
    """ViewLayer.unity_analysis: which analysis passes F12 adds to the render result."""

    use_passes: bpy.props.BoolProperty(
        name="Sort Analysis Passes",
        description=("Add the passes UnitySortedReference (what a per-fragment sort would show), UnitySortError "
                     "(8-bit steps, absolute for HDR) and UnityOverdraw (X fragments rasterised, Y written) "
                     "to the render result; the render takes about twice as long"),
        default=False,
    )


class UnitySortAdvice(bpy.types.PropertyGroup):
    """One inverted renderer pair of the last analysis, with its checked advice."""

    front: bpy.props.StringProperty(name="Front", description="Object in front but drawn first")
    behind: bpy.props.StringProperty(name="Behind", description="Object behind but drawn later")
    pixels: bpy.props.IntProperty(name="Pixels", description="Pixels where the pair is drawn out of order")
    text: bpy.props.StringProperty(name="Advice", description="What to change, with its measured effect")
    change: bpy.props.StringProperty(name="Change", description="The suggested setting as JSON (empty: none)")


class UnitySortResults(bpy.types.PropertyGroup):
    """The last analysis of this session (window manager data: never saved with the file)."""

    items: bpy.props.CollectionProperty(type=UnitySortAdvice, name="Inversions",
                                        description="Inverted renderer pairs, most pixels first")
    active_index: bpy.props.IntProperty(name="Active", description="Selected inversion", default=0, min=0)
    summary: bpy.props.StringProperty(name="Summary", description="Differing pixels and the largest error")


CLASSES = (UnitySortAnalysisSettings, UnitySortAdvice, UnitySortResults)


def attach() -> None:
    bpy.types.ViewLayer.unity_analysis = bpy.props.PointerProperty(
        type=UnitySortAnalysisSettings, name="Unity Sort Analysis",
        description="Sorted reference, sort error and overdraw passes (docs/sorting.md)")
    bpy.types.WindowManager.unity_sort_results = bpy.props.PointerProperty(
        type=UnitySortResults, name="Unity Sort Results", description="The last sort analysis of this session")


def detach() -> None:
    for owner, name in ((bpy.types.WindowManager, "unity_sort_results"), (bpy.types.ViewLayer, "unity_analysis")):
        if hasattr(owner, name):
            delattr(owner, name)


def passes_enabled(view_layer) -> bool:
    settings = getattr(view_layer, "unity_analysis", None)
    return bool(settings is not None and settings.use_passes)


def store(results, analysis) -> None:
    """Fill the window manager's rows from an :class:`~blendlib.explain.sorted_reference.Analysis`."""
    summary = analysis.summary()
    unit = "" if analysis.hdr else " steps"
    results.summary = (f"{summary['differing']} of {summary['pixels']} pixels differ "
                       f"(max {summary['max_error']:g}{unit})")
    results.items.clear()
    advice = {(a["front"], a["front_slot"], a["behind"], a["behind_slot"]): a for a in summary["advice"]}
    for inv in summary["inversions"]:
        row = results.items.add()
        row.front = inv["front"] if inv["front_slot"] == 0 else f"{inv['front']} [{inv['front_slot']}]"
        row.behind = inv["behind"] if inv["behind_slot"] == 0 else f"{inv['behind']} [{inv['behind_slot']}]"
        row.pixels = inv["pixels"]
        item = advice.get((inv["front"], inv["front_slot"], inv["behind"], inv["behind_slot"]))
        row.text = item["text"] if item else ""
        row.change = json.dumps(item["change"]) if item and item["change"] else ""
    results.active_index = 0
