"""Fuzz at scale (issue 21, item 6). Outside CI; ``tests/test_fuzz_smoke.py`` runs a few
inputs of each kind.

``ies``: the IES parser on mutated real files (``../shared/testdata/ies``, 29 files:
byte flips, truncation, token deletion/duplication, hostile numbers, inflated header
counts, swapped lines) and on random inputs (bytes; number soup after a valid header).
Pass: only ``IesError`` comes out, its message is one line starting with the file
name; a profile that parses samples (and bakes the GPU table) to finite, non-negative
candela with a finite, non-negative flux; no input takes more than ``--slow`` s.

``usd``: light scenes (the project's own, the luxtest, OpenUSD and Arnold UsdLux
scenes; flattened once) with 1-3 mutations each, applied to a fresh anonymous layer:
NaN / inf / huge / negative values and wrong-typed attributes on lights, cameras and
meshes (also time samples), NaN / zero / huge transforms, broken references and
payloads, reference cycles (inside a layer and across files), IES and texture files
that are missing, garbage, truncated or directories. Each is rendered at 32x18 with
every lighting method (one engine, ``set_lighting``). Pass: no exception but
``RenderError``; every pixel finite; every message (engine warnings, USD diagnostics
trapped as ``stb render`` does, a RenderError) one line; every mutation that makes the
input invalid (non-finite or wrong-typed values, broken or cyclic references, missing
or bad files) reported by a message naming the prim or the file. ``--structural``
adds a 1e6-prim stage and deep instancing (nested point instancers, nested
instanceable references), each rendered once with every method, timed.

    .venv/bin/python tools/fuzz.py ies --count 100000 --json out/fuzz_ies.json
    .venv/bin/python tools/fuzz.py usd --count 2000 --structural --json out/fuzz_usd.json

Exit status 0 when nothing failed, 1 otherwise (failures listed, with the seed and
case number to replay one: ``--seed S --only N``).
"""

from __future__ import annotations

import argparse
import contextlib
import faulthandler
import json
import math
import os
import random
import re
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
TESTDATA = Path(os.environ.get("STB_TESTDATA", REPO.parent.parent / "shared" / "testdata"))
if not TESTDATA.is_dir():
    TESTDATA = Path("/work/shared/testdata")
METHODS = ("reference", "sun", "stb", "tiled", "clustered", "lighttree")

# ---------------------------------------------------------------------------------------
# IES
# ---------------------------------------------------------------------------------------

HOSTILE_NUMBERS = [
    b"nan", b"inf", b"-inf", b"1e308", b"-1e308", b"1e400", b"0", b"-0", b"-1", b"99999999",
    b"4097", b"1000001", b"1e-320", b"360", b"-90", b"180.0001", b"x", b"", b"0x10", b"1,5",
    b"TILT=NONE", b"TILT=INCLUDE", b"[MORE]", b"\r", b"\x00", b"\xff\xfe",
]  # fmt: skip


def _ies_mutate(raw: bytes, rng: random.Random) -> bytes:
    """One random mutation of an IES file's bytes."""
    op = rng.choice(
        ["flip", "truncate", "del_token", "dup_token", "number", "counts", "lines", "insert"]
    )
    if not raw:
        return bytes(rng.randrange(256) for _ in range(rng.randrange(64)))
    if op == "flip":
        buf = bytearray(raw)
        for _ in range(rng.randint(1, 8)):
            buf[rng.randrange(len(buf))] = rng.randrange(256)
        return bytes(buf)
    if op == "truncate":
        return raw[: rng.randrange(len(raw) + 1)]
    if op == "insert":
        at = rng.randrange(len(raw) + 1)
        return raw[:at] + bytes(rng.randrange(256) for _ in range(rng.randint(1, 32))) + raw[at:]
    if op == "lines":
        lines = raw.split(b"\n")
        i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
        how = rng.choice(["swap", "delete", "dup"])
        if how == "swap":
            lines[i], lines[j] = lines[j], lines[i]
        elif how == "delete":
            del lines[i]
        else:
            lines.insert(j, lines[i])
        return b"\n".join(lines)
    spans = [m.span() for m in re.finditer(rb"[^\s,]+", raw)]
    if not spans:
        return raw + b" 1"
    if op == "counts":  # the luminaire line after TILT: lamps, lm, mult, nV, nH, type, ...
        tilt = raw.upper().find(b"TILT=")
        after = [s for s in spans if s[0] > tilt + 9] if tilt >= 0 else spans
        if after:
            a, b = after[min(len(after) - 1, rng.choice([0, 2, 3, 4, 5, 6, 7, 8, 9]))]
            v = rng.choice([b"0", b"-3", b"4097", b"1000001", b"2147483648", b"nan", b"1.5"])
            return raw[:a] + v + raw[b:]
    a, b = spans[rng.randrange(len(spans))]
    if op == "del_token":
        return raw[:a] + raw[b:]
    if op == "dup_token":
        return raw[:b] + b" " + raw[a:b] + raw[b:]
    return raw[:a] + rng.choice(HOSTILE_NUMBERS) + raw[b:]


