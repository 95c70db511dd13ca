#!/usr/bin/env bash
# The filter and TP+ on the same first N evaluation episodes of every setting (seed 0; N:
# EPISODES, 100 by default), each with its episodes' estimates, for docs/notebook's paired
# comparisons. The filter's first 100 of 300 episodes are its 100-episode run (its random
# streams carry over from episode to episode, so the runs agree where they overlap).
# Resumable: a setting whose two files exist is skipped; rerun after a kill.
#   SETTINGS="2link-0.1-1 2link-0.1-10" EPISODES=300 experiments/bayes/paired.sh
set -euo pipefail
cd "$(dirname "$0")/../.."  # the repository root
source .venv/bin/activate
mkdir -p results/paired
n=${EPISODES:-100}
for s in ${SETTINGS:-2link-0.1-1 2link-1-10 2link-0.1-10 3link-0.1-1 3link-1-10 3link-0.1-10}; do
  bayes="results/paired/$s-bayes-$n.json" tp="results/paired/$s-tp+-$n.json"
  if [ ! -s "$bayes" ]; then
    masspush evaluate --setting "$s" --model bayes --episodes "$n" --json > "$bayes.part"
    mv "$bayes.part" "$bayes"
  fi
  if [ ! -s "$tp" ]; then
    masspush evaluate --setting "$s" --model tp+ --episodes "$n" --paired-with "$bayes" --json \
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
