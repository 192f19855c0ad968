"""Image files without Blender: PNG (8-bit), OpenEXR (float), NPY, and buffer comparison.

Arrays here are ``(H, W, C)`` with row 0 the *top* of the image (as a
:class:`blendlib.pipeline.Frame` and as the files store them).

- PNG: written as 8-bit RGBA of the values (``floor(clamp(v, 0, 1) * 255 + 0.5)``, no
  colour conversion); read: 8/16-bit grey, grey+alpha, RGB, RGBA, palette, non-interlaced.
- EXR: written as uncompressed 32-bit float RGBA scanlines (exact values); read: scanline
  files with NONE, ZIPS or ZIP compression and HALF/FLOAT/UINT channels (Blender's default
  EXR codec is ZIP).
- NPY: the exact array.

Every writer goes through :func:`save`, which writes a temporary file next to the
target and renames it, so an error never leaves a half-written file.
"""

from __future__ import annotations

import math
import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .atomic import write_atomic

FORMATS = (".png", ".exr", ".npy")


class ImageIOError(ValueError):
    """A file that cannot be read or written; the message is one line."""


# ---------------------------------------------------------------------------
# Generic entry points
# ---------------------------------------------------------------------------


def file_format(path: str | os.PathLike) -> str:
    """``".png"``, ``".exr"`` or ``".npy"`` from the file name; ImageIOError otherwise."""
    ext = Path(path).suffix.lower()
    if ext not in FORMATS:
        raise ImageIOError(f"{os.fspath(path)}: unsupported image type {ext or '(none)'!r} "
                           f"(use one of {', '.join(FORMATS)})")
    return ext


def as_rgba(array: np.ndarray) -> np.ndarray:
    """(H, W), (H, W, 1|2|3|4) → (H, W, 4) float32 (grey replicated, missing alpha = 1)."""
    a = np.asarray(array)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4):
        raise ImageIOError(f"expected an (H, W[, 1..4]) image array, got shape {a.shape}")
    a = a.astype(np.float32, copy=False)
    h, w, c = a.shape
    out = np.ones((h, w, 4), np.float32)
    if c in (1, 2):
        out[..., :3] = a[..., :1]
        if c == 2:
            out[..., 3] = a[..., 1]
    else:
        out[..., :c] = a
    return out


