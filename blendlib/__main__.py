"""``python -m blendlib``: see :mod:`blendlib.cli`."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
