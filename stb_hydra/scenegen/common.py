"""Shared helpers of stb_hydra's scene generators (``stb_hydra.scenegen.lights`` /
``.chess`` / ``.orbs``, and the checkout's ``tools/gen_prefab_library.py`` /
``tools/make_ies_profiles.py``).

Why text and not the Sdf API: with usd-core 26.11 in Python, creating 100,000 light
prims through ``Sdf.PrimSpec``/``Sdf.AttributeSpec`` (inside ``Sdf.ChangeBlock``) costs
~7 s and ``Sdf.CopySpec`` templates ~5 s, while formatting the same .usda text takes
~0.4 s and USD's own parser reads it back from a file in ~1.7 s. So generators emit
.usda text with :class:`UsdaWriter` (deterministic, commented, byte-identical for a
given seed) and go through Sdf only to open it (in-memory stages) or to convert it
to .usdc.

Conventions of every scene written here: Y up, metres (metersPerUnit = 1),
right-handed meshes with face-varying normals and ``subdivisionScheme = "none"``
(polygons are triangles or quads only), UsdPreviewSurface materials with constant
inputs, UsdLux units (``inputs:intensity`` is luminance in nits).
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# --------------------------------------------------------------------------------------
# Input assets. The IES profiles of ``gen:lights`` and the two prefabs of ``gen:orbs``
# ship with the package (``stb_hydra/data/ies``, ``stb_hydra/data/prefabs``: copies of
# the checkout's usd_scenes/ies and usd_scenes/prefabs/{enemy_orb,wall_torch}.usda,
# which tests/test_scenes.py holds identical), read through importlib.resources; an
# explicit argument wins. The OpenChessSet of the shared test data is not shipped:
# an explicit path, ``$STB_SHARED``, or ``../shared`` beside the source checkout.
# --------------------------------------------------------------------------------------

#: The source checkout this module lives in, if it is one (``stb_hydra/scenegen/`` two
#: levels below the repository root); an installed package has no ``shared`` beside it.
CHECKOUT = Path(__file__).resolve().parents[2]
#: Environment variable naming the shared test-data root (holds ``testdata/``).
SHARED_ENV = "STB_SHARED"
CHESS_SET_REL = Path("testdata") / "scenes" / "OpenChessSet" / "chess_set.usda"


def package_data_dir(name: str) -> Path:
    """The folder ``name`` of the package data (``stb_hydra/data/<name>``) as a file
    system path (USD asset paths name real files); FileNotFoundError when the package
    is not installed as files (a zip import)."""
    from importlib import resources

    d = resources.files("stb_hydra.data").joinpath(name)
    p = Path(str(d))
    if not p.is_dir():
        raise FileNotFoundError(
            f"package data folder stb_hydra/data/{name} not found at {p} (installed as a zip?)"
        )
    return p


def _input_dir(name: str, what: str, explicit: Path | str | None) -> Path:
    if explicit is not None:
        d = Path(explicit).resolve()
        if not d.is_dir():
            raise FileNotFoundError(f"{what} folder not found: {d}")
        return d
    return package_data_dir(name)


def ies_dir(explicit: Path | str | None = None) -> Path:
    """Folder of the IES profiles (``<name>.ies``): ``explicit``, else the package's
    ``stb_hydra/data/ies``; FileNotFoundError when ``explicit`` is not a folder."""
    return _input_dir("ies", "IES profiles", explicit)


def prefab_dir(explicit: Path | str | None = None) -> Path:
    """Folder of the prefab layers (``<name>.usda``): ``explicit``, else the package's
    ``stb_hydra/data/prefabs`` (the generators' prefabs: ``enemy_orb``, ``wall_torch``);
    FileNotFoundError when ``explicit`` is not a folder."""
    return _input_dir("prefabs", "prefab library", explicit)


def chess_set(explicit: Path | str | None = None) -> Path:
    """The OpenChessSet's ``chess_set.usda``: ``explicit``, else
    ``$STB_SHARED/testdata/scenes/OpenChessSet/chess_set.usda``, else the same under
    ``../shared`` next to the source checkout. FileNotFoundError (saying where it
    looked) when the file is missing."""
    if explicit is not None:
        p = Path(explicit).resolve()
        if not p.is_file():
            raise FileNotFoundError(f"chess set not found: {p}")
        return p
    env = os.environ.get(SHARED_ENV)
    if env:
        p = (Path(env) / CHESS_SET_REL).resolve()
        if not p.is_file():
            raise FileNotFoundError(f"chess set not found: {p} (from ${SHARED_ENV})")
        return p
    p = (CHECKOUT.parent / "shared" / CHESS_SET_REL).resolve()
    if p.is_file():
        return p
    raise FileNotFoundError(
        "chess set not found: pass chess / --chess (chess_set.usda of the OpenChessSet) "
        f"or set ${SHARED_ENV} to the shared test-data root (holding {CHESS_SET_REL})"
    )


# --------------------------------------------------------------------------------------
# Photometry (UsdLux, see ../shared/docs/STB_SPEC.md "Light units")
# --------------------------------------------------------------------------------------

#: Rec.709 / sRGB luminance weights: the luminance of an RGB light colour.
REC709_Y = (0.2126, 0.7152, 0.0722)  # = color.LUMINANCE_REC709 (sibling layer)


def luminance(rgb: Sequence[float]) -> float:
    return float(sum(w * c for w, c in zip(REC709_Y, rgb)))


def sphere_cd(nits: float, radius: float) -> float:
    """Far-field luminous intensity (cd) of a sphere light: I = L * pi * r^2."""
    return nits * math.pi * radius * radius


def sphere_nits_for_lumens(lumens: float, radius: float, solid_angle: float = 4 * math.pi):
    """Luminance (nits) of a sphere light emitting ``lumens`` into ``solid_angle``.

    Isotropic: Phi = 4*pi*I. With a normalised hemispherical IES profile the light
    emits Phi = 2*pi*I (pass ``solid_angle=2*pi``).
    """
    return lumens / solid_angle / (math.pi * radius * radius)


def disk_nits_for_lumens(lumens: float, radius: float) -> float:
    """One-sided Lambertian disk: I_axis = L*pi*r^2, Phi = pi*I_axis."""
    return lumens / (math.pi * math.pi * radius * radius)


def rect_nits_for_lumens(lumens: float, width: float, height: float) -> float:
    """One-sided Lambertian rectangle: I_axis = L*w*h, Phi = pi*I_axis."""
    return lumens / (math.pi * width * height)


def exposure_for_illuminance(lux: float) -> float:
    """Camera ``exposure`` (stops) for a key illuminance: an 18 % grey card under
    ``lux`` maps to 0.18 scene-linear (ACES mid grey), i.e. scale * E / pi = 1 with
    scale = 2^exposure (UsdGeomCamera defaults for fStop, time, iso, responsivity).
    Rounded to 1/2 stop so the value reads as a photographer's setting."""
    return round(2.0 * math.log2(math.pi / max(lux, 1e-6))) / 2.0


# --------------------------------------------------------------------------------------
# Number / value formatting (deterministic, compact)
# --------------------------------------------------------------------------------------


def num(x: float, nd: int = 4) -> str:
    """Fixed-point with trailing zeros stripped: 1.5000 -> '1.5', -0.0 -> '0'."""
    s = f"{float(x):.{nd}f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "", "-") else s


def vec(v: Iterable[float], nd: int = 4) -> str:
    return "(" + ", ".join(num(c, nd) for c in v) + ")"


def array(items: Sequence[str], per_line: int = 0, indent: str = "") -> str:
    """USDA array literal; ``per_line`` > 0 wraps long arrays for readability."""
    if not per_line or len(items) <= per_line:
        return "[" + ", ".join(items) + "]"
    rows = [", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]
    inner = (",\n" + indent + "    ").join(rows)
    return "[\n" + indent + "    " + inner + ",\n" + indent + "]"


def token_array(tokens: Iterable[str]) -> str:
    return "[" + ", ".join(f'"{t}"' for t in tokens) + "]"


def quote(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def doc_string(s: str) -> str:
    """A USDA string for ``doc`` metadata; triple quotes when multi-line."""
    if "\n" in s:
        return '"""' + s.replace('"""', "'''") + '"""'
    return quote(s)


def asset_path(target: Path | str, anchor_dir: Path | str | None) -> str:
    """``@...@`` asset path: relative to ``anchor_dir`` (the directory of the layer
    that will hold it) so the written file is relocatable, absolute when None."""
    target = Path(target).resolve()
    if anchor_dir is None:
        return "@" + target.as_posix() + "@"
    rel = os.path.relpath(target, Path(anchor_dir).resolve())
    rel = Path(rel).as_posix()
    if not rel.startswith("../"):
        rel = "./" + rel
    return "@" + rel + "@"


# --------------------------------------------------------------------------------------
# USDA text writer
# --------------------------------------------------------------------------------------


class UsdaWriter:
    """Minimal, deterministic USDA text emitter with nesting via context managers."""

    def __init__(self) -> None:
        self._lines: list[str] = []
        self._depth = 0

    # -- basics ----------------------------------------------------------------------
    @property
    def pad(self) -> str:
        return "    " * self._depth

    def line(self, s: str = "") -> None:
        self._lines.append(self.pad + s if s else "")

    def raw(self, s: str) -> None:
        """Append pre-formatted text (already indented)."""
        self._lines.append(s)

    def comment(self, text: str) -> None:
        for ln in text.strip("\n").splitlines():
            self.line(("# " + ln).rstrip())

    def text(self) -> str:
        return "\n".join(self._lines).rstrip("\n") + "\n"

    # -- layer header ----------------------------------------------------------------
    def header(
        self,
        *,
        doc: str,
        default_prim: str | None,
        start: float | None = None,
        end: float | None = None,
        fps: float | None = None,
        extra: Sequence[str] = (),
    ) -> None:
        self._lines.append("#usda 1.0")
        self._lines.append("(")
        if default_prim:
            self._lines.append(f'    defaultPrim = "{default_prim}"')
        self._lines.append("    doc = " + doc_string(doc))
        if end is not None:
            self._lines.append(f"    endTimeCode = {num(end)}")
        if fps is not None:
            self._lines.append(f"    framesPerSecond = {num(fps)}")
        self._lines.append("    metersPerUnit = 1")
        if start is not None:
            self._lines.append(f"    startTimeCode = {num(start)}")
        if fps is not None:
            self._lines.append(f"    timeCodesPerSecond = {num(fps)}")
        self._lines.append('    upAxis = "Y"')
        for e in extra:
            self._lines.append("    " + e)
        self._lines.append(")")
        self._lines.append("")

    # -- prims -------------------------------------------------------------------------
    @contextlib.contextmanager
    def prim(
        self,
        type_name: str | None,
        name: str,
        meta: Sequence[str] = (),
        specifier: str = "def",
        doc: str | None = None,
    ) -> Iterator[None]:
        head = specifier + (f" {type_name}" if type_name else "") + f' "{name}"'
        metas = list(meta)
        if doc:
            metas.insert(0, "doc = " + doc_string(doc))
        if metas:
            self.line(head + " (")
            self._depth += 1
            for m in metas:
                first, *rest = m.splitlines()
                self.line(first)
                for ln in rest:
                    if m.startswith("doc = "):
                        self._lines.append(ln)  # inside a multi-line string: verbatim
                    else:
                        self.line(ln)  # e.g. a variants = { ... } dictionary
            self._depth -= 1
            self.line(")")
        else:
            self.line(head)
        self.line("{")
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            # no blank line before a closing brace
            if self._lines and self._lines[-1] == "":
                self._lines.pop()
            self.line("}")
            self.line("")

    @contextlib.contextmanager
    def variant_set(self, name: str) -> Iterator[None]:
        self.line(f'variantSet "{name}" = {{')
        self._depth += 1
        try:
            yield
        finally:
            self._depth -= 1
            self.line("}")

    @contextlib.contextmanager
    def variant(self, name: str) -> Iterator[None]:
        self.line(f'"{name}" {{')
        self._depth += 1
        try:
            yield
        finally:
            if self._lines and self._lines[-1] == "":
                self._lines.pop()
            self._depth -= 1
            self.line("}")

    # -- properties ---------------------------------------------------------------------
    def attr(self, decl: str, value: str, meta: Sequence[str] = ()) -> None:
        if meta:
            self.line(f"{decl} = {value} (")
            for m in meta:
                self.line("    " + m)
            self.line(")")
        else:
            self.line(f"{decl} = {value}")

    def time_samples(self, decl: str, samples: Sequence[tuple[float, str]]) -> None:
        self.line(f"{decl}.timeSamples = {{")
        for t, v in samples:
            self.line(f"    {num(t)}: {v},")
        self.line("}")

    def rel(self, name: str, targets: str | Sequence[str]) -> None:
        if isinstance(targets, str):
            self.line(f"rel {name} = <{targets}>")
        else:
            self.line(f"rel {name} = [" + ", ".join(f"<{t}>" for t in targets) + "]")

    def xform(
        self,
        translate: Sequence[float] | None = None,
        rotate_xyz: Sequence[float] | None = None,
        scale: Sequence[float] | None = None,
        nd: int = 4,
    ) -> None:
        """Authors translate / rotateXYZ (degrees) / scale ops, in that order."""
        order = []
        if translate is not None:
            self.attr("double3 xformOp:translate", vec(translate, nd))
            order.append("xformOp:translate")
        if rotate_xyz is not None:
            self.attr("float3 xformOp:rotateXYZ", vec(rotate_xyz, 3))
            order.append("xformOp:rotateXYZ")
        if scale is not None:
            self.attr("float3 xformOp:scale", vec(scale, 4))
            order.append("xformOp:scale")
        if order:
            self.attr("uniform token[] xformOpOrder", token_array(order))

    # -- shading ---------------------------------------------------------------------
    def preview_material(
        self,
        name: str,
        path: str,
        diffuse: Sequence[float] | None,
        roughness: float = 0.7,
        metallic: float = 0.0,
        emissive: Sequence[float] | None = None,
        opacity: float | None = None,
        doc: str | None = None,
    ) -> None:
        """A Material with one UsdPreviewSurface (constant inputs only).

        ``path`` is the material's own prim path (for the output connection)."""
        with self.prim("Material", name, doc=doc):
            self.attr("token outputs:surface.connect", f"<{path}/Surface.outputs:surface>")
            with self.prim("Shader", "Surface"):
                self.attr("uniform token info:id", '"UsdPreviewSurface"')
                if diffuse is not None:  # None: authored elsewhere (e.g. in a variant)
                    self.attr("color3f inputs:diffuseColor", vec(diffuse, 4))
                if emissive is not None:
                    self.attr("color3f inputs:emissiveColor", vec(emissive, 4))
                self.attr("float inputs:metallic", num(metallic))
                if opacity is not None:
                    self.attr("float inputs:opacity", num(opacity))
                self.attr("float inputs:roughness", num(roughness))
                self.line("token outputs:surface")

    def mesh(
        self,
        name: str,
        mesh: MeshData,
        material: str | None = None,
        display_color: Sequence[float] | None = None,
        doc: str | None = None,
        api_schemas: Sequence[str] = (),
        extra_attrs: Sequence[tuple[str, str]] = (),
        wrap: int = 4,
        nd: int = 4,
    ) -> None:
        schemas = list(api_schemas)
        if material:
            schemas.insert(0, "MaterialBindingAPI")
        meta = [f"prepend apiSchemas = {token_array(schemas)}"] if schemas else []
        with self.prim("Mesh", name, meta=meta, doc=doc):
            pad = self.pad
            lo, hi = mesh.extent()
            points, indices = mesh.shared_points(nd)
            self.attr("float3[] extent", f"[{vec(lo, nd)}, {vec(hi, nd)}]")
            self.attr(
                "int[] faceVertexCounts",
                array([str(c) for c in mesh.counts], wrap * 8, pad),
            )
            self.attr(
                "int[] faceVertexIndices",
                array([str(i) for i in indices], wrap * 8, pad),
            )
            if material:
                self.rel("material:binding", material)
            self.attr(
                "normal3f[] normals",
                array([vec(n, 4) for n in mesh.normals], wrap, pad),
                meta=['interpolation = "faceVarying"'],
            )
            self.attr("point3f[] points", array(points, wrap, pad))
            if display_color is not None:
                self.attr(
                    "color3f[] primvars:displayColor",
                    f"[{vec(display_color, 4)}]",
                    meta=['interpolation = "constant"'],
                )
            for decl, value in extra_attrs:
                self.attr(decl, value)
            self.attr("uniform token subdivisionScheme", '"none"')

    def camera(
        self,
        name: str,
        eye: Sequence[float],
        target: Sequence[float],
        *,
        focal_length: float = 24.0,
        h_aperture: float = 36.0,
        v_aperture: float = 20.25,
        clipping: tuple[float, float] = (0.1, 500.0),
        exposure: float = 0.0,
        doc: str | None = None,
        comment: str | None = None,
    ) -> None:
        with self.prim("Camera", name, doc=doc):
            if comment:
                self.comment(comment)
            self.attr("float2 clippingRange", vec(clipping, 4))
            self.attr("float exposure", num(exposure, 3))
            self.attr("float focalLength", num(focal_length, 3))
            self.attr("float horizontalAperture", num(h_aperture, 3))
            self.attr("token projection", '"perspective"')
            self.attr("float verticalAperture", num(v_aperture, 3))
            m = look_at(eye, target)
            rows = ", ".join(vec(r, 6) for r in m)
            self.attr("matrix4d xformOp:transform", f"( {rows} )")
            self.attr("uniform token[] xformOpOrder", '["xformOp:transform"]')


def look_at(eye: Sequence[float], target: Sequence[float], up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """USD row-vector camera-to-world matrix: camera looks down its -Z, +Y up."""
    eye = np.asarray(eye, float)
    fwd = np.asarray(target, float) - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, np.asarray(up, float))
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    m = np.eye(4)
    m[0, :3] = right
    m[1, :3] = true_up
    m[2, :3] = -fwd
    m[3, :3] = eye
    return m


# --------------------------------------------------------------------------------------
# Meshes (flat-shaded convex solids, smooth cylinders/spheres), all face-varying normals
# --------------------------------------------------------------------------------------


@dataclass
class MeshData:
    points: list[tuple[float, float, float]] = field(default_factory=list)
    counts: list[int] = field(default_factory=list)
    indices: list[int] = field(default_factory=list)
    normals: list[tuple[float, float, float]] = field(default_factory=list)

    def extent(self) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(self.points, float)
        return p.min(axis=0), p.max(axis=0)

    def shared_points(self, nd: int = 4) -> tuple[list[str], list[int]]:
        """Formatted unique points and face-vertex indices into them (positions equal
        at ``nd`` decimals are merged; normals stay face-varying, so flat faces keep
        their hard edges)."""
        lookup: dict[str, int] = {}
        remap = []
        for p in self.points:
            key = vec(p, nd)
            remap.append(lookup.setdefault(key, len(lookup)))
        return list(lookup), [remap[i] for i in self.indices]

    @property
    def triangles(self) -> int:
        return sum(c - 2 for c in self.counts)

    def add_face(self, pts: Sequence[Sequence[float]], normals=None) -> None:
        """One polygon with its own vertices (flat normal if ``normals`` is None)."""
        base = len(self.points)
        self.points.extend(tuple(float(c) for c in p) for p in pts)
        self.counts.append(len(pts))
        self.indices.extend(range(base, base + len(pts)))
        if normals is None:
            n = newell_normal(pts)
            self.normals.extend([n] * len(pts))
        else:
            self.normals.extend(tuple(float(c) for c in n) for n in normals)

    def extend(self, other: MeshData) -> MeshData:
        base = len(self.points)
        self.points.extend(other.points)
        self.counts.extend(other.counts)
        self.indices.extend(i + base for i in other.indices)
        self.normals.extend(other.normals)
        return self

    def transformed(
        self, translate=(0.0, 0.0, 0.0), yaw_deg: float = 0.0, scale=(1.0, 1.0, 1.0)
    ) -> MeshData:
        """Scale, then rotate about +Y by ``yaw_deg``, then translate."""
        a = math.radians(yaw_deg)
        c, s = math.cos(a), math.sin(a)
        rot = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])  # row-vector: p @ rot
        sc = np.asarray(scale, float)
        p = (np.asarray(self.points, float) * sc) @ rot + np.asarray(translate, float)
        n = (np.asarray(self.normals, float) / sc) @ rot
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return MeshData(
            [tuple(map(float, q)) for q in p],
            list(self.counts),
            list(self.indices),
            [tuple(map(float, q)) for q in n],
        )


def newell_normal(pts: Sequence[Sequence[float]]) -> tuple[float, float, float]:
    p = np.asarray(pts, float)
    q = np.roll(p, -1, axis=0)
    n = np.array(
        [
            np.sum((p[:, 1] - q[:, 1]) * (p[:, 2] + q[:, 2])),
            np.sum((p[:, 2] - q[:, 2]) * (p[:, 0] + q[:, 0])),
            np.sum((p[:, 0] - q[:, 0]) * (p[:, 1] + q[:, 1])),
        ]
    )
    n /= np.linalg.norm(n)
    return (float(n[0]), float(n[1]), float(n[2]))


def convex_solid(faces: Sequence[Sequence[Sequence[float]]]) -> MeshData:
    """Flat-shaded convex polyhedron; each face is re-wound to face outwards."""
    allp = np.concatenate([np.asarray(f, float) for f in faces])
    centre = allp.mean(axis=0)
    m = MeshData()
    for f in faces:
        f = [tuple(map(float, p)) for p in f]
        n = np.asarray(newell_normal(f))
        if np.dot(n, np.asarray(f, float).mean(axis=0) - centre) < 0:
            f = f[::-1]
        m.add_face(f)
    return m


def hexahedron(c: Sequence[Sequence[float]]) -> MeshData:
    """Convex 8-corner solid; corners ordered bottom 0-3, top 4-7 (same rotation)."""
    faces = [
        [c[0], c[1], c[2], c[3]],
        [c[4], c[5], c[6], c[7]],
        [c[0], c[1], c[5], c[4]],
        [c[1], c[2], c[6], c[5]],
        [c[2], c[3], c[7], c[6]],
        [c[3], c[0], c[4], c[7]],
    ]
    return convex_solid(faces)


def box(lo: Sequence[float], hi: Sequence[float], bottom: bool = True) -> MeshData:
    """Axis-aligned box from ``lo`` to ``hi``. ``bottom=False`` drops the face that
    lies on the ground (never seen, saves 2 triangles and a shadow-acne source)."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    faces = [
        [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],
        [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],
    ]
    if bottom:
        faces.insert(2, [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)])
    allc = [(x0, y0, z0), (x1, y1, z1)]
    centre = np.mean(np.asarray(allc, float), axis=0)
    m = MeshData()
    for f in faces:
        n = np.asarray(newell_normal(f))
        if np.dot(n, np.asarray(f, float).mean(axis=0) - centre) < 0:
            f = f[::-1]
        m.add_face(f)
    return m


def box_c(center: Sequence[float], size: Sequence[float], bottom: bool = True) -> MeshData:
    c = np.asarray(center, float)
    h = np.asarray(size, float) / 2
    return box(c - h, c + h, bottom)


def plane(size_x: float, size_z: float, y: float = 0.0, center=(0.0, 0.0)) -> MeshData:
    """Upward-facing quad (normal +Y)."""
    cx, cz = center
    hx, hz = size_x / 2, size_z / 2
    m = MeshData()
    m.add_face(
        [(cx - hx, y, cz - hz), (cx - hx, y, cz + hz), (cx + hx, y, cz + hz), (cx + hx, y, cz - hz)]
    )
    return m


def cylinder(
    radius: float,
    y0: float,
    y1: float,
    sides: int = 16,
    center=(0.0, 0.0),
    top: bool = True,
    bottom: bool = True,
    inside: bool = False,
) -> MeshData:
    """Y-axis cylinder, smooth sides, flat caps as triangle fans. ``inside=True``
    turns the side inwards (a can seen from inside, e.g. a downlight housing)."""
    cx, cz = center
    m = MeshData()
    ang = [2 * math.pi * i / sides for i in range(sides + 1)]
    ring = [(cx + radius * math.cos(a), cz - radius * math.sin(a)) for a in ang]
    nrm = [(math.cos(a), 0.0, -math.sin(a)) for a in ang]
    for i in range(sides):
        (xa, za), (xb, zb) = ring[i], ring[i + 1]
        na, nb = nrm[i], nrm[i + 1]
        quad = [(xa, y0, za), (xb, y0, zb), (xb, y1, zb), (xa, y1, za)]
        ns = [na, nb, nb, na]
        # CCW seen from outside: a -> b goes counter-clockwise about +Y.
        if inside:
            quad = quad[::-1]
            ns = [tuple(-c for c in n) for n in ns[::-1]]
        m.add_face(quad, ns)
    for y, up, on in ((y1, True, top), (y0, False, bottom)):
        if not on:
            continue
        for i in range(sides):
            (xa, za), (xb, zb) = ring[i], ring[i + 1]
            tri = [(cx, y, cz), (xa, y, za), (xb, y, zb)]
            if not up:
                tri = tri[::-1]
            m.add_face(tri, [(0.0, 1.0 if up else -1.0, 0.0)] * 3)
    return m


def sphere(radius: float, rings: int = 8, segments: int = 12, center=(0.0, 0.0, 0.0)) -> MeshData:
    """UV sphere with smooth normals; quads, triangles at the poles."""
    cx, cy, cz = center
    m = MeshData()

    def vtx(i: int, j: int) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        th = math.pi * i / rings
        ph = 2 * math.pi * j / segments
        n = (math.sin(th) * math.cos(ph), math.cos(th), -math.sin(th) * math.sin(ph))
        return (cx + radius * n[0], cy + radius * n[1], cz + radius * n[2]), n

    for i in range(rings):
        for j in range(segments):
            a, na = vtx(i, j)
            b, nb = vtx(i + 1, j)
            c, nc = vtx(i + 1, j + 1)
            d, nd_ = vtx(i, j + 1)
            if i == 0:
                m.add_face([a, b, c], [na, nb, nc])
            elif i == rings - 1:
                m.add_face([a, b, d], [na, nb, nd_])
            else:
                m.add_face([a, b, c, d], [na, nb, nc, nd_])
    return m


def arch(
    width: float,
    pier_height: float,
    depth: float,
    thickness: float,
    segments: int = 10,
    top_flat: bool = True,
) -> MeshData:
    """A free-standing round arch in the XY plane, centred on x = 0, z in
    [-depth/2, depth/2]: two piers, a band of ``segments`` voussoirs and (optionally)
    square spandrel blocks up to a flat top. Opening = ``width``, springs at
    ``pier_height``, ring ``thickness`` thick."""
    r_in = width / 2
    r_out = r_in + thickness
    hz = depth / 2
    m = MeshData()
    m.extend(box((-r_out, 0, -hz), (-r_in, pier_height, hz), bottom=False))
    m.extend(box((r_in, 0, -hz), (r_out, pier_height, hz), bottom=False))
    for k in range(segments):
        a0 = math.pi * k / segments
        a1 = math.pi * (k + 1) / segments
        pts = []
        for z in (-hz, hz):
            pts += [
                (r_in * math.cos(a0), pier_height + r_in * math.sin(a0), z),
                (r_out * math.cos(a0), pier_height + r_out * math.sin(a0), z),
                (r_out * math.cos(a1), pier_height + r_out * math.sin(a1), z),
                (r_in * math.cos(a1), pier_height + r_in * math.sin(a1), z),
            ]
        m.extend(hexahedron(pts))
    if top_flat:
        # A lintel over the crown, so the silhouette reads as a gate.
        y_top = pier_height + r_out
        m.extend(box((-r_out, y_top, -hz), (r_out, y_top + thickness * 0.6, hz)))
    return m


def merge(meshes: Iterable[MeshData]) -> MeshData:
    out = MeshData()
    for m in meshes:
        out.extend(m)
    return out


# --------------------------------------------------------------------------------------
# Turning text into layers / stages / files
# --------------------------------------------------------------------------------------


def write_text_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
        os.chmod(tmp, 0o644)  # mkstemp makes 0600 files; these are ordinary repo files
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def layer_from_text(text: str):
    """Anonymous Sdf layer holding ``text``. Parsing from a file is ~3x faster than
    ``Sdf.Layer.ImportFromString`` in usd-core 26.11, so go through a temp file."""
    from pxr import Sdf

    fd, tmp = tempfile.mkstemp(suffix=".usda")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
        layer = Sdf.Layer.OpenAsAnonymous(tmp)
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
    if layer is None:
        raise RuntimeError("USD could not parse the generated .usda text")
    return layer


def stage_from_text(text: str):
    """In-memory ``Usd.Stage`` (root layer anonymous). Asset paths in ``text`` must be
    absolute: an anonymous layer has no directory to anchor relative ones."""
    from pxr import Usd

    return Usd.Stage.Open(layer_from_text(text))


def save(text: str, out: Path) -> None:
    """Write ``text`` to ``out``: .usda verbatim, .usdc/.usd through Sdf (crate)."""
    out = Path(out)
    if out.suffix == ".usda":
        write_text_atomic(out, text)
        return
    if out.suffix not in (".usdc", ".usd"):
        raise ValueError(f"output must end in .usda, .usdc or .usd: {out}")
    layer = layer_from_text(text)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp" + out.suffix)
    if not layer.Export(str(tmp), args={"format": "usdc"}):
        raise RuntimeError(f"could not write {out}")
    os.replace(tmp, out)


def hsv_to_rgb(h: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectorised HSV -> RGB, h in [0, 1)."""
    i = np.floor(h * 6).astype(int) % 6
    f = h * 6 - np.floor(h * 6)
    p = v * (1 - s)
    q = v * (1 - f * s)
    t = v * (1 - (1 - f) * s)
    table = np.stack(
        [
            np.stack([v, t, p], -1),
            np.stack([q, v, p], -1),
            np.stack([p, v, t], -1),
            np.stack([p, q, v], -1),
            np.stack([t, p, v], -1),
            np.stack([v, p, q], -1),
        ],
        0,
    )
    return table[i, np.arange(len(h))]
