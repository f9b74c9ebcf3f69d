"""DomeLight textures -> one lat-long radiance map in the render frame (issue 37).

Every UsdLux ``texture:format`` is resampled once, on the CPU, into a single
representation every consumer shares: a lat-long map in the **render frame** (Y up),
OpenEXR's convention (UsdLux DomeLight docs): pixel column ``x`` has longitude
``pi - 2 pi (x + 0.5) / W``, row ``y`` latitude ``pi/2 - pi (y + 0.5) / H``; latitude 0,
longitude 0 is +Z, longitude pi/2 is +X. The dome's rotation (its transform,
``poleAxis`` / the stage's up axis) is folded into that resample, so shaders and the
reference's sampling tables never rotate anything.

Source formats (directions in the dome's own frame, Y up, before its rotation):

* ``latlong`` (and ``automatic`` unless the image is 3:4): the OpenEXR lat-long above;
* ``mirroredBall``: an orthographic image of a mirrored ball seen from +Z (the image
  centre reflects +Z, its rim -Z);
* ``angular``: Debevec's angular map: centre +Z, the radius linear in the angle from
  +Z (rim: -Z);
* ``cubeMapVerticalCross`` (and ``automatic`` for a 3:4 image): a 3 x 4 cross seen
  from inside the cube, front -Z: +Y on top, then -X, -Z, +X, then -Y, then +Z
  (stored upside down).

Values are radiance factors in linear Rec.709 (the texture decoded through the same
colour-space rules as material textures, ``color.texture_spaces``); the light's
intensity, exposure, colour and temperature multiply them (``LightPrim.dome_scale``).
No GL here.
"""

from __future__ import annotations

import math
import os

import numpy as np

from .. import limits
from .prims import DomeMap

FORMATS = ("automatic", "latlong", "mirroredBall", "angular", "cubeMapVerticalCross")

#: UsdLux DomeLight_1 ``poleAxis`` tokens.
POLE_AXES = ("scene", "Y", "Z")

#: Dome-local Y-up -> Z-up (+Y -> +Z, +Z -> -Y), row-vector convention.
Y_TO_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

_cache: dict[tuple, DomeMap] = {}


class DomeTextureError(Exception):
    """A dome texture that cannot be used (one-line reason)."""


# --- lat-long geometry ---------------------------------------------------------------------


def latlong_directions(h: int, w: int) -> np.ndarray:
    """(h, w, 3) unit directions of the texel centres of an OpenEXR lat-long map."""
    lat = math.pi / 2 - math.pi * (np.arange(h) + 0.5) / h
    lon = math.pi - 2.0 * math.pi * (np.arange(w) + 0.5) / w
    cl = np.cos(lat)[:, None]
    return np.stack(
        np.broadcast_arrays(cl * np.sin(lon)[None, :], np.sin(lat)[:, None], cl * np.cos(lon)),
        axis=-1,
    )


def latlong_uv(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lat-long coordinates (u right, v down, both in [0, 1]) of unit directions."""
    lon = np.arctan2(d[..., 0], d[..., 2])
    u = (math.pi - lon) / (2.0 * math.pi)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / math.pi
    return u, v


def texel_solid_angles(h: int, w: int) -> np.ndarray:
    """(h,) solid angle (sr) of one texel of each row of an h x w lat-long map."""
    edges = math.pi / 2 - math.pi * np.arange(h + 1) / h
    return (np.sin(edges[:-1]) - np.sin(edges[1:])) * (2.0 * math.pi / w)


def solid_angle_mean(img: np.ndarray) -> np.ndarray:
    """Solid-angle-weighted mean RGB of a lat-long map (the uniform-dome equivalent)."""
    h, w = img.shape[:2]
    sa = texel_solid_angles(h, w)
    return (img.astype(np.float64) * sa[:, None, None]).sum(axis=(0, 1)) / (4.0 * math.pi)


# --- SH irradiance -------------------------------------------------------------------------

#: Cosine-lobe convolution per SH band (Ramamoorthi & Hanrahan 2001), over pi: the
#: result is E / pi, the radiance a white Lambert surface reflects (albedo 1).
_A_OVER_PI = np.array([1.0, 2.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0, 0.25, 0.25, 0.25, 0.25, 0.25])


def sh9_basis(d: np.ndarray) -> np.ndarray:
    """(..., 9) real SH basis (bands 0-2) at unit directions ``d`` (..., 3); the order
    matches ``shaders/common/dome.glsl``."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack(
        [
            np.full_like(x, 0.282095),
            0.488603 * y,
            0.488603 * z,
            0.488603 * x,
            1.092548 * x * y,
            1.092548 * y * z,
            0.315392 * (3.0 * z * z - 1.0),
            1.092548 * x * z,
            0.546274 * (x * x - y * y),
        ],
        axis=-1,
    )


