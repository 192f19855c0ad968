"""sRGB transfer functions, exact to the bit (docs/pipeline.md §7).

The scalar definitions use Python's float ``**`` (C ``pow``). numpy's vectorised
``np.power`` differs from C ``pow`` in the last bit for about a quarter of inputs on
AVX-512 machines (it uses SVML), so array versions here never call it on exact
paths:

- :data:`DECODE_LUT`: ``decode(q / 255)`` for the 256 8-bit codes;
- :func:`quantize_encoded`: ``floor(encode(v) * 255 + 0.5)`` through 255 exact
  thresholds (the function is monotone in ``v``, so a code is the number of
  thresholds at or below ``v``);
- :func:`encode_array` / :func:`decode_array`: ``**`` once per distinct value.
"""

from __future__ import annotations

import numpy as np

_INV_GAMMA = 1.0 / 2.4


def encode(x: float) -> float:
    """Linear → sRGB-encoded (scalar, any float)."""
    if x <= 0.0031308:
        return x * 12.92
    return 1.055 * x**_INV_GAMMA - 0.055


def decode(x: float) -> float:
    """sRGB-encoded → linear (scalar, any float)."""
    if x <= 0.04045:
        return x / 12.92
    return ((x + 0.055) / 1.055) ** 2.4


def _per_unique(values: np.ndarray, fn) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return values.copy()
    unique, inverse = np.unique(values, return_inverse=True)
    mapped = np.array([fn(float(u)) for u in unique], dtype=np.float64)
    return mapped[inverse].reshape(values.shape)


def encode_array(values: np.ndarray) -> np.ndarray:
    """:func:`encode` elementwise, bit-exact; float64 out. Costs one ``**`` per distinct value."""
    return _per_unique(values, encode)


def decode_array(values: np.ndarray) -> np.ndarray:
    """:func:`decode` elementwise, bit-exact; float64 out. Costs one ``**`` per distinct value."""
    return _per_unique(values, decode)


#: ``decode(q / 255.0)`` for q = 0..255, float64.
DECODE_LUT = np.array([decode(q / 255.0) for q in range(256)], dtype=np.float64)


def _code_of_linear(v: float) -> int:
    """The 8-bit sRGB code of a linear value in [0, 1]: ``floor(encode(v)*255 + 0.5)``."""
    import math

    return int(math.floor(encode(v) * 255.0 + 0.5))


def _first_float_with_code(k: int) -> float:
    """Smallest float64 v in [0, 1] with ``_code_of_linear(v) >= k`` (bisection on the bit patterns)."""
    lo = 0  # bit pattern of 0.0: its code is 0 < k
    hi = int(np.float64(1.0).view(np.int64))  # code 255 >= k
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _code_of_linear(float(np.int64(mid).view(np.float64))) >= k:
            hi = mid
        else:
            lo = mid
    return float(np.int64(hi).view(np.float64))


#: ENCODE_THRESHOLDS[k-1] = the smallest linear value whose code is >= k (k = 1..255).
ENCODE_THRESHOLDS = np.array([_first_float_with_code(k) for k in range(1, 256)], dtype=np.float64)


#: Buckets of [0, 1] for :func:`quantize_encoded`: narrower than the closest two thresholds
#: (1/(255 * 12.92) apart, on the linear segment near 0), so each holds at most one.
ENCODE_BUCKETS = 4096
_EDGES = np.arange(ENCODE_BUCKETS + 1, dtype=np.float64) / ENCODE_BUCKETS
#: Per bucket ``[b/B, (b+1)/B)`` (and ``b = B`` for 1.0): the code at its lower edge (the
#: thresholds at or below it), and the next threshold (infinite after the last).
_BUCKET_CODE = np.searchsorted(ENCODE_THRESHOLDS, _EDGES, side="right").astype(np.uint8)
_BUCKET_NEXT = np.append(ENCODE_THRESHOLDS, np.inf)[_BUCKET_CODE.astype(np.int64)]
assert (np.searchsorted(ENCODE_THRESHOLDS, _EDGES[1:], side="left")
        - _BUCKET_CODE[:-1].astype(np.int64) <= 1).all(), "a bucket holds two thresholds"


def quantize_encoded(linear: np.ndarray) -> np.ndarray:
    """Clamp linear values to [0, 1], encode to sRGB and quantise to 8-bit codes (uint8), bit-exact:
    the number of :data:`ENCODE_THRESHOLDS` at or below the value (a NaN counts as 1.0, code 255).
    The value's bucket (``v * 4096``: exact, a power of two) gives the count at its lower edge,
    and one comparison adds the one threshold a bucket may hold above that edge."""
    v = np.asarray(linear, dtype=np.float64)
    v = np.fmax(np.fmin(v, 1.0), 0.0)  # fmin takes 1.0 over a NaN
    bucket = np.multiply(v, float(ENCODE_BUCKETS)).astype(np.intp)  # v >= 0: truncation is the floor
    code = _BUCKET_CODE.take(bucket)
    code += np.greater_equal(v, _BUCKET_NEXT.take(bucket))
    return code


def decode_fast(values: np.ndarray) -> np.ndarray:
    """:func:`decode` vectorised with ``np.power``: within an ulp, not bit-exact (for display output)."""
    x = np.asarray(values, dtype=np.float64)
    return np.where(x <= 0.04045, x / 12.92, ((np.maximum(x, 0.04045) + 0.055) / 1.055) ** 2.4)


def quantize_unorm(values: np.ndarray) -> np.ndarray:
    """Clamp to [0, 1] and quantise to 8-bit codes: ``floor(v*255 + 0.5)`` (uint8)."""
    # A copy, 0-d for a scalar: operated on in place.
    return unorm_codes_in_place(np.array(values, dtype=np.float64)).astype(np.uint8)


def unorm_codes_in_place(v: np.ndarray, low: bool = True, high: bool = True, floor: bool = True) -> np.ndarray:
    """:func:`quantize_unorm`'s codes as float64 values, computed in ``v`` (float64, overwritten),
    for a caller that owns ``v`` and stores the codes itself. ``low=False`` / ``high=False``: the
    caller knows no value is below 0 / above 1 (a NaN stays NaN either way), so that clamp is left out.
    ``floor=False``: ``v * 255 + 0.5`` without the floor, for a caller that stores the values
    into an unsigned integer array: the values lie in [0.5, 255.5] (or are NaN), where the
    cast's truncation toward zero is the floor, so the stored codes are the same."""
    if low:
        np.maximum(v, 0.0, out=v)
    if high:
        np.minimum(v, 1.0, out=v)
    v *= 255.0
    v += 0.5
    return np.floor(v, out=v) if floor else v
