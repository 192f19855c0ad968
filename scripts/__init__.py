"""Tools run from the repository root as modules: ``python -m scripts.benchmark`` and
``python -m scripts.make_blend_files`` (they import ``addon`` and ``tests`` from there)."""
