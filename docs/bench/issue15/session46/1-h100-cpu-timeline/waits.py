# Samples every thread of a command every 10 ms: its state and, when asleep, the kernel
# function it sleeps in (/proc/PID/task/TID/wchan). Prints, for the first and the second
# part of the run (cut at the fraction argv[1]), thread-samples by (thread name, state, wchan).
import collections, os, subprocess, sys, time

cut = float(sys.argv[1])
proc = subprocess.Popen(sys.argv[2:], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
samples = []
start = time.time()
while proc.poll() is None:
    t = time.time() - start
    try:
        tids = os.listdir(f"/proc/{proc.pid}/task")
    except OSError:
        break
    for tid in tids:
        base = f"/proc/{proc.pid}/task/{tid}"
        try:
            with open(base + "/stat") as f:
                stat = f.read()
            with open(base + "/wchan") as f:
                wchan = f.read().strip() or "-"
        except OSError:
            continue
        comm = stat[stat.index("(") + 1 : stat.rindex(")")]
        state = stat[stat.rindex(")") + 2]
        name = "".join(c for c in comm if not c.isdigit()).strip() or comm
        samples.append((t, name, state, wchan if state != "R" else "-"))
    time.sleep(0.01)
end = time.time() - start
out = proc.stdout.read().decode(errors="replace").strip().splitlines()
print(out[-1][:400] if out else "(no output)")
for label, lo, hi in (("first part", 0, cut * end), ("second part", cut * end, end)):
    c = collections.Counter((n, s, w) for t, n, s, w in samples if lo <= t < hi)
    total = sum(c.values())
    print(f"-- {label} ({lo:.2f}-{hi:.2f} s): {total} thread-samples")
    for (n, s, w), k in c.most_common(14):
        print(f"   {100 * k / max(total, 1):5.1f} %  {n:<18} {s} {w}")
