"""Image files without Blender: PNG, OpenEXR, NPY, and buffer comparison.

Arrays here are ``(H, W, C)`` with row 0 the *top* of the image (as a
:class:`blendlib.core.records.Frame` and as the files store them).

- PNG (Pillow): written as 8-bit RGBA of the values (``floor(clamp(v, 0, 1) * 255 + 0.5)``,
  no colour conversion); read: every colour type (grey, grey+alpha, RGB, RGBA, palette) at
  every bit depth, interlaced or not, as the stored values / (2^depth - 1), 16-bit exactly.
  Palette transparency and tRNS colour keys give alpha; gamma and ICC chunks are ignored.
- EXR (OpenEXR bindings): written as ZIP-compressed 32-bit float RGBA (exact values); read:
  scanline or tiled, single- or multi-part, any compression (Blender's ZIP, PIZ, DWAA, ...),
  HALF/FLOAT/UINT channels. Which channels are the colour: see :func:`exr_colour_layer`.
- NPY: the exact array.

Pillow and OpenEXR are imported only here, and only when a PNG or EXR file is read or written:
``import blendlib`` and the Blender add-on work without them (they are the ``files`` extra).

Every writer goes through :func:`save` (one file) or :func:`save_all` (the files of one frame,
committed together), which write temporary files next to the targets and rename them
(:mod:`blendlib.formats.atomic`), so an error never leaves a half-written file.

Memory: writing needs little beyond the array written. ``.npy`` and a float32 (H, W, 4) ``.exr``
are written from the array itself; a ``.png`` needs its 8-bit copy (4 bytes a pixel, a quarter
of a float32 RGBA frame), converted in blocks of :data:`PNG_BLOCK_PIXELS` pixels.
"""

from __future__ import annotations

import contextlib
import ctypes
import io
import math
import os
import sys
import tempfile
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from .atomic import write_group
from .heatmap import heat_image

FORMATS = (".png", ".exr", ".npy")

#: A PNG's 8-bit values are computed this many pixels at a time (float64 temporaries of 8 MB).
PNG_BLOCK_PIXELS = 1 << 18


class ImageIOError(ValueError):
    """A file that cannot be read or written; the message is one line."""


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _library(name: str, ext: str) -> Any:
    """Import Pillow (``"PIL.Image"``) or ``"OpenEXR"`` on first use; ImageIOError naming the extra."""
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError:
        dist = "Pillow" if name.startswith("PIL") else "OpenEXR"
        raise ImageIOError(f"{ext} files need the {dist} package (pip install 'blendlib[files]')") from None


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


def encoder(path: str | os.PathLike, color: np.ndarray) -> Callable[[BinaryIO], None]:
    """A function writing ``color`` (H, W, C) into an open binary file in the format of ``path``'s
    extension (the work happens when it is called). ImageIOError for an unknown extension."""
    ext = file_format(path)
    if ext == ".npy":
        array = np.asarray(color)
        return lambda fh: np.save(fh, array, allow_pickle=False)
    if ext == ".png":
        return _png_writer(color)
    return _exr_writer(color)


def _check_folder(path: Path) -> None:
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ImageIOError(f"{path}: output directory {str(folder)!r} does not exist")


def save(path: str | os.PathLike, color: np.ndarray) -> Path:
    """Write ``color`` (H, W, C) to ``path`` by its extension, atomically (temp file + rename).

    Raises ImageIOError (unknown extension, missing folder) or OSError naming ``path``."""
    return save_all([(path, color)])[0]


def save_all(items: Sequence[tuple[str | os.PathLike, np.ndarray]],
             before_commit: Callable[[], None] | None = None) -> list[Path]:
    """Write every ``(path, array)`` as one commit (:func:`blendlib.formats.atomic.write_group`):
    all of them or, on an error or when ``before_commit()`` raises, none; an existing file is
    replaced only by its complete successor."""
    paths = [Path(p) for p, _ in items]
    writers = [encoder(p, a) for p, (_, a) in zip(paths, items, strict=True)]
    for p in paths:
        _check_folder(p)
    return write_group(list(zip(paths, writers, strict=True)), before_commit=before_commit)


