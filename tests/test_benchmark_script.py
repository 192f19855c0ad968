"""The benchmark (``python -m scripts.benchmark``, the package scripts/benchmark/): a --quick run on
tiny sizes prints every table and writes sane values for every series; its tables, targets, doc
writing, plot and host probes on made-up results. Not a timed test: no figure is checked against
a target."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from scripts.benchmark import cases, cli, host, plot, report, tables, targets

REPO = Path(__file__).resolve().parent.parent

pytest.importorskip("bpy")


def _by_measure(tg) -> dict:
    return {t.measure: (t.limit, t.figure, t.met) for t in tg}


def test_quick_run_prints_the_table(tmp_path):
    out_json = tmp_path / "bench.json"
    out_png = tmp_path / "bench.png"
    blend_dir = tmp_path / "blend"
    blend_dir.mkdir()
    shutil.copy(REPO / "blend_files" / "alpha_blend.blend", blend_dir)  # one S3 scene is enough here
    backends = "project,workbench"
    try:
        import moderngl  # noqa: F401

        backends = "project,opengl,workbench"
    except ImportError:
        pass
    cmd = [sys.executable, "-m", "scripts.benchmark", "--quick", "--scenes", "S1,S2,S2p,S3,S4", "--backends", backends,
           "--repeats", "1", "--json", str(out_json), "--plot", str(out_png), "--log", str(tmp_path / "w.log"),
           "--blend-dir", str(blend_dir)]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr + (tmp_path / "w.log").read_text()
    out = proc.stdout
    header = next(line for line in out.splitlines() if line.startswith("scene "))
    for column in ("scene", "tris", "size", "extract s", "render s", "project s", "OpenGL s", "EEVEE s",
                   "Workbench s", "proj/GL", "proj/EEVEE", "spread proj/GL", "peak MB", "CPU"):
        assert column in header
    ids = ("S1", "S2", "S2p", "S3:alpha_blend", "S4")
    rows = {line.split()[0] for line in out.splitlines() if line.split()[:1] and line.split()[0] in ids}
    assert rows == set(ids)
    for title in ("Frame debugger", "Viewport", "Targets (QUICK sizes: not the real targets):",
                  "S2p render / OpenGL (llvmpipe) <= 1x: ", "S2 analyze peak memory at 480x270 < 2 GB: "):
        assert title in out
    assert "load average (1, 5, 15 min)" in out
    assert "CPU time the virtual machine's host took (steal) during the run:" in out
    assert "host speed probe: " in out
    data = json.loads(out_json.read_text())
    assert len(data["env"]["loadavg"]) == 2 and all(len(v) == 3 for v in data["env"]["loadavg"])
    probes = data["env"]["speed_probe_ms"]
    assert len(probes) == 1 + len(data["results"]) and all(0 < v < 10_000 for v in probes)  # start + per scene
    by_id = {r["case"]["id"]: r for r in data["results"]}
    assert by_id["S1"]["setup"]["project"]["triangles"] == 4 * 71 * 71  # the quick sphere, 2k segments k+1 rings
    assert by_id["S4"]["setup"]["project"]["triangles"] == 62976  # Suzanne, subdivision level 3
    assert by_id["S2p"]["setup"]["project"]["triangles"] == 20  # 10 planes of one quad
    for r in by_id.values():
        med = r["median"]["project"]
        assert med["render_s"] > 0 and med["extract_s"] > 0 and med["peak_mb"] >= 0
        assert not r["errors"], r["errors"]
    # S1 fills about a third of the frame; S2p's planes, each most of the frame, cover more than S2's.
    s1 = by_id["S1"]
    assert abs(s1["setup"]["project"]["covered_px"] / (480 * 270) - 1 / 3) < 0.02
    assert by_id["S2p"]["setup"]["project"]["covered_px"] > 0.9 * 480 * 270

    # Frame debugger and sorted reference: S1, S2, S2p and S3, not S4.
    assert {i for i, r in by_id.items() if "explain" in r} == {"S1", "S2", "S2p", "S3:alpha_blend"}
    for r in (by_id["S1"], by_id["S2"], by_id["S2p"], by_id["S3:alpha_blend"]):
        e = r["explain"]
        assert e["size"] == [r["case"]["width"], r["case"]["height"]]
        for key in ("plain_s", "drawlist_s", "pixel_s", "capture_s", "step_s", "analyze_s", "advised_s"):
            assert e[key] > 0, key
        for key in ("drawlist_ratio", "pixel_ratio", "capture_ratio", "step_ratio", "analyze_ratio",
                    "advised_ratio"):
            assert e[key] == pytest.approx(e[key.replace("_ratio", "_s")] / e["plain_s"])
        assert e["advice_over_analyze"] == pytest.approx(e["advised_s"] / e["analyze_s"])
        assert e["advice_items"] <= min(5, e["inversion_pairs"])
        assert "forward_add" not in e  # none of these scenes has a ForwardAdd pass
        assert 0 < e["plain_peak_mb"] and e["capture_peak_mb"] >= e["snapshot_mb"] and e["analyze_peak_mb"] > 0
        # snapshots after every interval-th draw but the last (the final frame is kept anyway)
        assert e["interval"] >= 1 and e["snapshots"] == (e["draws"] - 1) // e["interval"]
        assert (e["snapshot_mb"] > 0) == (e["snapshots"] > 0)
        assert 0 <= e["step_from"] < e["step_to"] <= e["draws"] and e["step_to"] == -(-e["draws"] // 2)
        assert e["pixel"] == [e["size"][0] // 2, e["size"][1] // 2]
    s2 = by_id["S2"]["explain"]
    # 10 planes, each exactly half of the 480x270 frame, ZWrite Off over a cleared depth: all written.
    assert s2["draws"] == 10 and s2["fragments"] == s2["written"] == 10 * 480 * 270 // 2
    assert 1 <= s2["pixel_fragments"] <= 10
    assert by_id["S1"]["explain"]["draws"] == 1 and by_id["S1"]["explain"]["step_to"] == 1

    # Viewport: the S3 scene at the quick size, reduced frame 1/4 per side.
    assert {i for i, r in by_id.items() if "viewport" in r} == {"S3:alpha_blend"}
    v = by_id["S3:alpha_blend"]["viewport"]
    assert v["size"] == [320, 180] and v["reduced_size"] == [80, 45] and v["runs"] == 5
    for key in ("extract_s", "reduced_s", "full_s", "full_one_process_s", "first_frame_s", "render_view_s",
                "scheduler_first_s", "scheduler_full_s"):
        assert 0 < v[key] < 60, key
    assert v["helper_failure"] is None  # the band helper started (quick frames are too small to split)
    assert v["scheduler_full_s"] >= v["scheduler_first_s"]
    measures = {t["measure"] for t in data["targets"]}
    assert {"S1 render / OpenGL (llvmpipe)", "every S3 scene: draw list / plain render",
            "every S3 scene and S5: first frame after a change, through the scheduler"} <= measures
    assert all(set(t) == {"measure", "limit", "figure", "met"} for t in data["targets"])

    from blendlib.formats import images

    plot = images.load(out_png)  # scenes, frame debugger, viewport: 3 x 16/3 by 5 inches at 80 dpi, not blank
    assert plot.shape == (400, 1280, 4) and plot[..., :3].std() > 0.05


def test_running_the_folder_by_path_says_how_to_run_it():
    # ``python scripts/benchmark`` runs the package's __main__ without the repository root on sys.path.
    proc = subprocess.run([sys.executable, str(REPO / "scripts" / "benchmark"), "--quick"], cwd=REPO,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and proc.stderr.strip().endswith("python -m scripts.benchmark [options]")


def test_help_lists_every_option():
    proc = subprocess.run([sys.executable, "-m", "scripts.benchmark", "--help"], cwd=REPO, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0
    for option in ("--quick", "--scenes", "--backends", "--repeats", "--json", "--plot", "--markdown", "--write-doc",
                   "--blend-dir", "--workers", "--chunk-candidates", "--profile", "--no-explain", "--from-json",
                   "--log"):
        assert option in proc.stdout
    assert "S1,S2,S2p,S3,S4,S5,S6,msaa,linear,scaling" in proc.stdout
    assert "project,opengl,eevee,workbench" in proc.stdout


def test_plot_has_one_panel_per_kind_of_figure(tmp_path):
    results = []
    for group, xkey, sizes in (("scale-tris", "triangles", (1e3, 1e4, 1e5)), ("scale-res", "covered_px", (1e4, 1e5))):
        for n in sizes:
            results.append({"case": {"group": group, "id": f"{group}-{n:g}"}, "setup": {"project": {xkey: n}},
                            "median": {"project": {"render_s": n * 1e-5, "total_s": n * 2e-5},
                                       "opengl": {"total_s": n * 1e-6}}})
    results.append({"case": {"group": "S1", "id": "S1"}, "setup": {"project": {}},
                    "median": {"project": {"total_s": 0.5}, "eevee": {"total_s": 2.0}}})
    from blendlib.formats import images

    path = plot.write_plot(results, tmp_path / "p.png", "title")
    image = images.load(path)
    assert image.shape == (400, 1280, 4)
    # each third of the figure has drawn (non-white) pixels: two line plots and the bars
    for third in np.array_split(image[40:360, :, :3], 3, axis=1):
        assert (third < 0.9).any(axis=2).mean() > 0.01
    results[-1]["explain"] = {"drawlist_ratio": 1.1, "pixel_ratio": 1.0, "capture_ratio": 1.2, "step_ratio": 0.1,
                              "analyze_ratio": 2.5}
    results[-1]["viewport"] = {"size": [960, 540], "reduced_s": 0.01, "full_s": 0.05, "scheduler_first_s": 0.02}
    image = images.load(plot.write_plot(results, tmp_path / "p5.png", "title"))
    assert image.shape == (400, 2133, 4)
    for fifth in np.array_split(image[40:360, :, :3], 5, axis=1):
        assert (fifth < 0.9).any(axis=2).mean() > 0.01


def test_table_and_slope_helpers():
    assert cases.sphere_k(200_000) == 224
    assert abs(targets.loglog_slope([1, 10, 100], [2, 20, 200]) - 1.0) < 1e-12
    case = dict(id="S1", group="S1", width=4, height=2)
    res = {"case": case, "setup": {"project": {"triangles": 10, "covered_px": 3}},
           "median": {"project": {"extract_s": 0.1, "render_s": 1.0, "total_s": 1.1, "peak_mb": 5.0, "cpu_ratio": 1.9},
                      "opengl": {"total_s": 0.25}},
           "ratio_gl": 4.0, "ratio_eevee": None, "errors": {}}
    text = tables.format_table([res])
    assert "4.0x" in text and "S1" in text
    tg = _by_measure(targets.targets([res]))
    assert tg["S1 render / OpenGL (llvmpipe)"] == ("<= 1.5x", "4.0x", False)  # issue 31: S1 within 1.5x
    res["ratio_gl"] = 1.5
    assert _by_measure(targets.targets([res]))["S1 render / OpenGL (llvmpipe)"] == ("<= 1.5x", "1.5x", True)


def test_steal_share_from_proc_stat_counters():
    #        user nice system idle iowait irq softirq steal guest
    start = [100, 0, 20, 500, 0, 0, 0, 10, 0]
    end = [400, 0, 50, 560, 0, 0, 0, 70, 0]  # 450 ticks went by, 60 of them stolen
    assert host.steal_pct(start, end) == pytest.approx(100.0 * 60 / 450)
    assert host.steal_pct(None, end) is None
    assert host.steal_pct(start, start) is None  # no time went by
    ticks = host.cpu_ticks()
    assert ticks is None or (len(ticks) >= 8 and all(t >= 0 for t in ticks))


def test_host_speed_probe_times_a_fixed_workload(monkeypatch):
    clock = iter(np.arange(0.0, 100.0, 0.5))  # each sample takes 0.5 s of the fake clock
    monkeypatch.setattr(host.time, "perf_counter", lambda: float(next(clock)))
    assert host.speed_probe_ms(samples=3) == pytest.approx(500.0)
    text = host.format_probes([20.0, 31.5, 23.0])
    assert text.startswith("23.0 ms median, 20.0–31.5 ms over 3 samples")


def test_targets_of_the_frame_debugger_sorted_reference_and_viewport():

    def result(sid, group, ratio_gl, explain=None, viewport=None):
        r = {"case": dict(id=sid, group=group, width=1920, height=1080), "setup": {"project": {}},
             "median": {}, "ratio_gl": ratio_gl, "ratio_eevee": None, "errors": {}}
        if explain:
            r["explain"] = dict(size=[1920, 1080], snapshots=19, snapshot_mb=500.0, capture_peak_mb=900.0,
                                analyze_peak_mb=2100.0, **explain)
        if viewport:
            r["viewport"] = dict(size=[960, 540], **viewport)
        return r

    results = [
        result("S2", "S2", 3.5, explain=dict(drawlist_ratio=1.1, pixel_ratio=1.3, step_ratio=0.2, analyze_ratio=2.9)),
        result("S2p", "S2p", 2.9),
        result("S3:a", "S3", 3.0, explain=dict(drawlist_ratio=1.0, pixel_ratio=1.0, step_ratio=0.5, analyze_ratio=1.5),
               viewport=dict(full_s=0.040, reduced_s=0.010, extract_s=0.002, scheduler_first_s=0.015,
                             full_view_s=0.045, reduced_view_s=0.022)),  # the view change is slower
        result("S3:b", "S3", 4.5, explain=dict(drawlist_ratio=1.2, pixel_ratio=1.0, step_ratio=0.4, analyze_ratio=3.2),
               viewport=dict(full_s=0.070, reduced_s=0.025, extract_s=0.002, scheduler_first_s=0.080)),
    ]
    tg = _by_measure(targets.targets(results))
    assert tg["S2 render / OpenGL (llvmpipe)"] == ("<= 1x", "3.5x", False)
    assert tg["S2p render / OpenGL (llvmpipe)"] == ("<= 1x", "2.9x", False)
    assert tg["every S3 scene: render / OpenGL (llvmpipe)"] == (
        "<= 2x", "worst 4.5x (S3:b); range 3.0x–4.5x; 0 of 2 met", False)
    assert tg["S2: pixel history / plain render"] == ("<= 1.2x", "1.3x", False)
    assert tg["every S3 scene: draw list / plain render"][2] is True
    assert tg["S2 capture peak memory at 1920x1080"] == ("< 2 GB", "900 MB (19 snapshots, 500 MB)", True)
    assert tg["S2: analyze / plain render"] == ("<= 15x", "2.9x", True)  # fill-heavy: 15x
    assert tg["every S3 scene: analyze / plain render"] == (
        "<= 3x", "worst 3.2x (S3:b); range 1.5x–3.2x; 1 of 2 met", False)
    assert tg["S2 analyze peak memory at 1920x1080"] == ("< 2 GB", "2100 MB", False)
    full = "every S3 scene and S5: viewport full frame at 960x540, median after an edit or a view change"
    reduced = "every S3 scene and S5: viewport reduced frame (1/4 per side), median after an edit or a view change"
    assert tg[full] == ("<= 33 ms", "worst 70 ms (S3:b); range 45 ms–70 ms; 0 of 2 met", False)
    # S3:a's reduced frame is within 10 ms after an edit, not after a view change; S3:b has no view figures.
    assert tg[reduced] == ("<= 10 ms", "worst 25 ms (S3:b); range 22 ms–25 ms; 0 of 2 met", False)
    # S3:b's first frame (80 ms) comes later than its full frame plus extraction (72 ms).
    assert tg["every S3 scene and S5: first frame after a change, through the scheduler"] == (
        "<= full frame + extraction", "worst S3:b: 80 ms vs 72 ms", False)
    # No S1/S4 results, no EEVEE figures, no scaling series: none of their targets.
    assert not [m for m in tg if m.startswith(("S1", "S4", "render time vs")) or "EEVEE" in m]


def test_targets_of_advice_forward_add_and_steadiness():
    def result(sid, project, opengl, explain=None):
        r = {"case": dict(id=sid, group="S3", width=1280, height=720), "setup": {"project": {}}, "median": {},
             "ratio_gl": None, "ratio_eevee": None, "errors": {},
             "runs": {"project": [{"render_s": v} for v in project], "opengl": [{"total_s": v} for v in opengl]}}
        if explain:
            r["explain"] = explain
        return r

    results = [
        # project 0.9..1.1 around 1.0: spread 20 %; OpenGL 0.45..0.55 around 0.5: 20 % -> met (equal)
        result("S3:a", [1.0, 0.9, 1.1], [0.5, 0.45, 0.55],
               explain=dict(advice_over_analyze=1.5, inversion_pairs=2,
                            forward_add=[dict(renderer="Glass[0]", base_s=0.010, add_s=0.012, ratio=1.2),
                                         dict(renderer="Stone[0]", base_s=0.020, add_s=0.010, ratio=0.5)])),
        # 30 % against OpenGL's 10 %: missed; its advice ratio does not count (no inversion pairs)
        result("S3:b", [1.0, 0.85, 1.15], [0.5, 0.48, 0.53], explain=dict(advice_over_analyze=9.0, inversion_pairs=0)),
        result("S3:c", [2.0], [1.0], explain=dict(advice_over_analyze=2.5, inversion_pairs=1)),  # one run: no spread
    ]
    tg = _by_measure(targets.targets(results))
    assert tg["render time spread over the repeats ((max - min) / median) vs OpenGL's, per scene"] == (
        "<= OpenGL's", "1 of 2 met; worst S3:b: 30% vs 10%", False)
    assert tg["every explained scene with inversions: analyze with advice (5 pairs) / analyze without it"] == (
        "<= 2x", "worst 2.5x (S3:c); range 1.5x–2.5x; 1 of 2 met", False)
    assert tg["each ForwardAdd draw / its renderer's ForwardBase draw (one thread)"] == (
        "<= 1x", "worst 1.2x (S3:a Glass[0]); range 0.50x–1.2x; 1 of 2 met", False)
    assert tables.fmt_spreads(0.2, None) == "20%/-"


def test_forward_add_prices_time_each_forwardadd_draw_against_its_base_pass():
    import bpy

    from blendlib import blender
    from scripts.benchmark.workers import forward_add_prices

    bpy.ops.wm.open_mainfile(filepath=str(REPO / "blend_files" / "lights.blend"), load_ui=False)
    scene = bpy.data.scenes["Lights"]
    scene.render.resolution_x, scene.render.resolution_y = 320, 180
    draw = blender.build_draw_scene(scene)
    prices = forward_add_prices(draw, 1)
    # blend_files/lights.blend: three materials with a ForwardAdd pass on four objects (the floor and the
    # wall share 'Stone'); each has a ForwardBase draw and one ForwardAdd draw per per-pixel light.
    assert [p["renderer"] for p in prices] == ["Floor[0]", "Glass Sphere[0]", "Glow Torus[0]", "Wall[0]"]
    for p in prices:
        assert p["base_s"] > 0 and p["add_s"] > 0 and p["ratio"] == pytest.approx(p["add_s"] / p["base_s"])


def test_write_doc_replaces_only_the_results_section(tmp_path):
    doc = tmp_path / "benchmark.md"
    doc.write_text(f"# B\n\nmethod\n\n{report.RESULTS_START}\nold\n{report.RESULTS_END}\n\nafter\n")
    case = dict(id="S4", group="S4", width=4, height=2)
    res = {"case": case, "setup": {"project": {"triangles": 1_000_000, "covered_px": 3}},
           "median": {"project": {"extract_s": 0.1, "render_s": 1.0, "total_s": 1.1, "peak_mb": 5.0, "cpu_ratio": 1.9}},
           "ratio_gl": None, "ratio_eevee": None, "errors": {}}
    env = {"command": "python -m scripts.benchmark", "processor": "CPU", "cpus": 2, "python": "3", "numpy": "1",
           "repeats": 3, "elapsed_s": 60.0}
    tg = targets.targets([res])
    report.write_doc(doc, [res], env, {}, tg, None)
    text = doc.read_text()
    assert text.startswith("# B\n\nmethod\n") and text.rstrip().endswith("after")
    assert "old" not in text and "| S4 | 1.00M |" in text
    assert "| S4 extraction of the 1.00M-triangle evaluated mesh | < 0.3 s | 0.100 s | yes |" in text


def test_from_json_prints_and_writes_a_saved_run_without_running_it(tmp_path, capsys):
    case = dict(id="S2", group="S2", width=1920, height=1080, explain=True)
    explain = dict(size=[1920, 1080], draws=50, fragments=51_840_000, written=51_840_000, plain_s=2.0,
                   drawlist_ratio=1.05, pixel_ratio=1.0, capture_ratio=1.4, step_ratio=0.05, step_to=25, step_from=24,
                   analyze_ratio=2.5, plain_peak_mb=140.0, capture_peak_mb=560.0, analyze_peak_mb=1000.0,
                   snapshots=16, snapshot_mb=411.0)
    viewport = dict(size=[960, 540], extract_s=0.004, reduced_s=0.015, full_s=0.050, reduced_view_s=0.017,
                    full_view_s=0.052, full_one_process_s=0.081, first_frame_s=0.019,
                    render_view_s=0.055, scheduler_first_s=0.021, scheduler_full_s=0.072)
    res = {"case": case, "setup": {"project": {"triangles": 100, "covered_px": 2_000_000, "first_s": 2.5}},
           "median": {"project": {"extract_s": 0.01, "render_s": 2.0, "total_s": 2.01, "peak_mb": 140.0,
                                  "cpu_ratio": 1.8}, "opengl": {"total_s": 0.8}},
           "ratio_gl": 2.5, "ratio_eevee": None, "errors": {}, "explain": explain,
           "viewport": viewport}
    env = {"command": "python -m scripts.benchmark --scenes S2", "processor": "CPU", "cpus": 2, "python": "3",
           "numpy": "1", "repeats": 3, "elapsed_s": 120.0, "quick": False, "loadavg": [[5.9, 4.7, 4.7], [4, 4.5, 4.7]]}
    saved = tmp_path / "run.json"
    saved.write_text(json.dumps({"env": env, "results": [res]}))
    doc = tmp_path / "benchmark.md"
    assert cli.main(["--from-json", str(saved), "--write-doc", str(doc)]) == 0
    out = capsys.readouterr().out
    assert "[MISS] S2 render / OpenGL (llvmpipe) <= 1x: 2.5x" in out
    assert "[ok] S2: analyze / plain render <= 15x: 2.5x" in out
    assert "5.9, 4.7, 4.7 at the start" in out
    text = doc.read_text()
    assert text.startswith(f"# Benchmark\n\n{report.RESULTS_START}\nCommand: `python -m scripts.benchmark --scenes S2`")
    assert ("| S2 | 1920x1080 | 50 | 51.84M | 2.00 | 1.1x | 1.0x | 1.4x | 0.050x (25<-24) | 2.5x | - "
            "| 140 | 560 | 1000 |" in text)
    assert "| S2 | 960x540 | 4.0 | 15.0 | 50.0 | 17.0 | 52.0 | 81.0 | 19.0 | 55.0 | 21.0 | 72.0 |" in text
    assert "| S2 capture peak memory at 1920x1080 | < 2 GB | 560 MB (16 snapshots, 411 MB) | yes |" in text
    assert "Load average (1, 5, 15 min) at the start 5.9, 4.7, 4.7, at the end 4.0, 4.5, 4.7 on 2 CPUs" in text


def test_s5_s6_and_msaa_cases():
    """S5 is the avatar example's first scene with the viewport series; S6 the particle scene; the
    msaa group S1 and S2 again with 4 samples, each naming the scene it is priced against."""
    planned = {c["id"]: c for c in cases.plan_cases("S5,S6,msaa")}
    assert list(planned) == ["S5", "S6", "S1 4x", "S2 4x"]
    s5 = planned["S5"]
    assert s5["kind"] == "blend" and Path(s5["path"]).name == "vrm_avatar.blend" and s5["scene"] == "Avatar"
    assert (s5["width"], s5["height"]) == (1920, 1080) and s5["viewport"] == [960, 540] and s5["explain"]
    assert planned["S6"]["count"] == 20_000 and planned["S6"]["explain"]
    for sid in ("S1", "S2"):
        m = planned[f"{sid} 4x"]
        assert m["msaa"] == 4 and m["base"] == sid and m["group"] == "msaa" and "explain" not in m
    tg = targets.targets([
        dict(case=dict(id="S1", group="S1", width=8, height=8), ratio_gl=None, ratio_eevee=None, setup={},
             median={"project": dict(render_s=0.5, extract_s=0.1, peak_mb=1.0, cpu_ratio=1.0)}),
        dict(case=dict(id="S1 4x", group="msaa", base="S1", width=8, height=8), ratio_gl=None, ratio_eevee=None,
             setup={}, median={"project": dict(render_s=2.5, extract_s=0.1, peak_mb=1.0, cpu_ratio=1.0)}),
    ])
    assert _by_measure(tg)["S1 4x render / S1 render"] == ("<= 4x", "5.0x", False)


def test_linear_cases_are_s5_and_s6_in_linear_colour_space():
    """The linear group: S5 and S6 again in Unity's Linear colour space (render only), and a built
    case's DrawScene is Linear."""
    from blendlib import blender
    from blendlib.core.vocabulary import ColorSpace
    from scripts.benchmark import scenes

    planned = {c["id"]: c for c in cases.plan_cases("linear")}
    assert list(planned) == ["S5 linear", "S6 linear"]
    for sid, case in zip(("S5", "S6"), planned.values(), strict=True):
        assert case["color_space"] == "Linear" and case["base"] == sid and case["group"] == "linear"
        assert "explain" not in case and "viewport" not in case
    scene = scenes.build_case(dict(kind="particles", count=40, width=32, height=18, color_space="Linear"))
    assert blender.build_draw_scene(scene).color_space is ColorSpace.Linear
    scene = scenes.build_case(dict(kind="particles", count=40, width=32, height=18))
    assert blender.build_draw_scene(scene).color_space is ColorSpace.Gamma


