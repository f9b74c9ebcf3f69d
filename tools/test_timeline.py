"""Where a ``make test`` run's time went, from its per-test CPU log.

``CI=true STB_TEST_CPU_LOG=/tmp/cpu.tsv make test`` writes one line per test
(tests/conftest.py: node id, wall s, own CPU s, children's CPU s, xdist worker, start
and end in epoch s). This prints, per xdist worker, its tests, busy wall time, CPU,
when it finished and how long it then sat idle while another worker still ran (the
run's tail), the last modules each worker ran, and the modules with the most CPU::

    python tools/test_timeline.py /tmp/cpu.tsv [--top 15]

Lines of an older log (four columns, no worker or times) count in the module table
only.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict


def _read(path: str) -> list[list[str]]:
    with open(path) as f:
        return [ln.rstrip("\n").split("\t") for ln in f if ln.strip()]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("log", help="the STB_TEST_CPU_LOG file")
    ap.add_argument("--top", type=int, default=15, help="modules listed by CPU (default 15)")
    args = ap.parse_args(argv)
    rows = _read(args.log)
    if not rows:
        print(f"{args.log}: empty", file=sys.stderr)
        return 1
    by_module: dict[str, float] = defaultdict(float)
    for r in rows:
        by_module[r[0].split("::")[0]] += float(r[2]) + float(r[3])
    timed = [r for r in rows if len(r) >= 7]
    if timed:
        t0 = min(float(r[5]) for r in timed)
        t_end = max(float(r[6]) for r in timed)
        print(f"run: {t_end - t0:.1f} s from the first test's start to the last test's end")
        workers: dict[str, list[list[str]]] = defaultdict(list)
        for r in timed:
            workers[r[4]].append(r)
        for w, rs in sorted(workers.items()):
            rs.sort(key=lambda r: float(r[5]))
            end = max(float(r[6]) for r in rs)
            busy = sum(float(r[1]) for r in rs)
            cpu = sum(float(r[2]) + float(r[3]) for r in rs)
            last: list[str] = []
            for r in reversed(rs):
                m = r[0].split("::")[0]
                if m not in last:
                    last.append(m)
                if len(last) == 3:
                    break
            print(
                f"{w}: {len(rs)} tests, busy {busy:.1f} s, CPU {cpu:.1f} s, done at "
                f"{end - t0:.1f} s, idle after {t_end - end:.1f} s; last: {', '.join(last)}"
            )
    total = sum(by_module.values())
    print(f"CPU by module ({total:.1f} s in all):")
    for m, c in sorted(by_module.items(), key=lambda kv: -kv[1])[: args.top]:
        print(f"  {c:7.1f}  {m}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
