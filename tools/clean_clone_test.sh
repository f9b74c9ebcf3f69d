#!/bin/bash
# Issue 32's measurement: a clean clone of this checkout beside ../shared, `CI=true make
# test` cold (a new empty MESA_SHADER_CACHE_DIR) and then warm (the same cache, the venv
# made), each under /usr/bin/time -v; WARM warm runs in all (default 1; the issue asks
# for three). Logs and a summary go to /tmp/clean_clone_N.*.
#   tools/clean_clone_test.sh N [WARM]   # N: a run number (the clone is ../clean_clone_N)
# With CPU_LOG=1 each run also writes tests/conftest.py's per-test CPU log to
# /tmp/clean_clone_N.RUN.tsv (compare runs with tools/test_timeline.py); the summary
# records the Mesa cache's size after each run. Each run is preceded by a calibration
# line: the CPU seconds of a fixed single-thread Python loop (20 M additions), the
# machine's speed at that moment -- the shared VM's speed moves between days (~1.6x
# measured, docs/TESTING.md "Run 18"), so compare runs of different days through it.
set -u
calib() {
    python3 -c 'import time
t = time.process_time(); s = 0
for i in range(20_000_000): s += i
print(f"calibration: 20M-add Python loop {time.process_time() - t:.2f} s CPU")'
}
n=${1:?run number}
warm=${2:-1}
src=$(cd "$(dirname "$0")/.." && pwd)
dst=$(dirname "$src")/clean_clone_$n
cache=$(mktemp -d /tmp/mesa_clean_clone_$n.XXXX)
rm -rf "$dst" && git clone -q "$src" "$dst" && cd "$dst" || exit 1
sum=/tmp/clean_clone_$n.summary
echo "commit $(git rev-parse --short HEAD) start $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg)" > "$sum"
runs="cold warm"
for ((i = 2; i <= warm; i++)); do runs="$runs warm$i"; done
for k in $runs; do
    log=
    echo "$k $(calib)" >> "$sum"
    [ "${CPU_LOG:-0}" = 1 ] && log=/tmp/clean_clone_$n.$k.tsv && rm -f "$log"
    STB_TEST_CPU_LOG=$log CI=true MESA_SHADER_CACHE_DIR=$cache /usr/bin/time -v make test > /tmp/clean_clone_$n.$k.log 2>&1
    echo "$k rc=$? end $(date +%T) load $(cut -d' ' -f1-3 /proc/loadavg) mesa cache $(du -sk "$cache" | cut -f1) KiB $(find "$cache" -type f | wc -l) files" >> "$sum"
    grep -E "passed|failed|Elapsed|User time|System time" /tmp/clean_clone_$n.$k.log | sed "s/^/$k: /" >> "$sum"
done
cat "$sum"
