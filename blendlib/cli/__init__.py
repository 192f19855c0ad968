"""Command line: ``python -m blendlib render|compare|shaderlab|drawlist|pixel|analyze|import ...``.

Each subcommand is a module with ``add_parser(subparsers)`` and ``run(args)``, imported when the
parser is built (after :mod:`.interrupts` has installed the signal handling). Errors are one
line on stderr (``error: ...``) with a non-zero exit status: 1 for bad input or a failed run,
2 for bad usage (argparse), 130 when interrupted by Ctrl+C and 143 by SIGTERM (the line then
says what was written). Warnings go to stderr as ``warning: ...``. Outputs are checked before
any work and committed together per frame (:mod:`.outputs`), so a failed or cancelled run
leaves every existing file as it was and no partial file.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

from . import interrupts
from .errors import CliError

COMMAND_NAMES = ("render", "compare", "shaderlab", "drawlist", "pixel", "analyze", "import_")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m blendlib",
        description="Unity Passes: render .blend files with Unity's built-in pipeline semantics "
                    "(render queues, ZWrite/ZTest, Cull, Blend, ColorMask, alpha test, stencil) and compare images.",
        epilog="run 'python -m blendlib COMMAND --help' for the options of a command",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_NAMES:
        importlib.import_module(f".{name}", __name__).add_parser(sub)
    return parser


def interrupted_line(exc: interrupts.Interrupted) -> str:
    """The one line an interruption prints: which signal, and what was written before it."""
    what = "interrupted" if exc.signum == signal.SIGINT else f"interrupted ({exc})"
    return f"error: {what}; {exc.detail or interrupts.written_summary()}"


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns the exit status. Ctrl+C and SIGTERM are handled from here on
    (:mod:`.interrupts`) and the previous handling restored on return."""
    restore = interrupts.install()
    try:
        return _main(argv)
    except interrupts.Interrupted as exc:
        print(interrupted_line(exc), file=sys.stderr)
        return exc.exit_status
    finally:
        restore()


def _main(argv: list[str] | None) -> int:
    interrupts.WRITTEN.clear()
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        with interrupts.interruptible():
            return args.func(args)
    except CliError as exc:
        interrupts.check()  # an error that the interruption caused is the interruption
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # the handlers could not be installed (not the main thread)
        print(f"error: interrupted; {interrupts.written_summary()}", file=sys.stderr)
        return 130
    except MemoryError:
        interrupts.check()
        print("error: out of memory (lower the resolution or the resolution percentage)", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - one line for the user; UNITY_PASSES_DEBUG=1 for the traceback
        interrupts.check()  # e.g. an import broken into by the signal: report the signal
        if os.environ.get("UNITY_PASSES_DEBUG"):
            raise
        text = " ".join(str(exc).split()) or "no details"
        print(f"error: internal error: {type(exc).__name__}: {text} (set UNITY_PASSES_DEBUG=1 for a traceback)",
              file=sys.stderr)
        return 1
