"""Local-light shadow maps in the 16-bit atlas, budgeted per frame.

prepare: register new shadowed FoV lights with the scheduler, report moved
lights, mark static maps whose static geometry changed, size maps with the
resolution policy (every ``POLICY_INTERVAL`` frames, or when lights come or
go), plan this frame's captures and assign map records to FoV lights.
execute: render the planned captures, commit them, upload the records.

Per-frame work is proportional to what changed (new, moved or captured lights),
not to the number of lights: bookkeeping lives in numpy arrays indexed by
light-table row, and records persist in slots.
"""

from __future__ import annotations

import numpy as np

from ... import limits
from ...shadows.atlas import ShadowAtlas
from ...shadows.capture import RECORD_FLOATS, Capture, capture_for
from ...shadows.scheduler import ShadowScheduler
from ..shadow_capture import ShadowCapturer
from .base import Task

#: Frames a shadowed light may stay out of the FoV before its map is freed.
KEEP_OUT_OF_VIEW_FRAMES = 120
#: Frames between two runs of the resolution policy over every registered map
#: (sizes have hysteresis; re-sizing every frame would cost O(lights) Python).
POLICY_INTERVAL = 8


class ShadowAtlasTask(Task):
    name = "shadow_atlas"

    def __init__(self, engine, atlas_size: int | None = None, budget_texels: int | None = None):
        super().__init__(engine)
        self.atlas_size = atlas_size or limits.SHADOW_ATLAS_SIZE_DEFAULT
        self.scheduler = ShadowScheduler(
            ShadowAtlas(self.atlas_size),
            budget_texels=budget_texels or limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
            pass_overhead_texels=limits.SHADOW_PASS_OVERHEAD_TEXELS,
        )
        self.capturer: ShadowCapturer | None = None
        #: Tests: plan nothing, so maps keep their last capture.
        self.frozen = False
        self._row_of: dict[str, int] = {}  # registered key -> light-table row
        self._captures: dict[str, Capture] = {}  # key -> the light's current capture
        self._slot_of: dict[str, int] = {}  # key -> record slot
        self._free_slots: list[int] = []
        self._records = np.zeros((0, RECORD_FLOATS), dtype=np.float32)
        self._slot_valid = np.zeros(0, dtype=bool)
        self._slot_rect: list[object] = []
        self._records_dirty = True
        self._last_seen = np.full(0, -1, dtype=np.int64)  # per light-table row
        self._seen_version = np.full(0, -1, dtype=np.int64)
        self._slot_of_row = np.full(0, -1, dtype=np.int64)
        self._plan = []
        self._last_policy = -(10**9)
        self._membership_changed = False
        self.records_ssbo = None
        self.last_stats = None

    # -- per-row arrays --
    def _grow(self, n: int) -> None:
        if len(self._last_seen) >= n:
            return
        m = max(n, 2 * len(self._last_seen), 64)
        for name, fill in (("_last_seen", -1), ("_seen_version", -1), ("_slot_of_row", -1)):
            old = getattr(self, name)
            new = np.full(m, fill, dtype=np.int64)
            new[: len(old)] = old
            setattr(self, name, new)

    def _slot(self, key: str) -> int:
        s = self._slot_of.get(key)
        if s is None:
            if self._free_slots:
                s = self._free_slots.pop()
            else:
                s = len(self._slot_rect)
                self._slot_rect.append(None)
                if s >= len(self._records):
                    cap = max(64, 2 * len(self._records))
                    rec = np.zeros((cap, RECORD_FLOATS), dtype=np.float32)
                    rec[: len(self._records)] = self._records
                    val = np.zeros(cap, dtype=bool)
                    val[: len(self._slot_valid)] = self._slot_valid
                    self._records, self._slot_valid = rec, val
            self._slot_of[key] = s
        return s

    def _forget(self, key: str) -> None:
        if key in self.scheduler:
            self.scheduler.remove_light(key)
        row = self._row_of.pop(key, None)
        self._captures.pop(key, None)
        s = self._slot_of.pop(key, None)
        if s is not None:
            self._slot_valid[s] = False
            self._slot_rect[s] = None
            self._free_slots.append(s)
        if row is not None and row < len(self._slot_of_row):
            self._slot_of_row[row] = -1
            self._seen_version[row] = -1
        self._membership_changed = True

    # -- phases --
    def prepare(self, frame) -> None:
        eng = self.engine
        d = eng.delegate
        if not frame.settings.shadows or not eng.method.uses_local_lights:
            # Nothing samples local shadows (sun-only): capture nothing.
            d.fov_shadow_maps = None
            self._plan = []
            return
        t = d.light_table
        sch = self.scheduler
        fidx = eng.frame_index
        self._grow(t.n_rows)
        rows = d.fov_rows
        shadowed = rows[t.shadow_enable[rows]] if len(rows) else rows
        self._last_seen[shadowed] = fidx
        # New or changed lights only (row version moved since we last looked).
        ver = t.cols["version"][shadowed]
        changed = shadowed[ver != self._seen_version[shadowed]]
        for r in changed.tolist():
            key = t.paths[r]
            if key is None:
                continue
            old_row = self._row_of.get(key)
            if old_row is not None and old_row != r:
                self._forget(key)
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
                    passes=limits.SHADOW_OMNI_PASSES if c.omni else limits.SHADOW_SPOT_PASSES,
                )
                self._row_of[key] = r
                self._membership_changed = True
            else:
                sch.set_dynamic(key, dyn)
                sch.set_transform(key, c)
            self._captures[key] = c
            self._seen_version[r] = t.cols["version"][r]
        # Forget lights that vanished, lost their shadows or stayed out of view.
        if self._row_of and (self._membership_changed or fidx % 16 == 0 or len(changed)):
            keys = list(self._row_of)
            rr = np.fromiter((self._row_of[k] for k in keys), dtype=np.int64, count=len(keys))
            c = t.cols
            ok = c["live"][rr] & c["shadow_enable"][rr] & c["enabled"][rr]
            stale = (fidx - self._last_seen[rr]) > KEEP_OUT_OF_VIEW_FRAMES
            for i in np.nonzero(~ok | stale)[0].tolist():
                self._forget(keys[i])
            for i in np.nonzero(ok & ~stale)[0].tolist():
                if t.paths[int(rr[i])] != keys[i]:
                    self._forget(keys[i])
        # Static geometry changed inside a static map's range.
        if d.changed_static_bounds and self._captures:
            reg = list(self._captures)
            pos = np.array([self._captures[k].position for k in reg])
            rng = np.array([self._captures[k].range for k in reg])
            lo = np.array([b[0] for b in d.changed_static_bounds])
            hi = np.array([b[1] for b in d.changed_static_bounds])
            dd = pos[:, None, :] - np.clip(pos[:, None, :], lo[None], hi[None])
            hit = np.any((dd**2).sum(-1) <= (rng**2)[:, None], axis=1)
            for i in np.nonzero(hit)[0].tolist():
                sch.mark_dirty(reg[i], "geometry")
        d.changed_static_bounds.clear()
        # Resolution policy (sizes, priorities), amortised.
        if self._row_of and (
            self._membership_changed or fidx - self._last_policy >= POLICY_INTERVAL
        ):
            keys = list(self._row_of)
            rr = np.fromiter((self._row_of[k] for k in keys), dtype=np.int64, count=len(keys))
            pos = t.cols["position"][rr]
            sch.update_lights(
                keys,
                distance_m=np.linalg.norm(pos - frame.view.position, axis=1),
                flux_lm=t.cols["flux"][rr].astype(np.float64),
                range_m=t.cols["range"][rr].astype(np.float64),
                viewport_height_px=float(frame.view.height),
                fov_y_rad=2.0 * float(np.arctan(frame.view.tan_half[1])),
                in_view=self._last_seen[rr] == fidx,
            )
            self._last_policy = fidx
            self._records_dirty = True  # rects may have moved
        self._membership_changed = False
        self._plan = [] if (self.frozen or not self._row_of) else sch.plan_frame(fidx)
        # Records: planned maps become valid this frame; rect changes invalidate.
        if self.capturer is None:
            self.capturer = ShadowCapturer(frame.ctx, self.atlas_size)
        if self._records_dirty:
            for key in self._row_of:
                s = self._slot(key)
                rect = sch.rect(key)
                valid = rect is not None and sch.is_valid(key)
                if valid and rect != self._slot_rect[s]:
                    valid = False  # moved by the atlas: invalid until re-captured
                self._slot_valid[s] = valid
            self._records_dirty = False
        for u in self._plan:
            if u.rect is None or u.transform is None:
                continue
            s = self._slot(u.key)
            self._records[s] = self.capturer.record(u.transform, u.rect)
            self._slot_rect[s] = u.rect
            self._slot_valid[s] = True
        self._slot_of_row[:] = -1
        if self._slot_of:
            keys = list(self._slot_of)
            slots = np.fromiter((self._slot_of[k] for k in keys), dtype=np.int64, count=len(keys))
            rr = np.fromiter((self._row_of[k] for k in keys), dtype=np.int64, count=len(keys))
            v = self._slot_valid[slots]
            self._slot_of_row[rr[v]] = slots[v]
        maps = self._slot_of_row[rows].astype(np.float32) if len(rows) else np.zeros(0, np.float32)
        d.fov_shadow_maps = maps
        frame.stats["shadow_maps"] = int(np.count_nonzero(maps >= 0))

    def execute(self, frame) -> None:
        if self.capturer is None:
            return
        d = self.engine.delegate
        for u in self._plan:
            if u.rect is None or u.transform is None:
                continue
            self.capturer.capture(d, u.key, u.transform, u.rect, u.dynamic)
        self.scheduler.commit(self._plan)
        n = len(self._slot_rect)
        data = self._records[: max(n, 1)].tobytes()
        if self.records_ssbo is None or self.records_ssbo.size < len(data):
            if self.records_ssbo is not None:
                self.records_ssbo.release()
            self.records_ssbo = frame.ctx.buffer(reserve=max(len(data), RECORD_FLOATS * 4 * 64))
            self._uploaded = None
        if self._plan or getattr(self, "_uploaded", None) is None:
            self.records_ssbo.write(data)
            self._uploaded = True
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
                "shadow_dynamic_age_p95": st.dynamic_age.p95,
                "shadow_atlas_occupancy": st.atlas.occupancy,
                "shadow_atlas_fragmentation": st.atlas.fragmentation,
                "shadow_evictions": st.atlas.evictions,
                "shadow_downgrades": st.atlas.downgrades,
                "shadow_unplaced": st.unplaced,
                "shadow_lights": st.lights,
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
