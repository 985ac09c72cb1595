#!/usr/bin/env bash
# Runs a railgrip campaign on a Slurm cluster: the campaign's calibration, then a job array of N
# estimate shards, then the models stage once every shard has finished (docs/cluster.md). The output folder must be on a file
# system every node sees. Extra sbatch options (partition, account, time) go in SBATCH_OPTS,
# the models job's own (cores, memory) in SBATCH_MODELS_OPTS.
#
#   scripts/slurm-campaign.sh ARCHIVE OUT N [PIPELINE]
#
# OUT may be s3://BUCKET/PREFIX (the AWS_* variables reach the jobs through sbatch's default
# --export=ALL). Prints the three job ids. RAILGRIP (default: railgrip on PATH) is the binary the
# jobs run; SLURM_LOGS the folder of the jobs' logs (default OUT/slurm, ./railgrip-slurm for s3://).
set -euo pipefail
if [ $# -lt 3 ] || [ $# -gt 4 ]; then
    echo "usage: $0 ARCHIVE OUT N [PIPELINE]" >&2
    exit 2
fi
archive=$1 out=$2 n=$3
pipeline=()
[ $# -eq 4 ] && pipeline=(--pipeline "$4")
case $n in
    '' | *[!0-9]* | 0) echo "$0: N = '$n': give the number of shards (≥ 1)" >&2; exit 2 ;;
esac
railgrip=${RAILGRIP:-railgrip}
sbatch=${SBATCH:-sbatch}
read -r -a opts <<< "${SBATCH_OPTS:-}"
read -r -a models_opts <<< "${SBATCH_MODELS_OPTS:-}"
# Job logs beside the outputs, or (for an s3:// output) in SLURM_LOGS, default ./railgrip-slurm.
case $out in
    *://*) logs=${SLURM_LOGS:-$PWD/railgrip-slurm} ;;
    *) logs=${SLURM_LOGS:-$out/slurm} ;;
esac
mkdir -p "$logs"

# The campaign's calibration (OUT/calibration.json, when the pipeline asks for one), which every
# shard and the models job take from OUT. Should it fail, the shards and the models job are
# cancelled (--kill-on-invalid-dep; the models job also depends on it with afterok, since
# afterany on cancelled shards would let it start), not left pending.
calib=$("$sbatch" --parsable "${opts[@]}" --job-name=railgrip-calibrate \
    --output="$logs/calibrate.log" \
    --wrap="$(printf '%q ' "$railgrip" run "$archive" --out "$out" "${pipeline[@]}" --stage calibrate)")
calib=${calib%%;*}
# One task per shard; each estimates every N-th run into the shared folder, one core each.
shards=$("$sbatch" --parsable "${opts[@]}" --job-name=railgrip-estimate --array="1-$n" \
    --dependency="afterok:$calib" --kill-on-invalid-dep=yes \
    --cpus-per-task=1 --output="$logs/estimate-%a.log" \
    --wrap="$(printf '%q ' "$railgrip" run "$archive" --out "$out" --jobs 1 "${pipeline[@]}" \
        --stage estimate --shard)\"\$SLURM_ARRAY_TASK_ID/$n\"")
shards=${shards%%;*}
# Training and the report, once every shard succeeded (exit 3, some runs failed, counts as done).
models=$("$sbatch" --parsable "${opts[@]}" "${models_opts[@]}" --job-name=railgrip-models \
    --dependency="afterany:$shards,afterok:$calib" --kill-on-invalid-dep=yes --output="$logs/models.log" \
    --wrap="$(printf '%q ' "$railgrip" run "$archive" --out "$out" "${pipeline[@]}" --stage models)")
echo "calibration: job $calib; estimate shards: job $shards (array 1-$n); models: job ${models%%;*}"
