# Sourced by the scripts of bench/device: the repository root as working directory, the
# build folder, the CLI and the data copies every device call carries in .devdata
# (copies of ../shared/data: CMU Panoptic basketball, 30 timesteps; the tiny D-NeRF lego).
# A device call carries at most 64 MiB: the tracked tree (44 MB, 28 MB of it the fuzz corpora)
# plus .devdata (22 MB) is over it, so move tests/fuzz/corpus out of the tree for the calls
# (only issue23_24.sh with FUZZ=1 reads it there; multi_gpu_session.sh fuzzes from .fuzzcorpus) and
# put it back afterwards.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
BUILD=${ATEX_GPU_BUILD:-bg}  # git-ignored: on a lent machine only ignored folders persist between calls
atex=$BUILD/bin/atex
bb=${ATEX_DEVDATA:-.devdata}/panoptic_basketball
lego=${ATEX_DEVDATA:-.devdata}/dnerf_lego_tiny/tiny_dnerf_data.npz
mkdir -p out

# Configures source tree SRC for a Release CUDA build (sm_90) in DIR and builds TARGET... with
# JOBS parallel jobs; BUILD_TREE_OPTIONS adds cmake options.
build_tree() {  # SRC DIR JOBS TARGET...
  # ATEX_SKIP_BUILD=1: the caller built already (background steps that outlive a device call must
  # not touch the source tree, which the next call replaces)
  [ -n "${ATEX_SKIP_BUILD:-}" ] && return 0
  local src=$1 dir=$2 jobs=$3
  shift 3
  # shellcheck disable=SC2086  # the options are words
  cmake -S "$src" -B "$dir" -DCMAKE_BUILD_TYPE=Release -DATEX_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES=90 \
    ${BUILD_TREE_OPTIONS:-} > /dev/null
  cmake --build "$dir" -j "$jobs" --target "$@"
}

# The CLI of .oldsrc (an earlier commit: `git archive COMMIT | tar -x -C .oldsrc`) in build-old,
# for A/B runs against the current tree; with a second argument NAME, that of .NAMEsrc in
# build-NAME (a third build, e.g. the last commit beside the old one and the working tree).
build_old() {  # JOBS [NAME]
  local name=${2:-old}
  BUILD_TREE_OPTIONS="-DATEX_TESTS=OFF -DATEX_BENCHMARKS=OFF" build_tree ".${name}src" "build-$name" "$1" atex_cli
}

# The shortened Panoptic stage-1 model of the A/B scripts, DIR/stage1.atex (6,000 fine steps,
# report DIR/stage1.train.json), trained on GPU unless DIR has it already; ARGS... are more
# train options.
train_short_stage1() {  # DIR GPU [ARGS...]
  [ -f "$1/stage1.atex" ] && return 0
  local dir=$1 gpu=$2
  shift 2
  mkdir -p "$dir"
  CUDA_VISIBLE_DEVICES=$gpu "$atex" train --data "$bb" --stage 1 --out "$dir/stage1.atex" --json \
    --set stage1.fine_iterations=6000 "$@" > "$dir/stage1.train.json" 2> "$dir/stage1.log"
}

# Steps that outlive a device call (10 minutes a command): a script defines `steps` (which
# writes DIR/steps.log through a `note` of its own, first "orchestrator started", last "done")
# and `snapshot` (which writes OUT/progress.txt and the archives that come back).
#
# True while the orchestrator of DIR/steps.pid runs.
steps_running() {  # DIR
  [ -f "$1/steps.pid" ] && kill -0 "$(cat "$1/steps.pid")" 2>/dev/null
}
# Starts `steps` under setsid, so that it runs on after the call while the machine stays warm;
# SETUP (shell words) runs first in the new shell.
start_steps() {  # DIR SETUP
  export -f steps
  setsid nohup bash -c "source bench/device/common.sh; $2; steps" > "$1/orchestrator.log" 2>&1 &
  echo $! > "$1/steps.pid"
}
# True when the last orchestrator of DIR has written "done" (the log keeps earlier attempts' lines).
steps_finished() {  # DIR
  tac "$1/steps.log" 2>/dev/null | sed '/\] orchestrator started$/q' | grep -q "\] done$"
}
# Calls `snapshot` every 15 s until COMMAND... succeeds or CALL_SECONDS (default 540) have passed
# since START, then once more, and prints OUT/progress.txt.
follow_until() {  # START OUT COMMAND...
  local since=$1 progress=$2/progress.txt
  shift 2
  while ! "$@"; do
    [ $(( $(date +%s) - since )) -ge "${CALL_SECONDS:-540}" ] && break
    snapshot
    sleep 15
  done
  snapshot
  cat "$progress"
}
