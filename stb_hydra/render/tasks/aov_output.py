"""AOV readback: colour (scene-linear float), display (uint8), depth, normal, albedo."""

from __future__ import annotations

import numpy as np

from .base import Task

AOVS = ("color", "depth", "normal", "albedo", "display")


def _read(tex, comps: int, dtype) -> np.ndarray:
    w, h = tex.size
    a = np.frombuffer(tex.read(), dtype=dtype).reshape(h, w, comps)
    return np.flipud(a)  # GL rows are bottom-up


def oct_decode(e: np.ndarray) -> np.ndarray:
    n = np.dstack([e[..., 0], e[..., 1], 1.0 - np.abs(e[..., 0]) - np.abs(e[..., 1])])
    t = np.clip(-n[..., 2], 0.0, 1.0)
    n[..., 0] += np.where(n[..., 0] >= 0, -t, t)
    n[..., 1] += np.where(n[..., 1] >= 0, -t, t)
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)


class AovOutputTask(Task):
    only_final = True
    name = "aov_output"

    def __init__(self, engine) -> None:
        super().__init__(engine)
        self.requested: set[str] = {"color"}
        self.results: dict[str, np.ndarray] = {}

    def execute(self, frame) -> None:
        bufs = frame.buffers
        out: dict[str, np.ndarray] = {}
        if "color" in self.requested:
            src = bufs.textures[frame.color_buffer]
            dt = np.float16 if src.dtype == "f2" else np.float32
            out["color"] = _read(src, 4, dt).astype(np.float32)
        if "display" in self.requested and "display" in bufs.textures:
            out["display"] = _read(bufs.textures["display"], 4, np.uint8)
        if "depth" in self.requested:
            out["depth"] = _read(bufs.textures["g_depth"], 1, np.float32)[..., 0]
        if "normal" in self.requested:
            e = _read(bufs.textures["g_normal"], 2, np.float16).astype(np.float32)
            n = oct_decode(e)
            bg = _read(bufs.textures["g_depth"], 1, np.float32)[..., 0] <= 0
            n[bg] = 0.0
            out["normal"] = n.astype(np.float32)
        if "albedo" in self.requested:
            out["albedo"] = _read(bufs.textures["g_base_rough"], 4, np.float16)[..., :3].astype(
                np.float32
            )
        self.results = out
