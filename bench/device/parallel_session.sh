#!/usr/bin/env bash
# Several experiment matrices at once on a machine of several GPUs, running on between
# device calls (a lent machine allows 10 minutes per command; processes started with
# setsid outlive the call while the machine stays warm, so each next call must follow at once).
#   bench/device/parallel_session.sh start OUT_DIR   build, then start every job in the background
#   bench/device/parallel_session.sh wait  OUT_DIR   follow the jobs until they end or the call's time is up
# Jobs (JOBS, default "session stress"):
#   session: bench/configs/panoptic_session.json on all GPUs (out/panoptic), with FPS
#   stress:  bench/configs/stress_gpu.json on all GPUs but the first (out/stress), no FPS
#   sweep:   bench/configs/panoptic_stage1_sweep.json on all GPUs (out/sweep), with FPS
#   sametime: bench/configs/panoptic_same_time.json on all GPUs (out/same_time), with FPS
#   fastraster: bench/configs/panoptic_fast_raster.json on all GPUs (out/fast_raster), with FPS
#   seeds: bench/configs/panoptic_seeds.json on all GPUs (out/seeds), with FPS
#   protocols: bench/configs/panoptic_budget_protocols.json on all GPUs (out/protocols), no FPS
#   base:    bench/configs/panoptic_base.json on all GPUs (out/base), with FPS (issue 20)
#   base2:   bench/configs/panoptic_base2.json on all GPUs (out/base2), no FPS (issue 20)
#   init:    bench/configs/panoptic_init.json on all GPUs (out/init), with FPS (issue 20)
#   stereo:  bench/configs/panoptic_stereo.json on all GPUs (out/stereo), no FPS (issue 20, third run;
#            issue20.sh sheets times the models)
#   textures: bench/configs/panoptic_textures.json on all GPUs (out/textures), no FPS (issue 20: the
#            texture study on the new base)
#   temporal: bench/configs/panoptic_temporal.json on all GPUs (out/temporal), no FPS (issue 20, fourth
#            run; ONLY=REGEX narrows the config's cells: run_matrix's --only applies on top of its "only")
# With .oldsrc present, `start` also builds it into build-old in the background, for a later
# bench/device/raster_ab.sh on the models these jobs train (AB_MODEL_DIR).
# The two share GPUs through run_matrix's per-GPU lock files: one cell per GPU at a time.
# Each call leaves OUT_DIR/results.tgz (rows, logs; no models) and OUT_DIR/progress.txt.
source "$(dirname "$0")/common.sh"
phase=$1 out=$2
mkdir -p "$out"
start=${PARALLEL_SESSION_START:-$(date +%s)}  # the call's start: `start` passes it on to `wait`
CALL_SECONDS=${CALL_SECONDS:-570}
gpus=$(nvidia-smi --query-gpu=index --format=csv,noheader | paste -sd, -)
rest=${gpus#*,}
[ "$rest" = "$gpus" ] && rest=$gpus  # one GPU: both jobs use it, one cell at a time

launch() {  # name config out-dir gpu-list extra-args...
  local name=$1 config=$2 dir=$3 list=$4
  shift 4
  [ -f "out/$name.rc" ] && return 0
  if [ -f "out/$name.pid" ] && kill -0 "$(cat "out/$name.pid")" 2>/dev/null; then return 0; fi
  setsid nohup bash -c "python3 bench/run_matrix.py $config --atex $atex --out $dir --gpus $list $* \
      > out/$name.log 2>&1; echo \$? > out/$name.rc" > /dev/null 2>&1 &
  echo $! > "out/$name.pid"
  echo "started $name on GPUs $list"
}

snapshot() {
  {
    date +%T
    for j in ${JOBS:-session stress}; do
      echo "== $j: rc=$(cat out/$j.rc 2>/dev/null || echo running)"
      tail -n 40 "out/$j.log" 2>/dev/null || true
    done
    nvidia-smi --query-gpu=index,utilization.gpu,memory.used --format=csv,noheader || true
  } > "$out/progress.txt"
  tar czf "$out/results.tgz" --exclude='*.atex' --exclude='*.ckpt' out/panoptic out/stress out/sweep out/same_time \
    out/fast_raster out/seeds out/protocols out/base out/base2 out/init out/stereo out/temporal out/textures out/*.log out/*.rc \
    2>/dev/null || true
}

case $phase in
  start)
    bench/device/paper_runs.sh build "$out"
    if [ -d .oldsrc ] && [ ! -x build-old/bin/atex ]; then
      setsid nohup nice bash -c "source bench/device/common.sh && build_old 16" > out/build_old.log 2>&1 &
    fi
    for j in ${JOBS:-session stress}; do
      case $j in
        session) launch session bench/configs/panoptic_session.json out/panoptic "$gpus" ;;
        stress) launch stress bench/configs/stress_gpu.json out/stress "$rest" --skip-fps ;;
        sweep) launch sweep bench/configs/panoptic_stage1_sweep.json out/sweep "$gpus" ;;
        sametime) launch sametime bench/configs/panoptic_same_time.json out/same_time "$gpus" ;;
        fastraster) launch fastraster bench/configs/panoptic_fast_raster.json out/fast_raster "$gpus" ;;
        seeds) launch seeds bench/configs/panoptic_seeds.json out/seeds "$gpus" ;;
        protocols) launch protocols bench/configs/panoptic_budget_protocols.json out/protocols "$gpus" --skip-fps ;;
        base) launch base bench/configs/panoptic_base.json out/base "$gpus" ;;
        base2) launch base2 bench/configs/panoptic_base2.json out/base2 "$gpus" --skip-fps ;;
        init) launch init bench/configs/panoptic_init.json out/init "$gpus" ;;
        stereo) launch stereo bench/configs/panoptic_stereo.json out/stereo "$gpus" --skip-fps ;;
        textures) launch textures bench/configs/panoptic_textures.json out/textures "$gpus" --skip-fps ;;
        temporal) launch temporal bench/configs/panoptic_temporal.json out/temporal "$gpus" --skip-fps \
          ${ONLY:+--only "'$ONLY'"} ;;
        *) echo "unknown job $j" >&2; exit 2 ;;
      esac
    done
    PARALLEL_SESSION_START=$start "$0" wait "$out"
    ;;
  wait)
    jobs_done() {
      for j in ${JOBS:-session stress}; do [ -f "out/$j.rc" ] || return 1; done
    }
    follow_until "$start" "$out" jobs_done
    ;;
  *) echo "unknown phase $phase" >&2; exit 2 ;;
esac
