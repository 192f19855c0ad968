"""``python -m blendlib shaderlab``: import a ``.shader`` or ``.mat`` file as JSON (the material
record), or export a material of a ``.blend`` file as ShaderLab."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..formats import shaderlab
from .common import CliError, check_blend, open_scene, redirect_fds, require_bpy, write_text_atomic

EPILOG = """\
import: parse FILE.shader (or - for standard input) or a Unity material FILE.mat and print the
  material record as JSON: {"name", "material": {material fields}, "passes": [{pass fields,
  "light_mode", "drawn", "reason"}], "warnings", "extra"} ("drawn" as in a scene with one
  directional light). UsePass and Fallback shaders are found in the file's folder, a .mat's
  shader and textures in its project's Assets/ folder (through their .meta guids), then in each
  --search folder (recursively); Unity's built-in shaders (Standard, Particles/..., UI/Default)
  by name: pass Unity's built-in shader source folder with --search.
export: write material NAME of FILE.blend as a ShaderLab shader (Properties, Tags, one Pass per
  pass with its LightMode and render state, a CG program with the same shading and alpha test);
  --name sets the Shader "..." name (default "Unity Passes/NAME").

examples:
  python -m blendlib shaderlab Glass.shader
  python -m blendlib shaderlab Assets/Materials/Glass.mat --search ~/builtin_shaders
  python -m blendlib shaderlab --export scene.blend --material Glass -o Glass.shader
"""


def add_parser(sub) -> None:
    s = sub.add_parser("shaderlab", help="import/export ShaderLab .shader files",
                       description="Import a ShaderLab shader (JSON on stdout) or export a material of a .blend file.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("file", nargs="?", metavar="FILE.shader|FILE.mat",
                   help="the shader or Unity material to import (- for a shader on standard input)")
    s.add_argument("--search", metavar="DIR", action="append", default=[],
                   help="a folder searched (recursively) for shaders and assets; repeatable")
    s.add_argument("--export", metavar="FILE.blend", help="export a material of this .blend file")
    s.add_argument("--material", metavar="NAME", help="with --export: the material to export")
    s.add_argument("-o", "--output", metavar="OUT.shader", help="with --export: the shader file to write")
    s.add_argument("--name", metavar="SHADER_NAME", help='with --export: the Shader "..." name')
    s.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.export is not None:
        if args.file is not None:
            raise CliError(f"unexpected argument {args.file!r} with --export")
        if not args.material or not args.output:
            raise CliError("--export needs --material NAME and -o OUT.shader")
        return _export(Path(args.export), args.material, Path(args.output), args.name)
    if args.file is None:
        raise CliError("no .shader or .mat file given (python -m blendlib shaderlab FILE.shader|FILE.mat)")
    for option in ("material", "output", "name"):
        if getattr(args, option) is not None:
            raise CliError(f"--{option} goes with --export")
    for folder in args.search:
        if not Path(folder).is_dir():
            raise CliError(f"{folder}: --search folder does not exist")
    search = tuple(args.search)
    try:
        if args.file == "-":
            result = shaderlab.parse_shaderlab(sys.stdin.read(), filename="<stdin>",
                                               search=shaderlab.AssetSearch([Path.cwd(), *search]))
        elif args.file.lower().endswith(".mat"):
            result = shaderlab.import_material_file(args.file, search)
        else:
            result = shaderlab.parse_shaderlab_file(args.file, search)
    except shaderlab.ShaderLabError as exc:
        raise CliError(str(exc)) from None
    except UnicodeDecodeError as exc:
        raise CliError(f"{args.file}: not UTF-8 text ({exc.reason})") from None
    except OSError as exc:
        raise CliError(f"{exc.filename or args.file}: {exc.strerror or exc}") from None
    sys.stdout.write(result.to_json() + "\n")
    return 0


def _export(blend: Path, material_name: str, output: Path, shader_name: str | None) -> int:
    if output.suffix.lower() != ".shader":
        raise CliError(f"{output}: the export writes a .shader file")
    check_blend(blend)
    if output.exists() and output.resolve() == blend.resolve():
        raise CliError(f"{output}: is the input file; choose another output")
    folder = output.parent if str(output.parent) else Path(".")
    if not folder.is_dir():
        raise CliError(f"{output}: output directory {str(folder)!r} does not exist")
    require_bpy()
    from .. import blender
    from ..core.scene import SceneError

    open_scene(blend, None)
    try:
        mat = blender.material_named(material_name, where=blend)
    except SceneError as exc:
        raise CliError(str(exc)) from None
    with redirect_fds(2):
        material = blender.material_from_blender(mat)
    write_text_atomic(output, shaderlab.export_shaderlab(material, shader_name))
    return 0
