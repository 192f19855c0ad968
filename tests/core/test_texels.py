"""Compact texel storage: exactly the values of converting every texel, in far less memory."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from blendlib.core import colorspace, shade
from blendlib.core.vocabulary import ColorSpace, Texture


def converted_float64(pixels: np.ndarray, encoding: str, cs: ColorSpace) -> np.ndarray:
    """The plain definition (§7): every texel to float64, RGB converted before filtering."""
    texels = np.asarray(pixels, np.float64).copy()
    if encoding == "sRGB" and cs is ColorSpace.Linear:
        texels[..., :3] = colorspace.decode_array(texels[..., :3])
    elif encoding == "Linear" and cs is ColorSpace.Gamma:
        texels[..., :3] = colorspace.encode_array(texels[..., :3])
    return texels.reshape(-1, 4)


def byte_image(rng, h, w) -> np.ndarray:
    return rng.integers(0, 256, size=(h, w, 4)).astype(np.float32) / np.float32(255.0)


@pytest.mark.parametrize("encoding", ["sRGB", "Linear", "Data"])
@pytest.mark.parametrize("cs", [ColorSpace.Gamma, ColorSpace.Linear])
@pytest.mark.parametrize("kind", ["byte", "float", "nan", "byte-large"])
def test_fetch_gives_the_converted_float64_texels_bit_for_bit(encoding, cs, kind, monkeypatch):
    """Byte images up to Texels.PLANE_TEXELS are fetched from decoded planes, larger ones
    ("byte-large": the limit lowered below this texture) through the per-channel tables."""
    if kind == "byte-large":
        monkeypatch.setattr(shade.Texels, "PLANE_TEXELS", 100)
    rng = np.random.default_rng(7)
    h, w = 300, 37  # more rows than one conversion step
    px = byte_image(rng, h, w) if kind.startswith("byte") else rng.uniform(-0.5, 1.5, size=(h, w, 4)).astype(np.float32)
    if kind == "nan":
        px[5, 6, 1] = np.nan
        px[7, 8, 3] = np.inf
    texels = shade.texture_texels(Texture(px, encoding=encoding), cs)
    assert texels.shape == (h, w, 4)
    index = rng.integers(0, h * w, size=5000)
    got = texels.fetch(index)
    want = converted_float64(px, encoding, cs)[index]
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, want)  # NaN positions equal too
    if kind.startswith("byte"):
        assert texels.codes is not None and texels.codes.dtype == np.uint8  # one byte a channel
        assert (getattr(texels, "_decoded", None) is None) == (kind == "byte-large")


def test_byte_texture_memory_is_one_byte_a_channel():
    rng = np.random.default_rng(3)
    n = 1024
    px = byte_image(rng, n, n)
    tracemalloc.start()
    try:
        texels = shade.texture_texels(Texture(px, encoding="sRGB"), ColorSpace.Linear)
        held, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert texels.codes.nbytes == n * n * 4
    assert held < n * n * 4 + 100_000  # the codes and two 256-entry tables
    assert peak < n * n * 4 * 6  # temporaries of a few rows: less than one float64 copy (32 bytes a texel)
