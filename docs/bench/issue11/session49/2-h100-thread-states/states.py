# Samples the state of every thread of a command every 5 ms (and, when asleep, the kernel
# function it sleeps in) and writes one line per thread-sample: time since start (s), thread
# name (digits dropped), state, wchan. Usage: states.py OUT.tsv COMMAND...
import os, subprocess, sys, time

out = open(sys.argv[1], "w")
proc = subprocess.Popen(sys.argv[2:], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
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
        name = "".join(c for c in comm if not c.isdigit()).strip("-_ ") or comm
        out.write(f"{t:.4f}\t{name}\t{state}\t{wchan if state != 'R' else '-'}\n")
    time.sleep(0.005)
sys.stdout.write(proc.stdout.read().decode(errors="replace"))
