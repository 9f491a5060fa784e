#!/usr/bin/env bash
# The stage-2 growth probes of BENCHMARKS.md (stage 2, seventh run), on the stage-1 models of seeds 2
# and 3 that the `seeds` job of parallel_session.sh left in out/seeds (same machine, still warm),
# one run per GPU of a machine of four:
#   probe2  adaptive, 1,200 steps, growth at steps 100 and 200 ("early") or threshold 1e-5 ("low"),
#           evaluated on the test and the training views
#   probe3  uniform and adaptive, 2,500 steps, growth at 250 and 500
#   bench/device/growth_probes.sh probe2|probe3 OUT_DIR   -> OUT_DIR/PROBE.tgz, test PSNRs on stdout
# Then, here: python3 bench/growth_probes.py collect out/probe2 out/probe3 --out PROBES.json
source "$(dirname "$0")/common.sh"
probe=$1 out=$2
dir=out/$probe
mkdir -p "$dir" "$out"
run() {  # GPU SEED NAME TEXTURES EVAL_TRAIN(0|1) SETTINGS...
  local gpu=$1 seed=$2 name=$3 textures=$4 eval_train=$5
  shift 5
  local model settings=()
  model=$(find out/seeds/models -path "*s$seed/stage1.atex" | head -1)
  for s in "$@"; do settings+=(--set "$s"); done
  CUDA_VISIBLE_DEVICES=$gpu "$atex" train --data "$bb" --stage 2 --init "$model" --textures "$textures" --seed "$seed" \
    "${settings[@]}" --out "$dir/$name.atex" --json > "$dir/$name.train.json" 2> "$dir/$name.log"
  CUDA_VISIBLE_DEVICES=$gpu "$atex" eval "$dir/$name.atex" --data "$bb" --json > "$dir/$name.eval.json"
  if [ "$eval_train" = 1 ]; then
    CUDA_VISIBLE_DEVICES=$gpu "$atex" eval "$dir/$name.atex" --data "$bb" --split train --json > "$dir/$name.evaltrain.json"
    "$atex" info "$dir/$name.atex" --json > "$dir/$name.info.json"
  fi
}
case $probe in
  probe2)
    run 0 2 s2_early adaptive 1 stage2.iterations=1200 'stage2.growth_steps=[100,200]' &
    run 1 2 s2_low adaptive 1 stage2.iterations=1200 stage2.growth_threshold=1e-5 &
    run 2 3 s3_early adaptive 1 stage2.iterations=1200 'stage2.growth_steps=[100,200]' &
    run 3 3 s3_low adaptive 1 stage2.iterations=1200 stage2.growth_threshold=1e-5 & ;;
  probe3)
    gpu=0
    for seed in 2 3; do
      for textures in uniform adaptive; do
        run $gpu $seed "s${seed}_$textures" $textures 0 stage2.iterations=2500 'stage2.growth_steps=[250,500]' &
        gpu=$((gpu + 1))
      done
    done ;;
  *) echo "unknown probe $probe" >&2; exit 2 ;;
esac
wait
tar czf "$out/$probe.tgz" "$dir"/*.json
for f in "$dir"/*.eval.json; do
  python3 -c "import json, sys; print(sys.argv[1], json.load(open(sys.argv[1]))['mean']['psnr'])" "$f"
done
