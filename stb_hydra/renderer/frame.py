"""Per-frame state shared by tasks, and the named render buffers they exchange."""

from __future__ import annotations

import math
import time
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Literal, TypeVar

import moderngl
import numpy as np

from .. import limits
from ..shadows.policy import DEFAULT_RESOLUTION, RESOLUTION_MODES
from .camera import ViewSetup
from .frame_data import SunSetup
from .records import DistantLights, InViewLights

T = TypeVar("T")

#: ``RenderSettings.temporal`` values (``stb render --temporal``).
TEMPORAL_MODES = ("accumulate", "taa", "off")


@dataclass
class RenderSettings:
    width: int = 256
    #: None or 0: from the camera's aspect ratio.
    height: int | None = 144
    camera: str | None = None
    lighting: str = "reference"
    seed: int = 0
    accumulate: int = 1
    sun_shadow_size: int = 2048
    #: Local-light shadows from the atlas (False: every local light unshadowed).
    shadows: bool = True
    #: Shadow atlas side (texels); None = limits.SHADOW_ATLAS_SIZE_DEFAULT.
    shadow_atlas_size: int | None = None
    #: Shadow-map capture budget, resolved here and nowhere else:
    #: None = offline (every shadow map is captured before the frame: what a still
    #: from ``stb render`` or ``stb_hydra.render`` shows); a positive number = the
    #: real-time budget in texels rendered per frame (maps refresh over several
    #: frames, e.g. ``limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT``). 0 is an error.
    shadow_budget: int | None = None
    #: Shadow-capture budget in milliseconds per frame (None: none). Each capture's
    #: time is predicted by a cost model of texels, render passes and triangles
    #: (``shadows.cost``), calibrated at start-up and re-fitted from wall-clock
    #: measurements. With ``shadow_budget`` too, a frame stops at whichever budget it
    #: reaches first; alone, it makes the render real-time (no texel limit).
    shadow_budget_ms: float | None = None
    #: Fixed cost-model coefficients (ms per Mtexel, ms per pass, ms per Mtriangle):
    #: deterministic scheduling (no clock, no re-fit), e.g. for tests. None: measured.
    shadow_cost_coeffs: tuple[float, float, float] | None = None
    #: Omni capture: "per_face" (each cube face drawn on its own with its culled
    #: batches; fastest on llvmpipe) or "one_pass" (one geometry-shader submission for
    #: all six faces; ``renderer.shadow_capture.CAPTURE_MODES``).
    shadow_capture_mode: str = "per_face"
    #: Local shadow-map sides (default ``shadows.policy.DEFAULT_RESOLUTION``, "lift")
    #: from "lift" (the flux rule, lifted to the
    #: footprint for the lights whose footprint asks for more than
    #: ``limits.SHADOW_LIFT_MIN_RATIO`` x it, within the atlas budget;
    #: ``shadows.policy.lift_targets``), "flux" (the light's projected influence
    #: sphere x sqrt(flux); ``shadows.policy.target_texels``), "footprint" (what its
    #: receivers need on screen, measured on the G-buffer by
    #: ``tasks/shadow_footprint.py``; one policy interval behind) or "max" (the larger
    #: of the two).
    shadow_resolution: str = DEFAULT_RESOLUTION
    #: Local shadow filter: "pcf" (4-tap gather) or "stochastic" (gather + a random
    #: sub-texel offset per pixel and frame; converges softer under accumulation).
    shadow_filter: str = "pcf"
    #: Temporal reuse: "accumulate" (a running average of the frames of one
    #: ``Engine.render`` call: a still camera, as ``accumulate`` frames), "taa"
    #: (reprojected history kept across frames and render calls, with subpixel
    #: jitter: a moving camera or animated objects; ``tasks/temporal.py``) or "off"
    #: (every frame on its own).
    temporal: str = "accumulate"
    #: taa only: a-trous levels of the edge-aware spatial filter of its output
    #: (``tasks/taa_filter.py``; 0 = off, at most ``limits.TAA_FILTER_LEVELS_MAX``).
    taa_filter: int = 0
    #: Extra uniform ambient radiance (nits) added to the dome, e.g. for thumbnails.
    ambient: float = 0.0
    #: GPU memory for material textures (MiB, mips included); None =
    #: ``limits.TEXTURE_BUDGET_BYTES``. Past it the largest textures are halved.
    texture_budget_mib: float | None = None
    #: ``ctx.finish()`` after every task so per-task wall times are real (benchmarks).
    profile: bool = False
    #: Lighting-method specific options (``renderer.lighting.<method>.options``).
    method_options: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.temporal not in TEMPORAL_MODES:
            raise ValueError(
                f"temporal must be one of {', '.join(TEMPORAL_MODES)}; got {self.temporal!r}"
            )
        tf = self.taa_filter
        if isinstance(tf, bool) or int(tf) != tf or not 0 <= tf <= limits.TAA_FILTER_LEVELS_MAX:
            raise ValueError(
                f"taa_filter must be 0..{limits.TAA_FILTER_LEVELS_MAX} levels; got {tf!r}"
            )
        b = self.shadow_budget
        if b is not None and (isinstance(b, bool) or int(b) != b or b <= 0):
            raise ValueError(
                f"shadow_budget must be a positive number of texels per frame, or None for "
                f"offline renders (every map captured before the frame); got {b!r}"
            )

        ms = self.shadow_budget_ms
        if ms is not None and (
            isinstance(ms, bool)
            or not isinstance(ms, (int, float))
            or not 0 < ms <= limits.SHADOW_UPDATE_BUDGET_MS_MAX
        ):
            raise ValueError(
                f"shadow_budget_ms must be a number of milliseconds in "
                f"(0, {limits.SHADOW_UPDATE_BUDGET_MS_MAX:g}], or None; got {ms!r}"
            )
        tb = self.texture_budget_mib
        if tb is not None and (
            isinstance(tb, bool) or not isinstance(tb, (int, float)) or not 0 < tb < 1e9
        ):
            raise ValueError(f"texture_budget_mib must be a positive number of MiB; got {tb!r}")
        cc = self.shadow_cost_coeffs
        if cc is not None:
            try:
                ok = len(cc) == 3 and all(math.isfinite(float(x)) and float(x) >= 0 for x in cc)
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(
                    f"shadow_cost_coeffs must be 3 numbers >= 0 (ms per Mtexel, per pass, "
                    f"per Mtriangle), or None; got {cc!r}"
                )
            self.shadow_cost_coeffs = (float(cc[0]), float(cc[1]), float(cc[2]))
        if self.shadow_resolution not in RESOLUTION_MODES:
            raise ValueError(
                f"shadow_resolution must be one of {RESOLUTION_MODES}; "
                f"got {self.shadow_resolution!r}"
            )
        if self.shadow_capture_mode not in ("per_face", "one_pass"):
            raise ValueError(
                f"shadow_capture_mode must be 'per_face' or 'one_pass'; "
                f"got {self.shadow_capture_mode!r}"
            )

    def realtime_shadow_budget(self) -> int:
        """Texels the shadow scheduler may render per frame (offline: unbounded; a
        millisecond budget alone: no texel limit)."""
        if self.shadow_budget is None:
            return limits.SHADOW_UPDATE_BUDGET_TEXELS_OFFLINE
        return int(self.shadow_budget)