def _ies_random(rng: random.Random) -> bytes:
    kind = rng.random()
    if kind < 0.3:
        return bytes(rng.randrange(256) for _ in range(rng.randrange(2000)))
    head = rng.choice([b"IESNA:LM-63-2002\n[TEST] x\nTILT=NONE\n", b"IESNA91\nTILT=NONE\n", b""])
    if kind < 0.6:
        alphabet = b"0123456789 .-+eE,\t\n"
        return head + bytes(rng.choice(alphabet) for _ in range(rng.randrange(600)))
    # a structurally valid file with random counts, angles and candela
    nv, nh, pt = rng.randint(0, 12), rng.randint(0, 8), rng.choice([1, 2, 3, 0, 4])
    nums = lambda n, lo, hi: b" ".join(b"%.6g" % rng.uniform(lo, hi) for _ in range(n))  # noqa: E731
    v = sorted(rng.uniform(-100, 200) for _ in range(nv))
    h = sorted(rng.uniform(-400, 400) for _ in range(nh))
    body = (
        b"%d -1 %.3g %d %d %d %d %.3g %.3g %.3g\n1 1 %.3g\n"
        % (1, rng.choice([1.0, 0.0, -1.0, 1e30]), nv, nh, pt, rng.choice([1, 2, 3]),
           rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-10, 10))
        + b" ".join(b"%.6g" % x for x in v) + b"\n" + b" ".join(b"%.6g" % x for x in h) + b"\n"
        + nums(nv * nh + rng.randint(-2, 2), -10, 1e6)
    )  # fmt: skip
    return head + body


def check_ies(
    data: bytes, name: str = "fuzz.ies", counts: Counter[str] | None = None
) -> str | None:
    """None when the parser behaved; else the failure, one line. ``counts``: adds
    ``rejected`` (IesError) or ``parsed``."""
    counts = Counter() if counts is None else counts
    from stb_hydra import limits
    from stb_hydra.scene.ies import IesError, parse_ies

    try:
        p = parse_ies(data, name=name)
    except IesError as e:
        msg = str(e)
        if not msg.startswith(f"{name}: ") or "\n" in msg:
            return f"IesError not one line naming the file: {msg!r}"
        if "internal parser error" in msg:
            return f"internal parser error: {msg!r}"
        counts["rejected"] += 1
        return None
    except Exception as e:  # noqa: BLE001 - what the fuzzer counts
        return f"crash {type(e).__name__}: {e}"
    counts["parsed"] += 1
    try:
        theta = np.linspace(0.0, np.pi, 7)[:, None]
        phi = np.linspace(-1.0, 7.0, 5)[None, :]
        table = p.bake_table(limits.IES_TABLE_THETA, limits.IES_TABLE_PHI)
        for what, values in (("sample", p.sample(theta, phi)), ("table", table)):
            if not (np.all(np.isfinite(values)) and np.all(values >= 0.0)):
                return f"non-finite or negative {what}"
        for what, x in (("power", p.power()), ("flux", p.flux()), ("max", p.max_candela())):
            if not (math.isfinite(x) and x >= 0.0):
                return f"{what} {x}"
        for w in p.warnings:
            if "\n" in w:
                return f"multi-line warning {w!r}"
    except Exception as e:  # noqa: BLE001
        return f"crash after parsing {type(e).__name__}: {e}"
    return None


def fuzz_ies(
    count: int, seed: int, slow_s: float = 1.0, log: Callable[[str], None] = print
) -> dict:
    """Run ``count`` IES inputs (80 % mutated real files, 20 % random)."""
    files = sorted((TESTDATA / "ies").glob("*.[iI][eE][sS]"))
    real = [f.read_bytes() for f in files]
    rng = random.Random(seed)
    stats: Counter[str] = Counter()
    failures: list[dict] = []
    slow: list[dict] = []
    check_ies(real[0])  # warm-up (imports) outside the timing
    worst = 0.0
    t_all = time.perf_counter()
    for i in range(count):
        if rng.random() < 0.8:
            data = rng.choice(real)
            for _ in range(rng.randint(1, 4)):
                data = _ies_mutate(data, rng)
            kind = "mutated"
        else:
            data = _ies_random(rng)
            kind = "random"
        t0 = time.perf_counter()
        err = check_ies(data, counts=stats)
        dt = time.perf_counter() - t0
        worst = max(worst, dt)
        stats[kind] += 1
        stats["failed" if err else "ok"] += 1
        if err:
            failures.append({"case": i, "kind": kind, "error": err, "input": data[:300].hex()})
            log(f"ies case {i}: {err}")
        if dt > slow_s:
            slow.append({"case": i, "seconds": dt, "bytes": len(data)})
        if (i + 1) % 10000 == 0:
            log(
                f"ies {i + 1}/{count}: {len(failures)} failures, "
                f"{time.perf_counter() - t_all:.0f} s"
            )
    return {
        "inputs": count,
        "seed": seed,
        "real_files": len(real),
        "counts": dict(stats),
        "failures": failures,
        "slow": slow,
        "worst_s": worst,
        "seconds": time.perf_counter() - t_all,
    }


# ---------------------------------------------------------------------------------------
# USD
# ---------------------------------------------------------------------------------------

LIGHT_TYPES = {
    "SphereLight", "RectLight", "DiskLight", "CylinderLight", "DistantLight", "DomeLight",
    "DomeLight_1", "GeometryLight", "PortalLight", "MeshLight",
}  # fmt: skip
#: Light inputs and the value type UsdLux gives them.
LIGHT_INPUTS = {
    "inputs:intensity": "float", "inputs:exposure": "float", "inputs:color": "color3f",
    "inputs:diffuse": "float", "inputs:specular": "float", "inputs:normalize": "bool",
    "inputs:enableColorTemperature": "bool", "inputs:colorTemperature": "float",
    "inputs:radius": "float", "inputs:width": "float", "inputs:height": "float",
    "inputs:length": "float", "inputs:angle": "float",
    "inputs:shaping:cone:angle": "float", "inputs:shaping:cone:softness": "float",
    "inputs:shaping:focus": "float", "inputs:shaping:focusTint": "color3f",
    "inputs:shaping:ies:angleScale": "float", "inputs:shaping:ies:normalize": "bool",
    "inputs:shaping:ies:file": "asset", "inputs:texture:file": "asset",
    "inputs:texture:format": "token", "inputs:shadow:enable": "bool",
    "inputs:shadow:color": "color3f", "inputs:shadow:distance": "float",
    "inputs:shadow:falloff": "float", "inputs:shadow:falloffGamma": "float",
    "treatAsPoint": "bool", "intensity": "float", "radius": "float",
}  # fmt: skip
CAMERA_ATTRS = {
    "focalLength": "float", "horizontalAperture": "float", "verticalAperture": "float",
    "clippingRange": "float2", "fStop": "float", "exposure": "float",
    "horizontalApertureOffset": "float", "projection": "token",
}  # fmt: skip
MESH_ATTRS = {
    "points": "point3f[]", "faceVertexIndices": "int[]", "faceVertexCounts": "int[]",
    "normals": "normal3f[]", "extent": "float3[]", "primvars:displayColor": "color3f[]",
}  # fmt: skip
NONFINITE = ("nan", "inf", "-inf")
HUGE = ("1e30", "1e38", "-1e30", "3.4e38")
SMALL = ("-1", "0", "-0", "1e-30", "-1e-30")
WRONG_TYPES = ("string", "token", "int[]", "float3", "float", "matrix4d", "asset", "double[]")


