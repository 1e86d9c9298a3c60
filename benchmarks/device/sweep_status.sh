# Lent GPU: progress of the background sweeps (architectures checkpointed per set); everything under /tmp/sw comes
# back as one file, $OUT/sw.tgz (the device returns at most 8 files).
for D in /tmp/sw/*/; do
  NAME=$(basename $D); N=$(ls $D/checkpoints/arch_*.npz 2>/dev/null | wc -l)
  ST=running; [ -f $D/done ] && ST=done; [ -f $D/pid ] && ! kill -0 "$(cat $D/pid)" 2>/dev/null && [ ! -f $D/done ] && ST=stopped
  echo "$NAME: $N/12 architectures, $ST"; tail -c 400 $D/train.log | tr '\r' '\n' | grep -v "^\s*$" | tail -2 | cut -c1-200
done
tar -czf $OUT/sw.tgz -C /tmp sw 2>/dev/null; ls -la $OUT/sw.tgz
nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader
