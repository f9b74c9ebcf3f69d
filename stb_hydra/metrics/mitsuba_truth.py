"""Mitsuba 3 as an independent ground truth for local lights (issue 20).

Converts small USD stages -- a camera, meshes and cubes (Lambert, or a Fresnel-1 GGX
metal: :func:`bsdf`), UsdLux sphere, disk, rect and cylinder lights (and a point / spot
light: ``treatAsPoint`` sphere with an optional hard cone) -- to a Mitsuba 3
``scalar_rgb`` scene and renders it with the
``direct`` integrator (one bounce: what our rasteriser computes). The stage is read
with ``pxr`` here, not with stb_hydra's own light reader, so the two renderers share
nothing but the USD file and the UsdLux conventions:

* radiance ``L = intensity * 2^exposure * color`` (nits), divided by the emitter's
  surface area when ``normalize`` is on; rect and disk emit from their -Z face only
  (one-sided Lambertian emitters); the cylinder from its side (no caps);
* a point light (``treatAsPoint``) has intensity ``L * pi r^2`` (cd);
* a RectLight's ``inputs:texture:file``: one constant rectangle of L x texel per texel,
  oriented as UsdLux says (decoded by ``scene/dome.py``'s reader: the file's decoding is
  the one shared step).

``compare`` returns the per-pixel relative error on pixels brighter than 1 % of the
floor's maximum, leaving out pixels the light's own shape covers in Mitsuba (ours does
not draw light shapes) and pixels on silhouette edges (Mitsuba integrates over the
pixel's area, ours shades its centre).

* a DomeLight with a lat-long texture: Mitsuba's ``envmap`` (issue 37).

Anything else in the stage (other gprims, distant lights, shaping on an area
light, IES, colour temperature, diffuse/specular multipliers, other materials) raises
ValueError naming the prim: a comparison is made only where the conversion is faithful
(``stb tradeoff`` reports the reference's error against Mitsuba only then).

Needs the ``mitsuba`` wheel (a test extra); importing this module without it raises
ImportError, so tests ``pytest.importorskip("mitsuba")`` first.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np
from pxr import Usd, UsdGeom, UsdLux, UsdShade

mi.set_variant("scalar_rgb")


def _m(mat) -> np.ndarray:
    """Gf row-vector matrix -> numpy column-vector convention (4x4)."""
    return np.array(mat, dtype=np.float64).T


def _pt(m: np.ndarray, p) -> list[float]:
    v = m @ np.array([p[0], p[1], p[2], 1.0])
    return [float(x) for x in v[:3] / v[3]]


def _surface_inputs(prim: Usd.Prim) -> dict:
    """The bound UsdPreviewSurface's authored inputs (name -> value), {} if none."""
    mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    if mat:
        src = mat.ComputeSurfaceSource()[0]
        if src:
            return {i.GetBaseName(): i.Get() for i in src.GetInputs() if i.Get() is not None}
    return {}


def _albedo(prim: Usd.Prim) -> list[float]:
    inp = _surface_inputs(prim)
    if "diffuseColor" in inp:
        return [float(x) for x in inp["diffuseColor"]]
    dc = UsdGeom.Gprim(prim).GetDisplayColorAttr().Get()
    if dc:
        return [float(x) for x in dc[0]]
    return [0.18, 0.18, 0.18]


