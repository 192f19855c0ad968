#!/usr/bin/env python3
"""Build docs/sorting.png: the example scenes' frame, sorted reference, sort error and overdraw.

    .venv/bin/python -m scripts.make_sorting_sheet            # docs/sorting.png
    .venv/bin/python -m scripts.make_sorting_sheet --sheet OUT.png

One row per example scene of ``blend_files/`` that has sorting problems (two transparent objects
in both orders, cyclic overlap, self-overlap with and without a depth prepass): the frame Unity
draws, the sorted reference (docs/sorting.md), the sort error (8-bit steps) and the overdraw (fragments
written per pixel) as heat maps on the scale of their legend. docs/sorting.md explains how to
read them. Captions use Blender's font (see scripts/make_gallery.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))

ROWS = (
    ("two_transparent", "TwoTransparent", "Two transparent objects: sorted (left), Transparent+1 inverts (right)"),
    ("cyclic_overlap", "CyclicOverlap", "Cyclic overlap: no object order is right"),
    ("self_overlap", "SelfOverlap", "Self-overlap: ZWrite Off (left), depth prepass (right)"),
)
COLUMNS = ("frame (as Unity draws it)", "sorted reference", "sort error", "overdraw (written)")
TILE = (320, 180)
CAPTION_H = 26
GAP = 8
BG = (24, 26, 30)


def downsample(image: np.ndarray, reduce: str = "mean") -> np.ndarray:
    """(2H, 2W, C) → (H, W, C) by 2x2 boxes (mean for images, max for heat maps: no error fades)."""
    h, w = image.shape[0] // 2, image.shape[1] // 2
    boxes = image[:2 * h, :2 * w].reshape(h, 2, w, 2, -1)
    return boxes.mean(axis=(1, 3)) if reduce == "mean" else boxes.max(axis=(1, 3))


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description="build the sorting sheet of the example scenes")
    parser.add_argument("--sheet", default=str(ROOT / "docs" / "sorting.png"), help="output PNG")
    args = parser.parse_args(argv)

    import bpy

    import blendlib
    from blendlib.formats import heatmap, images
    from scripts.make_gallery import text_image

    tw, th = TILE
    width = GAP + len(COLUMNS) * (tw + GAP)
    band = CAPTION_H + th + heatmap.LEGEND_HEIGHT // 2 + GAP
    sheet = np.zeros((GAP + CAPTION_H + len(ROWS) * (band + CAPTION_H), width, 3), np.float32)
    sheet[:] = np.array(BG, np.float32) / 255

    def put_text(text, y, x, w):
        cov = text_image(text, w, CAPTION_H, size=15)[..., None]
        region = sheet[y:y + CAPTION_H, x:x + w]
        sheet[y:y + CAPTION_H, x:x + w] = region * (1 - cov) + cov * np.array([0.93, 0.93, 0.93])

    for c, name in enumerate(COLUMNS):
        put_text(name, GAP, GAP + c * (tw + GAP), tw)
    y = GAP + CAPTION_H
    for file, scene_name, caption in ROWS:
        bpy.ops.wm.open_mainfile(filepath=str(ROOT / "blend_files" / f"{file}.blend"), load_ui=False)
        result = blendlib.analyze(bpy.data.scenes[scene_name], max_advice=3)
        put_text(f"{caption}: {result.differing} px differ, max {result.error.max():g} steps", y, GAP, width - 2 * GAP)
        y += CAPTION_H
        tiles = [
            downsample(np.clip(result.frame.color[..., :3], 0, 1)),
            downsample(np.clip(result.reference[..., :3], 0, 1)),
            downsample(heatmap.heat_image(result.error, "error in 8-bit steps")[..., :3], "max"),
            downsample(heatmap.heat_image(result.overdraw[..., 1], "fragments written")[..., :3], "max"),
        ]
        for c, tile in enumerate(tiles):
            x = GAP + c * (tw + GAP)
            sheet[y:y + tile.shape[0], x:x + tw] = tile[:, :tw]
        y += band
        for item in result.advice:
            print(f"{file}: {item['text']}")
    sheet = sheet[:y + GAP]
    images.save(args.sheet, sheet)
    print(f"wrote {args.sheet}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