def load(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG (stored values / (2^depth - 1)), EXR or NPY file as float32 (H, W, C), row 0 the top."""
    path = Path(path)
    ext = file_format(path)
    if not path.is_file():
        raise ImageIOError(f"{path}: no such file")
    try:
        if ext == ".npy":
            return _read_npy(path)
        if ext == ".png":
            return _read_png(path)
        return _read_exr(path)[0]
    except ImageIOError as exc:
        raise ImageIOError(f"{path}: {exc}") from None


def load_exr(path: str | os.PathLike) -> tuple[np.ndarray, str]:
    """Read an EXR as :func:`load` does, and say which layer was read: ``(array, layer name)``.

    The layer is ``""`` for plain R/G/B/A channels, else e.g. ``"ViewLayer.Combined"``
    (see :func:`exr_colour_layer`).
    """
    path = Path(path)
    if not path.is_file():
        raise ImageIOError(f"{path}: no such file")
    try:
        return _read_exr(path)
    except ImageIOError as exc:
        raise ImageIOError(f"{path}: {exc}") from None


def _read_npy(path: Path) -> np.ndarray:
    try:
        a = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise ImageIOError(f"not a readable .npy file ({_one_line(exc)})") from None
    if a.dtype.kind not in "biuf":
        raise ImageIOError(f"expected a numeric (bool, integer or real) array, got dtype {a.dtype}")
    if a.ndim not in (2, 3):
        raise ImageIOError(f"expected a 2-D or 3-D array, got shape {a.shape}")
    with np.errstate(over="ignore"):  # beyond float32: inf, a difference like any other
        return a.astype(np.float32, copy=False)


# ---------------------------------------------------------------------------
# PNG (Pillow)
# ---------------------------------------------------------------------------


def to_uint8(color: np.ndarray) -> np.ndarray:
    """``floor(clamp(v, 0, 1) * 255 + 0.5)`` as uint8 (NaN → 0)."""
    v = np.nan_to_num(np.asarray(color, np.float64), nan=0.0)
    return np.floor(np.clip(v, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _png_writer(color: np.ndarray) -> Callable[[BinaryIO], None]:
    """A writer of the 8-bit RGBA PNG of ``color`` (H, W, C) floats in [0, 1] (or uint8 RGBA).

    C = 3 (or 1) has alpha 255 (opaque). The 8-bit copy is made when the writer runs, block by
    block, and Pillow's image shares its memory (no second copy)."""
    a = np.asarray(color)
    image_module = _library("PIL.Image", "PNG")
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4):
        raise ImageIOError(f"expected an (H, W[, 1..4]) image array, got shape {a.shape}")

    def write(fh: BinaryIO) -> None:
        h, w = a.shape[:2]
        if a.dtype == np.uint8 and a.shape[2] == 4:
            q = np.ascontiguousarray(a)
        else:
            q = np.empty((h, w, 4), np.uint8)
            rows = max(1, PNG_BLOCK_PIXELS // max(w, 1))
            for r in range(0, h, rows):
                q[r:r + rows] = to_uint8(as_rgba(a[r:r + rows]))
        image = image_module.frombuffer("RGBA", (w, h), q, "raw", "RGBA", 0, 1)
        image.save(fh, format="PNG", compress_level=6)

    return write


# 16-bit colour PNGs: Pillow has no 16-bit multi-channel mode and keeps the high byte of each
# sample. Its PNG decoder unfilters with the bytes per pixel of the raw mode, so decoding the same
# file again with a raw mode of the same width that keeps the *other* bytes is exact:
# RGB(A);16L applied to PNG's big-endian samples keeps the low bytes, and plain RGBA (4 bytes a
# pixel, every byte kept) reads 16-bit grey+alpha as (Y hi, Y lo, A hi, A lo).
_PNG16_RAW = {"RGB;16B": ("RGB;16L", 3), "RGBA;16B": ("RGBA;16L", 4), "LA;16B": ("RGBA", 2)}
# Pillow scales 1/2/4-bit grey to 0..255 but leaves a 2/4-bit image's tRNS grey key at the file's
# bit depth (a 1-bit key it scales itself).
_PNG_LOW_DEPTH_SCALE = {"L;2": 85, "L;4": 17}


def _open_png(path: Path, image_module: Any) -> Any:
    try:
        return image_module.open(path, formats=["PNG"])
    except image_module.UnidentifiedImageError:
        with open(path, "rb") as fh:
            signed = fh.read(8) == b"\x89PNG\r\n\x1a\n"
        raise ImageIOError("corrupt PNG file (bad header chunk)" if signed else "not a PNG file") from None


def _decoded(image: Any, rawmode: str | None = None) -> np.ndarray:
    """Decode ``image`` (an opened, not yet loaded PNG), optionally with another raw mode."""
    if rawmode is not None:
        image.tile = [tile._replace(args=rawmode) for tile in image.tile]
    image.load()
    return np.asarray(image)


def _read_png(path: Path) -> np.ndarray:
    """PNG → (H, W, 4) float32 of the stored values / (2^depth - 1); alpha 1 without one."""
    image_module = _library("PIL.Image", "PNG")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", image_module.DecompressionBombWarning)
            with _open_png(path, image_module) as image:
                rawmode = image.tile[0].args if image.tile else None
                key = image.info.get("transparency")
                if rawmode in _PNG16_RAW:
                    other, channels = _PNG16_RAW[rawmode]
                    if channels == 2:  # grey+alpha: (Y hi, Y lo, A hi, A lo) in one decode
                        every = _decoded(image, other).astype(np.uint16)
                        words = (every[..., 0::2] << 8) | every[..., 1::2]
                    else:  # the high bytes as Pillow reads them, then the low bytes
                        high = _decoded(image).astype(np.uint16)
                        with _open_png(path, image_module) as again:
                            low = _decoded(again, other).astype(np.uint16)
                        words = (high[..., :channels] << 8) | low[..., :channels]
                    pix = words.astype(np.float32) / np.float32(65535.0)
                elif image.mode == "P":
                    pix = np.asarray(image.convert("RGBA")).astype(np.float32) / np.float32(255.0)
                    key = None  # the palette's alpha is in the conversion
                elif image.mode == "I;16":
                    words = np.asarray(image).astype(np.uint16)
                    pix = words.astype(np.float32) / np.float32(65535.0)
                else:
                    stored = np.asarray(image.convert("L") if image.mode == "1" else image)  # "1": bool
                    pix = stored.astype(np.float32) / np.float32(255.0)
                    words = stored.astype(np.uint16) if key is not None else None
                    if rawmode in _PNG_LOW_DEPTH_SCALE and key is not None:
                        key = int(key) * _PNG_LOW_DEPTH_SCALE[rawmode]
    except ImageIOError:
        raise
    except image_module.DecompressionBombError as exc:
        raise ImageIOError(f"PNG image too large to read ({_one_line(exc)})") from None
    except Exception as exc:  # Pillow reports corrupt files as OSError, SyntaxError, ValueError, zlib.error...
        raise ImageIOError(f"corrupt PNG file ({_one_line(exc)})") from None
    rgba = as_rgba(pix)
    if key is not None and not isinstance(key, bytes) and pix.ndim in (2, 3):
        # tRNS colour key of a grey or RGB image: that stored value is fully transparent.
        values = words if words.ndim == 3 else words[..., None]
        keys = np.atleast_1d(np.asarray(key, np.int64))
        if values.shape[2] == keys.size:
            rgba[..., 3] = np.where(np.all(values == keys, axis=2), np.float32(0), rgba[..., 3])
    return rgba


# ---------------------------------------------------------------------------
# OpenEXR (OpenEXR bindings)
# ---------------------------------------------------------------------------


def _exr_writer(color: np.ndarray) -> Callable[[BinaryIO], None]:
    """A writer of ``color`` (H, W, C) as ZIP-compressed 32-bit float RGBA OpenEXR (exact values).

    A C-contiguous float32 (H, W, 4) array is handed to OpenEXR as it is (one "RGBA" slice, no
    copy); other arrays are converted to one first."""
    exr = _library("OpenEXR", "EXR")

    def write(fh: BinaryIO) -> None:
        a = np.asarray(color)
        rgba = a if (a.dtype == np.float32 and a.ndim == 3 and a.shape[2] == 4 and a.flags.c_contiguous) \
            else as_rgba(a)
        header = {"compression": exr.ZIP_COMPRESSION, "type": exr.scanlineimage}
        exr.File(header, {"RGBA": rgba}).write(fh)

    return write


def exr_colour_layer(channel_names: list[str]) -> tuple[str, dict[str, str]]:
    """Which channels of an EXR are its colour: ``(layer, {"R"|"G"|"B"|"A"|"Y": channel name})``.

    A channel ``Layer.Pass.R`` belongs to layer ``Layer.Pass``; a plain ``R`` to the unnamed
    layer ``""``. A colour layer has R, G and B, or Y (grey); A is optional (missing alpha = 1).
    In ``channel_names`` order (the file's parts, then each part's channels), the choice is:
    the unnamed layer; else the first layer whose last name is ``Combined`` (Blender's Combined
    pass of the first view layer in a multilayer EXR, e.g. ``ViewLayer.Combined.R``); else the
    first colour layer. Channel names are case-sensitive, as in OpenEXR: a file with only
    ``r``/``g``/``b`` has no colour layer. No colour layer: ImageIOError listing the channels.
    """
    layers: dict[str, dict[str, str]] = {}
    for name in channel_names:
        layer, _, suffix = name.rpartition(".")
        if suffix in ("R", "G", "B", "A", "Y"):
            layers.setdefault(layer, {}).setdefault(suffix, name)
    colour = [layer for layer, found in layers.items() if {"R", "G", "B"} <= found.keys() or "Y" in found]
    if "" in colour:
        return "", layers[""]
    combined = [layer for layer in colour if layer.rpartition(".")[2] == "Combined"]
    for layer in combined + colour:
        return layer, layers[layer]
    shown = ", ".join(channel_names[:8]) + (f" and {len(channel_names) - 8} more" if len(channel_names) > 8 else "")
    raise ImageIOError(f"EXR has no colour channels (R, G, B or Y, as 'R' or 'Layer.Pass.R'); "
                       f"it has: {shown or 'no channels'}")


@contextlib.contextmanager
def _captured_output():
    """Collect what is printed to stdout and stderr meanwhile into a list (one string).

    The OpenEXR library reports a corrupt file by printing (the C core to the process's
    stderr, the bindings to Python's ``sys.stdout``) and returning an empty file; the caller
    turns that into one ImageIOError line. Redirects file descriptors 1 and 2 and
    ``sys.stdout``/``sys.stderr`` for the duration: not for use while other threads print.
    """
    try:
        libc = ctypes.CDLL(None)  # the C library of this process (not on Windows)
    except (OSError, TypeError):
        libc = None
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    text: list[str] = []
    python_text = io.StringIO()
    with tempfile.TemporaryFile() as sink:
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            with contextlib.redirect_stdout(python_text), contextlib.redirect_stderr(python_text):
                yield text
        finally:
            if libc is not None:
                libc.fflush(None)  # C stdio (and C++ streams synced with it) buffer when not a terminal
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            text.append(sink.read().decode("utf-8", "replace") + python_text.getvalue())


def _read_exr(path: Path) -> tuple[np.ndarray, str]:
    """EXR → ((H, W, 4) float32 R, G, B, A of :func:`exr_colour_layer`'s layer, layer name).

    Y (grey) fills R, G and B when the layer has no R; missing alpha is 1.
    """
    exr = _library("OpenEXR", "EXR")
    with _captured_output() as printed:
        try:
            file = exr.File(os.fspath(path), separate_channels=True)
            parts = list(file.parts)
            channels = {name: channel for part in parts for name, channel in part.channels.items()}
            deep = [part for part in parts if part.type() in (exr.deepscanline, exr.deeptile)]
        except Exception as exc:  # the bindings raise RuntimeError/ValueError/TypeError on bad headers
            reason = _one_line(exc).replace(f" '{os.fspath(path)}'", "")
            raise ImageIOError(f"not a readable OpenEXR file ({reason})") from None
    if not parts:  # the bindings print why the pixels did not read and return no parts
        reason = next((line for line in printed[0].splitlines() if line.strip()), "no image parts")
        reason = reason.removeprefix(f"{os.fspath(path)}: ")
        raise ImageIOError(f"corrupt or truncated OpenEXR file ({' '.join(reason.split())})")
    if deep:
        raise ImageIOError("deep OpenEXR images are not supported")
    layer, found = exr_colour_layer(list(channels))
    used = [channels[name] for name in found.values()]
    if any(ch.xSampling != 1 or ch.ySampling != 1 for ch in used):
        raise ImageIOError(f"sub-sampled EXR channels are not supported (layer {layer or '(unnamed)'})")
    shapes = {np.shape(ch.pixels) for ch in used}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ImageIOError(f"EXR channels of layer {layer or '(unnamed)'} differ in size: {sorted(shapes)}")
    h, w = next(iter(shapes))
    out = np.ones((h, w, 4), np.float32)
    if "Y" in found and "R" not in found:
        out[..., :3] = np.asarray(channels[found["Y"]].pixels, np.float32)[..., None]
    for c, suffix in enumerate("RGBA"):
        if suffix in found:
            out[..., c] = np.asarray(channels[found[suffix]].pixels, np.float32)
    return out, layer


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
    #: (H, W) float64: per pixel the largest channel difference (inf where one value is NaN).
    per_pixel: np.ndarray | None = field(default=None, repr=False)

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
    """Per-pixel difference (H, W) → RGBA heat map, black (equal) → red → yellow → white (largest,
    or not finite), with its legend below: (H + legend, W, 4) float32."""
    d = np.asarray(diff, np.float64)
    finite = d[np.isfinite(d)]
    peak = float(finite.max()) if finite.size else 0.0
    # any difference is visible (floor); a NaN/inf difference shows as the largest
    return heat_image(np.where(np.isfinite(d), d, peak), "largest channel difference", peak=peak, floor=0.1)


def compare(a: np.ndarray, b: np.ndarray, diff_path: str | os.PathLike | None = None,
            tolerance: float = 0.0) -> Comparison:
    """Compare two images (H, W[, C]) over their common channels.

    Returns max and mean absolute difference, PSNR (peak 1.0; ``inf`` when equal), the share of
    pixels where some channel differs by more than ``tolerance`` and the per-pixel largest
    difference. ``diff_path``: also write its heat map (:func:`heat_map`).
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
        save(diff_path, heat_map(per_pixel))
    return Comparison(max_abs, mean_abs, psnr, differing, a.shape[:2], c, per_pixel)