def _scene_files() -> list[Path]:
    files = [REPO / "usd_scenes" / "default.usda"]
    files += sorted((REPO / "usd_scenes" / "prefabs").glob("*.usda"))
    files += sorted((TESTDATA / "usd" / "luxtest" / "usd").glob("*.usda"))
    files += sorted((TESTDATA / "usd" / "arnold-usd").glob("*/data/*.usda"))
    for rel in (
        "openusd/usd/usdLux/testenv/testUsdLuxLightListAPI/root_with_instances.usda",
        "openusd/usd/usdLux/testenv/testUsdLuxLinkingAPI/linking_example.usda",
        "openusd/usdImaging/usdImagingGL/testenv/testUsdImagingGLMaterialXBasic/mxLights.usda",
    ):
        files.append(TESTDATA / "usd" / rel)
    return [f for f in files if f.is_file()]


def _all_lights_scene() -> str:
    """A scene with one light of every type (and shaping, IES, a textured dome) over a
    floor, for the mutations to hit every reader."""
    ies = (REPO / "usd_scenes" / "ies" / "downlight_narrow.ies").as_posix()
    tex = (TESTDATA / "usd" / "luxtest" / "dome_grid_2k.exr").as_posix()
    return f"""#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Y"
    startTimeCode = 1
    endTimeCode = 4
)
def Xform "World"
{{
    def Camera "Cam"
    {{
        float focalLength = 20
        float horizontalAperture = 36
        float verticalAperture = 20.25
        float2 clippingRange = (0.1, 1000)
        double3 xformOp:translate = (0, 3, 12)
        float xformOp:rotateX = -12
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
    }}
    def Mesh "Floor"
    {{
        int[] faceVertexCounts = [4, 4]
        int[] faceVertexIndices = [0, 1, 2, 3, 1, 4, 5, 2]
        point3f[] points = [(-10, 0, 10), (0, 0, 10), (0, 0, -10), (-10, 0, -10),
                            (10, 0, 10), (10, 0, -10)]
        normal3f[] normals = [(0, 1, 0), (0, 1, 0), (0, 1, 0), (0, 1, 0), (0, 1, 0),
                              (0, 1, 0)] (interpolation = "vertex")
        color3f[] primvars:displayColor = [(0.5, 0.5, 0.5)]
    }}
    def Xform "Lights"
    {{
        def SphereLight "Sphere"
        {{
            float inputs:intensity.timeSamples = {{1: 50, 4: 80}}
            float inputs:radius = 0.2
            double3 xformOp:translate = (-4, 2, 0)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }}
        def SphereLight "Spot" (prepend apiSchemas = ["ShapingAPI", "ShadowAPI"])
        {{
            float inputs:intensity = 400
            float inputs:radius = 0.05
            float inputs:shaping:cone:angle = 30
            float inputs:shaping:cone:softness = 0.3
            float inputs:shaping:focus = 2
            bool inputs:shadow:enable = 1
            double3 xformOp:translate = (0, 4, 0)
            float xformOp:rotateX = -90
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
        }}
        def SphereLight "Ies" (prepend apiSchemas = ["ShapingAPI"])
        {{
            float inputs:intensity = 20
            asset inputs:shaping:ies:file = @{ies}@
            float inputs:shaping:ies:angleScale = 0.1
            bool inputs:shaping:ies:normalize = 1
            double3 xformOp:translate = (4, 3, 0)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }}
        def RectLight "Rect"
        {{
            float inputs:intensity = 30
            float inputs:width = 1
            float inputs:height = 0.5
            bool inputs:normalize = 1
            double3 xformOp:translate = (2, 2, 3)
            float xformOp:rotateX = -90
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
        }}
        def DiskLight "Disk"
        {{
            float inputs:intensity = 30
            float inputs:radius = 0.3
            bool inputs:enableColorTemperature = 1
            float inputs:colorTemperature = 3000
            double3 xformOp:translate = (-2, 2, 3)
            float xformOp:rotateX = -90
            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
        }}
        def CylinderLight "Tube"
        {{
            float inputs:intensity = 20
            float inputs:radius = 0.05
            float inputs:length = 2
            double3 xformOp:translate = (0, 1, -3)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }}
        def DistantLight "Sun"
        {{
            float inputs:intensity = 2
            float inputs:angle = 1
            float xformOp:rotateX = -50
            uniform token[] xformOpOrder = ["xformOp:rotateX"]
        }}
        def DomeLight "Sky"
        {{
            float inputs:intensity = 0.05
            asset inputs:texture:file = @{tex}@
        }}
    }}
}}
"""


