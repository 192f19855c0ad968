"""blendlib.formats.images: PNG/EXR/NPY round trips, files written by Blender, compare, atomic writes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from blendlib.formats import images


def test_png_round_trip_and_quantisation(tmp_path):
    rng = np.random.default_rng(3)
    q = rng.integers(0, 256, (9, 13, 4))
    images.save(tmp_path / "a.png", (q / 255).astype(np.float32))
    np.testing.assert_array_equal(images.load(tmp_path / "a.png"), (q / 255).astype(np.float32))
    images.save(tmp_path / "b.png", np.array([[[0.5, -1.0, 2.0, np.nan]]], np.float32))
    assert (images.load(tmp_path / "b.png") * 255).round().tolist() == [[[128, 0, 255, 0]]]
    images.save(tmp_path / "rgb.png", np.full((2, 3, 3), 0.2, np.float32))
    got = images.load(tmp_path / "rgb.png")
    assert got.shape == (2, 3, 4) and (got[..., 3] == 1).all()


def test_png_written_by_blender_with_all_filters(tmp_path):
    import bpy

    from tests.support.blender_fixtures import empty_scene

    scene = empty_scene()
    img = bpy.data.images.new("W", 64, 48, alpha=True)
    yy, xx = np.mgrid[0:48, 0:64]
    v = np.stack([xx / 63, yy / 47, (xx * yy % 256) / 255, (xx + yy) % 7 / 6], -1).astype(np.float32)
    img.pixels.foreach_set(v.ravel())
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    img.save_render(str(tmp_path / "b.png"), scene=scene)
    got = images.load(tmp_path / "b.png")[::-1]  # Blender's row 0 is the bottom
    np.testing.assert_array_equal(got, (np.floor(v * 255 + 0.5) / 255).astype(np.float32))


def test_exr_round_trip_is_exact_and_blender_reads_it(tmp_path):
    rng = np.random.default_rng(4)
    a = rng.normal(scale=3, size=(5, 7, 4)).astype(np.float32)
    a[0, 0, 0] = np.inf
    images.save(tmp_path / "a.exr", a)
    np.testing.assert_array_equal(images.load(tmp_path / "a.exr"), a)
    import bpy
    img = bpy.data.images.load(str(tmp_path / "a.exr"))
    px = np.empty(5 * 7 * 4, np.float32)
    img.pixels.foreach_get(px)
    np.testing.assert_array_equal(px.reshape(5, 7, 4)[::-1][1:], a[1:])


def test_npy_and_errors(tmp_path):
    a = np.arange(24, dtype=np.float32).reshape(2, 3, 4)
    images.save(tmp_path / "a.npy", a)
    np.testing.assert_array_equal(images.load(tmp_path / "a.npy"), a)
    with pytest.raises(images.ImageIOError, match="unsupported image type"):
        images.save(tmp_path / "a.tif", a)
    with pytest.raises(images.ImageIOError, match="does not exist"):
        images.save(tmp_path / "no" / "a.png", a)
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(images.ImageIOError, match="not a PNG"):
        images.load(tmp_path / "bad.png")


def test_failed_write_leaves_previous_file_and_no_temp(tmp_path):
    target = tmp_path / "keep.png"
    images.save(target, np.zeros((2, 2, 4), np.float32))
    before = target.read_bytes()
    with pytest.raises(images.ImageIOError):
        images.save(target, np.zeros((2, 2, 7), np.float32))
    assert target.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["keep.png"]


def test_compare_numbers_and_heat_map(tmp_path):
    a = np.zeros((10, 10, 4), np.float32)
    b = a.copy()
    b[2, 3, 1] = 0.25
    b[7, 7, 0] = 1.0
    r = images.compare(a, b, diff_path=tmp_path / "h.png")
    assert r.max_abs == 1.0 and r.differing == pytest.approx(0.02)
    assert r.mean_abs == pytest.approx(1.25 / 400)
    assert r.psnr == pytest.approx(10 * math.log10(400 / (1 + 0.0625)))
    heat = images.load(tmp_path / "h.png")
    assert heat[7, 7, :3].tolist() == [1, 1, 1] and heat[0, 0, :3].tolist() == [0, 0, 0]
    assert 0 < heat[2, 3, 0] < 1  # smaller difference: red, not white
    same = images.compare(a, a)
    assert same.max_abs == 0 and math.isinf(same.psnr) and same.differing == 0
    assert images.compare(a, b, tolerance=0.5).differing == pytest.approx(0.01)
    with pytest.raises(images.ImageIOError, match="sizes differ"):
        images.compare(a, a[:5])


def _filter_rows(raw: np.ndarray, kinds: list[int], bpp: int) -> bytes:
    """PNG-filter each row of ``raw`` (H, W*bpp) uint8 with the given types, one byte at a time."""
    out = bytearray()
    prev = [0] * raw.shape[1]
    for row, kind in zip(raw.tolist(), kinds, strict=True):
        out.append(kind)
        for i, x in enumerate(row):
            a = row[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if kind == 0:
                pred = 0
            elif kind == 1:
                pred = a
            elif kind == 2:
                pred = b
            elif kind == 3:
                pred = (a + b) >> 1
            else:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            out.append((x - pred) & 0xFF)
        prev = row
    return bytes(out)


def _png(w: int, h: int, depth: int, ctype: int, body: bytes) -> bytes:
    import struct
    import zlib

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, depth, ctype, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(body)) + chunk(b"IEND", b"")


@pytest.mark.parametrize("depth,ctype,channels", [(8, 6, 4), (8, 2, 3), (16, 6, 4), (8, 0, 1)])
def test_png_every_filter_type_mixed_per_row(depth, ctype, channels):
    """Rows filtered None/Sub/Up/Average/Paeth in a random mix decode to the original bytes."""
    rng = np.random.default_rng(depth * 10 + ctype)
    w, h = 37, 23
    bpp = channels * depth // 8
    raw = rng.integers(0, 256, size=(h, w * bpp), dtype=np.uint8)
    kinds = rng.integers(0, 5, size=h).tolist()
    decoded = images.decode_png(_png(w, h, depth, ctype, _filter_rows(raw, kinds, bpp)))
    if depth == 16:
        words = raw.reshape(h, w * channels, 2).astype(np.uint32)
        expected = ((words[..., 0] << 8) | words[..., 1]).reshape(h, w, channels) / 65535.0
    else:
        expected = raw.reshape(h, w, channels) / 255.0
    got = decoded[..., :channels] if channels > 1 else decoded[..., :1]
    np.testing.assert_allclose(got, expected.astype(np.float32), rtol=0, atol=1e-7)
