"""The real-GPU reference (README "How correctness is checked"): a draw scene rendered through OpenGL.

The same draw list as the core, drawn with OpenGL's own fixed-function state on
Mesa's llvmpipe through a headless EGL context (moderngl). Everything the core does
by hand is done here by GL: near/far clipping, snapping, the fill rule, culling,
perspective-correct interpolation, depth, polygon offset, stencil, depth test,
blending, sRGB framebuffer conversion, the colour write mask and the clear.

    color, depth, stencil = render_gl(scene)       # row 0 = top, like Frame
    color, depth, stencil = render_gl_sorted(scene)  # docs/sorting.md's sorted reference, by depth peeling

For timing the draw alone::

    r = GLRenderer(scene)     # uploads buffers, textures, builds the FBO
    r.render(); r.finish()    # clear + every draw call, then glFinish
    color, depth, stencil = r.read()
    r.release()

What is done on the CPU (in float64, then handed to GL as float32): the vertex
transform to clip space (``matmul4`` order of docs/pipeline.md §1), world normals
(cofactor matrix), and the conversion of texels, ``_Color``, ambient, light and
clear colours to shading space (docs/pipeline.md §7), so both sides convert colours
identically and GL only filters. The fragment program of §7 runs in GLSL (float32).

The fixed-function state goes straight to GL through ctypes (``eglGetProcAddress``)
because moderngl has no stencil API and no DEPTH24_STENCIL8 attachment: the
framebuffer is a raw GL FBO with a colour texture (RGBA8, SRGB8_ALPHA8 with
GL_FRAMEBUFFER_SRGB for Linear LDR, RGBA32F for HDR) and a DEPTH24_STENCIL8
renderbuffer. moderngl only provides the context, programs, buffers and textures.

MSAA (``DrawScene.msaa`` 4: llvmpipe grants 4 samples for a request of 2 and refuses 8, so other
counts raise ValueError): the draws go to multisampled colour and DEPTH24_STENCIL8 renderbuffers
of the same formats with GL_MULTISAMPLE on, AlphaToMask passes with GL_SAMPLE_ALPHA_TO_COVERAGE,
and :meth:`GLRenderer.read` resolves with glBlitFramebuffer (colours averaged, in linear light
for the sRGB buffer with GL_FRAMEBUFFER_SRGB on; depth and stencil of sample 0).

This module is free of bpy; moderngl is imported lazily (``pip install
blendlib[reference]``).
"""

from __future__ import annotations

import ctypes
import math

import numpy as np

from blendlib.core.outline import outline_key
from blendlib.core.scene import DrawScene, validate_scene
from blendlib.core.vocabulary import (
    LAST_OPAQUE_QUEUE,
    QUEUE_NUMBERS,
    BlendFactor,
    BlendOp,
    ColorSpace,
    CompareFunction,
    Cull,
    Lighting,
    LightType,
    Queue,
    SortMode,
    StencilOp,
    TextureFilter,
    TextureWrap,
    VertexColor,
)

from .scalar import renderer_calls
from .scalar_shading import build_mips, outline_clip, width_factor

DMAX = 2**24 - 1

# ------------------------------------------------------------------ GL enums

GL_NEVER, GL_LESS, GL_EQUAL, GL_LEQUAL = 0x0200, 0x0201, 0x0202, 0x0203
GL_GREATER, GL_NOTEQUAL, GL_GEQUAL, GL_ALWAYS = 0x0204, 0x0205, 0x0206, 0x0207
GL_ZERO, GL_ONE = 0, 1
GL_SRC_COLOR, GL_ONE_MINUS_SRC_COLOR, GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA = 0x0300, 0x0301, 0x0302, 0x0303
GL_DST_ALPHA, GL_ONE_MINUS_DST_ALPHA, GL_DST_COLOR, GL_ONE_MINUS_DST_COLOR = 0x0304, 0x0305, 0x0306, 0x0307
GL_SRC_ALPHA_SATURATE = 0x0308
GL_FUNC_ADD, GL_MIN, GL_MAX = 0x8006, 0x8007, 0x8008
GL_FUNC_SUBTRACT, GL_FUNC_REVERSE_SUBTRACT = 0x800A, 0x800B
GL_KEEP, GL_REPLACE, GL_INCR, GL_DECR, GL_INVERT = 0x1E00, 0x1E01, 0x1E02, 0x1E03, 0x150A
GL_INCR_WRAP, GL_DECR_WRAP = 0x8507, 0x8508
GL_CULL_FACE, GL_DEPTH_TEST, GL_STENCIL_TEST, GL_BLEND = 0x0B44, 0x0B71, 0x0B90, 0x0BE2
GL_DITHER, GL_POLYGON_OFFSET_FILL, GL_FRAMEBUFFER_SRGB, GL_SCISSOR_TEST = 0x0BD0, 0x8037, 0x8DB9, 0x0C11
GL_MULTISAMPLE, GL_SAMPLE_ALPHA_TO_COVERAGE, GL_SAMPLE_MASK = 0x809D, 0x809E, 0x8E51
GL_RENDERBUFFER_SAMPLES, GL_SAMPLE_POSITION = 0x8CAB, 0x8E50
GL_READ_FRAMEBUFFER, GL_DRAW_FRAMEBUFFER, GL_NEAREST = 0x8CA8, 0x8CA9, 0x2600
GL_RGBA8, GL_RGBA32F = 0x8058, 0x8814
GL_FRONT, GL_BACK, GL_CW, GL_CCW = 0x0404, 0x0405, 0x0900, 0x0901
GL_COLOR_BUFFER_BIT, GL_DEPTH_BUFFER_BIT, GL_STENCIL_BUFFER_BIT = 0x4000, 0x0100, 0x0400
GL_FRAMEBUFFER, GL_RENDERBUFFER = 0x8D40, 0x8D41
GL_COLOR_ATTACHMENT0, GL_DEPTH_STENCIL_ATTACHMENT, GL_COLOR = 0x8CE0, 0x821A, 0x1800
GL_FRAMEBUFFER_COMPLETE = 0x8CD5
GL_TEXTURE_2D = 0x0DE1
GL_DEPTH24_STENCIL8, GL_SRGB8_ALPHA8 = 0x88F0, 0x8C43
GL_RGBA, GL_DEPTH_STENCIL = 0x1908, 0x84F9
GL_UNSIGNED_BYTE, GL_FLOAT, GL_UNSIGNED_INT_24_8 = 0x1401, 0x1406, 0x84FA
GL_PACK_ALIGNMENT = 0x0D05

