"""Image files through OpenImageIO: atomic writes, metadata, frame and AOV paths.

* ``.exr``: scene-linear (rendering colour space, linear Rec.709) half float by default,
  or 32-bit float (depth AOV); metadata as typed EXR attributes.
* ``.png`` / ``.jpg`` / ``.tif``: display-referred through a :class:`ColorPipeline`
  (OCIO display/view), 8-bit for png/jpg and 16-bit for tif by default, alpha
  unassociated (``oiio:UnassociatedAlpha``); JPEG drops alpha. These formats keep only
  some attributes, so the caller's metadata also goes, as JSON, into ``ImageDescription``
  and :func:`read_image` restores it with its types.

Writes are atomic: a temp file ``.<stem>.tmp-XXXXXXXX<ext>`` in the target directory is
written, closed and ``os.replace``-d onto the target; on any failure it is removed and an
existing target is left untouched. Failures raise :class:`ImageWriteError`.
"""

from __future__ import annotations

import functools
import json
import math
import os
import re
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import OpenImageIO as oiio

from .files import new_file_mode

if TYPE_CHECKING:
    from stb_hydra.color.ocio import ColorPipeline

PathLike = str | os.PathLike[str]

#: Extension -> default bits per channel of display-referred formats.
DISPLAY_FORMATS: dict[str, int] = {".png": 8, ".jpg": 8, ".jpeg": 8, ".tif": 16, ".tiff": 16}
#: Scene-linear formats.
SCENE_LINEAR_FORMATS = (".exr",)
SUPPORTED_EXTENSIONS = tuple(sorted((*SCENE_LINEAR_FORMATS, *DISPLAY_FORMATS)))

#: ``oiio:ColorSpace`` of scene-linear EXRs written without a pipeline (OIIO's interop
#: name for linear Rec.709; OIIO canonicalises config names such as ``lin_rec709_srgb``
#: to it on read).
DEFAULT_SCENE_LINEAR_SPACE = "lin_rec709_scene"

#: AOV name -> (EXR pixel type, channel names, ``oiio:ColorSpace``). Colour is not an
#: AOV file: it is the main image.
AOV_LAYOUTS: dict[str, tuple[str, tuple[str, ...], str | None]] = {
    "depth": ("float", ("Z",), "data"),
    "normal": ("half", ("R", "G", "B"), "data"),
    "albedo": ("half", ("R", "G", "B"), DEFAULT_SCENE_LINEAR_SPACE),
}
COLOR_AOVS = ("color", "beauty")

HALF_MAX = 65504.0

#: EXR attribute listing the keys whose values were JSON-encoded (nested, bool, None,
#: ints beyond 32 bits); :func:`read_image` decodes exactly those.
JSON_KEYS_ATTR = "stb:jsonKeys"
#: Marker key of the JSON metadata document stored in ``ImageDescription``.
_BLOB_MARKER = "stb_hydra:metadata"

_PLACEHOLDER = re.compile(r"#+(?:\.#+)?")
_AOV_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


class ImageWriteError(OSError):
    """An image could not be written; ``str()`` is one line naming the path and reason."""

    def __init__(self, path: PathLike, reason: str) -> None:
        self.path = os.fspath(path)
        self.reason = " ".join(str(reason).split())
        super().__init__(f"cannot write '{self.path}': {self.reason}")


class ImageReadError(OSError):
    """An image could not be read; ``str()`` is one line naming the path and reason."""

    def __init__(self, path: PathLike, reason: str) -> None:
        self.path = os.fspath(path)
        self.reason = " ".join(str(reason).split())
        super().__init__(f"cannot read '{self.path}': {self.reason}")


# --- paths ------------------------------------------------------------------------------


def has_frame_placeholder(pattern: PathLike) -> bool:
    """True when ``pattern`` holds exactly one usdrecord-style frame placeholder."""
    return len(_PLACEHOLDER.findall(os.fspath(pattern))) == 1


