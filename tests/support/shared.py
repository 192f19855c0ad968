"""Where the project's shared material is: ``shared/`` (SPEC, seeds, the Unity corpus).

It stands beside the repository root in the main checkout (``../shared``); a git worktree in a
folder of worktrees finds it one level higher (``../../shared``).
"""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def shared_dir() -> Path:
    """The ``shared/`` folder (the first of ``../shared`` and ``../../shared`` that exists)."""
    for candidate in (REPO.parent / "shared", REPO.parent.parent / "shared"):
        if candidate.is_dir():
            return candidate
    return REPO.parent / "shared"


SHARED = shared_dir()
#: Unity's built-in shader source, 2019.4 (MIT).
BUILTIN_SHADERS = SHARED / "corpus" / "unity-builtin-shaders-2019.4"
