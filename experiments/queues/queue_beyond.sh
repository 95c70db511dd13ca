#!/usr/bin/env bash
# The measurements of docs/notebook "Sim-to-real" and "The Bayesian estimator", one after
# the other (each resumes or reuses what is done): rerun after a kill.
set -euo pipefail
cd "$(dirname "$0")/../.."  # the repository root
source .venv/bin/activate
mkdir -p logs
while pgrep -f "masspush train" > /dev/null; do sleep 20; done  # one CPU job at a time
masspush sim2real --setting real-ur10 --out results/sim2real >> logs/sim2real.log 2>&1
for s in 2link-1-10 2link-0.1-10 3link-1-10 3link-0.1-10; do
  [ -f "src/masspush/models/$s/tp+.dirichlet.pt" ] || masspush calibrate --setting "$s" --model tp+ >> logs/calibrate.log 2>&1
done
for s in 2link-0.1-1 3link-0.1-1; do  # through the arm: fewer episodes
  [ -f "src/masspush/models/$s/tp+.dirichlet.pt" ] || masspush calibrate --setting "$s" --model tp+ --episodes 2000 >> logs/calibrate.log 2>&1
done
masspush bayes-table --settings all --episodes "${BAYES_EPISODES:-30}" >> logs/bayes-table.log 2>&1