def bsdf(prim: Usd.Prim) -> dict:
    """The Mitsuba BSDF of a surface, for the two materials the comparison supports:

    * Lambert: UsdPreviewSurface with ``useSpecularWorkflow = 1`` and a black
      ``specularColor`` (or no material: displayColor), ``diffuse``;
    * GGX mirror metal: black ``diffuseColor``, ``useSpecularWorkflow = 1``, white
      ``specularColor`` (our Schlick Fresnel is then exactly 1): ``roughconductor``,
      GGX, ``alpha = max(roughness^2, 0.002)`` (as brdf.glsl), ``material = none``
      (Fresnel 1). Mitsuba's GGX masking-shadowing is the separable Smith product
      ``G1(V) G1(L)``, ours the height-correlated one: up to a few per cent apart at
      grazing angles (tests/test_area_lights.py measures the difference it makes).

    Anything else raises ValueError (naming the prim)."""
    inp = _surface_inputs(prim)
    if not inp:
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": _albedo(prim)}}
    spec = [float(x) for x in inp.get("specularColor", (0.0, 0.0, 0.0))]
    dif = [float(x) for x in inp.get("diffuseColor", (0.18, 0.18, 0.18))]
    workflow = int(inp.get("useSpecularWorkflow", 0)) == 1
    unsupported = {"metallic", "clearcoat", "opacity", "emissiveColor", "normal"} & set(inp)
    if workflow and not unsupported and max(spec) == 0.0:
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": dif}}
    if workflow and not unsupported and max(dif) == 0.0 and min(spec) == 1.0:
        r = float(inp.get("roughness", 0.5))
        a = max(min(max(r, 0.02), 1.0) ** 2, 0.002)
        return {"type": "roughconductor", "distribution": "ggx", "alpha": a, "material": "none"}
    raise ValueError(
        f"{prim.GetPath()}: material not converted to Mitsuba (Lambert with black "
        "specularColor or white-specular GGX metal with black diffuseColor only)"
    )


def _input(light: UsdLux.LightAPI | UsdLux.BoundableLightBase, name: str, default):
    a = light.GetPrim().GetAttribute("inputs:" + name)
    v = a.Get() if a and a.HasAuthoredValue() else None
    return default if v is None else v


def _radiance(prim: Usd.Prim, area: float) -> list[float]:
    L = float(_input(prim, "intensity", 1.0)) * 2.0 ** float(_input(prim, "exposure", 0.0))
    rgb = np.array(_input(prim, "color", (1.0, 1.0, 1.0)), dtype=np.float64) * L
    if bool(_input(prim, "normalize", False)) and area > 0:
        rgb = rgb / area
    return [float(x) for x in rgb]


def _mesh(prim: Usd.Prim, world: np.ndarray, name: str, bsdf_dict: dict) -> mi.Mesh:
    mesh = UsdGeom.Mesh(prim)
    pts = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    counts = list(mesh.GetFaceVertexCountsAttr().Get())
    idx = list(mesh.GetFaceVertexIndicesAttr().Get())
    tris, k = [], 0
    for c in counts:
        for j in range(1, c - 1):
            tris.append((idx[k], idx[k + j], idx[k + j + 1]))
        k += c
    wp = (world @ np.c_[pts, np.ones(len(pts))].T).T[:, :3]
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf_dict)
    m = mi.Mesh(name, len(wp), len(tris), props=props)
    params = mi.traverse(m)
    params["vertex_positions"] = dr.scalar.ArrayXf(wp.astype(np.float32).ravel())
    params["faces"] = dr.scalar.ArrayXu(np.array(tris, dtype=np.uint32).ravel())
    params.update()
    return m