def test_particle_scene_is_unitys_legacy_particles():
    """S6's scene: two draw calls of camera-facing quads with vertex colours, drawn as Unity's
    Particles/Alpha Blended (``Blend SrcAlpha OneMinusSrcAlpha``) and Particles/Additive
    (``Blend SrcAlpha One``), both ``Cull Off Lighting Off ZWrite Off`` in the Transparent queue with
    ``2 * i.color * _TintColor * tex`` (the shaders' text); with ``msaa`` 4 the scene has 4 samples."""
    from blendlib import blender
    from blendlib.core.vocabulary import BlendFactor, Cull, Lighting, Queue, VertexColor
    from scripts.benchmark import scenes

    scene = scenes.build_case(dict(kind="particles", count=400, width=64, height=36, msaa=4))
    draw = blender.build_draw_scene(scene)
    assert draw.msaa == 4
    assert sorted(r.material.name for r in draw.renderers) == ["Particles/Additive", "Particles/AlphaBlended"]
    for r in draw.renderers:
        m, (p,) = r.material, r.material.draw_passes
        assert m.queue == Queue.Transparent.value and m.vertex_color is VertexColor.Particle
        assert m.lighting is Lighting.Unlit  # "Lighting Off" in both shaders' text
        assert p.cull is Cull.Off and not p.zwrite and p.blend and p.src_blend is BlendFactor.SrcAlpha
        additive = r.material.name.endswith("Additive")
        assert p.dst_blend is (BlendFactor.One if additive else BlendFactor.OneMinusSrcAlpha)
        colors = r.mesh.colors
        assert len(r.mesh.triangles) == 2 * 200 and colors is not None and colors.shape == (400, 3, 4)
        assert colors[..., 3].min() >= 0.29 and colors[..., 3].max() <= 1.0 and colors[..., :3].std() > 0.1
        # camera-facing: every quad's normal points at the camera (within rounding)
        tri = r.mesh.positions[r.mesh.triangles]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        to_eye = np.array([0.0, -9.0, 0.0]) - tri.mean(axis=1)
        cos = np.abs((normal * to_eye).sum(1)) / (np.linalg.norm(normal, axis=1) * np.linalg.norm(to_eye, axis=1))
        assert cos.min() > 0.999
