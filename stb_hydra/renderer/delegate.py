"""Render delegate: the prim factory and the owner of render-side resources.

``RenderDelegate`` is the CPU half (no GL): it creates render prims, owns the
:class:`LightTable` and the IES profile and RectLight texture registries, and tracks
what changed.
``render.gl_delegate.GLRenderDelegate`` adds the GPU resources and the real
``commit_resources()`` upload.
"""

from __future__ import annotations

import numpy as np

from .. import limits
from ..scene import prims
from ..scene.locators import DirtyBits
from ..scene.prims import LightPrim
from .light_table import LightTable
from .render_prims import CameraSprim, LightSprim, MaterialSprim, MeshRprim, RenderPrim


class LayerRegistry:
    """Files in use by lights: key (an IES profile's resolved path, a RectLight
    texture's path and colour space) -> texture-array layer (refcounted)."""

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

    def touch(self, key: str) -> bool:
        """The file behind ``key`` changed on disk: bump the version (the delegate
        re-uploads the array). False when no light uses it."""
        if key not in self.layers:
            return False
        self.version += 1
        return True

    def release_user(self, user: str) -> None:
        for path in [p for p, users in self.refs.items() if user in users]:
            users = self.refs[path]
            users.discard(user)
            if not users:
                del self.refs[path]
                self._free.append(self.layers.pop(path))
                self.version += 1


#: The IES profiles' registry (its original name).
IesRegistry = LayerRegistry


def rect_texture_key(tex: tuple[str, str]) -> str:
    """Registry key of a RectLight texture (``LightPrim.rect_texture``)."""
    return tex[0] + "\n" + tex[1]


def rect_texture_of(key: str) -> tuple[str, str]:
    """``LightPrim.rect_texture`` of a registry key."""
    path, _, space = key.partition("\n")
    return path, space


class RenderDelegate:
    """CPU render delegate: prim factory + light table + resource bookkeeping."""

    def __init__(self) -> None:
        self.light_table = LightTable()
        self.ies = LayerRegistry()
        #: RectLight textures in use (issue 37): layers of the rect texture array.
        self.rect_textures = LayerRegistry()
        self.meshes: dict[str, MeshRprim] = {}
        self.cameras: dict[str, CameraSprim] = {}
        self.materials: dict[str, MaterialSprim] = {}
        self.lights: dict[str, LightSprim] = {}
        self.warnings: list[str] = []
        self._warned: set[str] = set()
        self._light_ies: dict[str, str] = {}
        self._light_rect: dict[str, str] = {}

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
        layer = self._ies_layer(lp)
        self.light_table.write(row, lp, layer, self._rect_layer(lp))

    def write_lights(self, rows: list[int], lps: list[LightPrim]) -> None:
        """``write_light`` for many lights at once (one light-table write)."""
        layers = [self._ies_layer(lp) for lp in lps]
        tex = [self._rect_layer(lp) for lp in lps]
        self.light_table.write_many(
            np.asarray(rows, dtype=np.int64), lps, np.asarray(layers), np.asarray(tex)
        )

    def _ies_layer(self, lp: LightPrim) -> int:
        """The IES layer of ``lp`` (-1 none), its previous profile released."""
        layer = -1
        old = self._light_ies.pop(lp.path, None)
        if old is not None and old != lp.ies_file:
            self.ies.release_user(lp.path)
        if lp.ies_file:
            layer = self.ies.acquire(lp.ies_file, lp.path)
            self._light_ies[lp.path] = lp.ies_file
        return layer

    def _rect_layer(self, lp: LightPrim) -> int:
        """The RectLight texture layer of ``lp`` (-1 none: it emits its mean), its
        previous texture released; past ``limits.MAX_RECT_TEXTURES`` textures the light
        emits its mean (one warning)."""
        key = rect_texture_key(lp.rect_texture) if lp.rect_texture is not None else None
        old = self._light_rect.pop(lp.path, None)
        if old is not None and old != key:
            self.rect_textures.release_user(lp.path)
        if key is None:
            return -1
        layer = self.rect_textures.acquire(key, lp.path)
        self._light_rect[lp.path] = key
        if layer >= limits.MAX_RECT_TEXTURES:
            self.warn_once(
                "rect_textures",
                f"more than {limits.MAX_RECT_TEXTURES} RectLight textures: <{lp.path}> and "
                "others emit their texture's mean",
            )
            return -1
        return layer

    def release_light(self, path: str) -> None:
        if self._light_ies.pop(path, None) is not None:
            self.ies.release_user(path)
        if self._light_rect.pop(path, None) is not None:
            self.rect_textures.release_user(path)

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