def frame_path(pattern: PathLike, frame: float) -> str:
    """Replace the frame placeholder of ``pattern`` by ``frame`` (usdrecord rules).

    The placeholder is one group of ``#`` optionally followed by ``.`` and more ``#``
    (``#``, ``####``, ``###.##``). Its full width (dot included) is the minimum field
    width, zero-padded on the left, and the hashes after the dot are the decimal places:
    ``img.####.exr`` @ 12 -> ``img.0012.exr``; @ -3 -> ``img.-003.exr`` (the sign takes
    a digit, as in usdrecord); ``img.####.##.exr`` @ 1.5 -> ``img.0001.50.exr``.

    Raises ``ValueError`` when there is not exactly one placeholder, the frame is not
    finite, or it has more decimals than the placeholder keeps (two frames would share a
    file name).
    """
    text = os.fspath(pattern)
    found = list(_PLACEHOLDER.finditer(text))
    if len(found) != 1:
        what = "no" if not found else f"{len(found)}"
        raise ValueError(
            f"'{text}' has {what} frame placeholders; exactly one of the form '####' or "
            "'####.##' is needed"
        )
    match = found[0]
    placeholder = match.group(0)
    width = len(placeholder)
    precision = len(placeholder.partition(".")[2])
    getter = getattr(frame, "GetValue", None)  # Usd.TimeCode
    value = float(getter() if getter is not None else frame)
    if not math.isfinite(value):
        raise ValueError(f"frame must be finite (got {value})")
    rounded = round(value, precision)
    if abs(value - rounded) > 1e-6:
        raise ValueError(
            f"frame {value!r} needs more than the {precision} decimal place(s) of "
            f"placeholder '{placeholder}' in '{text}' (add '#' after a '.', e.g. '####.##')"
        )
    if rounded == 0.0:
        rounded = 0.0  # never "-000"
    return f"{text[: match.start()]}{rounded:0{width}.{precision}f}{text[match.end() :]}"


def aov_path(path: PathLike, aov_name: str) -> Path:
    """Path of AOV ``aov_name`` next to the colour image ``path`` (always ``.exr``).

    ``out/img.png`` + ``depth`` -> ``out/img.depth.exr``; frame placeholders are kept
    (``img.####.png`` -> ``img.####.depth.exr``). ``color``/``beauty`` give ``path``.
    """
    p = Path(os.fspath(path))
    if aov_name in COLOR_AOVS:
        return p
    if not _AOV_NAME.match(aov_name):
        raise ValueError(f"AOV name must match [A-Za-z][A-Za-z0-9_]* (got '{aov_name}')")
    return p.with_name(f"{p.stem}.{aov_name}.exr")


@functools.cache
def _oiio_can_write(ext: str) -> bool:
    return oiio.ImageOutput.create(f"probe{ext}") is not None


def check_output_path(path: PathLike) -> None:
    """Raise :class:`ImageWriteError` now if ``path`` cannot be written later.

    Checks the extension (supported by this module and by this OIIO build), that the
    directory exists and is writable, and that the target is not a directory. A frame
    pattern is checked through its frame-0 path. Call it before rendering.
    """
    p = Path(os.fspath(path))
    ext = p.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise ImageWriteError(
            p,
            f"unsupported extension '{ext or '(none)'}' "
            f"(supported: {', '.join(SUPPORTED_EXTENSIONS)})",
        )
    if not _oiio_can_write(ext):
        raise ImageWriteError(p, f"this OpenImageIO build has no writer for '{ext}'")
    if has_frame_placeholder(p):
        p = Path(frame_path(p, 0))
    parent = p.parent
    if not parent.exists():
        raise ImageWriteError(p, f"directory does not exist: '{parent}'")
    if not parent.is_dir():
        raise ImageWriteError(p, f"not a directory: '{parent}'")
    if p.is_dir():
        raise ImageWriteError(p, "the target is a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ImageWriteError(p, f"directory is not writable: '{parent}'")


# --- metadata ---------------------------------------------------------------------------


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"metadata value of type {type(value).__name__} is not JSON-encodable")