class Timings:
    """Wall-clock per task (ms), per frame: the last ``limits.TIMINGS_KEPT_FRAMES``
    frames at least (older ones are dropped, so a long-running engine stays bounded)."""

    def __init__(self) -> None:
        self.frames: list[dict[str, float]] = []
        self.current: dict[str, float] = defaultdict(float)
        #: Work done for the next frame but not as a frame of its own ({key: ms}).
        self._carried: dict[str, float] = {}

    def start_frame(self) -> None:
        self.current = defaultdict(float, self._carried)
        self._carried = {}

    def carry_frame(self, name: str) -> None:
        """Close the current frame without recording it as a frame: its total (the sum
        of its top-level keys, ms) goes into the next frame as ``name`` (e.g. the
        offline shadow-footprint probe, which renders part of a frame that is never
        shown: ``Engine._probe_footprint``)."""
        total = sum(v for k, v in self.current.items() if "." not in k)
        self._carried[name] = self._carried.get(name, 0.0) + total
        self.current = defaultdict(float)

    def end_frame(self) -> None:
        self.frames.append(dict(self.current))
        keep = limits.TIMINGS_KEPT_FRAMES
        if len(self.frames) >= 2 * keep:  # trimmed in chunks: amortised O(1) per frame
            del self.frames[:-keep]

    def add(self, name: str, ms: float) -> None:
        self.current[name] += ms

    def medians(self, skip: int = 0) -> dict[str, float]:
        frames = self.frames[skip:] or self.frames
        keys = sorted({k for f in frames for k in f})
        return {k: float(np.median([f.get(k, 0.0) for f in frames])) for k in keys}


