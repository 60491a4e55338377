#!/usr/bin/env bash
# Session 48, call 2: how many threads fill the BAR: `bench --progressive`'s upload probe
# (threads writing wgpu's mapped upload memory, and host memory the GPU pulls) with the rayon
# pool at 1-16 threads, on a 20 M store. Binary: .dev/pointlet-head.xz (d3de81e).
# Run: run(command="bash docs/bench/issue11/session48/2-h100-bar-threads/call.sh",
#   carry=[".dev", ".gl"])
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig; export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json; mkdir -p $OUT/c2; xz -dc .dev/pointlet-head.xz > /tmp/p; chmod +x /tmp/p; /tmp/p generate --points 20M -o /tmp/s20.pointlet 2>&1 | tail -1; for t in 1 2 4 8 12 16; do echo "threads $t: $(RAYON_NUM_THREADS=$t timeout 60 /tmp/p bench /tmp/s20.pointlet --progressive --realtime --orbit-seconds 1 2>&1 | grep -E '^upload path|^from host' | tr '\n' ' ')"; done 2>&1 | tee $OUT/c2/log.txt
