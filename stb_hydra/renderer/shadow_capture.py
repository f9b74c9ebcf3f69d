"""Shadow-map capture into the 16-bit atlas (GL): :class:`ShadowCapturer`.

Renders a light's depth (a perspective map for spots, a 6-face cube for omni lights)
and copies it into its atlas rect with ``shadow_copy.frag``. What is captured (the
:class:`~stb_hydra.shadows.capture.Capture` of a light), its matrices and the map
record layout are GL-free, in :mod:`stb_hydra.shadows.capture`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from typing import TYPE_CHECKING, NamedTuple, cast

import moderngl
import numpy as np

from .. import limits
from ..shadows.atlas import AtlasRect
from ..shadows.capture import (
    BIAS_TEXELS,
    Capture,
    capture_view_projs,
    face_rotations,
    map_record,
    texel_angle,
)
from ..shadows.culling import boxes_in_sphere, frustum_planes, visible_faces
from .depth_draw import DepthDraw
from .gl import set_uniform, shader_library
from .link_masks import batch_keep

if TYPE_CHECKING:
    from .gl_delegate import GLRenderDelegate

#: ``ShadowCapturer`` modes: "per_face" draws each cube face on its own (the culled
#: batches of that face; the reference), "one_pass" draws every batch once for all six
#: faces (``depth_cube.geom``: per-triangle face selection, faces in one 3x2 target).
CAPTURE_MODES = ("per_face", "one_pass")
#: GL_CLIP_DISTANCE0 (the one-pass path clips each face with 4 user planes).
_GL_CLIP_DISTANCE0 = 0x3000


class CaptureWork(NamedTuple):
    """What one capture rendered: the cost model's features."""

    texels: int  # depth texels rendered (all faces)
    passes: int  # render passes (faces or one submission, + the copy)
    triangles: float  # triangles submitted after culling (each face counts its own)


#: Released atlases ((texture, framebuffer)) per (context id, side), for the next
#: ``ShadowCapturer`` of that context: ``limits.SHADOW_ATLAS_POOL_BYTES`` in all.
_atlas_pool: dict[tuple[int, int], list[tuple[moderngl.Texture, moderngl.Framebuffer]]] = {}


def _atlas_bytes(size: int) -> int:
    return size * size * 2  # one 16-bit unorm channel


def _take_atlas(ctx: moderngl.Context, size: int) -> tuple[moderngl.Texture, moderngl.Framebuffer]:
    """A pooled atlas of ``ctx`` and ``size`` (its content stale: the caller clears it),
    else a new one."""
    kept = _atlas_pool.get((id(ctx), size))
    while kept:
        tex, fbo = kept.pop()
        if tex.ctx is ctx:  # not a context that died and whose id was reused
            return tex, fbo
    tex = ctx.texture((size, size), 1, dtype="nu2")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    tex.repeat_x = tex.repeat_y = False
    return tex, ctx.framebuffer(color_attachments=[tex])


def _give_atlas(ctx: moderngl.Context, tex: moderngl.Texture, fbo: moderngl.Framebuffer) -> None:
    """Keep a released atlas for the next capturer of ``ctx`` while the pool's bytes
    stay within ``limits.SHADOW_ATLAS_POOL_BYTES``; else free it."""
    size = int(tex.width)
    held = sum(_atlas_bytes(k[1]) * len(v) for k, v in _atlas_pool.items())
    if held + _atlas_bytes(size) > limits.SHADOW_ATLAS_POOL_BYTES:
        fbo.release()
        tex.release()
        return
    _atlas_pool.setdefault((id(ctx), size), []).append((tex, fbo))


def release_atlas_pool() -> None:
    """Free every pooled atlas (e.g. before a context is released)."""
    for kept in _atlas_pool.values():
        for tex, fbo in kept:
            fbo.release()
            tex.release()
    _atlas_pool.clear()


