"""``python -m blendlib``: see :mod:`blendlib.cli`."""

import sys

from .cli import main
from .runtime.allocator import keep_freed_memory

if __name__ == "__main__":
    keep_freed_memory()  # this process is the command line's own (runtime/allocator.py)
    sys.exit(main())
