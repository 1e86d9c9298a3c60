# Lent-GPU helper: unpack Warp packed by ../shared/tools/device-pack (stash part A first), put the repo on the path.
# unpack Warp (stash part A + carried part B), trimesh wheels, put the repo on the path
set -e
if [ ! -d /tmp/site/warp ]; then
  mkdir -p /tmp/site && cat /root/stash/part-aa .warp-b/part-ab | xz -d | tar -x -C /tmp/site
  python3 -m pip install -q --no-index --no-deps --target /tmp/site .device-wheels/*.whl
fi
rm -f /tmp/site/bubblecal && ln -s "$PWD" /tmp/site/bubblecal
export PYTHONPATH=/tmp/site PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv
python3 -c "import warp as wp; wp.config.quiet=True; wp.init(); print('warp', wp.__version__, wp.get_cuda_devices())"
set +e
