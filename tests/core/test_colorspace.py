"""The sRGB quantisation of the Linear colour space's 8-bit writes (docs/pipeline.md §7, §8): the
stored code of a linear value is ``floor(encode(clamp01(v)) * 255 + 0.5)`` with the sRGB encoding
``1.055 v^(1/2.4) − 0.055`` (``12.92 v`` up to 0.0031308), as the scalar reference writes it."""

from __future__ import annotations

import math

import numpy as np

from blendlib.core import colorspace


def _code(v: float) -> int:
    """The scalar definition, with Python's ``**`` (C ``pow``)."""
    v = min(max(v, 0.0), 1.0)
    e = v * 12.92 if v <= 0.0031308 else 1.055 * v ** (1.0 / 2.4) - 0.055
    return math.floor(e * 255 + 0.5)


def test_quantize_encoded_equals_the_scalar_definition_at_every_code_boundary():
    """Every code threshold and the floats beside it (the module's thresholds as probe points; the
    expected codes come from the definition alone), the buckets' edges and random values in and
    beyond [0, 1]: the same codes."""
    b = colorspace.ENCODE_THRESHOLDS
    assert [_code(float(t)) for t in b] == list(range(1, 256))
    assert [_code(float(np.nextafter(t, 0.0))) for t in b] == list(range(0, 255))  # each the first of its code
    edges = np.arange(colorspace.ENCODE_BUCKETS + 1) / colorspace.ENCODE_BUCKETS
    rng = np.random.default_rng(3)
    values = np.concatenate([b, np.nextafter(b, 0.0), np.nextafter(b, 2.0), edges, np.nextafter(edges, -1.0),
                             np.nextafter(edges, 2.0), rng.uniform(-0.2, 1.2, 20000), rng.uniform(0.0, 0.004, 5000),
                             [0.0, -0.0, 1.0, 5e-324, -5e-324, 2.0, -3.0, np.inf, -np.inf]])
    got = colorspace.quantize_encoded(values)
    assert got.dtype == np.uint8
    assert got.tolist() == [_code(float(v)) for v in values]
    assert colorspace.quantize_encoded(np.array([np.nan])).tolist() == [255]  # as clamping leaves it: 1.0


def test_quantize_encoded_keeps_the_shape():
    v = np.random.default_rng(4).uniform(0, 1, (7, 5, 3))
    got = colorspace.quantize_encoded(v)
    assert got.shape == (7, 5, 3)
    assert got.reshape(-1).tolist() == [_code(float(x)) for x in v.reshape(-1)]


def test_unorm_codes_without_the_floor_store_the_same_codes():
    """``unorm_codes_in_place(floor=False)`` leaves ``v * 255 + 0.5`` for a caller that stores it
    into uint8 (the 8-bit blend): the cast's truncation must give ``floor(clamp01(v) * 255 + 0.5)``
    (docs/pipeline.md §8) at every code's half-way point, just either side of it, at 0 and 1, and
    for values the clamps hold (below 0, above 1, infinities)."""
    halves = (np.arange(256, dtype=np.float64) + 0.5) / 255.0
    values = np.concatenate([halves, np.nextafter(halves, 0.0), np.nextafter(halves, 1.0),
                             np.arange(256, dtype=np.float64) / 255.0,
                             [0.0, -0.0, 1.0, -1e-300, -3.5, 1.0000001, 7.0, np.inf, -np.inf]])
    expected = np.array([math.floor(min(max(v, 0.0), 1.0) * 255 + 0.5) for v in values.tolist()], dtype=np.uint8)
    stored = np.empty(values.size, dtype=np.uint8)
    stored[:] = colorspace.unorm_codes_in_place(values.copy(), floor=False)
    np.testing.assert_array_equal(stored, expected)
    # The blend leaves out a clamp where it knows the values lie within it: the same codes.
    inside = values[(values >= 0.0) & (values <= 1.0)]
    stored = np.empty(inside.size, dtype=np.uint8)
    stored[:] = colorspace.unorm_codes_in_place(inside.copy(), low=False, high=False, floor=False)
    np.testing.assert_array_equal(stored, expected[(values >= 0.0) & (values <= 1.0)])