_COMPARE = {
    CompareFunction.Never: GL_NEVER, CompareFunction.Less: GL_LESS, CompareFunction.Equal: GL_EQUAL,
    CompareFunction.LEqual: GL_LEQUAL, CompareFunction.Greater: GL_GREATER,
    CompareFunction.NotEqual: GL_NOTEQUAL, CompareFunction.GEqual: GL_GEQUAL, CompareFunction.Always: GL_ALWAYS,
}
_FACTOR = {
    BlendFactor.One: GL_ONE, BlendFactor.Zero: GL_ZERO,
    BlendFactor.SrcColor: GL_SRC_COLOR, BlendFactor.SrcAlpha: GL_SRC_ALPHA,
    BlendFactor.DstColor: GL_DST_COLOR, BlendFactor.DstAlpha: GL_DST_ALPHA,
    BlendFactor.OneMinusSrcColor: GL_ONE_MINUS_SRC_COLOR, BlendFactor.OneMinusSrcAlpha: GL_ONE_MINUS_SRC_ALPHA,
    BlendFactor.OneMinusDstColor: GL_ONE_MINUS_DST_COLOR, BlendFactor.OneMinusDstAlpha: GL_ONE_MINUS_DST_ALPHA,
    BlendFactor.SrcAlphaSaturate: GL_SRC_ALPHA_SATURATE,
}
_EQUATION = {
    BlendOp.Add: GL_FUNC_ADD, BlendOp.Sub: GL_FUNC_SUBTRACT, BlendOp.RevSub: GL_FUNC_REVERSE_SUBTRACT,
    BlendOp.Min: GL_MIN, BlendOp.Max: GL_MAX,
}
_STENCIL_OP = {
    StencilOp.Keep: GL_KEEP, StencilOp.Zero: GL_ZERO, StencilOp.Replace: GL_REPLACE,
    StencilOp.IncrSat: GL_INCR, StencilOp.DecrSat: GL_DECR, StencilOp.Invert: GL_INVERT,
    StencilOp.IncrWrap: GL_INCR_WRAP, StencilOp.DecrWrap: GL_DECR_WRAP,
}

# ------------------------------------------------------------------ raw GL through EGL

_u = ctypes.c_uint
_i = ctypes.c_int
_f = ctypes.c_float
_d = ctypes.c_double
_b = ctypes.c_ubyte
_p = ctypes.c_void_p
_PROTOS = {
    "glEnable": (None, _u), "glDisable": (None, _u),
    "glDepthFunc": (None, _u), "glDepthMask": (None, _b),
    "glColorMask": (None, _b, _b, _b, _b),
    "glStencilFunc": (None, _u, _i, _u), "glStencilOp": (None, _u, _u, _u), "glStencilMask": (None, _u),
    "glBlendFuncSeparate": (None, _u, _u, _u, _u), "glBlendEquationSeparate": (None, _u, _u),
    "glPolygonOffset": (None, _f, _f), "glCullFace": (None, _u), "glFrontFace": (None, _u),
    "glClearColor": (None, _f, _f, _f, _f), "glClearDepth": (None, _d), "glClearStencil": (None, _i),
    "glClear": (None, _u), "glViewport": (None, _i, _i, _i, _i),
    "glReadPixels": (None, _i, _i, _i, _i, _u, _u, _p), "glPixelStorei": (None, _u, _i),
    "glGenFramebuffers": (None, _i, _p), "glDeleteFramebuffers": (None, _i, _p),
    "glBindFramebuffer": (None, _u, _u),
    "glGenRenderbuffers": (None, _i, _p), "glDeleteRenderbuffers": (None, _i, _p),
    "glBindRenderbuffer": (None, _u, _u), "glRenderbufferStorage": (None, _u, _u, _i, _i),
    "glFramebufferRenderbuffer": (None, _u, _u, _u, _u), "glFramebufferTexture2D": (None, _u, _u, _u, _u, _i),
    "glCheckFramebufferStatus": (_u, _u), "glFinish": (None,), "glGetError": (_u,),
    "glClearBufferuiv": (None, _u, _i, _p), "glClearBufferfv": (None, _u, _i, _p),
    "glRenderbufferStorageMultisample": (None, _u, _i, _u, _i, _i),
    "glBlitFramebuffer": (None, _i, _i, _i, _i, _i, _i, _i, _i, _u, _u),
    "glGetRenderbufferParameteriv": (None, _u, _u, _p), "glGetMultisamplefv": (None, _u, _u, _p),
    "glSampleMaski": (None, _u, _u),
}


