# Lent-GPU production of shipped campaigns, resumable across calls (stores under /tmp, copied to $OUT; carry a previous
# call's store back as .device-stores/NAME.store).  usage: bash benchmarks/device/prod_campaigns.sh NAME [NAME ...]
# env: PROD_TIMEOUT total seconds (default 550), RPT replicas per task (default 2000)
source benchmarks/device/setup.sh >/dev/null 2>&1
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
T_END=$(( $(date +%s) + ${PROD_TIMEOUT:-550} ))
for NAME in "$@"; do
  mkdir -p /tmp/st; rm -rf /tmp/st/$NAME.store
  if [ -d .device-stores/$NAME.store ]; then cp -r .device-stores/$NAME.store /tmp/st/; fi
  LEFT=$(( T_END - $(date +%s) ))
  if [ $LEFT -gt 20 ]; then
    timeout $LEFT python3 benchmarks/device/run_campaign.py $NAME /tmp/st/$NAME.store --replicas-per-task ${RPT:-2000} > $OUT/$NAME.log 2>&1
    echo "$NAME rc=$? after $(( $(date +%s) - T_END + ${PROD_TIMEOUT:-550} )) s"
  fi
  grep -v "^Module" $OUT/$NAME.log | tail -3 | cut -c1-500
  if [ -d /tmp/st/$NAME.store ]; then mkdir -p $OUT/$NAME.store; cp /tmp/st/$NAME.store/* $OUT/$NAME.store/; fi
done
du -sh $OUT/*
