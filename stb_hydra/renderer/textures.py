"""The GPU texture cache of material textures.

One :class:`GpuTexture` per (resolved file, decode), shared by every material,
prim and instance that reads it, refcounted by user (material path):

* **Read** through OpenImageIO (every format it reads; ``.tx`` mip chains used as
  stored), ``<UDIM>`` files as one 2D-array layer per tile (tiles 1001-1100,
  ``limits.MAX_UDIM_TILES``; a missing tile inside the range reads the fallback).
* **Colour** to scene-linear Rec.709 (:mod:`stb_hydra.color.texture_spaces`): 8-bit
  sRGB data is kept as ``GL_SRGB8_ALPHA8`` (the GPU decodes, before filtering);
  raw 8/16-bit data as unorm; float data and OCIO conversions as half floats.
* **Rows** are flipped on upload: USD's ``st`` has t = 0 at the image's bottom row.
* **Filtering**: mipmapped (trilinear), anisotropic (``limits.TEXTURE_ANISOTROPY``);
  wrap modes are sampler objects (:meth:`TextureCache.sampler`), so one texture
  serves repeat / mirror / clamp / black users alike.
* **Budget**: the textures of the current material set are planned together
  (:meth:`TextureCache.plan`): while they exceed ``limits.TEXTURE_BUDGET_BYTES`` the
  largest is halved (one warning naming the files and their sizes).
* **Bad input** (missing, unreadable, corrupt, too large) is one warning naming the
  file and the material; the lookup then uses the input's fallback.

No per-texel Python loops: decoding, downscaling and conversion are numpy / OCIO.
"""

from __future__ import annotations

import dataclasses
import glob
import os
import re
from collections import OrderedDict
from dataclasses import dataclass, field

import moderngl
import numpy as np

from .. import limits
from ..color.texture_spaces import (
    CONVERT,
    RAW,
    SRGB,
    Decode,
    TextureColorSpaces,
    linear_to_srgb,
    srgb_to_linear,
)
from ..scene.prims import TextureRef

_UDIM = "<UDIM>"
_UDIM_RE = re.compile(r"<UDIM>")
#: OIIO ``wrapmodes`` metadata words -> our wrap tokens.
_META_WRAP = {"periodic": "repeat", "clamp": "clamp", "mirror": "mirror", "black": "black"}


@dataclass(frozen=True)
class TextureKey:
    """What identifies a GPU texture: the resolved file and the colour token (the
    decode also depends on the file's bit depth and channels, read on load)."""

    file: str
    color_space: str


@dataclass
class ImageInfo:
    """What a texture file says of itself (header only; read once per plan)."""

    width: int
    height: int
    channels: int
    bits: int  # 8, 16, or 32 for float data (half included)
    #: (path, tile number) per layer; tile 0 for a plain file.
    layers: list[tuple[str, int]]
    #: Stored mip levels (``.tx``), 1 when none.
    mip_levels: int = 1
    wrap_meta: tuple[str | None, str | None] = (None, None)


@dataclass
class GpuTexture:
    key: TextureKey
    texture: moderngl.TextureArray
    #: Channels of the file (1-4): how the shader expands them (see ``expand_matrix``).
    channels: int
    #: First UDIM tile of layer 0 (0: a plain file, one layer).
    udim_first: int
    layers: int
    decode: Decode
    #: Downscale applied (1, 2, 4, ...), and the bytes it holds on the GPU.
    shrink: int
    nbytes: int
    wrap_meta: tuple[str | None, str | None] = (None, None)
    users: set[str] = field(default_factory=set)


def expand_matrix(channels: int) -> np.ndarray:
    """4x4 (column-vector) matrix from a texel as sampled to UsdUVTexture's rgba:
    1 channel -> (r, r, r, 1), 2 channels -> (r, r, r, g), 3 -> (r, g, b, 1), 4 as is
    (GL returns 0 for missing colour channels and 1 for a missing alpha)."""
    m = np.zeros((4, 4))
    if channels == 1:
        m[0, 0] = m[1, 0] = m[2, 0] = 1.0
        m[3, 3] = 1.0  # GL's alpha of an R texture is 1
    elif channels == 2:
        m[0, 0] = m[1, 0] = m[2, 0] = 1.0
        m[3, 1] = 1.0
    else:
        m = np.eye(4)
    return m


