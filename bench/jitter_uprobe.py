#!/usr/bin/env python3
"""From the kernel's return of clock_nanosleep to the task's first clock read, per thread.

    bench/jitter_uprobe.py [--cpu N] [--seconds S] [--rounds R] [--bench PATH] [--ftrace]
                           [--analyse-only PERF_SCRIPT_TXT] [-- BENCH_JITTER_ARGS...]

Needs root and perf. bench/jitter_trace.py shows that the kernel wakes RACK-RT's data task
and cyclictest equally fast up to the switch-in; what follows, the return to user space
and the code up to the timestamp, is not in an ftrace trace. This script measures it: it
puts a uprobe on glibc's clock_gettime (every side reads its timestamp through it: the
data task through rt::monotonic_ns, cyclictest and bench_jitter's bare thread directly),
records `syscalls:sys_exit_clock_nanosleep` and that probe on CPU N with `perf record`
while `bench_jitter --cpu N --seconds S --rounds R` runs (add --bare-side or --bare-lib
after `--` for the third side), and prints per thread the distribution of the time from
the syscall's exit tracepoint to the first clock_gettime after it.

The uprobe itself costs a trap (1-15 us on this VM) that is taken after the measured
interval ends, so the figures are comparable between threads but the wake-up latencies
bench_jitter prints during such a run are not. The probe is removed at the end. See
bench/RESULTS.md, "Fifth session".

--ftrace measures the kernel's part instead, with nanosecond timestamps (ftrace's raw
output; perf loses the timer events raised while the CPU idles on this VM): per thread,
from the hrtimer handler's entry on CPU N to the thread's exit from clock_nanosleep (the
wake-up, the switch-in and the rest of the system call). Threads are named from
saved_cmdlines.
"""
import argparse
import collections
import os
import subprocess
import sys

LIBC = "/lib/x86_64-linux-gnu/libc.so.6"
PROBE = "probe_libc:clock_gettime"


