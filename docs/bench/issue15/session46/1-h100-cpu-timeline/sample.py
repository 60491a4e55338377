# Samples /proc/stat every 20 ms while a command runs; prints the share of all cores busy
# (user + nice + system + irq + softirq) and waiting on I/O per 100 ms, and the totals.
import subprocess, sys, time

def read():
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    busy = v[0] + v[1] + v[2] + v[5] + v[6]
    return busy, v[4], sum(v)

samples = []
start = time.time()
proc = subprocess.Popen(sys.argv[1:], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
while proc.poll() is None:
    samples.append((time.time() - start, *read()))
    time.sleep(0.02)
samples.append((time.time() - start, *read()))
out = proc.stdout.read().decode(errors="replace")
print(out.strip().splitlines()[-1][:400] if out.strip() else "(no output)")
line, t0 = [], 0
i0 = 0
for i, s in enumerate(samples):
    if s[0] - samples[i0][0] >= 0.1 or i == len(samples) - 1:
        a = samples[i0]
        tot = max(s[3] - a[3], 1)
        line.append(f"{a[0]:.1f}:{100 * (s[1] - a[1]) / tot:.0f}" + (f"/io{100 * (s[2] - a[2]) / tot:.0f}" if s[2] > a[2] else ""))
        i0 = i
print("busy % per 100 ms (t:busy):", " ".join(line))
a, s = samples[0], samples[-1]
print(f"whole run: {100 * (s[1] - a[1]) / max(s[3] - a[3], 1):.1f} % busy over {s[0]:.2f} s")
