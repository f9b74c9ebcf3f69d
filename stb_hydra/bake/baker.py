"""``stb bake``: static lights' direct light into lightmaps, and the layer that uses them.

    report = bake_stage("scene.usda", "scene_baked.usda", texel_density=16.0)

Steps: open the stage in an :class:`~stb_hydra.renderer.engine.Engine` (its default
camera sets the exposure, hence the lights' influence ranges, as ``stb render``
does); pick the static lights (``stb:mobility = "static"``, not inside an instance,
which a layer cannot edit) and the static meshes (not dynamic, not instanced);
unwrap each mesh with xatlas (:mod:`.unwrap`, cached by content); bake on the GPU
(:mod:`.gpu`); write one EXR per mesh (``<OUT stem>_lightmaps/``) and OUT.usda, which
sublayers the input and adds, per baked mesh, ``primvars:stb:lightmap:uv``
(texCoord2f, faceVarying), ``asset stb:lightmap:file`` and
``float stb:lightmap:texelDensity``; per baked light ``stb:baked = true``; and in the
layer's ``customLayerData["stb:bake"]`` a fingerprint per baked light (what
``stb validate`` compares to call a bake stale). All files are written atomically.
"""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pxr import Sdf, Usd, UsdGeom, Vt

from .. import limits
from ..io.files import write_text_atomic
from ..io.images import write_image
from ..renderer.engine import Engine
from ..renderer.frame import RenderSettings
from ..scene.geometry import IMPLICIT_TYPES
from .gpu import BakedMap, run_bake_frame
from .unwrap import MeshLayout, UnwrapError, default_cache_dir, mesh_world_data, unwrap_mesh

#: Primvar / attribute names written on baked meshes and lights.
UV_PRIMVAR = "stb:lightmap:uv"
FILE_ATTR = "stb:lightmap:file"
DENSITY_ATTR = "stb:lightmap:texelDensity"
BAKED_ATTR = "stb:baked"
#: customLayerData key of the bake record.
LAYER_KEY = "stb:bake"
#: EXR channels of a lightmap, plane by plane (see BakedMap; the runtime reads them
#: by name: renderer/tasks/lightmap.py LIGHTMAP_CHANNELS).
CHANNELS = (
    "R",
    "G",
    "B",
    "specTop.R",
    "specTop.G",
    "specTop.B",
    "dirTop.X",
    "dirTop.Y",
    "dirTop.Z",
    "spec2nd.R",
    "spec2nd.G",
    "spec2nd.B",
    "dir2nd.X",
    "dir2nd.Y",
    "dir2nd.Z",
    "specRest.R",
    "specRest.G",
    "specRest.B",
    "dirRest.X",
    "dirRest.Y",
    "dirRest.Z",
)


@dataclass
class BakeReport:
    """What a bake did: paths, counts, seconds, bytes."""

    output: Path
    lights: list[str] = field(default_factory=list)
    meshes: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)  # mesh path -> reason
    texels: int = 0
    #: GPU memory of the runtime lightmaps (7 x RGB16F per texel), bytes.
    gpu_bytes: int = 0
    seconds: dict[str, float] = field(default_factory=dict)
    cached: int = 0
    warnings: list[str] = field(default_factory=list)
    #: Per baked mesh: (width, height) of its lightmap in texels and the texel density
    #: it achieves (texels per metre, measured on its UVs: ``unwrap.achieved_density``).
    densities: dict[str, tuple[int, int, float]] = field(default_factory=dict)
    #: Sum over baked meshes of lightmap texels x the static lights whose range reaches
    #: the mesh (what the GPU bake's time follows; ``gpu.mesh_lights``).
    texel_lights: int = 0


