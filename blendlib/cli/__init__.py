"""Command line: ``python -m blendlib render|compare|shaderlab|drawlist|pixel|analyze|import ...``.

Each subcommand is a module with ``add_parser(subparsers)`` and ``run(args)``. Errors are
one line on stderr (``error: ...``) with a non-zero exit status: 1 for bad input or a
failed run, 2 for bad usage (argparse), 130 when interrupted. Warnings go to stderr as
``warning: ...``. Outputs are written to a temporary file and renamed, so a failed or
cancelled run writes nothing.
"""

from __future__ import annotations

import argparse
import os
import sys

from . import analyze, compare, drawlist, import_, pixel, render, shaderlab
from .common import CliError

COMMANDS = (render, compare, shaderlab, drawlist, pixel, analyze, import_)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m blendlib",
        description="Unity Passes: render .blend files with Unity's built-in pipeline semantics "
                    "(render queues, ZWrite/ZTest, Cull, Blend, ColorMask, alpha test, stencil) and compare images.",
        epilog="run 'python -m blendlib COMMAND --help' for the options of a command",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
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
