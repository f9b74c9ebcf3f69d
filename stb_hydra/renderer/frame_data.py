"""The per-frame uniform block (``shaders/common/frame.glsl``, std140, binding 0)."""

from __future__ import annotations

from dataclasses import dataclass, field

import moderngl
import numpy as np

from .. import limits
from .camera import ViewSetup
from .shader_constants import UBO_FRAME

#: mat4 x 6 + vec4 x 9 + vec4[3] x 2 + uvec4 (std140: every member 16-byte aligned).
FRAME_BLOCK_BYTES = 6 * 64 + 16 * 16
MAX_EXTRA_DISTANT = limits.MAX_EXTRA_DISTANT


@dataclass
class SunSetup:
    """The shadowed DistantLight (the brightest one) in the render frame."""

    direction_to_sun: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))
    illuminance: np.ndarray = field(default_factory=lambda: np.zeros(3))  # lux RGB
    enabled: bool = False
    shadow: bool = False
    diffuse: float = 1.0
    specular: float = 1.0
    shadow_color: np.ndarray = field(default_factory=lambda: np.zeros(3))
    view_proj: np.ndarray = field(default_factory=lambda: np.eye(4))
    depth_bias: float = 0.0
    normal_bias: float = 0.0
    texel: float = 1.0 / 2048.0


def pack_frame_block(
    view: ViewSetup,
    prev_view_proj: np.ndarray,
    sun: SunSetup,
    ambient: np.ndarray,
    light_count: int,
    frame_index: int,
    seed: int,
    big_tiles: tuple[int, int] = (0, 0),
    extra_distant: list | None = None,
) -> bytes:
    """``extra_distant``: up to 3 (direction_to_light, lux_rgb, diffuse, specular)."""
    f = np.zeros(6 * 16 + 15 * 4, dtype=np.float32)
    extra = list(extra_distant or [])[:MAX_EXTRA_DISTANT]
    mats = [view.view, view.proj, view.view_proj, view.inv_view, prev_view_proj, sun.view_proj]
    for i, m in enumerate(mats):
        f[i * 16 : (i + 1) * 16] = np.asarray(m, dtype=np.float32).reshape(16)
    o = 6 * 16
    vecs = [
        (*view.position, 1.0 if view.orthographic else 0.0),
        (view.width, view.height, 1.0 / view.width, 1.0 / view.height),
        (*view.tan_half, *view.offset),
        (view.near, view.far, float(frame_index), view.exposure_scale),
        (*sun.direction_to_sun, 1.0 if sun.enabled else 0.0),
        (*sun.illuminance, 1.0 if sun.shadow else 0.0),
        (sun.diffuse, sun.specular, sun.depth_bias, sun.normal_bias),
        (*sun.shadow_color, sun.texel),
        (*np.asarray(ambient, dtype=np.float64), float(len(extra))),
    ]
    dirs = [(0.0, 1.0, 0.0, 0.0)] * MAX_EXTRA_DISTANT
    illum = [(0.0, 0.0, 0.0, 0.0)] * MAX_EXTRA_DISTANT
    for i, (d, e, kd, ks) in enumerate(extra):
        dirs[i] = (*np.asarray(d, dtype=np.float64), kd)
        illum[i] = (*np.asarray(e, dtype=np.float64), ks)
    vecs += dirs + illum
    for i, v in enumerate(vecs):
        f[o + 4 * i : o + 4 * i + 4] = v
    counts = np.array([light_count, seed & 0xFFFFFFFF, *big_tiles], dtype=np.uint32)
    return f.tobytes() + counts.tobytes()


class FrameUniforms:
    """Owns the UBO and binds it to block binding 0 for every program."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.buffer = ctx.buffer(reserve=FRAME_BLOCK_BYTES, dynamic=True)

    def update(self, data: bytes) -> None:
        assert len(data) == FRAME_BLOCK_BYTES, len(data)
        self.buffer.write(data)
        self.buffer.bind_to_uniform_block(UBO_FRAME)

    def release(self) -> None:
        self.buffer.release()
