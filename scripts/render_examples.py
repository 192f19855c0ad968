#!/usr/bin/env python3
"""Render every ``blend_files/*.blend`` to ``out/<name>.png`` and print each path.

    .venv/bin/python scripts/render_examples.py [--blend-dir blend_files] [--out out]

Each file goes through ``python -m blendlib render`` in its own process (a .blend load
replaces Blender's whole state). Exit status 1 when any file fails; the others still render.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Render every example scene to PNG.")
    parser.add_argument("--blend-dir", type=Path, default=ROOT / "blend_files")
    parser.add_argument("--out", type=Path, default=ROOT / "out")
    args = parser.parse_args(argv)
    files = sorted(args.blend_dir.glob("*.blend")) if args.blend_dir.is_dir() else []
    if not files:
        print(f"no .blend files in {args.blend_dir}; nothing to render", file=sys.stderr)
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    failed = 0
    for blend in files:
        target = args.out / f"{blend.stem}.png"
        proc = subprocess.run([sys.executable, "-m", "blendlib", "render", str(blend), "-o", str(target)],
                              cwd=ROOT, capture_output=True, text=True)
        if proc.returncode != 0:
            failed += 1
            reason = (proc.stderr.strip().splitlines() or ["unknown error"])[-1]
            print(f"{blend.name}: {reason}", file=sys.stderr)
            continue
        for line in proc.stderr.splitlines():
            if line.startswith("warning:"):
                print(f"{blend.name}: {line}", file=sys.stderr)
        print(target)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
