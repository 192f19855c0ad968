"""The frame driver: draw list → per draw call (vertex → raster → shade → output merger) → Frame.

Raster and shade of a chunk are pure functions of the chunk; they run on a small
thread pool (numpy releases the GIL in its array loops) while the main thread merges
the previous chunk, so both CPU cores work. Merging stays strictly in draw order.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from . import raster, shade
from .drawlist import sorted_renderers
from .merger import FrameBuffers, merge
from .scene import DrawScene, SceneError, validate_scene
from .shaderlab import Pass

#: Candidate pixels per chunk: bounds the memory of one chunk's arrays to a few hundred MB.
CHUNK_CANDIDATES = 1 << 20


class RenderCancelled(Exception):
    """Raised when ``should_cancel()`` returned True; no buffers are returned."""


@dataclass(eq=False)
class Frame:
    """A rendered frame. Row 0 is the top of the image.

    - ``color`` (H, W, 4) float32: the stored frame values (sRGB-encoded in Gamma
      mode and in Linear LDR; linear in Linear HDR).
    - ``depth`` (H, W) float32: window depth ``d / (2**24 - 1)``.
    - ``stencil`` (H, W) uint8.
    - ``warnings``: one line each (skipped triangles, empty meshes, missing images).
    """

    color: np.ndarray
    depth: np.ndarray
    stencil: np.ndarray
    warnings: list[str] = field(default_factory=list)


def _shade_chunk(setup, rows, start, stop, width, p: Pass, material, texels, lights, color_space):
    """Raster + interpolate + shade + alpha test of rows [start, stop): (pix, depth, rgba) in draw order."""
    frags = raster.rasterize_rows(rows, start, stop, width)
    if frags.count == 0:
        return None
    depth, weights = raster.interpolate(setup, frags, p.offset_factor, p.offset_units)
    src = setup.src[frags.tri]
    if setup.uvs is None:
        uv = np.zeros((frags.count, 2), dtype=np.float64)
    else:
        uv = raster.interpolate_attribute(weights, setup.uvs[src])
    normal = raster.interpolate_attribute(weights, setup.world_normals[src])
    rgba = shade.shade(material, texels, lights, color_space, uv, normal)
    pix = frags.pix
    if p.alpha_test:
        keep = ~(rgba[:, 3] - float(material.cutoff) < 0)
        pix, depth, rgba = pix[keep], depth[keep], rgba[keep]
    return pix, depth, rgba


def render_scene(
    scene: DrawScene,
    *,
    progress: Callable[[float], None] | None = None,
    should_cancel: Callable[[], bool] | None = None,
    workers: int | None = None,
    chunk_candidates: int = CHUNK_CANDIDATES,
) -> Frame:
    """Render a draw scene exactly as Unity's built-in pipeline would (docs/pipeline.md).

    ``progress(fraction)`` is called between draw calls; ``should_cancel()`` is polled
    between draw calls and chunks, and a True answer raises :class:`RenderCancelled`.
    Raises :class:`blendlib.scene.SceneError` (one line) for input that cannot render.
    """
    warnings = list(scene.warnings) + validate_scene(scene)
    cam = scene.camera
    width, height = int(cam.width), int(cam.height)
    cs = scene.color_space
    clear = shade.gamma_color_to_shading(scene.clear_color[:3], cs) + (float(scene.clear_color[3]),)
    buf = FrameBuffers(width, height, scene.hdr, cs, clear)
    lights = shade.frame_lights(scene)
    try:
        order = sorted_renderers(scene)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    calls = sum(len(r.material.draw_passes) for r in order)
    texel_cache: dict[int, np.ndarray] = {}
    workers = workers if workers is not None else min(2, os.cpu_count() or 1)

    def cancelled() -> None:
        if should_cancel is not None and should_cancel():
            raise RenderCancelled("render cancelled")

    done = 0
    pool = ThreadPoolExecutor(max_workers=workers) if workers > 1 else None
    try:
        for renderer in order:
            cancelled()
            mesh = renderer.mesh
            if mesh.triangle_count == 0:
                done += len(renderer.material.draw_passes)
                continue
            setup = raster.setup_triangles(mesh, renderer.matrix_world, cam)
            label = f"object {renderer.name!r} slot {renderer.slot}"
            if setup.skipped_nonfinite:
                warnings.append(f"{label}: skipped {setup.skipped_nonfinite} triangles with non-finite vertices")
            if setup.degenerate:
                warnings.append(f"{label}: {setup.degenerate} degenerate (zero-area) triangles draw nothing")
            material = renderer.material
            texels = None
            if material.main_tex is not None:
                key = id(material.main_tex)
                if key not in texel_cache:
                    texel_cache[key] = shade.texture_texels(material.main_tex, cs)
                texels = texel_cache[key]
            for p in material.draw_passes:
                cancelled()
                selected = raster.cull_select(setup, p.cull)
                rows = raster.coverage_rows(setup, selected, width, height)
                chunks = raster.row_chunks(rows, chunk_candidates)
                args = (setup, rows)
                tail = (width, p, material, texels, lights, cs)
                if pool is None:
                    results = (_shade_chunk(*args, a, b, *tail) for a, b in chunks)
                    for res in results:
                        cancelled()
                        if res is not None:
                            merge(buf, p, *res)
                else:
                    pending: deque = deque()
                    it = iter(chunks)
                    for a, b in it:
                        pending.append(pool.submit(_shade_chunk, *args, a, b, *tail))
                        if len(pending) >= workers:
                            break
                    while pending:
                        res = pending.popleft().result()
                        nxt = next(it, None)
                        if nxt is not None:
                            pending.append(pool.submit(_shade_chunk, *args, nxt[0], nxt[1], *tail))
                        cancelled()
                        if res is not None:
                            merge(buf, p, *res)
                done += 1
                if progress is not None:
                    progress(done / max(calls, 1))
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    color, depth, stencil = buf.output()
    textures = (r.material.main_tex for r in order)
    missing = {t.name for t in textures if t is not None and t.missing}
    warnings.extend(f"image {name!r}: file missing, drawn magenta" for name in sorted(missing))
    return Frame(color=color, depth=depth, stencil=stencil, warnings=warnings)
