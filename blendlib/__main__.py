"""``python -m blendlib``: see :mod:`blendlib.cli`.

The signal handling comes first, before anything heavy is imported (:mod:`blendlib.cli.interrupts`):
a Ctrl+C or SIGTERM from here on ends the command with one line, never a traceback.
"""

import sys

from .cli import interrupts

if __name__ == "__main__":
    interrupts.install()  # records a signal from now on; main() acts on it
    try:
        from .cli import main
        from .runtime.allocator import keep_freed_memory

        keep_freed_memory()  # this process is the command line's own (runtime/allocator.py)
        status = main()
    except interrupts.Interrupted as exc:  # while importing, before main() took over
        from .cli import interrupted_line

        print(interrupted_line(exc), file=sys.stderr)
        status = exc.exit_status
    interrupts.finish()
    sys.exit(status)