def _exr_attribute(value: Any) -> tuple[Any, bool]:
    """(attribute value, json-encoded?) for one metadata value in an EXR header."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if isinstance(value, str) or (isinstance(value, float) and not isinstance(value, bool)):
        return value, False
    if isinstance(value, int) and not isinstance(value, bool) and -(2**31) <= value < 2**31:
        return value, False
    return json.dumps(value, default=_json_default), True


def _apply_metadata(spec: oiio.ImageSpec, metadata: Mapping[str, Any], exr: bool) -> None:
    if exr:
        json_keys = []
        for key, value in metadata.items():
            attr, encoded = _exr_attribute(value)
            spec.attribute(key, attr)
            if encoded:
                json_keys.append(key)
        if json_keys:
            spec.attribute(JSON_KEYS_ATTR, json.dumps(json_keys))
        return
    for key, value in metadata.items():
        if isinstance(value, str):
            spec.attribute(key, value)
    if "ImageDescription" not in metadata:
        blob = {_BLOB_MARKER: 1, "metadata": dict(metadata)}
        spec.attribute("ImageDescription", json.dumps(blob, default=_json_default))


def _read_metadata(spec: oiio.ImageSpec) -> dict[str, Any]:
    meta: dict[str, Any] = {a.name: a.value for a in spec.extra_attribs}
    keys = meta.pop(JSON_KEYS_ATTR, None)
    if isinstance(keys, str):
        for key in json.loads(keys):
            if isinstance(meta.get(key), str):
                meta[key] = json.loads(meta[key])
    description = meta.get("ImageDescription")
    if isinstance(description, str) and _BLOB_MARKER in description:
        try:
            blob = json.loads(description)
        except ValueError:
            blob = None
        if isinstance(blob, dict) and blob.get(_BLOB_MARKER) == 1:
            # OIIO's JPEG reader also splits the comment at its first ':' into a bogus
            # attribute ('{"stb_hydra' -> 'metadata": 1, ...'); drop that echo.
            for key, value in list(meta.items()):
                if isinstance(value, str) and f"{key}:{value}" == description:
                    del meta[key]
            del meta["ImageDescription"]
            meta.update(blob.get("metadata", {}))
    return meta


# --- pixels -----------------------------------------------------------------------------


def _as_hwc(pixels: np.ndarray) -> np.ndarray:
    a = np.asarray(pixels)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 1 or a.shape[2] < 1:
        raise ValueError(f"pixels must be (h, w) or (h, w, c), got shape {a.shape}")
    return a


def _to_unit_float(a: np.ndarray) -> np.ndarray:
    """Display-referred pixels (float in [0, 1] or uint8/uint16 codes) -> float32."""
    if np.issubdtype(a.dtype, np.integer):
        if a.dtype not in (np.uint8, np.uint16):
            raise ValueError(f"integer pixels must be uint8 or uint16, got {a.dtype}")
        return a.astype(np.float32) / np.float32(np.iinfo(a.dtype).max)
    return a.astype(np.float32)


def _default_channel_names(n: int) -> tuple[str, ...]:
    names = {1: ("Y",), 2: ("Y", "A"), 3: ("R", "G", "B"), 4: ("R", "G", "B", "A")}
    if n not in names:
        raise ValueError(f"{n} channels need explicit channel_names")
    return names[n]


@functools.lru_cache(maxsize=4)
def _default_pipeline(ocio_env: str) -> ColorPipeline:
    from stb_hydra.color.ocio import ColorPipeline

    del ocio_env  # cache key only: ColorPipeline() reads $OCIO itself
    return ColorPipeline()


def _check_written(tmp: Path, path: Path) -> None:
    """Flush ``tmp`` to the disk and read it back whole before it replaces ``path``.

    OpenEXR drops write errors: on a full file system (ENOSPC, or EFBIG past
    RLIMIT_FSIZE) ``write_image`` and ``close`` succeeded and a truncated frame was
    renamed into place with exit status 0 (issue 21, tests/test_faults.py)."""
    fd = os.open(tmp, os.O_RDONLY)
    try:
        os.fsync(fd)  # reports deferred write-back errors (ENOSPC on delayed allocation)
    finally:
        os.close(fd)
    inp = oiio.ImageInput.open(str(tmp))
    if inp is None:
        raise ImageWriteError(path, f"the written file does not read back: {oiio.geterror()}")
    try:
        px = inp.read_image()
        err = inp.geterror() if px is None or inp.has_error else ""
    finally:
        inp.close()
    if px is None or err:
        why = " ".join((err or "read failed").split())
        raise ImageWriteError(path, f"the written file is incomplete (disk full?): {why}")


def _atomic_write(path: Path, spec: oiio.ImageSpec, pixels: np.ndarray) -> None:
    directory = path.parent
    try:
        fd, tmp_name = tempfile.mkstemp(
            prefix=f".{path.stem}.tmp-", suffix=path.suffix, dir=directory
        )
        os.close(fd)
    except OSError as exc:
        raise ImageWriteError(path, exc.strerror or str(exc)) from exc
    tmp = Path(tmp_name)
    try:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None:
            raise ImageWriteError(path, oiio.geterror() or "no OIIO writer")
        if not out.open(str(tmp), spec):
            raise ImageWriteError(path, out.geterror() or "OIIO open failed")
        try:
            if not out.write_image(pixels):  # the one pixel write (tests inject failures)
                raise ImageWriteError(path, out.geterror() or "OIIO write failed")
        finally:
            closed = out.close()
        if not closed:
            raise ImageWriteError(path, out.geterror() or "OIIO close failed")
        _check_written(tmp, path)
        os.chmod(tmp, new_file_mode(path))  # mkstemp creates 0600
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, ImageWriteError) or not isinstance(exc, Exception):
            raise
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise ImageWriteError(path, f"{type(exc).__name__}: {reason}") from exc


def write_image(
    path: PathLike,
    pixels: np.ndarray,
    *,
    metadata: Mapping[str, Any] | None = None,
    color_pipeline: ColorPipeline | None = None,
    display_referred: bool = False,
    bits: int | None = None,
    pixel_type: str = "half",
    channel_names: tuple[str, ...] | None = None,
    colorspace: str | None = "auto",
) -> Path:
    """Write ``pixels`` (h, w[, c]) to ``path`` atomically; returns the path.

    ``.exr``: scene-linear values, ``pixel_type`` ``'half'`` (clamped to +-65504) or
    ``'float'``. ``color_pipeline`` only names the colour space (its input space).

    ``.png``/``.jpg``/``.tif``: scene-linear RGB(A) goes through ``color_pipeline``
    (default: ``ColorPipeline()``, i.e. $OCIO or the built-in studio config) on the CPU.
    With ``display_referred=True`` the pixels are already display-referred (float in
    [0, 1], or uint8/uint16 codes, e.g. from ``ColorCorrectionPass``) and are only
    quantised; a given ``color_pipeline`` then only names the colour space. ``bits``: 8 or
    16 (png/tif), default 8 for png/jpg, 16 for tif.

    ``metadata``: attribute name -> str/int/float (EXR: 32-bit int/float attributes),
    anything else JSON-encoded; read back by :func:`read_image`. ``colorspace``: value of
    ``oiio:ColorSpace``; ``'auto'`` derives it, ``None`` writes none.
    """
    p = Path(os.fspath(path))
    check_output_path(p)
    ext = p.suffix.lower()
    a = _as_hwc(pixels)
    if ext in SCENE_LINEAR_FORMATS:
        if display_referred:
            raise ValueError(f"'{p}': EXR holds scene-linear data, not display-referred")
        data, fmt, pipeline = _scene_linear_pixels(a, pixel_type), pixel_type, color_pipeline
        auto_space = pipeline.input_space if pipeline else DEFAULT_SCENE_LINEAR_SPACE
    else:
        data, fmt, pipeline = _display_pixels(p, a, color_pipeline, display_referred, bits)
        auto_space = pipeline.display_space if pipeline is not None else None
    h, w, c = data.shape
    names = channel_names or _default_channel_names(c)
    if len(names) != c:
        raise ValueError(f"{len(names)} channel names for {c} channels")
    attrs: dict[str, Any] = pipeline.metadata() if pipeline is not None else {}
    from stb_hydra import __version__

    attrs.setdefault("Software", f"stb_hydra {__version__}")
    attrs.update(metadata or {})
    spec = _image_spec(w, h, fmt, names, ext)
    space = auto_space if colorspace == "auto" else colorspace
    if space:
        spec.attribute("oiio:ColorSpace", space)
    _apply_metadata(spec, attrs, exr=ext in SCENE_LINEAR_FORMATS)
    _atomic_write(p, spec, data)
    return p


def _scene_linear_pixels(a: np.ndarray, pixel_type: str) -> np.ndarray:
    """float32 EXR pixels; ``'half'`` clamps to +-HALF_MAX (NaN stays NaN)."""
    if pixel_type not in ("half", "float"):
        raise ValueError(f"EXR pixel_type must be 'half' or 'float' (got '{pixel_type}')")
    data = np.ascontiguousarray(a, dtype=np.float32)
    if pixel_type == "half":
        data = np.clip(data, -HALF_MAX, HALF_MAX)  # NaN stays NaN
    return data


def _display_pixels(
    p: Path,
    a: np.ndarray,
    color_pipeline: ColorPipeline | None,
    display_referred: bool,
    bits: int | None,
) -> tuple[np.ndarray, str, ColorPipeline | None]:
    """(quantised display-referred pixels, OIIO format, pipeline naming the colour space)
    for png/jpg/tif: through ``color_pipeline`` (default: $OCIO or the built-in config)
    unless already ``display_referred``; JPEG drops alpha."""
    ext = p.suffix.lower()
    bits = DISPLAY_FORMATS[ext] if bits is None else bits
    if bits not in (8, 16) or (bits == 16 and ext in (".jpg", ".jpeg")):
        raise ValueError(f"'{p}': {bits}-bit output is not supported for {ext}")
    if display_referred:
        display = np.clip(np.nan_to_num(_to_unit_float(a), nan=0.0), 0.0, 1.0)
        pipeline = color_pipeline
    else:
        if a.shape[2] not in (3, 4):
            raise ValueError(f"scene-linear pixels must be RGB or RGBA, got {a.shape}")
        pipeline = color_pipeline or _default_pipeline(os.environ.get("OCIO", ""))
        display = pipeline.apply_cpu(a)
    if ext in (".jpg", ".jpeg") and display.shape[2] in (2, 4):
        display = display[:, :, :-1]  # JPEG has no alpha
    from stb_hydra.color.ocio import quantize

    data = np.ascontiguousarray(quantize(display, bits))
    return data, "uint8" if bits == 8 else "uint16", pipeline


def _image_spec(w: int, h: int, fmt: str, names: tuple[str, ...], ext: str) -> oiio.ImageSpec:
    """ImageSpec with channel names and the alpha channel (unassociated outside EXR)."""
    spec = oiio.ImageSpec(w, h, len(names), fmt)
    spec.channelnames = tuple(names)
    if "A" in names:
        spec.alpha_channel = names.index("A")
        if ext not in SCENE_LINEAR_FORMATS:  # EXR alpha is associated by definition
            spec.attribute("oiio:UnassociatedAlpha", 1)
    return spec


def write_aov(
    path: PathLike,
    aov_name: str,
    pixels: np.ndarray,
    *,
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Write AOV ``aov_name`` next to colour image ``path`` as EXR; returns its path.

    ``depth``: 32-bit float, one channel ``Z`` (view-space distance, scene units);
    ``normal``: half RGB (unit vectors, colour space ``data``); ``albedo``: half RGB,
    linear Rec.709. Other names: half, channels by count.
    """
    if aov_name in COLOR_AOVS:
        raise ValueError("the colour AOV is the main image: use write_image")
    target = aov_path(path, aov_name)
    pixel_type, names, space = AOV_LAYOUTS.get(aov_name, ("half", None, None))
    a = _as_hwc(pixels)
    if names is not None and a.shape[2] != len(names):
        raise ValueError(f"AOV '{aov_name}' needs {len(names)} channel(s), got {a.shape[2]}")
    meta = {"stb:aov": aov_name, **(metadata or {})}
    return write_image(
        target, a, metadata=meta, pixel_type=pixel_type, channel_names=names, colorspace=space
    )


def read_image(path: PathLike, *, pixel_type: str = "float") -> tuple[np.ndarray, dict]:
    """Read ``path`` -> ``(pixels (h, w, c), metadata)``.

    ``pixel_type`` ``'float'`` gives float32 (integer formats normalised to [0, 1]);
    ``'native'`` keeps the file's type (``float16`` for half EXR, uint8/uint16 codes).
    Alpha is read unassociated (no premultiplication). ``metadata`` holds the file's
    attributes with the values given to :func:`write_image` decoded.
    """
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise ImageReadError(p, "no such file")
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    inp = oiio.ImageInput.open(p, config)
    if inp is None:
        raise ImageReadError(p, oiio.geterror() or "OIIO cannot open it")
    try:
        spec = inp.spec()
        fmt = "unknown" if pixel_type == "native" else pixel_type
        pixels = inp.read_image(fmt)
        if pixels is None:
            raise ImageReadError(p, inp.geterror() or "OIIO read failed")
        meta = _read_metadata(spec)
    finally:
        inp.close()
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    return pixels, meta