def sh9_irradiance(img: np.ndarray) -> np.ndarray:
    """(9, 3) SH coefficients of E(n) / pi for a lat-long radiance map: evaluated with
    :func:`sh9_basis` at a normal they give the light a white Lambert surface of that
    normal reflects (unshadowed)."""
    h, w = img.shape[:2]
    basis = sh9_basis(latlong_directions(h, w))  # (h, w, 9)
    wt = texel_solid_angles(h, w)[:, None, None]
    coeff = np.einsum("hwk,hwc->kc", basis * wt, img.astype(np.float64))
    return coeff * _A_OVER_PI[:, None]


# --- the sun of a sun-and-sky map ----------------------------------------------------------


def split_sun(img: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Split a compact, dominant bright source (a sun) off a lat-long map, for the
    real-time methods: they light it as a shadowed distant light and the rest from the
    prefiltered map. The sun is the texels brighter than ``limits.DOME_SUN_THRESHOLD``
    of the brightest within ``limits.DOME_SUN_MAX_RADIUS_DEG`` of it, when they carry
    at least ``limits.DOME_SUN_MIN_SHARE`` of the map's power.

    Returns (the map with those texels replaced by the mean of the ring around them,
    unit direction to the sun (render frame), its illuminance facing it per map unit
    (lux RGB)), or None when the map has no such source."""
    h, w = img.shape[:2]
    lum = img.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    sa = texel_solid_angles(h, w)[:, None]
    total = float((lum * sa).sum())
    k = int(np.argmax(lum))
    peak = float(lum.flat[k])
    if not (total > 0 and peak > 0 and math.isfinite(total)):
        return None
    dirs = latlong_directions(h, w)
    centre = dirs.reshape(-1, 3)[k]
    cosang = dirs @ centre
    near = cosang >= math.cos(math.radians(limits.DOME_SUN_MAX_RADIUS_DEG))
    region = near & (lum >= limits.DOME_SUN_THRESHOLD * peak)
    ring = (cosang >= math.cos(math.radians(1.5 * limits.DOME_SUN_MAX_RADIUS_DEG))) & ~near
    fill = img[ring].mean(axis=0) if ring.any() else np.zeros(3)
    excess = (img.astype(np.float64) - fill) * region[..., None]
    e = (excess * sa[..., None]).sum(axis=(0, 1))  # illuminance facing the sun, lux
    share = float(e @ np.array([0.2126, 0.7152, 0.0722])) / total
    if share < limits.DOME_SUN_MIN_SHARE:
        return None
    wts = (excess * sa[..., None]).sum(axis=-1)
    d = (dirs * wts[..., None]).sum(axis=(0, 1))
    d = d / max(float(np.linalg.norm(d)), 1e-12)
    rest = np.where(region[..., None], fill[None, None, :], img).astype(np.float32)
    return rest, d, np.maximum(e, 0.0)


# --- sampling of the source formats ---------------------------------------------------------


def _bilinear(img: np.ndarray, u: np.ndarray, v: np.ndarray, wrap_u: bool) -> np.ndarray:
    """Bilinear lookup of (h, w, c) ``img`` at (u right, v down) in [0, 1]."""
    h, w = img.shape[:2]
    x = u * w - 0.5
    y = np.clip(v * h - 0.5, 0.0, h - 1.0)
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[..., None]
    fy = (y - y0)[..., None]
    x0i = x0.astype(np.int64)
    y0i = y0.astype(np.int64)
    if wrap_u:
        xa, xb = x0i % w, (x0i + 1) % w
    else:
        xa, xb = np.clip(x0i, 0, w - 1), np.clip(x0i + 1, 0, w - 1)
    ya, yb = y0i, np.minimum(y0i + 1, h - 1)
    top = img[ya, xa] * (1 - fx) + img[ya, xb] * fx
    bot = img[yb, xa] * (1 - fx) + img[yb, xb] * fx
    return top * (1 - fy) + bot * fy


def _ball_uv(d: np.ndarray, angular: bool) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) of directions in a mirrored-ball or angular map (centre +Z)."""
    rxy = np.maximum(np.hypot(d[..., 0], d[..., 1]), 1e-12)
    ang = np.arccos(np.clip(d[..., 2], -1.0, 1.0))  # angle from +Z
    # mirrored ball: the normal halfway between +Z and d; its image radius sin(ang/2)
    r = ang / math.pi if angular else np.sin(ang / 2.0)
    x = d[..., 0] / rxy * r
    y = d[..., 1] / rxy * r
    return (x + 1.0) * 0.5, (1.0 - y) * 0.5


#: Vertical cross faces (front -Z, the viewer inside the cube, Y up): (column, row,
#: axis index, sign, (u axis, u sign), (v axis, v sign)), u right and v down in the
#: image; +Z, below -Y, is stored upside down.
_CROSS = (
    (1, 0, 1, 1.0, (0, 1.0), (2, -1.0)),  # +Y: top
    (0, 1, 0, -1.0, (2, -1.0), (1, -1.0)),  # -X
    (1, 1, 2, -1.0, (0, 1.0), (1, -1.0)),  # -Z: centre (front)
    (2, 1, 0, 1.0, (2, 1.0), (1, -1.0)),  # +X
    (1, 2, 1, -1.0, (0, 1.0), (2, 1.0)),  # -Y
    (1, 3, 2, 1.0, (0, 1.0), (1, 1.0)),  # +Z (upside down)
)


def _cross_sample(img: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Lookup of directions in a 3 x 4 vertical-cross cube map (nearest face)."""
    h, w = img.shape[:2]
    fw, fh = w // 3, h // 4
    out = np.zeros((*d.shape[:-1], img.shape[2]), dtype=np.float64)
    major = np.argmax(np.abs(d), axis=-1)
    for col, row, axis, sign, (ua, us), (va, vs) in _CROSS:
        sel = (major == axis) & (np.sign(d[..., axis]) == sign)
        if not sel.any():
            continue
        ds = d[sel]
        m = np.abs(ds[:, axis])
        fu = (us * ds[:, ua] / m + 1.0) * 0.5
        fv = (vs * ds[:, va] / m + 1.0) * 0.5
        face = img[row * fh : (row + 1) * fh, col * fw : (col + 1) * fw]
        out[sel] = _bilinear(face, np.clip(fu, 0, 1), np.clip(fv, 0, 1), wrap_u=False)
    return out


def _sample_source(img: np.ndarray, fmt: str, d: np.ndarray) -> np.ndarray:
    """Radiance of source image ``img`` (format ``fmt``) in dome-local directions ``d``."""
    if fmt == "latlong":
        u, v = latlong_uv(d)
        return _bilinear(img, u, v, wrap_u=True)
    if fmt in ("mirroredBall", "angular"):
        u, v = _ball_uv(d, fmt == "angular")
        return _bilinear(img, u, v, wrap_u=False)
    return _cross_sample(img, d)


def resolve_format(fmt: str, width: int, height: int) -> str:
    """The concrete format: ``automatic`` is a vertical cross for a 3:4 image, else
    lat-long."""
    if fmt == "automatic":
        return "cubeMapVerticalCross" if width * 4 == height * 3 else "latlong"
    return fmt


def dome_rotation(world: np.ndarray, pole_axis: str, stage_up_z: bool) -> np.ndarray:
    """3x3 row-vector rotation dome texture frame -> render frame: the pole-axis
    alignment (DomeLight_1 ``poleAxis``: Z, or "scene" on a Z-up stage, turns the
    texture's +Y pole to +Z) then the light's transform (scale removed)."""
    m = np.asarray(world, dtype=np.float64)[:3, :3]
    n = np.linalg.norm(m, axis=1, keepdims=True)
    m = m / np.where(n > 1e-12, n, 1.0)
    if pole_axis == "Z" or (pole_axis == "scene" and stage_up_z):
        m = Y_TO_Z @ m
    return m


# --- loading --------------------------------------------------------------------------------


def _read_rgb(path: str, color_space: str) -> np.ndarray:
    """(h, w, 3) float32 linear Rec.709 pixels of an image file (OIIO, decoded like a
    material texture: ``color_space`` "" or "auto" follows the file). Raises
    DomeTextureError."""
    import OpenImageIO as oiio

    from ..color.texture_spaces import CONVERT, SRGB, TextureColorSpaces, srgb_to_linear

    try:
        size = os.path.getsize(path)
    except OSError:
        raise DomeTextureError("file not found") from None
    if size > limits.TEXTURE_MAX_FILE_BYTES:
        raise DomeTextureError(f"file larger than {limits.TEXTURE_MAX_FILE_BYTES} bytes")
    buf = oiio.ImageBuf(path)
    # Read it all now: a lazily read (image cache) buffer of a truncated file resizes
    # for minutes, every missing tile retried (found by tools/fuzz.py).
    if buf.has_error or not buf.read(0, 0, True):
        raise DomeTextureError(" ".join(str(buf.geterror() or "unreadable image").split())[:200])
    spec = buf.spec()
    w, h, c = int(spec.width), int(spec.height), int(spec.nchannels)
    if w <= 0 or h <= 0 or c <= 0:
        raise DomeTextureError("empty image")
    # Shrink very large maps first with OIIO's filtered resize (energy kept).
    cap = limits.DOME_MAX_WIDTH
    if w > cap * 2 or h > cap * 2:
        k = max(w / (cap * 2), h / (cap * 2))
        nw, nh = max(1, int(w / k)), max(1, int(h / k))
        buf = oiio.ImageBufAlgo.resize(buf, roi=oiio.ROI(0, nw, 0, nh, 0, 1, 0, c))
        w, h = nw, nh
    px = np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float32).reshape(h, w, c)
    rgb = px[..., :3] if c >= 3 else np.repeat(px[..., :1], 3, axis=2)
    fmt = spec.format.basetype
    bits = 8 if fmt in (oiio.UINT8, oiio.INT8) else 16 if fmt in (oiio.UINT16, oiio.INT16) else 32
    colors = TextureColorSpaces()
    file_space = str(spec.getattribute("oiio:ColorSpace") or "")
    dec = colors.decode(color_space or "auto", bits, c, file_space)
    if dec.kind == SRGB:
        rgb = srgb_to_linear(rgb).astype(np.float32)
    elif dec.kind == CONVERT:
        rgb = colors.convert(rgb, dec.space)
    rgb = np.where(np.isfinite(rgb), np.maximum(rgb, 0.0), 0.0)
    return np.minimum(rgb, limits.DOME_MAX_RADIANCE).astype(np.float32)


def load_dome_map(path: str, fmt: str, rotation: np.ndarray, color_space: str = "") -> DomeMap:
    """The render-frame lat-long map of dome texture ``path`` (format ``fmt``, dome
    texture frame -> render frame ``rotation``), cached by file, mtime, format,
    colour space and rotation. Raises DomeTextureError with a one-line reason."""
    try:
        mtime = os.path.getmtime(path)
    except OSError:
        raise DomeTextureError("file not found") from None
    rot = np.round(np.asarray(rotation, dtype=np.float64), 6)
    key = (path, mtime, fmt, color_space, rot.tobytes())
    hit = _cache.get(key)
    if hit is not None:
        return hit
    src = _read_rgb(path, color_space)
    sh, sw = src.shape[:2]
    concrete = resolve_format(fmt, sw, sh)
    if concrete == "latlong":
        w = min(sw, limits.DOME_MAX_WIDTH)
    else:
        w = min(2 * max(sw, sh), limits.DOME_MAX_WIDTH)
    w = max(8, w - w % 2)
    h = w // 2
    if concrete == "latlong" and (sw, sh) == (w, h) and np.allclose(rot, np.eye(3)):
        img = src
    else:
        d_render = latlong_directions(h, w)
        d_tex = d_render @ rot.T  # inverse of the (orthonormal) rotation
        img = _sample_source(src.astype(np.float64), concrete, d_tex).astype(np.float32)
    img = np.ascontiguousarray(img, dtype=np.float32)
    dm = DomeMap(
        latlong=img,
        mean=solid_angle_mean(img),
        sh9=sh9_irradiance(img),
        source=path,
        format=concrete,
    )
    sun = split_sun(img)
    if sun is not None:
        dm.rest, dm.sun_direction, dm.sun_illuminance = sun
        dm.rest_sh9 = sh9_irradiance(dm.rest)
    if len(_cache) >= limits.DOME_CACHE_ENTRIES:
        _cache.pop(next(iter(_cache)))
    _cache[key] = dm
    return dm


# --- importance sampling (the reference method) ---------------------------------------------


class DomeSampler:
    """Directions drawn in proportion to a lat-long map's luminance x solid angle (a
    CDF over rows, then over the texels of the row), uniform in solid angle
    inside the chosen texel; ``pdf`` per steradian. Built once per map."""

    def __init__(self, img: np.ndarray) -> None:
        h, w = img.shape[:2]
        self.h, self.w = h, w
        lum = np.maximum(img.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722]), 0.0)
        sa = texel_solid_angles(h, w)
        # A floor keeps every texel reachable (pdf > 0 where the map is not black).
        weight = lum * sa[:, None]
        total = float(weight.sum())
        if not (total > 0 and math.isfinite(total)):
            weight = np.broadcast_to(sa[:, None], (h, w)).copy()
            total = float(weight.sum())
        self.p_texel = weight / total  # probability of each texel
        row = np.cumsum(self.p_texel.sum(axis=1))
        self.row_cdf = row / row[-1]
        cols = np.cumsum(self.p_texel, axis=1)
        cols = cols / np.maximum(cols[:, -1:], 1e-300)
        # Row r's conditional CDF shifted by r: one increasing array for every row.
        self.col_keys = (np.arange(h)[:, None] + cols).ravel()
        self.sa = sa
        self.img = img

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Directions for uniform numbers ``u`` (n, 4) in [0, 1) (row, column, then the
        point inside the texel): (unit directions
        (n, 3) render frame, map radiance (n, 3), pdf (n,) per steradian)."""
        h, w = self.h, self.w
        r = np.clip(np.searchsorted(self.row_cdf, u[:, 0], side="right"), 0, h - 1)
        k = np.searchsorted(self.col_keys, r + np.minimum(u[:, 1], 1.0 - 1e-12), side="right")
        c = np.clip(k - r * w, 0, w - 1)
        # Uniform in solid angle inside the texel: uniform in sin(latitude) and longitude.
        lat_hi = math.pi / 2 - math.pi * r / h
        lat_lo = math.pi / 2 - math.pi * (r + 1) / h
        s = np.sin(lat_lo) + u[:, 2] * (np.sin(lat_hi) - np.sin(lat_lo))
        lon = math.pi - 2.0 * math.pi * (c + u[:, 3]) / w
        cl = np.sqrt(np.maximum(1.0 - s * s, 0.0))
        d = np.stack([cl * np.sin(lon), s, cl * np.cos(lon)], axis=-1)
        pdf = self.p_texel[r, c] / self.sa[r]
        return d, self.img[r, c].astype(np.float64), pdf
