"""The Flamenco job type (farm/flamenco/unity_passes_render.js) under node against a stand-in of
Flamenco's job-compiler API (tests/farm/author_stub.js), and the engine guard with bpy."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
JOB_TYPE = ROOT / "farm" / "flamenco" / "unity_passes_render.js"
STUB = Path(__file__).with_name("author_stub.js")
GUARD = ROOT / "farm" / "check_engine.py"
NODE = shutil.which("node")

SETTINGS = {"frames": "1-10", "chunk_size": 4, "render_output_path": "/render/shot/{timestamp}/######",
            "blendfile": "/shared/shot.blend", "format": "PNG", "image_file_extension": ".png"}


def compile_job(tmp_path, **changes) -> tuple[int, dict]:
    if NODE is None:
        pytest.skip("node is not installed (the job type is JavaScript for Flamenco Manager)")
    job = tmp_path / "job.json"
    job.write_text(json.dumps({"settings": {**SETTINGS, **changes}, "created": "2025-01-02T03:04:05Z"}))
    proc = subprocess.run([NODE, str(STUB), str(JOB_TYPE), str(job)], capture_output=True, text=True, timeout=60)
    assert proc.returncode in (0, 3), proc.stderr
    return proc.returncode, json.loads(proc.stdout)


def test_check_task_first_then_render_chunks(tmp_path):
    code, out = compile_job(tmp_path)
    assert code == 0
    assert out["job_type"]["label"] == "Unity Passes Render"
    tasks = out["tasks"]
    assert [t["name"] for t in tasks] == ["check-unity-passes", "render-1-4", "render-5-8", "render-9,10"]
    check, *renders = tasks
    assert check["type"] == "blender" and check["dependencies"] == []
    (cmd,) = check["commands"]
    assert cmd["type"] == "blender-render"
    assert cmd["parameters"]["blendfile"] == "/shared/shot.blend"
    args = cmd["parameters"]["args"]
    assert args[:3] == ["--python-exit-code", "1", "--python-expr"] and "UNITY_PASSES" in args[3]
    assert "--render-frame" not in args  # the check renders nothing
    output = "/render/shot/20250102-030405/######"
    assert out["settings"]["render_output_path"] == output
    for task, frames in zip(renders, ("1..4", "5..8", "9,10"), strict=True):
        assert task["dependencies"] == ["check-unity-passes"]
        (cmd,) = task["commands"]
        p = cmd["parameters"]
        assert (cmd["type"], p["exe"], p["exeArgs"], p["blendfile"]) == \
            ("blender-render", "{blender}", "{blenderArgs}", "/shared/shot.blend")
        # engine first, the same check before any frame, then the render of this chunk
        assert p["args"] == ["--engine", "UNITY_PASSES", *args,
                             "--render-output", output, "--render-format", "PNG", "--render-frame", frames]


@pytest.mark.parametrize("frames,chunk,expected", [
    ("1-3", 1, ["1", "2", "3"]),
    ("1-3,7,9-20", 5, ["1-3,7,9", "10-14", "15-19", "20"]),
    ("47", 10, ["47"]),
])
def test_chunking(tmp_path, frames, chunk, expected):
    _, out = compile_job(tmp_path, frames=frames, chunk_size=chunk)
    assert [t["name"] for t in out["tasks"]] == ["check-unity-passes"] + [f"render-{c}" for c in expected]
    assert [t["commands"][0]["parameters"]["args"][-1] for t in out["tasks"][1:]] == \
        [c.replace("-", "..") for c in expected]


def test_guard_script_path_setting(tmp_path):
    _, out = compile_job(tmp_path, engine_check="/shared/farm/check_engine.py")
    for task in out["tasks"]:
        args = task["commands"][0]["parameters"]["args"]
        i = args.index("--python-exit-code")
        assert args[i:i + 4] == ["--python-exit-code", "1", "--python", "/shared/farm/check_engine.py"]


@pytest.mark.parametrize("changes,text", [({"format": "FFMPEG"}, "only renders images"),
                                          ({"chunk_size": 0}, "chunk_size"),
                                          ({"render_output_path": ""}, "render_output_path")])
def test_bad_jobs_are_refused(tmp_path, changes, text):
    code, out = compile_job(tmp_path, **changes)
    assert code == 3 and text in out["error"]


GUARD_RUN = """
import runpy, sys
sys.path.insert(0, {root!r})
import bpy
if {state!r} != "missing":
    import addon
    addon.register()
    if {state!r} == "unregistered":
        addon.unregister()  # imported, its class still exists, but not registered
if {mode!r} == "script":
    runpy.run_path({guard!r}, run_name="__main__")
else:
    exec({expr!r})
print("went on")  # Blender goes on with its command line after a passing check
"""


@pytest.mark.parametrize("mode", ["script", "inline"])
@pytest.mark.parametrize("state", ["registered", "unregistered", "missing"])
def test_engine_guard(tmp_path, mode, state):
    expr = ""
    if mode == "inline":
        _, out = compile_job(tmp_path)
        expr = out["tasks"][0]["commands"][0]["parameters"]["args"][3]
    code = GUARD_RUN.format(root=str(ROOT), state=state, mode=mode, guard=str(GUARD), expr=expr)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    if state == "registered":
        assert proc.returncode == 0, proc.stderr
        assert "the UNITY_PASSES render engine is registered" in proc.stdout and "went on" in proc.stdout
    else:
        assert proc.returncode == 1
        assert "went on" not in proc.stdout
        errors = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
        assert len(errors) == 1 and "UNITY_PASSES render engine is not registered" in errors[0]
        assert "install and enable the Unity Passes extension" in errors[0]
