#!/usr/bin/env bash
# Session 60: out of core at 200 M points leaves 2–5 of 16 cores idle (`1-h100-ooc-dirty`).
# On dev the idle threads wait in synchronous discards: the work directory's ext4 has no
# journal and is mounted with `discard`, so every hole punched in a run file
# (`pio::release`) frees blocks and waits for the disk's discard (stack: fallocate →
# ext4_punch_hole → ext4_free_blocks → blkdev_issue_discard → submit_bio_wait). The device's
# root file system has the same mount options. Variants of ac85753 with switches
# (`../x-switches.diff`, not committed): base; XBG=1 (the punches made by a thread of their
# own, `runs::Releaser`, so that the loading threads do not wait for the discards);
# XW=1 (runs through `write`, no reserved blocks: delayed allocation, so pages given back
# before writeback never get blocks). Alternated, two rounds; every thread's state and kernel
# wait channel sampled every ~5 ms (shell builtins): threads running and waiting a sample.
# Carry `.dev60` (pointlet-x.xz, the `time` .deb). ~3 min.
# Run: run(command="bash docs/bench/issue15/session60/3-h100-release/call.sh", carry=[".dev60"])
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
Z=/tmp/pointlet; xz -dc .dev60/pointlet-x.xz > $Z && chmod +x $Z
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w60
mkdir -p $W; SECONDS=0; trap 'rm -rf $W' EXIT
uname -r; findmnt -T $W -o SOURCE,FSTYPE,OPTIONS | tail -1; cat /proc/fs/ext4/*/options 2>/dev/null | grep -c journal_checksum
ls /proc/fs/jbd2/ 2>&1 | head -2; for d in /sys/block/*/queue/discard_max_bytes; do echo "$d $(cat $d)"; done | head -3
timeout 100 $Z generate --points ${N:-200M} -o $W/g.las 2>&1 | tail -1
sync; cat $W/g.las > /dev/null
conv() { # label budget, env from the caller
  sync
  $Z convert $W/g.las -o $W/s.pointlet --ram-budget $2 > $W/conv.txt 2>&1 &
  local P=$! t0=$EPOCHREALTIME nap line wc rest now
  exec {nap}<> <(:)
  while [ -d /proc/$P/task ]; do
    now=$(( (${EPOCHREALTIME/./} - ${t0/./}) / 1000 ))
    for t in /proc/$P/task/*; do
      read -r line 2>/dev/null < $t/stat || continue
      wc=; read -r wc 2>/dev/null < $t/wchan; wc=${wc:-?}
      rest=${line##*) }
      echo "$now ${t##*/} ${rest%% *} $wc"
    done
    read -r -t 0.005 -u $nap
  done > $W/s.txt
  wait $P; echo "$1: $(tail -1 $W/conv.txt | sed "s|$W/||; s/written through a mapping of the file; //")"
  rm -f $W/s.pointlet
  local rs=$(grep -o 'reading [0-9.]* s' $W/conv.txt | awk '{print $2 * 1000}')
  for stage in reading rest; do
    awk -v rs=$rs -v st=$stage '(st == "reading") == ($1 < rs) { t[$1]; n++; if ($3 == "R") r++; else w[$3 ":" $4]++ }
      END { s = length(t); printf "  %s: %d samples, threads running %.1f a sample; waits a sample:", st, s, r / s;
            for (k in w) if (w[k] >= 0.1 * s) printf " %s %.1f", k, w[k] / s; print "" }' $W/s.txt
  done
}
for r in $(seq ${ROUNDS:-2}); do
  [ $r = 1 ] && conv "r$r mem" 24GiB
  for v in base bg written; do
    case $v in base) conv "r$r $v" 1GiB;; bg) XBG=1 conv "r$r $v" 1GiB;; written) XW=1 conv "r$r $v" 1GiB;; esac
  done
done
echo "at $SECONDS s"