class _Base:
    """One base scene: flattened text, its light/camera/mesh prim paths, its times."""

    def __init__(self, name: str, text: str) -> None:
        from pxr import Sdf, Usd

        self.name, self.text = name, text
        layer = Sdf.Layer.CreateAnonymous(".usda")
        layer.ImportFromString(text)
        stage = Usd.Stage.Open(layer)
        self.lights: list[str] = []
        self.light_types: dict[str, str] = {}
        self.cameras: list[str] = []
        self.meshes: list[str] = []
        self.xforms: list[str] = []
        for p in stage.Traverse():
            tn = str(p.GetTypeName())
            path = str(p.GetPath())
            if tn in LIGHT_TYPES or tn.endswith("Light"):
                self.lights.append(path)
                self.light_types[path] = tn
            elif tn == "Camera":
                self.cameras.append(path)
            elif tn == "Mesh":
                self.meshes.append(path)
            elif tn == "Xform":
                self.xforms.append(path)
        self.meshes = self.meshes[:50]
        self.times: list[float | None] = [None]
        if stage.HasAuthoredTimeCodeRange():
            a, b = stage.GetStartTimeCode(), stage.GetEndTimeCode()
            self.times = [a, b, (a + b) / 2]


def load_bases(log: Callable[[str], None] = print) -> list[_Base]:
    """The base scenes, flattened (references resolved, asset paths anchored)."""
    from pxr import Usd

    from stb_hydra.scene.usd_diagnostics import UsdDiagnostics

    bases = [_Base("all_lights", _all_lights_scene())]
    for f in _scene_files():
        with UsdDiagnostics():  # the scenes' own USD warnings are not the fuzzer's
            try:
                text = Usd.Stage.Open(str(f)).Flatten().ExportToString()
            except Exception as e:  # noqa: BLE001
                log(f"skipping base {f}: {e}")
                continue
        bases.append(_Base(str(f.relative_to(f.parents[1])), text))
    return bases


def _bad_value(tname: str, rng: random.Random) -> tuple[str, bool]:
    """A hostile value for a ``tname`` attribute as USD text, and whether it is
    invalid (a reader must report it)."""
    pool = rng.choice([NONFINITE, HUGE, SMALL])
    x = rng.choice(pool)
    invalid = pool is NONFINITE
    if tname in ("float", "double", "half", "int"):
        if tname == "int":
            x = rng.choice(["-1", "0", "2147483647", "-2147483648"])
            invalid = False
        return x, invalid
    if tname in ("color3f", "float3", "point3f", "normal3f", "double3", "vector3f"):
        k = rng.randrange(3)
        v = ["1", "1", "1"]
        v[k] = x
        return f"({', '.join(v)})", invalid
    if tname == "float2":
        return rng.choice([f"({x}, 1000)", "(10, 1)", "(0, 0)", f"(0.1, {x})"]), invalid
    if tname.endswith("[]"):
        elem = tname[:-2]
        if elem == "int":
            v = rng.choice(["[]", "[0, 1, 2]", "[-1, 0, 1, 2]", "[1000000, 0, 1]", "[0, 0, 2**31]"])
            return v.replace("2**31", "2147483647"), False
        v = rng.choice(["[]", f"[({x}, 0, 0), (1, 1, 1), (0, 1, 0)]"])
        return v, invalid and v != "[]"
    if tname == "bool":
        return rng.choice(["0", "1"]), False
    if tname == "token":
        return '"fuzz_not_a_choice"', False
    if tname == "asset":
        return "@/nonexistent/fuzz.ies@", True
    return "0", False


def _wrong_type(tname: str, rng: random.Random) -> tuple[str, str]:
    choices = [t for t in WRONG_TYPES if t != tname and not (tname == "color3f" and t == "float3")]
    t = rng.choice(choices)
    val = {
        "string": '"fuzz"',
        "token": '"fuzz"',
        "int[]": "[1, 2, 3]",
        "float3": "(1, 2, 3)",
        "float": "2",
        "matrix4d": "( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) )",
        "asset": "@fuzz.ies@",
        "double[]": "[1.5, 2.5]",
    }[t]
    return t, val


_LOCAL = ("SphereLight", "RectLight", "DiskLight", "CylinderLight")
#: Which light types read an input (others ignore it: a bad value there is no problem).
_READ_BY = {
    "inputs:radius": ("SphereLight", "DiskLight", "CylinderLight"),
    "inputs:width": ("RectLight",), "inputs:height": ("RectLight",),
    "inputs:length": ("CylinderLight",), "inputs:angle": ("DistantLight",),
    "inputs:texture:file": ("DomeLight",), "inputs:texture:format": (),
    "intensity": (), "radius": (), "treatAsPoint": (),  # legacy: inputs:* wins when authored
    "inputs:colorTemperature": (),  # read only with enableColorTemperature on
}  # fmt: skip


def _read_by(name: str, light_type: str) -> bool:
    """Whether a light of ``light_type`` reads input ``name``."""
    if name in _READ_BY:
        return light_type in _READ_BY[name]
    if name.startswith("inputs:shaping:"):
        return light_type in _LOCAL
    return True


class Mutation:
    """One edit of a base layer: what it did, which prim or file it hit, and whether
    the edit makes the input invalid (then a message must name ``target``)."""

    def __init__(
        self, kind: str, target: str, detail: str, must_report: bool, also: str = "", key: str = ""
    ) -> None:
        self.kind, self.target, self.detail, self.must_report = kind, target, detail, must_report
        #: another name that counts as naming it (the light an IES file is on)
        self.also = also
        #: prim + attribute edited: a later edit of the same key supersedes this one
        self.key = key

    def __repr__(self) -> str:
        return f"{self.kind} {self.target}: {self.detail}"


