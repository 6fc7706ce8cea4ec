#!/usr/bin/env bash
# Submits a whole sharded batch to Slurm (README "Clusters"): the job array of
# typemerge-array.sbatch, one task per shard, then the merge step, which runs once every task
# has ended, whatever its state (--dependency=afterany), and joins the shard summaries.
#
#   submit.sh ROOT OUT [batch options] [-- sbatch options]
#
# Batch options default to --preset bone. sbatch options (--partition, --account, --time,
# --cpus-per-task, --mem, --output, ...) go to both jobs and take precedence over the script's
# #SBATCH defaults (2 CPUs, 8G, 4 h a task); sbatch's SBATCH_* variables work as usual.
# TYPEMERGE_SHARDS (default 16) is the shard count N, TYPEMERGE_BIN the typemerge executable
# (default: the one on PATH); both reach the jobs through the environment, so a failed task
# resubmitted with `sbatch --array=K typemerge-array.sbatch ROOT OUT [batch options]` in the
# same environment converts the same shard K/N. Prints both job ids.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
if (($# < 2)); then
  echo "usage: submit.sh ROOT OUT [batch options] [-- sbatch options]" >&2
  exit 2
fi
root="$1"
out="$2"
shift 2
batch_options=()
while (($#)) && [[ "$1" != "--" ]]; do
  batch_options+=("$1")
  shift
done
(($#)) && shift  # the "--"
sbatch_options=("$@")

export TYPEMERGE_SHARDS="${TYPEMERGE_SHARDS:-16}"
typemerge="${TYPEMERGE_BIN:-typemerge}"

array_job="$(sbatch --parsable --array="1-$TYPEMERGE_SHARDS" "${sbatch_options[@]}" \
  "$here/typemerge-array.sbatch" "$root" "$out" "${batch_options[@]}")"
array_job="${array_job%%;*}"  # "id;cluster" on a federation
merge_job="$(sbatch --parsable --job-name=typemerge-merge --dependency="afterany:$array_job" \
  --cpus-per-task=1 --mem=1G --time=00:30:00 --output=typemerge-merge-%j.out \
  "${sbatch_options[@]}" \
  --wrap "exec $(printf '%q' "$typemerge") batch --merge-summaries --out $(printf '%q' "$out")")"
merge_job="${merge_job%%;*}"
echo "array job $array_job: shards 1-$TYPEMERGE_SHARDS of $root into $out"
echo "merge job $merge_job: joins the shard summaries after $array_job ends"
