"""blendlib.formats.images: PNG/EXR/NPY round trips, files written by Blender, compare, atomic writes."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

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


def _png(w: int, h: int, depth: int, ctype: int, body: bytes, interlace: int = 0, plte: bytes = b"",
         trns: bytes = b"") -> bytes:
    """A PNG file byte by byte (the reader under test must not write its own test files)."""
    import struct
    import zlib

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, depth, ctype, 0, 0, interlace)
    extra = (chunk(b"PLTE", plte) if plte else b"") + (chunk(b"tRNS", trns) if trns else b"")
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + extra + chunk(b"IDAT", zlib.compress(body))
            + chunk(b"IEND", b""))


@pytest.mark.parametrize("depth,ctype,channels", [(8, 6, 4), (8, 2, 3), (16, 6, 4), (16, 2, 3), (16, 4, 2),
                                                   (8, 4, 2), (8, 0, 1), (16, 0, 1)])
@pytest.mark.parametrize("interlace", [0, 1])
def test_png_every_colour_type_and_filter_type_mixed_per_row(tmp_path, depth, ctype, channels, interlace):
    """Rows filtered None/Sub/Up/Average/Paeth in a random mix read back as the stored samples / (2^depth - 1)."""
    rng = np.random.default_rng(depth * 10 + ctype)
    w, h = 37, 23
    bpp = channels * depth // 8
    raw = rng.integers(0, 256, size=(h, w * bpp), dtype=np.uint8)
    if depth == 16:
        words = raw.reshape(h, w * channels, 2).astype(np.uint32)
        samples = ((words[..., 0] << 8) | words[..., 1]).reshape(h, w, channels)
    else:
        samples = raw.reshape(h, w, channels)
    if interlace:
        body = b"".join(_filter_rows(np.ascontiguousarray(sub), rng.integers(0, 5, size=len(sub)).tolist(), bpp)
                        for sub in _adam7_passes(raw, bpp))
    else:
        body = _filter_rows(raw, rng.integers(0, 5, size=h).tolist(), bpp)
    (tmp_path / "f.png").write_bytes(_png(w, h, depth, ctype, body, interlace))
    got = images.load(tmp_path / "f.png")
    expected = images.as_rgba((samples / (2.0 ** depth - 1)).astype(np.float32))
    assert got.shape == (h, w, 4) and got.dtype == np.float32
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-7)
    if depth == 16:  # the low byte matters: an 8-bit reading would be off by up to 255/65535
        assert np.abs(got - np.floor(got * 255) / 255).max() > 1e-3


def _adam7_passes(raw: np.ndarray, bpp: int) -> list[np.ndarray]:
    """The seven Adam7 sub-images of ``raw`` (H, W*bpp) bytes, empty ones left out."""
    h = raw.shape[0]
    pixels = raw.reshape(h, -1, bpp)
    starts = [(0, 0, 8, 8), (0, 4, 8, 8), (4, 0, 8, 4), (0, 2, 4, 4), (2, 0, 4, 2), (0, 1, 2, 2), (1, 0, 2, 1)]
    subs = [pixels[y0::dy, x0::dx] for y0, x0, dy, dx in starts]
    return [sub.reshape(sub.shape[0], -1) for sub in subs if sub.size]


@pytest.mark.parametrize("depth,scale", [(1, 255), (2, 85), (4, 17)])
def test_png_low_bit_depth_grey_palette_and_colour_keys(tmp_path, depth, scale):
    """1/2/4-bit grey reads as value / (2^depth - 1); tRNS makes the keyed grey, RGB or palette entry transparent."""
    rng = np.random.default_rng(depth)
    w, h = 11, 5
    values = rng.integers(0, 2 ** depth, size=(h, w))
    values[0, 0] = 1
    per_byte = 8 // depth
    padded = np.zeros((h, -(-w // per_byte) * per_byte), np.int64)
    padded[:, :w] = values
    packed = (padded.reshape(h, -1, per_byte) << (8 - depth * (np.arange(per_byte) + 1))).sum(axis=2)
    body = _filter_rows(packed.astype(np.uint8), [0] * h, 1)
    (tmp_path / "g.png").write_bytes(_png(w, h, depth, 0, body, trns=b"\0\1"))
    got = images.load(tmp_path / "g.png")
    np.testing.assert_array_equal(got[..., 0], (values * scale).astype(np.float32) / np.float32(255))
    np.testing.assert_array_equal(got[..., 3], np.where(values == 1, 0, 1).astype(np.float32))

    rgb = rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8)
    rgb[1, 2] = (10, 20, 30)
    (tmp_path / "k.png").write_bytes(_png(w, h, 8, 2, _filter_rows(rgb.reshape(h, -1), [0] * h, 3),
                                          trns=bytes([0, 10, 0, 20, 0, 30])))
    keyed = np.all(rgb == (10, 20, 30), axis=2)
    np.testing.assert_array_equal(images.load(tmp_path / "k.png")[..., 3], np.where(keyed, 0, 1).astype(np.float32))

    palette = rng.integers(0, 256, size=(4, 3), dtype=np.uint8)
    index = rng.integers(0, 4, size=(h, w), dtype=np.uint8)
    (tmp_path / "p.png").write_bytes(_png(w, h, 8, 3, _filter_rows(index, [0] * h, 1),
                                          plte=palette.tobytes(), trns=bytes([255, 0, 128])))
    got = images.load(tmp_path / "p.png")
    np.testing.assert_array_equal(got[..., :3], palette[index].astype(np.float32) / np.float32(255))
    alpha = np.array([255, 0, 128, 255], np.float32)[index] / np.float32(255)
    np.testing.assert_array_equal(got[..., 3], alpha)


def test_png_corrupt_or_other_format_is_one_line_error(tmp_path):
    noise = np.random.default_rng(0).integers(0, 256, size=(16, 64), dtype=np.uint8)
    good = _png(16, 16, 8, 6, _filter_rows(noise, [0] * 16, 4))
    cases = {"truncated.png": good[:len(good) // 2], "jpeg.png": b"\xff\xd8\xff\xe0" + bytes(100),
             "badcrc.png": good[:29] + b"\0" + good[30:], "empty.png": b""}
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(images.ImageIOError) as info:
            images.load(tmp_path / name)
        message = str(info.value)
        assert message.startswith(str(tmp_path / name) + ": ") and "\n" not in message, message
        assert ("not a PNG" if name in ("jpeg.png", "empty.png") else "corrupt PNG") in message, message


# ---------------------------------------------------------------------------
# EXR files written by Blender, Blender's multilayer channel names, corrupt files
# ---------------------------------------------------------------------------

# Lossless codecs read back bit for bit. PXR24 rounds 32-bit floats to 24 bits (relative error
# <= 2^-16, the 15 kept mantissa bits). DWAA/DWAB are lossy by design: they quantise R, G and B
# (and Y) in a DCT of 8x8 blocks in a perceptual (log-like) space, so the error grows with the
# value; alpha and other channels are stored losslessly.
BLENDER_EXR_CODECS = ["NONE", "ZIP", "ZIPS", "PIZ", "RLE", "PXR24", "DWAA", "DWAB"]


def test_exr_written_by_blender_with_every_codec(tmp_path):
    import bpy

    from tests.support.blender_fixtures import empty_scene

    scene = empty_scene()
    w, h = 64, 48
    yy, xx = np.mgrid[0:h, 0:w]
    smooth = 0.5 + 0.5 * np.sin(xx / 5.0) * np.cos(yy / 7.0)
    v = (np.stack([xx / (w - 1), yy / (h - 1), smooth, (xx + yy) % 5 / 4], -1) * 3 - 0.5).astype(np.float32)
    img = bpy.data.images.new("W", w, h, alpha=True, float_buffer=True)
    img.pixels.foreach_set(v.ravel())
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    for codec in BLENDER_EXR_CODECS:
        for depth in ("16", "32"):
            settings.exr_codec = codec
            settings.color_depth = depth
            path = tmp_path / f"{codec}_{depth}.exr"
            img.save_render(str(path), scene=scene)
            got = images.load(path)[::-1]  # Blender's row 0 is the bottom
            stored = v if depth == "32" else v.astype(np.float16).astype(np.float32)
            np.testing.assert_array_equal(got[..., 3], stored[..., 3])  # alpha: lossless in every codec
            error = np.abs(got[..., :3] - stored[..., :3])
            if codec in ("DWAA", "DWAB"):
                assert 0 < error.max() <= 0.02 * np.abs(stored[..., :3]).max(), (codec, depth, error.max())
                assert error.mean() < 0.005, (codec, depth, error.mean())
            elif codec == "PXR24" and depth == "32":
                assert (error <= np.abs(stored[..., :3]) * 2.0 ** -15).all()
            else:
                assert error.max() == 0, (codec, depth)


def _render_exr(path, color, *, multilayer: bool, codec: str = "PIZ", interleave: bool = False):
    """Render a plane of ``color`` with the add-on's engine into ``path`` as Blender writes EXRs."""
    import bpy

    from tests.support.blender_fixtures import add_plane, empty_scene, unlit_material

    scene = empty_scene(16, 8)
    add_plane("P", 3.0, material=unlit_material("M", color))
    scene.render.engine = "UNITY_PASSES"
    settings = scene.render.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE" if multilayer else "IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER" if multilayer else "OPEN_EXR"
    settings.exr_codec = codec
    settings.color_depth = "32"
    if multilayer:
        settings.use_exr_interleave = interleave
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return path


