"""Heat-map images with a legend (the ``analyze`` command's ``.png`` outputs, ``compare --diff`` and
the pytest plugin's difference maps).

A value map (H, W) becomes an RGBA image: black for 0, then red → yellow → white up to the
largest value, with a legend strip below — the colour bar, tick marks at round values with
their numbers, and what the values count on a line of its own. Several maps side by side
(:func:`heat_panels`) get their names in a caption strip above them, never over the data.
Text is drawn with Pillow's built-in font when Pillow is installed (it comes with matplotlib);
without it the legend is the bar and tick marks only.
"""

from __future__ import annotations

import math

import numpy as np

#: Height of the legend strip below a heat map: bar, ticks, numbers, label.
LEGEND_HEIGHT = 46
#: Height of the caption strip above side-by-side panels.
CAPTION_HEIGHT = 16
#: Text size (pixels) of legends and captions.
FONT_SIZE = 12
#: The legend and caption background (grey, opaque).
BACKGROUND = 0.12


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


def tick_values(peak: float, room: int, integer: bool = False) -> list[float]:
    """Round values from 0 to ``peak`` for a bar ``room`` pixels long: a step of 1, 2 or 5 × 10^k
    (at least 1 for ``integer`` counts) leaving about 60 pixels between ticks, and at least one
    tick between 0 and ``peak``; ``peak`` itself is the last tick."""
    if not (peak > 0 and math.isfinite(peak)):
        return [0.0]
    wanted = max(1, room // 60)
    raw = peak / wanted
    magnitude = 10.0 ** math.floor(math.log10(raw))
    nice = [m * magnitude for m in (0.5, 1, 2, 5, 10)]
    k = next(i for i, v in enumerate(nice) if v >= raw)
    if nice[k] * 2 > peak and k > 0:  # at least one tick between 0 and the peak
        k -= 1
    step = nice[k]
    if integer:
        step = max(1.0, round(step))
    ticks = [k * step for k in range(int(peak / step) + 1)]
    if peak - ticks[-1] > 1e-9 * peak:
        ticks.append(peak)
    return ticks


def _font():
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=FONT_SIZE)
    except (TypeError, OSError):  # an old Pillow or no FreeType: the bitmap font
        return ImageFont.load_default()


def _legend(width: int, peak: float, label: str, integer: bool = False) -> np.ndarray:
    """(LEGEND_HEIGHT, width, 4) float32: the colour bar from 0 to ``peak``, ticks and numbers at
    round values (:func:`tick_values`), and ``label`` on its own line."""
    strip = np.full((LEGEND_HEIGHT, width, 4), BACKGROUND, np.float32)
    strip[..., 3] = 1.0
    margin = 4
    length = max(width - 2 * margin, 1)
    bar = np.linspace(0.0, peak, length)[None, :].repeat(10, axis=0)
    strip[4:14, margin:margin + length] = colour_map(bar, peak)
    ticks = tick_values(peak, length, integer)
    xs = [margin + (round(t / peak * (length - 1)) if peak > 0 else 0) for t in ticks]
    for x in xs:
        strip[14:18, min(x, width - 1)] = 1.0
    try:
        from PIL import Image, ImageDraw
    except ImportError:  # the bar and ticks alone
        return strip
    image = Image.fromarray((strip * 255 + 0.5).astype(np.uint8), "RGBA")
    draw = ImageDraw.Draw(image)
    font = _font()
    white = (255, 255, 255, 255)
    spans = []  # (left, right, text) of each tick's number, centred under its tick, kept inside the strip
    for t, x in zip(ticks, xs, strict=True):
        text = _number(t)
        box = draw.textbbox((0, 0), text, font=font)
        w = box[2] - box[0]
        left = min(max(x - w // 2, 0), max(width - w, 0))
        spans.append((left, left + w, text))
    # 0 and the peak always; a number between them only where it overlaps neither its left
    # neighbour written nor the peak's
    shown = [spans[0]]
    for span in spans[1:-1]:
        if span[0] > shown[-1][1] + 6 and span[1] + 6 < spans[-1][0]:
            shown.append(span)
    if len(spans) > 1:
        shown.append(spans[-1])
    for left, _, text in shown:
        draw.text((left, 18), text, fill=white, font=font)
    box = draw.textbbox((0, 0), label, font=font)
    draw.text((max((width - (box[2] - box[0])) // 2, 0), 32), label, fill=white, font=font)
    return np.asarray(image, np.float32) / 255.0


def heat_image(values: np.ndarray, label: str, peak: float | None = None, floor: float = 0.08,
               integer: bool = False) -> np.ndarray:
    """(H, W) values → (H + LEGEND_HEIGHT, W, 4) float32 heat map with its legend below (row 0 =
    top); ``integer``: the values are counts (ticks at whole numbers)."""
    v = np.asarray(values, np.float64)
    if peak is None:
        finite = v[np.isfinite(v)]
        peak = float(finite.max()) if finite.size else 0.0
    return np.concatenate([colour_map(v, peak, floor), _legend(v.shape[1], peak, label, integer)], axis=0)


def heat_panels(panels: list[tuple[np.ndarray, str]], label: str, integer: bool = False) -> np.ndarray:
    """Several (H, W) maps side by side on one scale (a 2-pixel gap), their names in a caption
    strip above them and one legend below."""
    peak = max((float(np.max(v)) if np.size(v) else 0.0) for v, _ in panels)
    h = panels[0][0].shape[0]
    gap = np.full((h, 2, 4), BACKGROUND, np.float32)
    gap[..., 3] = 1
    row = []
    for k, (values, _) in enumerate(panels):
        if k:
            row.append(gap)
        row.append(colour_map(values, peak))
    top = np.concatenate(row, axis=1)
    caption = np.full((CAPTION_HEIGHT, top.shape[1], 4), BACKGROUND, np.float32)
    caption[..., 3] = 1
    try:
        from PIL import Image, ImageDraw
    except ImportError:
        pass
    else:
        image = Image.fromarray((caption * 255 + 0.5).astype(np.uint8), "RGBA")
        draw = ImageDraw.Draw(image)
        x = 0
        for values, name in panels:
            draw.text((x + 3, 1), name, fill=(120, 200, 255, 255), font=_font())
            x += values.shape[1] + 2
        caption = np.asarray(image, np.float32) / 255.0
    return np.concatenate([caption, top, _legend(top.shape[1], peak, label, integer)], axis=0)
