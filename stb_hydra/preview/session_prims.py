"""The stage's contents in a :class:`~stb_hydra.preview.session.PreviewSession`
(:class:`StageContents`): the prim tree (paths, children, search), selection and
picking (ID buffer), a prim's properties as text, the light and material lists, and
light edits on the session layer (:meth:`StageContents.set_light`, saved by
:meth:`StageContents.save_edits`).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from ..scene.lights import influence_range
from .picking import Picker, instance_rows
from .session_state import SessionState, _one_line


class StageContents(SessionState):
    """The prims, picking, properties and light-edit part of the session."""

    _picker: Picker | None

    # -- prims --
    def prim_paths(self, search: str = "") -> list[str]:
        """Every prim path (instance proxies included), filtered by a case-insensitive
        substring."""
        from pxr import Usd

        if not self.ok:
            return []
        s = search.lower()
        it = self.stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimAllPrimsPredicate))
        return [str(p.GetPath()) for p in it if s in str(p.GetPath()).lower()]

    def children(self, path: str) -> list[str]:
        """Child prim paths (instance proxies included)."""
        from pxr import Usd

        if not self.ok:
            return []
        prim = self.stage.GetPrimAtPath(path)
        if not prim:
            return []
        pred = Usd.TraverseInstanceProxies(Usd.PrimAllPrimsPredicate)
        return [str(c.GetPath()) for c in prim.GetFilteredChildren(pred)]

    def select(self, path: str | None) -> bool:
        if path is not None and (not self.ok or not self.stage.GetPrimAtPath(path)):
            self.message = f"prim '{path}' not found"
            return False
        self.selected = path
        return True

    def pick(self, x: int, y: int) -> str | None:
        """Select the prim covering viewport pixel (x, y) (top-left origin; ID buffer);
        the background clears the selection. Returns the selected path."""
        from ..renderer.camera import view_setup

        if not self.ok:
            return None
        e = self.engine
        assert e is not None
        if self._picker is None:
            self._picker = Picker(e.ctx)
        self._apply_camera()
        cam, exposure = e.camera()
        w, h = self.size
        path = self._picker.pick(e.delegate, view_setup(cam, w, h, exposure), int(x), int(y))
        self.selected = path
        return path

    def properties(self, path: str) -> list[tuple[str, str]]:
        """A prim's properties as (name, value) text: type, lights in physical units
        (as ``stb inspect`` reports them), then the attributes' values at the time."""
        from pxr import Usd

        if not self.ok:
            return []
        assert self.engine is not None
        prim = self.stage.GetPrimAtPath(path)
        if not prim:
            return instance_rows(self.engine.delegate, path)  # a picked point instance
        rows: list[tuple[str, str]] = [("type", prim.GetTypeName() or "-")]
        lp = self._light(path)
        if lp is not None:
            local = lp.type in ("sphereLight", "diskLight", "rectLight", "cylinderLight")
            unit = "cd" if local else ("lx" if lp.type == "distantLight" else "nit")
            rows += [
                ("enabled", str(bool(lp.enabled))),
                (f"intensity [{unit}]", _fmt(lp.intensity)),
                ("flux [lm]", _fmt(lp.flux)),
                ("position [m]", _fmt(lp.position)),
                ("direction", _fmt(lp.direction)),
                ("shadow", f"{'on' if lp.shadow_enable else 'off'} {lp.shadow_update}"),
            ]
            if local:
                _, exposure = self.engine.camera()
                rng = (
                    lp.range if lp.range_authored else influence_range(lp.peak_intensity, exposure)
                )
                rows.append(("range [m]", _fmt(float(rng))))
            if lp.ies_asset:
                rows.append(("IES", str(lp.ies_file or lp.ies_asset)))
        rp = self.engine.delegate.meshes.get(path)
        if rp is not None and rp.mesh is not None:
            rows.append(("material", rp.mesh.material or "(display colour)"))
        t = Usd.TimeCode(self.engine.scene_index.time)
        for a in prim.GetAttributes():
            if not a.HasAuthoredValue():
                continue
            rows.append((a.GetName(), _fmt(a.Get(t))))
        return rows

    # -- lights and edits (session layer) --
    def lights(self) -> list[dict[str, Any]]:
        """Every light: path, type, enabled, its authored intensity, exposure and
        colour (what the light list edits), and its light/shadow links in one line
        (``links``: "lights all, shadowed by all" without linking; ``linked``: a
        collection is authored)."""
        from pxr import UsdLux

        if not self.ok:
            return []
        assert self.engine is not None
        out = []
        for path in sorted(self.engine.delegate.lights):
            prim = self.stage.GetPrimAtPath(path)
            lp = self._light(path)
            if lp is None:
                continue
            api = UsdLux.LightAPI(prim)
            out.append(
                {
                    "path": path,
                    "type": lp.type,
                    "enabled": bool(lp.enabled),
                    "intensity": float(api.GetIntensityAttr().Get() or 0.0),
                    "exposure": float(api.GetExposureAttr().Get() or 0.0),
                    "color": [float(c) for c in (api.GetColorAttr().Get() or (1.0, 1.0, 1.0))],
                    "links": self.engine.scene_index.links.describe(path),
                    "linked": self.engine.scene_index.links.is_linked(path),
                }
            )
        return out

    def materials(self) -> list[dict[str, Any]]:
        """The Materials panel's records (``preview.materials_view``)."""
        from .materials_view import material_records

        if not self.ok:
            return []
        assert self.engine is not None
        return material_records(self.engine.delegate)

    def set_light(
        self,
        path: str,
        *,
        enabled: bool | None = None,
        intensity: float | None = None,
        exposure: float | None = None,
        color: Iterable[float] | None = None,
    ) -> bool:
        """Edit a light on the session layer (visibility for ``enabled``); the change
        reaches the engine through change tracking on the next frame."""
        from pxr import Gf, Usd, UsdGeom, UsdLux

        if not self.ok:
            return False
        prim = self.stage.GetPrimAtPath(path)
        assert self.engine is not None
        if not prim or path not in self.engine.delegate.lights:
            self.message = f"light '{path}' not found"
            return False
        api = UsdLux.LightAPI(prim)
        with Usd.EditContext(self.stage, self.stage.GetSessionLayer()):
            if enabled is not None:
                vis = UsdGeom.Tokens.inherited if enabled else UsdGeom.Tokens.invisible
                UsdGeom.Imageable(prim).CreateVisibilityAttr().Set(vis)
            if intensity is not None:
                api.CreateIntensityAttr().Set(float(intensity))
            if exposure is not None:
                api.CreateExposureAttr().Set(float(exposure))
            if color is not None:
                api.CreateColorAttr().Set(Gf.Vec3f(*[float(c) for c in color]))
        self._scene_dirty = True
        return True

    def save_edits(self, path: str | Path) -> Path | None:
        """Write the session layer (every edit made here) as a .usda layer, atomically."""
        from ..io.files import FileWriteError, write_text_atomic

        if not self.ok:
            return None
        try:
            return write_text_atomic(path, self.stage.GetSessionLayer().ExportToString())
        except (OSError, FileWriteError) as exc:
            self.message = f"cannot save edits to '{path}': {_one_line(exc)}"
            return None


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, np.ndarray) or (hasattr(v, "__len__") and not isinstance(v, str)):
        try:
            vals = [float(x) for x in v]
        except (TypeError, ValueError):
            return str(v)[:200]
        return (
            "(" + ", ".join(f"{x:.4g}" for x in vals[:16]) + (", ...)" if len(vals) > 16 else ")")
        )
    return str(v)[:200]