class ShadowCapturer:
    """Owns the atlas texture and the temporary depth targets.

    ``mode``: one of ``CAPTURE_MODES`` (omni lights; a spot map is one pass either way).
    ``cull``: test each batch's world bounds against the light's range sphere *and* each
    face's clip volume (``shadows.culling``); False keeps the range test only (the
    reference of the culling tests).
    """

    def __init__(
        self, ctx: moderngl.Context, size: int, mode: str = "per_face", cull: bool = True
    ) -> None:
        if mode not in CAPTURE_MODES:
            raise ValueError(f"shadow capture mode must be one of {CAPTURE_MODES}, got {mode!r}")
        self.ctx = ctx
        self.size = size
        self.mode = mode
        self.cull = cull
        self.atlas, self.atlas_fbo = _take_atlas(ctx, size)
        self.atlas_fbo.clear(1.0, 1.0, 1.0, 1.0)  # every texel "unoccluded", pooled or new
        self._temps: dict[tuple[int, int], tuple[moderngl.Texture, moderngl.Framebuffer]] = {}
        #: Depth targets of split omni captures in progress (key -> target), kept
        #: between frames until the chunk that completes the map copies them.
        self._staging: dict[str, tuple[moderngl.Texture, moderngl.Framebuffer]] = {}
        self._faces = face_rotations().astype(np.float32)
        self.captures = 0
        self.texels = 0
        self.triangles = 0.0

    @property
    def omni_passes(self) -> int:
        """Render passes of one omni capture in this mode (the copy included)."""
        return limits.SHADOW_OMNI_PASSES if self.mode == "per_face" else 2

    def _target(self, w: int, h: int) -> tuple[moderngl.Texture, moderngl.Framebuffer]:
        tex = self.ctx.depth_texture((w, h))
        tex.compare_func = ""  # read raw depth (moderngl enables comparison by default)
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        return tex, self.ctx.framebuffer(depth_attachment=tex)

    def _temp(self, w: int, h: int) -> tuple[moderngl.Texture, moderngl.Framebuffer]:
        t = self._temps.get((w, h))
        if t is None:
            t = self._temps[(w, h)] = self._target(w, h)
        return t

    def _stage(
        self, key: str, w: int, h: int, first: bool
    ) -> tuple[moderngl.Texture, moderngl.Framebuffer]:
        """The split capture's depth target of ``key`` (a fresh one for the first chunk)."""
        t = self._staging.get(key)
        if t is not None and (first or t[0].size != (w, h)):
            self.drop_partial(key)
            t = None
        if t is None:
            if not first:
                raise RuntimeError(f"{key}: split shadow capture continued without its start")
            t = self._staging[key] = self._target(w, h)
            t[1].clear(depth=1.0)
        return t

    def drop_partial(self, key: str) -> None:
        """Release the depth target of ``key``'s split capture in progress, if any."""
        t = self._staging.pop(key, None)
        if t is not None:
            t[1].release()
            t[0].release()

    def _draw_faces(
        self,
        delegate: GLRenderDelegate,
        vis: np.ndarray,
        vps: np.ndarray,
        faces: Iterable[int],
        f: int,
    ) -> None:
        """Draw the culled batches of cube ``faces`` into their cells of the bound 3x2
        target (cell side ``f``), one pass per face."""
        ctx = self.ctx
        batches = delegate.batch_arrays().batches
        draw = DepthDraw(ctx, "depth_only.vert", "depth_only.frag")
        for i in faces:
            ctx.viewport = ((i % 3) * f, (i // 3) * f, f, f)
            draw.set("u_light_view_proj", vps[i])
            for j in np.nonzero(vis[i])[0].tolist():
                draw.draw(delegate, batches[j])

    def visible(
        self,
        delegate: GLRenderDelegate,
        c: Capture,
        dynamic: bool,
        vps: np.ndarray | None = None,
    ) -> np.ndarray:
        """(F, B) bool: batch b is drawn into face f (F = 6 omni, 1 spot); static maps
        skip dynamic geometry, and every map the batches outside the light's shadow link.
        ``vps``: ``capture_view_projs(c)`` when the caller has it."""
        arr = delegate.batch_arrays()
        if vps is None:
            vps = capture_view_projs(c)
        keep = boxes_in_sphere(np.array(c.position), np.array(c.range), arr.lo, arr.hi)
        if not dynamic:
            keep &= ~arr.dynamic
        keep &= batch_keep(arr.batches, c.shadow_mask)
        if not self.cull:
            return np.broadcast_to(keep, (len(vps), len(keep)))
        return visible_faces(frustum_planes(vps), arr.lo, arr.hi) & keep

    def capture(
        self,
        delegate: GLRenderDelegate,
        key: str,
        c: Capture,
        rect: AtlasRect,
        dynamic: bool,
        faces: tuple[int, ...] | None = None,
        first: bool = True,
        complete: bool = True,
    ) -> CaptureWork:
        """Render the light's depth and copy it into ``rect`` of the atlas.

        ``faces`` (an omni map in "per_face" mode): render only these cube faces, into
        ``key``'s own depth target kept across frames (``first``: a fresh one), and copy
        into the atlas only with ``complete`` -- the same texels as a whole capture when
        every face was rendered with the same ``c`` (``ShadowScheduler`` splits)."""
        if faces is not None:
            return self._capture_faces(delegate, key, c, rect, dynamic, faces, first, complete)
        ctx = self.ctx
        border = limits.SHADOW_MAP_BORDER_PX
        interior = rect.size - 2 * border
        if interior < 4:
            return CaptureWork(0, 0, 0.0)
        vps64 = capture_view_projs(c)
        vis = self.visible(delegate, c, dynamic, vps64)
        arr = delegate.batch_arrays()
        batches = arr.batches
        triangles = float((vis * arr.triangles).sum())
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        vps = vps64.astype(np.float32)
        if c.omni:
            f = max(interior // 2, 4)
            tex, fbo = self._temp(3 * f, 2 * f)
            fbo.use()
            fbo.clear(depth=1.0)
            if self.mode == "one_pass":
                draw = DepthDraw(
                    ctx, "depth_cube.vert", "depth_only.frag", geometry="depth_cube.geom"
                )
                ctx.viewport = (0, 0, 3 * f, 2 * f)
                draw.set("u_face_vp", vps)
                masks = (vis * (1 << np.arange(6))[:, None]).sum(axis=0)
                for i in range(4):
                    ctx.enable_direct(_GL_CLIP_DISTANCE0 + i)
                for j in np.nonzero(masks)[0].tolist():
                    draw.set("u_face_mask", int(masks[j]))
                    draw.draw(delegate, batches[j])
                for i in range(4):
                    ctx.disable_direct(_GL_CLIP_DISTANCE0 + i)
                passes = 2
            else:
                self._draw_faces(delegate, vis, vps, range(6), f)
                passes = limits.SHADOW_OMNI_PASSES
            texels = 6 * f * f
        else:
            tex, fbo = self._temp(interior, interior)
            fbo.use()
            fbo.clear(depth=1.0)
            self._draw_faces(delegate, vis, vps, (0,), interior)  # face 0's cell: all of it
            texels = interior * interior
            passes = limits.SHADOW_SPOT_PASSES
        ctx.disable(moderngl.DEPTH_TEST)
        self._copy(delegate, c, rect, tex, interior)
        self.texels += texels
        self.triangles += triangles
        self.captures += 1
        return CaptureWork(texels, passes, triangles)

    def _capture_faces(
        self,
        delegate: GLRenderDelegate,
        key: str,
        c: Capture,
        rect: AtlasRect,
        dynamic: bool,
        faces: tuple[int, ...],
        first: bool,
        complete: bool,
    ) -> CaptureWork:
        """Some faces of a split omni capture (``capture`` with ``faces``)."""
        if not c.omni or self.mode != "per_face":
            raise ValueError("only omni maps captured per face can be split into faces")
        interior = rect.size - 2 * limits.SHADOW_MAP_BORDER_PX
        if interior < 4:
            return CaptureWork(0, 0, 0.0)
        ctx = self.ctx
        sel = sorted(set(faces))
        vps64 = capture_view_projs(c)
        vis = self.visible(delegate, c, dynamic, vps64)
        triangles = float((vis[sel] * delegate.batch_arrays().triangles).sum())
        f = max(interior // 2, 4)
        tex, fbo = self._stage(key, 3 * f, 2 * f, first)
        fbo.use()
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        self._draw_faces(delegate, vis, vps64.astype(np.float32), sel, f)
        ctx.disable(moderngl.DEPTH_TEST)
        if complete:
            self._copy(delegate, c, rect, tex, interior)
            self.drop_partial(key)
            self.captures += 1
        texels = len(sel) * f * f
        self.texels += texels
        self.triangles += triangles
        return CaptureWork(texels, len(sel) + int(complete), triangles)

    def _copy(
        self,
        delegate: GLRenderDelegate,
        c: Capture,
        rect: AtlasRect,
        tex: moderngl.Texture,
        interior: int,
    ) -> None:
        """Copy the depth target into the atlas rect (``shadow_copy.frag``)."""
        ctx = self.ctx
        border = limits.SHADOW_MAP_BORDER_PX
        cp = shader_library(ctx).program("fullscreen.vert", "shadow_copy.frag")
        self.atlas_fbo.use()
        ctx.viewport = (rect.x, rect.y, rect.size, rect.size)
        tex.use(0)
        cast(moderngl.Uniform, cp["u_depth"]).value = 0
        set_uniform(cp, "u_rect", (rect.x, rect.y, rect.size, border))
        set_uniform(cp, "u_omni", 1 if c.omni else 0)
        set_uniform(cp, "u_near", float(c.near))
        set_uniform(cp, "u_far", float(c.range))
        set_uniform(cp, "u_range", float(c.range))
        set_uniform(cp, "u_tan_half", math.tan(c.spot_half_angle) if not c.omni else 1.0)
        set_uniform(cp, "u_bias_angle", BIAS_TEXELS * texel_angle(c, interior))
        if "u_face_rot" in cp:
            cast(moderngl.Uniform, cp["u_face_rot"]).write(self._faces.tobytes())
        vao = delegate_fullscreen(ctx, cp)
        vao.render(moderngl.TRIANGLES, vertices=3)

    def record(self, c: Capture, rect: AtlasRect) -> np.ndarray:
        """The std430 ``ShadowMap`` record (28 floats) of a captured map."""
        return map_record(c, rect, self.size)

    def release(self) -> None:
        for key in list(self._staging):
            self.drop_partial(key)
        for tex, fbo in self._temps.values():
            fbo.release()
            tex.release()
        self._temps.clear()
        _give_atlas(self.ctx, self.atlas, self.atlas_fbo)  # the next engine's, or freed


_fs_vaos: dict[int, moderngl.VertexArray] = {}


def delegate_fullscreen(ctx: moderngl.Context, prog: moderngl.Program) -> moderngl.VertexArray:
    vao = _fs_vaos.get(prog.glo)
    if vao is None:
        vao = ctx.vertex_array(prog, [])
        _fs_vaos[prog.glo] = vao
    return vao


#: Start-up calibration workloads (``calibrate_cost``): (depth target side, passes,
#: triangles per pass). Pass-, texel- and triangle-dominated, ~0.1-0.3 s on llvmpipe.
_CALIBRATION = ((32, 24, 2), (1024, 2, 2), (64, 1, 200_000))


def calibrate_cost(ctx: moderngl.Context, repeats: int = 2) -> np.ndarray:
    """Measure the capture cost coefficients (ms per Mtexel, per pass, per Mtriangle;
    ``shadows.cost``) with three synthetic depth workloads, each timed with
    ``ctx.finish()`` (the fastest of ``repeats``), solved by least squares (>= 0).
    The copy into the atlas is not in the texel workload: the run-time re-fit adds it."""
    from ..shadows.cost import features

    prog = shader_library(ctx).program("depth_only.vert", "depth_only.frag")
    rng = np.random.default_rng(0)
    n_tri = max(t for _, _, t in _CALIBRATION)
    # random small triangles in clip space (depth 0.5), plus one covering quad first
    quad = np.array([[-1, -1], [1, -1], [1, 1], [-1, -1], [1, 1], [-1, 1]], np.float64)
    centers = rng.uniform(-1.0, 1.0, (n_tri, 1, 2))
    small = centers + rng.uniform(-0.01, 0.01, (n_tri, 3, 2))  # ~1 texel, like distant casters
    xy = np.concatenate([quad, small.reshape(-1, 2)])
    pos = np.c_[xy, np.full(len(xy), 0.5)].astype(np.float32)
    vbo = ctx.buffer(pos.tobytes())
    ibo = ctx.buffer(np.arange(len(pos), dtype=np.uint32).tobytes())
    inst = ctx.buffer(np.eye(4, dtype=np.float32).tobytes())
    vao = ctx.vertex_array(
        prog, [(vbo, "3f", "in_pos"), (inst, "16f/i", "in_model")], ibo, index_element_size=4
    )
    set_uniform(prog, "u_light_view_proj", np.eye(4, dtype=np.float32))
    rows: list[np.ndarray] = []
    times: list[float] = []
    ctx.enable(moderngl.DEPTH_TEST)
    try:
        for side, passes, tris in _CALIBRATION:
            tex = ctx.depth_texture((side, side))
            fbo = ctx.framebuffer(depth_attachment=tex)
            best = math.inf
            for _ in range(repeats):
                ctx.finish()
                t0 = time.perf_counter()
                for _ in range(passes):
                    fbo.use()
                    fbo.clear(depth=1.0)
                    ctx.viewport = (0, 0, side, side)
                    vao.render(moderngl.TRIANGLES, vertices=3 * tris)
                ctx.finish()
                best = min(best, (time.perf_counter() - t0) * 1e3)
            fbo.release()
            tex.release()
            rows.append(features(side * side * passes, passes, tris * passes))
            times.append(best)
    finally:
        ctx.disable(moderngl.DEPTH_TEST)
        for obj in (vao, vbo, ibo, inst):
            obj.release()
    c, *_ = np.linalg.lstsq(np.array(rows), np.array(times), rcond=None)
    return np.maximum(c, 0.0)