class _GL:
    """The GL entry points used here, resolved through ``eglGetProcAddress``."""

    def __init__(self) -> None:
        egl = ctypes.CDLL("libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        for name, (restype, *argtypes) in _PROTOS.items():
            address = egl.eglGetProcAddress(name.encode())
            if not address:
                raise RuntimeError(f"OpenGL function {name} is not available")
            setattr(self, name[2:], ctypes.CFUNCTYPE(restype, *argtypes)(address))

    def check(self, where: str) -> None:
        err = self.GetError()
        if err:
            raise RuntimeError(f"OpenGL error 0x{err:04X} after {where}")


_CONTEXT = None


def context():
    """The cached headless moderngl context (EGL, Mesa llvmpipe) and its raw GL table."""
    global _CONTEXT
    if _CONTEXT is None:
        import moderngl

        ctx = moderngl.create_standalone_context(backend="egl")
        gl = _GL()
        _CONTEXT = (ctx, gl, {})
    return _CONTEXT


_VERTEX_SHADER = """
#version 330
in vec4 in_clip;
in vec2 in_uv;
in vec3 in_nw;
in vec4 in_vc;
in vec3 in_wp;
out vec2 v_uv;
out vec3 v_nw;
out vec4 v_vc;
out vec3 v_wp;
void main() {
    v_uv = in_uv;
    v_nw = in_nw;
    v_vc = in_vc;
    v_wp = in_wp;
    gl_Position = in_clip;
}
"""
#: Per-corner vertex records: clip position, mesh uv, world normal, vertex colour (shading space,
#: white without one), world position.
VERTEX_FORMAT = ("4f 2f 3f 4f 3f", "in_clip", "in_uv", "in_nw", "in_vc", "in_wp")

#: The alpha test's comparisons by the number the fragment shader's ``alpha_comp`` holds.
ALPHA_COMPS = (CompareFunction.GEqual, CompareFunction.Greater, CompareFunction.Less, CompareFunction.LEqual,
               CompareFunction.Equal, CompareFunction.NotEqual, CompareFunction.Always, CompareFunction.Never)

_FRAGMENT_SHADER = """
#version 330
in vec2 v_uv;
in vec3 v_nw;
in vec4 v_vc;
in vec3 v_wp;
uniform int vc_mode;
uniform vec4 tint;
uniform int add_type;
uniform vec3 add_color;
uniform vec3 add_dir;
uniform vec3 add_pos;
uniform vec3 add_axis;
uniform float add_range2;
uniform float add_tan_half;
uniform vec4 color;
uniform vec2 tiling;
uniform vec2 uv_offset;
uniform float alpha_scale;
uniform float cutoff;
uniform bool lambert;
uniform bool has_tex;
uniform bool alpha_test;
uniform int alpha_comp;  // ALPHA_COMPS: 0 = GEqual (the book's clip(alpha - cutoff))
uniform vec3 ambient;
uniform vec3 light;
uniform vec3 ldir;
uniform sampler2D tex;
uniform bool has_outline;  // an MToon outline pass: rgb = outline_color * mix(1, lit, outline_mix)
uniform vec3 outline_color;
uniform float outline_mix;
out vec4 frag;
void main() {
    vec2 uv = v_uv * tiling + uv_offset;
    vec4 t = has_tex ? texture(tex, uv) : vec4(1.0);
    vec3 albedo = t.rgb * color.rgb;
    float alpha = (t.a * color.a) * alpha_scale;
    if (vc_mode == 1) {  // Multiply
        albedo *= v_vc.rgb;
        alpha *= v_vc.a;
    } else if (vc_mode == 2) {  // Particle: 2 * i.color * _TintColor * tex
        vec4 c = 2.0 * v_vc * tint * t;
        albedo = c.rgb;
        alpha = c.a;
    }
    if (alpha_test) {
        bool survives = alpha_comp == 0 ? !(alpha - cutoff < 0.0)
            : alpha_comp == 1 ? alpha > cutoff : alpha_comp == 2 ? alpha < cutoff
            : alpha_comp == 3 ? alpha <= cutoff : alpha_comp == 4 ? alpha == cutoff
            : alpha_comp == 5 ? alpha != cutoff : alpha_comp == 6;
        if (!survives) discard;
    }
    vec3 rgb = albedo;
    if (lambert) {
        float len = length(v_nw);
        vec3 n = len > 0.0 ? v_nw / len : vec3(0.0);
        if (add_type < 0) {
            float ndl = max(0.0, dot(n, ldir));
            rgb = ambient * albedo + (light * albedo) * ndl;
        } else {  // a ForwardAdd draw's light: 0 directional, 1 point, 2 spot
            vec3 l = add_dir;
            float atten = 1.0;
            if (add_type > 0) {
                vec3 d = v_wp - add_pos;
                float d2 = dot(d, d);
                float dl = sqrt(d2);
                l = dl > 0.0 ? -d / dl : vec3(0.0);
                float r2 = d2 / add_range2;
                atten = r2 >= 1.0 ? 0.0 : (1.0 / (1.0 + 25.0 * r2)) * min(1.0, (1.0 - r2) / 0.36);
                if (add_type == 2) {
                    float z = dot(d, add_axis);
                    float cone = 0.0;
                    if (z > 0.0) {
                        float rho = sqrt(max(d2 - z * z, 0.0)) / (z * add_tan_half);
                        cone = clamp((1.0 - rho) / 0.28125, 0.0, 1.0);
                    }
                    atten *= cone;
                }
            }
            rgb = ((add_color * albedo) * max(0.0, dot(n, l))) * atten;
        }
    }
    if (has_outline) rgb = outline_color * (1.0 + outline_mix * (rgb - 1.0));
    frag = vec4(rgb, alpha);
}
"""

# Depth peeling (render_gl_sorted): the fragment program above, each fragment tagged with its peel key
# (24-bit depth code, draw position, primitive id). ``roundEven(z * DMAX)`` in float32, clamped, is
# exactly the code llvmpipe stores in a DEPTH24 buffer for ``gl_FragCoord.z`` (polygon offset included;
# checked on every fragment of random triangles with and without offset), so the key's depth is the
# depth GL itself tests. ``after_peeled()``: the fragment comes after the last one peeled here.
_PEEL_KEY = """
uniform uint call_key;
uniform usampler2D peeled;
uvec2 fragment_key() {
    float code = clamp(roundEven(gl_FragCoord.z * 16777215.0), 0.0, 16777215.0);
    return uvec2(16777215u - uint(code), call_key | uint(gl_PrimitiveID));
}
bool after_peeled(uvec2 key) {
    uvec2 last = texelFetch(peeled, ivec2(gl_FragCoord.xy), 0).xy;
    return key.x > last.x || (key.x == last.x && key.y > last.y);
}
"""
_SHADED = "    frag = vec4(rgb, alpha);\n}"


def _peel_shader(outputs: str, tail: str) -> str:
    shader = _FRAGMENT_SHADER.replace("out vec4 frag;", _PEEL_KEY + outputs).replace(_SHADED, tail + "\n}")
    assert _PEEL_KEY in shader and tail in shader
    return shader


# Selection 1: the farthest depth left per pixel (MIN blending of the exact integer 2^24 - 1 - code in R32F).
_PEEL_FARTHEST_SHADER = _peel_shader("out vec4 farthest;", """
    uvec2 key = fragment_key();
    if (!after_peeled(key)) discard;
    farthest = vec4(float(key.x), 0.0, 0.0, 1.0);""")
# Selection 2: among the fragments at that depth, the first in draw then primitive order (a stencil
# test lets only the first fragment reaching a pixel through) records its whole key.
_PEEL_FIRST_SHADER = _peel_shader("uniform sampler2D farthest;\nout uvec2 selected_key;", """
    uvec2 key = fragment_key();
    if (!after_peeled(key) || float(key.x) != texelFetch(farthest, ivec2(gl_FragCoord.xy), 0).x) discard;
    selected_key = key;""")
# Application: only the selected fragment of each pixel goes on, through its pass's fixed-function state.
_PEEL_APPLY_SHADER = _peel_shader("uniform usampler2D selected;\nout vec4 frag;", """
    if (fragment_key() != texelFetch(selected, ivec2(gl_FragCoord.xy), 0).xy) discard;
    frag = vec4(rgb, alpha);""")


# ------------------------------------------------------------------ CPU side (float64)


def encode(x):
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.0031308, x * 12.92, 1.055 * np.power(np.maximum(x, 0.0031308), 1.0 / 2.4) - 0.055)


def decode(x):
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.04045, x / 12.92, np.power((np.maximum(x, 0.04045) + 0.055) / 1.055, 2.4))


def draw_order(scene: DrawScene) -> list:
    """Renderers in draw order: key (queue, signed distance, name, slot) of docs/pipeline.md §0."""
    cam = scene.camera
    p = np.asarray(cam.position, dtype=np.float64)
    mode = scene.sort_mode
    if mode is SortMode.Default:
        mode = SortMode.Orthographic if cam.orthographic else SortMode.Perspective
    axis = None
    if mode is SortMode.Orthographic:
        axis = np.asarray(cam.forward, dtype=np.float64)
    elif mode is SortMode.CustomAxis:
        a = np.asarray(scene.sort_axis, dtype=np.float64)
        axis = a / math.sqrt((a[0] * a[0] + a[1] * a[1]) + a[2] * a[2])

    def key(r):
        dx, dy, dz = (np.asarray(r.bounds_center, dtype=np.float64) - p).tolist()
        if axis is None:
            d = (dx * dx + dy * dy) + dz * dz
        else:
            d = (dx * axis[0] + dy * axis[1]) + dz * axis[2]
        q = r.material.render_queue
        return (q, d if q <= LAST_OPAQUE_QUEUE else -d, r.name, r.slot)

    return sorted(scene.renderers, key=key)


