#!/usr/bin/env bash
# The recipe runs of docs/notebook ("TP and TP+"), one after the other: run in parallel
# they oversubscribe the two cores (a predictor trained 7x slower beside another run).
# Each line is resumable: rerun this script after a kill. The reduced recipes are what
# fitted in one session's budget; docs/notebook says which setting got what. They predate
# the larger final stage of 2026-12-03: to remake their TP+ as shipped, add --final-steps 5000
# --final-lr 0.001 (and, where a line gives none, --final-episodes as many as data-0's).
set -euo pipefail
cd "$(dirname "$0")/../.."  # the repository root
source .venv/bin/activate
mkdir -p logs
while pgrep -f "masspush train" > /dev/null; do sleep 20; done  # one run at a time
run() { local name=$1; shift; masspush train "$@" --ship >> "logs/train-$name.log" 2>&1; }
run 2link-1-10   --setting 2link-1-10
run 2link-0.1-10 --setting 2link-0.1-10 --meta-iterations 3
run 3link-1-10   --setting 3link-1-10   --meta-iterations 2 --iteration-episodes 8000 --final-episodes 16000
run 2link-0.1-1  --setting 2link-0.1-1  --meta-iterations 2 --ppo-steps 20000 --envs 8 --iteration-episodes 4000 --final-episodes 8000
run 3link-0.1-10 --setting 3link-0.1-10 --meta-iterations 1 --iteration-episodes 8000 --final-episodes 16000
run 3link-0.1-1  --setting 3link-0.1-1  --meta-iterations 1 --ppo-steps 10000 --envs 8 --iteration-episodes 2000 --final-episodes 4000
# The paper's real setup (docs/real-robot.md): ships rp (predictor-0), tp and tp+.
run real-ur10    --setting real-ur10    --meta-iterations 2 --ppo-steps 20000 --envs 8 --iteration-episodes 4000 --final-episodes 8000