def _set_attr(layer, prim_path: str, name: str, tname: str, value_text: str, samples: bool) -> None:
    """Author ``name`` on ``prim_path`` (replacing any spec) from USD text."""
    from pxr import Sdf

    spec = layer.GetPrimAtPath(prim_path)
    if spec is None:
        return
    if name in spec.attributes:
        spec.RemoveProperty(spec.attributes[name])
    tmp = Sdf.Layer.CreateAnonymous(".usda")
    line = f"{tname} {name} = {value_text}"
    if samples:  # held before the first and after the last: every time reads it
        v = value_text
        line += f"\n    {tname} {name}.timeSamples = {{-1000000: {v}, 1000000: {v}}}"
    text = f'#usda 1.0\ndef "P"\n{{\n    {line}\n}}\n'
    if not tmp.ImportFromString(text):
        raise ValueError(f"bad fuzz text {text!r}")
    src = tmp.GetPrimAtPath("/P").attributes[name]
    Sdf.CopySpec(tmp, src.path, layer, Sdf.Path(prim_path).AppendProperty(name))


def mutate(layer, base: _Base, rng: random.Random, tmpdir: Path) -> list[Mutation]:
    """Apply 1-3 random mutations to ``layer`` (an anonymous copy of ``base``)."""
    from pxr import Sdf

    out: list[Mutation] = []
    for _ in range(rng.randint(1, 3)):
        kinds = ["light_value"] * 4 + ["light_type"] * 2 + ["xform", "camera", "mesh"]
        kinds += ["ref_missing", "ref_cycle", "file_cycle", "ies_file", "texture", "payload"]
        kind = rng.choice(kinds)
        if kind in ("light_value", "light_type", "ies_file", "texture") and not base.lights:
            kind = "ref_missing"
        if kind == "light_value":
            prim = rng.choice(base.lights)
            name = rng.choice(list(LIGHT_INPUTS))
            tname = LIGHT_INPUTS[name]
            val, invalid = _bad_value(tname, rng)
            samples = rng.random() < 0.3
            _set_attr(layer, prim, name, tname, val, samples)
            invalid = invalid and _read_by(name, base.light_types[prim])
            detail = f"{name} = {val}{' (samples)' if samples else ''}"
            out.append(Mutation(kind, prim, detail, invalid, key=prim + "." + name))
        elif kind == "light_type":
            prim = rng.choice(base.lights)
            name = rng.choice(list(LIGHT_INPUTS))
            t, val = _wrong_type(LIGHT_INPUTS[name], rng)
            _set_attr(layer, prim, name, t, val, False)
            # bool inputs are coerced with bool() (any number or asset reads as a flag)
            invalid = _read_by(name, base.light_types[prim]) and LIGHT_INPUTS[name] != "bool"
            out.append(Mutation(kind, prim, f"{t} {name} = {val}", invalid, key=prim + "." + name))
        elif kind == "xform":
            pool = base.lights + base.xforms + base.cameras + base.meshes
            if not pool:
                continue
            prim = rng.choice(pool)
            spec = layer.GetPrimAtPath(prim)
            op, tname = rng.choice(
                [("xformOp:translate:fuzz", "double3"), ("xformOp:scale:fuzz", "float3"),
                 ("xformOp:rotateXYZ:fuzz", "float3"), ("xformOp:transform:fuzz", "matrix4d")]
            )  # fmt: skip
            x = rng.choice(NONFINITE + HUGE + ("0",))
            if tname == "matrix4d":
                val = f"( ({x}, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1) )"
            else:
                val = f"({x}, {x if rng.random() < 0.5 else 1}, 1)"
            _set_attr(layer, prim, op, tname, val, False)
            order = spec.attributes.get("xformOpOrder")
            ops = list(order.default) if order is not None and order.default else []
            ops.append(op)
            _set_attr(layer, prim, "xformOpOrder", "uniform token[]",
                      "[" + ", ".join(f'"{o}"' for o in ops) + "]", False)  # fmt: skip
            out.append(Mutation(kind, prim, f"{op} = {val}", x in NONFINITE))
        elif kind == "camera" and base.cameras:
            prim = rng.choice(base.cameras)
            name = rng.choice(list(CAMERA_ATTRS))
            if rng.random() < 0.3:
                t, val = _wrong_type(CAMERA_ATTRS[name], rng)
                _set_attr(layer, prim, name, t, val, False)
                out.append(Mutation(kind, prim, f"{t} {name} = {val}", False))
            else:
                val, invalid = _bad_value(CAMERA_ATTRS[name], rng)
                _set_attr(layer, prim, name, CAMERA_ATTRS[name], val, False)
                out.append(Mutation(kind, prim, f"{name} = {val}", False))
        elif kind == "mesh" and base.meshes:
            prim = rng.choice(base.meshes)
            name = rng.choice(list(MESH_ATTRS))
            val, invalid = _bad_value(MESH_ATTRS[name], rng)
            _set_attr(layer, prim, name, MESH_ATTRS[name], val, False)
            out.append(Mutation(kind, prim, f"{name} = {val}", False))
        elif kind in ("ref_missing", "payload"):
            name = f"/FuzzRef{len(out)}"
            spec = Sdf.CreatePrimInLayer(layer, name)
            spec.specifier = Sdf.SpecifierDef
            missing = rng.choice(
                [Sdf.Reference("/nonexistent/fuzz_missing.usda"),
                 Sdf.Reference(str(tmpdir / "missing.usda"), "/Nope"),
                 Sdf.Reference("", "/NoSuchPrim")]
            )  # fmt: skip
            if kind == "payload":
                spec.payloadList.Prepend(Sdf.Payload(missing.assetPath, missing.primPath))
            else:
                spec.referenceList.Prepend(missing)
            out.append(Mutation(kind, name, f"{kind} {missing}", True))
        elif kind == "ref_cycle":
            a, b = f"/FuzzCycA{len(out)}", f"/FuzzCycB{len(out)}"
            for p, q in ((a, b), (b, a)):
                spec = Sdf.CreatePrimInLayer(layer, p)
                spec.specifier = Sdf.SpecifierDef
                spec.referenceList.Prepend(Sdf.Reference("", q))
            out.append(Mutation(kind, a, f"{a} -> {b} -> {a}", True))
        elif kind == "file_cycle":
            fa, fb = tmpdir / f"cyc_a{len(out)}.usda", tmpdir / f"cyc_b{len(out)}.usda"
            fa.write_text(
                f'#usda 1.0\n(defaultPrim = "A")\ndef Xform "A" (references = @{fb.name}@)\n{{}}\n'
            )
            fb.write_text(
                f'#usda 1.0\n(defaultPrim = "B")\ndef Xform "B" (references = @{fa.name}@)\n{{}}\n'
            )
            name = f"/FuzzFileCycle{len(out)}"
            spec = Sdf.CreatePrimInLayer(layer, name)
            spec.specifier = Sdf.SpecifierDef
            spec.referenceList.Prepend(Sdf.Reference(str(fa)))
            out.append(Mutation(kind, fa.name, f"{fa.name} <-> {fb.name}", True))
        elif kind == "ies_file":
            prim = rng.choice(base.lights)
            what = rng.choice(["missing", "dir", "garbage", "fuzzed", "empty"])
            path = tmpdir / f"f{len(out)}.ies"
            if what == "missing":
                path = tmpdir / "no_such.ies"
            elif what == "dir":
                path = tmpdir / f"dir{len(out)}.ies"
                path.mkdir(exist_ok=True)
            elif what == "garbage":
                path.write_bytes(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 4000))))
            elif what == "empty":
                path.write_bytes(b"")
            else:
                real = sorted((TESTDATA / "ies").glob("*.[iI][eE][sS]"))
                data = rng.choice(real).read_bytes()
                for _ in range(rng.randint(1, 3)):
                    data = _ies_mutate(data, rng)
                path.write_bytes(data)
            _set_attr(layer, prim, "inputs:shaping:ies:file", "asset", f"@{path}@", False)
            bad = what != "fuzzed" and _read_by("inputs:shaping:ies:file", base.light_types[prim])
            key = prim + ".inputs:shaping:ies:file"
            out.append(Mutation(kind, path.name, f"{what} IES on {prim}", bad, prim, key))
        elif kind == "texture":
            prim = rng.choice(base.lights)
            what = rng.choice(["missing", "truncated_exr", "truncated_png", "garbage"])
            path = tmpdir / f"tex{len(out)}.{'png' if 'png' in what else 'exr'}"
            src = TESTDATA / "usd" / "luxtest" / "dome_grid_2k.exr"
            if what == "missing":
                path = tmpdir / "no_such.exr"
            elif what == "truncated_exr":
                path.write_bytes(src.read_bytes()[: rng.randrange(10, 20000)])
            elif what == "truncated_png":
                png = _tiny_png()
                path.write_bytes(png[: rng.randrange(8, len(png) - 1)])
            else:
                path.write_bytes(bytes(rng.randrange(256) for _ in range(500)))
            _set_attr(layer, prim, "inputs:texture:file", "asset", f"@{path}@", False)
            bad = _read_by("inputs:texture:file", base.light_types[prim])
            key = prim + ".inputs:texture:file"
            out.append(Mutation(kind, path.name, f"{what} texture on {prim}", bad, prim, key))
    for i, m in enumerate(out):  # an attribute edited twice: the last edit counts
        if m.key and any(n.key == m.key for n in out[i + 1 :]):
            m.must_report = False
    return out