def test_blender_multilayer_exr_reads_the_combined_pass(tmp_path):
    """Blender's multilayer EXR names channels ViewLayer.Combined.R etc. (and writes Depth and
    UnityAlpha passes too): the reader takes the Combined pass, so different renders differ."""
    import OpenEXR

    import addon

    addon.register()
    try:
        plain = images.load(_render_exr(tmp_path / "plain.exr", (0.9, 0.2, 0.1, 0.5), multilayer=False))
        red = _render_exr(tmp_path / "red.exr", (0.9, 0.2, 0.1, 0.5), multilayer=True)
        green = _render_exr(tmp_path / "green.exr", (0.1, 0.8, 0.1, 1.0), multilayer=True)
        one_part = _render_exr(tmp_path / "one_part.exr", (0.9, 0.2, 0.1, 0.5), multilayer=True, interleave=True)
    finally:
        addon.unregister()
    names = [n for part in OpenEXR.File(str(red), separate_channels=True).parts for n in part.channels]
    assert "ViewLayer.Combined.R" in names and "ViewLayer.Depth.Z" in names and "R" not in names
    assert not (plain[..., :3] == 1).all() and plain.shape == (8, 16, 4)
    for path in (red, one_part):
        got, layer = images.load_exr(path)
        assert layer == "ViewLayer.Combined"
        np.testing.assert_array_equal(got, plain)
    assert images.compare(images.load(red), images.load(green)).max_abs > 0.5
    from tests.support.blender_fixtures import run_cli

    cli = run_cli("compare", str(red), str(green))
    assert cli.returncode == 0 and "PSNR: inf" not in cli.stdout and "max abs diff: 0\n" not in cli.stdout, cli
    assert run_cli("compare", str(red), str(one_part)).stdout.splitlines()[1] == "max abs diff: 0"


