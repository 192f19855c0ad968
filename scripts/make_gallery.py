"""Render every example scene with the project's own renderer and build docs/gallery.png.

    .venv/bin/python scripts/make_gallery.py                 # docs/gallery.png + out/<file>[-<Scene>].png
    .venv/bin/python scripts/make_gallery.py --out DIR       # the full-size renders go to DIR

Each scene of ``blend_files/*.blend`` is rendered at its own resolution (640x360,
as F12 would) through :func:`blendlib.render` and written as an 8-bit PNG; the
contact sheet shows them at 480x270 (a 2x2 box filter of a render at 150 %,
so the labels stay readable), captioned with the number and the
experiment. Captions are drawn with Blender's own font (``blf`` into an ``imbuf``),
so nothing beyond bpy and numpy is needed.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

#: (file, scene, caption) in gallery order.
CAPTIONS = (
    ("alpha_test", "AlphaTest", "1  Alpha test at four _Cutoff values, one- and two-sided"),
    ("alpha_blend", "AlphaBlend", "2  Alpha blend over an opaque cube, both queue orders"),
    ("two_transparent", "TwoTransparent", "3  Two transparent objects: sorted vs inverted"),
    ("cyclic_overlap", "CyclicOverlap", "4  Cyclic overlap: no object order is right"),
    ("self_overlap", "SelfOverlap", "5  Self-overlap with ZWrite Off, fixed by a depth prepass"),
    ("two_sided", "TwoSided", "6  Two-sided blending: 2 passes | Cull Off | Cull Back"),
    ("blend_modes", "BlendModes", "7  Blend modes over a textured background"),
    ("render_queues", "RenderQueues", "8  Render queues, Overlay ZTest Always, Transparent+1"),
    ("gamma_linear", "Gamma", "9a Gamma colour space: blending encoded values"),
    ("gamma_linear", "Linear", "9b Linear colour space: blending in linear light"),
    ("lights", "Lights", "10 Additional lights: ForwardAdd once per per-pixel light"),
    ("vrm_avatar", "Avatar", "11a VRM avatar: the skirt's ZWrite hides the stockings"),
    ("vrm_avatar", "AvatarFace", "11b VRM avatar: eyebrows over bangs, lashes over lenses"),
    ("unity_builtins", "UnityBuiltins", "12 Unity's built-in shaders: particles, sprite, UI, Standard"),
    ("foliage", "Foliage", "13a Foliage: mipmaps, Preserve Coverage, AlphaToMask, MSAA off"),
    ("foliage", "FoliageMSAA", "13b Foliage at MSAA 4x: AlphaToMask turns alpha into coverage"),
)

TILE = (480, 270)
COLUMNS = 2
CAPTION_H = 30
GAP = 10
BG = (24, 26, 30)


def text_image(text: str, width: int, height: int, size: int = 17) -> np.ndarray:
    """Coverage (height, width) float32 of ``text`` in Blender's default font, row 0 = top."""
    import blf
    import imbuf

    from blendlib.formats import images

    ib = imbuf.new((width, height))
    with blf.bind_imbuf(0, ib):
        blf.size(0, size)
        blf.color(0, 1.0, 1.0, 1.0, 1.0)
        blf.position(0, 8, (height - size) // 2 + 3, 0)
        blf.draw_buffer(0, text)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "caption.png"
        imbuf.write(ib, filepath=str(path))
        return images.load(path)[..., 3].astype(np.float32)


def render_scene_png(file: str, scene_name: str, percentage: int = 100) -> np.ndarray:
    """The frame of one scene as (H, W, 3) uint8 codes (row 0 top), at ``percentage`` % of its resolution."""
    import bpy

    import blendlib

    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "blend_files" / f"{file}.blend"), load_ui=False)
    scene = bpy.data.scenes[scene_name]
    scene.render.resolution_percentage = percentage  # in memory only; the file is not saved
    frame = blendlib.render(scene)
    return np.floor(np.clip(frame.color[..., :3], 0, 1) * 255 + 0.5).astype(np.uint8)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description="render the example scenes and the gallery contact sheet")
    parser.add_argument("--out", default=str(ROOT / "out"), help="folder for the full-size renders (default out/)")
    parser.add_argument("--sheet", default=str(ROOT / "docs" / "gallery.png"), help="contact sheet path")
    args = parser.parse_args(argv)

    import bpy  # noqa: F401  (bpy before addon)

    import addon

    addon.register()  # the scenes name the Unity Passes engine: Blender knows it when it loads them

    from blendlib.formats import images

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tw, th = TILE
    rows = (len(CAPTIONS) + COLUMNS - 1) // COLUMNS
    sheet = np.zeros((GAP + rows * (th + CAPTION_H + GAP), GAP + COLUMNS * (tw + GAP), 3), np.float32)
    sheet[:] = np.array(BG, np.float32) / 255
    for k, (file, scene_name, caption) in enumerate(CAPTIONS):
        full = render_scene_png(file, scene_name, 100)
        single = sum(1 for f, _, _ in CAPTIONS if f == file) == 1
        path = out / (f"{file}.png" if single else f"{file}-{scene_name}.png")
        images.save(path, full.astype(np.float32) / 255)
        print(f"wrote {path}")
        big = render_scene_png(file, scene_name, 150).astype(np.float32) / 255  # 960x540 → 2x2 box → 480x270
        tile = big.reshape(th, 2, tw, 2, 3).mean(axis=(1, 3))
        r, c = divmod(k, COLUMNS)
        y0 = GAP + r * (th + CAPTION_H + GAP)
        x0 = GAP + c * (tw + GAP)
        cov = text_image(caption, tw, CAPTION_H)[..., None]
        region = sheet[y0:y0 + CAPTION_H, x0:x0 + tw]
        sheet[y0:y0 + CAPTION_H, x0:x0 + tw] = region * (1 - cov) + cov * np.array([0.93, 0.93, 0.93])
        sheet[y0 + CAPTION_H:y0 + CAPTION_H + th, x0:x0 + tw] = tile
    sheet_path = Path(args.sheet)
    sheet_path.parent.mkdir(parents=True, exist_ok=True)
    images.save(sheet_path, sheet)
    print(f"wrote {sheet_path} ({sheet_path.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