class timed:
    """Context manager adding a task's wall time (optionally after ctx.finish())."""

    def __init__(
        self, timings: Timings, name: str, ctx: moderngl.Context | None, finish: bool
    ) -> None:
        self.t, self.name, self.ctx, self.finish = timings, name, ctx, finish

    def __enter__(self) -> timed:
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        if self.finish and self.ctx is not None:
            self.ctx.finish()
        self.t.add(self.name, (time.perf_counter() - self.t0) * 1e3)
        return False


class RenderBuffers:
    """Named textures/framebuffers sized to the viewport (Hydra's render buffers)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.size = (0, 0)
        self.textures: dict[str, moderngl.Texture] = {}
        self.fbos: dict[str, moderngl.Framebuffer] = {}
        self._fbo_deps: dict[str, tuple[str, ...]] = {}

    def resize(self, width: int, height: int) -> None:
        if (width, height) == self.size:
            return
        self.release()
        self.size = (width, height)

    def texture(
        self,
        name: str,
        components: int,
        dtype: str,
        size: tuple[int, int] | None = None,
        nearest: bool = True,
    ) -> moderngl.Texture:
        size = size or self.size
        t = self.textures.get(name)
        if t is None or t.size != tuple(size) or t.components != components or t.dtype != dtype:
            if t is not None:
                t.release()
                self._drop_fbos_using(name)
            t = self.ctx.texture(size, components, dtype=dtype)
            if nearest:
                t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
            self.textures[name] = t
        return t

    def _drop_fbos_using(self, tex_name: str) -> None:
        for fb_name, deps in list(self._fbo_deps.items()):
            if tex_name in deps:
                self.fbos.pop(fb_name).release()
                del self._fbo_deps[fb_name]

    def set_texture(self, name: str, tex: moderngl.Texture) -> None:
        old = self.textures.get(name)
        if old is not None and old is not tex:
            old.release()
            self._drop_fbos_using(name)
        self.textures[name] = tex

    def release_texture(self, name: str) -> None:
        """Free the texture ``name`` (and the framebuffers using it), if allocated."""
        t = self.textures.pop(name, None)
        if t is not None:
            self._drop_fbos_using(name)
            t.release()

    def framebuffer(
        self, name: str, colors: list[str], depth: str | None = None
    ) -> moderngl.Framebuffer:
        fb = self.fbos.get(name)
        if fb is None:
            fb = self.ctx.framebuffer(
                color_attachments=[self.textures[c] for c in colors],
                depth_attachment=self.textures[depth] if depth else None,
            )
            self.fbos[name] = fb
            self._fbo_deps[name] = (*colors, *([depth] if depth else []))
        return fb

    def release(self) -> None:
        for fb in self.fbos.values():
            fb.release()
        for t in self.textures.values():
            t.release()
        self.fbos.clear()
        self.textures.clear()
        self._fbo_deps.clear()


class PassScopeError(KeyError):
    """A pass touched a resource it did not declare."""

    def __str__(self) -> str:
        return str(self.args[0])


class ScopedBuffers:
    """The render buffers as one pass may see them: only what it declared."""

    def __init__(
        self, buffers: RenderBuffers, pass_name: str, reads: set[str], writes: set[str]
    ) -> None:
        self._b = buffers
        self._pass = pass_name
        self._reads = reads | writes
        self._writes = writes
        self.ctx = buffers.ctx
        self.textures = _ScopedTextures(self)

    @property
    def size(self) -> tuple[int, int]:
        return self._b.size

    def _check(self, name: str, write: bool) -> None:
        allowed = self._writes if write else self._reads
        if name not in allowed:
            what = "write" if write else "read"
            raise PassScopeError(
                f"pass '{self._pass}' tried to {what} texture '{name}' without declaring it"
            )

    def texture(
        self,
        name: str,
        components: int,
        dtype: str,
        size: tuple[int, int] | None = None,
        nearest: bool = True,
    ) -> moderngl.Texture:
        self._check(name, True)
        return self._b.texture(name, components, dtype, size, nearest)

    def set_texture(self, name: str, tex: moderngl.Texture) -> None:
        self._check(name, True)
        self._b.set_texture(name, tex)

    def framebuffer(
        self, name: str, colors: list[str], depth: str | None = None
    ) -> moderngl.Framebuffer:
        for c in (*colors, *([depth] if depth else [])):
            self._check(c, True)
        return self._b.framebuffer(name, colors, depth)


class _ScopedTextures:
    def __init__(self, scope: ScopedBuffers) -> None:
        self._s = scope

    def __getitem__(self, name: str) -> moderngl.Texture:
        self._s._check(name, False)
        return self._s._b.textures[name]

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self._s._reads and name in self._s._b.textures

    def get(self, name: str, default: moderngl.Texture | None = None) -> moderngl.Texture | None:
        return self[name] if name in self else default


@dataclass
class FrameContext:
    """One frame: view, settings, render buffers, timings and the typed records
    passes exchange (``put``/``get``, checked against the running pass's
    declarations; cleared every frame)."""

    ctx: moderngl.Context
    settings: RenderSettings
    view: ViewSetup
    buffers: RenderBuffers | ScopedBuffers
    timings: Timings
    frame_index: int = 0
    seed: int = 0
    stats: dict = field(default_factory=dict)
    #: Last frame of an accumulation sequence (display + readback run only then).
    final: bool = True
    #: This frame's place in the frames being integrated: the frames averaged before
    #: it (``Engine.render``'s accumulation or a previewer's still-camera running
    #: average; 0 for a lone frame), the frame index under ``temporal="taa"``. Exact
    #: methods rotate their area-shadow point sets by it, so integrated frames
    #: converge and a lone real-time frame is the fixed set.
    sample_index: int = 0
    records: dict[type, object] = field(default_factory=dict)
    #: Warnings about the user's scene raised by passes (the engine deduplicates).
    warnings: list[str] = field(default_factory=list)
    _scope: tuple[str, frozenset[type], frozenset[type]] | None = None

    def warn(self, msg: str) -> None:
        """A one-line warning about the scene (collected by the engine)."""
        self.warnings.append(msg)

    # -- records --
    def enter(self, name: str, reads: frozenset[type], writes: frozenset[type]) -> None:
        self._scope = (name, reads, writes)

    def leave(self) -> None:
        self._scope = None

    def put(self, record: object) -> None:
        cls = type(record)
        if self._scope is not None and cls not in self._scope[2]:
            raise PassScopeError(
                f"pass '{self._scope[0]}' wrote record {cls.__name__} without declaring it"
            )
        self.records[cls] = record

    def get(self, cls: type[T]) -> T:
        if self._scope is not None and cls not in self._scope[1] and cls not in self._scope[2]:
            raise PassScopeError(
                f"pass '{self._scope[0]}' read record {cls.__name__} without declaring it"
            )
        rec = self.records.get(cls)
        if rec is None:
            who = self._scope[0] if self._scope else "?"
            raise PassScopeError(
                f"pass '{who}' read record {cls.__name__} before any pass wrote it this frame"
            )
        return rec  # type: ignore[return-value]

    def has(self, cls: type) -> bool:
        """True when ``cls`` was written this frame (for optional reads)."""
        return cls in self.records

    # -- convenience views of common records --
    @property
    def light_count(self) -> int:
        """Lights in view (``InViewLights``; 0 when no pass culls lights)."""
        return self.get(InViewLights).count if self.has(InViewLights) else 0

    @property
    def sun(self) -> SunSetup:
        return self.get(DistantLights).sun

    @property
    def ambient(self) -> np.ndarray:
        return self.get(DistantLights).ambient

    @property
    def extra_distant(self) -> list:
        return self.get(DistantLights).extra

    def timings_scope(self, name: str) -> timed:
        """Time a sub-pass as ``lighting.<name>`` (ctx.finish() when profiling)."""
        return timed(self.timings, "lighting." + name, self.ctx, self.settings.profile)
