#!/usr/bin/env bash
# One seed of the real-object recipe (docs/evaluation.md, "Protocol"): a collection on the partnet
# catalogue's `train` split with collection seed SEED, then the three training phases with
# training seed SEED. Seed 0's checkpoint is the one the project ships; the protocol lock records
# this file's sha256 and every seed's weights.
#   ACTAIM2_PARTNET=DIR bash scripts/recipe_real_objects.sh SEED [DATA_DIR] [RUNS_DIR]
# Resumable: rerun the same command after an interruption (collection skips what is stored,
# training continues from its last checkpoint).
set -euo pipefail
SEED=${1:?usage: recipe_real_objects.sh SEED [DATA_DIR] [RUNS_DIR]}
DATA=${2:-data}
RUNS=${3:-runs}
: "${ACTAIM2_PARTNET:?set ACTAIM2_PARTNET to the PartNet-Mobility folder holding splits.yaml}"
source "$(dirname "${BASH_SOURCE[0]}")/env.sh"

actaim2 collect --out "$DATA/pm_s$SEED" --catalogue partnet --splits train \
  --random 20 --grasp 20 --gmm 20 --workers 2 --seed "$SEED" --no-progress
resume=()
if [ -f "$RUNS/pm_s$SEED/train_state.json" ]; then resume=(--resume); fi
actaim2 train --data "$DATA/pm_s$SEED" --out "$RUNS/pm_s$SEED" --catalogue partnet \
  --config cpu_default --seed "$SEED" --no-progress "${resume[@]}"