def light_fingerprint(prim: Usd.Prim, time_code: Usd.TimeCode | None = None) -> str:
    """Hash of what a baked light's contribution depends on: its world transform and
    every authored light input (``inputs:*``, ``shaping:*``, ``shadow:*``, ``stb:range``,
    ``stb:mobility``) and its light/shadow-link collection (``collection:lightLink:*``,
    ``collection:shadowLink:*``); ``stb:baked`` itself is left out."""
    tc = time_code if time_code is not None else Usd.TimeCode.Default()
    stage = prim.GetStage()
    if tc.IsDefault() and stage.HasAuthoredTimeCodeRange():
        tc = Usd.TimeCode(stage.GetStartTimeCode())
    h = hashlib.sha256()
    m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(tc)
    h.update(np.round(np.array(m, dtype=np.float64), 6).tobytes())
    for a in sorted(prim.GetAuthoredAttributes(), key=lambda a: a.GetName()):
        n = a.GetName()
        if n == BAKED_ATTR or not n.startswith(
            (
                "inputs:",
                "shaping:",
                "shadow:",
                "stb:range",
                "stb:mobility",
                "intensity",
                "color",
                "collection:lightLink:",
                "collection:shadowLink:",
            )
        ):
            continue
        h.update(f"{n}={a.Get(tc)!r};".encode())
    # Light and shadow linking decide which meshes the light baked into (and what shadowed
    # it): their authored attributes above, their relationships here (none: unchanged).
    for r in sorted(prim.GetAuthoredRelationships(), key=lambda r: r.GetName()):
        n = r.GetName()
        if n.startswith(("collection:lightLink:", "collection:shadowLink:")):
            h.update(f"{n}={[str(t) for t in r.GetTargets()]!r};".encode())
    return h.hexdigest()[:24]


def bake_stage(
    scene: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    texel_density: float = limits.BAKE_TEXEL_DENSITY_DEFAULT,
    jobs: int = 1,
    cache_dir: Path | None = None,
    camera: str | None = None,
    warn: Callable[[str], None] | None = None,
    progress: bool = True,
    shadow_view_height: int = limits.BAKE_SHADOW_VIEW_HEIGHT,
) -> BakeReport:
    """Bake ``scene``'s static lights into lightmaps; write ``out`` (.usda) and its
    ``<stem>_lightmaps/`` folder. ``jobs``: threads for the CPU unwrap (xatlas).
    ``shadow_view_height``: the 16:9 view height (px) the shadow maps are sized for
    (the resolution policy of a render at that height; default 1080p). A bake compared
    with a reference render of another height differs by that render's shadow-map
    resolution as well as by the lightmaps."""
    t0 = time.perf_counter()
    scene_p, out_p = Path(scene), Path(out)
    rep = BakeReport(out_p)
    say = warn or (lambda m: None)

    def _warn(msg: str) -> None:
        rep.warnings.append(msg)
        say(msg)

    if not (texel_density > 0 and np.isfinite(texel_density)):
        raise ValueError(f"--texel-density must be a positive number, got {texel_density}")
    if not (isinstance(shadow_view_height, int) and shadow_view_height > 0):
        raise ValueError(f"shadow view height must be a positive integer, got {shadow_view_height}")
    aspect_w = 16 * shadow_view_height // 9
    settings = RenderSettings(
        width=aspect_w,
        height=shadow_view_height,
        camera=camera,
        lighting="reference",
        shadow_budget=None,
    )
    eng = Engine(scene_p, settings)
    try:
        stage = eng.stage
        tc = _start_time(stage)
        if not stage.HasAuthoredMetadata("metersPerUnit"):
            _warn(
                f"{scene_p}: no metersPerUnit authored; USD's fallback 0.01 (centimetres) "
                "applies, and lightmap densities are per metre"
            )
        light_paths = _static_lights(eng, stage, _warn)
        rep.lights = light_paths
        sources = _static_meshes(eng, stage, _warn)
        t1 = time.perf_counter()
        layouts = _unwrap_all(sources, texel_density, cache_dir, jobs, rep, _warn)
        rep.seconds["unwrap"] = time.perf_counter() - t1
        if not light_paths:
            _warn(f'{scene_p}: no static lights (stb:mobility = "static") to bake')
        t2 = time.perf_counter()
        maps: dict[str, BakedMap] = {}
        if light_paths and layouts:
            _restrict_static(eng, light_paths)
            bar = _progress_bar(len(layouts), progress)
            bake = run_bake_frame(eng, layouts, lambda lay: bar.update(1) if bar else None)
            if bar is not None:
                bar.close()
            maps = bake.maps
            rep.texel_lights = bake.texel_lights
        rep.seconds["gpu"] = time.perf_counter() - t2
        t3 = time.perf_counter()
        _write_outputs(stage, scene_p, out_p, layouts, maps, light_paths, tc, rep)
        rep.seconds["write"] = time.perf_counter() - t3
    finally:
        eng.release()
    rep.seconds["total"] = time.perf_counter() - t0
    return rep


