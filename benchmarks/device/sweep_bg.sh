# Lent GPU: 12-architecture surrogate sweeps in the background, one process group per training set, resumable
# (each architecture is checkpointed under /tmp/sw/NAME/checkpoints as soon as it is trained; a restarted sweep
# reuses them).  Idempotent: a set whose sweep is running or finished is left alone.
#   usage: bash benchmarks/device/sweep_bg.sh NAME:SETUP:DIAMETER:DATA [...]      env: SWEEP_JOBS (default 2)
source benchmarks/device/setup.sh >/dev/null 2>&1
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
mkdir -p /tmp/sw
for SPEC in "$@"; do
  IFS=: read -r NAME SETUP DIA DATA <<< "$SPEC"
  D=/tmp/sw/$NAME
  if [ -f $D/done ] || { [ -f $D/pid ] && kill -0 "$(cat $D/pid)" 2>/dev/null; }; then echo "$NAME: running or done"; continue; fi
  mkdir -p $D
  ( setsid nohup bash -c "python3 -m bubblecal.workflows.cli surrogates train $DATA --setup $SETUP --diameter $DIA \
      --out $D --sweep --device cuda --jobs ${SWEEP_JOBS:-2} --max-epochs 1000 --no-onnx --quiet \
      --checkpoints $D/checkpoints > $D/train.log 2>&1 && touch $D/done" > /dev/null 2>&1 & echo $! > $D/pid )
  echo "$NAME: started (pid $(cat $D/pid))"
done
