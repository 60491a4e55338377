#!/usr/bin/env bash
# session 33 call 3 (issue 15): where the mapped in-memory writing stage goes: per-stretch
# emit / sort / join times (XP_TRACE, experiment.diff on call 2's code; pointlet-t8) and one
# build under perf record (flat, by symbol; writing stage only by --time).
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
gunzip -c .dev/pointlet-t8.gz > /tmp/pointlet && chmod +x /tmp/pointlet
[ -x /usr/bin/time ] || dpkg -x .dev/time_*.deb /
tar xzf .dev/perfpk.tgz -C /tmp
PERF="/tmp/perfpk/lib/ld-linux-x86-64.so.2 --library-path /tmp/perfpk/lib /tmp/perfpk/perf"
W=/tmp/w; mkdir -p $W /tmp/cb; SECONDS=0
L=$W/g.las
/tmp/pointlet generate --points 200M -o $L 2>&1 | tail -1
sync; sleep 2; cat $L > /dev/null
M="convert $L -o $W/s.pointlet --ram-budget 24GiB"
for r in 1 2; do XP_TRACE=1 /tmp/pointlet $M > /tmp/cb/trace-$r.txt 2>&1; rm -f $W/s.pointlet; sync; grep -E "XP|wrote" /tmp/cb/trace-$r.txt | awk '/XP/{e+=$5; s+=$8; j+=$11; r+=$14; n++} /wrote/{print} END{printf "stretches %d: emit %.0f ms, sort %.0f ms, join %.0f ms, release %.0f ms\n", n, e, s, j, r}'; done
head -40 /tmp/cb/trace-2.txt | grep XP
$PERF record -F 1999 -o $W/p.data /tmp/pointlet $M > /tmp/cb/perf-mem.txt 2>&1
rm -f $W/s.pointlet; sync; tail -1 /tmp/cb/perf-mem.txt
$PERF report -i $W/p.data --no-children --sort sym 2>/dev/null | grep -v '^#' | grep '%' | head -60 > /tmp/cb/perf-all.txt
$PERF report -i $W/p.data --no-children --sort sym --time 45%-100% 2>/dev/null | grep -v '^#' | grep '%' | head -60 > /tmp/cb/perf-late.txt
$PERF report -i $W/p.data --no-children --sort comm 2>/dev/null | grep -v '^#' | grep '%' | head -20 > /tmp/cb/perf-comm.txt
head -40 /tmp/cb/perf-all.txt; echo ---; head -40 /tmp/cb/perf-late.txt; echo ---; cat /tmp/cb/perf-comm.txt
echo "at $SECONDS s"
cd /tmp/cb && tar czf $OUT/runs.tgz *.txt
rm -rf $W