def _start_time(stage: Usd.Stage) -> Usd.TimeCode:
    """The time static data is read at (the first frame, as ``stb render`` does)."""
    if stage.HasAuthoredTimeCodeRange():
        return Usd.TimeCode(stage.GetStartTimeCode())
    return Usd.TimeCode.Default()


def _static_lights(eng: Engine, stage: Usd.Stage, warn: Callable[[str], None]) -> list[str]:
    """Paths of enabled static local lights a layer can mark baked."""
    t = eng.delegate.light_table
    rows = np.nonzero(t.local_mask() & t.static)[0]
    out: list[str] = []
    for r in rows.tolist():
        path = t.paths[r]
        if path is None:
            continue
        prim = stage.GetPrimAtPath(path)
        if not prim or prim.IsInstanceProxy() or prim.IsInPrototype():
            warn(
                f"light <{path}>: static but inside an instance (a layer cannot mark it "
                "baked); left dynamic"
            )
            continue
        out.append(path)
    return out


def _restrict_static(eng: Engine, paths: list[str]) -> None:
    """Only the bakeable lights keep the table's static flag during the bake frame."""
    t = eng.delegate.light_table
    keep = np.zeros(t.n_rows, dtype=bool)
    for p in paths:
        r = t.rows.get(p)
        if r is not None:
            keep[r] = True
    t.cols["static"][: t.n_rows] &= keep


def _static_meshes(eng: Engine, stage: Usd.Stage, warn: Callable[[str], None]) -> list:
    """(MeshSource) of every visible, static, non-instanced Mesh prim and implicit shape
    (``Cube``, ``Sphere``, ``Cylinder``, ``Cone``, ``Capsule``, ``Plane``: tessellated
    as the renderer draws them)."""
    tc = _start_time(stage)
    out = []
    for path, rp in sorted(eng.delegate.meshes.items()):
        m = rp.mesh
        if m is None or not m.visible or m.dynamic or m.instance_transforms is not None:
            continue
        prim = stage.GetPrimAtPath(path)
        if not prim or not (prim.IsA(UsdGeom.Mesh) or prim.GetTypeName() in IMPLICIT_TYPES):
            continue
        if prim.IsInstanceProxy() or prim.IsInPrototype():
            continue  # instanced: one prototype, many places; lit dynamically
        try:
            out.append(mesh_world_data(prim, np.asarray(m.transform, dtype=np.float64), tc))
        except UnwrapError as exc:
            warn(f"mesh <{path}>: not baked ({exc}); lit dynamically")
    return out


def _unwrap_all(
    sources: list,
    density: float,
    cache_dir: Path | None,
    jobs: int,
    rep: BakeReport,
    warn: Callable[[str], None],
) -> list[MeshLayout]:
    cdir = cache_dir if cache_dir is not None else default_cache_dir()

    def one(src: object) -> MeshLayout | str:
        try:
            return unwrap_mesh(src, density, cdir)  # type: ignore[arg-type]
        except UnwrapError as exc:
            return str(exc)

    if jobs > 1 and len(sources) > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=jobs) as ex:
            results = list(ex.map(one, sources))
    else:
        results = [one(s) for s in sources]
    layouts: list[MeshLayout] = []
    for src, res in zip(sources, results):
        path = str(src.prim.GetPath())
        if isinstance(res, str):
            rep.skipped[path] = res
            warn(f"mesh <{path}>: not baked ({res}); lit dynamically")
            continue
        if res.capped:
            warn(
                f"mesh <{path}>: lightmap density lowered to {res.achieved:.3g} texels/m "
                f"(asked {density:g}) to fit {limits.BAKE_LIGHTMAP_MAX_SIZE} texels a side "
                "(limits.BAKE_LIGHTMAP_MAX_SIZE)"
            )
        rep.cached += int(res.cached)
        layouts.append(res)
    return layouts


def _progress_bar(total: int, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc="stb bake", unit="mesh", leave=False)


def _safe_name(path: str) -> str:
    return path.strip("/").replace("/", "__").replace(":", "_") or "root"


