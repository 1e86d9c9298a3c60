# Lent GPU(s): issue 6 item 6 measurements (curves per GPU-hour), one lane per GPU, each < 10 min.
#   usage (after setup.sh, /tmp/ref holding ../shared/reference):
#     LANE_AFTER_0="bash benchmarks/device/throughput_lanes.sh 0" LANE_AFTER_1="bash benchmarks/device/throughput_lanes.sh 1" \
#       bash benchmarks/device/sweep_pipeline.sh "-/-"      # then poll: OUT=$OUT bash benchmarks/device/sweep_status.sh
#   lane 0: the FIRE iteration profile (per-vertex gather), then the 5.8 and 3.2 um campaigns at the fastest validated
#           settings; records carry fire_steps_chain (FIRE updates per chain point) for benchmarks/max_steps_study.py
#           (session 14 ran this lane with a gather computing one corner / dihedral role per element: 1.96 vs 1.90 ms
#           per 1,000-replica iteration, no gain, reverted)
#   lane 1: the implicit tier at a saturating batch (3.2 um, 256 LHS rows, scale 0.1); the explicit tier at the
#           published protocol length (scale 1) on the 2.9 um gate's rows (4 published + LHS rows 1-4 of --lhs 20
#           --seed 3), against the gate's scale-0.25 curves and Mirheo (3.2 um: session 14, x32s1)
#   results: /tmp/sw/itcost_gather.log, /tmp/sw/{implicit256,x29s1} (come back in sw.tgz), /tmp/st/*.log and the
#            stores (NAME.store.tgz)
LANE=${1:?lane 0 or 1}
RC="python3 benchmarks/device/run_campaign.py"
FAST="--max-replicas 1000 --tier-setting first_load_ramp=6 --tier-setting stop_unstable=true"
TV="python3 benchmarks/tier_validation.py --device cuda --seed 3 --reference /tmp/ref"
mkdir -p /tmp/st /tmp/sw
if [ "$LANE" = 0 ]; then
  date +%T; for R in 1000 62; do python3 benchmarks/qs_iteration_cost.py --device cuda --replicas $R --active all,1 \
    --iters 2000 --profile 100 --force-mode gather; done > /tmp/sw/itcost_gather.log 2>&1
  date +%T; $RC sonovue_indentation_5.8um_mirheo /tmp/st/s58g.store $FAST > /tmp/st/s58g.log 2>&1
  date +%T; $RC sonovue_indentation_3.2um_mirheo /tmp/st/s32g.store $FAST > /tmp/st/s32g.log 2>&1
else
  date +%T; $TV --scale 0.1 --tiers implicit --rows 0 --lhs 256 --diameters 3.2 --indentation-convention mirheo \
    --out /tmp/sw/implicit256 > /tmp/sw/implicit256.log 2>&1
  date +%T; $TV --scale 1 --tiers explicit --rows 4 --lhs 20 --lhs-slice 0:4 --diameters 2.9 \
    --out /tmp/sw/x29s1 > /tmp/sw/x29s1.log 2>&1
fi
date +%T