def _matmul4(a, b):
    out = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            out[i, j] = ((a[i, 0] * b[0, j] + a[i, 1] * b[1, j]) + a[i, 2] * b[2, j]) + a[i, 3] * b[3, j]
    return out


def vertex_data(scene: DrawScene, r, program=None) -> tuple[np.ndarray, bool, int]:
    """Per-corner float32 vertex records (:data:`VERTEX_FORMAT`, 3 rows per triangle), whether the
    object is mirrored, and the number of non-finite triangles left out. ``program``: a pass whose
    outline vertex program moves the corners (the scalar reference's arithmetic, per corner)."""
    V = np.asarray(scene.camera.view_matrix, np.float64)
    P = np.asarray(scene.camera.projection, np.float64)
    M = np.asarray(r.matrix_world, np.float64)
    mvp = _matmul4(P, _matmul4(V, M))
    m = M[:3, :3]
    C = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            C[i, j] = (m[(i + 1) % 3, (j + 1) % 3] * m[(i + 2) % 3, (j + 2) % 3]
                       - m[(i + 1) % 3, (j + 2) % 3] * m[(i + 2) % 3, (j + 1) % 3])
    det = (m[0, 0] * C[0, 0] + m[0, 1] * C[0, 1]) + m[0, 2] * C[0, 2]
    N = C if det >= 0 else -C
    mesh = r.mesh
    tri = np.asarray(mesh.triangles, dtype=np.int64).reshape(-1, 3)
    pos = np.asarray(mesh.positions, dtype=np.float64)[tri]  # (T, 3, 3)
    x, y, z = pos[..., 0], pos[..., 1], pos[..., 2]
    n = np.asarray(mesh.normals, dtype=np.float64).reshape(-1, 3, 3)
    if program is None:
        clip = np.stack([((mvp[i, 0] * x + mvp[i, 1] * y) + mvp[i, 2] * z) + mvp[i, 3] for i in range(4)], axis=-1)
    else:
        lists = [M.tolist(), V.tolist(), P.tolist()]
        uvs = np.zeros((tri.shape[0], 3, 2)) if mesh.uvs is None else np.asarray(mesh.uvs, np.float64).reshape(-1, 3, 2)
        linear = scene.color_space is ColorSpace.Linear
        clip = np.array([[outline_clip(program, pos[t, k].tolist(), n[t, k].tolist(), *lists,
                                       width_factor(r.material, uvs[t, k].tolist(), linear)) for k in range(3)]
                         for t in range(tri.shape[0])], dtype=np.float64).reshape(-1, 3, 4)
    nw = np.stack([(N[i, 0] * n[..., 0] + N[i, 1] * n[..., 1]) + N[i, 2] * n[..., 2] for i in range(3)], axis=-1)
    t = tri.shape[0]
    uv = np.zeros((t, 3, 2)) if mesh.uvs is None else np.asarray(mesh.uvs, dtype=np.float64).reshape(-1, 3, 2)
    vc = np.ones((t, 3, 4))
    if mesh.colors is not None:
        vc = np.asarray(mesh.colors, np.float32).astype(np.float64)
        linear = scene.color_space is ColorSpace.Linear
        if mesh.color_encoding == "sRGB" and linear:
            vc[..., :3] = decode(vc[..., :3])
        elif mesh.color_encoding == "Linear" and not linear:
            vc[..., :3] = encode(vc[..., :3])
    wp = np.stack([((M[i, 0] * x + M[i, 1] * y) + M[i, 2] * z) + M[i, 3] for i in range(3)], axis=-1)
    finite = np.all(np.isfinite(clip), axis=(1, 2))
    rec = np.concatenate([clip, uv, nw, vc, wp], axis=-1)[finite].reshape(-1, 16)
    return np.ascontiguousarray(rec, dtype=np.float32), bool(det < 0), int(t - finite.sum())


def _light_uniforms(scene: DrawScene, light) -> dict:
    """The ``add_*`` uniforms of a ForwardAdd draw's light (None: the main light, ``add_type`` -1)."""
    if light is None:
        return {"add_type": -1}
    linear = scene.color_space is ColorSpace.Linear
    lamp = np.asarray(light.color, np.float64)
    lamp = lamp if linear else encode(lamp)
    axis = np.asarray(light.axis, np.float64)
    axis = axis / math.sqrt((axis[0] * axis[0] + axis[1] * axis[1]) + axis[2] * axis[2])
    kinds = {LightType.Directional: 0, LightType.Point: 1, LightType.Spot: 2}
    return {"add_type": kinds[light.type], "add_color": tuple((lamp * float(light.intensity)).tolist()),
            "add_dir": tuple(axis.tolist()), "add_pos": tuple(float(v) for v in light.position),
            "add_axis": tuple((-axis).tolist()), "add_range2": float(light.range) ** 2,
            "add_tan_half": math.tan(math.radians(float(light.spot_angle)) / 2.0)}


def _outline_uniforms(sh: _Shading, p) -> dict:
    """The ``outline_*`` uniforms of pass ``p`` (MToon's outline colour in shading space)."""
    if p.outline_color is None:
        return {"has_outline": False, "outline_color": (0.0, 0.0, 0.0), "outline_mix": 0.0}
    return {"has_outline": True, "outline_color": tuple(float(c) for c in sh.from_gamma(p.outline_color)),
            "outline_mix": float(p.outline_lighting_mix)}


class _Shading:
    """Material constants in shading space (docs/pipeline.md §7)."""

    def __init__(self, scene: DrawScene, material) -> None:
        linear = scene.color_space is ColorSpace.Linear

        def from_gamma(c):
            return decode(c) if linear else np.asarray(c, np.float64)

        def from_linear(c):
            return np.asarray(c, np.float64) if linear else encode(c)

        self.from_gamma = lambda c: from_gamma(np.asarray(c, np.float64))
        col = np.asarray(material.color, np.float64)
        self.color = tuple(np.concatenate([from_gamma(col[:3]), col[3:]]).tolist())
        amb = np.asarray(scene.ambient, np.float64)
        self.ambient = tuple((from_linear(amb) if scene.ambient_is_linear else from_gamma(amb)).tolist())
        if scene.light is None:
            self.light, self.ldir = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        else:
            self.light = tuple((from_linear(np.asarray(scene.light.color, np.float64)) * scene.light.energy).tolist())
            d = np.asarray(scene.light.direction, np.float64)
            length = math.sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2])
            self.ldir = tuple((d / length if length else d * 0).tolist())
        self.texels = None
        self.levels = []  # mip levels 1.. (float32), when the material has mipmaps
        tex = material.main_tex
        if tex is not None:
            px = np.asarray(tex.pixels, np.float32).astype(np.float64)
            rgb = px[..., :3]
            if tex.encoding == "sRGB" and linear:
                rgb = decode(rgb)
            elif tex.encoding == "Linear" and not linear:
                rgb = encode(rgb)
            self.texels = np.ascontiguousarray(np.concatenate([rgb, px[..., 3:]], axis=-1), dtype=np.float32)
            if material.main_tex_mipmaps:  # the chain of docs/pipeline.md §7, by the scalar reference
                chain = build_mips(np.concatenate([rgb, px[..., 3:]], axis=-1).tolist(),
                                   material.main_tex_preserve_coverage, float(material.cutoff))
                self.levels = [np.asarray(level, np.float32) for level in chain[1:]]
        tint = np.asarray(material.tint_color, np.float64)
        self.tint = tuple(np.concatenate([from_gamma(tint[:3]), tint[3:]]).tolist())


