# Lent GPU(s), in the background: regenerate campaign sets, then the 12-architecture sweeps of every training set
# with the small widths on CPU cores (one architecture per process, 1 torch thread) and the widest on the GPUs, all
# writing per-architecture checkpoints to /tmp/sw/NAME/checkpoints (key = data hash + split + recipe, not the
# device), so a later `bubblecal surrogates train ... --sweep --checkpoints DIR` anywhere reuses all twelve.
#   usage: bash benchmarks/device/sweep_pipeline.sh LANES NAME:SETUP:DIA:DATA [...]
#     LANES: campaigns per GPU, "/" between GPUs: "A,B/C" runs A then B on GPU 0 and C on GPU 1 (one process per
#            GPU: processes sharing a GPU without MPS time-slice it); "-" for none.  A DATA under /tmp/train
#            appears when its campaign has been exported; a job waits for its DATA.
#   env: CPU_WIDTHS (32,64,128) GPU_WIDTHS (256) CPU_PAR (14) GPU_JOBS per GPU (2) MAX_EPOCHS (1000);
#        LANE_AFTER_<k>: a command run on GPU k after its campaigns, before it takes training jobs (e.g. a
#        tier validation writing under /tmp/sw, which comes back in sw.tgz);
#        for the campaigns (benchmarks/device/prod_campaigns.sh): RPT (the file's), WORKERS, PROD_TIMEOUT (1500);
#        for tests (tests/test_device_scripts.py, a fake python3): SETUP_SH, SW_DIR, TRAIN_DIR, PROD_OUT, POLL_S
#   progress and results: bash benchmarks/device/sweep_status.sh
SW=${SW_DIR:-/tmp/sw}; TR=${TRAIN_DIR:-/tmp/train}  # (the dirs are settable for the local test)
if [ "$1" = "--body" ]; then
  # ---- the background body (started below with setsid) ----
  shift; LANES=$1; shift
  ( xargs -r -P ${CPU_PAR:-14} -L 1 $SW/train_one.sh < $SW/cpu_jobs.txt; touch $SW/cpu_done ) &
  K=0
  for LANE in $(echo "$LANES" | tr / ' '); do
    (
      export CUDA_VISIBLE_DEVICES=$K
      if [ "$LANE" != "-" ]; then
        OUT=${PROD_OUT:-/tmp/prod_out} PROD_TIMEOUT=${PROD_TIMEOUT:-1500} RPT=${RPT:-} WORKERS=${WORKERS:-} \
          bash benchmarks/device/prod_campaigns.sh $(echo "$LANE" | tr , ' ') > $SW/campaigns_$K.log 2>&1
      fi
      touch $SW/lane${K}_campaigns_done
      AFTER=LANE_AFTER_$K
      [ -n "${!AFTER}" ] && { bash -c "${!AFTER}" > $SW/lane${K}_after.log 2>&1; touch $SW/lane${K}_after_done; }
      # this GPU alone now: training workers (the widest architectures), GPU_JOBS at once
      for J in $(seq ${GPU_JOBS:-2}); do bash $SW/gpu_worker.sh & done
      wait
      touch $SW/lane${K}_done
    ) &
    K=$((K + 1))
  done
  wait
  touch $SW/campaigns_done $SW/gpu_done
  exit 0
fi

source ${SETUP_SH:-benchmarks/device/setup.sh} >/dev/null 2>&1
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1 XLA_PYTHON_CLIENT_PREALLOCATE=false
mkdir -p $SW/claims $TR ${PROD_OUT:-/tmp/prod_out}
LANES=$1; shift
EP=${MAX_EPOCHS:-1000}
if [ -f $SW/pipeline.pid ] && kill -0 "$(cat $SW/pipeline.pid)" 2>/dev/null; then echo "pipeline running"; exit 0; fi

