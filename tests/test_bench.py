"""`stb bench`: argument parsing, the timing loop (GL-free fake engine), and a tiny
real run (records, JSON schema, CSV, plot)."""

from __future__ import annotations

import csv
import json
from types import SimpleNamespace

import pytest

from stb_hydra.apps import bench
from stb_hydra.apps.bench_core import measure_engine, median_dict, split_frame_timings
from stb_hydra.apps.cli import main as cli_main
from stb_hydra.apps.common import CliError
from stb_hydra.renderer.lighting import available

AVAIL = available()


# --- parsing (no GL) -------------------------------------------------------------------------


def test_methods_with_options_and_duplicates():
    ms = bench.parse_methods(["stb:N=4,K=16,sun,stb:N=1", "stb:N=1"], {}, AVAIL)
    assert [m.label for m in ms] == ["stb:N=4,K=16", "sun", "stb:N=1"]
    assert ms[0].options == {"N": 4, "K": 16}


def test_method_defaults_apply_and_entries_win():
    args = SimpleNamespace(method_option=["stb:K=32,eps=0.05"], opts_stb=["N=2"])
    for name in AVAIL:
        if name != "stb":
            setattr(args, bench.flag_dest(name), None)
    d = bench.method_defaults(args, AVAIL)
    assert d["stb"] == {"K": 32, "eps": 0.05, "N": 2}
    ms = bench.parse_methods(["stb,stb:N=4"], d, AVAIL)
    assert ms[0].options == {"K": 32, "eps": 0.05, "N": 2}
    assert ms[1].options["N"] == 4 and ms[1].options["K"] == 32


@pytest.mark.parametrize(
    "spec, match",
    [("nosuch", "unknown lighting method"), ("N=4,stb", "before any method"), ("stb:N", "key=")],
)
def test_bad_methods(spec, match):
    with pytest.raises(CliError, match=match):
        bench.parse_methods([spec], {}, AVAIL)


def test_values_sizes_and_generators():
    assert bench.parse_value("4") == 4 and bench.parse_value("0.5") == 0.5
    assert bench.parse_value("false") is False and bench.parse_value("none") is None
    assert bench.parse_value("segment") == "segment"
    assert bench.parse_size("745x360") == (745, 360)
    assert bench.parse_size("640") == (640, 0)
    with pytest.raises(CliError):
        bench.parse_size("axb")
    cases = bench.parse_scene("gen:lights:50,500:seed=3")
    assert [c.label for c in cases] == ["gen:lights:50:seed=3", "gen:lights:500:seed=3"]
    for bad in ("gen:nosuch:5", "gen:lights:x", "gen:lights:0", "gen:lights", "missing.usda"):
        with pytest.raises(CliError):
            bench.parse_scene(bad)


def test_cli_rejects_bad_stb_option_before_work(capsys):
    rc = cli_main(["bench", "gen:lights:10", "--methods", "stb:K=5", "--quiet"])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert "stb option K: expected one of 4, 8, 16, 32, 64, got 5" in err and "\n" not in err


# --- the timing loop with a fake engine (no GL) ------------------------------------------------


class FakeEngine:
    """render_frame() appends a fixed timing row; tasks a, lighting (with subs), c."""

    def __init__(self):
        self.tasks = [SimpleNamespace(name=n) for n in ("a", "lighting", "c")]
        self.timings = SimpleNamespace(frames=[])
        self.aov_output = SimpleNamespace(requested={"color"})
        self.seen_requested = []
        self.n = 0

    def render_frame(self, time=None):
        self.seen_requested.append(set(self.aov_output.requested))
        self.n += 1
        self.timings.frames.append(
            {
                "sync": 0.5,
                "commit": 0.1,
                "prepare": 1.0,
                "prepare.light_cull": 0.4,
                "a": 2.0,
                "lighting": 5.0,
                "lighting.x": 3.0,
                "lighting.y": 1.5,
                "c": 1.0,
            }
        )
        return SimpleNamespace(stats={"fov_lights": 7, "grid": [1]}, light_count=7)