def _bits(fmt: object) -> int:
    s = str(fmt)
    if s in ("uint8", "int8"):
        return 8
    if s in ("uint16", "int16"):
        return 16
    return 32


def udim_tiles(pattern: str) -> list[tuple[str, int]]:
    """Existing tiles of a ``<UDIM>`` path: (path, tile) sorted by tile."""
    head, _sep, tail = pattern.partition(_UDIM)
    out = []
    for p in glob.glob(glob.escape(head) + "[0-9][0-9][0-9][0-9]" + glob.escape(tail)):
        t = p[len(head) : len(head) + 4]
        if t.isdigit():
            n = int(t)
            first = limits.UDIM_FIRST_TILE
            if first <= n < first + limits.MAX_UDIM_TILES:
                out.append((p, n))
    return sorted(out, key=lambda x: x[1])


#: Headers read by ``read_info`` in this process, by (file, mtime ns, size): the next
#: engine on the same files (a reload, another render) does not open them again; a file
#: rewritten on disk has a new key. At most ``limits.TEXTURE_INFO_CACHE_FILES``.
_info_cache: OrderedDict[tuple[str, int, int], ImageInfo] = OrderedDict()


def read_info(path: str) -> ImageInfo:
    """Header of a texture file (or of a ``<UDIM>`` set: its first tile; every tile
    must have the same size, or the set is refused). Raises ``OSError`` with a
    one-line reason."""
    if _UDIM in path:
        tiles = udim_tiles(path)
        if not tiles:
            raise OSError("no UDIM tile found")
    else:
        tiles = [(path, 0)]
    first = tiles[0][0]
    try:
        st = os.stat(first)
    except OSError:
        raise OSError("file not found") from None
    if st.st_size > limits.TEXTURE_MAX_FILE_BYTES:
        raise OSError(f"file larger than {limits.TEXTURE_MAX_FILE_BYTES} bytes")
    key = (first, st.st_mtime_ns, st.st_size)
    known = _info_cache.get(key)
    if known is None:
        known = _read_header(first)
        _info_cache[key] = known
        while len(_info_cache) > limits.TEXTURE_INFO_CACHE_FILES:
            _info_cache.popitem(last=False)
    else:
        _info_cache.move_to_end(key)
    return dataclasses.replace(known, layers=list(tiles))


def _read_header(first: str) -> ImageInfo:
    """``read_info`` of one file, from the file (its ``layers``: that file alone)."""
    import OpenImageIO as oiio

    tiles = [(first, 0)]
    inp = oiio.ImageInput.open(first)
    if inp is None:
        raise OSError(_oiio_reason(oiio.geterror()))
    try:
        spec = inp.spec()
        w, h, c = int(spec.width), int(spec.height), int(spec.nchannels)
        levels = 1
        while inp.seek_subimage(0, levels):
            levels += 1
        wm = str(spec.getattribute("wrapmodes") or "")
    finally:
        inp.close()
    if w <= 0 or h <= 0 or c <= 0:
        raise OSError("empty image")
    wraps: list[str | None] = [None, None]
    if wm:
        parts = wm.split(",")
        for i, word in enumerate(parts[:2]):
            wraps[i] = _META_WRAP.get(word.strip())
        if len(parts) == 1:
            wraps[1] = wraps[0]
    return ImageInfo(w, h, min(c, 4), _bits(spec.format), tiles, levels, (wraps[0], wraps[1]))


def _oiio_reason(err: str) -> str:
    line = " ".join(str(err).split())
    return line[:200] if line else "unreadable image"