_PNG: bytes | None = None


def _tiny_png() -> bytes:
    global _PNG
    if _PNG is None:
        import OpenImageIO as oiio

        with tempfile.TemporaryDirectory() as d:
            p = os.path.join(d, "t.png")
            buf = oiio.ImageBuf(oiio.ImageSpec(64, 64, 3, "uint8"))
            oiio.ImageBufAlgo.fill(buf, (0.2, 0.5, 0.8))
            buf.write(p)
            _PNG = Path(p).read_bytes()
    return _PNG


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[str]]:
    """Lines written to fd 2 (by USD's worker threads, GL drivers...) while open."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as f:
        os.dup2(f.fileno(), 2)
        try:
            yield lines
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            f.seek(0)
            lines.extend(
                ln for ln in f.read().decode("utf-8", "replace").splitlines() if ln.strip()
            )


def render_all_methods(
    stage, size: tuple[int, int], time_code: float | None, methods=METHODS
) -> tuple[list[str], list[str]]:
    """Render ``stage`` with every method; (messages, failures). Messages are what a
    user would see: engine warnings, trapped USD diagnostics, a RenderError."""
    from stb_hydra.renderer.engine import Engine, RenderError
    from stb_hydra.renderer.frame import RenderSettings

    messages: list[str] = []
    failures: list[str] = []
    w, h = size
    try:
        eng = Engine(stage, RenderSettings(width=w, height=h, lighting=methods[0]), time=time_code)
    except RenderError as e:
        return [str(e)], []
    try:
        eng.request_aovs({"color"})
        for m in methods:
            try:
                if m != eng.method.name:
                    eng.set_lighting(m)
                eng.render(time_code)
                img = eng.aovs["color"]
            except RenderError as e:
                messages.append(str(e))
                continue
            bad = int(np.count_nonzero(~np.isfinite(img)))
            if bad:
                failures.append(f"{m}: {bad} non-finite values")
        messages.extend(eng.warnings)
    finally:
        eng.release()
    return messages, failures


def run_usd_case(base: _Base, rng: random.Random, tmpdir: Path, size, methods) -> dict:
    """One mutated scene rendered with every method; the case record."""
    from pxr import Sdf, Usd

    from stb_hydra.scene.usd_diagnostics import UsdDiagnostics, summarize

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(base.text)
    muts = mutate(layer, base, rng, tmpdir)
    t = rng.choice(base.times)
    rec: dict[str, Any] = {"base": base.name, "mutations": [repr(m) for m in muts], "time": t}
    messages: list[str] = []
    failures: list[str] = []
    t0 = time.perf_counter()
    with _captured_stderr() as raw, UsdDiagnostics() as diag:
        try:
            stage = Usd.Stage.Open(layer)
            msgs, failures = render_all_methods(stage, size, t, methods)
            messages += msgs
        except Exception as e:  # noqa: BLE001 - a crash is what we count
            failures.append(f"crash {type(e).__name__}: {e}")
            rec["traceback"] = traceback.format_exc().splitlines()[-6:]
        messages += summarize(diag.drain())
    rec["seconds"] = time.perf_counter() - t0
    for m in messages:
        if "\n" in m.strip() or not m.strip():
            failures.append(f"message not one line: {m!r}")
    for mut in muts:
        if not mut.must_report:
            continue
        leaf = mut.target.rsplit("/", 1)[-1]
        names = [mut.target, leaf] + ([mut.also] if mut.also else [])
        if any(n and n in m for m in messages for n in names):
            continue
        # USD's repeats of one cause are one line naming the first prim, "+N more"
        if any("more like this)" in m for m in messages):
            rec["collapsed"] = rec.get("collapsed", 0) + 1
            continue
        failures.append(f"not reported: {mut!r}")
    if raw:
        rec["raw_stderr"] = raw[:5]
    rec["messages"] = messages[:20]
    rec["failures"] = failures
    return rec


def _big_stage(n_prims: int):
    """A stage of ``n_prims`` prims: 1000-wide Xform groups of Xforms, with a floor,
    a camera and a light in each group's first child."""
    from pxr import Sdf, Usd

    layer = Sdf.Layer.CreateAnonymous(".usda")
    base = _Base("all_lights", _all_lights_scene())
    layer.ImportFromString(base.text)
    with Sdf.ChangeBlock():
        world = layer.GetPrimAtPath("/World")
        per = 1000
        made = 0
        g = 0
        while made < n_prims:
            grp = Sdf.PrimSpec(world, f"G{g}", Sdf.SpecifierDef, "Xform")
            made += 1
            for i in range(min(per, n_prims - made)):
                Sdf.PrimSpec(grp, f"P{i}", Sdf.SpecifierDef, "Xform" if i else "Scope")
                made += 1
            g += 1
    return Usd.Stage.Open(layer)


