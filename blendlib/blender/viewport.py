"""The viewport's Rendered shading, Blender's side: a view's matrices → Camera, a region → its view.

- :func:`camera_from_matrices` / :func:`render_view`: a Frame through any 4x4 view and
  projection matrices (the viewport's own view, README: Viewport, animations, render farms).
- :func:`region_view`: what a 3D viewport region shows (through the scene camera in camera
  view, the camera frame only; otherwise the region's view and window matrices).
- :func:`extract_template`: the scene as the viewport shows it, camera left open.

Only :func:`render_view`, :func:`region_view` and :func:`extract_template` touch bpy (imported
inside them), on the main thread. Rendering off the main thread is
:class:`blendlib.runtime.scheduler.ViewportScheduler`'s, on the bpy-free values these give.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Hashable
from typing import Any

import numpy as np

from ..core import pipeline
from ..core.records import Frame
from ..core.scene import Camera, DrawScene, SceneError, affine_inverse, reuse_unchanged

#: The camera the viewport template is extracted with; each view's camera replaces it
#: (``dataclasses.replace(template, camera=...)``).
PLACEHOLDER_CAMERA = Camera(view_matrix=np.eye(4), projection=np.eye(4), width=1, height=1)


def as_matrix(m: Any, name: str) -> np.ndarray:
    """A 4x4 float64 array of a ``mathutils.Matrix`` or anything numpy accepts; SceneError otherwise."""
    if not hasattr(m, "row") and np.iscomplexobj(m):  # float64 would drop the imaginary parts unsaid
        raise SceneError(f"{name}: must be a real 4x4 matrix, got complex values")
    try:
        arr = np.array([list(row) for row in m], dtype=np.float64) if hasattr(m, "row") else \
            np.asarray(m, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(f"{name}: not a 4x4 matrix") from None
    if arr.shape != (4, 4) or not np.all(np.isfinite(arr)):
        raise SceneError(f"{name}: must be a finite 4x4 matrix, got shape {arr.shape}")
    return arr


def determinant4(m: np.ndarray) -> float:
    """The determinant of a 4x4 matrix by its 2x2 minors (no LAPACK call, see
    :func:`blendlib.core.scene.affine_inverse`)."""
    a = [[float(x) for x in row] for row in np.asarray(m, np.float64)]
    s0, s1, s2 = (a[0][0] * a[1][k] - a[1][0] * a[0][k] for k in (1, 2, 3))
    s3 = a[0][1] * a[1][2] - a[1][1] * a[0][2]
    s4 = a[0][1] * a[1][3] - a[1][1] * a[0][3]
    s5 = a[0][2] * a[1][3] - a[1][2] * a[0][3]
    c5 = a[2][2] * a[3][3] - a[3][2] * a[2][3]
    c4 = a[2][1] * a[3][3] - a[3][1] * a[2][3]
    c3 = a[2][1] * a[3][2] - a[3][1] * a[2][2]
    c2 = a[2][0] * a[3][3] - a[3][0] * a[2][3]
    c1 = a[2][0] * a[3][2] - a[3][0] * a[2][2]
    c0 = a[2][0] * a[3][1] - a[3][0] * a[2][1]
    return s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0


def is_orthographic(projection: np.ndarray) -> bool:
    """A projection whose bottom row is (0, 0, 0, 1) is orthographic (w stays 1)."""
    return bool(np.array_equal(np.asarray(projection, np.float64)[3], [0.0, 0.0, 0.0, 1.0]))


def camera_from_matrices(view_matrix: Any, projection_matrix: Any, width: int, height: int) -> Camera:
    """The :class:`Camera` of a view: world → view ``view_matrix``, view → clip ``projection_matrix``.

    The sort position is the inverse view matrix's translation (:attr:`Camera.position`);
    orthographic when the projection's bottom row is (0, 0, 0, 1); near/far are those
    the projection encodes; pixel aspect 1.
    """
    view = as_matrix(view_matrix, "view_matrix")
    proj = as_matrix(projection_matrix, "projection_matrix")
    if isinstance(width, bool) or isinstance(height, bool) or not (
            isinstance(width, (int, np.integer)) and isinstance(height, (int, np.integer))):
        raise SceneError(f"view size must be integers, got {width!r}x{height!r}")
    try:
        affine_inverse(view)  # no LAPACK here: see affine_inverse
    except np.linalg.LinAlgError:
        raise SceneError("view_matrix is singular") from None
    if determinant4(proj) == 0.0:  # e.g. all zero: every vertex lands on one point, nothing is drawn
        raise SceneError("projection_matrix is singular (all zero, or rows that depend on each other): "
                         "a view through it shows nothing")
    return Camera(view_matrix=view, projection=proj, width=int(width), height=int(height),
                  orthographic=is_orthographic(proj))


def extract_template(scene: Any = None, depsgraph: Any = None, previous: DrawScene | None = None) -> DrawScene:
    """The scene as the viewport shows it (viewport visibility and modifiers), camera left open.

    The returned DrawScene carries :data:`PLACEHOLDER_CAMERA`; put a view's camera in with
    ``dataclasses.replace(template, camera=...)``. ``previous``: the template extracted before;
    its unchanged textures, materials, meshes and renderers are reused (:func:`reuse_unchanged`),
    so what frames derived from them (memos, the band helper's copy) carries over. Runs on the
    main thread (bpy).
    """
    from .extract import build_draw_scene

    template = build_draw_scene(scene, depsgraph, camera=PLACEHOLDER_CAMERA, visibility="viewport")
    return reuse_unchanged(template, previous)


def render_view(scene: Any, view_matrix: Any, projection_matrix: Any, width: int, height: int, *,
                depsgraph: Any = None, progress: Callable[[float], None] | None = None,
                should_cancel: Callable[[], bool] | None = None) -> Frame:
    """Render ``scene`` (a ``bpy.types.Scene``, its name; None: the context scene) through a view's
    4x4 matrices (real and finite; a singular projection is an error).

    Returns the :class:`Frame` a camera with those matrices would give at ``width`` x ``height``
    (see :func:`camera_from_matrices`), with objects and modifiers as the viewport shows them.
    The scene needs no camera, and its camera, resolution and frame are left unchanged.
    """
    from .files import scene_arg

    camera = camera_from_matrices(view_matrix, projection_matrix, width, height)
    draw = dataclasses.replace(extract_template(scene_arg(scene), depsgraph), camera=camera)
    frame = pipeline.render_scene(draw, progress=progress, should_cancel=should_cancel)
    frame.warnings[:0] = [w for w in draw.warnings if w not in frame.warnings]
    return frame


# ---------------------------------------------------------------------------------------------
# What a viewport region shows
# ---------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class ViewRequest:
    """One view of a viewport region: the camera to render and where to draw it.

    ``x``, ``y``, ``width``, ``height``: the rectangle in region pixels (origin bottom-left) the
    frame covers — the whole region, or the camera frame in camera view. ``key``: hashable,
    equal for equal views (a changed key means the view changed).
    """

    camera: Camera
    x: int
    y: int
    width: int
    height: int

    @property
    def key(self) -> Hashable:
        c = self.camera
        return (c.view_matrix.tobytes(), c.projection.tobytes(), c.width, c.height, self.x, self.y)


def free_view(view_matrix: Any, window_matrix: Any, width: int, height: int) -> ViewRequest:
    """The region's own view: its view matrix and window (projection) matrix, which carries the
    viewport's clip start/end, over the whole region."""
    width, height = max(int(width), 1), max(int(height), 1)
    return ViewRequest(camera_from_matrices(view_matrix, window_matrix, width, height), 0, 0, width, height)


def camera_frame_rect(frame_corners_world: np.ndarray, perspective_matrix: Any, width: int,
                      height: int) -> tuple[int, int, int, int]:
    """(x, y, w, h) in region pixels of the camera frame whose four world-space corners are given
    (``Camera.view_frame`` transformed by the camera's world matrix), as the region shows it
    through ``perspective_matrix`` (window @ view) at ``width`` x ``height``."""
    pm = as_matrix(perspective_matrix, "perspective_matrix")
    pts = np.c_[np.asarray(frame_corners_world, np.float64), np.ones(len(frame_corners_world))] @ pm.T
    w = np.where(np.abs(pts[:, 3]) < 1e-12, 1e-12, pts[:, 3])
    px = (pts[:, 0] / w * 0.5 + 0.5) * width
    py = (pts[:, 1] / w * 0.5 + 0.5) * height
    x0, x1 = math.floor(px.min() + 0.5), math.floor(px.max() + 0.5)
    y0, y1 = math.floor(py.min() + 0.5), math.floor(py.max() + 0.5)
    return x0, y0, max(x1 - x0, 1), max(y1 - y0, 1)


#: A zoomed-in camera frame larger than the region renders at most this many times the region's size.
MAX_CAMERA_FRAME_SCALE = 2.0


def region_view(scene: Any, depsgraph: Any, region: Any, region_data: Any) -> ViewRequest:
    """What a 3D viewport region shows: through the scene camera in camera view (the camera frame
    only, with the camera's own projection as F12 computes it), else the region's view.

    ``region`` needs ``width``/``height``; ``region_data`` ``view_matrix``, ``window_matrix``,
    ``perspective_matrix`` and ``view_perspective`` (a ``bpy.types.RegionView3D`` has them).
    """
    width, height = max(int(region.width), 1), max(int(region.height), 1)
    cam_obj = getattr(scene, "camera", None)
    if region_data.view_perspective != "CAMERA" or cam_obj is None or cam_obj.type != "CAMERA":
        return free_view(region_data.view_matrix, region_data.window_matrix, width, height)
    from .extract import _matrix, render_size

    cam_eval = cam_obj.evaluated_get(depsgraph)
    world = _matrix(cam_eval.matrix_world)
    corners = np.array([list(v) for v in cam_eval.data.view_frame(scene=scene)], np.float64)
    corners_world = (np.c_[corners, np.ones(4)] @ world.T)[:, :3]
    x, y, w, h = camera_frame_rect(corners_world, region_data.perspective_matrix, width, height)
    scale = min(1.0, MAX_CAMERA_FRAME_SCALE * width / w, MAX_CAMERA_FRAME_SCALE * height / h)
    rw, rh = max(int(w * scale), 1), max(int(h * scale), 1)
    r = scene.render
    rx, ry = render_size(scene)
    proj = cam_eval.calc_matrix_camera(depsgraph, x=rx, y=ry, scale_x=float(r.pixel_aspect_x),
                                       scale_y=float(r.pixel_aspect_y))
    camera = Camera(view_matrix=affine_inverse(world), projection=_matrix(proj), width=rw, height=rh,
                    orthographic=cam_eval.data.type == "ORTHO")
    return ViewRequest(camera, x, y, w, h)
