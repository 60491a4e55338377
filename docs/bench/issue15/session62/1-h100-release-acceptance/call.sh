#!/usr/bin/env bash
# Session 62, call 1: session 60's prepared comparison (`../../session60/3-h100-release`) and
# the acceptance of issue 15 on the same host. One build, HEAD (3ca8d4b, no conversion code
# changed since ac85753 but the builder's raw bounds) plus `../../session60/x-switches.diff`;
# without the switches it is HEAD. First the out-of-core variants, alternated, every thread's
# state and kernel wait channel sampled every ~5 ms: base (the read pages' holes punched by
# the loading threads), XBG=1 (punched by a thread of its own, `runs::Releaser`), XW=1 (runs
# written through `write`, no blocks reserved). Then `scripts/convert-bench.sh` without
# switches: LAS in memory and out of core three rounds, the LAZ ratio over five alternated
# rounds, PotreeConverter once. Carry `.dev62`: pointlet-x.xz (`cargo build --release -p
# pointlet`, `objcopy --strip-debug`, `xz -6`), PotreeConverter's folder, the `time` .deb.
# Run: run(command="bash docs/bench/issue15/session62/1-h100-release-acceptance/call.sh", carry=[".dev62"])
# N=2M OUT=DIR bash …/call.sh is a dry run on dev.
set -uo pipefail
mkdir -p $OUT; exec > >(tee "$OUT/log.txt") 2>&1
Z=/tmp/pointlet; xz -dc .dev62/pointlet-x.xz > $Z && chmod +x $Z
[ -x /usr/bin/time ] || dpkg -x .dev62/time_*.deb /
W=$(for d in /tmp $PWD/..; do echo "$(df --output=avail -k $d | tail -1) $d"; done | sort -n | tail -1 | cut -d' ' -f2)/w62
P=${N:-200M}
mkdir -p $W; SECONDS=0; trap 'rm -rf $W' EXIT
uname -r; lscpu | grep -E 'Model name|^CPU\(s\)'; findmnt -T $W -o SOURCE,FSTYPE,OPTIONS | tail -1
timeout 100 $Z generate --points $P -o $W/partial.las 2>&1 | tail -1 && mv $W/partial.las $W/gen-$P.las
sync; cat $W/gen-$P.las > /dev/null
conv() { # label budget, env from the caller
  sync
  $Z convert $W/gen-$P.las -o $W/s.pointlet --ram-budget $2 --tmp $W > $W/conv.txt 2>&1 &
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
echo "variants done at $SECONDS s"
POINTLET=$Z POINTS=$P ROUNDS=3 LAZ_ROUNDS=${LAZ_ROUNDS:-5} POTREE_ROUNDS=1 \
  POTREE=.dev62/potree-converter/run.sh timeout $((570 - SECONDS)) bash scripts/convert-bench.sh $W/cb $W
grep -h '^wrote' $W/cb/las-*.txt $W/cb/laz-mem-*.txt | sed "s|$W/||"
tar -C $W -czf $OUT/cb.tar.gz cb
echo "at $SECONDS s"
