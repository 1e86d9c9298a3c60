# Lent-GPU production of shipped campaigns, resumable across calls (stores under /tmp/st; a previous machine's store
# can be carried back as .device-stores/NAME.store).  Each store comes back as one file, $OUT/NAME.jsonl.gz (the
# shipped export, bubblecal.data.export_compressed), also left in /tmp/train for training on the same machine.
#   usage: bash benchmarks/device/prod_campaigns.sh NAME [NAME ...]
#   env: PROD_TIMEOUT total seconds (default 550), RPT replicas per task (default: the campaign file's),
#        WORKERS Dask LocalCluster processes (default: in-process, no Dask; in-process runs store each quasi-static
#        indentation curve as it finishes).  One campaign at a time: processes sharing the GPU without MPS
#        time-slice it and the slowest curves crawl (benchmarks/RESULTS.md, session 10: 9 processes, 24 min,
#        no task finished).
source ${SETUP_SH:-benchmarks/device/setup.sh} >/dev/null 2>&1
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
T0=$(date +%s)
T_END=$(( T0 + ${PROD_TIMEOUT:-550} ))
ST=${ST_DIR:-/tmp/st}; TR=${TRAIN_DIR:-/tmp/train}
mkdir -p $ST $TR
EXTRA=""
[ -n "$RPT" ] && EXTRA="$EXTRA --replicas-per-task $RPT"
[ -n "$WORKERS" ] && EXTRA="$EXTRA --workers $WORKERS"

run_one() {
  NAME=$1
  if [ ! -d $ST/$NAME.store ] && [ -d .device-stores/$NAME.store ]; then cp -r .device-stores/$NAME.store $ST/; fi
  LEFT=$(( T_END - $(date +%s) ))
  RC=1
  if [ $LEFT -gt 20 ]; then
    timeout $LEFT python3 benchmarks/device/run_campaign.py $NAME $ST/$NAME.store $EXTRA > $ST/$NAME.log 2>&1
    RC=$?
    echo "$NAME rc=$RC after $(( $(date +%s) - T0 )) s"
  fi
  grep -v "^Module" $ST/$NAME.log | tail -3 | cut -c1-700
  # only a finished design is exported (training waits for the file); an unfinished store stays in $ST
  # (sweep_status.sh returns it as NAME.store.tgz; carried back as .device-stores/NAME.store it resumes)
  if [ $RC -eq 0 ] && [ -d $ST/$NAME.store ]; then
    python3 -c "from bubblecal.data import export_compressed as e; e('$ST/$NAME.store', '$TR/$NAME.jsonl.gz')" \
      && cp $TR/$NAME.jsonl.gz $OUT/
  fi
}

for NAME in "$@"; do run_one $NAME; done
ls -la $OUT
