"""IES LM-63 parser: real files, peers' published expectations, closed forms.

Expected values come from ../shared/testdata (ies/MANIFEST.md, the peers' tests under
parsers/, the files' own [DESCRIPTION]/[LAMP] keywords) or from closed forms; none is
copied from this parser's output.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from stb_hydra.limits import IES_MAX_ANGLES, IES_TABLE_PHI, IES_TABLE_THETA
from stb_hydra.scene.ies import IesError, IesProfile, load_ies, parse_ies

PI = math.pi

VALID_FILES = (
    "arnoldusd__test_0075_12.IES",
    "arnoldusd__test_0075_6.ies",
    "arnoldusd__test_1316_light.ies",
    "iesna__defined.ies",
    "iesna__medium-scatter.ies",
    "iesna__overhead.ies",
    "iesna__soft-arrow.ies",
    "lidrs__iesna2002_example_typec.ies",
    "luxcore__ASA_15M_R2.ies",
    "luxtest__bega_50988.6k3.ies",
    "luxtest__bega_84659K4.ies",
    "luxtest__bega_84693k4.ies",
    "luxtest__bega_omni001_1238lm.ies",
    "luxtest__bega_omni002_4777lm.ies",
    "luxtest__test_linear_vertical.ies",
    "luxtest__test_stripes_nonuniform.ies",
    "luxtest__test_stripes_uniform.ies",
    "mdlsdk__example_modules.ies",
    "mdlsdk__test.ies",
    "photon__1.ies",
    "photon__7.ies",
    "photon__9.IES",
    "photon__L1768-65BR30FL_FL55.ies",
    "photon__constant_point5_candela.IES",
    "rpr__ies_light_1.ies",
    "rpr__ies_light_2.ies",
    "wagyx__CB1210-2LF13.IES",
    "wagyx__CB1900-NGT.IES",
)
BAD_FILE = "mdlsdk__test_file_format_error.ies"


def make_ies(
    v,
    h,
    cd,
    *,
    ptype: int = 1,
    mult: float = 1.0,
    ballast: float = 1.0,
    lumens: float = -1.0,
    first: str = "IESNA:LM-63-2002",
    tilt: str = "TILT=NONE",
) -> str:
    """An LM-63 text for a grid; ``cd`` broadcasts to (len(h), len(v))."""
    cd = np.broadcast_to(np.asarray(cd, dtype=float), (len(h), len(v)))
    fmt = lambda a: " ".join(repr(float(x)) for x in a)  # noqa: E731
    rows = [
        first,
        "[TEST] inline",
        tilt,
        f"1 {lumens} {mult} {len(v)} {len(h)} {ptype} 2 0 0 0",
        f"{ballast} 1.0 10",
        fmt(v),
        fmt(h),
        *(fmt(r) for r in cd),
    ]
    return "\n".join(rows) + "\n"


@pytest.fixture(scope="session")
def ies_dir(testdata: Path) -> Path:
    return testdata / "ies"


@pytest.fixture(scope="session")
def profiles(ies_dir: Path) -> dict[str, IesProfile]:
    return {f: load_ies(ies_dir / f) for f in VALID_FILES}


@pytest.fixture(scope="session")
def manifest(ies_dir: Path) -> dict[str, dict]:
    """MANIFEST.md table rows + the 'first line: ...; lumens/lamp X; units Y' notes."""
    text = (ies_dir / "MANIFEST.md").read_text(encoding="utf-8")
    rows: dict[str, dict] = {}
    for line in text.splitlines():
        if line.startswith("| `"):
            c = [x.strip() for x in line.strip().strip("|").split("|")]
            rows[c[0].strip("`")] = dict(
                version=c[2],
                tilt=c[3],
                type=c[4],
                vxh=c[5],
                vrange=c[6],
                hrange=c[7],
                symmetry=c[8],
                flags=c[9],
            )
    for m in re.finditer(
        r"### (\S+)\n(?:- .*\n)*?- first line: `(.*)`; lumens/lamp (\S+); "
        r"units (ft|m);",
        text,
    ):
        rows[m.group(1)].update(
            first_line=m.group(2), lumens=float(m.group(3)), units=1 if m.group(4) == "ft" else 2
        )
    return rows


# --- every real file -----------------------------------------------------------------------


def test_file_set_matches(ies_dir: Path) -> None:
    found = {p.name for p in ies_dir.iterdir() if p.suffix.lower() == ".ies"}
    assert found == {*VALID_FILES, BAD_FILE}


@pytest.mark.parametrize("fname", VALID_FILES)
def test_real_file_matches_manifest(fname: str, profiles, manifest) -> None:
    p, row = profiles[fname], manifest[fname]
    year = re.match(r"\d{4}", row["version"]).group(0)
    assert p.version == f"LM-63-{year}"
    assert p.tilt == row["tilt"]
    assert p.photometric_type == {"C": 1, "B": 2, "A": 3}[row["type"]]
    n_v, n_h = (int(x) for x in row["vxh"].split("x"))
    assert p.vertical_angles.shape == (n_v,) and p.horizontal_angles.shape == (n_h,)
    assert p.candela_raw.shape == (n_h, n_v)
    v0, v1 = (float(x) for x in row["vrange"].split(".."))
    h0, h1 = (float(x) for x in row["hrange"].split(".."))
    assert (p.vertical_angles[0], p.vertical_angles[-1]) == (v0, v1)
    assert (p.horizontal_angles[0], p.horizontal_angles[-1]) == (h0, h1)
    sym = row["symmetry"].split(" ")[0]
    expected_sym = {
        "axial": "axial",
        "quadrant": "quadrant",
        "full": "full",
        "H": "none",
        "bilateral": "bilateral" if "0-180" in row["symmetry"] else "bilateral_90_270",
    }
    assert p.symmetry == expected_sym[sym]
    assert p.lumens_per_lamp == pytest.approx(row["lumens"], rel=1e-5)
    assert p.units_type == row["units"]
    lamps = re.search(r"n_lamps=(\d+)", row["flags"])
    assert p.n_lamps == (int(lamps.group(1)) if lamps else 1)
    mult = re.search(r"mult=([\d.]+)", row["flags"])
    assert p.multiplier == pytest.approx(float(mult.group(1)) if mult else 1.0)
    if p.version == "LM-63-1986":
        assert p.labels and p.labels[0].startswith(row["first_line"].strip())
    assert p.name.endswith(fname)
    assert p.warnings == []
    assert np.all(np.isfinite(p.candela)) and np.all(p.candela >= 0.0)


def test_format_error_file_is_rejected(ies_dir: Path) -> None:
    with pytest.raises(IesError) as e:
        load_ies(ies_dir / BAD_FILE)
    msg = str(e.value)
    assert BAD_FILE in msg and "\n" not in msg and "'file'" in msg


def test_missing_and_unreadable_paths(tmp_path: Path) -> None:
    missing = tmp_path / "nope" / "missing.ies"
    with pytest.raises(IesError, match=re.escape(str(missing))):
        load_ies(missing)
    with pytest.raises(IesError, match=re.escape(str(tmp_path))):
        load_ies(tmp_path)  # a directory


# --- Photon-v2 ies_file_loading_test.cpp -------------------------------------------------


def test_photon_parse_1995_files(profiles) -> None:
    f1 = profiles["photon__1.ies"]
    assert f1.version == "LM-63-1995"
    assert f1.keywords["TEST"] == "3310_1 BY: ERCO / LUM650"  # Photon keeps a leading space
    assert f1.keywords["MANUFAC"] == "ERCO Leuchten GmbH"
    assert f1.keywords["LUMCAT"] == "83479000"
    assert f1.keywords["LUMINAIRE"] == "Panarc Corridor luminaire"
    assert f1.keywords["LAMPCAT"] == "TC-F 36W"
    assert (f1.n_lamps, f1.lumens_per_lamp, f1.multiplier) == (1, 2700.0, 1.0)
    c = f1.candela_raw
    assert c.shape == (7, 19)
    np.testing.assert_allclose([c[0][0], c[0][1], c[0][2], c[0][-1]], [197.8, 213.8, 275.2, 1.1])
    np.testing.assert_allclose([c[2][0], c[2][2], c[2][5], c[2][-1]], [197.8, 250.0, 412.3, 1.1])
    np.testing.assert_allclose([c[-1][0], c[-1][1], c[-1][3], c[-1][-1]], [197.8, 197.4, 193.2, 0])

    f2 = profiles["photon__7.ies"]
    assert (f2.version, f2.n_lamps, f2.lumens_per_lamp, f2.multiplier) == (
        "LM-63-1995",
        1,
        4450.0,
        1.0,
    )
    c = f2.candela_raw
    assert c.shape == (7, 37)
    for row in (c[0], c[2], c[-1]):
        assert row[0] == row[1] == row[2] == row[3] == row[5] == 0.0
        assert row[-1] == pytest.approx(1054.2)

    f3 = profiles["photon__L1768-65BR30FL_FL55.ies"]
    assert (f3.version, f3.n_lamps, f3.lumens_per_lamp) == ("LM-63-1995", 1, 635.0)
    assert f3.multiplier == pytest.approx(0.1)
    c = f3.candela_raw
    assert c.shape == (9, 73)
    np.testing.assert_allclose([c[0][0], c[0][1], c[0][2], c[0][-1]], [5453, 5669, 5798, 0])
    np.testing.assert_allclose([c[2][0], c[2][2], c[2][5], c[2][-1]], [5453, 5640, 5084, 0])
    np.testing.assert_allclose([c[-1][0], c[-1][1], c[-1][3], c[-1][-1]], [5453, 5178, 4400, 0])
    assert f3.candela[0][0] == pytest.approx(545.3)  # the caller's multiplier, applied


def test_photon_constant_point5_normalised_attenuation(profiles) -> None:
    p = profiles["photon__constant_point5_candela.IES"]
    # Photon's "normalised attenuation" is the profile over its peak; our normalisation
    # (shaping:ies:normalize) divides by the mean over the sphere: 0.5 x 2pi / 4pi
    assert p.is_hemispherical and p.power() == pytest.approx(0.25, rel=1e-12)
    cases = [
        ((0, 0), 1.0),
        ((PI, 0), 0.0),
        ((0, PI), 1.0),
        ((PI, PI), 0.0),
        ((2 * PI, 2 * PI), 0.0),
        ((2 * PI, 4 * PI), 0.0),
        ((-2 * PI, -4 * PI), 1.0),
        ((PI / 2, PI), 1.0),
    ]
    for (theta, phi), expected in cases:
        assert p.sample(theta, phi) / p.max_candela() == pytest.approx(expected, abs=1e-4)


# --- photometric-viewer tests/photometry/ies95 -------------------------------------------

PV_VERTICAL = [
    0.0,
    2.5,
    5.0,
    7.5,
    10.0,
    12.5,
    15.0,
    17.5,
    20.0,
    22.5,
    25.0,
    27.5,
    30.0,
    32.5,
    35.0,
    37.5,
    40.0,
    42.5,
    45.0,
    47.5,
    50.0,
    52.5,
    55.0,
    57.5,
    60.0,
    62.5,
    65.0,
    67.5,
    70.0,
    72.5,
    75.0,
    77.5,
    80.0,
    82.5,
    85.0,
    87.5,
    90.0,
]
PV_INTENSITIES = [
    2200.0,
    2000.2,
    1950.0,
    1700.1,
    1328.4,
    1115.1,
    900.5,
    700.4,
    600.3,
    501.2,
    400.1,
    398.3,
    380.9,
    400.2,
    390.5,
    320.0,
    185.0,
    100.6,
    40.1,
    20.0,
    15.2,
    15.0,
    14.0,
    11.0,
    10.8,
    10.8,
    10.0,
    7.0,
    4.0,
    1.2,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    1.0,
    0.0,
]
# file stem -> (lumens/lamp, multiplier, units, width, length, height) as written in the files
PV_FILES = {
    "absolute_photometry": (-1, 1.0, 2, -0.12, 0, 0),
    "absolute_photometry_with_multiplier": (-1, 1.5, 2, -0.12, 0, 0),
    "ellipse_opening_along_length": (-1, 1.0, 2, -0.12, 0.34, 0.56),
    "ellipse_opening_along_width": (-1, 1.0, 2, 0.12, -0.34, 0.56),
    "ellipsoid_opening_along_length": (-1, 1.0, 2, -0.12, 0.34, -0.56),
    "ellipsoid_opening_along_width": (-1, 1.0, 2, 0.12, -0.34, -0.56),
    "horizontal_cylinder_opening_along_length": (-1, 1.0, 2, 0, 0.12, -0.34),
    "horizontal_cylinder_opening_along_width": (-1, 1.0, 2, 0.12, 0, -0.34),
    "imperial_units": (-1, 1.0, 1, 0.12, 0.34, 0.56),
    "label_lines": (-1, 1.0, 1, 0.12, 0.34, 0.56),
    "metric_units": (-1, 1.0, 2, 0.12, 0.34, 0.56),
    "point_opening": (-1, 1.0, 2, 0, 0, 0),
    "rectangular_opening": (-1, 1.0, 2, 0.12, 0.34, 0),
    "rectangular_opening_with_height": (-1, 1.0, 2, 0.12, 0.34, 0.56),
    "relative_photometry": (500, 1.0, 2, -0.12, 0, 0),
    "relative_photometry_with_multiplier": (500, 1.5, 2, -0.12, 0, 0),
    "round_opening": (-1, 1.0, 2, -0.12, 0, 0),
    "round_opening_with_height": (-1, 1.0, 2, -0.12, 0, 0.34),
    "sphere_opening": (-1, 1.0, 2, -0.12, 0, -0.12),
}
# photometric-viewer converter.py: LM-63-2002 opening shape from the signs of (w, l, h)
PV_SHAPE_SIGNS = {
    "point": (0, 0, 0),
    "rectangular": (1, 1, 0),
    "round": (-1, 0, 0),
    "sphere": (-1, 0, -1),
    "horizontal_cylinder_opening_along_length": (0, 1, -1),
    "horizontal_cylinder_opening_along_width": (1, 0, -1),
    "ellipse_opening_along_length": (-1, 1, 1),
    "ellipse_opening_along_width": (1, -1, 1),
    "ellipsoid_opening_along_length": (-1, 1, -1),
    "ellipsoid_opening_along_width": (1, -1, -1),
}


@pytest.mark.parametrize("stem", sorted(PV_FILES))
def test_photometric_viewer_raw_fields(stem: str, testdata: Path) -> None:
    path = testdata / "parsers/photometric-viewer/tests/data/photometrics/ies95" / f"{stem}.ies"
    p = load_ies(path)
    lumens, mult, units, w, length, h = PV_FILES[stem]
    assert p.version == "LM-63-1995" and p.tilt == "NONE"
    assert (p.n_lamps, p.lumens_per_lamp, p.multiplier) == (1, lumens, mult)
    assert (p.photometric_type, p.units_type) == (1, units)
    assert (p.width, p.length, p.height) == (w, length, h)
    assert (p.ballast_factor, p.file_generation_type, p.input_watts) == (1.0, 1.0, 15.0)
    assert p.vertical_angles.tolist() == PV_VERTICAL
    assert p.horizontal_angles.tolist() == [0.0]
    assert p.candela_raw.tolist() == [PV_INTENSITIES]
    np.testing.assert_allclose(p.candela[0], np.array(PV_INTENSITIES) * mult)
    for shape, signs in PV_SHAPE_SIGNS.items():
        if stem.startswith(shape) and "with_height" not in stem:
            assert tuple(np.sign([p.width, p.length, p.height])) == signs
    if stem == "label_lines":
        assert p.keywords["MULTILINE"] == (
            "Test multiline metadata\nShould contain three lines\nDivided by LF characters"
        )
        assert p.keywords["BALLASTCAT"] == "BC15345"
    else:
        assert p.keywords["LUMINAIRE"] == (
            "Dummy IES file.\nCan be used for example for testing the software, create "
            "screenshots, etc.\nLicensed under MIT License"
        )


PV_HEADER = """
    IESNA:LM-63-1995
    [TEST] Photometry test file
    TILT=NONE
    1 -1 1.0 37 {n_h} 1 2 -0.12 0.34 -0.56
    1.0 1.0 15
