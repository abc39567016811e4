#!/usr/bin/env python3
"""What runs on the measured CPU around each wake-up of bench_jitter's two sides.

    bench/jitter_trace.py [--cpu N] [--seconds S] [--bench PATH] [-- BENCH_JITTER_ARGS...]

Needs root. Mounts tracefs at /sys/kernel/tracing if needed, traces CPU N only
(sched_switch/wakeup, irq and softirq entry/exit, hrtimer_start/expire, local timer
and IPI vectors) while `bench_jitter --cpu N --seconds S --rounds 2` runs (RACK-RT's
data task and cyclictest, one after the other), then prints per side:
  - timer lateness: the nanosleep hrtimer's 'now' in its handler minus its expiry
    (the interrupt's delivery: the hypervisor, interrupts disabled by what ran);
  - expiry -> switch-in: the kernel's wake-up and preemption of what ran;
  - what was running when the timer fired, and which IRQs/softirqs came within
    200 us before it, for the worst 1 % of wake-ups;
  - p50/p99 by the deadline's phase within the scheduler tick (HZ from the trace).
The trace stays in /tmp/jitter-trace.txt. The time from switch-in to the task's own
timestamp is user space (clock_nanosleep returning, clock_gettime in the vDSO) and is
not in the trace. See bench/RESULTS.md, "Jitter: what runs on the measured CPU".
"""
import argparse
import collections
import os
import re
import subprocess
import sys

T = "/sys/kernel/tracing"
EVENTS = ["sched/sched_switch", "sched/sched_wakeup", "irq/irq_handler_entry", "irq/irq_handler_exit",
          "irq/softirq_entry", "irq/softirq_exit", "timer/hrtimer_start", "timer/hrtimer_expire_entry",
          "irq_vectors/local_timer_entry", "irq_vectors/reschedule_entry", "irq_vectors/call_function_entry",
          "irq_vectors/call_function_single_entry"]
SIDES = {"gen:data": "rack-rt", "cyclictest": "cyclictest"}
LINE = re.compile(r"^\s*(.+?)-(\d+)\s+\[(\d+)\]\s+\S+\s+([\d.]+): (\w+): (.*)$")


def write(path, text):
    with open(os.path.join(T, path), "w") as f:
        f.write(text)


