"""Render prims (Hydra's Sprims/Rprims): CPU-side state synced from data sources.

Each ``sync(data_source, bits)`` re-reads only what its dirty bits say and
records the bits it consumed in ``pending_bits`` so the delegate's
``commit_resources`` can upload exactly what changed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from .. import limits
from ..scene import prims
from ..scene.locators import DirtyBits as D

if TYPE_CHECKING:
    from ..scene.prims import LightPrim
    from ..scene.stage_data_sources import (
        CameraDataSource,
        LightDataSource,
        MaterialDataSource,
        MeshDataSource,
    )
    from .light_table import LightTable


class PrimHost(Protocol):
    """What a render prim reads of its render delegate (``delegate.RenderDelegate``
    is one): a protocol, so this module does not import the delegate that imports
    it."""

    @property
    def light_table(self) -> LightTable: ...

    def write_light(self, row: int, lp: LightPrim) -> None: ...

    def write_lights(self, rows: list[int], lps: list[LightPrim]) -> None: ...

    def release_light(self, path: str) -> None: ...

    def release_mesh(self, path: str) -> None: ...

    def warn_once(self, key: str, msg: str) -> None: ...


_LIGHT_FULL = D.DirtyParams | D.DirtyShadowParams | D.DirtyResource


class RenderPrim:
    prim_type: str = ""

    def __init__(self, delegate: PrimHost, path: str, prim_type: str) -> None:
        self.delegate = delegate
        self.path = path
        self.prim_type = prim_type
        #: Bits synced since the delegate last committed this prim's resources.
        self.pending_bits = D.Clean

    def sync(self, ds: Any, bits: D) -> None:
        """``ds``: the prim kind's data source (``scene.stage_scene_index``)."""
        raise NotImplementedError

    def finalize(self) -> None:
        """Release delegate resources (prim removed)."""


class LightSprim(RenderPrim):
    def __init__(self, delegate: PrimHost, path: str, prim_type: str) -> None:
        super().__init__(delegate, path, prim_type)
        self.light: prims.LightPrim | None = None
        self.row = delegate.light_table.alloc(path)
        self.valid = False  # enabled before visibility

    def sync(self, ds: LightDataSource, bits: D) -> None:
        lp = self.light
        if lp is None or bits & _LIGHT_FULL:
            lp = ds.light()
            self.valid = lp.valid
            self.light = lp
            self.delegate.write_light(self.row, lp)
        else:
            if bits & D.DirtyCollection:  # only the link masks (scene/links.py)
                m = ds.link_masks()
                lp.light_link_mask, lp.shadow_link_mask = m.light, m.shadow
                self.delegate.light_table.set_link_masks(self.row, m)
            if bits & D.DirtyTransform and not ds.update_transform(lp):
                lp = ds.light()
                self.light = lp
                self.delegate.write_light(self.row, lp)
            elif bits & D.DirtyTransform:
                self.delegate.light_table.write_transform(self.row, lp)
            if bits & D.DirtyVisibility:
                lp.enabled = self.valid and ds.visible()
                self.delegate.light_table.set_enabled(self.row, lp.enabled)
        self.pending_bits |= bits

    def needs_full_read(self, bits: D) -> bool:
        """The next ``sync`` re-reads the whole light (what ``sync_lights`` batches)."""
        return self.light is None or bool(bits & _LIGHT_FULL)

    def finalize(self) -> None:
        self.delegate.light_table.free(self.path)
        self.delegate.release_light(self.path)


def sync_lights(sprims: list[LightSprim], sources: list[Any], bits: list[D]) -> None:
    """Full ``sync`` of many lights that share a delegate and a data source type: the
    records read in bulk (the source type's ``lights``), one light-table write."""
    if not sprims:
        return
    lps = type(sources[0]).lights(sources)
    for sp, lp, b in zip(sprims, lps, bits, strict=True):
        sp.valid = lp.valid
        sp.light = lp
        sp.pending_bits |= b
    sprims[0].delegate.write_lights([sp.row for sp in sprims], lps)


