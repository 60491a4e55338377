#!/usr/bin/env bash
# Prepared in session 42: session 42's depth pass (the colour loaded for every point that passes
# the depth test, no branch on the uniform any_hidden, which lavapipe recompiled at every bind)
# against s9 (32155d6): bench-raster of atomic-min-32, hqs and hqs1r on 100 M generated points,
# both encodings, every vertex order, alternated, twice. Binaries as ../1-h100-s9-s42a-cur/call.sh says.
# Run: run(command="bash docs/bench/issue15/session42/2-h100-raster/call.sh", carry=[".dev/pointlet-cur.xz",
#   ".dev/pointlet-s9.xz", ".gl"]) -- ~4 minutes.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
X() { xz -dc "$1" 2>/dev/null || python3 -c 'import lzma,sys,shutil; shutil.copyfileobj(lzma.open(sys.argv[1]), sys.stdout.buffer)' "$1"; }
for v in cur s9; do X .dev/pointlet-$v.xz > /tmp/p-$v && chmod +x /tmp/p-$v; done
R=/tmp/res; mkdir -p $R; SECONDS=0
nvidia-smi --query-gpu=name,driver_version --format=csv
# The depth pass: medians of 10 frames per configuration, both encodings, every vertex order.
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
for r in 1 2; do for v in s9 cur; do
  timeout 120 /tmp/p-$v bench-raster --points 100M --frames 10 --variants atomic-min-32,hqs,hqs1r --json $R/raster-$v-$r.json > $R/raster-$v-$r.txt 2>&1
  echo "raster-$v-$r:"; grep -E ' full16 .*(atomic-min-32|hqs)|unreliable|rror' $R/raster-$v-$r.txt
done; done
echo "at $SECONDS s"
cd $R && tar czf $OUT/runs.tgz *