def analyse(text_path):
    last = {}
    deltas = collections.defaultdict(list)
    for line in open(text_path, encoding="utf-8", errors="replace"):
        p = line.split()
        if len(p) < 4:
            continue
        comm, tid, ev = p[0], p[1], p[3].rstrip(":")
        try:
            t = float(p[2].rstrip(":"))
        except ValueError:
            continue
        if ev.endswith("sys_exit_clock_nanosleep"):
            last[tid] = t
        elif ev.endswith("clock_gettime") and tid in last:
            deltas[(comm, tid)].append((t - last.pop(tid)) * 1e6)
    print("%-22s %7s %8s %8s %8s %8s %8s" % ("thread", "n", "p10 us", "p50 us", "p90 us", "p99 us", "mean"))
    for (comm, tid), v in sorted(deltas.items(), key=lambda kv: -len(kv[1])):
        if len(v) < 100:
            continue
        v.sort()
        n = len(v)
        print("%-22s %7d %8.3f %8.3f %8.3f %8.3f %8.3f" % (
            "%s/%s" % (comm, tid), n, v[n // 10], v[n // 2], v[9 * n // 10], v[99 * n // 100], sum(v) / n))


def ftrace_kernel_part(a):
    t = "/sys/kernel/tracing"
    events = ["timer/hrtimer_expire_entry", "sched/sched_switch", "syscalls/sys_exit_clock_nanosleep"]

    def put(path, text):
        with open(os.path.join(t, path), "w", encoding="utf-8") as f:
            f.write(text)

    ids = {e: int(open(os.path.join(t, "events", e, "id"), encoding="utf-8").read()) for e in events}
    put("tracing_on", "0")
    put("trace", "")
    put("tracing_cpumask", "%x" % (1 << a.cpu))
    put("buffer_size_kb", "32768")
    put("options/raw", "1")
    put("events/enable", "0")
    for e in events:
        put("events/%s/enable" % e, "1")
    try:
        put("tracing_on", "1")
        bench = subprocess.run([a.bench, "--cpu", str(a.cpu), "--seconds", str(a.seconds), "--rounds",
                                str(a.rounds)] + a.extra, capture_output=True, text=True)
        put("tracing_on", "0")
        trace = open(os.path.join(t, "trace"), encoding="utf-8", errors="replace").read().splitlines()
        names = {}
        for line in open(os.path.join(t, "saved_cmdlines"), encoding="utf-8", errors="replace"):
            pid, _, comm = line.strip().partition(" ")
            names[pid] = comm
    finally:
        put("events/enable", "0")
        put("options/raw", "0")
        put("tracing_cpumask", "%x" % ((1 << os.cpu_count()) - 1))
        put("trace", "")
    for line in bench.stdout.splitlines():
        if line.startswith("median") or line.startswith("bare side"):
            print("bench_jitter:", line)
    last_expiry = None
    deltas = collections.defaultdict(list)
    first = {}
    for line in trace:  # raw: "pid cpu ts_ns type: id ..."
        p = line.split()
        if line.startswith("#") or len(p) < 5 or not p[2].isdigit():
            continue
        ts, kind = int(p[2]), int(p[4])
        if kind == ids["timer/hrtimer_expire_entry"]:
            last_expiry = ts
        elif kind == ids["syscalls/sys_exit_clock_nanosleep"] and last_expiry is not None:
            first.setdefault(p[0], ts)
            deltas[p[0]].append((ts - last_expiry) / 1e3)
            last_expiry = None
    print("timer handler entry -> clock_nanosleep exit, per thread, in order of appearance:")
    print("%-22s %7s %8s %8s %8s %8s" % ("thread", "n", "p10 us", "p50 us", "p90 us", "p99 us"))
    for pid, v in sorted(deltas.items(), key=lambda kv: first[kv[0]]):
        if len(v) < 100:
            continue
        v.sort()
        n = len(v)
        print("%-22s %7d %8.3f %8.3f %8.3f %8.3f" % ("%s/%s" % (names.get(pid, "?"), pid), n, v[n // 10],
                                                     v[n // 2], v[9 * n // 10], v[99 * n // 100]))
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cpu", type=int, default=os.cpu_count() - 1)
    ap.add_argument("--seconds", type=int, default=12)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--bench", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build",
                                                    "bench", "bench_jitter"))
    ap.add_argument("--ftrace", action="store_true", help="the kernel's part (ftrace, ns), not the uprobe")
    ap.add_argument("--analyse-only", metavar="TXT", help="analyse `perf script --ns -F comm,tid,time,event` output")
    ap.add_argument("extra", nargs="*", help="more bench_jitter arguments (after --)")
    a = ap.parse_args()
    if a.analyse_only:
        analyse(a.analyse_only)
        return 0
    if a.ftrace:
        return ftrace_kernel_part(a)
    if subprocess.run(["perf", "probe", "-x", LIBC, "--add", "clock_gettime"], capture_output=True).returncode != 0:
        if PROBE not in subprocess.run(["perf", "probe", "-l"], capture_output=True, text=True).stdout:
            sys.exit("jitter_uprobe: cannot add a uprobe on %s clock_gettime (root? perf?)" % LIBC)
    data, text = "/tmp/jitter-uprobe.data", "/tmp/jitter-uprobe.txt"
    try:
        rec = subprocess.Popen(["perf", "record", "-q", "-o", data, "-C", str(a.cpu), "-e",
                                "syscalls:sys_exit_clock_nanosleep", "-e", PROBE])
        bench = subprocess.run([a.bench, "--cpu", str(a.cpu), "--seconds", str(a.seconds), "--rounds",
                                str(a.rounds)] + a.extra, capture_output=True, text=True)
        rec.send_signal(2)
        rec.wait()
        for line in bench.stdout.splitlines():
            if line.startswith("median") or line.startswith("bare side"):
                print("bench_jitter:", line)
        with open(text, "w", encoding="utf-8") as out:
            subprocess.run(["perf", "script", "--ns", "-i", data, "-F", "comm,tid,time,event"], stdout=out,
                           stderr=subprocess.DEVNULL, check=True)
    finally:
        subprocess.run(["perf", "probe", "-d", PROBE], capture_output=True)
    analyse(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
