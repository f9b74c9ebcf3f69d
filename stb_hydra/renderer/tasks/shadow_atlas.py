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

import time
from typing import TYPE_CHECKING, cast

import moderngl
import numpy as np

from ... import limits
from ...shadows import policy
from ...shadows.atlas import ShadowAtlas
from ...shadows.capture import (
    RECORD_FLOATS,
    Capture,
    capture_for_row,
    omni_face_view_projs_many,
    spot_view_proj,
)
from ...shadows.cost import ShadowCostModel
from ...shadows.culling import boxes_in_sphere, triangles_submitted
from ...shadows.scheduler import SchedulerStats, ShadowScheduler, ShadowUpdate
from ..frame import FrameContext
from ..graph import Imported, Rec
from ..records import InViewLights, ShadowSlots
from ..shadow_capture import ShadowCapturer, calibrate_cost
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import BatchArrays, GLRenderDelegate

#: Angular span per side of an octahedral omni map (``shadows.capture.texel_angle``).
OMNI_SPAN = float(np.sqrt(4.0 * np.pi))
#: Frames a shadowed light may stay out of the FoV before its map is freed.
KEEP_OUT_OF_VIEW_FRAMES = 120
#: Frames between two runs of the resolution policy over every registered map
#: (sizes have hysteresis; re-sizing every frame would cost O(lights) Python).
POLICY_INTERVAL = 8


