#!/usr/bin/env bash
# device call 6: where the out-of-core build's idle end waits (wchan samples of every thread)
set -u
gzip -d -c .dev/pointlet.gz > /tmp/pointlet && chmod +x /tmp/pointlet
P=/tmp/pointlet; W=/tmp/cbw; R=$OUT/w6; mkdir -p $W $R
las=$W/g.las
$P generate --points 200M -o $las > /dev/null 2>&1
cat $las > /dev/null
$P convert $las -o $W/x.pointlet --ram-budget 1GiB --tmp $W > $R/run.txt 2>&1 &
pid=$!
t0=$(date +%s.%N)
while kill -0 $pid 2>/dev/null; do
  t=$(date +%s.%N)
  for d in /proc/$pid/task/*; do
    printf '%.2f %s %s %s\n' "$(awk -v a=$t -v b=$t0 'BEGIN{print a-b}')" "${d##*/}" "$(cat $d/stat 2>/dev/null | awk '{print $3}')" "$(cat $d/wchan 2>/dev/null)"
  done >> $R/wchan.txt
  sleep 0.1
done
wait $pid
grep -E "Dirty|Writeback" /proc/meminfo >> $R/run.txt
cd $OUT && tar czf w6.tgz w6 && rm -rf w6