def test_split_and_measure_fake_engine():
    passes, cpu = split_frame_timings(
        {"sync": 1.0, "lighting": 4.0, "lighting.x": 3.0, "a": 1.0}, ["a", "lighting"]
    )
    assert passes == {"a": 1.0, "lighting.x": 3.0, "lighting.other": 1.0}
    assert cpu == {"sync": 1.0}
    eng = FakeEngine()
    m = measure_engine(eng, frames=3, warmup=2)
    assert eng.n == 5 and len(m.frame) == 3
    assert eng.seen_requested == [set()] * 5 and eng.aov_output.requested == {"color"}
    s = m.summary()
    assert s["passes"] == {
        "a": 2.0,
        "lighting.x": 3.0,
        "lighting.y": 1.5,
        "lighting.other": 0.5,
        "c": 1.0,
    }
    assert s["gpu_ms"] == 8.0 and s["cull_upload_ms"] == 0.4
    assert m.stats == {"fov_lights": 7}
    assert median_dict([{"a": 1.0}, {"b": 3.0}, {"a": 2.0}]) == {"a": 1.0, "b": 0.0}


class SlowFakeEngine(FakeEngine):
    """Each frame takes ``delay`` seconds of wall time."""

    def __init__(self, delay):
        super().__init__()
        self.delay = delay

    def render_frame(self, time=None):
        import time as _t

        _t.sleep(self.delay)
        return super().render_frame(time)


def test_max_seconds_caps_slow_methods_but_keeps_one_measured_frame():
    eng = SlowFakeEngine(0.03)
    m = measure_engine(eng, frames=10, warmup=3, max_seconds=0.001)
    assert eng.n == 2 and len(m.frame) == 1  # one warm-up, one measured
    eng = SlowFakeEngine(0.0)
    m = measure_engine(eng, frames=4, warmup=2, max_seconds=60.0)
    assert eng.n == 6 and len(m.frame) == 4  # a generous budget changes nothing
    eng = SlowFakeEngine(0.03)
    m = measure_engine(eng, frames=10, warmup=0, max_seconds=0.001)
    assert eng.n == 1 and len(m.frame) == 1


# --- a real run -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def run(gl_ctx, tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    js = out / "bench.json"
    rc = cli_main(
        [
            "bench",
            "gen:lights:12,60",
            "--methods",
            "stb:N=1,sun,stb:N=4,K=8",
            "--size",
            "96x54",
            "--size",
            "64x36",
            "--frames",
            "3",
            "--warmup",
            "1",
            "--json",
            str(js),
            "--quiet",
        ]
    )
    assert rc == 0
    return out, json.loads(js.read_text())


@pytest.mark.gl
def test_records_cover_every_combination(run):
    _out, recs = run
    assert len(recs) == 2 * 2 * 3
    assert {r["scene"] for r in recs} == {"gen:lights:12", "gen:lights:60"}
    assert {r["label"] for r in recs} == {"stb:N=1", "sun", "stb:N=4,K=8"}
    assert {(r["width"], r["height"]) for r in recs} == {(96, 54), (64, 36)}
    by_scene = {r["scene"]: r["scene_lights"] for r in recs}
    assert by_scene == {"gen:lights:12": 12, "gen:lights:60": 60}
    for r in recs:
        if r["method"] == "sun":  # it holds no local lights (lighting.base.light_filter)
            assert r["lights"] == 0
        else:
            assert 0 < r["lights"] <= r["scene_lights"]