def save(path: str | os.PathLike, color: np.ndarray) -> Path:
    """Write ``color`` (H, W, C) to ``path`` by its extension, atomically (temp file + rename)."""
    path = Path(path)
    ext = file_format(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ImageIOError(f"{path}: output directory {str(folder)!r} does not exist")
    if ext == ".npy":
        data = None
    elif ext == ".png":
        data = encode_png(color)
    else:
        data = encode_exr(color)
    if data is None:
        write_atomic(path, lambda fh: np.save(fh, np.asarray(color), allow_pickle=False))
    else:
        write_atomic(path, data)
    return path


def load(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG (values / 255), EXR or NPY file as a float32 (H, W, C) array, row 0 the top."""
    path = Path(path)
    ext = file_format(path)
    if not path.is_file():
        raise ImageIOError(f"{path}: no such file")
    if ext == ".npy":
        try:
            a = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise ImageIOError(f"{path}: not a readable .npy file ({exc})") from None
        if a.ndim not in (2, 3):
            raise ImageIOError(f"{path}: expected a 2-D or 3-D array, got shape {a.shape}")
        if a.dtype.kind not in "biuf":
            raise ImageIOError(f"{path}: the array holds {a.dtype} values; expected real numbers (float or integer)")
        with np.errstate(over="ignore"):  # beyond float32: inf, a difference like any other
            return a.astype(np.float32, copy=False)
    data = path.read_bytes()
    try:
        return decode_png(data) if ext == ".png" else decode_exr(data)
    except ImageIOError as exc:
        raise ImageIOError(f"{path}: {exc}") from None
    except (zlib.error, struct.error, ValueError, IndexError) as exc:
        raise ImageIOError(f"{path}: corrupt {ext[1:].upper()} file ({exc})") from None


# ---------------------------------------------------------------------------
# PNG
# ---------------------------------------------------------------------------

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def to_uint8(color: np.ndarray) -> np.ndarray:
    """``floor(clamp(v, 0, 1) * 255 + 0.5)`` as uint8 (NaN → 0)."""
    v = np.nan_to_num(np.asarray(color, np.float64), nan=0.0)
    return np.floor(np.clip(v, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(color: np.ndarray) -> bytes:
    """8-bit RGBA PNG bytes of ``color`` (H, W, C) floats in [0, 1] (or uint8), row 0 the top."""
    a = np.asarray(color)
    rgba = as_rgba(a) if a.dtype != np.uint8 else a
    q = rgba if rgba.dtype == np.uint8 else to_uint8(rgba)
    if q.ndim != 3 or q.shape[2] != 4:
        q = to_uint8(as_rgba(q.astype(np.float32) / 255.0))
    h, w = q.shape[:2]
    raw = np.zeros((h, 1 + w * 4), np.uint8)  # filter byte 0 per row
    raw[:, 1:] = q.reshape(h, w * 4)
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)
    return _PNG_MAGIC + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + \
        _chunk(b"IEND", b"")


def _unfilter(rows: np.ndarray, w: int, bpp: int) -> np.ndarray:
    """Undo PNG row filters: ``rows`` (H, 1 + W*bpp) uint8 with the filter type first → (H, W*bpp).

    Every filter predicts a byte from its left (a), upper (b) and upper-left (c) neighbours
    of the *decoded* image, so pixel (x, y) depends only on pixels with a smaller x + y.
    Decoding walks the anti-diagonals x + y = k (W + H - 1 steps), each step vectorised over
    all rows and channels, whatever filter each row uses.
    """
    h = rows.shape[0]
    kinds = rows[:, 0].astype(np.int64)
    if np.any(kinds > 4):
        raise ImageIOError(f"bad PNG filter type {int(kinds.max())}")
    filt = rows[:, 1:].reshape(h, w, bpp).astype(np.int64)
    if np.all(kinds == 0):
        return filt.astype(np.uint8).reshape(h, w * bpp)
    # One zero row above and one zero column to the left stand for "outside the image".
    out = np.zeros((h + 1, w + 1, bpp), dtype=np.int64)
    ys_all = np.arange(h)
    for k in range(w + h - 1):
        ys = ys_all[max(0, k - w + 1):min(h, k + 1)]
        xs = k - ys
        a = out[ys + 1, xs]  # left
        b = out[ys, xs + 1]  # up
        c = out[ys, xs]  # up-left
        kind = kinds[ys][:, None]
        p = a + b - c
        pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
        paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
        pred = np.select([kind == 1, kind == 2, kind == 3, kind == 4], [a, b, (a + b) >> 1, paeth], 0)
        out[ys + 1, xs + 1] = (filt[ys, xs] + pred) & 0xFF
    return out[1:, 1:].astype(np.uint8).reshape(h, w * bpp)


def decode_png(data: bytes) -> np.ndarray:
    """PNG bytes → (H, W, 4) float32 of the stored values / (2^depth - 1), row 0 the top."""
    if not data.startswith(_PNG_MAGIC):
        raise ImageIOError("not a PNG file")
    pos, idat, palette, trns, header = 8, [], None, None, None
    while pos + 8 <= len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"PLTE":
            palette = np.frombuffer(body, np.uint8).reshape(-1, 3)
        elif kind == b"tRNS":
            trns = body
        elif kind == b"IEND":
            break
    if header is None:
        raise ImageIOError("PNG without IHDR")
    w, h, depth, ctype, _, _, interlace = header
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(ctype)
    if channels is None or depth not in (8, 16) or (ctype == 3 and depth != 8):
        raise ImageIOError(f"unsupported PNG (colour type {ctype}, bit depth {depth})")
    if interlace:
        raise ImageIOError("interlaced PNG is not supported")
    bpp = channels * depth // 8
    stride = w * bpp
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8)
    if raw.size < h * (stride + 1):
        raise ImageIOError("truncated PNG image data")
    rows = raw[: h * (stride + 1)].reshape(h, stride + 1)
    out = _unfilter(rows, stride // bpp, bpp)
    if depth == 16:
        values = out.reshape(h, w * channels, 2).astype(np.uint32)
        pix = ((values[..., 0] << 8) | values[..., 1]).reshape(h, w, channels).astype(np.float32) / 65535.0
    else:
        pix = out.reshape(h, w, channels).astype(np.float32) / 255.0
    if ctype == 3:
        if palette is None:
            raise ImageIOError("palette PNG without PLTE")
        idx = out.reshape(h, w)
        rgba = np.ones((h, w, 4), np.float32)
        rgba[..., :3] = palette[np.minimum(idx, len(palette) - 1)] / 255.0
        if trns is not None:
            alpha = np.full(256, 255, np.uint8)
            alpha[: len(trns)] = np.frombuffer(trns, np.uint8)
            rgba[..., 3] = alpha[idx] / 255.0
        return rgba
    return as_rgba(pix)


# ---------------------------------------------------------------------------
# OpenEXR (scanline)
# ---------------------------------------------------------------------------

_EXR_MAGIC = struct.pack("<i", 20000630)
_EXR_TYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}
_LINES_PER_BLOCK = {0: 1, 2: 1, 3: 16}


def _attr(name: str, kind: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def encode_exr(color: np.ndarray) -> bytes:
    """Uncompressed 32-bit float RGBA OpenEXR bytes (exact float32 values), row 0 the top."""
    rgba = as_rgba(color).astype("<f4")
    h, w = rgba.shape[:2]
    names = ["A", "B", "G", "R"]  # channel list sorted by name, as OpenEXR requires
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for n in names) + b"\0"
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = (_EXR_MAGIC + struct.pack("<i", 2)
              + _attr("channels", "chlist", chlist)
              + _attr("compression", "compression", b"\0")
              + _attr("dataWindow", "box2i", box)
              + _attr("displayWindow", "box2i", box)
              + _attr("lineOrder", "lineOrder", b"\0")
              + _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
              + _attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + b"\0")
    line_bytes = w * 4 * 4
    chunk = 8 + line_bytes
    first = len(header) + 8 * h
    offsets = np.arange(h, dtype="<u8") * chunk + first
    order = [3, 2, 1, 0]  # A, B, G, R
    planes = np.ascontiguousarray(rgba[..., order].transpose(0, 2, 1))  # (h, 4, w)
    lines = np.empty((h, chunk), np.uint8)
    lines[:, :8] = np.stack([np.arange(h, dtype="<i4"), np.full(h, line_bytes, "<i4")], axis=1) \
        .view(np.uint8).reshape(h, 8)
    lines[:, 8:] = planes.view(np.uint8).reshape(h, line_bytes)
    return header + offsets.tobytes() + lines.tobytes()


def _unzip_exr(block: bytes, expected: int) -> bytes:
    t = np.frombuffer(zlib.decompress(block), np.uint8)
    if t.size != expected:
        raise ImageIOError("bad ZIP block size in EXR")
    d = t.astype(np.int64)
    d[1:] -= 128
    t = (np.cumsum(d) & 0xFF).astype(np.uint8)
    half = (t.size + 1) // 2
    out = np.empty_like(t)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def decode_exr(data: bytes) -> np.ndarray:
    """Scanline OpenEXR bytes → (H, W, 4) float32 (R, G, B, A; Y as grey; missing alpha = 1)."""
    if not data.startswith(_EXR_MAGIC):
        raise ImageIOError("not an OpenEXR file")
    (version,) = struct.unpack("<i", data[4:8])
    if version & 0x200 or version & 0x1000:
        raise ImageIOError("tiled or multi-part EXR is not supported")
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        tend = data.index(b"\0", end + 1)
        (size,) = struct.unpack("<i", data[tend + 1:tend + 5])
        attrs[name] = data[tend + 5:tend + 5 + size]
        pos = tend + 5 + size
    pos += 1
    channels = []
    cl = attrs["channels"]
    i = 0
    while cl[i] != 0:
        end = cl.index(b"\0", i)
        name = cl[i:end].decode()
        ptype, _, xs, ys = struct.unpack("<iB3xii", cl[end + 1:end + 17])
        if xs != 1 or ys != 1:
            raise ImageIOError("sub-sampled EXR channels are not supported")
        channels.append((name, _EXR_TYPES[ptype]))
        i = end + 17
    compression = attrs["compression"][0]
    if compression not in _LINES_PER_BLOCK:
        raise ImageIOError(f"EXR compression {compression} is not supported (use NONE, ZIPS or ZIP)")
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    per_block = _LINES_PER_BLOCK[compression]
    blocks = (h + per_block - 1) // per_block
    offsets = np.frombuffer(data, "<u8", blocks, pos)
    line_bytes = sum(w * dt.itemsize for _, dt in channels)
    planes = {name: np.empty((h, w), np.float32) for name, _ in channels}
    for off in offsets.tolist():
        y, size = struct.unpack("<ii", data[off:off + 8])
        n = min(per_block, y1 - y + 1)
        block = data[off + 8:off + 8 + size]
        if size < n * line_bytes:
            block = _unzip_exr(block, n * line_bytes)
        for k in range(n):
            row = y - y0 + k
            p = k * line_bytes
            for name, dt in channels:
                planes[name][row] = np.frombuffer(block, dt, w, p).astype(np.float32)
                p += w * dt.itemsize
    out = np.ones((h, w, 4), np.float32)
    if "Y" in planes and "R" not in planes:
        out[..., :3] = planes["Y"][..., None]
    for c, name in enumerate("RGBA"):
        if name in planes:
            out[..., c] = planes[name]
    return out


# ---------------------------------------------------------------------------
# Comparison
# ---------------------------------------------------------------------------


@dataclass
class Comparison:
    """Result of :func:`compare` (differences over the common channels)."""

    max_abs: float
    mean_abs: float
    psnr: float
    differing: float  # share of pixels with any channel differing by more than the tolerance
    shape: tuple[int, ...]
    channels: int

    def lines(self) -> list[str]:
        psnr = "inf" if math.isinf(self.psnr) else f"{self.psnr:.2f} dB"
        return [
            f"size: {self.shape[1]}x{self.shape[0]}, {self.channels} channels",
            f"max abs diff: {self.max_abs:.6g}",
            f"mean abs diff: {self.mean_abs:.6g}",
            f"PSNR: {psnr}",
            f"differing pixels: {self.differing * 100:.4f}%",
        ]


def heat_map(diff: np.ndarray) -> np.ndarray:
    """Per-pixel difference (H, W) → RGBA heat map: black (equal) → red → yellow → white (largest)."""
    d = np.asarray(diff, np.float64)
    peak = float(d.max()) if d.size else 0.0
    t = d / peak if peak > 0 else np.zeros_like(d)
    t = np.where(d > 0, np.maximum(t, 0.1), 0.0)  # any difference is visible
    rgba = np.ones(d.shape + (4,), np.float32)
    rgba[..., 0] = np.clip(3 * t, 0, 1)
    rgba[..., 1] = np.clip(3 * t - 1, 0, 1)
    rgba[..., 2] = np.clip(3 * t - 2, 0, 1)
    return rgba


def compare(a: np.ndarray, b: np.ndarray, diff_path: str | os.PathLike | None = None,
            tolerance: float = 0.0) -> Comparison:
    """Compare two images (H, W[, C]) over their common channels.

    Returns max and mean absolute difference, PSNR (peak 1.0; ``inf`` when equal) and the
    share of pixels where some channel differs by more than ``tolerance``. ``diff_path``: also
    write a heat-map image (:func:`heat_map`) of the per-pixel largest difference.
    """
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if a.ndim == 2:
        a = a[..., None]
    if b.ndim == 2:
        b = b[..., None]
    if a.shape[:2] != b.shape[:2]:
        raise ImageIOError(f"image sizes differ: {a.shape[1]}x{a.shape[0]} vs {b.shape[1]}x{b.shape[0]}")
    c = min(a.shape[2], b.shape[2])
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf and overflow are differences too
        diff = np.abs(a[..., :c] - b[..., :c])
        diff = np.where(np.isnan(diff), np.inf, diff)
        per_pixel = diff.max(axis=2) if diff.size else np.zeros(a.shape[:2])
        max_abs = float(diff.max()) if diff.size else 0.0
        mean_abs = float(diff.mean()) if diff.size else 0.0
        mse = float((diff * diff).mean()) if diff.size else 0.0
    psnr = math.inf if mse == 0 else (10.0 * math.log10(1.0 / mse) if math.isfinite(mse) else 0.0)
    differing = float((per_pixel > tolerance).mean()) if per_pixel.size else 0.0
    if diff_path is not None:
        save(diff_path, heat_map(np.where(np.isfinite(per_pixel), per_pixel, 1.0)))
    return Comparison(max_abs, mean_abs, psnr, differing, a.shape[:2], c)
