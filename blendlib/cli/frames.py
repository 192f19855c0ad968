"""Frame ranges and Blender's ``#`` output patterns for ``render --frames``
(README: "Viewport, animations, render farms")."""

from __future__ import annotations

import re
from pathlib import Path

from .errors import CliError

#: Blender's frame range (MAXFRAME): ``scene.frame_set`` clamps to ±this.
MAX_FRAME = 1048574

_RANGE = re.compile(r"^(-?\d+)(?:-(-?\d+)(?::(-?\d+))?)?$")
_HASHES = re.compile(r"#+")


def parse_frames(text: str) -> range:
    """``N``, ``A-B`` or ``A-B:STEP``: integers, B inclusive, A ≤ B, STEP ≥ 1 (default 1), every
    frame inside Blender's frame range (±:data:`MAX_FRAME`; beyond it Blender would render the
    last frame of its range under another number) → the frame numbers."""
    match = _RANGE.match(text.strip())
    if match is None:
        raise CliError(f"--frames {text!r}: expected N, A-B or A-B:STEP with integers (e.g. 12, 1-250 or 1-250:10)")
    first = int(match.group(1))
    last = int(match.group(2)) if match.group(2) is not None else first
    step = int(match.group(3)) if match.group(3) is not None else 1
    if first > last:
        raise CliError(f"--frames {text!r}: the first frame {first} is after the last frame {last}")
    if step < 1:
        raise CliError(f"--frames {text!r}: STEP must be 1 or more, got {step}")
    if first < -MAX_FRAME or last > MAX_FRAME:
        raise CliError(f"--frames {text!r}: frames must lie in Blender's frame range -{MAX_FRAME} to {MAX_FRAME}")
    return range(first, last + 1, step)


def has_pattern(path: Path) -> bool:
    return "#" in path.name


def frame_path(path: Path, frame: int) -> Path:
    """The last run of ``#`` in the file name replaced by the frame number zero-padded to the run's
    length (a longer number is not cut), as Blender does; a name without ``#`` is kept."""
    runs = list(_HASHES.finditer(path.name))
    if not runs:
        return path
    run = runs[-1]
    width = run.end() - run.start()
    number = ("-" if frame < 0 else "") + f"{abs(frame):0{width}d}"  # printf's %.*d, as Blender: -005
    name = path.name[:run.start()] + number + path.name[run.end():]
    return path.with_name(name)


def check_pattern(path: Path, option: str, frames: range) -> None:
    """Several frames need a ``#`` in the file name (else each frame would overwrite the last)."""
    if len(frames) > 1 and not has_pattern(path):
        raise CliError(f"{path}: {option} needs a '#' run in the file name for several frames "
                       f"(e.g. out_####{path.suffix}); {len(frames)} frames were asked for")
