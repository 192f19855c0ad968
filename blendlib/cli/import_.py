"""``python -m blendlib import``: a ``.vrm`` / ``.glb`` / ``.gltf`` file as a ``.blend`` with Unity settings."""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

from .common import CliError, redirect_fds, require_bpy, warn

EPILOG = """\
examples:
  python -m blendlib import avatar.vrm -o avatar.blend
  python -m blendlib import model.glb -o model.blend --json

The geometry comes from Blender's glTF importer; every material gets the Unity settings UniVRM
(VRM 0.x materialProperties as stored, VRM 1.0 VRMC_materials_mtoon through MToon's validator) or
UniGLTF (plain glTF) set for Unity's built-in pipeline; the MToon materials of a .vrm get them as the
VRM Add-on for Blender's MToon settings (Unity settings off, the spec version on the armature), so
that they render, are advised and are changed as the add-on's own materials. A camera framing the
model and a Sun are added when the file has none. --json prints one record per material, the one `shaderlab` prints
(name, material, passes with light_mode/drawn/reason, warnings, extra), plus its glTF index and the
importer that took it. A bad file is one error line and writes nothing.
"""


def add_parser(sub) -> None:
    s = sub.add_parser("import", help="import a VRM/glTF file with Unity settings into a new .blend",
                       description="Import a .vrm, .glb or .gltf file into a new .blend file, each material "
                                   "with the Unity settings UniVRM / UniGLTF set.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("file", metavar="FILE", help="the .vrm, .glb or .gltf file")
    s.add_argument("-o", "--output", metavar="OUT.blend", required=True, help="the .blend file to write")
    s.add_argument("--json", action="store_true", help="print the material records as JSON on stdout")
    s.set_defaults(func=run)


def _check_output(output: Path, source: Path) -> None:
    """Before any work: a ``.blend`` name, not the input, in a folder a file can be created in."""
    if output.suffix.lower() != ".blend":
        raise CliError(f"{output}: the import writes a .blend file")
    if output.is_dir():
        raise CliError(f"{output}: is a directory; -o needs a file name")
    if output.exists() and source.exists() and output.resolve() == source.resolve():
        raise CliError(f"{output}: is the input file; choose another output")
    folder = output.parent if str(output.parent) else Path(".")
    try:  # the real test of the folder: create (and remove) a file there
        fd, probe = tempfile.mkstemp(prefix=f".{output.stem}.", suffix=".probe", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise CliError(f"{output}: cannot write in {str(folder)!r} ({exc.strerror or exc})") from None


def _save(output: Path) -> None:
    """Save the current data as ``output``: a temporary file beside it, then a rename."""
    from ..blender import gltf_import

    folder = output.parent if str(output.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{output.stem}.", suffix=".part.blend", dir=folder)
    os.close(fd)
    os.unlink(tmp)  # Blender would keep an existing file as FILE.blend1
    try:
        with redirect_fds(None):
            gltf_import.save_blend(tmp)
        os.replace(tmp, output)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, (RuntimeError, OSError)):
            raise CliError(f"{output}: cannot write ({' '.join(str(exc).split())})") from None
        raise


def run(args: argparse.Namespace) -> int:
    from ..formats.gltf import GltfError, import_materials, read_document

    source, output = Path(args.file), Path(args.output)
    try:
        result = import_materials(read_document(source))  # every check before Blender starts
    except GltfError as exc:
        raise CliError(str(exc)) from None
    _check_output(output, source)
    require_bpy()
    from ..blender import gltf_import

    try:
        with redirect_fds(None):  # the glTF importer's progress chatter; its errors come back as exceptions
            done = gltf_import.import_into_new_file(source)
    except GltfError as exc:
        raise CliError(str(exc)) from None
    _save(output)
    for warning in (*result.warnings, *done.warnings):
        warn(warning)
    if args.json:
        sys.stdout.write(json.dumps(done.result.to_dict() | {"output": str(output)}, indent=2) + "\n")
    else:
        for imported in done.result.materials:
            m = imported.material
            print(f"{m.name}: {imported.importer}, queue {m.render_queue}, {len(m.passes)} passes")
        print(f"Saved: '{output.resolve()}'")
    return 0
