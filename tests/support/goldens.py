"""Regenerate the golden buffers of the example scenes, on purpose.

    .venv/bin/python -m tests.support.goldens          # every blend_files/*.blend
    .venv/bin/python -m tests.support.goldens --check  # compare only, write nothing (exit 1 on a difference)

Run from the repository root.

For every scene of every ``blend_files/*.blend`` this renders the frame at
``GOLDEN_PERCENTAGE`` % of the scene's resolution (640x360 → 320x180) with the
project's own renderer and stores, losslessly, in ``tests/golden/<file>.npz``:

- ``<Scene>.color``: (H, W, 4) uint8, the 8-bit codes of the LDR colour buffer
  (``Frame.color * 255`` is exactly an integer for an LDR frame);
- ``<Scene>.depth``: (H, W) uint32, the 24-bit depth codes (``Frame.depth * (2**24 - 1)``);
- ``<Scene>.stencil``: (H, W) uint8.

``tests/golden/manifest.json`` records the sha256 of each ``.blend`` the buffers
were made from; ``tests/test_example_scenes.py`` fails when a scene file changes
without its golden buffers (run ``scripts/make_blend_files.py`` and then this).
Row 0 of every array is the top of the image.

The functions here are also what the tests use to load a scene and render it.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

BLEND_DIR = ROOT / "blend_files"
GOLDEN_DIR = ROOT / "tests" / "golden"
MANIFEST = GOLDEN_DIR / "manifest.json"
GOLDEN_PERCENTAGE = 50
DMAX = 2**24 - 1


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def ensure_addon() -> None:
    """Register the add-on (as Blender does when it is enabled) unless it already is."""
    import bpy

    if not hasattr(bpy.types.Material, "unity"):
        import addon

        addon.register()


def load_draw_scenes(path: Path, percentage: int = GOLDEN_PERCENTAGE) -> dict:
    """Open a .blend and return ``{scene name: DrawScene}`` at ``percentage`` % resolution.

    The file on disk is not modified (the percentage is changed in memory only).
    DrawScenes hold numpy copies, so they stay valid after another file is opened.
    """
    import bpy

    from blendlib import blender

    ensure_addon()
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    out = {}
    for scene in sorted(bpy.data.scenes, key=lambda s: s.name):
        if percentage is not None:
            scene.render.resolution_percentage = percentage
        out[scene.name] = blender.build_draw_scene(scene)
    return out


def frame_codes(frame) -> dict[str, np.ndarray]:
    """Lossless integer codes of an LDR frame: colour uint8, depth uint32 (24 bit), stencil uint8."""
    color = np.asarray(frame.color, np.float64) * 255.0
    codes = np.rint(color)
    if codes.size and np.abs(codes - color).max() > 1e-3:
        raise ValueError("frame colour is not an 8-bit LDR buffer")
    depth = np.rint(np.asarray(frame.depth, np.float64) * DMAX)
    return {
        "color": codes.astype(np.uint8),
        "depth": depth.astype(np.uint32),
        "stencil": np.asarray(frame.stencil, np.uint8),
    }


def render_codes(draw) -> dict[str, np.ndarray]:
    from blendlib import render_scene

    return frame_codes(render_scene(draw))


def blend_files() -> list[Path]:
    return sorted(BLEND_DIR.glob("*.blend"))


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="compare with the stored goldens, write nothing")
    args = parser.parse_args(argv)
    import bpy

    manifest = {
        "about": "golden buffers of blend_files/*.blend; regenerate with python -m tests.support.goldens",
        "percentage": GOLDEN_PERCENTAGE,
        "blender": bpy.app.version_string,
        "files": {},
    }
    GOLDEN_DIR.mkdir(parents=True, exist_ok=True)
    status = 0
    for path in blend_files():
        draws = load_draw_scenes(path)
        arrays = {}
        entry = {"sha256": sha256(path), "scenes": {}}
        for name, draw in draws.items():
            codes = render_codes(draw)
            for key, value in codes.items():
                arrays[f"{name}.{key}"] = value
            h, w = codes["depth"].shape
            entry["scenes"][name] = {"width": w, "height": h}
        manifest["files"][path.name] = entry
        target = GOLDEN_DIR / f"{path.stem}.npz"
        if args.check:
            old = np.load(target)
            same = set(old.files) == set(arrays) and all(np.array_equal(old[k], arrays[k]) for k in arrays)
            print(f"{path.name}: {'same' if same else 'DIFFERENT'}")
            status |= 0 if same else 1
        else:
            np.savez_compressed(target, **arrays)
            print(f"wrote {target.relative_to(ROOT)} ({target.stat().st_size} bytes) for {path.name}")
    if not args.check:
        MANIFEST.write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
        print(f"wrote {MANIFEST.relative_to(ROOT)}")
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
