"""Atomic writers fail midway without harm (issue 21): the old file survives byte for
byte and no temporary file is left. The failure is injected in the middle of the
write itself: a lone surrogate after 256 KiB of text cannot be encoded to UTF-8 (the
first part has already gone through the buffer), an object JSON cannot serialise
after the first keys of a document."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from stb_hydra.io.files import write_text_atomic
from stb_hydra.scenegen.common import write_text_atomic as scenegen_write_text_atomic
from stb_hydra.validate.report import write_json

OLD = "the old content\n"
BAD_TEXT = "x" * (256 * 1024) + "\ud800"  # encodes partly, then fails


def _old(tmp_path: Path, name: str) -> Path:
    p = tmp_path / name
    p.write_text(OLD)
    os.chmod(p, 0o640)
    return p


def _intact(tmp_path: Path, p: Path) -> None:
    assert p.read_text() == OLD, "the old file was damaged"
    assert os.stat(p).st_mode & 0o777 == 0o640
    assert sorted(q.name for q in tmp_path.iterdir()) == [p.name], "a temporary file was left"


def test_io_files_write_text_atomic_failing_midway(tmp_path):
    p = _old(tmp_path, "stats.json")
    with pytest.raises(UnicodeEncodeError):
        write_text_atomic(p, BAD_TEXT)
    _intact(tmp_path, p)
    write_text_atomic(p, "new\n")  # and a good write replaces it, keeping the mode
    assert p.read_text() == "new\n" and os.stat(p).st_mode & 0o777 == 0o640


def test_scenegen_write_text_atomic_failing_midway(tmp_path):
    p = _old(tmp_path, "scene.usda")
    with pytest.raises(UnicodeEncodeError):
        scenegen_write_text_atomic(p, BAD_TEXT)
    _intact(tmp_path, p)


def test_validate_json_failing_midway(tmp_path):
    p = _old(tmp_path, "validate.json")
    doc = {"schema": 1, "pad": "x" * (256 * 1024), "assets": [object()]}
    with pytest.raises(TypeError):
        write_json(str(p), doc)
    _intact(tmp_path, p)


class _Unprintable:
    def __str__(self) -> str:
        raise RuntimeError("cannot format")


def test_tradeoff_csv_failing_midway(tmp_path):
    from stb_hydra.apps.tradeoff_report import write_csv

    p = _old(tmp_path, "tradeoff.csv")
    rows = [{"label": "x" * 1000, "v": i} for i in range(300)] + [{"label": _Unprintable()}]
    with pytest.raises(RuntimeError):
        write_csv(rows, p, ["label", "v"])
    _intact(tmp_path, p)


def test_bench_outputs_failing_midway(tmp_path):
    """``stb bench``'s JSON and CSV go through ``io.files.write_text_atomic`` (they were
    written through a private helper that left its temporary file on a non-OS error)."""
    from stb_hydra.apps.bench import write_text

    for name in ("bench.json", "bench.csv"):
        p = _old(tmp_path, name)
        with pytest.raises(UnicodeEncodeError):
            write_text(str(p), BAD_TEXT)
        assert p.read_text() == OLD and os.stat(p).st_mode & 0o777 == 0o640
        write_text(str(p), "new\n")
        assert p.read_text() == "new\n" and os.stat(p).st_mode & 0o777 == 0o640
        p.unlink()
    assert list(tmp_path.iterdir()) == [], "a temporary file was left"


def test_bench_output_in_a_missing_directory_is_one_line(tmp_path):
    from stb_hydra.apps.bench import write_text
    from stb_hydra.apps.common import CliError

    with pytest.raises(CliError) as e:
        write_text(str(tmp_path / "no" / "bench.json"), "{}")
    assert "bench.json" in str(e.value) and "\n" not in str(e.value)
