# Lent GPU(s): the next round of issue 6 item 6 measurements (curves per GPU-hour), one lane per GPU, each < 9 min.
#   usage (after setup.sh, /tmp/ref holding ../shared/reference):
#     LANE_AFTER_0="bash benchmarks/device/throughput_lanes.sh 0" LANE_AFTER_1="bash benchmarks/device/throughput_lanes.sh 1" \
#       bash benchmarks/device/sweep_pipeline.sh "-/-"      # then poll: OUT=$OUT bash benchmarks/device/sweep_status.sh
#   lane 0: the quasi-static shell forces per element (force_mode scatter) against session 13's per-vertex gather:
#           the FIRE iteration profile, then the 3.2 and 5.8 um campaigns at the fastest validated settings
#   lane 1: the explicit engine's kernel split (dpd_engine.py), the implicit tier at a saturating batch (3.2 um, 256 LHS rows, protocol scale 0.1), then the 3.4 um
#           campaign with scatter
#   results: /tmp/sw/itcost_scatter.log, /tmp/sw/implicit256 (come back in sw.tgz), /tmp/st/*.log and the stores
LANE=${1:?lane 0 or 1}
RC="python3 benchmarks/device/run_campaign.py"
FAST="--max-replicas 1000 --tier-setting first_load_ramp=6 --tier-setting stop_unstable=true --tier-setting force_mode=scatter"
mkdir -p /tmp/st /tmp/sw
if [ "$LANE" = 0 ]; then
  date +%T; for R in 1000 62; do python3 benchmarks/qs_iteration_cost.py --device cuda --replicas $R --active all,1 \
    --iters 2000 --profile 100 --force-mode scatter; done > /tmp/sw/itcost_scatter.log 2>&1
  date +%T; $RC sonovue_indentation_3.2um_mirheo /tmp/st/s32sc.store $FAST > /tmp/st/s32sc.log 2>&1
  date +%T; $RC sonovue_indentation_5.8um_mirheo /tmp/st/s58sc.store $FAST > /tmp/st/s58sc.log 2>&1
else
  # the explicit engine's kernel split today (pure fluid vs 64 batched 3 um bubbles): where a bubble system's step goes
  date +%T; python3 benchmarks/dpd_engine.py --device cuda --cases i,iii --out /tmp/sw/dpd_engine.json > /tmp/sw/dpd_engine.log 2>&1
  date +%T; python3 benchmarks/tier_validation.py --device cuda --scale 0.1 --seed 3 --reference /tmp/ref --tiers implicit \
    --rows 0 --lhs 256 --diameters 3.2 --indentation-convention mirheo --out /tmp/sw/implicit256 > /tmp/sw/implicit256.log 2>&1
  date +%T; $RC sonovue_indentation_3.4um_mirheo /tmp/st/s34sc.store $FAST > /tmp/st/s34sc.log 2>&1
fi
date +%T
