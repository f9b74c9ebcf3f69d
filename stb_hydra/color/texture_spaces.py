"""Texture colour spaces: which decode a texture needs to reach the rendering space.

A material's texture names its encoding as a UsdUVTexture ``sourceColorSpace``
token ("auto", "sRGB", "raw") or an OCIO colour-space name (MaterialX
``colorspace``: "srgb_texture", "lin_rec709", "acescg", ...). The renderer wants
scene-linear Rec.709 (the rendering space, :func:`.ocio.find_linear_rec709`).
:class:`TextureColorSpaces` turns a name plus what the file says of itself into one
of three decodes:

* ``SRGB``: the sRGB transfer function with Rec.709 primaries -- decoded by the GPU's
  sRGB texture formats on 8-bit data (exact, no extra memory), on the CPU otherwise;
* ``RAW``: the values as stored (data: roughness, normals, linear Rec.709 colour);
* ``CONVERT``: any other colour space, converted on the CPU through OCIO into the
  rendering space (stored as half floats).

``auto`` follows Storm (HioImage): an 8-bit file with 3 or 4 channels is sRGB,
anything else raw, unless the file's ``oiio:ColorSpace`` metadata says otherwise.
Whether an OCIO name is sRGB or linear Rec.709 is decided by OCIO itself (the
processor from that space to the rendering space is compared with the sRGB curve /
the identity on a ramp), so aliases in any config are recognised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import PyOpenColorIO as ocio

from .ocio import find_linear_rec709, resolve_config

SRGB = "sRGB"
RAW = "raw"
CONVERT = "convert"

#: Ramp on which an OCIO space is compared with the sRGB curve / the identity.
_RAMP = np.linspace(0.0, 1.0, 33, dtype=np.float32)
#: Largest difference on the ramp for two decodes to count as the same.
_SAME_TOL = 2e-3


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """The sRGB EOTF (IEC 61966-2-1), elementwise, float64 in -> float64 out."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((np.maximum(v, 0.0) + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`srgb_to_linear` (values clamped to >= 0)."""
    v = np.maximum(np.asarray(v, dtype=np.float64), 0.0)
    return np.where(v <= 0.0031308, v * 12.92, 1.055 * v ** (1.0 / 2.4) - 0.055)


@dataclass(frozen=True)
class Decode:
    """How one texture reaches the rendering space: ``kind`` (SRGB / RAW / CONVERT)
    and, for CONVERT, the OCIO source colour space."""

    kind: str
    space: str = ""


class TextureColorSpaces:
    """Colour-space decisions for textures against one OCIO config (``None``: $OCIO,
    else the built-in studio config). ``warnings`` collects one line per unknown name."""

    def __init__(self, config: ocio.Config | None = None) -> None:
        self.config = config if config is not None else resolve_config(None)[0]
        self.rendering_space = find_linear_rec709(self.config)
        self._named: dict[str, Decode | None] = {}
        self._cpu: dict[str, ocio.CPUProcessor] = {}

    def decode(self, token: str, bits: int, channels: int, file_space: str = "") -> Decode:
        """The decode for a texture whose material names ``token`` and whose file has
        ``bits`` per channel (32 = float), ``channels`` channels and ``oiio:ColorSpace``
        ``file_space`` (may be ""). Unknown OCIO names decode as RAW (see
        :meth:`known`)."""
        if token == "raw":
            return Decode(RAW)
        if token == "sRGB":
            return Decode(SRGB)
        if token in ("auto", ""):
            if file_space:
                d = self.named(file_space)
                if d is not None:
                    return d
            return Decode(SRGB) if bits == 8 and channels >= 3 else Decode(RAW)
        d = self.named(token)
        return d if d is not None else Decode(RAW)

    def known(self, name: str) -> bool:
        """Whether ``name`` is a UsdUVTexture token or a colour space of the config."""
        return name in ("auto", "sRGB", "raw", "") or self.named(name) is not None

    def named(self, name: str) -> Decode | None:
        """Decode of OCIO colour space ``name`` (None when the config has no such space)."""
        if name in self._named:
            return self._named[name]
        d: Decode | None
        cs = self.config.getColorSpace(name)
        if cs is None:
            d = None
        else:
            canon = cs.getName()
            try:
                # Each primary alone and grey: primaries and curve both count.
                ramp = np.zeros((4 * len(_RAMP), 3), dtype=np.float32)
                for i in range(3):
                    ramp[i * len(_RAMP) : (i + 1) * len(_RAMP), i] = _RAMP
                ramp[3 * len(_RAMP) :] = _RAMP[:, None]
                r = ramp.astype(np.float64)
                self._processor(canon).applyRGB(ramp)  # in place
                out = ramp.astype(np.float64)
            except ocio.Exception:
                d = None
            else:
                if np.max(np.abs(out - r)) <= _SAME_TOL:
                    d = Decode(RAW)
                elif np.max(np.abs(out - srgb_to_linear(r))) <= _SAME_TOL:
                    d = Decode(SRGB)
                else:
                    d = Decode(CONVERT, canon)
        self._named[name] = d
        return d

    def _processor(self, space: str) -> ocio.CPUProcessor:
        p = self._cpu.get(space)
        if p is None:
            proc = self.config.getProcessor(space, self.rendering_space)
            p = proc.getOptimizedCPUProcessor(ocio.OPTIMIZATION_DEFAULT)
            self._cpu[space] = p
        return p

    def convert(self, rgb: np.ndarray, space: str) -> np.ndarray:
        """(..., 3) float values in OCIO space ``space`` -> the rendering space
        (float32, a copy)."""
        a = np.ascontiguousarray(rgb, dtype=np.float32).copy()
        flat = a.reshape(-1, 3)
        self._processor(space).applyRGB(flat)
        return a
