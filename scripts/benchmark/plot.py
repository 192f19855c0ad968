"""The run's plot: one panel per kind of figure the run has (matplotlib's Agg backend, no display)."""

from __future__ import annotations

from pathlib import Path

#: (backend, the median it plots, colour) of every backend.
SERIES = (("project", "render_s", "#1f77b4"), ("opengl", "total_s", "#ff7f0e"),
          ("eevee", "total_s", "#2ca02c"), ("workbench", "total_s", "#9467bd"))


def _scaling_series(results, group, xkey):
    """``[(backend, colour, [(x, seconds), ...]), ...]`` of one scaling group (points with both > 0)."""
    rs = [r for r in results if r["case"]["group"] == group]
    out = []
    for kind, key, color in SERIES:
        s = [(r["setup"].get("project", {}).get(xkey) or 0, (r["median"].get(kind) or {}).get(key) or 0) for r in rs]
        s = [p for p in s if p[0] and p[1]]
        if s:
            out.append((kind, color, s))
    return out


def write_plot(results: list[dict], path: Path, title: str) -> Path:
    """One panel per kind of figure the run has: time vs triangles and time vs covered pixels
    (log-log, the scaling groups), every scene's total time per backend (log bars), the frame
    debugger's and the sorted reference's ratios to a plain render, and the viewport's frame
    times. Written atomically as PNG, 16/3 x 5 inches per panel at 80 dpi."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from blendlib.formats.atomic import write_atomic

    path.parent.mkdir(parents=True, exist_ok=True)
    tri = _scaling_series(results, "scale-tris", "triangles")
    res = _scaling_series(results, "scale-res", "covered_px")
    bars = [r for r in results if r["case"]["group"] in ("S1", "S2", "S2p", "S3", "S4", "S5", "S6", "msaa", "linear")]
    explained = [r for r in results if r.get("explain")]
    viewports = [r for r in results if r.get("viewport")]
    panels = []

    def scaling_panel(series, xl, t):
        def draw(ax):
            for name, color, s in series:
                ax.loglog(*zip(*s, strict=True), "o-", color=color, label=name)
            ax.set_xlabel(xl)
            ax.set_ylabel("seconds (median)")
            ax.set_title(t)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        return draw

    def grouped_bars(ax, rs, series, value):
        width = 0.8 / len(series)
        for j, (label, key, color) in enumerate(series):
            ax.bar([i + j * width for i in range(len(rs))], [value(r, key) or 0 for r in rs], width,
                   color=color, label=label)
        ax.set_xticks([i + 0.4 - width / 2 for i in range(len(rs))], [r["case"]["id"] for r in rs],
                      rotation=30, ha="right")
        ax.legend(fontsize=8)

    def scenes_panel(ax):
        grouped_bars(ax, bars, [(kind, kind, color) for kind, _key, color in SERIES],
                     lambda r, kind: (r["median"].get(kind) or {}).get("total_s"))
        ax.set_yscale("log")
        ax.set_ylabel("seconds (median)")
        ax.set_title("scenes: total time (project = extraction + render)")

    def explain_panel(ax):
        grouped_bars(ax, explained, [("draw list", "drawlist_ratio", "#1f77b4"), ("pixel history", "pixel_ratio",
                                                                                   "#ff7f0e"),
                                     ("capture", "capture_ratio", "#2ca02c"), ("step", "step_ratio", "#9467bd"),
                                     ("analyze", "analyze_ratio", "#d62728")],
                     lambda r, key: r["explain"].get(key))
        ax.set_yscale("log")
        # a one-draw scene's step returns the kept frame (a ratio far below the axis); room for the legend
        ax.set_ylim(0.01, 30)
        ax.legend(fontsize=8, ncol=3, loc="upper left")
        for y, style in ((1.0, "-"), (3.0, "--")):
            ax.axhline(y, color="grey", linestyle=style, linewidth=0.8)
        ax.set_ylabel("time / plain render (median)")
        ax.set_title("frame debugger and analyze vs a plain render")

    def viewport_panel(ax):
        w, h = viewports[0]["viewport"]["size"]
        grouped_bars(ax, viewports, [("reduced frame", "reduced_s", "#2ca02c"), ("full frame", "full_s", "#1f77b4"),
                                     ("change -> first frame", "scheduler_first_s", "#ff7f0e")],
                     lambda r, key: r["viewport"][key] * 1000)
        for y in (20, 60):
            ax.axhline(y, color="grey", linestyle="--", linewidth=0.8)
        ax.set_ylabel("milliseconds (median)")
        ax.set_title(f"viewport {w}x{h} (targets 20 / 60 ms)")

    if tri:
        panels.append(scaling_panel(tri, "triangles", "time vs triangles (1080p)"))
    if res:
        panels.append(scaling_panel(res, "covered pixels", "time vs covered pixels (200k tris)"))
    if bars:
        panels.append(scenes_panel)
    if explained:
        panels.append(explain_panel)
    if viewports:
        panels.append(viewport_panel)
    n = max(len(panels), 1)
    fig = Figure(figsize=(16 / 3 * n, 5))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n, squeeze=False)[0]
    for ax, panel in zip(axes, panels, strict=False):
        panel(ax)
    fig.suptitle(title)
    fig.tight_layout()
    write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=80))
    return path
