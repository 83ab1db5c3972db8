#!/usr/bin/env bash
# A finite-difference sweep over a Slurm job array: each array task runs one share of the
# reruns (every share also runs the nominal analysis, whose increments the reruns follow),
# and a dependent job merges the shares into sensitivity.csv and sensitivity.json, the same
# numbers bit for bit as the unsharded run.
#
#   sbatch --array=1-16 tools/slurm-fdm.sh leaf-spring fdm-central 1e-6 out/leaf-fdm
#   sbatch --dependency=afterok:JOBID tools/slurm-fdm.sh --merge out/leaf-fdm
#
# The same with GNU parallel on one machine or over ssh logins (--sshloginfile):
#
#   parallel fricsens sensitivity leaf-spring --method fdm-central --beta 1e-6 \
#       --shard {}/16 --out out/leaf-fdm ::: $(seq 16) && fricsens merge out/leaf-fdm/partial-*-of-16.json
#
# tools/slurm-shards.sh shards any of fricsens' sweeps (validate, scaling, sensitivity).
#
#SBATCH --job-name=fricsens-fdm
#SBATCH --cpus-per-task=2
#SBATCH --time=02:00:00
set -euo pipefail
FRICSENS=${FRICSENS:-fricsens}
if [[ "${1:-}" == "--merge" ]]; then
  exec "$FRICSENS" merge "$2"/partial-*-of-*.json --out "$2"
fi
scene=$1 method=$2 beta=$3 out=$4
shift 4
: "${SLURM_ARRAY_TASK_ID:?run as a job array: sbatch --array=1-N}"
: "${SLURM_ARRAY_TASK_COUNT:?run as a job array: sbatch --array=1-N}"
exec "$FRICSENS" sensitivity "$scene" --method "$method" --beta "$beta" "$@" \
  --shard "$SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT" --out "$out"
