#!/usr/bin/env python3
"""Write docs/unity-shaders.md: Unity's built-in shaders as this importer reads them, from its own output.

    .venv/bin/python -m scripts.make_unity_shader_table            # → docs/unity-shaders.md
    .venv/bin/python -m scripts.make_unity_shader_table --corpus DIR -o OUT.md

Every ``.shader`` of Unity's built-in shader source (default: ``shared/corpus/unity-builtin-shaders-
2019.4`` beside the repository, or one level higher) is imported (``blendlib.formats.shaderlab``),
and each family's table lists per shader its queue, the passes that draw in a scene with one
directional light (LightMode and state line), the passes listed but not drawn, and what the import
warns is approximated or not imported. The sections before the tables (sources per surface-shader
option, fixed-function meanings, the LightMode rules, the decisions taken where the evidence is
thin, the built-in fileIDs) are ``scripts/unity_shaders_intro.md``.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from blendlib.core.vocabulary import pass_state_text, queue_text  # noqa: E402
from blendlib.formats.atomic import write_atomic  # noqa: E402
from blendlib.formats.shaderlab import BUILTIN_SHADERS, parse_shaderlab_file  # noqa: E402


def default_corpus() -> Path:
    for shared in (ROOT.parent / "shared", ROOT.parent.parent / "shared"):
        corpus = shared / "corpus" / "unity-builtin-shaders-2019.4"
        if corpus.is_dir():
            return corpus
    return ROOT.parent / "shared" / "corpus" / "unity-builtin-shaders-2019.4"


#: Warning text → the short note of the table's last column (first match per warning).
NOTES = [
    (r"Standard shader's physically based lighting|lighting model \w+ is drawn as Lambert", "lit colour: Lambert"),
    (r"fixed-function per-vertex lighting", "vertex lighting: per-pixel Lambert"),
    (r"use of the vertex colour", "vertex colour ≈"),
    (r"premultiplies its colour by alpha in the shader", "premultiplied: in the blend (exact)"),
    (r"premultiplies its colour by alpha, which", "premultiplication ≈"),
    (r"raises the output alpha", "Transparent mode's alpha ≈"),
    (r"GrabPass ignored", "GrabPass not drawn"),
    (r"vertex modifier", "vertex modifier not run"),
    (r"final colour modifier", "final colour modifier not run"),
    (r"drawn with the Fallback", "drawn with its Fallback"),
    (r"UsePass .*not imported", "UsePass not found"),
    (r"not a pass of the built-in forward path", "editor-only LightModes"),
    (r"unity_GUIZTestMode", "ZTest global → LEqual"),
    (r"a global, which Unity reads as 0", "globals read as 0"),
    (r"colour scale ×", "colour ×scale (exact in Gamma)"),
    (r"Material (Emission|Specular) is not drawn|ColorMaterial Emission", "emission/specular not drawn"),
    (r"drawn as texture × primary|combiners (multiply|do not use)|a second texture", "combiner ≈"),
    (r"discards fragments with its own condition", "own discard not drawn"),
    (r"compares with the constant", "constant alpha cutoff"),
    (r"per-face stencil", "per-face stencil ignored"),
    (r"shades differently", "passes shade differently"),
    (r"draws as Add", "advanced BlendOp → Add"),
    (r"albedo and alpha of", "surf() albedo ≈"),
    (r"alpha:blend imported|decal:(add|blend) imported", "unverified option"),
    (r"no program and no colour command", "primary colour: _Color"),
    (r"drawn as Multiply", "colour mode ≈"),
    (r"Modulate mode", "Modulate ≈"),
    (r"is drawn with the material's", "texture property ≈"),
    (r"no SubShader", "no SubShader"),
    (r"alpha test keeps alpha >= _Cutoff -", "cutoff - 0.0001"),
    (r"draws only with the Quality option", "Quality option assumed on"),
]


def notes(warnings) -> list[str]:
    out: list[str] = []
    for warning in warnings:
        for pattern, note in NOTES:
            if re.search(pattern, warning) and note not in out:
                out.append(note)
                break
    return out


def family(name: str) -> str:
    parts = name.split("/")
    if parts[0] == "Legacy Shaders" and len(parts) > 2:
        return "/".join(parts[:2])
    return parts[0] if len(parts) > 1 else "Standard and other top-level shaders"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def shader_tables(corpus: Path) -> tuple[str, int]:
    rows: dict[str, list[str]] = defaultdict(list)
    files = sorted(corpus.rglob("*.shader"))
    for path in files:
        result = parse_shaderlab_file(str(path))
        record = result.to_dict()
        drawn = [(e, p) for e, p in zip(record["passes"], [p for p, _ in result.listed], strict=True) if e["drawn"]]
        drawn_text = "<br>".join(f"**{_cell(p.name)}** ({p.light_mode}): `{_cell(pass_state_text(p))}`"
                                 for _, p in drawn) or "none"
        others = [e for e in record["passes"] if not e["drawn"]]
        listed = ", ".join(sorted({e["light_mode"] for e in others})) or "—"
        m = result.material
        shading = f"{m.lighting}" + (f", vertex colour {m.vertex_color}" if m.vertex_color.value != "Off" else "")
        rows[family(result.name)].append(
            f"| {_cell(result.name)} | `{path.relative_to(corpus)}` | {queue_text(m.queue, m.queue_offset)} | "
            f"{drawn_text} | {listed} | {shading} | {', '.join(notes(result.warnings)) or '—'} |")
    out = []
    for name in sorted(rows):
        out += [f"### {name}", "",
                "| shader | file | queue | passes drawn (one directional light) | listed, not drawn | shading | "
                "approximated / not imported |",
                "|---|---|---|---|---|---|---|", *rows[name], ""]
    return "\n".join(out), len(files)


#: The text before the tables (sources, meanings, decisions), kept beside this script.
INTRO = ROOT / "scripts" / "unity_shaders_intro.md"


def builtin_list() -> str:
    return ", ".join(f"{file_id} {name}" for (guid, file_id), name in sorted(BUILTIN_SHADERS.items(),
                                                                              key=lambda kv: kv[0][1]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--corpus", type=Path, default=default_corpus(), help="Unity's built-in shader source")
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "unity-shaders.md")
    args = parser.parse_args(argv)
    if not args.corpus.is_dir():
        print(f"error: {args.corpus}: no such folder (pass --corpus)", file=sys.stderr)
        return 1
    tables, count = shader_tables(args.corpus)
    text = (INTRO.read_text(encoding="utf-8") + builtin_list() + ".\n\n"
            + f"## Every built-in shader ({count}), by family\n\n"
            "Columns: the Queue, the passes drawn in a scene with one directional light with their state\n"
            "line (as the Blender panel and the draw list write it), the LightModes of the passes listed\n"
            "but never drawn here, the material's shading, and what the import warns about.\n\n" + tables)
    write_atomic(args.output, text)
    print(args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