def _write_outputs(
    stage: Usd.Stage,
    scene: Path,
    out: Path,
    layouts: list[MeshLayout],
    maps: dict[str, BakedMap],
    lights: list[str],
    tc: Usd.TimeCode,
    rep: BakeReport,
) -> None:
    out = out.resolve()
    lm_dir = out.parent / f"{out.stem}_lightmaps"
    if maps:
        lm_dir.mkdir(parents=True, exist_ok=True)
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths.append(_rel(scene.resolve(), out.parent))
    root = stage.GetRootLayer()
    for key in ("upAxis", "metersPerUnit"):
        if root.pseudoRoot.HasInfo(key):
            layer.pseudoRoot.SetInfo(key, root.pseudoRoot.GetInfo(key))
    if root.defaultPrim:
        layer.defaultPrim = root.defaultPrim
    baked_meshes = []
    for lay in layouts:
        bm = maps.get(lay.path)
        if bm is None:
            continue
        exr = lm_dir / f"{_safe_name(lay.path)}.exr"
        pix = np.concatenate(bm.planes(), axis=-1)[::-1]
        write_image(
            exr,
            np.ascontiguousarray(pix),
            channel_names=CHANNELS,
            pixel_type="half",
            metadata={"stb:lightmap:prim": lay.path, "stb:lightmap:texelDensity": lay.achieved},
        )
        _author_mesh(layer, lay, _rel(exr, out.parent))
        w, h = lay.size
        rep.texels += w * h
        rep.densities[lay.path] = (w, h, lay.achieved)
        baked_meshes.append(lay.path)
    rep.meshes = baked_meshes
    rep.gpu_bytes = rep.texels * 7 * 6
    fps: dict[str, str] = {}
    if baked_meshes:
        for path in lights:
            spec = Sdf.CreatePrimInLayer(layer, path)
            spec.specifier = Sdf.SpecifierOver
            a = Sdf.AttributeSpec(spec, BAKED_ATTR, Sdf.ValueTypeNames.Bool, Sdf.VariabilityUniform)
            a.default = True
            fps[path] = light_fingerprint(stage.GetPrimAtPath(path), tc)
    else:
        rep.lights = []
    layer.customLayerData = {
        LAYER_KEY: {
            "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "texelDensity": float(np.median([lay.achieved for lay in layouts])) if layouts else 0.0,
            "lights": fps,
            "meshes": Vt.StringArray(baked_meshes),
        }
    }
    write_text_atomic(out, layer.ExportToString())


def _author_mesh(layer: Sdf.Layer, lay: MeshLayout, exr_rel: str) -> None:
    spec = Sdf.CreatePrimInLayer(layer, lay.path)
    spec.specifier = Sdf.SpecifierOver
    uv = Sdf.AttributeSpec(spec, f"primvars:{UV_PRIMVAR}", Sdf.ValueTypeNames.TexCoord2fArray)
    uv.default = Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(lay.uv_fv, dtype=np.float32))
    uv.SetInfo("interpolation", UsdGeom.Tokens.faceVarying)
    f = Sdf.AttributeSpec(spec, FILE_ATTR, Sdf.ValueTypeNames.Asset, Sdf.VariabilityUniform)
    f.default = Sdf.AssetPath(exr_rel)
    d = Sdf.AttributeSpec(spec, DENSITY_ATTR, Sdf.ValueTypeNames.Float, Sdf.VariabilityUniform)
    d.default = float(lay.achieved)
    if lay.tri_points is not None:
        # Re-authored as its triangles (a polygon spans two charts; see unwrap.py).
        c = Sdf.AttributeSpec(spec, "faceVertexCounts", Sdf.ValueTypeNames.IntArray)
        c.default = Vt.IntArray.FromNumpy(np.full(len(lay.tri_points), 3, dtype=np.int32))
        i = Sdf.AttributeSpec(spec, "faceVertexIndices", Sdf.ValueTypeNames.IntArray)
        i.default = Vt.IntArray.FromNumpy(lay.tri_points.reshape(-1).astype(np.int32))
        if lay.tri_normals_fv is not None:
            n = Sdf.AttributeSpec(spec, "primvars:normals", Sdf.ValueTypeNames.Normal3fArray)
            n.default = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(lay.tri_normals_fv))
            n.SetInfo("interpolation", UsdGeom.Tokens.faceVarying)


def _rel(target: Path, base: Path) -> str:
    try:
        r = os.path.relpath(target, base)
    except ValueError:  # another drive (Windows)
        return str(target)
    return r if r.startswith("..") else f"./{r}"


__all__ = [
    "BAKED_ATTR",
    "CHANNELS",
    "DENSITY_ATTR",
    "FILE_ATTR",
    "LAYER_KEY",
    "UV_PRIMVAR",
    "BakeReport",
    "bake_stage",
    "light_fingerprint",
]
