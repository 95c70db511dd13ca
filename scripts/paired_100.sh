#!/usr/bin/env bash
# The filter and TP+ on the same first 100 evaluation episodes of every setting (seed 0),
# each with its episodes' estimates, for docs/results.md "TP+ and the filter on the same 100
# episodes". Resumable: a setting whose two files exist is skipped; rerun after a kill.
set -euo pipefail
cd "$(dirname "$0")/.."
source .venv/bin/activate
mkdir -p results/paired
for s in ${SETTINGS:-2link-0.1-1 2link-1-10 2link-0.1-10 3link-0.1-1 3link-1-10 3link-0.1-10}; do
  bayes="results/paired/$s-bayes-100.json" tp="results/paired/$s-tp+-100.json"
  if [ ! -s "$bayes" ]; then
    masspush evaluate --setting "$s" --model bayes --episodes 100 --json > "$bayes.part"
    mv "$bayes.part" "$bayes"
  fi
  if [ ! -s "$tp" ]; then
    masspush evaluate --setting "$s" --model tp+ --episodes 100 --paired-with "$bayes" --json \
      > "$tp.part"
    mv "$tp.part" "$tp"
  fi
  python - "$bayes" "$tp" <<'PY'
import json, sys
from masspush.metrics import paired_difference_interval, paired_percentage_errors
bayes, tp = (json.load(open(f)) for f in sys.argv[1:])
b, t = bayes["per_episode"], tp["per_episode"]
err_b, err_t, n = paired_percentage_errors(b, t)
low, high = paired_difference_interval(b, t)
print(f"| {bayes['setting']} | {n} | {err_b:.2f} | {err_t:.2f} | {low:+.2f} to {high:+.2f} "
      f"| {100 * bayes['coverage']:.0f} % |")
PY
done
