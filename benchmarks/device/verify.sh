# Full `bubblecal sim verify` on CUDA (run after benchmarks/device/setup.sh is available).
. benchmarks/device/setup.sh
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
timeout ${VERIFY_TIMEOUT:-420} python3 -m bubblecal.workflows.cli sim verify --device cuda "$@" > $OUT/verify_full.log 2>&1
echo "verify rc=$?"
grep -v "^Module\|warning" $OUT/verify_full.log | tail -60
