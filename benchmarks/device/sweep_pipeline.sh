# Lent GPU, in the background: regenerate campaign sets, then the 12-architecture sweeps of every training set with
# the small widths on CPU cores (one architecture per process, 1 torch thread) and the widest on the GPU, all
# writing per-architecture checkpoints to /tmp/sw/NAME/checkpoints (key = data hash + split + recipe, not the
# device), so a later `bubblecal surrogates train ... --sweep --checkpoints DIR` anywhere reuses all twelve.
#   usage: bash benchmarks/device/sweep_pipeline.sh CAMPAIGN[,CAMPAIGN..] NAME:SETUP:DIA:DATA [...]
#          (CAMPAIGN list may be "-"; a DATA under /tmp/train appears when its campaign has been exported)
#   env: CPU_WIDTHS (32,64,128) GPU_WIDTHS (256) CPU_PAR (14) GPU_JOBS (2) MAX_EPOCHS (1000); for the campaigns
#        (benchmarks/device/prod_campaigns.sh): RPT (the file's), WORKERS, PROD_TIMEOUT (1500)
#   progress and results: bash benchmarks/device/sweep_status.sh
source benchmarks/device/setup.sh >/dev/null 2>&1
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
mkdir -p /tmp/sw /tmp/train /tmp/prod_out
CAMPAIGNS=$1; shift
EP=${MAX_EPOCHS:-1000}
if [ -f /tmp/sw/pipeline.pid ] && kill -0 "$(cat /tmp/sw/pipeline.pid)" 2>/dev/null; then echo "pipeline running"; exit 0; fi

# one line per (set, architecture) for the CPU pool: width depth name setup dia data
: > /tmp/sw/cpu_jobs.txt
for SPEC in "$@"; do
  IFS=: read -r NAME SETUP DIA DATA <<< "$SPEC"
  mkdir -p /tmp/sw/$NAME/checkpoints
  # checkpoints carried back from an earlier machine (.device-stores/sw/NAME/checkpoints) are reused
  [ -d .device-stores/sw/$NAME/checkpoints ] && cp -n .device-stores/sw/$NAME/checkpoints/arch_*.npz /tmp/sw/$NAME/checkpoints/ 2>/dev/null
  for W in $(echo ${CPU_WIDTHS:-32,64,128} | tr , ' ' | xargs -n1 | sort -rn); do for DEP in 4 3 2; do
    # .device-stores/sw/NAME/have.txt lists architectures already trained elsewhere (WxD per line): skipped
    grep -qsx "${W}x${DEP}" .device-stores/sw/$NAME/have.txt && continue
    echo "$W $DEP $NAME $SETUP $DIA $DATA" >> /tmp/sw/cpu_jobs.txt; done; done
done

cat > /tmp/sw/train_one.sh <<EOF
#!/bin/bash
# train one architecture into the set's checkpoint folder (waits for a campaign's export)
export JAX_PLATFORMS=cpu  # the parity check only: 14 processes must not each preallocate GPU memory
W=\$1; DEP=\$2; NAME=\$3; SETUP=\$4; DIA=\$5; DATA=\$6; DEV=\${7:-cpu}
while [ ! -f \$DATA ]; do sleep 10; done
python3 -m bubblecal.workflows.cli surrogates train \$DATA --setup \$SETUP --diameter \$DIA --sweep --widths \$W \\
  --depths \$DEP --jobs 1 --device \$DEV --max-epochs $EP --no-onnx --quiet --checkpoints /tmp/sw/\$NAME/checkpoints \\
  --out /tmp/sw/\$NAME/run_\${W}x\${DEP} > /tmp/sw/\$NAME/log_\${W}x\${DEP}.txt 2>&1
echo "\$NAME \${W}x\${DEP} \$DEV rc=\$? \$(date +%T)" >> /tmp/sw/finished.txt
EOF
chmod +x /tmp/sw/train_one.sh

(
  setsid nohup bash -c "
    # CPU pool starts at once (indentation sets exist; compression jobs wait for their export)
    ( xargs -P ${CPU_PAR:-14} -L 1 /tmp/sw/train_one.sh < /tmp/sw/cpu_jobs.txt; touch /tmp/sw/cpu_done ) &
    if [ '$CAMPAIGNS' != '-' ]; then
      OUT=/tmp/prod_out PROD_TIMEOUT=${PROD_TIMEOUT:-1500} RPT=${RPT:-} WORKERS=${WORKERS:-} bash benchmarks/device/prod_campaigns.sh ${CAMPAIGNS//,/ } \
        > /tmp/sw/campaigns.log 2>&1
    fi
    touch /tmp/sw/campaigns_done
    # the GPU alone after the campaigns (they must not share it): widest first, GPU_JOBS at once
    : > /tmp/sw/gpu_jobs.txt
    for SPEC in $*; do IFS=: read -r NAME SETUP DIA DATA <<< \"\$SPEC\"
      for W in \$(echo ${GPU_WIDTHS:-256} | tr , ' '); do for DEP in 4 3 2; do
        grep -qsx \"\${W}x\${DEP}\" .device-stores/sw/\$NAME/have.txt && continue
        echo \"\$W \$DEP \$NAME \$SETUP \$DIA \$DATA cuda\" >> /tmp/sw/gpu_jobs.txt; done; done; done
    xargs -P ${GPU_JOBS:-2} -L 1 /tmp/sw/train_one.sh < /tmp/sw/gpu_jobs.txt
    touch /tmp/sw/gpu_done
  " > /tmp/sw/pipeline.log 2>&1 & echo $! > /tmp/sw/pipeline.pid
)
echo "pipeline started (pid $(cat /tmp/sw/pipeline.pid)); $(wc -l < /tmp/sw/cpu_jobs.txt) CPU architectures"
