"""Plant deliberate bugs one at a time and check that the tests catch each (issue 21).

Each mutant is a text substitution in one Python or GLSL file (the old text must
occur exactly once, so a refactor that moves it is reported, not silently skipped).
The checkout is never modified: the tree (tracked and untracked, not ignored files)
is copied to a scratch directory once; each mutant is applied there, the relevant
test files run against that copy (``PYTHONPATH`` puts the copy's ``stb_hydra`` first;
the top-level ``shaders/`` is linked in as ``stb_hydra/shaders`` as the wheel does),
and the file is restored in a ``finally`` before the next mutant. The scratch
directory is removed at the end.

    .venv/bin/python tools/mutation_check.py            # every mutant
    .venv/bin/python tools/mutation_check.py --list     # ids and descriptions
    .venv/bin/python tools/mutation_check.py --only abs_cosine,sun_half --json out/m.json
    .venv/bin/python tools/mutation_check.py --tests tests/test_lights.py   # other tests

Exit status: 0 when every mutant is killed (and the unmutated baseline passes), 1 when
one survives, 2 when a mutant no longer applies or the baseline fails. It runs outside
CI (minutes: see docs/RELIABILITY.md).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

CLOSED = ("tests/test_closed_form_hard.py", "tests/test_render_closed_form.py")
LIGHTS = ("tests/test_lights.py",)
VALIDATE = ("tests/test_validate_limits.py", "tests/test_validate.py")
STB_UNBIASED = "tests/test_stb.py::test_unbiased_mean_converges_to_reference"
REUSE_UNBIASED = "tests/test_stb_reuse.py::test_unbiased_mean_converges_to_closed_form"


@dataclass(frozen=True)
class Mutant:
    id: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]
    what: str
    listed: bool = False  # a bug class named in issue 21


MUTANTS: tuple[Mutant, ...] = (
    # --- the bug classes of issue 21 ---------------------------------------------------
    Mutant(
        "abs_cosine",
        "shaders/common/brdf.glsl",
        "float NoL = dot(s.N, L);",
        "float NoL = abs(dot(s.N, L));",
        CLOSED,
        "the surface cosine taken as an absolute value (a light below a floor lights it)",
        True,
    ),
    Mutant(
        "cone_band_half",
        "stb_hydra/renderer/light_table.py",
        "cut * (1.0 - lp.cone_softness)",
        "cut * (1.0 - 0.5 * lp.cone_softness)",
        CLOSED,
        "cone-softness band half as wide as UsdLux specifies",
        True,
    ),
    Mutant(
        "emit_back_side",
        "shaders/common/lights.glsl",
        "return max(dot(w, L.axis_emit.xyz), 0.0);",
        "return abs(dot(w, L.axis_emit.xyz));",
        CLOSED,
        "rect and disk lights emitting from their back side",
        True,
    ),
    Mutant(
        "sun_half",
        "stb_hydra/renderer/tasks/distant_lights.py",
        "sun.illuminance = t.intensity[r].astype(np.float64)",
        "sun.illuminance = 0.5 * t.intensity[r].astype(np.float64)",
        CLOSED,
        "the sun at half strength",
        True,
    ),
    Mutant(
        "ies_normalize_x2",
        "stb_hydra/scene/lights.py",
        "lp.ies_scale = mx / power if lp.ies_normalize else mx",
        "lp.ies_scale = mx / (2.0 * power) if lp.ies_normalize else mx",
        CLOSED,
        "shaping:ies:normalize off by a factor of 2",
        True,
    ),
    Mutant(
        "validate_flux_off_by_one",
        "stb_hydra/validate/rules_photometry.py",
        "if total > limits.VALIDATE_PREFAB_FLUX_MAX_LM:",
        "if total >= limits.VALIDATE_PREFAB_FLUX_MAX_LM:",
        VALIDATE,
        "a validator limit off by one (prefab flux: at the limit is allowed)",
        True,
    ),
    Mutant(
        "validate_overlap_plus_one",
        "stb_hydra/validate/rules_overlap.py",
        "np.unique(mesh_of[counts > limit])",
        "np.unique(mesh_of[counts > limit + 1])",
        VALIDATE,
        "a validator limit off by one (STB overlap: 17 lights over one point unreported)",
        True,
    ),
    Mutant(
        "stats_not_atomic",
        "stb_hydra/io/files.py",
        'fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name}.tmp-", dir=p.parent)',
        "fd, tmp_name = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), str(p)",
        ("tests/test_atomic_writes.py",),
        "stats/text JSON written in place instead of through a temporary file",
        True,
    ),
    Mutant(
        "validate_json_in_place",
        "stb_hydra/validate/report.py",
        'tmp = f"{path}.tmp-{os.getpid()}"',
        "tmp = path",
        ("tests/test_atomic_writes.py",),
        "stb validate JSON/HTML written in place",
    ),
    Mutant(
        "validate_json_tmp_left",
        "stb_hydra/validate/report.py",
        "os.unlink(tmp)",
        "os.path.exists(tmp)",
        ("tests/test_atomic_writes.py",),
        "stb validate JSON/HTML: the temporary file left behind on failure",
    ),
    # --- our own -------------------------------------------------------------------------
    Mutant(
        "dome_half",
        "stb_hydra/renderer/tasks/distant_lights.py",
        "rec.ambient = amb + frame.settings.ambient",
        "rec.ambient = 0.5 * amb + frame.settings.ambient",
        CLOSED,
        "the DomeLight at half strength",
    ),
    Mutant(
        "extra_distant_dropped",
        "shaders/common/sun.glsl",
        "for (int i = 0; i < int(u_ambient.w); ++i) {",
        "for (int i = 0; i < int(u_ambient.w) - 1; ++i) {",
        CLOSED,
        "the last of the extra (unshadowed) distant lights ignored",
    ),
    Mutant(
        "cone_linear_edge",
        "shaders/common/lights.glsl",
        "shape *= 1.0 - t * t * (3.0 - 2.0 * t);",
        "shape *= 1.0 - t;",
        CLOSED,
        "the soft cone edge linear instead of smoothstep",
    ),
    Mutant(
        "rect_area_square",
        "stb_hydra/scene/lights.py",
        "proj = area = lp.width * lp.height",
        "proj = area = lp.width * lp.width",
        CLOSED + LIGHTS,
        "RectLight intensity from width^2 (w h swapped for w w)",
    ),
    Mutant(
        "sphere_proj_area",
        "stb_hydra/scene/lights.py",
        "proj = math.pi * lp.radius**2\n",
        "proj = 2.0 * math.pi * lp.radius**2\n",
        CLOSED + LIGHTS,
        "SphereLight intensity from 2 pi r^2 instead of pi r^2",
    ),
    Mutant(
        "inverse_linear",
        "shaders/common/lights.glsl",
        "return range_window(dist, L.pos_range.w) / (r * r);",
        "return range_window(dist, L.pos_range.w) / (r * max(r, 1.0));",
        CLOSED,
        "inverse-square falloff clamped under 1 m (inverse-linear close to the light)",
    ),
    Mutant(
        "lambert_no_pi",
        "shaders/common/brdf.glsl",
        "diff = s.diffuse * (NoL / PI);",
        "diff = s.diffuse * NoL;",
        CLOSED,
        "Lambert BRDF without 1/pi",
    ),
    Mutant(
        "distant_angle_ignored",
        "stb_hydra/scene/lights.py",
        "return received / size if normalize else received",
        "return 1.0",
        (*LIGHTS, "tests/test_testdata_values.py"),
        "DistantLight angle ignored (E = L always)",
    ),
    Mutant(
        "exposure_ignored",
        "stb_hydra/scene/lights.py",
        "scalar = float(intensity) * 2.0 ** float(exposure) if ok else 0.0",
        "scalar = float(intensity) if ok else 0.0",
        CLOSED + LIGHTS,
        "inputs:exposure ignored",
    ),
    Mutant(
        "validate_exposure_off_by_one",
        "stb_hydra/validate/rules_lights.py",
        "if abs(c[0]) > limits.MAX_ABS_EXPOSURE:",
        "if abs(c[0]) >= limits.MAX_ABS_EXPOSURE:",
        VALIDATE,
        "validator: exposure exactly at the limit reported",
    ),
    Mutant(
        "validate_flux_range_open",
        "stb_hydra/validate/rules_photometry.py",
        "if math.isfinite(f) and lo <= f <= hi:",
        "if math.isfinite(f) and lo < f < hi:",
        VALIDATE,
        "validator: a light's flux exactly at the band ends reported",
    ),
    Mutant(
        "validate_shadow_count_ge",
        "stb_hydra/validate/rules_shadows.py",
        "if len(shadowed) > n_max:",
        "if len(shadowed) >= n_max:",
        VALIDATE,
        "validator: 8 shadowed lights per prefab reported",
    ),
    Mutant(
        "validate_dynamic_count_ge",
        "stb_hydra/validate/rules_shadows.py",
        "if len(dyn_on) > d_max:",
        "if len(dyn_on) >= d_max:",
        VALIDATE,
        "validator: 2 dynamic-shadow lights per prefab reported",
    ),
    Mutant(
        "validate_atlas_ge",
        "stb_hydra/validate/rules_shadows.py",
        "if frac > limits.VALIDATE_PREFAB_ATLAS_FRACTION_MAX:",
        "if frac >= limits.VALIDATE_PREFAB_ATLAS_FRACTION_MAX:",
        VALIDATE,
        "validator: exactly 25 % of the atlas reported",
    ),
    Mutant(
        "validate_cone_zero_ok",
        "stb_hydra/validate/rules_lights.py",
        "a <= 0.0 or a > prims.NO_CONE_ANGLE_DEG",
        "a < 0.0 or a > prims.NO_CONE_ANGLE_DEG",
        VALIDATE,
        "validator: a 0-degree cone accepted",
    ),
    Mutant(
        "validate_angle_scale_ge",
        "stb_hydra/validate/rules_lights.py",
        "if abs(s) > limits.VALIDATE_IES_ANGLE_SCALE_MAX:",
        "if abs(s) >= limits.VALIDATE_IES_ANGLE_SCALE_MAX:",
        VALIDATE,
        "validator: ies:angleScale exactly 10 reported as degrees",
    ),
    Mutant(
        "validate_units_rtol_min",
        "stb_hydra/validate/rules_units.py",
        "<= limits.VALIDATE_UNITS_RTOL * max(abs(a), abs(b))",
        "<= limits.VALIDATE_UNITS_RTOL * min(abs(a), abs(b))",
        VALIDATE,
        "validator: units tolerance relative to the smaller value (1 % apart reported)",
    ),
    Mutant(
        "exact_diffuse_ignored",
        "shaders/common/shadow.glsl",
        "vec3 c = (d * L.misc.z + sp * L.misc.w)",
        "vec3 c = (d + sp * L.misc.w)",
        CLOSED,
        "reference/tiled/clustered/lighttree (light_radiance, one place since the area-light "
        "refactor): the light's inputs:diffuse multiplier ignored",
    ),
    Mutant(
        "tiled_drops_last_light",
        "shaders/tiled_lighting.frag",
        "for (uint k = 0u; k < h.y; ++k) {",
        "for (uint k = 0u; k + 1u < h.y; ++k) {",
        CLOSED,
        "tiled/clustered: the last light of each tile's list skipped",
    ),
    Mutant(
        "shape_flipped",
        "shaders/common/area.glsl",
        "vec3 E = L.intensity.rgb * light_shape_rgb(L, -Ldir) * f;",
        "vec3 E = L.intensity.rgb * light_shape_rgb(L, Ldir) * f;",
        CLOSED,
        "every method (light_reflect, point model): the emission lobe evaluated towards the "
        "light instead of away from it",
    ),
    Mutant(
        "tradeoff_csv_tmp_left",
        "stb_hydra/io/files.py",
        "        tmp.unlink(missing_ok=True)\n        if isinstance(exc, OSError):",
        "        if isinstance(exc, OSError):",
        ("tests/test_atomic_writes.py",),
        "text writes (stb tradeoff's CSV, reports): the temporary file left behind on failure",
    ),
    # --- faults and fuzzing (issue 21, items 6-7): the bugs they found, put back -----
    Mutant(
        "image_not_read_back",
        "stb_hydra/io/images.py",
        "        _check_written(tmp, path)\n",
        "",
        ("tests/test_faults.py",),
        "a full disk's truncated EXR renamed into place with exit 0",
        True,
    ),
    Mutant(
        "sigterm_not_caught",
        "stb_hydra/apps/cli.py",
        "    old = _catch_sigterm()\n",
        "    old = None\n",
        ("tests/test_faults.py",),
        "SIGTERM kills stb render mid-write (no clean-up, no message)",
        True,
    ),
    Mutant(
        "validate_follows_symlink",
        "stb_hydra/validate/asset_paths.py",
        "    if not _inside(start, root):  # a symlink out of the library: never opened",
        "    if False:",
        ("tests/test_faults_validate.py",),
        "stb validate opens a symlinked asset outside the library root",
        True,
    ),
    Mutant(
        "validate_no_layer_limit",
        "stb_hydra/validate/asset_paths.py",
        "        if size > limits.VALIDATE_LAYER_MAX_BYTES:",
        "        if False:",
        ("tests/test_faults_validate.py",),
        "a 1 GB usdc opened by stb validate",
        True,
    ),
    Mutant(
        "camera_values_unchecked",
        "stb_hydra/scene/cameras.py",
        "        ok = _positive(value, default)",
        "        ok = value or default",
        ("tests/test_fuzz_regressions.py",),
        "camera focalLength inf / NaN apertures used as they are",
    ),
    Mutant(
        "mesh_xform_unchecked",
        "stb_hydra/renderer/render_prims.py",
        "        if not bad.any():",
        "        if True:",
        ("tests/test_fuzz_regressions.py",),
        "non-finite or float32-overflowing mesh transforms drawn",
    ),
    # --- estimator biases the convergence tests must see (issue 32: they run fewer
    # frames since; tests/convergence.py) ----------------------------------------------
    Mutant(
        "stb_select_one_floor",
        "shaders/stb_smalltile.frag",
        "float W = total / ph;",
        "float W = total / (ph + floor_ph);",
        (STB_UNBIASED,),
        "STB quad/pixel selection: the defensive floor counted twice in the pick's pdf",
    ),
    Mutant(
        "stb_stream_accept",
        "shaders/stb_smalltile.frag",
        "rng_float(rng) * total[j] <= w)",
        "rng_float(rng) * total[j] <= 0.9 * w)",
        (STB_UNBIASED,),
        "STB small-tile streams: a candidate replaces the pick with 0.9 of its probability",
    ),
    Mutant(
        "stb_stream_pdf_clamp",
        "shaders/stb_smalltile.frag",
        "total[j] / sel_p[j] : 0.0;",
        "total[j] / max(sel_p[j], 1.5 * floor_ph) : 0.0;",
        (STB_UNBIASED,),
        "STB small-tile streams: the pick's pdf clamped from below (dim candidates darker)",
    ),
    Mutant(
        "reuse_stream_accept",
        "shaders/common/reservoir.glsl",
        "if (u * s.wsum < w) {",
        "if (u * s.wsum < 0.9 * w) {",
        (REUSE_UNBIASED,),
        "reuse reservoirs: a candidate replaces the pick with 0.9 of its probability",
    ),
    Mutant(
        "reuse_share_mis_3pc",
        "shaders/common/reuse_share.glsl",
        "max(ws[k], 0.0) * P[k] / S : 0.0;",
        "max(ws[k], 0.0) * P[k] / (1.03 * S) : 0.0;",
        (REUSE_UNBIASED,),
        "reuse quad sharing: MIS weights summing to 0.97 (3 % dark)",
    ),
)


def tree_files(repo: Path) -> list[str]:
    out = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=repo,
        check=True,
        capture_output=True,
    ).stdout
    return [p for p in out.decode().split("\0") if p and (repo / p).is_file()]


def make_scratch(repo: Path) -> Path:
    scratch = Path(tempfile.mkdtemp(prefix="stb-mutation-"))
    for rel in tree_files(repo):
        dst = scratch / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(repo / rel, dst)
    link = scratch / "stb_hydra" / "shaders"
    if not link.exists():
        link.symlink_to(Path("..") / "shaders")
    return scratch


def run_tests(scratch: Path, tests: tuple[str, ...], timeout: float) -> tuple[bool, float, str]:
    """(passed, seconds, last lines) of pytest on ``tests`` in the scratch copy."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(scratch)
    env.setdefault("STB_SHARED", str((REPO.parent / "shared").resolve()))
    cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider"]
    cmd += ["-p", "no:randomly", *tests]
    t0 = time.perf_counter()
    try:
        r = subprocess.run(
            cmd, cwd=scratch, env=env, capture_output=True, text=True, timeout=timeout
        )
        ok, text = r.returncode == 0, r.stdout + r.stderr
    except subprocess.TimeoutExpired:
        ok, text = False, "timed out"
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    return ok, time.perf_counter() - t0, lines[-1] if lines else ""