def _read_level(path: str, level: int, channels: int, bits: int) -> np.ndarray:
    """(h, w, channels) pixels of one mip level, uint8 / uint16 / float32."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(_oiio_reason(oiio.geterror()))
    try:
        if level and not inp.seek_subimage(0, level):
            raise OSError(f"mip level {level} missing")
        fmt = {8: "uint8", 16: "uint16"}.get(bits, "float")
        data = inp.read_image(0, level, 0, channels, fmt)
    finally:
        inp.close()
    if data is None:
        raise OSError(_oiio_reason(oiio.geterror()))
    a = np.asarray(data)
    if a.ndim == 2:
        a = a[:, :, None]
    return a


_GL_FORMATS = {1: "GL_RED", 2: "GL_RG", 3: "GL_RGB", 4: "GL_RGBA"}


def _write_level(tex: moderngl.TextureArray, data: np.ndarray, level: int) -> None:
    """Define one stored mip level of layer 0 (moderngl's TextureArray.write has no
    level, and it allocated level 0 only): (h, w, c) uint8 / uint16 / float16, rows
    already flipped, the internal format of level 0."""
    from OpenGL import GL

    h, w, c = data.shape
    gl_type = {
        np.dtype(np.uint8): GL.GL_UNSIGNED_BYTE,
        np.dtype(np.uint16): GL.GL_UNSIGNED_SHORT,
        np.dtype(np.float16): GL.GL_HALF_FLOAT,
    }[data.dtype]
    target = GL.GL_TEXTURE_2D_ARRAY
    GL.glBindTexture(target, tex.glo)
    GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
    fmt = int(GL.glGetTexLevelParameteriv(target, 0, GL.GL_TEXTURE_INTERNAL_FORMAT))
    pixels = np.ascontiguousarray(data)
    GL.glTexImage3D(target, level, fmt, w, h, 1, 0, getattr(GL, _GL_FORMATS[c]), gl_type, pixels)


def _halve(a: np.ndarray, srgb: bool) -> np.ndarray:
    """2x2 box filter (odd sizes: the last row/column repeated), in linear light for
    sRGB data; same dtype out."""
    h, w = a.shape[:2]
    if h % 2:
        a = np.concatenate([a, a[-1:]], axis=0)
    if w % 2:
        a = np.concatenate([a, a[:, -1:]], axis=1)
    f: np.ndarray = a.astype(np.float64)
    scale = 255.0 if a.dtype == np.uint8 else 65535.0 if a.dtype == np.uint16 else 1.0
    if srgb and a.dtype == np.uint8:
        f = f / scale
        rgb = srgb_to_linear(f[..., :3])
        f = np.concatenate([rgb, f[..., 3:]], axis=-1)
    f = 0.25 * (f[0::2, 0::2] + f[1::2, 0::2] + f[0::2, 1::2] + f[1::2, 1::2])
    if srgb and a.dtype == np.uint8:
        f = np.concatenate([linear_to_srgb(f[..., :3]), f[..., 3:]], axis=-1) * scale
    if a.dtype == np.uint8 or a.dtype == np.uint16:
        return np.clip(np.rint(f), 0, scale).astype(a.dtype)
    return f.astype(a.dtype)


class TextureCache:
    """Material textures on the GPU; see the module docstring."""

    def __init__(
        self,
        ctx: moderngl.Context,
        colors: TextureColorSpaces | None = None,
        budget_bytes: int = limits.TEXTURE_BUDGET_BYTES,
    ) -> None:
        self.ctx = ctx
        self._colors = colors
        self.budget_bytes = int(budget_bytes)
        self.textures: dict[TextureKey, GpuTexture] = {}
        self._infos: dict[str, ImageInfo | str] = {}
        self._shrink: dict[TextureKey, int] = {}
        self._samplers: dict[tuple[str, str], moderngl.Sampler] = {}
        self._failed: set[TextureKey] = set()
        self._dummy: moderngl.TextureArray | None = None
        self.warnings: list[str] = []
        self._warned: set[str] = set()
        self.stats: dict[str, float] = {"loads": 0, "load_seconds": 0.0}

    @property
    def colors(self) -> TextureColorSpaces:
        if self._colors is None:
            self._colors = TextureColorSpaces()
        return self._colors

    @property
    def nbytes(self) -> int:
        return sum(t.nbytes for t in self.textures.values())

    def _warn(self, key: str, msg: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(msg)

    # -- planning -------------------------------------------------------------------

    def info(self, path: str) -> ImageInfo | None:
        """Header of ``path`` (cached; None when unreadable, warned once by the caller)."""
        got = self._infos.get(path)
        if got is None:
            try:
                got = read_info(path)
            except OSError as exc:
                got = str(exc) or "unreadable image"
            except Exception as exc:  # noqa: BLE001 - a corrupt file must not crash
                got = " ".join(str(exc).split())[:200] or "unreadable image"
            self._infos[path] = got
        return got if isinstance(got, ImageInfo) else None

    def info_error(self, path: str) -> str:
        got = self._infos.get(path)
        return got if isinstance(got, str) else ""

    @staticmethod
    def _bytes_for(info: ImageInfo, decode: Decode, shrink: int) -> int:
        w = max(1, info.width // shrink)
        h = max(1, info.height // shrink)
        if decode.kind == SRGB and info.bits == 8:
            texel = 4
        elif info.bits == 8 and decode.kind == RAW:
            texel = {1: 1, 2: 2, 3: 4, 4: 4}[info.channels]  # RGB8 is stored as RGBA8
        elif info.bits == 16 and decode.kind == RAW:
            texel = 2 * {1: 1, 2: 2, 3: 4, 4: 4}[info.channels]
        else:
            texel = 8  # half float RGBA
        return int(w * h * texel * len(info.layers) * 4 // 3)

    def decode_for(self, key: TextureKey, info: ImageInfo) -> Decode:
        return self.colors.decode(key.color_space, info.bits, info.channels)

    def plan(self, refs: dict[TextureKey, str]) -> None:
        """Choose each needed texture's downscale so the set fits the budget, before
        anything is loaded. ``refs``: key -> a description of its users (messages)."""
        sizes: dict[TextureKey, tuple[ImageInfo, Decode]] = {}
        for key in refs:
            info = self.info(key.file)
            if info is not None:
                sizes[key] = (info, self.decode_for(key, info))
        shrink = {k: 1 for k in sizes}
        for k, (info, _d) in sizes.items():
            while max(info.width, info.height) // shrink[k] > limits.TEXTURE_MAX_SIZE:
                shrink[k] *= 2
        total = sum(self._bytes_for(i, d, shrink[k]) for k, (i, d) in sizes.items())
        while total > self.budget_bytes and sizes:
            k = max(sizes, key=lambda k: self._bytes_for(*sizes[k], shrink[k]))
            i, d = sizes[k]
            if max(i.width, i.height) // shrink[k] <= 16:
                break
            before = self._bytes_for(i, d, shrink[k])
            shrink[k] *= 2
            total += self._bytes_for(i, d, shrink[k]) - before
        shrunk = sorted((k for k in sizes if shrink[k] > 1), key=lambda k: k.file)
        if shrunk:
            names = ", ".join(
                f"{os.path.basename(k.file)} ({sizes[k][0].width}->"
                f"{max(1, sizes[k][0].width // shrink[k])} px)"
                for k in shrunk[:6]
            )
            more = f" (+{len(shrunk) - 6} more)" if len(shrunk) > 6 else ""
            self._warn(
                "budget:" + ",".join(k.file for k in shrunk),
                f"textures exceed the {self.budget_bytes / 2**20:.4g} MiB texture budget "
                f"(or {limits.TEXTURE_MAX_SIZE} px); downscaled: {names}{more}",
            )
        for k in sizes:
            if self._shrink.get(k, 1) != shrink[k] and k in self.textures:
                self._drop(k)
            self._shrink[k] = shrink[k]

    # -- acquire / release ----------------------------------------------------------

    def acquire(self, ref: TextureRef, user: str) -> GpuTexture | None:
        """The GPU texture of ``ref`` for ``user`` (loaded on first use), or None
        when the file cannot be read (warned once, naming the file and the user)."""
        key = TextureKey(ref.file, ref.source_color_space)
        t = self.textures.get(key)
        if t is None:
            if key in self._failed:
                return None
            t = self._load(key, ref, user)
            if t is None:
                self._failed.add(key)
                return None
            self.textures[key] = t
        t.users.add(user)
        return t

    def release_user(self, user: str) -> None:
        """Forget ``user``; textures nobody uses any more are freed."""
        for key in [k for k, t in self.textures.items() if user in t.users]:
            t = self.textures[key]
            t.users.discard(user)
            if not t.users:
                self._drop(key)

    def forget_file(self, path: str) -> None:
        """The file changed on disk (or its asset path was edited): reload on next use."""
        self._infos.pop(path, None)
        for key in [k for k in self.textures if k.file == path]:
            self._drop(key)
        self._failed = {k for k in self._failed if k.file != path}
        self._warned = {w for w in self._warned if path not in w}

    def _drop(self, key: TextureKey) -> None:
        t = self.textures.pop(key, None)
        if t is not None:
            t.texture.release()

    def _load(self, key: TextureKey, ref: TextureRef, user: str) -> GpuTexture | None:
        import time

        t0 = time.perf_counter()
        where = f"texture '{ref.asset or ref.file}' (material <{user}>)"
        info = self.info(key.file)
        if info is None:
            self._warn(
                "load:" + key.file,
                f"{where}: {self.info_error(key.file) or 'unreadable'}; using the fallback",
            )
            return None
        decode = self.decode_for(key, info)
        if not self.colors.known(key.color_space):
            self._warn(
                "cs:" + key.color_space,
                f"{where}: colour space '{key.color_space}' is not in the OCIO config; read as raw",
            )
        shrink = self._shrink.get(key, 1)
        while max(info.width, info.height) // shrink > limits.TEXTURE_MAX_SIZE:
            shrink *= 2
        try:
            tex, channels = self._upload(info, decode, shrink)
        except (OSError, ValueError, moderngl.Error) as exc:
            self._warn(
                "load:" + key.file,
                f"{where}: {' '.join(str(exc).split())[:200]}; using the fallback",
            )
            return None
        self.stats["loads"] += 1
        self.stats["load_seconds"] += time.perf_counter() - t0
        first = info.layers[0][1] if _UDIM in key.file else 0
        return GpuTexture(
            key,
            tex,
            channels,
            first,
            self._layer_count(info),
            decode,
            shrink,
            self._bytes_for(info, decode, shrink),
            info.wrap_meta,
        )

    @staticmethod
    def _layer_count(info: ImageInfo) -> int:
        tiles = [t for _p, t in info.layers]
        if len(tiles) == 1 and tiles[0] == 0:
            return 1
        return tiles[-1] - tiles[0] + 1

    def _upload(
        self, info: ImageInfo, decode: Decode, shrink: int
    ) -> tuple[moderngl.TextureArray, int]:
        """The texture array and the channel count the shader expands it by (4 when
        the texels were expanded to RGBA on the CPU)."""
        w0, h0 = max(1, info.width // shrink), max(1, info.height // shrink)
        nlayers = self._layer_count(info)
        hw_srgb = decode.kind == SRGB and info.bits == 8
        if hw_srgb:
            comps, dtype = 4, "f1"
        elif decode.kind == RAW and info.bits in (8, 16):
            comps = {1: 1, 2: 2, 3: 4, 4: 4}[info.channels]
            dtype = "f1" if info.bits == 8 else "nu2"
        else:
            comps, dtype = 4, "f2"
        tex = self.ctx.texture_array((w0, h0, nlayers), comps, dtype=dtype)
        if hw_srgb:
            from OpenGL import GL

            # moderngl has no sRGB texture arrays: re-specify the storage (same bytes).
            GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, tex.glo)
            GL.glTexImage3D(
                GL.GL_TEXTURE_2D_ARRAY,
                0,
                GL.GL_SRGB8_ALPHA8,
                w0,
                h0,
                nlayers,
                0,
                GL.GL_RGBA,
                GL.GL_UNSIGNED_BYTE,
                None,
            )
        first_tile = info.layers[0][1]
        # Stored mips are used only when the file has the whole chain and no shrink.
        use_stored = info.mip_levels > 1 and shrink == 1 and nlayers == 1
        try:
            for path, tile in info.layers:
                layer = tile - first_tile if tile else 0
                px = _read_level(path, 0, info.channels, info.bits)
                if px.shape[1] != info.width or px.shape[0] != info.height:
                    raise ValueError(
                        f"UDIM tile {tile} is {px.shape[1]}x{px.shape[0]}, "
                        f"not {info.width}x{info.height}"
                    )
                s = shrink
                while s > 1:
                    px = _halve(px, decode.kind == SRGB)
                    s //= 2
                px = px[:h0, :w0]
                data = self._texels(px, decode, comps, dtype)
                tex.write(data[::-1].tobytes(), viewport=(0, 0, layer, w0, h0, 1))
                if use_stored:
                    for level in range(1, info.mip_levels):
                        lp = _read_level(path, level, info.channels, info.bits)
                        _write_level(tex, self._texels(lp, decode, comps, dtype)[::-1], level)
        except BaseException:
            tex.release()
            raise
        if use_stored:
            tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            from OpenGL import GL

            GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, tex.glo)
            GL.glTexParameteri(GL.GL_TEXTURE_2D_ARRAY, GL.GL_TEXTURE_MAX_LEVEL, info.mip_levels - 1)
        else:
            tex.build_mipmaps()
        return tex, (info.channels if comps == info.channels else 4)

    def _texels(self, px: np.ndarray, decode: Decode, comps: int, dtype: str) -> np.ndarray:
        """Pixels as the texture stores them (before the vertical flip)."""
        h, w, c = px.shape
        if dtype == "f1" and comps == 4 and c < 4:
            out = np.empty((h, w, 4), np.uint8)
            if c >= 3:
                out[..., :3] = px[..., :3]
                out[..., 3] = 255
            elif c == 2:
                out[..., :3] = px[..., :1]
                out[..., 3] = px[..., 1]
            else:
                out[..., :3] = px
                out[..., 3] = 255
            return out
        if dtype in ("f1", "nu2"):
            if comps == 4 and c == 3:
                one = 255 if dtype == "f1" else 65535
                return np.concatenate([px, np.full((h, w, 1), one, px.dtype)], axis=-1)
            return np.ascontiguousarray(px)
        # Half floats: decode / convert on the CPU.
        f = px.astype(np.float32)
        if px.dtype == np.uint8:
            f /= 255.0
        elif px.dtype == np.uint16:
            f /= 65535.0
        rgba = np.zeros((h, w, 4), np.float32)
        if c == 1:
            rgba[..., :3] = f
            rgba[..., 3] = 1.0
        elif c == 2:
            rgba[..., :3] = f[..., :1]
            rgba[..., 3] = f[..., 1]
        else:
            rgba[..., :3] = f[..., :3]
            rgba[..., 3] = f[..., 3] if c == 4 else 1.0
        if decode.kind == SRGB:
            rgba[..., :3] = srgb_to_linear(rgba[..., :3])
        elif decode.kind == CONVERT:
            rgba[..., :3] = self.colors.convert(rgba[..., :3], decode.space)
        rgba = np.nan_to_num(rgba, nan=0.0, posinf=limits.HALF_MAX, neginf=-limits.HALF_MAX)
        return np.clip(rgba, -limits.HALF_MAX, limits.HALF_MAX).astype(np.float16)

    # -- samplers -------------------------------------------------------------------

    def sampler(self, wrap_s: str, wrap_t: str) -> moderngl.Sampler:
        """Trilinear, anisotropic sampler with these wrap modes (repeat / mirror /
        clamp / black; useMetadata must be resolved first, see :func:`resolve_wrap`)."""
        key = (wrap_s, wrap_t)
        s = self._samplers.get(key)
        if s is None:
            black = "black" in key
            s = self.ctx.sampler(
                repeat_x=wrap_s == "repeat",
                repeat_y=wrap_t == "repeat",
                filter=(moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR),
                anisotropy=limits.TEXTURE_ANISOTROPY,
                border_color=(0.0, 0.0, 0.0, 0.0) if black else None,
            )
            if "mirror" in key or (black and "clamp" in key):
                from OpenGL import GL

                for axis, mode in ((GL.GL_TEXTURE_WRAP_S, wrap_s), (GL.GL_TEXTURE_WRAP_T, wrap_t)):
                    gl_mode = {
                        "repeat": GL.GL_REPEAT,
                        "mirror": GL.GL_MIRRORED_REPEAT,
                        "clamp": GL.GL_CLAMP_TO_EDGE,
                        "black": GL.GL_CLAMP_TO_BORDER,
                    }[mode]
                    GL.glSamplerParameteri(s._glo, axis, gl_mode)  # type: ignore[attr-defined]
            self._samplers[key] = s
        return s

    def dummy(self) -> moderngl.TextureArray:
        """A 1x1 black texture array for unused slots."""
        if self._dummy is None:
            self._dummy = self.ctx.texture_array((1, 1, 1), 4, b"\0\0\0\xff", dtype="f1")
        return self._dummy

    def release(self) -> None:
        for t in self.textures.values():
            t.texture.release()
        self.textures.clear()
        for s in self._samplers.values():
            s.release()
        self._samplers.clear()
        if self._dummy is not None:
            self._dummy.release()
            self._dummy = None


def resolve_wrap(mode: str, meta: str | None) -> str:
    """UsdUVTexture's ``useMetadata``: the file's own wrap mode, else black (Storm:
    no opinion anywhere is clamp-to-border black)."""
    if mode != "useMetadata":
        return mode
    return meta or "black"


def is_udim(path: str) -> bool:
    return bool(_UDIM_RE.search(path))
