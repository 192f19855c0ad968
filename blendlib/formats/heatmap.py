"""Heat-map images with a legend (the ``analyze`` command's ``.png`` outputs).

A value map (H, W) becomes an RGBA image: black for 0, then red → yellow → white up to the
largest value, with a legend strip below — the colour bar, its end values and what they count.
Text is drawn with Pillow's built-in font when Pillow is installed (it comes with matplotlib);
without it the legend is the bar and tick marks only.
"""

from __future__ import annotations

import numpy as np

LEGEND_HEIGHT = 34


def colour_map(values: np.ndarray, peak: float, floor: float = 0.08) -> np.ndarray:
    """(H, W) values → (H, W, 4) float32 RGBA: 0 black → red → yellow → ``peak`` white; any
    non-zero value shows at least at ``floor`` of the ramp."""
    v = np.asarray(values, np.float64)
    t = np.clip(v / peak, 0.0, 1.0) if peak > 0 else np.zeros_like(v)
    t = np.where(v > 0, np.maximum(t, floor), 0.0)
    rgba = np.ones(v.shape + (4,), np.float32)
    rgba[..., 0] = np.clip(3 * t, 0, 1)
    rgba[..., 1] = np.clip(3 * t - 1, 0, 1)
    rgba[..., 2] = np.clip(3 * t - 2, 0, 1)
    return rgba


def _number(x: float) -> str:
    return f"{x:.0f}" if float(x).is_integer() else f"{x:.3g}"


def _legend(width: int, peak: float, label: str) -> np.ndarray:
    """(LEGEND_HEIGHT, width, 4) float32: the colour bar from 0 to ``peak`` and its text."""
    strip = np.full((LEGEND_HEIGHT, width, 4), 0.12, np.float32)
    strip[..., 3] = 1.0
    margin = 4
    bar = np.linspace(0.0, peak, max(width - 2 * margin, 1))[None, :].repeat(10, axis=0)
    strip[4:14, margin:margin + bar.shape[1]] = colour_map(bar, peak)
    strip[14:17, margin] = 1.0
    strip[14:17, margin + bar.shape[1] - 1] = 1.0
    try:
        from PIL import Image, ImageDraw, ImageFont
    except ImportError:  # the bar alone
        return strip
    image = Image.fromarray((strip * 255 + 0.5).astype(np.uint8), "RGBA")
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default()
    left, right = "0", _number(peak)
    draw.text((margin, 18), left, fill=(255, 255, 255, 255), font=font)
    box = draw.textbbox((0, 0), right, font=font)
    draw.text((width - margin - (box[2] - box[0]), 18), right, fill=(255, 255, 255, 255), font=font)
    box = draw.textbbox((0, 0), label, font=font)
    draw.text(((width - (box[2] - box[0])) // 2, 18), label, fill=(255, 255, 255, 255), font=font)
    return np.asarray(image, np.float32) / 255.0


def heat_image(values: np.ndarray, label: str, peak: float | None = None) -> np.ndarray:
    """(H, W) values → (H + legend, W, 4) float32 heat map with its legend below (row 0 = top)."""
    v = np.asarray(values, np.float64)
    if peak is None:
        finite = v[np.isfinite(v)]
        peak = float(finite.max()) if finite.size else 0.0
    return np.concatenate([colour_map(v, peak), _legend(v.shape[1], peak, label)], axis=0)


def heat_panels(panels: list[tuple[np.ndarray, str]], label: str) -> np.ndarray:
    """Several (H, W) maps side by side on one scale (a 2-pixel gap), one legend below.

    Each panel's name is written into its top-left corner when Pillow is available."""
    peak = max((float(np.max(v)) if np.size(v) else 0.0) for v, _ in panels)
    h = panels[0][0].shape[0]
    gap = np.full((h, 2, 4), 0.12, np.float32)
    gap[..., 3] = 1
    row = []
    for k, (values, name) in enumerate(panels):
        if k:
            row.append(gap)
        img = colour_map(values, peak)
        try:
            from PIL import Image, ImageDraw, ImageFont
        except ImportError:
            row.append(img)
            continue
        pil = Image.fromarray((img * 255 + 0.5).astype(np.uint8), "RGBA")
        ImageDraw.Draw(pil).text((3, 2), name, fill=(120, 200, 255, 255), font=ImageFont.load_default())
        row.append(np.asarray(pil, np.float32) / 255.0)
    top = np.concatenate(row, axis=1)
    return np.concatenate([top, _legend(top.shape[1], peak, label)], axis=0)