def stage_to_mitsuba(
    stage: Usd.Stage,
    width: int,
    height: int,
    spp: int,
    emitter_samples: int = 1,
    camera: str | None = None,
) -> dict:
    """A Mitsuba scene dict for ``stage``'s camera (``camera``: its path, default the
    first), meshes, cubes and lights; ``spp`` camera rays per pixel, each with
    ``emitter_samples`` light samples (no BSDF samples: the lights are never hit by
    chance, which is what our rasteriser does). ValueError for what it cannot convert."""
    tc = Usd.TimeCode.Default()
    cache = UsdGeom.XformCache(tc)
    integ = {"type": "direct", "emitter_samples": emitter_samples, "bsdf_samples": 0}
    scene: dict = {"type": "scene", "integrator": integ}
    for prim in stage.Traverse():
        world = _m(cache.GetLocalToWorldTransform(prim))
        key = prim.GetPath().pathString.strip("/").replace("/", "_")
        if not prim.IsActive() or (
            prim.IsA(UsdGeom.Imageable)
            and UsdGeom.Imageable(prim).ComputeVisibility(tc) == UsdGeom.Tokens.invisible
        ):
            continue
        if prim.IsA(UsdGeom.Camera):
            if "sensor" in scene or (camera and prim.GetPath().pathString != camera):
                continue
            cam = UsdGeom.Camera(prim).GetCamera(tc)
            fov = math.degrees(2.0 * math.atan(cam.horizontalAperture / (2.0 * cam.focalLength)))
            o = _pt(world, (0, 0, 0))
            t = _pt(world, (0, 0, -1))
            up = (world[:3, :3] @ np.array([0.0, 1.0, 0.0])).tolist()
            scene["sensor"] = {
                "type": "perspective",
                "fov": fov,
                "fov_axis": "x",
                "near_clip": 0.01,
                "to_world": mi.ScalarTransform4f().look_at(origin=o, target=t, up=up),
                "film": {
                    "type": "hdrfilm",
                    "width": width,
                    "height": height,
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
                "sampler": {"type": "independent", "sample_count": spp},
            }
        elif prim.IsA(UsdGeom.Mesh):
            scene[key] = _mesh(prim, world, key, bsdf(prim))
        elif prim.IsA(UsdGeom.Cube):
            s = float(UsdGeom.Cube(prim).GetSizeAttr().Get()) / 2.0
            scene[key] = {
                "type": "cube",
                "to_world": mi.ScalarTransform4f(world.tolist()) @ mi.ScalarTransform4f().scale(s),
                "bsdf": bsdf(prim),
            }
        elif prim.HasAPI(UsdLux.LightAPI):
            scene.update(_light(prim, world, key))
        elif prim.IsA(UsdGeom.Gprim):
            raise ValueError(f"{prim.GetPath()}: {prim.GetTypeName()} not converted to Mitsuba")
    if "sensor" not in scene:
        raise ValueError(f"no camera {camera or ''} to convert to Mitsuba")
    return scene


def _light(prim: Usd.Prim, world: np.ndarray, key: str) -> dict:
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
    M = mi.ScalarTransform4f(world.tolist())
    t = prim.GetTypeName()
    tap = prim.GetAttribute("treatAsPoint")
    point = t == "SphereLight" and bool(tap and tap.Get())
    shaping = ["shaping:ies:file", "shaping:focus", "shaping:cone:softness"]
    if not point:
        shaping.append("shaping:cone:angle")
    for name, default in [(n, None) for n in shaping] + [
        ("enableColorTemperature", False),
        ("diffuse", 1.0),
        ("specular", 1.0),
    ]:
        v = _input(prim, name, default)
        if v != default and not (name == "shaping:cone:softness" and not v):
            raise ValueError(f"{prim.GetPath()}: inputs:{name} not converted to Mitsuba")
    if t in ("DomeLight", "DomeLight_1"):
        return {key: _envmap(prim, world)}
    if t == "SphereLight":
        r = float(_input(prim, "radius", 0.5))
        if point:
            rgb = _radiance(prim, 4 * math.pi * r * r)
            intensity = [c * math.pi * r * r for c in rgb]
            cone = prim.GetAttribute("inputs:shaping:cone:angle")
            if cone and cone.HasAuthoredValue():
                ang = float(cone.Get())
                to_world = mi.ScalarTransform4f().look_at(
                    origin=_pt(world, (0, 0, 0)),
                    target=_pt(world, (0, 0, -1)),
                    up=(world[:3, :3] @ np.array([0.0, 1.0, 0.0])).tolist(),
                )
                return {
                    key: {
                        "type": "spot",
                        "to_world": to_world,
                        "cutoff_angle": ang,
                        "beam_width": ang,
                        "intensity": {"type": "rgb", "value": intensity},
                    }
                }
            return {
                key: {
                    "type": "point",
                    "position": _pt(world, (0, 0, 0)),
                    "intensity": {"type": "rgb", "value": intensity},
                }
            }
        shape = {"type": "sphere", "to_world": M @ mi.ScalarTransform4f().scale(r)}
        area = 4 * math.pi * r * r
    elif t == "DiskLight":
        r = float(_input(prim, "radius", 0.5))
        shape = {
            "type": "disk",
            "to_world": M @ mi.ScalarTransform4f().scale(r),
            "flip_normals": True,
        }
        area = math.pi * r * r
    elif t == "RectLight":
        w, h = float(_input(prim, "width", 1.0)), float(_input(prim, "height", 1.0))
        shape = {
            "type": "rectangle",
            "to_world": M @ mi.ScalarTransform4f().scale([w / 2, h / 2, 1.0]),
            "flip_normals": True,
        }
        area = w * h
    elif t == "CylinderLight":
        r = float(_input(prim, "radius", 0.5))
        ln = float(_input(prim, "length", 1.0))
        shape = {
            "type": "cylinder",
            "p0": _pt(world, (-ln / 2, 0, 0)),
            "p1": _pt(world, (ln / 2, 0, 0)),
            "radius": r,
        }
        area = 2 * math.pi * r * ln
    else:
        raise ValueError(f"{prim.GetPath()}: {t} not converted")
    shape["bsdf"] = black
    rgb = _radiance(prim, area)
    if t == "RectLight" and _rect_texture(prim) is not None:
        return _textured_rect(prim, M, w, h, rgb, key)
    shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": rgb}}
    return {key: shape}


def _rect_texture(prim: Usd.Prim) -> np.ndarray | None:
    """A RectLight's decoded ``inputs:texture:file`` (h, w, 3), None without one."""
    a = prim.GetAttribute("inputs:texture:file")
    asset = a.Get() if a and a.HasAuthoredValue() else None
    path = asset.resolvedPath if asset is not None else ""
    if not path:
        return None
    from ..scene.dome import _read_rgb

    return _read_rgb(path, "").astype(np.float64)


def _textured_rect(
    prim: Usd.Prim, M: mi.ScalarTransform4f, w: float, h: float, rgb: list[float], key: str
) -> dict:
    """A textured RectLight as one constant rectangle emitter per texel (at most 32 x 32):
    UsdLux puts the image's first column on the rect's +X edge and its top row on +Y.
    (A Mitsuba ``bitmap`` radiance rendered black under the ``direct`` integrator's
    emitter sampling in Mitsuba 3.9.)"""
    img = _rect_texture(prim)
    assert img is not None
    ny, nx = img.shape[:2]
    if nx > 32 or ny > 32:
        raise ValueError(f"{prim.GetPath()}: a rect texture over 32 x 32 texels not converted")
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
    out = {}
    for j in range(ny):
        for i in range(nx):
            cx, cy = w / 2 - (i + 0.5) * w / nx, h / 2 - (j + 0.5) * h / ny
            xf = mi.ScalarTransform4f().translate([cx, cy, 0.0])
            out[f"{key}_{j}_{i}"] = {
                "type": "rectangle",
                "to_world": M @ xf @ mi.ScalarTransform4f().scale([w / nx / 2, h / ny / 2, 1.0]),
                "flip_normals": True,
                "bsdf": black,
                "emitter": {
                    "type": "area",
                    "radiance": {"type": "rgb", "value": [float(v) for v in img[j, i] * rgb]},
                },
            }
    return out


def _envmap(prim: Usd.Prim, world: np.ndarray) -> dict:
    """A lat-long DomeLight as Mitsuba's ``envmap`` (its lat-long parameterisation is
    OpenEXR's in a Y-up frame, as UsdLux's): ``scale`` = intensity x 2^exposure; a
    grey ``color`` only, no poleAxis, a Y-up stage."""
    if prim.GetTypeName() == "DomeLight_1" or UsdGeom.GetStageUpAxis(prim.GetStage()) != "Y":
        raise ValueError(f"{prim.GetPath()}: only a DomeLight on a Y-up stage is converted")
    fmt = prim.GetAttribute("inputs:texture:format")
    if fmt and fmt.HasAuthoredValue() and fmt.Get() not in ("latlong", "automatic"):
        raise ValueError(f"{prim.GetPath()}: only a latlong dome texture is converted")
    asset = prim.GetAttribute("inputs:texture:file").Get()
    path = asset.resolvedPath if asset is not None else ""
    if not path:
        raise ValueError(f"{prim.GetPath()}: a dome without a (found) texture file")
    rgb = _radiance(prim, 0.0)
    if max(rgb) - min(rgb) > 1e-9 * max(rgb):
        raise ValueError(f"{prim.GetPath()}: a coloured dome is not converted")
    rot = np.eye(4)
    rot[:3, :3] = world[:3, :3] / np.linalg.norm(world[:3, :3], axis=0, keepdims=True)
    return {
        "type": "envmap",
        "filename": path,
        "scale": float(rgb[0]),
        "to_world": mi.ScalarTransform4f(rot.tolist()),
    }


def render_mitsuba(
    stage: Usd.Stage,
    width: int,
    height: int,
    spp: int,
    seed: int = 0,
    emitter_samples: int = 1,
    camera: str | None = None,
):
    """(image (h, w, 3) float64 nits, hit (h, w) shape id per pixel centre, -1 none,
    light (h, w) bool: the centre ray hits a light's own shape, normals (h, w, 3))."""
    d = stage_to_mitsuba(stage, width, height, spp, emitter_samples, camera)
    scene = mi.load_dict(d)
    img = np.array(mi.render(scene, seed=seed), dtype=np.float64)[..., :3]
    sensor = scene.sensors()[0]
    shapes = list(scene.shapes())
    hit = np.full((height, width), -1, dtype=np.int64)
    light = np.zeros((height, width), dtype=bool)
    normals = np.zeros((height, width, 3))
    for j in range(height):
        for i in range(width):
            ray, _ = sensor.sample_ray(
                0.0, 0.5, mi.Point2f((i + 0.5) / width, (j + 0.5) / height), mi.Point2f(0.5, 0.5)
            )
            si = scene.ray_intersect(ray)
            if si.is_valid():
                s = si.shape
                k = next(n for n, sh in enumerate(shapes) if sh == s)
                hit[j, i] = k
                light[j, i] = s.is_emitter()
                normals[j, i] = np.array(si.n)
    return img, hit, light, normals


def edge_mask(hit: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Pixels whose 3x3 neighbourhood sees another shape or another normal."""
    h, w = hit.shape
    e = np.zeros((h, w), dtype=bool)
    hp = np.pad(hit, 1, mode="edge")
    npd = np.pad(normals, ((1, 1), (1, 1), (0, 0)), mode="edge")
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            sh = hp[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
            sn = npd[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
            e |= sh != hit
            e |= np.sum(sn * normals, axis=-1) < 0.999
    return e


def luminance(img: np.ndarray) -> np.ndarray:
    return img[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def compare(ours: np.ndarray, ref: np.ndarray, hit, light, normals, floor_id: int | None = None):
    """Per-pixel relative luminance error |ours - ref| / ref on the pixels brighter than
    1 % of the floor's maximum (floor: shape ``floor_id``, default the most common hit),
    minus light-shape and edge pixels. Returns (errors 1-D, mask (h, w), error map)."""
    yo, yr = luminance(ours), luminance(ref)
    if floor_id is None:
        ids, cnt = np.unique(hit[hit >= 0], return_counts=True)
        floor_id = int(ids[np.argmax(cnt)])
    fmax = float(yr[hit == floor_id].max())
    mask = (yr > 0.01 * fmax) & (hit >= 0) & ~light & ~edge_mask(hit, normals)
    emap = np.where(mask, np.abs(yo - yr) / np.maximum(yr, 1e-12), 0.0)
    return emap[mask], mask, emap
