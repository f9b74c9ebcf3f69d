"""Hostile libraries for ``stb validate`` (issue 21, item 7): a symlink out of the
library root is reported and never opened; a 100 MB IES file, a 1 GB usdc, a garbage
usdc and deeply nested references are each reported in bounded time and memory
(limits in ``stb_hydra/limits.py``: ``IES_MAX_FILE_BYTES``,
``VALIDATE_LAYER_MAX_BYTES``, ``VALIDATE_MAX_LAYERS``, ``VALIDATE_WORKER_MAX_BYTES``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pxr import Sdf

import stb_hydra.validate  # noqa: F401  (registers the stb validators)
from stb_hydra import limits
from stb_hydra.apps import cli
from stb_hydra.apps.validate import collect_inputs
from stb_hydra.validate.runner import Selection, validate_in_process

LIGHT_USDA = """#usda 1.0
(
    defaultPrim = "Prefab"
    metersPerUnit = 1
)
def Xform "Prefab"
{
    def SphereLight "L" (prepend apiSchemas = ["ShapingAPI"])
    {
        float inputs:intensity = 1000
        float inputs:radius = 0.05
        asset inputs:shaping:ies:file = @%s@
    }
}
"""


def _validate(path: Path, root: Path):
    t0 = time.perf_counter()
    rep = validate_in_process(str(path), str(root), Selection.parse(None), False)
    return rep, time.perf_counter() - t0


def _one_line(rep) -> None:
    for f in rep.findings:
        assert "\n" not in f.message


def test_symlink_out_of_the_root_is_reported_and_never_opened(tmp_path, capsys):
    lib, outside = tmp_path / "lib", tmp_path / "outside"
    lib.mkdir()
    outside.mkdir()
    target = outside / "secret.usda"
    target.write_text('#usda 1.0\ndef Xform "Secret"\n{\n}\n')
    (lib / "evil.usda").symlink_to(target)
    (lib / "linked_dir").symlink_to(outside, target_is_directory=True)
    (lib / "ok.usda").write_text('#usda 1.0\ndef Xform "Ok"\n{\n}\n')

    tasks = collect_inputs([str(lib)])
    names = sorted(Path(p).name for p, _ in tasks)
    assert names == ["evil.usda", "ok.usda"]  # the linked directory is not walked
    evil = next(p for p, _ in tasks if p.endswith("evil.usda"))
    rep, _ = _validate(Path(evil), lib)
    assert not rep.opened
    assert [f.rule for f in rep.findings] == ["asset_path_unsafe"]
    assert "symlink that escapes the library root" in rep.findings[0].message
    assert "evil.usda" in rep.findings[0].message
    assert Sdf.Layer.Find(str(target)) is None, "the target outside the root was opened"
    _one_line(rep)

    report = tmp_path / "v.json"
    code = cli.main(["validate", "--quiet", "--jobs", "0", "--json", str(report), str(lib)])
    assert code != 0
    doc = json.loads(report.read_text())
    flat = json.dumps(doc)
    assert "symlink that escapes the library root" in flat
    assert "secret.usda" not in flat.replace(str(target), "")  # named only as the target


def test_100mb_ies_file_is_reported_in_bounded_time(tmp_path):
    ies = tmp_path / "huge.ies"
    with open(ies, "wb") as f:
        f.write(b"IESNA:LM-63-2002\nTILT=NONE\n")
        f.truncate(100 * 1024 * 1024)  # sparse: 100 MB on paper
    asset = tmp_path / "lamp.usda"
    asset.write_text(LIGHT_USDA % "./huge.ies")
    rep, dt = _validate(asset, tmp_path)
    assert rep.opened
    hits = [f for f in rep.findings if f.rule == "ies_malformed"]
    assert hits and "huge.ies" in hits[0].message, [f.message for f in rep.findings]
    assert dt < 20.0  # reads at most IES_MAX_FILE_BYTES + 1 bytes
    _one_line(rep)


def test_1gb_usdc_is_not_opened(tmp_path):
    big = tmp_path / "big.usdc"
    with open(big, "wb") as f:
        f.write(b"PXR-USDC" + b"\0" * 80)
        f.truncate(1024**3)  # sparse
    rep, dt = _validate(big, tmp_path)
    assert not rep.opened and dt < 5.0
    (f,) = rep.findings
    assert f.rule == "unreadable" and "1024 MiB" in f.message and "not opened" in f.message
    # the same as a dependency: the referencing asset is reported, the layer not opened
    ref = tmp_path / "uses_big.usda"
    ref.write_text('#usda 1.0\ndef Xform "A" (references = @./big.usdc@)\n{\n}\n')
    rep, dt = _validate(ref, tmp_path)
    assert not rep.opened and dt < 5.0
    assert [x.rule for x in rep.findings] == ["unreadable"] and "big.usdc" in rep.findings[
        0
    ].message
    assert Sdf.Layer.Find(str(big)) is None


def test_garbage_usdc_is_unreadable_in_bounded_time(tmp_path):
    bad = tmp_path / "garbage.usdc"
    rnd = os.urandom(2 * 1024 * 1024)
    bad.write_bytes(b"PXR-USDC" + rnd)
    rep, dt = _validate(bad, tmp_path)
    assert dt < 30.0 and not rep.opened
    assert [f.rule for f in rep.findings] == ["unreadable"]
    _one_line(rep)


def _chain(root: Path, n: int) -> Path:
    """n layers, each referencing the next."""
    for i in range(n):
        nxt = f" (references = @./l{i + 1}.usda@)" if i + 1 < n else ""
        (root / f"l{i}.usda").write_text(
            f'#usda 1.0\n(defaultPrim = "P")\ndef Xform "P"{nxt}\n{{\n}}\n'
        )
    return root / "l0.usda"


def test_deeply_nested_references_are_bounded(tmp_path):
    deep = tmp_path / "deep"
    deep.mkdir()
    rep, dt = _validate(_chain(deep, limits.VALIDATE_MAX_LAYERS + 5), deep)
    assert not rep.opened
    assert [f.rule for f in rep.findings] == ["unreadable"]
    assert f"more than {limits.VALIDATE_MAX_LAYERS} layers" in rep.findings[0].message
    assert dt < 60.0
    # a 100-deep chain is fine: composed and validated
    ok = tmp_path / "ok"
    ok.mkdir()
    rep, dt = _validate(_chain(ok, 100), ok)
    assert rep.opened and dt < 60.0


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS semantics")
def test_validate_worker_address_space_is_capped():
    """A worker's address space is capped at limits.VALIDATE_WORKER_MAX_BYTES: an
    asset that makes USD allocate without bound ends that worker, not the machine."""
    code = (
        "import resource, sys\n"
        "from stb_hydra.validate.parallel import _limit_memory\n"
        "_limit_memory(1 << 30)\n"
        "print(resource.getrlimit(resource.RLIMIT_AS)[0])\n"
        "try:\n    b = bytearray(2 << 30)\nexcept MemoryError:\n    print('MemoryError')\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    ).stdout.split()
    assert out == [str(1 << 30), "MemoryError"]
    assert limits.VALIDATE_WORKER_MAX_BYTES >= 4 * 1024**3
