# DPD engine benchmark + GPU tests on CUDA.
. benchmarks/device/setup.sh
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
timeout ${BENCH_TIMEOUT:-380} python3 benchmarks/dpd_engine.py --device cuda --out $OUT/bench.json "$@" > $OUT/bench.log 2>&1
echo "bench rc=$?"
grep -v "^Module" $OUT/bench.log | tail -40
timeout 120 python3 -m pytest tests/sim/test_gpu.py -m gpu -q -p no:cacheprovider > $OUT/pytest_gpu.log 2>&1
echo "pytest gpu rc=$?"; tail -5 $OUT/pytest_gpu.log
