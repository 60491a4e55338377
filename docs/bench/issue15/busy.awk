# Busy cores over time from a call.sh CPU sample file (lines: epoch-seconds, then /proc/stat's
# "cpu" line): `awk -v cores=16 -f busy.awk cpu-ooc-new.txt` prints seconds since the first
# sample and the cores busy since the previous one, then the average over the whole file.
{
    t = $1; busy = $3 + $4 + $5 + $8 + $9 + $10; all = busy + $6 + $7
    if (NR > 1 && all > pall) {
        b = (busy - pbusy) / (all - pall) * cores
        printf "%6.2f s %5.1f\n", t - t0, b
        sum += b * (t - pt); span += t - pt
    } else if (NR == 1) t0 = t
    pt = t; pbusy = busy; pall = all
}
END { if (span > 0) printf "average %.1f of %d cores over %.2f s\n", sum / span, cores, span }