def trace(cpu, seconds, bench, extra, out):
    if not os.path.exists(os.path.join(T, "trace")):
        subprocess.run(["mount", "-t", "tracefs", "nodev", T], check=True)
    write("tracing_on", "0")
    write("trace", "")
    write("tracing_cpumask", format(1 << cpu, "x"))
    write("buffer_size_kb", "16384")
    write("events/enable", "0")
    for e in EVENTS:
        try:
            write(f"events/{e}/enable", "1")
        except OSError as err:
            print(f"jitter_trace: event {e} not available: {err}", file=sys.stderr)
    write("tracing_on", "1")
    try:
        r = subprocess.run([bench, "--cpu", str(cpu), "--seconds", str(seconds), "--rounds", "2"] + extra,
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    finally:
        write("tracing_on", "0")
    with open(os.path.join(T, "trace")) as src, open(out, "w") as dst:
        dst.write(src.read())
    write("trace", "")
    write("events/enable", "0")
    write("tracing_cpumask", format((1 << os.cpu_count()) - 1, "x"))
    print("\n".join(l for l in r.stdout.splitlines() if l.startswith(("rack-rt ", "cyclictest ", "side", "median"))))


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else 0.0


def analyse(path):
    starts, pending, res = {}, {}, collections.defaultdict(list)
    recent = collections.deque(maxlen=40)
    tick_ns = None
    last_tick = None
    for line in open(path):
        m = LINE.match(line)
        if not m:
            continue
        comm, pid, _, ts, ev, rest = m.groups()
        ts = float(ts) * 1e6
        recent.append((ts, comm, ev, rest))
        if ev == "hrtimer_start":
            p = re.search(r"hrtimer=(\w+) function=(\w+) expires=(\d+)", rest)
            if not p:
                continue
            if p.group(2) == "hrtimer_wakeup":
                starts[p.group(1)] = (int(p.group(3)), comm)
            elif p.group(2) == "tick_nohz_handler" or p.group(2) == "tick_sched_timer":
                e = int(p.group(3))
                if last_tick is not None and 0 < e - last_tick < 20_000_000:
                    tick_ns = e - last_tick if tick_ns is None else min(tick_ns, e - last_tick)
                last_tick = e
        elif ev == "hrtimer_expire_entry":
            p = re.search(r"hrtimer=(\w+) function=(\w+) now=(\d+)", rest)
            if p and p.group(2) == "hrtimer_wakeup" and p.group(1) in starts:
                exp, c = starts.pop(p.group(1))
                if c in SIDES:
                    pending[c] = {"side": SIDES[c], "deadline": exp, "late": (int(p.group(3)) - exp) / 1000.0,
                                  "at": ts, "running": comm, "ctx": list(recent)}
        elif ev == "sched_switch":
            p = re.search(r"prev_comm=(.*) prev_pid=\d+ .* next_comm=(.*) next_pid=\d+ next_prio=(\d+)", rest)
            if p and p.group(2) in pending:
                d = pending.pop(p.group(2))
                if int(p.group(3)) < 99:  # the RT thread (cyclictest's main thread is SCHED_OTHER)
                    d["switch"] = ts - d["at"]
                    res[d["side"]].append(d)
    tick_ns = tick_ns or 4_000_000
    for side, ds in res.items():
        late = [d["late"] for d in ds]
        sw = [d["switch"] for d in ds]
        tot = [d["late"] + d["switch"] for d in ds]
        print(f"\n{side}: {len(ds)} wake-ups; timer lateness p50 {pct(late, .5):.1f} p99 {pct(late, .99):.1f} "
              f"p99.9 {pct(late, .999):.1f} us; expiry -> switch-in p50 {pct(sw, .5):.1f} p99 {pct(sw, .99):.1f} "
              f"p99.9 {pct(sw, .999):.1f} us; sum p99 {pct(tot, .99):.1f} us")
        idle = sum(1 for d in ds if d["running"].startswith("<idle>"))
        print(f"  CPU idle when the timer fired: {idle} of {len(ds)}")
        thr = pct(tot, .99)
        running, irqs = collections.Counter(), collections.Counter()
        for d in ds:
            if d["late"] + d["switch"] < thr:
                continue
            running[re.sub(r"\d+", "N", d["running"])] += 1
            for ts, _, ev, rest in d["ctx"]:
                if d["at"] - ts < 200 and ev in ("irq_handler_entry", "softirq_entry", "call_function_entry",
                                                 "call_function_single_entry", "reschedule_entry"):
                    name = re.search(r"(?:name|action)=(\S+)", rest)
                    irqs[ev + (":" + name.group(1).rstrip("]") if name else "")] += 1
        print("  worst 1 %: running when the timer fired:", running.most_common(8))
        print("  worst 1 %: IRQs/softirqs/IPIs in the 200 us before:", irqs.most_common(8))
        by_phase = collections.defaultdict(list)
        for d in ds:
            by_phase[round((d["deadline"] % tick_ns) / 1e6, 2)].append(d["late"] + d["switch"])
        print(f"  by deadline phase in the {tick_ns / 1e6:g} ms tick (ms: p50/p99 us, n):",
              {k: (round(pct(v, .5)), round(pct(v, .99)), len(v)) for k, v in sorted(by_phase.items()) if len(v) > 50})


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cpu", type=int, default=os.cpu_count() - 1)
    ap.add_argument("--seconds", type=int, default=10)
    ap.add_argument("--bench", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build",
                                                    "bench", "bench_jitter"))
    ap.add_argument("--analyse-only", metavar="TRACE", help="analyse an existing trace file")
    ap.add_argument("extra", nargs="*", help="more bench_jitter arguments (after --)")
    a = ap.parse_args()
    out = "/tmp/jitter-trace.txt"
    if a.analyse_only:
        out = a.analyse_only
    else:
        if os.geteuid() != 0:
            sys.exit("jitter_trace: needs root (tracefs, SCHED_FIFO)")
        trace(a.cpu, a.seconds, a.bench, a.extra, out)
    analyse(out)


if __name__ == "__main__":
    main()