@pytest.mark.gl
def test_record_schema_and_pass_sum(run):
    _out, recs = run
    for r in recs:
        for key, typ in (
            ("method", str),
            ("lights", int),
            ("width", int),
            ("height", int),
            ("frame_ms", float),
            ("passes", dict),
            ("timings", dict),
            ("cpu_ms", float),
            ("gpu_ms", float),
        ):
            assert isinstance(r[key], typ), key
        assert r["frames"] == 3 and r["warmup"] == 1
        for k in ("sync", "commit", "prepare", "prepare.light_cull"):
            assert k in r["timings"], k
        assert all(v >= 0 for v in r["passes"].values())
        # How much of the frame the timed passes and CPU phases cover is a benchmark
        # figure (``accounted_fraction``), not a timing assertion: it is reported, and
        # it is the ratio of the record's own medians.
        cpu = sum(r["timings"].get(k, 0.0) for k in ("sync", "commit", "prepare"))
        total = sum(r["passes"].values()) + cpu
        assert r["accounted_fraction"] == pytest.approx(total / r["frame_ms"], abs=2e-3)
        assert r["frame_ms_min"] <= r["frame_ms"] <= r["frame_ms_max"]
        if r["method"] == "stb":  # the default: the reuse's slot and shading passes
            assert {
                "lighting.stb_bigtile",
                "lighting.stb_reuse_slot_pos",
                "lighting.stb_lighting",
            } <= set(r["passes"])


@pytest.mark.gl
def test_csv_and_plot_written(run):
    out, recs = run
    rows = list(csv.DictReader((out / "bench.csv").open()))
    assert len(rows) == len(recs)
    assert float(rows[0]["frame_ms"]) == recs[0]["frame_ms"]
    assert any(k.startswith("pass:lighting.stb_") for k in rows[0])
    png = (out / "bench.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


@pytest.mark.gl
def test_rows_come_out_as_each_configuration_finishes(gl_ctx, tmp_path, capsys):
    """A run stopped part-way still says where its time went (issue 34): each finished
    configuration is printed and written to the CSV / JSON before the next starts."""
    seen: list[tuple[int, int]] = []
    js, cs = tmp_path / "b.json", tmp_path / "b.csv"
    cases = bench.parse_scene("gen:lights:12")
    methods = bench.parse_methods(["sun,bare"], {}, AVAIL)

    def on_record(done):
        # The files on disk hold exactly the configurations finished so far.
        bench.write_text(str(js), json.dumps(done))
        bench.write_text(str(cs), bench.records_csv(done))
        seen.append((len(done), len(json.loads(js.read_text()))))

    recs = bench.run_bench(
        cases, methods, [(48, 27)], frames=1, warmup=1, progress=True, on_record=on_record
    )
    assert seen == [(1, 1), (2, 2)]
    rows = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("row ")]
    assert [r.split()[1] for r in rows] == ["sun", "bare"]
    assert rows == [bench.row_line(r) for r in recs]
    for r in recs:
        assert 0 < r["setup_s"] < r["config_wall_s"] and r["config_cpu_s"] > 0
        assert 0 < r["first_frame_s"] <= r["warmup_s"] < r["config_wall_s"]
    assert [row["method"] for row in csv.DictReader(cs.open())] == ["sun", "bare"]
    assert float(next(csv.DictReader(cs.open()))["config_cpu_s"]) == recs[0]["config_cpu_s"]


def test_cli_writes_the_files_after_every_configuration(monkeypatch, tmp_path):
    """The CLI hands run_bench a callback that rewrites --json / --csv (no GL: the
    run is replaced by one that reports two records, then is interrupted)."""
    rec = {"label": "x", "passes": {}, "timings": {}}
    got: list[str] = []

    def fake_run_bench(*a, on_record, **k):
        on_record([rec])
        got.append((tmp_path / "o.json").read_text())
        on_record([rec, rec])
        got.append((tmp_path / "o.json").read_text())
        raise KeyboardInterrupt

    monkeypatch.setattr(bench, "run_bench", fake_run_bench)
    rc = cli_main(["bench", "gen:lights:5", "--json", str(tmp_path / "o.json"), "--no-plot"])
    assert rc != 0  # interrupted, as a killed run
    assert [len(json.loads(t)) for t in got] == [1, 2]
    assert len(list(csv.DictReader((tmp_path / "o.csv").open()))) == 2
