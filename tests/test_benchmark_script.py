"""Smoke test of scripts/benchmark.py (issue 5): it runs in --quick mode on tiny sizes and prints
the table with the expected columns. Not a timed test: no figure is checked against a target."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent

pytest.importorskip("bpy")


def _load_module():
    import scripts.benchmark

    return scripts.benchmark


def test_quick_run_prints_the_table(tmp_path):
    out_json = tmp_path / "bench.json"
    out_png = tmp_path / "bench.png"
    backends = "project,workbench"
    try:
        import moderngl  # noqa: F401

        backends = "project,opengl,workbench"
    except ImportError:
        pass
    cmd = [sys.executable, "-m", "scripts.benchmark", "--quick", "--scenes", "S1,S2,S4", "--backends", backends,
           "--repeats", "1", "--json", str(out_json), "--plot", str(out_png), "--log", str(tmp_path / "w.log")]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr + (tmp_path / "w.log").read_text()
    out = proc.stdout
    header = next(line for line in out.splitlines() if line.startswith("scene "))
    for column in ("scene", "tris", "size", "extract s", "render s", "project s", "OpenGL s", "EEVEE s",
                   "Workbench s", "proj/GL", "proj/EEVEE", "peak MB", "CPU"):
        assert column in header
    rows = {line.split()[0]: line for line in out.splitlines() if line.split()[:1] in (["S1"], ["S2"], ["S4"])}
    assert set(rows) == {"S1", "S2", "S4"}
    assert "Targets of issue 5" in out
    data = json.loads(out_json.read_text())
    by_id = {r["case"]["id"]: r for r in data["results"]}
    assert by_id["S1"]["setup"]["project"]["triangles"] == 4 * 71 * 71  # the quick sphere, 2k segments k+1 rings
    assert by_id["S4"]["setup"]["project"]["triangles"] == 62976  # Suzanne, subdivision level 3
    for r in by_id.values():
        med = r["median"]["project"]
        assert med["render_s"] > 0 and med["extract_s"] > 0 and med["peak_mb"] >= 0
        assert not r["errors"], r["errors"]
    # S1 fills about a third of the frame.
    s1 = by_id["S1"]
    assert abs(s1["setup"]["project"]["covered_px"] / (480 * 270) - 1 / 3) < 0.02
    from blendlib.formats import images

    plot = images.load(out_png)  # matplotlib's figure: 16 x 5 inches at 80 dpi, not blank
    assert plot.shape == (400, 1280, 4) and plot[..., :3].std() > 0.05


def test_running_the_file_directly_says_how_to_run_it():
    proc = subprocess.run([sys.executable, str(REPO / "scripts" / "benchmark.py"), "--quick"], cwd=REPO,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and proc.stderr.strip().endswith("python -m scripts.benchmark [options]")


def test_plot_has_the_three_panels(tmp_path):
    bench = _load_module()
    results = []
    for group, xkey, sizes in (("scale-tris", "triangles", (1e3, 1e4, 1e5)), ("scale-res", "covered_px", (1e4, 1e5))):
        for n in sizes:
            results.append({"case": {"group": group, "id": f"{group}-{n:g}"}, "setup": {"project": {xkey: n}},
                            "median": {"project": {"render_s": n * 1e-5, "total_s": n * 2e-5},
                                       "opengl": {"total_s": n * 1e-6}}})
    results.append({"case": {"group": "S1", "id": "S1"}, "setup": {"project": {}},
                    "median": {"project": {"total_s": 0.5}, "eevee": {"total_s": 2.0}}})
    path = bench.write_plot(results, tmp_path / "p.png", "title")
    from blendlib.formats import images

    plot = images.load(path)
    assert plot.shape == (400, 1280, 4)
    # each third of the figure has drawn (non-white) pixels: two line plots and the bars
    for third in np.array_split(plot[40:360, :, :3], 3, axis=1):
        assert (third < 0.9).any(axis=2).mean() > 0.01


def test_table_and_slope_helpers():
    bench = _load_module()
    assert bench.sphere_k(200_000) == 224
    assert abs(bench.loglog_slope([1, 10, 100], [2, 20, 200]) - 1.0) < 1e-12
    case = dict(id="S1", group="S1", width=4, height=2)
    res = {"case": case, "setup": {"project": {"triangles": 10, "covered_px": 3}},
           "median": {"project": {"extract_s": 0.1, "render_s": 1.0, "total_s": 1.1, "peak_mb": 5.0, "cpu_ratio": 1.9},
                      "opengl": {"total_s": 0.25}},
           "ratio_gl": 4.0, "ratio_eevee": None, "errors": {}}
    text = bench.format_table([res])
    assert "4.0x" in text and "S1" in text
    assert bench.targets([res], quick=True)[0][2] is True  # 4x <= 8x


def test_write_doc_replaces_only_the_results_section(tmp_path):
    bench = _load_module()
    doc = tmp_path / "benchmark.md"
    doc.write_text(f"# B\n\nmethod\n\n{bench.RESULTS_START}\nold\n{bench.RESULTS_END}\n\nafter\n")
    case = dict(id="S4", group="S4", width=4, height=2)
    res = {"case": case, "setup": {"project": {"triangles": 1_000_000, "covered_px": 3}},
           "median": {"project": {"extract_s": 0.1, "render_s": 1.0, "total_s": 1.1, "peak_mb": 5.0, "cpu_ratio": 1.9}},
           "ratio_gl": None, "ratio_eevee": None, "errors": {}}
    env = {"command": "python scripts/benchmark.py", "processor": "CPU", "cpus": 2, "python": "3", "numpy": "1",
           "repeats": 3, "elapsed_s": 60.0}
    tg = bench.targets([res], quick=False)
    bench.write_doc(doc, [res], env, {}, tg, None)
    text = doc.read_text()
    assert text.startswith("# B\n\nmethod\n") and text.rstrip().endswith("after")
    assert "old" not in text and "| S4 | 1.00M |" in text and "under 0.3 s | 0.100 s | yes" in text
