"""``python -m scripts.benchmark [options]``: see :mod:`scripts.benchmark.cli`."""

import sys

if not __package__:  # run as a folder path: the repository root (scripts, addon, tests) is not importable
    sys.exit("error: run the benchmark from the repository root as: python -m scripts.benchmark [options]")

from scripts.benchmark.cli import main  # noqa: E402  (after the check above)

sys.exit(main())
