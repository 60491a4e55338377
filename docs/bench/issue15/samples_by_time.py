#!/usr/bin/env python3
"""On-CPU samples over time, from `perf script -F tid,time,ip,sym` text (gzip): for each bin of
BIN seconds, the samples, the threads they came from, and the three commonest (innermost frame |
first frame of ours) pairs. A bin with one thread is a stretch where one core worked alone.
Usage: samples_by_time.py perf-script.txt.gz [BIN]
(session41/2-h100-profile: `samples_by_time.py on-mem-script.txt.gz 0.01`)."""
import sys, gzip, re, collections
f = gzip.open(sys.argv[1], 'rt')
BIN = float(sys.argv[2]) if len(sys.argv) > 2 else 0.05
samples = []  # (time, tid, frames)
cur = None
for line in f:
    if not line.strip():
        if cur: samples.append(cur); cur = None
        continue
    if not line.startswith('\t') and not line.startswith(' ' * 8):
        m = re.match(r'\s*(\d+)\s+([\d.]+):', line)
        if m: cur = (float(m.group(2)), int(m.group(1)), [])
        continue
    if cur is not None:
        parts = line.strip().split(None, 1)
        cur[2].append(parts[1] if len(parts) > 1 else '?')
if cur: samples.append(cur)
t0 = samples[0][0]
bins = collections.defaultdict(list)
for t, tid, fr in samples: bins[int((t - t0) / BIN)].append((tid, fr))
def label(fr):
    ours = [x for x in fr if 'pointlet' in x]
    leaf = fr[0] if fr else '?'
    return (leaf[:40] + ' | ' + (ours[0][:70] if ours else ''))
for b in sorted(bins):
    s = bins[b]
    tids = collections.Counter(t for t, _ in s)
    labs = collections.Counter(label(fr) for _, fr in s)
    top = '; '.join(f'{n}:{l}' for l, n in labs.most_common(3))
    print(f'{b*BIN:6.2f} {len(s):5d} thr={len(tids):2d} {top}')