def test_exr_channel_naming_picks_combined_or_refuses(tmp_path):
    import OpenEXR

    pick = images.exr_colour_layer
    assert pick(["A", "B", "G", "R", "Z"]) == ("", {"A": "A", "B": "B", "G": "G", "R": "R"})
    assert pick(["Y"]) == ("", {"Y": "Y"})
    assert pick(["View.Depth.Z", "View.Combined.A", "View.Combined.B", "View.Combined.G", "View.Combined.R"])[0] \
        == "View.Combined"
    # the first Combined layer wins over an earlier colour layer and over later view layers
    names = [f"{layer}.{c}" for layer in ("V.Normal", "V.Combined", "W.Combined") for c in "RGB"]
    assert pick(names)[0] == "V.Combined"
    assert pick(["V.Normal.R", "V.Normal.G", "V.Normal.B", "V.UnityAlpha.A"])[0] == "V.Normal"

    a = np.random.default_rng(5).random((4, 6)).astype(np.float32)
    for name, channels in {"lower": "rgba", "alpha_only": ["View.UnityAlpha.A"], "depth": ["View.Depth.Z"]}.items():
        path = tmp_path / f"{name}.exr"
        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        OpenEXR.File(header, {c: a + i for i, c in enumerate(channels)}).write(str(path))
        with pytest.raises(images.ImageIOError, match="no colour channels") as info:
            images.load(path)
        assert str(info.value).startswith(f"{path}: ") and "\n" not in str(info.value)
        assert channels[0] in str(info.value)  # the message lists what the file has
    from tests.support.blender_fixtures import run_cli

    cli = run_cli("compare", str(tmp_path / "lower.exr"), str(tmp_path / "depth.exr"))
    assert cli.returncode == 1 and cli.stdout == ""
    assert cli.stderr.splitlines() == [f"error: {tmp_path / 'lower.exr'}: EXR has no colour channels (R, G, B or Y, "
                                       "as 'R' or 'Layer.Pass.R'); it has: a, b, g, r"]


