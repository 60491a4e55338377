#!/usr/bin/env python3
"""Where one program's threads waited off the CPU, from a system-wide
`perf record -a -g -e sched:sched_switch` read back by
`perf script -F comm,tid,time,event,trace,ip,sym`: each time a thread of COMM is switched out,
the time until it is switched in again, summed by its state and the first FRAMES frames of the
stack it left on (the scheduler's and the system call's own frames left out).
Usage: perf script ... | offcpu.py COMM [FRAMES] [SPLIT]; with SPLIT (seconds after the
program's first switch) the waits that began before and after it are tallied apart. Last, a
timeline: thread-seconds off the CPU in each tenth of a second, as idle pool threads (rayon's
sleep), waits in the kernel (state D) and other waits."""
import re
import sys
from collections import defaultdict

comm = sys.argv[1]
depth = int(sys.argv[2]) if len(sys.argv) > 2 else 6
split = float(sys.argv[3]) if len(sys.argv) > 3 else None
head = re.compile(r'^\s*(\S.*?)\s+(\d+)\s+([\d.]+):\s+sched:sched_switch:\s+(.*)$')
field = re.compile(r'(\w+)=(\S+)')
plumbing = re.compile(
    r'^(__schedule|schedule|schedule_timeout|io_schedule|schedule_preempt_disabled'
    r'|preempt_schedule_common|__cond_resched|schedule_hrtimeout_range_clock'
    r'|futex_do_wait|__futex_wait|futex_wait|do_futex|__x64_sys_futex|do_syscall_64'
    r'|entry_SYSCALL_64_after_hwframe|syscall|exit_to_user_mode_loop'
    r'|std::sys::.*|std::thread::.*park.*|\[unknown\])$')
since = {}                       # tid -> (when it was switched out, why)
tallies = [defaultdict(lambda: [0.0, 0]), defaultdict(lambda: [0.0, 0])]
BIN = 0.1
timeline = defaultdict(lambda: [0.0, 0.0, 0.0])   # bin -> idle, D, other
threads, first, last = set(), None, None
event, stack = None, []


def close():
    global event, stack
    if event is not None:
        prev, t, state, ours, nxt = event
        if ours:
            frames = [s for s in stack if not plumbing.match(s)][:depth]
            since[prev] = (t, state + ' ' + ' < '.join(frames))
        if nxt in since:
            t0, why = since.pop(nxt)
            part = 1 if split is not None and t0 - first >= split else 0
            tallies[part][why][0] += t - t0
            tallies[part][why][1] += 1
            kind = 0 if 'Sleep::sleep' in why else 1 if why.startswith('D') else 2
            i = int((t0 - first) / BIN)
            while i * BIN + first < t:
                lo, hi = max(t0, i * BIN + first), min(t, (i + 1) * BIN + first)
                timeline[i][kind] += max(0.0, hi - lo)
                i += 1
    event, stack = None, []


for line in sys.stdin:
    m = head.match(line)
    if m:
        close()
        t = float(m.group(3))
        f = dict(field.findall(m.group(4)))
        ours = f.get('prev_comm') == comm
        if ours or f.get('next_comm') == comm:
            first = t if first is None else first
            last = t
        if ours:
            threads.add(f.get('prev_pid'))
        event = (f.get('prev_pid'), t, f.get('prev_state', '?'), ours, f.get('next_pid'))
        continue
    parts = line.split(None, 1)
    if event is not None and len(parts) == 2:
        stack.append(parts[1].strip().split('+0x')[0])
close()
span = last - first if first is not None else 0.0
print(f'{len(threads)} threads of {comm} over {span:.3f} s')
for part, tally in enumerate(tallies):
    if split is None and part == 1:
        break
    if split is not None:
        print(f'== waits begun {"before" if part == 0 else "after"} {split:.3f} s')
    print(f'{sum(v[0] for v in tally.values()):.3f} thread-s off the CPU')
    for why, (s, n) in sorted(tally.items(), key=lambda x: -x[1][0])[:30]:
        print(f'{s:9.3f} s {n:7d}x  {why}')
print('== timeline: from s, idle pool threads, in kernel waits (D), other waits (thread-s / 0.1 s)')
for b in sorted(timeline):
    idle, d, other = timeline[b]
    print(f'{b * BIN:6.1f} {idle / BIN:6.1f} {d / BIN:6.1f} {other / BIN:6.1f}')