"""
PV_V = (
    "0.0 2.5 5.0 7.5 10.0 12.5 15.0 17.5 20.0 22.5 25.0 27.5 30.0 32.5 35.0 37.5 40.0 "
    "42.5 45.0 47.5 50.0 52.5 55.0\n57.5 60.0 62.5 65.0 67.5 70.0 72.5 75.0 77.5 80.0 "
    "82.5 85.0 87.5 {last}\n"
)
PV_I = (
    "2200.0 2000.2 1950.0 1700.1 1328.4 1115.1 900.5 700.4 600.3 501.2 400.1 398.3 "
    "380.9 400.2 390.5 320.0 185.0 100.6 40.1\n20.0 15.2 15.0 14.0 11.0 10.8 10.8 10.0 7.0 "
    "4.0 1.2 0.0 0.0 0.0 0.0 0.0 1.0 {tail}\n"
)


def _pv(n_h=1, last="90.0", h="0.0", first_i="2200.0", tail="0.0") -> str:
    body = PV_HEADER.format(n_h=n_h) + PV_V.format(last=last) + h + "\n"
    return body + PV_I.replace("2200.0", first_i, 1).format(tail=tail)


def test_photometric_viewer_extractor_cases() -> None:
    p = parse_ies(_pv())  # test_complete_file (indented lines, leading blank line)
    assert p.keywords == {"TEST": "Photometry test file"}
    assert p.vertical_angles.tolist() == PV_VERTICAL
    assert p.candela_raw.tolist() == [PV_INTENSITIES]
    assert (p.width, p.length, p.height) == (-0.12, 0.34, -0.56)
    assert p.warnings == []
    extra = parse_ies(_pv(tail="0.0 1.0 1.0 1.0 1.0"))  # test_extra_intensities: tolerated
    assert extra.candela_raw.tolist() == [PV_INTENSITIES]
    assert any("4 extra token" in w for w in extra.warnings)
    bad = {
        "missing_v_angles": _pv(last=""),
        "invalid_v_angles": _pv().replace("0.0 2.5", "Zero 2.5s", 1),
        "missing_h_angles": _pv(n_h=2),
        "invalid_h_angles": _pv(h="Zero"),
        "missing_intensities": _pv(tail=""),
        "invalid_intensities": _pv(first_i="2200.0 a2000.2 1950a.0 1700.1a None"),
        "empty_file": "",
        "header_only_file": "IESNA:LM-63-1995",
        "tilt_only_file": "\n    IESNA:LM-63-1995\n    TILT=NONE\n",
    }
    for case, text in bad.items():
        with pytest.raises(IesError, match=f"^{case}: "):
            parse_ies(text, name=case)


def test_photometric_viewer_metadata_joining() -> None:
    header = (
        "IESNA:LM-63-1995\n[KEY] Value\n[KEY] Value 2\n[OTHER_KEY] Other Value\n"
        "[Multiple Words]\n[MULTILINE_PROPERTY2] First line\n[MORE] Second line\n"
        "[MORE] Third line\n"
    )
    p = parse_ies(header + make_ies([0, 90], [0], 1.0).split("\n", 2)[2])
    assert p.keywords == {
        "KEY": "Value\nValue 2",
        "OTHER_KEY": "Other Value",
        "Multiple Words": "",
        "MULTILINE_PROPERTY2": "First line\nSecond line\nThird line",
    }


# --- lidrs src/io/ies/tests.rs -----------------------------------------------------------

LIDRS_IESNA_1991_FILE = """IESNA91
[TEST] Simple demo intensity distribution 
[MANUFAC] Lightscape Technologies, Inc.
TILT=NONE
1
-1
1
8
1
1
2
0.0 0.0 0.0
1.0 1.0 0.0
0.0 5.0 10.0 20.0 30.0 45.0 65.0 90.0
0.0
1000.0 1100.0 1300.0 1150.0 930.0 650.0 350.0 0.0
"""  # noqa: W291  (verbatim test data: trailing space after 'distribution')


def test_lidrs_basic_parse() -> None:
    p = parse_ies(LIDRS_IESNA_1991_FILE)
    assert p.version == "LM-63-1991"
    assert p.multiplier == 1.0
    assert (p.horizontal_angles.size, p.vertical_angles.size) == (1, 8)
    assert p.units_type == 2
    assert (p.width, p.length, p.height) == (0.0, 0.0, 0.0)
    assert p.vertical_angles.tolist() == [0.0, 5.0, 10.0, 20.0, 30.0, 45.0, 65.0, 90.0]
    assert p.horizontal_angles.tolist() == [0.0]
    assert p.candela_raw.ravel().tolist() == [
        1000.0,
        1100.0,
        1300.0,
        1150.0,
        930.0,
        650.0,
        350.0,
        0.0,
    ]
    assert p.keywords["TEST"] == "Simple demo intensity distribution"


def test_lidrs_iesna2002_example(profiles) -> None:
    p = profiles["lidrs__iesna2002_example_typec.ies"]
    kw = p.keywords
    assert len(kw) == 16
    assert kw["TEST"] == "ABC1234" and kw["MAINTCAT"] == "4"
    assert kw["_NEMATYPE"] == "4h x 6v" and kw["_PRICE"] == "Make us an offer"
    # lidrs joins [MORE] with a space; this API joins with "\n" (appleseed, photometric-viewer)
    assert kw["OTHER"].replace("\n", " ") == (
        "This luminaire is useful as an indirect flood and to reduce light pollution in down "
        "light applications."
    )
    # TILT=INCLUDE block (lidrs VALUES_TEST) and the data after it stays aligned
    assert (p.tilt, p.tilt_geometry) == ("INCLUDE", 1)
    np.testing.assert_array_equal(p.tilt_angles, np.arange(0.0, 181.0, 15.0))
    np.testing.assert_allclose(
        p.tilt_factors, [1.0, 0.95, 0.94, 0.90, 0.88, 0.87, 0.98, 0.87, 0.88, 0.90, 0.94, 0.95, 1.0]
    )
    assert (p.n_lamps, p.lumens_per_lamp, p.multiplier) == (1, 50000.0, 1.0)
    assert (p.width, p.length, p.height, p.units_type) == (0.5, 0.6, 0.0, 1)
    assert p.input_watts == 495.0
    assert p.vertical_angles.tolist() == [0, 22.5, 45, 67.5, 90]
    assert p.horizontal_angles.tolist() == [0, 45, 90]
    assert p.candela_raw.tolist() == [
        [100000, 50000, 25000, 10000, 5000],
        [100000, 35000, 16000, 8000, 3000],
        [100000, 20000, 10000, 5000, 1000],
    ]
    # lidrs photweb: quadrant symmetry resolves into 8 planes (0, 45, ..., 315)
    theta = np.radians(p.vertical_angles)
    for k, plane in enumerate(range(0, 360, 45)):
        row = [0, 1, 2, 1][k % 4]
        np.testing.assert_allclose(p.sample(theta, math.radians(plane)), p.candela[row])


# --- MDL SDK, appleseed --------------------------------------------------------------------


def test_mdlsdk_type_b_loads(profiles) -> None:
    p = profiles["mdlsdk__test.ies"]
    assert p.photometric_type == 2 and p.lumens_per_lamp == 0.0
    # Type B: nadir is (H 0, V 0): halfway between the V = -90 and V = 90 columns of H = 0
    assert p.sample(0.0, 0.0) == pytest.approx(0.55)
    # photometric horizontal (+X) is (H 0, V 90)
    assert p.sample(PI / 2, 0.0) == pytest.approx(0.6)
    assert p.sample(PI, 0.0) == 0.0  # V = 180: behind the listed -90..90 planes


@pytest.mark.parametrize(
    ("first", "version"),
    [
        ("IESNA91", "LM-63-1991"),
        ("IESNA:LM-63-1995", "LM-63-1995"),
        ("IESNA:LM-63-2002", "LM-63-2002"),
        ("IESNA: LM-63-2002", "LM-63-2002"),
        ("IES:LM-63-2019", "LM-63-2019"),
        ("Some free text", "LM-63-1986"),
        ("IESNA", "LM-63-1986"),
    ],
)
def test_appleseed_version_detection(first: str, version: str) -> None:
    p = parse_ies(make_ies([0, 90], [0], 1.0, first=first))
    assert p.version == version
    assert p.labels == ([first] if version == "LM-63-1986" else [])


def test_appleseed_numbers() -> None:
    text = make_ies([0, 90], [0], 2.0, mult=0.5)
    assert parse_ies(text.replace(" 0.5 ", " 1e-1 ", 1)).multiplier == pytest.approx(0.1)
    assert parse_ies(text.replace(" 0.5 ", " 5E-01 ", 1)).multiplier == pytest.approx(0.5)
    with pytest.raises(IesError, match="'\\+' is not a number"):
        parse_ies(text.replace(" 0.5 ", " + 3.0 ", 1))
    with pytest.raises(IesError, match="integer"):
        parse_ies(text.replace("\n1 -1.0 ", "\n1.5 -1.0 ", 1))


def test_appleseed_more_joining() -> None:
    p = parse_ies(
        "IESNA:LM-63-1995\n[TEST] a\n[MORE] b\n[MORE]c\n"
        + make_ies([0, 90], [0], 1.0).split("\n", 2)[2]
    )
    assert p.keywords["TEST"] == "a\nb\nc"


# --- luxtest synthetic files ----------------------------------------------------------------


def test_stripes_uniform_and_nonuniform_identical(profiles) -> None:
    uni = profiles["luxtest__test_stripes_uniform.ies"]
    non = profiles["luxtest__test_stripes_nonuniform.ies"]
    assert "identically" in non.keywords["DESCRIPTION4"]
    # Both files hold the stripes as plateaus joined by 1-degree linear edges (9->10,
    # 19->20, ...), so the bilinear profiles coincide everywhere, edges included.
    theta = np.radians(np.linspace(0.0, 180.0, 36001))
    for phi in (0.0, 1.0, 4.0):
        np.testing.assert_allclose(uni.sample(theta, phi), non.sample(theta, phi), atol=1e-9)
    np.testing.assert_allclose(uni.bake_table(), non.bake_table(), atol=1e-6)
    # [DESCRIPTION2/3]: bottom cap (0..9) .25, top cap (170..180) .75, stripes every 10 deg
    centres = np.radians([4.5, 15, 25, 35, 95, 105, 165, 175])
    for p in (uni, non):
        np.testing.assert_allclose(p.sample(centres, 0.3), [0.25, 1, 0, 1, 1, 0, 0, 0.75])


def test_linear_vertical_ramp(profiles) -> None:
    p = profiles["luxtest__test_linear_vertical.ies"]
    assert "0=>1 and 180=>0" in p.keywords["DESCRIPTION"]
    theta = np.linspace(0.0, PI, 721)
    for phi in (0.0, 2.0, 5.5):
        np.testing.assert_allclose(p.sample(theta, phi), 1.0 - theta / PI, atol=1e-12)
    assert p.power() == pytest.approx(0.5)  # mean of (1 + cos t)/2 over the sphere


# --- symmetry unfolding on real files ----------------------------------------------------

RNG = np.random.default_rng(1234)
THETA = RNG.uniform(0.0, PI, 400)
PHI = RNG.uniform(0.0, 2 * PI, 400)


@pytest.mark.parametrize(
    "fname",
    ["photon__1.ies", "iesna__overhead.ies", "arnoldusd__test_0075_12.IES", "photon__7.ies"],
)
def test_quadrant_symmetry(fname: str, profiles) -> None:
    p = profiles[fname]
    ref = p.sample(THETA, PHI)
    for mirrored in (PI - PHI, PI + PHI, 2 * PI - PHI, -PHI):
        np.testing.assert_allclose(p.sample(THETA, mirrored), ref, rtol=1e-12, atol=1e-12)
    assert ref.max() > 0.0


@pytest.mark.parametrize(
    "fname",
    [
        "photon__L1768-65BR30FL_FL55.ies",
        "luxcore__ASA_15M_R2.ies",
        "iesna__medium-scatter.ies",
        "wagyx__CB1900-NGT.IES",
    ],
)
def test_bilateral_0_180_symmetry(fname: str, profiles) -> None:
    p = profiles[fname]
    np.testing.assert_allclose(
        p.sample(THETA, 2 * PI - PHI), p.sample(THETA, PHI), rtol=1e-12, atol=1e-12
    )
    # listed planes are reproduced exactly, mirrored planes too
    theta = np.radians(p.vertical_angles)
    for k in (0, len(p.horizontal_angles) // 2, -1):
        phi = math.radians(p.horizontal_angles[k])
        np.testing.assert_allclose(p.sample(theta, phi), p.candela[k], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(
            p.sample(theta, 2 * PI - phi), p.candela[k], rtol=1e-12, atol=1e-9
        )
    assert not np.allclose(p.sample(theta, 0.0), p.sample(theta, PI / 2))  # really asymmetric


def test_bilateral_90_270_bega(profiles) -> None:
    p = profiles["luxtest__bega_84659K4.ies"]
    h = p.horizontal_angles
    assert (h[0], h[-1]) == (90.0, 270.0)
    theta = np.radians(p.vertical_angles)
    np.testing.assert_allclose(p.sample(THETA, PI - PHI), p.sample(THETA, PHI), rtol=1e-12)
    for angle in (90.0, 180.0, 205.0, 270.0):  # listed planes
        k = int(np.flatnonzero(h == angle)[0])
        np.testing.assert_allclose(p.sample(theta, math.radians(angle)), p.candela[k])
    # C0 mirrors C180, C315 mirrors C225 (about the 90-270 plane)
    k180, k225 = (int(np.flatnonzero(h == a)[0]) for a in (180.0, 225.0))
    np.testing.assert_allclose(p.sample(theta, 0.0), p.candela[k180])
    np.testing.assert_allclose(p.sample(theta, math.radians(315.0)), p.candela[k225])
    assert not np.allclose(p.candela[0], p.candela[-1])  # C90 != C270: a real asymmetry


@pytest.mark.parametrize("fname", ["rpr__ies_light_1.ies", "rpr__ies_light_2.ies"])
def test_full_0_360_seam_continuous(fname: str, profiles) -> None:
    p = profiles[fname]
    theta = np.linspace(0.0, PI, 997)
    for eps in (1e-9, 1e-6):
        np.testing.assert_allclose(
            p.sample(theta, 2 * PI - eps), p.sample(theta, eps), rtol=1e-6, atol=1e-9
        )
    np.testing.assert_allclose(p.sample(theta, 2 * PI), p.sample(theta, 0.0))


def test_full_range_interpolates_across_seam() -> None:
    v = [0.0, 90.0, 180.0]
    planes = np.array([[1.0], [2.0], [3.0], [5.0]])  # C0, C90, C180, C270 (no C360 entry)
    p = parse_ies(make_ies(v, [0, 90, 180, 270], planes))
    phi = np.radians([0, 45, 90, 135, 180, 225, 270, 315, 337.5, 359.0, -45.0])
    expected = [1, 1.5, 2, 2.5, 3, 4, 5, 3, 2, 1 + 4 / 90, 3]
    np.testing.assert_allclose(p.sample(PI / 3, phi), expected, rtol=1e-12)
    assert any("no LM-63 symmetry" in w for w in p.warnings)
    # the same distribution written 0..360 with a duplicated C360 plane
    q = parse_ies(make_ies(v, [0, 90, 180, 270, 360], np.vstack([planes, [[1.0]]])))
    np.testing.assert_allclose(q.sample(THETA, PHI), p.sample(THETA, PHI), rtol=1e-12)
    assert q.symmetry == "full" and q.warnings == []


def test_vertical_range_outside_is_zero() -> None:
    down = parse_ies(make_ies([0, 45, 90], [0], [[3.0, 2.0, 1.0]]))
    np.testing.assert_allclose(
        down.sample(np.radians([0, 45, 90, 90.001, 135, 180]), 0.0), [3, 2, 1, 0, 0, 0]
    )
    up = parse_ies(make_ies([90, 135, 180], [0], [[1.0, 2.0, 3.0]]))
    np.testing.assert_allclose(
        up.sample(np.radians([0, 89.999, 90, 135, 180]), 1.0), [0, 0, 1, 2, 3]
    )
    sub = parse_ies(make_ies([20, 40], [0], [[1.0, 3.0]]))
    np.testing.assert_allclose(sub.sample(np.radians([10, 20, 30, 40, 50]), 0.0), [0, 1, 2, 3, 0])


# --- Type A / Type B frames ----------------------------------------------------------------


def test_type_b_frame_and_mirror() -> None:
    v = np.arange(-90.0, 91.0, 15.0)
    h = np.arange(-90.0, 91.0, 15.0)
    by_v = parse_ies(make_ies(v, h, v[None, :] + 90.0, ptype=2))  # cd = V + 90
    theta = np.radians([0, 10, 45, 80, 90])
    # in the plane through nadir and +X: H = 0, V = theta
    np.testing.assert_allclose(by_v.sample(theta, 0.0), np.degrees(theta) + 90.0, atol=1e-9)
    np.testing.assert_allclose(by_v.sample(theta, PI), 90.0 - np.degrees(theta), atol=1e-9)
    assert by_v.sample(PI - 0.01, 0.0) == 0.0  # upper hemisphere: |V| > 90
    by_h = parse_ies(make_ies(v, h, (h[:, None] + 90.0) * np.ones((1, v.size)), ptype=2))
    # H is the latitude towards -Y (clockwise): +Y is H = -90, -Y is H = +90
    np.testing.assert_allclose(by_h.sample(PI / 2, [PI / 2, -PI / 2, 0.0]), [0, 180, 90], atol=1e-9)
    # laterally symmetric file (H 0..90) == the explicit -90..90 file
    half = parse_ies(
        make_ies(v, h[h >= 0], np.abs(h[h >= 0])[:, None] + v[None, :] / 100 + 1, ptype=2)
    )
    full = parse_ies(make_ies(v, h, np.abs(h)[:, None] + v[None, :] / 100 + 1, ptype=2))
    assert half.symmetry == "lateral"
    np.testing.assert_allclose(half.sample(THETA, PHI), full.sample(THETA, PHI), rtol=1e-12)
    np.testing.assert_allclose(half.sample(THETA, -PHI), half.sample(THETA, PHI), rtol=1e-12)
    assert half.flux() == pytest.approx(full.flux(), rel=1e-12)


def test_type_a_frame() -> None:
    v = np.arange(-90.0, 91.0, 10.0)
    h = np.arange(-90.0, 91.0, 10.0)
    by_v = parse_ies(make_ies(v, h, v[None, :] + 90.0, ptype=3))  # cd = V + 90
    theta = np.linspace(0.0, PI, 19)
    # V is the elevation: -90 at nadir, 0 at the horizon, 90 at the zenith
    np.testing.assert_allclose(by_v.sample(theta, 0.3), np.degrees(theta), atol=1e-9)
    by_h = parse_ies(make_ies(v, h, (h[:, None] + 90.0) * np.ones((1, v.size)), ptype=3))
    # H is the longitude from +X, clockwise seen from above (towards -Y)
    np.testing.assert_allclose(
        by_h.sample(PI / 2, np.radians([0, 30, -30, 90, -90])), [90, 60, 120, 0, 180], atol=1e-9
    )
    assert by_h.sample(PI / 2, PI) == 0.0  # behind: |H| > 90


# --- power / flux ---------------------------------------------------------------------------


def _brute_flux(p: IesProfile, n: int = 1200) -> float:
    """Midpoint rule in (theta, phi) on sample(): independent of the hat-function code."""
    t = (np.arange(n) + 0.5) * PI / n
    f = (np.arange(2 * n) + 0.5) * PI / n
    return float(np.sum(p.sample(t[:, None], f[None, :]) * np.sin(t)[:, None]) * (PI / n) ** 2)


def test_power_flux_closed_forms() -> None:
    sphere = parse_ies(make_ies([0, 30, 180], [0], 7.0))
    assert not sphere.is_hemispherical
    assert sphere.flux() == pytest.approx(4 * PI * 7.0, rel=1e-12)
    assert sphere.power() == pytest.approx(7.0, rel=1e-12)
    one = parse_ies(make_ies(np.linspace(0, 180, 37), [0, 90, 180, 270, 360], 1.0))
    assert one.flux() == pytest.approx(4 * PI, rel=1e-12)
    hemi = parse_ies(make_ies([0, 10, 90], [0, 45, 90], 3.0))
    assert hemi.is_hemispherical
    assert hemi.flux() == pytest.approx(2 * PI * 3.0, rel=1e-12)
    assert hemi.power() == pytest.approx(1.5, rel=1e-12)  # mean over the sphere: 3 x 2pi / 4pi
    up = parse_ies(make_ies([90, 180], [0], 2.0))
    assert up.is_hemispherical and up.power() == pytest.approx(1.0, rel=1e-12)
    # multiplier and ballast are applied, n_lamps is not
    scaled = parse_ies(make_ies([0, 180], [0], 2.0, mult=3.0, ballast=0.5))
    assert scaled.power() == pytest.approx(3.0, rel=1e-12)
    assert scaled.max_candela() == pytest.approx(3.0)
    # cosine lobe I0 cos(theta) over the lower hemisphere: flux = pi I0 (linear pieces ~ 0.1 %)
    v = np.linspace(0.0, 90.0, 91)
    lobe = parse_ies(make_ies(v, [0], np.cos(np.radians(v))[None, :] * 10.0))
    assert lobe.flux() == pytest.approx(PI * 10.0, rel=2e-4)
    # Type A and B: the solid-angle Jacobian of their own angle systems
    a_full = parse_ies(make_ies([-90, 0, 90], [-180, 0, 180], 1.0, ptype=3))
    assert a_full.flux() == pytest.approx(4 * PI, rel=1e-12)
    b_full = parse_ies(make_ies([-180, 0, 180], [-90, 90], 1.0, ptype=2))
    assert b_full.flux() == pytest.approx(4 * PI, rel=1e-12)
    b_std = parse_ies(make_ies([-90, 90], [-90, 0, 90], 1.0, ptype=2))  # lower hemisphere
    assert b_std.flux() == pytest.approx(2 * PI, rel=1e-12)


@pytest.mark.parametrize(
    ("v", "h", "ptype"),
    [
        ([0, 30, 90], [0], 1),  # type C axial
        ([0, 30, 90], [0, 45, 90], 1),  # type C quadrant-symmetric (0-90)
        ([0, 30, 90], [0, 90, 180], 1),  # type C bilateral (0-180)
        ([0, 30, 90], [0, 90, 180, 270, 360], 1),  # type C full
        ([90, 120, 180], [0, 90], 1),  # type C upper hemisphere, quadrant
        ([-90, 0, 90], [0, 90], 3),  # type A lateral symmetry, lower hemisphere
        ([-90, 0, 90], [-90, 0, 90], 3),  # type A, lower hemisphere
        ([-90, 90], [0, 45, 90], 2),  # type B lateral symmetry, lower hemisphere
    ],
)
def test_normalize_divides_by_the_mean_over_the_sphere(v, h, ptype) -> None:
    """Issue 33 item 2: a constant c over one hemisphere, whatever the photometric
    type and the symmetry the file folds, has flux 2 pi c and sphere mean c / 2, so
    ``shaping:ies:normalize`` (``sample / power``) makes it 2 there: the light keeps
    the flux 4 pi of the same light without IES (hdEmbree's / 2pi would give 1: half)."""
    p = parse_ies(make_ies(v, h, 3.0, ptype=ptype))
    assert p.flux() == pytest.approx(2 * PI * 3.0, rel=1e-9)
    assert p.power() == pytest.approx(1.5, rel=1e-9)
    assert _brute_flux(p) / p.power() == pytest.approx(4 * PI, rel=2e-3)


@pytest.mark.parametrize(
    "fname",
    [
        "luxtest__bega_50988.6k3.ies",
        "luxtest__bega_84659K4.ies",
        "luxtest__bega_84693k4.ies",
        "luxtest__bega_omni001_1238lm.ies",
        "luxtest__bega_omni002_4777lm.ies",
    ],
)
def test_flux_matches_manufacturer_lumens(fname: str, profiles) -> None:
    p = profiles[fname]  # absolute photometry; [LAMP] states the luminaire output
    rated = float(re.match(r"\s*(\d+) lm", p.keywords["LAMP"]).group(1))
    assert p.lumens_per_lamp == -1.0
    assert p.flux() == pytest.approx(rated, rel=5e-3)


RELATIVE_PHOTOMETRY = (  # lumens/lamp > 0 and real measurements (not the synthetic ones)
    "arnoldusd__test_0075_12.IES",
    "arnoldusd__test_0075_6.ies",
    "arnoldusd__test_1316_light.ies",
    "iesna__defined.ies",
    "iesna__medium-scatter.ies",
    "iesna__overhead.ies",
    "iesna__soft-arrow.ies",
    "luxcore__ASA_15M_R2.ies",
    "photon__1.ies",
    "photon__7.ies",
    "photon__9.IES",
    "photon__L1768-65BR30FL_FL55.ies",
    "wagyx__CB1210-2LF13.IES",
)


@pytest.mark.parametrize("fname", RELATIVE_PHOTOMETRY)
def test_relative_photometry_flux_below_lamp_lumens(fname: str, profiles) -> None:
    """Luminaire output <= rated lamp lumens (efficiency <= 1); catches a missing or
    doubled multiplier (arnoldusd 6: 4.8, L1768: 0.1, 1316: 0.89)."""
    p = profiles[fname]
    assert p.lumens_per_lamp > 0
    assert 0.2 * p.n_lamps * p.lumens_per_lamp < p.flux() <= p.n_lamps * p.lumens_per_lamp


@pytest.mark.parametrize(
    "fname",
    [
        "photon__1.ies",
        "luxtest__bega_84659K4.ies",
        "mdlsdk__test.ies",
        "rpr__ies_light_1.ies",
        "photon__9.IES",
    ],
)
def test_flux_agrees_with_sampled_quadrature(fname: str, profiles) -> None:
    p = profiles[fname]
    assert p.flux() == pytest.approx(_brute_flux(p), rel=3e-3)


# --- bake_table -------------------------------------------------------------------------


@pytest.mark.parametrize("fname", VALID_FILES)
def test_bake_table_matches_sample(fname: str, profiles) -> None:
    p = profiles[fname]
    table = p.bake_table()
    assert table.shape == (IES_TABLE_THETA, IES_TABLE_PHI) and table.dtype == np.float32
    assert np.all(np.isfinite(table)) and np.all(table >= 0.0)
    assert table.max() <= np.float32(p.max_candela())
    for i in (0, 1, 77, IES_TABLE_THETA - 1):
        theta = PI * i / (IES_TABLE_THETA - 1)
        for j in (0, 5, IES_TABLE_PHI // 2, IES_TABLE_PHI - 1):
            phi = 2 * PI * j / IES_TABLE_PHI
            assert table[i, j] == pytest.approx(float(p.sample(theta, phi)), rel=1e-6, abs=1e-30)
    small = p.bake_table(5, 3)
    assert small.shape == (5, 3) and small.dtype == np.float32
    assert small[0, 0] == table[0, 0] and small[-1, 0] == table[-1, 0]  # theta 0 and pi exact
    assert small[2, 1] == pytest.approx(float(p.sample(PI / 2, 2 * PI / 3)), rel=1e-6, abs=1e-30)


def test_bake_table_rejects_bad_sizes(profiles) -> None:
    p = profiles["photon__1.ies"]
    with pytest.raises(ValueError, match="n_theta"):
        p.bake_table(1, 4)


def test_sample_broadcasts(profiles) -> None:
    p = profiles["luxcore__ASA_15M_R2.ies"]
    out = p.sample(
        np.linspace(0, PI, 7)[:, None, None],
        np.linspace(0, 2 * PI, 5)[None, :, None] + np.zeros((1, 1, 3)),
    )
    assert out.shape == (7, 5, 3) and out.dtype == np.float64
    assert np.ndim(p.sample(0.1, 0.2)) == 0


# --- format robustness (inline) -----------------------------------------------------------


def test_separators_wrapping_and_line_endings() -> None:
    ref = parse_ies(make_ies([0, 45, 90], [0, 90], [[3.0, 2.0, 1.0], [6.0, 5.0, 4.0]]))
    variants = {
        "crlf": lambda s: s.replace("\n", "\r\n"),
        "cr": lambda s: s.replace("\n", "\r"),
        "no_final_newline": lambda s: s.rstrip("\n"),
        "commas": lambda s: (
            s.split("TILT=NONE")[0] + "TILT=NONE" + s.split("TILT=NONE")[1].replace(" ", ",")
        ),
        "tabs_blank_lines": lambda s: s.replace(" ", "\t\t").replace(
            "TILT=NONE\n", "TILT=NONE\n\n\n"
        ),
        "one_per_line": lambda s: (
            s.split("TILT=NONE")[0] + "TILT=NONE\n" + "\n".join(s.split("TILT=NONE")[1].split())
        ),
        "long_line": lambda s: (
            s.split("TILT=NONE")[0]
            + "TILT=NONE\n"
            + " ".join(s.split("TILT=NONE")[1].split())
            + " " * 300
        ),
        "leading_dots": lambda s: s.replace("1.0 1.0 10", ".1e1 1. 10"),
    }
    for name, f in variants.items():
        p = parse_ies(
            f(make_ies([0, 45, 90], [0, 90], [[3.0, 2.0, 1.0], [6.0, 5.0, 4.0]])), name=name
        )
        assert p.candela_raw.tolist() == ref.candela_raw.tolist(), name
        assert p.ballast_factor == 1.0 and p.warnings == [], name


def test_latin1_bom_and_keyword_spacing() -> None:
    body = make_ies([0, 90], [0], 1.0).split("\n", 2)[2]
    raw = b"\xef\xbb\xbfIESNA:LM-63-2002\n[MANUFAC]M\xfcller \xb0C\n[LAMP]   x  \n" + body.encode()
    p = parse_ies(raw)
    assert p.version == "LM-63-2002"
    assert p.keywords == {"MANUFAC": "Müller °C", "LAMP": "x"}


def test_tilt_include_wrapped_and_tilt_file() -> None:
    text = make_ies(
        [0, 90],
        [0, 90],
        [[1.0, 2.0], [3.0, 4.0]],
        tilt="TILT=INCLUDE\n3\n4 0\n30 60\n90 1.0 .9\n.8\n.7",
    )
    p = parse_ies(text)
    assert (p.tilt, p.tilt_geometry) == ("INCLUDE", 3)
    assert p.tilt_angles.tolist() == [0, 30, 60, 90]
    np.testing.assert_allclose(p.tilt_factors, [1.0, 0.9, 0.8, 0.7])
    assert p.candela_raw.tolist() == [[1.0, 2.0], [3.0, 4.0]]
    q = parse_ies(make_ies([0, 90], [0], 1.0, tilt="TILT= lamp tilt.dat "))
    assert q.tilt == "lamp tilt.dat" and q.tilt_angles is None
    assert any("lamp tilt.dat" in w for w in q.warnings)


def test_split_ten_number_line_and_2019() -> None:
    # iesna__defined.ies style "1 13172.61 1 / 37 1 / 1 / 2 / 0 0 0"; 2019 generation type
    text = (
        "IES:LM-63-2019\n[TEST] t\nTILT=NONE\n1 1000 1\n2 1\n1\n2\n0 0 0\n"
        "1.0 1.10000 50\n0 90\n0\n2 4\n"
    )
    p = parse_ies(text)
    assert p.version == "LM-63-2019"
    assert (p.lumens_per_lamp, p.file_generation_type, p.input_watts) == (1000.0, 1.1, 50.0)
    np.testing.assert_allclose(p.candela, [[2.0, 4.0]])  # generation type not multiplied in


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda s: s.replace("TILT=NONE", "TILT NONE"), "no TILT= line"),
        (lambda s: s.replace("TILT=NONE", "TILT="), "empty TILT"),
        (lambda s: s.replace(" 3 2 1 ", " 0 2 1 ", 1), "vertical angles"),
        (lambda s: s.replace(" 3 2 1 ", " 3 0 1 ", 1), "horizontal angles"),
        (lambda s: s.replace(" 3 2 1 ", f" 3 {IES_MAX_ANGLES + 1} 1 ", 1), "horizontal angles"),
        (lambda s: s.replace(" 3 2 1 ", " 3 2 4 ", 1), "photometric type"),
        (lambda s: s.replace("\n1 -1.0", "\n0 -1.0", 1), "number of lamps"),
        (lambda s: s.replace("0.0 45.0 90.0", "0.0 90.0 45.0"), "not strictly increasing"),
        (lambda s: s.replace("0.0 45.0 90.0", "0.0 45.0 45.0"), "not strictly increasing"),
        (lambda s: s.replace("0.0 90.0\n", "90.0 0.0\n"), "not strictly increasing"),
        (lambda s: s.replace("6.0 5.0", "6.0 -5.0"), "negative candela"),
        (lambda s: s.replace("6.0 5.0", "6.0 nan"), "not a number"),
        (lambda s: s.replace("6.0 5.0", "6.0 inf"), "not a number"),
        (lambda s: s.replace("6.0 5.0", "6.0 1e999"), "not finite"),
        (lambda s: s.replace("6.0 5.0", "6.0 1e300"), "exceeds"),
        (lambda s: s.rsplit(" ", 1)[0], "truncated"),
        (lambda s: s.replace("0.0 45.0 90.0", "0.0 45.0 190.0"), "outside"),
        (lambda s: s.replace(" 1.0 3 ", " -1.0 3 ", 1), "negative candela multiplier"),
    ],
)
def test_malformed_inputs_raise(edit, match: str) -> None:
    good = make_ies([0, 45, 90], [0, 90], [[3.0, 2.0, 1.0], [6.0, 5.0, 4.0]])
    assert " 3 2 1 " in good and "6.0 5.0" in good and " 1.0 3 " in good
    bad = edit(good)
    assert bad != good
    with pytest.raises(IesError, match=match) as e:
        parse_ies(bad, name="bad.ies")
    assert str(e.value).startswith("bad.ies: ") and "\n" not in str(e.value)
