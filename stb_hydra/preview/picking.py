"""Picking: which prim covers a pixel, from an ID buffer.

On a click the delegate's draw batches are rendered once more into an R32UI
buffer (the viewport's size, depth-tested), each instance writing ``1 + its index``
in a pick table of (prim path, instance) built from the delegate's meshes in the
order its batches were built; the clicked texel is read back. Nothing runs per frame.
A PointInstancer's instance is named by its own path, ``<instancer>/__instance_<id>``
plus the mesh's path below the prototype (``scene.instancing.instance_light_path``,
the scheme its lights are synced under), not by the shared prototype mesh.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl
import numpy as np

from ..renderer.camera import ViewSetup
from ..scene.instancing import instance_light_path, parse_instance_path

if TYPE_CHECKING:
    from ..renderer.gl_delegate import GLRenderDelegate
    from ..scene.prims import MeshPrim

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
        n = len(m.world_transforms())
        ids = m.instance_ids
        if m.instancer is not None and ids is not None and len(ids) == n:
            names = [instance_light_path(m.instancer, int(i), m.instance_rel_path) for i in ids]
        else:
            names = [path] * n
        groups.setdefault(key, []).extend(names)
    table = list(groups.values())
    if len(table) != len(delegate.batches) or any(
        len(t) != b.count for t, b in zip(table, delegate.batches)
    ):
        return None
    return table


def find_instance(delegate: GLRenderDelegate, path: str) -> tuple[MeshPrim, int] | None:
    """(prototype mesh prim, row in its ``instance_transforms``) of a picked
    PointInstancer instance path, or None (not an instance path, or it is gone)."""
    parsed = parse_instance_path(path)
    if parsed is None:
        return None
    instancer, iid, rel = parsed
    for rp in delegate.meshes.values():
        m = rp.mesh
        if m is None or m.instancer != instancer or m.instance_rel_path != rel:
            continue
        if m.instance_ids is None:
            continue
        rows = np.nonzero(m.instance_ids == iid)[0]
        if len(rows):
            return m, int(rows[0])
    return None


def instance_bounds(delegate: GLRenderDelegate, path: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Render-frame (lo, hi) bounds (m) of one picked instance, or None."""
    hit = find_instance(delegate, path)
    if hit is None:
        return None
    m, row = hit
    pts = np.c_[np.asarray(m.points, dtype=np.float64), np.ones(len(m.points))]
    w = (pts @ m.world_transforms()[row])[:, :3]
    w = w[np.all(np.isfinite(w), axis=1)]
    return (w.min(0), w.max(0)) if len(w) else None


def instance_rows(delegate: GLRenderDelegate, path: str) -> list[tuple[str, str]]:
    """Properties of one picked instance: its instancer, id and prototype mesh."""
    hit = find_instance(delegate, path)
    parsed = parse_instance_path(path)
    if hit is None or parsed is None:
        return []
    m = hit[0]
    lo_hi = instance_bounds(delegate, path)
    rows = [
        ("type", "point instance"),
        ("instancer", parsed[0]),
        ("instance id", str(parsed[1])),
        ("prototype", m.path),
        ("material", m.material or "(display colour)"),
    ]
    if lo_hi is not None:
        c = 0.5 * (lo_hi[0] + lo_hi[1])
        rows.append(("centre [m]", ", ".join(f"{v:.4g}" for v in c)))
    return rows


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
