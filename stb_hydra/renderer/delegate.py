"""Render delegate: the prim factory and the owner of render-side resources.

``RenderDelegate`` is the CPU half (no GL): it creates render prims, owns the
:class:`LightTable` and the IES profile registry, and tracks what changed.
``render.gl_delegate.GLRenderDelegate`` adds the GPU resources and the real
``commit_resources()`` upload.
"""

from __future__ import annotations

import numpy as np

from ..scene import prims
from ..scene.locators import DirtyBits
from ..scene.prims import LightPrim
from .light_table import LightTable
from .render_prims import CameraSprim, LightSprim, MaterialSprim, MeshRprim, RenderPrim


class IesRegistry:
    """IES profiles in use: resolved path -> texture-array layer (refcounted)."""

    def __init__(self) -> None:
        self.layers: dict[str, int] = {}
        self.refs: dict[str, set[str]] = {}
        self._free: list[int] = []
        self.version = 0

    def acquire(self, ies_path: str, user: str) -> int:
        layer = self.layers.get(ies_path)
        if layer is None:
            layer = self._free.pop() if self._free else len(self.layers) + len(self._free)
            self.layers[ies_path] = layer
            self.version += 1
        self.refs.setdefault(ies_path, set()).add(user)
        return layer

    def release_user(self, user: str) -> None:
        for path in [p for p, users in self.refs.items() if user in users]:
            users = self.refs[path]
            users.discard(user)
            if not users:
                del self.refs[path]
                self._free.append(self.layers.pop(path))
                self.version += 1


class RenderDelegate:
    """CPU render delegate: prim factory + light table + resource bookkeeping."""

    def __init__(self) -> None:
        self.light_table = LightTable()
        self.ies = IesRegistry()
        self.meshes: dict[str, MeshRprim] = {}
        self.cameras: dict[str, CameraSprim] = {}
        self.materials: dict[str, MaterialSprim] = {}
        self.lights: dict[str, LightSprim] = {}
        self.warnings: list[str] = []
        self._warned: set[str] = set()
        self._light_ies: dict[str, str] = {}

    # -- prim factory (Hydra: CreateRprim / CreateSprim) --
    def create_prim(self, prim_type: str, path: str) -> RenderPrim | None:
        p: RenderPrim
        if prim_type in prims.LIGHT_TYPES:
            p = LightSprim(self, path, prim_type)
            self.lights[path] = p
        elif prim_type == prims.MESH:
            p = MeshRprim(self, path, prim_type)
            self.meshes[path] = p
        elif prim_type == prims.CAMERA:
            p = CameraSprim(self, path, prim_type)
            self.cameras[path] = p
        elif prim_type == prims.MATERIAL:
            p = MaterialSprim(self, path, prim_type)
            self.materials[path] = p
        else:
            return None
        return p

    def destroy_prim(self, prim: RenderPrim) -> None:
        prim.finalize()
        for d in (self.lights, self.meshes, self.cameras, self.materials):
            d.pop(prim.path, None)

    # -- hooks used by render prims --
    def write_light(self, row: int, lp: LightPrim) -> None:
        layer = -1
        old = self._light_ies.pop(lp.path, None)
        if old is not None and old != lp.ies_file:
            self.ies.release_user(lp.path)
        if lp.ies_file:
            layer = self.ies.acquire(lp.ies_file, lp.path)
            self._light_ies[lp.path] = lp.ies_file
        self.light_table.write(row, lp, layer)

    def write_lights(self, rows: list[int], lps: list[LightPrim]) -> None:
        """``write_light`` for many lights at once (one light-table write)."""
        layers = []
        for lp in lps:
            layer = -1
            old = self._light_ies.pop(lp.path, None)
            if old is not None and old != lp.ies_file:
                self.ies.release_user(lp.path)
            if lp.ies_file:
                layer = self.ies.acquire(lp.ies_file, lp.path)
                self._light_ies[lp.path] = lp.ies_file
            layers.append(layer)
        self.light_table.write_many(np.asarray(rows, dtype=np.int64), lps, np.asarray(layers))

    def release_light(self, path: str) -> None:
        if self._light_ies.pop(path, None) is not None:
            self.ies.release_user(path)

    def release_mesh(self, path: str) -> None:
        pass

    def warn_once(self, key: str, msg: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(msg)

    def commit_resources(self) -> None:
        """CPU delegate: nothing to upload; clear pending bits."""
        for d in (self.lights, self.meshes, self.cameras, self.materials):
            for p in d.values():
                p.pending_bits = DirtyBits.Clean
