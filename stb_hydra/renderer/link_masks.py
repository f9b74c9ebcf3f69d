"""The GPU side of light and shadow linking (the groups and masks: ``scene/links.py``).

* **Light links** reach the shaders only in scenes where some light lights less than
  everything (``LightTable.has_light_links``): the G-buffer writes each pixel's link
  group into ``g_link`` (r8ui) and :class:`LinkBufferUploader` writes the link SSBO
  (binding ``SSBO_LIGHT_LINKS``, ``shaders/common/links.glsl``), std430::

      uvec4 link_distant;                  // masks: x the sun, y..w the extra distant lights
      vec4  link_ambient[LIM_LINK_GROUPS]; // rgb ambient (nits) per group: its dome lights'
                                           // means + the settings' ambient; w 1 where
                                           // the textured dome lights the group
      uint  link_mask[];                   // one mask per light of the light buffer, in its
                                           // order (the FoV list; the bake's static lights)

  uploaded when its bytes change (the FoV set, a mask, a distant light). Every
  lighting method multiplies a light's contribution by its bit for the pixel's group.
* **Shadow links** never reach a shader: draw batches carry their meshes' shadow group
  (``DrawBatch.links``) and a shadow capture draws only the batches whose group bit is
  set in the light's shadow mask (:func:`batch_keep`, the sun's map and the atlas'
  maps). A mask change re-captures the map (``Capture.shadow_mask`` is part of the key
  the scheduler compares).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import moderngl
import numpy as np

from .. import limits
from ..scene.links import ALL_GROUPS

if TYPE_CHECKING:
    from .gl_delegate import DrawBatch
    from .light_table import LightTable
    from .records import DistantLights

#: uint32 words before ``link_mask[]``: uvec4 + vec4[LIM_LINK_GROUPS].
HEADER_WORDS = 4 + 4 * limits.MAX_LIGHT_LINK_GROUPS


def pack_link_buffer(
    table: LightTable,
    rows: np.ndarray,
    distant: DistantLights | None = None,
    base_ambient: float | np.ndarray | None = None,
) -> np.ndarray:
    """The link SSBO's words (uint32) for the light-buffer ``rows`` (light-table rows in
    SSBO order) and the frame's distant lights (None: no distant lights, no ambient).
    ``base_ambient``: radiance every group receives (``RenderSettings.ambient``)."""
    out = np.zeros(HEADER_WORDS + max(len(rows), 1), dtype=np.uint32)
    masks = table.cols["light_link_mask"]
    if distant is not None:
        for j, r in enumerate(distant.rows[:4]):
            out[j] = masks[r]
        amb = np.zeros((limits.MAX_LIGHT_LINK_GROUPS, 4), dtype=np.float32)
        if base_ambient is not None:
            amb[:, :3] = np.asarray(base_ambient, dtype=np.float32)
        bits = 1 << np.arange(limits.MAX_LIGHT_LINK_GROUPS, dtype=np.uint64)
        textured = table.rows.get(distant.dome.path, -1) if distant.dome is not None else -1
        for r in distant.dome_rows:
            on = (np.uint64(masks[r]) & bits) != 0
            if r == textured:
                amb[on, 3] = 1.0  # lit by its map (common/sun.glsl, dome_sampled)
            else:
                amb[on, :3] += table.cols["intensity"][r]
        out[4:HEADER_WORDS] = amb.reshape(-1).view(np.uint32)
    if len(rows):
        out[HEADER_WORDS : HEADER_WORDS + len(rows)] = masks[rows]
    return out


class LinkBufferUploader:
    """The link SSBO, re-uploaded only when its contents change."""

    def __init__(self) -> None:
        self.ssbo: moderngl.Buffer | None = None
        self._bytes: bytes | None = None
        self.uploads = 0

    def upload(self, ctx: moderngl.Context, words: np.ndarray) -> moderngl.Buffer:
        raw = np.ascontiguousarray(words, dtype=np.uint32).tobytes()
        if self.ssbo is None or self.ssbo.size < len(raw):
            if self.ssbo is not None:
                self.ssbo.release()
            self.ssbo = ctx.buffer(reserve=max(len(raw), 4 * (HEADER_WORDS + 64)))
            self._bytes = None
        if raw != self._bytes:
            self.ssbo.write(raw)
            self._bytes = raw
            self.uploads += 1
        return self.ssbo

    def release(self) -> None:
        if self.ssbo is not None:
            self.ssbo.release()
        self.ssbo = None
        self._bytes = None


def batch_keep(batches: Sequence[DrawBatch], shadow_mask: int) -> np.ndarray:
    """(B,) bool: batch b casts shadows for a light with ``shadow_mask`` (its meshes'
    shadow-link group bit is set). All True for the default mask."""
    n = len(batches)
    if int(shadow_mask) & ALL_GROUPS == ALL_GROUPS:
        return np.ones(n, dtype=bool)
    groups = np.fromiter((b.links[1] for b in batches), dtype=np.int64, count=n)
    return ((int(shadow_mask) >> groups) & 1).astype(bool)


def shadow_batches(batches: Sequence[DrawBatch], shadow_mask: int) -> list[DrawBatch]:
    """The batches that cast shadows for a light with ``shadow_mask``."""
    keep = batch_keep(batches, shadow_mask)
    return [b for b, k in zip(batches, keep) if k]


__all__ = [
    "HEADER_WORDS",
    "LinkBufferUploader",
    "batch_keep",
    "pack_link_buffer",
    "shadow_batches",
]
