"""Picking: which prim covers a pixel, from an ID buffer.

On a click the delegate's draw batches are rendered once more into an R32UI
buffer (the viewport's size, depth-tested), each instance writing ``1 + its index``
in a pick table of (prim path, instance) built from the delegate's meshes in the
order its batches were built; the clicked texel is read back. Nothing runs per frame.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl
import numpy as np

from ..renderer.camera import ViewSetup

if TYPE_CHECKING:
    from ..renderer.gl_delegate import GLRenderDelegate

_VS = """
#version 430 core
in vec3 in_pos;
in mat4 in_model;
uniform mat4 u_view_proj;
uniform uint u_base;
flat out uint v_id;
void main() {
    v_id = u_base + uint(gl_InstanceID);
    gl_Position = u_view_proj * (in_model * vec4(in_pos, 1.0));
}
"""
_FS = """
#version 430 core
flat in uint v_id;
out uint o_id;
void main() { o_id = v_id; }
"""


def pick_table(delegate: GLRenderDelegate) -> list[list[str]] | None:
    """Per draw batch, the prim path of each instance (the delegate's grouping:
    geometry, material, dynamic, in mesh order); None if it does not match the
    batches (they are rebuilt on the next commit)."""
    groups: dict[tuple, list[str]] = {}
    for path, rp in delegate.meshes.items():
        m = rp.mesh
        if m is None or not m.visible or len(m.indices) == 0:
            continue
        key = delegate.batch_key(path, m)
        groups.setdefault(key, []).extend([path] * len(m.world_transforms()))
    table = list(groups.values())
    if len(table) != len(delegate.batches) or any(
        len(t) != b.count for t, b in zip(table, delegate.batches)
    ):
        return None
    return table


class Picker:
    """The ID-buffer renderer (one per context)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.prog = ctx.program(vertex_shader=_VS, fragment_shader=_FS)
        self._fbo: moderngl.Framebuffer | None = None

    def _target(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        if self._fbo is None or self._fbo.size != size:
            if self._fbo is not None:
                for a in (*self._fbo.color_attachments, self._fbo.depth_attachment):
                    if a is not None:
                        a.release()
                self._fbo.release()
            ids = self.ctx.texture(size, 1, dtype="u4")
            depth = self.ctx.depth_renderbuffer(size)
            self._fbo = self.ctx.framebuffer(color_attachments=[ids], depth_attachment=depth)
        return self._fbo

    def pick(self, delegate: GLRenderDelegate, view: ViewSetup, x: int, y: int) -> str | None:
        """The prim path at pixel (x, y) (window pixels, top-left origin), or None
        (background, or the batches are being rebuilt)."""
        table = pick_table(delegate)
        if table is None or not (0 <= x < view.width and 0 <= y < view.height):
            return None
        ctx = self.ctx
        fbo = self._target((view.width, view.height))
        with ctx.scope(framebuffer=fbo, enable_only=moderngl.DEPTH_TEST):
            ctx.viewport = (0, 0, view.width, view.height)
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            vp = self.prog["u_view_proj"]
            base = self.prog["u_base"]
            assert isinstance(vp, moderngl.Uniform) and isinstance(base, moderngl.Uniform)
            vp.write(np.asarray(view.view_proj, dtype=np.float32).tobytes())
            offset = 1
            for b, paths in zip(delegate.batches, table):
                base.value = offset
                delegate.vertex_array(b, self.prog, depth_only=True).render(
                    moderngl.TRIANGLES, instances=b.count
                )
                offset += len(paths)
            data = fbo.read(viewport=(x, view.height - 1 - y, 1, 1), components=1, dtype="u4")
        idx = int(np.frombuffer(data, np.uint32)[0])
        if idx == 0:
            return None
        flat = [p for paths in table for p in paths]
        return flat[idx - 1] if idx - 1 < len(flat) else None

    def release(self) -> None:
        if self._fbo is not None:
            for a in (*self._fbo.color_attachments, self._fbo.depth_attachment):
                if a is not None:
                    a.release()
            self._fbo.release()
        self.prog.release()