def _deep_instancing(depth: int, fan: int) -> str:
    """Nested point instancers ``depth`` deep, ``fan`` instances each (fan^depth
    leaves), plus a chain of ``depth`` instanceable references, each level holding a
    light."""
    lines = [
        "#usda 1.0",
        '(\n    defaultPrim = "World"\n    metersPerUnit = 1\n    upAxis = "Y"\n)',
        'def Xform "World"\n{',
        '    def Camera "Cam"\n    {\n        double3 xformOp:translate = (0, 3, 30)\n'
        '        uniform token[] xformOpOrder = ["xformOp:translate"]\n    }',
    ]
    pts = ", ".join(f"({i * 1.5}, 0, 0)" for i in range(fan))
    idx = ", ".join("0" for _ in range(fan))

    def level(d: int, indent: str) -> list[str]:
        if d == 0:
            return [
                f'{indent}def Sphere "Leaf"',
                f"{indent}{{",
                f"{indent}    double radius = 0.2",
                f"{indent}}}",
                f'{indent}def SphereLight "L"',
                f"{indent}{{",
                f"{indent}    float inputs:intensity = 5",
                f"{indent}    float inputs:radius = 0.05",
                f"{indent}}}",
            ]
        body = [
            f'{indent}def PointInstancer "PI{d}"',
            f"{indent}{{",
            f"{indent}    rel prototypes = [<Proto{d}>]",
            f"{indent}    int[] protoIndices = [{idx}]",
            f"{indent}    point3f[] positions = [{pts}]",
            f'{indent}    def Xform "Proto{d}"',
            f"{indent}    {{",
        ]
        body += level(d - 1, indent + "        ")
        body += [f"{indent}    }}", f"{indent}}}"]
        return body

    lines += level(depth, "    ")
    lines.append('    def Xform "Chain" (references = </R0>)\n    {\n    }\n}')
    # a chain of instanceable references /R0 -> /R1 -> ... each adding a light
    for d in range(depth * 4):
        ref = f" (instanceable = true\n    references = </R{d + 1}>)" if d + 1 < depth * 4 else ""
        lines.append(
            f'def Xform "R{d}"{ref}\n{{\n    def SphereLight "L{d}"\n    {{\n'
            "        float inputs:intensity = 1\n    }\n}"
        )
    return "\n".join(lines) + "\n"


