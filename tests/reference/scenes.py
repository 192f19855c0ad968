"""Scene builders shared by the core and GL reference tests: cameras, meshes, renderers."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from blendlib.core.scene import Camera, DrawScene, Light, Mesh, Renderer
from blendlib.core.vocabulary import Lighting, Material, Pass, Queue


def perspective(fov_deg: float, aspect: float, near: float = 0.1, far: float = 100.0) -> np.ndarray:
    """OpenGL perspective projection (what ``calc_matrix_camera`` gives a perspective camera)."""
    f = 1.0 / math.tan(math.radians(fov_deg) / 2)
    return np.array([
        [f / aspect, 0, 0, 0],
        [0, f, 0, 0],
        [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
        [0, 0, -1, 0],
    ], dtype=np.float64)


def orthographic(width: float, height: float, near: float = 0.1, far: float = 100.0) -> np.ndarray:
    return np.array([
        [2 / width, 0, 0, 0],
        [0, 2 / height, 0, 0],
        [0, 0, -2 / (far - near), -(far + near) / (far - near)],
        [0, 0, 0, 1],
    ], dtype=np.float64)


def look_at(eye, target=(0, 0, 0), up=(0, 1, 0)) -> np.ndarray:
    """World → camera matrix of a camera at ``eye`` looking at ``target`` (camera looks down −Z)."""
    eye, target, up = (np.asarray(v, np.float64) for v in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    true_up = np.cross(back, right)
    rot = np.stack([right, true_up, back])
    view = np.eye(4)
    view[:3, :3] = rot
    view[:3, 3] = -rot @ eye
    return view


def camera(width: int = 16, height: int = 16, *, eye=(0, 0, 5), target=(0, 0, 0), fov: float = 50.0,
           ortho: float | None = None, near: float = 0.1, far: float = 100.0) -> Camera:
    """A camera at ``eye``; ``ortho`` = the orthographic view height (None: perspective)."""
    aspect = width / height
    if ortho is None:
        proj = perspective(fov, aspect, near, far)
    else:
        proj = orthographic(ortho * aspect, ortho, near, far)
    return Camera(look_at(eye, target), proj, width, height, orthographic=ortho is not None)


def screen_camera(width: int, height: int) -> Camera:
    """Orthographic camera where world x, y in [0, W] x [0, H] map to pixels (y up), z=0 at depth 0.5.

    World point (x, y, z) lands on window (x, y) with window depth ``zw = (10 - z) / 20`` for z in
    [-10, 10] (camera at z=10 looking down −Z, near 0, far 20): larger z is nearer.
    """
    view = np.eye(4)
    view[2, 3] = -10.0
    view[0, 3] = -width / 2
    view[1, 3] = -height / 2
    proj = orthographic(width, height, 0.0, 20.0)
    return Camera(view, proj, width, height, orthographic=True)


def make_mesh(positions, triangles, normals=None, uvs=None) -> Mesh:
    """A mesh; ``normals`` default to the flat face normals (per corner)."""
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if normals is None:
        if len(tri):
            a, b, c = pos[tri[:, 0]], pos[tri[:, 1]], pos[tri[:, 2]]
            n = np.cross(b - a, c - a)
        else:
            n = np.zeros((0, 3))
        normals = np.repeat(n[:, None, :], 3, axis=1)
    normals = np.asarray(normals, dtype=np.float32).reshape(-1, 3, 3)
    if uvs is not None:
        uvs = np.asarray(uvs, dtype=np.float32).reshape(-1, 3, 2)
    return Mesh(pos, tri, normals, uvs)


def quad(x0, y0, x1, y1, z=0.0, uv=True) -> Mesh:
    """Axis-aligned rectangle facing +Z (counter-clockwise seen from +Z), two triangles."""
    pos = [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
    tri = [(0, 1, 2), (0, 2, 3)]
    uvs = [[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]] if uv else None
    return make_mesh(pos, tri, uvs=uvs)


def cube(size: float = 1.0) -> Mesh:
    """Closed cube centred at the origin, 12 outward-facing triangles."""
    h = size / 2
    pos = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    idx = {p: i for i, p in enumerate(pos)}

    def v(x, y, z):
        return idx[(x * h, y * h, z * h)]

    faces = [
        (v(1, -1, -1), v(1, 1, -1), v(1, 1, 1), v(1, -1, 1)),      # +X
        (v(-1, -1, -1), v(-1, -1, 1), v(-1, 1, 1), v(-1, 1, -1)),  # -X
        (v(-1, 1, -1), v(-1, 1, 1), v(1, 1, 1), v(1, 1, -1)),      # +Y
        (v(-1, -1, -1), v(1, -1, -1), v(1, -1, 1), v(-1, -1, 1)),  # -Y
        (v(-1, -1, 1), v(1, -1, 1), v(1, 1, 1), v(-1, 1, 1)),      # +Z
        (v(-1, -1, -1), v(-1, 1, -1), v(1, 1, -1), v(1, -1, -1)),  # -Z
    ]
    tri = []
    for a, b, c, d in faces:
        tri += [(a, b, c), (a, c, d)]
    return make_mesh(pos, tri)


def uv_sphere(radius: float = 1.0, segments: int = 12, rings: int = 8) -> Mesh:
    """Closed UV sphere with shared vertices (poles are single vertices), outward winding."""
    pos = [(0.0, 0.0, radius)]
    for r in range(1, rings):
        theta = math.pi * r / rings
        for s in range(segments):
            phi = 2 * math.pi * s / segments
            pos.append((radius * math.sin(theta) * math.cos(phi), radius * math.sin(theta) * math.sin(phi),
                        radius * math.cos(theta)))
    pos.append((0.0, 0.0, -radius))
    south = len(pos) - 1

    def ring(r, s):
        return 1 + (r - 1) * segments + (s % segments)

    tri = []
    for s in range(segments):
        tri.append((0, ring(1, s), ring(1, s + 1)))
    for r in range(1, rings - 1):
        for s in range(segments):
            a, b, c, d = ring(r, s), ring(r + 1, s), ring(r + 1, s + 1), ring(r, s + 1)
            tri += [(a, b, c), (a, c, d)]
    for s in range(segments):
        tri.append((south, ring(rings - 1, s + 1), ring(rings - 1, s)))
    p = np.asarray(pos)
    normals = p[np.asarray(tri)] / radius
    return make_mesh(pos, tri, normals=normals)


def fan(center=(0.0, 0.0, 0.0), radius: float = 1.0, count: int = 7, phase: float = 0.3) -> Mesh:
    """A disc of ``count`` triangles sharing the centre vertex (counter-clockwise seen from +Z)."""
    pos = [center]
    for k in range(count):
        a = phase + 2 * math.pi * k / count
        pos.append((center[0] + radius * math.cos(a), center[1] + radius * math.sin(a), center[2]))
    tri = [(0, 1 + k, 1 + (k + 1) % count) for k in range(count)]
    return make_mesh(pos, tri)


def jittered_grid(rng, x0: float, y0: float, x1: float, y1: float, n: int) -> Mesh:
    """A flat grid of n x n vertices over [x0, x1] x [y0, y1] (z = 0), its inner vertices jittered by
    up to 1.2 (``rng``, a numpy Generator), each cell split along a random diagonal, about half the
    triangles wound the other way (draw it with Cull Off): its outline is the rectangle."""
    xs, ys = np.linspace(x0, x1, n), np.linspace(y0, y1, n)
    pos = np.array([(x, y, 0.0) for y in ys for x in xs])
    inner = (pos[:, 0] > x0) & (pos[:, 0] < x1) & (pos[:, 1] > y0) & (pos[:, 1] < y1)
    pos[inner, :2] += rng.uniform(-1.2, 1.2, size=(inner.sum(), 2))
    tri = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            if rng.random() < 0.5:
                tri += [(a, b, c), (a, c, d)]
            else:
                tri += [(a, b, d), (b, c, d)]
    tri = np.array(tri)
    flip = rng.random(len(tri)) < 0.5
    tri[flip] = tri[flip][:, ::-1]
    return make_mesh(pos, tri)


def renderer(mesh: Mesh, material: Material | None = None, *, name: str = "Object", slot: int = 0,
             matrix=None) -> Renderer:
    matrix = np.eye(4) if matrix is None else np.asarray(matrix, np.float64)
    pos = np.asarray(mesh.positions, np.float64)
    if len(pos):
        with np.errstate(invalid="ignore", over="ignore"):  # bad-input tests give non-finite vertices
            world = pos @ matrix[:3, :3].T + matrix[:3, 3]
        center = (world.min(axis=0) + world.max(axis=0)) / 2
    else:
        center = matrix[:3, 3].copy()
    return Renderer(name, slot, mesh, matrix, material or Material(), center)


def unlit(color=(1, 1, 1, 1), queue=Queue.Geometry, passes=None, **kw) -> Material:
    """An Unlit material (albedo only), default one default pass."""
    return Material(color=tuple(color), queue=queue, passes=tuple(passes or (Pass(),)), lighting=Lighting.Unlit, **kw)


def scene(cam: Camera, *renderers: Renderer, **kw) -> DrawScene:
    kw.setdefault("light", Light(direction=(0.3, 0.5, 0.8)))
    return DrawScene(camera=cam, renderers=tuple(renderers), **kw)


def translate(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def scale(x=1.0, y=1.0, z=1.0) -> np.ndarray:
    return np.diag([x, y, z, 1.0])


__all__ = [
    "camera", "cube", "fan", "jittered_grid", "look_at", "make_mesh", "orthographic", "perspective", "quad", "renderer",
    "replace", "scale", "scene", "screen_camera", "translate", "unlit", "uv_sphere",
]