class ShadowAtlasTask(Pass):
    name = "shadow_atlas"
    reads = (Imported("light_table"), Imported("meshes"), Rec(InViewLights))
    writes = (Rec(ShadowSlots),)

    def __init__(
        self,
        delegate: GLRenderDelegate,
        atlas_size: int | None = None,
        budget_texels: int | None = None,
        enabled: bool = True,
        budget_ms: float | None = None,
        cost_coeffs: tuple[float, float, float] | None = None,
        capture_mode: str = "per_face",
        resolution: str = policy.DEFAULT_RESOLUTION,
    ) -> None:
        super().__init__(delegate)
        #: Map sides from "lift", "flux", "footprint" or "max"
        #: (``RenderSettings.shadow_resolution``).
        self.resolution = resolution
        #: Footprint pass results: key -> need (texels at 1 texel/px), the frame measured,
        #: whether the policy has used them, whether a measurement is due now.
        self._footprint: dict[str, float] = {}
        self._footprint_frame = -1
        self._footprint_new = False
        self._footprint_due = True
        #: False: nothing samples local shadows (sun-only, --no-shadows): capture nothing.
        self.enabled = enabled
        self.atlas_size = atlas_size or limits.SHADOW_ATLAS_SIZE_DEFAULT
        #: Fixed coefficients: deterministic (no clock); else calibrated + re-fitted.
        self.cost_model = ShadowCostModel(cost_coeffs, fixed=cost_coeffs is not None)
        self.scheduler = ShadowScheduler(
            ShadowAtlas(self.atlas_size),
            budget_texels=budget_texels or limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
            pass_overhead_texels=limits.SHADOW_PASS_OVERHEAD_TEXELS,
            budget_ms=budget_ms,
            cost_model=self.cost_model,
        )
        #: Wall-clock capture timing (ctx.finish() around the captures) feeds the cost
        #: model: only with a time budget and a model that is not fixed.
        self.measure = budget_ms is not None and cost_coeffs is None
        self.capture_mode = capture_mode
        self.capturer: ShadowCapturer | None = None
        self._work_batches: object = None  # batch list the per-light work was computed for
        self._work_arrays: BatchArrays | None = None  # and its arrays
        #: Last frame's capture time (ms, wall clock; None when not measured).
        self.last_capture_ms: float | None = None
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
        self._plan: list[ShadowUpdate] = []
        self._last_policy = -(10**9)
        self._membership_changed = False
        self.records_ssbo: moderngl.Buffer | None = None
        self._uploaded = False
        self.last_stats: SchedulerStats | None = None

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
        if self.capturer is not None:
            self.capturer.drop_partial(key)
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
    def prepare(self, frame: FrameContext) -> None:
        if not self.enabled:
            self._plan = []
            frame.put(ShadowSlots())
            return
        if self.capturer is None:
            self.capturer = ShadowCapturer(frame.ctx, self.atlas_size, mode=self.capture_mode)
            if self.measure:
                self.cost_model.set_prior(calibrate_cost(frame.ctx))
        t = self.delegate.light_table
        self._grow(t.n_rows)
        rows = frame.get(InViewLights).rows
        changed = self._register_changed(rows, frame.frame_index)
        self._forget_gone(frame.frame_index, len(changed))
        self._mark_static_geometry()
        self._run_policy(frame)
        self._membership_changed = False
        fidx = frame.frame_index
        self._plan = [] if (self.frozen or not self._row_of) else self.scheduler.plan_frame(fidx)
        self._update_records(self.capturer)
        self._reserve_records_buffer(frame)
        maps = self._slots_for(rows)
        frame.put(ShadowSlots(maps=maps, atlas=self.capturer.atlas, records=self.records_ssbo))
        frame.stats["shadow_maps"] = int(np.count_nonzero(maps >= 0))

    def _register_changed(self, rows: np.ndarray, fidx: int) -> np.ndarray:
        """Register new shadowed in-view lights, update moved/edited ones (rows whose
        table version moved since we last looked). Returns those rows."""
        t = self.delegate.light_table
        sch = self.scheduler
        shadowed = rows[t.shadow_enable[rows]] if len(rows) else rows
        self._last_seen[shadowed] = fidx
        ver = t.cols["version"][shadowed]
        changed = shadowed[ver != self._seen_version[shadowed]]
        touched: list[str] = []
        omni_passes = self.capturer.omni_passes if self.capturer else limits.SHADOW_OMNI_PASSES
        # per-face omni captures may be split into their faces (a time budget only)
        omni_faces = 6 if omni_passes == limits.SHADOW_OMNI_PASSES else 1
        for r in changed.tolist():
            key = t.paths[r]
            if key is None:
                continue
            old_row = self._row_of.get(key)
            if old_row is not None and old_row != r:
                self._forget(key)
            c = capture_for_row(t, r)
            dyn = bool(t.shadow_dynamic[r])
            if key not in sch:
                sch.add_light(
                    key,
                    dynamic=dyn,
                    transform=c,
                    cost_factor=limits.SHADOW_OMNI_COST_FACTOR if c.omni else 1.0,
                    passes=omni_passes if c.omni else limits.SHADOW_SPOT_PASSES,
                    faces=omni_faces if c.omni else 1,
                )
                self._row_of[key] = r
                self._membership_changed = True
            else:
                sch.set_dynamic(key, dyn)
                sch.set_transform(key, c)
            self._captures[key] = c
            self._seen_version[r] = t.cols["version"][r]
            touched.append(key)
        batches = self.delegate.batches
        if batches is not self._work_batches:  # geometry changed: the lights it reaches
            self._work_batches = batches
            touched = self._reached_by_geometry(touched)
        self._update_work(touched)
        return changed

    def _reached_by_geometry(self, touched: list[str]) -> list[str]:
        """The batches were rebuilt: ``touched`` and every registered light whose work
        (``_update_work``) may differ -- all of them when the batch count changed, else
        those whose range sphere touches a batch whose bounds, triangles or dynamic flag
        changed, before or after (a batch outside a light's sphere adds nothing to its
        count either way: the others' work is the same number)."""
        arr = self.delegate.batch_arrays()
        old, self._work_arrays = self._work_arrays, arr
        if old is None or len(old.lo) != len(arr.lo):
            return list(self._captures)
        diff = ~(
            (old.lo == arr.lo).all(axis=1)
            & (old.hi == arr.hi).all(axis=1)
            & (old.triangles == arr.triangles)
            & (old.dynamic == arr.dynamic)
        )
        if not diff.any() or not self._captures:
            return touched
        reg = list(self._captures)
        pos = np.array([self._captures[k].position for k in reg], dtype=np.float64)
        rng = np.array([self._captures[k].range for k in reg], dtype=np.float64)
        hit = boxes_in_sphere(pos, rng, old.lo[diff], old.hi[diff]).any(axis=1)
        hit |= boxes_in_sphere(pos, rng, arr.lo[diff], arr.hi[diff]).any(axis=1)
        seen = set(touched)
        return touched + [reg[i] for i in np.nonzero(hit)[0].tolist() if reg[i] not in seen]

    def _update_work(self, keys: list[str]) -> None:
        """Triangles each of ``keys``' captures submits after culling, per face (cost
        model; a split capture's chunks are priced with them), vectorised over the lights
        (``shadows.culling.triangles_submitted``)."""
        if not keys:
            return
        arr = self.delegate.batch_arrays()
        caps = [self._captures[k] for k in keys]
        n = len(caps)
        omni = np.fromiter((c.omni for c in caps), dtype=bool, count=n)
        pos = np.array([c.position for c in caps], dtype=np.float64)
        near = np.fromiter((c.near for c in caps), dtype=np.float64, count=n)
        rng = np.fromiter((c.range for c in caps), dtype=np.float64, count=n)
        vps = np.zeros((n, 6, 4, 4))
        valid = np.zeros((n, 6), dtype=bool)
        if omni.any():
            vps[omni] = omni_face_view_projs_many(pos[omni], near[omni], rng[omni])
            valid[omni] = True
        for i in np.nonzero(~omni)[0].tolist():  # spot lights: one frustum each
            vps[i, 0] = spot_view_proj(caps[i])
            valid[i, 0] = True
        dyn = np.fromiter((self.scheduler.is_dynamic(k) for k in keys), dtype=bool, count=n)
        bounds = (arr.lo, arr.hi)
        tri_all = triangles_submitted(vps, valid, pos, rng, *bounds, arr.triangles, per_face=True)
        static_tris = np.where(arr.dynamic, 0.0, arr.triangles)
        tri_static = (
            triangles_submitted(vps, valid, pos, rng, *bounds, static_tris, per_face=True)
            if arr.dynamic.any()
            else tri_all
        )
        tris = np.where(dyn[:, None], tri_all, tri_static)  # (n, 6)
        sch = self.scheduler
        for i, k in enumerate(keys):
            sch.set_work(k, tris[i] if omni[i] and sch.faces(k) == 6 else float(tris[i].sum()))

    def _forget_gone(self, fidx: int, n_changed: int) -> None:
        """Forget lights that vanished, lost their shadows or stayed out of view."""
        if not (self._row_of and (self._membership_changed or fidx % 16 == 0 or n_changed)):
            return
        t = self.delegate.light_table
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

    def _mark_static_geometry(self) -> None:
        """Static geometry changed inside a static map's range: re-capture it."""
        d = self.delegate
        if d.changed_static_bounds and self._captures:
            reg = list(self._captures)
            pos = np.array([self._captures[k].position for k in reg])
            rng = np.array([self._captures[k].range for k in reg])
            lo = np.array([b[0] for b in d.changed_static_bounds])
            hi = np.array([b[1] for b in d.changed_static_bounds])
            dd = pos[:, None, :] - np.clip(pos[:, None, :], lo[None], hi[None])
            hit = np.any((dd**2).sum(-1) <= (rng**2)[:, None], axis=1)
            for i in np.nonzero(hit)[0].tolist():
                self.scheduler.mark_dirty(reg[i], "geometry")
        d.changed_static_bounds.clear()

    def _run_policy(self, frame: FrameContext) -> None:
        """Resolution policy (sizes, priorities), amortised over POLICY_INTERVAL frames."""
        fidx = frame.frame_index
        if not self._row_of or not (
            self._membership_changed
            or fidx - self._last_policy >= POLICY_INTERVAL
            or self._footprint_new
        ):
            return
        t = self.delegate.light_table
        keys = list(self._row_of)
        rr = np.fromiter((self._row_of[k] for k in keys), dtype=np.int64, count=len(keys))
        pos = t.cols["position"][rr]
        self.scheduler.update_lights(
            keys,
            distance_m=np.linalg.norm(pos - frame.view.position, axis=1),
            # Flux as the camera sees it (lm x exposure scale), like the ranges: the
            # map sizes, hence the display image, do not depend on the unit scale.
            flux_lm=t.cols["flux"][rr].astype(np.float64) * float(frame.view.exposure_scale),
            range_m=t.cols["range"][rr].astype(np.float64),
            viewport_height_px=float(frame.view.height),
            fov_y_rad=2.0 * float(np.arctan(frame.view.tan_half[1])),
            in_view=self._last_seen[rr] == fidx,
            footprint_need=self._footprint_need(keys),
            resolution=self.resolution,
        )
        if self._membership_changed:
            self._footprint_due = True
        self._footprint_new = False
        self._last_policy = fidx
        self._records_dirty = True  # rects may have moved

    # -- screen footprint (tasks/shadow_footprint.py) --
    def wants_footprint(self, fidx: int) -> bool:
        """Measure the footprint this frame: not "flux", lights registered, and the
        policy runs next frame (or lights came / went since the last measurement)."""
        if self.resolution == "flux" or not self.enabled or not self._row_of:
            return False
        return self._footprint_due or fidx + 1 - self._last_policy >= POLICY_INTERVAL

    def footprint_candidates(self, rows: np.ndarray) -> tuple[list[str], np.ndarray, np.ndarray]:
        """(keys, FoV light index, map angular span per side) of the registered lights
        among in-view ``rows`` (light-buffer order), at most
        ``SHADOW_FOOTPRINT_LIGHTS_MAX`` of the highest scheduler priority."""
        t = self.delegate.light_table
        cand: list[tuple[float, int, str]] = []
        for i, r in enumerate(rows.tolist()):
            key = t.paths[r]
            if key is None or key not in self._captures or self._row_of.get(key) != r:
                continue
            cand.append((-self.scheduler.priority(key), i, key))
        cand.sort()
        cand = cand[: limits.SHADOW_FOOTPRINT_LIGHTS_MAX]
        keys = [k for _p, _i, k in cand]
        idx = np.array([i for _p, i, _k in cand], dtype=np.float64)
        caps = [self._captures[k] for k in keys]
        span = np.array(
            [OMNI_SPAN if c.omni else 2.0 * float(np.tan(c.spot_half_angle)) for c in caps],
            dtype=np.float64,
        )
        return keys, idx, span

    def set_footprint(self, keys: list[str], need: np.ndarray, fidx: int) -> None:
        """The footprint pass's measure (texels at 1 texel per pixel) for ``keys``; the
        policy uses it at its next run, which is forced to the next frame."""
        self._footprint = dict(zip(keys, np.asarray(need, dtype=np.float64).tolist()))
        self._footprint_frame = fidx
        self._footprint_new = True
        self._footprint_due = False

    @property
    def footprint_measured(self) -> bool:
        """The footprint pass has measured at least once (``Engine._probe_footprint``)."""
        return self._footprint_frame >= 0

    def footprint(self, key: str) -> float | None:
        """Last measured need of ``key`` (texels at 1 texel/px; None: not measured)."""
        return self._footprint.get(key)

    def _footprint_need(self, keys: list[str]) -> np.ndarray | None:
        if self.resolution == "flux" or self._footprint_frame < 0:
            return None
        fp = self._footprint
        return np.fromiter((fp.get(k, np.nan) for k in keys), dtype=np.float64, count=len(keys))

    def _update_records(self, capturer: ShadowCapturer) -> None:
        """Planned maps become valid this frame; rect changes invalidate."""
        sch = self.scheduler
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
            if u.rect is None or u.transform is None or not u.complete:
                continue  # (a split map's record changes with the chunk that completes it)
            # The scheduler keeps keys and transforms opaque: ours are paths and Captures.
            s = self._slot(cast(str, u.key))
            self._records[s] = capturer.record(cast(Capture, u.transform), u.rect)
            self._slot_rect[s] = u.rect
            self._slot_valid[s] = True

    def _slots_for(self, rows: np.ndarray) -> np.ndarray:
        """Record slot per in-view row (float32 for the light record; -1: none). A light
        whose shadows were switched off has none from that frame on, though its map
        is only forgotten later (``_forget_gone``): every method then shades it
        unshadowed at once, as the reference's loops without shadow code do."""
        self._slot_of_row[:] = -1
        if self._slot_of:
            keys = list(self._slot_of)
            slots = np.fromiter((self._slot_of[k] for k in keys), dtype=np.int64, count=len(keys))
            rr = np.fromiter((self._row_of[k] for k in keys), dtype=np.int64, count=len(keys))
            v = self._slot_valid[slots]
            self._slot_of_row[rr[v]] = slots[v]
        if not len(rows):
            return np.zeros(0, np.float32)
        on = self.delegate.light_table.shadow_enable[rows]
        return np.where(on, self._slot_of_row[rows], -1).astype(np.float32)

    def _reserve_records_buffer(self, frame: FrameContext) -> None:
        nbytes = max(len(self._slot_rect), 1) * RECORD_FLOATS * 4
        if self.records_ssbo is None or self.records_ssbo.size < nbytes:
            if self.records_ssbo is not None:
                self.records_ssbo.release()
            self.records_ssbo = frame.ctx.buffer(reserve=max(nbytes, RECORD_FLOATS * 4 * 64))
            self._uploaded = False

    def registered_keys(self) -> list[str]:
        """Prim paths of the shadowed lights the scheduler tracks (tests, tools)."""
        return list(self._row_of)

    def execute(self, frame: FrameContext) -> None:
        if self.capturer is None or not self.enabled:
            return
        d = self.delegate
        measure = self.measure and bool(self._plan)
        if measure:
            frame.ctx.finish()  # earlier passes' work is not the captures'
        t0 = time.perf_counter()
        texels = passes = 0
        triangles = 0.0
        for u in self._plan:
            if u.rect is None or u.transform is None:
                continue
            key, c = cast(str, u.key), cast(Capture, u.transform)
            w = self.capturer.capture(d, key, c, u.rect, u.dynamic, u.faces, u.first, u.complete)
            texels += w.texels
            passes += w.passes
            triangles += w.triangles
        if measure:
            frame.ctx.finish()
            ms = (time.perf_counter() - t0) * 1e3
            self.last_capture_ms = ms
            self.cost_model.observe(texels, passes, triangles, ms)
        self.scheduler.commit(self._plan)
        n = len(self._slot_rect)
        if self._plan or not self._uploaded:
            assert self.records_ssbo is not None  # reserved in prepare
            self.records_ssbo.write(self._records[: max(n, 1)].tobytes())
            self._uploaded = True
        st = self.scheduler.stats()
        self.last_stats = st
        frame.stats.update(
            {
                "shadow_maps_updated": st.maps_updated,
                "shadow_texels_rendered": st.texels_rendered,
                # None: offline, unlimited (every map captured before the frame)
                "shadow_budget_texels": (
                    None
                    if st.budget_texels >= limits.SHADOW_UPDATE_BUDGET_TEXELS_OFFLINE
                    else st.budget_texels
                ),
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
                "shadow_budget_ms": st.budget_ms,
                "shadow_ms_planned": st.ms_planned,
                "shadow_triangles": triangles,
                "shadow_stale_maps": st.stale_maps,
                "shadow_partial_maps": st.partial_maps,
            }
        )

    def release(self) -> None:
        if self.capturer is not None:
            self.capturer.release()
            self.capturer = None
        if self.records_ssbo is not None:
            self.records_ssbo.release()
            self.records_ssbo = None