def structural(size, methods, n_prims: int, depth: int, fan: int, log=print) -> list[dict]:
    """The 1e6-prim stage and deep instancing, each rendered with every method."""
    from pxr import Sdf, Usd

    from stb_hydra.scene.usd_diagnostics import UsdDiagnostics, summarize

    out = []
    for name in ("big", "deep_instancing"):
        t0 = time.perf_counter()
        rec: dict[str, Any] = {"case": name}
        with UsdDiagnostics() as diag:
            try:
                if name == "big":
                    stage = _big_stage(n_prims)
                    rec["prims"] = sum(1 for _ in stage.Traverse())
                else:
                    layer = Sdf.Layer.CreateAnonymous(".usda")
                    if not layer.ImportFromString(_deep_instancing(depth, fan)):
                        raise ValueError("deep instancing scene does not parse")
                    stage = Usd.Stage.Open(layer)
                    rec["depth"], rec["fan"] = depth, fan
                rec["open_s"] = time.perf_counter() - t0
                msgs, fails = render_all_methods(stage, size, None, methods)
            except Exception as e:  # noqa: BLE001
                msgs, fails = [], [f"crash {type(e).__name__}: {e}"]
                rec["traceback"] = traceback.format_exc().splitlines()[-8:]
            msgs += summarize(diag.drain())
        rec["seconds"] = time.perf_counter() - t0
        rec["messages"] = msgs[:20]
        rec["failures"] = fails + [f"message not one line: {m!r}" for m in msgs if "\n" in m]
        rec["rss_mib"] = _rss_mib()
        log(f"structural {name}: {rec['seconds']:.1f} s, {len(rec['failures'])} failures")
        out.append(rec)
    return out


def _rss_mib() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return 0.0


def fuzz_usd(
    count: int,
    seed: int,
    size=(32, 18),
    methods=METHODS,
    only: int | None = None,
    log: Callable[[str], None] = print,
    case_timeout: float = 300.0,
) -> dict:
    """``count`` mutated scenes, each rendered with every method."""
    bases = load_bases(log)
    rng = random.Random(seed)
    stats: Counter[str] = Counter()
    cases: list[dict] = []
    failed: list[dict] = []
    raw_examples: list[dict] = []
    t_all = time.perf_counter()
    hang_out = os.fdopen(os.dup(2), "w")  # fd 2 itself is captured during a case
    with tempfile.TemporaryDirectory(prefix="stb_fuzz_") as d:
        for i in range(count):
            case_rng = random.Random(rng.getrandbits(64))
            if only is not None and i != only:
                continue
            # a hang ends the run with every thread's stack (and the case number)
            hang_out.write(f"usd case {i}\n")
            hang_out.flush()
            faulthandler.dump_traceback_later(case_timeout, exit=True, file=hang_out)
            base = case_rng.choice(bases)
            cdir = Path(d) / f"c{i}"
            cdir.mkdir()
            rec = run_usd_case(base, case_rng, cdir, size, methods)
            rec["case"] = i
            stats["cases"] += 1
            for f in rec["failures"]:
                stats[f.split(":")[0].split(" ")[0]] += 1
            if rec["failures"]:
                failed.append(rec)
                log(f"usd case {i} ({base.name}; {rec['mutations']}): {rec['failures'][:3]}")
            if rec.get("raw_stderr"):
                stats["raw_stderr_cases"] += 1
                if len(raw_examples) < 50:
                    raw_examples.append(
                        {"case": i, "mutations": rec["mutations"], "stderr": rec["raw_stderr"]}
                    )
            stats["messages"] += len(rec["messages"])
            cases.append({k: rec[k] for k in ("case", "base", "mutations", "seconds")})
            faulthandler.cancel_dump_traceback_later()
            if (i + 1) % 100 == 0:
                log(
                    f"usd {i + 1}/{count}: {len(failed)} failing cases, "
                    f"{time.perf_counter() - t_all:.0f} s"
                )
    return {
        "cases": stats["cases"],
        "renders": stats["cases"] * len(methods),
        "seed": seed,
        "size": list(size),
        "methods": list(methods),
        "bases": [b.name for b in bases],
        "counts": dict(stats),
        "failed": failed,
        "raw_stderr": raw_examples,
        "slowest": sorted(cases, key=lambda c: -c["seconds"])[:5],
        "worst_s": max((c["seconds"] for c in cases), default=0.0),
        "seconds": time.perf_counter() - t_all,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=["ies", "usd"])
    ap.add_argument("--count", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", type=int, default=None, help="replay one case number")
    ap.add_argument("--size", default="32x18")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--slow", type=float, default=1.0, help="IES: seconds that count as slow")
    ap.add_argument("--structural", action="store_true", help="USD: 1e6 prims, deep instancing")
    ap.add_argument("--prims", type=int, default=1_000_000)
    ap.add_argument("--depth", type=int, default=6)
    ap.add_argument("--fan", type=int, default=4)
    ap.add_argument("--json", default="")
    args = ap.parse_args(argv)
    if args.what == "ies":
        doc = fuzz_ies(args.count, args.seed, args.slow)
        bad = len(doc["failures"]) + len(doc["slow"])
        print(
            f"ies: {doc['inputs']} inputs ({doc['counts']}) in {doc['seconds']:.0f} s, "
            f"worst {doc['worst_s'] * 1e3:.0f} ms: {len(doc['failures'])} failures, "
            f"{len(doc['slow'])} slower than {args.slow:g} s"
        )
    else:
        w, h = (int(v) for v in args.size.split("x"))
        methods = tuple(m for m in args.methods.split(",") if m)
        doc = fuzz_usd(args.count, args.seed, (w, h), methods, args.only)
        if args.structural:
            doc["structural"] = structural((w, h), methods, args.prims, args.depth, args.fan)
        bad = len(doc["failed"]) + sum(bool(s["failures"]) for s in doc.get("structural", []))
        print(
            f"usd: {doc['cases']} cases x {len(methods)} methods in {doc['seconds']:.0f} s "
            f"(worst case {doc['worst_s']:.1f} s): {len(doc['failed'])} failing cases "
            f"{ {k: v for k, v in doc['counts'].items() if k != 'cases'} }"
        )
    if args.json:
        Path(args.json).write_text(json.dumps(doc, indent=1, default=str) + "\n")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
