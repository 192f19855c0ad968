"""Stand-ins for what Blender builds only in a window: a UILayout that records what a panel draws,
and an operator instance whose job (:mod:`addon.jobs`) the test drives with timer and Esc events.

Blender builds no real UILayout in background mode, so panels' draw functions run against a
recording layout that checks what a real one would reject: every ``prop()`` must name an
RNA property of its data, every ``operator()``/``menu()`` a registered class.
"""

from __future__ import annotations

import time
from types import SimpleNamespace

import bpy


class RecordingLayout:
    """Stands in for bpy.types.UILayout; collects labels, properties, operators and menus."""

    def __init__(self, log: dict):
        self.log = log
        self.active = True
        self.enabled = True
        self.alignment = "EXPAND"
        self.use_property_split = False
        self.use_property_decorate = True

    def _child(self, *args, **kwargs):
        return RecordingLayout(self.log)

    row = column = box = split = column_flow = grid_flow = _child

    def separator(self, *args, **kwargs):
        pass

    def label(self, *, text="", **kwargs):
        self.log["labels"].append(text)

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, f"{type(data).__name__} has no property {name!r}"
        self.log["props"].append(name)

    def operator(self, idname, **kwargs):
        module, _, name = idname.partition(".")
        assert hasattr(getattr(bpy.ops, module), name), f"operator {idname} is not registered"
        self.log["operators"].append(idname)

        rna = getattr(getattr(bpy.ops, module), name).get_rna_type()

        class Properties:  # e.g. ``.direction = "UP"``: the operator must have that property
            def __setattr__(self, key, value):
                assert key in rna.properties, f"{idname} has no property {key!r}"

        return Properties()

    def menu(self, idname, **kwargs):
        assert hasattr(bpy.types, idname), f"menu {idname} is not registered"
        self.log["menus"].append(idname)

    def template_list(self, list_id, list_name, data, prop, active_data, active_prop, **kwargs):
        assert hasattr(bpy.types, list_id)
        assert prop in data.bl_rna.properties and active_prop in active_data.bl_rna.properties
        self.log["props"].append(prop)

    def template_ID(self, data, name, **kwargs):
        assert name in data.bl_rna.properties
        self.log["props"].append(name)


def draw_panel(cls, **context):
    """Run a panel's poll, draw_header and draw with a recording layout (``self`` stands in:
    Blender's struct classes cannot be instantiated outside a real region)."""
    log = {"labels": [], "props": [], "operators": [], "menus": []}
    panel = SimpleNamespace(layout=RecordingLayout(log))
    ctx = SimpleNamespace(**context)
    assert cls.poll(ctx)
    if "draw_header" in vars(cls):
        cls.draw_header(panel, ctx)
    cls.draw(panel, ctx)
    return log


class RecordingWindowManager:
    """The window manager calls a modal job operator makes (timer, progress, modal handler), recorded;
    any other attribute is the real window manager's (e.g. ``unity_sort_results``)."""

    def __init__(self):
        self.calls: list[tuple] = []

    def event_timer_add(self, interval, window=None):
        self.calls.append(("timer_add", interval))
        return "timer"

    def event_timer_remove(self, timer):
        self.calls.append(("timer_remove", timer))

    def progress_begin(self, low, high):
        self.calls.append(("progress_begin", low, high))

    def progress_update(self, value):
        self.calls.append(("progress_update", value))

    def progress_end(self):
        self.calls.append(("progress_end",))

    def modal_handler_add(self, operator):
        self.calls.append(("modal_handler_add",))
        return True

    def __getattr__(self, name):
        return getattr(bpy.context.window_manager, name)


class RecordingWorkspace:
    """``status_text_set`` recorded: the status bar's texts in order (None: cleared)."""

    def __init__(self):
        self.status: list[str | None] = []

    def status_text_set(self, text):
        self.status.append(text)


def job_context(**context) -> SimpleNamespace:
    """A context for driving a job operator by hand: a recording window manager and workspace."""
    return SimpleNamespace(window=None, window_manager=RecordingWindowManager(), workspace=RecordingWorkspace(),
                           **context)


def event(kind: str) -> SimpleNamespace:
    return SimpleNamespace(type=kind, value="PRESS")


def operator_probe(cls, **properties):
    """An instance of ``cls``'s own Python behaviour and its mixins' (``invoke``, ``modal``,
    ``job_done``, ...) without Blender's struct base, which cannot be instantiated outside an
    operator call; ``report()`` appends ``(kind, message)`` to ``.reports``."""
    namespace = {}
    for base in reversed(cls.__mro__):
        if base is cls or not issubclass(base, bpy.types.bpy_struct):
            namespace.update({k: v for k, v in vars(base).items() if not k.startswith("__") and k != "bl_rna"})

    def report(self, kinds, message):
        self.reports.append((next(iter(kinds)), message))

    namespace["report"] = report
    probe = type(f"{cls.__name__}Probe", (), namespace)()
    probe.reports = []
    for name, value in properties.items():
        setattr(probe, name, value)
    return probe


def run_modal(operator, context, timeout: float = 30.0) -> set[str]:
    """Send timer events (as Blender's event timer would) until the job operator returns."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        state = operator.modal(context, event("TIMER"))
        if state != {"RUNNING_MODAL"}:
            return state
        time.sleep(0.01)
    raise AssertionError("the job did not finish")