def check_loaded_from(scratch: Path) -> None:
    """The copy's package and shaders are the ones imported (not the checkout's)."""
    code = (
        "import importlib.resources as r, stb_hydra;"
        "print(stb_hydra.__file__); print(r.files('stb_hydra.shaders'))"
    )
    env = dict(os.environ, PYTHONPATH=str(scratch))
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=scratch,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    if any(not line.startswith(str(scratch)) for line in out.split()):
        raise SystemExit(f"mutation_check: the scratch copy is not what gets imported:\n{out}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--list", action="store_true", help="print the mutants and exit")
    ap.add_argument("--only", default="", help="comma-separated mutant ids")
    ap.add_argument("--json", default="", help="write the report as JSON here")
    ap.add_argument(
        "--tests",
        default="",
        help="comma-separated test files run for every mutant instead of each one's own "
        "(e.g. the suite before a test was added, to show a mutant survived it)",
    )
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per test run")
    args = ap.parse_args(argv)

    mutants = list(MUTANTS)
    if args.tests:
        files = tuple(args.tests.split(","))
        mutants = [Mutant(m.id, m.path, m.old, m.new, files, m.what, m.listed) for m in mutants]
    if args.only:
        want = set(args.only.split(","))
        unknown = want - {m.id for m in mutants}
        if unknown:
            ap.error(f"unknown mutant(s): {', '.join(sorted(unknown))}")
        mutants = [m for m in mutants if m.id in want]
    if args.list:
        for m in mutants:
            print(f"{m.id:30s} {'issue' if m.listed else 'own  '}  {m.path}: {m.what}")
        return 0

    t_start = time.perf_counter()
    scratch = make_scratch(REPO)
    rows = []
    status = 0
    try:
        check_loaded_from(scratch)
        all_tests = tuple(sorted({t for m in mutants for t in m.tests}))
        ok, secs, last = run_tests(scratch, all_tests, args.timeout)
        print(f"baseline ({len(all_tests)} files): {'pass' if ok else 'FAIL'} {secs:.1f} s  {last}")
        if not ok:
            return 2
        for m in mutants:
            target = scratch / m.path
            original = target.read_text()
            n = original.count(m.old)
            if n != 1:
                print(f"{m.id:30s} NOT APPLIED ({n} matches of the old text in {m.path})")
                rows.append({"id": m.id, "result": "not applied", "matches": n})
                status = 2
                continue
            try:
                target.write_text(original.replace(m.old, m.new))
                passed, secs, last = run_tests(scratch, m.tests, args.timeout)
            finally:
                target.write_text(original)
            result = "SURVIVED" if passed else "killed"
            if passed:
                status = max(status, 1)
            print(f"{m.id:30s} {result:8s} {secs:6.1f} s  {last[:90]}")
            rows.append(
                {
                    "id": m.id,
                    "listed": m.listed,
                    "path": m.path,
                    "what": m.what,
                    "result": result,
                    "seconds": round(secs, 1),
                    "tests": list(m.tests),
                }
            )
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    total = time.perf_counter() - t_start
    killed = sum(r["result"] == "killed" for r in rows)
    survived = [r["id"] for r in rows if r["result"] == "SURVIVED"]
    print(
        f"{killed}/{len(rows)} killed, {len(survived)} survived"
        f"{' (' + ', '.join(survived) + ')' if survived else ''}; {total:.0f} s in all"
    )
    if args.json:
        Path(args.json).write_text(
            json.dumps({"mutants": rows, "seconds": round(total, 1)}, indent=2) + "\n"
        )
    return status


if __name__ == "__main__":
    sys.exit(main())
