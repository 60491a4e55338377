#!/usr/bin/env bash
# The GPU benchmarks of docs/BENCHMARKS.md, run on the GPU machine (no Rust there: build here
# with `cargo build --release -p pointlet`, copy target/release/pointlet to .dev/pointlet).
# Usage: scripts/gpu-bench.sh PHASE OUT_DIR, PHASE one of:
#   raster  bench-raster on 100 M generated points (issue 3)
#   store   generate the 1 G-point lean store under /tmp (issue 4)
#   orbit   bench along the orbit path by frames and in real time, warm, then cold (issue 4)
#   quality PSNR of LoD images against full detail, 200 M points (issue 4)
#   threads residency threads × loaders A/B on the 1 G-point store (run store first)
#   diag    a quick 200 M-point orbit for profiling the residency step
#   first-frame      50 M-point LAS: render reading the file whole vs drawing while loading
#   progressive-1g   brute-force progressive rendering of a 1 G-point LAS (issue 11)
#   loading          50 M LAS/LAZ and a 200 M-point store read as a point file (--progressive),
#                    and temporal reuse on that store (issue 11)
#   view-first-frame `view --frames 1` of a 50 M-point LAS under a carried Xvfb (.xv/*.deb)
#   splats-raster    bench-raster of one-pixel points, 3-pixel and adaptive splats, compute
#                    footprints and billboard quads, 100 M points (issue 12)
#   splats-quality   PSNR per bucket of one-pixel points, hole filling and adaptive splats,
#                    200 M points (issue 12)
#   splats-orbit     the 1 G-point realtime orbit with one-pixel points and adaptive splats
#                    (compute, quads), alternated, warm (issue 12; generates the store;
#                    CONFIGS: pixel, quads or --point-size values; ROUNDS)
#   laz              50 M-point LAZ: decoding with our decoder and the laz crate, and loading
#                    while drawing (issue 11)
#   alloc            the GPU buffer suballocator against a buffer per allocation (issue 13)
#   tiles            the suballocator, then the 1 G-point lean store exported as a local 3D
#                    Tiles tileset (positions and colours) and both flown along the realtime
#                    orbit: the store (one-pixel points, then adaptive splats: issue 12's
#                    ratio), the tileset at max SSE 16, 4 and 1 (issue 13; generates the store)
set -euo pipefail
phase=$1
out=$2
bin=${POINTLET:-.dev/pointlet}
mkdir -p "$out"
# The GPU machine has the NVIDIA driver but not the Vulkan loader: unpack the carried one.
if ! ldconfig -p | grep -c libvulkan.so.1 >/dev/null; then
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
fi
if [ -f /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json ]; then
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
fi
store=/tmp/bench-1g.pointlet
case "$phase" in
  raster)
    nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv >"$out/gpu.txt" || true
    "$bin" bench-raster --points 100M --frames 10 --json "$out/raster.json" 2>&1 | tee "$out/raster.txt"
    ;;
  store)
    df -h /tmp >"$out/disk.txt"
    /usr/bin/time -v "$bin" generate --points 1G --lean -o "$store" 2>&1 | tee "$out/store.txt"
    "$bin" info "$store" | tee -a "$out/store.txt"
    ;;
  orbit)
    # The orbit by frames (1200 frames, as the paper's table) and in wall-clock time (20 s, as
    # a user flying it sees it), warm (page cache holds the store) and cold.
    size=$(stat -c %s "$store")
    # One-pixel points, as these figures were always measured (stores default to adaptive splats).
    common=(--frames 1200 --orbit-seconds 20 --vram-budget $((size / 20)) --ram-budget 4GiB --bucket 25M --point-size 1)
    sync
    cat "$store" >/dev/null
    for mode in frames realtime; do
      flag=()
      [ "$mode" = realtime ] && flag=(--realtime)
      "$bin" bench "$store" "${common[@]}" "${flag[@]}" --json "$out/orbit-$mode-warm.json" \
        --plot "$out/orbit-$mode-warm.png" 2>&1 | tee "$out/orbit-$mode-warm.txt"
    done
    for mode in frames realtime; do
      flag=()
      [ "$mode" = realtime ] && flag=(--realtime)
      sync
      echo 3 >/proc/sys/vm/drop_caches
      "$bin" bench "$store" "${common[@]}" "${flag[@]}" --json "$out/orbit-$mode-cold.json" \
        --plot "$out/orbit-$mode-cold.png" 2>&1 | tee "$out/orbit-$mode-cold.txt"
    done
    ;;
  threads)
    # Residency threads (t) and loaders (l), alternated, four rounds; the involuntary context
    # switches of each run show oversubscription.
    size=$(stat -c %s "$store")
    common=(--frames 1200 --orbit-seconds 20 --vram-budget $((size / 20)) --ram-budget 4GiB --bucket 25M --point-size 1)
    sync
    for round in 1 2 3 4; do
      for cfg in 16:8 8:8 8:4 4:4; do
        t=${cfg%:*} l=${cfg#*:}
        name="t${t}l${l}-$round"
        /usr/bin/time -v "$bin" bench "$store" "${common[@]}" --residency-threads "$t" --loaders "$l" \
          --json "$out/$name.json" >"$out/$name.txt" 2>&1
        echo "$name $(grep -o '1% low [0-9.]*, 0.1% low [0-9.]*' "$out/$name.txt")" \
          "$(grep -o 'avg [0-9.]* fps' "$out/$name.txt")" \
          "involuntary switches $(grep Involuntary "$out/$name.txt" | awk '{print $NF}')" | tee -a "$out/threads.txt"
      done
    done
    ;;
  diag)
    small=/tmp/bench-200m.pointlet
    "$bin" generate --points 200M --lean -o "$small" 2>&1 | tail -1
    size=$(stat -c %s "$small")
    "$bin" bench "$small" --frames 600 --orbit-seconds 10 --vram-budget $((size / 20)) --ram-budget 4GiB \
      --bucket 25M --point-size 1 --json "$out/diag.json" 2>&1 | tee "$out/diag.txt"
    ;;
  quality)
    # Fig. 16–17 of the paper used 100 M and 187 M points: a 200 M-point store, VRAM 1/6.
    small=/tmp/bench-200m.pointlet
    "$bin" generate --points 200M --lean -o "$small" 2>&1 | tail -1
    "$bin" bench "$small" --quality --vram-budget 1GiB --ram-budget 4GiB --loaders 8 \
      --json "$out/quality.json" 2>&1 | tee "$out/quality.txt"
    ;;
  first-frame)
    # The whole file read before the first frame (the in-memory path of a blending-free
    # 32-bit rasterizer) against drawing while loading, 50 M points, page cache warm.
    f=/tmp/p50.las
    "$bin" generate --points 50M -o "$f" 2>&1 | tail -1 | tee -a "$out/log.txt"
    cat "$f" >/dev/null
    for raster in atomic-min-32 reduce-early-z; do
      /usr/bin/time -f "render --raster $raster: %e s wall, %M KiB" "$bin" render "$f" -o /tmp/r.png \
        --raster "$raster" 2>&1 | tail -2 | tee -a "$out/log.txt"
    done
    rm -f "$f"
    ;;
  progressive-1g)
    f=/tmp/p1g.las
    df -h /tmp | tee -a "$out/log.txt"
    /usr/bin/time -f "generate: %e s, %M KiB" "$bin" generate --points 1G -o "$f" 2>&1 | tail -2 | tee -a "$out/log.txt"
    cat "$f" >/dev/null
    "$bin" bench-read "$f" 2>&1 | tee -a "$out/log.txt"
    "$bin" bench "$f" --realtime --orbit-seconds 20 --target-fps 60 --vram-budget 20GiB \
      --json "$out/p1g.json" 2>&1 | tee -a "$out/log.txt"
    ;;
  loading)
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv >"$out/gpu.txt" || true
    log="$out/log.txt"
    for ext in las laz; do
      f=/tmp/p50.$ext
      "$bin" generate --points 50M -o "$f" 2>&1 | tail -1 | tee -a "$log"
      cat "$f" >/dev/null
      "$bin" bench-read "$f" 2>&1 | tee -a "$log"
      for round in 1 2; do
        "$bin" bench "$f" --realtime --orbit-seconds 10 --target-fps 60 --vram-budget 8GiB \
          --json "$out/p50-$ext.json" 2>&1 | tee -a "$log"
      done
      [ "$ext" = las ] || rm -f "$f"
    done
    s=/tmp/s200.pointlet
    "$bin" generate --points 200M -o "$s" 2>&1 | tail -1 | tee -a "$log"
    cat "$s" >/dev/null
    for round in 1 2; do
      "$bin" bench "$s" --progressive --realtime --orbit-seconds 10 --target-fps 60 \
        --vram-budget 8GiB --json "$out/s200-progressive.json" 2>&1 | tee -a "$log"
    done
    # Temporal reuse: PSNR of moving frames against full detail, and frame times, per bucket.
    for bucket in 1M 10M; do
      for reuse in "" --temporal-reuse; do
        echo "== bucket $bucket ${reuse:-no reuse}" | tee -a "$log"
        "$bin" bench "$s" --frames 300 --orbit-seconds 10 --path-quality 10 --bucket "$bucket" \
          --point-size 1 $reuse 2>&1 | tail -11 | tee -a "$log"
        "$bin" bench "$s" --realtime --orbit-seconds 10 --bucket "$bucket" --point-size 1 $reuse 2>&1 \
          | awk "NR <= 3" | tee -a "$log"
      done
    done
    rm -f "$s" /tmp/p50.las
    ;;
  view-first-frame)
    log="$out/log.txt"
    "$bin" generate --points 50M -o /tmp/p50.las 2>&1 | tail -1 | tee -a "$log"
    cat /tmp/p50.las >/dev/null
    # view --frames 1 under Xvfb (carried in .xv, unpacked beside /, not over it).
    x=/tmp/xv
    mkdir -p "$x"
    for f in .xv/*.deb; do dpkg -x "$f" "$x"; done
    export LD_LIBRARY_PATH="$x/usr/lib/x86_64-linux-gnu:$x/lib/x86_64-linux-gnu"
    export XKB_CONFIG_ROOT="$x/usr/share/X11/xkb"
    [ -e /usr/bin/xkbcomp ] || ln -s "$x/usr/bin/xkbcomp" /usr/bin/xkbcomp || true
    "$x/usr/bin/Xvfb" :77 -screen 0 1920x1080x24 -xkbdir "$x/usr/share/X11/xkb" -nolisten tcp \
      >"$out/xvfb.txt" 2>&1 &
    sleep 3
    ls -la /tmp/.X11-unix >>"$out/xvfb.txt" 2>&1 || true
    for raster in atomic-min-32 reduce-early-z; do
      DISPLAY=:77 RUST_BACKTRACE=1 timeout 120 \
        /usr/bin/time -f "view --frames 1 --raster $raster: %e s wall, %M KiB" \
        "$bin" view /tmp/p50.las --frames 1 --screenshot "/tmp/v-$raster.png" --raster "$raster" \
        2>&1 | tee -a "$log" || echo "view --raster $raster failed" | tee -a "$log"
    done
    rm -f /tmp/p50.las
    ;;
  splats-raster)
    nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv >"$out/gpu.txt" || true
    for size in 1 3 adaptive; do
      "$bin" bench-raster --points 100M --frames 10 --orders original,shuffled-morton \
        --encodings full16 --variants early-z,reduce-early-z,atomic-min-32,hqs1r \
        --point-size "$size" --json "$out/raster-$size.json" 2>&1 | tee "$out/raster-$size.txt"
    done
    ;;
  splats-quality)
    small=/tmp/bench-200m.pointlet
    [ -f "$small" ] || "$bin" generate --points 200M --lean -o "$small" 2>&1 | tail -1
    "$bin" bench "$small" --quality --vram-budget 1GiB --ram-budget 4GiB --loaders 8 \
      --json "$out/quality.json" 2>&1 | tee "$out/quality.txt"
    ;;
  splats-orbit)
    [ -f "$store" ] || /usr/bin/time -f "generate: %e s, %M KiB" "$bin" generate --points 1G --lean \
      -o "$store" 2>&1 | tail -2 | tee "$out/store.txt"
    size=$(stat -c %s "$store")
    common=(--frames 1200 --orbit-seconds 20 --vram-budget $((size / 20)) --ram-budget 4GiB --bucket 25M --realtime)
    cat "$store" >/dev/null
    for round in $(seq 1 "${ROUNDS:-2}"); do
      for cfg in ${CONFIGS:-pixel adaptive quads}; do
        # pixel, quads (adaptive billboard quads), or any --point-size value (adaptive,
        # adaptive:1.1, 2, …).
        case "$cfg" in
          pixel) flags=(--point-size 1) ;;
          quads) flags=(--point-size adaptive --splat-raster quads) ;;
          *) flags=(--point-size "$cfg") ;;
        esac
        name=$(echo "$cfg" | tr ':' '-')
        "$bin" bench "$store" "${common[@]}" "${flags[@]}" --json "$out/orbit-$name-$round.json" \
          2>&1 | tee "$out/orbit-$name-$round.txt"
      done
    done
    ;;
  alloc)
    "$bin" bench-alloc --rounds 5 --json "$out/alloc.json" 2>&1 | tee "$out/alloc.txt"
    ;;
  tiles)
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv >"$out/gpu.txt" || true
    "$bin" bench-alloc --rounds 5 --json "$out/alloc.json" 2>&1 | tee "$out/alloc.txt"
    [ -f "$store" ] || /usr/bin/time -f "generate: %e s, %M KiB" "$bin" generate --points 1G --lean \
      -o "$store" 2>&1 | tail -2 | tee "$out/store.txt"
    tiles=/tmp/bench-1g-tiles
    [ -f "$tiles/tileset.json" ] || /usr/bin/time -f "export: %e s, %M KiB" "$bin" export-3dtiles \
      "$store" -o "$tiles" --local --no-metadata 2>&1 | tail -4 | tee "$out/export.txt"
    du -sb "$store" "$tiles" | tee -a "$out/export.txt"
    df -h /tmp | tee -a "$out/export.txt"
    size=$(stat -c %s "$store")
    common=(--frames 1200 --orbit-seconds 20 --realtime --vram-budget $((size / 20)) --ram-budget 4GiB)
    cat "$store" >/dev/null
    find "$tiles" -type f -exec cat {} + >/dev/null
    for round in $(seq 1 "${ROUNDS:-1}"); do
      for cfg in ${STORE_CONFIGS:-1 adaptive}; do
        name=$(echo "$cfg" | tr ':' '-')
        "$bin" bench "$store" "${common[@]}" --bucket 25M --point-size "$cfg" \
          --json "$out/store-$name-$round.json" 2>&1 | tee "$out/store-$name-$round.txt"
      done
      for sse in ${SSES:-16 4 1}; do
        "$bin" bench "$tiles/tileset.json" "${common[@]}" --max-sse "$sse" --point-size 1 \
          --json "$out/tiles-sse$sse-$round.json" 2>&1 | tee "$out/tiles-sse$sse-$round.txt"
      done
    done
    gzip -f "$out"/*.json
    ;;
  laz)
    f=/tmp/p50.laz
    log="$out/log.txt"
    /usr/bin/time -f "generate: %e s" "$bin" generate --points 50M -o "$f" 2>&1 | tail -2 | tee -a "$log"
    cat "$f" >/dev/null
    for round in 1 2; do
      for decoder in ours laz-crate; do
        echo "== bench-read, decoder $decoder" | tee -a "$log"
        POINTLET_LAZ_DECODER=$decoder "$bin" bench-read "$f" 2>&1 | tee -a "$log"
      done
    done
    for round in 1 2; do
      "$bin" bench "$f" --realtime --orbit-seconds 10 --target-fps 60 --vram-budget 8GiB \
        --json "$out/p50-laz-$round.json" 2>&1 | tee -a "$log"
    done
    rm -f "$f"
    ;;
  *)
    echo "unknown phase $phase" >&2
    exit 2
    ;;
esac
