"""Full-screen triangle draws (one cached, attribute-less VAO per program)."""

from __future__ import annotations

import weakref

import moderngl

_VAOS: weakref.WeakKeyDictionary[moderngl.Context, dict[int, moderngl.VertexArray]] = (
    weakref.WeakKeyDictionary()
)


def fullscreen_vao(ctx: moderngl.Context, prog: moderngl.Program) -> moderngl.VertexArray:
    """The program's full-screen VAO (3 vertices, ``fullscreen.vert``)."""
    vaos = _VAOS.setdefault(ctx, {})
    vao = vaos.get(prog.glo)
    if vao is None:
        vao = ctx.vertex_array(prog, [])
        vaos[prog.glo] = vao
    return vao


def draw_fullscreen(
    ctx: moderngl.Context, prog: moderngl.Program, fbo: moderngl.Framebuffer, size: tuple[int, int]
) -> None:
    """Draw ``prog`` over all of ``fbo`` (no blending, no depth test)."""
    fbo.use()
    ctx.viewport = (0, 0, *size)
    ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
    fullscreen_vao(ctx, prog).render(moderngl.TRIANGLES, vertices=3)


def release_fullscreen(ctx: moderngl.Context) -> None:
    """Release the context's cached VAOs (engine shutdown)."""
    for vao in _VAOS.pop(ctx, {}).values():
        vao.release()
