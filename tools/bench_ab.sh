#!/bin/sh
# A/B/A/B frame-time comparison of two revisions in one run (same machine, same load):
#   tools/bench_ab.sh BEFORE_REV AFTER_REV OUTDIR [stb bench arguments...]
# Each revision is checked out as a git worktree under OUTDIR and run with this
# checkout's .venv, its own package first on PYTHONPATH (and its own shaders/). Writes
# OUTDIR/{before,after}_{1,2}.json and OUTDIR/load.txt (load average after each run).
set -e
[ $# -ge 3 ] || { echo "usage: $0 BEFORE_REV AFTER_REV OUTDIR [stb bench args]" >&2; exit 2; }
before=$1; after=$2; out=$(mkdir -p "$3" && cd "$3" && pwd); shift 3
root=$(cd "$(dirname "$0")/.." && pwd)
py="$root/.venv/bin/python"
for side in before after; do
  rev=$before; [ $side = after ] && rev=$after
  [ -d "$out/$side" ] || git -C "$root" worktree add -q --detach "$out/$side" "$rev"
  # Top-level shaders/ (after the render-core refactor) must win over the editable install.
  if [ -d "$out/$side/shaders" ] && [ ! -e "$out/$side/stb_hydra/shaders" ]; then
    ln -s "$out/$side/shaders" "$out/$side/stb_hydra/shaders"
  fi
done
for round in ${ROUNDS:-1 2}; do
  for side in before after; do
    (cd "$out/$side" && PYTHONPATH="$out/$side" "$py" -m stb_hydra.apps.cli bench "$@" \
      --no-plot --quiet --json "$out/${side}_$round.json")
    echo "$side $round $(uptime)" >> "$out/load.txt"
  done
done
