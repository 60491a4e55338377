#!/usr/bin/env bash
# session 28 call 5: writes into mapped upload memory with 16-byte non-temporal stores (nt)
# against the standard copy (rep: libc's memcpy, `rep movsb` at these sizes), same binary
# (experiment switch XP_COPY=rep); the upload path measured with 1 / 4 / 16 writing threads
# (XP_UPLOAD_THREADS), then 50 M LAS and a 200 M store loaded with each, alternated.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
gunzip -c .dev/pointlet-xp.gz > /tmp/pointlet && chmod +x /tmp/pointlet
W=/tmp/w; mkdir -p $W
B() { local name=$1 file=$2; shift 2; /tmp/pointlet bench $file --realtime --target-fps 60 --json $OUT/$name.json "$@" > $OUT/$name.txt 2>&1; echo "$name: $(grep -E '^loading:' $OUT/$name.txt) $(grep -E '^upload path' $OUT/$name.txt) $(grep -iE 'error' $OUT/$name.txt | head -2)"; }
SECONDS=0
/tmp/pointlet generate --points 50M -o $W/p50.las 2>&1 | tail -1
sync; cat $W/p50.las > /dev/null
for t in 1 4 16; do for c in rep nt; do XP_COPY=$c XP_UPLOAD_THREADS=$t B up-$c-t$t $W/p50.las --orbit-seconds 1 --vram-budget 8GiB; done; done
for r in 1 2; do for c in rep nt; do XP_COPY=$c B las50-$c-$r $W/p50.las --orbit-seconds 2 --vram-budget 8GiB; done; done
rm -f $W/p50.las
echo "at $SECONDS s"
/tmp/pointlet generate --points 200M -o $W/s200.pointlet 2>&1 | tail -1
sync; sleep 1; cat $W/s200.pointlet > /dev/null
for r in 1 2 3; do for c in rep nt; do XP_COPY=$c B s200-$c-$r $W/s200.pointlet --progressive --orbit-seconds 2 --vram-budget 16GiB; done; done
echo "at $SECONDS s"
cd $OUT && gzip -f *.json; tar czf runs.tgz *.txt *.json.gz && rm -f u*.txt l*.txt s*.txt *.json.gz
rm -rf $W