def test_corrupt_exr_is_one_line_error_and_prints_nothing(tmp_path, capfd):
    images.save(tmp_path / "good.exr", np.random.default_rng(6).random((6, 5, 4)).astype(np.float32))
    good = (tmp_path / "good.exr").read_bytes()
    assert b"channels\0chlist\0" in good and b"dataWindow\0box2i\0" in good
    cases = {
        "magic_only": good[:4],
        "header_cut": good[:60],
        "pixels_cut": good[: len(good) - 40],
        "no_channels": good.replace(b"channels\0chlist\0", b"chXnnels\0chlist\0"),
        "no_data_window": good.replace(b"dataWindow\0", b"dataWindoX\0"),
        "huge_data_window": good.replace(b"dataWindow\0box2i\0\x10\0\0\0", b"dataWindow\0box2i\0\x10\0\0\0\0\0\0\x80"),
        "zeros": good[:8] + bytes(len(good) - 8),
        "png": b"\x89PNG\r\n\x1a\n" + bytes(64),
    }
    capfd.readouterr()
    for name, data in cases.items():
        path = tmp_path / f"{name}.exr"
        path.write_bytes(data)
        with pytest.raises(images.ImageIOError) as info:
            images.load(path)
        message = str(info.value)
        assert message.startswith(f"{path}: ") and "\n" not in message, (name, message)
        assert "OpenEXR file" in message or "no colour channels" in message, (name, message)
    assert capfd.readouterr() == ("", "")  # the library's own error printing is captured


def test_npy_of_strings_complex_or_objects_is_one_line_error(tmp_path, recwarn):
    arrays = {"str": np.array([["a", "b"], ["c", "d"]]), "complex": np.ones((2, 2), np.complex64),
              "datetime": np.zeros((2, 2), "datetime64[s]")}
    for name, array in arrays.items():
        np.save(tmp_path / f"{name}.npy", array)
    np.save(tmp_path / "object.npy", np.array([[None, 1]], dtype=object), allow_pickle=True)
    for name in [*arrays, "object"]:
        path = tmp_path / f"{name}.npy"
        with pytest.raises(images.ImageIOError) as info:
            images.load(path)
        assert str(info.value).startswith(f"{path}: ") and "\n" not in str(info.value)
    assert not [w for w in recwarn.list if issubclass(w.category, np.ComplexWarning)]
    np.save(tmp_path / "bool.npy", np.array([[True, False]]))
    assert images.load(tmp_path / "bool.npy").tolist() == [[1.0, 0.0]]


MEMORY = r"""
import sys
import numpy as np
import PIL.Image, PIL.PngImagePlugin, OpenEXR  # noqa: F401 - imported before the measurement
from blendlib.formats import images

def peak():
    return next(int(x.split()[1]) * 1024 for x in open("/proc/self/status") if x.startswith("VmHWM"))

out = sys.argv[1]
color = np.random.default_rng(1).random((2000, 2000, 4), dtype=np.float32)
images.save(out + ".warm" + out[-4:], color[:8, :8])  # the writer's own first-use costs
with open("/proc/self/clear_refs", "w") as fh:
    fh.write("5")  # the peak from here on (Linux)
before = peak()
images.save(out, color)
print(peak() - before, color.nbytes)
"""


@pytest.mark.skipif(not os.path.exists("/proc/self/clear_refs"), reason="peak memory needs Linux's /proc")
@pytest.mark.parametrize("ext, bound", [(".png", 0.25), (".exr", 0.0), (".npy", 0.0)])
def test_writing_needs_little_memory_beyond_the_array(tmp_path, ext, bound):
    """Peak memory of writing a 2000x2000 RGBA float32 frame (61 MB), measured in a fresh process:
    a PNG needs its 8-bit copy (a quarter of the array) plus blocks of a few MB; .exr and .npy
    nothing of the array's size. Before, a PNG needed 7x the array (float64 copies of the whole
    frame: 5000x5000 took 3.7 GB where .npy took 1.4 GB) and an EXR 2x."""
    out = tmp_path / f"frame{ext}"
    proc = subprocess.run([sys.executable, "-c", MEMORY, str(out)], capture_output=True, text=True, timeout=300,
                          cwd=Path(__file__).resolve().parents[2])
    assert proc.returncode == 0, proc.stderr
    extra, size = (int(v) for v in proc.stdout.split())
    assert extra <= bound * size + (48 << 20), f"{ext}: {extra / 2**20:.0f} MB beyond the {size / 2**20:.0f} MB array"
    assert images.load(out).shape == (2000, 2000, 4)
