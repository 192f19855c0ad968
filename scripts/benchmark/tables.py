"""The run's figures as tables: the main table (every scene, every backend), the frame debugger's
and the viewport's; plain text for the terminal, Markdown for docs/benchmark.md."""

from __future__ import annotations

from scripts.benchmark.cases import BACKENDS
from scripts.benchmark.timing import spreads
from scripts.benchmark.workers import VIEWPORT_TIMES


def fmt_t(v) -> str:
    """Seconds (or milliseconds) with three significant digits, at most; "-" for None."""
    if v is None:
        return "-"
    if v >= 100:
        return f"{v:.0f}"
    if v >= 10:
        return f"{v:.1f}"
    if v >= 1:
        return f"{v:.2f}"
    return f"{v:.3f}"


def fmt_x(v) -> str:
    """A ratio such as "2.5x" (more digits below 1x, fewer from 100x); "-" for None."""
    if v is None:
        return "-"
    return f"{v:.3f}x" if v < 0.1 else f"{v:.2f}x" if v < 1 else f"{v:.1f}x" if v < 100 else f"{v:.0f}x"


def fmt_n(v) -> str:
    """A count such as "1.01M", "691k" or "100"; "-" for None."""
    if v is None:
        return "-"
    if v >= 1e6:
        return f"{v / 1e6:.2f}M"
    if v >= 1e3:
        return f"{v / 1e3:.0f}k"
    return str(int(v))


def fmt_spreads(mine, gl) -> str:
    """The project's and OpenGL's spread over the repeats, e.g. "12%/5%"; "-" for a missing one."""
    return "/".join("-" if v is None else f"{v:.0%}" for v in (mine, gl))


COLUMNS = ("scene", "tris", "size", "covered", "extract s", "render s", "project s", "OpenGL s",
           "EEVEE s", "Workbench s", "proj/GL", "proj/EEVEE", "spread proj/GL", "peak MB", "CPU")


def table_rows(results: list[dict]) -> list[list[str]]:
    """The main table: per scene its size, the medians of every backend and the ratios."""
    rows = []
    for res in results:
        case = res["case"]
        m = res["median"]
        p, g, e, wb = (m.get(k) for k in BACKENDS)
        ps = res["setup"].get("project", {})
        rows.append([
            case["id"], fmt_n(ps.get("triangles")), f"{case['width']}x{case['height']}",
            fmt_n(ps.get("covered_px")),
            fmt_t(p and p["extract_s"]), fmt_t(p and p["render_s"]), fmt_t(p and p["total_s"]),
            fmt_t(g and g["total_s"]), fmt_t(e and e["total_s"]), fmt_t(wb and wb["total_s"]),
            fmt_x(res["ratio_gl"]), fmt_x(res["ratio_eevee"]), fmt_spreads(*spreads(res)),
            "-" if not p else f"{p['peak_mb']:.0f}", "-" if not p else f"{p['cpu_ratio']:.2f}",
        ])
    return rows


def format_table(results: list[dict], markdown: bool = False, columns=COLUMNS, rows_of=table_rows) -> str:
    """The main table (default), or with ``columns`` and ``rows_of`` another one (explain, viewport)."""
    rows = rows_of(results)
    if markdown:
        lines = ["| " + " | ".join(columns) + " |", "|" + "|".join("---" for _ in columns) + "|"]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        return "\n".join(lines)
    widths = [max(len(c), *(len(r[i]) for r in rows)) if rows else len(c) for i, c in enumerate(columns)]
    fmt = "  ".join(f"{{:{'<' if i == 0 else '>'}{w}}}" for i, w in enumerate(widths))
    lines = [fmt.format(*columns), fmt.format(*("-" * w for w in widths))]
    lines += [fmt.format(*r) for r in rows]
    return "\n".join(lines)


EXPLAIN_COLUMNS = ("scene", "size", "draws", "fragments", "plain s", "draw list", "pixel", "capture",
                   "step (to<-from)", "analyze", "advice / analyze", "plain MB", "capture MB", "analyze MB")
VIEWPORT_COLUMNS = ("scene", "size", "extract ms", "reduced ms", "full ms", "reduced (view) ms", "full (view) ms",
                    "full 1 proc. ms", "change->first ms", "render_view ms", "sched. first ms", "sched. full ms")


def explain_rows(results: list[dict]) -> list[list[str]]:
    """Frame debugger and sorted reference: ratios to a plain render of the same
    DrawScene in alternating runs, and tracemalloc peaks."""
    rows = []
    for res in results:
        e = res.get("explain")
        if not e:
            continue
        rows.append([
            res["case"]["id"], f"{e['size'][0]}x{e['size'][1]}", str(e["draws"]), fmt_n(e["fragments"]),
            fmt_t(e["plain_s"]), fmt_x(e["drawlist_ratio"]), fmt_x(e["pixel_ratio"]), fmt_x(e["capture_ratio"]),
            f"{fmt_x(e['step_ratio'])} ({e['step_to']}<-{e['step_from']})", fmt_x(e["analyze_ratio"]),
            fmt_x(e.get("advice_over_analyze")),
            f"{e['plain_peak_mb']:.0f}", f"{e['capture_peak_mb']:.0f}", f"{e['analyze_peak_mb']:.0f}",
        ])
    return rows


def viewport_rows(results: list[dict]) -> list[list[str]]:
    """Viewport frames, medians in milliseconds."""
    rows = []
    for res in results:
        v = res.get("viewport")
        if not v:
            continue
        rows.append([res["case"]["id"], f"{v['size'][0]}x{v['size'][1]}"]
                    + [f"{v[k] * 1000:.1f}" if k in v else "-" for k in VIEWPORT_TIMES])
    return rows
