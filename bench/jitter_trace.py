#!/usr/bin/env python3
"""What runs on the measured CPU around each wake-up of bench_jitter's two sides.

    bench/jitter_trace.py [--cpu N] [--seconds S] [--rounds R] [--late-us U] [--window-us W]
                          [--bench PATH] [--analyse-only TRACE] [-- BENCH_JITTER_ARGS...]

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
  - every wake-up later than --late-us (default 500): its time since the first
    wake-up of that side's thread (a segment's start-up shows as small offsets), and
    the events on the CPU in the --window-us (default 2500) before its switch-in.
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


def trace(cpu, seconds, rounds, bench, extra, out):
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
        r = subprocess.run([bench, "--cpu", str(cpu), "--seconds", str(seconds), "--rounds", str(rounds)] + extra,
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


def analyse(path, late_us=500.0, window_us=2500.0):
    starts, pending, res = {}, {}, collections.defaultdict(list)
    recent = collections.deque(maxlen=40)
    history = collections.deque()  # (ts, comm, pid, ev, rest) within window_us
    first_wake = {}  # pid of the measured thread -> its first switch-in (a segment's start)
    late_list = []
    tick_ns = None
    last_tick = None
    for line in open(path):
        m = LINE.match(line)
        if not m:
            continue
        comm, pid, _, ts, ev, rest = m.groups()
        ts = float(ts) * 1e6
        recent.append((ts, comm, ev, rest))
        history.append((ts, comm, pid, ev, rest))
        while history and ts - history[0][0] > window_us:
            history.popleft()
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
                    tid = re.search(r"next_pid=(\d+)", rest).group(1)
                    first_wake.setdefault(tid, ts)
                    if d["late"] + d["switch"] >= late_us:
                        late_list.append((d, ts - first_wake[tid], list(history)))
    tick_ns = tick_ns or 4_000_000
    tick_phase = None if last_tick is None else last_tick % tick_ns
    by_after = collections.defaultdict(lambda: collections.defaultdict(list))
    print(f"\nwake-ups later than {late_us:g} us (timer lateness + expiry -> switch-in), with the time since "
          f"the first wake-up of that thread (its segment's start) and the CPU's events in the {window_us:g} us "
          "before the switch-in (other threads' switches, IRQs, softirqs, IPIs; hrtimer starts left out):")
    for d, since, hist in late_list:
        print(f"- {d['side']}: {d['late'] + d['switch']:.0f} us late (timer {d['late']:.0f} + switch-in "
              f"{d['switch']:.0f}), {since / 1e6:.3f} s into its segment, running when it fired: {d['running']}")
        t_end = hist[-1][0] if hist else 0
        for ts, comm, pid, ev, rest in hist:
            if ev in ("hrtimer_start", "sched_wakeup") and "gen:data" not in rest and "cyclictest" not in rest:
                continue
            print(f"    {ts - t_end:9.1f} us  {comm}-{pid}  {ev}: {rest[:110]}")
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
        if tick_phase is not None:
            for d in ds:
                after = (d["deadline"] - tick_phase) % tick_ns
                by_after[side][int(after * 16 // tick_ns)].append(d["late"] + d["switch"])
    if tick_phase is not None and len(by_after) == 2:
        # The same wake-up, timed against the tick: if both sides have the same latency at
        # the same phase, a difference between them is the phases their segments drew.
        print(f"\nlatency (timer lateness + switch-in, p50 / p99 us, n) by the deadline's time after the "
              f"{tick_ns / 1e6:g} ms scheduler tick, in sixteenths of it:")
        for k in range(16):
            row = []
            for side in ("rack-rt", "cyclictest"):
                v = by_after[side].get(k, [])
                row.append(f"{side} {pct(v, .5):5.1f} / {pct(v, .99):6.1f} ({len(v):5d})" if v else f"{side} -")
            print(f"  {k * tick_ns / 16e3:6.0f}-{(k + 1) * tick_ns / 16e3:4.0f} us: " + "   ".join(row))
        for side in ("rack-rt", "cyclictest"):
            v = [x for k in range(16) for x in by_after[side].get(k, [])]
            w = {k: len(by_after[side].get(k, [])) / max(1, len(v)) for k in range(16)}
            print(f"  {side}: share of wake-ups per sixteenth: " + " ".join(f"{w[k]:.2f}" for k in range(16)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cpu", type=int, default=os.cpu_count() - 1)
    ap.add_argument("--seconds", type=int, default=10)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--late-us", type=float, default=500.0, help="list every wake-up at least this late")
    ap.add_argument("--window-us", type=float, default=2500.0, help="events shown before each late one")
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
        trace(a.cpu, a.seconds, a.rounds, a.bench, a.extra, out)
    analyse(out, a.late_us, a.window_us)


if __name__ == "__main__":
    main()