class GLRenderer:
    """One scene on the GPU: build once, then :meth:`render` (repeatable), :meth:`finish`, :meth:`read`."""

    def __init__(self, scene: DrawScene) -> None:
        self.warnings = validate_scene(scene)
        self.scene = scene
        ctx, gl, cache = context()
        self.ctx, self.gl = ctx, gl
        if "program" not in cache:
            cache["program"] = ctx.program(vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER)
        self.program = cache["program"]
        cam = scene.camera
        self.W, self.H = int(cam.width), int(cam.height)
        self.hdr = bool(scene.hdr)
        self.linear = scene.color_space is ColorSpace.Linear
        self._resources = []
        self._query = None  # one occlusion query, reused for every draw
        self._peeling = None  # render_sorted's selection targets, made on first use

        # Framebuffer: colour texture + DEPTH24_STENCIL8 renderbuffer on a raw FBO.

        size = (self.W, self.H)
        if self.hdr:
            self.color_tex = ctx.texture(size, 4, dtype="f4")
        elif self.linear:
            self.color_tex = ctx.texture(size, 4, dtype="f1", internal_format=GL_SRGB8_ALPHA8)
        else:
            self.color_tex = ctx.texture(size, 4, dtype="f1")
        self._resources.append(self.color_tex)
        self.rbo = self._renderbuffer(GL_DEPTH24_STENCIL8, 0)
        self.fbo = self._framebuffer(self.color_tex.glo, self.rbo)
        # MSAA: draw into multisampled colour and depth-stencil renderbuffers of the same formats;
        # read() resolves them into the single-sampled FBO above (glBlitFramebuffer).
        self.samples = int(scene.msaa)
        self.resolve_fbo = None
        self._ms_rbos: list[int] = []
        if self.samples > 1:
            color_format = GL_RGBA32F if self.hdr else GL_SRGB8_ALPHA8 if self.linear else GL_RGBA8
            self._ms_rbos = [self._renderbuffer(color_format, self.samples),
                             self._renderbuffer(GL_DEPTH24_STENCIL8, self.samples)]
            self.resolve_fbo, self.fbo = self.fbo, self._framebuffer(None, self._ms_rbos[1], self._ms_rbos[0])
        gl.check("framebuffer set-up")

        # Draw calls: (vao, vertex count, mirrored, texture, uniforms, pass).
        self.calls = []
        self.call_numbers = []  # the 1-based draw-call number (docs/framedebugger.md) of each entry of ``calls``
        self.call_queues = []  # the render queue of each entry of ``calls``
        self._call_buffers = []  # the vertex buffer of each entry of ``calls``
        self._peel_vaos = {}  # (program, vertex buffer) → vertex array of render_sorted's programs
        number = 0
        for r in draw_order(scene):
            calls = renderer_calls(scene, r)
            number += len(calls)
            data, mirrored, skipped = vertex_data(scene, r)
            if skipped:
                self.warnings.append(f"object {r.name!r} slot {r.slot}: {skipped} non-finite triangle(s) skipped")
            if len(data) == 0:
                continue
            buffers = {None: self._vertex_buffer(data)}
            mat = r.material
            sh = _Shading(scene, mat)
            tex = None if sh.texels is None else self._texture(sh, mat)
            uniforms = {
                "color": sh.color, "tiling": tuple(map(float, mat.main_tex_tiling)),
                "uv_offset": tuple(map(float, mat.main_tex_offset)), "alpha_scale": float(mat.alpha_scale),
                "cutoff": float(mat.cutoff), "lambert": mat.lighting is Lighting.Lambert,
                "has_tex": tex is not None, "ambient": sh.ambient, "light": sh.light, "ldir": sh.ldir,
                "vc_mode": {VertexColor.Off: 0, VertexColor.Multiply: 1, VertexColor.Particle: 2}[mat.vertex_color],
                "tint": sh.tint,
            }
            for k, (p, light) in enumerate(calls):
                key = outline_key(p)
                if key not in buffers:
                    buffers[key] = self._vertex_buffer(vertex_data(scene, r, p)[0])
                vbo, vao, count = buffers[key]
                self.calls.append((vao, count, mirrored, tex,
                                   {**uniforms, **_light_uniforms(scene, light), **_outline_uniforms(sh, p)}, p))
                self.call_numbers.append(number - len(calls) + k + 1)
                self.call_queues.append(mat.render_queue)
                self._call_buffers.append(vbo)

        clear = np.asarray(scene.clear_color, np.float64)
        if self.linear:
            clear = np.concatenate([decode(clear[:3]), clear[3:]])
        self.clear = tuple(float(c) for c in clear)

    def _vertex_buffer(self, data: np.ndarray):
        """(vertex buffer, vertex array for the main program, vertex count) of vertex records."""
        vbo = self.ctx.buffer(data.tobytes())
        vao = self.ctx.vertex_array(self.program, [(vbo, *VERTEX_FORMAT)], skip_errors=True)
        self._resources += [vao, vbo]
        return vbo, vao, len(data)

    def _texture(self, sh: _Shading, mat):
        """The material's texture: level 0 and, with mipmaps, the chain's other levels, filtered as
        the material's filter says (with mipmaps: GL_NEAREST_MIPMAP_NEAREST, GL_LINEAR_MIPMAP_NEAREST,
        GL_LINEAR_MIPMAP_LINEAR)."""
        import moderngl

        th, tw = sh.texels.shape[:2]
        tex = self.ctx.texture((tw, th), 4, sh.texels.tobytes(), dtype="f4")
        point = mat.main_tex_filter is TextureFilter.Point
        mag = moderngl.NEAREST if point else moderngl.LINEAR
        if sh.levels:
            tex.build_mipmaps(0, len(sh.levels))
            for level, values in enumerate(sh.levels, start=1):
                tex.write(np.ascontiguousarray(values).tobytes(), level=level)
            minify = {TextureFilter.Point: moderngl.NEAREST_MIPMAP_NEAREST,
                      TextureFilter.Bilinear: moderngl.LINEAR_MIPMAP_NEAREST,
                      TextureFilter.Trilinear: moderngl.LINEAR_MIPMAP_LINEAR}[mat.main_tex_filter]
            tex.filter = (minify, mag)
        else:
            tex.filter = (mag, mag)
        tex.repeat_x = tex.repeat_y = mat.main_tex_wrap is TextureWrap.Repeat
        self._resources.append(tex)
        return tex

    def _renderbuffer(self, internal_format: int, samples: int) -> int:
        """A W x H renderbuffer; ``samples`` > 1: multisampled, exactly that many samples granted
        (llvmpipe grants 4 for a request of 2 and refuses 8: ValueError)."""
        gl = self.gl
        ids = (ctypes.c_uint * 1)()
        gl.GenRenderbuffers(1, ids)
        gl.BindRenderbuffer(GL_RENDERBUFFER, ids[0])
        if samples > 1:
            gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, samples, internal_format, self.W, self.H)
            granted = ctypes.c_int(0)
            gl.GetRenderbufferParameteriv(GL_RENDERBUFFER, GL_RENDERBUFFER_SAMPLES, ctypes.byref(granted))
            if gl.GetError() or granted.value != samples:
                gl.DeleteRenderbuffers(1, ids)
                raise ValueError(f"this GL gives no {samples}-sample buffers (granted {granted.value}); "
                                 "llvmpipe has 4x MSAA only")
        else:
            gl.RenderbufferStorage(GL_RENDERBUFFER, internal_format, self.W, self.H)
        return ids[0]

    def _framebuffer(self, color_texture: int | None, depth_stencil: int, color_renderbuffer: int | None = None) -> int:
        """A complete FBO of a colour texture (or renderbuffer) and a depth-stencil renderbuffer."""
        gl = self.gl
        ids = (ctypes.c_uint * 1)()
        gl.GenFramebuffers(1, ids)
        gl.BindFramebuffer(GL_FRAMEBUFFER, ids[0])
        if color_texture is not None:
            gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, color_texture, 0)
        else:
            gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_renderbuffer)
        gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, depth_stencil)
        status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER)
        if status != GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"framebuffer incomplete: 0x{status:04X}")
        return ids[0]

    def sample_positions(self) -> list[tuple[float, float]]:
        """``glGetMultisamplefv(GL_SAMPLE_POSITION)`` of the drawing framebuffer: each sample's
        (x, y) within the pixel, y up."""
        gl = self.gl
        gl.BindFramebuffer(GL_FRAMEBUFFER, self.fbo)
        out = []
        for k in range(self.samples):
            xy = (ctypes.c_float * 2)()
            gl.GetMultisamplefv(GL_SAMPLE_POSITION, k, xy)
            out.append((float(xy[0]), float(xy[1])))
        gl.check("sample positions")
        return out

    # -------------------------------------------------------------- drawing

    def _set_pass(self, p, mirrored: bool) -> None:
        gl = self.gl
        if p.cull is Cull.Off:
            gl.Disable(GL_CULL_FACE)
        else:
            gl.Enable(GL_CULL_FACE)
            gl.CullFace(GL_BACK if p.cull is Cull.Back else GL_FRONT)
        gl.FrontFace(GL_CW if mirrored else GL_CCW)
        gl.Enable(GL_DEPTH_TEST)  # ZTest Always still needs the test enabled for depth writes
        gl.DepthFunc(_COMPARE[p.ztest])
        gl.DepthMask(1 if p.zwrite else 0)
        if p.offset_factor or p.offset_units:
            gl.Enable(GL_POLYGON_OFFSET_FILL)
            gl.PolygonOffset(float(p.offset_factor), float(p.offset_units))
        else:
            gl.Disable(GL_POLYGON_OFFSET_FILL)
        if p.stencil:
            gl.Enable(GL_STENCIL_TEST)
            gl.StencilFunc(_COMPARE[p.stencil_comp], p.stencil_ref, p.stencil_read_mask)
            gl.StencilOp(_STENCIL_OP[p.stencil_fail], _STENCIL_OP[p.stencil_zfail], _STENCIL_OP[p.stencil_pass])
            gl.StencilMask(p.stencil_write_mask)
        else:
            gl.Disable(GL_STENCIL_TEST)
            gl.StencilMask(0)
        if p.blend:
            gl.Enable(GL_BLEND)
            sa, da, opa = p.alpha_factors
            gl.BlendFuncSeparate(_FACTOR[p.src_blend], _FACTOR[p.dst_blend], _FACTOR[sa], _FACTOR[da])
            gl.BlendEquationSeparate(_EQUATION[p.blend_op], _EQUATION[opa])
        else:
            gl.Disable(GL_BLEND)
        gl.ColorMask(*(1 if c in p.color_mask else 0 for c in "RGBA"))
        if p.alpha_to_mask:
            gl.Enable(GL_SAMPLE_ALPHA_TO_COVERAGE)
        else:
            gl.Disable(GL_SAMPLE_ALPHA_TO_COVERAGE)

    def _bind(self, fbo: int | None = None) -> None:
        gl = self.gl
        gl.BindFramebuffer(GL_FRAMEBUFFER, self.fbo if fbo is None else fbo)
        gl.Viewport(0, 0, self.W, self.H)
        gl.Disable(GL_SCISSOR_TEST)
        gl.Disable(GL_DITHER)
        if self.samples > 1 and fbo is None:
            gl.Enable(GL_MULTISAMPLE)
        else:
            gl.Disable(GL_MULTISAMPLE)
        if self.linear and not self.hdr:
            gl.Enable(GL_FRAMEBUFFER_SRGB)
        else:
            gl.Disable(GL_FRAMEBUFFER_SRGB)

    def _clear(self) -> None:
        gl = self.gl
        self._bind()
        gl.ColorMask(1, 1, 1, 1)
        gl.DepthMask(1)
        gl.StencilMask(0xFF)
        gl.ClearColor(*self.clear)
        gl.ClearDepth(1.0)
        gl.ClearStencil(0)
        gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT)

    @staticmethod
    def _use_material(prog, tex, uniforms: dict, p) -> None:
        """Set one draw call's material uniforms (and texture, unit 0) on ``prog``."""
        for name, value in uniforms.items():
            if name in prog:
                prog[name].value = value
        if "alpha_test" in prog:
            prog["alpha_test"].value = bool(p.alpha_test)
        if "alpha_comp" in prog:
            prog["alpha_comp"].value = ALPHA_COMPS.index(p.alpha_test_comp)
        if tex is not None:
            tex.use(0)
            if "tex" in prog:
                prog["tex"].value = 0

    def render(self, max_calls: int | None = None, samples: dict | None = None) -> None:
        """Clear and issue every draw call (or those numbered up to ``max_calls``, docs/framedebugger.md numbering:
        renderers with no triangles count); no readback, no wait.

        ``samples``: a dict that receives, per draw-call number, the samples that passed the
        depth and stencil tests (an occlusion query, GL_SAMPLES_PASSED, around the draw)."""
        self._clear()
        prog = self.program
        for number, (vao, count, mirrored, tex, uniforms, p) in zip(self.call_numbers, self.calls, strict=True):
            if max_calls is not None and number > max_calls:
                break
            self._use_material(prog, tex, uniforms, p)
            self._bind()
            self._set_pass(p, mirrored)
            if samples is None:
                vao.render(vertices=count)
                continue
            if self._query is None:
                self._query = self.ctx.query(samples=True)
            with self._query:
                vao.render(vertices=count)
            samples[number] = self._query.samples
        self.gl.check("drawing")

    def render_sorted(self, max_peels: int = 10_000) -> int:
        """Clear and draw docs/sorting.md's sorted reference by depth peeling; returns the number of peels.

        1. The draw calls of queues ≤ 2500 are drawn as :meth:`render` draws them; the depth
           buffer they leave is the one step 2 tests against (nothing writes depth in step 2).
        2. The fragments of the draw calls of queues 2501–3999 that survive culling and the
           alpha test (passes with ColorMask 0 left out: they write nothing in step 2) are
           peeled back to front, one fragment per pixel per peel, in the order of the key
           (2^24 − 1 − depth code, draw position, primitive id) — far first, ties in draw order,
           then primitive order. The key is exact and total (no two fragments of a pixel share
           one), so a peel is "the smallest key greater than the last peeled key": each fragment
           is applied exactly once, in order. A peel is three passes over those draw calls, every
           fragment computing its key in the fragment program (``gl_FragCoord.z`` converted as
           the DEPTH24 buffer converts it, ``gl_PrimitiveID``) and dropping itself when not
           after the last peeled key (an RG32UI texture):

           a. farthest: MIN blending of the key's first word (an integer below 2^24, exact in
              R32F) gives the farthest depth left per pixel;
           b. first: the fragments at that depth, drawn in draw order, go through a stencil test
              that passes only the first to reach the pixel (GL keeps primitive order per
              pixel); it writes its whole key into the other RG32UI texture;
           c. apply: each draw call again, with its own pass's cull, offset, stencil test and
              operation, depth test against step 1's depth buffer (depth writes off), blending
              and ColorMask into the frame; the fragment program lets through only the fragment
              whose key is the one selected.

           The selection passes render into a DEPTH24_STENCIL8 target like the frame's, so polygon
           offset (whose unit depends on the depth format) gives the same depths in every pass.
           Peeling ends when step b selects nothing; the fragments selected over all peels
           (counted on the key texture) must number as many as step a counted in the first peel
           (an occlusion query), else RuntimeError.
        3. Overlay (queue ≥ 4000) is drawn as :meth:`render` draws it, testing against step 1's
           depth plus its own writes.
        """
        if self.samples > 1:
            raise ValueError("render_sorted: no MSAA (the sorted reference is per pixel)")
        overlay = QUEUE_NUMBERS[Queue.Overlay]
        peeled = [k for k, q in enumerate(self.call_queues)
                  if LAST_OPAQUE_QUEUE < q < overlay and self.calls[k][5].color_mask]
        if len(peeled) >= (1 << 12) - 1 or any(self.calls[k][1] // 3 > 1 << 20 for k in peeled):
            raise ValueError("depth peeling keys hold at most 4094 draw calls of 2^20 triangles each")
        self._clear()
        for k, q in enumerate(self.call_queues):
            if q <= LAST_OPAQUE_QUEUE:
                self._draw(self.program, k)
        peels = self._peel(peeled, max_peels) if peeled else 0
        for k, q in enumerate(self.call_queues):
            if q >= overlay:
                self._draw(self.program, k)
        self.gl.check("sorted drawing")
        return peels

    def _draw(self, prog, k: int, fbo: int | None = None, state=None, call_key: int | None = None) -> None:
        """Issue draw call ``k`` with ``prog``: its pass's state, then ``state()`` (overrides)."""
        vao, count, mirrored, tex, uniforms, p = self.calls[k]
        if prog is not self.program:  # a vertex array draws with the program it was made for
            vbo = self._call_buffers[k]
            vao = self._peel_vaos.get((prog.glo, vbo.glo))
            if vao is None:
                vao = self.ctx.vertex_array(prog, [(vbo, *VERTEX_FORMAT)], skip_errors=True)
                self._peel_vaos[(prog.glo, vbo.glo)] = vao
                self._resources.append(vao)
        self._use_material(prog, tex, uniforms, p)
        if call_key is not None:
            prog["call_key"].value = call_key
        self._bind(fbo)
        self._set_pass(p, mirrored)
        if state is not None:
            state()
        vao.render(vertices=count)

    def _peel_targets(self):
        """The selection framebuffers of :meth:`render_sorted` (made once): (farthest FBO, first FBO,
        their DEPTH24_STENCIL8 renderbuffer, the R32F farthest texture, two RG32UI key textures)."""
        if self._peeling is None:
            import moderngl

            ctx, gl = self.ctx, self.gl
            size = (self.W, self.H)
            farthest = ctx.texture(size, 1, dtype="f4")
            keys = [ctx.texture(size, 2, dtype="u4") for _ in range(2)]
            for tex in (farthest, *keys):
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)  # integer textures need it
            self._resources += [farthest, *keys]
            ids = (ctypes.c_uint * 2)()
            gl.GenRenderbuffers(1, ids)
            rbo = ids[0]
            gl.BindRenderbuffer(GL_RENDERBUFFER, rbo)
            gl.RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH24_STENCIL8, self.W, self.H)
            gl.GenFramebuffers(2, ids)
            fbos = ids[0], ids[1]
            for fbo, tex in zip(fbos, (farthest, keys[0]), strict=True):
                gl.BindFramebuffer(GL_FRAMEBUFFER, fbo)
                gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex.glo, 0)
                gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, rbo)
                status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER)
                if status != GL_FRAMEBUFFER_COMPLETE:
                    raise RuntimeError(f"peeling framebuffer incomplete: 0x{status:04X}")
            gl.check("peeling set-up")
            self._peeling = (*fbos, rbo, farthest, keys)
        return self._peeling

    def _peel(self, calls: list[int], max_peels: int) -> int:
        """Step 2 of :meth:`render_sorted` over the draw calls ``calls`` (indices of ``self.calls``)."""
        ctx, gl = self.ctx, self.gl
        fbo_far, fbo_first, _, farthest, keys = self._peel_targets()
        cache = context()[2]
        for name, source in (("peel_farthest", _PEEL_FARTHEST_SHADER), ("peel_first", _PEEL_FIRST_SHADER),
                             ("peel_apply", _PEEL_APPLY_SHADER)):
            if name not in cache:
                cache[name] = ctx.program(vertex_shader=_VERTEX_SHADER, fragment_shader=source)
        far_prog, first_prog, apply_prog = cache["peel_farthest"], cache["peel_first"], cache["peel_apply"]
        far_prog["peeled"].value = first_prog["peeled"].value = apply_prog["selected"].value = 1
        first_prog["farthest"].value = 2
        if self._query is None:
            self._query = ctx.query(samples=True)
        query = self._query
        call_keys = [(pos + 1) << 20 for pos in range(len(calls))]  # > 0: key (0, 0) precedes all

        def attach(tex) -> None:
            gl.BindFramebuffer(GL_FRAMEBUFFER, fbo_first)
            gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex.glo, 0)

        def farthest_state() -> None:
            gl.DepthFunc(GL_ALWAYS)  # the depth test stays on (as in the frame): only its result is ignored
            gl.DepthMask(0)
            gl.Disable(GL_STENCIL_TEST)
            gl.StencilMask(0)
            gl.Enable(GL_BLEND)
            gl.BlendFuncSeparate(GL_ONE, GL_ONE, GL_ONE, GL_ONE)
            gl.BlendEquationSeparate(GL_MIN, GL_MIN)
            gl.ColorMask(1, 1, 1, 1)

        def first_state() -> None:
            gl.DepthFunc(GL_ALWAYS)
            gl.DepthMask(0)
            gl.Enable(GL_STENCIL_TEST)  # passes while the stencil is 0, then sets it to 1
            gl.StencilFunc(GL_GREATER, 1, 0xFF)
            gl.StencilOp(GL_KEEP, GL_KEEP, GL_REPLACE)
            gl.StencilMask(0xFF)
            gl.Disable(GL_BLEND)
            gl.ColorMask(1, 1, 1, 1)

        def apply_state() -> None:
            gl.DepthMask(0)

        last, chosen = keys
        attach(last)
        gl.ColorMask(1, 1, 1, 1)
        gl.ClearBufferuiv(GL_COLOR, 0, (ctypes.c_uint * 4)(0, 0, 0, 0))
        total = selected = 0
        for peel in range(max_peels + 1):
            gl.BindFramebuffer(GL_FRAMEBUFFER, fbo_far)
            gl.ColorMask(1, 1, 1, 1)
            gl.ClearBufferfv(GL_COLOR, 0, (ctypes.c_float * 4)(2.0**24, 0, 0, 0))
            last.use(1)
            with query:
                for k, key in zip(calls, call_keys, strict=True):
                    self._draw(far_prog, k, fbo_far, farthest_state, key)
            if peel == 0:
                total = query.samples
            attach(chosen)
            gl.ColorMask(1, 1, 1, 1)
            gl.StencilMask(0xFF)
            gl.ClearStencil(0)
            gl.Clear(GL_STENCIL_BUFFER_BIT)
            gl.ClearBufferuiv(GL_COLOR, 0, (ctypes.c_uint * 4)(0xFFFFFFFF, 0xFFFFFFFF, 0, 0))
            last.use(1)
            farthest.use(2)
            for k, key in zip(calls, call_keys, strict=True):
                self._draw(first_prog, k, fbo_first, first_state, key)
            # Counted on the selected keys: around this pass llvmpipe's occlusion query reported more
            # samples than its stencil test lets through (measured), so the query is not used here.
            count = int(np.count_nonzero(np.frombuffer(chosen.read(), np.uint32)[0::2] != 0xFFFFFFFF))
            if count == 0:
                break
            if peel == max_peels:
                raise RuntimeError(f"more than {max_peels} depth peels")
            selected += count
            chosen.use(1)
            for k, key in zip(calls, call_keys, strict=True):
                self._draw(apply_prog, k, None, apply_state, key)
            last, chosen = chosen, last
        gl.check("depth peeling")
        if selected != total:
            raise RuntimeError(f"depth peeling applied {selected} of {total} fragments")
        return peel

    def finish(self) -> None:
        """Wait until the GPU has finished every draw call."""
        self.gl.Finish()

    def read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(color, depth, stencil)`` as in :class:`blendlib.core.pipeline.Frame`, row 0 = top."""
        gl, W, H = self.gl, self.W, self.H
        read_fbo = self.fbo
        if self.samples > 1:
            # Resolve: colours averaged (in linear light for the sRGB buffer: GL_FRAMEBUFFER_SRGB
            # on), depth and stencil of sample 0 (llvmpipe's blit of multisampled depth-stencil).
            if self.linear and not self.hdr:
                gl.Enable(GL_FRAMEBUFFER_SRGB)
            gl.Disable(GL_SCISSOR_TEST)
            gl.BindFramebuffer(GL_READ_FRAMEBUFFER, self.fbo)
            gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, self.resolve_fbo)
            gl.BlitFramebuffer(0, 0, W, H, 0, 0, W, H, GL_COLOR_BUFFER_BIT, GL_NEAREST)
            gl.BlitFramebuffer(0, 0, W, H, 0, 0, W, H, GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT, GL_NEAREST)
            gl.check("resolve")
            read_fbo = self.resolve_fbo
        gl.BindFramebuffer(GL_FRAMEBUFFER, read_fbo)
        gl.Disable(GL_FRAMEBUFFER_SRGB)  # read the stored (encoded) codes, no conversion
        gl.PixelStorei(GL_PACK_ALIGNMENT, 1)
        if self.hdr:
            color = np.empty((H, W, 4), np.float32)
            gl.ReadPixels(0, 0, W, H, GL_RGBA, GL_FLOAT, color.ctypes.data)
        else:
            codes = np.empty((H, W, 4), np.uint8)
            gl.ReadPixels(0, 0, W, H, GL_RGBA, GL_UNSIGNED_BYTE, codes.ctypes.data)
            color = (codes / 255.0).astype(np.float32)
        ds = np.empty((H, W), np.uint32)
        gl.ReadPixels(0, 0, W, H, GL_DEPTH_STENCIL, GL_UNSIGNED_INT_24_8, ds.ctypes.data)
        gl.check("readback")
        depth = ((ds >> 8).astype(np.int64) / DMAX).astype(np.float32)
        stencil = (ds & 0xFF).astype(np.uint8)
        return color[::-1].copy(), depth[::-1].copy(), stencil[::-1].copy()

    def release(self) -> None:
        gl = self.gl
        ids = (ctypes.c_uint * 1)(self.fbo)
        gl.DeleteFramebuffers(1, ids)
        if self.resolve_fbo is not None:
            ids[0] = self.resolve_fbo
            gl.DeleteFramebuffers(1, ids)
        for rbo in (self.rbo, *self._ms_rbos):
            ids[0] = rbo
            gl.DeleteRenderbuffers(1, ids)
        self._ms_rbos = []
        if self._peeling is not None:
            ids = (ctypes.c_uint * 2)(*self._peeling[:2])
            gl.DeleteFramebuffers(2, ids)
            ids[0] = self._peeling[2]
            gl.DeleteRenderbuffers(1, ids)
            self._peeling = None
        for res in self._resources:
            res.release()
        self._resources = []


def render_gl_sorted(scene: DrawScene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """docs/sorting.md's sorted reference through OpenGL by depth peeling (:meth:`GLRenderer.render_sorted`);
    returns ``(color, depth, stencil)``, row 0 = top."""
    r = GLRenderer(scene)
    try:
        r.render_sorted()
        r.finish()
        return r.read()
    finally:
        r.release()


def render_gl(scene: DrawScene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Render ``scene`` through OpenGL (llvmpipe); returns ``(color, depth, stencil)``, row 0 = top."""
    r = GLRenderer(scene)
    try:
        r.render()
        r.finish()
        return r.read()
    finally:
        r.release()
