#!/usr/bin/env bash
# Any sharded fricsens run over a Slurm job array: each array task runs one share
# (`--shard K/N`, K the task's id, N the array's size) of the fricsens command given, and a
# dependent job merges the shares (`fricsens merge`) into the unsharded run's outputs. The
# command must name its output folder with --out.
#
#   sbatch --array=1-8 tools/slurm-shards.sh validate --out out/validation
#   sbatch --array=1-6 tools/slurm-shards.sh scaling --out out/scaling
#   sbatch --array=1-16 tools/slurm-shards.sh sensitivity leaf-spring --method fdm-central \
#       --beta 1e-6 --out out/leaf-fdm
#   sbatch --dependency=afterok:JOBID tools/slurm-shards.sh --merge out/validation
#
# The same with GNU parallel on one machine or over ssh logins (--sshloginfile):
#
#   parallel fricsens validate --shard {}/8 --out out/validation ::: $(seq 8) \
#       && fricsens merge out/validation/partial-*-of-8.json
#
#SBATCH --job-name=fricsens-shards
#SBATCH --cpus-per-task=2
#SBATCH --time=02:00:00
set -euo pipefail
FRICSENS=${FRICSENS:-fricsens}
if [[ "${1:-}" == "--merge" ]]; then
  exec "$FRICSENS" merge "$2"/partial-*-of-*.json --out "$2"
fi
: "${1:?give the fricsens command to shard, e.g. validate --out out/validation}"
: "${SLURM_ARRAY_TASK_ID:?run as a job array: sbatch --array=1-N}"
: "${SLURM_ARRAY_TASK_COUNT:?run as a job array: sbatch --array=1-N}"
exec "$FRICSENS" "$@" --shard "$SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT"