# one line per (set, architecture): width depth name setup dia data [device]
: > $SW/cpu_jobs.txt
: > $SW/gpu_jobs.txt
for SPEC in "$@"; do
  IFS=: read -r NAME SETUP DIA DATA <<< "$SPEC"
  mkdir -p $SW/$NAME/checkpoints
  # checkpoints carried back from an earlier machine (.device-stores/sw/NAME/checkpoints) are reused
  [ -d .device-stores/sw/$NAME/checkpoints ] && cp -n .device-stores/sw/$NAME/checkpoints/arch_*.npz $SW/$NAME/checkpoints/ 2>/dev/null
  # .device-stores/sw/NAME/have.txt lists architectures already trained elsewhere (WxD per line): skipped
  for W in $(echo ${CPU_WIDTHS:-32,64,128} | tr , ' ' | xargs -n1 | sort -rn); do for DEP in 4 3 2; do
    grep -qsx "${W}x${DEP}" .device-stores/sw/$NAME/have.txt && continue
    echo "$W $DEP $NAME $SETUP $DIA $DATA" >> $SW/cpu_jobs.txt; done; done
  for W in $(echo ${GPU_WIDTHS:-256} | tr , ' '); do for DEP in 4 3 2; do
    grep -qsx "${W}x${DEP}" .device-stores/sw/$NAME/have.txt && continue
    echo "$W $DEP $NAME $SETUP $DIA $DATA cuda" >> $SW/gpu_jobs.txt; done; done
done

cat > $SW/train_one.sh <<EOF
#!/bin/bash
# train one architecture into the set's checkpoint folder (waits for a campaign's export)
export JAX_PLATFORMS=cpu  # the parity check only: many processes must not each preallocate GPU memory
W=\$1; DEP=\$2; NAME=\$3; SETUP=\$4; DIA=\$5; DATA=\$6; DEV=\${7:-cpu}
while [ ! -f \$DATA ]; do sleep ${POLL_S:-10}; done
${PYTHON:-python3} -m bubblecal.workflows.cli surrogates train \$DATA --setup \$SETUP --diameter \$DIA --sweep --widths \$W \\
  --depths \$DEP --jobs 1 --device \$DEV --max-epochs $EP --no-onnx --quiet --checkpoints $SW/\$NAME/checkpoints \\
  --out $SW/\$NAME/run_\${W}x\${DEP} > $SW/\$NAME/log_\${W}x\${DEP}.txt 2>&1
echo "\$NAME \${W}x\${DEP} \$DEV\${CUDA_VISIBLE_DEVICES:+:\$CUDA_VISIBLE_DEVICES} rc=\$? \$(date +%T)" >> $SW/finished.txt
EOF
# a GPU training worker: claims queued jobs (atomic mkdir), those whose data exist first, until none is left
cat > $SW/gpu_worker.sh <<EOF
#!/bin/bash
while true; do
  LEFT=0; RAN=0; N=0
  while read -r LINE; do
    N=\$((N + 1))
    [ -d $SW/claims/\$N ] && continue
    LEFT=1
    [ -f "\$(echo \$LINE | cut -d' ' -f6)" ] || continue
    mkdir $SW/claims/\$N 2>/dev/null || continue
    $SW/train_one.sh \$LINE < /dev/null
    RAN=1; break
  done < $SW/gpu_jobs.txt
  [ \$LEFT = 0 ] && break
  [ \$RAN = 0 ] && sleep ${POLL_S:-10}
done
EOF
chmod +x $SW/train_one.sh $SW/gpu_worker.sh

( setsid nohup bash benchmarks/device/sweep_pipeline.sh --body "$LANES" > $SW/pipeline.log 2>&1 & echo $! > $SW/pipeline.pid )
echo "pipeline started (pid $(cat $SW/pipeline.pid)); lanes '$LANES'; $(wc -l < $SW/cpu_jobs.txt) CPU and" \
     "$(wc -l < $SW/gpu_jobs.txt) GPU architectures"