class MeshRprim(RenderPrim):
    def __init__(self, delegate: PrimHost, path: str, prim_type: str) -> None:
        super().__init__(delegate, path, prim_type)
        self.mesh: prims.MeshPrim | None = None

    def sync(self, ds: MeshDataSource, bits: D) -> None:
        m = self.mesh
        geom_bits = D.DirtyPoints | D.DirtyTopology | D.DirtyNormals | D.DirtyPrimvar
        if m is None or bits & geom_bits:
            g = ds.geometry()
            uvs = tangents = attrs = None
            if g is None:
                pts = np.zeros((0, 3), np.float32)
                g_n, g_i, vc, dc, dsided = pts, np.zeros((0, 3), np.uint32), None, None, False
            else:
                pts, g_n, g_i, vc, dc, dsided = (
                    g.points,
                    g.normals,
                    g.indices,
                    g.vertex_colors,
                    g.display_color,
                    g.double_sided,
                )
                uvs, tangents, attrs = g.uvs, g.tangents, g.attrs
            old = m
            m = prims.MeshPrim(
                self.path,
                pts,
                g_n,
                g_i,
                vertex_colors=vc,
                uvs=uvs,
                tangents=tangents,
                attrs=attrs,
                double_sided=dsided,
            )
            if dc is not None:
                m.display_color = np.asarray(dc, dtype=np.float64)
            m.geometry_key = ds.geometry_key()
            if old is not None and not bits & D.DirtyTransform:
                m.transform = old.transform
                m.instance_transforms = old.instance_transforms
                m.instancer, m.instance_ids = old.instancer, old.instance_ids
                m.instance_rel_path = old.instance_rel_path
                m.visible, m.material, m.dynamic = old.visible, old.material, old.dynamic
                m.link_group, m.shadow_group = old.link_group, old.shadow_group
            else:
                bits |= D.DirtyTransform | D.DirtyInstancer | D.DirtyVisibility
                bits |= D.DirtyMaterialId | D.DirtyStbFlags | D.DirtyCategories
            self.mesh = m
        if bits & D.DirtyTransform:
            xf = ds.world_matrix() if ds.entry.instancer is None else np.eye(4)
            m.transform = self._finite_xforms(xf[None], "transform")[0]
        if bits & (D.DirtyInstancer | D.DirtyTransform):
            inst = ds.instance_transforms()
            m.instance_transforms = None if inst is None else self._finite_xforms(inst, "instance")
            m.instancer = ds.entry.instancer
            m.instance_ids = ds.instance_ids() if inst is not None else None
            m.instance_rel_path = ds.instance_rel_path()
        if bits & D.DirtyVisibility:
            m.visible = ds.visible()
        if bits & D.DirtyMaterialId:
            m.material = ds.material()
        if bits & D.DirtyStbFlags or bits & D.DirtyTransform:
            m.dynamic = ds.dynamic()
        if bits & D.DirtyCategories:
            m.link_group, m.shadow_group = ds.link_groups()
        self.pending_bits |= bits

    def _finite_xforms(self, xfs: np.ndarray, what: str) -> np.ndarray:
        """``xfs`` (n, 4, 4) with each non-finite matrix (or one with an entry beyond
        ``limits.MAX_COORDINATE_M``) collapsed to a point (the mesh or instance draws
        nothing), warned once (NaN/inf/overflow reached the rasteriser and the scene
        bounds otherwise: found by tools/fuzz.py)."""
        bad = ~(np.abs(xfs) <= limits.MAX_COORDINATE_M).all(axis=(1, 2))  # NaN fails too
        if not bad.any():
            return xfs
        n = int(bad.sum())
        self.delegate.warn_once(
            f"nonfinite-{what}:{self.path}",
            f"mesh <{self.path}>: {n} {what} matri{'ces' if n > 1 else 'x'} not finite or "
            f"beyond {limits.MAX_COORDINATE_M:.0e} m; not drawn",
        )
        out = np.array(xfs, dtype=np.float64, copy=True)
        out[bad] = np.diag([0.0, 0.0, 0.0, 1.0])
        return out

    def finalize(self) -> None:
        self.delegate.release_mesh(self.path)


class CameraSprim(RenderPrim):
    def __init__(self, delegate: PrimHost, path: str, prim_type: str) -> None:
        super().__init__(delegate, path, prim_type)
        self.camera: prims.CameraPrim | None = None
        self.exposure_scale = 1.0

    def sync(self, ds: CameraDataSource, bits: D) -> None:
        if self.camera is None or bits & (D.DirtyParams | D.DirtyClipPlanes):
            self.camera = ds.camera()
            self.exposure_scale = ds.exposure_scale()
        elif bits & D.DirtyTransform:
            t = ds.camera().transform
            self.camera.transform = t
        self.pending_bits |= bits


class MaterialSprim(RenderPrim):
    def __init__(self, delegate: PrimHost, path: str, prim_type: str) -> None:
        super().__init__(delegate, path, prim_type)
        self.material: prims.MaterialPrim | None = None

    def sync(self, ds: MaterialDataSource, bits: D) -> None:
        self.material = ds.material()
        for w in self.material.warnings:
            self.delegate.warn_once("material:" + w, w)
        self.pending_bits |= bits
