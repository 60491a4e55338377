# Samples /proc/stat every 10 ms while a command runs and prints the share of all cores busy
# (user + nice + system + irq + softirq) per 50 ms, with the command's last output line: where
# a conversion's stages leave cores idle (the stage times are in that line).
import subprocess, sys, time

def read():
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    return v[0] + v[1] + v[2] + v[5] + v[6], sum(v)

samples = []
start = time.time()
proc = subprocess.Popen(sys.argv[1:], stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
while proc.poll() is None:
    samples.append((time.time() - start, *read()))
    time.sleep(0.01)
samples.append((time.time() - start, *read()))
out = proc.stdout.read().decode(errors="replace").strip().splitlines()
print(out[-1][:400] if out else "(no output)")
line, i0 = [], 0
for i, s in enumerate(samples):
    if s[0] - samples[i0][0] >= 0.05 or i == len(samples) - 1:
        a = samples[i0]
        line.append(f"{a[0]:.2f}:{100 * (s[1] - a[1]) / max(s[2] - a[2], 1):.0f}")
        i0 = i
print("busy % per 50 ms (t:busy):", " ".join(line))
a, s = samples[0], samples[-1]
print(f"whole run: {100 * (s[1] - a[1]) / max(s[2] - a[2], 1):.1f} % busy over {s[0]:.2f} s")
