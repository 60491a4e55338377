#!/usr/bin/env bash
# session 33 call 1 (issue 15): page-cache writes into ONE 7 GiB file (about a 200 M-point
# store): pwrite threads (what the emitter does) against memcpy into a shared mapping of the
# fallocated file, by thread count; .dev/wb/wb.c, built on dev with gcc -O2.
set -uo pipefail
exec > >(tee "$OUT/log.txt") 2>&1
W=/tmp/w; mkdir -p $W; df -T $W | tail -1; nproc
for r in 1 2; do
  for t in 1 2 4; do .dev/wb/wb $W/f 7 0 $t; rm -f $W/f; sync; done
  for t in 2 4 8 16; do .dev/wb/wb $W/f 7 1 $t; rm -f $W/f; sync; done
  .dev/wb/wb $W/f 7 2 16; rm -f $W/f; sync
done
.dev/wb/wb /dev/shm/f 7 0 2; rm -f /dev/shm/f
.dev/wb/wb /dev/shm/f 7 1 16; rm -f /dev/shm/f
uname -r
