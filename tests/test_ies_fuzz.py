"""Fuzzing the IES parser: whatever the bytes, only ``IesError`` may come out, and every
profile that parses samples to finite, non-negative candela."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stb_hydra.scene.ies import IesError, IesProfile, parse_ies

NAME = "fuzz.ies"
SETTINGS = settings(
    max_examples=500, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)


@pytest.fixture(scope="session")
def real_files(testdata: Path) -> list[bytes]:
    files = sorted((testdata / "ies").glob("*.[iI][eE][sS]"))
    assert len(files) == 29
    return [f.read_bytes() for f in files]


def _check(data: bytes | str) -> IesProfile | None:
    try:
        p = parse_ies(data, name=NAME)
    except IesError as e:
        msg = str(e)
        assert msg.startswith(f"{NAME}: ") and "\n" not in msg, msg
        assert "internal parser error" not in msg, msg
        return None
    theta = np.linspace(0.0, np.pi, 7)[:, None]
    phi = np.linspace(-1.0, 7.0, 5)[None, :]
    for values in (p.sample(theta, phi), p.bake_table(6, 4), p.candela):
        assert np.all(np.isfinite(values)) and np.all(values >= 0.0)
    for x in (p.power(), p.flux(), p.max_candela()):
        assert np.isfinite(x) and x >= 0.0
    return p


@SETTINGS
@given(st.binary(max_size=1500))
def test_arbitrary_bytes(data: bytes) -> None:
    _check(data)


NUMERIC = st.text(alphabet="0123456789 .-+eE,\t\n", max_size=400)


@SETTINGS
@given(
    st.sampled_from(
        [
            "IESNA:LM-63-2002\n[TEST] x\nTILT=NONE\n",
            "IESNA91\nTILT=INCLUDE\n",
            "free text\nTILT=NONE\n",
        ]
    ),
    NUMERIC,
)
def test_numeric_soup_after_tilt(head: str, body: str) -> None:
    _check(head + body)


@SETTINGS
@given(st.integers(1, 10), st.integers(1, 10), st.integers(1, 3), st.data())
def test_generated_grids_sample_cleanly(n_v: int, n_h: int, ptype: int, data) -> None:
    """Well-formed files with random (sorted, in-range) angle grids never break sampling."""
    if ptype == 1:
        v_range, h_range = (0.0, 180.0), (-360.0, 360.0)
    elif ptype == 2:
        v_range, h_range = (-180.0, 180.0), (-90.0, 90.0)
    else:
        v_range, h_range = (-90.0, 90.0), (-180.0, 180.0)
    angle = lambda r: st.floats(*r, allow_nan=False).map(lambda x: round(x, 3))  # noqa: E731
    v = sorted(set(data.draw(st.lists(angle(v_range), min_size=n_v, max_size=n_v))))
    h = sorted(set(data.draw(st.lists(angle(h_range), min_size=n_h, max_size=n_h))))
    cd = data.draw(
        st.lists(
            st.floats(0, 1e6, allow_nan=False), min_size=len(v) * len(h), max_size=len(v) * len(h)
        )
    )
    text = (
        f"IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 {len(v)} {len(h)} {ptype} 2 0 0 0\n1 1 0\n"
        + " ".join(map(repr, v))
        + "\n"
        + " ".join(map(repr, h))
        + "\n"
        + " ".join(map(repr, cd))
        + "\n"
    )
    _check(text)


def _mutate(raw: bytes, data) -> bytes:
    op = data.draw(
        st.sampled_from(["bytes", "truncate", "delete_token", "dup_token", "insert_token"])
    )
    if op == "bytes":
        buf = bytearray(raw)
        for _ in range(data.draw(st.integers(1, 6))):
            buf[data.draw(st.integers(0, len(buf) - 1))] = data.draw(st.integers(0, 255))
        return bytes(buf)
    if op == "truncate":
        return raw[: data.draw(st.integers(0, len(raw)))]
    spans = [m.span() for m in re.finditer(rb"[^\s,]+", raw)]
    if not spans:
        return raw
    a, b = spans[data.draw(st.integers(0, len(spans) - 1))]
    if op == "delete_token":
        return raw[:a] + raw[b:]
    if op == "dup_token":
        return raw[:b] + b" " + raw[a:b] + raw[b:]
    token = data.draw(
        st.sampled_from(
            [
                b"-1",
                b"0",
                b"1e9",
                b"nan",
                b"TILT=NONE",
                b"[MORE]",
                b"\r",
                b"x",
                b"99999",
                b".5",
                b"360",
                b"-90",
            ]
        )
    )
    return raw[:a] + token + b" " + raw[a:]


@settings(
    max_examples=1500, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
@given(st.data())
def test_mutated_real_files(real_files: list[bytes], data) -> None:
    raw = data.draw(st.sampled_from(real_files))
    for _ in range(data.draw(st.integers(1, 3))):
        if raw:
            raw = _mutate(raw, data)
    _check(raw)
