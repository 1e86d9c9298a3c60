# Lent GPU(s): progress of the background sweeps (architectures checkpointed per set) and campaigns; the checkpoints,
# logs and exported campaign sets come back as $OUT/sw.tgz and $OUT/NAME.jsonl.gz, unfinished campaign stores as
# $OUT/NAME.store.tgz (the device returns <= 8 files).
for D in /tmp/sw/*/; do [ "$(basename $D)" = claims ] && continue
  NAME=$(basename $D); N=$(ls $D/checkpoints/arch_*.npz 2>/dev/null | wc -l)
  echo "$NAME: $N/12 architectures checkpointed: $(cd $D/checkpoints 2>/dev/null && ls arch_*.npz 2>/dev/null | sed 's/arch_//;s/.npz//' | tr '\n' ' ')"
done
echo "markers: $(cd /tmp/sw 2>/dev/null && ls -d *done 2>/dev/null | tr '\n' ' ')"
for L in /tmp/sw/campaigns*.log; do [ -f $L ] && grep -E "rc=|valid|ok" $L | tail -6 | cut -c1-300; done
for L in /tmp/sw/lane*_after.log; do [ -f $L ] && echo "$(basename $L): $(tr '\r' '\n' < $L | grep -v '^\s*$' | tail -2 | cut -c1-300)"; done
for L in /tmp/st/*.log; do [ -f $L ] && echo "$(basename $L): $(tr '\r' '\n' < $L | grep -v '^\s*$' | tail -1 | cut -c1-200)"; done
tail -4 /tmp/sw/finished.txt 2>/dev/null
grep -l "rc=[1-9]" /dev/null $(ls /tmp/sw/finished.txt 2>/dev/null) >/dev/null && grep "rc=[1-9]" /tmp/sw/finished.txt | head
tar -czf $OUT/sw.tgz -C /tmp --exclude='sw/*/run_*/*.npz' sw 2>/dev/null; ls -la $OUT/sw.tgz
for F in /tmp/train/*.jsonl.gz; do [ -f $F ] && [ "${COPY_SETS:-1}" = 1 ] && cp $F $OUT/; done
# unfinished stores too (streamed records survive a machine taken back): NAME.store.tgz -> tar -xzf -C .device-stores
for S in /tmp/st/*.store; do [ -d $S ] && [ "${COPY_STORES:-1}" = 1 ] && [ ! -f /tmp/train/$(basename $S .store).jsonl.gz ] \
  && tar -czf $OUT/$(basename $S).tgz -C /tmp/st $(basename $S); done
nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader
uptime
