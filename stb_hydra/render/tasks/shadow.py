"""The sun's shadow map: one depth map fitted to the part of the view frustum
that intersects the scene bounds, in the sun's orthographic space."""

from __future__ import annotations

import moderngl
import numpy as np

from ..camera import look_at, orthographic
from ..gl import set_uniform, shader_library
from .base import Task


def _frustum_corners(view, max_dist: float) -> np.ndarray:
    tx, ty = view.tan_half
    ox, oy = view.offset
    pts = []
    for d in (view.near, min(view.far, max_dist)):
        for sx in (-1, 1):
            for sy in (-1, 1):
                if view.orthographic:
                    p = np.array([sx * tx + ox, sy * ty + oy, -d, 1.0])
                else:
                    p = np.array([(sx * tx + ox) * d, (sy * ty + oy) * d, -d, 1.0])
                pts.append(p @ view.inv_view)
    return np.array(pts)[:, :3]


class SunShadowTask(Task):
    name = "shadow"

    def __init__(self, engine) -> None:
        super().__init__(engine)
        self.texture: moderngl.Texture | None = None
        self.fbo: moderngl.Framebuffer | None = None

    def prepare(self, frame) -> None:
        sun = frame.sun
        if not (sun.enabled and sun.shadow):
            return
        lo, hi = self.engine.delegate.scene_bounds
        if not np.all(hi > lo):
            sun.shadow = False
            return
        d = sun.direction_to_sun / np.linalg.norm(sun.direction_to_sun)
        center = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo))
        light_to_world = look_at(center + d * radius * 2.0, center)
        to_light = np.linalg.inv(light_to_world)
        box = np.array(
            [[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        scene_ls = (box @ to_light)[:, :3]
        fr = np.c_[_frustum_corners(frame.view, 4.0 * radius + frame.view.near), np.ones(8)]
        fr_ls = (fr @ to_light)[:, :3]
        xy_lo = np.maximum(scene_ls[:, :2].min(0), fr_ls[:, :2].min(0))
        xy_hi = np.minimum(scene_ls[:, :2].max(0), fr_ls[:, :2].max(0))
        if np.any(xy_hi <= xy_lo):
            xy_lo, xy_hi = scene_ls[:, :2].min(0), scene_ls[:, :2].max(0)
        half = 0.5 * (xy_hi - xy_lo) * 1.02 + 1e-4
        half = np.full(2, max(half))  # square texels
        off = 0.5 * (xy_hi + xy_lo)
        near = max(-scene_ls[:, 2].max() - 1e-3, 1e-4)
        far = -scene_ls[:, 2].min() + 1e-3
        proj = orthographic(half[0], half[1], off[0], off[1], near, far)
        sun.view_proj = to_light @ proj
        size = frame.settings.sun_shadow_size
        texel_world = 2.0 * half[0] / size
        sun.texel = 1.0 / size
        sun.normal_bias = 1.5 * texel_world
        sun.depth_bias = 1.0 * texel_world / max(far - near, 1e-6)
        self._light_vp = sun.view_proj
        frame.stats["sun_shadow_texel_m"] = texel_world

    def execute(self, frame) -> None:
        sun = frame.sun
        if not (sun.enabled and sun.shadow):
            return
        ctx = frame.ctx
        size = frame.settings.sun_shadow_size
        if self.texture is None or self.texture.size != (size, size):
            self.release()
            self.texture = ctx.depth_texture((size, size))
            self.texture.compare_func = "<="
            self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.texture.repeat_x = self.texture.repeat_y = False
            self.fbo = ctx.framebuffer(depth_attachment=self.texture)
        self.fbo.use()
        ctx.viewport = (0, 0, size, size)
        self.fbo.clear(depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        prog = shader_library(ctx).program("depth_only.vert", "depth_only.frag")
        set_uniform(prog, "u_light_view_proj", np.asarray(self._light_vp, dtype=np.float32))
        delegate = self.engine.delegate
        for b in delegate.batches:
            delegate.vertex_array(b, prog, depth_only=True).render(
                moderngl.TRIANGLES, instances=b.count
            )
        ctx.disable(moderngl.DEPTH_TEST)

    def release(self) -> None:
        if self.fbo is not None:
            self.fbo.release()
        if self.texture is not None:
            self.texture.release()
        self.fbo = self.texture = None


class ShadowAtlasTask(Task):
    """Local-light shadow maps in the 16-bit atlas, budgeted per frame.

    prepare: register/forget shadowed FoV lights with the scheduler, size maps
    (resolution policy), mark static maps whose light moved or whose static
    geometry changed, plan this frame's captures, assign map records to FoV
    lights. execute: render the planned captures, commit them.
    """

    name = "shadow_atlas"
    #: Frames a light may stay out of the FoV before its map is freed.
    KEEP_OUT_OF_VIEW_FRAMES = 120

    def __init__(self, engine, atlas_size: int | None = None, budget_texels: int | None = None):
        super().__init__(engine)
        from ... import limits
        from ...shadows.scheduler import ShadowScheduler

        self.atlas_size = atlas_size or limits.SHADOW_ATLAS_SIZE_DEFAULT
        from ...shadows.atlas import ShadowAtlas

        self.scheduler = ShadowScheduler(
            ShadowAtlas(self.atlas_size),
            budget_texels=budget_texels or limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
        )
        self.capturer = None
        self.frozen = False  # tests: plan nothing (shadows keep their last capture)
        self._captures: dict[str, object] = {}  # key -> Capture of the light now
        self._captured: dict[str, object] = {}  # key -> Capture the map holds
        self._last_seen: dict[str, int] = {}
        self._plan = []
        self.records_ssbo = None
        self._records_key = None
        self.last_stats = None

    def prepare(self, frame) -> None:
        from ... import limits
        from ...shadows.capture import capture_for

        if not frame.settings.shadows:
            self.engine.delegate.fov_shadow_maps = None
            self._plan = []
            return
        eng = self.engine
        d = eng.delegate
        t = d.light_table
        sch = self.scheduler
        fidx = eng.frame_index
        rows = d.fov_rows
        shadowed = rows[t.shadow_enable[rows]] if len(rows) else rows
        keys = [t.paths[r] for r in shadowed]
        # -- register / update / forget --
        for key, r in zip(keys, shadowed.tolist()):
            c = capture_for(
                t.position[r],
                t.direction[r],
                t.range[r],
                t.radius[r],
                t.cone_cutoff[r],
                t.emission[r],
            )
            dyn = bool(t.shadow_dynamic[r])
            if key not in sch:
                sch.add_light(
                    key,
                    dynamic=dyn,
                    transform=c,
                    cost_factor=limits.SHADOW_OMNI_COST_FACTOR if c.omni else 1.0,
                )
            else:
                sch.set_dynamic(key, dyn)
                sch.set_transform(key, c)
            self._captures[key] = c
            self._last_seen[key] = fidx
        for key in list(self._last_seen):
            row = t.rows.get(key)
            gone = row is None or not t.shadow_enable[row] or not t.enabled[row]
            if gone or fidx - self._last_seen[key] > self.KEEP_OUT_OF_VIEW_FRAMES:
                if key in sch:
                    sch.remove_light(key)
                self._last_seen.pop(key, None)
                self._captures.pop(key, None)
                self._captured.pop(key, None)
        # -- static geometry changes in range --
        if d.changed_static_bounds and len(sch):
            reg = list(self._captures)
            pos = np.array([self._captures[k].position for k in reg])
            rng = np.array([self._captures[k].range for k in reg])
            lo = np.array([b[0] for b in d.changed_static_bounds])
            hi = np.array([b[1] for b in d.changed_static_bounds])
            dd = pos[:, None, :] - np.clip(pos[:, None, :], lo[None], hi[None])
            hit = np.any((dd**2).sum(-1) <= (rng**2)[:, None], axis=1)
            for k in np.array(reg, dtype=object)[hit]:
                sch.mark_dirty(k, "geometry")
        d.changed_static_bounds.clear()
        # -- resolution policy over every registered light --
        reg = list(self._captures)
        if reg:
            pos = np.array([self._captures[k].position for k in reg])
            in_view = np.array([self._last_seen[k] == fidx for k in reg])
            rws = np.array([t.rows[k] for k in reg])
            sch.update_lights(
                reg,
                distance_m=np.linalg.norm(pos - frame.view.position, axis=1),
                flux_lm=t.flux[rws].astype(np.float64),
                range_m=t.range[rws].astype(np.float64),
                viewport_height_px=float(frame.view.height),
                fov_y_rad=2.0 * float(np.arctan(frame.view.tan_half[1])),
                in_view=in_view,
            )
        self._plan = [] if (self.frozen or not reg) else sch.plan_frame(fidx)
        planned = {u.key for u in self._plan}
        # -- records: maps valid after this frame's captures --
        recs = []
        index: dict[str, int] = {}
        if self.capturer is None:
            from ...shadows.capture import ShadowCapturer

            self.capturer = ShadowCapturer(frame.ctx, self.atlas_size)
        for k in reg:
            rect = sch.rect(k)
            if rect is None:
                continue
            if k in planned:
                cap = self._captures[k]
            elif sch.is_valid(k):
                cap = sch.captured_transform(k)
            else:
                continue
            index[k] = len(recs)
            recs.append(self.capturer.record(cap, rect))
        maps = np.full(len(rows), -1.0, dtype=np.float32)
        if index:
            lookup = {t.rows[k]: i for k, i in index.items()}
            maps = np.array([lookup.get(int(r), -1) for r in rows], dtype=np.float32)
        d.fov_shadow_maps = maps
        self._records = np.array(recs, dtype=np.float32).reshape(-1, 28) if recs else None
        frame.stats["shadow_maps"] = len(recs)

    def execute(self, frame) -> None:
        if self.capturer is None:
            return
        d = self.engine.delegate
        for u in self._plan:
            if u.rect is None or u.transform is None:
                continue
            self.capturer.capture(d, u.key, u.transform, u.rect, u.dynamic)
        self.scheduler.commit(self._plan)
        # upload records (tiny; re-sent when they changed)
        if self._records is not None:
            data = self._records.tobytes()
            if self.records_ssbo is None or self.records_ssbo.size < len(data):
                if self.records_ssbo is not None:
                    self.records_ssbo.release()
                self.records_ssbo = frame.ctx.buffer(reserve=max(len(data), 28 * 4 * 64))
            if data != self._records_key:
                self.records_ssbo.write(data)
                self._records_key = data
        st = self.scheduler.stats()
        self.last_stats = st
        frame.stats.update(
            {
                "shadow_maps_updated": st.maps_updated,
                "shadow_texels_rendered": st.texels_rendered,
                "shadow_budget_texels": st.budget_texels,
                "shadow_statics_pending": st.statics_pending,
                "shadow_staleness_mean": st.static_wait.mean,
                "shadow_staleness_p95": st.static_wait.p95,
                "shadow_staleness_max": st.static_wait.max,
                "shadow_atlas_occupancy": st.atlas.occupancy,
                "shadow_atlas_fragmentation": st.atlas.fragmentation,
                "shadow_evictions": st.atlas.evictions,
                "shadow_downgrades": st.atlas.downgrades,
                "shadow_unplaced": st.unplaced,
            }
        )

    def bind(self, prog, unit: int) -> int:
        """Bind the atlas and records for a lighting program; returns the next unit."""
        if self.records_ssbo is not None:
            self.records_ssbo.bind_to_storage_buffer(1)
        if self.capturer is not None and "u_shadow_atlas" in prog:
            self.capturer.atlas.use(unit)
            prog["u_shadow_atlas"].value = unit
            return unit + 1
        return unit

    def release(self) -> None:
        if self.capturer is not None:
            self.capturer.release()
            self.capturer = None
        if self.records_ssbo is not None:
            self.records_ssbo.release()
            self.records_ssbo = None
