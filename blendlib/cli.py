"""Command line: ``python -m blendlib render|compare|shaderlab ...``.

Errors are one line on stderr (``error: ...``) with a non-zero exit status:
1 for bad input or a failed render, 2 for bad usage (argparse), 130 when
interrupted. Warnings go to stderr as ``warning: ...``. Outputs are written to a
temporary file and renamed, so a failed or cancelled run writes nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import sys
from pathlib import Path

from . import imageio

EPILOG_RENDER = """\
examples:
  python -m blendlib render scene.blend -o out.png
  python -m blendlib render scene.blend -o frame.npy --depth depth.npy --frame 12 --scene Scene.001

OUT ends in .png (8-bit RGBA of the stored frame values: sRGB-encoded in Gamma mode and in
Linear LDR, exactly what Unity's colour buffer holds), .exr (32-bit float RGBA, exact values)
or .npy (the exact float32 (H, W, 4) array, row 0 = top). The Unity settings come from the
file (Material.unity, Scene.unity); the Unity Passes add-on need not be installed.
"""

EPILOG_COMPARE = """\
prints max and mean absolute difference, PSNR (peak 1.0) and the share of differing pixels;
exit status 0 either way (1 only when a file cannot be read or the sizes differ).
example:
  python -m blendlib compare out.png golden.png --diff diff.png
"""


class CliError(Exception):
    """A one-line error for the user."""


def _warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


@contextlib.contextmanager
def _redirect_fds(target: int | None):
    """Blender prints file-loading chatter on stdout/stderr at the C level. ``target`` None: silence
    both (errors come back as exceptions); else send stdout to that fd (keep stdout for results)."""
    sys.stdout.flush()
    sys.stderr.flush()
    fds = (1, 2) if target is None else (1,)
    try:
        saved = [os.dup(fd) for fd in fds]
    except OSError:
        yield
        return
    sink = os.open(os.devnull, os.O_WRONLY) if target is None else target
    try:
        for fd in fds:
            os.dup2(sink, fd)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        for fd, old in zip(fds, saved, strict=True):
            os.dup2(old, fd)
            os.close(old)
        if target is None:
            os.close(sink)


def _check_blend(path: Path) -> None:
    if not path.exists():
        raise CliError(f"{path}: no such file")
    if not path.is_file():
        raise CliError(f"{path}: not a file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(7)
    except OSError as exc:
        raise CliError(f"{path}: cannot read ({exc.strerror})") from None
    # Plain, gzip- or zstd-compressed .blend files.
    if not (head.startswith(b"BLENDER") or head.startswith(b"\x1f\x8b") or head.startswith(b"\x28\xb5\x2f\xfd")):
        raise CliError(f"{path}: not a .blend file")


def _check_output(path: Path, option: str) -> None:
    try:
        imageio.file_format(path) if option == "-o" else None
    except imageio.ImageIOError as exc:
        raise CliError(str(exc)) from None
    if option != "-o" and path.suffix.lower() != ".npy":
        raise CliError(f"{path}: {option} writes a .npy file")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise CliError(f"{path}: output directory {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise CliError(f"{path}: output directory {str(folder)!r} is not writable")


def cmd_render(args: argparse.Namespace) -> int:
    blend = Path(args.file)
    out = Path(args.output)
    _check_blend(blend)
    _check_output(out, "-o")
    if args.depth:
        _check_output(Path(args.depth), "--depth")
    if importlib.util.find_spec("bpy") is None:
        raise CliError("the bpy module is not installed (pip install bpy==5.0.1, or run bash scripts/setup.sh)")
    from . import bridge
    from .pipeline import RenderCancelled
    from .scene import SceneError

    with _redirect_fds(None):
        try:
            bridge.open_blend(blend)
        except SceneError as exc:
            raise CliError(str(exc)) from None
    try:
        scene = bridge.scene_named(args.scene, where=blend)
        with _redirect_fds(2):  # F12's render-mode depsgraph (modifier render levels)
            frame = bridge.render_final(scene, frame=args.frame)
    except SceneError as exc:
        raise CliError(str(exc)) from None
    except RenderCancelled:
        raise CliError("render cancelled") from None
    for warning in frame.warnings:
        _warn(warning)
    try:
        imageio.save(out, frame.color)
    except (imageio.ImageIOError, OSError) as exc:
        raise CliError(str(exc)) from None
    if args.depth:
        try:
            imageio.save(args.depth, frame.depth)
        except (imageio.ImageIOError, OSError) as exc:
            out.unlink(missing_ok=True)  # all or nothing
            raise CliError(str(exc)) from None
    print(out)
    if args.depth:
        print(args.depth)
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    try:
        a = imageio.load(args.a)
        b = imageio.load(args.b)
        if args.diff:
            _check_output(Path(args.diff), "-o")
        result = imageio.compare(a, b, diff_path=args.diff, tolerance=args.tolerance)
    except imageio.ImageIOError as exc:
        raise CliError(str(exc)) from None
    if a.ndim == 3 and b.ndim == 3 and a.shape[2] != b.shape[2]:
        _warn(f"channel counts differ ({a.shape[2]} vs {b.shape[2]}); compared the first {result.channels}")
    for line in result.lines():
        print(line)
    if args.diff:
        print(f"heat map: {args.diff}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m blendlib",
        description="Unity Passes: render .blend files with Unity's built-in pipeline semantics "
                    "(render queues, ZWrite/ZTest, Cull, Blend, ColorMask, alpha test, stencil) and compare images.",
        epilog="run 'python -m blendlib COMMAND --help' for the options of a command",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    r = sub.add_parser("render", help="render a .blend file to PNG/EXR/NPY",
                       description="Render the active (or named) scene of a .blend file through its camera.",
                       epilog=EPILOG_RENDER, formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("file", metavar="FILE.blend", help="the .blend file (it is only read, never saved)")
    r.add_argument("-o", "--output", required=True, metavar="OUT", help="output image: .png, .exr or .npy")
    r.add_argument("--depth", metavar="DEPTH.npy", help="also write the depth buffer (H, W) float32, 0..1 window depth")
    r.add_argument("--frame", type=int, metavar="N", help="frame number to render (default: the file's current frame)")
    r.add_argument("--scene", metavar="NAME", help="scene to render (default: the file's active scene)")
    r.set_defaults(func=cmd_render)
    c = sub.add_parser("compare", help="compare two images (PNG/EXR/NPY)",
                       description="Compare two images of the same size over their common channels.",
                       epilog=EPILOG_COMPARE, formatter_class=argparse.RawDescriptionHelpFormatter)
    c.add_argument("a", metavar="A", help="first image (.png, .exr or .npy)")
    c.add_argument("b", metavar="B", help="second image (.png, .exr or .npy)")
    c.add_argument("--diff", metavar="OUT.png", help="write a heat map of the per-pixel difference")
    c.add_argument("--tolerance", type=float, default=0.0,
                   help="a pixel counts as differing when a channel differs by more than this (default 0)")
    c.set_defaults(func=cmd_compare)
    sub.add_parser("shaderlab", help="import/export ShaderLab (see 'python -m blendlib shaderlab --help')",
                   add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "shaderlab":
        from . import shaderlab_io

        return int(shaderlab_io.main(argv[1:]) or 0)
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        return args.func(args)
    except CliError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("error: interrupted; nothing written", file=sys.stderr)
        return 130
    except MemoryError:
        print("error: out of memory (lower the resolution or the resolution percentage)", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - one line for the user; UNITY_PASSES_DEBUG=1 for the traceback
        if os.environ.get("UNITY_PASSES_DEBUG"):
            raise
        text = " ".join(str(exc).split()) or "no details"
        print(f"error: internal error: {type(exc).__name__}: {text} (set UNITY_PASSES_DEBUG=1 for a traceback)",
              file=sys.stderr)
        return 1
