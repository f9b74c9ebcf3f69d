"""Generate the chess many-light scene: the OpenChessSet on a table under N tiny lights.

The stage references the OpenChessSet's ``chess_set.usda`` (``--chess`` / ``chess``,
else ``$STB_SHARED/testdata/scenes/OpenChessSet/chess_set.usda``, else the same under
``../shared`` next to the source checkout; see :func:`.common.chess_set`) by a
relative asset path computed from OUT's folder, so the written file resolves it
(absolute for in-memory stages), puts the 70 cm board on a table in a room-sized
floor, and scatters N small shadowed sphere lights 2-20 cm above the board top
(radius 2-20 mm), never inside a piece (piece bounds come from the asset's
extentsHint, read without loading payloads). The lights share ``--total-lumens``
(default 300 lm, a desk lamp's worth, ~300 lx on the board) with log-normal
spread, so the board's exposure barely changes with N.

The asset renders with its own MaterialX looks (``scene.materialx``: marble, wood,
gold, normal maps). ``--fallback-materials`` binds plain UsdPreviewSurface looks
(ivory, ebony, walnut) over them on the White / Black / Chessboard groups with
``strongerThanDescendants`` -- untextured, as every scene of this generator was before
MaterialX looks loaded (the figures in docs/STB_NOTES.md before issue 30 used them).

    python -m stb_hydra.scenegen.chess out/chess_256.usda --lights 256

(``python tools/gen_chess_lights.py ...`` in a checkout is the same command.)
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from .common import (
    REC709_Y,
    UsdaWriter,
    asset_path,
    box,
    chess_set,
    exposure_for_illuminance,
    hsv_to_rgb,
    merge,
    plane,
    save,
    stage_from_text,
)

BOARD_HALF = 0.33  # lights stay over the playing area (board is +-0.353 m)
FALLBACK_LOOKS = {
    "White": ("Ivory", (0.78, 0.74, 0.64), 0.35),
    "Black": ("Ebony", (0.05, 0.045, 0.04), 0.3),
    "Chessboard": ("Walnut", (0.36, 0.24, 0.14), 0.45),
}


def piece_bounds(chess: Path) -> tuple[np.ndarray, float]:
    """((P, 6) world boxes lo.xyz/hi.xyz of every piece incl. instanced pawns, board
    top y). Uses extentsHint only, so no payload (and no .mtlx) is loaded."""
    from pxr import Gf, Usd, UsdGeom

    stage = Usd.Stage.Open(str(chess), Usd.Stage.LoadNone)
    if not stage:
        raise FileNotFoundError(chess)
    root = stage.GetDefaultPrim()
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), ["default", "render"], useExtentsHint=True)
    xf = UsdGeom.XformCache()
    boxes = []
    board_top = 0.0
    for group in root.GetAllChildren():  # unloaded prims are not in GetChildren()
        if group.GetName().lower().startswith("chessboard"):
            board_top = cache.ComputeWorldBound(group).ComputeAlignedRange().GetMax()[1]
            continue
        for prim in group.GetAllChildren():  # pieces, and the pawns' PointInstancer
            if not prim.IsA(UsdGeom.PointInstancer):
                r = cache.ComputeWorldBound(prim).ComputeAlignedRange()
                if not r.IsEmpty():
                    boxes.append([*r.GetMin(), *r.GetMax()])
                continue
            pi = UsdGeom.PointInstancer(prim)
            protos = pi.GetPrototypesRel().GetTargets()
            ids = pi.GetProtoIndicesAttr().Get()
            mats = pi.ComputeInstanceTransformsAtTime(
                Usd.TimeCode.Default(), Usd.TimeCode.Default()
            )
            world = xf.GetLocalToWorldTransform(prim)
            for k, m in zip(ids, mats):
                hint = UsdGeom.ModelAPI(stage.GetPrimAtPath(protos[k])).GetExtentsHint()
                if hint:
                    lo, hi = Gf.Vec3d(*hint[0]), Gf.Vec3d(*hint[1])
                    r = Gf.BBox3d(Gf.Range3d(lo, hi), m * world).ComputeAlignedRange()
                    boxes.append([*r.GetMin(), *r.GetMax()])
    return np.asarray(boxes, float), float(board_top)


def chess_scene_usda(
    n_lights: int = 256,
    seed: int = 0,
    chess: Path | str | None = None,
    total_lumens: float = 300.0,
    radius: tuple[float, float] = (0.002, 0.02),
    height: tuple[float, float] = (0.02, 0.2),
    fallback_materials: bool = False,
    anchor_dir: Path | str | None = None,
) -> str:
    chess = chess_set(chess)  # FileNotFoundError when missing
    rng = np.random.default_rng(seed)
    pieces, board_top = piece_bounds(chess)
    n = n_lights

    r = np.exp(rng.uniform(math.log(radius[0]), math.log(radius[1]), n))
    pos = np.empty((n, 3))
    todo = np.arange(n)
    for _ in range(200):
        k = len(todo)
        pos[todo, 0] = rng.uniform(-BOARD_HALF, BOARD_HALF, k)
        pos[todo, 1] = board_top + rng.uniform(height[0], height[1], k)
        pos[todo, 2] = rng.uniform(-BOARD_HALF, BOARD_HALF, k)
        p, rr = pos[todo], r[todo, None] + 0.005
        inside = np.zeros(k, bool)
        for b in pieces:
            inside |= np.all((p > b[:3] - rr) & (p < b[3:] + rr), axis=1)
        todo = todo[inside]
        if not len(todo):
            break
    if len(todo):
        raise RuntimeError(f"could not place {len(todo)} lights outside the pieces")
    pos = np.round(pos, 4)
    r = np.round(r, 4)
    share = rng.lognormal(0.0, 0.6, n)
    flux = total_lumens * share / share.sum()
    use_kelvin = rng.random(n) < 0.5
    kelvin = np.round(rng.uniform(2200.0, 7500.0, n), -1)
    rgb = hsv_to_rgb(rng.random(n), rng.uniform(0.3, 0.85, n), np.ones(n))
    rgb_y = rgb @ np.array(REC709_Y)
    cd = flux / (4 * math.pi)
    nits = cd / (math.pi * r * r)
    nits = np.where(use_kelvin, nits, nits / rgb_y)

    board_area = (2 * 0.353) ** 2
    e_mean = 0.5 * total_lumens / board_area  # half of isotropic flux goes down
    exposure = exposure_for_illuminance(e_mean)

    w = UsdaWriter()
    w.header(
        doc=(
            f"stb_hydra chess many-light scene: {n} small shadowed sphere lights "
            f"(r {radius[0] * 1000:g}-{radius[1] * 1000:g} mm, {total_lumens:g} lm in total)\n"
            f"hovering {height[0] * 100:g}-{height[1] * 100:g} cm over the OpenChessSet "
            "(CC BY 4.0, Academy Software Foundation; see the referenced layer's doc).\n"
            f"Generated by tools/gen_chess_lights.py --lights {n} --seed {seed} "
            f"--total-lumens {total_lumens:g}. Units: metres, nits. "
            f"Mean board illuminance ~{e_mean:.0f} lx."
        ),
        default_prim="World",
    )
    with w.prim("Xform", "World", meta=['kind = "assembly"']):
        looks = {"Table": ((0.25, 0.16, 0.1), 0.5), "Floor": ((0.4, 0.38, 0.36), 0.8)}
        if fallback_materials:
            looks.update({name: (c, rough) for name, c, rough in FALLBACK_LOOKS.values()})
        with w.prim("Scope", "Looks"):
            for name, (c, rough) in looks.items():
                w.preview_material(name, f"/World/Looks/{name}", diffuse=c, roughness=rough)
        chess_ref = asset_path(chess, anchor_dir)
        with w.prim(
            "Xform",
            "ChessSet",
            meta=[f"prepend references = {chess_ref}"],
            doc="The OpenChessSet, unchanged (board top at "
            f"y = {board_top:.4f} m)"
            + (", plus untextured fallback looks." if fallback_materials else "."),
        ):
            if fallback_materials:
                for group, (mat, _, _) in FALLBACK_LOOKS.items():
                    with w.prim(
                        None,
                        group,
                        specifier="over",
                        meta=['prepend apiSchemas = ["MaterialBindingAPI"]'],
                    ):
                        w.line(f"rel material:binding = </World/Looks/{mat}> (")
                        w.line('    bindMaterialAs = "strongerThanDescendants"')
                        w.line(")")
        with w.prim("Xform", "Room"):
            top = merge(
                [box((-0.6, -0.04, -0.6), (0.6, -0.0005, 0.6))]
                + [
                    box(
                        (sx * 0.55 - 0.03, -0.75, sz * 0.55 - 0.03),
                        (sx * 0.55 + 0.03, -0.04, sz * 0.55 + 0.03),
                        bottom=False,
                    )
                    for sx in (-1, 1)
                    for sz in (-1, 1)
                ]
            )
            w.mesh(
                "Table",
                top,
                material="/World/Looks/Table",
                doc="1.2 m table, top 0.5 mm under the board's underside.",
            )
            w.mesh("Floor", plane(6.0, 6.0, y=-0.75), material="/World/Looks/Floor")
        with w.prim("Xform", "Lights", doc=f"{n} SphereLights, shadowed (static maps)."):
            pad, p2 = w.pad, w.pad + "    "
            parts = []
            for i in range(n):
                col = (
                    (
                        f"{p2}float inputs:colorTemperature = {kelvin[i]:.0f}\n"
                        f"{p2}bool inputs:enableColorTemperature = 1\n"
                    )
                    if use_kelvin[i]
                    else (
                        f"{p2}color3f inputs:color = "
                        f"({rgb[i, 0]:.3f}, {rgb[i, 1]:.3f}, {rgb[i, 2]:.3f})\n"
                    )
                )
                parts.append(
                    f'{pad}def SphereLight "L{i:05d}" (\n{p2}prepend apiSchemas = ["ShadowAPI"]\n'
                    f"{pad})\n{pad}{{\n{col}"
                    f"{p2}float inputs:intensity = {nits[i]:.2f}\n"
                    f"{p2}float inputs:radius = {r[i]:.4f}\n"
                    f"{p2}bool inputs:shadow:enable = 1\n"
                    f"{p2}double3 xformOp:translate = "
                    f"({pos[i, 0]:.4f}, {pos[i, 1]:.4f}, {pos[i, 2]:.4f})\n"
                    f'{p2}uniform token[] xformOpOrder = ["xformOp:translate"]\n{pad}}}\n\n'
                )
            w.raw("".join(parts).rstrip("\n"))
    w.camera(
        "Camera",
        eye=(-0.28, 0.62, -0.78),
        target=(0.0, 0.03, 0.0),
        focal_length=35.0,
        clipping=(0.01, 20.0),
        exposure=exposure,
        comment=f"Looks at the board from White's side. exposure {exposure:g}: an 18 % card "
        f"under ~{e_mean:.0f} lx -> 0.18.",
    )
    return w.text()


def build_chess_stage(n_lights: int = 256, seed: int = 0, path: str | Path | None = None, **kwargs):
    """``Usd.Stage`` of the chess scene: in memory when ``path`` is None, else written."""
    from pxr import Usd

    if path is None:
        return stage_from_text(chess_scene_usda(n_lights, seed, **kwargs))
    path = Path(path)
    save(chess_scene_usda(n_lights, seed, anchor_dir=path.resolve().parent, **kwargs), path)
    return Usd.Stage.Open(str(path))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    ap.add_argument("out", type=Path, help="output .usda or .usdc")
    ap.add_argument("--lights", type=int, default=256)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--chess",
        type=Path,
        default=None,
        help="chess_set.usda to reference (default: $STB_SHARED's, else "
        "../shared's next to the checkout)",
    )
    ap.add_argument("--total-lumens", type=float, default=300.0, help="flux shared by all lights")
    ap.add_argument(
        "--radius",
        type=float,
        nargs=2,
        default=(0.002, 0.02),
        metavar=("MIN", "MAX"),
        help="light radius range (m), log-uniform",
    )
    ap.add_argument(
        "--height",
        type=float,
        nargs=2,
        default=(0.02, 0.2),
        metavar=("MIN", "MAX"),
        help="height range above the board top (m)",
    )
    ap.add_argument(
        "--fallback-materials",
        action="store_true",
        help="bind untextured UsdPreviewSurface looks over the asset's MaterialX looks",
    )
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    try:
        text = chess_scene_usda(
            args.lights,
            args.seed,
            args.chess,
            args.total_lumens,
            tuple(args.radius),
            tuple(args.height),
            args.fallback_materials,
            anchor_dir=args.out.resolve().parent,
        )
    except (FileNotFoundError, RuntimeError) as e:
        ap.error(str(e))
    save(text, args.out)
    print(f"wrote {args.out}: {args.lights} lights in {time.perf_counter() - t0:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
